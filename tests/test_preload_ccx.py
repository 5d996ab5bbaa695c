"""Preloaded frequencies against CalculiX: a geometrically nonlinear static step (``*STEP, NLGEOM`` ``*STATIC``)
under the load, then ``*STEP, PERTURBATION`` ``*FREQUENCY``, against the frequencies of
:func:`flexmor.preload.preload_stiffness` on the matrices CalculiX stores for the unloaded model
(``*FREQUENCY, SOLVER=MATRIXSTORAGE``): a clamped steel beam under tip tension (C3D20R, C3D20, C3D8, C3D8R,
C3D4, C3D6) and a blade clamped at its hub spinning about the z axis (C3D20R, C3D10)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from ccx_models import CCX, Mesh, dat_frequencies, solid_elements

from flexmor.io import read
from flexmor.linalg.eigen import eigenmodes, frequencies_hz
from flexmor.preload import preload_stiffness

pytestmark = [pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) is not installed; Debian: apt-get install "
                                                     "calculix-ccx"),
              pytest.mark.filterwarnings("ignore:.*mass matrix is singular")]  # C3D20R

#: (cells, size, offset) of the slender beam (x from 0 to 1 m) and of the blade (hub radius 0.2 m, 0.8 m long).
GEOMETRY = {"beam": ((20, 2, 2), (1.0, 0.05, 0.05), (0.0, 0.0, 0.0)),
            "blade": ((16, 2, 2), (0.8, 0.05, 0.05), (0.2, -0.025, -0.025))}


def _ids(ids) -> list:
    return [", ".join(map(str, ids[s:s + 16])) for s in range(0, len(ids), 16)]


def _deck(etype: str, case: str, steps: list) -> tuple[str, int]:
    """The deck of ``case`` in ``etype`` elements, clamped at x = min (``FIX``), ``TIP`` the face at x = max;
    and the number of tip nodes."""
    n, size, offset = GEOMETRY[case]
    mesh = Mesh(*n, size=size)
    # the nodes of the element of the same shape (C3D4: the corners of C3D10)
    base = {"C3D20": "C3D20R", "C3D4": "C3D10", "C3D8R": "C3D8", "C3D6": "C3D8"}.get(etype, etype)
    elems = [e[:4] if etype == "C3D4" else e for e in solid_elements(mesh, base)]
    if etype == "C3D6":  # each hexahedron as two wedges
        elems = [[e[i] for i in w] for e in solid_elements(mesh, "C3D8")
                 for w in ((0, 1, 2, 4, 5, 6), (0, 2, 3, 4, 6, 7))]
    ids = np.unique(np.concatenate(elems))
    xyz = mesh.xyz(ids) + np.asarray(offset)
    out = ["*NODE, NSET=NALL"] + [f"{i}, {x:.17g}, {y:.17g}, {z:.17g}" for i, (x, y, z) in zip(ids, xyz)]
    out.append(f"*ELEMENT, TYPE={etype}, ELSET=EALL")
    for k, e in enumerate(elems, 1):
        vals = [k, *e]
        rows = [vals[s:s + 16] for s in range(0, len(vals), 16)]
        out += [", ".join(map(str, r)) + ("," if j + 1 < len(rows) else "") for j, r in enumerate(rows)]
    fix, tip = ids[np.isclose(xyz[:, 0], xyz[:, 0].min())], ids[np.isclose(xyz[:, 0], xyz[:, 0].max())]
    out += ["*NSET, NSET=FIX", *_ids(fix), "*NSET, NSET=TIP", *_ids(tip)]
    out += ["*MATERIAL, NAME=STEEL", "*ELASTIC", "2.1e11, 0.3", "*DENSITY", "7850.",
            "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", "*BOUNDARY", "FIX, 1, 3", *steps]
    return "\n".join(out) + "\n", tip.size


def _run(directory: Path, job: str, text: str) -> Path:
    (directory / f"{job}.inp").write_text(text)
    proc = subprocess.run([CCX, "-i", job], cwd=directory, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 or "Job finished" not in proc.stdout:
        raise RuntimeError(f"ccx failed on {job}.inp:\n{proc.stdout[-3000:]}")
    return directory / job


def _compare(tmp_path, etype, case, load_lines, spec, n=4):
    text, _ = _deck(etype, case, ["*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"])
    model = read(_run(tmp_path, "model", text).with_suffix(".sti"))
    text, _ = _deck(etype, case, ["*STEP, NLGEOM", "*STATIC", *load_lines, "*END STEP", "*STEP, PERTURBATION",
                                  "*FREQUENCY", f"{n + 2}", "*END STEP"])
    ref = dat_frequencies(_run(tmp_path, "loaded", text).with_suffix(".dat"))[:n]
    f0 = frequencies_hz(eigenmodes(model.K, model.M, n)[0])
    pre = preload_stiffness(model, spec)
    f = frequencies_hz(eigenmodes(pre.K, model.M, n)[0])
    return f0, f, ref, model, pre


@pytest.mark.parametrize("etype", ["C3D20R", "C3D20", "C3D8", "C3D8R", "C3D4", "C3D6"])
def test_beam_under_tip_tension(tmp_path, etype):
    force = 2e5
    tip = _deck(etype, "beam", [])[1]
    f0, f, ref, _, _ = _compare(tmp_path, etype, "beam", ["*CLOAD", f"TIP, 1, {force / tip!r}"], f"TIP:x={force}")
    assert ref[0] > 1.05 * f0[0]  # the first bending frequencies rise by more than 5 %
    assert np.abs(f / ref - 1).max() < 0.005, (f, ref)


@pytest.mark.parametrize("etype", ["C3D20R", "C3D10"])
def test_blade_spinning_about_its_hub(tmp_path, etype):
    w = 200.0
    f0, f, ref, model, pre = _compare(tmp_path, etype, "blade", ["*DLOAD", f"EALL, CENTRIF, {w * w!r}, 0., 0., 0., "
                                                                 "0., 0., 1."], f"spin:0,0,{w}")
    assert ref[0] > 1.05 * f0[0] and ref[1] > f0[1]  # flapwise up by more than 5 %, edgewise up too
    assert np.abs(f / ref - 1).max() < 0.005, (f, ref)
    # without the spin softening the edgewise mode misses
    g = frequencies_hz(eigenmodes(pre.K - pre.softening, model.M, 4)[0])
    assert np.abs(g / ref - 1).max() > 0.02


def _complex_frequencies(dat: Path) -> np.ndarray:
    """The frequencies (Hz) of the ``*COMPLEX FREQUENCY`` step: the last eigenvalue output of the ``.dat``."""
    block = dat.read_text().split("E I G E N V A L U E   O U T P U T")[-1].split("P A R T I C I P A T I O N")[0]
    return np.array([float(r.split()[2]) for r in block.splitlines() if r.strip()[:1].isdigit()])


def test_spinning_blade_campbell_and_speed_range_body_against_calculix(tmp_path):
    """The blade spinning about z at 300 rad/s with Coriolis forces: CalculiX's ``*COMPLEX FREQUENCY, CORIOLIS``
    (after the NLGEOM centrifugal step and a ``*FREQUENCY, STORAGE=YES`` of 12 modes) against the Campbell
    frequencies of the full model and of a krylov body built over 0-300 rad/s (``spin_range``), and that body's
    frequencies without Coriolis against CalculiX's perturbation ``*FREQUENCY`` at five speeds: within 0.5 %."""
    import flexmor
    from flexmor.spin import campbell, spin_operators

    text, _ = _deck("C3D20R", "blade", ["*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"])
    model = read(_run(tmp_path, "model", text).with_suffix(".sti"))
    body = flexmor.reduce(model, "krylov", 12, flexmor.make_ports(model, ["TIP:x", "TIP:y", "TIP:z"]),
                          spin_range="z:0:300")
    spin = body.info["spin"]
    K2, G1 = np.asarray(spin["K2"]), np.asarray(spin["G1"])
    w = 300.0
    centrif = ["*DLOAD", f"EALL, CENTRIF, {w * w!r}, 0., 0., 0., 0., 0., 1."]
    text, _ = _deck("C3D20R", "blade", ["*STEP, NLGEOM", "*STATIC", *centrif, "*END STEP", "*STEP, PERTURBATION",
                                        "*FREQUENCY, STORAGE=YES", "12", "*END STEP", "*STEP, PERTURBATION",
                                        "*COMPLEX FREQUENCY, CORIOLIS", "6", "*END STEP"])
    ref = _complex_frequencies(_run(tmp_path, "complex", text).with_suffix(".dat"))
    ops = spin_operators(model, [0.0, 0.0, 1.0])
    full = campbell(model.M, model.K, ops.K2, ops.G1, [w], 6).frequencies_hz[0]
    mine = campbell(body.M, body.K, K2, G1, [w], 6).frequencies_hz[0]
    assert np.abs(full / ref - 1).max() < 0.005, (full, ref)
    assert np.abs(mine / ref - 1).max() < 0.005, (mine, ref)
    assert np.abs(G1).max() > 0 and abs(ref[1] - frequencies_hz(eigenmodes(model.K, model.M, 2)[0])[1]) > 1.0
    for i, s in enumerate(np.linspace(0.0, 300.0, 5).tolist()):
        load = ["*STEP, NLGEOM", "*STATIC", "*DLOAD", f"EALL, CENTRIF, {s * s!r}, 0., 0., 0., 0., 0., 1.",
                "*END STEP", "*STEP, PERTURBATION"] if s else ["*STEP"]
        text, _ = _deck("C3D20R", "blade", [*load, "*FREQUENCY", "6", "*END STEP"])
        ref = dat_frequencies(_run(tmp_path, f"speed{i}", text).with_suffix(".dat"))[:4]
        import scipy.linalg as sla

        mine = frequencies_hz(sla.eigh(body.K + s * s * K2, body.M, eigvals_only=True)[:4])
        assert np.abs(mine / ref - 1).max() < 0.005, (s, mine, ref)


