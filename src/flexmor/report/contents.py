"""The contents of a report judging reduced bodies against their full model.

:func:`build_report` computes everything (full FRF once, errors, H2 norms where they exist,
eigenfrequencies and MAC, the bodies held in their joints, time responses, the 3D scene) into a
:class:`Report`, one private function per section; :mod:`flexmor.report.html` turns it into one
HTML page.

Sections: summary table (method, order, ``band_error``, ``max_rel_error``, ``h2_error``,
``time_mean_error``, ``time_max_error``, seconds), the body with its ports and interface
nodes, ``|H|`` of full and reduced bodies per input/output pair, ``rel_error(f)`` of all bodies
on one log-log plot, singular values where the method reports them, the eigenfrequency/MAC
table with MAC matrices, and the time responses with their errors.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..analysis.compare import JUDGED_ELASTIC, JUDGED_RIGID
from ..checks import describe_couplings
from ..errors import FlexmorError, OptionError, check_choice
from ..linalg.context import SolverContext, as_solver
from ..linalg.distributed import is_partitioned
from . import plots
from .view3d import interface_nodes, port_nodes

__all__ = ["SIGNALS", "SINGULAR_VALUE_KEYS", "Report", "build_report"]


log = logging.getLogger(__name__)

#: Built-in input signals of the time-domain comparison.
SIGNALS = ("step", "impulse", "sweep")
#: ``info`` fields of a reduced body that hold singular values (first one found is plotted).
SINGULAR_VALUE_KEYS = ("hankel_sv", "hankel_singular_values", "hsv", "pod_sv", "singular_values",
                       "pod_singular_values")
@dataclass
class Report:
    """Everything a report shows; ``rows`` are JSON-ready (one per reduced body)."""

    title: str
    model: dict
    band: tuple
    rows: list
    figures: dict = field(default_factory=dict)
    modal: dict = field(default_factory=dict)
    time: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    scene: dict = field(default_factory=dict)
    #: What the bodies are judged against: ``full model`` or ``full model with RBE2 at HOLE``.
    reference: str = "full model"
    #: The coupling record (:func:`flexmor.checks.coupling_frequencies`) of a coupled model, else empty.
    coupling: dict = field(default_factory=dict)
    #: What the plots draw: ``frf_references`` (name -> full FRF on ``freqs_hz``), ``time_references``
    #: (name -> displacement), ``reference_of`` / ``time_reference_of`` (body label -> name) and
    #: ``time_error`` (label -> the error curve, whose peak is the row's ``time_max_error``).
    plot_data: dict = field(default_factory=dict)
    #: Bodies reduced over a speed range (:mod:`flexmor.spin`): ``spec``, ``speeds`` and the Campbell records
    #: of the full model (``full``) and of each such body (``bodies``, by label); empty without one.
    campbell: dict = field(default_factory=dict)
    #: Bodies reduced with moving loads (:mod:`flexmor.moving`): ``paths`` (label -> the records of
    #: :func:`~flexmor.moving.judge_path`, positions included) and ``crossings`` (label -> the crossings of
    #: :func:`~flexmor.moving.crossing`); empty without one.
    moving: dict = field(default_factory=dict)


def _numbers_units(model) -> str | None:
    """The system of the model's numbers: SI when its file's system was named (converted on reading), None
    when they are as given."""
    return None if model.units is None else "SI"


def _signal(name, dt: float, t_end: float, band):
    from ..dynamics import time as tm

    if callable(name):
        return name, getattr(name, "__name__", "custom")
    check_choice("signal", name, list(SIGNALS))
    if name == "step":
        return tm.step(), "unit step on each input in turn"
    if name == "impulse":
        w = max(4 * dt, 1.0 / band[1])
        return tm.impulse(w), f"unit impulse (half-sine, {w:.3g} s) on each input in turn"
    return tm.sine_sweep(band[0], band[1], t_end), f"linear sine sweep {band[0]:g}-{band[1]:g} Hz over {t_end:.3g} s"


def build_report(model, ports, bodies, *, band, labels=None, seconds=None, full=None, signal="step",
                 dt: float | None = None, t_end: float | None = None, max_steps: int = 5000,
                 scheme: str = "newmark", rho_inf: float = 0.9, n_modes: int = 12, h2_max_dof: int = 1000,
                 solver: SolverContext | None = None, progress=None, time_progress=None,
                 title: str | None = None, view3d: bool = True, mounted: bool = True,
                 coupling: dict | None = None) -> Report:
    """Compute the contents of a report on the reduced ``bodies`` of ``model``.

    Parameters
    ----------
    model : FEModel
        The full model (with the damping the bodies were judged with).
    ports : Ports
        Inputs and outputs shared by all bodies.
    bodies : list of ReducedModel
    band : (float, float)
        Frequency band in Hz.
    labels : list of str, optional
        Names of the bodies (default ``method r=order``).
    seconds : list of float, optional
        Reduction wall time of each body (else ``info['seconds']`` when present).
    full : FullResponse, optional
        The full FRF on the band, reused when given.
    signal : {'step', 'impulse', 'sweep'} or callable
        Input of the time-domain comparison (see :mod:`flexmor.dynamics.time`).
    dt, t_end : float, optional
        Time step and end time; default ``t_end = 3 / f1`` (lowest full eigenfrequency) and
        ``dt = 1 / (20 fmax)``, at most ``max_steps`` steps.
    scheme, rho_inf
        Integrator of :func:`flexmor.dynamics.time.simulate`.
    n_modes : int
        Full flexible modes in the eigenfrequency/MAC table.
    h2_max_dof : int
        The H2 error (:func:`flexmor.analysis.norms.h2_error`, dense) is computed for damped
        models up to this size.
    solver : SolverContext, optional
        Solver (backend, statistics) of :func:`flexmor.linalg.factorize`.
    progress, time_progress : callable, optional
        ``progress(iterable, total)`` wrappers of the FRF sweep and the full time integration.
    title : str, optional
    view3d : bool
        Add the interactive 3D view (:mod:`flexmor.report.view3d`): surface, couplings, modes
        with MAC pairs, full vs reduced deformation.
    mounted : bool
        Judge bodies with interfaces as held in their joints (:mod:`flexmor.analysis.mounted`):
        ``row["mounted"]`` and the section "The body in its joints".
    coupling : dict, optional
        How the bodies' couplings change the FE model's lowest elastic frequencies
        (:func:`flexmor.checks.coupling_frequencies`); default the record stored in the first
        body's ``info`` at reduce time.

    The plots judge each body against what its table row judges: a free body without rigid-body
    motion against the elastic part of the full response (|H| and time responses), any other
    against the full response; the reference is named in the legends, ``full model with RBE2 at
    HOLE`` for a coupled model.

    Returns
    -------
    Report
    """
    solver = as_solver(solver)
    from ..analysis.compare import FullResponse
    from ..analysis.modal_check import full_modes

    bodies = list(bodies)
    if not bodies:
        raise OptionError("a report needs at least one reduced body")
    labels = list(labels) if labels else [f"{r.method} r={r.order}" for r in bodies]
    labels = [lb if labels.count(lb) == 1 else f"{lb} #{i + 1}" for i, lb in enumerate(labels)]
    seconds = list(seconds) if seconds else [r.info.get("seconds") for r in bodies]
    band = (float(band[0]), float(band[1]))
    if full is None:
        full = FullResponse(model, ports, band, solver=solver, progress=progress)
    couplings = list(bodies[0].couplings)
    ref_name = "full model" + (f" with {describe_couplings(couplings)}" if couplings else "")
    coupling = dict(coupling if coupling is not None else bodies[0].info.get("coupling_frequencies") or {})
    rep = Report(title=title or f"flexmor report: {model.name}", model=model.summary(), band=band, rows=[],
                 reference=ref_name, coupling=coupling)
    if couplings and not coupling:
        rep.notes.append(f"the bodies are judged against the {ref_name}; how the coupling changes the FE model's "
                         "frequencies was not recorded with them")
    ref_of = _frequency_section(rep, model, ports, full, bodies, labels, seconds)
    if mounted:
        _mounted_records(rep, model, ports, bodies, labels, solver)
    _h2_errors(rep, model, ports, bodies, h2_max_dof)
    _singular_values_figure(rep, bodies, labels)
    modes = full_modes(model, n_modes, solver=solver)
    _modal_section(rep, model, bodies, labels, modes)
    _campbell_section(rep, model, bodies, labels, solver)
    f_lo = float(modes[0][0]) if modes[0].size else band[0]
    _moving_section(rep, model, bodies, labels, band=band, f_lo=f_lo, solver=solver)
    _time_section(rep, model, ports, bodies, labels, ref_of, f_lo=f_lo, signal=signal, dt=dt, t_end=t_end,
                  max_steps=max_steps, scheme=scheme, rho_inf=rho_inf, solver=solver, progress=time_progress)
    nodes = _body_figure(rep, model, ports, bodies)
    if view3d:
        _scene(rep, model, ports, bodies, labels, modes, nodes, solver)
    log.info("report on %d bodies: %d figures", len(bodies), len(rep.figures))
    return rep


def _frequency_section(rep: Report, model, ports, full, bodies, labels, seconds) -> dict:
    """One summary row per body with its error measures against ``full`` (and their notes), the |H| and
    rel_error(f) figures; returns the legend name of each body's reference (label -> name)."""
    from ..dynamics.frf import frf_reduced

    H_red, curves, H_refs, ref_of = {}, {}, {}, {}
    for lb, red, sec in zip(labels, bodies, seconds):
        err = full.evaluate(red)
        H_red[lb], curves[lb] = frf_reduced(red, full.freqs), err.rel_error
        H_ref, judged = full.reference(red)
        ref_of[lb] = _reference_label(rep.reference, judged)
        H_refs.setdefault(ref_of[lb], H_ref)
        rep.rows.append({"label": lb, "method": red.method, "order": red.order, **err.to_dict(),
                         "h2_error": None, "seconds": sec})
        rep.rows[-1]["judged_short"] = _SHORT.get(judged, judged)
        rep.rows[-1]["max_rel_error_where"] = (f"{err.max_rel_error_hz:.4g} Hz" + (
            " (anti-resonance)" if err.max_rel_error_at_antiresonance else "") + (
            " (spurious resonance)" if err.max_rel_error_at_spurious_resonance else ""))
        rep.notes.extend(f"{lb}: {n}" for n in err.notes)
    rep.figures["frf"] = plots.frf_png(full.freqs, H_refs, H_red, ports.input_names, ports.output_names,
                                       units=_numbers_units(model))
    rep.plot_data.update(freqs_hz=full.freqs, frf_references=H_refs, reference_of=ref_of)
    rep.figures["rel_error"] = plots.rel_error_png(full.freqs, curves, title=f"{model.name}, {model.n_dof} DOF")
    return ref_of


