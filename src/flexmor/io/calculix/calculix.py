"""Reader of CalculiX matrix exports (``*FREQUENCY, SOLVER=MATRIXSTORAGE``).

CalculiX writes, for the job ``<job>.inp``:

* ``<job>.sti`` and ``<job>.mas``: stiffness and mass as ``row col value`` lines, 1-based,
  upper triangle only (``row <= col``), constrained degrees of freedom already removed;
* ``<job>.dof``: the equation map, one line per equation, ``node.direction`` (``12.3`` is
  node 12, z).

The main file is the ``.sti``; ``.mas``, ``.dof`` and the input deck ``.inp`` (node table
from ``*NODE``, node sets from ``*NSET`` and ``*NODE, NSET=...``) must lie beside it. Without
the deck, the node block of the job's result file ``<job>.frd`` gives the nodes (a warning is
logged; there are no node sets then): this is how a job is often shipped (``.sti/.mas/.dof/.frd``).
Shell and beam elements, which CalculiX expands to solids, need both the deck and the ``.frd``
(:mod:`flexmor.io.calculix.expanded`). The full
symmetric matrices are rebuilt as ``A = U + U^T - diag(U)``.

The files of a job are checked against each other: CalculiX writes the ``.sti`` and ``.mas`` on
one sparsity pattern (explicit zeros included) with every diagonal entry, so a file cut off at
a line end or with lines lost (which parses without a defect) shows as a difference in their
entry counts or positions, or as an equation of the ``.dof`` without its diagonal entry: all
refused. A ``.dof`` out of node order (CalculiX numbers the equations node by node) is read
with a :class:`~flexmor.errors.FlexmorWarning`, since swapped lines cannot be told from an edit.
A ``.dof`` cut off (fewer equations than both matrices have) is named as the file at fault.

Quadratic elements (``C3D20R``, ``C3D20``, ``C3D15``, ``C3D10``, 8-node shells and plane
elements, found in the ``*ELEMENT, TYPE=`` lines) can give a singular mass matrix (reduced
integration) or one with zero or negative diagonal entries (row-sum lumping of serendipity
elements). For such decks non-positive mass diagonals are a :class:`~flexmor.errors.FlexmorWarning`
instead of an error, and :func:`~flexmor.io._mass.check_mass` estimates the smallest
eigenvalue of ``M`` and warns when it is (near) zero; the warning says which methods still
work (:data:`flexmor.model.SINGULAR_MASS_NOTE`). For other element types a non-positive mass
diagonal remains an error.
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ...errors import FlexmorWarning, ReadError
from ...model import FEModel
from .._abaqus_materials import DeckElements
from .._build import build_model
from .._cells import build_mesh
from .._mass import QUADRATIC_TYPES, check_mass
from .._open import beside, is_gzip, open_binary, stem, suffix
from .._registry import MODEL_FORMATS
from .._sparse import assemble
from .._text import both, entry_line, parse_triplets, read_bytes, read_text
from .deck import read_inp
from .expanded import expanded_dofs
from .frd import read_frd

__all__ = ["read_calculix", "read_dof", "read_inp"]

log = logging.getLogger(__name__)


def _sibling(path: Path, suf: str, what: str) -> Path:
    """The file ``<job><suf>`` beside ``path``, plain or ``.gz`` (:func:`~flexmor.io._open.beside`)."""
    p = beside(path, suf)
    if p is None:
        raise ReadError(path.parent / f"{stem(path)}{suf}", f"not found (nor {stem(path)}{suf}.gz); CalculiX writes "
                        f"the {what} beside {path.name} (*FREQUENCY, SOLVER=MATRIXSTORAGE in {stem(path)}.inp)")
    return p


def _sniff(path: Path) -> None:
    """Refuse empty, binary or cut-off matrix files before parsing them.

    CalculiX ends every line with a line break; a last line without one was cut off while
    writing or copying, and its last number may look valid but be wrong (``5.16e+0`` of
    ``5.16e+09``). A ``.gz`` file is judged by the head of its content; its own end marker
    and checksum tell a cut-off copy of it (found while it is parsed).
    """
    try:
        with open_binary(path) as f:
            head = f.read(65536)
            if is_gzip(path):
                last = b"\n"
            else:
                f.seek(0, 2)
                size = f.tell()
                f.seek(max(size - 1, 0))
                last = f.read(1)
    except OSError as exc:
        raise ReadError(path, f"cannot read: {exc.strerror}") from None
    if not head.strip():
        read_text(path)  # raises "file is empty" unless data follows leading blank space
    if b"\x00" in head:
        raise ReadError(path, "looks like a binary file; CalculiX writes text with 'row col value' lines")
    if last not in (b"\n", b"\r"):
        with open_binary(path) as f:
            nlines = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 24), b"")) + 1
        raise ReadError(path, "last line has no line end: the file was cut off (disk full, interrupted "
                              "copy?); write it again with CalculiX", nlines)


def read_dof(path) -> np.ndarray:
    """Read a CalculiX ``.dof`` equation map.

    Returns
    -------
    ndarray of int64, shape (n_dof, 2)
        Node id and direction code (1..6) of each equation.

    Raises
    ------
    ReadError
        For a line that is not ``node.direction`` or a direction outside 1..6.
    """
    path = Path(path)
    raw = read_bytes(path).rstrip()
    out = _dof_fast(raw)
    if out is not None:
        return out
    lines = raw.decode("latin-1").splitlines()
    out = np.empty((len(lines), 2), dtype=np.int64)
    for i, line in enumerate(lines):
        s = line.strip()
        node, dot, d = s.partition(".")
        if not (dot and node.isascii() and node.isdigit() and d.isascii() and d.isdigit()):
            raise ReadError(path, f"expected 'node.direction' such as '12.3', got {s[:40]!r}", i + 1)
        out[i] = int(node), int(d)
        if not 1 <= out[i, 1] <= 6:
            extra = " (0 is temperature: flexmor needs a mechanical model)" if out[i, 1] == 0 else ""
            raise ReadError(path, f"direction {out[i, 1]} is not one of 1..6{extra}", i + 1)
    return out


_DOF_BYTES = np.zeros(256, dtype=bool)
_DOF_BYTES[list(b"0123456789. \t\r\n")] = True


def _dof_fast(raw: bytes):
    """The equation map of a well-formed ``.dof`` text, vectorized; None when a line needs a closer look."""
    lines = raw.count(b"\n") + 1
    if raw.count(b".") != lines or not _DOF_BYTES[np.frombuffer(raw, dtype=np.uint8)].all():
        return None
    try:
        a = np.fromstring(raw.replace(b".", b" "), dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if a.size != 2 * lines:
        return None
    a = a.reshape(-1, 2)
    if np.any((a[:, 1] < 1) | (a[:, 1] > 6)) or len(raw.split()) != lines:
        return None
    return a


def _read_upper(path: Path, n: int):
    """Read one upper-triangular CalculiX matrix file.

    Returns the full symmetric matrix, the number of entries read and whether each row has
    its diagonal entry (CalculiX writes every one, zero or not).
    """
    r, c, v = parse_triplets(path, one_based=True, n=n, index_dtype=np.int32 if n < 2**31 - 1 else np.int64)
    lower = np.flatnonzero(r > c)
    if lower.size:
        k = int(lower[0])
        raise ReadError(path, f"entry ({r[k] + 1}, {c[k] + 1}) lies below the diagonal; CalculiX "
                              "writes the upper triangle only, so the file is damaged or not from CalculiX",
                        entry_line(path, k))
    count = int(r.size)
    has_diag = np.zeros(n, dtype=bool)
    has_diag[r[r == c]] = True
    triplets = [r, c, v]
    del r, c, v
    A = assemble(triplets, (n, n), mirror=True)
    if A is None:
        r, c, _ = parse_triplets(path, one_based=True, n=n)
        key = c * np.int64(n) + r
        order = np.argsort(key, kind="stable")
        dup = np.flatnonzero(key[order][1:] == key[order][:-1])
        k, first = int(order[dup[0] + 1]), int(order[dup[0]])
        raise ReadError(path, f"entry ({r[k] + 1}, {c[k] + 1}) appears twice (also on line "
                              f"{entry_line(path, first)}); the file is damaged", entry_line(path, k))
    return A, count, has_diag


def _check_order(dof_path: Path, dofs: np.ndarray) -> None:
    """Warn when the equations of a ``.dof`` are not in node order.

    CalculiX numbers the equations node by node, directions ascending; lines out of that order
    were swapped or edited, which no other file of the job can confirm or refute.
    """
    key = dofs[:, 0] * 8 + dofs[:, 1]
    back = np.flatnonzero(key[1:] <= key[:-1])
    if back.size:
        i = int(back[0]) + 1
        warnings.warn(f"{dof_path}:{i + 1}: equation {dofs[i, 0]}.{dofs[i, 1]} follows {dofs[i - 1, 0]}."
                      f"{dofs[i - 1, 1]}, but CalculiX writes the equations in node order: lines may have been "
                      "swapped or edited, and the equation map could not be checked", FlexmorWarning, stacklevel=3)


def _check_deck(geo: Path, sti: Path, keywords: set) -> None:
    """Warn when a deck with elements lacks the ``*STEP`` of the job that wrote the matrices.

    CalculiX writes a ``.sti`` only in a step (``*FREQUENCY, SOLVER=MATRIXSTORAGE``): a deck
    with ``*ELEMENT`` but without ``*STEP`` was cut off inside or after its element blocks and
    lost what followed the cut (elements, node sets, materials). The matrices and the nodes read
    are complete, so the model is read. (A deck of nodes only is taken for a geometry deck
    written for the matrices; a job deck cut right after its node block looks the same.)
    """
    if "STEP" in keywords or "ELEMENT" not in keywords:
        return
    warnings.warn(f"{geo}: no *STEP, which the job that wrote {sti.name} had: the deck seems cut off inside or "
                  "after its element blocks; elements, node sets and materials after the cut are missing from the "
                  "model", FlexmorWarning, stacklevel=3)


def _check_diagonal(path: Path, has_diag: np.ndarray, dofs: np.ndarray, dof_path: Path) -> None:
    """Refuse a matrix file without a diagonal entry for an equation of the ``.dof``.

    CalculiX writes every diagonal entry; one missing means the file was cut off or the
    ``.dof`` (its rows, the matrix dimension) belongs to another job.
    """
    if has_diag.all():
        return
    n = has_diag.size
    missing = np.flatnonzero(~has_diag)
    i = int(missing[0])
    tail = missing[-1] == n - 1 and missing.size == n - i
    more = (" nor for any later one" if i < n - 1 else "") if tail else f" and {missing.size - 1} more"
    raise ReadError(path, f"no diagonal entry for equation {i + 1} (node {dofs[i, 0]}, direction {dofs[i, 1]} in "
                          f"{dof_path.name}){more}; CalculiX writes every diagonal entry, so the file is cut off or "
                          f"{dof_path.name} ({n} equations) is from another job")


def _same_pattern(sti: Path, K: sp.csr_matrix, nk: int, mas: Path, M: sp.csr_matrix, nm: int, k_diag, m_diag,
                  dofs, dof_path) -> None:
    """Refuse a ``.sti`` and ``.mas`` whose entries differ: CalculiX writes both on one sparsity pattern.

    A line missing from either file (cut off at a line end, a lost line) shows as a count or
    pattern mismatch; without this check a cut stiffness file reads as a model with spurious
    rigid-body modes.
    """
    if nk != nm:
        short, other, few, many = (sti, mas, nk, nm) if nk < nm else (mas, sti, nm, nk)
        raise ReadError(short, f"{few} matrix entries, but {other.name} has {many}: CalculiX writes the stiffness "
                               f"and mass of a job on one pattern, so {short.name} is cut off or lines are missing; "
                               "write it again with CalculiX")
    _check_diagonal(sti, k_diag, dofs, dof_path)
    _check_diagonal(mas, m_diag, dofs, dof_path)
    if np.array_equal(K.indptr, M.indptr) and np.array_equal(K.indices, M.indices):
        return
    rows = np.flatnonzero(K.indptr != M.indptr)
    if rows.size:
        i = max(int(rows[0]) - 1, 0)
    else:
        i = int(np.searchsorted(K.indptr, np.flatnonzero(K.indices != M.indices)[0], side="right")) - 1
    raise ReadError(sti, f"the entries of row {i + 1} are not at the positions of those of {mas.name} (same "
                         "count): CalculiX writes the stiffness and mass of a job on one pattern, so one of the "
                         "files is damaged or they are from different jobs")


def _dof_too_short(sti: Path, mas: Path, dof_path: Path, n: int, exc: ReadError) -> ReadError | None:
    """The error naming a ``.dof`` cut off, ``exc`` (an index of a matrix file beyond its ``n`` equations) as
    the evidence: both matrix files have entries beyond them, up to the same equation (a single damaged index
    is the matrix file's defect, named by ``exc``); None otherwise."""
    if "beyond the matrix size" not in exc.reason:
        return None
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():  # an index beyond 64 bits: the matrix's defect
            warnings.simplefilter("ignore")
            top = [int(max(r.max(), c.max())) + 1 for r, c, _ in (parse_triplets(p, one_based=True)
                                                                   for p in (sti, mas))]
    except (ReadError, ValueError, OverflowError):
        return None
    if top[0] != top[1] or top[0] <= n:
        return None
    first = f"{Path(exc.path).name}:{exc.line}: " if exc.line else ""
    return ReadError(dof_path, f"{n} equations, but {sti.name} and {mas.name} have entries up to equation {top[0]} "
                               f"({first}{exc.reason}): the .dof seems cut off (or is from another job); write it "
                               "again with CalculiX")


def _geometry_file(path: Path) -> Path:
    """The input deck ``<job>.inp`` beside ``path``, else the result file ``<job>.frd`` (its node block);
    each plain or ``.gz``."""
    for suf in (".inp", ".frd"):
        p = beside(path, suf)
        if p is not None:
            return p
    raise ReadError(path.parent / f"{stem(path)}.inp", f"not found; the input deck with the nodes (*NODE) must lie "
                                                       f"beside {path.name} (or, without it, the job's "
                                                       f"{stem(path)}.frd with its node block)")


def read_calculix(path) -> FEModel:
    """Read a CalculiX ``.sti`` file with its ``.mas``, ``.dof`` and ``.inp`` siblings.

    Parameters
    ----------
    path : str or path-like
        The stiffness file ``<job>.sti``, or ``<job>.sti.gz``: every file of the job may be
        gzip-compressed (found as ``<job>.mas`` or ``<job>.mas.gz`` ...), decompressed while parsed.

    Returns
    -------
    FEModel
        Full symmetric ``M`` and ``K``, node table, node sets, element connectivity
        (``mesh``, elements as written in the deck) and the elements with their materials
        (``elements``: ``*MATERIAL``, ``*ELASTIC``, ``*DENSITY``, ``*SOLID SECTION``,
        ``*SHELL SECTION``) from the ``.inp`` (without it: node table
        from the ``.frd``, no node sets, no mesh), the equation map from the ``.dof``;
        ``name`` is the file stem.

    Raises
    ------
    ReadError
        Missing sibling files, malformed lines (with line number), lower-triangle or
        duplicate entries, equations on nodes the ``.inp`` does not define.
    """
    path = Path(path)
    if suffix(path) in (".mas", ".dof", ".inp"):
        raise ReadError(path, f"pass the stiffness file {stem(path)}.sti; the other files are found beside it")
    _sniff(path)
    mas = _sibling(path, ".mas", "mass matrix")
    dof_path = _sibling(path, ".dof", "equation map")
    geo = _geometry_file(path)
    dofs = read_dof(dof_path)
    n = dofs.shape[0]
    _sniff(mas)
    try:
        (K, nk, k_diag), (M, nm, m_diag) = both(lambda f: _read_upper(f, n), path, mas)
    except ReadError as exc:
        raise (_dof_too_short(path, mas, dof_path, n, exc) or exc) from None
    _same_pattern(path, K, nk, mas, M, nm, k_diag, m_diag, dofs, dof_path)
    types: set = set()
    cells: list = []
    deck_elements = DeckElements()
    if suffix(geo) == ".inp":
        keywords: set = set()
        node_ids, xyz, sets = read_inp(geo, element_types=types, cells=cells, elements=deck_elements,
                                       keywords=keywords)
        _check_deck(geo, path, keywords)
    else:
        res = read_frd(geo, results=False)
        node_ids, xyz, sets, types = res.node_ids, res.xyz, {}, res.element_types
        log.warning("%s: no input deck %s beside it; nodes read from the node block of %s (no node sets)",
                    path, f"{stem(path)}.inp", geo.name)
    if np.unique(dofs[:, 0] * 8 + dofs[:, 1]).size < n:  # shells or beams expanded to solids
        frd = beside(path, ".frd")
        if suffix(geo) != ".inp" or frd is None:
            raise ReadError(dof_path, "equations name nodes repeatedly, as when CalculiX expands shell or beam "
                                      f"elements to solids: {stem(path)}.inp and {stem(path)}.frd (with the expanded "
                                      "nodes, from *NODE FILE output) must both lie beside it")
        res = read_frd(frd, results=False)
        deck_ids, deck_xyz = node_ids, xyz
        dofs, node_ids, xyz, sets = expanded_dofs(dof_path, dofs, node_ids, xyz, res.node_ids, res.xyz, sets)
        types |= res.element_types
        if cells:  # the mesh shows the shells and beams as written: keep their (equation-less) deck nodes
            used = np.isin(deck_ids, np.concatenate([c.ravel() for _, c in cells]))
            node_ids, xyz = np.concatenate([node_ids, deck_ids[used]]), np.concatenate([xyz, deck_xyz[used]])
    else:
        _check_order(dof_path, dofs)
    quadratic = sorted(t for t in types if t.startswith(QUADRATIC_TYPES))
    known = np.isin(dofs[:, 0], node_ids)
    if not np.all(known):
        i = int(np.flatnonzero(~known)[0])
        raise ReadError(dof_path, f"equation {i + 1} is on node {dofs[i, 0]}, which {geo.name} does not define; "
                                  f"are the .dof and {suffix(geo)} from the same job?", i + 1)
    model = build_model(
        path,
        roles={"M": mas, "K": path},
        M=M, K=K, node_ids=node_ids, xyz=xyz, dofs=dofs, node_sets=sets, mesh=build_mesh(cells, "abaqus"),
        elements=deck_elements.elements(geo), name=stem(path), source=str(path), singular_mass_ok=bool(quadratic),
    )
    if quadratic and np.all(M.diagonal() > 0):
        check_mass(model, f"{mas} ({', '.join(quadratic)} elements)")
    return model


MODEL_FORMATS.register("calculix", [".sti"], read_calculix, gzip=True,
                       description="CalculiX *FREQUENCY, SOLVER=MATRIXSTORAGE export "
                       "(.sti + .mas + .dof + .inp or .frd)")
