"""The mass-matrix check shared by the readers of decks with quadratic elements (CalculiX, Abaqus).

Quadratic elements (``C3D20R``, ``C3D20``, ``C3D15``, ``C3D10``, 8-node shells and plane
elements) can give a singular mass matrix (reduced integration) or one with zero or negative
diagonal entries (row-sum lumping of serendipity elements): the readers then warn instead of
refusing the file, and :func:`check_mass` estimates the smallest eigenvalue of ``M``.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["QUADRATIC_TYPES", "check_mass"]

#: Element types whose mass matrix may legitimately be singular or indefinite (quadratic
#: serendipity / reduced-integration / row-sum-lumped): such decks get warnings, not errors.
QUADRATIC_TYPES = ("C3D20", "C3D15", "C3D10", "S8", "CPS8", "CPE8", "CAX8")


def check_mass(model, where, *, max_dof: int = 500_000, iterations: int = 12) -> float | None:
    """Warn (FlexmorWarning) when the mass matrix is singular or indefinite; return an estimate of
    ``lambda_min/lambda_max`` (0 when it is not positive definite).

    One factorization of ``M`` as positive definite (pardiso: Cholesky) and two inverse iterations
    (``iterations`` with another backend) estimate its smallest eigenvalue: a factorization that
    fails (a pivot ``<= 0``) means singular or indefinite, a ratio below 1e-12 singular, a negative
    Rayleigh quotient indefinite. Skipped (None) above ``max_dof`` equations.
    """
    from ..errors import FlexmorWarning, SolverError
    from ..linalg import factorize
    from ..model import SINGULAR_MASS_NOTE

    M = model.M
    if M.shape[0] > max_dof:
        return None
    lam_max = float(abs(M).sum(axis=1).max())  # Gershgorin bound
    kind = None
    try:
        try:
            F = factorize(M, symmetric=True, positive=True, check=False)
        except SolverError:  # a pivot <= 0 (pardiso's Cholesky), or singular (LU)
            kind, F = "singular or indefinite (a pivot <= 0 in its factorization)", None
        x = np.random.default_rng(1).standard_normal(M.shape[0])
        for _ in range(0 if F is None else 2 if F.backend == "pardiso" else iterations):
            x = F.solve(x)
            nx = np.linalg.norm(x)
            if not np.isfinite(nx) or nx == 0:
                raise SolverError("inverse iteration broke down")
            x /= nx
        ratio = 0.0 if F is None else float(x @ (M @ x)) / lam_max
    except (SolverError, RuntimeError, ValueError, np.linalg.LinAlgError):
        ratio = 0.0
    if kind is None and ratio < 1e-12:  # (its value at round-off level is noise: not shown)
        kind = "indefinite (a negative eigenvalue)" if ratio < -1e-12 else \
            "singular (smallest eigenvalue below 1e-12 of the largest)"
    if kind is not None:
        warnings.warn(f"{where}: the mass matrix is {kind}; {SINGULAR_MASS_NOTE}", FlexmorWarning, stacklevel=3)
    return ratio

