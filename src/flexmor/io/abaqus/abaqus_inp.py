"""Parser of Abaqus input decks (``.inp``): nodes, elements, sets, parts and instances, materials.

Interpreted keywords (case-insensitive, abbreviations such as ``*Nset`` are the same):
``*NODE``, ``*ELEMENT``, ``*NSET`` and ``*ELSET`` (member lists, ``GENERATE`` ranges,
``INSTANCE=``, set names as members), ``*PART``/``*END PART``, ``*ASSEMBLY``,
``*INSTANCE`` (``PART=``, translation and rotation data lines)/``*END INSTANCE``,
``*MATERIAL``, ``*DENSITY``, ``*ELASTIC``, ``*SOLID SECTION``, ``*SHELL SECTION`` and ``*INCLUDE``. Everything
else is skipped. The lines are read by :mod:`flexmor.io._abaqus_syntax`, as the CalculiX
reader's.

Node numbering of the result
----------------------------
Nodes are collected per instance (``block-1``) in the order of the ``*INSTANCE`` lines, a
part's nodes sorted by label within each instance, then the nodes defined at assembly level
(reference points). This is Abaqus' internal node order, which the COORDINATE matrix format
uses. A flat deck without parts is one anonymous instance. The node ids of the model are the
labels when they are unique over all instances; otherwise instance ``k`` (0-based) gets
``k * 10**d + label`` with ``10**d`` above the largest label, and the log says so.
Set names are upper case; a set of an instance is available as ``INSTANCE.SET`` and, when the
name is unique, as ``SET``.

A deck cut off (a copy interrupted, a disk full) is refused, naming the deck and the line where it
ends: a last data line without its line end (its last number may be cut short, ``1.2`` of
``1.20000005``), and a ``*PART``, ``*INSTANCE``, ``*ASSEMBLY`` or ``*STEP`` without its ``*END ...``
line (what followed the cut, such as sets, sections and materials, would be missing silently).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import ReadError
from .._abaqus_syntax import Data, Keyword, check_last_lines, element_continues, walk
from .._cells import abaqus_nodes

__all__ = ["AbaqusDeck", "read_deck"]

log = logging.getLogger(__name__)


#: A node line whose label is written as a real number (``2e+11, 0.3``): not a node line.
_NON_INTEGER_LABEL = re.compile(r"(?m)^[ \t]*[^ \t,]*[.eEdD]")


@dataclass
class _Part:
    labels: list = field(default_factory=list)
    xyz: list = field(default_factory=list)
    where: dict = field(default_factory=dict)
    elements: list = field(default_factory=list)  # (label, type, [node labels])
    nsets: dict = field(default_factory=dict)
    elsets: dict = field(default_factory=dict)
    sections: list = field(default_factory=list)  # (elset, material)
    set_lines: list = field(default_factory=list)  # (set name, members, path, lineno) of *NSET lines


@dataclass
class AbaqusDeck:
    """What flexmor uses of an Abaqus input deck.

    Attributes
    ----------
    node_ids : ndarray of int64, shape (n_nodes,)
        Model node ids, in Abaqus' internal node order (see module docstring).
    xyz : ndarray of float64, shape (n_nodes, 3)
        Coordinates in the assembly, instance translations/rotations applied.
    keys : list of tuple
        ``(instance name or '', label)`` of each node, same order.
    elements : list of tuple
        ``(element type, ndarray of node ids)``, node ids as in ``node_ids``.
    element_sets : dict of str to list of int
        Indices into ``elements`` per element set (upper-case names).
    node_sets : dict of str to ndarray of int64
        Node ids per node set (upper-case names).
    materials : dict of str to dict
        ``{'DENSITY': rho, 'E': .., 'NU': ..}`` per material (upper-case names).
    sections : list of tuple
        ``(element set name, material name)`` of each ``*SOLID SECTION`` and ``*SHELL SECTION``.
    element_labels : list of int
        The label of each element of ``elements`` (within its instance).
    element_materials : list of str or None
        The material of each element of ``elements`` by its part's sections (None: no section).
    keywords : set of str
        The name of every keyword of the deck and its includes (upper case, e.g. ``STEP``).
    path : Path or None
        The deck file.
    end : tuple or None
        ``(file, line)`` of the deck's last keyword or data line.
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    keys: list
    elements: list
    element_sets: dict
    node_sets: dict
    materials: dict
    sections: list
    element_labels: list = field(default_factory=list)
    element_materials: list = field(default_factory=list)
    keywords: set = field(default_factory=set)
    path: Path | None = None
    end: tuple | None = None

    def lookup(self) -> dict:
        """Map ``(instance, label)`` and, for unambiguous labels, ``('', label)`` to node ids."""
        out = {k: int(i) for k, i in zip(self.keys, self.node_ids)}
        counts: dict = {}
        for _, lab in self.keys:
            counts[lab] = counts.get(lab, 0) + 1
        for (_, lab), i in zip(self.keys, self.node_ids):
            if counts[lab] == 1:
                out.setdefault(("", lab), int(i))
        return out


