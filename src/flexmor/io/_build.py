"""The FE model of a reader: :func:`build_model` constructs it and reports a model the files
describe inconsistently (shapes, symmetry, non-finite values, a row without its diagonal
entry) against the file concerned."""

from __future__ import annotations

import numpy as np

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
        model = FEModel(**fields)
    except ModelError as exc:
        msg = str(exc)
        target = path
        words = {"M": "mass", "K": "stiffness", "D": "damping"}
        for name, p in (roles or {}).items():
            if msg.startswith((f"{name} ", f"{name}[", words.get(name, name))):
                target = p
                break
        raise ReadError(target, msg) from None
    for role in ("K", "M"):
        _check_diagonal(model, role, (roles or {}).get(role, path))
    return model


def _check_diagonal(model: FEModel, role: str, path) -> None:
    """Refuse a stiffness or mass row with off-diagonal entries but a zero (or missing) diagonal.

    FE stiffness and mass matrices are positive semidefinite: a zero diagonal entry forces
    its whole row to zero. A row that breaks this lost its diagonal entry (a file cut off or a
    line missing), or the file holds another matrix. Costs a look at the rows with a zero
    diagonal only.
    """
    A = getattr(model, role)
    zero = np.flatnonzero(A.diagonal() == 0)
    if zero.size == 0:
        return
    off = np.asarray(abs(A[zero]).sum(axis=1)).ravel()  # the diagonal is zero: all of it is off-diagonal
    bad = zero[off > 0]
    if bad.size:
        what = {"K": "stiffness", "M": "mass"}[role]
        more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
        raise ReadError(path, f"the {what} matrix has no diagonal entry at {model.describe_dof(int(bad[0]))}{more} "
                              "but entries beside it; an FE program writes one for every equation (the matrix is "
                              "positive semidefinite), so the file is cut off or lines are missing")
