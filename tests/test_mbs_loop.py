"""The MBS code in the loop: flexmor bodies in a real Exudyn simulation follow the full FE body.

Small size of ``bench/mbs_loop.py`` (same code): a free beam (297 DOF) swinging on a spherical
joint under gravity, simulated with Exudyn's unreduced ``ObjectFFRF`` of the whole FE model and
with flexmor's ``ObjectFFRFreducedOrder`` bodies; and the beam clamped to a spinning hub (270
DOF), reduced with and without the frame's inertia loads. Skipped without Exudyn (extra
``exudyn``, installed by ``make test``).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import ROOT, load_script

pytest.importorskip("exudyn")

mbs_loop = load_script(ROOT / "bench" / "mbs_loop.py")


@pytest.fixture(scope="module")
def pendulum():
    res = mbs_loop.free_body("pendulum", (10, 2, 2), [18], end_time=0.2, step=1e-3,
                             methods=("modal", "craig-bampton", "krylov"))
    return res, {row["method"]: row for row in res["rows"]}


@pytest.fixture(scope="module")
def slider_crank():
    res = mbs_loop.free_body("slider-crank", (10, 2, 2), [24], end_time=0.15, step=1e-3,
                             methods=("modal", "craig-bampton", "krylov"))
    return res, {row["method"]: row for row in res["rows"]}


HUB_DIVISIONS, HUB_ORDER = (10, 2, 2), 7


@pytest.fixture(scope="module")
def hub():
    res = mbs_loop.hub(HUB_DIVISIONS, HUB_ORDER, end_time=0.4, step=1e-3)
    return res, {(row["method"], row["port"], row["inertia_loads"]): row for row in res["rows"]}


def test_full_pendulum_deflects(pendulum):
    """The swinging beam bends: about 0.1 mm at the tip in 0.2 s (first free-free bending mode
    near 70 Hz, loads of order m g), so the comparison below is about a real elastic motion."""
    res, _ = pendulum
    assert res["n_dof"] == 297
    assert 3e-5 < res["max_deflection_m"] < 3e-4


def test_craig_bampton_and_krylov_follow_the_full_body(pendulum):
    """Order 18, error of the tip deflection in the frame relative to its maximum, measured
    (mean / max over 0.2 s): craig-bampton 1.3e-3 / 3.5e-3, krylov 4.1e-4 / 9.9e-4, modal
    6.7e-3 / 2.6e-2. Bounds: 1 % mean, 2 % max - the bodies are Rayleigh-Ritz bodies of the same
    FE model, what is left is the truncation of modes far above the excitation (the joint
    force and gravity vary at the pendulum's few Hz, the body's modes start at 70 Hz)."""
    _, rows = pendulum
    for method in ("craig-bampton", "krylov"):  # (craig-bampton: 19 when its 18th cuts a bending pair)
        assert rows[method]["order"] == 18 or (method == "craig-bampton" and rows[method]["order"] == 19)
        assert rows[method]["mean_error"] < 1e-2, method
        assert rows[method]["max_error"] < 2e-2, method
    # moment matching of the joint force beats the lowest free-free modes of equal order
    assert rows["krylov"]["mean_error"] < rows["modal"]["mean_error"] / 5
    # the reduced bodies are the point: each runs far faster than the full FE body
    assert all(row["seconds"] < pendulum[0]["full_seconds"] / 5 for row in rows.values())


def test_slider_crank_rod_follows_the_full_body(slider_crank):
    """Rod of the slider-crank, order 24 (Craig-Bampton: the 24 DOF of both joint sets, six
    elastic modes left after the rigid motion; Krylov: four moments of the six joint-force
    directions), slider end's deflection in the frame (max 0.41 mm), measured mean / max:
    craig-bampton 2.9e-3 / 5.8e-3, krylov 3.4e-9 / 9.4e-9, modal 1.2e-3 / 2.3e-3. The crank
    (about 1.6 Hz) loads the rod far below its first mode (70 Hz): the response is quasi-static,
    which Krylov's moments at s = 0 capture up to Exudyn's Newton tolerance (1e-8), while
    Craig-Bampton's constraint modes miss the inertia relief of the free rod."""
    res, rows = slider_crank
    assert 2e-4 < res["max_deflection_m"] < 8e-4
    assert rows["craig-bampton"]["order"] == rows["krylov"]["order"] == 24
    assert rows["craig-bampton"]["mean_error"] < 1e-2 and rows["craig-bampton"]["max_error"] < 2e-2
    assert rows["krylov"]["max_error"] < 1e-5
    assert rows["krylov"]["max_error"] < rows["modal"]["max_error"] / 100


def _bending(model, V) -> np.ndarray:
    """Beam bending of each column of ``V``: its transverse (y, z) displacement averaged over the nodes of
    each cross-section, relative to the column's norm. The Poisson contraction of an axial response is
    antisymmetric over the section and averages out."""
    x = np.round(model.node_xyz(model.dofs[:, 0])[:, 0], 9)
    sq = np.zeros(V.shape[1])
    for xs in np.unique(x):
        for d in (2, 3):
            rows = (x == xs) & (model.dofs[:, 1] == d)
            sq += rows.sum() * V[rows].mean(axis=0) ** 2
    return np.sqrt(sq) / np.linalg.norm(V, axis=0)


