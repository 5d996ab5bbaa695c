"""The body reduced, judged and stored is the body exported; what it was judged against is said.

Regression tests of a user's run on a free plate-rods-plate solid (issue 29): krylov, fw-sobt,
pod ... kept the rigid-body modes in the basis by default, were judged at that order on the full
response, and export wrote another body (order - rigid modes); a Krylov body resonated where the
full model has no resonance without a word; the RBE2 at the hole stiffened the model unsaid; the
report's plots drew another reference than its table.
"""

import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from helpers import FREE, run_json

from flexmor.analysis.compare import JUDGED_ELASTIC, JUDGED_RIGID, FullResponse
from flexmor.basis import Basis
from flexmor.checks import coupling_frequencies
from flexmor.cli import main
from flexmor.couplings import couple
from flexmor.errors import FlexmorWarning
from flexmor.io import read_body
from flexmor.models import plate_structure
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.rigid import elastic_body, exclude_rigid, rigid_content, rigid_residual
from flexmor.workflow import apply_damping, reduce_and_judge

BAND = (10.0, 2000.0)


@pytest.fixture(scope="module")
def damped(free):
    return apply_damping(free, modal_damping=0.01, band=BAND)


@pytest.fixture(scope="module")
def full(damped):
    return FullResponse(damped, make_ports(damped, ["TIP:y", "TIP:z"]), BAND, cache=False)


def _elastic_hz(model, k):
    """The k lowest elastic eigenfrequencies from a dense eigen solve of its own (rigid-body modes skipped)."""
    lam = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, k + 5])
    return np.sqrt(lam[6:]) / (2 * np.pi)


@pytest.mark.parametrize("method, order", [("krylov", 12), ("pod", 12), ("fw-sobt", 10), ("sobt", 10),
                                           ("two-step", 10), ("svdmor", 10), ("adaptive", 12)])
@pytest.mark.slow
def test_free_body_default_is_the_exported_body(damped, full, method, order):
    """The defaults exclude rigid-body motion: stored order = judged order = exported order. Before,
    krylov 12 on TIP:y, TIP:z held the 4 rigid motions those forces excite and export wrote order 8
    (fw-sobt 10 -> 6, two-step 10 -> 6 ...), judged on the whole response with its rigid motion."""
    ports = make_ports(damped, ["TIP:y", "TIP:z"])
    red, res = reduce_and_judge(damped, method, order, ports, band=BAND, full=full)
    assert red.info["n_rigid_excluded"] == 6 and rigid_residual(damped, red.V) < 1e-10
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexmorWarning)  # export keeps the body as it is: no warning
        exported = elastic_body(damped, red)
    assert exported is red and res["order"] == red.order == order
    assert res["judged"] == JUDGED_ELASTIC
    # Rayleigh-Ritz on the elastic subspace: the first reduced mode is an upper bound of the first elastic one
    f1 = _elastic_hz(damped, 1)[0]
    assert f1 * (1 - 1e-9) <= red.frequencies_hz()[0] < 1.01 * f1


def test_rigid_include_is_still_there_and_judged_on_the_full_response(damped, full):
    red, res = reduce_and_judge(damped, "krylov", 12, make_ports(damped, ["TIP:y", "TIP:z"]), band=BAND, full=full,
                                rigid="include")
    assert red.info["n_rigid_included"] == 4 and res["judged"] == JUDGED_RIGID
    # it holds rigid motion: the floating frame's body would be the basis without it, of order 8
    assert rigid_content(damped, red.V) < 1e-6
    assert exclude_rigid(damped, Basis(red.V, "krylov", {"rigid": "exclude"})).V.shape[1] == 8


