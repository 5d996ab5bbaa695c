"""Guyan (static) condensation onto interface degrees of freedom."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..errors import OptionError, check_choice
from ..linalg import factorize
from ..linalg.amg import register_rows
from ..linalg.context import SolverContext, as_solver
from ..options import option
from ..ports import interface_dofs
from ..rigid import rigid_body_modes
from ._options import interface_option
from ._registry import register_method
from .free_body import inertia_relief_modes


def constraint_modes(model, interface, solver: SolverContext | None = None):
    """Static constraint modes of the interface DOFs.

    Returns ``(V, b, i, F)``: the basis ``V`` (n_dof, n_b) with ``V[b] = I`` and
    ``V[i] = -K_ii^{-1} K_ib``, the interface and interior equation indices, and the
    factorization ``F`` of ``K_ii`` (for reuse, e.g. by fixed-interface modes).
    """
    solver = as_solver(solver)
    if not interface:
        raise OptionError("this method needs interface SPECs (NODE, SET or SET:DIR)", params=("interface",))
    b = interface_dofs(model, interface)
    mask = np.ones(model.n_dof, bool)
    mask[b] = False
    i = np.flatnonzero(mask)
    if i.size == 0:
        raise OptionError("every DOF is an interface DOF; nothing to condense")
    K = model.K.tocsr()
    Kii = K[i][:, i]
    Kib = K[i][:, b]
    register_rows(solver, model.n_dof, i)  # (the amg backend's near-null space: flexmor.linalg.amg)
    F = factorize(Kii, solver=solver, symmetric=True, positive=True)
    V = np.zeros((model.n_dof, b.size))
    V[b, np.arange(b.size)] = 1.0
    V[i] = -F.solve(Kib.toarray())
    return V, b, i, F


@dataclass(frozen=True)
class GuyanOptions:
    """Options of :func:`guyan`."""

    interface: list | None = interface_option()
    rigid: str = option("exclude", "free bodies: rigid-body motion in the basis or not (exclude: the interface's "
                        "inertia-relief attachment modes replace the constraint modes)", choices=("exclude", "include"))


@register_method("guyan", "static condensation onto the interface DOFs", options=GuyanOptions,
                 uses_inputs=False)
def guyan(model, ports, order, *, interface=None, rigid: str = "exclude",
          solver: SolverContext | None = None) -> Basis:
    """Guyan reduction: the static constraint modes of the interface DOFs.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        Unused by the basis.
    order : int or None
        Must equal the number of interface DOFs if given.
    interface : list of str, optional
        Interface SPECs (``NODE``, ``SET``, ``NODE:DIR``, ``SET:DIR``).
    rigid : {'exclude', 'include'}
        Free bodies: the constraint modes of an interface that holds the body span its rigid-body
        motions (six of them for one RBE2 master: the whole Guyan basis is rigid motion, nothing
        of it is left in the floating frame). ``exclude`` (default) uses the interface's
        inertia-relief attachment modes instead (:func:`flexmor.reduction.free_body.inertia_relief_modes`,
        as :func:`flexmor.reduction.craig_bampton.craig_bampton` does): the quasi-static elastic
        response to interface loads balanced by the body's inertia, M-orthogonal to the rigid-body
        modes, ``n_b`` columns. ``include`` keeps the constraint modes (interface coordinates).
        No effect on a supported body.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize` for ``K_ii``.

    Returns
    -------
    Basis
        Exact for static loads at the interface DOFs (for a free body without rigid motion:
        for their elastic, inertia-relieved part).

    References
    ----------
    Guyan, R. J. (1965). Reduction of stiffness and mass matrices. AIAA Journal 3(2), 380.
    """
    solver = as_solver(solver)
    check_choice("rigid", rigid, ("exclude", "include"))
    phi = rigid_body_modes(model) if rigid == "exclude" else np.zeros((model.n_dof, 0))
    if phi.shape[1]:  # a free body: the elastic, inertia-relieved responses to the interface loads
        if not interface:
            raise OptionError("this method needs interface SPECs (NODE, SET or SET:DIR)", params=("interface",))
        b = interface_dofs(model, interface)
        V = inertia_relief_modes(model, b, phi=phi, solver=solver)
        info = {"rigid": "exclude", "attachment": "inertia-relief", "n_rigid_body_modes": int(phi.shape[1])}
    else:
        V, b, _, _ = constraint_modes(model, interface, solver)
        info = {}
    if order is not None and order != b.size:
        raise OptionError(f"guyan's order is the number of interface DOFs ({b.size}), not {order}",
                          params=("order",))
    return Basis(V, "guyan", {"n_interface_dofs": int(b.size), **info})
