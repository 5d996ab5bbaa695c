"""The error measures of flexmor and the frequency grid they are integrated on.

Conventions as in :mod:`flexmor.dynamics.frf`: frequencies in Hz, FRF arrays of shape
(n_freq, n_outputs, n_inputs). Error measures (named exactly so in code, reports and JSON):

``rel_error(f)``
    ``||H(i2πf) - Ĥ(i2πf)||_F / ||H(i2πf)||_F`` pointwise on the grid
    (:func:`flexmor.dynamics.frf.rel_error`, shared with the reduction methods);
``band_error``
    ``∫ ||H - Ĥ||_F^2 df / ∫ ||H||_F^2 df`` over the band (piecewise-parabolic rule on the grid);
``max_rel_error``
    ``max_f rel_error(f)``; ``max_rel_error_hz`` is where it occurs and
    ``max_rel_error_at_antiresonance`` whether that is an anti-resonance (see
    :func:`at_antiresonance`), where ``||H||`` is small and any relative error is large;
``band_rms_error``, ``rms_rel_error_pct``
    ``sqrt(band_error)`` and ``100 sqrt(band_error)``: the band_error as the RMS relative
    error (in %) an engineer reads as "x %";
``hinf_error``
    ``max_f σ_max(H - Ĥ) / max_f σ_max(H)``: the largest error relative to the band's peak.

:data:`MEASURES` documents each of them in one line (for ``--help``, the README and the report).
"""

from __future__ import annotations

import numpy as np

from ..dynamics.frf import rel_error
from ..dynamics.grid import ANTIRESONANCE_FACTOR as _ANTIRESONANCE_FACTOR
from ..dynamics.grid import band_error, trapezoid_weights
from ..errors import OptionError

__all__ = ["rel_error", "band_error", "trapezoid_weights", "max_rel_error", "hinf_error", "band_grid", "error_measures",
           "MEASURES", "TOL_MEASURES", "MEASURE_KEYS", "measure_record", "at_antiresonance", "resonance_share",
           "error_notes", "ANTIRESONANCE_FACTOR", "MANY_MODES_ERROR", "NOTE_PARAMS"]

#: One line per error measure, in the order of the tables.
MEASURES = {
    "band_error": "∫|H-Hr|²df / ∫|H|²df over the band (squared relative L2 error, the measure of the reference tables)",
    "rms_rel_error_pct": "100·sqrt(band_error): RMS relative error over the band in %",
    "hinf_error": "max_f |H-Hr| / max_f |H|: largest error relative to the band's peak response (H∞-type)",
    "max_rel_error": "max_f |H-Hr|/|H| (pointwise, Frobenius norms): large at anti-resonances, where |H| is small",
}
#: The parameters the notes of :func:`error_notes` name, as bare words (an application may show them
#: as its own names: :func:`flexmor.errors.name_parameters`).
NOTE_PARAMS = ("rayleigh", "modal_damping")
#: Measures the ``tol`` of :func:`flexmor.workflow.reduce_and_judge` can target (``band_rms_error`` =
#: rms_rel_error_pct / 100 is JSON only).
TOL_MEASURES = tuple(MEASURES)
#: The fields of a body's judgement in every JSON record and error table, in order: those of
#: :func:`error_measures`, then those of :meth:`flexmor.analysis.compare.FullResponse.evaluate`
#: (``judged``: the reference, full response or its elastic part; the spurious resonances;
#: ``judge_check``: the direct check of a surrogate reference, :mod:`flexmor.analysis.judge`;
#: ``same_subspace_as``: bodies judged before that span the same subspace).
MEASURE_KEYS = ("band_error", "band_rms_error", "rms_rel_error_pct", "hinf_error", "max_rel_error",
                "max_rel_error_hz", "max_rel_error_at_antiresonance", "resonance_share",
                "max_rel_error_at_spurious_resonance", "spurious_resonances_hz", "judged", "judge_check",
                "same_subspace_as")
