#!/usr/bin/env python
"""Benchmark of the sparse direct solver backends of :func:`flexmor.linalg.factorize`.

For built-in clamped cantilever models (8-node hexahedra) of the requested sizes and each
available backend, factorize the symmetric positive definite matrix ``A = K - sigma M``
(``sigma = default_shift(K, M) < 0``, the matrix of flexmor's shift-invert eigen solves) and
solve a block of 100 random right-hand sides. Each (size, backend) case runs in a fresh
Python process so that its memory peak is its own.

Memory: the peak resident set size is reset (``/proc/self/clear_refs``) after the model is
built, so ``peak MB`` is the largest RSS of the process during factorization and solve and
``solver MB`` that peak minus the RSS before the factorization (matrices ``K, M, A`` and the
interpreter). Where the reset is impossible ``ru_maxrss`` of the whole run is reported.

Usage::

    python bench/solvers.py                         # 30k and 100k DOF, all backends
    python bench/solvers.py --sizes 30000 --backends pardiso,scipy
    python bench/solvers.py --skip-scipy-above 50000
    python bench/solvers.py --assembly --sizes 30000,100000,300000,1000000

Writes ``bench/results/solvers.json``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import pathlib
import platform
import resource
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
DEFAULT_OUT = HERE / "results" / "solvers.json"


# -- one case, run in a child process ---------------------------------------------------------
def _proc_status() -> dict:
    out = {}
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                key, _, val = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    out[key] = int(val.split()[0]) / 1024.0  # kB -> MiB
    except OSError:
        pass
    return out


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def run_case(size: int, backend: str, nrhs: int, seed: int) -> dict:
    import gc

    import numpy as np

    from flexmor.linalg import SolverContext, available_backends, factorize
    from flexmor.linalg.eigen import default_shift
    from flexmor.models import cantilever, size_for_dofs

    available_backends()  # loads the solver libraries (MKL ...) outside the timed region

    t0 = time.perf_counter()
    n = size_for_dofs(size)
    model = cantilever(n)
    sigma = default_shift(model.K, model.M)
    A = (model.K - sigma * model.M).tocsr()
    t_model = time.perf_counter() - t0
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((A.shape[0], nrhs))
    gc.collect()
    assembly_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    base = _proc_status().get("VmRSS", assembly_peak)
    reset = _reset_peak()

    t0 = time.perf_counter()
    F = factorize(A, solver=SolverContext(backend), symmetric=True, positive=True, check=False)
    t_factor = time.perf_counter() - t0
    t0 = time.perf_counter()
    X = F.solve(B)
    t_solve = time.perf_counter() - t0

    if reset:
        peak = _proc_status().get("VmHWM", float("nan"))
    else:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    R = A @ X - B
    col = np.linalg.norm(R, axis=0) / np.linalg.norm(B, axis=0)
    return {
        "target_dofs": size,
        "n": n,
        "model": model.name,
        "n_dof": int(A.shape[0]),
        "nnz": int(A.nnz),
        "sigma": sigma,
        "backend": F.backend,
        "nrhs": nrhs,
        "model_seconds": t_model,
        "factor_seconds": t_factor,
        "solve_seconds": t_solve,
        "rss_before_mb": base,
        "assembly_peak_mb": assembly_peak,
        "peak_mb": peak,
        "solver_mb": peak - base,
        "peak_reset": reset,
        "residual": float(np.linalg.norm(R) / np.linalg.norm(B)),
        "max_column_residual": float(col.max()),
    }


def run_assembly(size: int) -> dict:
    """Build the cantilever of about ``size`` DOF; wall time and peak RSS of the process."""
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    from flexmor.models import cantilever, size_for_dofs

    t0 = time.perf_counter()
    n = size_for_dofs(size)
    model = cantilever(n)
    seconds = time.perf_counter() - t0
    return {"target_dofs": size, "n": n, "model": model.name, "n_dof": model.n_dof,
            "n_elements": int(10 * n * n * n), "nnz_K": int(model.K.nnz), "seconds": seconds,
            "rss_mb": _proc_status().get("VmRSS"), "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "interpreter_mb": base}


def assembly_table(sizes, args) -> list[dict]:
    rows = []
    for size in sizes:
        cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--case", f"{size}:assembly"]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout, check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if proc.returncode or not lines:
            rows.append({"target_dofs": size, "error": (proc.stderr.strip().splitlines() or ["?"])[-1]})
            continue
        rows.append(json.loads(lines[-1]))
    head = f"{'size':>9} {'n':>4} {'n_dof':>9} {'nnz(K)':>11} {'seconds':>8} {'peak MB':>8} {'final MB':>8}"
    print(head + "\n" + "-" * len(head))
    for r in rows:
        if "error" in r:
            print(f"{r['target_dofs']:>9}  {r['error']}")
        else:
            print(f"{r['target_dofs']:>9} {r['n']:>4} {r['n_dof']:>9} {r['nnz_K']:>11} {r['seconds']:>8.1f} "
                  f"{r['peak_mb']:>8.0f} {r['rss_mb']:>8.0f}")
    return rows


# -- driver -----------------------------------------------------------------------------------
def _machine() -> dict:
    import numpy
    import scipy

    info = {
        "date": _dt.date.today().isoformat(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cores": os.cpu_count(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
    }
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as fh:
            info["mem_gb"] = round(int(fh.readline().split()[1]) / 1024**2, 1)
    except OSError:
        pass
    for mod in ("pypardiso", "mkl", "sksparse", "mumps"):
        try:
            from importlib.metadata import version

            info[mod] = version({"mkl": "mkl", "sksparse": "scikit-sparse", "mumps": "python-mumps"}.get(mod, mod))
        except Exception:  # noqa: BLE001, S110 - not installed
            pass
    return info


def spawn_case(script: str, case: str, options: list[str], timeout: float, ident: dict) -> dict:
    """Run ``script --case CASE OPTIONS`` in a fresh Python process (its memory peak its own) and
    return the JSON record of its last ``{``-line, with ``process_seconds``; on a timeout or a
    failure ``ident`` with an ``error`` message."""
    cmd = [sys.executable, str(pathlib.Path(script).resolve()), "--case", case, *options]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {**ident, "error": f"timeout after {timeout:.0f} s"}
    wall = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        return {**ident, "error": f"exit code {proc.returncode}: {tail}"}
    res = json.loads(lines[-1])
    res["process_seconds"] = wall
    return res


def write_results(out: str, record: dict) -> None:
    """Write a benchmark's JSON ``record`` to ``out`` (directories made) and say so."""
    path = pathlib.Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2))
    print(f"# wrote {path}")


