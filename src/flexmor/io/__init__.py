"""Files in and out: three format registries, one small entry point each.

* :func:`read` — an FE model (:class:`~flexmor.model.FEModel`) from an FE program's export
  (:data:`MODEL_FORMATS`: CalculiX, Abaqus, Ansys, Nastran, Matrix Market, MATLAB, SID);
* :func:`read_body` — a reduced body (:class:`~flexmor.body.ReducedModel`)
  (:data:`BODY_FORMATS`: flexmor's own HDF5, Nastran superelements); :func:`write_body`
  writes flexmor's own HDF5 body file;
* :func:`export` — a reduced body to a file for another program (:data:`EXPORT_FORMATS`:
  SID, Exudyn, MATLAB, state space, FMU, HDF5).

The file's suffix chooses the format within the registry asked (``format=`` overrides), so
the same suffix may mean different things to different registries (``.mat``: a model to read,
a body to export); :func:`kind_of` tells a model file from a body file, by its content where
the suffix is both (a Nastran ``.op4`` superelement). Gzip-compressed files (``job.sti.gz``)
are read as they are, by the format of the name without ``.gz`` (:mod:`._open`).
The registries and these entry points live in :mod:`._registry`, below
the format modules. Each format family registers itself when it is imported
(``MODEL_FORMATS.register(name, suffixes, reader, description=...)``): a family of one module
is a module of this package (:mod:`.hdf5`, :mod:`.exudyn`, :mod:`.statespace`, :mod:`.fmu`, :mod:`.vtu`), a
family of several modules a subpackage whose ``__init__`` imports its reader and its exporter
(:mod:`.calculix`, :mod:`.abaqus`, :mod:`.ansys`, :mod:`.nastran`, :mod:`.matrix_market`,
:mod:`.matlab`, :mod:`.sid`). This package imports the families; :func:`describe_formats` lists
them all (``flexmor info --formats``). Readers raise :class:`flexmor.errors.ReadError` naming
the file (and line) for anything malformed. Every file flexmor writes goes through
:func:`atomic_write` (:mod:`.atomic`).
"""

# The format families register themselves on import; the listings follow this order.
from . import hdf5, calculix, abaqus, sid, exudyn, matlab, statespace, fmu, matrix_market, ansys, nastran, vtu  # noqa: F401, I001
from ._registry import (
    BODY_FORMATS,
    EXPORT_FORMATS,
    MODEL_FORMATS,
    Format,
    Registry,
    describe_formats,
    export,
    export_format,
    kind_of,
    read,
    read_body,
    unit_formats,
)
from ._unchecked import UncheckedWarning
from .atomic import atomic_write
from .hdf5 import write_body

__all__ = ["BODY_FORMATS", "EXPORT_FORMATS", "MODEL_FORMATS", "Format", "Registry", "UncheckedWarning", "atomic_write",
           "describe_formats", "export", "export_format", "kind_of", "read", "read_body", "unit_formats",
           "write_body"]
