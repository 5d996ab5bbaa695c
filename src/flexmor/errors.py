"""Exception and warning classes of flexmor, the named notes, and the checks of argument values that
every layer uses (a choice, keywords, real finite numbers).

Every error that a user can cause (a bad file, a bad option, a model that a method cannot
handle) is raised as a subclass of :class:`FlexmorError`, with a one-line message that names
the file (and line) where there is one. The command line turns these into exit code 2.
"""

from __future__ import annotations

import contextlib
import os
import re
import warnings

__all__ = [
    "FlexmorError",
    "ReadError",
    "ModelError",
    "PortError",
    "SolverError",
    "ConvergenceError",
    "OptionError",
    "ResourceError",
    "OutOfMemoryError",
    "FlexmorWarning",
    "FlexmorNote",
    "NOTES",
    "QUIET_NOTES_VARIABLE",
    "note",
    "quiet_notes",
    "notes_quieted",
    "notes_stated",
    "did_you_mean",
    "check_keywords",
    "check_keywords_of",
    "keyword_names",
    "real_finite",
]


class _NamesParameters:
    """A message that names parameters (``params``), shown by the command line with its flags."""

    #: Kept by the class too: an error rebuilt from its message alone (unpickled, e.g. sent from
    #: MPI rank 0 to the others) names no parameter.
    params: tuple = ()

    def __init__(self, *args, params=()):
        super().__init__(*args)
        self.params = tuple(params)

    def message(self, names=None) -> str:
        """The message with each parameter in ``params`` renamed by ``names`` (e.g. ``{"inputs": "--input"}``)."""
        return name_parameters(str(self), self.params, names)


class FlexmorError(_NamesParameters, Exception):
    """Base class of all errors raised by flexmor for bad input or failed computations.

    Parameters
    ----------
    *args
        The message (as for :class:`Exception`).
    params : sequence of str, optional
        The parameters the message names (``inputs``, ``order``, ``band`` ...), each written
        in the message as the bare parameter name; the command line shows them as its flags
        (:meth:`message`).
    """



class ReadError(FlexmorError):
    """A file could not be read: missing, malformed, or not of the expected format.

    Parameters
    ----------
    path : str or path-like
        The file concerned.
    message : str
        What is wrong (and, where possible, what to do).
    line : int, optional
        1-based line number in the file, when the problem is on a line.
    params : sequence of str, optional
        Parameters the message names (see :class:`FlexmorError`).
    """

    def __init__(self, path, message: str, line: int | None = None, *, params=()):
        self.path = str(path)
        self.line = line
        self.reason = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}", params=params)


class ModelError(FlexmorError):
    """The finite-element model is inconsistent (shapes, symmetry, non-finite values, ...)."""


class PortError(FlexmorError):
    """An input, output or interface specification does not match the model."""


class SolverError(FlexmorError):
    """A linear solver failed (singular matrix, backend not available, out of memory)."""


class ResourceError(FlexmorError):
    """The machine ran short: memory, disk space, a file-size limit or the permission to write.

    The input was fine; the same job can run elsewhere or with other options (the message says
    which). The command line ends with exit code 1 (2 is for bad input).
    """


class OutOfMemoryError(ResourceError, SolverError):
    """A job or a factorization does not fit into the memory there is (the machine's, or the
    process's address-space or cgroup limit), or an allocation failed."""


class ConvergenceError(FlexmorError):
    """An iterative method did not converge within its iteration limit.

    Parameters
    ----------
    message : str
    result : object, optional
        The best result reached so far (e.g. ``(lam, phi)`` of the Ritz pairs of an eigen
        solver), for callers that can use an approximate answer; None when there is none.
    """

    def __init__(self, message: str, result=None, *, params=()):
        super().__init__(message, params=params)
        self.result = result


class OptionError(FlexmorError, ValueError):
    """An option has a value that is not allowed; the message lists the allowed ones."""


class FlexmorWarning(_NamesParameters, UserWarning):
    """Warnings about legal but noteworthy situations (rigid-body modes, singular mass, ...).

    Parameters
    ----------
    *args
        The message (as for :class:`Warning`).
    params : sequence of str, optional
        The parameters the message names, as for :class:`FlexmorError`; issue such a warning as
        ``warnings.warn(FlexmorWarning(text, params=("rigid",)))``.
    """



