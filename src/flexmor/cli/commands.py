"""The subcommands of the ``flexmor`` command line: ``cmd_NAME(args) -> exit code``."""

from __future__ import annotations

import contextlib
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from .._version import __version__
from ..body import convergence_record
from ..errors import FlexmorNote, FlexmorWarning, OptionError, notes_stated
from ..jsonutil import jsonable
from ..linalg.distributed import is_partitioned, on_root, row_blocks
from .info import (
    basis_record,
    basis_rows,
    coupling_lines,
    info_backends,
    info_body,
    info_formats,
    interface_lines,
    is_body_file,
    print_campbell,
    print_mass_properties,
)
from .method_flags import method_options
from .tables import fmt, note_text, notes_as_flags, print_error_table, print_mounted, print_moving, print_static

__all__ = ["cmd_info", "cmd_reduce", "cmd_run", "cmd_compare", "cmd_report", "cmd_demo"]


def _emit_json(obj) -> None:
    if isinstance(obj, dict):  # every JSON answer says which flexmor wrote it
        obj = {**obj, "flexmor_version": __version__}
    print(json.dumps(jsonable(notes_as_flags(obj), finite=True)))  # notes name flags, as messages do


def _progress(args, label: str = "full FRF", unit: str = "freq"):
    """The ``progress(iterable, total, desc=None)`` callback of a command
    (:func:`flexmor.linalg.context.track`), or None: nothing under --json, nor when stderr is
    not a terminal unless -v. A counted loop gets a tqdm bar on a terminal, a step without a
    count (or any step off a terminal) a start and an end line with its wall time; ``label`` and
    ``unit`` name the loops the library does not name."""
    tty = sys.stderr.isatty()
    if getattr(args, "json", False) or not (tty or getattr(args, "verbose", 0)):
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        tty = False

    def progress(it, total, desc=None):
        name = desc or label
        if total is None or not tty:
            return _lines(it, name)
        return tqdm(it, total=total, desc=name, unit=unit if desc is None else "it", leave=False)

    return progress


def _lines(it, desc):
    """``it`` with a start and an end line (wall time, a step's ``result``) on stderr."""
    t0 = time.perf_counter()
    print(f"{desc} ...", file=sys.stderr, flush=True)
    item = None
    for item in it:
        yield item
    result = item.get("result") if isinstance(item, dict) else None
    print(f"{desc}: " + (f"{result}, " if result else "") + f"{time.perf_counter() - t0:.2f} s",
          file=sys.stderr, flush=True)


def _check_new(path, args) -> Path:
    """``path`` as a Path; an OptionError if it exists and ``--force`` was not given, or its folder
    does not exist (a mistyped folder is not created)."""
    path = Path(path)
    if path.is_dir():
        raise OptionError(f"{path} is a directory; give a file name with -o")
    folder = path.parent
    if not folder.exists():
        raise OptionError(f"{path}: the folder {folder} does not exist; create it first (mkdir -p {folder}) "
                          "or give another -o")
    if not folder.is_dir():
        raise OptionError(f"{path}: {folder} is a file, not a folder; give another -o")
    if path.exists() and not getattr(args, "force", False):
        raise OptionError(f"{path} exists; pass --force to overwrite it")
    return path


def _body_suffix(path) -> None:
    """``reduce -o`` writes a flexmor body (HDF5): a name another export format's suffix names is refused (the
    export makes that file from the body), another suffix is named in a warning."""
    import warnings

    from ..errors import FlexmorWarning
    from ..io import EXPORT_FORMATS

    fmt = EXPORT_FORMATS.by_path(path)
    if fmt is not None and fmt.name != "hdf5":
        raise OptionError(f"{path}: reduce writes a flexmor body (.h5); a {fmt.name} file is made from it by "
                          f"flexmor export BODY.h5 -o {Path(path).name}")
    if fmt is None:
        warnings.warn(FlexmorWarning(f"{path}: written as a flexmor body (HDF5, .h5) although its suffix is "
                                     f"{Path(path).suffix or '(none)'!r}"), stacklevel=2)


def _solver(args):
    """The solver context of one command: ``--backend``, ``--factor-memory``, ``--memory-limit`` (out-of-core
    files beside ``-o FILE``), the progress callback."""
    from ..linalg.context import SOLVE_TOL, SolverContext

    out = getattr(args, "output_file", None)
    return SolverContext(backend=args.backend, progress=_progress(args), factor_memory=args.factor_memory,
                         memory_limit=args.memory_limit, scratch_dir=str(Path(out).resolve().parent) if out else None,
                         solve_tol=getattr(args, "solve_tol", SOLVE_TOL))


