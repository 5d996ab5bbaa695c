"""The MBS code in the loop: flexmor bodies in a real Exudyn simulation follow the full FE body.

Small size of ``bench/mbs_loop.py`` (same code): a free beam (297 DOF) swinging on a spherical
joint under gravity, simulated with Exudyn's unreduced ``ObjectFFRF`` of the whole FE model and
with flexmor's ``ObjectFFRFreducedOrder`` bodies; and the beam clamped to a spinning hub (270
DOF), reduced with and without the frame's inertia loads. Skipped without Exudyn (extra
``exudyn``, installed by ``make test``).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("exudyn")

_spec = importlib.util.spec_from_file_location("mbs_loop", Path(__file__).resolve().parents[1] / "bench" / "mbs_loop.py")
mbs_loop = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mbs_loop)


@pytest.fixture(scope="module")
def pendulum():
    res = mbs_loop.pendulum((10, 2, 2), [18], end_time=0.2, step=1e-3, methods=("modal", "craig-bampton", "krylov"))
    return res, {row["method"]: row for row in res["rows"]}


@pytest.fixture(scope="module")
def hub():
    res = mbs_loop.hub((10, 2, 2), 7, end_time=0.4, step=1e-3)
    return {(row["method"], row["port"], row["inertia_loads"]): row for row in res["rows"]}


def test_full_pendulum_deflects(pendulum):
    """The swinging beam bends: about 0.1 mm at the tip in 0.2 s (first free-free bending mode
    near 70 Hz, loads of order m g), so the comparison below is about a real elastic motion."""
    res, _ = pendulum
    assert res["n_dof"] == 297
    assert 3e-5 < res["max_deflection_m"] < 3e-4


def test_craig_bampton_and_krylov_follow_the_full_body(pendulum):
    """Order 18, error of the tip deflection in the frame relative to its maximum, measured
    (mean / max over 0.2 s): craig-bampton 1.9e-3 / 5.0e-3, krylov 4.2e-4 / 9.3e-4, modal
    7.6e-3 / 3.8e-2. Bounds: 1 % mean, 2 % max - the bodies are Rayleigh-Ritz bodies of the same
    FE model, what is left is the truncation of modes far above the excitation (the joint
    force and gravity vary at the pendulum's few Hz, the body's modes start at 70 Hz)."""
    _, rows = pendulum
    for method in ("craig-bampton", "krylov"):
        assert rows[method]["order"] == 18
        assert rows[method]["mean_error"] < 1e-2, method
        assert rows[method]["max_error"] < 2e-2, method
    # moment matching of the joint force beats the lowest free-free modes of equal order
    assert rows["krylov"]["mean_error"] < rows["modal"]["mean_error"] / 5
    # the reduced bodies are the point: each runs far faster than the full FE body
    assert all(row["seconds"] < pendulum[0]["full_seconds"] / 5 for row in rows.values())


def test_inertia_loads_beat_the_joint_force_alone_on_a_spinning_hub(hub):
    """Clamped beam on a hub spun up to 2 rad/s, order 7. Reduced for the axial force at the
    tip only (a rod), a Krylov body cannot bend at all: the tangential inertia load of the hub's
    angular acceleration is outside its basis (measured mean / max error 0.22 / 0.92). With the
    inertia loads among the inputs it follows the full body (6.3e-5 / 2.9e-4). Reduced for the
    transverse tip force, the bending is there either way, but the centrifugal stretching
    (rho omega² L³ / 3E ~ 1.6 um, 2.7e-4 of the 6 mm deflection) is only in the body with
    the inertia loads (measured 2.0e-4 / 2.8e-4 without, 1.4e-5 / 3.3e-5 with)."""
    for method in ("krylov", "two-step"):
        off, on = hub[method, "TIP:x", "off"], hub[method, "TIP:x", "on"]
        assert off["mean_error"] > 0.1 and off["max_error"] > 0.5, method
        assert on["mean_error"] < 1e-3 and on["max_error"] < 2e-3, method
        off, on = hub[method, "TIP:y", "off"], hub[method, "TIP:y", "on"]
        assert on["max_error"] < off["max_error"] / 5, method
        np.testing.assert_allclose(off["max_error"], 2.8e-4, rtol=0.3)
