"""Signed volumes of the cells read from the decks, with VTK's shape functions written out.

VTK maps each cell from its parametric coordinates (r, s, t) to space by its shape functions
(vtkWedge, vtkQuadraticWedge, vtkQuadraticTetra, vtkQuadraticHexahedron, vtkPyramid: the
functions below, equal to VTK's InterpolateFunctions); the volume ParaView shows (Cell Size,
Mesh Quality) is the integral of the determinant of that map's Jacobian. One element of each
type, positive in its FE program (CalculiX/Abaqus, Nastran, Ansys), read through flexmor must
have the volume of its shape, not its negative: a node permutation that turns a cell inside out
or swaps a mid-side node fails. The .vtu flexmor writes must hold them the same way.
"""

from xml.etree import ElementTree

import numpy as np
import pytest
from test_io_mesh import ABAQUS_EDGES, CORNERS, NASTRAN_EDGES, _bdf, _deck, _element

from flexmor.io._cells import ansys_cell, build_mesh, mesh_of_elements, nastran_cell
from flexmor.io.calculix import read_inp
from flexmor.io.meshio_mesh import read_mesh
from flexmor.io.nastran.nastran_bulk import read_bulk
from flexmor.mesh import NODES_PER_CELL, CellBlock, Mesh, outer_surface


def _tri(r, s):
    return np.array([1 - r - s, r, s])


def _wedge(r, s, t):
    return np.concatenate([_tri(r, s) * (1 - t), _tri(r, s) * t])


def _wedge15(r, s, t):
    lam, z = _tri(r, s), 2 * t - 1
    corner = [0.5 * lam * (2 * lam - 1) * (1 + side * z) - 0.5 * lam * (1 - z * z) for side in (-1, 1)]
    edges = [(0, 1), (1, 2), (2, 0)]
    mid = [[2 * lam[i] * lam[j] * (1 + side * z) for i, j in edges] for side in (-1, 1)]
    return np.concatenate(corner + mid + [lam * (1 - z * z)])


def _tetra10(r, s, t):
    lam = np.array([1 - r - s - t, r, s, t])
    edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    return np.concatenate([lam * (2 * lam - 1), [4 * lam[i] * lam[j] for i, j in edges]])


_HEX = 2 * np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]) - 1
_HEX_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]


def _hex20(r, s, t):
    x = 2 * np.array([r, s, t]) - 1  # VTK's (0, 1) as (-1, 1)
    corner = np.prod(1 + _HEX * x, axis=1) * (_HEX @ x - 2) / 8
    mid = []
    for a, b in _HEX_EDGES:
        m = (_HEX[a] + _HEX[b]) / 2
        k = int(np.flatnonzero(m == 0)[0])  # the edge's direction
        mid.append((1 - x[k] ** 2) * np.prod([1 + m[j] * x[j] for j in range(3) if j != k]) / 4)
    return np.concatenate([corner, mid])


def _pyramid(r, s, t):
    return np.array([(1 - r) * (1 - s) * (1 - t), r * (1 - s) * (1 - t), r * s * (1 - t), (1 - r) * s * (1 - t), t])


#: VTK's shape functions and parametric domain ("cube", "wedge" = triangle x [0, 1], "tetra") per cell
#: type; the 13-node pyramid by its corners (vtkPyramid; its mid-side nodes are checked on their edges).
SHAPES = {"wedge": (_wedge, "wedge"), "wedge15": (_wedge15, "wedge"), "tetra10": (_tetra10, "tetra"),
          "hexahedron20": (_hex20, "cube"), "pyramid": (_pyramid, "cube"), "pyramid13": (_pyramid, "cube")}
PYRAMID_EDGES = {5: (0, 1), 6: (1, 2), 7: (2, 3), 8: (3, 0), 9: (0, 4), 10: (1, 4), 11: (2, 4), 12: (3, 4)}


def _gauss(domain):
    """Points (n, 3) and weights of a product Gauss rule over VTK's parametric ``domain`` (collapsed cube)."""
    g, w = np.polynomial.legendre.leggauss(4)
    g, w = (g + 1) / 2, w / 2
    u, v, z = (a.ravel() for a in np.meshgrid(g, g, g, indexing="ij"))
    wt = np.einsum("i,j,k->ijk", w, w, w).ravel()
    if domain == "wedge":  # (u, v) -> triangle
        return np.stack([u, v * (1 - u), z], 1), wt * (1 - u)
    if domain == "tetra":
        return np.stack([u, v * (1 - u), z * (1 - u) * (1 - v)], 1), wt * (1 - u) ** 2 * (1 - v)
    return np.stack([u, v, z], 1), wt