def _factor_note(out: dict, solver) -> str:
    """``out["factor"]``: the memory modes of the factorizations; the line on those not in double in core, or ""."""
    from ..linalg.memory import describe_factor, factor_record

    out["factor"] = factor_record(solver.stats)
    st = solver.stats
    return f"factor: {describe_factor(st)}" if st.mixed or st.ooc or st.iterative else ""


def _preparation(args) -> dict:
    """The preparation keywords (:data:`flexmor.prepare.PREPARATION`, those of :class:`flexmor.System`) that
    ``--format``, ``--mesh``, ``--units``, ``--select``, ``--preload`` and ``--material`` give."""
    return {"format": getattr(args, "format", None), "mesh": getattr(args, "mesh", None),
            "units": getattr(args, "units", None), "select": list(getattr(args, "select", None) or ()),
            "preload": list(getattr(args, "preload", None) or ()), "material": getattr(args, "material", None)}


def _read_model(args, couplings=(), *, damped=True, check=None, solver=None):
    """:func:`flexmor.prepare.prepare` of ``args.model`` with the flags of :func:`_preparation`,
    ``couplings`` and (with ``damped``) the damping flags, and the band of ``--band`` (None when not
    given); the nodes that ``nearest`` selections chose are printed."""
    from ..options import Band
    from ..prepare import prepare

    band = Band.parse(args.band) if getattr(args, "band", None) else None
    done = prepare(args.model, **_preparation(args), couplings=couplings,
                   damping=_asked_damping(args) if damped else None, band=band, check=check,
                   solver=solver if solver is not None else _solver(args), progress=_progress(args))
    _print_nearest(done.nearest)
    return done, band


def _print_nearest(report) -> None:
    """One line on stderr per ``nearest`` selection: the node chosen and its distance from the point."""
    for r in report:
        print(f"selected {r['name']}=nearest:{','.join(f'{v:g}' for v in r['point'])}: node {r['node']} at "
              f"[{', '.join(f'{v:.6g}' for v in r['xyz'])}], {r['distance']:.4g} from the point"
              + (" (farther than a tenth of the model's size: a point outside the body, or in other units?)"
                 if r["outside"] else ""), file=sys.stderr)


def _asked_damping(args) -> dict | None:
    """The damping flags as the ``damping`` keyword of :class:`flexmor.System`
    (:func:`flexmor.prepare.as_damping`): ``{"rayleigh": (alpha, beta)}``, ``{"modal_damping": zeta}``,
    ``{"band_rayleigh": zeta}`` (more than one key is refused there, naming them), or None."""
    from ..options import parse_pair

    given = {"rayleigh": parse_pair(args.rayleigh, "rayleigh") if getattr(args, "rayleigh", None) else None,
             "modal_damping": getattr(args, "modal_damping", None),
             "band_rayleigh": getattr(args, "band_rayleigh", None)}
    return {k: v for k, v in given.items() if v is not None} or None


# -- info --------------------------------------------------------------------------------------
def _model_campbell(model, args, solver) -> dict:
    """The Campbell record of the model (``info MODEL --campbell AXIS:W0:W1[:N]``): its ``--modes`` lowest (6
    without) over N speeds."""
    from ..spin import campbell, parse_axis_speeds, spin_operators

    if not args.campbell:
        raise OptionError("--campbell of a model needs AXIS:W0:W1[:N] (e.g. z:0:500: 11 speeds from 0 to 500 rad/s "
                          "about z)", params=("campbell",))
    sr, n = parse_axis_speeds(args.campbell)
    ops = spin_operators(model, sr.axis, material=args.material, solver=solver, param="campbell")
    k = args.modes if args.modes > 0 else 6
    c = campbell(model.M, model.K, ops.K2, ops.G1, sr.speeds(n), k, D=model.D, solver=solver)
    return dict(c.record(), spec=sr.spec, axis=sr.axis.tolist())


