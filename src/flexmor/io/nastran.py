"""Readers of Nastran matrix exports: DMIG cards in punch files and ASCII OP4 files.

DMIG (``.pch``; ``PARAM,EXTOUT,DMIGPCH`` writes ``KAAX``, ``MAAX`` ...)
    Small-field, large-field (``DMIG*`` with ``*`` continuations) and free-field cards.
    Rows and columns are ``(grid, component)``; the model's equations are all pairs that
    occur, sorted by grid and component. Symmetric matrices (``IFO=6``) may store either
    triangle; an entry given twice is refused. Scalar points (component 0, e.g. the modal
    DOFs of a superelement) are refused: the model needs grid DOFs. Grid coordinates come
    from ``<stem>.bdf`` or ``<stem>.dat`` beside the punch file, or ``geometry=``
    (``GRID`` cards in the basic system: ``CP`` and ``CD`` must be blank or 0).
OP4, ASCII (``.op4``)
    Dense and sparse (string) columns, real or complex, any ``NxEw.d`` format. The model
    has no nodes: ``stiffness=``/``mass=`` name the matrices.

Matrix names default to the one name starting with ``K`` and the one starting with ``M``
(and ``B`` for damping); pass ``stiffness=``, ``mass=``, ``damping=`` otherwise. Units are
those of the Nastran model. pyNastran is not needed (and currently pins ``numpy<2``).
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..errors import ReadError
from . import register_format
from ._text import build_model, read_text

__all__ = ["read_nastran", "read_dmig", "read_op4", "read_grids"]

log = logging.getLogger(__name__)

#: Largest OP4 matrix (entries) read densely: 2e8 entries = 1.6 GB of float64.
_MAX_DENSE = 200_000_000

_IMPLICIT_EXP = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d+)$")


def _num(tok: str) -> float:
    t = tok.strip().upper().replace("D", "E")
    m = _IMPLICIT_EXP.match(t)
    return float(f"{m.group(1)}E{m.group(2)}" if m else t)


def _cards(path: Path, text: str):
    """Yield ``(lineno, NAME, fields, field line numbers)`` of each bulk-data card, continuations merged.

    Each line contributes 8 fields (small field, free field) or 4 (large field, ``NAME*``
    and ``*`` continuations); short free-field lines are padded with blanks.
    """
    card = None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("$", 1)[0].rstrip()
        if not line.strip():
            continue
        if "," in line[:10]:
            parts = line.split(",")
            head, fields = parts[0].strip(), [p.strip() for p in parts[1:]]
            large = head.endswith("*") or (head == "*")
            width = 4 if large else 8
            fields = (fields + [""] * width)[:max(width, len(fields))]
        elif line[0] == "*" or line[:8].strip().endswith("*"):
            head = line[:8].strip()
            fields = [line[i:i + 16].strip() for i in range(8, 72, 16)]
        else:
            head = line[:8].strip()
            fields = [line[i:i + 8].strip() for i in range(8, 72, 8)]
        if head == "" or head[0] in "*+":
            if card is None:
                raise ReadError(path, f"continuation line without a card: {raw[:60]!r}", lineno)
            card[2].extend(fields)
            card[3].extend([lineno] * len(fields))
            continue
        if card is not None:
            yield card
        card = (lineno, head.rstrip("*").upper(), fields, [lineno] * len(fields))
    if card is not None:
        yield card


def read_dmig(path) -> dict:
    """Read all DMIG matrices of a punch (or bulk-data) file.

    Returns
    -------
    dict of str to tuple
        ``name -> (form IFO, rows (k, 2), cols (k, 2), values (k,), line numbers (k,))`` with
        ``(grid, component)`` pairs; values are complex for TIN 3/4.

    Raises
    ------
    ReadError
        Malformed cards (with line number), column cards without a header, unknown forms.
    """
    path = Path(path)
    mats: dict = {}
    for lineno, name, f, flines in _cards(path, read_text(path)):
        if name != "DMIG":
            continue
        if len(f) < 3 or not f[0]:
            raise ReadError(path, "DMIG card without a matrix name", lineno)
        mname = f[0].upper()
        try:
            if f[1] == "0":
                ifo, tin = int(f[2]), int(f[3] or 0)
                if ifo not in (1, 2, 6, 9) or tin not in (1, 2, 3, 4):
                    raise ReadError(path, f"DMIG {mname}: form {ifo} / type {tin} not supported "
                                          "(IFO 1, 2, 6, 9; TIN 1-4)", lineno)
                mats[mname] = {"ifo": ifo, "complex": tin > 2, "r": [], "c": [], "v": [], "line": []}
                continue
            if mname not in mats:
                raise ReadError(path, f"DMIG {mname} column before its header card (GJ=0)", lineno)
            m = mats[mname]
            gj, cj = int(f[1]), int(f[2] or 0)
            for k in range(4, len(f), 4):
                g, c, a, b = (f[k:k + 4] + ["", "", "", ""])[:4]
                if not g:
                    continue
                lineno = flines[k]
                v = complex(_num(a), _num(b) if b else 0.0) if m["complex"] else _num(a)
                m["r"].append((int(g), int(c or 0)))
                m["c"].append((gj, cj))
                m["v"].append(v)
                m["line"].append(lineno)
        except ValueError:
            raise ReadError(path, f"DMIG {mname}: non-numeric field", lineno) from None
    out = {}
    for k, m in mats.items():
        dt = np.complex128 if m["complex"] else np.float64
        out[k] = (m["ifo"], np.array(m["r"], np.int64).reshape(-1, 2), np.array(m["c"], np.int64).reshape(-1, 2),
                  np.array(m["v"], dt), np.array(m["line"], np.int64))
    if not out:
        raise ReadError(path, "no DMIG matrices found")
    return out


def read_op4(path) -> dict:
    """Read the matrices of an ASCII OP4 file.

    Returns
    -------
    dict of str to ndarray
        Name -> dense matrix (nrow, ncol), real or complex; symmetric forms (6) are expanded.

    Raises
    ------
    ReadError
        Binary OP4, malformed headers or columns (with line number), truncated files.
    """
    path = Path(path)
    raw = path.read_bytes() if path.exists() else b""
    if b"\x00" in raw[:4096]:
        raise ReadError(path, "binary OP4 is not supported; write it with FORMAT=ASCII (OUTPUT4 ... ,-1 / ASCII)")
    lines = read_text(path).splitlines()
    out, i = {}, 0
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        h = lines[i]
        m = re.match(r"^\s*(-?\d+)\s+(-?\d+)\s+(\d+)\s+(\d+)\s*(\S+)\s+\S*?(\d+)[EeDd](\d+)\.(\d+)", h)
        if not m:
            raise ReadError(path, f"expected an OP4 header 'ncol nrow form type NAME fmt', got {h[:60]!r}", i + 1)
        ncol, nrow, form, typ = (int(m.group(k)) for k in range(1, 5))
        name, per_line, width = m.group(5).upper(), int(m.group(6)), int(m.group(7))
        bigmat = nrow < 0
        nrow = abs(nrow)
        cplx = typ in (3, 4)
        if nrow * ncol > _MAX_DENSE:
            raise ReadError(path, f"matrix {name} of {nrow} x {ncol} is too large for a dense OP4 read "
                                  f"(limit {_MAX_DENSE} entries); is the header corrupt?", i + 1)
        A = np.zeros((nrow, ncol), np.complex128 if cplx else np.float64)
        i += 1
        while True:
            if i >= len(lines):
                raise ReadError(path, f"matrix {name}: file ends before the closing column record", len(lines))
            try:
                icol, irow, nw = (int(x) for x in lines[i].split())
            except ValueError:
                raise ReadError(path, f"matrix {name}: expected a column record 'icol irow nwords'", i + 1) from None
            i += 1
            vals, i = _op4_values(path, lines, i, nw, per_line, width) if icol <= ncol else _skip(lines, i, nw,
                                                                                                    per_line)
            if icol > ncol:
                break
            pieces = [(irow, vals)] if irow > 0 else _strings(path, vals, bigmat, i)
            for r0, v in pieces:
                v = v[0::2] + 1j * v[1::2] if cplx else v
                if r0 < 1 or r0 - 1 + len(v) > nrow or icol < 1:
                    raise ReadError(path, f"matrix {name}: column {icol} rows {r0}..{r0 + len(v) - 1} outside "
                                          f"{nrow} x {ncol}", i)
                A[r0 - 1:r0 - 1 + len(v), icol - 1] = v
        if form == 6:
            A = np.triu(A) + np.triu(A, 1).T
        out[name] = A
    if not out:
        raise ReadError(path, "no matrices found")
    return out


def _skip(lines, i, nw, per_line):
    return None, i + -(-nw // per_line)


def _op4_values(path, lines, i, nw, per_line, width):
    vals = []
    while len(vals) < nw:
        if i >= len(lines):
            raise ReadError(path, "file ends inside a column (truncated?)", len(lines))
        s = lines[i].rstrip()
        toks = [s[k:k + width] for k in range(0, len(s), width)]
        if not toks:
            raise ReadError(path, "blank line inside a column", i + 1)
        try:
            vals.extend(_num(t) for t in toks)
        except ValueError:
            raise ReadError(path, f"non-numeric value in {s[:60]!r}", i + 1) from None
        i += 1
    if len(vals) != nw:
        raise ReadError(path, f"column announces {nw} words, found {len(vals)}", i)
    return np.asarray(vals), i


def _strings(path, vals, bigmat, lineno):
    """Split a sparse column's words into ``(first row, values)`` strings."""
    out, k = [], 0
    while k < len(vals):
        if bigmat:
            n, r0 = int(vals[k]) - 1, int(vals[k + 1])
            k += 2
        else:
            code = int(vals[k])
            n, r0 = (code >> 16) - 1, code & 0xFFFF
            k += 1
        if n < 0 or k + n > len(vals):
            raise ReadError(path, "broken sparse string in an OP4 column", lineno)
        out.append((r0, vals[k:k + n]))
        k += n
    return out


