"""Exudyn export: the body dropped into Exudyn (a real MBS code) reproduces flexmor's reduced
eigenfrequencies and its time response. Skipped when exudyn is not installed (extra ``exudyn``)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import solve_exudyn

from flexmor.basis import Basis
from flexmor.io.exudyn import add_marker, add_to_exudyn, exudyn_data, write_exudyn
from flexmor.io.invariants import compute_invariants, rigid_fields
from flexmor.ports import make_ports
from flexmor.projection import project

exu = pytest.importorskip("exudyn")


@pytest.fixture(scope="module")
def attached(free):
    """Free-free beam8 with an attached-frame basis: the 8 lowest modes of the beam clamped at
    x = 0 (zero at FIX), so the modes couple with the frame motion (Ct, Cr != 0)."""
    import scipy.linalg as sla

    fix = np.isin(free.dofs[:, 0], free.node_sets["FIX"])
    keep = np.flatnonzero(~fix)
    K, M = free.K[keep][:, keep].toarray(), free.M[keep][:, keep].toarray()
    lam, X = sla.eigh(K, M, subset_by_index=[0, 7])
    V = np.zeros((free.n_dof, 8))
    V[keep] = X
    ports = make_ports(free, ["TIP:y"])
    return project(free, Basis(V, "clamped-modes"), ports), ports


def _system(red, model):
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    body = add_to_exudyn(mbs, red, model)
    return SC, mbs, body


def test_exudyn_data_equals_the_invariants(free, attached):
    red, _ = attached
    d = exudyn_data(red, free)
    inv = compute_invariants(free, red.V)
    np.testing.assert_allclose(d["inertiaLocal"], inv.J0, rtol=1e-12)
    np.testing.assert_allclose(d["mPhitTPsi"], inv.Ct.T, atol=1e-12 * np.abs(inv.Ct).max())
    np.testing.assert_allclose(d["totalMass"], 7850 * 1 * 0.1 * 0.1, rtol=1e-12)
    np.testing.assert_allclose(-d["mXRefTildePsi"].T, inv.Cr0, atol=1e-12 * np.abs(inv.Cr0).max())


def test_free_floating_eigenfrequencies_equal_flexmor(free, attached):
    """Exudyn linearizes the free floating body (frame + modes); flexmor's reduced body with
    the basis [rigid motions, modes] must have the same eigenfrequencies."""
    red, ports = attached
    SC, mbs, body = _system(red, free)
    mbs.Assemble()
    ev, _ = exu.solver.ComputeODE2Eigenvalues(mbs)
    f_exu = np.sort(np.sqrt(np.abs(ev)) / (2 * np.pi))
    St, Sr, _ = rigid_fields(free)
    full = project(free, Basis(np.hstack([St, Sr, red.V]), "rigid+modes"), ports).frequencies_hz()
    assert f_exu.size == 14 and np.all(f_exu[:6] < 1e-3)
    np.testing.assert_allclose(f_exu[6:], full[6:], rtol=1e-6)
    # the coupling matters: the free body's frequencies are not those of the clamped modes alone
    assert abs(full[6] / red.frequencies_hz()[0] - 1) > 0.5


def test_force_at_the_tip_matches_flexmor_response(free, attached, tmp_path):
    """Step force 100 N in y on the tip face of the free body, 4 ms: the tip displacement in
    Exudyn (frame + modes, nonlinear FFRF) against the exact response of flexmor's reduced
    model (linear, basis [rigid motions, modes])."""
    red, ports = attached
    SC, mbs, body = _system(red, free)
    marker = add_marker(mbs, body, free, "TIP")
    F = 100.0
    mbs.AddLoad(exu.itemInterface.LoadForceVector(markerNumber=marker, loadVector=[0, F, 0]))
    sensor = mbs.AddSensor(exu.itemInterface.SensorMarker(markerNumber=marker, storeInternal=True,
                                                          outputVariableType=exu.OutputVariableType.Position))
    mbs.Assemble()
    s = exu.SimulationSettings()
    T, h = 4e-3, 5e-6
    s.timeIntegration.endTime = T
    s.timeIntegration.numberOfSteps = int(round(T / h))
    s.timeIntegration.generalizedAlpha.useNewmark = True
    s.timeIntegration.generalizedAlpha.useIndex2Constraints = True
    s.timeIntegration.generalizedAlpha.newmarkBeta = 0.25
    s.timeIntegration.generalizedAlpha.newmarkGamma = 0.5
    s.timeIntegration.verboseMode = 0
    s.solution.file.write = False
    s.solution.sensors.writePeriod = h
    mbs.SolveDynamic(s)
    data = mbs.GetSensorStoredData(sensor)
    t, y_exu = data[:, 0], data[:, 2] - data[0, 2]

    # flexmor: exact modal solution of Mr x'' + Kr x = Br F, y = Cr x
    import scipy.linalg as sla

    St, Sr, _ = rigid_fields(free)
    full = project(free, Basis(np.hstack([St, Sr, red.V]), "rigid+modes"), ports)
    lam, X = sla.eigh(full.K, full.M)
    g = X.T @ full.B[:, 0] * F
    lam = np.where(lam < 1e-6 * lam.max(), 0.0, lam)
    w = np.sqrt(lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        modal = np.where(w[None] > 0, g * (1 - np.cos(np.outer(t, w))) / np.where(w > 0, w, 1) ** 2,
                         g * t[:, None] ** 2 / 2)
    y_ref = (full.C @ X @ modal.T)[0]
    err = np.linalg.norm(y_exu - y_ref) / np.linalg.norm(y_ref)
    assert err < 0.01
    # the elastic part is not negligible: the rigid-body motion alone misses by far more
    y_rigid = F / full.M[0, 0] * t**2 / 2
    assert np.linalg.norm(y_rigid - y_ref) / np.linalg.norm(y_ref) > 10 * err


def test_npz_loads_in_exudyn(free, attached, tmp_path):
    from exudyn.FEM import ObjectFFRFreducedOrderInterface

    red, _ = attached
    path = tmp_path / "body.npz"
    write_exudyn(red, path, model=free)
    cms = ObjectFFRFreducedOrderInterface()
    cms.LoadFromFile(str(path))
    assert cms.nModes == 8 and cms.nNodes == free.n_nodes
    np.testing.assert_array_equal(cms.massMatrixReduced, red.M)


def test_full_body_falls_freely_and_refuses_rotational_dofs(free):
    """The unreduced ObjectFFRF of the whole FE model: under gravity alone the free body falls
    rigidly (the consistent load M Φt g at the mass-weighted mean), its nodes do not deform."""
    from flexmor.couplings import couple
    from flexmor.errors import ModelError
    from flexmor.io.exudyn import add_full_to_exudyn

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    body = add_full_to_exudyn(mbs, free, gravity=[0.0, -9.81, 0.0])
    assert len(body["node_index"]) == free.n_nodes == len(body["nodeList"])
    sensor = mbs.AddSensor(exu.itemInterface.SensorMarker(markerNumber=add_marker(mbs, body, free, "TIP"),
                                                          storeInternal=True,
                                                          outputVariableType=exu.OutputVariableType.Position))
    data = solve_exudyn(mbs, sensor, 0.1, 20)
    np.testing.assert_allclose(data[-1, 2] - data[0, 2], -9.81 * 0.1**2 / 2, rtol=1e-6)
    np.testing.assert_allclose(data[-1, [1, 3]], data[0, [1, 3]], atol=1e-9)
    coupled = couple(free, ["TIP@rbe2"]).model
    with pytest.raises(ModelError, match="rotational DOFs"):
        add_full_to_exudyn(exu.SystemContainer().AddSystem(), coupled)


def test_marker_on_clamped_nodes_of_the_full_body_is_refused():
    """A supported model's clamped nodes are not mesh nodes of the full body (they move with
    its frame): a marker there is refused with the parameter named, the free tip is fine."""
    from flexmor.errors import ModelError
    from flexmor.io.exudyn import add_full_to_exudyn
    from flexmor.models import cantilever

    model = cantilever(divisions=(4, 1, 1))
    mbs = exu.SystemContainer().AddSystem()
    body = add_full_to_exudyn(mbs, model, constrain_rigid=False)
    assert len(body["node_index"]) == model.n_nodes - 4 == model.n_dof // 3
    assert int(add_marker(mbs, body, model, "TIP")) >= 0
    with pytest.raises(ModelError, match="clamped nodes") as err:
        add_marker(mbs, body, model, "FIX")
    assert err.value.params == ("target",)


def test_full_body_draws_its_outer_surface():
    """The full body's triangles are the model's outer surface on Exudyn's mesh nodes; a
    clamped model's triangles that touch a clamped node (not a mesh node) are left out: the
    clamped face and the first element row of the four sides."""
    from flexmor.io.exudyn import add_full_to_exudyn
    from flexmor.models import cantilever

    for clamped, n_trigs in ((False, 2 * (4 * 4 + 2)), (True, 2 * (4 * 3 + 1))):  # 2 per face quad
        model = cantilever(divisions=(4, 1, 1), clamped=clamped)
        mbs = exu.SystemContainer().AddSystem()
        body = add_full_to_exudyn(mbs, model, constrain_rigid=not clamped)
        trigs = np.asarray(mbs.GetObject(body["oFFRF"])["VtriangleMesh"])
        assert trigs.shape == (n_trigs, 3) and trigs.max() < len(body["node_index"])
