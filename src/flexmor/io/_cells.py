"""Element types of the FE decks as meshio cell types, with the node permutation to meshio's (VTK's) order.

The node order of CalculiX/Abaqus (``C3D20``: corners, bottom edges, top edges, vertical
edges), of Nastran (``CHEXA`` 20: corners, bottom edges, *vertical* edges, top edges) and of
Ansys differ from VTK's, which :class:`flexmor.mesh.CellBlock` uses:

* wedges keep their corners: VTK's code (shape functions, faces, cell size) orients them as
  the FE programs do, the normal of the triangle (0, 1, 2) pointing towards (3, 4, 5)
  (:mod:`flexmor.mesh`);
* quadratic beams (Abaqus ``B32``): middle node second in the deck, last in VTK;
* 20-node bricks and 15-node wedges of Nastran: vertical edges before top edges (Ansys'
  ``SOLID186`` follows VTK).

``PERMUTATIONS[(convention, cell type)]`` gives ``vtk_nodes = deck_nodes[:, perm]``.
"""

from __future__ import annotations

import logging
import re

import numpy as np

from ..mesh import NODES_PER_CELL, CellBlock, Mesh

__all__ = ["abaqus_cell", "abaqus_nodes", "nastran_cell", "ansys_cell", "to_vtk", "build_mesh", "mesh_of_elements"]

log = logging.getLogger(__name__)

_HEX20_NASTRAN = list(range(12)) + [16, 17, 18, 19, 12, 13, 14, 15]
_WEDGE15_NASTRAN = list(range(9)) + [12, 13, 14, 9, 10, 11]

#: Node permutation deck -> VTK by (convention, meshio cell type); absent means identity.
PERMUTATIONS = {
    ("abaqus", "line3"): [0, 2, 1],
    ("nastran", "hexahedron20"): _HEX20_NASTRAN,
    ("nastran", "wedge15"): _WEDGE15_NASTRAN,
}

_SOLID = {4: "tetra", 5: "pyramid", 6: "wedge", 8: "hexahedron", 10: "tetra10", 13: "pyramid13",
          15: "wedge15", 20: "hexahedron20", 27: "hexahedron27"}
_SURFACE = {3: "triangle", 4: "quad", 6: "triangle6", 8: "quad8", 9: "quad9"}
_ABQ = re.compile(r"^(C3D|DC3D|CPS|CPE|CPEG|CAX|DC2D|S|SC|M3D|STRI|R3D|T3D|T2D|B3|B2|PIPE3|PIPE2)(\d+)")


def abaqus_cell(etype: str) -> str | None:
    """The meshio cell type of a CalculiX/Abaqus element type (``C3D20R`` -> ``hexahedron20``), or None."""
    m = _ABQ.match(etype.upper())
    if not m:
        return None
    family, digits = m.group(1), m.group(2)
    if family in ("B3", "B2", "PIPE3", "PIPE2"):  # B31 linear, B32 quadratic, B33 cubic (2 nodes)
        return {"1": "line", "2": "line3", "3": "line"}.get(digits[:1])
    if family in ("T3D", "T2D"):
        return {"2": "line", "3": "line3"}.get(digits[:1])
    if family == "STRI":
        return {"3": "triangle", "65": "triangle6"}.get(digits)
    if family in ("C3D", "DC3D", "SC"):
        return _SOLID.get(int(digits[:2]) if digits[:2] in ("10", "13", "15", "20", "27") else int(digits[:1]))
    return _SURFACE.get(int(digits[:1]))


def abaqus_nodes(etype: str) -> int | None:
    """The node count of a CalculiX/Abaqus element type of :func:`abaqus_cell` (``C3D20R`` -> 20), or None."""
    cell_type = abaqus_cell(etype)
    return None if cell_type is None else NODES_PER_CELL[cell_type]


_NASTRAN = {"CHEXA": {8: "hexahedron", 20: "hexahedron20"}, "CTETRA": {4: "tetra", 10: "tetra10"},
            "CPENTA": {6: "wedge", 15: "wedge15"}, "CPYRAM": {5: "pyramid", 13: "pyramid13"},
            "CQUAD4": {4: "quad"}, "CQUAD8": {8: "quad8"}, "CQUADR": {4: "quad"}, "CTRIA3": {3: "triangle"},
            "CTRIA6": {6: "triangle6"}, "CTRIAR": {3: "triangle"}, "CBAR": {2: "line"}, "CBEAM": {2: "line"},
            "CROD": {2: "line"}, "CONROD": {2: "line"}}


def nastran_cell(card: str, n_nodes: int) -> str | None:
    """The meshio cell type of a Nastran element card with ``n_nodes`` nodes given, or None."""
    return _NASTRAN.get(card, {}).get(n_nodes)


