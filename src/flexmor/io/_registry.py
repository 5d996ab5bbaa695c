"""A registry of file formats for one purpose (read a model, read a body, or export a body).

Each format module registers itself at import time, like meshio's ``register_format``::

    MODEL_FORMATS.register("calculix", [".sti"], read_calculix, description="...")

Within one registry every suffix belongs to one format (registering a taken suffix is an
error), so the suffix of a file names its format; the longest matching suffix wins, so
``.ss.npz`` can belong to another format than ``.npz``. A format may also *claim* files by
their name ahead of the suffixes (Abaqus ``<job>_STIF1.mtx`` among Matrix Market ``.mtx``).
The same suffix may appear in different registries: each is asked for its own purpose.
Names are seen through ``.gz`` (:mod:`flexmor.io._open`): ``job.sti.gz`` is a CalculiX file,
read by a reader that takes compressed files (``gzip=True``) and refused, with the reason,
by one that cannot. A reader format may also *recognize* its files by their content
(``recognizes``): :func:`kind_of` asks it when a suffix belongs to both a model and a body format
(a Nastran ``.op4`` or ``.pch`` holds an FE model or a Craig-Bampton superelement).

The three registries of flexmor (:data:`MODEL_FORMATS`, :data:`BODY_FORMATS`,
:data:`EXPORT_FORMATS`) and their entry points (:func:`read`, :func:`read_body`,
:func:`export`) live here, below every format module; :mod:`flexmor.io` imports the format
families, which fill them.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

from ..errors import FlexmorWarning, OptionError, ReadError, check_keywords_of, did_you_mean
from ..units import to_si, unit_system
from ._geometry import check_cells, check_stiffness_geometry
from ._mass import check_mass_directions
from ._minors import check_minors
from ._open import is_gzip, plain_name

__all__ = ["BODY_FORMATS", "EXPORT_FORMATS", "MODEL_FORMATS", "Format", "Registry", "describe_formats", "export",
           "export_format", "kind_of", "read", "read_body", "unit_formats"]


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
    gzip : bool or str
        Readers: True when the reader takes its files gzip-compressed too (``job.sti.gz``,
        decompressed while read); else False, or the reason it cannot (the refusal says it).
    recognizes : callable, optional
        ``recognizes(path) -> bool``: whether a file with one of the suffixes holds this format's
        content, where the suffix is shared with other formats or companion files (a Nastran
        superelement among Nastran matrix files, Ansys ``.txt`` matrices among its map and
        coordinates): :func:`kind_of` and :meth:`Registry.takes` ask it; cheap, False when unsure.
    """

    name: str
    suffixes: tuple
    function: Callable
    description: str = ""
    claims: Callable | None = None
    claims_doc: str = ""
    aliases: tuple = ()
    gzip: bool | str = False
    recognizes: Callable | None = None

    def row(self) -> dict:
        """The format as a JSON-able dict (name, suffixes, description, ...)."""
        return {"name": self.name, "suffixes": list(self.suffixes), "claims": self.claims_doc or None,
                "aliases": list(self.aliases), "gzip": self.gzip is True, "description": self.description}

    def check_gzip(self, path: Path) -> None:
        """Refuse a gzip-compressed ``path`` when this format's reader cannot read it (ReadError with the reason)."""
        if self.gzip is True or not is_gzip(path):
            return
        why = self.gzip if isinstance(self.gzip, str) else f"the {self.name} reader reads uncompressed files only"
        raise ReadError(path, f"gzip-compressed: {why}; decompress it first (gunzip {path.name})")


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
                 claims: Callable | None = None, claims_doc: str = "", aliases=(), gzip: bool | str = False,
                 recognizes: Callable | None = None) -> Format:
        """Register ``function`` as format ``name`` for ``suffixes`` (with dot; case is ignored).

        Raises
        ------
        ValueError
            When a suffix, name or alias already belongs to another format of this registry.
        """
        fmt = Format(name, tuple(s.lower() for s in suffixes), function, description, claims, claims_doc,
                     tuple(a.lower() for a in aliases), gzip, recognizes)
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
        raise OptionError(f"format={format!r} is not a known {self.purpose} file type; "
                          f"{did_you_mean(key, self.names() + aliases)}"
                          "choose one of: " + ", ".join(self.names() + aliases), params=("format",))

    def by_path(self, path) -> Format | None:
        """The format of ``path``: a format claiming its name, else the longest matching suffix (or None).

        The name is seen through ``.gz``: ``job.sti.gz`` has the format of ``job.sti``.
        """
        path = Path(path)
        for fmt in self._formats.values():
            if fmt.claims is not None and fmt.claims(path):
                return fmt
        name = plain_name(path).lower()
        best, length = None, 0
        for fmt in self._formats.values():
            for suffix in fmt.suffixes:
                if name.endswith(suffix) and len(suffix) > length and len(name) > len(suffix):
                    best, length = fmt, len(suffix)
        return best

    def takes(self, path) -> Format | None:
        """The format that reads ``path`` (:meth:`by_path`), None also when that format's
        ``recognizes`` turns the file down (another format's or a companion file sharing its suffix)."""
        fmt = self.by_path(path)
        if fmt is not None and fmt.recognizes is not None and not fmt.recognizes(Path(path)):
            return None
        return fmt

    def known(self) -> str:
        """The suffixes by format, for messages: ``.sti (calculix), .inp (abaqus), ...``."""
        return ", ".join(f"{' '.join(f.suffixes)} ({f.name})" for f in self._formats.values())


