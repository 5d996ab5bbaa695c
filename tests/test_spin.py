"""Spinning bodies (:mod:`flexmor.spin`): one body over a speed range (``reduce --spin-range``) against the full
model at five speeds, and Campbell diagrams (``info --campbell``) of model and body, on the CalculiX C3D8
cantilever of ``tests/data/calculix`` (1 x 0.1 x 0.1 m steel, clamped at x = 0). Against CalculiX's own
complex frequencies: ``tests/test_preload_ccx.py``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import run, solve_exudyn

from flexmor.io import read, read_body
from flexmor.linalg.eigen import eigenmodes, frequencies_hz
from flexmor.preload import preload_stiffness
from flexmor.spin import campbell, parse_spin_range, spin_operators

DATA = Path(__file__).parent / "data" / "calculix"
MODEL = DATA / "beam8_clamped_mat.sti"


@pytest.fixture(scope="module")
def model():
    return read(MODEL)


@pytest.fixture(scope="module")
def body(tmp_path_factory):
    from flexmor.cli import main

    path = tmp_path_factory.mktemp("spin") / "s.h5"
    assert main([str(a) for a in ("reduce", MODEL, "--method", "krylov", "--order", "12", "--input", "TIP:y",
                                  "--input", "TIP:z", "--spin-range", "x:0:400", "--no-error", "-o", path)]) == 0
    return read_body(path), path


def test_the_body_spins_as_the_full_model_at_five_speeds(model, body):
    """K_r(w) = V^T (K + K_G(w) - P^T M P) V at any speed (linear in w^2), and the lowest four frequencies
    within 1e-4 of the full model's at five speeds (its record says the same)."""
    red, _ = body
    spin = red.info["spin"]
    K2 = np.asarray(spin["K2"])
    for w in np.linspace(0.0, 400.0, 5):
        Kw = preload_stiffness(model, f"spin:{w},0,0").K if w else model.K
        ref = red.V.T @ (Kw @ red.V)
        assert np.abs(red.K + w * w * K2 - ref).max() <= 1e-9 * np.abs(ref).max()
        full = frequencies_hz(np.sort(eigenmodes(Kw, model.M, 4)[0]))
        mine = frequencies_hz(sla.eigh(red.K + w * w * K2, red.M, eigvals_only=True)[:4])
        assert np.abs(mine / full - 1).max() < 1e-4, (w, mine, full)
    assert spin["check"]["speeds"] == [0.0, 100.0, 200.0, 300.0, 400.0]
    assert spin["check"]["max_rel_error"] < 1e-3
    assert red.order > 12 and "union" in red.order_note  # the bases of three speeds


def test_campbell_of_a_beam_spinning_about_its_axis(model, body):
    """In the turning frame Coriolis splits each bending pair by twice the speed (slender beam: f0 -+ w / 2 pi):
    the forward branch falls, the backward one rises; the first forward branch meets the speed at w = pi f0.
    Body and full model agree to 1e-4."""
    red, _ = body
    ops = spin_operators(model, [1.0, 0.0, 0.0])
    speeds = np.linspace(0.0, 400.0, 5)
    full = campbell(model.M, model.K, ops.K2, ops.G1, speeds, 4)
    spin = red.info["spin"]
    mine = campbell(red.M, red.K, np.asarray(spin["K2"]), np.asarray(spin["G1"]), speeds, 4)
    assert np.abs(mine.frequencies_hz / full.frequencies_hz - 1).max() < 1e-4
    f0 = full.frequencies_hz[0, 0]
    split = full.frequencies_hz[-1, 1] - full.frequencies_hz[-1, 0]
    assert split == pytest.approx(2 * 400.0 / (2 * np.pi), rel=0.01)
    assert list(full.labels()[-1]) == ["FW", "BW", "FW", "BW"] == list(mine.labels()[-1])
    (first,) = [c for c in full.critical if c["mode"] == 1 and c["multiple"] == 1]
    assert first["speed"] == pytest.approx(np.pi * f0, rel=0.01)


def test_the_command_line_prints_both_diagrams(capsys, body):
    _, path = body
    code, out, err = run(capsys, "info", MODEL, "--campbell", "x:0:400:5", "--modes", "4")
    assert code == 0, err
    assert "Campbell diagram, spin x:0:400" in out and "critical speeds" in out and "FW" in out
    code, out, err = run(capsys, "info", path, "--campbell", "--json")
    assert code == 0, err
    rec = json.loads(out)["campbell"]
    assert rec["speeds"][0] == 0.0 and rec["speeds"][-1] == 400.0 and len(rec["speeds"]) == 11
    code, out, _ = run(capsys, "info", path)
    assert "spin        x:0:400 rad/s" in out


