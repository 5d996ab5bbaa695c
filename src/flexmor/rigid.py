"""Rigid-body motion of an FE model, the M-projections that remove it, and the elastic body of a floating frame.

In the floating frame of reference (FFRF) the rigid motion of a free body belongs to the
frame; the elastic coordinates must not contain it, or ``Ke = Vᵀ K V`` is singular and the
frame and the modes are redundant. The rigid motions of the model's geometry
(:func:`rigid_motions`) give its M-orthonormal rigid-body modes Φ (:func:`rigid_body_modes`),
and a basis is made mass-orthogonal to them by :func:`exclude_rigid`, the one place where rigid
motion leaves a basis (:func:`flexmor.reduction.reduce` applies it before the projection, an
export through :func:`elastic_body`):

    V  <-  (I - Φ Φᵀ M) V,   Φ the M-orthonormal rigid-body modes,

twice, then an order-preserving orthonormalization that drops the directions that were rigid
(the constraint modes of a Craig-Bampton basis span the rigid motions: they leave as many
columns), and a last projection so that the kept columns are clean to round-off of their own
size. Since ``span(V)`` then lies in the M-orthogonal complement of the rigid modes, the
reduced frequencies are Rayleigh-Ritz upper bounds of the full model's free-free elastic
ones, and moments of the flexible part that ``span(V)`` matched stay matched (the projector
leaves flexible vectors unchanged).

This module sits below the reduction methods, the analysis and the exporters, which all use it.

References
----------
Craig, R. R., Kurdila, A. J. (2006). Fundamentals of Structural Dynamics, 2nd ed., Wiley,
ch. 18-19 (free-interface and fixed-interface CMS of free components).

Schwertassek, R., Wallrapp, O. (1999). Dynamik flexibler Mehrkörpersysteme. Vieweg, ch. 6
(reference conditions of the elastic coordinates).
"""

from __future__ import annotations

import logging
import warnings

import numpy as np
import scipy.linalg as sla

from .basis import Basis
from .errors import FlexmorError, FlexmorWarning, ModelError
from .linalg import amg
from .linalg.amg import NearNull, node_block
from .linalg.threads import sparse_dense
from .ports import body_ports
from .projection import project

__all__ = ["ACCELERATIONS", "rigid_motions", "can_move_rigidly", "frame_participation", "rigid_body_modes", "m_project",
           "elastic_loads",
           "exclude_rigid", "elastic_body", "rigid_content", "rigid_residual", "RIGID_DEFLATION_TOL", "POLISH_TOL",
           "RIGID_CONTENT_TOL"]

log = logging.getLogger(__name__)

#: Names of the frame's six accelerations as static loads ``M R`` (the columns of :func:`rigid_motions`):
#: gravity (a unit translational acceleration) in x, y, z and a unit angular acceleration about x, y, z.
ACCELERATIONS = ("gravity:x", "gravity:y", "gravity:z", "angular:rx", "angular:ry", "angular:rz")

#: Relative norm below which a column made M-orthogonal to the rigid modes counts as rigid (dropped).
RIGID_DEFLATION_TOL = 1e-8

#: Relative norm a column may lose to the projection and still be kept as the method made it (polished).
POLISH_TOL = 1e-6


def rigid_motions(model, origin=None) -> np.ndarray:
    """The six rigid motions of the model's geometry as nodal fields, (n_dof, 6), unnormalized.

    Columns: unit translations x, y, z, then unit rotations about x, y, z through ``origin``
    (default the mean position of the equations' nodes; ``e_a x (x - x_o)`` on translational
    DOF, ``1`` on rotational DOF). A column is zero where the model has no DOF in that
    direction; all are zero without geometry.
    """
    R = np.zeros((model.n_dof, 6))
    if model.dofs is None or model.n_nodes == 0:
        return R
    xyz = model.node_xyz(model.dofs[:, 0])
    xyz = xyz - (xyz.mean(axis=0) if origin is None else np.asarray(origin, dtype=float))
    d = model.dofs[:, 1]
    for a in range(3):
        R[d == a + 1, a] = 1.0
        e = np.eye(3)[a]
        for j in range(3):  # (e_a x x)_j on translations
            R[d == j + 1, 3 + a] = np.cross(e, xyz[d == j + 1])[:, j]
        R[d == a + 4, 3 + a] = 1.0
    return R


