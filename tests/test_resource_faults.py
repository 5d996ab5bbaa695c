"""A machine that runs short: memory (the address-space limit), a full disk (the file-size limit)
and SIGKILL. Each ends in one ``flexmor: error:`` line with exit code 1, or leaves a complete file:
never a traceback, a signal death, or a half-written output."""

from __future__ import annotations

import math
import os
import resource
import signal
import subprocess
import sys
import time
import types

import numpy as np
import pytest
import scipy.io
from helpers import CLAMPED, FREE

import flexmor
from flexmor.errors import OutOfMemoryError
from flexmor.linalg import SolverContext

PY = sys.executable


#: ``sh -c`` mounting a tmpfs of $1 bytes on $2, running the rest of the command line (which writes
#: there) and listing what the disk holds then; exit _NO_SMALL_DISK when the tmpfs cannot be mounted
_NO_SMALL_DISK = 99
_SMALL_DISK = (f'mount -t tmpfs -o size="$1" tmpfs "$2" || exit {_NO_SMALL_DISK}; d="$2"; shift 2; "$@"; rc=$?; '
               'echo; echo "left on the disk:" $(ls -A "$d"); exit $rc')


def _start(argv, *, cwd, address_space=None, file_size=None, tmpdir=None, disk=None) -> subprocess.Popen:
    """Start ``python -m flexmor argv`` with the given soft limits (bytes) and ``$TMPDIR``; ``disk``
    ``(bytes, folder)``: with a disk that small mounted on the folder (a tmpfs, in a user and mount
    namespace of the process's own; :data:`_SMALL_DISK`)."""

    def limits():
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (int(address_space), resource.RLIM_INFINITY))
        if file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (int(file_size), resource.RLIM_INFINITY))

    env = _env(PYTHONFAULTHANDLER="1", **({"TMPDIR": str(tmpdir)} if tmpdir is not None else {}))
    cmd = [PY, "-m", "flexmor", *map(str, argv)]
    if disk is not None:
        cmd = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", _SMALL_DISK, "sh", str(int(disk[0])),
               str(disk[1]), *cmd]
    return subprocess.Popen(cmd, cwd=cwd, preexec_fn=limits, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _finish(proc: subprocess.Popen, timeout=300) -> subprocess.CompletedProcess:
    """Wait for a process of :func:`_start`: its CompletedProcess (killed after ``timeout`` s)."""
    try:
        out, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _limited(argv, *, cwd, address_space=None, file_size=None, timeout=300):
    """Run ``python -m flexmor argv`` with the given soft limits (bytes); the CompletedProcess."""
    return _finish(_start(argv, cwd=cwd, address_space=address_space, file_size=file_size), timeout)


def _env(**extra) -> dict:
    """The environment of the processes whose address space is measured or limited: ``auto`` takes the
    backend it takes on this machine and the BLAS libraries their default threads, also in a run that
    sets them otherwise (``make test-arith``): the limits below are set from what a default job maps
    (:data:`flexmor.linalg.resources.START_RESERVE` is the solver libraries' share with their threads)."""
    from flexmor.linalg.context import AUTO_BACKENDS_VARIABLE

    drop = {AUTO_BACKENDS_VARIABLE, "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_CORETYPE"}
    return {k: v for k, v in {**os.environ, **extra}.items() if k not in drop}


def _one_error_line(proc) -> str:
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-3000:])
    assert not any(s in proc.stderr for s in ("Traceback", "Fatal Python error", "Exception ignored")), \
        proc.stderr[-3000:]
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
    return int(subprocess.run([PY, "-c", code], capture_output=True, text=True, check=True, env=_env()).stdout)


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


