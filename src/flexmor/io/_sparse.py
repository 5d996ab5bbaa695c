"""Sparse matrices from parsed entries, in linear time and with few temporaries.

Readers of one-triangle formats (CalculiX, symmetric Matrix Market, OP4 ``FORM 6``) build
the stored triangle with :func:`triangle_csr` and complete it with :func:`mirror`. Explicit
zeros of the file stay stored: SciPy's sparse addition drops zeros, so they travel as NaN
(the readers refuse non-finite values before, so NaN can only mark a zero).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["triangle_csr", "mirror"]


def triangle_csr(triplets: list, shape) -> sp.csr_matrix:
    """CSR matrix (canonical: sorted, duplicates summed) of ``triplets = [rows, cols, values]``.

    ``triplets`` is emptied so that the caller's arrays are freed as soon as possible;
    explicit zeros are stored as NaN (see :func:`mirror`). Fewer stored entries than given
    means that some were given twice.
    """
    r, c, v = triplets
    triplets.clear()
    zero = v == 0
    if zero.any():
        v = v.copy() if not v.flags.writeable else v
        v[zero] = np.nan
    del zero
    A = sp.coo_matrix((v, (r, c)), shape=shape)
    del r, c, v
    return A.tocsr()


def mirror(T: sp.csr_matrix) -> sp.csr_matrix:
    """The full symmetric matrix of one stored triangle ``T`` (from :func:`triangle_csr`); NaN back to zero."""
    d = T.diagonal()
    A = T + T.T.tocsr()
    del T
    k = np.flatnonzero(d != 0)  # the stored diagonal entries, now doubled (zeros are NaN: also != 0)
    if k.size:
        A[k, k] = d[k]
    A.data[np.isnan(A.data)] = 0.0
    return A
