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
    Krylov vectors of the modal pre-pass's factorization, rational Krylov enrichment by the checks'
    solves), built for the right-hand sides ``[B, C^T]`` with the *state* as output, so its
    checks measure ``||X(w) - V x(w)||_F / ||X(w)||_F``. The candidates of its greedy checks
    are the quadrature nodes; the residual at every node and a final check at the node
    of the largest residual are reported in ``info['solves']``.

The full band ``[0, inf)`` (``sobt``) with the surrogate ends at the cutoff (the modes of the
pre-pass reach it): the part of the Gramians above is positive semi-definite, and with Rayleigh
damping its trace has a bound from the pre-pass's modes and one static solve
(:func:`tail_share`), reported in ``info['tail']`` as a share of each Gramian's trace.

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

from ..damping import Rayleigh
from ..errors import ModelError, check_choice
from ..linalg import factorize
from ..linalg.context import step, track
from ..linalg.distributed import is_partitioned
from ..linalg.threads import sparse_dense
from ..rigid import m_project
from ._options import SOLVES

__all__ = ["DENSE_GRAMIAN_MAX_DOF", "SURROGATE_GRAMIAN_TOL", "choose_solves", "projected_factors",
           "tail_boundable", "tail_share"]

log = logging.getLogger(__name__)

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
    for a finite band or a full band whose tail can be bounded (:func:`tail_boundable`), else
    ``direct``; explicit choices are returned as given."""
    check_choice("solves", solves, SOLVES)
    if solves != "auto":
        return solves
    if is_partitioned(model.K):
        return "direct"
    if model.n_dof <= DENSE_GRAMIAN_MAX_DOF:
        return "dense"
    return "surrogate" if math.isfinite(fmax) or tail_boundable(model) else "direct"


def tail_boundable(model) -> bool:
    """Whether the full band's tail above a cutoff has the bound of :func:`tail_share`: Rayleigh damping
    ``D = alpha M + beta K`` with ``beta > 0`` (an undamped model gets such a damping for its Gramians)."""
    return model.D is None or (isinstance(model.damping, Rayleigh) and model.damping.beta > 0)


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

        n, c = rhs.shape
        names = [f"rhs{j + 1}" for j in range(c)]
        state = Ports(B=sp.csr_matrix(rhs), C=sp.identity(n, format="csr"), input_names=names,
                      output_names=[""] * n)
        band = (float(nodes_hz.min()), float(nodes_hz.max()))
        sur = Surrogate(work, state, band, phi=modes.phi, factorization=modes.factorization, sigma=modes.sigma,
                        solver=solver, tol=SURROGATE_GRAMIAN_TOL, candidates=nodes_hz, edge=modes.take_edge(),
                        complete=modes.complete)
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


def _columns(Y: np.ndarray) -> np.ndarray:
    """The blocks ``Y[j]`` (nodes, k, c) side by side: shape (k, nodes c)."""
    return Y.transpose(1, 0, 2).reshape(Y.shape[1], -1)


def tail_share(work, rhs, m: int, wk, wt, modes, solver, traces) -> dict:
    """Bound of the Gramians' part above the last quadrature node (the full band's tail), relative.

    With M-orthonormal modes ``phi_j``, ``b_j = phi_j^T rhs`` and Rayleigh damping
    ``d_j = alpha + beta lam_j``, the M-trace of the tail ``E = (1/pi) int_wc^inf Re(X X^H) dw``
    is ``sum_j |b_j|^2 e_j`` with ``e_j = (1/pi) int_wc^inf |lam_j - w^2 + i w d_j|^-2 dw`` (times
    ``w^2`` for velocities). For the modes of the pre-pass, ``e_j`` is the exact full integral
    ``1/(2 d_j lam_j)`` (velocities ``1/(2 d_j)``) minus the quadrature's part below ``wc``. For
    the modes above them (``lam_j >= lam_H``, the largest known) ``e_j <= 1/(2 beta lam_j^2)``
    (``1/(2 beta lam_j)``), and ``sum |b_j|^2 / (lam_j - sigma)^p`` over them is the whole sum,
    ``tr(S^T M S)`` or ``tr(rhs^T S)`` with the static solution ``S = (K - sigma M)^{-1} rhs`` of
    the pre-pass factorization, minus the known modes' terms. ``E`` is positive semi-definite,
    so the Gramian without its tail is off by at most this trace.

    Parameters
    ----------
    work : FEModel
        The damped model (Rayleigh damping, ``beta > 0``).
    rhs : ndarray, shape (n_dof, m [+ p])
    m : int
        Number of inputs.
    wk, wt : ndarray
        Quadrature nodes (rad/s, the last one below ``wc``) and weights.
    modes : PrePass
        The modal pre-pass (:class:`flexmor.dynamics.modes.PrePass`, rigid-body modes included).
    solver : SolverContext
    traces : dict
        M-traces of the computed factors, ``{'position', 'velocity'[, 'observability']}``.

    Returns
    -------
    dict
        ``cutoff_hz``, ``known_modes`` and per Gramian (``position``, ``velocity``, ``observability``)
        the bound of ``tr(M E) / tr(M (P + E))``.
    """
    from ..linalg.eigen import is_rigid

    phi, F, sigma = modes.phi, modes.factorization, modes.sigma
    alpha, beta = work.damping.alpha, work.damping.beta
    if F is None:
        F = factorize((work.K - sigma * work.M).tocsr(), solver=solver, positive=sigma < 0)
    S = F.solve(rhs)
    lam = np.einsum("ij,ij->j", phi, sparse_dense(work.K, phi))
    b2 = (phi.T @ rhs) ** 2  # (modes, columns)
    flex = ~is_rigid(lam, work.K, work.M)
    lf, d = lam[flex], alpha + beta * lam[flex]
    inv = 1.0 / ((lf[:, None] - wk ** 2) ** 2 + (wk * d[:, None]) ** 2)
    known = {"position": np.maximum(1 / (2 * d * lf) - inv @ wt / math.pi, 0.0),
             "velocity": np.maximum(1 / (2 * d) - inv @ (wt * wk ** 2) / math.pi, 0.0)}
    lam_h = float(lam.max())
    grow = (lam_h - sigma) / lam_h
    rest = {"position": (np.einsum("ij,ij->j", S, sparse_dense(work.M, S)) - (b2 / (lam - sigma)[:, None] ** 2).sum(0))
            * max(1.0, grow ** 2),
            "velocity": (np.einsum("ij,ij->j", rhs, S) - (b2 / (lam - sigma)[:, None]).sum(0)) * max(1.0, grow)}
    cols = {"position": slice(0, m), "velocity": slice(0, m), "observability": slice(m, None)}
    out = {"cutoff_hz": float(wk.max() / (2 * math.pi)), "known_modes": int(flex.sum())}
    for name, tr in traces.items():
        kind = "velocity" if name == "velocity" else "position"
        c = cols[name]
        e = float(known[kind] @ b2[flex, c].sum(1) + max(float(rest[kind][c].sum()), 0.0) / (2 * beta))
        out[name] = e / (tr + e) if tr + e > 0 else 0.0
    return out


def projected_factors(solves: str, work, rhs, m: int, wk, wt, *, side: str, rigid_modes, modes, solver, store,
                      tail: bool = False):
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
    modes : PrePass
        The modal pre-pass (:class:`flexmor.dynamics.modes.PrePass`; surrogate solves: its edge
        factorization is taken and freed once the surrogate's basis is built).
    solver : SolverContext
    store : callable
        ``store(n, limit)`` -> an empty factor store (:class:`flexmor.reduction.gramians._FactorStore`).
    tail : bool
        The nodes end at a cutoff below the full band's end: report the bound of the rest
        (:func:`tail_share`) in ``info['tail']``.

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
        V = m_project(work, rigid_modes, V)
    k = V.shape[1]
    stores = [store(k, max(4 * k, 256)) for _ in range(3 if side == "both" else 2)]
    for s0 in track(solver.progress, range(0, wk.size, _CHUNK), -(-wk.size // _CHUNK),
                    f"Gramian quadrature ({wk.size} nodes, {solves})"):
        w, weight = wk[s0:s0 + _CHUNK], wt[s0:s0 + _CHUNK]
        Y = basis.solve(w) * np.sqrt(weight / math.pi)[:, None, None]  # (nodes, k, columns)
        # per node the real and imaginary parts side by side, all nodes of the chunk in one block
        Yr = np.concatenate([Y[:, :, :m].real, Y[:, :, :m].imag], axis=2)  # (nodes, k, 2 m)
        stores[0].add(_columns(Yr))
        stores[1].add(_columns(w[:, None, None] * Yr))
        if side == "both":
            stores[2].add(_columns(np.concatenate([Y[:, :, m:].real, Y[:, :, m:].imag], axis=2)))
    R, Rv = V @ stores[0].result(), V @ stores[1].result()
    L = V @ stores[2].result() if side == "both" else None
    info = basis.info
    if tail:
        traces = {name: float(np.einsum("ij,ij->", X, sparse_dense(work.M, X)))
                  for name, X in (("position", R), ("velocity", Rv), ("observability", L)) if X is not None}
        info["tail"] = tail_share(work, rhs, m, wk, wt, modes, solver, traces)
        log.info("Gramians up to %.4g Hz: the tail above is at most %.1e (position), %.1e (velocity) of the trace",
                 info["tail"]["cutoff_hz"], info["tail"]["position"], info["tail"]["velocity"])
    log.info("Gramian solves: %s (basis of order %d)", solves, k)
    return R, Rv, L, info
