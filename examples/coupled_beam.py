"""A reduced clamped beam coupled to a stiff spring after reduction: which error survives the coupling.

A slender clamped beam is excited and measured at its tip (``TIP:y``); the middle cross-section
(node set ``MID``) is also declared as a force input during reduction. After reduction a stiff
spring from the middle to the ground is added and the projection matrix is reused (the spring
acts through ``Br`` of the ``MID:y`` input). The relative error ``rel_error(f)`` of the tip
response is compared with and without the spring for ``krylov`` (block moment matching at one real
point, the band's geometric mean, so that every moment is matched in both port directions) and
``fw-sobt`` (frequency-limited second-order balanced truncation) at the same order.

``band_error`` is a ratio of squared norms, so its growth factor is the square of an amplitude
ratio, and its denominator changes with the spring (the uncoupled tip response is dominated by
the first bending resonance, which the spring moves and lowers): its growth can therefore differ
from the growth of the pointwise error. ``max_rel_error`` and the geometric mean of the pointwise
ratio ``rel_error_coupled(f) / rel_error(f)`` (``growth_pointwise``) are printed beside it.

Run ``python examples/coupled_beam.py [--out DIR] [--nx 40] [--nyz 1] [--model FILE] [--order 8]``;
it prints the band errors and growth factors and writes ``coupled_beam.png`` and
``coupled_beam.json`` to ``DIR`` (default ``./example-output``).

References
----------
Fehr, J., Eberhard, P. (2010). Error-controlled model reduction in flexible multibody
dynamics. J. Comput. Nonlinear Dyn. 5(3), 031005.

Holzwarth, P., Eberhard, P. (2015). Interface reduction for CMS methods and alternative model
order reduction. IFAC-PapersOnLine 48(1), 254-259.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from flexmor.analysis.assembly import Assembly
from flexmor.analysis.frequency import band_error, band_grid, rel_error
from flexmor.errors import FlexmorWarning
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce

TIP, MID = "TIP:y", "MID:y"
METHODS = ("krylov", "fw-sobt")


def beam(nx: int = 40, *, nyz: int = 1, length: float = 1.0, side: float = 0.02, zeta_beta: float = 2e-5,
         model=None):
    """The slender clamped steel beam (hex8, ``nx x nyz x nyz`` elements) with node set ``MID``.

    Light stiffness-proportional damping ``D = beta K`` keeps the resonance peaks finite.
    ``model``: use this clamped beam along x (e.g. the CalculiX test beam) instead.
    """
    if model is None:
        if nx % 2:
            raise ValueError("nx must be even so that a cross-section lies at mid-length")
        model = cantilever(divisions=(nx, nyz, nyz), length=length, width=side, height=side)
    x = model.xyz[:, 0]
    mid = model.node_ids[np.isclose(x, (x.min() + x.max()) / 2)]
    if mid.size == 0:
        raise ValueError("the beam has no cross-section at mid-length")
    model.node_sets["MID"] = mid
    return model.with_rayleigh(0.0, zeta_beta)


def spring_stiffness(model, factor: float = 100.0) -> float:
    """``factor`` times the static stiffness of the beam at its ``MID:y`` port (from a solve)."""
    from flexmor.linalg import factorize

    b = make_ports(model, inputs=[MID]).B.toarray()[:, 0]
    return factor / float(b @ factorize(model.K.tocsc(), symmetric=True).solve(b))


def run(nx: int = 40, order: int = 8, band=(1.0, 1000.0), n_freq: int = 200, factor: float = 100.0,
        methods=METHODS, nyz: int = 1, model=None) -> dict:
    """Reduce, couple, and measure; returns the numbers and the curves (JSON-ready except arrays)."""
    model = beam(nx, nyz=nyz, model=model)
    ports = make_ports(model, inputs=[TIP, MID], outputs=[TIP])
    k = spring_stiffness(model, factor=factor)
    # full references: the uncoupled body and the body with the spring (sparse assembly)
    full0 = Assembly()
    full0.add_body("beam", model, ports)
    full1 = Assembly()
    full1.add_body("beam", model, ports)
    full1.spring(("beam", MID), None, k)
    f = band_grid(*band, n=n_freq)
    io = {"inputs": [("beam", TIP)], "outputs": [("beam", TIP)]}
    t0 = time.perf_counter()
    H0, H1 = full0.frf(f, **io), full1.frf(f, **io)
    out = {"n_dof": model.n_dof, "order": order, "band_hz": list(band), "spring_N_per_m": k,
           "full_seconds": time.perf_counter() - t0, "methods": {}, "freqs": f, "curves": {}}
    for name in methods:
        opts = {"band": band, "inertia_loads": "off"}  # the bodies compared at their ports, as published
        if name == "krylov":  # one real point at the band's geometric mean: whole blocks of both inputs, every
            opts["points"] = repr(float(np.sqrt(band[0] * band[1])))  # moment matched in every port direction
        red = reduce(model, name, order, ports, **opts)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlexmorWarning)
            a0, a1 = Assembly(), Assembly()
            a0.add_body("beam", red)
            a1.add_body("beam", red)
        a1.spring(("beam", MID), None, k)
        R0, R1 = a0.frf(f, **io), a1.frf(f, **io)
        e0, e1 = band_error(f, H0, R0), band_error(f, H1, R1)
        r0, r1 = rel_error(H0, R0), rel_error(H1, R1)
        m0, m1 = float(r0.max()), float(r1.max())
        tiny = np.finfo(float).tiny
        out["methods"][name] = {"band_error": e0, "band_error_coupled": e1, "growth": e1 / e0,
                                "max_rel_error": m0, "max_rel_error_coupled": m1, "growth_max_rel": m1 / m0,
                                # pointwise: geometric mean over the grid of rel_error ratio
                                "growth_pointwise": float(np.exp(np.mean(np.log((r1 + tiny) / (r0 + tiny)))))}
        out["curves"][name] = (rel_error(H0, R0), rel_error(H1, R1))
        out["methods"][name]["reduced"] = red
        out["methods"][name]["assembly"] = (a1, full1)
    return out


def plot(result: dict, path) -> None:
    """rel_error(f) with and without the spring for each method (log-log)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    f = result["freqs"]
    for (name, (e0, e1)), c in zip(result["curves"].items(), ("C0", "C3")):
        ax.loglog(f, e0, color=c, ls="-", label=f"{name} (r={result['order']}), uncoupled")
        ax.loglog(f, e1, color=c, ls="--", label=f"{name}, with spring (basis reused)")
    ax.set_xlabel("f [Hz]")
    ax.set_ylabel("rel_error(f), tip → tip")
    ax.set_title(f"Clamped beam, {result['n_dof']} DOF: stiff spring at mid-length added after reduction")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def parser() -> argparse.ArgumentParser:
    """The command line of the example."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="example-output", help="folder for the figure and the JSON (created)")
    p.add_argument("--nx", type=int, default=40)
    p.add_argument("--nyz", type=int, default=1, help="elements across the section")
    p.add_argument("--model", help="a clamped beam along x to use instead "
                   "(e.g. tests/data/calculix/beam8_clamped_mat.sti)")
    p.add_argument("--order", type=int, default=8)
    p.add_argument("--factor", type=float, default=100.0, help="spring / static mid-length stiffness")
    return p


def main(argv=None) -> int:
    a = parser().parse_args(argv)
    t0 = time.perf_counter()
    model = None
    if a.model:
        from flexmor.io import read

        model = read(a.model)
    r = run(a.nx, a.order, factor=a.factor, nyz=a.nyz, model=model)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(r, out / "coupled_beam.png")
    rows = {k: {kk: vv for kk, vv in v.items() if kk not in ("reduced", "assembly")} for k, v in r["methods"].items()}
    summary = {"n_dof": r["n_dof"], "order": r["order"], "band_hz": r["band_hz"], "spring_N_per_m": r["spring_N_per_m"],
               "seconds": time.perf_counter() - t0, "methods": rows}
    (out / "coupled_beam.json").write_text(json.dumps(summary, indent=2))
    print(f"clamped beam, {r['n_dof']} DOF, order {r['order']}, spring {r['spring_N_per_m']:.3g} N/m at mid-length")
    print(f"{'method':10s} {'band_error':>12s} {'with spring':>12s} {'growth':>10s} "
          f"{'max_rel_error':>14s} {'with spring':>12s} {'growth':>8s} {'pointwise growth':>17s}")
    for name, v in rows.items():
        print(f"{name:10s} {v['band_error']:12.3e} {v['band_error_coupled']:12.3e} {v['growth']:10.3g} "
              f"{v['max_rel_error']:14.3e} {v['max_rel_error_coupled']:12.3e} {v['growth_max_rel']:8.3g} "
              f"{v['growth_pointwise']:17.3g}")
    print(f"wall time {summary['seconds']:.1f} s (full FRFs {r['full_seconds']:.1f} s); "
          f"wrote {out / 'coupled_beam.png'} and .json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
