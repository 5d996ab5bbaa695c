"""Craig-Bampton component mode synthesis: constraint modes + fixed-interface normal modes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import eigenmodes, frequencies_hz, whole_clusters
from ..ports import interface_dofs
from ..rigid import rigid_body_modes
from ._options import interface_option, rigid_option
from ._registry import register_method
from .free_body import inertia_relief_modes
from .guyan import constraint_modes
from .modal import CLUSTER_MARGIN, cluster_note

#: How a CMS method treats the constraint modes of a free body whose rigid motion it excludes:
#: ``inertia-relief`` replaces them by the interface's inertia-relief attachment modes
#: (:func:`flexmor.reduction.free_body.inertia_relief_modes`; the n_b columns stay), the default
#: keeps them and :func:`flexmor.rigid.exclude_rigid` drops their rigid motion
#: afterwards (n_rigid columns leave).
FREE_ATTACHMENT = {"craig-bampton": "inertia-relief"}


def _relief(method: str, n_rigid: int) -> bool:
    return bool(n_rigid) and FREE_ATTACHMENT.get(method) == "inertia-relief"


def lowest_order(model, method: str, interface, rigid: str) -> int:
    """The smallest order ``method`` accepts: the interface DOFs, less the rigid-body modes a free
    body's basis drops (see :data:`FREE_ATTACHMENT`)."""
    n_rb = rigid_body_modes(model).shape[1] if rigid == "exclude" else 0
    n_b = interface_dofs(model, interface).size
    return n_b if _relief(method, n_rb) else n_b - n_rb


def cb_frame(model, interface, order, method: str, solver: SolverContext | None = None, rigid: str = "include"):
    """The Craig-Bampton frame shared by the CMS methods.

    Returns ``(V, b, i, F, info)``: ``V`` (n_dof, order) with the constraint modes in its first
    ``n_b`` columns and zeros in the ``order - n_b`` internal columns (at most the number of
    interior DOFs), the interface and interior equations, the factorization of ``K_ii``, and the
    basis ``info`` to start from. With ``rigid='exclude'`` on a free body the constraint modes
    span its ``n_rigid`` rigid motions (the interface holds the body). Per
    :data:`FREE_ATTACHMENT`, the first ``n_b`` columns are then the inertia-relief attachment
    modes, or the constraint modes, whose rigid motion
    :func:`flexmor.rigid.exclude_rigid` removes afterwards (``n_rigid`` more
    internal columns keep the requested order). ``info`` asks for the removal either way.
    """
    solver = as_solver(solver)
    check_choice("rigid", rigid, ("exclude", "include"))
    if order is None:
        n_b = interface_dofs(model, interface).size if interface else 0
        raise OptionError(f"{method} needs order (at least the {n_b} interface DOFs, plus internal vectors), or a "
                          "target error (tol) to choose it", params=("order", "tol"))
    n_rb = rigid_body_modes(model).shape[1] if rigid == "exclude" else 0
    relief = _relief(method, n_rb)
    V_c, b, i, F = constraint_modes(model, interface, solver)
    low = b.size if relief else b.size - n_rb
    if order < low:
        raise OptionError(f"{method} needs order >= number of interface DOFs ({low}), got {order}",
                          params=("order",))
    extra = 0 if relief else n_rb
    V = np.zeros((model.n_dof, b.size + min(order + extra - b.size, i.size)))
    V[:, : b.size] = inertia_relief_modes(model, b, solver=solver, held=(V_c, i, F)) if relief else V_c
    info = {"n_interface_dofs": int(b.size)}
    if n_rb:
        info.update(rigid="exclude", n_rigid=int(extra))
    if relief:
        info.update(attachment="inertia-relief", n_rigid_body_modes=int(n_rb))
    return V, b, i, F, info


