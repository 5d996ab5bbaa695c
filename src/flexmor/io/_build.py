"""The FE model of a reader: :func:`build_model` constructs it and reports a model the files
describe inconsistently (shapes, symmetry, non-finite values) against the file concerned."""

from __future__ import annotations

from ..errors import ModelError, ReadError
from ..model import FEModel

__all__ = ["build_model"]


def build_model(path, roles: dict | None = None, **fields):
    """Construct a :class:`~flexmor.model.FEModel`, turning ModelError into ReadError.

    Parameters
    ----------
    path : str or path-like
        The main file, named in the error.
    roles : dict of str to path, optional
        File of each matrix (``{"M": mass_path, ...}``): a ModelError whose message starts
        with that matrix name (or ``mass``, ``stiffness``, ``damping``) is reported against
        that file.
    **fields
        Passed to ``FEModel``.
    """
    try:
        return FEModel(**fields)
    except ModelError as exc:
        msg = str(exc)
        target = path
        words = {"M": "mass", "K": "stiffness", "D": "damping"}
        for name, p in (roles or {}).items():
            if msg.startswith((f"{name} ", f"{name}[", words.get(name, name))):
                target = p
                break
        raise ReadError(target, msg) from None
