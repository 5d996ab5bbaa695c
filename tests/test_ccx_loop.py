"""CalculiX in the loop: small bars meshed here, run through ``ccx``, read back by flexmor.

Each job has an ordinary ``*FREQUENCY`` step (CalculiX's own eigenfrequencies and total mass
``EMAS`` in the ``.dat``) and a ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` step (the ``.sti/.mas/.dof``
flexmor reads); the clamped jobs also a ``*STATIC`` step with a unit tip force. flexmor's
frequencies must agree to 1e-6 (CalculiX prints 7 digits), its total mass to 1e-6, and a
Craig-Bampton body with the loaded node as interface must give CalculiX's static displacement.

Shells (S8R) and beams (B32R) are expanded to C3D20R solids by CalculiX; only the free bodies
are read (constraints on their nodes are refused, see :mod:`flexmor.io.calculix.expanded`).
"""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest
from ccx_models import CCX, NU, E, Mesh, dat_displacement, dat_frequencies, dat_mass, deck, run, solid_elements

from flexmor.io import read
from flexmor.linalg import eigenmodes

pytestmark = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) is not installed; Debian: apt-get install "
                                                    "calculix-ccx (.ci/run installs it in CI)")

SOLIDS = ["C3D8", "C3D20R", "C3D10"]


def _freqs(model, k):
    lam, _ = eigenmodes(model.K, model.M, k)
    return np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)


#: The mesh of the 6 x 2 x 2 bar (the shell's 6 x 2, the beam's 6): cell type, nodes and count.
CELLS = {"C3D8": ("hexahedron", 8, 24), "C3D20R": ("hexahedron20", 20, 24), "C3D10": ("tetra10", 10, 144),
         "S8R": ("quad8", 8, 12), "B32R": ("line3", 3, 6)}


@pytest.mark.parametrize("etype", SOLIDS + ["S8R", "B32R"])
def test_free_frequencies_and_mass(tmp_path, etype, caplog):
    text, _ = deck(etype, clamped=False)
    sti = run(tmp_path, "free", text)
    with pytest.warns(Warning, match="the mass matrix is singular") if etype != "C3D8" else _nothing():
        model = read(sti)
    assert "left out of the mesh" not in caplog.text
    ((cell, nodes),) = [(b.type, b.nodes) for b in model.mesh.blocks]
    assert (cell, *nodes.shape[::-1]) == CELLS[etype]  # every element of the deck, whole
    (block,) = model.elements.blocks
    assert block.type == etype and block.ids.tolist() == list(range(1, CELLS[etype][2] + 1))
    ref = dat_frequencies(sti.with_suffix(".dat"))
    np.testing.assert_allclose(_freqs(model, 10)[6:], ref[6:10], rtol=1e-6)
    assert ref[6] > 1e3 * ref[5]  # 6 rigid modes, then the elastic ones
    ux = (model.dofs[:, 1] == 1).astype(float)
    assert ux @ model.M @ ux == pytest.approx(dat_mass(sti.with_suffix(".dat")), rel=1e-6)
    assert ux @ model.M @ ux == pytest.approx(7850.0 * 0.6 * 0.1 * 0.1, rel=1e-12)
    assert model.node_sets["TIP"].size > 0 and np.allclose(model.node_xyz(model.node_sets["TIP"])[:, 0], 0.6)