def test_inertia_loads_beat_the_joint_force_alone_on_a_spinning_hub(hub):
    """Clamped beam on a hub spun up to 2 rad/s, order 7. With the frame's inertia loads among the
    basis inputs the body follows the full one (measured mean / max error: krylov 6.3e-5 / 2.9e-4,
    two-step 3.1e-5 / 1.2e-4).

    Reduced for the axial force at the tip alone (a rod), the body cannot bend in exact arithmetic:
    beam and load are symmetric about both midplanes, so is every moment of ``TIP:x``, and the
    tangential inertia load of the spin-up is outside the basis. Such a body misses the whole
    deflection: its error is ``|u_full(t)| / max |u_full|``, mean = the full body's mean over max
    deflection (0.244), max 1 (the centrifugal stretching it does capture is 2.7e-4 of it).
    Two-step measures exactly that (0.2439 / 1.0000): its balanced truncation keeps the six states
    the port sees (Hankel values down to 5e-14 of the largest) and no round-off state.

    Krylov's body depends on round-off instead. At the 10 Hz point, below the first bending
    modes (11 Hz, y and z alike on the square section; first axial mode 230 Hz), each moment
    amplifies the solves' round-off bending against the axial response (230² + 10²) / (11² + 10²)
    = 240-fold, and the orthogonalization, which keeps about a ninth of each new vector, ten-fold
    more (bending share of that point's Arnoldi vectors 6e-13, 1.3e-9, 9.4e-6). The seventh
    column, its third moment, has 4e-7 of new axial content left after the other six against
    9e-6 of bending: it is the round-off, a first bending mode at whatever angle between y and z
    the sparse solver's rounding gave it, and the body bends along it (a 12.3 Hz Ritz mode the
    port does not see). One machine, MKL PARDISO's kernels: mean / max error 0.10 / 0.28
    (AVX-512), 0.22 / 0.87 (AVX2), 0.16 / 0.53 (SSE4.2); with the exact first y-bending mode as
    seventh column 8e-4 / 3e-3, with the z-mode 0.244 / 1. Asserted for krylov is what survives the
    round-off: the port's own solves, the leading column of each point, hold no bending (measured
    at most 1e-10).
    """
    res, rows = hub
    for method in ("krylov", "two-step"):
        on = rows[method, "TIP:x", "on"]
        assert on["mean_error"] < 1e-3 and on["max_error"] < 2e-3, method
    off = rows["two-step", "TIP:x", "off"]
    np.testing.assert_allclose(off["mean_error"], res["mean_deflection_m"] / res["max_deflection_m"], rtol=1e-2)
    np.testing.assert_allclose(off["max_error"], 1.0, rtol=1e-2)
    model = mbs_loop.beam(HUB_DIVISIONS, clamped=True)
    V = mbs_loop.hub_body(model, "krylov", HUB_ORDER, "TIP:x", "off").V
    assert _bending(model, V[:, :3]).max() < 1e-8


def test_transverse_port_bends_either_way_but_misses_the_stretching_without_inertia_loads(hub):
    """Reduced for the transverse tip force, the bending is in the basis either way. What the
    body without inertia loads lacks is the centrifugal stretching, rho omega² L³ / 3E = 1.6 um,
    2.7e-4 of the 6 mm deflection: its error is exactly that (measured max 2.8e-4 for both
    methods). With the inertia loads the stretching is captured (static error 5 % instead of
    100 %) while the seven columns, shared with the other load patterns, leave the bending a
    little less exact (measured max: krylov 3.3e-5, two-step 1.5e-5)."""
    res, rows = hub
    assert 4e-3 < res["max_deflection_m"] < 8e-3
    stretch = mbs_loop.RHO * (mbs_loop.ALPHA0 * mbs_loop.T_SPIN / 2) ** 2 * mbs_loop.LENGTH**3 / (3 * mbs_loop.E)
    for method in ("krylov", "two-step"):
        off, on = rows[method, "TIP:y", "off"], rows[method, "TIP:y", "on"]
        np.testing.assert_allclose(off["max_error"], stretch / res["max_deflection_m"], rtol=0.1)
        assert on["max_error"] < off["max_error"] / 5, method


@pytest.mark.slow
def test_benchmark_command_line_prints_the_tables(tmp_path, capsys):
    """``bench/mbs_loop.py`` end to end on an 84-DOF beam: three tables, one row per method
    (and port and inertia-load choice), the JSON with the same rows."""
    import json

    tiny = ["--divisions", "6,1,1", "--crank-divisions", "6,1,1", "--hub-divisions", "6,1,1", "--orders", "12",
            "--end-time", "0.02", "--crank-end-time", "0.02", "--hub-end-time", "0.02",
            "--json", str(tmp_path / "r.json")]
    assert mbs_loop.main(tiny) == 0
    out = capsys.readouterr().out
    res = json.loads((tmp_path / "r.json").read_text())
    assert [len(res[k]["rows"]) for k in ("pendulum", "slider_crank", "hub")] == [4, 4, 8]
    assert res["pendulum"]["n_dof"] == 84 and res["hub"]["n_dof"] == 72
    assert out.count("craig-bampton") == 2 and "full ObjectFFRF" in out and "inertia_loads" in out
