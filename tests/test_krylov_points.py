"""Krylov's default expansion points: greedy where the body's error is largest, and an estimate that holds."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import ROOT

import flexmor
import flexmor.io
from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError
from flexmor.linalg import SolverContext
from flexmor.models import plate_structure
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.reduction.greedy_points import ResidualIndicator, greedy_basis
from flexmor.reduction.krylov import krylov

BAND = (10.0, 1000.0)


@pytest.fixture(scope="module")
def beam(clamped):
    model = clamped.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    return model, ports, FullResponse(model, ports, BAND, cache=False)


def test_static_point_first_then_points_on_the_axis(beam):
    model, ports, _ = beam
    solver = SolverContext()
    basis = krylov(model, ports, 12, band=BAND, solver=solver)
    pts = [complex(p) for p in basis.info["points_hz"]]
    assert pts[0] == 0 and all(p.real == 0 and BAND[0] <= p.imag <= BAND[1] for p in pts[1:]), pts
    check = basis.info["points_check"]
    assert len(check["checks_hz"]) == 2 and check["checks_hz"][0] == check["check_hz"]
    assert abs(check["checks_hz"][1] - check["check_hz"]) > 0.05 * check["check_hz"]
    built = basis.info.get("points_built", len(pts))  # the body's columns may come from the first of them
    assert len(pts) <= built and solver.stats.count == built + 2  # one factorization per point, two for the estimate
    body = flexmor.project(model, basis, ports)
    G = ports.C @ np.linalg.solve(model.K.toarray(), ports.B.toarray())  # the static compliance is matched
    Gr = body.C @ np.linalg.solve(body.K, body.B)
    assert np.linalg.norm(G - Gr) <= 1e-9 * np.linalg.norm(G)


def test_the_basis_is_nested(beam):
    """The order stops the greedy sequence and changes nothing before: the target-error search relies on it."""
    model, ports, _ = beam
    V8 = krylov(model, ports, 8, band=BAND, compress="off").V
    V12 = krylov(model, ports, 12, band=BAND, compress="off").V
    assert np.abs(V12[:, :8] - V8).max() <= 1e-10


def test_the_indicator_is_the_residual_formed_in_full(beam):
    """The Gram form of ``||F - A(w) V x(w)||`` equals the residual of the same states formed with the full
    matrices, up to its stated rounding (the states themselves: one small solve, the indicator's)."""
    model, ports, _ = beam
    V = krylov(model, ports, 10, band=BAND).V
    F = ports.B.toarray()
    F = F / np.linalg.norm(F, axis=0)
    ind = ResidualIndicator(model, F, BAND)
    ind.extend(V[:, :0], V[:, :4])
    ind.extend(V[:, :4], V[:, 4:])  # built in two steps: the cross terms of the Gram matrix
    f = np.array([20.0, 333.0, 900.0])
    got = ind(f)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        A = (model.K - w * w * model.M + 1j * w * model.D).tocsc()
        x = ind._states(np.array([w]))[0]
        exact = np.linalg.norm(F - A @ (V @ x)) / np.linalg.norm(F)
        W = np.hstack([model.K @ V, model.M @ V, model.D @ V])
        c = np.abs(np.vstack([x, -w * w * x, 1j * w * x]))
        terms = np.sum(c * (np.abs(W.T @ W) @ c)) + 2 * np.sum(np.abs(W.T @ F) * c) + np.sum(F ** 2)
        assert abs(got[k] ** 2 - exact ** 2) <= 3 * V.shape[1] * np.finfo(float).eps * terms / np.sum(F ** 2)


def test_options_and_errors(beam):
    model, ports, _ = beam
    basis = krylov(model, ports, 8, points="50,500")
    assert "points_check" not in basis.info and len(basis.info["points_hz"]) == 2
    with pytest.raises(OptionError, match="order"):
        krylov(model, ports, None)
    one = krylov(model, ports, 12, band=BAND, moments=2)
    assert set(one.info["moments"]) == {2}


def test_the_checks_projection_is_the_bodys(beam):
    """The greedy's reduced matrices serve project(): equal to a fresh projection."""
    from flexmor.basis import Basis
    from flexmor.projection import project

    model, ports, _ = beam
    basis = krylov(model, ports, 8, band=BAND)
    assert basis.reduced is not None and basis.reduced.of(model, basis.V)
    fresh = project(model, Basis(basis.V.copy(), "krylov"), ports)
    red = project(model, basis, ports)
    for a, b in ((red.M, fresh.M), (red.K, fresh.K), (red.D, fresh.D)):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


def _corner(model) -> str:
    return f"{int(model.node_ids[np.argmin(np.linalg.norm(model.xyz - [0.25, 0.25, 0.02], axis=1))])}:z"


@pytest.fixture(scope="module")
def corner_clamped():
    """The corner case: the plate structure clamped, one port at its top corner (z), 1 % modal damping."""
    m = plate_structure(20)
    return flexmor.System(m, inputs=[_corner(m)], band=(1.0, 2000.0), damping={"modal_damping": 0.01}, cache=False)


@pytest.fixture(scope="module")
def corner_free():
    """The free structure held by the RBE2 of its hole (six directions) plus the corner's z."""
    m = plate_structure(20, lower="free")
    return flexmor.System(m, inputs=[f"HOLE@rbe2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")] + [_corner(m)],
                          interfaces=["HOLE@rbe2"], band=(1.0, 2000.0), damping={"modal_damping": 0.01},
                          cache=False)


