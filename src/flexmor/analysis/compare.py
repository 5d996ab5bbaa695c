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
from .grid import DEFAULT_TOL, adaptive_grid, initial_grid
from .resonances import spurious_resonances

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
        rows += [("note", n) for n in self.notes]
        return f"band_error {self.band_error:.3g} over {band_text(self.band_hz)}", rows

    def to_dict(self) -> dict:
        """The JSON record: the :data:`~flexmor.analysis.frequency.MEASURE_KEYS` and ``notes``
        (without the band and the curves, which the records carry elsewhere)."""
        return {**{k: getattr(self, k) for k in MEASURE_KEYS}, "notes": list(self.notes)}


class FullResponse:
    """The full model's FRF over a band, computed once and reused for every reduced body.

    A modal pre-pass finds the resonances in the band and their modal damping; the adaptive
    grid (:func:`flexmor.analysis.grid.adaptive_grid`) places points at them and refines
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
    """

    def __init__(self, model, ports, band, *, n: int = 50, tol: float = DEFAULT_TOL, max_points: int = 3000,
                 solver: SolverContext | None = None, path: str = "auto", surrogate_tol: float = DEFAULT_SURROGATE_TOL,
                 cache=True, progress: Callable | None = None, check_solver: str = "auto"):
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
        params = {"band": self.band, "n": int(n), "tol": float(tol), "max_points": int(max_points), "path": path}
        if path == "surrogate":
            params["surrogate_tol"] = float(surrogate_tol)
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
            f_modes = fmax * (MODES_MARGIN if self.path == "surrogate" else 1.0)
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
        """
        self.check_judgeable(body)
        Hr = frf_reduced(body, self.freqs)
        H, judged = self.reference(body)
        out = error_measures(self.freqs, H, Hr, resonances=self.resonances)
        out["judged"] = judged
        sr = spurious_resonances(body, self.freqs, H, self.resonances, self.zeta, band=self.band,
                                 max_rel_error_hz=out["max_rel_error_hz"], max_rel_error=out["max_rel_error"])
        note = sr.pop("note")
        unseen = sr.pop("unseen_note", None)
        out.update(sr)
        notes = error_notes(out, damped=body.D is not None) + ([note] if note else []) + ([unseen] if unseen else [])
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
        if self.H_elastic is None:
            return self.H, JUDGED_FULL
        if body.info.get("n_rigid_excluded"):
            return self.H_elastic, JUDGED_ELASTIC
        return self.H, JUDGED_RIGID


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
