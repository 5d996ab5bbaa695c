"""What a study is given is held: method names resolve once to one method with the study's band, unknown
keywords are refused with the closest name, complex/NaN/Inf values are refused naming the argument, a band
in rad/s or above the model's highest mode is warned about, and an order a method cannot reach is treated
by one rule (flexmor.reduction._registry)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import CLAMPED, run

import flexmor
from flexmor.checks import highest_hz, looks_like_rad_per_s
from flexmor.damping import Rayleigh
from flexmor.errors import FlexmorWarning, OptionError
from flexmor.reduction import METHODS, reduce, register_method
from flexmor.workflow import with_method_band

BAND = (1.0, 5000.0)


@pytest.fixture(scope="module")
def study(clamped):
    return flexmor.System(clamped, inputs=["TIP:y"], band=BAND, damping=Rayleigh(10, 1e-6), cache=False)


def _refused(param, words, call):
    with pytest.raises(OptionError) as exc:
        call()
    assert param in exc.value.params and words in str(exc.value), str(exc.value)
    return exc.value


# -- method names -----------------------------------------------------------------------------------------------------
def test_a_short_name_or_another_case_is_the_method_with_the_study_band(study):
    """``bt`` and ``SOBT`` are ``sobt``: built for the study's band (1-5000 Hz, not the default 1-1000 Hz),
    the same body, recorded as ``sobt``."""
    ref = study.reduce("sobt", 10)
    assert ref.order == 10 and ref.info["band"] == list(BAND)
    for name in ("bt", "SOBT", " Bt "):
        body = study.reduce(name, 10)
        assert body.method == "sobt" and body.order == 10 and body.info["band"] == list(BAND), name
        np.testing.assert_allclose(body.K, ref.K, rtol=1e-10, atol=1e-10 * np.abs(ref.K).max())
    body, rec = study.reduce_and_judge("BT", 10, judge=False)
    assert rec["method"] == "sobt" and rec["info"]["band"] == list(BAND) and body.order == 10
    assert with_method_band("FWBT", BAND, {}) == {"band": BAND}  # fw-sobt takes a band
    assert with_method_band("CB", BAND, {}) == {}  # craig-bampton does not


def test_a_short_name_gets_the_study_interfaces(clamped):
    s = flexmor.System(clamped, inputs=["TIP:y"], interfaces=["TIP"], band=BAND)
    assert s.options("CB", {}) == {"interface": ["TIP"]}
    _refused("method", "did you mean 'krylov'?", lambda: s.options("kryolv", {}))


# -- keywords ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("wrong, right", [("bnad", "band"), ("dampnig", "damping"), ("ouputs", "outputs")])
def test_system_refuses_a_misspelt_keyword_with_the_closest_name(clamped, wrong, right):
    err = _refused(wrong, f"System does not take {wrong} (did you mean '{right}'?)",
                   lambda: flexmor.System(clamped, inputs=["TIP:y"], **{wrong: (1, 5000)}))
    assert "it takes: inputs, outputs, interfaces, band, damping" in str(err)


def test_public_functions_refuse_a_misspelt_keyword_with_the_closest_name(study, tmp_path):
    body = study.reduce("modal", 4)
    u = np.ones(11)
    _refused("shceme", "does not take shceme (did you mean 'scheme'?)",
             lambda: study.simulate(u, dt=1e-4, t_end=1e-3, shceme="newmark"))
    _refused("modez", "does not take modez (did you mean 'modes'?)", lambda: study.mounted(body, modez=3))
    _refused("bnad", "does not take option(s) bnad (did you mean 'band'?)",
             lambda: study.reduce("krylov", 4, bnad=BAND))
    _refused("n_frq", "does not take n_frq (did you mean 'n_freq'?)", lambda: study.reduce_and_judge("krylov", 4,
                                                                                                  n_frq=10))
    _refused("inertia_load", "did you mean 'inertia_loads'?", lambda: study.reduce("krylov", 4, inertia_load="on"))
    _refused("unitz", "does not take unitz (did you mean 'units'?)", lambda: flexmor.read(CLAMPED, unitz="SI"))
    _refused("nodez", "does not take nodez (did you mean 'nodes'?)",
             lambda: flexmor.export(body, tmp_path / "b.mat", nodez=[1]))
    assert not (tmp_path / "b.mat").exists()


# -- values where a real finite number belongs ------------------------------------------------------------------------
def _no_numpy_warning(call):
    """``call()`` with every warning an error: a ComplexWarning (or any other) would fail before the check."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return call()


