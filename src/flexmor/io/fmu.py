"""Export of a reduced body as an FMI 2.0 functional mock-up unit (``.fmu``).

One FMU for model exchange and co-simulation: the body's first-order state space
(:func:`flexmor.io.statespace.state_space`, damping included)

    x' = A x + B u,   y = C x + D u,   v = C x',   x = [q; q'],

as constant arrays (``%.17g``, the doubles as they are) in generated C, compiled at export time
by the system C compiler into ``binaries/linux64/<id>.so`` (``darwin64/<id>.dylib`` on macOS);
the C source is in ``sources/`` too, for other platforms. ``modelDescription.xml`` declares

* one input per input port, the force (``N``) or moment (``N.m``) of the port, named after its
  SPEC made into an identifier (``TIP:y`` -> ``TIP_y``; the SPEC is its description);
* per output port its displacement ``u_<port>`` (``m`` or ``rad``) and its velocity
  ``v_<port>`` (``m/s``, ``rad/s``), the ``C x'`` part (``C B = 0`` for a second-order body,
  so no output feeds through from an input: no algebraic loop when the outputs are fed back);
* the generalized coordinates ``q[i]`` and their rates ``qd[i]`` as continuous states (start
  0, settable before initialization), their derivatives ``der(q[i])``, ``der(qd[i])``, and as
  their nominal values the peak of each under a unit step on any input, the scale an
  integrator's absolute tolerance needs (the states are small numbers in SI units);
* the model structure with the sparsity of ``A``, ``B``, ``C`` as dependencies;
* for a body reduced over a speed range (``reduce --spin-range``, :mod:`flexmor.spin`) the last input
  ``omega`` (``rad/s``): ``A(w) = A + w A1 + w^2 A2`` with the body's ``K + w^2 K2`` and Coriolis matrix
  ``w G1`` (in the frame turning with it); the co-simulation step's exponential is computed again when
  the speed changes;
* for a body reduced with moving loads (``reduce --moving-load SET:DIR``, :mod:`flexmor.moving`) two more inputs
  per path, after those, ``F_<SET>`` (``N``, the force in the load's direction) and ``s_<SET>`` (``m``, the load's
  position: arc length along the path from its first node), and one more output per path, after the
  velocities, ``w_<SET>`` (``m``), the deflection under the load ``w(s)ᵀ B_pathᵀ q``. The load's generalized
  force ``B_path w(s) F`` (``B_path`` the body's ``V^T B_path``, ``w(s)`` the linear interpolation between the
  two path nodes of the segment ``s`` lies on, found by bisection of the nodes' arc lengths; no force off the
  path) joins the body's input each step. The compressed inputs the body was reduced with (``SET:DIR~1`` ...)
  stay inputs and outputs of their own.

The units declared are SI (N, m, rad, s): the numbers of the body are taken as SI, as the other
exports write them.

**Co-simulation step.** The inputs are held over a communication step (FMI 2.0 without input
derivatives), and over such a step the linear system has the exact solution
``x(t+h) = Φ(h) x(t) + Γ(h) u`` with ``[[Φ, Γ], [0, I]] = expm([[A, B], [0, 0]] h)``
(zero-order hold). The FMU computes that matrix exponential when the step size changes (for a
fixed step, once): balancing (Parlett-Reinsch, powers of 2), scaling and squaring, the
diagonal Padé approximant of degree 6 (truncation error below 1e-15 relative on the scaled
matrix). So ``doStep`` has neither a step-size nor a stability limit whatever the body's highest
mode (modes at tens of kHz do not shrink the step), and it is exact up to round-off for inputs
held over the step: it agrees with SciPy's ``expm`` to about 1e-11 of the peak response even
for a step as long as 70 periods of the highest mode. A master whose inputs vary within a
step sees the usual error of sampled inputs. A moving load's force and position held over a step
give a constant generalized force, so its step is exact too (a load moving at a speed ``c`` is taken where
it stood at the step's start, up to ``c h`` behind). The cost is ``O((n+m)³)`` once per step
size (``n + m + r`` with moving loads) and ``O(n (n+m))`` per step. For model exchange the importer's
integrator solves the same equations; the states' nominal values scale its absolute tolerance.

References
----------
Modelica Association, *Functional Mock-up Interface for Model Exchange and Co-Simulation*,
version 2.0, 2014 (2.0.4, 2022).

N. J. Higham, *Functions of Matrices*, SIAM, 2008, ch. 10 (scaling and squaring).
"""

