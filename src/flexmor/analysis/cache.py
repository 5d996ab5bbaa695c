"""Disk cache of full-model frequency responses.

A full FRF is stored as one ``.npz`` file (no pickles) named by a BLAKE2 hash of everything
it depends on: the contents of ``K``, ``M``, ``D``, ``B`` and ``C``, the damping description,
the band and the grid parameters. The key is stored inside the file and checked on load
together with the array shapes, so a renamed, truncated or foreign file is never used.
Files are written atomically (:func:`flexmor.io.atomic_write`).

Where: ``$FLEXMOR_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/flexmor``, else
``~/.cache/flexmor`` (:func:`cache_dir`); only the files ``frf-<key>.npz`` there are the cache's.

Size: at most ``$FLEXMOR_CACHE_MAX_MB`` megabytes (default :data:`DEFAULT_MAX_MB`) of entries;
after each write the least recently used entries (oldest modification time; a hit renews it)
are removed until the rest fits (:func:`prune`). An entry larger than the bound is not kept.

Off: ``FLEXMOR_CACHE_MAX_MB=0`` (nothing read or written), ``cache=False`` of
:class:`~flexmor.analysis.compare.FullResponse` and :class:`~flexmor.study.System`, or
``--no-cache`` on the command line.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..errors import ResourceError
from ..linalg.distributed import comm, is_partitioned

__all__ = ["cache_dir", "max_bytes", "frf_key", "load", "store", "prune", "FORMAT_VERSION", "DEFAULT_MAX_MB",
           "MAX_MB_ENV"]

log = logging.getLogger(__name__)

#: Bumped whenever the meaning of a cached FRF changes (grid rules, solver conventions).
FORMAT_VERSION = 2


def cache_dir() -> Path:
    """The cache directory (not created here)."""
    env = os.environ.get("FLEXMOR_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "flexmor"


#: Bound of the cache in megabytes (10^6 bytes) when ``$FLEXMOR_CACHE_MAX_MB`` is not set.
DEFAULT_MAX_MB = 2000.0

#: The environment variable of the bound (megabytes; 0 turns the cache off).
MAX_MB_ENV = "FLEXMOR_CACHE_MAX_MB"


def max_bytes() -> int:
    """The bound of the cache in bytes: ``$FLEXMOR_CACHE_MAX_MB`` megabytes, else :data:`DEFAULT_MAX_MB`
    (a value that is not a number >= 0 is logged and the default used); 0 means no cache."""
    text = os.environ.get(MAX_MB_ENV, "").strip()
    mb = DEFAULT_MAX_MB
    if text:
        try:
            mb = float(text)
            if not mb >= 0 or mb == float("inf"):
                raise ValueError(text)
        except ValueError:
            log.warning("%s=%r is not a size in megabytes (a number >= 0); the FRF cache keeps its default "
                        "bound of %g MB", MAX_MB_ENV, text, DEFAULT_MAX_MB)
            mb = DEFAULT_MAX_MB
    return int(mb * 1e6)


def _update_matrix(h, name: str, A) -> None:
    h.update(name.encode())
    if A is None:
        h.update(b"none")
        return
    if is_partitioned(A):  # rows over MPI ranks: the ranks' digests in rank order (same key on all)
        part = hashlib.blake2b(digest_size=20)
        _update_matrix(part, name, A.local)
        c = comm()
        for d in ([part.digest()] if c is None else c.allgather(part.digest())):
            h.update(d)
        return
    A = sp.csr_matrix(A, copy=True)
    A.sum_duplicates()
    A.sort_indices()
    h.update(np.asarray(A.shape, np.int64).tobytes())
    for arr, dt in ((A.indptr, np.int64), (A.indices, np.int64), (A.data, np.float64)):
        h.update(np.ascontiguousarray(arr, dtype=dt).tobytes())


def frf_key(model, ports, params: dict) -> str:
    """Hex key of a full FRF: hash of the matrix contents, ports, damping and ``params``.

    Parameters
    ----------
    model : FEModel
    ports : Ports
    params : dict
        JSON-serializable description of band, grid and evaluation path.
    """
    h = hashlib.blake2b(digest_size=20)
    h.update(f"flexmor-frf-v{FORMAT_VERSION}".encode())
    for name, A in (("K", model.K), ("M", model.M), ("D", model.D), ("B", ports.B), ("C", ports.C)):
        _update_matrix(h, name, A)
    h.update(json.dumps(model.damping.to_dict(), sort_keys=True, default=str).encode())
    h.update(json.dumps(params, sort_keys=True, default=str).encode())
    return h.hexdigest()


def _path(key: str, directory=None) -> Path:
    return Path(directory or cache_dir()) / f"frf-{key}.npz"


def load(key: str, shape_out: tuple[int, int], directory=None) -> dict | None:
    """The cached entry for ``key`` or None (missing, unreadable or not matching).

    Parameters
    ----------
    key : str
        From :func:`frf_key`.
    shape_out : (int, int)
        Expected ``(n_outputs, n_inputs)`` of the stored FRF.
    directory : path, optional
        Cache directory; default :func:`cache_dir`.

    Returns
    -------
    dict or None
        ``freqs``, ``H``, ``resonances``, ``zeta`` arrays and ``info`` (dict).
    """
    path = _path(key, directory)
    if not path.is_file():
        return None
    with contextlib.suppress(OSError):  # a hit is a use: the entry is evicted after older ones
        os.utime(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            entry = {k: z[k] for k in ("key", "freqs", "H", "resonances", "zeta", "info")}
        ok = (str(entry["key"]) == key and entry["H"].ndim == 3
              and entry["H"].shape == (entry["freqs"].size, *shape_out)
              and np.all(np.isfinite(entry["freqs"])) and np.all(np.diff(entry["freqs"]) > 0))
        if not ok:
            log.warning("ignoring cache file %s: it does not match its key", path)
            return None
        entry["info"] = json.loads(str(entry["info"]))
        del entry["key"]
        return entry
    except Exception as exc:  # noqa: BLE001 - a damaged cache file is only a miss
        log.warning("ignoring unreadable cache file %s (%s)", path, exc)
        return None


def store(key: str, freqs, H, resonances, zeta, info: dict, directory=None, *, limit: int | None = None) -> Path | None:
    """Write one entry atomically, then :func:`prune` the cache to ``limit`` bytes (default
    :func:`max_bytes`); returns its path, or None when the directory is not writable, the cache is
    off (``limit`` 0) or the entry alone exceeds the bound."""
    from ..io import atomic_write
    from ..jsonutil import jsonable

    limit = max_bytes() if limit is None else int(limit)
    if limit <= 0:
        return None
    path = _path(key, directory)
    arrays = dict(key=np.array(key), freqs=np.asarray(freqs, float), H=np.asarray(H, complex),
                  resonances=np.asarray(resonances, float), zeta=np.asarray(zeta, float),
                  info=np.array(json.dumps(jsonable(info))))
    try:
        atomic_write(path, lambda tmp: _savez(tmp, arrays))
    except (OSError, ResourceError) as exc:  # the cache is optional: the run goes on without it
        log.warning("could not write the FRF cache %s (%s)", path, exc)
        return None
    log.info("cached full FRF in %s", path)
    prune(path.parent, limit)
    return path if path.exists() else None


def prune(directory, limit: int) -> list[Path]:
    """Remove the least recently used entries (``frf-*.npz``, oldest modification time first) of
    ``directory`` until the others hold at most ``limit`` bytes; returns the files removed.

    Other files in the directory are neither counted nor touched; an entry another process
    removed meanwhile is skipped.
    """
    entries = []
    for p in Path(directory).glob("frf-*.npz"):
        try:
            st = p.stat()
        except OSError:
            continue
        entries.append((st.st_mtime, p.name, st.st_size, p))
    entries.sort()
    total = sum(e[2] for e in entries)
    removed = []
    for _, _, size, p in entries:
        if total <= limit:
            break
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
            removed.append(p)
        total -= size
    if removed:
        log.info("FRF cache %s: %d oldest entries removed to stay within %.4g MB", directory, len(removed),
                 limit / 1e6)
    return removed


def _savez(tmp: str, arrays: dict) -> None:
    with open(tmp, "wb") as fh:  # a file object: np.savez would append '.npz' to a name
        np.savez(fh, **arrays)
