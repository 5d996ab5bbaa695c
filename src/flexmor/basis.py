"""Reduction bases: the :class:`Basis` container and orthonormalization with deflation."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from .errors import ModelError

if TYPE_CHECKING:  # projection imports this module
    from .projection import ReducedMatrices

__all__ = ["Basis", "as_basis", "check_rank", "orthonormalize", "extend_orthonormal", "rank_revealing_qr", "Columns"]

#: Method name of a basis given as a plain array.
CUSTOM = "custom"


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
    reduced: ReducedMatrices | None = field(default=None, repr=False, compare=False)

    @property
    def order(self) -> int:
        """Number of columns of ``V``."""
        return int(self.V.shape[1])


def as_basis(basis, n_dof: int) -> Basis:
    """``basis`` as a :class:`Basis` of real, finite columns with ``n_dof`` rows.

    Parameters
    ----------
    basis : Basis or array_like, shape (n_dof, r)
        A plain array (dense or sparse) becomes a Basis of method ``"custom"``. A Basis whose
        ``V`` is a float array already is returned as it is (its ``reduced`` stays valid).
    n_dof : int
        Rows expected (the model's number of equations).

    Returns
    -------
    Basis

    Raises
    ------
    ModelError
        Naming ``basis``: not an array of numbers, not 2-D, a number of rows other than ``n_dof``,
        no column, NaN or Inf, or complex values (whose imaginary part a real projection would
        drop).
    """
    given = basis if isinstance(basis, Basis) else Basis(basis, CUSTOM)
    V = given.V
    if sp.issparse(V):
        V = sp.csr_matrix(V).toarray()
    try:
        A = np.asarray(V)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"basis must be an array of real numbers (n_dof, r): {exc}", params=("basis",)) from None
    if A.dtype.kind == "c":
        if np.any(A.imag != 0):
            raise ModelError("basis is complex; project() needs a real basis: split complex columns into their real "
                             "and imaginary parts, e.g. np.hstack([V.real, V.imag]), and orthonormalize",
                             params=("basis",))
        A = A.real
    if A.dtype.kind not in "fiu":
        raise ModelError(f"basis must be an array of real numbers (n_dof, r), got {type(V).__name__} of "
                         f"dtype {A.dtype}", params=("basis",))
    if A.ndim != 2 or A.shape[0] != n_dof:
        raise ModelError(f"basis has shape {A.shape}, expected ({n_dof}, r): one row per equation of the model",
                         params=("basis",))
    if A.shape[1] == 0:
        raise ModelError(f"basis of method {given.method!r} has no column", params=("basis",))
    A = np.asarray(A, dtype=float)
    if not np.all(np.isfinite(A)):
        bad = np.flatnonzero(~np.all(np.isfinite(A), axis=0))
        raise ModelError(f"basis has NaN or Inf values (in {bad.size} of its {A.shape[1]} columns, the first "
                         f"column {int(bad[0])})", params=("basis",))
    return given if A is given.V else dataclasses.replace(given, V=A)


def check_rank(V: np.ndarray, Mr: np.ndarray | None = None) -> None:
    """Refuse a basis whose columns are linearly dependent (numerically).

    The columns are scaled to unit length first (the test does not depend on their scaling).
    With ``Mr = V^T M V`` given, a well-conditioned ``Mr`` (smallest eigenvalue of the scaled
    ``Mr`` above ``1e-8`` of the largest) proves full rank at no cost; otherwise (a singular
    mass matrix may cause it too) the singular values of the scaled ``V`` decide: rank deficient
    when the smallest is below ``max(n, r) * eps`` of the largest (NumPy's ``matrix_rank``
    tolerance).

    Raises
    ------
    ModelError
        Naming ``basis``: a zero column, or dependent columns with the numerical rank found.
    """
    d = np.sqrt(np.einsum("ij,ij->j", V, V))
    if np.any(d == 0):
        raise ModelError(f"basis has a zero column (column {int(np.flatnonzero(d == 0)[0])})", params=("basis",))
    if Mr is not None:
        w = np.linalg.eigvalsh(Mr / np.outer(d, d))
        if w[-1] > 0 and w[0] > 1e-8 * w[-1]:
            return
    s = np.linalg.svd(V / d, compute_uv=False)
    tol = max(V.shape) * np.finfo(float).eps * s[0]
    if s[-1] <= tol:
        rank = int(np.sum(s > tol))
        raise ModelError(f"basis is rank deficient: its {V.shape[1]} columns span {rank} dimensions (smallest "
                         f"singular value {s[-1] / s[0]:.1e} of the largest, columns scaled to unit length); drop "
                         "the dependent columns, e.g. with flexmor.basis.orthonormalize", params=("basis",))


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
        """The ``k`` columns held, shape (n, k) (a view of the store, not a copy)."""
        return self._A[:, : self.k]

    def append(self, Q: np.ndarray) -> None:
        """Add the columns of ``Q`` (shape (n, q)) after those held, growing the store by doubling."""
        q = Q.shape[1]
        if self.k + q > self._A.shape[1]:
            A = np.empty((self._A.shape[0], max(2 * self._A.shape[1], self.k + q)), dtype=self._A.dtype, order="F")
            A[:, : self.k] = self.view
            self._A = A
        self._A[:, self.k:self.k + q] = Q
        self.k += q
