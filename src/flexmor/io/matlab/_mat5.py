"""Structural check of MATLAB v5/v7 MAT-files before :func:`scipy.io.loadmat` reads them.

SciPy's compiled MAT-file reader trusts the byte counts and dimensions in a file: a damaged
or hostile file (a truncated compressed variable, a sub-element claiming more bytes than its
parent holds) can crash the whole process with a segmentation fault instead of raising. This
module walks the element tree in pure Python first (Mathworks, *MAT-File Format*, R2018a:
8-byte tags, small data elements, ``miCOMPRESSED`` zlib streams, ``miMATRIX`` with array
flags, dimensions, name and the class-specific parts) and raises :class:`ReadError` for
anything inconsistent: an element that does not fit in its parent, an unknown data type or
class, a numeric part whose element count is not the product of the dimensions, sparse
row/column indices out of range, nesting deeper than :data:`MAX_DEPTH`, a compressed
variable expanding beyond :data:`MAX_EXPANDED` bytes. :func:`checked_v5_stream` returns the
file with its compressed variables expanded (exactly what was checked), for scipy to read.
"""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np

from ...errors import ReadError

__all__ = ["MAX_DEPTH", "MAX_EXPANDED", "checked_v5_stream"]

#: Deepest nesting of cells/structs accepted.
MAX_DEPTH = 32
#: Largest size (bytes) a compressed variable may expand to.
MAX_EXPANDED = 4 * 2**30

_MI_MATRIX, _MI_COMPRESSED = 14, 15
_SIZES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8, 16: 1, 17: 2, 18: 4}
_NUMERIC = (1, 2, 3, 4, 5, 6, 7, 9, 12, 13)
_CELL, _STRUCT, _OBJECT, _CHAR, _SPARSE = 1, 2, 3, 4, 5
_NUMERIC_CLASSES = range(6, 16)


