"""Inputs found by bench/fuzz.py that once escaped as raw ValueErrors; each must be a ReadError."""

import shutil

import pytest
from helpers import DATA

import flexmor.io
from flexmor.errors import ReadError


def test_op4_header_with_huge_dimension(tmp_path):
    src = (DATA / "nastran" / "pyyeti_rd_ascii.op4").read_text().splitlines(keepends=True)
    src[0] = src[0].replace("       6       5", "   99999  999999", 1)
    p = tmp_path / "big.op4"
    p.write_text("".join(src))
    with pytest.raises(ReadError, match="header announces 99999 columns"):
        flexmor.io.read(p)


def test_sid_taylor_object_with_huge_dimension(tmp_path):
    text = (DATA / "sid" / "Beam_3m.SID_FEM").read_text()
    p = tmp_path / "big.SID_FEM"
    p.write_text(text.replace("nrow                  =    3", "nrow                  =    999999999", 1))
    with pytest.raises(ReadError, match="implausibly large"):
        flexmor.io.read(p)


def test_ansys_mapping_vector_with_superscript_digit(tmp_path):
    for f in (DATA / "ansys").glob("rotor*.txt"):
        shutil.copy(f, tmp_path / f.name)
    vec = tmp_path / "rotorAnsysMatrixDofMappingVector.txt"
    lines = vec.read_text().splitlines(keepends=True)
    last = max(i for i, ln in enumerate(lines) if ln.strip().isdigit())
    lines[last] = "1\u00b9\n"
    vec.write_text("".join(lines), encoding="utf-8")
    with pytest.raises(ReadError, match="node number"):
        flexmor.io.read(tmp_path / "rotorAnsysStiffnessMatrixSparse.txt")


def test_mat_with_damaged_compressed_variable_is_refused_not_a_crash():
    # bench/fuzz.py seed 67581 (and 5 more seeds): scipy.io.loadmat alone dies with SIGSEGV on this
    # file, so it is read in a child process: a crash there fails the test instead of the suite
    import subprocess
    import sys

    code = ("import sys, flexmor.io\n"
            "from flexmor.errors import ReadError\n"
            "try:\n    flexmor.io.read(sys.argv[1])\n"
            "except ReadError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code, str(DATA / "bad" / "mat_cut_compressed.mat")],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "damaged MATLAB file: compressed data at byte 253 are" in out.stdout
