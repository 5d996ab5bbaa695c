import numpy as np
import pytest

from flexmor.errors import PortError
from flexmor.ports import interface_dofs, make_ports


def test_set_port_weights_and_collocation(clamped):
    p = make_ports(clamped, ["TIP:y", "11:z"])
    B = p.B.toarray()
    np.testing.assert_allclose(B.sum(axis=0), [1.0, 1.0])
    assert np.count_nonzero(B[:, 0]) == 9
    assert (p.C != p.B.T).nnz == 0
    i = clamped.dof_index(11, 3)
    assert B[i, 1] == 1.0


def test_constrained_nodes_keep_their_weight(clamped):
    # FIX nodes are clamped: no equation, yet the weights are 1/9 for the three... none exist
    with pytest.raises(PortError, match="no free equation"):
        make_ports(clamped, ["FIX:y"])


@pytest.mark.parametrize("spec,msg", [("999:y", "not in the model"), ("TIP:w", "unknown direction"),
                                      ("NOPE:y", "neither a node id nor a node set"), ("TIP", "give a direction")])
def test_bad_specs(clamped, spec, msg):
    with pytest.raises(PortError, match=msg):
        make_ports(clamped, [spec])


def test_interface_dofs(clamped):
    b = interface_dofs(clamped, ["TIP"])
    assert b.size == 27
    assert interface_dofs(clamped, ["TIP:x", "TIP:y"]).size == 18
