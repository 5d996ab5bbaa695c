"""The factorization layer and the eigen solver on real FE matrices."""

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import cond1

from flexmor.errors import OptionError, SolverError
from flexmor.linalg import EigenPolicy, SolverContext, available_backends, eigenmodes, factorize

BACKENDS = available_backends()


@pytest.mark.parametrize("backend", BACKENDS)
def test_solve_block_and_vector(clamped, backend):
    K = clamped.K
    rng = np.random.default_rng(1)
    B = rng.standard_normal((K.shape[0], 7))
    F = factorize(K, solver=SolverContext(backend), positive=True)
    assert F.backend == backend
    X = F.solve(B)
    assert np.linalg.norm(K @ X - B) / np.linalg.norm(B) < 1e-10
    x = F.solve(B[:, 0])
    assert x.shape == (K.shape[0],)
    # a single and a block solve may round differently (PARDISO): each is within ~eps cond(K) of
    # the solution (cond_1(K) ~ 8e5: 1.8e-10), measured 1e-12 apart; bit-equal for SuperLU
    tol = 4 * np.finfo(float).eps * cond1(K)
    assert np.linalg.norm(x - X[:, 0]) <= tol * np.linalg.norm(X[:, 0])
    z = F.solve(B[:, 0] + 1j * B[:, 1])
    assert np.linalg.norm(z.real - X[:, 0]) <= tol * np.linalg.norm(X[:, 0])
    assert np.linalg.norm(z.imag - X[:, 1]) <= tol * np.linalg.norm(X[:, 1])


@pytest.mark.skipif(len(BACKENDS) < 2, reason="only one solver backend installed: nothing to compare")
def test_backends_agree(clamped):
    b = np.ones(clamped.n_dof)
    xs = [factorize(clamped.K, solver=SolverContext(name), positive=True).solve(b) for name in BACKENDS]
    for x in xs[1:]:
        assert np.linalg.norm(x - xs[0]) / np.linalg.norm(xs[0]) < 1e-10


