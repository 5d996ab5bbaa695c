"""Judging several reduced bodies against one full frequency response computed once."""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..damping import ModalDamping
from ..display import Shown, band_text
from ..dynamics.dense_frf import DenseResolvent, dense_applicable
from ..dynamics.frf import angular_frequency, frf_full, frf_reduced, rel_error
from ..dynamics.grid import DEFAULT_TOL, adaptive_grid, initial_grid
from ..dynamics.modes import modal_damping_ratios, modes_below
from ..dynamics.surrogate import DEFAULT_SURROGATE_TOL, MODES_MARGIN
from ..errors import ModelError, OptionError, PortError
from ..linalg.context import SolverContext, as_solver, step
from ..linalg.eigen import frequencies_hz
from ..linalg.threads import blas_threads
from ..options import Band
from ..origin import check_origin, describe_damping, fingerprint, same_damping
from ..reduction.free_body import split_elastic, with_elastic_part
from . import cache as frf_cache
from .frequency import MEASURE_KEYS, error_measures, error_notes
from .judge import JUDGE_CHECKS, built_from_surrogate, judge_check, judge_notes
from .resonances import spurious_resonances
from .subspaces import Span, body_label, same_subspace, subspace_note

__all__ = ["FullResponse", "ErrorMeasures", "check_judgeable", "PATHS", "JUDGED_ELASTIC", "JUDGED_RIGID", "JUDGED_FULL"]

log = logging.getLogger(__name__)

#: How the full FRF on the grid is obtained: ``direct`` sparse solves at every grid point,
#: ``dense`` one dense eigendecomposition, exact at every point (:mod:`flexmor.dynamics.dense_frf`;
#: a singular mass matrix or an ill-conditioned non-proportional damping falls back to ``direct``),
#: ``surrogate`` a verified large projection model (see :mod:`flexmor.dynamics.surrogate`),
#: ``auto`` the surrogate from :data:`SURROGATE_MIN_DOF` DOF on for damped models, else dense up
#: to :data:`~flexmor.dynamics.dense_frf.DENSE_FRF_MAX_DOF` DOF, else direct; modal damping takes
#: the dense path up to that size (its ratio exact in every mode).
PATHS = ("auto", "direct", "dense", "surrogate")

#: ``judged`` of a body without rigid-body motion on a free model: the elastic part of H.
JUDGED_ELASTIC = "elastic part (rigid-body motion carried by the frame)"
#: ``judged`` of a body with rigid-body motion on a free model: the whole response.
JUDGED_RIGID = "full response, rigid-body motion included"
#: ``judged`` of a body of a supported model: the whole response.
JUDGED_FULL = "full response"

#: Damped models with at least this many DOF use the verified surrogate under ``path="auto"``.
#: Measured (``bench/small_frf.py``, cantilever, band 10-3000 Hz, ~750 grid points, one thread):
#: dense 0.11 s against the surrogate's 0.17 s at 540 DOF, 0.32 s against 0.17 s at 810 DOF,
#: 1.4 s against 0.24 s at 1,440 DOF and 13.4 s against 0.67 s at 3,000 DOF (both agree to the
#: surrogate's tolerance, 1e-6 pointwise).
SURROGATE_MIN_DOF = 700

#: Bases of the bodies evaluated that a :class:`FullResponse` keeps for the shared-subspace test (bytes; the
#: oldest dropped beyond): thirteen bodies of order 45 of a 35,000-DOF model take 160 MB.
SPANS_KEPT_BYTES = 512 * 2 ** 20


