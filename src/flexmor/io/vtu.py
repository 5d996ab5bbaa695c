"""Export of a reduced body's mode shapes on its mesh as a VTK unstructured grid (``.vtu``) for ParaView.

The body's modes are the eigenpairs of ``(Kr, Mr)``, expanded to the full model's
equations by the basis (``V phi``): the modes the reduced body moves in. The file holds
the mesh (the full model's elements, or without the model the body's outer surface as
triangles), the node ids as point data ``node_id``, one displacement vector per node and
mode as point data ``mode_1``, ``mode_2`` ... (global x y z; zero where a node has no such
equation, e.g. a clamped node) and the frequencies in Hz as field data ``frequencies_hz``. A body
with stress modes (``reduce --stress``, :func:`flexmor.stress.body_stresses`) adds each mode's
nodal stress ``stress_k`` (xx yy zz xy yz zx, CalculiX's order) and its von Mises stress
``mises_k`` (NaN at nodes where the body stores no stress).

Those fields belong to the body's eigenmodes (mass-normalised, sign chosen so that the largest
displacement is positive). The coordinates ``q`` of the body files (h5, SID, Exudyn, MAT, FMU) and of a
simulation belong to its basis vectors: the file also holds ``basis_j`` (the displacement of ``q_j = 1``),
``stress_basis_j`` / ``mises_basis_j`` (its stress, the body's ``stress_modes``) and the field data
``eigenvectors`` (r x r, row j, column k) with ``mode_k = sum_j basis_j eigenvectors[j, k]``; a state ``q``
from the MBS code is displayed by ``sum_j q_j basis_j`` (and its stress by ``sum_j q_j stress_basis_j``).
In ParaView: *Warp By Vector* with a ``mode_k`` array animates mode k. Written through
meshio (the optional extra ``flexmor[mesh]``), atomically.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace
from xml.etree import ElementTree

import numpy as np
import scipy.linalg as sla

from ..errors import ModelError
from ..mesh import CellBlock, Mesh, import_meshio
from ._registry import EXPORT_FORMATS
from .atomic import atomic_write
from .invariants import node_triples

__all__ = ["body_modes", "nodal_modes", "write_vtu"]


def body_modes(body) -> tuple[np.ndarray, np.ndarray]:
    """The reduced body's undamped modes, expanded to the full model's equations.

    Returns
    -------
    freqs_hz : ndarray, shape (r,)
        Eigenfrequencies of ``(Kr, Mr)``, ascending (round-off negatives as 0).
    shapes : ndarray, shape (n_dof, r)
        ``V phi`` with ``phi`` mass-normalized (``phi^T Mr phi = I``) and its sign chosen so
        that the entry of largest magnitude of each expanded mode is positive.

    Raises
    ------
    ModelError
        The body stores no basis ``V`` or its reduced mass matrix is not positive definite.
    """
    freqs, _, shapes = _modes(body)
    return freqs, shapes


def _modes(body):
    """Frequencies, reduced mode vectors ``phi`` (signed as :func:`body_modes` says) and ``V phi``."""
    if body.V is None:
        raise ModelError("the body stores no basis V, so its modes cannot be expanded to the nodes")
    try:
        lam, phi = sla.eigh(body.K, body.M)
    except (np.linalg.LinAlgError, ValueError):
        raise ModelError("the reduced mass matrix is not positive definite") from None
    shapes = np.asarray(body.V) @ phi
    if shapes.size:
        big = shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])]
        sign = np.where(big < 0, -1.0, 1.0)
        shapes *= sign
        phi = phi * sign
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi), phi, shapes


def _stress_data(body, phi, node_ids) -> dict:
    """Point data ``stress_k`` (xx yy zz xy yz zx) and ``mises_k`` of each mode at ``node_ids`` from the body's
    stress modes; NaN at nodes without stress (not in ``body.stress_nodes``)."""
    from ..stress import von_mises

    if body.stress_modes is None or body.stress_nodes is None:
        return {}
    S = np.einsum("jk,jsi->ksi", phi, np.asarray(body.stress_modes))  # (modes, stress nodes, 6)
    nodes = np.asarray(body.stress_nodes)
    order = np.argsort(nodes)
    pos = np.minimum(np.searchsorted(nodes[order], node_ids), max(nodes.size - 1, 0))
    hit = nodes[order][pos] == node_ids if nodes.size else np.zeros(len(node_ids), bool)
    out = {}
    for k in range(S.shape[0]):
        full = np.full((len(node_ids), 6), np.nan)
        full[hit] = S[k][order[pos[hit]]]
        out[f"stress_{k + 1}"] = full
        out[f"mises_{k + 1}"] = von_mises(full)
    return out


def nodal_modes(shapes: np.ndarray, geometry) -> np.ndarray:
    """Displacement vectors (n_nodes, 3, k) of ``shapes`` (n_dof, k) at the nodes of ``geometry``.

    ``geometry`` has ``node_ids``, ``dofs`` (n_dof, 2), ``n_nodes``, ``n_dof`` and optionally
    ``node_frames`` (an FEModel): translations in a node's own frame are turned to global x y z.
    """
    trans, _ = node_triples(geometry)
    out = np.zeros((trans.shape[0], 3, shapes.shape[1]))
    ok = trans >= 0
    out[ok] = shapes[trans[ok]]
    frames = getattr(geometry, "node_frames", None) or {}
    if frames:
        row = {int(k): i for i, k in enumerate(geometry.node_ids)}
        for node, Q in frames.items():
            out[row[node]] = Q @ out[row[node]]
    return out


def _geometry(body, model):
    """``(geometry, mesh)``: the node table and cells of ``model``, else the body's own nodes and surface."""
    n_dof = body.V.shape[0]
    if model is not None:
        if model.n_dof != n_dof:
            raise ModelError(f"the model has {model.n_dof} DOF but the body's basis V has {n_dof} rows; give model "
                             "the body was reduced from", params=("model",))
        if model.dofs is None or not model.n_nodes or model.mesh is None:
            raise ModelError(f"the model {model.source or model.name} has no {'elements' if model.n_nodes else 'nodes'}"
                             "; a .vtu needs its mesh (attach one to matrices without geometry with a mesh file, "
                             "flexmor.io.meshio_mesh.with_mesh)", params=("model",))
        return model, model.mesh
    if body.dofs is None or body.node_ids is None or not len(body.node_ids) or body.triangles is None:
        raise ModelError("the body has no node table and surface (its model had no elements); give model, the FE "
                         "model with elements it was reduced from", params=("model",))
    geometry = SimpleNamespace(node_ids=np.asarray(body.node_ids), dofs=np.asarray(body.dofs),
                               n_nodes=len(body.node_ids), n_dof=n_dof)
    return geometry, Mesh([CellBlock("triangle", body.triangles)])


