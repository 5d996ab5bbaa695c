"""The line syntax of Abaqus-style input decks, shared by the Abaqus and the CalculiX readers.

A deck is a sequence of keyword lines (``*KEYWORD, PARAM=VALUE, FLAG``, case-insensitive),
each followed by its data lines; lines starting with ``**`` are comments and blank lines are
skipped. ``*INCLUDE, INPUT=file`` inserts another file (relative to the folder of the file that
includes it), nested at most :data:`MAX_INCLUDE_DEPTH` levels. :func:`walk` reads a deck as
:class:`Keyword` and :class:`Data` items, includes inlined, each naming its file and line; the
readers interpret the keywords they know. Data lines continued on the next line (an element
whose line ends in a comma or is full, :func:`element_continues`) are the reader's to join.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from ..errors import ReadError
from ._open import is_gzip, open_binary
from ._text import FOREIGN, read_text, split_lines

__all__ = ["ELEMENT_LINE_ENTRIES", "MAX_INCLUDE_DEPTH", "Data", "Keyword", "check_last_lines", "element_continues",
           "include_path", "keyword_options", "walk"]

#: Deepest nesting of ``*INCLUDE`` files.
MAX_INCLUDE_DEPTH = 10

#: The most entries a data line of ``*ELEMENT`` holds (the element number and 15 nodes, then 16 nodes a line).
ELEMENT_LINE_ENTRIES = 16


@dataclass(frozen=True)
class Keyword:
    """A keyword line.

    Attributes
    ----------
    name : str
        Upper case, inner blanks single (``END PART``).
    options : dict of str to str
        ``PARAM=VALUE`` pairs, parameter names upper case, values unquoted; a flag maps to ``""``.
    path : Path
        The file of the line.
    line : int
        1-based line number.
    """

    name: str
    options: dict
    path: Path
    line: int


@dataclass(frozen=True)
class Data:
    """The data lines between a keyword line and the next one in the same file.

    Attributes
    ----------
    keyword : Keyword or None
        The keyword above the lines in their file; None for lines before the first keyword of
        a file and for lines after an ``*INCLUDE`` line, which belong to no keyword.
    lines : list of str
        The lines, stripped, without comments and blank lines.
    linenos : list of int
        1-based line number of each.
    path : Path
        The file of the lines.
    """

    keyword: Keyword | None
    lines: list
    linenos: list
    path: Path


def keyword_options(card: str) -> tuple[str, dict]:
    """The name and the options of the keyword line ``card`` (see :class:`Keyword`)."""
    parts = [p.strip() for p in card.lstrip("*").split(",")]
    opts = {}
    for p in parts[1:]:
        if p:
            key, _, val = p.partition("=")
            opts[key.strip().upper()] = val.strip().strip('"')
    return " ".join(parts[0].upper().split()), opts


def element_continues(line: str, entries: int, have: int, nodes: int | None) -> bool:
    """Whether an element continues on the data line after ``line``, the last of its ``*ELEMENT`` lines so far.

    ``entries`` counts the numbers on ``line``, ``have`` those of the element so far (its number and
    nodes, ``line``'s included), ``nodes`` is the node count of the element type (None: not known).
    An element continues while it has fewer nodes than its type, on a line that ends in a comma or
    is full (:data:`ELEMENT_LINE_ENTRIES`: a C3D20 is written as 16 entries and its last 5 nodes on
    the next line, with or without the comma, and CalculiX reads both); so a full line of a C3D15
    (its number and 15 nodes) ends it. Of a type of unknown node count, a line ending in a comma
    continues.
    """
    if nodes is None:
        return line.endswith(",")
    return have < 1 + nodes and (line.endswith(",") or entries >= ELEMENT_LINE_ENTRIES)


def include_path(path: Path, opts: dict, depth: int, lineno: int) -> Path:
    """The file named by ``*INCLUDE, INPUT=file`` (relative to ``path``'s folder), checked to exist
    and to nest at most :data:`MAX_INCLUDE_DEPTH` levels (``depth`` is the current level)."""
    inc = opts.get("INPUT", "").strip("\"'")
    if not inc:
        raise ReadError(path, "*INCLUDE without INPUT=file", lineno)
    if depth >= MAX_INCLUDE_DEPTH:
        raise ReadError(path, f"*INCLUDE nested deeper than {MAX_INCLUDE_DEPTH} levels", lineno)
    p = Path(inc) if Path(inc).is_absolute() else path.parent / inc
    if not p.exists() and Path(f"{p}.gz").is_file():  # shipped compressed: read as it is
        p = Path(f"{p}.gz")
    if not p.exists():
        raise ReadError(path, f"included file {inc} not found", lineno)
    return p


def walk(path, _depth: int = 0) -> Iterator[Keyword | Data]:
    """The keyword lines and data blocks of the deck ``path``, in file order, includes inlined.

    An ``*INCLUDE`` keyword comes before the items of the file it includes.

    Raises
    ------
    ReadError
        An unreadable file, or an ``*INCLUDE`` without ``INPUT=``, of a missing file or nested
        too deep (naming the including file and line); a ``*NODE`` or ``*ELEMENT`` line with a
        character such lines never hold (a control character, one beyond ASCII: Python would
        take some of them for a blank and read another number).
    """
    path = Path(path)
    keyword, data, linenos = None, [], []
    for lineno, line in enumerate(split_lines(read_text(path)), 1):
        s = line.strip()
        if not s or s.startswith("**"):
            continue
        if not s.startswith("*"):
            if keyword is not None and keyword.name in ("NODE", "ELEMENT") and FOREIGN.search(line):
                raise ReadError(path, f"character {FOREIGN.search(line).group()!r} in the *{keyword.name} line "
                                      f"{s[:60]!r}: is the file damaged?", lineno)
            data.append(s)
            linenos.append(lineno)
            continue
        if data:
            yield Data(keyword, data, linenos, path)
            data, linenos = [], []
        name, opts = keyword_options(s)
        keyword = Keyword(name, opts, path, lineno)
        yield keyword
        if name == "INCLUDE":
            yield from walk(include_path(path, opts, _depth, lineno), _depth + 1)
            keyword = None
    if data:
        yield Data(keyword, data, linenos, path)


def _cut_last_line(path: Path) -> bool:
    """Whether the last line of ``path`` holds data (no blank, no comment) but no line end."""
    with open_binary(path) as f:
        if is_gzip(path):
            tail = b""
            for chunk in iter(lambda: f.read(1 << 20), b""):
                tail = (tail + chunk)[-4096:]
        else:
            f.seek(0, 2)
            f.seek(max(f.tell() - 4096, 0))
            tail = f.read()
    last = tail.replace(b"\r", b"\n").rpartition(b"\n")[2].strip()
    return bool(last) and not last.startswith(b"**")


def check_last_lines(last: dict) -> None:
    """Refuse a deck file cut off in a data line: ``last`` maps each file of a deck to its last
    :class:`~flexmor.io._abaqus_syntax.Keyword` or :class:`~flexmor.io._abaqus_syntax.Data` item; a file
    whose last data line has no line end is named with that line (its last number may be cut short)."""
    for p, item in last.items():
        if isinstance(item, Data) and _cut_last_line(p):
            what = f"its *{item.keyword.name} data" if item.keyword is not None else "a data line"
            raise ReadError(p, f"last line {item.lines[-1][:40]!r} has no line end: the deck was cut off inside "
                               f"{what} (disk full, interrupted copy?); copy or write it again (a line that is "
                               "complete needs its line end)", item.linenos[-1])
