"""A registry of file formats for one purpose (read a model, read a body, or export a body).

Each format module registers itself at import time, like meshio's ``register_format``::

    MODEL_FORMATS.register("calculix", [".sti"], read_calculix, description="...")

Within one registry every suffix belongs to one format (registering a taken suffix is an
error), so the suffix of a file names its format; the longest matching suffix wins, so
``.ss.npz`` can belong to another format than ``.npz``. A format may also *claim* files by
their name ahead of the suffixes (Abaqus ``<job>_STIF1.mtx`` among Matrix Market ``.mtx``).
The same suffix may appear in different registries: each is asked for its own purpose.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import OptionError

__all__ = ["Format", "Registry"]


@dataclass(frozen=True)
class Format:
    """A registered file format.

    Attributes
    ----------
    name : str
        The name given to ``format=`` (``--format``).
    suffixes : tuple of str
        Lower-case suffixes with their dot (``.sti``; compound ones such as ``.ss.npz`` allowed).
    function : callable
        The reader ``function(path, **options)`` or the writer ``function(reduced, path, model=..., **options)``.
    description : str
        One line for listings.
    claims : callable, optional
        ``claims(path) -> bool``: files of this format recognized by their name, ahead of the suffixes.
    claims_doc : str
        How the claimed file names look (``<job>_STIF<n>.mtx``), for listings.
    aliases : tuple of str
        Other names accepted for ``name``.
    """

    name: str
    suffixes: tuple
    function: Callable
    description: str = ""
    claims: Callable | None = None
    claims_doc: str = ""
    aliases: tuple = ()

    def row(self) -> dict:
        """The format as a JSON-able dict (name, suffixes, description, ...)."""
        return {"name": self.name, "suffixes": list(self.suffixes), "claims": self.claims_doc or None,
                "aliases": list(self.aliases), "description": self.description}


class Registry:
    """File formats of one purpose, chosen by name or by the file's suffix.

    Parameters
    ----------
    purpose : str
        What the formats hold, for messages (``"FE model"``, ``"reduced body"``, ``"export"``).
    article : str
        ``"a"`` or ``"an"``, as spoken before ``purpose``.
    """

    def __init__(self, purpose: str, article: str = "a"):
        self.purpose = purpose
        self.noun = f"{article} {purpose}"
        self._formats: dict[str, Format] = {}

    def register(self, name: str, suffixes, function: Callable, *, description: str = "",
                 claims: Callable | None = None, claims_doc: str = "", aliases=()) -> Format:
        """Register ``function`` as format ``name`` for ``suffixes`` (with dot; case is ignored).

        Raises
        ------
        ValueError
            When a suffix, name or alias already belongs to another format of this registry.
        """
        fmt = Format(name, tuple(s.lower() for s in suffixes), function, description, claims, claims_doc,
                     tuple(a.lower() for a in aliases))
        for other in self._formats.values():
            if other.name == name:
                continue
            taken = set(fmt.suffixes) & set(other.suffixes)
            if taken:
                raise ValueError(f"{self.purpose} format {name!r}: suffix {' '.join(sorted(taken))} already "
                                 f"belongs to {other.name!r}")
            names = ({name} | set(fmt.aliases)) & ({other.name} | set(other.aliases))
            if names:
                raise ValueError(f"{self.purpose} format {name!r}: name {' '.join(sorted(names))} already taken "
                                 f"by {other.name!r}")
        self._formats[name] = fmt
        return fmt

    def formats(self) -> dict[str, Format]:
        """The registered formats by name, in the order of registration."""
        return dict(self._formats)

    def names(self) -> list[str]:
        """The format names, in the order of registration."""
        return list(self._formats)

    def by_name(self, format: str) -> Format:
        """The format called ``format`` (or one of its aliases); an OptionError listing the names otherwise."""
        key = str(format).lower()
        for fmt in self._formats.values():
            if key == fmt.name or key in fmt.aliases:
                return fmt
        aliases = [a for f in self._formats.values() for a in f.aliases]
        raise OptionError(f"format={format!r} is not {self.noun} format; choose one of: "
                          + ", ".join(self.names() + aliases))

    def by_path(self, path) -> Format | None:
        """The format of ``path``: a format claiming its name, else the longest matching suffix (or None)."""
        path = Path(path)
        for fmt in self._formats.values():
            if fmt.claims is not None and fmt.claims(path):
                return fmt
        name = path.name.lower()
        best, length = None, 0
        for fmt in self._formats.values():
            for suffix in fmt.suffixes:
                if name.endswith(suffix) and len(suffix) > length and len(name) > len(suffix):
                    best, length = fmt, len(suffix)
        return best

    def known(self) -> str:
        """The suffixes by format, for messages: ``.sti (calculix), .inp (abaqus), ...``."""
        return ", ".join(f"{' '.join(f.suffixes)} ({f.name})" for f in self._formats.values())