#: FE model readers: ``reader(path, **options) -> FEModel``.
MODEL_FORMATS = Registry("FE model", "an")
#: Reduced-body readers: ``reader(path, **options) -> ReducedModel``.
BODY_FORMATS = Registry("reduced body")
#: Exporters of reduced bodies: ``writer(reduced, path, *, model=None, **options)``, atomic.
EXPORT_FORMATS = Registry("export", "an")

_REGISTRIES = {"model": MODEL_FORMATS, "body": BODY_FORMATS, "export": EXPORT_FORMATS}


def _checked(path: Path) -> Path:
    if not path.exists():
        raise ReadError(path, "file not found")
    if path.is_dir():
        raise ReadError(path, "is a directory, expected a file")
    return path


def _other_purpose(path, registry: Registry) -> str:
    """``" ('.h5' is a reduced body file)"`` when another reader registry knows the suffix of ``path``."""
    for other in (MODEL_FORMATS, BODY_FORMATS):
        fmt = other.by_path(path) if other is not registry else None
        if fmt is not None:
            return f" ({Path(path).name} is {other.noun} file: {fmt.name})"
    return ""


def _choose_reader(registry: Registry, path: Path, format: str | None, hint: str = "") -> Format:
    if format is not None:
        return registry.by_name(format)
    fmt = registry.by_path(path)
    if fmt is None:
        ext = (Path(plain_name(path)).suffix.lower() + (path.suffix.lower() if is_gzip(path) else "")) or "(none)"
        raise ReadError(path, f"unknown {registry.purpose} file type {ext!r}{_other_purpose(path, registry)}; "
                              f"known: {registry.known()}{hint}",
                        params=("format",) if hint else ())
    return fmt


def kind_of(path, format: str | None = None) -> str | None:
    """Whether ``path`` holds an FE model (``"model"``) or a reduced body (``"body"``); None when no reader knows it.

    ``format`` decides when given (a body format that is no model format: ``"body"``). Else a
    body format whose suffix the file has and that recognizes its content (a Nastran
    superelement among Nastran matrix files) makes it a body; else the suffix decides, a model
    format first.

    Parameters
    ----------
    path : str or path-like
    format : str, optional
        A format name of :data:`MODEL_FORMATS` or :data:`BODY_FORMATS`.
    """
    path = Path(path)
    if format is not None:
        key = str(format).lower()

        def named(reg):
            return any(key == f.name or key in f.aliases for f in reg.formats().values())
        return "body" if named(BODY_FORMATS) and not named(MODEL_FORMATS) else "model"
    body = BODY_FORMATS.by_path(path)
    model = MODEL_FORMATS.by_path(path)
    if body is not None and model is not None and body.recognizes is not None and path.is_file():
        return "body" if body.recognizes(path) else "model"
    if model is not None:
        return "model"
    return "body" if body is not None else None


