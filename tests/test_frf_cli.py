"""The full FRF in the command line: grid report, timings, disk cache and --no-cache."""


import pytest
from helpers import CLAMPED, run_json

ARGS = ["--input", "TIP:y", "--band", "50:2000", "--rayleigh", "0:1e-6", "--json"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("FLEXMOR_CACHE_DIR", str(d))
    return d


def test_reduce_reports_grid_and_hits_cache(capsys, tmp_path, cache):
    first = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "4", "-o", tmp_path / "a.h5", *ARGS)
    grid = first["grid"]
    assert grid["cache_hit"] is False and grid["path"] == "dense" and grid["converged"]
    assert grid["n_resonances"] == 8 and grid["tol"] == 3e-3 and grid["n_points"] > 100
    assert grid["n_factorizations"] == 0  # 270 DOF: one dense eigendecomposition, no sweep
    assert first["timings"]["full_frf"] > 0 and first["timings"]["error"] > 0  # both timed (speed: bench/)
    assert len(list(cache.glob("frf-*.npz"))) == 1
    second = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "6", "-o", tmp_path / "b.h5", *ARGS)
    assert second["grid"]["cache_hit"] is True and second["grid"]["n_points"] == grid["n_points"]
    # modal on 270 DOF is dense; the FRF came from the cache
    assert second["timings"]["factorize"] == 0.0 and second["grid"]["n_factorizations"] == 0
    cmp = run_json(capsys, "compare", CLAMPED, str(tmp_path / "a.h5"), str(tmp_path / "b.h5"), "--band", "50:2000",
                   "--json")
    assert [g["cache_hit"] for g in cmp["grids"]] == [True]
    assert [r["band_error"] for r in cmp["results"]] == [first["band_error"], second["band_error"]]


def test_no_cache_option(capsys, tmp_path, cache):
    out = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "4", "-o", str(tmp_path / "a.h5"),
                   "--no-cache", "--grid-tol", "1e-2", *ARGS)
    assert out["grid"]["cache_hit"] is False and out["grid"]["tol"] == 1e-2
    assert not cache.exists() or not list(cache.iterdir())
