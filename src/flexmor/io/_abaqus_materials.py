"""Elements, element sets, materials and sections of Abaqus-style decks (CalculiX and Abaqus).

:class:`DeckElements` takes the items of :func:`flexmor.io._abaqus_syntax.walk` that a reader
hands it (``*ELEMENT`` blocks already parsed into numbers, the keyword lines and data of
``*ELSET``, ``*MATERIAL``, ``*ELASTIC``, ``*DENSITY``, ``*SOLID SECTION``, ``*SHELL SECTION``)
and builds the :class:`flexmor.elements.Elements` of the deck. Isotropic elasticity, orthotropy
(``TYPE=ORTHO``) and engineering constants in the global axes are evaluated; temperature
tables, ``TYPE=ANISO`` and orthotropy with an ``ORIENTATION=`` are kept as unsupported
materials (with the reason), so that the model still reads for a reduction. So is a defect of
these keywords (a section of an undefined element set, a malformed ``*ELSET`` line ...): it is
logged, and stresses are refused naming it.
"""

from __future__ import annotations

import logging

import numpy as np

from ..elements import ElementBlock, Elements, Material
from ..errors import ModelError, ReadError
from ._abaqus_syntax import Data, Keyword

__all__ = ["DeckElements"]

log = logging.getLogger(__name__)


def _numbers(item: Data, what: str) -> list:
    vals = []
    for lineno, t in zip(item.linenos, item.lines):
        for tok in t.split(","):
            tok = tok.strip()
            if not tok:
                continue
            try:
                vals.append(float(tok.replace("D", "E").replace("d", "e")))
            except ValueError:
                raise ReadError(item.path, f"non-numeric value {tok!r} in {what}", lineno) from None
    return vals


