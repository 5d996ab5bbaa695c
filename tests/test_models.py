"""Tests of the built-in scikit-fem solid models (flexmor.models)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from helpers import CCX, calculix_frequencies, geometric_rigid_modes

pytest.importorskip("skfem")

from flexmor.errors import OptionError
from flexmor.models import cantilever, plate, size_for_dofs

STEEL = {"E": 2.1e11, "nu": 0.3, "rho": 7850.0}

#: CalculiX 2.x, C3D8, 10x2x2 elements on 1 x 0.1 x 0.1 m, steel, *FREQUENCY 20:
#: column CYCLES/TIME of tests/data/calculix/beam8_clamped_freq.dat (FIX, 1, 3 at x=0)
CCX_CLAMPED_HZ = [
    100.0459, 100.0459, 608.5650, 608.5650, 802.7393, 1306.773, 1648.371, 1648.371, 2428.061,
    3116.942, 3116.942, 3958.758, 4113.257, 4981.376, 4981.376, 5898.581, 6728.120, 7210.562,
    7210.562, 7821.232,
]
#: the same free-free (beam8_free_freq.dat), modes 7..20 (modes 1..6 are rigid)
CCX_FREE_HZ = [
    620.6715, 620.6715, 1610.433, 1668.565, 1668.565, 2598.190, 3183.976, 3183.976, 3260.649,
    4990.931, 5122.121, 5122.121, 5269.543, 6840.755,
]


def _freqs_dense(model, k):
    lam = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, k - 1])
    return np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)


def _f1_sparse(model):
    lam = spla.eigsh(model.K.tocsc(), 2, model.M.tocsc(), sigma=0, which="LM", return_eigenvectors=False)
    return float(np.sqrt(np.min(lam)) / (2 * np.pi))


# -- conservation: mass and rigid-body modes ---------------------------------------------------
@pytest.mark.parametrize("element", ["hex", "hex27", "tet"])
def test_total_mass_of_free_cantilever(element):
    m = cantilever(2, element=element, clamped=False, length=1.0, width=0.2, height=0.1, **STEEL)
    R = geometric_rigid_modes(m, about=m.xyz.mean(axis=0))
    exact = 7850.0 * 1.0 * 0.2 * 0.1
    for j in range(3):
        assert R[:, j] @ (m.M @ R[:, j]) == pytest.approx(exact, rel=1e-10)
    # no mass coupling between translations in different directions
    assert abs(R[:, 0] @ (m.M @ R[:, 1])) < 1e-12 * exact


def test_total_mass_of_plate():
    m = plate(4, a=1.0, b=0.6, t=0.01)
    r = geometric_rigid_modes(m, about=m.xyz.mean(axis=0))[:, 2]
    assert r @ (m.M @ r) == pytest.approx(7850.0 * 1.0 * 0.6 * 0.01, rel=1e-10)


@pytest.mark.parametrize("maker", [
    lambda: cantilever(2, element="hex", clamped=False),
    lambda: cantilever(1, element="hex27", clamped=False, width=0.2),
    lambda: cantilever(2, element="tet", clamped=False),
    lambda: plate(3),
])
def test_rigid_body_modes_are_in_the_null_space(maker):
    m = maker()
    R = geometric_rigid_modes(m, about=m.xyz.mean(axis=0))
    Knorm = spla.norm(m.K, ord=np.inf)
    for j in range(6):
        r = R[:, j]
        assert np.linalg.norm(m.K @ r) <= 1e-10 * Knorm * np.linalg.norm(r), j
    # and exactly six of them: dense eigenvalues err by ~eps lam_max, so zero-energy modes come out
    # at that floor (measured up to 0.81 eps lam_max) and the 7th eigenvalue is far above it (the
    # thin plate's lam_max / lam_7 = 1.3e8 puts the floor at 2.8e-8 lam_7)
    lam = sla.eigh(m.K.toarray(), m.M.toarray(), eigvals_only=True, subset_by_index=[0, 6])
    floor = 4 * np.finfo(float).eps * spla.eigsh(m.K, 1, m.M, which="LA", return_eigenvectors=False, tol=1e-3)[0]
    assert np.all(np.abs(lam[:6]) < floor) and lam[6] > 1e6 * floor


# -- the stiffness assembly equals scikit-fem's linear_elasticity form -----------------------------
@pytest.mark.parametrize("element", ["hex", "hex27", "tet"])
def test_assembly_equals_skfem_linear_elasticity(element):
    import skfem
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from flexmor.models import solid

    m = cantilever(element=element, clamped=False, divisions=(3, 2, 1), length=0.3, width=0.1, height=0.07, **STEEL)
    mesh = solid._box_mesh(element, 3, 2, 1, 0.3, 0.1, 0.07)
    _, ename, intorder, _ = solid.ELEMENTS[element]
    vb = skfem.Basis(mesh, skfem.ElementVector(getattr(skfem, ename)()), intorder=intorder)
    K = linear_elasticity(*lame_parameters(2.1e11, 0.3)).assemble(vb)
    M = skfem.BilinearForm(lambda u, v, w: 7850.0 * dot(u, v)).assemble(vb)
    assert abs(K - m.K).max() <= 1e-13 * abs(K).max()
    assert abs(M - m.M).max() <= 1e-13 * abs(M).max()
    # equation 3 s + d is direction d+1 of node s+1 (scikit-fem's nodal_dofs)
    np.testing.assert_array_equal(vb.nodal_dofs[:, 5], [15, 16, 17])
    assert tuple(m.dofs[16]) == (6, 2)


# -- CalculiX C3D8 ---------------------------------------------------------------------------------
def test_clamped_hex_beam_reproduces_calculix_c3d8():
    m = cantilever(divisions=(10, 2, 2), length=1.0, width=0.1, height=0.1, **STEEL)
    assert m.n_dof == 270  # 99 nodes, 9 clamped
    f = _freqs_dense(m, 20)
    np.testing.assert_allclose(f, CCX_CLAMPED_HZ, rtol=2e-6)
    assert f[0] == pytest.approx(100.046, rel=1e-5)


def test_free_hex_beam_reproduces_calculix_c3d8():
    m = cantilever(divisions=(10, 2, 2), clamped=False, **STEEL)
    f = _freqs_dense(m, 20)
    assert np.all(f[:6] < 1e-2)  # rigid-body modes (round-off level)
    np.testing.assert_allclose(f[6:], CCX_FREE_HZ, rtol=2e-6)


def test_embedded_calculix_numbers_match_the_files():
    np.testing.assert_allclose(calculix_frequencies(CCX / "beam8_clamped_freq.dat"), CCX_CLAMPED_HZ, rtol=1e-12)
    np.testing.assert_allclose(calculix_frequencies(CCX / "beam8_free_freq.dat")[6:], CCX_FREE_HZ, rtol=1e-12)


# -- Euler-Bernoulli -------------------------------------------------------------------------------
def _euler_bernoulli_f1(L=1.0, w=0.1, h=0.1, E=2.1e11, rho=7850.0):
    inertia, area = w * h**3 / 12, w * h
    return 1.8751040687**2 / (2 * np.pi * L**2) * np.sqrt(E * inertia / (rho * area))


def test_cantilever_converges_to_euler_bernoulli():
    f_eb = _euler_bernoulli_f1()
    assert f_eb == pytest.approx(83.5517, rel=1e-5)
    f = [_f1_sparse(cantilever(n, **STEEL)) for n in (2, 3, 4, 6)]
    # trilinear hexahedra are too stiff in bending; refinement lowers f1 monotonically
    assert np.all(np.diff(f) < 0)
    assert 1.0 < f[0] / f_eb < 1.10
    assert abs(f[-1] / f_eb - 1) < 0.01
    # the quadratic element is close already on a coarse mesh (3D beam: slightly below EB)
    f27 = _f1_sparse(cantilever(2, element="hex27", **STEEL))
    assert abs(f27 / f_eb - 1) < 0.005
    assert f27 < f[-1]


def test_first_mode_bends_about_the_weak_axis():
    # width 0.2 > height 0.1: the first mode deflects in z; checks the direction map
    m = cantilever(2, width=0.2, height=0.1, **STEEL)
    lam, phi = spla.eigsh(m.K.tocsc(), 1, m.M.tocsc(), sigma=0, which="LM")
    node = m.node_sets["TIP_CENTER"][0]
    uz, uy = phi[m.dof_index(node, 3), 0], phi[m.dof_index(node, 2), 0]
    assert abs(uy) < 1e-6 * abs(uz)
    f1 = np.sqrt(lam[0]) / (2 * np.pi)
    assert f1 == pytest.approx(_euler_bernoulli_f1(w=0.2), rel=0.10)


# -- maps, node sets, sizes, options --------------------------------------------------------------
def test_clamped_dofs_and_node_sets():
    m = cantilever(2, length=1.0, width=0.1, height=0.1)
    free = cantilever(2, clamped=False)
    fix, tip = m.node_sets["FIX"], m.node_sets["TIP"]
    assert fix.size == tip.size == 9
    np.testing.assert_allclose(m.node_xyz(fix)[:, 0], 0.0)
    np.testing.assert_allclose(m.node_xyz(tip)[:, 0], 1.0)
    assert not np.any(np.isin(m.dofs[:, 0], fix))
    assert free.n_dof - m.n_dof == 3 * fix.size
    assert m.n_nodes == free.n_nodes == 21 * 3 * 3
    np.testing.assert_array_equal(m.node_ids, np.arange(1, m.n_nodes + 1))
    np.testing.assert_allclose(m.node_xyz(m.node_sets["TIP_CENTER"]), [[1.0, 0.05, 0.05]])
    assert m.name == "cantilever-hex-n2" and m.source == "built-in"
    # the clamped matrices are the free ones with the FIX rows and columns removed
    keep = [free.dof_index(a, b) for a, b in m.dofs]
    assert abs(free.K[keep][:, keep] - m.K).max() == 0.0


def test_dof_index_finds_every_equation_and_refuses_what_is_not_there():
    m = cantilever(n=2)
    rng = np.random.default_rng(1)
    for i in rng.permutation(m.n_dof)[:50]:
        assert m.dof_index(*m.dofs[i]) == i
    fixed = int(np.setdiff1d(m.node_ids, m.dofs[:, 0])[0])  # a clamped node: in the node table, no equations
    for node, d in ((fixed, 1), (int(m.dofs[0, 0]), 4), (int(m.node_ids.max()) + 1, 1), (int(m.dofs[0, 0]), 9)):
        with pytest.raises(KeyError):
            m.dof_index(node, d)


def test_plate_edges_and_clamping():
    p = plate(4, a=1.0, b=0.6, t=0.01)  # 7 x 4 x 2 elements
    assert p.n_nodes == 8 * 5 * 3
    pc = plate(4, a=1.0, b=0.6, t=0.01, clamped=True)
    for name, axis, value in [("EDGE_X0", 0, 0.0), ("EDGE_X1", 0, 1.0), ("EDGE_Y0", 1, 0.0), ("EDGE_Y1", 1, 0.6)]:
        np.testing.assert_allclose(p.node_xyz(p.node_sets[name])[:, axis], value)
    assert p.node_sets["EDGE_X0"].size == 5 * 3 and p.node_sets["EDGE_Y1"].size == 8 * 3
    assert p.n_dof - pc.n_dof == 3 * 15
    np.testing.assert_allclose(p.node_xyz(p.node_sets["CORNER"]), [[1.0, 0.6, 0.01]])


@pytest.mark.parametrize("kind,target,kw", [
    ("cantilever", 8_000, {}), ("cantilever", 30_000, {}), ("cantilever", 8_000, {"element": "hex27"}),
    ("plate", 10_000, {}), ("plate", 10_000, {"clamped": True}),
])
def test_size_for_dofs(kind, target, kw):
    n = size_for_dofs(target, kind, **kw)
    model = (cantilever if kind == "cantilever" else plate)(n, **kw)
    assert abs(np.log(model.n_dof / target)) < 0.35
    # neighbours are not closer
    for nb in (n - 1, n + 1):
        if nb >= 1:
            other = (cantilever if kind == "cantilever" else plate)(nb, **kw)
            assert abs(np.log(other.n_dof / target)) >= abs(np.log(model.n_dof / target))


def test_size_formula_matches_models():
    assert size_for_dofs(94_500) == 14
    assert cantilever(3, element="hex27").n_dof == 3 * 60 * 7 * 7  # 30x3x3 quadratic, x=0 clamped
    assert cantilever(1, element="tet", clamped=False).n_dof == 3 * 11 * 2 * 2


def test_bad_options_list_the_choices():
    with pytest.raises(OptionError, match="hex, hex27, tet"):
        cantilever(2, element="quad")
    with pytest.raises(OptionError, match="nu"):
        cantilever(2, nu=0.5)
    with pytest.raises(OptionError, match="length"):
        cantilever(2, length=-1.0)
    with pytest.raises(OptionError, match="cantilever, plate"):
        size_for_dofs(1000, "shell")


def test_import_does_not_need_scikit_fem():
    code = "import sys, flexmor, flexmor.models; sys.exit('skfem' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_matrices_are_csr_and_symmetric():
    m = cantilever(2, element="hex27")
    for A in (m.K, m.M):
        assert sp.isspmatrix_csr(A) or isinstance(A, sp.csr_array)
        assert abs(A - A.T).max() <= 1e-14 * abs(A).max()
