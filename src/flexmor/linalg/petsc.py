"""The ``petsc`` backend: distributed sparse direct solves (MUMPS through PETSc) and SLEPc eigenpairs.

Run under MPI (``mpirun -n P flexmor reduce MODEL ... --backend petsc``); see
:mod:`flexmor.linalg.distributed` for how the ranks share the work. A shifted matrix becomes a
PETSc ``MPIAIJ`` matrix whose rows are spread over the ranks, factorized once by MUMPS
(``KSPPREONLY`` + ``PCCHOLESKY``: ``LL^T`` for positive definite, ``LDL^T`` with 2x2 pivots for
indefinite matrices, or ``PCLU`` for unsymmetric ones); blocks of right-hand sides are solved
in one ``MatMatSolve``. MUMPS orders the matrix on rank 0 (its sequential analysis: the graph,
not the values, is gathered there); factor and solves are distributed.

Complex shifted matrices ``A = K - w^2 M + i w D`` with a real PETSc build (Debian's default
``python3-petsc4py-real``) are solved in the equivalent real form of twice the size,
interleaved per equation,

    [[Re A, Im A], [Im A, -Re A]] [Re x; -Im x] = [Re b; Im b],

which is real symmetric (indefinite) when ``A`` is complex symmetric; a complex PETSc build
(``PETSC_DIR`` of ``python3-petsc4py-complex``) takes complex matrices directly.

Eigenpairs (:func:`slepc_eigenmodes`): SLEPc's Krylov-Schur on the pencil
``(M, K - sigma M)`` with the spectral transformation's factorization reused as the ``B``
solve, i.e. shift-invert ``(K - sigma M)^{-1} M x = theta x`` with ``lambda = sigma + 1/theta``.

References
----------
Balay, S. et al. (2022). PETSc/TAO Users Manual, ANL-21/39 Rev. 3.18.
Amestoy, P. R., Duff, I. S., L'Excellent, J.-Y., Koster, J. (2001). A fully asynchronous
multifrontal solver using distributed dynamic scheduling. SIAM J. Matrix Anal. Appl. 23(1), 15-41.
Hernandez, V., Roman, J. E., Vidal, V. (2005). SLEPc: A scalable and flexible toolkit for the
solution of eigenvalue problems. ACM Trans. Math. Software 31(3), 351-362.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, OptionError, SolverError
from . import distributed as dist
from .factorization import Factorization

__all__ = ["INSTALL_HINT", "PetscFactorization", "available", "require", "slepc_eigenmodes"]

log = logging.getLogger(__name__)

INSTALL_HINT = ("the petsc backend needs petsc4py, slepc4py and mpi4py: on Debian/Ubuntu "
                "'apt-get install python3-petsc4py python3-slepc4py python3-mpi4py' and a virtual environment made "
                "with '/usr/bin/python3 -m venv --system-site-packages' (make test-mpi builds one: .venv-mpi), "
                "or 'pip install flexmor[petsc]'")

#: MUMPS error codes (INFOG(1)) in the messages of :class:`SolverError`.
_MUMPS_ERRORS = {-5: "not enough memory in analysis", -6: "matrix is structurally singular",
                 -7: "not enough memory", -8: "work array too small", -9: "work array too small (raise ICNTL(14))",
                 -10: "numerically singular matrix", -13: "memory allocation failed",
                 -38: "parallel analysis requested but MUMPS has neither PT-Scotch nor ParMETIS",
                 -40: "matrix was declared positive definite but a negative or zero pivot was found"}


def _petsc():
    """petsc4py's PETSc module (initialized on first use) or an OptionError naming the install route."""
    try:
        import petsc4py

        petsc4py.init()
        from petsc4py import PETSc
    except ImportError:
        raise OptionError(f"backend petsc is not installed: {INSTALL_HINT}", params=("backend",)) from None
    return PETSc


