"""Geometric stiffening of preloaded models (:mod:`flexmor.preload`) on the CalculiX C3D8 cantilever of
``tests/data/calculix`` (1 x 0.1 x 0.1 m steel, 10 x 2 x 2 elements): the stiffness under tension and
compression against the Euler-Bernoulli beam, loads, and refusals. Against CalculiX itself:
``tests/test_preload_ccx.py``."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from helpers import run, run_json
from scipy.integrate import quad

from flexmor.errors import ModelError
from flexmor.io import read, read_body
from flexmor.linalg.eigen import eigenmodes
from flexmor.preload import (
    geometric_stiffness,
    parse_preload,
    preload_load,
    preload_stiffness,
    spin_softening,
    with_preload,
)
from flexmor.stress import INTEGRATION_WEIGHTS

DATA = Path(__file__).parent / "data" / "calculix"
RHO, AREA, LENGTH = 7850.0, 0.01, 1.0


@pytest.fixture(scope="module")
def clamped():
    return read(DATA / "beam8_clamped_mat.sti")


@pytest.fixture(scope="module")
def free():
    return read(DATA / "beam8_free_mat.sti")


def _first(K, M) -> float:
    return float(eigenmodes(K, M, 2)[0][0])


def test_weights_integrate_the_reference_volume():
    volume = {"C3D8": 8, "C3D8R": 8, "C3D20": 8, "C3D20R": 8, "C3D4": 1 / 6, "C3D10": 1 / 6, "C3D6": 1, "C3D15": 1}
    for etype, w in INTEGRATION_WEIGHTS.items():
        assert w.sum() == pytest.approx(volume[etype], rel=1e-12), etype


def test_geometric_stiffness_is_symmetric_and_linear(clamped):
    u = np.random.default_rng(1).standard_normal(clamped.n_dof) * 1e-4
    KG = geometric_stiffness(clamped, u)
    assert KG.shape == clamped.K.shape
    assert abs(KG - KG.T).max() <= 1e-12 * abs(KG).max()
    assert abs(geometric_stiffness(clamped, 2 * u) - 2 * KG).max() <= 1e-9 * abs(KG).max()
    assert geometric_stiffness(clamped, 0 * u).nnz == 0 or abs(geometric_stiffness(clamped, 0 * u)).max() == 0


def test_tension_stiffens_compression_softens(clamped):
    lam0 = _first(clamped.K, clamped.M)
    up = _first(preload_stiffness(clamped, "TIP:x=5e5").K, clamped.M)
    down = _first(preload_stiffness(clamped, "TIP:x=-5e5").K, clamped.M)
    assert up > 1.05 * lam0  # first bending frequency: more than 2.5 % up (f^2 5 %)
    assert down < 0.95 * lam0


def test_slope_of_the_squared_frequency_in_the_tension_is_the_beam_limit(clamped):
    """Euler-Bernoulli: d(omega^2)/dP = int phi'^2 / (rho A int phi^2) for the cantilever's first mode phi; f^2 is
    linear in the tension."""
    P = 1e4
    lam = {s: _first(preload_stiffness(clamped, f"TIP:x={s * P}").K, clamped.M) for s in (1, -1)}
    lam0 = _first(clamped.K, clamped.M)
    slope = (lam[1] - lam[-1]) / (2 * P)
    b = 1.875104068711961
    s = (np.cosh(b) + np.cos(b)) / (np.sinh(b) + np.sin(b))

    def phi(x):
        return np.cosh(b * x) - np.cos(b * x) - s * (np.sinh(b * x) - np.sin(b * x))

    def dphi(x):
        return b * (np.sinh(b * x) + np.sin(b * x) - s * (np.cosh(b * x) - np.cos(b * x)))

    ratio = quad(lambda x: dphi(x) ** 2, 0, 1)[0] / quad(lambda x: phi(x) ** 2, 0, 1)[0]
    beam = ratio / (RHO * AREA * LENGTH ** 2)
    assert slope == pytest.approx(beam, rel=0.01)
    assert abs(lam[1] + lam[-1] - 2 * lam0) <= 1e-3 * (lam[1] - lam[-1])  # linear


def test_loads_add_up_to_the_total(free, clamped):
    mass = free.mass_properties()["mass"][2]
    F, pre = preload_load(free, ["gravity:0,0,-9.81"])
    assert pre[0].kind == "gravity"
    z = free.dofs[:, 1] == 3
    assert F[z].sum() == pytest.approx(-9.81 * mass, rel=1e-9)
    assert np.abs(F[~z]).max() == 0
    w = 30.0
    F, _ = preload_load(free, f"spin:0,0,{w}")
    x = free.dofs[:, 1] == 1
    com = free.mass_properties()["center_of_mass"]
    assert F[x].sum() == pytest.approx(mass * w * w * com[0], rel=1e-9)
    assert F[free.dofs[:, 1] == 3].sum() == pytest.approx(0, abs=1e-9 * mass * w * w)
    F, _ = preload_load(clamped, ["TIP:y=100", "TIP:y=-40"])
    assert F.sum() == pytest.approx(60.0)


def test_spin_softening_is_minus_the_centrifugal_mass(free):
    S = spin_softening(free, (0, 0, 2.0))
    v = np.where(free.dofs[:, 1] == 1, 1.0, 0.0)  # uniform x: softened by -w^2 m
    assert v @ S @ v == pytest.approx(-4.0 * (v @ free.M @ v), rel=1e-12)
    zz = np.where(free.dofs[:, 1] == 3, 1.0, 0.0)  # along the axis: not softened
    assert abs(zz @ S @ zz) <= 1e-12 * abs(v @ S @ v)


def test_free_model_is_refused(free):
    with pytest.raises(ModelError, match="supported model.*moves freely") as err:
        preload_stiffness(free, "spin:0,0,100")
    assert "spec" in err.value.params


@pytest.mark.parametrize("spec, words", [("TIP:x", "NODE:DIR=F"), ("TIP:rx=3", "direction x, y or z"),
                                         ("TIP:x=abc", "not a number"), ("spin:1,2", "three numbers"),
                                         ("gravity:0,0,nan", "three numbers")])
def test_bad_specs(spec, words):
    with pytest.raises(ModelError, match=words):
        parse_preload(spec)


def test_unknown_set_and_missing_elements(clamped):
    with pytest.raises(Exception, match="NOPE"):
        preload_stiffness(clamped, "NOPE:x=1")
    with pytest.raises(ModelError, match="no elements"):
        preload_stiffness(dataclasses.replace(clamped, elements=None), "TIP:x=1")


# -- command line -------------------------------------------------------------------------------------
def test_info_shows_frequencies_with_and_without_the_preload(capsys, clamped):
    out = run_json(capsys, "info", DATA / "beam8_clamped_mat.sti", "--preload", "TIP:x=4e5", "--preload", "TIP:x=1e5",
                   "--modes", "4")
    pre = out["preload"]
    assert pre["specs"] == ["TIP:x=4e5", "TIP:x=1e5"]
    lam = eigenmodes(preload_stiffness(clamped, "TIP:x=5e5").K, clamped.M, 4)[0]
    assert np.allclose(out["frequencies_hz"], np.sqrt(lam) / (2 * np.pi), rtol=1e-8)
    lam0 = eigenmodes(clamped.K, clamped.M, 4)[0]
    assert np.allclose(pre["frequencies_unloaded_hz"], np.sqrt(lam0) / (2 * np.pi), rtol=1e-8)
    assert out["frequencies_hz"][0] > 1.025 * pre["frequencies_unloaded_hz"][0]
    code, text, _ = run(capsys, "info", DATA / "beam8_clamped_mat.sti", "--preload", "TIP:x=-5e5", "--modes", "2")
    assert code == 0
    assert "preload   TIP:x=-5e5" in text and "without preload" in text and "-3." in text


def test_reduce_projects_the_preloaded_stiffness(capsys, tmp_path, clamped):
    body = tmp_path / "pre.h5"
    run_json(capsys, "reduce", DATA / "beam8_clamped_mat.sti", "--method", "modal", "--order", "4", "--input",
             "TIP:y", "--preload", "gravity:0,0,-9.81", "--preload", "TIP:x=5e5", "--no-error", "-o", body)
    red = read_body(body)
    K = preload_stiffness(clamped, ["gravity:0,0,-9.81", "TIP:x=5e5"]).K
    assert np.allclose(red.K, red.V.T @ (K @ red.V), rtol=1e-9, atol=1e-9 * np.abs(red.K).max())
    assert red.info["preload"]["specs"] == ["gravity:0,0,-9.81", "TIP:x=5e5"]
    assert red.info["preload"]["spin_softening"] is False
    # judged against the model with the same preload: given, or (without --preload) the one the body records;
    # another preload is another model
    given = run_json(capsys, "compare", DATA / "beam8_clamped_mat.sti", body, "--preload", "gravity:0,0,-9.81",
                     "--preload", "TIP:x=5e5")
    recorded = run_json(capsys, "compare", DATA / "beam8_clamped_mat.sti", body)
    assert recorded["results"][0]["band_error"] == pytest.approx(given["results"][0]["band_error"], rel=1e-12)
    code, _, err = run(capsys, "compare", DATA / "beam8_clamped_mat.sti", body, "--preload", "TIP:x=4e5")
    assert code != 0 and "different stiffness matrix K" in err
    code, _, err = run(capsys, "export", body, "--model", DATA / "beam8_clamped_mat.sti", "--allow-clamped",
                       "-o", tmp_path / "pre.SID_FEM")
    assert code == 0 and "geometric stiffness of preload gravity:0,0,-9.81 TIP:x=5e5" in \
        (tmp_path / "pre.SID_FEM").read_text().splitlines()[0]


def test_a_body_preloaded_with_a_given_material_is_exported_and_judged_with_it(capsys, tmp_path, clamped):
    """``--material`` replaces the deck's material of the preload's stresses: the body records it, and export
    and compare apply the recorded preload with it (export refused the body before: its own model file gave
    "a different stiffness matrix K"); a model preloaded with the deck's materials is refused naming
    --material."""
    body, model = tmp_path / "mat.h5", DATA / "beam8_clamped_mat.sti"
    run_json(capsys, "reduce", model, "--method", "modal", "--order", "4", "--input", "TIP:y", "--preload",
             "TIP:x=5e5", "--material", "1e11,0.3,7800", "--no-error", "-o", body)
    red = read_body(body)
    K = preload_stiffness(clamped, "TIP:x=5e5", material=(1e11, 0.3, 7800)).K
    assert np.allclose(red.K, red.V.T @ (K @ red.V), rtol=1e-9, atol=1e-9 * np.abs(red.K).max())
    deck = red.V.T @ (preload_stiffness(clamped, "TIP:x=5e5").K @ red.V)
    assert not np.allclose(red.K, deck, rtol=1e-6, atol=0)  # another material is another stiffness
    assert red.info["preload"]["material"]["rho"] == 7800.0
    code, _, err = run(capsys, "export", body, "--model", model, "-o", tmp_path / "mat.mat")
    assert code == 0, err
    recorded = run_json(capsys, "compare", model, body)
    given = run_json(capsys, "compare", model, body, "--preload", "TIP:x=5e5", "--material", "1e11,0.3,7800")
    assert recorded["results"][0]["band_error"] == pytest.approx(given["results"][0]["band_error"], rel=1e-12)
    code, _, err = run(capsys, "compare", model, body, "--preload", "TIP:x=5e5")
    assert code != 0 and "a material given in place of the deck's" in err and "--material" in err
    code, text, _ = run(capsys, "info", body)
    assert "TIP:x=5e5 with a material in place of the deck's" in text


def test_command_line_refusals_name_the_flag(capsys):
    code, _, err = run(capsys, "info", DATA / "beam8_free_mat.sti", "--preload", "spin:0,0,10", "--modes", "2")
    assert code != 0 and "--preload 'spin:0,0,10' needs a supported model" in err
    code, _, err = run(capsys, "info", DATA / "beam8_clamped_mat.sti", "--preload", "TIP:x")
    assert code != 0 and "--preload 'TIP:x': give NODE:DIR=F" in err


def test_with_preload_records_and_refuses_a_second_time(clamped):
    pre = with_preload(clamped, "TIP:x=5e5")
    assert pre.preload["specs"] == ["TIP:x=5e5"] and clamped.preload is None
    assert abs(pre.K - preload_stiffness(clamped, "TIP:x=5e5").K).max() == 0
    with pytest.raises(ModelError, match="preloaded already"):
        with_preload(pre, "TIP:x=1")


@pytest.mark.parametrize("argv", [("info", "--modes", "3"),
                                  ("reduce", "--method", "modal", "--order", "4", "--input", "TIP:y", "--no-error"),
                                  ("reduce", "--method", "krylov", "--order", "8", "--input", "TIP:y", "--no-error")])
def test_a_preload_beyond_buckling_is_refused(capsys, tmp_path, argv):
    """A compression above the buckling load makes K + K_G indefinite: its negative eigenvalues were shown as
    '2 rigid-body modes', modal dropped the unstable modes silently (band_error 1.00 written), krylov failed with
    PARDISO's 'zero pivot'. Below the load the body reduces (and softens)."""
    from helpers import CLAMPED

    extra = ["-o", str(tmp_path / "b.h5")] if argv[0] == "reduce" else []
    code, out, err = run(capsys, argv[0], CLAMPED, "--preload", "TIP:x=-1e7", *argv[1:], *extra)
    assert code == 2 and ("negative eigenvalue" in err or "is not positive definite" in err), err
    assert "the --preload (TIP:x=-1e7) exceeds the body's buckling load: K + K_G is indefinite" in err
    assert "rigid" not in err and not (tmp_path / "b.h5").exists()
    code, out, err = run(capsys, argv[0], CLAMPED, "--preload", "TIP:x=-3e6", *argv[1:], *extra)
    assert code == 0, err


