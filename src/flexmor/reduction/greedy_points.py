"""Krylov's default expansion points: chosen greedily where the body's error is largest.

A body of the Galerkin basis ``V`` answers a load ``F`` at the frequency ``w`` with the states
``x(w) = (V^T A(w) V)^{-1} V^T F``, ``A(w) = K - w^2 M + i w D``. What the basis misses shows in
the residual of the full equations,

    rho(w) = ||F - A(w) V x(w)||_F / ||F||_F,

(:class:`ResidualIndicator`: ``F`` the loads of every port, each column scaled to unit norm, so every
port counts; for a free body their elastic part). It vanishes at every expansion point and grows where
the basis lacks the modes that answer the loads, also where two successive bodies agree because both miss
the same modes.

:func:`greedy_basis` builds the default Krylov basis from it:

1. the static point ``s = 0`` (a free body: a small real shift): the body's static response is exact;
2. repeatedly, the point ``s = i 2 pi f*`` on the frequency axis where ``rho`` is largest on a
   candidate grid (log-spaced over the band, plus the current body's resonances in it), with
   :func:`moments_at` moments, until the order is reached. By default (``directions='missed'``) only the
   combinations of the loads that the body misses at ``f*`` start the point's Krylov sequence: the singular
   values of the body's error ``X - V x`` there, ``X = A^{-1} F`` (near a resonance one or two of ``b``;
   tangential interpolation, :func:`_tangential_blocks`). Each point costs one sparse factorization
   (complex for a damped model); ``rho`` costs one Gram matrix of ``[K V, M V, D V]``, extended step by
   step without an ``n x 3r`` array, and small dense solves.

The basis is nested: the points and their moments do not depend on the order asked for, the order only
stops the sequence, so the leading columns of a larger basis are the basis of a smaller order (the
target-error search uses this).

**The estimate** (:func:`difference_estimate`): the body of order ``r`` is compared with the body of ``V``
enriched by the full model's solutions at the frequency ``f_e`` where the indicator of the final body is
largest and at the largest peak of the indicator elsewhere in the band (more than :data:`CHECK_SEPARATION`
from ``f_e``; two more factorizations). The enriched body interpolates the full transfer function at both, so
the estimate is the body's true pointwise error at ``f_e`` and, over the band, its difference from a body that
is exact where it is worst in two regions; it is integrated on the judge's grid and rule with the judge's
damping (:func:`nested_difference`), and reported in ``info['points_check']`` beside the verified figure. One
check is not enough on an undamped body: its residual is largest beside its own resonances (its poles),
which a body may place within 4e-6 of the full model's while it misses a cluster of modes elsewhere that the
body enriched there misses as well (measured on the Abaqus C3D10 block, one port, 10-2000 Hz, order 12:
7.5e-6 verified, 1.1e-7 estimated with one check at 1924.6 Hz, 7.5e-6 with the second at the cluster near
1030 Hz).

References
----------
Feng, L., Korvink, J. G., Benner, P. (2015). A fully adaptive scheme for model order reduction
based on moment matching. IEEE Trans. Compon. Packag. Manuf. Technol. 5(12), 1872-1884.

Grimme, E. J. (1997). Krylov projection methods for model reduction. PhD thesis, University of
Illinois at Urbana-Champaign (rational Krylov with several points).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import scipy.linalg as sla

from ..basis import extend_orthonormal
from ..damping import ModalDamping, band_matched
from ..dynamics.dense_frf import dense_applicable
from ..dynamics.frf import frf_matrices
from ..dynamics.grid import adaptive_grid, band_error
from ..dynamics.surrogate import MODES_MARGIN
from ..linalg.context import step
from ..linalg.eigen import default_shift
from ..linalg.threads import sparse_dense
from ..projection import ReducedMatrices
from ..rigid import elastic_loads, m_project
from .arnoldi import DEFLATION_TOL, _point_blocks, blocks_at_points, rigid_projector, shifted_factorization, start_block
from .gramians import UNDAMPED_ZETA

__all__ = ["ResidualIndicator", "greedy_basis", "difference_estimate", "moments_at", "N_CANDIDATES",
           "CHECK_SEPARATION", "point_of", "points_within"]

log = logging.getLogger(__name__)

#: Log-spaced candidate frequencies of the greedy choice (the body's resonances in the band are added).
N_CANDIDATES = 400

#: Points on the frequency axis per number of moments (see :func:`moments_at`).
GROWTH = 3

#: Directions of the loads kept at a point on the axis: singular values of the body's error there above this
#: fraction of the largest (see :func:`_tangential_blocks`).
DIRECTION_TOL = 0.1

#: Candidates closer than this (relative) to a chosen point are not chosen again.
EXCLUDE_REL = 1e-3

#: The estimate's second check lies farther than this (relative) from its first: in another part of the band.
CHECK_SEPARATION = 0.05


def moments_at(step_index: int, n_loads: int) -> int:
    """Moments (blocks) of the ``step_index``-th point (0: the static point) for ``n_loads`` load columns.

    The static point (real): ``ceil(2 / b)``, at least two columns. A point on the axis: one moment (``2 b``
    real columns) at the first :data:`GROWTH` points, one more at each further :data:`GROWTH`: bodies of
    one or a few ports get many points (measured on the clamped plate structure with one port, order 20:
    band_error 7e-20 with seven points, 2.4e-10 with four points of three moments), and the number of
    factorizations grows like the square root of the order, not like the order.
    """
    b = max(int(n_loads), 1)
    if step_index == 0:
        return math.ceil(2 / b)
    return 1 + (step_index - 1) // GROWTH


class ResidualIndicator:
    """``rho(w) = ||F - A(w) V x(w)||_F / ||F||_F`` for a growing orthonormal basis ``V``.

    Keeps ``W = [K V, M V, D V]``, its Gram matrix ``G = W^T W``, ``P = W^T F`` and the reduced
    ``V^T (K, M, D) V``, ``V^T F``; :meth:`extend` adds columns (sparse products with the new columns only;
    the Gram matrix from ``W``'s columns, not from ``V^T X (Y V_new)``, whose rounding is that of ``||X||
    ||Y V_new||`` where the entries are far smaller).
    An undamped model is given the light Rayleigh damping of ratio
    :data:`~flexmor.reduction.gramians.UNDAMPED_ZETA` at the band ends (the body's poles would make
    ``rho`` infinite at its own resonances). The Gram form cancels terms of very different size: values
    below about ``sqrt(eps |c|^T |G| |c|) / ||F||`` are rounding, far below where a point is chosen.
    """

    def __init__(self, model, loads: np.ndarray, band):
        self.mats = [model.K, model.M] + ([model.D] if model.D is not None else [])
        self.reg = None if model.D is not None else band_matched(UNDAMPED_ZETA, band)
        F = np.asarray(loads, dtype=float)
        self.F = F
        self.n2 = float(np.sum(F ** 2))
        q, b = len(self.mats), F.shape[1]
        self.W = [np.zeros((F.shape[0], 0)) for _ in range(q)]  # K V, M V, D V
        self.G = np.zeros((q, 0, q, 0))
        self.P = np.zeros((q, 0, b))
        self.R = np.zeros((q, 0, 0))
        self.VF = np.zeros((0, b))

    @property
    def order(self) -> int:
        """Columns of the basis so far."""
        return self.VF.shape[0]

    def extend(self, V: np.ndarray, Vn: np.ndarray) -> None:
        """Add the columns ``Vn`` (orthonormal to ``V``, the columns added so far)."""
        q, r, d = len(self.mats), V.shape[1], Vn.shape[1]
        if d == 0:
            return
        Y = [sparse_dense(X, Vn) for X in self.mats]
        G = np.zeros((q, r + d, q, r + d))
        G[:, :r, :, :r] = self.G
        R = np.zeros((q, r + d, r + d))
        R[:, :r, :r] = self.R
        for i in range(q):
            R[i, :r, r:] = V.T @ Y[i]
            R[i, r:, :r] = R[i, :r, r:].T
            R[i, r:, r:] = Vn.T @ Y[i]
            for j in range(q):
                G[i, r:, j, r:] = Y[i].T @ Y[j]
                if r:
                    G[i, :r, j, r:] = self.W[i].T @ Y[j]
                    G[j, r:, i, :r] = G[i, :r, j, r:].T
        self.W = [np.hstack([Wi, Yi]) for Wi, Yi in zip(self.W, Y)]
        self.G, self.R = G, 0.5 * (R + R.transpose(0, 2, 1))
        self.P = np.concatenate([self.P, np.stack([Yi.T @ self.F for Yi in Y])], axis=1)
        self.VF = np.vstack([self.VF, Vn.T @ self.F])

    def reduced(self):
        """``(Kr, Mr, Dr)`` of the basis (``Dr``: the model's, or the light damping of an undamped one)."""
        Kr, Mr = self.R[0], self.R[1]
        Dr = self.R[2] if self.reg is None else self.reg.alpha * Mr + self.reg.beta * Kr
        return Kr, Mr, Dr

    def resonances(self) -> np.ndarray:
        """Undamped eigenfrequencies (Hz) of the body of the basis."""
        Kr, Mr, _ = self.reduced()
        lam = sla.eigh(Kr, Mr, eigvals_only=True)
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)

    def _states(self, w):
        Kr, Mr, Dr = self.reduced()
        A = Kr[None] - (w ** 2)[:, None, None] * Mr[None] + (1j * w)[:, None, None] * Dr[None]
        return np.linalg.solve(A, np.broadcast_to(self.VF + 0j, (w.size, *self.VF.shape)))

    def _rho(self, w, X) -> np.ndarray:
        if self.reg is None:  # A V x = K V x + M V (-w^2 x) + D V (i w x)
            coef = [np.ones_like(w), -(w ** 2) + 0j, 1j * w]
        else:  # D = alpha M + beta K folded into the K and M parts
            coef = [1 + 1j * w * self.reg.beta, -(w ** 2) + 1j * w * self.reg.alpha]
        c = np.stack([a[:, None, None] * X for a in coef], axis=1)  # (f, q, r, b)
        lin = np.real(np.einsum("qkm,fqkm->f", self.P, c))
        f, q, r, b = c.shape  # G c as one product (the three-operand einsum would loop over all four indices)
        Gc = (self.G.reshape(q * r, q * r) @ c.reshape(f, q * r, b)).reshape(f, q, r, b)
        quad = np.real(np.einsum("fqkm,fqkm->f", c.conj(), Gc))
        r2 = self.n2 - 2 * lin + quad
        return np.sqrt(np.maximum(r2, 0.0) / max(self.n2, np.finfo(float).tiny))

    def __call__(self, freqs) -> np.ndarray:
        """``rho`` at ``freqs`` (Hz)."""
        w = 2 * np.pi * np.asarray(freqs, dtype=float)
        return self._rho(w, self._states(w))


