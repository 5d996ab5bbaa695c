"""The outer surface of a mesh for display: boundary faces, shells and beams, and its decimation.

:func:`outer_surface` (:mod:`flexmor.mesh`) turns a :class:`flexmor.mesh.Mesh` into triangles and line segments over
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

import numpy as np

from ..mesh import FACES, Surface, outer_surface

__all__ = ["FACES", "Surface", "decimate", "outer_surface"]  # all but decimate from flexmor.mesh


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
