"""Free bodies in the reduction: inertia relief, inertia loads, rigid motion in a basis, checks of a body.

The rigid-body modes and the projection that removes them from a basis are the base module
:mod:`flexmor.rigid`; this module holds what the reduction methods and the workflow build on
it: the rigid-body modes a basis keeps on request (:func:`rigid_head`), the inertia-relief
attachment modes of a free body (:func:`inertia_relief_modes`), the elastic inputs a free body
is judged on (:func:`with_elastic_part`), and the frame's inertia loads added to the inputs a
basis is built for (:func:`with_inertia_loads`, :func:`interface_loads`).

:func:`check_body` is the guard against bodies that are written but wrong: a reduced mode
below the full model's first elastic frequency that is not a rigid-body mode (a Galerkin
body whose basis holds no rigid motion cannot have one), or a band_error above 1, is
reported with a one-line :class:`~flexmor.errors.FlexmorWarning` that says why and what to do.

References
----------
Craig, R. R., Kurdila, A. J. (2006). Fundamentals of Structural Dynamics, 2nd ed., Wiley,
ch. 18-19 (free-interface and fixed-interface CMS of free components).
"""

from __future__ import annotations

import logging
import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg.norm)

from ..errors import FlexmorWarning
from ..linalg.eigen import rigid_body_threshold
from ..linalg.threads import sparse_dense
from ..rigid import RIGID_DEFLATION_TOL, elastic_loads, m_project, rigid_body_modes, rigid_motions

__all__ = ["interface_loads", "rigid_head", "inertia_relief_modes", "inertia_relief", "elastic_ports",
           "with_elastic_part", "split_elastic", "with_inertia_loads",
           "INERTIA_LOAD_NAMES", "check_body", "spurious_modes_hz"]

log = logging.getLogger(__name__)

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


def inertia_relief_modes(model, dofs, *, phi=None, solver=None, held=None) -> np.ndarray:
    """Static elastic responses of a free body to unit forces at the equations ``dofs``, balanced
    by the inertia of its rigid motion (inertia relief), M-orthogonal to the rigid-body modes:

        x_j = K⁺ (I - M Φ Φᵀ) e_j,   Φᵀ M x_j = 0.

    ``K`` is singular. With ``held = (V_c, i, F)``, the constraint modes of ``dofs``, the other
    equations ``i`` and the factorization of ``K_ii`` (:func:`flexmor.reduction.guyan.constraint_modes`,
    the interface holding the body), the responses come from the body held at ``dofs``: with the
    loads ``g = (I - M Φ Φᵀ) E``, ``x_i = K_ii⁻¹ g_i`` (one solve of the ``k <= 6`` columns of
    ``(M Φ)_i``, since ``g_i = -(M Φ)_i Φ_bᵀ``) and the interface motion ``x_b`` from the Guyan
    stiffness ``S = V_cᵀ K V_c`` (singular on the rigid motions ``Φ_b``; the loads are balanced):
    ``S x_b = g_b - K_bi x_i``, ``x = V_c x_b + [0; x_i]``, made M-orthogonal to ``Φ``. Exact up to
    the factorization's rounding, no other factorization.

    Without ``held``, from the positive definite ``A = K - σ M`` (σ =
    :func:`flexmor.linalg.eigen.default_shift` < 0) with refinement ``x <- P (x + A⁻¹ (f - K x))``,
    ``P = I - Φ Φᵀ M``, whose error shrinks by ``|σ| / (ω² + |σ|)`` per step in each elastic mode ω,
    until the relative change is below :data:`RELIEF_TOL` (a few steps). One factorization, a few
    solves per column.
    """
    phi = rigid_body_modes(model) if phi is None else phi
    dofs = np.asarray(dofs, dtype=np.int64)
    if held is not None:
        return _relief_held(model, dofs, phi, *held)
    E = np.zeros((model.n_dof, dofs.size))
    E[dofs, np.arange(dofs.size)] = 1.0
    return inertia_relief(model, E, phi=phi, solver=solver)


