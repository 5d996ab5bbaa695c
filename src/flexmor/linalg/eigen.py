"""Generalized symmetric eigenproblems ``K phi = lambda M phi`` on the factorization layer."""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh

from ..errors import ConvergenceError, ModelError, OptionError
from .block_eigen import block_lanczos
from .context import DENSE_LIMIT, EIGEN_METHODS, SolverContext, as_solver
from .distributed import is_partitioned
from .factorize import factorize_shifted
from .lobpcg import lobpcg
from .threads import sparse_dense

__all__ = ["eigenmodes", "dense_eigenmodes", "default_shift", "rigid_body_threshold", "is_rigid", "frequencies_hz",
           "whole_clusters", "CLUSTER_RTOL",
           "DENSE_LIMIT", "METHODS", "MASS_RCOND_MIN", "RESIDUAL_MAX"]

log = logging.getLogger(__name__)

#: Choices of ``eigenmodes(method=...)``.
METHODS = EIGEN_METHODS

#: Dense problems whose mass matrix has a reciprocal condition number (LAPACK ``dpocon``, 1-norm)
#: below this are solved in the shift-inverted form ``M phi = mu (K - sigma M) phi``. The
#: Cholesky-based ``eigh(K, M)`` forms ``L^-1 K L^-T`` and loses about ``log10(cond(M))`` digits;
#: below 1e-6 that is more than the residual check accepts.
MASS_RCOND_MIN = 1e-6

#: Largest accepted relative residual ``||K phi - lam M phi|| / ((||K|| + |lam| ||M||) ||phi||)``
#: of a dense eigenpair. Both dense paths are backward stable to a few ``n * eps`` (below 1e-11 up to
#: 3,000 DOF); a larger residual means the pencil is not symmetric definite in the way assumed.
RESIDUAL_MAX = 1e-8


def default_shift(K, M) -> float:
    """A negative shift below the spectrum, scaled to the model: ``-1e-6 * tr(K) / tr(M)``.

    ``tr(K)/tr(M)`` is a mean eigenvalue; the lowest flexible eigenvalues of FE models lie
    several orders of magnitude below it, rigid-body modes at zero. With a negative shift
    ``K - sigma M`` is positive definite even for a free-free body.
    """
    tk, tm = float(K.diagonal().sum()), float(M.diagonal().sum())
    scale = tk / tm if tm > 0 and tk > 0 else 1.0
    return -1e-6 * scale


def rigid_body_threshold(K, M) -> float:
    """Eigenvalues below ``1e-4 * |default_shift(K, M)|`` (= 1e-10 tr(K)/tr(M)) count as rigid-body modes.

    For a steel body meshed with ~0.05 m elements this is about 0.3 Hz; round-off puts the
    computed rigid-body eigenvalues many orders of magnitude lower.
    """
    return 1e-4 * abs(default_shift(K, M))


def is_rigid(lam, K, M) -> np.ndarray:
    """Boolean mask of the eigenvalues ``lam`` that belong to rigid-body modes."""
    return np.asarray(lam) < rigid_body_threshold(K, M)


