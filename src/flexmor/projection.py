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

from .basis import Basis, as_basis, check_rank
from .body import ReducedModel
from .couplings import coupling_masters
from .damping import ModalDamping
from .errors import ModelError, PortError
from .linalg.threads import blas_threads, dense_threads, sparse_dense
from .mesh import outer_surface
from .model import FEModel
from .origin import fingerprint
from .ports import Ports

__all__ = ["ReducedMatrices", "project", "reduced_matrices"]


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


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
    with blas_threads(dense_threads(Vc.size)):  # V^T (A V): the basis is read once per product, all cores
        Mr = _sym(Vc.T @ sparse_dense(model.M, Vc))
        Kr = _sym(Vc.T @ sparse_dense(model.K, Vc))
        Dr = _sym(Vc.T @ sparse_dense(model.D, Vc)) if model.D is not None else None
    return ReducedMatrices(Mr, Kr, Dr, (V, model.M, model.K, model.D))


def project(model: FEModel, basis: Basis | np.ndarray, ports: Ports) -> ReducedModel:
    """Galerkin projection of ``model`` onto ``basis``; the one path used by every method.

    Parameters
    ----------
    model : FEModel
    basis : Basis or ndarray
        ``basis.V`` of shape (n_dof, r); ``basis.reduced`` (:class:`ReducedMatrices` of that
        ``V``), when the method computed them, saves the sparse products. A plain array
        (n_dof, r) is a basis of method ``"custom"``.
    ports : Ports
        Inputs and outputs; projected to ``Br = V^T B`` and ``Cr = C V``.

    Returns
    -------
    ReducedModel

    Raises
    ------
    ModelError
        Naming ``basis``: not real numbers, NaN or Inf, complex, a number of rows other than
        ``model.n_dof``, no column, or linearly dependent columns
        (:func:`flexmor.basis.as_basis`, :func:`flexmor.basis.check_rank`).
    PortError
        ``ports`` not a :class:`~flexmor.ports.Ports`, or of another size than the model.
    """
    if not isinstance(ports, Ports):
        raise PortError(f"ports must be a Ports (flexmor.make_ports(model, inputs, outputs) or Ports.from_arrays), "
                        f"got {type(ports).__name__}", params=("ports",))
    if ports.B.shape[0] != model.n_dof:
        raise PortError(f"ports have {ports.B.shape[0]} rows, the model has {model.n_dof} equations",
                        params=("ports",))
    basis = as_basis(basis, model.n_dof)
    V = basis.V
    pre = basis.reduced
    if pre is None or not pre.of(model, basis.V):
        pre = reduced_matrices(model, V)
    Mr, Kr, Dr = pre.M, pre.K, pre.D
    check_rank(V, Mr)
    if Dr is not None and isinstance(model.damping, ModalDamping):  # modal damping: zeta in the body's own modes
        Dr = model.damping.reduced_matrix(Mr, Kr)
    Br, Cr = ports.reduced(V)
    info = dict(basis.info)
    order_note = info.pop("order_note", None)  # a method's word on the order it returned: a field of the body
    if model.preload is not None:  # K holds the geometric stiffness of these preloads
        info["preload"] = dict(model.preload)
    masters = coupling_masters(model)
    if masters:  # the interfaces of the body: one master id everywhere (info, SID, Exudyn, report)
        info["masters"] = [{"name": m["name"], "id": m["id"], "kind": m["kind"], "xyz": m["xyz"],
                            "n_slaves": int(m["slaves"].size)} for m in masters]
    red = ReducedModel(
        M=Mr, K=Kr, D=Dr, B=Br, C=Cr, V=V, method=basis.method, info=info,
        input_names=list(ports.input_names), output_names=list(ports.output_names),
        node_ids=model.node_ids, xyz=model.xyz, dofs=model.dofs, model_name=model.name,
        damping=model.damping, triangles=None if model.mesh is None else outer_surface(model.mesh).triangles,
        origin=fingerprint(model), order_note=order_note, units=model.units,
    )
    try:
        with blas_threads(1):  # r x r: one thread is as fast, and never spins beside a busy process
            red.eigenvalues()  # solved once here, kept by the body
    except ModelError:
        pass  # the body says so where its frequencies are asked for
    return red
