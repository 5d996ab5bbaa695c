"""Bad-input cases that the per-format test files leave out: each is a ReadError naming file and line.

Rules (documented in the readers): duplicate matrix entries are refused, never summed
(CalculiX, Abaqus, Matrix Market, DMIG, OP4); an index beyond the matrix or the equation map is
refused with its line; a truncated file is reported as such.
"""

from __future__ import annotations

import numpy as np
import pytest
from op4_writer import write_ascii

import flexmor.io
from flexmor.errors import ReadError
from flexmor.io.nastran import read_op4

MM = "%%MatrixMarket matrix coordinate real symmetric\n"
PCH = "DMIG,KAAX,0,6,2,0,,2\nDMIG,KAAX,1,1\n,1,1,2.0,\nDMIG,KAAX,1,2\n,1,2,3.0,\n" \
      "DMIG,MAAX,0,6,2,0,,2\nDMIG,MAAX,1,1\n,1,1,1.0,\nDMIG,MAAX,1,2\n,1,2,1.0,\n"


@pytest.mark.parametrize("k_text, line, words", [
    (MM + "2 2 2\n1 1 1.0\n2 2\n", 4, "expected 3 columns"),
    (MM + "2 2 2\n1 1 1.0\n2 2 1.0 5.0\n", 4, "found 4"),
    (MM + "2 2 3\n1 1 1.0\n2 2 1.0\n1 1 1.0\n", 5, "appears twice"),
    (MM + "2 2 2\n1 1 1.0\n3 2 1.0\n", 4, "out of bounds"),
])
def test_matrix_market_columns_duplicates_bounds(tmp_path, k_text, line, words):
    (tmp_path / "p_M.mtx").write_text(MM + "2 2 2\n1 1 1.0\n2 2 1.0\n")
    (tmp_path / "p_K.mtx").write_text(k_text)
    with pytest.raises(ReadError, match=rf"p_K\.mtx:{line}: .*{words}"):
        flexmor.io.read(tmp_path / "p_K.mtx")


@pytest.mark.parametrize("edit, line, words", [
    (lambda s: s.replace(",1,2,3.0,", ",1,7,3.0,"), 5, "component 7 is not 0"),
    (lambda s: s.replace("DMIG,KAAX,1,2\n", "DMIG,KAAX,1,9\n"), 5, "component 9 is not 0"),
    (lambda s: s.rsplit("1.0,", 1)[0], 10, "has no value"),
    (lambda s: s.replace(",1,2,3.0,", ",1,2,3.0,4.0,"), 5, None),  # a B field on a real matrix is ignored
])
def test_dmig_components_and_truncation(tmp_path, edit, line, words):
    p = tmp_path / "x.pch"
    p.write_text(edit(PCH))
    if words is None:
        assert flexmor.io.read(p).K[1, 1] == 3.0
        return
    with pytest.raises(ReadError, match=rf"x\.pch:{line}: .*{words}"):
        flexmor.io.read(p)


def test_op4_duplicate_rows_refused(tmp_path):
    p = tmp_path / "d.op4"
    A = np.arange(1.0, 7.0).reshape(3, 2)
    write_ascii(p, {"A": A}, sparse=True)
    lines = p.read_text().splitlines()
    # column 1 holds one string (rows 1-3, 6 words); announce 14 words and repeat the string
    hdr = next(i for i, ln in enumerate(lines) if ln.split() == ["1", "0", "7"])
    lines[hdr] = f"{1:8d}{0:8d}{14:8d}"
    lines[hdr + 3:hdr + 3] = lines[hdr + 1:hdr + 3]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReadError, match="stores the same row twice"):
        read_op4(p)


def test_truncated_reduced_body(tmp_path, clamped):
    from flexmor.body import ReducedModel
    from flexmor.io import write_body

    red = ReducedModel(M=np.eye(2), K=np.diag([1.0, 4.0]), D=None, B=np.ones((2, 1)), C=np.ones((1, 2)))
    write_body(red, tmp_path / "r.h5")
    raw = (tmp_path / "r.h5").read_bytes()
    (tmp_path / "r.h5").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ReadError, match=r"r\.h5"):
        flexmor.io.read_body(tmp_path / "r.h5")
