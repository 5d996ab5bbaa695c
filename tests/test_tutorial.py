"""docs/tutorial.md runs and prints what it says.

Its ```python blocks run in order in one namespace, in a temporary working directory that holds
the CalculiX beams under the relative path the tutorial reads them from; the standard output of
each block is compared with the ```text block right after it (a block without one must print
nothing). Plots go to the Agg backend, chosen here: the library never switches backends.

Printed numbers are compared by the rules of ``tests/printed.py`` (text between the numbers exactly,
round-off figures as round-off).

``python tests/test_tutorial.py`` prints each block's output; with ``--write`` it rewrites the
tutorial's text blocks with them (run it from the repository root after changing the tutorial or
the numerics, and read the diff).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

from printed import lines, output_differs

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "tutorial.md"
DATA = Path("tests") / "data" / "calculix"  # relative to the working directory, as in the tutorial
FILES = [f"beam8_{kind}_mat.{ext}" for kind in ("free", "clamped") for ext in ("sti", "mas", "dof", "inp")]

#: a python block, then (blank lines allowed) the text block of its output, if any
BLOCK = re.compile(r"^```python\n(.*?)^```\n(?:\s*\n)*(?:^```text\n(.*?)^```\n)?", re.S | re.M)


def blocks(text: str) -> list[tuple[str, str | None]]:
    """``(code, printed)`` of every python block of ``text``; printed is None where no text block follows."""
    return [(m.group(1), m.group(2)) for m in BLOCK.finditer(text)]


def run_blocks(code_blocks: list[str], workdir: Path) -> list[str]:
    """Run ``code_blocks`` in order in one namespace with ``workdir`` (holding the beams) as working
    directory; the standard output of each."""
    import matplotlib

    matplotlib.use("Agg")
    for name in FILES:
        (workdir / DATA).mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / DATA / name, workdir / DATA / name)
    namespace: dict = {"__name__": "__tutorial__"}
    outputs = []
    cwd = os.getcwd()
    os.chdir(workdir)
    try:
        for i, code in enumerate(code_blocks, 1):
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                exec(compile(code, f"docs/tutorial.md, python block {i}", "exec"), namespace)
            outputs.append(buf.getvalue())
    finally:
        os.chdir(cwd)
        import matplotlib.pyplot as plt

        plt.close("all")
    return outputs


def test_the_tutorial_runs_and_prints_its_output(tmp_path):
    found = blocks(DOC.read_text(encoding="utf-8"))
    assert len(found) >= 8, "docs/tutorial.md: fewer python blocks than its steps"
    t0 = time.perf_counter()
    outputs = run_blocks([code for code, _ in found], tmp_path)
    seconds = time.perf_counter() - t0
    failures = []
    for i, ((code, printed), out) in enumerate(zip(found, outputs), 1):
        if printed is None:
            if out.strip():
                failures.append(f"python block {i} prints, but no text block follows it:\n{out}")
            continue
        why = output_differs(printed, out)
        if why:
            failures.append(f"python block {i} ({code.splitlines()[0]!r} ...): {why}")
    assert not failures, "\n\n".join(failures) + "\n\n(regenerate: python tests/test_tutorial.py --write)"
    # what the tutorial says it wrote
    assert (tmp_path / "tutorial-plots.png").read_bytes()[:4] == b"\x89PNG"
    for name in ("beam_cb.SID_FEM", "beam_cb.exudyn.npz", "beam_cb.mat", "beam_cb.h5"):
        assert (tmp_path / name).stat().st_size > 0, name
    assert seconds < 300, f"the tutorial took {seconds:.0f} s; keep it small"


def test_the_comparison_catches_drift():
    assert output_differs("band_error 4.39e-07 at 2670.3 Hz", "band_error 4.39e-07 at 2670.3 Hz") is None
    assert output_differs("band_error 4.39e-07", "band_error 4.40e-07") is None  # rounding boundary
    assert "4.41e-07" in output_differs("band_error 4.39e-07", "band_error 4.41e-07")
    assert output_differs("100.0460 Hz", "100.0461 Hz") is None
    assert output_differs("1610.43268979 Hz", "1610.43269 Hz") is None  # 1e-6 relative
    assert output_differs("1610.4327 Hz", "1610.4370 Hz") is not None
    assert output_differs("rel. error 6.1e-12", "rel. error 4.9e-11") is None  # round-off
    assert output_differs("rel. error 6.1e-12", "rel. error 2.5e-09") is not None
    assert output_differs("static 1.3e-09", "static 3.5e-09") is None  # nearly round-off: a factor 3
    assert output_differs("static 1.3e-09", "static 4.5e-09") is not None
    assert output_differs("255 DOF", "256 DOF") == \
        "the document says 255, the run printed 256: integers differ\n  in: '256 DOF'"
    assert output_differs("judged: elastic part", "judged: full response") is not None


def _main(argv: list[str]) -> None:
    text = DOC.read_text(encoding="utf-8")
    found = blocks(text)
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["FLEXMOR_CACHE_DIR"] = str(Path(tmp) / "flexmor-cache")  # leave the user's cache alone
        t0 = time.perf_counter()
        outputs = run_blocks([code for code, _ in found], Path(tmp))
        print(f"{len(found)} blocks in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    if "--write" not in argv:
        for i, out in enumerate(outputs, 1):
            print(f"--- python block {i}\n{out}", end="")
        return
    pieces, pos = [], 0
    for m, out in zip(BLOCK.finditer(text), outputs):
        pieces.append(text[pos:m.start()])
        code_block = text[m.start():m.end(1)] + "```\n"
        pieces.append(code_block + (f"\n```text\n{lines(out)}\n```\n" if out.strip() else ""))
        if m.group(2) is None:  # the blank lines after the code block were part of the match
            pieces.append("\n")
        pos = m.end()
    DOC.write_text("".join(pieces) + text[pos:], encoding="utf-8")


if __name__ == "__main__":
    _main(sys.argv[1:])
