"""``flexmor info`` on a reduced body (``BODY.h5``): what it is and where it came from."""

from __future__ import annotations

from pathlib import Path

__all__ = ["is_body_file", "info_body", "print_mass_properties"]


def is_body_file(path, format: str | None) -> bool:
    """Whether ``path`` (or ``--format``) names a reduced body rather than an FE model."""
    from ..io import BODY_FORMATS, MODEL_FORMATS

    if format is not None:
        return format in BODY_FORMATS.names() and format not in MODEL_FORMATS.names()
    return MODEL_FORMATS.by_path(Path(path)) is None and BODY_FORMATS.by_path(Path(path)) is not None


def _row(name: str, value, width: int = 12) -> None:
    print(f"{name:<{width}}{value}")


def info_body(args, emit_json) -> int:
    """Print (or emit as JSON) the summary of the body ``args.model``."""
    from ..damping import damping_from_dict
    from ..io import read_body
    from ..origin import describe_damping

    red = read_body(args.model, format=args.format)
    out = dict(red.summary(), file=str(args.model))
    if args.json:
        emit_json(out)
        return 0
    _row("body", f"{args.model}  (written by flexmor {out['version']})")
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
    _row("damping", describe_damping(damping_from_dict(out["damping"])))
    fr = out["frequencies_hz"]
    if fr is not None:
        _row("freqs [Hz]", " ".join(f"{f:.5g}" for f in fr[:16]) + (" ..." if len(fr) > 16 else ""))
    err = out["errors"]
    if err.get("band_error") is not None:
        band = err.get("band_hz") or ["?", "?"]
        text = f"band {band[0]:g}-{band[1]:g} Hz: band_error {err['band_error']:.3e}"
        if err.get("rms_rel_error_pct") is not None:
            text += (f", rms_rel_error {err['rms_rel_error_pct']:.3g} %, hinf_error {err['hinf_error']:.3e}, "
                     f"max_rel_error {err['max_rel_error']:.3e} at {err['max_rel_error_hz']:.4g} Hz"
                     + (" (anti-resonance)" if err.get("max_rel_error_at_antiresonance") else ""))
        elif err.get("max_rel_error") is not None:
            text += f", max_rel_error {err['max_rel_error']:.3e}"
        _row("errors", text)
    else:
        _row("errors", "not evaluated")
    m = out["model"]
    if m:
        _row("model", f"{m.get('name')} ({m.get('source') or 'no file'}): {m['n_dof']:,} DOF, {m['n_nodes']:,} nodes")
        _row("fingerprint", f"K {m.get('K')}, M {m.get('M')}, DOF map {m.get('dof_map')}"
             + (f", D {m['D']}" if m.get("D") else ""))
        made = [f"{k} {', '.join(m[k])}" for k in ("couplings", "interfaces", "selections") if m.get(k)]
        if made:
            _row("", "; ".join(made))
    else:
        _row("model", f"{out['model_name'] or '?'} (no fingerprint: written by an older flexmor)")
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
