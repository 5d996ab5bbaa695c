"""The plate-structure table at full size: examples/plate_structure_table.py on the 35,988-DOF structure.

    nice .venv/bin/python bench/plate_structure_table.py          # n=56: 35,988 DOF, band 1-2000 Hz, zeta 1 %
    .venv/bin/python bench/plate_structure_table.py --n 40 --band 1:3000

Runs :func:`plate_structure_table.run` (the full FRF once, then ``krylov`` 173, ``two-step`` 35/173,
``pod`` 24, ``modal`` 40 at the hole interface) with the full FRF in the disk cache, prints the
table after each method, writes ``bench/results/plate_structure_table.json`` and the figure
``bench/results/plate_structure_table.png``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _example():
    spec = importlib.util.spec_from_file_location("plate_structure_table",
                                                  ROOT / "examples" / "plate_structure_table.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=56)
    p.add_argument("--band", default="1:2000")
    p.add_argument("--zeta", type=float, default=0.01)
    p.add_argument("--pod-nodes", type=int, default=1)
    p.add_argument("--methods", default="krylov,two-step,modal,pod", help="comma-separated, in this order")
    p.add_argument("--figure", default=str(ROOT / "bench" / "results" / "plate_structure_table.png"))
    p.add_argument("--json", default=str(ROOT / "bench" / "results" / "plate_structure_table.json"))
    a = p.parse_args(argv)
    ex = _example()
    band = tuple(float(v) for v in a.band.split(":"))
    t0 = time.perf_counter()
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)

    def save(r):  # after the full FRF and after each method, so a partial run leaves its numbers
        summary = {k: v for k, v in r.items() if k not in ("freqs", "methods")}
        summary["methods"] = {k: {kk: vv for kk, vv in v.items() if kk != "rel_error"}
                              for k, v in r["methods"].items()}
        summary.update(wall_seconds=time.perf_counter() - t0, machine=platform.processor() or platform.machine(),
                       python=platform.python_version(), methods_requested=methods)
        Path(a.json).write_text(json.dumps(summary, indent=2))
        print(ex.table(r), flush=True)

    methods = [m.strip() for m in a.methods.split(",")]
    r = ex.run(a.n, band=band, zeta=a.zeta, pod_nodes=a.pod_nodes, cache=True, methods=methods, on_result=save)
    wall = time.perf_counter() - t0
    ex.plot(r, a.figure)
    print(f"total wall time {wall:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
