"""Abaqus: ``*MATRIX GENERATE`` exports (:mod:`.abaqus`) and the input-deck reader
(:mod:`.abaqus_inp`: nodes, sets, element types, instances), whose line syntax
(:mod:`flexmor.io._abaqus_syntax`) the CalculiX reader shares."""

from .abaqus import MATRIX_FILE, read_abaqus
from .abaqus_inp import AbaqusDeck, read_deck

__all__ = ["MATRIX_FILE", "AbaqusDeck", "read_abaqus", "read_deck"]
