"""The one projection path: ``project(model, basis, ports) -> ReducedModel``.

Galerkin (one-sided) projection keeps the reduced body a mechanical second-order system
with symmetric ``Mr``, ``Kr`` that a multibody code accepts::

    Mr = V^T M V,  Dr = V^T D V,  Kr = V^T K V,  Br = V^T B,  Cr = C V,   q ≈ V qr

The sparse products are made by :func:`reduced_matrices`; a method that needed the reduced
matrices itself (e.g. the check of ``krylov``'s expansion point) hands them on with its basis
(``Basis.reduced``), and :func:`project` uses them instead of forming the products again.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ._version import __version__
from .basis import Basis
from .couplings import coupling_masters
from .damping import Damping, ModalDamping, NoDamping, damping_from_dict
from .errors import ModelError
from .linalg.threads import sparse_dense
from .mesh import outer_surface
from .model import FEModel
from .origin import fingerprint
from .ports import Ports

__all__ = ["ReducedModel", "ReducedMatrices", "project", "reduced_matrices"]


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


@dataclass
class ReducedModel:
    """A reduced elastic body ``Mr qr'' + Dr qr' + Kr qr = Br u``, ``y = Cr qr``.

    Attributes
    ----------
    M, K : ndarray, shape (r, r)
        Reduced mass and stiffness (symmetric).
    D : ndarray, shape (r, r) or None
        Reduced damping.
    B : ndarray, shape (r, m)
    C : ndarray, shape (p, r)
    V : ndarray, shape (n_dof, r) or None
        The basis (mode shapes at the equations ``dofs``), for expansion and export.
    method, info
        Method name and its parameters / diagnostics.
    input_names, output_names : list of str
        Port SPECs (or names) of the inputs and outputs.
    node_ids, xyz, dofs
        Node table and equation map of the full model.
    triangles : ndarray of int, shape (n_tri, 3), or None
        Outer surface of the full model's mesh as triangles over node ids
        (:func:`flexmor.mesh.outer_surface`), for drawing the body (Exudyn's ``trigList``); None
        where the model has no elements.
    model_name : str
        Name of the full model; ``errors`` holds error measures once evaluated.
    damping : Damping
        The damping of the full model it was projected from (``D`` is its projection).
    origin : dict
        Fingerprint of the full model (:func:`flexmor.origin.fingerprint`); empty for bodies
        written before fingerprints existed.
    """

    M: np.ndarray
    K: np.ndarray
    D: np.ndarray | None
    B: np.ndarray
    C: np.ndarray
    V: np.ndarray | None = None
    method: str = ""
    info: dict = field(default_factory=dict)
    input_names: list = field(default_factory=list)
    output_names: list = field(default_factory=list)
    node_ids: np.ndarray | None = None
    xyz: np.ndarray | None = None
    dofs: np.ndarray | None = None
    triangles: np.ndarray | None = None
    model_name: str = ""
    damping: Damping = field(default_factory=NoDamping)
    errors: dict = field(default_factory=dict)
    version: str = __version__
    origin: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.damping, Damping):  # the stored form, e.g. {"type": "rayleigh", ...}
            self.damping = damping_from_dict(self.damping)

    @property
    def order(self) -> int:
        """Reduced dimension r."""
        return int(self.M.shape[0])

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues ``omega^2`` of ``(Kr, Mr)``, ascending."""
        try:
            return sla.eigh(self.K, self.M, eigvals_only=True)
        except np.linalg.LinAlgError:
            raise ModelError("the reduced mass matrix is not positive definite") from None

    def summary(self) -> dict:
        """What the body is, as a plain dict (used by ``flexmor info BODY.h5``).

        Keys: ``method``, ``order``, ``order_requested``, ``order_note``, ``inputs``,
        ``outputs``, ``couplings``, ``masters`` (each coupling's master node: ``name``, ``id``,
        ``kind``, ``xyz``, ``n_slaves``), ``options`` (the method options recorded), ``frequencies_hz``,
        ``damping`` (stored form), ``errors`` (the stored measures, without the curves),
        ``model`` (the fingerprint of the full model it came from, empty for older bodies),
        ``version`` (of the flexmor that wrote it).
        """
        try:
            freqs = self.frequencies_hz().tolist()
        except ModelError:
            freqs = None
        return {"method": self.method, "order": self.order, "order_requested": self.info.get("order_requested"),
                "order_note": self.info.get("order_note"), "inputs": list(self.input_names),
                "outputs": list(self.output_names), "couplings": list(self.info.get("couplings", [])),
                "masters": list(self.info.get("masters", [])),
                "options": dict(self.info.get("options", {})), "frequencies_hz": freqs,
                "damping": self.damping.to_dict(), "model_name": self.model_name,
                "errors": {k: v for k, v in self.errors.items() if k not in ("freqs_hz", "rel_error")},
                "model": dict(self.origin), "version": self.version}

    def frequencies_hz(self) -> np.ndarray:
        """Undamped eigenfrequencies in Hz (round-off negatives reported as 0)."""
        lam = self.eigenvalues()
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)


