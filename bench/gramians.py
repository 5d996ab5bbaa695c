#!/usr/bin/env python
"""Benchmark of the Gramian and hybrid methods on the built-in clamped cantilever.

Part 1, comparison (``--size``, default 20,000 DOF: ``cantilever(n)`` with the smallest ``n``
giving at least that many DOF): six inputs at the tip, ``TIP:x``, ``TIP:y``, ``TIP:z`` (forces
spread over the tip face) and ``TIP_CENTER:x``, ``TIP_CENTER:y``, ``TIP_CENTER:z`` (point forces
at the centre node of the tip face), collocated outputs; Rayleigh damping with ratio ``--zeta`` at both ends of
the band (``flexmor reduce --modal-damping``), band ``--band`` (default 10-2500 Hz, which holds
eleven resonances of the 27,000-DOF beam: two bending pairs below 600 Hz, torsion, the axial
mode, two more bending pairs). Each method builds its basis and projects (``seconds``); the
error against one full FRF on the adaptive grid of :class:`flexmor.analysis.compare.FullResponse`
is ``band_error``. Methods: ``modal`` 30, ``krylov`` 30, ``two-step`` (r1 = 120, r2 = 30),
``fw-sobt`` 30 and ``pod`` 30 (with ``--nodes`` Gauss points per quadrature panel).

Part 2, quadrature (``--nodes-check``): ``fw-sobt`` 30 on the same beam with 2, 3, 4 and 6
nodes per panel, to show what fewer quadrature nodes (fewer factorizations) cost in accuracy.

Usage::

    python bench/gramians.py                          # part 1 at >= 20k DOF
    python bench/gramians.py --size 3000 --nodes-check

Writes ``bench/results/gramians.json`` (``--out``).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from flexmor.analysis.compare import FullResponse
from flexmor.damping import band_matched
from flexmor.models import cantilever, size_for_dofs
from flexmor.ports import make_ports
from flexmor.workflow import reduce_and_judge

CASES = [("modal", 30, {}), ("krylov", 30, {}), ("two-step", 30, {"intermediate": 120}), ("fw-sobt", 30, {}),
         ("pod", 30, {})]


def beam(size: int, zeta: float, band):
    """The clamped cantilever with at least ``size`` DOF, Rayleigh damped, ports at the tip."""
    n = size_for_dofs(size)
    model = cantilever(n)
    while model.n_dof < size:
        n += 1
        model = cantilever(n)
    model = model.with_damping(band_matched(zeta, band))
    return model, make_ports(model, [f"{s}:{d}" for s in ("TIP", "TIP_CENTER") for d in "xyz"]), n


def run(case, model, ports, full, band, nodes):
    method, order, opts = case
    opts = dict(opts)
    if method in ("fw-sobt", "pod"):
        opts["nodes"] = nodes
    red, res = reduce_and_judge(model, method, order, ports, full=full, band=band, cache=False, **opts)
    row = {"method": method, "order": red.order, "seconds": res["seconds"], "band_error": res["band_error"],
           "max_rel_error": res["max_rel_error"], "options": opts}
    for key in ("n_nodes", "intermediate", "hankel_sv"):
        if key in red.info:
            row[key] = red.info[key][:10] if key == "hankel_sv" else red.info[key]
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=20000)
    ap.add_argument("--band", default="10:2500")
    ap.add_argument("--zeta", type=float, default=0.01)
    ap.add_argument("--nodes", type=int, default=4)
    ap.add_argument("--methods", default=",".join(c[0] for c in CASES))
    ap.add_argument("--nodes-check", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "gramians.json"))
    a = ap.parse_args(argv)
    band = tuple(float(x) for x in a.band.split(":"))
    t0 = time.perf_counter()
    model, ports, n = beam(a.size, a.zeta, band)
    t_model = time.perf_counter() - t0
    t0 = time.perf_counter()
    full = FullResponse(model, ports, band, cache=False)
    t_full = time.perf_counter() - t0
    res_in_band = [round(float(f), 1) for f in full.resonances]
    print(f"cantilever n={n}: {model.n_dof} DOF (built in {t_model:.1f} s); full FRF on {full.freqs.size} "
          f"frequencies ({full.path}) in {t_full:.1f} s; resonances in band: {res_in_band}", flush=True)
    rows = []
    wanted = a.methods.split(",")
    for case in CASES:
        if case[0] in wanted:
            rows.append(run(case, model, ports, full, band, a.nodes))
            r = rows[-1]
            print(f"{r['method']:>9} r={r['order']:3d}  band_error {r['band_error']:.3e}  "
                  f"max_rel_error {r['max_rel_error']:.3e}  {r['seconds']:7.1f} s  "
                  f"{'nodes ' + str(r['n_nodes']) if 'n_nodes' in r else ''}", flush=True)
    check = []
    if a.nodes_check:
        for nodes in (2, 3, 4, 6):
            check.append(run(("fw-sobt", 30, {}), model, ports, full, band, nodes))
            r = check[-1]
            print(f"fw-sobt nodes/panel {nodes}: {r['n_nodes']} factorizations, band_error {r['band_error']:.4e}, "
                  f"{r['seconds']:.1f} s, sigma_1..3 {np.round(r['hankel_sv'][:3], 12)}", flush=True)
    out = {"n_dof": model.n_dof, "n": n, "band_hz": list(band), "zeta": a.zeta, "damping": model.damping,
           "n_freq": int(full.freqs.size), "full_frf_path": full.path, "full_frf_seconds": t_full, "resonances_in_band": res_in_band,
           "rows": rows, "nodes_check": check, "python": platform.python_version(),
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(a.out).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
