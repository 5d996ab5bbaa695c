"""End-to-end jobs shared by the command line and scripts: damping, reduce + judge, demo."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

from .analysis.compare import FullResponse
from .analysis.frequency import measure_record
from .body import convergence_record
from .checks import check_rigid_body_modes, coupling_frequencies, first_elastic_hz
from .damping import Damping, NoDamping, Rayleigh, band_matched
from .damping import modal_damping as _modal_damping
from .errors import OptionError, check_keywords, keyword_names
from .linalg.backends import is_iterative
from .linalg.context import SolverContext, as_solver
from .linalg.distributed import is_partitioned
from .linalg.resources import check_basis_memory
from .options import DEFAULT_BAND, Band, check_order, parse_pair
from .ports import make_ports
from .reduction import BASIS_KEYWORDS, check_shift, method_name, methods, reduce
from .reduction.free_body import check_body
from .rigid import register_near_null

__all__ = ["coupling_specs", "prepare_model", "body_model", "parse_band", "parse_pair", "apply_damping", "damping_of",
           "with_method_band", "reduce_and_judge", "record_setup", "run_demo", "DEFAULT_BAND"]

log = logging.getLogger(__name__)

def parse_band(text) -> Band:
    """Parse ``FMIN:FMAX`` (Hz) (or check a pair) and check ``0 < FMIN < FMAX``."""
    return Band.of(text)


def damping_of(*, rayleigh=None, modal_damping=None, band_rayleigh=None, band=None) -> Damping:
    """The damping asked for (at most one of the three):

    * ``rayleigh=(alpha, beta)``: ``D = alpha M + beta K``;
    * ``modal_damping=zeta``: the ratio ``zeta`` in every mode (:class:`flexmor.damping.ModalDamping`,
      its sparse realization matched at the ends of ``band``, default :data:`DEFAULT_BAND`);
    * ``band_rayleigh=zeta``: the Rayleigh damping whose ratio is ``zeta`` at both ends of ``band``
      (:func:`flexmor.damping.band_matched`; lower in between, higher outside).

    :class:`~flexmor.damping.NoDamping` when none is given."""
    given = {k: v for k, v in (("rayleigh", rayleigh), ("modal_damping", modal_damping),
                               ("band_rayleigh", band_rayleigh)) if v is not None}
    if len(given) > 1:
        raise OptionError(f"give either {' or '.join(given)}, not both", params=tuple(given))
    if rayleigh is not None:
        try:
            alpha, beta = rayleigh
        except (TypeError, ValueError):
            raise OptionError(f"rayleigh must be a pair (alpha, beta), got {rayleigh!r}",
                              params=("rayleigh",)) from None
        return Rayleigh(alpha, beta)  # each a real, finite number >= 0, or refused naming it
    if modal_damping is not None:
        return _modal_damping(modal_damping, Band.of(band))
    if band_rayleigh is not None:
        return band_matched(band_rayleigh, Band.of(band))
    return NoDamping()


def apply_damping(model, *, rayleigh=None, modal_damping=None, band_rayleigh=None, band=None):
    """Return ``model`` with the damping of :func:`damping_of` (the model itself when none is given)."""
    return model.with_damping(damping_of(rayleigh=rayleigh, modal_damping=modal_damping,
                                         band_rayleigh=band_rayleigh, band=band))


def coupling_specs(interfaces=(), ports=()) -> list[str]:
    """The SPECs that change the model: interfaces ``SET@rbe2``/``SET@rbe3`` and ports ``SET@rbe2:DIR``.

    (``SET@rbe3:DIR`` ports work on the unchanged model and are not listed.)
    """
    from .ports import parse_spec

    specs = [s for s in interfaces if "@" in s] + [s for s in ports if "@rbe2" in s.lower()]
    out = []
    for s in specs:
        target = s.rpartition(":")[0] if s.lower().endswith(":all") else parse_spec(s)[0]
        if target.upper() not in (t.upper() for t in out):
            out.append(target)
    return out


def prepare_model(model, couplings=()):
    """The model with ``couplings`` applied (:func:`flexmor.couplings.couple`). The model a
    reduced body is judged against, with the body's damping, is
    :func:`flexmor.origin.reference_model`."""
    if couplings:
        from .couplings import couple

        model = couple(model, list(couplings)).model
    return model


def body_model(model, body, path="the body", *, damping: Damping | None = None):
    """The full model ``body`` was made from: the body's node selections (``reduced.selections``,
    the ``--select`` of ``flexmor reduce``), couplings and damping applied to ``model`` as read,
    checked against the body's fingerprint (:func:`flexmor.origin.reference_model`, which
    explains ``path`` and ``damping``)."""
    from .origin import reference_model

    return reference_model(model, body, path, damping=damping)


def reduce_and_judge(model, method: str, order, ports, *, band=None,
                     full: FullResponse | Callable[[], FullResponse] | None = None,
                     n_freq: int = 50, grid_tol: float | None = None, full_frf: str = "auto", cache=True,
                     solver: SolverContext | None = None, progress=None, tol: float | None = None, method_band=None,
                     tol_measure: str = "band_error", mounted: bool = True, uncoupled=None, couplings=(),
                     **options):
    """Reduce ``model`` and evaluate the error measures over ``band``.

    Returns ``(reduced, result)``; ``result`` is the JSON record of ``flexmor reduce``:
    ``method, order, order_requested, order_note``, ``converged`` and ``convergence_note`` of an
    iterative method (:func:`flexmor.body.convergence_record`), ``seconds, band_hz``, the error measures of
    :data:`flexmor.analysis.frequency.MEASURE_KEYS` (``band_error``, ``rms_rel_error_pct``,
    ``hinf_error``, ``max_rel_error`` ...), ``notes``, ``frequencies_hz``, ``timings``.
    ``full`` (a :class:`FullResponse`, or a function returning one, called when it is needed:
    after the reduction, or first in the target-error mode) is reused when given, else computed
    (``band=None`` skips the error evaluation); a method with a ``band`` option builds for ``band``, else for the
    band of ``full``, else for ``method_band`` (unless ``options`` give ``band``). ``n_freq``,
    ``grid_tol``, ``full_frf`` (the path: auto, direct, surrogate) and ``cache`` are passed to
    :class:`FullResponse`; ``result["grid"]`` describes the grid (size, tolerance, resonances,
    path, ``cache_hit``) and ``timings["full_frf"]`` is the wall time of the full FRF computed here.
    ``tol`` switches to the target-error mode (:func:`flexmor.tolerance.reduce_to_tolerance`):
    the smallest order whose verified ``tol_measure`` (default band_error) is ``<= tol``,
    ``order`` then being the largest order tried; ``result`` gets ``tol``, ``tol_measure`` and
    ``tol_reached``. ``order_requested`` is the order asked for (None in the target-error mode
    without one); ``order_note`` says why the order returned differs from it (else None). ``method_band`` is the band
    the method itself uses (expansion points, Gramian band) when ``band`` is None (no error
    evaluation). A mechanism (more than six zero-energy modes) is refused first
    (:func:`flexmor.checks.check_rigid_body_modes`). A body with modes below the full model's
    first elastic frequency that the full model does not have, or with band_error above 1, is
    reported by a :class:`~flexmor.errors.FlexmorWarning` (:func:`flexmor.reduction.free_body.check_body`);
    ``result["warnings"]`` lists them. With ``mounted`` (and the error evaluation), a body with
    interfaces (coupling masters, Craig-Bampton interface sets) is also judged as held in its
    joints (:func:`flexmor.analysis.mounted.mounted_record`): ``result["mounted"]`` and
    ``reduced.errors["mounted"]``, its note (if any) among the ``notes``, ``timings["mounted"]``; and every
    body its static error (:func:`flexmor.analysis.mounted.static_record`: ``result["static"]``,
    ``reduced.errors["static"]``, its note, ``timings["static"]``).
    With ``uncoupled`` (the model before its ``couplings`` were
    applied), ``result["coupling_frequencies"]`` (also in the body's ``info``) compares the lowest
    elastic frequencies of both (:func:`flexmor.checks.coupling_frequencies`; the coupled ones
    from the error grid's modal pre-pass when it holds them).
    """
    method = method_name(method)  # aliases and case resolved once: the band, the checks and the record use it
    check_keywords(f"reduce_and_judge with method {method!r}", options,
                   [*methods()[method].keywords, *BASIS_KEYWORDS, *keyword_names(reduce_and_judge)])
    solver = as_solver(solver)
    register_near_null(solver, model)  # the geometry's rigid motions, should the amg backend solve
    full_of = full if callable(full) and not isinstance(full, FullResponse) else None
    if full_of is not None:
        if band is not None:
            raise OptionError("give band or full, not both, when full is a function", params=("band", "full"))
        full = None
    if full is not None and band is not None and not _same_band(band, full.band):
        raise OptionError(f"band {tuple(Band.of(band))} differs from the band of full {full.band}; give one of them",
                          params=("band", "full"))
    method_band = band if band is not None else full.band if full is not None else method_band
    options = with_method_band(method, method_band, options)
    # a mechanism is refused before any work; the check's factorization serves the method where it
    # factorizes the same matrix first (not kept while a target-error search computes the full FRF)
    sigma, keep = check_shift(model, method, options) if tol is None else (None, False)
    order = check_order(order)
    if order is not None and not is_partitioned(model.K):  # a basis that cannot fit: refused before any work
        check_basis_memory(model.n_dof, order, solver)
    try:
        check_rigid_body_modes(model, solver=solver, sigma=sigma, keep=keep)
    except BaseException:
        solver.release()
        raise
    t_full = None
    if tol is not None:  # target-error mode: the order is chosen against the full FRF
        from .tolerance import check_tol_method

        check_tol_method(method)
        if is_iterative(solver.backend):
            raise OptionError(f"tol chooses the order by the band error, which backend {solver.backend} does not "
                              "compute (it solves no complex systems); give --order", params=("tol", "backend"))
        if full is None and band is None and full_of is None:
            raise OptionError("tol needs the error evaluation over a band (band is None)", params=("tol",))
        if full_of is not None:
            full, t_full = _timed(full_of)
        elif full is None:
            grid_opts = {} if grid_tol is None else {"tol": grid_tol}
            full = FullResponse(model, ports, band, n=n_freq, solver=solver, path=full_frf, cache=cache,
                                progress=progress, **grid_opts)
            t_full = full.seconds
    f0 = solver.stats.seconds
    if tol is not None:
        from .tolerance import reduce_to_tolerance

        red, t, _ = reduce_to_tolerance(model, method, ports, tol=tol, full=full, max_order=order,
                                        measure=tol_measure, solver=solver, **options)
        red.info["timings"] = t
        red.info["order_requested"] = None if order is None else int(order)
        red.order_note = None  # the order was chosen by the search (its record says how)
    else:
        try:
            red = reduce(model, method, order, ports, solver=solver, **options)
        finally:
            solver.release()
        t = red.info["timings"]
    t["factorize"] = solver.stats.seconds - f0
    if t_full is not None:
        t["full_frf"] = t_full
    result = {
        "method": method,
        "order": red.order,
        "order_requested": red.info.get("order_requested"),
        "order_note": red.order_note,
        **convergence_record(red),
        "seconds": t["basis"] + t["project"],
        "band_hz": None, **measure_record(None),
        "frequencies_hz": red.frequencies_hz().tolist(),
        "info": red.info,
    }
    skipped = None
    if full is None and (full_of is not None or band is not None) and is_iterative(solver.backend):
        skipped, band_only = ITERATIVE_SKIP, band if band is not None else method_band
        band = full_of = None
    if full is None and full_of is not None:
        full, t["full_frf"] = _timed(full_of)
    elif full is None and band is not None:
        grid_opts = {} if grid_tol is None else {"tol": grid_tol}
        full = FullResponse(model, ports, band, n=n_freq, solver=solver, path=full_frf, cache=cache,
                            progress=progress, **grid_opts)
        t["full_frf"] = full.seconds
    if full is not None:
        t0 = time.perf_counter()
        err = full.evaluate(red)
        t["error"] = time.perf_counter() - t0
        result.update(band_hz=list(full.band), **err.to_dict())
        result["grid"] = full.summary()
        red.errors = {"band_hz": list(full.band), **err.to_dict(), "freqs_hz": full.freqs,
                      "rel_error": err.rel_error}
    if skipped is not None:  # the mounted and static checks solve real positive definite systems: they run
        result["notes"].append(skipped)
        red.errors = {"notes": [skipped]}
        if band_only is not None:
            result["band_hz"] = list(Band.of(band_only))
    if mounted and result["band_hz"] is not None:
        _judge_mounted(model, red, ports, result, t, solver=solver)
    f1 = first_elastic_hz(model, solver=solver)
    result["warnings"] = check_body(model, red, f1_hz=f1, band_error=result["band_error"])
    if uncoupled is not None and couplings:
        known = None
        if full is not None and full.band[0] <= f1:  # the pre-pass found every elastic mode below the band top
            known = full.resonances[full.resonances >= f1 * (1 - 1e-6)]
        rec = coupling_frequencies(uncoupled, model, couplings, coupled_hz=known, solver=solver)
        red.info["coupling_frequencies"] = result["coupling_frequencies"] = rec
    if tol is not None:
        result["tol"] = tol
        result["tol_measure"] = tol_measure
        result["tol_reached"] = red.info["tol_search"]["tol_reached"]
    result["timings"] = t
    return red, result


#: The note of a body whose band error the ``amg`` backend did not compute.
ITERATIVE_SKIP = ("band error not computed: an iterative backend (amg, petsc-gamg) has no solver for the complex "
                  "K - w^2 M + i w D of the full model's FRF (real positive definite matrices only); judge the body "
                  "with a direct backend (flexmor compare) where one fits")


def record_setup(body, *, couplings=(), interfaces=(), selections=()) -> None:
    """Record on ``body`` what was applied to the model it was reduced from: its ``couplings``
    and ``selections`` (when any; :func:`flexmor.origin.reference_model` applies them again to
    the model as read), and all three in its fingerprint ``origin``."""
    if couplings:
        body.couplings = list(couplings)
    if selections:
        body.selections = list(selections)
    body.origin.update(couplings=list(couplings), interfaces=list(interfaces), selections=list(selections))


def _judge_mounted(model, body, ports, result, timings, *, solver=None) -> None:
    """The body held in its joints (:func:`flexmor.analysis.mounted.mounted_record`) and its static error
    (:func:`flexmor.analysis.mounted.static_record`) into ``result``, ``red.errors`` and their notes."""
    from .analysis.mounted import FullMounted, mounted_record, static_record

    t0 = time.perf_counter()
    band, rms = result["band_hz"], result["band_rms_error"]
    # the full side of both checks (rigid-body modes once); none for rows spread over MPI ranks (both skip)
    full = None if is_partitioned(model.K) else FullMounted(model, fmax=band[1], solver=solver)
    mounted = mounted_record(model, body, ports=ports, band=band, band_rms_error=rms, full=full)
    t1 = time.perf_counter()
    static = static_record(model, body, ports=ports, mounted=mounted, band_rms_error=rms, full=full)
    timings["mounted"], timings["static"] = t1 - t0, time.perf_counter() - t1
    for key, rec in (("mounted", mounted), ("static", static)):
        if rec is None:
            continue
        result[key] = body.errors[key] = rec
        if rec["note"]:
            result["notes"].append(rec["note"])
            body.errors["notes"].append(rec["note"])


def with_method_band(method: str, band, options: dict) -> dict:
    """``options`` with ``band`` (Hz) added when ``method`` (any case, or a short name:
    :func:`flexmor.reduction.method_name`) has a ``band`` option (expansion points, Gramian band)
    that ``options`` does not give; unchanged for other methods or without ``band``."""
    if band is None or options.get("band") is not None:
        return dict(options)
    if "band" not in methods()[method_name(method)].options:
        return dict(options)
    return {**options, "band": tuple(Band.of(band))}


def _timed(make):
    """``(make(), wall time)``."""
    t0 = time.perf_counter()
    out = make()
    return out, time.perf_counter() - t0


def _same_band(a, b) -> bool:
    return all(abs(x - y) <= 1e-9 * abs(y) for x, y in zip(Band.of(a), Band.of(b)))


def run_demo(out, *, n: int = 4, band=(10.0, 3000.0), progress=None, on_result=None, time_progress=None):
    """The demo job: the built-in clamped steel cantilever reduced by several methods.

    Inputs/outputs: tip force / tip displacement in y and z (``TIP:y``, ``TIP:z``), Rayleigh
    damping ``beta = 1e-6 s``; ``modal`` at r = 4, 8, 16, ``craig-bampton`` with the
    tip's centre node as interface (3 DOF) plus 5 and 13 fixed-interface modes, and
    ``krylov`` and ``fw-sobt`` at r = 16 over the band (built for the two ports and the frame's six
    inertia loads, :func:`flexmor.reduction.free_body.with_inertia_loads`). Writes one
    ``.h5`` per reduced body, ``rel_error.png`` and the HTML report ``report.html``
    (:mod:`flexmor.report.contents`, :mod:`flexmor.report.html`) into ``out``; ``progress`` is shown the long steps
    (:func:`flexmor.linalg.context.track`), ``time_progress`` wraps its time integration.

    Returns the list of result records (as :func:`reduce_and_judge`) with ``file`` added.
    """
    from .io import write_body
    from .models import cantilever
    from .report.plots import plot_rel_error

    out = Path(out)
    model = cantilever(n=n).with_rayleigh(0.0, 1e-6)
    ports = make_ports(model, ["TIP:y", "TIP:z"])
    solver = SolverContext(progress=progress)  # the long steps of the full FRF and the reductions
    full = FullResponse(model, ports, band, solver=solver)
    jobs = [("modal", 4, {}), ("modal", 8, {}), ("modal", 16, {}),
            ("craig-bampton", 8, {"interface": ["TIP_CENTER"]}),
            ("craig-bampton", 16, {"interface": ["TIP_CENTER"]}), ("krylov", 16, {"band": band}),
            ("fw-sobt", 16, {"band": band})]
    results, curves, reds = [], {}, []
    for method, order, opts in jobs:
        red, res = reduce_and_judge(model, method, order, ports, full=full, solver=solver, **opts)
        reds.append(red)
        path = out / f"{model.name}_{method}_{red.order}.h5"  # the order of the body (a pair kept whole: 17 for 16)
        write_body(red, path)
        res["file"] = str(path)
        results.append(res)
        curves[f"{method} r={red.order}"] = red.errors["rel_error"]
        if on_result:
            on_result(res)
    plot_rel_error(full.freqs, curves, out / "rel_error.png",
                   title=f"{model.name}: {model.n_dof} DOF, inputs/outputs TIP:y, TIP:z")
    from .report.contents import build_report
    from .report.html import write_report

    rep = build_report(model, ports, reds, band=band, full=full, seconds=[r["seconds"] for r in results],
                       solver=solver, time_progress=time_progress)
    write_report(rep, out / "report.html")
    for res, row in zip(results, rep.rows):
        res.update(time_mean_error=row["time_mean_error"], time_max_error=row["time_max_error"])
    return {"model": model.summary(), "full_frf_seconds": full.seconds, "n_freq": int(full.freqs.size),
            "grid": full.summary(),
            "band_hz": list(band), "results": results, "plot": str(out / "rel_error.png"),
            "report": str(out / "report.html"), "time": rep.time}
