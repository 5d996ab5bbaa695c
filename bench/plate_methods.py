#!/usr/bin/env python
"""Gramian and POD methods on the plate structure (issue 21), side by side with pyMOR.

    nice -n 5 .venv/bin/python bench/plate_methods.py --pymor-python /tmp/pymor-venv/bin/python --start-pymor
    nice -n 5 .venv/bin/python bench/plate_methods.py                        # 35,988 DOF, orders 20 and 30
    .venv/bin/python bench/plate_methods.py --dofs 300000 --methods fw-sobt,pod --orders 30 --no-frf

Model: the structure of ``examples/plate_structure_table.py`` (:func:`flexmor.models.plate_structure`,
``n=56``: 35,988 DOF; ``--dofs`` picks the resolution of about that many DOF), Rayleigh damping
ratio 1 % at the band ends, the six ports of an RBE3 at the hole (``HOLE@rbe3:x ... rz``) as
collocated inputs and outputs, band ``--band`` (default 1-2000 Hz, 24 resonances).

flexmor's ``fw-sobt``, ``sobt``, ``pod`` and ``two-step`` (default options, ``band`` given) of every
order in ``--orders`` run one after the other in this process: wall and CPU seconds of the basis
and the projection, band_error on one full FRF (:class:`flexmor.analysis.compare.FullResponse`,
disk cache; ``--no-frf`` skips it). pyMOR (``--pymor-python``, an interpreter with pyMOR) runs
``SOBTpReductor`` (its Gramians once, then every order) and ``SORIRKAReductor`` (per order,
``maxit=50``, ``tol=1e-4``) on the same matrices in detached child processes started by
``--start-pymor`` (at ``nice -n 15``, CPU limit ``--timeout``, wall limit ``--wall-timeout``), so
they overlap other work; each child's monitor writes ``<name>.status.json`` (exit, wall and CPU
seconds, load averages). A later run judges the pyMOR bodies that are there and reports the others
as not finished (with the CPU time they got). Results: ``bench/results/plate_methods_<n_dof>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import resource
import signal
import subprocess
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
INTERFACE = [f"HOLE@rbe3:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")]
METHODS = ("fw-sobt", "sobt", "pod", "two-step")
PYMOR = ("pymor-sobtp", "pymor-sor-irka")


def resolution(dofs: int) -> int:
    """``plate_structure``'s resolution ``n`` of about ``dofs`` DOF: ~n^2.3 (10,728 DOF at n=28, 35,988 at
    56, 93,348 at 84, 180,204 at 112; ``--dofs 300000`` gives n=141)."""
    return 56 if dofs is None else max(8, round(56 * (dofs / 35988.0) ** (1 / 2.3)))


def build(n: int, band):
    from flexmor.damping import band_matched
    from flexmor.models import plate_structure
    from flexmor.ports import make_ports

    model = plate_structure(n).with_damping(band_matched(0.01, band))
    return model, make_ports(model, INTERFACE)


# --------------------------------------------------------------------------- pyMOR side (its interpreter)
def _load_sparse(d, k):
    import scipy.sparse as sp

    return sp.csc_matrix((d[k + "_data"], d[k + "_indices"], d[k + "_indptr"]), shape=tuple(d[k + "_shape"]))


def _dense(op):
    from pymor.algorithms.to_matrix import to_matrix

    return np.asarray(to_matrix(op, format="dense"))


def pymor_worker(name: str, inp: str, out: str) -> None:
    """One pyMOR reductor on the matrices of ``inp``; every order's body goes to ``out`` (``r<order>_*``)."""
    import logging

    import pymor
    from pymor.models.iosys import SecondOrderModel

    logging.getLogger("pymor").setLevel(logging.ERROR)
    d = np.load(inp)
    fom = SecondOrderModel.from_matrices(*(_load_sparse(d, k) for k in ("M", "D", "K")), d["B"], d["C"])
    res = {"version": pymor.__version__}
    for r in (int(v) for v in d["orders"]):
        t0, c0 = time.perf_counter(), time.process_time()
        if name == "pymor-sobtp":
            from pymor.reductors.sobt import SOBTpReductor

            rom = SOBTpReductor(fom).reduce(r)  # the Gramians are cached on fom: the first order pays for them
        else:
            from pymor.reductors.sor_irka import SORIRKAReductor

            red = SORIRKAReductor(fom)
            rom = red.reduce(r, maxit=50, tol=1e-4)
            res[f"r{r}_iterations"] = len(red.conv_crit)
        res.update({f"r{r}_{k}": _dense(getattr(rom, a)) for k, a in
                    (("M", "M"), ("D", "E"), ("K", "K"), ("B", "B"), ("C", "Cp"))})
        res[f"r{r}_seconds"], res[f"r{r}_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
        np.savez(out, **res)  # after every order: a stopped run keeps what it finished


def _monitor(cmd: list, status: str, cpu_limit: float, wall_limit: float, nice: int) -> None:
    """Run the worker ``cmd`` (it sets its own niceness and CPU limit from the environment), stop it at the
    wall limit, then write its exit, wall and CPU seconds to ``status``."""
    t0, load0 = time.time(), os.getloadavg()
    env = dict(os.environ, PLATE_CPU_LIMIT=str(int(cpu_limit)), PLATE_NICE=str(int(nice)))
    with open(status + ".log", "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
        rec = {"pid": proc.pid, "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(t0)), "nice": nice,
               "cpu_limit_s": cpu_limit, "wall_limit_s": wall_limit, "load_start": load0, "running": True}
        pathlib.Path(status).write_text(json.dumps(rec))
        signal.signal(signal.SIGALRM, lambda *_: proc.kill())
        signal.alarm(int(wall_limit))
        _, st, ru = os.wait4(proc.pid, 0)
    rc = os.waitstatus_to_exitcode(st)
    cpu, wall = ru.ru_utime + ru.ru_stime, time.time() - t0
    rec.update(running=False, exit=rc, wall_s=wall, cpu_s=cpu, load_end=os.getloadavg(),
               finished=rc == 0, note="" if rc == 0 else
               (f"did not finish in {cpu_limit:.0f} s CPU" if cpu >= 0.95 * cpu_limit else
                f"did not finish in {wall_limit:.0f} s wall ({cpu:.0f} s CPU)" if wall >= 0.99 * wall_limit else
                f"failed (exit {rc}, see {status}.log)"))
    pathlib.Path(status).write_text(json.dumps(rec))


# --------------------------------------------------------------------------- flexmor side
def start_pymor(model, ports, work: pathlib.Path, args) -> None:
    """Save the matrices and start one detached monitor + worker per pyMOR reductor."""
    inp = work / "in.npz"
    arrays = {"B": ports.B.toarray(), "C": ports.C.toarray(), "orders": np.array(args.orders)}
    for k in ("M", "D", "K"):
        A = getattr(model, k).tocsc()
        arrays.update({k + "_data": A.data, k + "_indices": A.indices, k + "_indptr": A.indptr,
                       k + "_shape": np.array(A.shape)})
    np.savez(inp, **arrays)
    for name in PYMOR:
        worker = [args.pymor_python, __file__, "--pymor-worker", name, str(inp), str(work / f"{name}.npz")]
        cmd = [sys.executable, __file__, "--monitor", str(work / f"{name}.status.json"), str(args.timeout),
               str(args.wall_timeout), str(args.nice), "--", *worker]
        subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        print(f"started {name} (nice {args.nice}, {args.timeout:.0f} s CPU limit)", flush=True)


def _cpu_of(pid: int) -> float | None:
    """CPU seconds a running process has had so far (None if it is gone)."""
    try:
        f = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def pymor_rows(work: pathlib.Path, orders, model, full) -> dict:
    """The pyMOR rows: band_error of every body that is there, else the state of the run."""
    from flexmor.analysis.frequency import band_error
    from flexmor.body import ReducedModel
    from flexmor.dynamics.frf import frf_reduced

    rows = {}
    for name in PYMOR:
        st_path = work / f"{name}.status.json"
        if not st_path.exists():
            continue
        st = json.loads(st_path.read_text())
        out = work / f"{name}.npz"
        d = dict(np.load(out)) if out.exists() else {}
        for r in orders:
            row = {"nice": st["nice"], "load_start": st["load_start"]}
            if f"r{r}_M" in d:
                red = ReducedModel(M=d[f"r{r}_M"], K=d[f"r{r}_K"], D=d[f"r{r}_D"], B=d[f"r{r}_B"], C=d[f"r{r}_C"])
                row.update(order=int(d[f"r{r}_M"].shape[0]), seconds=float(d[f"r{r}_seconds"]),
                           cpu_s=float(d[f"r{r}_cpu_s"]), version=str(d["version"]))
                if f"r{r}_iterations" in d:
                    row["iterations"] = int(d[f"r{r}_iterations"])
                if full is not None:
                    row["band_error"] = float(band_error(full.freqs, full.H, frf_reduced(red, full.freqs)))
            elif st["running"]:
                row.update(note="running", cpu_s_so_far=_cpu_of(st["pid"]), started=st["started"])
            else:
                row.update(note=st["note"], process_cpu_s=st["cpu_s"], process_wall_s=st["wall_s"],
                           load_end=st["load_end"])
            rows[f"{name} {r}"] = row
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dofs", type=int, help="model size (DOF, approximate); default the 35,988-DOF structure")
    ap.add_argument("--band", default="1:2000")
    ap.add_argument("--orders", default="20,30")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--no-frf", action="store_true", help="no full FRF (no band_error): times only")
    ap.add_argument("--label", default="", help="a name for this run in the results file (e.g. 'before')")
    ap.add_argument("--pymor-python", default="/tmp/pymor-venv/bin/python")
    ap.add_argument("--start-pymor", action="store_true", help="start the pyMOR runs in the background and return")
    ap.add_argument("--timeout", type=float, default=1200.0, help="CPU limit of each pyMOR run (s)")
    ap.add_argument("--wall-timeout", type=float, default=7200.0, help="wall limit of each pyMOR run (s)")
    ap.add_argument("--nice", type=int, default=15, help="niceness of the pyMOR runs")
    ap.add_argument("--pymor-worker", nargs=3, help=argparse.SUPPRESS)
    ap.add_argument("--monitor", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("cmd", nargs="*", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.pymor_worker:
        if os.environ.get("PLATE_CPU_LIMIT"):  # started by --monitor: SIGXCPU at the limit
            os.nice(int(os.environ["PLATE_NICE"]))
            limit = int(os.environ["PLATE_CPU_LIMIT"])
            resource.setrlimit(resource.RLIMIT_CPU, (limit, limit + 10))
        pymor_worker(*args.pymor_worker)
        return 0
    if args.monitor:
        _monitor(args.cmd, args.monitor[0], float(args.monitor[1]), float(args.monitor[2]), int(args.monitor[3]))
        return 0
    from flexmor.reduction import reduce

    band = tuple(float(v) for v in args.band.split(":"))
    args.orders = [int(v) for v in args.orders.split(",")]
    n = resolution(args.dofs)
    t0 = time.perf_counter()
    model, ports = build(n, band)
    print(f"plate_structure({n}): {model.n_dof} DOF, {time.perf_counter() - t0:.1f} s", flush=True)
    work = HERE / "results" / f"plate_methods_{model.n_dof}_work"
    work.mkdir(parents=True, exist_ok=True)
    if args.start_pymor:
        start_pymor(model, ports, work, args)
        return 0
    full = None
    if not args.no_frf:
        from flexmor.analysis.compare import FullResponse

        full = FullResponse(model, ports, band, cache=True)
        print(f"full FRF {full.seconds:.1f} s, {full.freqs.size} frequencies", flush=True)
    path = HERE / "results" / f"plate_methods_{model.n_dof}{'_' + args.label if args.label else ''}.json"
    rec = {"n": n, "n_dof": model.n_dof, "band_hz": band, "label": args.label, "python": platform.python_version(),
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load_start": os.getloadavg(),
           "threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
           "flexmor": {}}
    for method in [m for m in args.methods.split(",") if m]:
        for r in args.orders:
            c0, w0 = time.process_time(), time.perf_counter()
            red = reduce(model, method, r, ports, band=band)
            t = red.info["timings"]
            row = {"order": red.order, "seconds": t["basis"] + t["project"], "wall_s": time.perf_counter() - w0,
                   "cpu_s": time.process_time() - c0, "load": os.getloadavg()[0]}
            sinfo = red.info.get("solves")
            if isinstance(sinfo, dict):
                row["solves"] = {k: v for k, v in sinfo.items() if k != "checks"}
            if full is not None:
                row["band_error"] = float(full.evaluate(red).band_error)
            rec["flexmor"][f"{method} {r}"] = row
            print(f"{method:9s} {red.order:3d}  {row['seconds']:8.1f} s  CPU {row['cpu_s']:8.1f} s  "
                  f"band_error {row.get('band_error', float('nan')):.3e}  load {row['load']:.1f}", flush=True)
            path.write_text(json.dumps(rec, indent=1, default=float))
    rec["pymor"] = pymor_rows(work, args.orders, model, full)
    for k, row in rec["pymor"].items():
        print(f"{k:22s} " + ", ".join(f"{a}={b}" for a, b in row.items()), flush=True)
    rec["load_end"] = os.getloadavg()
    path.write_text(json.dumps(rec, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
