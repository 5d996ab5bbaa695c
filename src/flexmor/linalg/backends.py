"""The sparse direct solver backends behind :func:`flexmor.linalg.factorize`.

Each backend is one :class:`Backend` entry of the static table :data:`BACKENDS`: a name, a
description, the function that factorizes a matrix and an availability check. The solver
libraries are imported only when a backend is checked or used.

``scipy``
    SuperLU from SciPy, always available; symmetric mode with minimum-degree ordering on
    ``A + A^T``. Slow and memory hungry above ~50k DOF of a 3D solid.
``pardiso``
    Intel MKL PARDISO (the library located by *pypardiso*, ``pip install flexmor[fast]``),
    called through ctypes: real symmetric positive definite (Cholesky), real symmetric
    indefinite (Bunch-Kaufman) or complex symmetric (``K - w^2 M + i w D``, matrix type 6)
    factorization of the upper triangle with nested-dissection ordering (METIS).
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

import functools
import hashlib
import importlib.util
import logging
import time
from dataclasses import dataclass
from types import MappingProxyType
from typing import Callable, Mapping

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from .memory import MEMORY_FRACTION, OutOfCore, estimate_memory, matrix_bytes, pardiso_estimates, plan_memory, refine

__all__ = ["Backend", "BACKENDS", "Factorization", "OrderingCache", "SolverStats", "available_backends",
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
            self._anorm = float(np.linalg.norm(self._A.data))
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


@functools.cache
def _mkl_pardiso():
    """The MKL ``pardiso`` entry point (found through pypardiso's library search), typed once."""
    import ctypes

    import pypardiso

    fn = pypardiso.PyPardisoSolver().libmkl.pardiso
    i32p = ctypes.POINTER(ctypes.c_int32)
    fn.argtypes = [ctypes.POINTER(ctypes.c_int64), i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p,
                   i32p, i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p, ctypes.c_void_p, i32p]
    fn.restype = None
    return fn


#: PARDISO error codes (MKL reference) in the messages of :class:`SolverError`.
_PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
                   -4: "zero pivot (singular matrix)", -5: "unclassified internal error",
                   -6: "reordering failed", -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
                   -9: "not enough memory for out-of-core", -10: "error opening out-of-core files"}


class OrderingCache:
    """Fill-reducing orderings of the last few sparsity patterns factorized by PARDISO.

    Shifted matrices ``K - w^2 M + i w D`` of one model share a pattern, so frequency sweeps,
    quadrature nodes and expansion points compute METIS' nested dissection once and reuse it
    (``iparm[4] = 1``); the symbolic factorization still runs. Keyed by :meth:`key`.

    Parameters
    ----------
    kept : int
        Patterns remembered (the oldest is dropped first).
    """

    def __init__(self, kept: int = 4):
        self.kept = int(kept)
        self._perms: dict = {}

    def __len__(self) -> int:
        return len(self._perms)

    @staticmethod
    def key(mtype: int, ia: np.ndarray, ja: np.ndarray) -> tuple:
        """Identity of a sparsity pattern (and of the matrix class): size, nnz and a digest."""
        h = hashlib.blake2b(ia.view(np.uint8), digest_size=16)
        h.update(ja.view(np.uint8))
        return (int(mtype), ia.size - 1, ja.size, h.hexdigest())

    def get(self, key: tuple) -> np.ndarray | None:
        """The ordering stored for ``key``, or None."""
        return self._perms.get(key)

    def remember(self, key: tuple, perm: np.ndarray) -> None:
        """Store a copy of ``perm`` for ``key`` as the newest entry."""
        self._perms.pop(key, None)
        self._perms[key] = perm.copy()
        while len(self._perms) > self.kept:
            self._perms.pop(next(iter(self._perms)))


