"""A body reduced with a moving load, exported so that the multibody code can move the load.

Body: the steel cantilever 1 x 0.1 x 0.1 m (40 x 2 x 2 cells, clamped at x = 0), its top centre line as the
path of a vertical force (``PATH:z@x``, 41 nodes), Krylov order 40 (its path maximum band error 3e-6).
The ``.h5`` body, the ``.mat`` file and the Exudyn data keep the path; in Exudyn (frame fixed to the ground,
Newmark's average acceleration as flexmor integrates) a 1 kN force crossing the path by the user function of
:mod:`flexmor.io.exudyn_moving` deflects the beam under it as the full model does (:func:`flexmor.moving.crossing`),
within the body's own error; on a floating frame its frame share pushes and turns the frame as Exudyn's own
load on the path nodes does.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.io

from flexmor.damping import Rayleigh
from flexmor.io.matlab.matlab_export import write_mat
from flexmor.models.solid import cantilever
from flexmor.moving import hat_weights
from flexmor.study import System

#: Positions (m) inside segments (the path's nodes are 0.025 m apart): a wrong interpolation shows there.
OFF_NODE = np.array([0.0125, 0.3, 0.5125, 0.7125, 0.99])
#: Force of the crossings (N, +z).
FORCE = 1000.0


@pytest.fixture(scope="module")
def study():
    model = cantilever(divisions=(40, 2, 2))
    S = System(model, moving_loads=["PATH:z@x"], select=["PATH=box:0,0.05,0.1,1,0.05,0.1"], inputs=["TIP:y"],
               band=(1, 2000), damping=Rayleigh(1.0, 1e-6), cache=False)
    body, rec = S.reduce_and_judge("krylov", 40)
    assert rec["moving_loads"][0]["path_max_band_error"] < 1e-4
    return S, body


def _reference_inputs(S, body, s) -> np.ndarray:
    """``V^T B_path w(s)`` (r, len(s)) of the full model's path: the reduced input of a unit force at ``s``."""
    path = S.moving[0][0]
    return np.asarray(body.V).T @ np.asarray(path.B @ path.weights(s).T)


def test_h5_body_keeps_the_path(study, tmp_path):
    from flexmor.io import read_body, write_body

    S, body = study
    write_body(body, tmp_path / "b.h5")
    back = read_body(tmp_path / "b.h5")
    a, b = body.info["moving_loads"][0], back.info["moving_loads"][0]
    assert {k: v for k, v in a.items() if k != "B_path"} == {k: v for k, v in b.items() if k != "B_path"}
    np.testing.assert_array_equal(np.asarray(b["B_path"]), np.asarray(a["B_path"]))