def cmd_info(args) -> int:
    """``flexmor info``: a model's sizes, checks and lowest frequencies, a body's summary, the
    backends or the formats; returns the exit code."""
    from ..checks import MAX_RIGID_BODY_MODES, mechanism_error, rigid_body_note, stable_lowest_eigenvalues
    from ..linalg import available_backends
    from ..linalg.eigen import eigenmodes, frequencies_hz, is_rigid

    if args.backends:
        return info_backends(args)
    if args.formats:
        return info_formats(args, _emit_json)
    if args.model is None:
        raise OptionError("info needs a MODEL file (or --backends, --formats)")
    from ..io._geometry import describe_geometry_check, geometry_check
    from ..origin import describe_damping

    if is_body_file(args.model, args.format):
        return info_body(args, _emit_json)
    from ..workflow import coupling_specs

    if args.modes < 0:  # --modes without N
        args.modes = 12
    couplings = coupling_specs(args.interface)
    notes: list = []  # the notes of the file (flexmor.errors.NOTES), stated in full below
    solver = _solver(args)
    with _noted(notes):
        done, _ = _read_model(args, couplings, check=geometry_check, solver=solver)  # the check: as read
    model = done.model
    out = model.summary()
    out.update(model.mass_properties())
    out["selections"] = {name: model.node_sets[name].tolist() for name in _selected_names(args)}
    out["backends"] = available_backends()
    out["geometry_check"] = done.check
    if args.modes:
        k = min(args.modes, model.n_dof)
        lam = stable_lowest_eigenvalues(model, solver, k)  # a buckled preload is refused, not rigid-body modes
        n_zero = int(np.sum(is_rigid(lam, model.K, model.M)))
        if n_zero > MAX_RIGID_BODY_MODES:
            raise mechanism_error(model, n_zero)
        if n_zero:
            with _noted(notes):
                rigid_body_note(model, n_zero)
        lam = lam[:k]
        out["frequencies_hz"] = frequencies_hz(lam).tolist()
        out["n_rigid"] = min(n_zero, k)
    if model.preload:  # the frequencies of the model as read beside the preloaded ones
        out["preload"] = dict(model.preload)
        if args.modes:
            free = done.unloaded
            out["preload"]["frequencies_unloaded_hz"] = frequencies_hz(eigenmodes(free.K, free.M, k,
                                                                                   solver=solver)[0]).tolist()
    if args.reference:  # the model the reference was computed for: as read, or with the couplings given
        from ..checks import describe_couplings
        from ..io.reference import compare_reference_with, read_reference

        ref = read_reference(args.reference)
        candidates = {"the model as read": model} if not couplings else {
            f"the model with {describe_couplings(couplings)}": model,
            "the model as read, before its couplings": done.as_read}
        out["reference"] = dict(compare_reference_with(candidates, ref, solver=solver), file=str(args.reference),
                                described=ref.describe())
    if couplings:
        from ..checks import COUPLING_MODES, coupling_frequencies

        out["couplings"] = couplings
        out["coupling_frequencies"] = coupling_frequencies(done.as_read, model, couplings,
                                                           n=max(args.modes, COUPLING_MODES), solver=solver)
    if args.campbell is not None:
        out["campbell"] = _model_campbell(model, args, solver)
    out["notes"] = [{"name": n.name, "text": n.full()} for n in notes]
    out["timings"] = {"read": done.seconds}
    factor = _factor_note(out, solver)
    if args.json:
        _emit_json(out)
        return 0
    print(f"model     {model.name}  ({model.source})")
    if out.get("couplings"):
        from ..checks import describe_couplings

        print(f"coupled   with {describe_couplings(out['couplings'])} "
              "(sizes and frequencies below are the coupled model's)")
    print(f"DOF       {model.n_dof}    nodes {model.n_nodes}    nnz(K) {out['nnz_K']}")
    print(f"damping   {describe_damping(model.damping)}")
    if model.node_sets:
        print("node sets " + ", ".join(f"{k} ({v.size})" for k, v in model.node_sets.items()))
    print_mass_properties(out)
    for text, (name, ids) in zip(args.select, out["selections"].items()):
        print(f"selected  {name}: {len(ids)} nodes: " + " ".join(map(str, ids[:40])) + (" ..." if len(ids) > 40 else "")
              + (" (a sphere selects the nodes on its surface, r +- tol)" if "=sphere:" in text.lower() else ""))
    print(f"backends  {', '.join(out['backends'])}")
    print(f"checks    {describe_geometry_check(out['geometry_check'])}")
    if out.get("preload"):
        print(f"preload   {', '.join(out['preload']['specs'])}: K about the static equilibrium (largest displacement "
              f"{out['preload']['max_displacement']:.4g})" + (", with spin softening"
                                                             if out["preload"]["spin_softening"] else ""))
    if args.modes:
        was = (out.get("preload") or {}).get("frequencies_unloaded_hz")
        print(f"\n mode   frequency [Hz]   ({out['n_rigid']} rigid-body modes)" + ("   without preload   change"
                                                                                  if was else ""))
        for i, f in enumerate(out["frequencies_hz"], 1):
            tag = "  rigid" if i <= out["n_rigid"] else ""
            print(f"{i:5d}   {f:14.6f}{tag}" + (f"   {was[i - 1]:15.6f}   {f / was[i - 1] - 1:+7.2%}"
                                               if was and was[i - 1] > 0 else ""))
    if out.get("coupling_frequencies"):
        print()
        for line in coupling_lines(out["coupling_frequencies"]):
            print(line)
    if args.reference:
        _print_reference(args.reference, out["reference"])
    if out.get("campbell"):
        print()
        print_campbell(out["campbell"])
    for n in out["notes"]:
        print(f"\nnote {n['name']}: {n['text']} (--quiet-note {n['name']} keeps other commands from repeating it)")
    if factor:
        print(factor)
    return 0


