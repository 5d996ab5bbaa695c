"""The error table that ``reduce``, ``compare``, ``report`` and ``demo`` print, with its notes and legend."""

from __future__ import annotations

from ..errors import name_parameters

__all__ = ["fmt", "note_text", "notes_as_flags", "print_error_table", "print_mounted", "print_moving",
           "print_static"]


def fmt(x, spec: str = ".3e") -> str:
    """``x`` formatted with ``spec``, or ``-`` when it is None."""
    return "-" if x is None else format(x, spec)


def note_text(note: str) -> str:
    """A note of the library (error measures, mounted check, methods) with the parameters it names as flags
    (``modal_damping`` -> ``--modal-damping``)."""
    from ..analysis import frequency, mounted
    from ..reduction import _options

    params = frequency.NOTE_PARAMS + mounted.NOTE_PARAMS + _options.NOTE_PARAMS
    return name_parameters(note, params, {p: "--" + p.replace("_", "-") for p in params})


def notes_as_flags(record):
    """A JSON record with the text of each ``notes`` list and ``...note`` key through :func:`note_text`."""
    if isinstance(record, (list, tuple)):
        return [notes_as_flags(v) for v in record]
    if not isinstance(record, dict):
        return record
    out = {}
    for k, v in record.items():
        if isinstance(v, str) and k.endswith("note"):
            out[k] = note_text(v)
        elif k == "notes" and isinstance(v, list):
            out[k] = [note_text(n) if isinstance(n, str) else n for n in v]
        else:
            out[k] = notes_as_flags(v)
    return out


def _where(r) -> str:
    """Where max_rel_error occurs: ``1234 Hz``, ``1234 Hz AR`` at an anti-resonance, ``1234 Hz SR`` at a
    spurious resonance of the body (one the full model does not have)."""
    if r.get("max_rel_error_hz") is None:
        return "-"
    return (f"{r['max_rel_error_hz']:.4g} Hz" + (" AR" if r.get("max_rel_error_at_antiresonance") else "")
            + (" SR" if r.get("max_rel_error_at_spurious_resonance") else ""))


def print_error_table(rows, label: str = "method", header: str | None = None) -> None:
    """Print the error table of reduce/compare/report/demo rows, then their notes and a legend.

    Parameters
    ----------
    rows : list of dict
        One dict per body: ``order``, the error measures (``band_error``, ``rms_rel_error_pct``,
        ``hinf_error``, ``max_rel_error`` and where it occurs), ``seconds``, ``notes``,
        ``converged`` and ``convergence_note`` (a row with ``converged`` False gets a line saying
        so), ``judge_check`` (against a surrogate reference: a band_error it does not resolve prints as
        ``<FLOOR``, and a line tells the direct check) and ``same_subspace_as``; a missing value prints as ``-``.
    label : str
        The key of the first column (``method``, ``file`` or ``label``).
    header : str, optional
        The title of the first column; default ``label``.
    """
    from ..analysis.judge import band_error_text

    w = max([16] + [len(str(r.get(label, ""))) + 2 for r in rows])
    print(f"{header or label:<{w}}{'order':>6}{'band_error':>12}{'rms %':>9}{'hinf_error':>12}{'max_rel_error':>15}"
          f"{'at':>14}{'seconds':>9}")
    for r in rows:
        rms = r.get("rms_rel_error_pct")
        print(f"{str(r.get(label, '')):<{w}}{r['order']:>6}{band_error_text(r):>12}"
              f"{'-' if rms is None else format(rms, '.3g'):>9}{fmt(r.get('hinf_error'), '.2e'):>12}"
              f"{fmt(r.get('max_rel_error'), '.2e'):>15}{_where(r):>14}{fmt(r.get('seconds'), '.3f'):>9}")
    _notes(rows, label)
    _judged(rows, label)
    _checked(rows, label)
    if any(r.get("band_error") is not None for r in rows):
        print("band_error = ∫|H-Hr|²/∫|H|² over the band; rms % = 100 sqrt(band_error); hinf_error = max|H-Hr| / "
              "max|H|; max_rel_error = max |H-Hr|/|H| (AR: at an anti-resonance, where |H| is small; SR: at a spurious "
              "resonance, one the full model does not have)")