def read_grids(path):
    """``(ids, xyz)`` of the ``GRID`` cards of a bulk-data file (basic system only)."""
    path = Path(path)
    ids, xyz = [], []
    for lineno, name, f, _ in _cards(path, read_text(path)):
        if name != "GRID":
            continue
        f = f + [""] * 6
        try:
            gid, cp, cd = int(f[0]), int(f[1] or 0), int(f[5] or 0)
            x = [_num(t) if t else 0.0 for t in f[2:5]]
        except ValueError:
            raise ReadError(path, "non-numeric GRID field", lineno) from None
        if cp or cd:
            raise ReadError(path, f"GRID {gid} uses coordinate system CP={cp}/CD={cd}; flexmor reads the basic "
                                  "system only", lineno)
        ids.append(gid)
        xyz.append(x)
    return np.asarray(ids, np.int64), np.asarray(xyz, np.float64).reshape(-1, 3)


def _pick(names, want, letter, what, path):
    if want:
        if want.upper() not in names:
            raise ReadError(path, f"no matrix {want.upper()}; the file has {', '.join(sorted(names))}")
        return want.upper()
    cands = [n for n in names if n.startswith(letter)]
    if len(cands) == 1:
        return cands[0]
    if letter == "B":
        return None
    raise ReadError(path, f"cannot tell the {what} matrix among {', '.join(sorted(names))}; name them K.../M... "
                          f"or pass {what}=NAME to flexmor.io.read")


