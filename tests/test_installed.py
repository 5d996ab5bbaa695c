"""The package as installed: its entry points answer, and every package-data file that pyproject.toml
declares is inside it. ``make test-wheel`` runs this file (and the tests that use each data file)
against the wheel installed in a clean environment, with ``FLEXMOR_TEST_INSTALLED=1``."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from importlib import resources
from pathlib import Path

import pytest

import flexmor

ROOT = Path(__file__).resolve().parents[1]


def _package_data() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return config["tool"]["setuptools"]["package-data"]["flexmor"]


def test_every_declared_data_file_is_in_the_package():
    root = resources.files("flexmor")
    for pattern in _package_data():
        folder, _, glob = pattern.rpartition("/")
        found = list(Path(str(root.joinpath(folder))).glob(glob))
        assert found, f"{pattern} (pyproject.toml package-data) is not in the installed package at {root}"
        assert all(p.stat().st_size > 0 for p in found), pattern
    assert (ROOT / "src" / "flexmor" / "io" / "fmu_runtime.c").exists()  # (the list names real files)


def test_the_entry_points_give_the_version():
    script = Path(sys.executable).with_name("flexmor")
    assert script.exists(), f"no flexmor script beside {sys.executable}: the package is not installed with its scripts"
    for argv in ([str(script), "--version"], [sys.executable, "-m", "flexmor", "--version"]):
        out = subprocess.run(argv, capture_output=True, text=True, timeout=120, cwd=ROOT.parent)
        assert out.returncode == 0 and out.stdout.strip() == f"flexmor {flexmor.__version__}", (argv, out.stderr)


@pytest.mark.skipif(os.environ.get("FLEXMOR_TEST_INSTALLED") != "1", reason="the wheel's run only (make test-wheel)")
def test_the_wheel_is_what_runs():
    here = Path(flexmor.__file__).resolve()
    assert ROOT / "src" not in here.parents, f"flexmor imported from the source tree ({here}), not the wheel"
    assert "site-packages" in here.parts
