"""Second-order IRKA: convergence and H2 error against krylov of the same order."""

import logging

import numpy as np
import pytest
from helpers import DATA

from flexmor.analysis.norms import h2_error
from flexmor.io import read
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce


@pytest.fixture(scope="module")
def lf10():
    model = read(DATA / "mor" / "LF10.mat")
    return model, make_ports(model)


@pytest.fixture(scope="module")
def cant3():
    model = cantilever(2).with_rayleigh(10.0, 1e-6)  # 540 DOF
    return model, make_ports(model, ["TIP:x", "TIP:y", "TIP:z"])


@pytest.mark.slow
def test_h2_modal_formula_equals_lyapunov():
    model = cantilever(1).with_rayleigh(10.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    red = reduce(model, "krylov", 8, ports)
    a = h2_error(model, ports, red, method="modal")
    b = h2_error(model, ports, red, method="lyapunov")
    assert abs(a / b - 1) < 1e-3 and 1e-3 < a < 1


@pytest.mark.slow
@pytest.mark.parametrize("r", [2, 4, 6, 8])
def test_irka_lf10_converges_and_beats_krylov_in_h2(lf10, r):
    model, ports = lf10
    ri = reduce(model, "irka", r, ports)
    assert ri.info["converged"] and ri.info["iterations"] < 50
    rk = reduce(model, "krylov", r, ports)
    omega = np.geomspace(1e-2, 1e11, 651)  # LF10 poles lie between 1e2 and 3e9 rad/s
    e_i = h2_error(model, ports, ri, omega=omega)
    e_k = h2_error(model, ports, rk, omega=omega)
    assert e_i <= e_k, (e_i, e_k)


@pytest.mark.slow
@pytest.mark.parametrize("r", [6, 12])
def test_irka_cantilever_three_inputs(cant3, r):
    model, ports = cant3
    ri = reduce(model, "irka", r, ports)
    assert ri.info["converged"], ri.info["shift_history"]
    assert ri.order == r
    # H2-optimal interpolation is a local optimum: below Krylov at one real point (the earlier default: 0.17 and
    # 0.017 at r = 6, 12), and near Krylov's greedy points (0.13 and 8.0e-3; irka 0.12 and 9.4e-3)
    one = reduce(model, "krylov", r, ports, points=str(np.sqrt(1000.0)))
    rk = reduce(model, "krylov", r, ports)
    e = h2_error(model, ports, ri)
    assert e <= h2_error(model, ports, one) and e <= 1.5 * h2_error(model, ports, rk)


def test_irka_reports_nonconvergence(cant3, caplog):
    model, ports = cant3
    with caplog.at_level(logging.WARNING):
        ri = reduce(model, "irka", 8, ports, max_iter=1)
    assert not ri.info["converged"] and ri.info["iterations"] == 1
    assert "did not converge" in caplog.text
    assert ri.order == 8 and np.isfinite(ri.frequencies_hz()).all()


def test_undamped_body_gets_a_clear_error(clamped):
    """Undamped: the points land on eigenfrequencies; the message says so instead of 'free-free body'."""
    from flexmor.errors import SolverError

    ports = make_ports(clamped, ["TIP:y"])
    with pytest.raises(SolverError, match="undamped body.*rayleigh"):
        reduce(clamped, "irka", 6, ports)
