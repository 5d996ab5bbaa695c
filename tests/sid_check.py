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
            if block is None:
                continue
            m = _INT.match(line)
            if m:
                dims[m.group(1)] = int(m.group(2))
                continue
            m = _M0.match(line)
            if m:
                entries.append((int(m.group(1)), int(m.group(2)), fortran_float(m.group(3))))
    return nodes
