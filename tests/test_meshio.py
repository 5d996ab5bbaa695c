"""The mesh through meshio: conversion both ways, flexmor's deck readers cross-checked against meshio's,
a mesh file attached to matrices without geometry (``--mesh``), and the ``.vtu`` export of mode shapes.

Where meshio is wrong for a format, the test says so and checks meshio's known deviation instead
of adapting flexmor's reader to it.
"""

import numpy as np
import pytest
import scipy.io
from helpers import CCX, DATA
from test_io_mesh import ABAQUS_EDGES, CORNERS, NASTRAN_EDGES, VTK_EDGES, _check_wedge, _deck, _element

import flexmor.io
from flexmor.cli import main
from flexmor.errors import ModelError, ReadError
from flexmor.io import write_body
from flexmor.io._cells import build_mesh, mesh_of_elements, nastran_cell
from flexmor.io.calculix import read_inp
from flexmor.io.meshio_mesh import read_mesh, with_mesh
from flexmor.io.nastran.nastran_bulk import read_bulk
from flexmor.io.vtu import body_modes
from flexmor.mesh import NODE_ID_DATA, CellBlock, Mesh
from flexmor.model import FEModel
from flexmor.models.solid import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce

meshio = pytest.importorskip("meshio")


def _cell_coords(mesh: Mesh, ids, xyz):
    """``{cell type: coordinates (n_cells, k, 3)}`` of the cells of ``mesh`` over the node table ``ids``, ``xyz``."""
    order = np.argsort(ids)
    return {b.type: xyz[order[np.searchsorted(ids, b.nodes, sorter=order)]] for b in mesh.blocks}


def _meshio_coords(m):
    """The same for a meshio.Mesh, in flexmor's node order (Mesh.from_meshio)."""
    index = np.arange(1, len(m.points) + 1)
    return _cell_coords(Mesh.from_meshio(m, index), index, np.asarray(m.points, float))


def _meshio_read(path, cell_type):
    """meshio's mesh of ``path``, or None where meshio cannot hold ``cell_type``.

    meshio 5.3.5 is wrong for 15-node wedges and 13-node pyramids: its Mesh lacks the types (KeyError
    'wedge15' from every reader, Abaqus C3D15 and Nastran CPENTA alike); a meshio that reads them
    must agree with flexmor.
    """
    try:
        return meshio.read(path)
    except KeyError as exc:
        assert cell_type in ("wedge15", "pyramid13") and exc.args == (cell_type,)
        return None


def _assert_same_cells(ours: dict, theirs: dict):
    assert sorted(ours) == sorted(theirs)
    for cell_type, x in ours.items():
        np.testing.assert_array_equal(x, theirs[cell_type], err_msg=cell_type)


# -- conversion ------------------------------------------------------------------------------------
def test_round_trip_keeps_node_ids_types_and_order():
    ids = np.array([40, 7, 12, 99, 3, 58, 21, 64])
    xyz = np.arange(24, dtype=float).reshape(8, 3) ** 1.5
    mesh = Mesh([CellBlock("hexahedron", [[3, 7, 12, 40, 58, 99, 21, 64]]),
                 CellBlock("wedge", [[7, 12, 40, 3, 58, 99]]),
                 CellBlock("line", [[21, 64]])])
    m = mesh.to_meshio(ids, xyz)
    assert [c.type for c in m.cells] == ["hexahedron", "wedge", "line"]
    np.testing.assert_array_equal(m.point_data[NODE_ID_DATA], ids)
    np.testing.assert_array_equal(m.cells[0].data[0], [4, 1, 2, 0, 5, 3, 6, 7])
    np.testing.assert_array_equal(m.cells[1].data[0], [1, 2, 0, 4, 5, 3])  # meshio's wedge is flexmor's
    np.testing.assert_array_equal(mesh.to_meshio(ids, xyz, vtk=True).cells[1].data[0], [1, 0, 2, 4, 3, 5])
    for vtk in (False, True):  # for VTK files the wedge is turned (meshio turns it back on writing)
        back = Mesh.from_meshio(mesh.to_meshio(ids, xyz, vtk=vtk), vtk=vtk)
        for a, b in zip(mesh.blocks, back.blocks):
            assert a.type == b.type
            np.testing.assert_array_equal(a.nodes, b.nodes)


