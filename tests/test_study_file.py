"""Study files: ``flexmor reduce ... --save-study`` writes the whole study; ``flexmor run`` and
``flexmor.System.from_study`` reproduce the same body (K, M, V equal) and record; an unknown key or a
changed model file is refused naming it; bodies record their study."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import CCX, run, run_json

import flexmor
from flexmor.errors import ModelError, OptionError
from flexmor.io import read_body

FLAGS = ["--input", "END@rbe2:y", "--select", "END=box:0.9,0,0,1,1,1", "--interface", "END@rbe2",
         "--rayleigh", "0:1e-6", "--band", "10:3000", "--preload", "TIP:x=5e5", "--material", "2.1e11,0.3,7850",
         "--n-freq", "30"]


@pytest.fixture
def folder(tmp_path):
    for f in CCX.glob("beam8_clamped_mat.*"):
        shutil.copy(f, tmp_path / f.name)
    return tmp_path


def _same(a, b):
    for name in ("M", "K", "D", "B", "C", "V"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None) and (x is None or np.array_equal(x, y)), name


MEASURES = ("order", "band_error", "max_rel_error", "hinf_error", "frequencies_hz")


def test_a_saved_study_reproduces_the_body_from_the_command_line_and_from_python(capsys, folder, monkeypatch):
    monkeypatch.chdir(folder)
    made = run_json(capsys, "reduce", "beam8_clamped_mat.sti", "--method", "krylov", "--order", "6", *FLAGS,
                    "--points", "0,1000j", "-o", "b.h5", "--save-study", "s.toml", "--no-cache")
    assert made["study"] == "s.toml"
    text = (folder / "s.toml").read_text()
    assert 'file = "beam8_clamped_mat.sti"' in text and 'points = "0,1000j"' in text and "material = [" in text
    # moved elsewhere with its model: the paths are the study file's own
    moved = folder / "moved"
    moved.mkdir()
    for f in folder.glob("beam8_clamped_mat.*"):
        shutil.copy(f, moved / f.name)
    shutil.copy(folder / "s.toml", moved / "s.toml")
    again = run_json(capsys, "run", moved / "s.toml", "-o", moved / "b.h5")
    body, cli = read_body(folder / "b.h5"), read_body(moved / "b.h5")
    _same(body, cli)
    assert all(made[k] == again[k] for k in MEASURES) and made["couplings"] == again["couplings"] == ["END@rbe2"]
    system = flexmor.System.from_study(moved / "s.toml", cache=False)
    assert system.recipe["method"] == "krylov" and system.preparation["preload"] == ["TIP:x=5e5"]
    py = system.reduce()
    _same(body, py)
    assert py.info["study"]["reduce"] == {"method": "krylov", "order": 6, "inertia_loads": "auto",
                                          "options": {"points": "0,1000j"}}
    assert body.info["study"]["model"]["sha256"] == py.info["study"]["model"]["sha256"]
    # the record too (the judgement of the Python path)
    _, record = system.reduce_and_judge()
    assert all(record[k] == made[k] for k in MEASURES)


def test_python_saves_a_study_the_command_line_runs(capsys, folder):
    system = flexmor.System(folder / "beam8_clamped_mat.sti", inputs=["TIP:y"], band=(10, 2000),
                            damping={"modal_damping": 0.01}, select=["END=box:0.9,0,0,1,1,1"])
    body = system.reduce("craig-bampton", 60, interface=["END"])
    system.save_study(folder / "py.toml", "craig-bampton", 60, {"interface": ["END"]}, judge={"error": False})
    run_json(capsys, "run", folder / "py.toml", "-o", folder / "c.h5")
    _same(body, read_body(folder / "c.h5"))
    code, text, _ = run(capsys, "info", folder / "c.h5")  # the body names its study
    assert code == 0 and "beam8_clamped_mat.sti (SHA-256 " in text and "select END=box:0.9,0,0,1,1,1" in text
    assert 'file = "beam8_clamped_mat.sti"' in (folder / "py.toml").read_text()


def _saved(capsys, folder):
    """The study file of a small krylov body of the folder's beam."""
    run_json(capsys, "reduce", folder / "beam8_clamped_mat.sti", "--method", "krylov", "--order", "6",
             "--input", "TIP:y", "--points", "0", "--no-error", "-o", folder / "b.h5", "--save-study",
             folder / "s.toml")
    return folder / "s.toml"


@pytest.mark.parametrize("edit, error, match", [
    (lambda t: t.replace("[ports]", "[ports]\nouputs = [\"TIP:y\"]"), OptionError,
     r"unknown key 'ports.ouputs' in the study file \(did you mean 'ports.outputs'\?\)"),
    (lambda t: t.replace("[judge]", "[jugde]"), OptionError, r"unknown key 'jugde'.*did you mean 'judge'"),
    (lambda t: t.replace("order = 6", "order = \"6\""), OptionError, "reduce.order must be an integer"),
    (lambda t: t.replace("[model]", "[model"), flexmor.errors.ReadError, "not a study file"),
])
def test_a_study_file_with_an_unknown_or_wrong_key_is_refused_naming_it(capsys, folder, edit, error, match):
    path = _saved(capsys, folder)
    path.write_text(edit(path.read_text()))
    with pytest.raises(error, match=match):
        flexmor.System.from_study(path)
    code, _, err = run(capsys, "run", path, "-o", folder / "c.h5")
    assert code == 2 and str(path) in err and not (folder / "c.h5").exists()


def _scale_first_entry(path):
    lines = path.read_text().splitlines()
    i, j, v = lines[0].split()
    path.write_text("\n".join([f"{i} {j} {float(v) * 1.001:.17e}", *lines[1:]]) + "\n")


def test_a_changed_model_file_is_refused_naming_it(capsys, folder):
    _saved(capsys, folder)
    sti = folder / "beam8_clamped_mat.sti"
    text = sti.read_text()
    _scale_first_entry(sti)
    with pytest.raises(ModelError, match="beam8_clamped_mat.sti changed since the study was saved"):
        flexmor.System.from_study(folder / "s.toml")
    # a companion file (the mass matrix) changed: the prepared model's fingerprint says so
    sti.write_text(text)
    _scale_first_entry(folder / "beam8_clamped_mat.mas")
    with pytest.raises(ModelError, match="is not the one the study was saved with"):
        flexmor.System.from_study(folder / "s.toml")
    code, _, err = run(capsys, "run", folder / "s.toml", "-o", folder / "c.h5")
    assert code == 2 and "s.toml" in err and "mass matrix" in err


def test_a_study_needs_a_model_file():
    system = flexmor.System(flexmor.io.read(CCX / "beam8_clamped_mat.sti"), inputs=["TIP:y"])
    with pytest.raises(OptionError, match="records the model's file"):
        system.study("krylov", 4)
    assert system.reduce("krylov", 4, points="0").info["study"] is None
    with pytest.raises(OptionError, match="reduce needs a method"):
        system.reduce()
