"""Modal checks of a reduced body: eigenfrequencies against the full model and the MAC matrix.

The reduced body's modes ``psi`` (of ``Kr psi = lam Mr psi``) are expanded with the basis,
``V psi``, and compared with the full model's modes ``phi`` by the modal assurance criterion

    MAC(phi_i, V psi_j) = |phi_i^T V psi_j|^2 / ((phi_i^T phi_i) (psi_j^T V^T V psi_j)).

Repeated eigenfrequencies (a square beam's two bending directions) make single modes
arbitrary within their eigenspace, in the full model as in the reduced one. Within each
cluster of numerically equal full eigenfrequencies the full modes are therefore rotated to
the best match of the reduced modes that lie in that eigenspace (orthogonal Procrustes in
the mass inner product); any orthonormal basis of the eigenspace is an equally valid set of
mode shapes. Rigid-body modes (zero frequency) of free bodies are left out of the comparison
and counted.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla

from ..errors import ModelError, OptionError
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import eigenmodes, frequencies_hz, is_rigid
from ..linalg.threads import sparse_dense

__all__ = ["DEGENERATE_RTOL", "PAIR_MAC_MIN", "full_modes", "mac", "modal_check"]

log = logging.getLogger(__name__)

#: Relative eigenvalue gap below which full modes count as one repeated eigenvalue.
DEGENERATE_RTOL = 1e-6
#: Smallest MAC for which a full mode counts as reproduced by (paired with) a reduced mode.
PAIR_MAC_MIN = 0.5


def mac(Phi, Psi) -> np.ndarray:
    """Modal assurance criterion matrix, shape (n_phi, n_psi), entries in [0, 1].

    ``MAC_ij = |phi_i^T psi_j|^2 / ((phi_i^T phi_i)(psi_j^T psi_j))`` for real mode shapes.

    References
    ----------
    Allemang, R. J. (2003). The modal assurance criterion - twenty years of use and abuse.
    Sound and Vibration 37(8), 14-23.
    """
    Phi, Psi = np.atleast_2d(np.asarray(Phi, float)), np.atleast_2d(np.asarray(Psi, float))
    if Phi.shape[0] != Psi.shape[0]:
        raise OptionError(f"mode shapes have {Phi.shape[0]} and {Psi.shape[0]} rows")
    num = (Phi.T @ Psi) ** 2
    den = np.outer(np.einsum("ij,ij->j", Phi, Phi), np.einsum("ij,ij->j", Psi, Psi))
    return num / np.where(den > 0, den, np.finfo(float).tiny)


def full_modes(model, n_modes: int, *, solver: SolverContext | None = None):
    """Lowest ``n_modes`` flexible eigenpairs of the full model (rigid-body modes skipped).

    A repeated eigenvalue at the end is kept whole, so one more mode may be returned.

    Returns ``(f_hz, phi, n_rigid)`` with mass-normalized ``phi`` (n_dof, n_modes).
    """
    solver = as_solver(solver)
    k = min(model.n_dof, int(n_modes) + 6 + 4)
    lam, phi = eigenmodes(model.K, model.M, k, solver=solver)
    rigid = is_rigid(lam, model.K, model.M)
    flex = np.flatnonzero(~rigid)
    n = min(int(n_modes), flex.size)
    # never cut a repeated eigenvalue in two: its modes are only defined together
    while 0 < n < flex.size and abs(lam[flex[n]] - lam[flex[n - 1]]) <= DEGENERATE_RTOL * lam[flex[n]]:
        n += 1
    keep = flex[:n]
    return frequencies_hz(lam[keep]), phi[:, keep], int(rigid.sum())


def _align_clusters(f, phi, Psi, M) -> np.ndarray:
    """Rotate full modes within clusters of repeated eigenvalues to best match ``Psi``."""
    phi = phi.copy()
    lam = f ** 2
    i = 0
    while i < f.size:
        j = i + 1
        while j < f.size and abs(lam[j] - lam[i]) <= DEGENERATE_RTOL * max(lam[i], lam[j]):
            j += 1
        if j - i > 1 and Psi.shape[1]:
            P = phi[:, i:j]
            G = P.T @ sparse_dense(M, Psi)  # projections of the reduced modes on the eigenspace
            psi_norm = np.sqrt(np.einsum("ij,ij->j", Psi, sparse_dense(M, Psi)))
            share = np.linalg.norm(G, axis=0) / np.where(psi_norm > 0, psi_norm, 1.0)
            J = np.sort(np.argsort(share)[::-1][: j - i])
            U, _, Wt = np.linalg.svd(G[:, J] / psi_norm[J])
            k = J.size
            phi[:, i:i + k] = P @ (U[:, :k] @ Wt)  # orthogonal Procrustes: P Q closest to Psi_J
        i = j
    return phi


def modal_check(model, body, *, n_modes: int | None = None, full=None, solver: SolverContext | None = None) -> dict:
    """Eigenfrequencies of ``body`` against the full model, and the MAC matrix.

    Parameters
    ----------
    model : FEModel
        The full model the body was reduced from.
    body : ReducedModel
        With its basis ``V`` (n_dof, r).
    n_modes : int, optional
        Number of full flexible modes compared; default ``min(r, 20)``.
    full : tuple, optional
        ``(f_hz, phi[, n_rigid])`` of :func:`full_modes`, to reuse for several bodies.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` for the full eigenproblem.

    Returns
    -------
    dict
        ``full_hz`` (n,), ``reduced_hz`` (flexible reduced modes, ascending), ``mac``
        (n, n_reduced), ``pair`` (index of the best-matching reduced mode per full mode,
        -1 when its MAC is below :data:`PAIR_MAC_MIN`), ``pair_hz`` and ``freq_rel_error``
        (``(f_pair - f) / f``, NaN when unpaired), ``pair_mac`` (the largest MAC of each full mode),
        ``n_rigid_full``, ``n_rigid_reduced``; ``full_shapes`` (n_dof, n) the full modes (aligned
        within clusters of repeated eigenfrequencies to the reduced ones) and ``reduced_shapes``
        (n_dof, n_reduced) the flexible reduced modes expanded with ``V``, as the MAC compares them.

    References
    ----------
    Allemang, R. J. (2003). The modal assurance criterion - twenty years of use and abuse.
    Sound and Vibration 37(8), 14-23.
    """
    solver = as_solver(solver)
    if body.V is None:
        raise ModelError("the reduced body has no basis V; the MAC needs the expanded mode shapes")
    V = np.asarray(body.V, float)
    if V.shape[0] != model.n_dof:
        raise ModelError(f"the basis has {V.shape[0]} rows, the model {model.n_dof} DOF")
    try:
        lam_r, psi = sla.eigh(body.K, body.M)
    except np.linalg.LinAlgError:
        raise ModelError("the reduced mass matrix is not positive definite") from None
    rig_r = is_rigid(lam_r, model.K, model.M)
    f_r, Psi = frequencies_hz(lam_r[~rig_r]), V @ psi[:, ~rig_r]
    if full is None:
        n = min(body.order, 20) if n_modes is None else int(n_modes)
        f, phi, n_rig = full_modes(model, n, solver=solver)
    else:
        f, phi, *rest = full
        n_rig = int(rest[0]) if rest else 0
        if n_modes is not None:
            f, phi = f[:n_modes], phi[:, :n_modes]
    phi = _align_clusters(np.asarray(f, float), np.asarray(phi, float), Psi, model.M)
    A = mac(phi, Psi)
    pair = np.argmax(A, axis=1) if A.shape[1] else np.full(f.size, -1)
    best = A[np.arange(f.size), np.maximum(pair, 0)] if A.shape[1] else np.zeros(f.size)
    pair = np.where(best >= PAIR_MAC_MIN, pair, -1)
    ok = pair >= 0
    pair_hz = np.where(ok, f_r[np.maximum(pair, 0)] if f_r.size else np.nan, np.nan)
    pair_mac = best
    out = {"full_hz": np.asarray(f, float), "reduced_hz": f_r, "mac": A, "pair": pair, "pair_hz": pair_hz,
           "pair_mac": pair_mac, "freq_rel_error": (pair_hz - f) / np.where(f > 0, f, 1.0),
           "n_rigid_full": n_rig, "n_rigid_reduced": int(rig_r.sum()), "full_shapes": phi, "reduced_shapes": Psi}
    log.info("modal check of %s r=%d: %d full modes, min paired MAC %.3f", body.method, body.order, f.size,
             float(np.nanmin(pair_mac)) if f.size else float("nan"))
    return out
