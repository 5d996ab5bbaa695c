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
    ``lambda_min/lambda_max`` (0 for a singular, negative for an indefinite mass).

    With pardiso, one Cholesky factorization of ``M`` and two inverse iterations: a ratio below
    1e-12 counts as singular; a Cholesky that meets a non-positive pivot is followed by one
    ``L D L^T`` whose pivots tell which: perturbed ones (below 1e-8 of the largest) singular,
    negative ones (Sylvester's law of inertia) indefinite. With another backend, one
    factorization and ``iterations`` inverse iterations estimate the smallest eigenvalue: a failed
    factorization, a ratio below 1e-12 or a negative Rayleigh quotient count as singular.
    Skipped (None) above ``max_dof`` equations.
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
        except SolverError:
            F = factorize(M, symmetric=True, positive=False, check=False)
            if F.perturbed:
                kind = f"singular ({F.perturbed} pivots of its LDL^T below 1e-8 of the largest)"
            elif F.inertia is not None and F.inertia[1]:
                kind = f"indefinite ({F.inertia[1]} negative eigenvalues)"
        cholesky = F.backend == "pardiso" and F.perturbed is None  # a positive definite factor
        x = np.random.default_rng(1).standard_normal(M.shape[0])
        for _ in range(0 if kind else 2 if cholesky else iterations):
            x = F.solve(x)
            nx = np.linalg.norm(x)
            if not np.isfinite(nx) or nx == 0:
                raise SolverError("inverse iteration broke down")
            x /= nx
        ratio = (0.0 if F.perturbed else -1.0) if kind else float(x @ (M @ x)) / lam_max
    except (SolverError, RuntimeError, ValueError, np.linalg.LinAlgError):
        ratio = 0.0
    if kind is None and ratio < 1e-12:  # (its value at round-off level is noise: not shown)
        kind = "indefinite (a negative eigenvalue)" if ratio < -1e-12 else \
            "singular (smallest eigenvalue below 1e-12 of the largest)"
    if kind is not None:
        warnings.warn(f"{where}: the mass matrix is {kind}; {SINGULAR_MASS_NOTE}", FlexmorWarning, stacklevel=3)
    return ratio
