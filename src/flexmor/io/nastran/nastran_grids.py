"""Runs of plain ``GRID`` cards parsed as one block with NumPy.

A bulk-data file of a large model is mostly ``GRID`` cards, one line each (two in large
field). Consecutive cards of the same form (small field ``GRID    ID      CP      X1 ...``,
large field ``GRID*`` with one ``*`` continuation, or free field ``GRID,ID,CP,X1,X2,X3,CD``)
are cut into a table of fields at once: fixed-field lines padded to 72 columns and sliced as a
byte matrix (8 or 16 columns a field), free-field lines split at their commas when every line
has the same number of fields. Each column is then
converted by NumPy's string casts, which parse integers and reals as Python's ``int`` and
``float`` do (the same doubles as ``strtod``).

:func:`grid_run` returns None for a run that does not fit (other field counts, Nastran's
implicit exponents ``1.5-3`` or ``D`` exponents, non-finite values, malformed fields, non-ASCII
text); the caller then reads those lines card by card, which names the line of a defect.
:class:`Grids` keeps the grids of runs and single cards as arrays in file order.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BLANK", "Grids", "grid_form", "grid_run"]

#: CP or CD field left blank (the ``GRDSET`` default applies).
BLANK = np.iinfo(np.int64).min
_WIDTH = 72  # columns 73-80 are the continuation marker
_MAX_FREE_FIELDS = 8  # ID CP X1 X2 X3 CD PS SEID


def grid_form(line: str) -> str | None:
    """``"small"``, ``"large"`` or ``"free"`` for a line that starts a plain ``GRID`` card, else None."""
    if line.startswith("GRID,"):
        return "free"
    if line.startswith("GRID") and "," not in line[:10]:
        head = line[:8].rstrip()
        return "small" if head == "GRID" else "large" if head == "GRID*" else None
    return None


def grid_run(lines: list, form: str):
    """``(ids, cp, xyz, cd)`` of ``GRID`` cards all of ``form``, or None when one does not fit.

    ``lines`` are one per card, or for ``"large"`` the head and its continuation line of each
    card. Blank CP and CD fields are :data:`BLANK`, blank coordinates 0.0; the fields PS and
    SEID are not read.
    """
    table = _free(lines) if form == "free" else _fixed(lines, form == "large")
    if table is None:
        return None
    try:
        ids = _ints(table[:, 0], None)
        if ids is None:
            return None
        cp, cd = _ints(table[:, 1], BLANK), _ints(table[:, 5], BLANK)
        xyz = np.column_stack([_reals(table[:, k]) for k in (2, 3, 4)])
    except (ValueError, OverflowError):
        return None
    if not np.all(np.isfinite(xyz)):
        return None
    return ids, cp, xyz, cd


def _fixed(lines: list, large: bool):
    """The fields ID to CD of fixed-field cards as an ``(n, 6)`` array of 8- or 16-byte strings."""
    try:
        raw = "".join(ln[:_WIDTH].ljust(_WIDTH) for ln in lines).encode("ascii")
    except UnicodeEncodeError:
        return None
    if not large:
        b = np.frombuffer(raw, dtype=np.uint8).reshape(-1, _WIDTH)
        if not _integer_fields(b[:, 56:72]):
            return None
        return np.ascontiguousarray(b[:, 8:56]).view("S8")
    b = np.frombuffer(raw, dtype=np.uint8).reshape(-1, 2 * _WIDTH)
    if not _integer_fields(b[:, _WIDTH + 40:_WIDTH + 72]):
        return None
    return np.ascontiguousarray(np.hstack([b[:, 8:_WIDTH], b[:, _WIDTH + 8:_WIDTH + 40]])).view("S16")


def _integer_fields(b: np.ndarray) -> bool:
    """Whether the bytes of the PS and SEID fields are digits and blanks only (else the card reader names them)."""
    return bool(np.all(((b >= 48) & (b <= 57)) | (b == 32)))


def _free(lines: list):
    """The fields 2-7 of free-field lines as an ``(n, 6)`` string array (blank beyond a line's end)."""
    n_fields = lines[0].count(",")
    if n_fields > _MAX_FREE_FIELDS or any(ln.count(",") != n_fields for ln in lines):
        return None
    toks = ",".join(lines).split(",")
    try:
        table = np.array(toks, dtype="S").reshape(len(lines), n_fields + 1)
    except UnicodeEncodeError:
        return None
    rest = np.strings.strip(table[:, 7:9])
    if rest.size and not np.all(np.strings.isdigit(rest) | (rest == b"")):
        return None  # PS or SEID not an integer: the card reader names it
    table = table[:, 1:7]
    if table.shape[1] < 6:
        table = np.concatenate([table, np.full((len(lines), 6 - table.shape[1]), "", dtype=table.dtype)], axis=1)
    return table


def _ints(col: np.ndarray, blank):
    """Integers of a column; blank fields are ``blank`` (None: a blank field does not fit)."""
    empty = np.strings.strip(col) == col.dtype.type()
    if not empty.any():
        return col.astype(np.int64)
    if blank is None:
        return None
    out = np.full(col.size, blank, dtype=np.int64)
    out[~empty] = col[~empty].astype(np.int64)
    return out


def _reals(col: np.ndarray) -> np.ndarray:
    """Reals of a column; blank fields are 0.0."""
    empty = np.strings.strip(col) == col.dtype.type()
    if not empty.any():
        return col.astype(np.float64)
    out = np.zeros(col.size)
    out[~empty] = col[~empty].astype(np.float64)
    return out


class Grids:
    """GRID cards as arrays, in file order: runs added whole, single cards collected and added as a block."""

    def __init__(self):
        self.blocks, self.one, self.files = [], [], []

    def _file(self, fpath) -> int:
        if not self.files or self.files[-1] != fpath:
            self.files.append(fpath)
        return len(self.files) - 1

    def add(self, fpath, lineno, gid, cp, x, cd):
        """Collect one GRID card (id ``gid``, frames ``cp`` and ``cd``, coordinates ``x``) read at ``lineno``."""
        if any(not BLANK <= v < 2**63 for v in (gid, cp, cd)):
            from ...errors import ReadError
            raise ReadError(fpath, f"GRID {gid}: an id, CP or CD beyond the 64-bit integer range (a damaged card?)",
                            lineno)
        self.one.append((gid, cp, *x, cd, lineno, self._file(fpath)))

    def add_run(self, fpath, linenos, run):
        """Add a run of GRID cards parsed as arrays ``(ids, cp, xyz, cd)`` at ``linenos``, after the cards collected."""
        self._flush()
        ids, cp, xyz, cd = run
        self.blocks.append((ids, cp, xyz, cd, linenos, np.full(ids.size, self._file(fpath))))

    def _flush(self):
        if self.one:
            a = np.array(self.one, dtype=object)
            self.blocks.append((a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 2:5].astype(np.float64),
                                a[:, 5].astype(np.int64), a[:, 6].astype(np.int64), a[:, 7].astype(np.int64)))
            self.one = []

    def arrays(self):
        """``(ids, cp, xyz, cd, line numbers, file indices)`` of all grids in file order."""
        self._flush()
        if not self.blocks:
            return (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64),
                    np.zeros(0, np.int64), np.zeros(0, np.int64))
        return tuple(np.concatenate(c) for c in zip(*self.blocks))
