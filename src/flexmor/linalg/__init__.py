"""Sparse linear algebra: one factorization layer, the solver context, and eigen solvers built on it."""

from .backends import BACKENDS, Backend, available_backends
from .context import EigenPolicy, SolverContext
from .eigen import eigenmodes
from .factorization import Factorization, SolverStats
from .factorize import factorize

__all__ = ["factorize", "Factorization", "SolverContext", "SolverStats", "EigenPolicy", "available_backends",
           "Backend", "BACKENDS", "eigenmodes"]
