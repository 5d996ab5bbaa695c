#!/usr/bin/env python
"""Sparse times dense side by side: SciPy's product, its rows over threads, MKL's sparse BLAS.

For ``K`` and ``M`` of the built-in plate structure (``plate_structure(56)``, 35,988 DOF) and the
cantilever (27,000 DOF), and of the CalculiX C3D10 bar export when it is there
(``bench/results/c3d10_20x8x8_clamped``, made by ``around_methods.py``), ``A @ X`` with ``X`` of
6 columns in Fortran order (a Krylov or Lanczos block) and of 174 columns in C order (a basis in
the projection): SciPy's ``A @ X`` (one thread), :func:`flexmor.linalg.threads.sparse_dense` with the
rows split over Python threads (``threads=cores``), and :func:`flexmor.linalg.mkl_sparse.mkl_product`
(MKL's threads), best of ``--repeat``; the largest difference to SciPy's product relative to its
largest entry. ``--large 1000000`` adds the built-in cantilever of a million DOF. Results:
``bench/results/sparse_products.json``.

Usage::

    .venv/bin/python bench/sparse_products.py
    .venv/bin/python bench/sparse_products.py --large 1000000 --repeat 2
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _models(large: int):
    import flexmor
    from flexmor.errors import FlexmorWarning
    from flexmor.models import cantilever, plate_structure, size_for_dofs

    yield "plate 35,988", plate_structure(56)
    yield "cantilever 27,000", cantilever(size_for_dofs(27000))
    sti = HERE / "results" / "c3d10_20x8x8_clamped" / "bar.sti"
    if sti.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlexmorWarning)
            yield "C3D10 bar 34,680", flexmor.read(sti)
    if large:
        model = cantilever(size_for_dofs(large))
        yield f"cantilever {model.n_dof:,}", model


def _best(fn, repeat: int) -> tuple[float, np.ndarray]:
    fn()
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--large", type=int, default=0, help="also the built-in cantilever of about this many DOF")
    ap.add_argument("--out", default=str(HERE / "results" / "sparse_products.json"))
    args = ap.parse_args(argv)
    from flexmor.linalg.mkl_sparse import mkl_product
    from flexmor.linalg.threads import cores, sparse_dense

    rng = np.random.default_rng(0)
    rows = []
    print(f"{'model':20s} {'A':2s} {'nnz':>9s} {'cols':>4s} {'scipy s':>9s} {'threads s':>9s} {'mkl s':>9s} "
          f"{'x scipy':>7s} {'rel diff':>8s}   (load {os.getloadavg()[0]:.2f})")
    for name, model in _models(args.large):
        for label, A in (("K", model.K.tocsr()), ("M", model.M.tocsr())):
            for cols, order in ((6, "F"), (174, "C")):
                X = np.asarray(rng.standard_normal((A.shape[0], cols)), order=order)
                t_sp, ref = _best(lambda A=A, X=X: A @ X, args.repeat)
                t_th, _ = _best(lambda A=A, X=X: sparse_dense(A, X, cores()), args.repeat)
                if mkl_product(A, X) is None:
                    t_mkl, diff = float("nan"), float("nan")
                else:
                    t_mkl, Y = _best(lambda A=A, X=X: mkl_product(A, X), args.repeat)
                    diff = float(np.abs(Y - ref).max() / np.abs(ref).max())
                rows.append({"model": name, "matrix": label, "nnz": int(A.nnz), "columns": cols, "scipy_s": t_sp,
                             "threads_s": t_th, "mkl_s": t_mkl, "rel_diff": diff})
                print(f"{name:20s} {label:2s} {A.nnz:9d} {cols:4d} {t_sp:9.4f} {t_th:9.4f} {t_mkl:9.4f} "
                      f"{t_sp / t_mkl:7.1f} {diff:8.1e}", flush=True)
    out = {"python": sys.version.split()[0], "machine": platform.processor() or platform.machine(),
           "cores": cores(), "load": os.getloadavg()[0], "date": time.strftime("%Y-%m-%d %H:%M"), "rows": rows}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
