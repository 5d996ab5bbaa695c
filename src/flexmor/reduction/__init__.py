"""Reduction methods, one family per module, each a function returning a :class:`Basis`.

A method is registered with :func:`register_method` (:mod:`flexmor.reduction._registry`)
together with the dataclass of its options (defaults and one-line help,
:func:`flexmor.options.option`; the shared ones in :mod:`flexmor.reduction._options`).
Importing the package imports every built-in method module, so :data:`METHODS` is complete.
A method is called through :func:`reduce`, which validates its options, builds the basis,
and projects with the one :func:`flexmor.projection.project`. Every method has the signature::

    method(model, ports, order, *, <one keyword per options field>, solver=None) -> Basis

and raises :class:`~flexmor.errors.OptionError` for a keyword it does not take.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..basis import Basis
from ..body import ReducedModel
from ..errors import OptionError, PortError
from ..linalg.context import as_solver
from ..linalg.distributed import is_partitioned
from ..linalg.memory import iterative_record
from ..linalg.resources import check_basis_memory
from ..linalg.threads import blas_threads
from ..options import Band, check_option_types
from ..ports import Ports
from ..projection import project
from ..rigid import exclude_rigid, frame_participation, register_near_null
from . import (  # noqa: F401  (each method module registers its methods in METHODS)
    adaptive,
    balanced,  # sobt, fw-sobt; gramians.py holds the Gramians
    cms,
    craig_bampton,
    free_interface,  # craig-chang, herting
    guyan,
    irka,
    krylov,
    modal,
    pod,
    svdmor,
    two_step,
)
from ._registry import (
    ALIASES,
    METHODS,
    Method,
    check_keywords,
    check_reachable,
    method_name,
    methods,
    order_note,
    register_method,
)
from .free_body import with_inertia_loads

#: The keywords of :func:`reduce` beside the method's options: what the basis is built for.
BASIS_KEYWORDS = ("inertia_loads", "residual_vectors", "spin_range")

#: How far (factor) the shift of a method's first factorization may lie from
#: :func:`flexmor.linalg.eigen.default_shift` for the rigid-body check to run at it.
SHARED_SHIFT_RANGE = 1e4

__all__ = ["register_method", "METHODS", "ALIASES", "methods", "method_name", "reduce", "Method", "check_keywords",
           "check_shift", "check_reachable"]


def reduce(model, method: str, order: int | None, ports, *, inertia_loads: str = "auto",
           residual_vectors: bool = False, **options) -> ReducedModel:
    """Reduce ``model`` with the registered ``method`` and project it.

    Every argument may be given by keyword: ``reduce(model=m, method="krylov", order=8, ports=p)``.

    Parameters
    ----------
    model : FEModel
    method : str
        A name in :data:`METHODS` (``modal``, ``guyan``, ``craig-bampton`` ...), in any case, or a
        short name of :data:`ALIASES` (:func:`method_name`).
    order : int or None
        Reduced dimension r (for ``guyan`` the interface size; may be None). An order above the
        model's number of DOF is refused; one the method cannot reach gives the reachable order
        with the reason in ``order_note`` (the order rule of :mod:`flexmor.reduction._registry`).
    ports : Ports
        Inputs and outputs of the reduced body.
    inertia_loads : {'auto', 'on', 'off'}
        Add the frame's inertia loads (six unit accelerations, gravity among them) to the inputs
        the basis is built for (:func:`flexmor.reduction.free_body.with_inertia_loads`; ``auto``, the
        default, and ``on``): ``M R`` on a supported body (gravity and the support's motion load it in
        directions its ports may not see), and on a free body with interface masters the same
        accelerations of the body held at each master, so that the mounted body sags like the full
        model. They share the order with the ports (``off``: the ports only). The reduced body keeps
        ``ports``. No effect on
        methods whose basis does not use the inputs (modal, guyan, craig-bampton).
    residual_vectors : bool
        Append the static responses to the inputs, the frame's accelerations and the coupling masters'
        unit loads (:mod:`flexmor.reduction.residual`), counted in ``order``: the method builds
        ``order - p`` vectors (``p`` the rank of those responses; built once more with a larger share
        where its basis holds some of them already). ``info["residual_vectors"]`` counts the vectors added.
    **options
        Method options (the fields of the method's ``options_class``, e.g. ``interface``) and
        ``solver``; any other keyword raises OptionError listing the allowed ones. Options
        not given take their defaults; a method with a ``band`` option not given one builds for
        :data:`flexmor.options.DEFAULT_BAND`.
        A basis that excludes rigid-body modes (``info['rigid'] == 'exclude'``) is made
        mass-orthogonal to them (:func:`flexmor.rigid.exclude_rigid`).

    Returns
    -------
    ReducedModel
        Its ``info`` holds the method's own record plus ``order_requested``, ``options`` (the
        options passed, as JSON values), ``band`` (``[fmin, fmax]`` in Hz the basis was built for,
        given or the default; None for a method without a band) and ``timings`` (wall times in
        seconds: ``basis``, ``project``); with ``version`` the result says how it was made. When
        the order differs from the one asked, ``order_note`` says what was returned and
        why (the method's own reason where it gives one).
    """
    method = method_name(method)
    m = METHODS[method]
    if not isinstance(ports, Ports):
        raise PortError(f"ports must be a Ports (flexmor.make_ports(model, inputs, outputs), e.g. inputs "
                        f"['TIP:y']), got {type(ports).__name__}", params=("ports",))
    check_keywords(method, options, [*m.keywords, *BASIS_KEYWORDS])
    spin = options.pop("spin_range", None)
    if spin is not None and residual_vectors:
        raise OptionError("spin_range builds one basis over the speeds; residual_vectors are not added to it",
                          params=("spin_range", "residual_vectors"))
    opts = {k: v for k, v in options.items() if v is not None}
    check_option_types(m.options_class, opts)
    order = check_reachable(model, order)  # the order rule: see flexmor.reduction._registry
    if order is not None and not is_partitioned(model.K):  # a basis that cannot fit: refused before any work
        check_basis_memory(model.n_dof, order, as_solver(options.get("solver")))
    solver = options.get("solver")
    if solver is not None:  # the geometry's rigid motions, should the amg backend solve (flexmor.linalg.amg)
        register_near_null(solver, model)
        its0 = (solver.stats.iterative, solver.stats.iterations, solver.stats.eigen_iterations)
    t0 = time.perf_counter()
    with blas_threads(1):  # tall-skinny and small dense products (see flexmor.linalg.threads)
        basis_ports, inertia = with_inertia_loads(model, ports, inertia_loads if m.uses_inputs else "off")
        if residual_vectors:
            from .residual import residual_order, static_responses, with_residual_vectors

            X, p = static_responses(model, ports, solver=options.get("solver"))
            basis = exclude_rigid(model, m.function(model, basis_ports, residual_order(order, p, method), **opts))
            basis = with_residual_vectors(model, basis, X)
            added = basis.info["residual_vectors"]
            if order is not None and added < p and basis.order < order:  # the method's basis held some of them:
                # it gets their share of the order back (fewer may be new then, never more: order is not exceeded)
                basis = exclude_rigid(model, m.function(model, basis_ports, residual_order(order, added, method),
                                                        **opts))
                basis = with_residual_vectors(model, basis, X)
        elif spin is not None:
            basis, spin_ops, spin_range = _over_speeds(model, m, basis_ports, order, opts, spin)
        else:
            basis = exclude_rigid(model, m.function(model, basis_ports, order, **opts))
        t1 = time.perf_counter()
        red = project(model, basis, ports)
        t2 = time.perf_counter()
    red.info.update(inertia)
    if solver is not None and (solver.stats.iterations, solver.stats.eigen_iterations) > its0[1:]:
        red.info["iterative_solves"] = iterative_record(solver.stats, since=its0)
    if spin is not None:
        red.info["spin"] = _spin_record(model, red, spin_ops, spin_range, opts.get("solver"))
    if not m.uses_inputs:  # the basis ignores the inputs: no inertia loads could be asked for
        red.info["inertia_loads"] = None
    red.info.setdefault("order_requested", order)
    red.info.setdefault("options", _recorded(opts))
    red.info["band"] = list(Band.of(opts.get("band"))) if "band" in m.options else None
    if model.n_nodes and model.dofs is not None and not is_partitioned(model.M):  # effective masses (mode table)
        P, mass = frame_participation(model, red.V)
        red.info["frame_participation"], red.info["frame_mass"] = P.tolist(), mass.tolist()
    if spin is not None and red.order != order:
        b = basis.info
        red.order_note = (f"order {red.order}: the union of the {method} bases of orders "
                          f"{', '.join(map(str, b['spin_build_orders']))} at "
                          f"{', '.join(f'{w:g}' for w in b['spin_build_speeds'])} rad/s (--spin-range; --order is "
                          "the order at each speed)")
    if residual_vectors and order is not None and red.order < order:
        red.order_note = (f"{method} built {red.order - red.info['residual_vectors']} vectors and "
                          f"{red.info['residual_vectors']} residual vectors were added: order {red.order} instead of "
                          f"{order}, the basis held {order - red.order} of the static responses already")
    if order is not None and red.order != order and not red.order_note:
        red.order_note = order_note(method, red.order, order)
    red.info["timings"] = {"basis": t1 - t0, "project": t2 - t1}
    return red


def _over_speeds(model, m, ports, order, opts, spec):
    """One basis for a speed range (:mod:`flexmor.spin`): the method's basis on the spinning model at each of
    :data:`~flexmor.spin.BUILD_SPEEDS` speeds, and their union (:func:`~flexmor.spin.merged_basis`). The range is
    checked at its top speed first: the lowest eigenvalue of ``K + w^2 K2`` is concave in ``w^2``, so positive
    at 0 and at the top speed it is positive at every speed between."""
    import dataclasses

    from ..spin import BUILD_SPEEDS, check_stable, merged_basis, parse_spin_range, spin_operators

    sr = parse_spin_range(spec)
    ops = spin_operators(model, sr.axis, solver=opts.get("solver"))
    check_stable(model, ops, sr.w1, solver=opts.get("solver"))  # before any build
    bases = [m.function(dataclasses.replace(model, K=ops.stiffness(model.K, w)), ports, order, **opts)
             for w in sr.speeds(BUILD_SPEEDS)]
    V = merged_basis(model, [b.V for b in bases])
    info = dict(bases[0].info)
    info["spin_build_speeds"] = sr.speeds(BUILD_SPEEDS).tolist()
    info["spin_build_orders"] = [b.order for b in bases]
    return Basis(V, bases[0].method, info), ops, sr


def _spin_record(model, red, ops, sr, solver) -> dict:
    """The body's spin record: the range, ``K2`` and ``G1`` and the check against the full model at
    :data:`~flexmor.spin.CHECK_SPEEDS` speeds."""
    from ..spin import CHECK_SPEEDS, reduced_spin, spin_check

    rec = {**sr.record(), **reduced_spin(model, np.asarray(red.V), ops)}
    modes = max(1, min(6, red.order // 2))
    rec["check"] = spin_check(model, red.M, red.K, np.asarray(rec["K2"]), ops, sr.speeds(CHECK_SPEEDS), modes,
                              solver=solver)
    return rec


def _recorded(opts: dict) -> dict:
    """The method options as JSON values (stored with the reduced body, with its version)."""
    import json

    from ..jsonutil import jsonable

    out = {}
    for k, v in sorted(opts.items()):
        if k == "solver":  # the body records the backend asked for, not the solver's caches
            k, v = "backend", v.backend
        try:
            out[k] = json.loads(json.dumps(jsonable(v)))
        except (TypeError, ValueError):
            out[k] = repr(v)
    return out


def check_shift(model, method: str, options: dict) -> tuple[float | None, bool]:
    """``(sigma, keep)`` for :func:`flexmor.checks.check_rigid_body_modes` before ``method`` reduces
    ``model`` with ``options``: the shift of the method's first factorization where it is ``K - sigma M``
    (``modal`` at its ``sigma``, ``krylov`` at a first point given real and positive, ``sigma = -(2 pi p)^2``),
    kept for the method, so that check and method share one factorization; else ``(None, False)``: the
    default shift, not kept. A point further than :data:`SHARED_SHIFT_RANGE` from the default shift is not
    shared (the check's Lanczos would converge slowly there)."""
    from ..linalg.eigen import DENSE_LIMIT, default_shift

    if model.n_dof <= DENSE_LIMIT or is_partitioned(model.K):
        return None, False
    if method == "modal":
        sigma = options.get("sigma")
        return (default_shift(model.K, model.M) if sigma is None else float(sigma)), True
    if method == "krylov" and options.get("points") is not None and model.D is None:  # its first point, real
        from .krylov import parse_points

        p = complex(parse_points(options["points"])[0])
        ref = abs(default_shift(model.K, model.M))
        sigma = -(2 * math.pi * p.real) ** 2
        if p.imag == 0 and p.real > 0 and ref / SHARED_SHIFT_RANGE <= -sigma <= ref * SHARED_SHIFT_RANGE:
            return sigma, True
    return None, False
