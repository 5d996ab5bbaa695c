#!/usr/bin/env python
"""Scaling of the reduction methods on the built-in solid: time, peak memory and solver share.

Each size runs in a fresh process (``--case``): ``cantilever(size_for_dofs(size))`` is built
(assembly time), one bare PARDISO Cholesky of ``K - sigma M`` plus one block solve with six
right-hand sides is timed (the reference unit of work, with PARDISO's memory estimate), then
each method runs through ``flexmor.reduction.reduce`` with six inputs (``TIP:x/y/z`` over the
tip face, ``TIP_CENTER:x/y/z`` at its centre node):

* ``modal`` (default order 40),
* ``craig-bampton`` with the tip face tied to one 6-DOF master by an RBE2 (``TIP@rbe2``; the
  coupling transformation is timed separately) and ``order - 6`` fixed-interface modes,
* ``krylov`` (default order 200; the default expansion points: 0 Hz, then points on the frequency
  axis where the body's residual is largest, one factorization each and two for the estimate;
  ``--band``, default 1-5000 Hz: about 15 resonances of the 1 m steel cantilever),
* ``two-step`` (``krylov`` to 200, then balanced truncation to 40 with the band's Gramians),
* ``krylov-1pt`` (not in the default list): ``krylov`` with that one real point given
  explicitly, i.e. one factorization and all moments there (the default before the greedy points).

For every method the solver layer's own counters (``SolverContext.stats``)
give the number and time of its factorizations and of its block solves. ``ratio`` is the
method's wall time (basis + projection) over that bare solver time: what flexmor adds on top
of factorizations and solves; ``cpu`` is the process's CPU time (user + system, all threads),
which the other jobs of a shared machine inflate far less than the wall time. ``peak MB`` is the peak RSS while the method ran (reset through
``/proc/self/clear_refs`` before each method; the model's matrices are included).

Usage::

    python bench/scale.py                                     # 30k, 100k, 300k DOF, all methods
    python bench/scale.py --sizes 1000000 --methods krylov --out bench/results/scale_1m.json
    python bench/scale.py --sizes 3000 --methods modal,krylov --order-krylov 60   # smoke run

Writes ``bench/results/scale.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
INPUTS = ["TIP:x", "TIP:y", "TIP:z", "TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]
METHODS = ("modal", "craig-bampton", "krylov", "two-step", "krylov-1pt")


def _status(key: str) -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _cpu() -> float:
    """User + system CPU seconds of this process (all threads): a measure that other jobs on
    the machine inflate far less than wall time."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _reset_peak() -> None:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def run_case(size: int, methods: list[str], order: int, order_krylov: int, band: tuple, *, bare: bool = True,
             memory: dict | None = None) -> dict:
    import numpy as np

    from flexmor.couplings import couple
    from flexmor.linalg import SolverContext, available_backends, factorize
    from flexmor.linalg.eigen import default_shift
    from flexmor.linalg.memory import factor_record
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce
    from flexmor.reduction.krylov import default_points

    available_backends()
    t0 = time.perf_counter()
    model = cantilever(size_for_dofs(size))
    out = {"target_dofs": size, "n_dof": model.n_dof, "nnz_K": int(model.K.nnz),
           "assembly_s": time.perf_counter() - t0, "model_mb": _status("VmRSS"), "methods": {}}
    if bare:
        sigma = default_shift(model.K, model.M)
        _reset_peak()
        t0, c0 = time.perf_counter(), _cpu()
        F = factorize((model.K - sigma * model.M).tocsr(), positive=True, check=False)
        out["factor_s"], out["factor_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
        b = np.random.default_rng(0).standard_normal((model.n_dof, 6))
        t0 = time.perf_counter()
        F.solve(b)
        out["solve6_s"] = time.perf_counter() - t0
        out["factor_estimate_mb"] = None if F.memory_estimate is None else F.memory_estimate / 2**20
        out["factor_peak_mb"] = _status("VmHWM")
        out["backend"] = F.backend
        del F, b
    ports = make_ports(model, INPUTS)
    for method in methods:
        opts: dict = {}
        body, p, r = model, ports, order
        t_couple = 0.0
        if method == "craig-bampton":
            t0 = time.perf_counter()
            body = couple(model, ["TIP@rbe2"]).model
            t_couple = time.perf_counter() - t0
            p = make_ports(body, [f"TIP@RBE2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")])
            opts["interface"] = ["TIP@RBE2"]
        elif method in ("krylov", "krylov-1pt"):
            r = order_krylov
            opts["band"] = band
            if method == "krylov-1pt":  # one real point at the band's geometric mean: one factorization
                opts["points"] = default_points(band, 1)
        elif method == "two-step":
            opts["intermediate"] = order_krylov
            opts["band"] = band
        ctx = SolverContext(**(memory or {}))
        _reset_peak()
        t0, c0 = time.perf_counter(), _cpu()
        red = reduce(body, method.removesuffix("-1pt"), r, p, solver=ctx, **opts)
        timings = red.info["timings"]
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
        d = dataclasses.asdict(ctx.stats)
        solver = d["seconds"] + d["solve_seconds"]
        out["methods"][method] = {
            "order": red.order, "wall_s": wall, "cpu_s": cpu, "basis_s": timings["basis"], "project_s": timings["project"],
            "couple_s": t_couple, "factorizations": d["count"], "factor_s": d["seconds"], "solves": d["solves"],
            "solve_columns": d["solve_columns"], "solve_s": d["solve_seconds"], "solver_s": solver,
            "ratio": wall / solver if solver > 0 else None, "peak_mb": _status("VmHWM"),
            "factor": factor_record(ctx.stats), "n_points": len(red.info.get("points_hz") or [])}
        del red, body
    return out


