"""Inputs, outputs and interfaces of a model, addressed by node and direction.

A port SPEC is a string:

``NODE:DIR``
    one node id and a direction ``x y z rx ry rz`` (e.g. ``42:y``);
``SET:DIR``
    a node set of the model (e.g. ``TIP:y``). As an **input**, a unit total force is
    spread over the set with equal weights ``1/k`` on each of its ``k`` nodes; as an
    **output**, the displacement is averaged with the same weights (an RBE3-like
    distributing coupling with uniform weights, so ``C = B^T`` for the same SPEC). Nodes of
    the set whose direction is constrained (removed from the equations) keep their weight:
    their displacement is zero and their share of the force goes into the support.
``SET`` or ``NODE`` (interfaces only)
    all directions of the set's (node's) nodes that are equations of the model.
``SET@rbe3:DIR`` (``SET@rbe3[x,y,z]:DIR``)
    force/moment at a master point (the set's centroid by default) distributed over the set
    by an RBE3 coupling, and the master's motion fitted to the set's translations
    (:mod:`flexmor.couplings`); ``DIR`` may be a rotation. ``SET@rbe2`` changes the model:
    apply :func:`flexmor.couplings.couple` first, then ``SET@rbe2`` and ``SET@rbe2:DIR``
    name the master node of the coupled model (also as interface: 6 DOFs).
``TARGET:all``
    one port per direction: the six of a coupling master (``SET@rbe2:all``, ``SET@rbe3:all``:
    ``x y z rx ry rz``), those of a node or set that are equations of the model
    (:func:`expand_specs`; the ports are named ``TARGET:x`` ...).

Models read with their own ``B``/``C`` (MATLAB benchmarks) use those when no SPEC is given.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import PortError, did_you_mean
from .model import DIRECTIONS, FEModel, direction_code, direction_name

__all__ = ["Ports", "make_ports", "interface_dofs", "parse_spec", "expand_specs", "path_matrix", "body_ports",
           "with_path_loads"]


@dataclass
class Ports:
    """Input matrix ``B`` (n_dof, m), output matrix ``C`` (p, n_dof) and their names/specs.

    Made by :func:`make_ports` from port SPECs, or from matrices by :meth:`from_arrays`.
    ``B`` and ``C`` may be given dense or sparse; they are kept as sparse CSR matrices, and
    their shapes and the numbers of names are checked when the ports are made.

    Raises
    ------
    PortError
        Naming ``B``, ``C``, ``input_names`` or ``output_names``: not a 2-D array of real finite
        numbers, ``B`` and ``C`` of different numbers of rows and columns (``n_dof``), or another
        number of names than of columns of ``B`` / rows of ``C``.
    """

    B: sp.csr_matrix
    C: sp.csr_matrix
    input_names: list
    output_names: list
    #: ``(m, p)``: a body built for these ports is judged on their leading ``m`` inputs and ``p`` outputs only
    #: (the user's ports, the rest added for the basis, e.g. the frame's inertia loads); None: on all of them.
    judged: tuple | None = None

    def __post_init__(self):
        self.B, self.C = _port_matrix(self.B, "B"), _port_matrix(self.C, "C")
        if self.B.shape[0] != self.C.shape[1]:
            raise PortError(f"B has {self.B.shape[0]} rows (equations) but C has {self.C.shape[1]} columns; both are "
                            "one per equation of the model: B (n_dof, n_inputs), C (n_outputs, n_dof)",
                            params=("B", "C"))
        for n, what, name in ((self.B.shape[1], "columns of B", "input_names"),
                              (self.C.shape[0], "rows of C", "output_names")):
            names = getattr(self, name)
            names = [names] if isinstance(names, str) else list(names)
            if len(names) != n:
                raise PortError(f"{name} must name each of the {n} {what}, got {len(names)} name(s)", params=(name,))
            setattr(self, name, names)

    @classmethod
    def from_arrays(cls, B, C=None, input_names=None, output_names=None, *, model=None) -> Ports:
        """Ports from an input matrix ``B`` and an output matrix ``C`` (dense or sparse).

        Parameters
        ----------
        B : array_like or sparse matrix, shape (n_dof, m)
            Input matrix: column ``j`` is the load pattern of input ``j``. A 1-D ``B`` is refused
            (give one column, ``B[:, None]``).
        C : array_like or sparse matrix, shape (p, n_dof), optional
            Output matrix; default ``B^T`` (collocated outputs).
        input_names, output_names : sequence of str, optional
            One name per input and per output; default ``u1 ... um`` and ``y1 ... yp`` (the
            input names for collocated outputs).
        model : FEModel or int, optional
            The model (or its number of equations) the ports must fit.

        Returns
        -------
        Ports

        Raises
        ------
        PortError
            Naming the argument: not a 2-D array of real finite numbers, shapes that do not fit
            each other or the model, or the wrong number of names.
        """
        B = _port_matrix(B, "B")
        collocated = C is None
        C = B.T.tocsr() if collocated else _port_matrix(C, "C")
        if model is not None:
            n_dof = model if isinstance(model, numbers.Integral) else model.n_dof
            for X, name, axis, what in ((B, "B", 0, "rows"), (C, "C", 1, "columns")):
                if X.shape[axis] != n_dof:
                    raise PortError(f"{name} has shape {X.shape}: {X.shape[axis]} {what}, but the model has "
                                    f"{n_dof} equations", params=(name,))
        if input_names is None:
            input_names = [f"u{j + 1}" for j in range(B.shape[1])]
        if output_names is None:
            output_names = list(input_names) if collocated else [f"y{i + 1}" for i in range(C.shape[0])]
        return cls(B, C, input_names, output_names)

    @property
    def n_inputs(self) -> int:
        """Number of inputs (columns of ``B``)."""
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of outputs (rows of ``C``)."""
        return self.C.shape[0]

    def reduced(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Br, Cr) = (V^T B, C V)`` for a basis ``V`` (n_dof, r): shapes (r, m) and (p, r).

        Only the rows of ``V`` the ports touch are read (a sparse product with the whole ``V``
        would copy it when it is column-major, as bases are).
        """
        B, C = sp.csr_matrix(self.B), sp.csc_matrix(self.C)
        rows = np.flatnonzero(np.diff(B.indptr))
        cols = np.flatnonzero(np.diff(C.indptr))
        Br = np.asarray((B[rows].T @ V[rows]).T)
        Cr = np.asarray(C[:, cols] @ V[cols])
        return Br, Cr


def _port_matrix(X, name: str) -> sp.csr_matrix:
    """``X`` (dense or sparse) as a CSR matrix of real finite numbers; a :class:`PortError` naming ``name``."""
    if sp.issparse(X):
        A = sp.csr_matrix(X)
        data = A.data
    else:
        try:
            data = np.asarray(X)
        except (TypeError, ValueError) as exc:
            raise PortError(f"{name} must be a 2-D array or sparse matrix of real numbers: {exc}",
                            params=(name,)) from None
        A = None
    if data.dtype.kind == "c" and not np.any(data.imag):
        data = data.real
    if data.dtype.kind not in "fiub":
        raise PortError(f"{name} must hold real numbers, got {type(X).__name__} of dtype {data.dtype}", params=(name,))
    if A is None:
        if data.ndim != 2:
            raise PortError(f"{name} must be 2-D, got shape {data.shape}" + (" (one column: B[:, None])"
                                                                            if data.ndim == 1 else ""),
                            params=(name,))
        A = sp.csr_matrix(np.asarray(data, dtype=float))
        data = A.data
    elif A.dtype != float:
        A = A.astype(float) if A.dtype.kind != "c" else sp.csr_matrix(A.real, dtype=float)
        data = A.data
    if not np.all(np.isfinite(data)):
        raise PortError(f"{name} has NaN or Inf entries", params=(name,))
    return A


def parse_spec(spec: str):
    """Split a SPEC into ``(target, direction code or None)``."""
    spec = str(spec).strip()
    if not spec:
        raise PortError("empty port specification")
    if ":" in spec:
        target, d = spec.rsplit(":", 1)
        if d.strip().lower() not in DIRECTIONS:
            raise PortError(f"port {spec!r}: unknown direction {d!r}; use one of: {' '.join(DIRECTIONS)}")
        return target.strip(), direction_code(d)
    return spec, None


def expand_specs(model: FEModel, specs) -> list[str]:
    """``specs`` with each ``TARGET:all`` replaced by one SPEC per direction: ``x y z rx ry rz``
    for a coupling master (``SET@rbe2``, ``SET@rbe3``), else the directions of the node's (set's
    nodes') equations in the model."""
    out = []
    for spec in specs:
        target, _, d = str(spec).strip().rpartition(":")
        if d.strip().lower() != "all" or not target:
            out.append(spec)
            continue
        target = target.strip()
        if "@" in target and target.replace(" ", "").upper() not in model.node_sets:
            codes = list(DIRECTIONS.values())
        else:
            nodes = _nodes_of(model, target, spec)
            if model.dofs is None:
                raise PortError(f"port {spec!r}: the model has no equation map, so directions cannot be listed")
            codes = sorted(set(model.dofs[np.isin(model.dofs[:, 0], nodes), 1].tolist()))
            if not codes:
                raise PortError(f"port {spec!r}: {target!r} has no free equation (constrained?)")
        out += [f"{target}:{name}" for name, code in DIRECTIONS.items() if code in codes]
    return out


