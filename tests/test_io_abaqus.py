"""Abaqus reader: the C3D8/C3D10 blocks written by Abaqus, LABELS form, decks with instances, broken files."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import CCX, DATA, SHARED, geometric_rigid_modes

import flexmor.io
from flexmor.errors import ReadError
from flexmor.io.abaqus import read_deck

ABAQUS = DATA / "abaqus"
SHARED_ABAQUS = SHARED / "abaqus"

# corner-node tetrahedra of a C3D8 (exact volume for planar faces)
HEX_TETS = [(0, 1, 3, 4), (1, 2, 3, 6), (1, 4, 5, 6), (3, 4, 6, 7), (1, 3, 4, 6)]


def _volume(deck) -> float:
    pos = {int(i): k for k, i in enumerate(deck.node_ids)}
    vol = 0.0
    for etype, nodes in deck.elements:
        x = deck.xyz[[pos[int(n)] for n in nodes]]
        tets = HEX_TETS if etype.startswith("C3D8") else [(0, 1, 2, 3)]
        for a, b, c, d in tets:
            vol += abs(np.linalg.det(np.stack([x[b] - x[a], x[c] - x[a], x[d] - x[a]]))) / 6
    return vol


def _block(name):
    folder = ABAQUS if (ABAQUS / f"{name}.inp").exists() else SHARED_ABAQUS
    if not (folder / f"{name}_STIF1.mtx").exists():
        pytest.skip(f"{name} not available")
    return folder / f"{name}.inp"


@pytest.fixture(scope="module", params=["blockC3D8", "blockC3D10"])
def block(request):
    inp = _block(request.param)
    return inp, flexmor.io.read(inp)


def test_block_sizes_and_sets(block):
    inp, model = block
    n_nodes = {"blockC3D8": 176, "blockC3D10": 257}[inp.stem]
    assert model.n_nodes == n_nodes and model.n_dof == 3 * n_nodes
    assert model.name == inp.stem
    np.testing.assert_array_equal(model.node_sets["SET-1"], np.arange(1, n_nodes + 1))
    np.testing.assert_array_equal(model.node_sets["BLOCK-1.SET-1"], model.node_sets["SET-1"])
    assert model.xyz.min(axis=0) == pytest.approx([0, 0, 0]) and model.xyz.max(axis=0) == pytest.approx([4, 1, 1])


def test_block_rigid_body_motions_and_mass(block):
    inp, model = block
    R = geometric_rigid_modes(model)
    # equations map to the right nodes: rigid translations AND rotations give no elastic force
    scale = abs(model.K).max() * np.abs(model.xyz).max()
    assert np.abs(model.K @ R).max() < 1e-12 * scale
    deck = read_deck(inp)
    rho = deck.materials["STEEL"]["DENSITY"]
    assert rho == 2900.0
    volume = _volume(deck)
    assert volume == pytest.approx(4.0, rel=1e-6)
    for j in range(3):
        assert R[:, j] @ (model.M @ R[:, j]) == pytest.approx(rho * volume, rel=1e-9)
    assert abs(model.K - model.K.T).max() <= 1e-12 * abs(model.K).max()


def test_block_six_rigid_modes(block):
    _, model = block
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 7])
    f = np.sqrt(np.abs(w)) / (2 * np.pi)
    assert np.all(f[:6] < 1e-2) and f[6] > 400


def _write_labels(path: Path, model, *, prefix="", triangle="both"):
    A = model.K.tocoo()
    keep = {"both": np.ones(A.nnz, bool), "upper": A.row <= A.col, "lower": A.row >= A.col}[triangle]
    nd = model.dofs
    with open(path, "w") as f:
        for i, j, v in zip(A.row[keep], A.col[keep], A.data[keep]):
            f.write(f"{prefix}{nd[i, 0]},{nd[i, 1]}, {prefix}{nd[j, 0]},{nd[j, 1]}, {float(v)!r}\n")


@pytest.mark.slow
def test_labels_form_gives_the_same_model(tmp_path):
    inp = _block("blockC3D8")
    ref = flexmor.io.read(inp)
    f_ref = sla.eigh(ref.K.toarray(), ref.M.toarray(), eigvals_only=True)
    for k, (prefix, tri) in enumerate([("", "both"), ("block-1.", "upper"), ("", "lower")]):
        d = tmp_path / str(k)
        d.mkdir()
        shutil.copy(inp, d)
        shutil.copy(inp.with_name("blockC3D8_MASS1.mtx"), d)  # mass stays in COORDINATE form
        _write_labels(d / "blockC3D8_STIF1.mtx", ref, prefix=prefix, triangle=tri)
        model = flexmor.io.read(d / "blockC3D8_MASS1.mtx")  # any of the files may be passed
        np.testing.assert_array_equal(model.dofs, ref.dofs)
        assert abs(model.K - ref.K).max() == 0.0
        f = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
        np.testing.assert_allclose(f[6:], f_ref[6:], rtol=1e-12)


DECK = """*Heading
*Part, name=P
*Node
 10, 0., 0., 0.
 11, 1., 0., 0.
*Element, type=B31
 1, 10, 11
*Nset, nset=ENDS
 10, 11
*Nset, nset=R, generate
 10, 11, 1
*End Part
*Assembly, name=A
*Instance, name=I1, part=P
*End Instance
*Instance, name=I2, part=P
 0., 2., 0.
 0., 0., 0., 0., 0., 1., 90.
