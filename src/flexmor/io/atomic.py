"""Atomic file writes: :func:`atomic_write`, through which every file flexmor writes goes, and
:data:`commit_guard`, the hook an application puts around the final rename."""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path

__all__ = ["atomic_write", "commit_guard"]

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

