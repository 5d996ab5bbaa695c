"""MATLAB reader: the SLICOT LF10 benchmark and broken or unsuitable .mat files."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
from helpers import DATA

import flexmor.io
from flexmor.damping import GivenDamping
from flexmor.errors import ReadError

LF10 = DATA / "mor" / "LF10.mat"


@pytest.fixture(scope="module")
def lf10():
    return flexmor.io.read(LF10)


def test_lf10_shapes_and_ports(lf10):
    assert lf10.n_dof == 18
    assert lf10.name == "LF10"
    assert lf10.M.nnz == lf10.K.nnz == 82
    assert lf10.B.shape == (18, 1) and lf10.C.shape == (1, 18)
    # input and output are both the 8th DOF
    assert lf10.B.toarray().ravel().nonzero()[0].tolist() == [7]
    assert lf10.C.toarray().ravel().nonzero()[0].tolist() == [7]
    assert lf10.input_names == ["u1"] and lf10.output_names == ["y1"]


def test_lf10_symmetric_and_rayleigh_damped(lf10):
    for A in (lf10.M, lf10.K, lf10.D):
        assert abs(A - A.T).max() == 0.0
    assert np.linalg.eigvalsh(lf10.M.toarray()).min() > 0
    # LF10's damping is exactly Rayleigh: D = 100 M + 0.01 K
    R = lf10.D - (100.0 * lf10.M + 0.01 * lf10.K)
    assert abs(R).max() < 1e-12 * abs(lf10.D).max()
    assert lf10.damping == GivenDamping()


def test_lower_case_names_and_dense(tmp_path):
    M, K = np.diag([1.0, 2.0]), np.array([[3.0, -1.0], [-1.0, 1.0]])
    scipy.io.savemat(tmp_path / "small.mat", {"m": M, "k": sp.csc_matrix(K), "b": np.array([[0.0], [1.0]])})
    model = flexmor.io.read(tmp_path / "small.mat")
    np.testing.assert_array_equal(model.K.toarray(), K)
    assert model.M[1, 1] == 2.0
    assert model.D is None and model.C is None
    assert model.B.shape == (2, 1)


@pytest.mark.parametrize("variables, words", [
    ({"A": np.eye(2), "B": np.ones((2, 1)), "C": np.ones((1, 2))},
     "first-order model (A, B, C); flexmor needs second-order M, K (and D)"),
    ({"M": np.eye(2)}, "variable K not found (variables in file: M)"),
    ({"M": np.eye(2), "K": np.eye(2) * (1 + 1j)}, "'K' is complex"),
    ({"M": np.eye(2), "K": np.array([[1.0, np.nan], [np.nan, 1.0]])}, "'K' contains NaN or Inf"),
    ({"M": np.eye(2), "K": {"a": 1.0}}, "'K' is not a numeric matrix"),
    ({"M": np.eye(2), "K": np.array([[2.0, 1.0], [0.0, 2.0]])}, "K is not symmetric"),
    ({"M": np.eye(2), "K": np.eye(3)}, "K has shape (3, 3), expected (2, 2)"),
    ({"M": np.eye(2), "K": np.eye(2), "B": np.ones((1, 2))}, "B is 1 x 2; expected n x m with n = 2 (transposed?)"),
    ({"M": np.diag([1.0, 0.0]), "K": np.eye(2)}, "mass matrix diagonal is not positive"),
])
def test_bad_contents(tmp_path, variables, words):
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, variables)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(path)
    assert str(exc.value).startswith(f"{path}: ")
    assert words in str(exc.value)


def test_text_file_named_mat():
    with pytest.raises(ReadError, match=r"text\.mat: is a text file, not a binary MATLAB MAT-file"):
        flexmor.io.read(DATA / "bad" / "text.mat")


def test_empty_and_junk_mat(tmp_path):
    (tmp_path / "empty.mat").write_bytes(b"")
    with pytest.raises(ReadError, match=r"empty\.mat: file is empty"):
        flexmor.io.read(tmp_path / "empty.mat")
    (tmp_path / "junk.mat").write_bytes(bytes(range(256)) * 8)
    with pytest.raises(ReadError, match=r"junk\.mat: not a readable MATLAB \.mat file"):
        flexmor.io.read(tmp_path / "junk.mat")


def test_v73_hdf5_file_is_refused(tmp_path):
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    path = tmp_path / "v73.mat"
    path.write_bytes(header.ljust(512, b" ") + b"\x89HDF\r\n\x1a\n" + bytes(64))
    with pytest.raises(ReadError, match=r"v73\.mat: MATLAB v7\.3 \(HDF5\) files are not supported; re-save"):
        flexmor.io.read(path)
