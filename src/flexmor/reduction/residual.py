"""Residual vectors: the static response to the body's loads added to any method's basis.

A basis built for the band (modal, balanced truncation, POD ...) can miss the static response: a body
within 1e-6 over the band can sag 1 % wrong. ``reduce(..., residual_vectors=True)`` (``flexmor reduce
--residual-vectors``) appends the static responses ``K^-1 F`` to

* the inputs ``B``,
* the frame's six accelerations ``M R`` (:func:`flexmor.reduction.free_body.with_inertia_loads`; on a free
  body the same accelerations of the body held at each coupling master, :func:`interface_loads`),
* unit loads at each coupling master's equations (a supported body),

made M-orthogonal to the method's basis and M- and K-orthogonal to each other (their pseudo-modes lie
above the band), counted in the order: the method builds ``order - p`` vectors (``p`` the rank of the
static responses), the residual vectors fill the rest; where the method's basis holds some of them already
(krylov's 0 Hz point holds the inputs'), the method is built once more with their share of the order.
A free body's static response is the inertia-relief one (its loads made self-equilibrated,
``(I - M Φ Φᵀ) F``; :func:`flexmor.reduction.free_body.inertia_relief`).

This is modal truncation augmentation (Dickens, Nakagawa, Wittbrodt 1997) and the static completion of
Craig-Chang's residual flexibility, for every method.
"""

from __future__ import annotations

import numpy as np

from ..basis import Basis
from ..errors import OptionError
from ..linalg import factorize
from ..linalg.context import SolverContext, as_solver
from ..linalg.threads import sparse_dense
from ..rigid import rigid_body_modes

__all__ = ["residual_loads", "static_solve", "static_responses", "with_residual_vectors", "residual_order",
           "RESIDUAL_TOL"]

#: Relative size (in the M-norm, after removing the basis) below which a residual vector adds nothing.
RESIDUAL_TOL = 1e-8


def residual_loads(model, ports) -> np.ndarray:
    """The loads whose static response the residual vectors hold (dense, n_dof x p): the inputs, the
    frame's six accelerations (a free body: held at each coupling master) and, on a supported body, unit
    loads at each coupling master's equations."""
    from ..couplings import coupling_masters
    from .free_body import with_inertia_loads

    loaded, _ = with_inertia_loads(model, ports, "on")
    F = [loaded.B.toarray()]
    if model.dofs is not None and not rigid_body_modes(model).shape[1]:
        for master in coupling_masters(model):
            eqs = np.flatnonzero(model.dofs[:, 0] == master["id"])
            E = np.zeros((model.n_dof, eqs.size))
            E[eqs, np.arange(eqs.size)] = 1.0
            F.append(E)
    return np.hstack(F)


def static_solve(model, F, phi, solver: SolverContext) -> np.ndarray:
    """``K^-1 F`` of a supported model; a free one's inertia-relief response
    (:func:`flexmor.reduction.free_body.inertia_relief`)."""
    if not phi.shape[1]:
        return factorize(model.K.tocsr(), solver=solver, positive=True).solve(F)
    from .free_body import inertia_relief

    return inertia_relief(model, F, phi=phi, solver=solver)


def static_responses(model, ports, *, solver: SolverContext | None = None) -> tuple[np.ndarray, int]:
    """``(X, p)``: the static responses to :func:`residual_loads` (see the module docstring) and their
    numerical rank ``p`` (the residual vectors they can give at most)."""
    X = static_solve(model, residual_loads(model, ports), rigid_body_modes(model), as_solver(solver))
    s = np.linalg.svd(X, compute_uv=False) if X.size else np.zeros(0)
    return X, int(np.sum(s > RESIDUAL_TOL * s[0])) if s.size and s[0] > 0 else 0


def with_residual_vectors(model, basis: Basis, X) -> Basis:
    """``basis`` with the static responses ``X`` (:func:`static_responses`) appended: M-orthogonal to the
    basis, M-orthonormal and K-orthogonal to each other, those the basis holds already left out
    (:data:`RESIDUAL_TOL`). ``info["residual_vectors"]`` counts them."""
    V = np.asarray(basis.V, float)
    X = np.asarray(X, float)
    MV = sparse_dense(model.M, V)
    G = V.T @ MV
    scale0 = np.max(np.sum(X * sparse_dense(model.M, X), axis=0), initial=0.0)
    for _ in range(2):  # M-orthogonal to the basis (twice: one Gram-Schmidt pass loses digits)
        X = X - V @ np.linalg.solve(G, MV.T @ X)
    MX = sparse_dense(model.M, X)
    w, U = np.linalg.eigh(0.5 * (X.T @ MX + MX.T @ X))
    keep = w > RESIDUAL_TOL ** 2 * max(float(scale0), np.finfo(float).tiny)
    W = X @ (U[:, keep] / np.sqrt(w[keep]))
    if W.shape[1]:  # K-orthogonal to each other: the residual pseudo-modes
        KW = sparse_dense(model.K, W)
        _, Z = np.linalg.eigh(0.5 * (W.T @ KW + KW.T @ W))
        W = W @ Z
    info = dict(basis.info, residual_vectors=int(W.shape[1]))
    return Basis(np.hstack([V, W]), basis.method, info)


def residual_order(order: int | None, n_loads: int, method: str) -> int | None:
    """The order the method builds when ``n_loads`` residual vectors are counted in ``order``."""
    if order is None:
        return None
    if order - n_loads < 1:
        raise OptionError(f"{method} with residual_vectors: order {order} leaves no vector for the method after "
                          f"the {n_loads} static loads (inputs, the frame's accelerations, interface loads); give "
                          f"order > {n_loads}", params=("order", "residual_vectors"))
    return order - n_loads
