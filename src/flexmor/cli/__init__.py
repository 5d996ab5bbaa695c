"""The ``flexmor`` command line. The only package that prints or exits.

Exit codes: 0 success, 2 bad input (a one-line ``flexmor: error: ...`` on stderr naming the
file and line where there is one, and the flags concerned), 1 the machine ran short (memory,
disk space, a file-size limit, the permission to write: one line naming what and the options
left), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM). Output files are written atomically
(:func:`flexmor.io.atomic_write`), so an interrupted run leaves neither a partial nor a
temporary file; an existing output file is only replaced with ``--force``. Under mpirun only rank 0
prints and writes; a rank that fails prints its one line and ends the whole job unless every rank
failed alike (:func:`flexmor.linalg.distributed.end_failed_run`).

Modules: :mod:`.parser` (arguments, generated per-method options), :mod:`.method_flags` (the
method options as flags), :mod:`.commands` (the subcommands and their output), :mod:`.ui` (the
``ui`` subcommand), :mod:`.tables` (the error table), :mod:`.info` (info on a body,
the backends and the formats).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import signal
import sys
import threading
import traceback
import warnings

from .. import io
from ..errors import (
    NOTES,
    QUIET_NOTES_VARIABLE,
    ConvergenceError,
    FlexmorError,
    FlexmorWarning,
    ModelError,
    PortError,
    ResourceError,
    SolverError,
    notes_quieted,
    quiet_notes,
)
from ..linalg.distributed import end_failed_run, quiet_other_ranks, several_ranks
from .parser import build_parser

__all__ = ["main", "build_parser"]


class _Terminated(BaseException):
    """Raised by the SIGTERM handler so that the run unwinds (and removes temporary files)."""


class _Run:
    """The signal state of one run: SIGTERM seen, files committed (removed if terminated).

    The handler both sets :attr:`terminated` and raises :class:`_Terminated`. The exception
    can be lost: raised inside a destructor (e.g. a solver's ``__del__``) Python only reports it
    as unraisable and carries on. The flag is not lost: :meth:`guard`, wrapped around the
    final rename of every written file (:data:`flexmor.io.atomic.commit_guard`), refuses to commit
    once it is set, with SIGTERM blocked so that check, rename and record are not split; and
    :func:`main` ends a flagged run with 143, removing the files it committed.
    """

    def __init__(self):
        self.terminated = False
        self.written: list = []
        self.thread = threading.get_ident()

    def on_sigterm(self, signum, frame):
        self.terminated = True
        raise _Terminated

    @contextlib.contextmanager
    def guard(self, path):
        if threading.get_ident() != self.thread:  # other threads' files (e.g. jobs of `flexmor ui`) are theirs
            yield
            return
        blocked = _block_sigterm()
        try:
            if self.terminated:
                raise _Terminated
            yield
            self.written.append(path)
        finally:
            if blocked is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

    def unraisable(self, previous):
        """A ``sys.unraisablehook`` that keeps a lost ``_Terminated`` quiet (the flag is set)."""
        def hook(unraisable):
            if not isinstance(unraisable.exc_value, _Terminated):
                previous(unraisable)
        return hook

    def remove_written(self) -> None:
        for path in self.written:
            try:
                os.unlink(path)
            except OSError:
                pass


#: The run of the process's main thread (the one whose SIGTERM handler is installed), or None.
_current: _Run | None = None


def raise_if_terminated() -> None:
    """Raise the termination of this process's run when SIGTERM has been seen but its exception was lost
    (raised in a destructor): a loop that would otherwise never end (the ``ui`` server's) calls this
    between its rounds."""
    if _current is not None and _current.terminated and threading.get_ident() == _current.thread:
        raise _Terminated


def _block_sigterm():
    """Block SIGTERM (the previous mask, or None where masks are not available)."""
    try:
        return signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
    except (AttributeError, ValueError, OSError):
        return None


_python_format_warning = warnings.formatwarning


def _format_warning(message, category, filename, lineno, line=None, names=None):
    """A :class:`FlexmorWarning` as its one-line message (no source path), the parameters it names
    renamed by ``names`` (the command's flags); others as Python does."""
    if issubclass(category, FlexmorWarning):
        return message.message(names) if isinstance(message, FlexmorWarning) else str(message)
    return _python_format_warning(message, category, filename, lineno, line)


class _LogFormat(logging.Formatter):
    """A warning (a FlexmorWarning, a logged one) as ``flexmor: warning: MESSAGE``; other records
    (-v: info, -vv: debug) as ``LEVEL logger: message``."""

    def format(self, record):
        if record.name == "py.warnings" or record.levelno >= logging.WARNING:
            kind = "warning" if record.levelno <= logging.WARNING else record.levelname.lower()
            return f"flexmor: {kind}: {record.getMessage().strip()}"
        return super().format(record)


class _OncePerRun(logging.Filter):
    """Lets each warning text through once per run (:func:`main` renews it)."""

    def __init__(self):
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record):
        if record.name != "py.warnings" and record.levelno < logging.WARNING:
            return True
        text = record.getMessage().strip()
        if text in self.seen:
            return False
        self.seen.add(text)
        return True


class _Stderr(logging.StreamHandler):
    """Writes to the ``sys.stderr`` of the moment (a caller or test runner may replace it)."""

    @property  # type: ignore[override]
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass


def _configure_logging(level) -> None:
    """The root logger at ``level`` with one stderr handler: warnings short and once per run."""
    root = logging.getLogger()
    root.setLevel(level)
    handler = next((h for h in root.handlers if isinstance(h, _Stderr)), None)
    if handler is None:
        handler = _Stderr()
        root.addHandler(handler)
    handler.setFormatter(_LogFormat("%(levelname)s %(name)s: %(message)s"))
    for f in list(handler.filters):
        handler.removeFilter(f)
    handler.addFilter(_OncePerRun())


def main(argv=None) -> int:
    """Run the command line; returns the exit code.

    With ``argv`` None (the process's own command line) SIGTERM stays blocked once the outcome is
    decided: a signal that arrives while the interpreter shuts down no longer changes it.
    """
    parser = build_parser()
    # handed to the ui subcommand, whose jobs run this command line and whose serving ends on SIGTERM
    parser.set_defaults(main=main, check_terminated=raise_if_terminated)
    args = parser.parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    _configure_logging(level)
    # renewed on every call: a warnings.catch_warnings() around an earlier call (a caller's, or a test
    # runner's) restores the warnings module's own display and leaves logging believing it captures
    logging.captureWarnings(False)
    logging.captureWarnings(True)
    # each run shows its warnings (once: _OncePerRun), also a later run in the same process: setting a
    # filter renews the warnings module's record of what it has shown
    warnings.simplefilter("default", FlexmorWarning)
    warnings.formatwarning = functools.partial(_format_warning, names=getattr(args, "flag_names", None))
    quiet_other_ranks()  # mpirun -n P: only rank 0 prints
    global _current
    run, previous, hook, code, outer = _Run(), None, sys.unraisablehook, None, _current
    try:
        previous = signal.signal(signal.SIGTERM, run.on_sigterm)
        io.atomic.commit_guard, sys.unraisablehook, _current = run.guard, run.unraisable(hook), run
    except ValueError:  # not the main thread: leave signal handling alone
        pass
    blocked = None
    try:
        try:
            code = _dispatch(args)
            # the run is over: a later SIGTERM is taken here (pending), not by the default action
            blocked = _block_sigterm() if previous is not None else None
        except _Terminated:  # in the instant between the command's end and the block
            run.terminated = True
            blocked = _block_sigterm() if previous is not None else None
        if blocked is not None and signal.SIGTERM in signal.sigpending():
            signal.sigwait({signal.SIGTERM})
            run.terminated = True
        if run.terminated:  # also when the exception was lost (raised in a destructor): the flag decides
            run.remove_written()
            if code != 143:
                print("flexmor: terminated", file=sys.stderr)
            code = 143
        return code
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
            io.atomic.commit_guard, sys.unraisablehook, _current = None, hook, outer
        # the process's own command line: the run's outcome is decided above (143 and no file, or its
        # code and its files), so SIGTERM stays blocked while the interpreter ends; at the end of
        # finalization Python restores the default action, which would kill a finished run
        if blocked is not None and argv is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _dispatch(args) -> int:
    """Run the command of ``args``; errors become messages and exit codes. Under mpirun a rank that
    fails ends the whole job unless every rank failed (:func:`flexmor.linalg.distributed.end_failed_run`):
    no rank waits for it forever."""
    code = _run_command(args)
    return code if code == 0 else end_failed_run(code)


def _run_command(args) -> int:
    """Run the command of ``args``; errors become messages and exit codes."""
    from ..linalg.resources import start_room

    short = start_room()  # a process limit too tight for any job: one line now rather than a library's abort
    if short is not None:
        print(f"flexmor: error: {short}", file=sys.stderr)
        return 1
    unknown = sorted(quiet_notes() - set(NOTES))
    if unknown:
        print(f"flexmor: warning: {QUIET_NOTES_VARIABLE} names no note {', '.join(map(repr, unknown))}; the notes: "
              f"{', '.join(NOTES)}", file=sys.stderr)
    try:
        with notes_quieted(getattr(args, "quiet_note", None) or ()):
            return args.func(args)
    except FlexmorError as exc:
        msg = exc.message(getattr(args, "flag_names", None))  # parameters named as this command's flags
        model = getattr(args, "model", None)
        if model and isinstance(exc, (ModelError, PortError, SolverError, ConvergenceError)) and str(model) not in msg:
            msg = f"{model}: {msg}"  # problems found after reading still name the file
        print(f"flexmor: error: {msg}", file=sys.stderr)
        return 1 if isinstance(exc, ResourceError) else 2
    except MemoryError:
        from ..linalg.resources import describe_memory

        print(f"flexmor: error: out of memory ({describe_memory()}); try --factor-memory mixed or ooc, a smaller "
              "--order, or a machine with more memory", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of stdout closed it (| head): nothing wrong with the run
        try:  # no second error when Python flushes stdout at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # a stdout without a descriptor (a capture)
            pass
        return 141
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
    except Exception as exc:  # under mpirun: the one line, then the job ends (other ranks may wait for this one)
        if not several_ranks():
            raise
        print(f"flexmor: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        if getattr(args, "verbose", 0):
            traceback.print_exc()
        return 1


if __name__ == "__main__":
    sys.exit(main())
