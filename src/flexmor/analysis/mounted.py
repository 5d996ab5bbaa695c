"""The body in its joint: a reduced body clamped or pinned at its interfaces, against the full model.

What counts for a multibody user is the body *as mounted*. Held at an interface, the reduced
body must behave like the full FE model supported the same way. For each interface (the master
node of a coupling ``SET@rbe2``/``SET@rbe3``, or a Craig-Bampton ``interface`` node or set) and
each way of holding it (:data:`HELD`: ``clamped``, all six master DOFs; ``pinned``, the three
translations) :func:`mounted_check` compares

* the lowest ``modes`` elastic eigenfrequencies: the full model with the held equations removed
  (sparse shift-invert, :func:`flexmor.linalg.eigen.eigenmodes`) against the Ritz values of the
  reduced body under the same constraint (dense ``eigh``); matched by order, the relative errors
  ``f_red / f_full - 1`` are >= 0 up to round-off (Rayleigh-Ritz: the mounted reduced body is a
  Galerkin projection of the mounted full model);
* the static deflection of the clamped body under the frame's six accelerations (gravity in x, y and z
  and unit angular accelerations: the loads ``M R_a``, R the rigid motions,
  :func:`flexmor.rigid.rigid_motions`) and under each input of
  the body that does not act on the held equations: ``output_error = ||C (u_red - u)|| / ||C u||``
  at the body's outputs and ``field_error = max|u_red - u| / max|u|`` over the translations.

:func:`static_record` gives every body its static error: a supported body as it is, a free body held
clamped at its first interface.

**The mounted reduced body.** A free body in the floating frame of reference moves as its frame
(the rigid motions Φ, M-orthonormal) plus its elastic coordinates: ``u = Φ a + V q``. The MBS code
holds the interface by constraining that total motion, ``Φ_b a + V_b q = 0`` (``b`` the held
equations); the mounted coordinates are the null space ``Z`` of ``[Φ_b  V_b]`` (SVD), in which
``(Zᵀ Ka Z, Zᵀ Ma Z)`` with ``Ma = [[I, ΦᵀMV], [VᵀMΦ, Mr]]``, ``Ka = diag(0, Kr)`` is the mounted
body (``ΦᵀMV`` are the body's inertia invariants). A basis made mass-orthogonal to the rigid
modes (``rigid='exclude'``) could not be held by ``V_b q = 0`` alone: its fixed-interface modes
carry a rigid part that the frame takes. A supported model has no frame: ``V_b q = 0``.

The full-model side, one factorization per support case, is kept by :class:`FullMounted` and
reused for every body judged against the same model (``compare`` of several bodies pays once).

References
----------
Craig, R. R., Bampton, M. C. C. (1968). Coupling of substructures for dynamic analyses. AIAA
Journal 6(7), 1313-1319 (fixed-interface modes: the clamped body's modes).

Géradin, M., Rixen, D. J. (2015). Mechanical Vibrations: Theory and Application to Structural
Dynamics, 3rd ed., Wiley, ch. 4 (Rayleigh-Ritz bounds of constrained systems) and ch. 8.

Schwertassek, R., Wallrapp, O. (1999). Dynamik flexibler Mehrkörpersysteme. Vieweg, ch. 6
(reference frames and joints of elastic bodies).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..damping import ModalDamping
from ..errors import FlexmorError, ModelError, OptionError
from ..linalg import factorize
from ..linalg.amg import register_rows
from ..linalg.context import SolverContext, as_solver
from ..linalg.distributed import is_partitioned
from ..linalg.eigen import eigenmodes, frequencies_hz, rigid_body_threshold
from ..linalg.threads import sparse_dense
from ..model import direction_name
from ..rigid import ACCELERATIONS, register_near_null, rigid_body_modes, rigid_motions
from ..support import AS_SUPPORTED, HELD, Support, supports

__all__ = ["HELD", "ACCELERATIONS", "Support", "supports", "FullMounted", "MountedCase", "MountedCheck",
           "mounted_check", "mounted_note", "mounted_record", "static_record", "static_note", "NOTE_FACTOR",
           "NOTE_FLOOR", "NOTE_PARAMS"]

log = logging.getLogger(__name__)


#: A mounted error above ``max(NOTE_FACTOR * band_rms_error, NOTE_FLOOR)`` is worth a note.
NOTE_FACTOR = 10.0
NOTE_FLOOR = 1e-3
#: The parameters :func:`mounted_note` names, as bare words (see :func:`flexmor.errors.name_parameters`).
NOTE_PARAMS = ("inertia_loads", "residual_vectors")

#: Relative singular value (of the constraint rows) and eigenvalue (of the mounted mass) below which
#: a direction counts as absent.
RANK_TOL = 1e-10



@dataclass
class _FullCase:
    """A support case of the full model: free equations, rigid motions left, elastic eigenvalues,
    the factorization (None when rigid motion is left) and the static deflections by load name."""

    free: np.ndarray
    n_rigid_left: int
    lam: np.ndarray
    F: object = None
    static: dict = field(default_factory=dict)
    zeta: list | None = None


class FullMounted:
    """The full model held at its interfaces, each support case computed once and reused.

    Parameters
    ----------
    model : FEModel
        The (coupled) full model the bodies are judged against.
    modes : int
        Elastic eigenfrequencies per support case.
    solver : SolverContext, optional
        Solver of the factorizations and eigen solves.

    Attributes
    ----------
    n_factorizations : int
        Sparse factorizations spent so far (one per support case).
    """

    def __init__(self, model, *, modes: int = 6, fmax: float | None = None, solver: SolverContext | None = None):
        if int(modes) != modes or modes < 1:
            raise OptionError(f"modes must be a positive integer, got {modes!r}", params=("modes",))
        self.model, self.modes, self.solver = model, int(modes), as_solver(solver)
        self.fmax = None if fmax is None else float(fmax)
        self.phi = rigid_body_modes(model)
        register_near_null(self.solver, model)
        self.threshold = rigid_body_threshold(model.K, model.M)
        self._cases: dict = {}
        self.n_factorizations = 0

    def case(self, support: Support) -> _FullCase:
        """The support case: its free equations, elastic eigenvalues and (when the support leaves no
        rigid motion) the factorization of the held stiffness matrix."""
        key = (support.interface, support.held)
        if key in self._cases:
            return self._cases[key]
        m = self.model
        if support.held == AS_SUPPORTED:  # the model as it is: one factorization of K, no eigen solve
            c0 = self.solver.stats.count
            case = _FullCase(np.arange(m.n_dof), 0, np.zeros(0), factorize(m.K.tocsr(), solver=self.solver,
                                                                         positive=True))
            self.n_factorizations += self.solver.stats.count - c0
            self._cases[key] = case
            return case
        free = np.setdiff1d(np.arange(m.n_dof), np.asarray(support.eqs))
        register_rows(self.solver, m.n_dof, free)  # (the amg backend's near-null space: flexmor.linalg.amg)
        Kf = m.K[free][:, free].tocsr()
        Mf = m.M[free][:, free].tocsr()
        rank = 0
        if self.phi.shape[1]:
            s = np.linalg.svd(self.phi[list(support.eqs)], compute_uv=False)
            rank = int(np.sum(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
        left = self.phi.shape[1] - rank
        k = min(self.modes + left, free.size)
        c0 = self.solver.stats.count
        F = factorize(Kf, solver=self.solver, positive=True) if left == 0 else None
        while True:  # the held modes up to fmax (at least ``modes``): more until one lies above it
            if F is not None:
                lam, X = eigenmodes(Kf, Mf, k, sigma=0.0, factorization=F, solver=self.solver)
            else:
                lam, X = eigenmodes(Kf, Mf, k, solver=self.solver)
            elastic = lam >= self.threshold
            if (self.fmax is None or k >= free.size
                    or (elastic.any() and frequencies_hz(np.max(lam[elastic])) > self.fmax)):
                break
            k = min(2 * k, free.size)
        self.n_factorizations += self.solver.stats.count - c0
        order = np.argsort(lam)
        lam, X = lam[order], X[:, order]
        keep = np.flatnonzero(lam >= self.threshold)
        f_el = frequencies_hz(lam[keep])
        n = self.modes if self.fmax is None else max(self.modes, int(np.sum(f_el <= self.fmax)))
        keep = keep[:n]
        zeta = None
        if m.D is not None and not isinstance(m.damping, ModalDamping):  # x^T D x / (2 w x^T M x) of each mode
            Df = m.D[free][:, free]
            Xk = X[:, keep]
            w = np.sqrt(lam[keep])
            zeta = (np.einsum("ij,ij->j", Xk, Df @ Xk) / (2 * w * np.einsum("ij,ij->j", Xk, Mf @ Xk))).tolist()
        case = _FullCase(free, left, lam[keep], F, zeta=zeta)
        log.info("%s %s at %s: full model %s Hz", m.name, support.held, support.interface,
                 np.array2string(frequencies_hz(case.lam), precision=5))
        self._cases[key] = case
        return case

    def deflection(self, support: Support, name: str, load) -> np.ndarray:
        """Static deflection (all equations, zero at the held ones) under ``load`` (named ``name``)."""
        case = self.case(support)
        if case.F is None:
            raise ModelError(f"{support.held} at {support.interface} leaves {case.n_rigid_left} rigid motion(s): "
                             "no static deflection")
        if name not in case.static:
            u = np.zeros(self.model.n_dof)
            u[case.free] = case.F.solve(np.asarray(load, dtype=float)[case.free])
            case.static[name] = u
        return case.static[name]


def _mounted_body(model, body, eqs, phi):
    """``(X, T, Kt)``: the mounted reduced body's displacements ``u = X T y`` with ``Tᵀ Ma T = I`` and
    stiffness ``Kt`` (see the module docstring)."""
    V = np.asarray(body.V, dtype=float)
    r, k = V.shape[1], phi.shape[1]
    X = np.hstack([phi, V]) if k else V
    Ma = np.zeros((k + r, k + r))
    Ka = np.zeros_like(Ma)
    Ma[k:, k:], Ka[k:, k:] = body.M, body.K
    if k:
        Ma[:k, :k] = np.eye(k)
        Ma[:k, k:] = phi.T @ sparse_dense(model.M, V)
        Ma[k:, :k] = Ma[:k, k:].T
    # the columns scaled to unit mass first: the null space does not depend on the scale of the basis
    # vectors, the rank decision does (a residual flexibility vector of 1e-10 m/N next to a unit mode)
    d = 1.0 / np.sqrt(np.clip(np.diag(Ma), np.finfo(float).tiny, None))
    _, s, Wt = np.linalg.svd(X[list(eqs)] * d, full_matrices=True)
    rank = int(np.sum(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
    Z = d[:, None] * Wt[rank:].T
    Mz = Z.T @ Ma @ Z
    w, U = np.linalg.eigh(0.5 * (Mz + Mz.T))
    keep = w > RANK_TOL * w[-1] if w.size else np.zeros(0, bool)
    T = Z @ (U[:, keep] / np.sqrt(w[keep]))
    Kt = T.T @ Ka @ T
    return X, T, 0.5 * (Kt + Kt.T)


@dataclass
class MountedCase:
    """One interface held one way: full and reduced frequencies (Hz), their relative errors, and the
    static deflection errors (``static``: one dict per load with ``load``, ``output_error``,
    ``field_error``; empty for a support that leaves rigid motion)."""

    interface: str
    node: int | None
    held: str
    n_held: int
    frequencies_full_hz: list
    frequencies_reduced_hz: list
    rel_error: list
    static: list
    damping_full: list | None = None
    damping_reduced: list | None = None

    def max_frequency_error(self, fmax: float | None = None) -> float | None:
        """Largest |relative frequency error| (of the modes up to ``fmax`` Hz when given)."""
        e = [abs(x) for x, f in zip(self.rel_error, self.frequencies_full_hz)
             if x is not None and (fmax is None or f <= fmax)]
        return max(e) if e else None

    def max_static_error(self) -> float | None:
        """Largest static error (output or field) over the loads."""
        e = [v for s in self.static for v in (s["output_error"], s["field_error"]) if v is not None]
        return max(e) if e else None

    def to_dict(self, fmax: float | None = None) -> dict:
        """The JSON record; ``max_frequency_error`` of the modes up to ``fmax`` Hz."""
        return {"interface": self.interface, "node": self.node, "held": self.held, "n_held": self.n_held,
                "frequencies_full_hz": self.frequencies_full_hz, "frequencies_reduced_hz": self.frequencies_reduced_hz,
                "rel_error": self.rel_error, "max_frequency_error": self.max_frequency_error(fmax),
                "damping_full": self.damping_full, "damping_reduced": self.damping_reduced,
                "static": self.static, "max_static_error": self.max_static_error()}


@dataclass
class MountedCheck:
    """The body in its joints: one :class:`MountedCase` per interface and way of holding it; the
    frequency errors count for the modes in ``band_hz`` (all without a band)."""

    cases: list
    modes: int
    band_hz: tuple | None = None

    def to_dict(self) -> dict:
        """The JSON record: ``modes``, ``band_hz``, ``cases`` (:meth:`MountedCase.to_dict`), the largest
        ``max_frequency_error`` and ``max_static_error`` of the cases (None where there is none)."""
        fmax = None if self.band_hz is None else self.band_hz[1]
        cases = [c.to_dict(fmax) for c in self.cases]
        worst = {k: [c[k] for c in cases if c[k] is not None] for k in ("max_frequency_error", "max_static_error")}
        return {"modes": self.modes, "band_hz": None if self.band_hz is None else list(self.band_hz), "cases": cases,
                **{k: max(v) if v else None for k, v in worst.items()}}


def _static_cases(model, body, full, support, X, T, Kt, ports):
    """The static errors of the clamped ``support`` (or of the supported model as it is): the frame's six
    accelerations (:data:`ACCELERATIONS`), unit loads at the master of every other interface (one per master
    DOF, named ``INTERFACE:DIR``) and the body's inputs."""
    R = rigid_motions(model)
    loads = [(name, model.M @ R[:, i]) for i, name in enumerate(ACCELERATIONS) if np.any(R[:, i])]
    held = np.asarray(support.eqs, dtype=np.int64)
    for other in supports(model, body, held=("clamped",)):  # unit loads at every other interface's master
        if other.node is None or other.interface == support.interface:
            continue
        for eq in other.eqs:
            f = np.zeros(model.n_dof)
            f[eq] = 1.0
            loads.append((f"{other.interface}:{direction_name(model.dofs[eq, 1])}", f))
    if ports is not None:
        B = ports.B.toarray()
        for j, name in enumerate(ports.input_names):
            b = B[:, j].copy()
            b[held] = 0.0
            if np.linalg.norm(b) > 1e-12 * np.linalg.norm(B[:, j]):
                loads.append((f"input:{name}", B[:, j]))
    trans = np.flatnonzero(model.dofs[:, 1] <= 3) if model.dofs is not None else np.arange(model.n_dof)
    trans = trans if trans.size else np.arange(model.n_dof)
    C = None if ports is None or not ports.n_outputs else ports.C
    out = []
    for name, f in loads:
        u = full.deflection(support, name, f)
        y = np.linalg.solve(Kt, T.T @ (X.T @ f))
        ur = X @ (T @ y)
        du = ur - u
        umax = np.max(np.abs(u[trans]))
        rec = {"load": name, "field_error": float(np.max(np.abs(du[trans])) / umax) if umax > 0 else None,
               "output_error": None}
        if C is not None:
            cu = np.linalg.norm(C @ u)
            if cu > 1e-10 * umax * np.sqrt(C.multiply(C).sum()):
                rec["output_error"] = float(np.linalg.norm(C @ du) / cu)
        out.append(rec)
    return out