@pytest.mark.slow
@pytest.mark.parametrize("etype", SOLIDS)
def test_clamped_frequencies_and_static_response(tmp_path, etype, capsys):
    from flexmor.cli import main
    from flexmor.io import read_body

    _, ids = deck(etype, clamped=True)
    node = int(ids[-1])  # the corner x = L, y = B, z = H
    text, _ = deck(etype, clamped=True, load_node=node, modes=6)
    sti = run(tmp_path, "clamped", text)
    model = read(sti)
    np.testing.assert_allclose(_freqs(model, 6), dat_frequencies(sti.with_suffix(".dat")), rtol=1e-6)
    body = tmp_path / "body.h5"
    assert main(["reduce", str(sti), "--method", "craig-bampton", "--order", "7", "--interface", "LOADED",
                 "--input", f"{node}:z", "--output", f"{node}:x", "--output", f"{node}:y", "--output", f"{node}:z",
                 "-o", str(body), "--no-error", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["order"] == 7
    red = read_body(body)
    u = red.C @ np.linalg.solve(red.K, red.B)[:, 0]
    ref = dat_displacement(sti.with_suffix(".dat"), node)
    np.testing.assert_allclose(u, ref, rtol=1e-6, atol=1e-6 * abs(ref[2]))


def test_quadratic_hexahedra_on_full_lines_have_their_nodes_and_stresses(tmp_path, caplog):
    """The C3D20R deck holds each element as a full line (its number and 15 nodes) and the 5 nodes left on the
    next line, without a comma (CalculiX reads it so): the elements have their 20 nodes, and a linear
    displacement field gives its exact stress in each."""
    from test_stress import _GRAD, _linear_field, _voigt

    from flexmor.elements import Material
    from flexmor.stress import element_stresses

    text, _ = deck("C3D20R", (2, 1, 1), clamped=False, modes=1)
    lines = text.splitlines()
    first = lines[lines.index("*ELEMENT, TYPE=C3D20R, ELSET=EALL") + 1:][:2]
    assert [len(t.split(",")) for t in first] == [16, 5] and not first[0].endswith(",")
    with pytest.warns(Warning, match="the mass matrix is singular"):
        model = read(run(tmp_path, "job", text))
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
    (block,) = model.elements.blocks
    assert block.type == "C3D20R" and block.ids.tolist() == [1, 2]
    assert block.nodes.tolist() == solid_elements(Mesh(2, 1, 1), "C3D20R")
    (field,) = element_stresses(model, _linear_field(model))
    exact = Material.isotropic(E, NU).D @ _voigt(_GRAD)
    np.testing.assert_allclose(field.values, np.broadcast_to(exact, field.values.shape), rtol=1e-9)


def test_clamped_shell_refused(tmp_path):
    from flexmor.errors import ReadError

    text, _ = deck("S8R", clamped=True)
    sti = run(tmp_path, "shell", text)
    with pytest.raises(ReadError, match="expanded shell or beam elements to solids"):
        read(sti)
    sti.with_suffix(".frd").unlink()
    with pytest.raises(ReadError, match=r"shell.inp and shell.frd \(with the expanded nodes"):
        read(sti)


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _with(text: str, extra: list, before: str = "*STEP") -> str:
    lines = text.splitlines()
    k = lines.index(before)
    return "\n".join(lines[:k] + extra + lines[k:]) + "\n"


@pytest.mark.parametrize("case, named", [("rigid body", False), ("spring to ground", False),
                                         ("tie equation", True), ("directional spring", True)])
def test_constraints_and_springs_against_the_stiffness_coordinate_check(tmp_path, case, named):
    """What follows a rigid rotation reads quietly; a tie of u_x between nodes apart or a SPRING2 along x
    between nodes apart does not follow it, and the warning names that cause (they strain a rigid motion)."""
    import warnings

    text, ids = deck("C3D8", (6, 2, 2), clamped=True)
    tip = [int(t) for t in text.split("*NSET, NSET=TIP")[1].split("*")[0].replace(",", " ").split()]
    ref = int(ids.max()) + 1
    extra = {"rigid body": ["*NODE", f"{ref}, 1.0, 0.05, 0.05", f"{ref + 1}, 1.0, 0.05, 0.05",
                            f"*RIGID BODY, NSET=TIP, REF NODE={ref}, ROT NODE={ref + 1}"],
             "spring to ground": ["*ELEMENT, TYPE=SPRING1, ELSET=EG", f"901, {tip[2]}", "*SPRING, ELSET=EG", "2,",
                                  "1.E7,"],
             "tie equation": ["*EQUATION", "2", f"{tip[0]}, 1, 1.0, {tip[1]}, 1, -1.0"],
             "directional spring": ["*ELEMENT, TYPE=SPRING2, ELSET=E2", f"902, {tip[0]}, {tip[3]}",
                                    "*SPRING, ELSET=E2", "1, 1,", "1.E8,"]}[case]
    sti = run(tmp_path, "job", _with(text, extra))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read(sti)
    said = [str(w.message) for w in caught if "node coordinates disagree" in str(w.message)]
    if not named:
        assert said == []
    else:
        assert len(said) == 1 and "a constraint equation or a directional spring" in said[0], said
        assert f"disagree at node {tip[0]}" in said[0] or f"disagree at node {tip[1]}" in said[0] \
            or f"disagree at node {tip[3]}" in said[0], said


def test_axisymmetric_model_is_not_taken_for_another_mesh(tmp_path):
    """CAX4: a radial translation strains the hoop, so no rigid motion is free; the stiffness-coordinate
    check is skipped (this ring's rotation ratios are ~1.2e-2, with translation ratios of ~5e-4: it was read
    as "another mesh" when only a median translation ratio above 1e-2 skipped the check)."""
    import warnings

    from flexmor.io._geometry import TRANSLATION_ROUNDING, geometry_residual

    nx, ny = 4, 8
    nid = lambda i, j: j * (nx + 1) + i + 1  # noqa: E731
    lines = ["*NODE, NSET=NALL"] + [f"{nid(i, j)}, {1.0 + 0.2 * i / nx:.12g}, {0.5 * j / ny:.12g}, 0"
                                    for j in range(ny + 1) for i in range(nx + 1)]
    lines += ["*ELEMENT, TYPE=CAX4, ELSET=EALL"]
    lines += [f"{1 + i + nx * j}, {nid(i, j)}, {nid(i + 1, j)}, {nid(i + 1, j + 1)}, {nid(i, j + 1)}"
              for j in range(ny) for i in range(nx)]
    lines += ["*NSET, NSET=FIX"] + [str(nid(i, 0)) for i in range(nx + 1)]
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", "2.1e11, 0.3", "*DENSITY", "7850",
              "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", "*BOUNDARY", "FIX, 1, 2", "*STEP",
              "*FREQUENCY, SOLVER=MATRIXSTORAGE", "*END STEP"]
    sti = run(tmp_path, "cax", "\n".join(lines) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = read(sti)
    assert not [w for w in caught if "node coordinates disagree" in str(w.message)]
    translation, rotation, _ = geometry_residual(model)
    assert 1e-4 < np.nanmedian(translation) < 1e-2 and np.nanmedian(translation) > TRANSLATION_ROUNDING  # skipped
    assert np.nanmedian(rotation) > 1e-2  # what it would have said


@pytest.mark.parametrize("etype", ["C3D8", "C3D20R", "C3D10"])
@pytest.mark.parametrize("dirs", ["1, 1", "3, 3", "1, 2"])
def test_supports_of_some_directions_are_no_changed_value(tmp_path, etype, dirs):
    """A face held in one or two directions leaves equations beside it that do not sum to zero in those
    directions alone, alike along the face: no stiffness entry is named, and the mass stays alike in x, y, z
    where both nodes have the direction."""
    import warnings

    text, _ = deck(etype, (6, 2, 2), clamped=False)
    sti = run(tmp_path, "job", _with(text, ["*BOUNDARY", f"FIX, {dirs}"]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = read(sti)
    said = [str(w.message) for w in caught if "stiffness entry" in str(w.message) or "x, y and z" in str(w.message)
            or "two directions of motion" in str(w.message)]
    assert said == []
    from flexmor.io._mass import direction_mismatches
    assert direction_mismatches(model.M, model.dofs) == []
    assert model.n_dof < 3 * model.n_nodes  # the support removed equations
