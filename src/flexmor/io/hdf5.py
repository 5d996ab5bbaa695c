"""flexmor's own reduced-body file (HDF5): :func:`write_body`, read by :func:`flexmor.io.read_body`.

Layout: datasets ``M K B C`` (and ``D``, ``V``, ``node_ids``, ``xyz``, ``dofs``, ``stress_nodes``,
``stress_modes`` when present; ``V`` and ``stress_modes`` per basis vector, i.e. per coordinate ``q`` of the
body, not per eigenmode as the ``.vtu``'s ``mode_k`` / ``stress_k``: :mod:`flexmor.io.vtu`),
``errors/freqs_hz`` and ``errors/rel_error`` when evaluated; attributes ``format``
(= ``flexmor-reduced``), ``version``, ``method``, ``model_name`` and JSON strings ``info``,
``damping``, ``errors``, ``input_names``, ``output_names``, ``origin`` (the fingerprint of
the full model, :mod:`flexmor.origin`; absent in bodies written before it existed),
``selections``, ``couplings`` and ``order_note`` (older bodies hold these three as keys of
``info``; they are read from there) and ``units`` (the unit system of the model's file, null:
as given; absent in older bodies). Written atomically.
"""

from __future__ import annotations

import copy
import json
import warnings
from pathlib import Path

import numpy as np

from ..errors import FlexmorWarning, ReadError
from ..jsonutil import jsonable
from ._registry import BODY_FORMATS, EXPORT_FORMATS
from .atomic import DiscardAfterFailure, atomic_write

FORMAT_TAG = "flexmor-reduced"
_ARRAYS = ("M", "K", "D", "B", "C", "V", "node_ids", "xyz", "dofs", "triangles", "stress_nodes", "stress_modes")
_JSON = ("info", "damping", "errors", "input_names", "output_names", "origin", "selections", "couplings",
         "order_note", "units")
#: JSON attributes that older bodies lack: name -> value then
_OPTIONAL = {"origin": {}, "selections": [], "couplings": [], "order_note": None, "units": None}
#: fields of the body that older bodies kept as keys of ``info``
_FROM_INFO = ("selections", "couplings", "order_note")


def write_body(body, path) -> None:
    """Write a reduced body to ``path`` as flexmor's own HDF5 file, atomically.

    Parameters
    ----------
    body : ReducedModel
        The reduced body; :func:`flexmor.io.read_body` reads the file back.
    path : str or path-like
        The file to write (``.h5``).
    """
    import h5py

    errors = {k: v for k, v in body.errors.items() if k not in ("rel_error", "freqs_hz")}

    def write(tmp):
        # HDF5 writes through this file object, which never raises into it (a failed write, e.g. a full
        # disk or the file-size limit, is kept and raised here once HDF5 has closed the file)
        with DiscardAfterFailure(tmp, "w+") as fh:
            try:
                _fill(fh)
            finally:
                fh.check()

    def _fill(fh):
        with h5py.File(fh, "w") as h:
            h.attrs["format"] = FORMAT_TAG
            h.attrs["version"] = body.version
            h.attrs["method"] = body.method
            h.attrs["model_name"] = body.model_name
            for name in _ARRAYS:
                val = getattr(body, name)
                if val is not None:  # floats (bases, modes) hardly compress: written as they are, ~8x faster
                    val = np.asarray(val)
                    packs = val.size > 4096 and val.dtype.kind in "iub"
                    h.create_dataset(name, data=val, compression="gzip" if packs else None)
                    fh.check()  # a write failed: stop here (closing the file is clean, its writes dropped)
            for name in _JSON:
                h.attrs[name] = json.dumps(jsonable(errors if name == "errors" else getattr(body, name)))
            if "rel_error" in body.errors and "freqs_hz" in body.errors:
                g = h.create_group("errors")
                g.create_dataset("freqs_hz", data=np.asarray(body.errors["freqs_hz"]))
                g.create_dataset("rel_error", data=np.asarray(body.errors["rel_error"]))

    atomic_write(path, write)


#: name -> (dimensions, allowed dtype kinds, axis names tying sizes together); "r" is the order
_LAYOUT = {"M": ("rr", "f"), "K": ("rr", "f"), "D": ("rr", "f"), "B": ("rm", "f"), "C": ("pr", "f"),
           "V": ("nr", "f"), "node_ids": ("k", "iu"), "xyz": ("k3", "f"), "dofs": ("n2", "iu"),
           "stress_nodes": ("s", "iu"), "stress_modes": ("rs6", "f")}
#: Largest number of values one dataset may hold (2**31, i.e. 16 GiB of float64).
MAX_VALUES = 2**31


