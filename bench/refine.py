#!/usr/bin/env python
"""The refined solves of the mixed-precision mode in a Krylov reduction: stationary refinement vs GMRES.

For the built-in clamped cantilever of each size, ``reduce(model, "krylov", 200, ports,
band=(1, 5000))`` with the six inputs of ``bench/scale.py`` (``TIP:x/y/z``,
``TIP_CENTER:x/y/z``) and default options, once per variant, each in a fresh process:

``double``
    ``SolverContext()``: the double-precision factor in core (the reference).
``stationary``
    ``factor_memory="mixed"`` with the refinement used up to 2026-11-24,
    ``x += M^-1 (b - A x)`` until the corrections reach the rounding of double precision
    (kept here, as :func:`stationary_refine`, only as the baseline of this comparison).
``gmres``
    ``factor_memory="mixed"`` with :func:`flexmor.linalg.memory.refine` (FGMRES with the
    single-precision factor as preconditioner, stopping at the backward error of a double solve).

The table shows the block solves, the single-precision solves per block solve (mean and
max), the time of the solves and of the whole reduction, the largest backward error and the
largest relative difference of the reduced body's eigenfrequencies to the double run.

Usage::

    python bench/refine.py                          # 94,500 DOF
    python bench/refine.py --sizes 100000,300000

Writes ``bench/results/refine.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
DEFAULT_OUT = HERE / "results" / "refine.json"
sys.path.insert(0, str(HERE))

from scale import INPUTS  # the inputs of the scale benchmark
from solvers import _machine, _proc_status, spawn_case, write_results  # the RSS and process helpers of bench/solvers.py

VARIANTS = ("double", "stationary", "gmres")
BAND = (1.0, 5000.0)


def stationary_refine(A, low_solve, b, *, anorm, tol, max_iter=30):
    """The stationary refinement of the mixed mode before GMRES (the baseline; same contract as ``refine``)."""
    import numpy as np

    from flexmor.errors import SolverError

    rounding = 4 * np.finfo(float).eps
    bnorm = np.linalg.norm(b, axis=0)
    x = np.zeros(b.shape, dtype=np.result_type(b.dtype, A.dtype))
    r = b.astype(x.dtype, copy=True)
    last, best, steps = np.inf, 1.0, 0
    while steps < max_iter:
        scale = np.linalg.norm(r, axis=0)
        scale[scale == 0] = 1.0
        d = np.asarray(low_solve(r / scale), dtype=x.dtype) * scale
        x += d
        r = b - A @ x
        steps += 1
        xnorm = np.linalg.norm(x, axis=0)
        change = float(np.max(np.linalg.norm(d, axis=0) / np.where(xnorm > 0, xnorm, 1.0), initial=0.0))
        ratio = change / last if steps > 1 else 1.0
        if not np.isfinite(change) or change * ratio <= rounding or (steps > 1 and ratio > min(0.5, 8 * best)):
            break
        last, best = change, min(best, ratio)
    denom = anorm * np.linalg.norm(x, axis=0) + bnorm
    worst = float(np.max(np.linalg.norm(r, axis=0) / np.where(denom > 0, denom, 1.0), initial=0.0))
    if not worst <= tol:
        raise SolverError(f"stationary refinement did not converge (backward error {worst:.1e})")
    return x, steps, worst


def run_case(size: int, variant: str, order: int) -> dict:
    from flexmor.linalg import SolverContext, available_backends, factorization
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    available_backends()
    model = cantilever(size_for_dofs(size))
    ports = make_ports(model, INPUTS)
    if variant == "stationary":
        factorization.refine = stationary_refine
    solver = SolverContext() if variant == "double" else SolverContext(factor_memory="mixed")
    t0 = time.perf_counter()
    red = reduce(model, "krylov", order, ports, band=BAND, solver=solver)
    wall = time.perf_counter() - t0
    st = solver.stats
    return {"target_dofs": size, "n_dof": model.n_dof, "variant": variant, "wall_s": wall,
            "factorizations": st.count, "mixed": st.mixed, "factor_s": st.seconds, "solves": st.solves,
            "solve_columns": st.solve_columns, "solve_s": st.solve_seconds, "refined_solves": st.refined_solves,
            "refine_steps": st.refine_steps, "refine_max_steps": st.refine_max_steps,
            "refine_residual": st.refine_residual if st.refined_solves else None,
            "peak_mb": _proc_status().get("VmHWM"), "frequencies_hz": [float(f) for f in red.frequencies_hz()]}


def _spawn(size: int, variant: str, args) -> dict:
    return spawn_case(__file__, f"{size}:{variant}", ["--order", str(args.order)], args.timeout,
                      {"target_dofs": size, "variant": variant})


def print_table(results: list[dict]) -> str:
    import numpy as np

    head = (f"{'n_dof':>8} {'variant':>10} {'wall s':>8} {'factor s':>9} {'solves':>7} {'solve s':>8} "
            f"{'steps/solve':>12} {'max':>4} {'backward':>9} {'band diff':>10} {'all diff':>9} {'peak MB':>8}")
    lines = [head, "-" * len(head)]
    ref = {r["target_dofs"]: r for r in results if r.get("variant") == "double" and "error" not in r}
    for r in results:
        if "error" in r:
            lines.append(f"{r['target_dofs']:>8} {r['variant']:>10}  {r['error']}")
            continue
        d = ref.get(r["target_dofs"])
        diff = band = "-"
        if d and len(d["frequencies_hz"]) == len(r["frequencies_hz"]):
            f0, f = np.array(d["frequencies_hz"]), np.array(r["frequencies_hz"])
            rel = np.abs(f - f0) / np.abs(f0)
            diff, band = f"{np.max(rel):.1e}", f"{np.max(rel[f0 <= BAND[1]], initial=0.0):.1e}"
        n = r["refined_solves"]
        mean = f"{r['refine_steps'] / n:.1f}" if n else "-"
        back = f"{r['refine_residual']:.1e}" if r["refine_residual"] is not None else "-"
        lines.append(f"{r['n_dof']:>8} {r['variant']:>10} {r['wall_s']:>8.1f} {r['factor_s']:>9.1f} {r['solves']:>7} "
                     f"{r['solve_s']:>8.1f} {mean:>12} {r['refine_max_steps'] or '-':>4} {back:>9} {band:>10} {diff:>9} "
                     f"{r['peak_mb'] or 0:>8.0f}")
    lines.append("solves = block solves; steps/solve, max = single-precision (block) solves per block solve; "
                 "backward = largest backward error ||b - A x|| / (||A|| ||x|| + ||b||), ||A|| = sqrt(||A||_1 ||A||_inf); band diff, all diff = largest "
                 "relative difference of the reduced eigenfrequencies to the double run's, in the band (<= 5000 Hz), all.")
    text = "\n".join(lines)
    print(text)
    return text


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="100000", help="comma-separated target DOF counts (default 100000)")
    p.add_argument("--variants", default=",".join(VARIANTS), help="double, stationary, gmres (default all)")
    p.add_argument("--order", type=int, default=200, help="krylov order (default 200)")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per case (default 900)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"JSON output (default {DEFAULT_OUT})")
    p.add_argument("--case", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.case:
        size, variant = args.case.split(":")
        print(json.dumps(run_case(int(size), variant, args.order)))
        return 0
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [v for v in variants if v not in VARIANTS]
    if bad:
        p.error(f"--variants: unknown {', '.join(bad)}; choose from {', '.join(VARIANTS)}")
    machine = _machine()
    print(f"# {machine['date']}  {machine.get('cpu', '?')}  {machine['cores']} cores  {machine.get('mem_gb', '?')} GB",
          flush=True)
    results = []
    for size in (int(float(s)) for s in args.sizes.split(",") if s.strip()):
        for variant in variants:
            print(f"# running {size} DOF, {variant} ...", file=sys.stderr, flush=True)
            r = _spawn(size, variant, args)
            results.append(r)
            print("#   " + (r["error"] if "error" in r else f"{r['wall_s']:.1f} s"), file=sys.stderr, flush=True)
    table = print_table(results)
    write_results(args.out, {"machine": machine, "args": {k: v for k, v in vars(args).items() if k != "case"},
                             "results": results, "table": table})
    return 0


if __name__ == "__main__":
    sys.exit(main())
