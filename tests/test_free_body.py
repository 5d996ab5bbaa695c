"""Free bodies for the floating frame: no rigid motion in the elastic coordinates, whatever the method.

Regression tests of the failures of a free body on its way to an MBS code: Craig-Bampton gave a
singular body, ``krylov --rigid exclude`` a body with modes at 44 and 73 Hz below the first
elastic one (620.7 Hz), clamped bodies exported without their supported nodes' mass.
"""

import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)
from helpers import CLAMPED, FREE, run_json

from flexmor.basis import Basis
from flexmor.cli import main
from flexmor.couplings import couple
from flexmor.errors import FlexmorWarning, ModelError
from flexmor.io.exudyn import exudyn_data, write_exudyn
from flexmor.io.sid import read_sid, write_sid
from flexmor.linalg.eigen import eigenmodes, frequencies_hz
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.projection import project
from flexmor.reduction import reduce
from flexmor.reduction.free_body import check_body
from flexmor.rigid import rigid_body_modes, rigid_residual
from flexmor.workflow import apply_damping, reduce_and_judge

IFACES = ["FIX@rbe2", "TIP@rbe2"]


def elastic_hz(model, k):
    """The k lowest elastic eigenfrequencies of the full model (rigid-body modes skipped)."""
    lam, _ = eigenmodes(model.K, model.M, k + 6)
    return frequencies_hz(lam[6:])


def mass_properties(model):
    """Mass, centre of mass and inertia tensor about the origin, from M and the rigid fields."""
    d, xyz = model.dofs[:, 1], model.node_xyz(model.dofs[:, 0])
    T = np.zeros((model.n_dof, 3))
    R = np.zeros((model.n_dof, 3))
    for a in range(3):
        T[d == a + 1, a] = 1.0
        R[d == a + 4, a] = 1.0
        for j in range(3):
            R[d == j + 1, a] = np.cross(np.eye(3)[a], xyz[d == j + 1])[:, j]
    mass = (T.T @ (model.M @ T))[0, 0]
    com = np.array([T[:, a] @ (model.M @ (xyz[:, a] * (d == a + 1))) for a in range(3)]) / mass
    return mass, com, R.T @ (model.M @ R)


@pytest.fixture(scope="module")
def symmetric_bar():
    """A cantilever of square section (40 x 4 x 4 hexahedra, 3,000 DOF), Rayleigh damped."""
    from flexmor.damping import Rayleigh

    return cantilever(4).with_damping(Rayleigh(1.0, 1e-6))


@pytest.fixture(scope="module")
def coupled(free):
    return couple(free, IFACES).model


@pytest.fixture(scope="module")
def solid():
    return cantilever(divisions=(12, 2, 2), clamped=False)


def _no_zero_mode(red, f1):
    lam = sla.eigh(red.K, red.M, eigvals_only=True)
    assert lam[0] > 0.99 * (2 * np.pi * f1) ** 2  # no zero eigenvalue in (Me, Ke): Ke non-singular


@pytest.mark.parametrize("name", ["beam8", "solid"])
def test_craig_bampton_free_body_upper_bounds_converging(name, coupled, solid):
    model = coupled if name == "beam8" else couple(solid, ["FIX@rbe2", "TIP@rbe2"]).model
    ports = make_ports(model, ["TIP@rbe2:y"])
    ref = elastic_hz(model, 4)
    errs = []
    for r in (16, 24, 36):
        red = reduce(model, "craig-bampton", r, ports, interface=IFACES)
        # inertia-relief attachment modes in place of the constraint modes: nothing rigid to drop
        assert red.order == r or (red.order == r + 1 and "same frequency" in red.order_note)  # a whole pair kept
        assert red.info["n_rigid_dropped"] == 0 and red.info["attachment"] == "inertia-relief"
        assert rigid_residual(model, red.V) < 1e-12
        f = red.frequencies_hz()[:4]
        assert np.all(f >= ref * (1 - 1e-9))  # Rayleigh-Ritz: upper bounds of the free-free ones
        errs.append(np.max(f / ref - 1))
        _no_zero_mode(red, ref[0])
    assert errs[0] > errs[1] > errs[2] and errs[2] < 1e-3, errs


def test_craig_bampton_rigid_include_keeps_the_classic_basis(coupled):
    red = reduce(coupled, "craig-bampton", 20, make_ports(coupled, ["TIP@rbe2:y"]), interface=IFACES,
                    rigid="include")
    assert np.sum(red.frequencies_hz() < 1.0) == 6 and red.order == 20


