"""Node selection on the CalculiX beam (1 x 0.1 x 0.1 m, nodes on an 11 x 3 x 3 grid)."""

from __future__ import annotations

import numpy as np
import pytest

from flexmor.couplings import couple
from flexmor.errors import PortError
from flexmor.linalg import eigenmodes
from flexmor.selection import box, cylinder, nearest, plane, select, sphere, with_selections

AXIS = ([0.0, 0.05, 0.05], [1.0, 0.0, 0.0])


def _at(model, ids):
    return model.node_xyz(ids)


def test_plane_box_nearest(clamped):
    tip = plane(clamped, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0])
    np.testing.assert_array_equal(tip, np.sort(clamped.node_sets["TIP"]))
    assert plane(clamped, [0, 0, 0.05], [0, 0, 1]).size == 33
    tilted = plane(clamped, [0, 0, 0], [1, -1, 0], tol=1e-9)  # x = y: nodes (0, 0, z) and (.1, .1, z)
    assert set(map(tuple, np.round(_at(clamped, tilted), 9))) == {(a, a, z) for a in (0, .1) for z in (0, .05, .1)}
    b = box(clamped, [0.3, 0.0, 0.0], [0.5, 0.1, 0.05])
    assert b.size == 3 * 3 * 2 and np.all(_at(clamped, b)[:, 2] <= 0.05 + 1e-12)
    n = nearest(clamped, [0.51, 0.049, -0.01])
    np.testing.assert_allclose(_at(clamped, [n])[0], [0.5, 0.05, 0.0])


def test_cylinder_and_sphere(clamped):
    corners = cylinder(clamped, *AXIS, 0.05 * np.sqrt(2))
    assert corners.size == 44
    mid = cylinder(clamped, *AXIS, 0.05, span=(0.85, 1.0))
    assert mid.size == 8
    x = _at(clamped, mid)
    np.testing.assert_allclose(np.hypot(x[:, 1] - 0.05, x[:, 2] - 0.05), 0.05)
    assert set(np.round(x[:, 0], 9)) == {0.9, 1.0}
    assert cylinder(clamped, *AXIS, 0.0).size == 11  # the axis itself
    s = sphere(clamped, [0.5, 0.05, 0.05], 0.05)  # the 4 edge midpoints of that section; x neighbours are 0.1 away
    assert s.size == 4 and np.allclose(_at(clamped, s)[:, 0], 0.5)


def test_select_specs_and_errors(clamped):
    np.testing.assert_array_equal(select(clamped, "set:tip"), np.sort(clamped.node_sets["TIP"]))
    np.testing.assert_array_equal(select(clamped, "cylinder:0,0.05,0.05,1,0,0,0.05,1e-9,0.85,1"),
                                  cylinder(clamped, *AXIS, 0.05, span=(0.85, 1.0)))
    assert select(clamped, "nearest:1,0.1,0.1").size == 1
    for spec, words in [("cone:1,2,3", "unknown kind 'cone'"), ("box:1,2", "box takes 6 numbers, got 2"),
                        ("cylinder:0,0,0,1,0,0,1,2,3", "not 9"), ("plane:0,0,0,0,0,0", "normal must not be zero"),
                        ("plane:5,0,0,1,0,0", "selects no node"), ("set:NOPE", "no node set 'NOPE'"),
                        ("box:a,b,c,d,e,f", "comma-separated numbers")]:
        with pytest.raises(PortError, match=words):
            select(clamped, spec)
    with pytest.raises(PortError, match="exists already"):
        with_selections(clamped, ["TIP=plane:1,0,0,1,0,0"])
    with pytest.raises(PortError, match="expected NAME=KIND:NUMBERS"):
        with_selections(clamped, ["cylinder:0,0,0,1,0,0,1"])


def test_selected_ring_as_rbe2_interface(free):
    """A ring of nodes selected as a 'hole' and coupled by RBE2: the free body keeps 6 rigid modes."""
    model = with_selections(free, ["RING=cylinder:0,0.05,0.05,1,0,0,0.05,1e-9,0.45,0.55", "END=set:RING"])
    assert model.node_sets["RING"].size == 4 and model.node_sets["END"].size == 4
    cm = couple(model, ["RING@rbe2"]).model
    lam, _ = eigenmodes(cm.K, cm.M, 8, method="lanczos")
    f = np.sqrt(np.abs(lam)) / (2 * np.pi)
    assert np.all(f[:6] < 1e-5 * f[6]) and f[6] > 500.0