def test_quadratic_wedges_go_to_meshio_as_their_corners(caplog):
    mesh = Mesh([CellBlock("wedge15", [np.arange(1, 16)])])
    (block,) = mesh.to_meshio(np.arange(1, 16), np.zeros((15, 3))).cells
    (vtk_block,) = mesh.to_meshio(np.arange(1, 16), np.zeros((15, 3)), vtk=True).cells
    if block.type == "wedge":  # meshio 5.3.5 cannot hold wedge15 cells
        np.testing.assert_array_equal(block.data, [[0, 1, 2, 3, 4, 5]])
        np.testing.assert_array_equal(vtk_block.data, [[0, 2, 1, 3, 5, 4]])  # meshio turns it back in the file
        assert "wedge15" in caplog.text
    else:
        np.testing.assert_array_equal(block.data[0], np.arange(15))


def test_from_meshio_numbers_points_without_ids_from_one_and_skips_unknown_types(caplog):
    m = meshio.Mesh(np.zeros((5, 3)), [("triangle", [[0, 1, 2]]), ("polygon", [[0, 1, 2, 3, 4]])])
    mesh = Mesh.from_meshio(m)
    (block,) = mesh.blocks
    np.testing.assert_array_equal(block.nodes, [[1, 2, 3]])
    assert "1 polygon" in caplog.text


def test_meshio_missing_names_the_extra(monkeypatch, tmp_path):
    import sys

    monkeypatch.setitem(sys.modules, "meshio", None)
    with pytest.raises(ModelError, match=r"flexmor\[mesh\]"):
        Mesh([CellBlock("line", [[1, 2]])]).to_meshio([1, 2], np.zeros((2, 3)))
    path = tmp_path / "m.vtu"
    path.write_text("x")
    with pytest.raises(ReadError, match=r"m\.vtu: .*flexmor\[mesh\]"):
        read_mesh(path)


# -- flexmor's readers against meshio's -------------------------------------------------------------
@pytest.mark.parametrize("deck", [DATA / "abaqus" / "blockC3D8.inp", DATA / "abaqus" / "blockC3D10.inp",
                                  CCX / "beam8_free_mat.inp"])
def test_deck_mesh_agrees_with_meshio(deck):
    """Linear and quadratic bricks and tetrahedra of real Abaqus/CalculiX decks: same cells, same points."""
    cells = []
    ids, xyz, _ = read_inp(deck, cells=cells)
    ours = _cell_coords(build_mesh(cells, "abaqus"), ids, xyz)
    m = meshio.read(deck)
    # meshio drops the deck's node ids (points numbered in the file's order): match the points by coordinates
    assert len(m.points) == len(ids)
    np.testing.assert_array_equal(np.unique(m.points, axis=0), np.unique(xyz, axis=0))
    _assert_same_cells(ours, _meshio_coords(m))
    assert sum(len(v) for v in ours.values()) == sum(len(c.data) for c in m.cells) > 0


@pytest.mark.parametrize("etype, corners, n", [("C3D20R", "hex", 20), ("C3D10", "tet", 10), ("C3D6", "wedge", 6),
                                               ("C3D15", "wedge", 15)])
def test_abaqus_elements_agree_with_meshio(tmp_path, etype, corners, n):
    edges = ABAQUS_EDGES.get(etype.rstrip("R"), {})
    xyz = _element(CORNERS[corners], edges, n)
    deck = _deck(tmp_path, etype, xyz)
    cells = []
    ids, coords, _ = read_inp(deck, cells=cells)
    mesh = build_mesh(cells, "abaqus")
    ours = _cell_coords(mesh, ids, coords)
    if corners == "wedge":
        _check_wedge(ours[mesh.blocks[0].type][0])
    m = _meshio_read(deck, mesh.blocks[0].type)
    if m is not None:
        _assert_same_cells(ours, _meshio_coords(m))


