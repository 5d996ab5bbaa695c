"""A body reduced with a moving load in the FMU and the SID exports: the FMU takes the load's force and
position as inputs and gives the deflection under it (driven by fmpy: a crossing against the exact
zero-order-hold solution of the body, a standing load against its static deflection, the model-exchange
derivatives against the body's equations); the SID writes the path's nodes as frame nodes in path order
(read back with the plain reader of ``tests/sid_check.py``)."""

from __future__ import annotations

import subprocess
import zipfile

import numpy as np
import pytest
import scipy.linalg as sla
import sid_check
from helpers import fmu_instance

from flexmor.damping import Rayleigh
from flexmor.errors import FlexmorError
from flexmor.io import export
from flexmor.io.fmu import find_compiler
from flexmor.io.sid import write_sid
from flexmor.io.statespace import state_space
from flexmor.models.solid import cantilever
from flexmor.moving import hat_weights
from flexmor.study import System

SPEED = 10.0  # m/s over the 1 m path


@pytest.fixture(scope="module")
def moving():
    """The steel cantilever 1 x 0.1 x 0.1 m (clamped at x = 0) with a vertical load moving along its top
    centre line, Krylov order 40: ``(system, body, B_path_r (r, N), arc lengths (N,), path node ids)``."""
    model = cantilever(divisions=(40, 2, 2))
    system = System(model, moving_loads=["PATH:z@x"], select=["PATH=box:0,0.05,0.1,1,0.05,0.1"], inputs=["TIP:y"],
                    band=(1, 2000), damping=Rayleigh(1.0, 1e-6), cache=False)
    body = system.reduce("krylov", 40)
    rec = body.info["moving_loads"][0]
    return system, body, np.asarray(rec["B_path"]), np.asarray(rec["s"]), list(rec["nodes"])


@pytest.fixture(scope="module")
def fmu(moving, tmp_path_factory):
    try:
        find_compiler()
    except FlexmorError as exc:
        pytest.skip(f"no C compiler: {exc}")
    path = tmp_path_factory.mktemp("moving") / "moving.fmu"
    export(moving[1], path, "fmu")
    return path


def _path_input(body) -> np.ndarray:
    """``[0; M^-1]``: the state-space input of a generalized force."""
    r = body.order
    return np.vstack([np.zeros((r, r)), np.linalg.inv(np.asarray(body.M))])


