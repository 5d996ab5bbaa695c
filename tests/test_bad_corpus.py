"""Every malformed input in tests/data/bad/ is refused by the CLI with exit code 2 and one line.

The cases and the substring each error message must contain are listed in
tests/data/bad/MANIFEST.tsv (regenerate the files with tests/data/bad/make_corpus.py).
"""

import csv

import pytest
from helpers import DATA

from flexmor.cli import main

BAD = DATA / "bad"
with open(BAD / "MANIFEST.tsv", newline="") as _f:
    CASES = [(r["file"], r["command"], r["expect"]) for r in csv.DictReader(_f, delimiter="\t")]


def test_corpus_is_large_and_small():
    assert len(CASES) >= 30
    assert all((BAD / f).exists() for f, _, _ in CASES)
    assert max(p.stat().st_size for p in BAD.iterdir()) < 16_000


@pytest.mark.parametrize("name,command,expect", CASES, ids=[c[0] for c in CASES])
def test_bad_input_refused(name, command, expect, tmp_path, capsys):
    out = tmp_path / "out.h5"
    path = BAD / name
    if command == "info":
        argv = ["info", str(path), "--modes", "4"]
    else:
        argv = ["reduce", str(path), "--method", "modal", "--order", "2", "--input", command.split()[1],
                "-o", str(out)]
    code = main(argv)
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert code == 2, (captured.out, err)
    lines = err.splitlines()  # one error line, last; before it at most the warnings of what was read
    assert lines[-1].startswith("flexmor: error: ") and all(ln.startswith("flexmor: warning: ") for ln in lines[:-1])
    assert len(lines) <= 2, err
    assert "Traceback" not in err and name.split(".")[0] in lines[-1] and expect in lines[-1], err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
