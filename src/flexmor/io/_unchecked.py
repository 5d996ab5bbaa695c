"""Reads whose format cannot show every damage: one warning naming what could not be cross-checked.

Most formats let a reader see a damaged file (a count, a second copy, a shared pattern, a
record length). Some cannot show every damage: a changed value in an OUTPUT4 record, a lost
entry line of a DMIG matrix stored as one triangle, two swapped lines of an Ansys mapping
vector. After every check such a file allows, its reader issues one :class:`UncheckedWarning`
per read naming what could not be checked.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from ..errors import FlexmorWarning

__all__ = ["UncheckedWarning", "warn_unchecked"]


class UncheckedWarning(FlexmorWarning):
    """A file was read as given: its format holds nothing to cross-check part of it against.

    Filter it with ``warnings.filterwarnings("ignore", category=UncheckedWarning)`` to trust
    such files.
    """


def warn_unchecked(path, what: str) -> None:
    """Issue the :class:`UncheckedWarning` ``"<file name>: <what>"`` (once per read); ``path`` may be a list of
    the files of one set (``"<name>, <name>: <what>"``)."""
    names = ", ".join(Path(p).name for p in path) if isinstance(path, (list, tuple)) else Path(path).name
    warnings.warn(UncheckedWarning(f"{names}: {what}"), stacklevel=3)
