"""Exact dense Gramians of small bodies (Lyapunov equations, Gawronski-Juang).

Used by ``two-step`` (the intermediate Krylov body), by ``sobt`` on small bodies, and as
the reference of the quadrature in :mod:`flexmor.reduction.gramians`. Small first-order
systems ``x' = A x + B u``, ``y = C x`` (benchmark state-space models) get the classic
square-root balanced truncation (:func:`balanced_truncation`) with its Hankel singular values
(:func:`hankel_singular_values`).

References
----------
Gawronski, W., Juang, J.-N. (1990). Model reduction in limited time and frequency intervals.
Int. J. Systems Sci. 21(2), 349-376.

Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
Math. Comput. Model. Dyn. Syst. 14(5), 391-406.

Moore, B. C. (1981). Principal component analysis in linear systems: controllability,
observability, and model reduction. IEEE Trans. Automat. Control 26(1), 17-32.

Laub, A. J., Heath, M. T., Paige, C. C., Ward, R. C. (1987). Computation of system balancing
transformations and other applications of simultaneous diagonalization algorithms. IEEE
Trans. Automat. Control 32(2), 115-122.

Antoulas, A. C. (2005). Approximation of Large-Scale Dynamical Systems. SIAM, ch. 7.
"""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np
import scipy.linalg as sla

from ..errors import ModelError, OptionError
from ..linalg.eigen import dense_eigenmodes, is_rigid

__all__ = ["balanced_truncation", "dense_gramians", "hankel_singular_values", "psd_factor"]

log = logging.getLogger(__name__)


def dense_gramians(M, D, K, B, C, band=None, *, rigid_tol=None):
    """Exact Gramians ``P_p, P_v, Q_p`` of a small dense second-order body (full band or a band).

    The flexible part is transformed to modal coordinates (``Phi^T M Phi = I``) and the
    well-scaled first-order realization ``[[0, Omega], [-Omega, -D_f]]`` (state
    ``(Omega q, q')``, ``Omega^2 = Lambda``) is solved by
    :func:`scipy.linalg.solve_continuous_lyapunov`; a band ``[w1, w2]`` uses the
    Gawronski-Juang formula ``P_Omega = P S^H + S P``, ``S = S(w2) - S(w1)``,
    ``S(w) = (i/2pi) log((A + iwI)(A - iwI)^{-1})``. Rigid-body modes (eigenvalues below
    :func:`flexmor.linalg.eigen.rigid_body_threshold`) are left out. Undamped bodies need
    ``D`` (see the module docstring).

    Parameters
    ----------
    M, D, K : ndarray, shape (r, r)
    B : ndarray, shape (r, m)
    C : ndarray, shape (p, r)
    band : (float, float), optional
        Band in Hz; None is the full band.

    Returns
    -------
    Pp, Pv, Qp : ndarray, shape (r, r)
        In the coordinates of ``M``, ``K`` (``P = Phi_f P_modal Phi_f^T``).
    Phi_rigid : ndarray, shape (r, k)
        The rigid-body modes left out.
    """
    lam, phi = dense_eigenmodes(K, M)
    rigid = is_rigid(lam, K, M) if rigid_tol is None else lam < rigid_tol
    pf, lf = phi[:, ~rigid], np.clip(lam[~rigid], 0, None)
    n = lf.size
    Df = pf.T @ D @ pf
    om = np.sqrt(np.maximum(lf, 1e-300))  # state (Omega q, q'): A = [[0, Omega], [-Omega, -D]] is well scaled
    A = np.block([[np.zeros((n, n)), np.diag(om)], [-np.diag(om), -Df]])

    def gram(Bm):
        Bt = np.vstack([np.zeros((n, Bm.shape[1])), pf.T @ Bm])
        P = sla.solve_continuous_lyapunov(A, -Bt @ Bt.T)
        if band is not None:
            S = np.zeros_like(A, dtype=complex)
            eye = np.eye(2 * n)
            for sign, f in ((1, band[1]), (-1, band[0])):
                if f > 0 and math.isfinite(f):
                    w = 2 * math.pi * f
                    S += sign * (1j / (2 * math.pi)) * sla.logm((A + 1j * w * eye) @ np.linalg.inv(A - 1j * w * eye))
                elif sign == 1:  # fmax = inf
                    S += 0.5 * eye
            P = (P @ S.conj().T + S @ P).real
        P = 0.5 * (P + P.T)
        return P

    with warnings.catch_warnings(record=True) as caught:  # scipy's accuracy notes go to the log
        warnings.simplefilter("always")
        P = gram(np.asarray(B, float))
        Q = gram(np.asarray(C, float).T)
    for w in caught:
        log.debug("dense Gramians: %s", w.message)
    Pp = (pf / om) @ P[:n, :n] @ (pf / om).T
    Pv = pf @ P[n:, n:] @ pf.T
    Qp = (pf / om) @ Q[:n, :n] @ (pf / om).T
    return Pp, Pv, Qp, phi[:, rigid]