@dataclass(frozen=True, repr=False)
class ErrorMeasures(Shown):
    """How well a reduced body reproduces the full model's FRF over a band
    (:meth:`FullResponse.evaluate`).

    The measures are those of :func:`flexmor.analysis.frequency.error_measures` (see
    :data:`flexmor.analysis.frequency.MEASURES`); :meth:`to_dict` gives the JSON record of
    ``flexmor reduce`` / ``flexmor compare`` (:data:`~flexmor.analysis.frequency.MEASURE_KEYS`
    and ``notes``).

    Attributes
    ----------
    band_error : float
        ``∫|H-Hr|²df / ∫|H|²df`` over the band (squared relative L2 error).
    band_rms_error, rms_rel_error_pct : float
        ``sqrt(band_error)``, and the same in %.
    hinf_error : float
        ``max_f |H-Hr| / max_f |H|``.
    max_rel_error, max_rel_error_hz : float
        Largest pointwise relative error and the frequency (Hz) where it occurs.
    max_rel_error_at_antiresonance, max_rel_error_at_spurious_resonance : bool
        Whether that frequency is an anti-resonance of the full model, or a resonance of the
        body where the full model has none.
    resonance_share : float or None
        Share of ``band_error`` within 1 % of the full model's resonances.
    spurious_resonances_hz : list of float
        Resonances of the body in the band where the full model has none.
    judged : str
        Which response the body was judged against (:data:`JUDGED_FULL`, :data:`JUDGED_RIGID`,
        :data:`JUDGED_ELASTIC`: the elastic part for a free body without rigid-body modes).
    judge_check : dict or None
        Against a surrogate reference (``path='surrogate'``): the body checked by direct solves of the
        full model at its worst frequencies (:func:`flexmor.analysis.judge.judge_check`: the pointwise
        errors against both, ``band_error_surrogate`` and ``band_error_checked``, ``agree``,
        ``corrected``, ``resolved`` and ``floor``, ``new_solves`` and ``seconds`` of this body); None
        against a direct or dense reference.
    same_subspace_as : list of str
        Bodies judged before against this reference whose bases span the same subspace as this one's
        (``method r=order``, :func:`flexmor.analysis.subspaces.same_subspace`).
    band_hz : (float, float)
        The band judged over (Hz).
    notes : tuple of str
        What a user should read about these numbers.
    freqs_hz, rel_error : ndarray
        The frequency grid (Hz) and the pointwise relative error on it.
    """

    band_error: float
    band_rms_error: float
    rms_rel_error_pct: float
    hinf_error: float
    max_rel_error: float
    max_rel_error_hz: float
    max_rel_error_at_antiresonance: bool
    resonance_share: float | None
    max_rel_error_at_spurious_resonance: bool
    spurious_resonances_hz: list
    judged: str
    judge_check: dict | None
    same_subspace_as: list
    band_hz: tuple
    notes: tuple = ()
    freqs_hz: np.ndarray = field(default=None, repr=False, compare=False)
    rel_error: np.ndarray = field(default=None, repr=False, compare=False)

    def _shown(self) -> tuple[str, list]:
        where = f"{self.max_rel_error:.3g} at {self.max_rel_error_hz:.4g} Hz" + (
            " (anti-resonance)" if self.max_rel_error_at_antiresonance else "") + (
            " (spurious resonance)" if self.max_rel_error_at_spurious_resonance else "")
        rows = [("rms_rel_error", f"{self.rms_rel_error_pct:.3g} %"), ("hinf_error", f"{self.hinf_error:.3g}"),
                ("max_rel_error", where), ("judged", self.judged)]
        check = self.judge_check
        if check:
            rows.append(("direct check", f"{check['n_checks']} frequencies: " + (
                "agrees with the surrogate's figure" if check["agree"] else
                f"corrected (against the surrogate alone {check['band_error_surrogate']:.3g})")))
        rows += [("note", n) for n in self.notes]
        return f"band_error {self.band_error:.3g} over {band_text(self.band_hz)}", rows

    def to_dict(self) -> dict:
        """The JSON record: the :data:`~flexmor.analysis.frequency.MEASURE_KEYS` and ``notes``
        (without the band and the curves, which the records carry elsewhere)."""
        return {**{k: getattr(self, k) for k in MEASURE_KEYS}, "notes": list(self.notes)}


