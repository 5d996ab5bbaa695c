"""A Craig-Bampton superelement (boundary grids + modal SPOINTs) from OP4 or DMIG, read as a reduced body.

The superelement is the clamped CalculiX beam reduced to its tip face (CB with 12
fixed-interface modes, computed here with NumPy); some tip grids use a cylindrical
displacement system. The body read back must reproduce the full model's static compliance at
the tip DOFs exactly and its lowest eigenfrequencies closely.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from op4_writer import write_ascii, write_binary

from flexmor.errors import ReadError
from flexmor.io import read_body, write_body
from flexmor.io.nastran import read_superelement

N_MODES = 12
SPOINT0 = 1001


def _cb(model, n_modes=N_MODES):
    tip = model.node_sets["TIP"]
    b = np.flatnonzero(np.isin(model.dofs[:, 0], tip))
    b = b[np.lexsort((model.dofs[b, 1], model.dofs[b, 0]))]  # Nastran a-set order: grid, component
    i = np.setdiff1d(np.arange(model.n_dof), b)
    K, M = model.K.toarray(), model.M.toarray()
    Phi = -np.linalg.solve(K[np.ix_(i, i)], K[np.ix_(i, b)])
    lam, Psi = sla.eigh(K[np.ix_(i, i)], M[np.ix_(i, i)], subset_by_index=[0, n_modes - 1])
    T = np.zeros((model.n_dof, b.size + n_modes))
    T[b, :b.size] = np.eye(b.size)
    T[np.ix_(i, np.arange(b.size))] = Phi
    T[i, b.size:] = Psi
    return b, T.T @ K @ T, T.T @ M @ T, lam


def _cyl_frame(x):
    t = np.arctan2(x[2], x[1])  # cylindrical system about the beam axis x: CORD2C with z = basic x
    er = np.array([0.0, np.cos(t), np.sin(t)])
    et = np.array([0.0, -np.sin(t), np.cos(t)])
    return np.column_stack([er, et, [1.0, 0, 0]])


def _files(tmp_path, model, fmt):
    b, Kr, Mr, lam = _cb(model)
    tip = np.unique(model.dofs[b, 0])
    local = set(tip[::2].tolist())  # every other tip grid in CD=7
    nb = b.size
    T = np.eye(nb + N_MODES)
    for g in model.dofs[b, 0]:
        if g in local:
            Q = _cyl_frame(model.node_xyz([g])[0] - np.array([0.0, 0.05, 0.05]))
            rows = [j for j in range(nb) if model.dofs[b[j], 0] == g]
            T[np.ix_(rows, rows)] = Q[np.ix_([r - 1 for r in model.dofs[b[rows], 1]], [0, 1, 2])]
    Kl, Ml = T.T @ Kr @ T, T.T @ Mr @ T  # in the CD systems
    bulk = ["CORD2C,7,,0.,.05,.05,1.,.05,.05,", ",0.,1.,.05"]
    for g in tip:
        x = model.node_xyz([g])[0]
        bulk.append(f"GRID,{g},," + ",".join(repr(float(v)) for v in x) + (",7" if g in local else ""))
    bulk += [f"ASET1,123,{g}" for g in tip]
    bulk += [f"SPOINT,{SPOINT0},THRU,{SPOINT0 + N_MODES - 1}", f"QSET1,0,{SPOINT0},THRU,{SPOINT0 + N_MODES - 1}"]
    (tmp_path / "se.bdf").write_text("\n".join(bulk) + "\n")
    if fmt == "binary":
        write_binary(tmp_path / "se.op4", {"KAA": Kl, "MAA": Ml}, sparse=True)
    elif fmt == "ascii":
        write_ascii(tmp_path / "se.op4", {"KAA": Kl, "MAA": Ml})
    else:
        dofs = [(int(g), int(d)) for g, d in model.dofs[b]] + [(SPOINT0 + k, 0) for k in range(N_MODES)]
        lines = []
        for name, A in (("KAAX", Kl), ("MAAX", Ml)):
            lines.append(f"DMIG,{name},0,6,2,0,,{len(dofs)}")
            for j, (gj, cj) in enumerate(dofs):
                lines.append(f"DMIG,{name},{gj},{cj}")
                lines += [f",{gi},{ci},{float(A[i, j])!r}" for i, (gi, ci) in enumerate(dofs) if i <= j and A[i, j]]
        if fmt == "dmig-inline":  # EXTSEOUT style: GRIDs in the punch file, and a K4AX beside KAAX
            k4 = [ln.replace("KAAX", "K4AX") for ln in lines if "KAAX" in ln]
            (tmp_path / "se.pch").write_text("\n".join(bulk[:2 + len(tip)] + lines + k4) + "\n")
        else:
            (tmp_path / "se.pch").write_text("\n".join(lines) + "\n")
            (tmp_path / "se.bdf").write_text("\n".join(bulk[:2 + len(tip)]) + "\n")  # grids only
    return b, lam


@pytest.mark.parametrize("fmt", ["binary", "ascii", "dmig", "dmig-inline"])
def test_craig_bampton_superelement(tmp_path, clamped, clamped_ref, fmt):
    b, lam = _files(tmp_path, clamped, fmt)
    red = read_superelement(tmp_path / ("se.pch" if fmt.startswith("dmig") else "se.op4"))
    assert red.order == b.size + N_MODES and red.info["n_boundary"] == b.size and red.info["n_modal"] == N_MODES
    assert red.input_names[:4] == [f"{clamped.dofs[b[0], 0]}:x", f"{clamped.dofs[b[0], 0]}:y",
                                   f"{clamped.dofs[b[0], 0]}:z", f"{clamped.dofs[b[1 + 2], 0]}:x"]
    np.testing.assert_allclose(red.info["fixed_interface_hz"], np.sqrt(lam) / (2 * np.pi), rtol=1e-9)
    assert red.info["kbq_rel"] < 1e-9
    # static compliance at the tip DOFs (basic x y z) equals the full model's
    G = red.C @ np.linalg.solve(red.K, red.B)
    full = np.linalg.inv(clamped.K.toarray())[np.ix_(b, b)]
    np.testing.assert_allclose(G, full, rtol=1e-7, atol=1e-9 * abs(full).max())
    f = red.frequencies_hz()
    np.testing.assert_allclose(f[:4], clamped_ref[:4], rtol=1e-3)  # CB with 12 modes: 2.3e-4 off at 608 Hz
    np.testing.assert_allclose(red.xyz, clamped.node_xyz(red.node_ids), atol=1e-12)
    assert red.info["matrices"]["K"] == ("KAAX" if fmt.startswith("dmig") else "KAA")
    write_body(red, tmp_path / "se.h5")
    back = read_body(tmp_path / "se.h5")
    np.testing.assert_allclose(back.frequencies_hz(), f, rtol=1e-12)


def test_superelement_errors(tmp_path, clamped):
    _files(tmp_path, clamped, "binary")
    bdf = tmp_path / "se.bdf"
    text = bdf.read_text()
    bdf.write_text(text.replace(f"THRU,{SPOINT0 + N_MODES - 1}", f"THRU,{SPOINT0 + N_MODES - 2}"))
    with pytest.raises(ReadError, match="give .* a-set DOFs, but the matrices have"):
        read_superelement(tmp_path / "se.op4")
    bdf.unlink()
    with pytest.raises(ReadError, match="needs the bulk data"):
        read_superelement(tmp_path / "se.op4")
    bdf.write_text(text + "SEQGP,1,5\n")
    with pytest.raises(ReadError, match="SEQGP cards resequence"):
        read_superelement(tmp_path / "se.op4")
    bdf.write_text(text)
    write_binary(tmp_path / "se.op4", {"KAA": np.eye(3), "MAA": np.eye(4)})
    with pytest.raises(ReadError, match=r"the matrices KAA \(3, 3\), MAA \(4, 4\) differ in size"):
        read_superelement(tmp_path / "se.op4")


def test_cli_compare_and_export_superelement(tmp_path, clamped, capsys):
    """The superelement is evaluated against the full model at its boundary DOFs, and exported."""
    import json

    import scipy.io
    from helpers import CLAMPED

    from flexmor.cli import main

    b, _ = _files(tmp_path, clamped, "binary")
    se = str(tmp_path / "se.op4")
    assert main(["compare", CLAMPED, se, "--band", "10:300", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["results"][0]
    assert row["method"] == "craig-bampton" and row["order"] == b.size + N_MODES
    assert row["band_error"] < 1e-4 and row["max_rel_error"] < 1e-2
    assert main(["export", se, "-o", str(tmp_path / "se.mat"), "--json"]) == 0
    m = scipy.io.loadmat(tmp_path / "se.mat")
    np.testing.assert_allclose(m["Kr"], read_superelement(se).K, rtol=1e-12)


@pytest.mark.parametrize("fmt", ["ascii", "binary"])
def test_extseout_null_damping(tmp_path, free, free_ref, fmt):
    """EXTSEOUT-style output: KXX/MXX (46, 46) beside a 1 x 1 null BXX1 ("no damping") and a
    null K4XX; the boundary grids, SPOINTs and a-set in the input deck (.dat) beside it.

    The superelement is the free-free CalculiX beam reduced to its 9 tip grids (27 boundary
    DOFs) and 19 fixed-interface modes: 6 rigid modes, then the beam's elastic modes.
    """
    n_modes = 19
    b, Kr, Mr, _ = _cb(free, n_modes)
    assert Kr.shape == (46, 46)
    tip = np.unique(free.dofs[b, 0])
    deck = ["SOL 103", "CEND", "EXTSEOUT(ASMBULK,EXTID=100,DMIGOP4=30)", "METHOD = 10", "BEGIN BULK",
            "EIGRL,10,,,20", "MAT1,1,2.1+11,,.3,7850.", "PSOLID,1,1"]
    for g, x in zip(free.node_ids, free.xyz):
        deck.append(f"GRID,{g},," + ",".join(f"{v:.6g}" for v in x))
    deck += [f"ASET1,123,{g}" for g in tip]
    deck += [f"SPOINT,{SPOINT0},THRU,{SPOINT0 + n_modes - 1}", f"QSET1,0,{SPOINT0},THRU,{SPOINT0 + n_modes - 1}",
             "ENDDATA"]
    (tmp_path / "se.dat").write_text("\n".join(deck) + "\n")
    mats = {"KXX": Kr, "MXX": Mr, "BXX1": np.zeros((1, 1)), "K4XX": np.zeros((1, 1))}
    (write_ascii if fmt == "ascii" else write_binary)(tmp_path / "se.op4", mats)
    red = read_superelement(tmp_path / "se.op4")
    assert red.D is None and red.damping.to_dict() == {"type": "none"}
    assert red.info["matrices"] == {"K": "KXX", "M": "MXX"}
    assert red.info["n_boundary"] == 27 and red.info["n_modal"] == n_modes
    np.testing.assert_array_equal(red.node_ids, tip)
    np.testing.assert_allclose(red.xyz, free.node_xyz(tip), atol=1e-9)
    f = red.frequencies_hz()
    np.testing.assert_allclose(f, np.sqrt(np.clip(sla.eigh(Kr, Mr, eigvals_only=True), 0, None)) / (2 * np.pi),
                               rtol=1e-8, atol=1e-3)
    assert np.all(f[:6] < 1e-2 * f[6])  # 6 rigid modes
    np.testing.assert_allclose(f[6:10], free_ref[6:10], rtol=2e-3)  # 620.67 Hz (x2), ... of CalculiX
    # the same matrices read as an FE model (without the deck): zero damping, not "differ in size"
    from flexmor.io.nastran import read_nastran

    (tmp_path / "se.dat").unlink()
    model = read_nastran(tmp_path / "se.op4")
    assert model.D is None and model.n_dof == 46
