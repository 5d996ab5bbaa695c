"""Export of reduced bodies to multibody codes and other tools: one entry point, ``export``.

Exporters register themselves like the readers (``register_format(name, extensions,
writer=...)``); a writer is called as ``writer(reduced, path, model=..., **options)``.

=============  ============  ===================================================  ==========
format         suffix        contents                                             FE model
=============  ============  ===================================================  ==========
``sid``        ``.SID_FEM``  Standard Input Data with all inertia invariants      required
``exudyn``     ``.npz``      ObjectFFRFreducedOrderInterface data for Exudyn      required
``mat``        ``.mat``      reduced matrices, basis, nodes (+ invariants)        optional
``statespace`` ``.npz``      first-order ``A B C D`` (+ descriptor ``E Ae Be``)   unused
=============  ============  ===================================================  ==========

The inertia invariants are integrals over the full model's mass matrix and node coordinates,
which the reduced body does not store (it stores the basis ``V``): exporting to an MBS code
therefore needs the FE model the body was reduced from (``flexmor export BODY.h5 --model
MODEL``); flexmor checks that its equation count matches ``V``.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import OptionError
from . import FORMATS

__all__ = ["ALIASES", "EXPORT_FORMATS", "export"]

#: Export formats (names) and aliases accepted by :func:`export`.
EXPORT_FORMATS = ("sid", "exudyn", "mat", "statespace")
ALIASES = {"ss": "statespace", "state-space": "statespace", "matlab": "mat", "sid_fem": "sid"}


def _load():
    from . import exudyn, matlab_export, sid, statespace  # noqa: F401  (they register themselves)


def export_format(path, format: str | None = None) -> str:
    """The export format name for ``path`` (from ``format`` or the suffix)."""
    _load()
    if format is not None:
        name = ALIASES.get(format.lower(), format.lower())
        if name not in EXPORT_FORMATS:
            raise OptionError(f"format={format!r} is not allowed; choose one of the export formats: "
                              + ", ".join(EXPORT_FORMATS + tuple(ALIASES)), params=("format",))
        return name
    ext = Path(path).suffix.lower()
    cands = [n for n in EXPORT_FORMATS if ext in FORMATS[n].extensions]
    if len(cands) != 1:
        raise OptionError(f"cannot tell the export type from the suffix {ext or '(none)'!r}"
                          + (f" (it fits {' and '.join(cands)})" if cands else "")
                          + f"; give format ({', '.join(EXPORT_FORMATS)})", params=("format",))
    return cands[0]


def export(reduced, path, format: str | None = None, *, model=None, **options) -> str:
    """Write ``reduced`` to ``path`` in an export format, atomically.

    Parameters
    ----------
    reduced : ReducedModel
    path : str or path-like
    format : str, optional
        ``sid``, ``exudyn``, ``mat``, ``statespace`` (aliases ``ss``, ``matlab``); default
        from the suffix (``.SID_FEM``, ``.mat``).
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
    FORMATS[name].writer(reduced, path, model=model, **options)
    return name
