"""MPI layout of flexmor runs started with ``mpirun -n P`` (or ``srun``) for the ``petsc`` backend.

flexmor runs SPMD: every rank executes the same program on the same small data (ports,
bases, reduced matrices, frequency grids), while the sparse matrices and their factorizations
are distributed by rows. Two ways of holding a model's matrices are supported:

*replicated*
    Every rank has the whole ``scipy.sparse`` matrix (a model built or read in each process);
    the ``petsc`` backend hands each rank's row block (:func:`row_range`) to PETSc, so the
    factor, which dominates the memory, is distributed.
*partitioned*
    :class:`PartitionedMatrix`: every rank holds only its own rows (zero elsewhere), the matrix
    being the sum of the ranks' pieces. A file model read by rank 0 reaches the other ranks
    this way (:func:`scatter_rows`, :func:`flexmor.models.distributed.read_on_root`). Products
    with dense blocks (``A @ X``, ``X.T @ A``), the diagonal and dense copies are completed by
    an ``MPI_Allreduce``; sums, scalings, transposes and submatrices ``A[i][:, i]`` of
    partitioned matrices stay partitioned. A model built this way
    (:func:`flexmor.models.distributed.partitioned_cantilever`) is never assembled on one rank, and the
    methods above the solver layer run on it unchanged.

Dense blocks (right-hand sides, solutions, bases) are replicated on every rank. Nothing here
imports MPI unless the process was started by an MPI launcher (or a partitioned matrix is made).
"""

from __future__ import annotations

import functools
import logging
import os
import sys
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError

__all__ = [
    "MPILayout",
    "PartitionedMatrix",
    "allgather_rows",
    "allreduce",
    "barrier",
    "comm",
    "end_failed_run",
    "is_partitioned",
    "is_root",
    "launched_by_mpi",
    "layout",
    "on_root",
    "quiet_other_ranks",
    "raise_root_failure",
    "rank",
    "row_blocks",
    "row_range",
    "scatter_rows",
    "several_ranks",
    "size",
]

log = logging.getLogger(__name__)

#: Environment variables set by MPI launchers (Open MPI, MPICH/Hydra, PMIx, Slurm PMI).
_LAUNCHER_VARS = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS", "PMI_RANK")

def launched_by_mpi() -> bool:
    """True if an MPI launcher (mpirun, mpiexec, srun with PMI/PMIx) started this process."""
    return any(v in os.environ for v in _LAUNCHER_VARS)


@functools.cache
def _world():
    from mpi4py import MPI

    return MPI.COMM_WORLD


def comm():
    """The world communicator (mpi4py), or None when mpi4py is missing and no launcher is seen."""
    try:
        return _world()
    except ImportError:
        if launched_by_mpi():
            raise SolverError("this process was started by an MPI launcher but mpi4py is not installed; "
                              "install python3-mpi4py (Debian) or 'pip install flexmor[petsc]'") from None
        return None


def rank() -> int:
    """Rank of this process (0 without MPI; a process not started by a launcher is rank 0 of 1)."""
    return comm().Get_rank() if launched_by_mpi() else 0


def size() -> int:
    """Number of ranks (1 without MPI)."""
    return comm().Get_size() if launched_by_mpi() else 1


@dataclass(frozen=True)
class MPILayout:
    """The ranks of a run: this process' ``rank`` of ``size``, and the row split of matrices over them."""

    rank: int = 0
    size: int = 1

    def row_range(self, n: int) -> tuple[int, int]:
        """Rows ``[start, stop)`` of this rank in PETSc's default split of ``n`` rows (:func:`row_range`)."""
        return row_range(n, self.size, self.rank)


def layout() -> MPILayout:
    """The layout of this process (rank 0 of 1 unless an MPI launcher started it)."""
    return MPILayout(rank(), size())


def is_root() -> bool:
    """True on rank 0 (and in serial runs): the rank that prints and writes files."""
    return rank() == 0


def barrier() -> None:
    """Wait for all ranks (nothing in serial runs)."""
    if size() > 1:
        comm().Barrier()


def on_root(fn, *args, **kwargs):
    """Call ``fn`` on rank 0 only, once every rank has come here (so no rank runs ahead of a file write);
    its result on rank 0, None on the others. An exception ``fn`` raises is raised on every rank
    (:func:`raise_root_failure`): no rank goes on without rank 0."""
    if size() == 1:
        return fn(*args, **kwargs)
    barrier()
    out, failure = None, None
    if is_root():
        try:
            out = fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - raised on every rank just below
            failure = exc
    raise_root_failure(failure)
    return out


