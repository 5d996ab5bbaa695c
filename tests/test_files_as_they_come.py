"""Files as FE programs ship them: gzip-compressed exports, the FE program's own frequencies as a
reference (CalculiX .dat, Nastran .f06, a list), and Nastran superelements recognised as bodies."""

from __future__ import annotations

import gzip
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import CCX, CLAMPED, DATA, FREE, run
from test_io_nastran_se import N_MODES, _files

from flexmor.errors import FlexmorWarning, ReadError
from flexmor.io import BODY_FORMATS, MODEL_FORMATS, kind_of, read, read_body
from flexmor.io.reference import read_reference


def _gzip(path: Path, keep: bool = False) -> Path:
    out = Path(f"{path}.gz")
    with open(path, "rb") as src, gzip.open(out, "wb") as dst:
        shutil.copyfileobj(src, dst)
    if not keep:
        path.unlink()
    return out


def _copy(tmp_path, folder: Path, pattern: str) -> None:
    for p in folder.glob(pattern):
        shutil.copy(p, tmp_path / p.name)


# -- gzip-compressed files ---------------------------------------------------------------------
def test_info_of_a_gzipped_calculix_job_gives_the_plain_files_numbers(tmp_path, capsys):
    """``flexmor info job.sti.gz``: the .mas.gz, .dof.gz and .inp.gz beside it are found and read as they are."""
    _copy(tmp_path, CCX, "beam8_free_mat.*")
    for suf in (".sti", ".mas", ".dof", ".inp"):
        _gzip(tmp_path / f"beam8_free_mat{suf}")
    code, out, err = run(capsys, "info", tmp_path / "beam8_free_mat.sti.gz", "--modes", "10", "--json")
    assert code == 0, err
    gz = json.loads(out)
    code, out, _ = run(capsys, "info", FREE, "--modes", "10", "--json")
    plain = json.loads(out)
    assert gz["n_dof"] == plain["n_dof"] == 297 and gz["n_nodes"] == plain["n_nodes"]
    np.testing.assert_allclose(gz["frequencies_hz"][6:], plain["frequencies_hz"][6:], rtol=1e-12)
    assert gz["name"] == "beam8_free_mat" and gz["node_sets"] == plain["node_sets"]


