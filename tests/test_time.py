"""Time integration (Newmark, generalized-α) against closed-form and matrix-exponential solutions."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from helpers import cond1

from flexmor.dynamics.time import impulse, scheme_parameters, simulate, sine_sweep, step, time_errors
from flexmor.errors import OptionError
from flexmor.ports import make_ports
from flexmor.reduction import reduce

W = 2 * np.pi * 1.0  # 1 Hz oscillator
SDOF = (np.eye(1), None, np.eye(1) * W ** 2, np.ones((1, 1)), np.ones((1, 1)))


def _chain(n=3, k=1000.0, m=1.0, c=0.5):
    """Spring-mass chain fixed at one end (sparse), unit force on the last mass, Rayleigh-like D."""
    K = sp.diags([2 * k * np.ones(n), -k * np.ones(n - 1), -k * np.ones(n - 1)], [0, 1, -1]).tolil()
    K[n - 1, n - 1] = k
    K = K.tocsr()
    M = sp.identity(n, format="csr") * m
    D = (c * M + 1e-4 * K).tocsr()
    B = np.zeros((n, 1))
    B[-1] = 1.0
    return M, D, K, B, sp.csr_matrix(B.T)


def _exact_step(M, D, K, B, C, t):
    """Step response of the first-order form, exact via the matrix exponential of the augmented system."""
    M, D, K = (X.toarray() for X in (M, D, K))
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ D]])
    b = np.vstack([np.zeros((n, 1)), Mi @ B])
    aug = np.zeros((2 * n + 1, 2 * n + 1))
    aug[:2 * n, :2 * n], aug[:2 * n, 2 * n:] = A, b
    e0 = np.zeros(2 * n + 1)
    e0[-1] = 1.0
    Cd = C.toarray()
    return np.array([(Cd @ (sla.expm(aug * tk) @ e0)[:n]) for tk in t])


def test_newmark_sdof_is_the_exact_discrete_solution_with_known_period_elongation():
    h = 1e-2
    r = simulate(SDOF, step(), dt=h, t_end=2.0)
    y = r.displacement[:, 0, 0] * W ** 2  # normalized by the static deflection
    w_bar = 2 / h * np.arctan(W * h / 2)  # trapezoidal rule: omega_bar h = 2 arctan(omega h / 2)
    assert np.max(np.abs(y - (1 - np.cos(w_bar * r.t)))) < 1e-12
    # period elongation dT/T = (omega h)^2 / 12 to second order
    assert (W / w_bar - 1) == pytest.approx((W * h) ** 2 / 12, rel=1e-3)
    assert r.n_factorizations == 0 and r.seconds > 0
    # the velocity and acceleration outputs follow the same discrete solution
    assert np.max(np.abs(r.acceleration[:, 0, 0] - np.cos(w_bar * r.t))) < 1e-9


def test_newmark_sdof_matches_closed_form_to_1e6():
    r = simulate(SDOF, step(), dt=2e-4, t_end=1.0)
    y = r.displacement[:, 0, 0] * W ** 2
    assert np.max(np.abs(y - (1 - np.cos(W * r.t)))) < 1e-6
    assert r.t[-1] == pytest.approx(1.0)


def test_generalized_alpha_with_rho_one_is_newmark():
    M, D, K, B, C = _chain()
    a = simulate((M, D, K, B, C), step(), dt=2e-3, t_end=0.5, scheme="newmark")
    g = simulate((M, D, K, B, C), step(), dt=2e-3, t_end=0.5, scheme="generalized-alpha", rho_inf=1.0)
    scale = np.max(np.abs(a.displacement))
    assert np.max(np.abs(a.displacement - g.displacement)) < 1e-12 * scale
    assert np.max(np.abs(a.acceleration - g.acceleration)) < 1e-10 * np.max(np.abs(a.acceleration))
    p = scheme_parameters("generalized-alpha", 0.0)
    assert (p["alpha_m"], p["alpha_f"], p["gamma"], p["beta"]) == pytest.approx((-1.0, 0.0, 1.5, 1.0))


@pytest.mark.parametrize("scheme", ["newmark", "generalized-alpha"])
def test_sparse_chain_against_matrix_exponential_second_order(scheme):
    M, D, K, B, C = _chain()
    errs = []
    for h in (4e-3, 2e-3):
        r = simulate((M, D, K, B, C), step(), dt=h, t_end=0.4, scheme=scheme, rho_inf=0.7)
        assert r.n_factorizations == 2  # effective matrix + M for the initial acceleration
        ex = _exact_step(M, D, K, B, C, r.t[::10])[:, 0]
        errs.append(np.max(np.abs(r.displacement[::10, 0, 0] - ex)) / np.max(np.abs(ex)))
    assert errs[1] < 2e-3
    assert 3.3 < errs[0] / errs[1] < 4.7  # second order


def test_block_over_inputs_equals_separate_runs(clamped):
    model = clamped.with_rayleigh(0.0, 1e-5)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    u = sine_sweep(10, 500, 0.02)
    blk = simulate(model, u, dt=1e-4, t_end=0.02, ports=ports)
    assert blk.displacement.shape == (201, 2, 2) and blk.n_factorizations == 1  # u(0) = 0: no M solve
    t = blk.t
    one = simulate(model, np.column_stack([np.zeros_like(t), u(t)]), dt=1e-4, t_end=0.02, ports=ports)
    assert one.displacement.shape == (201, 2, 1)
    # block and single-column solves with S = M + gamma h D + beta h^2 K round differently; Newmark
    # does not amplify errors, so 200 steps differ by at most ~ 200 eps cond(S) (cond_1 ~ 2.1e3: 9e-11)
    p = scheme_parameters("newmark")
    S = model.M + p["gamma"] * 1e-4 * model.D + p["beta"] * 1e-8 * model.K
    tol = (t.size - 1) * np.finfo(float).eps * cond1(S)
    assert np.abs(one.displacement[:, :, 0] - blk.displacement[:, :, 1]).max() <= tol * np.abs(blk.displacement).max()
    # bending in z barely moves the tip in y: the cross term is small but the direct one is not
    assert np.abs(blk.displacement[:, 0, 1]).max() < 1e-6 * np.abs(blk.displacement[:, 1, 1]).max()


def test_full_vs_modal_error_decreases_with_order_within_truncation_bound(clamped):
    """Newmark of the full model equals Newmark of all its modes, so the difference to the
    modal body is the discrete response of the truncated modes, bounded by 2 sum |c_k b_k| / w_k^2."""
    model = clamped.with_rayleigh(0.0, 1e-5)
    ports = make_ports(model, ["TIP:y"])
    lam, phi = sla.eigh(model.K.toarray(), model.M.toarray())
    cb = np.abs((ports.C @ phi).ravel() * (ports.B.T @ phi).ravel()) / lam
    f1 = np.sqrt(lam[0]) / (2 * np.pi)
    dt, t_end = 1 / (200 * f1), 3 / f1
    full = simulate(model, step(), dt=dt, t_end=t_end, ports=ports)
    peak = np.max(np.abs(full.displacement))
    assert 1.9 * np.sum(cb) < peak <= 2 * np.sum(cb)  # light damping: overshoot to nearly 2x static
    errs = []
    for r in (5, 10, 20):
        red = reduce(model, "modal", r, ports)
        e = time_errors(full, simulate(red, step(), dt=dt, t_end=t_end))
        assert e["time_max_error"] <= 2 * np.sum(cb[r:]) / peak
        assert e["time_max_error"] > 0.2 * np.sum(cb[r:]) / peak  # the bound is not vacuous
        errs.append(e)
    assert errs[0]["time_mean_error"] > errs[1]["time_mean_error"] > errs[2]["time_mean_error"]
    assert errs[2]["time_max_error"] < 2e-4


def test_signals():
    t = np.linspace(0, 0.02, 20001)
    assert np.trapezoid(impulse(0.01, 2.5)(t), t) == pytest.approx(2.5, rel=1e-6)
    assert step(3.0, rise=0.01)(np.array([0.005, 0.02])) == pytest.approx([1.5, 3.0])
    s = sine_sweep(100, 200, 1.0)
    # phase 2 pi (100 t + 50 t^2) = pi at the first zero crossing
    tt = np.linspace(1e-5, 0.008, 80000)
    assert tt[np.argmax(s(tt) < 0)] == pytest.approx((-100 + np.sqrt(100 ** 2 + 100)) / 100, rel=1e-4)
    with pytest.raises(OptionError, match="newmark"):
        simulate(SDOF, step(), dt=0.1, t_end=1, scheme="euler")
    with pytest.raises(OptionError, match="samples"):
        simulate(SDOF, np.ones(5), dt=0.1, t_end=1)


@pytest.mark.parametrize("scheme", ["newmark", "generalized-alpha"])
@pytest.mark.parametrize("multi", [False, True])
def test_dense_one_step_map_equals_the_sparse_step_loop(scheme, multi):
    # the same body as dense matrices (one-step map) and sparse ones (factorized loop), from a
    # non-zero initial state, each input in turn or all at once: equal to round-off
    rng = np.random.default_rng(3)
    n = 12
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    M = np.eye(n) + 0.2 * np.diag(rng.random(n))
    D = 0.3 * M + 2e-3 * K + 1e-3 * np.triu(np.ones((n, n))) @ np.triu(np.ones((n, n))).T  # not proportional
    B, C = rng.standard_normal((n, 2)), rng.standard_normal((3, n))
    u = (lambda t: np.column_stack([np.sin(40 * t), step()(t)])) if multi else sine_sweep(5, 80, 0.3)
    q0, v0 = rng.standard_normal(n), rng.standard_normal(n)
    kw = {"dt": 1e-3, "t_end": 0.3, "scheme": scheme, "rho_inf": 0.6, "q0": q0, "v0": v0}
    dense = simulate((M, D, K, B, C), u, **kw)
    sparse = simulate(tuple(sp.csr_matrix(X) for X in (M, D, K)) + (B, sp.csr_matrix(C)), u, **kw)
    assert dense.displacement.shape == (301, 3, 1 if multi else 2)
    for qty in ("displacement", "velocity", "acceleration"):
        y, ys = dense.output(qty), sparse.output(qty)
        assert np.abs(y - ys).max() <= 1e-9 * np.abs(ys).max(), qty


def test_rayleigh_products_equal_the_damping_matrix_products(clamped):
    # a Rayleigh model steps with K (x + beta y) + alpha M y; the same matrices given as a tuple
    # step with K x + D y: equal to round-off
    model = clamped.with_rayleigh(20.0, 1e-5)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    kw = {"dt": 1e-4, "t_end": 0.01, "scheme": "generalized-alpha", "rho_inf": 0.8}
    fast = simulate(model, step(), ports=ports, **kw)
    plain = simulate((model.M, model.D, model.K, ports.B, ports.C), step(), **kw)
    assert np.abs(fast.displacement - plain.displacement).max() <= 1e-10 * np.abs(plain.displacement).max()
    assert np.abs(fast.displacement).max() > 0



def test_mkl_threads_sets_and_restores_the_calling_threads_count(clamped):
    from flexmor.linalg import available_backends, factorize
    from flexmor.linalg.threads import _mkl_set_local, mkl_threads

    if "pardiso" not in available_backends():
        pytest.skip("pardiso not available")
    factorize(clamped.K, symmetric=True, positive=True)  # loads MKL
    set_local = _mkl_set_local()
    assert set_local is not None
    before = set_local(0)  # the local count in force (0: none, the global one applies)
    with mkl_threads(1):
        assert set_local(1) == 1  # set_local returns the count it replaces
    assert set_local(before) == 0


@pytest.mark.parametrize("kwargs, words", [
    (dict(dt=1e-3, t_end=3e-4), "t_end 0.0003 s is shorter than one step dt 0.001 s"),  # it ran one step to 1e-3
    (dict(dt="x", t_end=1.0), "dt and t_end are times in s (numbers), got dt='x'"),
    (dict(dt=1e-4, t_end=1e-3, q0=np.ones(5)), "q0 must have 270 rows (one per equation of the system), got shape"),
])
def test_time_arguments_are_checked(clamped, kwargs, words):
    with pytest.raises(OptionError) as exc:
        simulate(clamped, step(), ports=make_ports(clamped, ["TIP:y"]), **kwargs)
    assert words in str(exc.value)


def test_a_run_whose_records_do_not_fit_is_refused_before_it_starts(clamped, monkeypatch):
    """dt = 1e-12 s over 0.01 s: 1e10 steps whose records need 229 GB (numpy's MemoryError, and the CLI said
    'out of memory ... try --factor-memory mixed')."""
    import flexmor.linalg.resources as resources

    monkeypatch.setattr(resources, "memory_available", lambda: 16 * 2.0 ** 30)
    with pytest.raises(OptionError, match=r"t_end / dt = 0.01 s / 1e-12 s = 10,000,000,000 steps: the recorded "
                                          r"responses need \d+ MB, more than half the memory available"):
        simulate(clamped, step(), ports=make_ports(clamped, ["TIP:y"]), dt=1e-12, t_end=0.01)