def _check_layout(path, h) -> None:
    """Refuse datasets of the wrong kind, type or shape before anything is read."""
    import h5py

    sizes = {"3": 3, "2": 2, "6": 6}
    for name, (axes, kinds) in _LAYOUT.items():
        if name not in h:
            if name in "MKBC":
                raise ReadError(path, f"reduced body without dataset {name!r}")
            continue
        d = h[name]
        if not isinstance(d, h5py.Dataset) or d.dtype.kind not in kinds or d.dtype.names:
            what = "a group" if not isinstance(d, h5py.Dataset) else f"of type {d.dtype}"
            expected = "real numbers" if kinds == "f" else "integers"
            raise ReadError(path, f"dataset {name!r} is {what}; expected {expected}")
        if len(d.shape) != len(axes):
            raise ReadError(path, f"dataset {name!r} has shape {d.shape}; expected {len(axes)} dimensions")
        if int(np.prod(d.shape, dtype=object)) > MAX_VALUES:
            raise ReadError(path, f"dataset {name!r} has shape {d.shape}: implausibly large")
        for ax, size in zip(axes, d.shape):
            if sizes.setdefault(ax, size) != size:
                raise ReadError(path, f"dataset {name!r} has shape {d.shape}, inconsistent with the other "
                                      "matrices of the reduced body")
    for name in ("freqs_hz", "rel_error"):
        if "errors" in h and name in h["errors"]:
            d = h["errors"][name]
            if not isinstance(d, h5py.Dataset) or d.dtype.kind != "f" or len(d.shape) != 1 or d.shape[0] > MAX_VALUES:
                raise ReadError(path, f"dataset 'errors/{name}' is not a 1-D array of real numbers")
    for name in _JSON + ("method", "model_name", "version"):
        if not isinstance(h.attrs.get(name, ""), str):
            raise ReadError(path, f"attribute {name!r} is not a string")


def _check_fields(path, meta) -> None:
    """Refuse ``selections``/``couplings`` that are not lists of strings, ``order_note``/``units`` not strings."""
    for n in ("selections", "couplings"):
        if not (isinstance(meta[n], list) and all(isinstance(s, str) for s in meta[n])):
            raise ReadError(path, f"attribute {n!r} must be a JSON list of strings")
    for n in ("order_note", "units"):
        if not (meta[n] is None or isinstance(meta[n], str)):
            raise ReadError(path, f"attribute {n!r} must be a JSON string or null")


def _read(path):
    """Read a reduced body written by :func:`write_body` (the ``hdf5`` reader of :func:`flexmor.io.read_body`).

    The datasets' kinds, types and shapes (consistent with the order ``r``) are checked before
    any data is read; attributes are JSON text (never pickles).
    """
    import h5py

    from ..body import ReducedModel

    try:
        h = h5py.File(path, "r")
    except OSError as exc:
        raise ReadError(path, f"not an HDF5 file ({exc})") from None
    with h:
        if h.attrs.get("format") != FORMAT_TAG:
            raise ReadError(path, f"HDF5 file without format={FORMAT_TAG!r}: not a flexmor reduced body")
        _check_layout(path, h)
        try:
            arrays = {n: (h[n][()] if n in h else None) for n in _ARRAYS}
            meta = {n: json.loads(h.attrs[n]) if n in h.attrs or n not in _OPTIONAL else copy.copy(_OPTIONAL[n])
                    for n in _JSON}
            if "errors" in h:
                meta["errors"]["freqs_hz"] = h["errors/freqs_hz"][()]
                meta["errors"]["rel_error"] = h["errors/rel_error"][()]
            if not all(isinstance(meta[n], dict) for n in ("info", "damping", "errors", "origin")):
                raise ReadError(path, "attributes info, damping, errors and origin must be JSON objects")
            for n in _FROM_INFO:  # a body written when these were keys of info
                if n not in h.attrs and n in meta["info"]:
                    meta[n] = meta["info"].pop(n)
            _check_fields(path, meta)
            red = ReducedModel(**arrays, **meta, method=str(h.attrs["method"]),
                               model_name=str(h.attrs["model_name"]), version=str(h.attrs["version"]))
        except (KeyError, ValueError, TypeError, OSError) as exc:  # an unknown damping type is an OptionError
            raise ReadError(path, f"incomplete or corrupt reduced body ({exc})") from None
    if not all(np.all(np.isfinite(a)) for a in (red.M, red.K, red.B, red.C) + ((red.D,) if red.D is not None else ())):
        raise ReadError(path, "the reduced matrices contain NaN or Inf")
    if not red.origin and red.info.get("format") != "nastran superelement":  # one reduced by Nastran has none
        warnings.warn(f"body {Path(path).name} records no fingerprint of the model it was reduced from (written by "
                      "an older flexmor or another program): it cannot be checked against the model it is judged "
                      "or exported with", FlexmorWarning, stacklevel=3)
    return red


def _export(body, path, *, model=None) -> None:
    """:func:`write_body` as an exporter (``model`` is unused)."""
    write_body(body, path)


BODY_FORMATS.register("hdf5", [".h5", ".hdf5"], _read, aliases=["flexmor"],
                      gzip="h5py reads an HDF5 file by random access, so it must be uncompressed (HDF5 "
                           "compresses inside the file)",
                      description="flexmor reduced body (HDF5): M K D B C, basis V, nodes, ports, errors")
EXPORT_FORMATS.register("hdf5", [".h5", ".hdf5"], _export, aliases=["flexmor"],
                        description="flexmor reduced body (HDF5), e.g. of a Nastran superelement")
