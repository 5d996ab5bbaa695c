"""One self-contained HTML page of a :class:`~flexmor.report.contents.Report`.

:func:`render_html` turns the report into one HTML page whose figures are PNG images embedded
as base64 ``data:`` URIs (no external resources, readable offline and attachable to a mail);
:func:`write_report` writes it atomically. :func:`flexmor.report.contents.build_report`
computes what it shows.
"""

from __future__ import annotations

import base64
import datetime
import html

import numpy as np

from .._version import __version__
from ..analysis.frequency import ANTIRESONANCE_FACTOR, MEASURES
from ..checks import describe_couplings, signed_percent
from ..damping import damping_from_dict
from ..io import atomic_write
from ..origin import describe_damping
from .contents import Report

__all__ = ["COLUMNS", "fmt", "render_html", "write_report"]

#: Columns of the summary table: (key, header, format).
COLUMNS = [("label", "body", "s"), ("method", "method", "s"), ("order", "order", "d"),
           ("band_error", "band_error", ".3e"), ("rms_rel_error_pct", "rms_rel_error [%]", ".3g"),
           ("hinf_error", "H∞ error (rel., band)", ".3e"), ("max_rel_error", "max_rel_error", ".3e"),
           ("max_rel_error_where", "max_rel_error at", "s"), ("h2_error", "H2 error (rel.)", ".3e"),
           ("time_mean_error", "time_mean_error", ".3e"),
           ("time_max_error", "time_max_error", ".3e"), ("time_seconds", "time integration [s]", ".3f"),
           ("seconds", "reduction [s]", ".3f"), ("judged_short", "judged against", "s")]


def fmt(value, spec: str) -> str:
    """Format a table entry; None/NaN give '-'."""
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return format(value, spec)


# -- rendering ---------------------------------------------------------------------------------
_CSS = ("body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}\n"
        ".t{overflow-x:auto;margin:1em 0}table{border-collapse:collapse;font-size:0.85em}"
        "th,td{border:1px solid #bbb;padding:3px 6px;\n"
        "text-align:right}th{background:#eee;font-weight:600}td{white-space:nowrap}"
        "td.l{text-align:left;white-space:normal}img{max-width:100%;display:block;margin:1em 0}\n"
        ".note{color:#666;font-size:0.9em}h2{border-bottom:1px solid #ccc;margin-top:2em}")


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


def _table(header, rows, left=(0,)) -> str:
    h = "".join(f"<th>{html.escape(str(c)).replace('_', '_<wbr>')}</th>" for c in header)
    body = "".join("<tr>" + "".join(f'<td{" class=l" if k in left else ""}>{html.escape(str(c))}</td>'
                                    for k, c in enumerate(r)) + "</tr>" for r in rows)
    return f'<div class="t"><table><tr>{h}</tr>{body}</table></div>'


def _summary_table(rows) -> str:
    """The summary table of :data:`COLUMNS`; without the method and order columns where every body's label
    says them already (``craig-bampton r=17``), so that the table fits the page."""
    said = all(str(r.get("label")) == f"{r.get('method')} r={r.get('order')}" for r in rows)
    cols = [c for c in COLUMNS if not (said and c[0] in ("method", "order"))]
    from ..analysis.judge import band_error_text

    cells = [[band_error_text(r, s) if k == "band_error" else fmt(r.get(k), s) for k, _, s in cols] for r in rows]
    return _table([c[1] for c in cols], cells, [k for k, c in enumerate(cols) if c[2] == "s"])


def _units_words(units) -> str:
    """The units of the report's numbers: SI (the file's system named), or as given."""
    if units is None:
        return "as given by the FE file (no unit system named: axes without units)"
    return "SI (m, kg, s, N)" + ("" if units == "SI" else f", the model file in {units} converted on reading")


