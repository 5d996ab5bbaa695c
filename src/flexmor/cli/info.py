"""``flexmor info`` on what is not an FE model: a reduced body (``BODY.h5``: what it is and where
it came from), the solver backends (``--backends``) and the file formats (``--formats``)."""

from __future__ import annotations

import json
from pathlib import Path

from .tables import fmt, note_text

__all__ = ["is_body_file", "info_body", "interface_lines", "info_backends", "info_formats", "print_mass_properties",
           "coupling_lines", "BASIS_KEYS", "basis_record", "basis_rows"]


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
    nb = red.info.get("n_boundary", "?")
    what = (f"a Nastran Craig-Bampton superelement: {nb} boundary DOF{'' if nb == 1 else 's'}, "
            f"{red.info.get('n_modal', '?')} modal coordinates")
    return what if src == Path(path).name else f"{what}, from {src}; written by flexmor {version}"


def interface_lines(masters) -> list[str]:
    """One line per coupling master: ``HOLE@RBE2: master node 4183 (RBE2, 6 DOF) at [x, y, z], 100 slave nodes``."""
    return [f"{m['name']}: master node {m['id']} ({m['kind'].upper()}, 6 DOF x y z rx ry rz) at "
            f"[{', '.join(f'{v:.6g}' for v in m['xyz'])}], {m['n_slaves']} slave nodes" for m in masters]


#: The entries of a body's record (``info``) that say how its basis was built: expansion points, the band,
#: cutoff and quadrature of the Gramians, snapshots, iterations, the interface of a CMS basis, Krylov's estimate.
BASIS_KEYS = ("points_hz", "moments", "points_check", "compressed", "intermediate", "gramian", "gramians", "band_hz",
              "band_requested_hz", "cutoff_hz", "n_nodes", "snapshots", "energy_captured", "iterations", "max_iter",
              "shift_change", "shift_tol", "n_interface_dofs", "n_internal", "n_inertia_loads", "inertia_interfaces")


def basis_record(info: dict) -> dict:
    """The entries of :data:`BASIS_KEYS` that ``info`` (a body's record) holds, and ``krylov_points_hz``, the
    points of a first Krylov step (two-step, svdmor): what ``info BODY`` shows as text and as JSON."""
    rec = {k: info[k] for k in BASIS_KEYS if info.get(k) is not None}
    inner = info.get("krylov")
    if isinstance(inner, dict) and inner.get("points_hz"):
        rec["krylov_points_hz"] = inner["points_hz"]
    return rec


def _points(points) -> str:
    """Expansion points ``s / (2 pi)`` as text: ``0, 659.3i, 1652i`` (``i``: on the frequency axis)."""
    out = []
    for p in points:
        c = complex(str(p).replace(" ", ""))
        re_, im = f"{c.real:.4g}", f"{abs(c.imag):.4g}i"
        out.append(re_ if c.imag == 0 else im if c.real == 0 else f"{re_}{'-' if c.imag < 0 else '+'}{im}")
    return ", ".join(out)


