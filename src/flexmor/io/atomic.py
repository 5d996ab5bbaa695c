"""Atomic file writes: :func:`atomic_write`, through which every file flexmor writes goes, and
:data:`commit_guard`, the hook an application puts around the final rename."""

from __future__ import annotations

import contextlib
import errno
import io
import os
import secrets
from collections.abc import Callable
from pathlib import Path

from ..errors import ResourceError

__all__ = ["atomic_write", "commit_guard", "DiscardAfterFailure", "write_failure"]

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

    Raises
    ------
    ResourceError
        The file could not be written (a full disk, the file-size limit, a quota, no permission):
        :func:`write_failure`, naming ``path`` and the cause.
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
    except OSError as exc:
        raise write_failure(path, exc) from None
    finally:
        with contextlib.suppress(OSError):
            if tmp.exists():
                tmp.unlink()


#: The cause of a failed write, by errno, as messages say it.
_CAUSES = {errno.ENOSPC: "no space left on the disk",
           errno.EFBIG: "file too large: the process's file-size limit (ulimit -f) or the file system's",
           errno.EDQUOT: "disk quota exceeded", errno.EACCES: "permission denied",
           errno.EPERM: "operation not permitted", errno.EROFS: "read-only file system",
           errno.EIO: "input/output error"}


def write_failure(path, exc: OSError) -> ResourceError:
    """The :class:`~flexmor.errors.ResourceError` of a failed write of ``path``: its cause from
    ``exc``'s errno (no space, file-size limit, quota, permission), else its message."""
    cause = _CAUSES.get(exc.errno or 0) or exc.strerror or str(exc)
    return ResourceError(f"cannot write {path}: {cause}; nothing was written")


class DiscardAfterFailure(io.FileIO):
    """A binary file whose first failed write raises (and is kept in :attr:`failed`) and whose
    later writes are dropped: a library that writes again while it closes after the failure
    (HDF5 flushing its metadata) then closes cleanly; the file is discarded anyway."""

    failed: OSError | None = None

    def write(self, data):
        if self.failed is not None:
            return len(data)
        try:
            return super().write(data)
        except OSError as exc:
            self.failed = exc
            raise

