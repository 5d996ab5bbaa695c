"""Reduction methods, one family per module, each a function returning a :class:`Basis`.

A method is registered with :func:`register_method` together with the dataclass of its
options (defaults and documentation, :func:`flexmor.options.option`), and called through
:func:`reduce`, which validates its options, builds the basis, and projects with the one
:func:`flexmor.projection.project`. Every method has the signature::

    method(model, ports, order, *, <one keyword per options field>, solver=None) -> Basis

and raises :class:`~flexmor.errors.OptionError` for a keyword it does not take.
"""

from __future__ import annotations

import functools
import inspect
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..body import ReducedModel
from ..errors import OptionError
from ..options import check_option_types, check_order, option_fields
from ..projection import project
from .free_body import exclude_rigid, with_inertia_loads

__all__ = ["register_method", "METHODS", "methods", "reduce", "Method", "check_keywords"]


@dataclass(frozen=True)
class Method:
    """A registered reduction method.

    Attributes
    ----------
    name, description : str
    function : callable
        ``function(model, ports, order, **options) -> Basis``.
    survives_coupling : bool
        Whether the method's guarantee (moment matching) holds for an assembly of bodies.
    options_class : type
        The dataclass of the method's options (:func:`flexmor.options.option` fields).
    uses_inputs : bool
        Whether the basis depends on the inputs (and outputs); False for modal, guyan and
        craig-bampton, whose bases inertia-load inputs cannot change.
    """

    name: str
    function: Callable
    description: str
    survives_coupling: bool
    options_class: type
    uses_inputs: bool = True

    @property
    def options(self) -> list[str]:
        """Names of the method options (the fields of ``options_class``)."""
        return list(option_fields(self.options_class))

    @property
    def keywords(self) -> list[str]:
        """Keyword options the function accepts: the method options and the solver one."""
        sig = inspect.signature(self.function)
        return [p.name for p in sig.parameters.values() if p.kind is p.KEYWORD_ONLY]


#: name -> Method
METHODS: dict[str, Method] = {}


def check_keywords(method: str, given, allowed) -> None:
    """An :class:`OptionError` naming the keywords of ``given`` that are not in ``allowed`` (all listed)."""
    unknown = [k for k in given if k not in allowed]
    if unknown:
        raise OptionError(f"method {method!r} does not take option(s) {', '.join(unknown)}; "
                          f"it takes: {', '.join(allowed)}", params=tuple(unknown) + tuple(allowed))


def register_method(name: str, description: str, *, options: type, survives_coupling: bool = True,
                    uses_inputs: bool = True):
    """Decorator registering a basis function under ``name`` with its options dataclass ``options``.

    The function returned raises :class:`OptionError` (not ``TypeError``) for keywords the
    method does not take, listing those it takes.
    """

    def deco(fn):
        allowed = [p.name for p in inspect.signature(fn).parameters.values() if p.kind is p.KEYWORD_ONLY]

        @functools.wraps(fn)
        def method(model, ports, order=None, **kwargs):
            check_keywords(name, kwargs, allowed)
            return fn(model, ports, order, **kwargs)

        METHODS[name] = Method(name, method, description, survives_coupling, options, uses_inputs)
        return method

    return deco


def methods() -> dict[str, Method]:
    """All registered methods (importing the built-in modules first)."""
    _load_builtin()
    return dict(METHODS)


def _load_builtin():
    from . import (  # noqa: F401
        adaptive,
        balanced,  # noqa: F401  (sobt, fw-sobt; gramians.py holds the Gramians)
        cms,
        craig_bampton,
        guyan,
        irka,
        krylov,
        modal,
        pod,
        svdmor,
        two_step,
    )


def reduce(model, method: str, order: int | None, ports, *, inertia_loads: str = "auto",
           **options) -> tuple[ReducedModel, dict]:
    """Reduce ``model`` with the registered ``method`` and project it.

    Parameters
    ----------
    model : FEModel
    method : str
        A name in :data:`METHODS` (``modal``, ``guyan``, ``craig-bampton`` ...).
    order : int or None
        Reduced dimension r (for ``guyan`` the interface size; may be None).
    ports : Ports
        Inputs and outputs of the reduced body.
    inertia_loads : {'auto', 'on', 'off'}
        Add the frame's inertia loads (six unit accelerations, gravity among them) to the inputs
        the basis is built for (:func:`flexmor.reduction.free_body.with_inertia_loads`): ``M R``
        on a supported body (``on``), and on a free body with interface masters (``on`` and the
        default ``auto``) the same accelerations of the body held at each master, so that the
        mounted body sags like the full model. The reduced body keeps ``ports``. No effect on
        methods whose basis does not use the inputs (modal, guyan, craig-bampton).
    **options
        Method options (the fields of the method's ``options_class``, e.g. ``interface``) and
        ``solver``; any other keyword raises OptionError listing the allowed ones. Options
        not given take their defaults.
        A basis that excludes rigid-body modes (``info['rigid'] == 'exclude'``) is made
        mass-orthogonal to them (:func:`flexmor.reduction.free_body.exclude_rigid`).

    Returns
    -------
    reduced : ReducedModel
        Its ``info`` holds the method's own record plus ``order_requested`` and ``options`` (the
        options passed, as JSON values); with ``version`` the result says how it was made. When
        the order differs from the one asked, ``order_note`` says what was returned and
        why (the method's own reason where it gives one).
    timings : dict
        Wall times in seconds: ``basis``, ``project``.
    """
    _load_builtin()
    if method not in METHODS:
        raise OptionError(f"method={method!r} is not allowed; choose one of: {', '.join(sorted(METHODS))}",
                          params=("method",))
    m = METHODS[method]
    check_keywords(method, options, m.keywords)
    opts = {k: v for k, v in options.items() if v is not None}
    check_option_types(m.options_class, opts)
    order = check_order(order)
    t0 = time.perf_counter()
    basis_ports, inertia = with_inertia_loads(model, ports, inertia_loads if m.uses_inputs else "off")
    basis = exclude_rigid(model, m.function(model, basis_ports, order, **opts))
    t1 = time.perf_counter()
    red = project(model, basis, ports)
    t2 = time.perf_counter()
    red.info.update(inertia)
    red.info.setdefault("order_requested", order)
    red.info.setdefault("options", _recorded(opts))
    if order is not None and red.order != order and not red.order_note:
        red.order_note = f"order {red.order} instead of {order}: {method} returned a basis of that size"
    return red, {"basis": t1 - t0, "project": t2 - t1}


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
