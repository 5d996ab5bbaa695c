"""The ``pardiso`` backend: Intel MKL PARDISO called through ctypes, and its ordering cache.

The library is the one located by *pypardiso* (``pip install flexmor[fast]``); only its
``pardiso`` entry point is used, typed once (:func:`mkl_pardiso`). :class:`PardisoFactorization`
factorizes real symmetric positive definite (Cholesky), real symmetric indefinite
(Bunch-Kaufman, with the inertia), complex symmetric (``K - w^2 M + i w D``) and unsymmetric
matrices with nested-dissection ordering (METIS); the orderings of recent sparsity patterns are
reused (:class:`flexmor.linalg.factorization.OrderingCache`). After the analysis phase it chooses a memory mode from the
estimate of PARDISO (:mod:`flexmor.linalg.memory`): double precision in core, mixed precision
or out of core. It is the ``pardiso`` entry of :data:`flexmor.linalg.backends.BACKENDS`;
pypardiso and MKL are loaded only when that backend is checked or used.
"""

from __future__ import annotations

import functools
import logging
import time

import numpy as np
import scipy.sparse as sp

from ..errors import OutOfMemoryError, SolverError
from .factorization import Factorization
from .memory import OutOfCore, check_solve, pardiso_estimates
from .resources import describe_memory

__all__ = ["BACKWARD_TOL", "PARDISO_ERRORS", "PardisoFactorization", "mkl_pardiso"]

log = logging.getLogger(__name__)

#: Largest normwise backward error of a symmetric indefinite factor ordered without weighted matching
#: (measured 1e-17 to 1e-16 on shifted solid, plate and beam models, with and without damping).
BACKWARD_TOL = 1e-11


@functools.cache
def mkl_pardiso():
    """The MKL ``pardiso`` entry point, typed once, from :func:`flexmor.linalg.mkl_sparse.mkl_library`."""
    import ctypes

    from .mkl_sparse import mkl_library

    lib = mkl_library()
    if lib is None:
        raise SolverError("PARDISO needs Intel MKL (pip install pypardiso, the 'fast' extra)")
    fn = lib.pardiso
    i32p = ctypes.POINTER(ctypes.c_int32)
    fn.argtypes = [ctypes.POINTER(ctypes.c_int64), i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p,
                   i32p, i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p, ctypes.c_void_p, i32p]
    fn.restype = None
    return fn


#: PARDISO error codes (MKL reference) in the messages of :class:`SolverError`.
PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
                  -4: "zero pivot (singular matrix)", -5: "unclassified internal error",
                  -6: "reordering failed", -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
                  -9: "not enough memory for out-of-core", -10: "error opening out-of-core files"}


