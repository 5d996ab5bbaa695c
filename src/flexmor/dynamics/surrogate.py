"""A verified surrogate of the full model's responses for large models.

A direct sweep costs one sparse complex factorization per grid point, and the adaptive grid
of a band with tens of resonances has a thousand points or more. The surrogate replaces
those solves by a large Galerkin projection of the full model whose accuracy is checked
against direct solves:

1. basis ``V``: the modes of the modal pre-pass (up to 1.1 ``fmax``), the static response
   ``(K - sigma M)^{-1} B`` and ``n_krylov - 1`` second-order Krylov blocks
   ``(K - sigma M)^{-1} M X`` from the pre-pass factorization, and as many from the factorization
   of the pre-pass's inertia count at ``(2 pi 1.1 fmax)^2`` where it is kept (no new factorization:
   the vectors about ``sigma`` alone converge slowly towards the band's end, where a mode just
   above the pre-pass's last one dominates);
2. greedy verification: the relative residual ``||A(w) V x(w) - B||_F / ||B||_F`` is
   evaluated on candidate frequencies (cheaply, through the Gram matrix of
   ``[K V, M V, D V, B]``); at the frequency with the largest residual the full model is
   solved (a check) and the pointwise error of the surrogate ``||H - H_s||_F / ||H||_F`` is
   measured. If it exceeds ``tol``, the full solution is added to the basis (rational Krylov
   enrichment) and the step is repeated; it stops after two consecutive checks below ``tol``;
3. :meth:`Surrogate.verify` repeats the check at the worst-residual point of the final grid.

A check solves the full model iteratively (``check_solver="iterative"``): block Galerkin steps
on the surrogate's space enlarged by preconditioned residuals ``(K - sigma M)^{-1} r`` with the
pre-pass factorization (a deflated block Krylov method: the modes up to 1.1 ``fmax`` are in the
starting space, so the remaining spectrum of the preconditioned operator is clustered), until
the error estimate ``||(K - sigma M)^{-1} r||_M / ||x||_M`` is below ``1e-4 tol`` (it bounds the
error to a factor 6; the residual relative to ``B`` does not, at a resonance). Each check reports
the solver and its estimate relative to that target (``solution_residual <= 1``: converged). The
bound needs every mode below 1.1 ``fmax`` in the space (``complete``: counted by the pre-pass)
and proportional damping; otherwise the check is direct (``check_solver="direct"``): one complex
factorization, about twice the memory of the real one of the pre-pass, unless that does not fit
next to it (a million DOF on one machine).

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

from ..basis import extend_orthonormal
from ..errors import check_choice
from ..linalg import factorize
from ..linalg.backends import MEMORY_FRACTION
from ..linalg.context import SolverContext, as_solver, step
from ..linalg.threads import sparse_dense
from .frf import ShiftedMatrices, angular_frequency

__all__ = ["Surrogate", "DEFAULT_SURROGATE_TOL", "MODES_MARGIN"]

log = logging.getLogger(__name__)

#: How the checks solve the full model (see :class:`Surrogate`).
CHECK_SOLVERS = ("auto", "direct", "iterative")

#: Default largest pointwise relative error of the surrogate at its checks.
DEFAULT_SURROGATE_TOL = 1e-6

#: Error estimate (relative to ``tol``) that the iterative checks' reference solutions reach: the
#: estimate bounds the error up to a factor 6 (:meth:`Surrogate._iterative_solution`).
ITERATIVE_TARGET = 1e-4

#: The modal pre-pass of a surrogate reaches this multiple of the band's end: a mode just above
#: the band would otherwise dominate the response at its end and fail the first check there.
MODES_MARGIN = 1.1


def _orthonormal(V: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the span of the columns of ``V`` (rank-revealing QR)."""
    V = V / np.maximum(np.linalg.norm(V, axis=0), np.finfo(float).tiny)
    Q, R, _ = sla.qr(V, mode="economic", pivoting=True, check_finite=False)
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
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` for the direct checks.
    tol : float
        Largest accepted pointwise relative error at the checks.
    n_krylov : int
        Krylov blocks from the pre-pass factorization.
    max_checks : int
        Largest number of checks while building.
    check_solver : {'auto', 'direct', 'iterative'}
        How the checks solve the full model: a complex factorization, or the iterative solver
        on the pre-pass factorization; ``auto`` is iterative where its error estimate holds
        (``complete`` modes, damping diagonal in the surrogate's modes) or where twice the memory
        of the pre-pass factorization does not fit into the available memory
        (``solver.memory_available()``), else direct.
    candidates : array_like
        Frequencies (Hz) where the greedy checks look for the largest residual (e.g. the error
        grid's initial points over the band and its peaks, or a quadrature's nodes).
    edge : tuple, optional
        ``(factorization, shift)`` of ``K - shift M`` near the band's end (the pre-pass's inertia
        count, :attr:`flexmor.dynamics.modes.PrePass.edge`): ``n_krylov`` more Krylov blocks from
        it; not kept (its memory is freed when the caller holds no other reference).
    complete : bool
        ``phi`` holds all modes of the model up to 1.1 ``fmax`` (counted by the pre-pass,
        :attr:`flexmor.dynamics.modes.PrePass.complete`).
    """

    def __init__(self, model, ports, band, *, phi, factorization=None, sigma=0.0, solver: SolverContext | None = None,
                 tol: float = DEFAULT_SURROGATE_TOL, n_krylov: int = 3, max_checks: int = 10,
                 check_solver: str = "auto", candidates, edge=None, complete: bool = False):
        check_choice("check_solver", check_solver, CHECK_SOLVERS)
        solver = as_solver(solver)
        self.model, self.solver, self.tol = model, solver, float(tol)
        self.B = ports.B.toarray()
        self.C = ports.C
        self._shifted: ShiftedMatrices | None = None  # A(w) assembled: direct checks only
        F0 = factorization or factorize((model.K - sigma * model.M).tocsr(), solver=solver, positive=sigma < 0)
        self._F0 = F0
        blocks = [phi]
        for F in (F0, None if edge is None else edge[0]):
            if F is not None:
                blocks.append(F.solve(self.B))
                for _ in range(int(n_krylov) - 1):
                    blocks.append(F.solve(sparse_dense(model.M, blocks[-1])))
        del edge, F
        self._set_basis(np.hstack(blocks))
        if check_solver == "auto":
            est, avail = F0.memory_estimate, solver.memory_available()
            tight = bool(est and avail and 2 * est > MEMORY_FRACTION * avail)
            check_solver = "iterative" if tight or (complete and self._modal is not None) else "direct"
        self.check_solver = check_solver
        self.checks = []
        cand = np.unique(np.asarray(candidates, float))
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
        log.info("surrogate of order %d, %d %s checks", self.order, len(self.checks), self.check_solver)

    def release(self) -> None:
        """Drop the reference to the pre-pass factorization (no more checks after this)."""
        self._F0 = None

    @property
    def order(self) -> int:
        """Number of basis vectors."""
        return self.V.shape[1]

    def _set_basis(self, V):
        m = self.model
        self.V = _orthonormal(V)
        KV, MV = sparse_dense(m.K, self.V), sparse_dense(m.M, self.V)
        DV = sparse_dense(m.D, self.V)
        self.Kr, self.Mr, self.Dr = (self.V.T @ X for X in (KV, MV, DV))
        self.Br, self.Cr = self.V.T @ self.B, np.asarray(self.C @ self.V)
        P = (KV, MV, DV, self.B)  # the Gram matrix of [K V, M V, D V, B] by blocks (no copy of them side by side)
        G = [[X.T @ Y if i <= j else None for j, Y in enumerate(P)] for i, X in enumerate(P)]
        self._gram = np.block([[G[i][j] if i <= j else G[j][i].T for j in range(4)] for i in range(4)])
        lam, psi = sla.eigh((self.Kr + self.Kr.T) / 2, (self.Mr + self.Mr.T) / 2)
        self._psi = psi
        d = psi.T @ self.Dr @ psi
        off = np.abs(d - np.diag(np.diag(d))).max()
        self._modal = (lam, np.diag(d), self.Cr @ psi, psi.T @ self.Br) if off <= 1e-10 * np.abs(d).max() else None

    def reduced_solution(self, w):
        """Coordinates ``x(w)`` in the basis ``V`` of the surrogate's solutions ``V x(w) ≈ A(w)^{-1} B`` at the
        angular frequencies ``w``, shape (len(w), order, n_inputs)."""
        if self._modal is not None:
            lam, d, _, PB = self._modal
            psi = self._psi
            Y = (1.0 / (lam - w[:, None] ** 2 + 1j * w[:, None] * d))[:, :, None] * PB  # (f, k, m) modal
            Yk = Y.transpose(1, 0, 2).reshape(lam.size, -1)  # one GEMM with psi for all frequencies
            return (psi @ Yk.real + 1j * (psi @ Yk.imag)).reshape(psi.shape[0], w.size, -1).transpose(1, 0, 2)
        A = (self.Kr[None] - (w ** 2)[:, None, None] * self.Mr[None] + (1j * w)[:, None, None] * self.Dr[None])
        return np.linalg.solve(A, np.broadcast_to(self.Br.astype(complex), (w.size, *self.Br.shape)))

    def frf(self, freqs) -> np.ndarray:
        """Surrogate FRF, shape (n_freq, n_outputs, n_inputs)."""
        w = angular_frequency(freqs)
        if self._modal is not None:  # proportional damping: diagonal in the reduced modes
            lam, d, CP, PB = self._modal
            out = np.empty((w.size, CP.shape[0], PB.shape[1]), complex)
            for s in range(0, w.size, 256):
                ws = w[s:s + 256, None]
                out[s:s + 256] = np.einsum("pk,fk,km->fpm", CP, 1.0 / (lam - ws ** 2 + 1j * ws * d), PB)
            return out
        X = self.reduced_solution(w)
        return np.einsum("pr,frm->fpm", self.Cr, X)

    def residual(self, freqs) -> np.ndarray:
        """Relative residual ``||A(w) V x(w) - B||_F / ||B||_F`` of the surrogate, per frequency."""
        w = angular_frequency(freqs)
        m = self.B.shape[1]
        r2 = np.empty(w.size)
        step = max(1, 4096 // m)  # frequencies per chunk: one real GEMM with the Gram matrix for all of them
        for s in range(0, w.size, step):
            ws = w[s:s + step]
            X = self.reduced_solution(ws)
            c = np.concatenate([X, -(ws ** 2)[:, None, None] * X, (1j * ws)[:, None, None] * X,
                                np.broadcast_to(-np.eye(m), (ws.size, m, m))], axis=1)
            C = c.transpose(1, 0, 2).reshape(c.shape[1], -1)  # (a, frequencies x inputs)
            GC = self._gram @ C.real + 1j * (self._gram @ C.imag)
            r2[s:s + step] = np.einsum("aj,aj->j", C.conj(), GC).real.reshape(ws.size, m).sum(1)
        return np.sqrt(np.maximum(r2, 0.0)) / np.linalg.norm(self.B)

    def _check(self, f_hz: float, residual: float):
        w = 2 * np.pi * f_hz
        info = {"solver": self.check_solver}
        with step(self.solver.progress, f"surrogate check at {f_hz:.4g} Hz (order {self.order})") as note:
            if self.check_solver == "direct":
                if self._shifted is None:
                    self._shifted = ShiftedMatrices(self.model.K, self.model.M, self.model.D)
                F = factorize(self._shifted(w), solver=self.solver, symmetric=True, check=False)
                X = F.solve(self.B)
                del F
            else:
                X, info["solution_residual"], info["iterations"] = self._iterative_solution(w)
            H = np.asarray(self.C @ X)
            err = float(np.linalg.norm(H - self.frf([f_hz])[0]) / np.linalg.norm(H))
            if info.get("solution_residual", 0.0) > 1.0:  # the reference is not accurate enough:
                err = float("inf")  # the check fails (and the surrogate is enriched with X)
            note["result"] = f"error {err:.1e}"
        self.checks.append({"freq_hz": float(f_hz), "residual": float(residual), "rel_error": err,
                            "order": self.order, **info})
        log.debug("surrogate check at %.4g Hz: residual %.1e, error %.1e (order %d)", f_hz, residual, err, self.order)
        return err, X

    def _iterative_solution(self, w: float, max_iter: int = 60):
        """``A(w)^{-1} B`` by block Galerkin steps on ``span(V)`` enlarged by preconditioned residuals.

        Stops when the error estimate ``||Z||_M / ||X||_M`` with ``Z = (K - sigma M)^{-1} (B - A(w) X)`` is
        below :data:`ITERATIVE_TARGET` times ``tol``. With the modes below 1.1 ``fmax`` in the space
        (``complete``) the Galerkin condition leaves the residual without their parts, and on the modes
        above, ``(K - sigma M)^{-1}`` differs from ``A(w)^{-1}`` by a factor ``(lam - sigma) / |lam - w^2 +
        i w d|`` below 6 for ``lam >= (1.1 w)^2`` (proportional damping): the estimate is the error in the
        M-norm to that factor, at a resonance too (where the residual relative to ``B`` says nothing: a
        response 500 times the static one leaves a residual of ``B``'s size in the rounding of
        ``A X``). Returns ``(X, estimate / target, iterations)``. The first step takes the surrogate's
        reduced matrices; each further one costs a sparse product and a solve with the pre-pass
        factorization for the new block, and only the basis ``W`` and ``W^T A W`` are stored.
        """
        m = self.model
        M = m.M

        def apply(X):  # A(w) X without assembling A(w): real products with K, M, D (no complex copy of them)
            if np.iscomplexobj(X):
                return apply(X.real) + 1j * apply(X.imag)
            Y = sparse_dense(m.K, X) - w ** 2 * sparse_dense(M, X)
            return Y + 1j * w * sparse_dense(m.D, X) if m.D is not None else Y

        target = ITERATIVE_TARGET * self.tol
        W = self.V
        Ar = self.Kr - w ** 2 * self.Mr + 1j * w * self.Dr
        for it in range(max_iter + 1):
            X = W @ np.linalg.solve(Ar, W.T @ self.B)
            Z = self._F0.solve(self.B - apply(X))
            est = float(np.sqrt(max(np.vdot(Z, sparse_dense(M, Z)).real, 0.0)
                                / max(np.vdot(X, sparse_dense(M, X)).real, 1e-300)))
            if est <= target or it == max_iter:
                break
            N = extend_orthonormal(W, np.hstack([Z.real, Z.imag]))
            if N.shape[1] == 0:
                break
            AN = apply(N)
            WAN = W.T @ AN  # A is complex symmetric: N^T A W = (W^T A N)^T
            Ar = np.block([[Ar, WAN], [WAN.T, N.T @ AN]])
            W = np.hstack([W, N])
        log.debug("iterative check at %.4g Hz: error estimate %.1e after %d steps (basis %d)", w / (2 * np.pi), est,
                  it, W.shape[1])
        return X, est / target, it

    def verify(self, freqs) -> dict:
        """Check once more at the worst-residual point of ``freqs``; report all checks.

        Returns
        -------
        dict
            ``order, tol, verified, n_checks, max_check_error, final_check, checks``;
            ``final_check_reused`` when the worst point had been checked with the same basis.
        """
        res = self.residual(freqs)
        k = int(np.argmax(res))
        same = [c for c in self.checks if c["order"] == self.order and c["freq_hz"] == float(freqs[k])]
        if same:  # the worst point was checked with this very basis already: its solve would repeat
            final = same[-1]
        else:
            self._check(freqs[k], res[k])
            final = self.checks[-1]
        self.verified = self.verified and final["rel_error"] <= self.tol
        return {"order": self.order, "tol": self.tol, "verified": bool(self.verified),
                "n_checks": len(self.checks), "max_residual_on_grid": float(res[k]),
                "final_check": final, "final_check_reused": bool(same),
                "max_check_error": float(max(c["rel_error"] for c in self.checks if c["order"] == self.order)),
                "checks": self.checks}
