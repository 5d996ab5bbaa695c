#!/usr/bin/env python
"""MBS in the loop, mounted: free bodies held at their interface in Exudyn against the full FE model.

A free body reduced with an interface coupling (``HOLE@rbe2``) is mounted in Exudyn the way an
MBS user mounts it: a rigid marker with the coupling master's motion
(:func:`flexmor.io.exudyn.add_marker`, a ``MarkerSuperElementRigid`` on the slaves at the
master's point) and a ``GenericJoint`` to the ground locking all six axes.

*Static* (gravity -z): the deflection of the output (the upper plate's corner; the beam's tip
set, its mean) of the mounted ``ObjectFFRFreducedOrder`` against the full FE model held at its
interface: a sparse static solve of the model **as read** without the slave nodes' DOFs
(the RBE2 ring held rigidly at a fixed master is exactly that), under the consistent gravity
load ``M g`` of the whole body. The table gives the relative error, the body's ``band_error``
from :func:`flexmor.workflow.reduce_and_judge` and, as *check*, the ``field_error`` of gravity z
with the interface clamped from flexmor's own mounted check in the same record (no MBS code).

*Transient* (a force step at the output, no gravity): the mounted reduced bodies against
Exudyn's full, unreduced ``ObjectFFRF`` of the same body
(:func:`flexmor.io.exudyn.add_full_to_exudyn`), held exactly: its floating frame fixed to the
ground (``constrain_rigid=False``: no reference conditions, the frame is held) and every
interface slave node's three coordinates fixed by ``CoordinateConstraint`` objects. The plate's
rigid lower plate (a 6-DOF master in the FE model, which Exudyn's 3-DOF mesh cannot hold) is an
Exudyn rigid body (the master's mass and rotary inertia) tied to each node of the rods' lower
faces by a ``SphericalJoint``: the RBE2 of ``plate_structure(lower='mass')`` on the solid
``plate_structure(lower='free')``. Both sides get the same stiffness-proportional damping
``beta K`` (reduced: ``beta Kr = V^T beta K V``). Error ``e(t) = |u(t) - u_full(t)| / max_t
|u_full|`` of the output's displacement vector, mean and maximum over time; CPU time of
``SolveDynamic`` (generalized-alpha, spectral radius 0.9).

Usage::

    python bench/mounted.py                              # static: beam8 + plate n=56; transient: beam8 + plate n=12
    python bench/mounted.py --static-n 20 --transient-n 8 --end-time 0.01 --out out.json

Each case runs in a fresh process (``--case``, hidden). Results: ``bench/results/mounted.json``.
``tests/test_mounted_mbs.py`` calls these functions on small models.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import time
import warnings

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from mbs_loop import dynamic_settings, errors  # noqa: E402 - Exudyn settings and errors of bench/mbs_loop.py
from solvers import spawn_case, write_results  # noqa: E402 - the child-process runner of bench/solvers.py

DEFAULT_OUT = HERE / "results" / "mounted.json"
BEAM8 = HERE.parent / "tests" / "data" / "calculix" / "beam8_free_mat.sti"
METHODS = ("craig-bampton", "krylov", "fw-sobt", "pod")
#: Orders of the issue on the plate structure, and on the CalculiX beam.
PLATE_ORDERS = {"craig-bampton": 40, "krylov": 45, "fw-sobt": 40, "pod": 40}
BEAM_ORDERS = {"craig-bampton": 16, "krylov": 16, "fw-sobt": 16, "pod": 16}
BAND = (1.0, 2000.0)
GRAVITY = (0.0, 0.0, -9.81)
DIRECTIONS = ("x", "y", "z", "rx", "ry", "rz")
#: The transient's ``max_error_late`` is the largest error from this time (s) on.
LATE = 1e-3


@dataclasses.dataclass
class Case:
    """A free FE model with an interface coupling, the output whose deflection is compared and the
    reduction's inputs (the six master directions and the output's z: collocated ports)."""

    name: str
    model: object  # FEModel as read
    spec: str  # interface coupling, e.g. HOLE@rbe2
    output: object  # node id or node set name
    inputs: list
    orders: dict
    solid: object = None  # the model of 3-DOF nodes for Exudyn's full ObjectFFRF (None: model)
    rigid: dict | None = None  # rigid body of the full Exudyn model: xyz, mass, inertia (3,), slaves

    @property
    def slaves(self) -> np.ndarray:
        from flexmor.couplings import parse_coupling

        name = parse_coupling(self.spec)[0].strip().upper()
        return np.asarray(self.model.node_sets[name])

    @property
    def output_nodes(self) -> np.ndarray:
        out = self.output
        return np.asarray(self.model.node_sets[out] if isinstance(out, str) else [int(out)])

    @property
    def key(self) -> str:
        return self.spec.replace(" ", "").upper()


def corner_node(model) -> int:
    """The node of the upper plate's face at its (+x, +y) corner."""
    top = np.asarray(model.node_sets["TOP"])
    return int(top[np.argmax(model.node_xyz(top) @ np.array([1.0, 1.0, 0.0]))])