def available() -> bool:
    """petsc4py, slepc4py and mpi4py are importable (checked without importing them)."""
    import importlib.util

    try:
        return all(importlib.util.find_spec(m) is not None for m in ("petsc4py", "slepc4py", "mpi4py"))
    except (ImportError, ValueError):
        return False


def require() -> None:
    """Raise :class:`OptionError` with the install route unless the backend works here (MUMPS included)."""
    if not available():
        raise OptionError(f"backend petsc is not available: {INSTALL_HINT}", params=("backend",))
    if not _petsc().Sys.hasExternalPackage("mumps"):
        raise OptionError("backend petsc needs a PETSc built with MUMPS (Debian's is; from source: "
                          "--download-mumps --download-scalapack --download-ptscotch)", params=("backend",))


def _complex_scalars(PETSc) -> bool:
    return np.dtype(PETSc.ScalarType).kind == "c"


def _real_form(A: sp.csr_matrix, symmetric: bool) -> sp.csr_matrix:
    """Rows of the interleaved real form of the complex rows ``A`` (equation i -> rows 2i, 2i+1)."""
    if symmetric:  # [[Ar, Ai], [Ai, -Ar]] acting on [xr; -xi]
        re, im = np.array([[1.0, 0.0], [0.0, -1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]])
    else:  # [[Ar, -Ai], [Ai, Ar]] acting on [xr; xi]
        re, im = np.eye(2), np.array([[0.0, -1.0], [1.0, 0.0]])
    return (sp.kron(A.real, re, format="csr") + sp.kron(A.imag, im, format="csr")).tocsr()


def _local_rows(A, layout: dist.MPILayout):
    """``(start, stop, rows)`` of this rank: its block of a partitioned matrix or a slice of a replicated one."""
    if dist.is_partitioned(A):
        return A.local_rows()
    r0, r1 = layout.row_range(A.shape[0])
    return r0, r1, sp.csr_matrix(A[r0:r1])


def petsc_matrix(rows: sp.csr_matrix, n: int, *, symmetric: bool, positive: bool, block: int = 1):
    """A PETSc ``MPIAIJ`` matrix from this rank's row block ``rows`` (shape (m, n), global columns), of block
    size ``block`` (``m`` and this rank's first row multiples of it)."""
    PETSc = _petsc()
    rows = sp.csr_matrix(rows)
    rows.sum_duplicates()
    rows.sort_indices()
    itype = np.dtype(PETSc.IntType)
    m = rows.shape[0]
    A = PETSc.Mat().createAIJ(size=((m, n), (m, n)), bsize=block if block > 1 else None, comm=PETSc.COMM_WORLD,
                              csr=(rows.indptr.astype(itype), rows.indices.astype(itype),
                                   rows.data.astype(PETSc.ScalarType)))
    if symmetric:
        A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        if positive:
            A.setOption(PETSc.Mat.Option.SPD, True)
    A.assemble()
    return A


