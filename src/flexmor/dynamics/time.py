"""Time integration of full and reduced second-order bodies and the time-domain error.

Both bodies ``M q'' + D q' + K q = B u(t)``, ``y = C q`` are integrated by the same
one-step scheme on a uniform grid ``t_n = n h``:

``newmark``
    Newmark-β with average acceleration (``β = 1/4, γ = 1/2``, trapezoidal rule):
    unconditionally stable, second order, no numerical damping; its only error on an
    undamped oscillator is the period elongation ``ω̄ h = 2 arctan(ω h / 2)``, i.e.
    ``ΔT/T ≈ (ω h)² / 12``.
``generalized-alpha``
    Chung & Hulbert's generalized-α: equilibrium at ``t_{n+1-α_m}`` (inertia) and
    ``t_{n+1-α_f}`` (the rest), parameters from the spectral radius at infinity ``ρ∞``
    (``α_m = (2ρ∞-1)/(ρ∞+1)``, ``α_f = ρ∞/(ρ∞+1)``, ``γ = 1/2 - α_m + α_f``,
    ``β = (1 - α_m + α_f)²/4``); second order, damps the unresolved high modes of a full
    FE model. ``ρ∞ = 1`` reproduces the Newmark average-acceleration sequence.

The effective matrix ``S = (1-α_m) M + (1-α_f) γ h D + (1-α_f) β h² K`` is constant: the full
(sparse) body factorizes it once with :func:`flexmor.linalg.factorize` and reuses it at every
step; the reduced (dense) body inverts it once (dense Cholesky) and steps by its one-step map
``(q, v, a)_k = P (q, v, a)_(k-1) + G w_k`` (the same scheme, equal to round-off). A consistent initial
acceleration ``M a_0 = B u(0) - D v_0 - K q_0`` costs one more factorization (of ``M``) only
when the initial force is non-zero.

Inputs: a *signal* ``u`` is a callable ``u(t)`` on the array of step times, or an array
sampled on them. A single-channel signal (shape ``(n_t,)``) is applied to **each input in
turn**, integrated as one block of ``m`` right-hand sides, so responses have the shape
**(n_t, n_outputs, n_inputs)** (like an FRF array); a multi-channel signal ``(n_t, m)`` loads
all inputs together and gives ``(n_t, n_outputs, 1)``. :func:`step`, :func:`impulse` and
:func:`sine_sweep` build common signals.

Time-domain error measures (named so in reports and JSON), with ``‖·‖`` the Frobenius norm
over outputs and load cases at one time:

``time_mean_error``
    ``mean_t ‖y(t) - ŷ(t)‖ / mean_t ‖y(t)‖``;
``time_max_error``
    ``max_t ‖y(t) - ŷ(t)‖ / max_t ‖y(t)‖`` (relative to the peak response, since the
    pointwise ratio is undefined at zero crossings).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import OptionError, check_choice, real_finite
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..linalg.distributed import is_partitioned
from ..linalg.threads import mkl_threads, sparse_dense

__all__ = [
    "QUANTITIES",
    "SCHEMES",
    "TimeResponse",
    "impulse",
    "scheme_parameters",
    "simulate",
    "sine_sweep",
    "step",
    "time_errors",
]

log = logging.getLogger(__name__)

#: Integration schemes of :func:`simulate`.
SCHEMES = ("newmark", "generalized-alpha")
#: Output quantities stored in a :class:`TimeResponse`.
QUANTITIES = ("displacement", "velocity", "acceleration")
#: Up to this size the step loop of a sparse body solves on one MKL thread (PARDISO): a solve
#: with one or two right-hand sides plus the products of one step cost 1.6-2.1 ms on one thread
#: against 2.5-8.6 ms on two at 3,000 DOF (2 cores, loaded), equal within noise at 27,000 DOF.
ONE_THREAD_MAX_DOF = 30_000


# -- signals -----------------------------------------------------------------------------------
def step(amplitude: float = 1.0, *, t0: float = 0.0, rise: float = 0.0) -> Callable:
    """A step of height ``amplitude`` at ``t0``, optionally with a linear ramp of ``rise`` seconds."""
    a, t0, rise = float(amplitude), float(t0), float(rise)
    if rise < 0:
        raise OptionError(f"step rise time must be >= 0, got {rise}")

    def u(t):
        t = np.asarray(t, float)
        if rise == 0:
            return np.where(t >= t0, a, 0.0)
        return a * np.clip((t - t0) / rise, 0.0, 1.0)

    return u


def impulse(width: float, area: float = 1.0, *, t0: float = 0.0) -> Callable:
    """A half-sine pulse of duration ``width`` starting at ``t0`` with the given ``area`` (N s).

    A resolvable stand-in for a Dirac impulse: choose ``width`` a few time steps long and
    shorter than the period of the highest frequency of interest.
    """
    w, area, t0 = float(width), float(area), float(t0)
    if w <= 0:
        raise OptionError(f"impulse width must be > 0, got {w}")

    def u(t):
        s = (np.asarray(t, float) - t0) / w
        return np.where((s >= 0) & (s <= 1), area * np.pi / (2 * w) * np.sin(np.pi * np.clip(s, 0, 1)), 0.0)

    return u


def sine_sweep(f0: float, f1: float, duration: float, amplitude: float = 1.0, *, kind: str = "linear") -> Callable:
    """A sine sweep (chirp) from ``f0`` to ``f1`` Hz over ``duration`` seconds, zero afterwards.

    ``kind='linear'``: instantaneous frequency ``f0 + (f1 - f0) t / T``; ``'log'``:
    ``f0 (f1/f0)^(t/T)`` (equal time per octave).
    """
    check_choice("kind", kind, ["linear", "log"])
    f0, f1, T, a = float(f0), float(f1), float(duration), float(amplitude)
    if T <= 0 or f0 < 0 or f1 < 0 or (kind == "log" and (f0 <= 0 or f1 <= 0 or f0 == f1)):
        raise OptionError(f"sine sweep needs duration > 0 and valid frequencies, got {f0}:{f1} Hz over {T} s")

    def u(t):
        t = np.asarray(t, float)
        tc = np.clip(t, 0.0, T)
        if kind == "linear":
            phase = 2 * np.pi * (f0 * tc + 0.5 * (f1 - f0) * tc ** 2 / T)
        else:
            k = np.log(f1 / f0) / T
            phase = 2 * np.pi * f0 * (np.exp(k * tc) - 1) / k
        return np.where((t >= 0) & (t <= T), a * np.sin(phase), 0.0)

    return u


# -- result ------------------------------------------------------------------------------------
@dataclass
class TimeResponse:
    """Output time histories of one integration.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Times (s).
    displacement, velocity, acceleration : ndarray, shape (n_t, n_outputs, n_cases)
        ``C q``, ``C q'``, ``C q''``; ``n_cases`` is the number of inputs for a single-channel
        signal (one load case per input) and 1 for a multi-channel one.
    seconds : float
        Wall time of the integration (factorizations included).
    scheme : str
        ``newmark`` or ``generalized-alpha``; ``params`` holds ``alpha_m, alpha_f, beta,
        gamma, rho_inf, dt``.
    n_factorizations : int
        Factorizations spent (sparse ones counted for full bodies).
    """

    t: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    seconds: float
    scheme: str
    params: dict = field(default_factory=dict)
    n_factorizations: int = 0

    def output(self, quantity: str = "displacement") -> np.ndarray:
        """The history of ``quantity`` (one of :data:`QUANTITIES`)."""
        check_choice("quantity", quantity, list(QUANTITIES))
        return getattr(self, quantity)


def scheme_parameters(scheme: str = "newmark", rho_inf: float = 0.9) -> dict:
    """``alpha_m, alpha_f, beta, gamma`` of a scheme (Newmark: ``0, 0, 1/4, 1/2``)."""
    check_choice("scheme", scheme, list(SCHEMES))
    if scheme == "newmark":
        return {"alpha_m": 0.0, "alpha_f": 0.0, "beta": 0.25, "gamma": 0.5, "rho_inf": 1.0}
    r = float(rho_inf)
    if not 0.0 <= r <= 1.0:
        raise OptionError(f"rho_inf must be in [0, 1], got {r}")
    am, af = (2 * r - 1) / (r + 1), r / (r + 1)
    return {"alpha_m": am, "alpha_f": af, "beta": 0.25 * (1 - am + af) ** 2, "gamma": 0.5 - am + af, "rho_inf": r}


def _signal(u, t: np.ndarray, m: int) -> tuple[np.ndarray, bool]:
    """Sample ``u`` on ``t``: returns ``(U, each)``, U (n_t, k); ``each`` for one channel per input."""
    try:
        values = u(t) if callable(u) else u
    except (TypeError, ValueError) as exc:
        raise OptionError(f"the input signal u, a function of the time array, failed on it: {exc}"[:300],
                          params=("u",)) from None
    U = real_finite(values, "u", "real, finite numbers (one value, samples on the time grid) or a function of "
                    "the time array returning them")
    if U.ndim == 0:
        U = np.full(t.size, float(U))
    if U.shape[0] != t.size:
        raise OptionError(f"the input signal has {U.shape[0]} samples, the time grid {t.size}")
    if U.ndim == 1 or (U.ndim == 2 and U.shape[1] == 1 and m > 1):
        return U.reshape(t.size, 1), True
    if U.ndim == 2 and U.shape[1] == m:
        return U, False
    raise OptionError(f"the input signal has shape {U.shape}; expected ({t.size},) or ({t.size}, {m})")


def _matrices(system, B=None, C=None):
    """``M, D, K, B, C`` of a ReducedModel, an FEModel with ports, or a tuple; sparse flag."""
    if isinstance(system, tuple):
        M, D, K, B, C = system
    else:
        M, D, K = system.M, system.D, system.K
        B = system.B if B is None else B
        C = system.C if C is None else C
    if B is None or C is None:
        raise OptionError("give the input and output matrices (ports) of the full model")
    sparse = sp.issparse(M) or is_partitioned(M)
    if sparse:  # partitioned matrices (rows over MPI ranks) stay as they are
        M, K = (A if is_partitioned(A) else sp.csr_matrix(A) for A in (M, K))
        D = D if D is None or is_partitioned(D) else sp.csr_matrix(D)
        B = B.toarray() if sp.issparse(B) else np.asarray(B, float)
        C = sp.csr_matrix(C)
    else:
        M, K = np.asarray(M, float), np.asarray(K, float)
        D = None if D is None else np.asarray(D, float)
        B, C = np.asarray(B, float), np.asarray(C, float)
    return M, D, K, B, C, sparse


def _rayleigh_of(system, M, D, K) -> tuple[float, float] | None:
    """``(alpha, beta)`` when the sparse ``D`` of ``system`` is its Rayleigh ``alpha M + beta K``, else None.

    Trusts ``system.damping`` only after one product check (a relative ``1e-12``), so a damping
    matrix set by hand is never replaced by the coefficients it was not built from.
    """
    from ..damping import Rayleigh

    damping = getattr(system, "damping", None)
    if D is None or not isinstance(damping, Rayleigh) or not all(sp.issparse(A) for A in (M, D, K)):
        return None
    alpha, beta = float(damping.alpha), float(damping.beta)
    z = np.random.default_rng(0).standard_normal(K.shape[0])
    d = D @ z
    gap = np.linalg.norm(d - alpha * (M @ z) - beta * (K @ z))
    return (alpha, beta) if gap <= 1e-12 * max(np.linalg.norm(d), np.finfo(float).tiny) else None


def _dense_solver(S):
    try:
        c = sla.cho_factor(S)
        return lambda b: sla.cho_solve(c, b)
    except np.linalg.LinAlgError:
        lu = sla.lu_factor(S)
        return lambda b: sla.lu_solve(lu, b)


def _march_sparse(Y, steps, mats, rayleigh, solve, F, state, p, h):
    """The step loop of a sparse body: one factorized solve and one to three products per step."""
    M, D, K, C = mats
    q, v, a = state
    n, ncase = q.shape
    am, af, beta, gamma = p["alpha_m"], p["alpha_f"], p["beta"], p["gamma"]
    c_dv, c_dd, c_dda = (1 - af) * h * (1 - gamma), (1 - af) * h, (1 - af) * h * h * (0.5 - beta)
    Fprev = F(0)
    with mkl_threads(1) if n <= ONE_THREAD_MAX_DOF else contextlib.nullcontext():
        for k in steps:
            Fk = F(k)
            rhs = (1 - af) * Fk + af * Fprev
            x = q + c_dd * v + c_dda * a
            if am:
                rhs -= am * sparse_dense(M, a)
            if rayleigh is not None:  # K x + D y as one product with K (and one with M when alpha > 0)
                y = v + c_dv * a
                rhs -= sparse_dense(K, x + rayleigh[1] * y)
                if rayleigh[0]:
                    rhs -= rayleigh[0] * sparse_dense(M, y)
            else:
                rhs -= sparse_dense(K, x)
                if D is not None:
                    rhs -= sparse_dense(D, v + c_dv * a)
            a_new = solve(rhs).reshape(n, ncase)
            q = q + h * v + h * h * ((0.5 - beta) * a + beta * a_new)
            v = v + h * ((1 - gamma) * a + gamma * a_new)
            a, Fprev = a_new, Fk
            Y[0, k], Y[1, k], Y[2, k] = C @ q, C @ v, C @ a


def _march_dense(Y, steps, mats, S, U, each, state, p, h):
    """The step loop of a dense body as its one-step map: ``x_k = P x_(k-1) + G w_k`` on ``x = (q, v, a)``.

    The same scheme as :func:`_march_sparse` (equal to round-off): with ``S^-1`` formed once,
    ``a_k = S^-1 (r_k - K (q + c_dd v + c_dda a) - D (v + c_dv a) - alpha_m M a)``, and ``q_k``,
    ``v_k`` the Newmark updates of it, are linear in ``x_(k-1)`` and the load ``r_k = B w_k``,
    ``w_k = (1 - alpha_f) u_k + alpha_f u_(k-1)``; one product per step instead of a dozen.
    """
    M, D, K, B, C = mats
    q, v, a = state
    n = q.shape[0]
    am, af, beta, gamma = p["alpha_m"], p["alpha_f"], p["beta"], p["gamma"]
    c_dv, c_dd, c_dda = (1 - af) * h * (1 - gamma), (1 - af) * h, (1 - af) * h * h * (0.5 - beta)
    Sinv = _dense_solver(S)(np.eye(n))
    Dm = np.zeros_like(K) if D is None else D
    A = -Sinv @ np.hstack([K, c_dd * K + Dm, c_dda * K + c_dv * Dm + am * M])  # a_k = A x_(k-1) + Sinv r_k
    eye, zero = np.eye(n), np.zeros((n, n))
    P = np.vstack([np.hstack([eye, h * eye, h * h * (0.5 - beta) * eye]) + h * h * beta * A,
                   np.hstack([zero, eye, h * (1 - gamma) * eye]) + h * gamma * A, A])
    G = np.vstack([h * h * beta * Sinv, h * gamma * Sinv, Sinv]) @ B
    W = (1 - af) * U[1:] + af * U[:-1]
    C3 = np.kron(np.eye(3), C)
    x = np.vstack([q, v, a])
    shape = Y.shape[0], Y.shape[2], Y.shape[3]
    for k in steps:
        x = P @ x + (G * W[k - 1] if each else (G @ W[k - 1])[:, None])
        Y[:, k] = (C3 @ x).reshape(shape)


def _check_records(n_steps: int, p: int, m: int, dt: float, t_end: float) -> None:
    """Refuse a run whose recorded responses (three quantities, ``n_steps + 1`` times, ``p`` outputs, ``m``
    cases at most) would not fit into the memory available (a dt of 1e-12 s: 74.5 GiB, then numpy's MemoryError)."""
    from ..linalg.resources import describe_memory, megabytes, memory_available

    need = 3.0 * 8.0 * (n_steps + 1) * max(p, 1) * max(m, 1)
    room = memory_available()
    if room is not None and need > 0.5 * room:
        raise OptionError(f"t_end / dt = {t_end:g} s / {dt:g} s = {n_steps:,} steps: the recorded responses need "
                          f"{megabytes(need)}, more than half the memory available ({describe_memory()}); give a "
                          "larger dt or a shorter t_end", params=("dt", "t_end"))


def simulate(system, u, *, dt: float, t_end: float, ports=None, scheme: str = "newmark", rho_inf: float = 0.9,
             q0=None, v0=None, solver: SolverContext | None = None, progress: Callable | None = None) -> TimeResponse:
    """Integrate ``M q'' + D q' + K q = B u(t)`` from ``t = 0`` to ``t_end`` and record ``y = C q``.

    Parameters
    ----------
    system : ReducedModel, FEModel or tuple
        A reduced body (dense ``M, D, K, B, C``), a full model (sparse; give ``ports``), or a
        tuple ``(M, D, K, B, C)`` (``D`` may be None; sparse or dense).
    u : callable or array_like
        The input signal: ``u(t)`` on the array of times, or samples on them; shape
        ``(n_t,)`` (applied to each input in turn) or ``(n_t, n_inputs)`` (all at once).
    dt, t_end : float
        Step and end time (s); ``round(t_end / dt)`` steps.
    ports : Ports, optional
        Inputs and outputs of a full model (``B``, ``C``).
    scheme : {'newmark', 'generalized-alpha'}
    rho_inf : float
        Spectral radius at infinity of ``generalized-alpha`` (0 ≤ ρ∞ ≤ 1).
    q0, v0 : array_like, optional
        Initial displacement and velocity, shape (n,) or (n, n_cases); default zero.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` (full bodies).
    progress : callable, optional
        ``progress(iterable, total)`` wrapper of the step loop (e.g. tqdm).

    Returns
    -------
    TimeResponse

    References
    ----------
    Newmark, N. M. (1959). A method of computation for structural dynamics. Journal of the
    Engineering Mechanics Division, ASCE 85(EM3), 67-94.

    Chung, J., Hulbert, G. M. (1993). A time integration algorithm for structural dynamics
    with improved numerical dissipation: the generalized-α method. Journal of Applied
    Mechanics 60(2), 371-375.
    """
    solver = as_solver(solver)
    t_start = time.perf_counter()
    try:
        dt, t_end = float(dt), float(t_end)
    except (TypeError, ValueError):
        raise OptionError(f"dt and t_end are times in s (numbers), got dt={dt!r}, t_end={t_end!r}",
                          params=("dt", "t_end")) from None
    if not (np.isfinite(dt) and np.isfinite(t_end)) or dt <= 0 or t_end <= 0:
        raise OptionError(f"need dt > 0 and t_end > 0, got dt={dt}, t_end={t_end}", params=("dt", "t_end"))
    if t_end < dt * (1 - 1e-9):
        raise OptionError(f"t_end {t_end:g} s is shorter than one step dt {dt:g} s", params=("dt", "t_end"))
    n_steps = max(1, round(t_end / dt))
    p = scheme_parameters(scheme, rho_inf)
    am, af, beta, gamma = p["alpha_m"], p["alpha_f"], p["beta"], p["gamma"]
    M, D, K, B, C, sparse = _matrices(system, *((ports.B, ports.C) if ports is not None else (None, None)))
    n, m = B.shape
    _check_records(n_steps, C.shape[0], m, dt, t_end)
    for name, x0 in (("q0", q0), ("v0", v0)):
        if x0 is not None and (np.size(x0) == 0 or np.size(x0) % n):
            raise OptionError(f"{name} must have {n} rows (one per equation of the system), got shape "
                              f"{np.shape(x0)}", params=(name,))
    t = dt * np.arange(n_steps + 1)
    U, each = _signal(u, t, m)
    F = (lambda k: B * U[k]) if each else (lambda k: (B @ U[k]).reshape(n, 1))
    ncase = m if each else 1
    q = np.zeros((n, ncase)) if q0 is None else np.array(np.broadcast_to(np.reshape(q0, (n, -1)), (n, ncase)), float)
    v = np.zeros((n, ncase)) if v0 is None else np.array(np.broadcast_to(np.reshape(v0, (n, -1)), (n, ncase)), float)

    h = dt
    S = (1 - am) * M + (1 - af) * beta * h * h * K
    if D is not None:
        S = S + (1 - af) * gamma * h * D
    n_fact = 0
    if sparse:
        solve = factorize(S.tocsr(), solver=solver, symmetric=True, positive=True).solve
        n_fact += 1

    f0 = F(0) - K @ q - (D @ v if D is not None else 0.0)
    if np.any(f0):
        if sparse:
            a = factorize(M, solver=solver, symmetric=True, positive=True).solve(f0)
            n_fact += 1
        else:
            a = _dense_solver(M)(f0)
    else:
        a = np.zeros_like(q)
    a = a.reshape(n, ncase)

    nt = n_steps + 1
    p_out = C.shape[0]
    Y = np.empty((3, nt, p_out, ncase))
    Y[0, 0], Y[1, 0], Y[2, 0] = C @ q, C @ v, C @ a
    steps = range(1, nt) if progress is None else progress(range(1, nt), n_steps)
    if sparse:
        _march_sparse(Y, steps, (M, D, K, C), _rayleigh_of(system, M, D, K), solve, F, (q, v, a), p, h)
    else:
        _march_dense(Y, steps, (M, D, K, B, C), S, U, each, (q, v, a), p, h)
    if not np.all(np.isfinite(Y)):
        raise OptionError("the time integration produced NaN/Inf (check the model and the input signal)")
    seconds = time.perf_counter() - t_start
    params = dict(p, dt=dt, t_end=float(t[-1]), n_steps=n_steps)
    log.info("%s: %d steps of %.3g s on %d DOF x %d cases in %.3f s", scheme, n_steps, dt, n, ncase, seconds)
    return TimeResponse(t=t, displacement=Y[0], velocity=Y[1], acceleration=Y[2], seconds=seconds, scheme=scheme,
                        params=params, n_factorizations=n_fact)


def time_errors(full: TimeResponse, reduced: TimeResponse, quantity: str = "displacement") -> dict:
    """``time_mean_error`` and ``time_max_error`` of ``reduced`` against ``full`` (see module docstring).

    Both responses must be on the same time grid and load cases. Returns a dict with the two
    measures, ``quantity`` and the wall times ``seconds_full``, ``seconds_reduced``.
    """
    y, yr = full.output(quantity), reduced.output(quantity)
    if y.shape != yr.shape or full.t.size != reduced.t.size or not np.allclose(full.t, reduced.t):
        raise OptionError(f"responses differ in shape or time grid: {y.shape} vs {yr.shape}")
    e = np.linalg.norm((y - yr).reshape(y.shape[0], -1), axis=1)
    r = np.linalg.norm(y.reshape(y.shape[0], -1), axis=1)
    tiny = np.finfo(float).tiny
    return {"quantity": quantity,
            "time_mean_error": float(np.mean(e) / max(np.mean(r), tiny)),
            "time_max_error": float(np.max(e) / max(np.max(r), tiny)),
            "seconds_full": full.seconds, "seconds_reduced": reduced.seconds}
