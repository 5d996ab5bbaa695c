"""The plate-structure table (examples/plate_structure_table.py) on a small plate-and-rods structure."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import load_example

ex = load_example("plate_structure_table")

#: the table fixture alone runs every method on 1,728 DOF
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def table():
    """n=6 (1,728 DOF), band 1-2000 Hz (17 resonances), zeta 1 %, coarse grid and POD quadrature."""
    return ex.run(6, band=(1.0, 2000.0), zeta=0.01, pod_nodes=1, grid_tol=0.1)


def test_ordering_krylov_two_step_pod_modal(table):
    e = {name: v["band_error"] for name, v in table["methods"].items()}
    mx = {name: v["max_rel_error"] for name, v in table["methods"].items()}
    # measured: krylov 2.7e-20, two-step 7.9e-20 (all 31 non-zero Hankel values kept), pod 4.0e-14,
    # modal 3.1e-4. At this size krylov (173) and two-step (35/173) both reach the floor of the
    # error measure (max_rel_error ~1e-8, the accuracy of the full and reduced solves), so their
    # mutual order is round-off and is not asserted here; at 35,988 DOF (examples/README.md) two-step
    # truncates for real and krylov < two-step holds (4.1e-17 < 4.3e-16).
    for name in ("krylov", "two-step"):
        assert e[name] < 1e-14 and mx[name] < 1e-6
    assert 100 * max(e["krylov"], e["two-step"]) < e["pod"]
    assert 10 * e["pod"] < e["modal"]
    # modal truncation misses the static contribution of the modes above the band
    assert 1e-5 < e["modal"] < 1e-2 and mx["modal"] > 1


def test_orders_and_sizes(table):
    m = table["methods"]
    assert table["n_dof"] == 1728 and table["n_inputs"] == 6
    assert m["krylov"]["order"] == 173 and m["pod"]["order"] == 24 and m["modal"]["order"] == 40
    assert 24 < m["two-step"]["order"] <= 35  # fewer when the intermediate body has fewer Hankel values
    assert m["modal"]["info"]["highest_mode_hz"] > table["band_hz"][1]  # 40 modes cover the band
    assert table["n_resonances"] >= 10
    for v in m.values():
        assert v["seconds"] > 0 and v["rel_error"].shape == table["freqs"].shape
        assert v["max_rel_error"] == pytest.approx(v["rel_error"].max())


def test_table_and_figure(table, tmp_path):
    text = ex.table(table)
    for label in ("Krylov (173)", "Krylov+Gram (35/173)", "POD (36/24)", "modal (40)", "2.06e-07", "0.00727"):
        assert label in text
    ex.plot(table, tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 10_000
    assert np.all(np.isfinite(table["freqs"]))
