"""Block shift-invert Lanczos (``eigenmodes(method="lanczos")``) against dense LAPACK and ARPACK."""

import sys

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from flexmor.errors import OptionError
from flexmor.linalg import eigenmodes
from flexmor.linalg.eigen import default_shift, is_rigid
from flexmor.linalg.threads import _handles, blas_threads


def _reference(K, M, k):
    """Dense LAPACK eigenvectors, eigenvalues refined to their Rayleigh quotients."""
    _, phi = eigenmodes(K, M, k, method="dense")
    return np.einsum("ij,ij->j", phi, K @ phi) / np.einsum("ij,ij->j", phi, M @ phi)


def _assert_eigenvalues(K, M, lam, lam_ref):
    """Eigenvalues to 1e-10 relative, or to the round-off of the dense reference where that is
    larger: each of its eigenvalues (and Rayleigh quotients) errs by ~eps lam_max, i.e. by
    eps lam_max / lam = 1.4e-10 relative at the first mode of the clamped beam."""
    lam_max = spla.eigsh(K, 1, M, which="LA", return_eigenvectors=False, tol=1e-3)[0]
    rtol = np.maximum(1e-10, 4 * np.finfo(float).eps * lam_max / lam_ref)
    assert np.all(np.abs(lam - lam_ref) <= rtol * lam_ref), np.abs(lam / lam_ref - 1) / rtol


def _check(K, M, k, lam, phi, lam_ref, n_rigid):
    rigid = is_rigid(lam, K, M)
    assert int(rigid.sum()) == n_rigid
    scale = abs(default_shift(K, M))
    assert np.all(np.abs(lam[:n_rigid]) < 1e-4 * scale)
    _assert_eigenvalues(K, M, lam[n_rigid:], lam_ref[n_rigid:])
    np.testing.assert_allclose(phi.T @ (M @ phi), np.eye(k), atol=1e-10)
    assert np.all(np.diff(lam) >= -1e-9 * abs(lam).max())
    R = K @ phi[:, n_rigid:] - (M @ phi[:, n_rigid:]) * lam[n_rigid:]
    rel = np.linalg.norm(R, axis=0) / (lam[n_rigid:] * np.linalg.norm(M @ phi[:, n_rigid:], axis=0))
    assert rel.max() < 1e-6


@pytest.mark.parametrize("which, n_rigid", [("clamped", 0), ("free", 6)])
def test_lanczos_on_calculix_beams(request, which, n_rigid):
    model = request.getfixturevalue(which)
    k = 20
    lam_ref = _reference(model.K, model.M, k)
    lam, phi = eigenmodes(model.K, model.M, k, method="lanczos")
    _check(model.K, model.M, k, lam, phi, lam_ref, n_rigid)


@pytest.mark.slow
@pytest.mark.parametrize("clamped", [True, False])
def test_lanczos_square_section_pairs(clamped):
    """Square cross-section: bending modes come in pairs (equal eigenvalues to round-off)."""
    from flexmor.models import cantilever

    model = cantilever(3, clamped=clamped)  # 1,440 / 1,488 DOF
    k = 24
    n_rigid = 0 if clamped else 6
    lam_ref = _reference(model.K, model.M, k)
    lam, phi = eigenmodes(model.K, model.M, k, method="lanczos")
    _check(model.K, model.M, k, lam, phi, lam_ref, n_rigid)
    first = lam[n_rigid:n_rigid + 2]
    assert abs(first[1] - first[0]) < 1e-8 * first[0]  # a pair is found, both members
    lam_a, _ = eigenmodes(model.K, model.M, k, method="arpack")
    np.testing.assert_allclose(lam[n_rigid:], lam_a[n_rigid:], rtol=1e-10)


def test_lanczos_small_block_and_restarts(clamped):
    """Block size below the multiplicity of nothing, a tight basis limit forces thick restarts."""
    from flexmor.linalg import factorize
    from flexmor.linalg.block_eigen import block_lanczos

    K, M = clamped.K, clamped.M
    sigma = default_shift(K, M)
    F = factorize((K - sigma * M).tocsr())
    lam_ref = _reference(K, M, 10)
    lam, phi = block_lanczos(K, M, 10, F, sigma, block=3, max_basis=30)
    _assert_eigenvalues(K, M, lam, lam_ref)


def test_unknown_method_lists_choices(clamped):
    with pytest.raises(OptionError, match="arpack"):
        eigenmodes(clamped.K, clamped.M, 4, method="jacobi")


def test_blas_threads_restores_count():
    before = [get() for _, get in _handles()]
    with blas_threads(1):
        assert all(get() == 1 for _, get in _handles())
    assert [get() for _, get in _handles()] == before


@pytest.mark.parametrize("backend", ["pardiso", "scipy"])
def test_factorization_refused_when_memory_is_short(clamped, backend, monkeypatch):
    from flexmor.errors import SolverError
    from flexmor.linalg import SolverContext, available_backends, factorize

    if backend not in available_backends():
        pytest.skip(f"{backend} not available")
    mod = sys.modules["flexmor.linalg.resources"]
    F = factorize(clamped.K, solver=SolverContext(backend))
    assert F.memory_estimate > 1e4  # bytes: the factor of 270 equations needs more than 10 kB
    monkeypatch.setattr(mod, "memory_available", lambda: 2048.0)
    with pytest.raises(SolverError, match=r"needs about .* MB, but only 0 MB .* available; .*distributed backend"):
        factorize(clamped.K, solver=SolverContext(backend))


def test_describe_backends_lists_capabilities():
    from flexmor.linalg.backends import describe_backends

    rows = {r["name"]: r for r in describe_backends()}
    assert rows["scipy"]["available"] and rows["scipy"]["complex"]
    assert rows["cholmod"]["positive_only"] and not rows["cholmod"]["complex"]


def test_cli_info_backends(capsys):
    import json

    from flexmor.cli import main

    assert main(["info", "--backends", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    names = [b["name"] for b in out["backends"]]
    assert names == ["cholmod", "pardiso", "scipy", "petsc", "amg", "petsc-gamg"]
    assert [b["name"] for b in out["backends"] if b["iterative"]] == ["amg", "petsc-gamg"]
    assert out["memory_available_mb"] is None or out["memory_available_mb"] > 0
    assert main(["info"]) == 2  # neither MODEL nor --backends


def test_block_lanczos_converges_at_a_tolerance_below_the_rounding_of_its_ritz_values(clamped):
    """tol = 1e-15: the Ritz values never move by less than that (rounding), so the residuals are checked once
    they moved by less than 1e-9; the pairs stalled at the rounding floor are accepted."""
    import scipy.sparse as sp

    from flexmor.linalg import factorize
    from flexmor.linalg.block_eigen import block_lanczos
    from flexmor.linalg.eigen import default_shift
    K, M = clamped.K, clamped.M
    sigma = default_shift(K, M)
    F = factorize(sp.csr_matrix(K - sigma * M), symmetric=True, positive=True)
    lam, _ = block_lanczos(K, M, 6, F, sigma, tol=1e-15)
    exact = eigenmodes(K, M, 6, method="dense")[0]
    np.testing.assert_allclose(lam, exact, rtol=1e-10)
