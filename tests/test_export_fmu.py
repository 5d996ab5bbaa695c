"""The FMI 2.0 FMU export: fmpy's validation, a step on each input simulated by fmpy (model
exchange with CVode, co-simulation) against the body's own equations integrated by SciPy, the
generated C, and ``flexmor export body.h5 -o body.fmu`` with and without a C compiler."""

from __future__ import annotations

import shutil
import subprocess
import zipfile

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import fmu_instance
from scipy.integrate import solve_ivp

from flexmor.body import ReducedModel
from flexmor.cli import main
from flexmor.errors import FlexmorError
from flexmor.io import export, write_body
from flexmor.io.fmu import FMUVariables, find_compiler, fmu_variables
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce

INPUTS = ["TIP:y", "TIP:z"]
T_END, DT = 0.03, 1e-5


def _compiler():
    try:
        return find_compiler()
    except FlexmorError as exc:
        pytest.skip(f"no C compiler: {exc}")


@pytest.fixture(scope="module")
def bodies():
    """Krylov bodies of order 8 (Rayleigh 0, 1e-6) of the clamped and of the free cantilever (its basis
    without rigid-body modes), inputs and outputs TIP:y TIP:z."""
    out = {}
    for kind, clamped in (("clamped", True), ("free", False)):
        model = cantilever(2, clamped=clamped).with_rayleigh(0.0, 1e-6)
        # for the ports alone: the clamped body's highest mode at 3.7 kHz (built for the frame's inertia loads too,
        # order 8 stops at 1.5 kHz), which the co-simulation step test steps over
        out[kind] = reduce(model, "krylov", 8, make_ports(model, INPUTS), inertia_loads="off")
    assert out["free"].info["rigid"] == "exclude" and out["free"].frequencies_hz()[0] > 500
    return out


@pytest.fixture(scope="module")
def fmus(bodies, tmp_path_factory):
    _compiler()
    folder = tmp_path_factory.mktemp("fmu")
    paths = {}
    for kind, body in bodies.items():
        paths[kind] = folder / f"{kind}_body.fmu"
        assert export(body, paths[kind]) == "fmu"
    return paths


def _reference(body, j: int, t: np.ndarray):
    """Displacements and velocities at the outputs for a unit step on input ``j``: the body's
    ``M q'' + D q' + K q = B u`` integrated by SciPy (DOP853, tight tolerances)."""
    M, D, K, B, C = body.M, body.D, body.K, body.B, body.C
    r = M.shape[0]
    lu = sla.lu_factor(M)
    f = B[:, j]
    qs = np.abs(np.linalg.solve(K, f)).max()

    def rhs(_, x):
        q, qd = x[:r], x[r:]
        return np.concatenate([qd, sla.lu_solve(lu, f - D @ qd - K @ q)])

    sol = solve_ivp(rhs, (t[0], t[-1]), np.zeros(2 * r), method="DOP853", t_eval=t, rtol=1e-11,
                    atol=1e-13 * qs)
    assert sol.success
    return C @ sol.y[:r], C @ sol.y[r:]


def test_fmu_passes_fmpys_validation(fmus):
    pytest.importorskip("fmpy")
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    for path in fmus.values():
        assert validate_fmu(str(path)) == []
        md = read_model_description(str(path))
        assert md.fmiVersion == "2.0" and md.modelExchange and md.coSimulation
        names = {v.name: v for v in md.modelVariables}
        assert names["TIP_y"].causality == "input" and names["TIP_y"].unit == "N"
        assert names["TIP_y"].description == "force at the input port TIP:y"
        assert names["u_TIP_z"].unit == "m" and names["v_TIP_z"].unit == "m/s"
        assert len(md.derivatives) == 16 and md.derivatives[0].variable.derivative.name == "q[1]"
        with zipfile.ZipFile(path) as zf:
            assert f"binaries/linux64/{path.stem}.so" in zf.namelist()