@pytest.mark.parametrize("case, order, inertia", [("corner_clamped", 20, "off"), ("corner_clamped", 40, "auto"),
                                                  ("corner_free", 45, "auto")])
def test_default_points_are_as_good_as_fw_sobt_and_the_estimate_holds(case, order, inertia, request):
    """On the case the default points failed (a 33,735-DOF C3D10 plate structure: the earlier default gave 4.2e-2
    clamped and 5.6e-2 free, 140-200x above its own estimate), here the built-in plate structure at 6,300 DOF
    with the same ports, band, damping and orders (measured: krylov 7.4e-6 and 1.46e-6, fw-sobt 7.4e-6 and
    1.42e-6, the earlier default's single real point 1.3 and 2.6e-2): default krylov is within 3x of fw-sobt at
    the same order, and its estimate within 3x of the verified band_error. The issue's clamped case at order 20
    is for the port alone; with the frame's six inertia loads as inputs too (the default) the clamped body
    needs order 40 (at 20 every method is poor at the port: krylov 0.47, fw-sobt 0.23)."""
    S = request.getfixturevalue(case)
    body = S.reduce("krylov", order, inertia_loads=inertia)
    err = S.judge(body).band_error
    ref = S.judge(S.reduce("fw-sobt", order, inertia_loads=inertia)).band_error
    est = body.info["points_check"]["estimate"]
    assert err <= 3 * ref, (err, ref)
    assert err / 3 <= est <= 3 * err, (est, err)
    old = S.judge(S.reduce("krylov", order, points=str(np.sqrt(2000.0)), inertia_loads=inertia)).band_error
    assert err < old / 10, (err, old)  # the earlier default's single real point


