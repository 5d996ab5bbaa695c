"""Abaqus: ``*MATRIX GENERATE`` exports (:mod:`.abaqus`) and the input-deck parser shared with
CalculiX (:mod:`.abaqus_inp`: nodes, sets, element types, instances)."""

from .abaqus import MATRIX_FILE, read_abaqus
from .abaqus_inp import AbaqusDeck, read_deck

__all__ = ["MATRIX_FILE", "AbaqusDeck", "read_abaqus", "read_deck"]
