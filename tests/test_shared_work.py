"""Work the methods share instead of repeating it: the rigid-body check's factorization serves the method
that factorizes the same matrix, Craig-Bampton's inertia-relief modes come from its own ``K_ii``
factorization, and the mass check reads the pivots of one ``L D L^T`` instead of iterating."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.couplings import couple
from flexmor.errors import FlexmorWarning
from flexmor.linalg import SolverContext, available_backends
from flexmor.models import cantilever, plate_structure
from flexmor.ports import make_ports
from flexmor.reduction import check_shift, reduce
from flexmor.reduction.free_body import inertia_relief_modes
from flexmor.reduction.guyan import constraint_modes
from flexmor.rigid import rigid_body_modes
from flexmor.workflow import reduce_and_judge

PARDISO = "pardiso" in available_backends()


@pytest.fixture(scope="module")
def free_plate():
    """The free plate structure (rods and a rigid lower plate) held at its hole by an RBE2: 2,064 DOF."""
    return couple(plate_structure(8, lower="mass"), ["HOLE@rbe2"]).model


@pytest.mark.parametrize("method, order", [("modal", 8)])
def test_check_and_method_share_one_factorization(method, order):
    model = cantilever(4)  # 3,000 DOF: above the dense limit, the check factorizes
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    sigma, keep = check_shift(model, method, {"band": (10.0, 3000.0)})
    assert keep
    bodies, counts = [], []
    for shared in (True, False):
        ctx = SolverContext()
        if not shared:  # the check on its own: its factorization is not kept
            from flexmor.checks import check_rigid_body_modes

            check_rigid_body_modes(model, solver=ctx)
            red = reduce(model, method, order, ports, solver=ctx, **({"band": (10.0, 3000.0)}
                                                                        if method == "krylov" else {}))
        else:
            red, _ = reduce_and_judge(model, method, order, ports, band=None, method_band=(10.0, 3000.0),
                                      solver=ctx)
        bodies.append(red)
        counts.append(ctx.stats.count)
        assert ctx.kept(model.K, model.M, sigma) is None  # released after the reduction
    assert counts == [1, 2]
    np.testing.assert_allclose(bodies[0].frequencies_hz(), bodies[1].frequencies_hz(), rtol=1e-10)


def test_krylov_does_not_keep_the_check_factorization():
    """Krylov's first point is 0 Hz (complex points follow): nothing to share with the check's shift."""
    for model in (cantilever(4), cantilever(4).with_rayleigh(2.0, 1e-6)):
        assert check_shift(model, "krylov", {"band": (10.0, 3000.0)}) == (None, False)
    model = cantilever(4).with_rayleigh(2.0, 1e-6)
    assert check_shift(model, "craig-bampton", {}) == (None, False)


def test_craig_bampton_relief_modes_from_the_interior_factorization(free_plate):
    """The held route (one solve of the rigid-body columns on K_ii) equals the refinement on K - sigma M."""
    V_c, b, i, F = constraint_modes(free_plate, ["HOLE@RBE2"])
    phi = rigid_body_modes(free_plate)
    ref = inertia_relief_modes(free_plate, b, phi=phi)
    held = inertia_relief_modes(free_plate, b, phi=phi, held=(V_c, i, F))
    assert np.linalg.norm(held - ref) <= 1e-9 * np.linalg.norm(ref)
    E = np.zeros((free_plate.n_dof, b.size))
    E[b, np.arange(b.size)] = 1.0
    G = E - free_plate.M @ (phi @ (phi.T @ E))  # the balanced loads
    assert np.linalg.norm(free_plate.K @ held - G) <= 1e-9 * np.linalg.norm(G)
    assert np.abs(phi.T @ (free_plate.M @ held)).max() <= 1e-12 * np.abs(held).max()


def test_craig_bampton_on_a_free_body_makes_one_factorization(free_plate):
    ports = make_ports(free_plate, ["HOLE@RBE2:all"])
    ctx = SolverContext()
    red = reduce(free_plate, "craig-bampton", 20, ports, interface=["HOLE@RBE2"], solver=ctx)
    assert ctx.stats.count == 1  # K_ii: constraint modes, inertia relief and fixed-interface modes
    f = red.frequencies_hz()
    assert f[0] > 0 and red.order == 20


@pytest.mark.skipif(not PARDISO, reason="pardiso (pip install flexmor[fast]): the Cholesky route")
@pytest.mark.parametrize("shift", [0.0, -1e-3])
def test_mass_check_is_one_cholesky(shift):
    """One Cholesky and two inverse iterations: a failed Cholesky or a tiny Rayleigh quotient is warned."""
    from flexmor.io._mass import check_mass

    M = cantilever(2).M.toarray()
    mu, U = np.linalg.eigh(M)
    bad = M + (shift * mu[-1] - mu[0]) * np.outer(U[:, 0], U[:, 0])  # smallest eigenvalue moved to `shift`
    model = SimpleNamespace(M=sp.csr_matrix(0.5 * (bad + bad.T)))
    # pardiso's Cholesky fails on both ("singular or indefinite"); an LU (auto restricted to scipy) goes on to
    # the inverse iterations, whose Rayleigh quotient finds the negative eigenvalue ("indefinite")
    with pytest.warns(FlexmorWarning, match="m: the mass matrix is " + ("singular" if shift == 0 else
                                                                        "(singular or )?indefinite")):
        ratio = check_mass(model, "m")
    assert ratio < 1e-12
    assert check_mass(SimpleNamespace(M=sp.csr_matrix(M)), "m") > 1e-6  # the mass itself: quiet


def test_mkl_workers_sleep_after_a_parallel_region():
    """Set before MKL loads (a user's own setting stays): idle workers do not spin on the cores that the
    products between solves, or other processes, need."""
    import subprocess
    import sys

    code = ("import os; os.environ.pop('KMP_BLOCKTIME', None); import flexmor; "
            "print(os.environ['KMP_BLOCKTIME'])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "0"


def test_a_kept_factorization_is_handed_over():
    """The next computation on the same matrix takes the kept factorization; the context then holds it no
    longer (its memory goes with the last user), and another shift or matrix makes its own."""
    from flexmor.linalg.factorize import factorize_shifted

    model = cantilever(4)
    ctx = SolverContext()
    F = factorize_shifted(model.K, model.M, -1e3, solver=ctx, keep=True)
    assert ctx.kept(model.K, model.M, -1e3) is F and ctx.kept(model.K, model.M, -2e3) is None
    assert factorize_shifted(model.K, model.M, -2e3, solver=ctx) is not F
    assert factorize_shifted(model.K, model.M, -1e3, solver=ctx) is F
    assert ctx.kept(model.K, model.M, -1e3) is None
    assert ctx.stats.count == 2


def test_rigid_body_modes_kept_by_the_model_while_its_matrices_are_the_same():
    import copy

    model = cantilever(3, clamped=False)
    phi = rigid_body_modes(model)
    assert phi.shape[1] == 6 and rigid_body_modes(model) is phi and not phi.flags.writeable
    assert rigid_body_modes(model.with_rayleigh(0.0, 1e-6)) is phi  # damping leaves K, M and geometry
    held = copy.copy(model)
    fixed = np.flatnonzero(model.dofs[:, 0] == model.dofs[0, 0])  # one node held by stiff springs
    held.K = (model.K + sp.csr_matrix((np.full(fixed.size, 1e3 * abs(model.K).max()), (fixed, fixed)),
                                      shape=model.K.shape)).tocsr()
    assert rigid_body_modes(held).shape[1] == 0  # a new K: computed again
    assert rigid_body_modes(model) is phi
