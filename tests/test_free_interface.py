"""Craig-Chang and Herting: free-interface modes with the residual flexibility of the interfaces, on the free
CalculiX beam held at FIX@rbe2 and on the clamped one coupled at its tip."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import CLAMPED, FREE, run_json

import flexmor
from flexmor.damping import Rayleigh
from flexmor.errors import OptionError


@pytest.fixture(scope="module")
def free():
    s = flexmor.System(FREE, inputs=["FIX@rbe2:y", "TIP:y"], interfaces=["FIX@rbe2"], band=(1, 3000),
                       damping=Rayleigh(0.0, 2e-6), cache=False)
    lam = sla.eigh(s.model.K.toarray(), s.model.M.toarray(), eigvals_only=True)
    return s, np.sqrt(np.clip(lam[6:], 0, None)) / (2 * np.pi)  # its elastic free-free frequencies


@pytest.mark.parametrize("method", ["craig-chang", "herting"])
def test_the_kept_free_free_modes_are_the_full_models(free, method):
    s, f_full = free
    body = s.reduce(method, 18)
    k = body.info["n_modes"]
    assert body.order == 18 and k == 18 - 6 and body.info["n_interface_dofs"] == 6
    np.testing.assert_allclose(body.frequencies_hz()[:k], f_full[:k], rtol=1e-8)
    np.testing.assert_allclose(body.info["free_interface_hz"], f_full[:k], rtol=1e-8)
    assert body.frequencies_hz()[k] >= f_full[k] * (1 - 1e-9)  # the residual attachments' lie above (Ritz)


def test_herting_is_craig_chang_in_interface_coordinates(free):
    s, _ = free
    cc, he = s.reduce("craig-chang", 18), s.reduce("herting", 18)
    assert s.judge(he).band_error == pytest.approx(s.judge(cc).band_error, rel=1e-6)  # one space
    master = np.flatnonzero(s.model.dofs[:, 0] == s.model.node_sets["FIX@RBE2"][0])
    V = np.asarray(he.V)
    scale = np.abs(V[:, :6]).max()
    assert np.abs(V[master, :6] - np.eye(6)).max() < 1e-6 * scale  # the interface displacements
    assert np.abs(V[master, 6:]).max() < 1e-6 * scale


def test_held_at_the_interface_it_converges_to_the_full_model(free):
    """The mounted check (clamped and pinned at FIX@rbe2, held modes up to 3 kHz) improves with the order;
    measured 7.0e-2, 1.1e-4, 4.0e-6 at orders 12, 18, 24 (Craig-Bampton: 0.17, 1.8e-5, 7.9e-8)."""
    s, _ = free
    errors = [s.reduce_and_judge("herting", r)[1]["mounted"]["max_frequency_error"] for r in (12, 18, 24)]
    assert errors[0] > errors[1] > errors[2] and errors[2] < 1e-4


def test_a_supported_body_with_a_coupled_tip_has_exact_interface_statics():
    s = flexmor.System(CLAMPED, inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"], band=(1, 3000))
    lam = sla.eigh(s.model.K.toarray(), s.model.M.toarray(), eigvals_only=True)
    body = s.reduce("herting", 14)
    np.testing.assert_allclose(body.info["free_interface_hz"], np.sqrt(lam[:8]) / (2 * np.pi), rtol=1e-8)
    rec = s.static(body)
    tip = [x["field_error"] for x in rec["loads"] if x["load"].startswith("TIP@RBE2:")]
    assert len(tip) == 6 and max(tip) < 1e-9 and rec["static_error"] < 1e-9


def test_the_command_line_reduces_and_exports_it(capsys, tmp_path, free):
    _, f_full = free  # the coupled model's free-free frequencies, as the command line couples it
    made = run_json(capsys, "reduce", FREE, "--method", "herting", "--max-frequency", "5000", "--interface",
                    "FIX@rbe2", "--input", "TIP:y", "--no-cache", "-o", tmp_path / "h.h5")
    assert made["order"] == 6 + int(np.sum(f_full <= 5000))
    out = run_json(capsys, "export", tmp_path / "h.h5", "--model", FREE, "-o", tmp_path / "h.SID_FEM")
    assert out["order"] == made["order"]


def test_bad_requests_are_refused_naming_the_option(free):
    s, _ = free
    with pytest.raises(OptionError, match="needs order > the 6 interface DOFs"):
        s.reduce("herting", 6)
    with pytest.raises(OptionError, match="give order or max_frequency, not both"):
        s.reduce("craig-chang", 12, max_frequency=3000.0)
    with pytest.raises(OptionError, match="needs interface"):
        flexmor.System(FREE, inputs=["TIP:y"]).reduce("herting", 12)
