"""The load stiffening of SID bodies (:mod:`flexmor.stiffening`): the geometric stiffness of unit frame
accelerations, centrifugal products and forces at the frame nodes, in the ``m1`` terms of ``Ct``, ``Cr``,
``Oe`` and the nodes' ``phi`` and ``psi`` (Schwertassek & Wallrapp 1999, ch. 6). Read back with the plain
reader of ``tests/sid_check.py``, the stiffness a multibody code builds from the file for a spin, a tip
force and gravity equals the projection of ``--preload`` on the same basis and support."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sid_check

from flexmor.cli import main
from flexmor.expansion import expand_body
from flexmor.io import read, read_body
from flexmor.io.invariants import rigid_fields
from flexmor.linalg import factorize
from flexmor.preload import geometric_stiffness, preload_load, preload_stiffness, spin_softening
from flexmor.stiffening import centrifugal_loads

DATA = Path(__file__).parent / "data" / "calculix"
SPINS = ([0.0, 0.0, 300.0], [0.0, 200.0, 0.0], [100.0, 50.0, 30.0])


def _cli(*argv) -> int:
    return main([str(a) for a in argv])


def _products(w) -> np.ndarray:
    return np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])


def _close(A, B) -> float:
    return float(np.abs(A - B).max() / np.abs(B).max())


@pytest.fixture(scope="module")
def clamped_sid(tmp_path_factory):
    d = tmp_path_factory.mktemp("stiff")
    body, sid = d / "c.h5", d / "c.SID_FEM"
    assert _cli("reduce", DATA / "beam8_clamped_mat.sti", "--method", "modal", "--order", "6", "--input", "TIP:y",
                "--no-error", "-o", body) == 0
    assert _cli("export", body, "--model", DATA / "beam8_clamped_mat.sti", "--allow-clamped", "-o", sid) == 0
    return read(DATA / "beam8_clamped_mat.sti"), read_body(body), sid


def test_spin_tip_force_and_gravity_stiffen_the_clamped_body_as_the_preload_does(clamped_sid):
    model, body, sid = clamped_sid
    obj = sid_check.taylor_objects(sid)
    V, Ke = body.V, obj["Ke"][0]
    assert "load stiffening in the m1 of Ct Cr Oe phi psi (stresses supported)" in sid_check.header(sid)[2]
    for w in SPINS:  # centrifugal stiffening and spin softening: Ke + sum_k w_k Oe1_k
        ref = V.T @ (preload_stiffness(model, "spin:{},{},{}".format(*w)).K @ V)
        assert _close(ref, Ke) > 1e-3  # a stiffening the file must carry
        assert _close(Ke + np.einsum("akb,k->ab", obj["Oe"][1], _products(w)), ref) < 1e-6
    (tip,) = [k for k in obj if isinstance(k, tuple) and k[1] == "phi"]  # the TIP set's frame node
    F = 5e5  # phi(q)^T F is a generalized force: the stiffness is -F phi1
    ref = V.T @ (preload_stiffness(model, f"TIP:x={F}").K @ V)
    assert _close(ref, Ke) > 1e-3
    assert _close(Ke - F * obj[tip][1][0], ref) < 1e-6
    g = np.array([0.0, 0.0, -9.81])  # gravity g is the frame accelerating at -g
    ref = V.T @ (preload_stiffness(model, "gravity:0,0,-9.81").K @ V)
    assert _close(Ke + np.einsum("aib,i->ab", obj["Ct"][1], -g), ref) < 1e-6
    assert np.abs(obj["Ct"][1]).max() > 0


def test_the_unit_loads_are_those_whose_generalized_forces_the_file_holds(clamped_sid):
    """The unit loads whose stresses stiffen are the frame's inertia loads: projected on the basis they are
    minus ``Ct`` (translational), ``Cr0`` (angular) and ``Oe0`` (centrifugal) of the file."""
    model, body, sid = clamped_sid
    obj = sid_check.taylor_objects(sid)
    St, Sr, _ = rigid_fields(model)
    V = body.V
    assert _close(-(V.T @ (model.M @ St)), -obj["Ct"][0]) < 1e-9
    assert _close(-(V.T @ (model.M @ Sr)), -obj["Cr"][0]) < 1e-9
    assert _close(V.T @ centrifugal_loads(model), -obj["Oe"][0]) < 1e-9


@pytest.mark.parametrize("interface, order", [("FIX@rbe2", 10), ("FIX", 33)])
def test_a_free_body_stiffens_as_the_model_clamped_at_its_interface(tmp_path, interface, order):
    """A free Craig-Bampton body: the loads' stresses are those of the model held at its interface (the RBE2
    master clamped holds its slaves); the file's spin stiffness equals the preload of the model clamped there."""
    path = DATA / "beam8_free_mat.sti"
    assert _cli("reduce", path, "--method", "craig-bampton", "--order", order, "--interface", interface, "--input",
                "TIP:y", "--no-error", "-o", tmp_path / "f.h5") == 0
    assert _cli("export", tmp_path / "f.h5", "--model", path, "-o", tmp_path / "f.SID_FEM") == 0
    assert f"stresses clamped at {interface.upper()}" in sid_check.header(tmp_path / "f.SID_FEM")[2]
    obj = sid_check.taylor_objects(tmp_path / "f.SID_FEM")
    model = read(path)
    V = expand_body(model, read_body(tmp_path / "f.h5")).V
    free = np.flatnonzero(~np.isin(model.dofs[:, 0], model.node_sets["FIX"]))
    solve = factorize(model.K[free][:, free].tocsr()).solve
    for w in SPINS:
        u = np.zeros(model.n_dof)
        u[free] = solve(preload_load(model, "spin:{},{},{}".format(*w))[0][free])
        ref = V.T @ ((model.K + geometric_stiffness(model, u) + spin_softening(model, w)) @ V)
        assert _close(ref, obj["Ke"][0]) > 1e-4
        assert _close(obj["Ke"][0] + np.einsum("akb,k->ab", obj["Oe"][1], _products(w)), ref) < 1e-6
    nodes = {k[0]: v[1] for k, v in obj.items() if isinstance(k, tuple) and k[1] == "phi"}
    assert len(nodes) == (2 if "@" in interface else 1)
    assert max(np.abs(m).max() for m in nodes.values()) > 0  # the TIP's force stiffens