class FullResponse:
    """The full model's FRF over a band, computed once and reused for every reduced body.

    A modal pre-pass finds the resonances in the band and their modal damping; the adaptive
    grid (:func:`flexmor.dynamics.grid.adaptive_grid`) places points at them and refines
    until the trapezoidal integral of ``||H||_F^2`` is resolved to ``tol``. The result is
    cached on disk (:mod:`flexmor.analysis.cache`) so that later runs on the same model,
    ports, damping, band and grid parameters cost no sweep: one ``.npz`` file per FRF in
    ``$FLEXMOR_CACHE_DIR``, else ``$XDG_CACHE_HOME/flexmor``, else ``~/.cache/flexmor``, bounded by
    ``$FLEXMOR_CACHE_MAX_MB`` megabytes (default 2000; the least recently used entries are removed
    first); ``cache=False`` or ``FLEXMOR_CACHE_MAX_MB=0`` turns it off.

    Parameters
    ----------
    model : FEModel
        The full model.
    ports : Ports
        Inputs and outputs.
    band : (float, float)
        ``(fmin, fmax)`` in Hz.
    n : int
        Log-spaced base points of the grid.
    tol : float
        Relative tolerance of the grid refinement (see :func:`adaptive_grid`).
    max_points : int
        Largest grid.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.
    path : {'auto', 'direct', 'dense', 'surrogate'}
        How H is evaluated on the grid (see :data:`PATHS`); ``grid["path"]`` tells the one used.
    surrogate_tol : float
        Largest pointwise relative error of the surrogate at its checks.
    check_solver : {'auto', 'direct', 'iterative'}
        How the surrogate's checks solve the full model (see
        :class:`flexmor.dynamics.surrogate.Surrogate`; ``auto``: iterative where the pre-pass counted
        its modes and the damping is proportional, or where a complex factorization would not fit
        into memory, else direct).
    judge_checks : int
        With the surrogate: the frequencies per body where :meth:`evaluate` solves the full model
        directly (:mod:`flexmor.analysis.judge`; more where the check disagrees). 0 checks only the
        bodies built from a surrogate, which are always checked at
        :data:`~flexmor.analysis.judge.JUDGE_CHECKS` frequencies at least.
    cache : bool or path-like
        Use the disk cache (True: :func:`flexmor.analysis.cache.cache_dir`; a path: that
        directory; False: neither read nor write), bounded by
        :func:`flexmor.analysis.cache.max_bytes`.
    progress : callable, optional
        ``progress(iterable, total, desc=None)`` callback (:func:`flexmor.linalg.context.track`)
        shown the sweep, the modal pre-pass, the dense eigendecomposition and the surrogate's
        checks; default that of ``solver``.

    Attributes
    ----------
    freqs : ndarray
        The grid (Hz).
    H : ndarray, shape (n_freq, n_outputs, n_inputs)
        The full FRF on the grid.
    resonances, zeta : ndarray
        Eigenfrequencies (Hz) in the band and their modal damping ratios (0 when unknown).
    grid : dict
        Grid size, tolerance, number of resonances, refinement rounds, rationale, the path
        used and ``cache_hit``.
    seconds : float
        Wall time of the pre-pass and the sweep (or of the cache read).
    timings : dict
        ``prepass``, ``sweep``, ``cache`` seconds.
    cache_hit : bool
        The FRF came from the disk cache.
    n_factorizations : int
        Sparse factorizations spent (0 on a cache hit).
    surrogate : Surrogate or None
        The verified surrogate when it was built here.
    judge : dict
        The judge's direct solves of the full model (surrogate path): ``direct_solves`` (one complex
        factorization each, shared by the bodies), ``seconds``, ``bodies_checked``.
    """

    def __init__(self, model, ports, band, *, n: int = 50, tol: float = DEFAULT_TOL, max_points: int = 3000,
                 solver: SolverContext | None = None, path: str = "auto", surrogate_tol: float = DEFAULT_SURROGATE_TOL,
                 cache=True, progress: Callable | None = None, check_solver: str = "auto",
                 judge_checks: int = JUDGE_CHECKS):
        t0 = time.perf_counter()
        solver = as_solver(solver)
        progress = solver.progress if progress is None else progress
        c0 = solver.stats.count
        if path not in PATHS:
            raise OptionError(f"path={path!r} is not allowed; choose one of: {', '.join(PATHS)}")
        if band is None:
            raise OptionError("band is needed: the band (FMIN, FMAX) in Hz the full FRF is computed on",
                              params=("band",))
        self.band = tuple(float(f) for f in Band.of(band))  # a pair of numbers 0 < FMIN < FMAX, else OptionError
        damped = model.D is not None
        if path == "auto":
            exact_modal = isinstance(model.damping, ModalDamping) and dense_applicable(model)
            path = ("surrogate" if damped and model.n_dof >= SURROGATE_MIN_DOF and not exact_modal else
                    "dense" if dense_applicable(model) else "direct")
        if path == "surrogate" and not damped:
            raise OptionError("the surrogate path needs a damped model (rayleigh or modal_damping)",
                              params=("rayleigh", "modal_damping"))
        self.path = path
        given = ports
        ports = with_elastic_part(model, ports)  # a free body: the elastic part of H too, computed directly
        self.judge_checks = int(judge_checks)
        self.judge = {"direct_solves": 0, "seconds": 0.0, "bodies_checked": 0}
        self._solved: dict[int, np.ndarray] = {}  # the judge's direct solutions at grid points
        self._direct: Callable | None = None  # freqs -> the full FRF by direct solves (surrogate path)
        self._direct_of = (model, ports, solver) if path == "surrogate" else None
        self._spans: list = []  # the spans of the bodies evaluated (subspaces.Span), oldest first
        params = {"band": self.band, "n": int(n), "tol": float(tol), "max_points": int(max_points), "path": path}
        if path == "surrogate":
            params["surrogate_tol"] = float(surrogate_tol)
        elif path == "direct" and isinstance(model.damping, ModalDamping):
            params["modal_modes_margin"] = MODES_MARGIN  # the modes whose ratio is exact: as the surrogate's
        self.timings = {"prepass": 0.0, "sweep": 0.0, "cache": 0.0}
        directory = None if cache is True else cache
        key = frf_cache.frf_key(model, ports, params) if cache is not False and frf_cache.max_bytes() else None
        entry = frf_cache.load(key, (ports.n_outputs, ports.n_inputs), directory) if key else None
        self.timings["cache"] = time.perf_counter() - t0
        self.cache_hit = entry is not None
        self.surrogate = None
        if entry is not None:
            self.freqs, self.H = entry["freqs"], entry["H"]
            self.resonances, self.zeta, self.grid = entry["resonances"], entry["zeta"], entry["info"]
            log.info("full FRF from the cache (%d frequencies)", self.freqs.size)
        else:  # the sparse paths' dense products are tall-skinny: one BLAS thread (flexmor.linalg.threads)
            with blas_threads(1) if path != "dense" else contextlib.nullcontext():
                self._compute(model, ports, n=n, tol=tol, max_points=max_points, solver=solver, progress=progress,
                              surrogate_tol=surrogate_tol, check_solver=check_solver)
            if key:
                t1 = time.perf_counter()
                frf_cache.store(key, self.freqs, self.H, self.resonances, self.zeta, self.grid, directory)
                self.timings["cache"] += time.perf_counter() - t1
        self.grid["cache_hit"] = self.cache_hit
        #: the elastic part of H (inputs and outputs projected off the rigid-body modes, with_elastic_part), None
        #: for a supported body
        self.H, self.H_elastic = split_elastic(self.H, given)
        self.n_factorizations = solver.stats.count - c0
        self.seconds = time.perf_counter() - t0
        log.info("full FRF: %d frequencies in %.2f s (%s%s)", self.freqs.size, self.seconds, path,
                 ", cached" if self.cache_hit else "")
        #: what a body judged here must have been reduced from (:meth:`check_judgeable`)
        self.origin = fingerprint(model)
        self.damping = model.damping
        self.input_names, self.output_names = list(given.input_names), list(given.output_names)
        self.model_label = str(model.source or model.name)
        self._given = given

    def _compute(self, model, ports, *, n, tol, max_points, solver, progress, surrogate_tol, check_solver):
        t0 = time.perf_counter()
        fmin, fmax = self.band
        damped = model.D is not None
        dense = self._dense_resolvent(model, progress) if self.path == "dense" else None
        if dense is not None:  # all modes are known: the pre-pass is a selection
            f_all = frequencies_hz(dense.lam)
            phi = dense.phi[:, f_all <= fmax]
            f_all = f_all[f_all <= fmax]
        else:
            # the surrogate's modes reach above the band, and modal damping is exact in the modes found: the
            # direct path finds as many, so that both define the model alike (its direct checks compare like
            # with like); a mode just above the band shapes the response at its end
            margin = self.path == "surrogate" or isinstance(model.damping, ModalDamping)
            f_modes = fmax * (MODES_MARGIN if margin else 1.0)
            with step(progress, f"modes below {f_modes:.4g} Hz ({model.n_dof} DOF)"):
                pre = modes_below(model, f_modes, solver, keep_edge=self.path == "surrogate")
                f_all, phi = pre.f, pre.phi
        z_all = modal_damping_ratios(model.damping, f_all, phi, model.D) if damped else None
        z_all = np.zeros(f_all.size) if z_all is None else np.maximum(z_all, 0.0)
        inband = (f_all >= fmin) & (f_all <= fmax)
        self.resonances, self.zeta = f_all[inband], z_all[inband]
        self.timings["prepass"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        if self.path == "surrogate":
            from ..dynamics.surrogate import Surrogate

            self._direct = self._direct_frf(model, ports, solver, (f_all, phi))

            cand = initial_grid(fmin, fmax, n=400, resonances=self.resonances, zeta=self.zeta)
            sur = Surrogate(model, ports, self.band, phi=phi, factorization=pre.factorization, sigma=pre.sigma,
                            solver=solver, tol=surrogate_tol, check_solver=check_solver, candidates=cand,
                            edge=pre.take_edge(), complete=pre.complete)
            evaluate = sur.frf
        elif dense is not None:
            sur = None
            B, C = ports.B.toarray(), ports.C

            def evaluate(freqs):
                return dense.frf(angular_frequency(freqs), B, C)
        else:
            sur = None

            def evaluate(freqs):
                return frf_full(model, ports, freqs, solver=solver, progress=progress)

        if dense is None and isinstance(model.damping, ModalDamping):
            evaluate = _modal_correction(evaluate, model.damping, f_all, phi, ports)
            damping_note = (f"modal damping: ratio {model.damping.zeta:g} exact in the {f_all.size} modes up to "
                            f"{f_all.max(initial=0):.4g} Hz; higher modes (quasi-static in the band) with the "
                            "Rayleigh realization")
        elif isinstance(model.damping, ModalDamping):
            damping_note = f"modal damping: ratio {model.damping.zeta:g} exact in every mode (dense path)"
        else:
            damping_note = None
        refine = damped and bool(np.all(self.zeta > 0))
        self.freqs, self.H, self.grid = adaptive_grid(
            evaluate, fmin, fmax, n=n, resonances=self.resonances, zeta=self.zeta, tol=tol,
            max_points=max_points, refine=refine)
        if sur is not None:
            self.grid["surrogate"] = sur.verify(self.freqs)
            sur.release()  # its factorization (GBs at scale) is not needed by the FRF
        self.surrogate = sur
        self.grid["path"] = self.path
        if damping_note:
            self.grid["damping_note"] = damping_note
        if dense is not None:
            self.grid["dense_kind"] = dense.kind
        self.timings["sweep"] = time.perf_counter() - t1

    def _dense_resolvent(self, model, progress):
        """The dense resolvent, or None (and ``path`` set to ``direct``) where the dense path does not apply."""
        try:
            with step(progress, f"dense eigendecomposition ({model.n_dof} DOF)"):
                return DenseResolvent(model.K, model.M, model.D, damping=model.damping)
        except ModelError as exc:
            log.info("dense full FRF not applicable (%s): sparse direct sweep", exc)
            self.path = "direct"
            return None

    def summary(self) -> dict:
        """JSON-ready description of the grid: ``n_points, tol, n_resonances, path, cache_hit,
        seconds, n_factorizations`` and the rest of :attr:`grid` (surrogate checks without
        their list)."""
        out = {k: v for k, v in self.grid.items() if k != "surrogate"}
        if "surrogate" in self.grid:
            out["surrogate"] = {k: v for k, v in self.grid["surrogate"].items() if k != "checks"}
        out.update(seconds=self.seconds, n_factorizations=self.n_factorizations, timings=dict(self.timings))
        if self.path == "surrogate":
            out["judge"] = dict(self.judge)
        return out

    def evaluate(self, body) -> ErrorMeasures:
        """Error measures of ``body`` (:class:`ErrorMeasures`): those of
        :func:`flexmor.analysis.frequency.error_measures` (``band_error``, ``rms_rel_error_pct``,
        ``hinf_error``, ``max_rel_error`` and where it occurs ...), ``judged`` (which reference,
        :meth:`reference`), ``spurious_resonances_hz`` and ``max_rel_error_at_spurious_resonance``
        (:func:`flexmor.analysis.resonances.spurious_resonances`: resonances of the body in the band
        where the full model has none), ``notes`` (:func:`~flexmor.analysis.frequency.error_notes`,
        the spurious resonances, and a body built for another band), the band and the curve
        ``rel_error``.

        A body of another model, damping or ports is refused (:meth:`check_judgeable`).

        A free body whose basis excludes the rigid-body modes (``info['n_rigid_excluded']``, the
        floating-frame case: the frame carries the rigid motion) is judged on the elastic part
        of ``H`` (:attr:`H_elastic`, the FRF from the inputs' elastic part ``(I - M Φ Φᵀ) B`` to the outputs'
        ``C (I - Φ Φᵀ M)``, :func:`~flexmor.reduction.free_body.with_elastic_part`: exact
        for proportional damping, and computed directly rather than as ``H`` minus the rigid-body
        response, which at low frequencies exceeds it by orders of magnitude).

        Against the surrogate (``path='surrogate'``) the body is checked by direct solves of the full model
        at the frequencies where its error integrand is largest (:func:`flexmor.analysis.judge.judge_check`,
        ``judge_check``; the solves are kept for the next bodies): where the two figures differ by more than
        10 %, the measures are those with the direct solutions in place of the surrogate's, and a figure the
        surrogate does not resolve is flagged with its bound (``floor``, a note). ``same_subspace_as`` names
        the bodies evaluated before whose bases span the same subspace (a note says so).
        """
        self.check_judgeable(body)
        Hr = frf_reduced(body, self.freqs)
        H, judged = self.reference(body)
        check = self._judge_check(body, H, Hr)
        if check is not None and check[0]["corrected"]:
            H = check[1]  # the full model's solutions where they were computed
        out = error_measures(self.freqs, H, Hr, resonances=self.resonances)
        out["judged"] = judged
        out["judge_check"] = None if check is None else check[0]
        shared = self._same_subspace(body)
        out["same_subspace_as"] = shared
        sr = spurious_resonances(body, self.freqs, H, self.resonances, self.zeta, band=self.band,
                                 max_rel_error_hz=out["max_rel_error_hz"], max_rel_error=out["max_rel_error"])
        note = sr.pop("note")
        unseen = sr.pop("unseen_note", None)
        out.update(sr)
        notes = error_notes(out, damped=body.D is not None, n_resonances=int(self.resonances.size),
                            order=body.order) + ([note] if note else []) + ([unseen] if unseen else [])
        if check is not None:
            notes += judge_notes(check[0], out["band_error"])
        if shared:
            notes.append(subspace_note([*shared, body_label(body)]))
        built = (body.info or {}).get("band")
        if built and not np.allclose(built, self.band, rtol=1e-9, atol=0.0):
            notes.append(f"{body.method or 'the body'} was built for {built[0]:g}-{built[1]:g} Hz, "
                         f"judged over {self.band[0]:g}-{self.band[1]:g} Hz: reduce with band={self.band} "
                         "for this band")
        return ErrorMeasures(**{k: out.get(k) for k in MEASURE_KEYS}, band_hz=self.band, notes=tuple(notes),
                             freqs_hz=self.freqs, rel_error=rel_error(H, Hr))

    def check_judgeable(self, body) -> None:
        """Refuse a body that was not reduced from this response's model, damping and ports
        (:func:`check_judgeable`)."""
        check_judgeable(body, origin=self.origin, damping=self.damping, inputs=self.input_names,
                   outputs=self.output_names, label=self.model_label)

    def reference(self, body):
        """``(H, judged)``: the full FRF that ``body`` is judged against and its description,
        :data:`JUDGED_ELASTIC` (:attr:`H_elastic`, for a free body whose basis excludes the
        rigid-body modes) or :attr:`H` (:data:`JUDGED_RIGID` on a free model, else :data:`JUDGED_FULL`)."""
        return _pick(self.H, self.H_elastic, body)

    def _direct_frf(self, model, ports, solver, modes=None) -> Callable:
        """``freqs -> H`` of the full model at ``ports`` by direct solves (:func:`~flexmor.dynamics.frf.frf_full`),
        the model as the surrogate path defines it: modal damping with its ratio exact in the pre-pass's
        ``modes = (f, phi)`` up to :data:`~flexmor.dynamics.surrogate.MODES_MARGIN` ``fmax`` (computed here
        when None, e.g. after a cache hit), the same correction as the surrogate's."""
        def solve(freqs):
            with blas_threads(1):
                return frf_full(model, ports, freqs, solver=solver)

        if not isinstance(model.damping, ModalDamping):
            return solve
        if modes is None:
            pre = modes_below(model, self.band[1] * MODES_MARGIN, solver)
            modes = (pre.f, pre.phi)
        return _modal_correction(solve, model.damping, modes[0], modes[1], ports)

    def _direct_at(self, idx, body) -> np.ndarray:
        """The full model's FRF at the grid points ``idx`` by direct solves, the block ``body`` is judged on;
        solved once for all bodies (:attr:`judge`)."""
        new = [i for i in idx if i not in self._solved]
        if new:
            t0 = time.perf_counter()
            if self._direct is None:
                self._direct = self._direct_frf(*self._direct_of)
            solver = self._direct_of[2]
            with step(solver.progress, f"direct check at {len(new)} frequencies ({self._direct_of[0].n_dof} DOF)"):
                H = self._direct(self.freqs[new])
            self._solved.update(zip(new, H))
            self.judge["direct_solves"] += len(new)
            self.judge["seconds"] += time.perf_counter() - t0
        whole, elastic = split_elastic(np.stack([self._solved[i] for i in idx]), self._given)
        return _pick(whole, elastic, body)[0]

    def _judge_check(self, body, H, Hr):
        """``(record, H_checked)`` of :func:`flexmor.analysis.judge.judge_check` against a surrogate
        reference, with this body's ``new_solves`` and ``seconds``; None for a direct or dense reference, or
        with ``judge_checks=0`` for a body not built from a surrogate."""
        if self.path != "surrogate":
            return None
        built = built_from_surrogate(body.info)
        n = max(self.judge_checks, JUDGE_CHECKS) if built else self.judge_checks
        if n <= 0:
            return None
        sur = self.grid.get("surrogate") or {}
        extra = []
        worst = (sur.get("final_check") or {}).get("freq_hz")
        if worst is not None:
            k = int(np.argmin(np.abs(self.freqs - worst)))
            if abs(self.freqs[k] / worst - 1) <= 1e-9:
                extra.append(k)
        tol = max(float(sur.get("tol", 0.0)), float(sur.get("max_check_error", 0.0)))
        t0, n0 = time.perf_counter(), self.judge["direct_solves"]
        record, Hc = judge_check(self.freqs, H, Hr, lambda idx: self._direct_at(idx, body), tol=tol, n_checks=n,
                                 extra=extra, solved=list(self._solved), built=built)
        record.update(new_solves=self.judge["direct_solves"] - n0, seconds=time.perf_counter() - t0)
        self.judge["bodies_checked"] += 1
        return record, Hc

    def _same_subspace(self, body) -> list:
        """Labels of the bodies evaluated before whose bases span the subspace of ``body``
        (:func:`flexmor.analysis.subspaces.same_subspace`; bodies of the same method and order are not
        compared); the span of ``body`` is kept for the next, the oldest dropped beyond
        :data:`SPANS_KEPT_BYTES` (the bases are held, not copied)."""
        span = Span.of(body)
        out = [sp.label for sp in self._spans if sp.label != span.label and same_subspace(sp, span) is not None]
        self._spans = [sp for sp in self._spans if sp.V is not span.V] + ([span] if span.V is not None else [])
        while len(self._spans) > 1 and sum(sp.V.nbytes for sp in self._spans) > SPANS_KEPT_BYTES:
            self._spans.pop(0)
        return list(dict.fromkeys(out))

def _pick(H, H_elastic, body):
    """``(H, judged)`` of :meth:`FullResponse.reference` from the whole response ``H`` and its elastic part."""
    if H_elastic is None:
        return H, JUDGED_FULL
    if body.info.get("n_rigid_excluded"):
        return H_elastic, JUDGED_ELASTIC
    return H, JUDGED_RIGID


def check_judgeable(body, *, origin: dict, damping, inputs, outputs, label: str = "this model") -> None:
    """Refuse a body that was not reduced from the model of fingerprint ``origin``
    (:func:`flexmor.origin.fingerprint`), with ``damping`` and the ports named ``inputs`` and
    ``outputs`` (``label`` names that model in the messages).

    Raises
    ------
    ModelError
        The body's fingerprint names another model (DOF count, equation map, K, M, D:
        :func:`flexmor.origin.check_origin`), or its damping is another.
    PortError
        Its inputs or outputs are others (names, or their number); ``body`` is no reduced body.
    """
    from ..body import ReducedModel

    if not isinstance(body, ReducedModel):
        raise ModelError(f"a reduced body (flexmor.reduce(...), or flexmor.io.read_body(path) for a file) is judged, "
                         f"got {type(body).__name__}{f' {body!r}' if isinstance(body, str) else ''}",
                         params=("body",))
    check_origin(body, origin, label=label, advice="judge it against the model it was reduced from")
    name = f"body ({body.method or 'reduced'}, order {body.order})"
    if not same_damping(body.damping, damping):
        raise ModelError(f"{name} was reduced with damping {describe_damping(body.damping)}; this reference "
                         f"has {describe_damping(damping)}. A body is judged against the full model with "
                         "its own damping: give the model that damping (rayleigh / modal_damping / "
                         "band_rayleigh), or reduce again", params=("damping",))
    for role, mine, theirs, count in (("inputs", list(inputs), body.input_names, body.B.shape[1]),
                                      ("outputs", list(outputs), body.output_names, body.C.shape[0])):
        names = [str(n).strip().lower() for n in theirs]
        if count != len(mine) or (names and names != [str(n).strip().lower() for n in mine]):
            raise PortError(f"{name} has {count} {role} ({', '.join(map(str, theirs)) or 'unnamed'}); this "
                            f"reference has {len(mine)} ({', '.join(map(str, mine))}): judge it with the ports "
                            "it was reduced for", params=("ports",))


def _modal_correction(evaluate, damping, f_modes, phi, ports):
    """``evaluate`` (the FRF of the sparse Rayleigh realization of modal damping) with the share of
    the modes ``phi`` (mass-normalized, frequencies ``f_modes`` Hz) moved to the ratio of ``damping``:
    ``H += sum_k c_k b_k^T (1/(w_k^2 - w^2 + 2i zeta w_k w) - 1/(w_k^2 - w^2 + i w d_k))``, ``d_k`` the
    Rayleigh value ``alpha + beta w_k^2`` (exact for these modes: the realization is proportional)."""
    wk = 2 * np.pi * np.asarray(f_modes, float)
    d_modal = 2 * damping.ratios(f_modes) * wk
    d_rayleigh = damping.alpha + damping.beta * wk ** 2
    Bp, Cp = ports.reduced(phi)
    Bp = Bp.T

    def corrected(freqs):
        H = evaluate(freqs)
        w = 2 * np.pi * np.asarray(freqs, float)[:, None]
        g = 1 / (wk ** 2 - w ** 2 + 1j * w * d_modal) - 1 / (wk ** 2 - w ** 2 + 1j * w * d_rayleigh)
        return H + np.einsum("pk,fk,mk->fpm", Cp, g, Bp)

    return corrected
