"""The argument parser of the ``flexmor`` command line.

The per-method options of ``flexmor reduce`` are generated from the options dataclasses of
the registered methods (:attr:`flexmor.reduction.Method.options_class`): one flag per option
name (``max_iter`` -> ``--max-iter``), and in ``--help`` one group per method listing its
options with their defaults (:mod:`.method_flags` collects the ones given and refuses a flag the
chosen method does not take). :func:`flag_names` maps the parameters that library errors
name (:attr:`flexmor.errors.FlexmorError.params`) to the flags of a command.
"""

from __future__ import annotations

import argparse
import re

from .._version import __version__
from ..analysis.frequency import MEASURES, TOL_MEASURES
from ..errors import did_you_mean
from ..io import EXPORT_FORMATS
from ..linalg.context import SOLVE_TOL
from ..linalg.memory import FACTOR_MEMORY
from ..options import DEFAULT_BAND, option_fields
from ..tolerance import tol_methods
from .commands import cmd_compare, cmd_demo, cmd_info, cmd_reduce, cmd_report, cmd_run
from .export import cmd_export
from .method_flags import COMMON, all_options, flag
from .plan import add_plan_parser
from .ui import add_ui_parser

__all__ = ["build_parser", "flag_names"]

#: Library parameter -> the argparse ``dest`` of its flag, where the names differ.
PARAM_DESTS = {"inputs": "input", "outputs": "output", "selections": "select", "nodes": "node",
               "spec": "preload"}

_INTERFACE_HELP = "interface NODE, SET, SET:DIR, or SET@rbe2 / SET@rbe3 (6-DOF master node at the centroid)"
_MESH_HELP = ("mesh file read through meshio (.vtu .msh .inp .bdf ...) for matrices without geometry (Matrix "
              "Market, MATLAB): its points are the nodes, the equations their x y z (or x..rz) node after node")



def _method(text: str) -> str:
    """``--method``: the registered name (aliases, case), or the error with its "did you mean"."""
    from ..errors import OptionError
    from ..reduction import method_name

    try:
        return method_name(text)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(exc.message({"method": "--method"})) from None


def _unit_system(flag: str):
    """The type of ``--units`` / ``--export-units``: the canonical name, or the error with its "did you mean"."""
    def parse(text: str) -> str:
        from ..errors import OptionError
        from ..units import unit_system

        try:
            return unit_system(text).name
        except OptionError as exc:
            text = exc.message({"units": flag}).removeprefix(f"{flag}=")  # argparse names the flag
            raise argparse.ArgumentTypeError(text) from None

    return parse


_UNITS_HELP = ("unit system of the model file, converted to SI on reading: SI (= m-kg-s), mm-t-s, mm-kg-ms, mm-g-ms, "
               "in-lbf-s (default: the numbers as given)")


def _help(f) -> str:
    if f.default is None:
        return f.metadata["help"]
    return f"{f.metadata['help']} (default {f.default})"


def _add_method_options(p) -> None:
    """One flag per method option name (parsed once), and one ``--help`` group per method."""
    from ..reduction import METHODS

    for name, f in all_options().items():
        if name not in COMMON:
            md = f.metadata
            p.add_argument(flag(name), dest=name, type=md["parse"], choices=md["choices"] or None,
                           metavar=md["metavar"], help=argparse.SUPPRESS)
    for method in sorted(METHODS):
        m = METHODS[method]
        g = p.add_argument_group(f"--method {method}", m.description)
        for name, f in option_fields(m.options_class).items():
            md = f.metadata
            # shown in this group only; the flag itself was added above
            g._group_actions.append(argparse.Action([flag(name)], dest=name, metavar=md["metavar"],
                                                    choices=md["choices"] or None, help=_help(f)))


def flag_names(p) -> dict:
    """Parameter name -> flag for the parser ``p`` of one command (``inputs`` -> ``--input``)."""
    names = {a.dest: max(a.option_strings, key=len) for a in p._actions if a.option_strings}
    for param, dest in PARAM_DESTS.items():
        if dest in names and param not in names:
            names[param] = names[dest]
    return names


