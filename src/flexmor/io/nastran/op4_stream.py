"""Streamed, vectorized reading of ASCII OP4 files, and the header parsing both ASCII readers share.

An ASCII OP4 matrix is a header line (``NCOL NROW FORM TYPE NAME`` and a Fortran format such
as ``1P,3E24.16``: values per line and field width), then per stored column a record line
``ICOL IROW NW`` followed by its values in fixed-width fields, ``per_line`` to a line (sparse
columns, ``IROW = 0``: a string header line before each run of rows). :func:`fast_ascii`
reads the file in chunks of whole lines: the record lines are walked in Python (one per
column or string), the value fields of a whole chunk are parsed at once by
:func:`~flexmor.io._fastparse.parse_values` (the double ``strtod`` gives) into one
preallocated array per matrix, which becomes the ``data`` of a CSC matrix as it is. Fields
of another form (``1.0-3``, a three-digit exponent without its letter) are parsed one by one
like the line scanner does. It returns None for anything irregular (blank or trailing
characters, lines of another length than the format says, records out of column order,
overlapping rows, a field that is not a number, a truncated file): the line scanner of
:mod:`.op4` then reads the file and names the line of a defect.
"""

from __future__ import annotations

import re

import numpy as np
import scipy.sparse as sp

from ...errors import ReadError
from .._fastparse import parse_values, value_layout
from .nastran_bulk import num

