"""Proper orthogonal decomposition (POD) of frequency-domain and time-domain snapshots."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.threads import sparse_dense
from ..options import Band, band_option, option
from ..rigid import m_project
from ._options import nodes_option, rigid_option, side_option, solves_option
from ._registry import order_note, register_method
from .free_body import rigid_head
from .gramians import compress, gramian_factors

__all__ = ["pod", "PodOptions", "pod_modes", "SNAPSHOTS"]

log = logging.getLogger(__name__)

#: Snapshot directions whose singular value lies below this share of the largest are round-off (:func:`pod_modes`).
SIGMA_RTOL = 1e-13

SNAPSHOTS = ("frequency", "time", "both")

#: Largest number of time steps of a snapshot simulation.
MAX_STEPS = 4000


def pod_modes(S: np.ndarray, M, order: int | None = None, energy: float | None = None):
    """POD modes of the snapshot matrix ``S`` in the ``M`` inner product (method of snapshots).

    ``S = Q T`` (QR), ``Q^T M Q = L L^T`` (Cholesky) and ``L^T T = U diag(sigma) Z^T``: the modes
    ``Q L^{-T} U_r`` are M-orthonormal and optimal for ``sum_j ||s_j - V V^T M s_j||_M^2``
    (``lam = sigma^2``), computed without forming ``S^T M S``. ``order`` caps the number of modes,
    ``energy`` picks the fewest modes whose ``sum lam_r / sum lam`` reaches it.

    Returns
    -------
    V : ndarray, shape (n, r)
    lam : ndarray
        All POD eigenvalues (snapshot energies), descending.
    """
    Q, T = np.linalg.qr(S)  # Householder QR, then the M-weighted SVD of the small factor:
    Lq = np.linalg.cholesky(Q.T @ sparse_dense(M, Q))  # no squaring of singular values (accurate to eps)
    U, sig, _ = np.linalg.svd(Lq.T @ T, full_matrices=False)
    lam = sig ** 2
    pos = sig > SIGMA_RTOL * sig[0] if sig.size and sig[0] > 0 else np.zeros(sig.size, bool)
    r = int(pos.sum())
    if energy is not None:
        frac = np.cumsum(lam[pos]) / lam[pos].sum()
        r = min(r, int(np.searchsorted(frac, energy * (1 - 1e-12)) + 1))
    if order is not None:
        r = min(r, order)
    return Q @ np.linalg.solve(Lq.T, U[:, :r]), lam


def _time_snapshots(model, ports, band, solver):
    """States ``q(t)`` of the full body under a sine sweep over the band, one load case per input.

    Uses :func:`flexmor.dynamics.time.simulate` (Newmark) with the identity as output matrix;
    ``dt = 1/(20 fmax)``, ``t_end = min(5/fmin, MAX_STEPS dt)``. Columns are scaled by
    ``sqrt(dt)`` (the snapshot quadrature weight).
    """
    import scipy.sparse as sp

    from ..dynamics.time import simulate, sine_sweep
    from ..ports import Ports

    fmin, fmax = band
    dt = 1.0 / (20.0 * fmax)
    t_end = min(5.0 / fmin, MAX_STEPS * dt)
    eye = sp.identity(model.n_dof, format="csr")
    snap = Ports(B=ports.B, C=eye, input_names=ports.input_names, output_names=[""] * model.n_dof)
    res = simulate(model, sine_sweep(fmin, fmax, t_end), dt=dt, t_end=t_end, ports=snap, solver=solver)
    q = res.displacement  # (n_t, n_dof, m)
    S = np.transpose(q, (1, 0, 2)).reshape(model.n_dof, -1) * math.sqrt(dt)
    return compress(S), {"dt": dt, "t_end": t_end, "n_steps": int(q.shape[0]), "signal": "linear sine sweep"}


@dataclass(frozen=True)
class PodOptions:
    """Options of :func:`pod`."""

    band: Band | None = band_option("the snapshots")
    energy: float | None = option(None, "keep the fewest modes with this share (0, 1] of the snapshot energy",
                                  parse=float)
    snapshots: str = option("frequency", "snapshot source", choices=SNAPSHOTS)
    side: str = side_option("input", choices=("input", "both"))
    nodes: int = nodes_option()
    rigid: str = rigid_option()
    solves: str = solves_option()


@register_method("pod", "proper orthogonal decomposition of frequency (and time) snapshots", options=PodOptions,
                 survives_coupling=False)
def pod(model, ports, order, *, band=None, energy: float | None = None, snapshots: str = "frequency",
        side: str = "input", nodes: int = 4, rigid: str = "exclude", solves: str = "auto",
        solver: SolverContext | None = None) -> Basis:
    """POD basis from snapshots of the full body's response.

    Frequency snapshots are the solutions ``X(w_k) = (K - w_k^2 M + i w_k D)^{-1} B`` at the
    quadrature nodes of the band, weighted by the quadrature weights: the same solves as the
    frequency-limited Gramian (:func:`flexmor.reduction.gramians.gramian_factors`), whose
    dominant eigenvectors in the M inner product are then the POD modes. Time snapshots are
    the states of a Newmark simulation under a linear sine sweep over the band
    (:mod:`flexmor.dynamics.time`).

    Parameters
    ----------
    model : FEModel
    ports : Ports
    order : int or None
        Number of modes (upper bound when ``energy`` is given).
    band : (float, float), optional
        Band in Hz (default :data:`flexmor.options.DEFAULT_BAND`).
    energy : float, optional
        Keep the fewest modes whose share of the snapshot energy reaches ``energy`` (0, 1].
    snapshots : {'frequency', 'time', 'both'}
        Snapshot source; ``both`` weighs the two sets equally (each scaled to unit energy).
    side : {'input', 'both'}
        Snapshots of ``B`` only, or of ``B`` and ``C^T`` (the dual body).
    nodes : int
        Gauss points per quadrature panel (see :func:`flexmor.reduction.balanced.sobt`).
    rigid : {'exclude', 'include'}
        Free bodies: the snapshots are those of the flexible part (M-orthogonal to the rigid-body
        modes); ``exclude`` (default) leaves the rigid motion to the
        floating frame, ``include`` puts the rigid-body modes the inputs excite first.
    solves : {'auto', 'direct', 'dense', 'surrogate'}
        How the frequency snapshots are solved (see :func:`flexmor.reduction.balanced.fw_sobt`).
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info['pod_energy']`` the leading snapshot energies, ``info['energy_captured']``.

    References
    ----------
    Sirovich, L. (1987). Turbulence and the dynamics of coherent structures, part I.
    Quarterly of Applied Mathematics 45(3), 561-571 (method of snapshots).

    Kerschen, G., Golinval, J.-C., Vakakis, A. F., Bergman, L. A. (2005). The method of proper
    orthogonal decomposition for dynamical characterization and order reduction of
    mechanical systems: an overview. Nonlinear Dynamics 41, 147-169.

    Willcox, K., Peraire, J. (2002). Balanced model reduction via the proper orthogonal
    decomposition. AIAA Journal 40(11), 2323-2330 (frequency-domain snapshots).
    """
    solver = as_solver(solver)
    check_choice("snapshots", snapshots, SNAPSHOTS)
    check_choice("side", side, ("input", "both"))
    if order is None and energy is None:
        raise OptionError("pod needs order or energy", params=("order", "energy"))
    if energy is not None and not 0 < float(energy) <= 1:
        raise OptionError(f"energy must be in (0, 1], got {energy}", params=("energy",))
    band = Band.of(band)
    phi, head = rigid_head(model, ports.B.toarray(), rigid)
    parts, info = [], {"snapshots": snapshots, "band_hz": list(band)}
    if snapshots in ("frequency", "both"):
        G = gramian_factors(model, ports, band, side="both" if side == "both" else "input", nodes=nodes,
                            solves=solves, solver=solver, rigid_modes=phi)
        S = G.R if side == "input" else np.hstack([G.R, G.L])
        parts.append(S)
        info.update(n_nodes=G.info["n_nodes"], gramian_damping=G.info["gramian_damping"], solves=G.info["solves"])
    if snapshots in ("time", "both"):
        S, tinfo = _time_snapshots(model, ports, band, solver)
        parts.append(m_project(model, phi, S))
        info["time"] = tinfo
    if len(parts) > 1:
        parts = [P / math.sqrt(max(np.einsum("ij,ij->", P, sparse_dense(model.M, P)), 1e-300)) for P in parts]
    if order is not None and order <= head.shape[1]:
        raise OptionError(f"order {order} leaves no room next to {head.shape[1]} rigid-body modes", params=("order",))
    V, lam = pod_modes(np.hstack(parts), model.M, None if order is None else order - head.shape[1], energy)
    info.update(pod_energy=lam[: max(40, 2 * V.shape[1])].tolist(),
                energy_captured=float(lam[: V.shape[1]].sum() / lam[lam > 0].sum()), nested=True)
    if order is not None and V.shape[1] + head.shape[1] < order:
        info["order_note"] = order_note("pod", V.shape[1] + head.shape[1], order, _pod_reason(lam, V.shape[1], energy))
    if phi.shape[1]:
        info.update(rigid=rigid, n_rigid_included=int(head.shape[1]))
    return Basis(np.hstack([head, V]) if head.shape[1] else V, "pod", info)


def _pod_reason(lam, r: int, energy: float | None) -> str:
    """Why :func:`pod` kept ``r`` modes, fewer than asked: the ``energy`` share reached, or the snapshots'
    independent directions (POD eigenvalues above round-off, :func:`pod_modes`) all taken."""
    n_independent = int(np.sum(lam > SIGMA_RTOL ** 2 * lam[0])) if lam.size and lam[0] > 0 else 0
    if energy is not None and r < n_independent:
        return f"{float(energy):g} of the snapshot energy is reached with {r} POD modes (energy)"
    return (f"the snapshots span only {n_independent} independent directions (singular values above "
            f"{SIGMA_RTOL:g} of the largest); more columns would add round-off only; a wider band, side both or "
            "snapshots both gives more")