def test_abaqus_quadratic_beam_meshio_is_wrong(tmp_path):
    """meshio's Abaqus reader keeps B32's deck order (end, middle, end) for its line3, whose middle node is
    last: meshio is wrong for quadratic beams (and trusses); flexmor puts the middle node last."""
    xyz = np.array([(0.0, 0, 0), (3.0, 0, 0), (6.0, 0, 0)])
    deck = _deck(tmp_path, "B32", xyz)
    cells = []
    _, coords, _ = read_inp(deck, cells=cells)
    (block,) = build_mesh(cells, "abaqus").blocks
    assert block.type == "line3"
    np.testing.assert_array_equal(coords[block.nodes[0] - 1], xyz[[0, 2, 1]])  # VTK: ends, then middle
    theirs = _meshio_coords(meshio.read(deck))["line3"][0]
    np.testing.assert_array_equal(theirs, xyz)  # meshio: the middle node second


@pytest.mark.parametrize("card, corners, n", [("CHEXA", "hex", 20), ("CTETRA", "tet", 10), ("CPENTA", "wedge", 15),
                                              ("CPENTA", "wedge", 6), ("CHEXA", "hex", 8)])
def test_nastran_elements_agree_with_meshio(tmp_path, card, corners, n):
    xyz = _element(CORNERS[corners], NASTRAN_EDGES[card] if n > 8 else {}, n)
    ids = np.arange(101, 101 + n)  # GRID ids that are not point indices
    grids = [f"GRID,{i},,{x!r},{y!r},{z!r}" for i, (x, y, z) in zip(ids, xyz.tolist())]
    fields = ["1", "1"] + [str(i) for i in ids]
    rows = [f"{card}," + ",".join(fields[:8]) + ",+"] + \
        ["+," + ",".join(fields[k:k + 8]) + (",+" if k + 8 < len(fields) else "") for k in range(8, len(fields), 8)]
    if len(fields) <= 8:
        rows = [f"{card}," + ",".join(fields)]
    bdf = tmp_path / "one.bdf"
    bdf.write_text("\n".join(["BEGIN BULK"] + grids + rows + ["ENDDATA"]) + "\n")
    bulk = read_bulk(bdf)
    mesh = mesh_of_elements(bulk.elements, nastran_cell, "nastran", bulk.grid_ids)
    m = _meshio_read(bdf, mesh.blocks[0].type)
    if m is None:
        return
    theirs, their_ids, _ = read_mesh(bdf)
    np.testing.assert_array_equal(their_ids, ids)  # meshio keeps the GRID ids of Nastran files
    (a,), (b,) = mesh.blocks, theirs.blocks
    assert a.type == b.type
    np.testing.assert_array_equal(a.nodes, b.nodes)
    _assert_same_cells(_cell_coords(mesh, bulk.grid_ids, bulk.xyz), _meshio_coords(m))
    cell = _cell_coords(mesh, bulk.grid_ids, bulk.xyz)[a.type][0]
    if corners == "wedge":
        _check_wedge(cell)
    for pos, (i, j) in VTK_EDGES.get(a.type, {}).items():
        np.testing.assert_allclose(cell[pos], 0.5 * (cell[i] + cell[j]))


# -- a mesh file for matrices without geometry ------------------------------------------------------
@pytest.fixture(scope="module")
def free_beam():
    return cantilever(2, clamped=False)


def _matrix_market(folder, model):
    scipy.io.mmwrite(folder / "beam_K.mtx", model.K, symmetry="symmetric")
    scipy.io.mmwrite(folder / "beam_M.mtx", model.M, symmetry="symmetric")
    return folder / "beam_K.mtx"


@pytest.mark.parametrize("suffix", [".vtu", ".vtk", ".msh", ".inp"])
def test_matrix_market_with_a_mesh_file_gets_nodes_dofs_and_cells(tmp_path, free_beam, suffix):
    mtx = _matrix_market(tmp_path, free_beam)
    path = tmp_path / f"beam{suffix}"
    m = free_beam.mesh.to_meshio(free_beam.node_ids, free_beam.xyz)  # point i: equations 3 i .. 3 i + 2
    del m.point_data[NODE_ID_DATA]
    meshio.write(path, m)
    model = with_mesh(flexmor.io.read(mtx), path)
    assert model.n_nodes == free_beam.n_nodes and model.mesh.n_cells == free_beam.mesh.n_cells
    np.testing.assert_array_equal(model.dofs, free_beam.dofs)
    np.testing.assert_allclose(model.xyz, free_beam.xyz, rtol=1e-12)
    assert model.mass_properties()["center_of_mass"] == pytest.approx(free_beam.mass_properties()["center_of_mass"])
    _assert_same_cells(_cell_coords(model.mesh, model.node_ids, model.xyz),
                       _cell_coords(free_beam.mesh, free_beam.node_ids, free_beam.xyz))


