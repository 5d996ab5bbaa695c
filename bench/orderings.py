#!/usr/bin/env python
"""PARDISO's analysis with and without weighted matching, and with an ordering reused, side by side.

For ``K - w^2 M`` (real symmetric indefinite) and ``K - w^2 M + i w D`` (complex symmetric) of each
model, at a shift near the 8th eigenvalue, between the 7th and 8th, and just above the 12th, three
ways of PARDISO's analysis (phase 11) before the same numerical factorization (phase 22):

``matching``
    symmetric weighted matching and scaling (iparm 11/13 = 1), METIS: what flexmor did for these
    types before; MKL orders by the values and ignores a given ordering;
``plain``
    no matching, METIS on the pattern;
``reused``
    no matching, the ordering METIS gave the Cholesky factorization of ``K + s M`` (same pattern).

Printed per case: analysis + factorization seconds, perturbed pivots (iparm 14), the normwise
backward error of a solve with two random right-hand sides, and the inertia (real type).

Usage::

    .venv/bin/python bench/orderings.py                       # plate, cantilever, C3D10 (if exported)
    .venv/bin/python bench/orderings.py --models plate
"""

from __future__ import annotations

import argparse
import ctypes
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

HERE = Path(__file__).resolve().parent


def _factor(fn, A, mtype: int, matching: bool, perm=None):
    """Analysis and factorization of the upper triangle of ``A``; returns timings, pivots, backward error, inertia
    and the ordering."""
    U = sp.triu(A, format="csr")
    U.sort_indices()
    data = np.ascontiguousarray(U.data)
    ia, ja, n = U.indptr.astype(np.int32), U.indices.astype(np.int32), U.shape[0]
    pt, ip = np.zeros(64, np.int64), np.zeros(64, np.int32)
    ip[0], ip[1], ip[34], ip[9] = 1, 2, 1, 8
    ip[10] = ip[12] = int(matching)
    ip[4] = 2 if perm is None else 1
    perm = np.zeros(n, np.int32) if perm is None else perm.copy()
    i32, P = ctypes.c_int32, ctypes.POINTER
    err = i32(0)

    def call(phase, b=None, x=None, nrhs=0):
        d = np.zeros(1, data.dtype)
        fn(pt.ctypes.data_as(P(ctypes.c_int64)), ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(mtype)),
           ctypes.byref(i32(phase)), ctypes.byref(i32(n)), data.ctypes.data, ia.ctypes.data_as(P(i32)),
           ja.ctypes.data_as(P(i32)), perm.ctypes.data_as(P(i32)), ctypes.byref(i32(nrhs)), ip.ctypes.data_as(P(i32)),
           ctypes.byref(i32(0)), (b if b is not None else d).ctypes.data, (x if x is not None else d).ctypes.data,
           ctypes.byref(err))
        if err.value:
            raise RuntimeError(f"PARDISO phase {phase}: error {err.value}")

    t0 = time.perf_counter()
    call(11)
    t1 = time.perf_counter()
    call(22)
    t2 = time.perf_counter()
    b = np.asfortranarray(np.random.default_rng(0).standard_normal((n, 2)).astype(data.dtype))
    x = np.zeros_like(b, order="F")
    call(33, b, x, 2)
    eta = np.linalg.norm(A @ x - b) / (abs(A).sum(axis=1).max() * np.linalg.norm(x) + np.linalg.norm(b))
    out = (t1 - t0, t2 - t1, int(ip[13]), float(eta), (int(ip[21]), int(ip[22])), perm)
    call(-1)
    return out


def _models(names: list[str]):
    import flexmor
    from flexmor.couplings import couple
    from flexmor.errors import FlexmorWarning
    from flexmor.models import cantilever, plate_structure, size_for_dofs

    for name in names:
        if name == "plate":
            yield "plate_structure(56) free", couple(plate_structure(56, lower="mass"), ["HOLE@rbe2"]).model
        elif name == "cantilever":
            yield "cantilever 27,000", cantilever(size_for_dofs(27000))
        elif name == "c3d10":
            sti = HERE / "results" / "c3d10_20x8x8_clamped" / "bar.sti"
            if not sti.exists():
                print("C3D10 export missing (bench/around_methods.py --parts krylov makes it with ccx): skipped")
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", FlexmorWarning)
                yield "CalculiX C3D10 bar", flexmor.read(sti)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="plate,cantilever,c3d10")
    args = ap.parse_args(argv)
    from flexmor.linalg.eigen import eigenmodes
    from flexmor.linalg.pardiso import mkl_pardiso

    fn = mkl_pardiso()
    for label, model in _models(args.models.split(",")):
        K, M = model.K.tocsr(), model.M.tocsr()
        lam, _ = eigenmodes(K, M, 12)
        print(f"{label}, {model.n_dof} DOF")
        spd = _factor(fn, (K + lam[-1] * M).tocsr(), 2, False)[-1]
        for where, s in (("near the 8th", lam[7] * (1 + 1e-6)), ("7th-8th", 0.5 * (lam[6] + lam[7])),
                         ("above the 12th", lam[-1] * 1.0001)):
            for cplx in (False, True):
                A = (K - s * M).tocsr()
                if cplx:
                    A = (A + 1j * np.sqrt(s) * (1e-7 * K + 1e-2 * M)).tocsr()
                mtype = 6 if cplx else -2
                cells = []
                for name, matching, perm in (("matching", True, None), ("plain", False, None), ("reused", False, spd)):
                    t11, t22, pert, eta, inertia, _ = _factor(fn, A, mtype, matching, perm)
                    cells.append(f"{name} {t11:.3f}+{t22:.3f} s pert {pert} eta {eta:.0e}"
                                 + ("" if cplx else f" neg {inertia[1]}"))
                print(f"  {where:15s} {'complex' if cplx else 'real':7s} | " + " | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
