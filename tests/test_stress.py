"""Stress recovery without CalculiX: patch tests (a linear displacement field gives its exact constant
stress in every element type), materials and sections read from the decks, and the refusals."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import CCX as CCX_DATA
from helpers import DATA
from test_stress_ccx import _LINEAR, _cells

import flexmor.io
from flexmor.elements import ElementBlock, Elements, Material
from flexmor.errors import ModelError
from flexmor.model import FEModel
from flexmor.stress import element_strains, element_stresses, nodal_stresses, von_mises

_GRAD = np.array([[1.0, 0.4, -0.3], [0.2, -0.7, 0.5], [-0.6, 0.1, 0.9]]) * 1e-3  # du_i / dx_j


def _voigt(grad):
    """Engineering strains xx yy zz xy yz zx of a displacement gradient."""
    return np.array([grad[0, 0], grad[1, 1], grad[2, 2], grad[0, 1] + grad[1, 0], grad[1, 2] + grad[2, 1],
                     grad[2, 0] + grad[0, 2]])


def _grid_model(etype, material=None) -> FEModel:
    """A model of the distorted 3 x 2 x 2 bar meshed with ``etype``; unit matrices (the stresses need none)."""
    cells = _cells(etype)
    pts = sorted({tuple(int(x) for x in p) for e in cells for p in e})
    nid = {p: i + 1 for i, p in enumerate(pts)}
    xyz = np.array(pts, float) / 2 * [0.1, 0.1, 0.08]
    xyz += np.random.default_rng(3).uniform(-0.003, 0.003, xyz.shape)
    nodes = np.array([[nid[tuple(int(x) for x in p)] for p in e] for e in cells])
    ids = np.arange(1, len(pts) + 1)
    dofs = np.column_stack([np.repeat(ids, 3), np.tile([1, 2, 3], ids.size)])
    mats = (material,) if material is not None else ()
    block = ElementBlock(etype, np.arange(1, len(cells) + 1), nodes,
                         np.zeros(len(cells), np.int64) if material is not None else None)
    return FEModel(M=sp.eye(dofs.shape[0]), K=sp.eye(dofs.shape[0]), node_ids=ids, xyz=xyz, dofs=dofs,
                   elements=Elements((block,), mats, "grid.inp"), source="grid.inp")


def _linear_field(model, grad=_GRAD):
    x = model.node_xyz(model.dofs[:, 0])
    return np.einsum("ij,nj->ni", grad, x)[np.arange(model.n_dof), model.dofs[:, 1] - 1]


@pytest.mark.parametrize("etype", list(_LINEAR))
def test_linear_field_gives_its_exact_stress(etype):
    steel = Material.isotropic(210e3, 0.3, 7.85e-9, "STEEL")
    model = _grid_model(etype, steel)
    u = _linear_field(model)
    exact = steel.D @ _voigt(_GRAD)
    (field,) = element_stresses(model, u)
    np.testing.assert_allclose(field.values, np.broadcast_to(exact, field.values.shape), rtol=0, atol=1e-10 * 250)
    (strain,) = element_strains(model, u)
    eps = _voigt(_GRAD) * [1, 1, 1, 0.5, 0.5, 0.5]
    np.testing.assert_allclose(strain.values, np.broadcast_to(eps, strain.values.shape), atol=1e-15)
    # CalculiX's extrapolation coefficients are rounded (2.549 ...): a constant field comes back to 1e-4
    nodal = nodal_stresses(model, np.column_stack([u, 2 * u]))
    assert nodal.values.shape == (2, model.n_nodes, 6)
    np.testing.assert_allclose(nodal.values[1], 2 * nodal.values[0], rtol=1e-12)
    np.testing.assert_allclose(nodal.values[0], np.broadcast_to(exact, (model.n_nodes, 6)), rtol=0,
                               atol=1e-4 * np.abs(exact).max())
    some = model.node_ids[::7]
    part = nodal_stresses(model, u, nodes=some)
    np.testing.assert_array_equal(part.node_ids, some)
    np.testing.assert_allclose(part.values, nodal.values[0][::7], rtol=1e-13, atol=1e-9)


def test_material_argument_replaces_the_deck_and_is_needed_without_one():
    model = _grid_model("C3D10")
    u = _linear_field(model)
    with pytest.raises(ModelError, match=r"grid\.inp: 72 C3D10 element\(s\) have no elastic constants .*"
                                         r"pass material=\(E, nu\[, rho\]\)") as info:
        nodal_stresses(model, u)
    assert info.value.params == ("material",)
    (a,) = element_stresses(model, u, material=(70e3, 0.33))
    (b,) = element_stresses(model, u, material=Material.isotropic(140e3, 0.33))
    np.testing.assert_allclose(b.values, 2 * a.values, rtol=1e-12)
    with pytest.raises(ModelError, match=r"material must be \(E, nu\[, rho\]\), got 4 numbers"):
        element_stresses(model, u, material=(1, 2, 3, 4))
    with pytest.raises(ModelError, match=r"Poisson's ratio must lie in \(-1, 0.5\), got 0.5"):
        element_stresses(model, u, material=(70e3, 0.5))


def test_refusals_name_the_problem():
    steel = Material.isotropic(210e3, 0.3)
    model = _grid_model("C3D8", steel)
    shells = Elements((ElementBlock("S4", [1], [model.node_ids[:4]], [0]),), (steel,), "plate.inp")
    with pytest.raises(ModelError, match=r"plate\.inp: stresses of S4 elements are not recovered \(shell elements"):
        nodal_stresses(dataclasses.replace(model, elements=shells), np.zeros(model.n_dof))
    with pytest.raises(ModelError, match=r"u must have 108 rows"):
        nodal_stresses(model, np.zeros(5))
    with pytest.raises(ModelError, match=r"node 99999 is in no solid element"):
        nodal_stresses(model, np.zeros(model.n_dof), nodes=[99999])
    bare = dataclasses.replace(model, elements=None)
    with pytest.raises(ModelError, match=r"grid\.inp: the model has no elements"):
        element_stresses(bare, np.zeros(model.n_dof))
    aniso = Elements(model.elements.blocks, (Material("RUBBER", unsupported="*ELASTIC, TYPE=ANISO (x.inp:3) is "
                                                                            "not evaluated"),), "x.inp")
    with pytest.raises(ModelError, match=r"x\.inp: \*ELASTIC, TYPE=ANISO \(x\.inp:3\) is not evaluated; pass material"):
        element_stresses(dataclasses.replace(model, elements=aniso), np.zeros(model.n_dof))


def test_von_mises():
    s = np.array([[100.0, 0, 0, 0, 0, 0], [0, 0, 0, 50.0, 0, 0], [10.0, 10.0, 10.0, 0, 0, 0]])
    np.testing.assert_allclose(von_mises(s), [100.0, 50.0 * np.sqrt(3), 0.0], atol=1e-12)
    with pytest.raises(ModelError, match="6 components"):
        von_mises(np.zeros((3, 5)))


def test_engineering_constants_of_an_isotropic_material():
    E, nu = 200e3, 0.25
    G = E / (2 * (1 + nu))
    a = Material.engineering_constants(E, E, E, nu, nu, nu, G, G, G)
    np.testing.assert_allclose(a.D, Material.isotropic(E, nu).D, rtol=1e-12, atol=1e-9)
    with pytest.raises(ModelError, match="no positive definite compliance"):
        Material.engineering_constants(E, E, E, 0.9, 0.9, 0.9, G, G, G)


# -- the decks -------------------------------------------------------------------------------------
def _beam(tmp_path, edit=None):
    """The free C3D8 beam export, its deck edited by ``edit(text) -> text``."""
    for suf in (".sti", ".mas", ".dof", ".inp"):
        shutil.copy(CCX_DATA / f"beam8_free_mat{suf}", tmp_path / f"beam{suf}")
    inp = tmp_path / "beam.inp"
    if edit:
        inp.write_text(edit(inp.read_text()))
    return tmp_path / "beam.sti"


def test_calculix_deck_material_gives_the_patch_stress(tmp_path):
    model = flexmor.io.read(_beam(tmp_path))
    (block,) = model.elements.blocks
    assert block.type == "C3D8" and block.ids.size == 40 and (block.material == 0).all()
    (steel,) = model.elements.materials
    assert steel.name == "STEEL" and steel.rho == pytest.approx(7850.0)
    np.testing.assert_allclose(steel.D, Material.isotropic(2.1e11, 0.3).D, rtol=1e-12)
    (field,) = element_stresses(model, _linear_field(model))
    exact = steel.D @ _voigt(_GRAD)
    np.testing.assert_allclose(field.values, np.broadcast_to(exact, field.values.shape), rtol=1e-9)


def test_calculix_element_sets_and_material_kinds(tmp_path):
    def edit(text):
        text = text.replace("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL",
                            "*ELSET, ELSET=FRONT, GENERATE\n1, 10\n*ELSET, ELSET=BACK\nFRONT, 11, 12\n"
                            "*ELSET, ELSET=REST, GENERATE\n13, 40\n"
                            "*SOLID SECTION, ELSET=BACK, MATERIAL=ORTHO\n"
                            "*SOLID SECTION, ELSET=REST, MATERIAL=HOT")
        return text + ("*MATERIAL, NAME=ORTHO\n*ELASTIC, TYPE=ORTHO\n"
                       "1e11, 2e10, 9e10, 3e10, 2.5e10, 8e10, 4e10, 3e10,\n2e10\n"
                       "*MATERIAL, NAME=HOT\n*ELASTIC\n2.1e11, 0.3, 20.\n2.0e11, 0.3, 200.\n")
    model = flexmor.io.read(_beam(tmp_path, edit))
    (block,) = model.elements.blocks
    names = [m.name for m in model.elements.materials]
    assert names == ["ORTHO", "HOT"]
    np.testing.assert_array_equal(block.material, [0] * 12 + [1] * 28)
    ortho, hot = model.elements.materials
    assert ortho.D[0, 0] == 1e11 and ortho.D[0, 1] == 2e10 and ortho.D[2, 2] == 8e10 and ortho.D[5, 5] == 3e10
    assert hot.D is None and "temperature-dependent *ELASTIC (beam.inp:" in hot.unsupported
    with pytest.raises(ModelError, match=r"beam\.inp: temperature-dependent \*ELASTIC \(beam\.inp:\d+\) is not "
                                         r"evaluated; pass material"):
        nodal_stresses(model, np.zeros(model.n_dof))
    nodal_stresses(model, np.zeros(model.n_dof), material=(2.1e11, 0.3))  # the argument replaces them


def test_calculix_deck_without_section(tmp_path):
    model = flexmor.io.read(_beam(tmp_path, lambda t: t.replace("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n", "")))
    with pytest.raises(ModelError, match=r"beam\.inp: 40 C3D8 element\(s\) have no elastic constants \(first: "
                                         r"element 1\); pass material=\(E, nu\[, rho\]\)"):
        nodal_stresses(model, np.zeros(model.n_dof))


def test_ansys_archive_materials_and_patch_stress(tmp_path):
    pytest.importorskip("ansys.mapdl.reader")
    ansys = DATA / "ansys"
    text = (ansys / "ansys_HexBeam.cdb").read_text()
    model = flexmor.io.read(ansys / "ansys_file.full", coordinates=ansys / "ansys_HexBeam.cdb")
    (block,) = model.elements.blocks
    assert block.type == "C3D20R" and block.ids.size == 40
    (mat,) = model.elements.materials
    np.testing.assert_allclose(mat.D, Material.isotropic(7e10, 0.35).D, rtol=1e-12)
    assert mat.rho == 2700.0
    # away from the clamped face (its displacements are not equations), a linear field's exact stress
    u = _linear_field(model)
    (field,) = element_stresses(model, u)
    free = ~np.isin(block.nodes, model.constrained_dofs[:, 0]).any(axis=1)
    assert free.sum() == 36
    exact = mat.D @ _voigt(_GRAD)
    np.testing.assert_allclose(field.values[free], np.broadcast_to(exact, field.values[free].shape), rtol=1e-9)
    # the MP command form, and a material that is not isotropic refused
    mp = text.replace("MPDATA,R5.0, 1,EX  ,       1, 1, 7.000000000E+10,", "MP,EX,1,1.4e11")
    (tmp_path / "beam.cdb").write_text(mp)
    model = flexmor.io.read(ansys / "ansys_file.full", coordinates=tmp_path / "beam.cdb")
    np.testing.assert_allclose(model.elements.materials[0].D, Material.isotropic(1.4e11, 0.35).D, rtol=1e-12)
    (tmp_path / "beam.cdb").write_text(mp + "MP,EY,1,2e11\n")
    model = flexmor.io.read(ansys / "ansys_file.full", coordinates=tmp_path / "beam.cdb")
    with pytest.raises(ModelError, match=r"beam\.cdb: MAT 1 \(beam\.cdb:\d+\) is temperature-dependent or "
                                         "orthotropic"):
        nodal_stresses(model, u)


@pytest.mark.parametrize("etype", ["C3D8", "C3D10"])
def test_abaqus_deck_material_gives_the_patch_stress(etype):
    model = flexmor.io.read(DATA / "abaqus" / f"block{etype}.inp")
    (block,) = model.elements.blocks
    assert block.type == etype and (block.material == 0).all()
    (steel,) = model.elements.materials
    assert steel.name == "STEEL" and steel.rho == 2900.0
    np.testing.assert_allclose(steel.D, Material.isotropic(2e11, 0.3).D, rtol=1e-12)
    (field,) = element_stresses(model, _linear_field(model))
    exact = steel.D @ _voigt(_GRAD)
    np.testing.assert_allclose(field.values, np.broadcast_to(exact, field.values.shape), rtol=1e-9)


# -- stress modes of a reduced body (reduce --stress) ----------------------------------------------
def test_reduce_stores_stress_modes_and_exports_them(tmp_path, capsys):
    from helpers import run

    from flexmor.io import export, read_body
    from flexmor.stress import nodal_strains

    sti = _beam(tmp_path)
    h5 = tmp_path / "beam.h5"
    code, _, err = run(capsys, "reduce", sti, "--method", "modal", "--order", "8", "--input", "1:z",
                       "--no-error", "--no-mounted", "--stress", "-o", h5)
    assert code == 0, err
    body = read_body(h5)
    model = flexmor.io.read(sti)
    assert body.stress_modes.shape == (8, 90, 6) and body.info["stress"]["nodes"] == "surface"
    interior = np.setdiff1d(model.node_ids, body.stress_nodes)
    assert interior.size == 9 and np.all(np.isin(body.stress_nodes, model.node_ids))
    ref = nodal_stresses(model, body.V, nodes=body.stress_nodes)
    np.testing.assert_allclose(body.stress_modes, ref.values, rtol=1e-12, atol=1e-12 * np.abs(ref.values).max())
    assert np.abs(body.stress_modes).max() > 1e3  # modes of a steel beam in Pa
    assert nodal_strains(model, body.V[:, 0]).values.shape == (model.n_nodes, 6)

    # the .vtu: stress_k and mises_k of each mode (V phi), NaN inside
    pytest.importorskip("meshio")
    import meshio

    vtu = tmp_path / "beam.vtu"
    export(body, vtu, model=model)
    grid = meshio.read(vtu)
    ids = grid.point_data["node_id"]
    s1 = grid.point_data["stress_1"]
    mode1 = nodal_stresses(model, grid_mode := _vtu_mode(grid, model, 1))
    row = {int(n): i for i, n in enumerate(mode1.node_ids)}
    on = np.isin(ids, body.stress_nodes)
    np.testing.assert_allclose(s1[on], mode1.values[[row[int(n)] for n in ids[on]]], rtol=1e-6,
                               atol=1e-6 * np.abs(mode1.values).max())
    assert np.isnan(s1[~on]).all() and (~on).sum() == 9 and grid_mode.shape == (model.n_dof,)
    np.testing.assert_allclose(grid.point_data["mises_1"][on], von_mises(s1[on]), rtol=1e-12)
    # ... and the fields of the body's coordinates q (its basis vectors), which the h5/SID/Exudyn files use:
    # stress_basis_j are the body's stress modes, mode_k = sum_j basis_j eigenvectors[j, k]
    E = np.asarray(grid.field_data["eigenvectors"]).reshape(8, 8)
    pos = {int(n): i for i, n in enumerate(body.stress_nodes)}
    for j in (0, 5):
        sb = grid.point_data[f"stress_basis_{j + 1}"]
        np.testing.assert_allclose(sb[on], body.stress_modes[j][[pos[int(n)] for n in ids[on]]], rtol=1e-12,
                                   atol=1e-12 * np.abs(body.stress_modes).max())
    basis = np.stack([grid.point_data[f"basis_{j + 1}"] for j in range(8)], axis=-1)
    np.testing.assert_allclose(basis @ E[:, 2], grid.point_data["mode_3"], rtol=1e-9,
                               atol=1e-9 * np.abs(grid.point_data["mode_3"]).max())

    # the .mat file
    import scipy.io

    export(body, tmp_path / "beam.mat", model=model)
    data = scipy.io.loadmat(tmp_path / "beam.mat")
    assert data["stress_modes"].shape == (8, 90, 6) and data["stress_nodes"].shape == (90, 1)


def _vtu_mode(grid, model, k):
    """The displacement of mode ``k`` as the .vtu holds it, over the model's equations."""
    row = {int(n): i for i, n in enumerate(grid.point_data["node_id"])}
    disp = grid.point_data[f"mode_{k}"]
    return disp[[row[int(n)] for n in model.dofs[:, 0]], model.dofs[:, 1] - 1]


