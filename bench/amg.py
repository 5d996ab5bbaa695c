#!/usr/bin/env python
"""The iterative backend at scale: AMG + block CG against the direct solver on the built-in solid.

Each size runs in a fresh process (``--case``): ``cantilever(size_for_dofs(size))`` is built (assembly
time and memory), then per backend (``amg``; ``pardiso`` too where ``--direct`` names the size) and per
method, through ``flexmor.reduction.reduce`` with the six inputs of ``bench/scale.py`` (``TIP:x/y/z``
over the tip face, ``TIP_CENTER:x/y/z`` at its centre node):

* ``krylov`` at the one real point 0 Hz (``--order-krylov``, default 60: ten moments of six columns),
* ``modal`` (``--order``, default 30; LOBPCG with one V-cycle per iterating column and iteration,
  :mod:`flexmor.linalg.lobpcg`).

``--methods`` picks some of them.

Per method: wall and CPU time, the AMG setups (``factor_s``) and the solves (``solve_s``), block CG
iterations in all, per block solve and the most of one, the largest relative residual, and the peak RSS
while it ran (reset through ``/proc/self/clear_refs`` before each method; the model's matrices included).
``cycle_s`` is one V-cycle of a block of six columns on the finest matrix, ``spmm_s`` one product of the
finest matrix with such a block: a cycle reads the level matrices about ``2 * degree + 1`` times on the
finest level, so ``cycle_s / spmm_s`` says how far the cycle is from the memory-bandwidth bound of its
sparse products. With ``--direct`` the same bodies are built by PARDISO at that size and compared:
largest relative difference of the lowest 20 frequencies, and of the transfer functions at the six inputs
and outputs over 300 frequencies from 1 to 2000 Hz (``max |H_amg - H_direct| / max |H_direct|``).

Usage::

    python bench/amg.py --sizes 100000,300000 --direct 100000,300000
    python bench/amg.py --sizes 3000000 --out bench/results/amg_3m.json
    python bench/amg.py --sizes 1000000 --direct 1000000 --judge 1000000 --judge-checks 0 --methods krylov \
        --out bench/results/amg_1m.json
    python bench/amg.py --judge-case 1000000 --with-judge FOLDER --judge-checks 0   # bodies saved in FOLDER

Writes ``bench/results/amg.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import shutil
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from scale import INPUTS, _cpu, _reset_peak, _status, run_cases, run_json  # noqa: E402

#: the damping ratio (at the band's ends) both sides are judged with (:func:`_judge_case`)
JUDGE_ZETA = 0.01


def _spmm_and_cycle(F, n: int) -> tuple[float, float]:
    import numpy as np

    from flexmor.linalg.threads import sparse_dense

    B = np.random.default_rng(0).standard_normal((n, 6))
    A = F._cycle.A[0]
    sparse_dense(A, B)
    t0 = time.perf_counter()
    for _ in range(3):
        sparse_dense(A, B)
    spmm = (time.perf_counter() - t0) / 3
    t0 = time.perf_counter()
    F._cycle(B)
    return spmm, time.perf_counter() - t0


def run_case(size: int, order: int, order_krylov: int, direct: bool, judge: str = "",
             methods: tuple = ("krylov", "modal")) -> dict:
    import numpy as np

    from flexmor.linalg import SolverContext, factorize
    from flexmor.linalg.eigen import default_shift
    from flexmor.linalg.memory import factor_record
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce
    from flexmor.rigid import register_near_null

    t0 = time.perf_counter()
    model = cantilever(size_for_dofs(size))
    out: dict = {"target_dofs": size, "n_dof": model.n_dof, "nnz_K": int(model.K.nnz),
                 "assembly_s": time.perf_counter() - t0, "model_mb": _status("VmRSS"), "runs": {}}
    ports = make_ports(model, INPUTS)
    # one hierarchy of K - sigma M alone: its levels, the cycle against a bare product
    ctx = SolverContext(backend="amg")
    register_near_null(ctx, model)
    _reset_peak()
    t0 = time.perf_counter()
    F = factorize((model.K - default_shift(model.K, model.M) * model.M).tocsr(), solver=ctx, positive=True)
    out["setup_s"], out["setup_peak_mb"] = time.perf_counter() - t0, _status("VmHWM")
    out["levels"], out["operator_complexity"] = F.levels, F.operator_complexity
    out["spmm_s"], out["cycle_s"] = _spmm_and_cycle(F, model.n_dof)
    del F
    bodies = {}
    for backend in ("amg", "pardiso") if direct else ("amg",):
        for method, r, opts in (("krylov", order_krylov, {"points": "0"}), ("modal", order, {})):
            if method not in methods:
                continue
            ctx = SolverContext(backend=backend)
            _reset_peak()
            t0, c0 = time.perf_counter(), _cpu()
            red = reduce(model, method, r, ports, solver=ctx, **opts)
            wall, cpu = time.perf_counter() - t0, _cpu() - c0
            d = dataclasses.asdict(ctx.stats)
            out["runs"][f"{method}/{backend}"] = {
                "order": red.order, "wall_s": wall, "cpu_s": cpu, "factor_s": d["seconds"], "solves": d["solves"],
                "solve_columns": d["solve_columns"], "solve_s": d["solve_seconds"], "peak_mb": _status("VmHWM"),
                "iterations": d["iterations"], "iterations_max": d["iterations_max"],
                "eigen_iterations": d["eigen_iterations"], "eigen_residual": d["eigen_residual"] or None,
                "iterations_per_solve": d["iterations"] / d["solves"] if d["solves"] else None,
                "relative_residual_max": d["iterative_residual"] or None, "factor": factor_record(ctx.stats),
                "frequencies_hz": red.frequencies_hz()[:12].tolist()}
            bodies[(method, backend)] = red
    if direct:
        for method in methods:
            a, b = bodies[(method, "amg")], bodies[(method, "pardiso")]
            fa, fb = a.frequencies_hz(), b.frequencies_hz()
            k = min(fa.size, fb.size, 20)
            grid = np.geomspace(1.0, 2000.0, 300)
            Ha, Hb = a.frf(grid), b.frf(grid)
            out["runs"][f"{method}/amg"]["vs_direct"] = {
                "max_rel_freq_diff_20": float(np.max(np.abs(fa[:k] - fb[:k]) / fb[:k])),
                "transfer_diff": float(np.abs(Ha - Hb).max() / np.abs(Hb).max())}
        if judge:  # the bodies for the judge's own process (_judge_case): a fresh one has the memory for its factors
            from flexmor.io.hdf5 import write_body

            pathlib.Path(judge).mkdir(parents=True, exist_ok=True)
            for (method, backend), body in bodies.items():
                write_body(body, pathlib.Path(judge) / f"{method}-{backend}.h5")
    return out


def _judge_case(size: int, folder: str, judge_checks: int | None = None, zeta: float = JUDGE_ZETA) -> dict:
    """The bodies written to ``folder`` against the full model of ``size`` (the grid's own path: the surrogate,
    checked by its own solves), in a process of its own: band error of each, the grid's record and its seconds.
    ``judge_checks``: the direct solves of the full model per body (FullResponse's default where None; at 1M DOF
    each is a complex factorization, minutes; 0: only the surrogate's own checks).

    The bench's model is undamped, and the full FRF of an undamped model takes the direct path: one
    factorization per frequency of its grid (90 at 1M DOF, 3 minutes each). Both sides are judged with Rayleigh
    damping of ratio ``zeta`` at the band's ends instead: the full model with ``D = alpha M + beta K``, each body
    with ``D_r = alpha M_r + beta K_r``, which is what its basis gives the damped model (a Krylov basis at a real
    point holds the same moments with proportional damping: ``K^-1 D = alpha K^-1 M + beta I``)."""
    from flexmor.analysis.compare import FullResponse
    from flexmor.damping import band_matched
    from flexmor.io import read_body
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.origin import fingerprint
    from flexmor.ports import make_ports

    band = (1.0, 2000.0)
    damping = band_matched(zeta, band)
    model = cantilever(size_for_dofs(size)).with_damping(damping)
    ports = make_ports(model, INPUTS)
    _reset_peak()
    t0 = time.perf_counter()
    opts = {} if judge_checks is None else {"judge_checks": judge_checks}
    full = FullResponse(model, ports, band, **opts)
    out = {"seconds": time.perf_counter() - t0, "peak_mb": _status("VmHWM"), "grid": full.summary(),
           "judge_checks": judge_checks, "zeta": zeta, "band_error": {}}
    origin = fingerprint(model)
    for path in sorted(pathlib.Path(folder).glob("*.h5")):
        method, backend = path.stem.split("-", 1)
        body = read_body(path)
        body = dataclasses.replace(body, D=damping.alpha * body.M + damping.beta * body.K, damping=damping,
                                   origin=origin)
        out["band_error"][f"{method}/{backend}"] = float(full.evaluate(body).band_error)
    return out


def _rows(size: int, r: dict) -> list[str]:
    lines = [f"{size:>8} {r['n_dof']:>8} {r['nnz_K']:>11}  assembly {r['assembly_s']:.1f} s ({r['model_mb']:.0f} MB), "
             f"AMG setup {r['setup_s']:.1f} s (peak {r['setup_peak_mb']:.0f} MB, {r['levels']} levels, operator "
             f"complexity {r['operator_complexity']:.2f}), V-cycle of 6 columns {r['cycle_s']:.2f} s = "
             f"{r['cycle_s'] / r['spmm_s']:.1f} products with K ({r['spmm_s']:.3f} s)"]
    for name, m in r["runs"].items():
        its = "" if not m["iterations"] else (f"  CG {m['iterations']:>5} its ({m['iterations_per_solve']:.1f}/solve, "
                                              f"max {m['iterations_max']}), residual {m['relative_residual_max']:.0e}")
        if m.get("eigen_iterations"):
            its += f"  LOBPCG {m['eigen_iterations']} its, residual {m['eigen_residual']:.0e}"
        vs = m.get("vs_direct")
        be = "" if m.get("band_error") is None else f"  band error {m['band_error']:.2e}"
        lines.append(f"{'':>8} {name:>15} r={m['order']:<3} wall {m['wall_s']:8.1f} s  cpu {m['cpu_s']:8.1f} s  "
                     f"setup/factor {m['factor_s']:7.1f} s  {m['solves']:>4} solves ({m['solve_columns']:>4} cols) "
                     f"{m['solve_s']:7.1f} s  peak {m['peak_mb']:7.0f} MB" + its
                     + ("" if not vs else f"  vs direct: freq {vs['max_rel_freq_diff_20']:.1e}, transfer "
                        f"{vs['transfer_diff']:.1e}") + be)
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="100000,300000")
    ap.add_argument("--direct", default="", help="sizes at which PARDISO builds the same bodies for comparison")
    ap.add_argument("--order", type=int, default=30, help="modal order")
    ap.add_argument("--order-krylov", type=int, default=60, help="krylov order (one real point)")
    ap.add_argument("--timeout", type=float, default=7200)
    ap.add_argument("--case", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--with-direct", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--judge", default="", help="sizes (of --direct) at which both bodies are judged against the "
                    "full model (band error over 1-2000 Hz, the grid's default path)")
    ap.add_argument("--with-judge", default="", help=argparse.SUPPRESS)
    ap.add_argument("--judge-case", type=int, help="judge the bodies (.h5) in the folder --with-judge against the "
                    "full model of this size, alone")
    ap.add_argument("--judge-checks", type=int, help="direct solves of the full model per judged body (default "
                    "FullResponse's; 0: the surrogate's own checks only, where a complex factor does not fit)")
    ap.add_argument("--methods", default="krylov,modal", help="some of krylov,modal")
    ap.add_argument("--out", default=str(HERE / "results" / "amg.json"))
    args = ap.parse_args(argv)
    if args.case:
        print(json.dumps(run_case(args.case, args.order, args.order_krylov, args.with_direct, args.with_judge,
                                  tuple(args.methods.split(",")))))
        return 0
    if args.judge_case:
        print(json.dumps(_judge_case(args.judge_case, args.with_judge, args.judge_checks)))
        return 0
    direct = {int(s) for s in args.direct.split(",") if s.strip()}
    judged = {int(s) for s in args.judge.split(",") if s.strip()}

    folder = tempfile.mkdtemp(prefix="flexmor-amg-bodies-")

    def command(size: int) -> list[str]:
        cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--case", str(size), "--order", str(args.order),
               "--order-krylov", str(args.order_krylov), "--methods", args.methods]
        return cmd + (["--with-direct"] if size in direct else []) + \
            (["--with-judge", f"{folder}/{size}"] if size in judged and size in direct else [])

    print(f"{'size':>8} {'n_dof':>8} {'nnz(K)':>11}", flush=True)
    records = run_cases([int(s) for s in args.sizes.split(",")], command, _rows, timeout=args.timeout,
                        out=args.out)
    for r in records:  # the judge of each judged size in a process of its own, after the bodies' process ended
        size = r["target_dofs"]
        if size not in judged or size not in direct:
            continue
        checks = [] if args.judge_checks is None else ["--judge-checks", str(args.judge_checks)]
        judged_r = run_json([sys.executable, str(pathlib.Path(__file__).resolve()), "--judge-case", str(size),
                             "--with-judge", f"{folder}/{size}", *checks], f"{size:>8}  judge failed:",
                            timeout=args.timeout)
        if judged_r is None:
            continue
        r["judge"] = judged_r
        for name, value in r["judge"]["band_error"].items():
            r["runs"][name]["band_error"] = value
        print(f"{size:>8}  judge {r['judge']['seconds']:.1f} s (peak {r['judge']['peak_mb']:.0f} MB): "
              + ", ".join(f"{k} {v:.2e}" for k, v in r["judge"]["band_error"].items()), flush=True)
    pathlib.Path(args.out).write_text(json.dumps(records, indent=1))
    shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