class _Walker:
    def __init__(self, path, order: str):
        self.path, self.order = path, order

    def fail(self, what: str, where: str) -> ReadError:
        return ReadError(self.path, f"damaged MATLAB file: {what} ({where}); save it again with save(file, '-v7')")

    def tag(self, buf, off: int, end: int, where: str):
        """(type, nbytes, data offset, next offset) of the element at ``off``."""
        if off + 8 > end:
            raise self.fail(f"element tag at byte {off} cut off", where)
        word, n = struct.unpack_from(self.order + "II", buf, off)
        if word >> 16:  # small data element: type and count in one word, data in the next 4 bytes
            t, n = word & 0xFFFF, word >> 16
            if n > 4:
                raise self.fail(f"small element at byte {off} claims {n} bytes", where)
            return t, n, off + 4, off + 8
        t = word
        if off + 8 + n > end:
            raise self.fail(f"element at byte {off} claims {n} bytes, only {end - off - 8} left", where)
        return t, n, off + 8, min(off + 8 + n + (-n) % 8, end)

    def data(self, buf, off: int, end: int, where: str, types=None):
        t, n, d, nxt = self.tag(buf, off, end, where)
        if t not in _SIZES or (types is not None and t not in types):
            raise self.fail(f"unexpected data type {t} at byte {off}", where)
        if n % _SIZES[t]:
            raise self.fail(f"{n} bytes at byte {off} are no whole number of type-{t} values", where)
        return t, n // _SIZES[t], d, nxt

    def ints(self, buf, t: int, count: int, d: int) -> np.ndarray:
        dt = {5: "i4", 6: "u4"}[t]
        return np.frombuffer(buf, dtype=self.order + dt, count=count, offset=d)

    def matrix(self, buf, off: int, end: int, where: str, depth: int) -> int:
        """Check the ``miMATRIX`` element at ``off``; returns the next offset."""
        t, n, d, nxt = self.tag(buf, off, end, where)
        if t != _MI_MATRIX:
            raise self.fail(f"expected a matrix element at byte {off}, found type {t}", where)
        if n == 0:  # an empty cell entry
            return nxt
        if depth > MAX_DEPTH:
            raise self.fail(f"cells/structs nested deeper than {MAX_DEPTH}", where)
        stop = d + n
        ft, fc, fd, p = self.data(buf, d, stop, where, types=(6,))
        if fc != 2:
            raise self.fail("array flags are not two words", where)
        flags, nzmax = (int(x) for x in self.ints(buf, ft, 2, fd))
        cls, cplx = flags & 0xFF, bool(flags & 0x0800)
        if cls in (16, 17):
            raise ReadError(self.path, f"variable of MATLAB class {'function handle' if cls == 16 else 'object'} "
                                       f"({where}); save only numeric matrices: save(file, 'M', 'K', '-v7')")
        if not 1 <= cls <= 15:
            raise self.fail(f"unknown array class {cls}", where)
        dt, nd, dd, p = self.data(buf, p, stop, where, types=(5,))
        if nd < 2:
            raise self.fail(f"{nd} dimensions", where)
        dims = [int(x) for x in self.ints(buf, dt, nd, dd)]
        if min(dims) < 0:
            raise self.fail(f"negative dimension in {dims}", where)
        count = int(np.prod(dims, dtype=object))
        _, _, _, p = self.data(buf, p, stop, where, types=(1, 2))  # the name
        if cls in _NUMERIC_CLASSES:
            for part in ("real", "imaginary")[: 1 + cplx]:
                _, c, _, p = self.data(buf, p, stop, where, types=_NUMERIC)
                if c != count:
                    raise self.fail(f"{part} part holds {c} values for dimensions {dims}", where)
        elif cls == _SPARSE:
            self.sparse(buf, p, stop, where, dims, nzmax, cplx)
        elif cls == _CHAR:
            self.data(buf, p, stop, where)
        elif cls == _CELL:
            for _ in range(count):
                p = self.matrix(buf, p, stop, where, depth + 1)
        else:  # struct, object (with its class name first)
            if cls == _OBJECT:
                _, _, _, p = self.data(buf, p, stop, where, types=(1, 2))
            lt, lc, ld, p = self.data(buf, p, stop, where, types=(5,))
            length = int(self.ints(buf, lt, 1, ld)[0]) if lc == 1 else 0
            _, nb, _, p = self.data(buf, p, stop, where, types=(1, 2))
            if length <= 0 or nb % length:
                raise self.fail(f"field names of {nb} bytes do not split into names of {length}", where)
            for _ in range(count * (nb // length)):
                p = self.matrix(buf, p, stop, where, depth + 1)
        return nxt

    def sparse(self, buf, p, stop, where, dims, nzmax, cplx) -> None:
        if len(dims) != 2:
            raise self.fail(f"sparse matrix with dimensions {dims}", where)
        nrows, ncols = dims
        it, nir, ird, p = self.data(buf, p, stop, where, types=(5,))
        jt, njc, jcd, p = self.data(buf, p, stop, where, types=(5,))
        if njc != ncols + 1:
            raise self.fail(f"sparse column index holds {njc} entries for {ncols} columns", where)
        jc = self.ints(buf, jt, njc, jcd)
        nnz = int(jc[-1])
        if jc[0] != 0 or np.any(np.diff(jc) < 0) or nnz > nir:
            raise self.fail("sparse column index not ascending from 0 within the row indices", where)
        ir = self.ints(buf, it, nnz, ird)
        if nnz and (ir.min() < 0 or ir.max() >= nrows):
            raise self.fail(f"sparse row index outside 0..{nrows - 1}", where)
        for part in ("real", "imaginary")[: 1 + cplx]:
            _, c, _, p = self.data(buf, p, stop, where, types=_NUMERIC)
            if c < nnz:
                raise self.fail(f"sparse {part} part holds {c} values for {nnz} entries", where)


def checked_v5_stream(path, raw: bytes) -> io.BytesIO | None:
    """Check the v5/v7 MAT-file ``raw`` (the bytes of ``path``); None for a v4 file.

    Returns the file with every compressed variable expanded, as a stream for
    :func:`scipy.io.loadmat`. Raises :class:`ReadError` on any structural damage.
    """
    if len(raw) < 128 or not raw.startswith(b"MATLAB"):
        return None  # v4 (no text header): scipy's pure-Python v4 reader
    marker = raw[126:128]
    if marker not in (b"IM", b"MI"):
        raise ReadError(path, "MATLAB header without a valid byte-order mark; not a v5/v7 MAT-file")
    w = _Walker(path, "<" if marker == b"IM" else ">")
    out = [raw[:128]]
    off, k = 128, 0
    while off < len(raw):
        k += 1
        where = f"variable {k}"
        if len(raw) - off < 8 and not raw[off:].strip(b"\x00"):
            break  # zero padding at the end
        t, n, d, nxt = w.tag(raw, off, len(raw), where)
        if t == _MI_COMPRESSED:
            z = zlib.decompressobj()
            try:
                inner = z.decompress(raw[d:d + n], MAX_EXPANDED)
            except zlib.error as exc:
                raise w.fail(f"compressed data at byte {off} are corrupt ({exc})", where) from None
            if z.unconsumed_tail:
                raise w.fail(f"compressed data at byte {off} expand beyond {MAX_EXPANDED} bytes", where)
            if not z.eof:
                raise w.fail(f"compressed data at byte {off} are cut off", where)
            end = w.matrix(inner, 0, len(inner), where, 0)
            elem = inner[:end]
            out.append(elem + b"\x00" * (-len(elem) % 8))
            off = d + n  # compressed elements are not padded
        elif t == _MI_MATRIX:
            end = w.matrix(raw, off, len(raw), where, 0)
            out.append(raw[off:end] + b"\x00" * (-(end - off) % 8))
            off = nxt
        else:
            raise w.fail(f"top-level element of type {t} at byte {off}", where)
    return io.BytesIO(b"".join(out))