_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def material_values(text: str) -> tuple:
    """``(E, nu[, rho])`` of ``--material E,NU[,RHO]``."""
    try:
        vals = tuple(float(t) for t in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) not in (2, 3):
        raise argparse.ArgumentTypeError(f"{text!r} is not E,NU or E,NU,RHO (e.g. 210e9,0.3,7850)")
    return vals


def memory_size(text: str) -> float:
    """Bytes of ``--memory-limit``: a number with an optional unit K, M, G or T (powers of 1024)."""
    t = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = t[-1:] if t[-1:] in _UNITS and t[-1:] else ""
    try:
        value = float(t[:len(t) - len(unit)]) * _UNITS[unit]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a memory size (e.g. 8G, 500M, 2e9)") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: the memory limit must be positive")
    return value


def _add_model_args(p, damping=True):
    p.add_argument("model", help="main file of the FE export (format from the suffix)")
    p.add_argument("--format", help="override the format chosen from the suffix")
    p.add_argument("--mesh", metavar="FILE", help=_MESH_HELP)
    p.add_argument("--units", type=_unit_system("--units"), metavar="SYSTEM", help=_UNITS_HELP)
    p.add_argument("--backend", default="auto",
                   help="sparse solver: auto, pardiso, cholmod, scipy, petsc (MPI: mpirun -n P flexmor ...), amg "
                        "(iterative: algebraic multigrid + block CG for real positive definite matrices; no band "
                        "error, krylov at real points), petsc-gamg (the same with PETSc GAMG + CG under MPI; "
                        "with --no-error)")
    p.add_argument("--solve-tol", type=float, default=SOLVE_TOL, metavar="TOL",
                   help=f"relative residual of every solve of backends amg and petsc-gamg (default {SOLVE_TOL:g})")
    p.add_argument("--factor-memory", choices=FACTOR_MEMORY, default="auto",
                   help="memory mode of the factorizations: double (in core), mixed (single-precision factor, "
                        "solves refined in double; pardiso, scipy), ooc (out of core, files beside the output or "
                        "in $TMPDIR; pardiso); auto: double if it fits, else mixed, else ooc (default auto)")
    p.add_argument("--memory-limit", type=memory_size, metavar="SIZE",
                   help="memory the factorizations may count on, e.g. 16G (default: the available memory)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--select", action="append", default=[], metavar="NAME=KIND:NUMBERS",
                   help="add node set NAME: set:OTHER, box:x0,y0,z0,x1,y1,z1, plane:x0,y0,z0,nx,ny,nz[,tol], "
                        "cylinder:x0,y0,z0,dx,dy,dz,r[,tol[,s0,s1]] (a hole), sphere:x,y,z,r[,tol], nearest:x,y,z")
    p.add_argument("--preload", action="append", default=[], metavar="SPEC",
                   help="static preload whose geometric stiffness (and spin softening) the model's K takes on: "
                        "NODE:DIR=F or SET:DIR=F (total force F spread over the set), gravity:GX,GY,GZ, "
                        "spin:WX,WY,WZ (rad/s about an axis through the origin); repeatable, the loads add up; "
                        "in the model's units (SI with --units); needs a supported model and its elements")
    p.add_argument("--material", type=material_values, metavar="E,NU[,RHO]",
                   help="isotropic material of every element (for --stress and --preload), in place of the deck's")
    if damping:
        p.add_argument("--band", metavar="FMIN:FMAX",
                       help=f"frequency band in Hz (default {DEFAULT_BAND[0]:g}:{DEFAULT_BAND[1]:g})")
        p.add_argument("--rayleigh", metavar="ALPHA:BETA", help="Rayleigh damping D = alpha M + beta K (1/s, s)")
        p.add_argument("--band-rayleigh", metavar="ZETA", type=float,
                       help="Rayleigh damping D = alpha M + beta K with ratio ZETA at both band ends (lower in "
                       "between, higher outside)")
        p.add_argument("--modal-damping", metavar="ZETA", type=float,
                       help="modal damping: this ratio in every mode (exact in the reduced body and the dense full "
                       "FRF; the sparse full FRF has it below the band's top)")
        p.add_argument("--n-freq", type=int, default=50, help="log-spaced base points of the error grid")
        p.add_argument("--grid-tol", type=float, help="relative tolerance of the adaptive error grid (default 3e-3)")
        p.add_argument("--full-frf", choices=["auto", "direct", "dense", "surrogate"], default="auto",
                       help="full FRF by direct solves, one dense eigendecomposition or a verified surrogate "
                            "(auto: dense up to 5k DOF, surrogate from 20k DOF)")
        p.add_argument("--no-cache", action="store_true", help="neither read nor write the full-FRF disk cache")


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors name the closest choice or flag ("did you mean"), and that takes a
    value beginning with a minus and a digit as a value (``--band -5:1000``, ``--rayleigh -1:0``), so that its
    own check explains it, rather than as an unknown flag (no flag begins so)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def parse_args(self, args=None, namespace=None):
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            sub = self._subparsers._group_actions[0].choices.get(getattr(ns, "command", None)) \
                if self._subparsers else None
            (sub or self).error(_unrecognized(extras, sub or self))
        return ns

    def error(self, message):
        match = re.search(r"invalid choice: '(.*?)' \(choose from (.*)\)$", message)
        if match:
            hint = did_you_mean(match[1], re.findall(r"'([^']*)'", match[2])).strip()
            if hint:
                message = f"{message}; {hint}"
        super().error(message)


