"""Vectorized parsing of ``row col value`` text as FE programs write it, at hundreds of MB/s.

FE programs print matrix entries with one C format for the whole file: two integers and a
value in scientific notation with a fixed number of digits (CalculiX ``%d %d %.13e``, Abaqus
``%.15e``, Matrix Market writers ``%.16e``). Each line then ends in a value field of the same
width, so NumPy can parse the whole buffer column by column instead of number by number:

* the value field right-aligned at each line end (``[sign]d.ddd...e+dd``) is checked byte by
  byte against the layout of the first line, its digits are accumulated into an exact integer
  mantissa and scaled by a power of ten; mantissa below 2**53 and power up to 1e22 make
  this one correctly rounded operation, the same double as ``strtod`` (Clinger's fast path);
  the few other values are parsed by ``strtod``;
* the two integers before it are accumulated column by column in the same way.

:func:`fast_triplets` returns None whenever a line does not fit (another layout, comments,
blank lines, a third integer ...); the caller then parses with a general parser and, for a
defect, scans line by line to name the line.
"""

from __future__ import annotations

import numpy as np

__all__ = ["fast_triplets", "parse_values", "value_layout"]

_P10 = 10.0 ** np.arange(23)  # exactly representable powers of ten
_MAX_PREFIX = 24  # widest "row col " part handled by the fast path
_MAX_INT_DIGITS = 9  # indices fit int32 arithmetic


def value_layout(b: np.ndarray, end: int):
    """Layout of the value field that ends before ``b[end]``: ``(width, digit columns, mark, exponent digits)``.

    Columns count from the field start (the sign slot); None when the field is not
    ``[sign]d.d...{eEdD}{+-}dd...``.
    """
    k = end - 1
    ne = 0
    while k >= 0 and 48 <= b[k] <= 57:
        k, ne = k - 1, ne + 1
    if ne == 0 or ne > 3 or k < 0 or b[k] not in (43, 45):
        return None
    k -= 1
    if k < 0 or b[k] not in (69, 101, 68, 100):
        return None
    mark = k
    k -= 1
    nf = 0
    while k >= 0 and 48 <= b[k] <= 57:
        k, nf = k - 1, nf + 1
    if k < 1 or b[k] != 46 or not 48 <= b[k - 1] <= 57 or nf + 1 > 18:
        return None
    start = k - 2  # the sign slot before the leading digit
    if start < 0:
        return None
    width = end - start
    digits = [1] + list(range(3, 3 + nf))
    return width, digits, mark - start, ne


def parse_values(b, fields, width, digits, mark, ne, bad):
    """The values whose fields start at ``fields``; lines that break the layout set ``bad``."""
    col = lambda j: np.take(b, fields + j)  # noqa: E731
    sign = col(0)
    bad |= ~((sign == 45) | (sign == 43) | _is_sep(sign))
    point = col(2)
    bad |= point != 46
    m = col(mark)
    bad |= ~((m == 69) | (m == 101) | (m == 68) | (m == 100))
    es = col(mark + 1)
    bad |= ~((es == 43) | (es == 45))
    mant = np.zeros(fields.size, dtype=np.int64)
    for j in digits:
        d = col(j) - np.uint8(48)
        bad |= d > 9
        mant *= 10
        mant += d
    exp = np.zeros(fields.size, dtype=np.int64)
    for j in range(mark + 2, mark + 2 + ne):
        d = col(j) - np.uint8(48)
        bad |= d > 9
        exp *= 10
        exp += d
    scale = np.where(es == 45, -exp, exp) - (len(digits) - 1)
    vals = mant.astype(np.float64)
    up = np.minimum(np.maximum(scale, 0), 22)
    down = np.minimum(np.maximum(-scale, 0), 22)
    vals *= _P10[up]
    vals /= _P10[down]
    np.negative(vals, out=vals, where=sign == 45)
    slow = np.flatnonzero((mant > 2**53) | (np.abs(scale) > 22))
    if slow.size:  # outside the exact fast path: strtod on those fields
        text = np.take(b, fields[slow, None] + np.arange(width))
        text = np.concatenate([text, np.full((slow.size, 1), 32, np.uint8)], axis=1)
        try:
            exact = np.fromstring(_fortran(text).tobytes(), sep=" ")
        except ValueError:
            exact = np.zeros(0)
        if exact.size != slow.size:
            bad[slow] = True
        else:
            vals[slow] = exact
    return vals


