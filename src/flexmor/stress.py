"""Strains and stresses of the solid elements from nodal displacements, as CalculiX computes them.

For each element type the strain ``eps = B u`` is evaluated at the integration points of
CalculiX's scheme (``C3D8``: 2x2x2 Gauss points, ``C3D8R``: one, with the element's mean
strain as in CalculiX's hourglass-controlled element (Flanagan and Belytschko), ``C3D20``: 3x3x3,
``C3D20R``: 2x2x2, ``C3D10``: 4, ``C3D4``: one, ``C3D15``: 9, ``C3D6``: 2; the node orders
are CalculiX's) and the stress is ``sigma = D eps`` with the element's material
(:class:`flexmor.elements.Material`). Nodal values follow CalculiX's ``extrapolate.f``: the
integration-point values are extrapolated to the corner nodes with its (rounded) coefficient
tables, mid-side nodes get the mean of their two corners (``C3D20`` extrapolates all 20 nodes
from its 27 points), and each node takes the plain mean over the elements that contain it.
Nastran and Ansys solids are read as the CalculiX element of the same shape
(:mod:`flexmor.elements`), so their stresses are those CalculiX would give for that mesh.

:func:`integration_points` gives the elements at their integration points (shape-function
gradients, the volume each point stands for, the stress of a displacement) for what integrates
over the elements, such as the geometric stiffness of :mod:`flexmor.preload`.

Components are in :data:`flexmor.elements.VOIGT` order (xx yy zz xy yz zx); strains are tensor
strains (``eps_xy = gamma_xy / 2``, as CalculiX writes them), stresses in the units of ``E``.
Shells, beams and springs are refused: CalculiX expands them to solids internally, and their
stresses are not recovered here. The work is vectorized per element type (NumPy over all the
elements of a block at once, in chunks that bound the memory), with no loop over elements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elements import Elements, Material
from .errors import ModelError

__all__ = ["INTEGRATION_WEIGHTS", "SOLID_TYPES", "ElementField", "NodalField", "PointChunk", "as_material",
           "body_stresses", "element_strains", "element_stresses", "integration_points", "nodal_strains",
           "nodal_stresses", "stress_node_ids", "von_mises"]

#: Element types without stiffness of their own, left out of stress recovery (and of the nodal means).
IGNORED_TYPES = ("MASS", "ROTARYI")

#: Target number of floats of the per-chunk work arrays.
_CHUNK = 1 << 22

# -- CalculiX's integration points (gauss.f) -------------------------------------------------------
_G2 = 0.577350269189626
_G3 = 0.774596669241483
_THIRD, _SIXTH, _TWO3 = 0.333333333333333, 0.166666666666667, 0.666666666666667
_TA, _TB = 0.138196601125011, 0.585410196624968


def _tensor_points(g) -> np.ndarray:
    """Points of a Gauss product rule, xi running fastest (CalculiX's order)."""
    return np.array([(x, y, z) for z in g for y in g for x in g], dtype=np.float64)


_HEX8_POINTS = _tensor_points((-_G2, _G2))
_HEX27_POINTS = _tensor_points((-_G3, 0.0, _G3))
_TET4_POINTS = np.array([(_TA, _TA, _TA), (_TB, _TA, _TA), (_TA, _TB, _TA), (_TA, _TA, _TB)])
_WEDGE2_POINTS = np.array([(_THIRD, _THIRD, -_G2), (_THIRD, _THIRD, _G2)])
_WEDGE9_POINTS = np.array([(a, b, z) for z in (-_G3, 0.0, _G3) for a, b in ((_SIXTH, _SIXTH), (_TWO3, _SIXTH),
                                                                          (_SIXTH, _TWO3))])

# -- CalculiX's extrapolation from the integration points to the corner nodes (extrapolate.f) --------
_A2 = np.array([  # 6 nodes x 2 points, listed point by point
    1.1455, -0.1455, 1.1455, -0.1455, 1.1455, -0.1455, -0.1455, 1.1455, -0.1455, 1.1455, -0.1455, 1.1455,
]).reshape(2, 6).T
_A4 = np.array([  # 4 nodes x 4 points, listed point by point
    1.92705, -0.30902, -0.30902, -0.30902, -0.30902, 1.92705, -0.30902, -0.30902, -0.30902, -0.30902, 1.92705,
    -0.30902, -0.30902, -0.30902, -0.30902, 1.92705,
]).reshape(4, 4).T
_A8 = np.array([  # 8 nodes x 8 points, listed point by point
    2.549, -0.683, 0.183, -0.683, -0.683, 0.183, -0.04904, 0.183, -0.683, 2.549, -0.683, 0.183, 0.183, -0.683,
    0.183, -0.04904, -0.683, 0.183, -0.683, 2.549, 0.183, -0.04904, 0.183, -0.683, 0.183, -0.683, 2.549, -0.683,
    -0.04904, 0.183, -0.683, 0.183, -0.683, 0.183, -0.04904, 0.183, 2.549, -0.683, 0.183, -0.683, 0.183, -0.683,
    0.183, -0.04904, -0.683, 2.549, -0.683, 0.183, 0.183, -0.04904, 0.183, -0.683, -0.683, 0.183, -0.683, 2.549,
    -0.04904, 0.183, -0.683, 0.183, 0.183, -0.683, 2.549, -0.683,
]).reshape(8, 8).T
_A9 = np.array([  # 6 nodes x 9 points, listed point by point
    1.63138, -0.32628, -0.32628, -0.52027, 0.10405, 0.10405, -0.32628, 1.63138, -0.32628, 0.10405, -0.52027,
    0.10405, -0.32628, -0.32628, 1.63138, 0.10405, 0.10405, -0.52027, 0.55556, -0.11111, -0.11111, 0.55556,
    -0.11111, -0.11111, -0.11111, 0.55556, -0.11111, -0.11111, 0.55556, -0.11111, -0.11111, -0.11111, 0.55556,
    -0.11111, -0.11111, 0.55556, -0.52027, 0.10405, 0.10405, 1.63138, -0.32628, -0.32628, 0.10405, -0.52027,
    0.10405, -0.32628, 1.63138, -0.32628, 0.10405, 0.10405, -0.52027, -0.32628, -0.32628, 1.63138,
]).reshape(9, 6).T
_A27 = np.array([  # 20 nodes x 27 points, listed point by point
    2.37499, -0.12559, -0.16145, -0.12559, -0.12559, -0.16145, 0.11575, -0.16145, 0.32628, 0.11111, 0.11111,
    0.32628, 0.11111, -0.10405, -0.10405, 0.11111, 0.32628, 0.11111, -0.10405, 0.11111, -0.31246, -0.31246,
    0.31481, 0.31481, 0.31481, 0.31481, -0.16902, -0.16902, 1.28439, -0.27072, -0.19444, -0.27072, -0.19444,
    0.15961, -0.00661, 0.15961, -0.27072, -0.27072, 0.15961, 0.15961, -0.12559, 2.37499, -0.12559, -0.16145,
    -0.16145, -0.12559, -0.16145, 0.11575, 0.32628, 0.32628, 0.11111, 0.11111, 0.11111, 0.11111, -0.10405,
    -0.10405, 0.11111, 0.32628, 0.11111, -0.10405, -0.31246, 0.31481, 0.31481, -0.31246, 0.31481, -0.16902,
    -0.16902, 0.31481, -0.27072, -0.19444, -0.27072, 1.28439, 0.15961, -0.00661, 0.15961, -0.19444, -0.27072,
    0.15961, 0.15961, -0.27072, -0.48824, -0.48824, -0.48824, -0.48824, 0.22898, 0.22898, 0.22898, 0.22898,
    0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, -0.22222, -0.22222, -0.22222, -0.22222,
    0.31481, -0.31246, -0.31246, 0.31481, -0.16902, 0.31481, 0.31481, -0.16902, -0.27072, 1.28439, -0.27072,
    -0.19444, 0.15961, -0.19444, 0.15961, -0.00661, 0.15961, -0.27072, -0.27072, 0.15961, -0.12559, -0.16145,
    -0.12559, 2.37499, -0.16145, 0.11575, -0.16145, -0.12559, 0.11111, 0.11111, 0.32628, 0.32628, -0.10405,
    -0.10405, 0.11111, 0.11111, 0.11111, -0.10405, 0.11111, 0.32628, 0.31481, 0.31481, -0.31246, -0.31246,
    -0.16902, -0.16902, 0.31481, 0.31481, -0.19444, -0.27072, 1.28439, -0.27072, -0.00661, 0.15961, -0.19444,
    0.15961, 0.15961, 0.15961, -0.27072, -0.27072, -0.16145, -0.12559, 2.37499, -0.12559, 0.11575, -0.16145,
    -0.12559, -0.16145, 0.11111, 0.32628, 0.32628, 0.11111, -0.10405, 0.11111, 0.11111, -0.10405, -0.10405,
    0.11111, 0.32628, 0.11111, -0.31246, 0.31481, -0.16902, 0.31481, -0.31246, 0.31481, -0.16902, 0.31481,
    -0.27072, 0.15961, 0.15961, -0.27072, -0.27072, 0.15961, 0.15961, -0.27072, 1.28439, -0.19444, -0.00661,
    -0.19444, -0.48824, -0.48824, 0.22898, 0.22898, -0.48824, -0.48824, 0.22898, 0.22898, 0.05556, -0.22222,
    0.05556, -0.22222, 0.05556, -0.22222, 0.05556, -0.22222, 0.05556, 0.05556, 0.05556, 0.05556, 0.31481, -0.31246,
    0.31481, -0.16902, 0.31481, -0.31246, 0.31481, -0.16902, -0.27072, -0.27072, 0.15961, 0.15961, -0.27072,
    -0.27072, 0.15961, 0.15961, -0.19444, 1.28439, -0.19444, -0.00661, -0.48824, 0.22898, 0.22898, -0.48824,
    -0.48824, 0.22898, 0.22898, -0.48824, -0.22222, 0.05556, -0.22222, 0.05556, -0.22222, 0.05556, -0.22222,
    0.05556, 0.05556, 0.05556, 0.05556, 0.05556, -0.2963, -0.2963, -0.2963, -0.2963, -0.2963, -0.2963, -0.2963,
    -0.2963, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111, -0.11111,
    -0.11111, -0.11111, 0.22898, -0.48824, -0.48824, 0.22898, 0.22898, -0.48824, -0.48824, 0.22898, -0.22222,
    0.05556, -0.22222, 0.05556, -0.22222, 0.05556, -0.22222, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.31481,
    -0.16902, 0.31481, -0.31246, 0.31481, -0.16902, 0.31481, -0.31246, 0.15961, 0.15961, -0.27072, -0.27072,
    0.15961, 0.15961, -0.27072, -0.27072, -0.19444, -0.00661, -0.19444, 1.28439, 0.22898, 0.22898, -0.48824,
    -0.48824, 0.22898, 0.22898, -0.48824, -0.48824, 0.05556, -0.22222, 0.05556, -0.22222, 0.05556, -0.22222,
    0.05556, -0.22222, 0.05556, 0.05556, 0.05556, 0.05556, -0.16902, 0.31481, -0.31246, 0.31481, -0.16902, 0.31481,
    -0.31246, 0.31481, 0.15961, -0.27072, -0.27072, 0.15961, 0.15961, -0.27072, -0.27072, 0.15961, -0.00661,
    -0.19444, 1.28439, -0.19444, -0.12559, -0.16145, 0.11575, -0.16145, 2.37499, -0.12559, -0.16145, -0.12559,
    0.11111, -0.10405, -0.10405, 0.11111, 0.32628, 0.11111, 0.11111, 0.32628, 0.32628, 0.11111, -0.10405, 0.11111,
    0.31481, 0.31481, -0.16902, -0.16902, -0.31246, -0.31246, 0.31481, 0.31481, -0.19444, 0.15961, -0.00661,
    0.15961, 1.28439, -0.27072, -0.19444, -0.27072, -0.27072, -0.27072, 0.15961, 0.15961, -0.16145, -0.12559,
    -0.16145, 0.11575, -0.12559, 2.37499, -0.12559, -0.16145, 0.11111, 0.11111, -0.10405, -0.10405, 0.32628,
    0.32628, 0.11111, 0.11111, 0.11111, 0.32628, 0.11111, -0.10405, 0.31481, -0.16902, -0.16902, 0.31481, -0.31246,
    0.31481, 0.31481, -0.31246, 0.15961, -0.00661, 0.15961, -0.19444, -0.27072, -0.19444, -0.27072, 1.28439,
    -0.27072, 0.15961, 0.15961, -0.27072, 0.22898, 0.22898, 0.22898, 0.22898, -0.48824, -0.48824, -0.48824,
    -0.48824, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, 0.05556, -0.22222, -0.22222, -0.22222,
    -0.22222, -0.16902, 0.31481, 0.31481, -0.16902, 0.31481, -0.31246, -0.31246, 0.31481, 0.15961, -0.19444,
    0.15961, -0.00661, -0.27072, 1.28439, -0.27072, -0.19444, 0.15961, -0.27072, -0.27072, 0.15961, -0.16145,
    0.11575, -0.16145, -0.12559, -0.12559, -0.16145, -0.12559, 2.37499, -0.10405, -0.10405, 0.11111, 0.11111,
    0.11111, 0.11111, 0.32628, 0.32628, 0.11111, -0.10405, 0.11111, 0.32628, -0.16902, -0.16902, 0.31481, 0.31481,
    0.31481, 0.31481, -0.31246, -0.31246, -0.00661, 0.15961, -0.19444, 0.15961, -0.19444, -0.27072, 1.28439,
    -0.27072, 0.15961, 0.15961, -0.27072, -0.27072, 0.11575, -0.16145, -0.12559, -0.16145, -0.16145, -0.12559,
    2.37499, -0.12559, -0.10405, 0.11111, 0.11111, -0.10405, 0.11111, 0.32628, 0.32628, 0.11111, -0.10405, 0.11111,
    0.32628, 0.11111,
]).reshape(27, 20).T


# -- shape functions in CalculiX's node orders ------------------------------------------------------
_HEX_CORNERS = np.array([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                         (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)], dtype=np.float64)
_HEX20_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
_TET10_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
_WEDGE15_EDGES = [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)]
_HEX20_NODES = np.concatenate([_HEX_CORNERS, [(_HEX_CORNERS[a] + _HEX_CORNERS[b]) / 2 for a, b in _HEX20_EDGES]])


