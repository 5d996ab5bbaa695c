"""Load stiffening of a reduced body: the geometric stiffness of its elastic coordinates per unit load.

A body that an MBS code accelerates, spins and loads at its joints stiffens with the stresses of
those loads (a blade under centrifugal tension, a column under its own weight). The stresses are
linear in the loads, so is their geometric stiffness ``K_G`` (:func:`flexmor.preload.geometric_stiffness`):
the MBS code needs one matrix ``Vᵀ K_G V`` per unit load and scales it by the load it applies. The
unit loads are those of the floating frame of reference (Schwertassek & Wallrapp 1999, ch. 6):

* the frame's **translational accelerations** ``a_x, a_y, a_z``: the inertia load ``-M S_t e_i``;
* its **angular accelerations** ``α_x, α_y, α_z`` (about the frame origin): ``-M S_r e_i``;
* the **centrifugal** load of its angular velocity ``-M ω̃ω̃ r``, quadratic in ω: one load per product
  ``ωx² ωy² ωz² ωxωy ωyωz ωxωz`` (the order of the SID ``Oe`` columns);
* unit **forces and moments at each frame node** (a coupling master, a node, the RBE3 centroid of
  a set), spread to the model as the node's displacement is taken from it (``Wᵀ e``).

Each load's static deflection is solved on the model the body was reduced on (its couplings applied):
a supported model as it is, a free one held clamped at its first interface (as the static error check
holds it: the joint through which the MBS drives the body takes the reactions). The stresses are then
recovered on the model as read and ``K_G`` projected on the expanded basis ``T V``. With the spin
softening of the mass terms (in the SID ``Oe``), the stiffness of a body spinning at ω about an axis is
``Ke + Σ_k ω_k Oe1_k``, equal to the projection of ``--preload spin:`` on the same support.

Costs one sparse factorization, ``12 + 6 n_nodes`` solves and as many element passes of the stress
recovery.

References
----------
R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6 (the
geometric stiffening of the elastic coordinates in the Standard Input Data).

O. Wallrapp, Standardization of flexible body modeling in multibody system codes, Part I: Definition of
standard input data, *Mechanics of Structures and Machines* 22(3):283-304, 1994.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .errors import ModelError

__all__ = ["CENTRIFUGAL", "LoadStiffening", "centrifugal_loads", "load_stiffening"]

log = logging.getLogger(__name__)

#: The products of the angular velocity of the centrifugal unit loads, in the order of the SID ``Oe`` columns.
CENTRIFUGAL = ("wx2", "wy2", "wz2", "wxwy", "wywz", "wxwz")
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


@dataclass
class LoadStiffening:
    """The geometric stiffness ``Vᵀ K_G V`` of the body's elastic coordinates per unit load.

    Attributes
    ----------
    support : str
        How the model was held for the loads' stresses: ``supported`` or ``clamped at INTERFACE``.
    acceleration : ndarray (3, r, r)
        Unit translational accelerations of the frame ``a_x, a_y, a_z`` (m/s²).
    angular : ndarray (3, r, r)
        Unit angular accelerations ``α_x, α_y, α_z`` (rad/s²).
    centrifugal : ndarray (6, r, r)
        Unit products of the angular velocity (:data:`CENTRIFUGAL`, (rad/s)²).
    nodes : dict of int to ndarray (6, r, r)
        Per frame node id: unit forces x y z (N) and moments rx ry rz (N m) at the node (zero where the node
        has no such direction, or is held).
    """

    support: str
    acceleration: np.ndarray
    angular: np.ndarray
    centrifugal: np.ndarray
    nodes: dict = field(default_factory=dict)

    def spin(self, w) -> np.ndarray:
        """The geometric stiffness of a spin at angular velocity ``w`` (rad/s, (3,)): ``Σ_k ω_k centrifugal_k``."""
        w = np.asarray(w, dtype=float)
        return np.einsum("k,kab->ab", np.array([w[i] * w[j] for i, j in _PAIRS]), self.centrifugal)


def centrifugal_loads(model) -> np.ndarray:
    """The centrifugal unit loads ``-M ω̃ω̃ r`` of the model's translations, one column per product of
    :data:`CENTRIFUGAL` (n_dof, 6): the load of an angular velocity ω is ``Σ_k ω_k load_k``."""
    from .preload import preload_load

    cols = []
    for i, j in _PAIRS:  # the bilinear load of (e_i, e_j) by polarisation: F(e_i + e_j) - F(e_i) - F(e_j)
        def f(w):
            return preload_load(model, "spin:" + ",".join(repr(float(v)) for v in w))[0]
        if i == j:
            cols.append(f(np.eye(3)[i]))
        else:
            cols.append(f(np.eye(3)[i] + np.eye(3)[j]) - f(np.eye(3)[i]) - f(np.eye(3)[j]))
    return np.column_stack(cols)


def _support(coupled_model, body):
    """``(description, held equations)`` of the coupled model: none for a supported model, the first interface
    clamped for a free one; ModelError for a free body without interface."""
    from .rigid import rigid_body_modes
    from .support import AS_SUPPORTED, supports

    if rigid_body_modes(coupled_model).shape[1] == 0:
        return AS_SUPPORTED, np.zeros(0, dtype=np.int64)
    cases = supports(coupled_model, body, held=("clamped",))
    if not cases:
        raise ModelError("a free body without interface has no static equilibrium under a load: its load "
                         "stiffening needs an interface (a coupling or a Craig-Bampton interface) to hold it at",
                         params=("stiffening",))
    return f"clamped at {cases[0].interface}", np.asarray(cases[0].eqs, dtype=np.int64)


def load_stiffening(xb, nodes=(), *, material=None, solver=None, progress=None) -> LoadStiffening:
    """The load stiffening of an expanded body (:func:`flexmor.expansion.expand_body`).

    Parameters
    ----------
    xb : ExpandedBody
        The body at the model as read (its couplings in ``xb.coupled``).
    nodes : sequence of FrameNode
        Frame nodes whose unit forces and moments are wanted (:func:`flexmor.io.invariants.frame_nodes`).
    material : Material or tuple, optional
        In place of the deck's materials (as ``--material`` of a preload).
    solver : SolverContext, optional
        Backend of the factorization.
    progress : callable, optional
        The progress callback of :func:`flexmor.linalg.context.track` (one step per unit load's stresses).

    Returns
    -------
    LoadStiffening

    Raises
    ------
    ModelError
        A free body without interface; a model without solid elements and materials
        (:mod:`flexmor.stress`).
    """
    from .linalg import factorize
    from .linalg.context import track
    from .preload import geometric_stiffness
    from .stress import integration_points

    model, c = xb.model, xb.coupled
    coupled = model if c is None else c.model
    T = sp.identity(model.n_dof, format="csr") if c is None else sp.csr_matrix(c.T)
    next(integration_points(model, np.zeros(model.n_dof), material=material), None)  # elements checked first
    held, eqs = _support(coupled, xb.body)
    free = np.setdiff1d(np.arange(coupled.n_dof), eqs)
    V = np.asarray(xb.V, dtype=float)
    r = V.shape[1]
    from .rigid import rigid_motions

    R = rigid_motions(model, origin=np.zeros(3))  # translations and rotations about the frame origin
    read_loads = np.hstack([-(model.M @ R), centrifugal_loads(model)])
    loads = [np.asarray(T.T @ read_loads)]
    for nd in nodes:
        space, idx, W = nd.load if nd.load is not None else ("read", np.zeros(0, np.int64), np.zeros((6, 0)))
        F = np.zeros((model.n_dof if space == "read" else coupled.n_dof, 6))
        F[np.asarray(idx, dtype=np.int64)] = np.asarray(W).T
        loads.append(np.asarray(T.T @ F) if space == "read" else F)
    B = np.hstack(loads)
    Kf = coupled.K[free][:, free].tocsr()
    U = np.zeros_like(B)
    U[free] = np.asarray(factorize(Kf, solver=solver, positive=True).solve(B[free])).reshape(free.size, -1)
    U = np.asarray(T @ U)
    out = np.zeros((B.shape[1], r, r))
    for k in track(progress, range(B.shape[1]), B.shape[1], "load stiffening"):
        if np.any(U[:, k]):
            KG = geometric_stiffness(model, U[:, k], material=material)
            G = V.T @ (KG @ V)
            out[k] = 0.5 * (G + G.T)
    log.info("load stiffening of %d unit loads, %s", B.shape[1], held)
    per_node = {int(nd.id): out[12 + 6 * i:18 + 6 * i] for i, nd in enumerate(nodes)}
    return LoadStiffening(held, out[:3], out[3:6], out[6:12], per_node)
