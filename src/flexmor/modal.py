"""A reduced body in its own modes: the modal form, the mode table, and bodies trimmed to chosen modes.

The modal form of a body ``Mr qr'' + Dr qr' + Kr qr = Br u``, ``y = Cr qr`` is the same body in
the coordinates ``qr = Phi eta`` of its undamped modes (``Kr Phi = Mr Phi Lambda``,
``Phi^T Mr Phi = I``): ``M = I``, ``K = Lambda`` (diagonal), ``D = Phi^T Dr Phi`` (diagonal for
Rayleigh and modal damping), ``B = Phi^T Br``, ``C = Cr Phi`` and the basis ``V Phi``. Its rigid-body
modes (zero eigenvalues: a free body whose basis holds rigid motion) are left out: in the floating
frame of reference the frame carries that motion.

Stress modes (``stress_modes``, one field per coordinate) follow the coordinates.

The mode table gives per mode the frequency, the damping ratio ``zeta_i = D_ii / (2 omega_i)``, the
effective masses ``m_eff[i, a] = L[i, a]^2`` with the participation ``L = Phi^T V^T M R`` of the
six rigid motions ``R`` of the frame (translations x y z: mass; rotations about the frame's x y z
axes through its origin: rotary inertia), and the share of the port response the mode carries.
Over all modes of a body whose basis contains the rigid motions, the effective masses sum to
the rigid-body mass and inertia (for a free body the rigid-body modes carry all of it; the
elastic ones none). ``V^T M R`` is recorded by :func:`flexmor.reduction.reduce` in
``info["frame_participation"]`` (:func:`flexmor.rigid.frame_participation`).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .body import ReducedModel
from .errors import ModelError, OptionError
from .linalg.eigen import is_rigid
from .model import direction_name
from .rigid import ACCELERATIONS

__all__ = ["modal_form", "mode_table", "keep_modes", "keep_modes_static", "static_loads", "response_shares",
           "MODE_TABLE_DAMPING", "STATIC_RANK_TOL"]

#: Relative singular value below which a static response the dropped modes carry adds no vector
#: (:func:`keep_modes_static`).
STATIC_RANK_TOL = 1e-10

#: Damping ratio the response shares of an undamped body are computed with (its resonances
#: would make every share infinite).
MODE_TABLE_DAMPING = 0.02


def _modes(body: ReducedModel):
    """``(lam, phi, rigid)``: eigenvalues, mass-normalized modes and the rigid-body mask of ``body``."""
    try:
        lam, phi = sla.eigh(body.K, body.M)
    except (np.linalg.LinAlgError, ValueError):
        raise ModelError(f"the {body.method} body's reduced mass matrix is not positive definite: it has no "
                         "modal form") from None
    return lam, phi, is_rigid(lam, body.K, body.M)


def modal_form(body: ReducedModel) -> ReducedModel:
    """``body`` in its own undamped modes, rigid-body modes left out (see the module docstring).

    ``info["modal_form"]`` records ``n_rigid_left_out`` and the order before; ``info["n_rigid_excluded"]``
    counts the rigid-body modes left out (the body is judged on its elastic part). A body already
    in modal form is returned unchanged.

    Raises
    ------
    ModelError
        The reduced mass matrix is not positive definite, or the body has no elastic mode.
    """
    if body.info.get("modal_form"):
        return body
    lam, phi, rigid = _modes(body)
    lam, phi = lam[~rigid], phi[:, ~rigid]
    if lam.size == 0:
        raise ModelError(f"the {body.method} body holds rigid-body modes only: no elastic mode to write")
    info = dict(body.info)
    info["modal_form"] = {"order_before": body.order, "n_rigid_left_out": int(rigid.sum())}
    if rigid.any():
        info["n_rigid_excluded"] = int(info.get("n_rigid_excluded") or 0) + int(rigid.sum())
    if info.get("frame_participation") is not None:
        info["frame_participation"] = (phi.T @ np.asarray(info["frame_participation"], float)).tolist()
    D = None if body.D is None else _sym(phi.T @ body.D @ phi)
    S = None if body.stress_modes is None else np.einsum("ij,ikl->jkl", phi, body.stress_modes)
    return _replace(body, M=np.eye(lam.size), K=np.diag(lam), D=D, B=phi.T @ body.B, C=body.C @ phi,
                    V=None if body.V is None else body.V @ phi, info=info, stress_modes=S)


def keep_modes(body: ReducedModel, keep) -> ReducedModel:
    """The modal-form ``body`` with only the modes ``keep`` (indices or a boolean mask), in
    ascending frequency; ``info["modal_form"]["modes_kept"]`` lists them (1-based, in the
    numbering of ``body``), ``order_before_trim`` the order before."""
    if not body.info.get("modal_form"):
        raise OptionError("keep_modes needs a body in modal form (flexmor.modal.modal_form)", params=("body",))
    idx = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.unique(np.asarray(keep, int))
    if idx.size == 0:
        raise OptionError("keep no mode: at least one mode must stay", params=("keep",))
    if idx.min() < 0 or idx.max() >= body.order:
        raise OptionError(f"modes {idx.tolist()} outside 0..{body.order - 1}", params=("keep",))
    info = dict(body.info)
    info["modal_form"] = dict(info["modal_form"], modes_kept=(idx + 1).tolist(), order_before_trim=body.order)
    if info.get("frame_participation") is not None:
        info["frame_participation"] = np.asarray(info["frame_participation"], float)[idx].tolist()
    sub = np.ix_(idx, idx)
    return _replace(body, M=body.M[sub], K=body.K[sub], D=None if body.D is None else body.D[sub],
                    B=body.B[idx], C=body.C[:, idx], V=None if body.V is None else body.V[:, idx], info=info,
                    stress_modes=None if body.stress_modes is None else body.stress_modes[idx])


def static_loads(body: ReducedModel) -> tuple[np.ndarray, list[str]]:
    """``(F, names)``: the loads in ``body``'s coordinates whose static response a trimmed body keeps: its
    inputs (``B``), the frame's six accelerations (``info["frame_participation"]``, ``V^T M R``) and unit
    loads at each coupling master's equations (rows of ``V`` at the master, ``info["masters"]``)."""
    cols, names = [np.asarray(body.B, float)], [f"input:{n}" for n in body.input_names]
    P = body.info.get("frame_participation")
    if P is not None:
        cols.append(np.asarray(P, float))
        names += list(ACCELERATIONS)
    if body.V is not None and body.dofs is not None:
        dofs = np.asarray(body.dofs)
        for m in body.info.get("masters", []):
            rows = np.flatnonzero(dofs[:, 0] == int(m["id"]))
            cols.append(np.asarray(body.V, float)[rows].T)
            names += [f"{m['name']}:{direction_name(d)}" for d in dofs[rows, 1]]
    return np.hstack(cols), names


