"""MATLAB and state-space exports, the export dispatch and ``flexmor export`` on the command line."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
from helpers import FREE

from flexmor.cli import main
from flexmor.errors import OptionError
from flexmor.io import export, write_body
from flexmor.io.matlab import MAT_FIELDS
from flexmor.io.sid import read_sid
from flexmor.io.statespace import state_space


def test_mat_holds_every_documented_field(tmp_path, body):
    red, model = body
    path = tmp_path / "body.mat"
    export(red, path, model=model)
    data = scipy.io.loadmat(path)
    assert set(MAT_FIELDS) <= set(data)
    np.testing.assert_array_equal(data["Kr"], red.K)
    np.testing.assert_array_equal(data["V"], red.V)
    assert data["dofs"].shape == (model.n_dof, 2) and data["input_names"][0, 0][0] == "TIP:y"
    inv = data["inv"][0, 0]
    assert inv["mass"][0, 0] == pytest.approx(78.5, rel=1e-12)
    np.testing.assert_allclose(inv["Me"], np.eye(6), atol=1e-10)
    np.testing.assert_allclose(data["frequencies_hz"][:, 0], red.frequencies_hz(), rtol=1e-12)
    assert data["frequencies_hz"][0, 0] == pytest.approx(620.672, abs=1e-3)


def test_state_space_poles_are_the_damped_modes(body):
    red, _ = body
    ss = state_space(red)
    poles = np.linalg.eigvals(ss.A)
    w = 2 * np.pi * red.frequencies_hz()
    zeta = 0.5 * (2.0 / w + 1e-6 * w)  # Rayleigh: zeta = (alpha/w + beta w) / 2
    np.testing.assert_allclose(np.sort(-poles.real)[::2], np.sort(zeta * w), rtol=1e-8)
    # transfer function at 100 Hz equals Cr (s^2 Mr + s Dr + Kr)^-1 Br
    s = 2j * np.pi * 100
    H2 = red.C @ np.linalg.solve(s * s * red.M + s * red.D + red.K, red.B)
    H1 = ss.C @ np.linalg.solve(s * np.eye(12) - ss.A, ss.B)
    np.testing.assert_allclose(H1, H2, rtol=1e-10)
    He = ss.C @ np.linalg.solve(s * ss.E - ss.Ae, ss.Be)
    np.testing.assert_allclose(He, H2, rtol=1e-10)
    assert ss.to_scipy().A.shape == (12, 12)


def test_unknown_or_ambiguous_format(tmp_path, body):
    red, model = body
    with pytest.raises(OptionError, match="sid, exudyn, mat, statespace"):
        export(red, tmp_path / "x.npz", model=model)
    with pytest.raises(OptionError, match="not a known export file type"):
        export(red, tmp_path / "x.sid", "fbi", model=model)


def test_cli_export_sid_and_statespace(tmp_path, body):
    red, model = body
    h5 = tmp_path / "b.h5"
    write_body(red, h5)
    out = tmp_path / "b.SID_FEM"
    assert main(["export", str(h5), "--model", FREE, "-o", str(out), "--node", "TIP", "--json"]) == 0
    sid = read_sid(out)
    np.testing.assert_allclose(sid.frequencies_hz(), red.frequencies_hz(), rtol=1e-9)
    assert sid.mass == pytest.approx(78.5, rel=1e-12)
    assert main(["export", str(h5), "--format", "ss", "-o", str(tmp_path / "ss.npz")]) == 0
    with np.load(tmp_path / "ss.npz") as z:
        assert z["A"].shape == (12, 12)


def test_cli_export_bad_input_exits_2(tmp_path, body, capsys):
    red, _ = body
    h5 = tmp_path / "b.h5"
    write_body(red, h5)
    out = tmp_path / "b.SID_FEM"
    assert main(["export", str(h5), "-o", str(out)]) == 2  # no --model
    assert "--model" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.h5"), "-o", str(out)]) == 2
    assert main(["export", str(h5), "-o", str(tmp_path / "x.npz"), "--model", FREE]) == 2
    assert not out.exists()
