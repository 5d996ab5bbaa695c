"""Interfaces reach the MBS code: a body reduced with an RBE2/RBE3 coupling is exported with its master
as a 6-DOF node (one id everywhere) and its basis expanded through the coupling to every FE node, the
slaves included, so that the body mounted by its interface in Exudyn deflects like the FE model
supported the same way.

The free CalculiX beam (1 x 0.1 x 0.1 m, 99 nodes) with ``FIX@rbe2`` on its face x = 0: clamped at
the master, it is the clamped beam that CalculiX exported itself (``beam8_clamped_mat``), which is
the independent reference of the mounted tests.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spl
from helpers import CLAMPED, FREE

from flexmor.cli import main
from flexmor.couplings import couple
from flexmor.errors import ModelError
from flexmor.expansion import expand_body
from flexmor.io import read
from flexmor.io.exudyn import exudyn_data, write_exudyn
from flexmor.io.sid import read_sid, write_sid
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.workflow import apply_damping

SPEC = "FIX@rbe2"


@pytest.fixture(scope="module")
def beam():
    """(model as read, clamped CalculiX model, coupled model, Craig-Bampton body of order 16 with the
    coupling, krylov body of order 16 for forces at the master and the tip)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        free = read(FREE)
        clamped = read(CLAMPED)
    c = couple(free, [SPEC])
    mc = apply_damping(c.model, modal_damping=0.01, band=(10.0, 3000.0))
    bodies = {}
    for method, opts, ins in (("craig-bampton", {"interface": [SPEC]}, ["TIP:y"]),
                              ("krylov", {"rigid": "exclude", "band": (10.0, 3000.0)},
                               [f"{SPEC}:y", f"{SPEC}:z", "TIP:y", "TIP:z"])):
        red = reduce(mc, method, 16, make_ports(mc, ins), **opts)
        red.couplings = [SPEC]
        bodies[method] = red
    return free, clamped, c, bodies


def _master_rows(c, red):
    mid = c.masters["FIX@RBE2"]
    idx = [int(np.flatnonzero((c.model.dofs[:, 0] == mid) & (c.model.dofs[:, 1] == d))[0]) for d in range(1, 7)]
    return mid, red.V[idx]


def test_the_body_records_its_master_node(beam):
    free, _, c, bodies = beam
    (m,) = bodies["craig-bampton"].info["masters"]
    assert m["id"] == c.masters["FIX@RBE2"] == int(free.node_ids.max()) + 1
    assert m["kind"] == "rbe2" and m["n_slaves"] == free.node_sets["FIX"].size == 9
    np.testing.assert_allclose(m["xyz"], [0.0, 0.05, 0.05], atol=1e-12)


def test_sid_frame_node_is_the_master_with_its_rotations(beam, tmp_path):
    """The SID frame node of the interface is the coupling's master (same id), its phi and psi the
    master's translations and rotations in the body's coordinates."""
    free, _, c, bodies = beam
    red = bodies["craig-bampton"]
    write_sid(red, tmp_path / "cb.SID_FEM", model=free)
    sid = read_sid(tmp_path / "cb.SID_FEM")
    mid, rows = _master_rows(c, red)
    node = {n.id: n for n in sid.nodes}[mid]
    scale = np.abs(rows).max()
    np.testing.assert_allclose(node.phi.m0, rows[:3], rtol=0, atol=1e-14 * scale)
    np.testing.assert_allclose(node.psi.m0, rows[3:], rtol=0, atol=1e-14 * scale)
    assert np.abs(rows[3:]).max() > 0.1 * np.abs(rows[:3]).max()  # the constraint modes rotate the master
    assert f"{mid}=FIX@RBE2" in (tmp_path / "cb.SID_FEM").read_text().splitlines()[0]