def ansys_cell(etype: int, nodes) -> tuple | None:
    """``(meshio cell type, nodes in VTK order)`` of an Ansys element (``SOLID186`` ...), or None.

    Degenerate forms of the bricks (repeated nodes: wedge, pyramid, tetrahedron) and of the
    4-node shell (triangle) are recognized; beams drop their orientation node.
    """
    nodes = list(nodes)
    n = len(nodes)
    if etype in (185, 45, 65) and n >= 8:
        n_i, n_j, n_k, n_l, n_m, n_n, n_o, n_p = nodes[:8]  # the brick's nodes I ... P
        if len(set(nodes[:8])) == 8:
            return "hexahedron", nodes[:8]
        if n_k == n_l and n_m == n_n == n_o == n_p:
            return "tetra", [n_i, n_j, n_k, n_m]
        if n_m == n_n == n_o == n_p:
            return "pyramid", [n_i, n_j, n_k, n_l, n_m]
        if n_k == n_l and n_o == n_p:
            return "wedge", [nodes[x] for x in (0, 1, 2, 4, 5, 6)]
        return None
    if etype in (186, 95) and n >= 20:
        c = nodes[:20]
        if len(set(c)) == 20:
            return "hexahedron20", c
        if c[2] == c[3] and c[4] == c[5] == c[6] == c[7]:
            return "tetra10", [c[x] for x in (0, 1, 2, 4, 8, 9, 11, 16, 17, 18)]
        if c[2] == c[3] and c[6] == c[7]:
            return "wedge15", [c[x] for x in (0, 1, 2, 4, 5, 6, 8, 9, 11, 12, 13, 15, 16, 17, 18)]
        return None
    if etype in (187, 92) and n >= 10:
        return "tetra10", nodes[:10]
    if etype in (285, 72) and n >= 4:
        return "tetra", nodes[:4]
    if etype in (181, 63, 43) and n >= 4:
        return ("triangle", nodes[:3]) if nodes[2] == nodes[3] else ("quad", nodes[:4])
    if etype in (281, 93) and n >= 8:
        return ("quad8", nodes[:8]) if len(set(nodes[:8])) == 8 else None
    if etype in (188, 180, 14, 4, 8) and n >= 2:
        return "line", nodes[:2]
    if etype == 189 and n >= 3:
        return "line3", nodes[:3]
    if etype == 21 and n >= 1:
        return "vertex", nodes[:1]
    return None


def to_vtk(convention: str, cell_type: str, nodes: np.ndarray) -> np.ndarray:
    """``nodes`` (n_cells, k) in the deck's order -> meshio's (VTK's) order."""
    perm = PERMUTATIONS.get((convention, cell_type))
    return nodes if perm is None else nodes[:, perm]


def build_mesh(blocks, convention: str) -> Mesh | None:
    """A :class:`~flexmor.mesh.Mesh` from ``(cell type, nodes)`` pairs in deck order (same types merged).

    Cells whose node count does not match their type (e.g. degenerate or incomplete
    quadratic elements written with fewer nodes) are left out with a log message. None when
    there are no cells.
    """
    merged: dict[str, list] = {}
    for cell_type, nodes in blocks:
        nodes = np.asarray(nodes, dtype=np.int64)
        k = NODES_PER_CELL[cell_type]
        if nodes.ndim != 2 or nodes.shape[1] != k:
            log.info("%d %s cells with %s nodes instead of %d left out of the mesh", len(nodes), cell_type,
                     nodes.shape[1:] or "no", k)
            continue
        merged.setdefault(cell_type, []).append(to_vtk(convention, cell_type, nodes))
    if not merged:
        return None
    return Mesh(tuple(CellBlock(t, np.concatenate(parts)) for t, parts in merged.items()))


def mesh_of_elements(elements, cell_of, convention: str, node_ids=None) -> Mesh | None:
    """A :class:`~flexmor.mesh.Mesh` from per-element ``(element type, node ids)`` pairs.

    ``cell_of(element type, number of nodes)`` names the meshio cell type (None: not kept).
    Elements using a node outside ``node_ids`` (when given) are left out with a warning.
    """
    groups: dict[str, list] = {}
    for etype, nodes in elements:
        cell_type = cell_of(etype, len(nodes))
        if cell_type is not None and len(nodes) == NODES_PER_CELL[cell_type]:
            groups.setdefault(cell_type, []).append(nodes)
    blocks = []
    for cell_type, rows in groups.items():
        nodes = np.asarray(rows, dtype=np.int64)
        if node_ids is not None:
            ok = np.isin(nodes, node_ids).all(axis=1)
            if not ok.all():
                log.warning("%d %s elements use nodes without coordinates; left out of the mesh",
                            int((~ok).sum()), cell_type)
                nodes = nodes[ok]
        blocks.append((cell_type, nodes))
    return build_mesh(blocks, convention)
