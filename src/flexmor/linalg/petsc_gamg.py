"""The ``petsc-gamg`` backend: PETSc's smoothed-aggregation AMG (GAMG) preconditioning CG, under MPI.

The iterative counterpart of the ``petsc`` backend (:mod:`flexmor.linalg.petsc`) as ``amg``
(:mod:`flexmor.linalg.amg`) is that of the direct serial backends: where no MUMPS factor fits into the
memory of the ranks, a real symmetric positive definite matrix ``A`` (``K - sigma M`` with
``sigma <= 0``, a clamped ``K``, an interior block ``K_ii``) is solved iteratively. Chosen by name:
``SolverContext(backend="petsc-gamg")``, ``mpirun -n P flexmor reduce MODEL ... --backend petsc-gamg``.

``A`` becomes the same PETSc ``MPIAIJ`` matrix as for MUMPS (:func:`flexmor.linalg.petsc.petsc_matrix`;
rows split over the ranks as :func:`flexmor.linalg.distributed.row_range` does, a partitioned matrix
keeps its own rows). A ``KSPCG`` with ``PCGAMG`` is set up once in place of the factorization; each
right-hand side is then solved by CG (one column after the other with the same hierarchy: petsc4py
3.18 has no ``KSPMatSolve``) to the relative residual ``||b - A x|| / ||b|| <= solve_tol`` of every
column (:attr:`~flexmor.linalg.context.SolverContext.solve_tol`, default
:data:`~flexmor.linalg.memory.SOLVE_TOL`, the ``amg`` backend's), with the unpreconditioned norm
(the residual the tolerance names, not the preconditioned one CG would test by default), at most
:data:`~flexmor.linalg.amg.MAX_ITER` iterations. The true residual ``b - A x`` is formed after CG
stops; a column still above the tolerance (the recurred residual drifts by rounding) is iterated on
from its solution (at most :data:`~flexmor.linalg.amg.RESTARTS` times), and one that does not get
there raises :class:`~flexmor.errors.ConvergenceError` with the iterations and residual reached. As
in :func:`flexmor.linalg.amg.block_cg`, a residual at the rounding floor of a backward-stable solve
counts as converged.

Near-null space: the rigid-body motions registered for the model (:func:`flexmor.linalg.amg.near_null`,
:func:`flexmor.rigid.register_near_null`; rows of a sub-matrix with :func:`~flexmor.linalg.amg.register_rows`),
orthonormalized, given to GAMG by ``MatSetNearNullSpace``. They are built from those vectors rather than
from ``MatNullSpaceCreateRigidBody`` and node coordinates: the same six vectors where every node has
three translations, and the right ones where nodes carry rotations (shells, beams) or equations were
eliminated (a clamped face, the interior of an interface). Where every node's equations are
consecutive and each rank's rows are whole nodes, the matrix gets that block size (3 or 6), so that
GAMG aggregates nodes. Without a registered space GAMG takes the constant (logged).

Refusals (:class:`~flexmor.errors.SolverError`): a complex or unsymmetric matrix
(``K - w^2 M + i w D``) at once; an indefinite one (``sigma`` above the lowest eigenvalue) where CG
meets a direction of negative energy (``KSP_DIVERGED_INDEFINITE_*``) or the GAMG set-up fails: a
matrix not declared positive definite is probed by a short CG run on a random right-hand side when
the hierarchy is set up, so that the eigensolver (which applies the preconditioner only) does not
start on one.

Eigenpairs: :func:`flexmor.linalg.eigen.eigenmodes` runs the project's LOBPCG
(:func:`flexmor.linalg.lobpcg.lobpcg`) with :meth:`PetscGamg.precondition`, one GAMG V-cycle
(``PCApply``) per column, as the preconditioner (:func:`gamg_eigenmodes`). LOBPCG works on replicated
blocks: the products with ``K`` and ``M`` are those of the replicated matrices (each rank the whole
product) or of partitioned ones (reduced over the ranks), the preconditioned block is gathered on every
rank (:func:`flexmor.linalg.distributed.allgather_rows`), so every rank holds the same blocks, makes
the same dense Rayleigh-Ritz steps and the same convergence decisions, and so the same sequence of
collective calls. SLEPc's ``EPSLOBPCG`` was the alternative; the project's LOBPCG keeps one eigensolver
(soft locking, SVQB, the residual measure and the stall test) for ``amg`` and ``petsc-gamg`` alike, and
records its iterations the same way.

PETSc options of the solver: prefix ``flexmor_gamg_``, e.g.
``PETSC_OPTIONS="-flexmor_gamg_pc_gamg_threshold 0.02 -flexmor_gamg_pc_gamg_agg_nsmooths 1"``.

References
----------
Adams, M. F., Bayraktar, H. H., Keaveny, T. M., Papadopoulos, P. (2004). Ultrascalable implicit finite
element analyses in solid mechanics with over a half a billion degrees of freedom. Proc. ACM/IEEE SC04.
Balay, S. et al. (2022). PETSc/TAO Users Manual, ANL-21/39 Rev. 3.18.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..errors import ConvergenceError, SolverError
from . import distributed as dist
from .amg import MAX_ITER, RESTARTS, ROUNDING, near_null
from .factorization import Factorization
from .petsc import _local_rows, _petsc, petsc_matrix, require

__all__ = ["PetscGamg", "INDEFINITE", "OPTIONS_PREFIX", "gamg_eigenmodes"]

log = logging.getLogger(__name__)

#: Prefix of the PETSc options of the GAMG solver (``PETSC_OPTIONS="-flexmor_gamg_pc_gamg_threshold 0.02"``).
OPTIONS_PREFIX = "flexmor_gamg_"

#: The refusal of a matrix that is not positive definite.
INDEFINITE = ("the matrix is not positive definite ({where}): backend 'petsc-gamg' (GAMG + CG) needs K - sigma M "
              "positive definite, i.e. sigma below the lowest eigenvalue (a supported body, or a free body with a "
              "negative shift); backend 'petsc' (MUMPS) solves indefinite and complex matrices")

#: Relative residual and most iterations of the probe of a matrix not declared positive definite.
PROBE_TOL, PROBE_ITER = 1e-2, 50


class PetscGamg(Factorization):
    """A GAMG hierarchy of a real symmetric positive definite matrix distributed over the MPI ranks;
    :meth:`solve` runs CG to the relative residual ``solver.solve_tol`` of every column (see the module docs).

    Attributes
    ----------
    mat, ksp : PETSc Mat and KSP
        The matrix and the CG solver with its GAMG preconditioner.
    rows : tuple of int
        This rank's ``[start, stop)``.
    levels : int
        Levels of the hierarchy.
    operator_complexity : float
        Entries of all levels' matrices over those of ``A``.
    near_null : str
        Which near-null space the hierarchy was built on.
    block : int
        The matrix' block size (equations per node GAMG aggregates; 1: equations one by one).
    matrix : sparse matrix or PartitionedMatrix
        ``A`` as given (the products of the eigensolver).
    """

    backend = "petsc-gamg"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        if np.iscomplexobj(A.data) or not symmetric:
            raise SolverError("backend 'petsc-gamg' solves real symmetric positive definite matrices only (K - sigma "
                              "M, sigma <= 0), not a complex or unsymmetric one such as K - w^2 M + i w D: take real "
                              "expansion points (e.g. --points 0), judge without the full FRF (--no-error), or the "
                              "direct backend 'petsc' for this step", params=("backend",))
        PETSc = _petsc()
        require()
        PETSc.garbage_cleanup()  # (collective: the objects of earlier solvers, see PetscFactorization)
        self.dtype = np.dtype(np.float64)
        n = A.shape[0]
        r0, r1, rows = _local_rows(A, solver.layout())
        self.rows, self._n, self.matrix = (r0, r1), n, A
        nn = near_null(solver, n)
        self.block = _block_size(nn.block if nn is not None else 1, r0, r1)
        t0 = time.perf_counter()
        self.mat = petsc_matrix(rows, n, symmetric=True, positive=positive, block=self.block)
        if nn is not None:
            self.near_null = f"{nn.B.shape[1]} rigid-body motions of the geometry"
            self._space = _near_null_space(PETSc, self.mat, nn.B, r0, r1)
            self.mat.setNearNullSpace(self._space)
        else:
            self.near_null, self._space = "the constant (no geometry registered)", None
            log.info("petsc-gamg: no near-null space registered for %d equations; GAMG takes the constant", n)
        self._tol = float(solver.solve_tol)
        self.ksp = _cg_gamg(PETSc, self.mat, self._tol)
        try:
            self.ksp.setUp()
        except PETSc.Error as exc:
            raise SolverError(INDEFINITE.format(where=f"the GAMG set-up failed: {str(exc).strip()}"),
                              params=("backend",)) from None
        self.levels, self.operator_complexity = _hierarchy(PETSc, self.ksp.getPC(), self.mat)
        self._anorm = self.mat.norm(PETSc.NormType.INFINITY)  # ||A||_2 <= ||A||_inf for a symmetric A
        self._x, self._b = self.mat.createVecs()
        self._r = self._b.duplicate()
        if not positive:
            self._probe(PETSc)
        self.setup_seconds = time.perf_counter() - t0
        self.memory_estimate = self.operator_complexity * 12.0 * self.mat.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)[
            "nz_used"]
        stats = solver.stats
        stats.iterative += 1
        stats.iterative_tol = self._tol
        stats.iterative_backend = self.backend
        log.info("petsc-gamg: %d equations on %d ranks, %d levels, operator complexity %.2f, block %d, near-null "
                 "space %s, set up in %.2f s", n, dist.size(), self.levels, self.operator_complexity, self.block,
                 self.near_null, self.setup_seconds)

    def _probe(self, PETSc) -> None:
        """A short CG run on a random right-hand side: an indefinite matrix is refused before any solve."""
        r0, r1 = self.rows
        self._b.getArray()[:] = np.random.default_rng(0).standard_normal(self._n)[r0:r1]
        self.ksp.setTolerances(rtol=PROBE_TOL, max_it=PROBE_ITER)
        try:
            self._cg(PETSc, nonzero=False)
        except ConvergenceError:
            pass  # (slow, not indefinite: the solves say so with their own tolerance)
        finally:
            self.ksp.setTolerances(rtol=self._tol, max_it=MAX_ITER)

    def _cg(self, PETSc, *, nonzero: bool) -> int:
        """CG on ``A x = b`` (``self._b``, ``self._x``); its iterations, or the refusal of an indefinite matrix."""
        self.ksp.setInitialGuessNonzero(nonzero)
        self.ksp.solve(self._b, self._x)
        reason, its = self.ksp.getConvergedReason(), self.ksp.getIterationNumber()
        R = PETSc.KSP.ConvergedReason
        if reason in (R.DIVERGED_INDEFINITE_MAT, R.DIVERGED_INDEFINITE_PC):
            raise SolverError(INDEFINITE.format(where="CG met a direction of negative energy"), params=("backend",))
        if reason == R.DIVERGED_PCSETUP_FAILED:
            raise SolverError(INDEFINITE.format(where="the GAMG set-up failed"), params=("backend",))
        if reason < 0 and reason != R.DIVERGED_MAX_IT:
            raise SolverError(f"petsc-gamg: CG stopped with KSP reason {reason} after {its} iterations "
                              f"(residual {self.ksp.getResidualNorm():.1e})")
        if reason == R.DIVERGED_MAX_IT:
            rtol = self.ksp.getTolerances()[0]
            raise ConvergenceError(f"petsc-gamg: CG did not reach the relative residual {rtol:.0e} in {its} iterations")
        return its

    def precondition(self, R: np.ndarray) -> np.ndarray:
        """One GAMG V-cycle (``PCApply``) on each column of the replicated block ``R``; the result replicated
        (collective: every rank calls it with the same ``R``)."""
        R = np.asarray(R, dtype=float).reshape(self._n, -1)
        r0, r1 = self.rows
        pc = self.ksp.getPC()
        out = np.empty((r1 - r0, R.shape[1]))
        for j in range(R.shape[1]):
            self._b.getArray()[:] = R[r0:r1, j]
            pc.apply(self._b, self._x)
            out[:, j] = self._x.getArray()
        return dist.allgather_rows(out, self._n)

    def _solve_factor(self, b: np.ndarray) -> np.ndarray:
        PETSc = _petsc()
        r0, r1 = self.rows
        b = np.asarray(b, dtype=float)
        k = b.shape[1]
        out = np.empty((r1 - r0, k))
        st = self.stats
        for j in range(k):
            bl = b[r0:r1, j]
            self._b.getArray()[:] = bl
            bn = self._b.norm()
            if bn == 0:
                out[:, j] = 0.0
                continue
            its, res = 0, np.inf
            for attempt in range(RESTARTS + 1):
                try:
                    its += self._cg(PETSc, nonzero=attempt > 0)
                except ConvergenceError:
                    res = self._residual(bn)
                    raise ConvergenceError(f"petsc-gamg: CG did not reach the relative residual {self._tol:.0e} in "
                                           f"{MAX_ITER} iterations (column {j} of {k}: relative residual {res:.1e} "
                                           f"after {its + self.ksp.getIterationNumber()} iterations)") from None
                res = self._residual(bn)
                floor = ROUNDING * np.finfo(float).eps * (self._anorm * self._x.norm() + bn) / bn
                if res <= max(self._tol, floor):
                    break
            else:
                raise ConvergenceError(f"petsc-gamg: CG did not reach the relative residual {self._tol:.0e} (column "
                                       f"{j} of {k}: {res:.1e} after {its} iterations, {RESTARTS} restarts)")
            out[:, j] = self._x.getArray()
            st.iterations += its
            st.iterations_max = max(st.iterations_max, its)
            st.iterative_residual = max(st.iterative_residual, res)
        return dist.allgather_rows(out, self._n)

    def _residual(self, bn: float) -> float:
        """``||b - A x|| / ||b||`` of ``self._b``, ``self._x`` (collective)."""
        self.mat.mult(self._x, self._r)
        self._r.aypx(-1.0, self._b)
        return float(self._r.norm() / bn)

    def release(self) -> None:
        """Free the PETSc objects now (collective: call on all ranks)."""
        for name in ("ksp", "_space", "_x", "_b", "_r", "mat"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
                setattr(self, name, None)


def _block_size(block: int, r0: int, r1: int) -> int:
    """``block`` where every rank's rows are whole nodes of it (the same answer on every rank), else 1."""
    bad = np.array([0.0 if block > 1 and r0 % block == 0 and r1 % block == 0 else 1.0])
    return block if block > 1 and dist.allreduce(bad)[0] == 0 else 1


