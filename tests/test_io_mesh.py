"""Element connectivity read from the decks (FEModel.mesh), in meshio's (VTK's) node order.

Elements are written in each program's own node order (CalculiX/Abaqus, Nastran), with
mid-side nodes placed at the middle of the edge that the program's documentation names. After
the mapping, each mid-side node must lie at the middle of the edge VTK names for its position,
bricks and tetrahedra must have positive volume and wedges the orientation of VTK's code
(test_cell_volumes.py checks the signed volumes with VTK's shape functions).
"""

import numpy as np
import pytest
from helpers import CCX, DATA

import flexmor.io
from flexmor.io._cells import abaqus_cell, ansys_cell, build_mesh, mesh_of_elements, nastran_cell
from flexmor.io.calculix import read_inp
from flexmor.io.nastran.nastran_bulk import read_bulk

#: VTK's mid-side nodes: position -> the two corners of its edge.
VTK_EDGES = {
    "hexahedron20": {8: (0, 1), 9: (1, 2), 10: (2, 3), 11: (3, 0), 12: (4, 5), 13: (5, 6), 14: (6, 7), 15: (7, 4),
                     16: (0, 4), 17: (1, 5), 18: (2, 6), 19: (3, 7)},
    "wedge15": {6: (0, 1), 7: (1, 2), 8: (2, 0), 9: (3, 4), 10: (4, 5), 11: (5, 3), 12: (0, 3), 13: (1, 4), 14: (2, 5)},
    "tetra10": {4: (0, 1), 5: (1, 2), 6: (2, 0), 7: (0, 3), 8: (1, 3), 9: (2, 3)},
    "line3": {2: (0, 1)},
}
#: The programs' mid-side nodes (1-based, as in their manuals): node -> corners of its edge.
ABAQUS_EDGES = {
    "C3D20": {9: (1, 2), 10: (2, 3), 11: (3, 4), 12: (4, 1), 13: (5, 6), 14: (6, 7), 15: (7, 8), 16: (8, 5),
              17: (1, 5), 18: (2, 6), 19: (3, 7), 20: (4, 8)},
    "C3D15": {7: (1, 2), 8: (2, 3), 9: (3, 1), 10: (4, 5), 11: (5, 6), 12: (6, 4), 13: (1, 4), 14: (2, 5), 15: (3, 6)},
    "C3D10": {5: (1, 2), 6: (2, 3), 7: (3, 1), 8: (1, 4), 9: (2, 4), 10: (3, 4)},
    "B32": {2: (1, 3)},
}
NASTRAN_EDGES = {
    "CHEXA": {9: (1, 2), 10: (2, 3), 11: (3, 4), 12: (4, 1), 13: (1, 5), 14: (2, 6), 15: (3, 7), 16: (4, 8),
              17: (5, 6), 18: (6, 7), 19: (7, 8), 20: (8, 5)},
    "CPENTA": {7: (1, 2), 8: (2, 3), 9: (3, 1), 10: (1, 4), 11: (2, 5), 12: (3, 6), 13: (4, 5), 14: (5, 6), 15: (6, 4)},
    "CTETRA": {5: (1, 2), 6: (2, 3), 7: (3, 1), 8: (1, 4), 9: (2, 4), 10: (3, 4)},
}
#: Corners with the programs' orientation (bottom face seen from the top: counter-clockwise).
CORNERS = {
    "hex": [(0, 0, 0), (2, 0, 0), (2, 3, 0), (0, 3, 0), (0, 0, 4), (2, 0, 4), (2, 3, 4), (0, 3, 4)],
    "wedge": [(0, 0, 0), (2, 0, 0), (0, 3, 0), (0, 0, 4), (2, 0, 4), (0, 3, 4)],
    "tet": [(0, 0, 0), (2, 0, 0), (0, 3, 0), (0, 0, 4)],
    "beam": [(0, 0, 0), (0, 0, 0), (6, 0, 0)],  # B32: end, middle, end (middle filled in below)
}


