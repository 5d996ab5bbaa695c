#!/usr/bin/env python
"""flexmor side by side with pyMOR and Exudyn's Craig-Bampton on the ~30k and ~100k DOF models.

For every size in ``--sizes``: the built-in clamped cantilever ``cantilever(size_for_dofs(size))``
with light Rayleigh damping (``--rayleigh``, default ``alpha=10 1/s``, ``beta=1e-6 s``), three
inputs ``TIP_CENTER:x/y/z`` with collocated outputs, band ``--band`` (default 1-3000 Hz,
about ten resonances). One full FRF (:class:`flexmor.analysis.compare.FullResponse`) judges every
reduced body of order ``--order`` (default 24) by its band_error:

========================  =================================================================
flexmor                   external tool (same matrices, same order)
========================  =================================================================
``krylov`` (3 real        pyMOR ``SOLTIPGReductor`` on a basis from pyMOR's own
points over the band)     ``rational_arnoldi``: per point ``s`` and input ``b``, the Krylov
                          space of ``(s^2 M + s D + K)^{-1} b`` with ``E = M``,
                          ``A = -(s D + K)``, ``sigma = s^2`` repeated; columns ordered
                          moment by moment over points and inputs like ``krylov``
``irka``                  pyMOR ``SORIRKAReductor`` (``maxit`` and ``tol`` as ``irka``)
``sobt``, ``fw-sobt``     pyMOR ``SOBTpReductor`` (low-rank ADI Gramians)
``craig-bampton``         Exudyn ``FEMinterface.ComputeHurtyCraigBamptonModes`` with the
(interface               single boundary node ``TIP_CENTER`` and ``order - 3`` eigenmodes,
``TIP_CENTER``)           ``computationMode=allBoundaryNodes``: the classic Craig-Bampton
                          basis (3 constraint modes + fixed-interface modes), mapped back to
                          flexmor's DOF order and projected like flexmor's
========================  =================================================================

pyMOR runs in another interpreter (``--pymor-python``) in a child process per method, on the
matrices saved to a temporary ``.npz`` (the pattern of ``bench/krylov.py``, whose SOR-IRKA
worker is reused); Exudyn runs in a child process of this interpreter. Each external run has
the wall-time limit ``--timeout``; a run that does not finish is reported as such and its time
ratio as a lower bound. pyMOR's sparse solves use SciPy SuperLU (``--pymor-permc`` ordering;
scikit-umfpack is not installed); flexmor uses its ``auto`` backend.

Usage::

    nice -n 5 .venv/bin/python bench/tools.py --pymor-python /tmp/pymor2025-venv/bin/python
    .venv/bin/python bench/tools.py --sizes 3000 --pymor-python /tmp/pymor2025-venv/bin/python --timeout 120

Writes ``bench/results/tools_<size>.json`` (one file per size, written as soon as it is done); the
child processes' outputs and logs stay in ``bench/results/tools_<size>_work/``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import signal
import subprocess
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
INPUTS = ["TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]
#: flexmor method -> the external method it is compared with
PAIRS = {"krylov": "pymor-soltipg-arnoldi", "irka": "pymor-sor-irka", "sobt": "pymor-sobtp",
         "fw-sobt": "pymor-sobtp", "craig-bampton": "exudyn-cb"}
EXTERNAL = ("pymor-soltipg-arnoldi", "pymor-sor-irka", "pymor-sobtp", "exudyn-cb")


# --------------------------------------------------------------------------- child processes
def _load_sparse(d, k):
    import scipy.sparse as sp

    return sp.csc_matrix((d[k + "_data"], d[k + "_indices"], d[k + "_indptr"]), shape=tuple(d[k + "_shape"]))


def _pymor_dense(op):
    from pymor.algorithms.to_matrix import to_matrix

    A = to_matrix(op, format="dense")
    return np.asarray(A)


def _pymor_run(method: str, inp: str, out: str, permc: str) -> None:
    """In the pyMOR interpreter: one pyMOR reductor on the matrices in ``inp``."""
    import logging

    import pymor
    from pymor.core.defaults import set_defaults

    set_defaults({"pymor.bindings.scipy.ScipySpSolveSolver.permc_spec": permc})
    logging.getLogger("pymor").setLevel(logging.ERROR)
    if method == "pymor-sor-irka":
        import krylov  # bench/krylov.py: SOR-IRKA on the same .npz layout

        c0 = time.process_time()
        krylov._pymor_worker(inp, out)
        cpu = time.process_time() - c0  # includes loading the matrices
        d = dict(np.load(out))
        np.savez(out, cpu_s=cpu, version=pymor.__version__, **d)
        return
    from pymor.models.iosys import SecondOrderModel

    d = np.load(inp)
    M, D, K = (_load_sparse(d, k) for k in ("M", "D", "K"))
    fom = SecondOrderModel.from_matrices(M, D, K, d["B"], d["C"])
    r = int(d["r"])
    t0, c0 = time.perf_counter(), time.process_time()
    if method == "pymor-sobtp":
        from pymor.reductors.sobt import SOBTpReductor

        rom = SOBTpReductor(fom).reduce(r)
        extra = {}
    elif method == "pymor-soltipg-arnoldi":
        from pymor.algorithms.gram_schmidt import gram_schmidt
        from pymor.algorithms.krylov import rational_arnoldi
        from pymor.operators.numpy import NumpyMatrixOperator
        from pymor.reductors.basic import SOLTIPGReductor

        points = np.asarray(d["points"], dtype=float)
        counts = np.asarray(d["counts"], dtype=int)  # (n_points, n_inputs) moments per point and input
        Mop, Dop, Kop = fom.M, fom.E, fom.K
        blocks = {}
        for p, s in enumerate(points):
            A = -(s * Dop + Kop)
            for i in range(fom.dim_input):
                if counts[p, i] == 0:
                    continue
                b = NumpyMatrixOperator(d["B"][:, i:i + 1])
                blocks[p, i] = rational_arnoldi(A, Mop, b, [s * s] * int(counts[p, i]))
        V = fom.solution_space.empty()
        for j in range(int(counts.max())):  # moment by moment over points and inputs
            for p in range(len(points)):
                for i in range(fom.dim_input):
                    if (p, i) in blocks and len(blocks[p, i]) > j:
                        V.append(blocks[p, i][j])
        V = gram_schmidt(V, atol=0, rtol=1e-10)[:r]
        rom = SOLTIPGReductor(fom, V, V).reduce()
        extra = {"basis_columns": len(V)}
    else:
        raise SystemExit(f"unknown pyMOR method {method}")
    sec, cpu = time.perf_counter() - t0, time.process_time() - c0
    np.savez(out, M=_pymor_dense(rom.M), D=_pymor_dense(rom.E), K=_pymor_dense(rom.K), B=_pymor_dense(rom.B),
             C=_pymor_dense(rom.Cp), seconds=sec, cpu_s=cpu, version=pymor.__version__, **extra)


def _exudyn_run(inp: str, out: str) -> None:
    """In this interpreter: Exudyn's Hurty-Craig-Bampton modes on the matrices in ``inp``."""
    import exudyn
    from exudyn.FEM import FEMinterface, HCBstaticModeSelection

    d = np.load(inp)
    fem = FEMinterface()
    fem.nodes = {"Position": d["xyz"]}
    fem.massMatrix = _load_sparse(d, "M").tocsr()
    fem.stiffnessMatrix = _load_sparse(d, "K").tocsr()
    t0, c0 = time.perf_counter(), time.process_time()
    fem.ComputeHurtyCraigBamptonModes([[int(k) for k in d["boundary"]]], int(d["n_eig"]), useSparseSolver=True,
                                      computationMode=HCBstaticModeSelection.allBoundaryNodes)
    sec, cpu = time.perf_counter() - t0, time.process_time() - c0
    np.savez(out, V=np.asarray(fem.modeBasis["matrix"], dtype=float), seconds=sec, cpu_s=cpu,
             version=exudyn.__version__)