def _inputs(spec: str, output) -> list:
    return [f"{spec}:{d}" for d in DIRECTIONS] + [f"{output}:z"]


def beam8(path=BEAM8) -> Case:
    """The free CalculiX beam (1 x 0.1 x 0.1 m steel, 99 nodes, 297 DOF), interface ``FIX@rbe2``
    (its face x = 0), output the tip face ``TIP`` (mean of its nine nodes)."""
    from flexmor.io import read

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = read(str(path))
    return Case("beam8", model, "FIX@rbe2", "TIP", _inputs("FIX@rbe2", "TIP"), dict(BEAM_ORDERS))


def plate(n: int, *, transient: bool = False) -> Case:
    """``plate_structure(n, lower='mass')``, interface ``HOLE@rbe2``, output the upper plate's corner.
    With ``transient``, also the solid alone (``lower='free'``) and the rigid lower plate that
    Exudyn's full body needs (:func:`lower_plate`)."""
    from flexmor.models import plate_structure

    model = plate_structure(n, lower="mass")
    corner = corner_node(model)
    case = Case(f"plate-n{n}", model, "HOLE@rbe2", corner, _inputs("HOLE@rbe2", corner), dict(PLATE_ORDERS))
    if transient:
        case.solid = plate_structure(n, lower="free")
        case.rigid = lower_plate(case.solid, model)
    return case


def lower_plate(solid, model) -> dict:
    """The rigid lower plate of ``model`` (``lower='mass'``) for the solid ``lower='free'``: tying the
    solid's ``BOTTOM`` nodes by an RBE2 to the ``LOWER`` master gives ``model`` up to a mass at the
    master, checked here to be the plate's mass and diagonal rotary inertia (nothing else)."""
    from flexmor.couplings import couple

    master = int(model.node_sets["LOWER"][0])
    xyz = model.node_xyz([master])[0]
    c = couple(solid, [f"BOTTOM@rbe2[{float(xyz[0])!r},{float(xyz[1])!r},{float(xyz[2])!r}]"])
    if not np.array_equal(c.model.dofs, model.dofs) or abs(c.model.K - model.K).max() > 1e-12 * abs(model.K).max():
        raise RuntimeError("the solid tied to the lower plate's master is not the plate structure")
    extra = (model.M - c.model.M).toarray()
    eqs = [model.dof_index(master, d) for d in range(1, 7)]
    block = extra[np.ix_(eqs, eqs)]
    extra[np.ix_(eqs, eqs)] = 0.0
    mass = float(block[0, 0])
    if np.abs(extra).max() > 1e-12 * mass or np.abs(block - np.diag(np.diag(block))).max() > 1e-12 * mass:
        raise RuntimeError("the lower plate's mass is not a diagonal mass at its master")
    return {"xyz": xyz, "mass": mass, "inertia": np.diag(block)[3:].copy(),
            "slaves": np.asarray(solid.node_sets["BOTTOM"])}


# -- the full model held at its interface ---------------------------------------------------
def gravity_load(model, gravity=GRAVITY) -> np.ndarray:
    """The consistent gravity load ``M g`` of the whole body (rotational DOFs: no acceleration)."""
    g = np.zeros(model.n_dof)
    for k in range(3):
        g[model.dofs[:, 1] == k + 1] = gravity[k]
    return np.asarray(model.M @ g)


def held_static(case: Case, load: np.ndarray) -> np.ndarray:
    """Static displacement of the model as read held at its interface (slave nodes' DOFs removed)."""
    from flexmor.linalg import factorize

    model = case.model
    keep = ~np.isin(model.dofs[:, 0], case.slaves)
    K = model.K.tocsr()[keep][:, keep]
    u = np.zeros(model.n_dof)
    u[keep] = factorize(K.tocsc(), positive=True).solve(load[keep])
    return u


