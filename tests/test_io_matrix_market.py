"""Matrix Market reader: a spring-mass chain written by scipy, Ansys' own export, broken files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.linalg as sla
import scipy.sparse as sp
from helpers import DATA

import flexmor.io
from flexmor.damping import GivenDamping, NoDamping
from flexmor.errors import ReadError
from flexmor.io.matrix_market import find_siblings

BAD = DATA / "bad"

N, MASS, STIFF = 6, 2.0, 800.0


def _chain():
    """Fixed-free chain of N equal masses and springs (the first spring is tied to ground)."""
    K = sp.diags([-STIFF * np.ones(N - 1), 2 * STIFF * np.ones(N), -STIFF * np.ones(N - 1)], [-1, 0, 1]).tolil()
    K[N - 1, N - 1] = STIFF
    return MASS * sp.eye(N, format="csr"), K.tocsr()


def _chain_omega():
    j = np.arange(1, N + 1)
    return 2 * np.sqrt(STIFF / MASS) * np.sin((2 * j - 1) * np.pi / (2 * (2 * N + 1)))


def _write(folder: Path, names, D=None, symmetry="symmetric"):
    M, K = _chain()
    for A, name in zip((K, M, D), names):
        if A is not None and name:
            with open(folder / name, "wb") as f:  # a file object keeps the suffix (.mm) as given
                scipy.io.mmwrite(f, A, symmetry=symmetry)
    return [folder / n for n in names if n]


@pytest.mark.parametrize("names", [("chain_K.mtx", "chain_M.mtx"), ("chainK.mm", "chainM.mm"),
                                   ("chain_STIF.mtx", "chain_MASS.mtx"), ("chain_stiffness.mtx", "chain_mass.mtx"),
                                   ("K.mtx", "M.mtx")])
def test_spring_mass_chain_frequencies(tmp_path, names):
    k_file, m_file = _write(tmp_path, names)
    for main in (k_file, m_file):  # either file may be passed
        model = flexmor.io.read(main)
        assert model.n_dof == N and model.n_nodes == 0 and model.dofs is None
        assert model.K[N - 1, N - 1] == STIFF and model.K[0, 1] == model.K[1, 0] == -STIFF
        w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
        np.testing.assert_allclose(np.sqrt(w), _chain_omega(), rtol=1e-12)
        assert model.D is None and model.damping == NoDamping()
    assert model.name in ("chain", tmp_path.name)


def test_damping_file_and_general_storage(tmp_path):
    M, K = _chain()
    D = 0.5 * M + 1e-3 * K
    _write(tmp_path, ("rotor_K.mtx", "rotor_M.mtx", "rotor_D.mtx"), D=D, symmetry="general")
    model = flexmor.io.read(tmp_path / "rotor_M.mtx")
    assert model.name == "rotor"
    assert model.damping == GivenDamping()
    np.testing.assert_allclose(model.D.toarray(), D.toarray(), rtol=1e-15)
    assert set(find_siblings(tmp_path / "rotor_K.mtx")) == {"K", "M", "D"}


def test_ansys_rotor_matches_exudyn():
    # Ansys' own Matrix Market export; Exudyn computes the first flexible mode at 104.637011 Hz
    model = flexmor.io.read(DATA / "ansys" / "rotorAnsysStiffnessMatrixSparse.txt", format="matrix-market")
    assert model.n_dof == 345
    assert model.M.nnz == 345  # lumped mass
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 7])
    f = np.sqrt(np.abs(w)) / (2 * np.pi)
    assert np.all(f[:6] < 0.01)
    assert f[6] == pytest.approx(104.637011, rel=1e-7)


def test_asymmetric_general_storage():
    with pytest.raises(ReadError, match=r"asym_K\.mtx: K is not symmetric"):
        flexmor.io.read(BAD / "asym_K.mtx")


def test_missing_partner_lists_names(tmp_path):
    _write(tmp_path, ("beam_K.mtx", None))
    with pytest.raises(ReadError, match=r"beam_K\.mtx: read as the stiffness matrix, but no mass file.*beam_M\.mtx"):
        flexmor.io.read(tmp_path / "beam_K.mtx")


def test_unrecognized_name_and_damping_as_main(tmp_path):
    _write(tmp_path, ("rotor_K.mtx", "rotor_M.mtx", "rotor_D.mtx"), D=sp.eye(N))
    (tmp_path / "rotor_K.mtx").rename(tmp_path / "rotor_x.mtx")
    with pytest.raises(ReadError, match="cannot tell stiffness from mass"):
        flexmor.io.read(tmp_path / "rotor_x.mtx")
    with pytest.raises(ReadError, match="damping matrix"):
        flexmor.io.read(tmp_path / "rotor_D.mtx")


def _pair(tmp_path, k_text):
    _write(tmp_path, ("p_K.mtx", "p_M.mtx"))
    (tmp_path / "p_K.mtx").write_text(k_text)
    return tmp_path / "p_K.mtx"


HEAD = "%%MatrixMarket matrix coordinate real symmetric\n"


@pytest.mark.parametrize("text, line, words", [
    ("", None, "file is empty"),
    ("6 6 1\n1 1 1.0\n", 1, "not a Matrix Market file"),
    ("%%MatrixMarket matrix coordinate complex symmetric\n6 6 1\n1 1 1.0 0.0\n", 1, "complex"),
    ("%%MatrixMarket matrix coordinate pattern symmetric\n6 6 1\n1 1\n", 1, "pattern"),
    ("%%MatrixMarket matrix coordinate real skew-symmetric\n6 6 1\n2 1 1.0\n", 1, "skew-symmetric"),
    (HEAD + "6 6 3\n1 1 1.0\n2 x 2.0\n3 3 1.0\n", 4, "must be integers"),
    (HEAD + "6 6 3\n1 1 1.0\n2 9 2.0\n3 3 1.0\n", 4, "out of bounds"),
    (HEAD + "6 6 3\n1 1 1.0\n2 2 2.0\n", None, "runcated"),
    (HEAD + "6 6 2\n1 1 1.0\n2 2 nan\n", 4, "non-finite value nan"),
    (HEAD + "5 5 1\n1 1 1.0\n", None, "shape (5, 5), expected (6, 6)"),
    (HEAD + "6 5 1\n1 1 1.0\n", None, "6 x 5, expected square"),
])
def test_broken_files(tmp_path, text, line, words):
    path = _pair(tmp_path, text)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(path)
    msg = str(exc.value)
    assert words in msg
    assert "p_K.mtx" in msg
    if line is not None:
        assert f"p_K.mtx:{line}:" in msg
