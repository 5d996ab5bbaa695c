#!/usr/bin/env python
"""The cost around the methods, side by side with the bare solver work, in one run.

Parts (``--parts``, default all):

``krylov``
    ``krylov`` of order ``--order`` (174) with six inputs, band 1-2000 Hz, the whole of what
    ``flexmor reduce --no-error`` does: the rigid-body check, the basis with its points check, the
    projection, the reduced eigenvalues and the file (HDF5), against one bare factorization of
    ``K + s0^2 M`` at the same point plus as many block solves of the same width (``ratio``; the
    check's solves among them), and plus only the ``r`` columns in blocks of the inputs
    (``ratio_r``: the bare work of the basis alone); ``ratio_r_no_check`` leaves out the rigid-body
    check's own work (its time less the factorization it keeps for the method; the ``read`` part
    counts it). Models: the
    built-in cantilever (27,000 DOF, ``TIP`` and ``TIP_CENTER``), the plate structure
    (``plate_structure(56)``, 35,988 DOF, six RBE3 ports ``HOLE@rbe3:x ... rz``) and a CalculiX
    C3D10 bar export (``--c3d10 NX,NY,NZ`` cells, clamped, six RBE3 ports at the free end; made
    with ``ccx`` once and kept in ``bench/results/c3d10_*``; skipped without ccx).
``read``
    Reading the C3D10 export (clamped and free: with the mass check its quadratic elements get)
    plus the rigid-body check, against one factorization of its ``K - sigma M`` (``sigma`` the
    default shift, the matrix ``modal`` factorizes): where the sources keep that factorization for
    the check (``factorize_shifted``) the check runs on it, else it makes its own. ``--large DOF``:
    the same for the built-in free cantilever of that size (no file read; 0 skips it).
``busy``
    Each method on ``plate_structure(--busy-n)`` (Rayleigh damping 2 1/s, 1e-6 s; RBE3 ports at the
    hole; interface ``HOLE@rbe2``
    where the method takes one, on the model coupled so): wall time quiet, then beside one
    CPU-bound process (a Python busy loop), each in a fresh process; ratio busy / quiet.
``free``
    The free plate structure (``plate_structure(56, lower='mass')``, RBE2 at the hole, 35,604 DOF)
    at order ``--free-order`` (40): ``krylov`` (inputs ``HOLE@RBE2:all``) against ``craig-bampton``,
    ``cms-krylov`` and ``cms-gramian`` (interface ``HOLE@RBE2``); with ``--free-models plate,c3d10``
    also the free CalculiX C3D10 bar (RBE2 at ``TIP``, inputs ``TIP@RBE2:all``, 34,686 DOF).

``--src A,B`` runs every case with each of the source trees given (``PYTHONPATH``), alternately, so
that two versions compare under the same load. Each case runs in a fresh process (best of
``--repeat``); the load average before each part is printed. Results: ``bench/results/around.json``.

Usage::

    .venv/bin/python bench/around_methods.py
    .venv/bin/python bench/around_methods.py --parts krylov,free --src /old/src,src
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"
BAND = (1.0, 2000.0)
SIX = ("x", "y", "z", "rx", "ry", "rz")
CANTILEVER_INPUTS = ["TIP:x", "TIP:y", "TIP:z", "TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]
BUSY_METHODS = {  # method: (order, takes an interface)
    "modal": (30, False), "guyan": (None, True), "craig-bampton": (30, True), "cms-krylov": (30, True),
    "cms-gramian": (30, True), "krylov": (30, False), "irka": (12, False), "adaptive": (30, False),
    "sobt": (20, False), "fw-sobt": (20, False), "pod": (20, False), "two-step": (20, False), "svdmor": (20, False),
}


# ------------------------------------------------------------------------------------------- the cases (child)
def _c3d10(cells: str, clamped: bool) -> Path:
    """The CalculiX C3D10 bar export (made once with ccx, kept in bench/results)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from ccx_models import CCX, deck, run

    folder = RESULTS / f"c3d10_{cells.replace(',', 'x')}_{'clamped' if clamped else 'free'}"
    sti = folder / "bar.sti"
    if sti.exists():
        return sti
    if CCX is None:
        raise SystemExit("ccx (CalculiX) is not installed: no C3D10 export")
    text, _ = deck("C3D10", tuple(int(c) for c in cells.split(",")), clamped=clamped, modes=10)
    folder.mkdir(parents=True, exist_ok=True)
    return Path(run(folder, "bar", text))


