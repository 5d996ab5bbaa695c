"""Responses of second-order bodies, shared by :mod:`flexmor.reduction` and :mod:`flexmor.analysis`.

``frf`` (frequency responses of full and reduced bodies, the pointwise ``rel_error``),
``modes`` (the modal pre-pass up to a frequency, modal damping ratios), ``surrogate`` (a
verified projection of a large model: the error check's full FRF and the Gramian quadrature's
solves) and ``time`` (Newmark / generalized-α integration, input signals, time-domain errors). This package
imports neither of the two above it: methods build bases from these responses, the error
analysis judges reduced bodies with them.
"""

from .frf import ShiftedMatrices, angular_frequency, frf_full, frf_reduced, rel_error
from .modes import modal_damping_ratios, modes_below

__all__ = ["ShiftedMatrices", "angular_frequency", "frf_full", "frf_reduced", "rel_error", "modal_damping_ratios",
           "modes_below"]
