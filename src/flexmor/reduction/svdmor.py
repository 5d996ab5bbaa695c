"""SVDMOR: compress many inputs and outputs to a few dominant directions, then Krylov."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..basis import Basis
from ..errors import OptionError
from ..linalg.context import SolverContext, as_solver
from ..options import Band, band_option, option
from ..ports import Ports
from ._options import points_option, rigid_option, side_option
from ._registry import register_method
from .krylov import default_points, krylov, parse_points, shifted_factorization

__all__ = ["svdmor", "SvdmorOptions", "port_directions", "sampled_transfer", "real_parts"]

log = logging.getLogger(__name__)


def sampled_transfer(model, ports, points, *, solver: SolverContext | None = None) -> tuple[list, list]:
    """``H(s_k) = C (s_k^2 M + s_k D + K)^{-1} B`` at the points ``s_k = 2 pi p_k`` (``points`` in Hz, complex; one
    factorization each, :func:`flexmor.reduction.krylov.shifted_factorization`): ``([H(s_1), ...], used)``, the
    points actually used in rad/s (0 on a free body moves to a real point)."""
    solver = as_solver(solver)
    B, C = ports.B.toarray(), ports.C
    H, used = [], []
    for p in points:
        F, s = shifted_factorization(model, 2 * np.pi * complex(p), solver)
        H.append(C @ F.solve(B))
        used.append(s)
        del F
    return H, used


def port_directions(model, ports, points, *, solver: SolverContext | None = None):
    """Input and output directions from sampled transfer matrices ``H(s_k)``.

    ``H(s_k) = C (s_k^2 M + s_k D + K)^{-1} B`` at the points ``s_k`` (:func:`sampled_transfer`); the right
    singular vectors of ``[H(s_1); H(s_2); ...]`` (real and imaginary parts) are the input directions, the left
    singular vectors of ``[H(s_1), H(s_2), ...]`` the output directions.

    Returns
    -------
    W_in : ndarray, shape (m, m)
    s_in : ndarray
        Singular values of the input directions, descending.
    U_out : ndarray, shape (p, p)
    s_out : ndarray
    used : list of complex
        Points actually used (rad/s).
    """
    Hs, used = sampled_transfer(model, ports, points, solver=solver)
    H = [part for Hk in Hs for part in real_parts(Hk)]
    _, s_in, Wt = np.linalg.svd(np.vstack(H), full_matrices=False)
    U, s_out, _ = np.linalg.svd(np.hstack(H), full_matrices=False)
    return Wt.T, s_in, U, s_out, used


def real_parts(X) -> list:
    """``[Re X, Im X]`` of a complex ``X`` with an imaginary part, else ``[Re X]``."""
    return [X.real, X.imag] if np.iscomplexobj(X) and np.any(X.imag) else [np.real(X)]


@dataclass(frozen=True)
class SvdmorOptions:
    """Options of :func:`svdmor`."""

    directions: int | None = option(None, "input/output directions kept (default: singular values above 1e-3 of "
                                    "the largest)", parse=int)
    band: Band | None = band_option("the sampling and Krylov points")
    points: str | None = points_option("sampling and Krylov points", "three real points over the band")
    side: str = side_option("both")
    rigid: str = rigid_option()


@register_method("svdmor", "SVD compression of many inputs/outputs from sampled transfer data, then krylov",
                 options=SvdmorOptions, survives_coupling=False)
def svdmor(model, ports, order, *, directions: int | None = None, band=None, points=None, side: str = "both",
           rigid: str = "exclude", solver: SolverContext | None = None) -> Basis:
    """SVDMOR: Krylov reduction of the body with its inputs and outputs compressed by an SVD.

    A body with many inputs (``m``) makes block Krylov spaces grow by ``m`` per moment. SVDMOR
    samples ``H(s)`` at real points over the band, keeps the ``directions`` dominant input
    directions ``W`` (``B -> B W``) and output directions ``U`` (``C -> U^T C``), and builds
    the Krylov basis of the compressed body, so more moments fit into the same order. The
    reduced body keeps all original inputs and outputs (``Br = V^T B``). Moments are matched
    only in the kept directions (``U^T H W``), so the interpolation property does not carry
    over to an assembly.

    Parameters
    ----------
    model : FEModel
    ports : Ports
        The (many) inputs and outputs.
    order : int
        Reduced dimension r.
    directions : int, optional
        Number of input (and output) directions kept; default: those with singular values
        above ``1e-3`` of the largest (at least 1).
    band : (float, float), optional
        Band in Hz of the sampling and Krylov points (default :data:`flexmor.options.DEFAULT_BAND`).
    points : str, optional
        Points (Hz) of the sampling and of the Krylov spaces (default three real points).
    side : {'input', 'output', 'both'}
        Krylov space of the compressed ``B``, ``C^T`` or both.
    rigid : {'exclude', 'include'}
        See :func:`flexmor.reduction.krylov.krylov`.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info``: ``directions``, ``input_sv`` and ``output_sv`` (all singular values),
        ``discarded_input_sv`` and ``discarded_output_sv``.

    References
    ----------
    Feldmann, P., Liu, F. (2004). Sparse and efficient reduced order modeling of linear
    subcircuits with large number of terminals. Proc. IEEE/ACM ICCAD, 88-92.

    Benner, P., Schneider, A. (2011). Model order and terminal reduction approaches via
    matrix decomposition and low rank approximation. In: Scientific Computing in Electrical
    Engineering SCEE 2010, Springer, 523-530.
    """
    solver = as_solver(solver)
    if order is None:
        raise OptionError("svdmor needs order", params=("order",))
    pts = parse_points(points) if points is not None else default_points(Band.of(band))
    W, s_in, U, s_out, used = port_directions(model, ports, pts, solver=solver)
    if directions is None:
        k_in = max(1, int(np.sum(s_in > 1e-3 * s_in[0])))
        k_out = max(1, int(np.sum(s_out > 1e-3 * s_out[0])))
    else:
        if int(directions) != directions or directions < 1:
            raise OptionError(f"directions must be a positive integer, got {directions}", params=("directions",))
        k_in, k_out = min(int(directions), W.shape[1]), min(int(directions), U.shape[1])
    Bc = sp.csr_matrix(ports.B @ W[:, :k_in])
    Cc = sp.csr_matrix(U[:, :k_out].T @ ports.C)
    compressed = Ports(B=Bc, C=Cc, input_names=[f"w{j + 1}" for j in range(k_in)],
                       output_names=[f"v{j + 1}" for j in range(k_out)])
    Kb = krylov(model, compressed, order, points=pts, band=band, side=side, rigid=rigid, solver=solver)
    info = {"directions": [k_in, k_out], "input_sv": s_in.tolist(), "output_sv": s_out.tolist(),
            "discarded_input_sv": s_in[k_in:].tolist(), "discarded_output_sv": s_out[k_out:].tolist(),
            "sample_points_rad_s": [str(s) for s in used], "krylov": Kb.info, "nested": True,
            "rigid": rigid, "n_rigid_included": Kb.info["n_rigid_included"]}
    return Basis(Kb.V, "svdmor", info)
