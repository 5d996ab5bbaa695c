"""``flexmor ui``: the folder confinement, the token, the commands it composes, and one workflow in Chromium."""

from __future__ import annotations

import json
import re
import shutil
import threading
import urllib.error
import urllib.request

import numpy as np
import pytest
from browser import Browser, canvas_pixels, find_chromium
from helpers import CCX

from flexmor.cli import build_parser, main
from flexmor.errors import OptionError
from flexmor.ui import App, Workspace, make_server


@pytest.fixture()
def folder(tmp_path):
    for p in CCX.glob("beam8_free_mat.*"):
        shutil.copy(p, tmp_path / p.name)
    return tmp_path


def test_paths_stay_inside_the_folder(folder, tmp_path_factory):
    ws = Workspace(folder)
    assert ws.path("beam8_free_mat.sti") == folder.resolve() / "beam8_free_mat.sti"
    outside = tmp_path_factory.mktemp("outside")
    (outside / "secret.sti").write_text("x")
    (folder / "link").symlink_to(outside)
    for bad in ("/etc/passwd", "../outside/secret.sti", "sub/../../x", "link/secret.sti", "C:/x", ""):
        with pytest.raises(OptionError):
            ws.path(bad)
    with pytest.raises(OptionError, match="is not a file"):
        ws.path("missing.sti")
    assert ws.path("new/body.h5", exists=False).parent == folder.resolve() / "new"
    assert ws.files() == {"model": ["beam8_free_mat.inp", "beam8_free_mat.sti"], "body": []}  # by the registries


def test_commands_are_the_cli_ones(folder):
    app = App(folder, main)
    argv = app.argv({"command": "reduce", "file": "beam8_free_mat.sti", "select": ["B=box:1,0,0,1,1,1"],
                     "method": "krylov", "order": "8", "interface": [], "input": ["B@rbe3:y"], "output": [],
                     "band": "1:500", "modal_damping": "0.02", "options": {"max_iter": "", "points": "3"},
                     "out": "k.h5"})
    root = str(folder.resolve())
    assert argv == ["reduce", f"{root}/beam8_free_mat.sti", "--select", "B=box:1,0,0,1,1,1", "--method", "krylov",
                    "--order", "8", "--input", "B@rbe3:y", "--band", "1:500", "--modal-damping", "0.02",
                    "--points", "3", "-o", f"{root}/k.h5", "--force", "--json"]
    build_parser().parse_args(argv)  # the CLI's own parser takes it
    with pytest.raises(OptionError, match="leaves the working folder|without '..'"):
        app.argv({"command": "export", "body": "../x.h5", "out": "y.SID_FEM"})
    with pytest.raises(OptionError, match="unknown command"):
        app.argv({"command": "rm"})
    # the method options offered are the registered ones, without the common band/interface
    opts = {o["name"] for o in app.state()["methods"]["krylov"]["options"]}
    assert "band" not in opts and opts


@pytest.fixture()
def server(folder):
    srv, app, url = make_server(folder, main, 0)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    yield app, url
    srv.shutdown()
    srv.server_close()


def test_requests_need_the_token(server):
    app, url = server
    base = url.split("?")[0]
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(base + "api/state", timeout=30)
    assert exc.value.code == 403
    req = urllib.request.Request(base + "api/state", headers={"X-Flexmor-Token": app.token})
    state = json.load(urllib.request.urlopen(req, timeout=30))
    assert "beam8_free_mat.sti" in state["files"]["model"] and "craig-bampton" in state["methods"]
    bad = urllib.request.Request(base + "api/open", data=json.dumps({"file": "../../etc/passwd"}).encode(),
                                 headers={"X-Flexmor-Token": app.token}, method="POST")
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(bad, timeout=30)
    assert exc.value.code == 400 and "without '..'" in json.load(exc.value)["error"]