def test_mat_file_carries_the_path(study, tmp_path):
    """The ``moving_loads`` struct: ``B_path`` is the body's, nodes and arc lengths the full model's path; its
    interpolated input at positions between nodes is the full model's ``V^T B_path w(s)``; in mm-t-s ``B_path``
    scales as a force input and ``s`` as a length."""
    S, body = study
    path = S.moving[0][0]
    write_mat(body, tmp_path / "b.mat", model=S.model)
    ml = scipy.io.loadmat(tmp_path / "b.mat")["moving_loads"]
    assert ml.shape == (1, 1)
    e = ml[0, 0]
    info = body.info["moving_loads"][0]
    assert (str(e["spec"][0]), str(e["direction"][0])) == ("PATH:z@x", "z")
    assert str(e["interpolation"][0]) == info["interpolation"]
    assert float(e["length"][0, 0]) == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_array_equal(e["nodes"][:, 0], path.nodes)
    np.testing.assert_allclose(e["s"][:, 0], path.s, rtol=0, atol=1e-15)
    Bp = e["B_path"]
    assert Bp.shape == (body.order, path.nodes.size)
    np.testing.assert_allclose(Bp, np.asarray(info["B_path"]), rtol=0, atol=1e-12 * np.abs(Bp).max())
    ref = _reference_inputs(S, body, OFF_NODE)
    np.testing.assert_allclose(Bp @ hat_weights(e["s"][:, 0], OFF_NODE).T, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.linalg.norm(Bp[:, ::2] @ hat_weights(e["s"][::2, 0], OFF_NODE).T - ref) > 1e-3 * np.linalg.norm(ref)

    write_mat(dataclasses.replace(body, units="SI"), tmp_path / "mm.mat", units="mm-t-s")
    mm = scipy.io.loadmat(tmp_path / "mm.mat")["moving_loads"][0, 0]
    np.testing.assert_allclose(mm["B_path"], Bp * 1e3, rtol=1e-12)
    np.testing.assert_allclose(mm["s"][:, 0], path.s * 1e3, rtol=1e-12)
    assert float(mm["length"][0, 0]) == pytest.approx(1e3, rel=1e-12)


def test_exudyn_data_carries_the_path(study, tmp_path):
    """``exudyn_data``, the ``.exudyn.npz`` and ``add_npz_to_exudyn``'s result hold the path: its rows of the mode
    basis are the body's ``B_path``, its mesh nodes the path's nodes."""
    pytest.importorskip("exudyn", reason="Exudyn is not installed (optional extra 'exudyn')")
    import exudyn as exu

    from flexmor.io.exudyn import add_npz_to_exudyn, exudyn_data, write_exudyn
    from flexmor.io.exudyn_moving import path_data

    S, body = study
    data = exudyn_data(body, S.model)
    p = path_data(data)
    assert (p.spec, p.direction, p.axis) == ("PATH:z@x", "z", 2)
    np.testing.assert_array_equal(p.nodes, S.moving[0][0].nodes)
    np.testing.assert_array_equal(np.asarray(data["nodeIds"])[p.mesh_nodes], p.nodes)
    np.testing.assert_allclose(p.xyz, S.model.node_xyz(p.nodes), rtol=0, atol=1e-15)
    Bp = np.asarray(body.info["moving_loads"][0]["B_path"])
    np.testing.assert_allclose(p.B, Bp, rtol=0, atol=1e-12 * np.abs(Bp).max())
    write_exudyn(body, tmp_path / "b.exudyn.npz", model=S.model, allow_clamped=True)
    with np.load(tmp_path / "b.exudyn.npz", allow_pickle=False) as f:
        np.testing.assert_array_equal(path_data(f).B, p.B)
    res = add_npz_to_exudyn(exu.SystemContainer().AddSystem(), tmp_path / "b.exudyn.npz")
    np.testing.assert_array_equal(path_data(res).s, p.s)


def _solve(mbs, end_time: float, steps: int) -> None:
    """Newmark's average acceleration (beta 1/4, gamma 1/2: flexmor's ``newmark``), ``steps`` steps."""
    import exudyn as exu

    mbs.Assemble()
    s = exu.SimulationSettings()
    s.timeIntegration.endTime, s.timeIntegration.numberOfSteps = end_time, steps
    s.timeIntegration.verboseMode = 0
    ga = s.timeIntegration.generalizedAlpha
    ga.useNewmark, ga.newmarkBeta, ga.newmarkGamma = True, 0.25, 0.5
    s.solution.file.write = False
    s.solution.sensors.writePeriod = end_time / steps
    mbs.SolveDynamic(s)


@pytest.mark.parametrize("speed", [10.0, 20.0])
def test_exudyn_crossing_deflects_as_the_full_model(study, speed):
    """1 kN (+z) crossing the path at ``speed`` in Exudyn, the frame fixed to the ground: the deflection under
    the load (its sensor) follows the full model's crossing within 1.5e-3 of its peak at every time step and on
    average (1.28e-3 at both speeds: the body's own error against the full model; the load at the nearest node
    instead of shared by two would give 2.1e-3 to 2.7e-3), upwards, as the body's own crossing integrated by
    flexmor does (1e-13); the load user function's input between path nodes is the full model's
    ``V^T B_path w(s)``."""
    exu = pytest.importorskip("exudyn", reason="Exudyn is not installed (optional extra 'exudyn')")
    from exudyn.utilities import GenericJoint, MarkerBodyRigid, MarkerNodeRigid, ObjectGround, SensorNode

    from flexmor.io.exudyn import add_to_exudyn
    from flexmor.io.exudyn_moving import moving_load_force, under_load, under_load_sensor

    S, body = study
    full = S.crossing(body, speed, force=FORCE)
    mbs = exu.SystemContainer().AddSystem()
    res = add_to_exudyn(mbs, body, S.model)
    ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=mbs.AddObject(ObjectGround()), localPosition=[0, 0, 0]))
    frame = mbs.AddMarker(MarkerNodeRigid(nodeNumber=res["nRigidBody"]))
    mbs.AddObject(GenericJoint(markerNumbers=[ground, frame], constrainedAxes=[1] * 6))
    load = moving_load_force(res, speed=speed, force=FORCE)
    mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction", load)
    sensor = under_load_sensor(mbs, res, speed=speed)
    modal = mbs.AddSensor(SensorNode(nodeNumber=res["nGenericODE2"], storeInternal=True,
                                     outputVariableType=exu.OutputVariableType.Coordinates))
    _solve(mbs, full["duration"], full["steps"])

    q = np.zeros(7 + body.order)  # the frame's Euler-parameter node, then the modal coordinates
    got = np.array([load(mbs, s / speed, 0, q, q)[7:] for s in OFF_NODE]).T / FORCE
    ref = _reference_inputs(S, body, OFF_NODE)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())

    t, y = np.asarray(full["t"]), np.asarray(full["under_load"])
    data = mbs.GetSensorStoredData(sensor)
    np.testing.assert_allclose(data[:, 0], t, rtol=0, atol=1e-12)
    ye = data[:, 1]
    qs = mbs.GetSensorStoredData(modal)
    np.testing.assert_allclose(under_load(res, speed * qs[:, 0], qs[:, 1:]), ye, rtol=0, atol=1e-12 * np.abs(y).max())
    peak = np.abs(y).max()
    assert y[np.argmax(np.abs(y))] > 0 and ye[np.argmax(np.abs(y))] > 0  # a +z force lifts the beam
    assert np.abs(ye - y).max() / peak < 1.5e-3
    assert np.abs(ye - y).mean() / np.abs(y).mean() < 1.5e-3
    # the body's own crossing (flexmor's Newmark on the same steps): Exudyn integrates the same equations
    assert np.abs(ye - np.asarray(full["under_load_body"])).max() < 1e-9 * peak