def _element(corners, edges, n):
    """Coordinates of an element with ``n`` nodes: the corners, then each mid-side node at its edge's middle."""
    xyz = np.zeros((n, 3))
    xyz[:len(corners)] = corners
    for node, (a, b) in edges.items():
        xyz[node - 1] = 0.5 * (xyz[a - 1] + xyz[b - 1])
    return xyz


def _check_midsides(cell_type, cell, xyz_of):
    for pos, (a, b) in VTK_EDGES.get(cell_type, {}).items():
        np.testing.assert_allclose(xyz_of(cell[pos]), 0.5 * (xyz_of(cell[a]) + xyz_of(cell[b])), atol=1e-12,
                                   err_msg=f"{cell_type} node {pos}")


def _hex_volume(x):
    """Volume of a trilinear brick in VTK order (2x2x2 Gauss points, exact); negative when inverted."""
    nat = np.array([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)])
    g = 1 / np.sqrt(3)
    vol = 0.0
    for p in np.array(np.meshgrid([-g, g], [-g, g], [-g, g])).reshape(3, -1).T:
        dN = np.stack([nat[:, k] * np.prod([1 + nat[:, j] * p[j] for j in range(3) if j != k], axis=0) / 8
                       for k in range(3)])
        vol += np.linalg.det(dN @ x)
    return vol


def _bdf(tmp_path, card, xyz):
    """A Nastran bulk file with the GRIDs 1.. at ``xyz`` and one element ``card`` on them (property 1)."""
    grids = [f"GRID,{i + 1},,{x!r},{y!r},{z!r}" for i, (x, y, z) in enumerate(xyz.tolist())]
    fields = ["1", "1"] + [str(i + 1) for i in range(len(xyz))]
    chunks = [",".join(fields[k:k + 8]) for k in range(0, len(fields), 8)]
    rows = [("+," if k else f"{card},") + c + (",+" if k + 1 < len(chunks) else "") for k, c in enumerate(chunks)]
    bdf = tmp_path / f"{card}{len(xyz)}.bdf"
    bdf.write_text("\n".join(["BEGIN BULK"] + grids + rows + ["ENDDATA"]) + "\n")
    return bdf


def _deck(tmp_path, etype, xyz):
    lines = ["*NODE"] + [f"{i + 1}, {x!r}, {y!r}, {z!r}" for i, (x, y, z) in enumerate(xyz.tolist())]
    ids = [str(i + 1) for i in range(len(xyz))]
    rows = [", ".join(["1"] + ids[:15]) + ","] + [", ".join(ids[15:])] if len(ids) > 15 else [", ".join(["1"] + ids)]
    lines += [f"*ELEMENT, TYPE={etype}, ELSET=E"] + rows
    path = tmp_path / "one.inp"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("etype, corners, cell_type, n", [
    ("C3D20R", "hex", "hexahedron20", 20), ("C3D15", "wedge", "wedge15", 15), ("C3D10", "tet", "tetra10", 10),
    ("B32R", "beam", "line3", 3)])
def test_calculix_quadratic_elements_in_vtk_order(tmp_path, etype, corners, cell_type, n):
    edges = ABAQUS_EDGES[etype.rstrip("R")]
    xyz = _element(CORNERS[corners] if corners != "beam" else [(0, 0, 0)], edges, n)
    if corners == "beam":
        xyz[2] = (6, 0, 0)
        xyz[1] = (3, 0, 0)
    cells = []
    ids, coords, _ = read_inp(_deck(tmp_path, etype, xyz), cells=cells)
    mesh = build_mesh(cells, "abaqus")
    (block,) = mesh.blocks
    assert block.type == cell_type == abaqus_cell(etype)
    _check_midsides(cell_type, block.nodes[0], lambda i: coords[i - 1])
    if cell_type == "hexahedron20":
        assert _hex_volume(coords[block.nodes[0, :8] - 1]) == pytest.approx(24.0)
    if cell_type == "wedge15":
        _check_wedge(coords[block.nodes[0] - 1])


def _check_wedge(p):
    normal = np.cross(p[1] - p[0], p[2] - p[0])  # VTK's code: points towards the face (3, 4, 5)
    assert normal @ (p[3] - p[0]) > 0


