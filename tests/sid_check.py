"""A plain reader of the frame nodes of a ``.SID_FEM`` file, written from the format description and
independent of :mod:`flexmor.io.sid` (which the tests check with it).

The Standard Input Data (Wallrapp 1994; Schwertassek & Wallrapp 1999, ch. 6) of a flexible body is
a text of nested blocks closed by ``end <name>``. The ``frame`` block holds one ``new node = ID``
block per frame node; each holds Taylor matrices such as ``origin`` (the node's position: ``m0``,
3 x 1), ``phi`` (its translations per elastic coordinate: ``m0``, 3 x nq) and ``psi`` (its
rotations, 3 x nq). A Taylor matrix gives ``order``, ``nrow``, ``ncol``, ``nq``, ``nqn``,
``structure`` and then its entries one per line, ``m0( i, j) = value`` (1-based, Fortran ``D``
exponents); an entry that is not written is zero. The first line carries ``No. nodes, No. modes``
and a free comment.
"""

from __future__ import annotations

import re

import numpy as np

_NODE = re.compile(r"^\s*new node\s*=\s*(\d+)\s*$")
_M0 = re.compile(r"^\s*m0\(\s*(\d+)\s*,\s*(\d+)\s*\)\s*=\s*(\S+)\s*$")
_M1 = re.compile(r"^\s*m1\(\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*\)\s*=\s*(\S+)\s*$")
_INT = re.compile(r"^\s*(order|nrow|ncol|nq|nqn|structure)\s*=\s*(-?\d+)\s*$")
MATRICES = ("origin", "phi", "psi", "AP")


def fortran_float(text: str) -> float:
    """``-1.25D-02`` -> -0.0125."""
    return float(text.strip().replace("D", "E").replace("d", "e"))


def header(path) -> tuple[int, int, str]:
    """``(number of nodes, number of modes, comment)`` of the first line."""
    with open(path) as f:
        first = f.readline()
    numbers, _, comment = first.partition(":")
    n_nodes, n_modes = (int(v) for v in numbers.split()[:2])
    return n_nodes, n_modes, comment.strip()


def frame_nodes(path) -> dict[int, dict[str, np.ndarray]]:
    """``{node id: {'origin': (3, 1), 'phi': (3, nq), 'psi': (3, nq), ...}}`` (the ``m0`` of each
    Taylor matrix of the ``frame`` block; ``<name>_structure`` gives its structure code)."""
    nodes: dict[int, dict[str, np.ndarray]] = {}
    node = block = None
    dims: dict[str, int] = {}
    entries: list[tuple[int, int, float]] = []
    in_frame = False
    with open(path) as f:
        for line in f:
            word = line.strip()
            if word == "frame":
                in_frame = True
                continue
            if not in_frame:
                continue
            if word == "end frame":
                break
            m = _NODE.match(line)
            if m:
                node = nodes.setdefault(int(m.group(1)), {})
                continue
            if node is None:
                continue
            if block is None and word in MATRICES:
                block, dims, entries = word, {}, []
                continue
            if block is not None and word == f"end {block}":
                mat = np.zeros((dims["nrow"], dims["ncol"]))
                for i, j, v in entries:
                    mat[i - 1, j - 1] = v
                node[block] = mat
                node[f"{block}_structure"] = np.array(dims.get("structure", -1))
                block = None
                continue
            if block is not None:
                _entry(line, dims, entries)
    return nodes


def _entry(line: str, dims: dict, e0: list, e1: list | None = None) -> None:
    """One line inside a Taylor block: a header integer into ``dims``, an ``m0`` entry into ``e0``, an ``m1``
    entry into ``e1``."""
    m = _INT.match(line)
    if m:
        dims[m.group(1)] = int(m.group(2))
        return
    m = _M0.match(line)
    if m:
        e0.append((int(m.group(1)), int(m.group(2)), fortran_float(m.group(3))))
        return
    m = _M1.match(line)
    if m and e1 is not None:
        e1.append((int(m.group(1)), int(m.group(2)), int(m.group(3)), fortran_float(m.group(4))))

BODY = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")


def taylor_objects(path) -> dict:
    """Every Taylor matrix of the file with its first-order term: ``{name: (m0, m1)}`` for the body objects
    and ``{(node id, name): (m0, m1)}`` for the frame nodes' ``phi`` and ``psi``; ``m0`` (nrow, ncol), ``m1``
    (nrow, ncol, nq) indexed ``[row, col, q]``, zero where nothing is written. The entries ``m1(i, k, j)``
    are read in the order of the sample files of the format (row, modal coordinate, column): the matrix at
    the modal coordinates ``q`` is ``m0 + Σ_k m1[:, :, k] q_k``. Symmetric matrices (structure 2) are
    mirrored."""
    out: dict = {}
    node = block = None
    dims: dict[str, int] = {}
    e0: list = []
    e1: list = []
    with open(path) as f:
        for line in f:
            word = line.strip()
            m = _NODE.match(line)
            if m:
                node = int(m.group(1))
                continue
            if word == "end frame":
                node = None
                continue
            if block is None and (word in BODY or (node is not None and word in ("phi", "psi"))):
                block, dims, e0, e1 = word, {}, [], []
                continue
            if block is not None and word == f"end {block}":
                m0 = np.zeros((dims["nrow"], dims["ncol"]))
                for i, j, v in e0:
                    m0[i - 1, j - 1] = v
                if dims.get("structure") == 2:
                    m0 = np.triu(m0) + np.triu(m0, 1).T
                m1 = np.zeros((dims["nrow"], dims["ncol"], max(dims.get("nq", 0), 1)))
                for i, k, j, v in e1:
                    m1[i - 1, j - 1, k - 1] = v
                out[block if node is None else (node, block)] = (m0, m1)
                block = None
                continue
            if block is not None:
                _entry(line, dims, e0, e1)
    return out
