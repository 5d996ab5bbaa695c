"""Reduction bases: the :class:`Basis` container and orthonormalization with deflation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Basis", "orthonormalize"]


@dataclass
class Basis:
    """A reduction basis ``V`` (n_dof, r) with the method that made it.

    Attributes
    ----------
    V : ndarray, shape (n_dof, r)
        Columns span the reduced space; ``q ≈ V q_r``.
    method : str
        Registered method name.
    info : dict
        Method parameters and diagnostics (JSON-serializable values), e.g. the number of
        rigid-body modes excluded or the interface size.
    """

    V: np.ndarray
    method: str
    info: dict = field(default_factory=dict)

    @property
    def order(self) -> int:
        return int(self.V.shape[1])


def orthonormalize(V: np.ndarray, M=None, *, tol: float = 1e-10, passes: int = 2) -> np.ndarray:
    """Orthonormalize the columns of ``V`` (w.r.t. ``M`` if given) and drop dependent ones.

    Uses the eigen-decomposition of the Gram matrix ``G = V^T M V`` (a Cholesky-QR variant
    that tolerates rank deficiency), repeated ``passes`` times for full accuracy. Columns
    whose Gram eigenvalue is below ``tol * max`` are deflated, so the result may have fewer
    columns than ``V``. Cost: O(n r^2), BLAS-3.
    """
    X = np.asarray(V, dtype=float)
    for _ in range(passes):
        MX = X if M is None else M @ X
        G = X.T @ MX
        G = 0.5 * (G + G.T)
        w, U = np.linalg.eigh(G)
        if w.size == 0 or w[-1] <= 0:
            return X[:, :0]
        keep = w > tol * w[-1]
        X = X @ (U[:, keep] / np.sqrt(w[keep]))
    return X