def point_of(model, f_hz: float) -> complex:
    """The expansion point (Hz, :func:`flexmor.reduction.krylov.parse_points`) on the axis at ``f_hz``:
    ``f j``; for an undamped model slightly right of the axis, ``f (UNDAMPED_ZETA + j)`` (the undamped
    ``K - w^2 M`` is singular at the eigenfrequencies)."""
    return complex(UNDAMPED_ZETA * f_hz if model.D is None else 0.0, f_hz)


def static_point(model, phi, band) -> complex:
    """The first point: 0 Hz, or for a free body (``phi``: its rigid-body modes) the real point at the band's
    lower end, kept between 1e-2 and 1 times ``f0 = sqrt(-default_shift) / 2 pi``
    (:func:`flexmor.linalg.eigen.default_shift`; ``(2 pi f0 / 100)^2`` is the largest eigenvalue counted as a
    rigid-body mode): ``K + s^2 M`` is positive definite and well enough conditioned for the solver's check,
    and the Krylov vectors, made M-orthogonal to the rigid-body modes, are nearly the static (inertia relief)
    ones."""
    if phi.shape[1] == 0:
        return 0j
    f0 = math.sqrt(-default_shift(model.K, model.M)) / (2 * np.pi)
    return complex(min(max(float(band[0]), 1e-2 * f0), f0))


