"""Streamed, vectorized reading of ASCII OP4 files, and the header parsing both ASCII readers share.

An ASCII OP4 matrix is a header line (``NCOL NROW FORM TYPE NAME`` and a Fortran format such
as ``1P,3E24.16``: values per line and field width), then per stored column a record line
``ICOL IROW NW`` followed by its values in fixed-width fields, ``per_line`` to a line (sparse
columns, ``IROW = 0``: a string header line before each run of rows). :func:`fast_ascii`
reads the file in chunks of whole lines: the record lines of a chunk (those of integers only)
are parsed at once by ``np.fromstring`` and the structure (strings per sparse column, value
lines per record, column order) is checked with array arithmetic; the value fields are parsed
at once by :func:`~flexmor.io._fastparse.parse_values` (the double ``strtod`` gives). Rows,
values and column counts go straight into arrays per matrix, which become its CSC matrix as
they are (no Python loop per column or string). Fields of another form (``1.0-3``, a
three-digit exponent without its letter) are parsed one by one like the line scanner does.
It returns None for anything irregular (blank or trailing characters, lines of another
length than the format says, records out of column order, overlapping rows, a field that is
not a number, a truncated file): the line scanner of :mod:`.op4` then reads the file and
names the line of a defect.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import scipy.sparse as sp

from ...errors import ReadError
from .._fastparse import parse_values, value_layout
from .._open import open_binary
from .nastran_bulk import num

__all__ = ["check_header", "fast_ascii", "is_header", "is_values", "matrix_header"]

_CHUNK = 1 << 21  # bytes read at a time
_HEADER = re.compile(r"^\s*(-?\d+)\s+(-?\d+)\s+(\d+)\s+(\d+)\s*(\S+)\s*(.*)$")
_FMT = re.compile(r"(\d+)\s*[EeDd]\s*(\d+)\.(\d+)")


def check_header(path, ncol, nrow, form, typ, name, where):
    """Refuse an impossible or implausibly large OP4 matrix header (``where``: line or None)."""
    if ncol < 0 or nrow == 0 and ncol > 0 or typ not in (1, 2, 3, 4) or not 1 <= form <= 18:
        raise ReadError(path, f"OP4 header of {name!r}: ncol={ncol} nrow={nrow} form={form} type={typ} is not a "
                              "valid matrix header", where)
    if abs(nrow) * max(ncol, 1) > 10**13:
        raise ReadError(path, f"OP4 header of {name!r}: {abs(nrow)} x {ncol} is implausibly large; is the file "
                              "corrupt?", where)


def is_header(line: str) -> bool:
    """Whether ``line`` looks like a matrix header (four integers and a name)."""
    return bool(_HEADER.match(line)) and len(line.split()) > 3


def matrix_header(path, h: str, lineno: int):
    """``(ncol, nrow, form, typ, NAME, per_line, width)`` of the ASCII matrix header line ``h``."""
    try:
        ncol, nrow, form, typ = (int(h[k:k + 8]) for k in range(0, 32, 8))
        name, fmt = h[32:40].strip(), h[40:]
        if not name:
            raise ValueError
    except ValueError:
        m = _HEADER.match(h)
        if not m:
            raise ReadError(path, f"expected an OP4 header 'ncol nrow form type NAME format', got {h[:60]!r}",
                            lineno) from None
        ncol, nrow, form, typ = (int(m.group(k)) for k in range(1, 5))
        name, fmt = m.group(5), m.group(6)
        f = _FMT.search(name)
        if f:  # name and format touch
            name, fmt = name[:f.start()].rstrip("1P,").rstrip(), name[f.start():] + fmt
    f = _FMT.search(fmt)
    per_line, width = (int(f.group(1)), int(f.group(2))) if f else (5, 16)
    name = name.upper()
    check_header(path, ncol, nrow, form, typ, name, lineno)
    if per_line < 1 or width < 2:
        raise ReadError(path, f"matrix {name}: unusable number format {fmt.strip()!r}", lineno)
    return ncol, nrow, form, typ, name, per_line, width


def is_values(line: str) -> bool:
    """Whether ``line`` holds values (the dummy value line after a sparse matrix's closing record)."""
    try:
        num(line.split()[0])
        return "." in line or "E" in line.upper()
    except (ValueError, IndexError):
        return False


class _Matrix:
    """The matrix being read: its header, and its CSC data filled a chunk at a time.

    ``vals`` (values, two per complex entry) and ``rows`` (row of each entry) are sized from
    the first chunk's columns (at most the file's remaining bytes over the field width),
    grown should a later column hold more, and shrunk in place at the end.
    """

    def __init__(self, head, cap):
        self.ncol, nrow, self.form, typ, self.name, self.per_line, self.width = head
        self.nrow, self.bigmat, self.cplx = abs(nrow), nrow < 0 or abs(nrow) >= 65536, typ > 2
        self.wper = 1 if typ & 1 else 2
        self.idx = np.int32 if self.nrow < 2**31 - 1 else np.int64
        self.vals, self.rows, self.k, self.e, self.cap = np.empty(0), np.empty(0, self.idx), 0, 0, cap
        self.counts = np.zeros(self.ncol + 1, np.int64)  # entries per column (1-based)
        self.last = (0, 0)  # column and end row of the last entry: columns in order, rows not overlapping
        self.bad = False

    def put(self, icol, r0, n, values: np.ndarray) -> None:
        """Append records ``(column, first row, values)`` and their values; a broken rule sets ``bad``."""
        ne = n // 2 if self.cplx else n
        if self.bad or self.cplx and np.any(n % 2) or np.any(
                (icol < 1) | (icol > self.ncol) | (r0 < 1) | (r0 - 1 + ne > self.nrow)):
            self.bad = True
            return
        keep = ne > 0
        icol, r0, ne = icol[keep], r0[keep], ne[keep]
        c = np.r_[self.last[0], icol]
        stop = np.r_[self.last[1], r0 + ne]
        if np.any((c[1:] < c[:-1]) | ((c[1:] == c[:-1]) & (r0 < stop[:-1]))):
            self.bad = True  # out of column order or overlapping rows
            return
        if icol.size:
            self.last = (int(c[-1]), int(stop[-1]))
        k, e = self.k + values.size, self.e + int(ne.sum())
        if self.vals.size == 0 and icol.size:  # extrapolated from the first columns
            self.cap = min(self.cap, int(k * 1.05 * self.ncol / icol[-1]) + 1024)
        if k > self.vals.size:
            grow = max(k, self.cap, self.vals.size + self.vals.size // 4)
            self.vals = np.concatenate([self.vals[:self.k], np.empty(grow - self.k)])
            self.rows = np.concatenate([self.rows[:self.e], np.empty(grow // (2 if self.cplx else 1) - self.e,
                                                                     self.idx)])
        self.vals[self.k:k] = values
        rows = self.rows[self.e:e]
        rows[:] = np.arange(e - self.e, dtype=self.idx)
        rows -= np.repeat((np.cumsum(ne) - ne - (r0 - 1)).astype(self.idx), ne)
        self.counts += np.bincount(icol, weights=ne, minlength=self.ncol + 1).astype(np.int64)
        self.k, self.e = k, e

    def matrix(self):
        """``(form, CSC matrix)``, or None when the records broke a rule (the scanner names it)."""
        if self.bad:
            return None
        vals, rows = self.vals, self.rows
        vals.resize(self.k, refcheck=False)  # realloc: the unused capacity is returned
        rows.resize(self.e, refcheck=False)
        if self.cplx:
            vals = vals.view(np.complex128)
        indptr = np.cumsum(self.counts).astype(self.idx if self.e < 2**31 - 1 else np.int64)
        return self.form, sp.csc_matrix((vals, rows, indptr), shape=(self.nrow, self.ncol))


def fast_ascii(path, size: int):
    """Matrices of the ASCII OP4 file ``path`` (``size`` bytes) as ``{NAME: (form, CSC)}``, or None."""
    out, m = {}, None
    with open_binary(path) as f:
        rest, eof, done = b"", False, 0
        while not eof:
            block = f.read(_CHUNK)
            eof = not block
            buf = rest + block if rest else block
            if eof and buf and not buf.endswith(b"\n"):
                buf += b"\n"
            cut = buf.rfind(b"\n") + 1
            if cut == 0:
                rest = buf
                continue
            got = _Chunk(buf, cut).walk(path, m, out, size - done, eof)
            if got is None:
                return None
            m, used = got
            done += used
            rest = buf[used:]
            if eof and rest.strip():
                return None
    return out if m is None and out else None


class _Chunk:
    """The whole lines of a chunk: line table, and the integers of the lines that hold integers only."""

    _MAXINT = 64  # longest line of integers

    def __init__(self, buf: bytes, cut: int):
        self.buf = buf
        b = self.b = np.frombuffer(buf, dtype=np.uint8, count=cut)
        nl = np.flatnonzero(b == 10)
        self.starts = np.empty_like(nl)
        self.starts[:1] = 0
        self.starts[1:] = nl[:-1] + 1
        self.ends = nl - (np.take(b, nl - 1, mode="clip") == 13) * (nl > self.starts)
        self.n = nl.size
        length = self.ends - self.starts
        mark = np.take(b, self.ends - 4, mode="clip") | 32  # E or D four bytes before the end: a value line
        short = np.flatnonzero((length <= self._MAXINT) & (mark != 101) & (mark != 100))  # record lines among these
        s, e = self.starts[short], self.ends[short]
        width = int((e - s).max(initial=0))
        pad = np.concatenate([b, np.full(width + 1, 32, np.uint8)])
        t = np.take(pad, s[:, None] + np.arange(width + 1))
        t[np.arange(width + 1) >= (e - s)[:, None]] = 32
        isint = np.all(((t >= 48) & (t <= 57)) | (t == 32) | (t == 45) | (t == 43), axis=1)
        self.ilines, t = short[isint], t[isint]  # lines of integers only (record lines, blank lines)
        self.count = (~(t == 32)[:, :-1] & (t == 32)[:, 1:]).sum(axis=1)  # tokens (each ends before a blank)
        self.ints = None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # text that does not parse: fewer numbers, checked below
                ints = np.fromstring(t.tobytes(), dtype=np.int64, sep=" ") if t.size else np.zeros(0, np.int64)
        except ValueError:
            return
        if ints.size != int(self.count.sum()):
            return
        self.count[self.count > 3] = 0  # not a record line
        off = np.cumsum(self.count) - self.count
        self.ints = np.zeros((t.shape[0], 3), np.int64)
        for k in range(3):
            has = self.count > k
            self.ints[has, k] = ints[off[has] + k]

    def line(self, i: int) -> bytes:
        return self.buf[self.starts[i]:self.ends[i]]

    def walk(self, path, m, out, left_bytes, eof):
        """Read the matrices of the chunk; ``(matrix being read, bytes used)`` or None."""
        if self.ints is None:
            return None
        i, finished = 0, []
        while i < self.n:
            if m is None:
                line = self.line(i)
                if line.strip():
                    try:
                        head = matrix_header(path, line.decode("latin-1"), None)
                    except ReadError:
                        return None
                    m = _Matrix(head, left_bytes // head[6] + 1)
                i += 1
                continue
            got = self._body(m, i, eof)
            if got is None:
                return None
            closing, i = got
            if not closing:
                break
            nxt = self._closing(m, i, eof)
            if nxt is None:
                return None
            if nxt < 0:
                break
            finished.append(m)
            m, i = None, nxt
        for x in finished:
            got = x.matrix()
            if got is None:
                return None
            out[x.name] = got
        return m, int(self.starts[i]) if i < self.n else self.b.size

    def _closing(self, m, i, eof):
        """Line after the closing record at line ``i`` and its value lines; -1: in the next chunk; None: irregular."""
        irow, nw = (int(x) for x in self.ints[np.searchsorted(self.ilines, i), 1:])
        skip = -(-nw // m.per_line) if irow > 0 else 1
        if i + 1 + skip > self.n:
            return None if eof else -1
        if irow <= 0 and not is_values(self.line(i + 1).decode("latin-1")):
            skip = 0
        return i + 1 + skip

    def _body(self, m, i, eof):
        """Parse the column records from line ``i`` up to the closing record or the last complete column.

        Returns ``(closing, line)``: the closing record's line, or (``closing`` False) the line
        to read on from with the next chunk; None when the lines are irregular.
        """
        il = self.ilines
        a = int(np.searchsorted(il, i))
        if a >= il.size or il[a] != i:
            return None
        col = self.count[a:] == 3
        end = np.flatnonzero(col & (self.ints[a:, 0] > m.ncol))
        closing = end.size > 0
        if closing:
            z = a + int(end[0])
        elif eof:
            return None
        else:  # up to the last column record of the chunk: its column may go on in the next one
            z = a + int(np.flatnonzero(col)[-1]) if col.any() else a
        if z == a:
            return closing, i
        lines, cnt, ints = il[a:z], self.count[a:z], self.ints[a:z]
        col = col[:z - a]
        if not col[0] or not np.all(col | (cnt == (2 if m.bigmat else 1))):
            return None
        gap = np.diff(np.append(lines, il[z])) - 1  # value lines after each record line
        cols = np.flatnonzero(col)
        owner = cols[np.cumsum(col) - 1]  # the column record of each line
        icol, irow, nw = ints[owner, 0], ints[owner, 1], ints[owner, 2]
        string = ~col
        if m.bigmat:
            lp1, r0, words = ints[:, 0], ints[:, 1], ints[:, 0] + 1
        else:
            lp1, r0 = ints[:, 0] >> 16, ints[:, 0] & 0xFFFF
            words = lp1
        sparse = col & (irow <= 0)
        used = np.bincount(np.cumsum(col)[string] - 1, weights=words[string], minlength=cols.size)
        if (np.any(nw < 0) or np.any(string & (irow > 0)) or np.any(used != np.where(irow[cols] > 0, 0, nw[cols]))
                or np.any(string & ((lp1 < 1) | ((lp1 - 1) % m.wper != 0)))):
            return None
        r0 = np.where(col, irow, r0)
        n = np.where(col, nw, (lp1 - 1) // m.wper)
        n[sparse] = 0
        if np.any(gap != -(-n // m.per_line)):
            return None
        rec = ~sparse
        vals = _values(self, lines[rec] + 1, n[rec], m.per_line, m.width)
        if vals is None:
            return None
        m.put(icol[rec], r0[rec], n[rec], vals)
        return closing, int(il[z])


def _values(chunk, first, n, p, w):
    """The values of records whose ``n`` values, ``p`` to a line of ``w``-byte fields, start at line ``first``."""
    buf, b, starts, ends = chunk.buf, chunk.b, chunk.starts, chunk.ends
    total = int(n.sum())
    nlv = -(-n // p)
    lines = np.repeat(first - np.cumsum(nlv) + nlv, nlv) + np.arange(int(nlv.sum()))
    count = np.full(lines.size, p)
    count[np.cumsum(nlv)[nlv > 0] - 1] = (n - (nlv - 1) * p)[nlv > 0]
    if np.any(np.take(ends, lines) - np.take(starts, lines) != count * w):
        return None
    j = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    fields = np.take(starts, np.repeat(first, n) + j // p) + (j % p) * w  # field starts
    vals = np.empty(total)
    bad = np.zeros(total, dtype=bool)
    if total:
        _parse(b, fields, w, vals, bad)
    for k in np.flatnonzero(bad).tolist():  # other forms: one by one, as the line scanner
        try:
            vals[k] = num(buf[fields[k]:fields[k] + w].decode("latin-1"))
        except (ValueError, UnicodeDecodeError):
            return None
    return vals


def _parse(b, fields, width, vals, bad):
    """Values of the ``width``-byte fields at ``fields`` (one matrix) into ``vals``; ``bad`` marks the others."""
    lay = value_layout(b, int(fields[0]) + width)
    if lay is None:
        bad[:] = True
        return
    vw, digits, mark, ne = lay
    lead = width - vw  # blanks before the sign slot
    if lead < 0:
        bad[:] = True
        return
    for k in range(lead):
        bad |= np.take(b, fields + k) != 32
    s = np.take(b, fields + lead)
    bad |= (s != 32) & (s != 43) & (s != 45)
    vals[:] = parse_values(b, fields + lead, vw, digits, mark, ne, bad)
    bad |= ~np.isfinite(vals)