from __future__ import annotations

import errno
import hashlib
import os
import platform
import re
import shlex
import shutil
import signal
import subprocess
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import scipy.linalg as sla

from .._version import __version__
from ..errors import FlexmorError, ModelError
from ..model import DIRECTIONS
from ._registry import EXPORT_FORMATS
from .atomic import atomic_write, write_failure
from .statespace import state_space

__all__ = ["FMUVariables", "find_compiler", "fmu_source", "fmu_variables", "model_description", "write_fmu"]

_RUNTIME = Path(__file__).with_name("fmu_runtime.c")
_UNITS = {  # name: SI base-unit exponents
    "N": {"kg": 1, "m": 1, "s": -2}, "N.m": {"kg": 1, "m": 2, "s": -2},
    "m": {"m": 1}, "rad": {"rad": 1}, "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1},
}


def find_compiler() -> list[str]:
    """The C compiler command: ``CC`` (split like a shell word list) when set, else ``cc`` or ``gcc``.

    Returns
    -------
    list of str
        The command with the compiler's full path first.

    Raises
    ------
    FlexmorError
        When ``CC`` names no program, or when no ``cc``/``gcc`` is on the ``PATH``.
    """
    cc = os.environ.get("CC", "").strip()
    if cc:
        try:
            words = shlex.split(cc)
        except ValueError as exc:
            raise FlexmorError(f"the C compiler CC={cc!r} is not a command ({exc})") from None
        found = shutil.which(words[0]) if words else None
        if found is None:
            raise FlexmorError(f"the C compiler CC={cc!r} is not found; an FMU is compiled at export time: set CC to "
                               "a C compiler or install one (Debian/Ubuntu: apt-get install gcc)")
        return [found, *words[1:]]
    for name in ("cc", "gcc"):
        found = shutil.which(name)
        if found is not None:
            return [found]
    raise FlexmorError("no C compiler found (cc or gcc on the PATH, or CC); an FMU is compiled at export time: "
                       "install one (Debian/Ubuntu: apt-get install gcc) or set CC to a C compiler")


def _platform() -> tuple[str, str]:
    """``(folder, suffix)`` of the FMU binary for this machine (``("linux64", ".so")``)."""
    system, bits = platform.system(), platform.architecture()[0]
    if bits == "64bit" and system == "Linux":
        return "linux64", ".so"
    if bits == "64bit" and system == "Darwin":
        return "darwin64", ".dylib"
    raise FlexmorError(f"an FMU is compiled for this machine; FMI 2.0 binaries are built here for 64-bit Linux "
                       f"and macOS, not {system} {bits}")


def _identifier(text: str, fallback: str) -> str:
    """``text`` as a C / Modelica identifier: other characters become ``_``; ``n`` before a digit."""
    name = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "_", str(text))).strip("_")
    if not name:
        return fallback
    return "n" + name if name[0].isdigit() else name


def _direction(spec: str) -> int | None:
    """The direction code 1..6 of a port SPEC (``TIP:ry`` -> 5), None for a name without one."""
    head, sep, d = str(spec).rpartition(":")
    return DIRECTIONS.get(d.strip().lower()) if sep and head else None