def test_wedge_follows_vtk_orientation(tmp_path):
    xyz = np.array(CORNERS["wedge"], dtype=float)
    cells = []
    _, coords, _ = read_inp(_deck(tmp_path, "C3D6", xyz), cells=cells)
    (block,) = build_mesh(cells, "abaqus").blocks
    _check_wedge(coords[block.nodes[0] - 1])


@pytest.mark.parametrize("card, corners, cell_type, n", [
    ("CHEXA", "hex", "hexahedron20", 20), ("CPENTA", "wedge", "wedge15", 15), ("CTETRA", "tet", "tetra10", 10)])
def test_nastran_quadratic_elements_in_vtk_order(tmp_path, card, corners, cell_type, n):
    xyz = _element(CORNERS[corners], NASTRAN_EDGES[card], n)
    bulk = read_bulk(_bdf(tmp_path, card, xyz))
    (block,) = mesh_of_elements(bulk.elements, nastran_cell, "nastran", bulk.grid_ids).blocks
    assert block.type == cell_type
    _check_midsides(cell_type, block.nodes[0], lambda i: bulk.xyz[np.searchsorted(bulk.grid_ids, i)])
    if cell_type == "hexahedron20":
        assert _hex_volume(bulk.xyz[block.nodes[0, :8] - 1]) == pytest.approx(24.0)
    if cell_type == "wedge15":
        _check_wedge(bulk.xyz[block.nodes[0] - 1])


def test_calculix_job_has_the_deck_mesh():
    model = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
    (block,) = model.mesh.blocks
    assert block.type == "hexahedron"
    vols = [_hex_volume(model.xyz[np.searchsorted(model.node_ids, c)]) for c in block.nodes]
    lo, hi = model.xyz.min(axis=0), model.xyz.max(axis=0)
    assert min(vols) > 0
    assert sum(vols) == pytest.approx(np.prod(hi - lo))


def test_abaqus_job_has_the_deck_mesh():
    model = flexmor.io.read(DATA / "abaqus" / "blockC3D10.inp")
    (block,) = model.mesh.blocks
    assert block.type == "tetra10"
    x = model.xyz[np.searchsorted(model.node_ids, block.nodes)]
    _check_midsides("tetra10", np.arange(10), lambda i: x[:, i])
    vol = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6
    lo, hi = model.xyz.min(axis=0), model.xyz.max(axis=0)
    assert vol.min() > 0
    assert vol.sum() == pytest.approx(np.prod(hi - lo))


@pytest.mark.slow
def test_ansys_full_with_cdb_has_the_mesh():
    model = flexmor.io.read(DATA / "ansys" / "ansys_file.full", coordinates=DATA / "ansys" / "ansys_HexBeam.cdb")
    (block,) = model.mesh.blocks
    assert block.type == "hexahedron20" and len(block.nodes) == 40
    x = model.xyz[np.searchsorted(model.node_ids, block.nodes)]
    for cell in x:
        _check_midsides("hexahedron20", np.arange(20), lambda i, cell=cell: cell[i])
    vols = [_hex_volume(cell[:8]) for cell in x]
    assert min(vols) > 0
    assert sum(vols) == pytest.approx(np.prod(model.xyz.max(axis=0) - model.xyz.min(axis=0)))


def test_ansys_degenerate_bricks():
    wedge = np.array(CORNERS["wedge"], dtype=float)
    cell_type, nodes = ansys_cell(185, [1, 2, 3, 3, 4, 5, 6, 6])  # prism: K = L, O = P
    assert cell_type == "wedge"
    _check_wedge(wedge[np.array(nodes) - 1])
    tet = _element(CORNERS["tet"], ABAQUS_EDGES["C3D10"], 10)  # same mid-side edges as SOLID187
    cell_type, nodes = ansys_cell(186, [1, 2, 3, 3, 4, 4, 4, 4, 5, 6, 3, 7, 4, 4, 4, 4, 8, 9, 10, 10])
    assert cell_type == "tetra10"
    _check_midsides("tetra10", np.array(nodes), lambda i: tet[i - 1])
