"""Stresses of the solid elements against CalculiX's own: tiny distorted meshes of every supported
element type run through ``ccx`` (``*FREQUENCY`` with double-precision ``*ELEMENT OUTPUT`` of the
nodal stresses and ``*EL PRINT`` of the integration-point stresses), flexmor's stresses computed
from CalculiX's mode shapes and compared.

Two materials (isotropic steel and orthotropic engineering constants) on two element sets check
that each element gets the material of its section.
"""

from __future__ import annotations

import itertools
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ccx_models import CCX

from flexmor.io import read
from flexmor.io._cells import PERMUTATIONS
from flexmor.io.calculix import read_frd
from flexmor.stress import element_stresses, nodal_stresses

pytestmark = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) is not installed; Debian: apt-get install "
                                                    "calculix-ccx")

_HEX = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
_HEX20_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
_TET10_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
_WEDGE15_EDGES = [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)]
# the two wedges of a hex cell (corner indices, bottom triangle then top), and its six Kuhn tetrahedra
_WEDGES = [(0, 1, 2, 4, 5, 6), (0, 2, 3, 4, 6, 7)]
_LINEAR = {"C3D8": 8, "C3D8R": 8, "C3D20": 20, "C3D20R": 20, "C3D4": 4, "C3D10": 10, "C3D6": 6, "C3D15": 15}


