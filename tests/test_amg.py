"""The iterative ``amg`` backend: smoothed-aggregation AMG + block CG where no factor fits (flexmor.linalg.amg)."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from helpers import CLAMPED, run_json

from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError, OutOfMemoryError, SolverError
from flexmor.linalg import SolverContext, factorize
from flexmor.linalg.amg import block_cg
from flexmor.linalg.eigen import eigenmodes
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.rigid import register_near_null
from flexmor.workflow import reduce_and_judge

pytest.importorskip("pyamg", reason="the amg backend needs pyamg (pip install 'flexmor[amg]')")

SIX = ["TIP:x", "TIP:y", "TIP:z", "TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]


@pytest.fixture(scope="module")
def beam():
    return cantilever(n=4)  # 3,000 DOF, clamped at x = 0


def _residuals(A, X, B):
    return np.linalg.norm(B - A @ X, axis=0) / np.linalg.norm(B, axis=0)


def test_block_cg_reaches_the_stated_residual_and_the_direct_solution(beam):
    rng = np.random.default_rng(1)
    B = rng.standard_normal((beam.n_dof, 6))
    solver = SolverContext(backend="amg", solve_tol=1e-9)
    register_near_null(solver, beam)
    F = factorize(beam.K, solver=solver, positive=True)
    X = F.solve(B)
    assert F.backend == "amg" and F.near_null.startswith("6 rigid-body motions")
    assert _residuals(beam.K, X, B).max() <= 1e-9
    Xd = sla.spsolve(beam.K.tocsc(), B)
    assert np.linalg.norm(X - Xd) / np.linalg.norm(Xd) < 1e-6
    st = solver.stats
    assert st.iterative == 1 and st.iterations > 0 and st.iterative_residual <= 1e-9
    assert st.iterative_tol == 1e-9


def test_the_rigid_motions_of_the_geometry_cut_the_iterations(beam):
    """Aggregation needs the six rigid-body motions as near-null space; the constant alone (no geometry)
    leaves the rotations to CG (13-16 iterations against 190-330 on 3k-36k DOF)."""
    b = np.random.default_rng(2).standard_normal((beam.n_dof, 1))
    counts = {}
    for registered in (True, False):
        solver = SolverContext(backend="amg")
        if registered:
            register_near_null(solver, beam)
        factorize(beam.K, solver=solver, positive=True).solve(b)
        counts[registered] = solver.stats.iterations
    assert counts[True] * 4 < counts[False]


def test_complex_and_indefinite_matrices_are_refused_naming_the_backend(beam):
    solver = SolverContext(backend="amg")
    register_near_null(solver, beam)
    w = 2 * np.pi * 500.0
    with pytest.raises(SolverError, match="backend 'amg' solves real symmetric positive definite"):
        factorize((beam.K - w**2 * beam.M + 1j * w * 1e-6 * beam.K).tocsr(), solver=solver)
    lam, _ = eigenmodes(beam.K, beam.M, 4)
    above = (beam.K - 1.5 * lam[3] * beam.M).tocsr()  # four eigenvalues below the shift
    with pytest.raises(SolverError, match="not positive definite"):
        factorize(above, solver=solver).solve(np.ones(beam.n_dof))


def test_block_cg_stops_at_the_rounding_floor_of_an_ill_conditioned_matrix():
    """A relative residual below about eps ||A|| ||x|| / ||b|| is out of any solver's reach: block CG stops at
    that floor instead of failing (a stiff chain, condition ~1e13, a load at its soft end)."""
    n = 3000
    k = np.logspace(0, 6, n + 1)  # springs from 1 to 1e6 N/m
    A = (sp.diags(k[:-1] + k[1:]) - sp.diags(k[1:-1], 1) - sp.diags(k[1:-1], -1)).tocsr()
    B = np.zeros((n, 2))
    B[0, 0], B[:, 1] = 1.0, 1.0
    lu = sla.splu(A.tocsc())
    X, its, res = block_cg(A, B, lu.solve, tol=1e-15)
    direct = lu.solve(B)
    assert np.linalg.norm(X - direct) <= 1e-8 * np.linalg.norm(direct)
    assert res < 1e-9 and its >= 1


@pytest.mark.parametrize("method, order, opts", [
    ("krylov", 24, {"points": "0"}),
    ("modal", 20, {}),
    ("craig-bampton", 24, {"interface": ["TIP_CENTER"]}),
    ("guyan", None, {"interface": ["TIP_CENTER", "MID"]}),
])
def test_the_amg_body_is_the_direct_body(beam, method, order, opts):
    """Same basis by both backends: equal frequencies and, judged against the full model by direct solves,
    equal band errors; the record says what was solved iteratively and that the band error was not computed."""
    if method == "guyan" and "MID" not in beam.node_sets:
        opts = {"interface": ["TIP_CENTER"]}
    ports = make_ports(beam, SIX)
    bodies = {}
    for backend in ("amg", "auto"):
        solver = SolverContext(backend=backend)
        red, res = reduce_and_judge(beam, method, order, ports, band=(1.0, 2000.0) if backend == "amg" else None,
                                    solver=solver, mounted=True, **opts)
        bodies[backend] = (red, res)
    (amg, res), (direct, _) = bodies["amg"], bodies["auto"]
    assert amg.order == direct.order
    fa, fd = amg.frequencies_hz(), direct.frequencies_hz()
    assert np.max(np.abs(fa - fd) / fd) < 1e-6
    full = FullResponse(beam, ports, (1.0, 2000.0))
    ea, ed = full.evaluate(amg).band_error, full.evaluate(direct).band_error
    assert abs(ea - ed) <= 1e-3 * ed + 1e-12
    rec = amg.info["iterative_solves"]
    assert rec["backend"] == "amg" and rec["solve_tol"] == 1e-10
    # modes by LOBPCG (one V-cycle per iteration, no block solves), static and Krylov vectors by block CG
    assert (rec["eigen_iterations"] > 0) == (method in ("modal", "craig-bampton"))
    assert (rec["iterations"] > 0) == (method != "modal")
    if method in ("modal", "craig-bampton"):  # (the context's largest: the lowest-eigenvalue checks ask 1e-6)
        assert rec["eigen_residual_max"] <= 1e-6
    assert res["band_error"] is None
    assert any(n.startswith("band error not computed: an iterative backend (amg") for n in res["notes"])
    assert res["static"] is not None  # the static check solves positive definite systems: it runs


def test_a_free_body_is_reduced_with_a_negative_shift():
    free = cantilever(n=3, clamped=False)
    ports = make_ports(free, ["TIP:z"])
    got = {}
    for backend in ("amg", "auto"):
        red, _ = reduce_and_judge(free, "modal", 16, ports, solver=SolverContext(backend=backend))
        got[backend] = red.frequencies_hz()
    assert np.max(np.abs(got["amg"] - got["auto"]) / got["auto"]) < 1e-8


def test_modal_under_amg_asks_room_for_rigid_body_modes_only_where_the_geometry_can_move(beam):
    """Under an iterative backend LOBPCG iterates every column modal asks for: a clamped body gets no six columns
    for rigid-body modes; a free one, a body held at a single node (free to turn about it) and every body under a
    direct backend do. A loose part the test cannot see is found by the modes, and modal asks again."""
    import scipy.sparse as sps

    from flexmor.reduction.modal import room_for_rigid

    amg, direct = SolverContext(backend="amg"), SolverContext(backend="scipy")
    free = cantilever(n=3, clamped=False)
    assert room_for_rigid(beam, True) == 0 and room_for_rigid(beam, False) == 6
    assert room_for_rigid(free, True) == 6
    K = sps.lil_matrix(free.K)  # the first node held by stiff springs in x, y, z: the body can turn about it
    assert list(free.dofs[:3, 1]) == [1, 2, 3] and len(set(free.dofs[:3, 0])) == 1
    for j in range(3):
        K[j, j] += 1e6 * free.K.diagonal().max()
    pinned = cantilever(n=3, clamped=False)
    pinned.K = K.tocsr()
    assert room_for_rigid(pinned, True) == 6
    red, _ = reduce_and_judge(beam, "modal", 10, make_ports(beam, ["TIP:z"]), solver=amg)
    ref, _ = reduce_and_judge(beam, "modal", 10, make_ports(beam, ["TIP:z"]), solver=direct)
    assert np.max(np.abs(red.frequencies_hz() - ref.frequencies_hz()) / ref.frequencies_hz()) < 1e-8


def test_a_wide_block_goes_through_the_cycle_in_column_groups(beam):
    from flexmor.linalg.amg import CYCLE_COLUMNS

    solver = SolverContext(backend="amg")
    register_near_null(solver, beam)
    F = factorize(beam.K, solver=solver, positive=True)
    B = np.random.default_rng(3).standard_normal((beam.n_dof, 2 * CYCLE_COLUMNS + 3))
    Z = F.precondition(B)
    one = np.column_stack([F.precondition(B[:, [j]])[:, 0] for j in range(B.shape[1])])
    assert np.abs(Z - one).max() <= 1e-12 * np.abs(one).max()


def test_auto_takes_amg_where_no_factor_fits(beam):
    solver = SolverContext(memory_limit=2e5)  # 200 kB: no direct mode fits
    register_near_null(solver, beam)
    F = factorize(beam.K, solver=solver, positive=True)
    assert F.backend == "amg"
    assert solver.stats.factor_reason.startswith("no direct factorization fits")
    b = np.ones(beam.n_dof)
    x, xd = F.solve(b), sla.spsolve(beam.K.tocsc(), b)
    assert np.linalg.norm(x - xd) <= 1e-7 * np.linalg.norm(xd)


def test_auto_keeps_amg_off_a_shift_inside_the_spectrum(beam):
    """K - sigma M with sigma between eigenvalues is indefinite: where no factor fits, auto says so instead of
    running block CG on it (which never converges there)."""
    w = eigenmodes(beam.K, beam.M, 3)[0]
    A = (beam.K - 0.5 * (w[1] + w[2]) * beam.M).tocsr()  # between the first bending pair and the next mode
    solver = SolverContext(memory_limit=2e5)
    register_near_null(solver, beam)
    with pytest.raises(OutOfMemoryError):
        factorize(A, solver=solver)
    assert solver.stats.iterative == 0


def test_block_cg_that_stalls_on_a_matrix_not_known_positive_says_what_amg_needs(beam, monkeypatch):
    from flexmor.errors import ConvergenceError
    from flexmor.linalg import amg

    def stalls(*args, **kwargs):
        raise ConvergenceError("block CG did not reach the relative residual 1e-10 in 1000 iterations")

    solver = SolverContext(backend="amg")
    register_near_null(solver, beam)
    F, Fp = factorize(beam.K, solver=solver), factorize(beam.K, solver=solver, positive=True)
    monkeypatch.setattr(amg, "block_cg", stalls)
    with pytest.raises(ConvergenceError, match="not known to be positive definite.*sigma below"):
        F.solve(np.ones(beam.n_dof))
    with pytest.raises(ConvergenceError, match="1000 iterations$"):
        Fp.solve(np.ones(beam.n_dof))


def test_tol_is_refused_with_amg(beam):
    with pytest.raises(OptionError, match="backend amg"):
        reduce_and_judge(beam, "modal", 10, make_ports(beam, ["TIP:z"]), band=(1.0, 500.0), tol=1e-3,
                         solver=SolverContext(backend="amg"))


def test_the_command_line_reduces_with_amg_and_records_the_solves(capsys, tmp_path):
    out = run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--points", "0", "--order", "12",
                   "--input", "TIP:z", "--backend", "amg", "--solve-tol", "1e-9", "-o", str(tmp_path / "b.h5"),
                   "--json")
    res = out["results"][0] if "results" in out else out
    assert res["band_error"] is None
    assert res["info"]["iterative_solves"]["solve_tol"] == 1e-9
    assert out["factor"]["iterative"]["matrices"] >= 1


def test_the_plan_estimates_the_amg_setup_within_2x_and_auto_takes_it_when_nothing_fits():
    """flexmor plan's amg row: the hierarchy's memory from a block of the matrix, against the traced peak of
    setting up the whole matrix's hierarchy; auto's choice where no direct mode fits is amg, as the run's."""
    import tracemalloc

    from flexmor.linalg.amg import near_null
    from flexmor.linalg.eigen import default_shift
    from flexmor.linalg.plan import auto_choice, estimate_backends

    model = cantilever(n=8)  # 19,200 DOF
    A = (model.K - default_shift(model.K, model.M) * model.M).tocsr()
    geometry = SolverContext()
    register_near_null(geometry, model)
    est = {e.backend: e for e in estimate_backends(A, rows=4000,
                                                   near_null=near_null(geometry, model.n_dof))}
    planned = est["amg"].real["double"].bytes
    solver = SolverContext(backend="amg")
    register_near_null(solver, model)
    tracemalloc.start()
    try:
        factorize(A, solver=solver, positive=True)
        measured = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert 0.5 < planned / measured < 2.0
    short = SolverContext(memory_limit=1e6)
    choice = auto_choice(short, list(est.values()), model.n_dof, is_complex=False, positive=True)
    assert choice["backend"] == "amg" and choice["reason"].startswith("no direct factorization fits")
    assert factorize(A, solver=short, positive=True).backend == "amg"


