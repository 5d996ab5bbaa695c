"""The method options that several reduction methods share, declared once.

Each function returns a dataclass field (:func:`flexmor.options.option`) with the option's
default, its one-line help and its choices; a method's options dataclass uses them for the
options it shares with other methods (``rigid``, ``side``, ``points``, ``interface`` and the
Gramian quadrature's ``variant``, ``solves``, ``nodes``). The choices are the tuples below,
also used by the methods to check a value given directly.
"""

from __future__ import annotations

from ..options import option

__all__ = ["SIDES", "RIGID", "VARIANTS", "SOLVES", "points_option", "side_option", "rigid_option",
           "interface_option", "variant_option", "solves_option", "nodes_option", "NOTE_PARAMS"]

#: Method options the notes of the methods name (``order_note``, ``convergence_note``): a caller
#: with other names for them (the command line's flags) renames these words.
NOTE_PARAMS = ("cutoff", "solves", "max_iter", "shift_tol")

#: Choices of the ``side`` option: the space of the inputs, of the outputs or of both.
SIDES = ("input", "output", "both")
#: Choices of the ``rigid`` option.
RIGID = ("include", "exclude")


def points_option(what: str = "expansion points", default: str = "krylov's (0 Hz, then points on the frequency axis "
                  "where the body's residual is largest)"):
    """The ``points`` option of the Krylov-based methods: text or numbers in Hz
    (:func:`flexmor.reduction.krylov.parse_points`)."""
    return option(None, f"{what} in Hz, s = 2 pi p: 0, 300j (frequency axis), -5 (real); default {default}",
                  metavar="P1,P2")


def side_option(default: str = "input", choices=SIDES):
    """The ``side`` option: Krylov (or snapshot) space of ``B``, ``C^T`` or both."""
    return option(default, "space of the inputs B, the outputs C^T or both", choices=choices)


def rigid_option(default: str = "exclude"):
    """The ``rigid`` option: the rigid-body modes of a free body in the basis or not."""
    return option(default, "rigid-body modes of a free body in the basis (exclude: the floating frame carries "
                  "them, the body is the one an FFRF export writes)", choices=RIGID)


def interface_option():
    """The ``interface`` option of the component-mode methods: a list of interface SPECs."""
    return option(None, "interface NODE, SET, SET:DIR, or SET@rbe2 / SET@rbe3 (6-DOF master node at the centroid)",
                  metavar="SPEC")


#: Choices of ``gramian_factors(solves=...)`` (and the ``solves`` option of the Gramian methods).
SOLVES = ("auto", "direct", "dense", "surrogate")

#: Variants of second-order balancing: the controllability Gramian of positions or velocities.
VARIANTS = ("position", "velocity")


def variant_option():
    """The ``variant`` option: balance the position or the velocity controllability Gramian."""
    return option("position", "balance position or velocity Gramians", choices=VARIANTS)


def solves_option():
    """The ``solves`` option: how the quadrature nodes are solved
    (:func:`flexmor.reduction.gramians.gramian_factors`)."""
    return option("auto", "solves at the quadrature nodes: direct (one factorization each), dense (exact modal "
                  "form, small models), surrogate (verified reduced model; a full band up to its cutoff) or auto",
                  choices=SOLVES)


def nodes_option():
    """The ``nodes`` option: Gauss points per panel of the Gramian quadrature."""
    return option(4, "Gauss points per panel of the Gramian quadrature")
