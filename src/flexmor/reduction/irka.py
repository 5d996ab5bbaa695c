"""Structure-preserving second-order IRKA (one-sided Galerkin, tangential directions).

Iterative rational Krylov: interpolate ``H(s) = C (s^2 M + s D + K)^{-1} B`` tangentially at
the mirror images ``sigma_j = -lambda_j`` of poles of the current reduced body and repeat
until the points settle. The basis is built from
``(sigma_j^2 M + sigma_j D + K)^{-1} B b_j`` (one factorization per point, a complex point
and its conjugate share one solve that gives a real and an imaginary column); the reduced
body is the one-sided Galerkin projection, so it stays a symmetric mechanical system.

A reduced second-order body of order r has 2r poles, but r real columns interpolate at r
points only. The r points are the mirror images of the reduced poles of smallest magnitude
(the lowest reduced modes), in conjugate pairs. Choosing instead the most H2-dominant poles
(largest residue over damping) flips between pole sets and cycles on lightly damped
solids; the smallest-magnitude choice converged in all our tests.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..basis import Basis
from ..errors import OptionError, SolverError
from ..linalg.context import SolverContext, as_solver
from ..options import Band, band_option, option
from ..projection import project
from ..rigid import m_project, rigid_body_modes
from ._registry import register_method
from .krylov import krylov, merge_blocks, shifted_factorization

__all__ = ["irka", "IrkaOptions", "convergence_note", "reduced_poles", "select_shifts"]

log = logging.getLogger(__name__)


def _linearize(body):
    """First-order form ``E x' = A x + B u``, ``y = C x`` of a reduced body (dense)."""
    r = body.M.shape[0]
    Dr = body.D if body.D is not None else np.zeros((r, r))
    Z, Id = np.zeros((r, r)), np.eye(r)
    E = np.block([[Id, Z], [Z, body.M]])
    A = np.block([[Z, Id], [-body.K, -Dr]])
    B = np.vstack([np.zeros_like(body.B), body.B])
    C = np.hstack([body.C, np.zeros_like(body.C)])
    return E, A, B, C


def reduced_poles(body):
    """Poles and right tangential directions of a reduced body.

    Returns ``(lam, b)``: the 2r poles of the first-order form and the directions
    ``b_j = (y_j^H B1)^T`` with the left eigenvectors ``y_j`` normalized so that
    ``y_j^H E x_j = 1`` (the residue is ``(C1 x_j)(y_j^H B1)``).
    """
    E, A, B, _ = _linearize(body)
    lam, Y, X = sla.eig(A, E, left=True, right=True)
    scale = np.einsum("ij,ij->j", Y.conj(), E @ X)
    return lam, (Y.conj().T @ B) / scale[:, None]


def select_shifts(lam, b, r: int):
    """Mirror images of the smallest poles, in conjugate pairs, until r real columns.

    Returns ``(sigma, dirs)``: one representative point (``Im >= 0``) per pair and, per point,
    the tangential directions as columns of an (m, k) array. Poles that coincide (relative
    distance 1e-6; e.g. the y and z bending modes of a square beam) share one point with a
    block of directions; a direction adds columns only if it is new (rank test), so a
    repeated pole of a single-input body does not waste columns.
    """
    keep = lam.imag >= -1e-12 * np.abs(lam)
    lam, b = lam[keep], b[keep]
    sig, dirs, cols = [], [], 0
    for j in np.argsort(np.abs(lam)):
        if cols >= r:
            break
        real = abs(lam[j].imag) <= 1e-12 * abs(lam[j])
        d = (b[j].real if real else b[j])[:, None]
        g = next((i for i, q in enumerate(sig) if abs(lam[j] + q) <= 1e-6 * abs(lam[j])), None)
        if g is None:
            sig.append(-lam[j].real if real else -lam[j])
            dirs.append(d)
        else:
            blk = np.hstack([dirs[g], d])
            if np.linalg.matrix_rank(blk, tol=1e-8 * np.abs(blk).max()) <= dirs[g].shape[1]:
                continue
            dirs[g] = blk
        cols += 1 if real else 2
    return np.asarray(sig, dtype=complex), dirs


def _shift_change(new, old) -> float:
    """Largest relative distance of a new point to the nearest old one."""
    if old is None or len(old) == 0:
        return np.inf
    d = np.abs(new[:, None] - old[None, :]).min(axis=1)
    return float(np.max(d / np.maximum(np.abs(new), np.finfo(float).tiny)))


def tangential_basis(model, B, sigma, dirs, order, solver: SolverContext | None = None, rigid_modes=None):
    """Orthonormal real basis of ``(s_j^2 M + s_j D + K)^{-1} B b_j`` (real and imaginary parts); with
    ``rigid_modes`` (M-orthonormal, of a free body) their flexible parts, M-orthogonal to them."""
    solver = as_solver(solver)
    blocks = []
    for s, b in zip(sigma, dirs):
        F, s = shifted_factorization(model, s, solver)
        x = F.solve(B @ b)
        if rigid_modes is not None and rigid_modes.shape[1]:
            x = m_project(model, rigid_modes, x)
        blocks.append([np.hstack([x.real, x.imag]) if s.imag != 0 else np.real(x)])
        del F
    return merge_blocks(blocks, order)


def convergence_note(max_iter: int, change: float, shift_tol: float) -> str:
    """What an iteration that stopped without converging returned, and what to change."""
    moved = ("one set of points, none to compare it with" if not np.isfinite(change) else
             f"the points still moved by {change:.2g} relative, shift_tol {shift_tol:g}")
    return (f"irka did not converge in {max_iter} iterations ({moved}); the body interpolates at the last "
            "points, which are not the H2-optimal ones: pass a larger max_iter, another start (the band of the "
            "krylov start basis), or a lower order")


