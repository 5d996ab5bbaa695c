"""Files in and out: three format registries, one small entry point each.

* :func:`read` — an FE model (:class:`~flexmor.model.FEModel`) from an FE program's export
  (:data:`MODEL_FORMATS`: CalculiX, Abaqus, Ansys, Nastran, Matrix Market, MATLAB, SID);
* :func:`read_body` — a reduced body (:class:`~flexmor.projection.ReducedModel`)
  (:data:`BODY_FORMATS`: flexmor's own HDF5, Nastran superelements); :func:`write_body`
  writes flexmor's own HDF5 body file;
* :func:`export` — a reduced body to a file for another program (:data:`EXPORT_FORMATS`:
  SID, Exudyn, MATLAB, state space, HDF5).

The file's suffix chooses the format within the registry asked (``format=`` overrides), so
the same suffix may mean different things to different registries (``.mat``: a model to read,
a body to export). Each format family is a module or subpackage that registers itself
(``MODEL_FORMATS.register(name, suffixes, reader, description=...)``); :func:`describe_formats`
lists them all (``flexmor info --formats``). Readers raise :class:`flexmor.errors.ReadError`
naming the file (and line) for anything malformed. Every file flexmor writes goes through
:func:`atomic_write`.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path

from ..errors import OptionError, ReadError
from ._registry import Format, Registry

__all__ = ["BODY_FORMATS", "EXPORT_FORMATS", "MODEL_FORMATS", "Format", "Registry", "atomic_write",
           "describe_formats", "export", "export_format", "read", "read_body", "write_body"]

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
        ext = path.suffix.lower() or "(none)"
        raise ReadError(path, f"unknown {registry.purpose} file type {ext!r}{_other_purpose(path, registry)}; "
                              f"known: {registry.known()}{hint}", params=("format",) if hint else ())
    return fmt


def read(path, format: str | None = None, **options):
    """Read an FE model from ``path``.

    Parameters
    ----------
    path : str or path-like
        The main file of the FE export (e.g. CalculiX ``.sti``); files that belong with it
        are found beside it.
    format : str, optional
        A name from :data:`MODEL_FORMATS`; by default chosen from the file name.
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
        Unknown ``format``.
    """
    path = Path(path)
    fmt = _choose_reader(MODEL_FORMATS, path, format, " (or give format)")
    return fmt.function(_checked(path), **options)


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
    fmt = _choose_reader(BODY_FORMATS, path, format)
    return fmt.function(_checked(path), **options)


def export_format(path, format: str | None = None) -> str:
    """The export format name for ``path``: ``format`` (a name or alias) or the one its suffix names.

    Raises
    ------
    OptionError
        Unknown ``format``, or a suffix no export format has (the message lists the formats).
    """
    if format is not None:
        return EXPORT_FORMATS.by_name(format).name
    fmt = EXPORT_FORMATS.by_path(path)
    if fmt is None:
        ext = Path(path).suffix.lower() or "(none)"
        raise OptionError(f"cannot tell the export type from the suffix {ext!r} (known: {EXPORT_FORMATS.known()}); "
                          f"give format ({', '.join(EXPORT_FORMATS.names())})", params=("format",))
    return fmt.name


def export(reduced, path, format: str | None = None, *, model=None, **options) -> str:
    """Write ``reduced`` to ``path`` in an export format, atomically.

    The inertia invariants of SID and Exudyn bodies are integrals over the full model's mass
    matrix and node coordinates, which the reduced body does not store (it stores the basis
    ``V``): those exports need the FE model the body was reduced from, and flexmor checks that
    its equation count matches ``V``.

    Parameters
    ----------
    reduced : ReducedModel
    path : str or path-like
    format : str, optional
        A name or alias from :data:`EXPORT_FORMATS` (``sid``, ``exudyn``, ``mat``, ``statespace``
        or ``ss``, ``hdf5``); default from the suffix (``.SID_FEM``, ``.mat``, ``.h5``, ...).
    model : FEModel, optional
        The full model the body was reduced from (required by ``sid`` and ``exudyn``).
    **options
        Passed to the writer (e.g. ``nodes=[...]`` frame nodes, ``m1_order=`` for SID).

    Returns
    -------
    str
        The format name used.
    """
    name = export_format(path, format)
    EXPORT_FORMATS.by_name(name).function(reduced, path, model=model, **options)
    return name


def describe_formats() -> dict[str, list[dict]]:
    """Every registered format: ``{"model": [...], "body": [...], "export": [...]}``, each a list of
    ``{"name", "suffixes", "claims", "aliases", "description"}`` in registration order."""
    return {kind: [f.row() for f in reg.formats().values()] for kind, reg in _REGISTRIES.items()}


#: A context-manager factory ``commit_guard(path)`` wrapped around the final rename of every
#: :func:`atomic_write`, or None. An application sets it to veto the rename (raise in
#: ``__enter__``) or to record the file written; the command line uses it so that a run
#: terminated by a signal leaves no output (:mod:`flexmor.cli`).
commit_guard: Callable | None = None


def atomic_write(path, write: Callable[[str], None]) -> None:
    """Call ``write(tmp_path)`` and rename the temporary file to ``path`` only on success.

    Every file flexmor writes goes through this function. The temporary file
    (``.NAME.PID.RANDOM.tmp``) lives in the same directory (same file system), so the rename
    is atomic: readers see either the old file or the complete new one, never a half-written
    one. The data are flushed to disk before the rename, which runs inside :data:`commit_guard`
    when one is set. On any exception inside ``write`` (including ``KeyboardInterrupt``) the
    temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        write(str(tmp))
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        with (commit_guard(path) if commit_guard is not None else contextlib.nullcontext()):
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


# The built-in formats register themselves (listings follow the order of registration).
from . import hdf5, calculix, abaqus, matrix_market, ansys, nastran, sid, exudyn, matlab, statespace  # noqa: F401, I001
from . import matrix_market_export  # noqa: F401, E402
from .nastran import nastran_export  # noqa: F401, E402
from . import vtu  # noqa: F401, E402
from .hdf5 import write_body  # noqa: E402
