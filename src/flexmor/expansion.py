"""The body at every node of the FE model as read: its basis expanded through its couplings.

A body with interface couplings (``--interface HOLE@rbe2``, ports ``HOLE@rbe2:x``) is reduced
on the coupled model ``q = T q_c`` (:func:`flexmor.couplings.couple`): the set's equations are
replaced by the six of a new master node, and the basis ``V`` lives at the coupled model's
equations. What a multibody code needs is the body at the nodes of the FE model it knows: the
slaves of an RBE2 move rigidly with their master, those of an RBE3 as the model says, and the
master is a 6-DOF node of the body (translations and rotations) with one id everywhere.

:func:`expand_body` gives that view from the model **as read** (the body applies its own
selections and couplings, and is checked against the fingerprint of the model it came from):

* ``V_x = T V`` at every equation of the model as read (slaves included). Since
  ``V^T K_c V = (T V)^T K (T V)`` (same for ``M``, ``D``), the inertia invariants and the
  mass properties integrated over the model as read with ``V_x`` are those of the reduced body;
* each master as a :class:`MasterNode`: its id (the coupled model's), position, slave nodes and
  its six rows of ``V`` (x y z rx ry rz in the body's coordinates). The masters carry no mass
  of their own: the slaves carry it.

Exporters (SID, Exudyn, VTU, MATLAB) use this one view, so an interface reaches the MBS code
with its master and its slaves.

References
----------
MSC Nastran Quick Reference Guide, bulk data entries RBE2 and RBE3.

R. Schwertassek, O. Wallrapp, *Dynamik flexibler Mehrkörpersysteme*, Vieweg, 1999, ch. 6.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np

from .errors import ModelError

__all__ = ["MasterNode", "ExpandedBody", "expand_body", "expanded_reduced"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MasterNode:
    """The master node of one coupling of a body.

    Attributes
    ----------
    id : int
        Node id (the coupled model's, also in ``flexmor info BODY.h5``, SID and Exudyn).
    name : str
        The coupling's node set name, e.g. ``HOLE@RBE2``.
    kind : {'rbe2', 'rbe3'}
    xyz : ndarray, shape (3,)
        Position (model length unit).
    slaves : ndarray of int
        Node ids of the coupled set.
    rows : ndarray, shape (6, r)
        The master's x, y, z, rx, ry, rz in the body's coordinates (rows of ``V``).
    eqs : tuple of int
        Its six equations in the coupled model (x y z rx ry rz).
    """

    id: int
    name: str
    kind: str
    xyz: np.ndarray
    slaves: np.ndarray
    rows: np.ndarray
    eqs: tuple = ()

    def matches(self, target) -> bool:
        """Whether ``target`` (a coupling SPEC such as ``HOLE@rbe2``, the set name or the node id) names it."""
        t = str(target).strip()
        if t.lstrip("-").isdigit():
            return int(t) == self.id
        return t.replace(" ", "").upper() == self.name


@dataclass
class ExpandedBody:
    """A body at the equations of the FE model as read, with its masters.

    Attributes
    ----------
    body : ReducedModel
        The body (its reduced matrices; for a free body the elastic body the floating frame
        takes, :func:`flexmor.rigid.elastic_body`).
    model : FEModel
        The model as read, with the body's node selections.
    V : ndarray, shape (model.n_dof, r)
        The basis at the model's equations (``T V``; the body's ``V`` without couplings).
    masters : list of MasterNode
        One per coupling, in the body's order.
    coupled : Coupled or None
        The body's couplings on the model (:func:`flexmor.couplings.couple`: the coupled model the body
        was reduced on and ``T``); None for a body without couplings.
    """

    body: object
    model: object
    V: np.ndarray
    masters: list = field(default_factory=list)
    coupled: object = None

    @property
    def node_ids(self) -> np.ndarray:
        """Node ids of the model followed by the masters' ids."""
        return np.concatenate([self.model.node_ids, np.array([m.id for m in self.masters], dtype=np.int64)])

    @property
    def xyz(self) -> np.ndarray:
        """Coordinates of :attr:`node_ids`."""
        return np.vstack([self.model.xyz] + [m.xyz[None, :] for m in self.masters])


