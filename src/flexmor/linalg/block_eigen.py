"""Block shift-invert Lanczos for the lowest eigenpairs of ``K phi = lambda M phi``.

The Krylov space of the spectral transformation ``S = (K - sigma M)^{-1} M`` is built block by
block: every step is ONE solve with ``p`` right-hand sides through an existing
:class:`~flexmor.linalg.factorization.Factorization`, so the sparse direct solver works on
BLAS-3 blocks instead of single vectors. The basis is kept M-orthonormal by two passes of
block classical Gram-Schmidt (full reorthogonalization, Grimes et al. 1994 use selective
reorthogonalization; full is affordable for the few hundred columns needed here), blocks are
orthonormalized by an eigen-decomposition of their Gram matrix (rank-revealing, so a deflated
Krylov space shrinks the block instead of producing noise). Eigenpairs are extracted by
Rayleigh-Ritz on ``(K, M)`` and accepted by their true residual, formed once the wanted Ritz
values have settled (moved by less than ``tol`` relative since the previous block: a Ritz value
converges like the square of its vector's residual, so the products of ``k`` columns with ``K``
and ``M`` are not made at every block). Only the basis is kept (its M-products are formed again
per block by a sparse product). When the basis grows beyond
its limit it is thick-restarted with the lowest Ritz vectors (Wu & Simon 2000) and the
Krylov continuation block.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla

from ..errors import ConvergenceError
from .threads import blas_threads, dense_threads, sparse_dense

__all__ = ["block_lanczos"]

log = logging.getLogger(__name__)


#: Share of its M-norm every column of a block must keep in the first projection against the basis for the
#: second projection to be skipped: the loss of orthogonality a projection leaves is about ``eps`` over that
#: share (measured on a free C3D10 interior: shares 0.34-0.38 in every block after the first, the second
#: pass's coefficients then 1e-15 of the column).
REORTH_KEPT = 0.05


def _orthonormalize(W, MW, Q, m, M, drop_tol=1e-10):
    """M-orthogonalize the block ``W`` against ``Q[:, :m]`` (two passes) and within itself.

    The M-inner products with the basis are ``Q^T (M W)``: ``M W`` is formed again after each
    projection (a sparse product with the block) instead of keeping ``M Q`` beside ``Q``, which halves
    the basis' memory and replaces a tall ``gemm`` by a sparse product. The second projection is made
    only where the first cancelled more than :data:`REORTH_KEPT` of a column (Daniel, Gragg, Kaufman,
    Stewart 1976); both in-block orthonormalizations are. Returns the new columns and their
    M-products (possibly fewer columns than ``W``).
    """
    norm0 = np.sqrt(np.maximum(np.einsum("ij,ij->j", W, MW), 0.0))
    n = W.shape[0]
    mild = False
    for k in range(2):
        if m and not (k and mild):
            with blas_threads(dense_threads(n * m)):  # the basis read twice: all cores for a large one
                C = Q[:, :m].T @ MW
                W = W - Q[:, :m] @ C
            MW = sparse_dense(M, W)
            if k == 0:  # kept share of each column: 1 - the cancellation the projection's rounding is amplified by
                kept = np.sqrt(np.maximum(np.einsum("ij,ij->j", W, MW), 0.0)) / np.maximum(norm0, 1e-300)
                mild = bool(kept.min() >= REORTH_KEPT)
        G = W.T @ MW
        G = 0.5 * (G + G.T)
        s, U = np.linalg.eigh(G)
        keep = s > drop_tol**2 * max(float(norm0.max()) ** 2, 1e-300)
        if not keep.any():
            return W[:, :0], MW[:, :0]
        T = U[:, keep] / np.sqrt(s[keep])
        W, MW = W @ T, MW @ T
        norm0 = np.ones(W.shape[1])
    return W, MW


#: Ritz values that moved by less than this (or ``tol`` if larger) since the previous block have settled
#: above the rounding (~1e-12 relative) with which they come out of ``eigh`` of the projected matrix.
SETTLED = 1e-9


class _Check(NamedTuple):
    """The residual check of the Ritz pairs of a basis of ``m`` columns (:func:`_ritz_check`)."""

    R: np.ndarray  # true residuals K X - M X lam
    done: np.ndarray  # converged pairs
    res: np.ndarray  # relative residual norms
    m: int


def _ritz_check(K, M, X, lam, scale, tol, res_old, m) -> _Check:
    """The true residuals ``R = K X - M X lam`` of the Ritz pairs ``(lam, X)`` of a basis of ``m`` columns, their
    relative norms ``res`` and which pairs are converged (below ``tol``, or below ``0.01 sqrt(tol)`` and no
    longer falling by half against ``res_old``: round-off puts a floor of about ``eps ||K|| ||x||`` under
    ``||R||``)."""
    MX = sparse_dense(M, X)
    R = sparse_dense(K, X) - MX * lam
    res = np.linalg.norm(R, axis=0) / ((np.abs(lam) + scale) * np.linalg.norm(MX, axis=0) + 1e-300)
    stalled = res >= 0.5 * res_old if res_old is not None else np.zeros(lam.size, bool)
    done = (res <= tol) | (stalled & (res <= np.sqrt(tol) * 1e-2))
    return _Check(R, done, res, m)


def _iterate(K, M, k, F, sigma, *, block=None, tol=1e-8, max_basis=None, max_restarts=50, seed=0):
    """The iteration of :func:`block_lanczos` (same parameters)."""
    n = K.shape[0]
    p = int(block) if block else min(max(6, k // 4), 16)
    p = max(1, min(p, n - k if n > k else 1))
    cap = int(max_basis) if max_basis else max(5 * k, k + 14 * p)
    cap = min(max(cap, k + 2 * p), n)
    Q = np.empty((n, cap), order="F")  # column blocks contiguous for the BLAS products
    H = np.zeros((cap, cap))  # Q^T K Q
    rng = np.random.default_rng(seed)
    W = F.solve(M @ rng.standard_normal((n, p)))  # one step of S smooths the random block
    m = 0
    restarts = 0
    solves = 1
    scale = abs(sigma)
    res_old = None
    last = None
    theta_old = None
    while True:
        W, MW = _orthonormalize(W, sparse_dense(M, W), Q, m, M)
        b = W.shape[1]
        if b == 0 or m + b > cap:
            if b == 0 and m < k:
                W = F.solve(M @ rng.standard_normal((n, p)))  # invariant subspace found: restart fresh
                solves += 1
                continue
            # thick restart: keep the lowest Ritz vectors; continue from the Krylov block W and
            # the shift-inverted residuals of the unconverged Ritz pairs (the Ritz vectors of
            # (K, M) are not those of S, so W alone would not carry their residuals)
            restarts += 1
            if restarts > max_restarts:
                n_done = int(last.done.sum()) if last is not None else 0
                theta, Y = sla.eigh(H[:m, :m])  # the best Ritz pairs now (the last residual check may be older)
                kk = min(k, m)
                raise ConvergenceError(f"block Lanczos did not converge for {k} modes in {max_restarts} restarts "
                                       f"({n_done} converged)", result=(theta[:kk], Q[:, :m] @ Y[:, :kk]))
            keep = min(m - p, max(k + p, m // 2)) if m > k + p else m
            theta, Y = sla.eigh(H[:m, :m])
            if last is None or last.m != m:  # the residuals of the Ritz pairs now, for the continuation
                last = _ritz_check(K, M, Q[:, :m] @ Y[:, :k], theta[:k], scale, tol, None, m)
            Y = Y[:, :keep]
            Q[:, :keep] = Q[:, :m] @ Y
            H[:keep, :keep] = np.diag(theta[:keep])
            m = keep
            theta_old = None
            if last is not None:
                R, done = last.R, last.done
                idx = np.flatnonzero(~done)[:p]
                if idx.size:
                    W = np.hstack([W, F.solve(R[:, idx])])
                    solves += 1
            if W.shape[1] == 0:
                W = F.solve(M @ rng.standard_normal((n, p)))
                solves += 1
            continue
        KW = sparse_dense(K, W)
        Q[:, m:m + b] = W
        with blas_threads(dense_threads(n * (m + b))):
            H[:m + b, m:m + b] = Q[:, :m + b].T @ KW
        H[m:m + b, :m] = H[:m, m:m + b].T
        m += b
        if m >= min(k + p, n):
            theta, Y = sla.eigh(H[:m, :m])
            # the Ritz values settle (to about the square of the residual) before the Ritz vectors do:
            # the true residuals, k columns of products with K and M, are formed once they have
            moved = np.inf if theta_old is None else float(
                np.max(np.abs(theta[:k] - theta_old) / (np.abs(theta[:k]) + scale)))
            theta_old = theta[:k].copy()
            if moved > max(tol, SETTLED) and m < n:
                W = F.solve(MW)
                solves += 1
                continue
            lam = theta[:k]
            X = Q[:, :m] @ Y[:, :k]  # a new array: a restart overwriting Q leaves it intact
            last = _ritz_check(K, M, X, lam, scale, tol, res_old, m)
            done, res = last.done, last.res
            res_old = res
            log.debug("block Lanczos: %d columns, %d solves, max residual %.1e", m, solves, res.max())
            if done.all() or m == n:
                log.info("block Lanczos: %d modes from %d block solves of %d, %d columns, %d restarts",
                         k, solves, p, m, restarts)
                return lam, X
        W = F.solve(MW)
        solves += 1


def block_lanczos(K, M, k: int, F, sigma: float, *, block: int | None = None, tol: float = 1e-8,
                  max_basis: int | None = None, max_restarts: int = 50, seed: int = 0):
    """Lowest ``k`` eigenpairs of ``(K, M)`` near and above ``sigma`` by block shift-invert Lanczos.

    Parameters
    ----------
    K, M : sparse matrix, shape (n, n)
        Symmetric stiffness and positive definite mass.
    k : int
        Number of wanted eigenpairs (those of ``(K - sigma M)^{-1} M`` of largest magnitude,
        i.e. the ones closest to ``sigma``; the lowest when ``sigma`` lies below the spectrum).
    F : Factorization
        Factorization of ``K - sigma M`` (its ``solve`` takes ``(n, p)`` blocks).
    sigma : float
        The shift of ``F``.
    block : int, optional
        Block size ``p`` (right-hand sides per solve); default ``min(max(6, k // 4), 16)``.
        It should exceed the largest multiplicity among the wanted eigenvalues (6 for the
        rigid-body modes of a free-free body, 2 for pairs of a symmetric cross-section).
    tol : float
        Relative residual ``||K x - lambda M x|| / ((|lambda| + |sigma|) ||M x||)`` below which
        a Ritz pair counts as converged. The eigenvalue (a Rayleigh quotient) is then accurate
        to about ``tol**2`` relative to the gap. Round-off limits this residual to about
        ``eps ||K|| / lambda``; a pair whose residual is below ``0.01 sqrt(tol)`` and fell by less than
        half since the previous block (stalled at that floor) also counts.
    max_basis : int, optional
        Columns before a thick restart; default ``max(5 k, k + 14 p)``.
    max_restarts : int
        Raise :class:`ConvergenceError` after this many restarts; its ``result`` holds the best
        Ritz pairs ``(lam, phi)`` so far.
    seed : int
        Seed of the random start block (results are reproducible).

    Returns
    -------
    lam : ndarray, shape (k,)
        Eigenvalues in ascending order (Rayleigh quotients).
    phi : ndarray, shape (n, k)
        M-orthonormal eigenvectors.

    Notes
    -----
    The dense block algebra runs with one OpenBLAS thread
    (:func:`~flexmor.linalg.threads.blas_threads`) so that it does not compete with the
    solver's threads; the products with a large basis on
    :func:`~flexmor.linalg.threads.dense_threads`.

    References
    ----------
    Grimes, R. G., Lewis, J. G., Simon, H. D. (1994). A shifted block Lanczos algorithm for
    solving sparse symmetric generalized eigenproblems. SIAM J. Matrix Anal. Appl. 15(1),
    228-272.
    Ericsson, T., Ruhe, A. (1980). The spectral transformation Lanczos method for the
    numerical solution of large sparse generalized symmetric eigenvalue problems.
    Math. Comp. 35, 1251-1268.
    Wu, K., Simon, H. (2000). Thick-restart Lanczos method for large symmetric eigenvalue
    problems. SIAM J. Matrix Anal. Appl. 22(2), 602-616.
    """
    with blas_threads(1):
        return _iterate(K, M, k, F, sigma, block=block, tol=tol, max_basis=max_basis,
                        max_restarts=max_restarts, seed=seed)