def mounted_check(model, body, *, ports=None, full: FullMounted | None = None, modes: int = 6,
                  interfaces=None, held=("clamped", "pinned"), band=None,
                  solver: SolverContext | None = None) -> MountedCheck:
    """The reduced ``body`` held at each of its interfaces, against the full ``model`` held the same way.

    Parameters
    ----------
    model : FEModel
        The model the body was projected from (the coupled one, e.g.
        :func:`flexmor.origin.reference_model`); its damping plays no part.
    body : ReducedModel
        With its basis ``V``.
    ports : Ports, optional
        The body's inputs and outputs on ``model`` (loads and output errors); default rebuilt from
        its port names, none when that fails.
    full : FullMounted, optional
        The full side, reused between bodies of one model; made here when not given.
    modes : int
        Elastic eigenfrequencies per case (when ``full`` is not given).
    interfaces : sequence of str, optional
        See :func:`supports`.
    held : sequence of str
        Ways of holding an interface (:data:`HELD`).
    band : (float, float), optional
        The band in Hz: :meth:`MountedCheck.max_frequency_error` counts the modes below its top.
    solver : SolverContext, optional

    Returns
    -------
    MountedCheck
        No cases for a body without interfaces (or a model whose rows are spread over MPI ranks).

    Raises
    ------
    ModelError
        A body without basis ``V``, or one whose basis does not fit the model.
    """
    cases_ = supports(model, body, interfaces=interfaces, held=held)
    band = None if band is None else (float(band[0]), float(band[1]))
    if is_partitioned(model.K):  # rows spread over MPI ranks: the held matrices need the whole model
        log.info("mounted check skipped: the model's rows are spread over MPI ranks")
        return MountedCheck([], modes if full is None else full.modes, band)
    full = FullMounted(model, modes=modes, fmax=None if band is None else band[1], solver=solver) if full is None \
        else full
    check = MountedCheck([], full.modes, band)
    if not cases_:
        return check
    if body.V is None or np.shape(body.V)[0] != model.n_dof:
        raise ModelError(f"the {body.method} body has no basis at the {model.n_dof} equations of {model.name}: "
                         "its mounted behaviour cannot be checked")
    if ports is None:
        from ..ports import body_ports

        try:
            ports = body_ports(model, body)
        except FlexmorError as exc:
            log.info("mounted check without the body's ports: %s", exc)
    for sup in cases_:
        fc = full.case(sup)
        X, T, Kt = _mounted_body(model, body, sup.eqs, full.phi)
        lam_all, Y = sla.eigh(Kt)
        el = np.flatnonzero(lam_all >= full.threshold)[:max(len(fc.lam), full.modes)]
        lam_r = lam_all[el]
        f_full = frequencies_hz(fc.lam).tolist()
        f_red = frequencies_hz(lam_r).tolist()
        zeta_r = None
        if body.D is not None:  # the MBS code damps the elastic coordinates q only: D_a = diag(0, Dr)
            k = X.shape[1] - np.shape(body.V)[1]
            Da = np.zeros((X.shape[1], X.shape[1]))
            Da[k:, k:] = body.D
            Yk = Y[:, el]
            zeta_r = (np.einsum("ij,ij->j", Yk, (T.T @ Da @ T) @ Yk) / (2 * np.sqrt(lam_r))).tolist()
        rel = [f_red[i] / f_full[i] - 1.0 if i < len(f_red) and f_full[i] > 0 else None
               for i in range(len(f_full))]
        static = _static_cases(model, body, full, sup, X, T, Kt, ports) if fc.F is not None else []
        check.cases.append(MountedCase(sup.interface, sup.node, sup.held, len(sup.eqs), f_full, f_red, rel, static,
                                       fc.zeta, zeta_r))
    return check


