"""Plain functions and paths the tests share: the data folders, the CalculiX beam models, the
command-line runners and a few numerical checks. Fixtures live in ``conftest.py``."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

#: the test data in this repository, one folder per format family
DATA = Path(__file__).parent / "data"
#: the CalculiX beam exports (C3D8, 10x2x2 elements, 270 DOF clamped / 297 DOF free) and their ``.dat`` files
CCX = DATA / "calculix"
#: the larger sample files next to the repository (``../shared/data``), absent in some checkouts
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
#: the clamped and the free beam stiffness exports, as the command line takes them
CLAMPED = str(CCX / "beam8_clamped_mat.sti")
FREE = str(CCX / "beam8_free_mat.sti")
#: the repository root (examples/ and bench/ scripts)
ROOT = Path(__file__).resolve().parents[1]


def calculix_frequencies(dat_path) -> np.ndarray:
    """Eigenfrequencies (Hz) that CalculiX wrote into its ``.dat`` file (CYCLES/TIME column)."""
    text = Path(dat_path).read_text()
    block = text.split("E I G E N V A L U E   O U T P U T")[1].split("P A R T I C I P A T I O N")[0]
    rows = [ln.split() for ln in block.splitlines() if re.match(r"^\s+\d+\s+[-\d.]", ln)]
    return np.array([float(r[3]) for r in rows])


def run(capsys, *argv) -> tuple[int, str, str]:
    """Run ``flexmor`` in-process with ``argv`` (each turned into ``str``): exit code, stdout, stderr."""
    from flexmor.cli import main

    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def run_json(capsys, *argv) -> dict:
    """Run ``flexmor`` with ``--json`` (added when absent), require exit code 0 and return the parsed stdout."""
    if "--json" not in argv:
        argv = (*argv, "--json")
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    return json.loads(out)


def cond1(A) -> float:
    """Estimate of the 1-norm condition number of a sparse symmetric ``A`` (Higham-Tisseur
    ``onenormest`` of ``A`` and of ``A^-1`` applied through one factorization): the factor by
    which a backward-stable solve may magnify round-off, used to justify solver tolerances."""
    import scipy.sparse.linalg as spla

    from flexmor.linalg import SolverContext, factorize

    solve = factorize(A.tocsr(), solver=SolverContext("scipy"), check=False).solve
    # A symmetric (real or complex): A^H x = conj(A^-1 conj(x))
    inv = spla.LinearOperator(A.shape, matvec=solve, rmatvec=lambda x: np.conj(solve(np.conj(x))), dtype=A.dtype)
    return float(spla.onenormest(A) * spla.onenormest(inv))


def load_script(path: Path | str, name: str | None = None):
    """Import the script at ``path`` (examples/ and bench/ are scripts, not packages) as the module
    ``name`` (default: the file's stem), registered in ``sys.modules`` so that dataclasses find it."""
    path = Path(path)
    spec = importlib.util.spec_from_file_location(name or path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def load_example(name: str):
    """Import ``examples/NAME.py`` as a module."""
    return load_script(ROOT / "examples" / f"{name}.py", name)


def geometric_rigid_modes(model, about=None) -> np.ndarray:
    """The ``(n_dof, 6)`` rigid-body motions at the equations of a model with translational DOFs
    only: translations x y z, then rotations about the x y z axes through ``about`` (default: the
    origin), built from the node coordinates and the equation map alone."""
    n = model.n_dof
    xyz = model.node_xyz(model.dofs[:, 0])
    if about is not None:
        xyz = xyz - np.asarray(about, dtype=float)
    d = model.dofs[:, 1] - 1
    R = np.zeros((n, 6))
    for j in range(3):
        R[d == j, j] = 1.0
        R[:, 3 + j] = np.cross(np.eye(3)[j], xyz)[np.arange(n), d]  # u = e_j x r at each equation's node
    return R


def solve_exudyn(mbs, sensor, end_time: float, steps: int):
    """Assemble ``mbs``, integrate it quietly to ``end_time`` in ``steps`` steps (Exudyn's default implicit
    scheme, no solution file, the sensor stored every step) and return the stored data of ``sensor``."""
    import exudyn as exu

    mbs.Assemble()
    s = exu.SimulationSettings()
    s.timeIntegration.endTime, s.timeIntegration.numberOfSteps = end_time, steps
    s.timeIntegration.verboseMode = 0
    s.solution.file.write = False
    s.solution.sensors.writePeriod = end_time / steps
    mbs.SolveDynamic(s)
    return mbs.GetSensorStoredData(sensor)


@contextmanager
def fmu_instance(path, kind: str = "cs"):
    """An initialized fmpy instance of the FMU at ``path`` (``kind`` ``"cs"`` co-simulation, ``"me"`` model
    exchange) and its value references by name; terminated and freed on leaving."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Model, FMU2Slave

    md = read_model_description(str(path))
    cls, interface = (FMU2Slave, md.coSimulation) if kind == "cs" else (FMU2Model, md.modelExchange)
    inst = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=interface.modelIdentifier,
               instanceName="body")
    inst.instantiate()
    try:
        inst.setupExperiment(startTime=0.0)
        inst.enterInitializationMode()
        inst.exitInitializationMode()
        yield inst, {v.name: v.valueReference for v in md.modelVariables}
        inst.terminate()
    finally:
        inst.freeInstance()