def _mounted_records(rep: Report, model, ports, bodies, labels, solver) -> None:
    """``row["mounted"]``: each body held in its joints against the full model held the same way
    (:func:`flexmor.analysis.mounted.mounted_record`), and ``row["static"]``, its static error
    (:func:`flexmor.analysis.mounted.static_record`); the full side computed once for all bodies."""
    from ..analysis.mounted import FullMounted, mounted_record, static_record

    held = FullMounted(model, fmax=rep.band[1], solver=solver)
    for lb, row, red in zip(labels, rep.rows, bodies):
        row["mounted"] = mounted_record(model, red, ports=ports, full=held, band=rep.band,
                                        band_rms_error=row["band_rms_error"])
        row["static"] = static_record(model, red, ports=ports, full=held, mounted=row["mounted"],
                                      band_rms_error=row["band_rms_error"])
        for rec in (row["mounted"], row["static"]):
            if rec and rec["note"]:
                rep.notes.append(f"{lb}: {rec['note']}")


def _h2_errors(rep: Report, model, ports, bodies, h2_max_dof: int) -> None:
    """``row["h2_error"]`` of a damped model up to ``h2_max_dof`` DOF (dense), else a note saying why not."""
    damped = model.D is not None
    if not (damped and model.n_dof <= h2_max_dof):
        rep.notes.append("H2 errors not computed: " + (
            f"the model has {model.n_dof} > {h2_max_dof} DOF (dense method)" if damped
            else "undamped bodies have no finite H2 norm"))
        return
    from ..analysis.norms import h2_error
    from ..reduction.free_body import elastic_ports

    e_ports = elastic_ports(model, ports)
    for row, red in zip(rep.rows, bodies):
        try:  # against the row's reference: the elastic part for a body without rigid motion
            with np.errstate(divide="ignore", invalid="ignore"):
                h2 = h2_error(model, e_ports if row["judged"] == JUDGED_ELASTIC else ports, red)
            if np.isfinite(h2):
                row["h2_error"] = h2
            else:
                rep.notes.append(f"H2 error of {row['label']} not computed: the H2 norm of a response with "
                                 "undamped rigid-body motion is infinite")
        except (FlexmorError, np.linalg.LinAlgError) as exc:
            rep.notes.append(f"H2 error of {row['label']} not computed: {exc}")