def mounted_note(check: MountedCheck | dict, band_rms_error: float | None, *, free: bool = True) -> str | None:
    """A one-line note when the mounted body is off by more than its band error suggests, else None.

    The threshold is ``max(NOTE_FACTOR * band_rms_error, NOTE_FLOOR)`` (``NOTE_FLOOR`` without a band
    error); frequencies count for the modes in the band. ``check`` may be the JSON record. Its advice is for a
    free body (``free``: the inertia loads add the accelerations of the body held at each coupling master) or a
    supported one (whose inertia loads hold no interface: the residual vectors add the masters' unit loads).
    """
    rec = check.to_dict() if isinstance(check, MountedCheck) else check
    limit = max(NOTE_FACTOR * (band_rms_error or 0.0), NOTE_FLOOR)
    fmax = (rec.get("band_hz") or [None, None])[1]
    worst = []
    for c in rec.get("cases", ()):
        fe = [(abs(e), f"mode {i + 1} ({f:.4g} Hz)") for i, (e, f) in
              enumerate(zip(c["rel_error"], c["frequencies_full_hz"])) if e is not None and (fmax is None or f <= fmax)]
        se = [(v, s["load"]) for s in c["static"] for v in (s["output_error"], s["field_error"]) if v is not None]
        for what, errs in (("frequency of", fe), ("static deflection under", se)):
            if errs:
                e, name = max(errs)
                if e > limit:
                    worst.append((e, f"{c['held']} at {c['interface']}: {what} {name} off by {100 * e:.3g} %"))
    if not worst:
        return None
    worst.sort(reverse=True)
    told = "" if band_rms_error is None else f" (its band RMS error is {100 * band_rms_error:.3g} %)"
    advice = ("raise the order (methods that use the inputs: keep inertia_loads auto or on, which adds the loads of "
              "the body held at each coupling master)" if free else
              "add residual_vectors (the static responses to the coupling masters' unit loads join the basis) or "
              "the interface's six directions as inputs: the frame's inertia loads of a supported body hold none of "
              "its interfaces")
    return f"mounted body: {'; '.join(w for _, w in worst[:3])}{told}: the basis misses the body as held in its " \
           f"joint; {advice}"