*End Instance
*Node
 1, 5., 5., 5.
*Nset, nset=TIP, instance=I2
 11
*End Assembly
*Material, name=M1
*Density
 7850.
"""


def test_deck_with_instances(tmp_path):
    (tmp_path / "two.inp").write_text(DECK)
    deck = read_deck(tmp_path / "two.inp")
    # labels repeat across instances -> instance index * 100 + label; assembly node last
    np.testing.assert_array_equal(deck.node_ids, [10, 11, 110, 111, 201])
    # I2 translated by (0, 2, 0), then rotated 90 deg about z through the origin
    np.testing.assert_allclose(deck.xyz[2:4], [[-2, 0, 0], [-2, 1, 0]], atol=1e-12)
    np.testing.assert_array_equal(deck.node_sets["I2.ENDS"], [110, 111])
    np.testing.assert_array_equal(deck.node_sets["TIP"], [111])
    assert "ENDS" not in deck.node_sets  # ambiguous over two instances
    assert deck.materials["M1"]["DENSITY"] == 7850.0 and len(deck.elements) == 2


def test_calculix_inp_goes_to_calculix():
    ccx = CCX / "beam8_clamped_mat.inp"
    model = flexmor.io.read(ccx)
    assert model.n_dof == flexmor.io.read(ccx.with_suffix(".sti")).n_dof


def _copy(tmp_path, stiff_text=None, inp_text=None):
    inp = _block("blockC3D8")
    for name in ("blockC3D8.inp", "blockC3D8_MASS1.mtx", "blockC3D8_STIF1.mtx"):
        shutil.copy(inp.with_name(name), tmp_path / name)
    if stiff_text is not None:
        (tmp_path / "blockC3D8_STIF1.mtx").write_text(stiff_text)
    if inp_text is not None:
        (tmp_path / "blockC3D8.inp").write_text(inp_text)
    return tmp_path / "blockC3D8.inp"


def _lines(name="blockC3D8_STIF1.mtx"):
    return (_block("blockC3D8").with_name(name)).read_text().splitlines(keepends=True)


@pytest.mark.parametrize("edit, line, words", [
    (lambda L: L[:100] + ["5 6\n"] + L[100:], 101, "expected 3 columns"),
    (lambda L: L[:-1] + ["528 528\n"], len(_lines()), "expected 3 columns"),
    (lambda L: L[:50] + ["529 1 1.0\n", "1 529 1.0\n"] + L[50:], 51, "beyond 176 nodes x 3 DOFs"),
    (lambda L: L[:50] + [L[0]] + L[50:], 51, "appears twice"),
    (lambda L: L[:7] + ["7 x 1.0\n"] + L[7:], 8, "must be integers"),
    (lambda L: L[:7] + ["7 7 nan\n"] + L[7:], 8, "non-finite"),
    (lambda L: ["1, 1, 1, 1\n"] + L, None, "first entry has 4 columns"),
    (lambda L: ["1, 1, 1, 1, 1.0\n", "1, 1, 999, 1, 1.0\n"], 2, "node 999 is not defined"),
    (lambda L: ["1, 1, 1, 7, 1.0\n"], 1, "direction 7"),
    (lambda L: ["1, 1, 1, 1, 1.0\n", "1, 1, 2\n"], 2, "expected 5 columns"),
    (lambda L: [], None, "file is empty"),
])
def test_broken_matrix_files(tmp_path, edit, line, words):
    inp = _copy(tmp_path, "".join(edit(_lines())))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    msg = str(exc.value)
    assert words in msg and "blockC3D8_STIF1.mtx" in msg
    if line is not None:
        assert f"blockC3D8_STIF1.mtx:{line}:" in msg


@pytest.mark.parametrize("edit, line, words", [
    (lambda s: s.replace("*Nset, nset=Set-1, generate\n   1,  176,    1", "*Nset, nset=Set-1\n 1, 177"),
     286, "names node 177"),
    (lambda s: s.replace("     17,    3.5999999,           1.,           1.", "     17,    3.59x,  1., 1."),
     34, "non-numeric"),
    (lambda s: s.replace("      2,", "      1,", 1), 19, "node 1 defined twice"),
    (lambda s: s.replace("part=block", "part=other"), 16, "no *PART defines"),
    (lambda s: s.replace("   1,  176,    1", "   176,  1,    1"), 286, "first <= last"),
])
def test_broken_decks(tmp_path, edit, line, words):
    text = _block("blockC3D8").read_text()
    inp = _copy(tmp_path, inp_text=edit(text))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    msg = str(exc.value)
    assert words in msg and f"blockC3D8.inp:{line}:" in msg


def test_missing_files(tmp_path):
    inp = _copy(tmp_path)
    (tmp_path / "blockC3D8_MASS1.mtx").unlink()
    with pytest.raises(ReadError, match=r"blockC3D8_MASS1\.mtx: not found; request it with \*MATRIX GENERATE"):
        flexmor.io.read(inp)
    (tmp_path / "blockC3D8_STIF1.mtx").unlink()
    with pytest.raises(ReadError, match=r"blockC3D8_STIF1\.mtx: not found.*CalculiX job would have blockC3D8\.sti"):
        flexmor.io.read(inp)
    (tmp_path / "x_STIF1.mtx").write_text("1 1 1.0\n")
    with pytest.raises(ReadError, match=r"x\.inp: not found"):
        flexmor.io.read(tmp_path / "x_STIF1.mtx")