def _disc_deck(steps: list, nr: int = 4, nt: int = 32, r0: float = 0.05, r1: float = 0.25, t: float = 0.008) -> str:
    """A steel disc (annulus r0..r1, thickness t, C3D8 cells nr x nt x 1), clamped at its hub r = r0 (``FIX``);
    ``RIM`` a node of its rim."""
    def nid(i, j, k):
        return 1 + i + (nr + 1) * ((j % nt) + nt * k)

    out = ["*NODE, NSET=NALL"]
    for k in range(2):
        for j in range(nt):
            for i in range(nr + 1):
                r, a = r0 + (r1 - r0) * i / nr, 2 * np.pi * j / nt
                out.append(f"{nid(i, j, k)}, {r * np.cos(a):.13g}, {r * np.sin(a):.13g}, {t * k:.13g}")  # 20 columns
    out.append("*ELEMENT, TYPE=C3D8, ELSET=EALL")
    e = 0
    for j in range(nt):
        for i in range(nr):
            e += 1
            nodes = [nid(i, j, 0), nid(i + 1, j, 0), nid(i + 1, j + 1, 0), nid(i, j + 1, 0),
                     nid(i, j, 1), nid(i + 1, j, 1), nid(i + 1, j + 1, 1), nid(i, j + 1, 1)]
            out.append(", ".join(map(str, [e, *nodes])))
    out += ["*NSET, NSET=FIX", *_ids([nid(0, j, k) for k in range(2) for j in range(nt)]),
            "*NSET, NSET=RIM", str(nid(nr, 0, 1)),
            "*MATERIAL, NAME=STEEL", "*ELASTIC", "2.1e11, 0.3", "*DENSITY", "7850.",
            "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", "*BOUNDARY", "FIX, 1, 3", *steps]
    return "\n".join(out) + "\n"