def basis_rows(rec: dict) -> list[tuple[str, str]]:
    """``(label, text)`` rows of a :func:`basis_record`, for the text output of ``info`` and ``reduce``."""
    rows = []
    if rec.get("n_inertia_loads"):  # inputs the basis was built for beside the ports
        held = rec.get("inertia_interfaces")
        rows.append(("built for", f"the ports and {rec['n_inertia_loads']} inertia loads: "
                     + (f"the frame's accelerations of the body held at {', '.join(held)}" if held else
                        "the frame's unit accelerations M R") + " (--inertia-loads; off: the ports alone)"))
    if rec.get("points_hz"):
        moments = rec.get("moments")
        rows.append(("points", f"{_points(rec['points_hz'])} Hz (s / 2 pi)"
                     + (f", moments {', '.join(map(str, moments)) if isinstance(moments, list) else moments}"
                        if moments is not None else "")))
    check = rec.get("points_check")
    if isinstance(check, dict) and check.get("estimate") is not None:
        first = check.get("checks_hz") or []
        if isinstance(check.get("second_reference"), dict):  # its checks follow the first reference's
            first = first[:len(first) - len(check["second_reference"].get("checks_hz") or [])]
        more = first[1:]
        text = f"band_error {check['estimate']:.3g} (against the body " + (
            f"of the greedy basis of order {check['reference_order']} " if check.get("reference_order") else "")
        text += "enriched by the full solution"
        if check.get("check_hz") is not None:
            text += f"s at {check['check_hz']:.4g} and {more[0]:.4g} Hz" if more else f" at {check['check_hz']:.4g} Hz"
            if check.get("pointwise_at_check") is not None:
                text += f", its relative error at {check['check_hz']:.4g} Hz {check['pointwise_at_check']:.3g}"
        second = check.get("second_reference")
        if isinstance(second, dict) and second.get("checks_hz"):
            text += (f"; that body enriched again at {', '.join(f'{q:.4g}' for q in second['checks_hz'])} Hz, "
                     f"order {second['order']}, where the larger greedy body is far worse than the body")
        rows.append(("estimate", text + "; the judge's figure is verified)"))
    comp = rec.get("compressed")
    if isinstance(comp, dict) and comp.get("body"):
        diffs = comp.get("differences") or {}
        what = {"greedy": "the leading columns", "balanced": "the balanced truncation",
                "static+balanced": "the static responses and the balancing directions",
                "static+dynamic": "the static responses and the balancing directions of the dynamic part"}.get(
                    comp["body"], comp["body"])
        if comp["body"] == "reference balanced":
            what = f"the balanced truncation of the reference body (order {(check or {}).get('reference_order')})"
        else:
            what += f" of the greedy basis of order {comp.get('from_order')}"
        kept = "" if comp.get("keep_static", True) else "; --compress band: the static responses not kept"
        rows.append(("compressed", f"{what} (differences from the reference: "
                     + ", ".join(f"{k} {v:.3g}" for k, v in diffs.items()) + f"{kept}; --compress off: the greedy "
                     "basis of the order)"))
    if rec.get("krylov_points_hz"):
        rows.append(("points", f"{_points(rec['krylov_points_hz'])} Hz (s / 2 pi) of the Krylov step"
                     + (f" to order {rec['intermediate']}" if rec.get("intermediate") else "")))
    band = rec.get("band_hz")
    if rec.get("gramians") or rec.get("gramian"):
        text = str(rec.get("gramians") or f"{rec['gramian']} Gramians")
        if band:
            text += f"; band {band[0]:g}-{band[1]:g} Hz"
        asked = rec.get("band_requested_hz")
        if asked and list(asked) != list(band or ()):
            text += f" (asked {asked[0]:g}-{asked[1]:g} Hz)"
        if rec.get("cutoff_hz") is not None:
            text += f", cutoff {rec['cutoff_hz']:g} Hz"
        rows.append(("gramians", text))
    if rec.get("snapshots"):
        text = f"{rec['snapshots']}" + (f" over {band[0]:g}-{band[1]:g} Hz" if band else "")
        if rec.get("n_nodes"):
            text += f", {rec['n_nodes']} quadrature nodes"
        if rec.get("energy_captured") is not None:
            text += f", energy captured {rec['energy_captured']:.6g}"
        rows.append(("snapshots", text))
    if rec.get("iterations") is not None:
        text = f"{rec['iterations']}" + (f" of max_iter {rec['max_iter']}" if rec.get("max_iter") else "")
        if rec.get("shift_change") is not None:
            text += f", last change of the points {rec['shift_change']:.2g}" + (
                f" (shift_tol {rec['shift_tol']:g})" if rec.get("shift_tol") is not None else "")
        rows.append(("iterations", text))
    if rec.get("n_interface_dofs") is not None:
        rows.append(("interface", f"{rec['n_interface_dofs']} DOFs"
                     + (f" + {rec['n_internal']} internal vectors" if rec.get("n_internal") is not None else "")))
    return rows


def _row(name: str, value, width: int = 12) -> None:
    print(f"{name:<{width}}{value}")


def _study_text(study: dict) -> str:
    """One line on the study a body records: its model file, checksum and preparation."""
    model = study.get("model", {})
    prep = [f"{k} {', '.join(map(str, v)) if isinstance(v, list) else v}" for k, v in model.items()
            if k in ("format", "mesh", "units", "select", "preload", "material")]
    return (f"from {model.get('file')} (SHA-256 {str(model.get('sha256'))[:12]}...)" + (f"; {'; '.join(prep)}" if prep
                                                                                         else "")
            + " (info --json: the whole study)")


