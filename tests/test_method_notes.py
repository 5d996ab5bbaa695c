"""The records and notes of the balanced and iterative methods say what their Gramians cover and why they stopped."""

import math

import numpy as np
import pytest
from helpers import CLAMPED, run, run_json

from flexmor import System, read
from flexmor.reduction.gramians import balance_note


@pytest.fixture(scope="module")
def beam():
    return System(read(CLAMPED), inputs=["TIP:y"])


def test_sobt_surrogate_note_blames_the_cutoff_not_the_body(beam):
    cut = beam.reduce("sobt", 20, solves="surrogate", inertia_loads="off")  # the port's Hankel values alone
    info = cut.info
    # the Gramians end at the cutoff: the record says so, consistently
    assert info["band_requested_hz"] == [0.0, math.inf] and math.isfinite(info["cutoff_hz"])
    assert info["band_hz"] == [0.0, info["cutoff_hz"]] and "end at the cutoff" in info["gramians"]
    assert cut.order < 20  # the Hankel values of the cut Gramians fall below 1e-14 early (1e-26 at the 20th)
    # ... while the Gramians without the cutoff see states far above round-off there
    full = beam.reduce("sobt", 20, solves="dense", inertia_loads="off")
    sv_full = np.array(full.info["hankel_sv"])
    assert full.order == 20 and full.order_note is None and sv_full[cut.order] > 1e-12 * sv_full[0]
    assert "no further states" not in cut.order_note
    assert f"end at {info['cutoff_hz']:g} Hz" in cut.order_note and "solves='direct'" in cut.order_note


def test_gramian_records_state_what_they_cover(beam):
    direct = beam.reduce("sobt", 8, solves="direct").info  # the full band: quadrature cells up to the cutoff
    assert direct["band_hz"] == direct["band_requested_hz"] == [0.0, math.inf]
    assert direct["cutoff_hz"] < math.inf and "one tail cell" in direct["gramians"]
    exact = beam.reduce("sobt", 8).info  # 270 DOF: the exact Lyapunov solutions, no cutoff
    assert exact["band_hz"] == [0.0, math.inf] and "cutoff_hz" not in exact and "exact" in exact["gramians"]
    fw = beam.reduce("fw-sobt", 20, band=(1.0, 1000.0))
    assert fw.info["band_hz"] == fw.info["band_requested_hz"] == [1.0, 1000.0] == [1.0, fw.info["cutoff_hz"]]
    if fw.order < 20:  # the band's Gramians, resolved: the note names that band
        assert "over [1, 1000] Hz" in fw.order_note and "wider band" in fw.order_note


def test_balance_note_reasons():
    exact = balance_note(5, 8)
    assert "no further states" in exact and exact.startswith("order 5 instead of 8")
    ended = {"band_hz": [0.0, 500.0], "band_requested_hz": [0.0, math.inf], "n_nodes": 10,
             "solves": {"solves": "surrogate"}}
    note = balance_note(5, 8, 1, ended)
    assert note.startswith("order 6 instead of 9") and "end at 500 Hz" in note and "no further states" not in note
    whole = dict(ended, band_hz=[0.0, 500.0], band_requested_hz=[0.0, 500.0])
    assert "no further states in that band" in balance_note(5, 8, 0, whole)
    assert balance_note(8, 8, 0, ended) is None


@pytest.fixture(scope="module")
def unconverged(tmp_path_factory):
    return str(tmp_path_factory.mktemp("irka") / "irka.h5")


def test_irka_that_stops_says_so_everywhere(capsys, beam, unconverged):
    damped = System(read(CLAMPED).with_rayleigh(1.0, 1e-6), inputs=["TIP:y"])
    body = damped.reduce("irka", 20, max_iter=2)  # two iterations cannot settle 10 points
    assert body.info["converged"] is False
    note = body.info["convergence_note"]
    assert "did not converge in 2 iterations" in note and "max_iter" in note
    argv = ("reduce", CLAMPED, "--method", "irka", "--order", "20", "--input", "TIP:y", "--rayleigh", "1:1e-6",
            "--max-iter", "2", "-o", unconverged, "--force")
    rec = run_json(capsys, *argv, "--json")
    assert rec["converged"] is False and "--max-iter" in rec["convergence_note"]
    assert rec["info"]["converged"] is False
    code, out, _ = run(capsys, *argv)
    assert code == 0 and "NOT CONVERGED: irka" in out and "--max-iter" in out
    shown = run_json(capsys, "info", unconverged, "--json")
    assert shown["converged"] is False and "did not converge" in shown["convergence_note"]
    code, out, _ = run(capsys, "info", unconverged)
    assert code == 0 and any(ln.startswith("converged") and "NO: irka did not converge in 2 iterations" in ln
                             for ln in out.splitlines())


def test_a_method_without_iteration_records_none(capsys, tmp_path):
    path = str(tmp_path / "k.h5")
    rec = run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "6", "--input", "TIP:y", "-o", path,
                   "--json")
    assert rec["converged"] is None and rec["convergence_note"] is None
    code, out, _ = run(capsys, "info", path)
    assert code == 0 and "NOT CONVERGED" not in out and not any(ln.startswith("converged") for ln in out.splitlines())
