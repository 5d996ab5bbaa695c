"""A verified surrogate of the full model's FRF for large models.

A direct sweep costs one sparse complex factorization per grid point, and the adaptive grid
of a band with tens of resonances has a thousand points or more. The surrogate replaces
those solves by a large Galerkin projection of the full model whose accuracy is checked
against direct solves:

1. basis ``V``: the modes of the modal pre-pass (up to 1.1 ``fmax``), the static response
   ``(K - sigma M)^{-1} B`` and ``n_krylov - 1`` second-order Krylov blocks
   ``(K - sigma M)^{-1} M X`` from the pre-pass factorization (no new factorization);
2. greedy verification: the relative residual ``||A(w) V x(w) - B||_F / ||B||_F`` is
   evaluated on candidate frequencies (cheaply, through the Gram matrix of
   ``[K V, M V, D V, B]``); at the frequency with the largest residual the full model is
   solved directly (one factorization) and the pointwise error of the surrogate
   ``||H - H_s||_F / ||H||_F`` is measured. If it exceeds ``tol``, the direct solution is
   added to the basis (rational Krylov enrichment) and the step is repeated; it stops after
   two consecutive checks below ``tol``;
3. :meth:`Surrogate.verify` repeats the check at the worst-residual point of the final grid.

Every check and its error are reported, so the floor of the measured errors is known: a
band_error well above ``tol**2`` is unaffected by the surrogate.

References
----------
Grimme, E. J. (1997). Krylov projection methods for model reduction. PhD thesis, University
of Illinois at Urbana-Champaign (rational Krylov interpolation).
Bai, Z., Su, Y. (2005). Dimension reduction of large-scale second-order dynamical systems via
a second-order Arnoldi method. SIAM J. Sci. Comput. 26(5), 1692-1709.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla

from ..linalg import factorize
from .frequency import ShiftedMatrices, _omega
from .grid import initial_grid

__all__ = ["Surrogate", "DEFAULT_SURROGATE_TOL"]

log = logging.getLogger(__name__)

#: Default largest pointwise relative error of the surrogate at its checks.
DEFAULT_SURROGATE_TOL = 1e-6


def _orthonormal(V: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the span of the columns of ``V`` (rank-revealing QR)."""
    V = V / np.maximum(np.linalg.norm(V, axis=0), np.finfo(float).tiny)
    Q, R, _ = sla.qr(V, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    return Q[:, : int(np.sum(d > rtol * d[0]))]


class Surrogate:
    """Verified Galerkin surrogate of ``H(s) = C (s^2 M + s D + K)^{-1} B`` over a band.

    Parameters
    ----------
    model : FEModel
        Damped full model.
    ports : Ports
        Inputs and outputs.
    band : (float, float)
        Band in Hz.
    phi : ndarray, shape (n_dof, k)
        Modes of the modal pre-pass.
    factorization : Factorization or None
        Factorization of ``K - sigma M`` (computed here when None).
    sigma : float
        Its shift.
    backend : str
        Backend of :func:`flexmor.linalg.factorize` for the direct checks.
    tol : float
        Largest accepted pointwise relative error at the checks.
    n_krylov : int
        Krylov blocks from the pre-pass factorization.
    max_checks : int
        Largest number of direct checks (factorizations) while building.
    resonances, zeta : array_like, optional
        Resonances and damping ratios, for candidate points at the peaks.
    """

    def __init__(self, model, ports, band, *, phi, factorization=None, sigma=0.0, backend="auto",
                 tol: float = DEFAULT_SURROGATE_TOL, n_krylov: int = 3, max_checks: int = 10,
                 resonances=None, zeta=None):
        self.model, self.backend, self.tol = model, backend, float(tol)
        self.B = ports.B.toarray()
        self.C = ports.C
        self.shifted = ShiftedMatrices(model.K, model.M, model.D)
        F0 = factorization or factorize((model.K - sigma * model.M).tocsr(), backend, positive=sigma < 0)
        blocks = [phi, F0.solve(self.B)]
        for _ in range(int(n_krylov) - 1):
            blocks.append(F0.solve(model.M @ blocks[-1]))
        self._set_basis(np.hstack(blocks))
        self.checks = []
        cand = initial_grid(*band, n=400, resonances=resonances, zeta=zeta)
        passed = 0
        while passed < 2 and len(self.checks) < max_checks and cand.size:
            res = self.residual(cand)
            k = int(np.argmax(res))
            err, X = self._check(cand[k], res[k])
            if err <= self.tol:
                passed += 1  # the next check goes elsewhere: drop candidates within ±5 %
                cand = cand[np.abs(cand / cand[k] - 1) > 0.05]
            else:
                passed = 0
                self._set_basis(np.hstack([self.V, X.real, X.imag]))
        self.verified = passed >= 2
        if not self.verified:
            log.warning("surrogate not verified after %d checks (last error %.1e > %.1e)",
                        len(self.checks), self.checks[-1]["rel_error"], self.tol)
        log.info("surrogate of order %d, %d direct checks", self.order, len(self.checks))

    @property
    def order(self) -> int:
        """Number of basis vectors."""
        return self.V.shape[1]

    def _set_basis(self, V):
        m = self.model
        self.V = _orthonormal(V)
        KV, MV = m.K @ self.V, m.M @ self.V
        DV = m.D @ self.V
        self.Kr, self.Mr, self.Dr = (self.V.T @ X for X in (KV, MV, DV))
        self.Br, self.Cr = self.V.T @ self.B, np.asarray(self.C @ self.V)
        P = np.hstack([KV, MV, DV, self.B])
        self._gram = P.T @ P
        lam, psi = sla.eigh((self.Kr + self.Kr.T) / 2, (self.Mr + self.Mr.T) / 2)
        self._psi = psi
        d = psi.T @ self.Dr @ psi
        off = np.abs(d - np.diag(np.diag(d))).max()
        self._modal = (lam, np.diag(d), self.Cr @ psi, psi.T @ self.Br) if off <= 1e-10 * np.abs(d).max() else None

    def _reduced_solution(self, w):
        if self._modal is not None:
            lam, d, _, PB = self._modal
            psi = self._psi
            return np.einsum("rk,fk,km->frm", psi, 1.0 / (lam - w[:, None] ** 2 + 1j * w[:, None] * d), PB)
        A = (self.Kr[None] - (w ** 2)[:, None, None] * self.Mr[None] + (1j * w)[:, None, None] * self.Dr[None])
        return np.linalg.solve(A, np.broadcast_to(self.Br.astype(complex), (w.size, *self.Br.shape)))

    def frf(self, freqs) -> np.ndarray:
        """Surrogate FRF, shape (n_freq, n_outputs, n_inputs)."""
        w = _omega(freqs)
        if self._modal is not None:  # proportional damping: diagonal in the reduced modes
            lam, d, CP, PB = self._modal
            out = np.empty((w.size, CP.shape[0], PB.shape[1]), complex)
            for s in range(0, w.size, 256):
                ws = w[s:s + 256, None]
                out[s:s + 256] = np.einsum("pk,fk,km->fpm", CP, 1.0 / (lam - ws ** 2 + 1j * ws * d), PB)
            return out
        X = self._reduced_solution(w)
        return np.einsum("pr,frm->fpm", self.Cr, X)

    def residual(self, freqs) -> np.ndarray:
        """Relative residual ``||A(w) V x(w) - B||_F / ||B||_F`` of the surrogate, per frequency."""
        w = _omega(freqs)
        X = self._reduced_solution(w)
        m = self.B.shape[1]
        c = np.concatenate([X, -(w ** 2)[:, None, None] * X, (1j * w)[:, None, None] * X,
                            np.broadcast_to(-np.eye(m), (w.size, m, m))], axis=1)
        r2 = np.einsum("fam,ab,fbm->f", c.conj(), self._gram, c).real
        return np.sqrt(np.maximum(r2, 0.0)) / np.linalg.norm(self.B)

    def _check(self, f_hz: float, residual: float):
        w = 2 * np.pi * f_hz
        F = factorize(self.shifted(w), self.backend, symmetric=True, check=False)
        X = F.solve(self.B)
        del F
        H = np.asarray(self.C @ X)
        err = float(np.linalg.norm(H - self.frf([f_hz])[0]) / np.linalg.norm(H))
        self.checks.append({"freq_hz": float(f_hz), "residual": float(residual), "rel_error": err,
                            "order": self.order})
        log.debug("surrogate check at %.4g Hz: residual %.1e, error %.1e (order %d)", f_hz, residual, err, self.order)
        return err, X

    def verify(self, freqs) -> dict:
        """Check once more at the worst-residual point of ``freqs``; report all checks.

        Returns
        -------
        dict
            ``order, tol, verified, n_checks, max_check_error, final_check, checks``.
        """
        res = self.residual(freqs)
        k = int(np.argmax(res))
        err, _ = self._check(freqs[k], res[k])
        self.verified = self.verified and err <= self.tol
        return {"order": self.order, "tol": self.tol, "verified": bool(self.verified),
                "n_checks": len(self.checks), "max_residual_on_grid": float(res[k]),
                "final_check": self.checks[-1],
                "max_check_error": float(max(c["rel_error"] for c in self.checks if c["order"] == self.order)),
                "checks": self.checks}
