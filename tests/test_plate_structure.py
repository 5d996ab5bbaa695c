"""The built-in plate-and-rods structure (flexmor.models.plate_structure)."""

from __future__ import annotations

import numpy as np
import pytest

from flexmor.errors import OptionError
from flexmor.linalg.eigen import eigenmodes, frequencies_hz
from flexmor.models import plate_structure
from flexmor.ports import make_ports

E, RHO = 2.1e11, 7850.0


@pytest.fixture(scope="module")
def small():
    return plate_structure(20)


def test_size_and_sets(small):
    m = small
    assert m.n_dof == 6336
    # the rods' lower faces (4 x 3 x 3 nodes) are clamped: their nodes have no equations
    assert m.node_sets["BOTTOM"].size == 36
    assert not np.isin(m.dofs[:, 0], m.node_sets["BOTTOM"]).any()
    hole = m.node_xyz(m.node_sets["HOLE"])
    # the wall of the staircase hole: three through-thickness levels, symmetric, around radius 0.05
    assert np.allclose(sorted(set(np.round(hole[:, 2], 9))), [0.0, 0.01, 0.02])
    rad = np.hypot(hole[:, 0], hole[:, 1])
    h = 0.5 / 20
    assert rad.min() > 0.05 - h * np.sqrt(2) and rad.max() < 0.05 + h * np.sqrt(2)
    assert np.allclose(np.sort(hole[:, 0]), np.sort(-hole[:, 0]))
    assert np.allclose(hole[:, :2].mean(axis=0), 0.0, atol=1e-12)
    assert plate_structure(56).n_dof == 35988  # the default: the slides' 35,000-DOF class


def test_mass_and_first_frequency(small):
    m = small
    x = np.isin(np.arange(m.n_dof), np.flatnonzero(m.dofs[:, 1] == 1))
    mass_free_nodes = float(x @ (m.M @ x))  # the clamped nodes' share is missing: < the total
    nominal = RHO * (0.5 * 0.5 * 0.02 - np.pi * 0.05 ** 2 * 0.02 + 4 * 0.03 ** 2 * 0.4)
    assert 0.97 * nominal < mass_free_nodes < nominal
    lam, _ = eigenmodes(m.K, m.M, 4)
    f = frequencies_hz(lam)
    # sway of the (nearly rigid) plate on four fixed-guided rods: k = 4 * 12 E I / L^3 with the
    # plate's mass and 13/35 of the rods' mass
    k = 4 * 12 * E * (0.03 ** 4 / 12) / 0.4 ** 3
    m_eff = RHO * (0.5 * 0.5 * 0.02 - np.pi * 0.05 ** 2 * 0.02) + 13 / 35 * RHO * 4 * 0.03 ** 2 * 0.4
    f_sway = np.sqrt(k / m_eff) / (2 * np.pi)
    assert f[0] == pytest.approx(f_sway, rel=0.08)
    assert f[1] == pytest.approx(f[0], rel=1e-6)  # x and y sway: a double eigenvalue by symmetry
    assert f[2] > 1.2 * f[1]


def test_lower_plate_as_mass_is_free_with_its_inertia():
    m = plate_structure(12, lower="mass")
    lower = int(m.node_sets["LOWER"][0])
    assert np.allclose(m.node_xyz([lower])[0], [0.0, 0.0, -0.41])
    lam, _ = eigenmodes(m.K, m.M, 8)
    f = frequencies_hz(lam)
    assert np.all(f[:6] < 1e-3 * f[6])  # six rigid-body modes
    # rigid translation along z: structure + lower plate (0.5 x 0.5 x 0.02 steel, 39.25 kg)
    ports = make_ports(m, [f"{lower}:z"])
    clamped = plate_structure(12)
    nominal = RHO * (0.5 * 0.5 * 0.02 - np.pi * 0.05 ** 2 * 0.02 + 4 * 0.03 ** 2 * 0.4)
    rz = (m.dofs[:, 1] == 3).astype(float)
    total = float(rz @ (m.M @ rz))
    assert total == pytest.approx(nominal + 39.25, rel=0.03)
    assert ports.B.shape == (m.n_dof, 1) and clamped.n_dof < m.n_dof


@pytest.mark.parametrize("kw", [{"lower": "floating"}, {"hole": 0.5}, {"rod_inset": 0.01}, {"n": 1},
                                {"layers": 0}, {"t": -1.0}])
def test_bad_options(kw):
    with pytest.raises(OptionError):
        plate_structure(**({"n": 8} | kw))


def test_free_lower_ends_tied_to_the_rigid_plate_give_the_mass_variant():
    """``lower='free'``: the solid alone (3-DOF nodes, six rigid-body modes). Its rods' lower faces
    tied by the same RBE2 to the lower plate's centre give the ``mass`` variant's stiffness exactly,
    and its mass up to the rigid plate's own inertia at the master (39.25 kg; 0.8177 and 1.635
    kg m² about the centre)."""
    from flexmor.couplings import couple

    free, mass = plate_structure(8, lower="free"), plate_structure(8, lower="mass")
    assert free.n_dof == 3 * free.n_nodes == 2160 and free.name == "plate-structure-n8-free"
    lower = int(mass.node_sets["LOWER"][0])
    c = couple(free, [f"BOTTOM@rbe2[0,0,{float(mass.node_xyz([lower])[0][2])!r}]"])
    assert np.array_equal(c.model.dofs, mass.dofs)
    assert abs(c.model.K - mass.K).max() <= 1e-12 * abs(mass.K).max()
    extra = (mass.M - c.model.M).toarray()
    eqs = [mass.dof_index(lower, d) for d in range(1, 7)]
    m = RHO * 0.5 * 0.5 * 0.02
    np.testing.assert_allclose(np.diag(extra)[eqs], [m, m, m, m * (0.25 + 0.02 ** 2) / 12, m * (0.25 + 0.02 ** 2) / 12,
                                                     m * 0.25 / 6], rtol=1e-12)
    extra[eqs, eqs] = 0.0
    assert np.abs(extra).max() <= 1e-12 * m
    lam, _ = eigenmodes(free.K, free.M, 8)
    f = frequencies_hz(lam)
    assert np.all(f[:6] < 1e-3 * f[6])
