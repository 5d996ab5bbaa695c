"""Modal checks (eigenfrequencies, MAC) and the self-contained HTML report."""

from __future__ import annotations

import base64
import io
import re
import subprocess

import numpy as np
import pytest
import scipy.linalg as sla

from flexmor.analysis.compare import FullResponse
from flexmor.analysis.modal_check import mac, modal_check
from flexmor.analysis.norms import h2_error
from flexmor.dynamics.time import simulate, step, time_errors
from flexmor.ports import make_ports
from flexmor.reduction import reduce

BAND = (10.0, 3000.0)


def test_mac_definition():
    rng = np.random.default_rng(1)
    x, y = rng.standard_normal((50, 1)), rng.standard_normal((50, 1))
    y -= x * (x.T @ y) / (x.T @ x)  # orthogonal to x
    A = mac(np.hstack([x, y]), np.hstack([-3 * x, y + 0.5 * x]))
    assert A[0, 0] == pytest.approx(1.0, abs=1e-14) and A[1, 0] == pytest.approx(0.0, abs=1e-14)
    c = 0.5 ** 2 * np.sum(x * x) / np.sum((y + 0.5 * x) ** 2)  # cos^2 of the angle
    assert A[0, 1] == pytest.approx(c, rel=1e-12)


def test_modal_basis_has_unit_mac_and_equal_frequencies(clamped, clamped_ref):
    # the square beam has repeated bending frequencies: the MAC must not depend on the arbitrary
    # orientation of the modes inside each two-dimensional eigenspace
    ports = make_ports(clamped, ["TIP:y"])
    red = reduce(clamped, "modal", 12, ports)
    c = modal_check(clamped, red, n_modes=10)
    n = c["full_hz"].size
    assert n == 11  # modes 10 and 11 share 3117 Hz: a repeated eigenvalue is never cut in two
    assert np.sum(np.isclose(c["full_hz"][:-1], c["full_hz"][1:], rtol=1e-6)) >= 3
    assert np.max(np.abs(np.diag(c["mac"][:, :n]) - 1.0)) < 1e-10
    assert np.array_equal(c["pair"], np.arange(n))
    # the reduced frequencies come from the rounded Vᵀ K V: |Δλ_i| ~ eps λ_max, so Δf_i/f_i is a few
    # eps λ_max/λ_i (7.1e-11 for the first mode here, measured at most 0.38 of that)
    lam_max = sla.eigh(clamped.K.toarray(), clamped.M.toarray(), eigvals_only=True,
                       subset_by_index=[clamped.n_dof - 1] * 2)[0]
    lam = (2 * np.pi * c["full_hz"]) ** 2
    assert np.all(np.abs(c["freq_rel_error"]) <= 4 * np.finfo(float).eps * lam_max / lam)
    assert c["full_hz"] == pytest.approx(clamped_ref[:n], rel=1e-4)  # CalculiX's own eigenfrequencies


def test_truncated_bases_have_upper_bound_frequencies(clamped, free):
    ports = make_ports(clamped, ["TIP:y", "TIP:z"])
    cb = reduce(clamped, "craig-bampton", 33, ports, interface=["TIP"])
    c = modal_check(clamped, cb, n_modes=6)
    k = c["full_hz"].size
    # Rayleigh-Ritz: the i-th reduced eigenfrequency is never below the i-th full one
    assert np.all(c["reduced_hz"][:k] >= c["full_hz"] * (1 - 1e-10))
    assert np.all(c["pair_mac"][:4] > 0.99) and np.all(c["freq_rel_error"][:4] < 0.01)
    red = reduce(free, "modal", 8, make_ports(free, ["TIP:y"]))
    c = modal_check(free, red, n_modes=8)
    assert c["n_rigid_full"] == 6 and c["n_rigid_reduced"] == 0
    assert np.min(c["pair_mac"]) > 1 - 1e-10


@pytest.fixture(scope="module")
def report(clamped, tmp_path_factory):
    from flexmor.report.contents import build_report
    from flexmor.report.html import write_report

    model = clamped.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    reds = [reduce(model, "modal", 8, ports),
            reduce(model, "craig-bampton", 33, ports, interface=["TIP"])]
    reds[1].info["hankel_sv"] = np.geomspace(1.0, 1e-6, 20).tolist()  # as a balanced-truncation body reports
    rep = build_report(model, ports, reds, band=BAND, seconds=[0.5, None], n_modes=6, dt=5e-5, t_end=0.01)
    path = tmp_path_factory.mktemp("report") / "report.html"
    write_report(rep, path)
    return model, ports, reds, rep, path, path.read_text(encoding="utf-8")


def test_report_is_self_contained_with_valid_images(report):
    import matplotlib.image as mpimg

    *_, rep, _, text = report
    imgs = re.findall(r'<img[^>]*src="([^"]*)"', text)
    assert text.count("data:image/png;base64,") == len(imgs) == 6  # body, |H|, rel_error, SV, MAC, time
    for src in imgs:
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        arr = mpimg.imread(io.BytesIO(png))
        assert arr.shape[0] > 200 and arr.shape[1] > 200 and np.ptp(arr) > 0.1  # not blank
    assert not re.search(r'(src|href)="(?!data:)', text) and "http" not in text
    for sec in ("summary", "body", "frf", "rel-error", "singular-values", "modal", "time"):
        assert f'id="{sec}"' in text
    assert list(rep.figures) == ["frf", "rel_error", "singular_values", "mac", "time", "body"]
    # the labels (modal r=8, craig-bampton r=33) say method and order: no columns of their own, the table fits
    assert "<th>body</th><th>band_<wbr>error</th>" in text and "<th>method</th>" not in text
    from flexmor.report.html import _summary_table

    rows = [dict(r, label=f"body{k}.h5") for k, r in enumerate(rep.rows)]  # labels of files: the columns stay
    assert "<th>body</th><th>method</th><th>order</th>" in _summary_table(rows)