def test_reduce_stress_needs_a_material(tmp_path, capsys):
    from helpers import run

    from flexmor.io import read_body

    sti = _beam(tmp_path, lambda t: t.replace("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n", ""))
    args = ("reduce", sti, "--method", "modal", "--order", "4", "--input", "1:z", "--no-error", "--no-mounted",
            "--stress", "--stress-nodes", "TIP")
    code, _, err = run(capsys, *args, "-o", tmp_path / "a.h5")
    assert code != 0 and "beam.inp: 40 C3D8 element(s) have no elastic constants" in err and "--material" in err
    code, _, err = run(capsys, *args, "--material", "2.1e11,0.3", "-o", tmp_path / "b.h5")
    assert code == 0, err
    body = read_body(tmp_path / "b.h5")
    assert body.info["stress"]["material"] == [2.1e11, 0.3] and body.stress_nodes.size == 9
    with pytest.raises(SystemExit):
        run(capsys, *args, "--material", "2.1e11", "-o", tmp_path / "c.h5")
    assert "argument --material: '2.1e11' is not E,NU or E,NU,RHO" in capsys.readouterr().err


def test_defective_material_keywords_do_not_stop_the_reading(tmp_path):
    sti = _beam(tmp_path, lambda t: t.replace("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL",
                                              "*SOLID SECTION, ELSET=NOWHERE, MATERIAL=STEEL"))
    model = flexmor.io.read(sti)  # reads and reduces as before
    assert model.n_dof == 297
    with pytest.raises(ModelError, match=r"beam\.inp: .*beam\.inp:\d+: section refers to element set NOWHERE, which "
                                         r"the deck does not define; pass material"):
        nodal_stresses(model, np.zeros(model.n_dof))
    nodal_stresses(model, np.zeros(model.n_dof), material=(2.1e11, 0.3))


