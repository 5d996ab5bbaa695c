"""Temporarily limit the threads of the OpenBLAS libraries loaded by NumPy and SciPy, or MKL's.

PARDISO runs on MKL's own OpenMP threads; when OpenBLAS's threads run tall-skinny products
between two solves, the two thread pools compete for the same cores (their idle threads
spin), and small BLAS calls slow down by 3-10x on a 2-core machine. The block eigen solver
therefore runs its dense algebra with one OpenBLAS thread (the solves stay multi-threaded).
This is a small stand-in for ``threadpoolctl`` (not a dependency), which does the same.

:func:`mkl_threads` sets MKL's thread count of the calling thread (PARDISO's solves): a loop of
thousands of small solves, each followed by Python-side products, runs them faster on one
thread, since MKL's idle OpenMP workers spin between solves and take the core the products need.

:func:`sparse_dense` is SciPy's sparse-times-dense product (single-threaded, without the GIL) with
the rows split over Python threads, one per CPU this process may use.

The threads are chosen per kind of operation, not per machine load: the dense products of a
reduction and of the full FRF's sweep (:func:`flexmor.reduction.reduce`,
:class:`flexmor.analysis.compare.FullResponse`) are tall-skinny (``n x r``) or small (``r x r``),
memory-bound, and run on one OpenBLAS thread: two threads gain at most 2x on an idle machine,
but beside a CPU-bound process their spin-waits made a ``V^T X`` of 33,735 x 174 take 1.0 s
instead of 0.07 s. The sparse factorizations and solves run on all cores (MKL), the sparse
products split their rows (:func:`sparse_dense`): a thread that shares its core then delays the
product by at most its share.

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
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

__all__ = ["blas_threads", "mkl_threads", "blas_thread_count", "sparse_dense", "cores"]

log = logging.getLogger(__name__)

# MKL's OpenMP workers: sleep after a parallel region (read when MKL loads; a user's setting stays)
os.environ.setdefault("KMP_BLOCKTIME", "0")

_SYMBOLS = (("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
            ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
            ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
            ("openblas_set_num_threads", "openblas_get_num_threads"))
@functools.cache
def _handles() -> tuple:
    """``(set, get)`` thread-count functions of the OpenBLAS libraries loaded (found once per process)."""
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
                break
    return tuple(handles)


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
    """``A @ X`` for a sparse ``A`` and a dense block ``X``, the rows of a CSR ``A`` split over ``threads``.

    SciPy's product runs on one thread and releases the GIL, so row blocks of ``A`` multiply in
    parallel Python threads, each writing its rows of the result (the same sums in the same order
    as ``A @ X``). ``threads`` defaults to the CPUs this process may use (:func:`cores`); one thread,
    a small product or a matrix that is not CSR is plain ``A @ X``. ``X`` should be row-major (SciPy
    copies other layouts).
    """
    threads = cores() if threads is None else max(int(threads), 1)
    n = A.shape[0]
    if threads == 1 or A.format != "csr" or X.ndim != 2 or A.nnz * X.shape[1] < 1 << 22:
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
