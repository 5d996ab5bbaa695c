"""What a factorization will cost per backend and memory mode, without factorizing: the solver side of the plan.

For the matrix ``A`` of a model (``K - sigma M`` with a negative shift: real, symmetric, positive
definite, the matrix of the eigen solves and of Krylov's real points) each backend of
:data:`flexmor.linalg.backends.BACKENDS` that has an estimator in :data:`ESTIMATORS` gives a
:class:`BackendEstimate`: per memory mode (double, mixed, ooc, :mod:`flexmor.linalg.memory`) the bytes of
the factorization, the seconds of one factorization and the seconds per solved right-hand side, for the
real matrix and for a complex one of the same pattern (``K - w^2 M + i w D``).

Memory is the estimate the real run plans its memory mode with: PARDISO's analysis phase
(:meth:`flexmor.linalg.pardiso.PardisoFactorization.analysis`, :func:`~flexmor.linalg.memory.pardiso_estimates`)
or the SuperLU heuristic (:func:`~flexmor.linalg.memory.estimate_memory`), so :func:`auto_choice`, which calls
the functions a factorization calls (:meth:`~flexmor.linalg.context.SolverContext.pick`,
:func:`~flexmor.linalg.memory.plan_memory`), says what ``auto`` will take.

Time comes from the work of the factorization and a machine rate measured now (:func:`calibrate`): the
backend factorizes the leading ``CALIBRATION_ROWS`` x ``CALIBRATION_ROWS`` block of ``A`` itself (the same
elements, numbering and coupling as the model, a fraction of its work) and solves a block of right-hand
sides with it. The work is PARDISO's own count of floating-point operations (``iparm[18]``) and factor
nonzeros (``iparm[17]``); for SuperLU, which reports nothing beforehand, the fill of the calibration block is
measured and scaled to the model by the heuristic's growth law, and the work taken as ``fill^2 / n`` (the
operations of a factor with ``fill / n`` entries per column). A solve costs a pass over the factor per
right-hand side. A complex matrix of the same pattern: twice the factor's bytes, the times of
:data:`COMPLEX_FACTOR` (PARDISO: :data:`PARDISO_COMPLEX_FACTOR`).

PARDISO's rate grows with the work of the factorization: its dense fronts grow with the matrix, and MKL's
dense kernels run faster on larger ones. On the clamped cantilever of 94,500 DOF (one thread), the numerical
phase of the leading 8,000, 16,000, 32,000 and 64,000 rows and of the whole matrix ran at 11, 16, 23, 32 and
37 Gflop/s for 9e7, 5.5e8, 3.4e9, 2.1e10 and 5.7e10 operations (rate ~ operations^0.13-0.21 between
neighbours; the blocks of the 36,300- and 8,820-DOF models lie on the same curve): the rate of the 8,000-row
block alone puts that factorization at 2.2-2.4x its time. :func:`_pardiso_estimate` therefore factorizes a
second leading block of :data:`CALIBRATION_SCALE` times the rows (at most a third of ``A``'s: 6% of the
whole's operations at 94,500 DOF), fits ``rate = c * operations^a`` through the two blocks (``a`` clamped to
:data:`RATE_EXPONENT`) and takes it at the model's operations, at most the rate of a dense matrix product
(:func:`dense_rate`), which no factorization's fronts exceed. Each block's rate is its operations over the
seconds of its numerical phase alone (:attr:`PardisoFactorization.numeric_seconds`): the best of three
factorizations of the small block (its milliseconds are the most disturbed by other work on the machine, and
a slow small block steepens the fit, giving too short a time), one of the large block. The analysis of the
model is timed itself. A solved column costs the larger block's seconds per factor entry times the model's
factor entries (0.53 ns per entry at 8,000 rows, 0.41 at 32,000, 0.38 for the whole 94,500-DOF model).

SuperLU's rate, with the work taken as ``fill^2 / n``, grows too (6.5 "Gflop/s" on the leading 8,000 rows of
the 36,300-DOF cantilever, 11 on the whole), but the heuristic scales the block's fill by 14.6x where it grows
by 20x, so the work is underestimated by about as much: its estimates came out at 0.8-1.3x of the run
(bench/README.md), and it keeps one block.

A backend contributes its row through one function in :data:`ESTIMATORS`::

    estimate(A, *, positive: bool, rows: int) -> BackendEstimate

``A`` the real matrix (CSR, both triangles), ``positive`` whether it is positive definite, ``rows`` the size
of the calibration block. It may factorize that block, never ``A``. The ``amg`` backend's estimator also takes
``near_null``, the model's rigid motions, and sets up and solves the block instead of factorizing it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..errors import OptionError, OutOfMemoryError, SolverError
from .backends import BACKENDS
from .context import SolverContext
from .memory import MODE_NAMES, estimate_memory, matrix_bytes, pardiso_estimates, plan_memory
from .resources import MEMORY_FRACTION

__all__ = ["CALIBRATION_ROWS", "CALIBRATION_COLUMNS", "CALIBRATION_SCALE", "CALIBRATION_SOLVES", "COMPLEX_FACTOR",
           "DENSE_ORDER", "ESTIMATORS", "MIXED_SOLVE_FACTOR", "OOC_FACTOR", "PARDISO_COMPLEX_FACTOR", "RATE_EXPONENT",
           "REUSED_ANALYSIS", "ModeEstimate", "BackendEstimate", "estimate_backends", "auto_choice", "calibrate",
           "dense_rate"]

#: Rows of the leading block of ``A`` that a backend factorizes to measure the machine's rate.
CALIBRATION_ROWS = 8000

#: Right-hand sides of the calibration's block solve.
CALIBRATION_COLUMNS = 8

#: Block solves the calibration times, keeping the shortest: the first after a factorization took up to 1.6x
#: the time of the third (PARDISO, 12,100 rows of the 36,300-DOF cantilever: 1.15, 0.92, 0.75 ms per column).
CALIBRATION_SOLVES = 3

#: PARDISO's second calibration block has this many times the rows of the first, at most a third of the
#: matrix's (at 94,500 DOF its 31,500 rows: 0.14 s of numerical factorization and 80 MB of factor, against
#: 1.5 s and 470 MB for the whole matrix).
CALIBRATION_SCALE = 4

#: Bounds of the exponent ``a`` of PARDISO's rate ``c * operations^a`` fitted through the two calibration
#: blocks (measured 0.13-0.21 on the cantilever, module docstring): a pair of timings disturbed by other
#: work on the machine neither makes the rate fall with the work nor extrapolates it steeper than this.
RATE_EXPONENT = (0.0, 0.25)

#: Order of the square matrices whose product (:func:`dense_rate`) bounds PARDISO's extrapolated rate.
DENSE_ORDER = 1000

#: A solve of the mixed mode costs this many double-precision solves: its refinement took 7-8
#: single-precision solves and as many products with ``A`` (bench/README.md, ``memory.py``).
MIXED_SOLVE_FACTOR = 8.0

#: A complex matrix of the same pattern against the real one (factorization, solve): 2.3x and 4x, PARDISO
#: in one thread at 27,000 DOF (bench/README.md, ``memory.py``: 4.16 s against 1.79 s, 1.74 s against 0.44 s,
#: whole factorizations); four times the operations, at a higher rate in the factorization.
COMPLEX_FACTOR = (2.3, 4.0)

#: The same for PARDISO's estimates, whose factorization time is the analysis and a numerical phase: only the
#: numerical phase is scaled, and that of a complex symmetric matrix (``K - w^2 M + i w D``, LDL^T) took
#: 3.0-3.2x that of the real positive definite one (Cholesky) on the cantilever, one thread: 0.097 s against
#: 0.031 at 8,820 DOF, 0.91-1.0 s against 0.31 at 36,300, 4.9 s against 1.5 at 94,500 (``numeric_seconds``).
PARDISO_COMPLEX_FACTOR = (3.1, COMPLEX_FACTOR[1])

#: Share of the analysis a factorization pays when the ordering of its pattern is reused: "a quarter to a
#: half" of METIS' own (:class:`flexmor.linalg.factorization.OrderingCache`).
REUSED_ANALYSIS = 0.5

#: Out of core against in core (factorization, solve): 1.1-3.4x and 0.9-1.3x with the factor files in
#: the page cache (bench/README.md, ``memory.py``); a machine that must read them from disk is slower.
OOC_FACTOR = (2.0, 1.5)


@dataclass(frozen=True)
class ModeEstimate:
    """The cost of one factorization in one memory mode.

    Attributes
    ----------
    bytes : float or None
        Peak bytes of the factorization and its factor (None: not known).
    factor_seconds : float or None
        Seconds of one factorization (analysis included).
    column_seconds : float or None
        Seconds per right-hand side solved with the factor.
    analysis_seconds : float
        The part of ``factor_seconds`` spent ordering the pattern, of which a later factorization of the
        same pattern pays :data:`REUSED_ANALYSIS` (its ordering reused).
    """

    bytes: float | None
    factor_seconds: float | None
    column_seconds: float | None
    analysis_seconds: float = 0.0


@dataclass(frozen=True)
class BackendEstimate:
    """What factorizing ``A`` would cost with one backend.

    Attributes
    ----------
    backend : str
        Its name in :data:`~flexmor.linalg.backends.BACKENDS`.
    available : bool
        It works on this machine.
    real, complex : dict
        Memory mode -> :class:`ModeEstimate` for the real matrix and for a complex one of its pattern
        (empty: no estimate; a mode missing: the backend lacks it).
    source : str
        Where the estimates come from (the analysis, a heuristic, the calibration), or why there are none.
    flops : float or None
        Floating-point operations of the real factorization.
    factor_nonzeros : float or None
        Entries of the real factor.
    calibration : dict
        What the calibration measured (rows, seconds, rate; PARDISO: ``blocks``, each block's rows, operations,
        seconds and rate, ``exponent`` of the fit through them and ``dense_flops_per_second``, its bound).
    """

    backend: str
    available: bool
    real: dict = field(default_factory=dict)
    complex: dict = field(default_factory=dict)
    source: str = ""
    flops: float | None = None
    factor_nonzeros: float | None = None
    calibration: dict = field(default_factory=dict)

    def memory_estimates(self, is_complex: bool) -> dict:
        """``double``/``mixed``/``ooc`` -> bytes (None where the backend lacks the mode), as
        :func:`~flexmor.linalg.memory.plan_memory` takes them."""
        modes = self.complex if is_complex else self.real
        return {m: (modes[m].bytes if m in modes else None) for m in MODE_NAMES}


def _modes(double: float, mixed: float, ooc: float | None, factor_s: float, column_s: float,
           analysis_s: float = 0.0) -> dict:
    """The :class:`ModeEstimate` of each mode from the double-precision times and each mode's bytes."""
    out = {"double": ModeEstimate(double, factor_s, column_s, analysis_s),
           "mixed": ModeEstimate(mixed, factor_s, column_s * MIXED_SOLVE_FACTOR, analysis_s)}
    if ooc is not None:
        out["ooc"] = ModeEstimate(ooc, factor_s * OOC_FACTOR[0], column_s * OOC_FACTOR[1], analysis_s)
    return out