def test_complex_shifted_matrix(clamped):
    w = 2 * np.pi * 150.0
    A = (clamped.K - w**2 * clamped.M + 1j * w * 1e-5 * clamped.K).tocsr()
    b = np.ones(clamped.n_dof)
    x = factorize(A).solve(b)
    assert np.linalg.norm(A @ x - b) / np.linalg.norm(b) < 1e-10


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="needs pardiso")
def test_pardiso_reuses_the_ordering_of_a_pattern(clamped):
    """Shifted matrices of one model share a pattern: METIS runs once, every factorization is exact."""
    K, M, D = clamped.K, clamped.M, 1e-5 * clamped.K
    b = np.ones(clamped.n_dof)
    used = []
    pardiso, scipy = SolverContext("pardiso"), SolverContext("scipy")
    for f in (151.0, 377.0, 733.0):
        w = 2 * np.pi * f
        A = (K - w**2 * M + 1j * w * D).tocsr()
        F = factorize(A, solver=pardiso, check=False)
        used.append(F.reused_ordering)
        x = F.solve(b)
        assert np.linalg.norm(A @ x - b) / np.linalg.norm(b) < 1e-10
        x0 = factorize(A, solver=scipy, check=False).solve(b)
        assert np.linalg.norm(x - x0) / np.linalg.norm(x0) < 1e-10
    assert used == [False, True, True] and len(pardiso.orderings) == 1
    assert not factorize(A, solver=SolverContext("pardiso"), check=False).reused_ordering  # a context of its own
    n = K.shape[0]
    E = sp.coo_matrix(([1.0, 1.0], ([0, n - 1], [n - 1, 0])), shape=(n, n))
    A = (K - (2 * np.pi * 151.0) ** 2 * M + 1e-3 * abs(K).max() * E).tocsr()  # one more entry: a near pattern
    G = factorize(A, solver=pardiso, check=False)
    assert G.reused_ordering and len(pardiso.orderings) == 1
    assert np.linalg.norm(A @ G.solve(b) - b) / np.linalg.norm(b) < 1e-10
    E = sp.diags([np.ones(n - 7)], [7])  # an entry more in most rows: another pattern
    A = (K - (2 * np.pi * 151.0) ** 2 * M + 1e-3 * abs(K).max() * (E + E.T)).tocsr()
    G = factorize(A, solver=pardiso, check=False)
    assert not G.reused_ordering and len(pardiso.orderings) == 2
    assert np.linalg.norm(A @ G.solve(b) - b) / np.linalg.norm(b) < 1e-10


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="needs pardiso")
def test_pardiso_symmetric_types_share_one_ordering(clamped):
    """``K + s M`` (Cholesky), ``K - w^2 M`` (indefinite) and ``K - w^2 M + i w D`` (complex) are ordered once,
    without weighted matching, and solve as SciPy does; a saddle-point matrix, whose zero pivots need the
    matching, is factorized again with it."""
    K, M = clamped.K, clamped.M
    w = 2 * np.pi * 377.0
    b = np.random.default_rng(3).standard_normal(clamped.n_dof)
    ctx = SolverContext("pardiso")
    seen = []
    for A, positive in (((K + 1e4 * M).tocsr(), True), ((K - w**2 * M).tocsr(), False),
                        ((K - w**2 * M + 1j * w * 1e-5 * K).tocsr(), False)):
        F = factorize(A, solver=ctx, positive=positive, check=False)
        seen.append((F.reused_ordering, F.matching))
        x, x0 = F.solve(b), factorize(A, solver=SolverContext("scipy"), check=False).solve(b)
        assert np.linalg.norm(x - x0) <= 1e-10 * np.linalg.norm(x0)
    assert seen == [(False, False), (True, False), (True, False)] and len(ctx.orderings) == 1
    # three DOFs held by Lagrange multipliers: [[K - w^2 M, C^T], [C, 0]] (a zero diagonal)
    n = K.shape[0]
    C = sp.csr_matrix((np.full(3, abs(K).max()), (np.arange(3), [10, 40, 70])), shape=(3, n))
    A = sp.bmat([[K - w**2 * M, C.T], [C, sp.diags(np.full(3, 1e-300))]]).tocsr()
    bb = np.concatenate([b, np.zeros(3)])
    F = factorize(A, solver=ctx, check=False)
    assert F.matching and not F.reused_ordering
    assert np.linalg.norm(A @ F.solve(bb) - bb) <= 1e-10 * np.linalg.norm(bb)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_matrix_is_refused(free, backend):
    with pytest.raises(SolverError, match="singular"):
        factorize(free.K, solver=SolverContext(backend))


def test_unknown_backend_lists_choices():
    with pytest.raises(OptionError, match="pardiso"):
        SolverContext(backend="nonsense")
    with pytest.raises(OptionError, match="SolverContext"):
        factorize(sp.identity(3, format="csr"), solver="scipy")


def test_lanczos_matches_dense(free):
    lam_dense, _ = eigenmodes(free.K, free.M, 12)
    solver = SolverContext(eigen=EigenPolicy(dense_limit=10))
    lam, phi = eigenmodes(free.K, free.M, 12, solver=solver)
    assert solver.stats.count == 1  # the shift-invert path: one factorization of K - sigma M
    np.testing.assert_allclose(lam[6:], lam_dense[6:], rtol=1e-9)
    assert np.all(np.abs(lam[:6]) < 1e-6 * lam[6])  # rigid-body modes
    np.testing.assert_allclose(phi.T @ (free.M @ phi), np.eye(12), atol=1e-9)


def test_sparse_dense_rows_over_threads_equal_scipys_product():
    from flexmor.linalg.threads import sparse_dense

    rng = np.random.default_rng(3)
    A = sp.random(3000, 3000, density=0.01, format="csr", random_state=4) + sp.eye(3000, format="csr")
    X = rng.standard_normal((3000, 200))
    ref = A @ X
    for threads in (1, 2, 3):
        assert np.array_equal(sparse_dense(A, X, threads), ref)  # the same sums in the same order
    assert np.array_equal(sparse_dense(A.tocsc(), X, 2), A.tocsc() @ X)


