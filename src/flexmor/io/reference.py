"""Eigenfrequencies an FE program computed itself, to check a model against (``flexmor info MODEL --reference FILE``).

Four kinds of file are read, each plain or gzip-compressed:

``.frd`` (CalculiX result file)
    frequencies and ``DISP`` mode shapes (:mod:`flexmor.io.calculix.frd`): compared by
    frequency and MAC (:func:`flexmor.io.calculix.frd.compare_modes`);
CalculiX ``.dat``
    the ``E I G E N V A L U E   O U T P U T`` block of a ``*FREQUENCY`` step (the
    ``CYCLES/TIME`` column, of the first such block);
Nastran ``.f06``
    the ``R E A L   E I G E N V A L U E S`` table (the ``CYCLES`` column, of the first
    table; its continuation on later pages included);
a frequency list
    one frequency in Hz per line; blank lines and ``#`` comments are skipped.

A ``.dat``, ``.f06`` or list holds no mode shapes: it is compared by frequency only
(:func:`compare_frequencies`). A file is told by its content (the block titles), a list by
every data line holding one number; anything else is refused, naming the accepted kinds.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelError, ReadError
from ..linalg.context import SolverContext
from ._open import suffix
from ._text import read_text

__all__ = ["compare_reference_with", "KINDS", "Reference", "compare_frequencies", "compare_reference", "read_reference"]

#: The kinds of reference file, as the messages name them.
KINDS = {"frd": "CalculiX .frd (frequencies and mode shapes)",
         "calculix-dat": "CalculiX .dat (E I G E N V A L U E   O U T P U T)",
         "nastran-f06": "Nastran .f06 (R E A L   E I G E N V A L U E S)",
         "list": "a list of frequencies in Hz, one per line (# comments)"}
_ACCEPTED = "; ".join(KINDS.values())

_DAT_TITLE = "E I G E N V A L U E   O U T P U T"
_F06_TITLE = "R E A L   E I G E N V A L U E S"
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+)?"
_DAT_ROW = re.compile(rf"^\s*(\d+)\s+({_NUM})\s+({_NUM})\s+({_NUM})(?:\s+({_NUM}))?\s*$")
_F06_ROW = re.compile(rf"^\s*(\d+)\s+(\d+)\s+({_NUM})\s+({_NUM})\s+({_NUM})(?:\s+{_NUM}){{0,2}}\s*$")


@dataclass
class Reference:
    """The eigenfrequencies of a reference file.

    Attributes
    ----------
    path : Path
    kind : str
        A key of :data:`KINDS`.
    frequencies_hz : ndarray
        In the file's order.
    frd : FrdResult or None
        The result file (with the mode shapes) for kind ``frd``.
    """

    path: Path
    kind: str
    frequencies_hz: np.ndarray
    frd: object = None

    @property
    def has_shapes(self) -> bool:
        """Whether the file holds mode shapes (a MAC can be computed)."""
        return self.frd is not None

    def describe(self) -> str:
        """The kind of file in words (``CalculiX .dat (...)``)."""
        return KINDS[self.kind]


def _number(tok: str) -> float:
    return float(tok.replace("D", "E").replace("d", "e"))


def _dat_frequencies(path: Path, lines: list) -> np.ndarray:
    start = next(i for i, ln in enumerate(lines) if _DAT_TITLE in ln)
    out, seen = [], False
    for ln in lines[start + 1:]:
        m = _DAT_ROW.match(ln)
        if m:
            out.append(_number(m.group(4)))
            seen = True
        elif seen and ln.strip():
            break  # the end of the block (P A R T I C I P A T I O N   F A C T O R S ...)
    if not out:
        raise ReadError(path, f"no eigenvalue rows after {_DAT_TITLE!r}; is the CalculiX run complete?")
    return np.array(out)


def _f06_frequencies(path: Path, lines: list) -> np.ndarray:
    out, last, inside = [], 0, False
    for ln in lines:
        if _F06_TITLE in ln:
            inside = True
            continue
        if not inside:
            continue
        m = _F06_ROW.match(ln)
        if m:
            mode = int(m.group(1))
            if mode <= last:
                break  # the table of the next subcase
            out.append(_number(m.group(5)))
            last = mode
        elif out and ln.strip() and not _f06_page_line(ln):
            inside = False  # the table ends; its continuation on the next page starts with the title again
    if not out:
        raise ReadError(path, f"no eigenvalue rows in the {_F06_TITLE!r} table; is the Nastran run complete?")
    return np.array(out)


def _f06_page_line(ln: str) -> bool:
    """A column-title or page-break line inside an f06 table."""
    u = ln.upper()
    return any(w in u for w in ("MODE", "NO.", "ORDER", "PAGE", "SUBCASE", "EIGENVALUE")) or ln.startswith("1")


def _list_frequencies(path: Path, lines: list) -> np.ndarray | None:
    """The numbers of a frequency list, or None when a line is not one number."""
    out = []
    for ln in lines:
        s = ln.split("#", 1)[0].strip()
        if not s:
            continue
        try:
            out.append(_number(s))
        except ValueError:
            return None
    return np.array(out)


def read_reference(path) -> Reference:
    """Read the eigenfrequencies (and, from an ``.frd``, the mode shapes) of a reference file.

    Parameters
    ----------
    path : str or path-like
        A CalculiX ``.frd`` or ``.dat``, a Nastran ``.f06``, or a frequency list (each may be ``.gz``).

    Returns
    -------
    Reference

    Raises
    ------
    ReadError
        Missing or empty file, a file of none of the kinds (the message lists them), a
        ``.dat``/``.f06`` without its eigenvalue block, negative or non-finite frequencies.
    """
    from .calculix.frd import modes, read_frd

    path = Path(path)
    if suffix(path) == ".frd":
        res = read_frd(path)
        try:
            f = modes(res)[0]
        except ModelError as exc:
            raise ReadError(path, str(exc)) from None
        return Reference(path, "frd", np.asarray(f, float), res)
    lines = read_text(path).splitlines()
    text_has = {t: any(t in ln for ln in lines) for t in (_DAT_TITLE, _F06_TITLE)}
    if text_has[_DAT_TITLE]:
        kind, f = "calculix-dat", _dat_frequencies(path, lines)
    elif text_has[_F06_TITLE]:
        kind, f = "nastran-f06", _f06_frequencies(path, lines)
    else:
        f = _list_frequencies(path, lines)
        kind = "list"
        if f is None or f.size == 0:
            why = {".dat": f"no {_DAT_TITLE!r} block (a *FREQUENCY step writes it)",
                   ".f06": f"no {_F06_TITLE!r} table (an eigenvalue solution, SOL 103, writes it)"}.get(suffix(path))
            raise ReadError(path, (why or "not a reference file flexmor reads") + f"; give one of: {_ACCEPTED}")
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ReadError(path, "frequencies must be finite and not negative")
    return Reference(path, kind, f)


def compare_frequencies(model, f_ref, *, solver: SolverContext | None = None) -> dict:
    """Compare the eigenfrequencies of ``model`` with ``f_ref`` (Hz), without mode shapes.

    The pairing is that of :func:`flexmor.io._pairing.paired_modes`: one-to-one and in order, rigid-body modes with
    rigid-body modes; a :class:`~flexmor.errors.FlexmorWarning` is issued (and kept in ``notes``)
    when the numbers of rigid-body modes differ, when the largest relative difference of the
    elastic pairs exceeds :data:`flexmor.io._pairing.MISMATCH`, and when a reference mode is left without a model mode.

    Returns
    -------
    dict
        ``frequencies_hz`` (the reference's), ``model_frequencies_hz`` (the paired model mode's,
        None for a reference mode left unpaired), ``rel_diff`` (None for rigid-body modes and
        unpaired ones), ``mac`` (None: no shapes), ``model_modes`` (the 1-based model mode
        paired with each reference mode, or None) and ``notes`` (the warnings, as text).
    """
    from ._pairing import paired_modes, pairing_record

    f_ref = np.asarray(f_ref, float)
    p = paired_modes(model, f_ref, solver=solver)
    return dict(pairing_record(f_ref, p), mac=None)


def compare_reference(model, ref: Reference, *, solver: SolverContext | None = None) -> dict:
    """Compare ``model`` with a :class:`Reference`: by frequency and MAC (an ``.frd``), else by frequency.

    Returns
    -------
    dict
        As :func:`compare_frequencies` (``mac`` a list for an ``.frd``), with ``kind`` and
        ``shapes`` (whether a MAC was computed).
    """
    if ref.has_shapes:
        from .calculix.frd import compare_modes

        out = compare_modes(model, ref.frd, solver=solver)
    else:
        out = compare_frequencies(model, ref.frequencies_hz, solver=solver)
    return dict(out, kind=ref.kind, shapes=ref.has_shapes)


def compare_reference_with(models: dict, ref: Reference, *, solver: SolverContext | None = None) -> dict:
    """:func:`compare_reference` against the model of ``models`` (label -> FEModel, e.g. the coupled model and
    the model as read before its couplings) that the reference fits: the fewest notes (rigid-body modes,
    unpaired modes, a large difference), then the smallest largest relative difference of the elastic pairs.
    Only that comparison's notes are issued; ``compared_with`` is its label, ``others`` the largest
    difference of each other model."""
    import warnings

    tried = []
    for label, model in models.items():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = compare_reference(model, ref, solver=solver)
        diffs = [abs(d) for d in out["rel_diff"] if d is not None]
        tried.append(((len(out["notes"]), max(diffs) if diffs else np.inf), label, out, caught))
    score, label, out, caught = min(tried, key=lambda t: t[0])
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    others = {lb: (None if not np.isfinite(sc[1]) else float(sc[1])) for sc, lb, _, _ in tried if lb != label}
    return dict(out, compared_with=label, others=others)