def raise_root_failure(failure: Exception | None) -> None:
    """Raise on every rank the exception ``failure`` of rank 0 (ignored on the other ranks): there
    itself, elsewhere one of the same class with the same message. Nothing when rank 0 passes None.
    Collective (one broadcast)."""
    if size() == 1:
        if failure is not None:
            raise failure
        return
    sent = comm().bcast(None if failure is None else (type(failure), str(failure)), root=0)
    if sent is None:
        return
    if is_root() and failure is not None:
        raise failure
    exc = sent[0].__new__(sent[0])
    Exception.__init__(exc, sent[1])
    raise exc


def quiet_other_ranks() -> None:
    """Under MPI with several ranks: only rank 0 prints; the others drop stdout and log errors only."""
    if not launched_by_mpi():
        return
    try:
        if size() == 1 or is_root():
            return
    except SolverError:  # no mpi4py: every process runs alone; the petsc backend says what is missing
        return
    sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - lives as long as the process
    logging.getLogger().setLevel(logging.ERROR)


def several_ranks() -> bool:
    """True in a run of more than one MPI rank (False without a launcher, or without mpi4py)."""
    if not launched_by_mpi():
        return False
    try:
        return size() > 1
    except SolverError:
        return False


#: Seconds a failed rank waits for word that every other rank failed too before it ends the job.
FAIL_WAIT = 5.0
#: Message tag of that word (point-to-point, apart from the collectives any rank may be waiting in).
_FAIL_TAG = 31_415


def end_failed_run(code: int, wait: float = FAIL_WAIT) -> int:
    """The exit code of a rank whose run failed with ``code`` (not 0), once no rank can wait for it.

    Every rank that fails tells all others so, by a point-to-point message, and waits up to
    ``wait`` seconds for the same word from each of them. When it comes (an error every rank
    raised alike, e.g. from :func:`flexmor.models.distributed.read_on_root`) ``code`` is returned
    and each process ends by itself. Otherwise some rank may wait for this one in a collective
    operation forever: the whole job is ended with ``MPI_Abort(code)`` (the launcher then ends
    every rank). One process: ``code`` at once.
    """
    if not several_ranks():
        return code
    from mpi4py import MPI

    c = comm()
    me, n = c.Get_rank(), c.Get_size()
    others = [r for r in range(n) if r != me]
    word = np.array([code], dtype=np.int64)
    heard = [np.zeros(1, dtype=np.int64) for _ in others]
    sends = [c.Isend(word, dest=r, tag=_FAIL_TAG) for r in others]
    recvs = [c.Irecv(buf, source=r, tag=_FAIL_TAG) for buf, r in zip(heard, others)]
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        if MPI.Request.Testall(recvs):
            MPI.Request.Waitall(sends)
            return code
        time.sleep(0.01)
    silent = [r for r, req in zip(others, recvs) if not req.Test()]
    log.info("rank %d of %d failed alone (rank(s) %s did not fail within %g s): ending all ranks (MPI_Abort)",
              me, n, ", ".join(map(str, silent)), wait)
    c.Abort(code)
    return code  # not reached: MPI_Abort ends this process too


def row_range(n: int, nranks: int | None = None, r: int | None = None) -> tuple[int, int]:
    """Rows ``[start, stop)`` of rank ``r`` in PETSc's default split of ``n`` rows over ``nranks``."""
    nranks = size() if nranks is None else nranks
    r = rank() if r is None else r
    base, extra = divmod(n, nranks)
    start = r * base + min(r, extra)
    return start, start + base + (1 if r < extra else 0)


def allreduce(x: np.ndarray) -> np.ndarray:
    """Element-wise sum of ``x`` over all ranks (in place when possible)."""
    c = comm()
    if c is None or c.Get_size() == 1:
        return x
    from mpi4py import MPI

    x = np.ascontiguousarray(x)
    c.Allreduce(MPI.IN_PLACE, x, op=MPI.SUM)
    return x


def allgather_rows(local: np.ndarray, n: int) -> np.ndarray:
    """Stack the ranks' row blocks ``local`` (rank order) into the full ``(n, ...)`` array on every rank."""
    c = comm()
    local = np.ascontiguousarray(local)
    if c is None or c.Get_size() == 1:
        return local
    width = int(np.prod(local.shape[1:], dtype=np.int64))
    counts = np.array(c.allgather(local.shape[0] * width), dtype=np.int64)
    if counts.sum() != n * width:
        raise SolverError(f"row blocks of {counts.sum() // max(width, 1)} rows do not make {n} rows")
    out = np.empty((n, *local.shape[1:]), dtype=local.dtype)
    displs = np.concatenate([[0], np.cumsum(counts)[:-1]])
    from mpi4py import MPI

    c.Allgatherv(local, [out, counts, displs, MPI._typedict[local.dtype.char]])
    return out


