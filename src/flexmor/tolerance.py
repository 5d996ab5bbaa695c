"""Target-error mode: the smallest order whose *verified* error measure meets a tolerance.

Used by ``flexmor reduce --tol TOL`` (through :func:`flexmor.workflow.reduce_and_judge`).
The order is doubled until the error measure against the full model's FRF (computed once,
:class:`flexmor.analysis.compare.FullResponse`) is below ``tol``, then bisected. For methods
whose basis is nested (its leading r columns are the basis of order r: ``krylov``,
``adaptive`` (``info['nested']``) and ``modal``) every trial order below the largest
basis costs only a projection and a reduced FRF, not a new basis. The measure is
``band_error`` unless another one of :data:`flexmor.analysis.frequency.TOL_MEASURES` is
chosen. Component-mode methods (an ``interface`` option: ``craig-bampton``, ``cms-*``) search
the number of internal vectors: every trial order is the interface DOFs plus some of them.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .analysis.frequency import TOL_MEASURES
from .basis import Basis
from .errors import OptionError, check_choice
from .linalg.context import SolverContext, as_solver, step
from .linalg.eigen import whole_clusters
from .projection import project
from .reduction import reduce
from .reduction.modal import cluster_note

__all__ = ["reduce_to_tolerance", "NESTED", "leading", "min_order", "tol_methods", "check_tol_method"]

log = logging.getLogger(__name__)

#: Methods whose bases are nested without saying so in ``info['nested']``.
NESTED = {"modal"}

#: Records of a body's ``info`` that hold for its order alone: krylov's estimate of its band error
#: (``points_check``) and the candidates it was chosen from (``compressed``).
OF_THE_ORDER = ("points_check", "compressed")


def tol_methods() -> list[str]:
    """The registered methods that ``tol`` works with: those that take an order (not ``guyan``)."""
    from .reduction import methods

    return sorted(m for m in methods() if m != "guyan")


def check_tol_method(method: str) -> None:
    """An :class:`OptionError` when ``tol`` does not apply to ``method``."""
    if method not in tol_methods():
        raise OptionError(f"tol does not apply to {method} (its order is fixed by the interface); it works with: "
                          f"{', '.join(tol_methods())}", params=("tol",))


def min_order(model, method: str, ports, options: dict) -> int:
    """The smallest order ``method`` accepts plus one: for the component-mode methods one internal
    vector next to the interface (:func:`flexmor.reduction.craig_bampton.lowest_order`), else 1."""
    from .options import option_fields
    from .reduction import methods
    from .reduction.craig_bampton import lowest_order

    m = methods()[method]
    if "interface" not in m.options or not options.get("interface"):
        return 1
    fields = option_fields(m.options_class)
    rigid = options.get("rigid", fields["rigid"].default) if "rigid" in fields else "include"
    return max(lowest_order(model, method, options["interface"], rigid) + 1, 1)


def leading(big, r: int) -> tuple[int, dict]:
    """``(columns, info)`` of the body of order ``r`` that the nested basis of ``big`` holds: as many leading
    columns as the method itself returns for order ``r`` (a multiple eigenvalue that ``r`` cuts kept whole, as
    :func:`flexmor.reduction.modal.modal` and ``craig_bampton`` keep it: the basis is then the same whatever
    order ``big`` has) and ``big.info`` with the mode frequencies (``frequencies_hz`` of ``modal``,
    ``fixed_interface_hz`` and ``n_modes`` of the Craig-Bampton family) and ``order_note`` of those columns; the
    records of :data:`OF_THE_ORDER` (``big``'s estimate) are left out, ``cut_from_order`` says so; krylov's greedy
    points are those the ``r`` columns come from (:func:`flexmor.reduction.greedy_points.points_within`)."""
    info = dict(big.info)
    info.pop("order_note", None)  # big's own, of its order
    if [info.pop(k) for k in OF_THE_ORDER if k in info]:  # the estimate and compression of big's order
        info["cut_from_order"] = int(big.order)
    if info.get("nested") and not info.get("n_rigid_dropped"):  # krylov's greedy points: those of the r columns
        from .reduction.greedy_points import points_within

        info = points_within(info, r)
    key = next((k for k in ("fixed_interface_hz", "frequencies_hz") if isinstance(info.get(k), list)), None)
    if key is None:
        return r, info
    f = np.asarray(info[key], dtype=float)
    lead = big.V.shape[1] - f.size  # the columns before the modes (interface, relief)
    n = whole_clusters((2 * np.pi * f) ** 2, r - lead) if r > lead else 0
    if r > lead and lead + n > r:
        info["order_note"] = cluster_note(r, lead + n, float(f[r - lead - 1]))
    info[key] = f[:n].tolist()
    if "n_modes" in info:
        info["n_modes"] = int(n)
    return lead + n if r > lead else r, info


def reduce_to_tolerance(model, method: str, ports, *, tol: float, full, max_order: int | None = None,
                        start: int | None = None, measure: str = "band_error", solver: SolverContext | None = None,
                        **options):
    """Reduce with the smallest order (found by doubling and bisection) whose ``measure <= tol``.

    Parameters
    ----------
    model, ports
        As for :func:`flexmor.reduction.reduce`.
    method : str
        A registered method that takes an order.
    tol : float
        Target of ``measure`` (verified on ``full``).
    measure : {'band_error', 'rms_rel_error_pct', 'hinf_error', 'max_rel_error'}
        The error measure ``tol`` targets (:data:`flexmor.analysis.frequency.MEASURES`).
    full : FullResponse
        The full model's FRF over the band.
    max_order : int, optional
        Largest order tried; default ``min(n_dof, 400)``. If even it misses ``tol``, a
        warning is logged and that body is returned (``search['tol_reached']`` False).
    start : int, optional
        First order tried; default ``max(4, 2 * n_inputs)``, for the component-mode methods
        the interface DOFs plus that many internal vectors.

    Returns
    -------
    body : ReducedModel
    timings : dict
        ``basis`` (the whole search, bases and trial projections) and ``project``.
    search : dict
        ``tol``, ``measure``, ``tol_reached``, ``orders_tried``: the orders of the bodies tried with their
        value of ``measure`` (an order asked for inside a multiple eigenvalue gives the body that keeps it
        whole, :func:`leading`).
    """
    solver = as_solver(solver)
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.floating, np.integer)) or not tol > 0:
        raise OptionError(f"tol must be a positive number, got {tol!r}", params=("tol",))
    check_choice("tol_measure", measure, TOL_MEASURES)
    check_tol_method(method)
    low = min_order(model, method, ports, options)
    max_order = int(max_order or max(min(model.n_dof, 400), low))
    if max_order < low:
        raise OptionError(f"{method} needs order >= {low} (the interface DOFs plus one internal vector), got "
                          f"{max_order}", params=("order",))
    R = int(start or (low - 1 + max(4, 2 * ports.n_inputs) if low > 1 else max(4, 2 * ports.n_inputs)))
    t0 = time.perf_counter()
    # tried: the bodies by their order; asked: the order each order asked for gave (larger where it would cut
    # a multiple eigenvalue, smaller where the method found fewer directions)
    tried, asked, big, lo = {}, {}, None, low - 1

    def trial(r, body=None):
        """``(measure, body)`` of order ``r`` (``body`` given, else made), shown as one step."""
        with step(solver.progress, f"tol search: {method} order {r}") as note:
            if body is None:
                body = reduce(model, method, r, ports, solver=solver, **options)
            value = getattr(full.evaluate(body), measure)
            note["result"] = f"{measure} {value:.3g}" + (f" (order {body.order})" if body.order != r else "")
        return value, body

    def error(r):
        """``measure`` of the body asked for with order ``r``."""
        if r not in asked:
            if big is not None and (big.info.get("nested") or method in NESTED) and r <= big.order:
                cut, info = leading(big, r)
                value, body = trial(r, project(model, Basis(big.V[:, :cut], method, info), ports))
            else:
                value, body = trial(r)
            asked[r] = body.order
            tried.setdefault(body.order, (value, body))
        return tried[asked[r]][0]

    while True:
        R = min(R, max_order)
        value, big = trial(R)
        tried[big.order] = (value, big)
        if value <= tol or R >= max_order or big.order < R:
            break
        lo, R = big.order, 2 * R
    hi = min(R, big.order)
    asked[hi] = big.order
    reached = tried[big.order][0] <= tol
    if reached:
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if error(mid) <= tol:
                hi = mid
            else:
                lo = mid
    else:
        log.warning("%s: %s %.2e at order %d misses the target (tol) %.1e", method, measure, tried[big.order][0],
                    big.order, tol)
    red = tried[asked[hi]][1]
    search = {"tol": tol, "measure": measure, "tol_reached": reached,
              "orders_tried": {str(k): v[0] for k, v in sorted(tried.items())}}
    red.info["tol_search"] = search
    return red, {"basis": time.perf_counter() - t0, "project": 0.0}, search