def _nodes_of(model: FEModel, target: str, spec: str) -> np.ndarray:
    if target.upper() in model.node_sets:
        nodes = model.node_sets[target.upper()]
        if nodes.size == 0:
            raise PortError(f"port {spec!r}: node set {target!r} is empty")
        return nodes
    try:
        node = int(target)
    except ValueError:
        sets = ", ".join(sorted(model.node_sets)) or "none"
        raise PortError(f"port {spec!r}: {target!r} is neither a node id nor a node set; "
                        f"{did_you_mean(target, model.node_sets)}(sets: {sets})") from None
    if model.dofs is None:
        raise PortError(f"port {spec!r}: the model has no equation map, so nodes cannot be addressed")
    if model.n_nodes and not model.has_node(node):
        raise PortError(f"port {spec!r}: node {node} is not in the model")
    return np.array([node], dtype=np.int64)


def _weights(model: FEModel, spec: str):
    """Equation indices and weights (summing to 1 over the set) of a ``NODE:DIR``/``SET:DIR``."""
    target, d = parse_spec(spec)
    if d is None:
        raise PortError(f"port {spec!r}: give a direction, e.g. {target}:y")
    if "@" in target and target.replace(" ", "").upper() not in model.node_sets:
        from .couplings import port_row

        return port_row(model, target, d)
    nodes = _nodes_of(model, target, spec)
    if model.dofs is None:
        raise PortError(f"port {spec!r}: the model has no equation map")
    if nodes.size > 1 and any(int(k) in model.node_frames for k in nodes):
        raise PortError(f"port {spec!r}: set {target!r} has nodes with local displacement directions (Nastran CD "
                        "systems), so its average in one direction is undefined; read the model with "
                        "directions='basic'")
    idx = []
    for nd in nodes:
        try:
            idx.append(model.dof_index(nd, d))
        except KeyError:
            continue
    if not idx:
        what = f"node {nodes[0]}" if nodes.size == 1 else f"set {target!r}"
        raise PortError(f"port {spec!r}: {what} has no free equation in direction {spec.rsplit(':', 1)[1]} "
                        "(constrained or not a DOF of this model)")
    return np.asarray(idx), np.full(len(idx), 1.0 / nodes.size)


