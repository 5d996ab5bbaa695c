"""``flexmor export``: a reduced body to an MBS code (SID, Exudyn), MATLAB, state space or VTU."""

from __future__ import annotations

from ..errors import OptionError
from .commands import _check_new, _emit_json, _with_mesh
from .tables import fmt

__all__ = ["cmd_export"]


def cmd_export(args) -> int:
    from ..io import export, export_format, read, read_body
    from ..origin import reference_model

    _check_new(args.output_file, args)
    red = read_body(args.reduced)
    name = export_format(args.output_file, args.format)
    if args.mesh and not args.model:
        raise OptionError("--mesh attaches a mesh file to the --model; give --model too")
    model = _with_mesh(read(args.model, format=args.model_format), args) if args.model else None
    out = {"file": str(args.output_file), "format": name, "order": red.order, "method": red.method}
    body = red
    if model is not None:  # the body's own model (refused otherwise); the exporters apply its couplings
        ref = reference_model(model, red, args.reduced)
        if args.remove_rigid:
            body, judged = _without_rigid(ref, red)
            out.update(judged)
    opts = {"nodes": args.node or None} if name in ("sid", "mat") else {}
    if name == "sid":
        opts["m1_order"] = args.m1_order
    if args.allow_clamped and name in ("sid", "exudyn"):  # the writers of a floating frame
        opts["allow_clamped"] = True
    export(body, args.output_file, name, model=model, **opts)
    if args.json:
        _emit_json(out)
        return 0
    print(f"exported {args.reduced} ({red.method}, order {red.order}) as {name}: {args.output_file}")
    if "order_exported" in out:
        print(f"note: rigid-body motion removed from the basis: order {red.order} -> {out['order_exported']}; "
              f"the body written has band_error {fmt(out['band_error'], '.3g')} "
              f"(rms {fmt(out['rms_rel_error_pct'], '.3g')} %) over {out['band_hz'][0]:g}-{out['band_hz'][1]:g} Hz, "
              "judged on the elastic part")
    return 0


def _without_rigid(ref, red):
    """``--remove-rigid``: ``(body, record)``, the body export writes (its basis made mass-orthogonal to the
    rigid-body modes when it holds rigid motion, else ``red``) and, when it changed, its order and error
    measures over the band ``red`` was judged on, against ``ref`` (the model it was reduced on)."""
    from ..analysis.compare import FullResponse
    from ..linalg.context import SolverContext
    from ..options import DEFAULT_BAND, Band
    from ..ports import make_ports
    from ..rigid import elastic_body

    body = elastic_body(ref, red, remove_rigid=True)
    if "rigid_removed_at_export" not in body.info:
        return red, {}
    band = Band.of(red.errors.get("band_hz") or DEFAULT_BAND)
    full = FullResponse(ref, make_ports(ref, red.input_names, red.output_names), band, solver=SolverContext())
    return body, {"order_exported": body.order, "band_hz": list(band), **full.evaluate(body).to_dict()}
