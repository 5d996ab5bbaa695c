"""Shared helpers for the readers: opening files with clear errors, numeric line parsing.

:func:`parse_triplets` reads ``row col value`` files of any size. It parses the bytes in
chunks of whole lines: first with the layout-checking parser of :mod:`flexmor.io._fastparse`
(hundreds of MB/s for the fixed formats FE programs print), else with NumPy's C text parser;
only when that fails, or when the parsed numbers break a rule, does it scan the file line by
line to report the first offending line with its number.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ._fastparse import fast_triplets
from ._open import open_binary, read_all, size_hint

__all__ = ["FOREIGN", "check_text", "entry_line", "parse_triplets", "read_bytes", "read_text", "split_lines", "both"]

_COMMENT_CHARS = "#%*!"
#: A character a data line of numbers never holds: control characters other than tab and line ends,
#: anything beyond ASCII (Python's ``split`` and ``float`` take e.g. U+001C or a no-break space for a blank,
#: so a changed byte could turn ``3.2e+01`` into the number ``.2e+01`` without a word), and the underscore
#: (``float`` and NumPy take ``-6.02964743_897478E+06`` for the number with that digit dropped).
FOREIGN = re.compile(r"[^\t\n\r\x20-\x5e\x60-\x7e]")
_COMMENT_BYTES = (b"#", b"%", b"*", b"!")
_BLOCK = 50_000  # lines per block of the diagnosing scanner
_CHUNK = 1 << 21  # bytes per chunk of the fast parser


def check_text(path: Path, raw: bytes | None = None) -> None:
    """Refuse a missing, empty or binary file (judged by its first 64 kB unless ``raw`` is given).

    A ``.gz`` file is judged by its decompressed content (:func:`~flexmor.io._open.open_binary`).
    """
    path = Path(path)
    if not path.exists():
        raise ReadError(path, "file not found")
    if path.is_dir():
        raise ReadError(path, "is a directory, expected a file")
    try:
        if raw is None:
            with open_binary(path) as f:
                head = f.read(65536)
                if head.isspace():
                    head += f.read()
        else:
            head = raw
    except OSError as exc:
        raise ReadError(path, f"cannot read: {exc.strerror}") from None
    if not head or head.isspace():
        raise ReadError(path, "file is empty")
    if b"\x00" in head[:65536]:
        raise ReadError(path, "looks like a binary file, expected text")


def read_bytes(path) -> bytes:
    """Return the bytes of a text file ``path`` (decompressed when it is a ``.gz`` file); binary content or
    missing files raise ReadError."""
    path = Path(path)
    raw = read_all(path) if path.is_file() else None
    check_text(path, raw)
    return raw


def read_text(path) -> str:
    """Return the text of ``path`` (decompressed when it is a ``.gz`` file); binary content or missing files
    raise ReadError."""
    return _decode(read_bytes(path))


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def split_lines(text: str) -> list:
    """The lines of ``text`` at line ends only (LF, CRLF or CR): ``str.splitlines`` also breaks at
    U+001C, U+0085 and others, which in a damaged file would split a line of numbers."""
    return _LINE_END.split(text)


_LINE_END = re.compile(r"\r\n?|\n")


def _data_lines(text: str):
    """Yield ``(lineno, stripped_line)`` of the lines that are neither blank nor comments."""
    for lineno, line in enumerate(split_lines(text), 1):
        s = line.strip()
        if s and s[0] not in _COMMENT_CHARS:
            yield lineno, s


def _to_index(tok: str) -> int:
    """Parse an index token; integral floats such as ``3.0`` are accepted like the fast path."""
    try:
        return int(tok)
    except ValueError:
        v = float(tok)  # ValueError propagates
        if not v.is_integer():
            raise ValueError(tok) from None
        return int(v)


def _loadtxt(text: str):
    """``np.loadtxt`` of ``text`` (Fortran exponents and commas allowed) into an (k, 3) float array, or None on
    any parse problem. Blank text is None before NumPy would warn of it: no ``catch_warnings`` here, since the
    parse runs on worker threads (:func:`both`) and that context would change the warning filters of all."""
    text = text.replace(",", " ").replace("D", "E").replace("d", "e")
    if not text.strip():
        return None
    try:
        a = np.loadtxt(io.StringIO(text), dtype=np.float64, ndmin=2, comments=None)
    except (ValueError, OverflowError):
        return None
    if a.shape[0] == 0 or a.shape[1] != 3:
        return None
    return a


def _header_end(raw: bytes) -> int:
    """Offset of the first line after the leading blank and comment lines (a Matrix Market header)."""
    pos = 0
    while pos < len(raw):
        end = raw.find(b"\n", pos)
        end = len(raw) if end < 0 else end + 1
        s = raw[pos:min(end, pos + 4096)].strip()
        if s and s[:1] not in _COMMENT_BYTES:
            break
        pos = end
    return pos


def _fast_triplets(path: Path, index_dtype):
    """Vectorized parse into ``(rows, cols, values)`` as written, or None when the text needs the scanner.

    The file is streamed in chunks of whole lines (a ``.gz`` file decompressed as it is read)
    into arrays sized for the file's size over the shortest line of the first chunk (grown
    should a later line be shorter, or the size of a compressed file's content have been
    underestimated; shrunk in place at the end), so the text is never held whole. Leading
    comment lines (a header) are skipped; comments further down
    go to the scanner. Each chunk is parsed by :func:`~flexmor.io._fastparse.fast_triplets`,
    else by ``np.loadtxt``; non-integral indices give None.
    """
    size = size_hint(path)
    with open_binary(path) as f:
        head = f.read(_CHUNK)
        start = _header_end(head)
        if start >= _CHUNK:
            return None  # a header longer than a chunk: leave it to the scanner
        rows = cols = vals = None
        k, rest = 0, head[start:]
        del head
        while True:
            block = f.read(_CHUNK)
            buf = rest + block if rest else block
            if not buf:
                break
            cut = buf.rfind(b"\n") + 1 if block else len(buf)
            if cut == 0:  # no line end yet: read on
                rest = buf
                continue
            if rows is None:
                ends = np.flatnonzero(np.frombuffer(buf, dtype=np.uint8, count=cut) == 10)
                shortest = int(min(ends[0] + 1, np.diff(ends).min(initial=cut))) if ends.size else cut
                cap = (size - start) // max(shortest, 1) + 2
                rows, cols = np.empty(cap, dtype=index_dtype), np.empty(cap, dtype=index_dtype)
                vals = np.empty(cap, dtype=np.float64)
            got = _chunk(buf, cut)
            if got is None:
                return None
            rest = buf[cut:]
            del buf, block
            m = got[0].size
            if k + m > rows.size:  # shorter lines than the first chunk's: grow
                grow = max(k + m, rows.size + rows.size // 4)
                rows, cols, vals = (np.concatenate([x[:k], np.empty(grow - k, x.dtype)]) for x in (rows, cols, vals))
            rows[k:k + m], cols[k:k + m], vals[k:k + m] = got
            k += m
    if rows is None:
        return np.zeros(0, index_dtype), np.zeros(0, index_dtype), np.zeros(0)
    for x in (rows, cols, vals):
        x.resize(k, refcheck=False)  # realloc: the unused capacity is returned, nothing copied
    return rows, cols, vals


def _chunk(buf: bytes, cut: int):
    """``(rows, cols, values)`` of the whole lines ``buf[:cut]``, or None (comments, non-integral indices, parse error).

    A first line of another layout (the size line of Matrix Market) is parsed on its own.
    """
    if any(buf.find(ch, 0, cut) >= 0 for ch in _COMMENT_BYTES):
        return None  # loadtxt would also strip comments in mid-line; let the scanner decide
    b = np.frombuffer(buf, dtype=np.uint8, count=cut)
    got = fast_triplets(b)
    if got is not None:
        return got
    if buf[:cut].isspace():  # blank lines (at the end of the file)
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    nl = int(np.argmax(b == 10)) + 1 if b[-1] == 10 else 0
    if 0 < nl < b.size:
        first, got = _loadtxt_chunk(b[:nl]), fast_triplets(b[nl:])
        if first is not None and got is not None:
            return tuple(np.concatenate([x, y]) for x, y in zip(first, got))
    return _loadtxt_chunk(b)


def _loadtxt_chunk(b: np.ndarray):
    if np.any(((b < 32) & (b != 9) & (b != 10) & (b != 13)) | (b > 126)):
        return None  # a foreign character: the scanner names its line
    text = b.tobytes().decode("latin-1")
    a = _loadtxt(text)
    if a is None or not np.all(a[:, :2] == np.floor(a[:, :2])) or np.abs(a[:, :2]).max() > 2**31:
        return None
    return a[:, 0], a[:, 1], a[:, 2]


def _in_range(rows, cols, vals, base: int, n: int | None) -> bool:
    """Whether all parsed triplets have in-range indices and finite values."""
    if rows.size == 0:
        return True
    return bool(min(rows.min(), cols.min()) >= base
                and (n is None or max(rows.max(), cols.max()) - base < n)
                and np.all(np.isfinite(vals)))


def _valid(a: np.ndarray, base: int, n: int | None) -> bool:
    """Whether all parsed triplets have integral in-range indices and finite values."""
    if a.shape[0] == 0:
        return True
    ij = a[:, :2]
    return bool(
        np.all(ij == np.floor(ij))
        and ij.min() >= base
        and (n is None or ij.max() - base < n)
        and np.all(np.isfinite(a[:, 2]))
    )


def parse_triplets(path, *, one_based: bool = True, n: int | None = None, index_dtype=np.int64):
    """Parse ``row col value`` lines (whitespace or comma separated).

    Blank lines and lines starting with ``# % * !`` are skipped; Fortran exponents
    (``1.0D+03``) are accepted.

    Parameters
    ----------
    path : str or path-like
        The text file.
    one_based : bool
        Whether indices start at 1 (else 0).
    n : int, optional
        Matrix size; indices beyond it are refused.
    index_dtype : dtype
        Of the returned indices (``np.int32`` saves memory when ``n`` fits it).

    Returns
    -------
    rows, cols : ndarray of ``index_dtype``
        0-based indices, in file order.
    vals : ndarray of float64
        Values, in file order.

    Raises
    ------
    ReadError
        For every malformed line (wrong column count, non-numeric or non-integral index,
        index below the base or beyond ``n``, NaN or Inf value), with its line number.
    """
    path = Path(path)
    check_text(path)
    base = 1 if one_based else 0
    got = _fast_triplets(path, index_dtype)
    if got is None or not _in_range(*got, base, n):
        got = None
        a = _scan_triplets(path, read_text(path), base, n)
        got = a[:, 0].astype(index_dtype), a[:, 1].astype(index_dtype), np.ascontiguousarray(a[:, 2])
    rows, cols, vals = got
    rows -= base
    cols -= base
    return rows, cols, vals


def _scan_triplets(path: Path, text: str, base: int, n: int | None) -> np.ndarray:
    """Parse in blocks of lines: each block vectorized if it can be, else line by line.

    Line numbers stay exact; only a block with comments or a defect is scanned in Python, so
    a defect near the end of a huge file is found in seconds.
    """
    lines = split_lines(text)
    parts = []
    for start in range(0, len(lines), _BLOCK):
        block = lines[start:start + _BLOCK]
        joined = "\n".join(block)
        a = None
        if not any(ch in joined for ch in _COMMENT_CHARS) and not FOREIGN.search(joined):
            a = _loadtxt(joined)
        if a is None or not _valid(a, base, n):
            a = _scan_block(path, block, start, base, n)
        parts.append(a)
    a = np.concatenate(parts) if parts else np.zeros((0, 3))
    if a.shape[0] == 0:
        raise ReadError(path, "no matrix entries found")
    return a


def _scan_block(path: Path, lines: list, offset: int, base: int, n: int | None) -> np.ndarray:
    """Line-by-line parse of ``lines`` (line numbers start after ``offset``); raises at the first defect."""
    out = []
    for lineno, line in enumerate(lines, offset + 1):
        s = line.strip()
        if not s or s[0] in _COMMENT_CHARS:
            continue
        bad = FOREIGN.search(line)  # the line as read: strip() removes a trailing U+00A0
        if bad:
            raise ReadError(path, f"character {bad.group()!r} in {s[:60]!r}, which a line of numbers does not "
                                  "hold; is the file damaged?", lineno)
        parts = s.replace(",", " ").split()
        if len(parts) != 3:
            raise ReadError(path, f"expected 3 columns 'row col value', found {len(parts)} in {s[:60]!r}; "
                            "is the file truncated or damaged?", lineno)
        try:
            i, j = _to_index(parts[0]), _to_index(parts[1])
        except ValueError:
            raise ReadError(path, f"row and column must be integers, got {s[:60]!r}", lineno) from None
        try:
            v = float(parts[2].replace("D", "E").replace("d", "e"))
        except ValueError:
            raise ReadError(path, f"non-numeric value {parts[2][:30]!r}", lineno) from None
        if i < base or j < base:
            raise ReadError(path, f"index {min(i, j)} below {base} ({base}-based indices expected)", lineno)
        if n is not None and (i - base >= n or j - base >= n):
            raise ReadError(path, f"index {max(i, j)} beyond the matrix size {n}", lineno)
        if not np.isfinite(v):
            raise ReadError(path, f"non-finite value {parts[2]}; the FE program wrote NaN or Inf", lineno)
        out.append((i, j, v))
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def entry_line(path, k: int) -> int | None:
    """Line number (1-based) of the ``k``-th (0-based) data line of a triplet file.

    Used to point at an entry that breaks a rule found only after vectorized parsing
    (duplicates, wrong triangle). Returns None when there is no such line.
    """
    text = read_text(path)
    for count, (lineno, _) in enumerate(_data_lines(text)):
        if count == k:
            return lineno
    return None


def both(read, first, second):
    """``(read(first), read(second))``, the two parsed side by side on two threads where the process has two
    CPUs (the parse runs mostly without the GIL); the first file's error is raised first, as read in turn."""
    from concurrent.futures import ThreadPoolExecutor

    from ..linalg.threads import cores

    if cores() < 2:
        return read(first), read(second)
    with ThreadPoolExecutor(2) as ex:
        a, b = ex.submit(read, first), ex.submit(read, second)
        return a.result(), b.result()
