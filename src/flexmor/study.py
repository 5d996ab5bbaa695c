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

import time
from os import PathLike

from .analysis.compare import ErrorMeasures, FullResponse, check_judgeable
from .checks import check_band
from .damping import describe_damping
from .display import Shown, band_text, names_text
from .errors import ModelError, OptionError, check_keywords_of
from .linalg.backends import is_iterative
from .linalg.context import SolverContext, as_solver, step
from .linalg.distributed import is_partitioned
from .model import FEModel
from .options import Band
from .ports import make_ports
from .prepare import prepare
from .reduction import BASIS_KEYWORDS
from .workflow import coupling_specs, record_setup, reduce_and_judge, with_method_band

__all__ = ["System"]

#: Keywords of :meth:`System.reduce_and_judge` that judge the body rather than build it.
_JUDGE_KEYWORDS = ("tol", "tol_measure", "mounted", "judge")

#: Keywords of every method's basis (:func:`flexmor.reduction.reduce`), kept in a study file's ``[reduce]``.
_BASIS_KEYWORDS = BASIS_KEYWORDS


def _plain(value):
    """A method option's value as a study file holds it: complex numbers (and lists with them) as the
    text the option reads (``0,1000j``)."""
    if isinstance(value, complex):
        return repr(value).strip("()")
    if isinstance(value, list | tuple) and any(isinstance(v, complex) for v in value):
        return ",".join(repr(v).strip("()") if isinstance(v, complex) else repr(v) for v in value)
    if isinstance(value, tuple):
        return list(value)
    return value

def _moving(model, ports, specs, tol, band, solver) -> list:
    """``[(MovingLoad, Compression)]`` of the moving load SPECs on ``model`` (:mod:`flexmor.moving`)."""
    from .moving import DEFAULT_TOL, compress, moving_path

    out = []
    for spec in specs:
        path = moving_path(model, spec)
        with step(solver.progress, f"moving load {spec}: {path.nodes.size} path nodes compressed"):
            comp = compress(model, path, Band.of(band), tol=DEFAULT_TOL if tol is None else tol,
                            outputs=None if ports is None else ports.C, solver=solver)
        out.append((path, comp))
    return out


