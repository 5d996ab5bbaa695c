"""CalculiX reader: real CalculiX 2.20 exports of a steel beam, and a corpus of broken files."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from helpers import CLAMPED, DATA, FREE

import flexmor.io
from flexmor.errors import FlexmorError, ReadError
from flexmor.io._text import parse_triplets
from flexmor.model import DIRECTIONS

BAD = DATA / "bad"


def _freqs(model, k):
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, k - 1])
    return np.sqrt(np.abs(w)) / (2 * np.pi)


@pytest.fixture(scope="module")
def clamped():
    return flexmor.io.read(CLAMPED)


@pytest.fixture(scope="module")
def free():
    return flexmor.io.read(FREE)


def test_clamped_sizes_and_sets(clamped):
    assert clamped.n_dof == 270  # 99 nodes - 9 clamped, 3 DOF each
    assert clamped.n_nodes == 99
    assert clamped.name == "beam8_clamped_mat"
    assert clamped.source == CLAMPED
    assert sorted(clamped.node_sets) == ["FIX", "NALL", "TIP"]
    assert clamped.node_sets["TIP"].tolist() == [11, 22, 33, 44, 55, 66, 77, 88, 99]
    np.testing.assert_allclose(clamped.node_xyz([99])[0], [1.0, 0.1, 0.1])
    assert clamped.dof_index(2, DIRECTIONS["x"]) == 0  # .dof line 1 is "2.1"
    assert clamped.dof_index(99, DIRECTIONS["z"]) == 269
    assert not np.isin(clamped.dofs[:, 0], clamped.node_sets["FIX"]).any()


def test_clamped_matrices_symmetric_and_full(clamped):
    for A in (clamped.M, clamped.K):
        assert abs(A - A.T).max() == 0.0
    # the upper triangle in the file: 6309 entries, 270 of them on the diagonal; its explicit zeros
    # (K and M are written on one pattern) are not stored
    r, c, v = np.loadtxt(str(CLAMPED).replace(".inp", ".sti"), unpack=True)
    assert r.size == 6309 and np.count_nonzero(r == c) == 270
    assert clamped.K.nnz == 2 * np.count_nonzero(v) - np.count_nonzero((r == c) & (v != 0)) < 2 * 6309 - 270
    assert clamped.K[0, 0] == pytest.approx(5.1602564102564e09)
    assert clamped.K[1, 2] == clamped.K[2, 1] == pytest.approx(3.3653846153846e09)


def test_free_model_total_mass(free):
    assert free.n_dof == 297
    for d in (1, 2, 3):  # rigid translation: r^T M r = rho * volume = 7850 * 1 * 0.1 * 0.1
        r = (free.dofs[:, 1] == d).astype(float)
        assert r @ (free.M @ r) == pytest.approx(78.5, rel=1e-12)
    r = (free.dofs[:, 1] == 1).astype(float)
    assert np.abs(free.K @ r).max() < 1e-6 * abs(free.K).max()  # rigid motion is stress free


def test_clamped_frequencies_match_calculix(clamped):
    # beam8_clamped_freq.dat: 0.1000459E+03 (x2), 0.6085650E+03 (x2), 0.8027393E+03
    f = _freqs(clamped, 5)
    np.testing.assert_allclose(f, [100.0459, 100.0459, 608.5650, 608.5650, 802.7393], rtol=1e-5)


def test_free_frequencies_match_calculix(free):
    f = _freqs(free, 9)
    assert np.all(f[:6] < 0.01)  # six rigid-body modes
    np.testing.assert_allclose(f[6:], [620.6715, 620.6715, 1610.433], rtol=1e-5)


def test_nset_generate_set_reference_and_include(tmp_path):
    job = _job(tmp_path)
    inp = job.with_suffix(".inp")
    text = inp.read_text()
    head, rest = text.split("*ELEMENT", 1)
    nodes = head.split("\n", 3)[3]  # the node lines after *HEADING, title, *NODE
    (tmp_path / "nodes.msh").write_text("*node, nset=nall\n" + nodes)
    inp.write_text("*HEADING\ninclude test\n** comment\n*INCLUDE, INPUT=nodes.msh\n*ELEMENT" + rest
                   + "*NSET, NSET=gen, GENERATE\n1, 11, 2\n*NSET,NSET=ENDS\nFIX,\nTIP, 50\n")
    m = flexmor.io.read(job)
    assert m.n_nodes == 99
    assert m.node_sets["GEN"].tolist() == [1, 3, 5, 7, 9, 11]
    assert m.node_sets["ENDS"].size == 19


def test_empty_node_set_is_kept_with_warning(tmp_path, caplog):
    job = _job(tmp_path, inp=lambda t: t + "*NSET, NSET=NOTHING\n")
    with caplog.at_level(logging.WARNING, logger="flexmor.io.calculix"):
        m = flexmor.io.read(job)
    assert m.node_sets["NOTHING"].size == 0
    assert "NOTHING" in caplog.text


def test_parse_triplets_fast_and_slow_paths_agree(tmp_path):
    rng = np.random.default_rng(1)
    r = rng.integers(1, 500, 2000)
    c = rng.integers(1, 500, 2000)
    v = rng.standard_normal(2000) * 1e6
    plain = tmp_path / "plain.txt"
    plain.write_text("".join(f"{a} {b} {x:.16e}\n" for a, b, x in zip(r, c, v)))
    slow = tmp_path / "slow.txt"  # a comment forces the line-by-line scanner
    slow.write_text("# header\n" + "".join(f"{a}, {b}, {x:.16e}\n".replace("e", "D") for a, b, x in zip(r, c, v)))
    fast = tmp_path / "fortran.txt"  # commas and D exponents, no comments: fast path after rewriting
    fast.write_text(slow.read_text().split("\n", 1)[1])
    for p in (plain, slow, fast):
        rr, cc, vv = parse_triplets(p, n=500)
        np.testing.assert_array_equal(rr, r - 1)
        np.testing.assert_array_equal(cc, c - 1)
        np.testing.assert_array_equal(vv, v)


# -- broken files -----------------------------------------------------------------------------

def _job(tmp_path: Path, src: Path | str = CLAMPED, **edits) -> Path:
    """Copy the four files of a CalculiX job to tmp_path/job.*; edits[suffix](text) -> text."""
    for suf in (".sti", ".mas", ".dof", ".inp"):
        text = Path(src).with_suffix(suf).read_text()
        if suf[1:] in edits:
            text = edits[suf[1:]](text)
        (tmp_path / f"job{suf}").write_text(text)
    return tmp_path / "job.sti"


def _set_line(k: int, new: str):
    def edit(text):
        lines = text.split("\n")
        lines[k - 1] = new
        return "\n".join(lines)
    return edit


BROKEN = {
    # name: (edits, file named in the error, line, words in the message)
    "two_columns": (dict(sti=_set_line(10, "4 5")), "job.sti", 10, "3 columns"),
    "non_numeric": (dict(sti=_set_line(20, "5 7 1.0e+09x")), "job.sti", 20, "non-numeric"),
    "non_integer_index": (dict(sti=_set_line(21, "5.5 7 1.0")), "job.sti", 21, "integers"),
    "nan": (dict(mas=_set_line(30, "7 8 nan")), "job.mas", 30, "non-finite"),
    "inf": (dict(sti=_set_line(31, "7 8 -inf")), "job.sti", 31, "non-finite"),
    "index_zero": (dict(sti=_set_line(40, "0 9 1.0")), "job.sti", 40, "below 1"),
    "index_beyond_n": (dict(sti=_set_line(50, "9 271 1.0")), "job.sti", 50, "beyond the matrix size 270"),
    "lower_triangle": (dict(sti=_set_line(5, "3 2 3.3653846153846e+09")), "job.sti", 5, "below the diagonal"),
    "duplicate": (dict(mas=_set_line(6309, "1 1 0.1")), "job.mas", 6309, "appears twice"),
    "truncated": (dict(sti=lambda t: t.rstrip("\n")[:-8]), "job.sti", 6309, "cut off"),
    "mass_diag_zero": (dict(mas=_set_line(1, "1 1 0.0")), "job.mas", None, "mass matrix diagonal"),
    "dof_unknown_node": (dict(dof=_set_line(7, "999.1")), "job.dof", 7, "node 999"),
    "dof_bad_token": (dict(dof=_set_line(8, "4,2")), "job.dof", 8, "node.direction"),
    "dof_direction_7": (dict(dof=_set_line(9, "4.7")), "job.dof", 9, "direction 7"),
    "dof_too_short": (dict(dof=lambda t: t.rsplit("\n", 3)[0] + "\n"), "job.dof", None,
                      "268 equations, but job.sti and job.mas have entries up to equation 270"),
    "nset_unknown_node": (dict(inp=_set_line(147, "11, 22, 33, 44, 55, 66, 77, 88, 999")), "job.inp", 147, "node 999"),
    "nset_unknown_name": (dict(inp=_set_line(147, "11, BOGUS")), "job.inp", 147, "BOGUS"),
    "node_bad_line": (dict(inp=_set_line(50, "47, 0.2, zero, 0.05")), "job.inp", 50, "non-numeric"),
    "node_twice": (dict(inp=_set_line(50, "3, 0.2, 0.05, 0.05")), "job.inp", 50, "defined twice"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_broken_job_raises_read_error(tmp_path, case):
    edits, fname, line, words = BROKEN[case]
    job = _job(tmp_path, **edits)
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(job)
    msg = str(exc.value)
    assert isinstance(exc.value, FlexmorError)
    assert fname in msg
    assert words in msg
    if line is not None:
        assert f"{fname}:{line}:" in msg
        assert exc.value.line == line
    assert "\n" not in msg


@pytest.mark.parametrize("missing", [".mas", ".dof", ".inp"])
def test_missing_sibling_is_named(tmp_path, missing):
    job = _job(tmp_path)
    job.with_suffix(missing).unlink()
    with pytest.raises(ReadError, match=rf"job\{missing}: not found"):
        flexmor.io.read(job)


def test_literal_bad_files():
    with pytest.raises(ReadError, match=r"empty\.sti: file is empty"):
        flexmor.io.read(BAD / "empty.sti")
    with pytest.raises(ReadError, match=r"junk\.sti: looks like a binary file"):
        flexmor.io.read(BAD / "junk.sti")
    with pytest.raises(ReadError, match=r"truncated\.sti:4: last line has no line end"):
        flexmor.io.read(BAD / "truncated.sti")
    with pytest.raises(ReadError, match=r"orphan\.mas: not found"):
        flexmor.io.read(BAD / "orphan.sti")


def test_mas_given_as_main_file(tmp_path):
    job = _job(tmp_path)
    with pytest.raises(ReadError, match=r"pass the stiffness file job\.sti"):
        flexmor.io.read(job.with_suffix(".mas"), format="calculix")


def test_nodes_from_frd_without_deck(tmp_path, free, caplog):
    """A job shipped as .sti/.mas/.dof/.frd without its .inp: the nodes come from the .frd.

    ``beam8_free_mat.frd`` was written by CalculiX 2.20 for ``beam8_free_mat.inp`` with an
    ordinary ``*FREQUENCY`` step (8 modes, ``*NODE FILE``) before the ``MATRIXSTORAGE`` step;
    that job's ``.sti/.mas/.dof`` are byte for byte the ones in tests/data.
    """
    import logging
    import shutil

    from flexmor.io import read
    from flexmor.io.calculix import compare_modes, read_frd

    for suf in (".sti", ".mas", ".dof", ".frd"):
        shutil.copy(Path(FREE).with_suffix(suf), tmp_path / f"job{suf}")
    with caplog.at_level(logging.WARNING, logger="flexmor"):
        m = read(tmp_path / "job.sti")
    assert "no input deck job.inp beside it; nodes read from the node block of job.frd" in caplog.text
    np.testing.assert_array_equal(m.node_ids, free.node_ids)
    np.testing.assert_allclose(m.xyz, free.xyz, rtol=1e-5, atol=1e-9)  # frd coordinates: E12.5
    assert m.node_sets == {}
    assert (m.M != free.M).nnz == 0 and (m.K != free.K).nnz == 0
    res = read_frd(tmp_path / "job.frd")
    assert res.element_types == {"C3D8"} and len(res.blocks) == 8
    cmp = compare_modes(m, res)  # CalculiX's own modes of the same job: 620.67 Hz (x2), 1610.4 Hz
    assert cmp["frequencies_hz"][6] == pytest.approx(620.6715, rel=1e-6)
    assert np.max(np.abs(cmp["rel_diff"][6:])) < 1e-6 and np.min(cmp["mac"][6:]) > 0.999
    # with the deck beside it, nodes and node sets come from the deck
    shutil.copy(Path(FREE).with_suffix(".inp"), tmp_path / "job.inp")
    m2 = read(tmp_path / "job.sti")
    assert set(m2.node_sets) == set(free.node_sets) and "TIP" in m2.node_sets
    (tmp_path / "job.inp").unlink()
    (tmp_path / "job.frd").unlink()
    with pytest.raises(ReadError, match=r"job.inp: not found; .* the job's job.frd"):
        read(tmp_path / "job.sti")
