"""The README's tour runs as written, from a copy of the repository's example files.

The command lines are read from the README itself: the first block of its "## Tour" section and the
block after "After the tour, in the same folder:" (the exports). They run in order, in-process
(``flexmor.cli.main``), in a temporary folder that holds ``examples/data/`` as the repository ships it,
so a tour line naming a file that is neither shipped nor written by an earlier line fails here. Each
must exit with 0. The output the README quotes for the tour's ``compare`` is compared by the rules of
``tests/printed.py``; a figure the program prints below 1e-9 is round-off and is quoted as the bound
``< 1e-9`` (the run's number is replaced by that bound, right-aligned in its width, before comparing).

``examples/data/README.md`` is checked too: its files are the CalculiX exports of ``tests/data/calculix``
under other names, ``part.*`` is ``beam.*`` in mm-t-s, and its table of CalculiX frequencies is what the
``.dat`` files hold and what flexmor computes from the matrices, to half a unit in the printed digit; where
CalculiX is installed, ``ccx`` run on the shipped decks writes the shipped matrices and frequencies again.
"""

from __future__ import annotations

import re
import shlex
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from ccx_models import CCX as CCX_BIN
from helpers import CCX, run
from printed import FLOOR, NUMBER, output_differs

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DATA = ROOT / "examples" / "data"
EXPORTS_INTRO = "After the tour, in the same folder:\n\n```\n"
COMPARE_INTRO = "the `compare` of the tour prints\n\n```\n"


def _block_after(text: str, intro: str) -> str:
    assert intro in text, f"README.md: no {intro!r}"
    return text.split(intro, 1)[1].split("```", 1)[0]


def tour_blocks(text: str) -> dict[str, str]:
    """The README blocks this test runs or compares: ``tour``, ``exports`` (command lines) and ``compare``
    (the quoted output of the tour's compare line); tests/test_doc_blocks.py counts them as run."""
    section = text.split("\n## Tour\n", 1)[1].split("\n## ", 1)[0]
    tour = section.split("\n```\n", 1)[1].split("```", 1)[0]
    return {"tour": tour, "exports": _block_after(text, EXPORTS_INTRO), "compare": _block_after(text, COMPARE_INTRO)}


def command_lines(block: str) -> list[list[str]]:
    """The argument lists of a block of ``flexmor`` command lines (comments after ``#`` dropped)."""
    commands = []
    for line in block.splitlines():
        argv = shlex.split(line, comments=True)
        if argv:
            assert argv[0] == "flexmor", f"not a flexmor command line: {line!r}"
            commands.append(argv[1:])
    return commands


def round_off_as_bound(text: str) -> str:
    """``text`` with every printed non-integer number below ``FLOOR`` in magnitude replaced by ``< 1e-9``,
    right-aligned in the number's width (so the columns stay where they are)."""
    def bound(m: re.Match) -> str:
        s = m.group(0)
        if re.fullmatch(r"[-+]?\d+", s) or abs(float(s)) >= FLOOR:
            return s
        return f"{'< 1e-9':>{len(s)}}"

    return NUMBER.sub(bound, text)


def test_round_off_is_printed_as_a_bound():
    assert round_off_as_bound("1627     4.79e-13      4.02e-02") == "1627       < 1e-9      4.02e-02"
    assert round_off_as_bound("order 0, 33 DOF, 2.5e-09") == "order 0, 33 DOF, 2.5e-09"


@pytest.fixture(scope="module")
def tour(tmp_path_factory):
    """A fresh folder holding examples/data, and the command lines of the tour and the exports."""
    work = tmp_path_factory.mktemp("tour")
    shutil.copytree(DATA, work / "examples" / "data")
    blocks = tour_blocks(README.read_text(encoding="utf-8"))
    lines = command_lines(blocks["tour"]) + command_lines(blocks["exports"])
    assert len(lines) >= 20, "the tour and the exports have fewer lines than the README shows"
    return work, lines


def test_the_tour_runs_as_written(tour, capsys, monkeypatch):
    work, lines = tour
    monkeypatch.chdir(work)
    failures, outputs = [], {}
    t0 = time.perf_counter()
    for argv in lines:
        code, out, err = run(capsys, *argv)
        outputs[" ".join(argv)] = out
        if code != 0:
            failures.append(f"flexmor {' '.join(argv)}: exit code {code}\n{err}")
    seconds = time.perf_counter() - t0
    assert not failures, "\n\n".join(failures)
    # every file the lines write is there
    for argv in lines:
        if "-o" in argv:
            out_file = work / argv[argv.index("-o") + 1]
            assert out_file.stat().st_size > 0, out_file
    # the output the README quotes for the tour's compare line
    blocks = tour_blocks(README.read_text(encoding="utf-8"))
    compare = [k for k in outputs if k.startswith("compare ")]
    assert len(compare) == 1, "the tour has one compare line"
    got = round_off_as_bound(outputs[compare[0]])
    why = output_differs(blocks["compare"], got)
    assert why is None, f"README.md, the output of flexmor {compare[0]}: {why}\n--- printed:\n{outputs[compare[0]]}"
    # the mm-t-s file read with --units mm-t-s is the SI beam: the same frequencies as the SI body
    from flexmor.io import read_body

    si, mm = read_body(work / "modal8.h5"), read_body(work / "part.h5")
    f_si = np.sort(np.linalg.eigvals(np.linalg.solve(si.M, si.K)).real)
    f_mm = np.sort(np.linalg.eigvals(np.linalg.solve(mm.M, mm.K)).real)
    np.testing.assert_allclose(f_mm, f_si, rtol=1e-9)
    # the reference comparison names CalculiX's .dat and pairs all its modes
    ref = outputs["info examples/data/beam.sti.gz --reference examples/data/beam.dat"]
    assert "reference examples/data/beam.dat: CalculiX .dat" in ref
    assert seconds < 60, f"the tour took {seconds:.0f} s; keep it quick"


