"""The pairing of a model's eigenfrequencies with an FE program's own (``flexmor info --reference``): one-to-one
and in order, rigid-body modes with rigid-body modes, with the notes (and warnings) on a reference that does not
fit. Used by :func:`flexmor.io.reference.compare_frequencies` and :func:`flexmor.io.calculix.frd.compare_modes`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..linalg.context import SolverContext, as_solver

__all__ = ["MISMATCH", "Pairing", "paired_modes", "pairing_record"]


#: Above this largest relative difference of the elastic pairs, the comparison warns.
MISMATCH = 1e-3
#: Relative differences that agree to this (relative to the larger of the difference and 1) are equal.
EQUAL_REL = 1e-8


def _monotone_pairs(f_ref: np.ndarray, f_mod: np.ndarray) -> list:
    """The order-preserving one-to-one pairing of ascending ``f_ref`` with ascending ``f_mod``.

    Each reference frequency gets a distinct model frequency, in order (model frequencies may be
    left out), with the smallest sum of relative differences ``|g - f| / f``; a reference
    frequency is left unpaired (None) only when there are fewer model frequencies than
    reference ones. Ties go to the lower model modes. Returns a model index (or None) per
    reference frequency.
    """
    n, m = f_ref.size, f_mod.size
    if n == 0:
        return []
    cost = np.abs(f_mod[None, :] - f_ref[:, None]) / np.maximum(np.abs(f_ref), 1e-12)[:, None]
    skip = (n + 1) * (float(cost.max(initial=0.0)) + 1.0)  # leaving a reference mode unpaired: dearer than any pairing
    D = np.empty((n + 1, m + 1))
    D[0, :] = 0.0
    D[:, 0] = skip * np.arange(n + 1)
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            D[i, j] = min(D[i - 1, j - 1] + cost[i - 1, j - 1], D[i, j - 1], D[i - 1, j] + skip)
    pairs, i, j = [None] * n, n, m
    while i > 0:
        if j > 0 and D[i, j] == D[i, j - 1]:
            j -= 1  # model mode j left out
        elif j > 0 and D[i, j] == D[i - 1, j - 1] + cost[i - 1, j - 1]:
            pairs[i - 1] = j - 1
            i, j = i - 1, j - 1
        else:
            i -= 1  # reference mode i unpaired
    return pairs


class Pairing(NamedTuple):
    """The model's lowest modes and their pairing with reference frequencies (:func:`paired_modes`)."""

    f_mod: np.ndarray  # the model's frequencies (Hz), ascending
    phi: np.ndarray | None  # their M-orthonormal mode shapes (``vectors``), else None
    pair: list  # per reference frequency: the index of its model mode, or None
    rigid_ref: np.ndarray  # which reference frequencies are rigid-body modes
    rigid_mod: np.ndarray  # which model frequencies are


def paired_modes(model, f_ref, *, solver: SolverContext | None = None, vectors: bool = False) -> Pairing:
    """The lowest modes of ``model`` paired with the reference frequencies ``f_ref`` (Hz).

    The pairing is one-to-one and keeps the order: each reference frequency gets a distinct
    model mode, in ascending order of both, with the smallest sum of relative differences; the
    reference may leave out model modes (a list of elastic frequencies may leave out the six
    rigid-body modes of a free body). Rigid-body modes (below 1e-4 of the largest frequency)
    pair with rigid-body modes only, in turn. The lowest ``len(f_ref) + 8`` model modes are
    computed, more when needed to give every elastic reference mode an elastic model mode;
    ``vectors`` keeps their shapes.
    """
    from ..linalg.eigen import eigenmodes

    solver = as_solver(solver)
    f_ref = np.asarray(f_ref, float)
    k = min(f_ref.size + 8, model.n_dof)
    while True:
        lam, phi = eigenmodes(model.K, model.M, k, solver=solver)
        f_mod = np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)
        tiny = 1e-4 * max(float(f_ref.max(initial=0.0)), float(f_mod.max(initial=0.0)), 1e-300)
        rig_ref, rig_mod = f_ref <= tiny, f_mod <= tiny
        need = int(np.sum(~rig_ref)) + int(np.sum(rig_mod))
        if need <= k or k >= model.n_dof:
            break
        k = min(need + 8, model.n_dof)  # the model's rigid-body modes took the room of elastic ones
    order = np.argsort(f_ref, kind="stable")  # a file in ascending order (as FE programs write) stays as it is
    pair = [None] * f_ref.size
    for rigid, sel_ref, sel_mod in ((True, rig_ref, rig_mod), (False, ~rig_ref, ~rig_mod)):
        i_ref = order[sel_ref[order]]
        i_mod = np.flatnonzero(sel_mod)
        js = range(i_mod.size) if rigid else _monotone_pairs(f_ref[i_ref], f_mod[i_mod])  # rigid: in turn
        for i, j in zip(i_ref, js):
            pair[i] = None if j is None else int(i_mod[j])
    return Pairing(f_mod, phi if vectors else None, pair, rig_ref, rig_mod)


def pairing_record(f_ref, p: Pairing) -> dict:
    """``frequencies_hz``, ``model_frequencies_hz``, ``rel_diff``, ``model_modes`` and ``notes`` of the pairing
    ``p`` (see :func:`compare_frequencies`); the notes are also issued as warnings."""
    import warnings

    from ..errors import FlexmorWarning

    f_ref = np.asarray(f_ref, float)
    pair, rig_ref, rig_mod = p.pair, p.rigid_ref, p.rigid_mod
    out_f, rel = [], []
    for i, f in enumerate(f_ref):
        g = None if pair[i] is None else float(p.f_mod[pair[i]])
        out_f.append(g)
        rel.append(None if g is None or rig_ref[i] else abs(g - f) / max(abs(f), 1e-12))
    notes = []
    n_ref, n_mod = int(np.sum(rig_ref)), int(np.sum(rig_mod))
    if n_ref != n_mod:
        notes.append(f"the reference has {n_ref} rigid-body modes, the model {n_mod}: is it the same support?")
    lost = [i + 1 for i in range(f_ref.size) if pair[i] is None and not rig_ref[i]]  # rigid ones: the note above
    if lost:
        notes.append(f"reference modes {', '.join(map(str, lost))} have no model mode to pair with (the model "
                     f"has {n_mod} rigid-body and {int(np.sum(~rig_mod))} elastic modes)")
    elastic = [(d, i) for i, d in enumerate(rel) if d is not None]
    if elastic:
        # the first of the largest, equal ones taken as equal to the eigensolver's accuracy (the two modes of
        # a pair of equal frequencies differ by round-off: which of them is named is not left to it)
        top = max(t[0] for t in elastic)
        d, i = next(t for t in elastic if t[0] >= top - EQUAL_REL * max(top, 1.0))
        if d > MISMATCH:
            notes.append(f"the largest relative difference of the elastic modes is {d:.2e} (reference mode {i + 1}, "
                         f"{f_ref[i]:.6g} Hz, against the model's mode {pair[i] + 1}, {out_f[i]:.6g} Hz), above "
                         f"{MISMATCH:g}: the reference may be of another model or support")
    for text in notes:
        warnings.warn(FlexmorWarning(text), stacklevel=3)
    return {"frequencies_hz": f_ref.tolist(), "model_frequencies_hz": out_f, "rel_diff": rel,
            "model_modes": [None if j is None else j + 1 for j in pair], "notes": notes}
