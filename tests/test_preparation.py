"""One preparation: ``flexmor reduce`` maps its flags onto :func:`flexmor.prepare.prepare` (through
:class:`flexmor.System`), so the same flags and keywords give bit-identical bodies, option by option;
the command line reads and prepares nothing itself."""

from __future__ import annotations

import ast
from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.io
from helpers import CLAMPED, FREE, run_json
from test_cli_units import mm_copy

import flexmor
import flexmor.prepare
from flexmor.errors import OptionError
from flexmor.io import read_body
from flexmor.models import cantilever

CLI = Path(flexmor.__file__).parent / "cli"


def _mesh_case(tmp_path):
    beam = cantilever(2, clamped=False)
    scipy.io.mmwrite(tmp_path / "beam_K.mtx", beam.K, symmetry="symmetric")
    scipy.io.mmwrite(tmp_path / "beam_M.mtx", beam.M, symmetry="symmetric")
    meshio.write(tmp_path / "beam.vtu", beam.mesh.to_meshio(beam.node_ids, beam.xyz))
    tip = int(beam.node_ids[np.argmax(beam.xyz[:, 0] + beam.xyz[:, 1] + beam.xyz[:, 2])])
    return tmp_path / "beam_K.mtx", {"mesh": tmp_path / "beam.vtu"}, ["--mesh", tmp_path / "beam.vtu"], f"{tip}:z"


#: option -> (model, the keywords of System, the flags of flexmor reduce, inputs, method, order, method options)
#: (a callable model makes its file in tmp_path and returns the whole case)
CASES = {
    "format": (CLAMPED, {"format": "calculix"}, ["--format", "calculix"], "TIP:y", "krylov", 4, {"points": "0"}),
    "mesh": (_mesh_case, None, None, None, "modal", 8, {}),
    "units": (lambda tmp: (mm_copy(tmp), {"units": "mm-t-s"}, ["--units", "mm-t-s"], "TIP:y"), None, None, None,
              "modal", 8, {}),
    "select": (FREE, {"select": ["END=box:0.9,0,0,1,1,1"], "interfaces": ["END@rbe2"]},
               ["--select", "END=box:0.9,0,0,1,1,1", "--interface", "END@rbe2"], "END@rbe2:y", "craig-bampton", 8, {}),
    "preload": (CLAMPED, {"preload": ["TIP:x=5e5", "gravity:0,0,-9.81"]},
                ["--preload", "TIP:x=5e5", "--preload", "gravity:0,0,-9.81"], "TIP:y", "krylov", 4, {"points": "0"}),
    "material": (CLAMPED, {"preload": ["TIP:x=5e5"], "material": (2.0e11, 0.25, 7800.0)},
                 ["--preload", "TIP:x=5e5", "--material", "2.0e11,0.25,7800"], "TIP:y", "krylov", 4, {"points": "0"}),
    "rayleigh": (CLAMPED, {"damping": {"rayleigh": (0.0, 1e-5)}}, ["--rayleigh", "0:1e-5"], "TIP:y", "krylov", 4,
                 {"points": "0,500j"}),
    "modal_damping": (CLAMPED, {"damping": {"modal_damping": 0.02}, "band": (10, 2000)},
                      ["--modal-damping", "0.02", "--band", "10:2000"], "TIP:y", "krylov", 4, {"points": "0,500j"}),
    "band_rayleigh": (CLAMPED, {"damping": {"band_rayleigh": 0.01}, "band": "10:2000"},
                      ["--band-rayleigh", "0.01", "--band", "10:2000"], "TIP:y", "krylov", 4, {"points": "0,500j"}),
    "band": (CLAMPED, {"band": (10, 3000), "damping": {"rayleigh": (0.0, 1e-6)}},
             ["--band", "10:3000", "--rayleigh", "0:1e-6"], "TIP:y", "fw-sobt", 6, {}),
    "interfaces": (FREE, {"interfaces": ["TIP"]}, ["--interface", "TIP"], "TIP:y", "craig-bampton", 30, {}),
}


