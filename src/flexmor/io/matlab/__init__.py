"""MATLAB ``.mat``: FE matrices to read (:mod:`.matlab`), reduced bodies to export
(:mod:`.matlab_export`), and the structural check of MAT v5 files in front of SciPy's reader
(:mod:`._mat5`)."""

from .matlab import read_matlab
from .matlab_export import MAT_FIELDS, write_mat

__all__ = ["MAT_FIELDS", "read_matlab", "write_mat"]
