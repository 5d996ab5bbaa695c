"""Readers of Ansys matrix exports: Matrix Market (HBMAT/MMF) sets and binary ``.full`` files.

Matrix Market set (``.txt`` or ``.mtx``; pass the stiffness or the mass file)
    ``<base>Stiffness....txt`` + ``<base>Mass....txt`` (found as in
    :mod:`flexmor.io.matrix_market`), plus, beside them and starting with ``<base>``:

    * the equation map, either the *mapping vector* (a file whose name contains
      ``mapping``: Matrix Market ``array integer``, one node number per block of ``d``
      equations, ``d = n_eq / length``: 3 means UX UY UZ, 6 adds ROTX ROTY ROTZ; block ``i``
      holds equations ``d*i+1 .. d*i+d`` of node ``vector[i]``) or an HBMAT ``.mapping``
      file (``Matrix Eqn  Node  DOF`` lines with labels ``UX UY UZ ROTX ROTY ROTZ``);
    * the nodal coordinates (a name containing ``coord``, ``knoten`` or ``node``): a
      header line, then ``node  x  y  z`` separated by tabs or semicolons, decimal points or
      decimal commas (the German Workbench export ``Knotennummer  X-Position (m) ...``).

    Without a map the model has no nodes (like plain Matrix Market), and without the
    coordinates its nodes have no position; a FlexmorWarning names the missing file (as
    ``<base>MatrixDofMappingVector.txt`` and ``<base>NodalCoordinates.txt``, the names of the
    export). A missing stiffness or mass partner is named with the case of the export.
Binary ``.full`` (``ansys-mapdl-reader``, optional: ``pip install flexmor[ansys]``)
    Upper triangles are expanded; constrained DOFs (zero rows and columns) are removed, logged
    and listed in ``model.constrained_dofs`` (k, 2: node, direction). Coordinates and node
    components and the element connectivity (``model.mesh``) come from ``<stem>.cdb`` beside it
    or ``coordinates=``, and so do the solid elements with their materials (``model.elements``:
    ``MP,EX/PRXY/DENS`` or ``MPDATA`` of isotropic materials; the solids named by the CalculiX
    element of the same shape, ``SOLID186`` bricks as ``C3D20R``).

In both, equations with neither stiffness nor mass are removed and reported. Units are those
of the Ansys model. The files of a Matrix Market set may be gzip-compressed (``.txt.gz``);
``.full`` and ``.cdb`` files are read by ansys-mapdl-reader from their file name, so they must
be uncompressed.
"""

from __future__ import annotations

import logging
import re
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ...elements import ElementBlock, Elements, Material
from ...errors import FlexmorWarning, ModelError, ReadError
from ...model import FEModel
from .._build import build_model
from .._cells import ansys_cell, build_mesh
from .._open import beside, is_gzip, stem, suffix
from .._registry import MODEL_FORMATS
from .._sparse import rows_in_use
from .._text import read_text
from .._unchecked import warn_unchecked
from ..matrix_market.matrix_market import _check_header, _read_one, find_siblings

__all__ = ["read_ansys", "read_mapping", "read_coordinates"]

log = logging.getLogger(__name__)

#: Why a compressed ``.full`` or ``.cdb`` file is refused.
_BY_NAME = "ansys-mapdl-reader reads .full and .cdb files from their name, uncompressed"
_DOF_LABELS = {"UX": 1, "UY": 2, "UZ": 3, "ROTX": 4, "ROTY": 5, "ROTZ": 6}


