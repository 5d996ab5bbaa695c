"""The body in 3D: outer surface, decimation, display map, the report's scene and its viewer in Chromium."""

from __future__ import annotations

import base64

import numpy as np
import pytest
from browser import Browser, canvas_pixels, find_chromium
from helpers import cond1

from flexmor.couplings import couple
from flexmor.mesh import CellBlock, Mesh
from flexmor.models import cantilever, plate_structure
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.report.surface import decimate, outer_surface
from flexmor.report.view3d import body_scene, display_map

BAND = (10.0, 3000.0)


def _hex_block(nx, ny, nz):
    """Structured hexahedra in meshio order over the lattice, node id = lattice index + 1."""
    def nid(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k + 1

    cells = [[nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
              nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1)]
             for i in range(nx) for j in range(ny) for k in range(nz)]
    return np.array(cells)


def test_outer_surface_keeps_faces_of_one_cell_only():
    cells = _hex_block(3, 2, 1)
    s = outer_surface(Mesh([CellBlock("hexahedron", cells)]))
    assert s.n_faces == 2 * (3 * 2 + 3 * 1 + 2 * 1)  # 22 outer quads; the 7 inner faces dropped
    assert s.triangles.shape == (44, 3) and s.lines.shape == (0, 2)
    assert s.node_ids().size == 4 * 3 * 2  # every lattice node lies on the outside here
    # quadratic cells by their corners, shells as they are, beams as segments
    hex20 = np.hstack([cells, np.arange(1000, 1000 + 12 * len(cells)).reshape(len(cells), 12)])
    mixed = Mesh([CellBlock("hexahedron20", hex20), CellBlock("quad", np.array([[1, 2, 3, 4]])),
                  CellBlock("line3", np.array([[1, 5, 2]]))])
    s2 = outer_surface(mixed)
    assert s2.n_faces == 23 and s2.lines.tolist() == [[1, 5]] and s2.node_ids().max() < 1000


