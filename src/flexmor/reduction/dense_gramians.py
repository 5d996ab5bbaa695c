"""Exact dense Gramians of small second-order bodies (Lyapunov equations, Gawronski-Juang).

Used by ``two-step`` (the intermediate Krylov body), by ``sobt`` on small bodies, and as
the reference of the quadrature in :mod:`flexmor.reduction.gramians`.

References
----------
Gawronski, W., Juang, J.-N. (1990). Model reduction in limited time and frequency intervals.
Int. J. Systems Sci. 21(2), 349-376.

Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
Math. Comput. Model. Dyn. Syst. 14(5), 391-406.
"""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np
import scipy.linalg as sla

from ..linalg.eigen import is_rigid

__all__ = ["dense_gramians", "psd_factor"]

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
    lam, phi = sla.eigh(K, M)
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