@dataclass(frozen=True)
class IrkaOptions:
    """Options of :func:`irka`."""

    max_iter: int = option(50, "maximum iterations")
    shift_tol: float = option(1e-4, "relative change of the points for convergence")
    band: Band | None = band_option("the krylov start basis (its reduced poles give the initial points)")


@register_method("irka", "second-order IRKA: H2-type tangential interpolation at iterated points", options=IrkaOptions)
def irka(model, ports, order, *, max_iter: int = 50, shift_tol: float = 1e-4, band=None,
         solver: SolverContext | None = None) -> Basis:
    """Second-order IRKA basis (one-sided Galerkin, structure preserving).

    Parameters
    ----------
    model : FEModel
        Needs damping (``D``) for the poles to leave the imaginary axis; on an undamped body
        the points land on (nearly) its eigenfrequencies, and a singular shifted matrix is
        reported as such (:class:`flexmor.errors.SolverError`). A free body (rigid-body modes,
        :func:`flexmor.rigid.rigid_body_modes`) is reduced as the floating frame wants it: the
        start basis and every interpolation vector are made M-orthogonal to the rigid-body modes,
        so that the reduced poles are elastic ones (none at ``s = 0``, whose mirror image would be
        a singular point) and ``H``'s flexible part is interpolated (exact for proportional damping);
        ``info['rigid'] = 'exclude'``, judged on the elastic part.
    ports : Ports
        ``B`` gives the tangential interpolation data (``C`` enters through the residues).
    order : int
        Reduced dimension r.
    max_iter : int
        Maximum number of iterations (each: r/2 complex factorizations of order n).
    shift_tol : float
        Convergence when every new point lies within ``shift_tol`` (relative) of an old one.
    band : (float, float), optional
        Band (Hz) of the :func:`flexmor.reduction.krylov.krylov` start basis, whose
        reduced poles give the initial points; default :data:`flexmor.options.DEFAULT_BAND`.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.

    Returns
    -------
    Basis
        ``info``: ``converged`` (bool), ``iterations``, ``shift_change`` (last relative change),
        ``shifts_rad_s`` (final points). Without convergence the basis of the last points is returned
        (it interpolates there and is usable), ``info['convergence_note']`` says so and what to
        change (also logged as a warning); ``info['order_note']`` says why fewer vectors than
        ``order`` came out, if so.

    References
    ----------
    Gugercin, S., Antoulas, A. C., Beattie, C. (2008). H2 model reduction for large-scale
    linear dynamical systems. SIAM J. Matrix Anal. Appl. 30(2), 609-638.

    Wyatt, S. (2012). Issues in interpolatory model reduction: inexact solves, second-order
    systems and DAEs. PhD thesis, Virginia Tech, ch. 5 (SOR-IRKA).

    Beattie, C. A., Gugercin, S. (2009). Interpolatory projection methods for
    structure-preserving model reduction. Systems Control Lett. 58(3), 225-232.
    """
    solver = as_solver(solver)
    phi = rigid_body_modes(model)  # a free body: its flexible part (the frame carries the rigid motion)
    if order is None:
        raise OptionError("irka needs order", params=("order",))
    if int(max_iter) != max_iter or max_iter < 1:
        raise OptionError(f"max_iter must be a positive integer, got {max_iter}", params=("max_iter",))
    if not shift_tol > 0:
        raise OptionError(f"shift_tol must be positive, got {shift_tol}", params=("shift_tol",))
    B = ports.B.toarray()
    basis = krylov(model, ports, order, band=band, solver=solver)
    V = basis.V
    old, change, it, history = None, np.inf, 0, []
    for it in range(1, int(max_iter) + 1):
        red = project(model, Basis(V, "irka"), ports)
        sigma, dirs = select_shifts(*reduced_poles(red), order)
        change = _shift_change(sigma, old)
        history.append(change)
        log.debug("irka iteration %d: shift change %.2e", it, change)
        if change < shift_tol:
            break
        try:
            V = tangential_basis(model, B, sigma, dirs, order, solver, rigid_modes=phi)
        except SolverError:
            if model.D is not None:
                raise
            raise SolverError(
                "irka on an undamped body: the mirror images of the reduced poles lie on the frequency "
                "axis at (nearly) the body's eigenfrequencies, where s^2 M + K is singular; give the body "
                "damping (rayleigh or modal_damping) or use krylov or modal",
                params=("rayleigh", "modal_damping")) from None
        old = sigma
    converged = change < shift_tol
    info = {"converged": bool(converged), "iterations": it, "shift_change": change,
            "shift_history": history, "shifts_rad_s": [str(s) for s in (old if old is not None else [])],
            "max_iter": int(max_iter), "shift_tol": float(shift_tol)}
    if not converged:
        info["convergence_note"] = convergence_note(int(max_iter), change, shift_tol)
        log.warning("%s", info["convergence_note"])
    if V.shape[1] < order:
        info["order_note"] = (f"order {V.shape[1]} instead of {order}: the tangential directions at the "
                              f"{'last' if converged else 'last (unconverged)'} points span only {V.shape[1]} "
                              "independent vectors (a complex point gives a real and an imaginary part; "
                              "dependent ones are dropped)")
    if phi.shape[1]:
        info.update(rigid="exclude", n_rigid_included=0)
    return Basis(V, "irka", info)
