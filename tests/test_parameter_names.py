"""Library messages and notes name Python parameters; the command line shows them as its flags."""

from __future__ import annotations

import dataclasses
import warnings

import pytest
from helpers import CCX

import flexmor.io
from flexmor.analysis import frequency, mounted
from flexmor.analysis.compare import FullResponse
from flexmor.analysis.frequency import error_notes
from flexmor.analysis.mounted import mounted_note
from flexmor.cli import main
from flexmor.cli.tables import note_text, notes_as_flags
from flexmor.errors import FlexmorWarning, ModelError, OptionError, PortError, name_parameters
from flexmor.expansion import expand_body
from flexmor.ports import make_ports
from flexmor.reduction import reduce


def test_name_parameters_renames_whole_words_only():
    text = "band must be set; band_error, method_band and x.band stay; widen the band"
    assert name_parameters(text, ("band",), {"band": "--band"}) == \
        "--band must be set; band_error, method_band and x.band stay; widen the --band"
    assert name_parameters(text, ("band",)) == text
    assert name_parameters(text, ("order",), {"band": "--band"}) == text


def test_undamped_note_names_parameters_and_the_command_line_its_flags():
    (note,) = error_notes({"resonance_share": 0.9, "band_error": 1e-3, "max_rel_error": 1e-3}, damped=False)
    assert "add damping (rayleigh or modal_damping)" in note and "--" not in note
    assert "add damping (--rayleigh or --modal-damping)" in note_text(note)


def test_mounted_note_names_inertia_loads_and_the_command_line_its_flag():
    rec = {"band_hz": [1.0, 1000.0], "cases": [{"held": "clamped", "interface": "TIP", "rel_error": [0.2],
                                               "frequencies_full_hz": [120.0], "static": []}]}
    note = mounted_note(rec, 1e-4)
    assert "frequency of mode 1 (120 Hz) off by 20 %" in note
    assert "keep inertia_loads auto or on" in note and "--" not in note
    assert "keep --inertia-loads auto or on" in note_text(note)
    supported = mounted_note(rec, 1e-4, free=False)  # its inertia loads hold no interface
    assert "add residual_vectors" in supported and "add --residual-vectors" in note_text(supported)


def test_the_flags_of_note_parameters_exist(capsys):
    with pytest.raises(SystemExit):
        main(["reduce", "--help"])
    text = capsys.readouterr().out
    for p in frequency.NOTE_PARAMS + mounted.NOTE_PARAMS:
        assert "--" + p.replace("_", "-") in text


def test_json_records_show_notes_with_flags():
    rec = {"notes": ["undamped: add damping (rayleigh or modal_damping)", 3],
           "rows": [{"mounted": {"note": "keep inertia_loads auto or on"}, "method": "rayleigh"}],
           "order_note": None, "label": "rayleigh"}
    out = notes_as_flags(rec)
    assert out["notes"] == ["undamped: add damping (--rayleigh or --modal-damping)", 3]
    assert out["rows"][0]["mounted"]["note"] == "keep --inertia-loads auto or on"
    assert out["rows"][0]["method"] == "rayleigh" and out["label"] == "rayleigh"  # not notes: unchanged
    assert rec["notes"][0] == "undamped: add damping (rayleigh or modal_damping)"  # the record itself unchanged


def test_couplings_of_a_distributed_model_name_the_backend_parameter(clamped, monkeypatch):
    import flexmor.couplings as couplings

    monkeypatch.setattr(couplings, "is_partitioned", lambda K: True)
    with pytest.raises(PortError, match="need the whole model in one process") as exc:
        couplings.couple(clamped, ["TIP@rbe2"])
    assert exc.value.params == ("backend",)
    assert "flexmor reduce" not in str(exc.value) and "--" not in str(exc.value)
    assert "run serially (--backend other than 'petsc')" in exc.value.message({"backend": "--backend"})


def test_a_body_without_basis_names_no_command(clamped):
    body = reduce(clamped, "modal", 4, make_ports(clamped, ["TIP:y"]))
    with pytest.raises(ModelError, match="holds no basis V") as exc:
        expand_body(clamped, dataclasses.replace(body, V=None))
    assert "flexmor reduce" not in str(exc.value) and "--" not in str(exc.value)


def test_full_response_band_error_names_band(clamped):
    with pytest.raises(OptionError, match="band needs 0 < FMIN < FMAX") as exc:
        FullResponse(clamped, make_ports(clamped, ["TIP:y"]), (100.0, 10.0))
    assert exc.value.params == ("band",)
    assert exc.value.message({"band": "--band"}).startswith("--band needs")


def test_warnings_name_parameters_and_the_command_line_its_flags(monkeypatch, caplog, tmp_path):
    w = FlexmorWarning("the body is coarse: raise order", params=("order",))
    assert str(w) == "the body is coarse: raise order" and w.message({"order": "--order"}).endswith("raise --order")
    real_read = flexmor.io.read

    def read_and_warn(*args, **kwargs):
        warnings.warn(FlexmorWarning("a warning naming a parameter: raise order", params=("order",)), stacklevel=2)
        return real_read(*args, **kwargs)

    monkeypatch.setattr(flexmor.io, "read", read_and_warn)
    assert main(["reduce", str(CCX / "beam8_clamped_mat.sti"), "--method", "modal", "--order", "4", "--input",
                 "TIP:y", "--no-error", "--no-cache", "-o", str(tmp_path / "b.h5")]) == 0
    shown = [r.getMessage() for r in caplog.records if "a warning naming a parameter" in r.getMessage()]
    assert shown == ["a warning naming a parameter: raise --order"]
