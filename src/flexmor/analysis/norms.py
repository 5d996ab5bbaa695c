"""H2 norms of reduction errors ``||H - Hr||_H2`` for second-order bodies (small models).

Three honest ways, chosen by ``method``:

``modal``
    exact for Rayleigh damping: full and reduced bodies decouple into damped oscillators
    ``g_k(s) = 1/(s^2 + a_k s + b_k)`` (``a_k = alpha + beta w_k^2``, ``b_k = w_k^2``) with
    ``<g_k, g_l>_H2 = (a_k + a_l) / ((b_k - b_l)^2 + (a_k + a_l)(a_k b_l + a_l b_k))``;
``quadrature``
    ``||E||^2 = (1/pi) int_0^inf ||E(i w)||_F^2 dw``, trapezoidal in ``ln w`` on a log grid
    (the error is evaluated directly, so there is no cancellation);
``lyapunov``
    dense first-order controllability Gramian of the error system (round-off limits it to
    relative errors above ~1e-4 for stiff models).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import OptionError, check_choice
from .frequency import frf_full, frf_reduced

__all__ = ["h2_error", "DENSE_H2_LIMIT"]

#: Largest full model (DOF) for the dense ``modal`` and ``lyapunov`` methods.
DENSE_H2_LIMIT = 3000


def _dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)


def _modal_terms(M, K, B, C, alpha, beta):
    lam, phi = sla.eigh(_dense(K), _dense(M))
    lam = np.clip(lam, 0.0, None)
    R = np.einsum("pk,km->kpm", _dense(C) @ phi, phi.T @ _dense(B))  # residue matrices
    return alpha + beta * lam, lam, R


def _h2_modal(model, ports, red):
    d = model.damping
    if d.get("type") != "rayleigh":
        raise OptionError("h2_error(method='modal') needs Rayleigh damping")
    a1, b1, R1 = _modal_terms(model.M, model.K, ports.B, ports.C, d["alpha"], d["beta"])
    a2, b2, R2 = _modal_terms(red.M, red.K, red.B, red.C, d["alpha"], d["beta"])
    a, b = np.concatenate([a1, a2]), np.concatenate([b1, b2])
    R = np.concatenate([R1, -R2]).reshape(a.size, -1)
    if np.any(a <= 0):
        raise OptionError("the H2 norm needs damping of every mode (alpha > 0 for rigid-body modes)")
    S = a[:, None] + a[None, :]
    G = S / ((b[:, None] - b[None, :]) ** 2 + S * (a[:, None] * b[None, :] + a[None, :] * b[:, None]))
    W = R @ R.T
    err2 = float(np.sum(W * G))
    n1 = a1.size
    full2 = float(np.sum(W[:n1, :n1] * G[:n1, :n1]))
    return np.sqrt(max(err2, 0.0)), np.sqrt(full2)


def _h2_quadrature(model, ports, red, omega):
    w = np.asarray(omega, float)
    f = w / (2 * np.pi)
    H = frf_full(model, ports, f)
    E = H - frf_reduced(red, f)
    e2 = np.sum(np.abs(E) ** 2, axis=(1, 2))
    h2 = np.sum(np.abs(H) ** 2, axis=(1, 2))
    u = np.log(w)
    # [0, w0]: the integrand is constant near 0; int_0^w0 = w0 * value(w0)
    err2 = (np.trapezoid(e2 * w, u) + w[0] * e2[0]) / np.pi
    full2 = (np.trapezoid(h2 * w, u) + w[0] * h2[0]) / np.pi
    return np.sqrt(err2), np.sqrt(full2)


def _h2_lyapunov(model, ports, red):
    def first_order(M, D, K, B, C):
        M, K = _dense(M), _dense(K)
        n = M.shape[0]
        D = np.zeros((n, n)) if D is None else _dense(D)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
        return A, np.vstack([np.zeros((n, B.shape[1])), np.linalg.solve(M, _dense(B))]), \
            np.hstack([_dense(C), np.zeros((C.shape[0], n))])

    A1, B1, C1 = first_order(model.M, model.D, model.K, ports.B, ports.C)
    A2, B2, C2 = first_order(red.M, red.D, red.K, red.B, red.C)

    def norm(A, B, C):
        P = sla.solve_continuous_lyapunov(A, -B @ B.T)
        return float(np.sqrt(max(np.trace(C @ P @ C.T), 0.0)))

    return norm(sla.block_diag(A1, A2), np.vstack([B1, B2]), np.hstack([C1, -C2])), norm(A1, B1, C1)


def h2_error(model, ports, reduced, *, method: str = "auto", omega=None, relative: bool = True) -> float:
    """H2 norm of the error ``H - Hr`` (relative to ``||H||_H2`` by default).

    Parameters
    ----------
    model : FEModel
        With damping (the H2 norm of an undamped body is infinite).
    ports : Ports
    reduced : ReducedModel
    method : {'auto', 'modal', 'quadrature', 'lyapunov'}
        ``auto``: ``modal`` for Rayleigh damping, else ``quadrature``.
    omega : array_like, optional
        Log-spaced angular frequencies (rad/s) of ``quadrature``; default 100 points per
        decade over ``[1e-3, 1e3] x`` the range of the undamped eigenfrequencies.
    relative : bool
        Divide by ``||H||_H2``.

    References
    ----------
    Antoulas, A. C. (2005). Approximation of Large-Scale Dynamical Systems. SIAM, ch. 5.
    """
    check_choice("method", method, ["auto", "modal", "quadrature", "lyapunov"])
    if method == "auto":
        method = "modal" if model.damping.get("type") == "rayleigh" else "quadrature"
    if method in ("modal", "lyapunov") and model.n_dof > DENSE_H2_LIMIT:
        raise OptionError(f"h2_error method {method!r} is dense; the model has {model.n_dof} > {DENSE_H2_LIMIT} DOF")
    if method == "modal":
        err, full = _h2_modal(model, ports, reduced)
    elif method == "lyapunov":
        err, full = _h2_lyapunov(model, ports, reduced)
    else:
        if omega is None:
            lam = sla.eigh(_dense(model.K), _dense(model.M), eigvals_only=True) if model.n_dof <= DENSE_H2_LIMIT \
                else None
            if lam is None:
                raise OptionError("give omega for quadrature on a large model")
            lam = lam[lam > 1e-12 * lam[-1]]
            lo, hi = 1e-3 * np.sqrt(lam[0]), 1e3 * np.sqrt(lam[-1])
            omega = np.geomspace(lo, hi, int(100 * np.log10(hi / lo)) + 1)
        err, full = _h2_quadrature(model, ports, reduced, omega)
    return err / full if relative else err