def eigenmodes(K, M, k: int, *, sigma: float | None = None, solver: SolverContext | None = None, tol: float = 0.0,
               factorization=None, method: str | None = None, block: int | None = None, keep: bool = False):
    """Lowest ``k`` eigenpairs of ``K phi = lambda M phi`` (M positive definite).

    Parameters
    ----------
    K, M : sparse matrix, shape (n, n)
        Symmetric stiffness (positive semi-definite) and mass (positive definite).
    k : int
        Number of eigenpairs.
    sigma : float, optional
        Shift of the shift-invert Lanczos iteration; default :func:`default_shift`
        (negative, so rigid-body modes are found without a singular factorization).
    solver : SolverContext, optional
        Solver of :func:`flexmor.linalg.factorize` for ``K - sigma M`` and the eigen policy
        (method, block size, dense limit). With the ``petsc`` backend (or a ``petsc``
        factorization) the eigenpairs come from SLEPc's Krylov-Schur on the distributed
        factorization (:func:`flexmor.linalg.petsc.slepc_eigenmodes`) instead of
        ``lanczos``/``arpack``; with the ``amg`` backend (no factor) from LOBPCG with the AMG
        V-cycle as preconditioner (:func:`flexmor.linalg.lobpcg.lobpcg`), with ``petsc-gamg`` from
        the same LOBPCG with PETSc's GAMG V-cycle (:func:`flexmor.linalg.petsc_gamg.gamg_eigenmodes`).
    tol : float
        Convergence tolerance: ARPACK's (0 = machine precision) or the relative residual of
        the block Lanczos iteration (0 = its default 1e-8, eigenvalues to ~1e-14 relative).
    factorization : Factorization, optional
        An existing factorization of ``K - sigma M`` to reuse (``sigma`` must be given).
    method : {'auto', 'lanczos', 'arpack', 'dense'}, optional
        Default: the ``solver``'s :class:`~flexmor.linalg.context.EigenPolicy` (``auto``).
        ``lanczos``: block shift-invert Lanczos (:func:`flexmor.linalg.block_eigen.block_lanczos`,
        one block solve of ``p`` right-hand sides per step); ``arpack``: SciPy's ``eigsh``
        in shift-invert mode (one single-vector solve per step); ``dense``: LAPACK on dense
        copies. ``auto``: dense up to :data:`DENSE_LIMIT` DOF or ``k >= n/2``, else lanczos
        up to :data:`~flexmor.linalg.context.LANCZOS_MAX_K` modes and arpack above (measured
        in ``bench/eigen.py``: at 94,500 DOF lanczos is 1.57x faster for k = 20 and 1.56x for
        k = 50; at 36,300 DOF 1.2-1.6x for k = 60-150).
    block : int, optional
        Block size of ``lanczos`` (default: the policy's, else ``min(max(6, k // 4), 16)``).
    keep : bool
        Keep the factorization of ``K - sigma M`` in ``solver`` for the next computation at this
        shift (:func:`~flexmor.linalg.factorize.factorize_shifted`); one kept there already
        for these matrices and shift is used either way.

    Returns
    -------
    lam : ndarray, shape (k,)
        Eigenvalues ``omega^2`` (rad²/s²) in ascending order.
    phi : ndarray, shape (n, k)
        Mass-normalized eigenvectors (``phi.T @ M @ phi = I``).

    References
    ----------
    Ericsson, T., Ruhe, A. (1980). The spectral transformation Lanczos method for the
    numerical solution of large sparse generalized symmetric eigenvalue problems.
    Math. Comp. 35, 1251-1268.
    Grimes, R. G., Lewis, J. G., Simon, H. D. (1994). A shifted block Lanczos algorithm for
    solving sparse symmetric generalized eigenproblems. SIAM J. Matrix Anal. Appl. 15(1),
    228-272.
    """
    solver = as_solver(solver)
    policy = solver.eigen
    n = K.shape[0]
    k = int(k)
    method = policy.choose(n, k, method)  # an OptionError for an unknown method, before the size check
    if k < 1 or k > n:
        raise OptionError(f"number of modes must be between 1 and {n}, got {k}")
    block = policy.block if block is None else block
    if method == "dense":
        lam, phi = dense_eigenmodes(K, M, k, sigma=sigma)
    else:
        if sigma is None:
            if factorization is not None:
                raise OptionError("a given factorization needs its shift sigma")
            sigma = default_shift(K, M)
        F = factorization
        if F is None:
            F = factorize_shifted(K, M, sigma, solver=solver, keep=keep)
        if F.backend == "petsc":  # distributed: SLEPc Krylov-Schur on the same MUMPS factorization
            from .petsc import slepc_eigenmodes

            lam, phi = slepc_eigenmodes(K, M, k, F, sigma, tol=tol)
        elif F.backend == "petsc-gamg":  # distributed, no factor: LOBPCG with one GAMG V-cycle per column
            from .petsc_gamg import gamg_eigenmodes

            lam, phi = gamg_eigenmodes(K, M, k, F, sigma, tol=tol or 1e-8)
        elif F.backend == "amg":  # no factor: one V-cycle per iteration instead of an inner solve per block
            lam, phi = lobpcg(K, M, k, F.matrix, F.precondition, sigma, tol=tol or 1e-8, stats=F.stats)
        elif method == "lanczos":
            lam, phi = block_lanczos(K, M, k, F, sigma, block=block, tol=tol or 1e-8)
        else:
            op = LinearOperator(K.shape, matvec=F.solve, matmat=F.solve, dtype=np.float64)
            ncv = min(n, max(2 * k + 1, k + 32))
            v0 = np.random.default_rng(0).standard_normal(n)  # seeded: ARPACK's own start vector changes per call
            try:
                lam, phi = eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, tol=tol, ncv=ncv, v0=v0)
            except ArpackNoConvergence as exc:
                order = np.argsort(exc.eigenvalues)
                raise ConvergenceError(
                    f"Lanczos did not converge for {k} modes ({len(exc.eigenvalues)} converged)",
                    result=(exc.eigenvalues[order], exc.eigenvectors[:, order])) from None
            order = np.argsort(lam)
            lam, phi = lam[order], phi[:, order]
    mass = np.einsum("ij,ij->j", phi, sparse_dense(M, phi))
    if method != "dense":
        # Rayleigh quotients: quadratically accurate in the eigenvector error, they remove
        # the spectral transformation's loss of accuracy for eigenvalues far from sigma
        lam = np.einsum("ij,ij->j", phi, sparse_dense(K, phi)) / mass
    # mass normalization (ARPACK returns M-orthonormal vectors up to round-off)
    phi = phi / np.sqrt(mass)
    return lam, phi