def test_nastran_properties_and_materials(tmp_path):
    from flexmor.io.nastran import read_bulk
    from flexmor.io.nastran.nastran_elements import nastran_elements

    grids = [f"GRID,{i + 1},,{x},{y},{z}" for i, (x, y, z) in enumerate(_HEX_XYZ)]
    cards = ["CHEXA,1,10,1,2,3,4,5,6,+", "+,7,8", "CHEXA,2,20,1,2,3,4,5,6,+", "+,7,8",
             "CTETRA,3,30,1,2,3,5", "CQUAD4,4,40,1,2,3,4",
             "PSOLID,10,1", "PSOLID,20,2", "PSOLID,30,9", "PSHELL,40,1,0.01",
             "MAT1,1,200000.,80000.,,7.8e-9", "MAT8,2,1.,1.,0.3,1.,1.,1."]
    (tmp_path / "b.bdf").write_text("\n".join(grids + cards) + "\n")
    els = nastran_elements(read_bulk(tmp_path / "b.bdf"), tmp_path / "b.bdf")
    types = {b.type: b for b in els.blocks}
    assert set(types) == {"C3D8", "C3D4", "CQUAD4"}
    mats = els.materials
    assert [m.name for m in mats] == ["MAT 1", "MAT 2", "MAT 9"]
    np.testing.assert_allclose(mats[0].D, Material.isotropic(200000.0, 0.25).D, rtol=1e-12)  # nu = E / 2G - 1
    assert mats[0].rho == 7.8e-9
    assert "MAT8 2 (b.bdf:" in mats[1].unsupported and "MID 9 is not defined" in mats[2].unsupported
    np.testing.assert_array_equal(types["C3D8"].material, [0, 1])
    np.testing.assert_array_equal(types["C3D4"].material, [2])
    np.testing.assert_array_equal(types["CQUAD4"].material, [0])