@pytest.mark.parametrize("damping", [None, {"band_rayleigh": 0.01}])
def test_the_estimate_holds_where_the_body_misses_a_cluster_away_from_its_largest_residual(damping):
    """The Abaqus C3D10 block (771 DOF, free), one port at a corner (z), 10-2000 Hz (ten elastic modes, three
    of them at 1026.5-1033.3 Hz), order 12. Undamped, the body's residual is largest beside its own resonance
    at 1924.6 Hz (4e-6 from the full model's), while its error lies in the cluster it holds one mode of; the
    body enriched there alone missed the cluster as well: estimate 1.1e-7 against 7.5e-6 verified (67x low).
    The second check elsewhere in the band finds it (measured 1.00 undamped, 1.00 with Rayleigh damping at
    3.6e-9)."""
    model = flexmor.io.read(ROOT / "tests" / "data" / "abaqus" / "blockC3D10.inp")
    corner = int(model.node_ids[np.argmin(np.linalg.norm(model.xyz - [4.0, 1.0, 1.0], axis=1))])
    S = flexmor.System(model, inputs=[f"{corner}:z"], band=(10.0, 2000.0), damping=damping, cache=False)
    body = S.reduce("krylov", 12, compress="off")  # the greedy body's estimate (compressed: 1.6e-9 and 7e-11)
    err, check = S.judge(body).band_error, body.info["points_check"]
    assert err > 1e-9  # above the judge's round-off: the ratio means something
    assert err / 3 <= check["estimate"] <= 3 * err, (check, err)
    assert len(check["checks_hz"]) == 2
    # the pointwise figure only where the full model was solved on the axis (an undamped one: beside it)
    assert ("pointwise_at_check" in check) == (damping is not None)


def test_the_estimate_is_at_the_judged_ports_when_inertia_loads_share_the_basis(corner_clamped):
    """The frame's six inertia loads added as inputs (``inertia_loads='on'``) take most of order 20: the body is
    poor at its one port (measured 0.47), and the estimate must say so (it said 2.3e-5 when it compared the
    inputs added for the basis too, whose large responses hid the port's)."""
    S = corner_clamped
    body = S.reduce("krylov", 20, inertia_loads="on")
    assert body.info["n_inertia_loads"] == 6 and body.input_names == S.ports.input_names
    err, est = S.judge(body).band_error, body.info["points_check"]["estimate"]
    assert err / 3 <= est <= 3 * err, (est, err)


def test_the_pointwise_figure_of_the_estimate_is_the_full_models(corner_clamped):
    """At the frequency of the estimate's check the enriched body interpolates the full model: the body's
    pointwise error there equals its error against a direct solve."""
    from flexmor.dynamics.frf import frf_full, frf_reduced, rel_error

    S = corner_clamped
    model = S.model.with_rayleigh(0.0, 1e-6)  # a damping the sparse solve holds exactly
    body = reduce(model, "krylov", 10, S.ports, band=S.band)
    check = body.info["points_check"]
    f = np.array([check["check_hz"]])
    true = rel_error(frf_full(model, S.ports, f), frf_reduced(body, f))[0]
    assert check["pointwise_at_check"] == pytest.approx(true, rel=1e-6)


def test_greedy_basis_stops_on_its_tolerance(beam):
    """With ``tol`` the sequence stops at the first body whose predecessor is within ``tol`` of it; the body
    returned (with the latest point) is then at least as good by the judge."""
    model, ports, full = beam
    from flexmor.reduction.free_body import rigid_head

    phi, head = rigid_head(model, ports.B.toarray(), "exclude")
    V, info, _ = greedy_basis(model, ports, None, BAND, side="input", solver=SolverContext(), phi=phi, head=head,
                              moments=1, estimate=False, tol=1e-8, max_points=40)
    assert info["estimates"][-1] < 1e-8 <= min(info["estimates"][:-1], default=1.0)
    body = flexmor.project(model, V, ports)
    assert full.evaluate(body).band_error <= 1e-8


def _hole(lower):
    m = plate_structure(20, lower=lower)
    return flexmor.System(m, inputs=[f"HOLE@rbe2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")],
                          interfaces=["HOLE@rbe2"], band=(1.0, 2000.0), damping={"band_rayleigh": 0.01}, cache=False)


