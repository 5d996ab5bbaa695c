"""The command-line contract of DESIGN.md, on the real CalculiX exports."""

import shutil
import subprocess
import sys

import numpy as np
import pytest
from helpers import CCX, CLAMPED, FREE, run, run_json

from flexmor.cli import main


def test_info_clamped_matches_calculix(capsys, clamped_ref):
    out = run_json(capsys, "info", CLAMPED, "--modes", "10", "--json")
    assert out["n_dof"] == 270 and out["n_nodes"] == 99
    np.testing.assert_allclose(out["frequencies_hz"], clamped_ref[:10], rtol=1e-5)
    assert out["n_rigid"] == 0


def test_info_free_shows_rigid_modes(capsys, free_ref):
    out = run_json(capsys, "info", FREE, "--modes", "12", "--json")
    assert out["n_rigid"] == 6
    f = np.array(out["frequencies_hz"])
    assert np.all(f[:6] < 1e-2)
    np.testing.assert_allclose(f[6:9], [620.672, 620.672, 1610.433], rtol=1e-5)
    np.testing.assert_allclose(f[6:], free_ref[6:12], rtol=1e-5)
    assert main(["info", FREE, "--modes", "8"]) == 0
    text = capsys.readouterr().out
    assert sum(ln.rstrip().endswith(" rigid") for ln in text.splitlines()) == 6 and "(6 rigid-body modes)" in text
    assert "620.67" in text


def test_reduce_json_and_compare(capsys, tmp_path):
    body = tmp_path / "cb.h5"
    out = run_json(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--order", "33", "--interface", "TIP",
                   "--input", "TIP:y", "--band", "10:3000", "--rayleigh", "0:1e-6", "-o", str(body), "--json")
    for key in ("method", "order", "seconds", "band_hz", "band_error", "max_rel_error", "frequencies_hz", "timings"):
        assert key in out
    assert out["order"] == 33 and out["band_hz"] == [10, 3000]
    from flexmor import __version__

    assert out["flexmor_version"] == __version__
    assert 0 < out["band_error"] < 1
    assert set(out["timings"]) >= {"read", "factorize", "basis", "project", "error"}
    assert body.exists()
    modal = tmp_path / "modal.h5"
    out2 = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "8", "--input", "TIP:y",
                    "--band", "10:3000", "--rayleigh", "0:1e-6", "-o", str(modal), "--json")
    assert out2["band_error"] < 1e-5
    cmp = run_json(capsys, "compare", CLAMPED, str(body), str(modal), "--band", "10:3000", "--json")
    errs = [r["band_error"] for r in cmp["results"]]
    np.testing.assert_allclose(errs, [out["band_error"], out2["band_error"]], rtol=1e-10)


def _copy_beam(tmp_path):
    for ext in ("sti", "mas", "dof", "inp"):
        shutil.copy(CCX / f"beam8_clamped_mat.{ext}", tmp_path / f"b.{ext}")
    return tmp_path / "b.sti"


def _edit(path, lineno, new):
    lines = path.read_text().splitlines(keepends=True)
    lines[lineno - 1] = new
    path.write_text("".join(lines))


BAD = {
    "missing file": (lambda p: p.unlink(), "b.sti: file not found"),
    "missing sibling": (lambda p: p.with_suffix(".mas").unlink(), "b.mas"),
    "truncated line": (lambda p: _edit(p, 5, "2 3\n"), "b.sti:5"),
    "non-numeric": (lambda p: _edit(p, 7, "3 3 abc\n"), "b.sti:7"),
    "index out of range": (lambda p: _edit(p, 9, "3 999 1.0\n"), "b.sti:9"),
    "NaN": (lambda p: _edit(p, 3, "2 2 nan\n"), "b.sti:3"),
    "indefinite mass": (lambda p: p.with_suffix(".mas").write_text(
        p.with_suffix(".mas").read_text().replace("1 2  0.0000000000000e+00", "1 2  9.0e+03", 1)),
        "b.sti: the mass matrix of this model: entry (1, 2) = 9000 exceeds sqrt"),
}


