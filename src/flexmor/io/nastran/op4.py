"""Nastran OUTPUT4 (``.op4``) matrix files, ASCII and binary.

Layout (MSC/NX Nastran DMAP ``OUTPUT4``): per matrix a header ``NCOL NROW FORM TYPE NAME``
(ASCII: ``4I8, 2A4, format`` in fixed columns), then one record per stored column
``ICOL IROW NW`` followed by its values, and a closing record with ``ICOL = NCOL + 1``.
``TYPE`` 1/2 real single/double, 3/4 complex single/double; ``FORM`` 6 is symmetric (stored
in full by Nastran; an upper-triangle-only file is completed). A column with ``IROW > 0`` is
dense from row ``IROW``; ``IROW = 0`` marks a sparse column of strings, each with a header
``IS = 65536 (L + 1) + IROW`` (``L`` words follow), or, for ``BIGMAT`` matrices (``NROW <
0`` in the header), two header words ``L + 1, IROW``. Sparse counts are in words: a double
precision value is two words in 32-bit files. ASCII dense columns count values.

Columns and the rows within a column are stored in order; a symmetric matrix stored in full
must equal its transpose. Beyond that the format holds no checksum or count of its matrices:
every read gives one :class:`~flexmor.io.UncheckedWarning` saying so.

Binary files are Fortran unformatted records (4-byte record markers) in either byte order,
with 32-bit integers and names of 8 characters, or 64-bit integers (header record of 48
bytes, names of 16 characters, a "word" of 8 bytes). Every record length, count and index is
checked against the header and the file size before use.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ...errors import ReadError
from .._open import open_binary, read_all, size_hint
from .._text import read_text
from .._unchecked import warn_unchecked
from .nastran_bulk import num
from .op4_stream import check_header, fast_ascii, is_header, is_values, matrix_header

__all__ = ["read_op4"]

#: Largest OP4 matrix (entries) returned densely: 2e8 entries = 1.6 GB of float64.
MAX_DENSE = 200_000_000


def read_op4(path, *, sparse: bool = False) -> dict:
    """Read all matrices of an OP4 file (ASCII or binary).

    Parameters
    ----------
    path : str or path-like
    sparse : bool
        Return ``scipy.sparse.csc_matrix`` (any size) instead of dense arrays (refused
        above :data:`MAX_DENSE` entries).

    Returns
    -------
    dict of str to matrix
        Upper-case name -> matrix (nrow, ncol), real or complex.

    Raises
    ------
    ReadError
        Malformed headers or columns (with line number for ASCII, byte offset for binary),
        indices outside the matrix, columns or rows out of order, truncated files, a symmetric
        matrix stored in full that differs from its transpose.

    Warns
    -----
    UncheckedWarning
        On every read: OUTPUT4 has no checksum and no count of its matrices.
    """
    path = Path(path)
    if not path.exists():
        raise ReadError(path, "file not found")
    size = size_hint(path)
    with open_binary(path) as f:
        head = f.read(65536)
        if head.isspace() and len(head) == 65536:
            head += f.read()
    if not head.strip():
        raise ReadError(path, "file is empty")
    binary = len(head) >= 16 and (head[12] == 0 or head[15] == 0 or b"\x00" in head[:16])
    if binary:
        mats = _binary(path, read_all(path))
    else:
        mats = fast_ascii(path, size)
        if mats is None:  # irregular layout or a defect: the line scanner reads it or names the line
            mats = _ascii(path)
    out = {}
    for name, (form, A) in mats.items():
        nrow, ncol = A.shape
        if form == 6 and nrow == ncol and A.nnz:
            A.sort_indices()
            j = np.flatnonzero(np.diff(A.indptr))  # the first and last row of each stored column
            lower, upper = bool(np.any(A.indices[A.indptr[j + 1] - 1] > j)), bool(np.any(A.indices[A.indptr[j]] < j))
            if not (lower and upper):  # one triangle stored: complete it
                A = sp.csc_matrix(A + (sp.tril(A, -1) if lower else sp.triu(A, 1)).T)
            else:  # stored in full, as Nastran does: each entry has a copy in the other triangle
                _check_symmetric(path, name, A)
        A.eliminate_zeros()  # dense columns store the zeros between the first and last non-zero row
        if not sparse:
            if nrow * ncol > MAX_DENSE:
                raise ReadError(path, f"matrix {name} of {nrow} x {ncol} is too large to return densely "
                                      f"(limit {MAX_DENSE} entries); read it with sparse=True")
            A = A.toarray()
        out[name] = A
    if not out:
        raise ReadError(path, "no matrices found")
    warn_unchecked(path, "OUTPUT4 has no checksum and no count of its matrices; values (and a matrix lost from "
                         "the end of the file) could not be cross-checked")
    return out


def _check_symmetric(path, name, A) -> None:
    """Refuse a symmetric (form 6) matrix stored in full whose two triangles differ: a value changed
    or a record lost. Entries may differ by round-off (1e-9 of the larger diagonal of their row
    and column, or of the entry)."""
    D = A - A.T
    D.eliminate_zeros()
    if not D.nnz:
        return
    d = np.abs(A.diagonal())
    C = D.tocoo()
    scale = np.maximum(np.maximum(d[C.row], d[C.col]), np.abs(np.asarray(A[C.row, C.col]).ravel()))
    bad = np.flatnonzero(np.abs(C.data) > 1e-9 * scale)
    if bad.size:
        i, j = int(C.row[bad[0]]), int(C.col[bad[0]])
        raise ReadError(path, f"matrix {name} is symmetric (form 6) and stored in full, but its entries ({i + 1}, "
                              f"{j + 1}) = {A[i, j]:.9g} and ({j + 1}, {i + 1}) = {A[j, i]:.9g} differ: a value "
                              f"changed or a column lost ({bad.size // 2 or 1} such pairs)")


class _Col:
    """Collects the entries of one matrix and checks them against its size."""

    def __init__(self, path, name, nrow, ncol, cplx):
        self.path, self.name, self.nrow, self.ncol, self.cplx = path, name, nrow, ncol, cplx
        self.r, self.c, self.v = [], [], []
        self.last = (0, 0)  # column and end row of the last record: columns in order, rows not overlapping

    def put(self, icol, r0, vals, where):
        if self.cplx:
            if len(vals) % 2:
                raise ReadError(self.path, f"matrix {self.name}: odd number of words in a complex column", where)
            vals = np.asarray(vals[0::2]) + 1j * np.asarray(vals[1::2])
        n = len(vals)
        if icol < 1 or icol > self.ncol or r0 < 1 or r0 - 1 + n > self.nrow:
            raise ReadError(self.path, f"matrix {self.name}: column {icol} rows {r0}..{r0 + n - 1} lie outside "
                                       f"{self.nrow} x {self.ncol}", where)
        if n and icol == self.last[0] and r0 < self.last[1]:
            raise ReadError(self.path, f"matrix {self.name}: column {icol} stores the same row twice or out of "
                                       f"order: rows {r0}..{r0 + n - 1} follow row {self.last[1] - 1}", where)
        if n and icol < self.last[0]:
            raise ReadError(self.path, f"matrix {self.name}: column {icol} rows {r0}..{r0 + n - 1} follow column "
                                       f"{self.last[0]} row {self.last[1] - 1}; OUTPUT4 stores columns and rows in "
                                       "order (a changed or moved record?)", where)
        if n:
            self.last = (icol, r0 + n)
            self.r.append(np.arange(r0 - 1, r0 - 1 + n))
            self.c.append(np.full(n, icol - 1))
            self.v.append(np.asarray(vals))

    def done(self, form):
        dt = np.complex128 if self.cplx else np.float64

        def cat(xs, t):
            return np.concatenate(xs).astype(t) if xs else np.zeros(0, t)

        r, c, v = cat(self.r, np.int64), cat(self.c, np.int64), cat(self.v, dt)
        key = c * np.int64(self.nrow) + r
        if np.unique(key).size != key.size:
            raise ReadError(self.path, f"matrix {self.name}: a column stores the same row twice")
        return form, sp.csc_matrix((v, (r, c)), shape=(self.nrow, self.ncol))


# -- ASCII ------------------------------------------------------------------------------------
def _ascii(path):
    lines = read_text(path).splitlines()
    out, i = {}, 0
    while i < len(lines):
        h = lines[i]
        if not h.strip():
            i += 1
            continue
        ncol, nrow, form, typ, name, per_line, width = matrix_header(path, h, i + 1)
        bigmat = nrow < 0 or abs(nrow) >= 65536
        wper = 1 if typ & 1 else 2
        col = _Col(path, name, abs(nrow), ncol, typ > 2)
        i += 1
        while True:
            if i >= len(lines):
                raise ReadError(path, f"matrix {name}: file ends before the closing column record", len(lines))
            try:
                icol, irow, nw = (int(x) for x in lines[i].split())
            except ValueError:
                if is_header(lines[i]):
                    raise ReadError(path, f"matrix {name}: the next matrix header follows before the closing "
                                          f"record; the header announces {ncol} columns (corrupt header or "
                                          "truncated matrix?)", i + 1) from None
                raise ReadError(path, f"matrix {name}: expected a column record 'icol irow nwords', got "
                                      f"{lines[i][:60]!r}", i + 1) from None
            if nw < 0:
                raise ReadError(path, f"matrix {name}: negative word count", i + 1)
            i += 1
            if icol > ncol:
                i += -(-nw // per_line) if irow > 0 else 0
                if irow == 0:  # closing record of a sparse matrix: one dummy value line
                    i += 1 if i < len(lines) and is_values(lines[i]) else 0
                break
            if irow > 0:
                vals, i = _dense_values(path, lines, i, nw, per_line, width, wper)
                col.put(icol, irow, vals, i)
                continue
            left = nw
            while left > 0:
                if i >= len(lines):
                    raise ReadError(path, f"matrix {name}: file ends inside column {icol}", len(lines))
                try:
                    hdr = [int(x) for x in lines[i].split()]
                    if bigmat:
                        lp1, r0 = hdr
                        left -= lp1 + 1
                    else:
                        (is_,) = hdr
                        lp1, r0 = is_ >> 16, is_ & 0xFFFF
                        left -= lp1
                except ValueError:
                    raise ReadError(path, f"matrix {name}: expected a sparse string header, got {lines[i][:60]!r}",
                                    i + 1) from None
                L = lp1 - 1
                if L < 0 or L % wper or left < 0:
                    raise ReadError(path, f"matrix {name}: sparse string of {L} words does not fit column {icol}",
                                    i + 1)
                i += 1
                vals, i = _values(path, lines, i, L // wper, per_line, width)
                col.put(icol, r0, vals, i)
        out[name] = col.done(form)
    return out


def _dense_values(path, lines, i, nw, per_line, width, wper):
    """Values of a dense ASCII column: ``nw`` counts values (Nastran, pyyeti); a file that counts
    double precision words instead (``nw`` = 2 x values) is recognized by its next record."""
    try:
        return _values(path, lines, i, nw, per_line, width)
    except ReadError:
        if wper != 2 or nw % 2:
            raise
        vals, j = _values(path, lines, i, nw // 2, per_line, width)
        if j < len(lines) and len(lines[j].split()) == 3 and all(t.lstrip("-").isdigit() for t in lines[j].split()):
            return vals, j
        raise


def _values(path, lines, i, n, per_line, width):
    vals = []
    while len(vals) < n:
        if i >= len(lines):
            raise ReadError(path, "file ends inside a column (truncated?)", len(lines))
        s = lines[i].rstrip()
        toks = [s[k:k + width] for k in range(0, len(s), width)]
        if not toks:
            raise ReadError(path, "blank line inside a column", i + 1)
        try:
            vals.extend(num(t) for t in toks)
        except ValueError:
            raise ReadError(path, f"non-numeric or non-finite value in {s[:60]!r}", i + 1) from None
        i += 1
    if len(vals) != n:
        raise ReadError(path, f"column announces {n} values, found {len(vals)}", i)
    return vals, i


# -- binary -----------------------------------------------------------------------------------
def _binary(path, raw: bytes):
    size = len(raw)
    end = "<" if struct.unpack("<i", raw[:4])[0] in (24, 48) else ">"
    first = struct.unpack(end + "i", raw[:4])[0]
    if first not in (24, 48):
        raise ReadError(path, "not an OP4 file: the first record is neither an ASCII header nor a binary header "
                              "record of 24 or 48 bytes")
    ib = 8 if first == 48 else 4
    ifmt = end + ("q" if ib == 8 else "i")
    out, pos = {}, 0

    def record(pos):
        if pos + 4 > size:
            raise ReadError(path, f"file ends at byte {pos} where a record starts (truncated?)")
        n = struct.unpack(end + "i", raw[pos:pos + 4])[0]
        if n < 0 or pos + 8 + n > size:
            raise ReadError(path, f"record at byte {pos} announces {n} bytes beyond the end of the file (truncated?)")
        if struct.unpack(end + "i", raw[pos + 4 + n:pos + 8 + n])[0] != n:
            raise ReadError(path, f"record at byte {pos}: leading and trailing record lengths differ")
        return raw[pos + 4:pos + 4 + n], pos + 8 + n

    while pos < size:
        start = pos
        body, pos = record(pos)
        if len(body) != (4 * ib + (16 if ib == 8 else 8)):
            raise ReadError(path, f"expected a matrix header record at byte {start}")
        ncol, nrow, form, typ = struct.unpack(end + ("4q" if ib == 8 else "4i"), body[:4 * ib])
        name = body[4 * ib:].decode("latin-1").replace("\x00", " ").strip().upper() or f"M{len(out)}"
        check_header(path, ncol, nrow, form, typ, name, None)
        single = typ & 1 and ib == 4
        word_bytes = ib
        vfmt = np.dtype(end + ("f4" if single else "f8"))
        wper = 1 if (typ & 1 or ib == 8) else 2
        bigmat = nrow < 0 or abs(nrow) >= 65536
        col = _Col(path, name, abs(nrow), ncol, typ > 2)
        while True:
            cstart = pos
            body, pos = record(pos)
            if len(body) < 3 * ib:
                raise ReadError(path, f"matrix {name}: column record at byte {cstart} is too short")
            icol, irow, nw = struct.unpack(end + ("3q" if ib == 8 else "3i"), body[:3 * ib])
            data = body[3 * ib:]
            if icol > ncol:
                break
            if nw < 0 or nw * word_bytes != len(data):
                raise ReadError(path, f"matrix {name}: column {icol} announces {nw} words but its record holds "
                                      f"{len(data) // word_bytes} (byte {cstart})")
            if irow > 0:
                col.put(icol, irow, np.frombuffer(data, vfmt), None)
                continue
            k = 0
            while k < len(data):
                if bigmat:
                    if k + 2 * ib > len(data):
                        raise ReadError(path, f"matrix {name}: broken sparse string in column {icol}")
                    lp1, r0 = struct.unpack(end + ("2q" if ib == 8 else "2i"), data[k:k + 2 * ib])
                    k += 2 * ib
                else:
                    is_ = struct.unpack(ifmt, data[k:k + ib])[0]
                    lp1, r0 = is_ >> 16, is_ & 0xFFFF
                    k += ib
                L = lp1 - 1
                nb = L * word_bytes
                if L < 0 or L % wper or k + nb > len(data):
                    raise ReadError(path, f"matrix {name}: broken sparse string in column {icol} (byte {cstart})")
                col.put(icol, r0, np.frombuffer(data[k:k + nb], vfmt), None)
                k += nb
        out[name] = col.done(form)
    return out
