#!/usr/bin/env python
"""Scaling of the built-in solid models: assembly, factorization, modal r and peak memory per size.

Each size runs in a fresh process (``--case``): ``cantilever(size_for_dofs(size))`` is built
(assembly time), ``K - sigma M`` is factorized once through ``factorize`` (factorization time
and PARDISO's memory estimate), then ``reduce(model, "modal", r)`` computes the basis
(including its own factorization). *peak MB* is the peak RSS of the whole process.

Usage::

    python bench/scale.py                             # 30k, 100k, 300k DOF, r = 20
    python bench/scale.py --sizes 30000,100000,300000,1000000 --order 20

Writes ``bench/results/scale.json``. (The full issue asks for craig-bampton, krylov and
two-step at these sizes too; not yet here.)
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent


def _hwm() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def run_case(size: int, order: int) -> dict:
    from flexmor.linalg import available_backends, factorize
    from flexmor.linalg.eigen import default_shift
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    available_backends()
    t0 = time.perf_counter()
    model = cantilever(size_for_dofs(size))
    t_asm = time.perf_counter() - t0
    sigma = default_shift(model.K, model.M)
    t0 = time.perf_counter()
    F = factorize((model.K - sigma * model.M).tocsr(), positive=True, check=False)
    t_fac = time.perf_counter() - t0
    est = F.memory_estimate
    del F
    ports = make_ports(model, ["TIP:y"])
    t0 = time.perf_counter()
    _, timings = reduce(model, "modal", order, ports)
    t_modal = time.perf_counter() - t0
    return {"target_dofs": size, "n_dof": model.n_dof, "nnz_K": int(model.K.nnz), "assembly_s": t_asm,
            "factor_s": t_fac, "factor_estimate_mb": None if est is None else est / 2**20,
            "modal_s": t_modal, "order": order, "peak_mb": _hwm()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="30000,100000,300000")
    ap.add_argument("--order", type=int, default=20)
    ap.add_argument("--timeout", type=float, default=1800)
    ap.add_argument("--case", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(HERE / "results" / "scale.json"))
    args = ap.parse_args(argv)
    if args.case:
        print(json.dumps(run_case(args.case, args.order)))
        return 0
    rows = []
    head = f"{'size':>8} {'n_dof':>8} {'nnz(K)':>10} {'assembly s':>10} {'factor s':>9} {'est MB':>7} {'modal s':>8} {'peak MB':>8}"
    print(head + "\n" + "-" * len(head), flush=True)
    for size in [int(s) for s in args.sizes.split(",")]:
        cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--case", str(size), "--order", str(args.order)]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout, check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if proc.returncode or not lines:
            print(f"{size:>8}  failed: {(proc.stderr.strip().splitlines() or ['?'])[-1]}", flush=True)
            continue
        r = json.loads(lines[-1])
        rows.append(r)
        est = r["factor_estimate_mb"] or float("nan")
        print(f"{size:>8} {r['n_dof']:>8} {r['nnz_K']:>10} {r['assembly_s']:>10.1f} {r['factor_s']:>9.1f} "
              f"{est:>7.0f} {r['modal_s']:>8.1f} {r['peak_mb']:>8.0f}", flush=True)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