@contextlib.contextmanager
def _noted(notes: list):
    """Within the block the notes issued (:class:`~flexmor.errors.FlexmorNote`, quieted ones too) are added
    to ``notes``, each once, to be stated in full; other warnings are shown as they are."""
    with warnings.catch_warnings(record=True) as caught, notes_stated():
        warnings.simplefilter("default", FlexmorWarning)
        yield
    for w in caught:
        if isinstance(w.message, FlexmorNote):
            if all(n.full() != w.message.full() for n in notes):
                notes.append(w.message)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _print_reference(path, ref: dict) -> None:
    """The table of ``info --reference``: each reference frequency against the model's, and the MAC when
    the file holds mode shapes (an .frd); the kind of file and, without shapes, why there is no MAC."""
    shapes = ref["shapes"]
    print(f"\nreference {path}: {ref['described']}"
          + (f"; compared with {ref['compared_with']}" if ref.get("compared_with") else "")
          + "".join(f" (with {k}: largest difference {fmt(v, '.2e')})" for k, v in ref.get("others", {}).items())
          + ("" if shapes else "; frequencies only, no mode shapes: "
                                                                       "no MAC column"))
    print(" mode   reference [Hz]       model [Hz]   rel. diff" + ("   MAC" if shapes else ""))
    macs = ref["mac"] if shapes else [None] * len(ref["frequencies_hz"])
    for i, (f, g, d, mac) in enumerate(zip(ref["frequencies_hz"], ref["model_frequencies_hz"], ref["rel_diff"],
                                           macs), 1):
        diff = "    rigid" if d is None and g is not None else "        -" if d is None else f"{d:9.2e}"
        print(f"{i:5d}   {f:14.6f}   " + ("             -" if g is None else f"{g:14.6f}") + f"   {diff}"
              + (f"   {fmt(mac, '.6f')}" if shapes else ""))


def _selected_names(args) -> list:
    """The node set names that ``--select NAME=...`` added."""
    from ..selection import parse_selection

    return [parse_selection(t)[0].upper() for t in getattr(args, "select", None) or ()]


# -- reduce ------------------------------------------------------------------------------------
def cmd_reduce(args) -> int:
    """``flexmor reduce``: read, prepare the study, reduce and judge, write the body; returns the exit code."""
    from ..study import System

    options = method_options(args, args.method)  # before any work: flags the method does not take
    if args.spin_range:
        options["spin_range"] = args.spin_range
    if args.tol is not None and args.no_error:
        raise OptionError("--tol needs the error evaluation over a band (drop --no-error)")
    if args.tol is None and args.tol_measure != "band_error":
        raise OptionError("--tol-measure chooses the measure of --tol; give --tol too")
    if args.output_file:
        _check_new(args.output_file, args)
        _body_suffix(args.output_file)
    if args.save_study:
        _check_new(args.save_study, args)
    solver = _solver(args)
    if args.crossing and not args.moving_load:
        raise OptionError("--crossing needs a --moving-load (the path the force crosses)", params=("crossing",))
    if args.crossing and args.no_error:
        raise OptionError("--crossing compares the body with the full model: drop --no-error", params=("crossing",))
    system = System(args.model, inputs=args.input, outputs=args.output, interfaces=args.interface,
                    moving_loads=args.moving_load, moving_load_tol=args.moving_load_tol,
                    band=args.band or None, damping=_asked_damping(args),
                    **_preparation(args), solver=solver, **_grid_options(args))
    _print_nearest(system.prepared_as.nearest)
    return _reduce_system(args, system, options, solver)


