"""Export of a reduced body to Exudyn's floating-frame reduced-order object.

Exudyn's ``ObjectFFRFreducedOrder`` (nodal-based floating frame of reference with modal
reduction, Zwölfer & Gerstmayr 2021) works on meshes of 3-DOF nodes. Besides the reduced
mass and stiffness it needs the mode basis at every mesh node (``modeBasis``, 3 rows per node,
node-major), the reference positions ``xRef`` and the inertia terms

    Mtt = Φtᵀ M Φt,  inertiaLocal = x̃ᵀ M x̃,  chiU = Φtᵀ M x / m,
    mPsiTildePsi = Ψ̃ᵀ M Ψ,  mPsiTildePsiTilde = Ψ̃ᵀ M Ψ̃,  mPhitTPsi = Φtᵀ M Ψ,
    mPhitTPsiTilde = Φtᵀ M Ψ̃,  mXRefTildePsi = x̃ᵀ M Ψ,  mXRefTildePsiTilde = x̃ᵀ M Ψ̃,

(``Φt`` rigid translations, ``x̃``/``Ψ̃`` node-wise skew matrices of the positions/modes), the
same integrals as the SID invariants (:mod:`flexmor.invariants`). :func:`exudyn_data`
computes them with one sparse product (O(nnz(M)·r)) without Exudyn; :func:`write_exudyn`
stores them in the ``.npz`` layout of ``exudyn.FEM.ObjectFFRFreducedOrderInterface``
(``cms.LoadFromFile(path)``), and :func:`add_to_exudyn` adds the body to a ``MainSystem``.
Rotational DOFs of the FE model (beams, shells) are not part of Exudyn's mesh and are dropped.

References
----------
A. Zwölfer, J. Gerstmayr, The nodal-based floating frame of reference formulation with modal
reduction, *Acta Mechanica* 232:835-851, 2021.

J. Gerstmayr, Exudyn – a C++-based Python package for flexible multibody systems,
*Multibody System Dynamics* 60:533-561, 2024.

R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, OptionError
from . import EXPORT_FORMATS, atomic_write

__all__ = ["NODE_TYPES", "add_full_to_exudyn", "add_marker", "add_to_exudyn", "exudyn_data", "write_exudyn"]

log = logging.getLogger(__name__)

#: Rigid-body node types of the floating frame (Exudyn names).
NODE_TYPES = ("NodeType.RotationEulerParameters", "NodeType.RotationRxyz", "NodeType.RotationRotationVector")


def _skew_rows(U):
    """Node-wise skew matrices of ``U`` (3n, m): (3n, 3m), block (i, j) = skew(U[3i:3i+3, j])."""
    n3, m = U.shape
    T = U.reshape(n3 // 3, 3, m)
    S = np.zeros((n3 // 3, 3, 3, m))
    x, y, z = T[:, 0], T[:, 1], T[:, 2]
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 0] = -z, y, z
    S[:, 1, 2], S[:, 2, 0], S[:, 2, 1] = -x, -y, x
    return S.transpose(0, 1, 3, 2).reshape(n3, 3 * m)


def exudyn_data(reduced, model, *, node_type: str = NODE_TYPES[0]) -> dict:
    """The dictionary of ``ObjectFFRFreducedOrderInterface`` (file version 1) for a reduced body.

    Parameters
    ----------
    reduced : ReducedModel
        With its basis ``V``.
    model : FEModel
        The full model it was reduced from.
    node_type : str
        Rigid-body node of the floating frame, one of :data:`NODE_TYPES`.

    Returns
    -------
    dict
        Keys of ``ObjectFFRFreducedOrderInterface.GetDictionary()``; ``nodeIds`` (the FE node
        id of each Exudyn mesh node) and ``dampingMatrixReduced`` (the body's damping, to set on
        the ``ObjectFFRFreducedOrder``) in addition.

    Raises
    ------
    ModelError
        No basis, a basis that does not match the model, no node table.
    """
    from ..invariants import node_triples, rigid_fields
    from ..reduction.free_body import elastic_body

    if node_type not in NODE_TYPES:
        raise OptionError(f"node_type={node_type!r} is not allowed; choose one of: {', '.join(NODE_TYPES)}")
    if reduced.V is None:
        raise ModelError("the reduced body holds no basis V; re-run flexmor reduce (it stores V)")
    V = np.asarray(reduced.V, dtype=float)
    if V.shape[0] != model.n_dof:
        raise ModelError(f"basis has {V.shape[0]} rows, but the model {model.name!r} has {model.n_dof} equations; "
                         "export needs the model the body was reduced from")
    reduced = elastic_body(model, reduced)  # the floating frame carries the rigid motion
    V = np.asarray(reduced.V, dtype=float)
    trans, rot = node_triples(model)
    if np.any(rot >= 0):
        log.warning("%s: rotational DOFs are not part of Exudyn's 3-DOF mesh and are dropped", model.name)
    n, r = model.n_nodes, V.shape[1]
    ok = (trans >= 0).reshape(-1)
    rows = np.flatnonzero(ok)
    S = sp.csr_matrix((np.ones(rows.size), (trans.reshape(-1)[ok], rows)), shape=(model.n_dof, 3 * n))
    Me = (S.T @ model.M @ S).tocsr()
    Psi = np.zeros((3 * n, r))
    Psi[rows] = V[trans.reshape(-1)[ok]]
    x = model.xyz.reshape(-1)
    Phit = np.tile(np.eye(3), (n, 1))
    xt = _skew_rows(x[:, None])
    Pt = _skew_rows(Psi)
    MF = np.asarray(Me @ np.hstack([Psi, Pt]))
    MPsi, MPt = MF[:, :r], MF[:, r:]
    # the terms of the rigid fields are taken from the full mass matrix (rotational DOFs included,
    # e.g. the master nodes of RBE2 couplings that carry the mass of their faces): exact rigid-body
    # mass, centre of mass and inertia tensor, and the exact first-order coupling terms
    St, Sr, X = rigid_fields(model)
    MR = np.asarray(model.M @ np.hstack([St, Sr, X[:, None]]))
    Mtt = St.T @ MR[:, :3]
    mass = float(np.trace(Mtt) / 3)
    chi = (St.T @ MR[:, 6]) / mass
    inertia = Sr.T @ MR[:, 3:6]
    rot_dofs = 4 if node_type.endswith("EulerParameters") else 3
    return {
        "modeBasis": Psi, "trigList": _trig_list(reduced.triangles, model), "postProcessingModes": {},
        "massMatrixReduced": np.asarray(reduced.M, float), "stiffnessMatrixReduced": np.asarray(reduced.K, float),
        "dampingMatrixReduced": np.zeros((r, r)) if reduced.D is None else np.asarray(reduced.D, float),
        "infoList": np.array([r, n, 3, rot_dofs, 3 + rot_dofs, 3 + rot_dofs + r]),
        "rigidBodyNodeType": node_type, "xRef": x, "inertiaLocal": 0.5 * (inertia + inertia.T), "Mtt": Mtt,
        "totalMass": mass, "chiU": chi, "chiUtilde": _skew_rows(chi[:, None]),
        "mPsiTildePsi": Pt.T @ MPsi, "mPsiTildePsiTilde": Pt.T @ MPt, "mPhitTPsi": MR[:, :3].T @ V,
        "mPhitTPsiTilde": Phit.T @ MPt, "mXRefTildePsi": -(MR[:, 3:6].T @ V), "mXRefTildePsiTilde": xt.T @ MPt,
        "fileVersion": 1, "type": "ObjectFFRFreducedOrderInterface", "nodeIds": model.node_ids.copy(),
    }


def _trig_list(triangles, model) -> np.ndarray:
    """Exudyn's ``trigList``: outer surface triangles over node ids (a body's
    :attr:`ReducedModel.triangles`; None: those of ``model.mesh``) as indices of the model's nodes."""
    from ..mesh import outer_surface

    tri = triangles
    if tri is None and model.mesh is not None:
        tri = outer_surface(model.mesh).triangles
    if tri is None or not np.size(tri):
        return np.zeros((0, 3), dtype=np.int64)
    order = np.argsort(model.node_ids)
    pos = np.searchsorted(model.node_ids, np.asarray(tri), sorter=order)
    pos = np.minimum(pos, model.node_ids.size - 1)
    if not np.array_equal(model.node_ids[order[pos]], tri):
        raise ModelError("the body's surface uses nodes that are not in the model: export needs the model the body "
                         "was reduced from")
    return order[pos].astype(np.int64)


