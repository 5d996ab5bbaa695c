"""flexmor's own reduced-body file (HDF5).

Layout: datasets ``M K B C`` (and ``D``, ``V``, ``node_ids``, ``xyz``, ``dofs`` when present),
``errors/freqs_hz`` and ``errors/rel_error`` when evaluated; attributes ``format``
(= ``flexmor-reduced``), ``version``, ``method``, ``model_name`` and JSON strings ``info``,
``damping``, ``errors``, ``input_names``, ``output_names``. Written atomically.
"""

from __future__ import annotations

import json

import numpy as np

from ..errors import ReadError
from ..jsonutil import jsonable
from . import atomic_write, register_format

FORMAT_TAG = "flexmor-reduced"
_ARRAYS = ("M", "K", "D", "B", "C", "V", "node_ids", "xyz", "dofs")
_JSON = ("info", "damping", "errors", "input_names", "output_names")


def write_reduced(red, path) -> None:
    """Write a :class:`~flexmor.projection.ReducedModel` to ``path`` (HDF5), atomically."""
    import h5py

    errors = {k: v for k, v in red.errors.items() if k not in ("rel_error", "freqs_hz")}

    def write(tmp):
        with h5py.File(tmp, "w") as h:
            h.attrs["format"] = FORMAT_TAG
            h.attrs["version"] = red.version
            h.attrs["method"] = red.method
            h.attrs["model_name"] = red.model_name
            for name in _ARRAYS:
                val = getattr(red, name)
                if val is not None:
                    h.create_dataset(name, data=np.asarray(val), compression="gzip" if np.size(val) > 4096 else None)
            for name in _JSON:
                h.attrs[name] = json.dumps(jsonable(errors if name == "errors" else getattr(red, name)))
            if "rel_error" in red.errors and "freqs_hz" in red.errors:
                g = h.create_group("errors")
                g.create_dataset("freqs_hz", data=np.asarray(red.errors["freqs_hz"]))
                g.create_dataset("rel_error", data=np.asarray(red.errors["rel_error"]))

    atomic_write(path, write)


def read_reduced(path):
    """Read a reduced body written by :func:`write_reduced`."""
    import h5py

    from ..projection import ReducedModel

    try:
        h = h5py.File(path, "r")
    except OSError as exc:
        raise ReadError(path, f"not an HDF5 file ({exc})") from None
    with h:
        if h.attrs.get("format") != FORMAT_TAG:
            raise ReadError(path, f"HDF5 file without format={FORMAT_TAG!r}: not a flexmor reduced body")
        try:
            arrays = {n: (h[n][()] if n in h else None) for n in _ARRAYS}
            meta = {n: json.loads(h.attrs[n]) for n in _JSON}
            if "errors" in h:
                meta["errors"]["freqs_hz"] = h["errors/freqs_hz"][()]
                meta["errors"]["rel_error"] = h["errors/rel_error"][()]
            red = ReducedModel(**arrays, **meta, method=str(h.attrs["method"]),
                               model_name=str(h.attrs["model_name"]), version=str(h.attrs["version"]))
        except (KeyError, ValueError, TypeError) as exc:
            raise ReadError(path, f"incomplete or corrupt reduced body ({exc})") from None
    r = red.order
    if red.K.shape != (r, r) or red.B.shape[0] != r or red.C.shape[1] != r:
        raise ReadError(path, "inconsistent matrix shapes in the reduced body")
    return red


register_format("flexmor", [".h5", ".hdf5"], reader=read_reduced, writer=write_reduced,
                description="flexmor reduced body (HDF5)")
