"""Frequency responses and the error measures of flexmor.

Conventions (the same everywhere in flexmor):

* frequencies ``f`` in **Hz**, ``s = i 2 pi f``;
* transfer matrix ``H(s) = C (s^2 M + s D + K)^{-1} B``;
* an FRF array has shape **(n_freq, n_outputs, n_inputs)**, complex.

Error measures (named exactly so in code, reports and JSON):

``rel_error(f)``
    ``||H(i2πf) - Ĥ(i2πf)||_F / ||H(i2πf)||_F`` pointwise on the grid;
``band_error``
    ``∫ ||H - Ĥ||_F^2 df / ∫ ||H||_F^2 df`` over the band (piecewise-parabolic rule on the grid);
``max_rel_error``
    ``max_f rel_error(f)``.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import OptionError
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..linalg.distributed import PartitionedMatrix, is_partitioned

__all__ = ["ShiftedMatrices", "frf_full", "frf_reduced", "rel_error", "band_error", "max_rel_error", "hinf_error",
           "band_grid", "error_measures"]

log = logging.getLogger(__name__)


def _omega(freqs) -> np.ndarray:
    f = np.atleast_1d(np.asarray(freqs, dtype=float))
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise OptionError("frequencies must be finite and >= 0 Hz")
    return 2 * np.pi * f


class ShiftedMatrices:
    """``A(w) = K - w^2 M + i w D`` for many ``w`` on one sparsity pattern.

    The data of ``K``, ``M`` and ``D`` are aligned once on the union of their patterns, so
    each frequency costs one vector operation over the non-zeros instead of sparse additions.

    Parameters
    ----------
    K, M : sparse matrix, shape (n, n)
    D : sparse matrix, optional
        Partitioned over MPI ranks (:class:`flexmor.linalg.distributed.PartitionedMatrix`) or
        not; ``A(w)`` is partitioned like ``K``.
    """

    def __init__(self, K, M, D=None):
        self.partitioned = is_partitioned(K)
        mats = [sp.csr_matrix(X.local if is_partitioned(X) else X) for X in (K, M, D) if X is not None]
        pattern = abs(mats[0])
        for X in mats[1:]:
            pattern = pattern + abs(X)
        pattern = sp.csr_matrix(pattern)
        pattern.sum_duplicates()
        pattern.sort_indices()
        self.indptr, self.indices, self.shape = pattern.indptr, pattern.indices, pattern.shape
        keys = self._keys(pattern)
        self.data = []
        for X in mats:
            X = X.copy()
            X.sum_duplicates()
            vals = np.zeros(pattern.nnz)
            vals[np.searchsorted(keys, self._keys(X))] = X.data
            self.data.append(vals)
        self.damped = D is not None

    @staticmethod
    def _keys(X) -> np.ndarray:
        rows = np.repeat(np.arange(X.shape[0], dtype=np.int64), np.diff(X.indptr))
        return rows * X.shape[1] + X.indices

    def __call__(self, w: float):
        """The matrix at angular frequency ``w`` (rad/s); complex when damped."""
        data = self.data[0] - w ** 2 * self.data[1]
        if self.damped:
            data = data + 1j * w * self.data[2]
        A = sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)
        return PartitionedMatrix(A) if self.partitioned else A


def frf_full(model, ports, freqs, *, solver: SolverContext | None = None,
             progress: Callable | None = None) -> np.ndarray:
    """Frequency response of the full sparse model, shape (n_freq, n_outputs, n_inputs).

    One factorization of ``K - w^2 M + i w D`` per frequency (complex symmetric when damped,
    real symmetric indefinite when ``D`` is None) and one block solve for all inputs.

    Parameters
    ----------
    model : FEModel
        The full model (``K``, ``M``, optional ``D``).
    ports : Ports
        Inputs ``B`` (n_dof, m) and outputs ``C`` (p, n_dof).
    freqs : array_like
        Frequencies in Hz.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.
    progress : callable, optional
        Called as ``progress(iterable, total)`` and must return an iterable (e.g. tqdm).

    Returns
    -------
    ndarray, shape (n_freq, n_outputs, n_inputs), complex
    """
    solver = as_solver(solver)
    w = _omega(freqs)
    B = ports.B.toarray()
    C = ports.C
    H = np.empty((w.size, C.shape[0], B.shape[1]), dtype=complex)
    if w.size == 0:
        return H
    A = ShiftedMatrices(model.K, model.M, model.D)
    it = range(w.size) if progress is None else progress(range(w.size), w.size)
    for k in it:
        F = factorize(A(w[k]), solver=solver, symmetric=True, check=False)
        H[k] = C @ F.solve(B)
        del F  # release the factors before the next frequency
    return H


def frf_reduced(red, freqs) -> np.ndarray:
    """Frequency response of a reduced body (dense, batched), shape (n_freq, n_outputs, n_inputs)."""
    w = _omega(freqs)
    A = red.K[None, :, :] - (w ** 2)[:, None, None] * red.M[None, :, :]
    A = A.astype(complex)
    if red.D is not None:
        A = A + (1j * w)[:, None, None] * red.D[None, :, :]
    X = np.linalg.solve(A, np.broadcast_to(red.B.astype(complex), (w.size, *red.B.shape)))
    return np.einsum("pr,frm->fpm", red.C, X)


def rel_error(H, Hr) -> np.ndarray:
    """Pointwise ``||H - Hr||_F / ||H||_F`` per frequency, shape (n_freq,)."""
    num = np.linalg.norm((H - Hr).reshape(H.shape[0], -1), axis=1)
    den = np.linalg.norm(H.reshape(H.shape[0], -1), axis=1)
    return num / np.where(den > 0, den, np.finfo(float).tiny)


def band_error(freqs, H, Hr) -> float:
    """``∫ ||H - Hr||_F^2 df / ∫ ||H||_F^2 df`` on the grid ``freqs``.

    Both integrals use the piecewise-parabolic rule of
    :func:`flexmor.analysis.grid.quadrature_weights` (third order on smooth integrands, exact
    for the trapezoidal limit of two points), unless its error integral differs from the
    trapezoidal rule's by more than a factor 2 (an unresolved, noisy error curve, where
    the parabolic rule's negative weights on graded grids are not safe): then both integrals
    use the trapezoidal rule. A single frequency gives the pointwise ratio.
    """
    from .grid import quadrature_weights

    f = np.asarray(freqs, float)
    e2 = np.sum(np.abs(H - Hr) ** 2, axis=(1, 2))
    h2 = np.sum(np.abs(H) ** 2, axis=(1, 2))
    if f.size < 2:
        return float(e2[0] / h2[0]) if h2.size and h2[0] > 0 else float("nan")
    w = quadrature_weights(f)
    d = np.diff(f) / 2
    wt = np.zeros_like(f)  # trapezoidal rule: positive weights
    wt[:-1] += d
    wt[1:] += d
    den, num = w @ h2, w @ e2
    num_t = wt @ e2
    if not (den > 0 and 0.5 * num_t <= num <= 2.0 * num_t):
        # the parabolic rule on a graded grid has negative weights; where the error is not a
        # resolved smooth curve (e.g. round-off noise of a nearly exact body) it can then be far
        # off, even below max_rel_error^2: the positive trapezoidal rule is used instead
        den, num = wt @ h2, num_t
    return float(num / den) if den > 0 else float("nan")


def max_rel_error(H, Hr) -> float:
    """``max_f rel_error(f)``."""
    return float(np.max(rel_error(H, Hr)))


def hinf_error(H, Hr) -> float:
    """Band-limited relative H-infinity error estimate ``max_f σ_max(H - Hr) / max_f σ_max(H)``.

    Evaluated on the grid of ``H`` (which is refined at the resonances, where the maxima
    lie); a lower bound of the true band-limited value, exact up to the grid resolution.
    """
    num = np.linalg.norm(H - Hr, ord=2, axis=(1, 2)).max()
    den = np.linalg.norm(H, ord=2, axis=(1, 2)).max()
    return float(num / den) if den > 0 else float("nan")


def error_measures(freqs, H, Hr) -> dict:
    """All error measures of one reduced body as a JSON-ready dict:
    ``band_error``, ``max_rel_error``, ``hinf_error``."""
    return {"band_error": band_error(freqs, H, Hr), "max_rel_error": max_rel_error(H, Hr),
            "hinf_error": hinf_error(H, Hr)}


def band_grid(fmin: float, fmax: float, *, n: int = 200, resonances=None, zeta: float | None = None) -> np.ndarray:
    """Frequency grid in Hz for error integration over ``[fmin, fmax]``.

    ``n`` log-spaced points, plus points clustered around each resonance in the band so
    that peaks are resolved: with modal damping ratio ``zeta`` at offsets
    ``±{0.25, 0.5, 1, 2, 4} * zeta * f_k`` (the half-power bandwidth is ``2 zeta f_k``);
    without damping at relative offsets ``±{1e-3, 3e-3, 1e-2, 3e-2}`` (undamped peaks are
    infinite at ``f_k``, which is never itself a grid point).

    Parameters
    ----------
    fmin, fmax : float
        Band in Hz, ``0 < fmin < fmax``.
    n : int
        Number of log-spaced base points.
    resonances : array_like, optional
        Eigenfrequencies (Hz) of the full model; those inside the band get refinement.
    zeta : float or array_like, optional
        Modal damping ratio (one, or one per resonance) used to size the refinement.
    """
    if not (np.isfinite(fmin) and np.isfinite(fmax)) or fmin <= 0 or fmax <= fmin:
        raise OptionError(f"band must satisfy 0 < FMIN < FMAX (Hz), got {fmin}:{fmax}")
    pts = [np.geomspace(fmin, fmax, int(n))]
    if resonances is not None:
        res = np.atleast_1d(np.asarray(resonances, float))
        zetas = np.broadcast_to(np.asarray(0.0 if zeta is None else zeta, float), res.shape)
        for fk, zk in zip(res, zetas):
            rel = np.array([0.25, 0.5, 1, 2, 4]) * zk if zk > 0 else np.array([1e-3, 3e-3, 1e-2, 3e-2])
            rel = rel[rel < 0.5]
            if fmin < fk < fmax:
                pts.append(fk * (1 - rel))
                pts.append(fk * (1 + rel))
    f = np.unique(np.concatenate(pts))
    return f[(f >= fmin) & (f <= fmax)]