@pytest.fixture(scope="module")
def solid(tmp_path_factory):
    """Every output written without a limit: ``argv`` (the command line that writes each, the file's
    path to be appended), ``size`` (its bytes; no FMU without a C compiler) and ``fmu_source`` (the
    bytes of the FMU's C source). The model is a 13,632-DOF free solid beam (a MATLAB file and a VTU
    mesh), the body its krylov body of order 30 (3.5 MB: a basis HDF5 writes whole, then node ids, a
    DOF table and triangles it compresses in chunks and writes when their datasets close); the report
    is the CalculiX beam's."""
    import zipfile

    import meshio

    from flexmor.errors import FlexmorError
    from flexmor.io.fmu import find_compiler
    from flexmor.models import cantilever

    folder = tmp_path_factory.mktemp("solid")
    m = cantilever(7, clamped=False)
    scipy.io.savemat(folder / "beam.mat", {"M": m.M, "K": m.K})
    meshio.write(folder / "beam.vtu", m.mesh.to_meshio(m.node_ids, m.xyz))
    tip = int(m.node_sets["TIP_CENTER"][0])
    model = ["--model", folder / "beam.mat", "--mesh", folder / "beam.vtu"]
    body, small = folder / "k.h5", folder / "small.h5"
    argv = {"body.h5": ["reduce", folder / "beam.mat", "--mesh", folder / "beam.vtu", "--method", "krylov", "--order",
                        "30", "--input", f"{tip}:y", "--input", f"{tip}:z", "--rayleigh", "0:1e-6", "--no-error",
                        "--no-cache", "-o"],
            "body.SID_FEM": ["export", body, *model, "-o"], "body.exudyn.npz": ["export", body, *model, "-o"],
            "body.mat": ["export", body, "-o"], "body.ss.npz": ["export", body, "-o"],
            "body.vtu": ["export", body, *model, "-o"], "body.fmu": ["export", body, "-o"],
            "report.html": ["report", FREE, small, "--rayleigh", "0:1e-6", "--no-cache", "--modes", "4", "-o"]}
    assert _limited([*argv["body.h5"], body], cwd=folder).returncode == 0
    assert _limited(["reduce", FREE, "--method", "krylov", "--order", "8", "--input", "TIP:y", "--rayleigh", "0:1e-6",
                     "--no-error", "--no-cache", "-o", small], cwd=folder).returncode == 0
    try:
        find_compiler()
    except FlexmorError:
        del argv["body.fmu"]
    size, fmu_source = {"body.h5": body.stat().st_size}, None
    started = {name: _start([*argv[name], folder / name], cwd=folder) for name in argv.keys() - size.keys()}
    for name, done in {name: _finish(proc) for name, proc in started.items()}.items():
        assert done.returncode == 0, (name, done.stderr[-3000:])
        size[name] = (folder / name).stat().st_size
    if "body.fmu" in size:
        with zipfile.ZipFile(folder / "body.fmu") as zf:
            fmu_source = next(i.file_size for i in zf.infolist() if i.filename.startswith("sources/"))
    return types.SimpleNamespace(argv=argv, size=size, fmu_source=fmu_source)


OUTPUTS = ["body.h5", "body.SID_FEM", "body.exudyn.npz", "body.mat", "body.ss.npz", "body.vtu", "body.fmu",
           "report.html"]


def _written(solid, name) -> int:
    """The size of output ``name`` written without a limit (skip the FMU without a C compiler)."""
    if name not in solid.size:
        pytest.skip("no C compiler: the FMU export is refused before it writes")
    return solid.size[name]


@pytest.mark.parametrize("name", OUTPUTS)
def test_a_file_size_limit_ends_every_output_of_any_size_with_one_line(solid, tmp_path, name):
    """Each output 10 times and 1.01 times the file-size limit (ulimit -f): one line naming the file
    and the limit, exit 1 (no SIGSEGV 139, no SIGXFSZ 153), neither the file nor a temporary file,
    nothing left in $TMPDIR. The FMU also with a limit that its C source fits and the compiler's
    files do not ("compiler")."""
    size = _written(solid, name)
    limits = {"10x": size / 10, "1.01x": size / 1.01}
    if name.endswith(".fmu"):
        limits["compiler"] = 1.01 * solid.fmu_source
    started = {}
    for what, limit in limits.items():  # side by side
        (tmp_path / what / "scratch").mkdir(parents=True)
        started[what] = _start([*solid.argv[name], tmp_path / what / name], cwd=tmp_path / what, file_size=limit,
                               tmpdir=tmp_path / what / "scratch")
    for what, done in {what: _finish(proc) for what, proc in started.items()}.items():
        folder = tmp_path / what
        line = _one_error_line(done)
        assert "file too large: the process's file-size limit (ulimit -f)" in line, (what, line)
        # the file written, or the FMU's C source and binary in $TMPDIR (the limit strikes them first)
        written = f"{folder / 'scratch'}/flexmor-fmu-" if name.endswith(".fmu") else f"{folder / name}:"
        assert f"cannot write {written}" in line, (what, line)
        assert sorted(p.name for p in folder.rglob("*")) == ["scratch"], what