@pytest.mark.slow
@pytest.mark.browser
def test_workflow_in_chromium_equals_the_cli(server, folder, tmp_path_factory):
    exe = find_chromium()
    if exe is None:
        pytest.skip("no chromium/chrome on PATH (CI installs Debian's chromium): the app is not driven here")
    _, url = server
    with Browser(exe, 1400, 1000) as b:
        b.open(url)
        b.wait_for("document.getElementById('file').options.length > 0")
        b.js("document.getElementById('file').value = 'beam8_free_mat.sti'; document.getElementById('open').click()")
        b.wait_for("!!(window.flexmorApp && window.flexmorApp.viewer)")
        b.js("document.querySelector('[data-view=y]').click()")  # side view: the tip face is the right edge
        rect = b.js("JSON.parse(JSON.stringify(window.flexmorApp.viewer.canvas.getBoundingClientRect()))")
        png = b.screenshot()
        (folder / "shot-open.png").write_bytes(png)
        px = canvas_pixels(png, rect)
        points = b.js("window.flexmorApp.scene.points_only")  # a file without elements: its nodes as dots
        assert np.mean(np.any(px < 240, axis=2)) > (0.001 if points else 0.02)  # the body is drawn
        # a box around the projected nodes at x = 1 (the TIP set), dragged with shift held
        box = b.js("""(function () {
            var v = window.flexmorApp.viewer, p = v.project(), x = v.body.xyz, r = v.canvas.getBoundingClientRect();
            var lo = [1e9, 1e9], hi = [-1e9, -1e9];
            for (var i = 0; i < v.body.n; i++) if (x[3 * i] > 0.999) {
                lo = [Math.min(lo[0], p[2 * i]), Math.min(lo[1], p[2 * i + 1])];
                hi = [Math.max(hi[0], p[2 * i]), Math.max(hi[1], p[2 * i + 1])]; }
            return [r.left + lo[0] - 6, r.top + lo[1] - 6, r.left + hi[0] + 6, r.top + hi[1] + 6]; })()""")
        b.mouse("mousePressed", box[0], box[1], shift=True)
        b.mouse("mouseMoved", (box[0] + box[2]) / 2, (box[1] + box[3]) / 2, shift=True)
        b.mouse("mouseMoved", box[2], box[3], shift=True)
        b.mouse("mouseReleased", box[2], box[3], shift=True)
        status = b.wait_for("(document.getElementById('status').textContent.match(/nodes selected/) || [''])[0] && "
                            "document.getElementById('status').textContent")
        assert status == "BOX1: 9 nodes selected"
        spec = b.js("window.flexmorApp.selects[0]")
        assert spec.startswith("BOX1=box:1,")
        # a shift+click on the node at the origin gives the nearest-node form
        at = b.js("""(function () { var v = window.flexmorApp.viewer, p = v.project(), x = v.body.xyz,
            r = v.canvas.getBoundingClientRect();
            for (var i = 0; i < v.body.n; i++) if (x[3 * i] === 0 && x[3 * i + 1] === 0 && x[3 * i + 2] === 0)
                return [r.left + p[2 * i] + 2, r.top + p[2 * i + 1] + 1]; })()""")
        b.mouse("mousePressed", *at, shift=True)
        b.mouse("mouseReleased", *at, shift=True)
        b.wait_for("window.flexmorApp.selects.length === 2")
        assert b.js("window.flexmorApp.selects[1]") == "BOX2=nearest:0,0,0"
        b.js("document.getElementById('clearsel').click(); document.getElementById('selspec').value = "
             f"{json.dumps(spec)}; document.getElementById('addsel').click()")
        b.wait_for("window.flexmorApp.selects.length === 1 && window.flexmorApp.lastSet === 'BOX1'")
        b.js("""document.getElementById('asrbe2').click();
                document.getElementById('inputs').value = 'BOX1@rbe2:y, BOX1@rbe2:z';
                document.getElementById('method').value = 'craig-bampton';
                document.getElementById('method').dispatchEvent(new Event('change'));
                document.getElementById('order').value = '12';
                document.getElementById('out').value = 'cb.h5';
                document.getElementById('run').click();""")
        assert b.js("document.getElementById('interface').value") == "BOX1@rbe2"
        b.wait_for("document.getElementById('errplot').src.startsWith('data:image/png') && "
                   "document.getElementById('errplot').naturalWidth > 0", timeout=600)
        assert "band_error" in b.js("document.getElementById('errtable').textContent")
        command = b.js("document.getElementById('cmd').textContent")
        assert command.startswith("flexmor reduce beam8_free_mat.sti --select BOX1=box:")
        # the body's modes beside the full ones, with the MAC (same viewer as the report)
        b.js("document.getElementById('modes').click()")
        b.wait_for("document.getElementById('macplot').naturalWidth > 0 && "
                   "document.getElementById('v3d-left-cap').textContent.startsWith('full model: mode 1')", timeout=300)
        b.js("document.getElementById('v3d-anim').click(); document.getElementById('modesview').scrollIntoView()")
        caps = b.js("document.getElementById('v3d-right-cap').textContent")
        assert caps.startswith("cb: mode 1, ")
        right = b.js("JSON.parse(JSON.stringify(document.getElementById('v3d-right').getBoundingClientRect()))")
        assert np.mean(np.any(canvas_pixels(b.screenshot(), right) < 240, axis=2)) > 0.001
        b.js("window.scrollTo(0, 0)")
        b.js("document.getElementById('expout').value = 'ui.SID_FEM'; document.getElementById('export').click()")
        b.wait_for("document.getElementById('links').textContent.startsWith('exported')", timeout=300)
        (folder / "shot-done.png").write_bytes(b.screenshot())
    # the same choices on the command line give the same SID file
    cli = tmp_path_factory.mktemp("cli")
    sti = str(folder / "beam8_free_mat.sti")
    assert main(["reduce", sti, "--select", spec, "--method", "craig-bampton", "--order", "12",
                 "--interface", "BOX1@rbe2", "--input", "BOX1@rbe2:y", "--input", "BOX1@rbe2:z",
                 "-o", str(cli / "cb.h5"), "--json"]) == 0
    assert main(["export", str(cli / "cb.h5"), "--format", "sid", "-o", str(cli / "cli.SID_FEM"), "--model", sti]) == 0
    # the MAC shown is the one of the library's modal check on the body's own model
    from flexmor.analysis.modal_check import modal_check
    from flexmor.io import read, read_body
    from flexmor.selection import with_selections
    from flexmor.workflow import prepare_model

    red = read_body(folder / "cb.h5")
    model = prepare_model(with_selections(read(sti), [spec]), ["BOX1@rbe2"])
    c = modal_check(model, red, n_modes=12)
    hz, mac_shown = (float(v) for v in re.match(r"cb: mode 1, (\S+) Hz, MAC (\S+)$", caps).groups())
    assert hz == pytest.approx(c["reduced_hz"][0], rel=1e-4) and mac_shown == pytest.approx(c["pair_mac"][0], abs=1e-4)
    assert c["pair_mac"][0] > 0.99
    ui_sid = (folder / "ui.SID_FEM").read_bytes()
    assert ui_sid == (cli / "cli.SID_FEM").read_bytes() and b"BOX1@RBE2" in ui_sid


