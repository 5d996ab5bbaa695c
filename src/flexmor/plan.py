"""A plan before the run: the factorizations, solves, memory and time a reduction will take, per backend and mode.

:func:`plan_reduction` counts what ``flexmor reduce`` does with the sparse solver for a method and order
(:func:`method_stages`: the rigid-body check, the method's factorizations and the right-hand sides it
solves with each, the error grid) without factorizing the model, and prices them with the estimates of
:mod:`flexmor.linalg.plan` (memory from PARDISO's analysis or the SuperLU heuristic, time from the
factorization's operations and a rate measured on leading blocks of the model's own matrix). It says which
backend and memory mode ``auto`` takes for the method's real matrix and for the error grid's complex one,
through the functions a real run calls, and when nothing fits.

The counts follow the methods' code: the rigid-body check (:func:`flexmor.checks.check_rigid_body_modes`:
one factorization of ``K - sigma M`` and block Lanczos for 7 eigenpairs, shared with ``modal`` and with
``krylov`` at a first real point, :func:`flexmor.reduction.check_shift`); ``krylov`` at given points one
factorization per point and ``moments x b`` columns (``b`` the inputs with the frame's inertia loads), at its
default points the greedy sequence of :func:`flexmor.reduction.greedy_points.greedy_basis` and the two
factorizations of its estimate; ``modal`` block Lanczos for ``order + 9`` pairs; ``guyan`` and
``craig-bampton`` one factorization of ``K_ii`` and a solve of the interface columns, Craig-Bampton then
Lanczos on ``(K_ii, M_ii)`` with it. Every factorization adds the one column of its check. Direct solves
are counted exactly; the columns of an iterative eigen solve (:data:`LANCZOS_COLUMNS_PER_PAIR`) and the
directions of Krylov's default points are estimates, marked so.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from .analysis.compare import SURROGATE_MIN_DOF
from .checks import MAX_RIGID_BODY_MODES
from .damping import ModalDamping
from .dynamics.dense_frf import dense_applicable
from .linalg.amg import near_null
from .linalg.context import SolverContext, as_solver
from .linalg.eigen import DENSE_LIMIT, default_shift
from .linalg.lobpcg import guard_columns
from .linalg.memory import matrix_bytes
from .linalg.plan import CALIBRATION_ROWS, REUSED_ANALYSIS, BackendEstimate, auto_choice, estimate_backends
from .linalg.resources import BASIS_COPIES
from .ports import interface_dofs
from .reduction import check_shift, method_name
from .reduction.arnoldi import start_block
from .reduction.free_body import with_inertia_loads
from .reduction.greedy_compress import growth_orders
from .reduction.greedy_points import moments_at
from .reduction.krylov import parse_points
from .reduction.modal import CLUSTER_MARGIN, room_for_rigid
from .rigid import register_near_null, rigid_body_modes

__all__ = ["ESTIMATED_METHODS", "LANCZOS_COLUMNS_PER_PAIR", "LOBPCG_COLUMNS_PER_COLUMN", "MISSED_DIRECTIONS", "Plan",
           "Stage", "method_stages",
           "plan_reduction"]

#: Right-hand sides block Lanczos solves per wanted eigenpair (:mod:`flexmor.linalg.block_eigen`), measured on
#: the cantilever (bench/plan.py: 42 columns for 7 pairs, 66 for 13, 126 for 19; 5-6.6 per pair).
LANCZOS_COLUMNS_PER_PAIR = 6

#: Cost of the ``amg`` backend's LOBPCG (:mod:`flexmor.linalg.lobpcg`) in block-CG-solved columns per column it
#: iterates (``k`` pairs plus :func:`~flexmor.linalg.lobpcg.guard_columns`): measured on the cantilever with
#: modal 30 at 36,300 DOF (the rigid-body check's 13 columns and modal's 48: 6.0 s against 0.1 s per solved
#: column, 1.0-1.2 per column; the planned time 1.06x the run's with 1.5; not checked above 36,300 DOF).
LOBPCG_COLUMNS_PER_COLUMN = 1.5

#: Load combinations a default Krylov point on the axis starts from (``directions='missed'``): "near a
#: resonance one or two" (:func:`flexmor.reduction.greedy_points._tangential_blocks`).
MISSED_DIRECTIONS = 2

#: The methods whose solver work :func:`method_stages` counts.
ESTIMATED_METHODS = ("krylov", "modal", "craig-bampton", "guyan")


@dataclass(frozen=True)
class Stage:
    """One step of a run that uses the sparse solver.

    Attributes
    ----------
    what : str
        What it is (for the table).
    n : int
        Equations of the matrix factorized.
    complex : bool
        The matrix is complex.
    factorizations : int
        Factorizations it makes (0: it uses one made before).
    columns : int
        Right-hand sides it solves.
    exact : bool
        ``columns`` and ``factorizations`` are exact (direct solves), not an estimate (an iterative solver,
        an adaptive choice).
    block : int
        Columns of ``n`` it keeps beside the basis (Lanczos basis, Krylov block).
    iterative_columns : int, optional
        What the stage costs under the ``amg`` backend in solved columns, where it does not solve columns
        there: an eigen solve runs LOBPCG instead (:data:`LOBPCG_COLUMNS_PER_COLUMN`).
    """

    what: str
    n: int
    complex: bool
    factorizations: int
    columns: int
    exact: bool = True
    block: int = 0
    iterative_columns: int | None = None


def _lanczos(solver: SolverContext, n: int, k: int) -> tuple[int, int, str]:
    """``(columns, basis columns, method)`` of the eigen solve of ``k`` pairs of an ``n``-DOF problem."""
    method = solver.eigen.choose(n, k)
    if method == "dense":
        return 0, 0, method
    if method == "lanczos":
        p = max(1, min(min(max(6, k // 4), 16), n - k if n > k else 1))
        return p * math.ceil(LANCZOS_COLUMNS_PER_PAIR * k / p), min(max(5 * k, k + 14 * p), n), method
    return LANCZOS_COLUMNS_PER_PAIR * k, 2 * k + 1, method  # ARPACK, ncv = 2k + 1


def _rigid_check(model, solver, shared: bool) -> list[Stage]:
    """The rigid-body check's eigen solve (7 pairs); its factorization, kept for the method when ``shared``."""
    k = MAX_RIGID_BODY_MODES + 1
    if model.n_dof <= DENSE_LIMIT:
        return []
    cols, block, method = _lanczos(solver, model.n_dof, k)
    return [Stage("rigid-body check: K - sigma M, Lanczos 7 pairs" + (" (factorization kept for the method)"
                  if shared else ""), model.n_dof, False, 1, 1 + cols, False, block, _lobpcg(model.n_dof, k, method))]