class FMUVariables:
    """The FMU's variables, in the order of ``modelDescription.xml`` (value reference = position).

    Attributes
    ----------
    inputs, displacements, velocities : list of str
        The variable names of the input forces and of the output displacements and velocities.
    states : list of str
        ``q[1] ... q[r], qd[1] ... qd[r]``.
    loads, positions, under_load : list of str
        Per moving load: the names of its force and position inputs and of its deflection output.
    rows : list of dict
        One per variable: ``name``, ``causality``, ``description``, ``unit`` (or None) and, for a
        state derivative, ``derivative`` (the 1-based index of its state).
    """

    def __init__(self, input_names, output_names, r: int, spin: str | None = None, moving=()):
        taken: set = set()

        def unique(name):
            base, k = name, 2
            while name in taken:
                name, k = f"{base}_{k}", k + 1
            taken.add(name)
            return name

        m, p = len(input_names), len(output_names)
        ins = [str(s) for s in input_names]
        outs = [str(s) for s in output_names]
        self.inputs = [unique(_identifier(s, f"F{i + 1}")) for i, s in enumerate(ins)]
        ports = [_identifier(s, f"y{k + 1}") for k, s in enumerate(outs)]
        self.displacements = [unique(f"u_{s}") for s in ports]
        self.velocities = [unique(f"v_{s}") for s in ports]
        self.states = [f"q[{i + 1}]" for i in range(r)] + [f"qd[{i + 1}]" for i in range(r)]
        rows = []
        for spec, name in zip(ins, self.inputs):
            d = _direction(spec)
            rows.append(dict(name=name, causality="input", unit=None if d is None else ("N.m" if d > 3 else "N"),
                             description=f"{'moment' if d and d > 3 else 'force'} at the input port {spec}"))
        if spin is not None:  # the last input: the speed of a body over a speed range
            self.inputs.append(unique("omega"))
            rows.append(dict(name=self.inputs[-1], causality="input", unit="rad/s",
                             description=f"angular velocity about the spin axis of the body ({spin} rad/s): its "
                                         "stiffness K + w^2 K2 and Coriolis matrix w G1"))
            m += 1
        self.loads, self.positions, self.under_load = [], [], []
        for load in moving:  # per moving load: its force and position, after the other inputs
            what = f"the moving load {load['spec']} (direction {load['direction']})"
            self.loads.append(unique(_identifier(f"F_{load['set']}", "F_load")))
            self.positions.append(unique(_identifier(f"s_{load['set']}", "s_load")))
            self.inputs += [self.loads[-1], self.positions[-1]]
            rows.append(dict(name=self.loads[-1], causality="input", unit="N",
                             description=f"force of {what} at {self.positions[-1]}"))
            rows.append(dict(name=self.positions[-1], causality="input", unit="m",
                             description=f"position of {what}: arc length along its path from node "
                                         f"{load['first']} (0 to {load['length']:.6g} m; no force off the path)"))
            m += 2
        for spec, name in zip(outs, self.displacements):
            d = _direction(spec)
            rows.append(dict(name=name, causality="output", unit=None if d is None else ("rad" if d > 3 else "m"),
                             description=f"displacement at the output port {spec}"))
        for spec, name in zip(outs, self.velocities):
            d = _direction(spec)
            rows.append(dict(name=name, causality="output", unit=None if d is None else ("rad/s" if d > 3 else "m/s"),
                             description=f"velocity at the output port {spec}"))
        for load in moving:  # per moving load: the deflection under it, after the velocities
            self.under_load.append(unique(_identifier(f"w_{load['set']}", "w_load")))
            rows.append(dict(name=self.under_load[-1], causality="output", unit="m",
                             description=f"deflection under the moving load {load['spec']} (direction "
                                         f"{load['direction']}) at its position"))
        for i, name in enumerate(self.states):
            what = "generalized coordinate" if i < r else f"rate of the generalized coordinate q[{i - r + 1}]"
            rows.append(dict(name=name, causality="local", unit=None, description=what))
        first = m + 2 * p + len(self.under_load)  # 0-based position of q[1]
        for i, name in enumerate(self.states):
            rows.append(dict(name=f"der({name})", causality="local", unit=None, derivative=first + i + 1,
                             description=f"time derivative of {name}"))
        self.rows = rows


