"""Every fenced code block of the README and the docs is run by a test or says why not.

The convention (docs/contributing.md, "Documents that run"): a block no test runs has, on the line right
before its opening fence, ``<!-- not run: REASON -->``. The blocks the tests run are taken from those
tests' own parsers, so a block they stop running (a renamed section, a moved intro line) is found here:

* tests/test_readme_tour.py ``tour_blocks``: the README's tour, its exports and the quoted compare output;
* tests/test_study.py ``readme_python_section``: the README's "## Python" blocks and their quoted output;
* tests/test_tutorial.py ``blocks``: docs/tutorial.md's python blocks and the text blocks of their output.
"""

from __future__ import annotations

import re
from pathlib import Path

import test_readme_tour
import test_study
import test_tutorial

ROOT = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"^<!-- not run: (?P<reason>.*?)\s*-->$")
FENCE = re.compile(r"^```")


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "examples" / "data" / "README.md"]


def fenced_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """``(line number of the opening fence, body, marker line or None)`` of each fenced block of ``text``."""
    out, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        if FENCE.match(lines[i]):
            start = i
            i += 1
            while i < len(lines) and lines[i].rstrip() != "```":
                i += 1
            if i == len(lines):
                raise AssertionError(f"line {start + 1}: a code block that is never closed")
            before = lines[start - 1] if start > 0 else ""
            out.append((start + 1, "\n".join(lines[start + 1:i]), before if before.startswith("<!--") else None))
        i += 1
    return out


def run_bodies() -> dict[str, set[str]]:
    """The bodies of the blocks the tests run, by document name (relative to the repository root)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    code, printed = test_study.readme_python_section(readme)
    tutorial = test_tutorial.blocks(test_tutorial.DOC.read_text(encoding="utf-8"))
    norm = _norm
    return {
        "README.md": {norm(b) for b in [*test_readme_tour.tour_blocks(readme).values(), *code, printed]},
        "docs/tutorial.md": {norm(b) for pair in tutorial for b in pair if b is not None},
    }


def _norm(body: str) -> str:
    return "\n".join(line.rstrip() for line in body.strip("\n").splitlines())


def problems(name: str, text: str, run: set[str]) -> list[str]:
    """What is wrong with the code blocks of the document ``name``: blocks neither run nor marked, markers
    without a reason, marked blocks that a test runs."""
    found = []
    for line, body, marker in fenced_blocks(text):
        is_run = _norm(body) in run
        m = MARKER.match(marker) if marker else None
        if marker and not m:
            found.append(f"{name}:{line - 1}: a comment before the block that is not '<!-- not run: REASON -->'")
        elif m and len(m.group("reason").split()) < 2:
            found.append(f"{name}:{line - 1}: '<!-- not run: ... -->' without a reason")
        elif m and is_run:
            found.append(f"{name}:{line}: marked 'not run', but a test runs this block")
        elif not m and not is_run:
            first = body.splitlines()[0] if body else ""
            found.append(f"{name}:{line}: a code block no test runs and no '<!-- not run: REASON -->' marks "
                         f"({first[:60]!r})")
    return found


def test_every_code_block_is_run_or_marked():
    run = run_bodies()
    assert all(run.values()), "a runner found no blocks: its parser and the document disagree"
    found = []
    for path in documents():
        name = path.relative_to(ROOT).as_posix()
        found += problems(name, path.read_text(encoding="utf-8"), run.get(name, set()))
    assert not found, "\n".join(found) + "\n(the convention: docs/contributing.md, 'Documents that run')"


def test_the_check_finds_an_unmarked_block():
    text = ("run:\n```\nflexmor info a.sti\n```\n"
            "<!-- not run: needs MPI ranks -->\n```\nmpirun -n 2 flexmor\n```\n"
            "plain:\n```python\nprint(1)\n```\n"
            "<!-- not run: -->\n```\nx\n```\n"
            "<!-- not run: serves until stopped -->\n```\nflexmor info a.sti\n```\n")
    found = problems("doc.md", text, {"flexmor info a.sti"})
    assert len(found) == 3, found
    assert found[0].startswith("doc.md:10: a code block no test runs") and "print(1)" in found[0]
    assert found[1] == "doc.md:13: '<!-- not run: ... -->' without a reason"
    assert found[2] == "doc.md:18: marked 'not run', but a test runs this block"


def test_the_pictures_of_the_readme_are_there_and_small():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    first_screen = readme.split("\n## ", 1)[0]
    pictures = re.findall(r"!\[[^]]+\]\(([^)]+\.png)\)", first_screen)
    assert pictures, "the README's first screen shows no picture"
    for picture in re.findall(r"!\[[^]]+\]\(([^)]+\.png)\)", readme):
        data = (ROOT / picture).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) < 200_000, (picture, len(data))
    # the first screen: what flexmor is, the two set-up commands, and where to go next
    assert first_screen.index("flexmor turns") < first_screen.index("make demo")
    for link in ("docs/tutorial.md", "docs/contributing.md"):
        assert f"]({link})" in first_screen and (ROOT / link).exists(), link
    for development in ("make lint", "make lock", "test-mpi", "test-arith", "markers"):
        assert development not in first_screen, development