def write_exudyn(reduced, path, *, model=None, node_type: str = NODE_TYPES[0], allow_clamped: bool = False) -> None:
    """Write the Exudyn data of a reduced body to ``path`` (``.npz``), atomically.

    Load it in Exudyn with ``cms = exudyn.FEM.ObjectFFRFreducedOrderInterface();
    cms.LoadFromFile(path)``, then ``cms.AddObjectFFRFreducedOrder(mbs, ...)``. A body of a
    supported (clamped) model is refused unless ``allow_clamped`` (its mass properties miss the
    supported nodes, :func:`flexmor.invariants.check_free_model`).

    Raises
    ------
    ModelError
        Without ``model`` (the inertia terms need the FE mass matrix), a clamped model, or see
        :func:`exudyn_data`.
    """
    if model is None:
        raise ModelError("Exudyn export needs the FE data the body was reduced from, given as model: "
                         "the inertia terms are integrals over its mass matrix", params=("model",))
    from ..invariants import check_free_model

    check_free_model(model, allow_clamped=allow_clamped)
    data = exudyn_data(reduced, model, node_type=node_type)

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez(f, **data)

    atomic_write(path, write)


def add_to_exudyn(mbs, reduced, model, *, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0), rotation=None,
                  angular_velocity=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), rayleigh=(0.0, 0.0),
                  node_type: str = NODE_TYPES[0], name: str = "", color=(0.1, 0.9, 0.1, 1.0)) -> dict:
    """Add a reduced body as ``ObjectFFRFreducedOrder`` to an Exudyn ``MainSystem``.

    Parameters
    ----------
    mbs : exudyn.MainSystem
    reduced : ReducedModel
    model : FEModel
        The full model the body was reduced from.
    position, velocity : sequence of 3 float
        Reference position and initial velocity of the floating frame.
    rotation : array (3, 3), optional
        Reference rotation matrix of the frame (default identity).
    angular_velocity : sequence of 3 float
    gravity : sequence of 3 float
        Gravity vector (mass-proportional load) or zeros.
    rayleigh : (alpha, beta)
        Damping ``alpha Mr + beta Kr`` of the modal coordinates; with (0, 0) (default) the body's
        own damping matrix ``reduced.D`` (e.g. modal damping, its ratio in each mode) is used.
    node_type : str
        Rigid-body node of the frame, one of :data:`NODE_TYPES`.
    name : str
    color : sequence of 4 float

    Returns
    -------
    dict
        Exudyn's ``nRigidBody``, ``nGenericODE2``, ``oFFRFreducedOrder``, ``loadGravity``, and
        ``cms`` (the interface object) and ``node_index`` (FE node id -> Exudyn mesh node).
    """
    from exudyn.FEM import ObjectFFRFreducedOrderInterface

    data = exudyn_data(reduced, model, node_type=node_type)
    data.pop("nodeIds")
    D = data.pop("dampingMatrixReduced")
    cms = ObjectFFRFreducedOrderInterface()
    cms.SetWithDictionary(data)
    res = cms.AddObjectFFRFreducedOrder(
        mbs, positionRef=list(position), initialVelocity=list(velocity),
        rotationMatrixRef=[] if rotation is None else np.asarray(rotation), initialAngularVelocity=list(angular_velocity),
        massProportionalDamping=float(rayleigh[0]), stiffnessProportionalDamping=float(rayleigh[1]),
        gravity=list(gravity), color=list(color), name=name)
    res = dict(res)
    if not any(rayleigh) and np.any(D):  # the body's own damping (e.g. modal: its ratio in every mode)
        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "dampingMatrixReduced", D)
    res["cms"] = cms
    res["node_index"] = {int(k): i for i, k in enumerate(model.node_ids)}
    return res


