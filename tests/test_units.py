"""Unit systems: parsing, and a model read in another system converted to SI (rotational DOFs included)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.damping import Rayleigh, modal_damping
from flexmor.errors import ModelError, OptionError
from flexmor.model import FEModel
from flexmor.units import SYSTEMS, dof_lengths, frf_unit, port_kind, to_si, unit_system


def frame_beam(E, rho, length, b, h, n=6, nu=0.3):
    """A free 3D Euler-Bernoulli beam along x (6 DOF per node), assembled in the units its arguments are in."""
    G = E / (2 * (1 + nu))
    A, Iy, Iz = b * h, b * h**3 / 12, h * b**3 / 12
    J = Iy + Iz
    L = length / n
    k = np.zeros((12, 12))
    m = np.zeros((12, 12))
    ax, tor = [0, 6], [3, 9]
    k[np.ix_(ax, ax)] = E * A / L * np.array([[1, -1], [-1, 1]])
    k[np.ix_(tor, tor)] = G * J / L * np.array([[1, -1], [-1, 1]])
    m[np.ix_(ax, ax)] = rho * A * L / 6 * np.array([[2, 1], [1, 2]])
    m[np.ix_(tor, tor)] = rho * J * L / 6 * np.array([[2, 1], [1, 2]])
    for w, th, EI, sgn in ((1, 5, E * Iz, 1), (2, 4, E * Iy, -1)):  # bending in xy (v, rz) and xz (w, -ry)
        idx = [w, th, w + 6, th + 6]
        S = np.diag([1, sgn, 1, sgn])
        kb = EI / L**3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L**2, -6 * L, 2 * L**2],
                                    [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L**2, -6 * L, 4 * L**2]])
        mb = rho * A * L / 420 * np.array([[156, 22 * L, 54, -13 * L], [22 * L, 4 * L**2, 13 * L, -3 * L**2],
                                           [54, 13 * L, 156, -22 * L], [-13 * L, -3 * L**2, -22 * L, 4 * L**2]])
        k[np.ix_(idx, idx)] = S @ kb @ S
        m[np.ix_(idx, idx)] = S @ mb @ S
    N = 6 * (n + 1)
    K, M = np.zeros((N, N)), np.zeros((N, N))
    for e in range(n):
        s = slice(6 * e, 6 * e + 12)
        K[s, s] += k
        M[s, s] += m
    ids = np.arange(1, n + 2)
    xyz = np.column_stack([np.linspace(0, length, n + 1), np.zeros(n + 1), np.zeros(n + 1)])
    dofs = np.column_stack([np.repeat(ids, 6), np.tile(np.arange(1, 7), n + 1)])
    return FEModel(M=sp.csr_matrix(M), K=sp.csr_matrix(K), node_ids=ids, xyz=xyz, dofs=dofs, name="frame")


STEEL = {"E": 210e9, "rho": 7850.0, "length": 1.2, "b": 0.02, "h": 0.03}


def beam_in(system):
    """The steel beam assembled from its data given in ``system``."""
    s = unit_system(system)
    return frame_beam(STEEL["E"] / s.stress, STEEL["rho"] / s.density, STEEL["length"] / s.length,
                      STEEL["b"] / s.length, STEEL["h"] / s.length)


def rel(A, B):
    return abs(A - B).max() / abs(B).max()


@pytest.mark.parametrize("name", ["mm-t-s", "mm-kg-ms", "mm-g-ms", "in-lbf-s"])
def test_beam_with_rotations_converted_to_si(name):
    ref = beam_in("SI")
    model = beam_in(name)
    assert rel(model.K, ref.K) > 1e-3  # another system: other numbers
    conv = to_si(model, name)
    assert conv.units == name and model.units is None
    # translations, rotations and their coupling entries each by their own factor
    assert rel(conv.K, ref.K) < 1e-12 and rel(conv.M, ref.M) < 1e-12
    rot = ref.dofs[:, 1] > 3
    for A, B in ((conv.K, ref.K), (conv.M, ref.M)):
        for rows in (rot, ~rot):
            for cols in (rot, ~rot):
                a, b = A[rows][:, cols].toarray(), B[rows][:, cols].toarray()
                assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    assert np.allclose(conv.xyz, ref.xyz, rtol=1e-14, atol=0)
    assert (conv.K - conv.K.T).nnz == 0  # exactly symmetric


def test_frequencies_and_rayleigh_in_si():
    from flexmor.linalg.eigen import eigenmodes, frequencies_hz

    s = unit_system("mm-kg-ms")  # time in ms: frequencies of the file are per ms
    model = beam_in(s).with_rayleigh(2e-3, 1e-2)  # alpha 2e-3 1/ms = 2 1/s, beta 1e-2 ms = 1e-5 s
    conv = to_si(model, s)
    assert isinstance(conv.damping, Rayleigh) and np.allclose([conv.damping.alpha, conv.damping.beta], [2.0, 1e-5])
    ref = beam_in("SI").with_rayleigh(2.0, 1e-5)
    assert rel(conv.D, ref.D) < 1e-12
    f_conv = frequencies_hz(eigenmodes(conv.K, conv.M, 12)[0])
    f_ref = frequencies_hz(eigenmodes(ref.K, ref.M, 12)[0])
    assert np.allclose(f_conv[6:], f_ref[6:], rtol=1e-10)
    md = to_si(beam_in(s).with_damping(modal_damping(0.02, (1e-3, 2.0))), s).damping  # band 1 Hz .. 2 kHz
    assert md.zeta == 0.02 and np.allclose(md.band, (1.0, 2000.0))


def test_ports_given_with_the_model():
    model = beam_in("mm-t-s")
    n = model.n_dof
    B = np.zeros((n, 2))
    B[6 + 1, 0], B[6 + 5, 0] = 1.0, 50.0  # a force in y with a lever arm of 50 mm in rz
    B[12 + 3, 1] = 1.0  # a moment about x
    model.B, model.C = sp.csr_matrix(B), sp.csr_matrix(B.T)
    conv = to_si(model, "mm-t-s")
    Bs = conv.B.toarray()
    assert Bs[7, 0] == 1.0 and np.isclose(Bs[11, 0], 0.05) and Bs[15, 1] == 1.0
    assert np.allclose(conv.C.toarray(), Bs.T)


def test_names_and_errors():
    assert unit_system("m-kg-s") is SYSTEMS["SI"] and unit_system("MM-T-S").name == "mm-t-s"
    assert unit_system("mm_kg_ms").name == "mm-kg-ms"
    with pytest.raises(OptionError, match=r"units='mm-ts'.*did you mean 'mm-t-s'\?.*SI, mm-t-s, mm-kg-ms, "
                                          r"mm-g-ms, in-lbf-s") as e:
        unit_system("mm-ts")
    assert e.value.params == ("units",)
    s = SYSTEMS["in-lbf-s"]
    assert np.isclose(s.force, 4.4482216152605) and np.isclose(s.mass, 175.126835) and np.isclose(s.stress, 6894.757,
                                                                                                 rtol=1e-6)
    assert SYSTEMS["mm-kg-ms"].force == pytest.approx(1e3) and SYSTEMS["mm-t-s"].stress == pytest.approx(1e6)
    assert SYSTEMS["mm-t-s"].density == pytest.approx(1e12)
    assert list(dof_lengths([[1, 1], [1, 4]], "mm-t-s")) == [1e-3, 1.0]
    assert port_kind("TIP:y") == "translation" and port_kind("HOLE@rbe3:rx") == "rotation" and port_kind("u1") is None
    assert frf_unit("TIP:y", "TIP:y") == "m/N" and frf_unit("3:rz", "4:rx", "mm-t-s") == "rad/(N mm)"


def test_refusals():
    model = beam_in("mm-t-s")
    conv = to_si(model, "mm-t-s")
    with pytest.raises(ModelError, match="read in mm-t-s already"):
        to_si(conv, "mm-t-s")
    assert to_si(model, None) is model and to_si(model, "SI").K is model.K
    bare = FEModel(M=model.M, K=model.K)
    with pytest.raises(ModelError, match="no equation map"):
        to_si(bare, "mm-t-s")
    assert to_si(bare, "si").units == "SI"


def test_read_with_units():
    from helpers import CCX

    from flexmor.io import read

    ref = read(CCX / "beam8_clamped_mat.sti")
    assert ref.units is None and ref.summary()["units"] is None
    model = read(CCX / "beam8_clamped_mat.sti", units="mm-t-s")  # the numbers taken as N/mm, t, mm
    assert model.units == "mm-t-s"
    assert np.allclose(model.K.data, ref.K.data * 1e3)
    assert np.allclose(model.M.data, ref.M.data * 1e3) and np.allclose(model.xyz, ref.xyz * 1e-3)
    with pytest.raises(OptionError, match="did you mean 'in-lbf-s'"):
        read(CCX / "beam8_clamped_mat.sti", units="in-lb-s")


def test_a_coupled_model_converts_like_its_coupling(tmp_path):
    """An RBE2 master (6 DOF, lever arms in the file's length) coupled in mm-t-s and then converted equals the
    coupling of the converted model: each rotation is scaled by its own factor."""
    from test_cli_units import mm_copy

    from flexmor.couplings import couple
    from flexmor.io import read

    mm = read(mm_copy(tmp_path))
    a = to_si(couple(mm, ["TIP@rbe2"]).model, "mm-t-s")
    b = couple(to_si(mm, "mm-t-s"), ["TIP@rbe2"]).model
    assert (a.dofs[:, 1] > 3).sum() == 3 and np.array_equal(a.dofs, b.dofs)
    assert rel(a.K, b.K) < 1e-12 and rel(a.M, b.M) < 1e-12 and np.allclose(a.xyz, b.xyz, rtol=1e-14, atol=1e-15)
    rot = a.dofs[:, 1] > 3
    for A, B in ((a.K, b.K), (a.M, b.M)):
        x, y = A[rot][:, ~rot].toarray(), B[rot][:, ~rot].toarray()
        assert np.abs(x - y).max() <= 1e-12 * np.abs(y).max()
