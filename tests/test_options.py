"""Typed method options (a dataclass per method), the Band and Damping values, and errors that
name parameters in the library and flags on the command line.

The meta-tests check every registered method, in the spirit of python-control's
``test_kwargs``: its options dataclass and its keyword-only parameters agree, every option is
documented, and an unknown keyword is an :class:`OptionError` both through ``reduce()`` and
when the method function is called directly.
"""

import dataclasses
import inspect
import json
import pickle
import re

import numpy as np
import pytest
from helpers import CLAMPED

from flexmor.cli import main
from flexmor.damping import (
    BandMatched,
    GivenDamping,
    NoDamping,
    Rayleigh,
    band_matched,
    damping_from_dict,
    modal_damping,
)
from flexmor.errors import FlexmorError, OptionError, PortError
from flexmor.options import DEFAULT_BAND, Band, option_fields
from flexmor.ports import make_ports
from flexmor.reduction import METHODS, reduce

#: The solver parameter every method takes besides its options.
SOLVER = {"backend", "solver"}


@pytest.mark.parametrize("name", sorted(METHODS))
def test_options_dataclass_matches_the_signature(name):
    m = METHODS[name]
    cls = m.options_class
    assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen
    params = inspect.signature(m.function).parameters
    kwonly = {p.name: p for p in params.values() if p.kind is p.KEYWORD_ONLY}
    fields = {f.name: f for f in dataclasses.fields(cls)}
    assert set(fields) == set(kwonly) - SOLVER, name
    assert len(set(kwonly) & SOLVER) == 1  # one solver parameter, not a method option
    assert list(params)[:3] == ["model", "ports", "order"]
    for f in fields.values():
        assert f.default == kwonly[f.name].default, (name, f.name)  # one default, not two
        assert f.metadata["help"].strip(), (name, f.name)
        if f.metadata["choices"]:
            assert f.default in f.metadata["choices"]
    cls()  # all options have defaults


def _documented(function) -> dict:
    """``name -> (type, description)`` of the Parameters section of a numpydoc docstring."""
    section = inspect.getdoc(function).split("Parameters\n----------\n", 1)[1]
    section = re.split(r"\n\n?[A-Z][a-z]+(?: [A-Z][a-z]+)?\n-{3,}\n", section)[0]
    out, names = {}, []
    for line in section.splitlines():
        if m := re.match(r"^(\w+(?:, \w+)*) : (.*)$", line):
            names = m.group(1).split(", ")
            out.update({n: [m.group(2), ""] for n in names})
        elif line.startswith("    "):
            for n in names:
                out[n][1] += " " + line.strip()
    return out


@pytest.mark.parametrize("name", sorted(METHODS))
def test_docstring_documents_each_option_as_its_dataclass_declares_it(name):
    """The options dataclass holds each default and choice list once: the function's docstring
    documents every option, with the dataclass's choices and ``optional`` exactly for a None
    default, and restates no default value (it names the dataclass's, e.g. DEFAULT_BAND)."""
    m = METHODS[name]
    documented = _documented(m.function)
    keywords = set(inspect.signature(m.function).parameters) - {"model", "ports", "order"} - SOLVER
    assert set(documented) - {"model", "ports", "order"} - SOLVER <= keywords, name
    for option, f in option_fields(m.options_class).items():
        assert option in documented, (name, option)
        kind, text = documented[option]
        choices = re.match(r"^\{(.*)\}", kind)
        listed = {c.strip().strip("'") for c in choices.group(1).split(",")} if choices else set()
        assert listed == set(f.metadata["choices"]), (name, option, kind)
        assert ("optional" in kind) == (f.default is None), (name, option, kind)
        assert text.strip(), (name, option)
        assert not re.search(r"[Dd]efault:? \(?[-+]?\d", text), (name, option, text)


@pytest.mark.parametrize("name", sorted(METHODS))
def test_unknown_keyword_is_an_option_error(name, clamped):
    ports = make_ports(clamped, ["TIP:y"])
    allowed = METHODS[name].options
    for value in (1, None):  # a None-valued unknown option is refused too
        with pytest.raises(OptionError, match=r"does not take option\(s\) bogus_option; it takes: ") as exc:
            reduce(clamped, name, 4, ports, bogus_option=value)
        assert all(a in str(exc.value) for a in allowed)
    with pytest.raises(OptionError, match="bogus_option"):  # the function itself, before any work
        METHODS[name].function(clamped, ports, 4, bogus_option=1)


