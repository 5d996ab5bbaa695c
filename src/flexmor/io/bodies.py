"""Reduced bodies from files: flexmor's own ``.h5`` or a Nastran Craig-Bampton superelement.

``flexmor compare``, ``report`` and ``export`` accept either; a superelement's inputs and
outputs are its boundary DOFs (``GRID:DIR``), so ``flexmor compare FULL_MODEL SE.op4``
evaluates it against the full FE model at those DOFs.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["SUPERELEMENT_SUFFIXES", "read_body"]

#: Suffixes read as Nastran superelements (:func:`flexmor.io.nastran_se.read_superelement`).
SUPERELEMENT_SUFFIXES = (".op4", ".pch")


def read_body(path, **options):
    """Read a reduced body (:class:`~flexmor.projection.ReducedModel`) by the file's suffix."""
    if Path(path).suffix.lower() in SUPERELEMENT_SUFFIXES:
        from .nastran_se import read_superelement

        return read_superelement(path, **options)
    from .hdf5 import read_reduced

    return read_reduced(path)