def signed_volume(cell_type, x):
    """Integral of det(d position / d (r, s, t)) over the cell ``x`` (k, 3), VTK's node order."""
    shape, domain = SHAPES[cell_type]
    x = np.asarray(x, dtype=float)
    x = x[:5] if cell_type == "pyramid13" else x
    h, vol = 1e-4, 0.0
    for p, w in zip(*_gauss(domain)):
        jac = np.array([(shape(*(p + h * e)) - shape(*(p - h * e))) / (2 * h) for e in np.eye(3)]) @ x
        vol += w * np.linalg.det(jac)
    return vol


def _abaqus(tmp_path, etype, corners, n):
    xyz = _element(CORNERS[corners], ABAQUS_EDGES.get(etype.rstrip("R"), {}), n)
    cells = []
    _, coords, _ = read_inp(_deck(tmp_path, etype, xyz), cells=cells)
    (block,) = build_mesh(cells, "abaqus").blocks
    return block.type, coords[block.nodes[0] - 1]


def _nastran(tmp_path, card, corners, n):
    xyz = _element(CORNERS[corners], NASTRAN_EDGES[card] if n > len(CORNERS[corners]) else {}, n)
    bulk = read_bulk(_bdf(tmp_path, card, xyz))
    (block,) = mesh_of_elements(bulk.elements, nastran_cell, "nastran", bulk.grid_ids).blocks
    return block.type, bulk.xyz[np.searchsorted(bulk.grid_ids, block.nodes[0])]


def _ansys_prism(_tmp_path, etype, corners, n):
    """SOLID185/186 in their prism form (nodes K = L, O = P; SOLID186 also S = K, W = O, A = B)."""
    x = np.array(CORNERS["wedge"], dtype=float)
    mid = [0.5 * (x[a] + x[b]) for a, b in ((0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5))]
    xyz = np.concatenate([x, mid])  # node i + 1 at xyz[i]
    brick = [1, 2, 3, 3, 4, 5, 6, 6] + ([7, 8, 3, 9, 10, 11, 6, 12, 13, 14, 15, 15] if n == 15 else [])
    cell_type, nodes = ansys_cell(etype, brick)
    return cell_type, xyz[np.array(nodes) - 1]


CORNERS = dict(CORNERS, pyramid=[(0, 0, 0), (2, 0, 0), (2, 3, 0), (0, 3, 0), (1, 1.5, 4)])
NASTRAN_EDGES = dict(NASTRAN_EDGES, CPYRAM={6: (1, 2), 7: (2, 3), 8: (3, 4), 9: (4, 1), 10: (1, 5), 11: (2, 5),
                                            12: (3, 5), 13: (4, 5)})
#: (reader, element, corners, nodes, cell type, volume): base 2 x 3 (triangle: half of it), height 4.
ELEMENTS = [
    (_abaqus, "C3D6", "wedge", 6, "wedge", 12.0), (_abaqus, "C3D15", "wedge", 15, "wedge15", 12.0),
    (_abaqus, "C3D10", "tet", 10, "tetra10", 4.0), (_abaqus, "C3D20R", "hex", 20, "hexahedron20", 24.0),
    (_nastran, "CPENTA", "wedge", 6, "wedge", 12.0), (_nastran, "CPENTA", "wedge", 15, "wedge15", 12.0),
    (_nastran, "CTETRA", "tet", 10, "tetra10", 4.0), (_nastran, "CHEXA", "hex", 20, "hexahedron20", 24.0),
    (_nastran, "CPYRAM", "pyramid", 5, "pyramid", 8.0), (_nastran, "CPYRAM", "pyramid", 13, "pyramid13", 8.0),
    (_ansys_prism, 185, "wedge", 6, "wedge", 12.0), (_ansys_prism, 186, "wedge", 15, "wedge15", 12.0),
]


@pytest.mark.parametrize("read, etype, corners, n, cell_type, volume", ELEMENTS,
                         ids=[f"{e[1]}-{e[3]}" for e in ELEMENTS])
def test_cells_have_positive_volume_with_vtk_shape_functions(tmp_path, read, etype, corners, n, cell_type, volume):
    got, x = read(tmp_path, etype, corners, n)
    assert got == cell_type
    assert signed_volume(cell_type, x) == pytest.approx(volume, rel=1e-9)
    if cell_type == "pyramid13":
        for pos, (a, b) in PYRAMID_EDGES.items():
            np.testing.assert_allclose(x[pos], 0.5 * (x[a] + x[b]), atol=1e-12)


