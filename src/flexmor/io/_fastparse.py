"""Vectorized parsing of ``row col value`` text as FE programs write it, at hundreds of MB/s.

FE programs print matrix entries with one C format for the whole file: two integers and a
value in scientific notation with a fixed number of digits (CalculiX ``%d %d %.13e``, Abaqus
``%.15e``, Matrix Market writers ``%.16e``). Each line then ends in a value field of the same
width, so NumPy can parse the whole buffer column by column instead of number by number:

* the value field right-aligned at each line end (``[sign]d.ddd...e+dd``) is checked byte by
  byte against the layout of the first line, its digits are accumulated into an exact integer
  mantissa and scaled by a power of ten; mantissa below 2**53 and power up to 1e22 make
  this one correctly rounded operation, the same double as ``strtod`` (Clinger's fast path);
  powers up to 1e54 and longer mantissas go through x87 extended precision with a check
  that the result is not near a halfway point (:func:`_wide`); the few other values are
  parsed by ``strtod``;
* the two integers before it are accumulated column by column in the same way (bytes and
  ``int32``, no masked NumPy operations: those are ten times slower than plain ones).

:func:`fast_triplets` returns None whenever a line does not fit (another layout, comments,
blank lines, a third integer ...); the caller then parses with a general parser and, for a
defect, scans line by line to name the line.
"""

from __future__ import annotations

import numpy as np

__all__ = ["fast_triplets", "parse_values", "value_layout"]

_P10 = 10.0 ** np.arange(23)  # exactly representable powers of ten
#: x87 extended precision (64-bit significand, stored in 16 bytes, little-endian): the
#: powers of ten up to 1e27 are exact, which widens the exact range (see :func:`_wide`).
_WIDE = np.finfo(np.longdouble).nmant == 63 and np.dtype(np.longdouble).itemsize == 16 \
    and np.little_endian
_P10L = np.cumprod(np.r_[1, np.full(27, 10)].astype(np.longdouble)) if _WIDE else None
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
    """The values whose fields start at ``fields``; lines that break the layout set ``bad``.

    Digits are taken a column at a time as bytes, paired in ``uint8`` (two digits fit a byte)
    and accumulated into an ``int64`` mantissa a pair at a time.
    """
    def col(j):
        return np.take(b[j:], fields)

    sign = col(0)
    ok = _is_sep(sign)
    ok |= sign == 45
    ok |= sign == 43
    ok &= col(2) == 46
    m = col(mark)
    m |= 32  # E, D -> e, d
    ok &= (m == 101) | (m == 100)
    es = col(mark + 1)
    ok &= (es == 43) | (es == 45)
    top = np.zeros(fields.size, dtype=np.uint8)  # the largest digit byte - 48: > 9 for a non-digit
    mant = _number(col, digits, top)
    exp = _number(col, range(mark + 2, mark + 2 + ne), top)
    ok &= top < 10
    bad |= ~ok
    scale = exp.astype(np.int16)
    neg = es == 45
    scale *= 1 - 2 * neg.view(np.int8)
    scale -= len(digits) - 1
    up = np.abs(scale)
    slow = up > 22
    np.minimum(up, 22, out=up)
    power = _P10[up]
    power *= np.where(sign == 45, -1.0, 1.0)  # the sign, exactly
    vals = mant.astype(np.float64)
    vals = np.where(scale < 0, vals / power, vals * power)  # one correctly rounded operation
    slow |= mant > 2**53
    slow = np.flatnonzero(slow)
    if slow.size and _WIDE:
        slow = _wide(vals, slow, mant, scale, sign)
    if slow.size:  # outside the exact fast paths: strtod on those fields
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


