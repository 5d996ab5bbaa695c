"""An independent judge: a body judged against the surrogate is checked by direct solves of the full model,
and bodies that span one subspace say so (flexmor.analysis.judge, flexmor.analysis.subspaces)."""

from __future__ import annotations

import numpy as np
import pytest

import flexmor
from flexmor.analysis.compare import FullResponse
from flexmor.analysis.frequency import band_error
from flexmor.analysis.judge import AGREEMENT, MAX_JUDGE_CHECKS, judge_check
from flexmor.analysis.subspaces import SINE_TOL, subspace_groups, subspace_sine
from flexmor.cli.tables import print_error_table
from flexmor.dynamics.surrogate import Surrogate
from flexmor.models import plate_structure

BAND = (1.0, 2000.0)
ORDER = 30


def _system(**grid):
    """The free plate-and-rods structure (1,194 DOF), RBE2 at the hole (6 master directions) and the top corner's
    z, modal damping 1 %, judged against the surrogate."""
    model = plate_structure(4, lower="free")
    xyz = model.xyz
    top = xyz[:, 2] >= xyz[:, 2].max() - 1e-9
    corner = int(model.node_ids[np.argmax(xyz[:, 0] + xyz[:, 1] + 10 * top)])
    inputs = [f"HOLE@rbe2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")] + [f"{corner}:z"]
    return flexmor.System(model, inputs=inputs, interfaces=["HOLE@rbe2"], band=BAND,
                          damping={"modal_damping": 0.01}, cache=False, path="surrogate", **grid)


@pytest.fixture(scope="module")
def study():
    s = _system()
    bodies = {m: s.reduce(m, ORDER) for m in ("fw-sobt", "pod", "craig-bampton")}
    errors = {m: s.judge(b) for m, b in bodies.items()}  # in this order: pod after fw-sobt
    return s, bodies, errors


@pytest.fixture(scope="module")
def direct(study):
    s = study[0]
    return FullResponse(s.model, s.ports, s.band, path="direct", cache=False)


def test_printed_band_error_of_surrogate_bodies_agrees_with_a_direct_sweep(study, direct):
    s, bodies, errors = study
    assert s.full.path == "surrogate" and direct.path == "direct"
    for method in ("fw-sobt", "pod"):
        err, check = errors[method], errors[method].judge_check
        assert check["built_from_surrogate"] and check["n_checks"] >= 3 and check["agree"]
        truth = direct.evaluate(bodies[method]).band_error
        assert err.band_error == pytest.approx(truth, rel=0.10)
        assert check["band_error_checked"] == pytest.approx(truth, rel=0.10)
        for c in check["checks"]:  # the pointwise errors at the worst frequencies, against both
            assert c["rel_error_full"] == pytest.approx(c["rel_error_surrogate"], rel=AGREEMENT)
            assert c["surrogate_error"] < 1e-5
        assert any("confirmed" in n for n in err.notes)
    # the direct solutions are shared: pod (the same subspace) needs no solve of its own
    assert errors["pod"].judge_check["new_solves"] == 0
    assert s.full.judge["direct_solves"] <= 3 * (MAX_JUDGE_CHECKS + 1)
    assert s.full.summary()["judge"]["bodies_checked"] == 3


def test_an_independent_body_is_checked_too_and_the_record_carries_the_check(study, direct):
    s, bodies, errors = study
    check = errors["craig-bampton"].judge_check
    assert not check["built_from_surrogate"] and check["agree"] and check["resolved"] and check["floor"] is None
    truth = direct.evaluate(bodies["craig-bampton"]).band_error
    assert errors["craig-bampton"].band_error == pytest.approx(truth, rel=0.10)
    rec = errors["craig-bampton"].to_dict()
    assert rec["judge_check"]["checks"][0]["freq_hz"] > 0 and rec["same_subspace_as"] == []
    assert direct.evaluate(bodies["craig-bampton"]).judge_check is None  # a direct reference needs no check


def _off_between_checks(monkeypatch, scale):
    """The surrogate's FRF multiplied by ``scale(f)`` on a sweep (many frequencies), exact at its own checks
    (one frequency): a surrogate that is wrong between the points where it verified itself."""
    exact = Surrogate.frf

    def frf(self, freqs):
        H = exact(self, freqs)
        f = np.atleast_1d(np.asarray(freqs, float))
        return H if f.size == 1 else H * scale(f)[:, None, None]

    monkeypatch.setattr(Surrogate, "frf", frf)


def test_a_surrogate_wrong_between_its_checks_is_caught_and_reported(study, direct, monkeypatch, capsys):
    s, bodies, _ = study
    _off_between_checks(monkeypatch, lambda f: 1 + 0.02 * (f > 500))
    wrong = _system()
    body = bodies["fw-sobt"]
    err = wrong.judge(body)
    check = err.judge_check
    truth = direct.evaluate(body).band_error
    assert wrong.full.grid["surrogate"]["verified"]  # its own checks saw nothing
    assert check["band_error_surrogate"] > 30 * truth  # the figure the surrogate alone would print
    assert not check["agree"] and check["corrected"]
    # measured: the surrogate's part of H 2 % off (the modal-damping correction added to it is not)
    assert 0.015 < max(c["surrogate_error"] for c in check["checks"]) < 0.03
    # 2 % off over most of the band: a band_error of 2e-6 is below what it resolves; the bound holds
    assert not check["resolved"] and check["floor"] >= truth
    assert any(n.startswith("band_error corrected by direct solutions") for n in err.notes)
    assert any("below what the surrogate reference resolves" in n for n in err.notes)
    print_error_table([{"method": "fw-sobt", "order": body.order, **err.to_dict()}])
    out = capsys.readouterr().out
    assert f"<{check['floor']:.1e}" in out and "corrected where they differ by more than 10 %: fw-sobt r=30" in out