def cmd_run(args) -> int:
    """``flexmor run STUDY``: reduce as the study file says (:meth:`flexmor.System.from_study`), then as
    ``flexmor reduce`` (the same judgement, output and record); returns the exit code."""
    from ..study import System

    solver = _solver(args)
    system = System.from_study(args.study, solver=solver, progress=_progress(args, "full FRF"))
    recipe, judge = system.recipe, system.recipe["judge"]
    args.method, args.order = recipe["method"], recipe.get("order")
    args.no_error, args.no_mounted = not judge.get("error", True), not judge.get("mounted", True)
    args.tol, args.tol_measure = judge.get("tol"), judge.get("tol_measure", "band_error")
    args.inertia_loads = recipe.get("inertia_loads", "auto")
    args.residual_vectors = recipe.get("residual_vectors", False)
    args.stress, args.stress_nodes = recipe.get("stress", False), recipe.get("stress_nodes", "surface")
    args.output_file = args.output_file or recipe["output"].get("body")
    args.save_study = None
    if args.output_file:
        _check_new(args.output_file, args)
    options = dict(recipe.get("options", {}))
    if recipe.get("spin_range"):
        options["spin_range"] = recipe["spin_range"]
    return _reduce_system(args, system, options, solver)


def _reduce_system(args, system, options: dict, solver) -> int:
    """Reduce and judge ``system`` as ``args`` say (method, order, judgement, output), write the body (and
    with ``--save-study`` the study) and print the record; the rest of :func:`cmd_reduce` and :func:`cmd_run`."""
    from ..io import write_body
    from ..origin import describe_damping

    model, couplings = system.model, system.couplings
    if args.stress and is_partitioned(model.K):  # refused before the reduction, not after it
        raise OptionError("--stress needs the model on one process (not with --backend petsc under mpirun)")
    red, res = system.reduce_and_judge(args.method, args.order, judge=not args.no_error, tol=args.tol,
                                       tol_measure=args.tol_measure, inertia_loads=args.inertia_loads,
                                       residual_vectors=args.residual_vectors,
                                       mounted=not args.no_mounted, **options)
    res["timings"]["read"] = system.prepared_as.seconds
    if getattr(args, "crossing", None):
        t0 = time.perf_counter()
        curves = [system.crossing(red, v, force=args.crossing_force, k=k) for k in range(len(system.moving))
                  for v in args.crossing]
        red.errors["crossings"] = curves
        res["crossings"] = [{k: v for k, v in c.items() if not isinstance(v, list)} for c in curves]
        res["timings"]["crossings"] = time.perf_counter() - t0
    if is_partitioned(model.K):  # under mpirun with --backend petsc: the rows of K held by each rank
        res["partition"] = row_blocks(model.K)
    if args.stress:
        _stress_modes(red, system.as_read, system.material, args, res)
    if couplings:
        res["couplings"] = list(couplings)
    if system.selections:
        res["selections"] = list(system.selections)
    path = _check_new(args.output_file or f"{model.name}_{args.method}_{red.order}.h5", args)
    on_root(write_body, red, path)  # under MPI: written once, by rank 0
    res["file"] = str(path)
    if args.save_study:
        on_root(system.save_study, args.save_study, args.method, args.order, options,
                reduce={"inertia_loads": args.inertia_loads, "residual_vectors": args.residual_vectors or None,
                        "spin_range": getattr(args, "spin_range", None),
                        "stress": args.stress or None,
                        "stress_nodes": args.stress_nodes if args.stress else None},
                judge={"error": not args.no_error, "mounted": not args.no_mounted, "tol": args.tol,
                       "tol_measure": args.tol_measure, "n_freq": args.n_freq, "grid_tol": args.grid_tol,
                       "full_frf": args.full_frf, "cache": not args.no_cache},
                output={"body": str(path)})
        res["study"] = str(args.save_study)
    spin = red.info.get("spin")
    if spin:  # the speed range and its check, without the matrices
        res["spin"] = {k: v for k, v in spin.items() if k not in ("K2", "G1")}
    factor = _factor_note(res, solver)
    if args.json:
        _emit_json(res)
        return 0
    print(f"{args.method}: order {red.order}, {res['seconds']:.3f} s (basis + projection)")
    for line in interface_lines(red.info.get("masters", [])):
        print(f"interface {line}")
    for label, text in basis_rows(basis_record(red.info)):
        print(f"{label}: {text}")
    for m in red.info.get("moving_loads") or ():
        c = m["compression"]
        print(f"moving load {m['spec']}: {len(m['nodes'])} path nodes over {m['length']:.4g} m ({m['ordering']}), "
              f"{c['directions']} compressed loads (singular values above {c['tol']:g} of the largest"
              + (f"; the next {c['first_dropped']:.2e})" if c["first_dropped"] is not None else ")"))
    if res.get("order_note"):
        print(f"note: {note_text(res['order_note'])}")
    if res.get("converged") is False and not res["band_hz"]:  # else the error table says it
        print(f"NOT CONVERGED: {note_text(res['convergence_note'] or 'the iteration stopped without converging')}")
    if res.get("tol") is not None:
        m = res["tol_measure"]
        print(f"--tol {res['tol']:g} on {m}: order {red.order} chosen, verified {m} {fmt(res[m], '.3g')} "
              + ("meets it" if res["tol_reached"] else "MISSES it (largest order tried)"))
    if res["band_hz"]:
        print(f"band {res['band_hz'][0]:g}-{res['band_hz'][1]:g} Hz, damping "
              f"{describe_damping(model.damping)}:")
        print_error_table([res])
        print_mounted([res])
        print_static([res])
        print_moving([res])
    for line in coupling_lines(res.get("coupling_frequencies")):
        print(f"coupling: {line}")
    fr = res["frequencies_hz"]
    print("reduced frequencies [Hz]: " + " ".join(f"{f:.4g}" for f in fr[:12]) + (" ..." if len(fr) > 12 else ""))
    if spin:
        c = spin["check"]
        print(f"spin {spin['spec']} rad/s: the lowest {len(c['full_hz'][0])} frequencies (without Coriolis) within "
              f"{c['max_rel_error']:.2e} of the full model's at {', '.join(f'{w:g}' for w in c['speeds'])} rad/s; "
              "flexmor info BODY --campbell for the Campbell diagram")
    if factor:
        print(factor)
    print(f"written {path}" + (f" and the study {args.save_study}" if args.save_study else ""))
    return 0


