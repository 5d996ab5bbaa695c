#!/usr/bin/env python
"""What spinning bodies and SID load stiffening cost: flexmor's command line on a CalculiX bar, side by side.

The bar of ``tests/ccx_models.py`` (0.6 x 0.1 x 0.1 m steel) meshed with ``--n NX,NY,NZ`` cells of
``--etype`` (default C3D8 100,10,10: about 36k DOF), run through ``ccx`` (``*FREQUENCY,
SOLVER=MATRIXSTORAGE``) clamped at x = 0 and free. Each case is one ``flexmor`` process whose wall time and
peak resident memory are printed:

* clamped: ``reduce --method krylov --order R`` at ``TIP:y``, ``TIP:z``, without and with ``--spin-range
  x:0:W`` (W below the speed at which the spin softens the first bending mode to zero), its order and the
  largest frequency error of the five-speed check; ``info --campbell x:0:W:11`` of the model (6 modes) and
  of the body;
* free: Craig-Bampton at ``FIX@rbe2`` exported to SID with and without ``--no-stiffening``.

Usage::

    .venv/bin/python bench/spin.py                    # about 3 minutes
    .venv/bin/python bench/spin.py --n 20,4,4         # a quick check
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from ccx_models import CCX, deck  # noqa: E402

_CHILD = ("import resource, sys\nfrom flexmor.cli import main\ncode = main(sys.argv[1:])\n"
          "print('PEAK_KB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\nsys.exit(code)")


def _flexmor(*args) -> tuple[float, float, str]:
    """``(seconds, peak MB, stdout)`` of one ``flexmor`` process."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _CHILD, *map(str, args)], capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"flexmor {' '.join(map(str, args))} failed:\n{proc.stderr[-2000:]}")
    peak = next(float(line.split()[1]) for line in proc.stderr.splitlines() if line.startswith("PEAK_KB"))
    return seconds, peak / 1024.0, proc.stdout


def _model(folder: Path, etype: str, n, clamped: bool) -> Path:
    name = "clamped" if clamped else "free"
    text, _ = deck(etype, n, clamped=clamped, modes=2)
    (folder / f"{name}.inp").write_text(text)
    proc = subprocess.run([CCX, "-i", name], cwd=folder, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"ccx failed on {name}.inp:\n{proc.stdout[-2000:]}")
    return folder / f"{name}.sti"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", default="100,10,10", help="cells NX,NY,NZ")
    ap.add_argument("--etype", default="C3D8", choices=["C3D8", "C3D10"])
    ap.add_argument("--order", type=int, default=20)
    ap.add_argument("--speed", type=float, default=400.0, help="W of the speed range x:0:W (rad/s)")
    a = ap.parse_args()
    if CCX is None:
        sys.exit("ccx (CalculiX) is not installed")
    n = tuple(int(x) for x in a.n.split(","))
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_spin_") as tmp:
        d = Path(tmp)
        clamped, free = _model(d, a.etype, n, True), _model(d, a.etype, n, False)
        spin = f"x:0:{a.speed:g}"
        ports = ("--input", "TIP:y", "--input", "TIP:z", "--no-error", "--json", "--force")
        for label, extra in (("krylov", ()), (f"krylov --spin-range {spin}", ("--spin-range", spin))):
            s, mb, out = _flexmor("reduce", clamped, "--method", "krylov", "--order", a.order, *ports, *extra,
                                  "-o", d / ("spin.h5" if extra else "plain.h5"))
            rec = json.loads(out)
            note = f"order {rec['order']}"
            if extra:
                note += f", frequencies within {rec['spin']['check']['max_rel_error']:.1e} at five speeds"
            rows.append((label, s, mb, note))
        s, mb, _ = _flexmor("info", clamped, "--campbell", f"{spin}:11", "--modes", "6", "--json")
        rows.append(("info MODEL --campbell (11 speeds, 6 modes)", s, mb, ""))
        s, mb, _ = _flexmor("info", d / "spin.h5", "--campbell", "--json")
        rows.append(("info BODY --campbell (11 speeds)", s, mb, ""))
        _flexmor("reduce", free, "--method", "craig-bampton", "--order", 3 * a.order, "--interface", "FIX@rbe2",
                 "--input", "TIP:y", "--no-error", "--json", "-o", d / "cb.h5")
        for label, extra in (("export SID (load stiffening)", ()), ("export SID --no-stiffening",
                                                                     ("--no-stiffening",))):
            s, mb, _ = _flexmor("export", d / "cb.h5", "--model", free, "-o", d / f"cb{len(extra)}.SID_FEM", *extra)
            rows.append((label, s, mb, f"Craig-Bampton {3 * a.order} at FIX@rbe2"))
    print(f"{a.etype} bar {n[0]}x{n[1]}x{n[2]} cells (clamped at x = 0, and free)")
    print(f"{'case':48s} {'seconds':>8s} {'peak MB':>8s}  note")
    for label, s, mb, note in rows:
        print(f"{label:48s} {s:8.2f} {mb:8.0f}  {note}")


if __name__ == "__main__":
    main()