def _spawn(size: int, backend: str, args) -> dict:
    return spawn_case(__file__, f"{size}:{backend}", ["--nrhs", str(args.nrhs), "--seed", str(args.seed)],
                      args.timeout, {"target_dofs": size, "backend": backend})


def _fmt(v, spec, missing="-"):
    return missing if v is None else format(v, spec)


def print_table(results: list[dict]) -> str:
    head = (f"{'size':>8} {'n_dof':>8} {'backend':>8} {'factor s':>9} {'solve100 s':>10} "
            f"{'peak MB':>8} {'solver MB':>9} {'residual':>9} {'factor x':>8} {'solve x':>7} {'mem x':>6}")
    lines = [head, "-" * len(head)]
    ref = {r["target_dofs"]: r for r in results if r.get("backend") == "scipy" and "error" not in r}
    for r in results:
        if "error" in r:
            lines.append(f"{r['target_dofs']:>8} {'':>8} {r['backend']:>8}  {r['error']}")
            continue
        s = ref.get(r["target_dofs"])
        fx = s["factor_seconds"] / r["factor_seconds"] if s else None
        sx = s["solve_seconds"] / r["solve_seconds"] if s else None
        mx = s["solver_mb"] / r["solver_mb"] if s and r["solver_mb"] > 0 else None
        lines.append(
            f"{r['target_dofs']:>8} {r['n_dof']:>8} {r['backend']:>8} {r['factor_seconds']:>9.2f} "
            f"{r['solve_seconds']:>10.2f} {r['peak_mb']:>8.0f} {r['solver_mb']:>9.0f} "
            f"{r['residual']:>9.1e} {_fmt(fx, '>8.1f')} {_fmt(sx, '>7.1f')} {_fmt(mx, '>6.1f')}"
        )
    lines.append("x = speed-up / memory saving relative to scipy (SuperLU) at the same size; "
                 "solver MB = peak RSS during factor+solve minus RSS before.")
    text = "\n".join(lines)
    print(text)
    return text


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="30000,100000",
                   help="comma-separated target DOF counts (default 30000,100000)")
    p.add_argument("--backends", default=None,
                   help="comma-separated backends (default: flexmor.linalg.available_backends())")
    p.add_argument("--skip-scipy-above", type=int, default=120_000, metavar="N",
                   help="skip the scipy (SuperLU) backend above N DOF (default 120000; "
                        "SuperLU needs minutes and 6-12 GB at 100k DOF)")
    p.add_argument("--nrhs", type=int, default=100, help="right-hand sides of the block solve (default 100)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds per case (default 3600)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"JSON output (default {DEFAULT_OUT})")
    p.add_argument("--assembly", action="store_true",
                   help="instead: time the model assembly (seconds, peak RSS) for --sizes")
    p.add_argument("--case", help=argparse.SUPPRESS)
    args = p.parse_args(argv)

    if args.case:
        size, backend = args.case.split(":")
        if backend == "assembly":
            print(json.dumps(run_assembly(int(size))))
        else:
            print(json.dumps(run_case(int(size), backend, args.nrhs, args.seed)))
        return 0

    from flexmor.linalg import available_backends
    from flexmor.models import cantilever, size_for_dofs  # noqa: F401 - fail early without skfem

    sizes = [int(float(s)) for s in args.sizes.split(",") if s.strip()]
    if args.assembly:
        rows = assembly_table(sizes, args)
        out = pathlib.Path(args.out).with_name("assembly.json") if args.out == str(DEFAULT_OUT) else pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"machine": _machine(), "results": rows}, indent=2))
        print(f"# wrote {out}")
        return 0
    backends = args.backends.split(",") if args.backends else available_backends()
    # scipy last in each size, so the faster backends report first
    backends = sorted(backends, key=lambda b: b == "scipy")
    machine = _machine()
    print(f"# {machine['date']}  {machine.get('cpu', '?')}  {machine['cores']} cores  "
          f"{machine.get('mem_gb', '?')} GB  backends: {', '.join(backends)}", flush=True)
    results = []
    for size in sizes:
        for backend in backends:
            if backend == "scipy" and size > args.skip_scipy_above:
                results.append({"target_dofs": size, "backend": backend,
                                "error": f"skipped (--skip-scipy-above {args.skip_scipy_above})"})
                continue
            print(f"# running {size} DOF with {backend} ...", file=sys.stderr, flush=True)
            r = _spawn(size, backend, args)
            results.append(r)
            if "error" in r:
                print(f"#   {r['error']}", file=sys.stderr, flush=True)
            else:
                print(f"#   n_dof={r['n_dof']} factor {r['factor_seconds']:.2f} s, solve "
                      f"{r['solve_seconds']:.2f} s, peak {r['peak_mb']:.0f} MB", file=sys.stderr, flush=True)
    table = print_table(results)
    write_results(args.out, {"machine": machine, "nrhs": args.nrhs, "results": results, "table": table})
    return 0


if __name__ == "__main__":
    sys.exit(main())
