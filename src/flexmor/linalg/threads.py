"""Temporarily limit the threads of the OpenBLAS libraries loaded by NumPy and SciPy, or MKL's.

PARDISO runs on MKL's own OpenMP threads, the dense products between two solves on OpenBLAS's.
Idle OpenBLAS workers spin (calling ``sched_yield``) for ``2^28`` cycles, about 0.1 s, before they
sleep: between two solves they took the cores from the solver's threads (30 solves of a 35,988-DOF
plate with a ``V^T X`` of 174 columns before each: 0.72 s instead of 0.36 s on two cores) and,
beside a CPU-bound process, the products' own threads (a ``V^T X`` of 33,735 x 174: 1.0 s instead
of 0.07 s). When this module is imported, every OpenBLAS library loaded lets its idle workers
sleep after ``2^10`` cycles (``OPENBLAS_THREAD_TIMEOUT``, :data:`BLAS_TIMEOUT`, unless the user
set it; :func:`_quick_sleep`). Then the tall-skinny products of a reduction run on all cores
(:func:`dense_threads`, from 16 MB; memory-bound, 1.7x faster on two cores) without slowing the solves; where
the workers keep spinning (a user's timeout above :data:`QUICK_TIMEOUT`, or another thread was
running when flexmor was imported) they run on one thread, as before. :func:`blas_threads` is a
small stand-in for ``threadpoolctl`` (not a dependency), which does the same.

:func:`mkl_threads` sets MKL's thread count of the calling thread (PARDISO's solves): a loop of
thousands of small solves, each followed by Python-side products, runs them faster on one
thread, since MKL's idle OpenMP workers spin between solves and take the core the products need.

:func:`sparse_dense` is the sparse-times-dense product: MKL's sparse BLAS on MKL's threads where MKL
is installed (:mod:`flexmor.linalg.mkl_sparse`, 2.3-5.2x SciPy's), else SciPy's (single-threaded,
without the GIL) with the rows split over Python threads, one per CPU this process may use.

The threads are chosen per operation, not per machine load: the dense algebra of a reduction, of
the block eigen solver and of the full FRF's sweep (:func:`flexmor.reduction.reduce`,
:class:`flexmor.analysis.compare.FullResponse`) runs on one OpenBLAS thread, except the large
tall-skinny products of the Krylov basis and the projection (:func:`dense_threads`): beside a
CPU-bound process two threads made the many small and medium products of the Gramian methods up
to 1.3x slower than one (``bench/around_methods.py --parts busy``), for no gain on an idle machine.
The sparse factorizations, solves and products run on all cores (MKL, or rows split over threads in
:func:`sparse_dense`): a thread that shares its core then delays the product by about its share.

MKL's OpenMP workers sleep at once after a parallel region (``KMP_BLOCKTIME=0`` unless set
otherwise before MKL loads) instead of spinning for 200 ms (Intel's default) on the cores that
the Python-side products between two solves, or another process, need: beside one CPU-bound
process a parallel phase then costs its share of the cores, not the time its workers spin.
The thread counts stay fixed (not chosen from the machine's load), so that a reduction gives the
same bytes in every run.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import logging
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg  # noqa: F401 - its OpenBLAS loaded before _handles() looks
import scipy.sparse as sp

__all__ = ["blas_threads", "dense_threads", "mkl_threads", "blas_thread_count", "blas_idle_sleeps", "sparse_dense",
           "cores"]

log = logging.getLogger(__name__)

_USER_ENV = frozenset(k for k in ("OPENBLAS_THREAD_TIMEOUT",) if k in os.environ)  # as the user started us

# MKL's OpenMP workers: sleep after a parallel region (read when MKL loads; a user's setting stays)
os.environ.setdefault("KMP_BLOCKTIME", "0")

#: ``OPENBLAS_THREAD_TIMEOUT`` flexmor sets unless the user did: OpenBLAS's idle workers wait ``2^10`` cycles
#: (below a microsecond) before they sleep, instead of ``2^28`` (~0.1 s of ``sched_yield`` calls).
BLAS_TIMEOUT = 10
#: Largest timeout (log2 of cycles) at which :func:`dense_threads` runs the tall-skinny products on all cores.
QUICK_TIMEOUT = 16
#: Entries of a tall factor (16 MB of doubles, ~3 ms of one core's memory bandwidth) from which
#: :func:`dense_threads` gives it all cores.
DENSE_PARALLEL_MIN = 1 << 21

_SYMBOLS = (("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
            ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
            ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
            ("openblas_set_num_threads", "openblas_get_num_threads"))


def _quick_sleep(lib) -> int:
    """Let the idle workers of one OpenBLAS library sleep after :data:`BLAS_TIMEOUT`: the timeout it read
    (log2 of cycles; 0: OpenBLAS's default of 28). The library reads ``OPENBLAS_THREAD_TIMEOUT`` when it
    loads (with NumPy, usually before flexmor); where neither the user nor :mod:`flexmor` had set it then,
    it reads it again and its workers stop, to start with the new timeout at the next parallel call. Only
    while this is the process's one Python thread (no other can be inside BLAS)."""
    try:
        get = lib.openblas_thread_timeout
        timeout = int(get())
        if timeout == 0 and threading.active_count() == 1 and "OPENBLAS_THREAD_TIMEOUT" not in _USER_ENV:
            os.environ["OPENBLAS_THREAD_TIMEOUT"] = str(BLAS_TIMEOUT)
            lib.openblas_read_env()
            lib.blas_thread_shutdown_()
            timeout = int(get())
        return timeout
    except (AttributeError, OSError):
        return 0


@functools.cache
def _handles() -> tuple:
    """``(set, get)`` thread-count functions of the OpenBLAS libraries loaded (found once per process);
    their idle workers sleep quickly (:func:`_quick_sleep`)."""
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower() and ".so" in ln})
    except OSError:
        paths = []
    handles = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _SYMBOLS:
            if hasattr(lib, set_name) and hasattr(lib, get_name):
                handles.append((getattr(lib, set_name), getattr(lib, get_name)))
                _TIMEOUTS.append(_quick_sleep(lib))
                break
    return tuple(handles)


