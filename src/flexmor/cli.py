"""The ``flexmor`` command line. The only module that prints or exits.

Exit codes: 0 success, 2 bad input (a one-line ``flexmor: error: ...`` on stderr naming the
file and line where there is one), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM). Output
files are written atomically (:func:`flexmor.io.atomic_write`), so an interrupted run leaves
neither a partial nor a temporary file; an existing output file is only replaced with ``--force``.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import time
from pathlib import Path

import numpy as np

from . import __version__
from .errors import ConvergenceError, FlexmorError, ModelError, PortError, SolverError
from .jsonutil import jsonable
from .linalg.distributed import is_partitioned, on_root, quiet_other_ranks, row_blocks

__all__ = ["main"]


def _emit_json(obj) -> None:
    if isinstance(obj, dict):  # every JSON answer says which flexmor wrote it
        obj = {**obj, "flexmor_version": __version__}
    print(json.dumps(jsonable(obj, finite=True)))


def _progress(args, desc: str, unit: str = "freq"):
    """A ``progress(iterable, total)`` wrapper: tqdm on a terminal, nothing under --json."""
    if getattr(args, "json", False) or not sys.stderr.isatty():
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return lambda it, total: tqdm(it, total=total, desc=desc, unit=unit, leave=False)


class _Terminated(BaseException):
    """Raised by the SIGTERM handler so that the run unwinds (and removes temporary files)."""


def _on_sigterm(signum, frame):
    raise _Terminated


def _check_new(path, args) -> Path:
    """``path`` as a Path; an OptionError if it exists and ``--force`` was not given."""
    from .errors import OptionError

    path = Path(path)
    if path.is_dir():
        raise OptionError(f"{path} is a directory; give a file name with -o")
    if path.exists() and not getattr(args, "force", False):
        raise OptionError(f"{path} exists; pass --force to overwrite it")
    return path


def _solver(args):
    """The solver context of one command: the backend of ``--backend``."""
    from .linalg.context import SolverContext

    return SolverContext(backend=args.backend)


def _fmt(x, spec=".3e"):
    return "-" if x is None else format(x, spec)


def _read_model(args, couplings=()):
    from .io import read
    from .workflow import apply_damping, parse_band, parse_pair, prepare_model

    def load():
        model = read(args.model, format=args.format)
        if getattr(args, "select", None):
            from .selection import with_selections

            model = with_selections(model, args.select)
        return prepare_model(model, couplings)

    t0 = time.perf_counter()
    if getattr(args, "backend", None) == "petsc":  # under mpirun: rank 0 reads, each rank gets its rows
        from .models.distributed import read_on_root

        model = read_on_root(load)
    else:
        model = load()
    t_read = time.perf_counter() - t0
    band = parse_band(args.band) if getattr(args, "band", None) else None
    rayleigh = parse_pair(args.rayleigh, "--rayleigh") if getattr(args, "rayleigh", None) else None
    model = apply_damping(model, rayleigh=rayleigh, modal_damping=getattr(args, "modal_damping", None), band=band)
    return model, t_read, band


# -- info --------------------------------------------------------------------------------------
def _info_backends(args) -> int:
    from .linalg.backends import describe_backends, memory_available

    rows = describe_backends()
    avail = memory_available()
    if args.json:
        print(json.dumps({"backends": rows, "memory_available_mb": None if avail is None else avail / 2**20}))
        return 0
    for r in rows:
        flags = ("available" if r["available"] else "not installed") + (", complex" if r["complex"] else "") + \
            (", SPD only" if r["positive_only"] else "")
        print(f"{r['name']:<8} {flags:<32} {r['description']}")
    if avail is not None:
        print(f"memory available: {avail / 2**20:.0f} MB (factorizations that would not fit are refused)")
    return 0


_FORMAT_TITLES = {"model": "FE models (info, reduce, compare, report MODEL; --format NAME)",
                  "body": "reduced bodies (compare, report, export BODY)",
                  "export": "exports (export BODY -o FILE; --format NAME)"}


def _info_formats(args) -> int:
    from .io import describe_formats

    table = describe_formats()
    if args.json:
        _emit_json({"formats": table})
        return 0
    lines = {kind: [(r["name"] + (f" ({', '.join(r['aliases'])})" if r["aliases"] else ""),
                     " ".join(r["suffixes"] + ([r["claims"]] if r["claims"] else [])), r["description"])
                    for r in rows] for kind, rows in table.items()}
    w0, w1 = (max(len(line[i]) for rows in lines.values() for line in rows) for i in (0, 1))
    for kind, rows in lines.items():
        print(("\n" if kind != "model" else "") + _FORMAT_TITLES[kind])
        for name, suffixes, description in rows:
            print(f"  {name:<{w0}}  {suffixes:<{w1}}  {description}")
    return 0


def cmd_info(args) -> int:
    from .checks import MAX_RIGID_BODY_MODES, mechanism_error
    from .linalg import available_backends
    from .linalg.eigen import eigenmodes, frequencies_hz, is_rigid

    if args.backends:
        return _info_backends(args)
    if args.formats:
        return _info_formats(args)
    if args.model is None:
        from .errors import OptionError

        raise OptionError("info needs a MODEL file (or --backends, --formats)")
    model, t_read, _ = _read_model(args)
    out = model.summary()
    out["backends"] = available_backends()
    solver = _solver(args)
    if args.modes:
        k = min(args.modes, model.n_dof)
        lam, _ = eigenmodes(model.K, model.M, min(max(k, 7), model.n_dof), solver=solver)
        n_zero = int(np.sum(is_rigid(lam, model.K, model.M)))
        if n_zero > MAX_RIGID_BODY_MODES:
            raise mechanism_error(model, n_zero)
        lam = lam[:k]
        out["frequencies_hz"] = frequencies_hz(lam).tolist()
        out["n_rigid"] = min(n_zero, k)
    if args.reference:
        from .io.calculix import compare_modes, read_frd

        out["reference"] = dict(compare_modes(model, read_frd(args.reference), solver=solver),
                                file=str(args.reference))
    out["timings"] = {"read": t_read}
    if args.json:
        _emit_json(out)
        return 0
    print(f"model     {model.name}  ({model.source})")
    print(f"DOF       {model.n_dof}    nodes {model.n_nodes}    nnz(K) {out['nnz_K']}")
    print(f"damping   {model.damping}")
    if model.node_sets:
        print("node sets " + ", ".join(f"{k} ({v.size})" for k, v in model.node_sets.items()))
    print(f"backends  {', '.join(out['backends'])}")
    if args.modes:
        print(f"\n mode   frequency [Hz]   ({out['n_rigid']} rigid-body modes)")
        for i, f in enumerate(out["frequencies_hz"], 1):
            tag = "  rigid" if i <= out["n_rigid"] else ""
            print(f"{i:5d}   {f:14.6f}{tag}")
    if args.reference:
        ref = out["reference"]
        print(f"\n mode   {args.reference} [Hz]   model [Hz]   rel. diff   MAC")
        for i, row in enumerate(zip(ref["frequencies_hz"], ref["model_frequencies_hz"], ref["rel_diff"], ref["mac"]), 1):
            print(f"{i:5d}   {row[0]:14.6f}   {row[1]:14.6f}   {row[2]:9.2e}   {row[3]:.6f}")
    return 0


# -- reduce ------------------------------------------------------------------------------------
def cmd_reduce(args) -> int:
    from .io.hdf5 import write_reduced
    from .ports import make_ports
    from .workflow import DEFAULT_BAND, coupling_specs, reduce_and_judge

    if args.output_file:
        _check_new(args.output_file, args)
    couplings = coupling_specs(args.interface, args.input + args.output)
    model, t_read, given_band = _read_model(args, couplings)
    ports = make_ports(model, args.input, args.output)
    band = None if args.no_error else (given_band or DEFAULT_BAND)
    red, res = reduce_and_judge(model, args.method, args.order, ports, band=band, method_band=given_band,
                                n_freq=args.n_freq, grid_tol=args.grid_tol, full_frf=args.full_frf,
                                cache=not args.no_cache, solver=_solver(args), progress=_progress(args, "full FRF"),
                                interface=args.interface or None, tol=args.tol, points=args.points,
                                moments=args.moments, side=args.side, rigid=args.rigid, max_iter=args.max_iter,
                                shift_tol=args.shift_tol, intermediate=args.intermediate, variant=args.variant,
                                energy=args.energy, snapshots=args.snapshots, gramian=args.gramian,
                                directions=args.directions, nodes=args.nodes)
    res["timings"]["read"] = t_read
    if is_partitioned(model.K):  # under mpirun with --backend petsc: the rows of K held by each rank
        res["partition"] = row_blocks(model.K)
    if couplings:
        red.info["couplings"] = couplings
    if args.select:
        red.info["selections"] = list(args.select)
    path = _check_new(args.output_file or f"{model.name}_{args.method}_{red.order}.h5", args)
    on_root(write_reduced, red, path)  # under MPI: written once, by rank 0
    res["file"] = str(path)
    if args.json:
        _emit_json(res)
        return 0
    print(f"{args.method}: order {red.order}, {res['seconds']:.3f} s (basis + projection)")
    if res.get("tol") is not None:
        print(f"--tol {res['tol']:g}: order {red.order} chosen, verified band_error {_fmt(res['band_error'])} "
              + ("meets it" if res["tol_reached"] else "MISSES it (largest order tried)"))
    if res["band_hz"]:
        print(f"band {res['band_hz'][0]:g}-{res['band_hz'][1]:g} Hz: band_error {_fmt(res['band_error'])}, "
              f"max_rel_error {_fmt(res['max_rel_error'])}")
    fr = res["frequencies_hz"]
    print("reduced frequencies [Hz]: " + " ".join(f"{f:.4g}" for f in fr[:12]) + (" ..." if len(fr) > 12 else ""))
    print(f"written {path}")
    return 0


# -- compare -----------------------------------------------------------------------------------
def _model_and_bodies(args):
    """The full model (as read), the band (default DEFAULT_BAND) and the reduced bodies of ``args``."""
    from .io import read_body
    from .workflow import DEFAULT_BAND

    model, t_read, band = _read_model(args)
    return model, t_read, band or DEFAULT_BAND, [read_body(p) for p in args.reduced]


def cmd_compare(args) -> int:
    from .ports import make_ports
    from .workflow import prepare_model

    model, t_read, band, reds = _model_and_bodies(args)
    solver = _solver(args)
    fulls, rows = {}, []
    for path, red in zip(args.reduced, reds):
        couplings = tuple(red.info.get("couplings", ()))
        key = (tuple(red.input_names), tuple(red.output_names), couplings)
        if key not in fulls:
            body_model = prepare_model(model, couplings, red.damping)
            fulls[key] = _full_response(args, body_model, make_ports(body_model, *key[:2]), band, solver)
        t0 = time.perf_counter()
        err = fulls[key].evaluate(red)
        t_err = time.perf_counter() - t0
        rows.append({"file": str(path), "method": red.method, "order": red.order, "band_hz": list(band),
                     "band_error": err["band_error"], "max_rel_error": err["max_rel_error"],
                     "hinf_error": err["hinf_error"],
                     "timings": {"error": t_err}})
    if args.json:
        grids = [dict(f.summary(), inputs=list(k[0]), outputs=list(k[1]), couplings=list(k[2]))
                 for k, f in fulls.items()]
        _emit_json({"model": model.name, "band_hz": list(band), "results": rows, "grids": grids,
                    "timings": {"read": t_read, "full_frf": sum(f.seconds for f in fulls.values())}})
        return 0
    _table(rows)
    return 0


def _full_response(args, model, ports, band, solver):
    """The full FRF over ``band`` with the sweep options of the command line."""
    from .analysis.compare import FullResponse

    grid_opts = {} if args.grid_tol is None else {"tol": args.grid_tol}
    return FullResponse(model, ports, band, n=args.n_freq, solver=solver, path=args.full_frf,
                        cache=not args.no_cache, progress=_progress(args, "full FRF"), **grid_opts)


def _table(rows) -> None:
    print(f"{'method':<16}{'order':>6}{'band_error':>13}{'max_rel_error':>15}{'seconds':>10}")
    for r in rows:
        print(f"{r['method']:<16}{r['order']:>6}{_fmt(r['band_error']):>13}{_fmt(r['max_rel_error']):>15}"
              f"{_fmt(r.get('seconds'), '.3f'):>10}")


# -- export ------------------------------------------------------------------------------------
def cmd_export(args) -> int:
    from .io import export, export_format, read, read_body
    from .workflow import prepare_model

    _check_new(args.output_file, args)
    red = read_body(args.reduced)
    fmt = export_format(args.output_file, args.format)
    model = read(args.model, format=args.model_format) if args.model else None
    if model is not None:
        model = prepare_model(model, red.info.get("couplings", ()))
    opts = {"nodes": args.node or None} if fmt in ("sid", "mat") else {}
    if fmt == "sid":
        opts["m1_order"] = args.m1_order
    export(red, args.output_file, fmt, model=model, **opts)
    out = {"file": str(args.output_file), "format": fmt, "order": red.order, "method": red.method}
    if args.json:
        _emit_json(out)
    else:
        print(f"exported {args.reduced} ({red.method}, order {red.order}) as {fmt}: {args.output_file}")
    return 0


# -- report ------------------------------------------------------------------------------------
def cmd_report(args) -> int:
    from .errors import OptionError
    from .ports import make_ports
    from .report.html import build_report, write_report
    from .workflow import prepare_model

    _check_new(args.output_file, args)
    model, t_read, band, reds = _model_and_bodies(args)

    def key_of(r):
        return list(r.input_names), list(r.output_names), list(r.info.get("couplings", []))

    key = key_of(reds[0])
    other = [str(p) for p, r in zip(args.reduced, reds) if key_of(r) != key]
    if other:
        raise OptionError(f"a report needs bodies with the same inputs/outputs/couplings as {args.reduced[0]}; "
                          f"these differ: {', '.join(other)}")
    model = prepare_model(model, key[2], reds[0].damping)
    ports = make_ports(model, *key[:2])
    solver = _solver(args)
    full = _full_response(args, model, ports, band, solver)
    rep = build_report(model, ports, reds, band=band, full=full, signal=args.signal, dt=args.dt, t_end=args.t_end,
                       scheme=args.scheme, n_modes=args.modes, solver=solver,
                       time_progress=_progress(args, "time steps", unit="step"))
    write_report(rep, _check_new(args.output_file, args))
    if args.json:
        _emit_json({"file": str(args.output_file), "model": model.name, "band_hz": list(band), "results": rep.rows,
                    "time": rep.time, "notes": rep.notes, "timings": {"read": t_read, "full_frf": full.seconds}})
        return 0
    print(f"{'body':<22}{'band_error':>13}{'max_rel_error':>15}{'time_max_error':>16}")
    for r in rep.rows:
        print(f"{r['label']:<22}{_fmt(r['band_error']):>13}{_fmt(r['max_rel_error']):>15}"
              f"{_fmt(r['time_max_error']):>16}")
    print(f"written {args.output_file}")
    return 0


# -- demo --------------------------------------------------------------------------------------
def cmd_demo(args) -> int:
    from .workflow import run_demo

    if not args.json:
        print("flexmor demo: built-in steel cantilever 1 x 0.1 x 0.1 m, clamped at x = 0")
    res = run_demo(args.out, n=args.n, progress=_progress(args, "full FRF"),
                   time_progress=_progress(args, "time steps", unit="step"),
                   on_result=None if args.json else (lambda r: print(f"  reduced {r['method']} r={r['order']}")))
    if args.json:
        _emit_json(res)
        return 0
    m = res["model"]
    print(f"model {m['name']}: {m['n_dof']} DOF; band {res['band_hz'][0]:g}-{res['band_hz'][1]:g} Hz, "
          f"{res['n_freq']} frequencies, full FRF {res['full_frf_seconds']:.2f} s"
          + (" (from cache)" if res["grid"].get("cache_hit") else "") + "\n")
    _table(res["results"])
    print(f"\nreduced bodies and {res['plot']} written to {args.out}/")
    if res.get("report"):
        print(f"report: {res['report']}")
    return 0


# -- parser ------------------------------------------------------------------------------------
def _add_model_args(p, damping=True):
    p.add_argument("model", help="main file of the FE export (format from the suffix)")
    p.add_argument("--format", help="override the format chosen from the suffix")
    p.add_argument("--backend", default="auto",
                   help="sparse solver: auto, pardiso, cholmod, scipy, petsc (MPI: mpirun -n P flexmor ...)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--select", action="append", default=[], metavar="NAME=KIND:NUMBERS",
                   help="add node set NAME: set:OTHER, box:x0,y0,z0,x1,y1,z1, plane:x0,y0,z0,nx,ny,nz[,tol], "
                        "cylinder:x0,y0,z0,dx,dy,dz,r[,tol[,s0,s1]] (a hole), sphere:x,y,z,r[,tol], nearest:x,y,z")
    if damping:
        p.add_argument("--band", metavar="FMIN:FMAX", help="frequency band in Hz (default 1:1000)")
        p.add_argument("--rayleigh", metavar="ALPHA:BETA", help="Rayleigh damping D = alpha M + beta K (1/s, s)")
        p.add_argument("--modal-damping", metavar="ZETA", type=float,
                       help="damping ratio; realized as Rayleigh damping with this ratio at both band ends")
        p.add_argument("--n-freq", type=int, default=50, help="log-spaced base points of the error grid")
        p.add_argument("--grid-tol", type=float, help="relative tolerance of the adaptive error grid (default 3e-3)")
        p.add_argument("--full-frf", choices=["auto", "direct", "dense", "surrogate"], default="auto",
                       help="full FRF by direct solves, one dense eigendecomposition or a verified surrogate "
                            "(auto: dense up to 5k DOF, surrogate from 20k DOF)")
        p.add_argument("--no-cache", action="store_true", help="neither read nor write the full-FRF disk cache")


def build_parser() -> argparse.ArgumentParser:
    from .reduction import methods

    ap = argparse.ArgumentParser(prog="flexmor", description="Model order reduction of elastic bodies for EMBS.")
    ap.add_argument("--version", action="version", version=f"flexmor {__version__}")
    ap.add_argument("-v", "--verbose", action="count", default=0, help="log more (-vv: debug)")
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="reduce the built-in cantilever with several methods")
    p.add_argument("--out", default="demo-output",
                   help="output directory (default demo-output); the demo owns it and replaces its own files there")
    p.add_argument("--n", type=int, default=4, help="elements through the beam height (model size)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("info", help="sizes, checks and lowest eigenfrequencies of a model")
    _add_model_args(p, damping=False)
    p.add_argument("--modes", type=int, default=0, help="number of lowest eigenfrequencies to compute")
    p.add_argument("--backends", action="store_true", help="list the sparse solver backends and what each supports")
    p.add_argument("--formats", action="store_true", help="list the file formats flexmor reads (FE models, reduced "
                   "bodies) and exports, with their suffixes")
    p.add_argument("--reference", metavar="FRD", help="CalculiX .frd with the FE program's own modes: compare "
                   "frequencies and mode shapes (MAC) with the model's")
    for action in p._actions:  # MODEL is optional with --backends and --formats
        if action.dest == "model":
            action.nargs, action.required = "?", False
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("reduce", help="reduce a model and write the reduced body (.h5)")
    _add_model_args(p)
    p.add_argument("--method", required=True, choices=sorted(methods()), help="reduction method")
    p.add_argument("--order", type=int, help="reduced order r")
    p.add_argument("--input", action="append", default=[], metavar="SPEC", help="input NODE:DIR or SET:DIR")
    p.add_argument("--output", action="append", default=[], metavar="SPEC", help="output NODE:DIR or SET:DIR")
    p.add_argument("--interface", action="append", default=[], metavar="SPEC",
                   help="interface NODE, SET, SET:DIR, or SET@rbe2 / SET@rbe3 (6-DOF master node at the centroid)")
    p.add_argument("-o", "--output-file", metavar="FILE", help="reduced body file (.h5)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--no-error", action="store_true", help="skip the error evaluation against the full model")
    g = p.add_argument_group("interpolation methods (krylov, adaptive, irka)")
    g.add_argument("--tol", type=float, help="target band_error: choose the smallest order meeting it (verified)")
    g.add_argument("--points", metavar="P1,P2", help="expansion points in Hz, s = 2 pi p: 0, 300j (frequency "
                   "axis), -5 (real); default three real points over the band")
    g.add_argument("--moments", type=int, help="moments (blocks) per expansion point")
    g.add_argument("--side", choices=["input", "output", "both"], help="Krylov space of B, C^T or both (default input)")
    g.add_argument("--rigid", choices=["include", "exclude"], help="rigid-body modes of a free body in the basis "
                   "(krylov/adaptive default include, modal default exclude)")
    g.add_argument("--max-iter", type=int, help="irka: maximum iterations (default 50)")
    g.add_argument("--shift-tol", type=float, help="irka: relative change of the points for convergence (1e-4)")
    g = p.add_argument_group("Gramian and hybrid methods (sobt, fw-sobt, pod, two-step, cms-*, svdmor)")
    g.add_argument("--variant", choices=["position", "velocity"], help="balance position or velocity Gramians "
                   "(default position)")
    g.add_argument("--nodes", type=int, help="Gauss points per panel of the Gramian quadrature (default 4)")
    g.add_argument("--intermediate", type=int, metavar="R1", help="two-step: intermediate Krylov order (default 120)")
    g.add_argument("--gramian", choices=["band", "full"], help="two-step: frequency-limited or full-band Gramians")
    g.add_argument("--energy", type=float, help="pod: keep the fewest modes with this share of the snapshot energy")
    g.add_argument("--snapshots", choices=["frequency", "time", "both"], help="pod: snapshot source (default frequency)")
    g.add_argument("--directions", type=int, help="svdmor: input/output directions kept (default: sv > 1e-3 max)")
    p.set_defaults(func=cmd_reduce)

    p = sub.add_parser("compare", help="error measures of reduced bodies against the full model")
    _add_model_args(p)
    p.add_argument("reduced", nargs="+", help="reduced body files (.h5)")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("report", help="self-contained HTML report: FRFs, errors, MAC, time responses")
    _add_model_args(p)
    p.add_argument("reduced", nargs="+", help="reduced body files (.h5) with the same inputs and outputs")
    p.add_argument("-o", "--output-file", default="report.html", metavar="FILE", help="HTML file (report.html)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--signal", choices=["step", "impulse", "sweep"], default="step",
                   help="input of the time-domain comparison, applied to each input in turn (default step)")
    p.add_argument("--dt", type=float, help="time step in s (default 1/(20 FMAX))")
    p.add_argument("--t-end", type=float, help="end time in s (default 3 periods of the lowest mode)")
    p.add_argument("--scheme", choices=["newmark", "generalized-alpha"], default="newmark",
                   help="time integrator (default newmark, average acceleration)")
    p.add_argument("--modes", type=int, default=12, help="full flexible modes in the eigenfrequency/MAC table")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("export", help="export a reduced body to an MBS code (SID, Exudyn) or MATLAB/state space")
    p.add_argument("reduced", help="reduced body file (.h5)")
    p.add_argument("-o", "--output-file", required=True, metavar="FILE", help="file to write")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--format", help="sid, exudyn, mat, statespace (ss), hdf5; default from the suffix "
                   "(flexmor info --formats)")
    p.add_argument("--model", help="FE model the body was reduced from (required for sid and exudyn: the "
                   "inertia invariants integrate over its mass matrix)")
    p.add_argument("--model-format", help="override the format of --model chosen from its suffix")
    p.add_argument("--node", action="append", default=[], metavar="NODE|SET",
                   help="SID frame node (node id or set; a set gives an RBE3 master); default the port nodes")
    p.add_argument("--m1-order", choices=["row-q-col", "row-col-q"], default="row-q-col",
                   help="index order of SID m1(i,j,k) entries (default row-q-col, as PY_SID/EMBS)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_export)
    return ap


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    logging.captureWarnings(True)
    quiet_other_ranks()  # mpirun -n P: only rank 0 prints
    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread: leave signal handling alone
        pass
    try:
        return args.func(args)
    except FlexmorError as exc:
        msg = str(exc)
        model = getattr(args, "model", None)
        if model and isinstance(exc, (ModelError, PortError, SolverError, ConvergenceError)) and str(model) not in msg:
            msg = f"{model}: {msg}"  # problems found after reading still name the file
        print(f"flexmor: error: {msg}", file=sys.stderr)
        return 2
    except MemoryError:
        print("flexmor: error: out of memory; try a faster backend (--backend pardiso) or a smaller model",
              file=sys.stderr)
        return 2
    except OSError as exc:  # writing an output: permission denied, disk full, ...
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"flexmor: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("flexmor: interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print("flexmor: terminated", file=sys.stderr)
        return 143
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