def _hex8(x, y, z):
    c = _HEX_CORNERS
    return [(1 + x * c[a, 0]) * (1 + y * c[a, 1]) * (1 + z * c[a, 2]) / 8 for a in range(8)]


def _hex20(x, y, z):
    out = []
    for a, (p, q, r) in enumerate(_HEX20_NODES):
        if a < 8:
            out.append((1 + x * p) * (1 + y * q) * (1 + z * r) * (x * p + y * q + z * r - 2) / 8)
        elif p == 0:
            out.append((1 - x * x) * (1 + y * q) * (1 + z * r) / 4)
        elif q == 0:
            out.append((1 - y * y) * (1 + x * p) * (1 + z * r) / 4)
        else:
            out.append((1 - z * z) * (1 + x * p) * (1 + y * q) / 4)
    return out


def _tet4(x, y, z):
    return [1 - x - y - z, x, y, z]


def _tet10(x, y, z):
    a = 1 - x - y - z
    return [(2 * a - 1) * a, x * (2 * x - 1), y * (2 * y - 1), z * (2 * z - 1),
            4 * x * a, 4 * x * y, 4 * y * a, 4 * z * a, 4 * x * z, 4 * y * z]


def _wedge6(x, y, z):
    a = 1 - x - y
    return [a * (1 - z) / 2, x * (1 - z) / 2, y * (1 - z) / 2, a * (1 + z) / 2, x * (1 + z) / 2, y * (1 + z) / 2]


