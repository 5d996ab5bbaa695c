#!/usr/bin/env python
"""Time and peak memory of stress modes: the nodal stress of r basis vectors of a large body.

A box meshed with ``C3D8`` or ``C3D20R`` bricks on a structured grid of about ``--dofs``
equations (unit matrices: stress recovery needs only the nodes, the elements and a material)
and ``r`` random basis vectors; :func:`flexmor.stress.nodal_stresses` at the outer surface
(``--nodes surface``, what ``reduce --stress`` stores by default) or at every node (``all``).
*s* is the wall time of the recovery, *peak MB* the largest memory it allocated beyond the
basis (``tracemalloc``), *MB out* the size of the stress modes.

Usage::

    .venv/bin/python bench/stress.py                          # 1M DOF, r = 200, surface
    .venv/bin/python bench/stress.py --dofs 100000 --r 50 --nodes all --element C3D20R
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np
import scipy.sparse as sp

from flexmor.elements import ElementBlock, Elements, Material
from flexmor.mesh import CellBlock, Mesh
from flexmor.model import FEModel
from flexmor.stress import nodal_stresses, stress_node_ids

_HEX = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]


def box(dofs: float, element: str) -> FEModel:
    """A cube of bricks with about ``dofs`` equations (3 per node)."""
    quadratic = element == "C3D20R"
    per_cell = 4 if quadratic else 1  # nodes per cell, roughly
    n = max(2, int(round((dofs / 3 / per_cell) ** (1 / 3))))
    fine = 2 * n + 1 if quadratic else n + 1
    step = 2 if quadratic else 1
    c = np.stack(np.meshgrid(*(np.arange(n),) * 3, indexing="ij"), -1).reshape(-1, 3) * step
    pts = c[:, None, :] + step * _HEX[None]  # (cells, 8, 3) on the (doubled) grid
    if quadratic:
        pts = np.concatenate([pts, (pts[:, [a for a, _ in _EDGES]] + pts[:, [b for _, b in _EDGES]]) // 2], axis=1)
    nid = 1 + pts[..., 0] + fine * (pts[..., 1] + fine * pts[..., 2])
    used = np.unique(nid)
    k = used - 1
    xyz = np.column_stack([k % fine, (k // fine) % fine, k // fine ** 2]) / (fine - 1)
    nd = np.column_stack([np.repeat(used, 3), np.tile([1, 2, 3], used.size)])
    block = ElementBlock(element, np.arange(1, len(nid) + 1), nid, np.zeros(len(nid), np.int64))
    mesh = Mesh((CellBlock("hexahedron20" if quadratic else "hexahedron", nid),))
    return FEModel(M=sp.eye(nd.shape[0], format="csr"), K=sp.eye(nd.shape[0], format="csr"), node_ids=used,
                   xyz=xyz, dofs=nd, mesh=mesh, name="box",
                   elements=Elements((block,), (Material.isotropic(210e9, 0.3, 7850.0),), "box"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dofs", type=float, default=1e6)
    ap.add_argument("--r", type=int, default=200)
    ap.add_argument("--nodes", choices=["surface", "all"], default="surface")
    ap.add_argument("--element", choices=["C3D8", "C3D20R"], default="C3D8")
    args = ap.parse_args(argv)
    model = box(args.dofs, args.element)
    V = np.random.default_rng(0).standard_normal((model.n_dof, args.r)) * 1e-6
    nodes = stress_node_ids(model, args.nodes)
    tracemalloc.start()
    t0 = time.perf_counter()
    out = nodal_stresses(model, V, nodes=nodes)
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    print(f"{args.element} {model.n_dof} DOF, {model.elements.n_elements} elements, r = {args.r}, "
          f"{args.nodes}: {nodes.size} nodes: {dt:.1f} s, peak {peak:.0f} MB, MB out {out.values.nbytes / 2**20:.0f}")


if __name__ == "__main__":
    main()
