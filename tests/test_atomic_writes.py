"""Every writer is atomic: a failure or interrupt mid-write leaves neither the output nor a
temporary file, an existing output survives unchanged, and the command line needs --force to
overwrite and exits 130/143/2 without output when interrupted, terminated or out of disk."""

from __future__ import annotations

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import matplotlib.figure
import numpy as np
import pytest
import scipy.io
from helpers import CLAMPED

import flexmor
from flexmor.analysis import cache
from flexmor.cli import main
from flexmor.io import atomic_write, export, read_body, write_body
from flexmor.report import html
from flexmor.report.plots import plot_rel_error

SRC = Path(flexmor.__file__).parent


class Boom(Exception):
    pass


def _spill(target) -> None:
    """Write some bytes to ``target`` (a file name or an open binary/text file)."""
    if hasattr(target, "write"):
        target.write("partial" if "b" not in getattr(target, "mode", "b") else b"partial")
    else:
        with open(target, "wb") as fh:
            fh.write(b"partial")


def _inject(monkeypatch, name, exc, calls):
    """Make the library call under writer ``name`` write part of its file, then raise ``exc``."""
    def failing(first_arg_index=0, keep=None):
        def fake(*args, **kwargs):
            calls.append(name)
            if keep is not None:
                keep(*args, **kwargs)
            else:
                _spill(args[first_arg_index])
            raise exc
        return fake

    if name == "h5":
        orig = h5py.Group.create_dataset
        monkeypatch.setattr(h5py.Group, "create_dataset", failing(keep=orig))
    elif name in ("mat", "ss-mat"):
        monkeypatch.setattr(scipy.io, "savemat", failing())
    elif name in ("ss-npz", "exudyn", "cache"):
        monkeypatch.setattr(np, "savez", failing())
    elif name == "sid":
        monkeypatch.setattr(Path, "write_text", failing())
    elif name == "png":
        monkeypatch.setattr(matplotlib.figure.Figure, "savefig", failing(first_arg_index=1))
    elif name == "html":
        real_open = open

        class HalfFile:
            def __init__(self, fh):
                self.fh = fh
                self.mode = "w"

            def __enter__(self):
                return self

            def __exit__(self, *a):
                self.fh.close()

            def write(self, text):
                self.fh.write(text[: len(text) // 2])
                self.fh.flush()
                calls.append(name)
                raise exc

        monkeypatch.setattr(html, "open", lambda p, *a, **k: HalfFile(real_open(p, *a, **k)), raising=False)


def _write(name, body, path):
    red, model = body
    if name == "h5":
        write_body(red, path)
    elif name == "sid":
        export(red, path, "sid", model=model)
    elif name == "mat":
        export(red, path, "mat", model=model)
    elif name in ("ss-npz", "ss-mat"):
        export(red, path, "statespace")
    elif name == "exudyn":
        export(red, path, "exudyn", model=model)
    elif name == "html":
        real = html.render_html
        html.render_html = lambda rep: "<html>" + "x" * 100_000 + "</html>"
        try:
            html.write_report(None, path)
        finally:
            html.render_html = real
    elif name == "png":
        plot_rel_error(np.geomspace(1, 100, 20), {"modal": np.geomspace(1e-3, 1e-1, 20)}, path)


WRITERS = {"h5": "body.h5", "sid": "body.SID_FEM", "mat": "body.mat", "ss-npz": "ss.npz", "ss-mat": "ss.mat",
           "exudyn": "body_exudyn.npz", "html": "report.html", "png": "rel_error.png"}


@pytest.mark.parametrize("exc", [Boom("disk pulled"), KeyboardInterrupt()], ids=["exception", "ctrl-c"])
@pytest.mark.parametrize("name", sorted(WRITERS))
def test_writer_killed_mid_way_leaves_nothing(name, exc, body, tmp_path, monkeypatch):
    out = tmp_path / WRITERS[name]
    calls = []
    with monkeypatch.context() as mp:
        _inject(mp, name, exc, calls)
        with pytest.raises(type(exc)):
            _write(name, body, out)
    assert calls, "the failure was not injected: the writer no longer uses the patched call"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_writer_killed_mid_way_keeps_the_old_file(name, body, tmp_path, monkeypatch):
    out = tmp_path / WRITERS[name]
    out.write_bytes(b"old complete file")
    calls = []
    with monkeypatch.context() as mp:
        _inject(mp, name, Boom("disk pulled"), calls)
        with pytest.raises(Boom):
            _write(name, body, out)
    assert calls
    assert out.read_bytes() == b"old complete file"
    assert [p.name for p in tmp_path.iterdir()] == [out.name]
    _write(name, body, out)  # without the failure the file is replaced by a complete one
    assert out.stat().st_size > 1000 and [p.name for p in tmp_path.iterdir()] == [out.name]


def test_frf_cache_write_failure_leaves_nothing(tmp_path, monkeypatch):
    calls = []
    _inject(monkeypatch, "cache", OSError(errno.ENOSPC, "No space left on device"), calls)
    f = np.array([1.0, 2.0])
    path = cache.store("k" * 32, f, np.ones((2, 1, 1), complex), np.array([]), np.array([]), {}, directory=tmp_path)
    assert calls and path is None
    assert list(tmp_path.rglob("*")) == [] or all(p.is_dir() for p in tmp_path.rglob("*"))


def test_atomic_write_success_replaces_in_one_step(tmp_path):
    out = tmp_path / "sub" / "f.txt"
    seen = []

    def write(tmp):
        seen.append(Path(tmp))
        Path(tmp).write_text("new")
        assert not out.exists()  # the target appears only with the rename

    atomic_write(out, write)
    assert out.read_text() == "new"
    tmp = seen[0]
    assert tmp.parent == out.parent and tmp.name.startswith(".f.txt.") and tmp.name.endswith(".tmp")
    assert [p.name for p in out.parent.iterdir()] == ["f.txt"]


# every module that writes files does so through flexmor.io.atomic_write
_ANY_WRITE = re.compile(r"\.savefig\(|np\.savez|savemat\(|h5py\.File\([^)]*[\"'][wax]|write_text\(|write_bytes\("
                        r"|open\([^)]*[\"'][wax]b?[\"']|os\.replace\(|os\.rename\(|shutil\.(copy|move)")


def test_every_file_write_in_src_goes_through_atomic_write():
    offenders = []
    for path in SRC.rglob("*.py"):
        text = path.read_text()
        if path.relative_to(SRC).as_posix() == "io/atomic.py":
            continue
        for m in _ANY_WRITE.finditer(text):
            line = text[: m.start()].count("\n") + 1
            src_line = text.splitlines()[line - 1]
            in_memory = "BytesIO" in src_line or "buf" in src_line or "os.devnull" in src_line
            if not in_memory and "atomic_write" not in text:
                offenders.append(f"{path.name}:{line}: {src_line.strip()}")
            if "os.replace" in m.group(0) or "os.rename" in m.group(0):
                offenders.append(f"{path.name}:{line}: its own rename")
    assert offenders == []
    assert "os.replace(tmp, path)" in (SRC / "io" / "atomic.py").read_text()


# -- command line ------------------------------------------------------------------------------
def _reduce_argv(out, *extra):
    return ["reduce", CLAMPED, "--method", "modal", "--order", "4", "--input", "TIP:y", "--no-error",
            "-o", str(out), *extra]


@pytest.mark.slow
def test_cli_refuses_to_overwrite_without_force(tmp_path, capsys):
    out = tmp_path / "body.h5"
    out.write_bytes(b"precious")
    assert main(_reduce_argv(out)) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"flexmor: error: {out} exists; pass --force to overwrite it"
    assert out.read_bytes() == b"precious"
    assert main(_reduce_argv(out, "--force")) == 0
    assert read_body(out).order == 4
    sid = tmp_path / "body.SID_FEM"
    sid.write_text("old")
    argv = ["export", str(out), "--model", CLAMPED, "-o", str(sid), "--allow-clamped"]  # (a clamped body)
    assert main(argv) == 2 and "pass --force" in capsys.readouterr().err
    assert sid.read_text() == "old"
    assert main(argv + ["--force"]) == 0 and sid.stat().st_size > 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["body.SID_FEM", "body.h5"]


@pytest.mark.parametrize("exc,code",
                         [(KeyboardInterrupt(), 130), (OSError(errno.ENOSPC, "No space left on device"), 1)],
                         ids=["ctrl-c", "disk-full"])
def test_cli_interrupted_while_writing_leaves_no_output(exc, code, tmp_path, monkeypatch, capsys):
    out = tmp_path / "body.h5"
    calls = []
    _inject(monkeypatch, "h5", exc, calls)
    assert main(_reduce_argv(out)) == code
    err = capsys.readouterr().err.strip()
    assert calls and len(err.splitlines()) == 1 and "Traceback" not in err
    assert err == ("flexmor: interrupted" if code == 130 else
                   f"flexmor: error: cannot write {out}: no space left on the disk; nothing was written")
    assert list(tmp_path.iterdir()) == []


# a real flexmor process whose HDF5 writer stalls mid-file and says so (a marker file beside the
# output folder), so that the test signals it there however slow the machine is. A process started
# from a non-interactive shell's background job inherits SIGINT ignored, and Python then keeps it
# ignored: the child restores the interactive default so that the test does not depend on how the
# suite was started.
_STALL = """
import os, signal, sys, time, h5py
signal.signal(signal.SIGINT, signal.default_int_handler)
orig = h5py.Group.create_dataset
def slow(self, *a, **k):
    d = orig(self, *a, **k)
    self.file.flush()
    open(os.environ["STALLED_MARKER"], "w").close()
    time.sleep(60)
    return d
h5py.Group.create_dataset = slow
from flexmor.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_cli_process_signalled_mid_write_leaves_no_output(sig, code, tmp_path):
    folder, marker = tmp_path / "out", tmp_path / "stalled"
    folder.mkdir()
    out = folder / "body.h5"
    env = dict(os.environ, PYTHONPATH=str(SRC.parent), STALLED_MARKER=str(marker))
    proc = subprocess.Popen([sys.executable, "-c", _STALL, *_reduce_argv(out)], stderr=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, env=env, text=True)
    try:
        deadline = time.monotonic() + 120  # a loaded machine may take long to get there
        while not marker.exists():
            assert proc.poll() is None and time.monotonic() < deadline, "the writer never started"
            time.sleep(0.05)
        assert any(p.stat().st_size > 0 for p in folder.iterdir())  # a partial file exists now
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    assert err.strip().splitlines()[-1] == ("flexmor: interrupted" if code == 130 else "flexmor: terminated")
    assert list(folder.iterdir()) == []
