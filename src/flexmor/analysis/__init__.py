"""Judging reduced bodies: frequency responses and error measures."""

from .frequency import band_error, band_grid, error_measures, frf_full, frf_reduced, max_rel_error, rel_error

__all__ = ["frf_full", "frf_reduced", "rel_error", "band_error", "max_rel_error", "band_grid", "error_measures"]
