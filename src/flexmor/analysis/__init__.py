"""Judging reduced bodies: error measures against the full model's frequency response.

The responses themselves (FRF, modal pre-pass, time integration) are in :mod:`flexmor.dynamics`.
"""

from .frequency import band_error, band_grid, error_measures, max_rel_error, rel_error

__all__ = ["rel_error", "band_error", "max_rel_error", "band_grid", "error_measures"]
