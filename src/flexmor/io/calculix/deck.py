"""The parts of a CalculiX (Abaqus-style) input deck that a matrix export needs: nodes, node sets, elements.

``*NODE`` and ``*ELEMENT`` data are parsed a block at a time with NumPy (a deck of a million
nodes in about a second); a block that does not fit the plain ``id, x, y, z`` (or ``id,
n1, n2, ...``) form is parsed line by line, which names the offending line.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ...errors import ReadError
from ...mesh import NODES_PER_CELL
from .._abaqus_materials import DeckElements
from .._abaqus_syntax import ELEMENT_LINE_ENTRIES, Keyword, check_last_lines, element_continues, walk
from .._cells import abaqus_cell

__all__ = ["read_inp"]

log = logging.getLogger(__name__)


def read_inp(path, *, element_types: set | None = None, cells: list | None = None,
             elements: DeckElements | None = None, keywords: set | None = None):
    """Read the node table, node sets and elements of a CalculiX/Abaqus-style input deck.

    Only ``*NODE``, ``*NSET`` (with ``GENERATE`` and set names as members), ``*ELEMENT`` and
    ``*INCLUDE, INPUT=...`` are interpreted (the syntax of :mod:`flexmor.io._abaqus_syntax`);
    everything else is skipped.

    Parameters
    ----------
    path : str or path-like
    element_types : set, optional
        Receives the ``TYPE=`` of every ``*ELEMENT`` keyword.
    cells : list, optional
        Receives ``(meshio cell type, node ids (n_cells, k))`` per ``*ELEMENT`` block of a
        known type, nodes in the deck's order (:func:`flexmor.io._cells.to_vtk` maps them).
    elements : DeckElements, optional
        Receives the element blocks with their numbers, ``*ELSET``, ``*MATERIAL``, ``*ELASTIC``,
        ``*DENSITY`` and the sections (:mod:`flexmor.io._abaqus_materials`).
    keywords : set, optional
        Receives the name of every keyword of the deck and its includes (upper case, e.g. ``STEP``).

    Returns
    -------
    node_ids : ndarray of int64, shape (n_nodes,)
    xyz : ndarray of float64, shape (n_nodes, 3)
    node_sets : dict of str to ndarray of int64
        Upper-case names.

    Raises
    ------
    ReadError
        For malformed node or element lines, duplicate node ids, unreadable includes or set
        members that are no node, a file of the deck whose last data line has no line end (cut off).
    """
    path = Path(path)
    st = {"ids": [], "xyz": [], "src": [], "sets": {}, "set_lines": []}
    cur_set = None
    last: dict = {}  # file -> its last item
    for item in walk(path):
        last[item.path] = item
        if isinstance(item, Keyword):
            if keywords is not None:
                keywords.add(item.name)
            cur_set = _keyword(item, st, element_types)
            if elements is not None:
                elements.keyword(item)
            continue
        kw = item.keyword
        if kw is None:
            continue
        if elements is not None:
            elements.data(item)
        if kw.name == "NODE":
            _node_block(item.path, item.lines, item.linenos, st, cur_set)
        elif kw.name == "NSET":
            for lineno, t in zip(item.linenos, item.lines):
                _nset_line(item.path, lineno, t, st, cur_set, "GENERATE" in kw.options)
        elif kw.name == "ELEMENT" and (cells is not None or elements is not None):
            a = _element_block(item.path, item.lines, item.linenos, kw.options.get("TYPE", "").upper(),
                               [] if cells is None else cells)
            if a is not None and elements is not None:
                elements.element_block(kw.options.get("TYPE", ""), kw.options.get("ELSET"), a)
    check_last_lines(last)
    ids = np.concatenate(st["ids"]) if st["ids"] else np.zeros(0, np.int64)
    xyz = np.concatenate(st["xyz"]) if st["xyz"] else np.zeros((0, 3))
    _check_unique(ids, st["src"])
    known = np.sort(ids)
    for name, lp, lno, members in st["set_lines"]:
        bad = members[~np.isin(members, known)]
        if bad.size:
            raise ReadError(lp, f"node set {name} names node {bad[0]}, which no *NODE line defines", lno)
    sets = {}
    for name, members in st["sets"].items():
        arr = np.unique(np.asarray(members, dtype=np.int64))
        if arr.size == 0:
            log.warning("%s: node set %s is empty", path, name)
        sets[name] = arr
    return ids, xyz, sets


def _keyword(kw: Keyword, st: dict, element_types: set | None) -> str | None:
    """Take note of a keyword line; the node set its data lines go to (upper case), or None."""
    cur_set = None
    if kw.name == "NODE" and kw.options.get("NSET"):
        cur_set = kw.options["NSET"].upper()
        st["sets"].setdefault(cur_set, [])
    elif kw.name == "NSET":
        if not kw.options.get("NSET"):
            raise ReadError(kw.path, "*NSET without NSET=name", kw.line)
        cur_set = kw.options["NSET"].upper()
        st["sets"].setdefault(cur_set, [])
    elif kw.name == "ELEMENT" and element_types is not None:
        element_types.add(kw.options.get("TYPE", "").upper())
    return cur_set


def _check_unique(ids: np.ndarray, src: list) -> None:
    """Refuse a node id defined twice, naming the second definition's line and the first's."""
    order = np.argsort(ids, kind="stable")
    dup = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if not dup.size:
        return
    second = order[dup + 1]
    j = int(np.argmin(second))
    k, first = int(second[j]), int(order[dup[j]])
    paths = [p for p, linenos in src for _ in range(len(linenos))] if len(src) > 1 else None
    where = np.concatenate([linenos for _, linenos in src])
    p_first = paths[first] if paths else src[0][0]
    p_second = paths[k] if paths else src[0][0]
    raise ReadError(p_second, f"node {ids[k]} defined twice (first at {Path(p_first).name}:{where[first]})",
                    int(where[k]))


def _node_block(path, data, linenos, st, cur_set):
    """The nodes of consecutive ``*NODE`` data lines, vectorized when all are ``id, x, y, z``."""
    k = len(data)
    a = None
    if "".join(data).count(",") == 3 * k:
        try:
            a = np.loadtxt(data, delimiter=",", comments=None, ndmin=2)
        except (ValueError, OverflowError):
            a = None
        if a is not None and a.shape == (k, 4):
            if not (np.all(np.isfinite(a)) and np.all(a[:, 0] == np.floor(a[:, 0]))
                    and np.abs(a[:, 0]).max() < 2**53):
                a = None
        else:
            a = None
    if a is not None:
        ids, xyz = a[:, 0].astype(np.int64), a[:, 1:]
    else:
        rows = [_node_line(path, lineno, t) for lineno, t in zip(linenos, data)]
        ids = np.array([r[0] for r in rows], dtype=np.int64)
        xyz = np.array([r[1] for r in rows], dtype=np.float64).reshape(-1, 3)
    st["ids"].append(ids)
    st["xyz"].append(xyz)
    st["src"].append((str(path), np.asarray(linenos, dtype=np.int64)))
    if cur_set is not None:
        st["sets"][cur_set].extend(ids.tolist())


def _node_line(path, lineno, s):
    parts = [p.strip() for p in s.split(",")]
    if parts and parts[-1] == "":
        parts.pop()
    if not 2 <= len(parts) <= 4:
        raise ReadError(path, f"expected 'id, x, y, z' in *NODE, got {s[:60]!r}", lineno)
    try:
        nid = int(parts[0])
        c = [float(p.replace("D", "E").replace("d", "e")) for p in parts[1:]]
    except ValueError:
        raise ReadError(path, f"non-numeric node line {s[:60]!r}", lineno) from None
    if not np.all(np.isfinite(c)):
        raise ReadError(path, f"node {nid} has a non-finite coordinate", lineno)
    return nid, c + [0.0] * (3 - len(c))


def _element_block(path, data, linenos, etype, cells):
    """The cells of consecutive ``*ELEMENT`` data lines (an element continues on the next line after a
    line that ends in a comma or is full, while it has fewer nodes than its type:
    :func:`flexmor.io._abaqus_syntax.element_continues`).

    Returns the rows ``(element number, nodes ...)``, None for a block left out of the mesh.
    """
    cell_type = abaqus_cell(etype)
    if cell_type is None:
        log.info("%s: element type %s is not kept in the mesh", path, etype or "(none)")
        return None
    nn = NODES_PER_CELL[cell_type]
    a = _element_rows(data, 1 + nn)
    if a is None:
        a = _element_lines(path, data, linenos, etype, nn)
    if a is not None:
        a = a.reshape(-1, 1 + nn)
        cells.append((cell_type, a[:, 1:]))
    return a


def _element_rows(data, width):
    """All numbers of the element lines ``data`` at once, as :func:`_element_lines` joins them into elements
    of ``width`` numbers each; None when a field between commas is not one integer (or is 0), or the
    lines do not hold whole elements that way (the line-by-line parse then names the defect).

    A line of ``c`` commas holds ``c + 1`` numbers, ``c`` when it ends in a comma: every line must lie
    within one element, and a line that leaves its element short must continue it (end in a comma or
    be full).
    """
    if not data:
        return None
    try:  # comma-separated: a blank field reads as 0, an empty one or two numbers in a field fail
        a = np.fromstring("\n".join(data).replace(",\n", "\n").replace("\n", ","), dtype=np.int64, sep=",")
    except ValueError:
        return None
    comma = np.array([t.endswith(",") for t in data])
    counts = np.array([t.count(",") for t in data], dtype=np.int64) + ~comma
    if counts.sum() != a.size or a.size % width or not counts.all() or not a.all():
        return None
    ends = np.cumsum(counts)
    if np.any((ends - counts) // width != (ends - 1) // width):  # a line runs into the next element
        return None
    if np.any((ends % width != 0) & ~comma & (counts < ELEMENT_LINE_ENTRIES)):  # an element ends short
        return None
    return a


def _element_lines(path, data, linenos, etype, nn):
    """Line-by-line parse of element data, naming the line of a defect.

    Elements with another node count than their type has (the mesh is only for display)
    leave the block out of the mesh with a warning (None).
    """
    out, cur, start = [], [], 0
    for lineno, t in zip(linenos, data):
        try:
            vals = [int(x) for x in t.split(",") if x.strip()]
        except ValueError:
            raise ReadError(path, f"non-integer *ELEMENT line {t[:60]!r}", lineno) from None
        if not cur:
            start = lineno
        cur.extend(vals)
        if element_continues(t, len(vals), len(cur), nn) and lineno != linenos[-1]:
            continue
        if len(cur) != 1 + nn:
            log.warning("%s:%d: element %s of type %s has %d nodes, expected %d; its *ELEMENT block is left out "
                        "of the mesh", path, start, cur[0] if cur else "?", etype, len(cur) - 1, nn)
            return None
        out.extend(cur)
        cur = []
    return np.asarray(out, dtype=np.int64)


def _nset_line(path, lineno, s, st, cur_set, generate):
    toks = [t.strip() for t in s.split(",") if t.strip()]
    if generate:
        try:
            vals = [int(t) for t in toks]
        except ValueError:
            raise ReadError(path, f"GENERATE expects 'first, last, step', got {s[:60]!r}", lineno) from None
        if len(vals) == 2:
            vals.append(1)
        if len(vals) != 3 or vals[2] <= 0 or vals[1] < vals[0]:
            raise ReadError(path, "GENERATE expects 'first, last, step' with first <= last and step > 0, "
                                  f"got {s[:60]!r}", lineno)
        members = np.arange(vals[0], vals[1] + 1, vals[2], dtype=np.int64)
    else:
        ids = []
        for t in toks:
            if t.lstrip("-").isdigit():
                ids.append(int(t))
            elif t.upper() in st["sets"] and t.upper() != cur_set:
                ids.extend(st["sets"][t.upper()])
            else:
                raise ReadError(path, f"*NSET member {t!r} is neither a node number nor a known node set", lineno)
        members = np.asarray(ids, dtype=np.int64)
    st["sets"][cur_set].extend(members.tolist())
    st["set_lines"].append((cur_set, path, lineno, members))
