"""Judging refuses a body of another model, damping or ports; the judgement is an ErrorMeasures;
reduce returns the body and remembers its band; reduce_and_judge builds for the band of ``full``."""

from __future__ import annotations

import numpy as np
import pytest

from flexmor.analysis.compare import ErrorMeasures, FullResponse
from flexmor.analysis.frequency import MEASURE_KEYS
from flexmor.errors import ModelError, OptionError, PortError
from flexmor.options import DEFAULT_BAND
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.workflow import reduce_and_judge

BAND = (10.0, 3000.0)


@pytest.fixture(scope="module")
def damped(clamped):
    return clamped.with_rayleigh(0.0, 1e-6)


@pytest.fixture(scope="module")
def full_y(damped):
    return FullResponse(damped, make_ports(damped, ["TIP:y"]), BAND, cache=False)


def test_a_body_of_the_clamped_beam_is_refused_by_the_free_beam(clamped, free):
    body = reduce(clamped, "modal", 6, make_ports(clamped, ["TIP:y"]))
    full = FullResponse(free, make_ports(free, ["TIP:y"]), BAND, cache=False)
    with pytest.raises(ModelError, match="270 DOF, this model has 297"):
        full.evaluate(body)


def test_a_damped_body_is_refused_by_the_undamped_model(clamped, damped, full_y):
    body = reduce(damped, "modal", 8, make_ports(damped, ["TIP:y"]))
    undamped = FullResponse(clamped, make_ports(clamped, ["TIP:y"]), BAND, cache=False)
    with pytest.raises(ModelError, match=r"reduced with damping Rayleigh alpha 0 1/s, beta 1e-06 s; this reference "
                                         r"has none"):
        undamped.evaluate(body)
    assert full_y.evaluate(body).band_error < 1e-2  # against its own damping: judged


def test_a_body_of_other_ports_is_refused(damped, full_y):
    x = reduce(damped, "krylov", 8, make_ports(damped, ["TIP:x"]), band=BAND)
    with pytest.raises(PortError, match=r"1 inputs \(TIP:x\); this reference has 1 \(TIP:y\)"):
        full_y.evaluate(x)
    two = reduce(damped, "krylov", 8, make_ports(damped, ["TIP:y", "TIP:z"]), band=BAND)
    with pytest.raises(PortError, match=r"2 inputs \(TIP:y, TIP:z\); this reference has 1"):
        full_y.evaluate(two)


def test_evaluate_returns_error_measures_whose_record_keeps_the_json_keys(damped, full_y):
    body = reduce(damped, "krylov", 12, make_ports(damped, ["TIP:y"]), band=BAND, inertia_loads="off")
    err = full_y.evaluate(body)
    assert isinstance(err, ErrorMeasures)
    with pytest.raises(AttributeError):
        err.band_error = 0.0  # frozen
    assert list(err.to_dict()) == [*MEASURE_KEYS, "notes"]
    assert err.band_error < 1e-8 and err.band_hz == BAND and err.judged == "full response"
    assert err.rms_rel_error_pct == pytest.approx(100 * np.sqrt(err.band_error))
    assert err.rel_error.shape == err.freqs_hz.shape == full_y.freqs.shape
    assert err.max_rel_error == pytest.approx(err.rel_error.max())


def test_reduce_returns_the_body_with_its_timings_and_band(damped):
    ports = make_ports(damped, ["TIP:y"])
    body = reduce(model=damped, method="krylov", order=8, ports=ports)
    assert body.order == 8 and set(body.info["timings"]) == {"basis", "project"}
    assert body.info["band"] == list(DEFAULT_BAND)  # built for the default band, and says so
    assert reduce(damped, "modal", 4, ports).info["band"] is None  # modal has no band


def test_a_body_built_for_another_band_is_judged_with_a_note(damped, full_y):
    port = {"inertia_loads": "off"}  # for the port alone: the band decides
    body = reduce(damped, "krylov", 8, make_ports(damped, ["TIP:y"]), **port)
    assert any("built for 1-1000 Hz, judged over 10-3000 Hz" in n for n in full_y.evaluate(body).notes)
    own = reduce(damped, "krylov", 8, make_ports(damped, ["TIP:y"]), band=BAND, **port)
    assert not any("built for" in n for n in full_y.evaluate(own).notes)
    assert full_y.evaluate(own).band_error < full_y.evaluate(body).band_error


def test_reduce_and_judge_builds_for_the_band_of_full(damped, full_y):
    ports = make_ports(damped, ["TIP:y"])
    body, res = reduce_and_judge(damped, "fw-sobt", 6, ports, full=full_y, mounted=False)
    assert body.info["band"] == list(BAND) and res["band_hz"] == list(BAND)
    assert res["info"]["options"]["band"] == list(BAND)
    with pytest.raises(OptionError, match="differs from the band of full"):
        reduce_and_judge(damped, "modal", 4, ports, full=full_y, band=(1.0, 1000.0))