def test_a_cut_off_gzip_file_is_refused_naming_it(tmp_path, capsys):
    _copy(tmp_path, CCX, "beam8_clamped_mat.*")
    mas = _gzip(tmp_path / "beam8_clamped_mat.mas")
    raw = mas.read_bytes()
    mas.write_bytes(raw[:len(raw) // 2])
    code, _, err = run(capsys, "info", tmp_path / "beam8_clamped_mat.sti")  # the .mas.gz is found beside it
    assert code == 2
    assert "beam8_clamped_mat.mas.gz" in err and "cut off" in err and "Traceback" not in err
    mas.write_bytes(b"not gzip at all\n")
    code, _, err = run(capsys, "info", tmp_path / "beam8_clamped_mat.sti")
    assert code == 2 and "beam8_clamped_mat.mas.gz" in err and "not a valid gzip file" in err


@pytest.mark.parametrize(("folder", "files", "main"), [
    ("abaqus", "blockC3D8*", "blockC3D8_STIF1.mtx"),
    ("abaqus", "blockC3D8*", "blockC3D8.inp"),
    ("ansys", "rotorAnsys*", "rotorAnsysStiffnessMatrixSparse.txt"),
    ("mor", "LF10.mat", "LF10.mat"),
    ("sid", "Beam_3m.SID_FEM", "Beam_3m.SID_FEM"),
])
def test_every_format_reads_its_files_gzipped(tmp_path, folder, files, main):
    _copy(tmp_path, DATA / folder, files)
    plain = read(tmp_path / main)
    for p in list(tmp_path.iterdir()):
        _gzip(p)
    got = read(tmp_path / f"{main}.gz")
    assert got.name == plain.name and got.n_dof == plain.n_dof
    assert abs(got.K - plain.K).max() == 0 and abs(got.M - plain.M).max() == 0
    if plain.dofs is not None:
        np.testing.assert_array_equal(got.dofs, plain.dofs)


def test_matrix_market_pair_gzipped(tmp_path):
    from flexmor.io.matrix_market.matrix_market_export import write_matrix_market  # noqa: F401 - registers

    plain = read(CLAMPED)
    import scipy.io

    scipy.io.mmwrite(tmp_path / "beam_K.mtx", plain.K, symmetry="symmetric")
    scipy.io.mmwrite(tmp_path / "beam_M.mtx", plain.M)
    _gzip(tmp_path / "beam_K.mtx")
    _gzip(tmp_path / "beam_M.mtx")
    got = read(tmp_path / "beam_K.mtx.gz")
    assert abs(got.K - plain.K).max() <= 1e-12 * abs(plain.K).max() and got.name == "beam"
    assert abs(got.M - plain.M).max() <= 1e-12 * abs(plain.M).max()


@pytest.mark.parametrize("fmt", ["binary", "ascii", "dmig"])
def test_nastran_superelement_gzipped_with_its_bulk_data(tmp_path, clamped, fmt):
    _files(tmp_path, clamped, fmt)
    name = "se.pch" if fmt == "dmig" else "se.op4"
    plain = read_body(tmp_path / name)
    _gzip(tmp_path / name)
    _gzip(tmp_path / "se.bdf")
    got = read_body(tmp_path / f"{name}.gz")
    np.testing.assert_allclose(got.K, plain.K, rtol=0, atol=0)
    assert got.model_name == "se" and got.input_names == plain.input_names
    assert kind_of(tmp_path / f"{name}.gz") == "body"


def test_nastran_dmig_and_op4_matrices_gzipped(tmp_path):
    from flexmor.io.nastran import read_dmig, read_op4

    _copy(tmp_path, DATA / "nastran", "pyyeti_*.*")
    plain = read_dmig(tmp_path / "pyyeti_matrix_factory.pch")
    got = read_dmig(_gzip(tmp_path / "pyyeti_matrix_factory.pch"))
    assert sorted(got) == sorted(plain)
    for name, entries in plain.items():
        for a, b in zip(got[name], entries):
            np.testing.assert_array_equal(a, b)
    plain = read_op4(tmp_path / "pyyeti_rd_ascii.op4")
    got = read_op4(_gzip(tmp_path / "pyyeti_rd_ascii.op4"))
    assert sorted(got) == sorted(plain) and all(np.array_equal(got[k], plain[k]) for k in plain)


def test_format_lookup_sees_through_gz():
    assert MODEL_FORMATS.by_path("job.sti.gz").name == "calculix"
    assert MODEL_FORMATS.by_path("JOB_STIF1.MTX.GZ").name == "abaqus"  # claimed by name, through .gz
    assert MODEL_FORMATS.by_path("rotor_K.mtx.gz").name == "matrix-market"
    assert BODY_FORMATS.by_path("se.op4.gz").name == "nastran-se"
    assert MODEL_FORMATS.by_path("archive.gz") is None


def test_a_gzipped_file_a_reader_cannot_stream_is_refused_with_the_reason(tmp_path, body):
    from flexmor.io import write_body

    red, _ = body
    write_body(red, tmp_path / "b.h5")
    with pytest.raises(ReadError, match=r"b\.h5\.gz: gzip-compressed: h5py reads an HDF5 file by random access.*"
                                        r"gunzip b\.h5\.gz"):
        read_body(_gzip(tmp_path / "b.h5"))
    (tmp_path / "x.full.gz").write_bytes(gzip.compress(b"\0" * 512))
    with pytest.raises(ReadError, match="ansys-mapdl-reader reads .full and .cdb files from their name"):
        read(tmp_path / "x.full.gz")


def test_an_unknown_compressed_suffix_is_named(tmp_path):
    p = tmp_path / "model.xyz.gz"
    p.write_bytes(gzip.compress(b"1 1 1.0\n"))
    with pytest.raises(ReadError, match=r"unknown FE model file type '\.xyz\.gz'"):
        read(p)


# -- info --reference --------------------------------------------------------------------------
def test_info_reference_calculix_dat(capsys, free_ref):
    """CalculiX's own frequencies of the free beam (its .dat): no shapes, so no MAC column, and the table says so."""
    dat = CCX / "beam8_free_freq.dat"
    code, out, err = run(capsys, "info", FREE, "--reference", dat, "--json")
    assert code == 0, err
    ref = json.loads(out)["reference"]
    assert ref["kind"] == "calculix-dat" and ref["shapes"] is False and ref["mac"] is None
    np.testing.assert_allclose(ref["frequencies_hz"], free_ref, rtol=0)
    assert len(ref["frequencies_hz"]) == 20 and ref["rel_diff"][:6] == [None] * 6  # rigid-body modes
    assert max(ref["rel_diff"][6:]) < 1e-6  # CalculiX prints 7 digits
    code, out, _ = run(capsys, "info", FREE, "--reference", dat)
    assert code == 0
    assert "CalculiX .dat" in out and "no MAC column" in out and "   MAC" not in out
    assert "620.6715" in out and "rigid" in out


def _f06(freqs, page_break: int = 4) -> str:
    lines = ["1    BEAM MODES                                   JUNE  10, 2015  NX NASTRAN  5/ 1/14   PAGE     7",
             "0", "                                              R E A L   E I G E N V A L U E S",
             "   MODE    EXTRACTION      EIGENVALUE            RADIANS             CYCLES            GENERALIZED"
             "         GENERALIZED",
             "    NO.       ORDER                                                                       MASS"
             "              STIFFNESS"]
    for i, f in enumerate(freqs, 1):
        w = 2 * np.pi * f
        lines.append(f"{i:9d} {i:9d}       {w * w:13.6E}       {w:13.6E}       {f:13.6E}       {1.0:13.6E}"
                     f"       {w * w:13.6E}")
        if i == page_break:  # a page break inside the table: the title and the column titles again
            lines += ["1    BEAM MODES                                   JUNE  10, 2015  NX NASTRAN  5/ 1/14   "
                      "PAGE     8", "0", lines[2], lines[3], lines[4]]
    lines += ["1    BEAM MODES                                   JUNE  10, 2015  NX NASTRAN  5/ 1/14   PAGE     9",
              "0", "                                         E I G E N V E C T O R   N O .   1"]
    # a second subcase's table is not read
    lines += [lines[2], lines[3], lines[4], f"{1:9d} {1:9d}       {1.0:13.6E}       {1.0:13.6E}       {9.0:13.6E}"]
    return "\n".join(lines) + "\n"


def test_info_reference_nastran_f06_and_a_frequency_list(tmp_path, capsys, clamped_ref):
    f06 = tmp_path / "beam.f06"
    f06.write_text(_f06(clamped_ref[:8]))
    ref = read_reference(f06)
    assert ref.kind == "nastran-f06" and not ref.has_shapes
    np.testing.assert_allclose(ref.frequencies_hz, clamped_ref[:8], rtol=1e-6)
    code, out, err = run(capsys, "info", CLAMPED, "--reference", f06, "--json")
    assert code == 0, err
    got = json.loads(out)["reference"]
    assert got["kind"] == "nastran-f06" and max(got["rel_diff"]) < 1e-5 and got["mac"] is None
    lst = tmp_path / "freqs.txt"
    lst.write_text("# CalculiX, clamped beam\n" + "\n".join(f"{f:.7g}  # mode {i}" for i, f in
                                                            enumerate(clamped_ref[:5], 1)) + "\n\n")
    code, out, _ = run(capsys, "info", CLAMPED, "--reference", lst)
    assert code == 0 and "a list of frequencies in Hz" in out and "no MAC column" in out
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit() and len(ln.split()) == 4]
    assert len(rows) == 5 and max(float(r[3]) for r in rows) < 1e-6
    code, out, _ = run(capsys, "info", CLAMPED, "--reference", _gzip(lst, keep=True))  # compressed too
    assert code == 0 and "no MAC column" in out


def test_info_reference_refuses_what_it_cannot_read(tmp_path, capsys):
    code, _, err = run(capsys, "info", CLAMPED, "--reference", CCX / "beam8_clamped_mat.inp")
    assert code == 2 and "beam8_clamped_mat.inp" in err
    for kind in ("CalculiX .frd", "CalculiX .dat", "Nastran .f06", "a list of frequencies"):
        assert kind in err
    dat = tmp_path / "static.dat"
    dat.write_text("  displacements (vx,vy,vz) for set NALL and time  0.1000000E+01\n    1 0.0 0.0 0.0\n")
    code, _, err = run(capsys, "info", CLAMPED, "--reference", dat)
    assert code == 2 and "static.dat" in err and "E I G E N V A L U E   O U T P U T" in err


# -- superelements are bodies ------------------------------------------------------------------
@pytest.mark.parametrize("fmt", ["binary", "dmig"])
def test_info_recognises_a_superelement_by_its_content(tmp_path, clamped, capsys, fmt):
    _files(tmp_path, clamped, fmt)
    se = tmp_path / ("se.pch" if fmt == "dmig" else "se.op4")
    code, out, err = run(capsys, "info", se)
    assert code == 0, err
    first = out.splitlines()[0]
    assert "Nastran Craig-Bampton superelement" in first and f"{N_MODES} modal coordinates" in first
    assert "written by flexmor" not in out and "older flexmor" not in out
    assert "reduced by Nastran" in out and "read_superelement" not in out + err
    code, out, _ = run(capsys, "info", se, "--json")
    got = json.loads(out)
    assert got["made_by"] == "nastran" and got["method"] == "craig-bampton" and got["nastran"]["n_modal"] == N_MODES


def test_a_superelement_given_as_a_model_names_the_flag_not_a_function(tmp_path, clamped, capsys):
    _files(tmp_path, clamped, "binary")
    code, _, err = run(capsys, "reduce", tmp_path / "se.op4", "--method", "modal", "--order", "4",
                       "-o", tmp_path / "x.h5")
    assert code == 2 and "--format nastran-se" in err and "flexmor.io" not in err and "read_superelement" not in err


def test_a_plain_nastran_model_is_still_a_model(tmp_path):
    _copy(tmp_path, DATA / "nastran", "pyyeti_rd_ascii.op4")
    assert kind_of(tmp_path / "pyyeti_rd_ascii.op4") == "model"
    assert kind_of(tmp_path / "pyyeti_rd_ascii.op4", "nastran-se") == "body"
    assert kind_of(CLAMPED) == "model"


def test_export_compare_and_info_of_a_superelement(tmp_path, clamped, capsys):
    """export SE.op4 (no --format): the .h5 it writes says it came from Nastran, without a fingerprint warning."""
    _files(tmp_path, clamped, "binary")
    se = _gzip(tmp_path / "se.op4")
    code, out, err = run(capsys, "export", se, "-o", tmp_path / "se.h5")
    assert code == 0, err
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexmorWarning)
        code, out, err = run(capsys, "info", tmp_path / "se.h5")
    assert code == 0, err
    assert "Nastran Craig-Bampton superelement" in out.splitlines()[0] and "from se.op4.gz" in out.splitlines()[0]
    assert "older flexmor" not in out + err and "no fingerprint" not in err
    code, out, err = run(capsys, "compare", CLAMPED, se, "--band", "10:300", "--json")
    assert code == 0, err
    row = json.loads(out)["results"][0]
    assert row["method"] == "craig-bampton" and row["band_error"] < 1e-4


