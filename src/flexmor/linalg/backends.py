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
``amg``
    Not a factorization: smoothed-aggregation algebraic multigrid (*pyamg*, ``pip install
    flexmor[amg]``) preconditioning block conjugate gradients, solving real symmetric positive
    definite matrices to a stated relative residual (:mod:`flexmor.linalg.amg`); memory
    proportional to the matrix, for models whose factor fits in no memory mode.
``petsc-gamg``
    Not a factorization either: PETSc's smoothed-aggregation AMG (GAMG, near-null space of the
    rigid-body motions) preconditioning CG, distributed over MPI ranks like ``petsc``
    (``mpirun -n P ... --backend petsc-gamg``); real symmetric positive definite matrices to the
    same relative residual (:mod:`flexmor.linalg.petsc_gamg`).

``auto`` (a choice of :class:`flexmor.linalg.context.SolverContext`, not a backend) picks the
fastest available direct backend that supports the matrix (cholmod for real positive definite, then
pardiso for real or complex, then scipy); with ``factor_memory="auto"`` it takes ``amg`` for a real
symmetric matrix none of them can factorize in any memory mode (:func:`flexmor.linalg.factorize.factorize`).

pardiso and scipy choose a memory mode per factorization from their estimate
(:mod:`flexmor.linalg.memory`): double precision in core, mixed precision (single-precision
factor, solves refined in double) or, pardiso only, out of core.
"""

from __future__ import annotations

import importlib.util
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

from ..errors import OutOfMemoryError, SolverError
from .factorization import Factorization
from .memory import MEMORY_FRACTION, estimate_memory, matrix_bytes
from .resources import describe_memory

__all__ = ["Backend", "BACKENDS", "available_backends", "is_iterative",
           "estimate_memory", "MEMORY_FRACTION", "describe_backends"]

log = logging.getLogger(__name__)


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
        self._factor_dtype = C.dtype  # (SuperLU's .U builds a copy of the factor at every access)
        try:
            self._lu = splu(C, **opts)
        except RuntimeError as exc:
            raise SolverError(f"SuperLU failed: {exc}; the matrix is singular (a free body needs a shift)") from None
        except MemoryError:
            raise OutOfMemoryError(f"SuperLU ran out of memory factorizing {A.shape[0]} equations: "
                                   f"{describe_memory()}; try backend='pardiso' (less memory), factor_memory="
                                   "'mixed', or a machine with more memory",
                                   params=("backend", "factor_memory")) from None

    def _solve_factor(self, b):
        return self._lu.solve(np.asarray(b, dtype=self._factor_dtype))


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
    except (OSError, ImportError, AttributeError):  # missing MKL runtime or no pardiso entry point in it
        return False


def _pardiso(A, solver, *, symmetric=True, positive=False):
    from .pardiso import PardisoFactorization

    return PardisoFactorization(A, solver, symmetric=symmetric, positive=positive)


def _amg(A, solver, *, symmetric=True, positive=False):
    from .amg import AmgSolver

    return AmgSolver(A, solver, symmetric=symmetric, positive=positive)


def _petsc_ok() -> bool:
    from .petsc import available

    return available()


def _petsc(A, solver, *, symmetric=True, positive=False):
    from .petsc import PetscFactorization

    return PetscFactorization(A, solver, symmetric=symmetric, positive=positive)


def _petsc_gamg(A, solver, *, symmetric=True, positive=False):
    from .petsc_gamg import PetscGamg

    return PetscGamg(A, solver, symmetric=symmetric, positive=positive)


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
    iterative : bool
        Solves iteratively to a tolerance instead of factorizing; ``auto`` takes it only when no
        direct factorization fits.
    """

    name: str
    description: str
    factorize: Callable
    available: Callable[[], bool]
    complex: bool
    positive_only: bool
    iterative: bool = False


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
    Backend("amg", "smoothed-aggregation AMG (pyamg) preconditioning block CG, to a relative residual "
            "(--solve-tol); real symmetric positive definite only; memory proportional to the matrix",
            _amg, lambda: _has("pyamg"), complex=False, positive_only=True, iterative=True),
    Backend("petsc-gamg", "PETSc GAMG (smoothed aggregation, rigid-body near-null space) preconditioning CG, "
            "distributed over MPI ranks (mpirun -n P ... --backend petsc-gamg), to a relative residual "
            "(--solve-tol); real symmetric positive definite only; LOBPCG eigenpairs",
            _petsc_gamg, _petsc_ok, complex=False, positive_only=True, iterative=True),
)})


def is_iterative(name: str | None) -> bool:
    """Whether the backend ``name`` solves iteratively (``amg``, ``petsc-gamg``: real positive definite matrices
    to a tolerance, no complex solves) rather than factorizing."""
    b = BACKENDS.get(name or "")
    return bool(b is not None and b.iterative)


def available_backends(*, iterative: bool = False) -> list[str]:
    """Names of the sparse direct backends that work on this machine, fastest first (with ``iterative``,
    the iterative ones too)."""
    return [name for name, b in BACKENDS.items() if (iterative or not b.iterative) and b.available()]


def describe_backends() -> list[dict]:
    """One dict per known backend: ``name``, ``available``, ``complex``, ``positive_only``, ``description``."""
    avail = set(available_backends(iterative=True))
    return [{"name": b.name, "available": b.name in avail, "complex": b.complex, "positive_only": b.positive_only,
             "iterative": b.iterative, "description": b.description} for b in BACKENDS.values()]
