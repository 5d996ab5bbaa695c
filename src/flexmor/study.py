"""A study: one full model with its ports, band and damping, its reduced bodies reduced and judged against it.

::

    import flexmor

    beam = flexmor.System("beam.sti", inputs=["TIP:y"], band=(10, 3000),
                          damping=flexmor.damping.Rayleigh(0.0, 1e-6))
    body = beam.reduce("krylov", 8)        # built for the band of the study
    err = beam.judge(body)                 # ErrorMeasures; a body of another model is refused
    err.band_error, err.max_rel_error_hz

The steps are those of :mod:`flexmor.workflow` (and of ``flexmor reduce``): couplings of the
interfaces (:func:`~flexmor.workflow.coupling_specs`, :func:`~flexmor.workflow.prepare_model`),
damping (:func:`~flexmor.workflow.damping_of`), ports (:func:`~flexmor.ports.make_ports`),
:func:`flexmor.reduction.reduce` and :class:`~flexmor.analysis.compare.FullResponse`.
"""

from __future__ import annotations

from os import PathLike

from .analysis.compare import ErrorMeasures, FullResponse, check_judgeable
from .damping import Damping
from .linalg.context import SolverContext, as_solver
from .options import Band
from .ports import make_ports
from .workflow import coupling_specs, damping_of, prepare_model, record_setup, reduce_and_judge, with_method_band

__all__ = ["System"]


