"""``flexmor export``: a reduced body to an MBS code (SID, Exudyn), MATLAB, state space or VTU."""

from __future__ import annotations

from ..errors import OptionError
from ..linalg.distributed import on_root
from .commands import _check_new, _emit_json, _progress
from .tables import fmt

__all__ = ["cmd_export"]


def cmd_export(args) -> int:
    """``flexmor export``: write a body in an MBS code's format; returns the exit code."""
    from ..io import export, export_format, read_body, unit_formats
    from ..origin import reference_model
    from ..preload import recorded_material
    from ..prepare import prepare

    _check_new(args.output_file, args)
    red = read_body(args.reduced)
    name = export_format(args.output_file, args.format)
    if args.mesh and not args.model:
        raise OptionError("--mesh attaches a mesh file to the --model; give --model too")
    if args.export_units not in (None, "SI") and name not in unit_formats():
        raise OptionError(f"--export-units {args.export_units}: {name} files are written in SI only; other unit "
                          f"systems: {', '.join(unit_formats())}")
    units = args.units or red.units  # the --model file in the unit system the body records, unless given
    recorded = red.info.get("preload")
    preload = recorded.get("specs", []) if isinstance(recorded, dict) else []  # the body's preload, again
    material = recorded_material(recorded, args.reduced)  # and the material its stresses were computed with
    model = prepare(args.model, format=args.model_format, mesh=args.mesh, units=units, preload=preload,
                    material=material, progress=_progress(args)).model if args.model else None
    out = {"file": str(args.output_file), "format": name, "order": red.order, "method": red.method,
           "units": args.export_units or ("SI" if red.units is not None else None)}
    body, ref = red, None
    if model is not None:  # the body's own model (refused otherwise); the exporters apply its couplings
        ref = reference_model(model, red, args.reduced)
        if args.remove_rigid:
            body, judged = _without_rigid(ref, red)
            out.update(judged)
    if args.modal_form or args.max_frequency is not None or args.select_modes:
        body, out["modal_form"] = _modal(args, body, ref)
    opts = {"nodes": args.node or None} if name in ("sid", "mat") else {}
    if name == "sid":
        opts["m1_order"] = args.m1_order
        opts["stiffening"] = not args.no_stiffening
        opts["progress"] = _progress(args)
    if args.allow_clamped and name in ("sid", "exudyn"):  # the writers of a floating frame
        opts["allow_clamped"] = True
    on_root(export, body, args.output_file, name, model=model, units=args.export_units, **opts)  # under MPI: rank 0
    if args.json:
        _emit_json(out)
        return 0
    print(f"exported {args.reduced} ({red.method}, order {red.order}) as {name}: {args.output_file}"
          + (f" in {args.export_units}" if args.export_units else ""))
    if "modal_form" in out:
        r = out["modal_form"]
        n_kept = len(r["modes_kept"])
        kept = (f"{n_kept} of its {r['order_before']} elastic modes (up to {r['max_frequency_hz']:.4g} Hz)"
                + (f" and {r['static_vectors']} static vectors (the static response of the modes left out)"
                   if r.get("static_vectors") else "") if n_kept < r["order_before"]
                else f"all {r['order']} elastic modes")
        print(f"modal form: {kept}; the body written has band_error {fmt(r['band_error'], '.3g')} "
              f"(rms {fmt(r['rms_rel_error_pct'], '.3g')} %, hinf_error {fmt(r['hinf_error'], '.3g')}) over "
              f"{r['band_hz'][0]:g}-{r['band_hz'][1]:g} Hz against {r['reference']}")
        for c in ((r.get("mounted") or {}).get("cases") or ()):
            print(f"mounted: the body written {c['held']} at {c['interface']}: freq error "
                  f"{fmt(c['max_frequency_error'], '.2e')}, static error {fmt(c['max_static_error'], '.2e')}")
        if r.get("static"):
            print(f"static: the body written ({r['static']['as']}): error at the inputs "
                  f"{fmt(r['static']['static_error'], '.2e')}, largest {fmt(r['static']['max_static_error'], '.2e')}")
        if r.get("tol") is not None:
            m = r["tol_measure"]
            print(f"--tol {r['tol']:g} on {m}: " + ("met" if r["tol_reached"] else
                                                     "MISSED even with every mode: all modes written"))
    if "order_exported" in out:
        print(f"note: rigid-body motion removed from the basis: order {red.order} -> {out['order_exported']}; "
              f"the body written has band_error {fmt(out['band_error'], '.3g')} "
              f"(rms {fmt(out['rms_rel_error_pct'], '.3g')} %) over {out['band_hz'][0]:g}-{out['band_hz'][1]:g} Hz, "
              "judged on the elastic part")
    return 0


def _modal(args, body, ref):
    """``--modal-form`` / ``--max-frequency`` / ``--select-modes``: ``(body, record)`` of
    :func:`flexmor.analysis.mode_selection.trim`, judged against ``ref`` (the body's model) when
    ``--model`` was given."""
    from ..analysis.compare import FullResponse
    from ..analysis.mode_selection import trim
    from ..linalg.context import SolverContext
    from ..options import DEFAULT_BAND, Band
    from ..ports import body_ports

    if args.select_modes and args.tol is None:
        raise OptionError("--select-modes auto needs --tol (the error the modes kept must meet)")
    if args.tol is not None and not args.select_modes:
        raise OptionError("--tol is the error of --select-modes auto; give --select-modes auto too")
    if args.select_modes and args.max_frequency is not None:
        raise OptionError("give --max-frequency or --select-modes, not both")
    band = Band.of(args.band or body.info.get("band") or (body.errors or {}).get("band_hz") or DEFAULT_BAND)
    full = ports = None
    if ref is not None:
        ports = body_ports(ref, body)
        full = FullResponse(ref, ports, band, solver=SolverContext())
    trimmed, record = trim(body, band=band, max_frequency=args.max_frequency, tol=args.tol, measure=args.tol_measure,
                           full=full, static=not args.no_static_vectors)
    if ref is not None and trimmed is not body:  # the body written, held in its joints and statically (as reduce)
        from ..analysis.mounted import mounted_record, static_record

        rms = record.get("band_rms_error")
        record["mounted"] = mounted_record(ref, trimmed, ports=ports, band=band, band_rms_error=rms)
        record["static"] = static_record(ref, trimmed, ports=ports, mounted=record["mounted"], band_rms_error=rms)
    return trimmed, record


def _without_rigid(ref, red):
    """``--remove-rigid``: ``(body, record)``, the body export writes (its basis made mass-orthogonal to the
    rigid-body modes when it holds rigid motion, else ``red``) and, when it changed, its order and error
    measures over the band ``red`` was judged on, against ``ref`` (the model it was reduced on)."""
    from ..analysis.compare import FullResponse
    from ..linalg.context import SolverContext
    from ..options import DEFAULT_BAND, Band
    from ..ports import body_ports
    from ..rigid import elastic_body

    body = elastic_body(ref, red, remove_rigid=True)
    if "rigid_removed_at_export" not in body.info:
        return red, {}
    band = Band.of(red.errors.get("band_hz") or DEFAULT_BAND)
    full = FullResponse(ref, body_ports(ref, red), band, solver=SolverContext())
    return body, {"order_exported": body.order, "band_hz": list(band), **full.evaluate(body).to_dict()}
