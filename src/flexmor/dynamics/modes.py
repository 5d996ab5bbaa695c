"""The modal pre-pass: eigenfrequencies and modes of a full model up to a frequency.

The error grid (:class:`flexmor.analysis.compare.FullResponse`) places points at the
resonances it finds, and the band-limited Gramians (:mod:`flexmor.reduction.gramians`) put
one quadrature cell at each; both use :func:`modes_below` and the damping ratios of
:func:`modal_damping_ratios`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..damping import Damping
from ..errors import FlexmorError
from ..linalg import factorize
from ..linalg.backends import MEMORY_FRACTION
from ..linalg.context import SolverContext
from ..linalg.eigen import default_shift, eigenmodes, frequencies_hz
from ..linalg.factorize import factorize_shifted
from ..linalg.threads import sparse_dense

__all__ = ["PrePass", "modal_damping_ratios", "modes_below"]


def modal_damping_ratios(damping: Damping, freqs_hz, phi=None, D=None) -> np.ndarray | None:
    """Modal damping ratios of the modes with eigenfrequencies ``freqs_hz``.

    Rayleigh damping gives ``zeta = alpha/(2w) + beta w/2``; another damping matrix ``D``
    with mass-normalized modes ``phi`` gives ``zeta_k = phi_k^T D phi_k / (2 w_k)`` (exact
    for proportional damping, the diagonal approximation otherwise); else None.
    """
    z = damping.ratios(freqs_hz)
    if z is not None:
        return z
    w = 2 * np.pi * np.maximum(np.asarray(freqs_hz, float), 1e-30)
    if D is not None and phi is not None:
        return np.einsum("ij,ij->j", phi, sparse_dense(D, phi)) / (2 * w)
    return None


@dataclass
class PrePass:
    """The modal pre-pass of :func:`modes_below`.

    Attributes
    ----------
    f : ndarray
        Eigenfrequencies (Hz), ascending (rigid-body modes included, at about 0 Hz).
    phi : ndarray, shape (n_dof, len(f))
        Mass-normalized modes.
    factorization : Factorization or None
        The factorization of ``K - sigma M`` (None for small dense problems), reused by the
        surrogate of :mod:`flexmor.dynamics.surrogate`.
    sigma : float
        Its shift.
    edge : tuple or None
        ``(factorization, shift)`` of the inertia count, ``K - shift M`` with ``shift`` at the
        highest frequency wanted, when kept (:meth:`take_edge`).
    complete : bool
        The modes are all of the model's up to the highest frequency wanted: as many as the
        inertia count found, or all modes of a dense eigendecomposition.
    """

    f: np.ndarray
    phi: np.ndarray
    factorization: object | None
    sigma: float
    edge: tuple | None = None
    complete: bool = False

    def take_edge(self) -> tuple | None:
        """The edge factorization, no longer referenced here (its memory goes with the caller's last reference)."""
        edge, self.edge = self.edge, None
        return edge


def modes_below(model, fmax: float, solver: SolverContext, max_modes: int = 400, keep_edge: bool = False) -> PrePass:
    """Modal pre-pass: eigenfrequencies and mass-normalized modes up to ``fmax``.

    Above the solver's dense limit (``solver.eigen.dense_limit``) the number of modes below
    ``fmax`` is counted first (inertia of one factorization of ``K - (2 pi fmax)^2 M``), then the
    modes come from one shift-invert factorization of ``K - sigma M``: the one ``solver`` keeps for
    these matrices (e.g. ``K_ii`` of a fixed-interface body, factorized for the constraint modes:
    ``sigma = 0``), else one at the default shift.

    Parameters
    ----------
    model : FEModel
        The full model (``K``, ``M``).
    fmax : float
        Highest eigenfrequency (Hz) wanted.
    solver : SolverContext
        Solver (backend, statistics, eigen policy) of :func:`flexmor.linalg.factorize`.
    max_modes : int
        Upper limit of the number of modes computed.
    keep_edge : bool
        Keep the count's factorization in :attr:`PrePass.edge` (when two more of its size fit in
        the memory available): the surrogate's Krylov vectors at the band's end come from it.

    Returns
    -------
    PrePass
        Modes up to ``fmax``.
    """
    sigma = solver.kept_shift(model.K, model.M)  # a factorization kept for these matrices serves the pre-pass
    if sigma is None:
        sigma = default_shift(model.K, model.M)
    F, edge, below = None, None, None
    k = min(model.n_dof, 20)
    dense = model.n_dof <= solver.eigen.dense_limit
    if not dense:  # count first
        below, edge = _count_below(model, fmax, solver, keep_edge)
        k = k if below is None else min(model.n_dof, max(below, 1))  # as many as counted
        F = factorize_shifted(model.K, model.M, sigma, solver=solver)
    while True:
        lam, phi = eigenmodes(model.K, model.M, k, sigma=sigma, factorization=F, solver=solver)
        f = frequencies_hz(lam)
        keep = f <= fmax
        counted = below is not None and int(keep.sum()) == below
        if counted or f[-1] > fmax or k >= min(model.n_dof, max_modes):
            complete = counted or (dense and (f[-1] > fmax or k >= model.n_dof))  # dense: every mode up to f[-1]
            return PrePass(f[keep], phi[:, keep], F, sigma, edge, bool(complete))
        # the next k from the density of modes found so far (+15 %), at least 8 more
        k = min(model.n_dof, max_modes, max(k + 8, int(np.ceil(1.15 * k * fmax / max(f[-1], 1e-30)))))


def _count_below(model, fmax: float, solver: SolverContext, keep: bool = False):
    """Number of eigenfrequencies below ``fmax`` from the inertia of ``K - w^2 M``, and that factorization.

    One real symmetric indefinite factorization (Sylvester's law of inertia) replaces the
    guessing of the number of modes; the count is None when the backend does not report the
    inertia. The factorization is returned as ``(F, w^2)`` when ``keep`` and two more of its size
    fit in the memory available (the pre-pass's own and a check's), else None: by default only
    one large factorization is alive at a time.
    """
    shift = (2 * np.pi * fmax) ** 2
    try:
        F = factorize((model.K - shift * model.M).tocsr(), solver=solver, symmetric=True, check=False)
    except FlexmorError:  # the backends report every failure so (e.g. fmax exactly at an eigenvalue): guess
        return None, None
    est, avail = F.memory_estimate, solver.memory_available()
    kept = (F, shift) if keep and est and avail and 2 * est <= MEMORY_FRACTION * avail else None
    return (None if F.inertia is None else int(F.inertia[1])), kept