def _matrix(model: FEModel, specs) -> sp.csr_matrix:
    cols = [_weights(model, s) for s in specs]
    rows = np.concatenate([c[0] for c in cols])
    vals = np.concatenate([c[1] for c in cols])
    jj = np.concatenate([np.full(len(c[0]), j) for j, c in enumerate(cols)])
    return sp.csr_matrix((vals, (rows, jj)), shape=(model.n_dof, len(specs)))


def make_ports(model: FEModel, inputs=(), outputs=()) -> Ports:
    """Build ``B`` and ``C`` from port SPECs.

    Parameters
    ----------
    model : FEModel
    inputs, outputs : sequence of str
        SPECs (see module docstring; ``TARGET:all`` gives one port per direction,
        :func:`expand_specs`). Without inputs the model's own ``B`` is used; without
        outputs the model's own ``C``, or else the outputs equal the inputs (collocated).

    Returns
    -------
    Ports

    Raises
    ------
    PortError
        Unknown node, set or direction, or no inputs at all.
    """
    for name, specs in (("inputs", inputs), ("outputs", outputs)):
        if isinstance(specs, (str, bytes)):
            raise PortError(f"{name} must be a list of port SPECs, e.g. [{specs!r}], got the string {specs!r}",
                            params=(name,))
    if not hasattr(model, "node_sets") or not hasattr(model, "n_dof"):
        raise PortError(f"make_ports needs an FEModel (flexmor.read(path)), got {type(model).__name__}",
                        params=("model",))
    inputs, outputs = expand_specs(model, inputs or []), expand_specs(model, outputs or [])
    if inputs:
        B, in_names = _matrix(model, inputs), inputs
    elif model.B is not None:
        B, in_names = model.B, list(model.input_names)
    else:
        raise PortError("no input ports: inputs must name at least one NODE:DIR or SET:DIR", params=("inputs",))
    if outputs:
        C, out_names = _matrix(model, outputs).T.tocsr(), outputs
    elif model.C is not None:
        C, out_names = model.C, list(model.output_names)
    elif inputs:
        C, out_names = B.T.tocsr(), list(in_names)
    else:
        raise PortError("no output ports: outputs must name at least one NODE:DIR or SET:DIR", params=("outputs",))
    return Ports(B=sp.csr_matrix(B), C=sp.csr_matrix(C), input_names=list(in_names), output_names=list(out_names))


