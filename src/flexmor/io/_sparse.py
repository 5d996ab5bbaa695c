"""Sparse matrices from parsed entries, in linear time and with few temporaries.

Readers build their matrices with :func:`assemble`: the entries as given, or, for the
one-triangle formats (CalculiX, symmetric Matrix Market, one-triangle DMIG and Abaqus), the
stored triangle completed by its mirror image: the triangle and its transpose as CSR, their
rows copied side by side into the result (no sparse addition, so explicit zeros of the file
stay stored; peak memory the triangle twice plus the result).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["assemble", "rows_in_use", "row_blocks"]


def assemble(triplets: list, shape, *, mirror: bool = False) -> sp.csr_matrix | None:
    """Canonical CSR matrix (sorted indices) of ``triplets = [rows, cols, values]`` (0-based).

    Parameters
    ----------
    triplets : list of three ndarrays
        Emptied, so that the caller's arrays are freed as soon as they are used.
    shape : tuple of int
    mirror : bool
        Whether the entries are one triangle (either) of a square symmetric matrix: each
        off-diagonal entry ``(i, j)`` is also stored at ``(j, i)``.

    Returns
    -------
    scipy.sparse.csr_matrix or None
        None when an entry is given twice (the caller names it).
    """
    r, c, v = triplets
    triplets.clear()
    count = r.size
    lower = mirror and bool(np.any(r > c))
    A = sp.coo_matrix((v, (r, c)), shape=shape)
    del r, c, v
    A = A.tocsr()  # sums duplicates: fewer entries tell them
    if A.nnz < count:
        return None
    if not mirror:
        return A
    other = A.T.tocsr()  # the mirror image, as CSR
    return _symmetric(other, A) if lower else _symmetric(A, other)


_BLOCK = 1 << 18  # entries of the result filled at a time


def _symmetric(U: sp.csr_matrix, L: sp.csr_matrix) -> sp.csr_matrix:
    """The symmetric matrix whose upper triangle is ``U`` and lower triangle is ``L = U.T`` (canonical CSR).

    Row ``i`` of the result is row ``i`` of ``L`` without its diagonal (columns below ``i``)
    followed by row ``i`` of ``U``, so the rows are copied block by block in order; the only
    temporaries are masks over a block.
    """
    n = U.shape[0]
    Lp, Up = L.indptr.astype(np.int64), U.indptr.astype(np.int64)
    cnt = np.diff(Lp)
    diag = np.zeros(n, dtype=bool)  # the diagonal entry of a row of L is its last one
    rows = np.flatnonzero(cnt)
    diag[rows] = L.indices[Lp[rows + 1] - 1] == rows
    cnt -= diag
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(cnt + np.diff(Up), out=indptr[1:])
    nnz = int(indptr[-1])
    idx = np.int32 if max(nnz, n) < 2**31 - 1 else np.int64
    indices, data = np.empty(nnz, dtype=idx), np.empty(nnz, dtype=U.data.dtype)
    bounds = np.searchsorted(indptr, np.arange(0, nnz, _BLOCK)).tolist() + [n]
    for r0, r1 in zip(bounds[:-1], bounds[1:]):
        if r0 == r1:
            continue
        a0, a1, u0, u1, l0, l1 = (int(x) for x in (indptr[r0], indptr[r1], Up[r0], Up[r1], Lp[r0], Lp[r1]))
        rows = np.empty((r1 - r0, 2), dtype=np.int64)  # per row: entries from L, then from U (or the diagonal)
        alt = np.zeros(2 * (r1 - r0), dtype=bool)
        alt[1::2] = True
        rows[:, 0] = cnt[r0:r1]
        rows[:, 1] = Up[r0 + 1:r1 + 1] - Up[r0:r1]
        in_u = np.repeat(alt, rows.ravel())
        indices[a0:a1][in_u] = U.indices[u0:u1]
        data[a0:a1][in_u] = U.data[u0:u1]
        rows[:, 1] = diag[r0:r1]
        keep = np.repeat(~alt, rows.ravel())
        np.logical_not(in_u, out=in_u)
        indices[a0:a1][in_u] = L.indices[l0:l1][keep]
        data[a0:a1][in_u] = L.data[l0:l1][keep]
    return sp.csr_matrix((data, indices, indptr.astype(idx)), shape=U.shape)


def rows_in_use(A: sp.csr_matrix) -> np.ndarray:
    """Whether each row of ``A`` has a nonzero entry (without a temporary the size of ``A``)."""
    return (A.max(axis=1).toarray().ravel() != 0) | (A.min(axis=1).toarray().ravel() != 0)


def row_blocks(A: sp.csr_matrix, terms: int = 4_000_000):
    """``(start, stop)`` row ranges of a CSR ``A`` with about ``terms`` stored entries each (at least one
    row): work arrays over one block stay bounded at any size."""
    n, start = A.shape[0], 0
    while start < n:
        stop = min(n, max(start + 1, int(np.searchsorted(A.indptr, A.indptr[start] + terms, side="right")) - 1))
        yield start, stop
        start = stop