def _krylov(model, order, ports, options, solver, shared) -> list[Stage]:
    """Krylov at given points, or at its greedy default points (with their estimate's two factorizations), the
    greedy basis built to 1.5 times the order where the default compresses it."""
    side = options.get("side", "input")
    b = start_block(ports, side).shape[1]
    n = model.n_dof
    moments = options.get("moments")
    if options.get("points") is not None:
        pts = parse_points(options["points"])
        per_round = sum(b * (1 if p.imag == 0 else 2) for p in pts)
        k = int(moments) if moments is not None else math.ceil(order / per_round)
        return [Stage(f"krylov point {p:g} Hz, {k} moments of {b}" + (" (the check's factorization)"
                                                                       if shared and i == 0 else ""),
                      n, p.imag != 0, 0 if shared and i == 0 else 1, k * b + (0 if shared and i == 0 else 1),
                      block=b) for i, p in enumerate(pts)]
    if order is None:
        return []
    missed = options.get("directions", "missed") == "missed"
    stages, cols, i = [], 0, 0
    if missed and moments is None and options.get("compress", "auto") != "off" and options.get("rigid") != "include":
        # the greedy basis runs to the first of its compression's orders (growing further, where its reference
        # asks for it, adds points that are not planned: flexmor.reduction.greedy_compress)
        order = growth_orders(order, n)[0]
    while cols < order:
        m = int(moments) if moments is not None else moments_at(i, b)
        if i == 0:
            new, solved, what = m * b, m * b, f"krylov static point, {m} moments of {b}"
        elif missed:
            d = min(MISSED_DIRECTIONS, b)
            new, solved, what = 2 * d * m, b + d * m, f"krylov point {i} on the axis, {m} moments of ~{d} directions"
        else:
            new, solved, what = 2 * b * m, b * m, f"krylov point {i} on the axis, {m} moments of {b}"
        stages.append(Stage(what, n, i > 0, 1, 1 + solved, False, b))
        cols += max(new, 1)
        i += 1
    stages.append(Stage("krylov points check (estimate of the band error)", n, True, 2, 2 * (1 + b), False, b))
    return stages


