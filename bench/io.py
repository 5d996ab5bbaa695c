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
  (upper triangle, 10 digits), ``job.bdf`` with the GRIDs (not run by default: card by card).

*MB/s* is the size of the matrix files over the wall time of ``read`` (*MB/cpu s* over its CPU
time, the fairer number on a loaded machine); *peak MB* the largest
memory allocated during ``read`` (``tracemalloc``: NumPy arrays and Python objects); *x CSR* that
peak over the bytes of the final CSR ``K`` and ``M`` (data, indices, indptr).

Usage::

    .venv/bin/python bench/io.py                  # ~30k DOF
    .venv/bin/python bench/io.py --dofs 3000 --formats calculix
"""

from __future__ import annotations

import argparse
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
    raise ValueError(fmt)


def main() -> None:
    from flexmor.io import read
    from flexmor.models import cantilever, size_for_dofs

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dofs", type=int, default=30_000)
    ap.add_argument("--formats", default="calculix,matrix-market,abaqus")
    a = ap.parse_args()
    model = cantilever(size_for_dofs(a.dofs))
    print(f"cantilever, {model.n_dof} DOF, K nnz {model.K.nnz}")
    print(f"{'format':>14} {'MB':>8} {'read s':>8} {'MB/s':>8} {'cpu s':>8} {'MB/cpu s':>8} {'peak MB':>8} "
          f"{'x CSR':>6}")
    for fmt in a.formats.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            d = Path(tmp)
            main_file, files = write(fmt, model, d)
            mb = sum(p.stat().st_size for p in files) / 1e6
            tracemalloc.start()
            t0, c0 = time.perf_counter(), time.process_time()
            m = read(main_file)
            dt, cpu = time.perf_counter() - t0, time.process_time() - c0
            peak = tracemalloc.get_traced_memory()[1] / 1e6
            tracemalloc.stop()
            csr = sum(A.data.nbytes + A.indices.nbytes + A.indptr.nbytes for A in (m.K.tocsr(), m.M.tocsr())) / 1e6
            assert abs(m.K - model.K).max() <= (1e-9 if fmt == "nastran" else 1e-12) * abs(model.K).max()
            print(f"{fmt:>14} {mb:8.1f} {dt:8.2f} {mb / dt:8.1f} {cpu:8.2f} {mb / cpu:8.1f} {peak:8.0f} "
                  f"{peak / csr:6.2f}")


if __name__ == "__main__":
    main()