_HEX_XYZ = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]


def test_exudyn_stress_modes(tmp_path, capsys):
    from helpers import run

    from flexmor.io import read_body
    from flexmor.io.exudyn import exudyn_data

    sti = _beam(tmp_path)
    h5 = tmp_path / "free.h5"
    code, _, err = run(capsys, "reduce", sti, "--method", "modal", "--order", "10", "--input", "1:z",
                       "--no-error", "--no-mounted", "--stress", "--stress-nodes", "all", "-o", h5)
    assert code == 0, err
    body, model = read_body(h5), flexmor.io.read(sti)
    data = exudyn_data(body, model)
    X = data["postProcessingModes"]["matrix"]
    assert data["postProcessingModes"]["outputVariableType"] == "OutputVariableType.StressLocal"
    assert X.shape == (model.n_nodes, 6 * body.order)
    row = {int(n): i for i, n in enumerate(data["nodeIds"])}
    k, j = int(body.stress_nodes[5]), 3  # basis vector 3 at one node: xx yy zz yz xz xy
    np.testing.assert_array_equal(X[row[k], 6 * j:6 * j + 6], body.stress_modes[j, 5][[0, 1, 2, 4, 5, 3]])
    exu = pytest.importorskip("exudyn")
    from flexmor.io.exudyn import add_to_exudyn

    mbs = exu.SystemContainer().AddSystem()
    res = add_to_exudyn(mbs, body, model)
    assert mbs.GetObjectParameter(res["oFFRFreducedOrder"], "outputVariableModeBasis").shape == X.shape