def _eigen_stage(solver, what: str, n: int, k: int, k_iterative: int | None = None) -> list[Stage]:
    """The eigen solve of ``k`` pairs (``k_iterative`` under the iterative backends, where it differs)."""
    cols, block, method = _lanczos(solver, n, k)
    return [Stage(f"{what}: {method} {k} pairs", n, False, 0, cols, method == "dense", block,
                  _lobpcg(n, k if k_iterative is None else k_iterative, method))]


def _lobpcg(n: int, k: int, method: str) -> int | None:
    """The solved columns the ``amg`` backend's LOBPCG for ``k`` pairs costs (None where the eigen solve is
    dense)."""
    if method == "dense":
        return None
    return math.ceil(LOBPCG_COLUMNS_PER_COLUMN * min(n, k + guard_columns(k)))


def _interface(model, options, what: str) -> tuple[int, int]:
    """``(n_b, n_rigid)``: interface DOFs and the rigid-body modes a free body's basis excludes."""
    from .errors import OptionError

    if not options.get("interface"):
        raise OptionError(f"{what} needs interface SPECs (NODE, SET or SET:DIR)", params=("interface",))
    n_rb = rigid_body_modes(model).shape[1] if options.get("rigid", "exclude") == "exclude" else 0
    return int(interface_dofs(model, options["interface"]).size), int(n_rb)


def method_stages(model, method: str, order, ports, *, solver: SolverContext | None = None,
                  inertia_loads: str = "auto", **options) -> list[Stage] | None:
    """The solver stages of ``reduce`` (with the rigid-body check before it) for ``method`` at ``order``.

    Parameters
    ----------
    model : FEModel
    method : str
        A registered method (any case, or a short name).
    order : int or None
    ports : Ports
    solver : SolverContext, optional
        Its eigen policy decides dense, Lanczos or ARPACK.
    inertia_loads : {'auto', 'on', 'off'}
        As for :func:`flexmor.reduction.reduce` (the Krylov block grows by the inertia loads).
    **options
        The method's options (``points``, ``moments``, ``interface``, ``rigid`` ...).

    Returns
    -------
    list of Stage or None
        None for a method not in :data:`ESTIMATED_METHODS`.
    """
    from .reduction import methods

    solver = as_solver(solver)
    method = method_name(method)
    if method not in ESTIMATED_METHODS:
        return None
    n = model.n_dof
    sigma, shared = check_shift(model, method, options)
    stages = _rigid_check(model, solver, shared)
    if method == "krylov":
        basis_ports, _ = with_inertia_loads(model, ports, inertia_loads if methods()[method].uses_inputs else "off")
        return stages + _krylov(model, order, basis_ports, options, solver, shared)
    if method == "modal":
        room = options.get("rigid", "exclude") == "exclude"  # the iterative backends' LOBPCG may ask fewer pairs
        k = [min(n, int(order) + (room_for_rigid(model, it) if room else 0) + CLUSTER_MARGIN) for it in (False, True)]
        return stages + _eigen_stage(solver, "modal", n, k[0], k[1])
    n_b, n_rb = _interface(model, options, method)
    n_i = n - n_b
    if method == "guyan" and n_rb:  # a free body: inertia-relief modes from K - sigma M, refined per column
        return stages + [Stage(f"guyan inertia relief: {n_b} columns, refined", n, False, 1, 1 + 3 * n_b, False, n_b)]
    relief = method == "craig-bampton" and n_rb > 0
    low = n_b if relief or method == "guyan" else n_b - n_rb
    if method == "craig-bampton" and (order is None or order < low):
        from .errors import OptionError

        raise OptionError(f"{method} needs order >= number of interface DOFs ({low}), got {order}",
                          params=("order",))
    stages.append(Stage(f"{method} K_ii: {n_b} constraint modes", n_i, False, 1, 1 + n_b + (min(n_rb, 6) if relief
                                                                                              else 0), block=n_b))
    if method == "craig-bampton":
        n_modes = min(int(order) + (0 if relief else n_rb) - n_b, n_i)
        if n_modes > 0:
            stages += _eigen_stage(solver, "craig-bampton fixed-interface modes", n_i,
                                   min(n_i, n_modes + CLUSTER_MARGIN))
    return stages


