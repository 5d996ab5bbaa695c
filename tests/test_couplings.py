"""RBE2 / RBE3 couplings on the CalculiX beams: Craig-Bampton with a rigid tip, rigid modes, RBE3 averages."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from flexmor.couplings import couple, parse_coupling, rbe3_matrix
from flexmor.errors import PortError
from flexmor.ports import interface_dofs, make_ports
from flexmor.reduction.craig_bampton import craig_bampton


def _rigid(model, t, theta, p):
    """Displacements of a rigid motion (translation t, small rotation theta about point p)."""
    x = model.node_xyz(model.dofs[:, 0])
    u = t + np.cross(theta, x - p)
    q = np.zeros(model.n_dof)
    tr = model.dofs[:, 1] <= 3
    q[tr] = u[tr, model.dofs[tr, 1] - 1]
    q[~tr] = np.asarray(theta)[model.dofs[~tr, 1] - 4]
    return q


def test_craig_bampton_with_rbe2_tip_is_exact_statically(clamped):
    cp = couple(clamped, ["TIP@rbe2:y"])
    model = cp.model
    tip = cp.masters["TIP@RBE2"]
    assert model.n_dof == clamped.n_dof - 27 + 6
    np.testing.assert_allclose(model.node_xyz([tip])[0], [1.0, 0.05, 0.05])
    assert interface_dofs(model, ["TIP@rbe2"]).size == 6
    basis = craig_bampton(model, None, 17, interface=["TIP@rbe2"])  # 11 fixed-interface modes: whole pairs
    assert basis.info["n_interface_dofs"] == 6 and basis.V.shape == (model.n_dof, 17)
    ports = make_ports(model, ["TIP@rbe2:y", "TIP@rbe2:rx"])
    b = ports.B.toarray()
    full = spla.spsolve(model.K.tocsc(), b)
    V = basis.V
    red = V @ np.linalg.solve(V.T @ (model.K @ V), V.T @ b)
    assert np.abs(red - full).max() <= 1e-10 * np.abs(full).max()
    # the same through the original model: basis T V, rigid tip face
    Vf = cp.expand(V)
    Kr = V.T @ (model.K @ V)
    assert np.abs(Vf.T @ (clamped.K @ Vf) - Kr).max() <= 1e-12 * np.abs(Kr).max()
    face = [clamped.dof_index(n, 2) for n in clamped.node_sets["TIP"]]
    r = clamped.node_xyz(clamped.node_sets["TIP"]) - [1.0, 0.05, 0.05]
    for col in range(2):  # the tip force (mostly t_y) and the tip moment (mostly theta_x)
        u = cp.expand(full[:, col])
        t_y = full[model.dof_index(tip, 2), col]
        theta_x, theta_z = full[model.dof_index(tip, 4), col], full[model.dof_index(tip, 6), col]
        # rigid face: y displacement of each face node = t_y + (theta x r)_y, to the round-off of
        # these three terms (measured: exact)
        scale = abs(t_y) + (abs(theta_x) + abs(theta_z)) * np.abs(r).max()
        assert np.abs(u[face] - (t_y + theta_z * r[:, 0] - theta_x * r[:, 2])).max() <= 4 * np.finfo(float).eps * scale


def test_rbe2_ring_keeps_six_rigid_modes(free):
    model = couple(free, ["TIP@rbe2", "FIX@rbe2"]).model
    assert model.n_dof == free.n_dof - 2 * 27 + 12
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 6])
    f = np.sqrt(np.abs(w)) / (2 * np.pi)
    assert np.all(f[:6] < 1e-2 * f[6]) and f[6] > 500


def test_rbe3_rotation_of_a_rigid_motion(free):
    theta, t, p = np.array([1e-3, -2e-3, 3e-3]), np.array([0.1, -0.2, 0.3]), np.array([0.3, 0.2, -0.1])
    q = _rigid(free, t, theta, p)
    ports = make_ports(free, ["TIP@rbe3:rx", "TIP@rbe3:ry", "TIP@rbe3:rz", "TIP@rbe3[1,0,0]:y"])
    y = ports.C @ q
    # a row of C with n non-zeros applied to q errs by at most n eps |C||q|; the translations in q
    # cancel in the rotations, so that bound is 1.1e-12 relative to theta_x (measured 0.70 of eps |C||q|)
    n = np.diff(ports.C.tocsr().indptr).max()
    bound = n * np.finfo(float).eps * (abs(ports.C) @ np.abs(q))
    expected = np.r_[theta, (t + np.cross(theta, np.array([1.0, 0, 0]) - p))[1]]
    assert np.all(np.abs(y - expected) <= bound)
    assert abs(ports.B - ports.C.T).max() == 0.0  # the force distribution is the transpose


def test_rbe3_tip_deflection_is_the_face_average(clamped):
    cp = couple(clamped, ["TIP@rbe3"])
    model, tip = cp.model, cp.masters["TIP@RBE3"]
    assert model.n_dof == clamped.n_dof + 6 - 6
    f = np.zeros(model.n_dof)
    f[model.dof_index(tip, 2)] = 1000.0
    u = spla.spsolve(model.K.tocsc(), f)
    q = cp.expand(u)
    face = [clamped.dof_index(n, 2) for n in clamped.node_sets["TIP"]]
    assert u[model.dof_index(tip, 2)] == pytest.approx(np.mean(q[face]), rel=1e-12)
    # the same load as an RBE3 port on the unchanged model: force spread by W^T, not stiffened
    ports = make_ports(clamped, ["TIP@rbe3:y"])
    q2 = spla.spsolve(clamped.K.tocsc(), 1000.0 * ports.B.toarray()[:, 0])
    # two backward-stable solves of differently assembled systems agree to ~cond(K) eps in norm (entries
    # that are zero in exact arithmetic carry that absolute error): cond_1(K) ~ 8e5 here, the observed
    # difference 2e-11 relative, the bound 10 cond_1(K) eps ~ 2e-9
    lu = spla.splu(clamped.K.tocsc())
    inv = spla.LinearOperator(clamped.K.shape, matvec=lu.solve, rmatvec=lambda x: lu.solve(x, trans="T"))
    cond = spla.onenormest(clamped.K) * spla.onenormest(inv)
    assert np.linalg.norm(q2 - q) <= 10 * cond * np.finfo(float).eps * np.linalg.norm(q)
    # the coarse C3D8 mesh is stiffer than Euler-Bernoulli (its first mode is 100.0 Hz, not 83.5 Hz):
    # the static deflection is stiffer by about the same factor
    eb = 1000.0 * 1.0 ** 3 / (3 * 2.1e11 * 0.1 ** 4 / 12)
    assert u[model.dof_index(tip, 2)] / eb == pytest.approx((83.5 / 100.046) ** 2, rel=0.05)


def test_bad_couplings(clamped):
    with pytest.raises(PortError, match="RBE2 makes the set rigid"):
        make_ports(clamped, ["TIP@rbe2:y"])
    with pytest.raises(PortError, match="couplings are part of the model"):
        interface_dofs(clamped, ["TIP@rbe2"])
    with pytest.raises(PortError, match="expected SET@rbe2 or SET@rbe3"):
        parse_coupling("TIP@rbe4")
    with pytest.raises(PortError, match="three numbers"):
        parse_coupling("TIP@rbe2[1,2]")
    with pytest.raises(PortError, match="neither a node set nor a node"):
        couple(clamped, ["NOPE@rbe3"])
    line = clamped.node_sets["TIP"][:3]  # y = 0, 0.05, 0.1 at z = 0: one line
    with pytest.raises(PortError, match="on one line"):
        rbe3_matrix(clamped, line, [1.0, 0.05, 0.0])
    with pytest.raises(PortError, match="shares equations"):
        couple(clamped, ["TIP@rbe2", "TIP@rbe3"])