def test_elements_converted_to_other_units():
    steel = Material.isotropic(210e3, 0.3, 7.85e-9, "STEEL")  # N/mm^2 and t/mm^3
    els = Elements((ElementBlock("C3D4", [1], [[1, 2, 3, 4]], [0]),), (steel, Material("X", unsupported="why")), "a")
    si = els.converted(1e6, 1e12)
    np.testing.assert_allclose(si.materials[0].D, Material.isotropic(210e9, 0.3).D, rtol=1e-14)
    assert si.materials[0].rho == pytest.approx(7850.0) and si.materials[1].unsupported == "why"


def test_report_states_the_largest_von_mises_stress_of_its_time_responses(tmp_path, capsys):
    """A unit tip force step on the clamped beam: the report's peak von Mises stress of the Krylov body
    (over time and nodes) is the full model's, integrated the same way and recovered at every node, to
    the body's error; it sits at the clamped root. (Order 16: the basis serves the frame's six inertia loads
    too; at order 8 the peak was 2.4 % off.)"""
    from helpers import CLAMPED, run_json

    from flexmor.dynamics.time import simulate, step
    from flexmor.ports import Ports

    run_json(capsys, "reduce", CLAMPED, "--method", "krylov", "--order", "16", "--input", "TIP:y", "--rayleigh",
             "0:1e-6", "--band", "10:3000", "--stress", "--stress-nodes", "all", "-o", tmp_path / "k.h5")
    rec = run_json(capsys, "report", CLAMPED, tmp_path / "k.h5", "--rayleigh", "0:1e-6", "--modes", "4",
                   "-o", tmp_path / "r.html")
    peak = rec["results"][0]["max_mises"]
    model = flexmor.io.read(CLAMPED).with_rayleigh(0.0, 1e-6)
    B = flexmor.make_ports(model, ["TIP:y"]).B
    everywhere = Ports.from_arrays(B, sp.identity(model.n_dof, format="csr"))
    q = simulate(model, step(), dt=rec["time"]["dt"], t_end=rec["time"]["t_end"], ports=everywhere)
    vm = von_mises(nodal_stresses(model, q.displacement[:, :, 0].T).values)  # (steps, nodes)
    assert peak["mises"] == pytest.approx(vm.max(), rel=1e-2)
    assert model.node_xyz(np.array([peak["node"]]))[0, 0] == 0.0  # at the clamped root
    html = (tmp_path / "r.html").read_text()
    assert peak["input"] == "TIP:y" and "largest von Mises stress of the time responses" in html
    assert "no unit system named" in html  # read as given: no Pa claimed