def _wedge15(x, y, z):
    a = 1 - x - y
    return [-a * (1 - z) * (2 * x + 2 * y + z) / 2, x * (1 - z) * (2 * x - 2 - z) / 2,
            y * (1 - z) * (2 * y - 2 - z) / 2, -a * (1 + z) * (2 * x + 2 * y - z) / 2,
            x * (1 + z) * (2 * x - 2 + z) / 2, y * (1 + z) * (2 * y - 2 + z) / 2,
            2 * x * a * (1 - z), 2 * x * y * (1 - z), 2 * y * a * (1 - z),
            2 * x * a * (1 + z), 2 * x * y * (1 + z), 2 * y * a * (1 + z),
            a * (1 - z * z), x * (1 - z * z), y * (1 - z * z)]


def _derivatives(shape, points: np.ndarray) -> np.ndarray:
    """``dN_a / dxi_j`` at the points, shape (n_points, n_nodes, 3), exact (complex step of polynomials)."""
    h = 1e-30
    out = []
    for j in range(3):
        p = points.astype(np.complex128)
        p[:, j] += 1j * h
        out.append(np.array(shape(p[:, 0], p[:, 1], p[:, 2])).imag.T / h)
    return np.stack(out, axis=-1)


def _with_midsides(corner_rows: np.ndarray, edges) -> np.ndarray:
    """Extrapolation rows of the corners followed by the means of the corner pairs of the mid-side nodes."""
    return np.concatenate([corner_rows, [(corner_rows[a] + corner_rows[b]) / 2 for a, b in edges]])


