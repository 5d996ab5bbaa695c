"""The finite-element model container :class:`FEModel`.

A model is the second-order system ``M q'' + D q' + K q = B u`` with sparse symmetric
``M`` (positive definite), ``K`` (positive semi-definite) and optional ``D``, plus the
geometry needed to address degrees of freedom by node and direction:

* ``node_ids`` (n_nodes,) and ``xyz`` (n_nodes, 3): the node table, coordinates in the
  length unit of the model (m when the file's unit system was named on reading and converted,
  :mod:`flexmor.units`; else the file's own, as given);
* ``dofs`` (n_dof, 2): for each equation, the node id and the direction code
  1..6 = x, y, z, rx, ry, rz;
* ``node_sets``: named sets of node ids.

Files without geometry (MATLAB benchmarks) may instead carry their own input and output
matrices ``B`` (n_dof, m) and ``C`` (p, n_dof).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from .damping import Damping, NoDamping, Rayleigh, damping_from_dict, describe_damping
from .display import Shown, names_text
from .elements import Elements
from .errors import NOTES, ModelError, note
from .linalg.distributed import is_partitioned
from .mesh import Mesh

__all__ = ["FEModel", "DIRECTIONS", "direction_code", "direction_name"]

#: Direction names and their codes in ``FEModel.dofs[:, 1]``.
DIRECTIONS = {"x": 1, "y": 2, "z": 3, "rx": 4, "ry": 5, "rz": 6}
_DIR_NAMES = {v: k for k, v in DIRECTIONS.items()}
#: Keys of equations for :meth:`FEModel.dof_index`: ``node * _DIRECTION_KEYS + direction`` (directions 1-6).
_DIRECTION_KEYS = 8

#: What a singular or indefinite mass matrix is and allows: the note ``singular-mass`` (:data:`flexmor.errors.NOTES`).
SINGULAR_MASS_NOTE = NOTES["singular-mass"]

#: Relative tolerance of the symmetry check ``max|A - A^T| <= tol * max|A|``.
SYMMETRY_RTOL = 1e-8


def direction_code(name: str) -> int:
    """Return the code 1..6 of a direction name (``x y z rx ry rz``, case-insensitive)."""
    try:
        return DIRECTIONS[name.strip().lower()]
    except KeyError:
        raise ModelError(f"unknown direction {name!r}; use one of: {' '.join(DIRECTIONS)}") from None


def direction_name(code: int) -> str:
    """Return the name (``x`` ... ``rz``) of a direction code 1..6."""
    return _DIR_NAMES.get(int(code), str(code))


def _as_csr(name: str, A, n: int | None = None) -> sp.csr_matrix:
    if A is None or is_partitioned(A):  # rows spread over MPI ranks: kept as they are
        return A
    if not sp.issparse(A):
        A = np.asarray(A)
        if A.ndim != 2:
            raise ModelError(f"{name} must be a 2-D matrix, got shape {A.shape}")
    A = sp.csr_matrix(A)
    if not np.issubdtype(A.dtype, np.floating):
        if np.issubdtype(A.dtype, np.complexfloating):
            raise ModelError(f"{name} is complex; flexmor needs real matrices")
        A = A.astype(np.float64)
    A.sum_duplicates()
    A.eliminate_zeros()  # (CalculiX writes M on K's pattern: two thirds of a solid's mass entries are zeros)
    return A


def _nnz(A) -> int:
    """Stored entries of ``A`` (summed over the MPI ranks for a partitioned matrix)."""
    return A.global_nnz() if is_partitioned(A) else int(A.nnz)


def _transpose_matches(name: str, A: sp.csr_matrix, scale: float) -> bool:
    """Symmetry check without forming ``A - A.T``: True when ``A.T`` has ``A``'s pattern and values agree.

    Needs sorted indices; False (check the slow way) when the patterns differ. Compares the
    values in slices, so the only large temporary is the transpose.
    """
    if not A.has_sorted_indices:
        return False
    T = A.T.tocsr()
    if not (np.array_equal(T.indptr, A.indptr) and np.array_equal(T.indices, A.indices)):
        return False
    step = 1 << 16
    for s in range(0, A.nnz, step):
        d = np.abs(A.data[s:s + step] - T.data[s:s + step])
        k = int(np.argmax(d))
        if d[k] > SYMMETRY_RTOL * scale:
            k += s
            i, j = int(np.searchsorted(A.indptr, k, side="right")) - 1, int(A.indices[k])
            raise ModelError(
                f"{name} is not symmetric: |{name}[{i + 1},{j + 1}] - {name}[{j + 1},{i + 1}]| = {d[k - s]:.3g} > "
                f"{SYMMETRY_RTOL:g} * max|{name}| (1-based equation numbers)")
    return True


def _check_square_symmetric(name: str, A: sp.csr_matrix, n: int) -> None:
    if A.shape != (n, n):
        raise ModelError(f"{name} has shape {A.shape}, expected ({n}, {n}) like M")
    if not np.all(np.isfinite(A.data)):
        bad = int(np.count_nonzero(~np.isfinite(A.data)))
        raise ModelError(f"{name} contains {bad} non-finite entries (NaN or Inf)")
    if is_partitioned(A):  # each rank holds some rows: symmetric by construction
        return
    scale = float(np.max(np.abs(A.data))) if A.nnz else 0.0
    if scale == 0.0:
        return
    if _transpose_matches(name, A, scale):
        return
    R = (A - A.T).tocoo()
    if R.nnz:
        k = int(np.argmax(np.abs(R.data)))
        asym = abs(float(R.data[k]))
        if asym > SYMMETRY_RTOL * scale:
            raise ModelError(
                f"{name} is not symmetric: |{name}[{R.row[k] + 1},{R.col[k] + 1}] - "
                f"{name}[{R.col[k] + 1},{R.row[k] + 1}]| = {asym:.3g} > {SYMMETRY_RTOL:g} * max|{name}| "
                f"(1-based equation numbers)"
            )


@dataclass(repr=False)
class FEModel(Shown):
    """A linear finite-element model of one elastic body.

    Parameters
    ----------
    M, K : sparse matrix, shape (n_dof, n_dof)
        Mass and stiffness matrices (symmetric; stored in full, CSR).
    D : sparse matrix, optional
        Damping matrix. See :meth:`with_rayleigh` for proportional damping.
    node_ids : ndarray of int, shape (n_nodes,)
        Node numbers as in the FE file.
    xyz : ndarray of float, shape (n_nodes, 3)
        Node coordinates (length unit of the FE file).
    dofs : ndarray of int, shape (n_dof, 2), optional
        Equation map: node id and direction code 1..6 (x y z rx ry rz) of each equation.
    node_sets : dict of str to ndarray of int
        Named node sets (node ids). Names are stored upper-case.
    B, C : sparse matrix, optional
        Input (n_dof, m) and output (p, n_dof) matrices delivered with the model file.
    input_names, output_names : list of str
        Names of the columns of ``B`` and rows of ``C``.
    name : str
        Short model name. ``source`` is the file it was read from.
    damping : Damping
        How ``D`` was obtained (:mod:`flexmor.damping`), e.g. ``Rayleigh(alpha, beta)``; a
        stored form (``{"type": "given"}``) is converted.
    node_frames : dict of int to ndarray (3, 3)
        Nodes whose direction codes are not the global x y z (Nastran grids with a local
        displacement system): the columns are the node's directions 1-3 (and 4-6) in
        global components. Empty for almost all models.
    mesh : Mesh, optional
        Element connectivity (:mod:`flexmor.mesh`), for the visualization and meshio; None
        where the file has no elements.
    elements : Elements, optional
        The elements with their types, numbers, CalculiX node order and materials
        (:mod:`flexmor.elements`), for stress recovery (:mod:`flexmor.stress`); None where the
        reader does not read elements.
    singular_mass_ok : bool
        The element formulation legitimately gives a singular or indefinite mass matrix
        (20-node hexahedra with reduced integration or row-sum lumping, e.g. CalculiX
        C3D20R): non-positive mass diagonals are then reported by the note ``singular-mass``
        (:func:`flexmor.errors.note`, :data:`SINGULAR_MASS_NOTE`) instead of raising ModelError.
    units : str, optional
        The unit system of the file the model was read from (a name of
        :data:`flexmor.units.SYSTEMS`), whose numbers were converted to SI on reading
        (:func:`flexmor.units.to_si`); None when the file's system was not named: the numbers
        are as given.
    preload : dict, optional
        The record of the preloads whose geometric stiffness ``K`` holds
        (:func:`flexmor.preload.with_preload`: their SPECs ...); None for a model as read.
    stated_units : str, optional
        The unit system the file states for numbers that were read as given (not converted to SI:
        ``units`` is None), e.g. a SID file's header; None where the file states none.

    Raises
    ------
    ModelError
        On inconsistent shapes, non-finite values, asymmetric matrices or a mass diagonal
        that is not positive.
    """

    M: sp.csr_matrix
    K: sp.csr_matrix
    D: sp.csr_matrix | None = None
    node_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    dofs: np.ndarray | None = None
    node_sets: dict = field(default_factory=dict)
    B: sp.csr_matrix | None = None
    C: sp.csr_matrix | None = None
    input_names: list = field(default_factory=list)
    output_names: list = field(default_factory=list)
    name: str = "model"
    source: str = ""
    damping: Damping = field(default_factory=NoDamping)
    node_frames: dict = field(default_factory=dict)
    singular_mass_ok: bool = False
    mesh: Mesh | None = None
    units: str | None = None
    elements: Elements | None = None
    preload: dict | None = None
    stated_units: str | None = None

    def __post_init__(self):
        if not isinstance(self.damping, Damping):
            self.damping = damping_from_dict(self.damping)
        self.M = _as_csr("M", self.M)
        self.K = _as_csr("K", self.K)
        self.D = _as_csr("D", self.D)
        if self.M.shape[0] != self.M.shape[1]:
            raise ModelError(f"M must be square, got shape {self.M.shape}")
        n = self.M.shape[0]
        if n == 0:
            raise ModelError("the model has no degrees of freedom")
        for nm, A in (("M", self.M), ("K", self.K), ("D", self.D)):
            if A is not None:
                _check_square_symmetric(nm, A, n)
        dm = self.M.diagonal()
        if np.any(dm <= 0):
            i = int(np.flatnonzero(dm <= 0)[0])
            msg = (f"mass matrix diagonal is not positive at {np.count_nonzero(dm <= 0)} equation(s), "
                   f"first: {self.describe_dof(i)} (M = {dm[i]:.3g})")
            if not self.singular_mass_ok or not np.sum(dm) > 0:
                raise ModelError(msg)
            note("singular-mass", f"{self.source or self.name}: {msg}; every method still works", stacklevel=3)
        dk = self.K.diagonal()
        if np.any(dk < 0):
            i = int(np.flatnonzero(dk < 0)[0])
            raise ModelError(f"stiffness matrix has a negative diagonal entry at {self.describe_dof(i)}")
        self._check_geometry(n)
        self._check_io(n)
        if self.mesh is not None and self.node_ids.size:
            self.mesh.check_nodes(self.node_ids)
        if self.elements is not None and self.node_ids.size:
            missing = np.setdiff1d(self.elements.node_ids(), self.node_ids)
            if missing.size:
                raise ModelError(f"{missing.size} node(s) used by elements are not in the node table, "
                                 f"first: {int(missing[0])}")

    # -- validation -------------------------------------------------------------------------
    def _check_geometry(self, n: int) -> None:
        self.node_ids = np.asarray(self.node_ids, dtype=np.int64).reshape(-1)
        self.xyz = np.asarray(self.xyz, dtype=np.float64).reshape(-1, 3)
        if self.xyz.shape[0] != self.node_ids.size:
            raise ModelError(f"{self.node_ids.size} node ids but {self.xyz.shape[0]} coordinate rows")
        if not np.all(np.isfinite(self.xyz)):
            raise ModelError("node coordinates contain NaN or Inf")
        if np.unique(self.node_ids).size != self.node_ids.size:
            raise ModelError("node ids are not unique")
        frames = {}
        for nd, Q in (self.node_frames or {}).items():
            Q = np.asarray(Q, dtype=np.float64)
            if Q.shape != (3, 3) or not np.allclose(Q.T @ Q, np.eye(3), atol=1e-8):
                raise ModelError(f"node_frames[{nd}] is not an orthonormal 3 x 3 matrix")
            if not np.isin(int(nd), self.node_ids):
                raise ModelError(f"node_frames names node {nd}, which is not in the node table")
            frames[int(nd)] = Q
        self.node_frames = frames
        if self.dofs is not None:
            self.dofs = np.asarray(self.dofs, dtype=np.int64).reshape(-1, 2)
            if self.dofs.shape[0] != n:
                raise ModelError(f"the equation map has {self.dofs.shape[0]} rows but the matrices have {n}")
            if np.any((self.dofs[:, 1] < 1) | (self.dofs[:, 1] > 6)):
                raise ModelError("equation map has direction codes outside 1..6")
            if self.node_ids.size:
                known = np.isin(self.dofs[:, 0], self.node_ids)
                if not np.all(known):
                    i = int(np.flatnonzero(~known)[0])
                    raise ModelError(
                        f"equation {i + 1} refers to node {self.dofs[i, 0]}, which is not in the node table")
            key = self.dofs[:, 0] * 8 + self.dofs[:, 1]
            if np.unique(key).size != n:
                raise ModelError("the equation map names a (node, direction) pair twice")
        sets = {}
        for name, ids in self.node_sets.items():
            ids = np.asarray(ids, dtype=np.int64).reshape(-1)
            if self.node_ids.size:
                unknown = ids[~np.isin(ids, self.node_ids)]
                if unknown.size:
                    raise ModelError(f"node set {name!r} names unknown node {unknown[0]}")
            sets[str(name).upper()] = ids
        self.node_sets = sets

    def _check_io(self, n: int) -> None:
        if self.B is not None:
            self.B = _as_csr("B", self.B)
            if self.B.shape[0] != n:
                raise ModelError(f"B has {self.B.shape[0]} rows, expected {n}")
            if not self.input_names:
                self.input_names = [f"u{i + 1}" for i in range(self.B.shape[1])]
        if self.C is not None:
            self.C = _as_csr("C", self.C)
            if self.C.shape[1] != n:
                raise ModelError(f"C has {self.C.shape[1]} columns, expected {n}")
            if not self.output_names:
                self.output_names = [f"y{i + 1}" for i in range(self.C.shape[0])]
        for nm, A in (("B", self.B), ("C", self.C)):
            if A is not None and not np.all(np.isfinite(A.data)):
                raise ModelError(f"{nm} contains NaN or Inf")

    # -- queries ----------------------------------------------------------------------------
    @property
    def n_dof(self) -> int:
        """Number of equations (degrees of freedom)."""
        return self.M.shape[0]

    @property
    def n_nodes(self) -> int:
        """Number of nodes in the node table."""
        return int(self.node_ids.size)

    def _shown(self) -> tuple[str, list]:
        rows = [("damping", describe_damping(self.damping)), ("units", self.units or "as given"),
                ("node sets", names_text(self.node_sets)), ("nnz(K)", _nnz(self.K))]
        if self.B is not None or self.C is not None:
            rows.append(("ports", f"{len(self.input_names)} inputs, {len(self.output_names)} outputs"))
        if self.source:
            rows.append(("source", self.source))
        return f"{self.name!r}: {self.n_dof} DOF, {self.n_nodes} nodes", rows

    def describe_dof(self, i: int) -> str:
        """Human-readable name of equation ``i`` (0-based), e.g. ``'equation 7 (node 3, y)'``."""
        if self.dofs is not None and len(self.dofs) > i:
            nd, d = self.dofs[i]
            return f"equation {i + 1} (node {nd}, {direction_name(d)})"
        return f"equation {i + 1}"

    @functools.cached_property
    def _dof_keys(self) -> tuple[np.ndarray, np.ndarray]:
        """The sorted keys ``node * 8 + direction`` of the equations and the equation of each, built on first use
        (16 bytes per equation; a dict of ``(node, direction)`` took about 160, on every MPI rank)."""
        if self.dofs is None or not len(self.dofs):
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        key = self.dofs[:, 0].astype(np.int64) * _DIRECTION_KEYS + self.dofs[:, 1].astype(np.int64)
        order = np.argsort(key, kind="stable")
        return key[order], order

    @functools.cached_property
    def _node_index(self) -> dict:
        """``{node id: row of the node table}``, built on first use."""
        return {k: i for i, k in enumerate(self.node_ids.tolist())}

    def dof_index(self, node: int, direction: int) -> int:
        """Equation index (0-based) of ``(node, direction)``; ``KeyError`` when absent."""
        node, direction = int(node), int(direction)
        keys, order = self._dof_keys
        key = node * _DIRECTION_KEYS + direction
        i = int(np.searchsorted(keys, key, side="right")) - 1  # (the last of repeated pairs)
        if not 0 <= direction < _DIRECTION_KEYS or i < 0 or keys[i] != key:
            raise KeyError((node, direction))
        return int(order[i])

    def has_node(self, node: int) -> bool:
        """True if ``node`` is in the node table."""
        return int(node) in self._node_index

    @functools.cached_property
    def _node_order(self) -> np.ndarray:
        """Rows of the node table sorted by node id, built on first use."""
        return np.argsort(self.node_ids, kind="stable")

    def node_xyz(self, nodes) -> np.ndarray:
        """Coordinates (k, 3) of the given node ids; ``KeyError`` for an id not in the node table."""
        nodes = np.atleast_1d(np.asarray(nodes)).astype(np.int64, copy=False).ravel()
        order = self._node_order
        ids = self.node_ids[order]
        pos = np.minimum(np.searchsorted(ids, nodes), max(ids.size - 1, 0))
        bad = (ids[pos] != nodes) if ids.size else np.ones(nodes.shape, dtype=bool)
        if np.any(bad):
            raise KeyError(int(nodes[np.flatnonzero(bad)[0]]))
        return self.xyz[order[pos]]

    def summary(self) -> dict:
        """Sizes and properties as a plain dict (used by ``flexmor info``)."""
        return {
            "name": self.name,
            "source": self.source,
            "n_dof": self.n_dof,
            "n_nodes": self.n_nodes,
            "nnz_M": _nnz(self.M),
            "nnz_K": _nnz(self.K),
            "damping": self.damping.to_dict(),
            "node_sets": {k: int(v.size) for k, v in self.node_sets.items()},
            "inputs": list(self.input_names),
            "outputs": list(self.output_names),
            "units": self.units,
            "preload": None if self.preload is None else dict(self.preload),
            "stated_units": self.stated_units,
        }

    def mass_properties(self) -> dict:
        """Total mass, centre of mass and bounding box, from ``M`` and the node coordinates.

        The mass in direction d is ``e_d^T M e_d`` for the rigid translation ``e_d`` (ones at the
        equations of direction d), i.e. the mass carried by the model's equations: the mass at
        constrained (removed) DOFs is not in ``M``. The centre of mass weighs each node's
        coordinate by its share ``(M e_d)_i`` of that mass. Returns ``mass`` (per direction x y z,
        None where the model has no such equations or no equation map), ``center_of_mass``
        and ``bounding_box`` (``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``, None without nodes).
        """
        out: dict[str, Any] = {"mass": None, "center_of_mass": None, "bounding_box": None}
        if self.n_nodes:
            out["bounding_box"] = [self.xyz.min(axis=0).tolist(), self.xyz.max(axis=0).tolist()]
        if self.dofs is None or not self.n_nodes:  # (M partitioned over MPI ranks: M @ e is reduced over them)
            return out
        mass: list[float | None] = []
        com: list[float | None] = []
        for d in (1, 2, 3):
            rows = np.flatnonzero(self.dofs[:, 1] == d)
            if rows.size == 0:
                mass.append(None)
                continue
            e = np.zeros(self.n_dof)
            e[rows] = 1.0
            w = (self.M @ e)[rows]
            m = float(w.sum())
            mass.append(m)
            x = self.node_xyz(self.dofs[rows, 0])[:, d - 1]
            com.append(float(w @ x / m) if m > 0 else None)
        out["mass"] = mass
        if len(com) == 3 and all(c is not None for c in com):
            out["center_of_mass"] = com
        return out

    # -- derived models ---------------------------------------------------------------------
    def with_rayleigh(self, alpha: float, beta: float) -> FEModel:
        """Return a copy with Rayleigh damping ``D = alpha M + beta K`` (alpha in 1/s, beta in s)."""
        return self.with_damping(Rayleigh(alpha, beta))

    def with_damping(self, damping: Damping) -> FEModel:
        """Return a copy with the damping matrix of ``damping`` (a :class:`~flexmor.damping.Rayleigh`,
        e.g. :func:`~flexmor.damping.band_matched`); :class:`~flexmor.damping.NoDamping` returns the model."""
        if isinstance(damping, NoDamping):
            return self
        if not isinstance(damping, Rayleigh):
            raise ModelError(f"damping {damping} has no matrix to build; give Rayleigh damping")
        alpha, beta = damping.alpha, damping.beta
        if not (np.isfinite(alpha) and np.isfinite(beta)) or alpha < 0 or beta < 0:
            raise ModelError(f"Rayleigh coefficients must be finite and >= 0, got alpha={alpha}, beta={beta}")
        # M and K are this model's, checked: a copy with D (symmetric as they are), without checking them again
        D = _as_csr("D", damping.matrix(self.M, self.K))
        _check_square_symmetric("D", D, self.n_dof)
        out = copy.copy(self)
        out.D, out.damping = D, damping
        return out