def test_krylov_rigid_exclude_matches_in_band_modes(free, free_ref):
    model = apply_damping(free, modal_damping=0.01, band=(10.0, 2000.0))
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexmorWarning)  # no warning about this body ...
        warnings.filterwarnings("ignore", ".*6 rigid-body modes", FlexmorWarning)  # ... but the model's note
        red, res = reduce_and_judge(model, "krylov", 24, ports, band=(10.0, 2000.0), rigid="exclude")
    assert res["warnings"] == []
    assert rigid_residual(model, red.V) < 1e-12
    f = red.frequencies_hz()
    ref = elastic_hz(model, 2)
    np.testing.assert_allclose(f[:2], ref, rtol=1e-6)  # the in-band bending pair, 620.67 Hz
    np.testing.assert_allclose(f[:2], free_ref[6:8], rtol=1e-5)  # CalculiX's
    _no_zero_mode(red, ref[0])
    assert res["band_error"] < 1e-8  # the elastic part of H (the frame carries the rigid part)


def test_krylov_rigid_exclude_cli(capsys, tmp_path):
    """The issue's command: modes at 44 and 73 Hz and band_error 1.14, written without a warning."""
    out = run_json(capsys, "reduce", FREE, "--method", "krylov", "--order", "24", "--input", "TIP:y", "--input",
                   "TIP:z", "--modal-damping", "0.01", "--band", "10:2000", "--rigid", "exclude",
                   "-o", str(tmp_path / "k.h5"), "--json")
    assert out["frequencies_hz"][0] == pytest.approx(620.6715, rel=1e-5)
    assert out["band_error"] < 1e-8 and out["warnings"] == []
    assert out["info"]["n_rigid_excluded"] == 6 and out["info"]["rigid_residual"] < 1e-12
    assert out["info"]["inertia_loads"] == "auto" and out["info"]["n_inertia_loads"] == 0  # the CLI default


def test_krylov_rigid_include_has_no_spurious_mode(free):
    """``rigid='include'`` (no longer the default: a free body's default basis excludes rigid motion)."""
    model = apply_damping(free, modal_damping=0.01, band=(10.0, 2000.0))
    red = reduce(model, "krylov", 24, make_ports(model, ["TIP:y", "TIP:z"]), band=(10.0, 2000.0),
                    rigid="include")
    f = red.frequencies_hz()
    n = red.info["n_rigid_included"]
    assert n == 4 and np.all(f[:n] < 1e-2) and f[n] == pytest.approx(620.6715, rel=1e-5)  # once a 290 Hz mode