def output_value(case: Case, u: np.ndarray, direction: int = 3) -> float:
    """Mean of ``u`` in ``direction`` (1..3) over the output's nodes."""
    m = case.model
    return float(u[np.isin(m.dofs[:, 0], case.output_nodes) & (m.dofs[:, 1] == direction)].mean())


# -- reduced bodies -----------------------------------------------------------------------------
def coupled_model(case: Case):
    """The model with its interface coupled, with 1 % modal damping over the band (the reduction's model)."""
    from flexmor.couplings import couple
    from flexmor.workflow import apply_damping

    c = couple(case.model, [case.spec])
    return apply_damping(c.model, modal_damping=0.01, band=BAND)


def reduce_body(case: Case, method: str, order: int, *, judge: bool = True, model=None):
    """The body of ``method`` at ``order`` on the coupled model, with ``couplings`` as the
    command line records it; returns ``(body, record)`` (``record`` of ``reduce_and_judge``, or
    ``{'seconds': ...}`` without ``judge``)."""
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce
    from flexmor.workflow import reduce_and_judge

    mc = coupled_model(case) if model is None else model
    ports = make_ports(mc, case.inputs)
    opts = {"interface": [case.spec]} if method == "craig-bampton" else {"rigid": "exclude"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if judge:
            red, rec = reduce_and_judge(mc, method, order, ports, band=BAND, **opts)
        else:
            if method != "craig-bampton":
                opts["band"] = BAND
            t0 = time.perf_counter()
            red = reduce(mc, method, order, ports, **opts)
            rec = {"seconds": time.perf_counter() - t0}
    red.couplings = [case.spec]
    return red, rec


def mount(mbs, body: dict, case: Case) -> int:
    """Hold ``body`` at its interface: the coupling's rigid marker and a GenericJoint to the ground
    locking all six axes at the master's point; returns the joint's object number."""
    import exudyn.itemInterface as eii

    from flexmor.io.exudyn import add_marker

    point = np.asarray(body["interfaces"][case.key]["xyz"], float)
    ground = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=mbs.AddObject(eii.ObjectGround()), localPosition=list(point)))
    return mbs.AddObject(eii.GenericJoint(markerNumbers=[ground, add_marker(mbs, body, case.model, case.spec)],
                                          constrainedAxes=[1] * 6))


def _sensor(mbs, marker):
    import exudyn as exu
    import exudyn.itemInterface as eii

    return mbs.AddSensor(eii.SensorMarker(markerNumber=marker, outputVariableType=exu.OutputVariableType.Position,
                                          storeInternal=True, writeToFile=False))


def _static_settings():
    import exudyn as exu

    sc = exu.SimulationSettings()
    sc.solution.file.write = False
    sc.staticSolver.verboseMode = 0
    sc.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    sc.staticSolver.newton.relativeTolerance = 1e-12
    sc.staticSolver.newton.absoluteTolerance = 1e-14
    return sc


def mounted_static(red, case: Case, gravity=GRAVITY) -> float:
    """z-deflection of the output of ``red`` mounted at its interface in Exudyn under ``gravity``."""
    import exudyn as exu

    from flexmor.io.exudyn import add_marker, add_to_exudyn

    mbs = exu.SystemContainer().AddSystem()
    body = add_to_exudyn(mbs, red, case.model, gravity=list(gravity))
    mount(mbs, body, case)
    sensor = _sensor(mbs, add_marker(mbs, body, case.model, case.output))
    mbs.Assemble()
    mbs.SolveStatic(_static_settings())
    x0 = case.model.node_xyz(case.output_nodes).mean(axis=0)
    return float(mbs.GetSensorValues(sensor)[2] - x0[2])