def info_body(args, emit_json) -> int:
    """Print (or emit as JSON) the summary of the body ``args.model``."""
    from ..damping import damping_from_dict
    from ..io import read_body
    from ..origin import describe_damping

    red = read_body(args.model, format=args.format)
    se = red.info.get("format") == _NASTRAN_SE
    out = dict(red.summary(), file=str(args.model), coupling_frequencies=red.info.get("coupling_frequencies"),
               made_by="nastran" if se else "flexmor", coordinates=_coordinates(red), preload=red.info.get("preload"),
               basis=basis_record(red.info), study=red.info.get("study"))
    if se:
        out["nastran"] = {k: red.info.get(k) for k in ("source", "matrices", "n_boundary", "n_modal",
                                                         "fixed_interface_hz", "kbq_rel")}
    if getattr(args, "modes", 0):
        out["modes"] = _mode_table(red, args.modes)
    if getattr(args, "campbell", None) is not None:
        out["campbell"] = body_campbell(red, args.campbell)
    if args.json:
        emit_json(out)
        return 0
    _row("body", f"{args.model}  ({_made_by(red, args.model, out['version'])})")
    asked = out["order_requested"]
    _row("method", f"{out['method']}, order {out['order']}"
         + (f" ({asked} requested)" if asked not in (None, out["order"]) else ""))
    if out["order_note"]:
        _row("", note_text(out["order_note"]))
    if out["converged"] is not None:
        _row("converged", "yes" if out["converged"] else
             f"NO: {note_text(out['convergence_note'] or 'the iteration stopped without converging')}")
    for label, text in basis_rows(out["basis"]):
        _row(label, text)
    _row("coordinates", _coordinates_text(out["coordinates"]))
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
    preload = red.info.get("preload")
    if isinstance(preload, dict) and preload.get("specs"):
        given = " and --material" if preload.get("material") else ""
        _row("preload", f"{', '.join(map(str, preload['specs']))}"
                        + (" with a material in place of the deck's" if given else "")
                        + f": its K holds their geometric stiffness (judge and compare it with the same --preload"
                        f"{given}; export --model applies them itself)")
    _row("units", _units_line(out["units"], "the body is in SI; export --export-units writes other systems"))
    if out["study"]:
        _row("study", _study_text(out["study"]))
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
    _static_rows(err.get("static"))
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
    spin = red.info.get("spin")
    if spin:
        c = spin["check"]
        _row("spin", f"{spin['spec']} rad/s: K + w^2 K2 and the Coriolis matrix w G1; the lowest "
                     f"{len(c['full_hz'][0])} frequencies within {c['max_rel_error']:.2e} of the full model's at "
                     f"{', '.join(f'{w:g}' for w in c['speeds'])} rad/s")
    if out.get("modes"):
        _print_mode_table(out["modes"])
    if out.get("campbell"):
        print_campbell(out["campbell"])
    return 0


def _mode_table(body, n: int) -> dict:
    """The mode table of ``body`` (:func:`flexmor.modal.mode_table`; its first ``n`` modes, all for
    ``n < 0``) over the band it was reduced for, and the sums of its effective masses."""
    from ..modal import mode_table
    from ..options import DEFAULT_BAND

    band = body.info.get("band") or (body.errors or {}).get("band_hz")
    source = "the band the body was reduced for" if band else "the default band"
    band = list(band or DEFAULT_BAND)
    rows = mode_table(body, band=band)
    has_mass = rows[0]["effective_mass"] is not None
    sums = {"effective_mass": [sum(r["effective_mass"][a] for r in rows) for a in range(3)],
            "effective_inertia": [sum(r["effective_inertia"][a] for r in rows) for a in range(3)]} if has_mass else {}
    return {"band_hz": band, "band_source": source, "rows": rows if n < 0 else rows[:n], "n_modes": len(rows),
            "sums": sums, "model_mass": body.info.get("frame_mass"), "damped": body.D is not None,
            "frame": "the origin of the FE model's coordinates, its x y z axes"}


