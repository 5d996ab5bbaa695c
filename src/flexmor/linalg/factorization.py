"""The base of every solver backend: a factorized matrix, the solver statistics, the ordering cache.

:class:`Factorization` is the class each backend of :data:`flexmor.linalg.backends.BACKENDS`
subclasses (its constructor factorizes, ``_solve_factor`` solves); it counts its solves in the
:class:`SolverStats` of the solver context and refines solves of a mixed-precision factor
(:mod:`flexmor.linalg.memory`). :class:`OrderingCache` keeps the fill-reducing orderings that
the ``pardiso`` backend reuses across matrices of one sparsity pattern. This module imports no
backend, so the backends and the solver context can all import it.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from .memory import MemoryPlan, norm_bound, plan_memory, refine

__all__ = ["Factorization", "SolverStats", "OrderingCache"]


@dataclass
class SolverStats:
    """Running totals of the factorizations of one solver context and of the solves with them.

    Attributes
    ----------
    count, seconds : int, float
        Factorizations and their wall time.
    solves, solve_columns, solve_seconds : int, int, float
        Calls of :meth:`Factorization.solve`, right-hand sides solved, and their wall time.
    mixed, ooc : int
        Factorizations in mixed precision and out of core (:mod:`flexmor.linalg.memory`).
    refined_solves, refine_steps, refine_max_steps : int
        Solves refined in double precision (mixed mode), their single-precision solves in
        all and the most of one.
    refine_residual : float
        The largest backward error a refined solve ended with.
    factor_reason : str
        Why the last factorization in mixed precision or out of core was made so
        (:func:`flexmor.linalg.memory.factor_record` summarizes these counts).
    iterative, iterative_tol, iterative_backend : int, float, str
        Matrices solved iteratively instead of factorized (the ``amg`` backend, :mod:`flexmor.linalg.amg`, or
        ``petsc-gamg``, :mod:`flexmor.linalg.petsc_gamg`; counted in ``count`` too), the relative residual asked
        of their solves and the backend that solved the last of them.
    iterations, iterations_max, iterative_residual : int, int, float
        Block CG iterations of their solves in all and the most of one, and the largest relative
        residual ``||b - A x|| / ||b||`` of a column they ended with.
    eigen_iterations, eigen_residual : int, float
        Iterations of the preconditioned eigensolver (LOBPCG, :mod:`flexmor.linalg.lobpcg`; one V-cycle per
        iterating column each) and the largest relative residual of an eigenpair it returned.
    """

    count: int = 0
    seconds: float = 0.0
    solves: int = 0
    solve_columns: int = 0
    solve_seconds: float = 0.0
    mixed: int = 0
    ooc: int = 0
    refined_solves: int = 0
    refine_steps: int = 0
    refine_max_steps: int = 0
    refine_residual: float = 0.0
    factor_reason: str = ""
    iterative: int = 0
    iterative_tol: float = 0.0
    iterative_backend: str = ""
    iterations: int = 0
    iterations_max: int = 0
    iterative_residual: float = 0.0
    eigen_iterations: int = 0
    eigen_residual: float = 0.0


class Factorization:
    """A factorized square matrix; call :meth:`solve` for any number of right-hand sides.

    Attributes
    ----------
    backend : str
        Name of the backend that computed it.
    shape : tuple
        Shape of the factorized matrix.
    seconds : float
        Wall time of the factorization.
    memory_estimate : float or None
        Bytes the backend expected to need for factor and solves (pardiso: from its analysis
        phase; scipy: the heuristic of :func:`estimate_memory`), checked against the
        available memory before the numerical factorization.
    inertia : tuple of int or None
        ``(n_positive, n_negative)`` eigenvalues of a real symmetric indefinite matrix when
        the backend reports them (pardiso), else None. For ``K - s M`` the number of
        negative eigenvalues is the number of eigenvalues of ``(K, M)`` below ``s``
        (Sylvester's law of inertia).
    memory : MemoryPlan or None
        The memory mode and the estimates of the backends that choose one (pardiso, scipy).
    """

    backend = "none"

    def __init__(self, A, stats: SolverStats):
        self.stats = stats
        self.shape = A.shape
        self.dtype = A.dtype
        self.seconds = 0.0
        self.inertia = None
        self.memory_estimate: float | None = None
        self.memory: MemoryPlan | None = None
        self._A = None

    def _solve_factor(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """Solve with the factor itself (2-D ``b``, real for a real factor)."""
        raise NotImplementedError

    def solve(self, b) -> np.ndarray:
        """Solve ``A x = b``; ``b`` of shape (n,) or (n, k), real or complex."""
        b = np.asarray(b)
        if b.shape[0] != self.shape[0]:
            raise SolverError(f"right-hand side has {b.shape[0]} rows, the matrix {self.shape[0]}")
        t0 = time.perf_counter()
        if np.iscomplexobj(b) and not np.iscomplexobj(np.empty(0, self.dtype)):
            x = self._solve_real(b.real) + 1j * self._solve_real(b.imag)
        else:
            x = self._solve_real(b)
        self.stats.solves += 1
        self.stats.solve_columns += 1 if b.ndim == 1 else b.shape[1]
        self.stats.solve_seconds += time.perf_counter() - t0
        return x

    def _solve_real(self, b):
        one = b.ndim == 1
        x = self._solve(b.reshape(b.shape[0], -1))
        return x.reshape(-1) if one else x

    def _plan(self, solver, A, estimates: dict) -> None:
        """Choose the memory mode (:func:`flexmor.linalg.memory.plan_memory`); the mixed mode
        keeps ``A`` in double precision for the residuals of its refined solves."""
        self.memory = plan_memory(solver, self.backend, A.shape[0], estimates)
        self.memory_estimate = self.memory.estimate
        if self.memory.mode == "mixed":
            self._keep_for_refinement(A, solver)

    def _keep_for_refinement(self, A, solver) -> None:
        """Refine every solve from now on (:func:`flexmor.linalg.memory.refine`), with ``A`` kept in double
        precision for the residuals: a mixed-precision factor, or another that solves less accurately than
        a double-precision factor should."""
        self._A = A.tocsr().astype(self.dtype, copy=False)
        self._anorm = norm_bound(self._A)
        self._tol = solver.refine_tol

    def _solve(self, b: np.ndarray) -> np.ndarray:
        if self._A is None:
            return self._solve_factor(b)
        x, steps, residual = refine(self._A, self._solve_factor, b, anorm=self._anorm, tol=self._tol)
        st = self.stats
        st.refined_solves += 1
        st.refine_steps += steps
        st.refine_max_steps = max(st.refine_max_steps, steps)
        st.refine_residual = max(st.refine_residual, residual)
        return x

    __call__ = solve


#: Share of the rows (and of the entries) in which a pattern may differ from a stored one and still take its
#: ordering (:meth:`OrderingCache.near`).
NEAR_SHARE = 0.01


class OrderingCache:
    """Fill-reducing orderings of the last few sparsity patterns factorized by PARDISO.

    Shifted matrices ``K - w^2 M + i w D`` of one model share a pattern, so frequency sweeps,
    quadrature nodes, expansion points and the shifts of eigen solves compute METIS' nested
    dissection once and reuse it (``iparm[4] = 1``; the symbolic factorization still runs, at a
    quarter to a half of the cost with METIS). Keyed by :meth:`key`: the orderings of the symmetric
    types without weighted matching are one (``mtype`` 0 in the key); with matching, MKL orders
    by the values and ignores a given ordering. A pattern that differs from a stored one of the same
    size in a few entries (a few rows' counts and the number of entries, each by at most
    :data:`NEAR_SHARE`; e.g. ``K_ii`` and ``K_ii - sigma M_ii`` of an interface's interior, whose mass
    holds a few entries the stiffness does not) takes that one's ordering too (:meth:`near`): any
    permutation gives a correct factorization, a near one about the same fill.

    Parameters
    ----------
    kept : int
        Patterns remembered (the oldest is dropped first).
    """

    def __init__(self, kept: int = 4):
        self.kept = int(kept)
        self._perms: dict = {}
        self._rows: dict = {}  # the row counts of each stored pattern, for near()

    def __len__(self) -> int:
        return len(self._perms)

    @staticmethod
    def key(mtype: int, ia: np.ndarray, ja: np.ndarray) -> tuple:
        """Identity of a sparsity pattern (and of the matrix class): size, nnz and a digest."""
        h = hashlib.blake2b(ia.view(np.uint8).data, digest_size=16)
        h.update(ja.view(np.uint8).data)
        return (int(mtype), ia.size - 1, ja.size, h.hexdigest())

    def get(self, key: tuple) -> np.ndarray | None:
        """The ordering stored for ``key``, or None."""
        return self._perms.get(key)

    def near(self, key: tuple, ia: np.ndarray) -> np.ndarray | None:
        """The ordering of a stored pattern of the same kind and size that differs from ``(key, ia)`` in at
        most :data:`NEAR_SHARE` of the rows' counts and of the entries (or 8 of them), or None."""
        kind, n, nnz = key[:3]
        counts = np.diff(ia)
        for other, perm in reversed(self._perms.items()):
            if other[:2] != (kind, n) or abs(other[2] - nnz) > max(NEAR_SHARE * nnz, 8):
                continue
            if np.count_nonzero(self._rows[other] != counts) <= max(NEAR_SHARE * n, 8):
                return perm
        return None

    def remember(self, key: tuple, perm: np.ndarray, ia: np.ndarray | None = None) -> None:
        """Store a copy of ``perm`` for ``key`` (and its row pointers ``ia``, for :meth:`near`) as the newest entry."""
        self._perms.pop(key, None)
        self._perms[key] = perm.copy()
        self._rows[key] = np.diff(ia) if ia is not None else np.full(key[1], -1)
        while len(self._perms) > self.kept:
            self._rows.pop(oldest := next(iter(self._perms)), None)
            self._perms.pop(oldest)