def _stress_modes(red, model, material, args, res) -> None:
    """Store the stress modes of ``red`` (``--stress``) at ``--stress-nodes``, with ``material``."""
    from ..stress import body_stresses

    t0 = time.perf_counter()
    out = body_stresses(model, red, material=material, nodes=args.stress_nodes)
    red.stress_nodes, red.stress_modes = out.node_ids, out.values
    red.info["stress"] = {"nodes": args.stress_nodes, "n_nodes": int(out.node_ids.size),
                          "material": list(material) if material else "deck"}
    res["stress"] = dict(red.info["stress"], seconds=time.perf_counter() - t0)


# -- compare -----------------------------------------------------------------------------------
def _model_and_bodies(args):
    """The full model (as read, without damping), the reduced bodies of ``args``, the band of each
    and where it comes from, and the damping asked for on the command line. Without ``--units`` the
    model is read in the unit system its bodies record (when they record one), without ``--preload``
    with the preload they record. A body's band is
    ``--band``, else the band it was reduced for (or judged over when it was made), else
    DEFAULT_BAND."""
    from ..damping import NoDamping
    from ..io import read_body
    from ..options import Band
    from ..preload import recorded_material
    from ..prepare import as_damping
    from ..workflow import DEFAULT_BAND

    bodies = [read_body(p) for p in args.reduced]
    recorded = {b.units for b in bodies}
    if getattr(args, "units", None) is None and len(recorded) == 1 and None not in recorded:
        args.units = recorded.pop()  # the model in the unit system its bodies record (as export does)
    preloads = {tuple(b.info["preload"].get("specs", [])) if isinstance(b.info.get("preload"), dict) else ()
                for b in bodies}
    if not getattr(args, "preload", None) and len(preloads) == 1 and () not in preloads:
        args.preload = list(preloads.pop())  # the model stiffened by the preload its bodies record
        args.preload_from_bodies = True
        materials = {repr(b.info["preload"].get("material")) for b in bodies}
        if getattr(args, "material", None) is None and len(materials) == 1:  # and stressed with their material
            args.material = recorded_material(bodies[0].info["preload"], args.reduced[0])
    done, band = _read_model(args, damped=False)
    model, t_read = done.model, done.seconds
    if band is not None:
        bands, sources = [band] * len(bodies), ["as given by --band"] * len(bodies)
    else:
        own = [r.info.get("band") or (r.errors or {}).get("band_hz") for r in bodies]
        bands = [Band.of(b) if b else DEFAULT_BAND for b in own]
        sources = ["the band the body was reduced for" if b else "the default band (the body records none; "
                   "give --band)" for b in own]
    common = bands[0] if len({tuple(b) for b in bands}) == 1 else None
    return model, t_read, bands, sources, bodies, as_damping(_asked_damping(args) or NoDamping(),
                                                             band or common or DEFAULT_BAND)