def test_shape_functions_interpolate_their_nodes():
    """Each function is 1 at its node (VTK's parametric coordinates) and 0 at the others."""
    tri = [(0, 0), (1, 0), (0, 1)]
    nodes = {
        "wedge15": [(r, s, t) for t in (0, 1) for r, s in tri]
        + [(r, s, t) for t in (0, 1) for r, s in ((0.5, 0), (0.5, 0.5), (0, 0.5))] + [(r, s, 0.5) for r, s in tri],
        "tetra10": [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0.5, 0, 0), (0.5, 0.5, 0), (0, 0.5, 0), (0, 0, 0.5),
                    (0.5, 0, 0.5), (0, 0.5, 0.5)],
        "hexahedron20": [tuple((c + 1) / 2) for c in _HEX]
        + [tuple((_HEX[a] + _HEX[b] + 2) / 4) for a, b in _HEX_EDGES],
    }
    for cell_type, pts in nodes.items():
        shape = SHAPES[cell_type][0]
        np.testing.assert_allclose(np.array([shape(*p) for p in pts]), np.eye(len(pts)), atol=1e-12, err_msg=cell_type)


def test_a_wedge_turned_inside_out_has_negative_volume(tmp_path):
    _, x = _abaqus(tmp_path, "C3D15", "wedge", 15)
    turned = x[[0, 2, 1, 3, 5, 4, 8, 7, 6, 11, 10, 9, 12, 14, 13]]  # VTK's documentation's orientation
    assert signed_volume("wedge15", turned) == pytest.approx(-12.0)
    assert signed_volume("wedge", turned[:6]) == pytest.approx(-12.0)


def _cells(tmp_path):
    """One cell of each volume type over one node table (ids from 1, cells' nodes in VTK order)."""
    xyz, blocks = [], []
    for read, etype, corners, n, cell_type, _ in ELEMENTS[:4] + ELEMENTS[8:10]:
        _, x = read(tmp_path, etype, corners, n)
        offset = 200 * len(blocks)
        blocks.append(CellBlock(cell_type, [np.arange(1, n + 1) + offset]))
        xyz.append(x + [[10.0 * len(blocks), 0, 0]])
    ids = np.concatenate([b.nodes[0] for b in blocks])
    return Mesh(blocks), ids, np.concatenate(xyz)


def test_outer_faces_point_outwards(tmp_path):
    mesh, ids, xyz = _cells(tmp_path)
    surf = outer_surface(mesh)
    at = {int(i): p for i, p in zip(ids, xyz)}
    for block in mesh.blocks:
        centre = np.mean([at[int(i)] for i in block.nodes[0]], axis=0)
        tris = [t for t in surf.triangles if set(t.tolist()) <= set(block.nodes[0].tolist())]
        assert tris, block.type
        for t in tris:
            a, b, c = (at[int(i)] for i in t)
            assert np.cross(b - a, c - a) @ ((a + b + c) / 3 - centre) > 0, block.type


def _vtu_cells(path):
    """``[(VTK cell type id, point indices)]`` of an ASCII ``.vtu`` file, as VTK reads it."""
    piece = ElementTree.parse(path).getroot().find("UnstructuredGrid/Piece")
    arrays = {a.get("Name"): np.array(a.text.split(), dtype=float) for a in piece.find("Cells")}
    conn, ends = arrays["connectivity"].astype(int), arrays["offsets"].astype(int)
    return [(int(t), conn[b:e]) for t, b, e in zip(arrays["types"], np.r_[0, ends[:-1]], ends)]


def test_vtu_cells_have_positive_volume(tmp_path):
    """The cells flexmor hands meshio for a .vtu, as VTK reads the file: meshio 5.3.5 reverses linear
    wedges on the way (and keeps 15-node wedges and 13-node pyramids as their corners)."""
    import meshio

    mesh, ids, xyz = _cells(tmp_path)
    path = tmp_path / "cells.vtu"
    meshio.write(path, mesh.to_meshio(ids, xyz, vtk=True), file_format="vtu", binary=False)
    vtk_types = {13: "wedge", 24: "tetra10", 25: "hexahedron20", 14: "pyramid"}
    cells = _vtu_cells(path)
    assert [vtk_types[t] for t, _ in cells] == ["wedge", "wedge", "tetra10", "hexahedron20", "pyramid", "pyramid"]
    for (t, points), volume in zip(cells, (12.0, 12.0, 4.0, 24.0, 8.0, 8.0)):
        assert signed_volume(vtk_types[t], xyz[points]) == pytest.approx(volume, rel=1e-9)
    back, back_ids, _ = read_mesh(path)
    np.testing.assert_array_equal(back_ids, ids)
    corners = {"wedge15": "wedge", "pyramid13": "pyramid"}
    want = {}
    for block in mesh.blocks:
        kind = corners.get(block.type, block.type)
        want.setdefault(kind, []).append(block.nodes[:, :NODES_PER_CELL[kind]])
    assert [b.type for b in back.blocks] == list(want)
    for block in back.blocks:
        np.testing.assert_array_equal(block.nodes, np.concatenate(want[block.type]))
