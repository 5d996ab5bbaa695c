"""The study object flexmor.System, the flat namespace of ``import flexmor`` and the notebook plots."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import CCX
from printed import output_differs

import flexmor
from flexmor.damping import Rayleigh
from flexmor.errors import ModelError, PortError

BAND = (10.0, 3000.0)


@pytest.fixture(scope="module")
def beam():
    return flexmor.System(CCX / "beam8_clamped_mat.sti", inputs=["TIP:y"], band=BAND,
                          damping=Rayleigh(0.0, 1e-6), cache=False)


def test_system_reduces_for_its_band_and_judges(beam):
    body = beam.reduce("krylov", 16)  # the port and the frame's six inertia loads (measured 6.0e-8)
    assert body.info["band"] == list(BAND) and body.info["options"]["band"] == list(BAND)
    err = beam.judge(body)
    assert isinstance(err, flexmor.ErrorMeasures) and err.band_hz == BAND
    assert err.band_error < 1e-6 and not any("built for" in n for n in err.notes)
    # the same as the library steps it is made of
    model = flexmor.read(CCX / "beam8_clamped_mat.sti").with_rayleigh(0.0, 1e-6)
    ports = flexmor.make_ports(model, ["TIP:y"])
    same = flexmor.reduce(model, "krylov", 16, ports, band=BAND)
    assert np.allclose(same.K, body.K) and flexmor.FullResponse(model, ports, BAND).evaluate(same).band_error == \
        pytest.approx(err.band_error, rel=1e-6)


def test_system_refuses_a_body_of_another_study_with_the_reason(beam, clamped):
    undamped = flexmor.System(clamped, inputs=["TIP:y"], band=BAND)
    with pytest.raises(ModelError, match="damping"):
        beam.judge(undamped.reduce("modal", 6))
    other_ports = flexmor.System(beam.model, inputs=["TIP:z"], band=BAND)
    with pytest.raises(PortError, match="TIP:z"):
        beam.judge(other_ports.reduce("modal", 6))
    free = flexmor.System(CCX / "beam8_free_mat.sti", inputs=["TIP:y"], band=BAND, damping=Rayleigh(0.0, 1e-6))
    with pytest.raises(ModelError, match="297 DOF, this model has 270"):
        beam.judge(free.reduce("modal", 6))


def test_system_passes_its_interfaces_and_damping_by_keywords(clamped):
    s = flexmor.System(clamped, inputs=["TIP:y"], interfaces=["TIP"], band=BAND, damping={"band_rayleigh": 0.02})
    assert s.model.damping.zeta == 0.02 and tuple(s.model.damping.band) == BAND
    body = s.reduce("craig-bampton", 33)
    assert body.info["options"]["interface"] == ["TIP"]
    assert s.judge(body).band_error < 1e-2


def test_system_frf_and_simulate_are_the_full_models(beam):
    full = beam.full
    H = beam.frf(full.freqs[:3])
    np.testing.assert_allclose(H, full.H[:3], rtol=1e-7)
    from flexmor.dynamics.time import step

    y = beam.simulate(step(), dt=5e-5, t_end=2e-3)
    assert y.displacement.shape == (41, 1, 1) and y.displacement[-1, 0, 0] > 0


def test_flat_namespace():
    for name in flexmor.__all__:
        assert getattr(flexmor, name) is not None, name
    assert flexmor.io.read is flexmor.read and flexmor.System.__module__ == "flexmor.study"
    assert {"System", "read", "make_ports", "project", "reduce", "simulate", "state_space", "FullResponse",
            "ErrorMeasures", "FlexmorError", "io"} <= set(flexmor.__all__)


def _env(**extra) -> dict:
    """The environment of a child interpreter that imports this flexmor, from any working directory."""
    src = str(Path(flexmor.__file__).parents[1])
    return {**os.environ, **extra, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=_env())
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_import_flexmor_fills_the_method_registry_without_h5py_or_matplotlib():
    out = _run("import sys; sys.modules['h5py'] = None; sys.modules['matplotlib'] = None\n"
               "import flexmor; print(len(flexmor.reduction.METHODS), flexmor.io.__name__)")
    n, io = out.split()
    assert int(n) >= 13 and io == "flexmor.io"


def test_report_plots_leave_the_backend_alone():
    out = _run("import matplotlib; matplotlib.use('svg')\n"
               "import numpy as np, flexmor.report.plots as p\n"
               "png = p.rel_error_png(np.array([1.0, 2.0]), {'a': np.array([1e-3, 2e-3])})\n"
               "print(matplotlib.get_backend(), png[:4] == b'\\x89PNG')")
    assert out.split() == ["svg", "True"]


def test_notebook_plots_draw_on_the_axes_given(beam):
    from matplotlib.figure import Figure

    from flexmor.report.plots import plot_error, plot_frf, plot_modes

    full = beam.full
    body = beam.reduce("modal", 6)
    ax = Figure().subplots()
    assert plot_frf(full.freqs, full.H, ax=ax, label="full") is ax
    assert plot_error(beam.judge(body), ax=ax, label="modal 6") is ax
    np.testing.assert_allclose(ax.lines[0].get_ydata(), np.abs(full.H[:, 0, 0]))
    np.testing.assert_allclose(ax.lines[1].get_ydata(), beam.judge(body).rel_error)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["full", "modal 6"]
    ax2 = Figure().subplots()
    assert plot_modes(np.eye(3), ax=ax2, title="MAC") is ax2 and len(ax2.images) == 1


def readme_python_section(text: str) -> tuple[list[str], str]:
    """The ```python blocks of the README's "## Python" section and the output it quotes after "this prints"
    (tests/test_doc_blocks.py counts these blocks as run)."""
    section = text.split("\n## Python\n", 1)[1].split("\n## ", 1)[0]
    blocks = [b.split("```", 1)[0] for b in section.split("```python\n")[1:]]
    printed = section.split("this prints\n\n```\n", 1)[1].split("```", 1)[0]
    return blocks, printed


def test_the_readme_python_section_runs_and_prints_its_numbers(tmp_path):
    blocks, printed = readme_python_section((Path(__file__).parents[1] / "README.md").read_text())
    code = "\n".join(blocks)
    (tmp_path / "examples" / "data").mkdir(parents=True)
    for ext in ("sti", "mas", "dof", "inp"):  # the README reads examples/data/beam.sti from the repository's root
        name = Path("examples") / "data" / f"beam.{ext}"
        (tmp_path / name).write_bytes((Path(__file__).parents[1] / name).read_bytes())
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                         env=_env(MPLBACKEND="Agg"))
    assert out.returncode == 0, out.stderr
    got = "\n".join(out.stdout.splitlines()[:len(printed.strip().splitlines())])
    assert output_differs(printed, got) is None, output_differs(printed, got)
    assert (tmp_path / "body.h5").exists()


def test_system_on_a_free_body_with_an_interface_coupling(free):
    s = flexmor.System(free, inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"], band=BAND, damping=Rayleigh(0.0, 1e-6))
    body = s.reduce("craig-bampton", 20)
    assert body.couplings == ["TIP@rbe2"] and body.info["options"]["interface"] == ["TIP@rbe2"]
    mounted = s.mounted(body)
    assert [c["held"] for c in mounted["cases"]] == ["clamped", "pinned"] and mounted["max_frequency_error"] < 1e-5
    same, record = s.reduce_and_judge("craig-bampton", 20)  # the command line's job, on the study's full FRF
    assert record["band_hz"] == list(BAND) and record["mounted"]["cases"][0]["interface"] == "TIP@RBE2"
    assert {k: record[k] for k in ("band_error", "hinf_error", "judged")} == \
        {k: s.judge(body).to_dict()[k] for k in ("band_error", "hinf_error", "judged")}


def test_the_command_line_reduce_is_system_reduce_and_judge(capsys, monkeypatch, tmp_path):
    """``flexmor reduce`` makes its body and record with System.reduce_and_judge: the same numbers
    as the study from Python, and what System records reaches the file and the JSON."""
    from helpers import run_json

    import flexmor.study

    calls = []
    orig = flexmor.study.System.reduce_and_judge

    def spy(self, method, order=None, **kw):
        calls.append((method, order, self.couplings, self.selections, kw.get("judge", True)))
        return orig(self, method, order, **kw)

    monkeypatch.setattr(flexmor.study.System, "reduce_and_judge", spy)
    rec = run_json(capsys, "reduce", CCX / "beam8_free_mat.sti", "--method", "krylov", "--order", "10",
                   "--input", "TIP:y", "--input", "FIX@rbe2:y", "--band", "10:3000", "--rayleigh", "0:1e-6",
                   "--select", "Q=nearest:0,0,0", "--no-cache", "-o", tmp_path / "k.h5")
    assert calls == [("krylov", 10, ["FIX@rbe2"], ["Q=nearest:0,0,0"], True)]
    assert rec["timings"]["full_frf"] > 0 and rec["couplings"] == ["FIX@rbe2"] and rec["coupling_frequencies"]
    body = flexmor.read_body(tmp_path / "k.h5")
    assert body.couplings == ["FIX@rbe2"] and body.selections == ["Q=nearest:0,0,0"]
    monkeypatch.undo()
    study = flexmor.System(CCX / "beam8_free_mat.sti", inputs=["TIP:y", "FIX@rbe2:y"], band=BAND,
                           damping=Rayleigh(0.0, 1e-6), cache=False)
    same, srec = study.reduce_and_judge("krylov", 10)
    assert np.allclose(same.K, body.K, rtol=1e-12, atol=0)
    assert srec["band_error"] == pytest.approx(rec["band_error"], rel=1e-9)
    assert srec["mounted"]["cases"] and len(srec["mounted"]["cases"]) == len(rec["mounted"]["cases"])


def test_system_reduce_and_judge_computes_the_full_frf_once_and_after_the_reduction(clamped, monkeypatch):
    import flexmor.analysis.compare as compare

    made = []
    orig = compare.FullResponse.__init__

    def init(self, *a, **k):
        made.append(1)
        orig(self, *a, **k)

    monkeypatch.setattr(compare.FullResponse, "__init__", init)
    s = flexmor.System(clamped, inputs=["TIP:y"], band=BAND, damping=Rayleigh(0.0, 1e-6), cache=False)
    body, rec = s.reduce_and_judge("modal", 6, judge=False)
    assert made == [] and rec["band_error"] is None and "full_frf" not in rec["timings"]
    assert body.info["band"] is None and rec["order"] == 6
    port = {"inertia_loads": "off"}  # orders 3 and 4 for the port alone: measured 9.0e-5 and 1.1e-6
    _, first = s.reduce_and_judge("krylov", 3, **port)
    _, second = s.reduce_and_judge("krylov", 4, **port)
    assert made == [1] and second["timings"]["full_frf"] < 0.1 * first["timings"]["full_frf"]
    assert second["band_error"] < first["band_error"] < 1e-3
    prepared = flexmor.System.prepared(s.model, s.ports, band=BAND, cache=False)
    assert prepared.judge(s.reduce("krylov", 3, **port)).band_error == pytest.approx(first["band_error"], rel=1e-9)


def test_wrong_arguments_of_the_python_api_are_named(beam, clamped, free, tmp_path):
    """Each wrong type at the API's entry points is a FlexmorError that names the argument, not an
    AttributeError or ValueError from inside (as they were: 'int' object has no attribute 'node_sets', 'list'
    object has no attribute 'B', could not convert string to float ...)."""
    from flexmor.errors import OptionError

    cases = [
        (lambda: flexmor.System(42, inputs=["TIP:y"]), ModelError, "System needs an FE model or the path of its file"),
        (lambda: flexmor.System(clamped, inputs="TIP:y"), PortError, "inputs must be a list of port SPECs, e.g. "
                                                                     "['TIP:y'], got the string 'TIP:y'"),
        (lambda: flexmor.System(clamped, inputs=["TIP:y"], interfaces="TIP"), OptionError,
         "interfaces must be a list of SPECs"),
        (lambda: flexmor.System(clamped, inputs=["TIP:y"], damping=0.02), OptionError,
         "damping must be a flexmor.damping object"),
        (lambda: flexmor.System(clamped, inputs=["TIP:y"], damping={"foo": 0.02}), OptionError,
         "unknown key(s) 'foo'"),
        (lambda: beam.judge("body.h5"), ModelError, "a reduced body (flexmor.reduce(...), or flexmor.io.read_body"),
        (lambda: beam.frf("abc"), OptionError, "freqs must be frequencies in Hz"),
        (lambda: beam.simulate("step", dt=1e-4, t_end=1e-3), OptionError, "u must be real, finite numbers"),
        (lambda: flexmor.reduce(clamped, "krylov", 8, ["TIP:y"]), PortError, "ports must be a Ports"),
        (lambda: flexmor.export("abc", tmp_path / "x.h5"), OptionError, "export writes a reduced body"),
        (lambda: beam.reduce_and_judge("krylov", 40, tol="1e-6"), OptionError, "tol must be a positive number"),
    ]
    for call, kind, words in cases:
        with pytest.raises(kind) as exc:
            call()
        assert words in str(exc.value), str(exc.value)
    # the FE model's file where a model is wanted, as add_to_exudyn takes it
    fs = flexmor.System(free, inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"], band=BAND, damping=Rayleigh(5, 2e-6))
    body = fs.reduce("craig-bampton", 16)
    assert flexmor.export(body, tmp_path / "b.SID_FEM", model=CCX / "beam8_free_mat.sti") == "sid"