class System:
    """A full model with its inputs, outputs, interfaces, band and damping, given once.

    Parameters
    ----------
    model : FEModel or path-like
        The full model, or a file :func:`flexmor.io.read` reads.
    inputs, outputs : sequence of str
        Port SPECs (``NODE:DIR``, ``SET:DIR``, ``SET@rbe2:DIR`` ...; :func:`flexmor.ports.make_ports`).
        Without outputs they equal the inputs.
    interfaces : sequence of str
        Interface SPECs: ``SET@rbe2`` / ``SET@rbe3`` couple the set to a master node
        (:func:`flexmor.couplings.couple`); every interface is passed to the methods that take an
        ``interface`` option (craig-bampton, guyan ...) unless :meth:`reduce` is given one.
    band : (float, float) or str, optional
        Band in Hz (``FMIN:FMAX`` text too) of the judgement and of the methods that take a band;
        default :data:`flexmor.options.DEFAULT_BAND`.
    damping : Damping or dict, optional
        A :class:`flexmor.damping.Damping` (e.g. ``Rayleigh(0.0, 1e-6)``), or the keywords of
        :func:`flexmor.workflow.damping_of` (``{"modal_damping": 0.02}``, matched over ``band``).
        Default: the model's own damping (none for most files).
    solver : SolverContext, optional
        Solver (backend, statistics) of every factorization.
    **grid
        Options of :class:`~flexmor.analysis.compare.FullResponse` (``n``, ``tol``, ``path``,
        ``cache`` ...).

    Attributes
    ----------
    model : FEModel
        The model judged against: couplings applied, with the damping.
    as_read : FEModel
        The model before its couplings.
    ports : Ports
    band : Band
    couplings : list of str
        The coupling SPECs applied (:func:`flexmor.workflow.coupling_specs`).
    interfaces : list of str
    """

    def __init__(self, model, *, inputs=(), outputs=(), interfaces=(), band=None, damping=None,
                 solver: SolverContext | None = None, **grid):
        if isinstance(model, (str, PathLike)):
            from .io import read

            model = read(model)
        self.as_read = model
        self.interfaces = [str(s) for s in interfaces]
        self.band = Band.of(band)
        self.couplings = coupling_specs(self.interfaces, [*inputs, *outputs])
        model = prepare_model(model, self.couplings)
        if damping is not None:
            damping = damping if isinstance(damping, Damping) else damping_of(**{"band": self.band, **damping})
            model = model.with_damping(damping)
        self.model = model
        self.ports = make_ports(model, inputs, outputs)
        self.solver = as_solver(solver)
        self._grid = grid
        self._full: FullResponse | None = None

    def __repr__(self) -> str:
        return (f"System({self.model.name!r}, {self.model.n_dof} DOF, inputs={self.ports.input_names}, "
                f"outputs={self.ports.output_names}, band={self.band[0]:g}:{self.band[1]:g} Hz)")

    @property
    def full(self) -> FullResponse:
        """The full FRF over the band (:class:`~flexmor.analysis.compare.FullResponse`), computed
        on first use."""
        if self._full is None:
            self._full = FullResponse(self.model, self.ports, self.band, solver=self.solver, **self._grid)
        return self._full

    def options(self, method: str, options: dict) -> dict:
        """The options ``method`` gets: ``options``, plus the study's band (methods with a ``band``
        option) and interfaces (methods with an ``interface`` option) where not given."""
        from .reduction import methods

        options = with_method_band(method, self.band, options)
        registry = methods()
        if self.interfaces and method in registry and "interface" in registry[method].options:
            options.setdefault("interface", list(self.interfaces))
        return options

    def reduce(self, method: str, order: int | None = None, **options):
        """Reduce the model with ``method`` (:func:`flexmor.reduction.reduce`) for the study's
        band, ports and interfaces (:meth:`options`).

        Returns
        -------
        ReducedModel
            Recording the couplings and interfaces it was reduced with.
        """
        from .reduction import reduce

        options = self.options(method, options)
        options.setdefault("solver", self.solver)
        body = reduce(self.model, method, order, self.ports, **options)
        record_setup(body, couplings=self.couplings, interfaces=self.interfaces)
        return body

    def reduce_and_judge(self, method: str, order: int | None = None, **options):
        """:func:`flexmor.workflow.reduce_and_judge` on this study (its full FRF reused):
        ``(body, record)``, the record of ``flexmor reduce --json``."""
        options = self.options(method, options)
        body, record = reduce_and_judge(self.model, method, order, self.ports, full=self.full, solver=self.solver,
                                        uncoupled=self.as_read if self.couplings else None,
                                        couplings=self.couplings, **options)
        record_setup(body, couplings=self.couplings, interfaces=self.interfaces)
        return body, record

    def check(self, body) -> None:
        """Refuse ``body`` when it was not reduced from this model, with this damping and these
        ports (:func:`flexmor.analysis.compare.check_judgeable`: ModelError or PortError, with the reason)."""
        from .origin import fingerprint

        check_judgeable(body, origin=fingerprint(self.model), damping=self.model.damping,
                   inputs=self.ports.input_names, outputs=self.ports.output_names,
                   label=str(self.model.source or self.model.name))

    def judge(self, body) -> ErrorMeasures:
        """The error measures of ``body`` over the band (:meth:`FullResponse.evaluate`); a body of
        another model, damping or ports is refused with the reason."""
        self.check(body)
        return self.full.evaluate(body)

    def frf(self, freqs):
        """The full model's FRF at ``freqs`` (Hz) between the ports: shape (n_freq, n_outputs, n_inputs)
        (:func:`flexmor.dynamics.frf.frf_full`)."""
        import numpy as np

        from .dynamics.frf import frf_full

        return frf_full(self.model, self.ports, np.atleast_1d(np.asarray(freqs, float)), solver=self.solver)

    def simulate(self, u, *, dt: float, t_end: float, **options):
        """The full model's time response at the outputs to the input signal ``u``
        (:func:`flexmor.dynamics.time.simulate`; ``scheme``, ``q0`` ... as there)."""
        from .dynamics.time import simulate

        options.setdefault("solver", self.solver)
        return simulate(self.model, u, dt=dt, t_end=t_end, ports=self.ports, **options)

    def mounted(self, body, **options) -> dict | None:
        """``body`` held in its joints against the full model held there
        (:func:`flexmor.analysis.mounted.mounted_record`; None for a body without interfaces)."""
        from .analysis.mounted import mounted_record

        self.check(body)
        options.setdefault("solver", self.solver)
        return mounted_record(self.model, body, ports=self.ports, band=self.band, **options)
