"""Free-interface component mode synthesis: Craig-Chang and Herting.

Both keep the body's free-interface normal modes (the modes of the model as given, its interfaces
unconstrained; of a free body its elastic free-free modes) and complete them with the residual
flexibility of the interfaces: the static responses to unit loads at the interface DOFs that the kept
modes leave out,

    G_r = (K^-1 - Phi_k Lambda_k^-1 Phi_k^T) F_b

(``F_b`` the unit loads; on a free body the inertia-relief responses, elastic loads ``(I - M Phi Phi^T)
F_b`` solved on the elastic subspace, :mod:`flexmor.reduction.residual`). ``G_r`` is M- and K-orthogonal
to the kept modes, so the body's lowest frequencies are the kept modes' own (exact to round-off), the
residual attachment modes' lie above them, and the static response to any interface load is exact.

* ``craig-chang``: the coordinates are the modal ones and the residual attachment amplitudes,
  ``V = [Phi_k, G_r]`` (Craig, Chang 1977: free-interface modes with residual flexibility).
* ``herting``: the same space in interface coordinates, ``V = [Psi_b, Phi_k - Psi_b Phi_k,b]`` with
  ``Psi_b = G_r G_r,bb^-1``: the first ``n_b`` coordinates are the interface displacements (``V`` is the
  identity at the interface rows, the modal columns vanish there), as Craig-Bampton's constraint modes
  give and MBS codes expect of an interface (Herting 1985). On a free body they are the elastic
  interface displacements, the frame carrying its rigid motion.

The order counts ``n_b`` (the interface DOFs) plus the kept modes; ``max_frequency`` keeps the modes up to
a frequency instead. References: Craig, R. R., Chang, C.-J. (1977). On the use of attachment modes in
substructure coupling for dynamic analysis. AIAA paper 77-405. Herting, D. N. (1985). A general purpose,
multi-stage, component modal synthesis method. Finite Elements in Analysis and Design 1, 153-164.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..errors import ModelError, OptionError
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import eigenmodes, frequencies_hz, rigid_body_threshold
from ..options import option
from ..ports import interface_dofs
from ..rigid import rigid_body_modes
from ._options import interface_option
from ._registry import register_method
from .residual import static_solve

__all__ = ["craig_chang", "herting", "free_interface_basis"]


@dataclass(frozen=True)
class FreeInterfaceOptions:
    """Options of :func:`craig_chang` and :func:`herting`."""

    interface: list | None = interface_option()
    max_frequency: float | None = option(None, "keep the free-interface modes up to this frequency in Hz (the order "
                                         "then follows from it)", parse=float, metavar="HZ")


def free_interface_basis(model, order, interface, max_frequency, solver: SolverContext, method: str):
    """``(Phi_k, G_r, b, freqs)``: the kept free-interface modes (elastic, M-normalised), the residual
    flexibility attachments of the interface DOFs ``b``, and the kept modes' frequencies (Hz)."""
    if not interface:
        raise OptionError(f"{method} needs interface (the node, set or coupling master of the joint)",
                          params=("interface",))
    b = interface_dofs(model, interface)
    if order is None and max_frequency is None:
        raise OptionError(f"{method} needs order (the {b.size} interface DOFs plus the modes kept) or max_frequency",
                          params=("order", "max_frequency"))
    if order is not None and max_frequency is not None:
        raise OptionError("give order or max_frequency, not both", params=("order", "max_frequency"))
    if order is not None and order <= b.size:
        raise OptionError(f"{method} needs order > the {b.size} interface DOFs (the rest are the modes kept), got "
                          f"{order}", params=("order",))
    phi = rigid_body_modes(model)
    n_rb = phi.shape[1]
    threshold = rigid_body_threshold(model.K, model.M)
    n_free = model.n_dof - n_rb - b.size
    k = min(order - b.size, n_free) if order is not None else 8
    while True:
        lam, X = eigenmodes(model.K, model.M, min(k + n_rb, model.n_dof), solver=solver)
        el = np.flatnonzero(lam >= threshold)
        lam, X = lam[el], X[:, el]
        if max_frequency is None or k >= n_free or frequencies_hz(lam[-1]) > float(max_frequency):
            break
        k = min(2 * k, n_free)
    keep = np.flatnonzero(frequencies_hz(lam) <= float(max_frequency)) if max_frequency is not None \
        else np.arange(min(k, lam.size))
    if keep.size == 0:
        raise OptionError(f"max_frequency {max_frequency:g} Hz is below the lowest free-interface mode "
                          f"({frequencies_hz(lam[0]):.4g} Hz)", params=("max_frequency",))
    lam, X = lam[keep], X[:, keep]
    X = X / np.sqrt(np.einsum("ij,ij->j", X, model.M @ X))
    F = np.zeros((model.n_dof, b.size))
    F[b, np.arange(b.size)] = 1.0
    G = static_solve(model, F, phi, solver)
    G_r = G - X @ ((X.T @ F) / lam[:, None])
    return X, G_r, b, frequencies_hz(lam).tolist()