#: ``||H||_F`` at an anti-resonance is at most the band median divided by this factor (defined with the grid,
#: which resolves the anti-resonances: :data:`flexmor.dynamics.grid.ANTIRESONANCE_FACTOR`).
ANTIRESONANCE_FACTOR = _ANTIRESONANCE_FACTOR
#: Relative frequency window (±) in which an anti-resonance is a local minimum of ``||H||_F``.
ANTIRESONANCE_WINDOW = 0.05
#: Share of the band_error within ±1 % of the resonances above which an undamped body's
#: error is said to be dominated by them.
RESONANCE_DOMINATED = 0.5

#: A body whose band error is above this, judged over a band with more of the full model's resonances than its
#: order, is told so (:func:`error_notes`).
MANY_MODES_ERROR = 1e-2


def max_rel_error(H, Hr) -> float:
    """``max_f rel_error(f)``."""
    return float(np.max(rel_error(H, Hr)))


def hinf_error(H, Hr) -> float:
    """Band-limited relative H-infinity error estimate ``max_f σ_max(H - Hr) / max_f σ_max(H)``.

    Evaluated on the grid of ``H`` (which is refined at the resonances, where the maxima
    lie); a lower bound of the true band-limited value, exact up to the grid resolution.
    """
    num = np.linalg.norm(H - Hr, ord=2, axis=(1, 2)).max()
    den = np.linalg.norm(H, ord=2, axis=(1, 2)).max()
    return float(num / den) if den > 0 else float("nan")


def at_antiresonance(freqs, H, i: int) -> bool:
    """Whether grid point ``i`` is at an anti-resonance of ``H``.

    True when ``f_i`` is inside the band (not an end point), ``||H(f_i)||_F`` is at most the
    band median of ``||H||_F`` divided by :data:`ANTIRESONANCE_FACTOR` (10) and within a factor
    2 of the smallest ``||H||_F`` within ``±`` :data:`ANTIRESONANCE_WINDOW` (5 %) in frequency
    (a local minimum, up to the grid).
    """
    f = np.asarray(freqs, float)
    if i <= 0 or i >= f.size - 1:
        return False
    h = np.sqrt(np.sum(np.abs(H) ** 2, axis=(1, 2)))
    near = np.abs(f - f[i]) <= ANTIRESONANCE_WINDOW * f[i]
    return bool(h[i] <= np.median(h) / ANTIRESONANCE_FACTOR and h[i] <= 2.0 * h[near].min())


def resonance_share(freqs, H, Hr, resonances, width: float = 0.01) -> float | None:
    """Share of the band_error's numerator ``∫||H - Hr||² df`` within ``±width`` (relative) of the
    ``resonances`` (Hz); None without resonances or error."""
    res = np.atleast_1d(np.asarray(resonances if resonances is not None else [], float))
    f = np.asarray(freqs, float)
    if res.size == 0 or f.size < 2:
        return None
    e2 = np.sum(np.abs(H - Hr) ** 2, axis=(1, 2))
    w = trapezoid_weights(f)
    total = float(w @ e2)
    if not total > 0:
        return None
    near = np.any(np.abs(f[:, None] - res[None, :]) <= width * res[None, :], axis=1)
    return float(w[near] @ e2[near] / total)


def error_measures(freqs, H, Hr, *, resonances=None) -> dict:
    """All error measures of one reduced body as a JSON-ready dict: ``band_error``,
    ``band_rms_error``, ``rms_rel_error_pct``, ``hinf_error``, ``max_rel_error``,
    ``max_rel_error_hz``, ``max_rel_error_at_antiresonance`` and, with the full model's
    ``resonances`` (Hz), ``resonance_share`` (:func:`resonance_share`)."""
    be = band_error(freqs, H, Hr)
    rel = rel_error(H, Hr)
    i = int(np.nanargmax(rel)) if np.any(np.isfinite(rel)) else 0
    rms = float(np.sqrt(be)) if be >= 0 else float("nan")
    out = {"band_error": be, "band_rms_error": rms, "rms_rel_error_pct": 100.0 * rms,
           "hinf_error": hinf_error(H, Hr), "max_rel_error": float(np.max(rel)),
           "max_rel_error_hz": float(np.asarray(freqs, float)[i]),
           "max_rel_error_at_antiresonance": at_antiresonance(freqs, H, i)}
    if resonances is not None:
        out["resonance_share"] = resonance_share(freqs, H, Hr, resonances)
    return out


