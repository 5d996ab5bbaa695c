"""Models held in parts over MPI ranks: each rank builds or receives only its own rows.

:func:`partitioned_cantilever` is the solid beam of :func:`flexmor.models.cantilever`
(same mesh, elements, material and node sets), numbered plane by plane along x so that a
block of equations lies in a few neighbouring node planes. Rank ``r`` owns the equations of
PETSc's default row split (:func:`flexmor.linalg.distributed.row_range`), assembles with
scikit-fem only the elements that touch the node planes of its equations and keeps its rows,
which are then complete. M and K are :class:`flexmor.linalg.distributed.PartitionedMatrix`: the
whole matrices never exist on one rank. The node table and equation map (a few numbers per
node) are replicated.

Run with ``mpirun -n P`` and ``SolverContext(backend="petsc")``; with one process it is an ordinary
(differently numbered) cantilever.

:func:`read_on_root` does the same for a model read from a file: rank 0 alone reads it and
sends every other rank its rows of M, K (and D); the small data (node table, sets, equation
map, B, C) is broadcast.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import scipy.sparse as sp

from ..errors import OptionError
from ..linalg import distributed as dist
from ..model import FEModel
from .solid import ELEMENTS, _assemble, _check_choice, _count, _material, _positive

__all__ = ["partitioned_cantilever", "read_on_root"]

log = logging.getLogger(__name__)

#: Grid points per element edge of the node lattice (hex27 has mid-edge and mid-face nodes).
_STEPS = {"hex": 1, "tet": 1, "hex27": 2}


def partitioned_cantilever(n: int = 4, *, length: float = 1.0, width: float = 0.1, height: float = 0.1,
                           E: float = 2.1e11, nu: float = 0.3, rho: float = 7850.0, element: str = "hex",
                           clamped: bool = True, divisions: tuple[int, int, int] | None = None) -> FEModel:
    """The cantilever of :func:`flexmor.models.cantilever`, each MPI rank assembling only its rows.

    Parameters are those of :func:`flexmor.models.cantilever`. Equation ``3 g + d`` (``d`` = 0,
    1, 2 for x, y, z) belongs to lattice point ``g = (i (ny q + 1) + j) (nz q + 1) + k`` with
    ``i`` counted from the first free plane (``q`` = 2 for ``hex27``, else 1); node ids are
    ``g + 1`` over the whole lattice, clamped plane included.

    Returns
    -------
    FEModel
        ``M`` and ``K`` partitioned over the ranks; node sets ``ALL``, ``FIX``, ``TIP``,
        ``TIP_CENTER``; ``name`` ends in ``-partitioned``.

    Raises
    ------
    OptionError
        On a bad element, sizes or material, or more ranks than equations.
    """
    _positive(length=length, width=width, height=height)
    lam, mu = _material(E, nu, rho)
    _check_choice("element", element, ELEMENTS)
    if divisions is None:
        if int(n) < 1:
            raise OptionError(f"n must be an integer >= 1, got {n!r}")
        divisions = (_count(int(n), length, height), _count(int(n), width, height), int(n))
        tag = f"n{int(n)}"
    else:
        tag = "x".join(str(int(v)) for v in divisions)
    nx, ny, nz = (int(v) for v in divisions)
    if min(nx, ny, nz) < 1:
        raise OptionError(f"element divisions must be >= 1, got {(nx, ny, nz)}")
    q = _STEPS[element]
    px, py, pz = nx * q + 1, ny * q + 1, nz * q + 1  # lattice points per direction
    first = 1 if clamped else 0  # the clamped plane x = 0 has no equations
    n_free = px - first
    per_plane = py * pz
    n_eq = 3 * n_free * per_plane
    if dist.size() > n_eq:
        raise OptionError(f"{dist.size()} ranks but only {n_eq} equations to share")
    r0, r1 = dist.row_range(n_eq)
    i0, i1 = r0 // 3 // per_plane + first, (r1 - 1) // 3 // per_plane + first + 1  # lattice planes of my rows

    # elements touching the owned planes: element columns e0 .. e1-1 (lattice planes e q .. (e+1) q)
    e0, e1 = max((i0 - 1) // q, 0), min((i1 - 1) // q + 1, nx)
    K, M = _assemble_slab(element, (e0, e1), (nx, ny, nz), (length, width, height), lam, mu, rho, q,
                          (r0, r1), first, per_plane, n_eq)

    ii, jj, kk = np.meshgrid(np.arange(px), np.arange(py), np.arange(pz), indexing="ij")
    xyz = np.column_stack([ii.ravel() * length / (px - 1), jj.ravel() * width / (py - 1),
                           kk.ravel() * height / (pz - 1)])
    node_ids = np.arange(1, px * per_plane + 1, dtype=np.int64)
    plane = ii.ravel()
    sets = {"ALL": node_ids, "FIX": node_ids[plane == 0], "TIP": node_ids[plane == px - 1]}
    tip = sets["TIP"]
    centre = np.array([length, width / 2, height / 2])
    k = int(np.argmin(np.linalg.norm(xyz[tip - 1] - centre, axis=1)))
    sets["TIP_CENTER"] = tip[k:k + 1]
    free_nodes = node_ids[first * per_plane:]
    dofs = np.column_stack([np.repeat(free_nodes, 3), np.tile(np.arange(1, 4, dtype=np.int64), free_nodes.size)])
    name = f"cantilever-{element}-{tag}" + ("" if clamped else "-free") + "-partitioned"
    log.info("rank %d: equations %d..%d of %d (node planes %d..%d), %d local entries of K", dist.rank(), r0,
             r1 - 1, n_eq, i0, i1 - 1, K.nnz)
    return FEModel(M=M, K=K, node_ids=node_ids, xyz=xyz, dofs=dofs, node_sets=sets, name=name, source="built-in")


def read_on_root(load, keep: dict | None = None) -> FEModel:
    """The model ``load()`` returns, read by rank 0 alone and held by rows over the MPI ranks.

    ``load`` (no arguments) runs on rank 0 only, e.g. reading a file and applying node selections
    and couplings; the model is validated there in full (symmetry included). Every rank then
    receives only its rows :func:`flexmor.linalg.distributed.row_range` of ``M``, ``K`` and ``D``
    (:func:`flexmor.linalg.distributed.scatter_rows`) and, by broadcast, the small data: node
    table, node sets, equation map, ``B``, ``C``, names and damping. Collective over all ranks;
    with one process it returns ``load()`` itself.

    Parameters
    ----------
    load : callable
        Returns the model; called on rank 0 only.
    keep : dict, optional
        What ``load`` puts in it on rank 0 (a model before its couplings, the outcome of a check of
        the file as read, ...) is afterwards in it on every rank: its models held by rows like the
        returned one (an entry that is the returned model, or another entry's model, is that model),
        its other entries broadcast (small, picklable values).

    Raises
    ------
    Exception
        Whatever ``load`` raised on rank 0, raised on every rank (same class and message), so that
        no rank waits for data that will not come.
    """
    if dist.size() == 1:
        return load()
    model, failure = None, None
    if dist.is_root():
        try:
            model = load()
        except Exception as exc:  # noqa: BLE001 - passed on to the other ranks, then raised here too
            failure = exc
    dist.raise_root_failure(failure)
    out = _by_rows(model)
    if keep is not None:
        _share_kept(keep, model, out)
    log.info("rank %d: rows [%d, %d) of %d, %d local entries of K", dist.rank(), *dist.row_range(out.n_dof),
             out.n_dof, out.K.nnz)
    return out


def _by_rows(model) -> FEModel:
    """Rank 0's ``model`` (None on the other ranks) held by rows on every rank. Collective."""
    meta = None
    if dist.is_root():
        meta = {f.name: getattr(model, f.name) for f in dataclasses.fields(model) if f.name not in ("M", "K", "D")}
        meta["_shape"], meta["_has_D"] = model.M.shape, model.D is not None
    meta = dict(dist.comm().bcast(meta, root=0))
    (n, _), has_d = meta.pop("_shape"), meta.pop("_has_D")
    mats = {k: dist.scatter_rows(getattr(model, k, None), n) for k in ("M", "K", "D") if k != "D" or has_d}
    return FEModel(**mats, **meta)


def _share_kept(keep: dict, model, out: FEModel) -> None:
    """Rank 0's ``keep`` on every rank (:func:`read_on_root`); ``model`` is rank 0's whole model, ``out``
    the same held by rows. Collective."""
    plan = None
    if dist.is_root():
        plan, owner = [], {id(model): None}  # each whole model once: the key that distributes it
        for key, value in keep.items():
            if isinstance(value, FEModel):
                plan.append((key, "same", owner[id(value)]) if id(value) in owner else (key, "rows", None))
                owner.setdefault(id(value), key)
            else:
                plan.append((key, "value", value))
    for key, kind, arg in dist.comm().bcast(plan, root=0):
        if kind == "rows":
            keep[key] = _by_rows(keep.get(key))
        elif kind == "same":
            keep[key] = out if arg is None else keep[arg]
        else:
            keep[key] = arg


def _assemble_slab(element, cols, divisions, extent, lam, mu, rho, q, rows, first, per_plane, n_eq):
    """K and M rows ``[rows[0], rows[1])`` from the element columns ``cols`` (partitioned)."""
    import skfem

    (e0, e1), (nx, ny, nz), (lx, ly, lz) = cols, divisions, extent
    x = np.linspace(0.0, lx, nx + 1)[e0:e1 + 1]
    mesh = getattr(skfem, ELEMENTS[element][0]).init_tensor(x, np.linspace(0.0, ly, ny + 1),
                                                            np.linspace(0.0, lz, nz + 1))
    Ks, Ms, sxyz = _assemble(mesh, element, lam, mu, rho)
    steps = np.array([lx / (nx * q), ly / (ny * q), lz / (nz * q)])
    ijk = np.rint(sxyz / steps).astype(np.int64)
    g = (ijk[:, 0] * (ny * q + 1) + ijk[:, 1]) * (nz * q + 1) + ijk[:, 2]  # lattice point of each slab node
    eq = 3 * (np.repeat(g, 3) - first * per_plane) + np.tile(np.arange(3), g.size)
    eq[np.repeat(ijk[:, 0] < first, 3)] = -1  # clamped
    keep_row = (eq >= rows[0]) & (eq < rows[1])

    def part(A):
        A = sp.coo_matrix(A)
        ok = keep_row[A.row] & (eq[A.col] >= 0)
        return dist.PartitionedMatrix(sp.csr_matrix((A.data[ok], (eq[A.row[ok]], eq[A.col[ok]])), shape=(n_eq, n_eq)))

    return part(Ks), part(Ms)
