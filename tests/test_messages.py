"""Messages that help: a fact of the file that needs no action is a named note, stated in full by
``flexmor info``, one short line elsewhere and silenced by its name; messages name the real cause; the text
output of ``info BODY`` shows what its JSON shows."""

from __future__ import annotations

import shutil
import warnings

import pytest
from helpers import CCX, FREE, run, run_json

import flexmor
from flexmor.damping import Rayleigh
from flexmor.errors import NOTES, QUIET_NOTES_VARIABLE, FlexmorNote, ModelError, OptionError, notes_quieted

BAND = (10.0, 3000.0)


@pytest.fixture
def c3d10(tmp_path):
    """The Abaqus C3D10 block with the mass of its first equation cleared: a legal singular mass (warned)."""
    src = CCX.parent / "abaqus"
    for suffix in (".inp", "_STIF1.mtx"):
        shutil.copy(src / f"blockC3D10{suffix}", tmp_path / f"blockC3D10{suffix}")
    lines = (src / "blockC3D10_MASS1.mtx").read_text().splitlines()
    (tmp_path / "blockC3D10_MASS1.mtx").write_text("\n".join(ln for ln in lines if "1" not in ln.split()[:2]) + "\n")
    return tmp_path / "blockC3D10.inp"


def _notes(call) -> list[FlexmorNote]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [w.message for w in caught if isinstance(w.message, FlexmorNote)]


# -- named notes ------------------------------------------------------------------------------------------------------
def test_the_singular_mass_is_one_short_line_that_names_its_note(c3d10):
    (note,) = _notes(lambda: flexmor.read(c3d10))
    text = str(note)
    assert note.name == "singular-mass" and "\n" not in text
    assert text.startswith(f"{c3d10}: mass matrix diagonal is not positive at 1 equation")
    assert "every method still works (note singular-mass: see flexmor info; silenced by --quiet-note singular-mass" \
           in text
    assert NOTES["singular-mass"] not in text and note.full().endswith(NOTES["singular-mass"])
    assert len(text) < len(note.full()) / 2


def test_a_note_is_silenced_by_its_name(c3d10, monkeypatch):
    with notes_quieted(["singular-mass"]):
        assert _notes(lambda: flexmor.read(c3d10)) == []
    assert len(_notes(lambda: flexmor.read(c3d10))) == 1  # the block ends: said again
    with notes_quieted(["rigid-body-modes"]):
        assert len(_notes(lambda: flexmor.read(c3d10))) == 1  # another note's name
    monkeypatch.setenv(QUIET_NOTES_VARIABLE, "rigid-body-modes, singular-mass")
    assert _notes(lambda: flexmor.read(c3d10)) == []
    with pytest.raises(OptionError, match="did you mean 'singular-mass'") as exc:
        with notes_quieted(["singular-mas"]):
            pass
    assert exc.value.params == ("quiet_note",)


def test_info_states_the_note_in_full_and_other_commands_in_one_line(c3d10, capsys, monkeypatch):
    code, out, err = run(capsys, "info", c3d10)
    assert code == 0 and f"note singular-mass: {c3d10}: mass matrix diagonal is not positive" in out
    assert NOTES["singular-mass"] in out and "singular-mass" not in err  # stated on stdout, not repeated
    rec = run_json(capsys, "info", c3d10)
    assert [n["name"] for n in rec["notes"]] == ["singular-mass"] and NOTES["singular-mass"] in rec["notes"][0]["text"]
    monkeypatch.setenv(QUIET_NOTES_VARIABLE, "singular-mass")  # info states it all the same
    assert NOTES["singular-mass"] in run(capsys, "info", c3d10)[1]


def _rigid_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if "rigid-body modes" in ln]


