"""Checks of a model before it is reduced: rigid-body modes and mechanisms; the band of a study.

An elastic body has at most six zero-energy modes (three translations, three rotations of a
free body). More mean a mechanism: unconnected parts, missing elements, released DOFs. No
reduced body of a mechanism is useful in a multibody code, and most methods would either fail
with a solver message that does not say why or silently return a body with spurious
zero-frequency modes; :func:`check_rigid_body_modes` refuses it with a :class:`ModelError`
that names the cause. A free body (1 to 6 rigid-body modes) is legal: it is reported with a
:class:`~flexmor.errors.FlexmorNote` (``rigid-body-modes``, :func:`flexmor.errors.note`), and the
methods handle it (shifted expansion points, exclusion of the rigid-body modes).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .errors import FlexmorWarning, ModelError, SolverError, note
from .linalg.context import SolverContext, as_solver
from .linalg.distributed import is_partitioned

__all__ = ["MAX_RIGID_BODY_MODES", "COUPLING_MODES", "check_rigid_body_modes", "first_elastic_hz", "check_band",
           "highest_hz", "looks_like_rad_per_s", "rigid_body_note",
           "lowest_elastic_hz", "coupling_frequencies", "describe_couplings", "mechanism_error", "signed_percent",
           "stable_lowest_eigenvalues", "unstable_error"]

#: Zero-energy modes an elastic body can have (3 translations + 3 rotations).
MAX_RIGID_BODY_MODES = 6


def mechanism_error(model, n_zero: int) -> ModelError:
    """The error for a stiffness matrix with ``n_zero`` (> 6) zero-energy modes."""
    where = model.source or model.name
    return ModelError(f"{where}: the stiffness matrix has at least {n_zero} zero-energy modes (a free body has "
                      f"at most {MAX_RIGID_BODY_MODES}): the model is a mechanism; look for unconnected parts, "
                      "missing elements or released DOFs")


def check_rigid_body_modes(model, *, solver: SolverContext | None = None, sigma: float | None = None,
                           keep: bool = False) -> int:
    """Number of rigid-body (zero-energy) modes of ``model``; refuse a mechanism.

    The seven lowest eigenvalues of ``K phi = lam M phi`` (shift-invert at the negative shift
    ``sigma``, default :func:`flexmor.linalg.eigen.default_shift`, so a singular ``K`` needs no
    special care) are compared with :func:`flexmor.linalg.eigen.rigid_body_threshold`. The count
    is remembered by the ``solver`` context (:meth:`flexmor.linalg.context.SolverContext.remember`)
    per stiffness and mass matrix. ``keep`` keeps the factorization of ``K - sigma M`` in the
    context for the method that follows at that shift (see :func:`flexmor.reduction.check_shift`).

    Returns
    -------
    int
        0 for a supported body, 1 to 6 for a free (or partly supported) one; a
        :class:`FlexmorWarning` says so.

    Raises
    ------
    ModelError
        More than six zero-energy modes (a mechanism).
    """
    from .linalg.eigen import is_rigid

    lam = stable_lowest_eigenvalues(model, as_solver(solver), sigma=sigma, keep=keep)
    n_zero = int(np.sum(is_rigid(lam, model.K, model.M)))
    if n_zero > MAX_RIGID_BODY_MODES:
        raise mechanism_error(model, n_zero)
    if n_zero:
        rigid_body_note(model, n_zero, stacklevel=2)
    return n_zero


def rigid_body_note(model, n_zero: int, *, stacklevel: int = 2) -> None:
    """The note ``rigid-body-modes`` (:func:`flexmor.errors.note`) of ``model`` with ``n_zero`` rigid-body modes."""
    note("rigid-body-modes", f"{model.source or model.name}: {n_zero} rigid-body modes (free body): the methods "
         "exclude them", stacklevel=stacklevel + 1)


def stable_lowest_eigenvalues(model, solver: SolverContext, k: int = MAX_RIGID_BODY_MODES + 1, *,
                              sigma: float | None = None, keep: bool = False) -> np.ndarray:
    """The ``k`` lowest eigenvalues of ``(K, M)`` (as :func:`check_rigid_body_modes` computes them); an
    :func:`unstable_error` for a stiffness with negative ones (a preload beyond buckling), which would
    otherwise count as rigid-body modes, or whose ``K - sigma M`` (``sigma < 0``) is not positive definite."""
    from .linalg.eigen import rigid_body_threshold

    try:
        lam = _lowest_eigenvalues(model, solver, k, sigma=sigma, keep=keep)
    except SolverError as exc:  # K - sigma M, sigma < 0, is positive definite for a stable body and mass
        raise unstable_error(model, None, exc) from None
    unstable = lam[lam < -rigid_body_threshold(model.K, model.M)]
    if unstable.size:
        raise unstable_error(model, unstable)
    return lam


def unstable_error(model, lam, failed=None) -> ModelError:
    """The error for a stiffness with negative eigenvalues ``lam`` (rad²/s², modes that grow instead of
    oscillating), or whose shifted matrix ``K - sigma M`` (``sigma < 0``) ``failed`` to factorize as positive
    definite (then eigenvalues below ``sigma``, or an indefinite mass). Under a preload (``model.preload``):
    the preload beyond the buckling load."""
    where = model.source or model.name
    what = (f"the preload ({', '.join(map(str, model.preload.get('specs', [])))}) exceeds the body's buckling load: "
            "K + K_G is indefinite; lower the preload below the buckling load" if model.preload is not None else
            "the stiffness matrix is indefinite (a damaged file, a negative material constant, or a geometric "
            "stiffness in K)")
    if lam is None:
        return ModelError(f"{where}: K - sigma M (sigma < 0) is not positive definite ({failed}): the body has modes "
                          f"with negative eigenvalues, unstable ones, or its mass matrix is indefinite; {what}",
                          params=("preload",) if model.preload is not None else ())
    return ModelError(f"{where}: {lam.size} mode(s) with a negative eigenvalue (the lowest {float(np.min(lam)):.4g} "
                      f"rad^2/s^2: unstable, not oscillating): {what}",
                      params=("preload",) if model.preload is not None else ())


#: Relative residual of the lowest eigenpairs that the checks compute (only their eigenvalues are kept): a
#: Rayleigh quotient is accurate to about its square relative to the gap, 1e-12, below the ~1e-11 at which
#: rounding leaves the eigenvalues of these solves (a residual of 1e-8 costs one to two more block solves).
LOWEST_TOL = 1e-6


def _lowest_eigenvalues(model, solver: SolverContext, k: int = MAX_RIGID_BODY_MODES + 1, *,
                        sigma: float | None = None, keep: bool = False) -> np.ndarray:
    """The ``k`` (at least seven) lowest eigenvalues of ``(K, M)``, remembered by ``solver`` per matrix pair."""
    from .linalg.eigen import eigenmodes

    k = min(max(int(k), MAX_RIGID_BODY_MODES + 1), model.n_dof)
    name = "lowest_eigenvalues" if k == min(MAX_RIGID_BODY_MODES + 1, model.n_dof) else f"lowest_eigenvalues:{k}"

    def compute():
        return eigenmodes(model.K, model.M, k, solver=solver, sigma=sigma, keep=keep, tol=LOWEST_TOL)[0]

    return solver.remember(name, (model.K, model.M), compute)


def first_elastic_hz(model, *, solver: SolverContext | None = None) -> float:
    """The full model's first elastic (non rigid-body) eigenfrequency in Hz; ``inf`` if none is
    among the seven lowest (a mechanism). Reuses the eigenvalues of :func:`check_rigid_body_modes`."""
    from .linalg.eigen import frequencies_hz, is_rigid

    lam = _lowest_eigenvalues(model, as_solver(solver))
    flex = lam[~is_rigid(lam, model.K, model.M)]
    return float(frequencies_hz(flex[:1])[0]) if flex.size else float("inf")


#: Elastic eigenfrequencies compared by :func:`coupling_frequencies`.
COUPLING_MODES = 6


def lowest_elastic_hz(model, n: int, *, solver: SolverContext | None = None) -> np.ndarray:
    """The ``n`` lowest elastic (non rigid-body) eigenfrequencies of ``model`` in Hz (fewer if the
    model has fewer DOF); one eigen solve of ``n + 6`` pairs, remembered by ``solver``."""
    from .linalg.eigen import frequencies_hz, is_rigid

    lam = _lowest_eigenvalues(model, as_solver(solver), int(n) + MAX_RIGID_BODY_MODES)
    return frequencies_hz(lam[~is_rigid(lam, model.K, model.M)][: int(n)])


def coupling_frequencies(uncoupled, coupled, couplings, *, n: int = COUPLING_MODES, coupled_hz=None,
                         solver: SolverContext | None = None) -> dict:
    """How couplings (RBE2/RBE3 interfaces) change a model: its lowest elastic eigenfrequencies before and after.

    An RBE2 makes the nodes of its set move as one rigid body: the coupled model is stiffer than
    the FE model as exported (its frequencies are higher; Rayleigh-Ritz: the coupled model is the
    FE model restricted to displacements that satisfy the constraints). That is right for the
    assembly the coupling stands for, but a reduced body judged against the coupled model is not
    judged against the FE model as exported; this record says by how much the two differ.

    Parameters
    ----------
    uncoupled, coupled : FEModel
        The model as read (node selections applied) and with ``couplings``.
    couplings : list of str
        The coupling SPECs (e.g. ``HOLE@rbe2``).
    n : int
        Elastic frequencies compared.
    coupled_hz : array_like, optional
        The coupled model's lowest elastic frequencies when already known (e.g. the resonances of
        the error grid's modal pre-pass); at least ``n`` of them, else they are computed.
    solver : SolverContext, optional

    Returns
    -------
    dict
        ``couplings``, ``uncoupled_hz``, ``coupled_hz`` (the ``n`` lowest elastic frequencies) and
        ``rel_change`` (coupled / uncoupled - 1, per mode).
    """
    solver = as_solver(solver)
    f0 = lowest_elastic_hz(uncoupled, n, solver=solver)
    f1 = (np.asarray(coupled_hz, float)[: int(n)] if coupled_hz is not None and np.size(coupled_hz) >= n
          else lowest_elastic_hz(coupled, n, solver=solver))
    k = min(f0.size, f1.size)
    return {"couplings": [str(c) for c in couplings], "uncoupled_hz": f0[:k].tolist(), "coupled_hz": f1[:k].tolist(),
            "rel_change": (f1[:k] / f0[:k] - 1.0).tolist()}


def signed_percent(x: float, digits: int) -> str:
    """``100 x`` with its sign and ``digits`` decimals; a change that rounds to zero is ``+0.0...``, not ``-0.0...``
    (a coupling that changes nothing moves the frequencies by round-off of either sign)."""
    return f"{round(100.0 * float(x), digits) + 0.0:+.{digits}f}"


def describe_couplings(couplings) -> str:
    """``RBE2 at HOLE, RBE3 at TIP`` for the coupling SPECs ``HOLE@rbe2``, ``TIP@rbe3`` (the SPECs as they
    are otherwise)."""
    parts = []
    for c in couplings:
        target, _, kind = str(c).partition("@")
        parts.append(f"{kind.upper()} at {target}" if kind else str(c))
    return ", ".join(parts)


#: Models up to this many DOF get their highest eigenfrequency from a dense solve (:func:`highest_hz`).
DENSE_HIGHEST = 200


def highest_hz(model, *, solver: SolverContext | None = None, maxiter: int = 400) -> float | None:
    """The model's highest eigenfrequency (Hz) of ``K phi = lam M phi``, to about 0.1 %.

    Lanczos for the largest eigenvalue (ARPACK, regular mode with one factorization of ``M``).
    ``inf`` for a mass matrix that is not positive definite (its pencil has infinite eigenvalues);
    None for a model held by rows over MPI ranks, or where the iteration does not converge in
    ``maxiter`` steps.
    """
    import scipy.sparse.linalg as sla

    from .linalg import factorize

    if is_partitioned(model.K) or is_partitioned(model.M):
        return None
    n = model.n_dof
    if n <= DENSE_HIGHEST:
        import scipy.linalg

        try:
            lam = float(scipy.linalg.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)[-1])
        except (np.linalg.LinAlgError, ValueError):  # M not positive definite
            return math.inf
        return math.sqrt(max(lam, 0.0)) / (2 * math.pi)
    try:
        F = factorize(model.M, solver=solver, symmetric=True, positive=True, check=False)
    except SolverError:
        return math.inf
    Minv = sla.LinearOperator((n, n), matvec=F.solve, dtype=float)
    v0 = np.random.default_rng(0).standard_normal(n)
    try:
        lam = sla.eigsh(model.K, k=1, M=model.M, Minv=Minv, which="LA", tol=1e-3, maxiter=maxiter, v0=v0,
                        return_eigenvectors=False)
    except sla.ArpackNoConvergence:
        return None
    except (sla.ArpackError, SolverError, ValueError):
        return math.inf
    return math.sqrt(max(float(lam[0]), 0.0)) / (2 * math.pi)


def looks_like_rad_per_s(band) -> bool:
    """Whether ``band`` (Hz) looks like 2π times a band of round numbers (``(62.83, 18850)`` for
    ``(10, 3000)``): both limits divided by 2π are numbers of at most two significant digits (to
    0.1 %), while the limits themselves are not."""

    def round_number(x: float) -> bool:
        digits = x / 10 ** (math.floor(math.log10(x)) - 1)  # two digits before the point: 10 <= digits < 100
        return abs(digits - round(digits)) <= 1e-3 * digits

    return all(round_number(f / (2 * math.pi)) for f in band) and not all(round_number(f) for f in band)


def check_band(model, band, *, name: str = "band", solver: SolverContext | None = None) -> list[str]:
    """Warn (:class:`FlexmorWarning` naming ``name``) about a band (Hz) that is likely not the one meant:
    one that looks given in rad/s (:func:`looks_like_rad_per_s`), one whose top lies above the model's
    highest eigenfrequency (:func:`highest_hz`; computed only when the top lies above ``max K_ii / M_ii``,
    a lower bound of the largest eigenvalue). Returns the warnings' texts."""
    fmin, fmax = band
    where = model.source or model.name
    texts = []
    if looks_like_rad_per_s(band):
        texts.append(f"{where}: {name} {fmin:g}:{fmax:g} Hz is 2 pi times {fmin / (2 * math.pi):.4g}:"
                     f"{fmax / (2 * math.pi):.4g}: was it given in rad/s? The band is in Hz")
    top = None
    if not (is_partitioned(model.K) or is_partitioned(model.M)):  # (held by rows over MPI ranks: not checked)
        dm, dk = model.M.diagonal(), model.K.diagonal()
        pos = dm > 0
        floor = math.sqrt(float(np.max(dk[pos] / dm[pos]))) / (2 * math.pi) if np.any(pos) else math.inf
        top = highest_hz(model, solver=solver) if fmax > floor else None
    if top is not None and fmax > top:
        texts.append(f"{where}: {name} reaches {fmax:g} Hz, above the model's highest eigenfrequency {top:.4g} Hz: "
                     "the mesh resolves no motion there (an FE model is accurate well below its highest mode); "
                     "was the band meant in other units?")
    for text in texts:
        warnings.warn(FlexmorWarning(text, params=(name,)), stacklevel=3)
    return texts
