"""The method options of ``flexmor reduce`` as flags: their names, and the ones given for a method."""

from __future__ import annotations

from ..errors import OptionError
from ..options import option_fields

__all__ = ["COMMON", "flag", "all_options", "method_options"]

#: Method options set by a flag of their own (``--band`` is also the error band; ``--interface``
#: also makes couplings): not generated, and ``--band`` is never refused.
COMMON = ("band", "interface")


def flag(name: str) -> str:
    """The flag of the option ``name``: ``max_iter`` -> ``--max-iter``."""
    return "--" + name.replace("_", "-")


def all_options() -> dict:
    """``name -> Field`` over every registered method (the first declaration of each name)."""
    from ..reduction import methods

    out = {}
    for m in methods().values():
        for name, f in option_fields(m.options_class).items():
            out.setdefault(name, f)
    return out


def method_options(args, method: str) -> dict:
    """The method options given on the command line (not None), without ``band``.

    Raises
    ------
    OptionError
        For a flag that ``method`` does not take, naming the flags it takes.
    """
    from ..reduction import METHODS

    given = {n: getattr(args, n) for n in all_options() if getattr(args, n, None) not in (None, [])}
    given.pop("band", None)  # the workflow passes the band to the methods that take one
    taken = list(option_fields(METHODS[method].options_class))
    if "interface" not in taken and all("@" in str(s) for s in given.get("interface", [None])):
        given.pop("interface")  # couplings (joints) of the model, applied as System(interfaces=...) applies them
    bad = [n for n in given if n not in taken]
    if bad:
        joint = (" (as a node set; a coupling --interface SET@rbe2 or SET@rbe3 is a joint of the model, which "
                 "every method takes)" if "interface" in bad else "")
        raise OptionError(f"method {method!r} does not take {', '.join(flag(n) for n in bad)}{joint}; it takes: "
                          + (", ".join(flag(n) for n in taken) or "no options"))
    return given
