"""Built-in parametric finite-element models (scikit-fem) for the demo, tests and benchmarks.

scikit-fem is imported only when a model is built, so ``import flexmor`` needs NumPy and
SciPy only (``pip install flexmor[full]`` for the models).
"""

from .plate_structure import plate_structure
from .solid import ELEMENTS, KINDS, cantilever, plate, size_for_dofs

__all__ = ["ELEMENTS", "KINDS", "cantilever", "plate", "plate_structure", "size_for_dofs"]
