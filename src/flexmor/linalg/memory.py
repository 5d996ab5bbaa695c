"""Factorizations that fit into memory: the memory modes behind :func:`flexmor.linalg.factorize`.

A sparse direct factorization whose double-precision factor does not fit into the memory of
the machine can still be computed on it, in one of three modes
(``SolverContext(factor_memory=...)``, ``--factor-memory``):

``double``
    The factor in double precision, in memory (the fastest; refused when it does not fit).
``mixed``
    The factor in single precision (``float32`` / ``complex64``: half the memory of the
    factor; PARDISO ``iparm[27] = 1`` or SciPy's SuperLU), each solve refined in double
    precision against the double matrix by GMRES with the single-precision factor as
    preconditioner (:func:`refine`), until the normwise backward error
    ``||b - A x|| / (||A|| ||x|| + ||b||)`` of every column is that of a double-precision
    solve (:data:`BACKWARD_TARGET`); it must then be at most ``refine_tol``. Converges for
    ``eps_single * cond(A)`` beyond 1 too, as long as few eigenvalues of the preconditioned
    matrix are far from 1 (a shift near an eigenvalue); a matrix too ill-conditioned for it is
    refused with a :class:`~flexmor.errors.SolverError` that suggests the out-of-core mode.
``ooc``
    PARDISO's out-of-core mode (``iparm[59] = 2``): the factor is written to files in a
    temporary directory (:class:`OutOfCore`, removed with the factorization) and at most
    ``MKL_PARDISO_OOC_MAX_CORE_SIZE`` of it is kept in memory. Exact as in core, slower; each
    factor is checked by one solve (:meth:`OutOfCore.verify`).

``auto`` (the default) takes the first of double, mixed and out-of-core whose estimate fits
into :data:`MEMORY_FRACTION` of the available memory (``memory_limit``, default the
``MemAvailable`` of the machine), and otherwise refuses with the estimates of all three
(:func:`plan_memory`). The estimates come from PARDISO's analysis phase (the in-core peak
``max(iparm[14], iparm[15] + iparm[16])`` KB; see :func:`pardiso_estimates`) or from the
SuperLU heuristic of :func:`estimate_memory`; the mixed mode counts the double matrix it keeps
for the residuals. The choice and its reason are logged and counted in
:class:`~flexmor.linalg.factorization.SolverStats` (summarized by :func:`factor_record`).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import weakref
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..errors import OutOfMemoryError, SolverError
from .resources import MEMORY_FRACTION
from .resources import bound as _bound
from .resources import megabytes as _mb
from .threads import sparse_dense

__all__ = ["BACKWARD_TARGET", "FACTOR_MEMORY", "MEMORY_FRACTION", "MODE_NAMES", "REFINE_MAX_ITER", "REFINE_RESTART",
           "REFINE_TOL", "SOLVE_TOL", "MemoryPlan", "OutOfCore", "describe_factor", "estimate_memory", "factor_record",
           "iterative_record",
           "matrix_bytes", "norm_bound", "pardiso_estimates", "plan_memory", "refine", "refusal"]

log = logging.getLogger(__name__)

#: Choices of ``SolverContext(factor_memory=...)``.
FACTOR_MEMORY = ("auto", "double", "mixed", "ooc")

#: How the modes are named in logs, messages and reports.
MODE_NAMES = {"double": "double precision in core", "mixed": "mixed precision", "ooc": "out of core"}

#: Default backward error of the refined solves of the mixed mode.
REFINE_TOL = 1e-12

#: Default relative residual of the iterative solves of the ``amg`` backend (:mod:`flexmor.linalg.amg`).
SOLVE_TOL = 1e-10

#: Most steps (block solves with the single-precision factor) of one refined solve in the mixed mode.
REFINE_MAX_ITER = 30

#: Steps of one GMRES cycle of the refined solves before a restart (memory: this many Krylov
#: vectors in double and in single precision per right-hand side).
REFINE_RESTART = 10

#: Normwise backward error at which a refined solve stops: that of a backward-stable solve in
#: double precision (twice the unit roundoff; see :func:`refine`).
BACKWARD_TARGET = float(np.finfo(float).eps)

#: Relative residual of the check of an out-of-core factor (:meth:`OutOfCore.verify`) above which it is refused;
#: below it, a solve whose backward error is above the double-precision factor's is refined (GMRES with the factor,
#: whose steps contract the error by about this residual each).
OOC_CHECK_TOL = 1e-3

#: Share of the in-core factor that PARDISO's out-of-core mode needs in memory beside its
#: permanent data when MKL does not report a minimum (``iparm[62] = 0``, as MKL 2026 does):
#: measured on 3D cantilevers, where 1/10 of the factor (plus the permanent data) sufficed.
OOC_MIN_SHARE = 1 / 8


@dataclass(frozen=True)
class MemoryPlan:
    """The memory mode chosen for one factorization.

    Attributes
    ----------
    mode : {'double', 'mixed', 'ooc'}
        The mode used.
    estimates : dict
        Bytes each mode needs (None: the backend does not have it, or nothing is known).
    usable : float or None
        Bytes the factorization may use (:data:`MEMORY_FRACTION` of the available memory),
        None when unknown.
    reason : str
        Why this mode (logged, and recorded in the solver statistics).
    """

    mode: str
    estimates: dict
    usable: float | None
    reason: str

    @property
    def estimate(self) -> float | None:
        """Bytes the chosen mode needs."""
        return self.estimates.get(self.mode)


def refusal(n: int, backend: str, estimates: dict, available: float, others=()) -> OutOfMemoryError:
    """The error of a factorization of ``n`` equations that fits in no mode into ``available`` bytes."""
    alt = [f"in mixed precision {_mb(estimates['mixed'])}"] if estimates.get("mixed") is not None else []
    alt += [f"out of core at least {_mb(estimates['ooc'])}"] if estimates.get("ooc") is not None else []
    hint = (f"try another backend ({', '.join(others)}), " if others else "") + \
        "a distributed backend on a machine with more memory, or a smaller model"
    return OutOfMemoryError(
        f"factorizing {n} equations with {backend} needs about {_mb(estimates['double'])}"
        + "".join([" in double precision"] + [f", {a}" for a in alt] if alt else [])
        + f", but only {_mb(available)} of memory are available{_bound(available)}; {hint}")


def plan_memory(solver, backend: str, n: int, estimates: dict) -> MemoryPlan:
    """The memory mode of a factorization with the given ``estimates`` (bytes per mode).

    Parameters
    ----------
    solver : SolverContext
        Its ``factor_memory`` (auto, double, mixed, ooc) and available memory
        (:meth:`~flexmor.linalg.context.SolverContext.memory_available`).
    backend : str
        Name of the backend (in messages).
    n : int
        Number of equations (in messages).
    estimates : dict
        ``double``, ``mixed``, ``ooc`` -> bytes, or None where the backend lacks the mode (or
        for ``double``: nothing is known, which fits).

    Raises
    ------
    SolverError
        Nothing fits (auto), the mode asked for does not fit, or the backend lacks it.
    """
    asked = solver.factor_memory
    avail = solver.memory_available()
    usable = None if avail is None else MEMORY_FRACTION * avail

    def fits(mode):
        est = estimates.get(mode)
        if est is None:
            return mode == "double"  # no estimate: the factorization is tried
        return usable is None or est <= usable

    if asked != "auto" and asked != "double" and estimates.get(asked) is None:
        raise SolverError(f"factor_memory={asked!r} is not available with {backend}", params=("factor_memory",))
    candidates = ("double", "mixed", "ooc") if asked == "auto" else (asked,)
    mode = next((m for m in candidates if fits(m)), None)
    if mode is None:
        shown = estimates if asked == "auto" else {k: estimates[k] for k in {"double", asked}}
        raise refusal(n, backend, shown, avail, [b for b in solver.available() if b != backend])
    if asked != "auto":
        reason = f"{MODE_NAMES[mode]} (factor_memory={asked!r})"
    elif mode == "double":
        reason = MODE_NAMES[mode] + ("" if usable is None or estimates.get("double") is None
                                     else f" ({_mb(estimates['double'])} of {_mb(usable)} usable)")
    else:
        reason = (f"{MODE_NAMES[mode]}: the double-precision factor needs {_mb(estimates['double'])}, "
                  f"{_mb(usable)} usable; {MODE_NAMES[mode]} needs {_mb(estimates[mode])}")
    (log.info if mode != "double" else log.debug)("factorizing n=%d with %s: %s", n, backend, reason)
    return MemoryPlan(mode, dict(estimates), usable, reason)


def factor_record(stats) -> dict:
    """The memory modes of the factorizations counted in ``stats`` (a :class:`SolverStats`): the
    JSON record ``factor`` with the factorizations per mode, the refinement and the last reason."""
    return {"double": stats.count - stats.mixed - stats.ooc - stats.iterative, "mixed": stats.mixed, "ooc": stats.ooc,
            "refined_solves": stats.refined_solves, "refine_steps": stats.refine_steps,
            "refine_max_steps": stats.refine_max_steps,
            "refine_residual": stats.refine_residual if stats.refined_solves else None,
            "reason": stats.factor_reason or None,
            "iterative": iterative_record(stats) if stats.iterative else None}


def iterative_record(stats, since: tuple = (0, 0, 0)) -> dict:
    """The matrices of ``stats`` solved iteratively (the ``amg`` or ``petsc-gamg`` backend: ``backend``) since
    the counts ``since`` =
    ``(stats.iterative, stats.iterations, stats.eigen_iterations)`` were taken: how many, their block CG
    iterations (in all, and the most of one solve of the context), the relative residual asked and the largest
    one reached; the iterations of the preconditioned eigensolver (LOBPCG) and its largest relative eigenpair
    residual (None where it did not run)."""
    eig = stats.eigen_iterations - (since[2] if len(since) > 2 else 0)
    return {"backend": stats.iterative_backend or "amg", "matrices": stats.iterative - since[0],
            "iterations": stats.iterations - since[1],
            "iterations_max": stats.iterations_max, "solve_tol": stats.iterative_tol,
            "relative_residual_max": stats.iterative_residual if stats.iterations else None,
            "eigen_iterations": eig, "eigen_residual_max": stats.eigen_residual if eig else None}


def describe_factor(stats) -> str:
    """One line on the factorizations of ``stats`` not in double precision in core ("" when all were)."""
    parts = [f"{MODE_NAMES[m]} ({getattr(stats, m)} of {stats.count} factorizations)"
             for m in ("mixed", "ooc") if getattr(stats, m)]
    if stats.iterative:
        part = f"amg for {stats.iterative} of {stats.count} matrices"
        if stats.iterations:
            part += (f", block CG {stats.iterations} iterations, at most {stats.iterations_max} per solve; relative "
                     f"residual {stats.iterative_residual:.0e}, asked {stats.iterative_tol:.0e}")
        if stats.eigen_iterations:
            part += f", LOBPCG {stats.eigen_iterations} iterations (eigenpair residual {stats.eigen_residual:.0e})"
        parts.append(part)
    if stats.refined_solves:
        parts.append(f"at most {stats.refine_max_steps} refinement steps per solve "
                     f"({stats.refined_solves} solves), residual {stats.refine_residual:.0e}")
    return ", ".join(parts)


def matrix_bytes(A) -> int:
    """Bytes of a sparse matrix in compressed storage (values, indices, pointers)."""
    return int(A.data.nbytes + A.indices.nbytes + A.indptr.nbytes)


def pardiso_estimates(iparm: np.ndarray, A, stored: int) -> dict:
    """Bytes each memory mode of PARDISO needs, from ``iparm`` after a double-precision analysis.

    ``double``: the in-core peak ``max(iparm[14], iparm[15] + iparm[16])`` KB. ``mixed``: the
    same with the factor part ``iparm[16]`` halved, plus the single-precision copy of the
    ``stored`` matrix values PARDISO then reads, plus a copy of ``A`` for the residuals only when ``A``
    is not already a CSR matrix in double precision (otherwise the residuals use the
    caller's matrix, which is in memory already). ``ooc``: the permanent data ``iparm[15]``
    plus the minimum out-of-core memory ``iparm[62]`` KB (or :data:`OOC_MIN_SHARE` of
    ``iparm[16]`` when MKL reports none).
    """
    peak, perm, factor = (int(iparm[i]) for i in (14, 15, 16))
    ooc_min = int(iparm[62]) or OOC_MIN_SHARE * factor
    cplx = np.iscomplexobj(A.data)
    single_values = stored * (8 if cplx else 4)
    copied = not (A.format == "csr" and A.dtype == (np.complex128 if cplx else np.float64))
    return {"double": 1024.0 * max(peak, perm + factor),
            "mixed": 1024.0 * max(peak, perm + factor / 2) + single_values + (matrix_bytes(A) if copied else 0),
            "ooc": 1024.0 * (perm + ooc_min)}


def estimate_memory(A, backend: str) -> float | None:
    """Heuristic bytes for factorizing ``A`` with a backend that reports nothing beforehand.

    For SuperLU (``scipy``) an empirical fit to the fill of 3D solid FE matrices measured in
    ``bench/solvers.py`` (0.52 GB at 27k DOF, 3.7 GB at 94.5k DOF, nested-dissection-free
    minimum-degree ordering): ``3.7 GB * (n / 94500)**1.6 * (nnz / n / 73.5)``; it overestimates
    shells and 2D meshes, whose fill grows more slowly. None for other backends.
    """
    if backend != "scipy":
        return None
    n = A.shape[0]
    per_row = max(A.nnz / max(n, 1) / 73.5, 0.1)
    itemsize = 2.0 if np.iscomplexobj(A.data) else 1.0
    return 3.7e9 * (n / 94500.0) ** 1.6 * per_row * itemsize


def refine(A, low_solve, b: np.ndarray, *, anorm: float, tol: float = REFINE_TOL,
           max_iter: int = REFINE_MAX_ITER) -> tuple[np.ndarray, int, float]:
    """Solve ``A x = b`` in double precision with a low-precision factorization (GMRES-based refinement).

    Restarted flexible GMRES (FGMRES) in double precision on ``A M^-1 u = b``, ``x = M^-1 u``,
    with the single-precision factor ``M ~ A`` as the right preconditioner: each cycle starts
    from the residual ``r = b - A x`` computed in double precision, builds a Krylov space of at
    most :data:`REFINE_RESTART` vectors and adds the correction minimizing ``||r - A d||``.
    Stationary refinement ``x += M^-1 (b - A x)`` contracts by ``rho ~ eps_single * cond(A)``
    per step and diverges for ``rho > 1``; GMRES also converges then, as long as the
    preconditioned operator ``A M^-1 = I - E M^-1`` (``E = M - A``) has few eigenvalues away
    from 1 (GMRES-IR: E. Carson, N. J. Higham, SIAM J. Sci. Comput. 39(6), 2017; 40(2), 2018;
    with FGMRES, whose Arnoldi relation ``A Z = V H`` holds in double precision whatever the
    rounding of the single-precision solves ``Z = M^-1 V``: M. Arioli, I. S. Duff, ETNA 33, 2009).

    The columns of ``b`` run in lock step: each has its own Krylov space and Hessenberg matrix,
    but the preconditioner is applied to all columns still iterating as one block solve (one
    step); a column stops when its normwise backward error
    ``eta = ||b - A x|| / (||A|| ||x|| + ||b||)`` reaches :data:`BACKWARD_TARGET`, or when a
    whole cycle did not halve it (the rounding level of its residual). Memory: ``n x k``
    double-precision Krylov vectors and as many single-precision ``M^-1 V`` per step.

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
        The matrix in double precision (both triangles).
    low_solve : callable
        ``low_solve(v) -> z`` with ``M z = v`` from the single-precision factor; ``v`` (n, k) of
        unit-norm columns, so that single precision neither overflows nor underflows.
    b : ndarray, shape (n, k)
        Right-hand sides.
    anorm : float
        ``sqrt(||A||_1 ||A||_inf)`` (:func:`norm_bound`).
    tol : float
        Largest backward error of a column.
    max_iter : int
        Most steps (block solves with the low-precision factor).

    Returns
    -------
    x : ndarray, shape (n, k)
    steps : int
        Block solves with the low-precision factor.
    residual : float
        The largest backward error of a column.

    Raises
    ------
    SolverError
        The backward error stays above ``tol``: the matrix is too ill-conditioned for a
        single-precision factor.

    Notes
    -----
    The measure: ``||A|| = sqrt(||A||_1 ||A||_inf)`` (:func:`norm_bound`), an upper bound of
    ``||A||_2`` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM, 2002,
    sec. 6.3) within a factor ~1.5 of it on FE matrices, computed in one pass over ``A``. With
    ``||A||_F``, which grows like ``sqrt(n) ||A||_2``, the level of a double-precision solve
    would fall with the size of the model (measured on the cantilever: ``eps / 30`` at 3,000 DOF,
    ``eps / 100`` at 94,500) and no fixed multiple of ``eps`` would mark it.

    The target :data:`BACKWARD_TARGET` ``= eps = 2u`` (``u = 2^-53`` the unit roundoff): a
    backward-stable double-precision solve (Cholesky, LDL^T, LU with small growth) gives
    ``(A + dA) x = b`` with ``||dA||_2 <= c u ||A||_2``, ``c`` of order one in practice (Higham,
    ch. 9-10; by Rigal and Gaches, sec. 7.1, ``eta`` is the smallest such relative
    perturbation); PARDISO's solves of the cantilever's ``K`` measure ``c = 1.2-2.2`` at
    3,000-94,500 DOF, ``eta = 0.8-1.6 u`` in this measure. At ``eta <= 2u`` the forward error
    ``<~ cond(A) eta`` is that of the double solve. The target is attainable: ``x`` is stored
    with relative error ``u`` (``eta ~ u / 2``) and the residual computed with the error
    ``gamma_{p+1} (|A| |x| + |b|)`` at most (``p`` nonzeros in a row), of norm ``~ u || |A| |x| || /
    sqrt(p)`` for independent roundings, both below the target. A column whose rounding
    level is higher stops at it by the stall test and is judged by ``tol``. Going further, as
    the stationary refinement did down to the rounding of its corrections, buys nothing but
    solves.
    """
    n, k = b.shape
    dtype = np.result_type(b.dtype, A.dtype)
    bnorm = np.linalg.norm(b, axis=0)
    x = np.zeros((n, k), dtype=dtype)
    r = b.astype(dtype, copy=True)
    eta = np.where(bnorm > 0, 1.0, 0.0)
    active = bnorm > 0
    steps = 0
    while steps < max_iter and np.any(active):
        cols = np.flatnonzero(active)
        before = eta[cols]
        d, used = _fgmres_cycle(A, low_solve, r[:, cols], x[:, cols], bnorm[cols], anorm,
                                min(REFINE_RESTART, max_iter - steps))
        x[:, cols] += d
        steps += used
        r[:, cols] = b[:, cols] - sparse_dense(A, x[:, cols])
        eta[cols] = _backward(r[:, cols], x[:, cols], bnorm[cols], anorm)
        active[cols] = (eta[cols] > BACKWARD_TARGET) & (eta[cols] <= 0.5 * before)
    worst = float(np.max(eta, initial=0.0))
    if np.isfinite(worst) and worst <= tol:
        return x, steps, worst
    raise SolverError(
        f"the mixed-precision solve did not converge (backward error {worst:.1e} after {steps} single-precision "
        f"solves, target {tol:.0e}): the matrix is too ill-conditioned for a single-precision factor; "
        "set factor_memory to 'ooc' (out of core: exact in double precision) or 'double'",
        params=("factor_memory",))


def norm_bound(A) -> float:
    """``sqrt(||A||_1 ||A||_inf)``, an upper bound of ``||A||_2`` (the norm of :func:`refine`'s
    backward errors), from a sparse matrix in compressed storage in one pass over its values."""
    a = np.abs(A.data)
    sums = np.bincount(A.indices, weights=a, minlength=max(A.shape))
    lines = np.add.reduceat(a, A.indptr[:-1][np.diff(A.indptr) > 0]) if a.size else np.zeros(1)
    return float(np.sqrt(np.max(sums, initial=0.0) * np.max(lines, initial=0.0)))


def check_solve(A, solve) -> tuple[float, float]:
    """One solve with a random right-hand side ``b`` (``solve`` takes (n, 1)): its relative residual
    ``||A x - b|| / ||b||`` and normwise backward error ``||A x - b|| / (a ||x|| + ||b||)``, with
    ``a = ||A b|| / ||b||`` at most ``||A||`` (the error over- rather than underestimated, at the cost of
    two products with ``A`` and no copy of it)."""
    b = np.random.default_rng(0).standard_normal((A.shape[0], 1))
    x = solve(b)
    r = A @ x - b
    nb = np.linalg.norm(b, axis=0)
    eta = float(_backward(r, x, nb, float(np.linalg.norm(A @ b) / nb[0]))[0])
    return float(np.linalg.norm(r) / nb[0]), eta


def _backward(r, x, bnorm, anorm):
    """Normwise backward errors ``||r|| / (||A|| ||x|| + ||b||)`` of the columns."""
    denom = anorm * np.linalg.norm(x, axis=0) + bnorm
    return np.linalg.norm(r, axis=0) / np.where(denom > 0, denom, 1.0)


def _fgmres_cycle(A, low_solve, r, x0, bnorm, anorm, m):
    """One FGMRES cycle of at most ``m`` steps on ``A d = r`` per column, in lock step.

    Returns the corrections ``d`` (n, k) and the number of steps (block solves). A column
    stops when GMRES' residual ``||r - A d||`` (from its Hessenberg matrix) meets
    :data:`BACKWARD_TARGET` for ``x0 + d``, or at a breakdown (its Krylov space is invariant).
    """
    n, k = r.shape
    dtype = r.dtype
    beta = np.linalg.norm(r, axis=0)
    V = [r / beta]
    Z = []
    H = np.zeros((k, m + 1, m), dtype=dtype)
    y = np.zeros((k, m), dtype=dtype)
    znorm = np.zeros((m, k))
    x0norm = np.linalg.norm(x0, axis=0)
    live = np.ones(k, dtype=bool)
    for j in range(m):
        cols = np.flatnonzero(live)
        every = cols.size == k  # no copies while no column has stopped
        z = np.asarray(low_solve(V[j] if every else V[j][:, cols]))  # one block solve
        if every:
            Z.append(z)
        else:
            Z.append(np.zeros((n, k), dtype=z.dtype))
            Z[j][:, cols] = z
        w = np.asarray(sparse_dense(A, z), dtype=dtype)  # in double precision
        for i in range(j + 1):  # modified Gram-Schmidt, column by column
            vi = V[i] if every else V[i][:, cols]
            h = np.einsum("nk,nk->k", vi.conj(), w)
            w -= vi * h
            H[cols, i, j] = h
        hn = np.linalg.norm(w, axis=0)
        H[cols, j + 1, j] = hn
        V.append(np.zeros((n, k), dtype=dtype))
        V[j + 1][:, cols] = w / np.where(hn > 0, hn, 1.0)
        znorm[j, cols] = np.linalg.norm(z, axis=0)
        res = np.empty(cols.size)
        for c, col in enumerate(cols):  # min ||beta e1 - H y||, per column
            Hc = H[col, :j + 2, :j + 1]
            e1 = np.zeros(j + 2, dtype=dtype)
            e1[0] = beta[col]
            y[col, :j + 1] = np.linalg.lstsq(Hc, e1, rcond=None)[0]
            res[c] = np.linalg.norm(e1 - Hc @ y[col, :j + 1])
        # ||x0 + Z y|| <= ||x0|| + sum |y_i| ||z_i||: only the columns that may have met the
        # target with this bound need the exact norm
        bound = x0norm[cols] + np.einsum("ik,ki->k", znorm[:j + 1, cols], np.abs(y[cols, :j + 1]))
        done = (hn == 0) | ~np.isfinite(res)
        maybe = np.flatnonzero(~done & (res <= BACKWARD_TARGET * (anorm * bound + bnorm[cols])))
        for c in maybe:
            col = cols[c]
            xn = np.linalg.norm(x0[:, col] + sum(Z[i][:, col] * y[col, i] for i in range(j + 1)))
            done[c] = res[c] <= BACKWARD_TARGET * (anorm * xn + bnorm[col])
        live[cols[done]] = False
        if not live.any():
            break
    d = np.zeros((n, k), dtype=dtype)
    for i, Zi in enumerate(Z):  # the stopped columns' later coefficients are zero
        d += Zi * y[:, i]
    return d, len(Z)


def _remove(path: str) -> None:
    shutil.rmtree(path, ignore_errors=True)


class OutOfCore:
    """The temporary directory and settings of one out-of-core PARDISO factorization.

    MKL reads ``MKL_PARDISO_OOC_PATH`` (a directory) and ``MKL_PARDISO_OOC_MAX_CORE_SIZE``
    (MB of memory for the factor and its work arrays) from the environment in the numerical
    factorization (phase 22; measured with MKL 2026: not at the analysis, not at the solves),
    so :meth:`environment` sets them around that phase only and each factorization writes
    its files into a directory of its own. :meth:`remove` deletes the directory (after
    PARDISO's phase -1); it is also removed when this object is collected or at exit.

    Parameters
    ----------
    core_bytes : float
        Memory MKL may keep in core.
    scratch_dir : str or Path, optional
        Where the temporary directory is made (None: ``$TMPDIR`` / the system's default).

    Raises
    ------
    SolverError
        The directory cannot be made there.
    """

    def __init__(self, core_bytes: float, scratch_dir=None):
        self.core_mb = max(int(core_bytes // 2**20), 1)
        try:
            self.path = tempfile.mkdtemp(prefix="flexmor-ooc-", dir=None if scratch_dir is None else str(scratch_dir))
        except OSError as exc:
            raise SolverError(f"cannot make the directory of the out-of-core factor in {scratch_dir or '$TMPDIR'}: "
                              f"{exc.strerror or exc}") from None
        self._finalizer = weakref.finalize(self, _remove, self.path)
        log.info("out-of-core factor files in %s, %d MB in core", self.path, self.core_mb)

    @contextmanager
    def environment(self):
        """The OOC environment variables set for the ``with`` block (and restored afterwards)."""
        values = {"MKL_PARDISO_OOC_PATH": self.path, "MKL_PARDISO_OOC_MAX_CORE_SIZE": str(self.core_mb)}
        saved = {k: os.environ.get(k) for k in values}
        os.environ.update(values)
        try:
            yield
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v

    def verify(self, A, solve) -> float:
        """Check the factor by one solve with a random right-hand side (``solve`` takes (n, 1)); the
        normwise backward error of that solve, ``||A x - b|| / (a ||x|| + ||b||)`` with
        ``a = ||A b|| / ||b||`` (at most ``||A||``: over- rather than underestimated).

        With little memory in core, MKL may return a wrong out-of-core factor without an error
        (seen once, otherwise its error -9), or a slightly inaccurate one (a check's relative residual
        of 5.9e-6 on the CalculiX beam, one run in four of the memory-mode tests), so each one is checked,
        whatever ``check`` says; the caller refines the solves of a factor whose backward error is above
        its bound, which converges in a few steps where the residual is small (:data:`OOC_CHECK_TOL`).

        Raises
        ------
        SolverError
            The relative residual exceeds :data:`OOC_CHECK_TOL`.
        """
        res, eta = check_solve(A, solve)
        if not res <= OOC_CHECK_TOL:
            raise SolverError(f"the out-of-core factorization failed its check (relative residual {res:.1e}) with "
                              f"{self.core_mb} MB in core: give it more memory (memory_limit), or the matrix is "
                              "singular", params=("memory_limit",))
        return eta

    def remove(self) -> None:
        """Delete the directory and the factor files in it."""
        self._finalizer()
