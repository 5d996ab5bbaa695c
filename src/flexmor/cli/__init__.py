"""The ``flexmor`` command line. The only package that prints or exits.

Exit codes: 0 success, 2 bad input (a one-line ``flexmor: error: ...`` on stderr naming the
file and line where there is one, and the flags concerned), 130 interrupted (Ctrl-C), 143
terminated (SIGTERM). Output files are written atomically (:func:`flexmor.io.atomic_write`),
so an interrupted run leaves neither a partial nor a temporary file; an existing output file
is only replaced with ``--force``.

Modules: :mod:`.parser` (arguments, generated per-method options), :mod:`.commands` (the
subcommands and their output).
"""

from __future__ import annotations

import logging
import signal
import sys
import warnings

from ..errors import ConvergenceError, FlexmorError, FlexmorWarning, ModelError, PortError, SolverError
from ..linalg.distributed import quiet_other_ranks
from .parser import build_parser

__all__ = ["main", "build_parser"]


class _Terminated(BaseException):
    """Raised by the SIGTERM handler so that the run unwinds (and removes temporary files)."""


def _on_sigterm(signum, frame):
    raise _Terminated


_python_format_warning = warnings.formatwarning


def _format_warning(message, category, filename, lineno, line=None):
    """A :class:`FlexmorWarning` as its one-line message (no source path); others as Python does."""
    if issubclass(category, FlexmorWarning):
        return str(message)
    return _python_format_warning(message, category, filename, lineno, line)


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    logging.captureWarnings(True)
    warnings.formatwarning = _format_warning
    quiet_other_ranks()  # mpirun -n P: only rank 0 prints
    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread: leave signal handling alone
        pass
    try:
        return args.func(args)
    except FlexmorError as exc:
        msg = exc.message(getattr(args, "flag_names", None))  # parameters named as this command's flags
        model = getattr(args, "model", None)
        if model and isinstance(exc, (ModelError, PortError, SolverError, ConvergenceError)) and str(model) not in msg:
            msg = f"{model}: {msg}"  # problems found after reading still name the file
        print(f"flexmor: error: {msg}", file=sys.stderr)
        return 2
    except MemoryError:
        print("flexmor: error: out of memory; try a faster backend (--backend pardiso) or a smaller model",
              file=sys.stderr)
        return 2
    except OSError as exc:  # writing an output: permission denied, disk full, ...
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"flexmor: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("flexmor: interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print("flexmor: terminated", file=sys.stderr)
        return 143
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