def test_a_surrogate_wrong_at_one_peak_is_corrected_to_the_direct_figure(study, direct, monkeypatch):
    s, bodies, errors = study
    body = bodies["craig-bampton"]
    check = errors["craig-bampton"].judge_check
    peak = max(check["checks"], key=lambda c: c["share"])["freq_hz"]
    _off_between_checks(monkeypatch, lambda f: 1 + 1.0 * np.exp(-(((f / peak - 1) / 1e-2) ** 2)))
    wrong = _system()
    err = wrong.judge(body)
    truth = direct.evaluate(body).band_error
    assert not err.judge_check["agree"]
    assert err.judge_check["band_error_surrogate"] > 1.15 * truth  # off without the check (by ~20 %)
    assert err.judge_check["corrected"] and err.judge_check["explained"] and err.judge_check["resolved"]
    assert err.band_error == pytest.approx(truth, rel=0.10)


def test_judge_check_replaces_the_surrogate_where_it_is_solved():
    f = np.linspace(1.0, 100.0, 400)
    rng = np.random.default_rng(3)
    H = (1 / (30.0 ** 2 - f ** 2 + 0.6j * f))[:, None, None] * (1 + rng.normal(size=(1, 2, 2)))
    Hr = H * (1 + 1e-3)
    wrong = H.copy()
    near = np.abs(f - 30.0) < 0.6  # the surrogate 5 % off at the peak only
    wrong[near] *= 1.05
    solved = []

    def direct(idx):
        solved.extend(idx)
        return H[idx]

    rec, Hc = judge_check(f, wrong, Hr, direct, tol=1e-8, n_checks=3)
    assert not rec["agree"] and rec["corrected"] and rec["n_checks"] == len(set(solved)) <= MAX_JUDGE_CHECKS
    assert set(np.flatnonzero(near)) <= set(solved)
    assert rec["band_error_checked"] == pytest.approx(band_error(f, H, Hr), rel=0.01)
    assert abs(rec["band_error_surrogate"] / band_error(f, H, Hr) - 1) > 0.5
    assert np.array_equal(Hc[solved], H[solved])
    ok, _ = judge_check(f, H, Hr, lambda idx: H[idx], tol=1e-8)
    assert ok["agree"] and not ok["corrected"] and ok["resolved"] and ok["n_checks"] == 3
    tiny = H * (1 + 1e-9)  # a body within the surrogate's tolerance: the figure is noise, its bound is stated
    floor, _ = judge_check(f, H, tiny, lambda idx: H[idx], tol=1e-8)
    assert not floor["resolved"] and floor["floor"] == pytest.approx((1e-9 + 1e-8) ** 2, rel=0.05)


def test_methods_that_share_a_subspace_say_so(study, capsys):
    _, bodies, errors = study
    assert errors["pod"].same_subspace_as == [f"fw-sobt r={bodies['fw-sobt'].order}"]
    assert errors["craig-bampton"].same_subspace_as == [] and errors["fw-sobt"].same_subspace_as == []
    assert subspace_sine(bodies["fw-sobt"].V, bodies["pod"].V) <= SINE_TOL
    assert subspace_sine(bodies["fw-sobt"].V, bodies["craig-bampton"].V) > 0.1
    assert subspace_groups([bodies["craig-bampton"], bodies["fw-sobt"], bodies["pod"]]) == [[1, 2]]
    rows = [{"method": m, "order": b.order, **errors[m].to_dict()} for m, b in bodies.items()]
    print_error_table(rows)
    out = capsys.readouterr().out
    assert "note: fw-sobt r=30 and pod r=30 span one subspace" in out
    assert "craig-bampton r=30 and" not in out and "and craig-bampton" not in out


def test_subspace_sine_of_rotated_and_tilted_bases():
    rng = np.random.default_rng(0)
    V = rng.normal(size=(200, 6))
    R = rng.normal(size=(6, 6))
    assert subspace_sine(V, V @ R) < 1e-12  # the same span in other coordinates
    W = V.copy()
    W[:, 0] += 1e-3 * np.linalg.norm(V[:, 0]) * rng.normal(size=200) / np.sqrt(200)
    assert 1e-5 < subspace_sine(V, W) < 1e-2
    assert subspace_sine(V, V[:, :5]) == 1.0


def test_a_full_response_from_the_disk_cache_checks_alike(study, tmp_path):
    s, bodies, errors = study
    first = FullResponse(s.model, s.ports, s.band, path="surrogate", cache=tmp_path)
    again = FullResponse(s.model, s.ports, s.band, path="surrogate", cache=tmp_path)
    assert not first.cache_hit and again.cache_hit and again.surrogate is None
    body = bodies["craig-bampton"]
    a, b = first.evaluate(body).judge_check, again.evaluate(body).judge_check
    assert b["agree"] and b["new_solves"] == b["n_checks"] >= 3  # the model's modes found again for the checks
    assert [c["freq_hz"] for c in a["checks"]] == [c["freq_hz"] for c in b["checks"]]
    for ca, cb in zip(a["checks"], b["checks"]):
        assert cb["rel_error_full"] == pytest.approx(ca["rel_error_full"], rel=1e-6)
