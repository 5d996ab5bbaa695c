"""Judging several reduced bodies against one full frequency response computed once."""

from __future__ import annotations

import logging
import time
from typing import Callable

import numpy as np

from ..linalg import factorize
from ..linalg.eigen import DENSE_LIMIT, default_shift, eigenmodes, frequencies_hz
from .frequency import band_grid, error_measures, frf_full, frf_reduced, rel_error

__all__ = ["FullResponse", "modal_damping_ratios"]

log = logging.getLogger(__name__)


def modal_damping_ratios(damping: dict, freqs_hz) -> np.ndarray | None:
    """Damping ratio of each mode for Rayleigh damping ``zeta = alpha/(2w) + beta w/2``; else None."""
    if damping.get("type") != "rayleigh":
        return None
    w = 2 * np.pi * np.maximum(np.asarray(freqs_hz, float), 1e-30)
    return damping["alpha"] / (2 * w) + damping["beta"] * w / 2


def _resonances(model, fmax: float, backend: str, max_modes: int = 400) -> np.ndarray:
    """Eigenfrequencies (Hz) of the full model up to ``fmax`` (modal pre-pass, one factorization)."""
    sigma = default_shift(model.K, model.M)
    F = None
    if model.n_dof > DENSE_LIMIT:
        F = factorize((model.K - sigma * model.M).tocsr(), backend, positive=True)
    k = min(model.n_dof, 20)
    while True:
        lam, _ = eigenmodes(model.K, model.M, k, sigma=sigma, factorization=F)
        f = frequencies_hz(lam)
        if f[-1] > fmax or k >= min(model.n_dof, max_modes):
            return f[f <= fmax]
        k = min(model.n_dof, 2 * k, max_modes)


class FullResponse:
    """The full model's FRF over a band, computed once and reused for every reduced body.

    Parameters
    ----------
    model : FEModel
    ports : Ports
    band : (float, float)
        ``(fmin, fmax)`` in Hz.
    n : int
        Log-spaced base points of :func:`band_grid` (plus resonance refinement).
    backend : str
        Backend of :func:`flexmor.linalg.factorize`.
    progress : callable, optional
        ``progress(iterable, total)`` wrapper for the sweep.

    Attributes
    ----------
    freqs : ndarray
        The grid (Hz). ``resonances`` the full model's eigenfrequencies in the band.
    H : ndarray, shape (n_freq, n_outputs, n_inputs)
    seconds : float
        Wall time of the pre-pass and the sweep.
    """

    def __init__(self, model, ports, band, *, n: int = 200, backend: str = "auto", progress: Callable | None = None):
        t0 = time.perf_counter()
        self.band = (float(band[0]), float(band[1]))
        band_grid(*self.band, n=2)  # validates the band before any expensive work
        self.resonances = _resonances(model, self.band[1], backend)
        zeta = modal_damping_ratios(model.damping, self.resonances)
        self.freqs = band_grid(*self.band, n=n, resonances=self.resonances, zeta=zeta)
        self.H = frf_full(model, ports, self.freqs, backend=backend, progress=progress)
        self.seconds = time.perf_counter() - t0
        log.info("full FRF: %d frequencies in %.2f s", self.freqs.size, self.seconds)

    def evaluate(self, reduced) -> dict:
        """Error measures of ``reduced`` (dict with ``band_error``, ``max_rel_error``, ``rel_error``)."""
        Hr = frf_reduced(reduced, self.freqs)
        out = error_measures(self.freqs, self.H, Hr)
        out["rel_error"] = rel_error(self.H, Hr)
        return out