def _model(name: str, args):
    import warnings

    import flexmor
    from flexmor.errors import FlexmorWarning
    from flexmor.models import cantilever, plate_structure, size_for_dofs

    if name == "cantilever":
        return cantilever(size_for_dofs(args.cantilever_dofs)), CANTILEVER_INPUTS
    if name == "plate":
        return plate_structure(args.plate_n), [f"HOLE@rbe3:{d}" for d in SIX]
    if name == "c3d10":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlexmorWarning)
            model = flexmor.read(_c3d10(args.c3d10, True))
        return model, [f"TIP@rbe3:{d}" for d in SIX]
    raise SystemExit(f"unknown model {name}")


def _warm_up():
    """Load the solver libraries (MKL, PARDISO) before anything is timed."""
    import scipy.sparse as sp

    from flexmor.linalg import factorize

    factorize(sp.identity(10, format="csr") * 2.0, symmetric=True, positive=True).solve(__import__("numpy").ones(10))


def case_krylov(args) -> dict:
    import numpy as np

    import flexmor.workflow as workflow
    from flexmor.io.hdf5 import write_body
    from flexmor.linalg import SolverContext, factorize
    from flexmor.ports import make_ports
    from flexmor.workflow import reduce_and_judge

    model, inputs = _model(args.model, args)
    ports = make_ports(model, inputs)
    _warm_up()
    check, timed = workflow.check_rigid_body_modes, {}

    def timed_check(*a, **k):  # the read-time check's own work: its time less the factorization it keeps
        t = time.perf_counter()
        try:
            return check(*a, **k)
        finally:
            timed["check_s"] = time.perf_counter() - t - k["solver"].stats.seconds

    workflow.check_rigid_body_modes = timed_check
    best = None
    for _ in range(args.repeat):
        ctx = SolverContext()
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            red, _ = reduce_and_judge(model, "krylov", args.order, ports, band=None, method_band=BAND, solver=ctx,
                                      points=repr(float(np.sqrt(BAND[0] * BAND[1]))))  # the reference's one point
            t1 = time.perf_counter()
            lam = red.frequencies_hz()
            t2 = time.perf_counter()
            write_body(red, Path(tmp) / "body.h5")
            t3 = time.perf_counter()
        st = ctx.stats
        width = max(st.solve_columns // max(st.solves, 1), 1)
        s0 = 2 * np.pi * np.sqrt(BAND[0] * BAND[1])
        A = (model.K + s0 ** 2 * model.M).tocsr()
        X = [np.random.default_rng(i).standard_normal((model.n_dof, width)) for i in range(st.solves)]
        t4 = time.perf_counter()
        F = factorize(A, solver=SolverContext(), symmetric=True, positive=True, check=False)
        t5 = time.perf_counter()
        for k, x in enumerate(X):
            F.solve(x)
            if k + 1 == -(-red.order // len(inputs)):  # r columns in blocks of the inputs: the issue's reference
                t_r = time.perf_counter()
        t6 = time.perf_counter()
        del F, X
        floor = _floor(model, red.order, len(inputs))
        tm = red.info["timings"]
        row = {"whole_s": t3 - t0, "check_and_reduce_s": t1 - t0, "basis_s": tm["basis"], "project_s": tm["project"],
               "eigenvalues_s": t2 - t1, "file_s": t3 - t2, "factorizations": st.count, "factorize_s": st.seconds,
               "solves": st.solves, "width": width, "solve_s": st.solve_seconds, "bare_factorize_s": t5 - t4,
               "bare_solves_s": t6 - t5, "bare_s": t6 - t4, "order": red.order, "lowest_hz": float(lam[0]),
               "bare_r_s": t_r - t4 if st.solves >= -(-red.order // len(inputs)) else t6 - t4}
        row["check_s"] = timed.get("check_s", 0.0)
        row["ratio"] = row["whole_s"] / row["bare_s"]
        row["ratio_r"] = row["whole_s"] / row["bare_r_s"]
        # the reduction alone (basis, points check, projection, eigenvalues, file): without the read-time
        # rigid-body check, which the read part counts
        row["ratio_r_no_check"] = (row["whole_s"] - row["check_s"]) / row["bare_r_s"]
        row.update(floor)
        row["floor_ratio_r"] = (row["bare_r_s"] + floor["floor_extra_s"]) / row["bare_r_s"]
        if best is None or row["ratio"] < best["ratio"]:
            best = row
    best.update(n_dof=model.n_dof, model=args.model)
    return best


def _floor(model, r: int, b: int) -> dict:
    """The least any Galerkin projection onto an orthonormal basis of ``r`` columns built ``b`` at a time adds to
    its solves: the products ``K V``, ``M V`` (as :func:`flexmor.projection.reduced_matrices` forms them) and
    ``V^T K V``, ``V^T M V``, and one classical Gram-Schmidt pass per block (``h = V^T X``, ``X - V h``: each
    new block read against the columns before it once, half of what a stable CGS2 does), on random data."""
    import numpy as np

    from flexmor.linalg.threads import blas_threads, sparse_dense

    try:
        from flexmor.linalg.threads import dense_threads
    except ImportError:  # a tree from before it: one thread
        def dense_threads(entries):
            return 1

    rng = np.random.default_rng(0)
    V = np.asfortranarray(rng.standard_normal((model.n_dof, r)))
    with blas_threads(dense_threads(V.size)):  # as the basis and the projection run them
        gs = 0.0
        for j in range(b, r, b):
            X = np.asfortranarray(rng.standard_normal((model.n_dof, min(b, r - j))))  # not timed
            t0 = time.perf_counter()
            X -= V[:, :j] @ (V[:, :j].T @ X)
            gs += time.perf_counter() - t0
        Vc, K, M = np.ascontiguousarray(V), model.K.tocsr(), model.M.tocsr()
        t0 = time.perf_counter()
        for A in (K, M):
            Vc.T @ sparse_dense(A, Vc)
        proj = time.perf_counter() - t0
    return {"floor_gram_schmidt_s": gs, "floor_projection_s": proj, "floor_extra_s": gs + proj}


def case_read(args) -> dict:
    import warnings

    import flexmor
    from flexmor.checks import check_rigid_body_modes
    from flexmor.errors import FlexmorWarning
    from flexmor.linalg import SolverContext, factorize
    from flexmor.linalg.eigen import default_shift

    if args.model == "large":
        from flexmor.models import cantilever, size_for_dofs

        path, t_read = None, 0.0
        model = cantilever(size_for_dofs(args.large, clamped=False), clamped=False)
    else:
        path = _c3d10(args.c3d10, args.model == "clamped")
    _warm_up()
    try:  # the check on the factorization the method makes anyway (sources that keep it)
        from flexmor.linalg.factorize import factorize_shifted
    except ImportError:
        factorize_shifted = None
    best = None
    for _ in range(args.repeat):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlexmorWarning)
            if path is not None:
                t0 = time.perf_counter()
                model = flexmor.read(path)
                t_read = time.perf_counter() - t0
            sigma = default_shift(model.K, model.M)
            ctx = SolverContext()
            t0 = time.perf_counter()
            if factorize_shifted is not None:  # the method's factorization, kept for the check
                F = factorize_shifted(model.K, model.M, sigma, solver=ctx, keep=True)
            else:  # (freed before the check makes its own: one large factorization at a time)
                F = factorize((model.K - sigma * model.M).tocsr(), solver=ctx, symmetric=True, positive=True,
                              check=False)
            t_fact = time.perf_counter() - t0
            if factorize_shifted is None:
                del F
                F = None
            t0 = time.perf_counter()
            if factorize_shifted is not None:
                n_rigid = check_rigid_body_modes(model, solver=ctx, sigma=sigma)
            else:  # older sources: the check makes its own factorization
                n_rigid = check_rigid_body_modes(model, solver=ctx)
            t_check = time.perf_counter() - t0
            del F
            ctx = None
        row = {"read_s": t_read, "rigid_check_s": t_check, "factorize_s": t_fact, "n_rigid": n_rigid,
               "shared": factorize_shifted is not None, "ratio": (t_read + t_check) / t_fact}
        if best is None or row["ratio"] < best["ratio"]:
            best = row
    best.update(n_dof=model.n_dof, model=args.model)
    return best


def case_method(args) -> dict:
    from flexmor.couplings import couple
    from flexmor.linalg import SolverContext
    from flexmor.models import plate_structure
    from flexmor.ports import make_ports
    from flexmor.reduction import methods, reduce

    if args.free_body and args.model == "c3d10":
        import warnings

        import flexmor
        from flexmor.errors import FlexmorWarning

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlexmorWarning)
            model = couple(flexmor.read(_c3d10(args.c3d10, False)), ["TIP@rbe2"]).model
        ports, iface = make_ports(model, ["TIP@RBE2:all"]), ["TIP@RBE2"]
    elif args.free_body:
        model = couple(plate_structure(args.busy_n, lower="mass"), ["HOLE@rbe2"]).model
        ports, iface = make_ports(model, ["HOLE@RBE2:all"]), ["HOLE@RBE2"]
    else:  # damped (Rayleigh 2 1/s, 1e-6 s): irka needs it, and the others take it as it is
        base = plate_structure(args.busy_n).with_rayleigh(2.0, 1e-6)
        model = couple(base, ["HOLE@rbe2"]).model if BUSY_METHODS[args.method][1] else base
        ports = make_ports(model, ["HOLE@RBE2:all"] if BUSY_METHODS[args.method][1] else
                           [f"HOLE@rbe3:{d}" for d in SIX])
        iface = ["HOLE@RBE2"]
    m = methods()[args.method]
    opts = {"interface": iface} if "interface" in m.options else {}
    if "band" in m.options:
        opts["band"] = BAND
    _warm_up()
    best = float("inf")
    for _ in range(args.repeat):
        ctx = SolverContext()
        t0 = time.perf_counter()
        red = reduce(model, args.method, args.order, ports, solver=ctx, **opts)
        best = min(best, time.perf_counter() - t0)
    return {"method": args.method, "n_dof": model.n_dof, "order": red.order, "seconds": best,
            "factorizations": ctx.stats.count, "solves": ctx.stats.solves}


# ------------------------------------------------------------------------------------------- the run (parent)
def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _child(src: str, argv: list[str], busy: bool = False) -> dict:
    env = dict(os.environ, PYTHONPATH=src)
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        if burner is not None:
            time.sleep(0.5)
        proc = subprocess.run([sys.executable, __file__, "--case", *argv], env=env, capture_output=True, text=True,
                              timeout=3600)
    finally:
        if burner is not None:
            burner.kill()
            burner.wait()
    if proc.returncode:
        return {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _label(src: str, srcs: list[str]) -> str:
    return "" if len(srcs) == 1 else f"[{'before' if src == srcs[0] else 'after'}] "


def _row(rows: list, src: str, srcs: list[str], name: str, argv: list[str]) -> dict | None:
    """One case in a child process: its record (with ``src``) appended to ``rows``; None (said) on an error."""
    r = _child(src, argv)
    r["src"] = src
    rows.append(r)
    if "error" in r:
        print(f"  {_label(src, srcs)}{name}: {r['error']}")
        return None
    return r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("--parts", default="krylov,read,busy,free")
    ap.add_argument("--order", type=int, default=174)
    ap.add_argument("--c3d10", default="20,8,8", help="cells NX,NY,NZ of the C3D10 bar")
    ap.add_argument("--large", type=int, default=1_000_000, help="DOF of the large check case (0: none)")
    ap.add_argument("--read-cases", default="clamped,free,large", help="of the read part")
    ap.add_argument("--busy-n", type=int, default=40)
    ap.add_argument("--free-order", type=int, default=40)
    ap.add_argument("--free-n", type=int, default=56, help="plate_structure(n, lower='mass') of the free part")
    ap.add_argument("--free-models", default="plate", help="of the free part: plate, c3d10 (needs ccx once)")
    ap.add_argument("--plate-n", type=int, default=56, help="plate_structure(n) of the krylov part")
    ap.add_argument("--cantilever-dofs", type=int, default=27000)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--models", default="cantilever,plate,c3d10")
    ap.add_argument("--methods", default=",".join(BUSY_METHODS))
    ap.add_argument("--src", default=str(ROOT / "src"), help="source tree(s), comma-separated")
    ap.add_argument("--out", default=str(RESULTS / "around.json"))
    ap.add_argument("--case", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.case:
        return _run_case(args.case)
    srcs = [str(Path(s).resolve()) for s in args.src.split(",")]
    parts = args.parts.split(",")
    out = {"python": sys.version.split()[0], "machine": platform.processor() or platform.machine(),
           "cores": os.cpu_count(), "sources": srcs, "date": time.strftime("%Y-%m-%d %H:%M"), "parts": {}}
    rep = ["--repeat", str(args.repeat)]
    if "krylov" in parts:
        print(f"krylov r={args.order}, whole reduce vs bare factorization + solves (load {_load()})", flush=True)
        rows = out["parts"]["krylov"] = []
        for model in args.models.split(","):
            if model == "c3d10" and shutil.which("ccx") is None and not any(RESULTS.glob("c3d10_*/bar.sti")):
                print("  c3d10: skipped (no ccx)")
                continue
            for src in srcs:
                r = _row(rows, src, srcs, model, ["krylov", "--model", model, "--order", str(args.order), "--c3d10",
                                                  args.c3d10, "--plate-n", str(args.plate_n), "--cantilever-dofs",
                                                  str(args.cantilever_dofs), *rep])
                if r is None:
                    continue
                print(f"  {_label(src, srcs)}{model:10s} {r['n_dof']:7d} DOF r={r['order']}: "
                      f"whole {r['whole_s']:.2f} s "
                      f"(check+reduce {r['check_and_reduce_s']:.2f}, eigenvalues {r['eigenvalues_s']:.3f}, file "
                      f"{r['file_s']:.2f}; {r['factorizations']} factorization(s) {r['factorize_s']:.2f} s, "
                      f"{r['solves']} solves x {r['width']} {r['solve_s']:.2f} s) | bare {r['bare_factorize_s']:.2f} + "
                      f"{r['bare_solves_s']:.2f} = {r['bare_s']:.2f} s | ratio {r['ratio']:.2f} | bare with r columns "
                      f"only {r['bare_r_s']:.2f} s: ratio {r['ratio_r']:.2f}, without the rigid-body check "
                      f"({r.get('check_s', 0):.2f} s) {r.get('ratio_r_no_check', 0):.2f} | floor: + one "
                      f"Gram-Schmidt pass "
                      f"{r['floor_gram_schmidt_s']:.2f} + projection products {r['floor_projection_s']:.2f} s: "
                      f"{r['floor_ratio_r']:.2f} x bare", flush=True)
    if "read" in parts:
        print(f"read + checks vs one factorization of K - sigma M (load {_load()})", flush=True)
        rows = out["parts"]["read"] = []
        cases = [c for c in args.read_cases.split(",") if c != "large" or args.large]
        for model in cases:
            for src in srcs:
                r = _row(rows, src, srcs, model, ["read", "--model", model, "--c3d10", args.c3d10, "--large",
                                                  str(args.large), "--repeat",
                                                  "1" if model == "large" else str(args.repeat)])
                if r is None:
                    continue
                print(f"  {_label(src, srcs)}{model:8s} {r['n_dof']:8d} DOF: read {r['read_s']:.2f} s + rigid check "
                      f"{r['rigid_check_s']:.2f} s ({r['n_rigid']} rigid) | factorization {r['factorize_s']:.2f} s | "
                      f"ratio {r['ratio']:.2f}", flush=True)
    if "busy" in parts:
        print(f"each method quiet and beside one CPU-bound process, plate_structure({args.busy_n}) "
              f"(load {_load()})", flush=True)
        rows = out["parts"]["busy"] = []
        for method in args.methods.split(","):
            order = BUSY_METHODS[method][0]
            for src in srcs:
                a = ["method", "--method", method, "--busy-n", str(args.busy_n), *rep]
                a += ["--order", str(order)] if order else []
                q, b = _child(src, a), _child(src, a, busy=True)
                row = {"method": method, "src": src, "quiet": q, "busy": b}
                rows.append(row)
                if "error" in q or "error" in b:
                    print(f"  {_label(src, srcs)}{method}: {q.get('error') or b.get('error')}")
                    continue
                row["ratio"] = b["seconds"] / q["seconds"]
                print(f"  {_label(src, srcs)}{method:14s} r={q['order']:3d} quiet {q['seconds']:6.2f} s  busy "
                      f"{b['seconds']:6.2f} s  ratio {row['ratio']:.2f}", flush=True)
    if "free" in parts:
        rows = out["parts"]["free"] = []
        for fm in args.free_models.split(","):
            what = "plate structure, RBE2 at the hole" if fm == "plate" else "C3D10 bar, RBE2 at TIP"
            print(f"free {what}, order {args.free_order} (load {_load()})", flush=True)
            for src in srcs:
                ref = None
                for method in ("krylov", "craig-bampton", "cms-krylov", "cms-gramian"):
                    r = _row(rows, src, srcs, method, ["method", "--method", method, "--free-body", "--model", fm,
                                                       "--busy-n", str(args.free_n), "--c3d10", args.c3d10,
                                                       "--order", str(args.free_order), *rep])
                    if r is None:
                        continue
                    r["free_model"] = fm
                    ref = r["seconds"] if method == "krylov" else ref
                    print(f"  {_label(src, srcs)}{method:14s} {r['n_dof']} DOF r={r['order']:3d} {r['seconds']:6.2f} s "
                          f"({r['factorizations']} factorizations, {r['solves']} solves)  x krylov "
                          f"{r['seconds'] / ref:.2f}" if ref else "", flush=True)
    out["load_end"] = _load()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1, default=float))
    print(f"load average at the end {out['load_end']}; written {args.out}")
    return 0


def _run_case(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False)
    ap.add_argument("kind")
    ap.add_argument("--model", default="plate")
    ap.add_argument("--method", default="krylov")
    ap.add_argument("--order", type=int, default=None)
    ap.add_argument("--c3d10", default="20,8,8")
    ap.add_argument("--large", type=int, default=0)
    ap.add_argument("--busy-n", type=int, default=40)
    ap.add_argument("--free-body", action="store_true")
    ap.add_argument("--plate-n", type=int, default=56)
    ap.add_argument("--cantilever-dofs", type=int, default=27000)
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args(argv)
    res = {"krylov": case_krylov, "read": case_read, "method": case_method}[a.kind](a)
    print(json.dumps(res, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