def _grid_stage(model, n_freq: int, path: str) -> tuple[list[Stage], str]:
    """The error grid's solver work (:class:`flexmor.analysis.compare.FullResponse`): its path and, for
    direct solves, at least one factorization per base point."""
    damped = model.D is not None
    if path == "auto":
        exact_modal = isinstance(model.damping, ModalDamping) and dense_applicable(model)
        path = ("surrogate" if damped and model.n_dof >= SURROGATE_MIN_DOF and not exact_modal else
                "dense" if dense_applicable(model) else "direct")
    if path == "direct":  # undamped: K - w^2 M, real and indefinite
        return [Stage(f"error grid: {n_freq}+ frequencies (adaptive), K - w^2 M + i w D each", model.n_dof,
                      damped, n_freq, n_freq, False)], "direct: one factorization per grid frequency (its stage above)"
    if path == "dense":
        return [], "dense: one dense eigendecomposition (8 n^2 bytes), no sparse factorization"
    return [], "surrogate: a modal pre-pass and a few checking factorizations (not estimated)"


@dataclass
class Plan:
    """What a reduction will cost, per backend and memory mode (the record of ``flexmor plan``).

    Attributes
    ----------
    model : dict
        ``n_dof``, ``nnz_K``, ``damped``.
    method, order : str, int or None
    stages : list of Stage or None
        The solver work (None: the method is not estimated).
    grid : str
        How the error grid is computed.
    rows : list of dict
        Per backend and memory mode: ``backend``, ``mode``, ``available``, ``factor_bytes`` (the largest
        factorization), ``peak_bytes`` (with the matrices and vectors), ``factor_seconds``, ``solve_seconds``,
        ``total_seconds`` (None where not estimated), ``source``.
    auto : dict
        ``real`` and ``complex``: what ``auto`` takes (:func:`flexmor.linalg.plan.auto_choice`).
    memory : dict
        Bytes of the matrices and of the vectors counted in every row.
    calibration : str
        How the machine's rate was measured.
    seconds : float
        Wall time of the plan itself.
    """

    model: dict
    method: str
    order: int | None
    stages: list | None
    grid: str
    rows: list = field(default_factory=list)
    auto: dict = field(default_factory=dict)
    memory: dict = field(default_factory=dict)
    calibration: str = ""
    seconds: float = 0.0

    @property
    def factorizations(self) -> int | None:
        """Factorizations of the method and the rigid-body check (the error grid's not counted)."""
        return None if self.stages is None else sum(s.factorizations for s in self.stages if "error grid" not in s.what)

    @property
    def columns(self) -> int | None:
        """Right-hand sides of the method and the rigid-body check (the error grid's not counted)."""
        return None if self.stages is None else sum(s.columns for s in self.stages if "error grid" not in s.what)

    def to_dict(self) -> dict:
        """The plan as JSON values."""
        out = asdict(self)
        out.update(factorizations=self.factorizations, columns=self.columns)
        return out


def _row(est: BackendEstimate, mode: str, stages: list[Stage] | None, extra: float) -> dict:
    """One table row: the factor's bytes, the peak (with the ``extra`` bytes of matrices and vectors) and the
    times of ``stages`` with ``est`` in ``mode``."""
    row = {"backend": est.backend, "mode": mode, "available": est.available, "source": est.source,
           "factor_bytes": None, "peak_bytes": None, "factor_seconds": None, "solve_seconds": None,
           "total_seconds": None}
    kinds = {s.complex for s in stages or () if s.factorizations or s.columns}
    modes = {k: (est.complex if k else est.real).get(mode) for k in kinds or {False}}
    if any(m is None for m in modes.values()):
        return row
    row["factor_bytes"] = max((m.bytes for m in modes.values() if m.bytes is not None), default=None)
    row["peak_bytes"] = None if row["factor_bytes"] is None else row["factor_bytes"] + extra
    if stages is None or any(m.factor_seconds is None for m in modes.values()):
        return row
    count = sum(s.factorizations for s in stages)
    reused = max(count - 1, 0) * next(iter(modes.values())).analysis_seconds * (1 - REUSED_ANALYSIS)
    row["factor_seconds"] = sum(s.factorizations * modes[s.complex].factor_seconds for s in stages) - reused
    row["solve_seconds"] = sum(_columns(s, est) * modes[s.complex].column_seconds for s in stages)
    row["total_seconds"] = row["factor_seconds"] + row["solve_seconds"]
    return row