@pytest.mark.parametrize("lower", ["clamped", "free"])
def test_default_krylov_compresses_where_the_greedy_body_spends_its_order_on_whole_load_directions(lower):
    """The plate structure (6,200-6,300 DOF) with the six directions of its hole's RBE2 and the frame's six inertia
    loads at order 30: the greedy basis of the order gets few points (measured 2.9e-3 clamped, 1.1e-3 free;
    fw-sobt 1.1e-9 and 2.8e-12, with static errors over the field of 1.6e-2 and 1.5e-3 against the reference).
    The default builds the greedy basis to 1.5-2 times the order and takes the best candidate whose static
    responses are those of the reference (to 1e-6): the twelve static responses and the balanced truncation's
    leading directions (measured 1.8e-6 clamped, 1.6e-12 free); its estimate within 3x of the verified
    band_error; one factorization per point and two for each reference."""
    from flexmor.analysis.assembly import Assembly
    from flexmor.errors import FlexmorWarning
    from flexmor.reduction.greedy_compress import STATIC_TOL

    S = _hole(lower)
    solver = SolverContext()
    body = S.reduce("krylov", 30, solver=solver)
    err = S.judge(body).band_error
    greedy = S.judge(S.reduce("krylov", 30, compress="off")).band_error
    rec, check = body.info["compressed"], body.info["points_check"]
    assert rec["body"] == "static+balanced" and rec["from_order"] >= 45 and body.info["nested"] is False
    assert rec["static_errors"]["static+balanced"] < 1e-5  # the static responses are in the basis
    # the plain balanced truncation: closer to the reference at the ports, but its static responses are off
    assert rec["static_errors"]["balanced"] > STATIC_TOL and "balanced" not in rec["admitted"]
    assert err < greedy / 1000, (err, greedy)
    if lower == "free":  # here the static responses cost no accuracy: within 3x of fw-sobt
        assert err <= 3 * S.judge(S.reduce("fw-sobt", 30)).band_error
    assert err / 3 <= check["estimate"] <= 3 * err, (check, err)
    assert check["reference_estimate"] < check["difference"] / 10  # the reference is far better than the body
    built = body.info.get("points_built", len(body.info["points_hz"]))  # the checks that grew the basis among them
    assert solver.stats.count == built + 2
    with pytest.warns(FlexmorWarning, match="balanced truncation of its greedy basis"):
        Assembly().add_body("body", body)  # no moments kept: the coupled body has no guarantee (free: also the
        # warning on its excluded rigid-body modes)


def test_after_the_static_responses_the_dynamic_part_is_balanced():
    """The CalculiX beam8 clamped with ``TIP@rbe2:y`` at order 10: seven columns hold the static responses (the
    port and the frame's six inertia loads), three are left. Balancing the dynamic part of the response (the body
    driven by the inertia forces of the static responses) chooses them better than the balancing directions of
    the whole response after the static block (measured 2.5e-5 against 2.5e-4 from the reference; the greedy
    basis of the order 1.4e-4), and the static responses stay exact."""
    from helpers import CLAMPED

    S = flexmor.System(flexmor.io.read(CLAMPED), inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"],
                       band=(10.0, 5000.0), damping={"band_rayleigh": 0.01}, cache=False)
    body = S.reduce("krylov", 10)
    rec = body.info["compressed"]
    assert rec["body"] == "static+dynamic", rec
    assert rec["static_errors"]["static+dynamic"] < 1e-10
    assert rec["differences"]["static+dynamic"] < rec["differences"]["static+balanced"] / 3
    err = S.judge(body).band_error
    assert err < S.judge(S.reduce("krylov", 10, compress="off")).band_error / 3
    check = body.info["points_check"]
    assert err / 3 <= check["estimate"] <= 3 * err, (check, err)


