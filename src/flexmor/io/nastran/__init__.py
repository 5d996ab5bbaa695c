"""Nastran: DMIG punch and OP4 matrices with the bulk data's grids (an FE model), and
Craig-Bampton superelements (a reduced body), and reduced bodies written as superelements.

Modules: :mod:`.nastran` (the FE-model reader), :mod:`.nastran_bulk` (GRID/CORD/SET cards),
:mod:`.nastran_grids` (runs of GRID cards as one block), :mod:`.op4` (OUTPUT4 files),
:mod:`.nastran_se` (superelements), :mod:`.nastran_export` (DMIG punch and OP4 export).
"""

from .nastran import read_dmig, read_nastran
from .nastran_bulk import cards, read_bulk
from .nastran_export import write_dmig, write_op4
from .nastran_se import is_superelement, read_superelement
from .op4 import read_op4

__all__ = ["cards", "is_superelement", "read_bulk", "read_dmig", "read_nastran", "read_op4", "read_superelement",
           "write_dmig", "write_op4"]
