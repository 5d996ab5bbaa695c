"""Moving loads (flexmor.moving): the path, its compressed inputs, bodies judged over the path and in a crossing."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as sla
from helpers import CCX, run, run_json

from flexmor.damping import Rayleigh
from flexmor.errors import OptionError, PortError
from flexmor.models.solid import cantilever
from flexmor.moving import hat_weights, judge_paths, moving_path
from flexmor.ports import body_ports
from flexmor.selection import with_selections
from flexmor.study import System

#: a line of 41 nodes along the top of a 1 m steel beam (clamped at x = 0, 1,080 DOF), its centre line
TOP = "PATH=box:0,0.05,0.1,1,0.05,0.1"
BAND = (1.0, 2000.0)
BEAM = str(CCX / "beam8_clamped_mat.inp")


@pytest.fixture(scope="module")
def beam():
    return with_selections(cantilever(divisions=(40, 2, 2)), [TOP]).with_damping(Rayleigh(1.0, 1e-6))


@pytest.fixture(scope="module")
def system():
    return System(cantilever(divisions=(40, 2, 2)), moving_loads=["PATH:z@x"], select=[TOP], inputs=["TIP:y"],
                  band=BAND, damping=Rayleigh(1.0, 1e-6), cache=False)


@pytest.fixture(scope="module")
def krylov(system):
    return system.reduce_and_judge("krylov", 40)


def test_the_path_is_ordered_along_it_by_a_coordinate_or_as_a_chain(beam):
    by_x = moving_path(beam, "PATH:z@x")
    chain = moving_path(beam, "path:Z")  # the set's name and the direction in any case
    assert by_x.nodes.size == 41 and by_x.ordering == "by x"
    x = beam.node_xyz(by_x.nodes)[:, 0]
    assert np.all(np.diff(x) > 0)
    np.testing.assert_allclose(by_x.s, x - x[0], atol=1e-12)
    assert by_x.length == pytest.approx(1.0)
    # the chain starts at an end of the line and walks it: the same nodes, in one of the two directions
    assert "nearest-neighbour chain" in chain.ordering
    assert list(chain.nodes) in (list(by_x.nodes), list(by_x.nodes[::-1]))
    np.testing.assert_allclose(chain.s, by_x.s, atol=1e-12)
    # the node at the clamp has no equation in z: its column is zero, the others a unit force each
    held = np.asarray(by_x.B.sum(axis=0)).ravel()
    assert held[0] == 0 and np.all(held[1:] == 1)


def test_a_zigzag_set_is_chained_by_its_neighbours(beam):
    """Nodes of a set given out of order along an L-shaped line: the chain follows the line."""
    from flexmor.selection import add_node_set

    xyz = beam.xyz
    ids = beam.node_ids
    top = np.isclose(xyz[:, 2], 0.1)
    line1 = ids[top & np.isclose(xyz[:, 1], 0.05) & (xyz[:, 0] <= 0.5 + 1e-9)]
    line2 = ids[top & np.isclose(xyz[:, 0], 0.5) & (xyz[:, 1] < 0.05 - 1e-9)]
    rng = np.random.default_rng(1)
    m = add_node_set(beam, "LPATH", rng.permutation(np.concatenate([line1, line2])))
    path = moving_path(m, "LPATH:z")
    steps = np.linalg.norm(np.diff(m.node_xyz(path.nodes), axis=0), axis=1)
    np.testing.assert_allclose(steps[:20], 0.025, rtol=1e-9)  # along x (40 elements per m), then across y (2 per
    np.testing.assert_allclose(steps[20:], 0.05, rtol=1e-9)  # 0.1 m): every step to a neighbour, no jumps back
    assert path.length == pytest.approx(0.5 + 0.05)


@pytest.mark.parametrize("spec, words", [
    ("PTH:z", ["no node set 'PTH'", "PATH"]),
    ("PATH:rx", ["x, y or z"]),
    ("PATH", ["SET:DIR"]),
    ("PATH:z@w", ["@w"]),
    ("TIP:y@x", ["share x", "ambiguous"]),  # the tip face's nodes share x
])
def test_bad_moving_loads_are_refused_naming_them(beam, spec, words):
    with pytest.raises((OptionError, PortError)) as exc:
        moving_path(beam, spec)
    for w in words:
        assert w in str(exc.value)


def test_hat_weights_interpolate_linearly_between_path_nodes():
    s_nodes = np.array([0.0, 0.1, 0.3, 0.6])
    W = hat_weights(s_nodes, [0.0, 0.05, 0.1, 0.25, 0.6, 0.7, -0.1])
    np.testing.assert_allclose(W[0], [1, 0, 0, 0])
    np.testing.assert_allclose(W[1], [0.5, 0.5, 0, 0])
    np.testing.assert_allclose(W[2], [0, 1, 0, 0])
    np.testing.assert_allclose(W[3], [0, 0.25, 0.75, 0])
    np.testing.assert_allclose(W[4], [0, 0, 0, 1])
    assert not W[5].any() and not W[6].any()  # off the path: no load


def test_one_krylov_body_holds_for_every_position_of_the_path(system, krylov):
    body, rec = krylov
    comp = system.moving[0][1]
    assert 1 < comp.k < 41  # compressed: fewer loads than path nodes
    np.testing.assert_allclose(comp.W.T @ comp.W, np.eye(comp.k), atol=1e-12)
    assert body.order == 40
    m = rec["moving_loads"][0]
    assert m["path_max_band_error"] <= 1e-4, m
    assert m["held_positions"] == 1  # the node at the clamp
    assert m["n_positions"] >= 81 + 16
    # the body keeps every path node's reduced load: V^T B_path
    Bp = np.asarray(body.info["moving_loads"][0]["B_path"])
    np.testing.assert_allclose(Bp, np.asarray((system.moving[0][0].B.T @ body.V).T), atol=1e-15)


def test_the_judge_sees_each_position_as_a_direct_solve_does(system, krylov):
    """The path judge's response under a load between two nodes equals the full model's direct solution with
    the force shared by those nodes, and the body's equals its own solution with V^T b(s) (the interpolation)."""
    body, _ = krylov
    path = system.moving[0][0]
    system.judge_paths(body)
    full = next(iter(system._path_full.values()))  # the full model's path FRF the judge used
    s = 0.60625  # a quarter into the segment between the nodes at 0.6 and 0.625 m
    w = path.weights([s])[0]
    assert np.count_nonzero(w) == 2 and w.max() == pytest.approx(0.5 + 0.25)
    b = path.B @ w
    f = float(full.freqs[len(full.freqs) // 3])
    m = system.model
    om = 2 * np.pi * f
    A = (m.K - om ** 2 * m.M + 1j * om * m.D).tocsc()
    u = sla.spsolve(A, b.astype(complex))
    i = int(np.flatnonzero(full.freqs == f)[0])
    H = full.H[i, 1:, :]  # the path rows (the first output is TIP:y)
    np.testing.assert_allclose(w @ H @ w, b @ u, rtol=1e-9)
    Bp = np.asarray(body.info["moving_loads"][0]["B_path"]) @ w
    np.testing.assert_allclose(Bp, body.V.T @ b, rtol=1e-12, atol=1e-15)  # B_r(s) = V^T B(s)


def test_methods_without_inputs_get_the_paths_static_responses(system):
    """Craig-Bampton, modal and Guyan ignore the inputs: with a moving load they get the static responses of its
    compressed loads, so the body's static deflection under the load is right at every position."""
    body, rec = system.reduce_and_judge("modal", 40)
    assert body.info["residual_vectors"] > system.moving[0][1].k - 1
    path = system.moving[0][0]
    Bp = np.asarray(body.info["moving_loads"][0]["B_path"])
    K = system.model.K.tocsc()
    err = {}
    for s in (0.05, 0.1, 0.3125, 0.5, 0.77, 1.0):
        w = path.weights([s])[0]
        b = path.B @ w
        full = b @ sla.spsolve(K, b)
        red = (Bp @ w) @ np.linalg.solve(body.K, Bp @ w)
        err[s] = abs(red - full) / abs(full)
    # near the clamp the local deformation is the whole response (modal 40 alone: 68 % and 36 % off at 0.05 and
    # 0.1 m); elsewhere within the compression's tolerance (3e-3 of the singular values: 0.5 % at mid-span)
    assert err[0.05] < 1e-9 and err[0.1] < 1e-9, err
    assert max(err.values()) < 1e-2, err
    assert rec["moving_loads"][0]["path_max_band_error"] < 1e-3


def test_a_slow_crossing_follows_the_static_deflection_and_the_body_follows_the_full_model(system, krylov):
    body, _ = krylov
    c = system.crossing(body, 1.0, force=1000.0, steps=400)  # 1 s for 1 m: first mode at 100 Hz, quasi-static
    path = system.moving[0][0]
    t = np.asarray(c["t"])
    y = np.asarray(c["under_load"])
    K = system.model.K.tocsc()
    for s in (0.5, 0.75, 1.0):
        k = int(np.argmin(abs(t - s)))
        b = path.B @ path.weights([s])[0]
        static = 1000.0 * (b @ sla.spsolve(K, b))
        assert y[k] == pytest.approx(static, rel=2e-2)
    assert c["time_max_error"] < 1e-2 and c["seconds_body"] < c["seconds_full"]
    # the study's output: a z load does not move the tip in y (3e-20 m at the full model's tip under 1 N at
    # mid-span, where the load point moves 2.3e-8 m): its relative error is that of round-off, not asserted
    assert c["outputs"]["names"] == ["TIP:y"] and np.isfinite(c["outputs"]["time_max_error"])
    fast = system.crossing(body, 40.0)
    assert fast["time_max_error"] < 1e-2
    with pytest.raises(OptionError, match="speed"):
        system.crossing(body, -1.0)


def test_bodies_files_rebuild_their_ports_and_are_judged_again(system, krylov, tmp_path):
    from flexmor.io import read_body, write_body

    body, rec = krylov
    write_body(body, tmp_path / "b.h5")
    again = read_body(tmp_path / "b.h5")
    ports = body_ports(system.model, again)
    assert ports.input_names == system.ports.input_names
    assert abs(ports.B - system.ports.B).max() < 1e-15
    r = judge_paths(system.model, again, BAND, cache=False)[0]
    assert r["path_max_band_error"] == pytest.approx(rec["moving_loads"][0]["path_max_band_error"], rel=1e-6)


def test_the_command_line_reduces_judges_compares_and_saves_the_study(capsys, tmp_path):
    common = ["--select", "PATH=box:0,0.05,0.1,1,0.05,0.1", "--moving-load", "PATH:z@x", "--input", "TIP:y",
              "--band", "1:3000", "--rayleigh", "1:1e-6", "--no-cache"]
    body = tmp_path / "k.h5"
    rec = run_json(capsys, "reduce", BEAM, "--method", "krylov", "--order", "30", *common, "--crossing", "10",
                   "--crossing", "40", "-o", body, "--save-study", tmp_path / "s.toml")
    m = rec["moving_loads"][0]
    assert m["path"] == "PATH:z" and m["path_max_band_error"] < 1e-3
    assert [c["speed"] for c in rec["crossings"]] == [10.0, 40.0]
    assert all(c["time_max_error"] < 1e-2 for c in rec["crossings"])
    code, out, err = run(capsys, "compare", BEAM, body, "--no-cache")
    assert code == 0, err
    assert "moving load" in out and "path max" in out
    code, out, err = run(capsys, "report", BEAM, body, "-o", tmp_path / "r.html", "--no-cache")
    assert code == 0, err
    page = (tmp_path / "r.html").read_text()
    assert '<h2 id="moving">Moving loads</h2>' in page
    assert page.count('alt="band error along the path"') == 1 and "1 N crossing" not in page  # figures as images
    assert "40" in page.split('id="moving"')[1].split("</table>")[1]  # the recorded speeds are crossed again
    again = run_json(capsys, "run", tmp_path / "s.toml", "-o", tmp_path / "k2.h5")
    assert again["moving_loads"][0]["path_max_band_error"] == pytest.approx(m["path_max_band_error"], rel=1e-9)
    code, out, err = run(capsys, "reduce", BEAM, "--method", "krylov", "--order", "30", "--input", "TIP:y",
                         "--crossing", "10", "-o", tmp_path / "x.h5")
    assert code == 2 and "--crossing needs a --moving-load" in err


def test_a_free_plate_structure_is_judged_and_crossed_by_its_elastic_part():
    """The plate structure flying free (3,096 DOF), a path across its top plate: the judge and the crossing see the
    elastic part (the rigid motion belongs to the frame); the crossing starts in the inertia-relief deflection
    under the force at the path's first node (at the plate's edge: starting undeformed is a step load)."""
    from flexmor.models.plate_structure import plate_structure

    S = System(plate_structure(n=12, lower="free"), moving_loads=["PATH:z@x"],
               select=["PATH=box:-0.25,0,0.02,0.25,0,0.02"], interfaces=["HOLE@rbe2"], band=(1, 2000),
               damping=Rayleigh(2.0, 1e-6), cache=False)
    body, rec = S.reduce_and_judge("fw-sobt", 60)
    m = rec["moving_loads"][0]
    assert m["overall"]["judged"].startswith("elastic part")
    assert m["path_max_band_error"] < 1e-8 and m["held_positions"] == 0
    # the path crosses the hole's edge, whose nodes are slaves of HOLE@rbe2: their force acts on the master as
    # the force and its moment about it
    from flexmor.couplings import coupling_masters

    master = coupling_masters(S.model)[0]
    path = S.moving[0][0]
    j = next(i for i, k in enumerate(path.nodes) if k in set(master["slaves"].tolist()))
    col = path.B[:, j].toarray()[:, 0]
    r = S.model.node_xyz([path.nodes[j]])[0] - np.asarray(master["xyz"])
    dofs = [S.model.dof_index(master["id"], d) for d in range(1, 7)]
    np.testing.assert_allclose(col[dofs], [0, 0, 1, *np.cross(r, [0, 0, 1])], atol=1e-15)
    assert np.count_nonzero(col) == np.count_nonzero(col[dofs])
    c = S.crossing(body, 5.0, force=100.0)
    assert c["time_max_error"] < 1e-3, c["time_max_error"]  # 4.8e-5 seen; undeformed start: 1.9e-2
    rest = S.crossing(body, 5.0, force=100.0, start="rest")
    assert rest["time_max_error"] > 10 * c["time_max_error"]  # the step load's response above the band


@pytest.mark.parametrize("method, options", [("two-step", {}), ("pod", {}),
                                             ("craig-bampton", {"interface": ["TIP_CENTER"]})])
def test_every_kind_of_method_builds_for_the_compressed_loads(system, method, options):
    """Methods that take inputs build for the compressed loads; Craig-Bampton gets their static responses beside
    its interface's constraint modes (not one per path node)."""
    body, rec = system.reduce_and_judge(method, 50, **options)
    assert body.order <= 52  # a multiple eigenvalue at the cut is kept whole
    assert rec["moving_loads"][0]["path_max_band_error"] < 1e-3, (method, rec["moving_loads"][0])
    if method == "craig-bampton":
        assert body.info["residual_vectors"] >= system.moving[0][1].k - 1


def test_a_path_over_an_rbe3_couplings_dependent_dofs_is_refused_naming_them(beam):
    """An RBE3 coupling eliminates six translations of its set: a force there has no equation in the coupled
    model (an RBE2 slave passes it to the master; a held node carries none)."""
    from flexmor.couplings import couple, coupling_masters
    from flexmor.selection import add_node_set

    coupled = couple(beam, ["TIP@rbe3"]).model
    master = coupling_masters(coupled)[0]
    eq = set(map(tuple, coupled.dofs.tolist()))
    node = next(int(n) for n in master["slaves"] if (int(n), 3) not in eq)  # a node whose z the coupling took
    other = next(int(n) for n in coupled.node_ids if (int(n), 3) in eq and int(n) not in master["slaves"])
    m = add_node_set(coupled, "ONTIP", [node, other])
    with pytest.raises(PortError, match=rf"path node {node} .*TIP@RBE3.*dependent DOF"):
        moving_path(m, "ONTIP:z")
