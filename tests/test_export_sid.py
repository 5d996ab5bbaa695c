"""SID export: inertia invariants against analytic values and direct integration, file round trip,
the two sample files of ../shared/data/sid."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import DATA

from flexmor.errors import ModelError, PortError, ReadError
from flexmor.io.invariants import compute_invariants, node_triples, rigid_fields
from flexmor.io.sid import read_sid, sid_from_reduced, write_sid
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce

SID_DATA = DATA / "sid"
L, W, H, RHO = 1.0, 0.1, 0.1, 7850.0


@pytest.fixture(scope="module")
def block():
    """Free-free steel block 1 x 0.1 x 0.1 m of 10x2x2 trilinear hexahedra, consistent mass."""
    return cantilever(divisions=(10, 2, 2), clamped=False)


@pytest.fixture(scope="module")
def modal(block):
    red = reduce(block, "modal", 6, make_ports(block, ["TIP_CENTER:y"]))
    return red


def test_rigid_invariants_equal_the_analytic_block(block):
    inv = compute_invariants(block, np.zeros((block.n_dof, 0)))
    m = RHO * L * W * H
    assert inv.mass == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(inv.center_of_mass, [L / 2, W / 2, H / 2], rtol=1e-12)
    Jc = m / 12 * np.diag([W**2 + H**2, L**2 + H**2, L**2 + W**2])
    np.testing.assert_allclose(inv.inertia_about_com(), Jc, rtol=0, atol=1e-10 * Jc.max())
    # about the origin (corner): parallel axes, off-diagonal -m c_i c_j
    c = np.array([L, W, H]) / 2
    np.testing.assert_allclose(inv.J0, Jc + m * (c @ c * np.eye(3) - np.outer(c, c)), atol=1e-10 * Jc.max())


def test_mass_normalized_modes_give_unit_Me_and_omega2_Ke(block, modal):
    inv = compute_invariants(block, modal.V, K=modal.K)
    np.testing.assert_allclose(inv.Me, np.eye(6), atol=1e-10)
    w2 = (2 * np.pi * np.array(modal.info["frequencies_hz"])) ** 2
    np.testing.assert_allclose(inv.Ke, np.diag(w2), atol=1e-10 * w2.max())
    assert 620.672 == pytest.approx(np.sqrt(w2[0]) / 2 / np.pi, abs=1e-3)  # CalculiX: 620.672 Hz
    # free-free modes are M-orthogonal to rigid motion: no coupling
    assert np.abs(inv.Ct).max() < 1e-9 and np.abs(inv.Cr0).max() < 1e-9


def test_first_order_invariants_match_direct_integration(block, modal):
    """J(q), Cr(q) of the deformed body and the Coriolis/centrifugal forces, integrated directly."""
    V, r = modal.V, modal.order
    inv = compute_invariants(block, V)
    rng = np.random.default_rng(1)
    q, qd, w = 1e-4 * rng.standard_normal(r), rng.standard_normal(r), rng.standard_normal(3)
    trans, rot = node_triples(block)

    def nodal(vec):
        return np.stack([vec[trans[:, d]] for d in range(3)], axis=1)

    def field(x):
        f = np.zeros(block.n_dof)
        for d in range(3):
            f[trans[:, d]] = x[:, d]
        return f

    def J_of(qq):
        _, S, _ = rigid_fields(dataclasses.replace(block, xyz=block.xyz + nodal(V @ qq)))
        return S.T @ (block.M @ S), S

    (Jp, Sr), (Jm, _) = J_of(q), J_of(-q)
    dJ = np.einsum("aij,a->ij", inv.J1, q)  # J is quadratic in q: the central difference is exact
    np.testing.assert_allclose((Jp - Jm) / 2, dJ, atol=1e-9 * np.abs(dJ).max())
    pos = block.xyz + nodal(V @ q)
    Cr = V.T @ (block.M @ Sr)
    np.testing.assert_allclose(Cr, inv.Cr0 + np.einsum("abk,b->ak", inv.Cr1, q), atol=1e-10 * np.abs(Cr).max())
    # centrifugal: ∫ Φ_a·(ω×(ω×(r+u))) dm = Oe(q) [ωx² ωy² ωz² ωxωy ωyωz ωxωz]
    Q = V.T @ (block.M @ field(np.cross(w, np.cross(w, pos))))
    om = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[1] * w[2], w[0] * w[2]])
    np.testing.assert_allclose((inv.Oe0 + np.einsum("abc,b->ac", inv.Oe1, q)) @ om, Q, atol=1e-10 * np.abs(Q).max())
    # Coriolis on the modes: 2 ∫ Φ_a·(ω×u') dm = Σ_b Ge_b[a, :] ω q'_b
    vel = nodal(V @ qd)
    Qc = V.T @ (block.M @ field(2 * np.cross(w, vel)))
    np.testing.assert_allclose(np.einsum("abk,b,k->a", inv.Ge.reshape(r, r, 3), qd, w), Qc,
                               atol=1e-10 * np.abs(Qc).max())
    # and on the frame rotation: ∫ r × (2 ω×u') dm = Σ_a Gr_a q'_a ω
    _, Sr0, _ = rigid_fields(block)
    T = Sr0.T @ (block.M @ field(2 * np.cross(w, vel)))
    np.testing.assert_allclose(np.einsum("kal,a,l->k", inv.Gr.reshape(3, r, 3), qd, w), T, atol=1e-10 * np.abs(T).max())


@pytest.mark.parametrize("order", ["row-q-col", "row-col-q"])
def test_sid_round_trip_is_exact(tmp_path, block, modal, order):
    path = tmp_path / "body.SID_FEM"
    write_sid(modal, path, model=block, nodes=["TIP_CENTER", "TIP", "1"], m1_order=order)
    ref = sid_from_reduced(modal, block, nodes=["TIP_CENTER", "TIP", "1"])
    got = read_sid(path)  # order detected from the index ranges
    assert got.mass == ref.mass and [n.id for n in got.nodes] == [65, 100, 1]
    for name, t in ref.objects.items():
        assert np.array_equal(got.objects[name].m0, t.m0), name
        assert (t.m1 is None) == (got.objects[name].m1 is None) and (t.m1 is None or np.array_equal(
            got.objects[name].m1, t.m1)), name
    for a, b in zip(ref.nodes, got.nodes):
        for name in ("origin", "phi", "psi", "AP"):
            assert np.array_equal(getattr(a, name).m0, getattr(b, name).m0)
    np.testing.assert_allclose(got.ielastq_hz(), modal.frequencies_hz(), atol=1e-3)
    # the RBE3 node TIP: the mean tip translation of mode 1 at the origin's first-order term
    tip = block.node_sets["TIP"]
    uy = np.mean([modal.V[block.dof_index(n, 2), 0] for n in tip])
    assert got.nodes[1].origin.m1[1, 0, 0] == pytest.approx(uy, rel=1e-12)


def test_default_frame_nodes_are_the_ports(block, modal):
    sid = sid_from_reduced(modal, block)
    assert [n.id for n in sid.nodes] == [block.node_sets["TIP_CENTER"][0]]


def test_errors(tmp_path, block, modal):
    with pytest.raises(ModelError, match="given as model"):
        write_sid(modal, tmp_path / "x.SID_FEM")
    with pytest.raises(PortError, match="no nodes for the SID frame"):
        write_sid(dataclasses.replace(modal, input_names=["u1"], output_names=["y1"]), tmp_path / "x.SID_FEM",
                  model=block)
    with pytest.raises(ModelError, match="equations"):
        write_sid(modal, tmp_path / "x.SID_FEM", model=cantilever(divisions=(4, 1, 1), clamped=False))
    assert not list(tmp_path.iterdir())  # nothing half-written


@pytest.mark.parametrize("name, nq, nodes", [("Beam_3m", 4, 21), ("balken1m", 1, 3)])
def test_sample_files_read_and_reproduce_their_frequencies(name, nq, nodes):
    sid = read_sid(SID_DATA / f"{name}.SID_FEM")
    assert sid.nq == nq and len(sid.nodes) == nodes
    np.testing.assert_allclose(sid.frequencies_hz(), sid.ielastq_hz(), atol=6e-4)
    # Fortran D exponents and the m1(row, q, col) order: J's first-order term of q2 in Beam_3m
    if name == "Beam_3m":
        assert sid.mass == 706.5
        assert sid.objects["J"].m1[0, 0, 1] == pytest.approx(-1.15784568669)
        assert sid.objects["Cr"].m1[0, 0, 1] == pytest.approx(-9.99695683434e-01)  # m1(1,2,1): row 1, q 2, col 1
        assert sid.objects["Me"].structure == 4 and np.array_equal(sid.objects["Me"].m0, np.eye(4))


def test_truncated_file_names_the_line(tmp_path):
    text = (SID_DATA / "balken1m.SID_FEM").read_text().splitlines()
    bad = tmp_path / "bad.SID_FEM"
    bad.write_text("\n".join(text[:40] + ["                          m0( 1, 1)  = 1.0Q+00"]))
    with pytest.raises(ReadError, match=r"bad.SID_FEM:41: not a number"):
        read_sid(bad)
