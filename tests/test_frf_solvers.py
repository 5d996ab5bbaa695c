"""Complex symmetric factorizations of K - w^2 M + i w D (PARDISO matrix type 6) and the sweep."""

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import cond1

from flexmor.dynamics.frf import ShiftedMatrices, frf_full
from flexmor.linalg import SolverContext, available_backends, factorize
from flexmor.ports import make_ports

needs_pardiso = pytest.mark.skipif("pardiso" not in available_backends(), reason="needs MKL PARDISO")


def _shifted(model, f_hz, beta=1e-5):
    w = 2 * np.pi * f_hz
    return (model.K - w**2 * model.M + 1j * w * beta * model.K).tocsr()


@needs_pardiso
@pytest.mark.parametrize("f_hz", [0.0, 150.0, 2500.0])  # below, between and above resonances
def test_complex_symmetric_pardiso_matches_scipy(clamped, f_hz):
    A = _shifted(clamped, f_hz)
    rng = np.random.default_rng(3)
    B = rng.standard_normal((clamped.n_dof, 4)) + 1j * rng.standard_normal((clamped.n_dof, 4))
    F = factorize(A, solver=SolverContext("pardiso"))
    assert F.backend == "pardiso" and F._mtype == 6 and F.dtype == np.complex128
    X = F.solve(B)  # one block solve for all columns
    assert np.linalg.norm(A @ X - B) / np.linalg.norm(B) < 1e-10
    scipy = SolverContext("scipy")
    Xs = factorize(A, solver=scipy).solve(B)
    assert np.linalg.norm(X - Xs) / np.linalg.norm(Xs) < 1e-10
    x = F.solve(B[:, 0].real)  # real right-hand side of a complex matrix
    xs = factorize(A, solver=scipy).solve(B[:, 0].real)
    # two solvers: each within ~eps cond(A) of the solution (cond_1(A) 1.5e4 ... 8e5 over these shifts)
    assert np.linalg.norm(x - xs) <= 4 * np.finfo(float).eps * cond1(A) * np.linalg.norm(xs)


@needs_pardiso
@pytest.mark.usefixtures("auto_unrestricted")
def test_auto_picks_pardiso_for_complex_and_real_shift_stays_indefinite(clamped):
    assert factorize(_shifted(clamped, 300.0)).backend == "pardiso"
    w = 2 * np.pi * 300.0
    A = (clamped.K - w**2 * clamped.M).tocsr()  # undamped, between resonances: indefinite
    F = factorize(A)
    assert F.backend == "pardiso" and F._mtype == -2 and F.dtype == np.float64
    b = np.ones(clamped.n_dof)
    assert np.linalg.norm(A @ F.solve(b) - b) / np.linalg.norm(b) < 1e-10


@needs_pardiso
def test_pardiso_memory_is_released(clamped):
    F = factorize(_shifted(clamped, 100.0), solver=SolverContext("pardiso"))
    assert np.any(F._pt)
    F._release()
    assert not np.any(F._pt)
    F._release()  # idempotent


def test_shifted_matrices_equal_sparse_sum(clamped):
    model = clamped.with_rayleigh(2.0, 1e-6)
    S = ShiftedMatrices(model.K, model.M, model.D)
    w = 2 * np.pi * 700.0
    ref = model.K - w**2 * model.M + 1j * w * model.D
    assert abs(S(w) - ref).max() <= 1e-12 * abs(ref).max()
    assert S(w).dtype == np.complex128 and ShiftedMatrices(model.K, model.M)(w).dtype == np.float64
    # patterns that differ (a lumped mass, a damper between two DOFs not coupled in K), unsorted indices
    Ml = sp.diags(np.asarray(model.M.sum(axis=1)).ravel()).tocsr()
    n = model.n_dof
    Dd = sp.csr_matrix(([3.0, -3.0, -3.0, 3.0], ([0, 0, n - 1, n - 1], [0, n - 1, 0, n - 1])), shape=(n, n))
    Dd.indices = Dd.indices.copy()
    Dd.data[:2], Dd.indices[:2] = Dd.data[1::-1].copy(), Dd.indices[1::-1].copy()
    Dd.has_sorted_indices = False
    S = ShiftedMatrices(model.K, Ml, Dd)
    ref = model.K - w**2 * Ml + 1j * w * Dd
    assert S(w).nnz == model.K.nnz + 2 and abs(S(w) - ref).max() <= 1e-12 * abs(ref).max()


@pytest.mark.parametrize("backend", available_backends())
def test_frf_full_one_factorization_per_frequency(clamped, backend):
    if backend == "cholmod":
        pytest.skip("cholmod needs positive definite matrices")
    model = clamped.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    freqs = [20.0, 400.0, 1500.0]
    solver = SolverContext(backend)
    H = frf_full(model, ports, freqs, solver=solver)
    assert solver.stats.count == 3 and solver.stats.solves == 3 and solver.stats.solve_columns == 6
    assert H.shape == (3, 2, 2)
    w = 2 * np.pi * 400.0
    A = (model.K - w**2 * model.M + 1j * w * model.D).tocsr()
    X = factorize(A, solver=SolverContext("scipy")).solve(ports.B.toarray())
    ref = ports.C @ X
    assert np.abs(H[1] - ref).max() / np.abs(ref).max() < 1e-10
    assert np.abs(H[1] - H[1].T).max() < 1e-10 * np.abs(H[1]).max()  # collocated: reciprocity


@needs_pardiso
def test_pardiso_inertia_counts_modes_below_a_shift(clamped, clamped_ref):
    for f_hz in (100.0, 2000.0, 9000.0):
        w = 2 * np.pi * f_hz
        F = factorize((clamped.K - w**2 * clamped.M).tocsr(), solver=SolverContext("pardiso"), check=False)
        assert F.inertia == (clamped.n_dof - np.sum(clamped_ref < f_hz), np.sum(clamped_ref < f_hz))