def test_tetra_surface_is_closed():
    model = cantilever(2, element="tet")
    s = outer_surface(model.mesh)
    edges = np.sort(np.concatenate([s.triangles[:, [0, 1]], s.triangles[:, [1, 2]], s.triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)  # a closed triangulated skin: every edge has two triangles
    assert s.n_faces == 2 * 2 * (20 * 2 + 20 * 2 + 2 * 2)  # two triangles per face of the 20x2x2 box


def test_decimation_keeps_model_nodes_within_the_limit():
    model = cantilever(6, element="tet")
    s = outer_surface(model.mesh)
    d = decimate(s, model.node_xyz(s.node_ids()), 500)
    ids = d.node_ids()
    assert 200 < ids.size <= 500 and np.all(np.isin(ids, s.node_ids()))
    assert "decimated for display" in d.decimated and len(d.triangles) < len(s.triangles) / 3
    assert decimate(s, model.node_xyz(s.node_ids()), 10 ** 6) is s


def test_built_in_models_carry_their_mesh():
    for model, cell, n in ((cantilever(2), "hexahedron", 80), (cantilever(2, element="tet"), "tetra", 480),
                           (cantilever(2, element="hex27"), "hexahedron", 80)):
        (block,) = model.mesh.blocks
        assert block.type == cell and len(block.nodes) == n
        x = model.node_xyz(block.nodes[0])
        if cell == "hexahedron":  # meshio order: 0-3 one face counter-clockwise, 4-7 the opposite one
            assert np.allclose(x[4] - x[0], x[5] - x[1]) and np.allclose(x[6] - x[2], x[4] - x[0])
            assert np.linalg.norm(x[4] - x[0]) > 0 and np.dot(x[1] - x[0], x[4] - x[0]) == pytest.approx(0)
    plate = plate_structure(6)
    assert plate.mesh.n_cells > 0 and outer_surface(plate.mesh).n_faces > 0


def test_display_map_moves_rbe2_nodes_with_their_master():
    model = cantilever(2)
    c = couple(model, ["TIP@rbe2"])
    tip = model.node_sets["TIP"]
    S = display_map(c.model, tip, [("TIP@RBE2", c.masters["TIP@RBE2"], tip)])
    q_c = np.random.default_rng(0).standard_normal(c.model.n_dof)
    q = c.T @ q_c  # the original equations, dependent ones included
    rows = [model.dof_index(n, d) for n in tip for d in (1, 2, 3)]
    assert np.allclose(S @ q_c, q[rows], rtol=1e-12, atol=1e-12)
    assert np.array_equal((display_map(model, tip) @ q), q[rows])


def test_points_where_the_model_has_no_elements():
    model = cantilever(2)
    model.mesh = None
    scene, S = body_scene(model, inputs=[1], max_nodes=50)
    assert scene["points_only"] and scene["n_vertices"] <= 50 and S.shape == (3 * scene["n_vertices"], model.n_dof)
    assert "node shown" in scene["notes"][0] and scene["marks"]["inputs"] == [model.xyz[0].tolist()]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    from flexmor.report.contents import build_report
    from flexmor.report.html import write_report
    from flexmor.workflow import prepare_model

    model = prepare_model(cantilever(2).with_rayleigh(0.0, 1e-6), ["TIP@rbe2"])
    ports = make_ports(model, ["TIP@RBE2:y", "TIP@RBE2:z"])
    reds = [reduce(model, "modal", 8, ports),
            reduce(model, "craig-bampton", 14, ports, interface=["TIP@RBE2"])]
    rep = build_report(model, ports, reds, band=BAND, n_modes=6, dt=5e-5, t_end=0.01)
    path = tmp_path_factory.mktemp("view3d") / "report.html"
    write_report(rep, path)
    return model, ports, reds, rep, path


def _shape(scene, i):
    item = scene["shapes"][i]
    return np.frombuffer(base64.b64decode(item["re"]), "<i2") * item["amp"] / 32767


def test_scene_holds_modes_pairs_and_deformations(report):
    model, ports, reds, rep, path = report
    sc = rep.scene
    assert sc["kind"] == "outer surface: 168 faces of 80 cells" and sc["couplings"][0].startswith("TIP@RBE2: master")
    assert len(sc["spiders"]) == 9 and len(sc["marks"]["inputs"]) == 1  # the port is the master node
    ids = np.array(sc["node_ids"])
    S = display_map(model, ids, [("TIP@RBE2", int(model.node_sets["TIP@RBE2"][0]), model.node_sets["TIP"])])
    body = sc["bodies"]["modal r=8"]
    phi = rep.modal["bodies"]["modal r=8"]["full_shapes"]  # as the MAC saw them: aligned in clusters
    for i, k in enumerate(body["full_shapes"]):
        u = S @ phi[:, i]
        assert np.allclose(_shape(sc, k), u, atol=np.abs(u).max() / 30000)  # int16 quantization
    assert [p["pair"] for p in body["pairs"]] == list(range(6)) and min(p["mac"] for p in body["pairs"]) > 0.9999
    d = sc["deform"]
    assert len(d["freqs"]) == 6 and d["inputs"] == ["TIP@RBE2:y", "TIP@RBE2:z"]
    assert all(abs(f / fm - 1) >= 0.0199 for f in d["freqs"] for fm in rep.modal["full_hz"])
    # the relative difference at the lowest frequency, input 2, recomputed directly
    import scipy.sparse.linalg as spla

    w = 2 * np.pi * d["freqs"][0]
    A = (model.K - w ** 2 * model.M + 1j * w * model.D).tocsc()
    q = spla.spsolve(A, ports.B[:, 1].toarray().ravel())
    red = reds[1]
    qr = red.V @ np.linalg.solve(red.K - w ** 2 * red.M + 1j * w * red.D, red.B[:, 1])
    expect = np.linalg.norm(S @ (q - qr)) / np.linalg.norm(S @ q)
    got = d["bodies"]["craig-bampton r=14"][0][1]["rel_diff"]
    # a difference of two solutions ~2e-6 apart: each solver's q is within ~eps cond(A) of the true one
    # (cond_1 ~1e6 here: 1e-10; PARDISO and SuperLU measured 4e-12 and 6e-12 from a refined solution)
    assert abs(got - expect) <= 4 * np.finfo(float).eps * cond1(A) and 0 < got < 0.05
    assert d["bodies"]["modal r=8"][0][0]["rel_diff"] < 0.01
    text = path.read_text(encoding="utf-8")
    assert 'id="view3d"' in text and "FlexmorView.report" in text and "http" not in text


@pytest.fixture(scope="module")
def chromium():
    exe = find_chromium()
    if exe is None:
        pytest.skip("no chromium/chrome on PATH (CI installs Debian's chromium): the 3D view is not drawn here")
    with Browser(exe) as b:
        yield b


def _canvas(b, side="left"):
    return b.js(f"JSON.parse(JSON.stringify(document.getElementById('v3d-{side}').getBoundingClientRect()))")


def _set(b, ident, value, event="change"):
    b.js(f"var e=document.getElementById('{ident}'); e.value='{value}'; e.dispatchEvent(new Event('{event}'))")


@pytest.mark.browser
def test_report_3d_view_draws_and_follows_the_controls(report, chromium):
    *_, path = report
    b = chromium
    b.open(path.as_uri())
    b.js("document.getElementById('view3d').scrollIntoView(); document.getElementById('v3d-anim').click()")
    rect = _canvas(b)
    png = b.screenshot()
    mode1 = canvas_pixels(png, rect)
    drawn = np.mean(np.any(mode1 < 240, axis=2))
    assert 0.03 < drawn < 0.9  # the body covers part of the canvas
    assert np.mean(np.any(canvas_pixels(png, _canvas(b, "right")) < 240, axis=2)) > 0.03
    _set(b, "v3d-scale", "100", "input")
    scaled = canvas_pixels(b.screenshot(), rect)
    assert np.mean(np.any(scaled != mode1, axis=2)) > 0.01  # the slider moves the picture
    _set(b, "v3d-mode", "3")
    mode4 = canvas_pixels(b.screenshot(), rect)
    assert np.mean(np.any(mode4 != scaled, axis=2)) > 0.01  # another mode, another picture
    caps = b.js("document.getElementById('v3d-left-cap').textContent + '|' + "
                "document.getElementById('v3d-right-cap').textContent")
    assert caps.startswith("full model: mode 4") and "MAC 1.0000" in caps
    _set(b, "v3d-view", "1")
    caps = b.js("document.getElementById('v3d-right-cap').textContent")
    assert "same input and frequency" in caps


def test_rbe3_ports_draw_their_spiders():
    model = cantilever(2)
    scene, _ = body_scene(model, ports=["TIP@rbe3:y", "TIP@rbe3:rz", "TIP:z"])
    tip = model.node_xyz(model.node_sets["TIP"])
    assert len(scene["spiders"]) == len(tip) and scene["couplings"] == [
        f"TIP@RBE3 (port): master point {np.round(tip.mean(axis=0), 6).tolist()}, {len(tip)} nodes"]
    assert np.allclose(scene["marks"]["masters"], [tip.mean(axis=0)])