@pytest.mark.parametrize("argv, words", [
    (("info", MODEL, "--campbell"), "--campbell of a model needs AXIS:W0:W1"),
    (("info", MODEL, "--campbell", "q:0:10"), "the axis and the speeds must be numbers"),
    (("info", MODEL, "--campbell", "z:10:0"), "0 <= W0 < W1"),
    (("reduce", MODEL, "--method", "krylov", "--order", "8", "--input", "TIP:y", "--spin-range", "x:0:3000",
      "--no-error"), "not positive definite|singular or indefinite"),
    (("info", DATA / "beam8_free_mat.sti", "--campbell", "z:0:100"), "moves freely: constrain it"),
    (("info", MODEL, "--campbell", "x:0:3000:3"), "a mode that grows"),
    (("reduce", DATA / "beam8_free_mat.sti", "--method", "krylov", "--order", "8", "--input", "TIP:y",
      "--spin-range", "z:0:100", "--no-error"), "moves freely: constrain it"),
])
def test_bad_spin_ranges_are_refused_naming_the_flag(capsys, tmp_path, argv, words):
    code, _, err = run(capsys, *argv, *(("-o", tmp_path / "b.h5") if argv[0] == "reduce" else ()))
    assert code != 0
    import re

    assert re.search(words, err), err


def test_a_body_without_spin_has_no_campbell_diagram(capsys, tmp_path):
    path = tmp_path / "b.h5"
    code, _, err = run(capsys, "reduce", MODEL, "--method", "modal", "--order", "4", "--input", "TIP:y", "--no-error",
                       "-o", path)
    assert code == 0, err
    code, _, err = run(capsys, "info", path, "--campbell")
    assert code != 0 and "--spin-range" in err


def test_parse_spin_range():
    sr = parse_spin_range("1,1,0:0:10")
    assert np.allclose(sr.axis, [2 ** -0.5, 2 ** -0.5, 0]) and (sr.w0, sr.w1) == (0.0, 10.0)


def test_the_study_file_keeps_the_spin_range(capsys, tmp_path):
    first, study, again = tmp_path / "a.h5", tmp_path / "s.toml", tmp_path / "b.h5"
    code, _, err = run(capsys, "reduce", MODEL, "--method", "krylov", "--order", "8", "--input", "TIP:y",
                       "--spin-range", "x:0:300", "--no-error", "-o", first, "--save-study", study)
    assert code == 0, err
    assert 'spin_range = "x:0:300"' in study.read_text()
    code, _, err = run(capsys, "run", study, "-o", again)
    assert code == 0, err
    a, b = read_body(first), read_body(again)
    assert b.info["spin"]["spec"] == "x:0:300" and np.array_equal(a.K, b.K)


def test_the_mat_file_carries_the_spin(body, tmp_path):
    import scipy.io

    red, path = body
    from flexmor.cli import main

    assert main(["export", str(path), "-o", str(tmp_path / "s.mat")]) == 0
    data = scipy.io.loadmat(tmp_path / "s.mat", squeeze_me=True, struct_as_record=False)
    spin = data["spin"]
    assert np.allclose(spin.axis, [1, 0, 0]) and np.allclose(spin.range, [0, 400])
    assert np.array_equal(spin.K2, np.asarray(red.info["spin"]["K2"]))
    assert np.allclose(spin.G1, -spin.G1.T) and np.abs(spin.G1).max() > 0


def test_the_report_draws_the_campbell_diagram_of_full_model_and_body(capsys, body, tmp_path):
    _, path = body
    code, _, err = run(capsys, "report", MODEL, path, "-o", tmp_path / "r.html")
    assert code == 0, err
    html = (tmp_path / "r.html").read_text()
    assert 'id="campbell"' in html and "Campbell diagram" in html and "FW" in html
    import re

    worst = re.search(r"Largest relative difference to the full model: [^:]+: ([0-9.e+-]+?)\.? Critical", html)
    assert float(worst.group(1)) < 1e-2


