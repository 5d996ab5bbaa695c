"""CalculiX result files (``.frd``): nodes, eigenfrequencies and mode shapes as a reference.

The frd format (CalculiX GraphiX manual, "Result Format") is a sequence of blocks, each
starting with a key in columns 1-5 and a code in column 6:

``    1C``/``    1U``/``    1P``
    header, user and parameter records (``1PMODE``, ``1PGM`` generalized mass, ``1PGK``
    generalized stiffness of an eigenmode);
``    2C`` nodes
    ``numnod`` (columns 25-36) and a format flag (column 74): 0 ASCII short (node number
    I5), 1 ASCII long (I10), 2 binary float, 3 binary double. ASCII records ``-1 node x y z``
    (coordinates E12.5), closed by ``-3``; binary records are ``int32 node, 3 reals``;
``    3C`` elements (skipped: ASCII up to ``-3``; binary records of known size);
``  100C`` nodal results
    ``name(6) value(E12.5) numnod(I12) text(A20) ictype(I2) numstep(I5) analysis(A10)
    format(I2)``; for an eigenmode step ``value`` is the frequency (cycles per time) and the
    analysis is ``MODAL``. Then ``-4 NAME ncomps irtype`` and one ``-5`` line per component
    (an ``ALL`` component marked ``iexist = 1`` has no data), then per node ``-1 node values``
    (6 values per line, ``-2`` continuation lines) closed by ``-3``, or binary
    ``int32 node, ncomps reals`` (float32 for format 2, float64 for format 3, CalculiX's
    ``*NODE OUTPUT, DOUBLE``);
``9999`` end of data.

:func:`read_frd` keeps the node table and every result block; :func:`modes` returns the
eigenfrequencies and ``DISP`` mode shapes; :func:`compare_modes` checks a model against them
(the frequencies of ``flexmor info MODEL --reference JOB.frd``).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import ModelError, ReadError
from ...linalg.context import SolverContext
from .._open import read_all

__all__ = ["ELEMENT_TYPES", "FrdResult", "compare_modes", "modes", "read_frd"]


@dataclass
class FrdResult:
    """Contents of an frd file.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n,)
    xyz : ndarray, shape (n, 3)
    blocks : list of dict
        Result blocks in file order: ``name`` (e.g. ``DISP``), ``step``, ``value``
        (frequency of a ``MODAL`` step, else time), ``analysis``, ``components`` (names),
        ``nodes`` (k,), ``values`` (k, ncomp), ``params`` (the ``1P`` records before it).
    element_types : set of str
        CalculiX names of the element shapes in the element block (``C3D8``, ``C3D20``,
        ``C3D10``, ``S8``, ``B32`` ...; :data:`ELEMENT_TYPES`).
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    blocks: list = field(default_factory=list)
    element_types: set = field(default_factory=set)


class _Reader:
    def __init__(self, path: Path):
        self.path = path
        self.raw = read_all(path)
        self.pos = 0
        self.line = 0

    def eof(self) -> bool:
        return self.pos >= len(self.raw)

    def readline(self) -> str:
        if self.eof():
            raise ReadError(self.path, "file ends inside a block (truncated?)", self.line)
        end = self.raw.find(b"\n", self.pos)
        end = len(self.raw) if end < 0 else end
        s = self.raw[self.pos:end].decode("latin-1").rstrip("\r")
        self.pos = end + 1
        self.line += 1
        return s

    def read(self, n: int) -> bytes:
        if self.pos + n > len(self.raw):
            raise ReadError(self.path, f"binary block ends early at byte {len(self.raw)} (truncated?)")
        b = self.raw[self.pos:self.pos + n]
        self.pos += n
        return b

    def error(self, msg):
        return ReadError(self.path, msg, self.line)


def _int(r: _Reader, s: str, what: str) -> int:
    try:
        return int(s)
    except ValueError:
        raise r.error(f"expected an integer {what}, got {s.strip()[:20]!r}") from None


