#!/usr/bin/env python
"""A ~100k-DOF CalculiX job in the loop: generated bar, ``ccx`` run, read by flexmor, frequencies compared.

The bar of ``tests/ccx_models.py`` (0.6 x 0.1 x 0.1 m, steel, clamped at x = 0) is meshed with
``--n NX,NY,NZ`` cells of ``--etype`` (C3D8: 80,20,20 gives 107k DOF), run through ``ccx`` with
an ordinary ``*FREQUENCY`` step and ``*FREQUENCY, SOLVER=MATRIXSTORAGE``, and read back with
:func:`flexmor.io.read`. Prints the sizes, the ``ccx`` time, flexmor's read time (MB/s of the
``.sti`` + ``.mas``), the cells of ``model.mesh`` and the largest relative difference of the
lowest ``--modes`` eigenfrequencies from CalculiX's ``.dat`` (CalculiX prints 7 digits).

Usage::

    .venv/bin/python bench/ccx_large.py                 # 107k DOF, several minutes of ccx
    .venv/bin/python bench/ccx_large.py --n 20,5,5      # a quick check
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from ccx_models import CCX, dat_frequencies, deck  # noqa: E402


def main() -> None:
    from flexmor.io import read
    from flexmor.linalg import eigenmodes

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", default="80,20,20", help="cells NX,NY,NZ")
    ap.add_argument("--etype", default="C3D8", choices=["C3D8", "C3D20R", "C3D10"])
    ap.add_argument("--modes", type=int, default=10)
    ap.add_argument("--keep", help="folder for the job files (default: a temporary one)")
    a = ap.parse_args()
    if CCX is None:
        sys.exit("ccx (CalculiX) is not installed")
    n = tuple(int(x) for x in a.n.split(","))
    text, ids = deck(a.etype, n, clamped=True, modes=a.modes)
    d = Path(a.keep or tempfile.mkdtemp(prefix="ccx_large_"))
    d.mkdir(parents=True, exist_ok=True)
    (d / "bar.inp").write_text(text)
    t0 = time.perf_counter()
    proc = subprocess.run([CCX, "-i", "bar"], cwd=d, capture_output=True, text=True)
    t_ccx = time.perf_counter() - t0
    if proc.returncode != 0 or not (d / "bar.sti").exists():
        sys.exit(f"ccx failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    mb = sum((d / f"bar{s}").stat().st_size for s in (".sti", ".mas")) / 1e6
    t0 = time.perf_counter()
    model = read(d / "bar.sti")
    t_read = time.perf_counter() - t0
    lam, _ = eigenmodes(model.K, model.M, a.modes)
    f = np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)
    ref = dat_frequencies(d / "bar.dat")[:a.modes]
    cells = {b.type: len(b.nodes) for b in model.mesh.blocks} if model.mesh else {}
    print(f"{a.etype} bar {n}: {ids.size} nodes, {model.n_dof} DOF, K nnz {model.K.nnz}, mesh {cells}")
    print(f"ccx {t_ccx:.1f} s; read {t_read:.2f} s for {mb:.1f} MB of .sti/.mas ({mb / t_read:.0f} MB/s)")
    print(f"lowest {a.modes} frequencies (Hz): {np.array2string(f, precision=2)}")
    print(f"max relative difference from CalculiX's .dat: {np.max(np.abs(f - ref) / ref):.2e}")
    if not a.keep:
        shutil.rmtree(d)


if __name__ == "__main__":
    main()