def _band_lines(paths, bands, sources) -> list[str]:
    """Which band each body is judged over and why: one line when they share it."""
    if len({(tuple(b), s) for b, s in zip(bands, sources)}) == 1:
        return [f"band {bands[0][0]:g}-{bands[0][1]:g} Hz: {sources[0].replace('the body was', 'the bodies were')}"]
    return ["bands: each body over its own"] + [f"  {p}: {b[0]:g}-{b[1]:g} Hz ({s})"
                                                 for p, b, s in zip(paths, bands, sources)]


def cmd_compare(args) -> int:
    """``flexmor compare``: judge each body against the study of its model, damping and ports; returns
    the exit code."""
    from ..analysis.mounted import FullMounted
    from ..moving import judge_paths, moving_key
    from ..origin import describe_damping, reference_model
    from ..ports import body_ports
    from ..study import System

    model, t_read, bands, sources, reds, asked = _model_and_bodies(args)
    solver = _solver(args)
    systems, mounts, rows, path_fulls = {}, {}, [], {}
    for path, red, band, source in zip(args.reduced, reds, bands, sources):
        couplings = tuple(red.couplings)
        ref = reference_model(model, red, path, damping=asked)
        key = (tuple(red.input_names), tuple(red.output_names), couplings, tuple(red.selections),
               str(ref.damping.to_dict()), tuple(band), moving_key(red))
        if key not in systems:
            systems[key] = System.prepared(ref, body_ports(ref, red), couplings=couplings, band=band,
                                           solver=solver, **_grid_options(args))
        system = systems[key]  # reference_model checked the body against the model; ports and damping are its own
        full = system.full  # once per model, damping, ports and band (not in the error's time)
        t0 = time.perf_counter()
        err = full.evaluate(red)
        t_err = time.perf_counter() - t0
        row = {"file": str(path), "method": red.method, "order": red.order, **convergence_record(red),
               "band_hz": list(band), "band_source": source, **err.to_dict(), "damping": ref.damping.to_dict(),
               "reference_damping": describe_damping(ref.damping), "timings": {"error": t_err}}
        t0 = time.perf_counter()  # the body in its joints; the full side once per model (couplings, selections)
        mkey = (*key[2:5], band[1])  # held modes up to the band's top, their damping ratios with the damping
        if mkey not in mounts:
            mounts[mkey] = FullMounted(ref, fmax=band[1], solver=solver)
        row["mounted"] = system.mounted(red, full=mounts[mkey], band_rms_error=row["band_rms_error"])
        row["static"] = system.static(red, full=mounts[mkey], mounted=row["mounted"],
                                      band_rms_error=row["band_rms_error"])
        row["timings"]["mounted"] = time.perf_counter() - t0
        for rec in (row["mounted"], row["static"]):
            if rec and rec["note"]:
                row["notes"].append(rec["note"])
        if red.info.get("moving_loads"):  # judged over the path (the full path FRF once per model and path)
            t0 = time.perf_counter()
            row["moving_loads"] = [{k: v for k, v in r.items() if k != "positions"} for r in
                                   judge_paths(ref, red, band, fulls=path_fulls, solver=solver,
                                               **_grid_options(args))]
            row["timings"]["moving_loads"] = time.perf_counter() - t0
        rows.append(row)
    fulls = {k: s.full for k, s in systems.items()}
    if args.json:
        grids = [dict(f.summary(), inputs=list(k[0]), outputs=list(k[1]), couplings=list(k[2]))
                 for k, f in fulls.items()]
        same = len({tuple(b) for b in bands}) == 1  # else each row has its own
        source = sources[0].replace("the body was", "the bodies were") if same else "each body's own"
        _emit_json({"model": model.name, "band_hz": list(bands[0]) if same else None, "band_source": source,
                    "results": rows, "grids": grids,
                    "timings": {"read": t_read, "full_frf": sum(f.seconds for f in fulls.values()),
                                "mounted": sum(r["timings"]["mounted"] for r in rows)}})
        return 0
    print_error_table(rows, label="file")
    print_mounted(rows, label="file")
    print_static(rows, label="file")
    print_moving(rows, label="file")
    damp = sorted({r["reference_damping"] for r in rows})
    from ..checks import describe_couplings

    refs = sorted({"full model" + (f" with {describe_couplings(k[2])}" if k[2] else "") for k in fulls})
    print(f"reference: the {' / '.join(refs)} with each body's own damping ({'; '.join(damp)})")
    for line in _band_lines(args.reduced, bands, sources):
        print(line)
    if getattr(args, "preload_from_bodies", False):
        print(f"preload {', '.join(map(str, args.preload))}: the model stiffened by the preload the bodies record")
    return 0


