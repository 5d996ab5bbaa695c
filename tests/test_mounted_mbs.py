"""MBS in the loop, mounted: free bodies held at their interface in Exudyn deflect like the full FE
model held there (small sizes of ``bench/mounted.py``, same code).

The free plate structure (``plate_structure(12, lower='mass')``, 2,994 DOF, interface the RBE2 of
its hole's wall ``HOLE@rbe2``, output the upper plate's corner) and the free CalculiX beam (297 DOF,
``FIX@rbe2`` on its face x = 0, output the tip face), each reduced by craig-bampton, krylov,
fw-sobt and pod for the six master directions and the output's z (collocated), are mounted in
Exudyn by the coupling's rigid marker and a GenericJoint to the ground locking all six axes.
Reference: the model as read without the slave nodes' DOFs (the RBE2 ring held rigidly at a fixed
master), statically under its consistent gravity load, and as Exudyn's full ``ObjectFFRF`` with
its frame and slave nodes fixed for the transient. The frame nodes of the SID export are checked
with a reader of the format's text (``tests/sid_check.py``) that does not use flexmor's.
Skipped without Exudyn (extra ``exudyn``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sid_check
from helpers import ROOT, load_script

pytest.importorskip("exudyn")

mounted = load_script(ROOT / "bench" / "mounted.py")

METHODS = mounted.METHODS
PLATE_N = 12


def _bodies(case, orders=None):
    mc = mounted.coupled_model(case)
    orders = case.orders if orders is None else orders
    return {m: mounted.reduce_body(case, m, orders[m], judge=False, model=mc)[0] for m in METHODS}


@pytest.fixture(scope="module")
def beam():
    """(case, bodies of order 16, deflection of the held full model under gravity)."""
    case = mounted.beam8()
    full = mounted.output_value(case, mounted.held_static(case, mounted.gravity_load(case.model)))
    return case, _bodies(case), full


@pytest.fixture(scope="module")
def plate():
    """(case, bodies at the issue's orders CB 40, krylov 45, fw-sobt 40, pod 40, deflection of the
    held full model under gravity)."""
    case = mounted.plate(PLATE_N)
    full = mounted.output_value(case, mounted.held_static(case, mounted.gravity_load(case.model)))
    return case, _bodies(case), full


@pytest.fixture(scope="module")
def small_plate():
    """``plate_structure(4, lower='mass')`` (1,122 DOF) with the solid alone (1,224 DOF) and its rigid
    lower plate for Exudyn's full ObjectFFRF."""
    return mounted.plate(4, transient=True)