def expand_body(model, body, path="the body", *, elastic: bool = True, remove_rigid: bool = False) -> ExpandedBody:
    """The body at every equation of ``model`` (as read) and its coupling masters.

    Parameters
    ----------
    model : FEModel
        The FE model the body was reduced from, **as read** (its couplings not applied: the body
        applies ``body.couplings`` and ``body.selections`` itself). For a body without
        couplings, the model it was reduced on.
    body : ReducedModel
        With its basis ``V``.
    path : str
        Where the body was read from (named in errors).
    elastic : bool
        Take the body the floating frame needs: a basis without rigid-body motion
        (:func:`flexmor.rigid.elastic_body`, which refuses a body that holds
        rigid motion unless ``remove_rigid``).
    remove_rigid : bool
        Allow the export to remove rigid-body motion from the basis (another body than the one
        reduced and judged: its order and error change).

    Returns
    -------
    ExpandedBody

    Raises
    ------
    ModelError
        No basis, a model of another size or fingerprint, the coupled model given instead of
        the model as read.
    """
    from .couplings import parse_coupling
    from .origin import applied_to, check_origin, with_body_damping

    if body.V is None:
        raise ModelError("the reduced body holds no basis V (e.g. a Nastran superelement); reduce "
                         "the model with flexmor, whose bodies store V")
    couplings = tuple(body.couplings)
    keys = [c.replace(" ", "").upper() for c in couplings]
    rows = np.shape(body.V)[0]
    if couplings and all(k in model.node_sets for k in keys) and rows == model.n_dof:
        raise ModelError(f"{model.source or model.name} is the coupled model ({', '.join(couplings)} applied); give "
                         "the FE model as read: the body applies its couplings itself and expands its basis to "
                         "their slave nodes", params=("model",))
    ref, c = applied_to(model, body)
    reduced_on = ref if c is None else c.model
    if reduced_on.n_dof != rows:
        raise ModelError(f"basis has {rows} rows, but the model {reduced_on.name!r} has {reduced_on.n_dof} equations; "
                         "export needs the model the body was reduced from", params=("model",))
    if c is not None:
        check_origin(body, reduced_on, path, couplings=couplings)
    if elastic:
        body = _elastic(with_body_damping(reduced_on, body, path), body, remove_rigid)
    if c is None:
        return ExpandedBody(body, ref, np.asarray(body.V, dtype=float), [])
    V = np.asarray(body.V, dtype=float)
    eq = {(int(n), int(d)): i for i, (n, d) in enumerate(c.model.dofs)}
    masters = []
    for spec, key in zip(couplings, keys):
        mid = int(c.masters[key])
        name, kind, _ = parse_coupling(spec)
        name = name.strip().upper()
        slaves = ref.node_sets[name] if name in ref.node_sets else np.array([int(name)], dtype=np.int64)
        idx = [eq[(mid, d)] for d in range(1, 7)]
        masters.append(MasterNode(mid, key, kind, c.model.node_xyz([mid])[0].copy(), slaves, V[idx].copy(), tuple(idx)))
    Vx = np.asarray(c.T @ V)
    log.info("%s: basis expanded through %s to %d equations", body.method, ", ".join(couplings), ref.n_dof)
    return ExpandedBody(body, ref, Vx, masters, c)


def _elastic(model, body, remove_rigid):
    from .rigid import elastic_body

    return elastic_body(model, body, remove_rigid=remove_rigid)


def expanded_reduced(xb: ExpandedBody):
    """The body of ``xb`` as a :class:`~flexmor.body.ReducedModel` at the model's equations
    (``V`` expanded, the model's node table and equation map)."""
    m = xb.model
    return dataclasses.replace(xb.body, V=xb.V, node_ids=m.node_ids, xyz=m.xyz, dofs=m.dofs)