def _grid_options(args) -> dict:
    """The full FRF's options (:class:`flexmor.analysis.compare.FullResponse`) of the command line:
    ``--n-freq``, ``--grid-tol``, ``--full-frf``, ``--no-cache`` and the progress lines."""
    grid = {"n": args.n_freq, "path": args.full_frf, "cache": not args.no_cache,
            "progress": _progress(args, "full FRF")}
    if args.grid_tol is not None:
        grid["tol"] = args.grid_tol
    return grid


# -- report ------------------------------------------------------------------------------------
def cmd_report(args) -> int:
    """``flexmor report``: the HTML report of a model and its bodies; returns the exit code."""
    from ..moving import moving_key
    from ..origin import describe_damping, reference_model, same_damping
    from ..ports import body_ports
    from ..report.contents import build_report
    from ..report.html import write_report
    from ..study import System

    _check_new(args.output_file, args)
    model, t_read, bands, sources, reds, asked = _model_and_bodies(args)
    band, band_source = bands[0], sources[0].replace("the body was", "the bodies were")
    if len({tuple(b) for b in bands}) > 1:  # one band for the plots: the widest
        band = (min(b[0] for b in bands), max(b[1] for b in bands))
        band_source = ("the span of the bands the bodies were reduced for ("
                       + ", ".join(f"{p}: {b[0]:g}-{b[1]:g} Hz" for p, b in zip(args.reduced, bands)) + ")")

    def key_of(r):
        return (list(r.input_names), list(r.output_names), list(r.couplings), list(r.selections), moving_key(r))

    key = key_of(reds[0])
    other = [str(p) for p, r in zip(args.reduced, reds) if key_of(r) != key]
    if other:
        raise OptionError(f"a report needs bodies with the same inputs/outputs/couplings/selections as "
                          f"{args.reduced[0]}; these differ: {', '.join(other)}")
    other = [f"{p} ({describe_damping(r.damping)})" for p, r in zip(args.reduced, reds)
             if not same_damping(r.damping, reds[0].damping)]
    if other:
        raise OptionError(f"a report judges its bodies against one full model: {args.reduced[0]} was reduced with "
                          f"damping {describe_damping(reds[0].damping)}, these with another: {', '.join(other)}; "
                          "compare them with flexmor compare, or make one report per damping")
    as_read = model
    model = [reference_model(model, r, p, damping=asked) for p, r in zip(args.reduced, reds)][0]
    solver = _solver(args)
    system = System.prepared(model, body_ports(model, reds[0]), couplings=key[2], band=band, solver=solver,
                             **_grid_options(args))  # the bodies: checked by reference_model, same ports and damping
    ports, full = system.ports, system.full
    coupling = reds[0].info.get("coupling_frequencies")
    if key[2] and not coupling and not is_partitioned(model.K):  # a body written before it was recorded
        from ..checks import coupling_frequencies

        coupling = coupling_frequencies(as_read, model, key[2], solver=solver)
    rep = build_report(model, ports, reds, band=band, full=full, signal=args.signal, dt=args.dt, t_end=args.t_end,
                       scheme=args.scheme, n_modes=args.modes, solver=solver, coupling=coupling,
                       time_progress=_progress(args, "time steps", unit="step"))
    on_root(write_report, rep, _check_new(args.output_file, args))  # under MPI: written once, by rank 0
    if args.json:
        _emit_json({"file": str(args.output_file), "model": model.name, "band_hz": list(band),
                    "band_source": band_source, "results": rep.rows,
                    "time": rep.time, "notes": rep.notes, "reference": rep.reference,
                    "coupling_frequencies": rep.coupling or None,
                    "timings": {"read": t_read, "full_frf": full.seconds}})
        return 0
    print_error_table(rep.rows, label="label", header="body")
    print_mounted(rep.rows, label="label")
    print("time_max_error: " + ", ".join(f"{r['label']} {fmt(r['time_max_error'])}" for r in rep.rows))
    print(f"reference: the {rep.reference} with the bodies' damping ({describe_damping(model.damping)})")
    print(f"band {band[0]:g}-{band[1]:g} Hz: {band_source}")
    for line in coupling_lines(rep.coupling):
        print(f"coupling: {line}")
    print(f"written {args.output_file}")
    return 0


# -- demo --------------------------------------------------------------------------------------
def cmd_demo(args) -> int:
    """``flexmor demo``: the main job on the built-in model; returns the exit code."""
    from ..workflow import run_demo

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
    print_error_table(res["results"])
    print(f"\nreduced bodies and {res['plot']} written to {args.out}/")
    if res.get("report"):
        print(f"report: {res['report']}")
    return 0
