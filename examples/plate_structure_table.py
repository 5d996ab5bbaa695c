"""Four reductions of a plate-and-rods structure at its hole interface, judged on one full FRF.

The built-in :func:`flexmor.models.plate_structure` (steel upper plate 0.5 m x 0.5 m x 20 mm
with a 100 mm central hole, on four 30 mm square rods of 0.4 m, clamped lower plate; 35,988 DOF
at the default ``n=56``, 6,336 DOF at ``n=20``) is excited and measured at the wall of the hole
through an RBE3 coupling at the hole's centre: 6 inputs (forces x, y, z and moments about x, y,
z) and the 6 collocated outputs (the wall's mean translations and rotations). Damping is Rayleigh
damping with ratio ``zeta`` at both ends of the band. The four reductions and the band errors of
the reference comparison they are set beside:

========================  =========================================================  ====================
reference                 flexmor                                                    reference band_error
========================  =========================================================  ====================
Krylov (173)              ``krylov``, order 173, default expansion points            2.06e-7
Krylov+Gram (35/173)      ``two-step``, order 35, ``intermediate=173``               5.16e-6
POD (36/24)               ``pod``, order 24, frequency snapshots (count in the JSON)  2.64e-5
modal (40)                ``modal``, order 40 (lowest eigenmodes)                    7.27e-3
========================  =========================================================  ====================

With 6 inputs a Krylov block has 6 columns, so 173 is not a whole number of blocks: the basis
of order 173 holds 28 complete moment blocks (168 columns) and the first 5 columns of the next
block, which matches those moments only partly. The reference's "36/24" POD (36 snapshots, 24
modes) has no exact counterpart: flexmor's frequency-domain POD takes its snapshots at the
quadrature nodes of the band (``pod_nodes`` Gauss points per panel, one cell per resonance);
the snapshot count is written to the JSON.

``band_error = ∫‖H − Ĥ‖²_F df / ∫‖H‖²_F df`` over the band, on the adaptive grid of
:class:`flexmor.analysis.compare.FullResponse` (the full FRF computed once for all four
bodies); ``seconds`` is the wall time of the basis and the projection.

Run ``python examples/plate_structure_table.py [--n 56] [--band 1:2000] [--zeta 0.01] [--out DIR]``;
it prints the table beside the reference values and writes ``plate_structure_table.png``
(rel_error(f) per method) and ``plate_structure_table.json`` to ``DIR`` (default
``./example-output``).

References
----------
Fehr, J. (2011). Automated and error-controlled model reduction in elastic multibody
systems. Dissertation, Universität Stuttgart, Shaker Verlag.

Lehner, M., Eberhard, P. (2007). A two-step approach for model reduction in flexible
multibody dynamics. Multibody System Dynamics 17, 157-176.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from flexmor.analysis.compare import FullResponse
from flexmor.damping import band_matched
from flexmor.models import plate_structure
from flexmor.ports import make_ports
from flexmor.reduction import reduce

#: The hole interface: a force/moment at the hole's centre spread over the wall (RBE3).
INTERFACE = [f"HOLE@rbe3:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")]

#: method -> (label in the reference comparison, order, extra options, the reference band_error)
REFERENCE = {
    "krylov": ("Krylov (173)", 173, {}, 2.06e-7),
    "two-step": ("Krylov+Gram (35/173)", 35, {"intermediate": 173}, 5.16e-6),
    "pod": ("POD (36/24)", 24, {}, 2.64e-5),
    "modal": ("modal (40)", 40, {}, 7.27e-3),
}


def structure(n: int = 56, *, band=(1.0, 2000.0), zeta: float = 0.01):
    """The plate-and-rods structure at resolution ``n`` with Rayleigh damping ``zeta`` at the band ends."""
    return plate_structure(n).with_damping(band_matched(zeta, band))


def run(n: int = 56, *, band=(1.0, 2000.0), zeta: float = 0.01, pod_nodes: int = 1, grid_tol: float | None = None,
        methods=tuple(REFERENCE), cache=False, on_result=None) -> dict:
    """Reduce the structure with the four methods of the comparison and measure them on one full FRF.

    Returns a dict with ``n_dof``, ``band_hz``, ``zeta``, ``n_resonances`` (in the band),
    ``full_seconds``, ``grid_points``, ``freqs``, and ``methods[name]`` with ``label``,
    ``order``, ``band_error``, ``max_rel_error``, ``seconds``, ``reference_band_error``,
    ``rel_error`` (array over ``freqs``) and ``info`` (a few method details).
    ``on_result(result)`` is called after the full FRF and after each method with the
    results so far.
    """
    band = (float(band[0]), float(band[1]))
    model = structure(n, band=band, zeta=zeta)
    ports = make_ports(model, INTERFACE)
    grid = {} if grid_tol is None else {"tol": grid_tol}
    full = FullResponse(model, ports, band, cache=cache, **grid)
    out = {"n_dof": model.n_dof, "band_hz": list(band), "zeta": zeta, "n_inputs": ports.n_inputs,
           "n_resonances": int(full.resonances.size), "resonances_hz": full.resonances.tolist(),
           "full_seconds": full.seconds, "grid_points": int(full.freqs.size), "freqs": full.freqs, "methods": {}}
    if on_result is not None:
        on_result(out)
    for name in methods:
        label, order, opts, reference = REFERENCE[name]
        opts = dict(opts, inertia_loads="off")  # the reference's bases: built for its six inputs alone
        if name in ("krylov", "two-step", "pod"):
            opts["band"] = band
        if name == "pod":
            opts["nodes"] = pod_nodes
        red = reduce(model, name, order, ports, **opts)
        t = red.info["timings"]
        err = full.evaluate(red)
        info = {k: red.info[k] for k in ("points_hz", "n_nodes", "energy_captured", "intermediate")
                if k in red.info}
        if name == "pod":
            info["n_snapshots"] = int(red.info["n_nodes"]) * ports.n_inputs
        if name == "modal":
            info["highest_mode_hz"] = float(red.info["frequencies_hz"][-1])
        out["methods"][name] = {"label": label, "order": int(red.order), "band_error": float(err.band_error),
                                "max_rel_error": float(err.max_rel_error), "seconds": t["basis"] + t["project"],
                                "reference_band_error": reference, "rel_error": err.rel_error, "info": info}
        if on_result is not None:
            on_result(out)
    return out


def table(result: dict) -> str:
    """The table as text (Markdown)."""
    head = (f"plate-and-rods structure, {result['n_dof']} DOF, {result['n_inputs']} inputs/outputs at the hole "
            f"(RBE3), band {result['band_hz'][0]:g}-{result['band_hz'][1]:g} Hz ({result['n_resonances']} "
            f"resonances), zeta {result['zeta']:g}; full FRF {result['grid_points']} frequencies, "
            f"{result['full_seconds']:.1f} s")
    lines = [head, "",
             "| reference | flexmor | order | band_error | reference band_error | max_rel_error | seconds |",
             "|---|---|---|---|---|---|---|"]
    for name, v in result["methods"].items():
        lines.append(f"| {v['label']} | {name} | {v['order']} | {v['band_error']:.3g} "
                     f"| {v['reference_band_error']:.3g} | {v['max_rel_error']:.3g} | {v['seconds']:.2f} |")
    return "\n".join(lines)


def plot(result: dict, path) -> None:
    """rel_error(f) of every method (log-log), resonances marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    f = result["freqs"]
    tiny = 1e-18
    for name, v in result["methods"].items():
        ax.loglog(f, np.maximum(v["rel_error"], tiny), label=f"{name} (r={v['order']}): band_error "
                  f"{v['band_error']:.2g}")
    for fr in result["resonances_hz"]:
        ax.axvline(fr, color="0.85", lw=0.6, zorder=0)
    ax.set_xlabel("f [Hz]")
    ax.set_ylabel("rel_error(f), hole → hole (6 × 6)")
    ax.set_title(f"Plate-and-rods structure, {result['n_dof']} DOF (grey: resonances)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def parser() -> argparse.ArgumentParser:
    """The command line of the example."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=56, help="resolution of plate_structure (56: 35,988 DOF)")
    p.add_argument("--band", default="1:2000", help="FMIN:FMAX in Hz")
    p.add_argument("--zeta", type=float, default=0.01, help="damping ratio at the band ends (Rayleigh)")
    p.add_argument("--pod-nodes", type=int, default=1, help="Gauss points per quadrature panel of the POD")
    p.add_argument("--out", default="example-output", help="folder for the figure and the JSON (created)")
    return p


def main(argv=None) -> int:
    a = parser().parse_args(argv)
    band = tuple(float(v) for v in a.band.split(":"))
    t0 = time.perf_counter()
    r = run(a.n, band=band, zeta=a.zeta, pod_nodes=a.pod_nodes)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(r, out / "plate_structure_table.png")
    summary = {k: v for k, v in r.items() if k not in ("freqs", "methods")}
    summary["methods"] = {k: {kk: vv for kk, vv in v.items() if kk != "rel_error"} for k, v in r["methods"].items()}
    summary["seconds"] = time.perf_counter() - t0
    (out / "plate_structure_table.json").write_text(json.dumps(summary, indent=2))
    print(table(r))
    print(f"wall time {summary['seconds']:.1f} s; wrote {out / 'plate_structure_table.png'} and .json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
