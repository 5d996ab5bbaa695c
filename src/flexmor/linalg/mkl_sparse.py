"""Sparse times dense through MKL's inspector-executor sparse BLAS (``mkl_sparse_d_mm``).

SciPy's CSR product runs a scalar loop on one thread: ``K V`` of a 35,988-DOF plate (2.15 M
nonzeros) with 174 columns takes 0.109 s, MKL's ``mkl_sparse_d_mm`` on two cores 0.021 s; with
6 columns 5.1 ms against 1.7 ms; 2.3-5.2x on the plate, the cantilever and a C3D10 export
(``bench/sparse_products.py``). The library is the ``libmkl_rt``
that PARDISO comes from (the ``mkl`` wheel of the ``fast`` extra); without it :func:`mkl_product`
returns None and :func:`flexmor.linalg.threads.sparse_dense` takes SciPy's product.

The handle wraps the CSR arrays of the matrix without copying them (zero-based, 32-bit indices,
as SciPy stores matrices below 2^31 nonzeros); it lives for one product. The rows are split
over MKL's threads, each row summed by one thread in the order of its entries, so that the
result is the same in every run; it differs from SciPy's in the last bits only (another order
of the sums over a row's entries).
"""

from __future__ import annotations

import ctypes
import functools
import glob
import logging
import sys

import numpy as np

__all__ = ["mkl_library", "mkl_product", "MKL_MIN_WORK"]

log = logging.getLogger(__name__)

#: Smallest ``nnz(A) * columns`` that goes to MKL (below it SciPy's product takes less than a millisecond).
MKL_MIN_WORK = 1 << 20

_OPERATION_NON_TRANSPOSE = 10
_MATRIX_TYPE_GENERAL = 20
_FILL_MODE_LOWER = 40
_DIAG_NON_UNIT = 50
_INDEX_BASE_ZERO = 0
_LAYOUT_ROW_MAJOR = 101
_LAYOUT_COLUMN_MAJOR = 102


class _Descr(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("mode", ctypes.c_int), ("diag", ctypes.c_int)]


@functools.cache
def mkl_library():
    """``libmkl_rt`` from the environment's ``lib`` folder (where the ``mkl`` wheel that pypardiso
    depends on puts it), else through pypardiso's own search; None without MKL."""
    for path in sorted(glob.glob(f"{sys.prefix}/lib/libmkl_rt.so*"), key=len):
        try:
            return ctypes.CDLL(path)
        except OSError:
            continue
    try:
        import pypardiso
    except ImportError:
        return None
    return pypardiso.ps.libmkl


@functools.cache
def _functions():
    """``(create, mm, destroy)`` typed once, or None without MKL (or an MKL without the sparse BLAS)."""
    lib = mkl_library()
    if lib is None:
        return None
    try:
        create, mm, destroy = lib.mkl_sparse_d_create_csr, lib.mkl_sparse_d_mm, lib.mkl_sparse_destroy
    except AttributeError:
        return None
    vp, ci = ctypes.c_void_p, ctypes.c_int
    create.argtypes = [ctypes.POINTER(vp), ci, ci, ci, vp, vp, vp, vp]
    create.restype = ci
    mm.argtypes = [ci, ctypes.c_double, vp, _Descr, ci, vp, ci, ci, ctypes.c_double, vp, ci]
    mm.restype = ci
    destroy.argtypes = [vp]
    destroy.restype = ci
    return create, mm, destroy


def mkl_product(A, X: np.ndarray) -> np.ndarray | None:
    """``A @ X`` by MKL for a real CSR ``A`` (32-bit indices) and a dense ``X`` (1-D or 2-D, real or
    complex), in ``X``'s memory order (C or Fortran; a complex ``X`` in C order, its real and imaginary
    parts as interleaved real columns); None where MKL or the arguments do not fit (the caller takes
    SciPy's product)."""
    fns = _functions()
    if (fns is None or getattr(A, "format", None) != "csr" or A.dtype != np.float64 or X.ndim not in (1, 2)
            or X.dtype not in (np.float64, np.complex128) or A.shape[1] != X.shape[0]
            or A.indptr.dtype != np.int32 or A.indices.dtype != np.int32 or A.shape[0] == 0):
        return None
    vector = X.ndim == 1
    Y = X.reshape(-1, 1) if vector else X
    if Y.dtype == np.complex128:  # rows of (re, im) pairs: a real matrix acts on both parts alike
        Y = np.ascontiguousarray(Y).view(np.float64)
    if A.nnz * Y.shape[1] < MKL_MIN_WORK or Y.shape[1] == 0:
        return None
    if Y.flags.c_contiguous:
        layout, ld, order = _LAYOUT_ROW_MAJOR, Y.shape[1], "C"
    elif Y.flags.f_contiguous:
        layout, ld, order = _LAYOUT_COLUMN_MAJOR, Y.shape[0], "F"
    else:
        Y = np.ascontiguousarray(Y)
        layout, ld, order = _LAYOUT_ROW_MAJOR, Y.shape[1], "C"
    create, mm, destroy = fns
    m, n = A.shape
    out = np.empty((m, Y.shape[1]), dtype=np.float64, order="C" if order == "C" else "F")
    ldc = out.shape[1] if order == "C" else m
    handle = ctypes.c_void_p()
    ip, ix, data = A.indptr, A.indices, A.data
    if not data.flags.c_contiguous:
        data = np.ascontiguousarray(data)
    status = create(ctypes.byref(handle), _INDEX_BASE_ZERO, m, n, ip.ctypes.data, ip.ctypes.data + ip.itemsize,
                    ix.ctypes.data, data.ctypes.data)
    if status != 0:
        log.debug("mkl_sparse_d_create_csr: status %d", status)
        return None
    try:
        descr = _Descr(_MATRIX_TYPE_GENERAL, _FILL_MODE_LOWER, _DIAG_NON_UNIT)
        status = mm(_OPERATION_NON_TRANSPOSE, 1.0, handle, descr, layout, Y.ctypes.data, Y.shape[1], ld, 0.0,
                    out.ctypes.data, ldc)
    finally:
        destroy(handle)
    if status != 0:
        log.debug("mkl_sparse_d_mm: status %d", status)
        return None
    if X.dtype == np.complex128:
        out = out.view(np.complex128)
    return out[:, 0] if vector else out
