"""The solver context: which sparse solver, its caches and statistics, passed by value.

Every function that factorizes or computes eigenpairs takes ``solver: SolverContext | None``
(None: a fresh default context). One context carries

* the backend (a name of :data:`flexmor.linalg.backends.BACKENDS` or ``auto``, validated when
  the context is made; the backends available for ``auto`` are determined once per context),
* the memory mode of factorizations and the memory they may use (:mod:`flexmor.linalg.memory`),
* the statistics of its factorizations and solves (:class:`SolverStats`), so that a caller
  reads the solver share of its own computation from the context it passed,
* the PARDISO ordering cache (:class:`OrderingCache`, reused across shifted matrices of one
  sparsity pattern),
* the MPI layout used by the ``petsc`` backend (:class:`flexmor.linalg.distributed.MPILayout`),
* the eigen policy (:class:`EigenPolicy`) of :func:`flexmor.linalg.eigenmodes`,
* a memo of facts about a model's matrices (e.g. the number of rigid-body modes), valid while
  those matrices live,
* the progress callback of long steps (:func:`track`, :func:`step`).

Nothing of this is kept at module level, so two computations in one process with two contexts
neither share counts nor caches.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field

from ..errors import OptionError, SolverError
from . import resources as _resources
from .backends import BACKENDS
from .distributed import MPILayout, layout
from .factorization import OrderingCache, SolverStats
from .memory import FACTOR_MEMORY, REFINE_TOL, SOLVE_TOL

__all__ = ["SolverContext", "track", "step", "EigenPolicy", "DENSE_LIMIT", "LANCZOS_MAX_K",
           "EIGEN_METHODS", "as_solver"]

#: Problems up to this size are solved densely (LAPACK), larger ones by shift-invert Lanczos.
DENSE_LIMIT = 600

#: ``method="auto"`` uses block Lanczos up to this many modes, ARPACK above (bench/eigen.py: block Lanczos is
#: 1.2-1.6x faster up to 150 modes; its basis of up to ``5 k`` columns is the memory of 32 modes when it kept
#: ``M Q`` beside it, against ARPACK's ``2 k + 1``).
LANCZOS_MAX_K = 64

#: Choices of the eigen method.
EIGEN_METHODS = ("auto", "lanczos", "arpack", "dense")


@dataclass(frozen=True)
class EigenPolicy:
    """How :func:`flexmor.linalg.eigenmodes` solves ``K phi = lambda M phi`` unless told otherwise.

    Attributes
    ----------
    method : {'auto', 'lanczos', 'arpack', 'dense'}
        ``auto``: dense up to ``dense_limit`` DOF or ``k >= n/2``, else lanczos up to
        ``lanczos_max_k`` modes and arpack above.
    dense_limit : int
        Largest problem solved densely by ``auto``.
    lanczos_max_k : int
        Most modes for which ``auto`` takes block Lanczos.
    block : int or None
        Block size of ``lanczos`` (None: ``min(max(6, k // 4), 16)``).
    """

    method: str = "auto"
    dense_limit: int = DENSE_LIMIT
    lanczos_max_k: int = LANCZOS_MAX_K
    block: int | None = None

    def __post_init__(self):
        if self.method not in EIGEN_METHODS:
            raise OptionError(f"method={self.method!r} is not allowed; choose one of: {', '.join(EIGEN_METHODS)}")

    def choose(self, n: int, k: int, method: str | None = None) -> str:
        """The method for ``k`` modes of an ``n``-DOF problem (``method`` overrides the policy's)."""
        method = self.method if method is None else method
        if method not in EIGEN_METHODS:
            raise OptionError(f"method={method!r} is not allowed; choose one of: {', '.join(EIGEN_METHODS)}")
        if method == "auto":
            if n <= self.dense_limit or k >= n // 2:
                return "dense"
            return "lanczos" if k <= self.lanczos_max_k else "arpack"
        return "dense" if k >= n else method


@dataclass
class SolverContext:
    """The sparse solver of a computation, with its caches and statistics.

    Parameters
    ----------
    backend : str
        ``auto`` or a name of :data:`~flexmor.linalg.backends.BACKENDS` (``cholmod``,
        ``pardiso``, ``scipy``, ``petsc``, ``amg``, ``petsc-gamg``); ``auto`` picks per matrix the fastest available
        backend that supports it. The environment variable ``FLEXMOR_AUTO_BACKENDS`` (names
        separated by commas, e.g. ``scipy``) restricts the backends ``auto`` chooses from, so that
        a whole run takes another arithmetic path without changing a call (``scipy`` serves every
        matrix, and takes it where none of the named ones does).
    eigen : EigenPolicy
        Defaults of :func:`flexmor.linalg.eigenmodes`.
    mpi : MPILayout, optional
        Rank and number of ranks of the ``petsc`` backend (default: those of this process,
        determined on first use by :meth:`layout`).
    progress : callable, optional
        ``progress(iterable, total, desc=None)``: shown the long steps of the computation (see
        :func:`track`); None shows nothing.
    factor_memory : {'auto', 'double', 'mixed', 'ooc'}
        Memory mode of the factorizations (:mod:`flexmor.linalg.memory`): ``auto`` takes double
        precision in core when its estimate fits, else mixed precision, else out of core;
        ``double``, ``mixed`` (pardiso, scipy) and ``ooc`` (pardiso) force one.
    memory_limit : float, optional
        Bytes of memory the factorizations may count on (None: the machine's available memory,
        ``MemAvailable``); a factorization uses at most
        :data:`~flexmor.linalg.memory.MEMORY_FRACTION` of it.
    refine_tol : float
        Backward error to which the mixed mode refines each solve (default 1e-12).
    scratch_dir : str or Path, optional
        Where out-of-core factorizations write their temporary files (None: ``$TMPDIR``).
    solve_tol : float
        Relative residual ``||b - A x|| / ||b||`` to which the ``amg`` and ``petsc-gamg`` backends solve
        every column (default 1e-10; :mod:`flexmor.linalg.amg`, :mod:`flexmor.linalg.petsc_gamg`).

    Attributes
    ----------
    stats : SolverStats
        Factorizations and solves done with this context.
    orderings : OrderingCache
        Fill-reducing orderings reused by PARDISO.
    near_null : dict
        Matrix size -> :class:`flexmor.linalg.amg.NearNull`: the rigid-body motions of the geometry the
        ``amg`` backend builds its hierarchy on (:func:`flexmor.rigid.register_near_null`).

    Raises
    ------
    OptionError
        An unknown backend name or memory mode (the message lists the allowed ones), a
        memory limit or refinement tolerance that is not positive.
    """

    backend: str = "auto"
    eigen: EigenPolicy = field(default_factory=EigenPolicy)
    mpi: MPILayout | None = None
    progress: Callable | None = field(default=None, repr=False)
    factor_memory: str = "auto"
    memory_limit: float | None = None
    refine_tol: float = REFINE_TOL
    scratch_dir: str | None = None
    solve_tol: float = SOLVE_TOL
    stats: SolverStats = field(default_factory=SolverStats, init=False)
    orderings: OrderingCache = field(default_factory=OrderingCache, init=False, repr=False)
    near_null: dict = field(default_factory=dict, init=False, repr=False)
    _available: tuple | None = field(default=None, init=False, repr=False)
    _memo: dict = field(default_factory=dict, init=False, repr=False)
    _kept: tuple | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        allowed = ["auto", *BACKENDS]
        if self.backend not in allowed:
            raise OptionError(f"backend={self.backend!r} is not allowed; choose one of: {', '.join(allowed)}")
        if self.factor_memory not in FACTOR_MEMORY:
            raise OptionError(f"factor_memory={self.factor_memory!r} is not allowed; choose one of: "
                              f"{', '.join(FACTOR_MEMORY)}", params=("factor_memory",))
        if self.memory_limit is not None and not self.memory_limit > 0:
            raise OptionError(f"memory_limit must be a positive number of bytes, got {self.memory_limit!r}",
                              params=("memory_limit",))
        if not 0 < self.refine_tol < 1:
            raise OptionError(f"refine_tol must lie in (0, 1), got {self.refine_tol!r}", params=("refine_tol",))
        if not 0 < self.solve_tol < 1:
            raise OptionError(f"solve_tol must lie in (0, 1), got {self.solve_tol!r}", params=("solve_tol",))

    def memory_available(self) -> float | None:
        """Bytes of memory the factorizations may count on: ``memory_limit``, else the memory the
        process can still allocate (:func:`flexmor.linalg.resources.memory_available`: the machine's,
        bounded by the address-space and cgroup limits), or None if unknown."""
        return _resources.memory_available() if self.memory_limit is None else float(self.memory_limit)

    def layout(self) -> MPILayout:
        """The MPI layout of the ``petsc`` backend (this process' rank and size unless given)."""
        if self.mpi is None:
            self.mpi = layout()
        return self.mpi

    def available(self) -> tuple[str, ...]:
        """Names of the backends that work on this machine, fastest first (checked once per context)."""
        if self._available is None:
            self._available = tuple(name for name, b in BACKENDS.items() if b.available())
        return self._available

    def pick(self, *, is_complex: bool, positive: bool, symmetric: bool) -> str:
        """The backend that factorizes a matrix of this kind.

        Raises
        ------
        OptionError
            ``petsc`` asked for but not installed (the message names the install route).
        SolverError
            Another backend asked for but not available here.
        """
        avail = self.available()
        if self.backend != "auto":
            if self.backend not in avail:
                if self.backend in DISTRIBUTED:
                    from .petsc import require

                    require()  # OptionError naming the install route
                raise SolverError(f"backend {self.backend!r} is not available here; available: {', '.join(avail)}")
            return self.backend
        for name in _auto_candidates(avail):
            b = BACKENDS[name]
            if b.iterative or (is_complex and not b.complex) or (b.positive_only and not (positive and symmetric)):
                continue
            return name
        return "scipy"

    def remember(self, what: str, matrices: tuple, compute: Callable):
        """``compute()``, computed once per ``what`` while the (weak-referenceable) ``matrices`` live.

        Sparse matrices are not hashable, so the memo is keyed by their ids and guarded by weak
        references: an entry whose matrices were collected (and whose ids may be reused) is
        recomputed.
        """
        key = (what, *map(id, matrices))
        hit = self._memo.get(key)
        if hit is not None and all(ref() is m for ref, m in zip(hit[0], matrices)):
            return hit[1]
        value = compute()
        try:
            memo = self._memo

            def forget(_ref: weakref.ref, key: tuple = key) -> None:
                memo.pop(key, None)

            refs = tuple(weakref.ref(m, forget) for m in matrices)
        except TypeError:  # not weak-referenceable: not remembered
            return value
        self._memo[key] = (refs, value)
        return value


    def kept(self, K, M, sigma: float):
        """The factorization of ``K - sigma M`` kept by :meth:`keep` for these very matrices and shift, else None."""
        k = self._kept
        return k[3] if k is not None and self.kept_shift(K, M) == sigma else None

    def kept_shift(self, K, M) -> float | None:
        """The shift of the factorization kept for these very matrices, else None."""
        k = self._kept
        return k[2] if k is not None and k[0]() is K and k[1]() is M else None

    def keep(self, K, M, sigma: float, F) -> None:
        """Keep ``F``, the factorization of ``K - sigma M`` (one at a time), until :meth:`release`: the
        next computation on the same matrix shares it (:func:`flexmor.linalg.factorize.factorize_shifted`).
        Its memory stays taken meanwhile."""
        self._kept = (weakref.ref(K), weakref.ref(M), float(sigma), F)

    def release(self) -> None:
        """Drop the factorization kept by :meth:`keep` (its memory is free once nothing else holds it)."""
        self._kept = None


#: The backends that run under MPI on matrices whose rows are spread over the ranks.
DISTRIBUTED = ("petsc", "petsc-gamg")


#: The environment variable that restricts the backends ``backend="auto"`` chooses from.
AUTO_BACKENDS_VARIABLE = "FLEXMOR_AUTO_BACKENDS"


def _auto_candidates(available: tuple[str, ...]) -> tuple[str, ...]:
    """The available backends ``auto`` may choose from: all of them, or those that
    ``FLEXMOR_AUTO_BACKENDS`` names (an unknown name is an :class:`OptionError`)."""
    value = os.environ.get(AUTO_BACKENDS_VARIABLE, "").strip()
    if not value:
        return available
    names = [n.strip() for n in value.split(",") if n.strip()]
    unknown = [n for n in names if n not in BACKENDS]
    if unknown:
        raise OptionError(f"{AUTO_BACKENDS_VARIABLE}={value!r} names no backend {', '.join(map(repr, unknown))}; "
                          f"choose from: {', '.join(BACKENDS)}", params=("backend",))
    return tuple(n for n in available if n in names)


def as_solver(solver: SolverContext | None) -> SolverContext:
    """``solver`` itself, or a fresh default context for None; an OptionError for anything else."""
    if solver is None:
        return SolverContext()
    if not isinstance(solver, SolverContext):
        raise OptionError(f"solver must be a SolverContext (e.g. SolverContext(backend='scipy')), got {solver!r}")
    return solver


def track(progress: Callable | None, iterable, total: int | None, desc: str):
    """``iterable``, shown to ``progress`` as one long step named ``desc``.

    The progress convention of flexmor: a caller (the command line) passes a callback
    ``progress(iterable, total, desc=None)`` that returns an iterable over the same items
    (e.g. a tqdm bar); the library iterates it and never prints. ``total`` is the count of a
    loop (frequencies, quadrature nodes, time steps) or None for a step without one
    (:func:`step`). ``progress`` None returns ``iterable`` itself.
    """
    return iterable if progress is None else progress(iterable, total, desc=desc)


@contextmanager
def step(progress: Callable | None, desc: str):
    """A step without a count (e.g. one LAPACK call), shown to ``progress`` as it starts and ends.

    Yields a dict in which the step may leave a short ``result`` text (e.g. the error of a
    trial order) for ``progress`` to show with its end: the one item of the iterable that
    ``progress`` gets with ``total`` None.
    """
    yield from track(progress, [{}], None, desc)