def test_the_slaves_move_rigidly_with_the_master(beam):
    """Exudyn's mesh: the nine FIX nodes carry ``t + theta x (x - x_m)`` of the master (RBE2), the
    master is a mesh node of its own with its id and no mass; the mass properties stay the beam's."""
    free, _, c, bodies = beam
    red = bodies["krylov"]
    data = exudyn_data(red, free)
    mid, rows = _master_rows(c, red)
    ids = list(data["nodeIds"])
    assert ids[-1] == mid and data["interfaceNames"].tolist() == ["FIX@RBE2"]
    xm = np.array([0.0, 0.05, 0.05])
    Psi = data["modeBasis"].reshape(-1, 3, red.order)
    for k in free.node_sets["FIX"]:
        i = ids.index(int(k))
        r = free.node_xyz([int(k)])[0] - xm
        expected = rows[:3] + np.cross(rows[3:].T, r).T
        np.testing.assert_allclose(Psi[i], expected, rtol=0, atol=1e-13 * np.abs(rows).max())
    np.testing.assert_allclose(Psi[ids.index(mid)], rows[:3], rtol=0, atol=0)
    assert data["totalMass"] == pytest.approx(78.5, rel=1e-12)
    assert sorted(data["interfaceSlaveNodes"].tolist()) == sorted(ids.index(int(k)) for k in free.node_sets["FIX"])


def test_export_refuses_the_coupled_model_and_another_model(beam):
    free, clamped, c, bodies = beam
    with pytest.raises(ModelError, match="coupled model.*as read"):
        expand_body(c.model, bodies["krylov"])
    with pytest.raises(ModelError, match="reduced from a model with"):
        expand_body(dataclasses.replace(free, K=free.K * 2), bodies["krylov"])


def _mounted_tip_z(red, model, via_file=None):
    """Tip deflection (m, z) of ``red`` in Exudyn, held at its interface by a rigid marker and a
    GenericJoint locking all six axes, under gravity -z (static solve); ``model`` as read, or its file."""
    exu = pytest.importorskip("exudyn")
    import exudyn.itemInterface as eii

    from flexmor.io.exudyn import add_marker, add_npz_to_exudyn, add_to_exudyn

    mbs = exu.SystemContainer().AddSystem()
    if via_file is None:
        body = add_to_exudyn(mbs, red, model, gravity=[0.0, 0.0, -9.81])
    else:
        body = add_npz_to_exudyn(mbs, via_file, gravity=[0.0, 0.0, -9.81])
    model = body.get("model", model)  # add_to_exudyn takes the file too, and records the model it read
    held = add_marker(mbs, body, None if via_file is None else model, SPEC)
    ground = mbs.AddMarker(eii.MarkerBodyRigid(bodyNumber=mbs.AddObject(eii.ObjectGround()),
                                               localPosition=[0.0, 0.05, 0.05]))
    mbs.AddObject(eii.GenericJoint(markerNumbers=[ground, held], constrainedAxes=[1] * 6))
    tip = add_marker(mbs, body, model, "TIP")
    sensor = mbs.AddSensor(eii.SensorMarker(markerNumber=tip, outputVariableType=exu.OutputVariableType.Position,
                                            storeInternal=True, writeToFile=False))
    mbs.Assemble()
    sc = exu.SimulationSettings()
    sc.solution.file.write = False
    sc.staticSolver.verboseMode = 0
    sc.staticSolver.newton.relativeTolerance = 1e-12
    sc.staticSolver.newton.absoluteTolerance = 1e-14
    mbs.SolveStatic(sc)
    x0 = model.node_xyz(model.node_sets["TIP"]).mean(axis=0)
    return float(mbs.GetSensorValues(sensor)[2] - x0[2]), mbs, body