def _notes(rows, label: str) -> None:
    """The notes of the rows: the anti-resonances in one line, the others (undamped resonances) once each."""
    from ..analysis.frequency import ANTIRESONANCE_FACTOR
    from ..analysis.subspaces import SUBSPACE_MARK, subspace_note

    def name(r):
        return f"{r['method']} r={r['order']}" if label == "method" else str(r.get(label))

    ar = [name(r) for r in rows if r.get("max_rel_error_at_antiresonance") and (r.get("max_rel_error") or 0) >= 0.1]
    if ar:
        print(f"note: max_rel_error of {', '.join(ar)} lies at an anti-resonance (AR: |H| a local minimum, at most "
              f"1/{ANTIRESONANCE_FACTOR:g} of its band median): a large relative error of a small response; "
              "rms % and hinf_error measure the response itself")
    grouped: dict = {}
    for r in rows:
        for n in r.get("notes") or ():
            if not n.startswith("max_rel_error") and SUBSPACE_MARK not in n:
                grouped.setdefault(n, []).append(name(r))
    for group in _subspace_groups(rows):
        print(f"note: {subspace_note(group)}")
    for n, names in grouped.items():
        print(f"note: {', '.join(names)}: {note_text(n)}")
    for r in rows:
        if r.get("converged") is False:
            print(f"NOT CONVERGED: {name(r)}: "
                  f"{note_text(r.get('convergence_note') or 'the iteration stopped without converging')}")


def print_mounted(rows, label: str = "method") -> None:
    """Print the bodies held in their joints (``row["mounted"]``, :mod:`flexmor.analysis.mounted`), if any:
    per body, interface and support, the lowest full frequencies and the largest relative frequency
    (modes in the band) and static deflection errors."""
    lines = []
    for r in rows:
        rec = r.get("mounted")
        name = f"{r['method']} r={r['order']}" if label == "method" else str(r.get(label))
        for c in (rec or {}).get("cases", ()):
            lines.append((name, c["interface"], c["held"], " ".join(f"{f:.4g}" for f in c["frequencies_full_hz"][:4]),
                          fmt(c["max_frequency_error"], ".2e"), fmt(c["max_static_error"], ".2e")))
    if not lines:
        return
    head = ("body", "interface", "held", "full [Hz]")
    w = [max(len(h), *(len(x[i]) for x in lines)) + 2 for i, h in enumerate(head)]
    print("mounted: the body held at its interfaces against the full model held the same way")
    for x in [head + ("freq error", "static error")] + lines:
        print("".join(f"{v:<{n}}" for v, n in zip(x, w)) + f"{x[4]:>11}{x[5]:>14}")
    print("freq error = max |f_red/f_full - 1| of the held elastic modes up to the band's top, paired in order; "
          "static error = max relative error of the clamped deflection under the frame's six accelerations and the "
          "inputs (at the outputs and over the field)")
    for text in dict.fromkeys((r.get("mounted") or {}).get("damping_note") for r in rows):
        if text:
            print(f"note: {text}")


def print_static(rows, label: str = "method") -> None:
    """Print the bodies' static errors (``row["static"]``, :func:`flexmor.analysis.mounted.static_record`), if
    any: per body how it is held, the error at its outputs under its inputs and the largest error over the
    inputs and the frame's six accelerations."""
    lines = []
    for r in rows:
        rec = r.get("static")
        if rec:
            name = f"{r['method']} r={r['order']}" if label == "method" else str(r.get(label))
            lines.append((name, rec["as"], fmt(rec["static_error"], ".2e"), fmt(rec["max_static_error"], ".2e")))
    if not lines:
        return
    head = ("body", "held", "at inputs", "largest")
    w = [max(len(h), *(len(x[i]) for x in lines)) + 2 for i, h in enumerate(head)]
    print("static: the body's static deflection against the full model's, held the same way")
    for x in [head] + lines:
        print("".join(f"{v:<{n}}" for v, n in zip(x, w)).rstrip())
    print("at inputs = max over the inputs of ||C (u_red - u)|| / ||C u||; largest = max relative error at the outputs "
          "and over the field under the inputs and the frame's six accelerations (gravity x y z, angular rx ry rz)")