def static_rows(case: Case, *, judge: bool = True, methods=METHODS) -> dict:
    """Each method at its order mounted under gravity against the held full model."""
    import logging

    logging.getLogger("flexmor.io.exudyn").setLevel(logging.ERROR)  # the LOWER master's rotations: not in the mesh
    t0 = time.perf_counter()
    full = output_value(case, held_static(case, gravity_load(case.model)))
    out = {"case": case.name, "n_dof": case.model.n_dof, "full_m": full, "full_seconds": time.perf_counter() - t0,
           "rows": []}
    mc = coupled_model(case)
    for method in methods:
        red, rec = reduce_body(case, method, case.orders[method], judge=judge, model=mc)
        z = mounted_static(red, case)
        out["rows"].append({"method": method, "order": red.order, "mounted_m": z, "full_m": full,
                            "rel_error": abs(z - full) / abs(full), "band_error": rec.get("band_error"),
                            "check_field_error": _check_field_error(rec), "reduce_seconds": rec.get("seconds")})
    return out


def _check_field_error(rec: dict, load: str = "gravity:z"):
    """``field_error`` of ``load`` with the interface clamped in flexmor's own mounted check
    (:func:`flexmor.analysis.mounted.mounted_record`, ``rec['mounted']`` of ``reduce_and_judge``), or None."""
    for case in (rec.get("mounted") or {}).get("cases", []):
        if case["held"] == "clamped":
            return next((s["field_error"] for s in case["static"] if s["load"] == load), None)
    return None


# -- transient: force step at the output ----------------------------------------------------------
def _fix_coordinates(mbs, ground, node: int, coordinates) -> None:
    import exudyn.itemInterface as eii

    for c in coordinates:
        mbs.AddObject(eii.CoordinateConstraint(markerNumbers=[
            ground, mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=node, coordinate=c))]))


def add_held_full(mbs, case: Case, *, beta: float = 0.0, gravity=(0.0, 0.0, 0.0)) -> dict:
    """Exudyn's full ``ObjectFFRF`` of the case held at its interface: frame fixed to the ground
    (position and Euler parameters 1-3; the Euler-parameter constraint fixes the 0th), every slave
    node's coordinates fixed; the plate's rigid lower plate tied to the rods' lower faces."""
    import exudyn.itemInterface as eii

    from flexmor.io.exudyn import add_full_to_exudyn, add_marker

    solid = case.model if case.solid is None else case.solid
    body = add_full_to_exudyn(mbs, solid, constrain_rigid=False, rayleigh=(0.0, beta), gravity=list(gravity))
    ground = mbs.AddMarker(eii.MarkerNodeCoordinate(nodeNumber=mbs.AddNode(eii.NodePointGround()), coordinate=0))
    _fix_coordinates(mbs, ground, body["nRigidBody"], (0, 1, 2, 4, 5, 6))
    for k in case.slaves:
        _fix_coordinates(mbs, ground, body["nodeList"][body["node_index"][int(k)]], (0, 1, 2))
    if case.rigid is not None:
        r = case.rigid
        node = mbs.AddNode(eii.NodeRigidBodyEP(referenceCoordinates=list(r["xyz"]) + [1.0, 0.0, 0.0, 0.0]))
        plate_body = mbs.AddObject(eii.ObjectRigidBody(mass=r["mass"], nodeNumber=node,
                                                       inertia=list(r["inertia"]) + [0.0, 0.0, 0.0]))
        if np.any(gravity):
            mbs.AddLoad(eii.LoadMassProportional(markerNumber=mbs.AddMarker(eii.MarkerBodyMass(bodyNumber=plate_body)),
                                                 loadVector=list(gravity)))
        for k in r["slaves"]:
            at = mbs.AddMarker(eii.MarkerBodyPosition(bodyNumber=plate_body,
                                                      localPosition=list(solid.node_xyz([int(k)])[0] - r["xyz"])))
            mbs.AddObject(eii.SphericalJoint(markerNumbers=[at, add_marker(mbs, body, solid, int(k))]))
    return body


def full_static(case: Case, gravity=GRAVITY) -> float:
    """z-deflection of the output of the held full ``ObjectFFRF`` under gravity (a check of the
    transient's reference against :func:`held_static`)."""
    import exudyn as exu

    from flexmor.io.exudyn import add_marker

    mbs = exu.SystemContainer().AddSystem()
    body = add_held_full(mbs, case, gravity=gravity)
    sensor = _sensor(mbs, add_marker(mbs, body, case.model, case.output))
    mbs.Assemble()
    mbs.SolveStatic(_static_settings())
    x0 = case.model.node_xyz(case.output_nodes).mean(axis=0)
    return float(mbs.GetSensorValues(sensor)[2] - x0[2])


