"""Nastran bulk data: card splitting, grid points, coordinate systems, elements and their materials.

Cards
    Small field (8 columns), large field (``NAME*`` with 16-column fields and ``*``
    continuations), free field (commas; a 10th field that is blank or starts with ``+``/``*``
    is a continuation marker and dropped). Columns 73-80 of fixed-field lines are the
    continuation marker and ignored; tabs expand to 8-column stops; ``$`` starts a comment.
    When the file has ``BEGIN BULK``, only the lines after it (up to ``ENDDATA``) are read.
    ``INCLUDE 'file'`` lines are followed (relative to the including file). Runs of plain
    one-line GRID cards are read as one block (:mod:`.nastran_grids`).
Grid points
    ``GRID ID CP X1 X2 X3 CD`` with blank CP/CD taken from ``GRDSET``. Positions in the
    ``CP`` system are converted to the basic system; the ``CD`` system is the one in which
    the grid's displacement components (and thus DMIG/OP4 rows and columns) are measured.
Coordinate systems
    ``CORD2R/C/S`` (points A, B, C in the reference system ``RID``, chains of any depth) and
    ``CORD1R/C/S`` (three grid points, two systems per card). Cylindrical coordinates are
    ``(R, theta[deg], Z)``, spherical ``(R, theta[deg], phi[deg])``. The displacement
    directions of a grid in a cylindrical (spherical) ``CD`` system are the local unit
    vectors ``(e_R, e_theta, e_Z)`` (``(e_R, e_theta, e_phi)``) at the grid's position; on
    the axis, where they are undefined, those at ``theta = 0`` are used.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import ReadError
from .._text import read_text
from .nastran_grids import BLANK, Grids, grid_form, grid_run

__all__ = ["Bulk", "CoordSystem", "cards", "num", "read_bulk"]

_IMPLICIT_EXP = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d+)$")
_MAX_INCLUDE_DEPTH = 20
_MIN_RUN = 8  # shorter runs of GRID lines are read card by card
_RUN = "GRID run"  # the card name of a run of GRID lines read as one block (no card has a blank)


def num(tok: str) -> float:
    """A Nastran real: ``1.5``, ``1.5E-3``, ``1.5D-3``, ``1.5-3`` (implicit exponent), ``.5``."""
    try:
        v = float(tok)  # the common forms at once
    except ValueError:
        t = tok.strip().upper().replace("D", "E")
        m = _IMPLICIT_EXP.match(t)
        v = float(f"{m.group(1)}E{m.group(2)}" if m else t)
    if not np.isfinite(v):
        raise ValueError(tok)
    return v


def _lines(path: Path, depth: int = 0):
    """``(path, lineno, line)`` of the bulk section, INCLUDEs expanded."""
    text = read_text(path)
    raw_lines = text.splitlines()
    start = 0
    if depth == 0:
        for k, ln in enumerate(raw_lines):
            if ln.lstrip().upper().startswith("BEGIN") and "BULK" in ln.upper().split("$")[0]:
                start = k + 1
                break
    for lineno, raw in enumerate(raw_lines[start:], start + 1):
        s = raw.split("$", 1)[0]
        u = s.strip().upper()
        if u.startswith("ENDDATA"):
            return
        if u.startswith("INCLUDE"):
            m = re.search(r"['\"]([^'\"]+)['\"]", s) or re.match(r"\s*INCLUDE\s+(\S+)", s, re.IGNORECASE)
            if not m:
                raise ReadError(path, "INCLUDE without a file name", lineno)
            if depth >= _MAX_INCLUDE_DEPTH:
                raise ReadError(path, f"INCLUDE nested deeper than {_MAX_INCLUDE_DEPTH} levels (a cycle?)", lineno)
            inc = Path(m.group(1))
            inc = inc if inc.is_absolute() else path.parent / inc
            if not inc.exists() and Path(f"{inc}.gz").is_file():  # shipped compressed: read as it is
                inc = Path(f"{inc}.gz")
            if not inc.exists():
                raise ReadError(path, f"included file {inc} not found", lineno)
            yield from _lines(inc, depth + 1)
            continue
        yield path, lineno, s.expandtabs(8).rstrip()


def cards(path):
    """Yield ``(path, lineno, NAME, fields, field line numbers)`` of each card, continuations merged.

    Each line contributes 8 fields (small field, free field) or 4 (large field).
    """
    yield from _cards(_lines(Path(path)))


_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*\*?")


def _cards(lines):
    """The cards of ``(path, lineno, line)`` triples (see :func:`cards`)."""
    card = None
    for fpath, lineno, line in lines:
        if not line.strip():
            continue
        if "," in line[:10]:
            parts = line.split(",")
            head, fields = parts[0].strip(), [p.strip() for p in parts[1:]]
            large = head.endswith("*") or head.startswith("*")
            width = 4 if large else 8
            if len(fields) > width and (fields[width] == "" or fields[width][0] in "+*") \
                    and not any(fields[width + 1:]):
                fields = fields[:width]
            fields = fields + [""] * (width - len(fields))
        elif line[0] == "*" or line[:8].strip().endswith("*"):
            head = line[:8].strip()
            fields = [line[i:i + 16].strip() for i in range(8, 72, 16)]
        else:
            head = line[:8].strip()
            fields = [line[i:i + 8].strip() for i in range(8, 72, 8)]
        if head and head[0] not in "*+" and not _NAME.fullmatch(head):
            raise ReadError(fpath, f"{line[:60]!r} does not start with a card name (a letter, then letters and "
                                   "digits): a damaged or cut line?", lineno)
        if head == "" or head[0] in "*+":
            if card is None:
                raise ReadError(fpath, f"continuation line without a card: {line[:60]!r}", lineno)
            card[3].extend(fields)
            card[4].extend([lineno] * len(fields))
            continue
        if card is not None:
            yield card
        card = (fpath, lineno, head.rstrip("*").upper(), fields, [lineno] * len(fields))
    if card is not None:
        yield card


def _continues(line: str) -> bool:
    """Whether a (non-blank) line continues the card before it."""
    head = line.split(",", 1)[0].strip() if "," in line[:10] else line[:8].strip()
    return head == "" or head[0] in "*+"


def _items(path: Path):
    """The cards of :func:`cards`, runs of plain GRID cards as one item each.

    A run is ``(path, line numbers, _RUN, (ids, cp, xyz, cd), None)`` (see
    :func:`~flexmor.io.nastran.nastran_grids.grid_run`); a run that does not parse as a
    block is read card by card.
    """
    lines = [t for t in _lines(path) if t[2]]
    i = start = 0
    n = len(lines)
    while i < n:
        form = grid_form(lines[i][2])
        if form is None:
            i += 1
            continue
        step = 2 if form == "large" else 1  # GRID* and its * continuation
        fpath, j = lines[i][0], i
        while j + step <= n and lines[j][0] is fpath is lines[j + step - 1][0] and grid_form(lines[j][2]) == form \
                and (step == 1 or (lines[j + 1][2][0] == "*" and "," not in lines[j + 1][2][:10])):
            j += step
        if j < n and j > i and _continues(lines[j][2]):
            j -= step  # the last GRID of the run goes on
        run = grid_run([t[2] for t in lines[i:j]], form) if j - i >= _MIN_RUN * step else None
        if run is not None:
            yield from _cards(lines[start:i])
            yield fpath, np.array([t[1] for t in lines[i:j:step]], dtype=np.int64), _RUN, run, None
            start = j
        i = max(j, i + 1)
    yield from _cards(lines[start:])


def _rect(kind: str, c) -> np.ndarray:
    """Rectangular coordinates of ``c`` given in a system of ``kind`` R, C or S."""
    c = np.asarray(c, dtype=np.float64)
    if kind == "R":
        return c
    if kind == "C":
        r, t, z = c[0], np.radians(c[1]), c[2]
        return np.array([r * np.cos(t), r * np.sin(t), z])
    r, t, p = c[0], np.radians(c[1]), np.radians(c[2])
    return np.array([r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p), r * np.cos(t)])


def _triad(kind: str, x) -> np.ndarray:
    """Columns: the local unit vectors of ``kind`` at rectangular point ``x`` (in that system's frame)."""
    if kind == "R":
        return np.eye(3)
    rho = np.hypot(x[0], x[1])
    t = np.arctan2(x[1], x[0]) if rho > 0 else 0.0
    ct, st = np.cos(t), np.sin(t)
    if kind == "C":
        return np.array([[ct, -st, 0.0], [st, ct, 0.0], [0.0, 0.0, 1.0]])
    th = np.arctan2(rho, x[2]) if (rho > 0 or x[2] != 0) else 0.0
    p = t
    ce, se, cp, sp_ = np.cos(th), np.sin(th), np.cos(p), np.sin(p)
    e_r = [se * cp, se * sp_, ce]
    e_t = [ce * cp, ce * sp_, -se]
    e_p = [-sp_, cp, 0.0]
    return np.array([e_r, e_t, e_p]).T


@dataclass
class CoordSystem:
    """A resolved coordinate system: origin and axes (columns of ``R``) in the basic system."""

    cid: int
    kind: str  # R, C, S
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    R: np.ndarray = field(default_factory=lambda: np.eye(3))

    def to_basic(self, c) -> np.ndarray:
        """Basic position of a point with coordinates ``c`` in this system."""
        return self.origin + self.R @ _rect(self.kind, c)

    def directions(self, x_basic) -> np.ndarray:
        """Columns: the displacement directions (basic components) at basic point ``x_basic``."""
        return self.R @ _triad(self.kind, self.R.T @ (np.asarray(x_basic) - self.origin))


BASIC = CoordSystem(0, "R")


@dataclass
class Bulk:
    """Geometry and DOF sets of a bulk-data file.

    Attributes
    ----------
    grid_ids : ndarray of int
    xyz : ndarray, shape (n, 3)
        Basic coordinates.
    cd : ndarray of int
        Displacement coordinate system of each grid (0 = basic).
    systems : dict of int to CoordSystem
    spoints : ndarray of int
        Scalar points (``SPOINT``, also the ``QSET`` modal coordinates of a superelement).
    aset : list of (int, int)
        ``(id, component)`` pairs named by ``ASET/BSET/CSET/QSET (and ...1)`` (component 0
        for scalar points).
    seqgp : bool
        The file resequences grids (``SEQGP``): matrix DOF order is then not the id order.
    elements : list of (str, list of int)
        Card name and grid ids of each element card of :data:`ELEMENT_GRIDS` (for the mesh).
    element_cards : list of (str, int, int, list of int)
        Card name, element id, property id and grid ids of each solid and shell element card
        (:data:`PROPERTY_ELEMENTS`).
    properties : dict of int to (str, int, path, int)
        ``PSOLID``/``PSHELL`` by property id: card name, material id, file and line.
    materials : dict of int to dict
        ``MAT1`` by material id (``E G NU RHO`` as given, None when blank; file and line);
        other material cards (``MAT2 MAT8 MAT9`` ...) as ``{"card": name}``.
    """

    grid_ids: np.ndarray
    xyz: np.ndarray
    cd: np.ndarray
    systems: dict
    spoints: np.ndarray
    aset: list
    seqgp: bool = False
    elements: list = field(default_factory=list)
    element_cards: list = field(default_factory=list)
    properties: dict = field(default_factory=dict)
    materials: dict = field(default_factory=dict)

    def frame(self, gid: int) -> np.ndarray:
        """3x3 matrix whose columns are grid ``gid``'s displacement directions in basic components."""
        i = int(np.searchsorted(self.grid_ids, gid))
        c = int(self.cd[i])
        return np.eye(3) if c == 0 else self.systems[c].directions(self.xyz[i])


def _int(f, k, default=0):
    t = f[k] if k < len(f) else ""
    return int(t) if t else default


def _real(f, k):
    t = f[k] if k < len(f) else ""
    return num(t) if t else 0.0


def _components(tok: str) -> list:
    if tok in ("", "0"):
        return [0]
    if not tok.isdigit() or any(ch not in "123456" for ch in tok):
        raise ValueError(tok)
    return sorted({int(ch) for ch in tok})


def _thru(toks) -> list:
    """Expand ``ID1 THRU ID2`` lists of ids."""
    out, k = [], 0
    toks = [t for t in toks if t]
    while k < len(toks):
        if k + 2 < len(toks) and toks[k + 1].upper() == "THRU":
            a, b = int(toks[k]), int(toks[k + 2])
            if b < a or b - a > 10_000_000:
                raise ValueError(f"{a} THRU {b}")
            out.extend(range(a, b + 1))
            k += 3
        else:
            out.append(int(toks[k]))
            k += 1
    return out


#: Element cards kept for the mesh: (index of the first grid field after the card name, most grids).
ELEMENT_GRIDS = {"CHEXA": (2, 20), "CTETRA": (2, 10), "CPENTA": (2, 15), "CPYRAM": (2, 13), "CQUAD4": (2, 4),
                 "CQUADR": (2, 4), "CQUAD8": (2, 8), "CTRIA3": (2, 3), "CTRIAR": (2, 3), "CTRIA6": (2, 6),
                 "CBAR": (2, 2), "CBEAM": (2, 2), "CROD": (2, 2), "CONROD": (1, 2)}


#: Element cards whose property (``PSOLID``, ``PSHELL``) names their material (id, property id, grids from field 2).
PROPERTY_ELEMENTS = ("CHEXA", "CTETRA", "CPENTA", "CQUAD4", "CQUADR", "CQUAD8", "CTRIA3", "CTRIAR", "CTRIA6")
_OTHER_MATERIALS = ("MAT2", "MAT3", "MAT8", "MAT9", "MAT10", "MAT11")


def _blank_real(f, k):
    t = f[k] if k < len(f) else ""
    return num(t) if t else None


def _element(name: str, f) -> list:
    """Grid ids of an element card; optional mid-side grids left blank drop all of them (corners only)."""
    first, most = ELEMENT_GRIDS[name]
    toks = [t for t in f[first:first + most]]
    grids = [int(t) for t in toks if t]
    corners = {"CHEXA": 8, "CPENTA": 6, "CTETRA": 4, "CPYRAM": 5, "CQUAD8": 4, "CTRIA6": 3}.get(name)
    if corners and len(grids) not in (corners, most):
        grids = [int(t) for t in toks[:corners]]
    return grids


def read_bulk(path) -> Bulk:
    """Read grids, coordinate systems, scalar points and a-set cards of a bulk-data file.

    Raises
    ------
    ReadError
        Malformed cards (with file and line), grids or systems defined twice, references to
        undefined systems or grids, circular definitions, degenerate CORD2 points.
    """
    path = Path(path)
    grids, cord2, cord1, spoints, aset, elements = Grids(), {}, {}, [], [], []
    element_cards, properties, materials = [], {}, {}
    seqgp = False
    gdef = {"cp": 0, "cd": 0}
    for fpath, lineno, name, f, _fl in _items(path):
        try:
            if name == _RUN:
                grids.add_run(fpath, lineno, f)
            elif name == "GRID":
                gid = int(f[0])
                x = [_real(f, k) for k in (2, 3, 4)]
                try:
                    cp, cd = (int(t) if t else BLANK for t in (f[1], f[5] if len(f) > 5 else ""))
                except ValueError:
                    raise ReadError(fpath, f"GRID {gid}: CP/CD must be integers", lineno) from None
                if not all(t.isascii() and t.isdigit() for t in f[6:8] if t):
                    raise ReadError(fpath, f"GRID {gid}: PS and SEID must be integers, got {f[6:8]} (a damaged "
                                           "card?)", lineno)
                grids.add(fpath, lineno, gid, cp, x, cd)
            elif name == "GRDSET":
                gdef = {"cp": _int(f, 1), "cd": _int(f, 5)}
            elif name in ("CORD2R", "CORD2C", "CORD2S"):
                cid = int(f[0])
                if cid <= 0 or cid in cord2 or cid in cord1:
                    raise ReadError(fpath, f"{name} {cid}: id must be positive and unique", lineno)
                cord2[cid] = (name[-1], _int(f, 1), np.array([_real(f, k) for k in range(2, 11)]).reshape(3, 3),
                              lineno, fpath)
            elif name in ("CORD1R", "CORD1C", "CORD1S"):
                for k in (0, 4):
                    if k < len(f) and f[k]:
                        cid = int(f[k])
                        if cid <= 0 or cid in cord2 or cid in cord1:
                            raise ReadError(fpath, f"{name} {cid}: id must be positive and unique", lineno)
                        cord1[cid] = (name[-1], [int(f[k + j]) for j in (1, 2, 3)], lineno, fpath)
            elif name in ELEMENT_GRIDS:
                elements.append((name, _element(name, f)))
                if name in PROPERTY_ELEMENTS:
                    element_cards.append((name, int(f[0]), _int(f, 1, int(f[0])), elements[-1][1]))
            elif name in ("PSOLID", "PSHELL"):
                properties[int(f[0])] = (name, _int(f, 1), fpath, lineno)
            elif name == "MAT1":
                materials[int(f[0])] = {"card": name, "E": _blank_real(f, 1), "G": _blank_real(f, 2),
                                        "NU": _blank_real(f, 3), "RHO": _blank_real(f, 4), "path": fpath,
                                        "line": lineno}
            elif name in _OTHER_MATERIALS:
                materials[int(f[0])] = {"card": name, "path": fpath, "line": lineno}
            elif name == "SEQGP":
                seqgp = True
            elif name == "SPOINT":
                spoints.extend(_thru(f))
            elif name in ("ASET", "BSET", "CSET", "QSET"):
                for k in range(0, len(f) - 1, 2):
                    if f[k]:
                        aset.extend((int(f[k]), c) for c in _components(f[k + 1]))
            elif name in ("ASET1", "BSET1", "CSET1", "QSET1"):
                comps = _components(f[0])
                aset.extend((i, c) for i in _thru(f[1:]) for c in comps)
        except ValueError as exc:
            raise ReadError(fpath, f"{name}: malformed field ({exc})", lineno) from None
        except IndexError:
            raise ReadError(fpath, f"{name}: too few fields", lineno) from None
    bulk = _resolve(path, grids, gdef, cord2, cord1, spoints, aset)
    bulk.seqgp = seqgp
    bulk.elements = elements
    bulk.element_cards, bulk.properties, bulk.materials = element_cards, properties, materials
    return bulk


def _resolve(path, grids, gdef, cord2, cord1, spoints, aset) -> Bulk:
    gids, cp, x, cd, linenos, fidx = grids.arrays()
    order = np.argsort(gids, kind="stable")
    _check_unique(gids, order, linenos, fidx, grids.files)
    ids = gids[order]
    cp, x, cd, linenos, fidx = (a[order] for a in (cp, x, cd, linenos, fidx))
    cp = np.where(cp == BLANK, gdef["cp"], cp)
    cd = np.where(cd == BLANK, gdef["cd"], cd)
    cd[cd == -1] = 0  # -1: fluid grid point, no displacement system

    def where(k):
        return grids.files[fidx[k]], int(linenos[k])

    systems = {0: BASIC}
    xyz = np.zeros_like(x)  # basic positions
    done = np.zeros(ids.size, dtype=bool)
    pending_s = dict(cord2)
    pending_s.update(cord1)
    while True:
        progress = False
        for c in np.unique(cp[~done]).tolist():
            if c in systems:
                sel = np.flatnonzero(~done & (cp == c))
                if c == 0:
                    xyz[sel] = x[sel] + 0.0  # as BASIC.to_basic: -0.0 becomes 0.0
                else:
                    for k in sel.tolist():
                        xyz[k] = systems[c].to_basic(x[k])
                done[sel] = True
                progress = True
        for cid in list(pending_s):
            spec = pending_s[cid]
            if cid in cord2:
                kind, rid, P, lineno, fpath = spec
                if rid not in systems:
                    continue
                a, b, c = (systems[rid].to_basic(p) for p in P)
            else:
                kind, gl, lineno, fpath = spec
                k = np.minimum(np.searchsorted(ids, gl), max(ids.size - 1, 0))
                if not (ids.size and np.all(ids[k] == gl) and np.all(done[k])):
                    continue
                a, b, c = xyz[k]
            systems[cid] = _axes(fpath, lineno, cid, kind, a, b, c)
            del pending_s[cid]
            progress = True
        if done.all() and not pending_s:
            break
        if not progress:
            _unresolved(pending_s, cord2, ids, cp, np.flatnonzero(~done)[np.argsort(order[~done])], where)
    bad = np.flatnonzero(~np.isin(cd, list(systems)))
    if bad.size:
        fpath, lineno = where(int(bad[0]))
        raise ReadError(fpath, f"GRID {ids[bad[0]]}: displacement system CD={cd[bad[0]]} is not defined", lineno)
    return Bulk(ids, xyz, cd, systems, np.unique(np.asarray(spoints, np.int64)), aset)


def _check_unique(gids, order, linenos, fidx, files) -> None:
    """Refuse a grid id defined twice, at the first repeated definition in file order."""
    dup = np.flatnonzero(gids[order][1:] == gids[order][:-1])
    if dup.size:
        j = int(np.argmin(order[dup + 1]))
        k, first = int(order[dup[j] + 1]), int(order[dup[j]])
        raise ReadError(files[fidx[k]], f"GRID {gids[k]} defined twice (first on line {linenos[first]})",
                        int(linenos[k]))


def _unresolved(pending_s, cord2, ids, cp, pending_g, where):
    """Raise for the first definition that cannot be resolved; ``pending_g``: unresolved grids in file order."""
    for cid, spec in pending_s.items():
        if cid in cord2:
            kind, rid, _, lineno, fpath = spec
            if rid not in pending_s:
                raise ReadError(fpath, f"CORD2{kind} {cid}: reference system RID={rid} is not defined", lineno)
        else:
            kind, gl, lineno, fpath = spec
            miss = [g for g in gl if g not in set(ids[np.isin(ids, gl)].tolist())]
            if miss:
                raise ReadError(fpath, f"CORD1{kind} {cid}: grid {miss[0]} is not defined", lineno)
    for k in pending_g.tolist():
        if int(cp[k]) not in pending_s:
            fpath, lineno = where(k)
            raise ReadError(fpath, f"GRID {ids[k]}: coordinate system CP={cp[k]} is not defined", lineno)
    cid = next(iter(pending_s))
    fpath, lineno = pending_s[cid][-1], pending_s[cid][-2]
    raise ReadError(fpath, f"coordinate system {cid} depends on itself (circular CORD/GRID references)", lineno)


def _axes(fpath, lineno, cid, kind, a, b, c) -> CoordSystem:
    z = b - a
    nz = np.linalg.norm(z)
    xz = c - a
    scale = max(nz, np.linalg.norm(xz), 1e-300)
    y = np.cross(z, xz)
    if nz <= 1e-12 * scale or np.linalg.norm(y) <= 1e-12 * scale * scale:
        raise ReadError(fpath, f"coordinate system {cid}: points A, B, C are coincident or collinear", lineno)
    z = z / nz
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    return CoordSystem(cid, kind, a, np.column_stack([x, y, z]))
