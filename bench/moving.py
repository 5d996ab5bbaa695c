#!/usr/bin/env python
"""A moving load on a solid beam: compressed bodies against the naive ones (every path node an input), side by side.

The built-in solid cantilever (1 x 0.1 x 0.1 m steel, clamped at x = 0) meshed with ``--divisions NX,NY,NZ`` hexahedra
(default 100,4,4: 7,500 DOF), Rayleigh damping 1 1/s + 1e-6 s, band 1-2000 Hz. The path is the top surface's centre
line (NX + 1 nodes), the force in z (:mod:`flexmor.moving`). Every body is judged the same way: the band error of a
unit force at each position of the path (nodes, midpoints, the worst segments refined) under the load, against the
full model's path FRF (computed once, its time printed); the path maximum is the figure.

* compressed: ``System(moving_loads=["PATH:z@x"])``, the path's loads compressed (``--tol``), krylov, fw-sobt, pod
  and Craig-Bampton (modal + the compressed loads' static responses) at ``--orders``;
* naive: every path node's force an input: krylov (one or two moments of NX+1 inputs, at the default points and at
  0 Hz) and Craig-Bampton with the path nodes' z as interface (NX+1 constraint modes plus fixed-interface modes).

Then the crossing of a 1 kN force at two speeds (``--speeds``, m/s) for the best compressed body of order <= 60:
time max error under the load and the wall time of the full model (sparse Newmark, one factorization) and the body.

Usage::

    .venv/bin/python bench/moving.py                       # about 5 minutes
    .venv/bin/python bench/moving.py --divisions 40,2,2    # a quick check
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexmor.damping import Rayleigh
from flexmor.errors import OptionError
from flexmor.models.solid import cantilever
from flexmor.moving import judge_path, path_record
from flexmor.ports import Ports
from flexmor.reduction import reduce
from flexmor.study import System

BAND = (1.0, 2000.0)


def _naive(system, method: str, order: int, **options):
    """A body whose inputs are every path node's force, with the path record the judge reads."""
    path = system.moving[0][0]
    ports = Ports(B=path.B.tocsr(), C=path.B.T.tocsr(), input_names=path.node_names, output_names=path.node_names)
    t0 = time.perf_counter()
    body = reduce(system.model, method, order, ports, solver=system.solver, **options)
    seconds = time.perf_counter() - t0
    body.info["moving_loads"] = [path_record(body, path, None)]
    return body, seconds


#: the full model's path FRF, computed by the first judgement and shared by every body (naive ones too)
FULL: dict = {}


def _judge(system, body) -> dict:
    rec, FULL[0] = judge_path(system.model, body, system.moving[0][0], band=BAND, full=FULL.get(0),
                              solver=system.solver, cache=False)
    return rec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--divisions", default="100,4,4", help="hexahedra along x, y, z (y and z even)")
    ap.add_argument("--orders", default="40,50,60", help="orders of the compressed bodies")
    ap.add_argument("--tol", type=float, default=None, help="compression tolerance (default flexmor's)")
    ap.add_argument("--speeds", default="5,20", help="crossing speeds in m/s")
    args = ap.parse_args()
    nx, ny, nz = (int(v) for v in args.divisions.split(","))
    t0 = time.perf_counter()
    system = System(cantilever(divisions=(nx, ny, nz)), moving_loads=["PATH:z@x"],
                    select=["PATH=box:0,0.05,0.1,1,0.05,0.1"], band=BAND, damping=Rayleigh(1.0, 1e-6),
                    moving_load_tol=args.tol, cache=False)
    path, comp = system.moving[0]
    print(f"model: {system.model.n_dof} DOF; path {path.nodes.size} nodes; {comp.k} compressed loads (tol "
          f"{comp.tol:g}, next singular value {comp.record()['first_dropped']:.2e}) in {comp.seconds:.2f} s; "
          f"set-up {time.perf_counter() - t0:.1f} s")
    rows = []
    for method in ("krylov", "fw-sobt", "pod", "modal"):
        for order in (int(v) for v in args.orders.split(",")):
            t1 = time.perf_counter()
            try:
                body = system.reduce(method, order)
            except OptionError as exc:  # modal: the order must exceed the static loads it gets
                print(f"{method} {order}: {exc}")
                continue
            seconds = time.perf_counter() - t1
            t2 = time.perf_counter()
            rec = _judge(system, body)
            if len(rows) == 0:
                print(f"full path FRF: {FULL[0].freqs.size} frequencies x {path.nodes.size} loads, "
                      f"{time.perf_counter() - t2:.1f} s")
            label = "craig-bampton (modal + static)" if method == "modal" else method
            rows.append(("compressed", label, body.order, rec["path_max_band_error"], rec["worst_s"], seconds, body))
    n = path.nodes.size
    for order in (n, 2 * n):
        for label, opts in (("krylov (default points)", {}), ("krylov (point 0)", {"points": "0"})):
            body, seconds = _naive(system, "krylov", order, **opts)
            rec = _judge(system, body)
            rows.append(("naive", label, body.order, rec["path_max_band_error"], rec["worst_s"], seconds, body))
    for modes in (0, 10, 20, 40):
        body, seconds = _naive(system, "craig-bampton", n + modes, interface=["PATH:z"])
        rec = _judge(system, body)
        rows.append(("naive", "craig-bampton", body.order, rec["path_max_band_error"], rec["worst_s"], seconds,
                     body))
    print("\n| inputs | method | order | path max band_error | worst at s [m] | seconds |")
    print("|---|---|---|---|---|---|")
    for kind, method, order, err, s, seconds, _ in rows:
        print(f"| {kind} | {method} | {order} | {err:.2e} | {s:.3f} | {seconds:.2f} |")
    best = min((r for r in rows if r[0] == "compressed" and r[2] <= 60), key=lambda r: r[3])
    print(f"\ncrossing of 1 kN, {best[1]} order {best[2]}:")
    print("| speed m/s | duration s | steps | time mean error | time max error | full s | body s | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for v in (float(x) for x in args.speeds.split(",")):
        c = system.crossing(best[6], v, force=1000.0)
        print(f"| {v:g} | {c['duration']:.3g} | {c['steps']} | {c['time_mean_error']:.2e} | {c['time_max_error']:.2e} "
              f"| {c['seconds_full']:.2f} | {c['seconds_body']:.4f} | {c['speedup']:.0f}x |")


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