def print_moving(rows, label: str = "method") -> None:
    """Print the bodies' errors over their moving loads' paths (``row["moving_loads"]``,
    :func:`flexmor.moving.judge_path`) and their crossings (``row["crossings"]``, :func:`flexmor.moving.crossing`),
    if any."""
    lines, cross = [], []
    for r in rows:
        name = f"{r['method']} r={r['order']}" if label == "method" else str(r.get(label))
        for rec in r.get("moving_loads") or ():
            lines.append((name, rec["path"], str(rec["n_positions"]), fmt(rec["path_max_band_error"], ".2e"),
                          f"{rec['worst_s']:.4g} (node {rec['worst_node']})", fmt(rec["path_mean_band_error"], ".2e"),
                          fmt(rec["under_load_max"], ".2e")))
        for c in r.get("crossings") or ():
            o = c.get("outputs")
            cross.append((name, c["path"], f"{c['speed']:g}", f"{c['force']:g}", fmt(c["time_mean_error"], ".2e"),
                          fmt(c["time_max_error"], ".2e"), fmt(o["time_max_error"], ".2e") if o else "-",
                          f"{c['peak_deflection']:.4g}", f"{c['seconds_full']:.3g} / {c['seconds_body']:.3g}"))
    if lines:
        _print_table(("body", "moving load", "positions", "path max", "worst at s [m]", "mean", "under load max"),
                     lines, "moving load: band error of a unit force at each position along the path (nodes, "
                     "midpoints and the worst segments refined), at the outputs and under the load")
    if cross:
        _print_table(("body", "moving load", "speed [m/s]", "force [N]", "mean err", "max err", "outputs max",
                      "peak [m]", "full / body [s]"), cross,
                     "crossing: deflection under a force crossing the path (mean and max error) and at the outputs "
                     "(max error), body against the full model (Newmark, the same steps, from the static deflection "
                     "under the force at the path's start)")


def _print_table(head, lines, title: str) -> None:
    w = [max(len(h), *(len(x[i]) for x in lines)) + 2 for i, h in enumerate(head)]
    print(title)
    for x in [head, *lines]:
        print("".join(f"{v:<{n}}" for v, n in zip(x, w)).rstrip())


def _subspace_groups(rows) -> list[list[str]]:
    """The ``method r=order`` of the rows that span one subspace (``same_subspace_as``), grouped."""
    groups: list[list[str]] = []
    for r in rows:
        shared = list(r.get("same_subspace_as") or ())
        if not shared:
            continue
        members = [*shared, f"{r['method']} r={r['order']}"]
        hit = [g for g in groups if set(g) & set(members)]
        for g in hit:
            groups.remove(g)
        groups.append(list(dict.fromkeys([m for g in hit for m in g] + members)))
    return groups


def _checked(rows, label: str) -> None:
    """The line of the direct check of bodies judged against a surrogate (``judge_check``), if any."""
    checked = [r for r in rows if r.get("judge_check")]
    if not checked:
        return
    from ..analysis.judge import AGREEMENT

    def name(r):
        return f"{r['method']} r={r['order']}" if label == "method" else str(r.get(label))

    n = sum(r["judge_check"]["n_checks"] for r in checked)
    new = sum(r["judge_check"].get("new_solves", 0) for r in checked)
    off = [name(r) for r in checked if r["judge_check"]["corrected"]]
    floor = [name(r) for r in checked if not r["judge_check"]["resolved"]]
    text = (f"direct check: the reference is a verified surrogate; each body was checked at its worst frequencies "
            f"by solves of the full model ({n} checks, {new} solves): ")
    text += (f"corrected where they differ by more than {100 * AGREEMENT:.0f} %: {', '.join(off)}" if off
             else f"all agree within {100 * AGREEMENT:.0f} %")
    if floor:
        text += f"; below the surrogate's resolution (<: an upper bound): {', '.join(floor)}"
    print(text)


def _judged(rows, label: str) -> None:
    """The ``judged:`` line of bodies of a free model: which part of the full response they were judged
    against (the elastic part, or the response with its rigid motion); with both kinds, the bodies of each."""
    from ..analysis.compare import JUDGED_FULL

    kinds = {r.get("judged") for r in rows if r.get("judged")}
    if not kinds - {JUDGED_FULL}:
        return
    if len(kinds) == 1:
        print(f"judged: {kinds.pop()}")
        return
    for kind in sorted(kinds):
        names = [str(r.get(label)) if label != "method" else f"{r['method']} r={r['order']}" for r in rows
                 if r.get("judged") == kind]
        print(f"judged: {kind}: {', '.join(names)}")
