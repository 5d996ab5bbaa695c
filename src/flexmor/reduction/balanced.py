"""Second-order balanced truncation: ``sobt`` (full band) and ``fw-sobt`` (frequency-limited).

Both balance the low-rank Gramian factors of :mod:`flexmor.reduction.gramians`
(``P ≈ R R^T`` of positions or velocities, ``Q_p ≈ L L^T`` from the outputs): the singular
values of ``L^T M R`` are the second-order Hankel singular values used for truncation, the
leading right balancing vectors span the basis. The exported body is the one-sided
(Galerkin) projection onto that span, so it stays a symmetric mechanical body; the
two-sided balanced projection (and its error bound) is not used, and the bound would not
survive coupling anyway.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.eigen import DENSE_LIMIT
from ..options import Band, band_option, option
from ._options import VARIANTS, nodes_option, rigid_option, solves_option, variant_option
from ._registry import register_method
from .dense_gramians import dense_gramians, psd_factor
from .free_body import rigid_head
from .gramians import _regularized, balance, balance_note, gramian_factors, truncation_basis

__all__ = ["sobt", "fw_sobt", "balanced_basis", "SobtOptions", "FwSobtOptions"]

log = logging.getLogger(__name__)

#: Number of singular values reported in ``info['hankel_sv']`` (at least 2 * order).
N_REPORTED = 40

#: ``sobt``'s default cutoff of large models in units of the band's top. The modal pre-pass computes
#: every mode below it (plate_structure, 35,988 DOF, band top 2 kHz: 51 modes below 2 FMAX, 120 below
#: 5 FMAX, 256 below 10 FMAX); the surrogate solves end there and report a bound of the rest
#: (``info['solves']['tail']``). At 10,944 DOF: position tail 2.3e-4 of the trace at 2 FMAX (sobt 20:
#: 2.7 s CPU, band_error 8.5e-5), 4.6e-5 at 4 FMAX (5.0 s, 3.1e-4), 3.3e-5 at 10 FMAX (15 s).
SOBT_CUTOFF = 2.0


def balanced_basis(model, ports, order, band, *, method: str, variant: str = "position", nodes: int = 4,
                   cutoff=None, rigid: str = "exclude", solves: str = "auto",
                   solver: SolverContext | None = None) -> Basis:
    """Shared body of ``sobt`` and ``fw-sobt``: Gramian factors over ``band``, balancing, basis."""
    solver = as_solver(solver)
    check_choice("variant", variant, VARIANTS)
    if order is None:
        raise OptionError(f"{method} needs order", params=("order",))
    if order > model.n_dof:
        raise OptionError(f"order {order} exceeds the number of DOF {model.n_dof}", params=("order",))
    phi, head = rigid_head(model, ports.B.toarray(), rigid)  # the rigid motion the ports excite goes first
    n_flex = order - head.shape[1]
    if n_flex < 1:
        raise OptionError(f"order {order} leaves no room next to {head.shape[1]} rigid-body modes", params=("order",))
    if math.isinf(band[1]) and band[0] == 0 and model.n_dof <= DENSE_LIMIT and solves == "auto":
        R, L, ginfo = _dense_factors(model, ports, variant)  # small body: exact Lyapunov solutions
    else:
        G = gramian_factors(model, ports, band, nodes=nodes, cutoff=cutoff, solver=solver, rigid_modes=phi,
                            solves=solves)
        R, L, ginfo = G.controllability(variant), G.L, G.info
    T, sigma = balance(R, L, model.M, n_flex)
    V = truncation_basis(np.hstack([head, T]), model.M)
    k = max(N_REPORTED, 2 * order)
    info = {"variant": variant, "hankel_sv": sigma[:k].tolist(),
            "truncated_sv_sum": float(np.sum(sigma[n_flex:])), "rigid": rigid, "n_rigid_included": int(head.shape[1]),
            "nested": False, **ginfo}
    note = balance_note(T.shape[1], n_flex, head.shape[1], ginfo)
    if note:
        info["order_note"] = note
    return Basis(V, method, info)


def _dense_factors(model, ports, variant):
    """Exact full-band Gramian factors of a small body (:func:`~flexmor.reduction.dense_gramians.dense_gramians`)."""
    from ..linalg.eigen import dense_eigenmodes, frequencies_hz

    work, damping = _regularized(model, (0.0, math.inf), frequencies_hz(dense_eigenmodes(model.K, model.M)[0]))
    M, K = model.M.toarray(), model.K.toarray()
    Pp, Pv, Qp, _ = dense_gramians(M, work.D.toarray(), K, ports.B.toarray(), ports.C.toarray())
    info = {"band_hz": [0.0, math.inf], "gramians": "dense Lyapunov (exact)", "gramian_damping": damping}
    return psd_factor(Pp if variant == "position" else Pv), psd_factor(Qp), info


@dataclass(frozen=True)
class SobtOptions:
    """Options of :func:`sobt`."""

    variant: str = variant_option()
    nodes: int = nodes_option()
    band: Band | None = band_option(f"interest: large models resolve resonances up to {SOBT_CUTOFF:g} FMAX")
    cutoff: float | None = option(None, "large models: resonances up to CUTOFF Hz get their own quadrature cell "
                                  f"(default {SOBT_CUTOFF:g} FMAX)", parse=float)
    rigid: str = rigid_option()
    solves: str = solves_option()


@register_method("sobt", "second-order balanced truncation, full-band Gramians (low rank)", options=SobtOptions,
                 survives_coupling=False)
def sobt(model, ports, order, *, variant: str = "position", nodes: int = 4, band=None, cutoff: float | None = None,
         rigid: str = "exclude", solves: str = "auto", solver: SolverContext | None = None) -> Basis:
    """Second-order balanced truncation with full-band (``[0, inf)``) Gramians.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        ``B`` and ``C`` define the controllability and observability Gramians.
    order : int
        Reduced dimension r.
    variant : {'position', 'velocity'}
        Balance the position (``P_p``) or velocity (``P_v``) controllability Gramian against
        the position observability Gramian ``Q_p``; the velocity variant weighs the
        response by ``w^2`` and favours higher frequencies.
    nodes : int
        Gauss points per panel of the resonance-resolving quadrature (panels graded towards each
        resonance; 4 gives Gramians to ~1e-5, 6 to ~1e-7, 8 to ~1e-9).
    band : (float, float), optional
        Only used for the default ``cutoff`` of large models: ``SOBT_CUTOFF * fmax`` (2 fmax).
    cutoff : float, optional
        Large models (more than 600 DOF): resonances up to ``cutoff`` Hz get their own
        quadrature cell. With the surrogate solves the Gramians end at the cutoff and
        ``info['solves']['tail']`` bounds the part above it (a share of the trace; with
        Rayleigh damping the modes above contribute at most ``|phi_j^T B|^2 / (2 beta lam_j^2)``
        each, bounded in total by one static solve); with the direct solves the rest of
        ``[0, inf)`` is one tail cell. Small models (up to 600 DOF) get the exact dense
        Lyapunov solutions (:func:`flexmor.reduction.dense_gramians.dense_gramians`).
    rigid : {'exclude', 'include'}
        Free bodies: the rigid-body modes are left to the floating frame (exclude, default: the
        body reduced and judged is the one exported) or the ones the inputs excite lead the basis
        (include); the Gramians are those of the flexible part.
    solves : {'auto', 'direct', 'dense', 'surrogate'}
        How the quadrature nodes are solved (:func:`flexmor.reduction.gramians.gramian_factors`):
        ``auto`` is the exact dense Lyapunov solution up to 600 DOF, else the verified surrogate
        up to the cutoff with Rayleigh damping (``beta > 0``) or an undamped model, else ``direct``
        (one complex factorization per node).
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info['hankel_sv']`` the singular values used for truncation (leading ones),
        ``info['truncated_sv_sum']``, what the Gramians cover (``band_hz``: the interval integrated,
        which ends at the cutoff when the surrogate solves leave out the rest; ``band_requested_hz``;
        ``cutoff_hz``; ``gramians`` in words; :func:`flexmor.reduction.gramians.coverage`) and an
        ``order_note`` that says which Gramians limited the order when fewer vectors came out.

    References
    ----------
    Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
    Math. Comput. Model. Dyn. Syst. 14(5), 391-406.

    Chahlaoui, Y., Lemonnier, D., Vandendorpe, A., Van Dooren, P. (2006). Second-order
    balanced truncation. Linear Algebra Appl. 415, 373-384.
    """
    solver = as_solver(solver)
    if cutoff is None and model.n_dof > 600:
        cutoff = SOBT_CUTOFF * Band.of(band).fmax
    return balanced_basis(model, ports, order, (0.0, math.inf), method="sobt", variant=variant, nodes=nodes,
                          cutoff=cutoff, rigid=rigid, solves=solves, solver=solver)


@dataclass(frozen=True)
class FwSobtOptions:
    """Options of :func:`fw_sobt`."""

    band: Band | None = band_option("the frequency-limited Gramians")
    variant: str = variant_option()
    nodes: int = nodes_option()
    rigid: str = rigid_option()
    solves: str = solves_option()


@register_method("fw-sobt", "second-order balanced truncation, frequency-limited Gramians of the band",
                 options=FwSobtOptions, survives_coupling=False)
def fw_sobt(model, ports, order, *, band=None, variant: str = "position", nodes: int = 4, rigid: str = "exclude",
            solves: str = "auto", solver: SolverContext | None = None) -> Basis:
    """Frequency-limited second-order balanced truncation over the band of interest.

    The Gramians are the integrals of ``Re(X X^H)`` over ``band`` only (Gawronski & Juang),
    approximated by the resonance-resolving quadrature of
    :func:`flexmor.reduction.gramians.gramian_factors` and kept low-rank.

    Parameters
    ----------
    model : FEModel
    ports : Ports
    order : int
        Reduced dimension r.
    band : Band or (float, float), optional
        Band in Hz (default :data:`flexmor.options.DEFAULT_BAND`, the error band of ``flexmor reduce``).
    variant : {'position', 'velocity'}
        See :func:`sobt`.
    nodes : int
        Gauss points per panel of the quadrature (see :func:`sobt`).
    rigid : {'exclude', 'include'}
        See :func:`sobt`.
    solves : {'auto', 'direct', 'dense', 'surrogate'}
        How the quadrature nodes are solved (:func:`flexmor.reduction.gramians.gramian_factors`):
        ``auto`` is the exact modal form up to
        :data:`~flexmor.reduction.gramian_solves.DENSE_GRAMIAN_MAX_DOF` DOF and a verified surrogate
        above (reported in ``info['solves']``); ``direct`` is one complex factorization per node.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info['hankel_sv']`` the frequency-limited singular values used for truncation.

    References
    ----------
    Gawronski, W., Juang, J.-N. (1990). Model reduction in limited time and frequency
    intervals. Int. J. Systems Sci. 21(2), 349-376.

    Benner, P., Kürschner, P., Saak, J. (2016). Frequency-limited balanced truncation with
    low-rank approximations. SIAM J. Sci. Comput. 38(1), A471-A499.

    Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
    Math. Comput. Model. Dyn. Syst. 14(5), 391-406.
    """
    solver = as_solver(solver)
    return balanced_basis(model, ports, order, Band.of(band), method="fw-sobt", variant=variant, nodes=nodes,
                          rigid=rigid, solves=solves, solver=solver)