def test_a_body_of_the_greedy_basis_leading_columns_lists_the_points_of_its_columns():
    """The CalculiX beam8 clamped, undamped, ``TIP@rbe2:y`` at order 18: the default builds the greedy basis to
    order 27 (seven points) and keeps its 18 leading columns, which come from its first five points; its record
    listed all seven. It lists the five, with the columns each added, as the greedy basis of order 18 does
    (``compress='off'``: the same sequence of points up to there)."""
    from helpers import CLAMPED

    S = flexmor.System(flexmor.io.read(CLAMPED), inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"],
                       band=(10.0, 5000.0), damping=None, cache=False)
    body, greedy = S.reduce("krylov", 18), S.reduce("krylov", 18, compress="off")
    assert body.info["compressed"]["body"] == "greedy" and body.info["compressed"]["from_order"] > 18
    info, ref = body.info, greedy.info
    assert len(info["points_hz"]) == len(ref["points_hz"]) == len(info["moments"]) == len(info["points_columns"])
    np.testing.assert_allclose([complex(p) for p in info["points_hz"]], [complex(p) for p in ref["points_hz"]],
                               rtol=1e-9)
    assert info["points_columns"] == ref["points_columns"] and info["points_columns"][-1][1] == 18
    assert info["points_cut"] == ref["points_cut"] and len(info["rho_max"]) == len(info["points_hz"]) - 1
    spans = info["points_columns"]
    assert spans[0][0] == 0 and all(a[1] == b[0] for a, b in zip(spans, spans[1:]))  # contiguous, in order


@pytest.mark.parametrize("damping", [{"band_rayleigh": 0.01}, None])
def test_compress_band_gives_fw_sobts_band_error_and_says_the_static_responses_are_not_kept(damping):
    """``compress='band'`` chooses among all candidates on the band difference alone, and adds the balanced
    truncation of the reference body: a body judged at its ports only. The CalculiX beam8 clamped, ``TIP@rbe2:y``,
    order 10 (measured: 4.23e-7 damped and 7.24e-6 undamped, fw-sobt's figures; the default 2.5e-5 and 6.9e-4).
    Undamped, the balanced truncation of the larger greedy body is 2.9e-2 off (that order-15 body splits the pair
    at 1648.5 Hz), that of the reference body 7.2e-6. The static responses are not kept: the deflection under the
    frame's accelerations is 4.1 % off, as fw-sobt's, where the default's is at round-off; the static note
    says so."""
    from helpers import CLAMPED

    S = flexmor.System(flexmor.io.read(CLAMPED), inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"],
                       band=(10.0, 5000.0), damping=damping, cache=False)
    body, default, fw = S.reduce("krylov", 10, compress="band"), S.reduce("krylov", 10), S.reduce("fw-sobt", 10)
    err, err_fw = S.judge(body).band_error, S.judge(fw).band_error
    assert body.info["compressed"]["keep_static"] is False and default.info["compressed"]["keep_static"] is True
    assert err <= 3 * err_fw and err < S.judge(default).band_error / 30, (err, err_fw)
    if damping is None:
        assert body.info["compressed"]["body"] == "reference balanced"
    check = body.info["points_check"]
    assert err / 3 <= check["estimate"] <= 3 * err, (check, err)
    static, kept = S.static(body), S.static(default)
    assert static["frame_error"] > 1e-2 and kept["frame_error"] < 1e-9
    assert "did not keep the static responses (--compress band)" in static["note"]


@pytest.mark.parametrize("band", [(10.0, 5000.0), (10.0, 2000.0)])
def test_the_estimate_takes_a_second_reference_where_the_larger_greedy_body_is_far_worse(band):
    """The CalculiX beam8 clamped, undamped, ``TIP@rbe2:y`` at order 10: the greedy body of order 15 splits the
    bending pair at 1648.5 Hz and misses by 2.9e-2 between its halves, the body of order 10 by 6.9e-4 (3.7e-4 on
    10-2000 Hz). Its error was the reference's in the estimate: 42x and 79x the verified figure. Against a second
    reference (the first one enriched where its residual is largest) the estimate is the verified figure (measured
    1.00 on both bands)."""
    from helpers import CLAMPED

    from flexmor.reduction.greedy_compress import SECOND_REFERENCE

    S = flexmor.System(flexmor.io.read(CLAMPED), inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"], band=band,
                       damping=None, cache=False)
    solver = SolverContext()
    body = S.reduce("krylov", 10, solver=solver)
    err, check = S.judge(body).band_error, body.info["points_check"]
    assert check["reference_estimate"] > 10 * SECOND_REFERENCE * check["difference"]  # the case
    second = check["second_reference"]
    assert err / 3 <= check["estimate"] <= 3 * err, (check, err)
    assert check["estimate"] == pytest.approx(second["difference"] + second["reference_estimate"])
    assert len(check["checks_hz"]) == len(second["checks_hz"]) + 2
    # one factorization per point and two per reference
    assert solver.stats.count == body.info.get("points_built", len(body.info["points_hz"])) + len(check["checks_hz"])


