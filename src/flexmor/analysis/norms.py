"""H2 norms of reduction errors ``||H - Hr||_H2`` for second-order bodies (small models), and the
H-infinity norm of small dense first-order systems (:func:`hinf_norm`).

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
from scipy.integrate import trapezoid  # any numpy (np.trapezoid: numpy >= 2 only)

from ..damping import Rayleigh
from ..dynamics.frf import frf_full, frf_reduced
from ..errors import OptionError, check_choice
from ..linalg.distributed import is_partitioned
from ..linalg.eigen import dense_eigenmodes

__all__ = ["DENSE_H2_LIMIT", "h2_error", "hinf_norm"]

#: Largest full model (DOF) for the dense ``modal`` and ``lyapunov`` methods.
DENSE_H2_LIMIT = 3000


def _dense(A):
    return A.toarray() if sp.issparse(A) or is_partitioned(A) else np.asarray(A, dtype=float)


def _modal_terms(M, K, B, C, alpha, beta):
    lam, phi = dense_eigenmodes(K, M)
    lam = np.clip(lam, 0.0, None)
    R = np.einsum("pk,km->kpm", _dense(C) @ phi, phi.T @ _dense(B))  # residue matrices
    return alpha + beta * lam, lam, R


def _h2_modal(model, ports, body):
    d = model.damping
    if not isinstance(d, Rayleigh):
        raise OptionError("h2_error(method='modal') needs Rayleigh damping")
    a1, b1, R1 = _modal_terms(model.M, model.K, ports.B, ports.C, d.alpha, d.beta)
    a2, b2, R2 = _modal_terms(body.M, body.K, body.B, body.C, d.alpha, d.beta)
    a, b = np.concatenate([a1, a2]), np.concatenate([b1, b2])
    R = np.concatenate([R1, -R2]).reshape(a.size, -1)
    # modes the ports do not see (e.g. rigid-body modes of the inputs' elastic part) do not count
    r = np.linalg.norm(R, axis=1)
    seen = r > 1e-10 * r.max(initial=0.0)
    if np.any(a[seen] <= 0):
        raise OptionError("the H2 norm needs damping of every mode (alpha > 0 for rigid-body modes)")
    a, b, R = a[seen], b[seen], R[seen]
    n1 = int(np.sum(seen[: a1.size]))
    S = a[:, None] + a[None, :]
    G = S / ((b[:, None] - b[None, :]) ** 2 + S * (a[:, None] * b[None, :] + a[None, :] * b[:, None]))
    W = R @ R.T
    err2 = float(np.sum(W * G))
    full2 = float(np.sum(W[:n1, :n1] * G[:n1, :n1]))
    return np.sqrt(max(err2, 0.0)), np.sqrt(full2)


def _h2_quadrature(model, ports, body, omega):
    w = np.asarray(omega, float)
    f = w / (2 * np.pi)
    H = frf_full(model, ports, f)
    E = H - frf_reduced(body, f)
    e2 = np.sum(np.abs(E) ** 2, axis=(1, 2))
    h2 = np.sum(np.abs(H) ** 2, axis=(1, 2))
    u = np.log(w)
    # [0, w0]: the integrand is constant near 0; int_0^w0 = w0 * value(w0)
    err2 = (trapezoid(e2 * w, u) + w[0] * e2[0]) / np.pi
    full2 = (trapezoid(h2 * w, u) + w[0] * h2[0]) / np.pi
    return np.sqrt(err2), np.sqrt(full2)


def _h2_lyapunov(model, ports, body):
    def first_order(M, D, K, B, C):
        M, K = _dense(M), _dense(K)
        n = M.shape[0]
        D = np.zeros((n, n)) if D is None else _dense(D)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
        return A, np.vstack([np.zeros((n, B.shape[1])), np.linalg.solve(M, _dense(B))]), \
            np.hstack([_dense(C), np.zeros((C.shape[0], n))])

    A1, B1, C1 = first_order(model.M, model.D, model.K, ports.B, ports.C)
    A2, B2, C2 = first_order(body.M, body.D, body.K, body.B, body.C)

    def norm(A, B, C):
        P = sla.solve_continuous_lyapunov(A, -B @ B.T)
        return float(np.sqrt(max(np.trace(C @ P @ C.T), 0.0)))

    return norm(sla.block_diag(A1, A2), np.vstack([B1, B2]), np.hstack([C1, -C2])), norm(A1, B1, C1)


def h2_error(model, ports, body, *, method: str = "auto", omega=None, relative: bool = True) -> float:
    """H2 norm of the error ``H - Hr`` (relative to ``||H||_H2`` by default).

    Parameters
    ----------
    model : FEModel
        With damping (the H2 norm of an undamped body is infinite).
    ports : Ports
    body : ReducedModel
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
        method = "modal" if isinstance(model.damping, Rayleigh) else "quadrature"
    if method in ("modal", "lyapunov") and model.n_dof > DENSE_H2_LIMIT:
        raise OptionError(f"h2_error method {method!r} is dense; the model has {model.n_dof} > {DENSE_H2_LIMIT} DOF")
    if method == "modal":
        err, full = _h2_modal(model, ports, body)
    elif method == "lyapunov":
        err, full = _h2_lyapunov(model, ports, body)
    else:
        if omega is None:
            lam = dense_eigenmodes(model.K, model.M)[0] if model.n_dof <= DENSE_H2_LIMIT else None
            if lam is None:
                raise OptionError("give omega for quadrature on a large model")
            lam = lam[lam > 1e-12 * lam[-1]]
            lo, hi = 1e-3 * np.sqrt(lam[0]), 1e3 * np.sqrt(lam[-1])
            omega = np.geomspace(lo, hi, int(100 * np.log10(hi / lo)) + 1)
        err, full = _h2_quadrature(model, ports, body, omega)
    return err / full if relative else err