def test_complex_nan_and_inf_are_refused_naming_the_argument(study):
    body = study.reduce("modal", 4)
    _refused("freqs", "got the complex value (20+1j)", lambda: _no_numpy_warning(lambda: study.frf([10, 20 + 1j])))
    _refused("freqs_hz", "got the complex value (10+1j)", lambda: _no_numpy_warning(lambda: body.frf([10 + 1j])))
    _refused("freqs_hz", "got nan", lambda: body.frf([10, np.nan]))
    # a complex array whose imaginary parts are zero is the real one
    np.testing.assert_array_equal(body.frf(np.array([10, 20], complex)), body.frf([10.0, 20.0]))
    nan_u = np.ones(11)
    nan_u[3] = np.nan
    _refused("u", "got nan at 1 of 11 entries (the first at index 3)",
             lambda: study.simulate(nan_u, dt=1e-4, t_end=1e-3))
    _refused("u", "got the complex value (1+1j)",
             lambda: _no_numpy_warning(lambda: body.simulate(np.full(11, 1 + 1j), dt=1e-4, t_end=1e-3)))
    _refused("u", "got inf", lambda: body.simulate(lambda t: np.full(t.size, np.inf), dt=1e-4, t_end=1e-3))


@pytest.mark.parametrize("alpha, beta, param, words", [
    (10 + 1j, 1e-6, "alpha", "got the complex value (10+1j)"),
    (10, math.inf, "beta", "got inf"),
    (math.nan, 1e-6, "alpha", "got nan"),
    ("ten", 1e-6, "alpha", "got 'ten'"),
    (-1, 0, "alpha", "Rayleigh coefficients must be finite and >= 0, got alpha=-1.0"),
])
def test_rayleigh_refuses_a_coefficient_that_is_not_a_real_finite_number(clamped, alpha, beta, param, words):
    _refused(param, words, lambda: Rayleigh(alpha, beta))
    _refused(param, words, lambda: clamped.with_rayleigh(alpha, beta))


def test_a_complex_damping_ratio_is_refused_naming_it(clamped):
    _refused("modal_damping", "got the complex value (0.02+1j)",
             lambda: flexmor.System(clamped, inputs=["TIP:y"], damping={"modal_damping": 0.02 + 1j}))
    _refused("band_rayleigh", "got nan", lambda: flexmor.System(clamped, inputs=["TIP:y"],
                                                                damping={"band_rayleigh": math.nan}))


def test_rayleigh_takes_numbers_as_floats():
    r = Rayleigh(np.int64(10), np.float32(1e-6))
    assert type(r.alpha) is float and type(r.beta) is float and r.alpha == 10.0
    _refused("rayleigh", "rayleigh must be a pair (alpha, beta)",
             lambda: flexmor.workflow.damping_of(rayleigh=1e-6))


# -- the band ---------------------------------------------------------------------------------------------------------
def test_the_highest_eigenfrequency_is_that_of_the_dense_pencil(clamped, free):
    for model in (clamped, free):
        lam = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)[-1]
        assert highest_hz(model) == pytest.approx(math.sqrt(lam) / (2 * math.pi), rel=1e-3)


@pytest.mark.parametrize("band, rad", [((2 * math.pi * 10, 2 * math.pi * 3000), True), ((6.283, 6283), True),
                                       ((62.83, 18850), True), ((10, 3000), False), ((1, 1000), False),
                                       ((100, 2000), False), ((1.5, 4321), False)])
