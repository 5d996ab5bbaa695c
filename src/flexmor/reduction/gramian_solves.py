"""The solves of the Gramian quadrature: per node, in exact modal form, or by a verified surrogate.

The quadrature of :func:`flexmor.reduction.gramians.gramian_factors` needs
``X(w_k) = (K - w_k^2 M + i w_k D)^{-1} [B, C^T]`` at every node ``w_k`` (hundreds to
thousands of nodes). Three ways (``solves``) give them:

``direct``
    one complex sparse factorization per node (the reference; any model, any band);
``dense``
    small models: one dense eigendecomposition of ``(K, M)`` with proportional damping gives
    ``X(w) = Phi diag(1 / (lam - w^2 + i w d)) Phi^T [B, C^T]`` exactly (to round-off) at every
    node (:class:`flexmor.dynamics.dense_frf.DenseResolvent`);
``surrogate``
    larger models with a finite band: the Galerkin surrogate of
    :class:`flexmor.dynamics.surrogate.Surrogate` (the modes up to 1.1 ``fmax``, static and
    Krylov vectors of the modal pre-pass's factorization, rational Krylov enrichment by direct
    solves), built for the right-hand sides ``[B, C^T]`` with the *state* as output, so its
    checks measure ``||X(w) - V x(w)||_F / ||X(w)||_F``. The candidates of its greedy checks
    are the quadrature nodes; the residual at every node and a final direct check at the node
    of the largest residual are reported in ``info['solves']``.

With the dense and surrogate solves the quadrature factors are accumulated in the ``k``
coordinates of the basis ``V`` (the rank of the factors cannot exceed ``k``) and lifted once,
``R = V R_k``, so no ``N x (columns)`` store is ever compressed. The quadrature nodes and
weights are those of the direct solves, so the choices differ only by the error of the solves:
round-off for ``dense``, the reported surrogate error for ``surrogate``.

References
----------
Grimme, E. J. (1997). Krylov projection methods for model reduction. PhD thesis, University
of Illinois at Urbana-Champaign (rational Krylov interpolation).

Benner, P., Kürschner, P., Saak, J. (2016). Frequency-limited balanced truncation with
low-rank approximations. SIAM J. Sci. Comput. 38(1), A471-A499.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, check_choice
from ..linalg.context import step, track
from ..linalg.distributed import is_partitioned

__all__ = ["DENSE_GRAMIAN_MAX_DOF", "SOLVES", "SURROGATE_GRAMIAN_TOL", "choose_solves", "projected_factors"]

log = logging.getLogger(__name__)

#: Choices of ``gramian_factors(solves=...)`` (and the ``solves`` option of the Gramian methods).
SOLVES = ("auto", "direct", "dense", "surrogate")

#: Largest model (DOF) whose Gramian solves are ``dense`` under ``auto``. Measured with
#: ``bench/gramian_solves.py`` (cantilever, two tip inputs/outputs, band 10-3000 Hz, ~300 nodes):
#: dense 0.12 s against the surrogate's 0.16 s at 270 DOF, 0.32 s against 0.22 s at 405 DOF and
#: 0.93 s against 0.21 s at 540 DOF (the eigendecomposition and the factors in all ``n`` modal
#: coordinates grow ~n^3); the direct solves cost 0.9-1.8 s at these sizes.
DENSE_GRAMIAN_MAX_DOF = 300

#: Largest relative state error ``||X - V x||_F / ||X||_F`` accepted at the surrogate's checks;
#: below the quadrature's own error with the default 4 nodes per panel (~1e-5).
SURROGATE_GRAMIAN_TOL = 1e-6

#: Quadrature nodes per vectorized block of reduced solves (bounds the temporary arrays).
_CHUNK = 64


def choose_solves(solves: str, model, fmax: float) -> str:
    """The choice ``auto`` stands for: ``dense`` up to :data:`DENSE_GRAMIAN_MAX_DOF` DOF, ``surrogate``
    for a finite band, else ``direct``; explicit choices are returned as given."""
    check_choice("solves", solves, SOLVES)
    if solves != "auto":
        return solves
    if is_partitioned(model.K):
        return "direct"
    if model.n_dof <= DENSE_GRAMIAN_MAX_DOF:
        return "dense"
    return "surrogate" if math.isfinite(fmax) else "direct"


class _Dense:
    """Exact modal solutions of a small model with proportional damping (all modes)."""

    def __init__(self, work, rhs):
        from ..dynamics.dense_frf import DenseResolvent

        res = DenseResolvent(work.K, work.M, work.D)
        if res.kind != "modal":
            raise ModelError("non-proportional damping: no diagonal modal form")
        self.res, self.V = res, res.phi
        self.rhs = res.phi.T @ rhs
        self.info = {"solves": "dense", "order": int(res.phi.shape[1])}

    def solve(self, w):
        return self.res.pole_factors(w)[:, :, None] * self.rhs[None]


class _Projected:
    """Solutions of the verified surrogate of the state (see the module docstring)."""

    def __init__(self, work, rhs, nodes_hz, modes, solver):
        from ..dynamics.surrogate import Surrogate
        from ..ports import Ports

        phi, F, sigma = modes
        n, c = rhs.shape
        names = [f"rhs{j + 1}" for j in range(c)]
        state = Ports(B=sp.csr_matrix(rhs), C=sp.identity(n, format="csr"), input_names=names,
                      output_names=[""] * n)
        band = (float(nodes_hz.min()), float(nodes_hz.max()))
        sur = Surrogate(work, state, band, phi=phi, factorization=F, sigma=sigma, solver=solver,
                        tol=SURROGATE_GRAMIAN_TOL, candidates=nodes_hz)
        check = sur.verify(nodes_hz)
        sur.release()
        self.sur, self.V = sur, sur.V
        self.info = {"solves": "surrogate", **{k: v for k, v in check.items() if k != "checks"},
                     "n_direct_checks": len(check["checks"]),
                     "check_errors": [float(ch["rel_error"]) for ch in check["checks"]]}
        if not check["verified"]:
            log.warning("Gramian surrogate not verified: largest state error at the last checks %.1e > %.1e",
                        check["max_check_error"], SURROGATE_GRAMIAN_TOL)

    def solve(self, w):
        return self.sur.reduced_solution(w)


def projected_factors(solves: str, work, rhs, m: int, wk, wt, *, side: str, rigid_modes, modes, solver, store):
    """Quadrature factors ``R, Rv, L`` from the ``dense`` or ``surrogate`` solves.

    Parameters
    ----------
    solves : {'dense', 'surrogate'}
    work : FEModel
        The damped model (regularized when undamped).
    rhs : ndarray, shape (n_dof, m [+ p])
        ``B`` (and ``C^T``).
    m : int
        Number of inputs (the first ``m`` columns of ``rhs``).
    wk, wt : ndarray
        Quadrature nodes (rad/s) and weights.
    side : {'input', 'both'}
    rigid_modes : ndarray or None
        M-orthonormal rigid-body modes removed from the solutions.
    modes : tuple
        ``(phi, factorization, sigma)`` of the modal pre-pass (surrogate solves).
    solver : SolverContext
    store : callable
        ``store(n, limit)`` -> an empty factor store (:class:`flexmor.reduction.gramians._FactorStore`).

    Returns
    -------
    R, Rv, L : ndarray
        ``L`` None for ``side='input'``.
    info : dict
        ``solves``, ``order`` of the basis and, for the surrogate, its checks and residuals.
    """
    with step(solver.progress, f"Gramian solves: {solves} basis ({work.n_dof} DOF)"):
        basis = (_Dense(work, rhs) if solves == "dense"
                 else _Projected(work, rhs, wk / (2 * math.pi), modes, solver))
    V = basis.V
    if rigid_modes is not None and rigid_modes.shape[1]:
        V = V - rigid_modes @ (rigid_modes.T @ (work.M @ V))
    k = V.shape[1]
    stores = [store(k, max(4 * k, 256)) for _ in range(3 if side == "both" else 2)]
    for s0 in track(solver.progress, range(0, wk.size, _CHUNK), -(-wk.size // _CHUNK),
                    f"Gramian quadrature ({wk.size} nodes, {solves})"):
        w, weight = wk[s0:s0 + _CHUNK], wt[s0:s0 + _CHUNK]
        Y = basis.solve(w) * np.sqrt(weight / math.pi)[:, None, None]  # (nodes, k, columns)
        for j in range(w.size):
            Yr = np.hstack([Y[j, :, :m].real, Y[j, :, :m].imag])
            stores[0].add(Yr)
            stores[1].add(w[j] * Yr)
            if side == "both":
                stores[2].add(np.hstack([Y[j, :, m:].real, Y[j, :, m:].imag]))
    R, Rv = V @ stores[0].result(), V @ stores[1].result()
    L = V @ stores[2].result() if side == "both" else None
    log.info("Gramian solves: %s (basis of order %d)", solves, k)
    return R, Rv, L, basis.info
