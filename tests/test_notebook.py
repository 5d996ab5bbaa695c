"""A study in a notebook: short reprs and small HTML tables of a model, a study, a body and its
errors; the full FRF's disk cache is bounded, its oldest entries go first, and it can be turned off."""

from __future__ import annotations

import os
import re
import time

import numpy as np
import pytest

import flexmor
from flexmor.analysis import cache as frf_cache
from flexmor.analysis.compare import FullResponse
from flexmor.display import MAX_REPR_LINES, text_repr


@pytest.fixture(scope="module")
def study(clamped):
    system = flexmor.System(clamped, inputs=["TIP:y"], outputs=["TIP:y", "TIP:z"], band=(10, 2000))
    body = system.reduce("krylov", 6)
    return system, body, system.judge(body)


def test_reprs_are_short_and_say_what_it_is(study, clamped):
    system, body, err = study
    shown = [(clamped, ["'beam8_clamped_mat': 270 DOF, 99 nodes", "TIP"]),
             (system, ["270 DOF", "TIP:y", "TIP:z", "10-2000 Hz"]),
             (body, ["krylov", "order 6", "TIP:y"]),
             (err, [f"band_error {err.band_error:.3g}", "10-2000 Hz", "judged full response"])]
    for obj, words in shown:
        text = repr(obj)
        assert len(text.splitlines()) <= MAX_REPR_LINES and len(text) < 400, text
        assert text.startswith(f"<{type(obj).__name__} ") and all(w in text for w in words), text
        assert "array(" not in text and "0.0000" not in text


def test_html_tables_are_small_and_escaped(study, clamped):
    system, body, err = study
    for obj in (clamped, system, body, err):
        page = obj._repr_html_()
        assert page.startswith("<table>") and page.endswith("</table>") and len(page) < 3000
        assert page.count("<tr>") >= 3 and "array(" not in page
    f = body.frequencies_hz()
    assert f"{f[0]:.4g}" in body._repr_html_()
    assert "&lt;b&gt;" in flexmor.display.html_table("X", "<b>", [("a<", "1")]) and "a&lt;" in \
        flexmor.display.html_table("X", "<b>", [("a<", "1")])


def test_text_repr_keeps_three_lines_for_many_facts():
    rows = [(f"k{i}", "v" * 100) for i in range(20)]
    text = text_repr("Thing", "head", rows)
    assert len(text.splitlines()) == MAX_REPR_LINES and all(len(ln) < 40 * 72 for ln in text.splitlines())
    assert "k0 " in text and "..." in text  # long facts are clipped


def test_body_repr_says_when_an_iteration_did_not_converge(clamped):
    damped = flexmor.System(clamped.with_rayleigh(1.0, 1e-6), inputs=["TIP:y"])
    body = damped.reduce("irka", 20, max_iter=2)  # two iterations cannot settle 10 points
    assert body.info["converged"] is False and "converged no" in repr(body)


# -- the FRF cache ------------------------------------------------------------------------------------------------
def _entry(directory, key: str, n: int, age: float):
    f = np.linspace(1.0, 2.0, n)
    path = frf_cache.store(key, f, np.ones((n, 1, 1)), [], [], {"n": n}, directory, limit=10 ** 9)
    os.utime(path, (time.time() - age, time.time() - age))
    return path


def test_cache_keeps_the_newest_within_its_bound(tmp_path):
    old, mid, new = (_entry(tmp_path, k, 200, age) for k, age in (("a" * 40, 300), ("b" * 40, 200), ("c" * 40, 100)))
    (tmp_path / "notes.txt").write_text("not the cache's")  # other files are neither counted nor removed
    size = old.stat().st_size
    assert frf_cache.load("a" * 40, (1, 1), tmp_path) is not None  # a hit: 'a' is now the newest
    removed = frf_cache.prune(tmp_path, 2 * size + size // 2)
    assert removed == [mid] and old.exists() and new.exists() and (tmp_path / "notes.txt").exists()
    # a write prunes by itself: with room for two entries, the oldest one goes
    path = frf_cache.store("d" * 40, np.linspace(1, 2, 200), np.ones((200, 1, 1)), [], [], {}, tmp_path,
                           limit=2 * size + size // 2)
    assert path.exists() and not new.exists() and old.exists()
    # an entry larger than the bound is not kept
    assert frf_cache.store("e" * 40, np.linspace(1, 2, 200), np.ones((200, 1, 1)), [], [], {}, tmp_path,
                           limit=size // 2) is None
    assert not list(tmp_path.glob("frf-*.npz"))


def test_cache_bound_from_the_environment(monkeypatch, caplog):
    monkeypatch.delenv(frf_cache.MAX_MB_ENV, raising=False)
    assert frf_cache.max_bytes() == int(frf_cache.DEFAULT_MAX_MB * 1e6)
    monkeypatch.setenv(frf_cache.MAX_MB_ENV, "1.5")
    assert frf_cache.max_bytes() == 1_500_000
    monkeypatch.setenv(frf_cache.MAX_MB_ENV, "lots")
    assert frf_cache.max_bytes() == int(frf_cache.DEFAULT_MAX_MB * 1e6)
    assert re.search(r"FLEXMOR_CACHE_MAX_MB='lots' is not a size", caplog.text)


def test_cache_turned_off_by_a_zero_bound(clamped, tmp_path, monkeypatch):
    from flexmor.ports import make_ports

    ports = make_ports(clamped, ["TIP:y"])
    monkeypatch.setenv("FLEXMOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(frf_cache.MAX_MB_ENV, "0")
    FullResponse(clamped, ports, (100.0, 700.0))
    assert not FullResponse(clamped, ports, (100.0, 700.0)).cache_hit and not list(tmp_path.iterdir())
    monkeypatch.setenv(frf_cache.MAX_MB_ENV, "100")
    FullResponse(clamped, ports, (100.0, 700.0))
    assert FullResponse(clamped, ports, (100.0, 700.0)).cache_hit and len(list(tmp_path.glob("frf-*.npz"))) == 1


def test_cache_is_documented_where_users_look():
    for doc in (flexmor.System.__doc__, FullResponse.__doc__, frf_cache.__doc__):
        assert "~/.cache/flexmor" in doc and "FLEXMOR_CACHE_MAX_MB" in doc and "FLEXMOR_CACHE_DIR" in doc
    assert "cache=False" in flexmor.System.__doc__ and "cache=False" in FullResponse.__doc__
