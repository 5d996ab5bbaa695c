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

    One symmetric indefinite factorization ``M = L D L^T``: where the backend reports its pivots
    (pardiso), pivots it had to perturb (below 1e-8 of the largest) mean singular, negative ones
    (Sylvester's law of inertia) indefinite, and a solve gives the Rayleigh quotient returned;
    no other solve. Otherwise ``iterations`` inverse iterations estimate the smallest eigenvalue:
    a failed factorization, a ratio below 1e-12 or a negative Rayleigh quotient count as singular.
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
        F = factorize(M, symmetric=True, positive=False, check=False)
        pivots = F.perturbed is not None
        if pivots and F.perturbed:
            kind = f"singular ({F.perturbed} pivots of its LDL^T below 1e-8 of the largest)"
        elif pivots and F.inertia is not None and F.inertia[1]:
            kind = f"indefinite ({F.inertia[1]} negative eigenvalues)"
        x = np.random.default_rng(1).standard_normal(M.shape[0])
        for _ in range(0 if kind else 2 if pivots else iterations):
            x = F.solve(x)
            nx = np.linalg.norm(x)
            if not np.isfinite(nx) or nx == 0:
                raise SolverError("inverse iteration broke down")
            x /= nx
        ratio = 0.0 if kind and F.perturbed else -1.0 if kind else float(x @ (M @ x)) / lam_max
        if pivots and not kind:  # positive definite by its pivots
            ratio = max(ratio, np.finfo(float).tiny)
    except (SolverError, RuntimeError, ValueError, np.linalg.LinAlgError):
        ratio = 0.0
    if kind is None and ratio < 1e-12:  # (its value at round-off level is noise: not shown)
        kind = "indefinite (a negative eigenvalue)" if ratio < -1e-12 else \
            "singular (smallest eigenvalue below 1e-12 of the largest)"
    if kind is not None:
        warnings.warn(f"{where}: the mass matrix is {kind}; {SINGULAR_MASS_NOTE}", FlexmorWarning, stacklevel=3)
    return ratio
