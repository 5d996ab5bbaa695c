"""Export of a reduced body as a Nastran superelement: DMIG punch file or OUTPUT4 with its bulk data.

Nastran connects a superelement through physical **boundary** DOFs (grid components) and
carries the rest as **modal** DOFs (scalar points). A reduced body's coordinates ``q_r`` are
generalized, so they are changed (exactly, a congruence ``T``) to

    q_r = T [u_b; eta],   T = [P  N],   C_b P = I,   C_b N = 0,

where ``C_b`` are the body's displacement outputs at grid DOFs (outputs named ``NODE:DIR``),
``u_b`` the boundary displacements and ``eta`` the scalar points. ``P`` is the static shape
of the boundary (the minimum-energy ``q_r`` with ``C_b q_r = u_b``, from ``K`` shifted by a
tiny multiple of ``M`` for free bodies), so stiffness does not couple ``u_b`` and ``eta`` (a
Craig-Bampton form); ``N`` spans the null space of ``C_b``. ``K_se = T^T K_r T`` (likewise
``M``, ``D``) has the same eigenfrequencies as the body.

Files (read back by :func:`flexmor.io.nastran.read_superelement`)
    ``nastran-dmig`` (``.pch``): ``DMIG`` ``KAAX``, ``MAAX`` (``BAAX`` with damping), large
    field as Nastran punches them (10 significant digits), upper triangle (``IFO = 6``), with
    the ``GRID``, ``SPOINT``, ``ASET`` and ``QSET1`` cards in the same file (as ``EXTSEOUT``
    writes them);
    ``op4`` (``.op4``): ASCII OUTPUT4 ``KAA``, ``MAA`` (``BAA``), 17 significant digits,
    and ``<stem>.bdf`` beside it with the cards above (the a-set order of the matrices).

Scalar points are numbered after the largest boundary grid, from the next power of ten.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import scipy.linalg as sla

from ...errors import ModelError
from .._registry import EXPORT_FORMATS
from ..atomic import atomic_write

__all__ = ["superelement", "write_dmig", "write_op4"]

log = logging.getLogger(__name__)

_DIRS = {"x": 1, "y": 2, "z": 3, "rx": 4, "ry": 5, "rz": 6}
_PORT = re.compile(r"^\s*(\d+)\s*:\s*(x|y|z|rx|ry|rz)\s*$", re.I)


def superelement(body) -> dict:
    """The body in superelement coordinates.

    Returns
    -------
    dict
        ``aset`` (n, 2) ``(id, component)`` in Nastran's a-set order (component 0: scalar
        point), ``K``, ``M``, ``D`` (or None) in that order, ``grids`` (ids) and ``xyz`` of
        the boundary grids (xyz None when the body has no coordinates).

    Raises
    ------
    ModelError
        When the body has no displacement output at a grid DOF (``NODE:DIR``), or when those
        outputs are linearly dependent.
    """
    rows, dofs = [], []
    for k, name in enumerate(body.output_names):
        m = _PORT.match(str(name))
        if m and (int(m.group(1)), _DIRS[m.group(2).lower()]) not in dofs:
            rows.append(k)
            dofs.append((int(m.group(1)), _DIRS[m.group(2).lower()]))
    if not rows:
        raise ModelError("a Nastran superelement needs boundary DOFs: the body has no displacement output at a "
                         "grid DOF (reduce with outputs that name NODE:DIR, e.g. 12:x)", params=("outputs",))
    order = sorted(range(len(dofs)), key=lambda i: dofs[i])
    dofs = [dofs[i] for i in order]
    Cb = np.asarray(body.C, dtype=float)[[rows[i] for i in order]]
    K, M = np.asarray(body.K, dtype=float), np.asarray(body.M, dtype=float)
    r, p = K.shape[0], Cb.shape[0]
    if np.linalg.matrix_rank(Cb) < p:
        raise ModelError("the body's displacement outputs at grid DOFs are linearly dependent; they cannot all be "
                         "boundary DOFs of a superelement")
    shift = 1e-8 * np.trace(K) / max(np.trace(M), 1e-300)
    X = sla.solve(K + shift * M, Cb.T, assume_a="sym")
    P = X @ np.linalg.solve(Cb @ X, np.eye(p))
    T = np.hstack([P, sla.null_space(Cb)])

    def congruent(A):
        B = T.T @ np.asarray(A, dtype=float) @ T
        return 0.5 * (B + B.T)

    grids = np.unique([g for g, _ in dofs])
    base = 10 ** len(str(int(grids.max())))
    aset = np.array(dofs + [(base + k + 1, 0) for k in range(r - p)], dtype=np.int64).reshape(-1, 2)
    xyz = None
    if body.node_ids is not None and body.xyz is not None and len(body.node_ids):
        ids = np.asarray(body.node_ids)
        where = {int(i): k for k, i in enumerate(ids)}
        if all(int(g) in where for g in grids):
            xyz = np.asarray(body.xyz, dtype=float)[[where[int(g)] for g in grids]]
    if xyz is None:
        log.warning("the body has no coordinates of its boundary grids; the GRID cards are written at the origin")
        xyz = np.zeros((grids.size, 3))
    if body.D is None and body.damping.kind != "none":
        log.warning("the body's %s damping is not a matrix; the superelement is written without damping",
                    body.damping.kind)
    return {"aset": aset, "K": congruent(K), "M": congruent(M),
            "D": None if body.D is None else congruent(body.D), "grids": grids, "xyz": xyz}


def _large(v: float) -> str:
    """A real in a 16-character large field (10 significant digits, as Nastran punches)."""
    s = f"{v:16.9E}"
    return s if len(s) == 16 else f"{v:16.8E}"


def _bulk_cards(se) -> list:
    """GRID, SPOINT, ASET and QSET1 cards of the superelement's a-set."""
    lines = []
    for g, (x, y, z) in zip(se["grids"].tolist(), se["xyz"].tolist()):
        lines += [f"GRID*   {g:>16}{'':16}{_large(x)}{_large(y)}", f"*       {_large(z)}"]
    aset = se["aset"]
    for g in se["grids"].tolist():
        comps = "".join(str(c) for c in aset[(aset[:, 0] == g) & (aset[:, 1] > 0), 1].tolist())
        lines.append(f"ASET    {g:8d}{comps:>8}")
    spoints = aset[aset[:, 1] == 0, 0]
    if spoints.size:
        a, b = int(spoints[0]), int(spoints[-1])
        lines += [f"SPOINT  {a:8d}    THRU{b:8d}", f"QSET1   {0:8d}{a:8d}    THRU{b:8d}"]
    return lines