def read(path, format: str | None = None, *, units: str | None = None, **options):
    """Read an FE model from ``path``.

    Parameters
    ----------
    path : str or path-like
        The main file of the FE export (e.g. CalculiX ``.sti``); files that belong with it
        are found beside it. Gzip-compressed files (``job.sti.gz``, with ``job.mas.gz`` ...
        beside it) are read as they are, decompressed while parsed.
    format : str, optional
        A name from :data:`MODEL_FORMATS`; by default chosen from the file name.
    units : str, optional
        The unit system of the file (``SI`` or ``m-kg-s``, ``mm-t-s``, ``mm-kg-ms``, ``mm-g-ms``,
        ``in-lbf-s``; :data:`flexmor.units.SYSTEMS`): the model is converted to SI and records it
        (:func:`flexmor.units.to_si`). By default the numbers are taken as given.
    **options
        Passed to the reader.

    Returns
    -------
    FEModel

    Raises
    ------
    ReadError
        Missing, unreadable or malformed file, or unknown suffix.
    OptionError
        Unknown ``format`` or ``units``.
    ModelError
        ``units`` other than SI for a model without an equation map.
    """
    path = Path(path)
    if path.is_dir():  # before its (missing) suffix is asked about
        raise ReadError(path, "is a folder; give the main file of the FE export in it (the suffixes: flexmor "
                              "info --formats)")
    fmt = _choose_reader(MODEL_FORMATS, path, format, " (or give format)")
    _checked(path)
    fmt.check_gzip(path)
    if units is not None:
        unit_system(units)  # an unknown name before the file is read
    check_keywords_of(f"read ({fmt.name})", options, fmt.function, also=("format", "units"))
    model = fmt.function(path, **options)
    check_minors(model)
    check_mass_directions(model)
    check_stiffness_geometry(model)
    check_cells(model)
    return to_si(model, units)


def read_body(path, format: str | None = None, **options):
    """Read a reduced body: flexmor's own ``.h5`` or a Nastran superelement (``.op4``, ``.pch``).

    Parameters
    ----------
    path : str or path-like
        The body file.
    format : str, optional
        A name from :data:`BODY_FORMATS`; by default chosen from the suffix.
    **options
        Passed to the reader (e.g. ``geometry=`` for a superelement).

    Returns
    -------
    ReducedModel

    Raises
    ------
    ReadError
        Missing or malformed file, or a suffix no body format has (the message lists them).
    OptionError
        Unknown ``format``.
    """
    path = Path(path)
    if path.is_dir():
        raise ReadError(path, "is a folder; give a reduced body file (.h5)")
    fmt = _choose_reader(BODY_FORMATS, path, format)
    _checked(path)
    fmt.check_gzip(path)
    check_keywords_of(f"read_body ({fmt.name})", options, fmt.function, also=("format",))
    return fmt.function(path, **options)


