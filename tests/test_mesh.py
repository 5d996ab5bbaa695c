"""The element-connectivity container :class:`flexmor.mesh.Mesh` and its check in FEModel."""

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.errors import ModelError
from flexmor.mesh import CellBlock, Mesh
from flexmor.model import FEModel


def _two_node_model(mesh):
    n = 6
    return FEModel(M=sp.identity(n), K=sp.identity(n), node_ids=np.array([1, 2]),
                   xyz=np.zeros((2, 3)), dofs=np.array([[1, d] for d in (1, 2, 3)] + [[2, d] for d in (1, 2, 3)]),
                   mesh=mesh)


def test_cells_must_have_the_nodes_of_their_type():
    with pytest.raises(ModelError, match="tetra cells need 4 nodes"):
        CellBlock("tetra", np.array([[1, 2, 3]]))
    with pytest.raises(ModelError, match="unknown cell type"):
        CellBlock("brick", np.array([[1, 2]]))


def test_model_refuses_elements_on_unknown_nodes():
    ok = _two_node_model(Mesh([CellBlock("line", np.array([[1, 2]]))]))
    assert ok.mesh.n_cells == 1 and list(ok.mesh.node_ids()) == [1, 2]
    with pytest.raises(ModelError, match="not in the node table, first: 3"):
        _two_node_model(Mesh([CellBlock("line", np.array([[1, 3]]))]))
