"""Exports cut off or missing a file, as a tester made them from the shared samples: the file at fault is named.

An Abaqus deck cut inside a block (or in the middle of a data line) is refused naming the deck and
the line where it ends; matrices with more equations than the deck's nodes carry name the deck as
the likely cut file. A cut CalculiX ``.dof`` is named, not the ``.sti`` whose indices run past it.
An Ansys HBMAT/MMF set without its mapping vector or coordinates is read with a warning naming the
missing file; a missing mass file is named as the export names it.
"""

from __future__ import annotations

import shutil
import warnings

import pytest
from helpers import DATA, run

import flexmor.io
from flexmor.errors import FlexmorWarning, ReadError
from flexmor.io import UncheckedWarning

ABQ = DATA / "abaqus"  # the shared FE exports, as the repository keeps them
CCX = DATA / "calculix"
ANSYS = DATA / "ansys"


def _flexmor_warnings(record):
    """The FlexmorWarnings of ``record`` other than the UncheckedWarnings every read of some formats gives."""
    return [str(w.message) for w in record
            if issubclass(w.category, FlexmorWarning) and not issubclass(w.category, UncheckedWarning)]


def _read_quietly(path, **kw):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = flexmor.io.read(path, **kw)
    assert not _flexmor_warnings(record), _flexmor_warnings(record)
    return model


# -- Abaqus ---------------------------------------------------------------------------------------
def _abaqus(tmp_path, deck: bytes | None = None):
    """The blockC3D8 job in ``tmp_path``, its deck replaced by ``deck``."""
    for f in ("blockC3D8.inp", "blockC3D8_STIF1.mtx", "blockC3D8_MASS1.mtx"):
        shutil.copy(ABQ / f, tmp_path / f)
    inp = tmp_path / "blockC3D8.inp"
    if deck is not None:
        inp.write_bytes(deck)
    return inp


def _head_lines(path, n: int) -> bytes:
    return b"".join(path.read_bytes().splitlines(keepends=True)[:n])


def test_intact_abaqus_job_reads_quietly(tmp_path):
    model = _read_quietly(_abaqus(tmp_path))
    assert model.n_nodes == 176 and model.n_dof == 528 and "SET-1" in model.node_sets


def test_abaqus_deck_cut_inside_its_elements_is_refused(tmp_path, capsys):
    """``head -n 250``: elements lost, *End Instance and the node set SET-1 after them too."""
    inp = _abaqus(tmp_path, _head_lines(ABQ / "blockC3D8.inp", 250))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(inp) and exc.value.line == 250
    assert exc.value.reason.startswith("the deck ends inside *INSTANCE block-1 (line 16), without *END INSTANCE: "
                                       "it seems cut off, and what followed the cut (elements, node and element "
                                       "sets, sections, materials) is missing")
    code, _, err = run(capsys, "info", inp)
    assert code == 2 and "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith(f"flexmor: error: {inp}:250: the deck ends inside *INSTANCE")


def test_abaqus_deck_cut_inside_a_node_line_is_refused(tmp_path, capsys):
    """``head -c 6000``: the last node line lost its z coordinate and its line end; once blamed on the .mtx."""
    raw = (ABQ / "blockC3D8.inp").read_bytes()[:6000]
    line = raw.count(b"\n") + 1
    assert line == 132
    inp = _abaqus(tmp_path, raw)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(inp) and exc.value.line == line
    assert exc.value.reason == ("last line '115,   1.20000005,' has no line end: the deck was cut off inside its "
                                "*NODE data (disk full, interrupted copy?); copy or write it again (a line that is "
                                "complete needs its line end)")
    code, _, err = run(capsys, "info", inp)
    assert code == 2 and "dof_per_node" not in err and "STIF1.mtx" not in err
    assert err.strip().splitlines()[-1].startswith(f"flexmor: error: {inp}:{line}: last line ")


def _node_lines(first: int, last: int) -> bytes:
    """The lines of nodes ``first..last`` of the shared deck (one a line, from line 18 on)."""
    lines = (ABQ / "blockC3D8.inp").read_bytes().splitlines(keepends=True)
    return b"".join(lines[17 + first - 1:17 + last])


