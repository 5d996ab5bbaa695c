"""Factorizations that fit into memory: the memory modes behind :func:`flexmor.linalg.factorize`.

A sparse direct factorization whose double-precision factor does not fit into the memory of
the machine can still be computed on it, in one of three modes
(``SolverContext(factor_memory=...)``, ``--factor-memory``):

``double``
    The factor in double precision, in memory (the fastest; refused when it does not fit).
``mixed``
    The factor in single precision (``float32`` / ``complex64``: half the memory of the
    factor; PARDISO ``iparm[27] = 1`` or SciPy's SuperLU), each solve refined in double
    precision against the double matrix, ``x += F32.solve(b - A x)``, until the corrections
    reach the rounding level of double precision (as accurate as a double factor's solution)
    and the normwise backward error ``||b - A x|| / (||A||_F ||x|| + ||b||)`` of every column
    is at most ``refine_tol`` (:func:`refine`). Converges while ``eps_single * cond(A) < 1``;
    an ill-conditioned matrix is refused with a :class:`~flexmor.errors.SolverError` that
    suggests the out-of-core mode.
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
:class:`~flexmor.linalg.backends.SolverStats` (summarized by :func:`factor_record`).
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

from ..errors import SolverError

__all__ = ["FACTOR_MEMORY", "MEMORY_FRACTION", "MODE_NAMES", "REFINE_MAX_ITER", "REFINE_TOL", "MemoryPlan",
           "OutOfCore", "describe_factor", "estimate_memory", "factor_record", "matrix_bytes", "pardiso_estimates",
           "plan_memory", "refine", "refusal"]

log = logging.getLogger(__name__)

#: Choices of ``SolverContext(factor_memory=...)``.
FACTOR_MEMORY = ("auto", "double", "mixed", "ooc")

#: How the modes are named in logs, messages and reports.
MODE_NAMES = {"double": "double precision in core", "mixed": "mixed precision", "ooc": "out of core"}

#: Refuse a factorization whose estimate exceeds this share of the available memory.
MEMORY_FRACTION = 0.9

#: Default backward error of the refined solves of the mixed mode.
REFINE_TOL = 1e-12

#: Most refinement steps of one solve in the mixed mode.
REFINE_MAX_ITER = 30

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


def _mb(x) -> str:
    return f"{x / 2**20:.0f} MB"


def refusal(n: int, backend: str, estimates: dict, available: float, others=()) -> SolverError:
    """The error of a factorization of ``n`` equations that fits in no mode into ``available`` bytes."""
    alt = [f"in mixed precision {_mb(estimates['mixed'])}"] if estimates.get("mixed") is not None else []
    alt += [f"out of core at least {_mb(estimates['ooc'])}"] if estimates.get("ooc") is not None else []
    hint = (f"try another backend ({', '.join(others)}), " if others else "") + \
        "a distributed backend on a machine with more memory, or a smaller model"
    return SolverError(
        f"factorizing {n} equations with {backend} needs about {_mb(estimates['double'])}"
        + "".join([" in double precision"] + [f", {a}" for a in alt] if alt else [])
        + f", but only {_mb(available)} of memory are available; {hint}")


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
    return {"double": stats.count - stats.mixed - stats.ooc, "mixed": stats.mixed, "ooc": stats.ooc,
            "refined_solves": stats.refined_solves, "refine_steps": stats.refine_steps,
            "refine_max_steps": stats.refine_max_steps,
            "refine_residual": stats.refine_residual if stats.refined_solves else None,
            "reason": stats.factor_reason or None}


def describe_factor(stats) -> str:
    """One line on the factorizations of ``stats`` not in double precision in core ("" when all were)."""
    parts = [f"{MODE_NAMES[m]} ({getattr(stats, m)} of {stats.count} factorizations)"
             for m in ("mixed", "ooc") if getattr(stats, m)]
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
    """Solve ``A x = b`` in double precision with a low-precision factorization (iterative refinement).

    ``x += low_solve(b - A x)`` with the residual in double precision, until the corrections
    reach the rounding level of double precision (the next one, the last times the
    contraction per step, below it; or the contraction fading: less than half, or 8 times
    weaker than the best step), where
    ``x`` is as accurate as a double-precision factorization's solution; then the normwise
    backward error ``||b - A x|| / (||A||_F ||x|| + ||b||)`` of every column must be at most
    ``tol``.

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
        The matrix in double precision (both triangles).
    low_solve : callable
        ``low_solve(r) -> d`` with ``A d ~ r`` from the single-precision factor; ``r`` (n, k) of
        unit-norm columns, so that single precision neither overflows nor underflows.
    b : ndarray, shape (n, k)
        Right-hand sides.
    anorm : float
        ``||A||_F``.
    tol : float
        Largest backward error of a column.
    max_iter : int
        Most refinement steps.

    Returns
    -------
    x : ndarray, shape (n, k)
    steps : int
        Solves with the low-precision factor.
    residual : float
        The largest backward error of a column.

    Raises
    ------
    SolverError
        The backward error stays above ``tol``: the matrix is too ill-conditioned for a
        single-precision factor (``eps_single * cond(A)`` not small).

    References
    ----------
    N. J. Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM, 2002, ch. 12.
    """
    bnorm = np.linalg.norm(b, axis=0)
    x = np.zeros(b.shape, dtype=np.result_type(b.dtype, A.dtype))
    r = b.astype(x.dtype, copy=True)
    last, best = np.inf, 1.0
    steps = 0
    while steps < max_iter:
        scale = np.linalg.norm(r, axis=0)
        scale[scale == 0] = 1.0
        d = np.asarray(low_solve(r / scale), dtype=x.dtype) * scale
        x += d
        r = b - A @ x
        steps += 1
        xnorm = np.linalg.norm(x, axis=0)
        change = float(np.max(np.linalg.norm(d, axis=0) / np.where(xnorm > 0, xnorm, 1.0), initial=0.0))
        ratio = change / last if steps > 1 else 1.0
        # done at the rounding level: the next correction (this one times the contraction) is
        # below double precision's, or the contraction fades (the corrections are rounding noise)
        if not np.isfinite(change) or change * ratio <= _ROUNDING or (steps > 1 and ratio > min(0.5, 8 * best)):
            break
        last, best = change, min(best, ratio)
    denom = anorm * np.linalg.norm(x, axis=0) + bnorm
    worst = float(np.max(np.linalg.norm(r, axis=0) / np.where(denom > 0, denom, 1.0), initial=0.0))
    if np.isfinite(worst) and worst <= tol:
        return x, steps, worst
    raise SolverError(
        f"the mixed-precision solve did not converge (backward error {worst:.1e} after {steps} refinement steps, "
        f"target {tol:.0e}): the matrix is too ill-conditioned for a single-precision factor; "
        "set factor_memory to 'ooc' (out of core: exact in double precision) or 'double'",
        params=("factor_memory",))


#: Relative correction at the rounding level of double precision.
_ROUNDING = 4 * np.finfo(float).eps


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

    def verify(self, A, solve) -> None:
        """Check the factor by one solve with a random right-hand side (``solve`` takes (n, 1)).

        With little memory in core, MKL may return a wrong out-of-core factor without an error
        (seen once, otherwise its error -9), so each one is checked, whatever ``check`` says.

        Raises
        ------
        SolverError
            The relative residual exceeds 1e-6 (the bound of ``factorize(check=True)``).
        """
        b = np.random.default_rng(0).standard_normal((A.shape[0], 1))
        res = float(np.linalg.norm(A @ solve(b) - b) / np.linalg.norm(b))
        if not res <= 1e-6:
            raise SolverError(f"the out-of-core factorization failed its check (relative residual {res:.1e}) with "
                              f"{self.core_mb} MB in core: give it more memory (memory_limit), or the matrix is "
                              "singular", params=("memory_limit",))

    def remove(self) -> None:
        """Delete the directory and the factor files in it."""
        self._finalizer()
