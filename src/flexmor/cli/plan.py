"""The ``plan`` subcommand: memory and time of a reduction per backend and memory mode, before the run.

``flexmor plan MODEL --method M --order R`` reads the model as ``reduce`` does and prints, without
factorizing it, the solver work of the method (:func:`flexmor.plan.plan_reduction`), the memory and time
each backend and memory mode would take, and which one ``auto`` chooses (or that nothing fits).
"""

from __future__ import annotations

from ..linalg.memory import MODE_NAMES

__all__ = ["add_plan_parser", "cmd_plan", "plan_lines"]


def add_plan_parser(sub, *, add_model_args, method_type, methods, add_method_options) -> None:
    """The ``plan`` subparser, with the model flags of ``reduce`` (``add_model_args``), its ``--method``
    (``method_type``, the choices ``methods``), ``--order``, ports, interfaces and method options."""
    p = sub.add_parser("plan", help="memory and time of a reduction per backend and memory mode, before the run "
                       "(no factorization), and what auto chooses",
                       epilog="Times come from each factorization's operations and a rate measured now on a block "
                       "of the model's own matrix; solve columns marked ~ are estimates (iterative eigen solves, "
                       "Krylov's adaptive points).")
    add_model_args(p)
    p.add_argument("--method", required=True, type=method_type, choices=sorted(methods), help="reduction method")
    p.add_argument("--order", type=int, help="reduced order r")
    p.add_argument("--input", action="append", default=[], metavar="SPEC", help="input NODE:DIR or SET:DIR")
    p.add_argument("--output", action="append", default=[], metavar="SPEC", help="output NODE:DIR or SET:DIR")
    p.add_argument("--interface", action="append", default=[], metavar="SPEC", help="interface, as for reduce")
    p.add_argument("--inertia-loads", choices=["auto", "on", "off"], default="auto",
                   help="as for reduce (the inertia loads widen Krylov's blocks)")
    p.add_argument("--no-error", action="store_true", help="plan without the error grid, as reduce --no-error")
    add_method_options(p)
    p.set_defaults(func=cmd_plan)


def cmd_plan(args) -> int:
    """``flexmor plan``: the plan of a reduction; returns the exit code."""
    from ..errors import OptionError
    from ..plan import plan_reduction
    from ..study import System
    from .commands import _asked_damping, _emit_json, _grid_options, _preparation, _print_nearest, _solver
    from .method_flags import method_options

    options = method_options(args, args.method)
    if args.order is not None and args.order < 1:
        raise OptionError(f"--order must be at least 1, got {args.order}", params=("order",))
    solver = _solver(args)
    system = System(args.model, inputs=args.input, outputs=args.output, interfaces=args.interface,
                    band=args.band or None, damping=_asked_damping(args), **_preparation(args), solver=solver,
                    **_grid_options(args))
    _print_nearest(system.prepared_as.nearest)
    plan = plan_reduction(system.model, args.method, args.order, system.ports, solver=solver,
                          inertia_loads=args.inertia_loads, judge=not args.no_error, n_freq=args.n_freq,
                          full_frf=args.full_frf, **system.options(args.method, options))
    if args.json:
        _emit_json(dict(plan.to_dict(), file=str(args.model)))
        return 0
    for line in plan_lines(plan, str(args.model)):
        print(line)
    return 0


def _mb(x) -> str:
    return "-" if x is None else f"{x / 2**20:.0f}"


def _s(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def plan_lines(plan, name: str) -> list[str]:
    """The plan as the lines ``flexmor plan`` prints."""
    m = plan.model
    order = "" if plan.order is None else f", order {plan.order}"
    out = [f"plan      {plan.method}{order} of {name}: {m['n_dof']} DOF, nnz(K) {m['nnz_K']} "
           f"(nothing factorized; planned in {plan.seconds:.2f} s)"]
    if plan.stages is None:
        out.append(f"solver    {plan.method}: not estimated (the plan counts the work of krylov, modal, "
                   "craig-bampton and guyan); the memory of one factorization is shown")
    else:
        out.append("")
        out.append(f"  {'solver work':62s} {'n':>8s}  {'matrix':7s} {'fact.':>5s} {'columns':>8s}")
        for s in plan.stages:
            out.append(f"  {s.what[:62]:62s} {s.n:8d}  {'complex' if s.complex else 'real':7s} "
                       f"{s.factorizations:5d} {('' if s.exact else '~') + str(s.columns):>8s}")
        out.append(f"  {'total (rigid-body check and method)':62s} {'':8s}  {'':7s} {plan.factorizations:5d} "
                   f"{plan.columns:8d}")
    out.append(f"error     {plan.grid}")
    out.append(f"memory    every row counts the matrices ({_mb(plan.memory['matrices'])} MB) and the basis and "
               f"block vectors ({_mb(plan.memory['vectors'])} MB) beside the factor")
    out.append("")
    out.append(f"  {'backend':8s} {'mode':7s} {'factor MB':>9s} {'peak MB':>8s} {'factor s':>9s} {'solve s':>8s} "
               f"{'total s':>8s}")
    for r in plan.rows:
        if not r["available"] or r["factor_bytes"] is None:
            out.append(f"  {r['backend']:8s} {'-':7s} {r['source']}")
            continue
        out.append(f"  {r['backend']:8s} {r['mode']:7s} {_mb(r['factor_bytes']):>9s} {_mb(r['peak_bytes']):>8s} "
                   f"{_s(r['factor_seconds']):>9s} {_s(r['solve_seconds']):>8s} {_s(r['total_seconds']):>8s}")
    out.append("")
    sources = sorted({r["source"] for r in plan.rows if r["available"] and r["factor_bytes"] is not None})
    out.append("estimates " + "; ".join(sources))
    if plan.calibration:
        out.append(f"rate      {plan.calibration}")
    for kind, label in (("real", "K - sigma M (real)"), ("complex", "K - w^2 M + i w D (complex)")):
        a = plan.auto.get(kind)
        if a is None:
            continue
        if a["mode"] is None:
            out.append(f"auto      {label}: NOTHING FITS: {a['reason']}")
        else:
            why = a["reason"].removeprefix(MODE_NAMES[a["mode"]]).strip(" :")
            out.append(f"auto      {label}: {a['backend']}, {MODE_NAMES[a['mode']]}" + (f" ({why.strip('()')})"
                                                                                        if why else ""))
    return out
