"""Greedy (adaptive) choice of expansion points, stopped by an estimate: no mode or point selection by hand.

The points are those of Krylov's default (:func:`flexmor.reduction.greedy_points.greedy_basis`): the
static point, then repeatedly the point on the frequency axis where the residual of the full equations
left by the body, ``||F - A(w) V x(w)||_F / ||F||_F``, is largest on a candidate grid over the band
(:class:`~flexmor.reduction.greedy_points.ResidualIndicator`); here with ``moments`` moments per point
(default one), and with a stop on the estimated band error: after each point, the band error of the body
before it against the body with it, on the judge's grid and rule
(:func:`~flexmor.reduction.greedy_points.nested_difference`). Each point lies where the residual of the body
before it is largest, and the body with it interpolates the full model there, so the estimate sees the
error where the body is worst (the difference of two bodies with points chosen otherwise went to 2.7-7 Hz
on a 48-state building model while its dominant modes at 0.8-2.1 Hz were missing, and stopped at an
estimate of 2.6e-4 where the band_error was 0.28). The body with the latest point is returned: its error is
below the estimate wherever the point's solve was the largest missing piece. Each new point costs one
factorization and ``moments`` block solves (:func:`flexmor.reduction.krylov.blocks_at_points`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from ..basis import Basis
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..options import Band, band_option, option
from ._options import RIGID, SIDES, rigid_option, side_option
from ._registry import register_method
from .free_body import rigid_head
from .greedy_points import greedy_basis
from .krylov import start_block

__all__ = ["adaptive", "AdaptiveOptions"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class AdaptiveOptions:
    """Options of :func:`adaptive`."""

    band: Band | None = band_option("the candidate points")
    estimate_tol: float | None = option(None, "stop when the estimated band error (the body before the latest point "
                                        "against the body with it, on the judge's grid) falls below this; the body "
                                        "with the latest point is returned", parse=float)
    moments: int = option(1, "moments (blocks) per expansion point")
    side: str = side_option()
    n_candidates: int = option(400, "log-spaced candidate frequencies in the band")
    max_points: int = option(60, "upper limit of expansion points")
    rigid: str = rigid_option()


@register_method("adaptive", "greedy expansion points in the band from a cheap error estimate", options=AdaptiveOptions)
def adaptive(model, ports, order, *, band=None, estimate_tol: float | None = None, moments: int = 1,
             side: str = "input", n_candidates: int = 400, max_points: int = 60, rigid: str = "exclude",
             solver: SolverContext | None = None) -> Basis:
    """Krylov basis with greedily chosen expansion points in the band.

    Parameters
    ----------
    model : FEModel
    ports : Ports
    order : int or None
        Reduced dimension r (the basis is truncated to r columns). None: stop on ``estimate_tol``.
    band : Band or (float, float), optional
        Band (Hz) of the candidate points; default :data:`flexmor.options.DEFAULT_BAND`.
    estimate_tol : float, optional
        Stop when the estimated band error (the ``band_error`` of the body before the latest
        point against the body with it, :func:`flexmor.reduction.greedy_points.nested_difference`)
        falls below ``estimate_tol``; the body with the latest point is returned. Needs ``order``
        or ``estimate_tol``. The estimate is calibrated by the latest point's solve, not a bound;
        the target-error mode (``tol`` of :func:`flexmor.workflow.reduce_and_judge`,
        ``flexmor reduce --tol``) verifies against the full model.
    moments : int
        Moments (blocks) per point.
    side : {'input', 'output', 'both'}
        Krylov spaces of ``B``, ``C^T`` or both.
    n_candidates : int
        Log-spaced candidate frequencies in the band.
    max_points : int
        Upper limit of expansion points.
    rigid : {'exclude', 'include'}
        Free bodies, as in :func:`flexmor.reduction.krylov.krylov`: ``exclude`` (default)
        leaves them to the floating frame, ``include`` puts the rigid-body modes the ports
        excite first; the Krylov vectors are M-orthogonal to all rigid-body modes either way.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` (one factorization per point).

    Returns
    -------
    Basis
        ``info``: ``points_hz`` in the order chosen, ``estimates`` (with ``estimate_tol``: the
        estimated band error after each point from the second on), ``nested``.

    References
    ----------
    Grimme, E. J. (1997). Krylov projection methods for model reduction. PhD thesis,
    University of Illinois (rational Krylov with several points).

    Feng, L., Korvink, J. G., Benner, P. (2015). A fully adaptive scheme for model order
    reduction based on moment matching. IEEE Trans. Compon. Packag. Manuf. Technol. 5(12),
    1872-1884.

    Bonin, T., Fassbender, H., Soppa, A., Zaeh, M. (2016). A fully adaptive rational global
    Arnoldi method for the model-order reduction of second-order MIMO systems with
    proportional damping. Math. Comput. Simul. 122, 1-19.
    """
    solver = as_solver(solver)
    check_choice("side", side, SIDES)
    check_choice("rigid", rigid, RIGID)
    if order is None and estimate_tol is None:
        raise OptionError("adaptive needs order or estimate_tol", params=("order", "estimate_tol"))
    if estimate_tol is not None and not estimate_tol > 0:
        raise OptionError(f"estimate_tol must be positive, got {estimate_tol}", params=("estimate_tol",))
    for name, v in (("moments", moments), ("n_candidates", n_candidates), ("max_points", max_points)):
        if int(v) != v or v < 1:
            raise OptionError(f"{name} must be a positive integer, got {v}", params=(name,))
    phi, head = rigid_head(model, start_block(ports, side), rigid)
    V, info, reduced = greedy_basis(model, ports, order, Band.of(band), side=side, solver=solver, phi=phi, head=head,
                           moments=int(moments), estimate=False, tol=estimate_tol, max_points=int(max_points),
                           label="adaptive", n_candidates=int(n_candidates))
    n_rb = int(phi.shape[1]) if rigid == "exclude" else 0
    info.update(moments=int(moments), side=side, rigid=rigid, n_rigid=int(phi.shape[1]), n_rigid_excluded=n_rb,
                n_rigid_included=int(head.shape[1]), nested=True)
    info.pop("rho_max", None)
    return Basis(V, "adaptive", info, reduced=reduced)
