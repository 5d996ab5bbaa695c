"""One sparse direct solver interface for all of flexmor: :func:`factorize`.

Every method obtains its solves from ``factorize(A, solver=...)`` and never calls a solver
library itself, so a faster backend speeds up every method at once. A factorization is
computed once and reused for any number of right-hand sides (1-D or 2-D, real or complex).
The backends are listed in :mod:`flexmor.linalg.backends`; the
:class:`~flexmor.linalg.context.SolverContext` chooses among them and counts the work. A
factorization whose double-precision factor does not fit into memory is computed in mixed
precision or out of core (:mod:`flexmor.linalg.memory`, ``SolverContext(factor_memory=...)``).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from ..errors import OutOfMemoryError, SolverError
from .backends import BACKENDS
from .context import DISTRIBUTED, SolverContext, as_solver
from .distributed import is_partitioned
from .factorization import Factorization

__all__ = ["factorize", "factorize_shifted", "RESIDUAL_TOL"]

log = logging.getLogger(__name__)

#: Relative residual above which a factorization is reported as singular.
RESIDUAL_TOL = 1e-6


def factorize(A, *, solver: SolverContext | None = None, symmetric: bool = True, positive: bool = False,
              check: bool = True) -> Factorization:
    """Factorize the sparse square matrix ``A`` once for repeated solves.

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
        Real or complex; stored in full (both triangles) when symmetric. A matrix partitioned
        over MPI ranks (:class:`flexmor.linalg.distributed.PartitionedMatrix`) is factorized by
        the ``petsc`` backend (or solved by ``petsc-gamg`` where chosen).
    solver : SolverContext, optional
        The backend choice (``auto``: the fastest available one that supports ``A``), the
        memory mode (``factor_memory``; mixed precision needs pardiso or scipy, out of core
        pardiso, which ``auto`` then picks), and where the factorization and its solves are
        counted. None: a fresh default context.
    symmetric : bool
        ``A`` is (complex) symmetric; enables symmetric orderings and factorizations.
    positive : bool
        ``A`` is known to be positive definite (allows Cholesky).
    check : bool
        Solve once with a random right-hand side and raise :class:`SolverError` if the
        relative residual exceeds 1e-6 (singular or badly conditioned matrix).

    Returns
    -------
    Factorization
        Object with ``solve(b)`` for b of shape (n,) or (n, k).
    """
    solver = as_solver(solver)
    partitioned = is_partitioned(A)
    if not (partitioned or sp.issparse(A)):
        A = sp.csr_matrix(np.asarray(A))
    if A.shape[0] != A.shape[1]:
        raise SolverError(f"cannot factorize a non-square matrix of shape {A.shape}")
    is_complex = np.iscomplexobj(A.data)
    if partitioned:  # rows spread over MPI ranks (flexmor.linalg.distributed)
        if solver.backend not in ("auto", *DISTRIBUTED):
            raise SolverError(f"a matrix partitioned over MPI ranks needs the petsc or petsc-gamg backend, not "
                              f"{solver.backend!r}")
        name = "petsc" if solver.backend == "auto" else solver.backend  # (petsc says what to install when missing)
    else:
        name = solver.pick(is_complex=is_complex, positive=positive, symmetric=symmetric)
    if is_complex and not BACKENDS[name].complex and not BACKENDS[name].iterative:
        log.info("backend %s has no complex support; using scipy", name)
        name = "scipy"
    name = _memory_backend(name, solver)
    t0 = time.perf_counter()
    try:
        F = BACKENDS[name].factorize(A, solver, symmetric=symmetric, positive=positive)
    except OutOfMemoryError as exc:
        if not _iterative_instead(solver, is_complex, symmetric, positive):
            raise
        log.info("no direct factorization fits (%s): backend amg instead of %s", exc, name)
        name = "amg"
        F = BACKENDS[name].factorize(A, solver, symmetric=symmetric, positive=positive)
        solver.stats.factor_reason = f"no direct factorization fits: {exc}"
    F.seconds = time.perf_counter() - t0
    stats = solver.stats
    stats.count += 1
    stats.seconds += F.seconds
    if F.memory is not None and F.memory.mode != "double":
        setattr(stats, F.memory.mode, getattr(stats, F.memory.mode) + 1)
        stats.factor_reason = F.memory.reason
    log.debug("factorized n=%d nnz=%d with %s in %.3f s", A.shape[0], A.nnz, name, F.seconds)
    if check and not BACKENDS[name].iterative:  # (an iterative solve checks its residual itself)
        rng = np.random.default_rng(0)
        b = rng.standard_normal(A.shape[0])
        x = F.solve(b)
        res = np.linalg.norm(A @ x - b) / np.linalg.norm(b)
        if not np.isfinite(res) or res > RESIDUAL_TOL:
            raise SolverError(
                f"the matrix is singular or badly conditioned (relative residual {res:.1e} with {name}): a shift "
                "at an eigenfrequency of the body, or a free-free body without a shift or reference conditions"
            )
    return F


def _iterative_instead(solver: SolverContext, is_complex: bool, symmetric: bool, positive: bool) -> bool:
    """Whether ``auto`` takes the iterative ``amg`` backend for a matrix no direct factorization fits:
    backend and memory mode ``auto``, a real symmetric matrix known to be positive definite (``K - sigma M``
    with ``sigma`` below the spectrum: block CG diverges on ``K - w^2 M`` inside the band), pyamg installed."""
    return (solver.backend == "auto" and solver.factor_memory == "auto" and not is_complex and symmetric
            and positive and "amg" in solver.available())


#: The backends that have each forced memory mode (:mod:`flexmor.linalg.memory`).
_MODE_BACKENDS = {"mixed": ("pardiso", "scipy"), "ooc": ("pardiso",)}


def _memory_backend(name: str, solver: SolverContext) -> str:
    """``name``, or for a memory mode it lacks the first available backend that has it (``auto``)."""
    wanted = _MODE_BACKENDS.get(solver.factor_memory)
    if wanted is None or name in wanted:
        return name
    if solver.backend == "auto":
        for other in wanted:
            if other in solver.available():
                log.info("factor_memory=%r: backend %s instead of %s", solver.factor_memory, other, name)
                return other
    raise SolverError(f"factor_memory={solver.factor_memory!r} needs backend {' or '.join(wanted)}"
                      + ("" if "pardiso" in solver.available() else " (pardiso: pip install flexmor[fast])")
                      + f", not {name}", params=("factor_memory", "backend"))


def factorize_shifted(K, M, sigma: float, *, solver: SolverContext | None = None, keep: bool = False) -> Factorization:
    """The factorization of ``K - sigma M`` (positive definite for ``sigma < 0``): the one ``solver`` keeps
    for these very matrices and shift (:meth:`~flexmor.linalg.context.SolverContext.kept`), else a new one.

    ``keep=True`` keeps the new one in ``solver`` until the next call for the same matrix without
    ``keep`` takes it (handed over: the context holds it no longer, so no second large factorization
    lives beside it after its last user) or ``solver.release()``: the rigid-body check of a model
    (:func:`flexmor.checks.check_rigid_body_modes`) and the method that follows at that shift
    (``krylov`` at its point, ``modal``) make one factorization.
    """
    solver = as_solver(solver)
    F = solver.kept(K, M, sigma)
    if F is not None:
        if not keep:  # handed over: its memory goes with the caller's last reference
            solver.release()
        return F
    F = factorize((K - sigma * M).tocsr(), solver=solver, symmetric=True, positive=sigma < 0)
    if keep:
        solver.keep(K, M, sigma, F)
    return F
