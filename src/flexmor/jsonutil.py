"""Conversion of results (NumPy arrays and scalars, nested dicts) to JSON-ready values."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["jsonable"]


def jsonable(x, *, finite: bool = False):
    """Recursively turn arrays into lists and NumPy scalars into Python ones.

    With ``finite=True`` NaN and Inf become ``None`` (strict JSON has no NaN).
    """
    if hasattr(x, "to_dict"):  # typed values stored in their dict form (e.g. flexmor.damping.Damping)
        x = x.to_dict()
    if isinstance(x, dict):
        return {str(k): jsonable(v, finite=finite) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, finite=finite) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist(), finite=finite)
    if isinstance(x, np.generic):
        x = x.item()
    if finite and isinstance(x, float) and not math.isfinite(x):
        return None
    return x
