#!/usr/bin/env python
"""The plan before the run (``flexmor plan``) against the run: memory and time, estimated and measured.

For built-in clamped cantilevers (8-node hexahedra, ports ``TIP:y``, ``TIP:z``) of the requested sizes, the
script makes the plan of each method (:func:`flexmor.plan.plan_reduction`, without the error grid) and then
reduces as ``flexmor reduce --no-error --no-mounted`` does (:func:`flexmor.workflow.reduce_and_judge` without a
band), once per backend, in double precision in core. It prints per case the factorizations and solved columns
planned and counted (``SolverStats``), the seconds of the factorizations and of the solves planned and measured,
and per size the memory of one factorization of ``K - sigma M``: PARDISO's estimate against MKL's own peak
(``MKL_Peak_Mem_Usage``: every buffer PARDISO allocates, analysis included) and the SuperLU heuristic against
the factor SuperLU keeps (``(nnz(L) + nnz(U)) * 12`` bytes), with the seconds of the plan itself.

Usage::

    python bench/plan.py                              # 10k, 40k, 100k DOF; scipy up to 40k
    python bench/plan.py --sizes 20000 --scipy-max 20000
"""

from __future__ import annotations

import argparse
import ctypes
import time

CASES = [("krylov", 12, {"points": "100"}), ("krylov", 12, {}), ("modal", 20, {}),
         ("craig-bampton", 23, {"interface": ["TIP_CENTER"]})]


def mkl_peak(A) -> float | None:
    """MKL's peak memory (bytes) over one PARDISO factorization of ``A`` (None without MKL)."""
    from flexmor.linalg import SolverContext, factorize
    from flexmor.linalg.mkl_sparse import mkl_library

    lib = mkl_library()
    if lib is None:
        return None
    peak = lib.MKL_Peak_Mem_Usage
    peak.restype, peak.argtypes = ctypes.c_int64, [ctypes.c_int]
    peak(1)  # MKL_PEAK_MEM_ENABLE
    peak(-1)  # MKL_PEAK_MEM_RESET
    F = factorize(A, solver=SolverContext(backend="pardiso", factor_memory="double"), positive=True, check=False)
    out = float(peak(2))  # MKL_PEAK_MEM
    del F
    return out


def superlu_bytes(A) -> float:
    """Bytes of the factor SuperLU keeps for ``A`` (values and row indices of L and U)."""
    from flexmor.linalg import SolverContext, factorize

    F = factorize(A, solver=SolverContext(backend="scipy", factor_memory="double"), positive=True, check=False)
    return 12.0 * (F._lu.L.nnz + F._lu.U.nnz)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="10000,40000,100000", help="target DOF, comma-separated")
    p.add_argument("--scipy-max", type=int, default=40000, help="largest size run with scipy (SuperLU)")
    args = p.parse_args(argv)
    from flexmor.linalg import SolverContext
    from flexmor.linalg.eigen import default_shift
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.plan import plan_reduction
    from flexmor.ports import make_ports
    from flexmor.workflow import reduce_and_judge

    mb = 2.0**20
    mem_lines, run_lines = [], []
    for size in (int(s) for s in args.sizes.split(",")):
        model = cantilever(size_for_dofs(size))
        ports = make_ports(model, ["TIP:y", "TIP:z"])
        A = (model.K - default_shift(model.K, model.M) * model.M).tocsr()
        backends = ["pardiso"] + (["scipy"] if size <= args.scipy_max else [])
        for method, order, opts in CASES:
            plan = plan_reduction(model, method, order, ports, judge=False, **opts)
            for backend in backends:
                row = next(r for r in plan.rows if r["backend"] == backend and r["mode"] == "double")
                solver = SolverContext(backend=backend, factor_memory="double")
                t0 = time.perf_counter()
                reduce_and_judge(model, method, order, ports, solver=solver, mounted=False, **opts)
                wall = time.perf_counter() - t0
                st = solver.stats
                label = method + (f" @{opts['points']} Hz" if "points" in opts else "")
                run_lines.append(
                    f"{model.n_dof:7d}  {label:18s} {backend:8s} {plan.factorizations:3d} {st.count:3d}  "
                    f"{plan.columns:5d} {st.solve_columns:5d}  {row['factor_seconds']:8.2f} {st.seconds:8.2f}  "
                    f"{row['solve_seconds']:8.2f} {st.solve_seconds:8.2f}  "
                    f"{row['total_seconds'] / (st.seconds + st.solve_seconds):6.2f}  {plan.seconds:6.2f} {wall:7.2f}")
                print(run_lines[-1], flush=True)
        plan = plan_reduction(model, "krylov", 12, ports, judge=False, points="100")
        est = {r["backend"]: r["factor_bytes"] for r in plan.rows if r["mode"] == "double"}
        pk = mkl_peak(A)
        line = f"{model.n_dof:7d}  pardiso  {est['pardiso'] / mb:8.0f} {pk / mb:8.0f} {est['pardiso'] / pk:6.2f}"
        if size <= args.scipy_max:
            lu = superlu_bytes(A)
            line += f"    scipy  {est['scipy'] / mb:8.0f} {lu / mb:8.0f} {est['scipy'] / lu:6.2f}"
        mem_lines.append(line)
        print(line, flush=True)
    print("\nsolver work and time: plan (estimate) against the run (measured), double precision in core")
    print("   n_dof  method             backend  factorizations columns      factor s        solve s"
          "      total  plan s  run s")
    print("                                       plan  run  plan   run     plan     run     plan     run  "
          "est/meas")
    print("-" * 118)
    print("\n".join(run_lines))
    print("\nmemory of one factorization of K - sigma M: estimate against measured (MB)")
    print("   n_dof  backend   est MB  meas MB  ratio    backend  est MB  meas MB  ratio")
    print("-" * 80)
    print("\n".join(mem_lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