def can_move_rigidly(model) -> bool:
    """Whether some combination of the geometry's rigid motions (:func:`rigid_motions`) has a Rayleigh quotient
    ``x^T K x / x^T M x`` below ``1e3`` times the rigid-body threshold
    (:func:`flexmor.linalg.eigen.rigid_body_threshold`): a free body, or one held at a single node or about an
    axis, can; a supported body cannot. True where the
    model has fewer than six rigid motions (no geometry): nothing is known. A rigid-body mode that is not a
    motion of the whole geometry (a loose part) is not seen here."""
    from .linalg.eigen import rigid_body_threshold

    R = rigid_motions(model)
    nrm = np.linalg.norm(R, axis=0)
    if np.count_nonzero(nrm) < 6:
        return True
    R = R / nrm
    GK, GM = R.T @ (model.K @ R), R.T @ (model.M @ R)
    mu = sla.eigh(0.5 * (GK + GK.T), 0.5 * (GM + GM.T), eigvals_only=True)
    return bool(mu[0] < 1e3 * rigid_body_threshold(model.K, model.M))


def register_near_null(solver, model) -> None:
    """Register the rigid motions of ``model``'s geometry (:func:`rigid_motions`) in ``solver`` as the
    near-null space of the ``amg`` backend's hierarchies of matrices of the model's size
    (:mod:`flexmor.linalg.amg`); nothing without geometry. Costs nothing until that backend asks."""
    if model.dofs is None or not model.n_nodes:
        return

    def make() -> NearNull | None:
        R = rigid_motions(model)
        R = R[:, np.linalg.norm(R, axis=0) > 0]
        return NearNull(R, node_block(model.dofs)) if R.shape[1] else None

    amg.register_near_null(solver, model.n_dof, make)


def frame_participation(model, V) -> tuple[np.ndarray, np.ndarray]:
    """``(V^T M R, diag(R^T M R))``: how the basis ``V`` (n_dof, r) takes part in the six rigid
    motions ``R`` of the frame (:func:`rigid_motions` about the origin of the model's coordinates:
    translations x y z, rotations about x y z), and the model's mass in x y z and rotary inertia
    about those axes. The effective masses of the body's modes follow from them
    (:func:`flexmor.modal.mode_table`)."""
    R = rigid_motions(model, origin=np.zeros(3))
    MR = model.M @ R
    return np.asarray(V).T @ MR, np.einsum("ij,ij->j", R, MR)


def rigid_body_modes(model) -> np.ndarray:
    """M-orthonormal rigid-body modes of a free body from its geometry, (n_dof, k), k <= 6, read-only.

    The six rigid motions (:func:`rigid_motions`) with ``||K phi|| <= 1e-8 ||K||_1 ||phi||``
    are rigid-body modes of the model (none for a supported body or a model without
    geometry). Costs six sparse products, no eigen solve; kept by the model for the next call
    while its ``K``, ``M``, equations, node ids and coordinates are the same objects (a reduction asks
    three to four times).
    """
    key = (model.K, model.M, model.dofs, model.node_ids, model.xyz)
    kept = model.__dict__.get("_rigid_body_modes")
    if kept is not None and all(a is b for a, b in zip(kept[0], key)):
        return kept[1]
    phi = _rigid_body_modes(model)
    phi.flags.writeable = False
    model.__dict__["_rigid_body_modes"] = (key, phi)
    return phi


def _rigid_body_modes(model) -> np.ndarray:
    R = rigid_motions(model)
    nrm = np.linalg.norm(R, axis=0)
    R = R[:, nrm > 0] / nrm[nrm > 0]
    if R.shape[1] == 0:
        return R
    kn = abs(model.K).sum(axis=0).max()
    R = R[:, np.linalg.norm(model.K @ R, axis=0) <= 1e-8 * kn]
    if R.shape[1] == 0:
        return R
    G = R.T @ (model.M @ R)
    w, U = np.linalg.eigh(0.5 * (G + G.T))
    keep = w > 1e-12 * w[-1]
    return R @ (U[:, keep] / np.sqrt(w[keep]))


def m_project(model, phi, X):
    """Displacements ``X`` made M-orthogonal to the modes ``phi``: ``(I - Φ Φᵀ M) X``."""
    return X - phi @ (phi.T @ sparse_dense(model.M, X))


def elastic_loads(model, phi, F):
    """The elastic part of the loads ``F``: ``(I - M Φ Φᵀ) F`` (no work on the rigid-body modes ``phi``)."""
    return F - model.M @ (phi @ (phi.T @ F))