def test_report_of_a_superelement(tmp_path, clamped, capsys):
    """report MODEL SE.op4: judged like any body; without a basis it has no MAC, and the page says so."""
    _files(tmp_path, clamped, "binary")
    out_file = tmp_path / "r.html"
    code, out, err = run(capsys, "report", CLAMPED, tmp_path / "se.op4", "--band", "10:300", "-o", out_file,
                         "--json")
    assert code == 0, err
    got = json.loads(out)
    assert got["results"][0]["method"] == "craig-bampton" and got["results"][0]["band_error"] < 1e-4
    assert any("no basis V" in n and "no MAC" in n for n in got["notes"])
    assert out_file.stat().st_size > 0


def test_compressed_matrix_files_are_streamed(tmp_path, monkeypatch):
    """The .sti.gz and .mas.gz are decompressed chunk by chunk as they are parsed, never read whole."""
    from flexmor.io import _open

    _copy(tmp_path, CCX, "beam8_clamped_mat.*")
    for suf in (".sti", ".mas"):
        _gzip(tmp_path / f"beam8_clamped_mat{suf}")
    sizes: dict = {}
    real = _open._GzipReader.read

    def read_recorded(self, size=-1):
        sizes.setdefault(Path(self._path).name, []).append(size)
        return real(self, size)

    monkeypatch.setattr(_open._GzipReader, "read", read_recorded)
    model = read(tmp_path / "beam8_clamped_mat.sti.gz")
    assert model.n_dof == 270
    for name in ("beam8_clamped_mat.sti.gz", "beam8_clamped_mat.mas.gz"):
        assert sizes[name] and all(0 < s <= 1 << 21 for s in sizes[name]), sizes


def test_info_formats_says_which_readers_take_gz(capsys):
    code, out, _ = run(capsys, "info", "--formats")
    assert code == 0
    lines = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("  ")}
    assert "(also .gz)" in lines["calculix"] and "(also .gz)" in lines["nastran-se"]
    assert "(also .gz)" not in lines["hdf5"]
