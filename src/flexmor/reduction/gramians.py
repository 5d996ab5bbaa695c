"""Gramians of the second-order body, kept as low-rank factors, and the balancing step.

For ``H(s) = C (s^2 M + s D + K)^{-1} B`` and ``X(w) = (-w^2 M + i w D + K)^{-1} B`` the
position controllability Gramian restricted to a band ``Omega = [w1, w2]`` (rad/s) is

    P_p = (1/pi) int_Omega Re(X(w) X(w)^H) dw,

the velocity Gramian ``P_v`` has the integrand multiplied by ``w^2``, and the observability
Gramian ``Q_p`` is ``P_p`` of the dual body ``(M, D, K, C^T)`` (``Y(w) = A(w)^{-1} C^T``; ``M``, ``D``,
``K`` are symmetric, so the same factorization serves). With ``Omega = [0, inf)`` these are
the blocks of the Gramians of the first-order realization ``E = diag(I, M)``,
``A = [[0, I], [-K, -D]]``: ``P_p = P_11``, ``P_v = P_22``, ``Q_p = Q_22`` (Reis & Stykel 2008).

The integral is evaluated by a quadrature that resolves the resonances
(:mod:`flexmor.reduction.gramian_quadrature`): the band is split
into one cell per resonance ``w_k`` (at the geometric midpoints between neighbours), and in
each cell Gauss-Legendre panels are graded geometrically towards the peak (half width
``g_k = zeta_k w_k``), so every panel is as far from the poles as it is long; an unbounded last
cell ends with the substitution ``w = d0 / t``. The rule converges exponentially: doubling
``nodes`` changes the Gramian by round-off once the peaks are resolved. Resonances and damping
ratios come from the modal pre-pass of :mod:`flexmor.dynamics.modes`. Each node costs one
complex symmetric factorization of ``K - w^2 M + i w D`` (:func:`flexmor.linalg.factorize`) and
one block solve with ``[B, C^T]`` on the direct path (``[B]`` alone for collocated ports,
``C = B^T``: then ``Q_p = P_p``); small models and finite bands get the same solves from the exact modal form or a
verified surrogate instead, the full band a surrogate up to the cutoff with a bound of the rest
(:mod:`flexmor.reduction.gramian_solves`). The factors ``P ≈ R R^T`` have ``2 (m + p)`` columns
per node before column compression and no N x N matrix is ever formed.

**Undamped models** (``D`` is None): the integrand has poles ``1/(w - w_k)^2`` at the
resonances, so a Gramian over a band that contains one is infinite. The Gramians are then
computed for the body with a small Rayleigh damping of ratio :data:`UNDAMPED_ZETA` at the
band ends (reported in ``info['gramian_damping']``); the reduction basis is still projected
onto the undamped model. Free bodies: the rigid-body modes (from the geometry) are removed
M-orthogonally from every solution, the Gramians are those of the flexible part.

References
----------
Gawronski, W., Juang, J.-N. (1990). Model reduction in limited time and frequency intervals.
Int. J. Systems Sci. 21(2), 349-376.

Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
Math. Comput. Model. Dyn. Syst. 14(5), 391-406.

Benner, P., Kürschner, P., Saak, J. (2016). Frequency-limited balanced truncation with
low-rank approximations. SIAM J. Sci. Comput. 38(1), A471-A499.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..basis import orthonormalize
from ..damping import band_matched
from ..dynamics.frf import ShiftedMatrices
from ..dynamics.modes import PrePass, modal_damping_ratios, modes_below
from ..dynamics.surrogate import MODES_MARGIN
from ..errors import ModelError, OptionError, check_choice
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver, track
from ..linalg.eigen import DENSE_LIMIT, default_shift, eigenmodes, frequencies_hz, is_rigid
from ..rigid import m_project
from ._options import VARIANTS
from .gramian_quadrature import quadrature_rule
from .gramian_solves import choose_solves, projected_factors, tail_boundable

__all__ = ["GramianFactors", "quadrature_rule", "gramian_factors", "balance", "balance_note", "compress", "coverage",
           "truncation_basis", "UNDAMPED_ZETA"]

log = logging.getLogger(__name__)

#: Damping ratio given to undamped models for their Gramians (see module docstring).
UNDAMPED_ZETA = 1e-3

#: Relative singular value below which factor columns are dropped by :func:`compress`.
COMPRESS_TOL = 1e-13

#: Memory (bytes) of the three factor stores of :func:`gramian_factors` together, and their
#: largest share of one dense ``N x N`` float64 array: a store is column-compressed before it
#: grows beyond ``min(FACTOR_MEMORY, FACTOR_SHARE * 8 N^2) / (3 * 8 N)`` columns (at least
#: :data:`MIN_FACTOR_COLUMNS`), e.g. 64 columns at 5,400 DOF, 315 at 94,500, 64 at 1M.
FACTOR_MEMORY = 2 ** 30
FACTOR_SHARE = 0.01
MIN_FACTOR_COLUMNS = 64


@dataclass
class GramianFactors:
    """Low-rank factors of the Gramians: ``P_p ≈ R R^T``, ``P_v ≈ Rv Rv^T``, ``Q_p ≈ L L^T``.

    Attributes
    ----------
    R, Rv, L : ndarray, shape (n_dof, k)
        Position and velocity controllability and position observability factors
        (``L`` is None without outputs requested).
    nodes_hz, weights : ndarray
        Quadrature nodes (Hz) and weights (for ``dw`` in rad/s).
    info : dict
        ``n_nodes``, ``n_resonances``, ``band_hz``, ``gramian_damping`` ...
    """

    R: np.ndarray
    Rv: np.ndarray
    L: np.ndarray | None
    nodes_hz: np.ndarray
    weights: np.ndarray
    info: dict = field(default_factory=dict)

    def controllability(self, variant: str = "position") -> np.ndarray:
        """The factor of ``variant`` (``position`` or ``velocity``)."""
        check_choice("variant", variant, VARIANTS)
        return self.R if variant == "position" else self.Rv


def compress(R: np.ndarray, tol: float = COMPRESS_TOL, *, overwrite: bool = False) -> np.ndarray:
    """Column compression ``R -> R'`` with ``R' R'^T = R R^T`` up to ``tol`` (relative), fewer columns.

    A thin QR of ``R`` (``overwrite``: in the memory of ``R`` when it is Fortran-ordered, which
    ``R`` then loses) and an SVD of its triangular factor; columns with singular values below
    ``tol`` times the largest are dropped. Memory: ``R`` and the result (plus ``R``'s copy
    without ``overwrite``).
    """
    if R.shape[1] == 0:
        return R
    if R.shape[1] >= R.shape[0]:  # wide (small model): one thin SVD
        Q, T = None, R
    else:
        Q, T = sla.qr(R, mode="economic", overwrite_a=overwrite, check_finite=False)
    U, s, _ = np.linalg.svd(T, full_matrices=False)
    k = int(np.sum(s > tol * s[0])) if s.size and s[0] > 0 else 0
    W = U[:, :k] * s[:k]
    return W if Q is None else Q @ W


def _resonances(model, fmax: float, solver: SolverContext, surrogate: bool = False):
    """Eigenfrequencies (Hz), damping ratios and the modal pre-pass for the quadrature cells.

    Small models (``n_dof <= DENSE_LIMIT``): all modes. Larger: the modal pre-pass of
    :func:`flexmor.dynamics.modes.modes_below` up to ``fmax`` (finite). Returns
    ``(f, zeta, pre)``: the eigenfrequencies up to ``fmax`` and the pre-pass
    (:class:`flexmor.dynamics.modes.PrePass`, rigid-body modes included, its factorization None
    for small models), reused by the ``surrogate`` solves of :mod:`flexmor.reduction.gramian_solves`,
    whose basis needs the modes up to :data:`~flexmor.dynamics.surrogate.MODES_MARGIN` ``fmax`` and
    the inertia count's factorization at the band's end (kept then).
    """
    margin = MODES_MARGIN if surrogate else 1.0
    if model.n_dof <= DENSE_LIMIT:
        lam, phi = eigenmodes(model.K, model.M, model.n_dof, solver=solver)
        f = frequencies_hz(lam)
        near = f <= margin * fmax
        pre = PrePass(f[near], phi[:, near], None, default_shift(model.K, model.M), complete=True)
        keep = (f <= fmax) & ~is_rigid(lam, model.K, model.M)
        f_all, phi_all = f[keep], phi[:, keep]
    else:
        if math.isinf(fmax):
            raise OptionError("the Gramian of a large model needs a finite cutoff frequency")
        pre = modes_below(model, margin * fmax, solver, keep_edge=surrogate)
        keep = (pre.f > 0) & (pre.f <= fmax)
        f_all, phi_all = pre.f[keep], pre.phi[:, keep]
    z = modal_damping_ratios(model.damping, f_all, phi_all, model.D) if model.D is not None else None
    z = np.zeros(f_all.size) if z is None else np.asarray(z, float)
    return f_all, z, pre


def _regularized(model, band_hz, f_res):
    """``model`` itself when damped, else with Rayleigh damping of ratio UNDAMPED_ZETA at the band ends."""
    if model.D is not None:
        return model, model.damping.to_dict()
    lo = band_hz[0] if band_hz[0] > 0 else (f_res[0] / 2 if f_res.size else 1.0)
    hi = band_hz[1] if math.isfinite(band_hz[1]) else (f_res[-1] * 2 if f_res.size else 10 * lo)
    z = UNDAMPED_ZETA
    reg = model.with_damping(band_matched(z, (lo, max(hi, 1.01 * lo))))
    log.warning("undamped model: Gramians computed with Rayleigh damping of ratio %g (alpha=%.3g, beta=%.3g)",
                z, reg.damping.alpha, reg.damping.beta)
    return reg, dict(reg.damping.to_dict(), regularization=True)


def factor_store_columns(n_dof: int) -> int:
    """Columns a factor store of :func:`gramian_factors` holds before it is compressed (see :data:`FACTOR_MEMORY`)."""
    n = max(int(n_dof), 1)
    return max(MIN_FACTOR_COLUMNS, int(min(FACTOR_MEMORY, FACTOR_SHARE * 8.0 * n * n) / (3 * 8 * n)))


class _FactorStore:
    """The columns of one Gramian factor in a Fortran-ordered buffer, compressed in place when full.

    The buffer grows by doubling up to ``limit`` columns; a block that does not fit triggers
    :func:`compress` of the columns held. Should the compressed rank and the next block
    exceed half the limit (the factor's numerical rank is that large), the limit doubles, so
    a compression (``O(N limit^2)``) is always followed by at least ``limit / 2`` new columns
    and never dominates the solves.
    """

    def __init__(self, n: int, limit: int):
        self.limit = int(limit)
        self.buf = np.empty((n, 0), order="F")
        self.k = 0
        self.compressions = 0
        self.peak = 0

    def _resize(self, cols: int):
        buf = np.empty((self.buf.shape[0], cols), order="F")
        buf[:, :self.k] = self.buf[:, :self.k]
        self.buf = buf

    def _compress(self):
        C = compress(self.buf[:, :self.k], overwrite=True)
        self.k = C.shape[1]
        self.buf[:, :self.k] = C
        self.compressions += 1

    def add(self, X: np.ndarray):
        c = X.shape[1]
        if self.k + c > self.limit:
            self._compress()
            if 2 * (self.k + c) > self.limit:
                self.limit = 2 * (self.k + c)
                log.info("Gramian factor of rank %d: compression limit raised to %d columns", self.k, self.limit)
        if self.k + c > self.buf.shape[1]:
            self._resize(min(self.limit, max(2 * self.buf.shape[1], self.k + c, 8 * c)))
        self.buf[:, self.k:self.k + c] = X
        self.k += c
        self.peak = max(self.peak, self.k)

    def result(self) -> np.ndarray:
        """The compressed factor (the store is emptied)."""
        C = compress(self.buf[:, :self.k], overwrite=True)
        self.buf, self.k = self.buf[:, :0], 0
        return C


def gramian_factors(model, ports, band=(0.0, math.inf), *, side: str = "both", nodes: int = 4, panels: int = 1,
                    cutoff: float | None = None, solver: SolverContext | None = None, rigid_modes=None,
                    max_columns: int | None = None, solves: str = "auto") -> GramianFactors:
    """Low-rank factors of the (frequency-limited) second-order Gramians by quadrature.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        ``B`` (controllability) and ``C`` (observability).
    band : (float, float)
        ``(fmin, fmax)`` in Hz, ``0 <= fmin < fmax``; ``fmax = inf`` is the full band.
    side : {'input', 'both'}
        ``input``: only the controllability factors (``L`` is None).
    nodes, panels : int
        Gauss points per panel and panels per resonance cell
        (:func:`~flexmor.reduction.gramian_quadrature.quadrature_rule`).
    cutoff : float, optional
        Highest resonance (Hz) resolved by its own cell for a large model; default ``fmax``
        (full band: ``10 fmin`` or 10 kHz). Small models resolve all resonances.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.
    rigid_modes : ndarray, optional
        M-orthonormal rigid-body modes removed from every solution.
    max_columns : int, optional
        Each factor is column-compressed (:func:`compress`) before it exceeds this many
        columns; default :func:`factor_store_columns` of ``N``, so the three factors stay
        below ``min(1 GiB, 1 % of 8 N^2)`` unless their numerical rank needs more (then the
        limit doubles; direct path).
    solves : {'auto', 'direct', 'dense', 'surrogate'}
        How the solves at the quadrature nodes are done (:mod:`flexmor.reduction.gramian_solves`):
        one complex factorization per node, the exact modal form of a small model, or a verified
        surrogate (a full band ends at ``cutoff``, the rest bounded in ``info['solves']['tail']``);
        ``auto`` takes ``dense`` up to :data:`~flexmor.reduction.gramian_solves.DENSE_GRAMIAN_MAX_DOF`
        DOF, ``surrogate`` above for a finite band or Rayleigh damping, else ``direct``.
        ``info['solves']`` reports the choice and its checks.

    Returns
    -------
    GramianFactors
        Its ``info`` says what the Gramians cover (:func:`coverage`): ``band_hz`` the interval
        integrated, ``band_requested_hz``, ``cutoff_hz`` and ``gramians``.
    """
    solver = as_solver(solver)
    check_choice("side", side, ("input", "both"))
    fmin, fmax = float(band[0]), float(band[1])
    if not (0 <= fmin < fmax) or math.isnan(fmax):
        raise OptionError(f"band must satisfy 0 <= FMIN < FMAX (Hz), got {fmin}:{fmax}")
    if int(nodes) < 1 or int(panels) < 1:
        raise OptionError(f"nodes and panels must be positive integers, got {nodes}, {panels}")
    fcut = cutoff if cutoff is not None else (fmax if math.isfinite(fmax) else max(10 * fmin, 1e4))
    chosen = choose_solves(solves, model, fmax)
    f_res, z, pre = _resonances(model, max(fcut, fmin), solver, surrogate=chosen == "surrogate")
    work, damping = _regularized(model, (fmin, fmax), f_res)
    if model.D is None:
        z = modal_damping_ratios(work.damping, f_res)
    lo = 2 * math.pi * fmin
    if rigid_modes is not None and rigid_modes.shape[1] and lo == 0:
        lo = 2 * math.pi * 1e-3 * (f_res[0] if f_res.size else 1.0)  # the flexible part is regular at 0
    tail = chosen == "surrogate" and math.isinf(fmax) and tail_boundable(work) and fcut > fmin  # ends at fcut
    scale = (2 * math.pi * f_res[0], 2 * math.pi * f_res[-1]) if f_res.size else None
    wk, wt = quadrature_rule(lo, 2 * math.pi * (fcut if tail else fmax), 2 * math.pi * f_res,
                             2 * math.pi * f_res * np.maximum(z, 0), nodes=int(nodes), panels=int(panels), scale=scale)
    B = ports.B.toarray()
    m = B.shape[1]
    collocated = side == "both" and ports.C.shape == ports.B.T.shape and (ports.C != ports.B.T).nnz == 0
    rhs = np.hstack([B, ports.C.T.toarray()]) if side == "both" and not collocated else B
    limit = int(max_columns) if max_columns is not None else factor_store_columns(model.n_dof)
    sinfo, stores, one_side = {"solves": "direct"}, [], "input" if collocated else side
    chosen = "direct" if chosen == "surrogate" and math.isinf(fmax) and not tail else chosen  # tail not bounded
    if chosen != "surrogate":
        pre.take_edge()  # only the surrogate's basis uses it: freed here
    if chosen != "direct":
        try:
            R, Rv, L, sinfo = projected_factors(chosen, work, rhs, m, wk, wt, side=one_side, rigid_modes=rigid_modes,
                                                modes=pre, solver=solver, store=_FactorStore, tail=tail)
        except ModelError as exc:  # e.g. non-proportional damping of a small model
            log.info("Gramian solves: %s not applicable (%s), direct solves", chosen, exc)
            chosen = "direct"
    if chosen == "direct":
        stores = [_FactorStore(model.n_dof, limit) for _ in range(2 if one_side == "input" else 3)]
        R, Rv, L = _direct_factors(work, rhs, m, wk, wt, rigid_modes, stores, solver)
    L = R if collocated else L  # C = B^T: the observability Gramian is the controllability one
    info = {**coverage(fmin, fmax, fcut, tail, sinfo.get("solves", chosen), int(wk.size)),
            "n_nodes": int(wk.size), "nodes_per_panel": int(nodes), "panels": int(panels),
            "n_resonances": int(np.sum((f_res >= fmin) & (f_res <= fmax))), "gramian_damping": damping,
            "rank_R": int(R.shape[1]), "factor_columns_limit": limit,
            "factor_columns_peak": max((st.peak for st in stores), default=0),
            "compressions": sum(st.compressions for st in stores), "solves": sinfo, "collocated": bool(collocated)}
    log.info("Gramian factors: %d quadrature nodes, rank %d", wk.size, R.shape[1])
    return GramianFactors(R, Rv, L, wk / (2 * math.pi), wt, info)


def coverage(fmin: float, fmax: float, fcut: float, tail: bool, solves: str, n_nodes: int) -> dict:
    """What quadrature Gramians cover: ``band_hz`` (the interval integrated), ``band_requested_hz``,
    ``cutoff_hz`` (the highest frequency whose resonances have quadrature cells of their own; the
    end of the Gramians when they end there) and ``gramians`` (the same in words)."""
    top = fcut if tail else fmax
    cut = float(min(fcut, top))
    text = f"quadrature over [{fmin:g}, {top:g}] Hz ({n_nodes} nodes, {solves} solves)"
    if tail:
        text += (f"; the Gramians end at the cutoff {cut:g} Hz, the part of [{fmin:g}, {fmax:g}] Hz above it is "
                 "left out (its share of the trace bounded in info['solves']['tail'])")
    elif cut < top:
        text += f"; resonances up to {cut:g} Hz resolved by cells of their own, " + (
            "the rest of the band by one tail cell" if math.isinf(top) else "those above without")
    return {"band_hz": [fmin, top], "band_requested_hz": [fmin, fmax], "cutoff_hz": cut, "gramians": text}


def _direct_factors(work, rhs, m, wk, wt, rigid_modes, stores, solver):
    """The direct path: one complex factorization per quadrature node, factors in ``stores``."""
    A = ShiftedMatrices(work.K, work.M, work.D)
    nodes = track(solver.progress, list(zip(wk, wt)), wk.size, f"Gramian quadrature ({wk.size} nodes, direct)")
    for w, weight in nodes:
        F = factorize(A(w), solver=solver, symmetric=True, check=False)
        X = F.solve(rhs)
        del F
        if rigid_modes is not None and rigid_modes.shape[1]:
            X = m_project(work, rigid_modes, X)
        s = math.sqrt(weight / math.pi)
        Xr = s * np.hstack([X[:, :m].real, X[:, :m].imag])
        stores[0].add(Xr)
        stores[1].add(w * Xr)
        if len(stores) == 3:
            stores[2].add(s * np.hstack([X[:, m:].real, X[:, m:].imag]))
    return stores[0].result(), stores[1].result(), stores[2].result() if len(stores) == 3 else None


def balance(R: np.ndarray, L: np.ndarray, M, order: int):
    """Square-root balancing of factors: the right balancing vectors and the singular values.

    With ``Y = L^T M R = U diag(sigma) Z^T`` the leading ``order`` right balancing vectors
    are ``T = R Z_r diag(sigma_r)^{-1/2}``; ``sigma`` are the (position or velocity) Hankel
    singular values of the second-order body (Reis & Stykel 2008).

    Returns
    -------
    T : ndarray, shape (n, r)
    sigma : ndarray
        All singular values, descending.
    """
    Y = L.T @ (M @ R)
    _, s, Zt = np.linalg.svd(Y, full_matrices=False)
    r = int(min(order, int(np.sum(s > 1e-14 * s[0])) if s.size else 0))
    if r < order:
        log.info("balancing: only %d non-zero singular values for order %d", r, order)
    return R @ (Zt[:r].T / np.sqrt(s[:r])), s


def balance_note(kept: int, asked: int, n_rigid: int = 0, gramians: dict | None = None) -> str | None:
    """The ``order_note`` of a balanced basis with ``kept`` of ``asked`` balancing vectors (None if all).

    ``gramians`` is the record of the Gramians balanced (``band_hz``, ``band_requested_hz``,
    ``cutoff_hz``, ``gramians``, ``solves``): the note says which Gramians limit the rank. Exact
    full-band Gramians (no quadrature record) leave round-off only; Gramians that end at a cutoff
    below the band they were asked for miss what lies above it, so the rank is the cutoff's.
    """
    if kept >= asked:
        return None
    head = (f"order {kept + n_rigid} instead of {asked + n_rigid}: only {kept} Hankel singular values are above "
            "1e-14 times the largest")
    g = gramians or {}
    if "band_requested_hz" not in g:
        return head + "; the inputs and outputs see no further states (more would add round-off only)"
    lo, hi = g["band_hz"]
    asked_hi = g["band_requested_hz"][1]
    solves = g.get("solves", {}).get("solves", "quadrature")
    if hi < asked_hi:
        return (f"{head} in Gramians that end at {hi:g} Hz (cutoff, solves={solves!r}): that end limits the rank, "
                f"not necessarily the body, whose Gramians over [{lo:g}, {asked_hi:g}] Hz may see more states; raise "
                "cutoff, or pass solves='direct' (or solves='dense' on a small model) for Gramians without the cutoff")
    return (f"{head} in the Gramians over [{lo:g}, {hi:g}] Hz ({g.get('n_nodes')} quadrature nodes, "
            f"solves={solves!r}): the inputs and outputs see no further states in that band as far as the "
            "quadrature resolves them (more would add round-off only); a wider band sees more")


def truncation_basis(T: np.ndarray, M) -> np.ndarray:
    """M-orthonormal basis of ``span(T)`` for the Galerkin projection (exported bodies are one-sided)."""
    return orthonormalize(T, M)