def _cells(etype: str, n=(3, 2, 2)):
    """Elements of a grid of ``n`` cells on the doubled grid (points as integer triples)."""
    out = []
    for c in itertools.product(*(range(k) for k in n)):
        corners = [2 * (np.array(c) + v) for v in _HEX]
        if etype in ("C3D8", "C3D8R"):
            out.append(corners)
        elif etype in ("C3D20", "C3D20R"):
            out.append(corners + [(corners[a] + corners[b]) // 2 for a, b in _HEX20_EDGES])
        elif etype in ("C3D6", "C3D15"):
            for w in _WEDGES:
                v = [corners[i] for i in w]
                out.append(v if etype == "C3D6" else v + [(v[a] + v[b]) // 2 for a, b in _WEDGE15_EDGES])
        else:
            for perm in itertools.permutations(range(3)):
                v = [2 * np.array(c)]
                for ax in perm:
                    v.append(v[-1] + 2 * np.eye(3, dtype=int)[ax])
                if np.linalg.det(np.array([v[1] - v[0], v[2] - v[0], v[3] - v[0]])) < 0:
                    v[1], v[2] = v[2], v[1]
                out.append(v if etype == "C3D4" else v + [(v[a] + v[b]) // 2 for a, b in _TET10_EDGES])
    return out


def _rows(ids) -> list:
    return [", ".join(map(str, ids[s:s + 16])) for s in range(0, len(ids), 16)]


def _deck(etype: str, ortho: bool = True) -> str:
    """A clamped bar of 3 x 2 x 2 distorted cells, two materials (the right half orthotropic, else steel too),
    modes with stresses in the .frd and the .dat."""
    cells = _cells(etype)
    pts = sorted({tuple(int(x) for x in p) for e in cells for p in e})
    nid = {p: i + 1 for i, p in enumerate(pts)}
    rng = np.random.default_rng(7)
    cell = np.array([0.1, 0.1, 0.08])
    xyz = np.array(pts, float) / 2 * cell
    xyz = xyz + rng.uniform(-0.06, 0.06, xyz.shape) * cell / 2
    lines = ["*NODE, NSET=NALL"] + [f"{i + 1}, {x:.13e}, {y:.13e}, {z:.13e}" for i, (x, y, z) in enumerate(xyz)]
    left, right = [], []
    lines.append(f"*ELEMENT, TYPE={etype}, ELSET=EALL")
    for k, e in enumerate(cells, 1):
        ids = [k] + [nid[tuple(int(x) for x in p)] for p in e]
        for s in range(0, len(ids), 16):
            lines.append(", ".join(map(str, ids[s:s + 16])) + ("," if s + 16 < len(ids) else ""))
        (left if np.mean([p[0] for p in e]) < 3 else right).append(k)
    fix = [nid[p] for p in pts if p[0] == 0]
    lines += ["*ELSET, ELSET=LEFT", *_rows(left), "*ELSET, ELSET=RIGHT", *_rows(right), "*NSET, NSET=FIX", *_rows(fix)]
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", "210000., 0.3", "*DENSITY", "7.85e-9",
              "*MATERIAL, NAME=ORTHO", "*ELASTIC, TYPE=ENGINEERING CONSTANTS",
              "150000., 90000., 70000., 0.25, 0.3, 0.2, 40000., 30000.,", "25000.", "*DENSITY", "2.7e-9",
              "*SOLID SECTION, ELSET=LEFT, MATERIAL=STEEL",
              f"*SOLID SECTION, ELSET=RIGHT, MATERIAL={'ORTHO' if ortho else 'STEEL'}",
              "*BOUNDARY", "FIX, 1, 3",
              "*STEP", "*FREQUENCY", "6", "*NODE OUTPUT, DOUBLE", "U", "*ELEMENT OUTPUT, DOUBLE", "S",
              "*EL PRINT, ELSET=EALL", "S", "*END STEP",
              "*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"]
    return "\n".join(lines) + "\n"


def _run(tmp_path: Path, etype: str, ortho: bool = True) -> Path:
    job = f"s_{etype.lower()}"
    (tmp_path / f"{job}.inp").write_text(_deck(etype, ortho))
    proc = subprocess.run([CCX, "-i", job], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0 or "Job finished" not in proc.stdout:
        raise RuntimeError(f"ccx failed on {job}.inp:\n{proc.stdout[-3000:]}")
    return tmp_path / job


def _dat_stresses(dat: Path) -> list:
    """Per mode: rows (element, point, sxx, syy, szz, sxy, sxz, syz) and the printed strings of the values."""
    out = []
    for block in re.split(r"stresses \(elem, integ\.pnt\.,sxx,syy,szz,sxy,sxz,syz\)", dat.read_text())[1:]:
        rows = [ln.split() for ln in block.splitlines()[1:] if ln.strip()]
        rows = [r for r in rows[:next((i for i, r in enumerate(rows) if len(r) != 8), len(rows))]]
        out.append(rows)
    return out


def _half_ulp(text: str) -> float:
    """Half a unit in the last printed digit of a number such as ``-0.1234567E+03``."""
    mant, _, exp = text.upper().partition("E")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


def _modes(job: Path, model):
    """CalculiX's mode shapes over the model's equations (n_dof, 6) and its nodal stress blocks."""
    frd = read_frd(job.with_suffix(".frd"))
    disp = [b for b in frd.blocks if b["name"] == "DISP"]
    stress = [b for b in frd.blocks if b["name"] == "STRESS"]
    assert len(disp) == len(stress) == 6
    row = {int(n): i for i, n in enumerate(disp[0]["nodes"])}
    eq = np.array([row[int(n)] for n in model.dofs[:, 0]])
    return np.column_stack([b["values"][eq, model.dofs[:, 1] - 1] for b in disp]), stress, row


def _check_nodal(model, U, stress, row, tol):
    """flexmor's nodal stresses of the modes against CalculiX's, relative to each mode's peak."""
    nodal = nodal_stresses(model, U)
    assert nodal.values.shape == (6, nodal.node_ids.size, 6)
    for k, b in enumerate(stress):
        ref = b["values"][[row[int(n)] for n in nodal.node_ids]]
        peak = np.abs(ref).max()
        assert peak > 0
        err = np.abs(nodal.values[k] - ref).max() / peak
        assert err < tol, (k, err)


@pytest.mark.parametrize("etype", list(_LINEAR))
def test_stresses_match_calculix(tmp_path, etype):
    job = _run(tmp_path, etype)
    model = read(job.with_suffix(".sti"))
    assert model.elements is not None and {b.type for b in model.elements.blocks} == {etype}
    assert [m.name for m in model.elements.materials] == ["STEEL", "ORTHO"]
    U, stress, row = _modes(job, model)

    # nodal stresses: CalculiX's extrapolation and averaging (double-precision .frd), to 1e-9 of the peak
    _check_nodal(model, U, stress, row, 1e-9)

    # integration points: to 1e-8 of the peak beyond the rounding of the .dat's printed digits
    (field,) = element_stresses(model, U)
    pos = {int(e): i for i, e in enumerate(field.ids)}
    blocks = _dat_stresses(job.with_suffix(".dat"))
    assert len(blocks) == 6
    for k, rows in enumerate(blocks):
        assert len(rows) == field.ids.size * field.values.shape[2]
        el = np.array([pos[int(r[0])] for r in rows])
        ip = np.array([int(r[1]) - 1 for r in rows])
        ref = np.array([[float(v) for v in r[2:]] for r in rows])[:, [0, 1, 2, 3, 5, 4]]  # sxz syz -> yz zx
        tol = np.array([[_half_ulp(v) for v in r[2:]] for r in rows])[:, [0, 1, 2, 3, 5, 4]]
        mine = field.values[k][el, ip]
        peak = np.abs(ref).max()
        excess = np.abs(mine - ref) - tol
        assert excess.max() <= 1e-8 * peak, (etype, k, excess.max() / peak)


def _nastran_files(tmp_path: Path, model) -> Path:
    """The model as Nastran free-field DMIG (KAAX, MAAX) and bulk data: GRID, solids in Nastran's node
    order with PSOLID and MAT1 (steel, as the CalculiX deck)."""
    lines = []
    for name, A in (("KAAX", model.K), ("MAAX", model.M)):
        A = A.tocsc()
        lines.append(f"DMIG    {name:<8}       0       6       2       0                     {model.n_dof:>3}")
        for j in range(model.n_dof):
            col = slice(A.indptr[j], A.indptr[j + 1])
            lines.append(f"DMIG,{name},{model.dofs[j, 0]},{model.dofs[j, 1]},")
            lines += [f",{model.dofs[i, 0]},{model.dofs[i, 1]},{float(v)!r},"
                      for i, v in zip(A.indices[col], A.data[col]) if i <= j]
    pch = tmp_path / "bar.pch"
    pch.write_text("\n".join(lines) + "\n")
    bdf = [f"GRID,{n},," + ",".join(repr(float(c)) for c in p) for n, p in zip(model.node_ids, model.xyz)]
    to_nastran = {20: np.argsort(PERMUTATIONS[("nastran", "hexahedron20")]),
                  15: np.argsort(PERMUTATIONS[("nastran", "wedge15")])}
    card = {4: "CTETRA", 10: "CTETRA", 8: "CHEXA", 20: "CHEXA", 6: "CPENTA", 15: "CPENTA"}
    for b in model.elements.blocks:
        k = b.nodes.shape[1]
        nodes = b.nodes[:, to_nastran[k]] if k in to_nastran else b.nodes
        for e, g in zip(b.ids, nodes):
            fields = [str(e), "7", *map(str, g)]
            rows = [fields[:8]] + [fields[s:s + 8] for s in range(8, len(fields), 8)]
            bdf.append(f"{card[k]}," + ",".join(rows[0]) + ",+")
            bdf += ["+," + ",".join(r) + ",+" for r in rows[1:]]
            bdf[-1] = bdf[-1][:-2]
    bdf += ["PSOLID,7,3", "MAT1,3,210000.,,0.3,7.85e-9"]
    pch.with_suffix(".bdf").write_text("\n".join(bdf) + "\n")
    return pch


@pytest.mark.parametrize("etype", ["C3D8", "C3D20", "C3D10", "C3D15"])
def test_nastran_solids_match_calculix(tmp_path, etype):
    """The same mesh as Nastran CHEXA/CTETRA/CPENTA cards with PSOLID and MAT1 gives CalculiX's stresses."""
    job = _run(tmp_path, etype, ortho=False)
    ccx_model = read(job.with_suffix(".sti"))
    model = read(_nastran_files(tmp_path, ccx_model))
    (block,) = model.elements.blocks
    assert block.type == etype and (block.material == 0).all()
    assert model.elements.materials[0].rho == pytest.approx(7.85e-9)
    U, stress, row = _modes(job, model)
    _check_nodal(model, U, stress, row, 1e-9)
