#!/usr/bin/env python
"""Benchmark of the interpolation methods (``krylov``, ``irka``, ``adaptive``).

Part 1, overhead (``--size``, default 100k DOF): the built-in clamped cantilever
(``cantilever(size_for_dofs(size))``) with six inputs (``TIP:x/y/z`` spread over the tip face
and ``TIP_CENTER:x/y/z`` at its centre node). ``krylov`` of order 60 at the single point
``s = 0`` needs one factorization of ``K`` and 10 block solves with 6 right-hand sides. The
reference is exactly that bare work: ``factorize(K)`` plus 10 solves of random (n, 6) blocks.
``ratio = time(krylov basis) / time(reference)`` shows what the second-order Arnoldi process
(sparse products with ``M`` and ``D``, block Gram-Schmidt twice, deflation, merge) costs on
top of the solver. Also timed: ``krylov`` r = 60 at the three real points of the earlier
default over the band 1-3000 Hz, the projection, and the current default (one real point at the
band's geometric mean, checked) against its own factorizations + solves (``ratio_own``) and
against one bare factorization at that point + as many bare block solves, measured in the same
run (``ratio_bare``); both ratios count everything ``reduce`` does (basis, check, projection).

Part 2, quality (``--cmp-size``, default 3k DOF, Rayleigh damping ``alpha=10 1/s``,
``beta=1e-6 s``, band 1-3000 Hz, same six inputs, collocated outputs): time and band_error of
``modal``, ``krylov``, ``adaptive`` and ``irka`` at order ``--cmp-order`` and, when a Python
with pyMOR is given (``--pymor-python``), pyMOR's ``SORIRKAReductor`` at the same order (run in
that interpreter in a child process on the same matrices; its reduced model is two-sided,
so it is evaluated from its own reduced matrices).

Part 3, the whole reduce on solid models with coupled ports (``--whole cantilever,plate,c3d10``):
``krylov`` of order ``--order`` with what ``flexmor reduce --no-error`` does around it (rigid-body
check, points check, projection, reduced eigenvalues, file) against one bare factorization at its
point plus as many block solves: :func:`around_methods.main` (``bench/around_methods.py``, part
``krylov``, where the cases are described).

Usage::

    python bench/krylov.py --whole cantilever,plate,c3d10 --order 174 --skip-overhead --skip-compare
    python bench/krylov.py                                   # both parts
    python bench/krylov.py --size 30000 --cmp-size 3000 --pymor-python /tmp/pymor-venv/bin/python

Writes ``bench/results/krylov.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
INPUTS = ["TIP:x", "TIP:y", "TIP:z", "TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]


def overhead(size: int, order: int, backend: str, repeat: int) -> dict:
    from flexmor.linalg import SolverContext, factorize
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.projection import reduced_matrices
    from flexmor.reduction import reduce
    from flexmor.reduction.krylov import default_points

    model = cantilever(size_for_dofs(size))
    ports = make_ports(model, INPUTS)
    m = ports.n_inputs
    n_blocks = -(-order // m)
    rng = np.random.default_rng(0)
    t_ref, t_kry, t_proj = [], [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        F = factorize(model.K, solver=SolverContext(backend), symmetric=True, positive=True, check=False)
        t1 = time.perf_counter()
        for _ in range(n_blocks):
            F.solve(rng.standard_normal((model.n_dof, m)))
        t_ref.append((t1 - t0, time.perf_counter() - t1))
        del F
        red = reduce(model, "krylov", order, ports, points="0", solver=SolverContext(backend))
        t = red.info["timings"]
        t_kry.append(t["basis"])
        t_proj.append(t["project"])
    ref = min(a + b for a, b in t_ref)
    band = (1.0, 3000.0)
    red3 = reduce(model, "krylov", order, ports, band=band, points=",".join(str(p.real) for p in
                                                                          default_points(band)),
                  solver=SolverContext(backend))
    t3 = red3.info["timings"]
    # the default point (one real point at the band's geometric mean, checked) against the bare work at
    # that point: one factorization of K + s0^2 M and as many block solves as the basis made
    s0 = 2 * np.pi * default_points(band, 1)[0].real
    A0 = (model.K + s0 ** 2 * model.M).tocsr()
    t_def, t_bare, own, cpu = [], [], [], []
    for _ in range(repeat):
        ctx = SolverContext(backend)
        c0 = time.process_time()
        red1 = reduce(model, "krylov", order, ports, band=band, solver=ctx)
        t1 = red1.info["timings"]
        c1 = time.process_time()
        t_def.append((t1["basis"] + t1["project"], t1["basis"], t1["project"]))
        st = ctx.stats
        own.append((st.count, st.seconds, st.solves, st.solve_seconds))
        X = [rng.standard_normal((model.n_dof, m)) for _ in range(st.solves)]
        c2, t0 = time.process_time(), time.perf_counter()
        F = factorize(A0, solver=SolverContext(backend), symmetric=True, positive=True, check=False)
        for x in X:
            F.solve(x)
        t_bare.append(time.perf_counter() - t0)
        cpu.append((c1 - c0) / (time.process_time() - c2))  # CPU seconds (all threads): less load-sensitive
        del F, X
    best = int(np.argmin([t[0] for t in t_def]))
    n_fact, f_s, n_solves, s_s = own[best]
    reduce_s, basis_s, project_s = t_def[best]
    # the projection's sparse products and dense products (V^T M V, V^T K V), which the check shares
    # with the body: timed alone on the same basis, the rest of reduce is the basis and its check
    products = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        reduced_matrices(model, red1.V)
        products.append(time.perf_counter() - t0)
    return {"n_dof": model.n_dof, "nnz_K": int(model.K.nnz), "inputs": INPUTS, "order": red.order,
            "block_solves": n_blocks, "backend": backend,
            "ref_factorize_s": min(a for a, _ in t_ref), "ref_solves_s": min(b for _, b in t_ref), "ref_s": ref,
            "krylov_basis_s": min(t_kry), "krylov_project_s": min(t_proj), "ratio": min(t_kry) / ref,
            "krylov_3points_basis_s": t3["basis"], "krylov_3points_order": red3.order,
            "default": {"reduce_s": reduce_s, "basis_s": basis_s, "project_s": project_s,
                        "points_hz": red1.info["points_hz"],
                        "points_check": red1.info["points_check"], "factorizations": n_fact,
                        "factorize_s": f_s, "block_solves": n_solves, "solve_s": s_s,
                        "ratio_own": reduce_s / (f_s + s_s), "bare_s": min(t_bare),
                        "projection_products_s": min(products),
                        "ratio_basis_own": (reduce_s - min(products)) / (f_s + s_s),
                        "ratio_bare": reduce_s / min(t_bare), "cpu_ratio_bare": min(cpu), "threads": _threads()}}


def _threads() -> dict:
    """The thread settings of the run (environment), for the record."""
    import os

    return {k: os.environ.get(k) for k in ("MKL_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def _pymor_worker(inp: str, out: str) -> None:
    """Runs in the pyMOR interpreter: SOR-IRKA on the matrices in ``inp``."""
    import logging

    import scipy.sparse as sp
    from pymor.models.iosys import SecondOrderModel
    from pymor.reductors.sor_irka import SORIRKAReductor

    logging.getLogger("pymor").setLevel(logging.ERROR)
    d = np.load(inp)
    mats = [sp.csc_matrix((d[k + "_data"], d[k + "_indices"], d[k + "_indptr"]), shape=tuple(d[k + "_shape"]))
            for k in ("M", "D", "K")]
    fom = SecondOrderModel.from_matrices(mats[0], mats[1], mats[2], d["B"], d["C"])
    t0 = time.perf_counter()
    red = SORIRKAReductor(fom)
    rom = red.reduce(int(d["r"]), maxit=int(d["maxit"]), tol=1e-4)
    sec = time.perf_counter() - t0
    np.savez(out, M=rom.M.matrix, D=rom.E.matrix, K=rom.K.matrix, B=rom.B.matrix, C=rom.Cp.matrix, seconds=sec,
             iterations=len(red.conv_crit), conv=np.array(red.conv_crit))


def compare(size: int, order: int, pymor_python: str | None, maxit: int) -> dict:
    from flexmor.analysis.compare import FullResponse
    from flexmor.analysis.frequency import band_error
    from flexmor.body import ReducedModel
    from flexmor.dynamics.frf import frf_reduced
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.workflow import reduce_and_judge

    band = (1.0, 3000.0)
    model = cantilever(size_for_dofs(size)).with_rayleigh(10.0, 1e-6)
    ports = make_ports(model, INPUTS)
    full = FullResponse(model, ports, band)
    rows = {}
    for method in ("modal", "krylov", "adaptive", "irka"):
        red, res = reduce_and_judge(model, method, order, ports, full=full, band=band)
        rows[method] = {"order": red.order, "seconds": res["seconds"], "band_error": res["band_error"]}
        if method == "irka":
            rows[method].update(iterations=red.info["iterations"], converged=red.info["converged"])
    if pymor_python:
        with tempfile.TemporaryDirectory() as tmp:
            inp, out = f"{tmp}/in.npz", f"{tmp}/out.npz"
            arrs = {}
            for k, A in (("M", model.M), ("D", model.D), ("K", model.K)):
                A = A.tocsc()
                arrs.update({k + "_data": A.data, k + "_indices": A.indices, k + "_indptr": A.indptr,
                             k + "_shape": np.array(A.shape)})
            np.savez(inp, B=ports.B.toarray(), C=ports.C.toarray(), r=order, maxit=maxit, **arrs)
            t0 = time.perf_counter()
            proc = subprocess.run([pymor_python, __file__, "--pymor-worker", inp, out], capture_output=True, check=False,
                                  text=True)
            if proc.returncode:
                rows["pymor_sor_irka"] = {"error": proc.stderr.strip().splitlines()[-1:]}
            else:
                d = np.load(out)
                red = ReducedModel(M=d["M"], K=d["K"], D=d["D"], B=d["B"], C=d["C"])
                err = band_error(full.freqs, full.H, frf_reduced(red, full.freqs))
                rows["pymor_sor_irka"] = {"order": int(d["M"].shape[0]), "seconds": float(d["seconds"]),
                                          "band_error": err, "iterations": int(d["iterations"]),
                                          "last_conv": float(d["conv"][-1]), "process_s": time.perf_counter() - t0}
    return {"n_dof": model.n_dof, "band_hz": list(band), "order": order, "rayleigh": [10.0, 1e-6],
            "n_freq": int(full.freqs.size), "full_frf_s": full.seconds, "methods": rows}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=100_000)
    ap.add_argument("--order", type=int, default=60)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--cmp-size", type=int, default=3000)
    ap.add_argument("--cmp-order", type=int, default=30)
    ap.add_argument("--pymor-python", help="a Python interpreter with pyMOR installed")
    ap.add_argument("--pymor-maxit", type=int, default=50)
    ap.add_argument("--skip-overhead", action="store_true")
    ap.add_argument("--skip-compare", action="store_true")
    ap.add_argument("--out", default=str(HERE / "results" / "krylov.json"))
    ap.add_argument("--whole", help="models of the whole-reduce part (cantilever,plate,c3d10)")
    ap.add_argument("--pymor-worker", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.whole:
        sys.path.insert(0, str(HERE))
        import around_methods

        around_methods.main(["--parts", "krylov", "--models", args.whole, "--order", str(args.order),
                             "--repeat", str(args.repeat), "--out", str(HERE / "results" / "krylov_whole.json")])
    if args.pymor_worker:
        _pymor_worker(*args.pymor_worker)
        return 0
    res = {"python": sys.version.split()[0], "machine": platform.processor() or platform.machine()}
    if not args.skip_overhead:
        res["overhead"] = o = overhead(args.size, args.order, args.backend, args.repeat)
        print(f"overhead: n_dof {o['n_dof']}, krylov r={o['order']} with {len(INPUTS)} inputs at s=0: "
              f"{o['krylov_basis_s']:.2f} s; factorize {o['ref_factorize_s']:.2f} s + {o['block_solves']} block "
              f"solves {o['ref_solves_s']:.2f} s = {o['ref_s']:.2f} s; ratio {o['ratio']:.2f}; "
              f"projection {o['krylov_project_s']:.2f} s; 3 points {o['krylov_3points_basis_s']:.2f} s")
        d = o["default"]
        print(f"default point(s) {d['points_hz']} (estimate {d['points_check']['estimate']:.1e}): "
              f"basis + projection {d['reduce_s']:.2f} s ({d['basis_s']:.2f} + {d['project_s']:.2f}); its {d['factorizations']} factorization(s) {d['factorize_s']:.2f} s + "
              f"{d['block_solves']} block solves {d['solve_s']:.2f} s: ratio {d['ratio_own']:.2f}; "
              f"bare factorization + {d['block_solves']} solves {d['bare_s']:.2f} s: ratio {d['ratio_bare']:.2f} "
              f"(CPU time {d['cpu_ratio_bare']:.2f}); without the projection's products "
              f"({d['projection_products_s']:.2f} s, shared by the check and the body): ratio {d['ratio_basis_own']:.2f}")
    if args.skip_compare:
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out).write_text(json.dumps(res, indent=1, default=float))
        return 0
    res["compare"] = c = compare(args.cmp_size, args.cmp_order, args.pymor_python, args.pymor_maxit)
    print(f"compare: n_dof {c['n_dof']}, order {c['order']}, band {c['band_hz']} Hz, full FRF "
          f"{c['full_frf_s']:.1f} s ({c['n_freq']} frequencies)")
    for k, v in c["methods"].items():
        extra = {kk: vv for kk, vv in v.items() if kk not in ("order", "seconds", "band_error")}
        if "error" in v:
            print(f"  {k:16s} failed: {v['error']}")
        else:
            print(f"  {k:16s} r={v['order']:3d}  {v['seconds']:8.2f} s  band_error {v['band_error']:.2e}  {extra}")
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
