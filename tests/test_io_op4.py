"""OP4 files in every layout: binary (byte orders, 32/64-bit, single/double, complex), ASCII sparse
and BIGMAT, the CalculiX beam as KAA/MAA with its a-set from bulk data, and broken files."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from op4_writer import write_ascii, write_binary

import flexmor.io
from flexmor.errors import ReadError
from flexmor.io.nastran import read_op4

RNG = np.random.default_rng(7)


def _sample():
    A = RNG.standard_normal((7, 5))
    A[[0, 3, 4], 1] = 0.0  # runs: rows 2-3 and 6-7 of column 2
    A[:, 3] = 0.0  # an empty column
    return A


@pytest.mark.parametrize("endian", ["<", ">"])
@pytest.mark.parametrize("bit64", [False, True])
@pytest.mark.parametrize("layout", ["dense", "sparse", "bigmat"])
def test_binary_layouts(tmp_path, endian, bit64, layout):
    A = _sample()
    S = A[:5] + A[:5].T
    p = tmp_path / "m.op4"
    write_binary(p, {"A": A, "SYM": S}, endian=endian, bit64=bit64, sparse=layout != "dense",
                 bigmat=layout == "bigmat")
    m = read_op4(p)
    np.testing.assert_array_equal(m["A"], A)
    np.testing.assert_array_equal(m["SYM"], S)
    assert read_op4(p, sparse=True)["A"].nnz == np.count_nonzero(A)


@pytest.mark.parametrize("typ", [1, 3, 4])
def test_binary_single_and_complex(tmp_path, typ):
    A = _sample()
    if typ > 2:
        A = A + 1j * RNG.standard_normal(A.shape) * (A != 0)
    p = tmp_path / "c.op4"
    write_binary(p, {"C": A}, typ=typ, sparse=True)
    got = read_op4(p)["C"]
    np.testing.assert_allclose(got, A, rtol=1e-6 if typ in (1, 3) else 0)
    assert np.iscomplexobj(got) == (typ > 2)


@pytest.mark.parametrize("sparse, bigmat", [(True, False), (True, True), (False, False)])
def test_ascii_layouts(tmp_path, sparse, bigmat):
    A = _sample()
    p = tmp_path / "a.op4"
    write_ascii(p, {"A": A, "B": 2 * A}, sparse=sparse, bigmat=bigmat)
    m = read_op4(p)
    np.testing.assert_allclose(m["A"], A, rtol=1e-15)
    np.testing.assert_allclose(m["B"], 2 * A, rtol=1e-15)


def test_beam_as_op4_with_aset(tmp_path, clamped, clamped_ref):
    """KAA/MAA of the CalculiX beam in binary OP4; the a-set (ASET1 per node) gives the equation map."""
    order = np.lexsort((clamped.dofs[:, 1], clamped.dofs[:, 0]))
    K, M = clamped.K.toarray()[np.ix_(order, order)], clamped.M.toarray()[np.ix_(order, order)]
    write_binary(tmp_path / "beam.op4", {"KAA": K, "MAA": M}, endian=">", sparse=True)
    nodes = np.unique(clamped.dofs[:, 0])
    bdf = [f"GRID,{n},," + ",".join(repr(float(c)) for c in x) for n, x in zip(clamped.node_ids, clamped.xyz)]
    bdf += [f"ASET1,123,{n}" for n in nodes]
    (tmp_path / "beam.bdf").write_text("\n".join(bdf) + "\n")
    model = flexmor.io.read(tmp_path / "beam.op4")
    np.testing.assert_array_equal(model.dofs, clamped.dofs[order])
    np.testing.assert_array_equal(model.K.toarray(), K)
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 3])
    np.testing.assert_allclose(np.sqrt(w) / (2 * np.pi), clamped_ref[:4], rtol=1e-5)
    # a-set that does not match the matrices
    (tmp_path / "beam.bdf").write_text("\n".join(bdf[:-1]) + "\n")
    with pytest.raises(ReadError, match="give 267 equations, but the OP4 matrices have 270"):
        flexmor.io.read(tmp_path / "beam.op4", geometry=tmp_path / "beam.bdf")


def _bin(tmp_path, **kw):
    p = tmp_path / "b.op4"
    write_binary(p, {"A": _sample()}, **kw)
    return p, bytearray(p.read_bytes())


def test_broken_binary(tmp_path):
    p, raw = _bin(tmp_path)
    p.write_bytes(raw[:-30])
    with pytest.raises(ReadError, match="truncated"):
        read_op4(p)
    p, raw = _bin(tmp_path)
    raw[32 + 4 + 8:32 + 4 + 12] = (99).to_bytes(4, "little")  # nwords of the first column
    p.write_bytes(raw)
    with pytest.raises(ReadError, match="announces 99 words"):
        read_op4(p)
    p, raw = _bin(tmp_path)
    raw[32 + 4 + 4:32 + 4 + 8] = (7).to_bytes(4, "little")  # first row 7 of a 7-row dense column
    p.write_bytes(raw)
    with pytest.raises(ReadError, match="outside 7 x 5"):
        read_op4(p)
    p, raw = _bin(tmp_path)
    raw[16:20] = (9).to_bytes(4, "little")  # type 9
    p.write_bytes(raw)
    with pytest.raises(ReadError, match="not a valid matrix header"):
        read_op4(p)


def test_broken_ascii_sparse(tmp_path):
    p = tmp_path / "s.op4"
    write_ascii(p, {"A": _sample()}, sparse=True)
    lines = p.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if len(ln.split()) == 1 and ln.strip().isdigit())
    lines[k] = f"{(99 + 1) * 65536 + 1:12d}"  # a string longer than its column
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReadError, match=rf"s\.op4:{k + 1}: .*does not fit column"):
        read_op4(p)


# -- ASCII read streamed (op4_stream.fast_ascii) against the line scanner (op4._ascii) ---------
def _same(path):
    """The streamed reader takes ``path`` and gives bit for bit the matrices of the line scanner."""
    from flexmor.io.nastran import op4, op4_stream

    fast = op4_stream.fast_ascii(path, path.stat().st_size)
    assert fast is not None, "the streamed reader handed the file to the line scanner"
    old = op4._ascii(path)
    assert list(fast) == list(old)
    for name, (form, A) in fast.items():
        assert form == old[name][0]
        got, ref = (np.ascontiguousarray(x.toarray()).view(np.uint8) for x in (A, old[name][1]))
        np.testing.assert_array_equal(got, ref)
    return fast


def _wide_values(shape):
    """Values with exponents -90..90 (two digits: the field width holds them) and zeros."""
    A = RNG.standard_normal(shape) * 10.0 ** RNG.integers(-90, 90, shape)
    A[RNG.random(shape) < 0.3] = 0.0
    return A


@pytest.mark.parametrize("sparse, bigmat, per_line, width", [(False, False, 3, 23), (True, False, 3, 23),
                                                             (True, True, 5, 24), (False, False, 5, 16)])
def test_ascii_streamed_bit_identical(tmp_path, sparse, bigmat, per_line, width):
    p = tmp_path / "w.op4"
    A = _wide_values((40, 30))
    write_ascii(p, {"A": A, "S": A[:30] + A[:30].T, "E": np.zeros((3, 2))}, sparse=sparse, bigmat=bigmat,
                per_line=per_line, width=width)
    _same(p)
    np.testing.assert_array_equal(read_op4(p)["A"], A if width > 16 else read_op4(p)["A"])


def test_ascii_streamed_over_chunks(tmp_path, monkeypatch):
    """Records cut by the chunk boundaries (chunks of 1 kB), one matrix after the other."""
    from flexmor.io.nastran import op4_stream

    monkeypatch.setattr(op4_stream, "_CHUNK", 1000)
    p = tmp_path / "c.op4"
    A = _wide_values((61, 47))
    write_ascii(p, {"A": A, "B": A.T}, sparse=True)
    _same(p)
    write_ascii(p, {"A": A, "B": A.T})
    m = _same(p)
    np.testing.assert_array_equal(m["B"][1].toarray(), A.T)


def test_ascii_exporter_file(tmp_path, clamped):
    """A reduced body written by flexmor's own OP4 exporter (``1P,3E24.16``, symmetric, full columns)."""
    from flexmor.io import export
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    red = reduce(clamped, "krylov", 10, make_ports(clamped, [f"{int(clamped.dofs[-1, 0])}:y"]))
    p = tmp_path / "body.op4"
    export(red, p, model=clamped)
    m = _same(p)
    assert {"KAA", "MAA"} <= set(m)


