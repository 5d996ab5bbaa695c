"""Sparse linear algebra: one factorization layer and eigen solvers built on it."""

from .eigen import eigenmodes
from .factorize import BACKENDS, Factorization, available_backends, factorize

__all__ = ["factorize", "Factorization", "available_backends", "BACKENDS", "eigenmodes"]
