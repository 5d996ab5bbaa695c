"""Reproducibility: the same input and options give bit-identical reduced bodies, in the same
process and in fresh ones; every body records the flexmor version and the options it was made
with. Also the mechanism check that runs before every reduction."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import h5py
import numpy as np
import pytest
from helpers import CLAMPED, DATA, FREE

import flexmor
from flexmor.checks import check_rigid_body_modes
from flexmor.cli import main
from flexmor.errors import FlexmorWarning, ModelError
from flexmor.io import read
from flexmor.linalg.eigen import eigenmodes
from flexmor.ports import make_ports
from flexmor.reduction import reduce

#: method -> extra options; the orders keep every method cheap on the 270-DOF beam
METHODS = {"modal": ["--order", "8"], "krylov": ["--order", "8"], "irka": ["--order", "8"],
           "fw-sobt": ["--order", "8"], "pod": ["--order", "8"], "two-step": ["--order", "8", "--intermediate", "30"],
           "craig-bampton": ["--order", "33", "--interface", "TIP"]}
_RUN = """
import sys
from flexmor.cli import main
out, model = sys.argv[1], sys.argv[2]
for arg in sys.argv[3:]:
    method, *extra = arg.split()
    argv = ["reduce", model, "--method", method, "--input", "TIP:y", "--no-error", "--band", "10:3000",
            "--rayleigh", "2:1e-6", "-o", f"{out}/{method}.h5", *extra]
    assert main(argv) == 0, method
"""
DATASETS = ("M", "K", "D", "B", "C", "V")


def _run(folder):
    args = [" ".join([m, *extra]) for m, extra in METHODS.items()]
    subprocess.run([sys.executable, "-c", _RUN, str(folder), CLAMPED, *args], check=True, capture_output=True,
                   timeout=600)
    out = {}
    for m in METHODS:
        with h5py.File(folder / f"{m}.h5") as h:
            out[m] = ({k: h[k][()].tobytes() for k in DATASETS if k in h}, dict(h.attrs))
    return out


@pytest.mark.slow
def test_same_reduction_in_fresh_processes_gives_identical_bytes(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = _run(tmp_path / "a"), _run(tmp_path / "b")
    for m in METHODS:
        arrays_a, attrs = a[m]
        assert set(arrays_a) == set(DATASETS), m
        assert arrays_a == b[m][0], f"{m}: reduced matrices differ between runs"
        # the body says how it was made: version, method, options
        assert attrs["version"] == flexmor.__version__ and attrs["method"] == m
        info = json.loads(attrs["info"])
        assert info["order_requested"] == int(METHODS[m][1])
        opts = info["options"]
        assert opts["backend"] == "auto"
        if m in ("krylov", "irka", "fw-sobt", "pod", "two-step"):
            assert opts["band"] == [10.0, 3000.0], (m, opts)  # --band reaches the method with --no-error
    assert json.loads(a["two-step"][1]["info"])["options"]["intermediate"] == 30
    assert json.loads(a["craig-bampton"][1]["info"])["options"]["interface"] == ["TIP"]


@pytest.mark.parametrize("method", ["arpack", "lanczos"])
def test_iterative_eigensolvers_repeat_bit_for_bit_in_one_process(clamped, method):
    lam1, phi1 = eigenmodes(clamped.K, clamped.M, 8, method=method)
    lam2, phi2 = eigenmodes(clamped.K, clamped.M, 8, method=method)
    assert lam1.tobytes() == lam2.tobytes() and phi1.tobytes() == phi2.tobytes()
    assert lam1[0] == pytest.approx((2 * np.pi * 100.046) ** 2, rel=1e-5)


@pytest.mark.parametrize("method", ["modal", "krylov", "irka", "pod"])
def test_same_reduction_twice_in_one_process(clamped, method):
    model = clamped.with_rayleigh(2.0, 1e-6)
    ports = make_ports(model, ["TIP:y"])
    r1 = reduce(model, method, 6, ports)
    r2 = reduce(model, method, 6, ports)
    for k in DATASETS:
        assert getattr(r1, k).tobytes() == getattr(r2, k).tobytes(), k


# -- mechanisms and free bodies ----------------------------------------------------------------
def test_mechanism_is_refused_by_every_method():
    model = read(DATA / "bad" / "ccx_mechanism.sti")
    ports = make_ports(model, ["TIP:y"])
    with pytest.raises(ModelError, match="at least 7 zero-energy modes .* mechanism"):
        check_rigid_body_modes(model)
    with pytest.raises(ModelError, match="mechanism"):
        reduce(model, "modal", 1, ports)  # modal finds the zero modes itself


@pytest.mark.parametrize("method", ["krylov", "pod", "adaptive", "irka"])
def test_mechanism_refused_on_the_command_line(method, tmp_path, capsys):
    out = tmp_path / "body.h5"
    argv = ["reduce", str(DATA / "bad" / "ccx_mechanism.sti"), "--method", method, "--order", "2", "--input",
            "TIP:y", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("flexmor: error: ") and "ccx_mechanism.sti" in err and "the model is a mechanism" in err
    assert not out.exists()


def test_free_body_is_legal_with_a_warning(free, tmp_path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert check_rigid_body_modes(free) == 6
    assert any(issubclass(w.category, FlexmorWarning) and "6 rigid-body modes" in str(w.message) for w in caught)
    out = tmp_path / "free.h5"
    assert main(["reduce", FREE, "--method", "modal", "--order", "4", "--input", "TIP:y",
                 "--no-error", "-o", str(out)]) == 0
    assert out.exists()


def test_clamped_body_has_no_rigid_body_modes_and_no_warning(clamped):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_rigid_body_modes(clamped) == 0