def dense_eigenmodes(K, M, k: int | None = None, *, sigma: float | None = None):
    """Lowest ``k`` (default: all finite) eigenpairs of a small problem ``K phi = lambda M phi``, densely.

    The path is chosen by the conditioning of ``M``, not by whether LAPACK's Cholesky happens to
    fail: a mass matrix with ``rcond(M) >= MASS_RCOND_MIN`` takes ``eigh(K, M)``; a singular or
    nearly singular one (massless DOFs, reduced integration, rank-deficient consistent masses) the
    shift-inverted form ``M phi = mu (K - sigma M) phi`` with ``sigma < 0``, which needs only
    ``K - sigma M`` positive definite; its finite eigenvalues are ``lambda = sigma + 1/mu``
    (``mu > 0``, refined by Rayleigh quotients), the infinite ones (``mu = 0``) are dropped. Every
    returned pair is checked by its residual (:data:`RESIDUAL_MAX`).

    Parameters
    ----------
    K, M : sparse matrix or ndarray, shape (n, n)
        Symmetric stiffness (positive semi-definite) and mass (positive semi-definite).
    k : int, optional
        Number of eigenpairs; None for all finite ones.
    sigma : float, optional
        Negative shift of the shift-inverted form; default :func:`default_shift`.

    Returns
    -------
    lam : ndarray, shape (k,)
        Eigenvalues ``omega^2`` in ascending order.
    phi : ndarray, shape (n, k)
        Mass-normalized eigenvectors.

    Raises
    ------
    ModelError
        ``M`` is indefinite, has fewer than ``k`` finite eigenvalues, or an eigenpair's residual
        exceeds :data:`RESIDUAL_MAX`.
    """
    Kd, Md = _dense(K), _dense(M)
    n = Kd.shape[0]
    k = n if k is None else int(k)
    rcond = _mass_rcond(Md)
    if rcond >= MASS_RCOND_MIN:
        # all pairs: the divide-and-conquer driver (gvd), ~2.5x faster than the subset driver (gvx)
        lam, phi = sla.eigh(Kd, Md, subset_by_index=None if k == n else [0, k - 1])
    else:
        log.info("mass matrix singular or ill-conditioned (rcond %.1e): shift-inverted dense eigenproblem", rcond)
        lam, phi = _shift_inverted(Kd, Md, None if k == n else k, sigma)
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, Md @ phi))
    _check_residuals(Kd, Md, lam, phi)
    return lam, phi


