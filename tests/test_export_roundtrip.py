"""A reduced body written as a Nastran superelement (DMIG punch, OP4 + .bdf) and as a Matrix Market set,
read back with flexmor's own readers: the same frequencies, boundary grids and ports."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from flexmor.errors import ModelError
from flexmor.io import export, read, read_body
from flexmor.ports import make_ports
from flexmor.reduction import reduce


def _frequencies(K, M):
    lam = sla.eigh(np.asarray(K.todense() if hasattr(K, "todense") else K),
                   np.asarray(M.todense() if hasattr(M, "todense") else M), eigvals_only=True)
    return np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)


@pytest.fixture(scope="module", params=["clamped", "free"])
def body(request):
    model = request.getfixturevalue(request.param).with_rayleigh(2.0, 1e-6)
    tip = int(model.dofs[-1, 0])
    mid = int(model.dofs[model.n_dof // 2, 0])
    ports = make_ports(model, [f"{tip}:y", f"{mid}:z"], [f"{tip}:y", f"{tip}:x", f"{mid}:z"])
    red = reduce(model, "krylov", 12, ports)
    return red, model, {tip, mid}


@pytest.mark.parametrize("fmt, suffix, rtol", [("nastran-dmig", ".pch", 1e-7), ("op4", ".op4", 1e-10)])
def test_superelement_round_trip(tmp_path, body, fmt, suffix, rtol):
    red, model, grids = body
    path = tmp_path / f"body{suffix}"
    assert export(red, path, model=model) == fmt
    se = read_body(path)
    assert se.order == red.order
    assert set(se.node_ids.tolist()) == grids
    assert set(se.input_names) == {n for n in red.output_names}
    f_ref, f_se = red.frequencies_hz(), se.frequencies_hz()
    elastic = f_ref > 1e-3 * f_ref.max()  # rigid modes of the free body are zero to round-off
    np.testing.assert_allclose(f_se[elastic], f_ref[elastic], rtol=rtol)
    np.testing.assert_allclose(se.xyz, model.xyz[np.searchsorted(model.node_ids, sorted(grids))], rtol=1e-9)
    np.testing.assert_allclose(se.D, se.D.T)  # Rayleigh damping written as BAA(X)


def test_matrix_market_round_trip(tmp_path, clamped):
    # (a free body's Kr may have diagonal entries of -1e-12 relative, which an FE model refuses)
    node = int(clamped.dofs[-1, 0])
    red = reduce(clamped.with_rayleigh(2.0, 1e-6), "krylov", 12, make_ports(clamped, [f"{node}:y"]))
    assert export(red, tmp_path / "body.mtx") == "matrix-market"
    back = read(tmp_path / "body_K.mtx")
    np.testing.assert_array_equal(back.K.toarray(), np.tril(red.K) + np.tril(red.K, -1).T)
    np.testing.assert_array_equal(back.M.toarray(), np.tril(red.M) + np.tril(red.M, -1).T)
    assert back.D is not None
    f = red.frequencies_hz()
    elastic = f > 1e-3 * f.max()
    np.testing.assert_allclose(_frequencies(back.K, back.M)[elastic], f[elastic], rtol=1e-10)


def test_superelement_needs_grid_outputs(tmp_path, clamped):
    node = int(clamped.dofs[-1, 0])
    red = reduce(clamped, "modal", 4, make_ports(clamped, [f"{node}:y"]))
    red.output_names = ["tip deflection"]
    with pytest.raises(ModelError, match="boundary DOFs"):
        export(red, tmp_path / "x.pch")