def _dmig_model(path, mats, names, geometry):
    pairs = np.unique(np.concatenate([np.concatenate([mats[n][1], mats[n][2]]) for n in names.values()]), axis=0)
    if np.any(pairs[:, 1] == 0) or np.any(pairs[:, 1] > 6):
        g = pairs[(pairs[:, 1] == 0) | (pairs[:, 1] > 6)][0]
        raise ReadError(path, f"DOF {g[0]}-{g[1]} is a scalar point (or component > 6); flexmor needs grid DOFs "
                              "1..6 (superelement modal DOFs are not supported)")
    code = pairs[:, 0] * 8 + pairs[:, 1]
    n = pairs.shape[0]
    out = {}
    for role, name in names.items():
        ifo, r, c, v, line = mats[name]
        if np.iscomplexobj(v):
            raise ReadError(path, f"DMIG {name} is complex; flexmor needs real matrices")
        i = np.searchsorted(code, r[:, 0] * 8 + r[:, 1])
        j = np.searchsorted(code, c[:, 0] * 8 + c[:, 1])
        key = i * np.int64(n) + j
        order = np.argsort(key, kind="stable")
        dup = np.flatnonzero(key[order][1:] == key[order][:-1])
        if dup.size:
            k = int(order[dup[0] + 1])
            raise ReadError(path, f"DMIG {name}: entry ({r[k][0]}-{r[k][1]}, {c[k][0]}-{c[k][1]}) given twice; "
                                  "duplicates are refused, not summed", int(line[k]))
        if np.any(i > j) != np.any(i < j):  # one triangle stored
            off = i != j
            i, j, v = np.concatenate([i, j[off]]), np.concatenate([j, i[off]]), np.concatenate([v, v[off]])
        out[role] = sp.csr_matrix((v, (i, j)), shape=(n, n))
    node_ids, xyz = np.zeros(0, np.int64), np.zeros((0, 3))
    geo = Path(geometry) if geometry else next((p for p in (path.with_suffix(".bdf"), path.with_suffix(".dat"))
                                                if p.exists()), None)
    if geo is not None:
        if not geo.exists():
            raise ReadError(geo, "geometry file not found")
        node_ids, xyz = read_grids(geo)
        miss = ~np.isin(pairs[:, 0], node_ids)
        if np.any(miss):
            raise ReadError(geo, f"grid {pairs[miss][0, 0]} of the matrices has no GRID card here")
    return out, pairs, node_ids, xyz


