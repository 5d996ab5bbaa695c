#!/usr/bin/env python
"""Read speed (MB/s) and peak memory of the text matrix readers.

The built-in clamped cantilever (``cantilever(size_for_dofs(DOFS))``) is written in each text
format flexmor reads, then read back with :func:`flexmor.io.read`:

* ``calculix``: ``job.sti``/``job.mas`` (upper triangle, column by column, ``row col value``),
  ``job.dof``, ``job.inp`` with the nodes;
* ``matrix-market``: ``job_K.mtx``/``job_M.mtx``, ``coordinate real symmetric`` (lower triangle);
* ``abaqus``: ``job.inp`` with the nodes and ``job_STIF1.mtx``/``job_MASS1.mtx`` (both
  triangles, 3 DOFs per node, ``row col value``);
* ``nastran``: ``job.pch`` with ``DMIG KAAX``/``MAAX`` in large field as Nastran punches them
  (upper triangle, 10 digits), ``job.bdf`` with the GRIDs;
* ``op4``: ASCII OUTPUT4 ``job.op4`` with ``KAA``/``MAA`` (symmetric, stored in full) in the
  sparse BIGMAT form (a string per run of consecutive rows), ``1P,3E23.16``; no bulk file.

Each file is read twice (:func:`measure`): *read s* and *cpu s* are the wall and CPU time of
an untraced ``read``, *MB/cpu s* the size of the matrix files over that CPU time (the fair
number on a loaded machine); then, under ``tracemalloc``, *traced* is the CPU time and
*peak MB* the largest memory allocated (NumPy arrays and Python objects); *x CSR* that peak
over the bytes of the final CSR ``K`` and ``M`` (data, indices, indptr). ``--baseline SRC``
reads the same files with another source tree (in a child process) on the row above.

Usage::

    .venv/bin/python bench/io.py                  # ~30k DOF
    .venv/bin/python bench/io.py --dofs 3000 --formats calculix
    git worktree add ../base main && .venv/bin/python bench/io.py --baseline ../base/src
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import scipy.sparse as sp


def _write_triplets(path: Path, A: sp.spmatrix, header: str = "", base: int = 1) -> None:
    A = A.tocoo()
    order = np.lexsort((A.row, A.col))  # column by column, as CalculiX writes
    r, c, v = A.row[order] + base, A.col[order] + base, A.data[order]
    with open(path, "w") as fh:
        fh.write(header)
        for k in range(0, r.size, 200_000):
            sl = slice(k, k + 200_000)
            fh.write("".join(f"{i} {j} {x:.13e}\n" for i, j, x in zip(r[sl].tolist(), c[sl].tolist(),
                                                                     v[sl].tolist())))


def _nodes(path: Path, model, extra: str = "") -> None:
    lines = ["*NODE"] + [f"{i}, {x!r}, {y!r}, {z!r}" for i, (x, y, z) in zip(model.node_ids.tolist(),
                                                                             model.xyz.tolist())]
    path.write_text("\n".join(lines) + "\n" + extra)


def write(fmt: str, model, d: Path) -> tuple[Path, list]:
    """Write ``model`` in ``fmt`` into ``d``; return the file to read and the matrix files."""
    K, M = sp.triu(model.K).tocsr(), sp.triu(model.M).tocsr()
    if fmt == "calculix":
        _write_triplets(d / "job.sti", K)
        _write_triplets(d / "job.mas", M)
        (d / "job.dof").write_text("".join(f"{n}.{k}\n" for n, k in model.dofs.tolist()))
        _nodes(d / "job.inp", model)
        return d / "job.sti", [d / "job.sti", d / "job.mas"]
    if fmt == "matrix-market":
        for name, A in (("K", K.T), ("M", M.T)):
            A = sp.csr_matrix(A)
            _write_triplets(d / f"job_{name}.mtx", A,
                            f"%%MatrixMarket matrix coordinate real symmetric\n{A.shape[0]} {A.shape[1]} {A.nnz}\n")
        return d / "job_K.mtx", [d / "job_K.mtx", d / "job_M.mtx"]
    if fmt == "abaqus":
        n_nodes = model.node_ids.size
        eq = (np.searchsorted(model.node_ids, model.dofs[:, 0]) * 3 + model.dofs[:, 1] - 1)
        P = sp.csr_matrix((np.ones(model.n_dof), (eq, np.arange(model.n_dof))), shape=(3 * n_nodes, model.n_dof))
        _write_triplets(d / "job_STIF1.mtx", P @ model.K @ P.T)
        _write_triplets(d / "job_MASS1.mtx", P @ model.M @ P.T)
        fixed = np.setdiff1d(np.arange(3 * n_nodes), eq)
        _nodes(d / "job.inp", model, "*BOUNDARY\n" + "".join(
            f"{model.node_ids[k // 3]}, {k % 3 + 1}, {k % 3 + 1}\n" for k in fixed.tolist()))
        return d / "job.inp", [d / "job_STIF1.mtx", d / "job_MASS1.mtx"]
    if fmt == "nastran":
        lines = ["BEGIN BULK"] + [f"GRID,{i},,{x!r},{y!r},{z!r}" for i, (x, y, z) in zip(model.node_ids.tolist(),
                                                                                   model.xyz.tolist())]
        (d / "job.bdf").write_text("\n".join(lines + ["ENDDATA"]) + "\n")
        g, c = model.dofs[:, 0].tolist(), model.dofs[:, 1].tolist()
        with open(d / "job.pch", "w") as fh:
            for name, A in (("KAAX", K), ("MAAX", M)):
                A = sp.csc_matrix(A)  # upper triangle, column by column
                fh.write(f"DMIG    {name:<8}{0:8d}{6:8d}{2:8d}{0:8d}\n")
                for j in range(A.shape[1]):
                    rows = A.indices[A.indptr[j]:A.indptr[j + 1]].tolist()
                    vals = A.data[A.indptr[j]:A.indptr[j + 1]].tolist()
                    fh.write(f"DMIG*   {name:<16}{g[j]:>16}{c[j]:>16}\n" + "".join(
                        f"*       {g[i]:>16}{c[i]:>16}{v:16.9E}\n" for i, v in zip(rows, vals)))
        return d / "job.pch", [d / "job.pch"]
    if fmt == "op4":
        _write_op4(d / "job.op4", {"KAA": model.K, "MAA": model.M})
        return d / "job.op4", [d / "job.op4"]
    raise ValueError(fmt)


def _write_op4(path: Path, mats: dict) -> None:
    """ASCII OUTPUT4, BIGMAT strings (``L + 1, first row`` then ``L`` words), 3 values of ``E23.16`` a line."""
    with open(path, "w") as fh:
        for name, A in mats.items():
            A = sp.csc_matrix(A)
            n = A.shape[0]
            fh.write(f"{n:8d}{-n:8d}{6:8d}{2:8d}{name:<8}1P,3E23.16\n")
            for j in range(n):
                rows, vals = A.indices[A.indptr[j]:A.indptr[j + 1]], A.data[A.indptr[j]:A.indptr[j + 1]].tolist()
                cuts = [0] + (np.flatnonzero(np.diff(rows) != 1) + 1).tolist() + [rows.size]
                out = [f"{j + 1:8d}{0:8d}{2 * rows.size + 2 * (len(cuts) - 1):8d}\n"]
                for a, b in itertools.pairwise(cuts):
                    out.append(f"{2 * (b - a) + 1:8d}{int(rows[a]) + 1:8d}\n")
                    out += ["".join(f"{v:23.16E}" for v in vals[k:min(k + 3, b)]) + "\n" for k in range(a, b, 3)]
                fh.write("".join(out))
            fh.write(f"{n + 1:8d}{0:8d}{0:8d}\n{1.0:23.16E}\n")


def measure(main_file: Path, files: list) -> dict:
    """Read ``main_file`` twice: CPU and wall time untraced, then the ``tracemalloc`` peak (and the traced CPU time).

    ``tracemalloc`` slows every allocation of a Python object, so the Python parts of a
    reader (deck parsing, dictionaries) take up to twice as long under it: speed is measured
    in a run without it.
    """
    import flexmor.io.abaqus
    import flexmor.io.calculix
    import flexmor.io.matrix_market
    import flexmor.io.nastran  # noqa: F401 - imported before the clock starts
    from flexmor.io import read

    mb = sum(Path(p).stat().st_size for p in files) / 1e6
    t0, c0 = time.perf_counter(), time.process_time()
    m = read(main_file)
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    del m
    tracemalloc.start()
    c0 = time.process_time()
    m = read(main_file)
    traced = time.process_time() - c0
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    csr = sum(A.data.nbytes + A.indices.nbytes + A.indptr.nbytes for A in (m.K.tocsr(), m.M.tocsr())) / 1e6
    return {"mb": mb, "wall": dt, "cpu": cpu, "traced": traced, "peak": peak, "csr": csr, "K": m.K}


def _in_child(src: str, main_file: Path, files: list) -> dict:
    """:func:`measure` in a fresh interpreter that imports flexmor from ``src``."""
    env = dict(os.environ, PYTHONPATH=src)
    out = subprocess.run([sys.executable, __file__, "--measure", str(main_file), "--files", ",".join(map(str, files))],
                         env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dofs", type=int, default=30_000)
    ap.add_argument("--formats", default="calculix,matrix-market,abaqus,nastran,op4")
    ap.add_argument("--baseline", metavar="SRC", help="another flexmor source tree (e.g. a worktree of main: "
                                                     "../base/src), measured beside this one")
    ap.add_argument("--measure", help=argparse.SUPPRESS)
    ap.add_argument("--files", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.measure:  # child process of --baseline
        r = measure(Path(a.measure), a.files.split(","))
        del r["K"]
        print(json.dumps(r))
        return
    from flexmor.models import cantilever, size_for_dofs

    model = cantilever(size_for_dofs(a.dofs))
    print(f"cantilever, {model.n_dof} DOF, K nnz {model.K.nnz}")
    print(f"{'format':>14} {'code':>7} {'MB':>7} {'read s':>7} {'cpu s':>7} {'MB/cpu s':>8} {'traced':>7} "
          f"{'peak MB':>8} {'x CSR':>6}")
    here = str(Path(__file__).resolve().parents[1] / "src")
    for fmt in a.formats.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            d = Path(tmp)
            main_file, files = write(fmt, model, d)
            runs = [("before", a.baseline), ("after", here)] if a.baseline else [("", None)]
            for label, src in runs:
                if src is None:
                    r = measure(main_file, files)
                    K = r.pop("K")
                    assert abs(K - model.K).max() <= (1e-9 if fmt == "nastran" else 0 if fmt == "op4" else 1e-12) * abs(model.K).max()
                else:
                    r = _in_child(src, main_file, files)
                print(f"{fmt:>14} {label:>7} {r['mb']:7.1f} {r['wall']:7.2f} {r['cpu']:7.2f} "
                      f"{r['mb'] / r['cpu']:8.1f} {r['traced']:7.2f} {r['peak']:8.0f} {r['peak'] / r['csr']:6.2f}")


if __name__ == "__main__":
    main()
