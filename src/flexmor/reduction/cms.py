"""Component mode synthesis with Krylov or Gramian internal vectors: ``cms-krylov``, ``cms-gramian``.

The Craig-Bampton structure is kept: the static constraint modes of the interface DOFs
(:func:`flexmor.reduction.guyan.constraint_modes`) make the reduced coordinates the interface
displacements and reproduce the static response to interface loads exactly. The internal
(fixed-interface) vectors are not the lowest eigenmodes of ``(K_ii, M_ii)`` but a reduction
basis of the fixed-interface body ``M_ii q'' + D_ii q' + K_ii q = B_i u`` whose inputs are
the loads that the body's inputs put on the interior: the inertia (and damping) loads of the
constraint modes moving with the static interface motion under the inputs, and the external
inputs on interior DOFs ``B[i]`` (:func:`fixed_interface_body`). For an assembly, give the
coupling DOFs as inputs too (e.g. ``--input TIP:x --input TIP:y --input TIP:z``), so that the
internal vectors also serve the interface motions the other components impose. The internal vectors
come from :func:`flexmor.reduction.krylov.krylov` or from frequency-limited balancing
(:func:`flexmor.reduction.balanced.balanced_basis`) of that body.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..basis import Basis
from ..linalg.context import SolverContext, as_solver
from ..linalg.threads import sparse_dense
from ..model import FEModel
from ..options import Band, band_option
from ..ports import Ports
from ._options import interface_option, nodes_option, points_option, rigid_option, solves_option, variant_option
from ._registry import register_method
from .craig_bampton import cb_frame, cb_order_note

__all__ = ["cms_krylov", "cms_gramian", "fixed_interface_body", "CmsKrylovOptions", "CmsGramianOptions"]

log = logging.getLogger(__name__)


def fixed_interface_body(model, ports, Psi, b, i, *, tol: float = 1e-8):
    """The fixed-interface body and the loads that the body's inputs put on it.

    With ``x_b`` the static interface motion under the inputs (``Psi^T K Psi x_b = Psi^T B``,
    least squares for a free body), the interior is loaded by the inertia and damping loads
    ``-(M_ib + M_ii Psi_i) x_b``, ``-(D_ib + D_ii Psi_i) x_b`` and by the external inputs on
    interior DOFs ``B[i]``. Returns ``(sub, sub_ports)``: an :class:`FEModel` of the interior
    DOFs and collocated ports whose columns are an orthonormal basis of those loads.
    """
    M, K = model.M.tocsr(), model.K.tocsr()
    B = ports.B.toarray()
    Kb = Psi.T @ sparse_dense(K, Psi)
    x_b = np.linalg.lstsq(0.5 * (Kb + Kb.T), Psi.T @ B, rcond=1e-12)[0]
    Mii = M[i][:, i]
    loads = [M[i][:, b] @ x_b + Mii @ (Psi[i] @ x_b)]
    D = model.D.tocsr() if model.D is not None else None
    if D is not None:
        loads.append(D[i][:, b] @ x_b + D[i][:, i] @ (Psi[i] @ x_b))
    if np.any(B[i]):
        loads.append(B[i])
    L = np.hstack(loads)
    L = L[:, np.linalg.norm(L, axis=0) > 0]
    L = L / np.linalg.norm(L, axis=0)
    U, s, _ = np.linalg.svd(L, full_matrices=False)
    U = U[:, s > tol * s[0]]
    sub = FEModel(M=Mii, K=K[i][:, i], D=None if D is None else D[i][:, i], name=f"{model.name}-interior",
                  damping=model.damping)
    Bs = sp.csr_matrix(U)
    names = [f"load{k + 1}" for k in range(U.shape[1])]
    return sub, Ports(B=Bs, C=Bs.T.tocsr(), input_names=names, output_names=names)


def _cms(model, ports, order, interface, method, internal, solver, rigid):
    V, b, i, F, info = cb_frame(model, interface, order, method, solver, rigid)
    Psi, n_int = V[:, : b.size], V.shape[1] - b.size
    info["n_internal"] = int(n_int)
    if n_int:
        sub, sub_ports = fixed_interface_body(model, ports, Psi, b, i)
        solver.keep(sub.K, sub.M, 0.0, F)  # K_ii, factorized for the constraint modes: the modal pre-pass's too
        try:
            Bi = internal(sub, sub_ports, n_int)
        finally:
            solver.release()
        V[i, b.size: b.size + Bi.order] = Bi.V
        V = V[:, : b.size + Bi.order]
        info.update(n_internal=int(Bi.order), n_loads=int(sub_ports.n_inputs), internal=Bi.info)
    note = cb_order_note(order, b.size, V.shape[1] - b.size, i.size, info.get("n_rigid", 0))
    if note:
        info["order_note"] = note
    return Basis(V, method, info)


@dataclass(frozen=True)
class CmsKrylovOptions:
    """Options of :func:`cms_krylov`."""

    interface: list | None = interface_option()
    band: Band | None = band_option("the default Krylov points of the fixed-interface body")
    points: str | None = points_option("Krylov points of the fixed-interface body")
    rigid: str = rigid_option("exclude")


@register_method("cms-krylov", "constraint modes + Krylov vectors of the fixed-interface body",
                 options=CmsKrylovOptions)
def cms_krylov(model, ports, order, *, interface=None, band=None, points=None, rigid: str = "exclude",
               solver: SolverContext | None = None) -> Basis:
    """Craig-Bampton with second-order Krylov vectors of the fixed-interface body as internal vectors.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        External inputs on interior DOFs load the fixed-interface body.
    order : int
        Interface DOFs plus internal vectors.
    interface : list of str, optional
        Interface SPECs (``NODE``, ``SET``, ``NODE:DIR``, ``SET:DIR``).
    band : (float, float), optional
        Band (Hz) of the default Krylov point (see :func:`flexmor.reduction.krylov.krylov`; default
        :data:`flexmor.options.DEFAULT_BAND`).
    points : str, optional
        Krylov expansion points (Hz), see :func:`flexmor.reduction.krylov.parse_points`.
    rigid : {'exclude', 'include'}
        Free bodies: remove the rigid motions that the constraint modes span (default), as for
        :func:`flexmor.reduction.craig_bampton.craig_bampton`.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        Columns: constraint modes (reduced coordinates = interface displacements), then the
        internal vectors; moment matching of the fixed-interface body survives coupling.

    References
    ----------
    Craig, R. R., Bampton, M. C. C. (1968). Coupling of substructures for dynamic analyses.
    AIAA Journal 6(7), 1313-1319.

    Holzwarth, P., Eberhard, P. (2015). SVD-based improvements for component mode synthesis
    in elastic multibody systems. European Journal of Mechanics A/Solids 49, 408-418.

    Fehr, J. (2011). Automated and error-controlled model reduction in elastic multibody
    systems. Dissertation, Universität Stuttgart, Shaker Verlag.
    """
    solver = as_solver(solver)
    from .krylov import krylov

    def internal(sub, sub_ports, n):
        return krylov(sub, sub_ports, n, points=points, band=Band.of(band), rigid="exclude",
                      solver=solver)

    return _cms(model, ports, order, interface, "cms-krylov", internal, solver, rigid)


@dataclass(frozen=True)
class CmsGramianOptions:
    """Options of :func:`cms_gramian`."""

    interface: list | None = interface_option()
    band: Band | None = band_option("the frequency-limited Gramians of the fixed-interface body")
    variant: str = variant_option()
    nodes: int = nodes_option()
    rigid: str = rigid_option("exclude")
    solves: str = solves_option()


@register_method("cms-gramian", "constraint modes + balanced (frequency-limited Gramian) vectors of the "
                 "fixed-interface body", options=CmsGramianOptions, survives_coupling=False)
def cms_gramian(model, ports, order, *, interface=None, band=None, variant: str = "position", nodes: int = 4,
                rigid: str = "exclude", solves: str = "auto", solver: SolverContext | None = None) -> Basis:
    """Craig-Bampton with frequency-limited balanced vectors of the fixed-interface body.

    The internal vectors are the leading right balancing vectors of the fixed-interface body
    (:func:`flexmor.reduction.balanced.balanced_basis` with the Gramians of ``band``).

    Parameters
    ----------
    model : FEModel
    ports : Ports
    order : int
        Interface DOFs plus internal vectors.
    interface : list of str, optional
        Interface SPECs.
    band : (float, float), optional
        Band (Hz) of the frequency-limited Gramians (default :data:`flexmor.options.DEFAULT_BAND`).
    variant : {'position', 'velocity'}
        See :func:`flexmor.reduction.balanced.sobt`.
    nodes : int
        Gauss points per quadrature panel.
    rigid : {'exclude', 'include'}
        Free bodies: remove the rigid motions that the constraint modes span (default), as for
        :func:`flexmor.reduction.craig_bampton.craig_bampton`.
    solves : {'auto', 'direct', 'dense', 'surrogate'}
        How the quadrature nodes are solved (see :func:`flexmor.reduction.balanced.fw_sobt`).
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info['internal']['hankel_sv']`` the singular values of the fixed-interface body.

    References
    ----------
    Craig, R. R., Bampton, M. C. C. (1968). Coupling of substructures for dynamic analyses.
    AIAA Journal 6(7), 1313-1319.

    Benner, P., Kürschner, P., Saak, J. (2016). Frequency-limited balanced truncation with
    low-rank approximations. SIAM J. Sci. Comput. 38(1), A471-A499.

    Fehr, J. (2011). Automated and error-controlled model reduction in elastic multibody
    systems. Dissertation, Universität Stuttgart, Shaker Verlag.
    """
    solver = as_solver(solver)
    from .balanced import balanced_basis

    def internal(sub, sub_ports, n):
        return balanced_basis(sub, sub_ports, n, Band.of(band), method="cms-gramian",
                              variant=variant, nodes=nodes, rigid="exclude", solves=solves, solver=solver)

    return _cms(model, ports, order, interface, "cms-gramian", internal, solver, rigid)