#: Keywords that open a block ended by ``*END <keyword>``, the innermost first.
_BLOCKS = ("INSTANCE", "PART", "ASSEMBLY", "STEP")


def _floats(path, lineno, s, what):
    toks = [t.strip() for t in s.split(",")]
    if toks and toks[-1] == "":
        toks.pop()
    try:
        return [float(t.replace("D", "E").replace("d", "e")) if t else 0.0 for t in toks]
    except ValueError:
        raise ReadError(path, f"non-numeric {what} line {s[:60]!r}", lineno) from None


def _ints(path, lineno, s, what):
    toks = [t.strip() for t in s.split(",") if t.strip()]
    try:
        return [int(t) for t in toks]
    except ValueError:
        raise ReadError(path, f"non-integer {what} line {s[:60]!r}", lineno) from None


class _Parser:
    def __init__(self):
        self.parts: dict[str, _Part] = {}
        self.instances: list = []  # (name, part name, translation, rotation)
        self.flat = _Part()  # nodes outside parts/instances (flat decks, assembly level)
        self.asm_nsets: list = []  # (set name, instance or None, members, path, lineno)
        self.materials: dict = {}
        self.has_assembly = False
        self.keywords: set = set()
        self.open: dict = {}  # "PART", "INSTANCE", "ASSEMBLY", "STEP" -> the Keyword not yet ended
        self.last: dict = {}  # file -> its last item (Keyword or Data)
        self.end = None  # (file, line) of the deck's last line

    def parse(self, path: Path):
        st = {"block": None, "opts": {}, "part": None, "inst": None, "mat": None, "elem": None, "cont": [],
              "nodes": None}
        for item in walk(path):
            self.last[item.path] = item
            if isinstance(item, Keyword):
                self.end = (item.path, item.line)
                self.keywords.add(item.name)
                if item.name in _BLOCKS:
                    self.open[item.name] = item
                elif item.name.startswith("END ") and item.name[4:] in _BLOCKS:
                    self.open.pop(item.name[4:], None)
                self._keyword(item.path, item.line, item, st)
            else:
                self.end = (item.path, item.linenos[-1])
                if item.keyword is not None:  # data lines of st["block"]
                    self._data_lines(item, st)
        self._check_cut()
        return self

    def _check_cut(self) -> None:
        """Refuse a deck that was cut off: a last data line without its line end, or a block without its end."""
        check_last_lines(self.last)
        if self.open:
            kw = min(self.open.values(), key=lambda k: _BLOCKS.index(k.name))
            name = kw.options.get("NAME", "")
            where = kw.line if kw.path == self.end[0] else f"{kw.path.name}:{kw.line}"
            lost = ("" if kw.name == "STEP" else
                    ", and what followed the cut (elements, node and element sets, sections, materials) is missing")
            raise ReadError(self.end[0], f"the deck ends inside *{kw.name}{f' {name}' if name else ''} (line {where}), "
                                         f"without *END {kw.name}: it seems cut off{lost}; copy or write it again",
                            self.end[1])

    def _data_lines(self, item: Data, st) -> None:
        """The data lines of a keyword; runs of node lines on consecutive lines at once where they allow."""
        path, lines, linenos = item.path, item.lines, item.linenos
        k, n = 0, len(lines)
        while k < n:
            if st["block"] == "NODE":
                j = k + 1
                while j < n and linenos[j] == linenos[j - 1] + 1:
                    j += 1
                if not self._node_run(path, linenos[k], lines[k:j], st):
                    for m in range(k, j):
                        self._data(path, linenos[m], lines[m], st)
                k = j
                continue
            self._data(path, linenos[k], lines[k], st)
            k += 1

    def _node_run(self, path, lineno, data, st) -> bool:
        """Store the node lines ``data`` (the first on line ``lineno``) if all are plain
        ``label, x, y, z`` with new labels; False leaves them to the line-by-line parser."""
        text = "\n".join(data)
        k = len(data)
        if text.count(",") != 3 * k:
            return False
        try:
            a = np.fromstring(text.replace(",", " "), sep=" ")
        except ValueError:
            return False
        if a.size != 4 * k or _NON_INTEGER_LABEL.search(text):
            return False
        a = a.reshape(k, 4)
        labels = a[:, 0]
        if not (np.all(np.isfinite(a)) and np.all(labels == np.floor(labels)) and np.abs(labels).max() < 2**53):
            return False
        labels = labels.astype(np.int64).tolist()
        tgt = self._target(st)
        if len(set(labels)) < k or not tgt.where.keys().isdisjoint(labels):
            return False
        where = str(path)
        tgt.where.update((lab, (where, lineno + m)) for m, lab in enumerate(labels))
        tgt.labels.extend(labels)
        tgt.xyz.extend(a[:, 1:].tolist())
        if st["opts"].get("NSET"):
            tgt.nsets.setdefault(st["opts"]["NSET"].upper(), []).extend(labels)
        return True

    # -- keywords ---------------------------------------------------------------------------
    def _keyword(self, path, lineno, keyword: Keyword, st):
        kw, opts = keyword.name, keyword.options
        st["block"], st["opts"], st["cont"] = kw, opts, []
        if kw == "PART":
            name = opts.get("NAME", "").upper()
            if not name:
                raise ReadError(path, "*PART without NAME=", lineno)
            st["part"] = self.parts.setdefault(name, _Part())
        elif kw in ("END PART", "END INSTANCE"):
            st["part"], st["inst"] = None, None
        elif kw == "ASSEMBLY":
            self.has_assembly = True
        elif kw == "INSTANCE":
            name = opts.get("NAME", "").upper()
            part = opts.get("PART", "").upper()
            if not name or not part:
                raise ReadError(path, "*INSTANCE needs NAME= and PART=", lineno)
            if part not in self.parts:
                raise ReadError(path, f"*INSTANCE {name} refers to part {part}, which no *PART defines", lineno)
            if any(i[0] == name for i in self.instances):
                raise ReadError(path, f"instance {name} defined twice", lineno)
            st["inst"] = [name, part, None, None]
            self.instances.append(st["inst"])
            st["part"] = self.parts[part]  # mesh data inside an instance belongs to its part
            st["inst_lines"] = 0
        elif kw == "NSET":
            if not opts.get("NSET"):
                raise ReadError(path, "*NSET without NSET=name", lineno)
        elif kw == "ELSET":
            if not opts.get("ELSET"):
                raise ReadError(path, "*ELSET without ELSET=name", lineno)
        elif kw == "ELEMENT":
            if not opts.get("TYPE"):
                raise ReadError(path, "*ELEMENT without TYPE=", lineno)
            st["nodes"] = abaqus_nodes(opts["TYPE"])  # None: continued by commas only
        elif kw == "MATERIAL":
            st["mat"] = self.materials.setdefault(opts.get("NAME", "").upper(), {})
        elif kw in ("SOLID SECTION", "SHELL SECTION"):
            tgt = st["part"] or self.flat
            tgt.sections.append((opts.get("ELSET", "").upper(), opts.get("MATERIAL", "").upper()))
        elif kw == "INCLUDE":  # the included file's lines follow
            st["block"] = None

    def _target(self, st):
        return st["part"] if st["part"] is not None else self.flat

    # -- data lines -------------------------------------------------------------------------
    def _data(self, path, lineno, s, st):
        kw, opts = st["block"], st["opts"]
        if kw == "INSTANCE" and st["inst"] is not None:
            vals = _floats(path, lineno, s, "instance position")
            st["inst_lines"] += 1
            if st["inst_lines"] == 1 and len(vals) >= 3:
                st["inst"][2] = np.array(vals[:3])
            elif st["inst_lines"] == 2 and len(vals) >= 7:
                st["inst"][3] = np.array(vals[:7])
            else:
                raise ReadError(path, "expected translation 'x, y, z' or rotation 'ax, ay, az, bx, by, bz, angle' "
                                      f"after *INSTANCE, got {s[:60]!r}", lineno)
        elif kw == "NODE":
            vals = _floats(path, lineno, s, "*NODE")
            if not 2 <= len(vals) <= 4 or not float(vals[0]).is_integer() or _NON_INTEGER_LABEL.match(s):
                raise ReadError(path, f"expected 'label, x, y, z' in *NODE (an integer label), got {s[:60]!r}",
                                lineno)
            if not np.all(np.isfinite(vals)):
                raise ReadError(path, "non-finite node coordinate", lineno)
            tgt, lab = self._target(st), int(vals[0])
            if lab in tgt.where:
                raise ReadError(path, f"node {lab} defined twice (first at line {tgt.where[lab][1]})", lineno)
            tgt.where[lab] = (str(path), lineno)
            tgt.labels.append(lab)
            tgt.xyz.append(vals[1:] + [0.0] * (4 - len(vals)))
            if opts.get("NSET"):
                tgt.nsets.setdefault(opts["NSET"].upper(), []).append(lab)
        elif kw == "ELEMENT":
            ints = _ints(path, lineno, s, "*ELEMENT")
            cont = st["cont"]
            if cont:  # continuation of the previous element (its line ended with a comma or was full)
                cont[2].extend(ints)
            else:
                if len(ints) < 2:
                    raise ReadError(path, f"element line needs a label and nodes, got {s[:60]!r}", lineno)
                cont = [ints[0], opts["TYPE"].upper(), ints[1:]]
                self._target(st).elements.append(cont)
                if opts.get("ELSET"):
                    self._target(st).elsets.setdefault(opts["ELSET"].upper(), []).append(ints[0])
            st["cont"] = cont if element_continues(s, len(ints), 1 + len(cont[2]), st["nodes"]) else []
        elif kw in ("NSET", "ELSET"):
            self._set_line(path, lineno, s, st, kw)
        elif kw == "DENSITY" and st["mat"] is not None:
            st["mat"]["DENSITY"] = _floats(path, lineno, s, "*DENSITY")[0]
        elif kw == "ELASTIC" and st["mat"] is not None and "E" in st["mat"]:
            st["mat"]["UNSUPPORTED"] = f"temperature-dependent *ELASTIC ({Path(path).name}:{lineno})"
        elif kw == "ELASTIC" and st["mat"] is not None:
            v = _floats(path, lineno, s, "*ELASTIC")
            st["mat"].update({"E": v[0], "NU": v[1] if len(v) > 1 else 0.0})
            kind = " ".join(opts.get("TYPE", "ISOTROPIC").upper().split())
            if kind not in ("ISO", "ISOTROPIC"):
                st["mat"]["UNSUPPORTED"] = f"*ELASTIC, TYPE={kind} ({Path(path).name}:{lineno}) is not evaluated " \
                                           "for Abaqus decks; isotropic materials are"

    def _set_line(self, path, lineno, s, st, kw):
        opts = st["opts"]
        name = opts[kw].upper()
        at_assembly = st["part"] is None and self.has_assembly
        tgt = self._target(st)
        store = tgt.nsets if kw == "NSET" else tgt.elsets
        if "GENERATE" in opts:
            v = _ints(path, lineno, s, "GENERATE")
            if len(v) == 2:
                v.append(1)
            if len(v) != 3 or v[2] <= 0 or v[1] < v[0]:
                raise ReadError(path, f"GENERATE expects 'first, last, step' with first <= last and step > 0, "
                                      f"got {s[:60]!r}", lineno)
            members = list(range(v[0], v[1] + 1, v[2]))
        else:
            members = []
            for t in (t.strip() for t in s.split(",")):
                if not t:
                    continue
                if t.lstrip("-").isdigit():
                    members.append(int(t))
                elif t.upper() in store and t.upper() != name:
                    members.extend(store[t.upper()])
                else:
                    raise ReadError(path, f"*{kw} member {t!r} is neither a number nor a known set", lineno)
        if kw == "NSET" and at_assembly:
            self.asm_nsets.append((name, opts.get("INSTANCE", "").upper() or None, members, path, lineno))
            return
        if kw == "NSET":
            tgt.set_lines.append((name, members, path, lineno))
        store.setdefault(name, []).extend(members)