def write_vtu(body, path, *, model=None) -> None:
    """Write the body's mesh and mode shapes as a ``.vtu`` file for ParaView, atomically.

    Parameters
    ----------
    body : ReducedModel
        A body with its basis ``V``.
    path : str or path-like
        The ``.vtu`` file.
    model : FEModel, optional
        The full model the body was reduced from, as read: its elements and nodes are written
        (and its nodes' own frames applied); a body with couplings is expanded to their slave
        nodes (:func:`flexmor.expansion.expand_body`), and each coupling master is a point of its
        own (a ``vertex`` cell, ``node_id`` its id, its translations in ``mode_k``). Without it, the
        body's node table and outer surface (triangles) are used.

    Raises
    ------
    ModelError
        No basis, no nodes or elements to draw on, a model of another size, or meshio
        missing (the message names the extra ``flexmor[mesh]``).
    """
    meshio = import_meshio()
    masters = ()
    if model is not None and body.V is not None and body.couplings:
        from ..expansion import expand_body, expanded_reduced

        xb = expand_body(model, body, elastic=False)  # the slaves move with their masters
        body, model, masters = expanded_reduced(xb), xb.model, xb.masters
    geometry, mesh = _geometry(body, model)
    xyz = model.xyz if model is not None else body.xyz
    if masters:  # each coupling master a point of its own (a vertex cell), its id as node_id
        body = dataclasses.replace(body, V=np.vstack([body.V] + [m.rows for m in masters]))
        dofs = np.vstack([model.dofs] + [np.column_stack([np.full(6, m.id), np.arange(1, 7)]) for m in masters])
        geometry = SimpleNamespace(node_ids=xb.node_ids, dofs=dofs, n_nodes=xb.node_ids.size, n_dof=dofs.shape[0],
                                   node_frames=model.node_frames)
        xyz = xb.xyz
    freqs, phi, shapes = _modes(body)
    nodal = nodal_modes(shapes, geometry)
    point_data = {f"mode_{k + 1}": np.ascontiguousarray(nodal[:, :, k]) for k in range(nodal.shape[2])}
    point_data.update(_stress_data(body, phi, np.asarray(geometry.node_ids)))
    # the body's own coordinates q (those of the h5, SID, Exudyn, MAT and FMU files): basis_j = V e_j, and
    # mode_k = sum_j basis_j eigenvectors[j, k-1]
    r = np.shape(body.V)[1]
    basis = nodal_modes(np.asarray(body.V, dtype=float), geometry)
    point_data.update({f"basis_{j + 1}": np.ascontiguousarray(basis[:, :, j]) for j in range(r)})
    point_data.update({k.replace("stress_", "stress_basis_").replace("mises_", "mises_basis_"): v
                       for k, v in _stress_data(body, np.eye(r), np.asarray(geometry.node_ids)).items()})
    fields = {"frequencies_hz": freqs, "eigenvectors": phi}
    grid = mesh.to_meshio(geometry.node_ids, xyz, point_data=point_data, field_data={"frequencies_hz": freqs},
                          vtk=True)
    if masters:
        n0 = model.n_nodes
        grid.cells.append(meshio.CellBlock("vertex", np.arange(n0, n0 + len(masters), dtype=np.int64)[:, None]))

    def write(tmp):
        meshio.write(tmp, grid, file_format="vtu")
        _add_field_data(tmp, fields)

    atomic_write(path, write)


def _add_field_data(path, arrays: dict) -> None:
    """Insert ``arrays`` as ASCII ``FieldData`` into the ``.vtu`` file ``path`` (meshio 5.3.5 writes none)."""
    tree = ElementTree.parse(path)
    grid = tree.getroot().find("UnstructuredGrid")
    field = ElementTree.Element("FieldData")
    for name, values in arrays.items():
        values = np.asarray(values, dtype=np.float64)
        n_comp = values.shape[1] if values.ndim == 2 else 1  # a matrix: one tuple per row
        values = values.ravel()
        array = ElementTree.SubElement(field, "DataArray", type="Float64", Name=name,
                                       NumberOfTuples=str(values.size // n_comp), format="ascii",
                                       **({"NumberOfComponents": str(n_comp)} if n_comp > 1 else {}))
        array.text = " ".join(repr(float(v)) for v in values)
    grid.insert(0, field)
    tree.write(path, xml_declaration=True, encoding="utf-8")


EXPORT_FORMATS.register("vtu", [".vtu"], write_vtu,
                        description="mesh with the body's mode shapes (point data mode_k, field data frequencies_hz) "
                                    "for ParaView")