def fmu_variables(body) -> FMUVariables:
    """The FMU variables of ``body`` (:class:`FMUVariables`): its port SPECs made into names
    (``F1 F2 ...`` and ``u_y1 ...`` for a body without one name per input and output)."""
    m, p = np.shape(body.B)[1], np.shape(body.C)[0]
    ins, outs = list(body.input_names or []), list(body.output_names or [])
    spin = body.info.get("spin") if isinstance(body.info, dict) else None
    return FMUVariables(ins if len(ins) == m else [""] * m, outs if len(outs) == p else [""] * p, body.order,
                        spin=spin["spec"] if spin else None, moving=_moving_loads(body))


def _moving_loads(body) -> list[dict]:
    """The body's moving loads (``body.info['moving_loads']``, :func:`flexmor.moving.path_record`): per path
    ``spec``, ``set``, ``direction``, ``first`` (its first node), ``length``, ``s`` (N,) and ``B`` (r, N)."""
    records = body.info.get("moving_loads") if isinstance(body.info, dict) else None
    out = []
    for rec in records or ():
        s, B = np.asarray(rec["s"], float), np.asarray(rec["B_path"], float)
        if s.ndim != 1 or s.size < 2 or B.shape != (body.order, s.size) or not np.all(np.diff(s) > 0):
            raise ModelError(f"the moving load {rec.get('spec')!r} of the body has no path of 2 or more nodes at "
                             f"increasing arc lengths with one reduced input each (B_path {B.shape}, "
                             f"{s.size} arc lengths, order {body.order}); no FMU")
        out.append(dict(spec=str(rec["spec"]), set=str(rec["set"]), direction=str(rec["direction"]),
                        first=int(rec["nodes"][0]), length=float(s[-1]), s=s, B=B))
    return out


def _spin_state_space(body):
    """``(ss, A1, A2)``: the body's state space with the speed as an input after the ports' (a zero column of
    ``B`` and ``D``) and the coefficients of ``A(w) = A + w A1 + w^2 A2`` (None, None for a body without spin);
    then each moving load's force and position (two zero columns each: their generalized force, which is not
    linear in them, is added by the FMU itself, :func:`_path_input`)."""
    import dataclasses

    ss = state_space(body)
    spin = body.info.get("spin") if isinstance(body.info, dict) else None
    r = body.order
    extra = (1 if spin else 0) + 2 * len(_moving_loads(body))
    if extra and ss.A.shape[0] != 2 * r:
        raise ModelError("a body over a speed range or with a moving load needs its second-order state space "
                         "[q; q'] for its FMU")
    if extra:
        ss = dataclasses.replace(ss, B=np.hstack([ss.B, np.zeros((ss.B.shape[0], extra))]),
                                 D=np.hstack([ss.D, np.zeros((ss.D.shape[0], extra))]))
    if not spin:
        return ss, None, None
    M = np.asarray(body.M, float)
    K2, G1 = np.asarray(spin["K2"], float), np.asarray(spin["G1"], float)
    lu = sla.cho_factor(0.5 * (M + M.T))
    A1, A2 = np.zeros_like(ss.A), np.zeros_like(ss.A)
    A1[r:, r:] = -sla.cho_solve(lu, G1)
    A2[r:, :r] = -sla.cho_solve(lu, K2)
    return ss, A1, A2


def _path_input(body) -> np.ndarray:
    """``G = [0; M^-1]`` (2r, r): the state-space input of a generalized force (a moving load's ``B_path w F``)."""
    M = np.asarray(body.M, float)
    r = M.shape[0]
    return np.vstack([np.zeros((r, r)), sla.cho_solve(sla.cho_factor(0.5 * (M + M.T)), np.eye(r))])


