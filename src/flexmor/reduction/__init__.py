"""Reduction methods, one family per module, each a function returning a :class:`Basis`.

A method is registered with :func:`register_method` and called through :func:`reduce`,
which validates its options, builds the basis, and projects with the one
:func:`flexmor.projection.project`. Every method has the signature::

    method(model, ports, order, *, solver=None, **options) -> Basis
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass
from typing import Callable

from ..errors import OptionError
from ..projection import ReducedModel, project

__all__ = ["register_method", "METHODS", "methods", "reduce", "Method"]


@dataclass(frozen=True)
class Method:
    """A registered reduction method."""

    name: str
    function: Callable
    description: str
    survives_coupling: bool

    @property
    def options(self) -> list[str]:
        """Keyword options the method accepts (besides model, ports, order)."""
        sig = inspect.signature(self.function)
        return [p.name for p in sig.parameters.values() if p.kind is p.KEYWORD_ONLY]


#: name -> Method
METHODS: dict[str, Method] = {}


def register_method(name: str, description: str, *, survives_coupling: bool = True):
    """Decorator registering a basis function under ``name``."""

    def deco(fn):
        METHODS[name] = Method(name, fn, description, survives_coupling)
        return fn

    return deco


def methods() -> dict[str, Method]:
    """All registered methods (importing the built-in modules first)."""
    _load_builtin()
    return dict(METHODS)


def _load_builtin():
    from . import (  # noqa: F401  # noqa: F401
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


def reduce(model, method: str, order: int | None, ports, **options) -> tuple[ReducedModel, dict]:
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
    **options
        Method options (e.g. ``interface``, ``solver``); unknown ones raise OptionError.

    Returns
    -------
    reduced : ReducedModel
        Its ``info`` holds the method's own record plus ``order_requested`` and ``options`` (the
        options passed, as JSON values); with ``version`` the result says how it was made.
    timings : dict
        Wall times in seconds: ``basis``, ``project``.
    """
    _load_builtin()
    if method not in METHODS:
        raise OptionError(f"method={method!r} is not allowed; choose one of: {', '.join(sorted(METHODS))}")
    m = METHODS[method]
    allowed = m.options
    unknown = [k for k, v in options.items() if k not in allowed and v is not None]
    if unknown:
        raise OptionError(
            f"method {method!r} does not take option(s) {', '.join(unknown)}; it takes: {', '.join(allowed)}")
    opts = {k: v for k, v in options.items() if k in allowed and v is not None}
    if order is not None and (int(order) != order or order < 1):
        raise OptionError(f"order must be a positive integer, got {order}")
    t0 = time.perf_counter()
    basis = m.function(model, ports, order, **opts)
    t1 = time.perf_counter()
    red = project(model, basis, ports)
    t2 = time.perf_counter()
    red.info.setdefault("order_requested", order)
    red.info.setdefault("options", _recorded(opts))
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
