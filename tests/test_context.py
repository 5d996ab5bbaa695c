"""The solver context: statistics, caches and the backend choice travel with the context passed in."""

import dataclasses

import numpy as np
import pytest

from flexmor.checks import check_rigid_body_modes
from flexmor.errors import OptionError
from flexmor.linalg import BACKENDS, EigenPolicy, SolverContext, eigenmodes, factorize
from flexmor.linalg.distributed import MPILayout
from flexmor.ports import make_ports
from flexmor.reduction import reduce


def test_two_contexts_keep_separate_statistics(clamped):
    a, b = SolverContext(), SolverContext("scipy")
    rhs = np.ones((clamped.n_dof, 3))
    Fa = factorize(clamped.K, solver=a, positive=True, check=False)
    Fa.solve(rhs)
    Fa.solve(rhs[:, 0])
    for _ in range(2):
        factorize(clamped.K, solver=b, positive=True, check=False).solve(rhs)
    assert (a.stats.count, a.stats.solves, a.stats.solve_columns) == (1, 2, 4)
    assert (b.stats.count, b.stats.solves, b.stats.solve_columns) == (2, 2, 6)
    assert a.stats.seconds > 0 and b.stats.seconds > 0
    factorize(clamped.K, positive=True)  # no context: a fresh one, counted nowhere else
    assert (a.stats.count, b.stats.count) == (1, 2)


def test_factorization_count_read_from_the_context_passed_in(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    solver = SolverContext()
    red = reduce(clamped, "krylov", 6, ports, points=[0.0, 500.0], solver=solver)
    assert solver.stats.count == 2  # one factorization per expansion point
    assert red.info["options"]["backend"] == "auto"
    guyan = SolverContext()
    reduce(clamped, "guyan", None, ports, interface=["TIP"], solver=guyan)
    assert guyan.stats.count == 1 and solver.stats.count == 2  # K_ii once, counted in its own context


def test_rigid_body_count_is_remembered_by_the_context(free):
    solver = SolverContext(eigen=EigenPolicy(dense_limit=10))  # shift-invert: one factorization per count
    with pytest.warns(UserWarning, match="6 rigid-body modes"):
        assert check_rigid_body_modes(free, solver=solver) == 6
    with pytest.warns(UserWarning):
        assert check_rigid_body_modes(free, solver=solver) == 6
    assert solver.stats.count == 1  # the second check came from the context's memo
    other = SolverContext(eigen=EigenPolicy(dense_limit=10))
    with pytest.warns(UserWarning):
        check_rigid_body_modes(free, solver=other)
    assert other.stats.count == 1


def test_eigen_policy_chooses_the_method(clamped):
    assert EigenPolicy().choose(270, 10) == "dense"
    assert EigenPolicy(dense_limit=100).choose(270, 10) == "lanczos"
    assert EigenPolicy(dense_limit=100, lanczos_max_k=5).choose(270, 10) == "arpack"
    arpack = SolverContext(eigen=EigenPolicy(method="arpack"))
    lam, _ = eigenmodes(clamped.K, clamped.M, 6, solver=arpack)
    lam_dense, _ = eigenmodes(clamped.K, clamped.M, 6)
    np.testing.assert_allclose(lam, lam_dense, rtol=1e-9)
    assert arpack.stats.count == 1
    with pytest.raises(OptionError, match="lanczos"):
        EigenPolicy(method="qr")


def test_backend_table_and_validation():
    assert list(BACKENDS)[:3] == ["cholmod", "pardiso", "scipy"] and "petsc" in BACKENDS
    b = BACKENDS["scipy"]
    assert b.available() and b.complex and not b.positive_only
    with pytest.raises(dataclasses.FrozenInstanceError):
        b.complex = False
    with pytest.raises(OptionError, match="auto, cholmod, pardiso, scipy, petsc"):
        SolverContext(backend="mumps")
    assert SolverContext().layout().size == 1 and SolverContext().layout().row_range(10) == (0, 10)
    assert SolverContext(mpi=MPILayout(rank=1, size=3)).layout().row_range(10) == (4, 7)


def test_auto_backends_restricted_by_the_environment(clamped, monkeypatch):
    """``FLEXMOR_AUTO_BACKENDS`` restricts what ``auto`` chooses from (a run on another arithmetic path);
    a backend asked for by name is not affected, and a name that is no backend is refused naming it."""
    from flexmor.linalg.context import AUTO_BACKENDS_VARIABLE

    shifted = (clamped.K - 1e5 * clamped.M).tocsr()
    monkeypatch.setenv(AUTO_BACKENDS_VARIABLE, "scipy")
    F = factorize(shifted, check=False)
    assert F.backend == "scipy"
    b = np.ones(clamped.n_dof)
    assert np.linalg.norm(shifted @ F.solve(b) - b) <= 1e-10 * np.linalg.norm(b)
    avail = SolverContext().available()
    if "pardiso" in avail:
        assert factorize(shifted, solver=SolverContext("pardiso"), check=False).backend == "pardiso"
        monkeypatch.setenv(AUTO_BACKENDS_VARIABLE, " pardiso , scipy")
        assert factorize(shifted, check=False).backend == "pardiso"
    monkeypatch.setenv(AUTO_BACKENDS_VARIABLE, "scipy,superlu")
    with pytest.raises(OptionError, match=r"FLEXMOR_AUTO_BACKENDS='scipy,superlu' names no backend 'superlu'; "
                                          r"choose from: .*scipy"):
        factorize(shifted, check=False)