def psd_factor(P: np.ndarray, tol: float = 1e-14) -> np.ndarray:
    """A factor ``R`` with ``R R^T = P`` for a symmetric positive semi-definite ``P`` (eigen)."""
    w, U = np.linalg.eigh(0.5 * (P + P.T))
    keep = w > tol * max(w[-1], 0) if w.size else np.zeros(0, bool)
    return U[:, keep] * np.sqrt(w[keep])


def _first_order_factors(A, B, C):
    """Factors ``P = Lp Lp^T``, ``Q = Lq Lq^T`` of the Gramians of a stable ``(A, B, C)`` (dense)."""
    A = np.asarray(A.toarray() if hasattr(A, "toarray") else A, float)
    B = np.asarray(B.toarray() if hasattr(B, "toarray") else B, float)
    C = np.asarray(C.toarray() if hasattr(C, "toarray") else C, float)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or B.shape[0] != A.shape[0] or C.shape[1] != A.shape[0]:
        raise ModelError(f"inconsistent state-space sizes A {A.shape}, B {B.shape}, C {C.shape}")
    if np.linalg.eigvals(A).real.max(initial=-np.inf) >= 0:
        raise ModelError("balanced truncation needs an asymptotically stable A (all eigenvalues in Re < 0)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        P = sla.solve_continuous_lyapunov(A, -B @ B.T)
        Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    for w in caught:
        log.debug("first-order Gramians: %s", w.message)
    return A, B, C, psd_factor(P, 0.0), psd_factor(Q, 0.0)


def hankel_singular_values(A, B, C) -> np.ndarray:
    """Hankel singular values ``sqrt(eig(P Q))`` of a stable first-order system, descending.

    ``A P + P A^T + B B^T = 0``, ``A^T Q + Q A + C^T C = 0`` are solved densely (Bartels-Stewart,
    :func:`scipy.linalg.solve_continuous_lyapunov`); the values are the singular values of
    ``Lq^T Lp`` for factors ``P = Lp Lp^T``, ``Q = Lq Lq^T`` (no product ``P Q`` is formed).
    Small systems only (dense ``n x n``).
    """
    A, _, _, Lp, Lq = _first_order_factors(A, B, C)
    s = np.linalg.svd(Lq.T @ Lp, compute_uv=False)
    return np.concatenate([s, np.zeros(A.shape[0] - s.size)])


def balanced_truncation(A, B, C, order: int):
    """Square-root balanced truncation of a small stable first-order system ``(A, B, C)``.

    With ``Lq^T Lp = U diag(sigma) Z^T`` the projections ``T = Lp Z_r sigma_r^{-1/2}``,
    ``W = Lq U_r sigma_r^{-1/2}`` (``W^T T = I``) give ``Ar = W^T A T``, ``Br = W^T B``,
    ``Cr = C T``: a stable, balanced system whose error obeys
    ``sigma_{r+1} <= ||G - Gr||_Hinf <= 2 (sigma_{r+1} + ... + sigma_n)``.

    Parameters
    ----------
    A : array_like or sparse, shape (n, n)
    B : array_like, shape (n, m)
    C : array_like, shape (p, n)
    order : int
        Reduced order r (at most the number of non-zero Hankel singular values).

    Returns
    -------
    Ar, Br, Cr : ndarray
        The reduced system.
    sigma : ndarray, shape (n,)
        All Hankel singular values, descending (``sigma[order:]`` are the truncated ones).
    """
    A, B, C, Lp, Lq = _first_order_factors(A, B, C)
    U, s, Zt = np.linalg.svd(Lq.T @ Lp, full_matrices=False)
    r = int(order)
    if not 1 <= r <= int(np.sum(s > 0)):
        raise OptionError(f"order must be between 1 and {int(np.sum(s > 0))} (non-zero Hankel singular values), "
                          f"got {order}")
    scale = 1.0 / np.sqrt(s[:r])
    T = Lp @ Zt[:r].T * scale
    W = Lq @ U[:, :r] * scale
    sigma = np.concatenate([s, np.zeros(A.shape[0] - s.size)])
    return W.T @ A @ T, W.T @ B, C @ T, sigma
