"""``flexmor info`` on what is not an FE model: a reduced body (``BODY.h5``: what it is and where
it came from), the solver backends (``--backends``) and the file formats (``--formats``)."""

from __future__ import annotations

import json
from pathlib import Path

from .tables import note_text

__all__ = ["is_body_file", "info_body", "interface_lines", "info_backends", "info_formats", "print_mass_properties",
           "coupling_lines"]


def is_body_file(path, format: str | None) -> bool:
    """Whether ``path`` (or ``--format``) names a reduced body rather than an FE model: by its suffix, and by
    its content where the suffix is both (a Nastran Craig-Bampton superelement, :func:`flexmor.io.kind_of`)."""
    from ..io import kind_of

    return kind_of(Path(path), format) == "body"


#: ``info["format"]`` of a body read from a Nastran superelement (:mod:`flexmor.io.nastran.nastran_se`).
_NASTRAN_SE = "nastran superelement"


def _made_by(red, path, version) -> str:
    """Where the body came from, for the first row of ``info BODY``."""
    if red.info.get("format") != _NASTRAN_SE:
        return f"written by flexmor {version}"
    src = Path(str(red.info.get("source") or path)).name
    what = (f"a Nastran Craig-Bampton superelement: {red.info.get('n_boundary', '?')} boundary DOFs, "
            f"{red.info.get('n_modal', '?')} modal coordinates")
    return what if src == Path(path).name else f"{what}, from {src}; written by flexmor {version}"


def interface_lines(masters) -> list[str]:
    """One line per coupling master: ``HOLE@RBE2: master node 4183 (RBE2, 6 DOF) at [x, y, z], 100 slave nodes``."""
    return [f"{m['name']}: master node {m['id']} ({m['kind'].upper()}, 6 DOF x y z rx ry rz) at "
            f"[{', '.join(f'{v:.6g}' for v in m['xyz'])}], {m['n_slaves']} slave nodes" for m in masters]


def _row(name: str, value, width: int = 12) -> None:
    print(f"{name:<{width}}{value}")


def info_body(args, emit_json) -> int:
    """Print (or emit as JSON) the summary of the body ``args.model``."""
    from ..damping import damping_from_dict
    from ..io import read_body
    from ..origin import describe_damping

    red = read_body(args.model, format=args.format)
    se = red.info.get("format") == _NASTRAN_SE
    out = dict(red.summary(), file=str(args.model), coupling_frequencies=red.info.get("coupling_frequencies"),
               made_by="nastran" if se else "flexmor")
    if se:
        out["nastran"] = {k: red.info.get(k) for k in ("source", "matrices", "n_boundary", "n_modal",
                                                         "fixed_interface_hz", "kbq_rel")}
    if args.json:
        emit_json(out)
        return 0
    _row("body", f"{args.model}  ({_made_by(red, args.model, out['version'])})")
    asked = out["order_requested"]
    _row("method", f"{out['method']}, order {out['order']}"
         + (f" ({asked} requested)" if asked not in (None, out["order"]) else ""))
    if out["order_note"]:
        _row("", out["order_note"])
    opts = {k: v for k, v in out["options"].items() if k != "backend"}
    if opts:
        _row("options", ", ".join(f"{k}={v}" for k, v in opts.items()))
    _row("inputs", ", ".join(out["inputs"]) or "-")
    _row("outputs", ", ".join(out["outputs"]) or "-")
    if out["couplings"]:
        _row("couplings", ", ".join(out["couplings"]))
    for line in interface_lines(out["masters"]):
        _row("interface", line)
    for line in coupling_lines(red.info.get("coupling_frequencies")):
        _row("", line)
    _row("damping", describe_damping(damping_from_dict(out["damping"])))
    fr = out["frequencies_hz"]
    if fr is not None:
        _row("freqs [Hz]", " ".join(f"{f:.5g}" for f in fr[:16]) + (" ..." if len(fr) > 16 else ""))
    fi = red.info.get("fixed_interface_hz") if se else None
    if fi:
        _row("fixed [Hz]", " ".join(f"{f:.5g}" for f in fi[:16]) + (" ..." if len(fi) > 16 else "")
             + "  (modal coordinates: the interface held)")
    err = out["errors"]
    if err.get("band_error") is not None:
        band = err.get("band_hz") or ["?", "?"]
        text = f"band {band[0]:g}-{band[1]:g} Hz: band_error {err['band_error']:.3e}"
        if err.get("rms_rel_error_pct") is not None:
            text += (f", rms_rel_error {err['rms_rel_error_pct']:.3g} %, hinf_error {err['hinf_error']:.3e}, "
                     f"max_rel_error {err['max_rel_error']:.3e} at {err['max_rel_error_hz']:.4g} Hz"
                     + (" (anti-resonance)" if err.get("max_rel_error_at_antiresonance") else "")
                     + (" (spurious resonance)" if err.get("max_rel_error_at_spurious_resonance") else ""))
        elif err.get("max_rel_error") is not None:
            text += f", max_rel_error {err['max_rel_error']:.3e}"
        _row("errors", text)
        if err.get("judged"):
            _row("judged", err["judged"])
        for note in err.get("notes") or ():
            _row("note", note_text(note))
    else:
        _row("errors", "not evaluated")
    _mounted_rows(err.get("mounted"))
    m = out["model"]
    if m:
        _row("model", f"{m.get('name')} ({m.get('source') or 'no file'}): {m['n_dof']:,} DOF, {m['n_nodes']:,} nodes")
        _row("fingerprint", f"K {m.get('K')}, M {m.get('M')}, DOF map {m.get('dof_map')}"
             + (f", D {m['D']}" if m.get("D") else ""))
        made = [f"{k} {', '.join(m[k])}" for k in ("couplings", "interfaces", "selections") if m.get(k)]
        if made:
            _row("", "; ".join(made))
    elif se:
        _row("model", f"{out['model_name'] or '?'}: reduced by Nastran, so the body records no fingerprint of its "
                      "FE model (a full model given to compare or report is not checked against it)")
    else:
        _row("model", f"{out['model_name'] or '?'} (no fingerprint: written by an older flexmor)")
    return 0