@pytest.mark.parametrize("body_diff, first_diff, replaced", [(1.65, 1.05, False), (6.9e-4, 4e-22, True)])
def test_the_second_reference_replaces_the_estimate_only_where_it_is_far_better_than_the_body(
        body_diff, first_diff, replaced):
    """The second estimate (the body's difference from the second reference plus the first reference's) is taken
    where the first reference differs from the second by less than REFERENCE_MARGIN times the body's difference.
    Measured on the Ansys rotor (345 DOF, 313 modes in 10-3000 Hz, undamped, two ports at its top node, order 12),
    where no body of orders 12-34 holds the response: 1.65 and 1.05, and the second estimate, 2.7, was 5.7x below
    the verified 15.5 (the first, kept: 8.5). That body is decided by rounding (on another arithmetic path the
    same points give 3.6), so the rule is checked here on its figures; on the beam8 the second reference is far
    better than the body (6.9e-4 and 4e-22, the test above)."""
    from types import SimpleNamespace

    from flexmor.reduction.greedy_compress import _second_reference

    W, P, E2 = np.eye(7)[:, :4], np.eye(4)[:, :2], np.eye(7)[:, 4:]

    def check(B):
        assert B is W
        return {"check_hz": 120.0, "checks_hz": [120.0, 250.0]}, E2

    def differences(W2, bases, at):
        assert W2.shape == (7, 7) and bases[0].shape == (7, 2) and bases[1].shape == (7, 4) and at is None
        np.testing.assert_array_equal(bases[0][:4], P)
        return [{"estimate": body_diff}, {"estimate": first_diff}]

    rec, got = _second_reference(SimpleNamespace(D=None), W, P, check, differences)
    assert got is E2 and rec["second_reference"] == {"checks_hz": [120.0, 250.0], "order": 7,
                                                     "difference": body_diff, "reference_estimate": first_diff}
    assert ("estimate" in rec) == replaced
    if replaced:
        assert rec["estimate"] == body_diff + first_diff


def test_a_band_with_more_modes_than_the_order_is_told():
    """The Ansys rotor (345 DOF) over 10-3000 Hz holds 313 of its modes; a body of order 12 cannot hold those its
    ports see (modal 0.94), and the judge says so; over 10-300 Hz (8 modes, modal 1.0e-3) it does not."""
    model = flexmor.io.read(ROOT / "tests" / "data" / "ansys" / "rotorAnsysStiffnessMatrixSparse.txt")
    top = int(model.node_ids[np.argmax(model.xyz[:, 2] + 1e-3 * model.xyz[:, 0])])
    for band, told in (((10.0, 3000.0), True), ((10.0, 300.0), False)):
        S = flexmor.System(model, inputs=[f"{top}:x", f"{top}:y"], band=band, damping=None, cache=False)
        judged = S.judge(S.reduce("modal", 12))
        many = [n for n in judged.notes if n.startswith("the band holds")]
        assert bool(many) == told, (band, judged.band_error, judged.notes)
        if told:
            assert judged.band_error > 0.1 and many[0].startswith(
                f"the band holds {S.full.resonances.size} resonances of the full model, more than the body's order 12")
            assert S.full.resonances.size == 313