@pytest.mark.parametrize("option", list(CASES))
def test_the_same_flags_and_keywords_give_bit_identical_bodies(capsys, tmp_path, option):
    model, keywords, flags, port, method, order, options = CASES[option]
    if callable(model):
        model, keywords, flags, port = model(tmp_path)
    path = tmp_path / "cli.h5"
    args = [str(a) for a in flags] + [f"--{k.replace('_', '-')}={v}" for k, v in options.items()]
    made = run_json(capsys, "reduce", model, "--method", method, "--order", str(order), "--input", port, *args,
                    "--no-error", "--no-cache", "-o", path)
    cli = read_body(path)
    system = flexmor.System(model, inputs=[port], **keywords)
    body = system.reduce(method, order, **options)
    assert made["order"] == body.order == cli.order
    for name in ("M", "K", "D", "B", "C", "V"):
        a, b = getattr(cli, name), getattr(body, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert a.dtype == b.dtype and np.array_equal(a, b), f"{option}: {name} differs"
    assert cli.origin == body.origin and cli.selections == body.selections and cli.couplings == body.couplings
    assert cli.units == body.units
    assert system.preparation == {k: (list(v) if k in ("select", "preload") else v) for k, v in keywords.items()
                                  if k in flexmor.prepare.PREPARATION}


def test_the_command_line_prepares_nothing_itself():
    """cli/ reaches the model through flexmor.prepare (directly or through System) only: none of the
    steps of a preparation is imported or called there."""
    steps = {"read", "to_si", "with_mesh", "with_selections", "with_preload", "prepare_model", "couple",
             "with_damping", "damping_of", "apply_damping", "read_on_root"}
    for path in sorted(CLI.glob("*.py")):
        tree = ast.parse(path.read_text())
        imported = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
        called = {n.func.attr if isinstance(n.func, ast.Attribute) else getattr(n.func, "id", None)
                  for n in ast.walk(tree) if isinstance(n, ast.Call)}
        assert not (imported | called) & steps, f"{path.name}: {sorted((imported | called) & steps)}"
    uses = {p.name for p in CLI.glob("*.py") if "prepare(" in p.read_text() or "System(" in p.read_text()}
    assert {"commands.py", "export.py"} <= uses


def test_the_preparation_is_one_step_that_reports_what_it_made():
    done = flexmor.prepare.prepare(CLAMPED, select=["END=box:0.9,0,0,1,1,1", "P=nearest:1,0.05,0.05"],
                                   preload=["spin:0,0,10"], couplings=["END@rbe2"],
                                   damping={"rayleigh": (0.0, 1e-6)}, check=lambda m: m.n_dof)
    assert done.check == 270 and done.couplings == ["END@rbe2"]
    assert done.model.n_dof == 270 - 18 * 3 + 6 and done.as_read.n_dof == 270
    assert done.unloaded.n_dof == done.model.n_dof and done.unloaded.preload is None
    assert done.model.preload["specs"] == ["spin:0,0,10"] and done.model.damping.beta == 1e-6
    assert [r["name"] for r in done.nearest] == ["P"]


@pytest.mark.parametrize("keywords, match", [
    ({"select": "END=box:0.9,0,0,1,1,1"}, "select must be a list of texts"),
    ({"preload": "TIP:x=1"}, "preload must be a list of texts"),
    ({"damping": {"raleigh": (0, 1e-6)}}, "unknown key"),
    ({"damping": {"rayleigh": (0, 1e-6), "modal_damping": 0.01}}, "not both"),
])
def test_a_preparation_keyword_of_the_wrong_kind_is_refused_naming_it(keywords, match):
    with pytest.raises(OptionError, match=match):
        flexmor.System(CLAMPED, inputs=["TIP:y"], **keywords)


def test_a_model_already_read_is_not_read_again():
    model = flexmor.io.read(CLAMPED)
    with pytest.raises(OptionError, match="units say how a file is read; the model was given read"):
        flexmor.prepare.prepare(model, units="mm-t-s")