def step_response(case: Case, add_body, *, force, end_time: float, step: float):
    """Exudyn's response to a force step at the output (constant from t = 0): times, the output's
    displacement (k, 3) and the CPU time of ``SolveDynamic``. ``add_body(mbs)`` adds the held body
    and returns its dict."""
    import exudyn as exu
    import exudyn.itemInterface as eii

    from flexmor.io.exudyn import add_marker

    mbs = exu.SystemContainer().AddSystem()
    body = add_body(mbs)
    marker = add_marker(mbs, body, case.model, case.output)  # the solid has the model's node ids and sets
    mbs.AddLoad(eii.LoadForceVector(markerNumber=marker, loadVector=list(force)))
    sensor = _sensor(mbs, marker)
    mbs.Assemble()
    t0 = time.process_time()
    mbs.SolveDynamic(dynamic_settings(end_time, step))
    seconds = time.process_time() - t0
    data = mbs.GetSensorStoredData(sensor)
    return data[:, 0], data[:, 1:] - case.model.node_xyz(case.output_nodes).mean(axis=0), seconds


def transient_rows(case: Case, *, force=(0.0, 0.0, -1000.0), end_time: float = 0.03, step: float = 1e-4,
                   beta: float = 4e-5, methods=METHODS, bodies=None) -> dict:
    """The held full ObjectFFRF and each reduced body (``bodies``: method -> body, else reduced at the
    case's orders) under a force step at the output, damping ``beta K`` on both sides."""
    import logging

    logging.getLogger("flexmor.io.exudyn").setLevel(logging.ERROR)
    solid = case.model if case.solid is None else case.solid
    t, u_full, sec = step_response(case, lambda mbs: add_held_full(mbs, case, beta=beta), force=force,
                                   end_time=end_time, step=step)
    out = {"case": case.name, "n_dof": case.model.n_dof, "full_n_dof": solid.n_dof, "full_seconds": sec,
           "steps": int(t.size - 1), "step": step, "beta": beta, "force": list(force),
           "max_deflection_m": float(np.linalg.norm(u_full, axis=1).max()),
           "final_deflection_m": u_full[-1].tolist(), "rows": []}
    mc = coupled_model(case) if bodies is None else None
    for method in methods:
        red = bodies[method] if bodies is not None else reduce_body(case, method, case.orders[method], judge=False,
                                                                   model=mc)[0]
        _, u, sec = step_response(case, _mounted_body(case, red, beta), force=force, end_time=end_time, step=step)
        e = np.linalg.norm(u - u_full, axis=1)
        late = t >= LATE  # after the step's onset, where the full mesh answers the point force locally
        out["rows"].append({"method": method, "order": red.order, "seconds": sec, **errors(u, u_full),
                            "max_error_at_s": float(t[np.argmax(e)]),
                            "max_error_late": float(e[late].max() / np.linalg.norm(u_full, axis=1).max())
                            if late.any() else float("nan")})
    return out


def _mounted_body(case: Case, red, beta: float):
    """``add_body`` of :func:`step_response` for a reduced body: damping ``beta Kr`` (none for 0,
    not the body's own), mounted by :func:`mount`."""
    from flexmor.io.exudyn import add_to_exudyn

    def add(mbs):
        body = add_to_exudyn(mbs, red, case.model, rayleigh=(0.0, beta))
        if beta == 0.0:
            mbs.SetObjectParameter(body["oFFRFreducedOrder"], "dampingMatrixReduced", np.zeros((red.order, red.order)))
        mount(mbs, body, case)
        return body

    return add


# -- driver -------------------------------------------------------------------------------------
def _case(name: str, transient: bool) -> Case:
    return beam8() if name == "beam8" else plate(int(name.split("-n")[1]), transient=transient)


def run_case(spec: str, args) -> dict:
    """One case in this process: ``static:<case>`` or ``transient:<case>`` (``beam8``, ``plate-n<N>``)."""
    kind, name = spec.split(":", 1)
    case = _case(name, kind == "transient")
    methods = tuple(args.methods.split(","))
    if kind == "static":
        return {"kind": kind, **static_rows(case, judge=not args.no_judge, methods=methods)}
    res = transient_rows(case, force=(0.0, 0.0, -args.force), end_time=args.end_time, step=args.step, beta=args.beta,
                         methods=methods)
    return {"kind": kind, **res}