def mounted_record(model, body, *, band_rms_error: float | None = None, **options) -> dict | None:
    """The JSON record of :func:`mounted_check` (``options`` are its keywords) with ``note``
    (:func:`mounted_note`, None when the body is as good mounted as its band error says), or
    None for a body without interfaces."""
    check = mounted_check(model, body, **options)
    if not check.cases:
        return None
    rec = check.to_dict()
    rec["note"] = mounted_note(rec, band_rms_error, free=bool(rigid_body_modes(model).shape[1]))
    rec["damping_note"] = damping_note(model, body)
    return rec


def damping_note(model, body) -> str | None:
    """What the damping ratios of the held modes (``damping_full``, ``damping_reduced``) mean for ``model``'s
    damping, or None without damping."""
    if model.D is None and body.D is None:
        return None
    free = rigid_body_modes(model).shape[1] > 0
    text = ("damping ratios of the held modes: the body's from its damping of the elastic coordinates q (the MBS "
            "code's; the frame's motion undamped)" + (", so held modes that move the frame are damped less than "
                                                       "the body's own modes" if free else ""))
    if isinstance(model.damping, ModalDamping):
        return (text + f"; modal damping {model.damping.zeta:g} is the ratio of each mode of the model as given"
                + (" (free: its free-free modes)" if free else "") + ", the body has it exactly in its own modes; "
                "held, the modes are other combinations and their ratios those listed. The full model's held ratios "
                "are not given: its sparse damping matrix is the Rayleigh damping matched at the band's ends, lower "
                "in between (give --rayleigh for a like-for-like comparison)")
    return text + "; the full model's from its damping matrix D held the same way (x^T D x / 2 w)"