def test_spinning_disc_body_over_a_speed_range_against_calculix(tmp_path):
    """A disc clamped at its hub, one krylov body built over 0-1200 rad/s about its axis: its lowest eight
    frequencies at five speeds against the full model's (linear prestress, within 1e-3) and against CalculiX's
    ``*FREQUENCY`` after an NLGEOM centrifugal step (within 0.5 %)."""
    import scipy.linalg as sla

    import flexmor
    from flexmor.preload import preload_stiffness

    model = read(_run(tmp_path, "disc", _disc_deck(["*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"]))
                 .with_suffix(".sti"))
    body = flexmor.reduce(model, "krylov", 20, flexmor.make_ports(model, ["RIM:z", "RIM:y"]), spin_range="z:0:1200")
    K2 = np.asarray(body.info["spin"]["K2"])
    for i, w in enumerate(np.linspace(0.0, 1200.0, 5).tolist()):
        load = ["*STEP, NLGEOM", "*STATIC", "*DLOAD", f"EALL, CENTRIF, {w * w!r}, 0., 0., 0., 0., 0., 1.",
                "*END STEP", "*STEP, PERTURBATION"] if w else ["*STEP"]
        ref = dat_frequencies(_run(tmp_path, f"disc{i}", _disc_deck([*load, "*FREQUENCY", "10", "*END STEP"]))
                              .with_suffix(".dat"))[:8]
        Kw = preload_stiffness(model, f"spin:0,0,{w}").K if w else model.K
        full = frequencies_hz(np.sort(eigenmodes(Kw, model.M, 8)[0]))
        mine = frequencies_hz(sla.eigh(body.K + w * w * K2, body.M, eigvals_only=True)[:8])
        assert np.abs(mine / full - 1).max() < 1e-3, (w, mine, full)
        assert np.abs(mine / ref - 1).max() < 0.005, (w, mine, ref)
        if w == 1200.0:
            f0 = frequencies_hz(np.sort(eigenmodes(model.K, model.M, 8)[0]))
            assert full[0] > 1.05 * f0[0]  # the spin stiffens the disc


