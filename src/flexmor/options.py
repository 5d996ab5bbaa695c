"""Typed option values shared by the library and the command line: the frequency band and
the declaration of method options.

A method's options are a frozen dataclass whose fields are declared with :func:`option`
(default, one-line documentation, allowed choices, how to read the value from text); the
dataclass is attached when the method is registered
(:func:`flexmor.reduction.register_method`), and the command line builds its per-method
flags and ``--help`` groups from it.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

from .errors import OptionError

__all__ = ["Band", "DEFAULT_BAND", "option", "band_option", "option_fields", "parse_pair", "check_order",
           "check_option_types"]


def parse_pair(text, name: str) -> tuple[float, float]:
    """Parse ``A:B`` into two floats; an :class:`OptionError` naming the parameter ``name`` otherwise."""
    try:
        a, b = (float(x) for x in str(text).split(":"))
    except ValueError:
        raise OptionError(f"{name} must look like A:B with two numbers, got {text!r}", params=(name,)) from None
    return a, b


def check_order(order, name: str = "order") -> int | None:
    """``order`` as a positive ``int`` (None stays None): the reduced dimension asked for.

    An integer (also a NumPy one) or a float with an integer value is taken; a bool, a string,
    a fraction or a value below 1 is refused.

    Raises
    ------
    OptionError
        Naming the parameter ``name`` and what was given.
    """
    if order is None:
        return None
    if isinstance(order, bool | str | bytes) or not isinstance(order, numbers.Real):
        raise OptionError(f"{name} must be a positive integer, got {order!r} of type {type(order).__name__}",
                          params=(name,))
    value = float(order)
    if not (math.isfinite(value) and value.is_integer() and value >= 1):
        raise OptionError(f"{name} must be a positive integer, got {order!r}", params=(name,))
    return int(value)


class Band(tuple):
    """A frequency band ``(fmin, fmax)`` in Hz with ``0 < fmin < fmax < inf``.

    A tuple, so that ``fmin, fmax = band``, ``band[1]`` and JSON (a list of two numbers)
    work as for a plain pair.

    Parameters
    ----------
    fmin, fmax : float
        Band limits in Hz.
    """

    __slots__ = ()

    def __new__(cls, fmin, fmax):
        try:
            lo, hi = float(fmin), float(fmax)
        except (TypeError, ValueError):
            raise OptionError(f"band needs two numbers FMIN:FMAX in Hz, got {fmin!r}:{fmax!r}",
                              params=("band",)) from None
        if not (math.isfinite(lo) and math.isfinite(hi)) or not 0 < lo < hi:
            raise OptionError(f"band needs 0 < FMIN < FMAX in Hz, got {fmin}:{fmax}", params=("band",))
        return super().__new__(cls, (lo, hi))

    def __getnewargs__(self):
        return tuple(self)

    def __repr__(self) -> str:
        return f"Band({self[0]:g}, {self[1]:g})"

    @property
    def fmin(self) -> float:
        """Lower limit (Hz)."""
        return self[0]

    @property
    def fmax(self) -> float:
        """Upper limit (Hz)."""
        return self[1]

    @classmethod
    def parse(cls, text: str) -> Band:
        """The band of the text ``FMIN:FMAX`` (Hz)."""
        return cls(*parse_pair(text, "band"))

    @classmethod
    def of(cls, value) -> Band:
        """``value`` as a Band: None gives :data:`DEFAULT_BAND`, a pair or ``FMIN:FMAX`` text is checked."""
        if value is None:
            return DEFAULT_BAND
        if isinstance(value, Band):
            return value
        if isinstance(value, str):
            return cls.parse(value)
        try:
            fmin, fmax = value
        except (TypeError, ValueError):
            raise OptionError(f"band must be a pair (FMIN, FMAX) in Hz, got {value!r}", params=("band",)) from None
        return cls(fmin, fmax)


#: Band (Hz) used when none is given.
DEFAULT_BAND = Band(1.0, 1000.0)


def option(default, help: str, *, choices=None, parse=None, metavar: str | None = None):
    """A method option: a dataclass field with its default and documentation.

    Parameters
    ----------
    default
        The value the method uses when the option is not given (immutable).
    help : str
        One line of documentation (shown by ``flexmor reduce --help``).
    choices : sequence of str, optional
        The allowed values.
    parse : callable, optional
        Reads the value from command-line text; default the type of ``default`` (``str``
        when the default is None).
    metavar : str, optional
        Name of the value in ``--help``.
    """
    if parse is None:
        parse = str if default is None or choices else type(default)
    return dataclasses.field(default=default, metadata={"help": help, "choices": tuple(choices or ()),
                                                        "parse": parse, "metavar": metavar})


def band_option(what: str):
    """The ``band`` option of a method: the band (Hz) of ``what``; None is :data:`DEFAULT_BAND`."""
    return option(None, f"band in Hz of {what} (default {DEFAULT_BAND[0]:g}:{DEFAULT_BAND[1]:g})", parse=Band.parse,
                  metavar="FMIN:FMAX")


def option_fields(options_class) -> dict:
    """``name -> dataclasses.Field`` of an options dataclass, in declaration order."""
    return {f.name: f for f in dataclasses.fields(options_class)}


#: Kinds of option values checked by :func:`check_option_types` (from the field annotations):
#: kind -> (test, the words of the message)
_KINDS = {
    "bool": (lambda v: isinstance(v, bool), "True or False"),
    "int": (lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool)
            and math.isfinite(float(v)) and float(v).is_integer(), "an integer"),
    "float": (lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool), "a number"),
    "list": (lambda v: not isinstance(v, str | bytes) and hasattr(v, "__iter__"), "a list"),
}


def check_option_types(options_class, values: dict) -> None:
    """Refuse method option values of the wrong type, by the annotations of ``options_class``.

    Fields annotated with ``int``, ``float``, ``bool`` or ``list`` (each optionally ``| None``)
    are checked: a bool or a string is not a number (``moments=True``, ``max_iter="50"``), a
    string is not a list (``interface="TIP"``: give ``["TIP"]``). None values and fields of other
    types (text with choices, bands, points) are left to the method.

    Raises
    ------
    OptionError
        Naming the option, what it must be and what was given.
    """
    fields = option_fields(options_class)
    for name, value in values.items():
        f = fields.get(name)
        if f is None or value is None:
            continue
        kinds = [k.strip() for k in str(f.type).split("|") if k.strip() != "None"]
        if not kinds or not all(k in _KINDS for k in kinds):
            continue
        if not any(_KINDS[k][0](value) for k in kinds):
            want = " or ".join(_KINDS[k][1] for k in kinds)
            hint = f" (e.g. [{value!r}])" if "list" in kinds and isinstance(value, str) else ""
            raise OptionError(f"{name} must be {want}{hint}, got {value!r} of type {type(value).__name__}",
                              params=(name,))