@pytest.mark.parametrize("name", OUTPUTS)
def test_a_full_disk_ends_every_output_of_any_size_with_one_line(solid, tmp_path, name):
    """Each output written onto a disk (a tmpfs) 10 times and 1.01 times smaller than it (at least a
    page short: tmpfs counts whole pages of 4 KiB): one line naming the file and the full disk, exit 1,
    nothing left on the disk or in $TMPDIR."""
    import shutil

    if shutil.which("unshare") is None:
        pytest.skip("no unshare: a small disk cannot be mounted")
    size, page = _written(solid, name), 4096
    started = {}
    for what, factor in {"10x": 10, "1.01x": 1.01}.items():
        disk = max(page, min(size / factor, (math.ceil(size / page) - 1) * page) // page * page)
        (tmp_path / what / "disk").mkdir(parents=True)
        (tmp_path / what / "scratch").mkdir()
        started[what] = _start([*solid.argv[name], tmp_path / what / "disk" / name], cwd=tmp_path / what,
                               disk=(disk, tmp_path / what / "disk"), tmpdir=tmp_path / what / "scratch")
    for what, done in {what: _finish(proc) for what, proc in started.items()}.items():
        if done.returncode == _NO_SMALL_DISK or "unshare: " in done.stderr:
            pytest.skip(f"no tmpfs in a user namespace here: {done.stderr.strip()[-300:]}")
        line = _one_error_line(done)
        assert line == (f"flexmor: error: cannot write {tmp_path / what / 'disk' / name}: no space left on the disk; "
                        "nothing was written"), (what, line)
        assert done.stdout.rstrip().splitlines()[-1] == "left on the disk:", (what, done.stdout[-300:])
        assert list((tmp_path / what / "scratch").iterdir()) == [], what


def test_a_file_for_hdf5_keeps_its_first_failure_and_never_raises(tmp_path):
    """DiscardAfterFailure under a 1000-byte file-size limit: a write across the limit, which the
    system takes in part, is continued until it fails; neither it, a later write nor a truncation
    beyond the limit raises (each returns what the library expects); check() raises the failure kept."""
    code = ("import errno, resource, sys; from flexmor.io.atomic import DiscardAfterFailure;"
            "resource.setrlimit(resource.RLIMIT_FSIZE, (1000, resource.RLIM_INFINITY));"
            "f = DiscardAfterFailure(sys.argv[1], 'w+');"
            "print(f.write(b'x' * 600), f.failed, f.write(memoryview(b'y' * 4000)), f.failed.errno == errno.EFBIG,"
            "     f.write(b'z'), f.truncate(10**6));"
            "g = DiscardAfterFailure(sys.argv[2], 'w+'); print(g.truncate(10**6), g.failed.errno == errno.EFBIG);"
            "f.close(); f.check()")
    proc = subprocess.run([PY, "-c", code, tmp_path / "f", tmp_path / "g"], capture_output=True, text=True, check=False)
    assert proc.stdout.split() == ["600", "None", "4000", "True", "1", "1000000", "1000000", "True"], proc.stderr
    assert proc.returncode == 1 and proc.stderr.strip().endswith("OSError: [Errno 27] File too large")
    assert (tmp_path / "f").read_bytes() == b"x" * 600 + b"y" * 400 and (tmp_path / "g").stat().st_size == 0


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