def test_the_plan_counts_the_pairs_modal_asks_under_amg(beam, monkeypatch):
    """flexmor plan's LOBPCG columns for modal follow the pairs modal asks at its first try: no room for rigid-body
    modes on the clamped beam, six on the free one."""
    import math

    import flexmor.reduction.modal as modal
    from flexmor.linalg.lobpcg import guard_columns
    from flexmor.plan import LOBPCG_COLUMNS_PER_COLUMN, method_stages
    from flexmor.reduction import reduce

    asked = []

    def counted(K, M, k, **kw):
        asked.append(k)
        return eigenmodes(K, M, k, **kw)

    monkeypatch.setattr(modal, "eigenmodes", counted)
    for model, room in ((beam, 0), (cantilever(n=4, clamped=False), 6)):
        ports = make_ports(model, ["TIP:z"])
        stage = method_stages(model, "modal", 10, ports, solver=SolverContext(backend="amg"))[-1]
        asked.clear()
        reduce(model, "modal", 10, ports, solver=SolverContext(backend="amg"))
        assert asked[0] == 10 + room + modal.CLUSTER_MARGIN
        assert stage.iterative_columns == math.ceil(LOBPCG_COLUMNS_PER_COLUMN * (asked[0] + guard_columns(asked[0])))


def test_the_plan_of_modal_under_amg_counts_lobpcg_within_2x_of_the_run():
    """flexmor plan's amg row for modal: the setup and the LOBPCG iterations (in solved columns' time), against
    the run's time of the same reduction (the rigid-body check and modal 30 on 36,300 DOF)."""
    import time

    from flexmor.plan import plan_reduction
    from flexmor.reduction import reduce

    model = cantilever(n=10)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    plan = plan_reduction(model, "modal", 30, ports, judge=False, solver=SolverContext(backend="amg"))
    row = next(r for r in plan.rows if r["backend"] == "amg")
    solver = SolverContext(backend="amg")
    t0 = time.perf_counter()
    reduce(model, "modal", 30, ports, solver=solver)
    measured = time.perf_counter() - t0
    assert solver.stats.eigen_iterations > 0 and solver.stats.solves == 0
    assert 0.5 < row["total_seconds"] / measured < 2.0, (row["total_seconds"], measured)


def test_an_iterative_backend_names_itself_where_a_complex_point_is_asked(beam):
    """krylov's default points lie on the frequency axis: the refusal says that the backend solves real matrices
    only, not that the point sits at an eigenfrequency; the record names the backend that solved; the band error
    of every iterative backend is skipped with the same note."""
    from flexmor.linalg.backends import is_iterative
    from flexmor.reduction import reduce
    from flexmor.workflow import ITERATIVE_SKIP

    model = beam
    ports = make_ports(model, ["TIP:y"])
    with pytest.raises(SolverError, match="backend amg solves real positive definite matrices only") as exc:
        reduce(model, "krylov", 6, ports, solver=SolverContext(backend="amg"))
    assert "eigenfrequency" not in str(exc.value)
    body = reduce(model, "krylov", 6, ports, points="0", solver=SolverContext(backend="amg"))
    assert body.info["iterative_solves"]["backend"] == "amg"
    assert is_iterative("amg") and is_iterative("petsc-gamg") and not is_iterative("pardiso")
    assert not is_iterative(None) and "amg, petsc-gamg" in ITERATIVE_SKIP
