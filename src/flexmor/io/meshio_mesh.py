"""A mesh file read through meshio, and attached to a model that came without one.

Matrices exported without geometry (Matrix Market pairs, MATLAB files) have no node table,
equation map or elements; :func:`with_mesh` takes them from a mesh file that meshio reads
(``.vtu``, ``.vtk``, ``.msh``, ``.inp``, ``.bdf``, ``.med``, ``.xdmf`` ...; the optional extra
``flexmor[mesh]``). A model that has nodes but no elements (a Nastran DMIG with its GRID
cards) gets the file's cells, after a check that they use the model's nodes at the model's
coordinates.

The equations of a model without a node table must be the nodes' displacements, node after
node in the file's point order: ``3 P`` equations (x y z) or ``6 P`` (x y z rx ry rz) for
``P`` points, as scikit-fem's vector elements and most exports without constraints number
them. The node ids are the file's where meshio keeps them (Nastran GRID ids, flexmor's own
``node_id`` point data), else the point index + 1.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
from pathlib import Path

import numpy as np

from ..errors import ModelError, ReadError
from ..mesh import Mesh, import_meshio, meshio_node_ids

__all__ = ["read_mesh", "with_mesh"]

#: Relative tolerance (of the model's size) of the coordinate check of :func:`with_mesh`.
COORD_RTOL = 1e-6


def read_mesh(path) -> tuple[Mesh, np.ndarray, np.ndarray]:
    """Read a mesh file through meshio.

    Parameters
    ----------
    path : str or path-like
        Any mesh file meshio reads, its format told by the suffix.

    Returns
    -------
    mesh : Mesh
        The cells, over node ids.
    node_ids : ndarray of int, shape (n_points,)
    xyz : ndarray of float, shape (n_points, 3)
        Point coordinates (2-D points get z = 0).

    Raises
    ------
    ReadError
        Naming the file: missing, meshio not installed, a format meshio does not know, or a
        file meshio cannot parse.
    """
    path = Path(path)
    if not path.is_file():
        raise ReadError(path, "mesh file not found" if not path.exists() else "is a directory, expected a mesh file")
    try:
        meshio = import_meshio()
    except ModelError as exc:
        raise ReadError(path, str(exc)) from None
    said = io.StringIO()
    try:  # meshio prints its readers' complaints on stdout and exits on a file no reader takes
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            m = meshio.read(str(path))
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - meshio raises many kinds for a file it cannot read
        lines = [ln.strip() for ln in said.getvalue().splitlines() if ln.strip()]
        msg = str(exc).strip() if isinstance(exc, Exception) and str(exc).strip() else ""
        detail = " ".join(dict.fromkeys(([msg] if msg else []) + lines)) or type(exc).__name__
        raise ReadError(path, f"meshio cannot read this mesh file: {detail[:300]}") from None
    xyz = np.zeros((len(m.points), 3))
    pts = np.asarray(m.points, dtype=np.float64).reshape(len(m.points), -1)
    xyz[:, :min(3, pts.shape[1])] = pts[:, :3]
    try:
        ids = meshio_node_ids(m)
        return Mesh.from_meshio(m, ids, vtk=path.suffix.lower() in (".vtu", ".vtk")), ids, xyz
    except ModelError as exc:
        raise ReadError(path, str(exc)) from None


def with_mesh(model, path):
    """``model`` with the nodes and elements of the mesh file ``path`` (read by :func:`read_mesh`).

    Parameters
    ----------
    model : FEModel
        A model without a node table (its equations become the mesh points' x y z, or
        x y z rx ry rz, node after node), or with nodes but without elements.
    path : str or path-like
        The mesh file.

    Returns
    -------
    FEModel
        A copy with ``node_ids``, ``xyz``, ``dofs`` and ``mesh`` (only ``mesh`` when the model
        had nodes).

    Raises
    ------
    ReadError
        Naming the file: unreadable; a point count that does not fit the model's equations;
        cells on nodes the model does not have or at other coordinates; a model that has
        elements already.
    """
    path = Path(path)
    mesh, ids, xyz = read_mesh(path)
    if model.mesh is not None:
        raise ReadError(path, f"the model {model.source or model.name} has elements from its own files already; "
                              "a mesh file is for models without geometry (Matrix Market, MATLAB)")
    try:
        if not model.n_nodes and model.dofs is None:
            return dataclasses.replace(model, node_ids=ids, xyz=xyz, dofs=_node_major(path, ids, model.n_dof),
                                       mesh=mesh if mesh.blocks else None)
        _check_nodes(path, mesh, ids, xyz, model)
        return dataclasses.replace(model, mesh=mesh if mesh.blocks else None)
    except ModelError as exc:
        raise ReadError(path, str(exc)) from None


def _node_major(path: Path, ids: np.ndarray, n_dof: int) -> np.ndarray:
    """Equation map x y z (or x..rz) node after node; a ReadError when the counts do not fit."""
    p = ids.size
    per = n_dof // p if p else 0
    if per not in (3, 6) or per * p != n_dof:
        raise ReadError(path, f"{p} points give {3 * p} equations (x y z per node) or {6 * p} (x y z rx ry rz), "
                              f"but the model's matrices have {n_dof}: the mesh does not belong to this model "
                              "(its equations must be the points' displacements, node after node)")
    return np.column_stack([np.repeat(ids, per), np.tile(np.arange(1, per + 1, dtype=np.int64), p)])


def _check_nodes(path: Path, mesh: Mesh, ids: np.ndarray, xyz: np.ndarray, model) -> None:
    """Every node the cells use is in the model's node table, at the model's coordinates."""
    used = mesh.node_ids()
    missing = np.setdiff1d(used, model.node_ids)
    if missing.size:
        raise ReadError(path, f"{missing.size} node(s) of the cells are not in the model's node table, first: "
                              f"{int(missing[0])} (meshio keeps the node ids of Nastran files only; other formats "
                              "number the points 1, 2, ... in the file's order)")
    order = np.argsort(ids)
    mine = xyz[order[np.searchsorted(ids, used, sorter=order)]]
    theirs = model.node_xyz(used)
    span = float(np.ptp(model.xyz, axis=0).max()) if model.n_nodes else 0.0
    dist = np.linalg.norm(mine - theirs, axis=1)
    k = int(np.argmax(dist)) if dist.size else 0
    if dist.size and dist[k] > COORD_RTOL * max(span, 1e-300):
        raise ReadError(path, f"node {int(used[k])} lies at {mine[k].tolist()} in the mesh file but at "
                              f"{theirs[k].tolist()} in the model: the mesh does not belong to this model")