def read_mapping(path, n_eq: int) -> np.ndarray:
    """Read an Ansys equation map (mapping vector or HBMAT ``.mapping`` file).

    Parameters
    ----------
    path : str or path-like
    n_eq : int
        Number of equations of the matrices.

    Returns
    -------
    ndarray of int64, shape (n_eq, 2)
        Node and direction code (1..6) of each equation.

    Raises
    ------
    ReadError
        Malformed lines, a length that does not divide ``n_eq``, unknown DOF labels,
        equation numbers outside ``1..n_eq``.

    Warns
    -----
    UncheckedWarning
        For a mapping vector: it has no equation numbers, so swapped lines cannot be seen.
    """
    path = Path(path)
    text = read_text(path)
    fast = _mapping_fast(path, text, n_eq)
    if fast is not None:
        return fast
    lines = text.splitlines()
    data = [(k, s.strip()) for k, s in enumerate(lines, 1) if s.strip() and not s.lstrip().startswith("%")]
    if data and len(data[0][1].split()) >= 3 and not data[0][1].split()[0].lstrip("-").isdigit():
        data = data[1:]  # header "Matrix Eqn  Node  DOF"
    if not data:
        raise ReadError(path, "no equation map entries found")
    if len(data[0][1].split()) == 3:  # HBMAT .mapping: eqn node label
        out = np.zeros((n_eq, 2), dtype=np.int64)
        for lineno, s in data:
            t = s.split()
            if len(t) != 3 or not (t[0].isdigit() and t[1].isdigit()):
                raise ReadError(path, f"expected 'equation node DOF' such as '7 3 UX', got {s[:60]!r}", lineno)
            eq, node, lab = int(t[0]), int(t[1]), t[2].upper()
            if not 1 <= eq <= n_eq:
                raise ReadError(path, f"equation {eq} outside 1..{n_eq} of the matrices", lineno)
            if lab not in _DOF_LABELS:
                raise ReadError(path, f"DOF {lab} is not one of {' '.join(_DOF_LABELS)}", lineno)
            out[eq - 1] = node, _DOF_LABELS[lab]
        if np.any(out[:, 1] == 0):
            raise ReadError(path, f"equation {int(np.flatnonzero(out[:, 1] == 0)[0]) + 1} is missing from the map")
        return out
    (hl, head), body = data[0], data[1:]
    h = head.split()
    if len(h) != 2 or not all(x.isdigit() for x in h) or h[1] != "1":
        raise ReadError(path, f"expected the Matrix Market array size 'n 1', got {head[:60]!r}", hl)
    nodes = []
    for lineno, s in body:
        if not (s.isascii() and s.isdigit()):
            raise ReadError(path, f"expected one node number per line, got {s[:60]!r}", lineno)
        if len(s) > 15:
            raise ReadError(path, f"node number {s[:30]} is too large", lineno)
        nodes.append(int(s))
    if len(nodes) != int(h[0]):
        raise ReadError(path, f"header announces {h[0]} entries but {len(nodes)} follow; is the file truncated?",
                        body[-1][0] if body else hl)
    nodes = np.asarray(nodes, dtype=np.int64)
    if nodes.size == 0 or n_eq % nodes.size or n_eq // nodes.size not in (1, 2, 3, 6):
        raise ReadError(path, f"{nodes.size} nodes do not fit {n_eq} equations (1, 2, 3 or 6 DOFs per node)")
    d = n_eq // nodes.size
    _unchecked_vector(path)
    return np.stack([np.repeat(nodes, d), np.tile(np.arange(1, d + 1), nodes.size)], axis=1)


def _unchecked_vector(path) -> None:
    warn_unchecked(path, "an Ansys mapping vector has no equation numbers; the order of its lines (which node "
                         "owns which equations) could not be cross-checked")


_EQ_LINES = re.compile(r"(?:[ \t]*\d{1,15}[ \t]+\d{1,15}[ \t]+[1-6][ \t]*(?:\r?\n|\Z))+")
_NODE_LINES = re.compile(r"(?:[ \t]*\d{1,15}[ \t]*(?:\r?\n|\Z))+")
_XYZ_LINES = re.compile(r"(?:[ ]*\d{1,15}(?:[ ]+[-+.0-9eE]+){3}[ ]*(?:\r?\n|\Z))+")