# --------------------------------------------------------------------------- parent side
def _save(path, mats: dict, **arrays) -> None:
    """``mats`` (sparse) as ``<k>_data/_indices/_indptr/_shape`` (the layout of bench/krylov.py)."""
    for k, A in mats.items():
        A = A.tocsc()
        arrays.update({k + "_data": A.data, k + "_indices": A.indices, k + "_indptr": A.indptr,
                       k + "_shape": np.array(A.shape)})
    np.savez(path, **arrays)


class _Child:
    """An external run in a child process. The worker limits itself (see :func:`main`): CPU
    time ``RLIMIT_CPU`` (SIGXCPU), wall time ``alarm`` (SIGALRM), and lowers its priority by
    ``nice`` so that the flexmor side, timed in the parent, is not starved by it."""

    def __init__(self, cmd: list, cpu_limit: float, wall_limit: float, nice: int, log: str):
        self.cpu_limit, self.wall_limit = cpu_limit, wall_limit
        self.log = log
        self.t0 = time.perf_counter()
        env = dict(os.environ, TOOLS_CPU_LIMIT=str(int(cpu_limit)), TOOLS_WALL_LIMIT=str(int(wall_limit)),
                   TOOLS_NICE=str(int(nice)))
        with open(log, "w") as fh:
            self.proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)

    def poll(self, block: bool = False):
        """None while running, else (error or None, wall seconds, CPU seconds of the child)."""
        done, status, ru = os.wait4(self.proc.pid, 0 if block else os.WNOHANG)
        if not done:
            return None
        rc = self.proc.returncode = os.waitstatus_to_exitcode(status)
        wall, cpu = time.perf_counter() - self.t0, ru.ru_utime + ru.ru_stime
        if rc in (-signal.SIGXCPU, -signal.SIGKILL) and cpu >= 0.95 * self.cpu_limit:
            return f"did not finish in {self.cpu_limit:.0f} s CPU", wall, cpu
        if rc == -signal.SIGALRM:
            return f"did not finish in {self.wall_limit:.0f} s wall ({cpu:.0f} s CPU)", wall, cpu
        if rc:
            lines = [ln for ln in pathlib.Path(self.log).read_text(errors="replace").splitlines() if ln.strip()]
            return "failed: " + (lines[-1] if lines else f"exit code {rc}"), wall, cpu
        return None, wall, cpu