#: Notes: facts of a file that a user cannot act on, each by its name, stated in full (``flexmor info``
#: shows this text; elsewhere a :class:`FlexmorNote` says it in one short line, which
#: :data:`QUIET_NOTES_VARIABLE` or ``--quiet-note NAME`` silence).
NOTES = {
    "singular-mass": (
        "A singular mass matrix (or one with zero or negative diagonal entries) is a property of the element "
        "formulation, not an error of the file: CalculiX's consistent mass of the 10-node tetrahedron C3D10 has "
        "zero eigenvalues, serendipity elements with reduced integration or row-sum lumping (C3D20R, S8R) give "
        "zero or negative diagonals. Every method and the error evaluation still work (they factorize "
        "K - sigma M, sigma < 0, or K); what needs M^-1 does not (time integration of the full model from a "
        "non-zero initial force)."),
    "rigid-body-modes": (
        "A free (or partly supported) body has up to six rigid-body modes, zero-energy motion of the whole body. "
        "In a multibody code the floating frame carries that motion: the methods exclude these modes from the "
        "elastic basis (made mass-orthogonal to them) or use shifted expansion points, and the body is judged "
        "by its elastic part. A body meant to be held needs its supports in the FE model, or interfaces "
        "(interfaces=['SET@rbe2'], --interface SET@rbe2) to be judged held in its joints."),
}

#: The environment variable listing the names of :data:`NOTES` not to repeat (comma or space separated),
#: e.g. ``FLEXMOR_QUIET_NOTES=singular-mass,rigid-body-modes``.
QUIET_NOTES_VARIABLE = "FLEXMOR_QUIET_NOTES"

_quieted: list[set] = []  # the names of the notes_quieted() blocks entered (innermost last)


class FlexmorNote(FlexmorWarning):
    """A note: a :class:`FlexmorWarning` about a fact of the file a user cannot act on, named by ``name``
    (a key of :data:`NOTES`). Its message is one short line; :meth:`full` states it in full.

    Parameters
    ----------
    text : str
        The short line.
    name : str
        The note's name in :data:`NOTES`.
    found : str, optional
        What was found, where (the start of ``text``; default ``text``).
    params : sequence of str, optional
        As for :class:`FlexmorWarning`.
    """

    def __init__(self, text: str = "", *, name: str = "", found: str | None = None, params=()):
        super().__init__(text, params=params)
        self.name = name
        self.found = text if found is None else found

    def full(self) -> str:
        """What was found and the whole statement of :data:`NOTES` (as ``flexmor info`` shows it)."""
        return f"{self.found}. {NOTES.get(self.name, '')}".strip()


def quiet_notes() -> set[str]:
    """The names of the notes not to repeat: those of :data:`QUIET_NOTES_VARIABLE` and of the
    :func:`notes_quieted` blocks entered (none inside a :func:`notes_stated` block)."""
    if _stating:
        return set()
    names = set(os.environ.get(QUIET_NOTES_VARIABLE, "").replace(",", " ").split())
    return names.union(*_quieted)


_stating: list[bool] = []  # notes_stated() blocks entered


@contextlib.contextmanager
def notes_stated():
    """A block in which every note is issued, also a quieted one (``flexmor info`` states them in full)."""
    _stating.append(True)
    try:
        yield
    finally:
        _stating.pop()


@contextlib.contextmanager
def notes_quieted(names):
    """A block in which the notes ``names`` (keys of :data:`NOTES`) are not repeated.

    Raises
    ------
    OptionError
        Naming ``quiet_note``: a name that is no note, with the closest one.
    """
    names = set(names)
    for name in names:
        check_choice("quiet_note", name, NOTES)
    _quieted.append(names)
    try:
        yield
    finally:
        _quieted.remove(names)


def note(name: str, text: str, *, stacklevel: int = 2) -> None:
    """Issue the :class:`FlexmorNote` ``name`` (a key of :data:`NOTES`) in one short line: ``text`` (what
    was found, where) and how to silence it; nothing when ``name`` is in :func:`quiet_notes`."""
    if name not in NOTES:
        raise KeyError(name)
    if name in quiet_notes():
        return
    line = f"{text} (note {name}: see flexmor info; silenced by --quiet-note {name} or {QUIET_NOTES_VARIABLE})"
    warnings.warn(FlexmorNote(line, name=name, found=text), stacklevel=stacklevel + 1)


def name_parameters(text: str, params, names=None) -> str:
    """``text`` with each parameter of ``params`` that ``names`` maps renamed (``rayleigh`` -> ``--rayleigh``).

    Parameters
    ----------
    text : str
        A message or note that writes the parameters as their bare Python names.
    params : sequence of str
        The parameters ``text`` names.
    names : dict of str to str, optional
        The new name of each parameter (an application's flags); parameters it lacks stay.

    Returns
    -------
    str
        Only whole words are renamed: ``band`` in ``band_error``, ``method_band`` or
        ``x.band`` stays.
    """
    for p in params:
        if names and p in names:
            text = re.sub(rf"(?<![\w.-]){re.escape(p)}(?![\w-])", lambda _, f=names[p]: f, text)
    return text