def static_record(model, body, *, ports=None, full: FullMounted | None = None, mounted: dict | None = None,
                  band_rms_error: float | None = None, solver: SolverContext | None = None) -> dict | None:
    """The body's static error: its static deflection against the full model's under each of its inputs,
    the frame's six accelerations (:data:`ACCELERATIONS`) and unit loads at its (other) interfaces' masters,
    for a supported model as it is, for a free body
    held clamped at its first interface (the ``mounted`` record's case; a free body without interfaces has
    no static deflection: None).

    An MBS model leans on the static response (gravity, slow loads, the frame's accelerations), which the band
    error hides at the band's low end: a body within 1e-6 over the band can sag 0.65 % wrong.

    Returns
    -------
    dict or None
        ``as`` (``supported`` or ``clamped at INTERFACE``), ``loads`` (``load``, ``output_error``,
        ``field_error`` of each; :func:`mounted_check`), ``static_error`` (the largest ``output_error`` of
        the inputs: each input's static response at the outputs), ``max_static_error`` (over every load and
        both errors) and ``note`` (:func:`static_note`). None for a free body without interfaces, a body
        without basis or a model whose rows are spread over MPI ranks.
    """
    if is_partitioned(model.K) or body.V is None or np.shape(body.V)[0] != model.n_dof:
        return None
    full = FullMounted(model, solver=solver) if full is None else full
    if full.phi.shape[1]:  # free: held clamped at its first interface, as the mounted check holds it
        case = next((c for c in (mounted or {}).get("cases", ()) if c["held"] == "clamped" and c["static"]), None)
        if case is None:
            return None
        held, loads = f"clamped at {case['interface']}", case["static"]
    else:
        if ports is None:
            from ..ports import body_ports

            try:
                ports = body_ports(model, body)
            except FlexmorError as exc:
                log.info("static check without the body's ports: %s", exc)
        V = np.asarray(body.V, dtype=float)
        sup = Support(AS_SUPPORTED, None, AS_SUPPORTED, ())
        held = AS_SUPPORTED
        loads = _static_cases(model, body, full, sup, V, np.eye(V.shape[1]), 0.5 * (body.K + body.K.T), ports)
    inputs = [x["output_error"] for x in loads if x["load"].startswith("input:") and x["output_error"] is not None]
    every = [v for x in loads for v in (x["output_error"], x["field_error"]) if v is not None]
    frame = [x["field_error"] for x in loads if x["load"] in ACCELERATIONS and x["field_error"] is not None]
    rec = {"as": held, "loads": loads, "static_error": max(inputs) if inputs else None,
           "max_static_error": max(every) if every else None,
           "frame_error": max(frame) if frame and held == AS_SUPPORTED else None}
    rec["note"] = static_note(rec, band_rms_error, inertia_loads=(body.info.get("inertia_loads"),
                                                                  body.info.get("n_inertia_loads")),
                              static_kept=(body.info.get("compressed") or {}).get("keep_static", True))
    return rec