def test_a_band_that_looks_given_in_rad_per_s(band, rad):
    assert looks_like_rad_per_s(band) is rad


def _band_warnings(model, band):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flexmor.System(model, inputs=["TIP:y"], band=band)
    return [str(w.message) for w in caught if issubclass(w.category, FlexmorWarning) and "band" in str(w.message)]


def test_a_band_in_rad_per_s_or_above_the_highest_mode_is_warned(clamped):
    top = highest_hz(clamped)  # about 80 kHz; max K_ii / M_ii gives 38.5 kHz: the bands below pass through Lanczos
    (rad,) = _band_warnings(clamped, (2 * math.pi * 10, 2 * math.pi * 3000))
    assert "band 62.8319:18849.6 Hz is 2 pi times 10:3000: was it given in rad/s?" in rad
    (high,) = _band_warnings(clamped, (1, 5e6))
    assert f"band reaches 5e+06 Hz, above the model's highest eigenfrequency {top:.4g} Hz" in high
    assert len(_band_warnings(clamped, (1, 1.1 * top))) == 1
    assert _band_warnings(clamped, (1, 0.9 * top)) == [] and _band_warnings(clamped, (10, 3000)) == []


def test_the_command_line_warns_about_a_band_in_rad_per_s(capsys, tmp_path):
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "4", "--input", "TIP:y",
                       "--band", "62.8319:18849.6", "--no-error", "-o", tmp_path / "k.h5")
    assert code == 0 and "flexmor: warning: " in err and "--band 62.8319:18849.6 Hz is 2 pi times 10:3000" in err


# -- an order a method cannot reach -----------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["modal", "krylov", "sobt", "pod", "svdmor", "adaptive", "cms-krylov"])
def test_an_order_above_the_dof_is_refused_by_every_method(study, clamped, method):
    opts = {"interface": ["TIP"]} if "interface" in METHODS[method].options else {}
    err = _refused("order", f"order 1000 exceeds the number of DOF {clamped.n_dof} of the model",
                   lambda: study.reduce(method, 1000, **opts))
    assert err.params == ("order",)
    # the method function itself (as registered) applies the same rule
    _refused("order", "exceeds the number of DOF", lambda: METHODS[method].function(clamped, study.ports, 1000, **opts))


def test_an_order_a_method_cannot_reach_gives_the_reachable_order_and_the_reason(study):
    body = study.reduce("pod", 200)
    r = body.order
    assert r < 200 and body.info["order_requested"] == 200
    assert body.order_note.startswith(f"order {r} instead of 200: the snapshots span only {r} independent directions")
    cut = study.reduce("pod", 50, energy=0.9)
    assert cut.order < r and cut.order_note == (f"order {cut.order} instead of 50: 0.9 of the snapshot energy is "
                                                f"reached with {cut.order} POD modes (energy)")


def test_a_method_that_says_nothing_gets_the_reason_of_the_registry(study, clamped):
    """The rule holds for every registered method: one returning fewer columns without a word gets the
    registry's note."""

    @dataclasses.dataclass(frozen=True)
    class NoOptions:
        pass

    @register_method("fewer-columns", "returns at most two columns", options=NoOptions)
    def fewer(model, ports, order, *, solver=None):
        from flexmor.basis import Basis

        return Basis(flexmor.reduction.modal.modal(model, ports, min(order, 2)).V, "fewer-columns", {})

    try:
        body = reduce(clamped, "FEWER-COLUMNS", 5, study.ports)
        assert body.order == 2 and body.order_note == ("order 2 instead of 5: fewer-columns found only 2 independent "
                                                       "directions for it")
        _refused("order", "exceeds the number of DOF", lambda: fewer(clamped, study.ports, clamped.n_dof + 1))
    finally:
        del METHODS["fewer-columns"]
