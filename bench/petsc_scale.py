"""MUMPS through PETSc at scale: factorization time, fill and memory per rank, serial vs MPI.

Run under the MPI environment (``make test-mpi`` builds .venv-mpi), e.g.::

    .venv-mpi/bin/python bench/petsc_scale.py 14 21                  # one rank
    mpirun -n 2 .venv-mpi/bin/python bench/petsc_scale.py 14 21      # two ranks
    .venv-mpi/bin/python bench/petsc_scale.py 14 --no-modal          # factorization only
    mpirun -n 2 .venv-mpi/bin/python bench/petsc_scale.py 21 --backend petsc-gamg   # GAMG + CG instead
    mpirun -n 4 .venv-mpi/bin/python bench/petsc_scale.py 32 --backend petsc-gamg --no-modal --krylov 24

For each cantilever resolution ``n`` (14: 94,500 DOF, 21: 304,920 DOF) the model is built
partitioned (each rank assembles its own rows), ``K - sigma M`` is factorized once by MUMPS
(Cholesky) and ``modal`` with r = 20 runs on the model (SLEPc; skipped with ``--no-modal``). Rank 0 prints
one JSON line per model: DOF, nnz(K), factor entries (MUMPS INFOG(29)), MUMPS memory per rank (INFOG(21), largest) and
total (INFOG(22)), process peak memory per rank (VmHWM), factorization and modal wall times.

``--backend petsc-gamg``: the GAMG hierarchy of ``K - sigma M`` is set up instead (levels, operator
complexity, set-up time in ``factorize_s``), :data:`SOLVE_COLUMNS` random right-hand sides are solved by CG
to ``SOLVE_TOL`` (CG iterations per column, largest relative residual, solve time) and ``modal`` runs with
LOBPCG preconditioned by the GAMG V-cycle (its iterations).

``--krylov R``: a body to compare between rank counts, ``krylov`` of order ``R`` at the real point 0 Hz with the
inputs ``TIP:y`` and ``TIP:z`` (its seconds, CPU seconds per rank, lowest ten frequencies; CG iterations with GAMG).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from flexmor.linalg import SolverContext, factorize
from flexmor.linalg import distributed as dist
from flexmor.linalg.eigen import default_shift
from flexmor.models.distributed import partitioned_cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.rigid import register_near_null

#: Right-hand sides solved with the GAMG backend (one after the other, as its solves go).
SOLVE_COLUMNS = 3


def peak_mb() -> float:
    """Peak resident memory of this process (VmHWM) in MB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def one(n: int, modal: bool = True, backend: str = "petsc", krylov: int = 0) -> dict:
    t0 = time.perf_counter()
    model = partitioned_cantilever(n)
    t_build = time.perf_counter() - t0
    sigma = default_shift(model.K, model.M)
    solver = SolverContext(backend)
    register_near_null(solver, model)  # (the rigid-body motions: GAMG's near-null space)
    t0 = time.perf_counter()
    F = factorize((model.K - sigma * model.M).tocsr(), solver=solver, positive=True, check=False)
    t_fact = time.perf_counter() - t0
    row = {"n": n, "n_dof": model.n_dof, "ranks": dist.size(), "backend": backend, "nnz_K": model.K.global_nnz(),
           "build_s": t_build, "factorize_s": t_fact}
    if backend == "petsc":
        row.update(factor_entries=F.factor_entries, mumps_mb_per_rank_max=F.memory_per_rank / 1e6,
                   mumps_mb_total=F.memory_total / 1e6)
    else:
        B = np.random.default_rng(0).standard_normal((model.n_dof, SOLVE_COLUMNS))
        t0 = time.perf_counter()
        F.solve(B)
        st = solver.stats
        row.update(levels=F.levels, operator_complexity=F.operator_complexity, block=F.block,
                   solve_columns=SOLVE_COLUMNS, solve_s=time.perf_counter() - t0,
                   cg_iterations_per_column=st.iterations / SOLVE_COLUMNS, cg_iterations_max=st.iterations_max,
                   relative_residual_max=st.iterative_residual)
    del F
    if krylov:  # a body to compare between rank counts: krylov at the real point 0 Hz
        solver = SolverContext(backend)
        t0, c0 = time.perf_counter(), time.process_time()
        red = reduce(model, "krylov", krylov, make_ports(model, ["TIP:y", "TIP:z"]), solver=solver, points="0")
        row["krylov_order"], row["krylov_s"] = red.order, time.perf_counter() - t0
        cpus = dist.comm().allgather(time.process_time() - c0) if dist.size() > 1 else [time.process_time() - c0]
        row["krylov_cpu_s_per_rank"] = cpus
        row["krylov_frequencies_hz"] = red.frequencies_hz()[:10].tolist()
        if backend != "petsc":
            row["krylov_cg_iterations"] = solver.stats.iterations
    if modal:
        solver = SolverContext(backend)
        t0 = time.perf_counter()
        reduce(model, "modal", 20, make_ports(model, ["TIP:y"]), solver=solver)
        row["modal20_s"] = time.perf_counter() - t0
        if backend != "petsc":
            row["lobpcg_iterations"] = solver.stats.eigen_iterations
    peaks = dist.comm().allgather(peak_mb()) if dist.size() > 1 else [peak_mb()]
    row["peak_mb_per_rank"] = peaks
    return row


def main(argv) -> int:
    modal = "--no-modal" not in argv
    backend = argv[argv.index("--backend") + 1] if "--backend" in argv else "petsc"
    krylov = int(argv[argv.index("--krylov") + 1]) if "--krylov" in argv else 0
    values = {backend, str(krylov)}
    for n in (int(a) for a in argv if not a.startswith("--") and a not in values):
        row = one(n, modal, backend, krylov)
        if dist.is_root():
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
