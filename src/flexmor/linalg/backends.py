"""The sparse direct solver backends behind :func:`flexmor.linalg.factorize`.

Each backend is one :class:`Backend` entry of the static table :data:`BACKENDS`: a name, a
description, the function that factorizes a matrix and an availability check. The solver
libraries are imported only when a backend is checked or used.

``scipy``
    SuperLU from SciPy, always available; symmetric mode with minimum-degree ordering on
    ``A + A^T``. Slow and memory hungry above ~50k DOF of a 3D solid.
``pardiso``
    Intel MKL PARDISO (the library located by *pypardiso*, ``pip install flexmor[fast]``),
    called through ctypes (:mod:`flexmor.linalg.pardiso`): real symmetric positive definite
    (Cholesky), real symmetric indefinite (Bunch-Kaufman) or complex symmetric
    (``K - w^2 M + i w D``, matrix type 6) factorization of the upper triangle with
    nested-dissection ordering (METIS).
``cholmod``
    CHOLMOD through *scikit-sparse* when SuiteSparse is installed; real symmetric positive
    definite matrices only.
``petsc``
    MUMPS through PETSc, distributed over MPI ranks (:mod:`flexmor.linalg.petsc`).

``auto`` (a choice of :class:`flexmor.linalg.context.SolverContext`, not a backend) picks the
fastest available backend that supports the matrix (cholmod for real positive definite, then
pardiso for real or complex, then scipy).

pardiso and scipy choose a memory mode per factorization from their estimate
(:mod:`flexmor.linalg.memory`): double precision in core, mixed precision (single-precision
factor, solves refined in double) or, pardiso only, out of core.
"""

from __future__ import annotations

import importlib.util
import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from .memory import MEMORY_FRACTION, estimate_memory, matrix_bytes, norm_bound, plan_memory, refine

__all__ = ["Backend", "BACKENDS", "Factorization", "SolverStats", "available_backends",
           "memory_available", "estimate_memory", "MEMORY_FRACTION", "describe_backends"]

log = logging.getLogger(__name__)


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
        self.memory_estimate = None
        self.memory = None
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


class _ScipyLU(Factorization):
    backend = "scipy"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        from scipy.sparse.linalg import splu

        self.dtype = np.dtype(np.complex128 if np.iscomplexobj(A.data) else np.float64)
        est = estimate_memory(A, "scipy")
        self._plan(solver, A, {"double": est, "mixed": est / 2 + matrix_bytes(A), "ooc": None})
        opts = {}
        if symmetric:
            opts = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        C = sp.csc_matrix(A)
        if self.memory.mode == "mixed":  # the factor in single precision
            C = C.astype(np.complex64 if self.dtype.kind == "c" else np.float32)
        try:
            self._lu = splu(C, **opts)
        except RuntimeError as exc:
            raise SolverError(f"SuperLU failed: {exc}; the matrix is singular (a free body needs a shift)") from None
        except MemoryError:
            raise SolverError("SuperLU ran out of memory; use a faster solver (backend pardiso)",
                              params=("backend",)) from None

    def _solve_factor(self, b):
        return self._lu.solve(np.asarray(b, dtype=self._lu.U.dtype))


def memory_available() -> float | None:
    """Bytes of memory available to new allocations (``MemAvailable`` of /proc/meminfo), or None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return 1024.0 * int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


class _Cholmod(Factorization):
    backend = "cholmod"

    def __init__(self, A, solver, *, symmetric=True, positive=True):
        super().__init__(A, solver.stats)
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        if not (symmetric and positive):
            raise SolverError("the cholmod backend needs a symmetric positive definite matrix")
        try:
            self._f = cholesky(sp.csc_matrix(A))
        except CholmodNotPositiveDefiniteError as exc:
            raise SolverError(f"CHOLMOD: matrix is not positive definite ({exc})") from None

    def _solve_factor(self, b):
        return self._f(b)


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def _pardiso_ok() -> bool:
    if not _has("pypardiso"):
        return False
    from .pardiso import mkl_pardiso

    try:
        mkl_pardiso()
        return True
    except Exception:  # noqa: BLE001 - missing MKL runtime
        return False


def _pardiso(A, solver, *, symmetric=True, positive=False):
    from .pardiso import PardisoFactorization

    return PardisoFactorization(A, solver, symmetric=symmetric, positive=positive)


def _petsc_ok() -> bool:
    from .petsc import available

    return available()


def _petsc(A, solver, *, symmetric=True, positive=False):
    from .petsc import PetscFactorization

    return PetscFactorization(A, solver, symmetric=symmetric, positive=positive)


@dataclass(frozen=True)
class Backend:
    """One sparse direct solver library.

    Attributes
    ----------
    name : str
        The name of ``SolverContext(backend=...)`` and ``--backend``.
    description : str
        What it does (``flexmor info --backends``).
    factorize : callable
        ``factorize(A, solver, *, symmetric, positive) -> Factorization`` with ``solver`` the
        :class:`~flexmor.linalg.context.SolverContext` (statistics, ordering cache, MPI layout).
    available : callable
        ``available() -> bool``: the library works on this machine (imports it at most once).
    complex : bool
        Handles complex matrices.
    positive_only : bool
        Needs a real symmetric positive definite matrix.
    """

    name: str
    description: str
    factorize: Callable
    available: Callable[[], bool]
    complex: bool
    positive_only: bool


#: The backends, fastest first (the preference order of ``auto``); read-only.
BACKENDS: Mapping[str, Backend] = MappingProxyType({b.name: b for b in (
    Backend("cholmod", "CHOLMOD supernodal Cholesky (scikit-sparse); real symmetric positive definite only",
            _Cholmod, lambda: _has("sksparse"), complex=False, positive_only=True),
    Backend("pardiso", "Intel MKL PARDISO; real SPD (Cholesky), real symmetric indefinite (LDLT, inertia), "
            "complex symmetric and unsymmetric; METIS ordering; memory estimate before factorizing",
            _pardiso, _pardiso_ok, complex=True, positive_only=False),
    Backend("scipy", "SciPy SuperLU; real and complex, minimum-degree ordering; slow above ~50k DOF of a 3D solid",
            _ScipyLU, lambda: True, complex=True, positive_only=False),
    Backend("petsc", "MUMPS through PETSc, distributed over MPI ranks (mpirun -n P ... --backend petsc); "
            "real SPD, symmetric indefinite (inertia) and complex (real 2N form); SLEPc eigenpairs",
            _petsc, _petsc_ok, complex=True, positive_only=False),
)})


def available_backends() -> list[str]:
    """Names of the backends that work on this machine, fastest first."""
    return [name for name, b in BACKENDS.items() if b.available()]


def describe_backends() -> list[dict]:
    """One dict per known backend: ``name``, ``available``, ``complex``, ``positive_only``, ``description``."""
    avail = set(available_backends())
    return [{"name": b.name, "available": b.name in avail, "complex": b.complex, "positive_only": b.positive_only,
             "description": b.description} for b in BACKENDS.values()]