def _as_complex(modes: dict, A, factor: tuple[float, float] = COMPLEX_FACTOR) -> dict:
    """The estimates for a complex matrix of ``A``'s pattern: the factor's bytes doubled (its values; the
    matrix kept beside it too), the times but the analysis' scaled by ``factor`` (factorization, solve)."""
    extra = float(A.data.nbytes)
    return {m: ModeEstimate(None if e.bytes is None else 2.0 * e.bytes + extra,
                            None if e.factor_seconds is None else
                            e.analysis_seconds + factor[0] * (e.factor_seconds - e.analysis_seconds),
                            None if e.column_seconds is None else factor[1] * e.column_seconds,
                            e.analysis_seconds)
            for m, e in modes.items()}


def _block(A, rows: int):
    """The leading ``rows`` x ``rows`` block of ``A`` (CSR; ``A`` itself when it has no more rows)."""
    m = min(int(rows), A.shape[0])
    return A.tocsr() if m == A.shape[0] else A[:m][:, :m].tocsr()


def _timed_factor_in(solver: SolverContext, B, positive: bool):
    """``(factorization, seconds)`` of ``B`` in ``solver`` (the path of a real run)."""
    from .factorize import factorize

    F = factorize(B, solver=solver, positive=positive, check=False)
    return F, F.seconds


