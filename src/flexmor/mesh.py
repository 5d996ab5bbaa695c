"""Element connectivity of a model: :class:`Mesh`, blocks of cells of one type each.

The cell types use meshio's names (``hexahedron``, ``hexahedron20``, ``tetra``, ``tetra10``,
``wedge``, ``quad``, ``quad8``, ``triangle``, ``triangle6``, ``line``, ``line3``, ...), so a
mesh can be handed to meshio and the visualization without translation. Cells refer to
nodes by their ids in the FE file (``FEModel.node_ids``), not by row index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ModelError

__all__ = ["CellBlock", "Mesh", "NODES_PER_CELL"]

#: Nodes per cell of each supported cell type (meshio's names).
NODES_PER_CELL = {
    "vertex": 1, "line": 2, "line3": 3, "triangle": 3, "triangle6": 6, "quad": 4, "quad8": 8,
    "quad9": 9, "tetra": 4, "tetra10": 10, "pyramid": 5, "pyramid13": 13, "wedge": 6,
    "wedge15": 15, "hexahedron": 8, "hexahedron20": 20, "hexahedron27": 27,
}


@dataclass(frozen=True)
class CellBlock:
    """Cells of one type.

    Parameters
    ----------
    type : str
        meshio cell type name, one of :data:`NODES_PER_CELL`.
    nodes : ndarray of int, shape (n_cells, nodes_per_cell)
        Node ids of each cell, in meshio's (= VTK's) node order.
    """

    type: str
    nodes: np.ndarray

    def __post_init__(self):
        if self.type not in NODES_PER_CELL:
            raise ModelError(f"unknown cell type {self.type!r}; known: {', '.join(NODES_PER_CELL)}")
        nodes = np.asarray(self.nodes, dtype=np.int64)
        k = NODES_PER_CELL[self.type]
        if nodes.ndim != 2 or nodes.shape[1] != k:
            raise ModelError(f"{self.type} cells need {k} nodes each, got an array of shape {nodes.shape}")
        object.__setattr__(self, "nodes", nodes)


@dataclass(frozen=True)
class Mesh:
    """Element connectivity of a model, as blocks of cells of one type each."""

    blocks: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "blocks", tuple(self.blocks))

    @property
    def n_cells(self) -> int:
        """Number of cells over all blocks."""
        return sum(len(b.nodes) for b in self.blocks)

    def node_ids(self) -> np.ndarray:
        """Sorted unique ids of the nodes that cells use."""
        if not self.blocks:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate([b.nodes.ravel() for b in self.blocks]))

    def check_nodes(self, node_ids: np.ndarray) -> None:
        """Raise :class:`ModelError` if a cell uses a node that is not in ``node_ids``."""
        used = self.node_ids()
        missing = np.setdiff1d(used, node_ids)
        if missing.size:
            raise ModelError(f"{missing.size} node(s) used by elements are not in the node table, "
                             f"first: {int(missing[0])}")
