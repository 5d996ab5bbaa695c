"""Reader of second-order models stored in MATLAB ``.mat`` files (v4, v5/v6, v7).

Variables, as in the SLICOT / Oberwolfach benchmark collection (``LF10.mat``):

* ``M``, ``K`` (required): mass and stiffness, n x n, dense or sparse;
* ``D`` (optional): damping, n x n (``E`` is not read: in first-order files it is the
  descriptor matrix);
* ``B`` (optional): input matrix, n x m; ``C`` (optional): output matrix, p x n.

Lower-case names (``m``, ``k``, ``d``, ``b``, ``c``) are accepted when the upper-case one is
absent. First-order files (``A``, ``B``, ``C`` with ``A = [0 I; -M^-1 K -M^-1 D]`` in some
form) cannot be turned back into a mechanical model and are refused with a clear message.
MATLAB v7.3 files are HDF5 containers; re-save them with ``save(file, '-v7')``.
Reading uses :func:`scipy.io.loadmat`, which never unpickles, after a structural check of the
file in pure Python (:mod:`flexmor.io.matlab._mat5`): scipy's compiled reader trusts byte counts and
dimensions, and a damaged file could crash the process.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

from ...errors import ReadError
from ...model import FEModel
from .._build import build_model
from .._open import is_gzip, read_all, stem
from .._registry import MODEL_FORMATS
from .._unchecked import warn_unchecked
from ._mat5 import checked_v5_stream

__all__ = ["read_matlab"]

_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"


def _get(path: Path, data: dict, name: str):
    """Variable ``name`` (or its lower-case form) as a 2-D float matrix, or None."""
    for key in (name, name.lower()):
        if key in data:
            val = data[key]
            break
    else:
        return None
    if sp.issparse(val):
        A = val
    else:
        if not isinstance(val, np.ndarray) or val.dtype.kind not in "biuf" or val.dtype.names:
            kind = "complex" if isinstance(val, np.ndarray) and val.dtype.kind == "c" else "not a numeric matrix"
            raise ReadError(path, f"variable {key!r} is {kind}; flexmor needs real numeric matrices")
        if val.ndim != 2:
            raise ReadError(path, f"variable {key!r} has {val.ndim} dimensions, expected a 2-D matrix")
        A = val
    if np.iscomplexobj(A.data if sp.issparse(A) else A):
        raise ReadError(path, f"variable {key!r} is complex; flexmor needs real matrices")
    A = sp.csr_matrix(A, dtype=np.float64)
    if not np.all(np.isfinite(A.data)):
        raise ReadError(path, f"variable {key!r} contains NaN or Inf")
    return A


def read_matlab(path) -> FEModel:
    """Read ``M``, ``K`` and optional ``D``, ``B``, ``C`` from a MATLAB ``.mat`` file.

    Parameters
    ----------
    path : str or path-like
        A MATLAB v4/v5/v7 MAT-file, or one gzip-compressed (``.mat.gz``: decompressed in
        memory, as a MAT-file is read whole anyway).

    Returns
    -------
    FEModel
        No node table; ``B`` and ``C`` as delivered. ``name`` is the file stem.

    Raises
    ------
    ReadError
        Not a MAT-file, a v7.3 (HDF5) file, missing ``M`` or ``K``, a first-order model
        (``A``, ``B``, ``C``), non-numeric, complex or non-finite variables, inconsistent sizes.
    """
    path = Path(path)
    raw = read_all(path)
    head = raw[:1024]
    if not head:
        raise ReadError(path, "file is empty")
    if b"MATLAB 7.3" in head[:128] or head[512:520] == _HDF5_MAGIC or head[:8] == _HDF5_MAGIC:
        raise ReadError(path, "MATLAB v7.3 (HDF5) files are not supported; re-save in MATLAB with "
                              "save(file, 'M', 'K', ..., '-v7')")
    if b"\x00" not in head and not head.startswith(b"MATLAB"):
        raise ReadError(path, "is a text file, not a binary MATLAB MAT-file; in MATLAB, load the model "
                              "and save(file, 'M', 'K', '-v7')")
    stream = checked_v5_stream(path, raw)  # scipy's compiled reader trusts the file: check it first
    try:
        data = scipy.io.loadmat(stream or (io.BytesIO(raw) if is_gzip(path) else str(path)), squeeze_me=False,
                                struct_as_record=True)
    except Exception as exc:  # noqa: BLE001 - scipy raises many types for bad files
        raise ReadError(path, f"not a readable MATLAB .mat file ({type(exc).__name__}: {exc}); "
                              "save it with save(file, '-v7')") from None
    data = {k: v for k, v in data.items() if not k.startswith("__")}
    M, K = _get(path, data, "M"), _get(path, data, "K")
    if M is None or K is None:
        if any(k in data for k in ("A", "a")):
            raise ReadError(path, "first-order model (A, B, C); flexmor needs second-order M, K (and D)")
        missing = " and ".join(nm for nm, A in (("M", M), ("K", K)) if A is None)
        have = ", ".join(sorted(data)) or "none"
        raise ReadError(path, f"variable {missing} not found (variables in file: {have}); "
                              "flexmor needs mass M and stiffness K")
    D = _get(path, data, "D")
    B = _get(path, data, "B")
    C = _get(path, data, "C")
    n = M.shape[0]
    if B is not None and B.shape[0] != n and B.shape[1] == n:
        raise ReadError(path, f"B is {B.shape[0]} x {B.shape[1]}; expected n x m with n = {n} (transposed?)")
    if C is not None and C.shape[1] != n and C.shape[0] == n:
        raise ReadError(path, f"C is {C.shape[0]} x {C.shape[1]}; expected p x n with n = {n} (transposed?)")
    model = build_model(
        path,
        M=M, K=K, D=D, B=B, C=C,
        damping={"type": "given"} if D is not None else {"type": "none"},
        name=stem(path), source=str(path),
    )
    warn_unchecked(path, "a MAT-file holds no count of its variables and no node coordinates, so a file cut after "
                         "a whole variable (D, B or C lost) could not be told from one written without it, and a "
                         "value has no copy to be cross-checked with (compressed variables carry a checksum)")
    return model


MODEL_FORMATS.register("matlab", [".mat"], read_matlab, gzip=True,
                       description="MATLAB .mat with M, K (D, B, C), e.g. SLICOT benchmarks")