def _nominals(body) -> np.ndarray:
    """The scale of each state ``[q; q']``: its peak under a unit step on any one input (a unit force at a
    moving load's path node among them).

    Per mode of ``(Kr, Mr)`` (mass-normalized shapes ``φ``, ``b = φᵀ Br``): ``2 |b| / ω²`` and
    ``|b| / ω`` for an elastic mode (the undamped step response), ``|b| / 2`` and ``|b|`` after
    1 s for a rigid one; summed in absolute value over the modes. A state no input reaches
    takes the smallest scale of the others.
    """
    M, K, B = np.asarray(body.M, float), np.asarray(body.K, float), np.asarray(body.B, float)
    B = np.hstack([B, *(load["B"] for load in _moving_loads(body))])
    r = M.shape[0]
    if B.shape[1] == 0:
        return np.ones(2 * r)
    w2, phi = sla.eigh((K + K.T) / 2, (M + M.T) / 2)
    w = np.sqrt(np.clip(w2, 0.0, None))
    b = np.abs(phi.T @ B)
    rigid = w <= 1e-4 * max(w.max(), np.finfo(float).tiny)
    ws = np.where(rigid, 1.0, w)
    disp = np.where(rigid[:, None], b / 2, 2 * b / ws[:, None] ** 2)
    rate = np.where(rigid[:, None], b, b / ws[:, None])
    nominal = np.concatenate([(np.abs(phi) @ disp).max(axis=1), (np.abs(phi) @ rate).max(axis=1)])
    for part in (slice(0, r), slice(r, 2 * r)):
        x = nominal[part]
        ok = np.isfinite(x) & (x > 0)
        x[~ok] = x[ok].min() if ok.any() else 1.0
    return nominal


def _c_array(name: str, values, size: str) -> str:
    values = np.asarray(values, float).ravel()
    if not np.all(np.isfinite(values)):
        raise ModelError(f"the state-space matrix {name} of the body has NaN or Inf entries; no FMU")
    if values.size == 0:
        return f"static const double {name}[{size}] = {{0.0}};\n"
    rows = [", ".join(f"{float(v):.17g}" for v in values[i:i + 6]) for i in range(0, values.size, 6)]
    return f"static const double {name}[{size}] = {{\n    " + ",\n    ".join(rows) + "\n};\n"


def fmu_source(body, guid: str) -> str:
    """The C source of the FMU of ``body`` (FMI 2.0, model exchange and co-simulation).

    Parameters
    ----------
    body : ReducedModel
    guid : str
        The ``guid`` of its ``modelDescription.xml``; ``fmi2Instantiate`` refuses another.

    Returns
    -------
    str
        C99 without other headers than the C library's: the FMI 2.0 declarations it needs are in it.
    """
    ss, A1, A2 = _spin_state_space(body)
    loads = _moving_loads(body)
    n, m, p = ss.A.shape[0], ss.B.shape[1], ss.C.shape[0]
    ports = np.shape(body.B)[1]
    head = [f"/* FMI 2.0 model exchange and co-simulation of the reduced body {body.model_name or ''} "
            f"({body.method or 'body'}, order {body.order}), written by flexmor {__version__}.",
            "   x' = A x + B u, y = C x + D u (displacements), v = C x' (velocities); x = [q; q']. */",
            "#include <math.h>", "#include <stddef.h>", "#include <string.h>", "",
            f"#define NX {n}", f"#define NU {m}", f"#define NY {p}", f'#define GUID "{guid}"', ""]
    if A1 is not None:
        head += [f"#define SPIN_U {ports}", ""]
    if loads:  # path k: force input MOVING_U + 2 k, position MOVING_U + 2 k + 1; nodes PATH_AT[k] ... of PATH_S
        head += [f"#define MOVING {len(loads)}", f"#define MOVING_U {ports + (A1 is not None)}",
                 f"#define NG {body.order}", f"#define NPATH {sum(load['s'].size for load in loads)}", ""]
    arrays = (_c_array("A", ss.A, "NX * NX") + _c_array("B", ss.B, "NX * (NU > 0 ? NU : 1)")
              + _c_array("C", ss.C, "(NY > 0 ? NY : 1) * NX")
              + _c_array("D", ss.D, "(NY > 0 ? NY : 1) * (NU > 0 ? NU : 1)")
              + _c_array("NOMINAL", _nominals(body), "NX"))
    if A1 is not None:
        arrays += _c_array("A1", A1, "NX * NX") + _c_array("A2", A2, "NX * NX")
    if loads:  # PATH_B: per path node (in path order) its column of the body's V^T B_path
        at = np.cumsum([0] + [load["s"].size for load in loads])
        arrays += (f"static const int PATH_N[MOVING] = {{{', '.join(str(load['s'].size) for load in loads)}}};\n"
                   f"static const int PATH_AT[MOVING] = {{{', '.join(str(int(k)) for k in at[:-1])}}};\n"
                   + _c_array("PATH_S", np.concatenate([load["s"] for load in loads]), "NPATH")
                   + _c_array("PATH_B", np.hstack([load["B"] for load in loads]).T, "NPATH * NG")
                   + _c_array("G", _path_input(body), "NX * NG"))
    return "\n".join(head) + arrays + "\n" + _RUNTIME.read_text()