@pytest.mark.slow
def test_cli_reduce_stores_the_order_it_judged_and_export_writes(capsys, tmp_path):
    """``flexmor reduce`` of a free body with krylov's defaults: the JSON, the .h5 and the body an FFRF
    export makes of it have one order; the table says what was judged."""
    body = tmp_path / "k.h5"
    out = run_json(capsys, "reduce", FREE, "--method", "krylov", "--order", "12", "--input", "TIP:y", "--input",
                   "TIP:z", "--modal-damping", "0.01", "--band", "10:2000", "-o", str(body), "--json")
    assert out["order"] == 12 and out["judged"] == JUDGED_ELASTIC and out["info"]["rigid"] == "exclude"
    stored = read_body(body)
    assert stored.order == 12 and stored.errors["judged"] == JUDGED_ELASTIC
    from flexmor.io import read

    assert elastic_body(read(FREE), stored) is stored
    assert main(["reduce", FREE, "--method", "krylov", "--order", "12", "--input", "TIP:y", "--modal-damping", "0.01",
                 "--band", "10:2000", "-o", str(tmp_path / "t.h5")]) == 0
    assert f"judged: {JUDGED_ELASTIC}" in capsys.readouterr().out


def test_modal_excludes_the_six_rigid_modes(damped):
    red = reduce(damped, "modal", 8, make_ports(damped, ["TIP:y"]))
    assert red.order == 8 and red.info["n_rigid"] == 6 and red.info["n_rigid_excluded"] == 6
    np.testing.assert_allclose(red.frequencies_hz(), _elastic_hz(damped, 8), rtol=1e-8)
    assert elastic_body(damped, red) is red


@pytest.mark.slow
def test_guyan_on_a_free_body_is_inertia_relief_not_rigid_motion(free):
    """One RBE2 interface on the free beam: its 6 constraint modes are pure rigid motion, so the Guyan
    body had no elastic coordinate at all (export: 'empty basis'). By default it now has the 6
    inertia-relief attachment modes: measured rel_error 6.8e-6 at 10 Hz (quasi-static), first
    frequency 654.7 Hz above the first elastic one (620.68 Hz, Rayleigh-Ritz)."""
    model = apply_damping(couple(free, ["TIP@rbe2"]).model, modal_damping=0.01, band=BAND)
    ports = make_ports(model, ["TIP@rbe2:y", "TIP@rbe2:z"])
    red, res = reduce_and_judge(model, "guyan", None, ports, band=BAND, interface=["TIP@rbe2"])
    assert red.order == 6 and red.info["attachment"] == "inertia-relief" and rigid_residual(model, red.V) < 1e-12
    assert elastic_body(model, red) is red and res["judged"] == JUDGED_ELASTIC
    assert red.errors["rel_error"][0] < 1e-4  # 10 Hz: the static elastic response is exact
    assert red.frequencies_hz()[0] == pytest.approx(654.71, rel=1e-4) and red.frequencies_hz()[0] > 620.68
    old = reduce(model, "guyan", None, ports, interface=["TIP@rbe2"], rigid="include")
    assert np.all(old.frequencies_hz() < 1.0)  # the classic basis: rigid motion only


@pytest.mark.slow
def test_spurious_resonance_is_noted_and_marked(capsys, tmp_path):
    """krylov 3 for FIX:y, TIP:y on the free beam: the body resonates at 1760.9 Hz where the full model
    has none in the band (its resonances: 620.7, 1610.4, 1668.6 Hz); measured max_rel_error 6.35 at
    1765 Hz, 6.6x the full |H| at 1761 Hz. The resonance is the body's own eigenfrequency (undamped
    pencil, modal damping keeps it)."""
    points = "20,141.4213562373095,2000"  # three real points (the earlier default): the body with that resonance
    out = run_json(capsys, "reduce", FREE, "--method", "krylov", "--points", points, "--order", "3", "--input", "FIX:y",
                   "--input", "TIP:y", "--modal-damping", "0.01", "--band", "10:2000", "-o", str(tmp_path / "k3.h5"),
                   "--json")
    body = read_body(tmp_path / "k3.h5")
    f_body = np.sqrt(sla.eigh(body.K, body.M, eigvals_only=True)) / (2 * np.pi)
    assert out["spurious_resonances_hz"] == pytest.approx([f_body[1]], rel=1e-6)
    assert f_body[1] == pytest.approx(1760.9, rel=1e-4)
    assert out["max_rel_error_at_spurious_resonance"] and out["max_rel_error_hz"] == pytest.approx(1765.2, rel=1e-3)
    assert any(n.startswith("spurious resonance: the body resonates at 1761 Hz") for n in out["notes"])
    assert main(["info", str(tmp_path / "k3.h5")]) == 0
    assert "(spurious resonance)" in capsys.readouterr().out
    assert main(["reduce", FREE, "--method", "krylov", "--points", points, "--order", "3", "--input", "FIX:y",
                 "--input", "TIP:y",
                 "--modal-damping", "0.01", "--band", "10:2000", "-o", str(tmp_path / "t.h5")]) == 0
    text = capsys.readouterr().out
    assert "1765 Hz SR" in text and "note: krylov r=3: spurious resonance" in text