def _body(text: str, header) -> tuple[int, str] | None:
    """``(lines before, text after)`` the leading comment lines and the header line ``header(first)`` tells."""
    pos = lines = 0
    while True:
        end = text.find("\n", pos)
        line = text[pos:len(text) if end < 0 else end]
        if line.strip() and not line.lstrip().startswith("%"):
            break
        if end < 0:
            return None
        pos, lines = end + 1, lines + 1
    if header(line.split()):
        pos, lines = (len(text) if end < 0 else end + 1), lines + 1
    body = text[pos:].rstrip()
    return (lines, body) if body else None


def _ints(body: str, pattern, width: int) -> np.ndarray | None:
    """The integers of ``body`` as (lines, width) when every line matches ``pattern``, else None."""
    if pattern.fullmatch(body) is None:
        return None
    a = np.fromstring(body, dtype=np.int64, sep=" ")
    return a.reshape(-1, width) if a.size % width == 0 else None


def _mapping_fast(path, text: str, n_eq: int) -> np.ndarray | None:
    """The equation map of a well-formed map file, vectorized; None leaves it to the line-by-line parser."""
    got = _body(text, lambda t: len(t) >= 3 and not t[0].lstrip("-").isdigit())
    if got is None:
        return None
    body = got[1]
    first = body.split("\n", 1)[0].split()
    if len(first) == 3:  # HBMAT .mapping: eqn node label
        for lab, code in (("ROTX", "4"), ("ROTY", "5"), ("ROTZ", "6"), ("UX", "1"), ("UY", "2"), ("UZ", "3")):
            body = body.replace(lab, code)
        a = _ints(body, _EQ_LINES, 3)
        if a is None or a.shape[0] != n_eq or not np.array_equal(np.sort(a[:, 0]), np.arange(1, n_eq + 1)):
            return None
        out = np.empty((n_eq, 2), dtype=np.int64)
        out[a[:, 0] - 1] = a[:, 1:]
        return out
    head, _, rest = body.partition("\n")
    h = head.split()
    a = _ints(rest.strip(), _NODE_LINES, 1)
    if a is None or h != [str(a.shape[0]), "1"] or n_eq % a.shape[0] or n_eq // a.shape[0] not in (1, 2, 3, 6):
        return None
    d = n_eq // a.shape[0]
    _unchecked_vector(path)
    return np.stack([np.repeat(a[:, 0], d), np.tile(np.arange(1, d + 1), a.shape[0])], axis=1)


def _coordinates_fast(text: str):
    """``(node ids, xyz)`` of a well-formed coordinate table, vectorized; None leaves it to the line parser."""
    got = _body(text, lambda t: not t[0].isdigit())
    if got is None:
        return None
    body = got[1]
    if "\t" in body or ";" in body:
        body = body.replace(",", ".").replace("\t", " ").replace(";", " ")
    elif body.split("\n", 1)[0].count(",") >= 3:
        body = body.replace(",", " ")
    if _XYZ_LINES.fullmatch(body) is None:
        return None
    try:
        a = np.fromstring(body, sep=" ")
    except ValueError:
        return None
    if a.size % 4 or a.size != 4 * (body.count("\n") + 1) or not np.all(np.isfinite(a)):
        return None
    a = a.reshape(-1, 4)
    return a[:, 0].astype(np.int64), np.ascontiguousarray(a[:, 1:])


