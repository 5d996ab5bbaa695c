"""Damaged files are refused or named: every reader cross-checks what its format allows.

A file cut off at a line end, or with lines lost, parses line by line without a defect; what
gives it away is what the files of one export say about each other (the entry counts of a
CalculiX ``.sti`` and ``.mas`` on one pattern, the two triangles of an Abaqus matrix, a
stiffness row without its diagonal). Each test damages a real sample the way a copy does.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest
from helpers import CCX, DATA, ROOT, load_script, run

import flexmor.io
from flexmor.errors import FlexmorWarning, ReadError
from flexmor.io import UncheckedWarning
from flexmor.io._fastparse import fast_triplets
from flexmor.io.nastran import read_op4

ABQ = DATA / "abaqus"


def _job(tmp_path, src=CCX / "beam8_free_mat", name="job"):
    for suf in (".sti", ".mas", ".dof", ".inp"):
        shutil.copy(f"{src}{suf}", tmp_path / f"{name}{suf}")
    return tmp_path / f"{name}.sti"


def _cut_lines(path, k=None, keep=None):
    """Cut ``path`` at a line end: drop its last ``k`` lines (or keep the fraction ``keep``)."""
    lines = path.read_bytes().splitlines(keepends=True)
    n = len(lines) - k if k is not None else int(len(lines) * keep)
    path.write_bytes(b"".join(lines[:n]))
    return len(lines), n


def test_sti_cut_by_34_lines_is_refused(tmp_path):
    """The reported case: 34 of 6,984 lines lost read as a model with 5 rigid-body modes."""
    sti = _job(tmp_path)
    total, kept = _cut_lines(sti, 34)
    assert (total, kept) == (6984, 6950)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(sti)
    assert exc.value.path == str(sti)
    assert "6950 matrix entries, but job.mas has 6984" in str(exc.value)
    assert "cut off" in str(exc.value)


def test_cut_sti_is_refused_by_the_command_line(tmp_path, capsys):
    sti = _job(tmp_path)
    _cut_lines(sti, 34)
    code, _, err = run(capsys, "info", str(sti))
    assert code == 2
    assert err.strip().splitlines()[-1].startswith(f"flexmor: error: {sti}: 6950 matrix entries")
    assert "Traceback" not in err


def test_mas_cut_by_two_percent_is_refused(tmp_path):
    sti = _job(tmp_path)
    _, kept = _cut_lines(tmp_path / "job.mas", keep=0.98)
    with pytest.raises(ReadError, match=f"job.mas: {kept} matrix entries, but job.sti has 6984"):
        flexmor.io.read(sti)


def test_entries_at_other_positions_are_refused(tmp_path):
    """Same count, one entry moved: the two files no longer share one pattern."""
    sti = _job(tmp_path)
    mas = tmp_path / "job.mas"
    lines = mas.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.split()[0] != ln.split()[1])  # an off-diagonal entry
    r, c, v = lines[k].split()
    moved = next(j for j in range(int(c) + 1, 298) if f"{r} {j} " not in mas.read_text())
    lines[k] = f"{r} {moved} {v}\n"
    mas.write_text("".join(lines))
    with pytest.raises(ReadError, match=r"row \d+ are not at the positions of those of job\.mas"):
        flexmor.io.read(sti)


def test_dof_longer_than_the_matrices_is_refused(tmp_path):
    """A .dof with an equation more than the matrices: its diagonal entry is missing."""
    sti = _job(tmp_path)
    dof = tmp_path / "job.dof"
    node = int(dof.read_text().split()[-1].split(".")[0])
    with dof.open("a") as f:
        f.write(f"{node}.4\n")
    with pytest.raises(ReadError, match=r"job\.sti: no diagonal entry for equation 298 \(node \d+, direction 4 "
                                        r"in job\.dof\); CalculiX writes every diagonal entry"):
        flexmor.io.read(sti)


def test_dof_out_of_node_order_is_warned(tmp_path):
    sti = _job(tmp_path)
    dof = tmp_path / "job.dof"
    lines = dof.read_text().splitlines(keepends=True)
    lines[10], lines[200] = lines[200], lines[10]
    dof.write_text("".join(lines))
    with pytest.warns(FlexmorWarning, match=r"job\.dof:12: equation .* follows .* node order.*could not be checked"):
        flexmor.io.read(sti)


def test_intact_calculix_job_is_quiet(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexmorWarning)
        model = flexmor.io.read(_job(tmp_path))
    assert model.n_dof == 297


def _abaqus(tmp_path):
    for f in ("blockC3D8.inp", "blockC3D8_STIF1.mtx", "blockC3D8_MASS1.mtx"):
        shutil.copy(ABQ / f, tmp_path / f)
    return tmp_path / "blockC3D8.inp"


def test_abaqus_stiffness_cut_inside_a_pair_is_refused(tmp_path):
    """Both triangles are written, entry and mirror image on adjacent lines: a cut between them shows."""
    inp = _abaqus(tmp_path)
    stif = tmp_path / "blockC3D8_STIF1.mtx"
    lines = stif.read_text().splitlines(keepends=True)
    k = next(i for i in range(len(lines) // 2, len(lines))
             if lines[i].split()[:2] == lines[i + 1].split()[1::-1] and lines[i].split()[0] != lines[i].split()[1])
    stif.write_text("".join(lines[:k + 1]))  # keeps (i, j), loses (j, i)
    with pytest.raises(ReadError, match=r"blockC3D8_STIF1\.mtx: \d+ entries above the diagonal but \d+ below"):
        flexmor.io.read(inp)


def test_abaqus_stiffness_cut_at_a_pair_end_is_refused(tmp_path):
    """Cut after a whole pair: the last equations keep their mass but lose their stiffness diagonal."""
    inp = _abaqus(tmp_path)
    stif = tmp_path / "blockC3D8_STIF1.mtx"
    lines = stif.read_text().splitlines(keepends=True)
    k = int(len(lines) * 0.9)
    while lines[k].split()[0] == lines[k].split()[1] or lines[k - 1].split()[0] != lines[k].split()[1]:
        k += 1  # lines[k] completes a pair (j, i) after (i, j)
    stif.write_text("".join(lines[:k + 1]))
    with pytest.raises(ReadError, match=r"blockC3D8_STIF1\.mtx: (the stiffness matrix has no diagonal entry|no "
                                        r"entry for node).*cut off or lines are missing"):
        flexmor.io.read(inp)


def test_abaqus_mass_cut_at_a_line_end_is_warned(tmp_path):
    """A lumped mass file cut at a line end cannot be told from massless directions: a warning says so."""
    inp = _abaqus(tmp_path)
    mass = tmp_path / "blockC3D8_MASS1.mtx"
    total, kept = _cut_lines(mass, 9)
    with pytest.warns(FlexmorWarning, match=r"blockC3D8_MASS1\.mtx: the last 9 equations .* no mass entry: the "
                                            r"file may be cut off"):
        try:
            flexmor.io.read(inp)
        except ReadError as exc:  # the zero mass diagonal of a C3D8 deck is refused after the warning
            assert "mass matrix diagonal is not positive at 9 equation" in str(exc)


def test_missing_diagonal_entry_is_refused(tmp_path):
    """Matrix Market: one diagonal line lost (the header count adjusted): the row keeps its neighbours."""
    lines = (DATA / "bad" / "mm_nan_K.mtx").read_text().replace("2 2 NaN", "2 2 2.0").splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("2 2 "))
    del lines[k]
    nr, nc, nnz = lines[1].split()
    lines[1] = f"{nr} {nc} {int(nnz) - 1}\n"
    (tmp_path / "job_K.mtx").write_text("".join(lines))
    shutil.copy(DATA / "bad" / "mm_nan_M.mtx", tmp_path / "job_M.mtx")
    with pytest.raises(ReadError, match=r"job_K\.mtx: the stiffness matrix has no diagonal entry at equation 2"):
        flexmor.io.read(tmp_path / "job_K.mtx")


def test_matrix_market_header_count_is_checked(tmp_path):
    text = (DATA / "bad" / "mm_nan_K.mtx").read_text().replace("2 2 NaN", "2 2 2.0")
    (tmp_path / "job_K.mtx").write_text(text.replace("3 3 5", "3 3 6"))
    shutil.copy(DATA / "bad" / "mm_nan_M.mtx", tmp_path / "job_M.mtx")
    with pytest.raises(ReadError, match=r"job_K\.mtx: header announces 6 entries but the file holds 5"):
        flexmor.io.read(tmp_path / "job_K.mtx")


def test_fast_parser_reads_a_three_digit_exponent():
    """A value beyond 1e76 in a fixed layout (a digit appended to its exponent) is parsed, not a NumPy error."""
    rows, cols, vals = fast_triplets(np.frombuffer(b"1 1  1.1217948717949e+081\n", dtype=np.uint8))
    assert vals.tolist() == [1.1217948717949e81]


@pytest.mark.parametrize("offset, byte", [(433645, 164), (287722, 222), (383695, 213)])
def test_ansys_full_damaged_byte_is_refused_not_a_crash(tmp_path, offset, byte):
    """One byte changed deep in a matrix record made the compiled .full reader crash the process
    (SIGSEGV) or return indices outside the matrix; the read runs in a child process of its own.

    What the compiled reader makes of such a file depends on the memory it reads out of bounds: of 20
    reads of the first case, 17 died by SIGSEGV in the child (refused), 2 returned an unsymmetric K
    (refused), 1 returned a symmetric matrix (read). The outcome is never the death of flexmor's
    process, and a refusal names the file."""
    pytest.importorskip("ansys.mapdl.reader")
    raw = bytearray((DATA / "ansys" / "ansys_file.full").read_bytes())
    raw[offset] = byte
    path = tmp_path / "job.full"
    path.write_bytes(bytes(raw))
    code = ("import sys, flexmor.io\nfrom flexmor.errors import ReadError\ntry:\n    flexmor.io.read(sys.argv[1])\n"
            "except ReadError as exc:\n    print(exc)\n    sys.exit(2)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert proc.returncode in (0, 2), (proc.returncode, proc.stderr[-500:])  # no signal death, no traceback
    assert proc.returncode == 0 or proc.stdout.startswith(f"{path}: ")  # the reader's error, or a check


# -- files whose format cannot show every damage: checks where one is possible, else a named warning --

fuzz = load_script(ROOT / "bench" / "fuzz.py", "fuzz_for_damaged_files")


@pytest.fixture(scope="module")
def beam(tmp_path_factory):
    """The clamped beam's K and M as a DMIG punch file with its GRIDs and as ASCII / binary OP4 (60 x 60)."""
    folder = tmp_path_factory.mktemp("beam")
    fuzz._generate(folder)
    return folder