class _SchurResponse:
    """``G(i w) = C (i w I - A)^{-1} B`` through the complex Schur form ``A = Z T Z^H`` (O(n^2) per w)."""

    def __init__(self, A, B, C):
        T, Z = sla.schur(A.astype(complex), output="complex")
        self.T, self.ZB, self.CZ = T, Z.conj().T @ B, C @ Z
        self.I = np.eye(A.shape[0])

    def __call__(self, w: float) -> np.ndarray:
        return self.CZ @ sla.solve_triangular(1j * w * self.I - self.T, self.ZB, check_finite=False)

    def sigma(self, w) -> np.ndarray:
        """All singular values at each ``w``, shape (len(w), min(p, m))."""
        return np.array([np.linalg.svd(self(x), compute_uv=False) for x in np.atleast_1d(w)])


def hinf_norm(A, B, C, *, rtol: float = 1e-8, max_iter: int = 60) -> tuple[float, float]:
    """H-infinity norm ``sup_w sigma_max(C (iwI - A)^{-1} B)`` of a small stable first-order system.

    Bisection-free level-set iteration of Boyd, Balakrishnan, Bruinsma and Steinbuch: from a
    lower bound ``g`` (the largest value at ``w = 0`` and at the pole frequencies), the purely
    imaginary eigenvalues ``i w_j`` of the Hamiltonian
    ``H(gamma) = [[A, B B^T / gamma], [-C^T C / gamma, -A^T]]`` at ``gamma = (1 + 2 rtol) g``
    mark the frequencies where a singular value of ``G`` equals ``gamma``; the next lower bound
    is the largest ``sigma_max`` at the midpoints of those intervals. When ``H(gamma)`` has no
    imaginary eigenvalue, ``gamma`` is an upper bound and the iteration stops (quadratic
    convergence). A candidate eigenvalue counts as imaginary only if ``gamma`` is a singular
    value of ``G(i w_j)`` (relative ``1e-6``), which guards against round-off in ``eig``.

    Parameters
    ----------
    A : array_like or sparse, shape (n, n)
        Asymptotically stable (dense work ``O(n^3)``; a few thousand states at most).
    B : array_like, shape (n, m)
    C : array_like, shape (p, n)
    rtol : float
        Relative accuracy: the true norm lies in ``[value, (1 + 2 rtol) value]``.
    max_iter : int

    Returns
    -------
    value : float
        The norm (an attained value of ``sigma_max``, within ``rtol`` of the supremum).
    w_peak : float
        Frequency (rad/s) where it is attained.

    Raises
    ------
    OptionError
        Unstable ``A`` (the norm is infinite) or inconsistent sizes.
    ConvergenceError
        No certified upper bound after ``max_iter`` iterations.

    References
    ----------
    Boyd, S., Balakrishnan, V., Kabamba, P. (1989). A bisection method for computing the
    H-infinity norm of a transfer matrix and related problems. Math. Control Signals Systems 2, 207-219.

    Bruinsma, N. A., Steinbuch, M. (1990). A fast algorithm to compute the H-infinity norm of a
    transfer function matrix. Systems & Control Letters 14, 287-293.
    """
    from ..errors import ConvergenceError

    A, B, C = _dense(A), _dense(B), _dense(C)
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or C.shape[1] != n:
        raise OptionError(f"inconsistent state-space sizes A {A.shape}, B {B.shape}, C {C.shape}")
    lam = np.linalg.eigvals(A)
    if lam.real.max(initial=-np.inf) >= 0:
        raise OptionError("the H-infinity norm of a system with an eigenvalue in Re >= 0 is infinite")
    G = _SchurResponse(A, B, C)
    cand = np.unique(np.concatenate([[0.0], np.abs(lam.imag), np.abs(lam)]))
    vals = G.sigma(cand)[:, 0]
    k = int(np.argmax(vals))
    g, w_peak = float(vals[k]), float(cand[k])
    if g == 0:
        return 0.0, 0.0
    BB, CC = B @ B.T, C.T @ C
    for _ in range(max_iter):
        gamma = (1 + 2 * rtol) * g
        ev = np.linalg.eigvals(np.block([[A, BB / gamma], [-CC / gamma, -A.T]]))
        near = ev[(np.abs(ev.real) <= 1e-6 * np.maximum(np.abs(ev), 1.0)) & (ev.imag >= 0)]
        w = np.sort(near.imag)
        if w.size:  # keep the frequencies where gamma really is a singular value of G
            w = w[np.any(np.abs(G.sigma(w) - gamma) <= 1e-6 * gamma, axis=1)]
        if w.size == 0:
            return g, w_peak
        mids = 0.5 * (w[:-1] + w[1:]) if w.size > 1 else w
        vals = G.sigma(mids)[:, 0]
        k = int(np.argmax(vals))
        if vals[k] <= g:  # no progress: gamma is within round-off of the supremum
            return g, w_peak
        g, w_peak = float(vals[k]), float(mids[k])
    raise ConvergenceError(f"H-infinity norm: no certified upper bound after {max_iter} iterations (last {g:.6g})")
