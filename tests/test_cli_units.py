"""``--units`` on the command line: a mm-t-s copy of the CalculiX beam reads as the SI beam, the body
records its model's units, ``info`` states them and ``export --export-units`` writes other systems."""

from __future__ import annotations

import re

import numpy as np
import pytest
from helpers import CCX, FREE, run, run_json

from flexmor.io import read_body


def mm_copy(tmp_path, stem="beam8_free_mat"):
    """The beam in mm-t-s: K by 1e-3 (N/m -> N/mm), M by 1e-3 (kg -> t), coordinates by 1e3, E in MPa and
    the density in t/mm^3."""
    for ext, factor in (("sti", 1e-3), ("mas", 1e-3)):
        rows = [ln.split() for ln in (CCX / f"{stem}.{ext}").read_text().splitlines() if ln.strip()]
        (tmp_path / f"mm.{ext}").write_text("".join(f"{i} {j} {float(v) * factor:.17e}\n" for i, j, v in rows))
    (tmp_path / "mm.dof").write_text((CCX / f"{stem}.dof").read_text())
    lines, block = [], None
    for ln in (CCX / f"{stem}.inp").read_text().splitlines():
        if ln.startswith("*"):
            block = ln.split(",")[0].strip().upper()
        elif block == "*NODE" and ln.strip():
            nid, *xyz = ln.split(",")
            ln = ", ".join([nid] + [repr(float(x) * 1e3) for x in xyz])
        elif block in ("*ELASTIC", "*DENSITY") and ln.strip():
            vals = [float(v) for v in ln.split(",")]
            vals[0] *= 1e-6 if block == "*ELASTIC" else 1e-12
            ln = ", ".join(repr(v) for v in vals)
        lines.append(ln)
    (tmp_path / "mm.inp").write_text("\n".join(lines) + "\n")
    return tmp_path / "mm.sti"


def test_info_of_a_mm_copy_with_units(capsys, tmp_path):
    mm = mm_copy(tmp_path)
    ref = run_json(capsys, "info", FREE, "--modes", "12")
    out = run_json(capsys, "info", mm, "--units", "mm-t-s", "--modes", "12")
    assert out["units"] == "mm-t-s" and ref["units"] is None
    f, f0 = np.array(out["frequencies_hz"][6:]), np.array(ref["frequencies_hz"][6:])
    assert np.abs(f - f0).max() <= 1e-10 * f0.max()
    assert out["mass"] == pytest.approx(ref["mass"], rel=1e-12)  # kg, not t
    assert np.allclose(out["bounding_box"], ref["bounding_box"], rtol=1e-12, atol=1e-15)  # m, not mm
    as_given = run_json(capsys, "info", mm)
    assert as_given["mass"][0] == pytest.approx(ref["mass"][0] * 1e-3, rel=1e-12)
    code, text, _ = run(capsys, "info", mm, "--units", "mm-t-s")
    assert code == 0
    assert re.search(r"units +mm-t-s \(length mm, mass t, time s, force N, stress MPa, density t/mm\^3\), "
                     r"converted to SI on reading; the numbers below are SI", text)
    assert re.search(r"mass +78\.5 \(kg;", text) and "(m)" in text
    code, text, _ = run(capsys, "info", mm)
    assert re.search(r"units +as given \(the file states no unit system; give --units", text)
    assert re.search(r"mass +0\.0785 \(mass unit of the file", text)


def test_unknown_units_did_you_mean(capsys):
    with pytest.raises(SystemExit) as e:
        run(capsys, "info", FREE, "--units", "mm-ts")
    err = capsys.readouterr().err
    assert e.value.code == 2 and "argument --units: 'mm-ts' is not a unit system flexmor knows; did you mean " \
        "'mm-t-s'? choose one of: SI, mm-t-s, mm-kg-ms, mm-g-ms, in-lbf-s" in err


@pytest.fixture(scope="module")
def bodies(tmp_path_factory):
    """The free beam reduced in SI and from its mm-t-s copy read with --units mm-t-s."""
    from flexmor.cli import main

    tmp = tmp_path_factory.mktemp("units")
    mm = mm_copy(tmp)
    common = ["--method", "modal", "--order", "8", "--input", "TIP:y", "--band", "1:3000", "--no-mounted"]
    assert main(["reduce", FREE, *common, "-o", str(tmp / "si.h5"), "--json"]) == 0
    assert main(["reduce", str(mm), "--units", "mm-t-s", *common, "-o", str(tmp / "mm.h5"), "--json"]) == 0
    return tmp, mm