def test_abaqus_equations_beyond_the_nodes_name_the_deck(tmp_path, capsys):
    """A flat deck cut at a line end in its node block (no element tells the DOFs per node): the deck is
    named, and no Python keyword is suggested."""
    inp = _abaqus(tmp_path, b"*Node\n" + _node_lines(1, 115))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(inp)
    assert exc.value.reason == ("blockC3D8_STIF1.mtx has 528 equations, each with its diagonal entry, which fit no "
                                "count of 2, 3 or 6 DOFs per node of the 115 nodes of the deck (no element type tells "
                                "the count): the deck seems cut off in its node block, or the files are from "
                                "different jobs")
    code, _, err = run(capsys, "info", inp)
    assert code == 2 and "dof_per_node" not in err and f"flexmor: error: {inp}: blockC3D8_STIF1.mtx has 528" in err


def test_abaqus_equations_beyond_the_nodes_of_elements_name_the_deck(tmp_path):
    inp = _abaqus(tmp_path, b"*Node\n" + _node_lines(1, 115) + b"*Element, type=C3D8\n1, 1, 2, 3, 4, 5, 6, 7, 8\n"
                  b"*Step\n*Matrix Generate, stiffness, mass\n*End Step\n")
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(inp)
    assert exc.value.reason.startswith("its 115 nodes carry 345 equations (3 DOFs per node), but blockC3D8_STIF1.mtx "
                                       "has 528, each with its diagonal entry: the deck seems cut off")


def test_abaqus_damaged_matrix_index_still_names_the_matrix_file(tmp_path):
    """One index beyond the nodes without its diagonal entry is the .mtx's defect, not a cut deck."""
    inp = _abaqus(tmp_path)
    stif = tmp_path / "blockC3D8_STIF1.mtx"
    lines = stif.read_text().splitlines(keepends=True)
    stif.write_text("".join(lines[:50] + ["529 1 1.0\n", "1 529 1.0\n"] + lines[50:]))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(stif) and exc.value.line == 51


def test_abaqus_deck_cut_inside_its_step_is_refused(tmp_path):
    inp = _abaqus(tmp_path, _head_lines(ABQ / "blockC3D8.inp", 306))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(inp)
    assert exc.value.path == str(inp) and exc.value.line == 306
    assert exc.value.reason == ("the deck ends inside *STEP Step-2 (line 303), without *END STEP: it seems cut off; "
                                "copy or write it again")


def test_abaqus_deck_cut_before_its_step_is_warned(tmp_path):
    """Cut at a line end after its blocks: nothing shows but the *STEP every *MATRIX GENERATE job has (a warning,
    as for CalculiX: a mesh deck written for the matrices looks the same)."""
    inp = _abaqus(tmp_path, _head_lines(ABQ / "blockC3D8.inp", 302))
    with pytest.warns(FlexmorWarning, match=r"blockC3D8\.inp:302: the deck ends without \*STEP, which the job that "
                                            r"wrote the matrices had \(\*MATRIX GENERATE\): it seems cut off"):
        model = flexmor.io.read(inp)
    assert model.n_dof == 528 and "SET-1" in model.node_sets


# -- CalculiX -------------------------------------------------------------------------------------
def _calculix(tmp_path):
    for suf in (".sti", ".mas", ".dof", ".inp"):
        shutil.copy(CCX / f"beam8_clamped_mat{suf}", tmp_path / f"beam8_clamped_mat{suf}")
    return tmp_path / "beam8_clamped_mat.sti"


def test_intact_calculix_job_reads_quietly(tmp_path):
    assert _read_quietly(_calculix(tmp_path)).n_dof == 270


def test_calculix_dof_cut_is_named(tmp_path, capsys):
    """125 of 270 lines: the .sti's indices run past the .dof, which is at fault (once the .sti was named)."""
    sti = _calculix(tmp_path)
    dof = tmp_path / "beam8_clamped_mat.dof"
    dof.write_bytes(_head_lines(dof, 125))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(sti)
    assert exc.value.path == str(dof) and exc.value.line is None
    assert exc.value.reason == ("125 equations, but beam8_clamped_mat.sti and beam8_clamped_mat.mas have entries up "
                                "to equation 270 (beam8_clamped_mat.sti:1732: index 126 beyond the matrix size 125): "
                                "the .dof seems cut off (or is from another job); write it again with CalculiX")
    code, _, err = run(capsys, "info", sti)
    assert code == 2 and err.strip().splitlines()[-1].startswith(f"flexmor: error: {dof}: 125 equations")


