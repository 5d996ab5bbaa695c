"""The reduced elastic body: :class:`ReducedModel`, what every method, reader and exporter shares.

``Mr qr'' + Dr qr' + Kr qr = Br u``, ``y = Cr qr`` with its basis ``V`` (``q ≈ V qr``), the
names of its ports, the node table of the full model and the fingerprint of that model
(:mod:`flexmor.origin`). :func:`flexmor.projection.project` makes it; ``io`` reads and writes it.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ._version import __version__
from .damping import Damping, NoDamping, damping_from_dict, describe_damping
from .display import Shown, band_text, names_text
from .errors import ModelError

__all__ = ["ReducedModel", "convergence_record"]


def convergence_record(body) -> dict:
    """``converged`` (None for a method that does not iterate) and ``convergence_note`` of ``body``.

    An iterative method (``irka``) records whether it converged in the body's ``info``; a body
    whose iteration stopped without converging carries the note that says so and what to change.
    """
    info = getattr(body, "info", None) or {}
    converged = info.get("converged")
    return {"converged": None if converged is None else bool(converged),
            "convergence_note": info.get("convergence_note")}


#: ``id(body) -> (K, M, eigenvalues)`` of :meth:`ReducedModel.eigenvalues`, dropped with the body
_EIGENVALUES: dict = {}


@dataclass(repr=False)
class ReducedModel(Shown):
    """A reduced elastic body ``Mr qr'' + Dr qr' + Kr qr = Br u``, ``y = Cr qr``.

    Attributes
    ----------
    M, K : ndarray, shape (r, r)
        Reduced mass and stiffness (symmetric).
    D : ndarray, shape (r, r) or None
        Reduced damping.
    B : ndarray, shape (r, m)
    C : ndarray, shape (p, r)
    V : ndarray, shape (n_dof, r) or None
        The basis (mode shapes at the equations ``dofs``), for expansion and export.
    method, info
        Method name and its parameters / diagnostics.
    input_names, output_names : list of str
        Port SPECs (or names) of the inputs and outputs.
    node_ids, xyz, dofs
        Node table and equation map of the full model.
    triangles : ndarray of int, shape (n_tri, 3), or None
        Outer surface of the full model's mesh as triangles over node ids
        (:func:`flexmor.mesh.outer_surface`), for drawing the body (Exudyn's ``trigList``); None
        where the model has no elements.
    model_name : str
        Name of the full model; ``errors`` holds error measures once evaluated.
    damping : Damping
        The damping of the full model it was projected from (``D`` is its projection).
    origin : dict
        Fingerprint of the full model (:func:`flexmor.origin.fingerprint`); empty for bodies
        written before fingerprints existed.
    selections : list of str
        Node selections (:mod:`flexmor.selection`) made on the model as read before reducing;
        applied again with the couplings wherever the body meets that model
        (:func:`flexmor.origin.applied_to`).
    couplings : list of str
        RBE2/RBE3 couplings (:mod:`flexmor.couplings`, e.g. ``TIP@rbe2``) applied to the model
        (after the selections) before reducing; empty for a body reduced on the model as read.
    order_note : str or None
        Why the order differs from the one asked for (e.g. a Craig-Bampton basis bounded by the
        interior DOFs, Hankel singular values at round-off); None when it does not.
    units : str or None
        The unit system of the file its model was read from (:data:`flexmor.units.SYSTEMS`; the
        body itself is in SI, its model converted on reading), None when the file's system was
        not named (numbers as given).
    stress_nodes : ndarray of int, shape (k,), or None
        The nodes of the stress modes (:func:`flexmor.stress.body_stresses`).
    stress_modes : ndarray, shape (r, k, 6), or None
        The nodal stress (xx yy zz xy yz zx) of each basis vector at ``stress_nodes``: the
        stress for reduced coordinates ``qr`` is ``sum_j qr_j stress_modes[j]``.
    """

    M: np.ndarray
    K: np.ndarray
    D: np.ndarray | None
    B: np.ndarray
    C: np.ndarray
    V: np.ndarray | None = None
    method: str = ""
    info: dict = field(default_factory=dict)
    input_names: list = field(default_factory=list)
    output_names: list = field(default_factory=list)
    node_ids: np.ndarray | None = None
    xyz: np.ndarray | None = None
    dofs: np.ndarray | None = None
    triangles: np.ndarray | None = None
    model_name: str = ""
    damping: Damping = field(default_factory=NoDamping)
    errors: dict = field(default_factory=dict)
    version: str = __version__
    origin: dict = field(default_factory=dict)
    selections: list = field(default_factory=list)
    couplings: list = field(default_factory=list)
    order_note: str | None = None
    units: str | None = None
    stress_nodes: np.ndarray | None = None
    stress_modes: np.ndarray | None = None

    def __post_init__(self):
        if not isinstance(self.damping, Damping):  # the stored form, e.g. {"type": "rayleigh", ...}
            self.damping = damping_from_dict(self.damping)

    @property
    def order(self) -> int:
        """Reduced dimension r."""
        return int(self.M.shape[0])

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues ``omega^2`` of ``(Kr, Mr)``, ascending (solved once while ``K`` and ``M`` are the same
        arrays)."""
        hit = _EIGENVALUES.get(id(self))
        if hit is not None and hit[0] is self.K and hit[1] is self.M:
            return hit[2].copy()
        try:
            lam = sla.eigh(self.K, self.M, eigvals_only=True)
        except np.linalg.LinAlgError:
            raise ModelError("the reduced mass matrix is not positive definite") from None
        if hit is None:
            weakref.finalize(self, _EIGENVALUES.pop, id(self), None)
        _EIGENVALUES[id(self)] = (self.K, self.M, lam)
        return lam.copy()

    def summary(self) -> dict:
        """What the body is, as a plain dict (used by ``flexmor info BODY.h5``).

        Keys: ``method``, ``order``, ``order_requested``, ``order_note``, ``converged`` and
        ``convergence_note`` (:func:`convergence_record`), ``inputs``,
        ``outputs``, ``couplings``, ``masters`` (each coupling's master node: ``name``, ``id``,
        ``kind``, ``xyz``, ``n_slaves``), ``options`` (the method options recorded), ``frequencies_hz``,
        ``damping`` (stored form), ``errors`` (the stored measures, without the curves),
        ``model`` (the fingerprint of the full model it came from, empty for older bodies),
        ``units`` (the unit system of its model's file, None: as given), ``version`` (of the
        flexmor that wrote it).
        """
        try:
            freqs = self.frequencies_hz().tolist()
        except ModelError:
            freqs = None
        return {"method": self.method, "order": self.order, "order_requested": self.info.get("order_requested"),
                "order_note": self.order_note, **convergence_record(self), "inputs": list(self.input_names),
                "outputs": list(self.output_names), "couplings": list(self.couplings),
                "masters": list(self.info.get("masters", [])),
                "options": dict(self.info.get("options", {})), "frequencies_hz": freqs,
                "damping": self.damping.to_dict(), "model_name": self.model_name,
                "errors": {k: v for k, v in self.errors.items() if k not in ("freqs_hz", "rel_error")},
                "model": dict(self.origin), "units": self.units, "version": self.version}

    def _shown(self) -> tuple[str, list]:
        rows = [("inputs", names_text(self.input_names)), ("outputs", names_text(self.output_names)),
                ("damping", describe_damping(self.damping))]
        try:
            f = self.frequencies_hz()
            rows.append(("frequencies [Hz]", " ".join(f"{x:.4g}" for x in f[:6]) + (" ..." if f.size > 6 else "")))
        except ModelError:
            pass
        if self.errors.get("band_error") is not None:
            rows.append(("band_error", f"{self.errors['band_error']:.3g} over {band_text(self.errors.get('band_hz'))}"))
        conv = convergence_record(self)
        if conv["converged"] is False:
            rows.append(("converged", "no"))
        if self.order_note:
            rows.append(("order note", self.order_note))
        made = f" of {self.model_name!r}" if self.model_name else ""
        return f"{self.method or 'body'}{made}: order {self.order}", rows

    def frequencies_hz(self) -> np.ndarray:
        """Undamped eigenfrequencies in Hz (round-off negatives reported as 0)."""
        lam = self.eigenvalues()
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)

    # The methods below hand the body to the module that owns each concern (imported when called:
    # those modules sit above this one).

    def frf(self, freqs_hz) -> np.ndarray:
        """Frequency response ``H(f) = Cr (Kr - w² Mr + i w Dr)⁻¹ Br`` (:func:`flexmor.dynamics.frf.frf_reduced`).

        Parameters
        ----------
        freqs_hz : array_like
            Frequencies in Hz.

        Returns
        -------
        ndarray, complex, shape (n_freq, n_outputs, n_inputs)
            Outputs ``output_names`` over inputs ``input_names``.
        """
        from .dynamics.frf import frf_reduced

        return frf_reduced(self, freqs_hz, name="freqs_hz")

    def simulate(self, u, *, dt: float, t_end: float, scheme: str = "newmark", rho_inf: float = 0.9, q0=None,
                 v0=None, progress=None):
        """Time response to the input signal ``u`` (:func:`flexmor.dynamics.time.simulate`).

        Parameters
        ----------
        u : callable or array_like
            ``u(t)`` on the array of times, or samples on them; shape ``(n_t,)`` (each input in
            turn) or ``(n_t, n_inputs)`` (all at once), e.g. :func:`flexmor.dynamics.time.step`.
        dt, t_end : float
            Step and end time (s).
        scheme : {'newmark', 'generalized-alpha'}
        rho_inf : float
            Spectral radius at infinity of ``generalized-alpha``.
        q0, v0 : array_like, optional
            Initial reduced displacement and velocity, shape (r,) or (r, n_cases).
        progress : callable, optional
            ``progress(iterable, total)`` wrapper of the step loop.

        Returns
        -------
        flexmor.dynamics.time.TimeResponse
            Outputs ``y = Cr qr`` (and their velocities and accelerations) over time.
        """
        from .dynamics.time import simulate

        return simulate(self, u, dt=dt, t_end=t_end, scheme=scheme, rho_inf=rho_inf, q0=q0, v0=v0, progress=progress)

    def expand(self, model, *, elastic: bool = False, remove_rigid: bool = False) -> ReducedModel:
        """The body at every equation of ``model`` as read (:func:`flexmor.expansion.expand_body`).

        The basis ``V`` is expanded through the body's couplings to their slave nodes, and the
        node table and equation map become the model's, so that ``V @ qr`` is a displacement
        field of ``model``. :func:`flexmor.expansion.expand_body` also gives the coupling masters.

        Parameters
        ----------
        model : FEModel
            The FE model the body was reduced from, as read (its couplings not applied).
        elastic : bool
            Take the body a floating frame needs (a basis without rigid-body motion; refused for a
            body holding rigid motion unless ``remove_rigid``), as the exporters do.
        remove_rigid : bool
            With ``elastic``, allow rigid-body motion to be removed from the basis (another body).

        Returns
        -------
        ReducedModel

        Raises
        ------
        ModelError
            No basis, a model of another size or fingerprint, the coupled model instead of the
            model as read.
        """
        from .expansion import expand_body, expanded_reduced

        return expanded_reduced(expand_body(model, self, elastic=elastic, remove_rigid=remove_rigid))

    def state_space(self):
        """First-order form ``x' = A x + B u``, ``y = C x`` with ``x = [qr; qr']``
        (:func:`flexmor.io.statespace.state_space`), its signals labelled with the port names."""
        from .io.statespace import state_space

        return state_space(self)

    def to_control(self):
        """``control.StateSpace`` (python-control) of the body, inputs and outputs labelled with
        ``input_names`` and ``output_names`` (:meth:`flexmor.io.statespace.StateSpace.to_control`)."""
        return self.state_space().to_control()

    def to_scipy(self):
        """``scipy.signal.StateSpace`` of the body, with the attributes ``input_names`` and
        ``output_names`` (:meth:`flexmor.io.statespace.StateSpace.to_scipy`)."""
        return self.state_space().to_scipy()
