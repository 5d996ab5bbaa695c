"""examples/README.md against the example scripts: its commands parse, its tables have the printed columns.

The README's commands must be accepted by the scripts' command lines, must not write into the
repository, and its 480-DOF coupled-beam rows must be what ``examples/coupled_beam.py`` prints
now (to a factor 1.5, which leaves room for round-off in the tiny errors but not for stale numbers).
"""

from __future__ import annotations

import math
import re
import shlex
from pathlib import Path

import pytest
from helpers import load_example

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "examples" / "README.md"
COMMAND = re.compile(r"^(?:nice -n \d+ )?python examples/(\w+)\.py(.*)$")


def code_lines(text: str) -> list[str]:
    """The lines inside the ``` blocks of ``text``."""
    lines, inside = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            inside = not inside
        elif inside:
            lines.append(line.strip())
    return lines


def commands(text: str) -> list[tuple[str, list[str]]]:
    """``(script name, argv)`` of every ``python examples/NAME.py ...`` line in a code block."""
    out = []
    for line in code_lines(text):
        m = COMMAND.match(line)
        if m:
            out.append((m.group(1), shlex.split(m.group(2))))
    return out


def table_rows(text: str, first: str) -> list[list[str]]:
    """The cells of the Markdown table rows whose first cell is ``first``."""
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] == first:
            rows.append(cells)
    return rows


@pytest.fixture(scope="module")
def text():
    return README.read_text(encoding="utf-8")


def test_every_command_is_accepted_and_writes_outside_the_repository(text):
    found = commands(text)
    assert {name for name, _ in found} == {"coupled_beam", "plate_structure_table"}
    assert len(found) >= 5
    for name, argv in found:
        p = load_example(name).parser()
        try:
            args = p.parse_args(argv)
        except SystemExit:
            pytest.fail(f"examples/README.md: {name}.py does not accept {' '.join(argv)!r}")
        out = Path(args.out)
        out = out if out.is_absolute() else ROOT / out
        assert ROOT not in out.resolve().parents, f"{name}.py {' '.join(argv)} writes into the repository"
        if getattr(args, "model", None):
            assert (ROOT / args.model).is_file(), args.model
    # the README's figures exist under the names the scripts write
    for figure in re.findall(r"\]\((figures/[^)]+)\)", text):
        assert (ROOT / "examples" / figure).is_file(), figure
        assert Path(figure).stem in {name for name, _ in found}


@pytest.mark.parametrize("name", ["coupled_beam", "plate_structure_table"])
def test_default_output_folder_is_not_in_the_examples(name):
    out = load_example(name).parser().parse_args([]).out
    assert out == "example-output"


def test_plate_table_header_is_the_printed_one(text):
    ex = load_example("plate_structure_table")
    empty = {"n_dof": 1, "n_inputs": 6, "band_hz": [1.0, 2.0], "n_resonances": 0, "zeta": 0.01,
             "grid_points": 1, "full_seconds": 0.0, "methods": {}}
    header = ex.table(empty).splitlines()[2]
    assert text.count(header) == 2  # the full-size and the --n 20 table


#: A band_error (a ratio of squared norms) below this is the error of a body exact up to rounding in
#: its basis (amplitude ~1e-6 and below): its digits, and those of the growth divided by it, change with
#: the order of summation (BLAS threads, machine); both are only checked to be at rounding.
ROUNDING = 1e-12


def test_beam_480_rows_are_what_the_script_prints(text, tmp_path, capsys):
    cb = load_example("coupled_beam")
    argv = next(a for name, a in commands(text) if name == "coupled_beam" and "--nx" not in a and "--model" not in a)
    argv = argv[:argv.index("--out")] + ["--out", str(tmp_path)] + argv[argv.index("--out") + 2:]
    assert cb.main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    assert "480 DOF" in printed[0]
    columns = re.split(r"\s{2,}", printed[1].strip())
    assert columns[0] == "method" and len(columns) == 8, printed[1]
    assert table_rows(text, "model") == [["model", *columns]], "the README's beam table has other columns"
    rows = {r[1]: r[2:] for r in table_rows(text, "beam 480 DOF")}
    assert set(rows) == {"krylov", "fw-sobt"}
    for line in printed[2:4]:
        name, *values = line.split()
        seen: list[float] = []  # the error values so far (a growth divides the last one by the one before)
        for col, got, quoted in zip(columns[1:], values, rows[name], strict=True):
            g, q = float(got), float(quoted.replace(",", ""))
            if col == "growth":
                if min(seen[-2:]) < ROUNDING:  # a ratio with an error at rounding: its digits are rounding's
                    continue
            else:
                seen.append(max(g, q))
                if max(g, q) < ROUNDING:  # an exact body's error (with the spring or without): at rounding both
                    continue
            ratio = g / q
            assert abs(math.log10(ratio)) < math.log10(1.5), (
                f"examples/README.md quotes {name} {col} = {quoted}, the script prints {got}")
