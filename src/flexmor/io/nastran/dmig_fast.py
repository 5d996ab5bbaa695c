"""Vectorized, streamed reading of DMIG punch files as Nastran writes them (``PARAM,EXTOUT,DMIGPCH``).

A punched DMIG matrix is one large-field column card per column, ``DMIG*  NAME  GJ  CJ``, and
one continuation line per entry, ``*  GI  CI  A`` in fixed 16-character fields. Such files are
read in chunks of whole lines and parsed with NumPy a byte column at a time (the GRID and
other cards around them are skipped), straight into preallocated arrays: the text is never
held whole. :func:`scan_dmig` returns None for anything else (small or free field column
cards, tabs, ``INCLUDE``, ``BEGIN BULK``, blank first fields, complex or rectangular (form 9,
with its ``NCOL``) matrices, a field that does not parse, a column before its header card):
the card-by-card reader then reads the file and names the line of a defect.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._fastparse import parse_values, value_layout
from .._open import open_binary, size_hint
from .._text import check_text

__all__ = ["DmigColumns", "fast_dmig", "scan_dmig"]

_CHUNK = 1 << 21  # bytes read at a time
_PAD = b" " * 81  # fixed fields may reach past the last line of a chunk


class DmigColumns(NamedTuple):
    """One DMIG matrix, column by column: entries in file order, ``counts[k]`` of them in column ``k``.

    Codes are ``grid * 8 + component``.
    """

    ifo: int
    rows: np.ndarray  #: row code of each entry (int64)
    columns: np.ndarray  #: code of each column (int64)
    counts: np.ndarray  #: entries of each column (int64)
    values: np.ndarray  #: float64
    lines: np.ndarray | None  #: line number of each entry (int64), when asked for
    ncol: int | None = None  #: the number of columns a rectangular matrix (form 9) declares


def _fields(b, starts, offset, width=16):
    """The bytes of a fixed field ``[offset, offset + width)`` of each line, as an (n, width) array."""
    return sliding_window_view(b, width)[starts + offset]


def _right_ints(b, pos, bad, width=16):
    """The integers right-aligned in the fields ``b[pos:pos + width]`` (spaces, then up to 9 digits)."""
    bad |= np.any(sliding_window_view(b, width - 9)[pos] != 32, axis=1)
    acc = np.zeros(pos.size, dtype=np.int32)
    seen = np.zeros(pos.size, dtype=bool)
    for j in range(width - 9, width):
        c = np.take(b[j:], pos)
        d = c - np.uint8(48)
        isd = d < 10
        bad |= ~isd & (seen | (c != 32))  # a space after a digit, or another byte
        seen |= isd
        m = isd.view(np.uint8) * np.uint8(9)
        m += 1
        np.multiply(acc, m, out=acc, casting="unsafe")
        d *= isd
        np.add(acc, d, out=acc, casting="unsafe")
    bad |= ~isd  # the last byte is a digit
    return acc.astype(np.int64)


def _ints(b, starts, offset):
    """The integers in the fixed field at ``offset``: right-aligned by bytes, else by ``strtod``; None if not."""
    bad = np.zeros(starts.size, dtype=bool)
    got = _right_ints(b, starts + offset, bad)
    if not bad.any():
        return got
    block = _fields(b, starts, offset)
    out = np.full((block.shape[0], block.shape[1] + 1), 32, dtype=np.uint8)
    out[:, :-1] = block
    try:
        a = np.fromstring(out.tobytes(), dtype=np.int64, sep=" ")
    except ValueError:
        return None
    return a if a.size == block.shape[0] else None


def _reals(b, starts) -> np.ndarray | None:
    """The reals in the 16-character field at column 41 of each line: by the layout-checking parser
    of :mod:`flexmor.io._fastparse` when all share the first one's layout, else by ``strtod``."""
    if not starts.size:
        return np.zeros(0)
    lay = value_layout(b, int(starts[0]) + 56)
    if lay is not None and lay[0] <= 16:
        width, digits, mark, ne = lay
        bad = np.zeros(starts.size, dtype=bool)
        vals = parse_values(b, starts + 56 - width, width, digits, mark, ne, bad)
        if width < 16:
            bad |= np.any(_fields(b, starts, 40, 16 - width) != 32, axis=1)
        if not bad.any() and np.all(np.isfinite(vals)):
            return vals
    text = _fields(b, starts, 40).copy()
    text[(text == 68) | (text == 100)] = 69  # D exponent
    out = np.full((text.shape[0], 17), 32, dtype=np.uint8)
    out[:, :-1] = text
    try:
        a = np.fromstring(out.tobytes(), sep=" ")
    except ValueError:
        return None
    return a if a.size == starts.size and np.all(np.isfinite(a)) else None


