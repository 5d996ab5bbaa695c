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


def test_body_carries_its_surface_into_hdf5_and_exudyn(tmp_path):
    """The reduced body stores the outer surface (triangles over node ids); Exudyn's trigList
    indexes the same nodes, and the triangles' area is the box's surface."""
    from flexmor.io import read_body, write_body
    from flexmor.io.exudyn import exudyn_data
    from flexmor.models import cantilever
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    model = cantilever(divisions=(8, 2, 2), clamped=False)
    red = reduce(model, "modal", 8, make_ports(model, ["TIP_CENTER:y"]))
    assert red.triangles is not None and red.triangles.shape[1] == 3
    write_body(red, tmp_path / "b.h5")
    np.testing.assert_array_equal(read_body(tmp_path / "b.h5").triangles, red.triangles)
    trig = exudyn_data(red, model)["trigList"]
    np.testing.assert_array_equal(model.node_ids[trig], red.triangles)
    p = model.xyz[trig]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    a, b, c = model.xyz.max(axis=0) - model.xyz.min(axis=0)
    assert area == pytest.approx(2 * (a * b + b * c + c * a), rel=1e-12)
