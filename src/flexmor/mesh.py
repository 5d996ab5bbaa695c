"""Element connectivity of a model: :class:`Mesh`, blocks of cells of one type each.

The cell types use meshio's names (``hexahedron``, ``hexahedron20``, ``tetra``, ``tetra10``,
``wedge``, ``quad``, ``quad8``, ``triangle``, ``triangle6``, ``line``, ``line3``, ...), so a
mesh can be handed to meshio and the visualization without translation. Cells refer to
nodes by their ids in the FE file (``FEModel.node_ids``), not by row index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ModelError

__all__ = ["FACES", "NODES_PER_CELL", "CellBlock", "Mesh", "Surface", "outer_surface"]

#: Nodes per cell of each supported cell type (meshio's names).
NODES_PER_CELL = {
    "vertex": 1, "line": 2, "line3": 3, "triangle": 3, "triangle6": 6, "quad": 4, "quad8": 8,
    "quad9": 9, "tetra": 4, "tetra10": 10, "pyramid": 5, "pyramid13": 13, "wedge": 6,
    "wedge15": 15, "hexahedron": 8, "hexahedron20": 20, "hexahedron27": 27,
}


@dataclass(frozen=True)
class CellBlock:
    """Cells of one type.

    Parameters
    ----------
    type : str
        meshio cell type name, one of :data:`NODES_PER_CELL`.
    nodes : ndarray of int, shape (n_cells, nodes_per_cell)
        Node ids of each cell, in meshio's (= VTK's) node order.
    """

    type: str
    nodes: np.ndarray

    def __post_init__(self):
        if self.type not in NODES_PER_CELL:
            raise ModelError(f"unknown cell type {self.type!r}; known: {', '.join(NODES_PER_CELL)}")
        nodes = np.asarray(self.nodes, dtype=np.int64)
        k = NODES_PER_CELL[self.type]
        if nodes.ndim != 2 or nodes.shape[1] != k:
            raise ModelError(f"{self.type} cells need {k} nodes each, got an array of shape {nodes.shape}")
        object.__setattr__(self, "nodes", nodes)


@dataclass(frozen=True)
class Mesh:
    """Element connectivity of a model, as blocks of cells of one type each."""

    blocks: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "blocks", tuple(self.blocks))

    @property
    def n_cells(self) -> int:
        """Number of cells over all blocks."""
        return sum(len(b.nodes) for b in self.blocks)

    def node_ids(self) -> np.ndarray:
        """Sorted unique ids of the nodes that cells use."""
        if not self.blocks:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate([b.nodes.ravel() for b in self.blocks]))

    def check_nodes(self, node_ids: np.ndarray) -> None:
        """Raise :class:`ModelError` if a cell uses a node that is not in ``node_ids``."""
        used = self.node_ids()
        missing = np.setdiff1d(used, node_ids)
        if missing.size:
            raise ModelError(f"{missing.size} node(s) used by elements are not in the node table, "
                             f"first: {int(missing[0])}")


#: Faces of the volume cells by corner index in meshio's (= VTK's) node order.
FACES = {
    "tetra": [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)],
    "pyramid": [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)],
    "wedge": [(0, 1, 2), (3, 5, 4), (0, 3, 4, 1), (1, 4, 5, 2), (2, 5, 3, 0)],
    "hexahedron": [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
}
#: Corner nodes of each cell type (quadratic cells shown by their corners).
_CORNERS = {"tetra10": "tetra", "pyramid13": "pyramid", "wedge15": "wedge", "hexahedron20": "hexahedron",
            "hexahedron27": "hexahedron", "triangle6": "triangle", "quad8": "quad", "quad9": "quad",
            "line3": "line"}
_N_CORNERS = {"tetra": 4, "pyramid": 5, "wedge": 6, "hexahedron": 8, "triangle": 3, "quad": 4, "line": 2,
              "vertex": 1}


@dataclass
class Surface:
    """Triangles and segments over node ids.

    Attributes
    ----------
    triangles : ndarray of int, shape (n_tri, 3)
    lines : ndarray of int, shape (n_lines, 2)
    n_faces : int
        Outer faces (quads count once) before any decimation.
    decimated : str
        Empty, or how the surface was thinned for display.
    """

    triangles: np.ndarray
    lines: np.ndarray
    n_faces: int = 0
    decimated: str = ""

    def node_ids(self) -> np.ndarray:
        """Sorted unique node ids of the triangles and segments."""
        return np.unique(np.concatenate([self.triangles.ravel(), self.lines.ravel()]))


def _split(faces: np.ndarray) -> np.ndarray:
    """Triangles of polygons with 3 or 4 corners (quads cut along their 0-2 diagonal)."""
    if faces.shape[1] == 3:
        return faces
    return np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])


def _boundary(faces: np.ndarray) -> np.ndarray:
    """The rows of ``faces`` whose node set occurs once."""
    if not faces.size:
        return faces
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def outer_surface(mesh) -> Surface:
    """The outer surface of ``mesh`` (a :class:`flexmor.mesh.Mesh`).

    Returns
    -------
    Surface
        Outer faces of the volume cells (those of exactly one cell), shells, and beams as
        segments; vertices of isolated ``vertex`` cells are left out.
    """
    polys = {3: [], 4: []}
    shells, lines = {3: [], 4: []}, []
    for block in mesh.blocks:
        kind = _CORNERS.get(block.type, block.type)
        cells = block.nodes[:, :_N_CORNERS[kind]]
        if kind in FACES:
            for face in FACES[kind]:
                polys[len(face)].append(cells[:, face])
        elif kind in ("triangle", "quad"):
            shells[cells.shape[1]].append(cells)
        elif kind == "line":
            lines.append(cells)
    tris, n_faces = [], 0
    for k in (3, 4):
        if polys[k]:
            outer = _boundary(np.concatenate(polys[k]))
            n_faces += len(outer)
            tris.append(_split(outer))
        if shells[k]:
            sh = np.concatenate(shells[k])
            n_faces += len(sh)
            tris.append(_split(sh))
    triangles = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    segs = np.concatenate(lines) if lines else np.zeros((0, 2), np.int64)
    return Surface(triangles.astype(np.int64), segs.astype(np.int64), n_faces)