def test_mesh_file_node_ids_are_kept(tmp_path, free_beam):
    mtx = _matrix_market(tmp_path, free_beam)
    vtu = tmp_path / "beam.vtu"
    shifted = Mesh([CellBlock(b.type, b.nodes + 1000) for b in free_beam.mesh.blocks])
    meshio.write(vtu, shifted.to_meshio(free_beam.node_ids + 1000, free_beam.xyz))
    model = with_mesh(flexmor.io.read(mtx), vtu)
    np.testing.assert_array_equal(model.node_ids, free_beam.node_ids + 1000)
    np.testing.assert_array_equal(model.dofs[:, 0], free_beam.dofs[:, 0] + 1000)
    _assert_same_cells(_cell_coords(model.mesh, model.node_ids, model.xyz),
                       _cell_coords(free_beam.mesh, free_beam.node_ids, free_beam.xyz))


def test_mesh_file_that_does_not_fit_is_refused(tmp_path, free_beam):
    mtx = _matrix_market(tmp_path, free_beam)
    other = cantilever(3, clamped=False)
    vtu = tmp_path / "other.vtu"
    meshio.write(vtu, other.mesh.to_meshio(other.node_ids, other.xyz))
    with pytest.raises(ReadError, match=rf"other\.vtu: {other.n_nodes} points give {3 * other.n_nodes} equations .* "
                                        rf"model's matrices have {free_beam.n_dof}"):
        with_mesh(flexmor.io.read(mtx), vtu)
    with pytest.raises(ReadError, match=r"nothing\.vtu: mesh file not found"):
        with_mesh(flexmor.io.read(mtx), tmp_path / "nothing.vtu")
    junk = tmp_path / "junk.vtu"
    junk.write_text("not xml")
    with pytest.raises(ReadError, match=r"junk\.vtu: meshio cannot read"):
        read_mesh(junk)
    with pytest.raises(ReadError, match="has elements from its own files already"):
        with_mesh(free_beam, vtu)


def test_mesh_file_for_a_model_with_nodes_checks_ids_and_coordinates(tmp_path, free_beam):
    import dataclasses

    bare = dataclasses.replace(free_beam, mesh=None)
    vtu = tmp_path / "beam.vtu"
    meshio.write(vtu, free_beam.mesh.to_meshio(free_beam.node_ids, free_beam.xyz))
    model = with_mesh(bare, vtu)
    assert model.mesh.n_cells == free_beam.mesh.n_cells
    moved = free_beam.xyz.copy()
    moved[4] += 0.01
    meshio.write(vtu, free_beam.mesh.to_meshio(free_beam.node_ids, moved))
    with pytest.raises(ReadError, match=r"node 5 lies at .* in the mesh file"):
        with_mesh(bare, vtu)


def test_cli_reduce_matrix_market_with_mesh(tmp_path, free_beam, capsys):
    mtx = _matrix_market(tmp_path, free_beam)
    vtu = tmp_path / "beam.vtu"
    meshio.write(vtu, free_beam.mesh.to_meshio(free_beam.node_ids, free_beam.xyz))
    tip = int(free_beam.node_ids[np.argmax(free_beam.xyz[:, 0])])
    body = tmp_path / "body.h5"
    assert main(["reduce", str(mtx), "--mesh", str(vtu), "--method", "modal", "--order", "10",
                 "--input", f"{tip}:z", "-o", str(body), "--no-error"]) == 0
    out = tmp_path / "modes.vtu"
    assert main(["export", str(body), "--format", "vtu", "-o", str(out), "--model", str(mtx), "--mesh", str(vtu)]) == 0
    grid = meshio.read(out)
    assert grid.cells[0].type == "hexahedron" and len(grid.cells[0].data) == free_beam.mesh.n_cells
    capsys.readouterr()
    assert main(["info", str(mtx), "--mesh", str(tmp_path / "absent.vtu")]) == 2
    assert "absent.vtu: mesh file not found" in capsys.readouterr().err