def _candidates(indicator: ResidualIndicator, band, chosen_hz, n: int = N_CANDIDATES,
                low: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(freqs, rho)``: the candidate grid (log-spaced plus the body's resonances in the band, none below
    ``low`` Hz) and ``rho`` there, chosen points (and their neighbourhood of :data:`EXCLUDE_REL`) set to -1.

    A free body's ``low`` is its static point (:func:`static_point`): below it ``K - omega^2 M`` is nearer
    singular than the static point's ``K + s^2 M`` (its rigid-body eigenvalues ``-omega^2``), which is as
    close to the rigid-body modes as the solver's check is known to hold, and the elastic response there is
    the quasi-static one the static point's moments give."""
    fmin, fmax = max(float(band[0]), low), float(band[1])
    if fmin >= fmax:
        return np.array([fmax]), np.array([-1.0])
    f_res = indicator.resonances()
    f = np.unique(np.concatenate([np.geomspace(fmin, fmax, int(n)), f_res[(f_res > fmin) & (f_res < fmax)]]))
    with np.errstate(all="ignore"):
        rho = indicator(f)
    rho = np.where(np.isfinite(rho), rho, -1.0)
    if len(chosen_hz):
        near = np.min(np.abs(f[:, None] - np.asarray(chosen_hz)[None, :]), axis=1) <= EXCLUDE_REL * f
        rho[near] = -1.0
    return f, rho


def greedy_basis(model, ports, order: int | None, band, *, side: str, solver, phi, head, moments: int | None = None,
                 estimate: bool = True, tol: float | None = None, max_points: int | None = None, label: str = "krylov",
                 n_candidates: int = N_CANDIDATES, directions: str = "missed", compress_to: int | None = None,
                 keep_static: bool = True):
    """The greedy Krylov basis (see the module docstring): of order ``order``, or until the estimated band
    error of the body before the latest point falls below ``tol``.

    Parameters
    ----------
    model, ports
        As for :func:`flexmor.reduction.krylov.krylov`.
    order : int or None
        Columns; None: stop on ``tol`` (or ``max_points``) alone.
    band : (float, float)
        Band (Hz) of the candidate points.
    side : {'input', 'output', 'both'}
    solver : SolverContext
    phi : ndarray
        Rigid-body modes (empty for a supported body); the Krylov vectors are M-orthogonal to them.
    head : ndarray
        Columns put first (the rigid-body modes the ports excite, ``rigid='include'``).
    moments : int, optional
        Moments of every point (default :func:`moments_at`).
    estimate : bool
        Add the estimate of the final body's band error (:func:`difference_estimate`, two more factorizations).
    tol : float, optional
        Stop when the band error of the body before the latest point, against the body with it (nested:
        small matrices only, :func:`nested_difference`), is below ``tol``; the body with it is returned.
    max_points : int, optional
        Upper limit of expansion points.
    label : str
        The method named in progress and log lines.
    n_candidates : int
        Log-spaced candidate frequencies in the band.
    directions : {'missed', 'all'}
        At a point on the axis, only the Krylov blocks of the load combinations the body misses there
        (:func:`_tangential_blocks`: more points for the order on bodies of many ports, interpolation along
        those directions), or of every load (block moment matching: the body interpolates the full transfer
        function in every port direction, which survives coupling the body to other parts at its ports).
    compress_to : int, optional
        Build the basis to the orders of :func:`flexmor.reduction.greedy_compress.growth_orders` (instead of
        ``order``) and return a body of this order in its span: of the candidates (the greedy body's leading
        columns, the balanced truncation of the larger body, the static responses followed by the balancing
        directions of the whole response or of its dynamic part) whose static responses equal the larger
        greedy body's (``STATIC_TOL``; every candidate with ``keep_static=False``), the one that differs least
        from a reference body (:func:`flexmor.reduction.greedy_compress.compressed_greedy`); its record is
        ``info['compressed']``.

    Returns
    -------
    V : ndarray, shape (n_dof, <= order)
    info : dict
        ``points_hz``, ``points_rad_s``, ``moments`` (per point), ``rho_max`` (the largest residual ``rho``
        on the candidates before each point on the axis; None for the estimate's check frequencies),
        ``directions`` (load combinations per point), ``points_cut`` (1 when the order ends inside the last
        point's blocks: its moments are not all matched), ``points_columns`` (the columns ``[first, end)`` of
        the basis each point added; the full solutions at the estimate's check frequencies, where the basis grew
        by them, share theirs), ``estimates`` (with ``tol``: after each point from the second on) and
        ``points_check`` (the estimate). A body of the greedy basis's leading columns lists the points those
        columns come from (:func:`points_within`).
    reduced : ReducedMatrices
        ``V^T (M, K, D) V`` (for :func:`flexmor.projection.project`).
    """

    loads = start_block(ports, side)
    if phi.shape[1]:
        loads = elastic_loads(model, phi, loads)
    nrm = np.linalg.norm(loads, axis=0)
    loads = loads[:, nrm > 0] / nrm[nrm > 0]
    indicator = ResidualIndicator(model, loads, band)
    V = extend_orthonormal(None, head, tol=DEFLATION_TOL) if head.shape[1] else np.zeros((model.n_dof, 0))
    indicator.extend(np.zeros((model.n_dof, 0)), V)
    limit = model.n_dof if order is None else int(order)
    points, used, per_point, rho_max, estimates, empty = [], [], [], [], [], 0
    spans: list[tuple[int, int]] = []  # the columns [first, end) each point added (the check points: together)
    first = static_point(model, phi, band)
    low = abs(first)  # a free body: no point on the axis below its static point (_candidates)
    cut = False
    n_directions: list[int] = []
    compressed, before = None, np.inf
    if compress_to is not None:
        from .greedy_compress import GROWTH_GAIN, compressed_greedy, growth_orders

        stages = growth_orders(int(compress_to), model.n_dof)
        limit = stages.pop(0)
    while True:
        while V.shape[1] < limit and (max_points is None or len(used) < max_points) and empty < 3:
            if points:
                f, rho = _candidates(indicator, band, [abs(complex(q).imag) for q in points], n_candidates, low=low)
                k = int(np.argmax(rho))
                if rho[k] < 0:  # nothing left to choose
                    log.warning("%s: no further expansion point in the band at order %d", label, V.shape[1])
                    break
                rho_max.append(float(rho[k]))
            p = point_of(model, float(f[k])) if points else first
            points.append(p)
            m = int(moments) if moments is not None else moments_at(len(used), loads.shape[1])
            with step(solver.progress, f"{label} point {p:.6g} Hz ({m} moment{'s' if m > 1 else ''})"):
                if used and directions == "missed":  # on the axis: the directions the body misses there
                    blocks, s, n_dir = _tangential_blocks(model, loads, V, indicator, p, m, solver, phi)
                    n_directions.append(n_dir)
                else:
                    blocks, s = blocks_at_points(model, ports, [p], m, side=side, solver=solver, rigid_modes=phi)
                    n_directions.append(loads.shape[1])
            used.append(s[0])
            per_point.append(m)
            new = _new_columns(model, phi, V, blocks[0])
            cut = new.shape[1] > limit - V.shape[1]  # the order ends inside this point's blocks
            new = new[:, :limit - V.shape[1]]
            empty = 0 if new.shape[1] else empty + 1
            r_prev = V.shape[1]
            spans.append((r_prev, r_prev + new.shape[1]))
            indicator.extend(V, new)
            V = np.hstack([V, new])
            if tol is not None and len(used) > 1 and new.shape[1]:
                estimates.append(nested_difference(model, ports, V, indicator, r_prev, band)["estimate"])
                log.debug("%s: %d points, order %d, estimated band error %.2e", label, len(used), V.shape[1],
                          estimates[-1])
                if estimates[-1] < tol:
                    break
        if compress_to is None or V.shape[1] <= compress_to:
            break
        chosen = [abs(complex(q).imag) for q in points]
        compressed = compressed_greedy(
            model, ports, V, indicator, int(compress_to), band,
            check=lambda B, chosen=chosen: check_columns(model, ports, B, indicator, band, side=side,
                                                         solver=solver, phi=phi, chosen=chosen, low=low),
            differences=lambda W, bases, at: nested_differences(model, ports, W, indicator, bases, band, at,
                                                                judged=True), keep_static=keep_static)
        if not (stages and compressed.grow and compressed.check["difference"] < GROWTH_GAIN * before):
            break
        before = compressed.check["difference"]
        # the reference is not much better than the body: its columns (the full model's solutions at the
        # check frequencies) join the basis, which grows to the next stage
        limit = max(stages.pop(0), V.shape[1] + compressed.E.shape[1])
        spans += [(V.shape[1], V.shape[1] + compressed.E.shape[1])] * len(compressed.check["checks_hz"])
        V = np.hstack([V, compressed.E])
        for q in compressed.check["checks_hz"]:
            points.append(point_of(model, q))
            used.append(2 * np.pi * points[-1])
            per_point.append(1)
            n_directions.append(loads.shape[1])
            rho_max.append(None)  # chosen by the estimate, not by the residual
    info = {"points_hz": [str(p) for p in points[:len(used)]], "points_rad_s": [str(s) for s in used],
            "moments": per_point, "directions": n_directions, "rho_max": rho_max,
            "points_cut": int(cut) if used else 0, "points_columns": [list(c) for c in spans]}
    if tol is not None:
        info["estimates"] = estimates
    if compressed is not None:
        info["points_check"], info["compressed"] = compressed.check, compressed.record
        if compressed.record["body"] == "greedy":  # the leading columns: the points they come from
            info = points_within(info, compressed.V.shape[1])
        return compressed.V, info, compressed.reduced
    R = indicator.R  # V^T (K, M, D) V, handed on to the projection of the body
    reduced = ReducedMatrices(R[1].copy(), R[0].copy(), R[2].copy() if model.D is not None else None,
                              (V, model.M, model.K, model.D))
    if estimate:
        info["points_check"] = difference_estimate(model, ports, V, indicator, band, side=side, solver=solver,
                                                   phi=phi, chosen=[abs(complex(q).imag) for q in points], low=low)
    return V, info, reduced


def points_within(info: dict, r: int) -> dict:
    """``info`` (of :func:`greedy_basis`) of the body of the basis's leading ``r`` columns: the points, their moments,
    directions and columns (up to ``r``) of those that added a column among them, ``points_cut`` when ``r`` ends
    inside the last one's, ``points_built`` the points of the whole basis (one factorization each); ``info`` itself
    without ``points_columns``."""
    spans = info.get("points_columns")
    if not isinstance(spans, list):
        return info
    keep = [i for i, (a, b) in enumerate(spans) if a < r and b > a]
    out = dict(info)
    for key in ("points_hz", "points_rad_s", "moments", "directions", "points_columns"):
        if isinstance(out.get(key), list) and len(out[key]) == len(spans):
            out[key] = [out[key][i] for i in keep]
    if isinstance(out.get("rho_max"), list) and len(out["rho_max"]) == len(spans) - 1:  # one per point after the first
        out["rho_max"] = [out["rho_max"][i - 1] for i in keep if i > 0]
    out["points_cut"] = int(bool(keep) and spans[keep[-1]][1] > r)
    out["points_columns"] = [[a, min(b, r)] for a, b in (spans[i] for i in keep)]
    out.setdefault("points_built", len(spans))  # the basis's points, one factorization each
    return out


def _tangential_blocks(model, loads, V, indicator, p, m, solver, phi):
    """The blocks of the point ``p`` (Hz) on the axis for the directions of the loads that the body of ``V``
    misses there: with ``X = A(s)^{-1} F`` and the body's states ``x_r``, the error ``E = X - V x_r`` has the
    singular values ``sigma_j`` and right singular vectors ``w_j``; the loads ``F w_j`` with
    ``sigma_j >= DIRECTION_TOL sigma_1`` start the point's second-order Krylov sequence (tangential
    interpolation along them). A body of many ports near a resonance misses one or two directions, not all
    ``b``: the order then buys more points. Returns ``(blocks, [s], directions)``."""
    F, s = shifted_factorization(model, 2 * np.pi * complex(p), solver)
    proj = rigid_projector(model, phi)
    X = F.solve(loads.astype(complex))
    X = proj(X) if proj is not None else X
    if V.shape[1]:
        Kr, Mr, _ = indicator.reduced()
        Ar = Kr + (s * s) * Mr + (s * indicator.R[2] if model.D is not None else 0)
        E = X - V @ np.linalg.solve(Ar, indicator.VF + 0j)
    else:
        E = X
    _, R = np.linalg.qr(E)
    _, sig, Wh = np.linalg.svd(R)
    k = int(np.sum(sig >= DIRECTION_TOL * sig[0])) if sig.size and sig[0] > 0 else loads.shape[1]
    start = loads @ Wh[:k].conj().T
    blocks, s = _point_blocks(model, start, p, m, solver, proj, factorization=(F, s))
    return [blocks], [s], k


def _new_columns(model, phi, V, blocks) -> np.ndarray:
    """The orthonormal columns ``blocks`` add to ``V``, M-orthogonal to the rigid-body modes ``phi``: the
    solves near a free body's singular ``K`` leave rigid content of about ``eps`` times their condition,
    which one projection in the Arnoldi process reduces but does not remove (a rigid-body mode of the body
    at ``1e-9`` would spoil its response at low frequencies)."""
    if not blocks:
        return V[:, :0]
    X = np.hstack(blocks)
    for _ in range(2 if phi.shape[1] else 0):
        X = m_project(model, phi, X)
    return extend_orthonormal(V, X, tol=DEFLATION_TOL)


def nested_difference(model, ports, V, indicator: ResidualIndicator, r: int, band, at=None, *,
                      judged: bool = False, T: np.ndarray | None = None) -> dict:
    """Band error of the body of the leading ``r`` columns of ``V`` (or, with ``T``, of the columns ``V T``:
    ``T`` orthonormal, ``r`` of them) against the body of all of ``V``: :func:`nested_differences` of one body."""
    return nested_differences(model, ports, V, indicator, [np.eye(V.shape[1])[:, :r] if T is None else T], band,
                              at, judged=judged)[0]


def nested_differences(model, ports, V, indicator: ResidualIndicator, bases, band, at=None, *,
                       judged: bool = False) -> list[dict]:
    """Band error of the bodies of the columns ``V T`` (``T`` in ``bases``: orthonormal coordinates in ``V``,
    e.g. its leading columns) against the body of all of ``V`` (the
    reduced matrices of :class:`ResidualIndicator`, extended to ``V``), on the judge's grid and rule
    (:func:`flexmor.dynamics.grid.adaptive_grid` refined on the larger body, once for all of them,
    :func:`flexmor.dynamics.grid.band_error`). The smaller body has the damping the projection gives it
    (modal damping: the ratio in its own modes); the larger the damping of the judge's full model (modal
    damping: the ratio in its modes up to :data:`~flexmor.dynamics.surrogate.MODES_MARGIN` times the band's
    top, the Rayleigh realization above, on a model small enough for the judge's dense path the ratio in
    every mode; an undamped model undamped, on a grid that is not refined), so
    that the figure is comparable with the judge's. With ``judged`` only at the ports the judge looks at
    (``ports.judged``: not at the inputs added for the basis, the frame's inertia loads), the estimate of a
    body's error; without, at every input and output, which a stopping test needs (a point that served the
    inertia loads changes the ports' response little though they are not converged).

    Returns
    -------
    list of dict
        Per body ``estimate``, ``n_freq``, ``order`` (its columns), ``compared_order``; with ``at`` (Hz)
        ``pointwise_at_check``, the relative difference there.
    """
    Kr, Mr, Dr = indicator.reduced()
    if model.D is None:  # undamped, as the judge takes it (its grid then is not refined)
        Dr = np.zeros_like(Kr)
    Br, Cr = ports.reduced(V)
    if judged and ports.judged is not None:  # the judge's ports: not the inputs added for the basis
        Br, Cr = Br[:, :ports.judged[0]], Cr[:ports.judged[1]]
    lam, psi = sla.eigh(Kr, Mr)
    wn = np.sqrt(np.clip(lam, 0, None))
    f_res = wn / (2 * np.pi)
    bodies = []
    for P in bases:
        Ks, Ms, Ds = P.T @ Kr @ P, P.T @ Mr @ P, P.T @ Dr @ P
        if isinstance(model.damping, ModalDamping):
            Ds = model.damping.reduced_matrix(Ms, Ks)
        bodies.append((P, Ks, Ms, Ds))
    if isinstance(model.damping, ModalDamping):
        top = np.inf if dense_applicable(model) else MODES_MARGIN * band[1]  # the judge's dense path: all modes
        d = np.where(f_res <= top, 2 * model.damping.ratios(f_res) * wn,
                     model.damping.alpha + model.damping.beta * wn ** 2)
        G = Mr @ psi
        Dr = (G * d) @ G.T
        Dr = 0.5 * (Dr + Dr.T)
    zeta = np.abs(np.einsum("ik,ij,jk->k", psi, Dr, psi)) / (2 * np.where(wn > 0, wn, np.inf))
    inband = (f_res >= band[0]) & (f_res <= band[1])

    def larger(freqs):
        return frf_matrices(Kr, Mr, Dr, Br, Cr, 2 * np.pi * np.asarray(freqs, dtype=float))

    def smaller(body, freqs):
        P, Ks, Ms, Ds = body
        return frf_matrices(Ks, Ms, Ds, P.T @ Br, Cr @ P, 2 * np.pi * np.asarray(freqs, float))

    out = []
    with np.errstate(all="ignore"):
        grid, He, _ = adaptive_grid(larger, band[0], band[1], resonances=f_res[inband], zeta=zeta[inband],
                                    refine=model.D is not None)
        h = larger([at]) if at is not None else None
        for body in bodies:
            rec = {"estimate": float(band_error(grid, He, smaller(body, grid))), "n_freq": int(grid.size),
                   "order": int(body[0].shape[1]), "compared_order": int(V.shape[1])}
            if h is not None:
                rec["pointwise_at_check"] = float(np.linalg.norm(h - smaller(body, [at]))
                                                  / max(np.linalg.norm(h), np.finfo(float).tiny))
            out.append(rec)
    return out


def difference_estimate(model, ports, V, indicator: ResidualIndicator, band, *, side, solver, phi, chosen,
                        low: float = 0.0) -> dict:
    """The estimated band error of the body of ``V``: against the body enriched by the full model's
    solutions where the residual of ``V``'s body is largest and where it peaks elsewhere in the band (see the
    module docstring); ``indicator`` is extended by the new columns.

    Returns
    -------
    dict
        ``estimate`` (:func:`nested_difference`), ``check_hz`` (where the residual is largest),
        ``pointwise_at_check`` (a damped model: the body's true relative error there; not given for an undamped
        one, whose full model is solved beside the axis, :func:`point_of`, and whose body may resonate at
        ``check_hz``), ``indicator_at_check``, ``checks_hz``
        (every frequency where the full model was solved), ``n_freq``.
    """
    out, E = check_columns(model, ports, V, indicator, band, side=side, solver=solver, phi=phi, chosen=chosen,
                           low=low)
    if E is None:
        return out
    on_axis = model.D is not None  # an undamped model is solved beside the axis (point_of): no exact figure at f[k]
    out.update(nested_difference(model, ports, np.hstack([V, E]), indicator, V.shape[1], band,
                                 at=out["check_hz"] if on_axis else None, judged=True))
    return out


def check_columns(model, ports, V, indicator: ResidualIndicator, band, *, side, solver, phi, chosen,
                  low: float = 0.0):
    """``(record, E)``: the columns ``E`` of the full model's solutions that :func:`difference_estimate` adds to
    ``V`` (``indicator`` is extended by them; None when no candidate is left) and the record of where."""
    f, rho = _candidates(indicator, band, chosen, low=low)
    k = int(np.argmax(rho))
    out = {"estimate": float("nan"), "check_hz": float(f[k]), "indicator_at_check": float(rho[k])}
    if rho[k] < 0:
        return out, None
    far = (np.abs(f - f[k]) > CHECK_SEPARATION * f[k]) & (rho >= 0)
    at = [float(f[k])] + ([float(f[int(np.argmax(np.where(far, rho, -1.0)))])] if far.any() else [])
    out["checks_hz"] = at
    with step(solver.progress, f"estimate: the full model at {', '.join(f'{q:.6g}' for q in at)} Hz"):
        blocks, _ = blocks_at_points(model, ports, [point_of(model, q) for q in at], 1, side=side, solver=solver,
                                     rigid_modes=phi)
    E = _new_columns(model, phi, V, [b for point in blocks for b in point])
    indicator.extend(V, E)
    return out, E
