"""Reader of SID ``.SID_FEM`` files (see :mod:`flexmor.io.sid` for the format).

References
----------
O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I:
Definition of standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ...errors import OptionError, ReadError
from .sid_types import BODY_OBJECTS, M1_ORDERS, NODE_OBJECTS, SIDFile, SIDNode, Taylor

__all__ = ["read_sid"]

log = logging.getLogger(__name__)

_ENTRY = re.compile(r"^(m[01])\s*\(\s*(\d+)\s*,\s*(\d+)\s*(?:,\s*(\d+)\s*)?\)\s*=\s*(\S+)\s*$", re.IGNORECASE)
_KEYVAL = re.compile(r"^([A-Za-z_][\w ]*?)\s*(?:\(\s*(\d+)\s*\))?\s*=\s*(.*)$")


def _float(path, lineno, s):
    try:
        return float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise ReadError(path, f"not a number: {s!r}", line=lineno) from None


#: Largest Taylor object (nrow * ncol * nq entries) a SID file may announce.
_MAX_ENTRIES = 100_000_000


def _finish(path, raw, m1_order):
    h = raw["h"]
    try:
        nrow, ncol, nq, order = h["nrow"], h["ncol"], h.get("nq", 0), h.get("order", 0)
    except KeyError as exc:
        raise ReadError(path, f"Taylor object {raw['name']} lacks {exc.args[0]}", line=raw["line"]) from None
    structure = h.get("structure", 3)
    if min(nrow, ncol, nq) < 0 or max(nrow, 1) * max(ncol, 1) * max(nq, 1) > _MAX_ENTRIES:
        raise ReadError(path, f"Taylor object {raw['name']}: size {nrow} x {ncol} (nq {nq}) is negative or "
                              "implausibly large; is the header corrupt?", line=raw["line"])
    m0 = np.eye(nrow, ncol) if structure == 4 else np.zeros((nrow, ncol))
    for (i, j), v, ln in raw["m0"]:
        if not (1 <= i <= nrow and 1 <= j <= ncol):
            raise ReadError(path, f"{raw['name']}: m0({i},{j}) outside {nrow} x {ncol}", line=ln)
        m0[i - 1, j - 1] = v
        if structure == 2:
            m0[j - 1, i - 1] = v
    m1 = None
    if order >= 1:
        m1 = np.zeros((nrow, ncol, nq))
        for (i, a, b), v, ln in raw["m1"]:
            j, k = (b, a) if m1_order == "row-q-col" else (a, b)
            if not (1 <= i <= nrow and 1 <= j <= ncol and 1 <= k <= nq):
                raise ReadError(path, f"{raw['name']}: m1({i},{a},{b}) outside {nrow} x {ncol} x nq={nq} "
                                f"(m1_order={m1_order})", line=ln)
            m1[i - 1, j - 1, k - 1] = v
    return Taylor(m0, m1, nq, structure, h.get("nqn", 0))


def _evidence(raw):
    h, votes = raw["h"], set()
    ncol, nq = h.get("ncol", 0), h.get("nq", 0)
    for (_, a, b), _, _ in raw["m1"]:
        fits_rqc = a <= nq and b <= ncol
        fits_rcq = a <= ncol and b <= nq
        if fits_rqc != fits_rcq:
            votes.add("row-q-col" if fits_rqc else "row-col-q")
    return votes


def read_sid(path, *, m1_order: str = "auto") -> SIDFile:
    """Read a ``.SID_FEM`` file.

    Parameters
    ----------
    path : str or path-like
    m1_order : {'auto', 'row-q-col', 'row-col-q'}
        Index order of ``m1`` entries; ``auto`` decides from the index ranges and falls back
        to ``row-q-col``.

    Returns
    -------
    SIDFile

    Raises
    ------
    ReadError
        Missing file, malformed lines or blocks, entries outside the declared sizes,
        contradicting ``m1`` index orders.
    """
    path = Path(path)
    if m1_order not in ("auto",) + M1_ORDERS:
        raise OptionError(f"m1_order={m1_order!r} is not allowed; choose one of: auto, {', '.join(M1_ORDERS)}")
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise ReadError(path, f"cannot read: {exc.strerror}") from None
    header, mass, ielastq, nodes_raw, body_raw = "", None, {}, [], {}
    stack, cur_node, cur_obj, nelastq = [], None, None, None
    for ln, line in enumerate(lines, 1):
        s = line.strip()
        if not s:
            continue
        if ln == 1 and ":" in s and not s.lower().startswith("part"):
            header = line.rstrip()
            continue
        low = s.lower()
        if cur_obj is not None:
            m = _ENTRY.match(s)
            if m:
                key = m.group(1).lower()
                idx = tuple(int(g) for g in m.group(2, 3, 4) if g is not None)
                if (key == "m0") != (len(idx) == 2):
                    raise ReadError(path, f"{key} needs {2 if key == 'm0' else 3} indices: {s!r}", line=ln)
                cur_obj[key].append((idx, _float(path, ln, m.group(5)), ln))
                continue
            if low == "end " + cur_obj["name"].lower():
                (cur_node["objs"] if cur_node is not None else body_raw)[cur_obj["name"]] = cur_obj
                cur_obj = None
                continue
            m = _KEYVAL.match(s)
            if m and m.group(1).lower() in ("order", "nrow", "ncol", "nq", "nqn", "structure"):
                try:
                    cur_obj["h"][m.group(1).lower()] = int(m.group(3))
                except ValueError:
                    raise ReadError(path, f"{m.group(1)} must be an integer: {s!r}", line=ln) from None
                continue
            raise ReadError(path, f"unexpected line in Taylor object {cur_obj['name']}: {s!r}", line=ln)
        if low.startswith("end"):
            what = low[3:].strip()
            if what == "node":
                if cur_node is None:
                    raise ReadError(path, "'end node' without a 'new node' before it", line=ln)
                nodes_raw.append(cur_node)
                cur_node = None
            if stack and stack[-1] == what:
                stack.pop()
            continue
        m = _KEYVAL.match(s)
        if m:
            key, val = m.group(1).strip().lower(), m.group(3).strip()
            if key == "new node":
                try:
                    cur_node = {"id": int(val), "rframe": "", "objs": {}, "line": ln}
                except ValueError:
                    raise ReadError(path, f"node id must be an integer: {s!r}", line=ln) from None
            elif key == "mass":
                mass = _float(path, ln, val)
            elif key == "nelastq":
                try:
                    nelastq = int(val)
                except ValueError:
                    raise ReadError(path, f"nelastq must be an integer: {s!r}", line=ln) from None
            elif key == "ielastq":
                ielastq[int(m.group(2))] = val
            elif key == "rframe" and cur_node is not None:
                cur_node["rframe"] = val
            continue
        name = s.split()[0]
        names = NODE_OBJECTS if cur_node is not None else BODY_OBJECTS
        if name in names:
            cur_obj = {"name": name, "h": {}, "m0": [], "m1": [], "line": ln}
        else:
            stack.append(low)
    if cur_obj is not None:
        raise ReadError(path, f"Taylor object {cur_obj['name']} not closed (truncated file?)", line=cur_obj["line"])
    if mass is None:
        raise ReadError(path, "no refmod mass found: not a SID file")
    missing = [n for n in BODY_OBJECTS if n not in body_raw]
    if missing:
        raise ReadError(path, f"missing SID objects: {', '.join(missing)}")
    raws = list(body_raw.values()) + [o for nd in nodes_raw for o in nd["objs"].values()]
    if m1_order == "auto":
        votes = set().union(*[_evidence(r) for r in raws])
        if len(votes) > 1:
            raise ReadError(path, "m1 entries contradict each other in their index order")
        m1_order = votes.pop() if votes else M1_ORDERS[0]
        log.debug("%s: m1 index order %s", path, m1_order)
    objects = {n: _finish(path, body_raw[n], m1_order) for n in BODY_OBJECTS}
    nodes = []
    for nd in nodes_raw:
        miss = [n for n in NODE_OBJECTS if n not in nd["objs"]]
        if miss:
            raise ReadError(path, f"node {nd['id']} lacks {', '.join(miss)}", line=nd["line"])
        t = {n: _finish(path, nd["objs"][n], m1_order) for n in NODE_OBJECTS}
        nodes.append(SIDNode(nd["id"], rframe=nd["rframe"], **t))
    nq = nelastq if nelastq is not None else objects["Me"].m0.shape[0]
    names = [ielastq.get(a + 1, f"q{a + 1}") for a in range(nq)]
    return SIDFile(mass=mass, ielastq=names, nodes=nodes, objects=objects, header=header)
