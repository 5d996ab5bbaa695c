"""Frequency responses of full and reduced second-order bodies.

Conventions (the same everywhere in flexmor):

* frequencies ``f`` in **Hz**, ``s = i 2 pi f``;
* transfer matrix ``H(s) = C (s^2 M + s D + K)^{-1} B``;
* an FRF array has shape **(n_freq, n_outputs, n_inputs)**, complex.

Both reduction methods (greedy point selection, Gramian quadrature) and the error analysis
(:mod:`flexmor.analysis`) evaluate responses here. The pointwise ``rel_error`` of two FRF
arrays lives here too, since a greedy method uses it as its estimate; the band measures
built on it are in :mod:`flexmor.analysis.frequency`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import OptionError, real_finite
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..linalg.distributed import PartitionedMatrix, is_partitioned
from ..linalg.threads import sparse_dense

__all__ = ["ShiftedMatrices", "angular_frequency", "check_freqs", "frf_full", "frf_reduced", "frf_matrices",
           "rel_error"]


def check_freqs(freqs, name: str = "freqs") -> np.ndarray:
    """Frequencies ``f`` in Hz checked to be real, finite and >= 0, shape (n_freq,); an :class:`OptionError`
    naming ``name`` otherwise (a complex frequency too: the FRF is taken at ``s = i 2 pi f``, ``f`` real)."""
    f = np.atleast_1d(real_finite(freqs, name, "frequencies in Hz (real numbers)"))
    if f.ndim != 1 or np.any(f < 0):
        raise OptionError(f"{name} must be frequencies >= 0 in Hz, one list, got shape {np.shape(freqs)}"
                          + (f", the value {f.min():g}" if f.size and f.min() < 0 else ""), params=(name,))
    return f


def angular_frequency(freqs, name: str = "freqs") -> np.ndarray:
    """``2 pi f`` (rad/s) of frequencies ``f`` in Hz (:func:`check_freqs`, naming ``name``), shape (n_freq,)."""
    return 2 * np.pi * check_freqs(freqs, name)


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
        mats = [_canonical(X.local if is_partitioned(X) else X) for X in (K, M, D) if X is not None]
        first = mats[0]
        if all(_same_pattern(first, X) for X in mats[1:]):  # one pattern (e.g. K, M and a Rayleigh D): as it is
            pattern = first
        else:
            pattern = abs(first)
            for X in mats[1:]:
                pattern = pattern + abs(X)
            pattern = _canonical(pattern)
        self.indptr, self.indices, self.shape = pattern.indptr, pattern.indices, pattern.shape
        keys = None
        self.data = []
        for X in mats:
            if _same_pattern(pattern, X):
                self.data.append(X.data)
                continue
            keys = self._keys(pattern) if keys is None else keys
            vals = np.zeros(pattern.nnz, dtype=X.dtype)
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


def _canonical(X) -> sp.csr_matrix:
    """``X`` as CSR with sorted indices and no duplicates (a copy only where it is not so already)."""
    X = sp.csr_matrix(X)
    if not X.has_canonical_format:
        X = X.copy()
        X.sum_duplicates()
    return X


def _same_pattern(A, B) -> bool:
    """Whether two canonical CSR matrices store the same positions."""
    return A.shape == B.shape and A.nnz == B.nnz and np.array_equal(A.indptr, B.indptr) \
        and np.array_equal(A.indices, B.indices)


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
    w = angular_frequency(freqs)
    B = ports.B.toarray()
    C = ports.C
    H = np.empty((w.size, C.shape[0], B.shape[1]), dtype=complex)
    if w.size == 0:
        return H
    A = ShiftedMatrices(model.K, model.M, model.D)
    rigid = _rigid_part(model, B, C)
    rhs = B if rigid is None else rigid.elastic_loads
    it = range(w.size) if progress is None else progress(range(w.size), w.size)
    for k in it:
        if rigid is not None and w[k] == 0:  # a free body's rigid motion under a static load: unbounded
            H[k] = np.inf
            continue
        F = factorize(A(w[k]), solver=solver, symmetric=True, check=False)
        X = F.solve(rhs)
        del F  # release the factors before the next frequency
        H[k] = C @ X if rigid is None else rigid.response(X, w[k])
    return H


class _RigidPart:
    """A free body's FRF as its rigid part, exactly, plus its elastic part (see :func:`_rigid_part`)."""

    def __init__(self, model, phi, B, C):
        from ..rigid import elastic_loads

        self.model, self.phi, self.C = model, phi, C
        self.elastic_loads = elastic_loads(model, phi, B)  # (I - M Φ Φᵀ) B
        self.C_phi, self.phi_B = np.asarray(C @ phi), phi.T @ B
        D = model.D
        self.D_r = np.zeros((phi.shape[1],) * 2) if D is None else phi.T @ sparse_dense(D, phi)

    def response(self, X, w: float) -> np.ndarray:
        """``C (I - Φ Φᵀ M) X + C Φ (-w² I + i w Φᵀ D Φ)⁻¹ Φᵀ B`` for ``X = A(w)⁻¹ (I - M Φ Φᵀ) B``."""
        from ..rigid import m_project

        k = self.phi.shape[1]
        return (self.C @ m_project(self.model, self.phi, X)
                + self.C_phi @ np.linalg.solve(-w * w * np.eye(k) + 1j * w * self.D_r, self.phi_B))


