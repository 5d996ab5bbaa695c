#!/usr/bin/env python
"""Peak memory of every reduction method at ~100k DOF: no method forms a dense N x N matrix.

The built-in clamped cantilever ``cantilever(size_for_dofs(size))`` (default 94,500 DOF, where
one dense ``N x N`` float64 array would take ``8 N^2`` = 71 GB), Rayleigh damped, inputs
``TIP:y``, ``TIP:z``, ``TIP_CENTER:x`` (collocated outputs). Each method of
:data:`flexmor.reduction.METHODS` runs in a fresh process with a small order, cheap settings
(``CASES`` of ``tests/test_no_dense.py``) and the band 10-200 Hz (the first bending pair): the peak RSS is reset after the model is built
(``/proc/self/clear_refs``), so *peak MB* is the largest RSS while the basis is built and
projected (interpreter and model included) and *traced MB* the peak of NumPy/Python
allocations (``tracemalloc``; the sparse factorizations' C memory is not traced).
The run fails (exit 1) when a peak (RSS, model and factors included) exceeds ``8 N^2 / 20``.

Usage::

    python bench/no_dense.py                 # 100k DOF, all methods
    python bench/no_dense.py --size 30000 --methods modal,fw-sobt

Writes ``bench/results/no_dense.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests"))

from test_no_dense import CASES  # the same methods and settings as the 5,400-DOF test


def run_case(size: int, method: str) -> dict:
    import tracemalloc

    from solvers import _proc_status, _reset_peak

    from flexmor.linalg import SolverContext
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    model = cantilever(size_for_dofs(size)).with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z", "TIP_CENTER:x"])
    order, opts = CASES[method]
    before = _proc_status().get("VmRSS")
    reset = _reset_peak()
    tracemalloc.start()
    t0 = time.perf_counter()
    solver = SolverContext()
    red = reduce(model, method, order, ports, solver=solver, **opts)
    seconds = time.perf_counter() - t0
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    st = _proc_status()
    n = model.n_dof
    return {"method": method, "n_dof": n, "order": red.order, "seconds": seconds, "rss_before_mb": before,
            "peak_mb": st.get("VmHWM") if reset else None, "traced_mb": traced / 2 ** 20,
            "dense_nn_mb": 8 * n * n / 2 ** 20, "factorizations": solver.stats.count, "options": opts}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=100000)
    ap.add_argument("--methods", default=",".join(CASES))
    ap.add_argument("--case", help=argparse.SUPPRESS)
    ap.add_argument("--timeout", type=float, default=1800)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "no_dense.json"))
    a = ap.parse_args(argv)
    if a.case:
        print(json.dumps(run_case(a.size, a.case)))
        return 0
    rows, bad = [], []
    print(f"{'method':>14} {'order':>5} {'seconds':>8} {'peak MB':>8} {'traced MB':>9} {'fact.':>5}  8N^2 MB",
          flush=True)
    for method in a.methods.split(","):
        try:
            p = subprocess.run([sys.executable, __file__, "--size", str(a.size), "--case", method],
                               check=False, capture_output=True, text=True, timeout=a.timeout)
        except subprocess.TimeoutExpired:
            print(f"{method:>14} timed out after {a.timeout:.0f} s", flush=True)
            bad.append(method)
            continue
        if p.returncode:
            print(f"{method:>14} failed: {p.stderr.strip().splitlines()[-1:]}", flush=True)
            bad.append(method)
            continue
        r = json.loads(p.stdout.strip().splitlines()[-1])
        rows.append(r)
        peak = r["peak_mb"] if r["peak_mb"] is not None else float("nan")
        print(f"{method:>14} {r['order']:5d} {r['seconds']:8.1f} {peak:8.0f} {r['traced_mb']:9.1f} "
              f"{r['factorizations']:5d}  {r['dense_nn_mb']:.0f}", flush=True)
        if max(peak, r["traced_mb"]) > r["dense_nn_mb"] / 20:
            bad.append(method)
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(a.out).write_text(json.dumps({"size": a.size, "rows": rows, "failed": bad,
                                               "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