def read_coordinates(path):
    """Read a nodal-coordinate table (header line, then ``node x y z``; tabs/semicolons, decimal commas).

    Returns
    -------
    node_ids : ndarray of int64
    xyz : ndarray of float64, shape (n, 3)
    """
    path = Path(path)
    text = read_text(path)
    fast = _coordinates_fast(text)
    if fast is not None:
        return fast
    lines = text.splitlines()
    ids, xyz = [], []
    for lineno, raw in enumerate(lines, 1):
        s = raw.strip()
        if not s:
            continue
        if "\t" in s or ";" in s:
            t = [x.strip().replace(",", ".") for x in re.split(r"[\t;]", s) if x.strip()]
        else:
            t = s.replace(",", " ").split() if s.count(",") >= 3 else s.split()
        if lineno == 1 and not t[0].isdigit():
            continue  # header (e.g. "Knotennummer  X-Position (m) ...")
        if len(t) != 4 or not t[0].isdigit():
            raise ReadError(path, f"expected 'node x y z', got {s[:60]!r}", lineno)
        try:
            c = [float(x) for x in t[1:]]
        except ValueError:
            raise ReadError(path, f"non-numeric coordinate in {s[:60]!r}", lineno) from None
        if not np.all(np.isfinite(c)):
            raise ReadError(path, "non-finite coordinate", lineno)
        ids.append(int(t[0]))
        xyz.append(c)
    if not ids:
        raise ReadError(path, "no node lines found")
    return np.asarray(ids, dtype=np.int64), np.asarray(xyz, dtype=np.float64)


def _companions(stiff: Path):
    """Mapping and coordinate files beside an MMF stiffness file (None when absent)."""
    m = re.search(r"stiff", stem(stiff), re.I)
    base = stem(stiff)[: m.start()].lower() if m else stem(stiff).lower()
    mapping = coords = None
    for p in sorted(stiff.parent.iterdir()):
        low = p.name.lower()
        if not p.is_file() or not low.startswith(base) or p == stiff:
            continue
        if "mapping" in low and mapping is None:
            mapping = p
        elif any(w in low for w in ("coord", "knoten", "node")) and coords is None:
            coords = p
    return mapping, coords


def _partner(path: Path) -> tuple[str, str, Path] | None:
    """``(role, other role, file)``: the other matrix file of an MMF pair as the export names it
    (``rotorAnsysMassMatrixSparse.txt`` for ``rotorAnsysStiffnessMatrixSparse.txt``: the word swapped in the
    case it is written in), or None."""
    name = stem(path)
    m = list(re.finditer(r"stiffness|stiff|stif|mass", name, re.I))
    if not m:
        return None
    word = m[-1].group()
    role, other = ("stiffness", "mass") if word.lower().startswith("stif") else ("mass", "stiffness")
    written = other.upper() if word.isupper() else other.capitalize() if word[0].isupper() else other
    return role, other, path.parent / f"{name[:m[-1].start()]}{written}{name[m[-1].end():]}{suffix(path)}"


def _siblings(path: Path) -> dict:
    """:func:`~flexmor.io.matrix_market.find_siblings`; a missing partner is named as the Ansys export names
    it (the Matrix Market reader names the candidates it tried in lower case)."""
    try:
        return find_siblings(path)
    except ReadError:
        got = _partner(path)
        if got is None:
            raise
        role, other, want = got
        names = {p.name.lower() for p in path.parent.iterdir()}
        if want.name.lower() in names or f"{want.name}.gz".lower() in names:
            raise
        raise ReadError(want, f"not found (nor {want.name}.gz): {path.name} was read as the {role} matrix, and the "
                              f"Ansys export writes the {other} matrix beside it") from None


def _missing_companion(stiff: Path, what: str, name: str, words: str, lost: str) -> None:
    """Warn that the ``what`` file (``<base><name>``, or any ``<base>*<words>*``) is not beside ``stiff``."""
    m = re.search(r"stiff", stem(stiff), re.I)
    base = stem(stiff)[: m.start()] if m else stem(stiff)
    warnings.warn(FlexmorWarning(f"{stiff.parent / (base + name + suffix(stiff))}: not found (nor another "
                                 f"{base}*{words}* file) beside {stiff.name}: without the {what}, {lost}"),
                  stacklevel=3)