@dataclass(frozen=True)
class _Scheme:
    dN: np.ndarray  # (n_points, n_nodes, 3)
    extrapolation: np.ndarray  # (n_nodes, n_points)
    mean: bool = False  # one point with the element's mean gradient, integrated at the points of dN


def _scheme(shape, points, extrapolation, mean=False) -> _Scheme:
    return _Scheme(_derivatives(shape, points), np.asarray(extrapolation, dtype=np.float64), mean)


_SCHEMES = {
    "C3D8": _scheme(_hex8, _HEX8_POINTS, _A8),
    "C3D8R": _scheme(_hex8, _HEX8_POINTS, np.ones((8, 1)), mean=True),  # Flanagan-Belytschko mean strain
    "C3D20": _scheme(_hex20, _HEX27_POINTS, _A27),
    "C3D20R": _scheme(_hex20, _HEX8_POINTS, _with_midsides(_A8, _HEX20_EDGES)),
    "C3D4": _scheme(_tet4, np.full((1, 3), 0.25), np.ones((4, 1))),
    "C3D10": _scheme(_tet10, _TET4_POINTS, _with_midsides(_A4, _TET10_EDGES)),
    "C3D6": _scheme(_wedge6, _WEDGE2_POINTS, _A2),
    "C3D15": _scheme(_wedge15, _WEDGE9_POINTS, _with_midsides(_A9, _WEDGE15_EDGES)),
}

#: The element types whose strains and stresses are recovered.
SOLID_TYPES = tuple(_SCHEMES)

_G3W = (5 / 9, 8 / 9, 5 / 9)

#: Weights of the integration points per element type, in the order of the points (their sum is the
#: volume of the reference element: 8 for hexahedra, 1/6 for tetrahedra, 1 for wedges).
INTEGRATION_WEIGHTS = {
    "C3D8": np.ones(8),
    "C3D8R": np.ones(8),
    "C3D20": np.array([a * b * c for c in _G3W for b in _G3W for a in _G3W]),
    "C3D20R": np.ones(8),
    "C3D4": np.array([1 / 6]),
    "C3D10": np.full(4, 1 / 24),
    "C3D6": np.full(2, 0.5),
    "C3D15": np.array([w / 6 for w in _G3W for _ in range(3)]),
}


# -- results ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ElementField:
    """Values at the integration points of the elements of one type.

    Attributes
    ----------
    type : str
        CalculiX element type.
    ids : ndarray of int, shape (n_elements,)
    values : ndarray
        ``(n_elements, n_points, 6)`` for one displacement vector, ``(m, n_elements, n_points, 6)``
        for ``m`` vectors; integration points in CalculiX's order, components :data:`~flexmor.elements.VOIGT`.
    """

    type: str
    ids: np.ndarray
    values: np.ndarray


