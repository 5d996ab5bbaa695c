"""The command line as a new user meets it: the closest name on a typo, -v anywhere, ``:all`` ports,
what ``info`` says of a body, short warnings once per run, nearest nodes, output folders, the ui's list."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest
from helpers import CLAMPED, DATA, FREE, run, run_json

import flexmor


def _usage_error(capsys, *argv) -> str:
    with pytest.raises(SystemExit) as exc:
        run(capsys, *argv)
    assert exc.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


def test_typos_get_the_closest_name(capsys):
    assert _usage_error(capsys, "reduse", CLAMPED).endswith("did you mean 'reduce'?")
    err = _usage_error(capsys, "reduce", CLAMPED, "--method", "modal", "--ordr", "6", "--input", "TIP:y")
    assert "unrecognized arguments: --ordr 6 (--ordr: did you mean '--order'?)" in err
    err = _usage_error(capsys, "reduce", CLAMPED, "--method", "krylof", "--order", "6", "--input", "TIP:y")
    assert "did you mean 'krylov'?" in err
    err = _usage_error(capsys, "reduce", CLAMPED, "--method", "modal", "--full-frf", "dirct")
    assert "did you mean 'direct'?" in err
    code, _, err = run(capsys, "info", CLAMPED, "--format", "calculx")
    assert code == 2 and "--format='calculx' is not a known FE model file type; did you mean 'calculix'?" in err
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "6", "--input", "TPI:y")
    assert code == 2 and "'TPI' is neither a node id nor a node set; did you mean 'TIP'?" in err
    code, _, err = run(capsys, "info", CLAMPED, "--interface", "TPI@rbe2")
    assert code == 2 and "did you mean 'TIP'?" in err
    code, _, err = run(capsys, "info", CLAMPED, "--select", "A=set:TPI")
    assert code == 2 and "did you mean 'TIP'?" in err


def test_short_method_names(capsys, tmp_path):
    for alias, method in (("fw", "fw-sobt"), ("cb", "craig-bampton")):
        extra = ["--interface", "TIP"] if alias == "cb" else []
        order = "33" if alias == "cb" else "8"
        rec = run_json(capsys, "reduce", CLAMPED, "--method", alias, "--order", order, "--input", "TIP:y", *extra,
                       "--no-error", "-o", tmp_path / f"{alias}.h5")
        assert rec["method"] == method


def test_verbose_after_the_command(capsys):
    code, out, err = run(capsys, "info", CLAMPED, "-v")
    assert code == 0 and f"read {CLAMPED} ..." in err and "DOF" in out
    code, out, quiet = run(capsys, "info", CLAMPED)
    assert code == 0 and "read " not in quiet


def test_all_directions_of_a_coupling_master_and_of_a_set(capsys, tmp_path):
    rec = run_json(capsys, "reduce", FREE, "--method", "krylov", "--order", "18", "--input", "FIX@rbe2:all",
                   "--output", "TIP:all", "--no-error", "-o", tmp_path / "k.h5")
    body = flexmor.read_body(tmp_path / "k.h5")
    assert body.input_names == [f"FIX@rbe2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")]
    assert body.output_names == ["TIP:x", "TIP:y", "TIP:z"]  # a solid's nodes: translations only
    assert rec["couplings"] == ["FIX@rbe2"] and body.B.shape[1] == 6 and body.C.shape[0] == 3


def test_info_of_a_body_counts_rigid_and_elastic_coordinates(capsys, tmp_path):
    args = ("reduce", FREE, "--method", "modal", "--input", "TIP:y", "--input", "FIX@rbe2:y", "--no-error")
    run_json(capsys, *args, "--order", "10", "-o", tmp_path / "e.h5")
    run_json(capsys, *args, "--order", "11", "--rigid", "include", "-o", tmp_path / "r.h5")  # 6 rigid, 5 elastic
    code, out, _ = run(capsys, "info", tmp_path / "e.h5")
    assert code == 0
    assert "coordinates 10: 0 rigid-body, 10 elastic (6 rigid-body modes excluded from the basis" in out
    assert "SID/Exudyn export: 10 elastic coordinates" in out
    assert "FIX@RBE2: master node" in out and "9 slave nodes" in out
    rec = run_json(capsys, "info", tmp_path / "r.h5")
    assert rec["coordinates"] == {"n": 11, "rigid": 6, "elastic": 5, "rigid_excluded_from_basis": 0,
                                  "mbs_export": 5, "mbs_export_needs_remove_rigid": True}
    code, out, _ = run(capsys, "info", tmp_path / "r.h5")
    assert "11: 6 rigid-body, 5 elastic; SID/Exudyn export: 5 elastic coordinates with --remove-rigid" in out


@pytest.mark.skipif(shutil.which("ccx") is None, reason="CalculiX (ccx) is not installed")
def test_the_singular_mass_note_of_a_c3d10_model_is_short_stable_and_once(capsys, tmp_path):
    """CalculiX's C3D10 mass is singular: info states the note in full (stdout, once, the same in every run);
    reduce says it in one short line naming the note, which --quiet-note silences."""
    sys.path.insert(0, str(Path(__file__).parent))
    from ccx_models import deck
    from ccx_models import run as run_ccx

    text, _ = deck("C3D10", n=(6, 2, 2), clamped=False)
    sti = run_ccx(tmp_path, "free", text)
    texts = []
    for _ in range(2):
        code, out, err = run(capsys, "info", sti, "--modes", "8")
        lines = [ln for ln in out.splitlines() if ln.startswith("note singular-mass:")]
        assert code == 0 and len(lines) == 1 and "mass matrix" not in err
        texts.append(lines[0])
    assert texts[0] == texts[1]  # no estimate that changes between runs
    assert "C3D20R elements" not in texts[0] and "(C3D10 elements): the mass matrix is singular" in texts[0]
    base = ["reduce", sti, "--method", "modal", "--order", "4", "--input", "TIP:y", "--no-error", "--force", "-o",
            tmp_path / "m.h5"]
    code, _, err = run(capsys, *base)
    (line,) = [ln for ln in err.splitlines() if "mass matrix" in ln]
    assert code == 0 and line.startswith("flexmor: warning: ") and "(note singular-mass: see flexmor info" in line
    words = line.split(":", 3)[-1].split()
    assert len(words) < 50 and line.split("elements):")[1].split(" (note ")[0].count("singular") == 1
    code, _, err = run(capsys, *base, "--quiet-note", "singular-mass", "--quiet-note", "rigid-body-modes")
    assert code == 0 and "mass matrix" not in err and "rigid-body modes" not in err


def test_nearest_names_the_node_and_its_distance(capsys):
    code, _, err = run(capsys, "info", CLAMPED, "--select", "A=nearest:0.5,0.05,0.05", "--select",
                       "FAR=nearest:50,50,50")
    assert code == 0
    assert "selected A=nearest:0.5,0.05,0.05: node" in err and ", 0 from the point" in err
    far = next(ln for ln in err.splitlines() if ln.startswith("selected FAR"))
    assert "85.91 from the point" in far and "other units?" in far


def test_a_missing_output_folder_is_refused_not_created(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "6", "--input", "TIP:y",
                       "--no-error", "-o", "nodir/x.h5")
    assert code == 2 and "the folder nodir does not exist" in err and not (tmp_path / "nodir").exists()


def test_ui_lists_the_files_a_reader_takes(tmp_path):
    from flexmor.ui.server import Workspace

    for p in (DATA / "ansys").glob("rotorAnsys*.txt"):
        shutil.copy(p, tmp_path)
    (tmp_path / "notes.txt").write_text("not a model\n")
    shutil.copy(CLAMPED, tmp_path)
    shutil.copy(DATA / "nastran" / "pyyeti_rd_ascii.op4", tmp_path)  # OUTPUT4 matrices: a model, not a superelement
    files = Workspace(tmp_path).files()
    assert files["model"] == ["beam8_clamped_mat.sti", "pyyeti_rd_ascii.op4", "rotorAnsysMassMatrixSparse.txt",
                              "rotorAnsysStiffnessMatrixSparse.txt"]
    assert files["body"] == []


def test_report_says_its_band_and_where_it_comes_from(capsys, tmp_path):
    run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "8", "--input", "TIP:y", "--band",
             "10:2000", "-o", tmp_path / "k.h5")
    code, out, err = run(capsys, "report", CLAMPED, tmp_path / "k.h5", "-o", tmp_path / "r.html", "--modes", "4")
    assert code == 0, err
    assert "band 10-2000 Hz: the band the bodies were reduced for" in out


def test_compare_judges_each_body_over_its_own_band(capsys, tmp_path):
    made = {}
    for name, band in (("a", "10:2000"), ("b", "100:4000")):
        made[name] = run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "8", "--input", "TIP:y",
                              "--band", band, "--rayleigh", "0:1e-6", "-o", tmp_path / f"{name}.h5")
    rec = run_json(capsys, "compare", CLAMPED, tmp_path / "a.h5", tmp_path / "b.h5", "--rayleigh", "0:1e-6")
    assert rec["band_hz"] is None and rec["band_source"] == "each body's own"
    for row, name in zip(rec["results"], "ab"):
        assert row["band_hz"] == made[name]["band_hz"] and row["band_source"] == "the band the body was reduced for"
        assert row["band_error"] == pytest.approx(made[name]["band_error"], rel=1e-6)
    code, out, _ = run(capsys, "compare", CLAMPED, tmp_path / "a.h5", tmp_path / "b.h5", "--rayleigh", "0:1e-6")
    assert "bands: each body over its own" in out and "b.h5: 100-4000 Hz (the band the body was reduced for)" in out
    code, out, _ = run(capsys, "report", CLAMPED, tmp_path / "a.h5", tmp_path / "b.h5", "--rayleigh", "0:1e-6",
                       "--modes", "4", "-o", tmp_path / "r.html")
    assert code == 0 and "band 10-4000 Hz: the span of the bands the bodies were reduced for" in out
