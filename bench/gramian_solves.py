"""Solves of the Gramian quadrature: direct vs dense (modal form) vs surrogate, as factorizations.

    .venv/bin/python bench/gramian_solves.py                          # 135 ... 3,000 DOF
    .venv/bin/python bench/gramian_solves.py --sizes 540 3000 --direct-max 3000
    .venv/bin/python bench/gramian_solves.py --kind plate --sizes 51 --band 1:2000 --direct-max 0 --method pod

For each built-in model (cantilever: Rayleigh 0 / 1e-6, inputs and outputs TIP:y, TIP:z;
plate: Rayleigh 2 / 1e-6, the six RBE3 ports at the hole), band ``--band``:

1. one sparse complex factorization + block solve (median of 3): the unit;
2. :func:`flexmor.reduction.gramians.gramian_factors` with ``solves`` = ``dense`` (up to
   ``--dense-max`` DOF), ``surrogate`` and ``direct`` (up to ``--direct-max`` DOF), wall time and
   its ratio to the unit;
3. the agreement: largest relative difference of the Gramians ``R R^T``, ``L L^T`` and of the
   leading 10 Hankel singular values against the reference (direct where run, else dense);
4. with ``--method``: the method (``fw-sobt``, ``pod`` ...) of ``--order`` with ``solves=auto``
   (and ``direct`` where that was run): wall time, band_error from the error check, reduced
   eigenfrequencies and their relative differences.

Times depend on the load (printed); the ratios of one run are what carries over. Results go
to ``bench/results/gramian_solves.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from small_frf import unit_factorization  # bench/ is the script's directory

from flexmor.jsonutil import jsonable
from flexmor.models import cantilever, size_for_dofs
from flexmor.ports import make_ports
from flexmor.reduction.gramians import gramian_factors


def build(kind: str, size: int):
    """The model and its ports: a cantilever of about ``size`` DOF, or ``plate_structure(size)``."""
    if kind == "plate":
        from flexmor.couplings import couple
        from flexmor.models import plate_structure

        n = size
        specs = [f"HOLE@rbe3:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")]
        model = couple(plate_structure(n), specs).model.with_rayleigh(2.0, 1e-6)
        return model, make_ports(model, specs)
    if size < 540:  # 2 x 2 elements across, 27 DOF per element layer along the beam
        model = cantilever(divisions=(max(2, round(size / 27)), 2, 2))
    else:
        model = cantilever(n=size_for_dofs(size))
    model = model.with_rayleigh(0.0, 1e-6)
    return model, make_ports(model, ["TIP:y", "TIP:z"])


def _rel(a, b):
    P, Q = a @ a.T, b @ b.T
    return float(np.abs(P - Q).max() / np.abs(Q).max())


def _hsv(G, M):
    return np.linalg.svd(G.L.T @ (M @ G.R), compute_uv=False)[:10]


def run(kind: str, size: int, band, dense_max: int, direct_max: int, method: str | None, order: int) -> dict:
    model, ports = build(kind, size)
    out = {"kind": kind, "n_dof": model.n_dof, "load_before": os.getloadavg()[0]}
    unit = out["factorization_s"] = unit_factorization(model, ports)
    res = {}
    for solves in ("dense", "surrogate", "direct"):
        if (solves == "dense" and model.n_dof > dense_max) or (solves == "direct" and model.n_dof > direct_max):
            continue
        t = time.perf_counter()
        G = gramian_factors(model, ports, band, solves=solves)
        sec = time.perf_counter() - t
        res[solves] = G
        row = {"seconds": sec, "in_factorizations": sec / unit, "n_nodes": G.info["n_nodes"],
               "rank_R": G.info["rank_R"]}
        info = G.info["solves"]
        if solves == "surrogate":
            row.update(order=info["order"], n_direct_checks=info["n_direct_checks"],
                       max_residual_on_nodes=info["max_residual_on_grid"],
                       final_check_error=info["final_check"]["rel_error"], verified=info["verified"])
        out[solves] = row
    ref = res.get("direct") or res.get("dense")
    for name, G in res.items():
        if ref is not None and G is not ref:
            out[name].update(gramian_rel_diff=max(_rel(G.R, ref.R), _rel(G.L, ref.L)),
                             hsv_rel_diff=float(np.abs(_hsv(G, model.M) / _hsv(ref, model.M) - 1).max()))
    if method:
        from flexmor.analysis.compare import FullResponse
        from flexmor.workflow import reduce_and_judge

        full = FullResponse(model, ports, band, cache=False)
        for solves in ("auto", "direct") if "direct" in res else ("auto",):
            red, r = reduce_and_judge(model, method, order, ports, band=band, full=full, solves=solves)
            f = np.sort(np.abs(np.linalg.eigvals(np.linalg.solve(red.M, red.K)))) ** 0.5 / (2 * np.pi)
            out[f"method_{solves}"] = {"name": method, "order": order, "seconds": r["seconds"],
                                       "band_error": r["band_error"], "frequencies_hz": f}
        if "direct" in res:
            a, d = out["method_auto"], out["method_direct"]
            out["method_rel_diff"] = {"band_error": abs(a["band_error"] / d["band_error"] - 1),
                                      "frequencies": float(np.abs(a["frequencies_hz"] / d["frequencies_hz"] - 1).max())}
    out["load_after"] = os.getloadavg()[0]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kind", choices=("cantilever", "plate"), default="cantilever")
    p.add_argument("--sizes", type=int, nargs="+", default=[135, 270, 405, 540, 1440, 3000],
                   help="cantilever: DOF wanted; plate: the resolution n (n=16: 4,416 DOF, n=51: 32,412 DOF)")
    p.add_argument("--band", default="10:3000")
    p.add_argument("--dense-max", type=int, default=3000, help="largest model given the dense solves")
    p.add_argument("--direct-max", type=int, default=3000, help="largest model given the direct solves")
    p.add_argument("--method", default=None, help="also run this method with solves=auto")
    p.add_argument("--order", type=int, default=24)
    args = p.parse_args()
    band = tuple(float(x) for x in args.band.split(":"))
    rows = []
    for d in args.sizes:
        rows.append(run(args.kind, d, band, args.dense_max, args.direct_max, args.method, args.order))
        print(json.dumps(jsonable(rows[-1])), flush=True)
    path = Path(__file__).parent / "results" / "gramian_solves.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(jsonable({"band_hz": band, "rows": rows}), indent=1))


if __name__ == "__main__":
    main()