def test_reduced_from_the_mm_copy_is_the_si_body(bodies):
    tmp, _ = bodies
    si, mm = read_body(tmp / "si.h5"), read_body(tmp / "mm.h5")
    assert mm.units == "mm-t-s" and si.units is None
    f = np.geomspace(1, 3000, 40)
    H, H0 = mm.frf(f), si.frf(f)
    assert np.abs(H - H0).max() <= 1e-8 * np.abs(H0).max()
    fr, fr0 = mm.frequencies_hz(), si.frequencies_hz()
    assert np.abs(fr - fr0).max() <= 1e-10 * fr0.max()
    assert np.allclose(mm.xyz, si.xyz, rtol=1e-12, atol=1e-15)


def test_info_and_compare_of_the_body(capsys, bodies):
    tmp, mm = bodies
    code, text, _ = run(capsys, "info", tmp / "mm.h5")
    assert code == 0 and re.search(r"units +mm-t-s \(length mm, .*; the body is in SI", text)
    assert run_json(capsys, "info", tmp / "mm.h5")["units"] == "mm-t-s"
    out = run_json(capsys, "compare", mm, tmp / "mm.h5", "--units", "mm-t-s", "--no-cache")
    ref = run_json(capsys, "compare", FREE, tmp / "si.h5", "--no-cache")
    assert out["results"][0]["band_error"] == pytest.approx(ref["results"][0]["band_error"], rel=1e-6)
    same = run_json(capsys, "compare", mm, tmp / "mm.h5", "--no-cache")  # read in the units the body records
    assert same["results"][0]["band_error"] == pytest.approx(out["results"][0]["band_error"], rel=1e-12)
    code, _, err = run(capsys, "compare", mm, tmp / "mm.h5", "--units", "SI")  # in other units: another model
    assert code == 2 and "--units" in err


def _sid_value(text, key):
    m = re.search(rf"^\s*{re.escape(key)}\s*=\s*(\S+)", text, re.M)
    return float(m.group(1).replace("D", "E"))


def test_export_units(capsys, bodies):
    tmp, mm = bodies
    code, out, err = run(capsys, "export", tmp / "mm.h5", "--model", mm, "-o", tmp / "si.sid")
    assert code == 0, err  # the --model read in the units the body records
    code, out, err = run(capsys, "export", tmp / "mm.h5", "--model", mm, "--export-units", "mm-t-s",
                         "-o", tmp / "mm.sid")
    assert code == 0 and "in mm-t-s" in out, err
    si_text, mm_text = (tmp / "si.sid").read_text(), (tmp / "mm.sid").read_text()
    assert "units SI (length m, mass kg" in si_text.splitlines()[0]
    assert "units mm-t-s (length mm, mass t, time s, force N" in mm_text.splitlines()[0]
    assert _sid_value(si_text, "mass") == pytest.approx(78.5, rel=1e-9)
    assert _sid_value(mm_text, "mass") == pytest.approx(0.0785, rel=1e-9)  # t
    from flexmor.io.sid import read_sid

    a, b = read_sid(tmp / "si.sid"), read_sid(tmp / "mm.sid")
    code, out, _ = run(capsys, "info", tmp / "mm.sid")  # read back as a model: the header's units are said
    assert code == 0 and "units     as in the file, whose header states mm-t-s (read as given)" in out
    assert np.allclose(b.objects["J"].m0, a.objects["J"].m0 / (1e3 * 1e-6), rtol=1e-12)  # t mm^2
    assert np.allclose(b.nodes[0].origin.m0, a.nodes[0].origin.m0 * 1e3, rtol=1e-12)  # mm
    lam = np.linalg.eigvals(np.linalg.solve(b.objects["Me"].m0, b.objects["Ke"].m0))
    lam0 = np.linalg.eigvals(np.linalg.solve(a.objects["Me"].m0, a.objects["Ke"].m0))
    assert np.allclose(np.sort(lam.real), np.sort(lam0.real), rtol=1e-9)  # the same frequencies (time in s)
    # MATLAB: the variable units and the numbers in the system
    import scipy.io

    assert run(capsys, "export", tmp / "mm.h5", "--export-units", "mm-kg-ms", "-o", tmp / "b.mat")[0] == 0
    assert run(capsys, "export", tmp / "mm.h5", "-o", tmp / "a.mat")[0] == 0
    a, b = scipy.io.loadmat(tmp / "a.mat"), scipy.io.loadmat(tmp / "b.mat")
    assert str(b["units"][0]).startswith("mm-kg-ms (length mm, mass kg, time ms, force kN")
    assert np.allclose(b["Kr"], a["Kr"], rtol=1e-12)  # energy unit kN mm = 1 J
    assert np.allclose(b["Mr"], a["Mr"] / 1e-6, rtol=1e-12)  # kg mm^2
    assert np.allclose(b["xyz"], a["xyz"] * 1e3) and np.allclose(b["Br"], a["Br"] * 1e3)  # force input: mm
    # SI only
    code, _, err = run(capsys, "export", tmp / "mm.h5", "--export-units", "mm-t-s", "-o", tmp / "x.npz",
                       "--format", "statespace")
    assert code == 2 and "--export-units mm-t-s: statespace files are written in SI only" in err
    code, _, err = run(capsys, "export", tmp / "si.h5", "--export-units", "mm-t-s", "-o", tmp / "c.mat")
    assert code == 2 and "read as given" in err