def inertia_relief(model, F, *, phi=None, solver=None) -> np.ndarray:
    """Static elastic responses of a free body to the loads ``F`` (n_dof, k), balanced by the inertia of its
    rigid motion: ``x = K⁺ (I - M Φ Φᵀ) F``, ``Φᵀ M x = 0``, from ``K - σ M`` with refinement (see
    :func:`inertia_relief_modes`)."""
    from ..linalg import factorize
    from ..linalg.eigen import default_shift

    phi = rigid_body_modes(model) if phi is None else phi
    f = elastic_loads(model, phi, np.asarray(F, dtype=float))
    sigma = default_shift(model.K, model.M)
    F = factorize((model.K - sigma * model.M).tocsr(), solver=solver, positive=True)

    x = m_project(model, phi, F.solve(f))
    for _ in range(50):
        dx = m_project(model, phi, F.solve(f - sparse_dense(model.K, x)))
        x = x + dx
        if np.linalg.norm(dx) <= RELIEF_TOL * np.linalg.norm(x):
            break
    return x


def _relief_held(model, b, phi, V_c, i, F) -> np.ndarray:
    """:func:`inertia_relief_modes` from the body held at the equations ``b`` (see there)."""
    K = model.K.tocsr()
    M_phi = model.M @ phi
    phi_b = phi[b]
    x_i = -F.solve(np.ascontiguousarray(M_phi[i])) @ phi_b.T  # K_ii^-1 g_i, g_i = -(M phi)_i phi_b^T
    Kb = K[b]
    S = Kb @ V_c  # V_c^T K V_c: the interface rows of K V_c (V_c[b] = I, K V_c = 0 on the interior rows)
    S = 0.5 * (S + S.T)
    h = np.eye(b.size) - M_phi[b] @ phi_b.T - Kb[:, i] @ x_i  # g_b - K_bi x_i
    Q = sla.orth(phi_b)  # S's null space: the rigid motions of the interface
    scale = max(float(np.abs(S).sum(axis=0).max()), np.finfo(float).tiny)
    x_b = np.linalg.solve(S + scale * (Q @ Q.T), h - Q @ (Q.T @ h))
    x = V_c @ x_b
    x[i] += x_i
    return m_project(model, phi, x)


def elastic_ports(model, ports):
    """The ports of the elastic part of a free body's response (Φ its M-orthonormal rigid-body modes): inputs
    ``(I - M Φ Φᵀ) B`` and outputs ``C (I - Φ Φᵀ M)``; ``ports`` itself for a supported body.

    ``C (I - ΦΦᵀM) (s²M + sD + K)⁻¹ (I - MΦΦᵀ) B`` is the elastic part of ``H`` (exact for proportional
    damping, where the elastic inputs alone give it in exact arithmetic). Both projections are kept for the
    rounding: the numerical null space of ``K`` differs from ``Φ`` by rounding ``δ``, and its near-zero
    eigenvalues turn ``δ`` of the elastic inputs into a rigid response ``~ δ |B| / ω²``; the projected outputs
    see ``δ²`` of it. On the free CalculiX beam (input FIX:y) the elastic FRF without the output projection
    was off by 8e-7 at 1 Hz, 8e-3 at 0.01 Hz (1/f²) and passed the spurious poles of the rounding near
    0.002 Hz; with it, 2-3e-12 at every frequency (against the modal sum of the elastic modes).
    """
    from ..ports import Ports

    phi = rigid_body_modes(model)
    if not phi.shape[1] or not (ports.n_inputs or ports.n_outputs):
        return ports
    C = ports.C
    Ce = C.toarray() - sparse_dense(C, phi) @ sparse_dense(model.M, phi).T
    return Ports(B=sp.csr_matrix(elastic_loads(model, phi, ports.B.toarray())), C=sp.csr_matrix(Ce),
                 input_names=list(ports.input_names), output_names=list(ports.output_names))


def with_elastic_part(model, ports):
    """``ports`` with the elastic inputs and outputs of :func:`elastic_ports` appended (named ``elastic:...``)
    for a free body; ``ports`` itself for a supported body. The response to the first inputs at the first
    outputs is ``H``, to the appended inputs at the appended outputs its elastic part (:func:`split_elastic`).

    The elastic part is computed directly: at low frequencies, or over long times, the rigid-body response
    exceeds it by orders of magnitude, and a difference of the two would be round-off. The floating frame's
    bodies (rigid motion excluded) are judged on it.
    """
    from ..ports import Ports

    el = elastic_ports(model, ports)
    if el is ports:
        return ports
    return Ports(B=sp.hstack([ports.B, el.B]).tocsr(), C=sp.vstack([ports.C, el.C]).tocsr(),
                 input_names=list(ports.input_names) + [f"elastic:{n}" for n in ports.input_names],
                 output_names=list(ports.output_names) + [f"elastic:{n}" for n in ports.output_names])


