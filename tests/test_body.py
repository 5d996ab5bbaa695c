"""The reduced body: its fields (selections, couplings, order note) and its methods (FRF, time
response, expansion, state space with the port names), each checked against the module it hands
the body to."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from flexmor.body import ReducedModel
from flexmor.couplings import couple
from flexmor.dynamics.frf import frf_reduced
from flexmor.dynamics.time import simulate, step
from flexmor.io import export, read_body
from flexmor.ports import make_ports
from flexmor.projection import project
from flexmor.reduction.craig_bampton import craig_bampton
from flexmor.reduction.modal import modal

INPUTS, OUTPUTS = ["TIP:y", "TIP:z"], ["TIP:y", "TIP:x"]


@pytest.fixture(scope="module")
def body(clamped):
    """Modal body of order 8 of the clamped beam with Rayleigh damping, two inputs, two outputs."""
    model = clamped.with_rayleigh(0.0, 1e-5)
    ports = make_ports(model, INPUTS, OUTPUTS)
    return project(model, modal(model, ports, 8), ports)


def _transfer(A, B, C, w):
    return C @ np.linalg.solve(1j * w * np.eye(A.shape[0]) - A, B)


def test_frf_is_the_dense_frf_and_the_state_space_transfer(body):
    f = np.array([10.0, 237.0, 1500.0])
    H = body.frf(f)
    assert H.shape == (3, 2, 2)
    np.testing.assert_array_equal(H, frf_reduced(body, f))
    ss = body.to_scipy()
    for k, fk in enumerate(f):
        G = _transfer(ss.A, ss.B, ss.C, 2 * np.pi * fk)
        assert np.linalg.norm(G - H[k]) <= 1e-9 * np.linalg.norm(H[k])


def test_state_space_carries_the_port_names(body):
    ss = body.to_scipy()
    assert ss.input_names == INPUTS and ss.output_names == OUTPUTS
    assert body.state_space().input_names == INPUTS
    unnamed = ReducedModel(M=body.M, K=body.K, D=body.D, B=body.B, C=body.C)
    assert unnamed.to_scipy().input_names is None  # no names: none invented


def test_to_control_labels_inputs_and_outputs(body):
    control = pytest.importorskip("control")
    sys = body.to_control()
    assert list(sys.input_labels) == INPUTS and list(sys.output_labels) == OUTPUTS
    w = 2 * np.pi * 237.0
    H = body.frf([237.0])[0]
    assert np.linalg.norm(sys(1j * w) - H) <= 1e-9 * np.linalg.norm(H)
    assert isinstance(sys, control.StateSpace)
    from flexmor.io.statespace import to_control

    same = to_control(body)
    assert isinstance(same, control.StateSpace) and list(same.input_labels) == INPUTS
    assert np.array_equal(same.A, sys.A) and np.array_equal(same.C, sys.C)


def test_simulate_is_the_time_integration_of_the_body(body):
    res = body.simulate(step(), dt=1e-4, t_end=0.02)
    ref = simulate((body.M, body.D, body.K, body.B, body.C), step(), dt=1e-4, t_end=0.02)
    assert res.displacement.shape == (201, 2, 2)
    np.testing.assert_array_equal(res.displacement, ref.displacement)
    # the static limit: a unit tip force bends the tip like Kr^-1 (the last steps oscillate around it)
    static = body.C @ np.linalg.solve(body.K, body.B)
    assert abs(res.displacement[-50:, 0, 0].mean() / static[0, 0] - 1) < 0.5


def test_expand_through_the_couplings_to_the_model_as_read(free):
    spec = "FIX@rbe2"
    c = couple(free, [spec])
    ports = make_ports(c.model, ["TIP:y"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = project(c.model, craig_bampton(c.model, ports, 12, interface=[spec]), ports)
    body.couplings = [spec]
    x = body.expand(free)
    assert x.V.shape == (free.n_dof, body.order) and body.V.shape[0] == c.model.n_dof
    np.testing.assert_allclose(x.V, c.T @ body.V, rtol=0, atol=1e-14 * np.abs(body.V).max())
    np.testing.assert_array_equal(x.node_ids, free.node_ids)
    np.testing.assert_array_equal(x.M, body.M)  # the same reduced body, at other equations
    assert x.couplings == [spec]


def test_order_note_is_a_field(clamped):
    ports = make_ports(clamped, ["TIP:y"])
    body = project(clamped, craig_bampton(clamped, ports, 100, interface=["TIP"]), ports)
    assert body.order == 101  # the square section's bending pair is kept whole
    assert body.order_note.startswith("order 101 instead of 100: mode 100 has 1 more at the same frequency")
    assert "order_note" not in body.info
    assert body.summary()["order_note"] == body.order_note


def test_fields_written_and_read(body, tmp_path):
    import h5py

    b = ReducedModel(**{**body.__dict__, "selections": ["END=box(0.99,-1,-1,1.1,1,1)"], "couplings": ["END@rbe2"],
                        "order_note": "order 7 instead of 8: a reason", "info": dict(body.info)})
    path = tmp_path / "b.h5"
    export(b, path)
    back = read_body(path)
    assert back.selections == b.selections and back.couplings == ["END@rbe2"]
    assert back.order_note == "order 7 instead of 8: a reason"
    assert back.summary()["couplings"] == ["END@rbe2"]
    with h5py.File(path, "r") as h:
        info = json.loads(h.attrs["info"])
        assert json.loads(h.attrs["couplings"]) == ["END@rbe2"]
    assert not {"selections", "couplings", "order_note"} & set(info)


def test_body_written_with_info_keys_is_read_into_fields(body, tmp_path):
    """Bodies written when selections, couplings and the order note were keys of ``info``."""
    import h5py

    path = tmp_path / "old.h5"
    export(body, path)
    with h5py.File(path, "r+") as h:
        for name in ("selections", "couplings", "order_note"):
            del h.attrs[name]
        info = json.loads(h.attrs["info"])
        info.update(selections=["END=box(0.99,-1,-1,1.1,1,1)"], couplings=["END@rbe2"], order_note="a note")
        h.attrs["info"] = json.dumps(info)
    old = read_body(path)
    assert old.selections == ["END=box(0.99,-1,-1,1.1,1,1)"] and old.couplings == ["END@rbe2"]
    assert old.order_note == "a note"
    assert not {"selections", "couplings", "order_note"} & set(old.info)
    np.testing.assert_array_equal(old.K, body.K)


def test_body_with_a_bad_field_is_refused(body, tmp_path):
    import h5py

    from flexmor.errors import ReadError

    path = tmp_path / "bad.h5"
    export(body, path)
    with h5py.File(path, "r+") as h:
        h.attrs["couplings"] = json.dumps("END@rbe2")
    with pytest.raises(ReadError, match="'couplings' must be a JSON list of strings"):
        read_body(path)
