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

from ..basis import Basis, Columns, extend_orthonormal
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.threads import blas_threads
from ..options import Band, band_option, option
from ._options import RIGID, SIDES, points_option, rigid_option, side_option
from ._registry import register_method
from .arnoldi import DEFLATION_TOL, blocks_at_points, shifted_factorization, start_block
from .free_body import rigid_head
from .greedy_points import greedy_basis

__all__ = ["krylov", "KrylovOptions", "parse_points", "default_points", "start_block", "blocks_at_points",
           "shifted_factorization"]

log = logging.getLogger(__name__)

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


def merge_blocks(blocks, order: int | None = None, *, orthonormal: bool = False, head=None) -> np.ndarray:
    """Merge per-point blocks round-robin (moment 0 of every point, then moment 1, ...).

    With ``orthonormal=True`` (the blocks of each point are orthonormal, as from
    :func:`blocks_at_points`) a single point needs no further work: its blocks side by side
    (a view of its Arnoldi basis, no copy, when they are consecutive columns of it); otherwise,
    and for several points, the blocks are merged by block Gram-Schmidt with deflation.
    ``head`` (n, h), optional, comes first (orthonormalized): the rigid-body modes the ports
    excite. A single point's orthonormal blocks are then orthogonalized against the head alone
    (:func:`_after_head`: projections on the few head columns and Cholesky factors of the blocks'
    Gram matrix, BLAS-3), instead of a Gram-Schmidt pass over all earlier columns per block.
    """
    nonempty = [b for b in blocks if b]
    has_head = head is not None and head.shape[1] > 0
    if orthonormal and len(nonempty) == 1:  # one point: its blocks are orthonormal already
        if not has_head:
            Q = _side_by_side(nonempty[0])
            return Q[:, :order] if order is not None else Q
        H = extend_orthonormal(None, head, tol=DEFLATION_TOL)
        V = _head_then_blocks(H, nonempty[0], order)
        if V is not None:
            return V
    blocks = [[head]] + list(blocks) if has_head else blocks
    n = (head if has_head else nonempty[0][0]).shape[0]
    V = Columns(n)
    with blas_threads(1):
        for j in range(max(len(b) for b in blocks)):
            for b in blocks:
                if j < len(b):
                    V.append(extend_orthonormal(V.view, b[j], tol=DEFLATION_TOL))
                    if order is not None and V.k >= order:
                        return np.ascontiguousarray(V.view[:, :order])
    return np.ascontiguousarray(V.view)


def _head_then_blocks(H: np.ndarray, blocks, order: int | None):
    """``[H, blocks]`` merged as block Gram-Schmidt merges them (up to round-off), or None: the
    blocks that fit the order whole through :func:`_after_head`, a block cut by the order through
    :func:`flexmor.basis.extend_orthonormal` (its pivoted choice of the leading directions)."""
    need = None if order is None else max(order - H.shape[1], 0)
    cols = np.cumsum([b.shape[1] for b in blocks])
    whole = len(blocks) if need is None else int(np.searchsorted(cols, need, side="right"))
    rest = _after_head(H, _side_by_side(blocks[:whole]) if whole else H[:, :0])
    if rest is None:
        return None
    V = np.hstack([H, rest])
    for blk in blocks[whole:]:
        if V.shape[1] >= order:
            break
        with blas_threads(1):
            V = np.hstack([V, extend_orthonormal(V, blk, tol=DEFLATION_TOL)])
    return V[:, :order] if order is not None else V


def _after_head(H: np.ndarray, Q: np.ndarray, limit: float = 0.999):
    """The orthonormal ``Q`` made orthogonal to the orthonormal ``H``, in order: ``(Q - H C) R^{-1}``
    (``C = H^T Q``, ``R^T R = I - C^T C``), then the same once more with the Gram matrix formed
    (Cholesky QR twice: orthonormal to round-off). ``R`` is upper triangular, so the leading
    columns span what ``Q``'s leading columns add to ``H``. None when a column of ``Q`` lies
    closer to ``span(H)`` than ``||C||_2 <= limit`` allows (block Gram-Schmidt with deflation
    is then the safe way)."""
    if Q.shape[1] == 0:
        return Q
    C = H.T @ Q
    if np.linalg.norm(C, 2) > limit:
        return None
    trsm = sla.blas.get_blas_funcs("trsm", (H, Q))
    X = trsm(1.0, np.linalg.cholesky(np.eye(Q.shape[1]) - C.T @ C).T, np.asfortranarray(Q - H @ C), side=1,
             overwrite_b=1)
    X -= H @ (H.T @ X)
    syrk = sla.blas.get_blas_funcs("syrk", (X,))
    return trsm(1.0, sla.cholesky(syrk(1.0, X, trans=1), lower=False), X, side=1, overwrite_b=1)  # upper triangles


