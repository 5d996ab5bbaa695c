"""A Craig-Bampton superelement from Nastran, read as an already reduced body.

Nastran delivers a reduced component (``EXTSEOUT``, or a CB reduction written with
``OUTPUT4``/``DMIGPCH``) as matrices on the a-set: the **boundary** DOFs (grid components
1-6, ``ASET``/``BSET``) followed, in id order, by the **modal** DOFs (scalar points,
``SPOINT`` + ``QSET``). flexmor reads them as a :class:`~flexmor.body.ReducedModel`
that can be evaluated (frequencies, FRF between boundary DOFs, assembly) and exported
(``mat``, ``statespace``, flexmor ``.h5``); exports that integrate over the full mass matrix
(SID, Exudyn) need the full FE model and are not possible from a superelement alone.

What is required
    * the matrices: an OP4 file (ASCII or binary) with the stiffness and mass (default the one
      name starting with K and with M, e.g. ``KAA``/``MAA``; ``BAA`` damping when present),
      or a DMIG punch file (``KAAX``/``MAAX`` with grid and scalar-point DOFs);
    * for OP4, the bulk data that defines the a-set: ``GRID`` cards of the boundary grids,
      ``SPOINT`` cards of the modal coordinates and ``ASET``/``ASET1``/``BSET``/``BSET1``/
      ``QSET``/``QSET1`` cards (without any of these: 6 DOFs per GRID plus all SPOINTs). The
      a-set is ordered by id (grids and scalar points share one id range) and component, as
      Nastran orders it; its size must equal the matrix size. The bulk file is
      ``<stem>.bdf/.dat/.nas/.blk/.asm`` beside the matrix file or ``bulk=``;
    * for a punch file the bulk data is optional (it gives coordinates and CD systems); GRID
      cards in the punch file itself (as ``EXTSEOUT`` writes them) are used too.

On the command line a superelement file can stand where a reduced body is expected:
``flexmor compare FULL_MODEL SE.op4`` (FRF at the boundary DOFs), ``flexmor export SE.op4 -o
SE.mat``.

The body's inputs and outputs are the boundary DOFs (``B`` selects them, ``C = B^T``), named
``GRID:DIR``; boundary DOFs in a local ``CD`` system are rotated to basic x y z. ``info``
holds the a-set, the fixed-interface frequencies (``sqrt(K_qq/M_qq)`` of the modal DOFs) and
the relative size of the stiffness coupling between boundary and modal DOFs, which is zero
for a Craig-Bampton basis.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import scipy.linalg as sla

from ...errors import FlexmorError, ReadError
from ...model import direction_name
from .._open import open_binary, stem, suffix
from .._registry import BODY_FORMATS
from .nastran import SEQGP_REFUSED, bulk_of, dmig_matrices, dof_transform, find_bulk, load_matrices, op4_matrices
from .nastran_bulk import _cards, read_bulk

__all__ = ["MAX_ORDER", "is_superelement", "read_superelement"]

log = logging.getLogger(__name__)

#: Largest a-set read as a (dense) reduced body.
MAX_ORDER = 20_000


def _aset(bulk, n, where):
    if bulk.seqgp:
        raise ReadError(where, SEQGP_REFUSED)
    if bulk.aset:
        dofs = {tuple(d) for d in bulk.aset} | {(int(s), 0) for s in bulk.spoints}
        what = "the ASET/BSET/QSET DOFs and SPOINTs"
    else:
        dofs = {(int(g), c) for g in bulk.grid_ids for c in range(1, 7)} | {(int(s), 0) for s in bulk.spoints}
        what = "6 DOFs per GRID plus the SPOINTs"
    dofs = np.array(sorted(dofs), np.int64).reshape(-1, 2)
    if dofs.shape[0] != n:
        raise ReadError(where, f"{what} give {dofs.shape[0]} a-set DOFs, but the matrices have {n}")
    grid = dofs[:, 1] > 0
    unknown = grid & ~np.isin(dofs[:, 0], bulk.grid_ids)
    if np.any(unknown):
        raise ReadError(where, f"a-set DOF {dofs[unknown][0, 0]}-{dofs[unknown][0, 1]} names a grid without a "
                               "GRID card")
    clash = (~grid) & np.isin(dofs[:, 0], bulk.grid_ids)
    if np.any(clash):
        raise ReadError(where, f"id {dofs[clash][0, 0]} is both a GRID and a scalar point")
    return dofs


#: Bytes of a punch file searched for scalar points by :func:`is_superelement`.
_HEAD = 4 << 20


def is_superelement(path) -> bool:
    """Whether the Nastran matrix file ``path`` (``.op4``, ``.pch``, or either ``.gz``) holds a superelement.

    A superelement has scalar points (its modal coordinates) among its DOFs, which an FE model
    has not: an OP4 file whose bulk data beside it has ``SPOINT`` cards, or a punch file with
    ``SPOINT`` cards or DMIG DOFs of component 0 in its first 4 MB (or in its bulk data beside
    it). Cheap and never raising: False when unsure (a file that cannot be read, scalar points
    further down a large punch file).
    """
    path = Path(path)
    try:
        geo = find_bulk(path)
        if geo is not None and read_bulk(geo).spoints.size:
            return True
        return suffix(path) == ".pch" and _scalar_points_in_head(path)
    except (FlexmorError, OSError, ValueError):
        return False


def _scalar_points_in_head(path: Path) -> bool:
    """Whether the first :data:`_HEAD` bytes of a punch file hold a ``SPOINT`` card or a DMIG DOF of component 0."""
    with open_binary(path) as f:
        head = f.read(_HEAD)
    if len(head) == _HEAD:
        head = head[:head.rfind(b"\n") + 1]
    lines = ((path, k, line.split("$", 1)[0].expandtabs(8).rstrip())
             for k, line in enumerate(head.decode("latin-1").splitlines(), 1))
    for _, _, name, f, _ in _cards(line for line in lines if line[2]):
        if name == "SPOINT":
            return True
        if name != "DMIG" or len(f) < 3 or f[1] in ("", "0"):
            continue
        if f[2] in ("", "0"):  # a column of a scalar point (blank CJ is 0)
            return True
        if any(f[k] and f[k + 1] in ("", "0") for k in range(4, len(f) - 1, 4)):
            return True
    return False


def read_superelement(path, *, bulk=None, stiffness=None, mass=None, damping=None):
    """Read a Craig-Bampton superelement (boundary + modal DOFs) as a reduced body.

    Parameters
    ----------
    path : str or path-like
        ``.op4`` (ASCII or binary) or a DMIG punch file.
    bulk : str or path-like, optional
        Bulk data with GRID/SPOINT/ASET/QSET cards (default: found beside ``path``).
    stiffness, mass, damping : str, optional
        Matrix names (default: the one name starting with K, M, B).

    Returns
    -------
    ReducedModel
        ``method = 'craig-bampton'``, ``V = None``; ``node_ids``/``xyz`` of the boundary grids.

    Raises
    ------
    ReadError
        Missing bulk data for an OP4 file, a-set size different from the matrices,
        non-square, non-symmetric or complex matrices, a mass matrix that is not positive
        definite, no boundary DOF.
    """
    from ...body import ReducedModel

    path = Path(path)
    op4, mats, names = load_matrices(path, stiffness, mass, damping)
    geo, blk = bulk_of(path, bulk, op4)
    if op4:
        if blk is None:
            raise ReadError(path, "an OP4 superelement needs the bulk data with its GRID, SPOINT and ASET/QSET "
                                  f"cards: put {stem(path)}.bdf (or .asm/.dat) beside it or pass bulk=")
        out = op4_matrices(path, mats, names)
        n = out["K"].shape[0]
        dofs = _aset(blk, n, geo)
    else:
        out, dofs = dmig_matrices(path, mats, names)
        if blk is not None:
            miss = (dofs[:, 1] > 0) & ~np.isin(dofs[:, 0], blk.grid_ids)
            if np.any(miss):
                raise ReadError(geo, f"grid {dofs[miss][0, 0]} of the matrices has no GRID card here")
    n = dofs.shape[0]
    if n > MAX_ORDER:
        raise ReadError(path, f"{n} a-set DOFs: too many for a reduced body (limit {MAX_ORDER}); is this a full "
                              "model? read it as an FE model (format nastran)", params=("format",))
    if blk is not None:
        T = dof_transform(blk, dofs, geo)
        if T is not None:
            out = {k: (T @ A @ T.T).tocsr() for k, A in out.items()}
    bnd = np.flatnonzero(dofs[:, 1] > 0)
    modal = np.flatnonzero(dofs[:, 1] == 0)
    if bnd.size == 0:
        raise ReadError(path, "the a-set has no grid DOFs: a superelement needs boundary DOFs to connect to")
    K, M = out["K"].toarray(), out["M"].toarray()
    D = out["D"].toarray() if "D" in out else None
    for nm, A in (("stiffness", K), ("mass", M), ("damping", D)):
        if A is not None:
            scale = np.abs(A).max() or 1.0
            if not np.all(np.isfinite(A)) or np.abs(A - A.T).max() > 1e-8 * scale:
                raise ReadError(path, f"{nm} matrix {names[nm[0].upper()]} is not symmetric (or not finite)")
    try:
        sla.cholesky(0.5 * (M + M.T))
    except np.linalg.LinAlgError:
        raise ReadError(path, f"mass matrix {names['M']} is not positive definite") from None
    info = {"source": str(path), "format": "nastran superelement", "matrices": names,
            "n_boundary": int(bnd.size), "n_modal": int(modal.size), "aset": dofs.tolist()}
    if modal.size:
        kq, mq = np.diag(K)[modal], np.diag(M)[modal]
        info["fixed_interface_hz"] = (np.sqrt(np.clip(kq / mq, 0, None)) / (2 * np.pi)).tolist()
        info["kbq_rel"] = float(np.abs(K[np.ix_(bnd, modal)]).max() / max(np.abs(K).max(), 1e-300))
        if info["kbq_rel"] > 1e-6:
            log.warning("%s: boundary-modal stiffness coupling %.2e (relative) - not a Craig-Bampton basis?",
                        path, info["kbq_rel"])
    Bsel = np.zeros((n, bnd.size))
    Bsel[bnd, np.arange(bnd.size)] = 1.0
    port_names = [f"{g}:{direction_name(c)}" for g, c in dofs[bnd]]
    gids = np.unique(dofs[bnd, 0])
    xyz = None
    if blk is not None:
        xyz = blk.xyz[np.searchsorted(blk.grid_ids, gids)]
    return ReducedModel(M=0.5 * (M + M.T), K=0.5 * (K + K.T), D=None if D is None else 0.5 * (D + D.T),
                        B=Bsel, C=Bsel.T.copy(), V=None, method="craig-bampton", info=info,
                        input_names=port_names, output_names=list(port_names), node_ids=gids, xyz=xyz,
                        dofs=None, model_name=stem(path),
                        damping={"type": "given"} if D is not None else {"type": "none"})


BODY_FORMATS.register("nastran-se", [".op4", ".pch"], read_superelement, gzip=True, recognizes=is_superelement,
                      description="Nastran Craig-Bampton superelement: a-set K, M (B) as OP4 or DMIG punch "
                                  "(boundary grids + modal scalar points)")
