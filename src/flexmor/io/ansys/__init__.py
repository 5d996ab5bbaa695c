"""Ansys: HBMAT/MMF matrix exports with mapping vector and coordinates, or binary ``.full`` files."""

from .ansys import read_ansys, read_coordinates, read_mapping

__all__ = ["read_ansys", "read_coordinates", "read_mapping"]
