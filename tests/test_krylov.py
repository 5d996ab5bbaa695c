"""Second-order Krylov moment matching: exact moments, band error against modal, free bodies."""

import math

import numpy as np
import pytest

from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError
from flexmor.linalg import SolverContext, factorize
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.reduction.krylov import parse_points
from flexmor.workflow import reduce_and_judge


def taylor_moments(M, D, K, B, C, s, k):
    """Moments H_j of H(s + t) = sum_j H_j t^j from the exact recursion of solves (dense or sparse)."""
    A0, A1 = s * s * M + s * D + K, 2 * s * M + D
    if hasattr(A0, "tocsr"):
        solve = factorize(A0.tocsr().astype(complex), solver=SolverContext("scipy"), check=False).solve
    else:
        solve = lambda b: np.linalg.solve(A0, b)  # noqa: E731
    X = [solve(np.asarray(B, dtype=complex))]
    for j in range(1, k):
        X.append(-solve(A1 @ X[-1] + (M @ X[-2] if j > 1 else 0)))
    return [np.asarray(C @ x) for x in X]


@pytest.mark.parametrize("points,k,side", [("0", 4, "input"), ("300j", 3, "input"), ("100,1500j", 3, "both"),
                                           ("-50", 4, "output")])
def test_moment_matching_mimo(clamped, points, k, side):
    model = clamped.with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"], ["TIP:y", "TIP:x"])
    red = reduce(model, "krylov", None, ports, points=points, moments=k, side=side)
    B, C = ports.B.toarray(), ports.C.toarray()
    for p in parse_points(points):
        s = 2 * np.pi * p
        full = taylor_moments(model.M, model.D, model.K, B, C, s, k)
        mine = taylor_moments(red.M, red.D, red.K, red.B, red.C, s, k)
        for j, (a, b) in enumerate(zip(full, mine)):
            # d^j H / ds^j = j! H_j: the derivatives match exactly when the moments do
            rel = np.linalg.norm(math.factorial(j) * (a - b)) / np.linalg.norm(math.factorial(j) * a)
            assert rel < 1e-8, (p, j, rel)


@pytest.mark.slow
def test_krylov_beats_modal_by_10x(clamped):
    model = clamped.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y"])
    full = FullResponse(model, ports, (1.0, 3000.0))
    for r in (6, 10, 16):
        e_mod = reduce_and_judge(model, "modal", r, ports, full=full)[1]["band_error"]
        # for the port alone (the frame's six inertia loads as inputs too would take their share of order 6)
        red, res = reduce_and_judge(model, "krylov", r, ports, full=full, band=(1.0, 3000.0), inertia_loads="off")
        assert red.order <= r
        assert res["band_error"] * 10 <= e_mod, (r, res["band_error"], e_mod)


def test_free_body_krylov_rigid_include_and_exclude(free, free_ref):
    ports = make_ports(free, ["TIP:y", "TIP:z"])
    # singular K: moved to a small shift; rigid="include" (no longer the default) keeps the excited rigid motion
    red = reduce(free, "krylov", 16, ports, points="0", rigid="include")
    f = red.frequencies_hz()
    assert red.order == 16
    assert np.sum(f < 1.0) >= 2  # rigid-body motion the loads excite is kept in the span
    assert abs(f[np.argmax(f > 1.0)] / free_ref[6] - 1) < 1e-3
    red = reduce(free, "krylov", 12, ports, rigid="exclude", band=(10.0, 3000.0))
    f = red.frequencies_hz()
    assert red.info["n_rigid_excluded"] == 6
    assert np.all(f > 0.5 * free_ref[6])
    assert abs(f[0] / free_ref[6] - 1) < 1e-3


