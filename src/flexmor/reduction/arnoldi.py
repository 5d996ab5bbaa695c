"""The block second-order Arnoldi process of :mod:`flexmor.reduction.krylov`.

For the pencil ``A0 = sigma^2 M + sigma D + K``, ``A1 = 2 sigma M + D`` of an expansion point,
:class:`SecondOrderArnoldi` orthonormalizes the upper half of the first-order Krylov vectors of
``[[-A0^{-1} A1, -A0^{-1} M], [I, 0]]`` (stored as ``[Q U1; Q U2]`` with one orthonormal
``n x eta`` basis ``Q``) by block classical Gram-Schmidt with reorthogonalization and
deflation, one factorization of ``A0`` serving every block.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import scipy.linalg as sla

from ..basis import Columns, extend_orthonormal, rank_revealing_qr
from ..errors import SolverError, check_choice
from ..linalg import factorize
from ..linalg.backends import is_iterative
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import default_shift
from ..linalg.factorize import factorize_shifted
from ..linalg.threads import blas_threads, dense_threads, sparse_dense
from ..rigid import m_project
from ._options import SIDES

__all__ = ["SecondOrderArnoldi", "DEFLATION_TOL", "start_block", "shifted_factorization", "blocks_at_points",
           "rigid_projector"]

log = logging.getLogger(__name__)

#: Relative size below which a new Krylov direction counts as dependent (deflated).
DEFLATION_TOL = 1e-10


class SecondOrderArnoldi:
    """Block second-order Arnoldi sequence at one expansion point ``s`` in two-level form (TOAR).

    Block Arnoldi on the linearization ``[[-A0^{-1} tau A1, -A0^{-1} tau^2 M], [I, 0]]``
    started with ``[A0^{-1} start; 0]``, with the Taylor variable scaled by ``tau`` (a
    frequency of the point and of the body) so that both halves have comparable size. The
    upper halves of the first ``k`` blocks span ``{X_0 ... X_{k-1}}``; orthogonalizing the full
    vectors (twice, with deflation) keeps the process stable even when an upper half
    vanishes (e.g. ``s = 0`` with stiffness-proportional damping, where ``X_1 || X_0``).

    The lower half of every Krylov vector is an upper half of an earlier one, so all
    ``2n``-vectors are stored as ``[Q U1; Q U2]`` with one orthonormal ``n x eta`` basis ``Q``
    of the upper halves and small coefficient matrices (two-level orthogonal Arnoldi): the
    memory is that of ``Q``, the basis the method wants, instead of ``3x`` it for the
    ``2n``-vectors and a separate basis; the orthogonalization of the ``2n``-vectors runs on
    the ``2 eta``-long coefficients.

    Each call of :meth:`next_block` returns the new columns of ``Q`` (orthonormal to the
    earlier ones; complex if ``s`` is; none when a moment lies in the span already) or
    ``None`` when the sequence is exhausted; :meth:`last_top` is the upper half of the
    newest orthonormal ``2n``-block.

    References
    ----------
    Lu, D., Su, Y., Bai, Z. (2016). Stability analysis of the two-level orthogonal Arnoldi
    procedure. SIAM J. Matrix Anal. Appl. 37(1), 195-214.
    """

    def __init__(self, model, F, s: complex, start: np.ndarray, *, tol: float = DEFLATION_TOL, project=None,
                 capacity: int = 16):
        self.M, self.D, self.F, self.tol = model.M, model.D, F, tol
        self._project = project if project is not None else (lambda X: X)
        s = complex(s).real if complex(s).imag == 0 else complex(s)
        self.s, self.n_solves, self.tau = s, 0, 1.0
        self._start = start
        self._K = model.K
        dtype = np.result_type(start.dtype, float) if isinstance(s, float) else np.complex128
        self.Q = Columns(model.M.shape[0], dtype, capacity=max(int(capacity), 1))
        self.U = np.zeros((0, 0), dtype=dtype)  # coefficients [U1; U2] of the 2n-vectors, (2 eta, k)
        self._last = None  # coefficients of the last orthonormal block
        self._P = None  # Q [w, u1] of the next right-hand side (next_block)

    def _orthogonalize(self, top: np.ndarray, *, overwrite: bool = False):
        """Block CGS2 of ``top`` against ``Q``: ``(new, t, second)`` with ``t`` the coefficients of ``top``.

        As :func:`flexmor.basis.extend_orthonormal` (unit columns, projection, rank-revealing QR,
        deflation below ``tol``, a second projection), with the QR between the two passes: the
        second pass projects orthonormal directions, so ``Q^H new`` is at round-off without the
        third pass a nearly dependent block otherwise needs. In place on Fortran-ordered blocks
        (BLAS ``gemm``); ``t`` (the coefficients in ``[Q, new']``) comes from the projections and
        triangular factors, not another pass.

        The second pass is left to :meth:`_append`: with ``second = (g, R2)``, ``g = Q^H new``, the
        new columns are ``new' = (new - Q g) R2^{-1}`` where ``R2^H R2 = I - g^H g`` (the Gram matrix
        of ``new - Q g`` for orthonormal ``new``; ``||g||`` is at most ``eps / tol``, so its
        Cholesky factor is as accurate as a QR). Its product ``Q g`` is then formed in the same
        pass over ``Q`` as the next right-hand side's ``Q w`` (:meth:`_second_pass`): ``Q`` is read
        four times per block. ``overwrite``: ``top`` may be overwritten.
        """
        Q = self.Q.view
        n, b = top.shape
        eta0 = Q.shape[1]
        t = np.zeros((eta0, b), dtype=Q.dtype, order="F")
        nrm = np.linalg.norm(top, axis=0)
        nz = np.flatnonzero(nrm > 0)
        if nz.size == 0:
            return np.zeros((n, 0), Q.dtype), t, None
        if overwrite and nz.size == b and top.flags.f_contiguous and top.dtype == Q.dtype:  # in place
            X = top
            X /= nrm
        else:
            X = np.asfortranarray(top[:, nz] / nrm[nz], dtype=Q.dtype)
        if eta0:
            h = _gemm(Q, X, conj=True)
            X = _gemm(Q, h, into=X)
            t[:, nz] = h * nrm[nz]
        W, R, piv = rank_revealing_qr(X, overwrite=True)
        k = int(np.sum(np.abs(np.diag(R)) > self.tol))
        new, Rk = W[:, :k], R[:k] * nrm[nz[piv]]  # top[:, nz[piv]] = Q t[:, nz[piv]] + new Rk (+ deflated part)
        second = None
        if eta0 and k:  # second pass: new = Q g + new' R2
            g = _gemm(Q, new, conj=True)
            R2 = sla.cholesky(np.eye(k) - g.conj().T @ g, lower=False)
            t[:, nz[piv]] += g @ Rk
            Rk = R2 @ Rk
            second = (g, R2)
        tn = np.zeros((k, b), dtype=Q.dtype)
        tn[:, nz[piv]] = Rk
        return new, np.vstack([t, tn]), second

    def _append(self, top: np.ndarray, bottom: np.ndarray):
        """Add the 2n-vectors ``[top; Q bottom]`` (``top`` n-long, ``bottom`` coefficients)."""
        eta0 = self.Q.k
        new, t, second = self._orthogonalize(top, overwrite=True)  # top is ours (next_block)
        eta = eta0 + new.shape[1]
        X = np.vstack([t, np.pad(bottom, ((0, eta - bottom.shape[0]), (0, 0)))])
        U = self.U
        if U.shape[1]:  # pad the earlier coefficients to the grown basis
            U = np.vstack([np.pad(U[:eta0], ((0, eta - eta0), (0, 0))), np.pad(U[eta0:], ((0, eta - eta0), (0, 0)))])
        ref = np.linalg.norm(X, axis=0).max(initial=0.0)
        if ref == 0:
            return None
        for _ in range(2):
            if U.shape[1]:
                X -= U @ (U.conj().T @ X)
        W, R, _ = rank_revealing_qr(X)
        k = int(np.sum(np.abs(np.diag(R)) > self.tol * ref))
        if k < X.shape[1]:
            log.debug("second-order Arnoldi: %d of %d directions deflated", X.shape[1] - k, X.shape[1])
        if k == 0:
            return None
        self.U = np.hstack([U, W[:, :k]]) if U.shape[1] else np.ascontiguousarray(W[:, :k])
        self._last = W[:, :k]
        # the next right-hand side's basis product Q c, c = [w] or [w, u1] (see next_block), in the
        # pass over the old columns that completes the second Gram-Schmidt pass of the new ones
        u1, u2 = self._last[:eta], self._last[eta:]
        w = (2 * self.s * self.tau) * u1 + self.tau ** 2 * u2
        new, self._P = self._second_pass(new, second, np.hstack([w, u1]) if self.D is not None else w)
        self.Q.append(new)
        return self.Q.view[:, eta0:]

    def _second_pass(self, new: np.ndarray, second, c: np.ndarray):
        """``(new', P)``: the new columns after the second pass of :meth:`_orthogonalize` and
        ``P = [Q, new'] c``, with one product with ``Q`` for both."""
        Q = self.Q.view
        eta0 = Q.shape[1]
        if second is not None:
            g, R2 = second
            kn = g.shape[1]
            Y = _gemm(Q, np.hstack([g, c[:eta0]]))  # Fortran-ordered: its leading columns are contiguous
            new = np.subtract(new, Y[:, :kn], out=Y[:, :kn])
            trsm = sla.blas.get_blas_funcs("trsm", (R2, new))
            new = trsm(1.0, R2, new, side=1, lower=0, overwrite_b=True)  # (new - Q g) R2^{-1}, in place
            P = Y[:, kn:]
        else:
            P = _gemm(Q, c[:eta0]) if eta0 else np.zeros((Q.shape[0], c.shape[1]), dtype=c.dtype, order="F")
        if new.shape[1] and c.shape[1]:  # P += new c_new, in place
            P = sla.blas.get_blas_funcs("gemm", (new, P))(1.0, new, c[eta0:], 1.0, P, overwrite_c=True)
        return new, P

    def last_top(self) -> np.ndarray:
        """Upper half ``Q U1`` of the newest orthonormal block of ``2n``-vectors (not orthonormal)."""
        return _gemm(self.Q.view, self._last[: self._last.shape[0] // 2])

    def next_block(self):
        """Extend the basis by the next block of the second-order Krylov sequence (one solve with the
        point's factorization); returns the new orthonormal columns of ``Q`` (n, b), None once the sequence
        has deflated."""
        if self.n_solves == 0:
            X0 = self._project(self.F.solve(self._start))
            self.n_solves += 1
            x = X0[:, 0]
            mx = np.vdot(x, self.M @ x).real
            if mx > 0:  # tau^2 = Rayleigh quotient of |s|^2 M + K: the frequency scale of the point
                kx = np.vdot(x, self._K @ x).real
                self.tau = float(np.sqrt(abs(self.s) ** 2 + max(kx, 0.0) / mx)) or 1.0
            return self._append(X0, np.zeros((0, X0.shape[1]), X0.dtype))
        if self._last is None:
            return None
        u1 = self._last[: self._last.shape[0] // 2]
        P, self._P, self._last = self._P, None, None
        b = u1.shape[1]
        # rhs = tau A1 V + tau^2 M L with A1 = 2 s M + D, V = Q u1 and L = Q u2: P = Q [w, u1] from _append
        rhs = sparse_dense(self.M, P[:, :b])
        if self.D is not None:
            rhs += self.tau * sparse_dense(self.D, P[:, b:])
        del P  # memory: the basis and a few n x b blocks
        if not np.any(rhs):  # e.g. s = 0 without damping: odd moments vanish, no solve needed
            return self._append(np.zeros_like(rhs), u1)
        top = self._project(self.F.solve(rhs))
        del rhs
        np.negative(top, out=top)
        self.n_solves += 1
        return self._append(top, u1)


def _gemm(Q: np.ndarray, h: np.ndarray, *, conj: bool = False, into: np.ndarray | None = None) -> np.ndarray:
    """``Q @ h``, ``Q^H @ h`` (``conj``) or ``into - Q @ h`` (in place if ``into`` is Fortran-ordered
    of the type) by BLAS ``gemm``: for a tall ``Q`` and few columns 2-3x faster than ``@``; on
    :func:`~flexmor.linalg.threads.dense_threads` threads."""
    gemm = sla.blas.get_blas_funcs("gemm", (Q, h))
    with blas_threads(dense_threads(Q.size)):  # memory-bound: all cores for a large basis
        if into is not None:
            return gemm(-1.0, Q, h, 1.0, into, overwrite_c=True)
        return gemm(1.0, Q, h, trans_a=(2 if np.iscomplexobj(Q) else 1) if conj else 0)


def start_block(ports, side: str) -> np.ndarray:
    """Dense starting block: ``B`` (input), ``C^T`` (output) or ``[B, C^T]`` (both)."""
    check_choice("side", side, SIDES)
    blocks = []
    if side in ("input", "both"):
        blocks.append(ports.B.toarray())
    if side in ("output", "both"):
        blocks.append(ports.C.T.toarray())
    return np.hstack(blocks)


def shifted_factorization(model, s: complex, solver: SolverContext | None = None):
    """Factorize ``s^2 M + s D + K`` once; returns ``(F, s)``.

    For ``s = 0`` on a free-free body (singular ``K``) the point is moved to the real
    ``s0 = sqrt(-default_shift(K, M))``, i.e. the matrix ``K - lambda0 M`` with the negative
    eigen-shift ``lambda0`` of :func:`flexmor.linalg.eigen.default_shift`; a warning is logged
    and the point actually used is returned.
    """
    solver = as_solver(solver)
    s = complex(s)
    real = s.imag == 0
    if real and s.real > 0 and model.D is None:  # K + s^2 M: shared with the rigid-body check at this shift
        return factorize_shifted(model.K, model.M, -s.real ** 2, solver=solver), s
    A = (s.real ** 2) * model.M + model.K if real else (s * s) * model.M + model.K
    if model.D is not None and s != 0:
        A = A + (s.real if real else s) * model.D
    try:
        return factorize(A.tocsr(), solver=solver, symmetric=True, positive=real and s.real >= 0), s
    except SolverError as exc:
        if not real and is_iterative(solver.backend):  # not singular: an iterative backend solves no complex matrix
            raise SolverError(f"backend {solver.backend} solves real positive definite matrices only: the expansion "
                              f"point {s / (2 * math.pi):.6g} Hz is complex (krylov's default points lie on the "
                              "frequency axis); give real points (e.g. 0) or a direct backend",
                              params=("points", "backend")) from exc
        if s != 0:
            if not real and abs(s.real) <= 1e-12 * abs(s):  # a point on the frequency axis
                raise SolverError(f"s^2 M + s D + K is singular at the expansion point {abs(s) / (2 * math.pi):.8g} "
                                  f"Hz{'' if model.D is not None else ' of the undamped body'}: it lies at an "
                                  "eigenfrequency; move the point off it (or give the body damping)",
                                  params=("points",)) from exc
            raise
    s0 = math.sqrt(-default_shift(model.K, model.M))
    log.warning("K is singular (free body?): expansion point 0 moved to the real point s = %.4g rad/s", s0)
    return shifted_factorization(model, complex(s0), solver)


def rigid_projector(model, phi):
    """``X -> (I - Φ Φᵀ M) X`` for the rigid-body modes ``phi`` (M-orthonormal), or None when there are none."""
    if phi is None or not phi.shape[1]:
        return None
    return lambda X: m_project(model, phi, X)


def blocks_at_points(model, ports, points, n_moments: int, *, side: str = "input", solver: SolverContext | None = None,
                     rigid_modes=None):
    """Krylov blocks for every point, ``n_moments`` per point, one factorization at a time.

    Returns ``(blocks, used)``: ``blocks[p]`` the list of real, orthonormal blocks of point
    ``p`` (a complex point's block split into real and imaginary parts; together
    ``n_moments`` blocks' worth of independent columns unless the space is exhausted; the
    blocks of one point are orthonormal to each other), ``used`` the points (rad/s)
    actually used. With ``rigid_modes`` (M-orthonormal, of a free body) every new vector is
    made M-orthogonal to them: the blocks span moments of the flexible part of ``H`` (exact
    for proportional damping), without rigid-body round-off from nearly singular shifts.
    """
    solver = as_solver(solver)
    start = start_block(ports, side)
    proj = rigid_projector(model, rigid_modes)
    blocks, used = [], []
    for p in points:
        with blas_threads(1):  # tall-skinny products between solves (see flexmor.linalg.threads)
            out, s = _point_blocks(model, start, p, n_moments, solver, proj)
        blocks.append(out)
        used.append(s)
    return blocks, used


def _point_blocks(model, start, p, n_moments: int, solver: SolverContext, proj, factorization=None):
    """The orthonormal blocks of one point (see :func:`blocks_at_points`) and its ``s``; ``factorization``
    ``(F, s)``: the point's, made already.

    A real point's blocks are views of its Arnoldi basis (no copy); a complex point's come
    from the real and imaginary parts of the upper halves of its orthonormal Arnoldi blocks,
    orthonormalized (a direction counts when its real or imaginary part is new).
    """
    F, s = factorization if factorization is not None else shifted_factorization(model, 2 * np.pi * complex(p),
                                                                                   solver)
    # the point's share: n_moments blocks of independent directions; vanishing moments
    # (matched for free) and deflated directions do not count, so no second pass is needed
    b = start.shape[1]
    share = n_moments * b * (1 if s.imag == 0 else 2)
    seq = SecondOrderArnoldi(model, F, s, start, project=proj, capacity=share + b)
    T = seq.Q if s.imag == 0 else Columns(model.n_dof, capacity=share + 2 * b)
    out, empty = [], 0
    while T.k < share and empty < 3:
        Vb = seq.next_block()
        if Vb is None:
            break
        if s.imag != 0:
            top = seq.last_top()
            Vb = extend_orthonormal(T.view, np.hstack([top.real, top.imag]), tol=DEFLATION_TOL)
            T.append(Vb)
        empty = empty + 1 if Vb.shape[1] == 0 else 0
        if Vb.shape[1]:
            out.append(T.view[:, T.k - Vb.shape[1]:])
    return out, s