def test_calculix_damaged_index_still_names_the_sti(tmp_path):
    """An index of the .sti beyond the .dof that the .mas does not share is the .sti's defect."""
    sti = _calculix(tmp_path)
    lines = sti.read_text().splitlines(keepends=True)
    lines[10] = "11 271 1.0\n"
    sti.write_text("".join(lines))
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(sti)
    assert exc.value.path == str(sti) and exc.value.line == 11
    assert "index 271 beyond the matrix size 270" in exc.value.reason


def test_calculix_deck_cut_inside_a_node_line_is_refused(tmp_path):
    """The last node line lost its z coordinate: once read as z = 0 (only the K-vs-coordinates check hinted)."""
    sti = _calculix(tmp_path)
    inp = tmp_path / "beam8_clamped_mat.inp"
    lines = inp.read_bytes().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.upper().startswith(b"*ELEMENT"))
    inp.write_bytes(b"".join(lines[:k - 1]) + lines[k - 1].rsplit(b",", 1)[0])
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(sti)
    assert exc.value.path == str(inp) and exc.value.line == k
    assert "has no line end: the deck was cut off inside its *NODE data" in exc.value.reason


# -- Ansys HBMAT/MMF ----------------------------------------------------------------------------
ROTOR = ("StiffnessMatrixSparse", "MassMatrixSparse", "MatrixDofMappingVector", "NodalCoordinates")


def _rotor(tmp_path, missing=None):
    for f in ROTOR:
        if f != missing:
            shutil.copy(ANSYS / f"rotorAnsys{f}.txt", tmp_path / f"rotorAnsys{f}.txt")
    return tmp_path / "rotorAnsysStiffnessMatrixSparse.txt"


def test_intact_rotor_reads_quietly(tmp_path):
    model = _read_quietly(_rotor(tmp_path))
    assert model.n_nodes == 115 and model.n_dof == 345


@pytest.mark.parametrize("missing, words, lost", [
    ("NodalCoordinates", "coord", "without the nodal coordinates, the model has no node positions (the nodes of "
                                  "the equation map are left out)"),
    ("MatrixDofMappingVector", "mapping", "without the equation map, the equations cannot be tied to nodes, so the "
                                          "model has no nodes (no coordinates, node sets or ports by node)"),
])
def test_rotor_without_a_companion_is_warned(tmp_path, capsys, missing, words, lost):
    stiff = _rotor(tmp_path, missing)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = flexmor.io.read(stiff)
    assert _flexmor_warnings(record) == [
        f"{tmp_path / f'rotorAnsys{missing}.txt'}: not found (nor another rotorAnsys*{words}* file) beside "
        f"rotorAnsysStiffnessMatrixSparse.txt: {lost}"]
    assert model.n_dof == 345 and model.n_nodes == 0
    code, _, err = run(capsys, "info", stiff)
    assert code == 0 and f"flexmor: warning: {tmp_path / f'rotorAnsys{missing}.txt'}: not found" in err


@pytest.mark.parametrize("missing, given, role", [("MassMatrixSparse", "StiffnessMatrixSparse", "stiffness"),
                                                  ("StiffnessMatrixSparse", "MassMatrixSparse", "mass")])
def test_rotor_missing_matrix_is_named_as_the_export_names_it(tmp_path, missing, given, role):
    _rotor(tmp_path, missing)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(tmp_path / f"rotorAnsys{given}.txt")
    other = "mass" if role == "stiffness" else "stiffness"
    assert exc.value.path == str(tmp_path / f"rotorAnsys{missing}.txt")
    assert exc.value.reason == (f"not found (nor rotorAnsys{missing}.txt.gz): rotorAnsys{given}.txt was read as the "
                                f"{role} matrix, and the Ansys export writes the {other} matrix beside it")
