"""Runs of GRID cards and CalculiX ``*NODE`` blocks read as whole blocks, against the line-by-line readers.

A deck mixes runs the block parser takes (small field, free field, blank and given CP/CD) with
cards it leaves to the card-by-card reader (large field, continuations, Nastran exponents,
short runs); the block reader must give the same grids, positions (to the bit) and systems as
the card-by-card one, and name the line of a bad card deep inside a run.
"""

from __future__ import annotations

import numpy as np
import pytest

import flexmor.io.nastran.nastran_bulk as nb
from flexmor.errors import ReadError
from flexmor.io.calculix.deck import read_inp
from flexmor.io.nastran import read_bulk
from flexmor.io.nastran.nastran_grids import BLANK, grid_form, grid_run


def _small(gid, cp, x, cd=""):
    return f"{'GRID':<8}{gid:<8}{cp:<8}" + "".join(f"{v:<8}" for v in x) + f"{cd:<8}"


def _large(gid, cp, x, cd=""):
    return [f"{'GRID*':<8}{gid:>16}{cp:>16}{x[0]:>16}{x[1]:>16}*G{gid}", f"{'*G' + str(gid):<8}{x[2]:>16}{cd:>16}"]


def _mixed_deck(rng) -> tuple[list, dict]:
    """Lines of a bulk deck with ~400 grids in every form, and the expected CP/CD of each grid."""
    ids = rng.permutation(np.arange(1, 401)) * 3
    reals = ["0.", "-0.", "1.5", ".25", "-3.125", "2.5E-1", "12345.6", "-.0625", "1e2"]
    lines = ["$ mixed forms", "BEGIN BULK", "CORD2R  5       0       1.      2.      3.      1.      2.      4.",
             "+       2.      2.      3.", "CORD2C,7,5,0.,0.,0.,0.,0.,1.", ",1.,0.,0.", "GRDSET,,5,,,,7"]
    cpcd = {}
    for k, gid in enumerate(ids.tolist()):
        x = [reals[j] for j in rng.integers(0, len(reals), 3)]
        cp, cd = ["", "0", "5", "7"][k % 4], ["", "0", "7", "-1"][k // 4 % 4]
        cpcd[gid] = (cp, cd, x)
        block = k // 50
        if block in (0, 3):
            lines.append(_small(gid, cp, x, cd))
        elif block in (1, 4):
            lines.append(",".join(["GRID", str(gid), cp, *x, cd]))
        elif block == 2 and k % 7 == 0:
            lines += _large(gid, cp, x, cd)
        elif block == 2:
            x[:] = [v.replace("E", "") for v in x]  # 2.5-1: Nastran's implicit exponent
            x[0] = "1.+2" if k == 101 else x[0]
            lines.append(_small(gid, cp, x, cd))
        elif block == 5:
            lines.append(f"GRID,{gid},{cp},{x[0]},{x[1]},{x[2]},{cd},,,+C{k}")
            lines.append(f"+C{k}")
        elif block == 6:
            lines.append(f"GRID\t{gid}\t{cp}\t{x[0]}\t{x[1]}\t{x[2]}\t{cd}")
            if k % 10 == 0:
                lines.append("")
        elif k < 375:
            lines += _large(gid, cp, x, cd)
        else:
            lines.append(_small(gid, cp, x, cd) if k % 2 else ",".join(["GRID", str(gid), cp, *x, cd]))
    lines.append("ENDDATA")
    return lines, cpcd


def test_runs_give_the_grids_of_the_card_by_card_reader(tmp_path, monkeypatch):
    lines, cpcd = _mixed_deck(np.random.default_rng(5))
    p = tmp_path / "mixed.bdf"
    p.write_text("\n".join(lines) + "\n")
    runs = []

    def spy(block, form):
        out = grid_run(block, form)
        runs.append((form, len(block), out is not None))
        return out

    monkeypatch.setattr(nb, "grid_run", spy)
    fast = read_bulk(p)
    assert {("small", 50, True), ("free", 50, True), ("large", 50, True)} <= set(runs)  # read as blocks
    monkeypatch.setattr(nb, "_MIN_RUN", 10**9)
    slow = read_bulk(p)
    np.testing.assert_array_equal(fast.grid_ids, slow.grid_ids)
    np.testing.assert_array_equal(fast.cd, slow.cd)
    assert fast.xyz.tobytes() == slow.xyz.tobytes()
    assert sorted(fast.systems) == sorted(slow.systems) == [0, 5, 7]
    assert fast.grid_ids.size == 400
    for gid, cd in zip(fast.grid_ids.tolist(), fast.cd.tolist()):
        want = int(cpcd[gid][1] or 7)  # GRDSET CD=7
        assert cd == (0 if want == -1 else want)
    for gid, xyz in zip(fast.grid_ids.tolist(), fast.xyz.tolist()):
        cp, _, x = cpcd[gid]
        if cp == "0":
            assert xyz == [nb.num(v) + 0.0 for v in x]


def test_grid_run_parses_fields_as_the_card_reader():
    ids, cp, xyz, cd = grid_run([_small(12, "", ["1.5", "", "-0."], "3"), _small(7, "4", ["1e3", ".5", "2."])],
                                "small")
    np.testing.assert_array_equal(ids, [12, 7])
    np.testing.assert_array_equal(cp, [BLANK, 4])
    np.testing.assert_array_equal(cd, [3, BLANK])
    np.testing.assert_array_equal(xyz, [[1.5, 0.0, -0.0], [1000.0, 0.5, 2.0]])
    ids, cp, xyz, cd = grid_run(["GRID,1,,0.1,0.2,0.3", "GRID, 2 ,0, 1.,2.,3."], "free")
    np.testing.assert_array_equal(xyz, [[0.1, 0.2, 0.3], [1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(cp, [BLANK, 0])
    assert grid_run(["GRID,1,,0.1,0.2,0.3", "GRID,2,,1.,2.,3.,0"], "free") is None  # field counts differ
    assert grid_run([_small(1, "", ["1.5-3", "0.", "0."])], "small") is None  # Nastran exponent: card reader
    assert grid_run([_small(1, "", ["inf", "0.", "0."])], "small") is None
    assert grid_run(["GRID,1,,0.,0.,1.é"], "free") is None
    assert grid_run([_small(1, "", ["1.é", "0.", "0."])], "small") is None
    assert grid_run([_small("", "", ["1.", "0.", "0."])], "small") is None
    assert grid_form("GRID*          1") == "large" and grid_form("GRIDS   1") is None
    assert grid_form("GRID*,1,,1.,2.") is None  # free-field large: card reader
    ids, cp, xyz, cd = grid_run(_large(4, "", ["1.", "2.", "3."], "2") + _large(5, "1", ["", "-0.", "1e-3"]), "large")
    np.testing.assert_array_equal(ids, [4, 5])
    np.testing.assert_array_equal(cp, [BLANK, 1])
    np.testing.assert_array_equal(cd, [2, BLANK])
    np.testing.assert_array_equal(xyz, [[1.0, 2.0, 3.0], [0.0, -0.0, 1e-3]])
    assert grid_form("GRID    1") == "small" and grid_form("GRID,1") == "free" and grid_form("grid,1") is None


def test_large_field_run_bad_continuation_names_the_card(tmp_path):
    lines = ["BEGIN BULK"] + [ln for k in range(1, 201) for ln in _large(k, "", [f"{k}.", "0.", "-1.5"])]
    lines[2 * 150] = lines[2 * 150].replace("-1.5", "1..5")  # the continuation of GRID 150 (line 301)
    p = tmp_path / "large.bdf"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReadError, match="GRID: malformed field") as exc:
        read_bulk(p)
    assert exc.value.line == 300  # the card's first line, as the card reader says
    lines[2 * 150] = lines[2 * 150].replace("1..5", "-2.5")
    p.write_text("\n".join(lines) + "\n")
    b = read_bulk(p)
    np.testing.assert_array_equal(b.xyz[149], [150.0, 0.0, -2.5])
    np.testing.assert_array_equal(b.xyz[0], [1.0, 0.0, -1.5])


def _run_deck(tmp_path, bad_line: str | None, at: int, free: bool) -> tuple:
    lines = ["BEGIN BULK"] + [(f"GRID,{k},,{k}.,0.,1." if free else _small(k, "", [f"{k}.", "0.", "1."]))
                              for k in range(1, 301)] + ["ENDDATA"]
    if bad_line is not None:
        lines[at] = bad_line
    p = tmp_path / "run.bdf"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("free", [False, True])
@pytest.mark.parametrize("bad, words", [
    ("x", "malformed field"),
    ("nan", "malformed field"),
    ("1.2.3", "malformed field"),
])
def test_bad_grid_deep_in_a_run_names_its_line(tmp_path, free, bad, words):
    row = f"GRID,250,,0.,{bad},1." if free else _small(250, "", ["0.", bad, "1."])
    p = _run_deck(tmp_path, row, 250, free)
    with pytest.raises(ReadError, match=words) as exc:
        read_bulk(p)
    assert exc.value.line == 251 and exc.value.path == str(p)


@pytest.mark.parametrize("free", [False, True])
def test_run_errors_of_ids_and_systems(tmp_path, free):
    p = _run_deck(tmp_path, "GRID,17,,0.,0.,0." if free else _small(17, "", ["0.", "0.", "0."]), 200, free)
    with pytest.raises(ReadError, match=r"GRID 17 defined twice \(first on line 18\)") as exc:
        read_bulk(p)
    assert exc.value.line == 201
    p = _run_deck(tmp_path, "GRID,150,9,0.,0.,0." if free else _small(150, "9", ["0.", "0.", "0."]), 150, free)
    with pytest.raises(ReadError, match="CP=9 is not defined") as exc:
        read_bulk(p)
    assert exc.value.line == 151
    p = _run_deck(tmp_path, "GRID,150,,0.,0.,0.,8" if free else _small(150, "", ["0.", "0.", "0."], "8"), 150,
                  free)
    with pytest.raises(ReadError, match="CD=8 is not defined") as exc:
        read_bulk(p)
    assert exc.value.line == 151
    p = _run_deck(tmp_path, "GRID,150,1.5,0.,0.,0." if free else _small(150, "1.5", ["0.", "0.", "0."]), 150,
                  free)
    with pytest.raises(ReadError, match="CP/CD must be integers") as exc:
        read_bulk(p)
    assert exc.value.line == 151


def test_run_before_a_continuation_keeps_it(tmp_path):
    lines = [f"GRID,{k},,{k}.,0.,0." for k in range(1, 21)] + ["+,ignored", "GRID,21,,1.,2.,3."]
    p = tmp_path / "c.bdf"
    p.write_text("\n".join(lines) + "\n")
    b = read_bulk(p)
    np.testing.assert_array_equal(b.grid_ids, np.arange(1, 22))
    np.testing.assert_array_equal(b.xyz[19], [20.0, 0.0, 0.0])


def _node_deck(tmp_path, bad: str | None = None) -> tuple:
    lines = ["*HEADING", "nodes", "*NODE, NSET=NALL"] + [f"{k}, {k * 0.1!r}, {-k / 3!r}, 1.5e-3" for k in
                                                         range(1, 2001)]
    lines[1500:1500] = ["** a comment inside the block", ""]
    if bad is not None:
        lines[1800] = bad
    lines += ["*ELEMENT, TYPE=C3D8", "*NSET, NSET=A", "1, 2, 3"]
    p = tmp_path / "n.inp"
    p.write_text("\n".join(lines) + "\n")
    return p, lines


def test_node_block_read_whole(tmp_path):
    p, _ = _node_deck(tmp_path)
    ids, xyz, sets = read_inp(p)
    np.testing.assert_array_equal(ids, np.arange(1, 2001))
    k = np.arange(1, 2001)
    assert xyz[:, 0].tolist() == [float(repr(v * 0.1)) for v in k.tolist()]
    assert xyz[:, 1].tolist() == [-v / 3 for v in k.tolist()]
    assert np.all(xyz[:, 2] == 1.5e-3)
    assert sets["NALL"].size == 2000 and sets["A"].tolist() == [1, 2, 3]


@pytest.mark.parametrize("bad, words", [
    ("1799, 0.1, abc, 0.", "non-numeric node line"),
    ("1799, 0.1, 0.2, 0.3, 0.4", "expected 'id, x, y, z'"),
    ("1799, 0.1, inf, 0.", "non-finite"),
])
def test_node_block_bad_line_named(tmp_path, bad, words):
    p, lines = _node_deck(tmp_path, bad)
    with pytest.raises(ReadError, match=words) as exc:
        read_inp(p)
    assert exc.value.line == 1801 and lines[exc.value.line - 1] == bad


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_node_block_other_line_ends(tmp_path, newline):
    p, lines = _node_deck(tmp_path)
    want = read_inp(p)
    p.write_bytes(newline.join(lines).encode() + newline.encode())
    ids, xyz, sets = read_inp(p)
    np.testing.assert_array_equal(ids, want[0])
    assert xyz.tobytes() == want[1].tobytes()
    assert sets.keys() == want[2].keys()
    lines[1800] = "1799, 0.1, abc, 0."
    p.write_bytes(newline.join(lines).encode())
    with pytest.raises(ReadError, match="non-numeric") as exc:
        read_inp(p)
    assert exc.value.line == 1801