def cb_order_note(order: int, n_b: int, n_internal: int, n_interior: int, n_rigid: int = 0) -> str | None:
    """The ``order_note`` of a CMS basis of ``n_b + n_internal`` columns, ``n_rigid`` of them rigid motion
    removed afterwards, for ``order`` asked (None if it has that order)."""
    got = n_b + n_internal - n_rigid
    if got >= order:
        return None
    why = (f"the model has only {n_interior} interior DOFs next to the {n_b} interface DOFs"
           if n_internal >= n_interior else f"only {n_internal} internal vectors were found")
    return f"order {got} instead of {order}: {why}"


@dataclass(frozen=True)
class CraigBamptonOptions:
    """Options of :func:`craig_bampton`."""

    interface: list | None = interface_option()
    rigid: str = rigid_option("exclude")


@register_method("craig-bampton", "constraint modes + fixed-interface normal modes", options=CraigBamptonOptions,
                 uses_inputs=False)
def craig_bampton(model, ports, order, *, interface=None, rigid: str = "exclude",
                  solver: SolverContext | None = None) -> Basis:
    """Craig-Bampton basis ``[[I, 0], [Psi, Phi_i]]`` of total order r = n_b + n_modes.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        Unused by the basis.
    order : int
        Total reduced dimension: interface DOFs plus fixed-interface modes
        (``order - n_b`` modes; ``order == n_b`` is Guyan).
    interface : list of str, optional
        Interface SPECs (``NODE``, ``SET``, ``NODE:DIR``, ``SET:DIR``).
    rigid : {'exclude', 'include'}
        Free bodies: the constraint modes of an interface that holds the body span its
        rigid-body motions. ``exclude`` (default), as the floating frame of reference wants,
        replaces them by the interface's inertia-relief attachment modes
        (:func:`flexmor.reduction.free_body.inertia_relief_modes`: static elastic responses to
        unit interface forces balanced by the body's inertia, mass-orthogonal to the rigid-body
        modes). They span the elastic part of the constraint modes and the quasi-static
        deformation under any interface load, so the body is exact at low frequency; the
        reduced coordinates are no longer the interface displacements. ``order - n_b``
        fixed-interface modes follow. The frequencies are upper bounds of the free-free elastic
        ones (Rayleigh-Ritz). ``include`` keeps the classic basis (interface coordinates,
        zero-frequency rigid-body modes). No effect on a supported body.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`; the factorization of ``K_ii`` serves
        both the constraint modes and the shift-invert eigen solver.

    Returns
    -------
    Basis
        Columns: the n_b constraint modes (reduced coordinates = interface displacements),
        then the fixed-interface modes; ``info['fixed_interface_hz']`` their frequencies.

    References
    ----------
    Craig, R. R., Bampton, M. C. C. (1968). Coupling of substructures for dynamic analyses.
    AIAA Journal 6(7), 1313-1319.
    """
    solver = as_solver(solver)
    V, b, i, F, info = cb_frame(model, interface, order, "craig-bampton", solver, rigid)
    n_modes = V.shape[1] - b.size
    freqs = []
    cluster = None
    if n_modes:
        Kii = model.K[i][:, i]
        Mii = model.M[i][:, i]
        k = min(i.size, n_modes + CLUSTER_MARGIN)  # a few more: does n_modes cut a multiple eigenvalue?
        lam, phi = eigenmodes(Kii, Mii, k, sigma=0.0, factorization=F, solver=solver)
        whole = whole_clusters(lam, n_modes) if k > n_modes else n_modes
        if whole > n_modes and whole < k:  # keep the whole set (else, rarely, the cut stays)
            cluster = cluster_note(b.size + n_modes, b.size + whole, frequencies_hz(lam)[n_modes - 1])
            V = np.hstack([V, np.zeros((V.shape[0], whole - n_modes))])
            n_modes = whole
        V[i, b.size:] = phi[:, :n_modes]
        freqs = frequencies_hz(lam[:n_modes]).tolist()
    info.update(n_modes=int(n_modes), fixed_interface_hz=freqs, nested=True)
    note = cb_order_note(order, b.size, n_modes, i.size, info.get("n_rigid", 0)) or cluster
    if note:
        info["order_note"] = note
    return Basis(V, "craig-bampton", info)