def test_the_fmu_takes_the_speed_as_an_input(body, tmp_path):
    """The FMU of a body over a speed range has the input ``omega`` (rad/s): fmpy's validation passes, the
    co-simulation step at 300 rad/s is the exact zero-order-hold solution of K + w^2 K2 and w G1, and its
    step response differs from the one at rest."""
    pytest.importorskip("fmpy")
    from fmpy import read_model_description, simulate_fmu
    from fmpy.validation import validate_fmu

    from flexmor.io import export
    from flexmor.io.statespace import state_space

    red, _ = body
    path = tmp_path / "spin.fmu"
    export(red, path, "fmu")
    assert validate_fmu(str(path)) == []
    names = [v.name for v in read_model_description(str(path)).modelVariables if v.causality == "input"]
    assert names == ["TIP_y", "TIP_z", "omega"]
    spin = red.info["spin"]
    ss = state_space(red)
    r, h, n_steps = red.order, 2e-4, 200
    M = np.asarray(red.M)
    outputs = {}
    for w in (0.0, 300.0):
        A = ss.A.copy()
        A[r:, :r] -= w * w * np.linalg.solve(M, np.asarray(spin["K2"]))
        A[r:, r:] -= w * np.linalg.solve(M, np.asarray(spin["G1"]))
        n, m = ss.B.shape
        aug = np.zeros((n + m, n + m))
        aug[:n, :n], aug[:n, n:] = A * h, ss.B * h
        E = sla.expm(aug)
        u, x, ref = np.array([1.0, -0.5]), np.zeros(n), [np.zeros(ss.C.shape[0])]
        for _ in range(n_steps):
            x = E[:n, :n] @ x + E[:n, n:] @ u
            ref.append(ss.C @ x)
        signal = np.array([(0.0, *u, w), (n_steps * h, *u, w)],
                          dtype=[("time", float), ("TIP_y", float), ("TIP_z", float), ("omega", float)])
        res = simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=n_steps * h, step_size=h, output_interval=h,
                           input=signal, output=["u_TIP_y", "u_TIP_z"])
        got = np.array([res["u_TIP_y"], res["u_TIP_z"]]).T
        assert np.abs(got - np.array(ref)).max() < 1e-9 * np.abs(ref).max()
        outputs[w] = got
    assert np.abs(outputs[300.0] - outputs[0.0]).max() > 0.01 * np.abs(outputs[0.0]).max()
    import shutil
    import subprocess
    import zipfile

    cc = shutil.which("cc") or shutil.which("gcc")
    with zipfile.ZipFile(path) as zf:
        (tmp_path / "spin.c").write_text(zf.read("sources/spin.c").decode())
    run_cc = subprocess.run([cc, "-std=c99", "-fPIC", "-shared", "-Wall", "-Wextra", "-pedantic", "-Werror", "-o",
                             str(tmp_path / "spin.so"), str(tmp_path / "spin.c"), "-lm"],
                            capture_output=True, text=True)
    assert run_cc.returncode == 0, run_cc.stderr  # warning-free with the speed as well


def test_exudyn_spins_the_body_with_its_stiffening(model):
    """The body over 0-400 rad/s in Exudyn, its frame turning freely about z at 150 rad/s (a GenericJoint to the
    ground frees that rotation only), started from its centrifugal equilibrium plus a flapwise (z) deflection of
    the tip: the flapwise frequency of the time response (zero crossings of the tip's z) is the full model's
    under ``--preload spin:0,0,150`` (103.4 Hz) with the user function :func:`spin_stiffening_force` that
    :func:`add_to_exudyn` sets, and the unstressed one (100.0 Hz: Exudyn's floating frame has no stress
    stiffening of its own) without it."""
    exu = pytest.importorskip("exudyn")
    from exudyn.utilities import GenericJoint, MarkerBodyRigid, MarkerNodeRigid, ObjectGround, SensorNode

    import flexmor
    from flexmor.io.exudyn import add_to_exudyn
    from flexmor.preload import preload_load

    red = flexmor.reduce(model, "krylov", 12, flexmor.make_ports(model, ["TIP:z", "TIP:y"]), spin_range="z:0:400")
    w = 150.0
    K2 = np.asarray(red.info["spin"]["K2"])
    qc = np.linalg.solve(red.K + w * w * K2, red.V.T @ preload_load(model, f"spin:0,0,{w}")[0])

    def flapwise_hz(stiffened: bool) -> float:
        mbs = exu.SystemContainer().AddSystem()
        res = add_to_exudyn(mbs, red, model, angular_velocity=(0.0, 0.0, w))
        assert res["spin_stiffening"]
        if not stiffened:
            mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction", 0)
        ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=mbs.AddObject(ObjectGround()), localPosition=[0, 0, 0]))
        frame = mbs.AddMarker(MarkerNodeRigid(nodeNumber=res["nRigidBody"]))
        mbs.AddObject(GenericJoint(markerNumbers=[ground, frame], constrainedAxes=[1, 1, 1, 1, 1, 0]))
        q0 = qc + 1e4 * np.linalg.solve(red.K, red.B[:, 0])
        mbs.SetNodeParameter(res["nGenericODE2"], "initialCoordinates", q0.tolist())
        sensor = mbs.AddSensor(SensorNode(nodeNumber=res["nGenericODE2"], storeInternal=True,
                                          outputVariableType=exu.OutputVariableType.Coordinates))
        data = solve_exudyn(mbs, sensor, 0.05, 2000)
        t, z = data[:, 0], data[:, 1:] @ red.C[0]
        i = np.flatnonzero(np.sign(z[:-1]) * np.sign(z[1:]) < 0)
        crossings = t[i] - z[i] * (t[i + 1] - t[i]) / (z[i + 1] - z[i])
        return (crossings.size - 1) / 2 / (crossings[-1] - crossings[0])

    pre = frequencies_hz(np.sort(eigenmodes(preload_stiffness(model, f"spin:0,0,{w}").K, model.M, 2)[0]))
    rest = frequencies_hz(np.sort(eigenmodes(model.K, model.M, 2)[0]))
    assert flapwise_hz(True) == pytest.approx(pre[1], rel=2e-3)  # the z mode: the stiffer of the pair
    assert flapwise_hz(False) == pytest.approx(rest[1], rel=2e-3)
    assert pre[1] > 1.03 * rest[1]