def _drop_empty(path, mats, dofs, what="without stiffness and mass"):
    used = rows_in_use(mats["K"]) | rows_in_use(mats["M"])
    if np.all(used):
        return mats, dofs, np.zeros((0, 2), dtype=np.int64)
    keep = np.flatnonzero(used)
    gone = dofs[~used] if dofs is not None else np.stack([np.flatnonzero(~used) + 1, np.zeros(int((~used).sum()),
                                                                                               np.int64)], axis=1)
    log.info("%s: removed %d equations %s (first: %s)", path, gone.shape[0], what, gone[:3].tolist())
    return {k: A[keep][:, keep] for k, A in mats.items()}, (dofs[keep] if dofs is not None else None), gone


def _read_mmf(path: Path):
    _check_header(path)
    files = _siblings(path)
    mats = {role: _read_one(p, role) for role, p in files.items()}
    n = mats["K"].shape[0]
    mapping, coords = _companions(files["K"])
    if mapping is None:
        _missing_companion(files["K"], "equation map", "MatrixDofMappingVector", "mapping",
                           "the equations cannot be tied to nodes, so the model has no nodes (no coordinates, node "
                           "sets or ports by node)")
    elif coords is None:
        _missing_companion(files["K"], "nodal coordinates", "NodalCoordinates", "coord",
                           "the model has no node positions (the nodes of the equation map are left out)")
    dofs = read_mapping(mapping, n) if mapping else None
    node_ids, xyz = (read_coordinates(coords) if coords else (np.zeros(0, np.int64), np.zeros((0, 3))))
    if dofs is None:
        log.info("%s: no equation map beside it; the model has no nodes", path)
        node_ids, xyz = np.zeros(0, np.int64), np.zeros((0, 3))
    elif node_ids.size:
        miss = ~np.isin(dofs[:, 0], node_ids)
        if np.any(miss):
            raise ReadError(mapping, f"node {dofs[np.flatnonzero(miss)[0], 0]} is not in {coords.name}")
    mats, dofs, _ = _drop_empty(path, mats, dofs)
    return build_model(path, roles=files, M=mats["M"], K=mats["K"], D=mats.get("D"),
                       damping={"type": "given"} if "D" in mats else {"type": "none"},
                       node_ids=node_ids, xyz=xyz, dofs=dofs,
                       name=re.split(r"stiff", stem(files["K"]), flags=re.I)[0] or stem(files["K"]),
                       source=str(path))


def _read_full(path: Path, coordinates=None):
    try:
        from ansys.mapdl.reader import read_binary
    except ImportError:
        raise ReadError(path, "binary .full files need ansys-mapdl-reader: pip install 'flexmor[ansys]'") from None
    _check_records(path)
    dof_ref, k, m = _isolated(path, lambda: _load_km(path, read_binary))
    if dof_ref is None or k is None or m is None:
        raise ReadError(path, "the .full file holds no stiffness and mass matrices")
    dofs = np.asarray(dof_ref, dtype=np.int64).copy()
    dofs[:, 1] += 1
    if np.any((dofs[:, 1] < 1) | (dofs[:, 1] > 6)):
        raise ReadError(path, "the .full file has non-mechanical DOFs (temperature, pressure ...)")
    mats = {}
    for role, U in (("K", k), ("M", m)):
        U = sp.csr_matrix(U, dtype=np.float64)
        lower = sp.tril(U, -1)
        if lower.nnz and sp.triu(U, 1).nnz:
            mats[role] = U  # already full
        else:
            mats[role] = (U + U.T - sp.diags(U.diagonal())).tocsr()
    mats, dofs, gone = _drop_empty(path, mats, dofs, "constrained (zero rows and columns)")
    node_ids, xyz, sets, mesh, elements = np.zeros(0, np.int64), np.zeros((0, 3)), {}, None, None
    cdb = Path(coordinates) if coordinates else (beside(path, ".cdb") or path.with_suffix(".cdb"))
    if cdb.exists():
        if is_gzip(cdb):
            raise ReadError(cdb, f"gzip-compressed: {_BY_NAME}; decompress it first (gunzip {cdb.name})")
        node_ids, xyz, sets, mesh, elements = _read_cdb(cdb)
    elif coordinates:
        raise ReadError(cdb, "coordinate file not found")
    model = build_model(path, roles={"K": path, "M": path}, M=mats["M"], K=mats["K"], node_ids=node_ids, xyz=xyz,
                        dofs=dofs, node_sets=sets, mesh=mesh, elements=elements, name=stem(path), source=str(path))
    model.constrained_dofs = gone
    warn_unchecked(path, "an Ansys .full file has no checksum; the values in its matrix records were read as given "
                         "and could not be cross-checked")
    return model