def scatter_rows(A, n: int) -> PartitionedMatrix:
    """Rank 0's whole sparse matrix ``A`` (``n`` rows; ignored on the other ranks) as a
    :class:`PartitionedMatrix`: every rank receives only its rows :func:`row_range`, by point-to-point
    messages (no rank but 0 ever holds more). Collective over all ranks."""
    c = comm()
    nranks = 1 if c is None else c.Get_size()
    me = 0 if c is None else c.Get_rank()
    r0, r1 = row_range(n, nranks, me)
    if me == 0:
        A = sp.csr_matrix(A)
        if A.shape[0] != n:
            raise SolverError(f"scatter_rows: the matrix has {A.shape[0]} rows, expected {n}")
        for r in range(1, nranks):
            a, b = row_range(n, nranks, r)
            blk = sp.csr_matrix(A[a:b])
            arrays = (blk.indptr.astype(np.int64), blk.indices.astype(np.int64), blk.data.astype(np.float64))
            c.send((blk.shape, blk.nnz), dest=r, tag=11)
            for k, arr in enumerate(arrays):
                c.Send(np.ascontiguousarray(arr), dest=r, tag=12 + k)
        mine = sp.csr_matrix(A[r0:r1])
        indptr, indices, data, ncols = mine.indptr, mine.indices, mine.data, A.shape[1]
    else:
        (m, ncols), nnz = c.recv(source=0, tag=11)
        indptr, indices, data = np.empty(m + 1, np.int64), np.empty(nnz, np.int64), np.empty(nnz, np.float64)
        for k, arr in enumerate((indptr, indices, data)):
            c.Recv(arr, source=0, tag=12 + k)
    # the local block as rows r0..r1-1 of the global matrix: empty rows above and below
    full = np.concatenate([np.zeros(r0, np.int64), np.asarray(indptr, np.int64),
                           np.full(n - r1, indptr[-1], np.int64)])
    return PartitionedMatrix(sp.csr_matrix((data, indices, full), shape=(n, ncols)))


def row_blocks(A) -> dict:
    """Where the rows of a partitioned matrix ``A`` are: ``{"rows": [[start, stop] per rank],
    "local_nnz": [entries held per rank]}``, the same on every rank (collective)."""
    lo, hi, _ = A.local_rows()
    c = comm()
    spans, nnz = ([(lo, hi)], [int(A.nnz)]) if c is None else (c.allgather((lo, hi)), c.allgather(int(A.nnz)))
    return {"rows": [[int(a), int(b)] for a, b in spans], "local_nnz": nnz}


def is_partitioned(A) -> bool:
    """True for a matrix whose rows are spread over the ranks (:class:`PartitionedMatrix`)."""
    return isinstance(A, PartitionedMatrix)


