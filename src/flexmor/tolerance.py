"""Target-error mode: the smallest order whose *verified* band_error meets a tolerance.

Used by ``flexmor reduce --tol TOL`` (through :func:`flexmor.workflow.reduce_and_judge`).
The order is doubled until the band_error against the full model's FRF (computed once,
:class:`flexmor.analysis.compare.FullResponse`) is below ``tol``, then bisected. For methods
whose basis is nested (its leading r columns are the basis of order r: ``krylov``,
``adaptive`` (``info['nested']``) and ``modal``) every trial order below the largest
basis costs only a projection and a reduced FRF, not a new basis.
"""

from __future__ import annotations

import logging
import time

from .basis import Basis
from .errors import OptionError
from .linalg.context import SolverContext, as_solver
from .projection import project
from .reduction import reduce

__all__ = ["reduce_to_tolerance", "NESTED"]

log = logging.getLogger(__name__)

#: Methods whose bases are nested without saying so in ``info['nested']``.
NESTED = {"modal"}


def reduce_to_tolerance(model, method: str, ports, *, tol: float, full, max_order: int | None = None,
                        start: int | None = None, solver: SolverContext | None = None, **options):
    """Reduce with the smallest order (found by doubling and bisection) with ``band_error <= tol``.

    Parameters
    ----------
    model, ports
        As for :func:`flexmor.reduction.reduce`.
    method : str
        A registered method that takes an order.
    tol : float
        Target band_error (verified on ``full``).
    full : FullResponse
        The full model's FRF over the band.
    max_order : int, optional
        Largest order tried; default ``min(n_dof, 400)``. If even it misses ``tol``, a
        warning is logged and that body is returned (``search['tol_reached']`` False).
    start : int, optional
        First order tried; default ``max(4, 2 * n_inputs)``.

    Returns
    -------
    reduced : ReducedModel
    timings : dict
        ``basis`` (the whole search, bases and trial projections) and ``project``.
    search : dict
        ``tol``, ``tol_reached``, ``orders_tried`` with their band_error.
    """
    solver = as_solver(solver)
    if tol is None or not tol > 0:
        raise OptionError(f"tol must be a positive number, got {tol}", params=("tol",))
    max_order = int(max_order or min(model.n_dof, 400))
    R = int(start or max(4, 2 * ports.n_inputs))
    t0 = time.perf_counter()
    tried, big, lo = {}, None, 0

    def error(r):
        if r not in tried:
            if big is not None and (big.info.get("nested") or method in NESTED) and r <= big.order:
                red = project(model, Basis(big.V[:, :r], method, dict(big.info)), ports)
            else:
                red = reduce(model, method, r, ports, solver=solver, **options)[0]
            tried[r] = (full.evaluate(red)["band_error"], red)
        return tried[r][0]

    while True:
        R = min(R, max_order)
        big = reduce(model, method, R, ports, solver=solver, **options)[0]
        tried[big.order] = (full.evaluate(big)["band_error"], big)
        if tried[big.order][0] <= tol or R >= max_order or big.order < R:
            break
        lo, R = big.order, 2 * R
    hi = big.order
    reached = tried[hi][0] <= tol
    if reached:
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if error(mid) <= tol:
                hi = mid
            else:
                lo = mid
    else:
        log.warning("%s: band_error %.2e at order %d misses the target (tol) %.1e", method, tried[hi][0], hi, tol)
    red = tried[hi][1]
    search = {"tol": tol, "tol_reached": reached,
              "orders_tried": {str(k): v[0] for k, v in sorted(tried.items())}}
    red.info["tol_search"] = search
    return red, {"basis": time.perf_counter() - t0, "project": 0.0}, search