@dataclass(frozen=True)
class NodalField:
    """Values at nodes.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n,)
    values : ndarray
        ``(n, 6)`` for one displacement vector, ``(m, n, 6)`` for ``m`` vectors; components
        :data:`~flexmor.elements.VOIGT`.
    """

    node_ids: np.ndarray
    values: np.ndarray


def von_mises(stress) -> np.ndarray:
    """The von Mises equivalent stress of stress components :data:`~flexmor.elements.VOIGT` on the last axis."""
    s = np.asarray(stress, dtype=np.float64)
    if s.shape[-1:] != (6,):
        raise ModelError(f"stress must have its 6 components (xx yy zz xy yz zx) on the last axis, got shape {s.shape}")
    xx, yy, zz, xy, yz, zx = np.moveaxis(s, -1, 0)
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3 * (xy ** 2 + yz ** 2 + zx ** 2))


# -- the work ---------------------------------------------------------------------------------------
def _source(model) -> str:
    el = model.elements
    return (el.source if el is not None and el.source else "") or model.source or model.name


def as_material(material) -> Material:
    """``material`` as a :class:`~flexmor.elements.Material` with an elasticity matrix: a Material, or
    ``(E, nu[, rho])`` (isotropic); a :class:`~flexmor.errors.ModelError` naming ``material`` otherwise."""
    if isinstance(material, Material):
        if material.D is None:
            raise ModelError(f"{material.name!r}: {material.unsupported or 'no elasticity matrix'}",
                             params=("material",))
        return material
    try:
        vals = [float(v) for v in material]
    except (TypeError, ValueError):
        raise ModelError(f"material must be a Material or (E, nu[, rho]), got {material!r}",
                         params=("material",)) from None
    if len(vals) not in (2, 3):
        raise ModelError(f"material must be (E, nu[, rho]), got {len(vals)} numbers", params=("material",))
    return Material.isotropic(*vals, name="material")


def _blocks(model, material) -> tuple[list, Elements]:
    """The solid element blocks of ``model`` and their materials, checked."""
    src = _source(model)
    el = model.elements
    if el is None or not el.blocks:
        raise ModelError(f"{src}: the model has no elements to recover stresses from (read the FE deck with its "
                         "*ELEMENT / CHEXA ... definitions)")
    if material is not None:
        el = el.with_material(as_material(material))
    blocks = []
    for b in el.blocks:
        if b.type in IGNORED_TYPES or not b.ids.size:
            continue
        if b.type not in _SCHEMES:
            kind = "shell" if b.type.startswith(("S3", "S4", "S6", "S8", "CPS", "CPE", "CAX", "M3D")) else "these"
            raise ModelError(f"{src}: stresses of {b.type} elements are not recovered ({kind} elements; the solids "
                             f"{', '.join(SOLID_TYPES)} are)")
        missing = b.material < 0
        if missing.any():
            raise ModelError(f"{src}: {int(missing.sum())} {b.type} element(s) have no elastic constants (first: "
                             f"element {int(b.ids[np.flatnonzero(missing)[0]])}); pass material=(E, nu[, rho])",
                             params=("material",))
        for m in np.unique(b.material):
            mat = el.materials[m]
            if mat.D is None:
                raise ModelError(f"{src}: {mat.unsupported}; pass material=(E, nu[, rho])", params=("material",))
        blocks.append(b)
    if not blocks:
        raise ModelError(f"{src}: the model has no solid elements ({', '.join(SOLID_TYPES)})")
    return blocks, el


def _rows(model, ids: np.ndarray) -> np.ndarray:
    order = model._node_order
    sorted_ids = model.node_ids[order]
    pos = np.minimum(np.searchsorted(sorted_ids, ids), max(sorted_ids.size - 1, 0))
    if np.any(sorted_ids[pos] != ids):
        bad = ids[sorted_ids[pos] != ids]
        raise ModelError(f"node {int(bad.ravel()[0])} of an element is not in the node table")
    return order[pos]


@dataclass(frozen=True)
class _Displacements:
    """Vectors over the model's equations and where each node's x y z are among them."""

    U: np.ndarray  # (n_dof, m)
    eq: np.ndarray  # (n_nodes, 3): equation of each node row and direction, -1 for none
    frames: np.ndarray | None  # (n_nodes, 3, 3) where a node has its own frame (NaN elsewhere), or None
    single: bool

    @property
    def m(self) -> int:
        return self.U.shape[1]

    def at(self, rows: np.ndarray) -> np.ndarray:
        """Displacements (c, k, 3, m) in global x y z of the node rows ``rows`` (c, k)."""
        e = self.eq[rows]
        Ue = self.U[np.maximum(e, 0)]
        Ue[e < 0] = 0.0
        if self.frames is not None:
            Q = self.frames[rows]
            own = ~np.isnan(Q[..., 0, 0])
            if own.any():
                Ue[own] = np.einsum("nij,njm->nim", Q[own], Ue[own])
        return Ue