class PartitionedMatrix:
    """A global sparse matrix of which this rank holds its own rows; the matrix is the sum over ranks.

    Not a SciPy matrix: a small operator type with the operations flexmor's methods apply to a
    model's matrices. Linear operations (sums and differences of partitioned matrices, scalings,
    transposes, submatrices ``A[i][:, i]``, ``abs``, real and imaginary parts) keep the sum
    structure and return partitioned matrices; the operations that need the whole matrix
    (products with dense blocks ``A @ X`` and ``X @ A``, the diagonal, column or row sums,
    ``toarray``) reduce over the ranks, so their results are the same on every rank. Products
    with sparse matrices and sums with replicated or dense ones are refused
    (:class:`~flexmor.errors.SolverError`).

    Parameters
    ----------
    local : scipy.sparse matrix
        Of the global shape, holding this rank's entries only (zero elsewhere).

    Attributes
    ----------
    local : scipy.sparse.csr_matrix
        This rank's piece; ``nnz`` and ``data`` are the local ones.
    """

    #: NumPy defers ``ndarray @ A`` and ``ndarray * A`` to this class (``__rmatmul__``).
    __array_ufunc__ = None

    def __init__(self, local):
        if not sp.issparse(local):
            raise SolverError("a partitioned matrix is made from this rank's sparse piece")
        self.local = sp.csr_matrix(local)

    def __repr__(self) -> str:
        return f"<PartitionedMatrix {self.shape[0]}x{self.shape[1]}, {self.nnz} entries on this rank>"

    # -- properties of the local piece -------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.local.shape

    @property
    def ndim(self) -> int:
        return 2

    @property
    def dtype(self):
        return self.local.dtype

    @property
    def nnz(self) -> int:
        return self.local.nnz

    @property
    def data(self) -> np.ndarray:
        return self.local.data

    def global_nnz(self) -> int:
        """Stored entries summed over the ranks."""
        return int(allreduce(np.array([self.nnz], dtype=np.int64))[0])

    # -- results that stay partitioned --------------------------------------------------------
    def _other(self, other, what: str) -> sp.csr_matrix:
        if isinstance(other, PartitionedMatrix):
            return other.local
        if sp.issparse(other):
            raise SolverError(f"cannot {what} a partitioned and a replicated sparse matrix; "
                              "build all matrices of a distributed model partitioned")
        raise SolverError(f"cannot {what} a partitioned sparse matrix and {type(other).__name__!s}")

    def __add__(self, other):
        return PartitionedMatrix(self.local + self._other(other, "add"))

    __radd__ = __add__

    def __sub__(self, other):
        return PartitionedMatrix(self.local - self._other(other, "subtract"))

    def __rsub__(self, other):
        return PartitionedMatrix(self._other(other, "subtract") - self.local)

    def __mul__(self, alpha):
        if not np.isscalar(alpha):
            raise SolverError("a partitioned matrix is multiplied by scalars only; use @ for products")
        return PartitionedMatrix(self.local * alpha)

    __rmul__ = __mul__

    def __truediv__(self, alpha):
        return self * (1.0 / alpha)

    def __neg__(self):
        return PartitionedMatrix(-self.local)

    def __abs__(self):
        return PartitionedMatrix(abs(self.local))

    @property
    def real(self):
        return PartitionedMatrix(self.local.real)

    @property
    def imag(self):
        return PartitionedMatrix(self.local.imag)

    def astype(self, dtype):
        return PartitionedMatrix(self.local.astype(dtype))

    def copy(self):
        return PartitionedMatrix(self.local.copy())

    def tocsr(self):
        """The matrix itself (its pieces are CSR)."""
        return self

    def transpose(self):
        return PartitionedMatrix(self.local.transpose().tocsr())

    @property
    def T(self):
        return self.transpose()

    def __getitem__(self, key):
        sub = self.local[key]
        if not sp.issparse(sub):
            raise SolverError("single entries of a partitioned matrix are not available; select rows and columns")
        return PartitionedMatrix(sub)

    # -- results reduced over the ranks -------------------------------------------------------
    def __matmul__(self, other):
        if sp.issparse(other) or isinstance(other, PartitionedMatrix):
            raise SolverError("products of a partitioned matrix with sparse matrices are not supported")
        return allreduce(np.asarray(self.local @ np.asarray(other)))

    dot = __matmul__

    def __rmatmul__(self, other):
        if sp.issparse(other):
            raise SolverError("products of a partitioned matrix with sparse matrices are not supported")
        return allreduce(np.asarray(np.asarray(other) @ self.local))

    def diagonal(self, k: int = 0) -> np.ndarray:
        return allreduce(self.local.diagonal(k))

    def sum(self, axis=None):
        """Sum of all entries (a float) or along an axis (an ndarray of shape (1, n) or (n, 1))."""
        if axis is None:
            return float(allreduce(np.array([self.local.sum()]))[0])
        return allreduce(np.asarray(self.local.sum(axis=axis)))

    def toarray(self) -> np.ndarray:
        return allreduce(self.local.toarray())

    def local_rows(self) -> tuple[int, int, sp.csr_matrix]:
        """``(start, stop, rows)``: the contiguous block of rows held here, as a plain CSR of shape
        ``(stop - start, n)``. Raises :class:`SolverError` if this rank's rows are not one block
        following those of the previous rank (e.g. a transposed partitioned matrix)."""
        n = self.shape[0]
        filled = np.flatnonzero(np.diff(self.local.indptr))
        lo, hi = (int(filled[0]), int(filled[-1]) + 1) if filled.size else (-1, -1)
        c = comm()
        spans = [(lo, hi)] if c is None else c.allgather((lo, hi))
        start = 0
        for r, (a, b) in enumerate(spans):
            if a < 0:
                continue
            if a != start:
                raise SolverError(f"rank {r} holds rows {a}..{b - 1}, but its block should start at row {start}: "
                                  "the partitioned matrix is not a row partition in rank order")
            start = b
        if start != n:
            raise SolverError(f"the ranks hold rows 0..{start - 1} of a matrix with {n} rows")
        me = 0 if c is None else c.Get_rank()
        first = 0
        for a, b in spans[:me]:
            if a >= 0:
                first = b
        lo, hi = (lo, hi) if lo >= 0 else (first, first)
        return lo, hi, sp.csr_matrix(self.local[lo:hi])
