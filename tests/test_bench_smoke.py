"""Smoke run of ``bench/scale.py`` (the full benchmark is not part of the suite): tiny model, same code."""

import json
import subprocess
import sys

from helpers import ROOT


def test_scale_benchmark_smoke_run(tmp_path):
    out = tmp_path / "scale.json"
    cmd = [sys.executable, str(ROOT / "bench" / "scale.py"), "--sizes", "3000", "--methods",
           "modal,krylov,krylov-1pt", "--order", "12", "--order-krylov", "36", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    (row,) = json.loads(out.read_text())
    assert row["n_dof"] == 3000 and row["backend"]
    m = row["methods"]
    assert m["modal"]["order"] in (12, 13) and m["modal"]["factorizations"] == 1  # 13: a bending pair kept whole
    # krylov: one factorization per expansion point and two for the estimate of its default points
    assert m["krylov"]["order"] == 36 and m["krylov"]["factorizations"] == m["krylov"]["n_points"] + 2 >= 4
    assert m["krylov-1pt"]["order"] == 36 and m["krylov-1pt"]["factorizations"] == 1
    assert m["krylov-1pt"]["solve_columns"] >= 36
    for v in m.values():
        assert v["ratio"] >= 1.0 and v["solver_s"] > 0 and v["peak_mb"] > 0
    assert "krylov-1pt r=36" in proc.stdout


def test_around_methods_smoke_run(tmp_path):
    """bench/around_methods.py on tiny models: every part but the CalculiX read runs and records its ratios;
    the whole krylov reduce makes one factorization (the rigid-body check's, shared)."""
    out = tmp_path / "around.json"
    cmd = [sys.executable, str(ROOT / "bench" / "around_methods.py"), "--parts", "krylov,busy,free", "--models",
           "cantilever,plate", "--cantilever-dofs", "3000", "--plate-n", "8", "--order", "24", "--busy-n", "8",
           "--methods", "krylov,craig-bampton", "--free-n", "8", "--free-order", "16", "--repeat", "1",
           "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stderr
    parts = json.loads(out.read_text())["parts"]
    for row in parts["krylov"]:
        assert "error" not in row, row
        assert row["factorizations"] == 1 and row["order"] == 24 and row["ratio"] > 1.0
        # the floor: the bare work plus one Gram-Schmidt pass and the projection's products, timed
        assert row["floor_gram_schmidt_s"] > 0 and row["floor_projection_s"] > 0 and row["floor_ratio_r"] > 1.0
    assert {r["method"] for r in parts["busy"]} == {"krylov", "craig-bampton"}
    assert all(r["ratio"] > 0 for r in parts["busy"])
    free = {r["method"]: r for r in parts["free"]}
    assert set(free) == {"krylov", "craig-bampton", "cms-krylov", "cms-gramian"}
    assert free["craig-bampton"]["factorizations"] == 1
