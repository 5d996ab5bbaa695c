"""Exception and warning classes of flexmor.

Every error that a user can cause (a bad file, a bad option, a model that a method cannot
handle) is raised as a subclass of :class:`FlexmorError`, with a one-line message that names
the file (and line) where there is one. The command line turns these into exit code 2.
"""

from __future__ import annotations

import re

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
    "did_you_mean",
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