def _singular_values_figure(rep: Report, bodies, labels) -> None:
    """The singular values the methods report (first key of :data:`SINGULAR_VALUE_KEYS` found), if any."""
    svs = {}
    for lb, red in zip(labels, bodies):
        key = next((k for k in SINGULAR_VALUE_KEYS if np.size(red.info.get(k, [])) > 1), None)
        if key:
            svs[f"{lb} ({key})"] = np.asarray(red.info[key], float)
    if svs:
        rep.figures["singular_values"] = plots.singular_values_png(svs)


def _modal_section(rep: Report, model, bodies, labels, modes) -> None:
    """``rep.modal``: the full eigenfrequencies ``modes = (f, phi, n_rigid)`` paired with each body's
    (:func:`flexmor.analysis.modal_check.modal_check`), and the MAC figure."""
    from ..analysis.modal_check import modal_check

    f, _, n_rig = modes
    rep.modal = {"full_hz": f, "n_rigid": n_rig, "bodies": {}}
    if n_rig:
        rep.notes.append(f"free body ({n_rig} rigid-body modes): bodies without rigid-body motion (rigid excluded, "
                         f"the floating frame carries it) are compared with the {rep.reference}'s elastic response, "
                         "that to the inputs made orthogonal to the rigid-body modes, in the table and the plots; "
                         "the others with the whole response")
    for lb, red in zip(labels, bodies):
        if red.V is None:  # a body made elsewhere (a Nastran superelement) has no basis to expand its modes with
            rep.notes.append(f"{lb}: no basis V (a body reduced by another program), so no MAC: its "
                             "eigenfrequencies are in the body's own summary")
            continue
        rep.modal["bodies"][lb] = modal_check(model, red, full=modes)
    rep.figures["mac"] = plots.mac_png({lb: c["mac"] for lb, c in rep.modal["bodies"].items()})