def test_mounted_by_its_interface_it_sags_like_the_clamped_beam(beam, tmp_path):
    """Craig-Bampton 16 held at FIX@rbe2 in Exudyn under gravity: the tip sags -38.2 um like
    CalculiX's own clamped beam (sparse static solve; measured relative difference 6.3e-4, which is
    the clamped export's gravity load: ``M g`` of the clamped model lacks the mass coupling of the
    clamped nodes; against the free model held at its slaves the body sags to 4.5e-10,
    tests/test_mounted_mbs.py). Before the interface reached the export, the body was rigid
    there: 0 um. Through the .npz file (no unpickling) the same."""
    free, clamped, _, bodies = beam
    g = np.zeros(clamped.n_dof)
    g[clamped.dofs[:, 1] == 3] = -9.81
    u = spl.spsolve(clamped.K.tocsc(), clamped.M @ g)
    sel = np.isin(clamped.dofs[:, 0], clamped.node_sets["TIP"]) & (clamped.dofs[:, 1] == 3)
    full = u[sel].mean()
    assert full == pytest.approx(-3.822e-5, rel=1e-3)
    red = bodies["craig-bampton"]
    z, _, _ = _mounted_tip_z(red, FREE)  # the plain model file
    assert z == pytest.approx(full, rel=2e-3)
    write_exudyn(red, tmp_path / "cb.exudyn.npz", model=free)
    z_file, mbs, body = _mounted_tip_z(red, free, via_file=tmp_path / "cb.exudyn.npz")
    assert z_file == pytest.approx(z, rel=1e-10)
    # the body's own (modal) damping survives the file
    D = mbs.GetObjectParameter(body["oFFRFreducedOrder"], "dampingMatrixReduced").Convert2DenseMatrix()
    np.testing.assert_allclose(D, red.D, rtol=1e-12, atol=1e-12 * np.abs(red.D).max())


@pytest.mark.parametrize("method", ["craig-chang", "herting"])
def test_a_free_interface_body_mounts_by_its_interface(beam, method):
    """Craig-Chang and Herting 16 (free-interface modes and the master's residual flexibility) held at FIX@rbe2
    in Exudyn under gravity sag like Craig-Bampton 16, which sags like the full model (4.5e-10)."""
    free, _, c, bodies = beam
    mc = apply_damping(c.model, modal_damping=0.01, band=(10.0, 3000.0))
    red = reduce(mc, method, 16, make_ports(mc, ["TIP:y"]), interface=[SPEC])
    red.couplings = [SPEC]
    z, _, _ = _mounted_tip_z(red, free)
    assert z == pytest.approx(_mounted_tip_z(bodies["craig-bampton"], free)[0], rel=1e-6)


@pytest.mark.parametrize("method", ["craig-bampton", "krylov"])
def test_a_body_trimmed_by_frequency_still_sags_like_the_body(beam, method):
    """Issue: Craig-Bampton 16 and Krylov 16 trimmed by --max-frequency 20000 (14-15 of their modes) sagged
    15-16 % less in Exudyn. With the static vectors of the modes left out (the default) the trimmed body sags
    like the body within 1e-6; without them the old loss shows."""
    from flexmor.analysis.mode_selection import trim

    free, _, _, bodies = beam
    red = bodies[method]
    z, _, _ = _mounted_tip_z(red, free)
    kept, rec = trim(red, band=(10.0, 3000.0), max_frequency=20000.0)
    bare, bare_rec = trim(red, band=(10.0, 3000.0), max_frequency=20000.0, static=False)
    assert len(rec["modes_kept"]) == len(bare_rec["modes_kept"]) < red.order and rec["static_vectors"] >= 1
    assert kept.order <= red.order and "static vectors" in kept.order_note
    z_kept, _, _ = _mounted_tip_z(kept, free)
    z_bare, _, _ = _mounted_tip_z(bare, free)
    assert z_kept == pytest.approx(z, rel=1e-6)
    assert abs(z_bare / z - 1) > 0.05


