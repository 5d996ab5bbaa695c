"""Full-FRF cost of small and mid-size models: sparse sweep vs the dense path, as factorizations.

    .venv/bin/python bench/small_frf.py                      # 540, 3,000 DOF (+ --dofs 27000)
    .venv/bin/python bench/small_frf.py --dofs 540 3000 27000 --sweep-points 40

For each built-in cantilever (Rayleigh 0 / 1e-6, inputs and outputs TIP:y, TIP:z, band 1-5000 Hz):

1. one sparse complex factorization + block solve of ``K - w^2 M + i w D`` (median of 3): the unit;
2. the dense path: :class:`flexmor.dynamics.dense_frf.DenseResolvent` (one dense eigendecomposition)
   plus the FRF on the grid, skipped above ``--dense-max`` DOF;
3. :class:`flexmor.analysis.compare.FullResponse` with ``path="dense"`` (where it applies) and
   the grid size ``n_points``; the sparse sweep's cost is ``n_points`` factorizations
   (measured on ``--sweep-points`` of them, extrapolated), plus the modal pre-pass;
4. ``FullResponse`` with ``path="surrogate"`` (modal pre-pass, verified projection), its
   time and its largest relative difference from the dense FRF on the grid.

Every time is also given as a ratio to the unit of step 1, which is what carries over between
machines and loads. Results go to ``bench/results/small_frf.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from flexmor.analysis.compare import FullResponse
from flexmor.dynamics.dense_frf import DenseResolvent
from flexmor.dynamics.frf import ShiftedMatrices, frf_full
from flexmor.jsonutil import jsonable
from flexmor.linalg import SolverContext, factorize
from flexmor.models import cantilever, size_for_dofs
from flexmor.ports import make_ports


def unit_factorization(model, ports) -> float:
    """Median seconds of one complex factorization + block solve at 3 frequencies."""
    A = ShiftedMatrices(model.K, model.M, model.D)
    B = ports.B.toarray()
    times = []
    for f in (100.0, 1000.0, 3000.0):
        t = time.perf_counter()
        F = factorize(A(2 * np.pi * f), solver=SolverContext(), symmetric=True, check=False)
        F.solve(B)
        del F
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def run(dofs: int, band, dense_max: int, sweep_points: int) -> dict:
    model = cantilever(n=size_for_dofs(dofs)).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    out = {"n_dof": model.n_dof, "load_before": os.getloadavg()[0]}
    unit = out["factorization_s"] = unit_factorization(model, ports)
    if model.n_dof <= dense_max:
        t = time.perf_counter()
        full = FullResponse(model, ports, band, path="dense", cache=False)
        out["dense_full_frf_s"] = time.perf_counter() - t
        out["n_points"] = int(full.freqs.size)
        out["dense_in_factorizations"] = out["dense_full_frf_s"] / unit
        freqs = full.freqs
    else:
        full = FullResponse(model, ports, band, path="surrogate", cache=False)
        freqs = full.freqs
        out["n_points"] = int(freqs.size)
    t = time.perf_counter()
    sur = FullResponse(model, ports, band, path="surrogate", cache=False)
    out["surrogate_full_frf_s"] = time.perf_counter() - t
    out["surrogate_in_factorizations"] = out["surrogate_full_frf_s"] / unit
    if model.n_dof <= dense_max:
        Hs = sur.surrogate.frf(freqs)
        out["max_rel_diff_surrogate_vs_dense"] = float(np.max(
            np.linalg.norm((Hs - full.H).reshape(freqs.size, -1), axis=1)
            / np.linalg.norm(full.H.reshape(freqs.size, -1), axis=1)))
    sample = freqs[np.linspace(0, freqs.size - 1, min(sweep_points, freqs.size)).astype(int)]
    t = time.perf_counter()
    H_direct = frf_full(model, ports, sample)
    per_point = (time.perf_counter() - t) / sample.size
    out["sweep_s_estimate"] = per_point * freqs.size
    out["sweep_in_factorizations"] = out["sweep_s_estimate"] / unit
    if model.n_dof <= dense_max:
        res = DenseResolvent(model.K, model.M, model.D)
        H_dense = res.frf(2 * np.pi * sample, ports.B.toarray(), ports.C)
        out["max_rel_diff_dense_vs_direct"] = float(np.max(
            np.linalg.norm((H_dense - H_direct).reshape(sample.size, -1), axis=1)
            / np.linalg.norm(H_direct.reshape(sample.size, -1), axis=1)))
        out["speedup"] = out["sweep_s_estimate"] / out["dense_full_frf_s"]
    out["load_after"] = os.getloadavg()[0]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dofs", type=int, nargs="+", default=[540, 3000])
    p.add_argument("--band", default="1:5000")
    p.add_argument("--dense-max", type=int, default=6000, help="largest model given the dense path")
    p.add_argument("--sweep-points", type=int, default=40, help="grid points solved directly to time the sweep")
    args = p.parse_args()
    band = tuple(float(x) for x in args.band.split(":"))
    rows = []
    for d in args.dofs:
        rows.append(run(d, band, args.dense_max, args.sweep_points))
        print(json.dumps(jsonable(rows[-1])), flush=True)
    path = Path(__file__).parent / "results" / "small_frf.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(jsonable({"band_hz": band, "rows": rows}), indent=1))


if __name__ == "__main__":
    main()
