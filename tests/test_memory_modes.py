"""Factorizations beyond the memory of the machine: mixed precision and out of core behind factorize()."""

import gc
import json
import re

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import ROOT

from flexmor.cli import main
from flexmor.errors import OptionError, SolverError
from flexmor.linalg import SolverContext, available_backends, factorize, memory
from flexmor.linalg.memory import BACKWARD_TARGET, MEMORY_FRACTION, REFINE_MAX_ITER, describe_factor, factor_record
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce

BACKENDS = available_backends()
needs_pardiso = pytest.mark.skipif("pardiso" not in BACKENDS, reason="out of core needs the pardiso backend "
                                   "(pip install flexmor[fast]); mixed precision also runs with scipy")
MIXED = [b for b in ("pardiso", "scipy") if b in BACKENDS]


@pytest.fixture(scope="module")
def beam():
    return cantilever(n=4)  # 3,000 equations, clamped


def _matrices(model):
    """The stiffness (real SPD) and the complex symmetric K - w^2 M + i w D at 300 Hz."""
    w = 2 * np.pi * 300.0
    return {"real": (model.K.tocsr(), True),
            "complex": ((model.K - w**2 * model.M + 1j * w * 1e-5 * model.K).tocsr(), False)}


def _rhs(n, k=3):
    return np.random.default_rng(7).standard_normal((n, k))


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["real", "complex"])
@pytest.mark.parametrize("backend", MIXED)
def test_mixed_precision_solves_equal_the_double_ones(beam, backend, kind):
    A, positive = _matrices(beam)[kind]
    B = _rhs(A.shape[0])
    X0 = factorize(A, solver=SolverContext(backend), positive=positive).solve(B)
    solver = SolverContext(backend, factor_memory="mixed")
    F = factorize(A, solver=solver, positive=positive)
    assert F.memory.mode == "mixed" and F.backend == backend
    X = F.solve(B)
    assert np.linalg.norm(X - X0) / np.linalg.norm(X0) < 1e-10
    x = F.solve(B[:, 0] + 1j * B[:, 1])  # a complex right-hand side of a real factor too
    assert np.linalg.norm(x - (X0[:, 0] + 1j * X0[:, 1])) / np.linalg.norm(X0[:, :2]) < 1e-10
    rec = factor_record(solver.stats)
    # the check's solve too; a complex right-hand side of a real factor is two solves
    assert rec["mixed"] == 1 and rec["double"] == 0 and rec["refined_solves"] == (4 if kind == "real" else 3)
    # stopped at the backward error of a double-precision solve (4-5 steps; stationary refinement took 7-8)
    assert 2 <= rec["refine_max_steps"] <= 8 and rec["refine_residual"] <= BACKWARD_TARGET
    assert "mixed precision (1 of 1 factorizations)" in describe_factor(solver.stats)


@needs_pardiso
@pytest.mark.parametrize("kind", ["real", "complex"])
def test_out_of_core_solves_equal_the_in_core_ones_and_leave_no_files(beam, kind, tmp_path):
    A, positive = _matrices(beam)[kind]
    B = _rhs(A.shape[0])
    X0 = factorize(A, solver=SolverContext("pardiso"), positive=positive).solve(B)
    solver = SolverContext(factor_memory="ooc", scratch_dir=str(tmp_path))
    F = factorize(A, solver=solver, positive=positive)
    assert F.memory.mode == "ooc" and F.backend == "pardiso"
    (work,) = tmp_path.iterdir()  # one directory of this factorization, holding the factor files
    assert work.name.startswith("flexmor-ooc-") and any(work.iterdir())
    X = F.solve(B)
    assert np.linalg.norm(X - X0) / np.linalg.norm(X0) < 1e-10
    assert factor_record(solver.stats)["ooc"] == 1
    del F
    gc.collect()
    assert list(tmp_path.iterdir()) == []


