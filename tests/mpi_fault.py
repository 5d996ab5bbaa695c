"""MPI driver of tests/test_petsc.py: the ``flexmor`` command line with a fault on one rank only.

Run as ``mpirun -n 2 python tests/mpi_fault.py RANK KIND flexmor-arguments...``: on rank ``RANK``
:func:`flexmor.checks.stable_lowest_eigenvalues` (the first eigen solve of ``info --modes`` and of
``reduce``) raises before it starts, while the other ranks go on into the collective operations that
follow (reductions over the rows of ``M`` and ``K``, or the distributed solve itself) and wait there
for that rank. ``KIND`` is ``model`` (a :class:`flexmor.errors.ModelError`, as
for a bad model) or ``bug`` (a ``RuntimeError``, as a programming error would raise).
"""

from __future__ import annotations

import sys

import flexmor.checks
from flexmor.cli import main
from flexmor.errors import ModelError
from flexmor.linalg import distributed as dist

#: Text of the raised error, looked for in the job's stderr.
FAULT = "fault raised on rank"


def _broken(kind: str):
    def lowest(*args, **kwargs):
        text = f"{FAULT} {dist.rank()} only"
        raise ModelError(text) if kind == "model" else RuntimeError(text)

    return lowest


def run(argv) -> int:
    rank, kind, *cli = argv
    if kind not in ("model", "bug"):
        raise SystemExit(f"KIND must be model or bug, got {kind!r}")
    if dist.rank() == int(rank):
        flexmor.checks.stable_lowest_eigenvalues = _broken(kind)
    return main(cli)


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