def export_format(path, format: str | None = None) -> str:
    """The export format name for ``path``: ``format`` (a name or alias) or the one its suffix names.

    Raises
    ------
    OptionError
        Unknown ``format``, a suffix no export format has (the message lists the formats), or a
        ``format`` whose files the suffix does not name while another format's do (``.mat`` for ``sid``).

    Warns
    -----
    FlexmorWarning
        A ``format`` given for a name whose suffix belongs to no export format (``body.py`` for
        ``exudyn``: the file holds that format's data all the same).
    """
    if format is not None:
        fmt = EXPORT_FORMATS.by_name(format)
        name = Path(path).name.lower()
        # the format's own suffixes, or their last part (.mat of .ss.mat, .npz of .exudyn.npz)
        if not any(name.endswith(s) or name.endswith("." + s.rsplit(".", 1)[-1]) for s in fmt.suffixes):
            other, own = EXPORT_FORMATS.by_path(path), " or ".join(fmt.suffixes)
            if other is not None:
                raise OptionError(f"{path}: its suffix names {other.name} files, format is {fmt.name}; end the "
                                  f"file's name in {own} or leave format out", params=("format",))
            warnings.warn(FlexmorWarning(f"{path}: written as {fmt.name} ({own}) although no export format has the "
                                         f"suffix {Path(path).suffix or '(none)'!r}", params=("format",)),
                          stacklevel=1)  # at this line: once, also when export() asks again for its caller's name
        return fmt.name
    fmt = EXPORT_FORMATS.by_path(path)
    if fmt is None:
        ext = Path(path).suffix.lower() or "(none)"
        raise OptionError(f"cannot tell the export type from the suffix {ext!r} (known: {EXPORT_FORMATS.known()}); "
                          f"give format ({', '.join(EXPORT_FORMATS.names())})", params=("format",))
    return fmt.name


def unit_formats() -> list[str]:
    """The export formats that write other unit systems than SI (their writer takes ``units``)."""
    import inspect

    return [f.name for f in EXPORT_FORMATS.formats().values() if "units" in inspect.signature(f.function).parameters]


def export(body, path, format: str | None = None, *, model=None, units: str | None = None, **options) -> str:
    """Write ``body`` to ``path`` in an export format, atomically.

    The inertia invariants of SID and Exudyn bodies are integrals over the full model's mass
    matrix and node coordinates, which the reduced body does not store (it stores the basis
    ``V``): those exports need the FE model the body was reduced from, and flexmor checks that
    its equation count matches ``V``.

    Parameters
    ----------
    body : ReducedModel
    path : str or path-like
    format : str, optional
        A name or alias from :data:`EXPORT_FORMATS` (``sid``, ``exudyn``, ``mat``, ``statespace``
        or ``ss``, ``hdf5``); default from the suffix (``.SID_FEM``, ``.mat``, ``.h5``, ...).
    model : FEModel or path-like, optional
        The full model the body was reduced from (required by ``sid`` and ``exudyn``), or its file.
    units : str, optional
        The unit system of the file (:data:`flexmor.units.SYSTEMS`), for the formats of
        :func:`unit_formats` (``sid``, ``mat``; the file states it); default SI. The body must
        know its model's units (``body.units``).
    **options
        Passed to the writer (e.g. ``nodes=[...]`` frame nodes, ``m1_order=`` for SID).

    Returns
    -------
    str
        The format name used.

    Raises
    ------
    OptionError
        Unknown ``format`` or ``units``, or ``units`` other than SI for a format that writes SI only.
    """
    from ..body import ReducedModel

    if not isinstance(body, ReducedModel):
        raise OptionError(f"export writes a reduced body (flexmor.reduce(...), or flexmor.io.read_body(path)), got "
                          f"{type(body).__name__}", params=("body",))
    if isinstance(model, (str, PathLike)):  # the FE model's file, as add_to_exudyn takes it
        model = read(model)
    name = export_format(path, format)
    check_keywords_of(f"export ({name})", options, EXPORT_FORMATS.by_name(name).function, drop=("model", "units"),
                      also=("format", "model", "units"))
    if units is not None:
        system = unit_system(units)
        if name in unit_formats():
            options["units"] = system.name
        elif not system.is_si:
            raise OptionError(f"{name} files are written in SI only; units={units!r} is for "
                              f"{', '.join(unit_formats())}", params=("units",))
    EXPORT_FORMATS.by_name(name).function(body, path, model=model, **options)
    return name


def describe_formats() -> dict[str, list[dict]]:
    """Every registered format: ``{"model": [...], "body": [...], "export": [...]}``, each a list of
    ``{"name", "suffixes", "claims", "aliases", "description"}`` in registration order."""
    return {kind: [f.row() for f in reg.formats().values()] for kind, reg in _REGISTRIES.items()}
