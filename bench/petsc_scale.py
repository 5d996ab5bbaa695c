"""MUMPS through PETSc at scale: factorization time, fill and memory per rank, serial vs MPI.

Run under the MPI environment (``make test-mpi`` builds .venv-mpi), e.g.::

    .venv-mpi/bin/python bench/petsc_scale.py 14 21                  # one rank
    mpirun -n 2 .venv-mpi/bin/python bench/petsc_scale.py 14 21      # two ranks
    .venv-mpi/bin/python bench/petsc_scale.py 14 --no-modal          # factorization only

For each cantilever resolution ``n`` (14: 94,500 DOF, 21: 304,920 DOF) the model is built
partitioned (each rank assembles its own rows), ``K - sigma M`` is factorized once by MUMPS
(Cholesky) and ``modal`` with r = 20 runs on the model (SLEPc; skipped with ``--no-modal``). Rank 0 prints one JSON line per model:
DOF, nnz(K), factor entries (MUMPS INFOG(29)), MUMPS memory per rank (INFOG(21), largest) and
total (INFOG(22)), process peak memory per rank (VmHWM), factorization and modal wall times.
"""

from __future__ import annotations

import json
import sys
import time

from flexmor.linalg import SolverContext, factorize
from flexmor.linalg import distributed as dist
from flexmor.linalg.eigen import default_shift
from flexmor.models.distributed import partitioned_cantilever
from flexmor.ports import make_ports
from flexmor.reduction import reduce


def peak_mb() -> float:
    """Peak resident memory of this process (VmHWM) in MB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def one(n: int, modal: bool = True) -> dict:
    t0 = time.perf_counter()
    model = partitioned_cantilever(n)
    t_build = time.perf_counter() - t0
    sigma = default_shift(model.K, model.M)
    t0 = time.perf_counter()
    F = factorize((model.K - sigma * model.M).tocsr(), solver=SolverContext("petsc"), positive=True, check=False)
    t_fact = time.perf_counter() - t0
    row = {"n": n, "n_dof": model.n_dof, "ranks": dist.size(), "nnz_K": model.K.global_nnz(),
           "factor_entries": F.factor_entries, "mumps_mb_per_rank_max": F.memory_per_rank / 1e6,
           "mumps_mb_total": F.memory_total / 1e6, "build_s": t_build, "factorize_s": t_fact}
    del F
    if modal:
        t0 = time.perf_counter()
        reduce(model, "modal", 20, make_ports(model, ["TIP:y"]), solver=SolverContext("petsc"))
        row["modal20_s"] = time.perf_counter() - t0
    peaks = dist.comm().allgather(peak_mb()) if dist.size() > 1 else [peak_mb()]
    row["peak_mb_per_rank"] = peaks
    return row


def main(argv) -> int:
    modal = "--no-modal" not in argv
    for n in (int(a) for a in argv if not a.startswith("--")):
        row = one(n, modal)
        if dist.is_root():
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
