"""Shared fixtures: the real CalculiX beam exports in tests/data and their reference values."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
CCX = DATA / "calculix"


def calculix_frequencies(dat_path) -> np.ndarray:
    """Eigenfrequencies (Hz) that CalculiX wrote into its ``.dat`` file (CYCLES/TIME column)."""
    text = Path(dat_path).read_text()
    block = text.split("E I G E N V A L U E   O U T P U T")[1].split("P A R T I C I P A T I O N")[0]
    rows = [ln.split() for ln in block.splitlines() if re.match(r"^\s+\d+\s+[-\d.]", ln)]
    return np.array([float(r[3]) for r in rows])


@pytest.fixture(scope="session")
def clamped():
    from flexmor.io import read

    return read(CCX / "beam8_clamped_mat.sti")


@pytest.fixture(scope="session")
def free():
    from flexmor.io import read

    return read(CCX / "beam8_free_mat.sti")


@pytest.fixture(scope="session")
def clamped_ref():
    return calculix_frequencies(CCX / "beam8_clamped_freq.dat")


@pytest.fixture(scope="session")
def free_ref():
    return calculix_frequencies(CCX / "beam8_free_freq.dat")


@pytest.fixture(scope="session", autouse=True)
def _hermetic_frf_cache(tmp_path_factory):
    """Every test writes the full-FRF disk cache into a temporary directory, never ~/.cache.

    Session-scoped, so that module- and session-scoped fixtures are covered too (a function-scoped
    one is set up after them: their entries went to the user's cache and outlived the run).
    """
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("FLEXMOR_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "flexmor-cache"))
        yield


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


def load_example(name: str):
    """Import ``examples/NAME.py`` as a module (the examples are scripts, not a package)."""
    import importlib.util

    path = Path(__file__).parents[1] / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