def _row(size: int, r: dict) -> list[str]:
    line = f"{size:>8} {r['n_dof']:>8} {r['nnz_K']:>10}  assembly {r['assembly_s']:.1f} s"
    if "factor_s" in r:
        est = r["factor_estimate_mb"] or float("nan")
        line += (f", bare factor {r['factor_s']:.1f} s (cpu {r['factor_cpu_s']:.1f} s, {r['backend']}, estimate {est:.0f} MB, "
                 f"peak {r['factor_peak_mb']:.0f} MB), block solve (6 rhs) {r['solve6_s']:.2f} s")
    lines = [line]
    for name, m in r["methods"].items():
        ratio = "-" if m["ratio"] is None else f"{m['ratio']:.2f}"
        lines.append(f"{'':>8} {name:>14} r={m['order']:<4} wall {m['wall_s']:8.1f} s  cpu {m['cpu_s']:8.1f} s  "
                     f"{m['factorizations']:>2} fact {m['factor_s']:7.1f} s  {m['solves']:>4} solves "
                     f"({m['solve_columns']:>4} cols) {m['solve_s']:7.1f} s  ratio {ratio:>5}  "
                     f"peak {m['peak_mb']:7.0f} MB" + (f"  (+ RBE2 {m['couple_s']:.1f} s)" if m["couple_s"] else ""))
        f = m.get("factor") or {}
        if f.get("reason"):
            lines.append(f"{'':>8} {'':>14} factor: {f['reason']}" + (
                f"; {f['refine_steps']} refinement steps in {f['refined_solves']} solves (most {f['refine_max_steps']}), "
                f"residual {f['refine_residual']:.1e}" if f.get("refined_solves") else ""))
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="30000,100000,300000")
    ap.add_argument("--methods", default=",".join(METHODS[:4]))
    ap.add_argument("--order", type=int, default=40, help="order of modal, craig-bampton, two-step")
    ap.add_argument("--order-krylov", type=int, default=200, help="krylov order and two-step's intermediate order")
    ap.add_argument("--band", default="1:5000", help="band (Hz) of krylov's points and two-step's Gramians")
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--factor-memory", choices=["auto", "double", "mixed", "ooc"], default="auto",
                    help="memory mode of the methods' factorizations (default auto)")
    ap.add_argument("--memory-limit", help="memory the factorizations may assume, e.g. 12G (default: what is available)")
    ap.add_argument("--no-bare", action="store_true", help="skip the bare double-precision factorization")
    ap.add_argument("--case", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(HERE / "results" / "scale.json"))
    args = ap.parse_args(argv)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad:
        ap.error(f"unknown method(s) {', '.join(bad)}; choose from {', '.join(METHODS)}")
    if args.case:
        band = tuple(float(x) for x in args.band.split(":"))
        memory = {"factor_memory": args.factor_memory}
        if args.memory_limit:
            from flexmor.cli.parser import memory_size
            memory["memory_limit"] = memory_size(args.memory_limit)
        print(json.dumps(run_case(args.case, methods, args.order, args.order_krylov, band, bare=not args.no_bare,
                                  memory=memory)))
        return 0
    def command(size: int) -> list[str]:
        return [sys.executable, str(pathlib.Path(__file__).resolve()), "--case", str(size), "--methods",
                ",".join(methods), "--order", str(args.order), "--order-krylov", str(args.order_krylov), "--band",
                args.band, "--factor-memory", args.factor_memory] + \
            (["--memory-limit", args.memory_limit] if args.memory_limit else []) + (["--no-bare"] if args.no_bare else [])

    print(f"{'size':>8} {'n_dof':>8} {'nnz(K)':>10}", flush=True)
    run_cases([int(s) for s in args.sizes.split(",")], command, _row, timeout=args.timeout, out=args.out)
    return 0


def run_json(cmd: list[str], label: str, *, timeout: float) -> dict | None:
    """The record of a process that prints one JSON line last, or None: then the tail of its error output is
    printed after ``label`` (e.g. ``size  failed:``)."""
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode or not lines:
        print(f"{label}\n" + "\n".join(proc.stderr.strip().splitlines()[-15:] or ["?"]), flush=True)
        return None
    return json.loads(lines[-1])


def run_cases(sizes: list[int], command, rows, *, timeout: float, out: str) -> list[dict]:
    """Each size in a fresh process (``command(size)``, which prints one JSON line), its lines of ``rows(size, r)``
    printed as it ends; all records written to ``out``."""
    records = []
    for size in sizes:
        t0 = time.perf_counter()
        r = run_json(command(size), f"{size:>8}  failed:", timeout=timeout)
        if r is None:
            continue
        r["process_s"] = time.perf_counter() - t0
        records.append(r)
        print("\n".join(rows(size, r)), flush=True)
    path = pathlib.Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(records, indent=1))
    return records


if __name__ == "__main__":
    raise SystemExit(main())