def test_craig_bampton_free_body_cli_and_exports(capsys, tmp_path, coupled):
    """The issue's command gave 0 0 0.0005 ... 621.1 Hz and a singular SID body."""
    body = tmp_path / "cb.h5"
    out = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--order", "20", "--interface", "FIX@rbe2",
                   "--interface", "TIP@rbe2", "--input", "TIP@rbe2:y", "--rayleigh", "0:1e-6", "-o", str(body),
                   "--json")
    assert out["order"] == 20 and out["frequencies_hz"][0] > 620.0
    mass, com, J = mass_properties(coupled)
    assert mass == pytest.approx(78.5, rel=1e-12)
    sid_path = tmp_path / "cb.SID_FEM"
    assert main(["export", str(body), "--model", FREE, "--format", "sid", "-o", str(sid_path)]) == 0
    sid = read_sid(sid_path)
    assert sid.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(sid.objects["mdCM"].m0[:, 0], mass * com, rtol=1e-10, atol=1e-12 * mass)
    Jv = sid.objects["J"].m0[:, 0]
    np.testing.assert_allclose(Jv, [J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]], rtol=1e-10,
                               atol=1e-12 * np.abs(J).max())
    assert np.all(sid.frequencies_hz() > 620.0)  # no zero eigenvalue in (Me, Ke)
    npz = tmp_path / "cb.npz"
    assert main(["export", str(body), "--model", FREE, "--format", "exudyn", "-o", str(npz)]) == 0
    with np.load(npz) as z:
        assert float(z["totalMass"]) == pytest.approx(mass, rel=1e-12)
        np.testing.assert_allclose(z["chiU"], com, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(z["inertiaLocal"], J, rtol=1e-10, atol=1e-12 * np.abs(J).max())
        assert sla.eigh(z["stiffnessMatrixReduced"], z["massMatrixReduced"], eigvals_only=True)[0] > 1e6


def test_krylov_free_solid_exports_exact_mass_properties(solid, tmp_path):
    model = solid.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP_CENTER:y", "TIP_CENTER:z"])
    red = reduce(model, "krylov", 16, ports, band=(10.0, 3000.0), rigid="exclude")
    ref = elastic_hz(model, 2)
    np.testing.assert_allclose(red.frequencies_hz()[:2], ref, rtol=1e-6)
    mass, com, J = mass_properties(model)
    data = exudyn_data(red, model)
    assert data["totalMass"] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(data["chiU"], com, rtol=1e-10)
    np.testing.assert_allclose(data["inertiaLocal"], J, rtol=1e-10, atol=1e-12 * np.abs(J).max())
    write_sid(red, tmp_path / "k.SID_FEM", model=model)
    assert read_sid(tmp_path / "k.SID_FEM").mass == pytest.approx(mass, rel=1e-12)


def test_spurious_mode_and_bad_band_error_warn_in_one_line(free):
    ports = make_ports(free, ["TIP:y"])
    lam, phi = eigenmodes(free.K, free.M, 10)
    mixed = phi[:, :1] + 1e-3 * phi[:, 6:7]  # rigid motion with a little elastic content
    red = project(free, Basis(np.hstack([mixed, phi[:, 7:10]]), "test"), ports)
    f1 = frequencies_hz(lam[6:7])[0]
    with pytest.warns(FlexmorWarning) as rec:
        msgs = check_body(free, red, f1_hz=f1, band_error=1.5)
    assert len(msgs) == 2 and [str(w.message) for w in rec] == msgs
    assert "below the full model's first elastic frequency" in msgs[0] and "band_error 1.5 > 1" in msgs[1]
    assert f"at {frequencies_hz(red.eigenvalues()[:1])[0]:.4g} Hz" in msgs[0] and "rigid='exclude'" in msgs[0]
    assert all("\n" not in m for m in msgs)
    clean = project(free, Basis(phi[:, 6:10], "modal"), ports)
    assert check_body(free, clean, f1_hz=f1, band_error=0.5) == []


def test_rigid_body_modes_are_exact(coupled):
    phi = rigid_body_modes(coupled)
    assert phi.shape[1] == 6
    np.testing.assert_allclose(phi.T @ (coupled.M @ phi), np.eye(6), atol=1e-12)


def test_clamped_body_is_refused_for_ffrf_export(clamped, tmp_path, capsys):
    red = reduce(clamped, "modal", 4, make_ports(clamped, ["TIP:y"]))
    with pytest.raises(ModelError, match="supported.*mass"):
        write_exudyn(red, tmp_path / "c.npz", model=clamped)
    with pytest.raises(ModelError, match="pass allow_clamped for a body whose frame does not move"):
        write_sid(red, tmp_path / "c.SID_FEM", model=clamped)
    assert not (tmp_path / "c.npz").exists() and not (tmp_path / "c.SID_FEM").exists()
    from flexmor.io import write_body

    write_body(red, tmp_path / "c.h5")
    assert main(["export", str(tmp_path / "c.h5"), "--model", CLAMPED, "-o", str(tmp_path / "c.SID_FEM")]) == 2
    err = capsys.readouterr().err
    assert "supported (0 of 6 rigid-body modes)" in err and "Traceback" not in err
    assert main(["export", str(tmp_path / "c.h5"), "--model", CLAMPED, "-o", str(tmp_path / "c.SID_FEM"),
                 "--allow-clamped"]) == 0


@pytest.mark.parametrize("method", ["cms-krylov", "cms-gramian"])
def test_cms_methods_on_a_free_body(method, coupled):
    model = coupled.with_rayleigh(0.0, 1e-6)
    # the free-free spectrum at order 24 with the input alone (the default also spends internal vectors on the
    # inertia loads of the body held at each of the two masters: first frequency 630.7 Hz, 1.6 % high, measured)
    red = reduce(model, method, 24, make_ports(model, ["TIP@rbe2:y"]), interface=IFACES, band=(10.0, 2000.0),
                    inertia_loads="off")
    ref = elastic_hz(model, 1)
    assert red.order == 12 - 6 + red.info["n_internal"] and red.info["n_rigid_dropped"] == 6
    assert red.order == 24 or method == "cms-gramian"  # (its Hankel rank may end the internal vectors)
    assert rigid_residual(model, red.V) < 1e-12
    assert ref[0] * (1 - 1e-9) <= red.frequencies_hz()[0] < 1.01 * ref[0]


def test_body_of_a_selection_exports_with_its_selection(capsys, tmp_path):
    """A body that uses --select carries its selections; export applies them (no --select there)."""
    ring = "RING=cylinder:0,0.05,0.05,1,0,0,0.05,1e-9,0.45,0.55"
    body = tmp_path / "ring.h5"
    out = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--order", "10", "--select", ring,
                   "--interface", "RING@rbe2", "--input", "RING@rbe2:y", "--no-error", "-o", str(body), "--json")
    # the 6 constraint modes of the single interface are pure rigid motion: its 6 inertia-relief modes replace them
    assert out["order"] == 10 and out["info"]["attachment"] == "inertia-relief" and out["frequencies_hz"][0] > 620.0
    sid_path = tmp_path / "ring.SID_FEM"
    assert main(["export", str(body), "--model", FREE, "-o", str(sid_path)]) == 0, capsys.readouterr().err
    sid = read_sid(sid_path)
    assert sid.mass == pytest.approx(78.5, rel=1e-12) and np.all(sid.frequencies_hz() > 620.0)
    npz = tmp_path / "ring.exudyn.npz"
    assert main(["export", str(body), "--model", FREE, "-o", str(npz)]) == 0, capsys.readouterr().err
    with np.load(npz) as z:
        assert float(z["totalMass"]) == pytest.approx(78.5, rel=1e-12)