def _mass_rcond(Md) -> float:
    """LAPACK's estimate of ``1 / cond_1(M)`` from a Cholesky factor; 0 when Cholesky fails."""
    c, info = sla.lapack.dpotrf(Md, lower=False, clean=False)
    if info != 0:
        return 0.0
    rcond, info = sla.lapack.dpocon(c, float(np.abs(Md).sum(axis=0).max()))
    return float(rcond) if info == 0 else 0.0


def _shift_inverted(Kd, Md, k: int | None, sigma: float | None):
    """Finite eigenpairs of ``(K, M)`` with ``M`` semi-definite from ``M phi = mu (K - sigma M) phi``."""
    sigma = default_shift(Kd, Md) if sigma is None or sigma >= 0 else sigma
    try:
        mu, phi = sla.eigh(Md, Kd - sigma * Md)
    except np.linalg.LinAlgError:
        raise ModelError("K - sigma M is not positive definite: the mass matrix is indefinite, or K and M share "
                         "a null space (a DOF with neither stiffness nor mass); no meaningful eigenmodes") from None
    if mu.min() < -1e-12 * max(abs(mu).max(), 1e-300):
        raise ModelError("the mass matrix is not positive definite: it is indefinite (negative eigenvalues of M "
                         "relative to K); no meaningful eigenmodes")
    finite = mu > 1e-12 * max(mu.max(), 1e-300)
    if k is not None and np.count_nonzero(finite) < k:
        raise ModelError(f"the mass matrix is singular: only {np.count_nonzero(finite)} finite eigenvalues, "
                         f"{k} requested")
    if np.count_nonzero(~finite):
        log.info("mass matrix singular: %d infinite eigenvalues dropped", int(np.count_nonzero(~finite)))
    mu, phi = mu[finite][::-1], phi[:, finite][:, ::-1]
    if k is not None:
        mu, phi = mu[:k], phi[:, :k]
    # Rayleigh quotients: accurate to the square of the eigenvector error, also far from sigma
    lam = np.einsum("ij,ij->j", phi, Kd @ phi) / np.einsum("ij,ij->j", phi, Md @ phi)
    order = np.argsort(lam, kind="stable")
    return lam[order], phi[:, order]


def _check_residuals(Kd, Md, lam, phi) -> None:
    """Raise if an eigenpair's relative residual exceeds :data:`RESIDUAL_MAX`."""
    if lam.size == 0:
        return
    nk, nm = float(np.abs(Kd).sum(axis=0).max()), float(np.abs(Md).sum(axis=0).max())
    R = Kd @ phi - (Md @ phi) * lam
    res = np.linalg.norm(R, axis=0) / ((nk + np.abs(lam) * nm) * np.linalg.norm(phi, axis=0))
    worst = int(np.argmax(res))
    if not res[worst] <= RESIDUAL_MAX:
        raise ModelError(f"dense eigenpair {worst + 1} of {lam.size} has relative residual {res[worst]:.1e} "
                         f"(> {RESIDUAL_MAX:g}): K and M do not form a symmetric definite pencil (check that both "
                         "are symmetric and M is positive semi-definite)")


def _dense(A):
    return A.toarray() if sp.issparse(A) or is_partitioned(A) else np.asarray(A)


#: Eigenvalues closer than this (relative) are one multiple eigenvalue: their eigenvectors are any
#: basis of one space (a symmetric section's bending pair), chosen by round-off.
CLUSTER_RTOL = 1e-8


def whole_clusters(lam, k: int) -> int:
    """The smallest ``k' >= k`` at which the ascending eigenvalues ``lam`` (at least ``k + 1`` of
    them, else ``k``) do not split a multiple eigenvalue (:data:`CLUSTER_RTOL`): cutting a pair
    at equal frequency keeps one vector of it, chosen by round-off, so that the basis would
    differ from machine to machine."""
    lam = np.asarray(lam, float)
    while 0 < k < lam.size and abs(lam[k] - lam[k - 1]) <= CLUSTER_RTOL * max(abs(lam[k]), abs(lam[k - 1])):
        k += 1
    return k


def frequencies_hz(lam) -> np.ndarray:
    """Eigenfrequencies in Hz from eigenvalues ``omega^2``; tiny negative round-off gives 0."""
    lam = np.asarray(lam, dtype=float)
    return np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * np.pi)
