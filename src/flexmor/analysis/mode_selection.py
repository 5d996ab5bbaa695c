"""A body trimmed to chosen modes, with the error of the body written.

:func:`trim` puts a body in modal form (:func:`flexmor.modal.modal_form`) and keeps the modes up
to a frequency, or the fewest modes whose verified error over the band meets a tolerance
(selected by the response they carry, :func:`flexmor.modal.response_shares`, not by frequency
alone). The error of the body it returns is measured against the full model when a
:class:`~flexmor.analysis.compare.FullResponse` is given, else against the body before trimming.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.grid import adaptive_grid
from ..errors import OptionError
from ..modal import keep_modes, keep_modes_static, modal_form, response_shares
from .frequency import MEASURES, error_measures

__all__ = ["trim", "REFERENCE_FULL", "REFERENCE_BODY"]

REFERENCE_FULL = "the full model"
REFERENCE_BODY = "the body before trimming (no full model given)"


class _BodyReference:
    """The untrimmed body's FRF on an adaptive grid over the band: a reference without the full model."""

    def __init__(self, body, band):
        f = body.frequencies_hz()
        zeta = None
        if body.D is not None:
            lam = np.diag(body.K)
            zeta = np.diag(body.D) / (2 * np.sqrt(np.clip(lam, 1e-300, None)))
        self.band = tuple(float(b) for b in band)
        # an undamped body's |H|^2 has poles: the grid stays the initial one (points beside its resonances), as the
        # full model's does; refining it bisected towards a pole until a point fell on it (singular)
        refine = zeta is not None and bool(np.all(zeta > 0))
        self.freqs, self.H, _ = adaptive_grid(body.frf, *self.band, resonances=f, zeta=zeta, refine=refine)

    def measures(self, body) -> dict:
        return error_measures(self.freqs, self.H, body.frf(self.freqs))


def trim(body, *, band, max_frequency: float | None = None, tol: float | None = None,
         measure: str = "band_error", full=None, static: bool = True):
    """``(trimmed, record)``: ``body`` in modal form with the modes ``max_frequency`` (Hz) or
    ``tol`` keep (all its elastic modes when neither is given), and the record of what was kept
    and of the error of ``trimmed``.

    Parameters
    ----------
    body : ReducedModel
    band : (float, float)
        Band (Hz) of the error measures.
    max_frequency : float, optional
        Keep the modes at or below this frequency.
    tol : float, optional
        Keep the fewest modes whose ``measure`` meets ``tol``: modes are added in the order of
        the response they carry until it does, then each is dropped again where the error still
        meets ``tol`` (verified after every change). When even all modes miss it, all are kept
        and ``record["tol_reached"]`` is False.
    measure : str
        The error measure of ``tol`` (:data:`flexmor.analysis.frequency.MEASURES`).
    full : FullResponse, optional
        The full model's FRF over ``band``: the error is the body's against the full model
        (judged as :meth:`FullResponse.evaluate` judges it); else against ``body`` itself.
    static : bool
        Where modes are dropped, add the static response they carry under the body's inputs, the frame's
        six accelerations and unit loads at its coupling masters (:func:`flexmor.modal.keep_modes_static`):
        the trimmed body sags like the body. False keeps the modes alone.

    Returns
    -------
    trimmed : ReducedModel
    record : dict
        ``order_before`` (elastic modes of the modal form), ``order``, ``modes_kept`` (1-based,
        ascending frequency), ``frequencies_hz`` and ``max_frequency_hz`` of the modes kept,
        ``reference`` (:data:`REFERENCE_FULL` or :data:`REFERENCE_BODY`), ``band_hz``, the
        error measures and, with ``tol``, ``tol``, ``tol_measure`` and ``tol_reached``.
    """
    if max_frequency is not None and tol is not None:
        raise OptionError("give max_frequency or tol, not both", params=("max_frequency", "tol"))
    if measure not in MEASURES:
        raise OptionError(f"measure={measure!r} is not an error measure; choose one of: {', '.join(MEASURES)}",
                          params=("measure",))
    if max_frequency is not None and not float(max_frequency) > 0:
        raise OptionError(f"max_frequency must be a positive frequency in Hz, got {max_frequency!r}",
                          params=("max_frequency",))
    modal = modal_form(body)
    f = modal.frequencies_hz()
    if full is not None:
        reference = REFERENCE_FULL

        def measures(b):
            return full.evaluate(b).to_dict()
    else:
        reference = REFERENCE_BODY
        ref = _BodyReference(modal, band)
        measures = ref.measures
    record: dict = {"order_before": modal.order, "reference": reference, "band_hz": [float(b) for b in band]}
    if max_frequency is not None:
        keep = np.flatnonzero(f <= float(max_frequency))
        if keep.size == 0:
            raise OptionError(f"max_frequency {float(max_frequency):g} Hz is below the body's lowest elastic mode "
                              f"({f[0]:.4g} Hz): no mode would stay", params=("max_frequency",))
    elif tol is not None:
        keep, reached = _fewest(modal, band, float(tol), measure, measures)
        record.update(tol=float(tol), tol_measure=measure, tol_reached=reached)
    else:
        keep = np.arange(modal.order)
    n_static = 0
    if keep.size == modal.order:
        trimmed = modal
    elif static:
        trimmed, n_static = keep_modes_static(modal, keep)
    else:
        trimmed = keep_modes(modal, keep)
    err = measures(trimmed)
    record.update(order=trimmed.order, modes_kept=(keep + 1).tolist(), frequencies_hz=f[keep].tolist(),
                  max_frequency_hz=float(f[keep].max()), static_vectors=n_static, **err)
    if tol is not None:  # verified on the body written (with its static vectors)
        record["tol_reached"] = bool(err[measure] <= float(tol))
    # the body written says what it is: its order and its error, as judged here (info, compare)
    trimmed.order_note = (f"modal form: {keep.size} of the {modal.order} elastic modes of the body reduced"
                          + (f" (up to {record['max_frequency_hz']:.4g} Hz)" if keep.size < modal.order else "")
                          + (f" and {n_static} static vectors (the static response of the modes left out)"
                             if n_static else ""))
    trimmed.errors = dict({k: v for k, v in err.items() if k != "notes"}, band_hz=[float(b) for b in band],
                          judged=reference, notes=list(err.get("notes") or []))
    return trimmed, record


def _fewest(modal, band, tol, measure, measures):
    """Modes (indices, ascending) whose ``measure`` meets ``tol``: added by response share, then
    each dropped again while the error still meets ``tol``; ``(keep, reached)``."""
    order = np.argsort(-response_shares(modal, band), kind="stable")

    def error(idx):
        return measures(keep_modes(modal, np.sort(idx)))[measure]

    keep = []
    for i in order:
        keep.append(int(i))
        if error(keep) <= tol:
            break
    else:
        return np.arange(modal.order), False
    freqs = modal.frequencies_hz()
    for i in sorted(keep, key=lambda j: -freqs[j]):  # highest modes first
        trial = [j for j in keep if j != i]
        if trial and error(trial) <= tol:
            keep = trial
    return np.sort(np.asarray(keep, int)), True