def test_floating_frame_gets_the_load_share(study):
    """On a floating frame the user function and :func:`moving_load_frame_loads` (a 1 kN force standing between
    path nodes at s = 0.7125 m) move the body as Exudyn's own force on the two path nodes (a weighted position
    marker: the frame's generalized forces from Exudyn's kinematics) over 10 ms: the modal coordinates within
    2e-3 (4.8e-4), the frame's coordinates within 1e-2 of their motion (Exudyn's force keeps its global
    direction, ours turns with the frame, by 1.6 mrad)."""
    exu = pytest.importorskip("exudyn", reason="Exudyn is not installed (optional extra 'exudyn')")
    import exudyn.itemInterface as eii
    from exudyn.utilities import SensorNode

    from flexmor.io.exudyn import add_to_exudyn
    from flexmor.io.exudyn_moving import moving_load_force, moving_load_frame_loads, path_data

    S, body = study
    s0 = 0.7125

    def run(ours: bool):
        mbs = exu.SystemContainer().AddSystem()
        res = add_to_exudyn(mbs, body, S.model)
        if ours:
            mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction",
                                   moving_load_force(res, position=lambda t: s0, force=FORCE))
            moving_load_frame_loads(mbs, res, position=lambda t: s0, force=FORCE)
        else:
            p = path_data(res)
            j, frac, _ = p.segment(s0)
            marker = mbs.AddMarker(eii.MarkerSuperElementPosition(
                bodyNumber=res["oFFRFreducedOrder"], meshNodeNumbers=[int(p.mesh_nodes[j]), int(p.mesh_nodes[j + 1])],
                weightingFactors=[1.0 - float(frac), float(frac)]))
            mbs.AddLoad(eii.LoadForceVector(markerNumber=marker, loadVector=[0.0, 0.0, FORCE]))
        sensors = [mbs.AddSensor(SensorNode(nodeNumber=res[n], storeInternal=True,
                                            outputVariableType=exu.OutputVariableType.Coordinates))
                   for n in ("nGenericODE2", "nRigidBody")]
        _solve(mbs, 0.01, 400)
        return [mbs.GetSensorStoredData(s)[:, 1:] for s in sensors]

    (qa, fa), (qb, fb) = run(False), run(True)
    assert np.abs(qb - qa).max() < 2e-3 * np.abs(qa).max()
    moved = np.abs(fa - fa[0]).max(axis=0)
    assert moved[2] > 1e-4 and moved[5] > 1e-4  # pushed up (z) and turned about y
    big = moved > 1e-9
    assert np.all(np.abs(fb - fa).max(axis=0)[big] < 1e-2 * moved[big])


def test_readme_example_crosses_the_beam(study, tmp_path, monkeypatch):
    """The README's Exudyn example on this body (``bridge.exudyn.npz``): 1 kN downwards at 10 m/s deflects the
    beam under the load as the full model's crossing, mirrored (within 1.5e-3 of its peak)."""
    pytest.importorskip("exudyn", reason="Exudyn is not installed (optional extra 'exudyn')")
    from pathlib import Path

    from flexmor.io.exudyn import write_exudyn

    S, body = study
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    section = text.split("**Moving loads in the `.mat` file and Exudyn**", 1)[1]
    block = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    write_exudyn(body, "bridge.exudyn.npz", model=S.model, allow_clamped=True)
    ns: dict = {}
    exec(compile(block, "README.md", "exec"), ns)
    full = S.crossing(body, 10.0, force=FORCE)
    _solve(ns["mbs"], full["duration"], full["steps"])
    ye, y = ns["mbs"].GetSensorStoredData(ns["sensor"])[:, 1], -np.asarray(full["under_load"])
    assert np.abs(ye - y).max() < 1.5e-3 * np.abs(y).max()