def print_static(res: dict) -> str:
    lines = [f"static, gravity -z: {res['case']} ({res['n_dof']} DOF), output deflection of the held full model "
             f"{res['full_m']:.6e} m",
             f"{'method':>14} {'order':>6} {'mounted m':>14} {'full m':>14} {'rel. error':>11} {'band_error':>11} "
             f"{'check':>9} {'reduce s':>9}"]
    for r in res["rows"]:
        be, ce = ("-" if v is None else f"{v:.2e}" for v in (r["band_error"], r["check_field_error"]))
        lines.append(f"{r['method']:>14} {r['order']:>6} {r['mounted_m']:>14.6e} {r['full_m']:>14.6e} "
                     f"{r['rel_error']:>11.2e} {be:>11} {ce:>9} {r['reduce_seconds']:>9.1f}")
    return "\n".join(lines)


def print_transient(res: dict) -> str:
    lines = [f"transient, force step {res['force'][2]:g} N z at the output: {res['case']} ({res['n_dof']} DOF; "
             f"full ObjectFFRF {res['full_n_dof']} DOF), {res['steps']} steps of {res['step']:g} s, damping "
             f"{res['beta']:g} K; full: {res['full_seconds']:.2f} cpu s, max deflection "
             f"{res['max_deflection_m']:.4g} m",
             f"{'method':>14} {'order':>6} {'mean error':>11} {'max error':>11} {'at s':>7} {'max t>=1ms':>11} "
             f"{'MBS cpu s':>10} {'speed-up':>9}"]
    for r in res["rows"]:
        lines.append(f"{r['method']:>14} {r['order']:>6} {r['mean_error']:>11.2e} {r['max_error']:>11.2e} "
                     f"{r['max_error_at_s']:>7.4f} {r['max_error_late']:>11.2e} {r['seconds']:>10.3f} "
                     f"{res['full_seconds'] / max(r['seconds'], 1e-9):>9.0f}")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--static-n", default="56", help="plate resolutions of the static table (default 56: 35,994 DOF)")
    p.add_argument("--transient-n", default="12", help="plate resolutions of the transient (default 12: 2,994 DOF)")
    p.add_argument("--no-beam", action="store_true", help="leave out the CalculiX beam")
    p.add_argument("--methods", default=",".join(METHODS), help="reduction methods (default all four)")
    p.add_argument("--no-judge", action="store_true", help="static table without band_error (no full FRF)")
    p.add_argument("--force", type=float, default=1000.0, help="force step in N, along -z (default 1000)")
    p.add_argument("--end-time", type=float, default=0.03, help="simulated time in s (default 0.03)")
    p.add_argument("--step", type=float, default=1e-4, help="time step in s (default 1e-4)")
    p.add_argument("--beta", type=float, default=4e-5,
                   help="stiffness-proportional damping beta K on both sides, s (default 4e-5: 1 %% at 80 Hz)")
    p.add_argument("--timeout", type=float, default=7200.0, help="seconds per case (default 7200)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help=f"JSON output (default {DEFAULT_OUT})")
    p.add_argument("--case", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    options = ["--methods", args.methods, "--force", str(args.force), "--end-time", str(args.end_time),
               "--step", str(args.step), "--beta", str(args.beta)] + (["--no-judge"] if args.no_judge else [])
    if args.case:
        print(json.dumps(run_case(args.case, args)))
        return 0
    beam = [] if args.no_beam else ["beam8"]
    cases = ([f"static:{c}" for c in beam + [f"plate-n{n}" for n in args.static_n.split(",") if n.strip()]]
             + [f"transient:{c}" for c in beam + [f"plate-n{n}" for n in args.transient_n.split(",") if n.strip()]])
    results, tables = [], []
    for spec in cases:
        print(f"# running {spec} ...", file=sys.stderr, flush=True)
        res = spawn_case(__file__, spec, options, args.timeout, {"case": spec})
        results.append(res)
        if "error" in res:
            tables.append(f"{spec}: {res['error']}")
        else:
            tables.append(print_static(res) if res["kind"] == "static" else print_transient(res))
        print(tables[-1] + "\n", flush=True)
    write_results(args.out, {"args": {k: v for k, v in vars(args).items() if k != "case"}, "results": results,
                             "tables": tables})
    return 0


if __name__ == "__main__":
    sys.exit(main())