def _load_km(path: Path, read_binary):
    """``(dof_ref, K, M)`` of a ``.full`` file by ansys-mapdl-reader (None for what it lacks)."""
    try:
        full = read_binary(str(path))
        if not hasattr(full, "load_km"):
            return None, None, None
        dof_ref, k, m = full.load_km(as_sparse=True, sort=False)
        if k is not None and m is not None:  # indices outside the matrix crash scipy's compiled routines later
            for A in (k, m):
                A.check_format(full_check=True)
            if dof_ref is None or not (k.shape[0] == k.shape[1] == m.shape[0] == m.shape[1] == len(dof_ref)):
                raise ValueError(f"matrices of {k.shape} and {m.shape} for {len(dof_ref)} DOFs")
    except Exception as exc:  # noqa: BLE001 - the library raises many kinds on damaged files
        raise ReadError(path, f"not a readable Ansys .full file ({type(exc).__name__}: {str(exc)[:120]})") from None
    return dof_ref, k, m


def _isolated(path: Path, load):
    """``load()`` (``(dof_ref, K, M)``) in a forked child process, so that a damaged file crashing the
    compiled reader is a ReadError.

    ansys-mapdl-reader trusts the sizes and indices in the file: a damaged byte deep in a
    matrix record can make it write outside its arrays (a segmentation fault, or a heap
    corrupted for whatever runs next). The child sends the arrays back through a pipe in NumPy's
    ``.npy`` format; where ``fork`` is not available the reader runs in this process.
    """
    import io
    import os
    import signal

    if not hasattr(os, "fork"):
        return load()
    rd, wr = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: load, hand over, leave without cleanup handlers
        code = 0
        try:
            os.close(rd)
            try:
                dof_ref, k, m = load()
                if dof_ref is None or k is None or m is None:
                    arrays = [np.frombuffer(b"none", np.uint8)]
                else:
                    k, m = sp.csr_matrix(k), sp.csr_matrix(m)
                    arrays = [np.frombuffer(b"ok", np.uint8), np.asarray(dof_ref)]
                    arrays += [x for A in (k, m) for x in (A.data, A.indices, A.indptr, np.asarray(A.shape))]
            except ReadError as exc:
                arrays = [np.frombuffer(b"error:" + exc.reason.encode(), np.uint8)]
            buf = io.BytesIO()
            for x in arrays:
                np.lib.format.write_array(buf, np.ascontiguousarray(x), allow_pickle=False)
            data = buf.getbuffer()
            while data:  # a pipe, not a file
                data = data[os.write(wr, data):]
        except BaseException:  # noqa: BLE001 - nothing may escape the child
            code = 1
        finally:
            os._exit(code)
    os.close(wr)
    with os.fdopen(rd, "rb") as f:
        data = f.read()
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status) or os.WEXITSTATUS(status) or not data:
        how = (f"signal {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
               else f"exit code {os.WEXITSTATUS(status)}")
        raise ReadError(path, f"the Ansys .full reader failed on this file ({how}): the file is damaged or "
                              "not a complete .full file; write it again with Ansys")
    buf = io.BytesIO(data)
    status = np.lib.format.read_array(buf, allow_pickle=False).tobytes()
    if status.startswith(b"error:"):
        raise ReadError(path, status[6:].decode())
    if status == b"none":
        return None, None, None
    dof_ref = np.lib.format.read_array(buf, allow_pickle=False)
    mats = []
    for _ in range(2):
        d, i, p, shape = (np.lib.format.read_array(buf, allow_pickle=False) for _ in range(4))
        mats.append(sp.csr_matrix((d, i, p), shape=tuple(int(x) for x in shape)))
    return dof_ref, mats[0], mats[1]