@pytest.mark.parametrize("kind", ["clamped", "free"])
def test_a_step_on_each_input_matches_the_bodys_equations(fmus, bodies, kind):
    """fmpy with CVode (model exchange) and co-simulation against SciPy, to 1e-4 of the peak; the
    co-simulation step is the exact solution for inputs held over the step."""
    pytest.importorskip("fmpy")
    from fmpy import simulate_fmu

    body, path = bodies[kind], str(fmus[kind])
    t = np.linspace(0.0, T_END, round(T_END / DT) + 1)
    outputs = ["u_TIP_y", "u_TIP_z", "v_TIP_y", "v_TIP_z"]
    for j in range(len(INPUTS)):
        disp, vel = _reference(body, j, t)
        u = np.zeros(len(INPUTS))
        u[j] = 1.0
        signal = np.array([(0.0, *u), (T_END, *u)], dtype=[("time", float), ("TIP_y", float), ("TIP_z", float)])
        for fmi_type, options in (("ModelExchange", {"solver": "CVode", "relative_tolerance": 1e-8}),
                                  ("CoSimulation", {"step_size": DT})):
            res = simulate_fmu(path, fmi_type=fmi_type, start_time=0.0, stop_time=T_END, output_interval=DT,
                               input=signal, output=outputs, **options)
            np.testing.assert_allclose(res["time"], t, atol=1e-12)
            got_u = np.array([res["u_TIP_y"], res["u_TIP_z"]])
            got_v = np.array([res["v_TIP_y"], res["v_TIP_z"]])
            for got, ref in ((got_u, disp), (got_v, vel)):
                peak = np.abs(ref).max()
                assert peak > 0
                err = np.abs(got - ref).max() / peak
                assert err < (1e-4 if fmi_type == "ModelExchange" else 1e-7), (kind, j, fmi_type, err)


def test_cosimulation_step_is_exact_for_steps_longer_than_the_highest_period(fmus, bodies):
    """A communication step of more than 18 periods of the body's highest mode (3.5 kHz): the FMU's step is the
    zero-order-hold solution (SciPy's expm of the augmented matrix), with no step-size limit."""
    pytest.importorskip("fmpy")
    from fmpy import simulate_fmu

    from flexmor.io.statespace import state_space

    body = bodies["clamped"]
    h = 6e-3
    assert h * body.frequencies_hz().max() > 18
    ss = state_space(body)
    n, m = ss.B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = ss.A * h, ss.B * h
    E = sla.expm(aug)
    u = np.array([1.0, -0.5])
    x, ref = np.zeros(n), [np.zeros(ss.C.shape[0])]
    for _ in range(100):
        x = E[:n, :n] @ x + E[:n, n:] @ u
        ref.append(ss.C @ x)
    signal = np.array([(0.0, *u), (100 * h, *u)], dtype=[("time", float), ("TIP_y", float), ("TIP_z", float)])
    res = simulate_fmu(str(fmus["clamped"]), fmi_type="CoSimulation", stop_time=100 * h, step_size=h,
                       output_interval=h, input=signal, output=["u_TIP_y", "u_TIP_z"])
    got = np.array([res["u_TIP_y"], res["u_TIP_z"]]).T
    assert np.abs(got - np.array(ref)).max() < 1e-10 * np.abs(ref).max()


def test_fmu_state_is_saved_and_restored(fmus):
    pytest.importorskip("fmpy")
    with fmu_instance(fmus["clamped"]) as (fmu, vr):
        fmu.setReal([vr["TIP_y"]], [1.0])
        fmu.doStep(0.0, 1e-3)
        state = fmu.getFMUState()
        fmu.doStep(1e-3, 1e-3)
        first = fmu.getReal([vr["u_TIP_y"], vr["v_TIP_y"]])
        fmu.setFMUState(state)
        fmu.doStep(1e-3, 1e-3)
        assert fmu.getReal([vr["u_TIP_y"], vr["v_TIP_y"]]) == first and first[0] > 0
        fmu.freeFMUState(state)


