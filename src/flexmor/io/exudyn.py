"""Export of a reduced body to Exudyn's floating-frame reduced-order object.

Exudyn's ``ObjectFFRFreducedOrder`` (nodal-based floating frame of reference with modal
reduction, Zwölfer & Gerstmayr 2021) works on meshes of 3-DOF nodes. Besides the reduced
mass and stiffness it needs the mode basis at every mesh node (``modeBasis``, 3 rows per node,
node-major), the reference positions ``xRef`` and the inertia terms

    Mtt = Φtᵀ M Φt,  inertiaLocal = x̃ᵀ M x̃,  chiU = Φtᵀ M x / m,
    mPsiTildePsi = Ψ̃ᵀ M Ψ,  mPsiTildePsiTilde = Ψ̃ᵀ M Ψ̃,  mPhitTPsi = Φtᵀ M Ψ,
    mPhitTPsiTilde = Φtᵀ M Ψ̃,  mXRefTildePsi = x̃ᵀ M Ψ,  mXRefTildePsiTilde = x̃ᵀ M Ψ̃,

(``Φt`` rigid translations, ``x̃``/``Ψ̃`` node-wise skew matrices of the positions/modes), the
same integrals as the SID invariants (:mod:`flexmor.io.invariants`). :func:`exudyn_data`
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
import os

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, OptionError
from ._registry import EXPORT_FORMATS
from .atomic import atomic_write
from .exudyn_moving import MOVING_KEYS, moving_load_data

__all__ = ["NODE_TYPES", "EXTRA_KEYS", "add_full_to_exudyn", "add_marker", "add_npz_to_exudyn", "add_to_exudyn",
           "exudyn_data", "spin_stiffening_force", "write_exudyn"]

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


def exudyn_data(body, model, *, node_type: str = NODE_TYPES[0], remove_rigid: bool = False) -> dict:
    """The dictionary of ``ObjectFFRFreducedOrderInterface`` (file version 1) for a reduced body.

    Parameters
    ----------
    body : ReducedModel
        With its basis ``V``.
    model : FEModel
        The full model it was reduced from, as read: the body applies its own couplings, and
        its basis is expanded to their slave nodes (:func:`flexmor.expansion.expand_body`).
    node_type : str
        Rigid-body node of the floating frame, one of :data:`NODE_TYPES`.
    remove_rigid : bool
        Allow the basis of a body that holds rigid-body motion to be made mass-orthogonal to
        it (another body than the one judged); refused by default.

    Returns
    -------
    dict
        Keys of ``ObjectFFRFreducedOrderInterface.GetDictionary()``, and in addition:
        ``nodeIds`` (the FE node id of each Exudyn mesh node: the model's nodes, then each
        coupling master, which carries no mass), ``dampingMatrixReduced`` (the body's damping, to
        set on the ``ObjectFFRFreducedOrder``), ``postProcessingModes`` (the body's stress modes,
        ``reduce --stress``, as Exudyn's stress modes for its post-processing: ``matrix`` of shape
        (mesh nodes, 6 r), components xx yy zz yz xz xy, zero where the body has no stress;
        ``{}`` without), ``interfaceNames``, ``interfaceMasterNodes``
        (mesh node of each master), ``interfaceSlaveNodes`` and ``interfaceSlaveOffsets`` (the
        mesh nodes of interface ``k`` are ``interfaceSlaveNodes[offsets[k]:offsets[k+1]]``); a body reduced
        with moving loads: their paths (:data:`flexmor.io.exudyn_moving.MOVING_KEYS`).

    Raises
    ------
    ModelError
        No basis, a basis that does not match the model, no node table.
    """
    from ..expansion import expand_body
    from .invariants import node_triples, rigid_fields

    if node_type not in NODE_TYPES:
        raise OptionError(f"node_type={node_type!r} is not allowed; choose one of: {', '.join(NODE_TYPES)}")
    xb = expand_body(model, body, remove_rigid=remove_rigid)  # the floating frame carries the rigid motion
    if body.stress_modes is not None and xb.body.stress_modes is None:
        log.warning("%s body: its basis was changed to remove rigid-body motion; its stress modes (of the basis "
                    "reduced) are not written", body.method)
    body, model, V = xb.body, xb.model, xb.V
    trans, rot = node_triples(model)
    if np.any(rot >= 0):
        log.warning("%s: rotational DOFs are not part of Exudyn's 3-DOF mesh and are dropped", model.name)
    n0, r = model.n_nodes, V.shape[1]
    n = n0 + len(xb.masters)  # the coupling masters follow the model's nodes (no mass of their own)
    ok = (trans >= 0).reshape(-1)
    rows = np.flatnonzero(ok)
    S = sp.csr_matrix((np.ones(rows.size), (trans.reshape(-1)[ok], rows)), shape=(model.n_dof, 3 * n))
    Me = (S.T @ model.M @ S).tocsr()
    Psi = np.zeros((3 * n, r))
    Psi[rows] = V[trans.reshape(-1)[ok]]
    for k, m in enumerate(xb.masters):
        Psi[3 * (n0 + k):3 * (n0 + k) + 3] = m.rows[:3]
    x = xb.xyz.reshape(-1)
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
    index = {int(k): i for i, k in enumerate(xb.node_ids)}
    slaves = [np.array([index[int(k)] for k in m.slaves], dtype=np.int64) for m in xb.masters]
    return {**_spin_data(body, model, V), **moving_load_data(body, xb.node_ids, Psi, x),
        "modeBasis": Psi, "trigList": _trig_list(body.triangles, model),
        "postProcessingModes": _stress_modes(body, xb.node_ids),
        "massMatrixReduced": np.asarray(body.M, float), "stiffnessMatrixReduced": np.asarray(body.K, float),
        "dampingMatrixReduced": np.zeros((r, r)) if body.D is None else np.asarray(body.D, float),
        "infoList": np.array([r, n, 3, rot_dofs, 3 + rot_dofs, 3 + rot_dofs + r]),
        "rigidBodyNodeType": node_type, "xRef": x, "inertiaLocal": 0.5 * (inertia + inertia.T), "Mtt": Mtt,
        "totalMass": mass, "chiU": chi, "chiUtilde": _skew_rows(chi[:, None]),
        "mPsiTildePsi": Pt.T @ MPsi, "mPsiTildePsiTilde": Pt.T @ MPt, "mPhitTPsi": MR[:, :3].T @ V,
        "mPhitTPsiTilde": Phit.T @ MPt, "mXRefTildePsi": -(MR[:, 3:6].T @ V), "mXRefTildePsiTilde": xt.T @ MPt,
        "fileVersion": 1, "type": "ObjectFFRFreducedOrderInterface", "nodeIds": xb.node_ids,
        "interfaceNames": np.array([m.name for m in xb.masters], dtype=str),
        "interfaceMasterNodes": np.arange(n0, n, dtype=np.int64),
        "interfaceSlaveNodes": np.concatenate(slaves) if slaves else np.zeros(0, np.int64),
        "interfaceSlaveOffsets": np.cumsum([0] + [s.size for s in slaves]).astype(np.int64),
    }


def _spin_data(body, model, V) -> dict:
    """The spin data of a body reduced over a speed range (``{}`` without): ``spinAxis``, ``spinRange`` and
    ``spinStiffening``, the geometric stiffness of the unit speed's centrifugal stresses alone (the body's ``K2``
    without the spin softening, which Exudyn's floating frame computes from the mass, as it does the Coriolis
    forces): :func:`spin_stiffening_force` applies ``w_a^2 spinStiffening``."""
    from ..linalg.threads import sparse_dense
    from ..preload import spin_softening

    spin = body.info.get("spin") if isinstance(body.info, dict) else None
    if not spin:
        return {}
    axis = np.asarray(spin["axis"], float)
    S = V.T @ sparse_dense(spin_softening(model, axis), V)
    KG = np.asarray(spin["K2"], float) - 0.5 * (S + S.T)
    return {"spinAxis": axis, "spinRange": np.asarray(spin["range"], float), "spinStiffening": KG}


def spin_stiffening_force(mbs, node: int, data: dict):
    """The ``forceUserFunction`` of an ``ObjectFFRFreducedOrder`` body reduced over a speed range: the
    geometric stiffening of its centrifugal stresses, ``-(w . a)^2 KG q`` on its modal coordinates ``q``
    (``w`` the angular velocity of its frame node ``node`` in body coordinates, ``a`` ``data["spinAxis"]``,
    ``KG`` ``data["spinStiffening"]``), zero on the frame's coordinates. Exudyn's floating frame supplies the
    centrifugal and Coriolis forces and the spin softening from the mass; this supplies what Exudyn does not
    model, the stiffening of the stresses. Set it with::

        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction",
                               spin_stiffening_force(mbs, res["nRigidBody"], np.load(path, allow_pickle=False)))

    (:func:`add_to_exudyn` and :func:`add_npz_to_exudyn` do so for such a body.)
    """
    import exudyn as exu

    axis = np.asarray(data["spinAxis"], float)
    KG = np.asarray(data["spinStiffening"], float)
    r = KG.shape[0]

    def force(mbs_, t, itemNumber, q, q_t):
        # the speed at the start of the time step: within a step the force is linear in q (a Newton iteration
        # that also followed the speed's change in the step would need the force's derivative by the frame's
        # velocity, which the solver does not take from a user function); O(h) in a speed that varies
        w = np.asarray(mbs_.GetNodeOutput(node, exu.OutputVariableType.AngularVelocityLocal,
                                          configuration=exu.ConfigurationType.StartOfStep), float)
        q = np.asarray(q, float)
        out = np.zeros(q.size)
        out[q.size - r:] = -(float(w @ axis) ** 2) * (KG @ q[q.size - r:])
        return out.tolist()

    return force


#: Exudyn's stress components (xx yy zz yz xz xy) from flexmor's (xx yy zz xy yz zx).
_EXUDYN_STRESS = [0, 1, 2, 4, 5, 3]


def _stress_modes(body, node_ids) -> dict:
    """Exudyn's ``postProcessingModes`` of a body with stress modes (``{}`` without): ``matrix`` (mesh nodes,
    6 r), column ``6 i + j`` component ``j`` (xx yy zz yz xz xy) of basis vector ``i``, zero at nodes
    without stress; ``outputVariableType`` StressLocal. The stress of rigid-body motion is zero, so the
    stress modes hold for the elastic body of the floating frame too."""
    if body.stress_modes is None or body.stress_nodes is None:
        return {}
    S = np.asarray(body.stress_modes, float)[:, :, _EXUDYN_STRESS]  # (r, k, 6)
    nodes = np.asarray(body.stress_nodes)
    index = {int(k): i for i, k in enumerate(node_ids)}
    at = np.array([index.get(int(k), -1) for k in nodes], dtype=np.int64)
    X = np.zeros((len(node_ids), S.shape[0], 6))
    X[at[at >= 0]] = S[:, at >= 0].transpose(1, 0, 2)
    return {"matrix": X.reshape(len(node_ids), -1), "outputVariableType": "OutputVariableType.StressLocal"}


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


def write_exudyn(body, path, *, model=None, node_type: str = NODE_TYPES[0], allow_clamped: bool = False,
                 remove_rigid: bool = False) -> None:
    """Write the Exudyn data of a reduced body to ``path`` (``.npz``), atomically.

    Load it in Exudyn with ``cms = exudyn.FEM.ObjectFFRFreducedOrderInterface();
    cms.LoadFromFile(path)``, then ``res = cms.AddObjectFFRFreducedOrder(mbs, ...)``. Exudyn's
    loader does not read the body's damping (modal damping: its ratio in every mode); one line
    sets it::

        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "dampingMatrixReduced",
                               np.load(path, allow_pickle=False)["dampingMatrixReduced"])

    (:func:`add_npz_to_exudyn` does both.) A body of a supported (clamped) model is refused
    unless ``allow_clamped`` (its mass properties miss the supported nodes,
    :func:`flexmor.io.invariants.check_free_model`). ``model`` is the FE model as read; see
    :func:`exudyn_data` for the coupling masters and ``remove_rigid``.

    Raises
    ------
    ModelError
        Without ``model`` (the inertia terms need the FE mass matrix), a clamped model, or see
        :func:`exudyn_data`.
    """
    if model is None:
        raise ModelError("Exudyn export needs the FE data the body was reduced from, given as model: "
                         "the inertia terms are integrals over its mass matrix", params=("model",))
    from .invariants import check_free_model

    check_free_model(model, allow_clamped=allow_clamped)
    data = exudyn_data(body, model, node_type=node_type, remove_rigid=remove_rigid)

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez(f, **data)

    atomic_write(path, write)


#: Keys of :func:`exudyn_data` that Exudyn's ``ObjectFFRFreducedOrderInterface`` does not read.
EXTRA_KEYS = ("nodeIds", "dampingMatrixReduced", "interfaceNames", "interfaceMasterNodes", "interfaceSlaveNodes",
              "interfaceSlaveOffsets", "spinAxis", "spinRange", "spinStiffening", *MOVING_KEYS)


def _add(mbs, data: dict, *, position, velocity, rotation, angular_velocity, gravity, rayleigh, name, color):
    """Add the body of ``data`` (:func:`exudyn_data`) to ``mbs``: Exudyn's result dict with ``cms``,
    ``node_index`` (FE node id -> mesh node) and ``interfaces`` (name -> master and slave mesh nodes)."""
    from exudyn.FEM import ObjectFFRFreducedOrderInterface

    cms = ObjectFFRFreducedOrderInterface()
    cms.SetWithDictionary({k: v for k, v in data.items() if k not in EXTRA_KEYS})
    res = cms.AddObjectFFRFreducedOrder(
        mbs, positionRef=list(position), initialVelocity=list(velocity),
        rotationMatrixRef=[] if rotation is None else np.asarray(rotation),
        initialAngularVelocity=list(angular_velocity),
        massProportionalDamping=float(rayleigh[0]), stiffnessProportionalDamping=float(rayleigh[1]),
        gravity=list(gravity), color=list(color), name=name)
    res = dict(res)
    D = np.asarray(data["dampingMatrixReduced"], float)
    if not any(rayleigh) and np.any(D):  # the body's own damping (e.g. modal: its ratio in every mode)
        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "dampingMatrixReduced", D)
    if "spinStiffening" in data:  # a body over a speed range: the stiffening Exudyn does not model
        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction",
                               spin_stiffening_force(mbs, res["nRigidBody"], data))
        res["spin_stiffening"] = True
    if MOVING_KEYS[0] in data:  # the paths, for flexmor.io.exudyn_moving's load user functions
        res["moving_loads"] = {k: data[k] for k in MOVING_KEYS}
    res["cms"] = cms
    res["node_index"] = {int(k): i for i, k in enumerate(np.asarray(data["nodeIds"]))}
    off = np.asarray(data["interfaceSlaveOffsets"])
    slaves = np.asarray(data["interfaceSlaveNodes"])
    xyz = np.asarray(data["xRef"], float).reshape(-1, 3)
    res["interfaces"] = {str(nm): {"master": int(mn), "slaves": slaves[off[k]:off[k + 1]].tolist(),
                                   "master_id": int(np.asarray(data["nodeIds"])[mn]), "xyz": xyz[int(mn)]}
                         for k, (nm, mn) in enumerate(zip(data["interfaceNames"], data["interfaceMasterNodes"]))}
    return res


def add_npz_to_exudyn(mbs, path, *, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0), rotation=None,
                      angular_velocity=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), rayleigh=(0.0, 0.0), name: str = "",
                      color=(0.1, 0.9, 0.1, 1.0)) -> dict:
    """Add a body written by :func:`write_exudyn` (``.exudyn.npz``) to an Exudyn ``MainSystem``,
    with its own damping and its interfaces (the arguments and the result as in :func:`add_to_exudyn`).
    The file is read without unpickling."""
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files if k != "postProcessingModes"}
    data["postProcessingModes"] = {}
    data["trigList"] = np.asarray(data["trigList"])
    data["rigidBodyNodeType"] = str(data["rigidBodyNodeType"])
    return _add(mbs, data, position=position, velocity=velocity, rotation=rotation, angular_velocity=angular_velocity,
                gravity=gravity, rayleigh=rayleigh, name=name, color=color)


def add_to_exudyn(mbs, body, model, *, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0), rotation=None,
                  angular_velocity=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), rayleigh=(0.0, 0.0),
                  node_type: str = NODE_TYPES[0], name: str = "", color=(0.1, 0.9, 0.1, 1.0),
                  remove_rigid: bool = False) -> dict:
    """Add a reduced body as ``ObjectFFRFreducedOrder`` to an Exudyn ``MainSystem``.

    Parameters
    ----------
    mbs : exudyn.MainSystem
    body : ReducedModel
    model : FEModel or path
        The full model the body was reduced from, as read (or its file): the body applies its
        own couplings (:func:`exudyn_data`).
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
    remove_rigid : bool
        See :func:`exudyn_data`.

    Returns
    -------
    dict
        Exudyn's ``nRigidBody``, ``nGenericODE2``, ``oFFRFreducedOrder``, ``loadGravity``, and
        ``cms`` (the interface object), ``node_index`` (FE node id -> Exudyn mesh node, coupling
        masters included), ``interfaces`` (coupling name, e.g. ``HOLE@RBE2`` -> ``master``
        and ``slaves`` mesh nodes, ``master_id``, ``xyz``): :func:`add_marker` puts markers on them,
        ``model`` (the model as read), and ``moving_loads`` for a body with moving loads (the paths that
        :func:`flexmor.io.exudyn_moving.moving_load_force` moves a force over).
    """
    if isinstance(model, (str, os.PathLike)):  # the model file
        from ._registry import read

        model = read(model)
    data = exudyn_data(body, model, node_type=node_type, remove_rigid=remove_rigid)
    res = _add(mbs, data, position=position, velocity=velocity, rotation=rotation, angular_velocity=angular_velocity,
               gravity=gravity, rayleigh=rayleigh, name=name, color=color)
    res["model"] = model
    return res


def add_full_to_exudyn(mbs, model, *, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0),
                       angular_velocity=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), constrain_rigid: bool = True,
                       rayleigh=(0.0, 0.0), color=(0.9, 0.1, 0.1, 1.0)) -> dict:
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
        a supported model, whose clamped nodes fix the frame, or for a body whose frame is held
        (fixed to the ground, its nodes then held where the body is mounted).
    rayleigh : (alpha, beta)
        Damping ``alpha M + beta K`` of the nodal coordinates (default none); the same as
        ``rayleigh`` of :func:`add_to_exudyn` on a reduced body (``V^T (alpha M + beta K) V``).
        Set here directly: Exudyn's ``AddObjectFFRF`` (1.13.6) drops a stiffness-proportional
        damping without a mass-proportional one.
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
    import exudyn
    from exudyn.FEM import FEMinterface, ObjectFFRFinterface

    from .invariants import node_triples

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
    if any(rayleigh):
        damping = exudyn.MatrixContainer()
        damping.SetWithSparseMatrix(sp.csr_matrix(float(rayleigh[0]) * fem.massMatrix + float(rayleigh[1])
                                                  * fem.stiffnessMatrix), useDenseMatrix=False)
        mbs.SetObjectParameter(res["oFFRF"], "dampingMatrixFF", damping)
    if np.any(gravity):  # the consistent load M Φt g: a force m g at the nodes' mass-weighted mean
        share = np.asarray(fem.massMatrix @ np.tile([1.0, 0.0, 0.0], eq.size // 3))[0::3]
        mass = share.sum()
        res["loadGravity"] = mbs.AddLoad(exudyn.itemInterface.LoadForceVector(
            markerNumber=mbs.AddMarker(exudyn.itemInterface.MarkerSuperElementPosition(
                bodyNumber=res["oFFRF"], meshNodeNumbers=list(range(share.size)), weightingFactors=list(share / mass))),
            loadVector=list(mass * np.asarray(gravity, float))))
    res["node_index"] = {int(k): i for i, k in enumerate(model.node_ids[has])}
    return res


def _interface(body: dict, target):
    """The entry of ``body['interfaces']`` that ``target`` names (``HOLE@rbe2``, ``HOLE@RBE2``, master id) or None."""
    t = str(target).strip()
    for name, itf in body.get("interfaces", {}).items():
        if t.replace(" ", "").upper() == name or (t.lstrip("-").isdigit() and int(t) == itf["master_id"]):
            return itf
    return None


def add_marker(mbs, body: dict, model, target, *, kind: str | None = None) -> int:
    """Marker at a node, a node set or a coupling master of a body in Exudyn.

    Parameters
    ----------
    mbs : exudyn.MainSystem
    body : dict
        As returned by :func:`add_to_exudyn`, :func:`add_npz_to_exudyn` or :func:`add_full_to_exudyn`.
    model : FEModel or None
        The model as read (its node sets); None: the one :func:`add_to_exudyn` recorded.
    target : int or str
        Node id, node-set name, or a coupling of the body (``HOLE@rbe2``, its set ``HOLE@RBE2``
        or its master's node id).
    kind : {'position', 'rigid'}, optional
        ``position``: ``MarkerSuperElementPosition`` at the node, or at the mean of the set's
        nodes (equal weights), or at a coupling master's mesh node. ``rigid``:
        ``MarkerSuperElementRigid`` (position and orientation) fitted to the set's nodes, or to
        a coupling's slave nodes with the master's position as its point: the master's rigid
        motion for an RBE2 (whose slaves move rigidly with it), the set's fitted motion for
        an RBE3. Default ``rigid`` for a coupling, ``position`` otherwise.

    Returns
    -------
    int
        The marker number.

    Raises
    ------
    ModelError
        A node that is not a mesh node of the body; a rigid marker on fewer than three nodes.
    """
    import exudyn.itemInterface as eii

    from ..errors import check_choice, did_you_mean

    model = body.get("model") if model is None else model
    itf = _interface(body, target)
    kind = ("rigid" if itf is not None else "position") if kind is None else kind
    check_choice("kind", kind, ("position", "rigid"))
    obj = body["oFFRFreducedOrder"] if "oFFRFreducedOrder" in body else body["oFFRF"]
    if itf is not None and kind == "position":
        return mbs.AddMarker(eii.MarkerSuperElementPosition(bodyNumber=obj, meshNodeNumbers=[itf["master"]],
                                                            weightingFactors=[1.0]))
    if itf is not None:
        idx, point = list(itf["slaves"]), np.asarray(itf["xyz"], float)
    else:
        if isinstance(target, str) and model is not None and target.upper() in model.node_sets:
            ids = model.node_sets[target.upper()]
        elif str(target).strip().lstrip("-").isdigit():
            ids = [int(target)]
        elif model is None:
            raise ModelError(f"target={target!r} is not a node id nor a coupling of the body "
                             f"({', '.join(body.get('interfaces', {})) or 'none'}), and its node sets are unknown: "
                             "no model was given and none was recorded by add_to_exudyn; pass the FE model as read "
                             f"(add_marker(mbs, body, model, {target!r}), model = flexmor.read(path))",
                             params=("model", "target"))
        else:
            sets = ", ".join(sorted(model.node_sets)) or "none"
            raise ModelError(f"target={target!r} is neither a node id, nor a node set of the model "
                             f"({did_you_mean(str(target), model.node_sets)}sets: {sets}), nor a coupling of the "
                             f"body ({', '.join(body.get('interfaces', {})) or 'none'})", params=("target",))
        missing = [int(k) for k in ids if int(k) not in body["node_index"]]
        if missing:
            raise ModelError(f"target={target!r}: node(s) {missing[:5]} are not mesh nodes of the Exudyn body "
                             "(unknown ids, or clamped nodes of the full body, which move with its frame)",
                             params=("target",))
        idx, point = [body["node_index"][int(k)] for k in ids], None
    w = [1.0 / len(idx)] * len(idx)
    if kind == "position":
        return mbs.AddMarker(eii.MarkerSuperElementPosition(bodyNumber=obj, meshNodeNumbers=idx, weightingFactors=w))
    if len(idx) < 3:
        raise ModelError(f"target={target!r}: a rigid marker needs at least three nodes off one line, "
                         f"got {len(idx)}", params=("target",))
    offset = None
    if point is not None:  # the master's point, against the slaves' mean (reference positions in the frame)
        offset = (point - np.asarray(body["cms"].xRef, float).reshape(-1, 3)[idx].mean(axis=0)).tolist()
    return mbs.AddMarker(eii.MarkerSuperElementRigid(bodyNumber=obj, meshNodeNumbers=idx, weightingFactors=w,
                                                     offset=offset))


EXPORT_FORMATS.register("exudyn", [".exudyn.npz"], write_exudyn,
                        description="Exudyn ObjectFFRFreducedOrderInterface data (.npz) of a reduced body "
                                    "(needs the FE model)")
