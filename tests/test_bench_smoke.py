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
    # krylov: one factorization per expansion point; the default single point passes its check here
    # (estimated band error 2.8e-9), so one factorization, as with the point given explicitly
    assert m["krylov"]["order"] == 36 and m["krylov"]["factorizations"] == 1
    assert m["krylov-1pt"]["order"] == 36 and m["krylov-1pt"]["factorizations"] == 1
    assert m["krylov-1pt"]["solve_columns"] >= 36
    for v in m.values():
        assert v["ratio"] >= 1.0 and v["solver_s"] > 0 and v["peak_mb"] > 0
    assert "krylov-1pt r=36" in proc.stdout