def test_generated_c_is_warning_free(fmus, tmp_path):
    """The C in sources/ compiles with -std=c99 -Wall -Wextra -pedantic -Werror, also for a body without inputs."""
    cc = _compiler()
    with zipfile.ZipFile(fmus["free"]) as zf:
        source = zf.read("sources/free_body.c").decode()
    assert "%.17g" not in source and "static const double A[NX * NX]" in source
    rng = np.random.default_rng(0)
    X = rng.standard_normal((3, 3))
    no_inputs = ReducedModel(M=np.eye(3), K=X @ X.T + 3 * np.eye(3), D=None, B=np.zeros((3, 0)), C=np.eye(3)[:1])
    export(no_inputs, tmp_path / "silent.fmu")
    with zipfile.ZipFile(tmp_path / "silent.fmu") as zf:
        silent = zf.read("sources/silent.c").decode()
    for name, text in (("free", source), ("silent", silent)):
        src = tmp_path / f"{name}.c"
        src.write_text(text)
        run = subprocess.run([*cc, "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-pedantic", "-Werror",
                              "-o", str(tmp_path / f"{name}.so"), str(src), "-lm"], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr


def test_variable_names_and_units_from_port_specs():
    var = FMUVariables(["TIP@rbe3:rx", "42:y", "TIP:y"], ["TIP:y", "tip:y", "out1"], 2)
    assert var.inputs == ["TIP_rbe3_rx", "n42_y", "TIP_y"]
    assert var.displacements == ["u_TIP_y", "u_tip_y", "u_out1"] and var.velocities[0] == "v_TIP_y"
    rows = {row["name"]: row for row in var.rows}
    assert rows["TIP_rbe3_rx"]["unit"] == "N.m" and rows["TIP_rbe3_rx"]["description"].startswith("moment")
    assert rows["u_out1"]["unit"] is None and rows["v_TIP_y"]["unit"] == "m/s"
    assert rows["der(qd[2])"]["derivative"] == 3 + 6 + 4  # 1-based index of qd[2]
    assert FMUVariables(["a:b", "a.b"], [], 1).inputs == ["a_b", "a_b_2"]
    unnamed = fmu_variables(ReducedModel(M=np.eye(2), K=np.eye(2), D=None, B=np.ones((2, 2)), C=np.ones((1, 2))))
    assert unnamed.inputs == ["F1", "F2"] and unnamed.displacements == ["u_y1"]


def test_cli_exports_an_fmu(tmp_path, bodies, capsys):
    _compiler()
    pytest.importorskip("fmpy")
    from fmpy.validation import validate_fmu

    h5 = tmp_path / "body.h5"
    write_body(bodies["clamped"], h5)
    out = tmp_path / "body.fmu"
    assert main(["export", str(h5), "-o", str(out)]) == 0
    assert "as fmu" in capsys.readouterr().out
    assert validate_fmu(str(out)) == []
    # --allow-clamped concerns the floating-frame exports only; an FMU takes a clamped body as it is
    assert main(["export", str(h5), "-o", str(tmp_path / "clamped.fmu"), "--allow-clamped"]) == 0


def test_no_compiler_is_a_clear_error(tmp_path, bodies, capsys, monkeypatch):
    h5 = tmp_path / "body.h5"
    write_body(bodies["clamped"], h5)
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    monkeypatch.delenv("CC", raising=False)
    out = tmp_path / "body.fmu"
    assert main(["export", str(h5), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no C compiler" in err and "CC" in err and "apt-get install gcc" in err and "Traceback" not in err
    assert set(tmp_path.iterdir()) == {empty, h5}
    monkeypatch.setenv("CC", "no-such-cc")
    with pytest.raises(FlexmorError, match="CC='no-such-cc' is not found"):
        export(bodies["clamped"], out)


def test_failed_compilation_names_the_compiler_and_leaves_no_file(tmp_path, bodies, monkeypatch):
    if shutil.which("false") is None:
        pytest.skip("no 'false' program to stand for a failing compiler")
    monkeypatch.setenv("CC", "false")
    out = tmp_path / "body.fmu"
    with pytest.raises(FlexmorError, match="could not build the FMU"):
        export(bodies["clamped"], out)
    assert list(tmp_path.iterdir()) == []