def _pch(beam, tmp_path, change=None):
    for f in ("beam.pch", "beam.bdf"):
        shutil.copy(beam / f, tmp_path / f)
    pch = tmp_path / "beam.pch"
    if change:
        lines = pch.read_text().splitlines(keepends=True)
        change(lines)
        pch.write_text("".join(lines))
    return pch


def _column_card(lines, name, grid, comp):
    return next(i for i, ln in enumerate(lines) if ln.startswith(f"DMIG*   {name:<16}{grid:>16}{comp:>16}"))


def _unchecked(record):
    return [str(w.message) for w in record if issubclass(w.category, UncheckedWarning)]


def test_dmig_lost_column_card_is_refused(beam, tmp_path):
    """Its entries would be read into the column before it: the row of its diagonal has no column card."""
    pch = _pch(beam, tmp_path, lambda lines: lines.pop(_column_card(lines, "KAAX", 50, 2)))
    with pytest.raises(ReadError, match=r"DMIG KAAX \(form 6, square\): row 50-2 \(line \d+\) has no column card "
                                        r"'DMIG KAAX 50 2': a column card lost"):
        flexmor.io.read(pch)


def test_dmig_entry_without_its_grid_is_refused(beam, tmp_path):
    """A blanked grid field: the card reader used to skip the entry."""
    def blank(lines):
        k = _column_card(lines, "MAAX", 40, 1) + 1
        lines[k] = "*" + " " * 23 + lines[k][24:]
    pch = _pch(beam, tmp_path, blank)
    with pytest.raises(ReadError, match=r"beam\.pch:\d+: DMIG MAAX: an entry of column 40-1 has no grid \(row\) "):
        flexmor.io.read(pch)