def test_report_states_units(capsys, bodies):
    from flexmor.report.plots import frf_unit_label, output_unit

    tmp, mm = bodies
    code, _, err = run(capsys, "report", mm, tmp / "mm.h5", "--units", "mm-t-s", "-o", tmp / "r.html", "--modes", "4")
    assert code == 0, err
    assert "units SI (m, kg, s, N), the model file in mm-t-s converted on reading" in (tmp / "r.html").read_text()
    assert frf_unit_label("TIP:y", "TIP:y", "SI") == "|H| [m/N]" and frf_unit_label("TIP:y", "TIP:y", None) == "|H|"
    assert frf_unit_label("7:ry", "TIP:x", "SI") == "|H| [rad/N]" and output_unit(["TIP:y", "3:rx"], "SI") == "m, rad"


def test_stress_modes_of_a_mm_model_are_in_pa(capsys, tmp_path):
    """The deck's material in MPa and t/mm^3 is converted with the model: the stress modes of the mm copy
    read with --units mm-t-s equal those of the SI beam (Pa per unit coordinate)."""
    mm = mm_copy(tmp_path)
    args = ("--method", "modal", "--order", "8", "--input", "TIP:y", "--no-error", "--stress", "--stress-nodes",
            "all")
    run_json(capsys, "reduce", FREE, *args, "-o", tmp_path / "si.h5")
    run_json(capsys, "reduce", mm, "--units", "mm-t-s", *args, "-o", tmp_path / "mm.h5")
    si, mmb = read_body(tmp_path / "si.h5"), read_body(tmp_path / "mm.h5")
    assert np.array_equal(si.stress_nodes, mmb.stress_nodes)
    # the stress of one physical state, independent of how each body's modes are chosen in their pairs:
    # the static response to a unit tip force (N) in Pa
    fields = [np.einsum("j,jkl->kl", np.linalg.solve(b.K, b.B[:, 0]), b.stress_modes) for b in (si, mmb)]
    peak = np.abs(fields[0]).max()
    assert 100 < peak < 1e5  # Pa per N (669 here): not MPa per N, which would be 1e-6 of it
    assert np.abs(fields[1] - fields[0]).max() <= 1e-6 * peak
    # the MATLAB file in mm-t-s states stress in MPa: its stress modes are MPa per reduced coordinate (they stayed
    # in Pa, a factor 1e6 off, while the rest of the file was converted)
    import scipy.io

    assert run(capsys, "export", tmp_path / "mm.h5", "-o", tmp_path / "si.mat")[0] == 0
    assert run(capsys, "export", tmp_path / "mm.h5", "--export-units", "mm-t-s", "-o", tmp_path / "mm.mat")[0] == 0
    a, b = scipy.io.loadmat(tmp_path / "si.mat"), scipy.io.loadmat(tmp_path / "mm.mat")
    assert "stress MPa" in str(b["units"][0])
    assert np.allclose(b["stress_modes"], a["stress_modes"] * 1e-6, rtol=1e-12, atol=0)
    assert np.allclose(b["Kr"], a["Kr"] * 1e3, rtol=1e-12)  # the coordinates keep their scale: N mm per unit