def measure_record(measures: dict | None) -> dict:
    """The :data:`MEASURE_KEYS` of ``measures`` (None for each when not evaluated) and its ``notes``."""
    measures = measures or {}
    return {**{k: measures.get(k) for k in MEASURE_KEYS}, "notes": list(measures.get("notes", []))}


def error_notes(measures: dict, *, damped: bool, n_resonances: int | None = None,
                order: int | None = None) -> list[str]:
    """One-line explanations of ``measures`` (of :func:`error_measures`) a user should read; with the number of the
    full model's resonances in the band and the body's order, whether the band holds more modes than the body can
    (where the band error is above :data:`MANY_MODES_ERROR`)."""
    notes = []
    if n_resonances is not None and order is not None and n_resonances > order \
            and measures["band_error"] > MANY_MODES_ERROR:
        notes.append(f"the band holds {n_resonances} resonances of the full model, more than the body's order "
                     f"{order}: it cannot hold all that its ports see, nor can an estimate built from bodies of a "
                     "similar order tell its error; raise the order or narrow the band")
    if measures.get("max_rel_error_at_antiresonance") and measures["max_rel_error"] >= 0.1:
        notes.append(f"max_rel_error {measures['max_rel_error']:.3g} is at the anti-resonance near "
                     f"{measures['max_rel_error_hz']:.4g} Hz, where |H| is small; rms_rel_error_pct and "
                     "hinf_error measure the response itself")
    share = measures.get("resonance_share")
    if not damped and share is not None and share > RESONANCE_DOMINATED and measures["band_error"] > 1e-12:
        notes.append(f"undamped model: {100 * share:.0f} % of the error lies within 1 % of the resonances, where a "
                     "tiny frequency shift gives a huge error; add damping (rayleigh or modal_damping) for a "
                     "measure of the response")
    return notes


def band_grid(fmin: float, fmax: float, *, n: int = 200, resonances=None, zeta: float | None = None) -> np.ndarray:
    """Frequency grid in Hz for error integration over ``[fmin, fmax]``.

    ``n`` log-spaced points, plus points clustered around each resonance in the band so
    that peaks are resolved: with modal damping ratio ``zeta`` at offsets
    ``±{0.25, 0.5, 1, 2, 4} * zeta * f_k`` (the half-power bandwidth is ``2 zeta f_k``);
    without damping at relative offsets ``±{1e-3, 3e-3, 1e-2, 3e-2}`` (undamped peaks are
    infinite at ``f_k``, which is never itself a grid point).

    Parameters
    ----------
    fmin, fmax : float
        Band in Hz, ``0 < fmin < fmax``.
    n : int
        Number of log-spaced base points.
    resonances : array_like, optional
        Eigenfrequencies (Hz) of the full model; those inside the band get refinement.
    zeta : float or array_like, optional
        Modal damping ratio (one, or one per resonance) used to size the refinement.
    """
    if not (np.isfinite(fmin) and np.isfinite(fmax)) or fmin <= 0 or fmax <= fmin:
        raise OptionError(f"band must satisfy 0 < FMIN < FMAX (Hz), got {fmin}:{fmax}")
    pts = [np.geomspace(fmin, fmax, int(n))]
    if resonances is not None:
        res = np.atleast_1d(np.asarray(resonances, float))
        zetas = np.broadcast_to(np.asarray(0.0 if zeta is None else zeta, float), res.shape)
        for fk, zk in zip(res, zetas):
            rel = np.array([0.25, 0.5, 1, 2, 4]) * zk if zk > 0 else np.array([1e-3, 3e-3, 1e-2, 3e-2])
            rel = rel[rel < 0.5]
            if fmin < fk < fmax:
                pts.append(fk * (1 - rel))
                pts.append(fk * (1 + rel))
    f = np.unique(np.concatenate(pts))
    return f[(f >= fmin) & (f <= fmax)]