def test_the_rigid_body_modes_of_a_free_body(capsys, tmp_path, monkeypatch):
    base = ["reduce", FREE, "--method", "modal", "--order", "6", "--input", "TIP:y", "--no-error", "--force", "-o",
            tmp_path / "m.h5"]
    code, _, err = run(capsys, *base)
    (line,) = _rigid_lines(err)
    assert code == 0 and line.startswith("flexmor: warning: ") and "6 rigid-body modes (free body)" in line
    assert "(note rigid-body-modes: see flexmor info; silenced by --quiet-note rigid-body-modes" in line
    code, _, err = run(capsys, *base, "--quiet-note", "rigid-body-modes")
    assert code == 0 and _rigid_lines(err) == []
    monkeypatch.setenv(QUIET_NOTES_VARIABLE, "rigid-body-modes")
    code, _, err = run(capsys, *base)
    assert code == 0 and _rigid_lines(err) == []
    code, out, err = run(capsys, "info", FREE, "--modes", "8")
    assert code == 0 and f"note rigid-body-modes: {FREE}: 6 rigid-body modes" in out
    assert NOTES["rigid-body-modes"] in out
    monkeypatch.setenv(QUIET_NOTES_VARIABLE, "rigid-body-modes,sinuglar-mass")
    code, _, err = run(capsys, *base)
    assert code == 0 and f"{QUIET_NOTES_VARIABLE} names no note 'sinuglar-mass'" in err
    with pytest.raises(SystemExit):  # argparse: the names to choose from
        run(capsys, *base, "--quiet-note", "rigid")
    assert "invalid choice: 'rigid' (choose from 'singular-mass', 'rigid-body-modes')" in capsys.readouterr().err


def test_python_reduce_of_a_free_body_names_the_note(free):
    s = flexmor.System(free, inputs=["TIP:y"], band=BAND)
    (note,) = _notes(lambda: s.reduce_and_judge("modal", 6, judge=False))
    assert note.name == "rigid-body-modes"
    with notes_quieted(["rigid-body-modes"]):
        assert _notes(lambda: s.reduce_and_judge("modal", 6, judge=False)) == []


# -- the real cause ---------------------------------------------------------------------------------------------------
def test_add_marker_names_the_missing_model_as_the_cause():
    exu = pytest.importorskip("exudyn")
    from flexmor.io.exudyn import add_full_to_exudyn, add_marker
    from flexmor.models import cantilever

    model = cantilever(divisions=(4, 1, 1))
    mbs = exu.SystemContainer().AddSystem()
    body = add_full_to_exudyn(mbs, model, constrain_rigid=False)  # records no model
    with pytest.raises(ModelError) as exc:
        add_marker(mbs, body, None, "TIP")
    assert "no model was given and none was recorded by add_to_exudyn" in str(exc.value)
    assert "neither" not in str(exc.value) and exc.value.params == ("model", "target")
    with pytest.raises(ModelError, match=r"nor a node set of the model \(did you mean 'TIP'\? sets: ") as exc:
        add_marker(mbs, body, model, "TIPP")
    assert exc.value.params == ("target",)
    assert int(add_marker(mbs, body, model, "TIP")) >= 0