def _pattern(X) -> np.ndarray:
    return np.asarray(X) != 0


def _deps(row, offset: int) -> list[int]:
    return [offset + int(j) + 1 for j in np.flatnonzero(row)]


def model_description(body, identifier: str, guid: str, *, sources=()) -> str:
    """The ``modelDescription.xml`` of the FMU of ``body`` (see the module docstring).

    Parameters
    ----------
    body : ReducedModel
    identifier : str
        The ``modelIdentifier`` (a C identifier, the name of the binary).
    guid : str
    sources : sequence of str
        The files of ``sources/``, listed for both interfaces.
    """
    ss, A1, A2 = _spin_state_space(body)
    var = fmu_variables(body)
    loads = _moving_loads(body)
    m, p = ss.B.shape[1], ss.C.shape[0]
    vrs = {row["name"]: k for k, row in enumerate(var.rows)}
    first_state = m + 2 * p + len(loads)
    nominal = _nominals(body)
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(body.model_name or identifier)} '
             f'guid="{guid}" description={quoteattr(_describe(body))} generationTool="flexmor {__version__}" '
             f'variableNamingConvention="structured" numberOfEventIndicators="0">']
    files = "".join(f'<File name={quoteattr(s)}/>' for s in sources)
    files = f"<SourceFiles>{files}</SourceFiles>" if files else ""
    lines.append(f'  <ModelExchange modelIdentifier="{identifier}" completedIntegratorStepNotNeeded="true" '
                 f'canGetAndSetFMUstate="true" canSerializeFMUstate="true">{files}</ModelExchange>')
    lines.append(f'  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true" '
                 f'canGetAndSetFMUstate="true" canSerializeFMUstate="true">{files}</CoSimulation>')
    units = sorted({row["unit"] for row in var.rows if row["unit"]})
    if units:
        lines.append("  <UnitDefinitions>")
        for u in units:
            base = " ".join(f'{k}="{v}"' for k, v in _UNITS[u].items())
            lines.append(f'    <Unit name="{escape(u)}"><BaseUnit {base}/></Unit>')
        lines.append("  </UnitDefinitions>")
    lines.append('  <LogCategories><Category name="logStatusError" description="errors"/></LogCategories>')
    lines.append(_default_experiment(body))
    lines.append("  <ModelVariables>")
    for vr, row in enumerate(var.rows):
        attrs = ""
        if row["causality"] == "input":
            attrs, real = ' causality="input" variability="continuous"', 'start="0"'
        elif row["causality"] == "output":
            attrs, real = ' causality="output" variability="continuous" initial="calculated"', ""
        elif "derivative" in row:
            attrs, real = ' causality="local" variability="continuous" initial="calculated"', \
                f'derivative="{row["derivative"]}"'
        else:
            attrs = ' causality="local" variability="continuous" initial="exact"'
            real = f'start="0" nominal="{nominal[vr - first_state]:.6g}"'
        real = " ".join(([f'unit="{escape(row["unit"])}"'] if row["unit"] else []) + ([real] if real else []))
        lines.append(f'    <ScalarVariable name={quoteattr(row["name"])} valueReference="{vr}"{attrs} '
                     f'description={quoteattr(row["description"])}><Real{" " if real else ""}{real}/>'
                     '</ScalarVariable>')
    lines.append("  </ModelVariables>")
    # dependencies: indices (1-based) of the inputs and the states each unknown depends on
    pA, pB, pC, pD = _pattern(ss.A), _pattern(ss.B), _pattern(ss.C), _pattern(ss.D)
    if A1 is not None:  # A(w): the speed acts where A1 or A2 does, on the states they couple
        pA = pA | _pattern(A1) | _pattern(A2)
        pB[:, np.shape(body.B)[1]] = (_pattern(A1) | _pattern(A2)).any(axis=1)

    def deps(on_inputs, on_states):
        return " ".join(map(str, _deps(on_inputs, 0) + _deps(on_states, first_state)))

    under = []  # per moving load: the deflection under it depends on its position and the q it reads
    G = _pattern(_path_input(body)) if loads else None
    for k, load in enumerate(loads):
        at = vrs[var.loads[k]]  # its force; at + 1 its position
        pB[:, at] = pB[:, at + 1] = (G.astype(int) @ _pattern(load["B"]).astype(int)).any(axis=1)
        on_q = np.concatenate([_pattern(load["B"]).any(axis=1), np.zeros(body.order, bool)])
        under.append((vrs[var.under_load[k]] + 1, deps(np.arange(m) == at + 1, on_q)))
    pCA, pCB = (pC.astype(int) @ pA.astype(int)) > 0, (pC.astype(int) @ pB.astype(int)) > 0
    outputs = [(m + k + 1, deps(pD[k], pC[k])) for k in range(p)]
    outputs += [(m + p + k + 1, deps(pCB[k], pCA[k])) for k in range(p)] + under
    derivs = [(vrs[f"der({s})"] + 1, deps(pB[i], pA[i])) for i, s in enumerate(var.states)]
    lines.append("  <ModelStructure>")
    for tag, items in (("Outputs", outputs), ("Derivatives", derivs), ("InitialUnknowns", outputs + derivs)):
        if items:
            lines.append(f"    <{tag}>")
            lines += [f'      <Unknown index="{i}" dependencies="{d}"/>' for i, d in sorted(items)]
            lines.append(f"    </{tag}>")
    lines.append("  </ModelStructure>")
    lines.append("</fmiModelDescription>")
    return "\n".join(lines) + "\n"