@pytest.mark.parametrize("order,kind", [("C", "real"), ("F", "real"), ("C", "complex"), ("F", "complex"),
                                        ("C", "vector")])
def test_mkl_sparse_product_within_rounding_of_scipys(order, kind):
    """MKL's sparse times dense: SciPy's product up to the order of each row's sums (the bound
    ``nnz_row eps |A| |X|``), in the order of ``X``, the same bytes in every call."""
    from flexmor.linalg.mkl_sparse import mkl_product
    from flexmor.linalg.threads import sparse_dense

    rng = np.random.default_rng(5)
    n = 20000
    offsets = [0, 1, -1, 37, -37, 401, -401, 5003, -5003]
    if kind == "vector":  # one column: enough entries to go to MKL
        offsets += [s * k for k in range(2, 30) for s in (1, -1) if k != 37]
    A = sp.diags([rng.standard_normal(n - abs(k)) for k in offsets], offsets, format="csr")
    A.sum_duplicates()
    shape = (n,) if kind == "vector" else (n, 60)
    X = rng.standard_normal(shape) + (1j * rng.standard_normal(shape) if kind == "complex" else 0)
    X = np.asarray(X, order=order)
    Y = mkl_product(A, X)
    if Y is None:
        pytest.skip("no MKL (pypardiso's mkl wheel) in this environment")
    ref = A @ X
    absA = abs(A)
    bound = np.diff(A.indptr).max() * np.finfo(float).eps * (absA @ np.abs(X.real) + absA @ np.abs(X.imag))
    assert Y.shape == ref.shape and Y.dtype == ref.dtype and np.all(np.abs(Y - ref) <= bound)
    assert np.array_equal(Y, mkl_product(A, X)) and np.array_equal(sparse_dense(A, X), Y)
    if kind == "real":
        assert Y.flags[f"{order}_CONTIGUOUS"]
    assert mkl_product(A.tocsc(), X) is None and mkl_product(A.astype(complex), X) is None  # SciPy's then
    assert mkl_product(A[:50, :50], X[:50]) is None  # small: SciPy's


_SLEEP_PROBE = ("import numpy, json, os; numpy.ones((300, 300)) @ numpy.ones((300, 300)); "
                "from flexmor.linalg import threads as t; "
                "print(json.dumps([t._TIMEOUTS, t.blas_idle_sleeps(), t.dense_threads(t.DENSE_PARALLEL_MIN), "
                "t.cores()]))")


def _probe(env_extra: dict) -> list:
    import json
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", _SLEEP_PROBE], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_idle_blas_workers_sleep_after_numpy_loaded_first():
    """NumPy (and its OpenBLAS, with its threads started) before flexmor: the timeout is set afterwards."""
    from flexmor.linalg.threads import BLAS_TIMEOUT, _handles

    if not _handles():
        pytest.skip("no OpenBLAS library loaded (NumPy built against another BLAS)")
    timeouts, sleeps, dense, cores = _probe({})
    assert timeouts and all(t == BLAS_TIMEOUT for t in timeouts)
    assert sleeps and dense == cores


def test_a_users_blas_timeout_is_kept():
    """A timeout the user set stays; above QUICK_TIMEOUT the tall-skinny products keep to one thread."""
    from flexmor.linalg.threads import QUICK_TIMEOUT, _handles

    if not _handles():
        pytest.skip("no OpenBLAS library loaded (NumPy built against another BLAS)")
    timeouts, sleeps, dense, _ = _probe({"OPENBLAS_THREAD_TIMEOUT": str(QUICK_TIMEOUT + 4)})
    assert timeouts and all(t == QUICK_TIMEOUT + 4 for t in timeouts)
    assert not sleeps and dense == 1
    timeouts, sleeps, _, _ = _probe({"OPENBLAS_THREAD_TIMEOUT": "6"})
    assert all(t == 6 for t in timeouts) and sleeps
