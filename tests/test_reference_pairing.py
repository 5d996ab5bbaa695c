"""``info --reference`` without mode shapes: each reference frequency gets a distinct model mode, in order
(the smallest sum of relative differences), rigid-body modes only rigid-body ones, and a warning when the
rigid-body counts differ or the frequencies do not match (a reference of another model or support)."""

from __future__ import annotations

import contextlib
import io
import json
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import CCX, run

from flexmor.cli.commands import _print_reference
from flexmor.errors import FlexmorWarning
from flexmor.io.reference import compare_frequencies

#: three rigid-body modes, a pair of equal frequencies (25 Hz) and well separated modes above
MODEL_HZ = [0.0, 0.0, 0.0, 10.0, 25.0, 25.0, 40.0, 61.0, 90.0, 130.0, 180.0, 240.0, 310.0, 400.0]
RIGID_NOTE = "the reference has {} rigid-body modes, the model {}: is it the same support?"
OTHER = "the reference may be of another model or support"


def _model(hz=MODEL_HZ):
    """A model of uncoupled unit masses with the eigenfrequencies ``hz``."""
    w2 = (2 * np.pi * np.asarray(hz)) ** 2
    return SimpleNamespace(K=sp.diags(w2).tocsc(), M=sp.identity(len(hz), format="csc"), n_dof=len(hz))


def _compare(f_ref):
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        cmp = compare_frequencies(_model(), f_ref)
    texts = [str(w.message) for w in got if issubclass(w.category, FlexmorWarning)]
    assert texts == cmp["notes"]
    return cmp


def _one_to_one(cmp) -> None:
    modes = [j for j in cmp["model_modes"] if j is not None]
    assert modes == sorted(set(modes)), cmp["model_modes"]  # distinct and in order


def test_reference_with_and_without_rigid_body_modes():
    elastic = [10.001, 25.002, 25.002, 40.004, 61.0]
    cmp = _compare([0.0, 0.0, 0.0, *elastic])  # the model's own list: mode by mode, no note
    assert cmp["model_modes"] == [1, 2, 3, 4, 5, 6, 7, 8]
    assert cmp["rel_diff"][:3] == [None] * 3 and max(cmp["rel_diff"][3:]) < 2e-4
    np.testing.assert_allclose(cmp["model_frequencies_hz"][3:], [10, 25, 25, 40, 61], rtol=1e-9)
    assert cmp["notes"] == [] and cmp["mac"] is None and cmp["frequencies_hz"] == [0.0, 0.0, 0.0, *elastic]
    cmp = _compare(elastic)  # elastic frequencies only: the rigid-body modes are left out, with a note
    assert cmp["model_modes"] == [4, 5, 6, 7, 8]
    assert None not in cmp["rel_diff"] and max(cmp["rel_diff"]) < 2e-4
    assert cmp["notes"] == [RIGID_NOTE.format(0, 3)]
    cmp = _compare([0.0] * 4 + elastic)  # one rigid-body mode more than the model has: left unpaired
    assert cmp["model_modes"] == [1, 2, 3, None, 4, 5, 6, 7, 8]
    assert cmp["model_frequencies_hz"][3] is None and cmp["rel_diff"][:4] == [None] * 4
    assert cmp["notes"] == [RIGID_NOTE.format(4, 3)]


def test_pairing_is_one_to_one_where_nearest_reuses():
    # nearest pairing gave 33 Hz and 40 Hz both the model's 40 Hz; one-to-one: 33 Hz gets the second 25 Hz mode
    cmp = _compare([0.0, 0.0, 0.0, 10.0, 25.0, 33.0, 40.0])
    assert cmp["model_modes"] == [1, 2, 3, 4, 5, 6, 7]
    assert cmp["rel_diff"][5] == pytest.approx(8 / 33, rel=1e-9) and cmp["rel_diff"][6] == pytest.approx(0, abs=1e-9)
    assert cmp["notes"] == ["the largest relative difference of the elastic modes is 2.42e-01 (reference mode 6, "
                            f"33 Hz, against the model's mode 6, 25 Hz), above 0.001: {OTHER}"]
    # three reference modes around the pair: each gets its own model mode, the third the next one (40 Hz)
    cmp = _compare([24.9, 25.1, 25.3])
    assert cmp["model_modes"] == [5, 6, 7]
    _one_to_one(cmp)
    assert cmp["notes"][0] == RIGID_NOTE.format(0, 3) and cmp["notes"][1].endswith(OTHER)
    assert "reference mode 3, 25.3 Hz, against the model's mode 7, 40 Hz" in cmp["notes"][1]
    # a reference that leaves out model modes in the middle (the pair)
    assert _compare([0.0, 0.0, 0.0, 10.0, 40.0, 61.0])["model_modes"] == [1, 2, 3, 4, 7, 8]


