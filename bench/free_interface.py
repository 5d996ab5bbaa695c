#!/usr/bin/env python
"""Craig-Bampton, Craig-Chang and Herting side by side at equal order on the free plate structure held at its hole.

The plate-rods-plate solid (``flexmor.models.plate_structure(n, lower="mass")``) is free; its hole's wall is
tied by an RBE2 to a master node (``HOLE@rbe2``, the interface of all three methods). Inputs: the master's six
directions and the top corner's z; band 1-2000 Hz; Rayleigh damping D = 2e-6 K. Each body is judged by one
full FRF (:class:`flexmor.System`): band error, the mounted check (held clamped and pinned at the master: the
largest frequency error of the held modes up to 2 kHz, and the static error under the frame's six
accelerations and the inputs) and the seconds of its basis and projection.

Usage::

    .venv/bin/python bench/free_interface.py                 # n = 16, orders 20 30 40
    .venv/bin/python bench/free_interface.py --n 12 --orders 16,24
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=16, help="plate_structure size (default 16)")
    ap.add_argument("--orders", default="20,30,40", help="orders, comma-separated")
    args = ap.parse_args(argv)

    import flexmor
    from flexmor.damping import Rayleigh
    from flexmor.models import plate_structure

    model = plate_structure(args.n, lower="mass")
    top = model.node_sets["TOP"]
    corner = int(top[np.argmax(model.node_xyz(top) @ [1.0, 1.0, 0.0])])
    system = flexmor.System(model, inputs=[f"HOLE@rbe2:{d}" for d in ("x", "y", "z", "rx", "ry", "rz")]
                            + [f"{corner}:z"], interfaces=["HOLE@rbe2"], band=(1, 2000),
                            damping=Rayleigh(0.0, 2e-6), cache=False)
    print(f"plate_structure({args.n}, lower='mass'), free, HOLE@rbe2: {system.model.n_dof} DOF, band 1-2000 Hz\n")
    print("| method | order | band_error | mounted freq error | mounted static error | seconds |")
    print("|---|---|---|---|---|---|")
    for order in (int(o) for o in args.orders.split(",")):
        for method in ("craig-bampton", "craig-chang", "herting"):
            body, rec = system.reduce_and_judge(method, order)
            m = rec["mounted"]
            print(f"| {method} | {body.order} | {rec['band_error']:.2e} | {m['max_frequency_error']:.2e} | "
                  f"{m['max_static_error']:.2e} | {rec['seconds']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