def read_nastran(path, *, stiffness=None, mass=None, damping=None, geometry=None) -> "FEModel":  # noqa: F821
    """Read stiffness and mass (and damping) from a DMIG punch file or an ASCII OP4 file.

    Parameters
    ----------
    path : str or path-like
        ``.pch`` (DMIG) or ``.op4``.
    stiffness, mass, damping : str, optional
        Matrix names (default: the one name starting with K, M, B).
    geometry : str or path-like, optional
        Bulk-data file with the GRID cards (default ``<stem>.bdf``/``.dat`` beside a punch file).

    Returns
    -------
    FEModel

    Raises
    ------
    ReadError
        Malformed cards or columns (with line number), missing or ambiguous matrix names,
        complex matrices, scalar points, duplicate entries, grids without coordinates.
    """
    path = Path(path)
    op4 = path.suffix.lower() == ".op4"
    mats = read_op4(path) if op4 else read_dmig(path)
    names = {"K": _pick(mats, stiffness, "K", "stiffness", path), "M": _pick(mats, mass, "M", "mass", path)}
    b = _pick(mats, damping, "B", "damping", path)
    if b:
        names["D"] = b
    if op4:
        out = {}
        for role, nm in names.items():
            A = mats[nm]
            if np.iscomplexobj(A):
                raise ReadError(path, f"matrix {nm} is complex; flexmor needs real matrices")
            out[role] = sp.csr_matrix(A)
        kw = {}
    else:
        out, pairs, node_ids, xyz = _dmig_model(path, mats, names, geometry)
        kw = {"dofs": pairs, "node_ids": node_ids, "xyz": xyz}
    log.info("%s: matrices %s", path, names)
    return build_model(path, M=out["M"], K=out["K"], D=out.get("D"),
                       damping={"type": "given"} if "D" in out else {"type": "none"},
                       name=path.stem, source=str(path), **kw)


register_format("nastran", [".pch", ".op4"], reader=read_nastran,
                description="Nastran DMIG punch file (KAAX/MAAX ...) or ASCII OP4")