def _floats(r: _Reader, s: str, width: int = 12):
    try:
        vals = [float(s[k:k + width]) for k in range(0, len(s.rstrip()), width)]
    except ValueError:
        raise r.error(f"non-numeric value in {s[:60]!r}") from None
    if not np.all(np.isfinite(vals)):
        raise r.error("non-finite value (NaN or Inf)")
    return vals


def _nodes(r: _Reader, head: str):
    n, fmt = _int(r, head[24:36], "node count"), _int(r, head[36:].strip()[-1:] or "x", "format flag")
    if n < 0:
        raise r.error("negative node count")
    ids, xyz = np.empty(n, np.int64), np.empty((n, 3))
    if fmt >= 2:
        dt = np.dtype([("id", "<i4"), ("x", "<f4" if fmt == 2 else "<f8", (3,))])
        a = np.frombuffer(r.read(n * dt.itemsize), dt)
        return a["id"].astype(np.int64), a["x"].astype(np.float64)
    w = 5 if fmt == 0 else 10
    for k in range(n):
        s = r.readline()
        if s[:3].strip() != "-1":
            raise r.error(f"expected node record ' -1' ({k} of {n} nodes read), got {s[:30]!r}")
        ids[k] = _int(r, s[3:3 + w], "node number")
        c = _floats(r, s[3 + w:])
        if len(c) != 3:
            raise r.error(f"node {ids[k]}: expected 3 coordinates, got {len(c)}")
        xyz[k] = c
    s = r.readline()
    if s[:3].strip() != "-3":
        raise r.error(f"expected ' -3' after the {n} nodes the block announces, got {s[:30]!r}")
    return ids, xyz


_ELEM_NODES = {1: 8, 2: 6, 3: 4, 4: 20, 5: 15, 6: 10, 7: 3, 8: 6, 9: 4, 10: 8, 11: 2, 12: 3}
#: Element shape codes of the frd format and the CalculiX element name they stand for.
ELEMENT_TYPES = {1: "C3D8", 2: "C3D6", 3: "C3D4", 4: "C3D20", 5: "C3D15", 6: "C3D10", 7: "S3", 8: "S6",
                 9: "S4", 10: "S8", 11: "B31", 12: "B32"}


def _elements(r: _Reader, head: str) -> set:
    """Skip an element block; return the CalculiX names of its element shapes."""
    n, fmt = _int(r, head[24:36], "element count"), _int(r, head[36:].strip()[-1:] or "x", "format flag")
    codes = set()
    if fmt >= 2:
        for _ in range(n):
            _, etype, _, _ = struct.unpack("<4i", r.read(16))
            if etype not in _ELEM_NODES:
                raise ReadError(r.path, f"binary element of unknown type {etype}")
            codes.add(etype)
            r.read(4 * _ELEM_NODES[etype])
    else:
        w = 5 if fmt == 0 else 10
        while (s := r.readline())[:3].strip() != "-3":
            if s[:3].strip() == "-1":
                codes.add(_int(r, s[3 + w:3 + w + 5], "element type"))
    return {ELEMENT_TYPES.get(c, f"frd type {c}") for c in codes}


