"""Checks of a model before it is reduced: rigid-body modes and mechanisms.

An elastic body has at most six zero-energy modes (three translations, three rotations of a
free body). More mean a mechanism: unconnected parts, missing elements, released DOFs. No
reduced body of a mechanism is useful in a multibody code, and most methods would either fail
with a solver message that does not say why or silently return a body with spurious
zero-frequency modes; :func:`check_rigid_body_modes` refuses it with a :class:`ModelError`
that names the cause. A free body (1 to 6 rigid-body modes) is legal: it is reported with a
:class:`FlexmorWarning`, and the methods handle it (shifted expansion points, exclusion of the
rigid-body modes).
"""

from __future__ import annotations

import warnings

import numpy as np

from .errors import FlexmorWarning, ModelError
from .linalg.context import SolverContext, as_solver

__all__ = ["MAX_RIGID_BODY_MODES", "check_rigid_body_modes", "first_elastic_hz", "mechanism_error"]

#: Zero-energy modes an elastic body can have (3 translations + 3 rotations).
MAX_RIGID_BODY_MODES = 6


def mechanism_error(model, n_zero: int) -> ModelError:
    """The error for a stiffness matrix with ``n_zero`` (> 6) zero-energy modes."""
    where = model.source or model.name
    return ModelError(f"{where}: the stiffness matrix has at least {n_zero} zero-energy modes (a free body has "
                      f"at most {MAX_RIGID_BODY_MODES}): the model is a mechanism; look for unconnected parts, "
                      "missing elements or released DOFs")


def check_rigid_body_modes(model, *, solver: SolverContext | None = None) -> int:
    """Number of rigid-body (zero-energy) modes of ``model``; refuse a mechanism.

    The seven lowest eigenvalues of ``K phi = lam M phi`` (shift-invert at a negative shift, so
    a singular ``K`` needs no special care) are compared with
    :func:`flexmor.linalg.eigen.rigid_body_threshold`. The count is remembered by the ``solver``
    context (:meth:`flexmor.linalg.context.SolverContext.remember`) per stiffness and mass matrix.

    Returns
    -------
    int
        0 for a supported body, 1 to 6 for a free (or partly supported) one; a
        :class:`FlexmorWarning` says so.

    Raises
    ------
    ModelError
        More than six zero-energy modes (a mechanism).
    """
    from .linalg.eigen import is_rigid

    n_zero = int(np.sum(is_rigid(_lowest_eigenvalues(model, as_solver(solver)), model.K, model.M)))
    if n_zero > MAX_RIGID_BODY_MODES:
        raise mechanism_error(model, n_zero)
    if n_zero:
        warnings.warn(f"{model.source or model.name}: {n_zero} rigid-body modes (free or partly supported body); "
                      "methods exclude them or use shifted expansion points", FlexmorWarning, stacklevel=2)
    return n_zero


def _lowest_eigenvalues(model, solver: SolverContext) -> np.ndarray:
    """The seven lowest eigenvalues of ``(K, M)``, remembered by ``solver`` per matrix pair."""
    from .linalg.eigen import eigenmodes

    def compute():
        return eigenmodes(model.K, model.M, min(MAX_RIGID_BODY_MODES + 1, model.n_dof), solver=solver)[0]

    return solver.remember("lowest_eigenvalues", (model.K, model.M), compute)


def first_elastic_hz(model, *, solver: SolverContext | None = None) -> float:
    """The full model's first elastic (non rigid-body) eigenfrequency in Hz; ``inf`` if none is
    among the seven lowest (a mechanism). Reuses the eigenvalues of :func:`check_rigid_body_modes`."""
    from .linalg.eigen import frequencies_hz, is_rigid

    lam = _lowest_eigenvalues(model, as_solver(solver))
    flex = lam[~is_rigid(lam, model.K, model.M)]
    return float(frequencies_hz(flex[:1])[0]) if flex.size else float("inf")
