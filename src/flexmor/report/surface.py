"""The outer surface of a mesh for display: boundary faces, shells and beams, and its decimation.

:func:`outer_surface` turns a :class:`flexmor.mesh.Mesh` into triangles and line segments over
node ids: the faces of volume cells that belong to one cell only (the outer skin, inner faces
dropped), shell cells as they are, beam cells as segments. Quadratic cells are shown by their
corner nodes. :func:`decimate` thins a large surface by vertex clustering (Rossignac and
Borrel): nodes are snapped to the node nearest the centre of their cell of a uniform grid,
triangles that collapse are dropped, so every displayed vertex is still a node of the model
(and mode shapes are sampled there, not interpolated).

References
----------
J. Rossignac and P. Borrel, Multi-resolution 3D approximations for rendering complex scenes,
in *Modeling in Computer Graphics*, Springer, 1993, pp. 455-465.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FACES", "Surface", "decimate", "outer_surface"]

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


def _snap(ids: np.ndarray, xyz: np.ndarray, cell: float) -> np.ndarray:
    """Representative node id of each of ``ids``: the one nearest its grid cell's centre."""
    lo = xyz.min(axis=0)
    ijk = np.floor((xyz - lo) / cell).astype(np.int64)
    _, cluster = np.unique(ijk, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    dist = np.linalg.norm(xyz - (lo + (ijk + 0.5) * cell), axis=1)
    order = np.lexsort((dist, cluster))  # by cluster, nearest first
    first = order[np.r_[True, cluster[order][1:] != cluster[order][:-1]]]
    rep = np.empty(cluster.max() + 1, np.int64)
    rep[cluster[first]] = ids[first]
    return rep[cluster]


def decimate(surface: Surface, xyz: np.ndarray, max_nodes: int) -> Surface:
    """``surface`` with at most ``max_nodes`` vertices (vertex clustering on a uniform grid).

    Parameters
    ----------
    surface : Surface
    xyz : ndarray, shape (n, 3)
        Coordinates of ``surface.node_ids()``.
    max_nodes : int
        Largest number of displayed vertices; a surface within it is returned unchanged.
    """
    ids = surface.node_ids()
    if ids.size <= max_nodes:
        return surface
    t = np.searchsorted(ids, surface.triangles)
    area = 0.5 * np.linalg.norm(np.cross(xyz[t[:, 1]] - xyz[t[:, 0]], xyz[t[:, 2]] - xyz[t[:, 0]]), axis=1).sum()
    cell = np.sqrt(area / max_nodes) if area > 0 else float(np.max(np.ptp(xyz, axis=0))) / max_nodes
    while True:
        rep = _snap(ids, xyz, cell)
        if np.unique(rep).size <= max_nodes:
            break
        cell *= 1.25
    tri = rep[np.searchsorted(ids, surface.triangles)]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    if tri.size:
        tri = tri[np.sort(np.unique(np.sort(tri, axis=1), axis=0, return_index=True)[1])]
    seg = rep[np.searchsorted(ids, surface.lines)]
    seg = seg[seg[:, 0] != seg[:, 1]]
    note = (f"surface decimated for display: {ids.size} -> {np.unique(rep).size} vertices, "
            f"{len(surface.triangles)} -> {len(tri)} triangles (vertex clustering, grid {cell:.3g})")
    return Surface(tri, seg, surface.n_faces, note)
