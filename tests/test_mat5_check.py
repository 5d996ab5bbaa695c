"""The structural MAT-file check in front of scipy's compiled reader (flexmor.io.matlab._mat5):
every legal file passes unchanged, every damaged one is a ReadError naming what is wrong."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
from helpers import DATA

from flexmor.errors import ReadError
from flexmor.io.matlab._mat5 import MAX_DEPTH, checked_v5_stream

VARIABLES = {
    "M": np.eye(3), "K": sp.random(30, 20, density=0.2, random_state=1, format="csc"),
    "cplx": np.array([[1 + 2j, 3 - 1j]]), "ints": np.arange(12, dtype=np.int16).reshape(3, 4),
    "flags": np.array([[True, False]]), "name": "beam", "empty": np.zeros((0, 3)),
    "cell": np.array([[np.eye(2), "x"]], dtype=object), "st": {"a": np.ones((2, 2)), "b": "text"},
    "scplx": sp.csc_matrix(np.array([[0, 1j], [2, 0]])),
}


def _same(a, b):
    if sp.issparse(a):
        return sp.issparse(b) and a.shape == b.shape and (a != b).nnz == 0
    if isinstance(a, np.ndarray) and a.dtype.names:
        return all(_same(a[n][0, 0], b[n][0, 0]) for n in a.dtype.names)
    if isinstance(a, np.ndarray) and a.dtype == object:
        return all(_same(x, y) for x, y in zip(a.ravel(), b.ravel()))
    return np.array_equal(a, b)


@pytest.mark.parametrize("compress", [True, False])
def test_legal_files_pass_and_read_the_same(tmp_path, compress):
    p = tmp_path / "a.mat"
    scipy.io.savemat(p, VARIABLES, do_compression=compress)
    raw = p.read_bytes()
    direct = scipy.io.loadmat(p)
    checked = scipy.io.loadmat(checked_v5_stream(p, raw))
    assert set(direct) == set(checked)
    for k in VARIABLES:
        assert _same(direct[k], checked[k]), k


def test_v4_files_are_left_to_scipy(tmp_path):
    p = tmp_path / "v4.mat"
    scipy.io.savemat(p, {"M": np.eye(2)}, format="4")
    assert checked_v5_stream(p, p.read_bytes()) is None


def _element(t, payload):
    return struct.pack("<II", t, len(payload)) + payload + b"\x00" * (-len(payload) % 8)


def _matrix(cls, dims, parts, name=b"A", flags2=0):
    body = _element(6, struct.pack("<II", cls, flags2)) + _element(5, struct.pack(f"<{len(dims)}i", *dims))
    body += _element(1, name) + b"".join(parts)
    return _element(14, body)


def _file(*elements, compress=False):
    head = b"MATLAB 5.0 MAT-file, flexmor test".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x01IM"
    if compress:
        elements = [struct.pack("<II", 15, len(z)) + z for z in (zlib.compress(e) for e in elements)]
    return head + b"".join(elements)


def _check(tmp_path, raw):
    p = tmp_path / "x.mat"
    p.write_bytes(raw)
    return checked_v5_stream(p, raw)


def test_handmade_file_passes(tmp_path):
    raw = _file(_matrix(6, [2, 2], [_element(9, np.arange(4.0).tobytes())]), compress=True)
    out = scipy.io.loadmat(_check(tmp_path, raw))
    np.testing.assert_array_equal(out["A"], [[0, 2], [1, 3]])


@pytest.mark.parametrize("raw,message", [
    (_file(_matrix(6, [1000000, 1000000], [_element(9, np.arange(4.0).tobytes())])),
     "real part holds 4 values for dimensions [1000000, 1000000]"),
    (_file(_matrix(6, [2, 2], [_element(9, np.arange(4.0).tobytes())]))[:-8], "claims"),
    (_file(_matrix(6, [2, -2], [_element(9, b"")])), "negative dimension"),
    (_file(_matrix(99, [1, 1], [_element(9, b"\x00" * 8)])), "unknown array class 99"),
    (_file(_matrix(6, [1, 1], [_element(8, b"\x00" * 8)])), "unexpected data type 8"),
    (_file(_matrix(5, [3, 2], [_element(5, struct.pack("<2i", 0, 7)), _element(5, struct.pack("<3i", 0, 1, 2)),
                               _element(9, np.ones(2).tobytes())])), "sparse row index outside 0..2"),
    (_file(_matrix(5, [3, 2], [_element(5, struct.pack("<2i", 0, 1)), _element(5, struct.pack("<3i", 0, 2, 1)),
                               _element(9, np.ones(2).tobytes())])), "not ascending"),
    (_file(_matrix(5, [3, 2], [_element(5, struct.pack("<2i", 0, 1)), _element(5, struct.pack("<2i", 0, 2)),
                               _element(9, np.ones(2).tobytes())])), "column index holds 2 entries for 2 columns"),
    (_file(_element(9, b"\x00" * 8)), "top-level element of type 9"),
    (_file(_matrix(6, [1, 1], [_element(9, b"\x00" * 8)]), compress=True)[:-5], "claims"),
], ids=["huge-dims", "cut", "negative-dim", "class", "type", "sparse-row", "sparse-col", "sparse-ncol", "toplevel",
        "compressed-cut"])
def test_damaged_files_are_refused(tmp_path, raw, message):
    with pytest.raises(ReadError, match="damaged MATLAB file") as e:
        _check(tmp_path, raw)
    assert message in str(e.value)


def test_truncated_zlib_stream_and_deep_nesting_are_refused(tmp_path):
    inner = _matrix(6, [1, 1], [_element(9, b"\x00" * 8)])
    z = zlib.compress(inner)[:-6]  # the stream stops early, its element size says so consistently
    with pytest.raises(ReadError, match="compressed data at byte 128 are cut off"):
        _check(tmp_path, _file() + struct.pack("<II", 15, len(z)) + z)
    m = inner
    for _ in range(MAX_DEPTH + 2):
        m = _matrix(1, [1, 1], [m])
    with pytest.raises(ReadError, match="nested deeper"):
        _check(tmp_path, _file(m))


def test_the_corpus_file_that_crashed_scipy(tmp_path):
    p = DATA / "bad" / "mat_cut_compressed.mat"
    with pytest.raises(ReadError, match="variable 3"):
        checked_v5_stream(p, p.read_bytes())