def _columns(stage: Stage, est: BackendEstimate) -> int:
    """The columns ``stage`` solves with ``est``'s backend (an eigen solve's LOBPCG under ``amg``)."""
    if est.backend == "amg" and stage.iterative_columns is not None:
        return stage.iterative_columns
    return stage.columns


def _calibration_text(est: BackendEstimate) -> str:
    """How ``est``'s rate was measured: the rows of its block(s), their seconds and the rate (PARDISO: each
    block's, and the one taken at the model's operations)."""
    c = est.calibration
    blocks = c.get("blocks", [])
    if len(blocks) > 1:
        rows = " and ".join(str(b["rows"]) for b in blocks)
        rates = " and ".join(f"{b['flops_per_second'] / 1e9:.1f}" for b in blocks)
        return (f"{est.backend}: {rows} rows in {c['seconds']:.3f} s, {rates} Gflop/s, "
                f"{c['flops_per_second'] / 1e9:.1f} at the model's {est.flops:.2g} operations")
    return f"{est.backend}: {c['rows']} rows in {c['seconds']:.3f} s, " + (
        f"{c['flops_per_second'] / 1e9:.2f} Gflop/s" if "flops_per_second" in c else
        f"{c['iterations']:.0f} CG iterations per solve")


def plan_reduction(model, method: str, order, ports, *, solver: SolverContext | None = None,
                   inertia_loads: str = "auto", judge: bool = True, n_freq: int = 50, full_frf: str = "auto",
                   rows: int = CALIBRATION_ROWS, **options) -> Plan:
    """The plan of reducing ``model`` with ``method`` at ``order``, without factorizing it.

    Parameters
    ----------
    model : FEModel
    method : str
    order : int or None
    ports : Ports
    solver : SolverContext, optional
        The backend and memory mode asked for and the memory available (``auto``'s choice is its).
    inertia_loads : {'auto', 'on', 'off'}
        As for :func:`flexmor.reduction.reduce`.
    judge : bool
        Count the error grid over the band (``flexmor reduce`` without ``--no-error``).
    n_freq : int
        Base points of the error grid.
    full_frf : {'auto', 'direct', 'dense', 'surrogate'}
        The error grid's path.
    rows : int
        Rows of the leading block of the model's matrix each backend factorizes to measure its rate (PARDISO
        a second one too, :data:`~flexmor.linalg.plan.CALIBRATION_SCALE` times as large).
    **options
        The method's options.

    Returns
    -------
    Plan
    """
    import time

    t0 = time.perf_counter()
    solver = as_solver(solver)
    method = method_name(method)
    stages = method_stages(model, method, order, ports, solver=solver, inertia_loads=inertia_loads, **options)
    grid = "not judged (no error grid)"
    if judge and stages is not None:
        extra, grid = _grid_stage(model, n_freq, full_frf)
        stages = stages + extra
    A = (model.K - default_shift(model.K, model.M) * model.M).tocsr()
    n = model.n_dof
    mats = sum(matrix_bytes(X.tocsr()) for X in (model.K, model.M, model.D, A) if X is not None)
    block = max((s.block for s in stages or ()), default=0)
    vectors = 8.0 * n * (BASIS_COPIES * (order or 0) + block)
    geometry = SolverContext()
    register_near_null(geometry, model)  # the rigid motions, for the amg backend's calibration
    estimates = estimate_backends(A, positive=True, rows=rows, available=solver.available(),
                                  near_null=near_null(geometry, n))
    out = Plan({"n_dof": n, "nnz_K": int(model.K.nnz), "damped": model.D is not None}, method,
               None if order is None else int(order), stages, grid,
               memory={"matrices": float(mats), "vectors": float(vectors)})
    for est in estimates:
        modes = list(est.real) or ["double"]
        out.rows += [_row(est, m, stages, mats + vectors) for m in modes]
    complex_needed = any(s.complex for s in stages or ())
    out.auto = {"real": auto_choice(solver, estimates, n, is_complex=False, positive=True)}
    if complex_needed:
        out.auto["complex"] = auto_choice(solver, estimates, n, is_complex=True, positive=False)
    cal = [_calibration_text(e) for e in estimates if e.calibration]
    out.calibration = ("factorized (amg: set up and solved) leading blocks of the model's matrix ("
                       + "; ".join(cal) + ")") if cal else ""
    out.seconds = time.perf_counter() - t0
    return out