def _quasi_static_error(model, red, load, C):
    """Relative error at the outputs C of the reduced body's static response to ``load``."""
    from flexmor.linalg import factorize

    u = factorize(model.K.tocsc()).solve(load)
    ur = red.V @ np.linalg.solve(red.K, red.V.T @ load)
    return np.linalg.norm(C @ (ur - u)) / np.linalg.norm(C @ u)


@pytest.mark.slow
@pytest.mark.parametrize("method, off_min, on_max", [("krylov", 0.5, 1e-6), ("fw-sobt", 0.5, 0.05)])
def test_inertia_loads_make_a_supported_body_see_its_frame_acceleration(clamped, method, off_min, on_max):
    """A clamped beam loaded at the tip in y, its support accelerating along the axis (x):
    without the inertia-load inputs the body cannot stretch; with them the quasi-static
    axial response of the tip matches the full model."""
    from flexmor.rigid import rigid_motions

    ports = make_ports(clamped, ["TIP:y"])
    C = make_ports(clamped, ["TIP:x"]).C
    load = clamped.M @ rigid_motions(clamped)[:, 0]  # uniform acceleration along x
    off = reduce(clamped, method, 12, ports, band=(10.0, 3000.0), inertia_loads="off")
    on = reduce(clamped, method, 12, ports, band=(10.0, 3000.0), inertia_loads="on")
    assert off.info["n_inertia_loads"] == 0 and on.info["n_inertia_loads"] == 6
    assert on.input_names == ["TIP:y"] and on.B.shape[1] == 1  # the body keeps the user's ports
    assert _quasi_static_error(clamped, off, load, C) > off_min
    assert _quasi_static_error(clamped, on, load, C) < on_max


def test_a_supported_symmetric_bar_carries_the_bending_its_ports_do_not_see(symmetric_bar):
    """A clamped bar of square section, its one port at the tip in y: by symmetry the ports do not see
    its z-bending (the same frequencies as the y-bending). Its support accelerating along z bends it in z.
    With the default (the inertia loads on a supported body too) the body's tip z response to that acceleration
    follows the full model's over the band and converges with the order; its static record holds gravity z;
    ``off`` builds for the port alone."""
    from flexmor.rigid import rigid_motions

    model = symmetric_bar
    ports = make_ports(model, ["TIP:y"])
    Cz = make_ports(model, ["TIP:z"]).C.toarray().ravel()
    F = model.M @ rigid_motions(model)[:, 2]  # the support's unit acceleration along z
    hz = np.linspace(1.0, 2000.0, 41)
    s = 2j * np.pi * hz
    full = np.array([Cz @ sp.linalg.spsolve((model.K + x * model.D + x * x * model.M).tocsc(), F) for x in s])
    errors = []
    for order in (10, 20, 30):
        body = reduce(model, "krylov", order, ports, band=(1.0, 2000.0))
        assert body.info["inertia_loads"] == "auto" and body.info["n_inertia_loads"] == 6
        assert body.input_names == ["TIP:y"]  # the body keeps the user's ports
        zr, fr = body.V.T @ Cz, body.V.T @ F
        red = np.array([zr @ np.linalg.solve(body.K + x * body.D + x * x * body.M, fr) for x in s])
        errors.append(np.max(np.abs(red - full)) / np.max(np.abs(full)))
    assert errors[1] < 1e-5 and errors[2] < errors[1] < errors[0]
    assert reduce(model, "krylov", 10, ports, band=(1.0, 2000.0), inertia_loads="off").info["n_inertia_loads"] == 0
    _, rec = reduce_and_judge(model, "krylov", 20, ports, band=(1.0, 2000.0), cache=False)
    sag = {row["load"]: row for row in rec["static"]["loads"]}
    assert sag["gravity:z"]["field_error"] < 1e-6 and sag["gravity:y"]["output_error"] < 1e-6


