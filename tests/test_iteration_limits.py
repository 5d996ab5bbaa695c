"""Iterative methods stop at their iteration limits and report it, with the best result so far."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import CLAMPED
from scipy.sparse.linalg import ArpackNoConvergence

import flexmor.linalg.eigen as eigen_mod
from flexmor.cli import main
from flexmor.errors import ConvergenceError
from flexmor.linalg import factorize
from flexmor.linalg.block_eigen import block_lanczos
from flexmor.linalg.eigen import default_shift, eigenmodes


def test_block_lanczos_gives_up_with_its_best_ritz_pairs(clamped):
    K, M = clamped.K, clamped.M
    sigma = default_shift(K, M)
    F = factorize((K - sigma * M).tocsr(), symmetric=True, positive=True)
    with pytest.raises(ConvergenceError, match="did not converge for 8 modes in 0 restarts") as e:
        block_lanczos(K, M, 8, F, sigma, block=2, max_basis=12, max_restarts=0, tol=1e-14)
    lam, phi = e.value.result
    exact, _ = eigenmodes(K, M, 8, method="dense")
    assert lam.shape == (8,) and phi.shape == (K.shape[0], 8)
    # Ritz values bound the eigenvalues from above; the lowest is already close
    assert np.all(lam >= exact * (1 - 1e-9)) and lam[0] == pytest.approx(exact[0], rel=1e-3)


def test_arpack_non_convergence_carries_the_converged_pairs(clamped, monkeypatch):
    n = clamped.n_dof

    def fake_eigsh(*args, **kwargs):
        raise ArpackNoConvergence("no convergence", np.array([3.0, 1.0]), np.eye(n)[:, :2])

    monkeypatch.setattr(eigen_mod, "eigsh", fake_eigsh)
    with pytest.raises(ConvergenceError, match="did not converge for 8 modes \\(2 converged\\)") as e:
        eigenmodes(clamped.K, clamped.M, 8, method="arpack")
    lam, phi = e.value.result
    np.testing.assert_array_equal(lam, [1.0, 3.0])
    np.testing.assert_array_equal(phi[:, 0], np.eye(n)[:, 1])


@pytest.mark.slow
def test_irka_iteration_limit_on_the_command_line(tmp_path, capsys, caplog):
    out = tmp_path / "irka.h5"
    code = main(["reduce", CLAMPED, "--method", "irka", "--order", "6", "--input",
                 "TIP:y", "--rayleigh", "2:1e-6", "--max-iter", "1", "--no-error", "--json", "-o", str(out)])
    captured = capsys.readouterr()
    assert code == 0 and out.exists()
    info = json.loads(captured.out)["info"]
    assert info["converged"] is False and info["iterations"] == 1 and info["max_iter"] == 1
    assert "irka did not converge in 1 iterations" in caplog.text  # a warning on stderr outside pytest
