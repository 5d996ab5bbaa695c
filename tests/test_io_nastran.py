"""Nastran readers: pyyeti's DMIG punch and OP4 files, DMIG written from the CalculiX beam, broken files."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import DATA

import flexmor.io
from flexmor.errors import ReadError
from flexmor.io.nastran import read_dmig, read_op4

NASTRAN = DATA / "nastran"
PCH = NASTRAN / "pyyeti_matrix_factory.pch"
OP4 = NASTRAN / "pyyeti_rd_ascii.op4"


def _dense(entry):
    ifo, r, c, v, _ = entry
    rows, ri = np.unique(r, axis=0, return_inverse=True)
    cols, ci = np.unique(c, axis=0, return_inverse=True)
    A = np.zeros((len(rows), len(cols)), v.dtype)
    A[ri.ravel(), ci.ravel()] = v
    return rows, cols, A


def test_pyyeti_punch_matrices():
    mats = read_dmig(PCH)
    assert set(mats) == {"PATRN", "IDENT", "RANDM", "CMPLX"}
    rows, cols, P = _dense(mats["PATRN"])
    assert P.shape == (21, 21) and rows[-1].tolist() == [12, 0]  # three scalar points after grids 1-3
    np.testing.assert_array_equal(P, np.tile(np.arange(1.0, 22.0), (21, 1)))  # column k holds k
    assert mats["IDENT"][0] == 6 and np.array_equal(_dense(mats["IDENT"])[2], np.eye(21))
    assert _dense(mats["RANDM"])[2][0, 0] == pytest.approx(0.1676407065)
    _, ccols, C = _dense(mats["CMPLX"])
    assert C.shape == (21, 50) and C[0, 0] == pytest.approx(0.6223991745 + 0.09231721747j)


def test_pyyeti_op4():
    m = read_op4(OP4)
    assert {k: v.shape for k, v in m.items()} == {"R1": (5, 6), "R2": (10, 19), "R3": (1, 1)}
    R1 = m["R1"]
    assert R1[1, 0] == pytest.approx(0.2305579698285401, rel=1e-15)  # values touch: fixed-width split
    assert R1[2, 0] == pytest.approx(-0.07900736795661149, rel=1e-15)
    np.testing.assert_array_equal(R1[:, 1], 0.0)
    np.testing.assert_array_equal(R1[:2, 3], 0.0)
    assert R1[4, 3] == pytest.approx(1.974703726546386) and not m["R2"].any() and m["R3"][0, 0] == 3.0


def test_punch_with_scalar_points_is_refused():
    with pytest.raises(ReadError, match="scalar point"):
        flexmor.io.read(PCH, stiffness="IDENT", mass="IDENT")
    with pytest.raises(ReadError, match="cannot tell the stiffness matrix among CMPLX, IDENT, PATRN, RANDM"):
        flexmor.io.read(PCH)


def _large(v):
    return f"{v: .9E}".replace("E", "D").rjust(16)


def _write_dmig(path, model, style):
    """Write K and M of ``model`` as KAAX/MAAX DMIG (upper triangle) in small, large or free field."""
    lines = []
    for name, A in (("KAAX", model.K), ("MAAX", model.M)):
        A = A.tocsc()
        lines.append(f"DMIG    {name:<8}       0       6       2       0                     {model.n_dof:>3}")
        for j in range(model.n_dof):
            gj, cj = model.dofs[j]
            rows = [i for i in A.indices[A.indptr[j]:A.indptr[j + 1]] if i <= j]
            vals = dict(zip(A.indices[A.indptr[j]:A.indptr[j + 1]], A.data[A.indptr[j]:A.indptr[j + 1]]))
            if style == "large":
                lines.append(f"DMIG*   {name:<16}{gj:>16}{cj:>16}")
                lines += [f"*       {model.dofs[i, 0]:>16}{model.dofs[i, 1]:>16}{_large(vals[i])}" for i in rows]
            else:
                lines.append(f"DMIG,{name},{gj},{cj},")
                lines += [f",{model.dofs[i, 0]},{model.dofs[i, 1]},{float(vals[i])!r}," for i in rows]
    path.write_text("\n".join(lines) + "\n")
    bdf = ["$ grids", *(f"GRID,{n},," + ",".join(repr(float(c)) for c in p) for n, p in zip(model.node_ids, model.xyz))]
    path.with_suffix(".bdf").write_text("\n".join(bdf) + "\n")


@pytest.mark.parametrize("style", ["large", "free"])
def test_dmig_of_the_calculix_beam(tmp_path, clamped, clamped_ref, style):
    pch = tmp_path / "beam.pch"
    _write_dmig(pch, clamped, style)
    model = flexmor.io.read(pch)
    np.testing.assert_array_equal(model.dofs, clamped.dofs[np.lexsort((clamped.dofs[:, 1], clamped.dofs[:, 0]))])
    assert model.n_nodes == clamped.n_nodes
    np.testing.assert_array_equal(model.node_xyz(model.dofs[:5, 0]), clamped.node_xyz(model.dofs[:5, 0]))
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 4])
    rtol = 1e-9 if style == "free" else 1e-5  # large field keeps 10 digits, as Nastran's own punch
    np.testing.assert_allclose(np.sqrt(w) / (2 * np.pi), clamped_ref[:5], rtol=max(rtol, 1e-5))
    ref = sla.eigh(clamped.K.toarray(), clamped.M.toarray(), eigvals_only=True, subset_by_index=[0, 4])
    np.testing.assert_allclose(w, ref, rtol=rtol)


def test_op4_model_spring_mass(tmp_path):
    k, m = 800.0, 2.0
    K = np.array([[2 * k, -k], [-k, k]])
    text = ""
    for name, A in (("KAA", K), ("MAA", m * np.eye(2))):
        text += f"       2       2       6       2{name:<8}1P,3E23.16\n"
        for j in range(2):
            text += f"       {j + 1}       1       2\n" + "".join(f"{x:23.16E}" for x in A[:, j]) + "\n"
        text += "       3       1       1\n 0.0000000000000000E+00\n"
    (tmp_path / "chain.op4").write_text(text)
    model = flexmor.io.read(tmp_path / "chain.op4")
    assert model.dofs is None and model.n_dof == 2
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
    np.testing.assert_allclose(w, k / m * np.array([(3 - 5 ** 0.5) / 2, (3 + 5 ** 0.5) / 2]), rtol=1e-14)


BEAM_PCH = "DMIG,KAAX,0,6,2,0,,2\nDMIG,KAAX,1,1\n,1,1,2.0,\nDMIG,KAAX,1,2\n,1,2,3.0,\n" \
           "DMIG,MAAX,0,6,2,0,,2\nDMIG,MAAX,1,1\n,1,1,1.0,\nDMIG,MAAX,1,2\n,1,2,1.0,\n"


@pytest.mark.parametrize("edit, line, words", [
    (lambda s: s.replace(",1,2,3.0,", ",1,2,3.x,"), 5, "non-numeric field"),
    (lambda s: s.replace("DMIG,KAAX,1,2\n,1,2,3.0,\n", "DMIG,KAAX,1,2\n,1,2,3.0,\nDMIG,KAAX,1,2\n,1,2,1.0,\n"),
     7, "given twice"),
    (lambda s: s.replace("DMIG,KAAX,0,6,2,0,,2\n", ""), 1, "column before its header"),
    (lambda s: s.replace("DMIG,MAAX,0,6,2", "DMIG,MAAX,0,6,9"), 6, "not supported"),
    (lambda s: ",1,1,1.0\n" + s, 1, "continuation line without a card"),
    (lambda s: s.replace("MAAX", "XAAX"), None, "cannot tell the mass matrix"),
    (lambda s: "GRID,1\n", None, "no DMIG matrices found"),
])
def test_broken_punch(tmp_path, edit, line, words):
    p = tmp_path / "bad.pch"
    p.write_text(edit(BEAM_PCH))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(p)
    msg = str(exc.value)
    assert words in msg and "bad.pch" in msg
    if line is not None:
        assert f"bad.pch:{line}:" in msg


def test_punch_geometry_errors(tmp_path):
    p = tmp_path / "g.pch"
    p.write_text(BEAM_PCH)
    assert flexmor.io.read(p).n_dof == 2
    p.with_suffix(".bdf").write_text("GRID,2,,0.,0.,0.\n")
    with pytest.raises(ReadError, match=r"g\.bdf: grid 1 of the matrices has no GRID card"):
        flexmor.io.read(p)
    p.with_suffix(".bdf").write_text("$\nGRID,1,5,0.,0.,0.\n")
    with pytest.raises(ReadError, match=r"g\.bdf:2: GRID 1: coordinate system CP=5 is not defined"):
        flexmor.io.read(p)


@pytest.mark.parametrize("edit, words", [
    (lambda L: L[:3], "file ends"),
    (lambda L: L[:1] + ["       1       1       x"] + L[2:], "column record"),
    (lambda L: ["junk header"] + L, "expected an OP4 header"),
    (lambda L: L[:1] + ["       1       4       5"] + L[2:], "outside 5 x 6"),
])
def test_broken_op4(tmp_path, edit, words):
    p = tmp_path / "bad.op4"
    p.write_text("\n".join(edit(OP4.read_text().splitlines())) + "\n")
    with pytest.raises(ReadError, match=words):
        read_op4(p)
    (tmp_path / "bin.op4").write_bytes(b"\x00\x01\x02" * 40)
    with pytest.raises(ReadError, match="not an OP4 file"):
        read_op4(tmp_path / "bin.op4")
