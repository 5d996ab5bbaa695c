"""Equation maps of CalculiX jobs whose shell or beam elements were expanded to solids.

CalculiX replaces every shell (S8R, S6 ...) and beam (B32R, B31 ...) element by a C3D20R
(C3D15, C3D8I) solid: each shell node becomes 3 nodes (through the thickness), each beam node
4 or 8 (around the section). The new nodes are numbered after the largest node of the deck and
appear in the job's ``.frd`` node block (with ``*NODE FILE`` output), not in the deck. The
matrices of ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` act on the expanded nodes, but the ``.dof``
file labels each equation with the *original* node, so one ``node.direction`` pair occurs
several times. The equations follow the expanded nodes in ascending order, three directions
each; an expanded node belongs to the original node nearest to it (the expansion is normal to
the shell, or in the plane of the beam's section).

:func:`expanded_dofs` rebuilds the map when every expanded node carries equations (a body
without constraints on shell or beam nodes). A constraint on a shell or beam node removes
some of its expanded nodes' equations in a way the files do not record; such jobs are
refused with a clear error.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ...errors import ReadError

__all__ = ["expanded_dofs"]

log = logging.getLogger(__name__)


def expanded_dofs(dof_path: Path, dofs, node_ids, xyz, frd_ids, frd_xyz, sets):
    """Map the equations of an expanded job to the expanded nodes.

    Parameters
    ----------
    dof_path : Path
        The ``.dof`` file (named in errors).
    dofs : ndarray, shape (n_dof, 2)
        Equation map as read (original node, direction).
    node_ids, xyz : ndarray
        Nodes of the deck.
    frd_ids, frd_xyz : ndarray
        Nodes of the ``.frd`` node block (the expanded nodes among them).
    sets : dict of str to ndarray
        Node sets of the deck.

    Returns
    -------
    dofs : ndarray, shape (n_dof, 2)
        Equation map on the expanded nodes.
    node_ids, xyz : ndarray
        The expanded nodes.
    sets : dict
        Each set holds the expanded nodes of its members.

    Raises
    ------
    ReadError
        When the equations cannot be assigned to the expanded nodes one to one.
    """
    new = ~np.isin(frd_ids, node_ids)
    order = np.argsort(frd_ids[new])
    eids, exyz = frd_ids[new][order], frd_xyz[new][order]
    starts = np.flatnonzero(np.r_[True, (np.diff(dofs[:, 1]) <= 0) | (np.diff(dofs[:, 0]) != 0)])
    labels = dofs[starts, 0]
    owner = node_ids[cKDTree(xyz).query(exyz)[1]] if eids.size else eids
    if eids.size != starts.size or not np.array_equal(owner, labels):
        raise ReadError(dof_path, f"equations name nodes repeatedly ({starts.size} node groups on "
                                  f"{np.unique(labels).size} nodes): CalculiX expanded shell or beam elements to "
                                  f"solids ({eids.size} new nodes in the .frd), and constraints on shell or beam "
                                  "nodes removed expanded equations in a way the files do not record; export the "
                                  "unconstrained body (no *BOUNDARY on shell or beam nodes), with *NODE FILE output")
    node_of_group = np.repeat(eids, np.diff(np.r_[starts, dofs.shape[0]]))
    out = np.column_stack([node_of_group, dofs[:, 1]])
    new_sets = {name: eids[np.isin(owner, members)] for name, members in sets.items()}
    log.warning("%s: CalculiX expanded shell/beam elements to solids; the %d equations are mapped to the %d "
                "expanded nodes of the .frd, and node sets to the expanded nodes of their members",
                dof_path, dofs.shape[0], eids.size)
    return out, eids, exyz, new_sets