def test_a_supported_body_built_for_its_ports_alone_is_told_of_the_frame_accelerations(symmetric_bar):
    """Built for its y port alone (``inertia_loads='off'``) the bar cannot stretch: its deflection under the
    frame's x acceleration is all wrong (measured 100 %), and the record's note says so and what adds them;
    with the inertia loads (the default) the note is gone. A method whose basis ignores the inputs is told of
    the residual vectors only."""
    ports = make_ports(symmetric_bar, ["TIP:y"])
    _, alone = reduce_and_judge(symmetric_bar, "krylov", 10, ports, band=(1.0, 2000.0), cache=False,
                                inertia_loads="off")
    assert alone["static"]["frame_error"] > 0.1
    assert any(n.startswith("frame accelerations:") and "--inertia-loads on" in n for n in alone["notes"])
    _, loaded = reduce_and_judge(symmetric_bar, "krylov", 20, ports, band=(1.0, 2000.0), cache=False)
    assert loaded["static"]["frame_error"] < 1e-6
    assert not any(n.startswith("frame accelerations:") for n in loaded["notes"])
    from flexmor.analysis.mounted import static_note

    modal = reduce(symmetric_bar, "modal", 6, ports)
    assert modal.info["inertia_loads"] is None and modal.info["n_inertia_loads"] == 0
    note = static_note({"static_error": None, "frame_error": 0.5}, None, inertia_loads=(None, 0))
    assert note.startswith("frame accelerations:") and "--residual-vectors" in note and "--inertia-loads" not in note


def test_inertia_loads_have_no_elastic_part_on_a_free_body(free):
    """M R lies in M span(rigid modes): a uniform acceleration only moves a free body rigidly."""
    model = free.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    a = reduce(model, "krylov", 12, ports, band=(10.0, 2000.0), rigid="exclude", inertia_loads="auto")
    b = reduce(model, "krylov", 12, ports, band=(10.0, 2000.0), rigid="exclude", inertia_loads="off")
    assert a.info["inertia_loads"] == "auto" and a.info["n_inertia_loads"] == 0
    np.testing.assert_array_equal(a.V, b.V)


def test_a_body_with_rigid_motion_is_refused_at_export_unless_removed(free, tmp_path):
    """A basis with the rigid motion the ports excite (rigid='include') is not what the floating
    frame takes: export refuses it (the body written would have another order and error than the one
    judged); with remove_rigid the basis is made M-orthogonal to it (with a warning naming the orders)."""
    model = apply_damping(free, modal_damping=0.01, band=(10.0, 2000.0))
    red = reduce(model, "krylov", 16, make_ports(model, ["TIP:y", "TIP:z"]), band=(10.0, 2000.0),
                    rigid="include")
    assert red.info["n_rigid_included"] == 4 and red.frequencies_hz()[3] < 1.0
    with pytest.raises(ModelError, match=r"order 16 -> 12.*remove_rigid"):
        write_sid(red, tmp_path / "k.SID_FEM", model=model)
    assert not (tmp_path / "k.SID_FEM").exists()
    with pytest.warns(FlexmorWarning, match=r"order 16 -> 12"):
        write_sid(red, tmp_path / "k.SID_FEM", model=model, remove_rigid=True)
    sid = read_sid(tmp_path / "k.SID_FEM")
    np.testing.assert_allclose(sid.frequencies_hz()[:2], elastic_hz(model, 2), rtol=1e-6)
    assert sid.mass == pytest.approx(78.5, rel=1e-12)
    with pytest.raises(ModelError, match="rigid-body motion"):
        exudyn_data(red, model)
    with pytest.warns(FlexmorWarning, match="rigid-body motion"):
        data = exudyn_data(red, model, remove_rigid=True)
    assert data["massMatrixReduced"].shape == (12, 12)
    assert sla.eigh(data["stiffnessMatrixReduced"], data["massMatrixReduced"], eigvals_only=True)[0] > 1e6