def did_you_mean(text, choices, *, aliases=None) -> str:
    """``"did you mean 'X'? "`` with the choice closest to ``text`` (case ignored; ``aliases`` maps
    a short name to the name it stands for), or ``""`` when none is close."""
    import difflib

    names = {str(c).lower(): str(c) for c in choices}
    close = difflib.get_close_matches(str(text).strip().lower(), list(names), n=1, cutoff=0.6)
    if not close:
        return ""
    name = names[close[0]]
    return f"did you mean {(aliases or {}).get(name, name)!r}? "


def check_choice(name: str, value: str, allowed) -> str:
    """Return `value` if it is one of `allowed`, else raise :class:`OptionError` listing them
    (and the closest one)."""
    allowed = list(allowed)
    if value not in allowed:
        raise OptionError(f"{name}={value!r} is not allowed; {did_you_mean(value, allowed)}choose one of: "
                          f"{', '.join(map(str, allowed))}", params=(name,))
    return value


def real_finite(value, name: str, what: str = "real numbers"):
    """``value`` as a float ndarray of real, finite numbers: the check where a real value belongs.

    A complex value with a non-zero imaginary part, NaN, Inf or something that is not a number
    is refused (NumPy would drop the imaginary part with only a ComplexWarning, or fail deep
    inside a solver); a complex array whose imaginary parts are all zero is taken as real.

    Parameters
    ----------
    value : array_like
    name : str
        The parameter the error names (``freqs``, ``u``, ``alpha`` ...).
    what : str
        What ``value`` must be, in words (``"frequencies in Hz"``).

    Raises
    ------
    OptionError
        Naming ``name``, what it must be and where it is not.
    """
    import numpy as np

    try:
        a = np.asarray(value)
        real = a.real if a.dtype.kind == "c" else a
        out = np.asarray(real, dtype=float)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be {what}, got {value!r}"[:300], params=(name,)) from None
    if a.dtype.kind == "c" and np.any(a.imag != 0):
        bad = np.flatnonzero(np.ravel(a.imag) != 0)
        raise OptionError(f"{name} must be {what}, got the complex value {np.ravel(a)[bad[0]]}"
                          + (f" (imaginary part not zero at {bad.size} of {a.size} entries)" if a.size > 1 else ""),
                          params=(name,))
    bad = np.flatnonzero(~np.isfinite(np.ravel(out)))
    if bad.size:
        raise OptionError(f"{name} must be {what}, got {np.ravel(out)[bad[0]]}"
                          + (f" at {bad.size} of {out.size} entries (the first at index {int(bad[0])})"
                             if out.size > 1 else ""), params=(name,))
    return out


def check_keywords(where: str, given, allowed, *, what: str = "") -> None:
    """Refuse the keywords of ``given`` that are not in ``allowed``: an :class:`OptionError` naming each
    unknown keyword with the closest allowed name ("did you mean"), and listing the allowed ones.

    ``where`` names what takes them (``"System"``, ``"method 'krylov'"``), ``what`` the kind of
    keyword (``"option(s) "``).
    """
    allowed = list(dict.fromkeys(allowed))
    unknown = [k for k in given if k not in allowed]
    if unknown:
        named = ", ".join(f"{k} ({hint.strip()})" if (hint := did_you_mean(k, allowed)) else k for k in unknown)
        raise OptionError(f"{where} does not take {what}{named}; it takes: {', '.join(allowed)}",
                          params=tuple(unknown) + tuple(allowed))


def keyword_names(*functions, drop=()) -> list[str]:
    """The keyword-only parameters of ``functions`` (in order, each once), without those of ``drop``."""
    import inspect

    names = [p.name for fn in functions for p in inspect.signature(fn).parameters.values()
             if p.kind is p.KEYWORD_ONLY and p.name not in drop]
    return list(dict.fromkeys(names))


def check_keywords_of(where: str, given, *functions, drop=(), also=()) -> None:
    """:func:`check_keywords` of ``given``, the keywords passed on to ``functions`` (the last is called with
    them): allowed are their keyword-only parameters (:func:`keyword_names`, without ``drop``) and
    ``also``. Nothing is checked when the last function takes any keyword (``**options``)."""
    import inspect

    if any(p.kind is p.VAR_KEYWORD for p in inspect.signature(functions[-1]).parameters.values()):
        return
    check_keywords(where, given, [*also, *keyword_names(*functions, drop=drop)])
