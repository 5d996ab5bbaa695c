"""``--select NAME=KIND:NUMBERS`` on the command line: named node sets for ports, interfaces and couplings."""

from __future__ import annotations

import json

import pytest
from helpers import CLAMPED, FREE

from flexmor.cli import main
from flexmor.io import read_body

RING = "RING=cylinder:0,0.05,0.05,1,0,0,0.05,1e-9,0.45,0.55"


def test_info_lists_the_selected_set(capsys):
    assert main(["info", CLAMPED, "--select", "TIPX=plane:1,0,0,1,0,0",
                 "--select", "MID=nearest:0.5,0.05,0.05", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["node_sets"]["TIPX"] == 9 and out["node_sets"]["MID"] == 1


@pytest.mark.slow
def test_reduce_with_a_selected_hole_coupled_by_rbe2(tmp_path, capsys):
    out = tmp_path / "ring.h5"
    code = main(["reduce", FREE, "--method", "craig-bampton", "--order", "10", "--select", RING,
                 "--interface", "RING@rbe2", "--input", "RING@rbe2:y", "--no-error", "-o", str(out), "--json"])
    assert code == 0, capsys.readouterr().err
    red = read_body(out)
    assert red.selections == [RING] and red.couplings == ["RING@rbe2"]
    assert red.input_names == ["RING@rbe2:y"] and red.B.shape == (10, 1)


def test_bad_selection_exits_2(capsys):
    code = main(["info", FREE, "--select", "HOLE=cylinder:0,0,0,1,0,0,0.5"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "selects no node" in err and "beam8_free_mat.sti" in err
