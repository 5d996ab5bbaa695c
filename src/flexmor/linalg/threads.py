"""Temporarily limit the threads of the OpenBLAS libraries loaded by NumPy and SciPy.

PARDISO runs on MKL's own OpenMP threads; when OpenBLAS's threads run tall-skinny products
between two solves, the two thread pools compete for the same cores (their idle threads
spin), and small BLAS calls slow down by 3-10x on a 2-core machine. The block eigen solver
therefore runs its dense algebra with one OpenBLAS thread (the solves stay multi-threaded).
This is a small stand-in for ``threadpoolctl`` (not a dependency), which does the same.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import logging

__all__ = ["blas_threads"]

log = logging.getLogger(__name__)

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