def test_krylov_options_are_validated(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    with pytest.raises(OptionError, match="input, output, both"):
        reduce(clamped, "krylov", 4, ports, side="left")
    with pytest.raises(OptionError, match="include, exclude"):
        reduce(clamped, "krylov", 4, ports, rigid="drop")
    with pytest.raises(OptionError, match="points"):
        reduce(clamped, "krylov", 4, ports, points="a,b")
    with pytest.raises(OptionError, match="order or moments"):
        reduce(clamped, "krylov", None, ports)


@pytest.mark.slow
def test_arnoldi_stores_one_n_by_r_basis():
    """Two-level Arnoldi: the 2n-vectors live as coefficients of one n x r basis (memory ~ n r)."""
    import tracemalloc

    from flexmor.models import cantilever
    from flexmor.reduction.arnoldi import SecondOrderArnoldi
    from flexmor.reduction.krylov import shifted_factorization, start_block

    model = cantilever(4).with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:x", "TIP:y", "TIP:z"])
    start = start_block(ports, "input")
    F, s = shifted_factorization(model, 2 * np.pi * 300.0)
    share = 20 * start.shape[1]
    n = model.n_dof
    tracemalloc.start()
    seq = SecondOrderArnoldi(model, F, s, start, capacity=share + start.shape[1])
    while seq.Q.k < share and seq.next_block() is not None:
        pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert seq.Q.k >= share
    Q = seq.Q.view
    assert np.linalg.norm(Q.T @ Q - np.eye(Q.shape[1])) < 1e-12
    # the basis and a few n x b work blocks; 2n-vectors stored explicitly would need 3x the basis
    assert peak < 1.5 * n * (share + start.shape[1]) * 8, (peak, n * share * 8)


@pytest.mark.parametrize("dtype", [float, complex])
def test_arnoldi_orthogonalization_matches_block_gram_schmidt(dtype):
    """The Arnoldi's block CGS2 (coefficients from its projections) against extend_orthonormal.

    Per step the new columns span the same space as :func:`flexmor.basis.extend_orthonormal`
    (largest principal angle < 1e-10), are orthonormal to the basis to round-off, and the
    coefficients equal ``[Q^H top; new^H top]`` to 1e-12 relative, also for columns nearly in
    ``span(Q)``, nearly dependent ones, exactly dependent (deflated) and zero ones.
    """
    import scipy.linalg as sla

    from flexmor.basis import extend_orthonormal
    from flexmor.models import cantilever
    from flexmor.reduction.arnoldi import SecondOrderArnoldi
    from flexmor.reduction.krylov import shifted_factorization, start_block

    model = cantilever(2)
    ports = make_ports(model, ["TIP:x", "TIP:y", "TIP:z"])
    s = 2 * np.pi * (300.0 if dtype is float else 300j)
    F, s = shifted_factorization(model, s)
    seq = SecondOrderArnoldi(model, F, s, start_block(ports, "input"))
    rng = np.random.default_rng(3)
    n = model.n_dof

    def rand(*shape):
        x = rng.standard_normal(shape)
        return x + 1j * rng.standard_normal(shape) if dtype is complex else x

    Q, _ = np.linalg.qr(rand(n, 20))
    seq.Q.append(Q)
    Q = seq.Q.view
    generic = rand(n, 4)
    near = Q @ rand(20, 4) + 1e-6 * rand(n, 4)  # residual 1e-6 of the column: a third pass
    dependent = np.hstack([generic[:, :2], generic[:, :1] + generic[:, 1:2], np.zeros((n, 1))])
    close = np.hstack([generic[:, :2], generic[:, :1] + 1e-5 * generic[:, 2:3]])  # nearly dependent block
    for top in (generic, near, dependent, close, Q @ rand(20, 3)):
        new, t, second = seq._orthogonalize(top)
        new, _ = seq._second_pass(new, second, np.zeros((Q.shape[1], 0), Q.dtype))
        ref = extend_orthonormal(Q, top, tol=seq.tol)
        assert new.shape[1] == ref.shape[1]
        if new.shape[1]:
            assert np.max(sla.subspace_angles(new, ref)) < 1e-10
            assert np.abs(new.conj().T @ new - np.eye(new.shape[1])).max() < 1e-13
            assert np.abs(Q.conj().T @ new).max() < 1e-13
        direct = np.vstack([Q.conj().T @ top, new.conj().T @ top])
        assert np.abs(t - direct).max() < 1e-12 * np.abs(top).max()


@pytest.mark.slow
def test_arnoldi_basis_spans_the_leading_moments():
    """The orthonormal basis of four blocks spans the explicit moments X_0..X_3 (principal angles < 1e-8)."""
    import scipy.linalg as sla

    from flexmor.models import cantilever
    from flexmor.reduction.arnoldi import SecondOrderArnoldi
    from flexmor.reduction.krylov import shifted_factorization, start_block

    model = cantilever(4).with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:x", "TIP:y", "TIP:z"])
    start = start_block(ports, "input")
    for p in (300.0, 300j):
        F, s = shifted_factorization(model, 2 * np.pi * p)
        seq = SecondOrderArnoldi(model, F, s, start)
        for _ in range(4):
            seq.next_block()
        Q = seq.Q.view
        assert np.abs(Q.conj().T @ Q - np.eye(Q.shape[1])).max() < 1e-12
        assert np.abs(seq.U.conj().T @ seq.U - np.eye(seq.U.shape[1])).max() < 1e-12  # the 2n-vectors
        A1 = 2 * s * model.M + model.D
        X = [F.solve(start.astype(Q.dtype))]
        for j in range(1, 4):
            X.append(-F.solve(A1 @ X[-1] + (model.M @ X[-2] if j > 1 else 0)))
        assert Q.shape[1] == 4 * start.shape[1]
        assert np.max(sla.subspace_angles(Q, np.hstack(X))) < 1e-8


def test_one_point_merge_against_the_rigid_head_is_block_gram_schmidt():
    """A single point's blocks merged after the rigid head (one projection and a Cholesky factor)
    span, block by block, what block Gram-Schmidt over all columns spans; without a head the
    merged basis is a view of the Arnoldi basis (no copy)."""
    import scipy.linalg as sla

    from flexmor.models import cantilever
    from flexmor.reduction.free_body import rigid_head
    from flexmor.reduction.krylov import blocks_at_points, merge_blocks, start_block

    model = cantilever(4, clamped=False)
    ports = make_ports(model, ["TIP:x", "TIP:y", "TIP:z"])
    phi, head = rigid_head(model, start_block(ports, "input"), "include")
    blocks, _ = blocks_at_points(model, ports, [300.0], 4, rigid_modes=phi)
    h = head.shape[1]
    fast = merge_blocks(blocks, h + 10, orthonormal=True, head=head)  # the order cuts the fourth block
    slow = merge_blocks([[head]] + blocks, h + 10)
    assert fast.shape == slow.shape == (model.n_dof, h + 10)
    assert np.abs(fast.T @ fast - np.eye(h + 10)).max() < 1e-12
    for k in (h, h + 3, h + 6, h + 9, h + 10):  # the head, block by block, the cut block's leading direction
        assert np.max(sla.subspace_angles(fast[:, :k], slow[:, :k])) < 1e-8, k
    plain = merge_blocks(blocks, 9, orthonormal=True)
    assert np.shares_memory(plain, blocks[0][0]) and np.array_equal(plain, np.hstack(blocks[0])[:, :9])


def test_a_point_on_an_eigenfrequency_is_named(clamped, clamped_ref):
    """An expansion point on the frequency axis exactly at the clamped beam's first eigenfrequency: the shifted
    matrix is singular, and the message says where (it said 'a free-free body needs a shift')."""
    import scipy.linalg as sla

    from flexmor.errors import SolverError

    lam = sla.eigh(clamped.K.toarray(), clamped.M.toarray(), eigvals_only=True, subset_by_index=[0, 0])[0]
    f1 = math.sqrt(lam) / (2 * math.pi)
    with pytest.raises(SolverError, match=r"singular at the expansion point 100\.0459\d* Hz of the undamped body: it "
                                          r"lies at an eigenfrequency"):
        reduce(clamped, "krylov", 8, make_ports(clamped, ["TIP:y"]), points=f"{f1!r}j")
