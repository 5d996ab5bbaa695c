"""Reader of SID ``.SID_FEM`` files (see :mod:`flexmor.io.sid` for the format).

References
----------
O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I:
Definition of standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.
"""

from __future__ import annotations

import logging
import re
import warnings
from pathlib import Path

import numpy as np

from ...errors import FlexmorWarning, OptionError, ReadError
from .._open import read_all
from .sid_types import BODY_OBJECTS, M1_ORDERS, NODE_OBJECTS, NODE_OPTIONAL, SIDFile, SIDNode, Taylor

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
    seen: dict = {}
    for (i, j), v, ln in raw["m0"]:
        if not (1 <= i <= nrow and 1 <= j <= ncol) or (structure == 2 and not (j <= nrow and i <= ncol)):
            raise ReadError(path, f"{raw['name']}: m0({i},{j}) outside {nrow} x {ncol}", line=ln)
        # the structure says which coefficients the object has: a line against it was moved or repeated here
        if structure in (0, 4) or (structure == 1 and i != j):
            kind = {0: "a zero matrix", 4: "a unit matrix", 1: "a diagonal matrix"}[structure]
            raise ReadError(path, f"{raw['name']}: m0({i},{j}) in an object of structure {structure} ({kind}, "
                                  f"object from line {raw['line']}); a line moved or repeated from another object?",
                            line=ln)
        key = (min(i, j), max(i, j)) if structure == 2 else (i, j)
        if key in seen and seen[key][1] != v:  # the same value twice is harmless; two values are not
            raise ReadError(path, f"{raw['name']}: m0({i},{j}) given twice with different values (lines "
                                  f"{seen[key][0]} and {ln})", line=ln)
        seen[key] = (ln, v)
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


_TAYLOR_KEYS = ("order", "nrow", "ncol", "nq", "nqn", "structure")


class _Scan:
    """The objects of a SID file as read line by line, before their sizes are checked.

    A Taylor object is a dict ``{"name", "h" (header integers), "m0", "m1" (entries with their
    line), "line"}``; a node ``{"id", "rframe", "objs", "line"}``.
    """

    def __init__(self, path: Path):
        self.path = path
        self.header, self.mass, self.nelastq = "", None, None
        self.ielastq: dict = {}
        self.nodes: list = []
        self.body: dict = {}
        self.stack: list = []  # open blocks other than nodes and Taylor objects
        self.node = None  # the node being read
        self.obj = None  # the Taylor object being read

    def line(self, ln: int, line: str) -> None:
        s = line.strip()
        if not s:
            return
        if ln == 1 and ":" in s and not s.lower().startswith("part"):
            self.header = line.rstrip()
        elif self.obj is not None:
            self._object_line(ln, s)
        elif s.lower().startswith("end"):
            self._end(ln, s.lower()[3:].strip())
        elif not self._key_value(ln, s):
            name = s.split()[0]
            if name in (NODE_OBJECTS + NODE_OPTIONAL if self.node is not None else BODY_OBJECTS):
                self.obj = {"name": name, "h": {}, "m0": [], "m1": [], "line": ln}
            else:
                self.stack.append(s.lower())

    def _object_line(self, ln: int, s: str) -> None:
        """A line inside a Taylor object: an entry, a header integer, or its end."""
        obj, path = self.obj, self.path
        m = _ENTRY.match(s)
        if m:
            key = m.group(1).lower()
            idx = tuple(int(g) for g in m.group(2, 3, 4) if g is not None)
            if (key == "m0") != (len(idx) == 2):
                raise ReadError(path, f"{key} needs {2 if key == 'm0' else 3} indices: {s!r}", line=ln)
            obj[key].append((idx, _float(path, ln, m.group(5)), ln))
            return
        if s.lower() == "end " + obj["name"].lower():
            (self.node["objs"] if self.node is not None else self.body)[obj["name"]] = obj
            self.obj = None
            return
        m = _KEYVAL.match(s)
        if m and m.group(1).lower() in _TAYLOR_KEYS:
            try:
                obj["h"][m.group(1).lower()] = int(m.group(3))
            except ValueError:
                raise ReadError(path, f"{m.group(1)} must be an integer: {s!r}", line=ln) from None
            return
        raise ReadError(path, f"unexpected line in Taylor object {obj['name']}: {s!r}", line=ln)

    def _end(self, ln: int, what: str) -> None:
        """``end node`` closes the node; ``end <block>`` the innermost open block of that name."""
        if what == "node":
            if self.node is None:
                raise ReadError(self.path, "'end node' without a 'new node' before it", line=ln)
            self.nodes.append(self.node)
            self.node = None
        if self.stack and self.stack[-1] == what:
            self.stack.pop()

    def _key_value(self, ln: int, s: str) -> bool:
        """A ``key = value`` line (``new node``, ``mass``, ``nelastq``, ``ielastq(i)``, ``rframe``); False if none."""
        m = _KEYVAL.match(s)
        if not m:
            return False
        path, key, val = self.path, m.group(1).strip().lower(), m.group(3).strip()
        if key == "new node":
            try:
                self.node = {"id": int(val), "rframe": "", "objs": {}, "line": ln}
            except ValueError:
                raise ReadError(path, f"node id must be an integer: {s!r}", line=ln) from None
        elif key == "mass":
            self.mass = _float(path, ln, val)
        elif key == "nelastq":
            try:
                self.nelastq = int(val)
            except ValueError:
                raise ReadError(path, f"nelastq must be an integer: {s!r}", line=ln) from None
        elif key == "ielastq":
            self.ielastq[int(m.group(2))] = val
        elif key == "rframe" and self.node is not None:
            self.node["rframe"] = val
        return True

    def check_complete(self) -> None:
        """Refuse a file that ends inside a Taylor object, or lacks the mass or a body object."""
        if self.obj is not None:
            raise ReadError(self.path, f"Taylor object {self.obj['name']} not closed (truncated file?)",
                            line=self.obj["line"])
        if self.mass is None:
            raise ReadError(self.path, "no refmod mass found: not a SID file")
        missing = [n for n in BODY_OBJECTS if n not in self.body]
        if missing:
            raise ReadError(self.path, f"missing SID objects: {', '.join(missing)}")

    def taylor_objects(self) -> list:
        """Every Taylor object read, of the body and of the nodes."""
        return list(self.body.values()) + [o for nd in self.nodes for o in nd["objs"].values()]