@pytest.mark.slow
def test_report_numbers_equal_the_computed_ones(report):
    model, ports, reds, rep, _, text = report
    full = FullResponse(model, ports, BAND, cache=False)
    y = simulate(model, step(), dt=5e-5, t_end=0.01, ports=ports)
    for row, red in zip(rep.rows, reds):
        err = full.evaluate(red)
        assert row["band_error"] == pytest.approx(err.band_error, rel=1e-6)
        assert row["max_rel_error"] == pytest.approx(err.max_rel_error, rel=1e-6)
        assert row["h2_error"] == pytest.approx(h2_error(model, ports, red), rel=1e-9)
        e = time_errors(y, simulate(red, step(), dt=5e-5, t_end=0.01))
        assert row["time_mean_error"] == pytest.approx(e["time_mean_error"], rel=1e-9)
        for key in ("band_error", "max_rel_error", "h2_error", "time_mean_error", "time_max_error"):
            assert f"<td>{row[key]:.3e}</td>" in text
    assert rep.rows[0]["band_error"] < 1e-3 < rep.rows[1]["band_error"]  # modal 8 beats CB here
    assert "<td>0.500</td>" in text  # the given reduction time
    # modal r=8 reproduces the six lowest eigenfrequencies: MAC 1.0000 and Δf/f ~ 0 in its columns
    modal = rep.modal["bodies"]["modal r=8"]
    assert np.allclose(modal["pair_hz"], rep.modal["full_hz"], rtol=1e-10)
    assert text.count("<td>1.0000</td>") >= 6
    assert f"<td>{rep.modal['full_hz'][0]:.4f}</td>" in text


@pytest.mark.browser
def test_report_opens_in_headless_chromium(report):
    from browser import find_chromium

    *_, path, text = report
    exe = find_chromium()
    if exe is None:
        pytest.skip("no chromium/chrome on PATH; images are checked by decoding them instead")
    js = ("<script>window.onload=()=>{const bad=[...document.images].filter(i=>!i.complete||i.naturalWidth==0)"
          ".length;document.title='BROKEN='+bad+' OF '+document.images.length;}</script>")
    probe = path.with_name("probe.html")
    probe.write_text(text.replace("</body>", js + "</body>"), encoding="utf-8")
    out = subprocess.run([exe, "--headless", "--disable-gpu", "--no-sandbox", "--virtual-time-budget=5000",
                          "--dump-dom", probe.as_uri()], check=False, capture_output=True, text=True,
                         timeout=120)
    assert "BROKEN=0 OF 6" in out.stdout


@pytest.mark.slow
def test_cli_report_writes_html_and_json(report, tmp_path, capsys):
    import json

    from helpers import CLAMPED

    from flexmor.cli import main
    from flexmor.io import write_body

    _, _, reds, rep, _, _ = report
    files = []
    for k, red in enumerate(reds):
        files.append(tmp_path / f"body{k}.h5")
        write_body(red, files[-1])
    out = tmp_path / "r.html"
    code = main(["report", CLAMPED, *map(str, files), "-o", str(out), "--band", "10:3000",
                 "--dt", "5e-5", "--t-end", "0.01", "--modes", "6", "--json"])
    assert code == 0
    res = json.loads(capsys.readouterr().out)
    assert [r["label"] for r in res["results"]] == ["modal r=8", "craig-bampton r=33"]
    # the bodies carry the Rayleigh damping; the report applies it to the undamped file: same numbers
    for got, want in zip(res["results"], rep.rows):
        assert got["band_error"] == pytest.approx(want["band_error"], rel=1e-6)
        assert got["time_max_error"] == pytest.approx(want["time_max_error"], rel=1e-9)
    assert out.read_text(encoding="utf-8").count("data:image/png;base64,") == 6  # hankel_sv kept in the .h5
    # a dt coarser than 1/(20 FMAX) is said, with the frequency the time responses resolve
    assert "time responses with dt = 5e-05 s (as given), coarser than 1/(20 FMAX) = 1.67e-05 s: they resolve up " \
           "to about 1000 Hz of the 10-3000 Hz band" in out.read_text(encoding="utf-8")


def test_report_on_a_model_without_node_coordinates():
    from helpers import DATA

    from flexmor.io import read
    from flexmor.report.contents import build_report

    model = read(DATA / "mor" / "LF10.mat")  # matrices with their own B, C and D, no nodes
    ports = make_ports(model)
    red = reduce(model, "krylov", 6, ports)
    rep = build_report(model, ports, [red], band=(1.0, 1000.0), n_modes=4)
    assert model.n_nodes == 0
    assert "body" not in rep.figures and not rep.scene
    assert "the model has no node coordinates: no picture of the body" in rep.notes
    assert list(rep.figures) == ["frf", "rel_error", "mac", "time"]
    assert rep.rows[0]["h2_error"] == pytest.approx(h2_error(model, ports, red), rel=1e-9)
    assert rep.rows[0]["time_max_error"] > 0 and rep.time["n_steps"] > 0
