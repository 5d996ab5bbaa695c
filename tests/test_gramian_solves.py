"""The solves of the Gramian quadrature: dense modal form and verified surrogate against direct solves."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError
from flexmor.linalg import available_backends
from flexmor.model import FEModel
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction.gramian_solves import DENSE_GRAMIAN_MAX_DOF, SURROGATE_GRAMIAN_TOL, choose_solves
from flexmor.reduction.gramians import gramian_factors
from flexmor.workflow import reduce_and_judge

BAND = (50.0, 700.0)
SOLVES = ("direct", "dense", "surrogate")


def _rel(a, b):
    P, Q = a @ a.T, b @ b.T
    return np.abs(P - Q).max() / np.abs(Q).max()


def _freqs(red):
    """Eigenvalues of the reduced body above the rigid-body range, ascending."""
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(red.M, red.K)).real)
    return lam[lam > 1e-6 * lam.max()]


@pytest.fixture(scope="module")
def beam(clamped):
    model = clamped.with_rayleigh(0.0, 1e-6)
    return model, make_ports(model, ["TIP:y", "TIP:z"])


@pytest.fixture(scope="module")
def factors(beam):
    model, ports = beam
    return {s: gramian_factors(model, ports, BAND, solves=s) for s in SOLVES}


def test_gramians_of_every_solves_equal_the_direct_ones(factors):
    ref = factors["direct"]
    assert ref.info["solves"] == {"solves": "direct"}
    for s in ("dense", "surrogate"):
        G = factors[s]
        assert G.info["solves"]["solves"] == s and G.info["n_nodes"] == ref.info["n_nodes"]
        # measured: 7.9e-10 both (round-off of the direct solves at the lightly damped peaks; the
        # surrogate's state error at its checks is below 1e-9)
        for a, b in ((G.R, ref.R), (G.Rv, ref.Rv), (G.L, ref.L)):
            assert _rel(a, b) < 1e-8, s


def test_surrogate_solves_report_their_checks(beam, factors):
    model, _ = beam
    info = factors["surrogate"].info["solves"]
    # two passing checks in a row, and the node of the largest residual checked with the final basis
    # (here one of the two: its result is reused instead of a third factorization at the same node)
    assert info["verified"] is True and info["n_direct_checks"] >= 2
    assert info["n_direct_checks"] >= 3 or info["final_check_reused"] is True
    assert info["final_check"]["order"] == info["order"]
    assert info["final_check"]["rel_error"] <= SURROGATE_GRAMIAN_TOL
    assert info["max_check_error"] <= SURROGATE_GRAMIAN_TOL
    assert 0 < info["max_residual_on_grid"] < 1e-2 and info["order"] < model.n_dof // 4
    assert factors["dense"].info["solves"]["order"] == model.n_dof


@pytest.mark.slow
@pytest.mark.parametrize("method, order", [("fw-sobt", 4), ("pod", 4)])
def test_methods_give_the_same_body_with_every_solves(beam, method, order):
    model, ports = beam
    full = FullResponse(model, ports, BAND, cache=False)
    out = {}
    for s in SOLVES:
        red, res = reduce_and_judge(model, method, order, ports, full=full, band=BAND, solves=s)
        out[s] = _freqs(red), res["band_error"]
    f0, e0 = out["direct"]
    assert 1e-10 < e0 < 1e-2  # far above the round-off floor of the error check
    for s in ("dense", "surrogate"):
        f, e = out[s]
        # measured: frequencies 2.5e-12 relative, band_error 7e-9 relative (band_error 6.8e-8)
        assert f.size == f0.size and np.abs(f / f0 - 1).max() < 1e-9, s
        assert abs(e / e0 - 1) < 1e-5, s


@pytest.mark.slow
def test_free_body_flexible_gramians_agree(free):
    model = free.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    out = {}
    for s in SOLVES:  # rigid="include" (the default excludes it): the rigid head must agree too
        red, res = reduce_and_judge(model, "fw-sobt", 6, ports, band=BAND, solves=s, rigid="include")
        out[s] = _freqs(red), res["band_error"], red.info["n_rigid_included"]
    f0, e0, k0 = out["direct"]
    for s in ("dense", "surrogate"):
        f, e, k = out[s]
        assert k == k0 > 0 and f.size == f0.size and 1e-10 < e0 < 1e-2
        # measured: frequencies 1.2e-13, band_error 2.8e-9 relative (band_error 4.0e-5)
        assert np.abs(f / f0 - 1).max() < 1e-8 and abs(e / e0 - 1) < 1e-4, s


def test_auto_choice_and_bad_choice():
    small = cantilever(divisions=(5, 2, 2))
    large = cantilever(n=2)
    assert small.n_dof <= DENSE_GRAMIAN_MAX_DOF < large.n_dof
    assert choose_solves("auto", small, np.inf) == "dense"
    assert choose_solves("auto", large, 3000.0) == "surrogate"
    # the full band: the surrogate up to a cutoff when the tail has a bound (Rayleigh beta > 0; an
    # undamped model gets such a damping for its Gramians), else one factorization per node
    assert choose_solves("auto", large, np.inf) == "surrogate"
    assert choose_solves("auto", large.with_rayleigh(1.0, 1e-6), np.inf) == "surrogate"
    assert choose_solves("auto", large.with_rayleigh(1.0, 0.0), np.inf) == "direct"
    given = FEModel(M=large.M, K=large.K, D=large.M * 2.0, dofs=large.dofs, node_ids=large.node_ids, xyz=large.xyz,
                    node_sets=large.node_sets)
    assert choose_solves("auto", given, np.inf) == "direct"
    assert choose_solves("direct", small, 3000.0) == "direct"
    with pytest.raises(OptionError, match="solves"):
        choose_solves("fast", small, 3000.0)


@pytest.mark.slow
def test_non_proportional_damping(beam):
    # a damper at the tip: Phi^T D Phi is not diagonal; dense solves fall back to direct ones,
    # the surrogate solves the small projected systems and agrees with them
    model, ports = beam
    tip = ports.B.toarray()[:, 0] != 0
    d = np.zeros(model.n_dof)
    d[tip] = 50.0
    damped = FEModel(M=model.M, K=model.K, D=model.D + sp.diags(d), dofs=model.dofs, node_ids=model.node_ids,
                     xyz=model.xyz, node_sets=model.node_sets)
    G = {s: gramian_factors(damped, ports, BAND, solves=s) for s in SOLVES}
    assert G["dense"].info["solves"]["solves"] == "direct"
    assert G["surrogate"].info["solves"]["verified"] is True
    assert _rel(G["surrogate"].R, G["direct"].R) < 1e-8 and _rel(G["surrogate"].L, G["direct"].L) < 1e-8


@pytest.mark.slow
def test_full_frf_auto_path_of_mid_size_models():
    # 810 DOF: damped models take the verified surrogate (measured 0.17 s against 0.32 s dense),
    # modal damping keeps the dense path (its ratio exact in every mode)
    from flexmor.damping import modal_damping

    model = cantilever(divisions=(30, 2, 2))
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    band = (10.0, 3000.0)
    rayleigh = model.with_rayleigh(0.0, 1e-6)
    auto = FullResponse(rayleigh, ports, band, cache=False)
    dense = FullResponse(rayleigh, ports, band, cache=False, path="dense")
    assert model.n_dof == 810 and auto.grid["path"] == "surrogate" and auto.grid["surrogate"]["verified"]
    modal = model.with_damping(modal_damping(0.01, band))
    assert FullResponse(modal, ports, band, cache=False).grid["path"] == "dense"
    red, _ = reduce_and_judge(rayleigh, "modal", 6, ports, full=dense, band=band)
    e_auto, e_dense = auto.evaluate(red).band_error, dense.evaluate(red).band_error
    # measured: 1.2722730e-5 on both grids, 2.4e-9 relative
    assert 1e-8 < e_dense < 1 and abs(e_auto / e_dense - 1) < 1e-6, (e_auto, e_dense)


def test_full_band_surrogate_ends_at_the_cutoff_and_bounds_the_rest(clamped):
    # sobt's full band: the surrogate up to the cutoff, the tail above bounded; 270 DOF, so the
    # exact full-band trace sum_j |phi_j^T B|^2 / (2 d_j lam_j) is at hand from all modes
    from flexmor.linalg.eigen import dense_eigenmodes

    model = clamped.with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    G = gramian_factors(model, ports, (0.0, np.inf), cutoff=7000.0, solves="surrogate")
    tail = G.info["solves"]["tail"]
    assert G.info["solves"]["verified"] is True and 6900 < tail["cutoff_hz"] <= 7000 and G.info["collocated"]
    lam, phi = dense_eigenmodes(model.K.toarray(), model.M.toarray())
    b2 = ((phi.T @ ports.B.toarray()) ** 2).sum(1)
    d = 5.0 + 1e-6 * lam
    for X, exact, name in ((G.R, (b2 / (2 * d * lam)).sum(), "position"), (G.Rv, (b2 / (2 * d)).sum(), "velocity")):
        share = 1 - np.einsum("ij,ij->", X, model.M @ X) / exact
        # measured: position 3.343e-5 bounded by 3.352e-5, velocity 3.41e-3 by 3.68e-3
        assert 0 < share <= tail[name] < 1.1 * share, name


@pytest.mark.slow
def test_sobt_full_band_surrogate_equals_direct_to_its_tail(clamped):
    model = clamped.with_rayleigh(5.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    full = FullResponse(model, ports, BAND, cache=False)
    out = {}
    for s in ("direct", "surrogate"):
        red, res = reduce_and_judge(model, "sobt", 6, ports, full=full, band=BAND, cutoff=7000.0, solves=s)
        out[s] = _freqs(red), res["band_error"], red.info
    (f0, e0, i0), (f, e, info) = out["direct"], out["surrogate"]
    assert i0["solves"] == {"solves": "direct"} and info["solves"]["solves"] == "surrogate"
    assert info["n_nodes"] < i0["n_nodes"]  # the direct path's tail cell beyond the cutoff is not solved
    # measured: frequencies 1.3e-7, band_error 1.0e-3 relative (band_error 8.3e-8; tail 3.4e-5 of the trace)
    assert 1e-10 < e0 < 1e-2 and np.abs(f / f0 - 1).max() < 1e-5 and abs(e / e0 - 1) < 1e-2


def test_collocated_ports_share_one_gramian_and_pod_equals_fw_sobt(beam):
    # C = B^T: Q_p = P_p from the same solves, and the balanced subspace span(R Z_r) of
    # L^T M R = R^T M R is the M-weighted POD subspace of R: pod and fw-sobt give one body
    model, ports = beam
    G = gramian_factors(model, ports, BAND, solves="surrogate")
    assert G.info["collocated"] is True and G.L is G.R
    bodies = {}
    for method in ("pod", "fw-sobt"):
        red, res = reduce_and_judge(model, method, 4, ports, band=BAND)
        bodies[method] = _freqs(red), res["band_error"]
    (fp, ep), (fb, eb) = bodies["pod"], bodies["fw-sobt"]
    # measured: frequencies 1.9e-12, band_error 6.3e-9 relative (band_error 6.8e-8)
    assert np.abs(fp / fb - 1).max() < 1e-9 and abs(ep / eb - 1) < 1e-6
    other = make_ports(model, ["TIP:y", "TIP:z"], ["TIP:x", "TIP:z"])  # not collocated: P_p != Q_p
    G2 = gramian_factors(model, other, BAND, solves="surrogate")
    # the factors' ranks come from a compression tolerance, so they may differ by a column
    assert G2.info["collocated"] is False and G2.L.shape[0] == model.n_dof
    assert G2.L.shape != G2.R.shape or not np.allclose(G2.L, G2.R)


@pytest.mark.parametrize("proportional", [True, False])
def test_surrogate_residuals_equal_the_full_ones(beam, proportional):
    # the residuals from the Gram matrix (one GEMM per chunk of frequencies, modal or not)
    # against ||A(w) V x(w) - B|| / ||B|| formed in the full space
    from flexmor.dynamics.frf import ShiftedMatrices
    from flexmor.dynamics.modes import modes_below
    from flexmor.dynamics.surrogate import Surrogate
    from flexmor.linalg.context import as_solver

    model, ports = beam
    if not proportional:  # a damper at the tip: no diagonal modal form of the surrogate
        d = np.zeros(model.n_dof)
        d[ports.B.toarray()[:, 0] != 0] = 50.0
        model = FEModel(M=model.M, K=model.K, D=model.D + sp.diags(d), dofs=model.dofs, node_ids=model.node_ids,
                        xyz=model.xyz, node_sets=model.node_sets)
    pre = modes_below(model, BAND[1], as_solver(None))
    phi, F, sigma = pre.phi, pre.factorization, pre.sigma
    freqs = np.linspace(BAND[0], BAND[1], 700)
    sur = Surrogate(model, ports, BAND, phi=phi, factorization=F, sigma=sigma, candidates=freqs[::50], max_checks=1)
    assert (sur._modal is not None) == proportional
    A, B = ShiftedMatrices(model.K, model.M, model.D), sur.B
    X = sur.reduced_solution(2 * np.pi * freqs)
    full = [np.linalg.norm(A(2 * np.pi * f) @ (sur.V @ X[k]) - B) / np.linalg.norm(B) for k, f in enumerate(freqs)]
    w = 2 * np.pi * freqs
    c = np.concatenate([X, -(w ** 2)[:, None, None] * X, (1j * w)[:, None, None] * X,
                        np.broadcast_to(-np.eye(2), (w.size, 2, 2))], axis=1)
    gram = np.sqrt(np.maximum(np.einsum("fam,ab,fbm->f", c.conj(), sur._gram, c).real, 0)) / np.linalg.norm(B)
    res, full = sur.residual(freqs), np.array(full)
    big = full > 0.1 * full.max()
    # both Gram forms carry the rounding of the quadratic form ||P c||^2 = c^H G c, at most m eps |c|^T |G| |c|
    # for m terms, with ||K V x|| >> ||B||; |a - b| <= sqrt(|a^2 - b^2|) bounds the residuals' difference by
    # the square root of the two roundings (measured: below 0.45 sqrt(eps |c|^T |G| |c|) / ||B||, which is up
    # to 7.5e-2 of the largest residual with proportional damping, 1.3e-2 without); res within 1.2e-2 and
    # 3.4e-3 of the full residual where that is above a tenth of its largest value
    absg = np.einsum("fam,ab,fbm->f", np.abs(c), np.abs(sur._gram), np.abs(c)).real
    floor = np.sqrt(2 * c.shape[1] * np.finfo(float).eps * absg) / np.linalg.norm(B)
    assert full.max() > 1e-5 and np.all(np.abs(res - gram) <= floor)
    assert np.abs(res / full - 1)[big].max() < 0.05


def test_surrogate_takes_the_inertia_count_factorization_at_the_band_end():
    # the pre-pass keeps the count's factorization of K - (2 pi fmax)^2 M when asked; the surrogate's
    # basis holds its solutions (Krylov vectors at the band's end) and the pre-pass no longer holds it
    from flexmor.dynamics.modes import modes_below
    from flexmor.dynamics.surrogate import MODES_MARGIN, Surrogate
    from flexmor.linalg import EigenPolicy, SolverContext

    model = cantilever(6).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    fmax = 3000.0
    solver = SolverContext(eigen=EigenPolicy(dense_limit=100))
    assert modes_below(model, fmax, solver).edge is None
    pre = modes_below(model, MODES_MARGIN * fmax, solver, keep_edge=True)
    F, shift = pre.edge
    assert shift == pytest.approx((2 * np.pi * MODES_MARGIN * fmax) ** 2)
    B = ports.B.toarray()
    X = F.solve(B)
    assert np.linalg.norm((model.K - shift * model.M) @ X - B) <= 1e-10 * np.linalg.norm(B)
    assert pre.f.max() <= MODES_MARGIN * fmax < 1.5 * pre.f.max()  # modes up to the margin
    sur = Surrogate(model, ports, (10.0, fmax), phi=pre.phi, factorization=pre.factorization, sigma=pre.sigma,
                    solver=solver, candidates=np.linspace(10.0, fmax, 50), edge=pre.take_edge())
    assert pre.edge is None and pre.take_edge() is None
    outside = X - sur.V @ (sur.V.T @ X)
    assert np.linalg.norm(outside) <= 1e-8 * np.linalg.norm(X)
    assert sur.verified


@pytest.mark.skipif("pardiso" not in available_backends(),
                    reason="the pre-pass's inertia count (complete modes) needs pardiso")
@pytest.mark.parametrize("n_krylov", [1, 3])
def test_iterative_check_estimate_bounds_the_error_at_a_resonance(n_krylov):
    # the reference of an iterative check: its M-norm distance to a direct solve is below 6 times its
    # estimate (the modes below 1.1 fmax in the space, proportional damping) plus what the problem's
    # conditioning leaves undetermined: twice the distance of the direct solve to the modal solution of the
    # dense eigendecomposition (two exact methods; 1.2e-7 apart at the resonance, where the eigenvalues'
    # rounding of ~1e-10 is amplified by 1 / (2 zeta), 2e-13 near fmax), with few starting vectors (steps
    # needed) and with the usual ones; measured: 1.1 times the estimate near fmax
    from flexmor.dynamics.dense_frf import DenseResolvent
    from flexmor.dynamics.frf import ShiftedMatrices
    from flexmor.dynamics.modes import modes_below
    from flexmor.dynamics.surrogate import ITERATIVE_TARGET, MODES_MARGIN, Surrogate
    from flexmor.linalg import EigenPolicy, SolverContext, factorize

    model = cantilever(2).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    fmax = 3000.0
    solver = SolverContext("pardiso", eigen=EigenPolicy(dense_limit=100))
    pre = modes_below(model, MODES_MARGIN * fmax, solver)
    assert pre.complete
    sur = Surrogate(model, ports, (10.0, fmax), phi=pre.phi, factorization=pre.factorization, sigma=pre.sigma,
                    solver=solver, candidates=[fmax], n_krylov=n_krylov, max_checks=1, complete=True)
    assert sur.check_solver == "iterative"
    # without the edge's vectors the surrogate misses fmax by 1e-3 and more: its one check says so
    assert sur.checks[0]["rel_error"] > 100 * sur.tol and not sur.verified
    exact, A, M = DenseResolvent(model.K, model.M, model.D), ShiftedMatrices(model.K, model.M, model.D), model.M

    def dist(X, Y):
        return np.sqrt(np.vdot(X - Y, M @ (X - Y)).real / np.vdot(Y, M @ Y).real)

    f1 = float(pre.f[pre.f > 1][0])
    steps = []
    for f in (f1, 1.01 * f1, 0.5 * (pre.f[2] + pre.f[3]), 0.98 * fmax, 50.0):
        w = 2 * np.pi * f
        X, ratio, it = sur._iterative_solution(w)
        Xd = factorize(A(w), check=False).solve(sur.B)
        Xe = exact.phi @ (exact.pole_factors(np.array([w]))[0][:, None] * (exact.phi.T @ sur.B))
        assert ratio <= 1 and dist(X, Xd) <= 6 * ratio * ITERATIVE_TARGET * sur.tol + 2 * dist(Xd, Xe), f
        steps.append(it)
    assert max(steps) > 0 or n_krylov > 1


def test_without_an_inertia_count_the_checks_are_direct():
    # SciPy's factorization reports no inertia: the pre-pass cannot say its modes are all below 1.1 fmax, so
    # the iterative checks' estimate would not hold and auto takes direct checks
    from flexmor.dynamics.modes import modes_below
    from flexmor.dynamics.surrogate import MODES_MARGIN, Surrogate
    from flexmor.linalg import EigenPolicy, SolverContext

    model = cantilever(2).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    solver = SolverContext("scipy", eigen=EigenPolicy(dense_limit=100))
    pre = modes_below(model, MODES_MARGIN * 3000.0, solver)
    assert not pre.complete and pre.f.size > 0
    sur = Surrogate(model, ports, (10.0, 3000.0), phi=pre.phi, factorization=pre.factorization, sigma=pre.sigma,
                    solver=solver, candidates=np.linspace(10.0, 3000.0, 40), complete=pre.complete)
    assert sur.check_solver == "direct" and sur.verified
