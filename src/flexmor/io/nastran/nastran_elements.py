"""The elements of a Nastran bulk-data file with their materials (``PSOLID``/``PSHELL`` -> ``MAT1``).

Solids are named by the CalculiX element of the same shape (``CHEXA`` 8/20 grids: ``C3D8``/``C3D20``,
``CTETRA`` 4/10: ``C3D4``/``C3D10``, ``CPENTA`` 6/15: ``C3D6``/``C3D15``), their grids put in
CalculiX's node order (``CHEXA`` 20 and ``CPENTA`` 15 list the vertical edges before the top
ones); shells keep their card name. ``MAT1`` gives an isotropic material from ``E`` and ``NU``
(a blank one of ``E``, ``G``, ``NU`` follows from the other two, as Nastran defines it);
other material cards are kept as unsupported.
"""

from __future__ import annotations

import numpy as np

from ...elements import ElementBlock, Elements, Material
from ...errors import ModelError
from .._cells import PERMUTATIONS

__all__ = ["nastran_elements"]

_SOLIDS = {("CHEXA", 8): "C3D8", ("CHEXA", 20): "C3D20", ("CTETRA", 4): "C3D4", ("CTETRA", 10): "C3D10",
           ("CPENTA", 6): "C3D6", ("CPENTA", 15): "C3D15"}
_ORDER = {"C3D20": PERMUTATIONS[("nastran", "hexahedron20")], "C3D15": PERMUTATIONS[("nastran", "wedge15")]}


def _material(mid: int, data: dict | None) -> Material:
    name = f"MAT {mid}"
    if data is None:
        return Material(name, unsupported=f"MID {mid} is not defined (no MAT1 card)")
    where = f"{data['path'].name}:{data['line']}"
    if data["card"] != "MAT1":
        return Material(name, unsupported=f"{data['card']} {mid} ({where}) is not evaluated; MAT1 is")
    E, G, nu, rho = data["E"], data["G"], data["NU"], data["RHO"]
    if E is None and G is not None and nu is not None:
        E = 2 * (1 + nu) * G
    if nu is None:
        nu = E / (2 * G) - 1 if (E is not None and G) else 0.0
    try:
        return Material.isotropic(E if E is not None else 0.0, nu, rho if rho else None, name)
    except ModelError as exc:
        return Material(name, unsupported=f"MAT1 {mid} ({where}): {exc}")


def nastran_elements(bulk, source, node_ids=None) -> Elements | None:
    """The :class:`~flexmor.elements.Elements` of a :class:`~.nastran_bulk.Bulk` (None without elements).

    Elements using a grid outside ``node_ids`` (when given) are left out, as from the mesh.
    """
    groups: dict = {}
    for card, eid, pid, grids in bulk.element_cards:
        etype = _SOLIDS.get((card, len(grids)), card)
        groups.setdefault(etype, []).append((eid, pid, grids))
    if not groups:
        return None
    mids = sorted({bulk.properties[p][1] for rows in groups.values() for _, p, _ in rows if p in bulk.properties})
    materials = [_material(m, bulk.materials.get(m)) for m in mids]
    blocks = []
    for etype, rows in groups.items():
        if len({len(g) for _, _, g in rows}) != 1:
            continue
        ids = np.array([r[0] for r in rows], dtype=np.int64)
        nodes = np.array([r[2] for r in rows], dtype=np.int64)
        if etype in _ORDER:
            nodes = nodes[:, _ORDER[etype]]
        mat = np.array([mids.index(bulk.properties[p][1]) if p in bulk.properties else -1 for _, p, _ in rows],
                       dtype=np.int64)
        if node_ids is not None:
            ok = np.isin(nodes, node_ids).all(axis=1)
            ids, nodes, mat = ids[ok], nodes[ok], mat[ok]
        blocks.append(ElementBlock(etype, ids, nodes, mat))
    return Elements(tuple(blocks), tuple(materials), str(source))
