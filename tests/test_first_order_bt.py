"""First-order balanced truncation and the H-infinity norm on the SLICOT clamped-beam benchmark.

``tests/data/mor/beam.mat`` (SLICOT benchmark collection, n = 348) stores ``A``, ``B``, ``C``,
its Hankel singular values ``hsv`` and the magnitude ``mag`` of its frequency response at
``w`` (rad/s), all computed outside flexmor.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io as sio
import scipy.linalg as sla
from helpers import DATA

from flexmor.analysis.norms import hinf_norm
from flexmor.errors import ModelError, OptionError
from flexmor.linalg.threads import blas_threads
from flexmor.reduction.dense_gramians import balanced_truncation, hankel_singular_values

BEAM = DATA / "mor" / "beam.mat"


@pytest.fixture(autouse=True)
def _one_blas_thread():
    with blas_threads(1):  # dense eigenvalue work of a few hundred states (see flexmor.linalg.threads)
        yield


@pytest.fixture(scope="module")
def beam():
    d = sio.loadmat(BEAM)
    return d["A"], d["B"].astype(float), d["C"].astype(float), d["hsv"].ravel(), d["w"].ravel(), d["mag"].ravel()


def test_hankel_singular_values_match_stored(beam):
    A, B, C, hsv_ref, _, _ = beam
    hsv = hankel_singular_values(A, B, C)
    assert hsv.shape == (348,)
    assert np.abs(hsv[:20] / hsv_ref[:20] - 1).max() < 1e-6  # measured 3.5e-10


def test_hinf_norm_of_the_beam_matches_its_stored_response(beam):
    A, B, C, _, w, mag = beam
    g, w_peak = hinf_norm(A, B, C)
    # the stored magnitudes lie below the supremum and the peak of the 168-point grid is close to it
    assert g >= mag.max() * (1 - 1e-9)
    assert g == pytest.approx(mag.max(), rel=1e-4)  # measured 4554.872 vs 4554.836
    Gp = C @ np.linalg.solve(1j * w_peak * np.eye(348) - A.toarray(), B)
    assert abs(Gp[0, 0]) == pytest.approx(g, rel=1e-9)
    # the file read as stored: |C (iwI - A)^-1 B| reproduces the stored magnitudes
    G = [(C @ np.linalg.solve(1j * x * np.eye(348) - A.toarray(), B))[0, 0] for x in w[::8]]
    assert np.abs(np.abs(G) / mag[::8] - 1).max() < 1e-8  # measured 6e-10


@pytest.mark.parametrize("order", [10, 20])
def test_balanced_truncation_error_between_the_bounds(beam, order):
    A, B, C, _, _, _ = beam
    Ar, Br, Cr, sigma = balanced_truncation(A, B, C, order)
    assert Ar.shape == (order, order) and np.linalg.eigvals(Ar).real.max() < 0
    err, _ = hinf_norm(sla.block_diag(A.toarray(), Ar), np.vstack([B, Br]), np.hstack([C, -Cr]))
    # sigma_{r+1} <= ||G - Gr||_Hinf <= 2 sum_{k>r} sigma_k
    # measured: r=10 err 10.62 in [3.09, 24.1]; r=20 err 0.400 in [0.216, 3.67]
    assert sigma[order] * (1 - 1e-6) <= err < 2 * sigma[order:].sum()
    # the reduced system is balanced: its Gramians are diag(sigma_1..sigma_r)
    P = sla.solve_continuous_lyapunov(Ar, -Br @ Br.T)
    Q = sla.solve_continuous_lyapunov(Ar.T, -Cr.T @ Cr)
    S = np.diag(sigma[:order])
    assert np.abs(P - S).max() < 1e-6 * sigma[0] and np.abs(Q - S).max() < 1e-6 * sigma[0]


def test_hinf_norm_of_an_oscillator():
    # 1 / (s^2 + 2 z w0 s + w0^2): peak 1 / (2 z sqrt(1 - z^2) w0^2) at w0 sqrt(1 - 2 z^2)
    w0, z = 30.0, 0.02
    A = np.array([[0.0, 1.0], [-w0 ** 2, -2 * z * w0]])
    g, wp = hinf_norm(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), rtol=1e-10)
    assert g == pytest.approx(1 / (2 * z * np.sqrt(1 - z ** 2) * w0 ** 2), rel=1e-9)
    assert wp == pytest.approx(w0 * np.sqrt(1 - 2 * z ** 2), rel=1e-4)


def test_unstable_systems_are_refused():
    A = np.array([[0.1, 0.0], [0.0, -1.0]])
    B, C = np.ones((2, 1)), np.ones((1, 2))
    with pytest.raises(OptionError, match="infinite"):
        hinf_norm(A, B, C)
    with pytest.raises(ModelError, match="stable"):
        balanced_truncation(A, B, C, 1)
    with pytest.raises(OptionError, match="order"):
        balanced_truncation(-np.eye(2), B, C, 3)
