"""Printed output against the text a document quotes: the text between the numbers exactly, the
numbers by what decides them.

How printed numbers are compared (text between the numbers must match exactly). The rules go by
size: every number the README and the tutorial print below 1e-8 is a dimensionless error (they print physical
quantities in units that keep them larger, e.g. an FRF in nm/N).

* integers (DOF and node counts, orders, node ids, sizes) exactly;
* numbers below 1e-9 (``FLOOR``) match any number below 1e-9: they are round-off, not truncation.
  The relative frequency error of an exact reduction (a Craig-Bampton body clamped at its own
  interface) is double-precision round-off (2.2e-16) magnified by the conditioning of the
  eigenproblems and left by the eigensolvers' stopping tolerance; on one machine it printed
  6.1e-12 with two BLAS threads and 4.9e-11 with one. Such a number says "exact", and a
  regression makes it 1e-6 or more;
* numbers between 1e-9 and 1e-8 within a factor of 3 (``|log10(got / expected)| <= 0.5``, same
  sign): errors this small are still partly round-off;
* every other number to ``1e-6`` relative or one unit in its last printed digit, whichever is
  larger. Frequencies (Hz) of a symmetric eigenproblem of this size are reproducible to far better
  than 1e-6; error measures above 1e-8 are truncation errors of the bases, set by the method and
  not by round-off, and agree to every printed digit across machines (for bases that keep pairs
  of equal eigenfrequencies whole: the documents' orders do, and say why). One unit in the last digit
  lets a value that sits on a rounding boundary round either way: a drift of two units or more in
  any printed error measure fails the test.
"""

from __future__ import annotations

import math
import re

NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
FLOOR = 1e-9
TINY = 1e-8
REL = 1e-6


def lines(text: str) -> str:
    return "\n".join(line.rstrip() for line in text.strip("\n").splitlines())


def _is_int(s: str) -> bool:
    return re.fullmatch(r"[-+]?\d+", s) is not None


def _last_digit(s: str) -> float:
    """The value of one unit in the last printed digit of the number ``s``."""
    mantissa, _, exponent = s.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exponent or 0) - decimals)


def number_differs(expected: str, got: str) -> str | None:
    """Why the printed number ``got`` is not ``expected`` (rules in the module docstring), or None."""
    if expected == got:
        return None
    if _is_int(expected) or _is_int(got):
        return "integers differ"
    e, g = float(expected), float(got)
    if abs(e) < FLOOR:
        return None if abs(g) < FLOOR else f"round-off-level number (below {FLOOR:g}) is now {got}"
    if abs(e) < TINY:
        if e == g or (e * g > 0 and abs(math.log10(g / e)) <= 0.5):
            return None
        return "round-off-level number off by more than a factor of 3 (tolerance: |log10 ratio| <= 0.5)"
    tol = max(REL * abs(e), _last_digit(expected) * (1 + 1e-9))
    if abs(g - e) <= tol:
        return None
    return f"differs by {abs(g - e):.3g} (> {tol:.3g}: {REL:g} relative or one unit in the last digit)"


def output_differs(expected: str, got: str) -> str | None:
    """Why the printed text ``got`` is not ``expected``: the text between numbers exactly, the numbers
    by :func:`number_differs`; None when they agree."""
    expected, got = lines(expected), lines(got)
    e_text, g_text = NUMBER.split(expected), NUMBER.split(got)
    if e_text != g_text:
        for line_e, line_g in zip(expected.splitlines() + [""] * 99, got.splitlines() + [""] * 99):
            if NUMBER.split(line_e) != NUMBER.split(line_g):
                return f"text differs:\n  expected: {line_e!r}\n  got:      {line_g!r}"
        return "text differs"
    for e, g in zip(NUMBER.findall(expected), NUMBER.findall(got)):
        why = number_differs(e, g)
        if why:
            line = next(line for line in got.splitlines() if g in line)
            return f"the document says {e}, the run printed {g}: {why}\n  in: {line!r}"
    return None