def test_without_stiffening_the_file_says_so(clamped_sid, tmp_path):
    model, body, _ = clamped_sid
    from flexmor.io.sid import write_sid

    write_sid(body, tmp_path / "n.SID_FEM", model=model, allow_clamped=True, stiffening=False)
    obj = sid_check.taylor_objects(tmp_path / "n.SID_FEM")
    assert not np.any(obj["Ct"][1]) and "no load stiffening" in sid_check.header(tmp_path / "n.SID_FEM")[2]


def test_the_ansys_c3d20r_beam_spins_as_its_preload(tmp_path):
    """The Ansys 20-node hexahedron beam (a real FE export, supported): the file's spin stiffness about two
    axes equals the preload's."""
    pytest.importorskip("ansys.mapdl.reader")
    import flexmor
    from flexmor.io.sid import write_sid

    data = Path(__file__).parent / "data" / "ansys"
    with pytest.warns(Warning):  # the .full file has no checksum
        model = flexmor.io.read(data / "ansys_file.full", coordinates=data / "ansys_HexBeam.cdb")
    body = flexmor.reduce(model, "krylov", 8, flexmor.make_ports(model, ["NCOMP2:y"]))
    write_sid(body, tmp_path / "a.SID_FEM", model=model, allow_clamped=True, nodes=["NCOMP2"])
    obj = sid_check.taylor_objects(tmp_path / "a.SID_FEM")
    for w in ([0.0, 100.0, 0.0], [40.0, 0.0, 20.0]):
        ref = body.V.T @ (preload_stiffness(model, "spin:{},{},{}".format(*w)).K @ body.V)
        assert _close(ref, obj["Ke"][0]) > 1e-3
        assert _close(obj["Ke"][0] + np.einsum("akb,k->ab", obj["Oe"][1], _products(w)), ref) < 1e-6