def _describe(body) -> str:
    moving = ("; a moving load's force and position in, the deflection under it out" if _moving_loads(body)
              else "")
    return (f"reduced elastic body {body.model_name or ''} ({body.method or 'body'}, order {body.order}): "
            f"port forces in, port displacements and velocities out{moving}").replace("  ", " ")


def _default_experiment(body) -> str:
    """Ten periods of the lowest elastic mode, 20 steps per period (no stop time and step for a body
    without an elastic mode)."""
    try:
        f = np.asarray(body.frequencies_hz(), float)
    except FlexmorError:
        f = np.array([])
    f = f[np.isfinite(f)]
    f = f[f > 1e-4 * f.max()] if f.size and f.max() > 0 else f[:0]
    if f.size == 0:
        return '  <DefaultExperiment startTime="0" tolerance="1e-06"/>'
    return (f'  <DefaultExperiment startTime="0" stopTime="{10 / f.min():.6g}" tolerance="1e-06" '
            f'stepSize="{1 / (20 * f.min()):.6g}"/>')


#: the errors of a write that found no room, which a compiler reports in its messages
_SHORT_OF_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


def _compile(cc: list[str], source: str, folder: Path, identifier: str, suffix: str) -> Path:
    src = folder / f"{identifier}.c"
    try:
        src.write_text(source)
    except OSError as exc:  # the scratch folder: a full disk or the file-size limit
        raise write_failure(src, exc) from None
    out = folder / f"{identifier}{suffix}"
    cmd = [*cc, "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-o", str(out), str(src), "-lm"]
    try:  # SIGXFSZ stays ignored: at the file-size limit the compiler's writes fail and it says so (in the C locale)
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, restore_signals=False,
                             env={**os.environ, "LC_ALL": "C"})
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise FlexmorError(f"the C compiler {cc[0]} could not build the FMU: {exc}") from None
    if run.returncode != 0 or not out.exists():
        said = run.stderr + run.stdout
        short = next((e for e in _SHORT_OF_ROOM if os.strerror(e) in said), None)
        if short is None and signal.strsignal(signal.SIGXFSZ) in said:  # a compiler that restores the signal
            short = errno.EFBIG
        if short is not None:  # the compiler's files (the binary, its scratch files) did not fit
            raise write_failure(out, OSError(short, os.strerror(short))) from None
        tail = "\n".join((run.stderr or run.stdout).strip().splitlines()[-12:])
        raise FlexmorError(f"the C compiler {cc[0]} could not build the FMU (exit {run.returncode}):\n{tail}")
    return out