def test_more_reference_modes_than_the_model_has():
    cmp = _compare([0.0, 0.0, 0.0, *MODEL_HZ[3:], 500.0])  # 12 elastic against the model's 11: one unpaired
    _one_to_one(cmp)
    assert cmp["model_modes"].count(None) == 1 and len(cmp["model_modes"]) == 15
    assert any("have no model mode to pair with (the model has 3 rigid-body and 11 elastic modes)" in n
               for n in cmp["notes"])
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        _print_reference("x.txt", dict(cmp, shapes=False, described="a list"))
    rows = [ln for ln in buf.getvalue().splitlines() if ln.strip()[:1].isdigit()]
    assert len(rows) == 15 and sum(ln.split()[2:] == ["-", "-"] for ln in rows) == 1


def test_free_model_against_the_clamped_reference(capsys):
    """The tester's case: a free beam against the clamped beam's CalculiX .dat (the wrong reference)."""
    ccx = CCX
    argv = ("info", ccx / "beam8_free_mat.sti", "--modes", 10, "--reference", ccx / "beam8_clamped_freq.dat")
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0
    ref = json.loads(out)["reference"]
    assert ref["model_modes"] == list(range(7, 27))  # the 20 elastic modes, each once, rigid-body modes left out
    assert None not in ref["rel_diff"] and min(ref["model_frequencies_hz"]) > 600
    assert ref["notes"][0] == RIGID_NOTE.format(0, 6)
    assert ref["notes"][1].startswith("the largest relative difference of the elastic modes is 5.20e+00 "
                                      "(reference mode 1, 100.046 Hz") and ref["notes"][1].endswith(OTHER)
    for note in ref["notes"]:
        assert f"warning: {note}" in err
    code, out, err = run(capsys, *argv)  # the table on stdout, the warnings once on stderr
    assert code == 0 and err.count(RIGID_NOTE.format(0, 6)) == 1 and err.count(OTHER) == 1 and OTHER not in out


@pytest.mark.parametrize("support", ["free", "clamped"])
def test_the_right_reference_stays_as_good(capsys, support):
    ccx = CCX
    code, out, err = run(capsys, "info", ccx / f"beam8_{support}_mat.sti", "--modes", 10,
                         "--reference", ccx / f"beam8_{support}_freq.dat", "--json")
    assert code == 0 and "warning" not in err
    ref = json.loads(out)["reference"]
    n_rigid = 6 if support == "free" else 0
    assert ref["model_modes"] == list(range(1, 21)) and ref["notes"] == []
    assert ref["rel_diff"][:n_rigid] == [None] * n_rigid and max(ref["rel_diff"][n_rigid:]) < 5e-7


def test_a_reference_of_the_model_as_read_is_compared_with_it_when_couplings_are_given(capsys):
    """CalculiX's frequencies of the free beam, with ``--interface FIX@rbe2``: compared with the model as read
    (the RBE2 stiffens the coupled model by up to 6.4e-4, which was reported as "another model or support"),
    and the line says which model and how far the other is."""
    code, out, err = run(capsys, "info", CCX / "beam8_free_mat.sti", "--interface", "FIX@rbe2",
                         "--reference", CCX / "beam8_free_freq.dat", "--json")
    ref = json.loads(out)["reference"]
    assert code == 0 and "warning" not in err and ref["notes"] == []
    assert ref["compared_with"] == "the model as read, before its couplings"
    assert max(d for d in ref["rel_diff"] if d is not None) < 5e-7
    assert ref["others"]["the model with RBE2 at FIX"] > 1e-4
    code, out, _ = run(capsys, "info", CCX / "beam8_free_mat.sti", "--interface", "FIX@rbe2",
                       "--reference", CCX / "beam8_free_freq.dat")
    assert "compared with the model as read, before its couplings (with the model with RBE2 at FIX: largest" in out