def _is_sep(c: np.ndarray) -> np.ndarray:
    return (c == 32) | (c == 9) | (c == 44)


def _fortran(text: np.ndarray) -> np.ndarray:
    """``D``/``d`` exponent marks as ``E``/``e``, separators as spaces (for ``strtod``)."""
    out = text.copy()
    out[out == 68] = 69
    out[out == 100] = 101
    out[(out == 44) | (out == 9)] = 32
    return out


#: Byte classes of the index part: 0 other, 1 digit, 2 separator (space, tab, comma).
_CLASS = np.zeros(256, dtype=np.uint8)
_CLASS[48:58] = 1
_CLASS[[32, 9, 44]] = 2


def _indices(b, starts, ends, bad):
    """The two integers between ``starts`` (line start) and ``ends`` (value field) of each line.

    Returns ``(first, second, digit_last)``, ``digit_last`` telling lines whose index part
    ends in a digit (no separator before the value field); None when a line is too wide.
    """
    plen = ends - starts
    width = int(plen.max(initial=0))
    if width > _MAX_PREFIX:
        return None
    n = starts.size
    first = np.zeros(n, dtype=np.int64)
    acc = np.zeros(n, dtype=np.int64)
    ndig = np.zeros(n, dtype=np.int8)
    tokens = np.zeros(n, dtype=np.int8)
    prev = np.zeros(n, dtype=bool)
    for j in range(width):
        c = np.take(b, ends - (width - j), mode="clip")
        cls = np.take(_CLASS, c)
        np.maximum(cls, (plen < width - j).view(np.uint8) * np.uint8(2), out=cls)  # before the line: separator
        bad |= cls == 0
        isd = cls == 1
        start = isd & ~prev
        tokens += start
        first += acc * (start & (tokens == 2))
        acc *= ~start
        ndig *= ~start
        ndig += isd
        acc *= np.where(isd, 10, 1)
        acc += (c - np.uint8(48)) * isd
        prev = isd
    bad |= (tokens != 2) | (ndig > _MAX_INT_DIGITS)
    return first, acc, prev


def fast_triplets(b: np.ndarray):
    """Parse the bytes ``b`` (uint8, whole lines of ``row col value``) into ``(rows, cols, values)``, or None.

    Returns
    -------
    rows, cols : ndarray of int64
        The integers as written (not shifted to 0-based).
    values : ndarray of float64
    None
        When any line does not follow the layout of the first one.
    """
    if b.size == 0 or b[-1] != 10:
        return None
    nl = np.flatnonzero(b == 10)
    cr = int(nl[0] > 0 and b[nl[0] - 1] == 13)
    lay = value_layout(b, int(nl[0]) - cr)
    if lay is None:
        return None
    width, digits, mark, ne = lay
    ends = nl - cr
    fields = ends - width
    starts = np.empty_like(nl)
    starts[0] = 0
    starts[1:] = nl[:-1] + 1
    if np.any(fields < starts) or (cr and np.any(np.take(b, ends) != 13)):
        return None
    bad = np.zeros(nl.size, dtype=bool)
    vals = parse_values(b, fields, width, digits, mark, ne, bad)
    ij = _indices(b, starts, fields, bad)
    if ij is None:
        return None
    rows, cols, digit_last = ij
    bad |= digit_last & ~_is_sep(np.take(b, fields))  # a sign needs a separator before it
    if bad.any():
        return None
    return rows, cols, vals