def test_ascii_fortran_forms(tmp_path):
    """``D`` exponents, an implicit exponent (``1.25-3``) and a three-digit one without its letter."""
    p = tmp_path / "f.op4"
    A = _wide_values((8, 4))
    write_ascii(p, {"A": A}, per_line=3, width=23)
    text = p.read_text().replace("E+", "D+").replace("E-", "D-")
    p.write_text(text)
    _same(p)
    np.testing.assert_array_equal(read_op4(p)["A"], A)
    lines = p.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if len(ln) == 69)  # a full line of three values
    lines[k] = f"{'1.25-3':>23}{'-2.5+100':>23}{'.5':>23}"
    p.write_text("\n".join(lines) + "\n")
    m = _same(p)
    assert {1.25e-3, -2.5e100, 0.5} <= set(m["A"][1].data.tolist())


def test_ascii_corrupt_value_deep_in_file(tmp_path):
    p = tmp_path / "deep.op4"
    write_ascii(p, {"A": _wide_values((300, 200)) + 1.0, "B": np.eye(4)})
    lines = p.read_text().splitlines()
    k = 5000 + next(i for i, ln in enumerate(lines[5000:]) if len(ln) == 69)
    lines[k] = lines[k][:30] + "x" + lines[k][31:]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReadError, match=rf"deep\.op4:{k + 1}: non-numeric or non-finite value"):
        read_op4(p)
    lines[k] = lines[k][:23]  # a short line: the column reads into its next record
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReadError, match=r"deep\.op4:\d+: "):
        read_op4(p)