def static_note(rec: dict, band_rms_error: float | None, *, inertia_loads: tuple = (None, None),
                static_kept: bool = True) -> str | None:
    """A one-line note when the body's static error at its inputs (``rec``: :func:`static_record`) exceeds
    ``NOTE_FLOOR`` (1e-3) or ``NOTE_FACTOR`` (10) times its band RMS error; else, for a supported body built
    without the frame's inertia loads (``inertia_loads``: the body's ``inertia_loads`` mode, None for a method
    whose basis ignores the inputs, and ``n_inertia_loads``, 0) or compressed without keeping the static responses
    (``static_kept`` False: krylov's ``compress='band'``), when its deflection under one of the frame's
    accelerations (``frame_error``) is off by more than ``NOTE_FLOOR``; else None."""
    e = rec.get("static_error")
    frame = rec.get("frame_error")
    if e is None and frame is None:
        return None
    limits = [NOTE_FLOOR] + ([NOTE_FACTOR * band_rms_error] if band_rms_error is not None else [])
    if e is None or e <= min(limits):
        mode, n = inertia_loads
        if frame is None or frame <= NOTE_FLOOR or (n != 0 and static_kept):
            return None
        how = ("its compression did not keep the static responses (--compress band): --compress auto keeps them, "
               if not static_kept else
               "it was built for its ports alone: --inertia-loads on adds the six to the inputs the basis is built "
               "for (they share the order), " if mode is not None else "its basis is not built for them: ")
        return (f"frame accelerations: the supported body deflects {100 * frame:.3g} % off the full model under "
                f"one of the frame's unit accelerations (gravity, its support's motion; see the static table); {how}"
                "--residual-vectors adds their static responses")
    told = "" if band_rms_error is None else f" (its band RMS error is {100 * band_rms_error:.3g} %)"
    return (f"static response: the body ({rec['as']}) is off by {100 * e:.3g} % at its outputs under its inputs"
            f"{told}: slow loads and the frame's accelerations load it wrongly; a method with the static response "
            "in its basis (krylov, whose first point is 0 Hz) or a higher order")
