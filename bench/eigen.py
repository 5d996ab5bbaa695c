#!/usr/bin/env python
"""Lowest eigenpairs at FE scale: block shift-invert Lanczos vs ARPACK, side by side in one run.

For the built-in clamped cantilever of about ``--size`` DOF (and optionally the free-free one),
``flexmor.linalg.eigenmodes(K, M, k, method=...)`` runs for each ``k`` with ``method='arpack'``
(``eigsh`` shift-invert, one single-vector solve per Lanczos step, the path before the block
solver) and ``method='lanczos'`` (block shift-invert Lanczos, one block solve per step). Both
factorize ``K - sigma M`` themselves (same backend), so the times include that factorization,
which is also reported alone. Accuracy: the largest relative difference of the eigenvalues of
the two methods and the largest relative residual ``||K x - lam M x|| / (|lam| ||M x||)`` of
the flexible modes.

Usage::

    python bench/eigen.py                      # ~100k DOF, k = 20 and 50
    python bench/eigen.py --size 30000 --ks 20 --free

Writes ``bench/results/eigen.json``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

HERE = pathlib.Path(__file__).resolve().parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=100000)
    ap.add_argument("--ks", default="20,50")
    ap.add_argument("--methods", default="arpack,lanczos")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--free", action="store_true", help="free-free body (six rigid-body modes)")
    ap.add_argument("--out", default=str(HERE / "results" / "eigen.json"))
    args = ap.parse_args(argv)

    import numpy as np

    from flexmor.linalg import SolverContext, available_backends, factorize
    from flexmor.linalg.eigen import default_shift, eigenmodes
    from flexmor.models import cantilever, size_for_dofs

    available_backends()
    n = size_for_dofs(args.size, clamped=not args.free)
    model = cantilever(n, clamped=not args.free)
    K, M = model.K, model.M
    sigma = default_shift(K, M)
    t0 = time.perf_counter()
    factorize((K - sigma * M).tocsr(), solver=SolverContext(args.backend), positive=True, check=False)
    t_fact = time.perf_counter() - t0
    print(f"model {model.name}: {model.n_dof} DOF, nnz(K) {K.nnz}; factorization alone {t_fact:.2f} s")
    rows = []
    head = f"{'n_dof':>8} {'k':>4} {'method':>8} {'seconds':>8} {'x':>6} {'max rel dlam':>12} {'max residual':>12}"
    print(head + "\n" + "-" * len(head))
    for k in [int(s) for s in args.ks.split(",")]:
        ref = None
        base = None
        for method in args.methods.split(","):
            t0 = time.perf_counter()
            lam, phi = eigenmodes(K, M, k, method=method, solver=SolverContext(args.backend))
            sec = time.perf_counter() - t0
            R = K @ phi - (M @ phi) * lam
            flex = lam > 1e-4 * abs(sigma)
            res = np.linalg.norm(R, axis=0) / np.maximum(np.abs(lam) * np.linalg.norm(M @ phi, axis=0), 1e-300)
            ref = lam if ref is None else ref
            base = sec if base is None else base
            dlam = float(np.max(np.abs(lam - ref) / np.maximum(np.abs(ref), abs(sigma))))
            row = {"n_dof": model.n_dof, "k": k, "method": method, "seconds": sec, "speedup": base / sec,
                   "max_rel_dlam": dlam, "max_residual": float(res[flex].max()) if flex.any() else 0.0,
                   "factor_seconds": t_fact, "model": model.name, "f_hz": list(np.sqrt(np.abs(lam)) / 2 / np.pi)}
            rows.append(row)
            print(f"{model.n_dof:>8} {k:>4} {method:>8} {sec:>8.2f} {row['speedup']:>6.2f} {dlam:>12.1e} "
                  f"{row['max_residual']:>12.1e}", flush=True)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