def test_dmig_entry_repeated_into_another_column_is_named(beam, tmp_path):
    """A copy of an entry of column 2-1 after the last entry of column 60-3 (an upper-triangle position the
    matrix does not have, no duplicate): out of the row order Nastran writes, so named."""
    def repeat(lines):
        entry = lines[_column_card(lines, "KAAX", 2, 1) + 1]
        k = _column_card(lines, "KAAX", 60, 3) + 1
        while lines[k].startswith("* "):  # after the column's last entry
            k += 1
        lines.insert(k, entry)
    pch = _pch(beam, tmp_path, repeat)
    with pytest.warns(FlexmorWarning, match=r"beam\.pch: line \d+: DMIG KAAX: entry 2-1 of column 60-3 follows row "
                                            r"60-3, out of the row order of the other entries \(1 such\)"):
        flexmor.io.read(pch)


def test_dmig_read_says_once_what_it_could_not_check(beam, tmp_path):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        flexmor.io.read(_pch(beam, tmp_path))
    assert _unchecked(record) == ["beam.pch: DMIG cards have no entry counts; a lost entry line, or one repeated "
                                  "into another column in row order, could not be cross-checked"]
    assert not [w for w in record if w.category is FlexmorWarning]


def test_dmig_stored_in_both_triangles_needs_no_warning(tmp_path):
    """Each off-diagonal entry of K twice: a lost line leaves K unsymmetric, which the model refuses."""
    K = np.array([[4.0, -1, 0], [-1, 4, -1], [0, -1, 4]])
    lines = ["GRID,1,,0.,0.,0.", "DMIG,KAAX,0,6,2", "DMIG,MAAX,0,6,2"]
    for j in range(3):
        lines += [f"DMIG,KAAX,1,{j + 1},,1,{i + 1},{float(K[i, j])!r}" for i in range(3) if K[i, j]]
        lines.append(f"DMIG,MAAX,1,{j + 1},,1,{j + 1},1.0")
    pch = tmp_path / "k.pch"
    pch.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = flexmor.io.read(pch)
    assert np.array_equal(model.K.toarray(), K)
    assert not _unchecked(record)  # a lost line of the diagonal M leaves a zero diagonal, which is refused
    pch.write_text(pch.read_text().replace("DMIG,KAAX,1,1,,1,2,-1.0\n", ""))  # K(2,1) lost, K(1,2) kept
    with pytest.raises(ReadError, match="K is not symmetric"):
        flexmor.io.read(pch)


def _op4(tmp_path, mats, **kw):
    sys.path.insert(0, str(ROOT / "tests"))
    from op4_writer import write_ascii
    path = tmp_path / "m.op4"
    write_ascii(path, mats, **kw)
    return path


