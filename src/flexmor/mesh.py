"""Element connectivity of a model: :class:`Mesh`, blocks of cells of one type each.

The cell types use meshio's names (``hexahedron``, ``hexahedron20``, ``tetra``, ``tetra10``,
``wedge``, ``quad``, ``quad8``, ``triangle``, ``triangle6``, ``line``, ``line3``, ...), so a
mesh can be handed to meshio and the visualization without translation. Cells refer to
nodes by their ids in the FE file (``FEModel.node_ids``), not by row index.

:meth:`Mesh.to_meshio` and :meth:`Mesh.from_meshio` convert to and from ``meshio.Mesh``
(the optional extra ``flexmor[mesh]``); the node ids travel as the point data
:data:`NODE_ID_DATA`. The node orders are meshio's. Wedges (``wedge``, ``wedge15``) have the
orientation of VTK's code, gmsh, meshio and the FE programs: the normal of the triangle
(0, 1, 2) points towards (3, 4, 5). VTK's shape functions have always been this way round; VTK
9.7 turned its documentation (which said the opposite), its wedges' faces, cell sizes and mesh
quality to agree with them (older ParaView may show such wedges with a negative cell size).
meshio 5.3.5 turns linear wedges around when it writes and reads VTK files; flexmor undoes that
for those files (:data:`MESHIO_ORDER`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .errors import ModelError

__all__ = ["FACES", "MESHIO_ORDER", "NODES_PER_CELL", "NODE_ID_DATA", "CellBlock", "Mesh", "Surface", "import_meshio",
           "meshio_node_ids", "outer_surface"]

log = logging.getLogger(__name__)

#: Node permutation flexmor -> meshio per meshio cell type for meshes meshio writes to or reads from VTK
#: files (``.vtu``, ``.vtk``; each is its own inverse; in memory meshio's order is flexmor's): meshio
#: 5.3.5 reverses the linear wedge's triangles on the way to and from VTK files, which turns the
#: wedges of VTK's code inside out, so flexmor reverses them first.
MESHIO_ORDER = {
    "wedge": [0, 2, 1, 3, 5, 4],
}

#: Point-data array with the node ids in the meshio meshes (and files) flexmor writes.
NODE_ID_DATA = "node_id"

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
        Node ids of each cell, in VTK's (and meshio's) node order.
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

    def to_meshio(self, node_ids, xyz, *, point_data=None, field_data=None, vtk=False):
        """This mesh as a ``meshio.Mesh`` over the node table ``node_ids``, ``xyz``.

        Parameters
        ----------
        node_ids : array_like of int, shape (n_nodes,)
            The node table's ids; point ``i`` of the result is node ``node_ids[i]``.
        xyz : array_like of float, shape (n_nodes, 3)
            Node coordinates.
        point_data, field_data : dict, optional
            Passed to ``meshio.Mesh``; the node ids are added as point data :data:`NODE_ID_DATA`.
        vtk : bool
            The result goes to a VTK file (``.vtu``, ``.vtk``): cells turned by
            :data:`MESHIO_ORDER`, so that they are right in the file.

        Returns
        -------
        meshio.Mesh
            Cells as point indices, block by block with the same cell types; ``wedge15`` and
            ``pyramid13`` cells, which meshio 5.3.5 cannot hold, as their corners (with a log
            message).

        Raises
        ------
        ModelError
            meshio is not installed, or a cell uses a node outside ``node_ids``.
        """
        meshio = import_meshio()
        node_ids = np.asarray(node_ids, dtype=np.int64).reshape(-1)
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        if xyz.shape[0] != node_ids.size:
            raise ModelError(f"{node_ids.size} node ids but {xyz.shape[0]} coordinate rows")
        self.check_nodes(node_ids)
        order = np.argsort(node_ids, kind="stable")
        cells = [_meshio_block(meshio, b.type, order[np.searchsorted(node_ids, b.nodes, sorter=order)])
                 for b in self.blocks]
        if vtk:
            cells = [meshio.CellBlock(c.type, _reorder(c.type, c.data)) for c in cells]
        return meshio.Mesh(xyz, cells, point_data={NODE_ID_DATA: node_ids, **(point_data or {})},
                           field_data=dict(field_data or {}))

    @classmethod
    def from_meshio(cls, mesh, node_ids=None, *, vtk=False) -> Mesh:
        """The cells of a ``meshio.Mesh`` over node ids.

        Parameters
        ----------
        mesh : meshio.Mesh
        node_ids : array_like of int, optional
            Id of each point; default :func:`meshio_node_ids`.
        vtk : bool
            ``mesh`` was read from a VTK file (``.vtu``, ``.vtk``): cells turned by
            :data:`MESHIO_ORDER`.

        Returns
        -------
        Mesh
            One block per meshio cell block of a type in :data:`NODES_PER_CELL` (meshio's
            names and node orders are flexmor's); blocks of other types (polygons, Lagrange
            cells ...) are left out with a log message.
        """
        ids = meshio_node_ids(mesh) if node_ids is None else np.asarray(node_ids, dtype=np.int64).reshape(-1)
        if ids.size != len(mesh.points):
            raise ModelError(f"{ids.size} node ids for {len(mesh.points)} points")
        blocks, skipped = [], []
        for block in mesh.cells:
            if block.type in NODES_PER_CELL:
                nodes = ids[np.asarray(block.data, dtype=np.int64)]
                blocks.append(CellBlock(block.type, _reorder(block.type, nodes) if vtk else nodes))
            else:
                skipped.append(f"{len(block.data)} {block.type}")
        if skipped:
            log.warning("cells of types flexmor does not know left out of the mesh: %s", ", ".join(skipped))
        return cls(tuple(blocks))


def _reorder(cell_type: str, nodes: np.ndarray) -> np.ndarray:
    perm = MESHIO_ORDER.get(cell_type)
    return nodes if perm is None else np.asarray(nodes)[:, perm]


def _meshio_block(meshio, cell_type: str, cells: np.ndarray):
    """A ``meshio.CellBlock``; cells of a type meshio cannot hold (5.3.5: ``wedge15``, ``pyramid13``) as corners."""
    try:
        return meshio.CellBlock(cell_type, cells)
    except KeyError:
        corners = _CORNERS[cell_type]
        log.warning("meshio %s cannot hold %s cells: %d of them passed as their corners (%s)",
                    getattr(meshio, "__version__", "?"), cell_type, len(cells), corners)
        return meshio.CellBlock(corners, cells[:, :_N_CORNERS[corners]])


def import_meshio():
    """The ``meshio`` module; a :class:`ModelError` naming the extra ``flexmor[mesh]`` when it is absent."""
    try:
        import meshio
    except ImportError:
        raise ModelError("meshes through meshio need the meshio package: pip install 'flexmor[mesh]'") from None
    return meshio


def meshio_node_ids(mesh) -> np.ndarray:
    """The node id of each point of a ``meshio.Mesh``.

    The ids meshio's Nastran reader keeps (``points_id``, the GRID ids), else the point data
    :data:`NODE_ID_DATA` (files flexmor wrote), else the point index + 1 (meshio's Abaqus,
    gmsh, VTK readers number the points from 0 in the file's order and drop the file's ids).
    """
    n = len(mesh.points)
    ids = getattr(mesh, "points_id", None)
    if ids is None:
        ids = mesh.point_data.get(NODE_ID_DATA)
    if ids is None:
        return np.arange(1, n + 1, dtype=np.int64)
    ids = np.asarray(ids).reshape(-1)
    if ids.size != n or not np.array_equal(ids, np.round(ids)) or np.unique(ids).size != n:
        raise ModelError(f"the node ids of the {n} points are not {n} distinct integers")
    return ids.astype(np.int64)


#: Faces of the volume cells by corner index in meshio's (= VTK's) node order, outward (right-hand rule).
FACES = {
    "tetra": [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)],
    "pyramid": [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)],
    "wedge": [(0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)],
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
    order = np.lexsort(key.T[::-1])  # equal node sets next to each other (7x faster than np.unique(axis=0))
    key = key[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    shared = np.zeros(len(key), dtype=bool)
    shared[1:] |= same
    shared[:-1] |= same
    once = np.empty(len(key), dtype=bool)
    once[order] = ~shared
    return faces[once]


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