def _displacements(model, u) -> _Displacements:
    """The vectors ``u`` over the model's equations, checked, with the map of node rows to equations."""
    if model.dofs is None:
        raise ModelError(f"{_source(model)}: the model has no equation map (node, direction) to read displacements")
    u = np.asarray(u)
    single = u.ndim == 1
    U = u.reshape(u.shape[0], -1) if u.ndim else u
    if U.ndim != 2 or U.shape[0] != model.n_dof:
        raise ModelError(f"u must have {model.n_dof} rows (one per equation of the model), got shape {u.shape}",
                         params=("u",))
    if np.iscomplexobj(U) or not np.all(np.isfinite(U)):
        raise ModelError("u must be real and finite", params=("u",))
    U = U.astype(np.float64, copy=False)
    trans = np.flatnonzero(model.dofs[:, 1] <= 3)
    eq = np.full((model.n_nodes, 3), -1, dtype=np.int64)
    eq[_rows(model, model.dofs[trans, 0]), model.dofs[trans, 1] - 1] = trans
    frames = None
    if model.node_frames:
        frames = np.full((model.n_nodes, 3, 3), np.nan)
        framed = np.array(sorted(model.node_frames), dtype=np.int64)
        frames[_rows(model, framed)] = np.stack([model.node_frames[int(n)] for n in framed])
    return _Displacements(U, eq, frames, single)