def keep_modes_static(body: ReducedModel, keep, loads=None) -> tuple[ReducedModel, int]:
    """The modal-form ``body`` with the modes ``keep`` and the static response the dropped modes carry
    under ``loads`` (default :func:`static_loads`): ``(trimmed, p)``, ``p`` static vectors added.

    In modal coordinates (``M = I``, ``K = Lambda``) the dropped modes ``D`` carry the static response
    ``Lambda_D^-1 F_D``; its range (SVD, singular values above :data:`STATIC_RANK_TOL` of the largest)
    is added as ``p`` vectors, M- and K-orthogonal to the modes kept and to each other (the residual
    pseudo-modes, above the kept frequencies). The trimmed body's static response to every load of
    ``loads`` is then that of ``body``: a body trimmed to its modes up to a frequency still sags like the
    body (and so like the full model, where the body did), where the kept modes alone miss the residual
    flexibility of the dropped ones (Craig-Chang, MacNeal).
    """
    trimmed = keep_modes(body, keep)
    idx = np.asarray(trimmed.info["modal_form"]["modes_kept"], int) - 1
    drop = np.setdiff1d(np.arange(body.order), idx)
    F = static_loads(body)[0] if loads is None else np.asarray(loads, float)
    lam = np.diag(body.K)
    if drop.size == 0 or F.shape[1] == 0:
        return trimmed, 0
    U, sv, _ = np.linalg.svd(F[drop] / lam[drop, None], full_matrices=False)
    p = int(np.sum(sv > STATIC_RANK_TOL * sv[0])) if sv.size and sv[0] > 0 else 0
    if p == 0:
        return trimmed, 0
    W = U[:, :p]
    mu, Z = np.linalg.eigh(W.T @ (lam[drop, None] * W))
    W = W @ Z
    T = np.zeros((body.order, idx.size + p))
    T[idx, np.arange(idx.size)] = 1.0
    T[np.ix_(drop, np.arange(idx.size, idx.size + p))] = W
    info = dict(trimmed.info)
    info["modal_form"] = dict(info["modal_form"], static_vectors=p)
    if info.get("frame_participation") is not None:
        info["frame_participation"] = (T.T @ np.asarray(body.info["frame_participation"], float)).tolist()
    D = None if body.D is None else _sym(T.T @ body.D @ T)
    S = None if body.stress_modes is None else np.einsum("ij,ikl->jkl", T, body.stress_modes)
    return _replace(body, M=np.eye(T.shape[1]), K=np.diag(np.concatenate([lam[idx], mu])), D=D, B=T.T @ body.B,
                    C=body.C @ T, V=None if body.V is None else body.V @ T, info=info, stress_modes=S), p


