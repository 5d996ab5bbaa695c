"""docs/benchmark.md and ``bench/benchmark.py`` (``make benchmark``): the page's tables are the script's.

The script runs in its ``--quick`` mode (tiny sizes, the same cases and code) into a copy of the page; the
committed page's tables must have the rows and columns the script writes, so a hand edit of a table (a row or a
column added, removed or renamed) fails here.
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
import shutil
import subprocess
import sys

from helpers import ROOT

PAGE = ROOT / "docs" / "benchmark.md"
SCRIPT = ROOT / "bench" / "benchmark.py"
MACHINE = re.compile(r"^Machine: .+, \d+ cores, [\d.]+ GB memory; flexmor \S+, git \S+.*; "
                     r"\d{4}-\d\d-\d\d \d\d:\d\d UTC;", re.MULTILINE)


def bench():
    spec = importlib.util.spec_from_file_location("flexmor_bench_benchmark", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclass looks its module up there
    spec.loader.exec_module(mod)
    return mod


def _rows(text: str, key: str) -> dict[str, list[str]]:
    """The cells after the method's name of each row of the table of ``key``."""
    part = text.split(f"### `{key}`", 1)[1].split("### `", 1)[0]
    rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in part.splitlines()
            if ln.startswith("| ") and not ln.startswith("| method")]
    return {r[0]: r[1:] for r in rows}


def test_quick_run_writes_every_method_for_every_model(tmp_path):
    b = bench()
    page = tmp_path / "benchmark.md"
    shutil.copy(PAGE, page)
    text = page.read_text()
    i, j = text.index(b.BEGIN), text.index(b.END)
    page.write_text(text[:i + len(b.BEGIN)] + "\nSTALE TABLE\n" + text[j:])
    out = tmp_path / "benchmark.json"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--page", str(page), "--json", str(out)],
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    written = page.read_text()
    assert "STALE TABLE" not in written
    assert written.count(b.BEGIN) == 1 and written.count(b.END) == 1
    # the text outside the markers is the page's own
    assert written[:written.index(b.BEGIN)] == text[:i] and written[written.index(b.END):] == text[j:]
    assert MACHINE.search(written), written[:2000]
    methods = b.method_names()
    assert len(methods) >= 13 and {"modal", "guyan", "craig-bampton", "svdmor"} <= set(methods)
    assert b.structure(written) == b.expected_structure()
    record = json.loads(out.read_text())
    assert [m["key"] for m in record["models"]] == [c.key for c in b.CASES]
    ran = 0
    for model in record["models"]:
        assert list(model["rows"]) == methods
        table = _rows(written, model["key"])
        assert list(table) == methods
        for method, row in model["rows"].items():
            cells = table[method]
            if "error" in row:
                assert cells[1].startswith("not run: ") and len(cells[1]) > len("not run: ") + 3
                continue
            ran += 1
            for k in ("band_error", "hinf_error", "static_error", "seconds"):
                assert math.isfinite(row[k]) and row[k] >= 0, (model["key"], method, k, row[k])
            assert row["mounted_error"] is None and row["mounted_note"] or math.isfinite(row["mounted_error"])
            assert int(cells[0]) == row["order"] >= 1
            for c in cells[1:3] + cells[4:5] + cells[6:7]:
                assert math.isfinite(float(c)), (model["key"], method, cells)
            # the frame's accelerations deflect every body held as the check holds it (guyan's held at its only
            # DOF has none left: the cell says "-")
            assert cells[5] == "-" if row["frame_error"] is None else math.isfinite(float(cells[5]))
            assert math.isfinite(float(cells[3])) if row["mounted_error"] is not None else cells[3].startswith("- (")
    # every method runs on every model at these sizes (a method that cannot would say why in its cell)
    assert ran == len(methods) * len(b.CASES)


def test_committed_page_has_the_tables_the_script_writes():
    b = bench()
    text = PAGE.read_text()
    assert text.count(b.BEGIN) == 1 and text.count(b.END) == 1
    assert b.structure(text) == b.expected_structure()
    assert MACHINE.search(text)
    assert "--quick sizes" not in text.split(b.BEGIN, 1)[1].split(b.END, 1)[0]  # the full run, not the test's