def rigid_residual(model, V, phi=None) -> float:
    """Largest relative rigid content of a column of ``V``: ``max_j ‖Φᵀ M v_j‖ / ‖v_j‖_M`` (0 if clean)."""
    phi = rigid_body_modes(model) if phi is None else phi
    if phi.shape[1] == 0 or V.shape[1] == 0:
        return 0.0
    MV = sparse_dense(model.M, V)
    nrm = np.sqrt(np.clip(np.einsum("ij,ij->j", V, MV), 0.0, None))
    c = np.linalg.norm(phi.T @ MV, axis=0)
    return float(np.max(c / np.where(nrm > 0, nrm, 1.0)))


def _orthonormal_in_order(X, tol: float, ref=None):
    """Orthonormal columns spanning ``X`` in the order of its columns (the first ``k`` results span
    the leading kept columns), dropping those whose part outside the earlier ones is at most
    ``tol * ref[j]`` (``ref`` defaults to the columns' own norms; pass the norms the columns had
    before a projection to drop columns that the projection emptied). The parts are the diagonal
    of a Householder QR of ``X`` (no pivoting: the order is kept), whose ``Q`` is the result when no
    column is dropped (else a QR of the kept columns), with the signs of Gram-Schmidt (a positive
    diagonal)."""
    ref = np.linalg.norm(X, axis=0) if ref is None else np.asarray(ref, dtype=float)
    if X.shape[1] == 0:
        return X[:, :0].copy(), []
    Q, R = np.linalg.qr(X)
    d = np.abs(np.diag(R))
    keep = [j for j in range(X.shape[1]) if d[j] > tol * ref[j] and d[j] > 0]
    if not keep:
        return X[:, :0].copy(), keep
    if len(keep) < X.shape[1]:
        Q, R = np.linalg.qr(X[:, keep])
    sign = np.sign(np.diag(R))
    return Q * np.where(sign == 0, 1.0, sign), keep


def exclude_rigid(model, basis: Basis) -> Basis:
    """``basis`` made mass-orthogonal to the rigid-body modes of ``model`` (when it excludes them).

    Acts when ``basis.info['rigid'] == 'exclude'`` and the model has rigid-body modes (a free
    or partly supported body). With ``rigid == 'include'`` and ``info['n_rigid_included'] = h``
    (the leading ``h`` columns are rigid-body modes) the columns after them are cleaned the same
    way, so that the body holds exactly those rigid motions. Otherwise ``basis`` is returned
    unchanged.

    Parameters
    ----------
    model : FEModel
    basis : Basis

    Returns
    -------
    Basis
        The method's columns, only projected, when none loses more than :data:`POLISH_TOL` of its
        norm (a basis clean up to round-off, e.g. eigenmodes); else the cleaned columns,
        orthonormal (Euclidean). Either way M-orthogonal to the rigid-body modes to round-off
        (``info['rigid_residual']``, relative), in the order of the method's columns (a nested
        basis stays nested); for ``exclude`` ``info['n_rigid_excluded']`` the number of
        rigid-body modes and ``info['n_rigid_dropped']`` the columns that were rigid motion.
    """
    rigid = basis.info.get("rigid")
    head = int(basis.info.get("n_rigid_included", 0)) if rigid == "include" else 0
    if rigid not in ("exclude", "include") or (rigid == "include" and not head):
        return basis
    phi = rigid_body_modes(model)
    if phi.shape[1] == 0:
        return basis
    V0 = np.asarray(basis.V, dtype=float)[:, head:]
    X = V0
    for _ in range(2):
        X = m_project(model, phi, X)
    # relative to the method's columns: a column that was rigid motion leaves only round-off
    scale = np.linalg.norm(V0, axis=0)
    kept = np.linalg.norm(X, axis=0) / np.where(scale > 0, scale, 1.0)
    if np.all(kept > 1 - POLISH_TOL):  # (nearly) clean already, e.g. eigenmodes: the method's columns, polished
        Q = X
    else:
        # a column that was rigid motion keeps only round-off of the method's column: dropped
        Q, _ = _orthonormal_in_order(X, RIGID_DEFLATION_TOL, ref=scale)
        Q = m_project(model, phi, Q)  # clean to round-off of unit columns
        Q, _ = _orthonormal_in_order(Q, RIGID_DEFLATION_TOL)
    info = dict(basis.info, rigid_residual=rigid_residual(model, Q, phi))
    if rigid == "exclude":
        info.update(n_rigid_excluded=int(phi.shape[1]), n_rigid_dropped=int(X.shape[1] - Q.shape[1]))
    if Q.shape[1] < X.shape[1]:
        log.info("%s: %d columns were rigid-body motion and are dropped", basis.method, X.shape[1] - Q.shape[1])
    return Basis(np.hstack([np.asarray(basis.V, dtype=float)[:, :head], Q]), basis.method, info)


