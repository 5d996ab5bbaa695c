"""Vectorized reading of DMIG punch files as Nastran writes them (``PARAM,EXTOUT,DMIGPCH``).

A punched DMIG matrix is one large-field column card per column, ``DMIG*  NAME  GJ  CJ``, and
one continuation line per entry, ``*  GI  CI  A`` in fixed 16-character fields. Such files are
parsed with NumPy a field column at a time (the GRID and other cards around them are skipped).
:func:`fast_dmig` returns None for anything else (small or free field column cards, tabs,
``INCLUDE``, ``BEGIN BULK``, blank first fields, complex matrices, a field that does not parse):
the card-by-card reader then reads the file and names the line of a defect.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._fastparse import parse_values, value_layout
from .._text import check_text

__all__ = ["fast_dmig"]



def _fields(b, starts, offset, width=16):
    """The bytes of a fixed field ``[offset, offset + width)`` of each line, as an (n, width) array."""
    return sliding_window_view(b, width)[starts + offset]


def _separated(block) -> bytes:
    """The fields of ``block`` one after the other, a space after each."""
    out = np.full((block.shape[0], block.shape[1] + 1), 32, dtype=np.uint8)
    out[:, :-1] = block
    return out.tobytes()


def _ints(block) -> np.ndarray | None:
    if not block.size:
        return np.zeros(0, dtype=np.int64)
    try:
        a = np.fromstring(_separated(block), dtype=np.int64, sep=" ")
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
    try:
        a = np.fromstring(_separated(text), sep=" ")
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


def fast_dmig(path) -> dict | None:
    """All DMIG matrices of a punch file, as :func:`~flexmor.io.nastran.read_dmig` returns them, or None."""
    path = Path(path)
    check_text(path)
    size = path.stat().st_size
    raw = bytearray(size + 81)  # padding: fixed fields may reach past the last line
    with open(path, "rb") as f:
        if f.readinto(memoryview(raw)[:size]) != size:
            return None
    if raw.find(b"\t", 0, size) >= 0:
        return None
    if raw[size - 1] != 10:
        raw[size] = 10
        size += 1
    raw[size:] = b" " * (len(raw) - size)
    b = np.frombuffer(raw, dtype=np.uint8)
    ends = np.flatnonzero(b[:size] == 10)
    starts = np.r_[0, ends[:-1] + 1]
    length = ends - starts - (b[np.maximum(ends - 1, 0)] == 13)
    first = b[starts]
    keep = (length > 0) & (first != 36)  # not blank, not a $ comment
    starts, length, first, lineno = starts[keep], length[keep], first[keep], np.flatnonzero(keep) + 1
    cont = first == 42
    if np.any(np.isin(first, (32, 43))):
        return None  # blank first field or '+' continuations: small/free field
    heads = np.flatnonzero(~cont)
    word = _fields(b, starts[heads], 0, 8)
    low = word | 32
    for w in (b"incl", b"begi", b"endd"):  # INCLUDE, BEGIN BULK, ENDDATA: the card reader handles them
        if np.any(np.all(low[:, :4] == np.frombuffer(w, np.uint8), axis=1)):
            return None
    dmig = np.all(word[:, :4] == np.frombuffer(b"DMIG", np.uint8), axis=1)
    if np.any(np.all(low[:, :4] == np.frombuffer(b"dmig", np.uint8), axis=1) & ~dmig):
        return None  # lower-case card names
    large = dmig & (word[:, 4] == 42)
    col_heads = heads[large]
    gj = _ints(_fields(b, starts[col_heads], 24))
    cj = _ints(_fields(b, starts[col_heads], 40))
    if gj is None or cj is None:
        return None
    headers = {}
    for h in np.r_[heads[dmig & ~large], col_heads[gj == 0]].tolist():  # header cards: few, one by one
        got = _header(bytes(raw[starts[h]:starts[h] + length[h]]))
        if got is None:
            return None  # a small-field column card
        if got[2] > 2 or got[1] not in (1, 2, 6, 9):
            return None
        headers[got[0]] = got[1]
    is_col = gj != 0
    col_heads, gj, cj = col_heads[is_col], gj[is_col], cj[is_col]
    if np.any(length[col_heads] > 56) and np.any(_fields(b, starts[col_heads], 56)[length[col_heads] > 56] != 32):
        return None  # entries on the column card itself
    names = [bytes(x).decode("latin-1").strip().upper() for x in _fields(b, starts[col_heads], 8)]
    owner = np.maximum.accumulate(np.where(~cont, np.arange(cont.size), -1))
    col_of = np.full(cont.size, -1)
    col_of[col_heads] = np.arange(col_heads.size)
    owned = np.where(owner >= 0, col_of[np.maximum(owner, 0)], -1)
    entry = np.flatnonzero(cont & (owned >= 0))
    if np.any(length[entry] < 56):
        return None
    tail = _fields(b, starts[entry], 56)
    if np.any((tail != 32) & (np.arange(16) < (length[entry] - 56)[:, None])):
        return None  # an imaginary part or more fields
    g = _ints(_fields(b, starts[entry], 8))
    c = _ints(_fields(b, starts[entry], 24))
    v = _reals(b, starts[entry])
    if g is None or c is None or v is None or np.any((c < 0) | (c > 6)) or np.any((cj < 0) | (cj > 6)):
        return None
    col = owned[entry]
    out = {}
    for name in dict.fromkeys(names):
        if name not in headers:
            return None
        mine = np.flatnonzero(np.asarray(names) == name)
        sel = np.flatnonzero(np.isin(col, mine))
        k = col[sel]
        out[name] = (headers[name], np.stack([g[sel], c[sel]], axis=1), np.stack([gj[k], cj[k]], axis=1), v[sel],
                     lineno[entry[sel]])
    for name, ifo in headers.items():
        out.setdefault(name, (ifo, np.zeros((0, 2), np.int64), np.zeros((0, 2), np.int64), np.zeros(0),
                              np.zeros(0, np.int64)))
    return out or None