def test_a_preloaded_body_says_so(capsys, tmp_path):
    """info of the body and the report name its preload; a model with another preload (or none) is refused
    naming the preloads (it said only 'a different stiffness matrix K (the body's model: beam8_clamped_mat.sti;
    this model: beam8_clamped_mat.sti)')."""
    from helpers import CLAMPED

    body = tmp_path / "pre.h5"
    code, _, err = run(capsys, "reduce", CLAMPED, "--preload", "TIP:x=2e6", "--method", "krylov", "--order", "8",
                       "--input", "TIP:y", "-o", body)
    assert code == 0, err
    code, out, _ = run(capsys, "info", body)
    assert code == 0 and "preload     TIP:x=2e6: its K holds their geometric stiffness" in out
    code, _, err = run(capsys, "compare", CLAMPED, body, "--preload", "TIP:x=1e6")
    assert code == 2 and "the body was reduced with the --preload TIP:x=2e6 (its K holds the geometric " \
                         "stiffness), this model has the --preload TIP:x=1e6" in err
    code, out, err = run(capsys, "compare", CLAMPED, body)
    assert code == 0 and "preload TIP:x=2e6: the model stiffened by the preload the bodies record" in out, err
    code, _, err = run(capsys, "report", CLAMPED, body, "-o", tmp_path / "r.html")
    assert code == 0, err
    assert "Preload TIP:x=2e6: K holds its geometric stiffness." in (tmp_path / "r.html").read_text()
