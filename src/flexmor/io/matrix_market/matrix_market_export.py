"""Export of a reduced body as a Matrix Market set (``<base>_K.mtx``, ``<base>_M.mtx``, ``<base>_D.mtx``).

The files follow the naming rule of :mod:`flexmor.io.matrix_market`, so
:func:`~flexmor.io.matrix_market.read_matrix_market` reads them back as an FE model (without
nodes) with the same matrices.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .._registry import EXPORT_FORMATS
from ..atomic import atomic_write
from .matrix_market import _ROLE_NAME, _role_of

__all__ = ["write_matrix_market"]


def write_matrix_market(body, path, *, model=None) -> None:
    """Write a reduced body's ``Kr``, ``Mr`` (and ``Dr``) as a Matrix Market set, atomically.

    ``path`` names the set: ``body.mtx`` gives ``body_K.mtx``, ``body_M.mtx`` (``body_D.mtx``);
    a name that already ends in a stiffness tag (``body_K.mtx``) is used as the stiffness
    file. ``coordinate real symmetric`` (lower triangle), 17 significant digits: read back
    with :func:`read_matrix_market` the matrices are the same. ``model`` is not needed.
    """
    path = Path(path)
    readings = [rd for rd in _role_of(path.stem) if rd[0] == "K" and not rd[2]]
    base = readings[0][1] if readings else path.stem + "_"
    mats = {"K": body.K, "M": body.M}
    if body.D is not None:
        mats["D"] = body.D
    for role, A in mats.items():
        L = sp.tril(sp.csr_matrix(np.asarray(A, dtype=np.float64))).tocoo()
        lines = ["%%MatrixMarket matrix coordinate real symmetric",
                 f"% {_ROLE_NAME[role]} matrix of the reduced body {body.model_name} ({body.method})",
                 f"{L.shape[0]} {L.shape[1]} {L.nnz}"]
        lines += [f"{i + 1} {j + 1} {v!r}" for i, j, v in zip(L.row.tolist(), L.col.tolist(), L.data.tolist())]
        text = "\n".join(lines) + "\n"
        atomic_write(path.with_name(f"{base}{role}{path.suffix or '.mtx'}"),
                     lambda tmp, text=text: Path(tmp).write_text(text))


EXPORT_FORMATS.register("matrix-market", [".mtx"], write_matrix_market, aliases=["mtx"],
                        description="reduced body as a Matrix Market set <base>_K.mtx + <base>_M.mtx (+ _D.mtx)")
