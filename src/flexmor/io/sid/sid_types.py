"""Containers of SID (Standard Input Data) files: Taylor objects, frame nodes, the file.

References
----------
O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I:
Definition of standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BODY_OBJECTS", "M1_ORDERS", "NODE_OBJECTS", "NODE_OPTIONAL", "SIDFile", "SIDNode", "Taylor"]

#: Index orders of ``m1(i, j, k)`` entries; the first is the default.
M1_ORDERS = ("row-q-col", "row-col-q")
BODY_OBJECTS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
NODE_OBJECTS = ("origin", "phi", "psi", "AP")
#: Node objects a node may hold: its modal stresses.
NODE_OPTIONAL = ("sigma",)


@dataclass
class Taylor:
    """A SID Taylor object ``A(q) = m0 + Σ_k m1[:, :, k] q_k``.

    Attributes
    ----------
    m0 : ndarray (nrow, ncol)
    m1 : ndarray (nrow, ncol, nq) or None
        First-order term (``order = 1``), indexed ``[row, col, q]`` whatever the file order.
    nq : int
        Number of modal coordinates. ``structure`` as in the file (0..4); ``nqn`` 0.
    """

    m0: np.ndarray
    m1: np.ndarray | None = None
    nq: int = 0
    structure: int = 3
    nqn: int = 0

    @property
    def order(self) -> int:
        """Order of the Taylor expansion: 0 (``m0`` only) or 1 (with ``m1``)."""
        return 0 if self.m1 is None else 1

    def value(self, q) -> np.ndarray:
        """The matrix at the modal coordinates ``q``."""
        return self.m0 if self.m1 is None else self.m0 + self.m1 @ np.asarray(q, dtype=float)


@dataclass
class SIDNode:
    """A frame node: ``origin`` (3x1, order 1), ``phi``, ``psi`` (3 x nq), ``AP`` (3x3, order 1),
    and, where the body holds stress modes there, ``sigma`` (6x1, order 1: ``m1(i, 1, k)`` the
    stress component i (xx yy zz xy yz zx) of modal coordinate k; ``m0`` the reference stress, zero)."""

    id: int
    origin: Taylor
    phi: Taylor
    psi: Taylor
    AP: Taylor
    rframe: str = "body ref"
    sigma: Taylor | None = None


@dataclass
class SIDFile:
    """Contents of a ``.SID_FEM`` file.

    Attributes
    ----------
    mass : float
    ielastq : list of str
        Names of the modal coordinates (``nelastq = len(ielastq)``).
    nodes : list of SIDNode
    objects : dict of str to Taylor
        ``mdCM J Ct Cr Me Gr Ge Oe ksigma Ke De``.
    header : str
        The first line (node and mode counts and a comment).
    """

    mass: float
    ielastq: list
    nodes: list = field(default_factory=list)
    objects: dict = field(default_factory=dict)
    header: str = ""

    @property
    def nq(self) -> int:
        """Number of elastic coordinates (one name each in ``ielastq``)."""
        return len(self.ielastq)

    def frequencies_hz(self) -> np.ndarray:
        """Undamped eigenfrequencies of ``(Ke, Me)`` in Hz."""
        import scipy.linalg as sla

        lam = sla.eigh(self.objects["Ke"].m0, self.objects["Me"].m0, eigvals_only=True)
        return np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)

    def ielastq_hz(self) -> np.ndarray:
        """Frequencies written in the ``ielastq`` names (``... : 9.089 Hz``); NaN where none."""
        out = []
        for s in self.ielastq:
            m = re.search(r"([-+\d.eEdD]+)\s*Hz", s)
            out.append(float(m.group(1).replace("D", "E").replace("d", "e")) if m else np.nan)
        return np.array(out)
