"""Two-step reduction: Krylov to an intermediate order, then balanced truncation of that small body."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..basis import Basis, orthonormalize
from ..damping import band_matched
from ..errors import OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.threads import blas_threads
from ..options import Band, band_option, option
from ..projection import project
from ..rigid import exclude_rigid
from ._options import VARIANTS, points_option, rigid_option, variant_option
from ._registry import register_method
from .dense_gramians import dense_gramians, psd_factor
from .gramians import UNDAMPED_ZETA, balance, balance_note
from .krylov import default_points, krylov

__all__ = ["two_step", "TwoStepOptions", "GRAMIANS"]

log = logging.getLogger(__name__)

GRAMIANS = ("band", "full")


@dataclass(frozen=True)
class TwoStepOptions:
    """Options of :func:`two_step`."""

    intermediate: int = option(120, "intermediate Krylov order r1 (at least the final order)", metavar="R1")
    band: Band | None = band_option("the Krylov points and the frequency-limited Gramians")
    gramian: str = option("band", "frequency-limited (band) or full-band Gramians", choices=GRAMIANS)
    variant: str = variant_option()
    points: str | None = points_option("Krylov expansion points of the first step", "three real points over the band")
    rigid: str = rigid_option()


@register_method("two-step", "krylov to an intermediate order, then balanced truncation with exact Gramians",
                 options=TwoStepOptions, survives_coupling=False)
def two_step(model, ports, order, *, intermediate: int = 120, band=None, gramian: str = "band",
             variant: str = "position", points=None, rigid: str = "exclude",
             solver: SolverContext | None = None) -> Basis:
    """Krylov reduction to ``intermediate`` (r1), then second-order balanced truncation to ``order`` (r2).

    The first step (:func:`flexmor.reduction.krylov.krylov`, input and output Krylov spaces at
    real points over the band) is cheap and accurate; the small body ``V1^T (M, D, K) V1`` then
    gets exact dense Gramians (:func:`flexmor.reduction.dense_gramians.dense_gramians`: Lyapunov
    equations, frequency-limited by the Gawronski-Juang formula), is balanced and truncated.
    The final basis ``V1 T`` lives in the full space and is projected one-sided (Galerkin).

    Parameters
    ----------
    model : FEModel
    ports : Ports
    order : int
        Final order r2.
    intermediate : int
        Krylov order r1 (typically 100-200; at least ``order``).
    band : (float, float), optional
        Band in Hz: the Krylov points and the frequency-limited Gramians (default
        :data:`flexmor.options.DEFAULT_BAND`).
    gramian : {'band', 'full'}
        Frequency-limited Gramians of ``band`` or full-band Gramians.
    variant : {'position', 'velocity'}
        Controllability Gramian of positions or velocities (see :func:`flexmor.reduction.balanced.sobt`).
    points : str, optional
        Krylov expansion points (Hz), see :func:`flexmor.reduction.krylov.parse_points`; default the
        three real points of :func:`flexmor.reduction.krylov.default_points`.
    rigid : {'exclude', 'include'}
        Rigid-body modes of a free body (see :func:`flexmor.reduction.krylov.krylov`); the
        included ones are kept in front of the balanced vectors (they have no finite Gramian).
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info``: ``intermediate``, ``hankel_sv`` (of the intermediate body), ``krylov`` info.

    References
    ----------
    Lehner, M., Eberhard, P. (2007). A two-step approach for model reduction in flexible
    multibody dynamics. Multibody System Dynamics 17, 157-176.

    Fehr, J. (2011). Automated and error-controlled model reduction in elastic multibody
    systems. Dissertation, Universität Stuttgart, Shaker Verlag.

    Reis, T., Stykel, T. (2008). Balanced truncation model reduction of second-order systems.
    Math. Comput. Model. Dyn. Syst. 14(5), 391-406.
    """
    solver = as_solver(solver)
    check_choice("gramian", gramian, GRAMIANS)
    check_choice("variant", variant, VARIANTS)
    if order is None:
        raise OptionError("two-step needs order (the final dimension r2)", params=("order",))
    r1 = min(int(intermediate), model.n_dof)
    if r1 < order:
        raise OptionError(f"intermediate ({intermediate}) must be at least order ({order})",
                          params=("intermediate", "order"))
    band = Band.of(band)
    # the intermediate basis without rigid round-off, so that the intermediate body has no spurious modes
    if points is None:  # the three real points over the band: the intermediate order needs no choice of points
        points = default_points(band)
    K1 = exclude_rigid(model, krylov(model, ports, r1, points=points, side="both", band=band, rigid=rigid,
                                     solver=solver))
    red = project(model, K1, ports)
    Dr = red.D
    if Dr is None:  # undamped: Gramians of the lightly damped body (see flexmor.reduction.gramians)
        reg = band_matched(UNDAMPED_ZETA, band)
        Dr = reg.alpha * red.M + reg.beta * red.K
    with blas_threads(1):  # small dense matrices: a second OpenBLAS thread only adds contention
        Pp, Pv, Qp, phi_rb = dense_gramians(red.M, Dr, red.K, red.B, red.C, band if gramian == "band" else None)
    head = phi_rb if rigid == "include" else phi_rb[:, :0]
    n_flex = order - head.shape[1]
    if n_flex < 1:
        raise OptionError(f"order {order} leaves no room next to {head.shape[1]} rigid-body modes", params=("order",))
    T, sigma = balance(psd_factor(Pp if variant == "position" else Pv), psd_factor(Qp), red.M, n_flex)
    V = orthonormalize(K1.V @ np.hstack([head, T]), model.M)
    info = {"intermediate": int(K1.order), "gramian": gramian, "variant": variant, "band_hz": list(band),
            "hankel_sv": sigma[: max(40, 2 * order)].tolist(), "truncated_sv_sum": float(sigma[n_flex:].sum()),
            "n_rigid_included": int(head.shape[1]), "krylov": K1.info, "nested": False}
    if rigid == "exclude":  # (an included head is mixed into the M-orthonormal columns: nothing to keep apart)
        info["rigid"] = rigid
    note = balance_note(T.shape[1], n_flex, head.shape[1])
    if note:
        info["order_note"] = note
    return Basis(V, "two-step", info)