def test_an_accurate_body_has_no_spurious_resonance(damped, full):
    red, res = reduce_and_judge(damped, "krylov", 16, make_ports(damped, ["TIP:y", "TIP:z"]), band=BAND, full=full)
    assert res["spurious_resonances_hz"] == [] and not res["max_rel_error_at_spurious_resonance"]
    assert res["band_error"] < 1e-12


@pytest.fixture(scope="module")
def plate():
    m0 = plate_structure(n=6, lower="mass")
    return m0, couple(m0, ["HOLE@rbe2"]).model


def _eigsh_elastic_hz(model, k):
    """SciPy's shift-invert Lanczos below the first elastic mode (about 250 Hz): an eigen solve of its own."""
    lam = spla.eigsh(model.K.tocsc(), k=k + 6, M=model.M.tocsc(), sigma=-(2 * np.pi * 50.0) ** 2, tol=1e-14,
                     return_eigenvectors=False)
    return np.sqrt(np.sort(lam)[6:]) / (2 * np.pi)


def test_rbe2_at_the_hole_stiffens_the_plate_structure(plate):
    """An RBE2 makes the hole's wall move rigidly: the coupled model's displacements are a subspace of the
    FE model's, so each elastic frequency rises (Rayleigh-Ritz). Measured at n=6: 247.89 -> 247.91 Hz
    (first), 857.97 -> 891.61 Hz (fourth, +3.9 %); checked against a shift-invert eigsh of each model."""
    m0, cm = plate
    rec = coupling_frequencies(m0, cm, ["HOLE@rbe2"])
    np.testing.assert_allclose(rec["uncoupled_hz"], _eigsh_elastic_hz(m0, 6), rtol=1e-8)
    np.testing.assert_allclose(rec["coupled_hz"], _eigsh_elastic_hz(cm, 6), rtol=1e-8)
    assert np.all(np.array(rec["coupled_hz"]) >= np.array(rec["uncoupled_hz"]) * (1 - 1e-10))
    assert rec["rel_change"][3] == pytest.approx(891.61 / 857.97 - 1, abs=2e-4)


