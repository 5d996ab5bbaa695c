"""Small structured FE models written as CalculiX decks, and a runner for ``ccx``.

A bar ``L x B x H`` along x is meshed on a structured grid of ``nx x ny x nz`` cells with
C3D8 (8-node hex), C3D20R (20-node serendipity hex, reduced integration) or C3D10 (each cell
split into 6 quadratic tetrahedra, Kuhn's conforming triangulation along the main diagonal).
Shells (S8R: 8-node quads in the mid-plane z = H/2, thickness H) and beams (B32R: 3-node beams
on the axis, rectangular section) model the same bar; CalculiX expands them to C3D20R solids.
Nodes are numbered on the doubled grid (corner and mid-edge positions), so quadratic elements
share mid-side nodes without bookkeeping; only nodes used by an element are written.
"""

from __future__ import annotations

import itertools
import shutil
import subprocess
from pathlib import Path

import numpy as np

E, NU, RHO = 2.1e11, 0.3, 7850.0
L, B, H = 0.6, 0.1, 0.1
CCX = shutil.which("ccx")

# C3D20 mid-side nodes 9..20 as pairs of corners (0-based) of the hex 1..8
_HEX20_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
# C3D10 mid-side nodes 5..10
_TET10_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
_HEX_CORNERS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])


class Mesh:
    """Node ids on the doubled grid of ``nx x ny x nz`` cells; ``conn`` lists elements as fine-grid points."""

    def __init__(self, nx, ny, nz, size=(L, B, H)):
        self.n = np.array([nx, ny, nz])
        self.size = np.asarray(size, float)
        self.fine = 2 * self.n + 1

    def nid(self, p) -> int:
        p = np.asarray(p)
        return int(1 + p[0] + self.fine[0] * (p[1] + self.fine[1] * p[2]))

    def xyz(self, ids) -> np.ndarray:
        k = np.asarray(ids) - 1
        i, j, m = k % self.fine[0], (k // self.fine[0]) % self.fine[1], k // (self.fine[0] * self.fine[1])
        return np.column_stack([i, j, m]) / np.maximum(self.fine - 1, 1) * self.size

    def cells(self):
        yield from itertools.product(range(self.n[0]), range(self.n[1]), range(self.n[2]))


def solid_elements(mesh: Mesh, etype: str) -> list:
    """Connectivity (node ids) of the solid elements of ``etype`` (C3D8, C3D20R, C3D10)."""
    out = []
    for c in mesh.cells():
        corners = 2 * (np.array(c) + _HEX_CORNERS)
        if etype == "C3D8":
            out.append([mesh.nid(p) for p in corners])
        elif etype == "C3D20R":
            mids = [(corners[a] + corners[b]) // 2 for a, b in _HEX20_EDGES]
            out.append([mesh.nid(p) for p in list(corners) + mids])
        elif etype == "C3D10":
            for perm in itertools.permutations(range(3)):
                v = [2 * np.array(c)]
                for ax in perm:
                    v.append(v[-1] + 2 * np.eye(3, dtype=int)[ax])
                x = [p / np.maximum(mesh.fine - 1, 1) * mesh.size for p in v]
                if np.dot(np.cross(x[1] - x[0], x[2] - x[0]), x[3] - x[0]) < 0:
                    v[1], v[2] = v[2], v[1]
                mids = [(v[a] + v[b]) // 2 for a, b in _TET10_EDGES]
                out.append([mesh.nid(p) for p in v + mids])
        else:
            raise ValueError(etype)
    return out


def _lines(ids, per=8):
    return [", ".join(str(int(i)) for i in ids[k:k + per]) for k in range(0, len(ids), per)]


def deck(etype: str, n=(6, 2, 2), *, clamped: bool, load_node: int | None = None, modes: int = 10) -> tuple:
    """Text of a CalculiX deck for the bar and its node ids.

    Steps: an optional ``*STATIC`` step (unit force in z at ``load_node``, its displacement
    printed), a ``*FREQUENCY`` step with ``modes`` eigenmodes, the total mass (``EMAS``) printed,
    and ``*FREQUENCY, SOLVER=MATRIXSTORAGE``. ``clamped``: the face x = 0 is fixed (``FIX``).
    ``TIP`` is the node set of the face x = L.

    Returns
    -------
    text : str
    node_ids : ndarray
    """
    if etype in ("S8R", "B32R"):
        mesh = Mesh(n[0], n[1] if etype == "S8R" else 0, 0, (L, B, 0.0))
        if etype == "S8R":
            elems = []
            for i, j in itertools.product(range(n[0]), range(n[1])):
                q = 2 * np.array([(i, j, 0), (i + 1, j, 0), (i + 1, j + 1, 0), (i, j + 1, 0)])
                mids = [(q[a] + q[(a + 1) % 4]) // 2 for a in range(4)]
                elems.append([mesh.nid(p) for p in list(q) + mids])
        else:
            elems = [[mesh.nid((2 * i, 0, 0)), mesh.nid((2 * i + 1, 0, 0)), mesh.nid((2 * i + 2, 0, 0))]
                     for i in range(n[0])]
    else:
        mesh = Mesh(*n)
        elems = solid_elements(mesh, etype)
    ids = np.unique(np.concatenate(elems))
    xyz = mesh.xyz(ids)
    if etype == "S8R":
        xyz[:, 1] -= B / 2
    fix, tip = ids[np.isclose(xyz[:, 0], 0)], ids[np.isclose(xyz[:, 0], L)]
    out = ["*HEADING", f"bar {L} x {B} x {H}, {etype}", "*NODE, NSET=NALL"]
    out += [f"{i}, {x:.17g}, {y:.17g}, {z:.17g}" for i, (x, y, z) in zip(ids, xyz)]
    out.append(f"*ELEMENT, TYPE={etype}, ELSET=EALL")
    for k, e in enumerate(elems, 1):
        out += _lines([k] + list(e), 16)
    out += ["*NSET, NSET=FIX"] + _lines(fix) + ["*NSET, NSET=TIP"] + _lines(tip)
    out += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{E:.6g}, {NU}", "*DENSITY", f"{RHO}"]
    if etype == "S8R":
        out += ["*SHELL SECTION, ELSET=EALL, MATERIAL=STEEL", f"{H}"]
    elif etype == "B32R":
        out += ["*BEAM SECTION, ELSET=EALL, MATERIAL=STEEL, SECTION=RECT", f"{B}, {H}", "0., 1., 0."]
    else:
        out += ["*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL"]
    if clamped:
        out += ["*BOUNDARY", "FIX, 1, 6" if etype in ("S8R", "B32R") else "FIX, 1, 3"]
    if load_node is not None:
        out += ["*STEP", "*STATIC", "*CLOAD", f"{load_node}, 3, 1.0", "*NODE PRINT, NSET=LOADED", "U",
                "*END STEP"]
        out.insert(out.index("*MATERIAL, NAME=STEEL"), f"*NSET, NSET=LOADED\n{load_node}")
    out += ["*STEP", "*FREQUENCY", f"{modes}", "*NODE FILE", "U", "*EL PRINT, ELSET=EALL, TOTALS=ONLY", "EMAS",
            "*END STEP", "*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"]
    return "\n".join(out) + "\n", ids


def run(directory: Path, job: str, text: str) -> Path:
    """Write ``<job>.inp`` into ``directory``, run ``ccx`` on it; return the ``.sti`` path."""
    directory = Path(directory)
    (directory / f"{job}.inp").write_text(text)
    proc = subprocess.run([CCX, "-i", job], cwd=directory, capture_output=True, text=True, timeout=300)
    sti = directory / f"{job}.sti"
    if proc.returncode != 0 or not sti.exists() or "Job finished" not in proc.stdout:
        raise RuntimeError(f"ccx failed on {job}.inp:\n{proc.stdout[-3000:]}\n{proc.stderr[-2000:]}")
    return sti


def dat_frequencies(dat: Path) -> np.ndarray:
    """Eigenfrequencies (Hz, CYCLES/TIME column) of the first eigenvalue output in a ``.dat``."""
    text = Path(dat).read_text()
    block = text.split("E I G E N V A L U E   O U T P U T")[1].split("P A R T I C I P A T I O N")[0]
    rows = [ln.split() for ln in block.splitlines() if ln.strip()[:1].isdigit()]
    return np.array([float(r[3]) for r in rows])


def dat_mass(dat: Path) -> float:
    """Total mass (``EMAS`` with ``TOTALS=ONLY``) printed in a ``.dat``."""
    lines = Path(dat).read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if "mass (total)" in ln or "total mass" in ln.lower())
    nums = [ln for ln in lines[k + 1:] if ln.strip()]
    return float(nums[0].split()[-1])


def dat_displacement(dat: Path, node: int) -> np.ndarray:
    """Displacement (ux, uy, uz) of ``node`` from a ``*NODE PRINT`` block of a ``.dat``."""
    for ln in Path(dat).read_text().splitlines():
        p = ln.split()
        if len(p) == 4 and p[0] == str(node):
            return np.array([float(v) for v in p[1:]])
    raise ValueError(f"node {node} not in {dat}")