def _rotate(xyz, rot):
    a, b, ang = rot[:3], rot[3:6], np.deg2rad(rot[6])
    k = b - a
    if np.linalg.norm(k) == 0:
        return xyz
    k = k / np.linalg.norm(k)
    p = xyz - a
    p = p * np.cos(ang) + np.cross(k, p) * np.sin(ang) + np.outer(p @ k, k) * (1 - np.cos(ang))
    return p + a


def read_deck(path) -> AbaqusDeck:
    """Read the mesh, sets and materials of an Abaqus input deck.

    Parameters
    ----------
    path : str or path-like
        The ``.inp`` file.

    Returns
    -------
    AbaqusDeck

    Raises
    ------
    ReadError
        Malformed node, element or set lines, duplicate nodes, unknown parts, set members
        that are not nodes, missing includes, a deck without nodes; a deck cut off (a last data
        line without its line end, a ``*PART``, ``*INSTANCE``, ``*ASSEMBLY`` or ``*STEP`` without
        its ``*END ...``), naming the line where it ends.
    """
    path = Path(path)
    P = _Parser().parse(path)
    groups = []  # (instance name, part)
    if P.instances:
        groups = [(name, P.parts[part], t, r) for name, part, t, r in P.instances]
    elif P.parts and not P.flat.labels:
        groups = [(name, part, None, None) for name, part in P.parts.items()]
    if P.flat.labels or not groups:
        groups.append(("", P.flat, None, None))
    keys, xyz = [], []
    for name, part, t, r in groups:
        if not part.labels:
            continue
        order = np.argsort(part.labels, kind="stable")
        c = np.asarray(part.xyz, dtype=np.float64)[order]
        if t is not None:
            c = c + t
        if r is not None:
            c = _rotate(c, r)
        keys.extend((name, int(part.labels[i])) for i in order)
        xyz.append(c)
    if not keys:
        raise ReadError(path, "no nodes (*NODE) found in the input deck")
    labels = np.array([k[1] for k in keys], dtype=np.int64)
    if np.unique(labels).size == labels.size:
        ids = labels
    else:
        step = 10 ** len(str(int(labels.max())))
        inst_index = {n: i for i, n in enumerate(dict.fromkeys(k[0] for k in keys))}
        ids = np.array([inst_index[k[0]] * step + k[1] for k in keys], dtype=np.int64)
        log.info("%s: node labels repeat across instances; node id = instance index * %d + label", path, step)
    lut = {k: int(i) for k, i in zip(keys, ids)}
    node_sets, element_sets, elements, sections = {}, {}, [], []
    labels_, materials_ = [], []
    seen_names: dict = {}
    for name, part, _, _ in groups:
        prefix = f"{name}." if name else ""
        eidx = {}
        for lab, etype, nodes in part.elements:
            try:
                elements.append((etype, np.array([lut[(name, n)] for n in nodes], dtype=np.int64)))
            except KeyError as exc:
                raise ReadError(path, f"element {lab} ({etype}) uses node {exc.args[0][1]}, which no *NODE defines") \
                    from None
            eidx[lab] = len(elements) - 1
            labels_.append(lab)
            materials_.append(None)
        for elset, mat in part.sections:
            for m in part.elsets.get(elset, []):
                if m in eidx:
                    materials_[eidx[m]] = mat
        for sname, members, p, lineno in part.set_lines:
            bad = [m for m in members if (name, m) not in lut]
            if bad:
                raise ReadError(p, f"node set {sname} names node {bad[0]}, which no *NODE defines", lineno)
        for sname, members in part.nsets.items():
            ids_ = np.unique(np.asarray([lut[(name, m)] for m in members], dtype=np.int64))
            node_sets[prefix + sname] = ids_
            seen_names.setdefault(sname, []).append(ids_)
        for ename, members in part.elsets.items():
            element_sets[prefix + ename] = [eidx[m] for m in members if m in eidx]
            element_sets.setdefault(ename, element_sets[prefix + ename])
        sections.extend(part.sections)
    for sname, inst, members, p, lineno in P.asm_nsets:
        ids_ = []
        for m in members:
            key = (inst or "", m)
            if key not in lut:
                raise ReadError(p, f"node set {sname} names node {m}" + (f" of instance {inst}" if inst else "")
                                + ", which no *NODE defines", lineno)
            ids_.append(lut[key])
        node_sets[sname] = np.unique(np.concatenate([node_sets.get(sname, np.zeros(0, np.int64)), ids_]))
    for sname, arrs in seen_names.items():
        if len(arrs) == 1 and sname not in node_sets:
            node_sets[sname] = arrs[0]
    return AbaqusDeck(ids, np.vstack(xyz), keys, elements, element_sets, node_sets, P.materials, sections,
                      labels_, materials_, P.keywords, path, P.end)