def test_op4_symmetric_matrix_stored_in_full_with_a_changed_value_is_refused(tmp_path):
    """Nastran writes a symmetric matrix (form 6) in full: a value changed in one triangle shows."""
    K = flexmor.io.read(CCX / "beam8_clamped_mat.sti").K.toarray()[:60, :60]
    i, j = 3, int(np.flatnonzero(K[3, 4:])[-1]) + 4
    K[i, j] *= 1.5  # one triangle only
    with pytest.raises(ReadError, match=rf"m\.op4: matrix KAAX is symmetric \(form 6\) and stored in full, but its "
                                        rf"entries \({j + 1}, 4\) = .* and \(4, {j + 1}\) = .* differ"):
        read_op4(_op4(tmp_path, {"KAAX": K}, sparse=True, form=6))
    K[j, i] = K[i, j]
    assert np.array_equal(read_op4(_op4(tmp_path, {"KAAX": K}, sparse=True, form=6))["KAAX"], K)


def test_op4_column_record_out_of_order_is_refused(tmp_path):
    """A changed column number that moves a record before its predecessor (no rows overlap): the line
    scanner used to read it into the other column."""
    path = _op4(tmp_path, {"KAAX": np.diag([1.0, 2.0, 3.0, 4.0])})
    lines = path.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.split() == ["3", "3", "1"])
    lines[k] = f"{1:8d}{3:8d}{1:8d}\n"
    path.write_text("".join(lines))
    with pytest.raises(ReadError, match=r"m\.op4:\d+: matrix KAAX: column 1 rows 3\.\.3 follow column 2 row 2; "
                                        r"OUTPUT4 stores columns and rows in order"):
        read_op4(path)


def test_op4_read_says_once_what_it_could_not_check(tmp_path):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        read_op4(_op4(tmp_path, {"KAAX": np.diag([1.0, 2.0]), "MAAX": np.eye(2)}))
    assert _unchecked(record) == ["m.op4: OUTPUT4 has no checksum and no count of its matrices; values (and a "
                                  "matrix lost from the end of the file) could not be cross-checked"]



def test_files_without_node_coordinates_say_what_they_could_not_check(tmp_path):
    """A Matrix Market pair names both of its files; a MAT-file names what its format has no count of."""
    import scipy.io

    model = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
    scipy.io.mmwrite(tmp_path / "beam_K.mtx", model.K, symmetry="symmetric")
    scipy.io.mmwrite(tmp_path / "beam_M.mtx", model.M, symmetry="symmetric")
    for path, expect in ((DATA / "mor" / "LF10.mat", "LF10.mat: a MAT-file holds no count of its variables"),
                         (tmp_path / "beam_K.mtx", "beam_K.mtx, beam_M.mtx: Matrix Market files hold each "
                                                   "entry once and no node coordinates")):
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            flexmor.io.read(path)
        said = _unchecked(record)
        assert len(said) == 1 and said[0].startswith(expect), said

def test_op4_warning_shown_once_by_the_command_line(beam, tmp_path, capsys):
    shutil.copy(beam / "beam.op4", tmp_path / "beam.op4")
    code, _, err = run(capsys, "info", str(tmp_path / "beam.op4"))
    assert code == 0, err
    assert err.count("flexmor: warning: beam.op4: OUTPUT4 has no checksum") == 1, err


def _rotor(tmp_path):
    for f in ("MassMatrixSparse", "StiffnessMatrixSparse", "MatrixDofMappingVector", "NodalCoordinates"):
        shutil.copy(DATA / "ansys" / f"rotorAnsys{f}.txt", tmp_path / f"rotorAnsys{f}.txt")
    return tmp_path / "rotorAnsysStiffnessMatrixSparse.txt"


def test_ansys_mapping_vector_read_says_what_it_could_not_check(tmp_path):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        flexmor.io.read(_rotor(tmp_path), format="ansys")
    assert _unchecked(record) == ["rotorAnsysMatrixDofMappingVector.txt: an Ansys mapping vector has no equation "
                                  "numbers; the order of its lines (which node owns which equations) could not be "
                                  "cross-checked"]


def test_matrix_market_entry_with_a_changed_index_is_named(tmp_path):
    """Ansys writes the entries column by column, rows ascending: a changed row index is out of that order."""
    stiff = _rotor(tmp_path)
    lines = stiff.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.split()[:2] == ["12", "1"])
    lines[k] = lines[k].replace("12 1 ", "300 1 ", 1)
    stiff.write_text("".join(lines))
    with pytest.warns(FlexmorWarning, match=rf"rotorAnsysStiffnessMatrixSparse\.txt:{k + 1}: entry \(300, 1\) is "
                                            r"out of the order of the other entries \(1 such\): an index changed"):
        flexmor.io.read(stiff, format="ansys")