def _rigid_part(model, B, C):
    """For a free body with damping that its rigid-body modes ``Φ`` uncouple (none, Rayleigh, modal): the
    rigid part ``C Φ (s² + s ΦᵀDΦ)⁻¹ Φᵀ B`` is exact, and the elastic part is solved with the loads and the
    response projected off ``Φ``. Solved whole, ``K - w² M`` is singular up to the rounding of ``K``'s null
    space, whose eigenvalues (``~1e-4 rad²/s²`` on the free CalculiX beam) put spurious poles near 0.002 Hz and
    an error ``~ λ / w²`` into the rigid response (6e-6 at 1 Hz). None otherwise (a supported body, another
    damping, a model over MPI ranks)."""
    from ..damping import NoDamping, Rayleigh
    from ..rigid import rigid_body_modes

    if is_partitioned(model.K) or model.dofs is None:
        return None
    if model.D is not None and not isinstance(model.damping, (Rayleigh, NoDamping)):
        return None
    phi = rigid_body_modes(model)
    return _RigidPart(model, phi, B, C) if phi.shape[1] else None


def frf_reduced(body, freqs, *, name: str = "freqs") -> np.ndarray:
    """Frequency response of a reduced body (dense, batched), shape (n_freq, n_outputs, n_inputs);
    ``name`` is the parameter an error about ``freqs`` names."""
    return frf_matrices(body.K, body.M, body.D, body.B, body.C, angular_frequency(freqs, name))


def frf_matrices(K, M, D, B, C, w) -> np.ndarray:
    """``C (K - w^2 M + i w D)^{-1} B`` of small dense matrices at the angular frequencies ``w`` (rad/s), batched;
    ``D`` may be None. Shape (n_freq, n_outputs, n_inputs)."""
    w = np.asarray(w, dtype=float)
    A = (K[None, :, :] - (w ** 2)[:, None, None] * M[None, :, :]).astype(complex)
    if D is not None:
        A = A + (1j * w)[:, None, None] * D[None, :, :]
    X = np.linalg.solve(A, np.broadcast_to(np.asarray(B).astype(complex), (w.size, *np.shape(B))))
    return np.einsum("pr,frm->fpm", C, X)


def rel_error(H, Hr) -> np.ndarray:
    """Pointwise ``||H - Hr||_F / ||H||_F`` per frequency, shape (n_freq,)."""
    num = np.linalg.norm((H - Hr).reshape(H.shape[0], -1), axis=1)
    den = np.linalg.norm(H.reshape(H.shape[0], -1), axis=1)
    return num / np.where(den > 0, den, np.finfo(float).tiny)