def _mounted_rows(rec) -> None:
    """The body held in its joints (``errors["mounted"]``, :mod:`flexmor.analysis.mounted`): one row per case."""
    if not rec:
        return
    for k, c in enumerate(rec.get("cases", ())):
        fe, se = c.get("max_frequency_error"), c.get("max_static_error")
        text = (f"{c['held']} at {c['interface']}" + (f" (node {c['node']})" if c.get("node") is not None else "")
                + ": full " + " ".join(f"{f:.4g}" for f in c["frequencies_full_hz"][:4]) + " Hz, freq error "
                + ("-" if fe is None else f"{fe:.2e}") + ("" if se is None else f", static error {se:.2e}"))
        _row("mounted" if k == 0 else "", text)
    if rec.get("note"):
        _row("", f"note: {note_text(rec['note'])}")


def info_backends(args) -> int:
    """Print (or emit as JSON) the solver backends, what they handle, and the memory available."""
    from ..linalg.backends import describe_backends, memory_available

    rows = describe_backends()
    avail = memory_available()
    if args.json:
        print(json.dumps({"backends": rows, "memory_available_mb": None if avail is None else avail / 2**20}))
        return 0
    for r in rows:
        flags = ("available" if r["available"] else "not installed") + (", complex" if r["complex"] else "") + \
            (", SPD only" if r["positive_only"] else "")
        print(f"{r['name']:<8} {flags:<32} {r['description']}")
    if avail is not None:
        print(f"memory available: {avail / 2**20:.0f} MB (what does not fit runs in mixed precision or out of core)")
    return 0


_FORMAT_TITLES = {"model": "FE models (info, reduce, compare, report MODEL; --format NAME)",
                  "body": "reduced bodies (compare, report, export BODY)",
                  "export": "exports (export BODY -o FILE; --format NAME)"}


def info_formats(args, emit_json) -> int:
    """Print (or emit as JSON with ``emit_json``) the registered model, body and export formats."""
    from ..io import describe_formats

    table = describe_formats()
    if args.json:
        emit_json({"formats": table})
        return 0
    lines = {kind: [(r["name"] + (f" ({', '.join(r['aliases'])})" if r["aliases"] else ""),
                     " ".join(r["suffixes"] + ([r["claims"]] if r["claims"] else []))
                     + (" (also .gz)" if r["gzip"] and kind != "export" else ""), r["description"])
                    for r in rows] for kind, rows in table.items()}
    w0, w1 = (max(len(line[i]) for rows in lines.values() for line in rows) for i in (0, 1))
    for kind, rows in lines.items():
        print(("\n" if kind != "model" else "") + _FORMAT_TITLES[kind])
        for name, suffixes, description in rows:
            print(f"  {name:<{w0}}  {suffixes:<{w1}}  {description}")
    return 0


def print_mass_properties(out: dict) -> None:
    """The bounding box, mass and centre of mass lines of ``flexmor info MODEL``."""
    box = out.get("bounding_box")
    if box:
        _row("bbox", "x {:.6g} .. {:.6g}, y {:.6g} .. {:.6g}, z {:.6g} .. {:.6g} (length unit of the file)".format(
            *(v for pair in zip(*box) for v in pair)), 10)
    mass = out.get("mass")
    if mass and any(m is not None for m in mass):
        known = [m for m in mass if m is not None]
        text = (f"{known[0]:.6g}" if max(known) - min(known) <= 1e-9 * max(known)
                else "x {} y {} z {}".format(*("-" if m is None else f"{m:.6g}" for m in mass)))
        _row("mass", text + " (mass unit of the file; DOFs constrained in the export carry none)", 10)
    if out.get("center_of_mass"):
        _row("c.o.m.", "({:.6g}, {:.6g}, {:.6g})".format(*out["center_of_mass"]), 10)


def coupling_lines(rec) -> list[str]:
    """Lines on the coupling record of :func:`flexmor.checks.coupling_frequencies` (none without one)."""
    from ..checks import describe_couplings

    if not rec or not rec.get("coupled_hz"):
        return []
    ch = rec["rel_change"]
    lines = [f"{describe_couplings(rec['couplings'])} changes the lowest elastic frequencies by "
             f"{100 * min(ch):+.2f} to {100 * max(ch):+.2f} % against the FE model as read "
             "(the coupled model is the one reduced and judged against)"]
    lines.append("mode  FE model [Hz]  coupled [Hz]  change")
    lines += [f"{i:4d}  {a:13.6g}  {b:12.6g}  {100 * c:+.3f} %"
              for i, (a, b, c) in enumerate(zip(rec["uncoupled_hz"], rec["coupled_hz"], ch), 1)]
    return lines