def _chunks(n: int, per_element: int):
    step = max(1, _CHUNK // max(per_element, 1))
    for s in range(0, n, step):
        yield slice(s, min(s + step, n))


def _gradients(model, block, sl) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node rows (c, k), ``dN_a / dx_k`` (c, n_points, 3, k) and Jacobian determinants (c, n_points) of the
    elements ``sl`` of ``block`` (the scheme's points, before a mean gradient)."""
    sch = _SCHEMES[block.type]
    rows = _rows(model, block.nodes[sl])  # (c, k)
    X = model.xyz[rows]  # (c, k, 3)
    J = np.einsum("cak,pal->cpkl", X, sch.dN)
    det = np.linalg.det(J)
    if np.any(det <= 0):
        e = int(block.ids[sl][np.flatnonzero((det <= 0).any(axis=1))[0]])
        raise ModelError(f"{_source(model)}: {block.type} element {e} has a Jacobian determinant <= 0 at an "
                         "integration point (inverted or degenerate element)")
    return rows, np.einsum("pal,cplk->cpka", sch.dN, np.linalg.inv(J)), det


def _strains(model, block, disp: _Displacements, sl) -> np.ndarray:
    """Engineering strains (c, n_points, 6, m) of the elements ``sl`` of ``block``."""
    sch = _SCHEMES[block.type]
    rows, dNdx, det = _gradients(model, block, sl)  # dNdx (c, p, 3, k): dN_a / dx_k
    if sch.mean:  # the volume mean of the gradient, exact with 2x2x2 points for a trilinear hexahedron
        dNdx = np.einsum("cpka,cp->cka", dNdx, det)[:, None] / det.sum(axis=1)[:, None, None, None]
    c, k = rows.shape
    m = disp.m
    Ue = disp.at(rows).reshape(c, 1, k, 3 * m)
    H = np.matmul(dNdx, Ue).reshape(c, dNdx.shape[1], 3, 3, m)  # [.., k, i, :] = du_i / dx_k
    return np.stack([H[:, :, 0, 0], H[:, :, 1, 1], H[:, :, 2, 2], H[:, :, 1, 0] + H[:, :, 0, 1],
                     H[:, :, 2, 1] + H[:, :, 1, 2], H[:, :, 0, 2] + H[:, :, 2, 0]], axis=2)


def _field(model, block, disp, sl, D, stress: bool) -> np.ndarray:
    """Stresses or tensor strains (c, n_points, 6, m) of the elements ``sl`` of ``block``."""
    eps = _strains(model, block, disp, sl)
    if stress:
        return np.matmul(D[block.material[sl]][:, None], eps)
    eps[:, :, 3:] *= 0.5
    return eps


def _per_element(sch, m: int) -> int:
    """Floats of the work arrays per element and vector."""
    k, n_ip = sch.extrapolation.shape
    return m * (n_ip * 24 + k * 12) + n_ip * k * 6


def _element_field(model, u, material, stress: bool) -> list:
    blocks, el = _blocks(model, material)
    disp = _displacements(model, u)
    D = np.stack([m.D if m.D is not None else np.zeros((6, 6)) for m in el.materials])
    out = []
    for b in blocks:
        parts = [_field(model, b, disp, sl, D, stress) for sl in _chunks(b.ids.size, _per_element(_SCHEMES[b.type],
                                                                                                  disp.m))]
        vals = np.concatenate(parts, axis=0).transpose(3, 0, 1, 2)  # (m, n_el, p, 6)
        out.append(ElementField(b.type, b.ids, vals[0] if disp.single else vals))
    return out


def element_strains(model, u, *, material=None) -> list:
    """Strains at the integration points of every solid element.

    Parameters
    ----------
    model : FEModel
        With :attr:`~flexmor.model.FEModel.elements`.
    u : array_like, shape (n_dof,) or (n_dof, m)
        Displacement vectors over the model's equations (constrained directions are zero).
    material : Material or tuple, optional
        Not used for strains; accepted so that a model without material can be checked the same way.

    Returns
    -------
    list of ElementField
        One per element type; tensor strains (``eps_xy = gamma_xy / 2``).

    Raises
    ------
    ModelError
        No elements, elements of a type that is not recovered (shells, beams, springs), an
        element without material, a degenerate element, or ``u`` of the wrong shape.
    """
    return _element_field(model, u, material, False)


def element_stresses(model, u, *, material=None) -> list:
    """Stresses at the integration points of every solid element (CalculiX's points and order).

    Parameters
    ----------
    model : FEModel
        With :attr:`~flexmor.model.FEModel.elements` (its materials from the deck).
    u : array_like, shape (n_dof,) or (n_dof, m)
        Displacement vectors over the model's equations (constrained directions are zero).
    material : Material or tuple, optional
        ``(E, nu[, rho])`` or a :class:`~flexmor.elements.Material` for every element, in place
        of the deck's materials; needed when the deck defines none.

    Returns
    -------
    list of ElementField
        One per element type.

    Raises
    ------
    ModelError
        As :func:`element_strains`; also an element without usable material (pass ``material``).
    """
    return _element_field(model, u, material, True)


@dataclass(frozen=True)
class PointChunk:
    """Elements of one type at their integration points, with the stress of one displacement.

    Attributes
    ----------
    type : str
        CalculiX element type.
    ids : ndarray of int, shape (c,)
    rows : ndarray of int, shape (c, k)
        The rows of the element nodes in the model's node table.
    equations : ndarray of int, shape (c, k, 3)
        The equation of each node's x y z, -1 where the direction is not an equation.
    gradients : ndarray, shape (c, p, 3, k)
        ``dN_a / dx_j`` at the points (``C3D8R``: one point, the element's mean gradient).
    volumes : ndarray, shape (c, p)
        The volume each point stands for (weight times Jacobian determinant).
    stress : ndarray, shape (c, p, 6)
        Components :data:`~flexmor.elements.VOIGT`.
    """

    type: str
    ids: np.ndarray
    rows: np.ndarray
    equations: np.ndarray
    gradients: np.ndarray
    volumes: np.ndarray
    stress: np.ndarray


def integration_points(model, u, *, material=None):
    """The solid elements at their integration points, in chunks that bound the memory.

    Parameters
    ----------
    model : FEModel
        With :attr:`~flexmor.model.FEModel.elements`; nodes with local displacement directions
        are refused.
    u : array_like, shape (n_dof,)
        One displacement vector over the model's equations.
    material : Material or tuple, optional
        ``(E, nu[, rho])`` or a :class:`~flexmor.elements.Material` for every element.

    Yields
    ------
    PointChunk

    Raises
    ------
    ModelError
        As :func:`element_stresses`.
    """
    blocks, el = _blocks(model, material)
    disp = _displacements(model, np.asarray(u).reshape(-1))
    if disp.frames is not None:
        raise ModelError(f"{_source(model)}: nodes with local displacement directions (Nastran CD systems); read "
                         "the model with directions='basic'", params=("model",))
    D = np.stack([m.D if m.D is not None else np.zeros((6, 6)) for m in el.materials])
    for b in blocks:
        sch = _SCHEMES[b.type]
        for sl in _chunks(b.ids.size, _per_element(sch, 4)):
            rows, G, det = _gradients(model, b, sl)
            dv = det * INTEGRATION_WEIGHTS[b.type]
            if sch.mean:
                G = np.einsum("cpka,cp->cka", G, dv)[:, None] / dv.sum(axis=1)[:, None, None, None]
                dv = dv.sum(axis=1, keepdims=True)
            c, k = rows.shape
            H = np.matmul(G, disp.at(rows).reshape(c, 1, k, 3))  # [.., j, i] = du_i / dx_j
            eps = np.stack([H[..., 0, 0], H[..., 1, 1], H[..., 2, 2], H[..., 1, 0] + H[..., 0, 1],
                            H[..., 2, 1] + H[..., 1, 2], H[..., 0, 2] + H[..., 2, 0]], axis=-1)
            stress = np.einsum("cij,cpj->cpi", D[b.material[sl]], eps)
            yield PointChunk(b.type, b.ids[sl], rows, disp.eq[rows], G, dv, stress)


def _nodal(model, u, material, nodes, stress: bool) -> NodalField:
    blocks, el = _blocks(model, material)
    disp = _displacements(model, u)
    D = np.stack([m.D if m.D is not None else np.zeros((6, 6)) for m in el.materials])
    if nodes is None:
        out_ids = np.unique(np.concatenate([b.nodes.ravel() for b in blocks]))
    else:
        out_ids = np.unique(np.asarray(nodes, dtype=np.int64).ravel())
        unknown = np.setdiff1d(out_ids, np.concatenate([b.nodes.ravel() for b in blocks]))
        if unknown.size:
            raise ModelError(f"node {int(unknown[0])} is in no solid element ({unknown.size} such nodes)",
                             params=("nodes",))
    m = disp.m
    acc = np.zeros((out_ids.size, 6 * m))
    count = np.zeros(out_ids.size)
    for b in blocks:
        sch = _SCHEMES[b.type]
        k, n_ip = sch.extrapolation.shape
        pos = np.minimum(np.searchsorted(out_ids, b.nodes), out_ids.size - 1)
        hit = out_ids[pos] == b.nodes
        use = np.flatnonzero(hit.any(axis=1))
        count += np.bincount(pos[hit], minlength=out_ids.size)
        for sl in _chunks(use.size, _per_element(sch, m)):
            idx = use[sl]
            vals = _field(model, b, disp, idx, D, stress).reshape(idx.size, n_ip, 6 * m)
            at_nodes = np.tensordot(sch.extrapolation, vals, axes=(1, 1)).reshape(k * idx.size, 6 * m)
            h = hit[idx].T.ravel()  # node-major, as at_nodes
            rows = pos[idx].T.ravel()[h]
            order = np.argsort(rows, kind="stable")
            first = np.flatnonzero(np.r_[True, rows[order][1:] != rows[order][:-1]])
            acc[rows[order][first]] += np.add.reduceat(at_nodes[np.flatnonzero(h)[order]], first, axis=0)
    vals = (acc / count[:, None]).reshape(out_ids.size, 6, m).transpose(2, 0, 1)
    return NodalField(out_ids, vals[0] if disp.single else vals)


def nodal_stresses(model, u, *, material=None, nodes=None) -> NodalField:
    """Stresses at the nodes, extrapolated from the integration points and averaged as CalculiX does.

    Parameters
    ----------
    model : FEModel
        With :attr:`~flexmor.model.FEModel.elements`.
    u : array_like, shape (n_dof,) or (n_dof, m)
        Displacement vectors over the model's equations (constrained directions are zero).
    material : Material or tuple, optional
        ``(E, nu[, rho])`` or a :class:`~flexmor.elements.Material` for every element, in place
        of the deck's materials; needed when the deck defines none.
    nodes : array_like of int, optional
        The node ids to return (only the elements containing them are evaluated); default
        every node of a solid element.

    Returns
    -------
    NodalField
        Node ids (sorted) and stresses; each node's value is the plain mean over the solid
        elements that contain it of their extrapolated values (CalculiX's ``extrapolate.f``).

    Raises
    ------
    ModelError
        As :func:`element_stresses`; also a node of ``nodes`` that is in no solid element.
    """
    return _nodal(model, u, material, nodes, True)


def nodal_strains(model, u, *, material=None, nodes=None) -> NodalField:
    """Tensor strains at the nodes, extrapolated and averaged like :func:`nodal_stresses`."""
    return _nodal(model, u, material, nodes, False)


def stress_node_ids(model, nodes="surface") -> np.ndarray:
    """The node ids of a stress-node choice.

    Parameters
    ----------
    model : FEModel
    nodes : str or array_like of int
        ``"surface"``: the nodes of the outer surface of the mesh (:func:`flexmor.mesh.outer_surface`)
        that lie in a solid element; ``"all"``: every node of a solid element; a node set name of
        the model; or node ids.

    Raises
    ------
    ModelError
        An unknown node set, or no solid elements.
    """
    from .mesh import outer_surface

    if model.elements is None:
        raise ModelError(f"{_source(model)}: the model has no elements to recover stresses from")
    solid = [b.nodes.ravel() for b in model.elements.blocks if b.type in _SCHEMES]
    if not solid:
        raise ModelError(f"{_source(model)}: the model has no solid elements ({', '.join(SOLID_TYPES)})")
    in_solids = np.unique(np.concatenate(solid))
    if isinstance(nodes, str):
        key = nodes.strip()
        if key.lower() == "all":
            return in_solids
        if key.lower() == "surface":
            if model.mesh is None:
                return in_solids
            return np.intersect1d(outer_surface(model.mesh).node_ids(), in_solids)
        if key.upper() in model.node_sets:
            return np.unique(model.node_sets[key.upper()])
        raise ModelError(f"stress nodes {nodes!r}: neither 'surface', 'all' nor a node set of the model (sets: "
                         f"{', '.join(sorted(model.node_sets)) or 'none'})", params=("nodes",))
    return np.unique(np.asarray(nodes, dtype=np.int64).ravel())


def body_stresses(model, body, *, material=None, nodes="surface") -> NodalField:
    """The nodal stress of every basis vector of a reduced body (its stress modes).

    The stress at the nodes for reduced coordinates ``qr`` is ``sum_j qr_j S[j]`` (stress is
    linear in the displacement ``V qr``).

    Parameters
    ----------
    model : FEModel
        The FE model the body was reduced from, as read (a body with couplings expands its
        basis through them to their slave nodes, :func:`flexmor.expansion.expand_body`).
    body : ReducedModel
        With its basis ``V``.
    material : Material or tuple, optional
        ``(E, nu[, rho])`` for every element in place of the deck's materials.
    nodes : str or array_like of int
        Where (:func:`stress_node_ids`); default the outer surface.

    Returns
    -------
    NodalField
        ``values`` of shape ``(r, k, 6)``.

    Raises
    ------
    ModelError
        As :func:`nodal_stresses`; a body without basis or of another model.
    """
    from .expansion import expand_body

    xb = expand_body(model, body, elastic=False)
    ids = stress_node_ids(xb.model, nodes)
    out = nodal_stresses(xb.model, xb.V, material=material, nodes=ids)
    values = out.values if out.values.ndim == 3 else out.values[None]
    return NodalField(out.node_ids, values)
