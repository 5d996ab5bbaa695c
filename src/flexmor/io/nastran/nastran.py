"""Readers of Nastran matrix exports: DMIG cards in punch files and OP4 files.

DMIG (``.pch``; ``PARAM,EXTOUT,DMIGPCH`` writes ``KAAX``, ``MAAX`` ...)
    Small-field, large-field (``DMIG*`` with ``*`` continuations) and free-field cards.
    Rows and columns are ``(grid, component)``; the model's equations are all pairs that
    occur, sorted by grid and component. Symmetric matrices (``IFO=6``) may store either
    triangle (or both); an entry given twice is refused, not summed. What the cards declare is
    checked against what was read: every row of a square stiffness or mass matrix has a column
    card of its own (a lost column card is refused), a rectangular one (``IFO=9``) its ``NCOL``
    columns; entries out of the row order Nastran writes are named. DMIG has no entry counts:
    a matrix stored as one triangle is read with an :class:`~flexmor.io.UncheckedWarning`. Scalar points
    (component 0, the modal DOFs of a superelement) are refused here: such files are reduced
    bodies, read by :func:`flexmor.io.nastran.read_superelement` (format ``nastran-se`` of
    :func:`flexmor.io.read_body`).
OP4 (``.op4``, ASCII or binary, :mod:`flexmor.io.nastran.op4`)
    Without a bulk-data file the model has no nodes. With one, its ``ASET/ASET1/BSET/...``
    cards (else 6 DOFs per GRID, sorted by id) give the equation map, checked against the
    matrix size.
Geometry (:mod:`flexmor.io.nastran.nastran_bulk`)
    ``<stem>.bdf``/``.dat``/``.nas``/``.asm`` beside the matrix file, or ``geometry=``:
    ``GRID`` positions in any ``CP`` system (``CORD1*``/``CORD2*``, chained) are converted
    to basic. Matrix rows and columns are in each grid's displacement system ``CD``: by
    default such grids' equations are rotated to basic x y z (``K_b = T K T^T`` with the
    orthogonal block ``T`` of each grid), so that ports, couplings and node selections use
    global directions; ``directions='local'`` keeps them and records the frames.

Matrix names default to the one name starting with ``K`` and the one starting with ``M``
(and ``B`` for damping); pass ``stiffness=``, ``mass=``, ``damping=`` otherwise. Units are
those of the Nastran model. pyNastran is not needed.
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ...errors import FlexmorWarning, ReadError
from ...model import FEModel
from .._build import build_model
from .._cells import mesh_of_elements, nastran_cell
from .._open import beside, stem, suffix
from .._registry import MODEL_FORMATS
from .._sparse import assemble
from .._unchecked import warn_unchecked
from .dmig_fast import DmigColumns, fast_dmig, scan_dmig
from .nastran_bulk import Bulk, cards, num, read_bulk
from .nastran_elements import nastran_elements
from .op4 import read_op4

__all__ = ["bulk_of", "dof_transform", "find_bulk", "read_dmig", "read_grids", "read_nastran", "read_op4"]

log = logging.getLogger(__name__)


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
    top = Path(path)
    fast = fast_dmig(top)
    if fast is not None:
        return fast
    return _dmig_cards(top)[0]


def _dmig_cards(top: Path):
    """:func:`read_dmig` card by card, and the ``NCOL`` each header declares (None where blank) by name."""
    mats: dict = {}
    ncols: dict = {}
    for fpath, lineno, name, f, flines in cards(top):
        if name != "DMIG":
            continue
        if len(f) < 3 or not f[0]:
            raise ReadError(fpath, "DMIG card without a matrix name", lineno)
        mname = f[0].upper()
        try:
            if f[1] == "0":
                ifo, tin = int(f[2]), int(f[3] or 0)
                if ifo not in (1, 2, 6, 9) or tin not in (1, 2, 3, 4):
                    raise ReadError(fpath, f"DMIG {mname}: form {ifo} / type {tin} not supported "
                                          "(IFO 1, 2, 6, 9; TIN 1-4)", lineno)
                mats[mname] = {"ifo": ifo, "complex": tin > 2, "r": [], "c": [], "v": [], "line": []}
                ncols[mname] = int(f[7]) if ifo == 9 and len(f) > 7 and f[7] else None  # NCOL, form 9 only
                continue
            if mname not in mats:
                raise ReadError(fpath, f"DMIG {mname} column before its header card (GJ=0)", lineno)
            m = mats[mname]
            gj, cj = int(f[1]), int(f[2] or 0)
            for k in range(4, len(f), 4):
                g, c, a, b = (f[k:k + 4] + ["", "", "", ""])[:4]
                if not g:
                    if c or a or b:  # a value without its row: the grid field was lost or blanked
                        raise ReadError(fpath, f"DMIG {mname}: an entry of column {gj}-{cj} has no grid (row) "
                                               "number", flines[k])
                    continue
                lineno = flines[k]
                if not a:
                    raise ReadError(fpath, f"DMIG {mname}: entry {g}-{c or 0} of column {gj}-{cj} has no value "
                                           "(truncated card?)", lineno)
                if not (0 <= int(c or 0) <= 6 and 0 <= cj <= 6):
                    raise ReadError(fpath, f"DMIG {mname}: component {c if 0 <= cj <= 6 else cj} is not 0 "
                                           "(scalar point) or 1..6", lineno)
                v = complex(num(a), num(b) if b else 0.0) if m["complex"] else num(a)
                m["r"].append((int(g), int(c or 0)))
                m["c"].append((gj, cj))
                m["v"].append(v)
                m["line"].append(lineno)
        except ValueError:
            raise ReadError(fpath, f"DMIG {mname}: non-numeric field", lineno) from None
    out = {}
    for k, m in mats.items():
        dt = np.complex128 if m["complex"] else np.float64
        out[k] = (m["ifo"], np.array(m["r"], np.int64).reshape(-1, 2), np.array(m["c"], np.int64).reshape(-1, 2),
                  np.array(m["v"], dt), np.array(m["line"], np.int64))
    if not out:
        raise ReadError(top, "no DMIG matrices found")
    return out, ncols


def read_grids(path):
    """``(ids, xyz)`` of the ``GRID`` cards of a bulk-data file, positions in the basic system."""
    b = read_bulk(path)
    return b.grid_ids, b.xyz


#: Why OP4 matrices with a resequenced bulk file are refused.
SEQGP_REFUSED = ("SEQGP cards resequence the grids, so the order of the OP4 rows and columns is not the id order "
                 "flexmor assumes; export without SEQGP or as DMIG (PARAM,EXTOUT,DMIGPCH)")

#: Matrix names Nastran gives the a-set (and g-set ...) matrices, in order of preference:
#: ``KAAX``/``MAAX``/``BAAX`` (DMIG punch), ``KAA``/``MAA``/``BAA`` (OUTPUT4), ``KGG`` ...
_USUAL_SETS = ("AAX", "AA", "GGX", "GG", "FFX", "FF", "LLX", "LL", "XX", "HH")


def _pick(names, want, letter, what, path):
    if want:
        if want.upper() not in names:
            raise ReadError(path, f"no matrix {want.upper()}; the file has {', '.join(sorted(names))}")
        return want.upper()
    cands = [n for n in names if n.startswith(letter)]
    if len(cands) == 1:
        return cands[0]
    usual = [f"{letter}{s}" for s in _USUAL_SETS if f"{letter}{s}" in cands]
    if usual:  # e.g. KAAX beside K4AX (structural damping) from EXTSEOUT
        return usual[0]
    if letter == "B":
        return None
    raise ReadError(path, f"cannot tell the {what} matrix among {', '.join(sorted(names))}; name them K.../M... "
                          f"or pass {what}=NAME", params=(what,))


def find_bulk(path: Path, geometry=None) -> Path | None:
    """The bulk-data file with the GRID cards: ``geometry`` or ``<stem>.bdf/.dat/.nas/.asm`` beside ``path``
    (plain or ``.gz``)."""
    if geometry:
        geo = Path(geometry)
        if not geo.exists():
            raise ReadError(geo, "geometry file not found")
        return geo
    for suf in (".bdf", ".dat", ".nas", ".blk", ".asm"):
        p = beside(path, suf)
        if p is not None:
            return p
    return None


def bulk_of(path: Path, geometry, op4: bool):
    """``(file, Bulk)`` of the geometry: :func:`find_bulk`, else the punch file itself when it
    holds GRID cards (EXTSEOUT punch files carry GRID/ASET/SPOINT with the DMIG); else ``(None, None)``."""
    geo = find_bulk(path, geometry)
    if geo is not None:
        return geo, read_bulk(geo)
    if not op4:
        b = read_bulk(path)
        if b.grid_ids.size:
            return path, b
    return None, None


def dof_transform(bulk: Bulk, dofs: np.ndarray, where) -> sp.csr_matrix | None:
    """``T`` with ``q_basic = T q_cd`` for the equations ``dofs`` (grid, component 1..6), or None.

    Grids whose displacement system ``CD`` is not the basic system need all three
    translations (rotations) among the equations to be rotated; otherwise ReadError.
    Scalar points (component 0) pass unchanged.
    """
    local = {int(g) for g, c in zip(bulk.grid_ids, bulk.cd) if c != 0}
    if not local:
        return None
    n = dofs.shape[0]
    idx = {(int(g), int(c)): i for i, (g, c) in enumerate(dofs)}
    rows, cols, vals = [], [], []
    done = np.zeros(n, bool)
    for g in sorted(local & {int(x) for x in dofs[:, 0]}):
        Q = bulk.frame(g)
        for base in (1, 4):
            eq = [idx.get((g, base + k)) for k in range(3)]
            have = [e for e in eq if e is not None]
            if not have:
                continue
            if len(have) < 3:
                miss = [base + k for k, e in enumerate(eq) if e is None]
                cd = int(bulk.cd[np.searchsorted(bulk.grid_ids, g)])
                raise ReadError(where, f"grid {g}: components {','.join(map(str, miss))} of its displacement "
                                       f"system CD={cd} are not among the equations (constrained?), so the "
                                       f"remaining ones cannot be rotated to the basic system; read with "
                                       f"directions='local' to keep the equations in the CD systems")
            for a in range(3):
                for b in range(3):
                    rows.append(eq[a])
                    cols.append(eq[b])
                    vals.append(Q[a, b])
            done[eq] = True
    keep = np.flatnonzero(~done)
    T = sp.csr_matrix((np.concatenate([vals, np.ones(keep.size)]),
                       (np.concatenate([rows, keep]).astype(np.int64), np.concatenate([cols, keep]).astype(np.int64))),
                      shape=(n, n))
    return T


def _columns(mats: dict, ncols: dict) -> dict:
    """:func:`read_dmig`'s matrices (an entry's row, column and line each) as :class:`DmigColumns`."""
    out = {}
    for name, (ifo, r, c, v, line) in mats.items():
        code = c[:, 0] * 8 + c[:, 1]
        first = np.flatnonzero(np.r_[True, code[1:] != code[:-1]]) if code.size else np.zeros(0, np.int64)
        out[name] = DmigColumns(ifo, r[:, 0] * 8 + r[:, 1], code[first], np.diff(np.r_[first, code.size]), v, line,
                                ncols.get(name))
    return out


def _read_columns(path: Path, lines: bool = False) -> dict:
    """All DMIG matrices of ``path`` as :class:`DmigColumns`: streamed when the file allows, else card by card."""
    got = scan_dmig(path, lines=lines)
    return got if got is not None else _columns(*_dmig_cards(Path(path)))


def _dof(code) -> str:
    return f"{int(code) // 8}-{int(code) % 8}"


def _check_columns(path, name, m: DmigColumns) -> None:
    """What the column cards of a square DMIG stiffness or mass matrix declare, against its entries.

    Every row must have a column card of its own (its diagonal entry is in it): a row without
    one is a lost column card, whose entries went to the column before it. Entries within a
    column follow in row order as Nastran writes them: a few out of order are named (a moved or
    repeated line).
    """
    cols = np.sort(m.columns)
    for s in range(0, m.rows.size, 1 << 20):
        part = m.rows[s:s + (1 << 20)]
        k = np.minimum(np.searchsorted(cols, part), max(cols.size - 1, 0))
        miss = np.flatnonzero(cols[k] != part) if cols.size else np.arange(part.size)
        if miss.size:
            at = s + int(miss[0])
            lines = m.lines if m.lines is not None else _read_columns(Path(path), lines=True)[name].lines
            where = f" (line {int(lines[at])})"
            raise ReadError(path, f"DMIG {name} (form {m.ifo}, square): row {_dof(m.rows[at])}{where} has no column "
                                  f"card 'DMIG {name} {int(m.rows[at]) // 8} {int(m.rows[at]) % 8}': a column card "
                                  "lost (its entries read into the column before it)?")
    if m.rows.size < 2:
        return
    first = np.cumsum(m.counts)[:-1]  # the first entry of each column after the first one
    down = m.rows[1:] < m.rows[:-1]
    down[first[(first > 0) & (first < m.rows.size)] - 1] = False
    bad = np.flatnonzero(down)
    if 0 < bad.size <= 3:  # a file written in row order with a line moved or repeated (else: written in any order)
        k = int(bad[0])  # the entry out of place: k when k + 1 follows k - 1 in order, else k + 1
        k += not (k > 0 and m.rows[k + 1] > m.rows[k - 1])
        col = m.columns[np.searchsorted(np.cumsum(m.counts), k, side="right")]
        lines = m.lines if m.lines is not None else _read_columns(Path(path), lines=True)[name].lines
        where = f"line {int(lines[k])}: "
        warnings.warn(FlexmorWarning(f"{Path(path).name}: {where}DMIG {name}: entry {_dof(m.rows[k])} of column "
                                     f"{_dof(col)} follows row {_dof(m.rows[k - 1])}, out of the row order of the "
                                     f"other entries ({bad.size} such): a line moved or repeated from another "
                                     "column?"), stacklevel=3)


def dmig_matrices(path, mats, names):
    """CSR matrices by role and the equation map ``(grid, component)`` of the DMIG matrices ``names``.

    ``mats`` (:class:`DmigColumns` by name) gives up the matrices it assembles, so that their
    entries are freed as soon as they are used. An entry given twice is refused with its line;
    so is a row of a stiffness or mass matrix without a column card of its own (a lost column
    card). DMIG has no entry counts: in a matrix stored as one triangle a lost entry line cannot
    be seen, which one :class:`~flexmor.io.UncheckedWarning` says.
    """
    code = np.unique(np.concatenate([mats[name].columns for name in names.values()]))
    for name in names.values():  # rows without a column of their own (a rectangular block), in slices
        rows = mats[name].rows
        for s in range(0, rows.size, 1 << 20):
            k = np.minimum(np.searchsorted(code, rows[s:s + (1 << 20)]), code.size - 1)
            if np.any(code[k] != rows[s:s + (1 << 20)]):
                code = np.unique(np.concatenate([code, rows]))
                break
    del rows
    pairs = np.stack([code // 8, code % 8], axis=1)
    if np.any((pairs[:, 1] < 0) | (pairs[:, 1] > 6)):
        g = pairs[(pairs[:, 1] < 0) | (pairs[:, 1] > 6)][0]
        raise ReadError(path, f"DOF {g[0]}-{g[1]}: component must be 0 (scalar point) or 1..6")
    n = pairs.shape[0]
    idx = np.int32 if n < 2**31 - 1 else np.int64
    if code.size and code[0] >= 0 and code[-1] < 64 * n + 2**20:  # moderate codes: a table, no binary searches
        table = np.zeros(int(code[-1]) + 1, dtype=idx)
        table[code] = np.arange(n, dtype=idx)
        number = table.take
    else:
        def number(x):
            return np.searchsorted(code, x).astype(idx)
    out, unchecked = {}, False
    for role, name in names.items():
        if name not in mats:  # the same matrix in two roles
            out[role] = next(out[r] for r, nm in names.items() if nm == name and r in out)
            continue
        m = mats.pop(name)
        if np.iscomplexobj(m.values):
            raise ReadError(path, f"DMIG {name} is complex; flexmor needs real matrices")
        if role in ("K", "M") and m.ifo in (1, 6):
            _check_columns(path, name, m)
        if m.ifo == 9 and m.ncol is not None and np.unique(m.columns).size != m.ncol:
            raise ReadError(path, f"DMIG {name}: its header declares NCOL={m.ncol} columns, but the file has "
                                  f"{np.unique(m.columns).size} column cards of it: a column card lost or repeated?")
        parts = [number(m.rows), np.repeat(number(m.columns), m.counts), m.values]
        del m  # no other reference: assemble() frees the parsed entries as it goes
        lower, upper = bool(np.any(parts[0] > parts[1])), bool(np.any(parts[0] < parts[1]))
        A = assemble(parts, (n, n), mirror=lower != upper)  # one triangle stored: mirror it
        unchecked |= role in ("K", "M") and lower != upper  # both: the model's symmetry check sees a lost line
        if A is None:
            m = _read_columns(Path(path), lines=True)[name]
            r, c = m.rows, np.repeat(m.columns, m.counts)
            key = np.searchsorted(code, r) * np.int64(n) + np.searchsorted(code, c)
            order = np.argsort(key, kind="stable")
            k = int(order[np.flatnonzero(key[order][1:] == key[order][:-1])[0] + 1])
            raise ReadError(path, f"DMIG {name}: entry ({r[k] // 8}-{r[k] % 8}, {c[k] // 8}-{c[k] % 8}) given twice; "
                                  "duplicates are refused, not summed", int(m.lines[k]))
        out[role] = A
    if unchecked:
        warn_unchecked(path, "DMIG cards have no entry counts; a lost entry line, or one repeated into another "
                             "column in row order, could not be cross-checked")
    return out, pairs


def _op4_dofs(path, n, bulk: Bulk | None, geo, explicit):
    """Equation map of OP4 matrices of size ``n``: the a-set cards of the bulk file, else all grid DOFs."""
    if bulk is None:
        return None
    if bulk.seqgp:
        raise ReadError(geo, SEQGP_REFUSED)
    if bulk.aset:
        dofs = np.unique(np.array(bulk.aset, np.int64).reshape(-1, 2), axis=0)
        what = "the ASET/BSET/QSET DOFs"
    else:
        dofs = np.array([(g, c) for g in bulk.grid_ids for c in range(1, 7)] + [(s, 0) for s in bulk.spoints],
                        np.int64).reshape(-1, 2)
        dofs = dofs[np.lexsort((dofs[:, 1], dofs[:, 0]))]
        what = "6 DOFs per GRID plus the SPOINTs"
    if dofs.shape[0] != n:
        msg = f"{what} of {geo.name} give {dofs.shape[0]} equations, but the OP4 matrices have {n}"
        if explicit:
            raise ReadError(geo, msg)
        log.warning("%s; the model is read without node table", msg)
        return None
    return dofs


def _model_dofs(path, out, pairs, bulk, geo, directions):
    """Node table, equation map and matrices in basic directions (or kept local)."""
    if np.any(pairs[:, 1] == 0):
        g = pairs[pairs[:, 1] == 0][0]
        raise ReadError(path, f"DOF {g[0]}-0 is a scalar point (a superelement's modal coordinate): the file holds "
                              "a Craig-Bampton superelement, a reduced body rather than an FE model, which needs "
                              "grid DOFs 1..6; read it as a reduced body (format nastran-se)", params=("format",))
    if bulk is None:
        return out, np.zeros(0, np.int64), np.zeros((0, 3)), {}
    miss = ~np.isin(pairs[:, 0], bulk.grid_ids)
    if np.any(miss):
        raise ReadError(geo, f"grid {pairs[miss][0, 0]} of the matrices has no GRID card here")
    frames = {}
    if directions == "basic":
        T = dof_transform(bulk, pairs, geo)
        if T is not None:
            Tt = T.T.tocsr()
            out = {k: (T @ A @ Tt).tocsr() for k, A in out.items()}
            log.info("%s: equations of grids with a local CD system rotated to the basic system", path)
    else:
        frames = {int(g): bulk.frame(int(g)) for g, c in zip(bulk.grid_ids, bulk.cd) if c != 0}
    return out, bulk.grid_ids, bulk.xyz, frames


def load_matrices(path: Path, stiffness, mass, damping):
    """``(is_op4, matrices by name, {"K": name, "M": name[, "D": name]})`` of a DMIG or OP4 file."""
    op4 = suffix(path) == ".op4"
    mats = read_op4(path, sparse=True) if op4 else _read_columns(path)
    names = {"K": _pick(mats, stiffness, "K", "stiffness", path), "M": _pick(mats, mass, "M", "mass", path)}
    b = _pick(mats, damping, "B", "damping", path)
    if b:
        names["D"] = b
    return op4, mats, names


def op4_matrices(path, mats, names) -> dict:
    """The named OP4 matrices as CSR by role; refuses complex, non-square or differently sized ones.

    A damping matrix without any non-zero entry (Nastran writes "no damping" as a 1 x 1 null
    matrix, e.g. ``BXX`` of ``EXTSEOUT`` beside 46 x 46 ``KXX``/``MXX``) is read as zero
    damping: it is dropped from ``names`` and the result. Each converted matrix is released
    from ``mats`` (only one copy of it is held at a time).
    """
    shapes = {nm: A.shape for nm, A in mats.items()}
    out = {}
    for role, nm in list(names.items()):
        if mats[nm] is None:  # the same matrix in two roles
            out[role] = next(out[r] for r, m in names.items() if m == nm and r in out)
            continue
        A = mats[nm]
        if role == "D" and A.count_nonzero() == 0:
            log.info("%s: damping matrix %s %s is null: read as zero damping", path, nm, A.shape)
            del names[role]
            continue
        if np.iscomplexobj(A.data):
            raise ReadError(path, f"matrix {nm} is complex; flexmor needs real matrices")
        if A.shape[0] != A.shape[1]:
            raise ReadError(path, f"matrix {nm} is {A.shape[0]} x {A.shape[1]}, not square")
        out[role] = sp.csr_matrix(A)
        mats[nm] = A = None
    n = out["K"].shape[0]
    if any(A.shape != (n, n) for A in out.values()):
        raise ReadError(path, "the matrices " + ", ".join(f"{nm} {shapes[nm]}" for nm in names.values())
                              + " differ in size")
    return out


def read_nastran(path, *, stiffness=None, mass=None, damping=None, geometry=None,
                 directions: str = "basic") -> FEModel:
    """Read stiffness and mass (and damping) from a DMIG punch file or an OP4 file.

    Parameters
    ----------
    path : str or path-like
        ``.pch`` (DMIG) or ``.op4`` (ASCII or binary), or either gzip-compressed (``.pch.gz``,
        decompressed while read; the bulk-data file beside it plain or ``.gz``).
    stiffness, mass, damping : str, optional
        Matrix names (default: the one name starting with K, M, B).
    geometry : str or path-like, optional
        Bulk-data file with the GRID cards (default ``<stem>.bdf``/``.dat``/``.nas``/``.asm``
        beside the file). For OP4 its ASET/BSET cards (else 6 DOFs per GRID) give the
        equation map.
    directions : {'basic', 'local'}
        ``basic``: equations of grids with a displacement system ``CD`` other than basic are
        rotated to basic x y z (``K_b = T K T^T``), so ports and couplings see global
        directions; needs all three translations (rotations) of such a grid. ``local``:
        keep the ``CD`` components; the model's ``node_frames`` holds each such grid's
        directions, which couplings use and set ports refuse.

    Returns
    -------
    FEModel

    Raises
    ------
    ReadError
        Malformed cards or columns (with line number), missing or ambiguous matrix names,
        complex matrices, scalar points, duplicate entries, grids without coordinates,
        undefined or circular coordinate systems.
    """
    from ...errors import check_choice

    check_choice("directions", directions, ("basic", "local"))
    path = Path(path)
    op4, mats, names = load_matrices(path, stiffness, mass, damping)
    geo, bulk = bulk_of(path, geometry, op4)
    if op4:
        out = op4_matrices(path, mats, names)
        n = out["K"].shape[0]
        pairs = _op4_dofs(path, n, bulk, geo, geometry is not None)
        if pairs is None:
            bulk = None
    else:
        out, pairs = dmig_matrices(path, mats, names)
    kw = {}
    if pairs is not None:
        out, ids, xyz, frames = _model_dofs(path, out, pairs, bulk, geo, directions)
        kw = {"dofs": pairs, "node_ids": ids, "xyz": xyz}
        if bulk is not None and bulk.elements:
            kw["mesh"] = mesh_of_elements(bulk.elements, nastran_cell, "nastran", ids)
            kw["elements"] = nastran_elements(bulk, geo, ids)
        if frames:
            kw["node_frames"] = frames
    log.info("%s: matrices %s", path, names)
    return build_model(path, M=out["M"], K=out["K"], D=out.get("D"),
                       damping={"type": "given"} if "D" in out else {"type": "none"},
                       name=stem(path), source=str(path), **kw)


MODEL_FORMATS.register("nastran", [".pch", ".op4"], read_nastran, gzip=True,
                       description="Nastran DMIG punch file (KAAX/MAAX ...) or OP4 (ASCII or binary), "
                       "GRIDs from the .bdf")
