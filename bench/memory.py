#!/usr/bin/env python
"""Benchmark of the memory modes of :func:`flexmor.linalg.factorize`: double in core, mixed, out of core.

For built-in clamped cantilever models (8-node hexahedra) of the requested sizes, factorize
``A = K - sigma M`` (real, ``sigma = default_shift(K, M)``, the matrix of the shift-invert
eigen solves and Krylov's real expansion point) or, with ``--matrix complex``,
``A = K - w^2 M + i w D`` (``D = 1e-6 K``, ``w = 2 pi 500 Hz``, the matrix of frequency
sweeps and Gramian quadrature) once with ``SolverContext(factor_memory=MODE)`` and solve
``--nrhs`` single right-hand sides one after the other (the refined solves of the mixed mode
pay per call). Each (size, mode) case runs in a fresh Python process so that its memory peak
is its own (peak RSS reset after the model is built, as in ``bench/solvers.py``).

The table shows the estimates of all three modes (from PARDISO's analysis), the measured peak
and solver RSS, the time of the factorization and of the solves, the refinement steps and
the residual ``||A X - B||_F / ||B||_F``, and the ratios of time and memory to the double
in-core case of the same size. ``--memory-limit`` (with ``--mode auto``) simulates a smaller
machine: ``auto`` then shows which mode it picks.

Usage::

    python bench/memory.py                                    # 30k and 100k DOF, double, mixed, ooc
    python bench/memory.py --sizes 300000,1000000 --mode double,mixed,ooc
    python bench/memory.py --sizes 1000000 --mode auto --memory-limit 12G
    python bench/memory.py --matrix complex --sizes 100000

Writes ``bench/results/memory.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import resource
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
DEFAULT_OUT = HERE / "results" / "memory.json"
sys.path.insert(0, str(HERE))

from solvers import (  # the RSS and process helpers of bench/solvers.py
    _machine,
    _proc_status,
    _reset_peak,
    spawn_case,
    write_results,
)

MODES = ("double", "mixed", "ooc")


def run_case(size: int, mode: str, args) -> dict:
    import gc

    import numpy as np

    from flexmor.linalg import SolverContext, available_backends, factorize
    from flexmor.linalg.eigen import default_shift
    from flexmor.linalg.memory import factor_record
    from flexmor.models import cantilever, size_for_dofs

    available_backends()  # loads MKL outside the measured region
    n = size_for_dofs(size)
    model = cantilever(n)
    if args.matrix == "complex":
        w = 2 * np.pi * 500.0
        A = (model.K - w**2 * model.M + 1j * w * 1e-6 * model.K).tocsr()
    else:
        A = (model.K - default_shift(model.K, model.M) * model.M).tocsr()
    del model
    B = np.random.default_rng(args.seed).standard_normal((A.shape[0], args.nrhs))
    gc.collect()
    base = _proc_status().get("VmRSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
    reset = _reset_peak()
    with tempfile.TemporaryDirectory(prefix="bench-ooc-", dir=args.scratch) as scratch:
        solver = SolverContext("pardiso", factor_memory=mode, memory_limit=args.memory_limit, scratch_dir=scratch)
        t0 = time.perf_counter()
        F = factorize(A, solver=solver, positive=args.matrix == "real", check=False)
        t_factor = time.perf_counter() - t0
        t0 = time.perf_counter()
        X = np.column_stack([F.solve(B[:, j]) for j in range(args.nrhs)])
        t_solve = time.perf_counter() - t0
        peak = _proc_status().get("VmHWM") if reset else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        ooc_files_mb = sum(p.stat().st_size for p in pathlib.Path(scratch).rglob("*") if p.is_file()) / 2**20
        plan = F.memory
        del F
        gc.collect()
        left = [str(p) for p in pathlib.Path(scratch).iterdir()]
    rec = factor_record(solver.stats)
    return {"target_dofs": size, "n": n, "n_dof": int(A.shape[0]), "nnz": int(A.nnz), "matrix": args.matrix,
            "asked": mode, "mode": plan.mode, "reason": plan.reason,
            "estimates_mb": {k: None if v is None else v / 2**20 for k, v in plan.estimates.items()},
            "memory_limit_mb": None if args.memory_limit is None else args.memory_limit / 2**20,
            "factor_seconds": t_factor, "solve_seconds": t_solve, "nrhs": args.nrhs,
            "rss_before_mb": base, "peak_mb": peak, "solver_mb": peak - base, "peak_reset": reset,
            "ooc_files_mb": ooc_files_mb, "files_left": left,
            "refine_steps": rec["refine_steps"], "refine_max_steps": rec["refine_max_steps"],
            "refine_residual": rec["refine_residual"],
            "residual": float(np.linalg.norm(A @ X - B) / np.linalg.norm(B))}


def _spawn(size: int, mode: str, args) -> dict:
    options = ["--nrhs", str(args.nrhs), "--seed", str(args.seed), "--matrix", args.matrix]
    if args.memory_limit is not None:
        options += ["--memory-limit", str(args.memory_limit)]
    if args.scratch:
        options += ["--scratch", args.scratch]
    return spawn_case(__file__, f"{size}:{mode}", options, args.timeout, {"target_dofs": size, "asked": mode})


def _f(v, spec):
    return "-" if v is None else format(v, spec)


def print_table(results: list[dict]) -> str:
    head = (f"{'size':>8} {'n_dof':>8} {'mode':>7} {'est dbl':>8} {'est mix':>8} {'est ooc':>8} {'factor s':>9} "
            f"{'solves s':>9} {'peak MB':>8} {'solver MB':>9} {'steps':>6} {'residual':>9} {'time x':>7} {'mem x':>6}")
    lines = [head, "-" * len(head)]
    ref = {r["target_dofs"]: r for r in results if r.get("mode") == "double" and "error" not in r}
    for r in results:
        if "error" in r:
            lines.append(f"{r['target_dofs']:>8} {'':>8} {r['asked']:>7}  {r['error']}")
            continue
        d, e = ref.get(r["target_dofs"]), r["estimates_mb"]
        total = r["factor_seconds"] + r["solve_seconds"]
        tx = total / (d["factor_seconds"] + d["solve_seconds"]) if d else None
        mx = r["solver_mb"] / d["solver_mb"] if d and d["solver_mb"] > 0 else None
        lines.append(f"{r['target_dofs']:>8} {r['n_dof']:>8} {r['mode']:>7} {_f(e['double'], '>8.0f')} "
                     f"{_f(e['mixed'], '>8.0f')} {_f(e['ooc'], '>8.0f')} {r['factor_seconds']:>9.2f} "
                     f"{r['solve_seconds']:>9.2f} {r['peak_mb']:>8.0f} {r['solver_mb']:>9.0f} "
                     f"{r['refine_max_steps'] or '-':>6} {r['residual']:>9.1e} {_f(tx, '>7.2f')} {_f(mx, '>6.2f')}")
    lines.append("est = MB estimated from PARDISO's analysis (ooc: the minimum); solver MB = peak RSS during factor + "
                 "solves minus RSS before; steps = most refinement steps of one solve; x = ratio to double in core "
                 "(time: factor + solves).")
    text = "\n".join(lines)
    print(text)
    return text


def main(argv=None) -> int:
    from flexmor.cli.parser import memory_size

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="30000,100000", help="comma-separated target DOF counts (default 30000,100000)")
    p.add_argument("--mode", default=",".join(MODES),
                   help="comma-separated factor_memory modes: double, mixed, ooc, auto (default double,mixed,ooc)")
    p.add_argument("--memory-limit", type=memory_size, metavar="SIZE",
                   help="SolverContext(memory_limit=...), e.g. 12G: a smaller machine for auto")
    p.add_argument("--matrix", choices=["real", "complex"], default="real",
                   help="K - sigma M (real, default) or K - w^2 M + i w D (complex)")
    p.add_argument("--nrhs", type=int, default=10, help="single right-hand sides solved one by one (default 10)")
    p.add_argument("--scratch", help="directory of the out-of-core files (default $TMPDIR)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds per case (default 3600)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"JSON output (default {DEFAULT_OUT})")
    p.add_argument("--case", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.case:
        size, mode = args.case.split(":")
        print(json.dumps(run_case(int(size), mode, args)))
        return 0
    modes = [m.strip() for m in args.mode.split(",") if m.strip()]
    bad = [m for m in modes if m not in (*MODES, "auto")]
    if bad:
        p.error(f"--mode: unknown {', '.join(bad)}; choose from double, mixed, ooc, auto")
    sizes = [int(float(s)) for s in args.sizes.split(",") if s.strip()]
    machine = _machine()
    print(f"# {machine['date']}  {machine.get('cpu', '?')}  {machine['cores']} cores  {machine.get('mem_gb', '?')} GB  "
          f"matrix {args.matrix}  modes {', '.join(modes)}"
          + (f"  memory limit {args.memory_limit / 2**30:.1f} GB" if args.memory_limit else ""), flush=True)
    results = []
    for size in sizes:
        for mode in modes:
            print(f"# running {size} DOF, {mode} ...", file=sys.stderr, flush=True)
            r = _spawn(size, mode, args)
            results.append(r)
            print("#   " + (r["error"] if "error" in r else f"{r['mode']}: factor {r['factor_seconds']:.2f} s, "
                  f"solves {r['solve_seconds']:.2f} s, peak {r['peak_mb']:.0f} MB"), file=sys.stderr, flush=True)
    table = print_table(results)
    write_results(args.out, {"machine": machine, "args": {k: v for k, v in vars(args).items() if k != "case"},
                             "results": results, "table": table})
    return 0


if __name__ == "__main__":
    sys.exit(main())