def _column_seconds(F, n: int) -> float:
    """Seconds per right-hand side of a block solve of :data:`CALIBRATION_COLUMNS` columns with ``F``."""
    b = np.random.default_rng(0).standard_normal((n, CALIBRATION_COLUMNS))
    t0 = time.perf_counter()
    F.solve(b)
    return (time.perf_counter() - t0) / CALIBRATION_COLUMNS


def calibrate(backend: str, A, *, positive: bool, rows: int = CALIBRATION_ROWS, repeats: int = 2) -> dict:
    """Factorize the leading ``rows`` x ``rows`` block of ``A`` with ``backend`` ``repeats`` times and solve a
    block with it :data:`CALIBRATION_SOLVES` times, keeping the shortest times (a machine busy with other work
    slows one of them).
    The factorizations are made in one :class:`SolverContext`, so that PARDISO's later ones reuse the
    ordering of the first, as a run's later factorizations do.

    Returns ``rows``, ``block`` (the block), ``factorization`` (to read its fill), ``factor_seconds``,
    ``numeric_seconds`` (PARDISO: of the numerical phase alone, :attr:`PardisoFactorization.numeric_seconds`;
    else as ``factor_seconds``), ``column_seconds`` and ``solver`` (the context, with its orderings).
    """
    B = _block(A, rows)
    solver = SolverContext(backend=backend, factor_memory="double")
    runs = [_timed_factor_in(solver, B, positive) for _ in range(max(int(repeats), 1))]
    F = runs[-1][0]
    out = {"rows": B.shape[0], "block": B, "factorization": F, "solver": solver,
           "factor_seconds": min(seconds for _, seconds in runs),
           "numeric_seconds": min(getattr(G, "numeric_seconds", seconds) for G, seconds in runs),
           "column_seconds": min(_column_seconds(F, B.shape[0]) for _ in range(CALIBRATION_SOLVES))}
    del runs
    return out