@needs_pardiso
@pytest.mark.parametrize("off", [5e-7, 5e-5, 1e-2])
def test_an_out_of_core_factor_that_solves_inaccurately_is_refined(beam, tmp_path, monkeypatch, off):
    """MKL's out-of-core factor once solved with a relative error of 7e-4 (its residual inside the 1e-6 of
    the factor check), and in one run in four of this module its check's residual was 5.9e-6: a factor whose
    backward error is above BACKWARD_TOL has its solves refined in double precision, so that they equal the
    in-core ones; one whose check's residual is above OOC_CHECK_TOL (1e-3) is refused."""
    from flexmor.errors import SolverError
    from flexmor.linalg.memory import OOC_CHECK_TOL
    from flexmor.linalg.pardiso import PardisoFactorization

    A, positive = _matrices(beam)["real"]
    B = _rhs(A.shape[0])
    X0 = factorize(A, solver=SolverContext("pardiso"), positive=positive).solve(B)
    exact = PardisoFactorization._solve_factor

    def inexact(self, b):  # solves `off` too long: a backward error above BACKWARD_TOL
        return (1 + off) * exact(self, b)

    monkeypatch.setattr(PardisoFactorization, "_solve_factor", inexact)
    solver = SolverContext("pardiso", factor_memory="ooc", scratch_dir=str(tmp_path))
    if off > OOC_CHECK_TOL:
        with pytest.raises(SolverError, match="failed its check"):
            factorize(A, solver=solver, positive=positive)
        return
    F = factorize(A, solver=solver, positive=positive)
    assert F.memory.mode == "ooc"
    X = F.solve(B)
    assert np.linalg.norm(X - X0) / np.linalg.norm(X0) < 1e-10
    assert factor_record(solver.stats)["refined_solves"] >= 1


@needs_pardiso
def test_out_of_core_files_are_removed_when_the_factorization_fails(beam, tmp_path, monkeypatch):
    """An in-core share below what MKL needs: error -9 in the numerical phase, and no files left."""
    monkeypatch.setattr(memory, "OOC_MIN_SHARE", 1e-4)
    est = factorize(beam.K, solver=SolverContext("pardiso"), positive=True).memory.estimates
    limit = 1.01 * est["ooc"] / MEMORY_FRACTION  # the permanent data and almost nothing for the factor
    solver = SolverContext(factor_memory="ooc", memory_limit=limit, scratch_dir=str(tmp_path))
    with pytest.raises(SolverError, match="out-of-core"):
        factorize(beam.K, solver=solver, positive=True)
    gc.collect()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("backend", MIXED)
def test_auto_takes_the_first_mode_that_fits_the_memory_limit(beam, backend, tmp_path):
    A, positive = _matrices(beam)["complex"]
    b = _rhs(A.shape[0], 1)[:, 0]
    F = factorize(A, solver=SolverContext(backend), positive=positive)
    est = F.memory.estimates
    assert F.memory.mode == "double" and est["mixed"] < est["double"]
    x0 = F.solve(b)
    between = (est["mixed"] + est["double"]) / 2 / MEMORY_FRACTION
    G = factorize(A, solver=SolverContext(backend, memory_limit=between), positive=positive)
    assert G.memory.mode == "mixed" and "the double-precision factor needs" in G.memory.reason
    assert np.linalg.norm(G.solve(b) - x0) / np.linalg.norm(x0) < 1e-10
    if backend == "pardiso":
        assert est["ooc"] < est["mixed"]
        below = (est["ooc"] + est["mixed"]) / 2 / MEMORY_FRACTION
        H = factorize(A, solver=SolverContext(backend, memory_limit=below, scratch_dir=str(tmp_path)),
                      positive=positive)
        assert H.memory.mode == "ooc"
        assert np.linalg.norm(H.solve(b) - x0) / np.linalg.norm(x0) < 1e-10
        del H
        gc.collect()
        assert list(tmp_path.iterdir()) == []
    tiny = 0.5 * min(v for v in est.values() if v) / MEMORY_FRACTION
    with pytest.raises(SolverError, match=rf"with {backend} needs about \d+ MB in double precision, in mixed "
                       r"precision \d+ MB.*, but only \d+ MB of memory are available"):
        factorize(A, solver=SolverContext(backend, memory_limit=tiny), positive=positive)


@needs_pardiso
def test_krylov_with_mixed_precision_gives_the_same_reduced_body():
    model = cantilever(n=4).with_rayleigh(0.0, 1e-6)
    spec = ["TIP_CENTER:x", "TIP_CENTER:y", "TIP_CENTER:z"]  # one symmetric input: deflation by rounding noise
    ports = make_ports(model, spec, spec)
    # one real point given (the greedy default points follow the residual, whose near-ties and deflations the
    # rounding of the solves can decide on this symmetric input: the factor's precision is the subject here)
    pts = repr(float(np.sqrt(10.0 * 3000.0)))
    ref = reduce(model, "krylov", 12, ports, points=pts, solver=SolverContext())
    solver = SolverContext(factor_memory="mixed")
    red = reduce(model, "krylov", 12, ports, points=pts, solver=solver)
    assert solver.stats.mixed == solver.stats.count >= 1 and solver.stats.refined_solves > 0
    np.testing.assert_allclose(red.frequencies_hz(), ref.frequencies_hz(), rtol=1e-9)


