"""Reader of mass/stiffness pairs in Matrix Market format (``.mtx``, ``.mm``).

A model is two (or three) Matrix Market files in one folder, told apart by the end of the
file stem (case-insensitive); the part before it, ``<base>``, is the same for all of them
and may end in a separator such as ``_``:

=========  ==============================================
stiffness  ``<base>K``, ``<base>STIF``, ``<base>STIFF``, ``<base>STIFFNESS``
mass       ``<base>M``, ``<base>MASS``
damping    ``<base>D``, ``<base>DAMP``, ``<base>DAMPING`` (optional)
=========  ==============================================

e.g. ``rotor_K.mtx`` + ``rotor_M.mtx`` (+ ``rotor_D.mtx``), or ``plate_stiffness.mm`` +
``plate_mass.mm``. The whole words may also stand inside the stem, as in Ansys' export
``rotorStiffnessMatrix.txt`` + ``rotorMassMatrix.txt`` (read with ``format="matrix-market"``).
Pass either the stiffness or the mass file; the other is found beside it (with the same
suffix, ``.mtx`` or ``.mm``; each file may be gzip-compressed, ``rotor_K.mtx.gz``).
Symmetric storage (one triangle) is expanded by :func:`scipy.io.mmread`.
The model has no node table and no equation map.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

from ...errors import FlexmorWarning, ReadError
from ...model import FEModel
from .._build import build_model
from .._open import is_gzip, open_binary, plain_name, size_hint, stem, suffix
from .._registry import MODEL_FORMATS
from .._sparse import assemble
from .._text import entry_line, parse_triplets
from .._unchecked import warn_unchecked

__all__ = ["read_matrix_market", "find_siblings"]

_SUFFIXES = (".mtx", ".mm")
#: Stem endings of each role, longest first within a role.
_TAGS = {
    "K": ("stiffness", "stiff", "stif", "k"),
    "M": ("mass", "m"),
    "D": ("damping", "damp", "d"),
}
_ROLE_NAME = {"K": "stiffness", "M": "mass", "D": "damping"}
_LINE_MSG = re.compile(r"^\s*Line\s+(\d+)\s*:\s*(.*)$", re.S)


def _role_of(stem: str):
    """All ``(role, head, tail)`` readings of a file stem (``stem = head + tag + tail``).

    Tags at the end of the stem come first (longest first), then the full words
    (``stiffness``, ``mass``) inside the stem, as in ``rotorMassMatrix``.
    """
    low = stem.lower()
    found = [(1, len(t), role, stem[: len(stem) - len(t)], "") for role in ("K", "M") for t in _TAGS[role]
             if low.endswith(t)]
    for role, word in (("K", "stiffness"), ("M", "mass")):
        i = low.rfind(word)
        if i >= 0 and i + len(word) < len(low):
            found.append((0, len(word), role, stem[:i], stem[i + len(word):]))
    return [(role, head, tail) for *_, role, head, tail in sorted(found, key=lambda f: (-f[0], -f[1]))]


def find_siblings(path) -> dict:
    """Find the stiffness, mass and (optional) damping files that belong with ``path``.

    Returns
    -------
    dict
        ``{"K": Path, "M": Path}`` and ``"D"`` when a damping file exists.

    Raises
    ------
    ReadError
        When the name does not follow the naming rule or a partner file is missing.
    """
    path = Path(path)
    readings = _role_of(stem(path))
    if not readings and any(stem(path).lower().endswith(t) for t in _TAGS["D"]):
        raise ReadError(path, "this looks like the damping matrix; pass the stiffness or mass file, "
                              "the damping file is found beside it")
    if not readings:
        raise ReadError(path, "cannot tell stiffness from mass by the name; name the files "
                              "<base>_K.mtx and <base>_M.mtx (see flexmor.io.matrix_market)")
    listing = {}  # by the name seen through .gz; the compression of path first
    for p in sorted((p for p in path.parent.iterdir() if p.is_file()), key=lambda p: is_gzip(p) != is_gzip(path)):
        listing.setdefault(plain_name(p).lower(), p)
    suffixes = tuple(dict.fromkeys((suffix(path),) + _SUFFIXES))
    tried = []
    for role, head, tail in readings:
        other = "M" if role == "K" else "K"
        found = {role: path}
        for want in (other, "D"):
            for tag in _TAGS[want]:
                if tail and len(tag) < 4:
                    continue  # inside a stem only whole words are swapped
                for suf in suffixes:
                    name = head + (tag.upper() if len(tag) == 1 else tag) + tail + suf
                    if want == other:
                        tried.append(name)
                    if name.lower() in listing and listing[name.lower()] != path:
                        found.setdefault(want, listing[name.lower()])
        if other in found:
            return found
    role = readings[0][0]
    other = "mass" if role == "K" else "stiffness"
    raise ReadError(path, f"read as the {_ROLE_NAME[role]} matrix, but no {other} file beside it; looked for "
                          f"{', '.join(dict.fromkeys(tried))}")


def _check_header(path: Path) -> None:
    try:
        with open_binary(path) as f:
            head = f.readline(200)
            more = bool(head) or bool(f.read(1))
    except OSError as exc:
        raise ReadError(path, f"cannot read: {exc.strerror}") from None
    if not head.strip():
        raise ReadError(path, "first line is blank" if more else "file is empty", 1)
    words = head.decode("latin-1").lower().split()
    if not words or words[0] != "%%matrixmarket":
        raise ReadError(path, "not a Matrix Market file (first line must start with %%MatrixMarket); "
                              "plain 'row col value' files (Abaqus *MATRIX GENERATE, <job>_STIF1.mtx) are "
                              "read with format abaqus from the .inp beside them", 1, params=("format",))
    if len(words) < 5 or words[1] != "matrix" or words[2] not in ("coordinate", "array"):
        raise ReadError(path, f"unsupported Matrix Market header {head.strip()[:80]!r}; expected "
                              "'%%MatrixMarket matrix coordinate|array real|integer general|symmetric'", 1)
    if words[3] not in ("real", "integer", "double"):
        raise ReadError(path, f"field '{words[3]}' is not supported; flexmor needs real matrices", 1)
    if words[4] not in ("general", "symmetric"):
        raise ReadError(path, f"symmetry '{words[4]}' is not supported; use general or symmetric", 1)


#: Largest matrix dimension accepted (a header claiming more is refused before allocation).
MAX_DIM = 2**31 - 1


def _size_line(path: Path):
    """``(lineno, [ints])`` of the size line (the first line after the banner and comments)."""
    with open_binary(path) as f:
        for lineno, raw in enumerate(f, 1):
            s = raw.decode("latin-1").strip()
            if lineno == 1 or not s or s.startswith("%"):
                continue
            try:
                return lineno, [int(t) for t in s.split()]
            except ValueError:
                raise ReadError(path, f"size line must hold integers 'rows cols entries', got {s[:60]!r}",
                                lineno) from None
    raise ReadError(path, "no size line after the %%MatrixMarket header: the file was cut off")


def _second_banner(path: Path) -> None:
    """Refuse a ``%%MatrixMarket`` line after the first line: read as a comment, it would hide that
    lines were repeated or two files joined (the size line after it read as an entry)."""
    lines, tail = 0, b""
    with open_binary(path) as f:
        while True:
            block = f.read(1 << 22)
            if not block:
                return
            buf = tail + block
            at = buf.lower().find(b"\n%%matrixmarket")
            if at >= 0:
                raise ReadError(path, "a second %%MatrixMarket header line: lines repeated, or two files joined?",
                                lines + buf.count(b"\n", 0, at) + 2)
            keep = len(b"\n%%matrixmarket") - 1
            lines += buf.count(b"\n", 0, len(buf) - keep)
            tail = buf[len(buf) - keep:]


def _check_order(path: Path, rows, cols, nr: int, nc: int) -> None:
    """Name an entry out of the order of the others in a file written in column or row order.

    Ansys and most writers give the entries sorted by column then row (or by row then column):
    in such a file an entry whose index was changed, or a line moved, is out of order. A file
    with more than three entries out of either order was written in its own order: nothing to
    tell.
    """
    if rows.size < 8:
        return
    best = None
    for major, minor, size in ((cols, rows, max(nr, 1)), (rows, cols, max(nc, 1))):
        down = _descents(major, minor, size)
        if not down.size:
            return
        if best is None or down.size < best[0].size:
            best = down, major, minor, size
    down, major, minor, size = best
    if down.size <= 3:
        k = int(down[0])  # the entry out of place: k when k + 1 follows k - 1 in order, else k + 1
        key = major[k - 1:k + 2].astype(np.int64) * size + minor[k - 1:k + 2]
        k += not (k > 0 and key[2] > key[0])
        warnings.warn(FlexmorWarning(f"{path.name}:{entry_line(path, k + 1)}: entry ({rows[k] + 1}, {cols[k] + 1}) "
                                     f"is out of the order of the other entries ({down.size} such): an index "
                                     "changed or a line moved?"), stacklevel=4)


def _descents(major, minor, size: int, stop: int = 3) -> np.ndarray:
    """Positions ``k`` where entry ``k + 1`` does not follow entry ``k`` in the order (major, minor), in slices
    (little memory); the scan ends after more than ``stop`` of them."""
    out = []
    step = 1 << 22
    for s in range(0, major.size - 1, step):
        e = min(s + step + 1, major.size)
        key = major[s:e].astype(np.int64) * size + minor[s:e]
        out.append(s + np.flatnonzero(key[1:] <= key[:-1]))
        if sum(x.size for x in out) > stop:
            break
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def _read_coordinate(path: Path, symmetric: bool) -> sp.csr_matrix:
    """Strict parser of a real coordinate file: sizes, indices, values and duplicates checked."""
    lineno, size = _size_line(path)
    if len(size) != 3 or min(size) < 0:
        raise ReadError(path, "size line must be 'rows cols entries' (three non-negative integers)", lineno)
    nr, nc, nnz = size
    fsize = size_hint(path) if not is_gzip(path) else path.stat().st_size * 1032  # deflate packs at most 1032:1
    if max(nr, nc) > MAX_DIM or nnz > fsize // 6 + 1 or (nnz and max(nr, nc) > 1000 * nnz + 10**6):
        raise ReadError(path, f"header claims a {nr} x {nc} matrix with {nnz} entries, which a "
                              f"{fsize}-byte file cannot hold; the size line is corrupt", lineno)
    idx = np.int32 if max(nr, nc) < 2**31 - 1 else np.int64
    rows, cols, vals = parse_triplets(path, index_dtype=idx)
    rows, cols, vals = rows[1:], cols[1:], vals[1:]  # the first 'triplet' is the size line
    if len(vals) != nnz:
        raise ReadError(path, f"header announces {nnz} entries but the file holds {len(vals)}"
                              + ("; the file is truncated (cut off)" if len(vals) < nnz else ""))
    if nnz and (min(rows.min(), cols.min()) < 0 or rows.max() >= nr or cols.max() >= nc):
        k = int(np.flatnonzero((rows < 0) | (cols < 0) | (rows >= nr) | (cols >= nc))[0])
        raise ReadError(path, f"entry ({rows[k] + 1}, {cols[k] + 1}) is out of bounds of the {nr} x {nc} matrix "
                              "(indices are 1-based)", entry_line(path, k + 1))
    _second_banner(path)
    _check_order(path, rows, cols, nr, nc)
    if symmetric and not np.all(rows >= cols):
        rows, cols = np.maximum(rows, cols), np.minimum(rows, cols)
    triplets = [rows, cols, vals]
    del rows, cols, vals
    A = assemble(triplets, (nr, nc), mirror=symmetric and nr == nc)  # a non-square one is refused by the caller
    if A is None:
        rows, cols, _ = parse_triplets(path)
        rows, cols = rows[1:], cols[1:]
        r, c = (np.maximum(rows, cols), np.minimum(rows, cols)) if symmetric else (rows, cols)
        key = r * max(nc, 1) + c
        order = np.argsort(key, kind="stable")
        k = int(order[np.flatnonzero(np.diff(key[order]) == 0)[0] + 1])
        raise ReadError(path, f"entry ({rows[k] + 1}, {cols[k] + 1}) appears twice; each entry once, please",
                        entry_line(path, k + 1))
    return A


def _read_one(path: Path, role: str) -> sp.csr_matrix:
    _check_header(path)
    with open_binary(path) as f:
        words = f.readline(200).decode("latin-1").lower().split()
    try:
        if words[2] == "coordinate":
            A = _read_coordinate(path, words[4] == "symmetric")
        else:
            lineno, size = _size_line(path)
            room = size_hint(path) if not is_gzip(path) else path.stat().st_size * 1032
            if len(size) != 2 or min(size) < 0 or size[0] * size[1] > room // 2 + 1:
                raise ReadError(path, f"array size line {size} does not fit the file; the size line is corrupt",
                                lineno)
            with open_binary(path) as f:
                A = scipy.io.mmread(f)
    except ReadError:
        raise
    except Exception as exc:  # noqa: BLE001 - any parser failure is a malformed file
        msg = str(exc).strip() or type(exc).__name__
        m = _LINE_MSG.match(msg)
        if m:
            raise ReadError(path, f"malformed Matrix Market data: {m.group(2)}", int(m.group(1))) from None
        raise ReadError(path, f"malformed Matrix Market file: {msg}") from None
    A = sp.csr_matrix(A, dtype=np.float64)
    if A.shape[0] != A.shape[1]:
        raise ReadError(path, f"{_ROLE_NAME[role]} matrix is {A.shape[0]} x {A.shape[1]}, expected square")
    bad = ~np.isfinite(A.data)
    if np.any(bad):
        coo = A.tocoo()
        k = int(np.flatnonzero(~np.isfinite(coo.data))[0])
        raise ReadError(path, f"non-finite value {coo.data[k]} at ({coo.row[k] + 1}, {coo.col[k] + 1})")
    return A


def read_matrix_market(path) -> FEModel:
    """Read a stiffness/mass (/damping) triple of Matrix Market files.

    Parameters
    ----------
    path : str or path-like
        The stiffness or the mass file; see the module docstring for the naming rule.

    Returns
    -------
    FEModel
        ``M``, ``K`` and ``D`` if present; no nodes. ``name`` is the common base of the
        file names.

    Raises
    ------
    ReadError
        Missing partner file, bad header or data (with line number where the parser knows
        it), non-square, non-finite or asymmetric matrices, sizes that disagree.
    """
    path = Path(path)
    _check_header(path)
    files = find_siblings(path)
    mats = {role: _read_one(p, role) for role, p in files.items()}
    _, head, tail = _role_of(stem(files["K"]))[0]
    base = (head.rstrip("_-. ") + tail) or files["K"].parent.name or "model"
    model = build_model(
        path,
        roles=files,
        M=mats["M"], K=mats["K"], D=mats.get("D"),
        damping={"type": "given"} if "D" in mats else {"type": "none"},
        name=base, source=str(path),
    )
    warn_unchecked(list(files.values()), "Matrix Market files hold each entry once and no node coordinates, so a "
                                         "value changed within its bounds or an entry moved to a free position "
                                         "could not be cross-checked")
    return model


MODEL_FORMATS.register("matrix-market", [".mtx", ".mm"], read_matrix_market, gzip=True,
                       description="Matrix Market pair <base>_K.mtx + <base>_M.mtx (+ <base>_D.mtx)")