def dense_rate(order: int = DENSE_ORDER) -> float:
    """Floating-point operations per second of the product of two dense square matrices of ``order`` (numpy's
    BLAS, the better of two), the upper bound of a sparse factorization's rate: its work is dense updates of
    its fronts, at best at the rate of a matrix product (on one core of the machine of bench/README.md numpy's
    product ran at 60-70 Gflop/s at order 1000, MKL's ``dgemm`` at 77-81, PARDISO's factorization of the
    94,500-DOF cantilever at 37).
    """
    a = np.random.default_rng(0).standard_normal((order, order))
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        a @ a
        best = min(best, time.perf_counter() - t0)
    return 2.0 * order**3 / max(best, 1e-9)


def _rate_at(points: list[tuple[float, float]], flops: float, peak: float) -> tuple[float, float]:
    """``(rate, a)``: operations per second of a factorization of ``flops`` operations on the line
    ``rate = c * operations^a`` through the first and last ``(operations, rate)`` of ``points`` (``a`` clamped to
    :data:`RATE_EXPONENT`, 0 for one point), at most ``peak`` (never below the measured rates)."""
    (f1, r1), (f2, r2) = points[0], points[-1]
    a = float(np.clip(np.log(r2 / r1) / np.log(f2 / f1), *RATE_EXPONENT)) if f2 > f1 else 0.0
    return min(r2 * (flops / f2) ** a, max(peak, r2)), a


def _pardiso_block(A, *, positive: bool, rows: int, repeats: int = 2) -> dict:
    """:func:`calibrate` of PARDISO on the leading ``rows`` rows, with the block's operations and factor entries
    from its analysis (the ordering of the calibration's factorizations reused) and ``flops_per_second``: the
    operations over the seconds of the numerical phase."""
    from .pardiso import PardisoFactorization

    cal = calibrate("pardiso", A, positive=positive, rows=rows, repeats=repeats)
    ip = PardisoFactorization.analysis(cal["block"], cal["solver"], positive=positive)
    flops, fill = 1e6 * max(float(ip[18]), 1.0), max(float(ip[17]), 1.0)
    return {**cal, "flops": flops, "fill": fill, "flops_per_second": flops / max(cal["numeric_seconds"], 1e-6)}


