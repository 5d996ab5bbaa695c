"""The registry of reduction methods: :class:`Method`, :data:`METHODS` and :func:`register_method`.

Each method module registers its function here when it is imported; :mod:`flexmor.reduction`
imports every built-in method module, so :data:`METHODS` is complete once the package is
imported. The method modules import this module, never the package, so the package can import
them without a cycle.

Method names resolve in one place, :func:`method_name`: any case, and the short names of
:data:`ALIASES` (``bt`` is ``sobt``, ``cb`` is ``craig-bampton`` ...), give the one registered
name that every later step (the study's band, interfaces, records) uses.

An order a method cannot reach is treated by one rule, applied by every registered method (the
function :func:`register_method` returns) and by :func:`flexmor.reduction.reduce`:

* an order above the model's number of DOF is refused before any work (:class:`OptionError`
  naming ``order``): no basis has more independent columns than the model has equations;
* an order up to the number of DOF that the method cannot reach (fewer independent directions
  than asked: snapshots, Hankel singular values above round-off, internal vectors, tangential
  directions) gives the body of the reachable order, never an error; its ``order_note`` says
  ``order r instead of R:`` and the reason (:data:`UNREACHED_NOTE` where the method gives none);
* an order that contradicts the method's own definition is an option error naming ``order`` and
  the option concerned: guyan's order is the number of interface DOFs, craig-bampton and the
  cms methods need at least the interface DOFs, two-step at most its ``intermediate`` order.

A multiple eigenvalue cut by the order is kept whole (modal, craig-bampton): one more column
than asked, with the reason in ``order_note``.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import OptionError, did_you_mean
from ..errors import check_keywords as check_names
from ..options import check_order, option_fields

__all__ = ["Method", "METHODS", "ALIASES", "UNREACHED_NOTE", "register_method", "check_keywords", "methods",
           "method_name", "check_reachable", "order_note"]


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
    """An :class:`OptionError` naming the keywords of ``given`` that are not in ``allowed``, each with the
    closest allowed name (:func:`flexmor.options.check_keywords`), all allowed ones listed."""
    check_names(f"method {method!r}", given, allowed, what="option(s) ")


def register_method(name: str, description: str, *, options: type, survives_coupling: bool = True,
                    uses_inputs: bool = True):
    """Decorator registering a basis function under ``name`` with its options dataclass ``options``.

    The function returned raises :class:`OptionError` (not ``TypeError``) for keywords the
    method does not take, listing those it takes, and refuses an order above the model's number
    of DOF (:func:`check_reachable`: the order rule of this module).
    """

    def deco(fn):
        allowed = [p.name for p in inspect.signature(fn).parameters.values() if p.kind is p.KEYWORD_ONLY]

        @functools.wraps(fn)
        def method(model, ports, order=None, **kwargs):
            check_keywords(name, kwargs, allowed)
            return fn(model, ports, check_reachable(model, order), **kwargs)

        METHODS[name] = Method(name, method, description, survives_coupling, options, uses_inputs)
        return method

    return deco


def check_reachable(model, order):
    """``order`` (:func:`flexmor.options.check_order`), refused when above the number of DOF of ``model``.

    Raises
    ------
    OptionError
        Naming ``order``: not a positive integer, or more than the model's DOF.
    """
    order = check_order(order)
    if order is not None and order > model.n_dof:
        raise OptionError(f"order {order} exceeds the number of DOF {model.n_dof} of the model: no basis has more "
                          "independent columns than the model has equations", params=("order",))
    return order


#: The reason recorded when a method returns fewer columns than asked and says nothing itself.
UNREACHED_NOTE = "{method} found only {order} independent directions for it"


def order_note(method: str, order: int, requested: int, reason: str | None = None) -> str:
    """The ``order_note`` of a body of ``order`` columns asked for ``requested``: ``order r instead of R:``
    and ``reason`` (:data:`UNREACHED_NOTE` when None)."""
    why = reason or UNREACHED_NOTE.format(method=method, order=order)
    return f"order {order} instead of {requested}: {why}"


def methods() -> dict[str, Method]:
    """All registered methods, by name (a copy of :data:`METHODS`)."""
    return dict(METHODS)


#: Short names in common use, each for one registered method.
ALIASES = {"cb": "craig-bampton", "bt": "sobt", "fw": "fw-sobt", "fwbt": "fw-sobt", "cms": "cms-krylov"}


def method_name(name) -> str:
    """The registered name of method ``name`` (case-insensitive; an alias of :data:`ALIASES` allowed).

    Raises
    ------
    OptionError
        Naming ``method``: an unknown name, with the closest registered name ("did you mean")
        and the list of them.
    """
    text = str(name).strip().lower()
    text = ALIASES.get(text, text)
    if text in METHODS:
        return text
    hint = did_you_mean(text, [*METHODS, *ALIASES], aliases=ALIASES)
    raise OptionError(f"method={name!r} is unknown; {hint}choose one of: {', '.join(sorted(METHODS))} "
                      f"(short names: {', '.join(f'{a}={m}' for a, m in ALIASES.items())})", params=("method",))
