"""Plots and reports of reduced bodies."""