def _side_by_side(blocks) -> np.ndarray:
    """``np.hstack(blocks)``, as a view when the blocks are consecutive columns of one
    Fortran-ordered array (a real point's blocks: views of its Arnoldi basis)."""
    base = blocks[0].base
    if base is not None and base.ndim == 2 and base.flags.f_contiguous and all(b.base is base for b in blocks):
        addr = [b.__array_interface__["data"][0] for b in blocks]
        start, step = divmod(addr[0] - base.__array_interface__["data"][0], base.strides[1])
        if not step and all(a1 - a0 == b.shape[1] * base.strides[1] for a0, a1, b in zip(addr, addr[1:], blocks)):
            return base[:, start:start + sum(b.shape[1] for b in blocks)]
    return np.hstack(blocks)


@dataclass(frozen=True)
class KrylovOptions:
    """Options of :func:`krylov`."""

    points: str | None = points_option()
    moments: int | None = option(None, "moments (blocks) per expansion point (default: as many as the order needs)",
                                 parse=int)
    side: str = side_option()
    band: Band | None = band_option("the default expansion points")
    rigid: str = rigid_option()
    directions: str = option("missed", "default points: at each point on the axis the blocks of the load "
                             "combinations the body misses there (missed: more points per order on bodies of many "
                             "ports, interpolation along those directions) or of every port (all: interpolation "
                             "in every port direction, kept when the body is coupled at its ports)",
                             choices=("all", "missed"))
    compress: str = option("auto", "default points at a given order: build the greedy basis to 1.5-3 times the "
                           "order and return the body of the order in its span that differs least from a reference "
                           "body with the same static responses (auto: the greedy one, its balanced truncation, or "
                           "the static responses and balancing directions), the same without keeping the static "
                           "responses (band: for a body judged at its ports alone; its deflection under slow loads "
                           "and the frame's accelerations may be off), or the greedy basis of the order (off)",
                           choices=("auto", "band", "off"))