def path_matrix(model: FEModel, nodes, direction: int) -> sp.csc_matrix:
    """Unit forces in ``direction`` (a translation) at each of ``nodes``: shape (n_dof, len(nodes)), the input matrix
    of a moving load's path (:mod:`flexmor.moving`). A node whose direction is not an equation is held (a zero
    column), unless it is a slave of an RBE2 coupling of the model: its force then acts on the master, as the force
    and its moment ``r x F`` about the master (:func:`flexmor.couplings.coupling_masters`). A node whose direction
    an RBE3 coupling eliminated (one of its dependent DOFs) is refused (:class:`PortError`): the coupled model has
    no equation for a force there."""
    rows, cols, vals = [], [], []
    rbe2 = None
    for j, k in enumerate(nodes):
        try:
            rows.append(model.dof_index(int(k), direction))
            cols.append(j)
            vals.append(1.0)
            continue
        except KeyError:
            pass
        if rbe2 is None:
            from .couplings import coupling_masters

            rbe2 = {(m["kind"], int(n)): m for m in coupling_masters(model) for n in m["slaves"]}
        master = rbe2.get(("rbe2", int(k)))
        if master is None:
            rbe3 = rbe2.get(("rbe3", int(k)))
            if rbe3 is not None:
                raise PortError(f"path node {int(k)} is a node of the coupling {rbe3['name']} that eliminated its "
                                f"{direction_name(direction)} (a dependent DOF of the RBE3): the coupled model has "
                                "no equation for a force there; lay the path off the coupling's nodes, or couple "
                                "them by RBE2", params=("moving_load",))
            continue
        e = np.eye(3)[direction - 1]
        load = np.concatenate([e, np.cross(model.node_xyz([int(k)])[0] - np.asarray(master["xyz"]), e)])
        for d in np.flatnonzero(load):
            rows.append(model.dof_index(master["id"], int(d) + 1))
            cols.append(j)
            vals.append(float(load[d]))
    return sp.csc_matrix((vals, (rows, cols)), shape=(model.n_dof, len(nodes)))


def with_path_loads(ports: Ports | None, paths) -> Ports:
    """``ports`` (None: none) with, for each ``(name, B_path, W)`` of ``paths``, the compressed loads
    ``B_path W`` appended as inputs and their collocated deflections as outputs, named ``NAME~1`` ... (the
    compressed inputs of a moving load, :mod:`flexmor.moving`)."""
    B = [] if ports is None else [ports.B]
    C = [] if ports is None else [ports.C]
    ins = [] if ports is None else list(ports.input_names)
    outs = [] if ports is None else list(ports.output_names)
    for name, B_path, W in paths:
        Bc = sp.csr_matrix(B_path @ np.asarray(W, float))
        names = [f"{name}~{j + 1}" for j in range(Bc.shape[1])]
        B.append(Bc)
        C.append(Bc.T.tocsr())
        ins += names
        outs += names
    return Ports(B=sp.hstack(B).tocsr(), C=sp.vstack(C).tocsr(), input_names=ins, output_names=outs)


def body_ports(model: FEModel, body) -> Ports:
    """The ports ``body`` was reduced with, on ``model``: its input and output SPECs (:func:`make_ports`), and the
    compressed loads of its moving loads (``SET:DIR~j``, from ``body.info['moving_loads']``: the path's nodes,
    direction and directions ``W``; :mod:`flexmor.moving`)."""
    moving = body.info.get("moving_loads") or []
    if not moving:
        return make_ports(model, body.input_names, body.output_names)
    ins = [n for n in body.input_names if "~" not in n]
    outs = [n for n in body.output_names if "~" not in n]
    user = make_ports(model, ins, outs) if ins else None
    return with_path_loads(user, [(f"{r['set']}:{r['direction']}",
                                   path_matrix(model, r["nodes"], direction_code(r["direction"])),
                                   r["compression"]["W"]) for r in moving])


def interface_dofs(model: FEModel, specs) -> np.ndarray:
    """Sorted equation indices of interface SPECs (``NODE``, ``SET``, ``NODE:DIR``, ``SET:DIR``)."""
    if model.dofs is None:
        raise PortError("the model has no equation map, so interfaces cannot be defined")
    out = set()
    for spec in specs:
        target, d = parse_spec(spec)
        if "@" in target and target.replace(" ", "").upper() not in model.node_sets:
            raise PortError(f"interface {spec!r}: couplings are part of the model; use "
                            f"flexmor.couplings.couple(model, [{spec!r}]).model and reduce that")
        nodes = _nodes_of(model, target, spec)
        found = np.flatnonzero(np.isin(model.dofs[:, 0], nodes) & ((model.dofs[:, 1] == d) if d else True))
        if found.size == 0:
            raise PortError(f"interface {spec!r} has no free equations (all constrained?)")
        out.update(found.tolist())
    if not out:
        raise PortError("interface names no DOF: give NODE, SET or SET:DIR", params=("interface",))
    return np.array(sorted(out), dtype=np.int64)