def test_reduce_records_given_options_and_uses_dataclass_defaults(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    red = reduce(clamped, "krylov", 6, ports, side=None, moments=2)
    assert red.info["options"] == {"moments": 2}  # None: the default ("input"), not recorded
    assert red.info["side"] == METHODS["krylov"].options_class().side == "input"


def test_band_is_validated_once():
    assert DEFAULT_BAND == (1.0, 1000.0) and DEFAULT_BAND.fmax == 1000.0
    assert Band.of(None) is DEFAULT_BAND and Band.of("10:3000") == (10.0, 3000.0)
    assert Band.of((5, 50)) == Band(5.0, 50.0) and json.dumps(Band(5, 50)) == "[5.0, 50.0]"
    assert pickle.loads(pickle.dumps(Band(2, 20))) == Band(2, 20)
    for bad in ("3:1", "0:10", "1:inf", "a:b", (1, 2, 3)):
        with pytest.raises(OptionError, match="band") as exc:
            Band.of(bad)
        assert exc.value.params == ("band",)


def test_damping_types_and_their_stored_form(clamped):
    bm = band_matched(0.02, (10.0, 3000.0))
    w1, w2 = 2 * np.pi * 10.0, 2 * np.pi * 3000.0
    assert bm.alpha == 2 * 0.02 * w1 * w2 / (w1 + w2) and bm.beta == 2 * 0.02 / (w1 + w2)
    np.testing.assert_allclose(bm.ratios([10.0, 3000.0]), [0.02, 0.02], rtol=1e-12)
    assert bm.to_dict() == {"type": "rayleigh", "alpha": bm.alpha, "beta": bm.beta}  # stored as before
    assert damping_from_dict(bm.to_dict()) == Rayleigh(bm.alpha, bm.beta)
    for d in (NoDamping(), GivenDamping(), Rayleigh(1.0, 1e-6)):
        assert damping_from_dict(d.to_dict()) == d
    assert NoDamping().to_dict() == {"type": "none"} and GivenDamping().to_dict() == {"type": "given"}
    with pytest.raises(OptionError, match="'viscous' is not known"):
        damping_from_dict({"type": "viscous"})
    with pytest.raises(OptionError, match=r"band_rayleigh must be in \[0, 1\)"):
        band_matched(1.5, DEFAULT_BAND)
    with pytest.raises(OptionError, match=r"modal_damping must be in \[0, 1\)"):
        modal_damping(1.5, DEFAULT_BAND)
    md = modal_damping(0.02, (10.0, 3000.0))
    assert damping_from_dict(md.to_dict()) == md and md.to_dict()["type"] == "modal"
    np.testing.assert_allclose(md.ratios([0.0, 10.0, 500.0, 3000.0]), [0.0, 0.02, 0.02, 0.02])
    damped = clamped.with_damping(bm)
    assert isinstance(damped.damping, BandMatched) and damped.summary()["damping"]["type"] == "rayleigh"
    np.testing.assert_allclose((damped.D - clamped.with_rayleigh(bm.alpha, bm.beta).D).toarray(), 0.0)


def test_error_message_maps_parameters_to_flags():
    exc = OptionError("intermediate (50) must be at least order (80); see the interface", params=("intermediate",
                                                                                                  "order"))
    assert exc.message() == str(exc)
    assert exc.message({"intermediate": "--intermediate", "order": "--order"}) == \
        "--intermediate (50) must be at least --order (80); see the interface"
    assert FlexmorError("max_iter=3, max_iterations", params=("max_iter",)).message({"max_iter": "--max-iter"}) \
        == "--max-iter=3, max_iterations"


def test_library_errors_name_parameters(clamped):
    with pytest.raises(PortError, match="no input ports: inputs must name") as exc:
        make_ports(clamped, [])
    assert exc.value.params == ("inputs",) and "--" not in str(exc.value)
    ports = make_ports(clamped, ["TIP:y"])
    for method, opts, text in [("modal", {}, "modal needs order"), ("krylov", {}, "krylov needs order or moments"),
                               ("irka", {}, "irka needs order"), ("two-step", {}, "two-step needs order")]:
        with pytest.raises(OptionError, match=text) as exc:
            reduce(clamped, method, None, ports, **opts)
        assert "--" not in str(exc.value)
    with pytest.raises(OptionError, match=r"intermediate \(8\) must be at least order \(10\)"):
        reduce(clamped, "two-step", 10, ports, intermediate=8)


def _err(capsys, *argv):
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("argv,expect", [
    (["--method", "modal", "--order", "4"], "no input ports: --input must name at least one NODE:DIR or SET:DIR"),
    (["--method", "modal", "--input", "TIP:y"], "modal needs --order"),
    (["--method", "krylov", "--input", "TIP:y"], "krylov needs --order or --moments"),
    (["--method", "two-step", "--order", "10", "--intermediate", "8", "--input", "TIP:y"],
     "--intermediate (8) must be at least --order (10)"),
    (["--method", "adaptive", "--input", "TIP:y"], "adaptive needs --order or --estimate-tol"),
    (["--method", "guyan", "--input", "TIP:y"], "this method needs --interface SPECs"),
    (["--method", "modal", "--order", "4", "--input", "TIP:y", "--band", "30:3"], "--band needs 0 < FMIN < FMAX"),
    (["--method", "modal", "--order", "4", "--input", "TIP:y", "--rayleigh", "1e-6"],
     "--rayleigh must look like A:B with two numbers"),
    (["--method", "modal", "--order", "4", "--input", "TIP:y", "--modal-damping", "1.5"],
     "--modal-damping must be in [0, 1), got 1.5"),
    (["--method", "modal", "--order", "4", "--input", "TIP:y", "--rayleigh", "0:1e-6", "--modal-damping", "0.01"],
     "give either --rayleigh or --modal-damping, not both"),
    (["--method", "irka", "--order", "6", "--input", "TIP:y"], "damping (--rayleigh or --modal-damping)"),
    (["--method", "modal", "--order", "4", "--input", "TIP:y", "--select", "nonsense"], "--select 'nonsense'"),
    (["--method", "krylov", "--order", "4", "--input", "TIP:y", "--side", "both", "--points", "x"],
     "--points must be numbers in Hz"),
    (["--method", "krylov", "--tol", "1e-3", "--no-error", "--input", "TIP:y"],
     "--tol needs the error evaluation over a band (drop --no-error)"),
])
def test_cli_names_the_flags(argv, expect, capsys, tmp_path):
    err = _err(capsys, "reduce", CLAMPED, *argv, "--no-cache", "-o", str(tmp_path / "b.h5"))
    assert expect in err, err
    assert not (tmp_path / "b.h5").exists()


def test_cli_refuses_a_flag_the_method_does_not_take(capsys, tmp_path):
    err = _err(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "4", "--input", "TIP:y",
               "--intermediate", "50", "--points", "0", "-o", str(tmp_path / "b.h5"))
    assert err == "flexmor: error: method 'modal' does not take --points, --intermediate; it takes: --rigid, --sigma"
    err = _err(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "4", "--input", "TIP:y",
               "--interface", "TIP", "-o", str(tmp_path / "b.h5"))
    assert ("'krylov' does not take --interface (as a node set; a coupling --interface SET@rbe2 or SET@rbe3 is a "
            "joint of the model, which every method takes); it takes: --points, --moments, --side, --band, --rigid"
            in err)


def test_cli_adaptive_estimate_tol_is_reachable_and_tol_keeps_its_meaning(capsys, tmp_path):
    argv = ["reduce", CLAMPED, "--method", "adaptive", "--input", "TIP:y", "--band", "1:3000", "--rayleigh",
            "0:1e-6", "--no-cache", "--json"]
    assert main(argv + ["--estimate-tol", "1e-8", "--max-points", "12", "-o", str(tmp_path / "a.h5")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["info"]["options"]["estimate_tol"] == 1e-8 and out["info"]["options"]["max_points"] == 12
    assert out["info"]["estimates"][-1] < 1e-8 and "tol" not in out  # the method's own stop, no verified search
    assert main(argv + ["--tol", "1e-6", "-o", str(tmp_path / "t.h5")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["tol"] == 1e-6 and out["tol_reached"] and out["band_error"] <= 1e-6  # the verified target


def test_reduce_help_has_a_group_per_method(capsys):
    with pytest.raises(SystemExit):
        main(["reduce", "--help"])
    text = capsys.readouterr().out
    for name, m in METHODS.items():
        assert f"--method {name}:" in text
        for f in dataclasses.fields(m.options_class):
            assert "--" + f.name.replace("_", "-") in text
    group = text.split("--method two-step:")[1]
    assert "--intermediate R1" in group and "(default 120)" in group
    for flag in ("--order", "--input", "--output", "--interface", "--band", "--rayleigh", "--modal-damping", "--tol",
                 "--backend", "--json"):
        assert flag in text


def test_cli_names_format_and_model_flags(capsys, tmp_path):
    odd = tmp_path / "beam.xyz"
    odd.write_text("1 1 1.0\n")
    assert "(or give --format)" in _err(capsys, "info", str(odd))
    body = tmp_path / "m.h5"
    assert main(["reduce", CLAMPED, "--method", "modal", "--order", "4", "--input", "TIP:y", "--no-error",
                 "-o", str(body)]) == 0
    capsys.readouterr()
    err = _err(capsys, "export", str(body), "-o", str(tmp_path / "body.txt"))
    assert "cannot tell the export type from the suffix '.txt' (known: .h5" in err and "give --format (hdf5, sid" in err
    assert "given as --model: the inertia" in _err(capsys, "export", str(body), "-o", str(tmp_path / "b.sid"))


def test_method_names_take_aliases_and_an_unknown_one_gets_the_closest(clamped, capsys):
    ports = make_ports(clamped, ["TIP:y"])
    assert reduce(clamped, "CB", 30, ports, interface=["TIP"]).method == "craig-bampton"
    with pytest.raises(OptionError, match=r"method='krylof' is unknown; did you mean 'krylov'\?") as exc:
        reduce(clamped, "krylof", 8, ports)
    assert exc.value.params == ("method",)
    with pytest.raises(OptionError) as exc:
        reduce(clamped, "xyz", 8, ports)
    assert "did you mean" not in str(exc.value) and "craig-bampton" in str(exc.value)
    with pytest.raises(SystemExit):
        main(["reduce", CLAMPED, "--method", "fwbtt", "--order", "4", "--input", "TIP:y", "--no-error"])
    assert "--method='fwbtt' is unknown; did you mean 'fw-sobt'?" in capsys.readouterr().err