@register_method("krylov", "second-order block Krylov moment matching at expansion points", options=KrylovOptions)
def krylov(model, ports, order, *, points=None, moments: int | None = None, side: str = "input",
           band=None, rigid: str = "exclude", directions: str = "missed", compress: str = "auto",
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
        safe for free bodies. Default (``order`` needed): chosen greedily by
        :func:`flexmor.reduction.greedy_points.greedy_basis`: the static point 0 Hz (a free body:
        a small real shift), then points on the frequency axis where the residual of the full
        equations left by the body is largest over the band, until the order is reached; one more
        factorization gives ``info['points_check']``, the estimated band error
        (:func:`flexmor.reduction.greedy_points.difference_estimate`).
    moments : int, optional
        Moments (blocks) per point; default as many as ``order`` needs. A point delivers
        ``moments`` blocks' worth of independent columns: moments that vanish (odd moments
        at ``s = 0`` without damping) or deflate are replaced by further ones.
    side : {'input', 'output', 'both'}
        Krylov space of ``B`` (input), of ``C^T`` (output) or of both.
    band : (float, float), optional
        Band (Hz) for the default points; default :data:`flexmor.options.DEFAULT_BAND`.
    rigid : {'exclude', 'include'}
        Free bodies (rigid-body modes found from the geometry, :func:`flexmor.rigid.rigid_body_modes`):
        the Krylov vectors are kept M-orthogonal to the rigid-body modes (moments of the
        flexible part of ``H``; for proportional damping ``H`` is rigid part + flexible part,
        so nothing is lost), which removes the round-off that nearly singular shifts would
        otherwise put into the basis. ``exclude`` (default) leaves them out, as the floating
        frame of reference wants (it describes rigid motion itself): the moments of the
        flexible part are matched, and the body reduced, judged (on the elastic part of ``H``)
        and stored is the one an FFRF export writes. ``include`` puts the rigid-body modes that
        the ports excite first in the basis: the reduced body moves rigidly like the full one
        and all moments of ``H`` are matched (an FFRF export refuses such a body unless asked to
        remove them, ``remove_rigid``). A point 0 on a free body (singular ``K``) is moved to a
        small real shift.
    directions : {'missed', 'all'}
        Default points: at each point on the axis only the Krylov blocks of the load combinations the body
        misses there (default), or of every port (interpolation in every port direction, which carries over
        when the body is coupled at its ports; :func:`flexmor.reduction.greedy_points.greedy_basis`).
    compress : {'auto', 'band', 'off'}
        Default points with ``directions='missed'``, ``moments`` not given, on a body without included
        rigid-body modes: ``auto``
        builds the greedy basis to 1.5 times the order (2 or 3 times while its reference is not ten times better than
        the body: :data:`flexmor.reduction.greedy_compress.GROWTH`) and returns, of the greedy body of the
        order (its leading columns), the frequency-limited balanced truncation of the larger body and the static
        responses followed by its balancing directions, the one that differs least from a reference body among
        those whose static responses are the reference's
        (:func:`flexmor.reduction.greedy_compress.compressed_greedy`; ``info['compressed']``); ``band`` the
        same among all of them, the static responses not kept (a body judged at its ports alone: fw-sobt's band
        error, with fw-sobt's static errors); ``off`` builds the greedy basis of the order.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` (one factorization per point).

    Returns
    -------
    Basis
        ``info``: ``points_hz`` (as given), ``points_rad_s`` (used), ``moments``, ``side``,
        ``n_rigid_excluded``, ``nested`` (its leading columns are the basis of lower order),
        ``points_check`` (default points: the estimate), ``rho_max`` (default points: the largest
        residual before each point on the axis).

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
    check_choice("directions", directions, ("all", "missed"))
    check_choice("compress", compress, ("auto", "band", "off"))
    band = Band.of(band)
    if order is None and moments is None:
        raise OptionError("krylov needs order or moments", params=("order", "moments"))
    if order is None and points is None:
        raise OptionError("krylov needs order for its default points (with moments alone, give points)",
                          params=("order", "points"))
    if moments is not None and (int(moments) != moments or moments < 1):
        raise OptionError(f"moments must be a positive integer, got {moments}", params=("moments",))
    if order is not None and order > model.n_dof:
        raise OptionError(f"order {order} exceeds the number of DOF {model.n_dof}", params=("order",))
    b = start_block(ports, side).shape[1]
    phi, excited = rigid_head(model, start_block(ports, side), rigid)  # the rigid motion the ports excite, first
    extra, reduced = {}, None
    if points is None:
        wide = compress != "off" and directions == "missed" and moments is None and not excited.shape[1]
        V, extra, reduced = greedy_basis(model, ports, int(order), band, side=side, solver=solver, phi=phi,
                                         head=excited, moments=moments, directions=directions,
                                         compress_to=int(order) if wide else None, keep_static=compress != "band")
        used, k = extra.pop("points_rad_s"), extra.pop("moments")
        pts = np.array([complex(p) for p in extra.pop("points_hz")])
    else:
        pts = parse_points(points)
        V, k, used = _basis_at(model, ports, pts, order, moments, b, excited, side, solver, phi, {})
    n_rb = int(phi.shape[1]) if rigid == "exclude" else 0
    if order is not None and V.shape[1] < order:
        log.warning("krylov: only %d independent directions for order %d (deflation)", V.shape[1], order)
    info = {"points_hz": [str(p) for p in pts], "points_rad_s": [str(s) for s in used], "moments": k,
            "side": side, "rigid": rigid, "n_rigid": int(phi.shape[1]), "n_rigid_excluded": n_rb,
            "n_rigid_included": int(excited.shape[1]),
            "nested": extra.get("compressed", {}).get("body", "greedy") == "greedy"}
    info.update(extra)
    return Basis(V, "krylov", info, reduced=reduced)


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
        V = merge_blocks(blocks, order, orthonormal=True, head=head)
        exhausted = all(len(bl) < k for bl in blocks)
        if moments is not None or V.shape[1] >= order or exhausted:
            break
        # deflation (e.g. real solutions at points on the frequency axis of an undamped body):
        # more moments per point fill the order
        k += math.ceil((order - V.shape[1]) / per_round) + 1
    return V, k, used