@dataclass(frozen=True)
class ReducedMatrices:
    """The projected matrices of the columns ``V``: ``Mr = V^T M V``, ``Kr = V^T K V`` (symmetrized)
    and ``Dr = V^T D V`` (symmetrized; None when the model has no ``D``).

    Made by :func:`reduced_matrices`; :func:`project` uses them for a basis whose ``V`` is this
    ``V`` of the same model (the same array and sparse matrix objects, see :meth:`of`).
    """

    M: np.ndarray
    K: np.ndarray
    D: np.ndarray | None
    source: tuple = field(repr=False, compare=False)  # (V, model.M, model.K, model.D) they were made from

    def of(self, model: FEModel, V) -> bool:
        """Whether these are the matrices of ``V`` and ``model`` (the very objects: not a copy, a slice
        or a model with another matrix)."""
        return all(a is b for a, b in zip(self.source, (V, model.M, model.K, model.D)))


def reduced_matrices(model: FEModel, V: np.ndarray) -> ReducedMatrices:
    """``V^T M V``, ``V^T K V`` and ``V^T D V`` (symmetrized): the sparse products of :func:`project`.

    Parameters
    ----------
    model : FEModel
    V : ndarray, shape (n_dof, r)

    Returns
    -------
    ReducedMatrices
    """
    # one row-major copy serves every sparse product (SciPy copies Fortran-ordered columns for each)
    Vc = np.ascontiguousarray(V, dtype=float)
    Mr = _sym(Vc.T @ sparse_dense(model.M, Vc))
    Kr = _sym(Vc.T @ sparse_dense(model.K, Vc))
    Dr = _sym(Vc.T @ sparse_dense(model.D, Vc)) if model.D is not None else None
    return ReducedMatrices(Mr, Kr, Dr, (V, model.M, model.K, model.D))


def project(model: FEModel, basis: Basis, ports: Ports) -> ReducedModel:
    """Galerkin projection of ``model`` onto ``basis``; the one path used by every method.

    Parameters
    ----------
    model : FEModel
    basis : Basis
        ``basis.V`` of shape (n_dof, r); ``basis.reduced`` (:class:`ReducedMatrices` of that
        ``V``), when the method computed them, saves the sparse products.
    ports : Ports
        Inputs and outputs; projected to ``Br = V^T B`` and ``Cr = C V``.

    Returns
    -------
    ReducedModel
    """
    V = np.asarray(basis.V, dtype=float)
    if V.ndim != 2 or V.shape[0] != model.n_dof:
        raise ModelError(f"basis has shape {V.shape}, expected ({model.n_dof}, r)")
    if V.shape[1] == 0:
        raise ModelError(f"method {basis.method!r} produced an empty basis")
    pre = basis.reduced
    if pre is None or not pre.of(model, basis.V):
        pre = reduced_matrices(model, V)
    Mr, Kr, Dr = pre.M, pre.K, pre.D
    if Dr is not None and isinstance(model.damping, ModalDamping):  # modal damping: zeta in the body's own modes
        Dr = model.damping.reduced_matrix(Mr, Kr)
    Br, Cr = ports.reduced(V)
    info = dict(basis.info)
    masters = coupling_masters(model)
    if masters:  # the interfaces of the body: one master id everywhere (info, SID, Exudyn, report)
        info["masters"] = [{"name": m["name"], "id": m["id"], "kind": m["kind"], "xyz": m["xyz"],
                            "n_slaves": int(m["slaves"].size)} for m in masters]
    return ReducedModel(
        M=Mr, K=Kr, D=Dr, B=Br, C=Cr, V=V, method=basis.method, info=info,
        input_names=list(ports.input_names), output_names=list(ports.output_names),
        node_ids=model.node_ids, xyz=model.xyz, dofs=model.dofs, model_name=model.name,
        damping=model.damping, triangles=None if model.mesh is None else outer_surface(model.mesh).triangles,
        origin=fingerprint(model),
    )
