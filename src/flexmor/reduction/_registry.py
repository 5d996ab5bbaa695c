"""The registry of reduction methods: :class:`Method`, :data:`METHODS` and :func:`register_method`.

Each method module registers its function here when it is imported; :mod:`flexmor.reduction`
imports every built-in method module, so :data:`METHODS` is complete once the package is
imported. The method modules import this module, never the package, so the package can import
them without a cycle.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import OptionError, did_you_mean
from ..options import option_fields

__all__ = ["Method", "METHODS", "ALIASES", "register_method", "check_keywords", "methods", "method_name"]


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
