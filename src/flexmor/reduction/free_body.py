"""Free bodies for the floating frame of reference: the one place where rigid motion leaves a basis.

In the floating frame of reference (FFRF) the rigid motion of a free body belongs to the
frame; the elastic coordinates must not contain it, or ``Ke = Vᵀ K V`` is singular and the
frame and the modes are redundant. Whatever the method, a basis whose method records
``info['rigid'] == 'exclude'`` is made mass-orthogonal to the model's rigid-body modes by
:func:`exclude_rigid`, which :func:`flexmor.reduction.reduce` applies before the projection:

    V  <-  (I - Φ Φᵀ M) V,   Φ the M-orthonormal rigid-body modes (:func:`rigid_body_modes`),

twice, then an order-preserving orthonormalization that drops the directions that were rigid
(the constraint modes of a Craig-Bampton basis span the rigid motions: they leave as many
columns), and a last projection so that the kept columns are clean to round-off of their own
size. Since ``span(V)`` then lies in the M-orthogonal complement of the rigid modes, the
reduced frequencies are Rayleigh-Ritz upper bounds of the full model's free-free elastic
ones, and moments of the flexible part that ``span(V)`` matched stay matched (the projector
leaves flexible vectors unchanged).

:func:`check_body` is the guard against bodies that are written but wrong: a reduced mode
below the full model's first elastic frequency that is not a rigid-body mode (a Galerkin
body whose basis holds no rigid motion cannot have one), or a band_error above 1, is
reported with a one-line :class:`~flexmor.errors.FlexmorWarning` that says why and what to do.

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
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg.norm)

from ..basis import Basis
from ..errors import FlexmorWarning
from ..linalg.eigen import rigid_body_threshold

__all__ = ["rigid_motions", "rigid_body_modes", "interface_loads", "rigid_head", "m_project", "elastic_loads",
           "inertia_relief_modes", "with_elastic_inputs", "with_inertia_loads", "INERTIA_LOAD_NAMES", "exclude_rigid",
           "elastic_body", "rigid_content", "rigid_residual", "check_body", "spurious_modes_hz"]

log = logging.getLogger(__name__)

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


def rigid_body_modes(model) -> np.ndarray:
    """M-orthonormal rigid-body modes of a free body from its geometry, (n_dof, k), k <= 6.

    The six rigid motions (:func:`rigid_motions`) with ``||K phi|| <= 1e-8 ||K||_1 ||phi||``
    are rigid-body modes of the model (none for a supported body or a model without
    geometry). Costs six sparse products, no eigen solve.
    """
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
    return X - phi @ (phi.T @ (model.M @ X))


def elastic_loads(model, phi, F):
    """The elastic part of the loads ``F``: ``(I - M Φ Φᵀ) F`` (no work on the rigid-body modes ``phi``)."""
    return F - model.M @ (phi @ (phi.T @ F))


def rigid_head(model, loads, rigid: str):
    """``(phi, head)``: the rigid-body modes of ``model`` and, for ``rigid='include'``, those the
    dense ``loads`` (e.g. ``B``) excite (the leading columns of a basis that keeps the rigid
    motion); ``head`` is empty for ``'exclude'`` or a supported body."""
    from ..errors import check_choice

    check_choice("rigid", rigid, ("include", "exclude"))
    phi = rigid_body_modes(model)
    head = np.zeros((model.n_dof, 0))
    if phi.shape[1] and rigid == "include":
        w = np.linalg.norm(phi.T @ loads, axis=1)
        head = phi[:, w > 1e-8 * w.max(initial=0.0)] if w.max(initial=0.0) > 0 else head
    return phi, head


#: Relative change of the inertia-relief responses at which their refinement stops.
RELIEF_TOL = 1e-13


def inertia_relief_modes(model, dofs, *, phi=None, solver=None) -> np.ndarray:
    """Static elastic responses of a free body to unit forces at the equations ``dofs``, balanced
    by the inertia of its rigid motion (inertia relief), M-orthogonal to the rigid-body modes:

        x_j = K⁺ (I - M Φ Φᵀ) e_j,   Φᵀ M x_j = 0.

    ``K`` is singular; the responses come from the positive definite ``A = K - σ M``
    (σ = :func:`flexmor.linalg.eigen.default_shift` < 0) with refinement
    ``x <- P (x + A⁻¹ (f - K x))``, ``P = I - Φ Φᵀ M``, whose error shrinks by ``|σ| / (ω² + |σ|)``
    per step in each elastic mode ω, until the relative change is below :data:`RELIEF_TOL`
    (a few steps). One factorization, a few solves per column.
    """
    from ..linalg import factorize
    from ..linalg.eigen import default_shift

    phi = rigid_body_modes(model) if phi is None else phi
    dofs = np.asarray(dofs, dtype=np.int64)
    E = np.zeros((model.n_dof, dofs.size))
    E[dofs, np.arange(dofs.size)] = 1.0
    f = elastic_loads(model, phi, E)
    sigma = default_shift(model.K, model.M)
    F = factorize((model.K - sigma * model.M).tocsr(), solver=solver, positive=True)

    x = m_project(model, phi, F.solve(f))
    for _ in range(50):
        dx = m_project(model, phi, F.solve(f - model.K @ x))
        x = x + dx
        if np.linalg.norm(dx) <= RELIEF_TOL * np.linalg.norm(x):
            break
    return x


def with_elastic_inputs(model, ports):
    """``ports`` with the elastic part ``(I - M Φ Φᵀ) B`` of its inputs appended (named ``elastic:...``)
    for a free body (Φ its M-orthonormal rigid-body modes); ``ports`` itself for a supported body.

    The response to the appended inputs is the elastic part of the response to ``B`` (exact for
    proportional damping), computed directly: at low frequencies, or over long times, the
    rigid-body response exceeds it by orders of magnitude, and a difference of the two would be
    round-off. The floating frame's bodies (rigid motion excluded) are judged on it.
    """
    from ..ports import Ports

    phi = rigid_body_modes(model)
    if not phi.shape[1] or not ports.n_inputs:
        return ports
    B = ports.B.toarray()
    Be = elastic_loads(model, phi, B)
    return Ports(B=sp.hstack([ports.B, sp.csr_matrix(Be)]).tocsr(), C=ports.C,
                 input_names=list(ports.input_names) + [f"elastic:{n}" for n in ports.input_names],
                 output_names=list(ports.output_names))


#: Names of the inertia-load inputs (unit accelerations of the frame: translations, rotations).
INERTIA_LOAD_NAMES = ("inertia:ax", "inertia:ay", "inertia:az", "inertia:arx", "inertia:ary", "inertia:arz")


def interface_loads(model, node) -> np.ndarray:
    """The frame's six unit accelerations on a free body held at the master ``node``, (n_dof, 6).

    Column k is ``f_k = M r_k + E_m λ_k`` (``r_k`` the k-th rigid motion, :func:`rigid_motions`;
    ``E_m`` the master's six equations) with the reaction ``λ_k = -(R_mᵀ)⁻¹ Rᵀ M r_k`` at the master
    (``R_m`` the rigid motions' rows there), so that ``Rᵀ f_k = 0``: the loads are in equilibrium,
    and the free body's static response to ``f_k`` is the deflection of the body clamped at the
    master under that acceleration, plus a rigid motion. A ModelError when ``node`` has not six
    equations at which the rigid motions are defined.
    """
    from ..errors import ModelError

    eqs = np.flatnonzero(model.dofs[:, 0] == int(node)) if model.dofs is not None else np.zeros(0, np.int64)
    R = rigid_motions(model)
    if eqs.size != 6 or np.linalg.cond(R[eqs]) > 1e12:
        raise ModelError(f"node {node} is not a 6-DOF master node at which the rigid motions are defined")
    MR = model.M @ R
    F = np.asarray(MR, dtype=float).copy()
    F[eqs] -= np.linalg.solve(R[eqs].T, R.T @ MR)
    return F


def with_inertia_loads(model, ports, mode: str = "off"):
    """The ports a basis is built for, with the frame's inertia loads added as inputs.

    A body in the floating frame is loaded by its joints and by the inertia of its moving
    frame: a frame acceleration ``a`` (gravity among them) loads the nodes with ``-M R a``,
    ``R`` the six rigid motions (:func:`rigid_motions`). ``mode='on'`` adds the elastic part
    ``(I - M Φ Φᵀ) M R`` of those six columns (Φ the M-orthonormal rigid-body modes; all of
    ``M R`` on a supported body, whose moving support they load) and, for a free body, the same
    accelerations of the body held at each coupling master (:func:`interface_loads`; not for a
    master whose six directions the inputs hold) to the inputs and, transposed, to the outputs,
    each column scaled to the mean norm of the port inputs (so that Gramian methods weigh them
    like a port); ``'auto'`` is ``on`` for a free body and records a note for a supported one,
    ``'off'`` never adds them. The reduced body keeps the user's ports. On a free body ``M R``
    lies in ``M span(Φ)`` (a uniform acceleration moves it rigidly); held in its joint it sags,
    and with the master's columns the mounted body sags like the full model
    (:mod:`flexmor.analysis.mounted` measures it).

    Returns
    -------
    ports : Ports
        ``ports`` itself, or a copy with the inertia loads appended.
    record : dict
        ``inertia_loads`` (the mode asked for), ``n_inertia_loads`` (columns added) and, when
        some were added for interfaces, ``inertia_interfaces`` (their master node sets);
        ``inertia_interfaces_in_inputs`` the masters whose six directions the inputs hold
        (``f_k`` is then an inertia load plus a force the inputs give).
    """
    from ..errors import check_choice
    from ..ports import Ports

    check_choice("inertia_loads", mode, ("auto", "on", "off"))
    record = {"inertia_loads": mode, "n_inertia_loads": 0}
    if mode == "off":
        return ports, record
    phi = rigid_body_modes(model)
    if mode == "auto" and not phi.shape[1]:
        record["inertia_loads_note"] = ("supported body: not reduced for the inertia loads of a moving support; "
                                        "use inertia_loads='on' (--inertia-loads on) if its support accelerates")
        return ports, record
    R = rigid_motions(model)
    keep = np.linalg.norm(R, axis=0) > 0
    L = model.M @ R[:, keep]
    if phi.shape[1]:  # the elastic part: nothing is left of a uniform field on a free body
        L0 = np.linalg.norm(L, axis=0)
        for _ in range(2):
            L = elastic_loads(model, phi, L)
        left = np.linalg.norm(L, axis=0) > RIGID_DEFLATION_TOL * L0
        keep[keep] = left
        L = L[:, left]
    names = [n for n, k in zip(INERTIA_LOAD_NAMES, keep) if k]
    held, given = [], []
    if phi.shape[1] == 6:  # a free body: the accelerations of the body held at each interface
        from ..couplings import coupling_masters

        Q = sla.orth(ports.B.toarray()) if ports.n_inputs else np.zeros((model.n_dof, 0))
        for master in coupling_masters(model):
            E = np.flatnonzero(model.dofs[:, 0] == master["id"])
            if np.linalg.norm(Q[E] @ Q[E].T - np.eye(E.size)) < 1e-10:  # the inputs hold any force at the master
                given.append(master["name"])
                continue
            L = np.hstack([L, interface_loads(model, master["id"])])
            names += [f"inertia@{master['name']}:{n.split(':')[1]}" for n in INERTIA_LOAD_NAMES]
            held.append(master["name"])
    if given:
        record["inertia_interfaces_in_inputs"] = given
    if not L.shape[1]:
        return ports, record
    scale = np.mean(sp.linalg.norm(ports.B, axis=0)) if ports.n_inputs else 1.0
    L = sp.csr_matrix(L * (scale / np.linalg.norm(L, axis=0)))
    aug = Ports(B=sp.hstack([ports.B, L]).tocsr(), C=sp.vstack([ports.C, L.T]).tocsr(),
                input_names=list(ports.input_names) + names, output_names=list(ports.output_names) + names)
    record["n_inertia_loads"] = int(L.shape[1])
    if held:
        record["inertia_interfaces"] = held
    return aug, record


def rigid_residual(model, V, phi=None) -> float:
    """Largest relative rigid content of a column of ``V``: ``max_j ‖Φᵀ M v_j‖ / ‖v_j‖_M`` (0 if clean)."""
    phi = rigid_body_modes(model) if phi is None else phi
    if phi.shape[1] == 0 or V.shape[1] == 0:
        return 0.0
    MV = model.M @ V
    nrm = np.sqrt(np.clip(np.einsum("ij,ij->j", V, MV), 0.0, None))
    c = np.linalg.norm(phi.T @ MV, axis=0)
    return float(np.max(c / np.where(nrm > 0, nrm, 1.0)))


def _orthonormal_in_order(X, tol: float, ref=None):
    """Orthonormal columns spanning ``X`` built column by column (Gram-Schmidt order kept:
    the first ``k`` results span the leading columns), dropping those whose part outside the
    earlier ones is at most ``tol * ref[j]`` (``ref`` defaults to the columns' own norms; pass
    the norms the columns had before a projection to drop columns that the projection emptied)."""
    ref = np.linalg.norm(X, axis=0) if ref is None else np.asarray(ref, dtype=float)
    keep = []
    Q = np.zeros_like(X)
    k = 0
    for j in range(X.shape[1]):
        x = X[:, j]
        for _ in range(2):  # twice is enough
            x = x - Q[:, :k] @ (Q[:, :k].T @ x)
        s = np.linalg.norm(x)
        if s > tol * ref[j] and s > 0:
            Q[:, k] = x / s
            keep.append(j)
            k += 1
    return Q[:, :k], keep


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
        orthonormal (Euclidean). Either way M-orthogonal to the rigid-body modes to round-off (``info['rigid_residual']``, relative), in the order of the method's columns
        (a nested basis stays nested); for ``exclude`` ``info['n_rigid_excluded']`` the number of
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
    Gvv = V.T @ (model.M @ V)
    Gvr = V.T @ MR
    P = Grr - Gvr.T @ np.linalg.solve(Gvv, Gvr)
    lam = sla.eigh(0.5 * (P + P.T), 0.5 * (Grr + Grr.T), eigvals_only=True)
    return float(np.sqrt(max(lam[0], 0.0)))


#: :func:`rigid_content` below which a basis contains a rigid-body motion.
RIGID_CONTENT_TOL = 1e-6


def elastic_body(model, reduced, *, remove_rigid: bool = False):
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
    from ..errors import FlexmorError, ModelError
    from ..ports import make_ports
    from ..projection import project

    phi = rigid_body_modes(model)
    if reduced.V is None or phi.shape[1] == 0 or rigid_content(model, reduced.V) >= RIGID_CONTENT_TOL:
        return reduced
    try:
        ports = make_ports(model, reduced.input_names, reduced.output_names)
    except FlexmorError as exc:
        raise ModelError(f"the {reduced.method} body holds rigid-body motion, which the floating frame carries; "
                         f"removing it needs the body's ports on the model: {exc}") from None
    basis = exclude_rigid(model, Basis(reduced.V, reduced.method, dict(reduced.info, rigid="exclude")))
    body = project(model, basis, ports)
    change = (f"made mass-orthogonal to the {phi.shape[1]} rigid-body modes (order {reduced.order} -> {body.order}), "
              "another body than the one reduced and judged")
    if not remove_rigid:
        raise ModelError(f"the {reduced.method} body holds rigid-body motion, which the floating frame carries; "
                         f"exporting it would need its basis {change}. Reduce with rigid='exclude' (--rigid exclude, "
                         "the default for free bodies), or pass remove_rigid to allow the change (flexmor export then "
                         "states the error of the body it writes)", params=("remove_rigid",))
    body.info["rigid_removed_at_export"] = {"order_reduced": reduced.order, "order_exported": body.order}
    body.origin = dict(reduced.origin)  # with the couplings and selections the body was made with
    body.couplings, body.selections = list(reduced.couplings), list(reduced.selections)
    body.order_note = reduced.order_note
    warnings.warn(f"{reduced.method} body: its basis holds rigid-body motion, which the floating frame carries; "
                  f"exported with its basis {change}", FlexmorWarning, stacklevel=2)
    return body


def spurious_modes_hz(model, reduced, f1_hz: float) -> np.ndarray:
    """Reduced frequencies (Hz) that are neither rigid-body modes nor at or above ``f1_hz``.

    ``f1_hz`` is the full model's first elastic frequency. A Galerkin body's Ritz values are
    upper bounds of the full model's eigenvalues, so a mode between the rigid-body threshold
    (:func:`flexmor.linalg.eigen.rigid_body_threshold`) and ``f1_hz`` (less a relative 1e-6)
    is a mixture of rigid and elastic motion that the full model does not have.
    """
    lam = reduced.eigenvalues()
    lo = rigid_body_threshold(model.K, model.M)
    hi = (2 * np.pi * f1_hz) ** 2 * (1 - 2e-6)
    bad = (lam > lo) & (lam < hi)
    return np.sqrt(lam[bad]) / (2 * np.pi)


def check_body(model, reduced, *, f1_hz: float | None = None, band_error: float | None = None) -> list[str]:
    """Warn (one-line :class:`FlexmorWarning` each) about a reduced body that would be wrong.

    Parameters
    ----------
    model : FEModel
        The full model.
    reduced : ReducedModel
    f1_hz : float, optional
        The full model's first elastic frequency; without it the spectrum is not checked.
    band_error : float, optional
        The body's band_error; above 1 the body is worse than no body at all.

    Returns
    -------
    list of str
        The warnings issued (empty for a sound body).
    """
    msgs = []
    if f1_hz is not None and np.isfinite(f1_hz):
        bad = spurious_modes_hz(model, reduced, f1_hz)
        if bad.size:
            hint = ("reduce with rigid-body modes excluded (--rigid exclude) so that the floating frame carries "
                    "the rigid motion")
            msgs.append(f"{reduced.method} body has {bad.size} mode(s) at {', '.join(f'{f:.4g}' for f in bad[:4])} Hz "
                        f"below the full model's first elastic frequency {f1_hz:.4g} Hz that the full model does not "
                        f"have (rigid motion mixed into the elastic coordinates); {hint}")
    if band_error is not None and np.isfinite(band_error) and band_error > 1:
        if model.D is None:
            why = "the model is undamped, so its resonances dominate: add damping to judge the body, or raise the order"
        else:
            why = "raise the order, widen the expansion points or band, or use another method"
        msgs.append(f"{reduced.method} body has band_error {band_error:.3g} > 1: it is worse than no body over the "
                    f"band; {why}")
    for m in msgs:
        warnings.warn(m, FlexmorWarning, stacklevel=2)
    return msgs
