"""Krylov's default expansion point: one factorization, checked by an estimate of its band error."""

from __future__ import annotations

import pytest

from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError
from flexmor.linalg import SolverContext
from flexmor.ports import make_ports
from flexmor.reduction.krylov import default_points, krylov
from flexmor.workflow import reduce_and_judge

BAND = (10.0, 1000.0)


@pytest.fixture(scope="module")
def beam(clamped):
    model = clamped.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    return model, ports, FullResponse(model, ports, BAND, cache=False)


def _three_points():
    return ",".join(str(p.real) for p in default_points(BAND))


def test_one_point_when_its_estimate_passes(beam):
    model, ports, full = beam
    solver = SolverContext()
    basis = krylov(model, ports, 8, band=BAND, solver=solver)
    check = basis.info["points_check"]
    assert solver.stats.count == 1 and check["n_points"] == 1 and len(basis.info["points_hz"]) == 1
    _, res = reduce_and_judge(model, "krylov", 8, ports, full=full, band=BAND)
    _, res3 = reduce_and_judge(model, "krylov", 8, ports, full=full, band=BAND, points=_three_points())
    # measured: estimate 6.0e-7 (order 8 against its leading 6 columns), band_error 1.9e-12; the three
    # points of the earlier default give 2.0e-10 at three factorizations
    assert res["band_error"] <= check["single_point"]["estimate"] <= check["tol"]
    assert res["band_error"] < res3["band_error"]


def test_more_points_when_the_estimate_fails(beam):
    model, ports, full = beam
    solver = SolverContext()
    basis = krylov(model, ports, 4, band=BAND, solver=solver)
    check = basis.info["points_check"]
    assert check["single_point"]["estimate"] > check["tol"] and check["n_points"] == 3
    assert solver.stats.count == 3  # the single point's blocks are reused: two more factorizations
    _, res = reduce_and_judge(model, "krylov", 4, ports, full=full, band=BAND)
    _, res3 = reduce_and_judge(model, "krylov", 4, ports, full=full, band=BAND, points=_three_points())
    # the same three points as the earlier default ([10, 100, 1000] Hz): the same body (1.5e-3)
    assert res["band_error"] == pytest.approx(res3["band_error"], rel=1e-6)


@pytest.mark.slow
def test_estimate_bounds_the_error_and_decreases(beam):
    model, ports, full = beam
    est, err = [], []
    for r in (6, 8, 10):
        basis = krylov(model, ports, r, band=BAND, points_tol=1.0)  # no fallback: the single point
        _, res = reduce_and_judge(model, "krylov", r, ports, full=full, band=BAND, points_tol=1.0)
        est.append(basis.info["points_check"]["single_point"]["estimate"])
        err.append(res["band_error"])
    assert est[0] > est[1] > est[2] and err[0] > err[1] > err[2]
    assert all(e <= s for e, s in zip(err, est)), (err, est)


def test_explicit_points_are_not_checked_and_bad_tol(beam):
    model, ports, _ = beam
    basis = krylov(model, ports, 8, points="50,500")
    assert "points_check" not in basis.info and len(basis.info["points_hz"]) == 2
    with pytest.raises(OptionError, match="points_tol"):
        krylov(model, ports, 8, points_tol=0.0)


def test_the_checks_projection_is_the_bodys(beam):
    """The check's reduced matrices serve project(); a copy of V or another model is projected anew."""
    import dataclasses

    import numpy as np

    from flexmor.basis import Basis
    from flexmor.damping import ModalDamping
    from flexmor.projection import project

    model, ports, _ = beam
    basis = krylov(model, ports, 8, band=BAND)
    assert basis.reduced is not None and basis.reduced.of(model, basis.V)
    fresh = project(model, Basis(basis.V.copy(), "krylov"), ports)
    red = project(model, basis, ports)
    for a, b in ((red.M, fresh.M), (red.K, fresh.K), (red.D, fresh.D)):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    assert red.M is basis.reduced.M  # shared, not recomputed
    stiffer = dataclasses.replace(model, K=model.K * 2.0)  # the same V on another model: its own products
    assert np.allclose(project(stiffer, basis, ports).K, 2.0 * fresh.K, rtol=1e-12, atol=0)
    undamped = dataclasses.replace(model, D=None)
    assert project(undamped, basis, ports).D is None
    modal = model.with_damping(ModalDamping(1.5e-4, 5e-7, zeta=0.02, band=BAND))
    mb = krylov(modal, ports, 8, band=BAND)  # modal damping: the body's own modes, from the shared Mr, Kr
    assert mb.reduced is not None
    got, want = project(modal, mb, ports).D, project(modal, Basis(mb.V.copy(), "krylov"), ports).D
    assert np.abs(got - want).max() <= 1e-10 * np.abs(want).max()