def test_cli_ui_serves_until_terminated(folder):
    import os
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "flexmor", "ui", str(folder), "--no-browser", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"flexmor ui: serving {folder.resolve()} at http://127.0.0.1:")
        url = line.split(" at ", 1)[1].split()[0]
        base, token = url.split("?token=")
        req = urllib.request.Request(base + "api/state", headers={"X-Flexmor-Token": token})
        assert "beam8_free_mat.sti" in json.load(urllib.request.urlopen(req, timeout=60))["files"]["model"]
    finally:
        proc.terminate()
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = f"still serving 60 s after SIGTERM; its stderr: {proc.communicate()[1][-3000:]}"
        assert code == 143
    bad = subprocess.run([sys.executable, "-m", "flexmor", "ui", str(folder / "missing"), "--no-browser"],
                         check=False, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "is not a folder" in bad.stderr


def test_a_sigterm_whose_exception_was_lost_still_ends_the_serving(folder, capsys):
    """The SIGTERM handler sets the run's flag and raises; raised inside a destructor the exception is
    lost (Python reports it as unraisable). The flag alone must end ``flexmor ui``'s endless loop."""
    import os
    import signal
    import time

    import flexmor.cli as cli

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("the SIGTERM handler is installed by the main thread only")
    fallback = []

    def lose_the_exception():
        deadline = time.monotonic() + 60
        while cli._current is None and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(1.0)  # serving by now
        cli._current.terminated = True  # what the handler does before its exception is lost
        time.sleep(20)
        if cli._current is not None:  # still serving: end it for real (the test fails below)
            fallback.append(True)
            os.kill(os.getpid(), signal.SIGTERM)

    helper = threading.Thread(target=lose_the_exception, daemon=True)
    helper.start()
    code = main(["ui", str(folder), "--no-browser", "--port", "0"])
    assert code == 143 and not fallback
    assert "flexmor ui: serving" in capsys.readouterr().out and cli._current is None