def _check_records(path: Path) -> None:
    """Walk the record structure of an Ansys binary file before the C reader sees it.

    Every record is ``[n][flags] n words [n]``; a record running past the end of the file
    means the file was cut off. ansys-mapdl-reader aborts the whole process on such files,
    so they are refused here.
    """
    raw = path.read_bytes()
    if len(raw) < 412 or len(raw) % 4:
        raise ReadError(path, f"{len(raw)} bytes is not an Ansys binary file (truncated?)")
    w = np.frombuffer(raw, dtype="<i4")
    if w[0] != 100 or w[102] != 100:
        raise ReadError(path, "no Ansys binary header (first record of 100 words); not a .full file")
    off, count = 0, 0
    while off < w.size:
        n = int(w[off])
        if n == -1 and count > 2:
            return  # end of data; the rest is block padding
        end = off + 2 + n
        if n < 0 or off + 1 >= w.size or end >= w.size or int(w[end]) != n:
            raise ReadError(path, f"record {count + 1} at byte {4 * off} is broken or runs past the end of the "
                                  "file: the file is truncated or damaged; write it again with Ansys")
        off, count = end + 1, count + 1


def _read_cdb(path: Path):
    from ansys.mapdl.reader import Archive

    try:
        a = Archive(str(path), read_parameters=False, parse_vtk=False)
    except Exception as exc:  # noqa: BLE001 - the reader library raises many kinds on a damaged archive
        raise ReadError(path, f"not a readable Ansys archive ({type(exc).__name__}: {str(exc)[:120]})") from None
    sets = {str(k).upper(): np.asarray(v, dtype=np.int64) for k, v in dict(a.node_components).items()}
    types = {int(k): int(v) for k, v in np.asarray(a.ekey, dtype=np.int64).reshape(-1, 2)}
    groups: dict = {}
    solids: dict = {}
    enum = np.asarray(a.enum, dtype=np.int64)
    for k, row in enumerate(a.elem):  # 10 attribute fields (material, type, ...), then the nodes
        etype = types.get(int(row[1]), 0)
        got = ansys_cell(etype, np.asarray(row[10:], dtype=np.int64).tolist())
        if got is not None:
            groups.setdefault(got[0], []).append(got[1])
            name = _SOLIDS.get((etype in (186, 95), got[0]))
            if name is not None:
                solids.setdefault(name, []).append((int(enum[k]), int(row[0]), got[1]))
    mesh = build_mesh([(t, np.asarray(rows, dtype=np.int64)) for t, rows in groups.items()], "vtk")
    return (np.asarray(a.nnum, dtype=np.int64), np.asarray(a.nodes, dtype=np.float64)[:, :3], sets, mesh,
            _elements(path, solids))


#: CalculiX element of each Ansys solid shape: ``(SOLID186/SOLID95, meshio cell type)`` -> name. SOLID186
#: integrates its bricks with 2 x 2 x 2 points by default (``KEYOPT(2) = 0``), as C3D20R.
_SOLIDS = {(False, "hexahedron"): "C3D8", (False, "tetra"): "C3D4", (False, "wedge"): "C3D6",
           (True, "hexahedron20"): "C3D20R", (True, "tetra10"): "C3D10", (True, "wedge15"): "C3D15",
           (False, "tetra10"): "C3D10"}