# -- mode shapes for ParaView -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def ccx_body(free):
    red = reduce(free, "modal", 12, make_ports(free, ["TIP:y"]))
    return red, free


def test_vtu_holds_the_mesh_and_the_expanded_modes(tmp_path, ccx_body):
    red, model = ccx_body
    path = tmp_path / "modes.vtu"
    assert flexmor.io.export(red, path, model=model) == "vtu"
    assert [p.name for p in tmp_path.iterdir()] == ["modes.vtu"]  # atomic: no temporary file left
    grid = meshio.read(path)
    ids = grid.point_data[NODE_ID_DATA]
    np.testing.assert_array_equal(ids, model.node_ids)
    np.testing.assert_allclose(grid.field_data["frequencies_hz"], red.frequencies_hz(), rtol=1e-12)
    freqs, shapes = body_modes(red)
    np.testing.assert_allclose(freqs, red.frequencies_hz(), rtol=1e-12)
    phi = shapes[:, 0]
    assert phi @ (model.M @ phi) == pytest.approx(1.0, rel=1e-9)  # mass-normalized
    mode1 = grid.point_data["mode_1"]
    for i in (0, 17, model.dofs.shape[0] - 1):
        node, d = model.dofs[i]
        assert mode1[np.flatnonzero(ids == node)[0], d - 1] == pytest.approx(phi[i], rel=1e-12, abs=1e-300)
    assert len([k for k in grid.point_data if k.startswith("mode_")]) == red.order
    _assert_same_cells(_cell_coords(Mesh.from_meshio(grid), ids, grid.points),
                       _cell_coords(model.mesh, model.node_ids, model.xyz))


def test_vtu_of_quadratic_tetrahedra_keeps_vtk_order(tmp_path):
    """A tet10 model (an Abaqus C3D10 deck): after the export the mid-side nodes of every cell lie
    mid-edge in VTK's order and the volumes are positive (a permuted order fails)."""
    deck = DATA / "abaqus" / "blockC3D10.inp"
    model = flexmor.io.read(deck)
    red = reduce(model, "modal", 4, make_ports(model, [f"{int(model.node_ids[0])}:x"]))
    path = tmp_path / "tet10.vtu"
    flexmor.io.export(red, path, model=model)
    grid = meshio.read(path)
    (block,) = grid.cells
    assert block.type == "tetra10"
    x = grid.points[block.data]
    for pos, (i, j) in VTK_EDGES["tetra10"].items():
        np.testing.assert_allclose(x[:, pos], 0.5 * (x[:, i] + x[:, j]), atol=1e-12)
    vol = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    assert vol.min() > 0


def test_vtu_without_model_draws_the_body_surface(tmp_path, ccx_body):
    red, _ = ccx_body
    body = tmp_path / "body.h5"
    write_body(red, body)
    out = tmp_path / "surface.vtu"
    assert main(["export", str(body), "-o", str(out)]) == 0
    grid = meshio.read(out)
    (block,) = grid.cells
    assert block.type == "triangle" and len(block.data) == len(red.triangles)
    _, shapes = body_modes(red)
    node, d = red.dofs[5]
    row = np.flatnonzero(grid.point_data[NODE_ID_DATA] == node)[0]
    assert grid.point_data["mode_2"][row, d - 1] == pytest.approx(shapes[5, 1], rel=1e-12)


def test_vtu_needs_nodes(tmp_path, ccx_body):
    import dataclasses

    red, _ = ccx_body
    bare = dataclasses.replace(red, triangles=None)
    with pytest.raises(ModelError, match="no node table and surface"):
        flexmor.io.export(bare, tmp_path / "x.vtu")
    springs = FEModel(M=np.eye(3), K=np.diag([1.0, 2.0, 3.0]))
    with pytest.raises(ModelError, match="has 3 DOF but the body's basis V has"):
        flexmor.io.export(red, tmp_path / "x.vtu", model=springs)
    assert not (tmp_path / "x.vtu").exists()