def test_sid_frame_nodes_carry_their_modal_stresses(tmp_path, capsys):
    from helpers import CLAMPED, run_json

    from flexmor.io.sid import read_sid

    run_json(capsys, "reduce", CLAMPED, "--units", "SI", "--method", "modal", "--order", "6", "--input", "TIP:y",
             "--no-error", "--stress", "-o", tmp_path / "m.h5")
    body = flexmor.io.read_body(tmp_path / "m.h5")
    node = int(body.stress_nodes[len(body.stress_nodes) // 2])
    run_json(capsys, "export", tmp_path / "m.h5", "--model", CLAMPED, "--node", str(node), "--allow-clamped",
             "-o", tmp_path / "m.SID_FEM")
    sid = read_sid(tmp_path / "m.SID_FEM")
    nd = next(n for n in sid.nodes if n.id == node)
    want = body.stress_modes[:, list(body.stress_nodes).index(node), :].T  # (6, r)
    assert nd.sigma is not None and nd.sigma.m1.shape == (6, 1, 6)
    np.testing.assert_allclose(nd.sigma.m1[:, 0, :], want, rtol=1e-15, atol=1e-15 * np.abs(want).max())
    assert not np.any(nd.sigma.m0)
    run_json(capsys, "export", tmp_path / "m.h5", "--model", CLAMPED, "--node", str(node), "--allow-clamped",
             "--export-units", "mm-t-s", "-o", tmp_path / "mm.SID_FEM")
    mm = next(n for n in read_sid(tmp_path / "mm.SID_FEM").nodes if n.id == node)
    np.testing.assert_allclose(mm.sigma.m1, 1e-6 * nd.sigma.m1, rtol=1e-14)  # Pa -> MPa (N/mm^2)


def test_remove_rigid_keeps_the_stress_modes(free):
    """A free body with rigid motion in its basis and stress modes, exported with remove_rigid: its new basis
    (I - Φ Φᵀ M) V T carries the stress modes S T (rigid motion has none); they were dropped (Exudyn's
    postProcessingModes {}, the SID without sigma). They equal the stresses recovered from the new basis."""
    import warnings

    from flexmor.errors import FlexmorWarning
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce
    from flexmor.rigid import elastic_body
    from flexmor.stress import body_stresses

    red = reduce(free, "krylov", 16, make_ports(free, ["TIP:y"]), rigid="include")
    out = body_stresses(free, red, nodes="all")
    red.stress_nodes, red.stress_modes = out.node_ids, out.values
    assert red.info["n_rigid_included"] > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FlexmorWarning)
        el = elastic_body(free, red, remove_rigid=True)
    assert el.order < red.order and el.stress_modes.shape == (el.order, red.stress_nodes.size, 6)
    direct = nodal_stresses(free, el.V, nodes=red.stress_nodes).values
    assert direct.shape == el.stress_modes.shape
    assert np.abs(el.stress_modes - direct).max() <= 1e-8 * np.abs(direct).max()
