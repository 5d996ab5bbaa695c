"""Second-order Krylov moment matching: block second-order Arnoldi at one or several points.

For ``H(s) = C (s^2 M + s D + K)^{-1} B`` and an expansion point ``sigma``, write
``s = sigma + t`` and ``A0 = sigma^2 M + sigma D + K``, ``A1 = 2 sigma M + D``. The
moments (Taylor coefficients) of ``H`` around ``sigma`` are ``H_j = C X_j`` with

    A0 X_0 = B,    A0 X_j = -(A1 X_{j-1} + M X_{j-2}),

and ``d^j H/ds^j (sigma) = j! H_j``. If ``span(V)`` contains ``X_0 ... X_{k-1}``, the one-sided
(Galerkin) projection matches ``H`` and its first ``k - 1`` derivatives at ``sigma`` and keeps
the reduced body mechanical (symmetric ``Mr``, ``Kr``). With ``V`` spanning the moments of
both ``B`` and ``C^T`` (``side='both'``) twice as many moments are matched.

The moments are never formed explicitly: the block second-order Arnoldi process
orthonormalizes the upper half of the first-order Krylov vectors of
``[[-A0^{-1} A1, -A0^{-1} M], [I, 0]]`` and carries the lower half along, which is
numerically stable for any number of moments. One factorization of ``A0`` per point
(:func:`flexmor.linalg.factorize`) serves all moments and all right-hand sides.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..basis import Basis, Columns, extend_orthonormal, rank_revealing_qr
from ..errors import OptionError, SolverError, check_choice
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import default_shift
from ..linalg.threads import blas_threads
from ..options import Band, band_option, option
from . import register_method
from .free_body import rigid_body_modes, rigid_head
from .krylov_check import POINTS_TOL, nested_estimate

__all__ = ["krylov", "KrylovOptions", "parse_points", "default_points", "SecondOrderArnoldi", "start_block",
           "rigid_body_modes", "points_option", "side_option", "rigid_option"]

log = logging.getLogger(__name__)

SIDES = ("input", "output", "both")
RIGID = ("include", "exclude")

#: Relative size below which a new Krylov direction counts as dependent (deflated).
DEFLATION_TOL = 1e-10


def points_option(what: str = "expansion points", default: str = "krylov's (one real point at the band's geometric "
                  "mean, checked by points_tol)"):
    """The ``points`` option (text or numbers in Hz, :func:`parse_points`) of the Krylov-based methods."""
    return option(None, f"{what} in Hz, s = 2 pi p: 0, 300j (frequency axis), -5 (real); default {default}",
                  metavar="P1,P2")


def side_option(default: str = "input", choices=SIDES):
    """The ``side`` option: Krylov (or snapshot) space of ``B``, ``C^T`` or both."""
    return option(default, "space of the inputs B, the outputs C^T or both", choices=choices)


def rigid_option(default: str = "include"):
    """The ``rigid`` option: the rigid-body modes of a free body in the basis or not."""
    return option(default, "rigid-body modes of a free body in the basis", choices=RIGID)


def parse_points(points) -> np.ndarray:
    """Expansion points in Hz as a complex array; ``s = 2 pi p``.

    ``points`` is a sequence of numbers or a comma-separated string such as ``"0,300j,-5"``:
    a real ``p`` is the real point ``s = 2 pi p`` (rad/s), an imaginary ``p = f j`` the point
    ``s = i 2 pi f`` on the frequency axis at ``f`` Hz, ``a+bj`` a general complex point.
    """
    if isinstance(points, str):
        try:
            vals = [complex(t.strip().replace(" ", "")) for t in points.split(",") if t.strip()]
        except ValueError:
            raise OptionError(f"points must be numbers in Hz like 0,300j,-5 (j marks imaginary), got {points!r}",
                              params=("points",)) from None
    else:
        vals = list(np.atleast_1d(np.asarray(points, dtype=complex)))
    p = np.asarray(vals, dtype=complex)
    if p.size == 0 or not np.all(np.isfinite(p)):
        raise OptionError(f"points must be a non-empty list of finite numbers (Hz), got {points!r}",
                          params=("points",))
    return p


def default_points(band, n: int = 3) -> np.ndarray:
    """``n`` real points ``s = 2 pi f`` with ``f`` log-spaced over the band (Hz).

    Real positive points make ``sigma^2 M + sigma D + K`` symmetric positive definite (fast
    Cholesky-type solvers, no singularity for free-free bodies) and each contributes one real
    vector per moment and input, half the cost of a complex point.
    """
    fmin, fmax = Band.of(band)
    if n == 1:
        return np.array([np.sqrt(fmin * fmax) + 0j])
    return np.geomspace(max(fmin, fmax / 100), fmax, n).astype(complex)


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
    A = (s.real ** 2) * model.M + model.K if real else (s * s) * model.M + model.K
    if model.D is not None and s != 0:
        A = A + (s.real if real else s) * model.D
    try:
        return factorize(A.tocsr(), solver=solver, symmetric=True, positive=real and s.real >= 0), s
    except SolverError:
        if s != 0:
            raise
    s0 = math.sqrt(-default_shift(model.K, model.M))
    log.warning("K is singular (free body?): expansion point 0 moved to the real point s = %.4g rad/s", s0)
    return shifted_factorization(model, complex(s0), solver)


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

    def _orthogonalize(self, top: np.ndarray):
        """Block CGS2 of ``top`` against ``Q``: ``(new, t)`` with ``t`` the coefficients of ``top``.

        As :func:`flexmor.basis.extend_orthonormal` (unit columns, projection, rank-revealing QR,
        deflation below ``tol``, a second projection), with the QR between the two passes: the
        second pass projects orthonormal directions, so ``Q^H new`` is at round-off without the
        third pass a nearly dependent block otherwise needs (``Q`` is read four times per block).
        In place on Fortran-ordered blocks (BLAS ``gemm``); ``t`` (the coefficients in
        ``[Q, new]``) comes from the projections and triangular factors, not another pass.
        """
        Q = self.Q.view
        n, b = top.shape
        eta0 = Q.shape[1]
        t = np.zeros((eta0, b), dtype=Q.dtype, order="F")
        nrm = np.linalg.norm(top, axis=0)
        nz = np.flatnonzero(nrm > 0)
        if nz.size == 0:
            return np.zeros((n, 0), Q.dtype), t
        X = np.asfortranarray(top[:, nz] / nrm[nz], dtype=Q.dtype)
        if eta0:
            h = _gemm(Q, X, conj=True)
            X = _gemm(Q, h, into=X)
            t[:, nz] = h * nrm[nz]
        W, R, piv = rank_revealing_qr(X)
        k = int(np.sum(np.abs(np.diag(R)) > self.tol))
        new, Rk = W[:, :k], R[:k] * nrm[nz[piv]]  # top[:, nz[piv]] = Q t[:, nz[piv]] + new Rk (+ deflated part)
        if eta0 and k:  # second pass: W = Q g + new R2
            g = _gemm(Q, new, conj=True)
            new, R2 = np.linalg.qr(_gemm(Q, g, into=np.asfortranarray(new)))
            t[:, nz[piv]] += g @ Rk
            Rk = R2 @ Rk
        tn = np.zeros((k, b), dtype=Q.dtype)
        tn[:, nz[piv]] = Rk
        return new, np.vstack([t, tn])

    def _append(self, top: np.ndarray, bottom: np.ndarray):
        """Add the 2n-vectors ``[top; Q bottom]`` (``top`` n-long, ``bottom`` coefficients)."""
        eta0 = self.Q.k
        new, t = self._orthogonalize(top)
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
        self.Q.append(new)
        self.U = np.hstack([U, W[:, :k]]) if U.shape[1] else np.ascontiguousarray(W[:, :k])
        self._last = W[:, :k]
        return self.Q.view[:, eta0:]

    def last_top(self) -> np.ndarray:
        """Upper half ``Q U1`` of the newest orthonormal block of ``2n``-vectors (not orthonormal)."""
        return _gemm(self.Q.view, self._last[: self._last.shape[0] // 2])

    def next_block(self):
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
        c = self._last
        u1, u2 = c[: c.shape[0] // 2], c[c.shape[0] // 2:]
        self._last = None
        b = u1.shape[1]
        # rhs = tau A1 V + tau^2 M L with A1 = 2 s M + D, V = Q u1 and L = Q u2: one product with Q, one with M
        w = (2 * self.s * self.tau) * u1 + self.tau ** 2 * u2
        P = _gemm(self.Q.view, np.hstack([w, u1]) if self.D is not None else w)
        rhs = self.M @ P[:, :b]
        if self.D is not None:
            rhs += self.tau * (self.D @ P[:, b:])
        del P  # memory: the basis and a few n x b blocks
        if not np.any(rhs):  # e.g. s = 0 without damping: odd moments vanish, no solve needed
            return self._append(np.zeros_like(rhs), u1)
        top = -self._project(self.F.solve(rhs))
        self.n_solves += 1
        return self._append(top, u1)


def _gemm(Q: np.ndarray, h: np.ndarray, *, conj: bool = False, into: np.ndarray | None = None) -> np.ndarray:
    """``Q @ h``, ``Q^H @ h`` (``conj``) or ``into - Q @ h`` (in place if ``into`` is Fortran-ordered
    of the type) by BLAS ``gemm``: for a tall ``Q`` and few columns 2-3x faster than ``@``."""
    gemm = sla.blas.get_blas_funcs("gemm", (Q, h))
    if into is not None:
        return gemm(-1.0, Q, h, 1.0, into, overwrite_c=True)
    return gemm(1.0, Q, h, trans_a=(2 if np.iscomplexobj(Q) else 1) if conj else 0)


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
    proj = None
    if rigid_modes is not None and rigid_modes.shape[1]:

        def proj(X):
            return X - rigid_modes @ (rigid_modes.T @ (model.M @ X))

    blocks, used = [], []
    for p in points:
        with blas_threads(1):  # tall-skinny products between solves (see flexmor.linalg.threads)
            out, s = _point_blocks(model, start, p, n_moments, solver, proj)
        blocks.append(out)
        used.append(s)
    return blocks, used


def _point_blocks(model, start, p, n_moments: int, solver: SolverContext, proj):
    """The orthonormal blocks of one point (see :func:`blocks_at_points`) and its ``s``.

    A real point's blocks are views of its Arnoldi basis (no copy); a complex point's come
    from the real and imaginary parts of the upper halves of its orthonormal Arnoldi blocks,
    orthonormalized (a direction counts when its real or imaginary part is new).
    """
    F, s = shifted_factorization(model, 2 * np.pi * complex(p), solver)
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


def merge_blocks(blocks, order: int | None = None, *, orthonormal: bool = False) -> np.ndarray:
    """Merge per-point blocks round-robin (moment 0 of every point, then moment 1, ...).

    With ``orthonormal=True`` (the blocks of each point are orthonormal, as from
    :func:`blocks_at_points`) a single point needs no further work; otherwise, and for
    several points, the blocks are merged by block Gram-Schmidt with deflation.
    """
    nonempty = [b for b in blocks if b]
    if orthonormal and len(nonempty) == 1:  # one point: its blocks are orthonormal already
        V = np.hstack(nonempty[0])
        return V[:, :order] if order is not None else V
    n = nonempty[0][0].shape[0]
    V = Columns(n)
    with blas_threads(1):
        for j in range(max(len(b) for b in blocks)):
            for b in blocks:
                if j < len(b):
                    V.append(extend_orthonormal(V.view, b[j], tol=DEFLATION_TOL))
                    if order is not None and V.k >= order:
                        return np.ascontiguousarray(V.view[:, :order])
    return np.ascontiguousarray(V.view)


@dataclass(frozen=True)
class KrylovOptions:
    """Options of :func:`krylov`."""

    points: str | None = points_option()
    moments: int | None = option(None, "moments (blocks) per expansion point (default: as many as the order needs)",
                                 parse=int)
    side: str = side_option()
    band: Band | None = band_option("the default expansion points")
    rigid: str = rigid_option()
    points_tol: float = option(POINTS_TOL, "largest estimated band error of the default single point; above it "
                               "the band's outer default points are added", parse=float)


@register_method("krylov", "second-order block Krylov moment matching at expansion points", options=KrylovOptions)
def krylov(model, ports, order, *, points=None, moments: int | None = None, side: str = "input",
           band=None, rigid: str = "include", points_tol: float = POINTS_TOL,
           solver: SolverContext | None = None) -> Basis:
    """Second-order block Krylov (moment matching) basis at one or several expansion points.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        ``B`` and ``C`` give the starting blocks.
    order : int or None
        Reduced dimension r; the basis is truncated to r columns (moment by moment, over all
        points). None: ``moments`` per point decide.
    points : str or sequence of complex, optional
        Expansion points in Hz, ``s = 2 pi p`` (see :func:`parse_points`): ``"0"`` is the
        classic static point, ``"300j"`` interpolates at 300 Hz on the frequency axis (complex
        solve; contributes real and imaginary parts), real positive points are cheap and
        safe for free bodies. Default: one real point at the geometric mean of ``band`` (one
        factorization), checked by the estimated band error of
        :func:`flexmor.reduction.krylov_check.nested_estimate`; when the estimate exceeds
        ``points_tol`` (and ``order`` is given), the basis is rebuilt at three real points
        (the single point and the outer two of :func:`default_points`; the single point's blocks
        are reused, so two more factorizations). ``info['points_check']``
        reports the estimate(s).
    moments : int, optional
        Moments (blocks) per point; default as many as ``order`` needs. A point delivers
        ``moments`` blocks' worth of independent columns: moments that vanish (odd moments
        at ``s = 0`` without damping) or deflate are replaced by further ones.
    side : {'input', 'output', 'both'}
        Krylov space of ``B`` (input), of ``C^T`` (output) or of both.
    band : (float, float), optional
        Band (Hz) for the default points; default (1, 1000).
    points_tol : float
        Largest estimated band error of the default single point (see ``points``).
    rigid : {'include', 'exclude'}
        Free bodies (rigid-body modes found from the geometry, :func:`rigid_body_modes`):
        the Krylov vectors are kept M-orthogonal to the rigid-body modes (moments of the
        flexible part of ``H``; for proportional damping ``H`` is rigid part + flexible part,
        so nothing is lost), which removes the round-off that nearly singular shifts would
        otherwise put into the basis. ``include`` (default) puts the rigid-body modes that
        the ports excite first in the basis: the reduced body moves rigidly like the full one
        and all moments of ``H`` are matched. ``exclude`` leaves them out, as the floating
        frame of reference wants (it describes rigid motion itself); then the moments of the
        flexible part are matched. A point 0 on a free body (singular ``K``) is moved to a
        small real shift.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` (one factorization per point).

    Returns
    -------
    Basis
        ``info``: ``points_hz`` (as given), ``points_rad_s`` (used), ``moments``, ``side``,
        ``n_rigid_excluded``, ``nested`` (its leading columns are the basis of lower order),
        ``points_check`` (default points: the estimates and the choice).

    References
    ----------
    Salimbahrami, B., Lohmann, B. (2006). Order reduction of large scale second-order systems
    using Krylov subspace methods. Linear Algebra Appl. 415, 385-405.

    Bai, Z., Su, Y. (2005). Dimension reduction of large-scale second-order dynamical systems
    via a second-order Arnoldi method. SIAM J. Sci. Comput. 26(5), 1692-1709.

    Grimme, E. J. (1997). Krylov projection methods for model reduction. PhD thesis,
    University of Illinois at Urbana-Champaign (multiple expansion points).
    """
    solver = as_solver(solver)
    check_choice("side", side, SIDES)
    check_choice("rigid", rigid, RIGID)
    band = Band.of(band)
    pts = parse_points(points) if points is not None else default_points(band, 1)
    if order is None and moments is None:
        raise OptionError("krylov needs order or moments", params=("order", "moments"))
    if moments is not None and (int(moments) != moments or moments < 1):
        raise OptionError(f"moments must be a positive integer, got {moments}", params=("moments",))
    if order is not None and order > model.n_dof:
        raise OptionError(f"order {order} exceeds the number of DOF {model.n_dof}", params=("order",))
    if not float(points_tol) > 0:
        raise OptionError(f"points_tol must be positive, got {points_tol}", params=("points_tol",))
    b = start_block(ports, side).shape[1]
    phi, excited = rigid_head(model, start_block(ports, side), rigid)  # the rigid motion the ports excite, first
    head = [[excited]] if excited.shape[1] else []
    cache = {}
    V, k, used = _basis_at(model, ports, pts, order, moments, b, head, side, solver, phi, cache)
    check = None
    if points is None and order is not None:
        check = {"tol": float(points_tol), "single_point": nested_estimate(model, ports, V, b, band)}
        if check["single_point"]["estimate"] > float(points_tol):  # the outer two of the three default points,
            pts = np.sort_complex(np.concatenate([pts, default_points(band)[[0, 2]]]))  # lowest first, as before
            log.info("krylov: estimated band error %.1e of one point > %.1e: %d points",
                     check["single_point"]["estimate"], points_tol, pts.size)
            V, k, used = _basis_at(model, ports, pts, order, moments, b, head, side, solver, phi, cache)
        check["n_points"] = int(pts.size)
    n_rb = int(phi.shape[1]) if rigid == "exclude" else 0
    if order is not None and V.shape[1] < order:
        log.warning("krylov: only %d independent directions for order %d (deflation)", V.shape[1], order)
    info = {"points_hz": [str(p) for p in pts], "points_rad_s": [str(s) for s in used], "moments": k,
            "side": side, "rigid": rigid, "n_rigid": int(phi.shape[1]), "n_rigid_excluded": n_rb,
            "n_rigid_included": int(head[0][0].shape[1]) if head else 0, "nested": True}
    if check is not None:
        info["points_check"] = check
    return Basis(V, "krylov", info)


def _basis_at(model, ports, pts, order, moments, b, head, side, solver, phi, cache):
    """The merged basis at the points ``pts``: ``(V, moments per point, points used)``.

    ``cache`` maps a point to its blocks, ``s`` and moments from an earlier call; a point's
    blocks are nested moment by moment, so a call that needs fewer moments reuses their leading
    ``moments * b`` columns' worth (no new factorization).
    """
    per_round = sum(b * (1 if p.imag == 0 else 2) for p in pts)
    k = int(moments) if moments is not None else math.ceil(order / per_round)
    for _ in range(4):
        blocks, used = [], []
        for p in pts:
            if p not in cache or cache[p][2] < k:
                got, s = blocks_at_points(model, ports, [p], k, side=side, solver=solver, rigid_modes=phi)
                cache[p] = (got[0], s[0], k)
            share = k * b * (1 if p.imag == 0 else 2)  # columns of the point (see _point_blocks)
            cols = np.cumsum([bl.shape[1] for bl in cache[p][0]])
            blocks.append(cache[p][0][:int(np.searchsorted(cols, share)) + 1])
            used.append(cache[p][1])
        V = merge_blocks(head + blocks, order, orthonormal=not head)
        exhausted = all(len(bl) < k for bl in blocks)
        if moments is not None or V.shape[1] >= order or exhausted:
            break
        # deflation (e.g. real solutions at points on the frequency axis of an undamped body):
        # more moments per point fill the order
        k += math.ceil((order - V.shape[1]) / per_round) + 1
    return V, k, used