def _pardiso_estimate(A, *, positive: bool, rows: int) -> BackendEstimate:
    """PARDISO: memory, operations and factor nonzeros from its analysis of ``A``; the rate at those operations
    from the numerical factorization of two leading blocks, ``rows`` and :data:`CALIBRATION_SCALE` times as
    many rows (at most a third of ``A``'s; one block when that is not more), on ``rate = c * operations^a``
    through them (:func:`_rate_at`, at most :func:`dense_rate`); a factorization costs the analysis of ``A``
    (timed here) and its operations at that rate, a solved column the larger block's seconds per factor entry."""
    from .pardiso import PardisoFactorization

    t0 = time.perf_counter()
    ip = PardisoFactorization.analysis(A, SolverContext(), positive=positive)
    analysis_s = time.perf_counter() - t0
    flops, fill = 1e6 * float(ip[18]), float(ip[17])
    n = A.shape[0]
    first, second = min(rows, n), min(CALIBRATION_SCALE * rows, n // 3)
    blocks = [_pardiso_block(A, positive=positive, rows=first, repeats=3)]
    if second > first:
        blocks.append(_pardiso_block(A, positive=positive, rows=second, repeats=1))
    peak = dense_rate()
    rate, exponent = _rate_at([(b["flops"], b["flops_per_second"]) for b in blocks], flops, peak)
    factor_s = analysis_s + flops / rate
    big = blocks[-1]
    column_s = big["column_seconds"] * fill / big["fill"]
    est = pardiso_estimates(ip, A, (A.nnz + A.shape[0]) // 2)  # the upper triangle PARDISO keeps
    real = _modes(est["double"], est["mixed"], est["ooc"], factor_s, column_s, analysis_s)
    return BackendEstimate("pardiso", True, real, _as_complex(real, A, PARDISO_COMPLEX_FACTOR),
                           "PARDISO analysis (iparm[14:19]); rate "
                           f"from factorizing the leading {' and '.join(str(b['rows']) for b in blocks)} rows",
                           flops, fill,
                           {"rows": big["rows"], "seconds": sum(b["factor_seconds"] for b in blocks),
                            "flops_per_second": rate, "analysis_seconds": analysis_s, "exponent": exponent,
                            "dense_flops_per_second": peak,
                            "blocks": [{k: b[k] for k in ("rows", "flops", "numeric_seconds", "flops_per_second")}
                                       for b in blocks]})


def _scipy_estimate(A, *, positive: bool, rows: int) -> BackendEstimate:
    """SuperLU: memory from :func:`~flexmor.linalg.memory.estimate_memory`; the fill of the calibration block
    measured and scaled to ``A`` by that heuristic, the work ``fill^2 / n``, the rate from the block's
    factorization."""
    cal = calibrate("scipy", A, positive=positive, rows=rows)
    lu = cal["factorization"]._lu
    cal_fill = float(lu.L.nnz + lu.U.nnz)
    n, m = A.shape[0], cal["rows"]
    double, block = float(estimate_memory(A, "scipy") or 0.0), float(estimate_memory(cal["block"], "scipy") or 1.0)
    fill = cal_fill * double / block
    rate = (cal_fill ** 2 / m) / max(cal["factor_seconds"], 1e-6)
    flops = fill ** 2 / n
    real = _modes(double, double / 2 + matrix_bytes(A), None, flops / rate, cal["column_seconds"] * fill / cal_fill)
    return BackendEstimate("scipy", True, real, _as_complex(real, A), "SuperLU heuristic (estimate_memory); "
                           f"fill and rate from factorizing the leading {m} rows", flops, fill,
                           {"rows": m, "seconds": cal["factor_seconds"], "flops_per_second": rate})


def _amg_estimate(A, *, positive: bool, rows: int, near_null=None) -> BackendEstimate:
    """AMG + block CG (:mod:`flexmor.linalg.amg`): the hierarchy of the calibration block set up and
    :data:`CALIBRATION_COLUMNS` columns solved, on the rows' part of ``near_null`` (the model's rigid
    motions); the setup's peak memory (traced) per byte of the block's matrix, and its times per entry,
    scaled to ``A`` (both grow with the entries; the iterations per solve hardly with the size:
    ``bench/amg.py``)."""
    import tracemalloc

    from .amg import NearNull, register_near_null

    B = _block(A, rows)
    ctx = SolverContext(backend="amg")
    if near_null is not None:
        part = NearNull(near_null.B[:B.shape[0]], near_null.block if B.shape[0] % near_null.block == 0 else 1)
        register_near_null(ctx, B.shape[0], lambda: part)
    tracemalloc.start()
    try:
        F, setup_s = _timed_factor_in(ctx, B, positive)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    column_s = _column_seconds(F, B.shape[0])
    scale = A.nnz / max(B.nnz, 1)
    per_byte = peak / max(matrix_bytes(B), 1)
    real = {"double": ModeEstimate(per_byte * matrix_bytes(A), setup_s * scale, column_s * scale)}
    its = ctx.stats.iterations / max(ctx.stats.solves, 1)
    return BackendEstimate("amg", True, real, {}, "hierarchy set up and solved on the leading "
                           f"{B.shape[0]} rows ({its:.0f} block CG iterations; "
                           f"{'rigid motions' if near_null is not None else 'no geometry: the constant'} as "
                           "near-null space), scaled by the entries; real positive definite matrices only",
                           calibration={"rows": B.shape[0], "seconds": setup_s, "iterations": its,
                                        "setup_bytes_per_matrix_byte": per_byte})


#: Backend name -> its estimator ``estimate(A, *, positive, rows) -> BackendEstimate`` (module docstring);
#: a backend of :data:`~flexmor.linalg.backends.BACKENDS` without one gets a row without estimates.
ESTIMATORS: Mapping[str, Callable] = MappingProxyType({
    "pardiso": _pardiso_estimate,
    "scipy": _scipy_estimate,
    "amg": _amg_estimate,
})


def estimate_backends(A, *, positive: bool = True, rows: int = CALIBRATION_ROWS,
                      available: tuple | None = None, near_null=None) -> list[BackendEstimate]:
    """One :class:`BackendEstimate` per backend of :data:`~flexmor.linalg.backends.BACKENDS`, in its order.

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
        The real symmetric matrix (both triangles).
    positive : bool
        ``A`` is positive definite.
    rows : int
        Rows of the calibration block.
    available : tuple of str, optional
        The backends that work here (default: as a new :class:`SolverContext` finds them).
    near_null : flexmor.linalg.amg.NearNull, optional
        The model's rigid motions, for the ``amg`` backend's estimate.

    Returns
    -------
    list of BackendEstimate
        A backend not available here, or without an estimator, has empty estimates and says why in ``source``.
    """
    A = A.tocsr()
    avail = SolverContext().available() if available is None else tuple(available)
    out = []
    for name in BACKENDS:
        if name not in avail:
            out.append(BackendEstimate(name, False, source="not available here"))
            continue
        fn = ESTIMATORS.get(name)
        extra = {"near_null": near_null} if name == "amg" else {}
        est = fn(A, positive=positive, rows=rows, **extra) if fn is not None else None
        out.append(est if est is not None else
                   BackendEstimate(name, True, source="no estimator for this backend (not estimated)"))
    return out


def auto_choice(solver: SolverContext, estimates: list[BackendEstimate], n: int, *, is_complex: bool,
                positive: bool) -> dict:
    """What ``solver`` takes for a matrix of ``n`` equations of this kind: the backend of
    :meth:`~flexmor.linalg.context.SolverContext.pick` and the memory mode of
    :func:`~flexmor.linalg.memory.plan_memory` with its estimates.

    Returns
    -------
    dict
        ``backend``, ``mode`` (None when nothing fits), ``reason`` (why this mode, or the refusal the run
        would end with), ``usable`` (bytes, or None).
    """
    try:
        backend = solver.pick(is_complex=is_complex, positive=positive, symmetric=True)
    except (OptionError, SolverError) as exc:
        return {"backend": None, "mode": None, "reason": str(exc), "usable": None}
    from .factorize import _memory_backend

    try:
        backend = _memory_backend(backend, solver)
    except SolverError as exc:
        return {"backend": backend, "mode": None, "reason": str(exc), "usable": None}
    if backend not in ("pardiso", "scipy"):  # the backends that plan a memory mode; the others factorize in double
        return {"backend": backend, "mode": "double", "reason": "the backend has no memory modes", "usable": None}
    row = next((e for e in estimates if e.backend == backend), None)
    memory = row.memory_estimates(is_complex) if row is not None else {m: None for m in MODE_NAMES}
    try:
        plan = plan_memory(solver, backend, n, memory)
    except SolverError as exc:
        usable = solver.memory_available()
        usable = None if usable is None else MEMORY_FRACTION * usable
        from .factorize import _iterative_instead

        if isinstance(exc, OutOfMemoryError) and _iterative_instead(solver, is_complex, True, positive):
            return {"backend": "amg", "mode": "double", "usable": usable,
                    "reason": f"no direct factorization fits: {exc}; amg (iterative) instead"}
        return {"backend": backend, "mode": None, "reason": str(exc), "usable": usable}
    return {"backend": backend, "mode": plan.mode, "reason": plan.reason, "usable": plan.usable}