def response_shares(body: ReducedModel, band) -> np.ndarray:
    """The share of the port response over ``band`` (Hz) that each mode of the modal-form ``body``
    carries: ``s_i = E_i / sum_j E_j`` with ``E_i`` the integral over the band of
    ``||c_i b_i^T||_F^2 / |lambda_i - omega^2 + i omega d_i|^2`` (the mode's own FRF term; the
    diagonal of ``D``, or :data:`MODE_TABLE_DAMPING` where the body is undamped)."""
    from scipy.integrate import quad

    lam = np.diag(body.K)
    w = np.sqrt(np.clip(lam, 0.0, None))
    d = np.diag(body.D) if body.D is not None else 2 * MODE_TABLE_DAMPING * w
    if not np.all(lam > 0):  # rigid-body modes: H_i = c_i b_i^T / (-omega^2) (their integral over the band is finite)
        d = np.where(lam > 0, d, 0.0)
    gain = np.sum(body.C ** 2, axis=0) * np.sum(body.B ** 2, axis=1)
    w1, w2 = 2 * np.pi * float(band[0]), 2 * np.pi * float(band[1])
    energy = np.zeros(body.order)
    for i in range(body.order):
        if gain[i] == 0:
            continue
        peaks = [x for x in (w[i],) if w1 < x < w2]
        val, _ = quad(lambda om, i=i: 1.0 / ((lam[i] - om * om) ** 2 + (om * d[i]) ** 2), w1, w2,
                      points=peaks or None, limit=200)
        energy[i] = gain[i] * val
    total = energy.sum()
    return energy / total if total > 0 else energy


def mode_table(body: ReducedModel, *, band=None, participation=None) -> list[dict]:
    """One row per mode of ``body``, rigid-body modes included: ``mode`` (1-based), ``rigid``,
    ``frequency_hz``, ``damping_ratio`` (None for an undamped body and a rigid-body mode),
    ``effective_mass`` (x y z) and ``effective_inertia`` (about the frame's x y z axes), None
    without the participation, and ``response_share`` over ``band`` (None without a band).

    The rigid-body modes (one eigenvalue zero, any basis of their space is one) are taken in the
    order of the frame's motions: the first carries all of the mass in x, the next in y, ...
    (a Gram-Schmidt of their participations). ``participation`` is ``V^T M R`` (r, 6) of
    ``body`` (:func:`flexmor.rigid.frame_participation`; default its
    ``info["frame_participation"]``)."""
    lam, phi, rigid = _modes(body)
    lam = np.where(rigid, 0.0, lam)  # a rigid-body mode's eigenvalue is round-off
    P = participation if participation is not None else body.info.get("frame_participation")
    L = None if P is None else phi.T @ np.asarray(P, float)
    if L is not None and 0 < rigid.sum() <= 6:  # the rigid-body modes (a degenerate eigenspace) in the order of
        Q, _ = np.linalg.qr(L[rigid])         # the frame's motions x y z rx ry rz: Gram-Schmidt of L's columns
        phi[:, rigid], L[rigid] = phi[:, rigid] @ Q, Q.T @ L[rigid]
    omega = np.sqrt(np.clip(lam, 0.0, None))
    d = None if body.D is None else np.where(rigid, 0.0, np.einsum("ij,ik,kj->j", phi, body.D, phi))
    modal = _replace(body, M=np.eye(lam.size), K=np.diag(lam), D=None if body.D is None else np.diag(d),
                     B=phi.T @ body.B, C=body.C @ phi, V=None)
    shares = None if band is None else response_shares(modal, band)
    rows = []
    for i in range(lam.size):
        rows.append({"mode": i + 1, "rigid": bool(rigid[i]), "frequency_hz": float(omega[i] / (2 * np.pi)),
                     "damping_ratio": None if d is None or rigid[i] else float(d[i] / (2 * omega[i])),
                     "effective_mass": None if L is None else (L[i, :3] ** 2).tolist(),
                     "effective_inertia": None if L is None else (L[i, 3:] ** 2).tolist(),
                     "response_share": None if shares is None else float(shares[i])})
    return rows


def _sym(A):
    return 0.5 * (A + A.T)


def _replace(body: ReducedModel, **fields) -> ReducedModel:
    """A copy of ``body`` with ``fields`` replaced (the rest shared, lists and dicts copied)."""
    from dataclasses import fields as dc_fields

    values = {f.name: getattr(body, f.name) for f in dc_fields(body)}
    for name in ("input_names", "output_names", "selections", "couplings"):
        values[name] = list(values[name])
    values["origin"] = dict(values["origin"])
    values["errors"] = {}  # the measures were of the body before
    values.update(fields)
    return ReducedModel(**values)