@pytest.mark.slow
def test_coupling_frequencies_in_info_reduce_and_the_body(capsys, tmp_path, free):
    """``info MODEL --interface``, ``reduce`` (JSON, text, the .h5) and ``info BODY.h5`` give the coupled and
    the uncoupled frequencies; coupled ones from the error grid's pre-pass equal the eigen solve's."""
    args = ["--interface", "FIX@rbe2", "--interface", "TIP@rbe2"]
    info = run_json(capsys, "info", FREE, *args, "--json")
    rec = info["coupling_frequencies"]
    coupled = couple(free, ["FIX@rbe2", "TIP@rbe2"]).model
    np.testing.assert_allclose(rec["uncoupled_hz"], _elastic_hz(free, 6), rtol=1e-8)
    np.testing.assert_allclose(rec["coupled_hz"], _elastic_hz(coupled, 6), rtol=1e-8)
    assert info["n_dof"] == coupled.n_dof and rec["coupled_hz"][5] > rec["uncoupled_hz"][5]
    out = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--order", "16", *args, "--input",
                   "TIP@rbe2:y", "--modal-damping", "0.01", "--band", "10:3000", "-o", tmp_path / "cb.h5", "--json")
    np.testing.assert_allclose(out["coupling_frequencies"]["coupled_hz"], rec["coupled_hz"], rtol=1e-8)
    np.testing.assert_allclose(out["coupling_frequencies"]["uncoupled_hz"], rec["uncoupled_hz"], rtol=1e-10)
    body = run_json(capsys, "info", str(tmp_path / "cb.h5"), "--json")
    assert body["coupling_frequencies"] == out["coupling_frequencies"]
    assert main(["info", str(tmp_path / "cb.h5")]) == 0
    assert "RBE2 at FIX, RBE2 at TIP changes the lowest elastic frequencies by" in capsys.readouterr().out


@pytest.mark.slow
def test_report_plots_judge_what_the_table_judges(free, tmp_path):
    """A mixed report (a body without rigid motion, one with it): each body's |H| reference and time-error
    curve are those of its table row. Before, the time plot compared every body with the whole response
    when not all were elastic: the Craig-Bampton curve rose to 1.0 while its row said 3e-2."""
    from flexmor.report.contents import build_report
    from flexmor.report.html import render_html

    model = apply_damping(couple(free, ["FIX@rbe2", "TIP@rbe2"]).model, modal_damping=0.01, band=BAND)
    ports = make_ports(model, ["TIP@rbe2:y"])
    full = FullResponse(model, ports, BAND, cache=False)
    cb = reduce(model, "craig-bampton", 16, ports, interface=["FIX@rbe2", "TIP@rbe2"])
    kr = reduce(model, "krylov", 12, ports, band=BAND, rigid="include")
    for red in (cb, kr):
        red.couplings = ["FIX@rbe2", "TIP@rbe2"]
    rep = build_report(model, ports, [cb, kr], band=BAND, full=full, view3d=False, n_modes=4)
    data = rep.plot_data
    cb_row, kr_row = rep.rows
    assert data["reference_of"][cb_row["label"]] == "full model with RBE2 at FIX, RBE2 at TIP, elastic part"
    np.testing.assert_array_equal(data["frf_references"][data["reference_of"][cb_row["label"]]], full.H_elastic)
    np.testing.assert_array_equal(data["frf_references"][data["reference_of"][kr_row["label"]]], full.H)
    for row in rep.rows:
        assert np.max(data["time_error"][row["label"]]) == pytest.approx(row["time_max_error"], rel=1e-12)
    assert cb_row["time_max_error"] < 0.1 and cb_row["judged"] == JUDGED_ELASTIC
    # the H2 error against the same elastic part (measured 5.4e-2; against the whole response it was 1.0)
    assert cb_row["h2_error"] < 0.1 and kr_row["h2_error"] is None
    assert kr_row["judged"] == JUDGED_RIGID
    page = render_html(rep)
    assert "judged against the <b>full model with RBE2 at FIX, RBE2 at TIP</b>" in page
    assert "full [Hz]" not in page and "full model with RBE2 at FIX, RBE2 at TIP [Hz]" in page


def test_a_coupling_that_changes_nothing_shows_no_negative_zero():
    """A rigid coupling of nodes that move together changes the frequencies by round-off of either sign:
    the tables show +0.000 %, not -0.000 %."""
    from flexmor.checks import signed_percent
    from flexmor.cli.info import coupling_lines

    assert [signed_percent(x, 3) for x in (-5.7e-14, 0.0, -4.9e-6, 3.4e-3)] == ["+0.000", "+0.000", "+0.000", "+0.340"]
    assert signed_percent(-6e-6, 3) == "-0.001" and signed_percent(-1.2e-4, 2) == "-0.01"
    rec = {"couplings": [], "uncoupled_hz": [100.0, 200.0], "coupled_hz": [100.0, 200.0], "rel_change": [-5.7e-14, 0.0]}
    lines = coupling_lines(rec)
    assert "by +0.000 to +0.000 %" in lines[0] and lines[2].endswith("+0.000 %") and "-0.0" not in "".join(lines)