def write_fmu(body, path, *, model=None) -> None:
    """Write ``body`` as an FMI 2.0 FMU for model exchange and co-simulation, atomically.

    The binary is compiled for this machine by the system C compiler (:func:`find_compiler`).

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
        The ``.fmu`` file; its name (made an identifier) is the ``modelIdentifier``.
    model : FEModel, optional
        Unused (the state space is the body's own).

    Raises
    ------
    FlexmorError
        No C compiler (naming ``CC`` and what to install), or the compilation failed.
    ModelError
        A body without a state-space form (mass matrix not positive definite).
    """
    path = Path(path)
    cc = find_compiler()
    folder, suffix = _platform()
    stem = path.name[:-4] if path.name.lower().endswith(".fmu") else path.stem
    identifier = _identifier(stem, "body")
    source_hash = hashlib.sha256()
    ss, A1, A2 = _spin_state_space(body)
    paths = [X for load in _moving_loads(body) for X in (load["s"], load["B"])]
    for X in (ss.A, ss.B, ss.C, ss.D, *(() if A1 is None else (A1, A2)), *paths):
        source_hash.update(np.ascontiguousarray(X, float).tobytes())
    names = [identifier, *body.input_names, *body.output_names, *(load["spec"] for load in _moving_loads(body))]
    source_hash.update("\x00".join(map(str, names)).encode())
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "flexmor:" + source_hash.hexdigest())) + "}"
    source = fmu_source(body, guid)
    xml = model_description(body, identifier, guid, sources=[f"{identifier}.c"])
    with tempfile.TemporaryDirectory(prefix="flexmor-fmu-") as tmp:
        binary = _compile(cc, source, Path(tmp), identifier, suffix).read_bytes()

    def write(tmp_path):
        with zipfile.ZipFile(tmp_path, "w", zipfile.ZIP_DEFLATED) as zf:
            for name, data in (("modelDescription.xml", xml.encode()),
                               (f"binaries/{folder}/{identifier}{suffix}", binary),
                               (f"sources/{identifier}.c", source.encode())):
                info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                zf.writestr(info, data)

    atomic_write(path, write)


EXPORT_FORMATS.register("fmu", [".fmu"], write_fmu,
                        description="FMI 2.0 FMU (model exchange and co-simulation) of the body's state space, "
                                    "compiled by the system C compiler")
