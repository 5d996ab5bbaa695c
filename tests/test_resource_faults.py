"""A machine that runs short: memory (the address-space limit), a full disk (the file-size limit)
and SIGKILL. Each ends in one ``flexmor: error:`` line with exit code 1, or leaves a complete file:
never a traceback, a signal death, or a half-written output."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import scipy.io
from helpers import CLAMPED, FREE

import flexmor
from flexmor.errors import OutOfMemoryError
from flexmor.linalg import SolverContext

PY = sys.executable


def _limited(argv, *, cwd, address_space=None, file_size=None, timeout=300):
    """Run ``python -m flexmor argv`` with the given soft limits (bytes); the CompletedProcess."""

    def limits():
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (int(address_space), resource.RLIM_INFINITY))
        if file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (int(file_size), resource.RLIM_INFINITY))

    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    return subprocess.run([PY, "-m", "flexmor", *map(str, argv)], cwd=cwd, preexec_fn=limits, env=env,
                          capture_output=True, text=True, timeout=timeout, check=False)


def _one_error_line(proc) -> str:
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-3000:])
    assert "Traceback" not in proc.stderr and "Fatal Python error" not in proc.stderr, proc.stderr[-3000:]
    errors = [ln for ln in lines if ln.startswith("flexmor: error:")]
    assert len(errors) == 1 and lines[-1] == errors[0], proc.stderr[-3000:]
    return errors[0]


def test_a_basis_that_cannot_fit_is_refused_before_any_work(clamped):
    ports = flexmor.make_ports(clamped, ["TIP:y"])
    with pytest.raises(OutOfMemoryError, match=r"order 200 for 270 equations needs about \d+ MB .* order (\d+) or "
                                               r"less would fit"):
        flexmor.reduce(clamped, "krylov", 200, ports, solver=SolverContext(memory_limit=1e6))


def test_memory_limits_count_the_address_space_limit():
    code = ("import resource; from flexmor.linalg.resources import memory_limits, memory_available, describe_memory;"
            "resource.setrlimit(resource.RLIMIT_AS, (2**36, resource.RLIM_INFINITY));"
            "lim = memory_limits(); print(lim['address_space'] <= 2**36, memory_available() <= lim['address_space'],"
            " 'ulimit -v' in describe_memory() or lim['machine'] < lim['address_space'])")
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "True"]


@pytest.fixture(scope="module")
def big_model(tmp_path_factory):
    """A 19,440-DOF clamped solid beam as a MATLAB file with its own ports (B, C: tip force and displacement)."""
    from flexmor.models import cantilever

    folder = tmp_path_factory.mktemp("big")
    m = cantilever(n=8)
    p = flexmor.make_ports(m, ["TIP:y"])
    scipy.io.savemat(folder / "beam.mat", {"M": m.M, "K": m.K, "B": p.B, "C": p.C})
    return folder / "beam.mat"


@pytest.fixture(scope="module")
def baseline(tmp_path_factory):
    """Peak address space of a flexmor process that has loaded its solver libraries (bytes)."""
    code = ("import numpy as np, flexmor; from flexmor.linalg import factorize; from flexmor.models import cantilever;"
            "m = cantilever(n=2); factorize(m.K).solve(np.ones(m.n_dof));"
            "print([int(l.split()[1]) for l in open('/proc/self/status') if l.startswith('VmPeak')][0] * 1024)")
    return int(subprocess.run([PY, "-c", code], capture_output=True, text=True, check=True).stdout)


@pytest.mark.parametrize("margin_mb,order,says", [(40, 40, "before starting"), (400, 1000, "or less would fit")])
def test_a_job_under_an_address_space_limit_stops_with_one_line(big_model, baseline, tmp_path, margin_mb, order,
                                                                says):
    """An address-space limit (ulimit -v) too tight for any job (40 MB beyond what a process with its
    solver libraries maps), or for this job's basis (order 1000 of 19,440 equations: 622 MB): one
    line naming the memory needed and available and the limit that bounds it, exit 1, no file."""
    proc = _limited(["reduce", big_model, "--method", "krylov", "--order", order, "--no-error", "-o", "k.h5"],
                    cwd=tmp_path, address_space=baseline + margin_mb * 2**20)
    line = _one_error_line(proc)
    assert says in line and "address-space limit (ulimit -v)" in line and "MB" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_with_room_the_same_job_runs(big_model, tmp_path):
    rec = run_json_subprocess(["reduce", big_model, "--method", "krylov", "--order", "10", "--no-error",
                               "-o", tmp_path / "k.h5"], tmp_path)
    assert rec["order"] == 10 and (tmp_path / "k.h5").exists()


def run_json_subprocess(argv, cwd):
    import json

    proc = _limited([*argv, "--json"], cwd=cwd)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def bodies(tmp_path_factory):
    """A free body (krylov 8, Rayleigh) and its model, for the exporters."""
    import warnings

    folder = tmp_path_factory.mktemp("bodies")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = flexmor.System(FREE, inputs=["TIP:y"], band=(10, 3000), damping=flexmor.damping.Rayleigh(0, 1e-6),
                           cache=False)
        flexmor.io.write_body(s.reduce("krylov", 8), folder / "k.h5")
    return folder


EXPORTS = [("body.SID_FEM", ["--model", FREE]), ("body.exudyn.npz", ["--model", FREE]), ("body.mat", []),
           ("body.ss.npz", []), ("body.vtu", ["--model", FREE])]


@pytest.mark.parametrize("name,extra", EXPORTS, ids=[e[0] for e in EXPORTS])
def test_a_full_disk_ends_every_export_with_one_line_and_no_file(bodies, tmp_path, name, extra):
    proc = _limited(["export", bodies / "k.h5", "-o", tmp_path / name, *extra], cwd=tmp_path, file_size=2048)
    line = _one_error_line(proc)
    assert f"cannot write {tmp_path / name}: file too large" in line and "ulimit -f" in line
    assert list(tmp_path.iterdir()) == []  # neither the file nor its temporary file


def test_a_full_disk_ends_reduce_and_report_with_one_line_and_no_file(bodies, tmp_path):
    proc = _limited(["reduce", CLAMPED, "--method", "krylov", "--order", "8", "--input", "TIP:y", "--no-cache",
                     "-o", tmp_path / "k.h5"], cwd=tmp_path, file_size=4096)
    assert "cannot write" in _one_error_line(proc) and list(tmp_path.iterdir()) == []
    proc = _limited(["report", FREE, bodies / "k.h5", "--rayleigh", "0:1e-6", "--no-cache", "--modes", "4",
                     "-o", tmp_path / "r.html"], cwd=tmp_path, file_size=4096)
    assert "cannot write" in _one_error_line(proc) and list(tmp_path.iterdir()) == []


def test_a_write_without_permission_names_the_file(bodies, tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root may write anywhere: no permission to refuse")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    proc = _limited(["export", bodies / "k.h5", "-o", locked / "b.mat"], cwd=tmp_path)
    assert "permission denied" in _one_error_line(proc)


@pytest.mark.slow
def test_sigkill_at_any_moment_leaves_no_file_or_a_complete_one(tmp_path):
    """reduce killed at random moments over its run: the output path holds nothing or the whole body."""
    argv = [PY, "-m", "flexmor", "reduce", CLAMPED, "--method", "krylov", "--order", "10", "--input", "TIP:y",
            "--rayleigh", "0:1e-6", "--no-cache", "-o"]
    t0 = time.perf_counter()
    subprocess.run([*argv, tmp_path / "ref.h5"], check=True, capture_output=True)
    duration = time.perf_counter() - t0
    ref = flexmor.read_body(tmp_path / "ref.h5")
    rng = np.random.default_rng(7)
    outcomes = []
    for k, delay in enumerate(rng.uniform(0.3, 1.1, 8) * duration):
        out = tmp_path / f"k{k}.h5"
        proc = subprocess.Popen([*argv, out], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if out.exists():
            body = flexmor.read_body(out)
            assert np.array_equal(body.K, ref.K) and np.array_equal(body.V, ref.V)
            outcomes.append("complete")
        else:
            outcomes.append("none")
    assert set(outcomes) <= {"complete", "none"}


def test_a_full_disk_ends_the_fmu_export_with_one_line(bodies, tmp_path):
    import shutil

    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler: the FMU export is refused before it writes")
    proc = _limited(["export", bodies / "k.h5", "-o", tmp_path / "b.fmu"], cwd=tmp_path, file_size=2048)
    line = _one_error_line(proc)
    assert "cannot write" in line and "file too large" in line and list(tmp_path.iterdir()) == []