def _read_lines(path: Path) -> list:
    return read_all(path).decode("utf-8", errors="replace").splitlines()


def _m1_order(path, raws: list, m1_order: str) -> str:
    """The index order of ``m1`` entries: ``m1_order``, or for ``auto`` the one the index ranges show."""
    if m1_order != "auto":
        return m1_order
    votes = set().union(*[_evidence(r) for r in raws])
    if len(votes) > 1:
        raise ReadError(path, "m1 entries contradict each other in their index order")
    m1_order = votes.pop() if votes else M1_ORDERS[0]
    log.debug("%s: m1 index order %s", path, m1_order)
    return m1_order


def _sid_file(scan: _Scan, m1_order: str) -> SIDFile:
    """The :class:`SIDFile` of a complete scan, every Taylor object checked against its sizes."""
    path = scan.path
    objects = {n: _finish(path, scan.body[n], m1_order) for n in BODY_OBJECTS}
    nodes = []
    for nd in scan.nodes:
        miss = [n for n in NODE_OBJECTS if n not in nd["objs"]]
        if miss:
            raise ReadError(path, f"node {nd['id']} lacks {', '.join(miss)}", line=nd["line"])
        t = {n: _finish(path, nd["objs"][n], m1_order) for n in NODE_OBJECTS + NODE_OPTIONAL if n in nd["objs"]}
        nodes.append(SIDNode(nd["id"], rframe=nd["rframe"], **t))
    for name, what in (("Ke", "stiffness"), ("Me", "mass")):
        m0 = objects[name].m0
        zero = np.flatnonzero(~(np.diag(m0) > 0)) if m0.shape[0] == m0.shape[1] else np.zeros(0, int)
        if zero.size:  # an elastic coordinate has both; a missing coefficient reads as zero
            a = int(zero[0]) + 1
            warnings.warn(FlexmorWarning(
                f"{path.name}: {name}({a},{a}) = {m0[a - 1, a - 1]:g}: elastic coordinate {a} has no {what}"
                f"{f' (and {zero.size - 1} more)' if zero.size > 1 else ''}; a coefficient line lost (SID objects "
                "have no count of their coefficients), or the coordinates hold rigid motion"), stacklevel=3)
    nq = scan.nelastq if scan.nelastq is not None else objects["Me"].m0.shape[0]
    names = [scan.ielastq.get(a + 1, f"q{a + 1}") for a in range(nq)]
    return SIDFile(mass=scan.mass, ielastq=names, nodes=nodes, objects=objects, header=scan.header)


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
    scan = _Scan(path)
    for ln, line in enumerate(_read_lines(path), 1):
        scan.line(ln, line)
    scan.check_complete()
    return _sid_file(scan, _m1_order(path, scan.taylor_objects(), m1_order))