class PardisoFactorization(Factorization):
    """Intel MKL PARDISO called through ctypes on the upper triangle (symmetric) or the full matrix.

    Matrix types: real symmetric positive definite (2), real symmetric indefinite (-2,
    Bunch-Kaufman), complex symmetric (6, e.g. ``K - w^2 M + i w D``), real (11) and complex
    (13) unsymmetric. The symmetric types are ordered by nested dissection of the pattern alone,
    so ``K - sigma M`` and every ``K - w^2 M + i w D`` of a model share one ordering (computed
    once, :class:`~flexmor.linalg.factorization.OrderingCache`; the analysis then costs a
    quarter to a half of METIS' own at 35,000 DOF). An indefinite factor that had to perturb a
    pivot, or whose solve of a random right-hand side misses a backward error of
    :data:`BACKWARD_TOL`, is computed again with symmetric weighted matching and scaling
    (iparm 11/13, recommended by Intel for saddle-point-like matrices; its ordering depends on the
    values and is not reused); the unsymmetric types always use them. After the analysis, the
    memory mode is chosen from its estimate; the mixed (``iparm[27] = 1``) and out-of-core
    (``iparm[59] = 2``) modes analyse again with the ordering just computed. ``numeric_seconds`` is the wall
    time of the numerical factorization phase alone (22, the analysis not included).
    """

    backend = "pardiso"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        self._setup(A, symmetric=symmetric, positive=positive)
        plain = symmetric  # ordered by the pattern alone (no weighted matching) first
        try:
            self._factor(A, solver, matching=not plain)
            if plain and self._mtype != 2 and not self._stable(A):
                log.info("PARDISO: %d perturbed pivots or a backward error above %.0e without weighted matching "
                         "(n=%d): factorized again with it", self._iparm[13], BACKWARD_TOL, self._n)
                self._release()
                self._factor(A, solver, matching=True)
        except SolverError:
            self._release()
            raise
        self._values = None  # the values in use are self._data
        self._live = True
        # no perturbed pivots: exact inertia (not of a single-precision factor, whose rounding
        # of ~1e-7 ||A|| may move the eigenvalues nearest the shift across it)
        if self._mtype == -2 and self._iparm[13] == 0 and self.memory.mode != "mixed":
            self.inertia = (int(self._iparm[21]), int(self._iparm[22]))

    @classmethod
    def analysis(cls, A, solver, *, symmetric: bool = True, positive: bool = False) -> np.ndarray:
        """``iparm`` after PARDISO's analysis phase of ``A`` alone (no numerical factorization; nothing is
        kept): ``iparm[14:17]`` the peak, permanent and factor memory in KB, ``iparm[17]`` the nonzeros of
        the factor, ``iparm[18]`` the MFLOPS of its numerical factorization. The ordering is the one a
        factorization with ``solver`` would compute (and is remembered in its ordering cache)."""
        self = cls.__new__(cls)
        Factorization.__init__(self, A, solver.stats)
        self._setup(A, symmetric=symmetric, positive=positive)
        try:
            self._analyse(solver.orderings, matching=not symmetric, flops=True)
            return self._iparm.copy()
        finally:
            self._release()

    def _setup(self, A, *, symmetric: bool, positive: bool) -> None:
        """The matrix type and the upper triangle (symmetric) or the whole ``A`` in PARDISO's arrays."""
        import ctypes

        self._fn = mkl_pardiso()
        self._ctypes = ctypes
        self._live = False
        self._ooc: OutOfCore | None = None
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
        self._values = np.ascontiguousarray(U.data, dtype=self.dtype)
        self._ia = np.ascontiguousarray(U.indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(U.indices, dtype=np.int32)
        self._n = U.shape[0]
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm: np.ndarray = np.zeros(64, dtype=np.int32)
        self._data: np.ndarray = self._values

    def _factor(self, A, solver, *, matching: bool) -> None:
        """Analysis (with the ordering of this pattern when known), memory plan and numerical factorization."""
        cplx = self.dtype.kind == "c"
        self._analyse(solver.orderings, matching=matching)
        ip = self._iparm
        self._plan(solver, A, pardiso_estimates(ip, A, self._data.size))
        plan = self.memory
        assert plan is not None  # set by _plan
        if plan.mode != "double":
            self._release()
            ip[4] = 1  # the ordering just computed
            if plan.mode == "mixed":
                ip[27] = 1  # single-precision values, factor and solves
                self._data = self._values.astype(np.complex64 if cplx else np.float32)
            else:
                ip[59] = 2  # out of core, in memory at most what fits (no more than in core)
                self._ooc = OutOfCore(min(plan.usable or np.inf, plan.estimates["double"]),
                                      solver.scratch_dir)
            self._call(11, None, None, 0)
        t0 = time.perf_counter()
        if self._ooc is None:
            self._call(22, None, None, 0)  # numerical factorization
        else:
            with self._ooc.environment():  # read by MKL in this phase only
                self._call(22, None, None, 0)
        self.numeric_seconds = time.perf_counter() - t0
        if self._ooc is not None:
            if self._ooc.verify(A, self._solve_factor) > BACKWARD_TOL or self._iparm[13] > 0:
                # an out-of-core factor whose solves are less accurate than a double-precision factor's (a
                # backward error above BACKWARD_TOL, seen once as a relative error of 7e-4 against the in-core
                # solve, far inside verify's bound): its solves are refined in double precision, as a mixed one's
                log.info("PARDISO out of core: a solve's backward error is above %.0e; solves are refined",
                         BACKWARD_TOL)
                self._keep_for_refinement(A, solver)

    def _analyse(self, orderings, *, matching: bool, flops: bool = False) -> None:
        """PARDISO's analysis phase (11: ordering, with the one of this pattern when ``orderings`` knows it,
        and symbolic factorization), its estimates in ``self._iparm``; ``flops`` asks for the MFLOPS of the
        numerical factorization too (``iparm[18] = -1``: reported in ``iparm[18]``)."""
        self._data = self._values
        self._iparm = np.zeros(64, dtype=np.int32)
        ip = self._iparm
        ip[0] = 1  # user values below, zeros are MKL defaults
        ip[1] = 2  # nested dissection (METIS)
        ip[7] = 0  # iterative refinement (two steps) only after perturbed pivots
        ip[9] = 13 if self._mtype in (11, 13) else 8  # pivot perturbation 1e-13 / 1e-8
        ip[10] = ip[12] = 1 if matching else 0  # scaling + weighted matching
        ip[34] = 1  # zero-based indices
        if flops:
            ip[17] = ip[18] = -1  # report the nonzeros of the factor and the MFLOPS of its factorization
        # a plain ordering serves every symmetric type of the pattern; with matching MKL computes its own
        key = orderings.key(self._mtype if matching else 0, self._ia, self._ja)
        self._perm = None if matching else orderings.get(key)
        if self._perm is None and not matching:
            self._perm = orderings.near(key, self._ia)
            if self._perm is not None:
                self._perm = self._perm.copy()
        ip[4] = 2 if self._perm is None else 1  # 2: return METIS' permutation, 1: reuse a stored one
        if self._perm is None:
            self._perm = np.zeros(self._n, dtype=np.int32)
        self.reused_ordering = ip[4] == 1
        self.matching = matching
        self._call(11, None, None, 0)  # analysis: ordering, symbolic factorization, memory
        if not self.reused_ordering and not matching:
            orderings.remember(key, self._perm, self._ia)

    def _stable(self, A) -> bool:
        """No perturbed pivot, and the backward error of one solve (:func:`~flexmor.linalg.memory.check_solve`)
        below :data:`BACKWARD_TOL` (a factor in single precision: its unit round-off times 1e3)."""
        if self._iparm[13] > 0:
            return False
        mixed = self.memory is not None and self.memory.mode == "mixed"
        tol = 1e3 * float(np.finfo(np.float32).eps) if mixed else BACKWARD_TOL
        return check_solve(A, self._solve_factor)[1] <= tol

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
                 self._perm.ctypes.data_as(c.POINTER(i32)), c.byref(i32(nrhs)),
                 self._iparm.ctypes.data_as(c.POINTER(i32)), c.byref(i32(0)), bp, xp, c.byref(err))
        if err.value != 0:
            what = PARDISO_ERRORS.get(err.value, "unknown error")
            if err.value in (-2, -9):  # out of memory: the machine's or the process's limit
                raise OutOfMemoryError(f"PARDISO phase {phase} ({self._n} equations): {what}; "
                                       f"{describe_memory()}; try factor_memory='mixed' or 'ooc', a smaller "
                                       "model, or a machine with more memory", params=("factor_memory",))
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
            self._ooc = None

    def __del__(self):
        try:
            self._release()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass
