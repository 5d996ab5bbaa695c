"""The body in its own modes (flexmor.modal), the mode table, and bodies trimmed to chosen modes with
the error of what is written (flexmor.analysis.mode_selection, ``flexmor export --modal-form``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.io
from helpers import CLAMPED, FREE, run, run_json

import flexmor
from flexmor.analysis.mode_selection import REFERENCE_BODY, REFERENCE_FULL, trim
from flexmor.damping import Rayleigh
from flexmor.errors import OptionError
from flexmor.modal import keep_modes, modal_form, mode_table
from flexmor.rigid import rigid_motions

BAND = (10.0, 3000.0)
F = np.array([50.0, 620.0, 1500.0, 2900.0])


@pytest.fixture(scope="module")
def beam():
    return flexmor.System(CLAMPED, inputs=["TIP:y", "TIP:z"], band=BAND, damping=Rayleigh(0.0, 1e-6), cache=False)


@pytest.fixture(scope="module")
def free_study():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return flexmor.System(FREE, inputs=["TIP:y"], band=BAND, damping=Rayleigh(0.0, 1e-6), cache=False)


def test_modal_form_is_the_same_body_with_diagonal_matrices(beam):
    body = beam.reduce("krylov", 12)
    m = modal_form(body)
    assert np.allclose(m.M, np.eye(12), atol=0) and np.count_nonzero(m.K - np.diag(np.diag(m.K))) == 0
    assert np.abs(m.D - np.diag(np.diag(m.D))).max() <= 1e-12 * np.abs(m.D).max()  # Rayleigh: diagonal
    # two eigen solves of (Kr, Mr): the lowest frequency to ~eps (f_max/f_min)^2 = 1.6e-12 and Mr's condition
    np.testing.assert_allclose(np.sqrt(np.diag(m.K)) / (2 * np.pi), body.frequencies_hz(), rtol=1e-10)
    H, Hm = body.frf(F), m.frf(F)
    assert np.abs(Hm - H).max() <= 1e-10 * np.abs(H).max()
    q = np.linalg.solve(body.K, body.B[:, 0])  # the same static field through either basis
    eta = np.linalg.solve(m.K, m.B[:, 0])
    assert np.abs(m.V @ eta - body.V @ q).max() <= 1e-10 * np.abs(body.V @ q).max()
    assert beam.judge(m).band_error == pytest.approx(beam.judge(body).band_error, rel=1e-3, abs=1e-14)


def test_modal_form_leaves_the_rigid_body_modes_of_a_free_body_out(free_study):
    with_rigid = free_study.reduce("modal", 16, rigid="include")
    m = modal_form(with_rigid)
    assert m.order == 10 and m.info["modal_form"] == {"order_before": 16, "n_rigid_left_out": 6}
    assert m.info["n_rigid_excluded"] == 6 and m.frequencies_hz()[0] > 600  # 620.7 Hz: the first elastic mode
    elastic = free_study.reduce("modal", 10)  # the same ten elastic modes, reduced without rigid motion
    np.testing.assert_allclose(m.frequencies_hz(), elastic.frequencies_hz(), rtol=1e-9)
    assert free_study.judge(m).judged == free_study.judge(elastic).judged
    assert free_study.judge(m).band_error == pytest.approx(free_study.judge(elastic).band_error, rel=1e-6)


def test_effective_masses_of_a_free_body_sum_to_its_mass_and_inertia(free_study):
    body = free_study.reduce("modal", 16, rigid="include")
    rows = mode_table(body, band=BAND)
    model = free_study.model
    R = rigid_motions(model, origin=np.zeros(3))
    total = np.einsum("ij,ij->j", R, model.M @ R)  # mass x y z, inertia about the x y z axes
    assert total[0] == pytest.approx(78.5, rel=1e-12)  # steel 1 x 0.1 x 0.1 m
    eff = np.array([r["effective_mass"] + r["effective_inertia"] for r in rows])
    np.testing.assert_allclose(eff.sum(axis=0), total, rtol=1e-10)
    assert [r["rigid"] for r in rows] == [True] * 6 + [False] * 10
    for a in range(3):  # the rigid-body modes in the frame's order: all the mass in x in the first, ...
        assert eff[a, a] == pytest.approx(total[a], rel=1e-10)
    assert np.abs(eff[6:]).max() <= 1e-10 * total[0]  # elastic modes of a free body carry none
    assert body.info["frame_mass"] == pytest.approx(total.tolist(), rel=1e-12)
    shares = np.array([r["response_share"] for r in rows])
    assert shares.sum() == pytest.approx(1.0, rel=1e-12) and np.all(shares >= 0)


def test_effective_masses_of_a_clamped_body_grow_with_its_modes(beam):
    small, large = (mode_table(beam.reduce("modal", r)) for r in (4, 16))
    y4, y16 = (sum(r["effective_mass"][1] for r in rows) for rows in (small, large))
    mass_y = beam.reduce("modal", 4).info["frame_mass"][1]
    assert 0 < y4 < y16 < mass_y  # the clamped nodes' mass is in no mode (they are no equations)
    assert y16 > 0.9 * mass_y
    z = [r["damping_ratio"] for r in small]  # Rayleigh beta: zeta = beta omega / 2
    np.testing.assert_allclose(z, [1e-6 * np.pi * r["frequency_hz"] for r in small], rtol=1e-9)


def test_trim_by_frequency_and_its_error_against_the_full_model(beam):
    body = beam.reduce("modal", 20)
    trimmed, rec = trim(body, band=BAND, max_frequency=5000.0, full=beam.full, static=False)  # the modes alone
    kept = body.frequencies_hz() <= 5000.0
    assert rec["reference"] == REFERENCE_FULL and rec["order"] == kept.sum() == trimmed.order
    assert rec["static_vectors"] == 0
    # by default with the static response of the modes left out: no worse, and as many modes
    with_static, srec = trim(body, band=BAND, max_frequency=5000.0, full=beam.full)
    assert srec["modes_kept"] == rec["modes_kept"] and srec["order"] == kept.sum() + srec["static_vectors"]
    assert srec["band_error"] <= rec["band_error"]
    assert rec["modes_kept"] == (np.flatnonzero(kept) + 1).tolist()
    assert rec["band_error"] == pytest.approx(beam.judge(trimmed).band_error, rel=1e-12)
    assert rec["band_error"] > beam.judge(body).band_error
    _, own = trim(body, band=BAND, max_frequency=5000.0)
    assert own["reference"] == REFERENCE_BODY and 0 < own["band_error"] < 10 * rec["band_error"]
    with pytest.raises(OptionError, match="below the body's lowest elastic mode"):
        trim(body, band=BAND, max_frequency=50.0)


def test_select_modes_by_response_keeps_fewer_modes_than_by_frequency():
    """Inputs and outputs in y only: the z bending modes carry no response and are left out."""
    s = flexmor.System(CLAMPED, inputs=["TIP:y"], band=BAND, damping=Rayleigh(0.0, 1e-6), cache=False)
    body = s.reduce("modal", 20)
    tol = 1e-4
    trimmed, rec = trim(body, band=BAND, tol=tol, full=s.full, static=False)
    assert rec["tol_reached"] and rec["band_error"] <= tol and trimmed.order < 20
    assert s.judge(trimmed).band_error == pytest.approx(rec["band_error"], rel=1e-12)
    lowest = keep_modes(modal_form(body), np.arange(trimmed.order))  # as many modes, the lowest ones
    assert s.judge(lowest).band_error > tol
    _, missed = trim(body, band=BAND, tol=1e-30, full=s.full, static=False)
    assert not missed["tol_reached"] and missed["order"] == 20


def test_export_modal_form_and_trimmed_bodies(capsys, tmp_path):
    run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "20", "--input", "TIP:y", "--band",
             "10:3000", "--rayleigh", "0:1e-6", "-o", tmp_path / "m.h5")
    rec = run_json(capsys, "export", tmp_path / "m.h5", "-o", tmp_path / "m.mat", "--modal-form")
    data = scipy.io.loadmat(tmp_path / "m.mat")
    assert rec["modal_form"]["order"] == 20 and np.allclose(data["Mr"], np.eye(20), atol=1e-15)
    assert np.count_nonzero(data["Kr"] - np.diag(np.diag(data["Kr"]))) == 0
    rec = run_json(capsys, "export", tmp_path / "m.h5", "-o", tmp_path / "t.ss.npz", "--max-frequency", "6000",
                   "--model", CLAMPED)
    mf = rec["modal_form"]
    assert mf["reference"] == REFERENCE_FULL and mf["max_frequency_hz"] <= 6000 and len(mf["modes_kept"]) < 20
    assert mf["order"] == len(mf["modes_kept"]) + mf["static_vectors"]
    ss = np.load(tmp_path / "t.ss.npz")
    assert ss["A"].shape == (2 * mf["order"], 2 * mf["order"])
    code, out, _ = run(capsys, "export", tmp_path / "m.h5", "-o", tmp_path / "s.mat", "--select-modes", "auto",
                       "--tol", "1e-4", "--model", CLAMPED)
    assert code == 0 and "--tol 0.0001 on band_error: met" in out and "against the full model" in out
    code, _, err = run(capsys, "export", tmp_path / "m.h5", "-o", tmp_path / "x.mat", "--select-modes", "auto")
    assert code == 2 and "--select-modes auto needs --tol" in err


def test_info_mode_table_of_a_free_body(capsys, tmp_path):
    run_json(capsys, "reduce", FREE, "--method", "modal", "--order", "14", "--rigid", "include", "--input", "TIP:y",
             "--no-error", "-o", tmp_path / "r.h5")
    rec = run_json(capsys, "info", tmp_path / "r.h5", "--modes")
    table = rec["modes"]
    assert table["n_modes"] == 14 and len(table["rows"]) == 14
    np.testing.assert_allclose(table["sums"]["effective_mass"], table["model_mass"][:3], rtol=1e-10)
    np.testing.assert_allclose(table["sums"]["effective_inertia"], table["model_mass"][3:], rtol=1e-10)
    code, out, _ = run(capsys, "info", tmp_path / "r.h5", "--modes", "8")
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith(" mode  frequency"))
    assert lines[head + 1].split()[:3] == ["1", "0", "-"] and lines[head + 1].split()[3] == "78.5"
    assert lines[head + 7].split()[1] == "620.672" and "(all 14 modes)" in lines[head + 9]


def test_sid_export_of_a_free_body_in_modal_form(capsys, tmp_path):
    from flexmor.io.sid import read_sid

    run_json(capsys, "reduce", FREE, "--method", "krylov", "--order", "12", "--input", "TIP:y", "--input",
             "FIX@rbe2:all", "--band", "10:3000", "--rayleigh", "0:1e-6", "-o", tmp_path / "k.h5")
    rec = run_json(capsys, "export", tmp_path / "k.h5", "-o", tmp_path / "k.SID_FEM", "--modal-form",
                   "--max-frequency", "4000", "--model", FREE, "--no-static-vectors")
    sid = read_sid(tmp_path / "k.SID_FEM")
    assert sid.nq == rec["modal_form"]["order"] < 12
    np.testing.assert_allclose(sid.frequencies_hz(), rec["modal_form"]["frequencies_hz"], rtol=1e-6)
    assert sid.mass == pytest.approx(78.5, rel=1e-10)


def test_trim_of_an_undamped_body_without_the_full_model():
    """An undamped body trimmed against itself: its |H|^2 has poles, so its reference grid is not refined (it
    was, towards a pole, until a point fell on one: numpy's 'Singular matrix' from export --modal-form, here
    for krylov 12 of the built-in cantilever, after 'grid refinement stopped ... gap 5.0e-01')."""
    from flexmor.models import cantilever
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    model = cantilever(2)
    body = reduce(model, "krylov", 12, make_ports(model, ["TIP:y"]))
    trimmed, rec = trim(body, band=(1.0, 1000.0))
    assert rec["reference"] == REFERENCE_BODY and rec["order"] == 12 and rec["band_error"] < 1e-12
    np.testing.assert_allclose(trimmed.frequencies_hz(), body.frequencies_hz(), rtol=1e-9)
    trimmed, rec = trim(body, band=(1.0, 1000.0), max_frequency=600.0)
    assert len(rec["modes_kept"]) == int(np.sum(body.frequencies_hz() <= 600.0)) < 12


def test_a_trimmed_body_says_what_it_is(capsys, tmp_path):
    """The body export --modal-form --max-frequency writes carries its own order note and error record (info said
    'order 7 (20 requested)' and 'errors not evaluated' although export had judged it)."""
    run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "20", "--input", "TIP:y", "--rayleigh",
             "5:2e-6", "--band", "10:3000", "-o", tmp_path / "k.h5")
    out = run_json(capsys, "export", tmp_path / "k.h5", "--model", CLAMPED, "--modal-form", "--max-frequency",
                   "3000", "-o", tmp_path / "m.h5")
    rec = out["modal_form"]
    body = flexmor.io.read_body(tmp_path / "m.h5")
    assert body.order == rec["order"] == len(rec["modes_kept"]) + rec["static_vectors"] and rec["static_vectors"] > 0
    assert body.order_note == f"modal form: {len(rec['modes_kept'])} of the 20 elastic modes of the body reduced " \
                              f"(up to {rec['max_frequency_hz']:.4g} Hz) and {rec['static_vectors']} static vectors " \
                              "(the static response of the modes left out)"
    assert body.errors["band_error"] == pytest.approx(rec["band_error"], rel=1e-12)
    assert body.errors["judged"] == REFERENCE_FULL and body.errors["band_hz"] == [10.0, 3000.0]
