"""Modal truncation: the lowest free (or constrained) eigenmodes of the body."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..checks import MAX_RIGID_BODY_MODES, mechanism_error
from ..errors import OptionError, check_choice
from ..linalg.backends import is_iterative
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import eigenmodes, frequencies_hz, is_rigid, whole_clusters
from ..options import option
from ._options import rigid_option
from ._registry import register_method

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModalOptions:
    """Options of :func:`modal`."""

    rigid: str = rigid_option("exclude")
    sigma: float | None = option(None, "shift of the shift-invert Lanczos solver (default: negative, model-scaled)",
                                 parse=float)


@register_method("modal", "lowest eigenmodes (rigid-body modes excluded by default)", options=ModalOptions,
                 survives_coupling=False, uses_inputs=False)
def modal(model, ports, order, *, rigid: str = "exclude", sigma: float | None = None,
          solver: SolverContext | None = None) -> Basis:
    """Modal truncation basis: the ``order`` lowest mass-normalized eigenmodes.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        Unused by the basis (modes do not depend on inputs); kept for the common signature.
    order : int
        Number of modes r.
    rigid : {'exclude', 'include'}
        Rigid-body modes (eigenvalue below :func:`flexmor.linalg.eigen.rigid_body_threshold`)
        of a free body are excluded by default: the floating frame of reference describes
        rigid motion; their number is reported in ``info['n_rigid']``. More than six zero-energy
        modes (a mechanism) raise :class:`~flexmor.errors.ModelError`.
    sigma : float, optional
        Shift of the shift-invert Lanczos solver (default: negative, model-scaled).
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info`` holds ``frequencies_hz`` of the kept modes and ``n_rigid``.

    References
    ----------
    Craig, R. R., Kurdila, A. J. (2006). Fundamentals of Structural Dynamics, 2nd ed.,
    Wiley, ch. 11 (modal truncation).
    """
    solver = as_solver(solver)
    check_choice("rigid", rigid, ["exclude", "include"])
    if order is None:
        raise OptionError("modal needs order", params=("order",))
    n = model.n_dof  # (an order above it is refused where every method is called: _registry.check_reachable)
    # beyond the order: a pair cut at the order shows, and room for the rigid-body modes where there may be some
    extra = (room_for_rigid(model, is_iterative(solver.backend)) if rigid == "exclude" else 0) + CLUSTER_MARGIN
    while True:
        k = min(n, order + extra)
        lam, phi = eigenmodes(model.K, model.M, k, sigma=sigma, solver=solver)
        is_rb = is_rigid(lam, model.K, model.M)
        n_rb = int(is_rb.sum())
        keep = ~is_rb if rigid == "exclude" else np.ones(lam.size, bool)
        whole = whole_clusters(lam[keep], order)
        if k == n or (keep.sum() > whole and (rigid == "include" or k - n_rb >= order)):
            break
        extra = n_rb + 6 + CLUSTER_MARGIN + (whole - order)
    if n_rb > MAX_RIGID_BODY_MODES:
        raise mechanism_error(model, n_rb)
    lam, phi = lam[keep][:whole], phi[:, keep][:, :whole]
    if lam.size < order:
        raise OptionError(f"only {lam.size} flexible modes exist; order {order} is too large")
    info = {"n_rigid": n_rb, "rigid": rigid, "frequencies_hz": frequencies_hz(lam).tolist()}
    if lam.size > order:
        info["order_note"] = cluster_note(order, lam.size, frequencies_hz(lam)[order - 1])
    return Basis(phi, "modal", info)


#: Eigenpairs computed beyond the order, to see whether the order cuts a multiple eigenvalue.
CLUSTER_MARGIN = 3


def room_for_rigid(model, iterative: bool) -> int:
    """Eigenpairs modal asks beyond its order at the first try for rigid-body modes: six, except under an
    iterative backend (whose eigensolver iterates every column asked for: six of 45 at order 30) on a body whose
    geometry cannot move rigidly (:func:`flexmor.rigid.can_move_rigidly`). A rigid-body mode that is no motion of
    the whole geometry (a loose part) is found by the modes themselves, and the eigenpairs are computed again with
    room. :func:`flexmor.plan.method_stages` counts the same."""
    from ..rigid import can_move_rigidly

    return 6 if not iterative or can_move_rigidly(model) else 0


def cluster_note(order: int, got: int, f_hz: float) -> str:
    """The ``order_note`` of a basis that keeps a whole multiple eigenvalue the order would cut."""
    return (f"order {got} instead of {order}: mode {order} has {got - order} more at the same frequency "
            f"({f_hz:.6g} Hz, a multiple eigenvalue such as a symmetric section's bending pair); the whole set is "
            "kept, since a cut inside it would keep a vector chosen by round-off")