def test_cli_export_refuses_a_body_with_rigid_motion_unless_asked(tmp_path, capsys):
    """krylov with rigid='include' on the free beam: the body judged has order 12 with 4 rigid-body
    modes; export refuses to write another body silently, and with --remove-rigid states the order
    and the error of what it writes."""
    beam = FREE
    body = tmp_path / "k.h5"
    assert main(["reduce", beam, "--method", "krylov", "--order", "12", "--rigid", "include", "--input", "TIP:y",
                 "--input", "TIP:z", "--modal-damping", "0.01", "--band", "10:3000", "-o", str(body), "--json"]) == 0
    capsys.readouterr()
    out = tmp_path / "k.SID_FEM"
    assert main(["export", str(body), "--model", beam, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "rigid-body motion" in err and "order 12 -> 8" in err and "--remove-rigid" in err
    assert not out.exists()
    assert main(["export", str(body), "--model", beam, "-o", str(out), "--remove-rigid", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["order"] == 12 and rec["order_exported"] == 8
    assert 0 < rec["band_error"] < 1 and rec["band_hz"] == [10.0, 3000.0]
    assert len(read_sid(out).ielastq) == 8


def test_vtu_of_a_coupled_body_moves_the_slaves(beam, tmp_path):
    meshio = pytest.importorskip("meshio")
    from flexmor.io.vtu import write_vtu

    free, _, c, bodies = beam
    red = bodies["craig-bampton"]
    write_vtu(red, tmp_path / "cb.vtu", model=free)
    grid = meshio.read(tmp_path / "cb.vtu")
    fix = np.isin(free.node_ids, free.node_sets["FIX"])
    # the constraint modes move the interface: the highest modes of the body (its constraint modes'
    # share) displace the FIX nodes
    moved = max(np.abs(grid.point_data[f"mode_{k}"][:free.n_nodes][fix]).max() for k in range(1, red.order + 1))
    assert moved > 1e-3
    # the master is a point of its own, with its id, at its position, moving with its translations
    mid, rows = _master_rows(c, red)
    i = int(np.flatnonzero(grid.point_data["node_id"] == mid)[0])
    assert i == free.n_nodes and grid.points.shape[0] == free.n_nodes + 1
    np.testing.assert_allclose(grid.points[i], [0.0, 0.05, 0.05], atol=1e-12)
    assert any(b.type == "vertex" and b.data.ravel().tolist() == [i] for b in grid.cells)
    lam, phi = sla.eigh(red.K, red.M)
    for k in (0, red.order - 1):  # the mode shapes' sign is free: compare magnitudes of the master's motion
        np.testing.assert_allclose(np.abs(grid.point_data[f"mode_{k + 1}"][i]), np.abs(rows[:3] @ phi[:, k]),
                                   rtol=1e-8, atol=1e-12)


@pytest.mark.slow
def test_cli_mounted_record_against_calculix_clamped_and_its_opt_out(tmp_path, capsys, clamped_ref):
    """The free beam with FIX@rbe2, held clamped at the master, is the beam CalculiX clamped itself: the
    mounted record's full frequencies are CalculiX's own (100.046, 100.046, 608.565 ... Hz) to the
    printed digits, and the Craig-Bampton body's equal them (its fixed-interface modes). --no-mounted
    leaves the check out."""
    beam = FREE
    args = ["reduce", beam, "--method", "craig-bampton", "--order", "16", "--interface", SPEC, "--input", "TIP:y",
            "--band", "10:3000", "--json"]
    assert main(args + ["-o", str(tmp_path / "a.h5")]) == 0
    rec = json.loads(capsys.readouterr().out)
    (case,) = [c for c in rec["mounted"]["cases"] if c["held"] == "clamped"]
    assert case["node"] == 100
    k = 4
    np.testing.assert_allclose(case["frequencies_full_hz"][:k], clamped_ref[:k], rtol=2e-6)
    np.testing.assert_allclose(case["frequencies_reduced_hz"][:k], clamped_ref[:k], rtol=2e-6)
    assert main(args + ["-o", str(tmp_path / "b.h5"), "--no-mounted"]) == 0
    assert "mounted" not in json.loads(capsys.readouterr().out)
