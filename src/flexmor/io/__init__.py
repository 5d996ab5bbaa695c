"""Readers and writers of FE files, in one registry.

Each format lives in its own module that calls :func:`register_format` at import time
(``register_format(name, extensions, reader=..., writer=...)``, like meshio). ``read(path)``
chooses the reader by the file suffix; ``format=`` overrides.

A reader takes a path and returns a :class:`flexmor.model.FEModel`; it raises
:class:`flexmor.errors.ReadError` naming the file (and line) for anything malformed.
"""

from __future__ import annotations

import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..errors import OptionError, ReadError

__all__ = ["register_format", "read", "formats", "FORMATS", "atomic_write"]


@dataclass(frozen=True)
class Format:
    """A registered file format."""

    name: str
    extensions: tuple
    reader: Callable | None = None
    writer: Callable | None = None
    description: str = ""
    match: Callable | None = None


#: name -> Format
FORMATS: dict[str, Format] = {}


def register_format(name: str, extensions, reader=None, writer=None, description: str = "",
                    match: Callable | None = None) -> None:
    """Register a file format under ``name`` for the given suffixes (with dot, lower case).

    ``match(path) -> bool`` optionally tells files of this format apart from other formats
    with the same suffix (e.g. Abaqus ``<job>_STIF1.mtx`` among Matrix Market ``.mtx``): a
    format whose ``match`` accepts the path wins; one whose ``match`` refuses it comes last.
    """
    FORMATS[name] = Format(name, tuple(e.lower() for e in extensions), reader, writer, description, match)


def formats() -> dict[str, Format]:
    """All registered formats (importing the built-in modules first)."""
    _load_builtin()
    return dict(FORMATS)


def _load_builtin() -> None:
    from . import abaqus, ansys, calculix, hdf5, matlab, matrix_market, nastran, sid  # noqa: F401  (they register themselves)


def _suffix(path: Path) -> str:
    return path.suffix.lower()


def read(path, format: str | None = None, **options):
    """Read an FE model from ``path``.

    Parameters
    ----------
    path : str or path-like
        The main file of the FE export (e.g. CalculiX ``.sti``); files that belong with it
        are found beside it.
    format : str, optional
        Registered format name; by default chosen from the suffix.
    **options
        Passed to the reader.

    Returns
    -------
    FEModel

    Raises
    ------
    ReadError
        Missing, unreadable or malformed file, or unknown suffix.
    """
    _load_builtin()
    path = Path(path)
    if format is None:
        ext = _suffix(path)
        cands = [f for f in FORMATS.values() if ext in f.extensions and f.reader is not None]
        if not cands:
            known = sorted({e for f in FORMATS.values() if f.reader for e in f.extensions})
            raise ReadError(path, f"unknown file type {ext!r}; known: {' '.join(known)} (or give format)",
                            params=("format",))
        cands.sort(key=lambda f: 1 if f.match is None else (0 if f.match(path) else 2))
        fmt = cands[0]
    else:
        if format not in FORMATS or FORMATS[format].reader is None:
            raise OptionError(
                f"format={format!r} is not a known reader; choose one of: "
                + ", ".join(sorted(k for k, f in FORMATS.items() if f.reader))
            )
        fmt = FORMATS[format]
    if not path.exists():
        raise ReadError(path, "file not found")
    if path.is_dir():
        raise ReadError(path, "is a directory, expected a file")
    return fmt.reader(path, **options)


def atomic_write(path, write: Callable[[str], None]) -> None:
    """Call ``write(tmp_path)`` and rename the temporary file to ``path`` only on success.

    Every file flexmor writes goes through this function. The temporary file
    (``.NAME.PID.RANDOM.tmp``) lives in the same directory (same file system), so the rename
    is atomic: readers see either the old file or the complete new one, never a half-written
    one. The data are flushed to disk before the rename. On any exception inside ``write``
    (including ``KeyboardInterrupt``) the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        write(str(tmp))
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