def _print_mode_table(table) -> None:
    rows, band, s = table["rows"], table["band_hz"], table["sums"]
    print("\n mode  frequency [Hz]     zeta   effective mass x y z          effective inertia x y z       share "
          f"({band[0]:g}-{band[1]:g} Hz)")
    # round-off (below 1e-10 of the model's mass and inertia, else of the column's sum) shown as 0
    total = table.get("model_mass")
    ref = {"effective_mass": total[:3], "effective_inertia": total[3:]} if total else s
    floor = {k: [1e-10 * abs(x) for x in ref[k]] for k in ref} if ref else {}

    def triple(v, key):
        if v is None:
            return f"{'-':>29}"
        return " ".join(f"{(0.0 if abs(x) <= floor[key][a] else x):9.4g}" for a, x in enumerate(v))

    for r in rows:
        zeta = "-" if r["damping_ratio"] is None else f"{r['damping_ratio']:.3g}"
        share = "-" if r["response_share"] is None else f"{100 * r['response_share']:.3g} %"
        f = 0.0 if r["rigid"] else r["frequency_hz"]
        print(f"{r['mode']:5d}  {f:14.6g}  {zeta:>7}   {triple(r['effective_mass'], 'effective_mass')}   "
              f"{triple(r['effective_inertia'], 'effective_inertia')}   {share}" + ("  rigid" if r["rigid"] else ""))
    if s:
        print(f"{'sum':>5}  {'':14}  {'':>7}   {triple(s['effective_mass'], 'effective_mass')}   "
              f"{triple(s['effective_inertia'], 'effective_inertia')}"
              + (f"   (all {table['n_modes']} modes)" if len(rows) < table["n_modes"] else ""))
        if total:
            print(f"{'model':>5}  {'':14}  {'':>7}   {triple(total[:3], 'effective_mass')}   "
                  f"{triple(total[3:], 'effective_inertia')}   (the FE model's mass and inertia)")
        print("effective mass and inertia: about the frame (the origin of the FE coordinates, their axes), in the "
              "model's units; over the modes of a body whose basis holds the rigid-body motions they sum to its "
              "mass and inertia (elastic modes of a free body carry none: the frame does)")
    else:
        print("effective masses: not recorded in this body (reduced before flexmor recorded them); reduce again")
    print("share: the mode's part of the port response over the band (its own FRF term squared, integrated)"
          + f", {table['band_source']}" + ("; undamped body: with 2 % damping" if not table["damped"] else ""))


def _coordinates(body) -> dict:
    """How many of the body's coordinates are rigid-body motion (zero eigenvalues of its ``K, M``)
    and elastic, and how many an MBS export (SID, Exudyn) writes: the elastic ones (the frame
    carries the rigid-body motion; a basis holding it is written with ``--remove-rigid`` only)."""
    import numpy as np

    from ..linalg.eigen import is_rigid

    try:
        n_rigid = int(np.sum(is_rigid(body.eigenvalues(), body.K, body.M)))
    except Exception:  # noqa: BLE001 (a body whose M is singular: its count stays unknown)
        n_rigid = None
    excluded = int(body.info.get("n_rigid_excluded") or 0)
    return {"n": int(body.order), "rigid": n_rigid, "elastic": None if n_rigid is None else body.order - n_rigid,
            "rigid_excluded_from_basis": excluded,
            "mbs_export": None if n_rigid is None else body.order - n_rigid,
            "mbs_export_needs_remove_rigid": bool(n_rigid)}


def _coordinates_text(c) -> str:
    if c["rigid"] is None:
        return f"{c['n']} (rigid/elastic split unknown: singular reduced mass matrix)"
    text = f"{c['n']}: {c['rigid']} rigid-body, {c['elastic']} elastic"
    if c["rigid_excluded_from_basis"]:
        text += f" ({c['rigid_excluded_from_basis']} rigid-body modes excluded from the basis: the frame carries them)"
    if c["rigid"]:
        return text + (f"; SID/Exudyn export: {c['mbs_export']} elastic coordinates with --remove-rigid "
                       "(refused without)")
    return text + f"; SID/Exudyn export: {c['mbs_export']} elastic coordinates"


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


def _static_rows(rec) -> None:
    """The body's static error (``errors["static"]``, :func:`flexmor.analysis.mounted.static_record`): one row."""
    if not rec:
        return
    _row("static", f"{rec['as']}: error at the inputs {fmt(rec['static_error'], '.2e')}, largest over the inputs "
         f"and the frame's six accelerations {fmt(rec['max_static_error'], '.2e')}")
    if rec.get("note"):
        _row("", f"note: {note_text(rec['note'])}")


def info_backends(args) -> int:
    """Print (or emit as JSON) the solver backends, what they handle, and the memory available."""
    from ..linalg.backends import describe_backends
    from ..linalg.resources import memory_available

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


def _units_line(units, si_note: str, stated: str | None = None) -> str:
    """The ``units`` row: the file's system (and ``si_note``), or the model's numbers as given (in the
    system the file ``stated``, where it names one)."""
    from ..units import describe_units

    if units is None and stated:
        return f"as in the file, whose header states {stated} (read as given)"
    if units is None:
        return "as given (the file states no unit system; give --units SI, mm-t-s, ... to convert to SI)"
    return f"{describe_units(units)}; {si_note}"