class DeckElements:
    """Collects the elements, element sets, materials and sections of a deck (see the module)."""

    def __init__(self):
        self.blocks: list = []  # (type, ids, nodes)
        self.elsets: dict = {}
        self.materials: dict = {}  # name -> dict(elastic=..., rho=..., unsupported=...)
        self.sections: list = []  # (elset, material name, orientation, path, line)
        self._material = None
        self._elset = None
        self.problem = ""  # the first defect of the keywords read here (the deck still reads)

    def _defect(self, exc: ReadError) -> None:
        if not self.problem:
            self.problem = str(exc)
            log.warning("%s; stresses will not be recovered from this deck's materials", exc)

    # -- items ------------------------------------------------------------------------------
    def element_block(self, etype: str, elset: str | None, numbers: np.ndarray) -> None:
        """An ``*ELEMENT`` block as rows ``(element number, node ids ...)`` in the deck's node order."""
        ids, nodes = numbers[:, 0], numbers[:, 1:]
        self.blocks.append((etype.upper(), ids, nodes))
        if elset:
            self.elsets.setdefault(elset.upper(), []).append(ids)

    def keyword(self, kw: Keyword) -> None:
        """Take note of a keyword line."""
        if not self.problem:
            try:
                self._keyword(kw)
            except ReadError as exc:
                self._defect(exc)

    def data(self, item: Data) -> None:
        """Data lines under a keyword this class takes note of."""
        if not self.problem:
            try:
                self._data(item)
            except ReadError as exc:
                self._defect(exc)

    def _keyword(self, kw: Keyword) -> None:
        name = kw.name
        if name == "ELSET":
            self._elset = kw.options.get("ELSET", "").upper()
            if not self._elset:
                raise ReadError(kw.path, "*ELSET without ELSET=name", kw.line)
            self.elsets.setdefault(self._elset, [])
        elif name == "MATERIAL":
            self._material = kw.options.get("NAME", "").upper()
            if not self._material:
                raise ReadError(kw.path, "*MATERIAL without NAME=", kw.line)
            self.materials[self._material] = {}
        elif name in ("SOLID SECTION", "SHELL SECTION"):
            elset, mat = kw.options.get("ELSET", "").upper(), kw.options.get("MATERIAL", "").upper()
            if not elset or not mat:
                raise ReadError(kw.path, f"*{name} needs ELSET= and MATERIAL=", kw.line)
            self.sections.append((elset, mat, kw.options.get("ORIENTATION", ""), kw.path, kw.line))
        elif name in ("PART", "END PART", "ASSEMBLY", "INSTANCE", "STEP"):
            self._material = None

    def _data(self, item: Data) -> None:
        kw = item.keyword
        if kw is None:
            return
        if kw.name == "ELSET" and self._elset:
            self._elset_lines(item, "GENERATE" in kw.options)
        elif kw.name == "ELASTIC" and self._material is not None:
            self._elastic(item, kw)
        elif kw.name == "DENSITY" and self._material is not None:
            vals = _numbers(item, "*DENSITY")
            mat = self.materials[self._material]
            if len(item.lines) > 1:
                mat["rho_unsupported"] = "a temperature-dependent *DENSITY"
            elif vals:
                mat["rho"] = vals[0]

    def _elset_lines(self, item: Data, generate: bool) -> None:
        out = self.elsets[self._elset]
        for lineno, t in zip(item.linenos, item.lines):
            toks = [x.strip() for x in t.split(",") if x.strip()]
            if generate:
                try:
                    v = [int(x) for x in toks]
                except ValueError:
                    raise ReadError(item.path, f"GENERATE expects 'first, last, step', got {t[:60]!r}",
                                    lineno) from None
                if len(v) == 2:
                    v.append(1)
                if len(v) != 3 or v[2] <= 0 or v[1] < v[0]:
                    raise ReadError(item.path, f"GENERATE expects 'first, last, step', got {t[:60]!r}", lineno)
                out.append(np.arange(v[0], v[1] + 1, v[2], dtype=np.int64))
                continue
            ids = []
            for x in toks:
                if x.lstrip("-").isdigit():
                    ids.append(int(x))
                elif x.upper() in self.elsets and x.upper() != self._elset:
                    out.extend(self.elsets[x.upper()])
                else:
                    raise ReadError(item.path, f"*ELSET member {x!r} is neither an element number nor a known "
                                               "element set", lineno)
            out.append(np.asarray(ids, dtype=np.int64))

    def _elastic(self, item: Data, kw: Keyword) -> None:
        mat = self.materials[self._material]
        kind = " ".join(kw.options.get("TYPE", "ISO").upper().split())
        vals = _numbers(item, "*ELASTIC")
        need = {"ISO": 2, "ISOTROPIC": 2, "ORTHO": 9, "ORTHOTROPIC": 9, "ENGINEERING CONSTANTS": 9}.get(kind)
        where = f"{item.path.name}:{item.linenos[0]}"
        if need is None:
            mat["unsupported"] = f"*ELASTIC, TYPE={kind} ({where}) is not evaluated; isotropic, ORTHO and " \
                                 "ENGINEERING CONSTANTS are"
            return
        per = need + 1  # a temperature follows the constants
        if len(vals) > per or (kind in ("ISO", "ISOTROPIC") and len(item.lines) > 1):
            mat["unsupported"] = f"temperature-dependent *ELASTIC ({where}) is not evaluated"
            return
        if len(vals) < need:
            raise ReadError(item.path, f"*ELASTIC, TYPE={kind} needs {need} constants, got {len(vals)}",
                            item.linenos[0])
        mat["elastic"] = (kind, vals[:need], where)

    # -- result -----------------------------------------------------------------------------
    def _material_of(self, name: str) -> Material:
        data = self.materials.get(name)
        if data is None:
            return Material(name, unsupported=f"{name} is not defined by a *MATERIAL keyword")
        rho = data.get("rho")
        if data.get("unsupported"):
            return Material(name, rho=rho, unsupported=data["unsupported"])
        if "elastic" not in data:
            return Material(name, rho=rho, unsupported=f"*MATERIAL {name} has no *ELASTIC")
        kind, v, where = data["elastic"]
        try:
            if kind in ("ISO", "ISOTROPIC"):
                return Material.isotropic(v[0], v[1], rho, name)
            if kind in ("ORTHO", "ORTHOTROPIC"):
                return Material.orthotropic(*v, rho=rho, name=name)
            return Material.engineering_constants(*v, rho=rho, name=name)
        except ModelError as exc:
            return Material(name, rho=rho, unsupported=f"{exc} ({where})")

    def elements(self, source) -> Elements | None:
        """The :class:`~flexmor.elements.Elements` of the deck (None without elements); ``source`` is named
        in errors."""
        if not self.blocks:
            return None
        if not self.problem:
            try:
                return self._elements(source)
            except ReadError as exc:
                self._defect(exc)
        bad = Material("deck", unsupported=self.problem)
        blocks = [ElementBlock(t, ids, nodes, np.zeros(ids.size, np.int64)) for t, ids, nodes in self.blocks]
        return Elements(tuple(blocks), (bad,), str(source))

    def _elements(self, source) -> Elements:
        names = list(dict.fromkeys(s[1] for s in self.sections))
        materials = [self._material_of(n) for n in names]
        for _, mat, orient, path, line in self.sections:
            m = materials[names.index(mat)]
            if orient and m.D is not None and not _isotropic(m.D):
                materials[names.index(mat)] = Material(
                    m.name, rho=m.rho, unsupported=f"the anisotropic {m.name} in the local ORIENTATION={orient} "
                                                   f"({path.name}:{line}) is not evaluated")
        index = {}
        for elset, mat, _, path, line in self.sections:
            if elset not in self.elsets:
                raise ReadError(path, f"section refers to element set {elset}, which the deck does not define", line)
            ids = np.concatenate(self.elsets[elset]) if self.elsets[elset] else np.zeros(0, np.int64)
            index[elset] = (ids, names.index(mat))
        blocks = []
        for etype, ids, nodes in self.blocks:
            mat = np.full(ids.size, -1, np.int64)
            for set_ids, m in index.values():
                mat[np.isin(ids, set_ids)] = m
            blocks.append(ElementBlock(etype, ids, nodes, mat))
        return Elements(tuple(blocks), tuple(materials), str(source))


def _isotropic(D: np.ndarray) -> bool:
    lam, mu = D[0, 1], D[3, 3]
    ref = np.zeros((6, 6))
    ref[:3, :3] = lam
    ref[np.arange(3), np.arange(3)] = lam + 2 * mu
    ref[np.arange(3, 6), np.arange(3, 6)] = mu
    return bool(np.allclose(D, ref, rtol=1e-12, atol=0))