class _Pardiso(Factorization):
    """Intel MKL PARDISO called through ctypes on the upper triangle (symmetric) or the full matrix.

    Matrix types: real symmetric positive definite (2), real symmetric indefinite (-2,
    Bunch-Kaufman), complex symmetric (6, e.g. ``K - w^2 M + i w D``), real (11) and complex
    (13) unsymmetric. Symmetric indefinite types use symmetric weighted matching and scaling
    (iparm 11/13), recommended by Intel for saddle-point-like and shifted matrices. After the
    analysis, the memory mode is chosen from its estimate; the mixed (``iparm[27] = 1``) and
    out-of-core (``iparm[59] = 2``) modes analyse again with the ordering just computed.
    """

    backend = "pardiso"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        import ctypes

        orderings = solver.orderings
        self._fn = _mkl_pardiso()
        cplx = np.iscomplexobj(A.data)
        if cplx:
            self._mtype = 6 if symmetric else 13
        else:
            self._mtype = (2 if positive else -2) if symmetric else 11
        self.dtype = np.dtype(np.complex128 if cplx else np.float64)
        U = sp.triu(A, format="csr") if symmetric else sp.csr_matrix(A)
        U.sum_duplicates()
        U.sort_indices()
        if np.any(np.diff(U.indptr) == 0):
            raise SolverError("matrix has an empty row: it is singular")
        self._data = np.ascontiguousarray(U.data, dtype=self.dtype)
        self._ia = np.ascontiguousarray(U.indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(U.indices, dtype=np.int32)
        self._n = U.shape[0]
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        ip = self._iparm
        ip[0] = 1  # user values below, zeros are MKL defaults
        ip[1] = 2  # nested dissection (METIS)
        ip[7] = 0  # iterative refinement (two steps) only after perturbed pivots
        ip[9] = 13 if self._mtype in (11, 13) else 8  # pivot perturbation 1e-13 / 1e-8
        indefinite = self._mtype in (-2, 6, 11, 13)
        ip[10] = ip[12] = 1 if indefinite else 0  # scaling + weighted matching
        ip[34] = 1  # zero-based indices
        self._ctypes = ctypes
        self._live = False
        key = orderings.key(self._mtype, self._ia, self._ja)
        self._perm = orderings.get(key)
        ip[4] = 2 if self._perm is None else 1  # 2: return METIS' permutation, 1: reuse a stored one
        if self._perm is None:
            self._perm = np.zeros(self._n, dtype=np.int32)
        self.reused_ordering = ip[4] == 1
        self._ooc = None
        try:
            self._call(11, None, None, 0)  # analysis: ordering, symbolic factorization, memory
            if not self.reused_ordering:
                orderings.remember(key, self._perm)
            self._plan(solver, A, pardiso_estimates(ip, A))
            if self.memory.mode != "double":
                self._release()
                ip[4] = 1  # the ordering just computed
                if self.memory.mode == "mixed":
                    ip[27] = 1  # single-precision values, factor and solves
                    self._data = self._data.astype(np.complex64 if cplx else np.float32)
                else:
                    ip[59] = 2  # out of core, in memory at most what fits (no more than in core)
                    self._ooc = OutOfCore(min(self.memory.usable or np.inf, self.memory.estimates["double"]),
                                          solver.scratch_dir)
                self._call(11, None, None, 0)
            if self._ooc is None:
                self._call(22, None, None, 0)  # numerical factorization
            else:
                with self._ooc.environment():  # read by MKL in this phase only
                    self._call(22, None, None, 0)
                self._ooc.verify(A, self._solve_factor)
        except SolverError:
            self._release()
            raise
        self._live = True
        # no perturbed pivots: exact inertia (not of a single-precision factor, whose rounding
        # of ~1e-7 ||A|| may move the eigenvalues nearest the shift across it)
        if self._mtype == -2 and self._iparm[13] == 0 and self.memory.mode != "mixed":
            self.inertia = (int(self._iparm[21]), int(self._iparm[22]))

    def _call(self, phase, b, x, nrhs):
        c = self._ctypes
        i32 = c.c_int32
        err = i32(0)
        one = c.byref(i32(1))
        dummy = np.zeros(1, self.dtype)
        bp = (b if b is not None else dummy).ctypes.data
        xp = (x if x is not None else dummy).ctypes.data
        self._fn(self._pt.ctypes.data_as(c.POINTER(c.c_int64)), one, one, c.byref(i32(self._mtype)),
                 c.byref(i32(phase)), c.byref(i32(self._n)), self._data.ctypes.data,
                 self._ia.ctypes.data_as(c.POINTER(i32)), self._ja.ctypes.data_as(c.POINTER(i32)),
                 self._perm.ctypes.data_as(c.POINTER(i32)), c.byref(i32(nrhs)), self._iparm.ctypes.data_as(c.POINTER(i32)), c.byref(i32(0)),
                 bp, xp, c.byref(err))
        if err.value != 0:
            what = _PARDISO_ERRORS.get(err.value, "unknown error")
            raise SolverError(f"PARDISO phase {phase} failed with error {err.value}: {what}")

    def _solve_factor(self, b):
        if np.iscomplexobj(b) and self.dtype.kind != "c":  # handled by Factorization.solve
            raise SolverError("complex right-hand side for a real PARDISO factorization")
        b = np.asfortranarray(b, dtype=self._data.dtype)
        x = np.zeros_like(b, order="F")
        self._call(33, b, x, b.shape[1])
        return x

    def _release(self):
        if np.any(self._pt):
            self._call(-1, None, None, 0)  # free all internal memory of this handle (and the OOC files)
            self._pt[:] = 0
        if self._ooc is not None:
            self._ooc.remove()

    def __del__(self):
        try:
            self._release()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


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
    try:
        _mkl_pardiso()
        return True
    except Exception:  # noqa: BLE001 - missing MKL runtime
        return False


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
            _Pardiso, _pardiso_ok, complex=True, positive_only=False),
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