def rigid_content(model, V) -> float:
    """How well ``span(V)`` contains a rigid motion: the smallest relative M-norm of the part of
    a rigid motion (:func:`rigid_motions`) outside ``span(V)`` (0: ``V`` contains one; 1: ``V`` is
    M-orthogonal to all of them; 1 also for a model without geometry)."""
    R = rigid_motions(model)
    R = R[:, np.linalg.norm(R, axis=0) > 0]
    MR = model.M @ R
    Grr = R.T @ MR
    if R.shape[1] == 0 or not np.all(np.linalg.eigvalsh(Grr) > 0):
        return 1.0
    Gvv = V.T @ sparse_dense(model.M, V)
    Gvr = V.T @ MR
    P = Grr - Gvr.T @ np.linalg.solve(Gvv, Gvr)
    lam = sla.eigh(0.5 * (P + P.T), 0.5 * (Grr + Grr.T), eigvals_only=True)
    return float(np.sqrt(max(lam[0], 0.0)))


#: :func:`rigid_content` below which a basis contains a rigid-body motion.
RIGID_CONTENT_TOL = 1e-6


def elastic_body(model, body, *, remove_rigid: bool = False):
    """The body for a floating-frame export: its basis without rigid-body motion.

    In the floating frame the rigid motion belongs to the frame. A body whose basis contains
    a rigid-body motion (``rigid='include'``, or a method that does not separate it; measured
    by :func:`rigid_content`) would be singular there (``Ke`` has zero
    eigenvalues, the frame and the modes are redundant). Such a body is refused: the body
    exported must be the body reduced and judged (reduce it with ``rigid='exclude'``, the
    default). With ``remove_rigid`` its basis is made mass-orthogonal to the rigid-body modes
    (:func:`exclude_rigid`) and projected again, with the body's ports and the model's
    damping; a one-line :class:`~flexmor.errors.FlexmorWarning` says so and
    ``info['rigid_removed_at_export']`` records the order it had.
    A basis that only couples with the frame motion without containing any rigid motion (an
    attached frame: modes held at a node set, ``Ct, Cr != 0``) is a valid choice of reference
    conditions and is kept, as is a model without rigid-body modes.

    Raises
    ------
    ModelError
        A body that holds rigid motion without ``remove_rigid``; with it, when the body's ports
        cannot be rebuilt on ``model`` (they are needed for the projection).
    """
    phi = rigid_body_modes(model)
    if body.V is None or phi.shape[1] == 0 or rigid_content(model, body.V) >= RIGID_CONTENT_TOL:
        return body
    try:
        ports = body_ports(model, body)
    except FlexmorError as exc:
        raise ModelError(f"the {body.method} body holds rigid-body motion, which the floating frame carries; "
                         f"removing it needs the body's ports on the model: {exc}") from None
    basis = exclude_rigid(model, Basis(body.V, body.method, dict(body.info, rigid="exclude")))
    elastic = project(model, basis, ports)
    change = (f"made mass-orthogonal to the {phi.shape[1]} rigid-body modes (order {body.order} -> {elastic.order}), "
              "another body than the one reduced and judged")
    if not remove_rigid:
        raise ModelError(f"the {body.method} body holds rigid-body motion, which the floating frame carries; "
                         f"exporting it would need its basis {change}. Reduce with rigid='exclude' (the default for "
                         "free bodies), or pass remove_rigid to allow the change (flexmor export then "
                         "states the error of the body it writes)", params=("remove_rigid",))
    elastic.info["rigid_removed_at_export"] = {"order_reduced": body.order, "order_exported": elastic.order}
    if elastic.info.get("frame_participation") is not None:  # of the new basis
        elastic.info["frame_participation"] = frame_participation(model, elastic.V)[0].tolist()
    elastic.origin = dict(body.origin)  # with the couplings and selections the body was made with
    elastic.couplings, elastic.selections = list(body.couplings), list(body.selections)
    elastic.order_note = body.order_note
    if body.stress_modes is not None:  # linear in the basis: V_e = (I - Φ Φᵀ M) V T, and rigid motion has no stress
        T = np.linalg.lstsq(m_project(model, phi, np.asarray(body.V, float)), elastic.V, rcond=None)[0]
        elastic.stress_modes = np.einsum("ij,ikl->jkl", T, body.stress_modes)
        elastic.stress_nodes = body.stress_nodes
    warnings.warn(f"{body.method} body: its basis holds rigid-body motion, which the floating frame carries; "
                  f"exported with its basis {change}", FlexmorWarning, stacklevel=2)
    return elastic