def test_a_spurious_pair_is_named_once():
    """The demo's craig-bampton 8 on the square cantilever: its bending pair at 1429 Hz (y and z) is spurious;
    the note named it twice ('1429 Hz (...); 1429 Hz (...)')."""
    from flexmor.models import cantilever

    model = cantilever(n=4).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    full = FullResponse(model, ports, (10.0, 3000.0))
    err = full.evaluate(reduce(model, "craig-bampton", 8, ports, interface=["TIP_CENTER"]))
    f = np.asarray(err.spurious_resonances_hz)
    assert f.size == 3 and abs(f[1] / f[0] - 1) < 1e-6 and abs(f[0] - 1429) < 1  # the pair, and one more
    note = next(n for n in err.notes if n.startswith("spurious resonances"))
    assert note.count("1429 Hz") == 1 and "1429 Hz (2 modes) (nearest full resonances" in note


@pytest.mark.parametrize("path", ["dense", "direct"])
def test_the_elastic_reference_of_a_free_body_holds_at_low_frequency(free, path):
    """The elastic part of H from the inputs' and the outputs' projections: against the modal sum of the elastic
    modes, to 1e-9 from 0.001 Hz (below the spurious poles the rounding gives the rigid-body modes, near 0.002
    Hz) to 100 Hz. With the inputs' projection alone it was off by 0.53 at 0.001 Hz and 8e-7 at 1 Hz (1/f²), and
    an exact body (krylov 12, input FIX:y) was reported with hinf_error 0.85 over 0.001-100 Hz."""
    ports = make_ports(free, ["FIX:y"])
    full = FullResponse(free, ports, (0.001, 100.0), path=path, cache=False)
    lam, phi = sla.eigh(free.K.toarray(), free.M.toarray())
    lam, phi = lam[6:], phi[:, 6:]
    cb = (ports.C @ phi) * (phi.T @ ports.B.toarray()).T
    exact = np.array([np.sum(cb / (lam - (2 * np.pi * f) ** 2)) for f in full.freqs])
    assert np.max(np.abs(full.H_elastic[:, 0, 0] - exact) / np.abs(exact)) < 1e-9
    err = full.evaluate(reduce(free, "krylov", 12, ports, band=(0.001, 100.0)))
    assert err.judged == JUDGED_ELASTIC and err.hinf_error < 1e-9 and err.band_error < 1e-18


@pytest.mark.parametrize("damping", [None, (5.0, 2e-6)])
def test_the_whole_frf_of_a_free_body_is_exact_down_to_zero(free, damping):
    """A free body's H as its rigid part (exact: C Φ (s² + s ΦᵀDΦ)⁻¹ Φᵀ B) plus its projected elastic part, on
    both paths: against the modal sum with the rigid-body eigenvalues at 0, to 1e-10 from 1e-9 Hz to 1 kHz
    (solved whole, undamped: relative error 1.0 at 1e-9 Hz, 0.55 at 0.001 Hz, 4.4e-7 at 1 Hz; System.frf gave
    455 m/N at 1e-9 and 1e-6 Hz for -1.28e9 at 1e-6); at 0 Hz it is infinite."""
    from flexmor.dynamics.dense_frf import DenseResolvent
    from flexmor.dynamics.frf import frf_full

    model = free if damping is None else free.with_rayleigh(*damping)
    ports = make_ports(model, ["FIX:y", "TIP:z"])
    B, C = ports.B.toarray(), ports.C.toarray()
    lam, phi = sla.eigh(model.K.toarray(), model.M.toarray())
    lam[:6] = 0.0
    a, b = damping or (0.0, 0.0)
    f = np.array([1e-9, 1e-6, 1e-3, 1.0, 100.0, 1000.0])
    w = 2 * np.pi * f
    cb = np.einsum("pk,km->kpm", C @ phi, phi.T @ B)
    exact = np.array([np.einsum("kpm,k->pm", cb, 1 / (lam - x * x + 1j * x * (a + b * lam))) for x in w])
    for H in (frf_full(model, ports, f), DenseResolvent(model.K, model.M, model.D, damping=model.damping).frf(w, B, C)):
        rel = np.linalg.norm((H - exact).reshape(f.size, -1), axis=1) / np.linalg.norm(exact.reshape(f.size, -1),
                                                                                      axis=1)
        assert rel.max() < 1e-10, rel
    assert np.all(np.isinf(frf_full(model, ports, [0.0])))