def _wide(vals, slow, mant, scale, sign):
    """Values at ``slow`` (powers of ten beyond 1e22, mantissas beyond 2**53) in x87 extended precision.

    ``mant`` times or over ``10**k`` in two steps of at most ``10**27`` (exact in a 64-bit
    significand) carries at most two roundings of 2**-64; rounding that to a double is
    correct unless the extended result lies within a few units of its last place of a
    halfway point between two doubles (its low 11 bits near ``0x400``). Sets those values;
    returns the rest (far powers, near-halfway results) for ``strtod``.
    """
    k = np.abs(scale[slow]).astype(np.int64)
    ok = k <= 54
    sel, k = slow[ok], k[ok]
    if sel.size == 0:  # only far powers (an overflowing exponent): all for strtod
        return slow
    k1 = np.minimum(k, 27)
    q = mant[sel].astype(np.longdouble)
    down = scale[sel] < 0
    for p in (_P10L[k1], _P10L[k - k1]):
        q = np.where(down, q / p, q * p)
    low = q.view(np.uint64).reshape(q.size, -1)[:, 0] & np.uint64(0x7FF)
    near = (low >= 0x400 - 4) & (low <= 0x400 + 4)
    done = sel[~near]
    vals[done] = q[~near].astype(np.float64) * np.where(sign[done] == 45, -1.0, 1.0)
    return np.setdiff1d(slow, done, assume_unique=True)


def _number(col, cols, top):
    """The decimal number written in the byte columns ``cols`` (int64); ``top`` keeps the largest digit."""
    out = None
    cols = list(cols)
    for k in range(0, len(cols), 2):
        pair = cols[k:k + 2]
        d = col(pair[0])
        d -= 48
        np.maximum(top, d, out=top)
        if len(pair) == 2:
            e = col(pair[1])
            e -= 48
            np.maximum(top, e, out=top)
            d *= 10  # garbage for non-digits, which ``top`` reports
            d += e
        if out is None:
            out = d.astype(np.int64)
        else:
            out *= 100 if len(pair) == 2 else 10
            out += d
    return out


def _is_sep(c: np.ndarray) -> np.ndarray:
    return (c == 32) | (c == 9) | (c == 44)


def _fortran(text: np.ndarray) -> np.ndarray:
    """``D``/``d`` exponent marks as ``E``/``e``, separators as spaces (for ``strtod``)."""
    out = text.copy()
    out[out == 68] = 69
    out[out == 100] = 101
    out[(out == 44) | (out == 9)] = 32
    return out


def _indices(b, starts, ends, bad):
    """The two integers between ``starts`` (line start) and ``ends`` (value field) of each line.

    The index part is scanned a byte column at a time, left to right, right-aligned on the
    value field (bytes before the line start count as separators). Returns
    ``(first, second, digit_last)`` as int32 (``digit_last`` tells lines whose index part ends
    in a digit), or None when a line is too wide.
    """
    plen = ends - starts
    width = int(plen.max(initial=0))
    if width > _MAX_PREFIX:
        return None
    n = starts.size
    plen = plen.astype(np.int8)
    pad = np.empty(b.size + _MAX_PREFIX, dtype=np.uint8)  # line ends before the first line
    pad[:_MAX_PREFIX] = 10
    pad[_MAX_PREFIX:] = b
    first = np.zeros(n, dtype=np.int32)
    acc = np.zeros(n, dtype=np.int32)
    ndig = np.zeros(n, dtype=np.uint8)
    longest = np.zeros(n, dtype=np.uint8)
    tokens = np.zeros(n, dtype=np.uint8)
    other = np.zeros(n, dtype=bool)
    prev = np.zeros(n, dtype=bool)
    for j in range(width):  # masks as 0/1 bytes: NumPy's masked (where=) operations are slow
        c = np.take(pad[_MAX_PREFIX - width + j:], ends)
        inside = plen >= width - j
        d = c - np.uint8(48)
        isd = d < 10
        isd &= inside
        ok = _is_sep(c)
        ok |= isd
        ok |= ~inside
        other |= ~ok
        start = isd > prev
        tokens += start
        s = start.view(np.uint8)
        first += acc * (s & (tokens == 2))  # token 2 starts: token 1 is complete
        keep = 1 - s  # a token starts: drop the count
        ndig *= keep
        ndig += isd
        np.maximum(longest, ndig, out=longest)
        m = isd.view(np.uint8) * np.uint8(9)
        m += 1
        m *= keep
        np.multiply(acc, m, out=acc, casting="unsafe")
        d *= isd
        np.add(acc, d, out=acc, casting="unsafe")
        prev = isd
    bad |= other
    bad |= tokens != 2
    bad |= longest > _MAX_INT_DIGITS
    return first, acc, prev


def fast_triplets(b: np.ndarray):
    """Parse the bytes ``b`` (uint8, whole lines of ``row col value``) into ``(rows, cols, values)``, or None.

    Returns
    -------
    rows, cols : ndarray of int32
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
