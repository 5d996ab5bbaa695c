"""The solves of the Gramian quadrature: dense modal form and verified surrogate against direct solves."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.analysis.compare import FullResponse
from flexmor.errors import OptionError
from flexmor.model import FEModel
from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction.gramian_solves import DENSE_GRAMIAN_MAX_DOF, SURROGATE_GRAMIAN_TOL, choose_solves
from flexmor.reduction.gramians import gramian_factors
from flexmor.workflow import reduce_and_judge

BAND = (50.0, 700.0)
SOLVES = ("direct", "dense", "surrogate")


def _rel(a, b):
    P, Q = a @ a.T, b @ b.T
    return np.abs(P - Q).max() / np.abs(Q).max()


def _freqs(red):
    """Eigenvalues of the reduced body above the rigid-body range, ascending."""
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(red.M, red.K)).real)
    return lam[lam > 1e-6 * lam.max()]


@pytest.fixture(scope="module")
def beam(clamped):
    model = clamped.with_rayleigh(0.0, 1e-6)
    return model, make_ports(model, ["TIP:y", "TIP:z"])


@pytest.fixture(scope="module")
def factors(beam):
    model, ports = beam
    return {s: gramian_factors(model, ports, BAND, solves=s) for s in SOLVES}


def test_gramians_of_every_solves_equal_the_direct_ones(factors):
    ref = factors["direct"]
    assert ref.info["solves"] == {"solves": "direct"}
    for s in ("dense", "surrogate"):
        G = factors[s]
        assert G.info["solves"]["solves"] == s and G.info["n_nodes"] == ref.info["n_nodes"]
        # measured: 7.9e-10 both (round-off of the direct solves at the lightly damped peaks; the
        # surrogate's state error at its checks is below 1e-9)
        for a, b in ((G.R, ref.R), (G.Rv, ref.Rv), (G.L, ref.L)):
            assert _rel(a, b) < 1e-8, s


def test_surrogate_solves_report_their_checks(beam, factors):
    model, _ = beam
    info = factors["surrogate"].info["solves"]
    assert info["verified"] is True and info["n_direct_checks"] >= 3
    assert info["final_check"]["rel_error"] <= SURROGATE_GRAMIAN_TOL
    assert info["max_check_error"] <= SURROGATE_GRAMIAN_TOL
    assert 0 < info["max_residual_on_grid"] < 1e-2 and info["order"] < model.n_dof // 4
    assert factors["dense"].info["solves"]["order"] == model.n_dof


@pytest.mark.parametrize("method, order", [("fw-sobt", 4), ("pod", 4)])
def test_methods_give_the_same_body_with_every_solves(beam, method, order):
    model, ports = beam
    full = FullResponse(model, ports, BAND, cache=False)
    out = {}
    for s in SOLVES:
        red, res = reduce_and_judge(model, method, order, ports, full=full, band=BAND, solves=s)
        out[s] = _freqs(red), res["band_error"]
    f0, e0 = out["direct"]
    assert 1e-10 < e0 < 1e-2  # far above the round-off floor of the error check
    for s in ("dense", "surrogate"):
        f, e = out[s]
        # measured: frequencies 2.5e-12 relative, band_error 7e-9 relative (band_error 6.8e-8)
        assert f.size == f0.size and np.abs(f / f0 - 1).max() < 1e-9, s
        assert abs(e / e0 - 1) < 1e-5, s


def test_free_body_flexible_gramians_agree(free):
    model = free.with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    out = {}
    for s in SOLVES:
        red, res = reduce_and_judge(model, "fw-sobt", 6, ports, band=BAND, solves=s)
        out[s] = _freqs(red), res["band_error"], red.info["n_rigid_included"]
    f0, e0, k0 = out["direct"]
    for s in ("dense", "surrogate"):
        f, e, k = out[s]
        assert k == k0 > 0 and f.size == f0.size and 1e-10 < e0 < 1e-2
        # measured: frequencies 1.2e-13, band_error 2.8e-9 relative (band_error 4.0e-5)
        assert np.abs(f / f0 - 1).max() < 1e-8 and abs(e / e0 - 1) < 1e-4, s


def test_auto_choice_and_bad_choice():
    small = cantilever(divisions=(5, 2, 2))
    large = cantilever(n=2)
    assert small.n_dof <= DENSE_GRAMIAN_MAX_DOF < large.n_dof
    assert choose_solves("auto", small, np.inf) == "dense"
    assert choose_solves("auto", large, 3000.0) == "surrogate"
    # the full band: the surrogate up to a cutoff when the tail has a bound (Rayleigh beta > 0; an
    # undamped model gets such a damping for its Gramians), else one factorization per node
    assert choose_solves("auto", large, np.inf) == "surrogate"
    assert choose_solves("auto", large.with_rayleigh(1.0, 1e-6), np.inf) == "surrogate"
    assert choose_solves("auto", large.with_rayleigh(1.0, 0.0), np.inf) == "direct"
    given = FEModel(M=large.M, K=large.K, D=large.M * 2.0, dofs=large.dofs, node_ids=large.node_ids, xyz=large.xyz,
                    node_sets=large.node_sets)
    assert choose_solves("auto", given, np.inf) == "direct"
    assert choose_solves("direct", small, 3000.0) == "direct"
    with pytest.raises(OptionError, match="solves"):
        choose_solves("fast", small, 3000.0)


def test_non_proportional_damping(beam):
    # a damper at the tip: Phi^T D Phi is not diagonal; dense solves fall back to direct ones,
    # the surrogate solves the small projected systems and agrees with them
    model, ports = beam
    tip = ports.B.toarray()[:, 0] != 0
    d = np.zeros(model.n_dof)
    d[tip] = 50.0
    damped = FEModel(M=model.M, K=model.K, D=model.D + sp.diags(d), dofs=model.dofs, node_ids=model.node_ids,
                     xyz=model.xyz, node_sets=model.node_sets)
    G = {s: gramian_factors(damped, ports, BAND, solves=s) for s in SOLVES}
    assert G["dense"].info["solves"]["solves"] == "direct"
    assert G["surrogate"].info["solves"]["verified"] is True
    assert _rel(G["surrogate"].R, G["direct"].R) < 1e-8 and _rel(G["surrogate"].L, G["direct"].L) < 1e-8


def test_full_frf_auto_path_of_mid_size_models():
    # 810 DOF: damped models take the verified surrogate (measured 0.17 s against 0.32 s dense),
    # modal damping keeps the dense path (its ratio exact in every mode)
    from flexmor.damping import modal_damping

    model = cantilever(divisions=(30, 2, 2))
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    band = (10.0, 3000.0)
    rayleigh = model.with_rayleigh(0.0, 1e-6)
    auto = FullResponse(rayleigh, ports, band, cache=False)
    dense = FullResponse(rayleigh, ports, band, cache=False, path="dense")
    assert model.n_dof == 810 and auto.grid["path"] == "surrogate" and auto.grid["surrogate"]["verified"]
    modal = model.with_damping(modal_damping(0.01, band))
    assert FullResponse(modal, ports, band, cache=False).grid["path"] == "dense"
    red, _ = reduce_and_judge(rayleigh, "modal", 6, ports, full=dense, band=band)
    e_auto, e_dense = auto.evaluate(red)["band_error"], dense.evaluate(red)["band_error"]
    # measured: 1.2722730e-5 on both grids, 2.4e-9 relative
    assert 1e-8 < e_dense < 1 and abs(e_auto / e_dense - 1) < 1e-6, (e_auto, e_dense)