def _matrices(se, suffix: str) -> dict:
    out = {"K" + suffix: se["K"], "M" + suffix: se["M"]}
    if se["D"] is not None:
        out["B" + suffix] = se["D"]
    return out


def write_dmig(body, path, *, model=None) -> None:
    """Write a reduced body as a Nastran DMIG punch file (see the module docstring), atomically.

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
        The ``.pch`` file.
    model : FEModel, optional
        Not needed (accepted like every exporter).
    """
    se = superelement(body)
    aset = se["aset"]
    lines = ["$ reduced body written by flexmor as a superelement: boundary grids + modal scalar points"]
    lines += _bulk_cards(se)
    for name, A in _matrices(se, "AAX").items():
        lines.append(f"DMIG    {name:<8}{0:8d}{6:8d}{2:8d}{0:8d}")
        for j, (gj, cj) in enumerate(aset.tolist()):
            lines.append(f"DMIG*   {name:<16}{gj:>16}{cj:>16}{'':16}")
            for i in np.flatnonzero(A[: j + 1, j]).tolist():
                lines.append(f"*       {int(aset[i, 0]):>16}{int(aset[i, 1]):>16}{_large(A[i, j])}")
    text = "\n".join(lines) + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def write_op4(body, path, *, model=None) -> None:
    """Write a reduced body as an ASCII OUTPUT4 file plus ``<stem>.bdf`` with its a-set, atomically.

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
        The ``.op4`` file; the bulk data goes to the same name with ``.bdf``.
    model : FEModel, optional
        Not needed (accepted like every exporter).
    """
    se = superelement(body)
    lines = []
    for name, A in _matrices(se, "AA").items():
        n = A.shape[0]
        lines.append(f"{n:8d}{n:8d}{6:8d}{2:8d}{name:<8}1P,3E24.16")
        for j in range(n):
            lines.append(f"{j + 1:8d}{1:8d}{n:8d}")
            vals = [f"{v:24.16E}" for v in A[:, j].tolist()]
            lines += ["".join(vals[k:k + 3]) for k in range(0, n, 3)]
        lines += [f"{n + 1:8d}{1:8d}{1:8d}", f"{1.0:24.16E}"]
    text = "\n".join(lines) + "\n"
    bulk = "\n".join(["$ a-set of the superelement in " + Path(path).name, "BEGIN BULK"] + _bulk_cards(se)
                     + ["ENDDATA"]) + "\n"
    atomic_write(Path(path).with_suffix(".bdf"), lambda tmp: Path(tmp).write_text(bulk))
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


EXPORT_FORMATS.register("nastran-dmig", [".pch"], write_dmig, aliases=["dmig"],
                        description="reduced body as a Nastran superelement: DMIG punch KAAX/MAAX on boundary grids "
                                    "+ modal scalar points")
EXPORT_FORMATS.register("op4", [".op4"], write_op4, aliases=["nastran-op4"],
                        description="reduced body as a Nastran superelement: ASCII OUTPUT4 KAA/MAA + <stem>.bdf")
