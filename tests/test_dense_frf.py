"""The dense small-model path of the full FRF equals the sparse direct sweep.

Tolerance: both paths are backward stable, so each is within ~ eps * cond(K - w^2 M + i w D) of
the exact H (for the modal sum: the eigenvalue error ~ eps lam_max relative to the distance
lam_k - w^2 + i w d_k, the same ratio). cond_1 of the shifted matrices here is 1e4 ... 1e7 (the
static limit below the first mode is lam_max / lam_1), so the two agree to 1e-12 ... 1e-9
relative; each frequency is asserted against its own ``20 eps cond1(A(w))``.
"""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from helpers import DATA, cond1

from flexmor.analysis.compare import FullResponse
from flexmor.dynamics.dense_frf import DenseResolvent
from flexmor.dynamics.frf import ShiftedMatrices, frf_full, rel_error
from flexmor.errors import FlexmorWarning, ModelError
from flexmor.io import read
from flexmor.ports import make_ports
from flexmor.reduction import reduce

EPS = np.finfo(float).eps


def _agree(model, ports, freqs):
    """Dense and sparse H at ``freqs``; asserts the per-frequency tolerance of the module docstring."""
    res = DenseResolvent(model.K, model.M, model.D)
    w = 2 * np.pi * np.asarray(freqs)
    Hd = res.frf(w, ports.B.toarray(), ports.C)
    Hs = frf_full(model, ports, freqs)
    err = rel_error(Hs, Hd)
    S = ShiftedMatrices(model.K, model.M, model.D)
    for k in range(w.size):
        assert err[k] <= 20 * EPS * cond1(S(w[k])), (freqs[k], err[k])
    return res, err


@pytest.fixture(scope="module")
def block():
    return read(DATA / "abaqus" / "blockC3D8.inp")


def test_clamped_rayleigh(clamped):
    model = clamped.with_rayleigh(2.0, 1e-6)
    res, _ = _agree(model, make_ports(model, ["TIP:y", "TIP:z"]), np.geomspace(10.0, 5000.0, 25))
    assert res.kind == "modal" and res.lam.size == model.n_dof


def test_clamped_undamped_between_resonances(clamped):
    res, _ = _agree(clamped, make_ports(clamped, ["TIP:y"]), np.array([3.0, 77.7, 333.3, 1234.5]))
    assert res.kind == "modal"


def test_free_body_rigid_modes(free):
    model = free.with_rayleigh(0.0, 1e-5)
    res, _ = _agree(model, make_ports(model, ["TIP:y", "TIP:x"]), np.geomspace(1.0, 5000.0, 20))
    assert np.sum(np.abs(res.lam) < 1e-3) == 6  # six rigid-body modes kept in the modal sum


def test_abaqus_block(block):
    model = block.with_rayleigh(2.0, 1e-6)
    nodes = model.node_ids
    ports = make_ports(model, [f"{nodes[-1]}:x", f"{nodes[-1]}:z"])
    _agree(model, ports, np.geomspace(100.0, 20000.0, 15))


@pytest.mark.slow
def test_non_proportional_damping(clamped):
    ray = clamped.with_rayleigh(2.0, 1e-6)
    dash = sp.csr_matrix((np.full(3, 50.0), (np.arange(3) + 30, np.arange(3) + 30)), shape=ray.K.shape)
    model = dataclasses.replace(ray, D=(ray.D + dash).tocsr(), damping={"type": "given"})
    res, _ = _agree(model, make_ports(model, ["TIP:y", "TIP:z"]), np.geomspace(10.0, 5000.0, 20))
    assert res.kind == "state-space"


@pytest.mark.slow
def test_singular_mass_falls_back_to_sparse(clamped):
    M = clamped.M.tolil()
    M[5, :] = 0
    M[:, 5] = 0
    with pytest.warns(FlexmorWarning, match="mass matrix diagonal is not positive"):
        model = dataclasses.replace(clamped, M=M.tocsr(), singular_mass_ok=True).with_rayleigh(0.0, 1e-6)
    with pytest.raises(ModelError, match="singular"):
        DenseResolvent(model.K, model.M, model.D)
    ports = make_ports(model, ["TIP:y"])
    fr = FullResponse(model, ports, (50.0, 2000.0), path="dense", cache=False)
    assert fr.grid["path"] == "direct" and fr.n_factorizations == fr.freqs.size


@pytest.mark.slow
def test_full_response_paths_give_same_errors(clamped):
    model = clamped.with_rayleigh(2.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    band = (20.0, 3000.0)
    dense = FullResponse(model, ports, band, cache=False)  # auto: dense at this size
    direct = FullResponse(model, ports, band, path="direct", cache=False)
    assert dense.grid["path"] == "dense" and dense.grid["dense_kind"] == "modal" and dense.n_factorizations == 0
    assert direct.grid["path"] == "direct" and direct.n_factorizations >= direct.freqs.size
    # same H: same refinement decisions (the resonances agree to round-off, so do the points placed there)
    np.testing.assert_allclose(dense.freqs, direct.freqs, rtol=1e-9)
    np.testing.assert_allclose(dense.resonances, direct.resonances, rtol=1e-10)
    red = reduce(model, "modal", 6, ports)
    a, b = dense.evaluate(red), direct.evaluate(red)
    assert a.band_error == pytest.approx(b.band_error, rel=1e-8)
    assert a.max_rel_error == pytest.approx(b.max_rel_error, rel=1e-8)