def _count(text: str) -> int:
    """A count of at least 0 (argparse type)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number (0 or more), got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number (0 or more), got {value}")
    return value


def _unrecognized(extras, parser) -> str:
    """The message on arguments ``parser`` does not take, each flag with the closest of its flags."""
    flags = [s for a in parser._actions for s in a.option_strings if s.startswith("--")]
    hints = [f"{x}: {h.strip()}" for x in extras if x.startswith("--")
             for h in [did_you_mean(x.split("=")[0], flags)] if h]
    return f"unrecognized arguments: {' '.join(extras)}" + (f" ({'; '.join(hints)})" if hints else "")


def _add_verbose(p, default=0) -> None:
    p.add_argument("-v", "--verbose", action="count", default=default,
                   help="log more (-vv: debug); long steps show their progress on stderr, "
                   "also when it is not a terminal (never under --json)")


def _add_quiet_note(p) -> None:
    from ..errors import NOTES, QUIET_NOTES_VARIABLE

    p.add_argument("--quiet-note", action="append", choices=list(NOTES), metavar="NAME",
                   help="do not repeat the note NAME, a fact of the file that needs no action (repeatable; "
                   f"{', '.join(NOTES)}; flexmor info states them in full; {QUIET_NOTES_VARIABLE}=NAME,... "
                   "does the same)")


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``flexmor`` with every subcommand and its flags (the method options' flags
    generated from the registered options dataclasses)."""
    from ..reduction import ALIASES, METHODS

    ap = Parser(prog="flexmor", description="Model order reduction of elastic bodies for EMBS.")
    ap.add_argument("--version", action="version", version=f"flexmor {__version__}")
    _add_verbose(ap)
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="reduce the built-in cantilever with several methods")
    p.add_argument("--out", default="demo-output",
                   help="output directory (default demo-output); the demo owns it and replaces its own files there")
    p.add_argument("--n", type=int, default=4, help="elements through the beam height (model size)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("info", help="sizes, checks and lowest eigenfrequencies of a model")
    _add_model_args(p, damping=False)
    p.add_argument("--modes", type=_count, nargs="?", const=-1, default=0, metavar="N",
                   help="a model: its N lowest eigenfrequencies (12 without N); a body: its mode table (frequency, "
                   "damping ratio, effective mass and rotary inertia about the frame, share of the port response; "
                   "all modes without N)")
    p.add_argument("--backends", action="store_true", help="list the sparse solver backends and what each supports")
    p.add_argument("--formats", action="store_true", help="list the file formats flexmor reads (FE models, reduced "
                   "bodies) and exports, with their suffixes")
    p.add_argument("--reference", metavar="FILE", help="the FE program's own eigenfrequencies, compared with the "
                   "model's: a CalculiX .frd (also mode shapes: MAC), a CalculiX .dat, a Nastran .f06 or a list of "
                   "frequencies in Hz, one per line")
    p.add_argument("--interface", action="append", default=[], metavar="SPEC",
                   help="couple SET@rbe2 / SET@rbe3 as reduce does: the model shown is the coupled one, and its "
                        "lowest elastic frequencies are compared with those of the FE model as read")
    p.add_argument("--campbell", nargs="?", const="", default=None, metavar="AXIS:W0:W1[:N]",
                   help="Campbell diagram: the damped frequencies over N speeds (default 11) from W0 to W1 rad/s "
                        "about AXIS, with the centrifugal stiffening, spin softening and Coriolis forces, each mode's "
                        "whirl (FW/BW in the turning frame) and the critical speeds; a model: its --modes lowest (6 "
                        "without); a body reduced with --spin-range: without a value, over its range")
    for action in p._actions:  # MODEL is optional with --backends and --formats
        if action.dest == "model":
            action.nargs, action.required = "?", False
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("reduce", help="reduce a model and write the reduced body (.h5)",
                       epilog="A method option given to a method that does not take it is an error.")
    _add_model_args(p)
    p.add_argument("--method", required=True, type=_method, choices=sorted(METHODS),
                   help="reduction method (short names: " + ", ".join(f"{a}={m}" for a, m in ALIASES.items()) + ")")
    p.add_argument("--order", type=int, help="reduced order r")
    p.add_argument("--input", action="append", default=[], metavar="SPEC", help="input NODE:DIR or SET:DIR")
    p.add_argument("--output", action="append", default=[], metavar="SPEC", help="output NODE:DIR or SET:DIR")
    p.add_argument("--interface", action="append", default=[], metavar="SPEC", help=_INTERFACE_HELP)
    p.add_argument("-o", "--output-file", metavar="FILE", help="reduced body file (.h5)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--no-error", action="store_true", help="skip the error evaluation against the full model")
    p.add_argument("--no-mounted", action="store_true", help="skip the check of the body held at its interfaces "
                   "(clamped and pinned frequencies, static deflection against the full model held the same way; "
                   "one factorization and eigen solve of the full model per interface and support)")
    p.add_argument("--tol", type=float,
                   help="target error: choose the smallest order whose verified error (--tol-measure) meets it; "
                        f"--order is then the largest order tried. Methods: {', '.join(tol_methods())} "
                        "(craig-bampton, cms-*: the number of internal vectors next to the interface DOFs); "
                        "not guyan (its order is the interface)")
    p.add_argument("--tol-measure", choices=TOL_MEASURES, default="band_error",
                   help="the error measure --tol targets (default band_error): "
                        + "; ".join(f"{k}: {v}" for k, v in MEASURES.items()).replace("%", "%%"))
    p.add_argument("--inertia-loads", choices=["auto", "on", "off"], default="auto",
                   help="add the frame's inertia loads (6 unit accelerations, gravity among them) to the inputs "
                   "the basis is built for, sharing the order with the ports; auto (the default) and on: M R on a "
                   "supported body (gravity and its support's motion load it in directions its ports may not see); on "
                   "a free body the accelerations of the body held at each coupling master (--interface SET@rbe2), so "
                   "that the mounted body sags like the full model (nothing for a free body without one); off: the "
                   "ports only. Methods whose basis ignores the inputs (modal, guyan, craig-bampton) are not affected")
    p.add_argument("--residual-vectors", action="store_true",
                   help="append the static responses to the inputs, the frame's six accelerations and the coupling "
                   "masters' unit loads to the method's basis (counted in --order): the body's static response is "
                   "exact (every method; flexmor.reduction.residual)")
    p.add_argument("--stress", action="store_true",
                   help="store the body's stress modes: the nodal stress (xx yy zz xy yz zx, extrapolated and "
                        "averaged as CalculiX does) of every basis vector at --stress-nodes; needs the elements "
                        "and materials of the FE deck (or --material)")
    p.add_argument("--stress-nodes", default="surface", metavar="SET|surface|all",
                   help="where --stress stores the stress: the outer surface (default), every node, or a node set")
    p.add_argument("--save-study", metavar="FILE", help="also write the study (model file and its checksum, every "
                   "preparation flag, ports, band, damping, method, order, options; .toml) that flexmor run FILE "
                   "reproduces")
    p.add_argument("--spin-range", metavar="AXIS:W0:W1", help="one body for every speed from W0 to W1 rad/s about "
                   "AXIS (x, y, z or AX,AY,AZ, through the origin): the method's basis at three speeds, merged to "
                   "--order; the body carries K(w) = K + w^2 K2 (centrifugal stiffening and spin softening) and the "
                   "Coriolis matrix w G1, checked against the full model at five speeds; needs a supported model and "
                   "its elements")
    p.add_argument("--moving-load", action="append", default=[], metavar="SET:DIR[@AXIS]",
                   help="a force in DIR (x, y, z) moving over the nodes of SET (ordered along AXIS, else as a "
                   "nearest-neighbour chain), interpolated linearly between them: its inputs are compressed over the "
                   "band (--moving-load-tol) and join the ports; the body keeps every path node's reduced load and is "
                   "judged over the path's positions (flexmor.moving)")
    p.add_argument("--moving-load-tol", type=float, metavar="TOL",
                   help="relative singular value below which a compressed direction of the moving load's inputs is "
                   "dropped (default 3e-3)")
    p.add_argument("--crossing", action="append", default=[], type=float, metavar="SPEED",
                   help="with --moving-load: a force crossing the path at SPEED (m/s), body against the full model in "
                   "time (the deflection under the load; repeat for more speeds)")
    p.add_argument("--crossing-force", type=float, default=1.0, metavar="N",
                   help="the crossing force in N (default 1)")
    _add_method_options(p)
    p.set_defaults(func=cmd_reduce)

    p = sub.add_parser("run", help="reduce as a study file says (flexmor reduce --save-study) and write the body")
    p.add_argument("study", help="study file (.toml)")
    p.add_argument("-o", "--output-file", metavar="FILE", help="reduced body file (.h5; default the study's)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--backend", default="auto",
                   help="sparse solver: auto, pardiso, cholmod, scipy, petsc, amg, petsc-gamg")
    p.add_argument("--solve-tol", type=float, default=SOLVE_TOL, metavar="TOL", help="as for reduce")
    p.add_argument("--factor-memory", choices=FACTOR_MEMORY, default="auto", help="as for reduce")
    p.add_argument("--memory-limit", type=memory_size, metavar="SIZE", help="as for reduce")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_run)

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
    p.add_argument("--dt", type=float, help="time step in s (default 1/(20 FMAX), or t_end/5000 where that is "
                   "longer: the report then says up to which frequency the time responses resolve)")
    p.add_argument("--t-end", type=float, help="end time in s (default 3 periods of the lowest mode)")
    p.add_argument("--scheme", choices=["newmark", "generalized-alpha"], default="newmark",
                   help="time integrator (default newmark, average acceleration)")
    p.add_argument("--modes", type=int, default=12, help="full flexible modes in the eigenfrequency/MAC table")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("export", help="export a reduced body to an MBS code (SID, Exudyn) or MATLAB/state space")
    p.add_argument("reduced", help="reduced body file (.h5)")
    p.add_argument("-o", "--output-file", required=True, metavar="FILE", help="file to write")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--format", help=f"{', '.join(EXPORT_FORMATS.names())}; default from the suffix "
                   "(flexmor info --formats)")
    p.add_argument("--model", help="FE model the body was reduced from (required for sid and exudyn: the "
                   "inertia invariants integrate over its mass matrix)")
    p.add_argument("--model-format", help="override the format of --model chosen from its suffix")
    p.add_argument("--units", type=_unit_system("--units"), metavar="SYSTEM",
                   help="unit system of the --model file, converted to SI on reading (as --units of reduce); "
                        "default the one the body records")
    p.add_argument("--export-units", type=_unit_system("--export-units"), metavar="SYSTEM",
                   help="unit system of the file written: SI (default) or mm-t-s, mm-kg-ms, mm-g-ms, in-lbf-s "
                        "(sid, mat; the file states it)")
    p.add_argument("--mesh", metavar="FILE", help=_MESH_HELP + " (with --model)")
    p.add_argument("--node", action="append", default=[], metavar="NODE|SET",
                   help="SID frame node (node id, set, or coupling such as HOLE@rbe2: its master; a set gives an "
                   "RBE3 master); default the port nodes and the coupling masters")
    p.add_argument("--remove-rigid", action="store_true", help="sid/exudyn: export a body whose basis holds "
                   "rigid-body motion with its basis made mass-orthogonal to the rigid-body modes (another order "
                   "and error than the body judged; the error of what is written is stated); refused otherwise")
    p.add_argument("--allow-clamped", action="store_true", help="sid/exudyn: export a body of a supported "
                   "(clamped) model, whose mass properties miss the supported nodes (for a frame that does not move)")
    p.add_argument("--modal-form", action="store_true", help="write the body in its own modes (diagonal M and K; "
                   "rigid-body modes of a free body left out) and state the band error of the body written")
    p.add_argument("--max-frequency", type=float, metavar="HZ", help="modal form with the modes up to HZ only (and "
                   "the static response of the modes left out: see --no-static-vectors)")
    p.add_argument("--no-static-vectors", action="store_true", help="with --max-frequency or --select-modes: the "
                   "modes kept alone, without the static vectors that keep the static response of the modes left "
                   "out (under the inputs, the frame's accelerations and the interface loads)")
    p.add_argument("--select-modes", choices=["auto"], help="modal form with the fewest modes whose verified "
                   "error (--tol-measure, over --band) meets --tol, chosen by the response they carry")
    p.add_argument("--tol", type=float, help="the error --select-modes auto must meet")
    p.add_argument("--tol-measure", choices=TOL_MEASURES, default="band_error",
                   help="the error measure of --tol (default band_error)")
    p.add_argument("--band", metavar="FMIN:FMAX", help="band (Hz) of the errors of --modal-form (default the band "
                   "the body was reduced for)")
    p.add_argument("--m1-order", choices=["row-q-col", "row-col-q"], default="row-q-col",
                   help="index order of SID m1(i,j,k) entries (default row-q-col, as PY_SID/EMBS)")
    p.add_argument("--no-stiffening", action="store_true", help="SID without the load stiffening (the geometric "
                   "stiffness of unit frame accelerations, spin and node forces in the m1 of Ct Cr Oe phi psi)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_export)

    add_plan_parser(sub, add_model_args=_add_model_args, method_type=_method, methods=METHODS,
                    add_method_options=_add_method_options)
    add_ui_parser(sub)
    for p in sub.choices.values():  # each command maps the parameters named by library errors to its flags
        _add_verbose(p, default=argparse.SUPPRESS)  # -v also after the command (adds to one before it)
        _add_quiet_note(p)
        p.set_defaults(flag_names=flag_names(p))
    return ap


