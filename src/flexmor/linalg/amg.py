"""The ``amg`` backend: smoothed-aggregation algebraic multigrid preconditioning block conjugate gradients.

Where no sparse direct factor fits into memory (a 3D solid of several million DOF: the factor grows
like ``n^(4/3)``), a real symmetric positive definite matrix ``A`` (``K - sigma M`` with
``sigma <= 0``, a clamped ``K``, an interior block ``K_ii``) is solved iteratively instead: a
smoothed-aggregation AMG hierarchy (*pyamg*, ``pip install flexmor[amg]``; memory proportional to
``nnz(A)``) is set up once in place of the factorization, and each block of right-hand sides is
solved by block conjugate gradients with one symmetric V-cycle per column as preconditioner, to the
relative residual ``||b - A x|| / ||b|| <= solve_tol`` of every column
(:attr:`~flexmor.linalg.context.SolverContext.solve_tol`, default :data:`SOLVE_TOL`).

Near-null space: aggregation-based AMG for elasticity needs the rigid-body motions of the
geometry (six per body in 3D) as the vectors its coarse spaces must represent; without them the
coarse spaces carry translations only and CG needs several times the iterations. Whoever knows
the model registers them (:func:`flexmor.rigid.register_near_null`; rows of a sub-matrix with
:func:`register_rows`); a matrix of a size nothing was registered for gets the constant vector
(logged). They change the iteration count, not the solution.

Block CG: the breakdown-free variant of Ji & Li (2017): the preconditioned residual block is
A-orthogonalized against the last search block and A-orthonormalized within itself by an
eigen-decomposition of its Gram matrix, which drops directions that have become dependent (columns
that converged drop out of the block); the search blocks share one Krylov space, so ``k`` right-hand
sides need fewer iterations each than ``k`` separate CG runs. A Gram matrix with a negative
eigenvalue proves ``A`` indefinite: refused with a :class:`~flexmor.errors.SolverError`.

References
----------
Vaněk, P., Mandel, J., Brezina, M. (1996). Algebraic multigrid by smoothed aggregation for second
and fourth order elliptic problems. Computing 56, 179-196.
O'Leary, D. P. (1980). The block conjugate gradient algorithm and related methods. Linear Algebra
Appl. 29, 293-322.
Ji, H., Li, Y. (2017). A breakdown-free block conjugate gradient method. BIT Numer. Math. 57, 379-403.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, SolverError
from .factorization import Factorization
from .memory import SOLVE_TOL, matrix_bytes, norm_bound
from .threads import sparse_dense

__all__ = ["SOLVE_TOL", "MAX_ITER", "AmgSolver", "NearNull", "register_near_null", "register_rows", "node_block",
           "near_null", "block_cg", "amg_estimate"]

log = logging.getLogger(__name__)

#: Most block CG iterations of one solve.
MAX_ITER = 1000

#: Coarsest level of the hierarchy: at most this many nodes (blocks of equations), solved by a dense Cholesky
#: factor computed once (pyamg counts the coarse size in blocks: six equations per aggregate below the first level).
MAX_COARSE = 150

#: Operator complexity (entries of all levels over those of ``A``) assumed by :func:`amg_estimate`:
#: measured 1.3-1.5 on 3D hexahedral solids with the six rigid-body modes (``bench/amg.py``).
OPERATOR_COMPLEXITY = 1.6


@dataclass(frozen=True)
class NearNull:
    """The near-null space of the matrices of one size: the rigid-body motions ``B`` (n, k) and the
    number of equations per node when every node's equations are consecutive and alike (3 for a solid,
    6 for shells and beams; 1 otherwise), for a hierarchy on node blocks."""

    B: np.ndarray
    block: int = 1


def register_near_null(solver, n: int, make) -> None:
    """Register ``make() -> NearNull | None`` as the near-null space of the matrices of ``n`` equations in
    ``solver`` (called once, when the ``amg`` backend first asks; :func:`flexmor.rigid.register_near_null`
    registers a model's rigid motions). One registered for ``n`` already is kept (and so is its vectors, once
    computed): the callers of one computation register the same model again."""
    solver.near_null.setdefault(n, make)


def register_rows(solver, n: int, rows: np.ndarray) -> None:
    """Register the near-null space of the sub-matrix on ``rows`` of the ``n``-equation matrices whose
    near-null space ``solver`` knows (the interior of an interface, the free rows of a held model)."""
    rows = np.asarray(rows)
    if n not in solver.near_null or rows.size == n:
        return

    def make() -> NearNull | None:
        full = near_null(solver, n)
        if full is None:
            return None
        block = full.block
        if block > 1 and not (rows.size % block == 0 and np.all(rows[::block] % block == 0)
                              and np.all(np.diff(rows.reshape(-1, block), axis=1) == 1)):
            block = 1  # (whole nodes, each with all its equations)
        return NearNull(full.B[rows], block)

    solver.near_null[rows.size] = make


def near_null(solver, n: int) -> NearNull | None:
    """The near-null space registered for matrices of ``n`` equations (computed once), or None."""
    got = solver.near_null.get(n)
    if callable(got):
        got = solver.near_null[n] = got()
    return got


def node_block(dofs: np.ndarray) -> int:
    """3 or 6 when the equations come node by node with the same directions 1..3 (1..6), else 1."""
    for b in (6, 3):
        if dofs.shape[0] % b == 0:
            d = dofs.reshape(-1, b, 2)
            if np.all(d[:, :, 1] == np.arange(1, b + 1)) and np.all(d[:, :, 0] == d[:, :1, 0]):
                return b
    return 1


def amg_estimate(n: int, nnz: int, columns: int, *, block: int = 3) -> float:
    """Bytes an AMG hierarchy of a matrix with ``n`` equations and ``nnz`` entries and a block CG solve of
    ``columns`` right-hand sides need: the levels (:data:`OPERATOR_COMPLEXITY` times the matrix in CSR,
    12 bytes per entry), the smoothed prolongators (taken as half the matrix' entries over the equations
    per node), and ten blocks of ``n`` x ``columns`` in the iteration (block CG's and the V-cycles')."""
    levels = OPERATOR_COMPLEXITY * (12.0 * nnz + 4.0 * n)
    prolong = 0.5 * 12.0 * nnz / max(block, 1)
    return levels + prolong + 10.0 * 8.0 * n * max(columns, 1)


#: The refusal of a matrix that is not positive definite.
INDEFINITE = ("the matrix is not positive definite ({where}): backend 'amg' needs K - sigma M with sigma below "
              "the lowest eigenvalue (a supported body, or a free body with a negative shift)")


class AmgSolver(Factorization):
    """A smoothed-aggregation AMG hierarchy of a real symmetric positive definite matrix; :meth:`solve`
    runs block CG to the relative residual ``solver.solve_tol`` of every column.

    Attributes
    ----------
    levels : int
        Levels of the hierarchy.
    operator_complexity : float
        Entries of all levels' matrices over those of ``A``.
    near_null : str
        Which near-null space the hierarchy was built on (rigid-body motions or the constant).
    """

    backend = "amg"

    def __init__(self, A, solver, *, symmetric=True, positive=False):
        super().__init__(A, solver.stats)
        try:
            import pyamg
        except ImportError:
            raise SolverError("backend 'amg' needs pyamg (pip install 'flexmor[amg]')",
                              params=("backend",)) from None
        if np.iscomplexobj(A.data) or not symmetric:
            raise SolverError("backend 'amg' solves real symmetric positive definite matrices only (K - sigma M, "
                              "sigma <= 0), not a complex or unsymmetric one such as K - w^2 M + i w D: take "
                              "real expansion points (e.g. --points 0), or a direct backend for this step",
                              params=("backend",))
        self.dtype = np.dtype(np.float64)
        A = sp.csr_matrix(A, dtype=np.float64)
        A.sum_duplicates()
        n = A.shape[0]
        nn = near_null(solver, n)
        if nn is not None:
            B, block, self.near_null = nn.B, nn.block, f"{nn.B.shape[1]} rigid-body motions of the geometry"
        else:
            B, block, self.near_null = np.ones((n, 1)), 1, "the constant (no geometry registered)"
            log.info("amg: no near-null space registered for %d equations; the constant vector is used", n)
        # scaled so that every column has the norm of the constant: the rotations are lengths (m)
        B = np.asarray(B, float) / np.maximum(np.linalg.norm(B, axis=0), 1e-300) * np.sqrt(n)
        M = sp.bsr_matrix(A, blocksize=(block, block)) if block > 1 else A  # (freed with the hierarchy)
        t0 = time.perf_counter()
        self._ml = pyamg.smoothed_aggregation_solver(
            M, B=B, symmetry="symmetric", strength=("symmetric", {"theta": 0.0}), max_coarse=MAX_COARSE,
            keep=False)
        try:
            self._cycle = BlockCycle(self._ml, A)
        except np.linalg.LinAlgError:
            raise SolverError(INDEFINITE.format(where="its coarsest level has no Cholesky factor"),
                              params=("backend",)) from None
        del self._ml  # (its levels live on in the cycle, in CSR)
        self.levels = len(self._cycle.A)
        self.operator_complexity = sum(a.nnz for a in self._cycle.A) / max(A.nnz, 1)
        self.setup_seconds = time.perf_counter() - t0
        self._A = None  # (no refinement: the iteration itself solves to the tolerance)
        self._anorm = norm_bound(A)
        self._tol = float(solver.solve_tol)
        self._positive = bool(positive)
        self.memory_estimate = self.operator_complexity * matrix_bytes(A)
        stats = solver.stats
        stats.iterative += 1
        stats.iterative_tol = self._tol
        stats.iterative_backend = self.backend
        log.info("amg: %d levels, operator complexity %.2f, near-null space %s, set up in %.2f s",
                 self.levels, self.operator_complexity, self.near_null, self.setup_seconds)

    @property
    def matrix(self):
        """The matrix the hierarchy was set up for, in CSR (the finest level's)."""
        return self._cycle.A[0]

    def precondition(self, R: np.ndarray) -> np.ndarray:
        """One V-cycle applied to the block ``R``: a symmetric positive definite approximation of ``A^-1 R``."""
        return self._cycle(R)

    def _solve_factor(self, b: np.ndarray) -> np.ndarray:
        try:
            X, its, res = block_cg(self._cycle.A[0], b, self.precondition, tol=self._tol, anorm=self._anorm)
        except ConvergenceError as exc:
            if self._positive:
                raise
            raise ConvergenceError(f"{exc}; the matrix was not known to be positive definite, and block CG does not "
                                   f"converge on an indefinite one: backend 'amg' needs K - sigma M with sigma below "
                                   f"the lowest eigenvalue", result=exc.result, params=("backend",)) from None
        st = self.stats
        st.iterations += its
        st.iterations_max = max(st.iterations_max, its)
        st.iterative_residual = max(st.iterative_residual, res)
        return X


class BlockCycle:
    """One symmetric V-cycle of an AMG hierarchy applied to a block of vectors at once.

    Each level is smoothed by a Chebyshev polynomial of degree :data:`CHEBYSHEV_DEGREE` in the
    Jacobi-scaled matrix ``D^-1 A`` on ``[lmax / CHEBYSHEV_RATIO, 1.05 lmax]`` (``lmax`` from
    :data:`LANCZOS_STEPS` Lanczos steps), the same polynomial before and after the coarse correction
    (so the cycle is a symmetric operator), the coarsest level by a dense Cholesky factor. Every step is
    a sparse product with the whole block (all columns in one pass over the matrix): the cycle is bound
    by the memory bandwidth of reading the levels' matrices, once per product, not per column.

    Parameters
    ----------
    ml : pyamg MultilevelSolver
        Its levels' ``A``, ``P`` and ``R``.
    finest : sparse matrix
        The finest level's matrix in CSR (the hierarchy's own copy, in node blocks, is not kept).
    """

    def __init__(self, ml, finest):
        import scipy.linalg as sla

        lv = ml.levels
        self.A = [finest] + [sp.csr_matrix(level.A) for level in lv[1:]]
        self.P = [sp.csr_matrix(level.P) for level in lv[:-1]]
        self.R = [sp.csr_matrix(level.R) for level in lv[:-1]]
        self.dinv = [1.0 / a.diagonal() for a in self.A[:-1]]
        self.lmax = [1.05 * _lanczos_max(a, d) for a, d in zip(self.A[:-1], self.dinv)]
        self.coarse = sla.cho_factor(self.A[-1].toarray())

    def __call__(self, B: np.ndarray) -> np.ndarray:
        B = np.asarray(B, float)
        if B.ndim < 2 or B.shape[1] <= CYCLE_COLUMNS:
            return self._cycle(0, B)
        out = np.empty_like(B)  # column groups: the temporaries of the levels for one group at a time
        for j in range(0, B.shape[1], CYCLE_COLUMNS):
            out[:, j:j + CYCLE_COLUMNS] = self._cycle(0, np.ascontiguousarray(B[:, j:j + CYCLE_COLUMNS]))
        return out

    def _cycle(self, i: int, b: np.ndarray) -> np.ndarray:
        import scipy.linalg as sla

        if i == len(self.A) - 1:
            return sla.cho_solve(self.coarse, b)
        A = self.A[i]
        x = self._smooth(i, b, None)
        r = sparse_dense(A, x)
        np.subtract(b, r, out=r)
        x += sparse_dense(self.P[i], self._cycle(i + 1, sparse_dense(self.R[i], r)))
        del r
        return self._smooth(i, b, x)

    def _smooth(self, i: int, b: np.ndarray, x) -> np.ndarray:
        """Chebyshev smoothing of ``A x = b`` from ``x`` (None: zero), Saad (2003), algorithm 12.1; in place
        where it can (the blocks are as large as the level, each temporary a pass over memory)."""
        A, dinv, hi = self.A[i], self.dinv[i][:, None], self.lmax[i]
        lo = hi / CHEBYSHEV_RATIO
        theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
        sigma = theta / delta
        rho = 1.0 / sigma
        if x is None:
            r = b  # (not written to: the first update below makes a new residual)
        else:
            r = sparse_dense(A, x)
            np.subtract(b, r, out=r)
        d = r * (dinv / theta)
        if x is None:
            x = d.copy()
        else:
            x += d
        for _ in range(CHEBYSHEV_DEGREE - 1):
            Ad = sparse_dense(A, d)
            if r is b:
                r = np.subtract(b, Ad, out=Ad)
            else:
                r -= Ad
            del Ad
            rho_new = 1.0 / (2.0 * sigma - rho)
            d *= rho_new * rho
            d += r * (dinv * (2.0 * rho_new / delta))
            rho = rho_new
            x += d
        return x


#: Degree of the Chebyshev smoother of :class:`BlockCycle` (products with a level's matrix per smoothing).
CHEBYSHEV_DEGREE = 2

#: Most columns :class:`BlockCycle` takes through the levels at once; a wider block goes in groups. The cycle
#: holds about five blocks of the finest level's size (1.2 GB each for 48 columns at 3 M DOF), and a sparse
#: product costs about the same per column from six columns on (the matrix read once per product is a small
#: part of the traffic beside the block's), so groups bound the memory at no cost in time.
CYCLE_COLUMNS = 16

#: The smoother damps the eigenvalues of ``D^-1 A`` in ``[lmax / CHEBYSHEV_RATIO, lmax]`` (the upper part
#: of the spectrum, the one the coarse levels do not represent).
CHEBYSHEV_RATIO = 30.0

#: Lanczos steps for the largest eigenvalue of ``D^-1 A`` on each level.
LANCZOS_STEPS = 15


def _lanczos_max(A, dinv: np.ndarray) -> float:
    """The largest eigenvalue of ``D^-1 A`` (the largest Ritz value of :data:`LANCZOS_STEPS` Lanczos steps on
    the symmetric ``D^-1/2 A D^-1/2``)."""
    s = np.sqrt(dinv)
    n = A.shape[0]
    v = np.random.default_rng(0).standard_normal(n)
    v /= np.linalg.norm(v)
    alpha, beta = [], []
    v_old, b = np.zeros(n), 0.0
    for _ in range(min(LANCZOS_STEPS, n)):
        w = s * (A @ (s * v)) - b * v_old
        a = float(v @ w)
        w -= a * v
        alpha.append(a)
        b = float(np.linalg.norm(w))
        if b <= 1e-12 * abs(a):
            break
        beta.append(b)
        v_old, v = v, w / b
    T = np.diag(alpha) + np.diag(beta[:len(alpha) - 1], 1) + np.diag(beta[:len(alpha) - 1], -1)
    return float(np.linalg.eigvalsh(T)[-1])


def block_cg(A, B: np.ndarray, precondition, *, tol: float = SOLVE_TOL, max_iter: int = MAX_ITER,
             anorm: float | None = None):
    """Solve ``A X = B`` (``A`` symmetric positive definite) by breakdown-free block preconditioned CG.

    A column is solved when its relative residual ``||b - A x|| / ||b||`` is at most ``tol``, or when its
    residual has reached the rounding floor of a backward-stable solve, ``||b - A x|| <= ROUNDING *
    eps * (||A|| ||x|| + ||b||)`` (a direct solver's residual; below it no iteration can go). The
    iteration's own residuals drift from the true ones by rounding: the true residual ``B - A X`` is
    formed when they say converged, and a column still above its target is iterated on from it (at most
    :data:`RESTARTS` times).

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
    B : ndarray, shape (n, k)
    precondition : callable
        ``precondition(R) -> Z``, an approximation of ``A^-1 R`` by a symmetric positive definite operator.
    tol : float
        Relative residual every column must reach (or the rounding floor).
    max_iter : int
        Most iterations in all.
    anorm : float, optional
        A bound of ``||A||_2`` (default :func:`flexmor.linalg.memory.norm_bound`).

    Returns
    -------
    X : ndarray, shape (n, k)
    iterations : int
    residual : float
        The largest relative residual of a column, from ``B - A X``.

    Raises
    ------
    SolverError
        ``A`` (or the preconditioner) is not positive definite.
    ConvergenceError
        ``max_iter`` iterations did not reach ``tol`` (its ``result`` holds ``X``).
    """
    B = np.asarray(B, dtype=float)
    n, k = B.shape
    anorm = norm_bound(A) if anorm is None else anorm
    X = np.zeros((n, k))
    bn = np.linalg.norm(B, axis=0)
    bn[bn == 0] = 1.0
    R = B.copy()
    its = 0
    for _ in range(RESTARTS + 1):
        target = np.maximum(tol, _floor(X, bn, anorm))
        res = np.linalg.norm(R, axis=0) / bn
        if np.all(res <= target):
            break
        its = _iterate(A, X, R, bn, precondition, tol, anorm, its, max_iter)
        R = B - sparse_dense(A, X)
    res = np.linalg.norm(R, axis=0) / bn
    if np.any(res > np.maximum(tol, _floor(X, bn, anorm))):
        raise ConvergenceError(f"block CG did not reach the relative residual {tol:.0e} ({res.max():.1e} after "
                               f"{its} iterations, {RESTARTS} restarts)", result=X)
    return X, its, float(res.max())


#: The rounding floor of a residual, in units of ``eps (||A|| ||x|| + ||b||)`` (:func:`block_cg`).
ROUNDING = 64


def _floor(X, bn, anorm) -> np.ndarray:
    """The relative residual of each column at the rounding floor of a backward-stable solve."""
    return ROUNDING * np.finfo(float).eps * (anorm * np.linalg.norm(X, axis=0) + bn) / bn


#: Restarts of block CG from the true residual (:func:`block_cg`).
RESTARTS = 3


def _iterate(A, X, R, bn, precondition, tol, anorm, its, max_iter) -> int:
    """Block CG iterations on ``A X = B`` from ``X`` and its residual ``R`` (both updated in place) until
    the recurred residuals are below ``tol`` or the rounding floor; the iteration count so far."""
    P: np.ndarray | None = None
    AP = np.zeros((0, 0))
    active = np.linalg.norm(R, axis=0) / bn > np.maximum(tol, _floor(X, bn, anorm))
    while active.any():
        if its >= max_iter:
            raise ConvergenceError(f"block CG did not reach the relative residual {tol:.0e} in {max_iter} "
                                   f"iterations", result=X)
        Z = precondition(R[:, active])
        if P is not None:
            Z -= P @ (AP.T @ Z)  # A-orthogonal to the last search block (P^T A P = I)
        AZ = sparse_dense(A, Z)
        G = Z.T @ AZ
        G = 0.5 * (G + G.T)
        s, U = np.linalg.eigh(G)
        top = max(float(s[-1]), 0.0)
        if s[0] < -1e-8 * top:
            raise SolverError(INDEFINITE.format(where="block CG met a direction of negative energy"),
                              params=("backend",))
        keep = s > 1e-12 * top
        if not keep.any():
            break
        T = U[:, keep] / np.sqrt(s[keep])
        P, AP = Z @ T, AZ @ T
        alpha = P.T @ R
        X += P @ alpha
        R -= AP @ alpha
        its += 1
        active = np.linalg.norm(R, axis=0) / bn > np.maximum(tol, _floor(X, bn, anorm))
    return its