def test_refine_solves_a_hermitian_system_with_a_single_precision_factor(beam):
    """``refine`` itself, on K + i S (S real antisymmetric: A Hermitian) with a complex64 LU as the factor."""
    from scipy.sparse.linalg import splu, spsolve

    S = sp.triu(beam.M, 1, format="csr") * 1e12  # entries as large as those of K
    A = ((beam.K + beam.K.T) / 2 + 1j * (S - S.T)).tocsr()
    assert abs(A - A.conj().T).max() == 0
    lu = splu(A.astype(np.complex64).tocsc())
    B = _rhs(A.shape[0]) + 1j * _rhs(A.shape[0])[:, ::-1]
    B[:, 1] = 0  # a zero column stays zero, without steps
    X, steps, eta = memory.refine(A, lambda v: lu.solve(v.astype(np.complex64)), B, anorm=memory.norm_bound(A))
    X0 = spsolve(A.tocsc(), B)
    assert np.linalg.norm(X - X0) / np.linalg.norm(X0) < 1e-10 and not X[:, 1].any()
    assert 2 <= steps <= 8 and eta <= memory.BACKWARD_TARGET


def test_norm_bound_bounds_the_two_norm():
    A = sp.random(40, 30, density=0.3, random_state=1, format="csr") - 0.5 * sp.eye(40, 30, format="csr")
    D = A.toarray()
    expected = np.sqrt(np.linalg.norm(D, 1) * np.linalg.norm(D, np.inf))
    assert memory.norm_bound(A) == pytest.approx(expected, rel=1e-14) and expected >= np.linalg.norm(D, 2)


@pytest.mark.parametrize("backend", MIXED)
def test_gmres_refinement_converges_where_stationary_refinement_does_not(beam, backend):
    """K - s M with s 0.3 % below the first eigenvalue: SPD, cond ~ 4e8, eps_single * cond ~ 25."""
    from flexmor.linalg import eigenmodes

    lam, _ = eigenmodes(beam.K, beam.M, 1)
    A = (beam.K - lam[0] * (1 - 3e-3) * beam.M).tocsr()
    B = _rhs(A.shape[0])
    X0 = factorize(A, solver=SolverContext(backend), positive=True, check=False).solve(B)
    solver = SolverContext(backend, factor_memory="mixed")
    F = factorize(A, solver=solver, positive=True, check=False)
    anorm, bnorm = memory.norm_bound(A), np.linalg.norm(B, axis=0)
    X = np.zeros_like(B)  # stationary refinement x += M^-1 (b - A x) with as many steps: far from converged
    for _ in range(REFINE_MAX_ITER):
        R = B - A @ X
        X += F._solve_factor(R / np.linalg.norm(R, axis=0)) * np.linalg.norm(R, axis=0)
    assert np.max(memory._backward(B - A @ X, X, bnorm, anorm)) > 1e-12
    X = F.solve(B)
    rec = factor_record(solver.stats)
    assert rec["refined_solves"] == 1 and rec["refine_max_steps"] <= 20 and rec["refine_residual"] <= BACKWARD_TARGET
    assert np.max(memory._backward(B - A @ X, X, bnorm, anorm)) <= BACKWARD_TARGET
    # both solutions within cond * eps of the exact one
    assert np.linalg.norm(X - X0) / np.linalg.norm(X0) < 1e-7


@pytest.mark.parametrize("backend", MIXED)
def test_mixed_precision_refuses_an_ill_conditioned_matrix(backend):
    """A dense SPD matrix with eigenvalues spread evenly from 1 to 1e-12: a third of them below the rounding of a
    single-precision factor (cond 1e12), too many for GMRES to correct in its steps."""
    rng = np.random.default_rng(0)
    Q, _ = np.linalg.qr(rng.standard_normal((300, 300)))
    A = sp.csr_matrix((Q * np.logspace(0, -12, 300)) @ Q.T)
    with pytest.raises(SolverError, match="too ill-conditioned for a single-precision factor; set "
                                          "factor_memory to 'ooc'"):
        factorize(A, solver=SolverContext(backend, factor_memory="mixed"), check=False).solve(np.ones(A.shape[0]))


def test_a_mode_the_backend_lacks_is_refused(beam):
    with pytest.raises(SolverError, match="factor_memory='ooc' needs backend pardiso.*, not scipy"):
        factorize(beam.K, solver=SolverContext("scipy", factor_memory="ooc"), positive=True)