def add_full_to_exudyn(mbs, model, *, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0),
                       angular_velocity=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), constrain_rigid: bool = True,
                       color=(0.9, 0.1, 0.1, 1.0)) -> dict:
    """Add the full FE body as Exudyn's unreduced ``ObjectFFRF`` (the reference of a reduced body).

    Every mesh node is a 3-DOF point node of the floating frame; the mass and stiffness matrices
    are the model's (``exudyn.FEM.FEMinterface`` and ``ObjectFFRFinterface.AddObjectFFRF``,
    Euler-parameter frame at the reference orientation), drawn with the outer surface of
    ``model.mesh``. Nodes without DOF (a supported model's clamped nodes) are left out: they move
    with the frame (and the surface triangles that touch them are not drawn).

    Parameters
    ----------
    mbs : exudyn.MainSystem
    model : FEModel
        Translational DOF only.
    position, velocity, angular_velocity, gravity : sequence of 3 float
        As in :func:`add_to_exudyn`.
    constrain_rigid : bool
        Exudyn's reference conditions (the nodal displacements are mass-orthogonal to the rigid
        motions, the frame follows the body, as for a basis without rigid motion); ``False`` for
        a supported model, whose clamped nodes fix the frame.
    color : sequence of 4 float

    Returns
    -------
    dict
        Exudyn's ``nRigidBody``, ``nodeList``, ``oFFRF``, ``oRigidBodyConstraint``,
        ``loadGravity`` (with gravity) and ``node_index`` (FE node id -> Exudyn mesh node).

    Raises
    ------
    ModelError
        A model with rotational DOFs (Exudyn's mesh has 3-DOF nodes only).
    """
    from exudyn.FEM import FEMinterface, ObjectFFRFinterface
    from ..invariants import node_triples

    import exudyn

    trans, rot = node_triples(model)
    if np.any(rot >= 0):
        raise ModelError(f"{model.name}: the full FFRF body of Exudyn has 3-DOF nodes; the model has rotational DOFs")
    has = np.all(trans >= 0, axis=1)
    if np.any((trans >= 0).any(axis=1) & ~has):
        raise ModelError(f"{model.name}: a node has some but not all translational DOFs; Exudyn's mesh needs all three")
    eq = trans[has].reshape(-1)
    fem = FEMinterface()
    fem.nodes = {"Position": np.asarray(model.xyz, float)[has]}
    fem.massMatrix = sp.csr_matrix(model.M)[eq][:, eq]
    fem.stiffnessMatrix = sp.csr_matrix(model.K)[eq][:, eq]
    fem.modeBasis = {"matrix": np.zeros((eq.size, 0))}
    mesh_node = np.cumsum(has) - 1  # model node -> Exudyn mesh node (clamped nodes: not drawn)
    tri = _trig_list(None, model)
    fem.surface = [{"Name": "outer", "Trigs": mesh_node[tri[np.all(has[tri], axis=1)]]}]
    ffrf = ObjectFFRFinterface(fem)
    res = dict(ffrf.AddObjectFFRF(exudyn, mbs, positionRef=list(position), initialVelocity=list(velocity),
                                  initialAngularVelocity=list(angular_velocity), gravity=list(gravity),
                                  constrainRigidBodyMotion=constrain_rigid, color=list(color)))
    if np.any(gravity):  # the consistent load M Φt g: a force m g at the nodes' mass-weighted mean
        share = np.asarray(fem.massMatrix @ np.tile([1.0, 0.0, 0.0], eq.size // 3))[0::3]
        mass = share.sum()
        res["loadGravity"] = mbs.AddLoad(exudyn.itemInterface.LoadForceVector(
            markerNumber=mbs.AddMarker(exudyn.itemInterface.MarkerSuperElementPosition(
                bodyNumber=res["oFFRF"], meshNodeNumbers=list(range(share.size)), weightingFactors=list(share / mass))),
            loadVector=list(mass * np.asarray(gravity, float))))
    res["node_index"] = {int(k): i for i, k in enumerate(model.node_ids[has])}
    return res


def add_marker(mbs, body: dict, model, target) -> int:
    """Marker (``MarkerSuperElementPosition``) at a node id or the mean of a node set.

    Parameters
    ----------
    mbs : exudyn.MainSystem
    body : dict
        As returned by :func:`add_to_exudyn` or :func:`add_full_to_exudyn`.
    model : FEModel
    target : int or str
        Node id, or node-set name (equal weights).

    Returns
    -------
    int
        The marker number.

    Raises
    ------
    ModelError
        A node that is not a mesh node of the body.
    """
    import exudyn.itemInterface as eii

    if isinstance(target, str) and target.upper() in model.node_sets:
        ids = model.node_sets[target.upper()]
    else:
        ids = [int(target)]
    missing = [int(k) for k in ids if int(k) not in body["node_index"]]
    if missing:
        raise ModelError(f"target={target!r}: node(s) {missing[:5]} are not mesh nodes of the Exudyn body "
                         "(unknown ids, or clamped nodes of the full body, which move with its frame)",
                         params=("target",))
    idx = [body["node_index"][int(k)] for k in ids]
    obj = body["oFFRFreducedOrder"] if "oFFRFreducedOrder" in body else body["oFFRF"]
    return mbs.AddMarker(eii.MarkerSuperElementPosition(bodyNumber=obj, meshNodeNumbers=idx,
                                                        weightingFactors=[1.0 / len(idx)] * len(idx)))


EXPORT_FORMATS.register("exudyn", [".exudyn.npz"], write_exudyn,
                        description="Exudyn ObjectFFRFreducedOrderInterface data (.npz) of a reduced body "
                                    "(needs the FE model)")
