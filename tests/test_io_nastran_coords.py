"""Nastran grids in local coordinate systems (CP for positions, CD for displacements).

The CalculiX beam is written as DMIG + bulk data with every grid placed in one of seven
systems (CORD2R/C/S chained through RID, CORD1R/C/S on grid points) and its matrices
expressed in another: read back, positions and eigenfrequencies must be those of the beam.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import flexmor.io
from flexmor.errors import PortError, ReadError
from flexmor.io.nastran import cards, read_bulk

# -- an independent statement of the Nastran definitions ------------------------------------


def _cyl2rect(c):
    r, t, z = c[0], np.radians(c[1]), c[2]
    return np.array([r * np.cos(t), r * np.sin(t), z])


def _sph2rect(c):
    r, t, p = c[0], np.radians(c[1]), np.radians(c[2])
    return np.array([r * np.sin(t) * np.cos(p), r * np.sin(t) * np.sin(p), r * np.cos(t)])


def _rect2(kind, x):
    if kind == "R":
        return x
    if kind == "C":
        return np.array([np.hypot(x[0], x[1]), np.degrees(np.arctan2(x[1], x[0])), x[2]])
    r = np.linalg.norm(x)
    return np.array([r, np.degrees(np.arccos(x[2] / r)), np.degrees(np.arctan2(x[1], x[0]))])


def _from_abc(a, b, c):
    z = (b - a) / np.linalg.norm(b - a)
    y = np.cross(z, c - a)
    y /= np.linalg.norm(y)
    return a, np.column_stack([np.cross(y, z), y, z])


class _Sys:
    def __init__(self, kind, origin, R):
        self.kind, self.o, self.R = kind, origin, R

    def to_basic(self, c):
        x = {"R": np.asarray(c, float), "C": _cyl2rect(c), "S": _sph2rect(c)}[self.kind]
        return self.o + self.R @ x

    def from_basic(self, p):
        return _rect2(self.kind, self.R.T @ (p - self.o))

    def dirs(self, p):
        x = self.R.T @ (p - self.o)
        if self.kind == "R":
            return self.R
        t = np.arctan2(x[1], x[0])
        if self.kind == "C":
            e = np.array([[np.cos(t), np.sin(t), 0], [-np.sin(t), np.cos(t), 0], [0, 0, 1.0]]).T
        else:
            th = np.arccos(x[2] / np.linalg.norm(x))
            e = np.array([[np.sin(th) * np.cos(t), np.sin(th) * np.sin(t), np.cos(th)],
                          [np.cos(th) * np.cos(t), np.cos(th) * np.sin(t), -np.sin(th)],
                          [-np.sin(t), np.cos(t), 0.0]]).T
        return self.R @ e


A1, B1, C1 = np.array([0.3, -0.2, 0.1]), np.array([0.3, 0.5, 0.8]), np.array([1.0, 0.0, 0.0])
P2 = np.array([[0.1, 0.2, -0.3], [0.4, -0.5, 0.9], [1.2, 0.7, 0.1]])  # in system 1 (rectangular)
P3 = np.array([[0.5, 30.0, 0.2], [0.8, 75.0, -0.4], [1.1, 200.0, 0.3]])  # in system 2 (cylindrical)
G1 = (11, 40, 90)  # grids defining CORD1R 4 / CORD1C 5 / CORD1S 6 (permuted)


def _systems(nodes, xyz):
    s = {0: _Sys("R", np.zeros(3), np.eye(3))}
    s[1] = _Sys("R", *_from_abc(A1, B1, C1))
    s[2] = _Sys("C", *_from_abc(*(s[1].to_basic(p) for p in P2)))
    s[3] = _Sys("S", *_from_abc(*(s[2].to_basic(p) for p in P3)))
    pos = {int(n): x for n, x in zip(nodes, xyz)}
    g = [pos[k] for k in G1]
    s[4] = _Sys("R", *_from_abc(g[0], g[1], g[2]))
    s[5] = _Sys("C", *_from_abc(g[1], g[2], g[0]))
    s[6] = _Sys("S", *_from_abc(g[2], g[0], g[1]))
    return s


def _small(*fields):
    return "".join(f"{f!s:<8}"[:8] for f in fields)


def _write(tmp_path, model, *, drop=None):
    """DMIG in the CD systems (free field) + bulk: CORD cards in small field with markers, GRIDs mixed."""
    nodes, xyz = model.node_ids, model.xyz
    s = _systems(nodes, xyz)
    cp = {int(n): int(k % 5) for k, n in enumerate(nodes)}  # CP 0..4 (4 = CORD1R on grids)
    cd = {int(n): int((k * 5 + 3) % 7) for k, n in enumerate(nodes)}  # CD 0..6
    for g in G1:
        cp[g] = 0  # the grids of CORD1 are given in basic (they could be in CORD2 systems too)
    bulk = ["SOL 103", "CEND", "BEGIN BULK", "$ systems",
            _small("CORD2R", 1, "", *A1, *B1) + "+C1",
            _small("+C1", *C1),
            _small("CORD2C", 2, 1, *P2[0], *P2[1]) + "+C2",
            _small("+C2", *P2[2]),
            "CORD2S,3,2," + ",".join(map(str, P3[:2].ravel())) + ",+C3",
            "+C3," + ",".join(map(str, P3[2])),
            _small("CORD1R", 4, *G1),
            _small("CORD1C", 5, G1[1], G1[2], G1[0], ""),
            "CORD1S,6," + ",".join(str(G1[k]) for k in (2, 0, 1))]
    for k, (n, p) in enumerate(zip(nodes, xyz)):
        c = s[cp[int(n)]].from_basic(p)
        if k % 2:
            bulk.append(f"GRID*   {n:>16}{cp[int(n)]:>16}{c[0]:>16.9E}{c[1]:>16.9E}*G{n}")
            bulk.append(f"*G{n:<6}{c[2]:>16.9E}{cd[int(n)]:>16}")
        else:
            bulk.append(f"GRID,{n},{cp[int(n)]}," + ",".join(repr(float(v)) for v in c) + f",{cd[int(n)]}")
    bulk.append("ENDDATA")
    (tmp_path / "beam.bdf").write_text("\n".join(bulk) + "\n")
    n = model.n_dof
    T = np.zeros((n, n))  # q_basic = T q_local
    pos = {int(a): p for a, p in zip(nodes, xyz)}
    for i, (g, d) in enumerate(model.dofs):
        Q = s[cd[int(g)]].dirs(pos[int(g)])
        for j, (g2, d2) in enumerate(model.dofs):
            if g2 == g:
                T[i, j] = Q[d - 1, d2 - 1]
    lines = []
    keep = np.ones(n, bool) if drop is None else ~np.all(model.dofs == drop, axis=1)
    for name, A in (("KAAX", model.K.toarray()), ("MAAX", model.M.toarray())):
        L = T.T @ A @ T
        lines.append(f"DMIG,{name},0,6,2,0,,{n}")
        for j in np.flatnonzero(keep):
            lines.append(f"DMIG,{name},{model.dofs[j, 0]},{model.dofs[j, 1]}")
            lines += [f",{model.dofs[i, 0]},{model.dofs[i, 1]},{float(L[i, j])!r}" for i in np.flatnonzero(keep)
                      if i <= j and L[i, j] != 0.0]
    (tmp_path / "beam.pch").write_text("\n".join(lines) + "\n")
    return s, cd, T


def test_grids_in_local_systems_give_the_beam(tmp_path, clamped, clamped_ref):
    s, cd, _ = _write(tmp_path, clamped)
    b = read_bulk(tmp_path / "beam.bdf")
    np.testing.assert_array_equal(b.grid_ids, np.sort(clamped.node_ids))
    order = np.argsort(clamped.node_ids)
    np.testing.assert_allclose(b.xyz, clamped.xyz[order], atol=1e-9)
    for cid in range(1, 7):
        np.testing.assert_allclose(b.systems[cid].R, s[cid].R, atol=1e-12)
        np.testing.assert_allclose(b.systems[cid].origin, s[cid].o, atol=1e-12)
    assert sorted(set(cd.values())) == list(range(7))

    model = flexmor.io.read(tmp_path / "beam.pch")
    np.testing.assert_allclose(model.node_xyz(clamped.node_ids), clamped.xyz, atol=1e-9)
    perm = [clamped.dof_index(*d) for d in model.dofs]
    K0 = clamped.K.toarray()[np.ix_(perm, perm)]
    assert abs(model.K.toarray() - K0).max() < 1e-9 * abs(K0).max()  # rotated back to basic x y z
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True, subset_by_index=[0, 5])
    np.testing.assert_allclose(np.sqrt(w) / (2 * np.pi), clamped_ref[:6], rtol=1e-5)

    local = flexmor.io.read(tmp_path / "beam.pch", directions="local")
    assert set(local.node_frames) == {int(g) for g, c in cd.items() if c}
    g = next(iter(local.node_frames))
    np.testing.assert_allclose(local.node_frames[g], s[cd[g]].dirs(clamped.node_xyz([g])[0]), atol=1e-9)
    wl = sla.eigh(local.K.toarray(), local.M.toarray(), eigvals_only=True, subset_by_index=[0, 5])
    np.testing.assert_allclose(wl, w, rtol=1e-9)
    assert abs(local.K - model.K).max() > 1e-3 * abs(K0).max()  # really different equations
    with pytest.raises(PortError, match="local displacement"):
        from flexmor.couplings import couple

        couple(local, ["TIP@rbe2"]) if "TIP" in local.node_sets else couple(local, [f"{g}@rbe2"])


def test_incomplete_local_triplet(tmp_path, clamped):
    _, cd, _ = _write(tmp_path, clamped)
    g = next(int(n) for n in clamped.dofs[:, 0] if cd[int(n)] == 2)
    _write(tmp_path, clamped, drop=(g, 3))
    with pytest.raises(ReadError, match=f"grid {g}: components 3 of its displacement system CD=2.*directions='local'"):
        flexmor.io.read(tmp_path / "beam.pch")
    local = flexmor.io.read(tmp_path / "beam.pch", directions="local")
    assert local.n_dof == clamped.n_dof - 1


def test_field_formats(tmp_path):
    p = tmp_path / "f.bdf"
    p.write_text("\n".join([
        "$ comment",
        "GRID           1       0      1.      2.      3.",
        f"{'GRID*':<8}{2:>16}{0:>16}{'1.5-3':>16}{'-2.5D+1':>16}*A",
        f"{'*A':<8}{'7.0':>16}{0:>16}",
        "GRID,3,,.5,1.+2,-3.,\t",
        "GRID\t4\t\t1.0\t2.0\t3.0",
        "GRDSET,,,,,,0",
        "GRID,5,,1.,2.,3.,,,,+G5",
        "+G5",
        "SPOINT,101,THRU,103,107",
        "ASET1,123,1,THRU,2",
        "QSET1,0,101,THRU,103",
        "ENDDATA",
        "GRID,99,,0.,0.,0.",
    ]) + "\n")
    b = read_bulk(p)
    np.testing.assert_array_equal(b.grid_ids, [1, 2, 3, 4, 5])
    np.testing.assert_allclose(b.xyz, [[1, 2, 3], [1.5e-3, -25.0, 7.0], [0.5, 100.0, -3.0], [1, 2, 3], [1, 2, 3]])
    np.testing.assert_array_equal(b.spoints, [101, 102, 103, 107])
    assert b.aset == [(1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3), (101, 0), (102, 0), (103, 0)]
    names = [c[2] for c in cards(p)]
    assert names.count("GRID") == 5


@pytest.mark.parametrize("text, line, words", [
    ("GRID,1,7,0.,0.,0.\n", 1, "CP=7 is not defined"),
    ("GRID,1,,0.,0.,0.,7\n", 1, "CD=7 is not defined"),
    ("CORD2R,1,2,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\nCORD2R,2,1,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\n", 1, "depends on itself"),
    ("CORD2R,1,0,0.,0.,0.,0.,0.,1.\n,0.,0.,2.\n", 1, "collinear"),
    ("CORD1R,1,5,6,7\nGRID,5,,0.,0.,0.\n", 1, "grid 6 is not defined"),
    ("GRID,1,,0.,0.,0.\nGRID,1,,1.,0.,0.\n", 2, "defined twice"),
    ("GRID,1,,0.,x,0.\n", 1, "malformed field"),
    ("GRID,1,,0.,nan,0.\n", 1, "malformed field"),
    ("INCLUDE 'missing.bdf'\n", 1, "not found"),
])
def test_bad_bulk(tmp_path, text, line, words):
    p = tmp_path / "b.bdf"
    p.write_text(text)
    with pytest.raises(ReadError, match=words) as exc:
        read_bulk(p)
    assert f"b.bdf:{line}:" in str(exc.value)


def test_include(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "g.bdf").write_text("GRID,2,1,1.,90.,0.\n")
    (tmp_path / "main.bdf").write_text("BEGIN BULK\nCORD2C,1,,0.,0.,0.,0.,0.,1.,\n,1.,0.,0.\n"
                                       "INCLUDE 'sub/g.bdf'\nENDDATA\n")
    b = read_bulk(tmp_path / "main.bdf")
    np.testing.assert_allclose(b.xyz, [[0.0, 1.0, 0.0]], atol=1e-15)


def test_fluid_grid_and_grdset_defaults(tmp_path):
    p = tmp_path / "g.bdf"
    p.write_text("CORD2R,5,,1.,0.,0.,1.,0.,1.,\n,2.,0.,0.\nGRDSET,,5,,,,5\nGRID,1,,1.,2.,3.,-1\nGRID,2,,0.,0.,0.\n"
                 "GRID,3,0,0.,0.,0.,0\n")
    b = read_bulk(p)
    np.testing.assert_array_equal(b.cd, [0, 5, 0])  # -1 (fluid) has no displacement system; GRDSET CD=5
    np.testing.assert_allclose(b.xyz, [[2.0, 2.0, 3.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # GRDSET CP=5


def test_six_dof_grids_rotations_rotated_too(tmp_path):
    """Grids with 6 DOFs (shells, beams) in a cylindrical CD system: rotations use the same frame."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((12, 12))
    K = A @ A.T + 12 * np.eye(12)
    (tmp_path / "s.bdf").write_text("CORD2C,3,,0.,0.,0.,1.,1.,1.,\n,1.,0.,0.\n"
                                    "GRID,1,,0.5,0.2,0.1,3\nGRID,2,3,0.7,30.,0.4,3\n")
    b = read_bulk(tmp_path / "s.bdf")
    T = np.zeros((12, 12))
    for k, g in enumerate((1, 2)):
        Q = b.frame(g)
        T[6 * k:6 * k + 3, 6 * k:6 * k + 3] = Q
        T[6 * k + 3:6 * k + 6, 6 * k + 3:6 * k + 6] = Q
    np.testing.assert_allclose(T.T @ T, np.eye(12), atol=1e-14)
    L = T.T @ K @ T
    dofs = [(g, c) for g in (1, 2) for c in range(1, 7)]
    lines = []
    for name, X in (("KAAX", L), ("MAAX", np.eye(12))):
        lines.append(f"DMIG,{name},0,6,2,0,,12")
        for j, (gj, cj) in enumerate(dofs):
            lines.append(f"DMIG,{name},{gj},{cj}")
            lines += [f",{gi},{ci},{float(X[i, j])!r}" for i, (gi, ci) in enumerate(dofs) if i <= j and X[i, j]]
    (tmp_path / "s.pch").write_text("\n".join(lines) + "\n")
    model = flexmor.io.read(tmp_path / "s.pch")
    np.testing.assert_allclose(model.K.toarray(), K, rtol=1e-12, atol=1e-12 * abs(K).max())
    np.testing.assert_allclose(model.M.toarray(), np.eye(12), atol=1e-14)
    e_r = b.xyz[0] - b.systems[3].origin
    e_r -= (e_r @ b.systems[3].R[:, 2]) * b.systems[3].R[:, 2]
    np.testing.assert_allclose(b.frame(1)[:, 0], e_r / np.linalg.norm(e_r), atol=1e-12)  # radial direction
