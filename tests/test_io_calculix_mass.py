"""Singular and indefinite mass matrices of quadratic CalculiX elements (C3D20R): a warning, not an error.

The beam job is rewritten with ``TYPE=C3D20R`` and a mass matrix that is (a) lumped with
massless nodes, (b) consistent but rank-deficient. The model must load with a FlexmorWarning,
and the shift-invert eigen solver (which only factorizes ``K - sigma M``) must give the
frequencies of the exact static condensation of the massless DOFs.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from helpers import CCX

import flexmor.io
from flexmor.errors import FlexmorWarning, ReadError
from flexmor.linalg import eigenmodes


def _job(tmp_path, M, etype="C3D20R"):
    """The beam job with mass ``M``; K and M written on one pattern (zeros included), as CalculiX does."""
    for suf in (".dof", ".inp"):
        shutil.copy(CCX / f"beam8_clamped_mat{suf}", tmp_path / f"job{suf}")
    inp = tmp_path / "job.inp"
    inp.write_text(inp.read_text().replace("TYPE=C3D8", f"TYPE={etype}"))
    K = flexmor.io.read(CCX / "beam8_clamped_mat.sti").K
    r, c = np.nonzero(np.triu((M != 0) | (K.toarray() != 0) | np.eye(len(M), dtype=bool)))
    for name, A in (("job.sti", K.toarray()), ("job.mas", M)):
        (tmp_path / name).write_text("".join(f"{i + 1} {j + 1} {float(A[i, j])!r}\n" for i, j in zip(r, c)))
    return tmp_path / "job.sti"


@pytest.mark.parametrize("method", ["dense", "lanczos"])
def test_massless_nodes(tmp_path, clamped, method):
    M = np.diag(np.asarray(clamped.M.sum(axis=1)).ravel())  # row-sum lumping
    massless = np.isin(clamped.dofs[:, 0], clamped.dofs[::7, 0])
    M[massless, massless] = 0.0
    with pytest.warns(FlexmorWarning, match=r"diagonal is not positive at \d+ equation.*still work"):
        model = flexmor.io.read(_job(tmp_path, M))
    assert model.M.diagonal().min() == 0.0
    lam, phi = eigenmodes(model.K, model.M, 4, method=method)
    np.testing.assert_allclose(phi.T @ model.M @ phi, np.eye(4), atol=1e-9)
    K = clamped.K.toarray()
    m, z = ~massless, massless
    Kc = K[np.ix_(m, m)] - K[np.ix_(m, z)] @ np.linalg.solve(K[np.ix_(z, z)], K[np.ix_(z, m)])
    ref = sla.eigh(Kc, M[np.ix_(m, m)], eigvals_only=True, subset_by_index=[0, 3])
    np.testing.assert_allclose(lam, ref, rtol=1e-8)
    with pytest.raises(ReadError, match="mass matrix diagonal is not positive"):
        flexmor.io.read(_job(tmp_path, M, etype="C3D8"))


@pytest.mark.parametrize("method", ["dense", "lanczos"])
def test_rank_deficient_consistent_mass(tmp_path, clamped, method):
    M = clamped.M.toarray()
    mu, U = np.linalg.eigh(M)
    Ms = M - mu[0] * np.outer(U[:, 0], U[:, 0]) - mu[1] * np.outer(U[:, 1], U[:, 1])  # rank n - 2, PSD
    Ms = 0.5 * (Ms + Ms.T)
    assert Ms.diagonal().min() > 0
    kinds = "singular|indefinite|not positive definite"
    with pytest.warns(FlexmorWarning, match=rf"job\.mas \(C3D20R elements\): the mass matrix is ({kinds})"):
        model = flexmor.io.read(_job(tmp_path, Ms))
    lam, _ = eigenmodes(model.K, model.M, 3, method=method)
    mu = sla.eigh(Ms, clamped.K.toarray(), eigvals_only=True)  # K positive definite, Ms singular: 1 / lambda
    np.testing.assert_allclose(lam, np.sort(1.0 / mu[-3:]), rtol=1e-6)


def test_regular_mass_with_quadratic_elements_is_quiet(tmp_path, clamped, recwarn):
    from flexmor.io._mass import check_mass

    model = flexmor.io.read(_job(tmp_path, clamped.M.toarray()))
    assert not [w for w in recwarn if issubclass(w.category, FlexmorWarning)]
    assert check_mass(model, "x") > 1e-6


@pytest.mark.parametrize("block, ok", [("blockC3D10", True), ("blockC3D8", False)])
def test_abaqus_massless_equation(tmp_path, block, ok):
    """Row and column 1 of the Abaqus mass cleared: allowed (warned) for C3D10, an error for C3D8."""
    src = CCX.parent / "abaqus"
    shutil.copy(src / f"{block}.inp", tmp_path / f"{block}.inp")
    shutil.copy(src / f"{block}_STIF1.mtx", tmp_path / f"{block}_STIF1.mtx")
    lines = (src / f"{block}_MASS1.mtx").read_text().splitlines()
    kept = [ln for ln in lines if "1" not in ln.split()[:2]]
    (tmp_path / f"{block}_MASS1.mtx").write_text("\n".join(kept) + "\n")
    if not ok:
        with pytest.raises(ReadError, match="mass matrix diagonal is not positive at 1 equation"):
            flexmor.io.read(tmp_path / f"{block}.inp")
        return
    with pytest.warns(FlexmorWarning,
                      match=r"blockC3D10.inp: mass matrix diagonal is not positive at 1 equation.*still work"):
        model = flexmor.io.read(tmp_path / f"{block}.inp")
    assert model.M.diagonal()[0] == 0.0 and np.count_nonzero(model.M.diagonal() <= 0) == 1


def _nearly_singular(M, delta_rel):
    """``M`` with its two smallest eigenvalues replaced by ``delta_rel * ||M||_2`` (symmetric, PD)."""
    mu, U = np.linalg.eigh(M)
    delta = delta_rel * mu[-1]
    Ms = M + (delta - mu[0]) * np.outer(U[:, 0], U[:, 0]) + (delta - mu[1]) * np.outer(U[:, 1], U[:, 1])
    return 0.5 * (Ms + Ms.T)


@pytest.mark.slow
def test_dense_path_ignores_whether_cholesky_fails(clamped):
    """Cholesky of M succeeds with tiny pivots, yet the dense path must not use ``L^-1 K L^-T``.

    The two smallest eigenvalues of the mass are set to 1e-12 ||M||: far above the ~n eps ||M||
    (6e-14 at 270 DOF) by which rounding could move them, so LAPACK's Cholesky succeeds on every
    machine; ``eigh(K, M)`` through that factor loses ~12 digits (on one machine it gave 3.9519e5
    instead of 3.9517e5). ``M phi = mu K phi`` (K positive definite: clamped) is well posed and
    gives the reference ``lambda = 1 / mu`` to ~eps cond(K) / cond-free of M.
    """
    from flexmor.linalg.eigen import MASS_RCOND_MIN, _mass_rcond, dense_eigenmodes

    K = clamped.K.toarray()
    Ms = _nearly_singular(clamped.M.toarray(), 1e-12)
    np.linalg.cholesky(Ms)  # succeeds: this is the branch the old code trusted
    assert _mass_rcond(Ms) < MASS_RCOND_MIN
    ref = np.sort(1.0 / sla.eigh(Ms, K, eigvals_only=True)[-4:])
    for lam in (dense_eigenmodes(K, Ms, 4)[0], eigenmodes(clamped.K, sp.csr_matrix(Ms), 4, method="dense")[0]):
        np.testing.assert_allclose(lam, ref, rtol=1e-9)
    lam_all, phi_all = dense_eigenmodes(K, Ms)  # all finite ones, M-normalized
    np.testing.assert_allclose(lam_all[:4], ref, rtol=1e-9)
    np.testing.assert_allclose(phi_all[:, :4].T @ Ms @ phi_all[:, :4], np.eye(4), atol=1e-10)


def test_dense_path_refuses_an_indefinite_mass(clamped):
    """A mass matrix with a clearly negative eigenvalue: a ModelError, not eigenvalues."""
    from flexmor.errors import ModelError
    from flexmor.linalg.eigen import dense_eigenmodes

    Mi = _nearly_singular(clamped.M.toarray(), -1e-3)
    with pytest.raises(ModelError, match="not positive definite|indefinite"):
        dense_eigenmodes(clamped.K.toarray(), Mi, 4)


def test_dense_residual_check_rejects_a_nonsymmetric_pencil(clamped):
    """A non-symmetric K is not a symmetric definite pencil: the residual check says so."""
    from flexmor.errors import ModelError
    from flexmor.linalg.eigen import dense_eigenmodes

    K = clamped.K.toarray()
    K[0, 1] += 1e-3 * np.abs(K).max()  # eigh reads one triangle: the returned pairs do not solve this K
    with pytest.raises(ModelError, match="relative residual"):
        dense_eigenmodes(K, clamped.M.toarray(), 4)


def test_a_mass_of_one_direction_singular_is_found_block_by_block(tmp_path, clamped):
    """A solid's mass couples no two directions: checked per direction (x, y, z alike: one block of a
    third of the equations); a singular y block alone is found."""
    from flexmor.io._mass import check_mass, direction_blocks

    blocks = direction_blocks(clamped.M, clamped.dofs)
    assert len(blocks) == 1 and blocks[0].shape == (clamped.n_dof // 3,) * 2
    M = clamped.M.toarray()
    y = np.flatnonzero(clamped.dofs[:, 1] == 2)
    mu, U = np.linalg.eigh(M[np.ix_(y, y)])
    My = M[np.ix_(y, y)] - mu[0] * np.outer(U[:, 0], U[:, 0])
    My[np.abs(My) < 1e-12 * np.abs(My).max()] = 0.0
    M[np.ix_(y, y)] = 0.5 * (My + My.T)
    model = flexmor.io.read(_job(tmp_path, M, etype="C3D8"))  # (a linear element: no mass check at read)
    assert len(direction_blocks(model.M, model.dofs)) == 2  # x and z alike, y its own
    with pytest.warns(FlexmorWarning, match="x: the mass matrix is singular"):
        assert check_mass(model, "x") < 1e-12
    coupled = model.M.tolil()
    coupled[0, 1] = coupled[1, 0] = 1e-3 * model.M[0, 0]
    assert len(direction_blocks(coupled.tocsr(), model.dofs)) == 1
