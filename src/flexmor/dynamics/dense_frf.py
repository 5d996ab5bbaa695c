"""Exact responses of small models from one dense eigendecomposition.

Below :data:`DENSE_FRF_MAX_DOF` DOF one dense eigendecomposition costs less than the sparse
sweep's factorizations (one per frequency; measured in ``bench/small_frf.py``), and it gives
``(K - w^2 M + i w D)^{-1}`` at every frequency exactly (to round-off):

* ``D`` None or proportional in the modes (``Phi^T D Phi`` diagonal: Rayleigh, modal damping):
  ``X(w) = Phi diag(1 / (lam_k - w^2 + i w d_k)) Phi^T rhs``;
* any other ``D``: the scaled companion form of the modal coordinates (state ``(S z, z')``,
  ``S = Lam^(1/2)``), ``A = [[0, S], [-Lam S^-1, -Phi^T D Phi]]``, is diagonalized,
  ``A = V diag(mu) V^{-1}``, and
  ``X(w) = Phi S^-1 V_top diag(1 / (i w - mu_k)) (V^{-1})_{:, n:} Phi^T rhs``; accepted only when
  ``V`` is well conditioned (:data:`STATE_COND_MAX`), e.g. not for undamped rigid-body modes
  (a defective eigenvalue 0).

Rigid-body modes (``lam_k = 0``) are kept: ``s = i w`` is never zero in a band. A singular mass
matrix has infinite eigenvalues that :func:`flexmor.linalg.eigen.dense_eigenmodes` drops; the
modal sum would then miss a static term, so :class:`DenseResolvent` refuses (``ModelError``)
and callers fall back to the sparse path.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..damping import ModalDamping
from ..errors import ModelError
from ..linalg.distributed import is_partitioned
from ..linalg.eigen import dense_eigenmodes, is_rigid
from ..linalg.threads import sparse_dense

__all__ = ["DENSE_FRF_MAX_DOF", "PROPORTIONAL_TOL", "STATE_COND_MAX", "DenseResolvent", "dense_applicable"]

log = logging.getLogger(__name__)

#: Largest model (DOF) whose full FRF takes the dense path under ``auto`` (damped models above
#: :data:`flexmor.analysis.compare.SURROGATE_MIN_DOF` DOF take the cheaper verified surrogate).
#: Measured (``bench/small_frf.py``, cantilever, band 1-5000 Hz, 2 cores): the dense path costs
#: as much as 58 sparse complex factorizations at 540 DOF and 449 at 3,000 DOF, while the sweep
#: on the same grid spends ~930-1,000; the dense cost grows ~n^3 against ~n^1.5 of one
#: factorization, so the two meet near 5,000 DOF.
DENSE_FRF_MAX_DOF = 5000

#: ``D`` counts as proportional when the off-diagonal part of ``Phi^T D Phi`` is below this
#: fraction of its largest diagonal entry (round-off of the transformation is ~n eps).
PROPORTIONAL_TOL = 1e-10

#: Largest accepted condition estimate ``||V||_1 ||V^{-1}||_1`` of the companion eigenvectors:
#: the resolvent's relative error is about ``eps cond(V)`` (<= 2e-11 here).
STATE_COND_MAX = 1e5

#: Frequencies per vectorized block of :meth:`DenseResolvent.frf` (bounds the temporary arrays).
_CHUNK = 64


def dense_applicable(model) -> bool:
    """True when ``model`` is small enough for the dense path and not distributed over MPI ranks."""
    return model.n_dof <= DENSE_FRF_MAX_DOF and not is_partitioned(model.K)


def _dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)


class DenseResolvent:
    """``(K - w^2 M + i w D)^{-1}`` of a small model for many ``w`` from one eigendecomposition.

    Parameters
    ----------
    K, M : sparse matrix or ndarray, shape (n, n)
        Symmetric stiffness and mass.
    D : sparse matrix or ndarray, optional
        Damping; None for an undamped model.
    damping : Damping, optional
        The model's damping description; :class:`~flexmor.damping.ModalDamping` puts its ratio
        in every mode exactly (``D`` is then not used).

    Attributes
    ----------
    kind : {'modal', 'state-space'}
        The representation used (see the module docstring).
    lam : ndarray, shape (n,)
        Eigenvalues ``omega^2`` of ``(K, M)``, ascending (rigid-body modes near 0).
    phi : ndarray, shape (n, n)
        Mass-normalized eigenvectors.

    Raises
    ------
    ModelError
        ``M`` is singular (infinite eigenvalues), or a non-proportional ``D`` gives an
        ill-conditioned companion eigenbasis: use the sparse path.
    """

    def __init__(self, K, M, D=None, damping=None):
        n = K.shape[0]
        self.lam, self.phi = dense_eigenmodes(K, M)
        # rigid-body modes at exactly 0: their computed eigenvalues are the rounding of K's null space (~1e-4
        # rad²/s² on the free CalculiX beam), which put poles near 0.002 Hz and an error ~ lam / w² in the response
        self.lam[is_rigid(self.lam, K, M)] = 0.0
        if self.lam.size < n:
            raise ModelError(f"the mass matrix is singular ({n - self.lam.size} infinite eigenvalues): the modal "
                             "sum misses a static term")
        if isinstance(damping, ModalDamping):  # modal damping: its ratio in every mode, exactly
            w = np.sqrt(np.maximum(self.lam, 0.0))
            self.kind, self._d = "modal", 2 * damping.ratios(w / (2 * np.pi)) * w
            return
        if D is None:
            self.kind, self._d = "modal", np.zeros(n)
            return
        Dm = self.phi.T @ sparse_dense(D, self.phi) if sp.issparse(D) else self.phi.T @ _dense(D) @ self.phi
        Dm = (Dm + Dm.T) / 2
        d = np.diag(Dm).copy()
        off = np.abs(Dm - np.diag(d)).max(initial=0.0)
        if off <= PROPORTIONAL_TOL * max(np.abs(d).max(initial=0.0), np.finfo(float).tiny):
            self.kind, self._d = "modal", d
            return
        # scaled state (S z, z'), S = diag(sqrt(lam)) (rigid-body modes: the first flexible scale), so that
        # both halves of the eigenvectors have the same magnitude
        lam_pos = self.lam[self.lam > 1e-12 * max(self.lam.max(), 1e-300)]
        self._s = np.sqrt(np.maximum(self.lam, lam_pos.min() if lam_pos.size else 1.0))
        A = np.block([[np.zeros((n, n)), np.diag(self._s)], [-np.diag(self.lam / self._s), -Dm]])
        mu, V = sla.eig(A, overwrite_a=True, check_finite=False)
        try:
            lu = sla.lu_factor(V, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            raise ModelError("the damped companion form is defective: use the sparse path") from None
        Vinv_tail = sla.lu_solve(lu, np.vstack([np.zeros((n, n)), np.eye(n)]), check_finite=False)
        cond = _cond1_estimate(V, lu)
        if not np.isfinite(cond) or cond > STATE_COND_MAX:
            raise ModelError(f"the damped companion eigenbasis is ill-conditioned (cond ~ {cond:.1e} > "
                             f"{STATE_COND_MAX:g}): use the sparse path")
        self.kind, self._mu, self._Vtop, self._Vtail = "state-space", mu, V[:n], Vinv_tail
        log.info("dense resolvent: non-proportional damping, companion eigenbasis cond ~ %.1e", cond)

    def _factors(self, rhs, C=None):
        """``left (., k)``, ``right (k, m)`` of ``X(w) = left diag(g(w)) right``."""
        right = self.phi.T @ rhs
        left = self.phi if C is None else np.asarray(C @ self.phi)
        if self.kind == "state-space":
            right = self._Vtail @ right
            left = (left / self._s) @ self._Vtop
        return left, right

    def pole_factors(self, w):
        """Pole factors ``g_k(w)`` at the angular frequencies ``w``, shape (len(w), k); for the
        ``modal`` kind ``X(w) = phi diag(g(w)) phi^T rhs``."""
        w = np.asarray(w, float)[:, None]
        if self.kind == "modal":
            return 1.0 / (self.lam[None, :] - w ** 2 + 1j * w * self._d[None, :])
        return 1.0 / (1j * w - self._mu[None, :])

    def solve(self, w: float, rhs) -> np.ndarray:
        """``(K - w^2 M + i w D)^{-1} rhs`` at one angular frequency ``w``, shape like ``rhs``, complex."""
        rhs = _dense(rhs)
        left, right = self._factors(rhs)
        return left @ (self.pole_factors([w])[0][:, None] * right)

    def frf(self, w, B, C) -> np.ndarray:
        """``C (K - w^2 M + i w D)^{-1} B`` at angular frequencies ``w``, shape (n_freq, n_outputs, n_inputs)."""
        w = np.asarray(w, float)
        left, right = self._factors(_dense(B), C)
        H = np.empty((w.size, left.shape[0], right.shape[1]), dtype=complex)
        for i in range(0, w.size, _CHUNK):
            H[i:i + _CHUNK] = np.einsum("pk,fk,km->fpm", left, self.pole_factors(w[i:i + _CHUNK]), right, optimize=True)
        return H


def _cond1_estimate(V, lu) -> float:
    """LAPACK's 1-norm condition estimate of ``V`` from its LU factors."""
    rcond, info = sla.lapack.zgecon(lu[0], float(np.abs(V).sum(axis=0).max()), norm="1")
    return 1.0 / rcond if info == 0 and rcond > 0 else np.inf