def _campbell_section(rep: Report, model, bodies, labels, solver) -> None:
    """``rep.campbell`` and its figure for the bodies reduced over a speed range (those about the first one's
    axis and range): the full model's and each body's Campbell diagram over 11 speeds."""
    from ..spin import campbell, parse_spin_range, spin_operators

    spun = [(lb, r) for lb, r in zip(labels, bodies) if isinstance(r.info.get("spin"), dict)]
    if not spun:
        return
    spec = spun[0][1].info["spin"]["spec"]
    sr = parse_spin_range(spec)
    same = [(lb, r) for lb, r in spun if r.info["spin"]["spec"] == spec]
    if len(same) < len(spun):
        rep.notes.append(f"the Campbell diagram is drawn for spin {spec}; bodies reduced for other speed ranges "
                         "are left out of it")
    k = max(1, min(6, min(r.order for _, r in same) // 2))
    speeds = sr.speeds(11)
    ops = spin_operators(model, sr.axis, solver=solver)
    full = campbell(model.M, model.K, ops.K2, ops.G1, speeds, k, D=model.D, solver=solver)
    mine = {lb: campbell(r.M, r.K, np.asarray(r.info["spin"]["K2"]), np.asarray(r.info["spin"]["G1"]), speeds, k,
                         D=r.D) for lb, r in same}
    rep.campbell = {"spec": spec, "speeds": speeds.tolist(), "full": full.record(),
                    "bodies": {lb: c.record() for lb, c in mine.items()},
                    "max_rel_error": {lb: float(np.nanmax(np.abs(c.frequencies_hz / full.frequencies_hz - 1)))
                                      for lb, c in mine.items()}}
    rep.figures["campbell"] = plots.campbell_png(speeds, full.frequencies_hz,
                                                 {lb: c.frequencies_hz for lb, c in mine.items()},
                                                 reference=rep.reference)


def _moving_section(rep: Report, model, bodies, labels, *, band, f_lo: float, solver) -> None:
    """``rep.moving`` and its figures for the bodies reduced with moving loads: each judged over its paths
    (the full path FRF once per path) and crossed at the speeds recorded with it (``reduce --crossing``), else at
    the speed whose crossing lasts ten periods of the lowest mode."""
    from ..moving import crossing, judge_paths, moving_path

    moving = [(lb, r) for lb, r in zip(labels, bodies) if r.info.get("moving_loads")]
    if not moving:
        return
    fulls: dict = {}
    paths, crossings = {}, {}
    for lb, r in moving:
        paths[lb] = judge_paths(model, r, band, fulls=fulls, solver=solver)
        recorded = r.errors.get("crossings") or []
        crossings[lb] = []
        for k, rec in enumerate(r.info["moving_loads"]):
            path = moving_path(model, rec["spec"])
            asked = [(c["speed"], c["force"]) for c in recorded if c.get("path") == path.name] or \
                [(path.length * f_lo / 10.0, 1.0)]
            crossings[lb] += [crossing(model, r, path, speed=v, force=f, k=k, solver=solver) for v, f in asked]
    rep.moving = {"paths": paths, "crossings": crossings}
    rep.figures["moving_path"] = plots.path_error_png(paths)
    rep.figures["moving_crossing"] = plots.crossing_png(crossings, reference=rep.reference)


def _time_section(rep: Report, model, ports, bodies, labels, ref_of, *, f_lo: float, signal, dt, t_end,
                  max_steps: int, scheme: str, rho_inf: float, solver, progress) -> None:
    """``rep.time``, the rows' time errors and the time figure: the full model and each body under
    ``signal`` (one full run for both the whole and the elastic response)."""
    from ..dynamics.time import simulate, time_errors
    from ..reduction.free_body import with_elastic_part

    band = rep.band
    t_end = float(t_end) if t_end else 3.0 / f_lo
    fine = 1.0 / (20.0 * band[1])
    given = bool(dt)
    dt = float(dt) if given else max(fine, t_end / max_steps)
    if dt > fine * (1 + 1e-9):  # the responses then resolve only the lower part of the band
        why = "as given" if given else f"t_end / {max_steps} steps"
        rep.notes.append(f"time responses with dt = {dt:.3g} s ({why}), coarser than 1/(20 FMAX) = {fine:.3g} s: "
                         f"they resolve up to about {1 / (20 * dt):.4g} Hz of the {band[0]:g}-{band[1]:g} Hz band "
                         "(give --dt, or a shorter --t-end)")
    u, desc = _signal(signal, dt, t_end, band)
    elastic = [bool(red.info.get("n_rigid_excluded")) for red in bodies]
    # one run for both responses (a single-channel signal is applied to each input in turn)
    single = np.ndim(u(np.array([0.0, dt])) if callable(u) else u) == 1
    sim_ports = with_elastic_part(model, ports) if any(elastic) and single else ports
    y_all = simulate(model, u, dt=dt, t_end=t_end, ports=sim_ports, scheme=scheme, rho_inf=rho_inf, solver=solver,
                     progress=progress)
    y_full, y_elastic = _split_elastic(y_all, ports)
    y_red, y_refs, t_ref_of = {}, {}, {}
    for lb, red, row, el in zip(labels, bodies, rep.rows, elastic):
        yr, q = _body_run(red, u, dt=dt, t_end=t_end, scheme=scheme, rho_inf=rho_inf)
        y_ref = y_elastic if el and y_elastic is not None else y_full
        e = time_errors(y_ref, yr)
        row.update(time_mean_error=e["time_mean_error"], time_max_error=e["time_max_error"], time_seconds=yr.seconds)
        y_red[lb] = yr.displacement
        if q is not None:  # the body's stress modes (reduce --stress): its largest von Mises stress
            row["max_mises"] = _mises_peak(red, q)
            rep.notes.append(_mises_note(lb, row["max_mises"], red))
        t_ref_of[lb] = ref_of[lb] if y_ref is y_elastic or not el else _reference_label(rep.reference, JUDGED_RIGID)
        y_refs.setdefault(t_ref_of[lb], y_ref.displacement)
        if y_ref is y_full and el:
            rep.notes.append(f"{lb}: time errors against the whole response (the elastic part needs a single-channel "
                             "signal)")
    rep.time = {"signal": desc, "dt": dt, "t_end": float(y_full.t[-1]), "n_steps": int(y_full.t.size - 1),
                "scheme": scheme, "seconds_full": y_full.seconds}
    n_in = y_full.displacement.shape[2]
    chan = {(i, j): f"{ports.output_names[i]} / {ports.input_names[j] if n_in > 1 else 'u'}"
            for i in range(ports.n_outputs) for j in range(n_in)}
    unit = plots.output_unit(ports.output_names, _numbers_units(model))
    rep.figures["time"] = plots.time_png(y_full.t, y_refs, y_red, chan, reference_of=t_ref_of,
                                         quantity=f"displacement [{unit}]" if unit else "displacement")
    rep.plot_data.update(time_references=y_refs, time_reference_of=t_ref_of,
                         time_error=plots.time_error_curves(y_refs, y_red, t_ref_of))


def _body_run(body, u, **options):
    """``(outputs, coordinates)``: the time response of ``body`` to ``u`` at its outputs, and, for a body
    with stress modes, the history of its reduced coordinates too (None else), from one integration
    (outputs ``[C; I]``)."""
    from dataclasses import replace

    from ..dynamics.time import simulate

    if body.stress_modes is None:
        return simulate(body, u, **options), None
    p = body.C.shape[0]
    both = simulate((body.M, body.D, body.K, body.B, np.vstack([body.C, np.eye(body.order)])), u, **options)
    outputs = replace(both, displacement=both.displacement[:, :p], velocity=both.velocity[:, :p],
                      acceleration=both.acceleration[:, :p])
    return outputs, replace(both, displacement=both.displacement[:, p:])


def _mises_peak(body, q, *, chunk: int = 256) -> dict:
    """The largest von Mises stress at the stress nodes of ``body`` over the history ``q`` of its reduced
    coordinates (a :class:`~flexmor.dynamics.time.TimeResponse`): ``mises`` (Pa in SI), ``node``, ``t``
    (s), ``input`` (the input driven, for a single-channel signal)."""
    from ..stress import von_mises

    S = np.asarray(body.stress_modes, float)
    best = {"mises": -1.0}
    for c in range(q.displacement.shape[2]):
        Q = q.displacement[:, :, c]
        for k0 in range(0, Q.shape[0], chunk):
            vm = von_mises(np.einsum("tr,rkl->tkl", Q[k0:k0 + chunk], S))
            i, j = np.unravel_index(int(np.argmax(vm)), vm.shape)
            if vm[i, j] > best["mises"]:
                best = {"mises": float(vm[i, j]), "node": int(body.stress_nodes[j]), "t": float(q.t[k0 + i]),
                        "input": body.input_names[c] if q.displacement.shape[2] == len(body.input_names) else None}
    return best


def _mises_note(label, peak: dict, body) -> str:
    where = ""
    if body.node_ids is not None and body.xyz is not None:
        at = np.flatnonzero(np.asarray(body.node_ids) == peak["node"])
        if at.size:
            where = " at [" + ", ".join(f"{v:.4g}" for v in np.asarray(body.xyz)[at[0]]) + "]"
    by = f", under {peak['input']}" if peak.get("input") else ""
    value = (f"{peak['mises'] / 1e6:.4g} MPa ({peak['mises']:.4g} Pa)" if body.units is not None else
             f"{peak['mises']:.4g} (the stress unit of the file's material: no unit system named)")
    return (f"{label}: largest von Mises stress of the time responses {value} at node {peak['node']}{where}, "
            f"t = {peak['t']:.4g} s{by}")


def _body_figure(rep: Report, model, ports, bodies) -> dict:
    """The picture of the body's nodes with its ports and interface (or a note); returns those nodes
    (``inputs``, ``outputs``, ``interface``)."""
    nodes = {"inputs": port_nodes(model, ports.input_names), "outputs": port_nodes(model, ports.output_names),
             "interface": np.unique(np.concatenate([interface_nodes(model, r) for r in bodies]))}
    if not model.n_nodes:
        rep.notes.append("the model has no node coordinates: no picture of the body")
        return nodes
    marks = {"inputs": model.node_xyz(nodes["inputs"]), "outputs": model.node_xyz(nodes["outputs"])}
    if nodes["interface"].size:
        marks["interface"] = model.node_xyz(nodes["interface"])
    rep.figures["body"] = plots.body_png(model.xyz, marks, title=f"{model.name}: {model.n_nodes} nodes",
                                         units=_numbers_units(model))
    return nodes


def _scene(rep: Report, model, ports, bodies, labels, modes, nodes, solver) -> None:
    """The interactive 3D view (:func:`flexmor.report.view3d.build_scene`), or a note why there is none."""
    if is_partitioned(model.K):
        rep.notes.append("no 3D view: the model's rows are spread over MPI ranks")
    elif model.n_nodes and model.dofs is not None:
        from .view3d import build_scene

        rep.scene = build_scene(model, ports, bodies, labels, band=rep.band, modal=rep.modal["bodies"],
                                full_modes=modes, solver=solver, nodes=nodes)


#: The summary table's short form of ``judged``.
_SHORT = {JUDGED_ELASTIC: "elastic part", JUDGED_RIGID: "with rigid motion"}


def _reference_label(ref_name: str, judged: str) -> str:
    """The legend name of a reference: ``full model with RBE2 at HOLE, elastic part`` ..."""
    return f"{ref_name}, {_SHORT[judged]}" if judged in _SHORT else ref_name


def _split_elastic(y, ports):
    """``(y for ports, y of the elastic part or None)`` of a :class:`TimeResponse` of the ports of
    :func:`flexmor.reduction.free_body.with_elastic_part`."""
    import dataclasses

    from ..reduction.free_body import split_elastic

    whole, elastic = zip(*(split_elastic(getattr(y, f), ports) for f in ("displacement", "velocity", "acceleration")))
    if elastic[0] is None:
        return y, None
    fields = ("displacement", "velocity", "acceleration")
    return tuple(dataclasses.replace(y, **dict(zip(fields, part))) for part in (whole, elastic))