_TIMEOUTS: list[int] = []  # per OpenBLAS library of _handles(): the timeout its workers use (0: 28)


def blas_idle_sleeps() -> bool:
    """Whether the idle workers of every OpenBLAS library loaded sleep within ``2^QUICK_TIMEOUT`` cycles."""
    _handles()
    return bool(_TIMEOUTS) and all(0 < t <= QUICK_TIMEOUT for t in _TIMEOUTS)


def dense_threads(entries: int) -> int:
    """OpenBLAS threads for a tall-skinny product that reads ``entries`` numbers of its tall factor (``V^T X``,
    ``V h`` of an ``n x r`` basis between two solves): all cores of the process (:func:`cores`) where idle
    workers sleep at once (:func:`blas_idle_sleeps`) and the factor has :data:`DENSE_PARALLEL_MIN` entries or
    more, else one. Memory-bound, such a product gains 1.7x from two threads on two cores; a smaller one
    gains less than waking a worker costs beside a CPU-bound process (its scheduling delay of up to a few
    milliseconds per call). With workers that spin (OpenBLAS's default) a second thread slowed the solver's
    threads between the products by 2x. The count depends on the machine and the sizes, not the load."""
    if int(entries) < DENSE_PARALLEL_MIN:
        return 1
    return cores() if blas_idle_sleeps() else 1


@contextlib.contextmanager
def blas_threads(n: int = 1):
    """Context manager: at most ``n`` OpenBLAS threads inside, the previous counts restored after."""
    saved = []
    for set_fn, get_fn in _handles():
        try:
            saved.append((set_fn, int(get_fn())))
            set_fn(int(n))
        except Exception:  # noqa: BLE001 - foreign library, never fail the computation
            log.debug("could not set the OpenBLAS thread count")
    try:
        yield
    finally:
        for set_fn, count in saved:
            set_fn(count)


def blas_thread_count() -> int:
    """Threads the (first) OpenBLAS library loaded may use now; 1 when none is found."""
    for _, get_fn in _handles():
        try:
            return max(int(get_fn()), 1)
        except Exception:  # noqa: BLE001 - foreign library
            continue
    return 1