def test_matrix_market_header_repeated_among_the_entries_is_refused(tmp_path):
    """A repeated banner reads as a comment, and the size line after it as an entry (3, 3) = 3."""
    (tmp_path / "job_M.mtx").write_text("%%MatrixMarket matrix coordinate real symmetric\n3 3 3\n1 1 1.0\n"
                                        "%%MatrixMarket matrix coordinate real symmetric\n3 3 3\n2 2 1.0\n")
    shutil.copy(DATA / "bad" / "mm_nan_K.mtx", tmp_path / "job_K.mtx")
    with pytest.raises(ReadError, match=r"job_M\.mtx:4: a second %%MatrixMarket header line"):
        flexmor.io.read(tmp_path / "job_M.mtx")


@pytest.mark.parametrize("cut", ["*STEP", "elements"])
def test_calculix_deck_cut_after_its_elements_is_named(tmp_path, cut):
    """The matrices are complete, the deck lost its step (and elements, sets, materials): read, with a warning."""
    sti = _job(tmp_path)
    inp = tmp_path / "job.inp"
    lines = inp.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.upper().startswith("*STEP" if cut == "*STEP" else "*ELEMENT"))
    inp.write_text("".join(lines[:k if cut == "*STEP" else k + 5]))
    with pytest.warns(FlexmorWarning, match=r"job\.inp: no \*STEP, which the job that wrote job\.sti had: the deck "
                                            r"seems cut off inside or after its element blocks"):
        model = flexmor.io.read(sti)
    assert model.n_dof == 297


def test_control_character_in_a_line_of_numbers_is_refused(tmp_path):
    """U+001C where a digit was: Python's split() takes it for a blank, so '3.2e+01' was read as '.2e+01'."""
    inp = _abaqus(tmp_path)
    mass = tmp_path / "blockC3D8_MASS1.mtx"
    lines = mass.read_bytes().splitlines(keepends=True)
    k = len(lines) // 2
    i = lines[k].rindex(b" ") + 1
    lines[k] = lines[k][:i] + b"\x1c" + lines[k][i + 1:]
    mass.write_bytes(b"".join(lines))
    with pytest.raises(ReadError, match=rf"blockC3D8_MASS1\.mtx:{k + 1}: character '\\x1c' in .* which a line of "
                                        r"numbers does not hold"):
        flexmor.io.read(inp)


def test_no_break_space_in_a_node_line_is_refused(tmp_path):
    """'0.05' with its last digit turned into U+00A0 read as 0.0 (float() strips it)."""
    sti = _job(tmp_path)
    inp = tmp_path / "job.inp"
    text = inp.read_text()
    k = text.index("\n2, ") + 1
    line = text[k:text.index("\n", k)]
    inp.write_text(text[:k] + line[:-1] + "\xa0" + text[k + len(line):])
    with pytest.raises(ReadError, match=r"job\.inp:\d+: character '\\xa0' in the \*NODE line"):
        flexmor.io.read(sti)


@pytest.mark.parametrize("change, expect", [
    (lambda t: t.replace("GRID,51,,0.6,0.05,0.05\n", "GRID,51,,0.6,0.05,0.\n5\n"),
     r"beam\.bdf:\d+: '5' does not start with a card name"),  # a byte turned into a line end
    (lambda t: t.replace("GRID,76,,0.9,0.0,0.1\n", "GRID,76,,0.9,1,5,,0.1\n"),
     r"beam\.bdf:\d+: GRID 76: PS and SEID must be integers"),  # a token replaced by '1,5,'
])
def test_damaged_grid_card_is_refused(beam, tmp_path, change, expect):
    pch = _pch(beam, tmp_path)
    bdf = tmp_path / "beam.bdf"
    text = bdf.read_text()
    assert change(text) != text
    bdf.write_text(change(text))
    with pytest.raises(ReadError, match=expect):
        flexmor.io.read(pch)


def test_dmig_rectangular_form_checks_its_declared_columns(tmp_path):
    """Form 9 declares NCOL: a lost column card shows in the count."""
    lines = ["GRID,1,,0.,0.,0.", "DMIG,KAAX,0,9,2,,,,3", "DMIG,MAAX,0,6,2"]
    for j in range(3):
        lines += [f"DMIG,KAAX,1,{j + 1},,1,{j + 1},{2.0 + j}", f"DMIG,MAAX,1,{j + 1},,1,{j + 1},1.0"]
    pch = tmp_path / "k.pch"
    pch.write_text("\n".join(lines) + "\n")
    assert flexmor.io.read(pch).K.diagonal().tolist() == [2.0, 3.0, 4.0]
    pch.write_text(pch.read_text().replace("DMIG,KAAX,1,3,,1,3,4.0\n", ""))
    with pytest.raises(ReadError, match=r"k\.pch: DMIG KAAX: its header declares NCOL=3 columns, but the file has 2 "
                                        "column cards of it"):
        flexmor.io.read(pch)


# --- the stiffness and the node coordinates cross-check each other (K times a rigid rotation is zero) ---