__all__ = ["check_header", "fast_ascii", "is_values", "matrix_header"]

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
    """The matrix being read: its header, its records ``(icol, first row, values)`` and values."""

    def __init__(self, head, cap):
        self.ncol, nrow, self.form, typ, self.name, self.per_line, self.width = head
        self.nrow, self.bigmat, self.cplx = abs(nrow), nrow < 0 or abs(nrow) >= 65536, typ > 2
        self.wper = 1 if typ & 1 else 2
        self.icol, self.r0, self.n = [], [], []
        self.vals, self.k = np.empty(cap), 0
        self.left = 0  # words left in the sparse column being read
        self.col = 0

    def put(self, values: np.ndarray) -> None:
        k = self.k + values.size
        if k > self.vals.size:
            self.vals = np.concatenate([self.vals[:self.k], np.empty(max(k, self.vals.size + self.vals.size // 4) - self.k)])
        self.vals[self.k:k] = values
        self.k = k

    def matrix(self):
        """``(form, CSC matrix)``, or None when the records break a rule (the scanner names it)."""
        icol, r0, n = (np.array(x, dtype=np.int64) for x in (self.icol, self.r0, self.n))
        vals = self.vals
        vals.resize(self.k, refcheck=False)  # realloc: the unused capacity is returned
        if self.cplx:
            if np.any(n % 2):
                return None
            vals, n = vals.view(np.complex128), n // 2
        if np.any((icol < 1) | (icol > self.ncol) | (r0 < 1) | (r0 - 1 + n > self.nrow)):
            return None
        keep = n > 0
        icol, r0, n = icol[keep], r0[keep], n[keep]
        if np.any((icol[1:] < icol[:-1]) | ((icol[1:] == icol[:-1]) & (r0[1:] < r0[:-1] + n[:-1]))):
            return None  # out of column order or overlapping rows
        total = int(n.sum())
        idx = np.int32 if max(total, self.nrow) < 2**31 - 1 else np.int64
        indices = np.arange(total, dtype=idx)
        indices -= np.repeat((np.cumsum(n) - n - (r0 - 1)).astype(idx), n)
        indptr = np.zeros(self.ncol + 1, dtype=idx)
        np.add.at(indptr, icol, n.astype(idx))
        np.cumsum(indptr, out=indptr)
        return self.form, sp.csc_matrix((vals, indices, indptr), shape=(self.nrow, self.ncol))


def fast_ascii(path, size: int):
    """Matrices of the ASCII OP4 file ``path`` (``size`` bytes) as ``{NAME: (form, CSC)}``, or None."""
    out, m = {}, None
    with open(path, "rb") as f:
        rest, eof, done = b"", False, 0
        while not eof:
            block = f.read(_CHUNK)
            eof = not block
            buf = rest + block if rest else block
            cut = buf.rfind(b"\n") + 1 if not eof else len(buf)
            if eof and buf and not buf.endswith(b"\n"):
                buf += b"\n"
                cut = len(buf)
            if not buf[:cut]:
                continue
            b = np.frombuffer(buf, dtype=np.uint8, count=cut)
            got = _walk(path, buf, b, m, out, size - done, eof)
            if got is None:
                return None
            m, used = got
            done += used
            rest = buf[used:]
            if eof and rest.strip():
                return None
    return out if m is None and out else None


def _walk(path, buf, b, m, out, left_bytes, eof):
    """Walk the records of the whole lines in ``b``; parse their values. ``(matrix being read, bytes used)`` or None."""
    nl = np.flatnonzero(b == 10)
    starts = np.empty_like(nl)
    starts[:1] = 0
    starts[1:] = nl[:-1] + 1
    ends = nl - (np.take(b, nl - 1, mode="clip") == 13) * (nl > starts)
    st, en = starts.tolist(), ends.tolist()
    nlines = len(st)
    recs = []  # (matrix, first value line, values, per line, width)
    finished = []
    i = 0
    while i < nlines:
        line = buf[st[i]:en[i]]
        if m is None:
            if not line.strip():
                i += 1
                continue
            try:
                head = matrix_header(path, line.decode("latin-1"), None)
            except ReadError:
                return None
            m = _Matrix(head, left_bytes // head[6] + 1)
            i += 1
            continue
        p = m.per_line
        try:
            toks = [int(t) for t in line.split()]
        except ValueError:
            return None
        if m.left > 0:  # a string header of a sparse column
            if len(toks) != (2 if m.bigmat else 1):
                return None
            lp1, r0 = toks if m.bigmat else (toks[0] >> 16, toks[0] & 0xFFFF)
            left = m.left - (lp1 + 1 if m.bigmat else lp1)
            if lp1 < 1 or (lp1 - 1) % m.wper or left < 0:
                return None
            nv = (lp1 - 1) // m.wper
            nlv = -(-nv // p)
            if i + 1 + nlv > nlines:
                break
            m.left = left
            recs.append((m, i + 1, nv, p, m.width))
            m.icol.append(m.col)
            m.r0.append(r0)
            m.n.append(nv)
            i += 1 + nlv
            continue
        if len(toks) != 3 or toks[2] < 0:
            return None
        icol, irow, nw = toks
        if icol > m.ncol:  # closing record
            skip = -(-nw // p) if irow > 0 else 1
            if i + 1 + skip > nlines and not eof:
                break
            if irow == 0 and not (i + 1 < nlines and is_values(buf[st[i + 1]:en[i + 1]].decode("latin-1"))):
                skip = 0
            if i + 1 + skip > nlines:
                return None
            finished.append(m)
            m = None
            i += 1 + skip
            continue
        if irow > 0:
            nlv = -(-nw // p)
            if i + 1 + nlv > nlines:
                break
            recs.append((m, i + 1, nw, p, m.width))
            m.icol.append(icol)
            m.r0.append(irow)
            m.n.append(nw)
            i += 1 + nlv
        else:
            m.left, m.col = nw, icol
            i += 1
    if not _values(buf, b, starts, ends, recs):
        return None
    for x in finished:
        got = x.matrix()
        if got is None:
            return None
        out[x.name] = got
    return m, st[i] if i < nlines else len(b)


def _values(buf, b, starts, ends, recs) -> bool:
    """Parse the values of the records ``recs`` and append them to their matrices; False for a bad line."""
    if not recs:
        return True
    first = np.array([r[1] for r in recs], dtype=np.int64)
    n = np.array([r[2] for r in recs], dtype=np.int64)
    p = np.array([r[3] for r in recs], dtype=np.int64)
    w = np.array([r[4] for r in recs], dtype=np.int64)
    total = int(n.sum())
    # value lines: expected length (count x width) of each
    nlv = -(-n // p)
    lines = np.repeat(first - np.cumsum(nlv) + nlv, nlv) + np.arange(int(nlv.sum()))
    count = np.repeat(p, nlv)
    last = np.cumsum(nlv)[nlv > 0] - 1
    count[last] = (n - (nlv - 1) * p)[nlv > 0]
    if np.any(np.take(ends, lines) - np.take(starts, lines) != count * np.repeat(w, nlv)):
        return False
    j = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    pe, we = np.repeat(p, n), np.repeat(w, n)
    fields = np.take(starts, np.repeat(first, n) + j // pe) + (j % pe) * we  # field starts
    vals = np.empty(total)
    bad = np.zeros(total, dtype=bool)
    seg = np.flatnonzero(np.diff([id(r[0]) for r in recs], prepend=0, append=1))  # runs of one matrix
    offs = np.cumsum(n) - n
    for a, z in zip(seg[:-1], seg[1:]):
        e0, e1 = int(offs[a]), int(offs[z - 1] + n[z - 1])
        if e1 > e0:
            _parse(b, fields[e0:e1], int(w[a]), vals[e0:e1], bad[e0:e1])
    for k in np.flatnonzero(bad).tolist():  # other forms: one by one, as the line scanner
        try:
            vals[k] = num(buf[fields[k]:fields[k] + we[k]].decode("latin-1"))
        except (ValueError, UnicodeDecodeError):
            return False
    for a, z in zip(seg[:-1], seg[1:]):
        recs[a][0].put(vals[int(offs[a]):int(offs[z - 1] + n[z - 1])])
    return True


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