def _dat_frequencies(path: Path) -> list[str]:
    """The CYCLES/TIME column of a CalculiX .dat's eigenvalue output, as printed."""
    text = path.read_text().split("E I G E N V A L U E   O U T P U T", 1)[1].split("P A R T I C I P A T I O N", 1)[0]
    return [m.group(1) for m in re.finditer(r"^\s+\d+\s+\S+\s+\S+\s+(\S+)\s+\S+\s*$", text, re.M)]


def test_the_example_data_is_what_its_readme_says():
    for kind, name in (("clamped", "beam"), ("free", "free")):
        for ext in ("sti", "mas", "dof", "inp"):
            assert (DATA / f"{name}.{ext}").read_bytes() == (CCX / f"beam8_{kind}_mat.{ext}").read_bytes(), name
        assert (DATA / f"{name}.dat").read_bytes() == (CCX / f"beam8_{kind}_freq.dat").read_bytes()
    import gzip

    assert gzip.decompress((DATA / "beam.sti.gz").read_bytes()) == (DATA / "beam.sti").read_bytes()
    # part.* is beam.* in mm, t, s, N
    for ext in ("sti", "mas"):
        si = np.loadtxt(DATA / f"beam.{ext}")
        mm = np.loadtxt(DATA / f"part.{ext}")
        np.testing.assert_array_equal(mm[:, :2], si[:, :2])
        np.testing.assert_allclose(mm[:, 2], si[:, 2] * 1e-3, rtol=1e-15, atol=0)
    assert (DATA / "part.dof").read_bytes() == (DATA / "beam.dof").read_bytes()
    import flexmor

    beam, part = flexmor.read(DATA / "beam.sti"), flexmor.read(DATA / "part.sti")
    np.testing.assert_array_equal(part.node_ids, beam.node_ids)
    np.testing.assert_allclose(part.xyz, beam.xyz * 1e3, rtol=1e-15, atol=1e-12)
    assert part.elements is not None and beam.elements is not None


def test_the_calculix_frequencies_of_the_example_readme(capsys):
    text = (DATA / "README.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| (\d+) \| ([\d.]+) \| ([\d.]+|rigid) \|$", text, re.M)
    assert [int(r[0]) for r in rows] == list(range(1, 13))
    for column, name in ((1, "beam"), (2, "free")):
        dat = _dat_frequencies(DATA / f"{name}.dat")
        code, out, err = run(capsys, "info", DATA / f"{name}.sti", "--modes", "12")
        assert code == 0, err
        ours = [float(m.group(1)) for m in re.finditer(r"^\s+\d+\s+([\d.]+)(?:\s+rigid)?\s*$", out, re.M)]
        assert len(ours) == 12, out
        for i, row in enumerate(rows):
            quoted = row[column]
            if quoted == "rigid":
                assert float(dat[i]) < 1e-3 and abs(ours[i]) < 1e-2, (name, i + 1, dat[i], ours[i])
                continue
            # the README rounds the .dat's seven significant digits as printed
            assert float(quoted) == float(dat[i]), (name, i + 1, quoted, dat[i])
            digits = len(quoted.split(".")[1])
            assert abs(ours[i] - float(quoted)) <= 0.5 * 10.0 ** -digits * (1 + 1e-9), (name, i + 1, ours[i], quoted)


@pytest.mark.skipif(CCX_BIN is None, reason="CalculiX (ccx) is not installed; Debian: apt-get install calculix-ccx")
def test_calculix_writes_the_example_data_from_its_decks(tmp_path):
    """What examples/data/README.md says wrote each file: ``ccx beam`` the matrices, ``ccx beam_freq`` the .dat."""
    import subprocess

    for name in ("beam", "free"):
        for job in (name, f"{name}_freq"):
            shutil.copy(DATA / f"{job}.inp", tmp_path)
            proc = subprocess.run([CCX_BIN, job], cwd=tmp_path, capture_output=True, text=True, timeout=120)
            assert proc.returncode == 0, proc.stdout[-2000:]
        for ext in ("sti", "mas"):
            np.testing.assert_allclose(np.loadtxt(tmp_path / f"{name}.{ext}"), np.loadtxt(DATA / f"{name}.{ext}"),
                                       rtol=1e-12, atol=0)
        assert (tmp_path / f"{name}.dof").read_text().split() == (DATA / f"{name}.dof").read_text().split()
        ours = np.array([float(f) for f in _dat_frequencies(tmp_path / f"{name}_freq.dat")])
        shipped = np.array([float(f) for f in _dat_frequencies(DATA / f"{name}.dat")])
        elastic = shipped > 1.0  # the free beam's six rigid-body modes are round-off of zero
        assert ours.shape == shipped.shape == (20,) and elastic.sum() == (20 if name == "beam" else 14)
        np.testing.assert_allclose(ours[elastic], shipped[elastic], rtol=1e-6)
        assert np.all(np.abs(ours[~elastic]) < 1e-3)