def test_a_mode_the_ports_do_not_see_is_noted():
    """A basis built to hold a mode the ports cannot see: on the 270-DOF C3D8 beam (square section,
    clamped), the pure y-bending members of the first two bending pairs plus one pure z-bending vector
    ``z1 + c z2`` whose Rayleigh quotient lies at ``sqrt(f1 f2)`` (246.7 Hz), between the full
    resonances. The input and output TIP_CENTER:y do not see z-bending (zero there by symmetry), so the
    body has a resonance in the band that is no spurious resonance at its ports: a note names it (an
    MBS body loaded in z would carry it). Without that vector there is no such note."""
    from flexmor.linalg import eigenmodes
    from flexmor.models import cantilever
    from flexmor.projection import project

    model = cantilever(2, divisions=(10, 2, 2))
    ports = make_ports(model, ["TIP_CENTER:y"])
    lam, phi = eigenmodes(model.K, model.M, 6)
    f = np.sqrt(lam) / (2 * np.pi)
    assert abs(f[1] / f[0] - 1) < 1e-8 and abs(f[3] / f[2] - 1) < 1e-8  # two bending pairs (y, z)
    tip_y = (ports.C @ phi).ravel()
    tip_z = (make_ports(model, ["TIP_CENTER:z"]).C @ phi).ravel()

    def pure(i, c):  # the member of the pair (i, i + 1) with no tip displacement c, mass-normalized
        v = c[i + 1] * phi[:, i] - c[i] * phi[:, i + 1]
        return v / np.sqrt(v @ (model.M @ v))

    (y1, z1), (y2, z2) = [(pure(i, tip_z), pure(i, tip_y)) for i in (0, 2)]
    w = 2 * np.pi * np.array([f[0], f[2], np.sqrt(f[0] * f[2])])
    v = z1 + np.sqrt((w[2] ** 2 - w[0] ** 2) / (w[1] ** 2 - w[2] ** 2)) * z2  # Rayleigh quotient w[2]^2
    f_v = np.sqrt((v @ (model.K @ v)) / (v @ (model.M @ v))) / (2 * np.pi)
    assert f_v == pytest.approx(np.sqrt(f[0] * f[2]), rel=1e-8)
    full = FullResponse(model, ports, (1.0, 1000.0), cache=False)
    assert np.min(np.abs(full.resonances - f_v) / full.resonances) > 0.5  # far from every full mode

    err = full.evaluate(project(model, np.column_stack([y1, y2, v]), ports))
    assert not err.spurious_resonances_hz and err.band_error < 1e-5  # the ports see the two y modes only
    note = next(n for n in err.notes if n.startswith("the body has a mode at "))
    assert float(note.split(" at ")[1].split(" Hz")[0]) == pytest.approx(f_v, rel=1e-3)  # printed to 4 digits
    assert "its ports hardly see it, loads elsewhere (the frame's inertia, other joints) would" in note
    without = full.evaluate(project(model, np.column_stack([y1, y2]), ports))
    assert not [n for n in without.notes if n.startswith("the body has")]