def test_solver_context_checks_the_memory_options():
    with pytest.raises(OptionError, match="factor_memory='fast' is not allowed; choose one of: auto, double, "
                                          "mixed, ooc"):
        SolverContext(factor_memory="fast")
    with pytest.raises(OptionError, match="memory_limit must be a positive number of bytes"):
        SolverContext(memory_limit=0)
    with pytest.raises(OptionError, match="refine_tol must lie in"):
        SolverContext(refine_tol=2.0)
    assert SolverContext(memory_limit=5e9).memory_available() == 5e9


@needs_pardiso
def test_cli_reduce_records_the_memory_mode(capsys, tmp_path):
    from helpers import CLAMPED

    model = CLAMPED
    base = ["reduce", model, "--method", "krylov", "--order", "6", "--input", "TIP:y", "--backend", "pardiso",
            "--no-cache", "--json"]

    def run(*extra, name):
        assert main(base + ["-o", str(tmp_path / name), *extra]) == 0
        return json.loads(capsys.readouterr().out)

    ref = run(name="double.h5")
    assert ref["factor"]["double"] >= 1 and ref["factor"]["mixed"] == 0 and ref["factor"]["reason"] is None
    out = run("--factor-memory", "mixed", name="mixed.h5")
    assert out["factor"]["mixed"] >= 1 and out["factor"]["refine_residual"] <= 1e-12
    assert "factor_memory='mixed'" in out["factor"]["reason"]
    out = run("--factor-memory", "ooc", name="ooc.h5")
    assert out["factor"]["ooc"] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["double.h5", "mixed.h5", "ooc.h5"]  # no OOC files
    assert main(base[:-1] + ["-o", str(tmp_path / "x.h5"), "--memory-limit", "100K"]) == 1  # the machine: exit 1
    err = capsys.readouterr().err
    # PARDISO's estimates include per-thread work space: 1 MB with one thread, 16 MB with two
    assert re.search(r"needs about \d+ MB in double precision, in mixed precision \d+ MB, out of core at least "
                     r"\d+ MB, but only 0 MB", err) and "Traceback" not in err
    with pytest.raises(SystemExit):
        main(base + ["--memory-limit", "lots"])
    assert "--memory-limit: 'lots' is not a memory size" in capsys.readouterr().err


@pytest.mark.slow
@needs_pardiso
def test_memory_benchmark_smoke_run(tmp_path):
    """``bench/memory.py`` on a tiny model (the full benchmark is not part of the suite): same code."""
    import subprocess
    import sys

    out = tmp_path / "memory.json"
    cmd = [sys.executable, str(ROOT / "bench" / "memory.py"), "--sizes", "3000",
           "--mode", "double,mixed,ooc", "--nrhs", "2", "--scratch", str(tmp_path), "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(out.read_text())["results"]
    assert [r["mode"] for r in rows] == ["double", "mixed", "ooc"]
    for r in rows:
        assert r["n_dof"] == 3000 and r["residual"] < 1e-10 and r["files_left"] == []
        assert r["estimates_mb"]["ooc"] < r["estimates_mb"]["mixed"] < r["estimates_mb"]["double"]
    assert rows[1]["refine_max_steps"] >= 2 and rows[2]["ooc_files_mb"] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory.json"]


@needs_pardiso
def test_a_single_precision_factor_reports_no_inertia(beam):
    """The eigen solvers count modes below a shift by the inertia; a single-precision factor's is not exact."""
    A = (beam.K - 1e7 * beam.M).tocsr()  # a shift above the lowest eigenvalues: indefinite
    assert factorize(A, solver=SolverContext("pardiso")).inertia[1] > 0
    assert factorize(A, solver=SolverContext("pardiso", factor_memory="mixed")).inertia is None


@needs_pardiso
def test_out_of_core_in_a_missing_directory_is_a_clear_error(beam, tmp_path):
    with pytest.raises(SolverError, match="cannot make the directory of the out-of-core factor in .*nowhere"):
        factorize(beam.K, solver=SolverContext(factor_memory="ooc", scratch_dir=str(tmp_path / "nowhere")))


def test_a_wrong_out_of_core_factor_is_caught(beam, tmp_path):
    """MKL may return a wrong out-of-core factor without an error when starved of memory: one check solve."""
    ooc = memory.OutOfCore(2**20, tmp_path)
    ooc.verify(beam.K, factorize(beam.K, positive=True).solve)
    with pytest.raises(SolverError, match=r"failed its check \(relative residual 1.0e\+00\) with 1 MB in core: give "
                                          r"it more memory \(memory_limit\)"):
        ooc.verify(beam.K, lambda b: 0 * b)
    ooc.remove()
    assert list(tmp_path.iterdir()) == []
