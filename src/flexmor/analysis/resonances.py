"""Spurious resonances: peaks of a reduced body's FRF in the band where the full model has none.

A reduced body can resonate where the full model does not: a poorly converged Ritz vector of a
Krylov or Gramian basis, a mixture of two modes, a mode that a coupling moved. Its response then
peaks at a frequency at which the full FRF is smooth, and ``max_rel_error`` there is large for a
reason that is neither an anti-resonance (small ``|H|``) nor a shifted resonance. This module
finds such resonances by comparing the body's own resonances (the damped eigenvalues of
``s² Mr + s Dr + Kr``) with the full model's resonances in the band, which the error grid's
modal pre-pass knows (:attr:`flexmor.analysis.compare.FullResponse.resonances`).

A resonance ``f_r`` of the body (an underdamped pole ``λ``, ``f_r = |λ| / 2π``) is *spurious*
when

* no resonance of the full model lies within ``max(SPURIOUS_REL, 2 ζ_k)`` (relative) of it, ``ζ_k``
  the full mode's damping ratio (so a shifted peak of a broad, well damped resonance is not
  counted), with ``f_r`` that far inside the band (a full resonance just outside the band is not
  known to the grid), and
* the body's FRF at ``f_r`` exceeds the full FRF there (interpolated on the grid, where it is
  smooth) by at least :data:`SPURIOUS_PEAK`: the ports see the peak.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..dynamics.frf import frf_reduced

__all__ = ["body_resonances", "spurious_resonances", "SPURIOUS_REL", "SPURIOUS_PEAK"]

#: Smallest relative distance of a body's resonance from every resonance of the full model for it to be spurious.
SPURIOUS_REL = 0.03
#: Factor by which the body's ``||Hr||_F`` at its resonance must exceed the full ``||H||_F`` there.
SPURIOUS_PEAK = 2.0
#: Largest damping ratio of a pole counted as a resonance (above it the FRF has no peak).
MAX_ZETA = 1 / np.sqrt(2)


def body_resonances(body) -> tuple[np.ndarray, np.ndarray]:
    """The resonances of a reduced body: ``(f_hz, zeta)`` of its underdamped poles, sorted.

    The poles are the eigenvalues ``λ`` of the quadratic pencil ``λ² Mr + λ Dr + Kr``; each complex
    pair gives ``f = |λ| / 2π`` (the undamped natural frequency for proportional damping) and
    ``ζ = -Re λ / |λ|``. Damping that the undamped modes diagonalize (none, Rayleigh, modal: what
    flexmor projects) needs only the symmetric eigenproblem of ``(Kr, Mr)``; other damping the
    dense first-order companion form. Rigid-body (zero) poles and poles with ``ζ >=`` 1/√2 (no
    peak) are left out.
    """
    M, K = np.asarray(body.M, float), np.asarray(body.K, float)
    r = M.shape[0]
    lam, phi = sla.eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
    w = np.sqrt(np.clip(lam, 0.0, None))
    if body.D is None:
        f, z = w / (2 * np.pi), np.zeros_like(w)
    else:
        D = np.asarray(body.D, float)
        Dm = phi.T @ D @ phi
        d = np.diag(Dm).copy()
        off = Dm - np.diag(d)
        if np.abs(off).max(initial=0.0) <= 1e-10 * max(np.abs(d).max(initial=0.0), 1e-300):  # proportional
            f, z = w / (2 * np.pi), d / (2 * np.where(w > 0, w, np.inf))
        else:
            A = np.block([[np.zeros((r, r)), np.eye(r)], [-K, -D]])
            E = np.block([[np.eye(r), np.zeros((r, r))], [np.zeros((r, r)), M]])
            mu = sla.eig(A, E, right=False)
            mu = mu[np.isfinite(mu) & (mu.imag > 0)]
            f = np.abs(mu) / (2 * np.pi)
            z = -mu.real / np.where(np.abs(mu) > 0, np.abs(mu), 1.0)
    scale = f.max(initial=0.0)
    keep = (f > 1e-6 * scale) & (z < MAX_ZETA)
    order = np.argsort(f[keep])
    return f[keep][order], z[keep][order]


def _interp_norm(freqs, H, f) -> np.ndarray:
    """``||H||_F`` at the frequencies ``f``, interpolated linearly in log-log on the grid ``freqs``."""
    h = np.sqrt(np.sum(np.abs(H) ** 2, axis=(1, 2)))
    tiny = np.finfo(float).tiny
    return np.exp(np.interp(np.log(f), np.log(freqs), np.log(np.maximum(h, tiny))))


def spurious_resonances(body, freqs, H, resonances, zeta=None, *, band=None, max_rel_error_hz=None,
                        max_rel_error=None) -> dict:
    """The body's resonances in the band where the full model has none (see the module docstring).

    Parameters
    ----------
    body : ReducedModel
    freqs : ndarray
        The error grid (Hz).
    H : ndarray, shape (n_freq, n_outputs, n_inputs)
        The full FRF the body is judged against, on ``freqs``.
    resonances : array_like
        The full model's resonances in the band (Hz).
    zeta : array_like, optional
        Their modal damping ratios (0 when unknown).
    band : (float, float), optional
        Default the ends of ``freqs``.
    max_rel_error_hz, max_rel_error : float, optional
        Where the body's max_rel_error occurs, and its value (named in the note).

    Returns
    -------
    dict
        ``spurious_resonances_hz`` (list), ``max_rel_error_at_spurious_resonance`` (True when
        ``max_rel_error_hz`` lies within the window of a spurious resonance and nearer to it than
        to any full resonance) and ``note`` (one line for the user, or None).
    """
    freqs = np.asarray(freqs, float)
    fmin, fmax = (float(freqs[0]), float(freqs[-1])) if band is None else (float(band[0]), float(band[1]))
    res = np.atleast_1d(np.asarray(resonances if resonances is not None else [], float))
    zk = np.broadcast_to(np.asarray(0.0 if zeta is None else zeta, float), res.shape)
    out = {"spurious_resonances_hz": [], "max_rel_error_at_spurious_resonance": False, "note": None}
    fr, zr = body_resonances(body)
    inside = (fr * (1 - SPURIOUS_REL) >= fmin) & (fr * (1 + SPURIOUS_REL) <= fmax)
    win = np.maximum(SPURIOUS_REL, 2 * zk)  # per full resonance
    cand = [(f, z) for f, z in zip(fr[inside], zr[inside]) if not np.any(np.abs(res - f) <= win * res)]
    if not cand:
        return out
    f_c = np.array([c[0] for c in cand])
    at = f_c * (1 + np.where(np.array([c[1] for c in cand]) > 0, 0.0, 1e-3))  # an undamped pole: just beside it
    ratio = np.linalg.norm(frf_reduced(body, at).reshape(at.size, -1), axis=1) / _interp_norm(freqs, H, at)
    bad = f_c[ratio >= SPURIOUS_PEAK]
    unseen = f_c[ratio < SPURIOUS_PEAK]
    if unseen.size:  # modes the ports hardly see: no error at the ports, but another load (the frame's) would
        shown = "; ".join(f"{f:.4g} Hz" for f in unseen[:4]) + (" ..." if unseen.size > 4 else "")
        what, it = ("modes", "them") if unseen.size > 1 else ("a mode", "it")
        built = int((getattr(body, "info", None) or {}).get("n_inertia_loads") or 0) > 0
        advice = ("raise the order (the basis is built for the frame's inertia loads already) or add the other "
                  "joints' loads as inputs" if built else "raise the order or add those loads as inputs")
        out["unseen_note"] = (f"the body has {what} at {shown} in the band with no full mode within "
                              f"{100 * SPURIOUS_REL:g} % ({what} the basis approximates poorly): its ports hardly see "
                              f"{it}, loads elsewhere (the frame's inertia, other joints) would; {advice}")
    if not bad.size:
        return out
    out["spurious_resonances_hz"] = bad.tolist()
    if max_rel_error_hz is not None:
        d_s = np.min(np.abs(bad - max_rel_error_hz) / bad)
        d_f = np.min(np.abs(res - max_rel_error_hz) / res) if res.size else np.inf
        out["max_rel_error_at_spurious_resonance"] = bool(d_s <= SPURIOUS_REL and d_s < d_f)
    near = []
    groups = np.split(bad, np.flatnonzero(np.diff(bad) > 1e-6 * bad[1:]) + 1)  # a pair (y, z bending) once
    for g in groups[:4]:
        f = float(g[0])
        lo, hi = res[res < f], res[res > f]
        near.append(f"{f:.4g} Hz{f' ({g.size} modes)' if g.size > 1 else ''} (nearest full resonances in the band: "
                    + (f"{lo.max():.4g} Hz" if lo.size else "none") + " below, "
                    + (f"{hi.min():.4g} Hz" if hi.size else "none") + " above)")
    where = (f"; max_rel_error {max_rel_error:.3g} lies there" if out["max_rel_error_at_spurious_resonance"]
             and max_rel_error is not None else "")
    out["note"] = (f"spurious resonance{'s' if bad.size > 1 else ''}: the body resonates at {'; '.join(near)}"
                   f"{' ...' if len(groups) > 4 else ''}, where the full model has none (none within "
                   f"{100 * SPURIOUS_REL:g} % or two damping ratios) and the body's |H| is "
                   f"{ratio[ratio >= SPURIOUS_PEAK].min():.3g}x the full one or more{where}; raise the order, or check "
                   "the method's expansion points / band")
    return out