def _header(line: bytes):
    """``(name, ifo, tin)`` of a small- or large-field DMIG header card (GJ = 0), else None."""
    s = line.decode("latin-1").rstrip()
    width = 16 if s[:8].rstrip().endswith("*") else 8
    f = [s[k:k + width].strip() for k in range(8, 8 + 4 * width, width)]
    if len(f) < 4 or f[1] != "0" or not f[2].isdigit() or not f[3].isdigit():
        return None
    return f[0].upper(), int(f[2]), int(f[3])


class _Scan:
    """State carried from chunk to chunk: the headers, the columns so far and the owner of continuation lines."""

    def __init__(self, capacity: int, lines: bool):
        self.headers: dict = {}  # name -> IFO
        self.col_names: list = []  # per chunk: the name of each column
        self.col_codes: list = []
        self.col_starts: list = []
        self.rows = np.empty(capacity, dtype=np.int64)
        self.vals = np.empty(capacity, dtype=np.float64)
        self.lines = np.empty(capacity, dtype=np.int64) if lines else None
        self.k = 0  # entries stored
        self.owner_is_col = False  # the last card before the chunk: a DMIG column?
        self.lineno = 0  # lines before the chunk

    def chunk(self, buf: bytes) -> bool:
        """Parse the whole lines ``buf``; False when the file needs the card reader."""
        size = len(buf)
        b = np.frombuffer(buf + _PAD, dtype=np.uint8)
        ends = np.flatnonzero(b[:size] == 10)
        starts = np.empty_like(ends)
        starts[0] = 0
        starts[1:] = ends[:-1] + 1
        length = ends - starts - (b[np.maximum(ends - 1, 0)] == 13)
        first = b[starts]
        keep = (length > 0) & (first != 36)  # not blank, not a $ comment
        lineno = np.flatnonzero(keep) + 1 + self.lineno
        self.lineno += ends.size
        starts, length, first = starts[keep], length[keep], first[keep]
        cont = first == 42
        if np.any((first == 32) | (first == 43)):
            return False  # blank first field or '+' continuations: small/free field
        heads = np.flatnonzero(~cont)
        word = _fields(b, starts[heads], 0, 8)
        low = word | 32
        for w in (b"incl", b"begi", b"endd"):  # INCLUDE, BEGIN BULK, ENDDATA: the card reader handles them
            if np.any(np.all(low[:, :4] == np.frombuffer(w, np.uint8), axis=1)):
                return False
        dmig = np.all(word[:, :4] == np.frombuffer(b"DMIG", np.uint8), axis=1)
        if np.any(np.all(low[:, :4] == np.frombuffer(b"dmig", np.uint8), axis=1) & ~dmig):
            return False  # lower-case card names
        large = dmig & (word[:, 4] == 42)
        cols = heads[large]
        gj, cj = _ints(b, starts[cols], 24), _ints(b, starts[cols], 40)
        if gj is None or cj is None or np.any((cj < 0) | (cj > 6)):
            return False
        for h in np.r_[heads[dmig & ~large], cols[gj == 0]].tolist():  # header cards: few, one by one
            got = _header(buf[starts[h]:starts[h] + length[h]])
            if got is None or got[2] > 2 or got[1] not in (1, 2, 6):
                return False  # a small-field column card, a complex matrix, a rectangular (NCOL) or unknown form
            self.headers[got[0]] = got[1]
        is_col = np.zeros(heads.size, dtype=bool)  # heads that are column cards (GJ != 0)
        is_col[np.flatnonzero(large)[gj != 0]] = True
        cols, gj, cj = cols[gj != 0], gj[gj != 0], cj[gj != 0]
        if np.any(length[cols] > 56) and np.any(_fields(b, starts[cols], 56)[length[cols] > 56] != 32):
            return False  # entries on the column card itself
        field = np.ascontiguousarray(_fields(b, starts[cols], 8)).view("S16").ravel()
        unique, which = np.unique(field, return_inverse=True)  # the few names, decoded once each
        names = [x.decode("latin-1").strip().upper() for x in unique.tolist()]
        if any(nm not in self.headers for nm in names):
            return False  # a column before its header: the card reader says so
        # the card owning each line: the last non-continuation line (before the chunk: carried over)
        owner = np.maximum.accumulate(np.where(~cont, np.arange(cont.size), -1))
        col_line = np.zeros(cont.size + 1, dtype=bool)  # lines that are column cards (the last: before the chunk)
        col_line[heads[is_col]] = True
        col_line[-1] = self.owner_is_col
        owned = col_line[owner]
        if heads.size:
            self.owner_is_col = bool(is_col[-1])
        entry = np.flatnonzero(cont & owned)
        before = np.searchsorted(entry, cols)  # entries of the chunk before each column card
        if np.any(length[entry] < 56):
            return False
        long = entry[length[entry] > 56]
        tail = _fields(b, starts[long], 56)
        if np.any((tail != 32) & (np.arange(16) < (length[long] - 56)[:, None])):
            return False  # an imaginary part or more fields
        g, c = _ints(b, starts[entry], 8), _ints(b, starts[entry], 24)
        v = _reals(b, starts[entry])
        if g is None or c is None or v is None or np.any((c < 0) | (c > 6)):
            return False
        m, k = entry.size, self.k
        if k + m > self.rows.size:  # only when the size of a compressed file's content was underestimated
            grow = max(k + m, self.rows.size + self.rows.size // 4)
            self.rows, self.vals = (np.concatenate([x[:k], np.empty(grow - k, x.dtype)])
                                    for x in (self.rows, self.vals))
            if self.lines is not None:
                self.lines = np.concatenate([self.lines[:k], np.empty(grow - k, np.int64)])
        g *= 8
        g += c
        self.rows[k:k + m], self.vals[k:k + m] = g, v
        if self.lines is not None:
            self.lines[k:k + m] = lineno[entry]
        self.col_names.append(np.asarray(names + [""])[which])
        self.col_codes.append(gj * 8 + cj)
        self.col_starts.append(before + k)
        self.k += m
        return True

    def result(self) -> dict | None:
        for x in (self.rows, self.vals, self.lines):
            if x is not None:
                x.resize(self.k, refcheck=False)  # realloc: the unused capacity is returned, nothing copied
        starts = np.concatenate(self.col_starts + [np.array([self.k])]).astype(np.int64)
        codes = np.concatenate(self.col_codes + [np.zeros(0, np.int64)])
        names = np.concatenate(self.col_names + [np.zeros(0, str)])
        out = {}
        for name in dict.fromkeys(names.tolist()):
            mine = np.flatnonzero(names == name)
            counts = starts[mine + 1] - starts[mine]
            if mine[-1] - mine[0] == mine.size - 1:  # columns in one run
                sel = slice(int(starts[mine[0]]), int(starts[mine[-1] + 1]))
            else:
                sel = np.concatenate([np.arange(starts[i], starts[i + 1]) for i in mine.tolist()])
            # copies, so that each matrix's entries are freed on their own once assembled
            out[name] = DmigColumns(self.headers[name], np.array(self.rows[sel]), codes[mine], counts,
                                    np.array(self.vals[sel]), None if self.lines is None else self.lines[sel])
        self.rows = self.vals = self.lines = None
        for name, ifo in self.headers.items():
            empty = np.zeros(0, np.int64)
            out.setdefault(name, DmigColumns(ifo, empty, empty, empty, np.zeros(0), None if self.lines is None
                                             else empty))
        return out or None


def scan_dmig(path, *, lines: bool = False) -> dict | None:
    """All DMIG matrices of a punch file as :class:`DmigColumns` by name, or None (see the module docstring).

    Parameters
    ----------
    path : str or path-like
    lines : bool
        Whether to record the line number of each entry (8 bytes per entry more).
    """
    path = Path(path)
    check_text(path)
    with open_binary(path) as f:
        scan = _Scan(size_hint(path) // 57 + 1, lines)  # an entry line has at least 56 characters and a line end
        rest = b""
        while True:
            block = f.read(_CHUNK)
            buf = rest + block
            if not buf:
                break
            if not block and buf[-1:] != b"\n":
                buf += b"\n"
            cut = buf.rfind(b"\n") + 1
            if cut == 0:
                rest = buf
                continue
            if b"\t" in buf or not scan.chunk(buf[:cut]):
                return None  # tabs: the card reader expands them
            rest = buf[cut:]
    return scan.result()


def fast_dmig(path) -> dict | None:
    """All DMIG matrices of a punch file, as :func:`~flexmor.io.nastran.read_dmig` returns them, or None."""
    got = scan_dmig(path, lines=True)
    if got is None:
        return None
    out = {}
    for name, m in got.items():
        cols = np.repeat(m.columns, m.counts)
        out[name] = (m.ifo, np.stack([m.rows // 8, m.rows % 8], axis=1), np.stack([cols // 8, cols % 8], axis=1),
                     m.values, m.lines)
    return out