def _results(r: _Reader, head: str, params: dict):
    value = _floats(r, head[12:24])
    numnod = _int(r, head[24:36], "node count")
    step = _int(r, head[58:63] or "0", "step number") if head[58:63].strip() else 0
    analysis = head[63:73].strip()
    fmt = _int(r, head[73:75], "format flag") if head[73:75].strip() else 1
    h4 = r.readline()
    if h4[:3].strip() != "-4":
        raise r.error(f"expected the ' -4' record of a result block, got {h4[:30]!r}")
    name = h4[5:13].strip()
    ncomp = _int(r, h4[13:18], "component count")
    comps = []
    for _ in range(ncomp):
        c = r.readline()
        if c[:3].strip() != "-5":
            raise r.error(f"expected a ' -5' component record, got {c[:30]!r}")
        if c[33:38].strip() != "1":  # iexist = 1: no data (e.g. ALL, computed by the viewer)
            comps.append(c[5:13].strip())
    nv = len(comps)
    if fmt >= 2:
        dt = np.dtype([("id", "<i4"), ("v", "<f4" if fmt == 2 else "<f8", (nv,))])
        a = np.frombuffer(r.read(numnod * dt.itemsize), dt)
        nodes, vals = a["id"].astype(np.int64), a["v"].astype(np.float64).reshape(numnod, nv)
    else:
        w = 5 if fmt == 0 else 10
        nodes, vals = np.empty(numnod, np.int64), np.empty((numnod, nv))
        k = 0
        cur = None
        while True:
            s = r.readline()
            key = s[:3].strip()
            if key == "-3":
                break
            if key == "-1":
                if cur is not None:
                    raise r.error(f"node {nodes[k]}: {len(cur)} values, expected {nv}")
                if k >= numnod:
                    raise r.error(f"result block {name} announces {numnod} nodes but has more")
                nodes[k] = _int(r, s[3:3 + w], "node number")
                cur = _floats(r, s[3 + w:])
            elif key == "-2" and cur is not None:
                cur += _floats(r, s[3 + w:])
            else:
                raise r.error(f"unexpected record {s[:30]!r} in result block {name}")
            if len(cur) > nv:
                raise r.error(f"node {nodes[k]}: more than {nv} values")
            if len(cur) == nv:
                vals[k] = cur
                k += 1
                cur = None
        if cur is not None or k != numnod:
            raise r.error(f"result block {name} has {k} complete node records, its header announces {numnod}")
    return {"name": name, "step": step, "value": value[0] if value else 0.0, "analysis": analysis,
            "components": comps, "nodes": nodes, "values": vals, "params": dict(params)}


def read_frd(path, *, results: bool = True) -> FrdResult:
    """Read nodes and nodal result blocks of a CalculiX ``.frd`` file (ASCII or binary blocks).

    Parameters
    ----------
    path : str or path-like
    results : bool
        False: stop before the first result block (nodes and element types only).

    Raises
    ------
    ReadError
        Missing file, unknown or malformed records (with line number), counts that do not
        match, truncated binary blocks.
    """
    path = Path(path)
    if not path.exists():
        raise ReadError(path, "file not found")
    r = _Reader(path)
    if not r.raw.strip():
        raise ReadError(path, "file is empty")
    ids, xyz, blocks, params, types = None, None, [], {}, set()
    while True:
        if r.eof():
            raise ReadError(path, "no end record 9999: the file was cut off (or CalculiX stopped early)", r.line)
        s = r.readline()
        if not s.strip():
            continue
        key, code = s[:5].strip(), s[5:6]
        if key == "9999":
            break
        if key == "1" and code == "P":
            m = re.match(r"\s*([A-Za-z]+)\s*(.*)$", s[6:])
            if m:
                params[m.group(1).upper()] = m.group(2).strip()
        elif key in ("1",):
            continue
        elif key == "2" and code == "C":
            if ids is not None:
                raise r.error("a second node block")
            ids, xyz = _nodes(r, s)
        elif key == "3" and code == "C":
            types |= _elements(r, s)
        elif key == "100" and code == "C":
            if not results:
                break
            blocks.append(_results(r, s, params))
            params = {}
        else:
            raise r.error(f"unknown frd record {s[:20]!r}; is this a CalculiX .frd file?")
    if ids is None:
        raise ReadError(path, "no node block (    2C) found")
    if np.unique(ids).size != ids.size:
        raise ReadError(path, "node numbers in the node block are not unique")
    return FrdResult(ids, xyz, blocks, types)