def test_held_references(beam, plate, small_plate):
    """The references. The beam held at FIX@rbe2 sags -38.25 um at the tip under gravity; CalculiX's
    own clamped export of the same mesh gives -38.22 um because its load ``M_cc g`` lacks the mass
    coupling ``M_cf g`` of the clamped nodes (same K and M, 6.3e-4 apart). Exudyn's full ObjectFFRF
    held by its fixed frame and the slaves' coordinates (the transient's reference; for the plate the
    solid with the rigid lower plate on spherical joints) sags like the sparse solve: measured 5e-12."""
    case, _, full = beam
    assert full == pytest.approx(-3.8246e-5, rel=1e-4)
    assert mounted.full_static(case) == pytest.approx(full, rel=1e-9)
    assert plate[0].model.n_dof == 2994 and plate[2] == pytest.approx(-5.2478e-6, rel=1e-4)
    case = small_plate
    assert case.solid.n_dof == 1224 and case.rigid["slaves"].size == 36
    assert case.rigid["mass"] == pytest.approx(7850 * 0.5 * 0.5 * 0.02, rel=1e-12)
    full = mounted.output_value(case, mounted.held_static(case, mounted.gravity_load(case.model)))
    assert full == pytest.approx(-1.1796e-6, rel=1e-4)
    assert mounted.full_static(case) == pytest.approx(full, rel=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_plate_mounted_sags_like_the_held_model(plate, method):
    """Mounted under gravity, the corner sags -5.25 um like the held structure: measured rel. error
    2.2e-12 (craig-bampton 40: its inertia-relief attachment modes are the held body's response to
    any rigid-body acceleration), 2.6e-13 (krylov 45: its inputs include the master's six
    directions, whose inertia-relief responses are the same), 3.4e-9 (fw-sobt 40, pod 40: the same
    basis for collocated ports). Bound: the issue's 1 %. A body rigid at its interface sags 0."""
    case, bodies, full = plate
    z = mounted.mounted_static(bodies[method], case)
    assert bodies[method].order == case.orders[method]
    assert z == pytest.approx(full, rel=1e-2)


@pytest.mark.parametrize("method", METHODS)
def test_beam_mounted_sags_like_the_held_model(beam, method):
    """The beam of order 16 mounted at FIX@rbe2: measured rel. error 4.5e-10 (craig-bampton,
    krylov), 9.5e-8 (fw-sobt, pod)."""
    case, bodies, full = beam
    z = mounted.mounted_static(bodies[method], case)
    assert z == pytest.approx(full, rel=1e-2)


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_beam_mounted_without_master_moments(beam, method):
    """The ports of ``tests/test_interfaces.py`` (master forces y and z, tip y and z; no moments at
    the master): craig-bampton's attachment modes span the held body's gravity response (4.5e-10);
    krylov, fw-sobt and pod get it from the inertia loads of the body held at its master, which
    they add to their inputs when the inputs do not hold the master's six directions (measured
    4.5e-10, 9.8e-9, 9.8e-9). Without them (main before the inertia loads of the held body)
    krylov 16 missed it by 15 %, fw-sobt (order 14 of 16 asked) by 20 %, pod 16 by 15 %: the
    moment the master takes was not among their inputs."""
    case, _, full = beam
    case = dataclasses.replace(case, inputs=["FIX@rbe2:y", "FIX@rbe2:z", "TIP:y", "TIP:z"])
    red, _ = mounted.reduce_body(case, method, 16, judge=False)
    z = mounted.mounted_static(red, case)
    assert z == pytest.approx(full, rel=1e-2)


def test_beam_transient_follows_the_full_object_ffrf(beam):
    """A 1 kN step at the tip (-z) for 20 ms (200 steps of 0.1 ms), damping 4e-5 K on both sides
    (1 % at the first bending mode, about 80 Hz; 25 % at 2 kHz, so what the order-16 bodies leave
    out decays within a millisecond). The full ObjectFFRF overshoots the static Euler-Bernoulli
    deflection F L³ / 3EI = 0.19 mm to 0.255 mm (a step: up to twice the static deflection, less
    the damping and the shear). Error relative to that peak, measured mean / max: craig-bampton
    4.0e-4 / 5.2e-4 (its basis lacks the tip load's static correction, a constant offset),
    krylov, fw-sobt, pod 4.8e-5 / 1.3e-4 (the tip force is an input). Bounds: 2.5x those."""
    case, bodies, _ = beam
    res = mounted.transient_rows(case, bodies=bodies, end_time=0.02, step=1e-4, beta=4e-5)
    static_eb = 1000.0 * 1.0 ** 3 / (3 * 2.1e11 * 0.1 ** 4 / 12)
    assert res["steps"] == 200 and res["full_n_dof"] == 297
    assert 1.2 * static_eb < res["max_deflection_m"] < 1.5 * static_eb
    rows = {r["method"]: r for r in res["rows"]}
    assert rows["craig-bampton"]["mean_error"] < 1e-3 and rows["craig-bampton"]["max_error"] < 1.3e-3
    for method in ("krylov", "fw-sobt", "pod"):
        assert rows[method]["mean_error"] < 1.2e-4 and rows[method]["max_error"] < 3.2e-4, method


def test_plate_transient_follows_the_full_object_ffrf(small_plate):
    """The small plate, a 1 kN step at the corner (-z) for 10 ms (100 steps), damping 4e-5 K: the full
    ObjectFFRF (the solid, its rigid lower plate on 36 spherical joints: its mass and rotary inertia
    now act) against the bodies mounted at HOLE@rbe2 (craig-bampton and krylov; the Gramian
    methods' transient is checked on the beam). Measured mean / max error: krylov 45 2.9e-3 /
    5.1e-2 (fw-sobt and pod alike); the max is the first step, where the full mesh answers the
    point force locally and a basis of global shapes cannot. Craig-Bampton 40 misses the corner
    force's static correction (its basis is the interface's attachment modes and fixed-interface
    modes; the point force's local deflection on this coarse mesh is a fifth of the corner's):
    1.9e-1 / 2.8e-1."""
    res = mounted.transient_rows(small_plate, end_time=0.01, step=1e-4, beta=4e-5,
                                 methods=("craig-bampton", "krylov"))
    assert res["full_n_dof"] == 1224 and 2e-5 < res["max_deflection_m"] < 4e-5
    rows = {r["method"]: r for r in res["rows"]}
    assert rows["krylov"]["mean_error"] < 7e-3 and rows["krylov"]["max_error"] < 0.1
    assert 0.1 < rows["craig-bampton"]["mean_error"] < 0.3


def _check_sid(body, model, path):
    """The SID frame node of the interface against the expanded body: master rows and the slaves'
    rigid motion ``phi + psi x (x_slave - x_master)``; returns the largest |psi| / |phi|."""
    from flexmor.expansion import expand_body
    from flexmor.io.sid import write_sid

    write_sid(body, path, model=model)
    xb = expand_body(model, body)
    (master,) = xb.masters
    n_nodes, n_modes, comment = sid_check.header(path)
    assert n_modes == body.order and f"{master.id}={master.name}" in comment
    nodes = sid_check.frame_nodes(path)
    assert len(nodes) == n_nodes and master.id in nodes
    node = nodes[master.id]
    scale = np.abs(master.rows).max()
    np.testing.assert_allclose(node["origin"][:, 0], master.xyz, rtol=0, atol=1e-15)
    np.testing.assert_allclose(node["phi"], master.rows[:3], rtol=0, atol=1e-15 * scale)
    np.testing.assert_allclose(node["psi"], master.rows[3:], rtol=0, atol=1e-15 * scale)
    dofs = xb.model.dofs
    for k in master.slaves:
        idx = [int(np.flatnonzero((dofs[:, 0] == k) & (dofs[:, 1] == d))[0]) for d in (1, 2, 3)]
        r = xb.model.node_xyz([int(k)])[0] - node["origin"][:, 0]
        rigid = node["phi"] + np.cross(node["psi"].T, r).T
        np.testing.assert_allclose(xb.V[idx], rigid, rtol=0, atol=1e-12 * scale)
    return np.abs(node["psi"]).max() / np.abs(node["phi"]).max()


@pytest.mark.parametrize("method", METHODS)
def test_sid_interface_node_is_the_expanded_master(beam, plate, method, tmp_path):
    """SID of the beam's and the plate's bodies (``--model`` the model as read): the frame node of
    the interface carries the master's position, its translations (phi) and rotations (psi)
    exactly as the body expanded through its coupling, and each slave of the RBE2 moves as
    ``phi + psi x (x_slave - x_master)``. The rotations are a real part of the interface motion
    (|psi| / |phi| > 1 1/m: a wrong or missing psi fails)."""
    for (case, bodies, _), name in ((beam, "beam"), (plate, "plate")):
        ratio = _check_sid(bodies[method], case.model, tmp_path / f"{name}.SID_FEM")
        assert ratio > 1.0, (name, ratio)


@pytest.mark.slow
def test_benchmark_command_line_prints_the_tables(tmp_path, capsys):
    """``bench/mounted.py`` end to end on the smallest plate (one method, no error evaluation, 1 ms):
    each case in its own process, a static and a transient table, the JSON with their rows."""
    import json

    out = tmp_path / "m.json"
    assert mounted.main(["--no-beam", "--static-n", "4", "--transient-n", "4", "--methods", "krylov", "--no-judge",
                         "--end-time", "0.001", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    res = json.loads(out.read_text())["results"]
    assert [r["kind"] for r in res] == ["static", "transient"] and res[1]["steps"] == 10
    assert res[0]["rows"][0]["rel_error"] < 1e-6 and res[0]["n_dof"] == 1122
    assert "rel. error" in text and "full ObjectFFRF 1224 DOF" in text