def _geometry_warnings(path, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = flexmor.io.read(path, **kw)
    return model, [str(w.message) for w in caught if "node coordinates disagree" in str(w.message)]


@pytest.mark.parametrize("path", [CCX / "beam8_clamped_mat.sti", CCX / "beam8_free_mat.sti",
                                  ABQ / "blockC3D8.inp", ABQ / "blockC3D10.inp",
                                  DATA / "ansys" / "rotorAnsysMassMatrixSparse.txt"])
def test_sound_exports_follow_a_rigid_rotation(path):
    from flexmor.io._geometry import geometry_residual
    model, named = _geometry_warnings(path)
    assert named == []
    translation, rotation, _ = geometry_residual(model)
    complete = translation < 1e-9
    assert complete.sum() > 0.8 * model.n_dof
    assert np.nanmax(rotation[complete]) < 1e-12  # the rounding of 14+ written digits


@pytest.mark.parametrize("old, new", [(b"\n4, 0.3, 0, 0\n", b"\n4, 0.3, 0, 0.001\n"),     # 1 mm of a 0.1 m section
                                      (b"\n4, 0.3, 0, 0\n", b"\n4, 0.300000001, 0, 0\n"),  # the 9th digit
                                      (b"\n4, 0.3, 0, 0\n", b"\n4, 0, 0, 0\n")])          # a field emptied (0)
def test_a_changed_node_coordinate_is_named(tmp_path, old, new):
    """A coordinate has no second copy in the deck; the stiffness matrix is its counterpart."""
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    inp = tmp_path / "job.inp"
    assert inp.read_bytes().count(old) == 1
    inp.write_bytes(inp.read_bytes().replace(old, new))
    _, named = _geometry_warnings(sti)
    assert len(named) == 1 and "disagree at node 4" in named[0], named


def test_coordinates_in_other_units_per_axis_are_named(tmp_path):
    """The node table of another mesh: y written in mm while x and z are in m."""
    model = flexmor.io.read(CCX / "beam8_free_mat.sti")
    from flexmor.io._geometry import check_stiffness_geometry
    model.xyz = model.xyz * np.array([1.0, 1000.0, 1.0])
    with pytest.warns(FlexmorWarning, match="node coordinates disagree"):
        nodes = check_stiffness_geometry(model)
    assert len(nodes) > 0.5 * model.n_nodes


def test_supports_springs_to_ground_and_local_frames_are_not_named():
    """Equations beside removed DOF or a spring to ground do not sum to zero: not checked."""
    import scipy.sparse as sp

    from flexmor.io._geometry import check_stiffness_geometry
    model = flexmor.io.read(CCX / "beam8_free_mat.sti")
    grounded = sp.csr_matrix(model.K + sp.diags(np.where(np.arange(model.n_dof) % 7 == 0, 1e9, 0.0)))
    model.K = grounded
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_stiffness_geometry(model) == []
        clamped = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
        assert check_stiffness_geometry(clamped) == []
        frames = flexmor.io.read(CCX / "beam8_free_mat.sti")
        moved = int(frames.node_ids[40])
        frames.xyz[40] += 0.01
        frames.node_frames = {moved: np.eye(3)}  # its DOF in a local frame: neither it nor its neighbours checked
        assert check_stiffness_geometry(frames) == []
    frames.node_frames = {}
    with pytest.warns(FlexmorWarning, match=f"disagree at node {moved} and"):
        check_stiffness_geometry(frames)



@pytest.mark.parametrize("src, old, new, written", [
    ("beam8_clamped_mat", b"\n236 268 -8.4134615384615e+08\n", b"\n236 268 -8.4134605384615e+08\n", "-841346153.8"),
    ("beam8_free_mat", b"\n120 214  8.4134615384615e+08\n", b"\n120 214  8.4134615384615e+07\n", "841346153.8"),
])
def test_a_changed_stiffness_value_is_named_with_the_value_written(tmp_path, src, old, new, written):
    """A value stored once changes the translation sums of its two equations by the same amount, each in the
    direction of the other: the entry is named with the value the file held."""
    sti = _job(tmp_path, CCX / src)
    assert sti.read_bytes().count(old) == 1
    sti.write_bytes(sti.read_bytes().replace(old, new))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flexmor.io.read(sti)
    named = [str(w.message) for w in caught if "stiffness entry" in str(w.message)]
    i, j = (int(k) for k in old.split()[:2])
    assert len(named) == 1 and f"stiffness entry ({i}, {j}) = " in named[0], named
    assert f"(written as {written}?)" in named[0]


def test_info_names_a_changed_stiffness_entry_on_its_checks_line(tmp_path, capsys):
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    sti.write_bytes(sti.read_bytes().replace(b"\n236 268 -8.4134615384615e+08\n", b"\n236 268 -8.4134605384615e+08\n"))
    code, out, err = run(capsys, "info", str(sti), "--modes", "0")
    assert code == 0 and "stiffness entry (236, 268)" in err
    line = next(ln for ln in out.splitlines() if ln.startswith("checks"))
    assert "K entry (236, 268) changed? (see the warning); K vs node coordinates: a rigid rotation at" in line

def test_springs_to_ground_alike_at_many_nodes_are_not_a_changed_value():
    """Equal springs to ground along a row of nodes: every grounded equation alone at its node, but many by
    the same amount, so none pairs up."""
    import scipy.sparse as sp

    from flexmor.io._geometry import geometry_check
    model = flexmor.io.read(CCX / "beam8_free_mat.sti")
    z = np.flatnonzero(model.dofs[:, 1] == 3)[:12]
    model.K = sp.csr_matrix(model.K + sp.diags(np.isin(np.arange(model.n_dof), z) * 1e8))
    assert geometry_check(model)["changed"] == []


def test_a_changed_mass_value_is_named_against_the_other_directions(tmp_path):
    """A solid's mass holds every value for x, y and z: a digit changed in one of them, and an explicit zero
    between two directions turned into a number, are named."""
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    mas = sti.with_suffix(".mas")
    text = mas.read_bytes()
    mas.write_bytes(text.replace(b"\n56 59  7.2685185185185e-02\n", b"\n56 59  7.2685195185185e-02\n"))
    with pytest.warns(FlexmorWarning, match=r"same value for x, y and z of each pair of nodes except at entry "
                                            r"\(56, 59\) = 0.0726852 .*the other directions hold 0.0726852"):
        flexmor.io.read(sti)
    mas.write_bytes(text.replace(b"\n236 268  0.0000000000000e+00\n", b"\n236 268  0.0005000000000e+00\n"))
    with pytest.warns(FlexmorWarning, match=r"couples no two directions of motion except at entry \(236, 268\)"):
        flexmor.io.read(sti)


def test_a_mass_that_differs_by_direction_is_compared_only_where_alike():
    from flexmor.io._mass import direction_mismatches
    model = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
    assert direction_mismatches(model.M, model.dofs) == []
    M = model.M.tolil()
    i = int(np.flatnonzero((model.dofs[:, 0] == 50) & (model.dofs[:, 1] == 1))[0])
    M[i, i] = M[i, i] + 2.0  # a point mass of node 50 in x only (an anisotropic point mass)
    assert [f[:2] for f in direction_mismatches(M.tocsr(), model.dofs)] == [(i, i)]
    z = model.dofs[:, 1] == 3
    scaled = model.M.multiply(np.where(z, 2.0, 1.0)[:, None]).tocsr()  # every z value differs: not isotropic
    assert direction_mismatches(scaled, model.dofs) is None

# --- every 2 x 2 principal minor of K and M is non-negative: |A_ij| <= sqrt(A_ii A_jj) ---

@pytest.mark.parametrize("suffix, old, new, what", [
    (".sti", b"\n26 146 -3.9262820512820e+09\n", b"\n26 146 -359262820512820e+09\n", "stiffness"),  # a mantissa byte
    (".sti", b"\n26 146 -3.9262820512820e+09\n", b"\n26 146 -3.9262820512820e+19\n", "stiffness"),  # the exponent
    (".mas", b"\n7 99  0.0000000000000e+00\n", b"\n7 99  060000000000000e+00\n", "mass"),           # an explicit zero
])
def test_an_entry_beyond_its_diagonals_is_refused(tmp_path, suffix, old, new, what):
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    f = sti.with_suffix(suffix)
    assert f.read_bytes().count(old) == 1
    f.write_bytes(f.read_bytes().replace(old, new))
    with pytest.raises(ReadError, match=rf"the {what} matrix of this model: entry \(\d+, \d+\) = .* exceeds sqrt"):
        flexmor.io.read(sti)


def test_an_indefinite_mass_of_quadratic_elements_is_a_warning(tmp_path):
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    inp, mas = sti.with_suffix(".inp"), sti.with_suffix(".mas")
    inp.write_text(inp.read_text().replace("TYPE=C3D8", "TYPE=C3D20R"))
    mas.write_bytes(mas.read_bytes().replace(b"\n7 99  0.0000000000000e+00\n", b"\n7 99  1.0e+00\n"))
    with pytest.warns(FlexmorWarning, match=r"the mass matrix of this model: entry \(7, 99\) = 1 exceeds"):
        flexmor.io.read(sti)


def test_a_penalty_coupling_on_the_bound_is_read():
    """[[k, -k], [-k, k]] is positive semidefinite: its off-diagonal entry sits exactly on the bound."""
    import scipy.sparse as sp

    from flexmor.io._minors import check_minors
    model = flexmor.io.read(CCX / "beam8_free_mat.sti")
    k = 1e12
    P = sp.csr_matrix(([k, -k, -k, k], ([0, 0, 3, 3], [0, 3, 0, 3])), shape=model.K.shape)
    model.K = sp.csr_matrix(model.K + P)
    check_minors(model)


def test_sid_coefficient_given_twice(tmp_path):
    """The same line twice is read; two values for one coefficient are refused with both lines."""
    src = (DATA / "sid" / "Beam_3m.SID_FEM").read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(src) if ln.strip().startswith("m0( 1, 1)"))
    same = tmp_path / "same.SID_FEM"
    same.write_text("".join(src[:k + 1] + [src[k]] + src[k + 1:]))
    flexmor.io.read(same)
    other = tmp_path / "other.SID_FEM"
    other.write_text("".join(src[:k + 1] + [src[k].split("=")[0] + "= 1.50000000000D+00\n"] + src[k + 1:]))
    with pytest.raises(ReadError, match=r"m0\(1,1\) given twice with different values \(lines \d+ and \d+\)"):
        flexmor.io.read(other)