def modes(res: FrdResult):
    """Eigenfrequencies (Hz) and ``DISP`` shapes of the modal steps.

    Returns
    -------
    freqs : ndarray, shape (k,)
    nodes : ndarray of int, shape (n,)
        The node numbers of the first modal DISP block (all blocks must have the same).
    shapes : ndarray, shape (k, n, 3)
    """
    disp = [b for b in res.blocks
            if b["name"] == "DISP" and (b["analysis"].upper() == "MODAL" or "MODE" in b["params"])]
    if not disp:
        raise ModelError("the frd file has no DISP block of a MODAL step (write it with *FREQUENCY and "
                         "*NODE FILE, U)")
    nodes = disp[0]["nodes"]
    shapes = []
    for b in disp:
        if not np.array_equal(b["nodes"], nodes) or b["values"].shape[1] < 3:
            raise ModelError(f"DISP block of step {b['step']} has other nodes or fewer than 3 components")
        shapes.append(b["values"][:, :3])
    return np.array([_frequency(b) for b in disp]), nodes, np.array(shapes)


def _frequency(block) -> float:
    """The step's frequency: ``value`` (6 digits), refined by ``sqrt(GK/GM)/2pi`` when the
    generalized stiffness and mass records (8 digits) confirm it."""
    f = float(block["value"])
    try:
        gk, gm = float(block["params"]["GK"]), float(block["params"]["GM"])
    except (KeyError, ValueError):
        return f
    if gk >= 0 and gm > 0:
        g = float(np.sqrt(gk / gm) / (2 * np.pi))
        if abs(g - f) <= 1e-4 * max(abs(f), 1e-300) or (f == 0 and g < 1e-3):
            return g
    return f


def compare_modes(model, res: FrdResult, *, k: int | None = None, solver: SolverContext | None = None,
                  cluster: float = 1e-3):
    """Compare ``model`` with the modes of an frd file.

    The frd modes are paired with the model's one-to-one and in order by frequency
    (:func:`flexmor.io._pairing.paired_modes`: rigid-body modes with rigid-body modes, the
    least sum of relative differences; the notes and warnings of
    :func:`flexmor.io._pairing.pairing_record`). Each frd mode is mapped to the model's
    translational equations (its nodes and x y z) and measured against the span ``S`` of the
    model's modes of its pair's frequency, those within ``cluster`` (relative) of it, or all the
    model's rigid-body modes for a rigid-body mode: ``mac = |S^T M phi|^2 / (phi^T M phi)`` with
    M-orthonormal ``S`` (1 for a mode the model reproduces, also within a pair of equal
    frequencies or among the rigid-body motions).

    Returns
    -------
    dict
        As :func:`flexmor.io.reference.compare_frequencies` (``frequencies_hz`` the frd's,
        ``model_frequencies_hz``, ``rel_diff``, ``model_modes``, ``notes``) with ``mac`` (None for an
        frd mode without a model mode).
    """
    from .._pairing import paired_modes, pairing_record

    f_ref, nodes, shapes = modes(res)
    k = len(f_ref) if k is None else min(k, len(f_ref))
    if model.dofs is None:
        raise ModelError("the model has no equation map to compare mode shapes with")
    f_ref = f_ref[:k]
    p = paired_modes(model, f_ref, solver=solver, vectors=True)
    pos = {int(n): i for i, n in enumerate(nodes)}
    rows = [(e, pos.get(int(g)), d - 1) for e, (g, d) in enumerate(model.dofs) if d <= 3]
    rigid = np.flatnonzero(p.rigid_mod)
    out_mac = []
    for i in range(k):
        j = p.pair[i]
        if j is None:
            out_mac.append(None)
            continue
        v = np.zeros(model.n_dof)
        for e, q, d in rows:
            if q is not None:
                v[e] = shapes[i, q, d]
        near = rigid if p.rigid_mod[j] else np.flatnonzero(
            ~p.rigid_mod & (np.abs(p.f_mod - p.f_mod[j]) <= cluster * p.f_mod[j]))
        Mv = model.M @ v
        vMv = float(v @ Mv)
        out_mac.append(float(np.sum((p.phi[:, near].T @ Mv) ** 2) / vMv) if vMv > 0 else 0.0)
    return dict(pairing_record(f_ref, p), mac=out_mac)