def _near_null_space(PETSc, mat, B: np.ndarray, r0: int, r1: int):
    """The columns of ``B`` (replicated, (n, k)) orthonormalized, as a PETSc near-null space of ``mat``."""
    Q, R = np.linalg.qr(np.asarray(B, dtype=float))
    Q = Q[:, np.abs(np.diag(R)) > 1e-12 * np.abs(np.diag(R)).max()]  # (dependent motions dropped)
    vecs = []
    for j in range(Q.shape[1]):
        v = mat.createVecLeft()
        v.getArray()[:] = Q[r0:r1, j]
        vecs.append(v)
    return PETSc.NullSpace().create(constant=False, vectors=vecs, comm=mat.getComm())


def _cg_gamg(PETSc, mat, tol: float):
    """``KSPCG`` + ``PCGAMG`` on ``mat``: the relative unpreconditioned residual ``tol``, :data:`MAX_ITER`
    iterations; options of the prefix :data:`OPTIONS_PREFIX` applied."""
    ksp = PETSc.KSP().create(comm=mat.getComm())
    ksp.setOptionsPrefix(OPTIONS_PREFIX)
    ksp.setOperators(mat)
    ksp.setType(PETSc.KSP.Type.CG)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=tol, atol=0.0, max_it=MAX_ITER)
    ksp.getPC().setType(PETSc.PC.Type.GAMG)
    ksp.setFromOptions()
    return ksp


def _hierarchy(PETSc, pc, mat) -> tuple[int, float]:
    """Levels of the GAMG hierarchy and its operator complexity (entries of all levels over those of ``mat``)."""
    try:
        nlev = pc.getMGLevels()
        nz = sum(pc.getMGSmoother(i).getOperators()[0].getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]
                 for i in range(nlev))
        return int(nlev), float(nz) / max(mat.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"], 1.0)
    except PETSc.Error:  # pragma: no cover - a PC without levels
        return 1, 1.0


def gamg_eigenmodes(K, M, k: int, F: PetscGamg, sigma: float, *, tol: float = 1e-8):
    """The lowest ``k`` eigenpairs of ``K phi = lambda M phi`` by LOBPCG preconditioned by ``F``'s GAMG V-cycle
    (``F`` set up for ``K - sigma M``); see the module docs. Replicated results, the same on every rank."""
    from .lobpcg import lobpcg

    if F.shape[0] != K.shape[0]:
        raise SolverError("the GAMG hierarchy does not belong to K - sigma M")
    return lobpcg(K, M, k, F.matrix, F.precondition, sigma, tol=tol, stats=F.stats)
