"""Preconditioned block eigensolver (LOBPCG) for the lowest eigenpairs of ``K phi = lambda M phi``.

Where ``K - sigma M`` is not factorized (the ``amg`` backend, :mod:`flexmor.linalg.amg`), shift-invert
Lanczos would need an inner iterative solve to full accuracy for every block of its Krylov space. The
locally optimal block preconditioned conjugate gradient method (Knyazev 2001) needs one application of
the preconditioner ``T ~ (K - sigma M)^-1`` (one AMG V-cycle per column) per iteration instead: each
iteration is a Rayleigh-Ritz step of the pencil ``(A, M)``, ``A = K - sigma M`` (positive definite), on
the space of the current Ritz vectors ``X``, the preconditioned residuals ``W = T (A X - M X mu)`` and
the previous search directions ``P``.

Robustness follows Hetmaniuk & Lehoucq (2006) and Duersch et al. (2018): ``W`` is M-orthogonalized
against ``X`` and orthonormalized within itself before the Rayleigh-Ritz step, the directions ``P``
carry no ``X`` component, and the projected pencil is reduced by an eigen-decomposition of its
(diagonally scaled) Gram matrix that drops directions below rounding (SVQB) instead of a Cholesky
factorization that fails when ``P`` and ``W`` become nearly dependent. Converged columns are soft-locked:
they stay in ``X`` (and in the Rayleigh-Ritz step) but get no new directions, so the preconditioner
works on the columns still iterating only. ``m = k + guard`` columns are iterated; the guard columns
speed the convergence of the ``k``-th (its rate depends on ``mu_k / mu_{m+1}``).

Memory: six blocks of ``n x m`` at most (``X``, ``M X``, ``W``, ``P``, and two products or the next
``X`` and ``P``); the products of ``A`` and ``M`` with the blocks are formed again in each iteration
instead of being kept and updated, which would take three more.

References
----------
Knyazev, A. V. (2001). Toward the optimal preconditioned eigensolver: locally optimal block
preconditioned conjugate gradient method. SIAM J. Sci. Comput. 23(2), 517-541.
Hetmaniuk, U., Lehoucq, R. (2006). Basis selection in LOBPCG. J. Comput. Phys. 218, 324-332.
Duersch, J. A., Shao, M., Yang, C., Gu, M. (2018). A robust and efficient implementation of LOBPCG.
SIAM J. Sci. Comput. 40(5), C655-C676.
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import ConvergenceError
from .threads import blas_threads, dense_threads, sparse_dense

__all__ = ["lobpcg", "MAX_ITER", "guard_columns"]

log = logging.getLogger(__name__)

#: Most iterations of :func:`lobpcg`.
MAX_ITER = 500

#: Directions of a Gram matrix whose eigenvalue (columns scaled to unit norm) is below this are dropped
#: as dependent: their M-norm is below rounding relative to the columns they are made of.
DROP = 1e-12


#: A pair whose residual did not halve in this many iterations (and is below ``0.01 sqrt(tol)``) has stalled at
#: the rounding floor: LOBPCG reduces an unconverged residual by a factor of about 0.3-0.7 per iteration.
STALL_WINDOW = 4


def guard_columns(k: int) -> int:
    """Columns iterated beyond the ``k`` wanted: ``max(6, k // 4)`` (a free body's six rigid-body modes,
    a cluster beyond the ``k``-th)."""
    return max(6, k // 4)


def _svqb(G: np.ndarray, drop: float = DROP):
    """``T`` with ``T^T G T = I`` for a symmetric positive semi-definite Gram matrix ``G``, over the directions
    of ``G`` (columns scaled to unit diagonal) whose eigenvalue exceeds ``drop`` times the largest; and the
    smallest kept eigenvalue over the largest (``T`` orthonormalizes to about ``eps`` over it)."""
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / d[:, None] / d[None, :]
    Gs = 0.5 * (Gs + Gs.T)
    s, U = np.linalg.eigh(Gs)
    top = max(float(s[-1]), 1e-300)
    keep = s > drop * top
    low = float(s[keep][0]) / top if keep.any() else 0.0
    return (U[:, keep] / np.sqrt(s[keep])) / d[:, None], low


#: One orthonormalization of a block suffices where its scaled Gram matrix' smallest kept eigenvalue is above
#: this (its result orthonormal to ``eps / 1e-4``); else a second pass.
ONE_PASS = 1e-4

#: Share of its M-norm every column must keep in the projection against ``X`` for a second projection to be
#: skipped: the loss of orthogonality a projection leaves is about ``eps`` over that share.
REORTH_KEPT = 0.05


def _m_orthonormal(M, W: np.ndarray, X: np.ndarray | None = None, MX: np.ndarray | None = None):
    """``W`` M-orthogonalized against ``X`` (M-orthonormal, ``MX = M X``) and M-orthonormalized within itself,
    with ``M W``; fewer columns where ``W`` was dependent. A second pass of either step only where the first
    lost accuracy (:data:`REORTH_KEPT`, :data:`ONE_PASS`)."""
    n = W.shape[0]
    against = X is not None and MX is not None and X.shape[1] > 0
    for _ in range(2):
        C = None
        if against and X is not None and MX is not None:
            with blas_threads(dense_threads(n * X.shape[1])):
                C = MX.T @ W
                W = W - X @ C
        MW = sparse_dense(M, W)
        with blas_threads(dense_threads(n * W.shape[1])):
            G = W.T @ MW
        if C is not None:  # M-norm kept over M-norm before the projection (X is M-orthonormal)
            after = np.maximum(np.diag(G), 0.0)
            kept = np.sqrt(after / np.maximum(after + np.einsum("ij,ij->j", C, C), 1e-300))
            against = bool(kept.min() < REORTH_KEPT)
        T, low = _svqb(G)
        with blas_threads(dense_threads(n * W.shape[1])):
            W, MW = W @ T, MW @ T
        if W.shape[1] == 0 or (not against and low >= ONE_PASS):
            break
    return W, MW


def _reorthonormal(M, X, m, precondition, rng):
    """``X`` (M-orthonormal up to the rounding of the projected problem) made M-orthonormal again, with ``M X``
    and whether its columns are still (near) the Ritz vectors: by the symmetric ``G^-1/2`` of its Gram matrix
    ``G`` (the nearest M-orthonormal block, which keeps the columns where they are) while ``G`` is near ``I``
    and ``X`` has its ``m`` columns, else by :func:`_m_orthonormal`, refilled to ``m`` columns by smoothed random
    ones where columns were dependent or missing (the projected basis had fewer than ``m`` directions)."""
    n = X.shape[0]
    MX = sparse_dense(M, X)
    with blas_threads(dense_threads(n * m)):
        G = X.T @ MX
    s, U = np.linalg.eigh(G)
    if s[0] > 0.5 and X.shape[1] >= m:
        T = (U / np.sqrt(s)) @ U.T
        with blas_threads(dense_threads(n * m)):
            return X @ T, MX @ T, True
    return (*_refilled(M, *_m_orthonormal(M, X), m, precondition, rng), False)


def _refilled(M, X, MX, m, precondition, rng):
    """The M-orthonormal ``X`` (with ``M X``) refilled to ``m`` columns by smoothed random ones M-orthogonal to
    it (a smoothed random block can be dependent to rounding where a few directions dominate the preconditioned
    mass, e.g. a heavy rigid part); fewer only where :data:`REFILLS` tries found no more directions."""
    n = X.shape[0]
    for _ in range(REFILLS):
        if X.shape[1] >= m:
            break
        W, MW = _m_orthonormal(M, precondition(sparse_dense(M, rng.standard_normal((n, m - X.shape[1])))), X, MX)
        X, MX = np.hstack([X, W]), np.hstack([MX, MW])
    return X, MX


#: Tries of :func:`_refilled` to bring a block to its columns.
REFILLS = 8


def lobpcg(K, M, k: int, A, precondition, sigma: float, *, tol: float = 1e-8, guard: int | None = None,
           max_iter: int = MAX_ITER, seed: int = 0, stats=None):
    """Lowest ``k`` eigenpairs of ``(K, M)`` by LOBPCG on the pencil ``(A, M)``, ``A = K - sigma M``.

    Parameters
    ----------
    K, M : sparse matrix, shape (n, n)
        Symmetric stiffness and positive definite mass.
    k : int
        Number of wanted eigenpairs (the lowest).
    A : sparse matrix, shape (n, n)
        ``K - sigma M``, symmetric positive definite (``sigma`` below the spectrum).
    precondition : callable
        ``precondition(R) -> Z``, a symmetric positive definite approximation of ``A^-1`` applied to a block.
    sigma : float
        The shift of ``A``.
    tol : float
        Relative residual ``||K x - lambda M x|| / ((|lambda| + |sigma|) ||M x||)`` below which a pair counts
        as converged (the measure of :func:`flexmor.linalg.block_eigen.block_lanczos`); a pair whose residual
        is below ``0.01 sqrt(tol)`` and fell by less than half in the last :data:`STALL_WINDOW` iterations
        (stalled at the rounding floor, about ``eps ||K|| / lambda``) also counts.
    guard : int, optional
        Columns iterated beyond ``k`` (default :func:`guard_columns`).
    max_iter : int
        Most iterations; then :class:`ConvergenceError` with the current pairs as ``result``.
    seed : int
        Seed of the random start block (results are reproducible).
    stats : SolverStats, optional
        Where the iterations (``eigen_iterations``) and the largest residual (``eigen_residual``) are added.

    Returns
    -------
    lam : ndarray, shape (k,)
        Eigenvalues in ascending order.
    phi : ndarray, shape (n, k)
        M-orthonormal eigenvectors.
    """
    with blas_threads(1):
        return _iterate(K, M, int(k), A, precondition, float(sigma), tol=tol, guard=guard, max_iter=max_iter,
                        seed=seed, stats=stats)


def _iterate(K, M, k, A, precondition, sigma, *, tol, guard, max_iter, seed, stats):
    n = A.shape[0]
    m = min(n, k + (guard_columns(k) if guard is None else int(guard)))
    scale = abs(sigma)
    rng = np.random.default_rng(seed)
    X = precondition(sparse_dense(M, rng.standard_normal((n, m))))  # a smoothed random start
    X, MX = _refilled(M, *_m_orthonormal(M, X), m, precondition, rng)
    P = np.zeros((n, 0))
    history: list = []
    its = 0
    ritz = False  # X holds the Ritz vectors of its span (else M-orthonormal vectors near them)
    while True:
        AX = sparse_dense(A, X)
        with blas_threads(dense_threads(n * X.shape[1])):
            GXX = X.T @ AX
            GXX = 0.5 * (GXX + GXX.T)
            if not ritz:  # Rayleigh-Ritz on X alone (the start, after a refill)
                mu, Z = np.linalg.eigh(GXX)
                X, AX, MX = X @ Z, AX @ Z, MX @ Z
                if P.shape[1]:
                    P = P @ Z  # (the directions stay with their Ritz vectors)
                GXX, ritz = np.diag(mu), True
        mu = np.diag(GXX).copy()  # Rayleigh quotients
        AX -= MX * mu  # the residuals A x - mu M x = K x - lambda M x
        res = np.linalg.norm(AX, axis=0) / ((np.abs(mu + sigma) + scale) * np.linalg.norm(MX, axis=0) + 1e-300)
        if history and history[-1].size != res.size:  # (the block changed its columns: a new history)
            history.clear()
        history.append(res)
        old = history.pop(0) if len(history) > STALL_WINDOW else np.full(res.size, np.inf)
        conv = (res <= tol) | ((res >= 0.5 * old) & (res <= 1e-2 * np.sqrt(tol)))
        mk = min(k, X.shape[1])
        if conv[:k].all():
            if np.abs(GXX - np.diag(mu)).max() > 1e-8 * np.abs(mu).max():  # the Ritz pairs of the final X
                mu, Z = np.linalg.eigh(GXX)
                with blas_threads(dense_threads(n * X.shape[1])):
                    X = X @ Z
            break
        if its >= max_iter:
            raise ConvergenceError(f"LOBPCG did not converge for {k} modes in {max_iter} iterations "
                                   f"({int(conv[:k].sum())} converged, largest residual {res[:k].max():.1e})",
                                   result=(mu[:mk] + sigma, X[:, :mk]))
        active = np.flatnonzero(~conv)
        W = precondition(AX[:, active])
        del AX
        W, MW = _m_orthonormal(M, W, X, MX)
        if W.shape[1] == 0:
            raise ConvergenceError(f"LOBPCG stalled for {k} modes (no new directions; {int(conv[:k].sum())} "
                                   "converged)", result=(mu[:mk] + sigma, X[:, :mk]))
        Pa = P[:, active] if P.shape[1] else P  # (P has a column per Ritz vector after the first step)
        del P
        blocks = [X, W] + ([Pa] if Pa.shape[1] else [])
        sizes = [b.shape[1] for b in blocks]
        offs = np.concatenate([[0], np.cumsum(sizes)])
        GA, GM = np.zeros((offs[-1], offs[-1])), np.zeros((offs[-1], offs[-1]))
        GA[:sizes[0], :sizes[0]] = GXX
        GM[:sizes[0], :sizes[0]] = np.eye(sizes[0])
        for j in range(1, len(blocks)):  # the Gram matrices column block by column block
            AY = sparse_dense(A, blocks[j])
            if j == 1:
                MY, MW = MW, None
            else:
                MY = sparse_dense(M, blocks[j])
            with blas_threads(dense_threads(n * offs[j + 1])):
                for i in range(j + 1):
                    GA[offs[i]:offs[i + 1], offs[j]:offs[j + 1]] = blocks[i].T @ AY
                    GM[offs[i]:offs[i + 1], offs[j]:offs[j + 1]] = blocks[i].T @ MY
            del AY, MY
        GA = np.triu(GA) + np.triu(GA, 1).T
        GM = np.triu(GM) + np.triu(GM, 1).T
        T, _ = _svqb(GM)
        H = T.T @ GA @ T
        _, Z = np.linalg.eigh(0.5 * (H + H.T))
        C = T @ Z[:, :m]
        del MX
        with blas_threads(dense_threads(n * offs[-1])):
            X_new = X @ C[:sizes[0]]
            P = blocks[1] @ C[offs[1]:offs[2]]
            if len(blocks) > 2:
                P += blocks[2] @ C[offs[2]:]
            X_new += P
        X = X_new
        del blocks, W, Pa, X_new
        X, MX, ritz = _reorthonormal(M, X, m, precondition, rng)
        if X.shape[1] != P.shape[1]:  # the projected basis had fewer than m directions, refilled: the new columns
            P = np.zeros((n, 0))  # have no search directions
        its += 1
        log.debug("LOBPCG iteration %d: %d of %d columns iterating, largest wanted residual %.1e", its,
                  active.size, m, res[:k].max())
    if stats is not None:
        stats.eigen_iterations += its
        stats.eigen_residual = max(stats.eigen_residual, float(res[:k].max()))
    log.info("LOBPCG: %d modes (%d columns) in %d iterations, largest residual %.1e", k, m, its, res[:k].max())
    order = np.argsort(mu[:k], kind="stable")
    return mu[:k][order] + sigma, X[:, :k][:, order]
