"""Modal, Guyan and Craig-Bampton on the CalculiX beam: numbers that are wrong if a method is wrong."""

import numpy as np
import pytest

from flexmor.dynamics import frf_full, frf_reduced
from flexmor.errors import OptionError
from flexmor.linalg import SolverContext, available_backends, factorize
from flexmor.linalg.eigen import eigenmodes, frequencies_hz
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.workflow import reduce_and_judge


def _static(model, ports):
    X = factorize(model.K, positive=True).solve(ports.B.toarray())
    return ports.C @ X


@pytest.mark.parametrize("r,got", [(1, 2), (5, 5), (12, 12)])
def test_modal_reproduces_lowest_frequencies(clamped, r, got):
    """Order 1 would cut the first bending pair (100.05 Hz in y and z, a square section): both are kept."""
    ports = make_ports(clamped, ["TIP:y"])
    red = reduce(clamped, "modal", r, ports)
    lam, _ = eigenmodes(clamped.K, clamped.M, got)
    assert red.order == got and (red.order_note is None) == (got == r)
    np.testing.assert_allclose(red.frequencies_hz(), frequencies_hz(lam), rtol=1e-8)


def test_modal_free_free_excludes_rigid_modes(free, free_ref):
    ports = make_ports(free, ["TIP:y"])
    red = reduce(free, "modal", 5, ports)
    assert red.info["n_rigid"] == 6
    np.testing.assert_allclose(red.frequencies_hz(), free_ref[6:11], rtol=1e-5)
    red = reduce(free, "modal", 8, ports, rigid="include")
    assert np.all(red.frequencies_hz()[:6] < 1e-2)


def test_craig_bampton_static_tip_response(clamped):
    ports = make_ports(clamped, ["TIP:y", "TIP:x"], ["TIP:y", "TIP:z"])
    red = reduce(clamped, "craig-bampton", 27 + 6, ports, interface=["TIP"])
    H0 = _static(clamped, ports)
    Hr0 = red.C @ np.linalg.solve(red.K, red.B)
    assert np.linalg.norm(Hr0 - H0) / np.linalg.norm(H0) < 1e-10
    assert red.info["n_modes"] == 6


def test_guyan_exact_at_zero_frequency(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    red = reduce(clamped, "guyan", None, ports, interface=["TIP"])
    assert red.order == 27
    H0 = frf_full(clamped, ports, [0.0])[0]
    Hr0 = frf_reduced(red, [0.0])[0]
    assert abs(Hr0 - H0).max() / abs(H0).max() < 1e-10


def test_craig_bampton_free_body(free, free_ref):
    # the tip face holds the free body: K_ii is regular and the fixed-interface modes exist
    ports = make_ports(free, ["TIP:y"])
    red = reduce(free, "craig-bampton", 40, ports, interface=["TIP"], rigid="include")
    f = red.frequencies_hz()
    assert np.sum(f < 1.0) == 6  # rigid-body modes are in the CB space
    assert abs(f[6] / free_ref[6] - 1) < 1e-2  # and the first flexible mode is close
    # by default the rigid motion leaves the basis (floating frame): same order, same elastic modes
    ex = reduce(free, "craig-bampton", 40, ports, interface=["TIP"])
    assert ex.order == 40 and ex.info["n_rigid_excluded"] == 6
    assert abs(ex.frequencies_hz()[0] / free_ref[6] - 1) < 1e-2 and ex.frequencies_hz()[0] >= free_ref[6] * (1 - 1e-5)


def test_modal_band_error_decreases(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    from flexmor.analysis.compare import FullResponse

    full = FullResponse(clamped, ports, (10.0, 3000.0))
    errs = [reduce_and_judge(clamped, "modal", r, ports, full=full)[1]["band_error"] for r in (2, 4, 8, 16)]
    assert all(b < a for a, b in zip(errs, errs[1:])), errs
    assert errs[-1] < 1e-6


@pytest.mark.skipif(len(available_backends()) < 2, reason="needs a fast backend")
@pytest.mark.parametrize("method,order,opts", [("modal", 8, {}), ("craig-bampton", 35, {"interface": ["TIP"]}),
                                               ("guyan", None, {"interface": ["TIP"]})])
def test_same_results_with_every_backend(clamped, method, order, opts):
    ports = make_ports(clamped, ["TIP:y"])
    freqs = np.array([50.0, 300.0, 1000.0])
    H = []
    for b in available_backends():
        solver = SolverContext(b)
        red = reduce(clamped, method, order, ports, solver=solver, **opts)
        H.append(frf_reduced(red, freqs))
        H.append(frf_full(clamped, ports, freqs, solver=solver))
        assert red.info["options"]["backend"] == b and solver.stats.count >= 3
    for h in H[2::2]:
        assert np.abs(h - H[0]).max() / np.abs(H[0]).max() < 1e-8
    for h in H[3::2]:
        assert np.abs(h - H[1]).max() / np.abs(H[1]).max() < 1e-8


def test_method_option_errors(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    with pytest.raises(OptionError, match="craig-bampton"):
        reduce(clamped, "nonsense", 4, ports)
    with pytest.raises(OptionError, match="interface"):
        reduce(clamped, "craig-bampton", 4, ports)
    with pytest.raises(OptionError, match="does not take"):
        reduce(clamped, "modal", 4, ports, interface=["TIP"])
    with pytest.raises(OptionError, match="interface DOFs"):
        reduce(clamped, "craig-bampton", 10, ports, interface=["TIP"])


def test_hinf_error_band_estimate(clamped):
    from flexmor.analysis.frequency import hinf_error

    ports = make_ports(clamped, ["TIP:y", "TIP:z"])
    freqs = np.geomspace(10, 3000, 400)
    H = frf_full(clamped, ports, freqs)
    red = reduce(clamped, "modal", 6, ports)
    Hr = frf_reduced(red, freqs)
    E = H - Hr
    expect = max(np.linalg.svd(e, compute_uv=False)[0] for e in E) / max(
        np.linalg.svd(h, compute_uv=False)[0] for h in H)
    assert hinf_error(H, Hr) == pytest.approx(expect, rel=1e-12)
    assert hinf_error(H, H) == 0.0
    red2 = reduce(clamped, "modal", 12, ports)
    assert hinf_error(H, frf_reduced(red2, freqs)) < hinf_error(H, Hr)
