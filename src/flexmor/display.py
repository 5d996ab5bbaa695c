"""How the objects of a study show themselves: short text reprs and small HTML tables for notebooks.

A model or a body holds arrays of thousands of entries; its repr names what it is in at most
three lines (:func:`text_repr`) and its ``_repr_html_`` is a table of a few rows
(:func:`html_table`), never the arrays themselves.
"""

from __future__ import annotations

import html

__all__ = ["MAX_REPR_LINES", "Shown", "text_repr", "html_table", "band_text", "names_text"]

#: Lines of the text repr of a model, a body, a study or an error record at most.
MAX_REPR_LINES = 3


def names_text(names, limit: int = 4) -> str:
    """``names`` joined by commas, the first ``limit`` of them and a count of the rest."""
    names = [str(n) for n in names]
    if not names:
        return "-"
    rest = len(names) - limit
    return ", ".join(names[:limit]) + (f" (+{rest} more)" if rest > 0 else "")


def band_text(band) -> str:
    """A band ``(fmin, fmax)`` in Hz as ``fmin-fmax Hz`` (``-`` when None)."""
    return "-" if band is None else f"{band[0]:g}-{band[1]:g} Hz"


#: Characters of one fact in a text repr at most (the HTML table shows it whole).
MAX_FACT = 72


#: Characters of one line of a text repr at most, before its count of the facts left out.
MAX_LINE = 150


def _clip(text: str) -> str:
    return text if len(text) <= MAX_FACT else text[:MAX_FACT - 3] + "..."


def text_repr(kind: str, head: str, rows) -> str:
    """``kind(head)`` and the ``(label, value)`` rows joined on at most :data:`MAX_REPR_LINES` lines.

    Parameters
    ----------
    kind : str
        The class name.
    head : str
        What the object is in a few words (its name, its size).
    rows : sequence of (str, str)
        Facts shown as ``label value``, wrapped onto the lines after the first (rows beyond
        what fits are left to the HTML table).
    """
    lines = [f"<{kind} {head}>"]
    parts = [_clip(f"{label} {value}" if label else str(value)) for label, value in rows]
    per_line = max(1, -(-len(parts) // (MAX_REPR_LINES - 1))) if parts else 1
    shown = 0
    while shown < len(parts) and len(lines) < MAX_REPR_LINES:
        line, end = "  " + parts[shown], min(shown + per_line, len(parts))
        shown += 1
        while shown < end and len(line) + 2 + len(parts[shown]) <= MAX_LINE:  # the rest: the HTML table
            line += "; " + parts[shown]
            shown += 1
        lines.append(line)
    if shown < len(parts):
        lines[-1] += f" (+{len(parts) - shown} more)"
    return "\n".join(lines)


def html_table(kind: str, head: str, rows) -> str:
    """A small HTML table: a caption ``kind head`` and one ``label | value`` row per fact (escaped)."""
    body = "".join(f"<tr><th style='text-align:left'>{html.escape(str(label))}</th>"
                   f"<td style='text-align:left'>{html.escape(str(value))}</td></tr>" for label, value in rows)
    return (f"<table><caption style='text-align:left'><b>{html.escape(kind)}</b> {html.escape(head)}</caption>"
            f"{body}</table>")


class Shown:
    """A class that shows itself by :meth:`_shown`: ``repr`` through :func:`text_repr`, ``_repr_html_``
    through :func:`html_table` (dataclasses using it are declared with ``repr=False``)."""

    __slots__ = ()

    def _shown(self) -> tuple[str, list]:
        """``(head, rows)``: what the object is in a few words and its ``(label, value)`` facts."""
        raise NotImplementedError

    def __repr__(self) -> str:
        head, rows = self._shown()
        return text_repr(type(self).__name__, head, rows)

    def _repr_html_(self) -> str:
        """A small HTML table of the object (Jupyter's rich display)."""
        head, rows = self._shown()
        return html_table(type(self).__name__, head, rows)
