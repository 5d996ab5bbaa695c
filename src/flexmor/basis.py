"""Reduction bases: the :class:`Basis` container and orthonormalization with deflation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Basis", "orthonormalize", "extend_orthonormal", "rank_revealing_qr", "Columns"]


@dataclass
class Basis:
    """A reduction basis ``V`` (n_dof, r) with the method that made it.

    Attributes
    ----------
    V : ndarray, shape (n_dof, r)
        Columns span the reduced space; ``q ≈ V q_r``.
    method : str
        Registered method name.
    info : dict
        Method parameters and diagnostics (JSON-serializable values), e.g. the number of
        rigid-body modes excluded or the interface size.
    reduced : flexmor.projection.ReducedMatrices or None
        The projected matrices of ``V`` when the method computed them already (used by
        :func:`flexmor.projection.project` instead of the sparse products); None otherwise.
    """

    V: np.ndarray
    method: str
    info: dict = field(default_factory=dict)
    reduced: object = field(default=None, repr=False, compare=False)

    @property
    def order(self) -> int:
        return int(self.V.shape[1])


def orthonormalize(V: np.ndarray, M=None, *, tol: float = 1e-10, passes: int = 2) -> np.ndarray:
    """Orthonormalize the columns of ``V`` (w.r.t. ``M`` if given) and drop dependent ones.

    Uses the eigen-decomposition of the Gram matrix ``G = V^T M V`` (a Cholesky-QR variant
    that tolerates rank deficiency), repeated ``passes`` times for full accuracy. Columns
    whose Gram eigenvalue is below ``tol * max`` are deflated, so the result may have fewer
    columns than ``V``. Cost: O(n r^2), BLAS-3.
    """
    X = np.asarray(V, dtype=float)
    for _ in range(passes):
        MX = X if M is None else M @ X
        G = X.T @ MX
        G = 0.5 * (G + G.T)
        w, U = np.linalg.eigh(G)
        if w.size == 0 or w[-1] <= 0:
            return X[:, :0]
        keep = w > tol * w[-1]
        X = X @ (U[:, keep] / np.sqrt(w[keep]))
    return X


def extend_orthonormal(V: np.ndarray | None, X: np.ndarray, *, tol: float = 1e-10) -> np.ndarray:
    """Block Gram-Schmidt step: orthonormal columns spanning the part of ``X`` outside ``span(V)``.

    ``V`` (n, r) must have orthonormal columns (Euclidean; real or complex, then the Hermitian
    inner product is used). The columns of ``X`` are scaled to unit norm, orthogonalized
    against ``V`` twice ("twice is enough"), and factorized by a rank-revealing QR; columns
    whose remaining norm is below ``tol`` (relative to their own norm) are deflated, so the
    result has between 0 and ``X.shape[1]`` columns. A third projection pass keeps the new
    block orthogonal to ``V`` when deflation was close (a kept ``|R_ii| < 1e-3``). Cost: O(n r b) BLAS-3 for a block of
    ``b`` columns.

    Returns
    -------
    ndarray, shape (n, k)
        New orthonormal columns Q, ``Q^H V = 0``, ``Q^H Q = I``.

    References
    ----------
    Giraud, L., Langou, J., Rozloznik, M. (2005). The loss of orthogonality in the
    Gram-Schmidt orthogonalization process. Comput. Math. Appl. 50, 1069-1075.
    """
    X = np.array(X, dtype=np.result_type(X, float if V is None else V, float), copy=True)
    if X.ndim == 1:
        X = X[:, None]
    nrm = np.linalg.norm(X, axis=0)
    X = X[:, nrm > 0] / nrm[nrm > 0]
    if X.shape[1] == 0:
        return X
    has_v = V is not None and V.shape[1] > 0
    for _ in range(2):
        if has_v:
            X -= V @ (V.conj().T @ X)
    Q, R, _ = rank_revealing_qr(X)
    d = np.abs(np.diag(R))
    k = int(np.sum(d > tol))
    Q = Q[:, :k]
    if has_v and k and d[k - 1] < 1e-3:  # nearly dependent: one more pass keeps Q^H V = 0
        Q -= V @ (V.conj().T @ Q)
        Q, _ = np.linalg.qr(Q)
    return Q


def rank_revealing_qr(X: np.ndarray, *, overwrite: bool = False):
    """``X[:, piv] = Q R`` with ``|R_ii|`` non-increasing, for tall ``X`` (n, b), n >> b.

    A Householder QR of the tall block followed by a column-pivoted QR of its small (b, b)
    triangular factor: as rank revealing as a pivoted QR of ``X`` at the cost of an
    unpivoted one (LAPACK's pivoted ``geqp3`` is BLAS-2 bound on tall blocks).
    ``overwrite``: ``Q`` is written into ``X`` (memory of one block less).
    """
    import scipy.linalg as sla

    Q1, R1 = np.linalg.qr(X)
    Q2, R, piv = sla.qr(R1, pivoting=True)
    return np.matmul(Q1, Q2, out=X if overwrite else None), R, piv


class Columns:
    """A growable (n, k) column store: appending costs O(n b), not a copy of all columns.

    Storage is Fortran-ordered with doubling capacity, so :attr:`view` (the first ``k``
    columns) is contiguous for BLAS.
    """

    def __init__(self, n: int, dtype=float, capacity: int = 16):
        self._A = np.empty((n, capacity), dtype=dtype, order="F")
        self.k = 0

    @property
    def view(self) -> np.ndarray:
        return self._A[:, : self.k]

    def append(self, Q: np.ndarray) -> None:
        q = Q.shape[1]
        if self.k + q > self._A.shape[1]:
            A = np.empty((self._A.shape[0], max(2 * self._A.shape[1], self.k + q)), dtype=self._A.dtype, order="F")
            A[:, : self.k] = self.view
            self._A = A
        self._A[:, self.k:self.k + q] = Q
        self.k += q
