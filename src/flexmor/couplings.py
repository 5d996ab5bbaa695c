"""Interface couplings RBE2 (rigid spider) and RBE3 (weighted average) onto a 6-DOF master node.

A coupling SPEC names a node set (or node) and a kind, optionally the master point:

``TIP@rbe2``, ``TIP@rbe3``, ``HOLE@rbe2[0.5,0,0.05]``
    master at the centroid of the set's nodes, or at the given point (model length unit).

RBE2
    The set's DOFs follow the master rigidly: a node at offset ``r = x - x_m`` moves by
    ``u = t + theta x r`` (its rotations, if it has any, equal ``theta``). The set becomes
    rigid.
RBE3
    The master's motion is the weighted least-squares fit of a rigid motion to the
    translations of the set: with weights ``w_i`` (default equal), weighted centroid ``c``,
    ``r_i = x_i - c`` and ``J = sum w_i (|r_i|^2 I - r_i r_i^T)``: ``t_c = sum w_i u_i / sum w_i``,
    ``theta = J^-1 sum w_i r_i x u_i``, ``t_m = t_c + theta x (x_m - c)``, i.e. ``u_m = W q``.
    A force/moment ``F`` at the master is distributed as ``f = W^T F`` (equal virtual work);
    the set is not stiffened. Constrained DOFs of the set count as zero displacement.

Two ways to use them:

* as **ports** on the unchanged model (RBE3 only): ``make_ports(model, ["TIP@rbe3:ry"])``
  gives the column ``W[4]^T`` (a moment about y distributed over the set) and the row
  ``W[4]`` (the set's mean rotation about y);
* as a **transformation of the model**, :func:`couple`: ``q = T q_c``, the coupled model
  ``K_c = T^T K T`` (same for M, D, B, C) has one new master node (in node set ``TIP@RBE2``)
  with 6 equations replacing the dependent ones (all DOFs of an RBE2 set; 6 well-conditioned
  translations of an RBE3 set, chosen by pivoted QR). Any reduction of the coupled model
  (``--interface TIP@rbe2`` gives 6 interface DOFs), and ``T V`` is its basis at the
  original equations; ``V^T K_c V = (T V)^T K (T V)``.

References
----------
MSC Nastran Quick Reference Guide, bulk data entries RBE2 and RBE3.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .errors import ModelError, PortError, did_you_mean
from .linalg.distributed import is_partitioned
from .model import FEModel

__all__ = ["parse_coupling", "is_coupling", "rbe2_matrix", "rbe3_matrix", "couple", "Coupled", "port_row",
           "coupling_masters"]

log = logging.getLogger(__name__)

_SPEC = re.compile(r"^\s*(?P<target>[^@\[\]:]+?)\s*@\s*(?P<kind>rbe2|rbe3)\s*(?:\[(?P<pt>[^\]]*)\])?\s*$", re.I)


def is_coupling(target: str) -> bool:
    """Whether a SPEC target (the part before ``:DIR``) names a coupling."""
    return "@" in str(target)


def parse_coupling(target: str):
    """Split ``SET@rbe2[x,y,z]`` into ``(set, 'rbe2', point or None)``.

    Raises
    ------
    PortError
        When the kind is not rbe2/rbe3 or the point is not three numbers.
    """
    m = _SPEC.match(str(target))
    if not m:
        raise PortError(f"coupling {target!r}: expected SET@rbe2 or SET@rbe3, optionally with a master point "
                        "[x,y,z]")
    pt = None
    if m.group("pt") is not None:
        try:
            pt = np.array([float(v) for v in m.group("pt").split(",")])
        except ValueError:
            pt = None
        if pt is None or pt.shape != (3,) or not np.all(np.isfinite(pt)):
            raise PortError(f"coupling {target!r}: the master point must be [x,y,z] with three numbers")
    return m.group("target"), m.group("kind").lower(), pt


def _set_nodes(model: FEModel, name: str, spec: str) -> np.ndarray:
    if name.upper() in model.node_sets:
        nodes = model.node_sets[name.upper()]
    elif name.strip().lstrip("-").isdigit() and model.has_node(int(name)):
        nodes = np.array([int(name)], dtype=np.int64)
    else:
        sets = ", ".join(sorted(model.node_sets)) or "none"
        raise PortError(f"coupling {spec!r}: {name!r} is neither a node set nor a node; "
                        f"{did_you_mean(name, model.node_sets)}(sets: {sets})")
    if model.dofs is None or not model.n_nodes:
        raise PortError(f"coupling {spec!r}: the model has no node table and equation map")
    if nodes.size == 0:
        raise PortError(f"coupling {spec!r}: node set {name!r} is empty")
    local = [int(k) for k in nodes if int(k) in model.node_frames]
    if local:
        raise PortError(f"coupling {spec!r}: node {local[0]} has local displacement directions (a Nastran CD "
                        "system); couplings need global x y z: read the model with directions='basic'")
    return nodes


def _master(model, nodes, pt):
    return model.node_xyz(nodes).mean(axis=0) if pt is None else pt


def _skew(r):
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def rbe2_matrix(model: FEModel, nodes, master) -> tuple[np.ndarray, np.ndarray]:
    """Rigid kinematics of the equations of ``nodes``: ``q[eqs] = G @ u_m``.

    Returns
    -------
    eqs : ndarray of int, shape (k,)
        All equations of the nodes (translations and rotations present in the model).
    G : ndarray, shape (k, 6)
    """
    eqs = np.flatnonzero(np.isin(model.dofs[:, 0], nodes))
    G = np.zeros((eqs.size, 6))
    r = model.node_xyz(model.dofs[eqs, 0]) - master
    for k, d in enumerate(model.dofs[eqs, 1]):
        if d <= 3:
            G[k, d - 1] = 1.0
            G[k, 3:] = -_skew(r[k])[d - 1]  # (theta x r)_d = (-[r]x theta)_d
        else:
            G[k, d - 1] = 1.0
    return eqs, G


def rbe3_matrix(model: FEModel, nodes, master, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares rigid fit of the translations of ``nodes``: ``u_m = W @ q[eqs]``.

    Parameters
    ----------
    model : FEModel
    nodes : array of int
        Node ids of the set.
    master : array of float, shape (3,)
        Master point.
    weights : array of float, optional
        One weight per node (default 1).

    Returns
    -------
    eqs : ndarray of int, shape (k,)
        The translational equations of the nodes (constrained ones are absent: zero motion).
    W : ndarray, shape (6, k)

    Raises
    ------
    PortError
        When the nodes lie on one line (or are one node): rotations cannot be fitted.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    w = np.ones(nodes.size) if weights is None else np.asarray(weights, dtype=np.float64)
    x = model.node_xyz(nodes)
    c = w @ x / w.sum()
    r = x - c
    J = sum(wi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for wi, ri in zip(w, r))
    if np.linalg.matrix_rank(J, tol=1e-10 * max(np.trace(J), 1e-300)) < 3:
        raise PortError(f"RBE3 over {nodes.size} node(s) on one line: rotations about that line are undefined; "
                        "use a set with nodes off the line")
    Jinv = np.linalg.inv(J)
    pos = {int(n): i for i, n in enumerate(nodes)}
    eqs = np.flatnonzero(np.isin(model.dofs[:, 0], nodes) & (model.dofs[:, 1] <= 3))
    W = np.zeros((6, eqs.size))
    d_m = _skew(np.asarray(master, dtype=np.float64) - c)
    for k, e in enumerate(eqs):
        i, d = pos[int(model.dofs[e, 0])], model.dofs[e, 1] - 1
        rot = w[i] * Jinv @ _skew(r[i])[:, d]  # theta from u_i,d
        W[3:, k] = rot
        W[:3, k] = (w[i] / w.sum()) * np.eye(3)[:, d] - d_m @ rot  # t_m = t_c - [x_m - c]x theta
    return eqs, W


def port_row(model: FEModel, target: str, direction: int):
    """Equations and weights of a port ``SET@rbe3:DIR`` on the unchanged model (row ``W[DIR]``).

    Raises
    ------
    PortError
        For RBE2 (a kinematic constraint: apply :func:`couple` first) and bad sets.
    """
    name, kind, pt = parse_coupling(target)
    if kind == "rbe2":
        raise PortError(f"port {target!r}: RBE2 makes the set rigid, which changes the model; use "
                        f"flexmor.couplings.couple(model, [{target!r}]) first, or {name}@rbe3 as a port")
    nodes = _set_nodes(model, name, target)
    eqs, W = rbe3_matrix(model, nodes, _master(model, nodes, pt))
    return eqs, W[direction - 1]


@dataclass
class Coupled:
    """A coupled model and its transformation ``q = T q_c``.

    Attributes
    ----------
    model : FEModel
        The coupled model (master nodes added, dependent equations removed).
    T : scipy.sparse.csr_matrix, shape (n_dof original, n_dof coupled)
    masters : dict of str to int
        Master node id of each coupling (key: the node-set name, e.g. ``TIP@RBE2``).
    """

    model: FEModel
    T: sp.csr_matrix
    masters: dict

    def expand(self, V):
        """The basis ``T V`` at the equations of the original model."""
        return self.T @ V


class _Constraint(NamedTuple):
    """The kinematics of one coupling: ``q[dependent] = to_master @ u_m + to_others @ q[others]``.

    The dependent equations leave the coupled model (the master's 6 DOFs replace them); the
    others (RBE3: the set's translations beyond the 6 chosen ones) stay.
    """

    target: str
    kind: str
    nodes: np.ndarray
    master_xyz: np.ndarray
    dependent: np.ndarray
    to_master: np.ndarray  # (dependent.size, 6)
    others: np.ndarray
    to_others: np.ndarray  # (dependent.size, others.size)


def _coupling_targets(specs) -> list[str]:
    """The coupling SPECs among ``specs`` (``:DIR`` suffixes dropped), each once, in order."""
    targets = []
    for s in specs:
        t = str(s).rsplit(":", 1)[0] if re.search(r":\s*r?[xyz]\s*$", str(s), re.I) else str(s)
        if is_coupling(t) and t.strip().upper() not in [x.strip().upper() for x in targets]:
            targets.append(t.strip())
    return targets


def _constraint(model: FEModel, target: str, weights: dict | None) -> _Constraint:
    """The dependent equations of one coupling and their coefficients."""
    name, kind, pt = parse_coupling(target)
    nodes = _set_nodes(model, name, target)
    xm = _master(model, nodes, pt)
    if kind == "rbe2":
        eqs, G = rbe2_matrix(model, nodes, xm)
        return _Constraint(target, kind, nodes, xm, eqs, G, np.zeros(0, np.int64), np.zeros((eqs.size, 0)))
    eqs, W = rbe3_matrix(model, nodes, xm, (weights or {}).get(target.upper()))
    if eqs.size < 6:
        raise PortError(f"coupling {target!r}: {eqs.size} free translations, RBE3 needs at least 6")
    _, _, piv = sla.qr(W, pivoting=True, mode="economic")
    d_idx, o_idx = np.sort(piv[:6]), np.sort(piv[6:])
    Wd_inv = np.linalg.inv(W[:, d_idx])  # q_d = Wd^-1 u_m - Wd^-1 Wo q_o
    return _Constraint(target, kind, nodes, xm, eqs[d_idx], Wd_inv, eqs[o_idx], -Wd_inv @ W[:, o_idx])


def _check_disjoint(constraints: list[_Constraint], n: int) -> np.ndarray:
    """The dependent equations of all couplings (a mask), refusing couplings that share equations."""
    dependent = np.zeros(n, bool)
    for c in constraints:
        if np.any(dependent[c.dependent]) or np.any(dependent[c.others]):
            raise PortError(f"coupling {c.target!r} shares equations with another coupling")
        dependent[c.dependent] = True
    if any(np.any(dependent[c.others]) for c in constraints):
        raise PortError("an RBE3 set uses equations that another coupling makes dependent")
    return dependent


def _transformation(constraints: list[_Constraint], dependent: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """``T`` of ``q = T q_c`` and the kept equations: ``q_c`` is the kept equations, then 6 per master."""
    n = dependent.size
    keep = np.flatnonzero(~dependent)
    col_of = -np.ones(n, np.int64)
    col_of[keep] = np.arange(keep.size)
    rows, cols, vals = [keep], [np.arange(keep.size)], [np.ones(keep.size)]
    for k, c in enumerate(constraints):
        rows.append(np.repeat(c.dependent, 6))
        cols.append(np.tile(keep.size + 6 * k + np.arange(6), c.dependent.size))
        vals.append(np.asarray(c.to_master, float).ravel())
        rows.append(np.repeat(c.dependent, c.others.size))
        cols.append(np.tile(col_of[c.others], c.dependent.size))
        vals.append(np.asarray(c.to_others, float).ravel())
    n_c = keep.size + 6 * len(constraints)
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n_c))
    T.eliminate_zeros()
    return T, keep


def _coupled_model(model: FEModel, constraints: list[_Constraint], T: sp.csr_matrix, keep: np.ndarray):
    """``T^T K T`` (M, D, B, C alike) with the master nodes added; returns ``(model, masters)``."""
    first = int(model.node_ids.max()) + 1
    new_ids = [first + k for k in range(len(constraints))]
    masters, sets = {}, dict(model.node_sets)
    for c, mid in zip(constraints, new_ids):
        key = c.target.replace(" ", "").upper()
        masters[key] = mid
        sets[key] = np.array([mid], dtype=np.int64)
        log.info("%s: %s over %d nodes, master node %d at %s", model.name, c.kind.upper(), c.nodes.size, mid,
                 c.master_xyz)
    master_dofs = np.stack([np.repeat(new_ids, 6), np.tile(np.arange(1, 7), len(new_ids))], axis=1)
    Tt = T.T.tocsr()
    try:
        coupled = dataclasses.replace(
            model,
            M=(Tt @ model.M @ T).tocsr(), K=(Tt @ model.K @ T).tocsr(),
            D=None if model.D is None else (Tt @ model.D @ T).tocsr(),
            B=None if model.B is None else (Tt @ model.B).tocsr(),
            C=None if model.C is None else (model.C @ T).tocsr(),
            node_ids=np.concatenate([model.node_ids, new_ids]),
            xyz=np.vstack([model.xyz] + [c.master_xyz for c in constraints]),
            dofs=np.concatenate([model.dofs[keep], master_dofs]), node_sets=sets,
            name=f"{model.name}+" + "+".join(c.target.upper() for c in constraints))
    except ModelError as exc:
        raise PortError(f"coupled model is invalid: {exc}") from None
    return coupled, masters


def couple(model: FEModel, specs, *, weights: dict | None = None) -> Coupled:
    """Apply RBE2/RBE3 couplings as a transformation of the model.

    Parameters
    ----------
    model : FEModel
    specs : sequence of str
        Coupling SPECs (``TIP@rbe2``, ``HOLE@rbe3[0,0,1]``); a ``:DIR`` suffix and SPECs
        without ``@`` are ignored, so all port and interface SPECs may be passed at once.
    weights : dict, optional
        RBE3 weights per node of a set: ``{"TIP@RBE3": array}``.

    Returns
    -------
    Coupled

    Raises
    ------
    PortError
        Unknown sets, sets sharing equations, collinear RBE3 sets, a coupled model without
        mass at a master direction.
    """
    targets = _coupling_targets(specs)
    if not targets:
        raise PortError("no coupling SPEC (SET@rbe2 or SET@rbe3) given")
    if is_partitioned(model.K):  # T^T K T needs whole rows and columns of K
        raise PortError(f"couplings ({', '.join(targets)}) need the whole model in one process, but its rows are "
                        "spread over MPI ranks; apply them before the rows are distributed, or run serially "
                        "(backend other than 'petsc')", params=("backend",))
    constraints = [_constraint(model, t, weights) for t in targets]
    dependent = _check_disjoint(constraints, model.n_dof)
    T, keep = _transformation(constraints, dependent)
    coupled, masters = _coupled_model(model, constraints, T, keep)
    return Coupled(coupled, T, masters)


def coupling_masters(model: FEModel) -> list[dict]:
    """The coupling masters of a coupled model (its node sets ``NAME@RBE2`` / ``NAME@RBE3`` of one node).

    Returns
    -------
    list of dict
        ``name`` (e.g. ``HOLE@RBE2``), ``id`` (the master's node id), ``kind`` (``rbe2``/``rbe3``),
        ``xyz`` (its position), ``slaves`` (node ids of the coupled set), in the model's order.
    """
    from .errors import FlexmorError

    out = []
    for key, ids in model.node_sets.items():
        if "@" not in key or np.size(ids) != 1:
            continue
        try:
            name, kind, _ = parse_coupling(key)
        except FlexmorError:  # a set name with '@' that is no coupling
            continue
        nodes = model.node_sets.get(name.strip().upper())
        if nodes is None and name.strip().lstrip("-").isdigit():
            nodes = np.array([int(name)], dtype=np.int64)
        if nodes is None or not model.has_node(int(ids[0])):
            continue
        nodes = np.asarray([n for n in np.atleast_1d(nodes) if model.has_node(int(n))], dtype=np.int64)
        out.append({"name": key, "id": int(ids[0]), "kind": kind, "xyz": model.node_xyz([int(ids[0])])[0].tolist(),
                    "slaves": nodes})
    return out
