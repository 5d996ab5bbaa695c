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
    """A binary file for a library that writes through a Python file object and cannot survive
    an exception raised by it (h5py's ``fileobj`` driver: HDF5 then leaves a dataset half
    closed, and closes it at interpreter exit through the freed file, a segmentation fault).

    No method raises: the first failure of :meth:`write` or :meth:`truncate` (an
    :class:`OSError` such as a full disk or the file-size limit, or an exception raised by a
    signal handler while the call waited) is kept in :attr:`failed`, that write and every later
    one are dropped, and the library carries on and closes its file cleanly. A write the system
    takes only in part is continued (h5py ignores the count): the one that reaches the file-size
    limit or fills the disk, whose end then fails and is kept too, and any of more than 2 GiB,
    which Linux takes in parts. The caller raises :attr:`failed` (:meth:`check`) once the
    library has closed its file, and may check earlier to stop early; the file is discarded then.
    """

    failed: BaseException | None = None

    def write(self, data):
        view = memoryview(data)
        try:
            rest = view.cast("B")
            while self.failed is None and rest:
                n = super().write(rest)
                if not n:
                    raise OSError(errno.EIO, "the system wrote nothing")
                rest = rest[n:]
        except BaseException as exc:  # noqa: BLE001 - kept for check(): nothing may reach the library
            self.failed = exc
        return view.nbytes

    def truncate(self, size=None):
        if self.failed is None:
            try:
                return super().truncate(size)
            except BaseException as exc:  # noqa: BLE001 - as in write
                self.failed = exc
        return self.tell() if size is None else size

    def check(self) -> None:
        """Raise the failure kept, if any."""
        if self.failed is not None:
            raise self.failed
