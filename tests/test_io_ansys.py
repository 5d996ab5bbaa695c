"""Ansys readers: the rotor's HBMAT/MMF export with mapping vector and coordinates, the binary .full file."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import DATA, geometric_rigid_modes

import flexmor.io
from flexmor.errors import ReadError

ANSYS = DATA / "ansys"
ROTOR = ["rotorAnsysStiffnessMatrixSparse.txt", "rotorAnsysMassMatrixSparse.txt",
         "rotorAnsysMatrixDofMappingVector.txt", "rotorAnsysNodalCoordinates.txt"]


@pytest.fixture(scope="module")
def rotor():
    return flexmor.io.read(ANSYS / ROTOR[0])


def test_rotor_first_flexible_mode_matches_exudyn(rotor):
    assert rotor.n_dof == 345 and rotor.n_nodes == 115 and rotor.name == "rotorAnsys"
    w = sla.eigh(rotor.K.toarray(), rotor.M.toarray(), eigvals_only=True, subset_by_index=[0, 7])
    f = np.sqrt(np.abs(w)) / (2 * np.pi)
    assert np.all(f[:6] < 1e-2)
    assert f[6] == pytest.approx(104.637011, abs=1e-6)


def test_rotor_equations_map_to_nodes(rotor):
    # block i of 3 equations belongs to node vector[i]: rigid rotations give no elastic force
    np.testing.assert_array_equal(rotor.dofs[:4], [[3, 1], [3, 2], [3, 3], [31, 1]])
    R = geometric_rigid_modes(rotor)
    assert np.abs(rotor.K @ R).max() < 1e-11 * abs(rotor.K).max()
    np.testing.assert_allclose(rotor.node_xyz([1])[0], [-4.996003611e-16, -4.996003611e-16, 0.15])
    np.testing.assert_allclose(rotor.node_xyz([2])[0], [-4.996003611e-16, -4.996003611e-16, 0.1])
    m = [R[:, j] @ (rotor.M @ R[:, j]) for j in range(3)]
    np.testing.assert_allclose(m, m[0], rtol=1e-12)


def _rotor_copy(tmp_path, **texts):
    for name in ROTOR:
        shutil.copy(ANSYS / name, tmp_path / name)
    for key, text in texts.items():
        (tmp_path / ROTOR[["K", "M", "map", "xyz"].index(key)]).write_text(text)
    return tmp_path / ROTOR[0]


def test_hbmat_mapping_file_and_decimal_points(tmp_path, rotor):
    path = _rotor_copy(tmp_path)
    (tmp_path / ROTOR[2]).unlink()
    lab = {1: "UX", 2: "UY", 3: "UZ"}
    (tmp_path / "rotorAnsysStiffness.mapping").write_text(
        "Matrix Eqn   Node   DOF\n" + "".join(f"{i + 1} {n} {lab[d]}\n" for i, (n, d) in enumerate(rotor.dofs)))
    xyz = "Node;X;Y;Z\n" + "".join(f"{n};" + ";".join(repr(float(c)) for c in p) + "\n"
                                    for n, p in zip(rotor.node_ids, rotor.xyz))
    (tmp_path / ROTOR[3]).write_text(xyz)
    model = flexmor.io.read(path)
    np.testing.assert_array_equal(model.dofs, rotor.dofs)
    np.testing.assert_array_equal(model.xyz, rotor.xyz)


def _text(i):
    return (ANSYS / ROTOR[i]).read_text(encoding="latin-1")


@pytest.mark.parametrize("key, edit, fname, line, words", [
    ("map", lambda s: s.rsplit("\n", 3)[0] + "\n", ROTOR[2], 120, "announces 115 entries but 113"),
    ("map", lambda s: s.replace("\n31\n", "\n3x\n", 1), ROTOR[2], 9, "one node number per line"),
    ("map", lambda s: s.replace("115 1", "114 1").rsplit("\n", 2)[0] + "\n", ROTOR[2], None, "do not fit 345"),
    ("xyz", lambda s: s.replace("2\t-4,996003611e-016\t", "2\t", 1), ROTOR[3], 3, "expected 'node x y z'"),
    ("xyz", lambda s: s.replace("0,15", "0,1x5", 1), ROTOR[3], 2, "non-numeric coordinate"),
    ("xyz", lambda s: "\n".join(ln for ln in s.splitlines() if not ln.startswith("31\t")) + "\n",
     ROTOR[2], None, "node 31 is not in rotorAnsysNodalCoordinates.txt"),
])
def test_broken_companion_files(tmp_path, key, edit, fname, line, words):
    path = _rotor_copy(tmp_path, **{key: edit(_text(2 if key == "map" else 3))})
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(path)
    msg = str(exc.value)
    assert words in msg and fname in msg
    if line is not None:
        assert f"{fname}:{line}:" in msg


def test_hbmat_mapping_errors(tmp_path):
    path = _rotor_copy(tmp_path)
    (tmp_path / ROTOR[2]).unlink()
    m = tmp_path / "rotorAnsysStiffness.mapping"
    m.write_text("Matrix Eqn Node DOF\n1 3 UX\n346 3 UY\n")
    with pytest.raises(ReadError, match=r"mapping:3: equation 346 outside 1\.\.345"):
        flexmor.io.read(path)
    m.write_text("Matrix Eqn Node DOF\n1 3 TEMP\n")
    with pytest.raises(ReadError, match=r"mapping:2: DOF TEMP is not one of"):
        flexmor.io.read(path)
    m.write_text("Matrix Eqn Node DOF\n1 3 UX\n")
    with pytest.raises(ReadError, match=r"equation 2 is missing from the map"):
        flexmor.io.read(path)


FULL = ANSYS / "ansys_file.full"


@pytest.fixture(scope="module")
def full_model():
    pytest.importorskip("ansys.mapdl.reader")
    if not FULL.exists():
        pytest.skip("ansys_file.full not available")
    return flexmor.io.read(FULL, coordinates=ANSYS / "ansys_HexBeam.cdb")


def test_full_file_constrained_dofs_removed_and_reported(full_model):
    m = full_model
    assert m.n_dof == 900 and m.n_nodes == 321
    gone = m.constrained_dofs
    assert gone.shape == (63, 2)
    np.testing.assert_array_equal(np.unique(gone[:, 0]), np.arange(1, 22))
    assert not np.any(np.isin(m.dofs[:, 0], gone[:, 0]))
    assert abs(m.K - m.K.T).max() == 0.0 and m.K.diagonal().min() > 0
    # away from the clamp, rigid motions of the nodes give no elastic force (the map is right)
    res = np.abs(m.K @ geometric_rigid_modes(m)).max(axis=1) / abs(m.K).max()
    assert np.count_nonzero(res < 1e-10) >= 800
    w = sla.eigh(m.K.toarray(), m.M.toarray(), eigvals_only=True, subset_by_index=[0, 1])
    assert np.sqrt(w[0]) / (2 * np.pi) == pytest.approx(1283.2004, rel=1e-6)


def test_broken_full_files(tmp_path):
    pytest.importorskip("ansys.mapdl.reader")
    if not FULL.exists():
        pytest.skip("ansys_file.full not available")
    raw = FULL.read_bytes()
    cases = [(f"cut{k}.full", raw[:k]) for k in (100, 1000, 20000, 425984, 600000, 800000)]
    cases += [("junk.full", b"\x01" * 4096), ("tiny.full", b"x")]
    for name, data in cases:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ReadError, match=name.replace(".", r"\.")):
            flexmor.io.read(tmp_path / name)
