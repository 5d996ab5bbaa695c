"""The error measures of flexmor and the frequency grid they are integrated on.

Conventions as in :mod:`flexmor.dynamics.frf`: frequencies in Hz, FRF arrays of shape
(n_freq, n_outputs, n_inputs). Error measures (named exactly so in code, reports and JSON):

``rel_error(f)``
    ``||H(i2πf) - Ĥ(i2πf)||_F / ||H(i2πf)||_F`` pointwise on the grid
    (:func:`flexmor.dynamics.frf.rel_error`, shared with the reduction methods);
``band_error``
    ``∫ ||H - Ĥ||_F^2 df / ∫ ||H||_F^2 df`` over the band (piecewise-parabolic rule on the grid);
``max_rel_error``
    ``max_f rel_error(f)``.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.frf import rel_error
from ..errors import OptionError

__all__ = ["rel_error", "band_error", "max_rel_error", "hinf_error", "band_grid", "error_measures"]


def band_error(freqs, H, Hr) -> float:
    """``∫ ||H - Hr||_F^2 df / ∫ ||H||_F^2 df`` on the grid ``freqs``.

    Both integrals use the piecewise-parabolic rule of
    :func:`flexmor.analysis.grid.quadrature_weights` (third order on smooth integrands, exact
    for the trapezoidal limit of two points), unless its error integral differs from the
    trapezoidal rule's by more than a factor 2 (an unresolved, noisy error curve, where
    the parabolic rule's negative weights on graded grids are not safe): then both integrals
    use the trapezoidal rule. A single frequency gives the pointwise ratio.
    """
    from .grid import quadrature_weights

    f = np.asarray(freqs, float)
    e2 = np.sum(np.abs(H - Hr) ** 2, axis=(1, 2))
    h2 = np.sum(np.abs(H) ** 2, axis=(1, 2))
    if f.size < 2:
        return float(e2[0] / h2[0]) if h2.size and h2[0] > 0 else float("nan")
    w = quadrature_weights(f)
    d = np.diff(f) / 2
    wt = np.zeros_like(f)  # trapezoidal rule: positive weights
    wt[:-1] += d
    wt[1:] += d
    den, num = w @ h2, w @ e2
    num_t = wt @ e2
    if not (den > 0 and 0.5 * num_t <= num <= 2.0 * num_t):
        # the parabolic rule on a graded grid has negative weights; where the error is not a
        # resolved smooth curve (e.g. round-off noise of a nearly exact body) it can then be far
        # off, even below max_rel_error^2: the positive trapezoidal rule is used instead
        den, num = wt @ h2, num_t
    return float(num / den) if den > 0 else float("nan")


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


def error_measures(freqs, H, Hr) -> dict:
    """All error measures of one reduced body as a JSON-ready dict:
    ``band_error``, ``max_rel_error``, ``hinf_error``."""
    return {"band_error": band_error(freqs, H, Hr), "max_rel_error": max_rel_error(H, Hr),
            "hinf_error": hinf_error(H, Hr)}


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