class System(Shown):
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
    format, mesh, units, select, preload, material
        How the file becomes the model (:func:`flexmor.prepare.prepare`, the step ``flexmor reduce``
        takes with ``--format``, ``--mesh``, ``--units``, ``--select``, ``--preload`` and ``--material``):
        the file's format, a mesh file of its nodes and elements, the unit system of its numbers (the
        model is converted to SI), ``NAME=KIND:NUMBERS`` node selections, preload SPECs and the
        material ``(E, nu[, rho])`` of the preload's stresses.
    moving_loads : sequence of str
        Moving loads ``SET:DIR`` or ``SET:DIR@AXIS`` (:mod:`flexmor.moving`): a force moving over the node set's
        path. Its inputs, compressed to the directions whose singular values exceed ``moving_load_tol`` (default
        :data:`flexmor.moving.DEFAULT_TOL`), join the ports (``SET:DIR~1`` ...; the ports alone when no inputs are
        given); the bodies keep the path's reduced loads and are judged over its positions
        (:meth:`reduce_and_judge`, :meth:`crossing`).
    solver : SolverContext, optional
        Solver (backend, statistics) of every factorization; with the ``petsc`` backend under
        ``mpirun`` rank 0 reads and prepares the model.
    **grid
        Options of :class:`~flexmor.analysis.compare.FullResponse` (``n``, ``tol``, ``path``,
        ``cache`` ...); any other keyword is refused (:class:`~flexmor.errors.OptionError` naming
        it and the closest keyword: ``bnad=`` is not ``band=``). The full FRF is kept on disk for
        later studies of the same model, ports, damping and band: in ``$FLEXMOR_CACHE_DIR``, else
        ``$XDG_CACHE_HOME/flexmor``, else ``~/.cache/flexmor``, at most ``$FLEXMOR_CACHE_MAX_MB``
        megabytes (default 2000, the least recently used entries removed first); ``cache=False`` or
        ``FLEXMOR_CACHE_MAX_MB=0`` turns it off (:mod:`flexmor.analysis.cache`).

    A band given that looks given in rad/s, or whose top lies above the model's highest
    eigenfrequency, is warned about (:func:`flexmor.checks.check_band`). Method names resolve in any case and by
    their short names (:func:`flexmor.reduction.method_name`: ``"bt"`` is ``"sobt"``), with the
    study's band and interfaces.

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
    selections : list of str
        The ``select`` texts.
    preparation : dict
        The preparation options given (``format`` ... ``material``), as a study file records them.
    prepared_as : Prepared or None
        What the preparation made (:class:`flexmor.prepare.Prepared`: the model without its preload,
        the nodes ``nearest`` selections chose, the time); None for :meth:`prepared`.
    material : tuple or None
        The ``material`` given (also the material of :func:`flexmor.stress.body_stresses`).
    moving : list of (MovingLoad, Compression)
        The moving loads' paths and compressions (:mod:`flexmor.moving`).
    n_user_ports : (int, int)
        The inputs and outputs given (the ports before the moving loads' compressed ones).
    recipe : dict or None
        Of a system made by :meth:`from_study`: the study file's ``reduce`` section (``method``,
        ``order``, ``options`` ...) with its ``judge`` and ``output`` sections; None otherwise.
    """

    def __init__(self, model, *, inputs=(), outputs=(), interfaces=(), band=None, damping=None,
                 format: str | None = None, mesh=None, units=None, select=(), preload=(), material=None,
                 moving_loads=(), moving_load_tol: float | None = None, solver: SolverContext | None = None, **grid):
        check_keywords_of("System", grid, System.__init__, FullResponse.__init__)
        if not isinstance(model, str | PathLike | FEModel):
            raise ModelError(f"System needs an FE model or the path of its file, got {type(model).__name__}",
                             params=("model",))
        if isinstance(interfaces, (str, bytes)):
            raise OptionError(f"interfaces must be a list of SPECs, e.g. [{interfaces!r}], got the string "
                              f"{interfaces!r}", params=("interfaces",))
        interfaces = [str(s) for s in interfaces]
        couplings = coupling_specs(interfaces, [*inputs, *outputs])
        solver = as_solver(solver)
        done = prepare(model, format=format, mesh=mesh, units=units, select=select, preload=preload,
                       material=material, couplings=couplings, damping=damping, band=band, solver=solver,
                       progress=solver.progress)
        if isinstance(moving_loads, (str, bytes)):
            raise OptionError(f"moving_loads must be a list of SPECs, e.g. [{moving_loads!r}]",
                              params=("moving_loads",))
        moving_loads = [str(s) for s in moving_loads]
        if moving_loads and outputs and not inputs:
            raise OptionError("outputs need inputs: give inputs too, or the moving loads alone (their outputs are the "
                              "deflections under the load)", params=("outputs",))
        ports = make_ports(done.model, inputs, outputs) if inputs or not moving_loads else None
        moving = _moving(done.model, ports, moving_loads, moving_load_tol, band, solver)
        self._setup(done.model, ports, as_read=done.as_read, couplings=couplings, interfaces=interfaces, band=band,
                    solver=solver, grid=grid, selections=select, moving=moving)
        self.prepared_as, self.material = done, material
        self._given = {"model": model if isinstance(model, str | PathLike) else None, "inputs": list(inputs),
                       "outputs": list(outputs), "interfaces": interfaces, "band": band, "damping": damping,
                       "moving_loads": moving_loads, "moving_load_tol": moving_load_tol}
        self.recipe: dict | None = None
        self.preparation = {k: v for k, v in (("format", format), ("mesh", mesh), ("units", units),
                                              ("select", list(select)), ("preload", list(preload)),
                                              ("material", material)) if v not in (None, [])}

    @classmethod
    def prepared(cls, model, ports, *, as_read=None, couplings=(), interfaces=(), selections=(), band=None,
                 solver: SolverContext | None = None, **grid) -> System:
        """The study of a model already prepared: read, its node selections, ``couplings``
        (:func:`flexmor.workflow.prepare_model`) and damping applied, with its ``ports``.

        ``as_read`` is the model before its couplings (for the coupling frequencies of
        :meth:`reduce_and_judge`; None leaves them out), ``selections`` the ``NAME=...`` texts of
        :func:`flexmor.selection.with_selections` that made node sets of it (recorded on the bodies,
        like ``couplings`` and ``interfaces``); the rest as for :class:`System`.
        """
        system = cls.__new__(cls)
        system.prepared_as, system.material, system.preparation = None, None, {}
        system._given, system.recipe = {"model": None}, None
        system._setup(model, ports, as_read=as_read, couplings=[str(s) for s in couplings],
                      interfaces=[str(s) for s in interfaces], band=band, solver=solver, grid=grid,
                      selections=[str(s) for s in selections])
        return system

    def _setup(self, model, ports, *, as_read, couplings, interfaces, band, solver, grid, selections=(),
               moving=()) -> None:
        check_keywords_of("System", grid, System.__init__, FullResponse.__init__)
        from .moving import with_moving_loads

        self.moving = list(moving)
        self.n_user_ports = (0, 0) if ports is None else (ports.n_inputs, ports.n_outputs)
        if self.moving:
            ports = with_moving_loads(ports, *zip(*self.moving))
        self.model, self.ports, self.as_read = model, ports, as_read
        self._path_full: dict = {}
        self.couplings, self.interfaces, self.selections = list(couplings), list(interfaces), list(selections)
        self.band = Band.of(band)
        if band is not None:  # a band given (the default one is no user's mistake)
            check_band(model, self.band)
        self.solver = as_solver(solver)
        self._grid = grid
        self._full: FullResponse | None = None
        self._origin: dict | None = None

    def _shown(self) -> tuple[str, list]:
        rows = [("inputs", names_text(self.ports.input_names)), ("outputs", names_text(self.ports.output_names)),
                ("band", band_text(self.band)), ("damping", describe_damping(self.model.damping))]
        if self.interfaces:
            rows.append(("interfaces", names_text(self.interfaces)))
        for path, comp in self.moving:
            rows.append(("moving load", f"{path.name}: {path.nodes.size} nodes over {path.length:.4g} m, "
                                        f"{comp.k} compressed loads"))
        return f"{self.model.name!r}: {self.model.n_dof} DOF", rows

    @property
    def full(self) -> FullResponse:
        """The full FRF over the band (:class:`~flexmor.analysis.compare.FullResponse`), computed
        on first use."""
        if self._full is None:
            self._full = FullResponse(self.model, self.ports, self.band, solver=self.solver, **self._grid)
        return self._full

    def options(self, method: str, options: dict) -> dict:
        """The options ``method`` (any case, or a short name: :func:`flexmor.reduction.method_name`)
        gets: ``options``, plus the study's band (methods with a ``band`` option) and interfaces
        (methods with an ``interface`` option) where not given."""
        from .reduction import method_name, methods

        method = method_name(method)
        options = with_method_band(method, self.band, options)
        if self.interfaces and "interface" in methods()[method].options:
            options.setdefault("interface", list(self.interfaces))
        return options

    def reduce(self, method: str | None = None, order: int | None = None, **options):
        """Reduce the model with ``method`` (:func:`flexmor.reduction.reduce`) for the study's
        band, ports and interfaces (:meth:`options`). Without ``method``: the method, order and
        options of the study file the system was made from (:meth:`from_study`).

        Returns
        -------
        ReducedModel
            Recording the couplings, interfaces and selections it was reduced with.
        """
        from .reduction import method_name, reduce

        method, order, options = self._recipe(method, order, options)
        given = dict(options)
        method = method_name(method)
        options = self._moving_options(method, self.options(method, options))
        options.setdefault("solver", self.solver)
        body = reduce(self.model, method, order, self.ports, **options)
        self._record(body, method, order, given)
        return body

    def reduce_and_judge(self, method: str | None = None, order: int | None = None, *, judge: bool = True,
                         **options):
        """:func:`flexmor.workflow.reduce_and_judge` on this study: ``(body, record)``, the record
        of ``flexmor reduce --json``.

        The full FRF (:attr:`full`) is computed after the reduction on first use and reused;
        ``record["timings"]["full_frf"]`` is the time spent on it in this call. ``judge=False``
        reduces without the error evaluation (the record's measures are None). ``options`` are the
        method's and those of :func:`~flexmor.workflow.reduce_and_judge` (``tol``, ``tol_measure``,
        ``mounted``). Without ``method``: those of the study file (:meth:`from_study`).
        """
        method, order, options = self._recipe(method, order, options)
        given = {k: v for k, v in options.items() if k not in _JUDGE_KEYWORDS}
        options = self._moving_options(method, self.options(method, options))
        method_band = options.pop("band", None)  # the method's band (the study's unless given)
        iterative = judge and is_iterative(self.solver.backend)  # no full FRF: the band for the mounted check alone
        body, record = reduce_and_judge(self.model, method, order, self.ports, method_band=method_band,
                                        full=(lambda: self.full) if judge and not iterative else None,
                                        band=self.band if iterative else None, solver=self.solver,
                                        uncoupled=self.as_read if self.couplings else None,
                                        couplings=self.couplings, **options)
        self._record(body, method, order, given)
        if self.moving and judge:
            t0 = time.perf_counter()
            recs = self.judge_paths(body)
            body.errors["moving_loads"] = recs
            record["moving_loads"] = [{k: v for k, v in r.items() if k != "positions"} for r in recs]
            record["timings"]["moving_loads"] = time.perf_counter() - t0
        return body, record

    def _moving_options(self, method: str, options: dict) -> dict:
        """``options`` with residual vectors for a method whose basis ignores the inputs, when there are moving
        loads: it gets the static responses of their compressed loads (not one constraint mode per path node)."""
        from .reduction import methods

        if self.moving and not methods()[method].uses_inputs:
            options = {**options, "residual_vectors": True}
        return options

    def judge_paths(self, body) -> list[dict]:
        """``body``'s band error over the positions of each moving load (:func:`flexmor.moving.judge_paths`, at the
        study's outputs and under the load; the full model's path FRF computed once per path and kept)."""
        from .moving import judge_paths

        self.check(body)
        return judge_paths(self.model, body, self.band, fulls=self._path_full, solver=self.solver, **self._grid)

    def crossing(self, body, speed: float, *, force: float = 1.0, k: int = 0, **options) -> dict:
        """A force crossing the ``k``-th moving load's path at ``speed`` (m/s), body against full model, under the
        load and at the study's outputs (:func:`flexmor.moving.crossing`; ``dt``, ``steps``, ``scheme``, ``start``
        as there)."""
        from .moving import crossing

        self.check(body)
        options.setdefault("solver", self.solver)
        n_out = self.n_user_ports[1]
        if n_out:
            options.setdefault("outputs", self.ports.C[:n_out])
            options.setdefault("output_names", self.ports.output_names[:n_out])
        return crossing(self.model, body, self.moving[k][0], speed=speed, force=force, k=k, **options)

    def _recipe(self, method, order, options):
        """``(method, order, options)``: as given, or the study file's when no method is given."""
        if method is not None:
            return method, order, options
        if self.recipe is None:
            raise OptionError("reduce needs a method (only a system made from a study file has one of its own)",
                              params=("method",))
        basis_keys = {k: self.recipe[k] for k in _BASIS_KEYWORDS if k in self.recipe}
        return (self.recipe["method"], order or self.recipe.get("order"),
                {**basis_keys, **self.recipe.get("options", {}), **options})

    def _record(self, body, method, order, options) -> None:
        from .moving import path_record

        record_setup(body, couplings=self.couplings, interfaces=self.interfaces, selections=self.selections)
        if self.moving:
            body.info["moving_loads"] = [path_record(body, path, comp) for path, comp in self.moving]
        try:
            body.info["study"] = self.study(method, order, options)
        except OptionError:  # a model given read, or damping of no file form: no study to record
            body.info["study"] = None

    def study(self, method: str, order: int | None = None, options: dict | None = None, **extra) -> dict:
        """The study file's content (:mod:`flexmor.studyfile`) of reducing this system with ``method``,
        ``order`` and ``options``; ``extra`` adds sections (``judge``, ``output``) and keys of
        ``reduce``. Paths are as given (:meth:`save_study` writes them relative to the file).

        Raises
        ------
        OptionError
            For a system made from a model already read (no file to record), or damping given as an
            object other than Rayleigh damping.
        """
        from .damping import NoDamping, Rayleigh
        from .reduction import method_name
        from .studyfile import file_sha256, study_fingerprint

        given = self._given
        if given["model"] is None:
            raise OptionError("a study file records the model's file: make the System from its path", params=("model",))
        damping = given["damping"]
        if isinstance(damping, Rayleigh):
            damping = {"rayleigh": [damping.alpha, damping.beta]}
        elif isinstance(damping, NoDamping):
            damping = None
        elif damping is not None and not isinstance(damping, dict):
            raise OptionError(f"a study file records damping as {{'rayleigh': (alpha, beta)}}, {{'modal_damping': "
                              f"zeta}} or {{'band_rayleigh': zeta}}, not {type(damping).__name__}", params=("damping",))
        if given.get("study_model") is None:  # once per system: the checksums read the files, hash K and M
            model = {"file": str(given["model"]), "sha256": file_sha256(given["model"]), **self.preparation}
            if "mesh" in model:
                model["mesh"], model["mesh_sha256"] = str(model["mesh"]), file_sha256(model["mesh"])
            if "material" in model:
                model["material"] = [float(v) for v in model["material"]]
            if not is_partitioned(self.model.K):
                model["fingerprint"] = study_fingerprint(self.model)
            given["study_model"] = model
        model = {k: (dict(v) if isinstance(v, dict) else v) for k, v in given["study_model"].items()}
        band = None if given["band"] is None else [float(v) for v in Band.of(given["band"])]
        opts = {k: _plain(v) for k, v in (options or {}).items() if v is not None and k != "solver"}
        reduce = {"method": method_name(method), **({"order": int(order)} if order is not None else {}),
                  **{k: opts.pop(k) for k in _BASIS_KEYWORDS if k in opts},
                  **{k: v for k, v in extra.pop("reduce", {}).items() if v is not None}, "options": opts}
        ports = {k: list(given[k]) for k in ("inputs", "outputs", "interfaces", "moving_loads") if given.get(k)}
        if given.get("moving_loads") and given.get("moving_load_tol") is not None:
            ports["moving_load_tol"] = float(given["moving_load_tol"])
        return {k: v for k, v in {"band": band, "model": model, "ports": ports,
                                  "damping": {k: (list(v) if k == "rayleigh" else v) for k, v in damping.items()}
                                  if damping else None, "reduce": reduce, **extra}.items() if v}

    def save_study(self, path, method: str, order: int | None = None, options: dict | None = None, **extra) -> None:
        """Write the study file of :meth:`study` to ``path``, its paths relative to the file's folder."""
        from pathlib import Path

        from .studyfile import relative_to, write_study

        study = self.study(method, order, options, **extra)
        folder = Path(path).resolve().parent
        for section, key in (("model", "file"), ("model", "mesh"), ("output", "body")):
            if key in study.get(section, {}):
                study[section][key] = relative_to(study[section][key], folder)
        write_study(path, study)

    @classmethod
    def from_study(cls, path, *, solver: SolverContext | None = None, **grid) -> System:
        """The system of the study file ``path`` (:mod:`flexmor.studyfile`): its model prepared as the
        file says and checked against the study's fingerprint; :meth:`reduce` without a method then
        reduces with the study's method, order and options (:attr:`recipe`). ``grid`` adds to the
        file's judgement options (``n``, ``tol``, ``path``, ``cache``, ``progress``)."""
        from .studyfile import check_fingerprint, read_study

        study = read_study(path)
        model = dict(study["model"])
        keywords = {k: model[k] for k in ("format", "mesh", "units", "select", "preload") if k in model}
        if "material" in model:
            keywords["material"] = tuple(model["material"])
        ports = study.get("ports", {})
        damping = study.get("damping")
        if damping and "rayleigh" in damping:
            damping = {**damping, "rayleigh": tuple(damping["rayleigh"])}
        judge = study.get("judge", {})
        grid = {**{k: judge[j] for j, k in (("n_freq", "n"), ("grid_tol", "tol"), ("full_frf", "path"),
                                            ("cache", "cache")) if j in judge}, **grid}
        system = cls(model["file"], inputs=ports.get("inputs", ()), outputs=ports.get("outputs", ()),
                     interfaces=ports.get("interfaces", ()), moving_loads=ports.get("moving_loads", ()),
                     moving_load_tol=ports.get("moving_load_tol"), band=study.get("band"), damping=damping or None,
                     solver=solver, **keywords, **grid)
        if not is_partitioned(system.model.K):
            check_fingerprint(study, system.model, path)
        system.recipe = dict(study["reduce"], judge=judge, output=study.get("output", {}))
        return system

    def check(self, body) -> None:
        """Refuse ``body`` when it was not reduced from this model, with this damping and these
        ports (:func:`flexmor.analysis.compare.check_judgeable`: ModelError or PortError, with the reason)."""
        from .origin import fingerprint

        if self._origin is None:
            self._origin = self._full.origin if self._full is not None else fingerprint(self.model)
        check_judgeable(body, origin=self._origin, damping=self.model.damping,
                        inputs=self.ports.input_names, outputs=self.ports.output_names,
                        label=str(self.model.source or self.model.name))

    def judge(self, body) -> ErrorMeasures:
        """The error measures of ``body`` over the band (:meth:`FullResponse.evaluate`); a body of
        another model, damping or ports is refused with the reason (before the full FRF is computed)."""
        self.check(body)
        return self.full.evaluate(body)

    def frf(self, freqs):
        """The full model's FRF at ``freqs`` (Hz) between the ports: shape (n_freq, n_outputs, n_inputs)
        (:func:`flexmor.dynamics.frf.frf_full`)."""
        from .dynamics.frf import check_freqs, frf_full

        return frf_full(self.model, self.ports, check_freqs(freqs, "freqs"), solver=self.solver)

    def simulate(self, u, *, dt: float, t_end: float, **options):
        """The full model's time response at the outputs to the input signal ``u``
        (:func:`flexmor.dynamics.time.simulate`; ``scheme``, ``q0`` ... as there)."""
        from .dynamics.time import simulate

        check_keywords_of("System.simulate", options, simulate, drop=("dt", "t_end", "ports"))
        options.setdefault("solver", self.solver)
        return simulate(self.model, u, dt=dt, t_end=t_end, ports=self.ports, **options)

    def static(self, body, **options) -> dict | None:
        """``body``'s static error against the full model's static deflection under its inputs and the frame's
        six accelerations, supported as it is or (a free body) held clamped at its first interface
        (:func:`flexmor.analysis.mounted.static_record`; ``options`` as there: ``full``, ``mounted``,
        ``band_rms_error``)."""
        from .analysis.mounted import mounted_record, static_record

        check_keywords_of("System.static", options, static_record, drop=("ports",))
        self.check(body)
        options.setdefault("solver", self.solver)
        if "mounted" not in options:
            options["mounted"] = mounted_record(self.model, body, ports=self.ports, band=self.band,
                                                solver=options["solver"], full=options.get("full"))
        return static_record(self.model, body, ports=self.ports, **options)

    def mounted(self, body, **options) -> dict | None:
        """``body`` held in its joints against the full model held there
        (:func:`flexmor.analysis.mounted.mounted_record`; None for a body without interfaces)."""
        from .analysis.mounted import mounted_check, mounted_record

        check_keywords_of("System.mounted", options, mounted_record, mounted_check, drop=("ports", "band"))
        self.check(body)
        options.setdefault("solver", self.solver)
        return mounted_record(self.model, body, ports=self.ports, band=self.band, **options)