def test_fmu_has_the_loads_force_and_position_as_inputs_and_the_deflection_under_it_as_output(moving, fmu, tmp_path):
    pytest.importorskip("fmpy")
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    _, body, _, _, nodes = moving
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    ports = ["TIP_y", *(f"PATH_z_{k}" for k in range(1, len(body.input_names)))]
    assert inputs == [*ports, "F_PATH", "s_PATH"]  # the ports' inputs as before, then the load's
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs == [*(f"u_{p}" for p in ports), *(f"v_{p}" for p in ports), "w_PATH"]
    assert (var["F_PATH"].unit, var["s_PATH"].unit, var["w_PATH"].unit) == ("N", "m", "m")
    assert f"from node {nodes[0]} (0 to 1 m" in var["s_PATH"].description
    assert len(md.derivatives) == 2 * body.order and md.derivatives[0].variable.derivative.name == "q[1]"
    cc = find_compiler()
    with zipfile.ZipFile(fmu) as zf:
        (tmp_path / "moving.c").write_text(zf.read("sources/moving.c").decode())
    run = subprocess.run([*cc, "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-pedantic", "-Werror",
                          "-o", str(tmp_path / "moving.so"), str(tmp_path / "moving.c"), "-lm"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


def test_fmu_crossing_is_the_exact_zero_order_hold_response(moving, fmu):
    """1 N crossing the 1 m path at 10 m/s, co-simulation steps of 0.1 ms with s = 10 t held over each step: the
    deflection under the load equals the zero-order-hold solution of the body (SciPy's expm of the augmented
    first-order system) at every step, to 1e-9 of its peak."""
    pytest.importorskip("fmpy")
    _, body, Bp, s_nodes, _ = moving
    h = 1e-4
    n = round(s_nodes[-1] / SPEED / h)
    s = SPEED * h * np.arange(n + 1)
    got = []
    with fmu_instance(fmu, "cs") as (inst, vr):
        for k in range(n + 1):
            inst.setReal([vr["F_PATH"], vr["s_PATH"]], [1.0, s[k]])
            got.append(inst.getReal([vr["w_PATH"]])[0])
            if k < n:
                inst.doStep(k * h, h)
    r, A = body.order, state_space(body).A
    aug = np.zeros((3 * r, 3 * r))
    aug[:2 * r, :2 * r], aug[:2 * r, 2 * r:] = A * h, _path_input(body) * h
    E = sla.expm(aug)
    x, ref = np.zeros(2 * r), []
    for w in hat_weights(s_nodes, s):
        ref.append(w @ Bp.T @ x[:r])
        x = E[:2 * r, :2 * r] @ x + E[:2 * r, 2 * r:] @ (Bp @ w)
    ref = np.asarray(ref)
    peak = np.abs(ref).max()
    assert peak > 1e-8  # about 0.18 um under 1 N
    assert np.abs(np.asarray(got) - ref).max() < 1e-9 * peak


def test_fmu_standing_load_settles_at_the_static_deflection(moving, fmu):
    """1 kN standing halfway between two path nodes (s = 0.5125 m) for 60 s (0.5 s steps): the deflection under
    it is ``w^T B_path_r^T K_r^-1 B_path_r w F`` to 1e-9; moved off the path, it is zero."""
    pytest.importorskip("fmpy")
    _, body, Bp, s_nodes, _ = moving
    s0, F, h = 0.5125, 1000.0, 0.5
    w = hat_weights(s_nodes, s0)[0]
    assert np.count_nonzero(w) == 2 and np.allclose(w[w > 0], 0.5)
    static = w @ Bp.T @ np.linalg.solve(np.asarray(body.K), Bp @ w) * F
    with fmu_instance(fmu, "cs") as (inst, vr):
        inst.setReal([vr["F_PATH"], vr["s_PATH"]], [F, s0])
        for k in range(120):
            inst.doStep(k * h, h)
        settled = inst.getReal([vr["w_PATH"]])[0]
        inst.setReal([vr["s_PATH"]], [1.5])
        off = inst.getReal([vr["w_PATH"]])[0]
    assert static > 1e-5 and abs(settled / static - 1) < 1e-9
    assert off == 0.0


def test_fmu_derivatives_hold_the_loads_generalized_force(moving, fmu):
    """Model exchange: at random states, ``der(x) = A x + B u + [0; M^-1] B_path_r w(s) F`` and the deflection
    under the load ``w(s)^T B_path_r^T q`` at positions inside segments, at path nodes, at both ends and off the
    path (no force, no deflection), to 1e-12."""
    pytest.importorskip("fmpy")
    from ctypes import c_double

    _, body, Bp, s_nodes, _ = moving
    r = body.order
    ss = state_space(body)
    x = 1e-6 * np.random.default_rng(1).standard_normal(2 * r)
    with fmu_instance(fmu, "me") as (inst, vr):
        inst.enterContinuousTimeMode()
        inst.setContinuousStates((c_double * (2 * r))(*x), 2 * r)
        for s0, F in ((0.5125, 1000.0), (0.3, 5.0), (0.0, 3.0), (1.0, -2.0), (1.5, 7.0), (-0.1, 1.0)):
            inst.setReal([vr["TIP_y"], vr["F_PATH"], vr["s_PATH"]], [2.0, F, s0])
            dx = (c_double * (2 * r))()
            inst.getDerivatives(dx, 2 * r)
            w = hat_weights(s_nodes, s0)[0]
            ref = ss.A @ x + 2.0 * ss.B[:, 0] + _path_input(body) @ Bp @ w * F
            assert np.abs(np.asarray(dx[:]) - ref).max() < 1e-12 * np.abs(ref).max(), s0
            y, y_ref = inst.getReal([vr["w_PATH"]])[0], w @ Bp.T @ x[:r]
            assert abs(y - y_ref) <= 1e-12 * np.abs(Bp.T @ x[:r]).max(), s0
            if not 0 <= s0 <= 1:  # off the path
                assert y == 0.0


def test_sid_writes_the_path_nodes_as_frame_nodes_in_path_order(moving, tmp_path):
    """The path's 41 nodes follow the TIP frame node, in path order, at the nodes' coordinates; their ``phi`` in
    the load's direction are the columns of ``B_path_r`` (so ``phi_z`` summed with the hat weights at ``s`` is
    ``B_path_r w(s)``), to 1e-10; the header names the block. The compressed loads ``PATH:z~k`` add no frame
    node of their own."""
    system, body, Bp, s_nodes, nodes = moving
    path = tmp_path / "moving.SID_FEM"
    write_sid(body, path, model=system.model, allow_clamped=True)
    frame = sid_check.frame_nodes(path)
    n_nodes, n_modes, comment = sid_check.header(path)
    assert list(frame)[1:] == nodes and n_nodes == 1 + len(nodes) and n_modes == body.order
    assert (f"moving load PATH:z@x: frame nodes 2 to {1 + len(nodes)} (1-based) are the nodes {nodes[0]} to "
            f"{nodes[-1]} of its path, set PATH, in path order") in comment
    assert np.allclose(frame[list(frame)[0]]["origin"][:, 0], [1.0, 0.05, 0.05])  # TIP: the end face's centre
    origins = np.array([frame[k]["origin"][:, 0] for k in nodes])
    assert np.abs(origins - system.model.node_xyz(np.array(nodes))).max() < 1e-12
    assert np.all(np.diff(origins[:, 0]) > 0) and np.allclose(origins[:, 1:], [0.05, 0.1])
    phi_z = np.array([frame[k]["phi"][2] for k in nodes]).T  # (r, N)
    scale = np.abs(Bp).max()
    assert np.abs(phi_z - Bp).max() < 1e-10 * scale
    for s in (0.0, 0.3, 0.5125, 0.99, 1.0):
        w = hat_weights(s_nodes, s)[0]
        assert np.abs(phi_z @ w - Bp @ w).max() < 1e-10 * scale
    assert not any(frame[k]["psi"].any() for k in nodes)  # a solid model's nodes have no rotations