def split_elastic(Y, ports):
    """``(whole, elastic)``: the blocks of ``Y`` (``(..., outputs, inputs)`` of the ports of
    :func:`with_elastic_part`) for the original ``ports``; elastic None when ``Y`` has no more outputs and inputs."""
    p, m = ports.n_outputs, ports.n_inputs
    if Y.shape[-2] == p and Y.shape[-1] == m:
        return Y, None
    return Y[..., :p, :m], Y[..., p:, m:]


#: Names of the inertia-load inputs (unit accelerations of the frame: translations, rotations).
INERTIA_LOAD_NAMES = ("inertia:ax", "inertia:ay", "inertia:az", "inertia:arx", "inertia:ary", "inertia:arz")


def interface_loads(model, node) -> np.ndarray:
    """The frame's six unit accelerations on a free body held at the master ``node``, (n_dof, 6).

    Column k is ``f_k = M r_k + E_m λ_k`` (``r_k`` the k-th rigid motion, :func:`flexmor.rigid.rigid_motions`;
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
    ``R`` the six rigid motions (:func:`flexmor.rigid.rigid_motions`). ``mode='on'`` adds the elastic part
    ``(I - M Φ Φᵀ) M R`` of those six columns (Φ the M-orthonormal rigid-body modes; all of
    ``M R`` on a supported body, whose moving support they load) and, for a free body, the same
    accelerations of the body held at each coupling master (:func:`interface_loads`; not for a
    master whose six directions the inputs hold) to the inputs and, transposed, to the outputs,
    each column scaled to the mean norm of the port inputs (so that Gramian methods weigh them
    like a port); ``'auto'`` (the default) is ``on`` for free and supported bodies alike (a supported
    body's support is its frame: gravity and the support's motion load it with ``-M R a``, in
    directions its ports may not see, e.g. the z-bending of a bar loaded in y), ``'off'`` never adds
    them. The reduced body keeps the user's ports. On a free body ``M R``
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
                input_names=list(ports.input_names) + names, output_names=list(ports.output_names) + names,
                judged=(ports.n_inputs, ports.n_outputs))
    record["n_inertia_loads"] = int(L.shape[1])
    if held:
        record["inertia_interfaces"] = held
    return aug, record


def spurious_modes_hz(model, body, f1_hz: float) -> np.ndarray:
    """Reduced frequencies (Hz) that are neither rigid-body modes nor at or above ``f1_hz``.

    ``f1_hz`` is the full model's first elastic frequency. A Galerkin body's Ritz values are
    upper bounds of the full model's eigenvalues, so a mode between the rigid-body threshold
    (:func:`flexmor.linalg.eigen.rigid_body_threshold`) and ``f1_hz`` (less a relative 1e-6)
    is a mixture of rigid and elastic motion that the full model does not have.
    """
    lam = body.eigenvalues()
    lo = rigid_body_threshold(model.K, model.M)
    hi = (2 * np.pi * f1_hz) ** 2 * (1 - 2e-6)
    bad = (lam > lo) & (lam < hi)
    return np.sqrt(lam[bad]) / (2 * np.pi)


def check_body(model, body, *, f1_hz: float | None = None, band_error: float | None = None) -> list[str]:
    """Warn (one-line :class:`FlexmorWarning` each) about a reduced body that would be wrong.

    Parameters
    ----------
    model : FEModel
        The full model.
    body : ReducedModel
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
        bad = spurious_modes_hz(model, body, f1_hz)
        if bad.size:
            hint = ("reduce with rigid-body modes excluded (rigid='exclude') so that the floating frame carries "
                    "the rigid motion")
            msgs.append(f"{body.method} body has {bad.size} mode(s) at {', '.join(f'{f:.4g}' for f in bad[:4])} Hz "
                        f"below the full model's first elastic frequency {f1_hz:.4g} Hz that the full model does not "
                        f"have (rigid motion mixed into the elastic coordinates); {hint}")
    if band_error is not None and np.isfinite(band_error) and band_error > 1:
        if model.D is None:
            why = "the model is undamped, so its resonances dominate: add damping to judge the body, or raise the order"
        else:
            why = "raise the order, widen the expansion points or band, or use another method"
        msgs.append(f"{body.method} body has band_error {band_error:.3g} > 1: it is worse than no body over the "
                    f"band; {why}")
    for m in msgs:
        warnings.warn(m, FlexmorWarning, stacklevel=2)
    return msgs