def test_non_symmetric_exit_2(capsys, tmp_path):
    from helpers import DATA

    out = tmp_path / "o.h5"
    code = main(["reduce", str(DATA / "bad" / "asym_K.mtx"), "--method", "modal", "--order", "2", "--input", "1:x",
                 "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "asym_K.mtx" in err and "not symmetric" in err and len(err.splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_exit_2_one_line(case, tmp_path, capsys):
    sti = _copy_beam(tmp_path)
    mutate, expect = BAD[case]
    mutate(sti)
    out = tmp_path / "out.h5"
    code = main(["reduce", str(sti), "--method", "modal", "--order", "4", "--input", "TIP:y", "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and expect in err and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("spec,msg", [("12345:y", "node 12345"), ("NOSET:y", "NOSET")])
def test_bad_port_exit_2(spec, msg, tmp_path, capsys):
    out = tmp_path / "out.h5"
    code = main(["reduce", CLAMPED, "--method", "modal", "--order", "4", "--input", spec, "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and msg in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_console_script_exit_code(tmp_path):
    r = subprocess.run([sys.executable, "-m", "flexmor", "info", str(tmp_path / "nope.sti")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip() == f"flexmor: error: {tmp_path / 'nope.sti'}: file not found"


def test_a_closed_pipe_ends_the_run_quietly(capsys, monkeypatch):
    """``flexmor info MODEL | head -1``: the reader leaves; no error message, the exit code of SIGPIPE."""

    class Closed:  # stdout whose reader has gone
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", Closed())
    code = main(["info", CLAMPED])
    monkeypatch.undo()
    assert code == 141 and capsys.readouterr().err == ""


@pytest.mark.parametrize("argv,expect", [
    (["--band", "-5:1000"], "--band needs 0 < FMIN < FMAX in Hz, got -5.0:1000.0"),  # the value, not a flag
    (["--rayleigh", "-1:0"], "Rayleigh coefficients must be finite and >= 0, got alpha=-1.0"),
])
def test_a_value_beginning_with_a_minus_gets_its_own_check(argv, expect, tmp_path, capsys):
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "4", "--input", "TIP:y", *argv,
                       "-o", tmp_path / "k.h5")
    assert code == 2 and expect in err and not (tmp_path / "k.h5").exists()
    with pytest.raises(SystemExit) as exc:  # argparse's own exit
        main(["info", CLAMPED, "--modes", "-1"])
    assert exc.value.code == 2
    assert "argument --modes: expected a whole number (0 or more), got -1" in capsys.readouterr().err


def test_reduce_writes_a_body_under_a_body_name(tmp_path, capsys):
    base = ["reduce", CLAMPED, "--method", "krylov", "--order", "4", "--input", "TIP:y", "--no-error", "-o"]
    code, _, err = run(capsys, *base, tmp_path / "k.mat")
    assert code == 2 and "k.mat: reduce writes a flexmor body (.h5); a mat file is made from it by flexmor " \
                         "export BODY.h5 -o k.mat" in err and not (tmp_path / "k.mat").exists()
    code, _, err = run(capsys, *base, tmp_path / "k.txt")
    assert code == 0 and "k.txt: written as a flexmor body (HDF5, .h5) although its suffix is '.txt'" in err
    code, _, err = run(capsys, "info", tmp_path)
    assert code == 2 and f"{tmp_path}: is a folder; give the main file of the FE export in it" in err


@pytest.mark.slow
def test_demo_writes_bodies_and_plot(capsys, tmp_path):
    out = run_json(capsys, "demo", "--out", str(tmp_path), "--n", "2", "--json")
    res = out["results"]
    assert [r["method"] for r in res] == ["modal"] * 3 + ["craig-bampton"] * 2 + ["krylov", "fw-sobt"]
    # balanced truncation and krylov beat modal at r = 16 (their bases built for the ports and the frame's six
    # inertia loads: krylov's deflection under them exact)
    assert res[6]["band_error"] < res[2]["band_error"] and res[5]["band_error"] < res[2]["band_error"]
    assert res[5]["static"]["max_static_error"] < 1e-9
    modal = [r["band_error"] for r in res[:3]]
    assert modal[0] > modal[1] > modal[2]
    assert res[4]["band_error"] < res[3]["band_error"]
    for r in res:
        assert (tmp_path / r["file"].split("/")[-1]).exists()
    png = (tmp_path / "rel_error.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert out["report"] == str(tmp_path / "report.html")
    assert page.count("data:image/png;base64,") == 6  # incl. fw-sobt's singular values
    assert all(f"<td>{r['time_max_error']:.3e}</td>" in page for r in res)


@pytest.mark.slow
def test_rbe2_interface_reduce_compare_export(capsys, tmp_path):
    body = tmp_path / "cb.h5"
    out = run_json(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--order", "10", "--interface", "TIP@rbe2",
                   "--input", "TIP@rbe2:y", "--input", "TIP@rbe2:rz", "--band", "10:3000", "--rayleigh", "0:1e-6",
                   "-o", str(body), "--json")
    assert out["info"]["n_interface_dofs"] == 6
    assert out["order"] == 10 or (out["order"] == 11 and "same frequency" in out["order_note"])  # a whole pair
    assert out["couplings"] == ["TIP@rbe2"] and "couplings" not in out["info"]
    cmp = run_json(capsys, "compare", CLAMPED, str(body), "--band", "10:3000", "--json")
    assert cmp["results"][0]["band_error"] == pytest.approx(out["band_error"], rel=1e-10)
    sid = tmp_path / "cb.SID_FEM"
    # a clamped body misses its supported nodes' mass: refused for the floating frame unless asked for
    assert main(["export", str(body), "--model", CLAMPED, "--format", "sid", "-o", str(sid)]) == 2
    assert "supported" in capsys.readouterr().err and not sid.exists()
    assert main(["export", str(body), "--model", CLAMPED, "--format", "sid", "-o", str(sid), "--allow-clamped"]) == 0
    assert sid.exists()


def test_compare_without_band_judges_over_the_band_the_body_was_reduced_for(capsys, tmp_path):
    body = tmp_path / "k.h5"
    made = run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "6", "--input", "TIP:y",
                    "--band", "1:2000", "-o", body)
    out = run_json(capsys, "compare", CLAMPED, body)
    assert out["band_hz"] == [1.0, 2000.0]  # not the default 1:1000
    assert out["results"][0]["band_error"] == pytest.approx(made["band_error"], rel=1e-9)
    code, text, _ = run(capsys, "compare", CLAMPED, body)
    assert code == 0 and "band 1-2000 Hz: the band the bodies were reduced for" in text
    assert run_json(capsys, "compare", CLAMPED, body, "--band", "1:1000")["band_hz"] == [1.0, 1000.0]
