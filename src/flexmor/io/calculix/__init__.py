"""CalculiX: matrix exports of ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` (:mod:`.calculix`) and
``.frd`` result files with the program's own modes (:mod:`.frd`); equation maps of jobs whose
shells and beams CalculiX expanded to solids (:mod:`.expanded`)."""

from .calculix import read_calculix, read_dof
from .deck import read_inp
from .frd import FrdResult, compare_modes, modes, read_frd

__all__ = ["FrdResult", "compare_modes", "modes", "read_calculix", "read_dof", "read_frd", "read_inp"]
