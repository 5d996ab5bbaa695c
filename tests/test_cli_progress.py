"""Progress of long steps: lines on stderr under -v (stderr is not a terminal here), none
under --json, and stdout unchanged."""

import json

import pytest
from helpers import CLAMPED

from flexmor.analysis.compare import FullResponse
from flexmor.cli import main
from flexmor.io import read
from flexmor.linalg.context import SolverContext, step, track
from flexmor.ports import make_ports

REDUCE = ["reduce", CLAMPED, "--input", "TIP:z", "--rayleigh", "0:1e-5", "--full-frf", "dense", "--no-cache",
          "--force"]


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out, out.err


def progress_lines(err):
    return [line for line in err.splitlines() if not line.startswith(("INFO", "DEBUG", "WARNING"))]


def test_dense_path_and_tol_search_show_their_steps_under_verbose(capsys, tmp_path):
    out = tmp_path / "b.h5"
    _, err = run(capsys, "-v", *REDUCE, "--method", "modal", "--tol", "1e-3", "-o", out)
    lines = progress_lines(err)
    assert "dense eigendecomposition (270 DOF) ..." in lines
    assert any(line.startswith("dense eigendecomposition (270 DOF): ") and line.endswith(" s") for line in lines)
    tried = [line for line in lines if line.startswith("tol search: modal order ") and "band_error" in line]
    assert len(tried) >= 2 and all(line.endswith(" s") for line in tried)
    assert f"read {CLAMPED} ..." in lines


@pytest.mark.slow
def test_quiet_without_verbose_off_a_terminal(capsys, tmp_path):
    _, err = run(capsys, *REDUCE, "--method", "modal", "--tol", "1e-3", "-o", tmp_path / "b.h5")
    assert progress_lines(err) == []


@pytest.mark.slow
def test_json_stays_one_object_and_shows_no_progress(capsys, tmp_path):
    argv = [*REDUCE, "--method", "modal", "--tol", "1e-3", "-o", tmp_path / "b.h5", "--json"]
    plain, _ = run(capsys, *argv)
    out, err = run(capsys, "-v", *argv)
    assert progress_lines(err) == []
    a, b = json.loads(plain), json.loads(out)
    for res in (a, b):
        res.pop("timings")
        res.pop("seconds")
        res["grid"].pop("seconds")
        res["grid"].pop("timings")
        res["info"].pop("seconds", None)
        res["info"].pop("timings")
    assert a == b


@pytest.mark.slow
def test_library_steps_reach_the_callback():
    seen = []

    def progress(it, total, desc=None):
        seen.append((desc, total))
        return it

    model = read(CLAMPED).with_rayleigh(0.0, 1e-5)
    ports = make_ports(model, ["TIP:z"], ["TIP:z"])
    FullResponse(model, ports, (1.0, 1000.0), path="dense", cache=False,
                 solver=SolverContext(progress=progress))
    assert ("dense eigendecomposition (270 DOF)", None) in seen
    assert list(track(None, [1, 2], 2, "x")) == [1, 2]
    with step(None, "y") as note:
        note["result"] = "ok"