def test_ascii_broken_record_lines(tmp_path):
    """Record lines that are not three integers go to the line scanner, which names them."""
    p = tmp_path / "r.op4"
    write_ascii(p, {"A": _sample()})
    lines = p.read_text().splitlines()
    assert lines[5].split() == ["2", "2", "6"]
    for bad in ("       2       2--     6", "       2       2", "", "       2       2       6       0"):
        p.write_text("\n".join(lines[:5] + [bad] + lines[6:]) + "\n")
        with pytest.raises(ReadError, match=r"r\.op4:6: matrix A: expected a column record"):
            read_op4(p)


@pytest.mark.parametrize("sparse", [False, True])
def test_ascii_streamed_complex(tmp_path, sparse):
    """Type 4 (complex double): real and imaginary parts one after the other (words counted as values)."""
    C = RNG.standard_normal((4, 3)) + 1j * RNG.standard_normal((4, 3))
    interleaved = np.empty((8, 3))
    interleaved[0::2], interleaved[1::2] = C.real, C.imag
    p = tmp_path / "z.op4"
    write_ascii(p, {"Z": interleaved}, sparse=sparse)
    lines = p.read_text().splitlines()
    lines[0] = f"{3:8d}{4:8d}{2:8d}{4:8d}{'Z':<8}" + lines[0][40:]
    p.write_text("\n".join(lines) + "\n")
    _same(p)
    np.testing.assert_array_equal(read_op4(p)["Z"], C)
