"""Benchmark of the error evaluation (full FRF over a band + band_error) on a large built-in model.

    .venv/bin/python bench/frf.py                       # hex27 cantilever, ~35k DOF, ~40 resonances
    .venv/bin/python bench/frf.py --dofs 35000 --fmax 15000 --direct-checks 20 --per-freq scipy,pardiso

Steps (each timed):

1. per-frequency cost of one complex symmetric factorization + block solve of
   ``K - w^2 M + i w D`` with each backend in ``--per-freq`` (3 frequencies each);
2. :class:`flexmor.analysis.compare.FullResponse` with ``path="surrogate"`` (modal pre-pass,
   verified surrogate, adaptive grid), no disk cache, then ``evaluate`` of several reduced
   bodies (``band_error``): the time a user waits for the error of a reduction;
3. agreement with direct solves: at ``--direct-checks`` grid points spread over the band (and
   at the resonances) the full model is solved directly with PARDISO and compared pointwise
   with the surrogate FRF; the band_error of each reduced body is recomputed with the direct
   FRF at those points replacing the surrogate's (a partial brute force);
4. with ``--brute`` the complete direct sweep on the same adaptive grid (one factorization
   per point; long: ~ n_points x step 1) and the band_errors from it.

Results go to ``bench/results/frf.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from flexmor.analysis.compare import FullResponse
from flexmor.analysis.frequency import band_error
from flexmor.damping import band_matched
from flexmor.dynamics.frf import ShiftedMatrices, frf_full, frf_reduced
from flexmor.jsonutil import jsonable
from flexmor.linalg import SolverContext, available_backends, factorize
from flexmor.models import cantilever, size_for_dofs
from flexmor.ports import make_ports
from flexmor.reduction import reduce


def _cpu() -> float:
    """User + system CPU seconds of this process (all threads)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _peak_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def per_frequency(model, ports, backends, freqs):
    S = ShiftedMatrices(model.K, model.M, model.D)
    B = ports.B.toarray()
    rows = []
    for be in backends:
        for f in freqs:
            t0 = time.perf_counter()
            A = S(2 * np.pi * f)
            F = factorize(A, be, check=False)
            t1 = time.perf_counter()
            X = F.solve(B)
            t2 = time.perf_counter()
            res = float(np.linalg.norm(A @ X - B) / np.linalg.norm(B))
            rows.append({"backend": be, "freq_hz": f, "factor_s": t1 - t0, "solve_s": t2 - t1, "residual": res})
            print(f"  {be:8s} {f:9.1f} Hz  factor {t1 - t0:6.2f} s  block solve ({B.shape[1]} rhs) {t2 - t1:5.2f} s  "
                  f"residual {res:.1e}", flush=True)
            del F
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dofs", type=int, default=35000)
    ap.add_argument("--element", default="hex27")
    ap.add_argument("--fmin", type=float, default=10.0)
    ap.add_argument("--fmax", type=float, default=15000.0)
    ap.add_argument("--zeta", type=float, default=0.01, help="modal damping (Rayleigh, exact at band ends)")
    ap.add_argument("--per-freq", default="scipy,pardiso", help="backends timed per frequency")
    ap.add_argument("--direct-checks", type=int, default=16)
    ap.add_argument("--brute", action="store_true", help="complete direct sweep on the adaptive grid")
    ap.add_argument("--bodies", default="modal:10,modal:20,modal:30,craig-bampton:23",
                    help="reduced bodies METHOD:ORDER (craig-bampton with interface TIP_CENTER)")
    ap.add_argument("--skip-direct", action="store_true",
                    help="skip step 3 (complex factorizations; a million DOF do not fit next to the model)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "frf.json"))
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    n = size_for_dofs(args.dofs, element=args.element)
    model = cantilever(n, element=args.element)
    band = (args.fmin, args.fmax)
    model = model.with_damping(band_matched(args.zeta, band))
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    t_build = time.perf_counter() - t0
    print(f"{model.name}: {model.n_dof} DOF, nnz(K) {model.K.nnz}, band {band[0]:g}-{band[1]:g} Hz, "
          f"Rayleigh {model.damping}, built in {t_build:.1f} s", flush=True)
    out = {"model": model.summary(), "band_hz": band, "machine": platform.processor() or platform.machine(),
           "backends": available_backends()}

    print("1. one frequency: complex factorization + block solve", flush=True)
    out["per_frequency"] = per_frequency(model, ports, [b for b in args.per_freq.split(",") if b],
                                         [band[1] * 0.05, band[1] * 0.5, band[1] * 0.95])

    print("2. error evaluation: FullResponse (surrogate path, no cache) + band_error", flush=True)
    solver = SolverContext()
    t0, cpu0 = time.perf_counter(), _cpu()
    full = FullResponse(model, ports, band, path="surrogate", cache=False, solver=solver)
    t_full, cpu_full = time.perf_counter() - t0, _cpu() - cpu0
    jobs = [(m, int(r), {"interface": ["TIP_CENTER"]} if m == "craig-bampton" else {})
            for m, r in (b.split(":") for b in args.bodies.split(","))]
    bodies, t_red = [], 0.0
    for method, order, opts in jobs:
        t1 = time.perf_counter()
        bodies.append(reduce(model, method, order, ports, **opts))
        t_red += time.perf_counter() - t1
    t1 = time.perf_counter()
    errs = [full.evaluate(b).band_error for b in bodies]
    t_eval = time.perf_counter() - t1
    g = full.summary()
    print(f"  grid {g['n_points']} points ({g['n_initial']} initial, {g['rounds']} rounds, tol {g['tol']:g}, "
          f"converged {g['converged']}), {g['n_resonances']} resonances in the band")
    print(f"  surrogate order {g['surrogate']['order']}, {g['surrogate']['n_checks']} checks "
          f"({g['surrogate']['final_check']['solver']}), "
          f"max check error {g['surrogate']['max_check_error']:.1e}, verified {g['surrogate']['verified']}")
    print(f"  full FRF {t_full:.1f} s (pre-pass {full.timings['prepass']:.1f} s, surrogate + grid "
          f"{full.timings['sweep']:.1f} s; CPU {cpu_full:.1f} s, peak RSS {_peak_mb():.0f} MB), "
          f"{solver.stats.count} factorizations; "
          f"band_error of {len(bodies)} bodies {t_eval:.2f} s", flush=True)
    out["full"] = dict(g, seconds_total=t_full, cpu_seconds=cpu_full, peak_mb=_peak_mb(), seconds_evaluate=t_eval, seconds_reduce=t_red,
                       band_errors={f"{m}-{r}": e for (m, r, _), e in zip(jobs, errs)})

    if args.skip_direct:
        print("3. skipped", flush=True)
    else:
        _direct_checks(args, model, ports, full, bodies, errs, out)
    _fine_grid(band, full, bodies, errs, out)
    if args.brute:
        print(f"4. brute force: direct sweep on all {full.freqs.size} grid points", flush=True)
        t1 = time.perf_counter()
        Hb = frf_full(model, ports, full.freqs)
        t_b = time.perf_counter() - t1
        brute = [band_error(full.freqs, Hb, frf_reduced(b, full.freqs)) for b in bodies]
        agree_b = [abs(a / b - 1) for a, b in zip(errs, brute)]
        print(f"  {t_b:.0f} s; band_error relative difference max {max(agree_b):.1e}", flush=True)
        out["brute"] = {"seconds": t_b, "band_errors": brute, "rel_diff": agree_b}
    for (m, r, _), e in zip(jobs, errs):
        print(f"  {m:14s} r={r:3d}  band_error {e:.3e}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(jsonable(out, finite=True), indent=1))
    print(f"results in {args.out}")


def _direct_checks(args, model, ports, full, bodies, errs, out):
    print(f"3. direct checks at {args.direct_checks} grid points + the resonances", flush=True)
    idx = np.unique(np.concatenate([np.linspace(0, full.freqs.size - 1, args.direct_checks).astype(int),
                                    np.searchsorted(full.freqs, full.resonances).clip(0, full.freqs.size - 1)]))
    t1 = time.perf_counter()
    Hd = frf_full(model, ports, full.freqs[idx])
    t_chk = time.perf_counter() - t1
    pt = np.linalg.norm((Hd - full.H[idx]).reshape(idx.size, -1), axis=1) / np.linalg.norm(Hd.reshape(idx.size, -1), axis=1)
    H_mixed = full.H.copy()
    H_mixed[idx] = Hd
    mixed = [band_error(full.freqs, H_mixed, frf_reduced(b, full.freqs)) for b in bodies]
    agree = [abs(a / b - 1) for a, b in zip(errs, mixed)]
    print(f"  {idx.size} direct solves in {t_chk:.1f} s ({t_chk / idx.size:.2f} s each): pointwise "
          f"||H - H_s||/||H|| max {pt.max():.1e}, median {np.median(pt):.1e}; band_error change "
          f"max {max(agree):.1e}", flush=True)
    out["direct_checks"] = {"n": int(idx.size), "seconds": t_chk, "max_rel_diff": float(pt.max()),
                            "median_rel_diff": float(np.median(pt)), "band_error_rel_change": agree}


def _fine_grid(band, full, bodies, errs, out):
    print("3b. adaptive grid vs a fine uniform-plus-peaks grid (both with the verified surrogate)", flush=True)
    fk, zk = full.resonances, full.zeta
    peaks = (fk[:, None] * (1 + np.linspace(-20, 20, 801)[None, :] * zk[:, None])).ravel()
    fine = np.unique(np.concatenate([np.linspace(*band, 200_001), peaks]))
    fine = fine[(fine >= band[0]) & (fine <= band[1])]
    t1 = time.perf_counter()
    Hf = full.surrogate.frf(fine)
    fine_errs = [band_error(fine, Hf, frf_reduced(b, fine)) for b in bodies]
    agree_f = [abs(a / b - 1) for a, b in zip(errs, fine_errs)]
    print(f"  {fine.size} points in {time.perf_counter() - t1:.1f} s; band_error relative difference "
          f"max {max(agree_f):.1e}", flush=True)
    out["fine_grid"] = {"n_points": int(fine.size), "band_errors": fine_errs, "rel_diff": agree_f}


if __name__ == "__main__":
    main()
