"""Every 2 x 2 principal minor of a stiffness or mass matrix is non-negative.

A symmetric positive semidefinite matrix ``A`` satisfies ``A_ij^2 <= A_ii A_jj`` for every entry
(the minor of rows and columns ``i, j``). Stiffness and mass matrices of a structure are
positive semidefinite, so an entry larger than the geometric mean of its two diagonal entries
cannot come from an FE program: a value whose exponent or leading digits were changed
(``-3.9262820512820e+09`` read as ``-359262820512820e+09``), or an explicit zero turned into a
number. One pass over the stored entries. Stiffness: refused. Mass: refused, or a warning where the
deck's elements may give an indefinite mass (quadratic elements with row-sum lumping,
``FEModel.singular_mass_ok``). Entries may exceed the bound by the rounding of written values
(:data:`MINOR_RTOL`): a penalty coupling ``[[k, -k], [-k, k]]`` sits exactly on it.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from ..errors import FlexmorWarning, ReadError
from ._sparse import row_blocks

__all__ = ["check_minors", "MINOR_RTOL"]

#: Relative excess ``|A_ij| / sqrt(A_ii A_jj) - 1`` allowed for the rounding of written values.
MINOR_RTOL = 1e-6


def _worst(A) -> tuple[int, int, float, float] | None:
    """``(i, j, A_ij, sqrt(A_ii A_jj))`` of the entry with the largest excess over the bound, or None.

    One pass over the CSR arrays: ``|A_ij| / sqrt(A_ii A_jj)`` must not exceed ``1 + MINOR_RTOL``
    (the diagonal gives exactly 1); a zero diagonal with entries beside it is another check's.
    """
    A = sp.csr_matrix(A)
    d = np.abs(A.diagonal())
    with np.errstate(divide="ignore"):
        s = np.where(d > 0, 1.0 / np.sqrt(d), 0.0)
    best, m = 0.0, 0
    for start, stop in row_blocks(A):
        lo, hi = A.indptr[start], A.indptr[stop]
        if hi > lo:
            ratio = np.abs(A.data[lo:hi]) * s[A.indices[lo:hi]]
            ratio *= np.repeat(s[start:stop], np.diff(A.indptr[start:stop + 1]))
            k = int(np.argmax(ratio))
            if ratio[k] > best:
                best, m = float(ratio[k]), lo + k
    if best <= 1.0 + MINOR_RTOL:
        return None
    i = int(np.searchsorted(A.indptr, m, side="right")) - 1
    j = int(A.indices[m])
    return i, j, float(A.data[m]), float(np.sqrt(d[i] * d[j]))


def check_minors(model) -> None:
    """Refuse (``ReadError`` naming ``model.source``) a ``K`` or ``M`` with a 2 x 2 principal minor below zero.

    A mass matrix of a model that may have an indefinite mass (``singular_mass_ok``) gets a
    ``FlexmorWarning`` instead.
    """
    for name, A in (("stiffness", model.K), ("mass", model.M)):
        found = _worst(A)
        if found is None:
            continue
        i, j, v, bound = found
        msg = (f"the {name} matrix of this model: entry ({i + 1}, {j + 1}) = {v:.6g} exceeds "
               f"sqrt(diagonal {i + 1} x diagonal {j + 1}) = {bound:.6g} ({model.describe_dof(i)}, "
               f"{model.describe_dof(j)}): an entry no positive semidefinite matrix can hold; a changed value "
               "(a digit or an exponent)?")
        if name == "mass" and model.singular_mass_ok:
            warnings.warn(FlexmorWarning(f"{model.source or model.name}: {msg}"), stacklevel=3)
        else:
            raise ReadError(model.source or model.name, msg)
