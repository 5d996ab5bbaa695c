"""Inertia invariants of a reduced elastic body for the floating frame of reference.

In the floating frame of reference formulation a material point at ``r`` moves to
``r + u``, ``u = Φ q``, relative to a body frame. The equations of motion of the body need,
besides ``Me = Vᵀ M V`` and ``Ke = Vᵀ K V``, the volume integrals ("inertia invariants")
that couple frame motion and deformation (Schwertassek & Wallrapp 1999, ch. 6; the names of
the Standard Input Data, Wallrapp 1994):

=========  ===========  =============================================================
name       shape        definition (``dm`` = mass element, ``Φ_a`` = mode ``a``)
=========  ===========  =============================================================
mass       scalar       ``∫ dm``
mdCM0      (3,)         ``∫ r dm`` (mass times centre of mass)
mdCM1      (3, r)       ``∫ Φ dm`` (= ``Ctᵀ``)
J0         (3, 3)       ``∫ (rᵀr I − r rᵀ) dm`` about the frame origin
J1         (r, 3, 3)    first-order term of ``J(q)``: ``J1[a] = sym(Gr_a)``
Ct         (r, 3)       ``∫ Φᵀ dm``
Cr0        (r, 3)       ``Cr0[a] = ∫ r × Φ_a dm``
Cr1        (r, r, 3)    ``Cr1[a, b] = ∫ Φ_b × Φ_a dm`` (coefficient of ``q_b``)
Gr         (3, 3r)      ``[Gr_1 … Gr_r]``, ``Gr_a = −2 ∫ r̃ Φ̃_a dm``
Ge         (r, 3r)      ``[Ge_1 … Ge_r]``, ``Ge_b[a, k] = 2 Cr1[a, b, k]``
Oe0        (r, 6)       centrifugal, columns ``ωx² ωy² ωz² ωxωy ωyωz ωxωz``
Oe1        (r, r, 6)    first-order term of ``Oe``
=========  ===========  =============================================================

All integrals are evaluated with the FE mass matrix ``M`` itself: a field ``f`` is the vector
of its nodal values and ``∫ f·g dm = fᵀ M g``. The rigid-body fields (translations ``St``,
rotations ``Sr = e_k × r``, the position ``r``) and the rotated modes ``e_k × Φ_a`` are exact
members of the FE space of isoparametric solid elements, so with a consistent mass matrix
the invariants are the exact integrals of the FE displacement field (the inertia tensor of a
box of trilinear hexahedra is exact). For beams and shells with rotational DOFs the rotational
triples are rotated like vectors, which is exact for the rigid-body terms and an
approximation for the second-order terms. The cost is one sparse product of ``M`` with
``6 + 4r`` vectors, O(nnz(M)·r), plus dense products O(N·r²).

References
----------
O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I:
Definition of standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.

R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError, PortError
from ..rigid import rigid_body_modes, rigid_motions

__all__ = ["FrameNode", "Invariants", "compute_invariants", "frame_nodes", "node_frames", "node_triples",
           "check_free_model", "rigid_fields"]

log = logging.getLogger(__name__)


@dataclass
class FrameNode:
    """A node of the SID frame: a marker/interface point of the body.

    Attributes
    ----------
    id : int
        Node id (for a node set: a new id above the model's largest).
    name : str
        The SPEC it came from (node id or set name).
    origin : ndarray (3,)
        Position in the body frame.
    phi, psi : ndarray (3, r)
        Translational and rotational mode shapes at the node.
    load : tuple or None
        ``(space, eqs, W)``: the node's x y z rx ry rz are ``W @ u[eqs]`` (``W`` (6, len(eqs))) of the
        displacement ``u`` of the model as read (``space`` ``"read"``) or of the coupled model the body
        was reduced on (``"coupled"``, a coupling master); a force ``F`` (6,) there loads ``eqs`` with
        ``W.T @ F``.
    """

    id: int
    name: str
    origin: np.ndarray
    phi: np.ndarray
    psi: np.ndarray
    load: tuple | None = None


@dataclass
class Invariants:
    """Inertia invariants of a reduced body (see the module docstring for definitions)."""

    mass: float
    mdCM0: np.ndarray
    J0: np.ndarray
    Ct: np.ndarray
    Cr0: np.ndarray
    Cr1: np.ndarray
    J1: np.ndarray
    Gr: np.ndarray
    Ge: np.ndarray
    Oe0: np.ndarray
    Oe1: np.ndarray
    Me: np.ndarray
    Ke: np.ndarray
    De: np.ndarray | None = None
    nodes: list = field(default_factory=list)

    @property
    def mdCM1(self) -> np.ndarray:
        """``∫ Φ dm`` (3, r)."""
        return self.Ct.T

    @property
    def center_of_mass(self) -> np.ndarray:
        """Centre of mass of the undeformed body."""
        return self.mdCM0 / self.mass

    def inertia_about_com(self) -> np.ndarray:
        """Inertia tensor (3, 3) about the centre of mass (parallel-axis theorem)."""
        c = self.center_of_mass
        return self.J0 - self.mass * (c @ c * np.eye(3) - np.outer(c, c))


def node_triples(model) -> tuple[np.ndarray, np.ndarray]:
    """Equation indices of the translations and rotations of every node.

    Returns
    -------
    trans, rot : ndarray of int, shape (n_nodes, 3)
        ``trans[i, d]`` is the equation of node ``model.node_ids[i]`` in direction ``d + 1``,
        ``rot[i, d]`` the one in direction ``d + 4``; -1 where the model has none.
    """
    if model.dofs is None or not model.n_nodes:
        raise ModelError("the model has no node table and equation map; inertia invariants need node coordinates")
    pos = np.searchsorted(model.node_ids, model.dofs[:, 0], sorter=np.argsort(model.node_ids))
    node_row = np.argsort(model.node_ids)[pos]
    table = -np.ones((model.n_nodes, 6), dtype=np.int64)
    table[node_row, model.dofs[:, 1] - 1] = np.arange(model.n_dof)
    return table[:, :3], table[:, 3:]


def _gather(W, idx):
    """Nodal triples (n_nodes, 3, m) of the columns of ``W``; zero where the DOF is absent."""
    out = np.zeros((idx.shape[0], 3, W.shape[1]))
    ok = idx >= 0
    out[ok] = W[idx[ok]]
    return out


def _scatter(T, idx, n):
    out = np.zeros((n, T.shape[2]))
    ok = idx >= 0
    out[idx[ok]] = T[ok]
    return out


def _cross_fields(W, trans, rot, n):
    """``[e_x × W, e_y × W, e_z × W]`` applied node-wise to translations and rotations, (n, 3m)."""
    out = []
    for k in range(3):
        Y = np.zeros((n, W.shape[1]))
        for idx in (trans, rot):
            if np.any(idx >= 0):
                T = _gather(W, idx)
                C = np.zeros_like(T)
                i, j = (k + 1) % 3, (k + 2) % 3  # e_k × t = (.., -t_j at i, t_i at j)
                C[:, i] = -T[:, j]
                C[:, j] = T[:, i]
                Y += _scatter(C, idx, n)
        out.append(Y)
    return np.hstack(out)


def rigid_fields(model):
    """Translations St (n, 3), rotations about the origin Sr (n, 3) and position X (n,) as nodal
    vectors (:func:`flexmor.rigid.rigid_motions` about the origin; X holds the
    coordinate of each translational equation's node along its direction)."""
    R = rigid_motions(model, origin=np.zeros(3))
    X = np.zeros(model.n_dof)
    xyz, d = model.node_xyz(model.dofs[:, 0]), model.dofs[:, 1]
    for a in range(3):
        X[d == a + 1] = xyz[d == a + 1, a]
    return R[:, :3], R[:, 3:], X


def compute_invariants(model, V, *, K=None, D=None, nodes=()) -> Invariants:
    """Inertia invariants of the basis ``V`` on the FE model ``model``.

    Parameters
    ----------
    model : FEModel
        The full model (mass matrix, node coordinates, equation map).
    V : ndarray, shape (n_dof, r)
        The basis at the model's equations (``ReducedModel.V``).
    K, D : ndarray (r, r), optional
        Reduced stiffness and damping; default ``Vᵀ K V`` and ``Vᵀ D V`` of the model.
    nodes : sequence of FrameNode
        Frame nodes to carry along (see :func:`frame_nodes`).

    Returns
    -------
    Invariants

    Raises
    ------
    ModelError
        Without node table, or when ``V`` does not match the model.
    """
    V = np.asarray(V, dtype=float)
    if V.ndim != 2 or V.shape[0] != model.n_dof:
        raise ModelError(f"basis has shape {V.shape}, but the model {model.name!r} has {model.n_dof} equations; "
                         "export needs the model the body was reduced from")
    trans, rot = node_triples(model)
    n, r = model.n_dof, V.shape[1]
    St, Sr, X = rigid_fields(model)
    Y = _cross_fields(V, trans, rot, n)  # (n, 3r): columns k*r + b = e_k × Φ_b
    F = np.hstack([St, Sr, X[:, None], V, Y])
    MF = np.asarray(model.M @ F)
    MSt, MSr, MX, MV, MY = MF[:, :3], MF[:, 3:6], MF[:, 6], MF[:, 7:7 + r], MF[:, 7 + r:]
    Mtt = St.T @ MSt
    mass = float(np.trace(Mtt) / 3)
    if np.max(np.abs(Mtt - mass * np.eye(3))) > 1e-8 * mass:
        log.warning("%s: translational mass differs by direction (%s); constrained DOFs removed from the "
                    "model lose their mass, so mass, mdCM and J describe the free part only",
                    model.name, np.diag(Mtt))
    mdCM0 = St.T @ MX
    J0 = Sr.T @ MSr
    Ct = V.T @ MSt
    Cr0 = V.T @ MSr
    Me = V.T @ MV
    G = 2.0 * MSr.T @ Y  # (3, 3r): [k, l*r + a] = Gr_a[k, l]
    Gr_t = G.reshape(3, 3, r).transpose(2, 0, 1)  # (r, 3, 3): Gr_a
    C = MV.T @ Y  # (r, 3r): [a, k*r + b] = ∫ Φ_a·(e_k × Φ_b) = Cr1[a, b, k]
    Cr1 = C.reshape(r, 3, r).transpose(0, 2, 1)
    YMY = Y.T @ MY  # (3r, 3r) blocks (k, l): ∫ (e_k × Φ_a)·(e_l × Φ_b)
    B = YMY.reshape(3, r, 3, r).transpose(0, 2, 1, 3)  # [k, l, a, b]
    J1 = 0.5 * (Gr_t + Gr_t.transpose(0, 2, 1))
    Oe0 = np.stack([-0.5 * J1[:, 0, 0], -0.5 * J1[:, 1, 1], -0.5 * J1[:, 2, 2],
                    -J1[:, 0, 1], -J1[:, 1, 2], -J1[:, 0, 2]], axis=1)
    Oe1 = np.stack([-B[0, 0], -B[1, 1], -B[2, 2], -(B[1, 0] + B[0, 1]), -(B[2, 1] + B[1, 2]),
                    -(B[2, 0] + B[0, 2])], axis=2)
    Oe1 = 0.5 * (Oe1 + Oe1.transpose(1, 0, 2))
    Ke = np.asarray(V.T @ (model.K @ V)) if K is None else np.asarray(K, dtype=float)
    if D is None and model.D is not None:
        D = V.T @ (model.D @ V)

    def sym(A):
        return None if A is None else 0.5 * (A + A.T)

    return Invariants(
        mass=mass, mdCM0=mdCM0, J0=sym(J0), Ct=Ct, Cr0=Cr0, Cr1=Cr1, J1=J1,
        Gr=Gr_t.transpose(1, 0, 2).reshape(3, 3 * r),  # column 3a + l
        Ge=2.0 * Cr1.reshape(r, 3 * r),  # column 3b + k
        Oe0=Oe0, Oe1=Oe1, Me=sym(Me), Ke=sym(Ke), De=sym(D), nodes=list(nodes))


def check_free_model(model, *, allow_clamped: bool = False) -> int:
    """Refuse a supported (clamped) model for a floating-frame export; return its rigid-body mode count.

    A model with boundary conditions has lost the equations of its supported nodes, and with
    them their mass: the body's mass, centre of mass and inertia tensor in the floating frame
    would be those of the unsupported part only. ``allow_clamped=True`` is the explicit choice
    for a body whose frame does not move (fixed to the ground), where the inertia terms do not act.

    Raises
    ------
    ModelError
        The model has fewer than six rigid-body modes and ``allow_clamped`` is False.
    """
    n = int(rigid_body_modes(model).shape[1])
    if n < 6 and not allow_clamped:
        raise ModelError(
            f"{model.source or model.name} is supported ({n} of 6 rigid-body modes): the nodes held by its boundary "
            "conditions and their mass are not in the model, so the floating-frame body would carry a wrong mass, "
            "centre of mass and inertia; reduce the free model (no boundary conditions; rigid-body modes "
            "excluded) for FFRF export, or pass allow_clamped for a body whose frame does not move",
            params=("allow_clamped",))
    return n


def _spec_targets(body) -> list[str]:
    out = []
    specs = list(body.input_names) + list(body.output_names)
    iface = body.info.get("interface") if isinstance(body.info, dict) else None
    if isinstance(iface, (list, tuple)):
        specs += [str(s) for s in iface]
    elif isinstance(iface, str):
        specs.append(iface)
    for s in specs:
        if re.search(r":[A-Za-z]+~\d+$", str(s).strip()):  # a moving load's compressed input: no point of the body
            continue
        t = str(s).rsplit(":", 1)[0] if ":" in str(s) else str(s)
        t = t.strip()
        if t and t.upper() not in [x.upper() for x in out]:
            out.append(t)
    return out


def frame_nodes(model, V, specs=None, body=None, *, masters=()) -> list[FrameNode]:
    """Frame nodes (marker/interface points) of the SID file.

    Parameters
    ----------
    model : FEModel
        The model as read (:attr:`flexmor.expansion.ExpandedBody.model`).
    V : ndarray (n_dof, r)
        The basis at its equations.
    specs : sequence of str, optional
        Node ids or node sets. A coupling master (``HOLE@rbe2``, its set name ``HOLE@RBE2`` or its
        node id, one of ``masters``) gives the master node itself: its translations as ``phi`` and
        its rotations as ``psi``. A single node gives its own translations and, if the model has
        them, its rotational DOFs as ``psi`` (else zero). A set of several nodes (or
        ``SET@rbe3``) gives an RBE3 master at the set's centroid: the weighted least-squares
        rigid motion of the set's translations (:func:`flexmor.couplings.rbe3_matrix`).
        Default: the port and interface targets of ``body`` and every master.
    body : ReducedModel, optional
    masters : sequence of MasterNode
        The body's coupling masters (:func:`flexmor.expansion.expand_body`).

    Raises
    ------
    PortError
        No frame node could be found, or an unknown node/set.
    """
    from ..couplings import parse_coupling, rbe3_matrix

    masters = list(masters)
    if specs is None:
        specs = _spec_targets(body) if body is not None else []
        specs = [s for s in specs if not _is_generic(s)]
        named = {m.id for m in masters for s in specs if m.matches(s)}
        specs += [m.name for m in masters if m.id not in named]
    if not specs:
        raise PortError("no nodes for the SID frame: the reduced body names no port or interface nodes; "
                        "give them as nodes (node ids or node sets, e.g. TIP and 12)", params=("nodes",))
    trans, rot = node_triples(model)
    index = {int(k): i for i, k in enumerate(model.node_ids)}
    next_id = max([int(model.node_ids.max())] + [m.id for m in masters]) + 1
    out = []
    for spec in specs:
        name = str(spec).strip()
        master = next((m for m in masters if m.matches(name)), None)
        if master is not None:
            out.append(FrameNode(master.id, master.name, np.array(master.xyz, float), master.rows[:3].copy(),
                                 master.rows[3:].copy(),  # its one name, however the spec spells it
                                 ("coupled", np.asarray(master.eqs, dtype=np.int64), np.eye(6))))
            continue
        target = parse_coupling(name)[0] if "@" in name else name
        if target.upper() in model.node_sets:
            ids = model.node_sets[target.upper()]
        elif target.lstrip("-").isdigit() and int(target) in index:
            ids = np.array([int(target)])
        else:
            known = ", ".join(sorted(model.node_sets) + [m.name for m in masters]) or "none"
            raise PortError(f"SID frame node {name!r} is neither a node id nor a node set (sets: {known})")
        if ids.size == 1 and "@" not in name:
            out += node_frames(model, V, ids, [name], triples=(trans, rot))
            continue
        centroid = model.node_xyz(ids).mean(axis=0)
        eqs, W = rbe3_matrix(model, ids, centroid)
        out.append(FrameNode(next_id, name, centroid, W[:3] @ V[eqs], W[3:] @ V[eqs], ("read", np.asarray(eqs), W)))
        log.info("SID frame node %d: RBE3 master of %s (%d nodes) at %s", next_id, name, ids.size, centroid)
        next_id += 1
    return out


def node_frames(model, V, ids, names, *, triples=None) -> list[FrameNode]:
    """Frame nodes of single nodes ``ids`` (named ``names``) of ``model``: each at its position, its
    translations as ``phi`` and its rotational DOFs as ``psi`` (zero where the model has none).
    ``triples``: :func:`node_triples` of the model when known."""
    trans, rot = node_triples(model) if triples is None else triples
    index = {int(k): i for i, k in enumerate(model.node_ids)}
    out = []
    for k, name in zip(ids, names):
        if int(k) not in index:
            raise PortError(f"SID frame node {name!r}: node {int(k)} is not a node of the model")
        i = index[int(k)]
        own = np.concatenate([trans[i], rot[i]])
        out.append(FrameNode(int(k), str(name), model.xyz[i].copy(), _gather(V, trans[i:i + 1])[0],
                             _gather(V, rot[i:i + 1])[0], ("read", own[own >= 0], np.eye(6)[:, own >= 0])))
    return out


def _is_generic(name: str) -> bool:
    return bool(name) and name[0] in "uy" and name[1:].isdigit()