@pytest.mark.parametrize("damping", [{"band_rayleigh": 0.01}, None])
def test_default_krylov_is_as_good_as_fw_sobt_holding_the_same_static_responses(damping):
    """The CalculiX beam8 clamped, ``TIP@rbe2:y``, order 10: fw-sobt's body is better at the port (4.2e-7 damped,
    7.2e-6 undamped, against krylov's 2.5e-5 and 6.9e-4) with its static deflection under the frame's accelerations
    4 % off; krylov's holds the port's and the six accelerations' static responses (seven of its ten columns).
    With the same seven static responses and fw-sobt's three leading directions, fw-sobt's body is no better than
    krylov's (measured 2.5e-4 and 7.3e-4)."""
    from helpers import CLAMPED

    from flexmor.rigid import ACCELERATIONS

    S = flexmor.System(flexmor.io.read(CLAMPED), inputs=["TIP@rbe2:y"], interfaces=["TIP@rbe2"],
                       band=(10.0, 5000.0), damping=damping, cache=False)
    body = S.reduce("krylov", 10)
    Vs = S.reduce("krylov", 10, points="0", moments=1, compress="off").V  # the static responses
    frame = [x["field_error"] for x in S.static(body)["loads"] if x["load"] in ACCELERATIONS]
    assert Vs.shape[1] == 7 and len(frame) == 6 and max(frame) < 1e-9
    Vf = S.reduce("fw-sobt", 10 - Vs.shape[1]).V
    Q, _ = np.linalg.qr(np.hstack([Vs, Vf]))
    fw = flexmor.project(S.model, Q, S.ports)
    err, err_fw = S.judge(body).band_error, S.judge(fw).band_error
    assert err <= 1.5 * err_fw, (err, err_fw)
    assert S.judge(S.reduce("fw-sobt", 10)).band_error < err / 10  # without them: better at the port


def test_the_body_is_the_best_admitted_candidate(beam):
    """The body is the candidate that differs least from the reference among those whose static responses hold
    (the greedy one always); where that is the leading columns of the larger greedy basis, the body is nested
    and the basis ``compress='off'`` gives, which builds only to the order."""
    import flexmor.reduction.greedy_compress as gc

    model, ports, _ = beam
    basis = krylov(model, ports, 12, band=BAND)
    rec = basis.info["compressed"]
    assert rec["from_order"] in (18, 24, 36) and "greedy" in rec["admitted"]
    assert rec["body"] == min(rec["admitted"], key=lambda k: (rec["differences"][k], k != "greedy"))
    for k in rec["admitted"]:
        assert k == "greedy" or rec["static_errors"][k] <= gc.STATIC_TOL
    greedy = rec["body"] == "greedy"
    assert basis.info["nested"] is greedy
    off = krylov(model, ports, 12, band=BAND, compress="off")
    assert "compressed" not in off.info and off.info["nested"] is True
    if greedy:
        assert np.abs(basis.V - off.V).max() <= 1e-10
    assert gc.growth_orders(12, 20) == [18, 20] and gc.growth_orders(10, 1000) == [15, 20, 30]
    with pytest.raises(OptionError, match="compress"):
        krylov(model, ports, 12, band=BAND, compress="yes")


def test_static_errors_of_a_body_in_the_span():
    from flexmor.reduction.greedy_compress import static_errors

    rng = np.random.default_rng(1)
    A = rng.standard_normal((8, 8))
    K = A @ A.T + 8 * np.eye(8)
    F = rng.standard_normal((8, 2))
    u = np.linalg.solve(K, F)
    P = np.linalg.qr(np.column_stack([u, rng.standard_normal((8, 1))]))[0]
    assert static_errors(K, F, P).max() < 1e-12  # the responses in the span: exact
    assert static_errors(K, F, np.eye(8)[:, :3]).min() > 1e-3