def _exudyn_layout(model):
    """Node-major permutation of flexmor's DOFs (3 per node) as Exudyn's position nodes need."""
    dofs = np.asarray(model.dofs)
    perm = np.lexsort((dofs[:, 1], dofs[:, 0]))
    nodes = dofs[perm[::3], 0]
    if dofs.shape[0] != 3 * nodes.size or not np.array_equal(dofs[perm, 1], np.tile([1, 2, 3], nodes.size)):
        raise SystemExit("Exudyn needs three translational DOF per node")
    return perm, nodes


def krylov_counts(info: dict, order: int, n_inputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (rad/s, real) of a ``krylov`` basis and the moments per point and input that fill
    ``order`` columns moment by moment over points and inputs (``krylov``'s truncation)."""
    points = np.array([complex(s).real for s in info["points_rad_s"]])
    counts = np.zeros((points.size, n_inputs), dtype=int)
    left = order
    while left > 0:
        for p in range(points.size):
            for i in range(n_inputs):
                if left > 0:
                    counts[p, i] += 1
                    left -= 1
    return points, counts


def judge_external(name: str, out: str, model, ports, full) -> dict:
    """Row of an external run that finished: its times and the band_error of its reduced body."""
    from flexmor.analysis.frequency import band_error
    from flexmor.basis import Basis
    from flexmor.body import ReducedModel
    from flexmor.dynamics.frf import frf_reduced
    from flexmor.projection import project

    d = np.load(out)
    if name.startswith("pymor"):
        red = ReducedModel(M=d["M"], K=d["K"], D=d["D"], B=d["B"], C=d["C"])
        row = {"order": int(d["M"].shape[0]), "seconds": float(d["seconds"]), "cpu_s": float(d["cpu_s"])}
        if name == "pymor-sor-irka":
            row.update(iterations=int(d["iterations"]), last_conv=float(d["conv"][-1]))
    else:
        perm, _ = _exudyn_layout(model)
        V = np.empty_like(d["V"])
        V[perm] = d["V"]
        t1 = time.perf_counter()
        red = project(model, Basis(V, "exudyn-cb"), ports)
        t_proj = time.perf_counter() - t1
        row = {"order": red.order, "seconds": float(d["seconds"]) + t_proj, "cpu_s": float(d["cpu_s"]) + t_proj,
               "modes_s": float(d["seconds"]), "project_s": t_proj}
    row.update(version=str(d["version"]), band_error=band_error(full.freqs, full.H, frf_reduced(red, full.freqs)))
    return row


def _report(size, name, row) -> None:
    msg = (f"{row['seconds']:8.2f} s ({row['cpu_s']:8.2f} s CPU)  band_error {row['band_error']:.2e}"
           if "error" not in row else row["error"])
    print(f"[{size}]   {name:22s} {msg}", flush=True)


def collect_later(size: int, args) -> dict:
    """``--collect``: judge the external outputs left in ``tools_<size>_work`` (runs whose parent
    was stopped) against the same (cached) full FRF and merge them into ``tools_<size>.json``.
    Runs still without output are taken from ``unfinished.json`` in that directory
    (``{name: {"cpu_s", "wall_s"}}``, read off the process table when they were stopped)."""
    from flexmor.analysis.compare import FullResponse
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports

    out_dir = pathlib.Path(args.out_dir)
    res = json.loads((out_dir / f"tools_{size}.json").read_text())
    work = out_dir / f"tools_{size}_work"
    stopped = json.loads((work / "unfinished.json").read_text()) if (work / "unfinished.json").exists() else {}
    model = cantilever(size_for_dofs(size)).with_rayleigh(*args.rayleigh)
    ports = make_ports(model, INPUTS)
    full = FullResponse(model, ports, tuple(args.band))
    rows = res["methods"]
    for name in args.external:
        if name in rows:
            continue
        out = work / f"{name}.npz"
        if out.exists():
            rows[name] = judge_external(name, str(out), model, ports, full)
        elif name in stopped:
            st = stopped[name]
            rows[name] = {"error": f"did not finish in {st['wall_s']:.0f} s wall ({st['cpu_s']:.0f} s CPU); "
                                   "stopped at the deadline of the run", "process_wall_s": st["wall_s"],
                          "process_cpu_s": st["cpu_s"], "did_not_finish": True}
        else:
            continue
        _report(size, name, rows[name])
    res.update(n_freq=int(full.freqs.size), full_frf_path=full.path, table=table_rows(rows), collected_later=True,
               inputs=INPUTS, band_hz=list(args.band), rayleigh=list(args.rayleigh), order=args.order)
    if full.path == "surrogate":
        res["surrogate_check"] = {k: v for k, v in full.grid.get("surrogate", {}).items() if k != "checks"}
    return res


def run_size(size: int, args) -> dict:
    from flexmor.analysis.compare import FullResponse
    from flexmor.models import cantilever, size_for_dofs
    from flexmor.ports import make_ports
    from flexmor.reduction.krylov import default_points
    from flexmor.workflow import reduce_and_judge

    band = tuple(args.band)
    order = args.order
    t0 = time.perf_counter()
    model = cantilever(size_for_dofs(size)).with_rayleigh(*args.rayleigh)
    ports = make_ports(model, INPUTS)
    print(f"[{size}] n_dof {model.n_dof}: model {time.perf_counter() - t0:.1f} s", flush=True)
    rows = {}

    def dump(final=False):  # partial results after every method
        rec = {"size": size, "n_dof": model.n_dof, "complete": final, "methods": rows}
        (pathlib.Path(args.out_dir) / f"tools_{size}.json").write_text(json.dumps(rec, indent=1, default=float))

    work = pathlib.Path(args.out_dir) / f"tools_{size}_work"  # inputs, outputs and logs of the child processes
    work.mkdir(parents=True, exist_ok=True)
    tmp = str(work)
    # the external runs start first and run concurrently (each is timed by its own CPU time)
    children = {}
    if any(e.startswith("pymor") for e in args.external):
        # krylov's default points (three real points over the band); the moments per point
        # and input are those that fill the order moment by moment, as krylov truncates
        points, counts = krylov_counts({"points_rad_s": 2 * np.pi * default_points(band)}, order, ports.n_inputs)
        inp = f"{tmp}/in.npz"
        _save(inp, {"M": model.M, "D": model.D, "K": model.K}, B=ports.B.toarray(), C=ports.C.toarray(),
              r=order, maxit=args.maxit, points=points, counts=counts)
    for name in args.external:
        out = f"{tmp}/{name}.npz"
        if name.startswith("pymor"):
            cmd = [args.pymor_python, __file__, "--pymor-worker", name, inp, out, args.pymor_permc]
        else:
            perm, nodes = _exudyn_layout(model)
            tip = int(model.node_sets["TIP_CENTER"][0])
            inp_x = f"{tmp}/exudyn_in.npz"
            Mx, Kx = model.M.tocsr()[perm][:, perm], model.K.tocsr()[perm][:, perm]
            _save(inp_x, {"M": Mx, "K": Kx}, xyz=model.node_xyz(nodes), n_eig=order - 3,
                  boundary=np.flatnonzero(nodes == tip))
            cmd = [sys.executable, __file__, "--exudyn-worker", inp_x, out]
        children[name] = (_Child(cmd, args.timeout, args.wall_timeout, args.external_nice, f"{tmp}/{name}.log"), out)
    t0 = time.perf_counter()
    full = FullResponse(model, ports, band)
    print(f"[{size}]   full FRF {time.perf_counter() - t0:.1f} s ({full.freqs.size} frequencies, "
          f"path {full.path})", flush=True)

    def collect(block: bool):
        for name, (child, out) in list(children.items()):
            got = child.poll(block)
            if got is None:
                continue
            del children[name]
            err, wall, cpu = got
            if err is None:
                rows[name] = judge_external(name, out, model, ports, full)
                rows[name].update(process_wall_s=wall, process_cpu_s=cpu)
            else:
                rows[name] = {"error": err, "process_wall_s": wall, "process_cpu_s": cpu,
                              "did_not_finish": err.startswith("did not")}
            _report(size, name, rows[name])
            dump()

    opts = {"craig-bampton": {"interface": ["TIP_CENTER"]}, "irka": {"max_iter": args.maxit},
            "sobt": {"cutoff": args.sobt_cutoff}}
    for method in args.flexmor:
        c0 = time.process_time()
        red, res = reduce_and_judge(model, method, order, ports, full=full, band=band, **opts.get(method, {}))
        rows[method] = {"order": red.order, "seconds": res["seconds"], "band_error": res["band_error"],
                        "cpu_s": time.process_time() - c0}
        if method == "irka":
            rows[method].update(iterations=red.info["iterations"], converged=red.info["converged"])
        if method == "krylov":
            rows[method]["points_rad_s"] = red.info["points_rad_s"]
        print(f"[{size}]   flexmor {method:14s} r={red.order:3d} {res['seconds']:8.2f} s "
              f"({rows[method]['cpu_s']:8.2f} s CPU)  band_error {res['band_error']:.2e}", flush=True)
        dump()
        collect(block=False)
    collect(block=True)
    for f in ("in.npz", "exudyn_in.npz"):
        (work / f).unlink(missing_ok=True)
    return {"size": size, "n_dof": model.n_dof, "nnz_K": int(model.K.nnz), "inputs": INPUTS, "band_hz": list(band),
            "rayleigh": list(args.rayleigh), "order": order, "n_freq": int(full.freqs.size),
            "full_frf_s": full.seconds, "full_frf_path": full.path, "cpu_limit_s": args.timeout,
            "wall_limit_s": args.wall_timeout, "external_nice": args.external_nice, "pymor_permc": args.pymor_permc,
            "krylov_points_rad_s": points.tolist() if any(e.startswith("pymor") for e in args.external) else None,
            "methods": rows, "table": table_rows(rows)}


def table_rows(rows: dict) -> list:
    """One row per pair: flexmor method, its CPU s, wall s, band_error; the external method,
    its CPU s, wall s (None when it did not finish), CPU-time ratio external/flexmor (a lower
    bound when it did not finish), wall ratio, band_error, note."""
    out = []
    for fm, ext in PAIRS.items():
        if fm not in rows or ext not in rows:
            continue
        a, b = rows[fm], rows[ext]
        if "error" in b:
            lb = b["process_cpu_s"] / a["cpu_s"] if b.get("did_not_finish") else None
            out.append([fm, a["cpu_s"], a["seconds"], a["band_error"], ext, None, None, lb, None, None, b["error"]])
        else:
            out.append([fm, a["cpu_s"], a["seconds"], a["band_error"], ext, b["cpu_s"], b["seconds"],
                        b["cpu_s"] / a["cpu_s"], b["seconds"] / a["seconds"], b["band_error"], ""])
    return out


def print_table(res: dict) -> None:
    print(f"n_dof {res['n_dof']}, order {res['order']}, {len(INPUTS)} inputs, band {res['band_hz']} Hz; "
          "CPU s (wall s)")
    print(f"{'flexmor':14s} {'CPU s (wall)':>17s} {'band_error':>10s}   {'external':22s} {'CPU s (wall)':>17s} "
          f"{'ratio CPU':>9s} {'(wall)':>7s} {'band_error':>10s}")
    for fm, fc, fw, fe, ext, ec, ew, rc, rw, ee, note in res["table"]:
        if ec is None:
            ext_ = f"{'-':>17s} {('>' + format(rc, '.1f')) if rc else '-':>9s} {'':>7s} {note}"
        else:
            ext_ = f"{ec:8.1f} ({ew:6.1f}) {rc:9.1f} ({rw:5.1f}) {ee:10.2e}"
        print(f"{fm:14s} {fc:8.2f} ({fw:6.2f}) {fe:10.2e}   {ext:22s} {ext_}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="30000,100000", help="comma-separated target DOF counts")
    ap.add_argument("--order", type=int, default=24)
    ap.add_argument("--band", type=float, nargs=2, default=(1.0, 3000.0), metavar=("FMIN", "FMAX"))
    ap.add_argument("--rayleigh", type=float, nargs=2, default=(10.0, 1e-6), metavar=("ALPHA", "BETA"))
    ap.add_argument("--maxit", type=int, default=50, help="IRKA iterations (flexmor and pyMOR)")
    ap.add_argument("--flexmor", default="krylov,irka,sobt,fw-sobt,craig-bampton")
    ap.add_argument("--external", default=",".join(EXTERNAL))
    ap.add_argument("--timeout", type=float, default=1200.0, help="CPU-time limit of each external run (s)")
    ap.add_argument("--wall-timeout", type=float, default=5400.0, help="wall-time limit of each external run (s)")
    ap.add_argument("--external-nice", type=int, default=10, help="niceness added to the external runs")
    ap.add_argument("--sobt-cutoff", type=float, help="flexmor sobt's cutoff (Hz; default its own, 10 fmax)")
    ap.add_argument("--pymor-python", help="a Python interpreter with pyMOR installed")
    ap.add_argument("--pymor-permc", default="MMD_AT_PLUS_A", help="SuperLU column ordering for pyMOR's solves")
    ap.add_argument("--out-dir", default=str(HERE / "results"))
    ap.add_argument("--collect", action="store_true",
                    help="judge the outputs left in tools_<size>_work by runs whose parent was stopped")
    ap.add_argument("--pymor-worker", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--exudyn-worker", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if (args.pymor_worker or args.exudyn_worker) and os.environ.get("TOOLS_CPU_LIMIT"):
        import resource

        limit = int(os.environ["TOOLS_CPU_LIMIT"])
        resource.setrlimit(resource.RLIMIT_CPU, (limit, limit + 10))  # SIGXCPU, then SIGKILL
        signal.alarm(int(os.environ["TOOLS_WALL_LIMIT"]))  # SIGALRM ends the process
        os.nice(int(os.environ["TOOLS_NICE"]))
    if args.pymor_worker:
        _pymor_run(*args.pymor_worker)
        return 0
    if args.exudyn_worker:
        _exudyn_run(*args.exudyn_worker)
        return 0
    args.flexmor = [m for m in args.flexmor.split(",") if m]
    args.external = [m for m in args.external.split(",") if m]
    bad = [m for m in args.external if m not in EXTERNAL]
    if bad:
        ap.error(f"unknown external method(s) {bad}; choose from {', '.join(EXTERNAL)}")
    if any(m.startswith("pymor") for m in args.external):
        if not args.pymor_python:
            ap.error("pyMOR methods need --pymor-python (an interpreter with pyMOR installed), "
                     "or leave them out with --external exudyn-cb")
        proc = subprocess.run([args.pymor_python, "-c", "import pymor; print(pymor.__version__)"], capture_output=True,
                              text=True, check=False)
        if proc.returncode:
            ap.error(f"{args.pymor_python} cannot import pymor: {proc.stderr.strip().splitlines()[-1:]}")
        pymor_version = proc.stdout.strip()
    else:
        pymor_version = None
    if "exudyn-cb" in args.external:
        try:
            import exudyn  # noqa: F401
        except ImportError:
            ap.error("exudyn-cb needs Exudyn in this interpreter (pip install 'flexmor[exudyn]')")
    import scipy

    meta = {"python": sys.version.split()[0], "machine": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(), "numpy": np.__version__, "scipy": scipy.__version__, "pymor": pymor_version,
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}}
    out_dir = pathlib.Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if args.collect:
        for size in (int(s) for s in args.sizes.split(",")):
            res = collect_later(size, args)
            (out_dir / f"tools_{size}.json").write_text(json.dumps(res, indent=1, default=float))
            print_table(res)
        return 0
    for size in (int(s) for s in args.sizes.split(",")):
        load0 = os.getloadavg()
        res = run_size(size, args)
        res.update(meta, loadavg_start=load0, loadavg_end=os.getloadavg(), complete=True)
        (out_dir / f"tools_{size}.json").write_text(json.dumps(res, indent=1, default=float))
        print_table(res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