def print_mass_properties(out: dict) -> None:
    """The units, bounding box, mass and centre of mass lines of ``flexmor info MODEL``."""
    known_units = out.get("units") is not None
    _row("units", _units_line(out.get("units"), "the numbers below are SI", out.get("stated_units")), 10)
    box = out.get("bounding_box")
    if box:
        _row("bbox", "x {:.6g} .. {:.6g}, y {:.6g} .. {:.6g}, z {:.6g} .. {:.6g} ({})".format(
            *(v for pair in zip(*box) for v in pair), "m" if known_units else "length unit of the file"), 10)
    mass = out.get("mass")
    if mass and any(m is not None for m in mass):
        known = [m for m in mass if m is not None]
        text = (f"{known[0]:.6g}" if max(known) - min(known) <= 1e-9 * max(known)
                else "x {} y {} z {}".format(*("-" if m is None else f"{m:.6g}" for m in mass)))
        _row("mass", text + f" ({'kg' if known_units else 'mass unit of the file'}; DOFs constrained in the export "
                            "carry none)", 10)
    if out.get("center_of_mass"):
        _row("c.o.m.", "({:.6g}, {:.6g}, {:.6g})".format(*out["center_of_mass"]), 10)


def coupling_lines(rec) -> list[str]:
    """Lines on the coupling record of :func:`flexmor.checks.coupling_frequencies` (none without one)."""
    from ..checks import describe_couplings, signed_percent

    if not rec or not rec.get("coupled_hz"):
        return []
    ch = rec["rel_change"]
    lines = [f"{describe_couplings(rec['couplings'])} changes the lowest elastic frequencies by "
             f"{signed_percent(min(ch), 3)} to {signed_percent(max(ch), 3)} % against the FE model as read "
             "(the coupled model is the one reduced and judged against)"]
    lines.append("mode  FE model [Hz]  coupled [Hz]  change")
    lines += [f"{i:4d}  {a:13.6g}  {b:12.6g}  {signed_percent(c, 3)} %"
              for i, (a, b, c) in enumerate(zip(rec["uncoupled_hz"], rec["coupled_hz"], ch), 1)]
    return lines


def body_campbell(red, value) -> dict:
    """The Campbell record of a body reduced with ``--spin-range`` (``value``: ``AXIS:W0:W1[:N]`` about its axis,
    or empty: over its own range)."""
    import numpy as np

    from ..errors import OptionError
    from ..spin import campbell, parse_axis_speeds, parse_spin_range

    spin = red.info.get("spin")
    if not spin:
        raise OptionError("--campbell needs a body reduced with --spin-range (it carries the spin's stiffness and "
                          "Coriolis matrices), or the model", params=("campbell",))
    if value:
        sr, n = parse_axis_speeds(value)
        if not np.allclose(sr.axis, spin["axis"], atol=1e-12):
            raise OptionError(f"--campbell {value}: the body was reduced for spin about {spin['axis']}, not "
                              f"{sr.axis.tolist()}", params=("campbell",))
    else:
        sr, n = parse_spin_range(spin["spec"]), 11
    k = max(1, min(6, red.order // 2))
    c = campbell(red.M, red.K, np.asarray(spin["K2"]), np.asarray(spin["G1"]), sr.speeds(n), k, D=red.D)
    out = c.record()
    out.update(spec=sr.spec, axis=sr.axis.tolist())
    if not (sr.w0 >= spin["range"][0] - 1e-12 and sr.w1 <= spin["range"][1] + 1e-12):
        out["note"] = (f"speeds beyond the range the body was built and checked for ({spin['range'][0]:g} to "
                       f"{spin['range'][1]:g} rad/s)")
    return out


def print_campbell(rec: dict) -> None:
    """The Campbell table: one row per speed, each mode's frequency (Hz) and whirl (FW forward, BW backward in
    the turning frame), then the critical speeds."""
    print(f"Campbell diagram, spin {rec['spec']} (rad/s; frequencies in Hz in the frame turning with the body; "
          "FW/BW: forward/backward whirl there)")
    k = len(rec["frequencies_hz"][0])
    print("  speed  " + "".join(f"{'mode ' + str(j + 1):>16}" for j in range(k)))
    for w, f, lab in zip(rec["speeds"], rec["frequencies_hz"], rec["labels"]):
        print(f"{w:7.4g}  " + "".join(f"{fmt(x, '.6g'):>12} {s:>3}" for x, s in zip(f, lab)))
    crit = rec["critical"]
    if crit:
        print("critical speeds (a frequency equal to a multiple of the speed): " + "; ".join(
            f"mode {c['mode']} x{c['multiple']} at {c['speed']:.5g} rad/s ({c['frequency_hz']:.5g} Hz)" for c in crit))
    if rec.get("note"):
        print(f"note: {rec['note']}")
