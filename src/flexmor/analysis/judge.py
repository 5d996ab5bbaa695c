"""The judge's direct check: a body judged against the surrogate, verified by solves of the full model.

Above :data:`flexmor.analysis.compare.SURROGATE_MIN_DOF` DOF the full FRF of a damped model is the
verified surrogate of :mod:`flexmor.dynamics.surrogate` (a Galerkin projection of the full model,
checked against direct solves at its own worst residuals). A band_error measured against it is a
figure of the surrogate: a body whose basis came from a surrogate of its own (the Gramian and POD
methods' ``solves='surrogate'``) lies in nearly the same space, and what that space misses is
invisible to both. The judge therefore solves the full model directly (one complex factorization per
frequency) where the body's error matters and compares.

What the surrogate can change
    Where the surrogate's pointwise error is ``|H - H_s| <= tol |H|`` (Frobenius norms), the body's
    error against it, ``|H_s - H_r|``, differs from its error against the full model by at most
    ``tol |H|`` at every frequency; in the L2 norm of the band,
    ``|sqrt(band_error) - sqrt(band_error_s)| <= tol`` to first order in ``tol``. A band_error is
    therefore resolved to 10 % where ``sqrt(band_error) >= 20 tol`` (:data:`RESOLUTION`), i.e. above
    ``400 tol^2``; below it the figure is the surrogate's noise, and the judge states the bound
    ``(sqrt(band_error) + tol)^2`` instead (``floor``). ``tol`` is the larger of the surrogate's
    tolerance (and its own checks' errors) and the pointwise error of the surrogate measured by the
    judge's direct solves where the surrogate still decides the figure (below).

Where the full model is solved
    At the :data:`JUDGE_CHECKS` grid points where the body's error integrand ``w_i |H_s - H_r|^2``
    (trapezoidal weights ``w_i``) is largest, one per peak (points within ±5 % of a chosen one belong
    to its peak; a point solved for an earlier body within ±1 % of the peak, carrying at least a
    quarter of its integrand, serves instead), and at the surrogate's worst residual on the grid.
    The error integrand at these points against the full model and against the surrogate,
    ``sum_i w_i |H - H_r|^2`` and ``sum_i w_i |H_s - H_r|^2``, are compared (the band_error is a squared
    measure, its largest parts are these points): they agree where they differ by at most
    :data:`AGREEMENT` (10 %). Each point's pointwise errors are in the record too.

Where they disagree
    The surrogate is wrong where the body's error matters: the next points, the largest integrand
    (the full model's where solved) first, are solved by rounds of three until a round agrees (the
    failure was local and is now replaced by direct solutions) or :data:`MAX_JUDGE_CHECKS` points are
    solved. The band_error is then integrated with the full model's solutions at the points solved
    and the surrogate's elsewhere (``band_error_checked``), and that figure is the one printed; the
    surrogate's alone stays in the record (``band_error_surrogate``). The surrogate's error that still
    decides the figure is that of the agreeing last round, or, where no round agreed (the surrogate off
    over the band: ``explained`` False), the largest measured: a figure it does not resolve is given as
    its bound (``floor``), and the full model's direct sweep (``path='direct'``) gives the figure.

The direct solutions are kept by the caller (:class:`flexmor.analysis.compare.FullResponse`), so
bodies judged against one reference share them.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable

import numpy as np

from .frequency import band_error, trapezoid_weights

__all__ = ["JUDGE_CHECKS", "MAX_JUDGE_CHECKS", "AGREEMENT", "RESOLUTION", "judge_check", "built_from_surrogate",
           "judge_notes", "band_error_text"]

log = logging.getLogger(__name__)

#: Frequencies per body where the full model is solved (the largest peaks of its error integrand).
JUDGE_CHECKS = 3
#: Most grid points solved directly for one body (its first checks and those added on disagreement).
MAX_JUDGE_CHECKS = 12
#: Largest relative difference of the squared pointwise errors against the full model and the surrogate.
AGREEMENT = 0.1
#: ``sqrt(band_error) / tol`` from which the surrogate resolves a band_error to 10 % (see the module docstring).
RESOLUTION = 20.0
#: Relative distance within which grid points belong to one peak of the error integrand.
PEAK_WINDOW = 0.05
#: Relative distance within which a point solved before serves a peak.
REUSE_WINDOW = 0.01


def built_from_surrogate(info, depth: int = 3) -> bool:
    """Whether a body's ``info`` records solves by a surrogate (``{'solves': 'surrogate', ...}``, also nested,
    e.g. the Gramian solves of a hybrid method)."""
    if not isinstance(info, dict) or depth < 0:
        return False
    if info.get("solves") == "surrogate":
        return True
    return any(built_from_surrogate(v, depth - 1) for v in info.values() if isinstance(v, dict))


def _peaks(f, contrib, n: int, solved: Iterable[int]) -> list[int]:
    """Grid points of the ``n`` largest peaks of ``contrib``, a point in ``solved`` where it serves a peak."""
    solved = np.fromiter(solved, dtype=np.int64)
    picked: list[int] = []
    for i in np.argsort(-contrib, kind="stable"):
        if len(picked) >= n or not contrib[i] > 0:
            break
        if any(abs(f[i] / f[j] - 1) <= PEAK_WINDOW for j in picked):
            continue
        near = solved[(np.abs(f[solved] / f[i] - 1) <= REUSE_WINDOW) & (contrib[solved] >= 0.25 * contrib[i])]
        picked.append(int(near[np.argmax(contrib[near])]) if near.size else int(i))
    return picked


def judge_check(freqs, H, Hr, direct: Callable, *, tol: float, n_checks: int = JUDGE_CHECKS,
                max_checks: int = MAX_JUDGE_CHECKS, extra: Iterable[int] = (), solved: Iterable[int] = (),
                built: bool = False) -> tuple[dict, np.ndarray]:
    """Check a body's error against the surrogate ``H`` by the full model's solutions (see the module docstring).

    Parameters
    ----------
    freqs : ndarray
        The grid (Hz).
    H, Hr : ndarray, shape (n_freq, n_outputs, n_inputs)
        The surrogate's FRF the body is judged against, and the body's.
    direct : callable
        ``direct(indices)`` -> the full model's FRF at those grid points (the same block as ``H``).
    tol : float
        Bound of the surrogate's pointwise relative error known before (its tolerance and checks).
    n_checks : int
        Peaks of the error integrand solved first.
    max_checks : int
        Most points solved for this body.
    extra : iterable of int
        Grid points always solved (the surrogate's worst residual).
    solved : iterable of int
        Grid points solved before (they serve a peak within :data:`REUSE_WINDOW`).
    built : bool
        The body's basis came from a surrogate (recorded in the result).

    Returns
    -------
    record : dict
        ``checks`` (per point: ``freq_hz``, ``rel_error_full``, ``rel_error_surrogate``, ``surrogate_error``,
        ``share`` of the error integral, ``agree``), ``n_checks``, ``band_error_surrogate``,
        ``band_error_checked``, ``checked_share`` (of the error integral, at the points solved), ``agree`` (the
        first round agreed), ``corrected`` (the printed figure is ``band_error_checked``), ``explained`` (the
        last round agreed), ``tol``, ``resolved``, ``floor`` (the bound where not resolved, else None),
        ``built_from_surrogate``.
    H_checked : ndarray
        ``H`` with the full model's solutions at the points solved.
    """
    f = np.asarray(freqs, float)
    e2 = np.sum(np.abs(H - Hr) ** 2, axis=(1, 2))
    w = trapezoid_weights(f) if f.size > 1 else np.ones(f.size)
    contrib = w * e2
    total = float(contrib.sum())
    idx = list(dict.fromkeys([*_peaks(f, contrib, int(n_checks), solved), *(int(i) for i in extra)]))
    idx = idx or [int(np.argmax(contrib))]  # a body without error: one point still checks the claim
    sol: dict[int, np.ndarray] = {}
    rounds: list[tuple[list[int], bool]] = []  # the points of each round and whether they agreed
    while True:
        sol.update(zip(idx, direct(idx)))
        checked = np.array(sorted(sol), dtype=np.int64)
        Hc = H.copy()
        Hc[checked] = np.stack([sol[i] for i in checked])
        e2c = np.sum(np.abs(Hc - Hr) ** 2, axis=(1, 2))
        part_s, part_c = float(w[idx] @ e2[idx]), float(w[idx] @ e2c[idx])
        rounds.append((idx, abs(part_c - part_s) <= AGREEMENT * part_s))
        if rounds[-1][1] or checked.size >= max_checks:
            break
        rest = np.setdiff1d(np.arange(f.size), checked)
        idx = [int(i) for i in rest[np.argsort(-(w * e2c)[rest], kind="stable")][: min(3, max_checks - checked.size)]]
        if not idx:
            break
    total_c = float(w @ e2c)
    share = w[checked] * e2c[checked] / total_c if total_c > 0 else np.zeros(checked.size)
    h2d = np.sum(np.abs(Hc[checked]) ** 2, axis=(1, 2))
    sur_err = np.sqrt(np.sum(np.abs(Hc[checked] - H[checked]) ** 2, axis=(1, 2)) / np.maximum(h2d, 1e-300))
    be_s, be_c = band_error(f, H, Hr), band_error(f, Hc, Hr)
    ok = len(rounds) == 1 and rounds[0][1]
    # the surrogate's error where it still decides the figure: at the last round's points where that round
    # agreed (a local failure, corrected), at every point solved where it did not (no bound is known)
    last = np.isin(checked, rounds[-1][0]) if rounds[-1][1] else np.ones(checked.size, bool)
    tol_eff = float(max(tol, sur_err[last].max(initial=0.0)))
    be = be_s if ok else be_c
    resolved = bool(np.sqrt(max(be, 0.0)) >= RESOLUTION * tol_eff)
    agree = np.abs(e2c[checked] - e2[checked]) <= AGREEMENT * e2[checked]
    rows = [{"freq_hz": float(f[i]), "rel_error_full": float(np.sqrt(e2c[i] / max(h2d[k], 1e-300))),
             "rel_error_surrogate": float(np.sqrt(e2[i] / max(np.sum(np.abs(H[i]) ** 2), 1e-300))),
             "surrogate_error": float(sur_err[k]), "share": float(share[k]), "agree": bool(agree[k])}
            for k, i in enumerate(checked)]
    record = {"checks": rows, "n_checks": int(checked.size), "band_error_surrogate": be_s,
              "band_error_checked": be_c, "checked_share": float(share.sum()) if total > 0 else 0.0, "agree": ok,
              "corrected": not ok, "explained": bool(rounds[-1][1]), "tol": tol_eff, "resolved": resolved,
              "floor": None if resolved else float((np.sqrt(max(be, 0.0)) + tol_eff) ** 2),
              "built_from_surrogate": bool(built)}
    log.info("judge check: %d direct points, band_error %.3e against the surrogate, %.3e checked (%s)",
             checked.size, be_s, be_c, "agree" if ok else "corrected")
    return record, Hc


def band_error_text(record: dict, spec: str = ".2e") -> str:
    """The band_error of a JSON record as a table shows it: ``format(band_error, spec)``, ``<FLOOR`` where its
    ``judge_check`` says the surrogate reference does not resolve it (the bound, an upper one), ``-`` without."""
    check = record.get("judge_check") or {}
    if check.get("resolved") is False and check.get("floor") is not None:
        return "<" + format(check["floor"], ".1e")
    value = record.get("band_error")
    return "-" if value is None else format(value, spec)


def judge_notes(check: dict, band_error_value: float) -> list[str]:
    """What a user should read about a :func:`judge_check` record (``band_error_value``: the figure printed)."""
    notes = []
    pts = sorted(check["checks"], key=lambda c: -c["share"])
    if check["corrected"]:
        c = next((c for c in pts if not c["agree"]), pts[0])
        notes.append(f"band_error corrected by direct solutions of the full model at {check['n_checks']} "
                     f"frequencies ({100 * check['checked_share']:.0f} % of the error integral): against the "
                     f"surrogate alone it reads {check['band_error_surrogate']:.3g}; at {c['freq_hz']:.4g} Hz the "
                     f"pointwise error is {c['rel_error_full']:.3g} against the full model, "
                     f"{c['rel_error_surrogate']:.3g} against the surrogate")
    elif check["built_from_surrogate"]:
        notes.append(f"built from a surrogate: its band_error confirmed within {100 * AGREEMENT:.0f} % by direct "
                     "solutions of the full model at its worst frequencies (judge_check)")
    if not check["resolved"]:
        notes.append(f"band_error {band_error_value:.2g} is below what the surrogate reference resolves (its "
                     f"pointwise error up to {check['tol']:.1g}, checked against direct solutions): it is at most "
                     f"{check['floor']:.2g}" + ("" if check["explained"] else
                                               "; the full model's direct sweep (path='direct') gives the figure"))
    return notes