class PetscFactorization(Factorization):
    """MUMPS factorization of a (possibly partitioned) sparse matrix on all ranks; see the module docs.

    The ``petsc`` entry of :data:`flexmor.linalg.backends.BACKENDS`. Attributes beyond
    :class:`~flexmor.linalg.factorization.Factorization`: ``mat`` (the PETSc matrix), ``ksp``, ``rows``
    (this rank's ``[start, stop)`` of the factorized matrix), ``memory_per_rank`` (MUMPS
    INFOG(21), bytes, largest over ranks), ``memory_total`` (INFOG(22)), ``factor_entries`` (INFOG(29)).
    """

    backend = "petsc"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        PETSc = _petsc()
        require()
        # petsc4py defers the destruction of parallel objects dropped by Python (e.g. earlier
        # factorizations) to this collective call; without it their MUMPS factors pile up
        PETSc.garbage_cleanup()
        n = A.shape[0]
        cplx = np.iscomplexobj(A.data)
        self._split = cplx and not _complex_scalars(PETSc)
        self._sym_form = symmetric
        r0, r1, rows = _local_rows(A, solver.layout())
        if self._split:
            rows, r0, r1, n = _real_form(rows, symmetric), 2 * r0, 2 * r1, 2 * n
            positive = False
        self.rows, self._n = (r0, r1), n
        self.dtype = np.dtype(np.complex128 if cplx else np.float64)
        self.mat = petsc_matrix(rows, n, symmetric=symmetric, positive=positive)
        prefix = f"flexmor_{id(self):x}_"  # options of this factorization only, removed after setUp
        opts = PETSc.Options()
        # real symmetric indefinite: ICNTL(13)=1 (no ScaLAPACK root node), so that the inertia of LDL^T
        # is exact in parallel, and ICNTL(24)=1 (null pivot detection), which PETSc needs for it
        indefinite = symmetric and not positive and not self._split
        settings = {"mat_mumps_icntl_13": int(indefinite), "mat_mumps_icntl_24": int(indefinite)}
        for key, val in settings.items():
            opts[prefix + key] = val
        ksp = PETSc.KSP().create(comm=PETSc.COMM_WORLD)
        ksp.setOptionsPrefix(prefix)
        ksp.setOperators(self.mat)
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.CHOLESKY if symmetric else PETSc.PC.Type.LU)
        pc.setFactorSolverType("mumps")
        ksp.setFromOptions()
        try:
            ksp.setUp()
        except PETSc.Error as exc:
            raise SolverError(self._mumps_failure(pc, exc)) from None
        finally:
            for key in settings:
                del opts[prefix + key]
        self.ksp = ksp
        self._factor = pc.getFactorMatrix()
        if self._factor.getMumpsInfog(1) < 0:
            raise SolverError(self._mumps_failure(pc, None))
        if indefinite and self._factor.getMumpsInfog(28) > 0:  # null pivots found
            raise SolverError(f"MUMPS found {self._factor.getMumpsInfog(28)} null pivots in {n} equations: the matrix "
                              "is singular (a free body needs a shift)")
        self.memory_per_rank = 1e6 * self._factor.getMumpsInfog(21)
        self.memory_total = 1e6 * self._factor.getMumpsInfog(22)
        self.memory_estimate = self.memory_total
        entries = self._factor.getMumpsInfog(29)
        self.factor_entries = entries if entries >= 0 else -entries * 1e6  # negative: millions
        if indefinite:
            nneg, nzero, npos = self._factor.getInertia()
            if nzero == 0:
                self.inertia = (int(npos), int(nneg))
        log.debug("MUMPS: %d equations, %.0f MB per rank (max), %.0f MB total, %.3g factor entries",
                  n, self.memory_per_rank / 2**20, self.memory_total / 2**20, self.factor_entries)

    def _mumps_failure(self, pc, exc) -> str:
        try:
            code = self._factor_code(pc)
        except Exception:  # noqa: BLE001 - no factor matrix after an early failure
            code = None
        what = _MUMPS_ERRORS.get(code, "") if code is not None else ""
        msg = f"MUMPS factorization of {self._n} equations failed"
        if code is not None:
            msg += f" with INFOG(1) = {code}" + (f": {what}" if what else "")
        elif exc is not None:
            msg += f": {str(exc).strip()}"
        if code in (-6, -10):
            msg += "; the matrix is singular (a free body needs a shift)"
        return msg

    @staticmethod
    def _factor_code(pc) -> int:
        return int(pc.getFactorMatrix().getMumpsInfog(1))

    def _solve_factor(self, b: np.ndarray) -> np.ndarray:
        PETSc = _petsc()
        r0, r1 = self.rows
        k = b.shape[1]
        if k == 0:
            return np.zeros((self.shape[0], 0), dtype=np.result_type(b.dtype, self.dtype))
        if self._split:
            b = np.asarray(b, dtype=np.complex128)
            loc = np.empty((r1 - r0, k))
            half = b[r0 // 2: r1 // 2]
            loc[0::2], loc[1::2] = half.real, half.imag
        else:
            if np.iscomplexobj(b) and not _complex_scalars(PETSc):
                raise SolverError("complex right-hand side for a real PETSc factorization")
            loc = np.asarray(b[r0:r1], dtype=PETSc.ScalarType)
        B = PETSc.Mat().createDense(size=((r1 - r0, self._n), (None, k)), comm=PETSc.COMM_WORLD)
        B.setUp()
        B.getDenseArray()[:, :] = loc
        B.assemble()
        X = B.duplicate()
        self._factor.matSolve(B, X)
        xl = np.array(X.getDenseArray(), order="C")
        B.destroy()
        X.destroy()
        if self._split:
            xl = xl[0::2] - 1j * xl[1::2] if self._sym_form else xl[0::2] + 1j * xl[1::2]
        return dist.allgather_rows(xl, self.shape[0])

    def release(self) -> None:
        """Free the PETSc objects now (collective: call on all ranks)."""
        for name in ("_factor", "ksp", "mat"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
                setattr(self, name, None)


def slepc_eigenmodes(K, M, k: int, F, sigma: float, *, tol: float = 0.0):
    """Eigenpairs of ``K phi = lambda M phi`` nearest above ``sigma`` with SLEPc, reusing ``F``.

    ``F`` is a ``petsc`` factorization of ``K - sigma M``. Returns ``(lam, phi)`` in ascending
    order with ``phi`` replicated on every rank and M-orthonormal (a Rayleigh-Ritz step on the
    converged vectors). ``tol`` is SLEPc's relative residual (0: 1e-10).
    """
    PETSc = _petsc()
    from slepc4py import SLEPc

    n = K.shape[0]
    if F.mat.getSize()[0] != n:
        raise SolverError("the factorization does not belong to K - sigma M")
    r0, r1, mrows = M.local_rows() if dist.is_partitioned(M) else (*F.rows, sp.csr_matrix(M[F.rows[0]:F.rows[1]]))
    if (r0, r1) != tuple(F.rows):
        raise SolverError("M and K - sigma M are partitioned differently over the ranks")
    Mp = petsc_matrix(mrows, n, symmetric=True, positive=True)
    eps = SLEPc.EPS().create(comm=PETSc.COMM_WORLD)
    eps.setOperators(Mp, F.mat)
    positive = F.inertia is None or F.inertia[1] == 0
    eps.setProblemType(SLEPc.EPS.ProblemType.GHEP if positive else SLEPc.EPS.ProblemType.GNHEP)
    eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
    eps.setDimensions(nev=k, ncv=min(n, max(2 * k + 1, k + 32)))
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_REAL)
    eps.setTolerances(tol=tol or 1e-10, max_it=max(100, 10 * k))
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SHIFT)
    st.setShift(0.0)
    st.setKSP(F.ksp)
    eps.solve()
    nconv = eps.getConverged()
    if nconv < k:
        raise ConvergenceError(f"SLEPc Krylov-Schur converged {nconv} of {k} eigenpairs")
    vr = F.mat.createVecRight()
    theta = np.empty(nconv)
    vecs = []
    for i in range(nconv):
        theta[i] = eps.getEigenpair(i, vr).real
        vecs.append(vr.getArray().copy())
    order = np.argsort(-theta)[:k]
    if np.any(theta[order] <= 0):
        raise ConvergenceError(f"SLEPc returned eigenvalues below the shift sigma = {sigma:g}; choose a lower sigma")
    phi = dist.allgather_rows(np.column_stack([vecs[i] for i in order]), n)
    for obj in (eps, Mp, vr):
        obj.destroy()
    # Rayleigh-Ritz on the converged subspace: M-orthonormal vectors also within clusters
    # (SLEPc orthogonalizes in the K - sigma M inner product) and eigenvalues from K and M directly
    import scipy.linalg as sla

    Kr, Mr = phi.T @ (K @ phi), phi.T @ (M @ phi)
    lam, U = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
    return lam, phi @ U