def test_info_says_what_the_stiffness_coordinate_check_compared(tmp_path, capsys):
    code, out, _ = run(capsys, "info", str(CCX / "beam8_clamped_mat.sti"), "--modes", "0")
    assert code == 0
    line = next(ln for ln in out.splitlines() if ln.startswith("checks"))
    assert "a rigid rotation at 81 of 90 nodes (the others beside supports or springs): median" in line
    assert "(rounding)" in line
    code, out, _ = run(capsys, "info", str(CCX / "beam8_free_mat.sti"), "--modes", "0", "--json")
    import json
    c = json.loads(out)["geometry_check"]
    assert (c["checked"], c["nodes"], c["named"], c["skipped"]) == (99, 99, [], "") and c["level"] < 1e-14


# --- hexahedra and tetrahedra turned inside out by the node coordinates ---

@pytest.mark.parametrize("path", [CCX / "beam8_clamped_mat.sti", ABQ / "blockC3D8.inp", ABQ / "blockC3D10.inp"])
def test_sound_meshes_have_no_inverted_cells(path):
    from flexmor.io._geometry import inverted_cells
    model = flexmor.io.read(path)
    assert model.mesh is not None and model.mesh.n_cells > 0
    assert len(inverted_cells(model)[1]) == 0


def test_a_moved_node_without_equations_that_inverts_a_cell_is_named(tmp_path):
    """Node 1 lies on the clamped face (no row or column in K): the stiffness cannot check it, its cell can."""
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    inp = tmp_path / "job.inp"
    inp.write_bytes(inp.read_bytes().replace(b"\n1, 0, 0, 0\n", b"\n1, 0, 1000, 0\n"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flexmor.io.read(sti)
    said = [str(w.message) for w in caught if "turned inside out" in str(w.message)]
    assert len(said) == 1 and "1 element(s) turned inside out" in said[0] and "corner nodes 1, 2," in said[0], said
    assert not [w for w in caught if "node coordinates disagree" in str(w.message)]  # node 1 has no equations



@pytest.mark.parametrize("new, named", [(b"\n1, -1, 0, 0\n", True),       # ten element lengths out: nearly flat
                                        (b"\n1, -0.01, 0, 0\n", False),   # a tenth of an element length: a sound cell
                                        (b"\n1, 0, 0.05, 0\n", False)])   # onto node 12: a collapsed corner
def test_a_moved_node_without_equations_that_flattens_a_cell_is_named(tmp_path, new, named):
    """Node 1 (clamped face, no equations) moved without turning its cell inside out: a corner angle below half
    a degree is named; a cell moved a little, or collapsed onto a neighbour (a zero edge), is not."""
    sti = _job(tmp_path, CCX / "beam8_clamped_mat")
    inp = tmp_path / "job.inp"
    inp.write_bytes(inp.read_bytes().replace(b"\n1, 0, 0, 0\n", new))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flexmor.io.read(sti)
    said = [str(w.message) for w in caught if "nearly flat" in str(w.message) or "inside out" in str(w.message)]
    if named:
        assert len(said) == 1 and "1 element(s) nearly flat at a corner" in said[0] and "at node 1:" in said[0]
    else:
        assert said == []

def test_a_mesh_in_the_other_orientation_is_not_named():
    """Every cell left-handed (corner order mirrored) is a convention, not a moved node."""
    import dataclasses

    from flexmor.io._geometry import inverted_cells
    from flexmor.mesh import CellBlock, Mesh
    model = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
    block = model.mesh.blocks[0]
    mirrored = Mesh([CellBlock(block.type, block.nodes[:, [0, 3, 2, 1, 4, 7, 6, 5]])])
    assert len(inverted_cells(dataclasses.replace(model, mesh=mirrored))[1]) == 0
    one = block.nodes.copy()
    one[0] = one[0, [0, 3, 2, 1, 4, 7, 6, 5]]
    assert len(inverted_cells(dataclasses.replace(model, mesh=Mesh([CellBlock(block.type, one)])))[1]) == 1


def test_the_masses_of_beam_nodes_are_not_compared_across_directions():
    """A beam's consistent mass differs between its axial and transverse directions: nodes with rotational DOF
    are left out, so a solid with a beam element's node is not named; as a node without rotations it is."""
    import scipy.sparse as sp

    from flexmor.io._mass import direction_mismatches
    solid = flexmor.io.read(CCX / "beam8_clamped_mat.sti")
    node = np.column_stack([np.full(3, 999), [1, 2, 3]])
    rot = np.column_stack([np.full(3, 999), [4, 5, 6]])  # a node with rotations whose x mass differs from y, z
    M = sp.block_diag([solid.M, sp.diags([1.0, 2.0, 2.0, 0.1, 0.1, 0.1])]).tocsr()
    assert direction_mismatches(M, np.vstack([solid.dofs, node, rot])) == []
    M3 = sp.block_diag([solid.M, sp.diags([1.0, 2.0, 2.0])]).tocsr()
    assert [f[0] for f in direction_mismatches(M3, np.vstack([solid.dofs, node]))] == [solid.n_dof]
