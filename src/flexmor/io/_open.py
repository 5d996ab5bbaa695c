"""Opening the files of the readers: plain or gzip-compressed (``.gz``), with errors that name the file.

FE exports are often shipped gzip-compressed (``job.sti.gz``, ``KAAX.pch.gz``). A reader opens
its file with :func:`open_binary`, which decompresses a ``.gz`` file while it is read (the
parsers that stream a file in chunks keep streaming: no temporary file, no whole copy in
memory); a damaged compressed file (cut off, wrong checksum, not gzip at all) is a
:class:`~flexmor.errors.ReadError` naming it, raised where the damage is met. The names of a
compressed file are seen through ``.gz``: :func:`suffix` and :func:`stem` of ``job.sti.gz``
are ``.sti`` and ``job``, and :func:`beside` finds the files that belong with it
(``job.mas.gz`` or ``job.mas``).
"""

from __future__ import annotations

import gzip
import os
import zlib
from pathlib import Path

from ..errors import ReadError

__all__ = ["GZIP_SUFFIX", "beside", "is_gzip", "open_binary", "plain_name", "read_all", "size_hint", "stem",
           "suffix"]

#: The suffix of a gzip-compressed file.
GZIP_SUFFIX = ".gz"
_DAMAGED = (EOFError, zlib.error, gzip.BadGzipFile)


def is_gzip(path) -> bool:
    """Whether ``path`` names a gzip-compressed file (its name ends in ``.gz``, any case)."""
    name = Path(path).name.lower()
    return name.endswith(GZIP_SUFFIX) and len(name) > len(GZIP_SUFFIX)


def plain_name(path) -> str:
    """The file name without ``.gz``: ``job.sti`` for ``job.sti.gz``, the name itself otherwise."""
    name = Path(path).name
    return name[:-len(GZIP_SUFFIX)] if is_gzip(path) else name


def suffix(path) -> str:
    """The lower-case suffix seen through ``.gz`` (``.sti`` for ``job.sti.gz`` and ``job.STI``)."""
    return Path(plain_name(path)).suffix.lower()


def stem(path) -> str:
    """The name without its suffix, seen through ``.gz`` (``job`` for ``job.sti.gz``)."""
    return Path(plain_name(path)).stem


def beside(path, suffix: str) -> Path | None:
    """The file ``<stem><suffix>`` beside ``path`` as it exists: plain or ``.gz``, the suffix in lower or upper case.

    The compression of ``path`` comes first (``job.mas.gz`` beside ``job.sti.gz``, ``job.mas``
    beside ``job.sti``), then the other. None when there is none.
    """
    path = Path(path)
    base = path.parent / stem(path)
    order = (GZIP_SUFFIX, "") if is_gzip(path) else ("", GZIP_SUFFIX)
    for gz in order:
        for suf in (suffix.lower(), suffix.upper()):
            p = Path(f"{base}{suf}{gz}")
            if p.is_file() and p != path:
                return p
    return None


class _GzipReader(gzip.GzipFile):
    """A gzip file whose damage (cut off, bad checksum, not gzip) is a ReadError naming it."""

    def __init__(self, path: Path):
        self._path = path
        super().__init__(filename=os.fspath(path), mode="rb")

    def _damaged(self, exc):
        what = ("cut off before its end (an interrupted copy or download?)" if isinstance(exc, EOFError)
                else f"not a valid gzip file ({exc})")
        return ReadError(self._path, f"damaged compressed file: {what}; compress it again or read the "
                                     "uncompressed file")

    def read(self, size=-1):
        try:
            return super().read(size)
        except _DAMAGED as exc:
            raise self._damaged(exc) from None

    def read1(self, size=-1):
        try:
            return super().read1(size)
        except _DAMAGED as exc:
            raise self._damaged(exc) from None

    def peek(self, n):
        try:
            return super().peek(n)
        except _DAMAGED as exc:
            raise self._damaged(exc) from None

    def readline(self, size=-1):
        try:
            return super().readline(size)
        except _DAMAGED as exc:
            raise self._damaged(exc) from None

    def seek(self, offset, whence=os.SEEK_SET):
        try:
            return super().seek(offset, whence)
        except _DAMAGED as exc:
            raise self._damaged(exc) from None


def open_binary(path):
    """Open ``path`` for reading bytes; a ``.gz`` file is decompressed as it is read.

    The file object supports ``read``, ``readline``, iteration and forward ``seek`` (a
    compressed file seeks by decompressing; ``seek(0, 2)`` is not supported there: use
    :func:`size_hint`). Use it as a context manager.

    Raises
    ------
    ReadError
        Missing file, a directory, no permission; for a ``.gz`` file, damage met while reading.
    """
    path = Path(path)
    try:
        if is_gzip(path):
            return _GzipReader(path)
        return open(path, "rb")
    except FileNotFoundError:
        raise ReadError(path, "file not found") from None
    except IsADirectoryError:
        raise ReadError(path, "is a directory, expected a file") from None
    except OSError as exc:
        raise ReadError(path, f"cannot read: {exc.strerror or exc}") from None


def read_all(path) -> bytes:
    """All bytes of ``path``, decompressed for a ``.gz`` file (:func:`open_binary`)."""
    with open_binary(path) as f:
        try:
            return f.read()
        except ReadError:
            raise
        except OSError as exc:
            raise ReadError(path, f"cannot read: {exc.strerror or exc}") from None


def size_hint(path) -> int:
    """The size of the content of ``path`` in bytes: exact for a plain file, an estimate for a ``.gz`` file.

    A gzip file records its uncompressed size modulo 2**32 in its last four bytes; the estimate
    is that size, raised by multiples of 2**32 until it is at least the compressed size. Use it
    to size buffers, never to judge the content.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if not is_gzip(path) or size < 18:
            return size
        with open(path, "rb") as f:
            f.seek(-4, os.SEEK_END)
            isize = int.from_bytes(f.read(4), "little")
    except OSError:
        return 0
    while isize < size:
        isize += 1 << 32
    return isize