def _mp_commands(path: Path) -> dict:
    """``{material: {label: value}}`` of the ``MP,Lab,MAT,C0`` and ``MPDATA,R5.0,n,Lab,MAT,LOC,C1`` lines of
    an archive (a temperature table, ``MPTEMP`` with more than one entry, is marked ``TABLE``)."""
    out: dict = {}
    for lineno, line in enumerate(read_text(path).splitlines(), 1):
        f = [t.strip() for t in line.split(",")]
        head = f[0].upper()
        try:
            if head == "MP" and len(f) >= 4:
                out.setdefault(int(float(f[2])), {})[f[1].upper()] = (float(f[3]), lineno)
            elif head == "MPDATA" and len(f) >= 7:
                vals = [float(t) for t in f[6:] if t]
                entry = out.setdefault(int(float(f[4])), {})
                entry[f[3].upper()] = (vals[0] if vals else 0.0, lineno)
                if len(vals) > 1:
                    entry["TABLE"] = (1.0, lineno)
        except ValueError:
            raise ReadError(path, f"non-numeric {head} command {line[:60]!r}", lineno) from None
    return out


def _material(path: Path, number: int, props: dict | None) -> Material:
    name = f"MAT {number}"
    if not props or "EX" not in props:
        return Material(name, unsupported=f"MAT {number} has no MP,EX in {path.name}")
    where = f"{path.name}:{props['EX'][1]}"
    if "TABLE" in props or any(k in props for k in ("EY", "EZ", "GXY", "GYZ", "GXZ")):
        return Material(name, unsupported=f"MAT {number} ({where}) is temperature-dependent or orthotropic; "
                                          "isotropic MP,EX/PRXY/DENS are evaluated")
    nu = props.get("PRXY", props.get("NUXY", (0.0, 0)))[0]
    rho = props.get("DENS", (None, 0))[0]
    try:
        return Material.isotropic(props["EX"][0], nu, rho or None, name)
    except ModelError as exc:
        return Material(name, unsupported=f"{exc} ({where})")


def _elements(path: Path, solids: dict) -> Elements | None:
    """The solids of an archive with the materials of its ``MP`` commands."""
    if not solids:
        return None
    props = _mp_commands(path)
    numbers = sorted({m for rows in solids.values() for _, m, _ in rows})
    materials = [_material(path, m, props.get(m)) for m in numbers]
    blocks = [ElementBlock(name, [r[0] for r in rows], [r[2] for r in rows], [numbers.index(r[1]) for r in rows])
              for name, rows in solids.items()]
    return Elements(tuple(blocks), tuple(materials), str(path))


def read_ansys(path, *, coordinates=None) -> FEModel:
    """Read an Ansys matrix export (Matrix Market set or binary ``.full``).

    Parameters
    ----------
    path : str or path-like
        The stiffness (or mass) Matrix Market file, or the ``.full`` file.
    coordinates : str or path-like, optional
        ``.cdb`` archive with the nodes of a ``.full`` file (default ``<stem>.cdb`` beside it).

    Returns
    -------
    FEModel

    Raises
    ------
    ReadError
        Missing partner files, malformed matrices, maps or coordinates (with line numbers),
        maps that do not fit the matrices, ``.full`` without ansys-mapdl-reader.
    """
    path = Path(path)
    if suffix(path) == ".full":
        if is_gzip(path):
            raise ReadError(path, f"gzip-compressed: {_BY_NAME}; decompress it first (gunzip {path.name})")
        return _read_full(path, coordinates)
    return _read_mmf(path)


def _is_matrix_file(path: Path) -> bool:
    """A ``.full``, or a ``.txt`` whose name says stiffness or mass (not the map, coordinates or elements)."""
    name = path.name.lower()
    return path.suffix.lower() == ".full" or (("stiff" in name or "mass" in name) and "mapping" not in name)


MODEL_FORMATS.register("ansys", [".full", ".txt"], read_ansys, gzip=True,
                       description="Ansys HBMAT/MMF export (stiffness, mass, mapping vector, coordinates) "
                       "or binary .full", recognizes=_is_matrix_file)