@pytest.mark.parametrize("rigid, n_head", [("include", 4), ("exclude", 0)])
def test_pod_on_a_free_body_has_no_spurious_mode(free, rigid, n_head):
    """POD snapshots mixed rigid and elastic motion: modes at 147 and 307 Hz below the first
    elastic one (620.7 Hz). They are now snapshots of the flexible part, behind the rigid-body
    modes the inputs excite (include) or without them (exclude)."""
    model = apply_damping(free, modal_damping=0.01, band=(10.0, 2000.0))
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    red = reduce(model, "pod", 16, ports, band=(10.0, 2000.0), rigid=rigid)
    f = red.frequencies_hz()
    assert red.order == 16 and red.info["n_rigid_included"] == n_head
    assert np.all(f[:n_head] < 1e-2)
    np.testing.assert_allclose(f[n_head:n_head + 2], elastic_hz(model, 2), rtol=1e-6)


def test_irka_reduces_a_free_body_as_the_floating_frame_wants(free):
    """The free beam held by nothing, one input at TIP: irka on the flexible part. At its points it interpolates
    the elastic part of H (one input: tangential is full), its basis holds no rigid motion, its lowest frequency
    is an upper bound of the full model's first elastic one, and it beats krylov of the same order (measured:
    band_error 2.3e-6 against 5.5e-2 at order 8, 7.3e-7 against 9.2e-3 at 16)."""
    import scipy.sparse.linalg as spla

    from flexmor.analysis.compare import FullResponse
    from flexmor.rigid import m_project, rigid_body_modes, rigid_residual

    model = free.with_rayleigh(5.0, 2e-6)
    ports = make_ports(model, ["TIP:y"])
    full = FullResponse(model, ports, (10.0, 3000.0))
    red = reduce(model, "irka", 8, ports)
    assert red.info["converged"] and red.info["rigid"] == "exclude" and red.info["n_rigid_excluded"] == 6
    assert rigid_residual(model, red.V) < 1e-10
    phi = rigid_body_modes(model)
    B = ports.B.toarray()
    for s in map(complex, red.info["shifts_rad_s"]):
        x = m_project(model, phi, spla.spsolve((s * s * model.M + s * model.D + model.K).tocsc(), B.astype(complex)))
        h = (ports.C @ x).ravel()
        hr = (red.C @ np.linalg.solve(s * s * red.M + s * red.D + red.K, red.B)).ravel()
        assert np.abs(hr - h).max() <= 1e-8 * np.abs(h).max(), s
    assert red.frequencies_hz()[0] >= elastic_hz(model, 1)[0] * (1 - 1e-12)
    err = full.evaluate(red)
    assert err.judged.startswith("elastic part") and err.band_error < 1e-4
    assert err.band_error < 1e-2 * full.evaluate(reduce(model, "krylov", 8, ports)).band_error


def test_craig_bampton_free_body_is_exact_at_low_frequency(capsys, tmp_path):
    """One RBE2 interface on the free beam: the constraint modes are pure rigid motion; without
    attachment modes the body missed the inertia-relief deformation (band_error 1.95e-3, first
    frequency 621.06 Hz). With them: measured band_error 3.9e-10 and 620.68 Hz (full 620.67)."""
    out = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--order", "12", "--interface", "TIP@rbe2",
                   "--input", "TIP@rbe2:y", "--modal-damping", "0.01", "-o", str(tmp_path / "cb.h5"), "--json")
    assert out["band_error"] < 1e-8 and out["frequencies_hz"][0] == pytest.approx(620.67, rel=2e-5)


def test_report_judges_a_free_body_on_its_elastic_time_response(capsys, tmp_path):
    """The time responses of the full free beam include its rigid motion (a step force accelerates it
    away); a body without rigid motion was 'wrong' by 99.8 %. It is now compared with the elastic
    response (inputs made orthogonal to the rigid-body modes): measured 3.0e-2 for CB 20 (step)."""
    body = tmp_path / "cb.h5"
    run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--order", "20", "--interface", "FIX@rbe2",
             "--interface", "TIP@rbe2", "--input", "TIP@rbe2:y", "--modal-damping", "0.01", "-o", str(body), "--json")
    out = run_json(capsys, "report", FREE, str(body), "-o", str(tmp_path / "r.html"), "--json")
    assert out["results"][0]["time_max_error"] < 0.1
    assert any("elastic response" in n for n in out["notes"])