# -- the text output shows what the JSON shows ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bodies(clamped, tmp_path_factory):
    from flexmor.io import write_body

    s = flexmor.System(clamped, inputs=["TIP:y"], band=BAND, damping=Rayleigh(0, 1e-6), cache=False)
    folder = tmp_path_factory.mktemp("bodies")
    out = {}
    for method in ("krylov", "fw-sobt", "irka", "pod"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opts = {"max_iter": 3} if method == "irka" else {}
            write_body(s.reduce(method, 8, inertia_loads="off", **opts), folder / f"{method}.h5")  # the port's points
        out[method] = folder / f"{method}.h5"
    return out


def _row(out: str, label: str) -> str:
    (line,) = [ln for ln in out.splitlines() if ln.startswith(f"{label:<12}")]
    return line[12:]


def test_info_of_a_body_shows_its_points_cutoff_and_iterations(bodies, capsys):
    rec = run_json(capsys, "info", bodies["krylov"])["basis"]
    _, out, _ = run(capsys, "info", bodies["krylov"])
    points = _row(out, "points")
    moments = ", ".join(map(str, rec["moments"]))
    assert len(rec["points_hz"]) >= 4 and points.endswith(f"Hz (s / 2 pi), moments {moments}")
    for p in rec["points_hz"][1:]:  # on the frequency axis: i f
        assert f"{complex(p).imag:.4g}i" in points
    comp = rec["compressed"]  # the default body: chosen in the span of a larger greedy basis
    assert _row(out, "compressed").startswith(("the balanced truncation", "the leading columns", "the static"))
    assert f"of the greedy basis of order {comp['from_order']}" in _row(out, "compressed")

    rec = run_json(capsys, "info", bodies["fw-sobt"])["basis"]
    _, out, _ = run(capsys, "info", bodies["fw-sobt"])
    assert rec["cutoff_hz"] == BAND[1] and rec["band_hz"] == list(BAND)
    assert _row(out, "gramians").startswith(rec["gramians"]) and f"cutoff {rec['cutoff_hz']:g} Hz" in out

    rec = run_json(capsys, "info", bodies["irka"])["basis"]
    _, out, _ = run(capsys, "info", bodies["irka"])
    assert rec["iterations"] == rec["max_iter"] == 3
    assert _row(out, "iterations").startswith(f"3 of max_iter 3, last change of the points {rec['shift_change']:.2g}")

    rec = run_json(capsys, "info", bodies["pod"])["basis"]
    _, out, _ = run(capsys, "info", bodies["pod"])
    assert _row(out, "snapshots") == (f"frequency over 10-3000 Hz, {rec['n_nodes']} quadrature nodes, energy captured "
                                      f"{rec['energy_captured']:.6g}")


def test_reduce_prints_the_points_of_its_json(capsys, tmp_path):
    argv = ["reduce", str(CCX / "beam8_clamped_mat.sti"), "--method", "krylov", "--order", "8", "--input", "TIP:y",
            "--band", "10:3000", "--no-error", "-o"]
    rec = run_json(capsys, *argv, tmp_path / "a.h5")
    _, out, _ = run(capsys, *argv, tmp_path / "b.h5")
    (line,) = [ln for ln in out.splitlines() if ln.startswith("points: ")]
    for p in rec["info"]["points_hz"][1:]:
        assert f"{complex(p).imag:.4g}i" in line


def test_reduce_and_info_say_what_the_basis_was_built_for(capsys, tmp_path):
    """A supported body's krylov basis is built for its port and the frame's six inertia loads by default: the text
    of ``reduce`` and ``info`` says so (with how to build for the ports alone); with ``off`` the row is absent; a
    free body names the coupling master it is held at."""
    from helpers import CLAMPED

    base = ["reduce", CLAMPED, "--method", "krylov", "--order", "12", "--input", "TIP:y", "--band", "10:3000",
            "--rayleigh", "0:1e-6", "--no-error"]
    code, out, _ = run(capsys, *base, "-o", tmp_path / "k.h5")
    assert code == 0 and "the ports and 6 inertia loads: the frame's unit accelerations M R" in out
    code, out, _ = run(capsys, "info", tmp_path / "k.h5")
    assert _row(out, "built for").startswith("the ports and 6 inertia loads") and "--inertia-loads" in out
    assert run_json(capsys, "info", tmp_path / "k.h5", "--json")["basis"]["n_inertia_loads"] == 6
    code, out, _ = run(capsys, *base, "--inertia-loads", "off", "-o", tmp_path / "k0.h5")
    assert code == 0 and "built for" not in out
    code, out, _ = run(capsys, "reduce", FREE, "--method", "krylov", "--order", "16", "--interface", "FIX@rbe2",
                       "--input", "TIP:y", "--no-error", "-o", tmp_path / "f.h5")
    assert code == 0 and "the frame's accelerations of the body held at FIX@RBE2" in out