#: The parameters of both methods' docstrings.
_PARAMETERS = """
    Parameters
    ----------
    model : FEModel
        Free or supported; its interfaces unconstrained (the free-interface modes are its own).
    ports : Ports
        Not used: the basis depends on the interface only.
    order : int
        The interface DOFs plus the number of free-interface modes kept.
    interface : list of str, optional
        Interface SPECs: a node, a set, ``SET:DIR`` or a coupling master ``SET@RBE2``.
    max_frequency : float, optional
        Keep the free-interface modes up to this frequency (Hz) in place of ``order``.
    solver : SolverContext, optional
        Solver of the eigen solve and of the static responses.

    Returns
    -------
    Basis
        ``info['free_interface_hz']`` the kept modes' frequencies, ``info['n_modes']``,
        ``info['n_interface_dofs']``.
    """


def _documented(fn):
    fn.__doc__ = fn.__doc__.rstrip() + "\n" + _PARAMETERS
    return fn


def _info(b, freqs, method) -> dict:
    return {"n_interface_dofs": int(b.size), "n_modes": len(freqs), "free_interface_hz": freqs, "rigid": "exclude",
            "attachment": "residual flexibility", "coordinates": "interface displacements, modal" if method == "herting"
            else "modal, residual attachment"}


@register_method("craig-chang", "free-interface modes + residual flexibility of the interfaces",
                 options=FreeInterfaceOptions, uses_inputs=False)
@_documented
def craig_chang(model, ports, order, *, interface=None, max_frequency: float | None = None,
                solver: SolverContext | None = None) -> Basis:
    """Craig-Chang basis ``[Phi_k, G_r]``: free-interface modes and residual flexibility attachment modes
    (see the module docstring; the attachments scaled to unit modal mass).
    """
    X, G_r, b, freqs = free_interface_basis(model, order, interface, max_frequency, as_solver(solver), "craig-chang")
    G_r = G_r / np.sqrt(np.einsum("ij,ij->j", G_r, model.M @ G_r))  # unit modal mass, like the modes
    return Basis(np.hstack([X, G_r]), "craig-chang", _info(b, freqs, "craig-chang"))


@register_method("herting", "free-interface modes + residual flexibility, in interface coordinates",
                 options=FreeInterfaceOptions, uses_inputs=False)
@_documented
def herting(model, ports, order, *, interface=None, max_frequency: float | None = None,
            solver: SolverContext | None = None) -> Basis:
    """Herting basis ``[Psi_b, Phi_k - Psi_b Phi_k,b]``: Craig-Chang's space in interface coordinates (the
    first ``n_b`` columns are the identity at the interface DOFs; see the module docstring).
    """
    X, G_r, b, freqs = free_interface_basis(model, order, interface, max_frequency, as_solver(solver), "herting")
    Gbb = G_r[b]
    if np.linalg.cond(Gbb) > 1e12:
        raise ModelError("herting: the residual flexibility at the interface is singular (interface DOFs that the "
                         "kept modes or the rigid-body motion determine); use craig-chang", params=("interface",))
    Psi = np.linalg.solve(Gbb.T, G_r.T).T  # G_r Gbb^-1
    return Basis(np.hstack([Psi, X - Psi @ X[b]]), "herting", _info(b, freqs, "herting"))