def sparse_dense(A, X: np.ndarray, threads: int | None = None) -> np.ndarray:
    """``A @ X`` for a sparse ``A`` and a dense ``X``: by MKL's sparse BLAS, else with the rows of a CSR ``A``
    split over ``threads``.

    Without ``threads``, a real CSR ``A`` goes to :func:`flexmor.linalg.mkl_sparse.mkl_product` where MKL is
    installed (the result in ``X``'s memory order, the same in every run, SciPy's up to the order of each
    row's sums). Else one or two columns go column by column through SciPy's one-vector kernel; more, and
any with ``threads`` given: SciPy's product runs on one thread and releases the GIL,
    so row blocks of ``A`` multiply in parallel Python threads, each writing its rows of the result (the
    same sums in the same order as ``A @ X``). ``threads`` defaults to the CPUs this process may use
    (:func:`cores`); one thread, a small product or a matrix that is not CSR is plain ``A @ X``. ``X``
    should be row-major there (SciPy copies other layouts).
    """
    if threads is None:  # MKL's sparse BLAS where it is there (flexmor.linalg.mkl_sparse)
        from .mkl_sparse import mkl_product

        Y = mkl_product(A, X)
        if Y is not None:
            return Y
    if threads is None and sp.issparse(A) and X.ndim == 2 and X.shape[1] <= 2:
        # one or two columns: SciPy's one-vector kernel column by column (about twice as fast as its
        # multi-vector kernel at two columns, the same at four)
        return np.column_stack([A @ X[:, j] for j in range(X.shape[1])])
    threads = cores() if threads is None else max(int(threads), 1)
    n = A.shape[0]
    if threads == 1 or getattr(A, "format", None) != "csr" or X.ndim != 2 or A.nnz * X.shape[1] < 1 << 22:
        return A @ X
    cuts = np.searchsorted(A.indptr, np.linspace(0, A.nnz, threads + 1)[1:-1])  # equal shares of nonzeros
    bounds = np.concatenate([[0], cuts, [n]])
    out = np.empty((n, X.shape[1]), dtype=np.result_type(A.dtype, X.dtype))

    def rows(i):
        a, b = bounds[i], bounds[i + 1]
        if b > a:  # the row block as views of A's arrays (slicing A would copy them)
            p0, p1 = A.indptr[a], A.indptr[b]
            part = sp.csr_matrix((A.data[p0:p1], A.indices[p0:p1], A.indptr[a:b + 1] - p0), shape=(b - a, A.shape[1]))
            out[a:b] = part @ X

    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(rows, range(threads)))
    return out


_MKL_SET_LOCAL: list[Callable[[int], int]] = []


def _mkl_set_local():
    """MKL's ``MKL_Set_Num_Threads_Local`` (by value; returns the previous local count), or None
    while no MKL library is loaded (looked up again on the next call until found)."""
    if _MKL_SET_LOCAL:
        return _MKL_SET_LOCAL[0]
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "libmkl_rt" in ln and ".so" in ln})
    except OSError:
        paths = []
    for path in paths:
        try:
            fn = ctypes.CDLL(path).MKL_Set_Num_Threads_Local
        except (OSError, AttributeError):
            continue
        fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
        _MKL_SET_LOCAL.append(fn)
        return fn
    return None


@contextlib.contextmanager
def mkl_threads(n: int = 1):
    """Context manager: at most ``n`` MKL threads for the calling thread inside, its previous count after.

    Does nothing where MKL is not loaded (e.g. no PARDISO factorization yet, or another backend).
    """
    fn = _mkl_set_local()
    prev = None
    if fn is not None:
        try:
            prev = int(fn(int(n)))
        except Exception:  # noqa: BLE001 - foreign library, never fail the computation
            log.debug("could not set the MKL thread count")
    try:
        yield
    finally:
        if prev is not None:
            fn(prev)


def cores() -> int:
    """CPUs this process may run on (its affinity), at least 1."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):
        return max(os.cpu_count() or 1, 1)


_handles()  # at import (the process's one Python thread, as a rule): idle OpenBLAS workers sleep quickly
