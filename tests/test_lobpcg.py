"""LOBPCG with the AMG V-cycle as preconditioner: the lowest modes where K - sigma M is not factorized."""

import numpy as np
import pytest

from flexmor.errors import ConvergenceError
from flexmor.linalg import SolverContext, factorize
from flexmor.linalg.eigen import default_shift, dense_eigenmodes, eigenmodes
from flexmor.linalg.lobpcg import lobpcg
from flexmor.models import cantilever
from flexmor.rigid import register_near_null

pytest.importorskip("pyamg", reason="the amg backend needs pyamg (pip install 'flexmor[amg]')")


def _amg(model, sigma):
    solver = SolverContext(backend="amg")
    register_near_null(solver, model)
    return solver, factorize((model.K - sigma * model.M).tocsr(), solver=solver, positive=True)


def _subspace_gap(A, B, M):
    """Largest sine of the angles between the M-orthonormal column spaces of A and B."""
    s = np.linalg.svd(A.T @ (M @ B), compute_uv=False)
    return float(np.sqrt(max(0.0, 1.0 - s.min() ** 2)))


@pytest.mark.parametrize("clamped, k", [(True, 12), (False, 14)])
def test_the_modes_are_the_dense_ones_with_the_stated_residual(clamped, k):
    """Clamped (1,536 DOF) and free (six rigid-body modes at zero, negative shift): eigenvalues to 1e-10 of the
    dense solution, M-orthonormal vectors, the residual asked; the space of each whole cluster is the dense one
    (the vectors within a multiple eigenvalue are any basis of it)."""
    model = cantilever(n=3, clamped=clamped)
    sigma = default_shift(model.K, model.M)
    solver, F = _amg(model, sigma)
    lam, phi = lobpcg(model.K, model.M, k, F.matrix, F.precondition, sigma, tol=1e-9, stats=solver.stats)
    lam_d, phi_d = dense_eigenmodes(model.K, model.M, k + 6)
    scale = lam_d[k - 1]
    assert np.max(np.abs(lam - lam_d[:k])) <= 1e-10 * scale
    M = model.M
    assert np.abs(phi.T @ (M @ phi) - np.eye(k)).max() < 1e-12
    R = model.K @ phi - (M @ phi) * lam
    res = np.linalg.norm(R, axis=0) / ((np.abs(lam) + abs(sigma)) * np.linalg.norm(M @ phi, axis=0))
    assert res.max() <= 1e-9 and solver.stats.eigen_residual == pytest.approx(res.max(), rel=0.5)
    assert solver.stats.eigen_iterations > 0
    # clusters (eigenvalues closer than 1e-3 relative) share one space; by Davis-Kahan its angle is at most
    # the residual over the gap to the rest, here 1e-9 / 1e-3 (a cluster the k-th mode cuts is left out)
    edges = [0] + [i for i in range(1, k + 1) if lam_d[i] - lam_d[i - 1] > 1e-3 * scale]
    assert len(edges) > 3
    for a, b in zip(edges[:-1], edges[1:]):
        assert _subspace_gap(phi[:, a:b], phi_d[:, a:b], M) < 1e-5
    if not clamped:
        assert np.all(np.abs(lam[:6]) < 1e-8 * scale)


def test_eigenmodes_takes_lobpcg_under_amg_and_agrees_with_the_direct_backend():
    """``eigenmodes`` with the amg backend runs LOBPCG (no block solves) and returns the direct modes."""
    model = cantilever(n=4)  # 3,000 DOF
    solver = SolverContext(backend="amg")
    register_near_null(solver, model)
    lam, phi = eigenmodes(model.K, model.M, 20, solver=solver)
    lam_d, _ = eigenmodes(model.K, model.M, 20, solver=SolverContext("scipy"))
    assert np.max(np.abs(lam - lam_d) / lam_d) < 1e-10
    st = solver.stats
    assert st.iterative == 1 and st.eigen_iterations > 0 and st.iterations == 0 and st.solves == 0


def test_a_start_block_dependent_to_rounding_is_refilled():
    """The free plate structure with its lower plate as a rigid mass (1,992 DOF with the hole's RBE2 coupled): the
    smoothed random start of 45 columns is dependent to rounding in 5 (its Gram matrix spans 1e-13, the heavy part
    dominates the preconditioned mass); LOBPCG refills the block and returns the direct modes (six rigid-body modes
    at zero, then the elastic ones to 1e-10)."""
    from flexmor.couplings import couple
    from flexmor.models import plate_structure

    model = couple(plate_structure(8, lower="mass"), ["HOLE@rbe2"]).model
    solver = SolverContext(backend="amg")
    register_near_null(solver, model)
    lam, _ = eigenmodes(model.K, model.M, 36, solver=solver)
    lam_d, _ = eigenmodes(model.K, model.M, 36, solver=SolverContext("scipy"))
    assert solver.stats.eigen_iterations > 0
    assert np.all(np.abs(lam[:6]) < 1e-8 * lam_d[6]) and np.all(np.abs(lam_d[:6]) < 1e-8 * lam_d[6])
    assert np.max(np.abs(lam[6:] - lam_d[6:]) / lam_d[6:]) < 1e-10


def test_the_iterations_do_not_grow_with_the_mesh():
    """The V-cycle with the rigid motions is a preconditioner of bounded quality: 3,000 to 19,200 DOF take
    about the same number of iterations (14-18 here); the identity instead needs far more."""
    its = []
    for n in (4, 8):
        model = cantilever(n=n)
        sigma = default_shift(model.K, model.M)
        solver, F = _amg(model, sigma)
        lobpcg(model.K, model.M, 10, F.matrix, F.precondition, sigma, stats=solver.stats)
        its.append(solver.stats.eigen_iterations)
    assert its[1] <= 1.5 * its[0] + 2, its
    model = cantilever(n=4)
    sigma = default_shift(model.K, model.M)
    with pytest.raises(ConvergenceError) as exc:
        lobpcg(model.K, model.M, 10, (model.K - sigma * model.M).tocsr(), lambda R: R, sigma, max_iter=3 * its[0])
    lam, phi = exc.value.result
    assert lam.shape == (10,) and phi.shape == (model.n_dof, 10)