def render_html(rep: Report) -> str:
    """The report as one self-contained HTML page (figures embedded as base64 PNG)."""
    e = html.escape
    m = rep.model
    out = [(f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{e(rep.title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{e(rep.title)}</h1>"),
           (f"<p>Model <b>{e(str(m['name']))}</b> ({e(str(m.get('source', '')))}): {m['n_dof']} DOF, "
           f"{m['n_nodes']} nodes, damping {e(describe_damping(damping_from_dict(m['damping'])))}, "
           f"units {e(_units_words(m.get('units')))}. "
           + (f"Preload {e(', '.join(map(str, m['preload'].get('specs', []))))}: K holds its geometric stiffness. "
              if isinstance(m.get("preload"), dict) else "") +
           f"Band {rep.band[0]:g}-{rep.band[1]:g} Hz. Bodies judged against the <b>{e(rep.reference)}</b>. "
           f"flexmor {e(__version__)}, {datetime.datetime.now().isoformat(timespec='seconds')}.</p>"),
           '<h2 id="summary">Summary</h2>',
           _summary_table(rep.rows),
           "<p class=note>Error measures over the band: " + "; ".join(
               f"<b>{e(k)}</b> = {e(v)}" for k, v in MEASURES.items()) + ". "
           + (f"An anti-resonance is a local minimum of &Vert;H&Vert; at most 1/{ANTIRESONANCE_FACTOR:g} of the "
              "band median. ")
           + ("Time errors of the "
           "output displacements: mean<sub>t</sub>&Vert;y&minus;&ycirc;&Vert; / mean<sub>t</sub>&Vert;y&Vert; and "
           f"max<sub>t</sub>&Vert;y&minus;&ycirc;&Vert; / max<sub>t</sub>&Vert;y&Vert;. Time integration of the "
           f"{e(rep.reference)}: {rep.time.get('seconds_full', float('nan')):.3f} s.</p>")]
    out += [f"<p class=note>{e(n)}</p>" for n in rep.notes]
    out += _coupling_section(rep)
    if "body" in rep.figures:
        out += ['<h2 id="body">The body</h2>', _img(rep.figures["body"], "nodes with ports and interface")]
    if rep.scene:
        from .view3d import render_section

        out.append(render_section(rep.scene))
    out += _mounted_section(rep.rows)
    out += _static_section(rep.rows)
    out += _moving_section(rep)
    out += ['<h2 id="frf">Transfer functions |H|</h2>', _img(rep.figures["frf"], "|H| full vs reduced"),
            '<h2 id="rel-error">rel_error(f)</h2>', _img(rep.figures["rel_error"], "rel_error per method")]
    if "singular_values" in rep.figures:
        out += ['<h2 id="singular-values">Singular values</h2>',
                _img(rep.figures["singular_values"], "singular values")]
    out.append('<h2 id="modal">Eigenfrequencies and MAC</h2>')
    if rep.modal:
        bodies = rep.modal["bodies"]
        header = ["mode", f"{rep.reference} [Hz]"] + [h for lb in bodies for h in (f"{lb} [Hz]", "Δf/f", "MAC")]
        rows = []
        for i, f in enumerate(rep.modal["full_hz"]):
            row = [i + 1, fmt(float(f), ".4f")]
            for c in bodies.values():
                row += [fmt(float(c["pair_hz"][i]), ".4f"), fmt(float(c["freq_rel_error"][i]), ".2e"),
                        fmt(float(c["pair_mac"][i]), ".4f")]
            rows.append(row)
        out.append(_table(header, rows, ()))
        if rep.modal.get("n_rigid"):
            out.append(f"<p class=note>{rep.modal['n_rigid']} rigid-body modes of the full model are left out.</p>")
        out.append("<p class=note>Each full mode is paired with the reduced mode of largest MAC (reduced modes "
                   "expanded with V); modes of repeated eigenfrequencies are aligned within their eigenspace.</p>")
        out.append(_img(rep.figures["mac"], "MAC matrices"))
    if rep.campbell:
        c = rep.campbell
        out.append(f'<h2 id="campbell">Campbell diagram: spin {e(c["spec"])} rad/s</h2>')
        header = ["speed [rad/s]", f"{rep.reference} [Hz]"] + [f"{lb} [Hz]" for lb in c["bodies"]]
        rows = []
        for i, w in enumerate(c["speeds"]):
            cells = [" ".join(f"{f:.5g}{'' if s == '-' else ' ' + s}" for f, s in
                              zip(c["full"]["frequencies_hz"][i], c["full"]["labels"][i]))]
            cells += [" ".join(f"{f:.5g}" for f in b["frequencies_hz"][i]) for b in c["bodies"].values()]
            rows.append([f"{w:.4g}", *cells])
        out.append(_table(header, rows, ()))
        worst = "; ".join(f"{e(lb)}: {v:.2e}" for lb, v in c["max_rel_error"].items())
        out.append("<p class=note>Damped frequencies in the frame turning with the body, with centrifugal "
                   "stiffening, spin softening and Coriolis forces; FW/BW: forward/backward whirl there. Largest "
                   f"relative difference to the {e(rep.reference)}: {worst}. Critical speeds (a frequency equal to "
                   "a multiple of the speed): " + (", ".join(
                       f"mode {x['mode']} x{x['multiple']} at {x['speed']:.4g} rad/s" for x in c["full"]["critical"])
                       or "none in the range") + ".</p>")
        out.append(_img(rep.figures["campbell"], "Campbell diagram"))
    t = rep.time
    out += ['<h2 id="time">Time responses</h2>',
            (f"<p>{e(t['signal'])}; {e(t['scheme'])}, dt = {t['dt']:.3g} s, {t['n_steps']} steps to "
             f"{t['t_end']:.3g} s.</p>"), _img(rep.figures["time"], "time responses and errors"), "</body></html>"]
    return "\n".join(out)


def _mounted_section(rows) -> list:
    """The section "The body in its joints" (rows with a ``mounted`` record), or nothing."""
    table = []
    for r in rows:
        for c in (r.get("mounted") or {}).get("cases", ()):
            zf, zr = c.get("damping_full"), c.get("damping_reduced")
            table.append([r["label"], c["interface"], c["held"],
                          " ".join(fmt(f, ".4g") for f in c["frequencies_full_hz"]),
                          " ".join(fmt(f, ".4g") for f in c["frequencies_reduced_hz"]),
                          fmt(c["max_frequency_error"], ".2e"), fmt(c["max_static_error"], ".2e"),
                          " / ".join(" ".join(fmt(z, ".2g") for z in zs[:3]) if zs else "-" for zs in (zf, zr))])
    if not table:
        return []
    notes = [f"<p class=note>{html.escape(n)}</p>" for n in dict.fromkeys((r.get("mounted") or {}).get("damping_note")
                                                                          for r in rows) if n]
    return ['<h2 id="mounted">The body in its joints</h2>',
            _table(["body", "interface", "held", "full model held [Hz]", "body held [Hz]", "max Δf/f (band)",
                    "static error", "ζ of the first 3: full / body"],
                   table, (0, 1, 2, 3, 4, 7)),
            "<p class=note>Each interface clamped (its six master DOFs held) and pinned (three translations held), "
            "the reduced body (its floating frame and elastic coordinates under the same constraint) against the full "
            "model supported the same way: the held elastic eigenfrequencies, and the relative error of the clamped "
            "static deflection under the frame's six accelerations and under each input (at the outputs and the "
            "largest displacement error over the body). The held modes up to the band's top, paired in order (a mode "
            "the body misses shifts the pairs above it).</p>", *notes]


def _static_section(rows) -> list:
    """The section "Static response" (rows with a ``static`` record), or nothing."""
    def by_load(x):
        return f"{x['load']} {fmt(x['output_error'] if x['output_error'] is not None else x['field_error'], '.1e')}"

    table = [[r["label"], rec["as"], fmt(rec["static_error"], ".2e"), fmt(rec["max_static_error"], ".2e"),
              ", ".join(by_load(x) for x in rec["loads"])] for r in rows for rec in [r.get("static")] if rec]
    if not table:
        return []
    return ['<h2 id="static">Static response</h2>',
            _table(["body", "held", "error at the inputs", "largest", "by load (at the outputs, else the field)"],
                   table, (0, 1, 4)),
            "<p class=note>The body's static deflection against the full model's, supported as it is (a free body: "
            "clamped at its first interface): under each input (the error at the outputs) and under the frame's six "
            "accelerations, gravity in x, y, z and unit angular accelerations (at the outputs and the largest "
            "displacement error over the body). The band error hides it at the band's low end; an MBS model under "
            "gravity or a slow load sags by it.</p>"]


def _moving_section(rep: Report) -> list:
    """The section "Moving loads" (bodies reduced with one), or nothing."""
    if not rep.moving:
        return []
    paths = [[lb, r["path"], r["n_positions"], fmt(r["path_max_band_error"], ".2e"),
              f"{r['worst_s']:.4g} (node {r['worst_node']})", fmt(r["path_mean_band_error"], ".2e"),
              fmt(r["under_load_max"], ".2e")] for lb, recs in rep.moving["paths"].items() for r in recs]
    cross = [[lb, c["path"], f"{c['speed']:g}", f"{c['force']:g}", fmt(c["time_mean_error"], ".2e"),
              fmt(c["time_max_error"], ".2e"), f"{c['peak_deflection']:.4g}",
              f"{c['seconds_full']:.3g} / {c['seconds_body']:.3g}"] for lb, cs in rep.moving["crossings"].items()
             for c in cs]
    return ['<h2 id="moving">Moving loads</h2>',
            _table(["body", "path", "positions", "path max band_error", "worst at s [m]", "mean", "under the load"],
                   paths, (0, 1, 4)),
            "<p class=note>A unit force at each position s along the path (every node and midpoint, the worst "
            "segments refined; linear between the path's nodes): the band error of the response at the outputs and "
            "under the load. Positions where the full model does not move (a held node) are left out.</p>",
            _img(rep.figures["moving_path"], "band error along the path"),
            _table(["body", "path", "speed [m/s]", "force [N]", "mean error", "max error", "peak deflection [m]",
                    "time full / body [s]"], cross, (0, 1)),
            "<p class=note>The deflection under a force crossing the path from its first node to its last, body "
            f"against the {html.escape(rep.reference)} (Newmark, the same steps): "
            "mean<sub>t</sub>|y&minus;&ycirc;| / mean<sub>t</sub>|y| and max<sub>t</sub>|y&minus;&ycirc;| / "
            "max<sub>t</sub>|y|.</p>",
            _img(rep.figures["moving_crossing"], "deflection under a crossing force")]


def _coupling_section(rep: Report) -> list:
    """The coupling paragraph and table: the lowest elastic frequencies of the FE model as read and coupled."""
    c = rep.coupling
    if not c or not c.get("coupled_hz"):
        return []
    e = html.escape
    ch = c["rel_change"]
    rows = [[i, fmt(float(a), ".4f"), fmt(float(b), ".4f"), f"{signed_percent(d, 3)} %"]
            for i, (a, b, d) in enumerate(zip(c["uncoupled_hz"], c["coupled_hz"], ch), 1)]
    return ['<h2 id="coupling">Coupling</h2>',
            (f"<p>{e(describe_couplings(c['couplings']))} changes the lowest elastic frequencies by "
             f"{signed_percent(min(ch), 3)} to {signed_percent(max(ch), 3)} % over the FE model as read: the "
             f"{e(rep.reference)} "
             "is what the bodies are reduced from and judged against (right for the assembly the coupling "
             "stands for; the FE model as read is another model).</p>"),
            _table(["mode (by rank)", "FE model as read [Hz]", "coupled [Hz]", "change"], rows, ())]


def write_report(rep: Report, path) -> None:
    """Write :func:`render_html` of ``rep`` to ``path`` atomically (UTF-8)."""
    text = render_html(rep)

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write(path, write)

