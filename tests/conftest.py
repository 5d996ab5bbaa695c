"""Shared fixtures: the real CalculiX beam exports in tests/data, their reference values and a
reduced body of the free beam. Plain functions and paths are in ``helpers.py``."""

from __future__ import annotations

import pytest
from helpers import CCX, calculix_frequencies


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


@pytest.fixture(scope="module")
def body(free):
    """``(reduced, model)``: a modal body of order 6 of the free beam with Rayleigh damping
    (alpha 2, beta 1e-6), one input and output at TIP:y."""
    from flexmor.ports import make_ports
    from flexmor.reduction import reduce

    model = free.with_rayleigh(2.0, 1e-6)
    red = reduce(model, "modal", 6, make_ports(model, ["TIP:y"]))
    return red, model


@pytest.fixture(scope="session", autouse=True)
def _hermetic_frf_cache(tmp_path_factory):
    """Every test writes the full-FRF disk cache into a temporary directory, never ~/.cache.

    Session-scoped, so that module- and session-scoped fixtures are covered too (a function-scoped
    one is set up after them: their entries went to the user's cache and outlived the run).
    """
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("FLEXMOR_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "flexmor-cache"))
        yield


@pytest.fixture
def auto_unrestricted(monkeypatch):
    """``backend="auto"`` chooses from every available backend, also in a run that restricts it
    (``make test-arith`` sets ``FLEXMOR_AUTO_BACKENDS``): for tests of what ``auto`` picks."""
    from flexmor.linalg.context import AUTO_BACKENDS_VARIABLE

    monkeypatch.delenv(AUTO_BACKENDS_VARIABLE, raising=False)