def test_the_free_c3d20_beams_sid_stiffens_as_its_preload(tmp_path):
    """The free C3D20R beam's Craig-Bampton body (interface FIX): its SID's load stiffening, read back by the plain
    reader of ``tests/sid_check.py``, gives the stiffness of a spin about z equal to the projection of the model
    held at FIX under ``spin:`` (geometric stiffness and spin softening) to 1e-6."""
    import sid_check

    from flexmor.cli import main
    from flexmor.expansion import expand_body
    from flexmor.io import read_body
    from flexmor.linalg import factorize
    from flexmor.preload import geometric_stiffness, preload_load, spin_softening

    text, _ = _deck("C3D20R", "beam", ["*STEP", "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"])
    text = text.replace("*BOUNDARY\nFIX, 1, 3\n", "")  # free
    path = _run(tmp_path, "free", text).with_suffix(".sti")
    model = read(path)
    body, sid = tmp_path / "cb.h5", tmp_path / "cb.SID_FEM"
    assert main([str(a) for a in ("reduce", path, "--method", "craig-bampton", "--order", "40", "--interface",
                                  "FIX@rbe2", "--input", "TIP:y", "--no-error", "-o", body)]) == 0
    assert main([str(a) for a in ("export", body, "--model", path, "-o", sid)]) == 0
    obj = sid_check.taylor_objects(sid)
    V = expand_body(model, read_body(body)).V
    free = np.flatnonzero(~np.isin(model.dofs[:, 0], model.node_sets["FIX"]))
    solve = factorize(model.K[free][:, free].tocsr()).solve
    w = np.array([0.0, 0.0, 400.0])
    u = np.zeros(model.n_dof)
    u[free] = solve(preload_load(model, "spin:0,0,400")[0][free])
    ref = V.T @ ((model.K + geometric_stiffness(model, u) + spin_softening(model, w)) @ V)
    mine = obj["Ke"][0] + 400.0 ** 2 * obj["Oe"][1][:, 2, :]
    assert np.abs(ref - obj["Ke"][0]).max() > 1e-4 * np.abs(ref).max()
    assert np.abs(mine - ref).max() < 1e-6 * np.abs(ref).max()
