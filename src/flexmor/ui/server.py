"""``flexmor ui``: a local web application for the whole workflow, on the standard library's HTTP server.

The page (``app.html``) shows the body in the report's 3D viewer (:mod:`flexmor.report.view3d`)
and composes the command lines of ``flexmor reduce``, ``compare``, ``report`` and ``export``;
the server runs them in-process through the command line's ``main`` (handed in by
``flexmor ui``: same parser, same validation, same library calls and files as typed in a shell) and shows each command
so that it can be repeated. Long runs go to a background thread; the page polls their log (the
library's ``logging`` records) and elapsed time.

Safety: the server binds 127.0.0.1; every request carries the random token of the URL it
printed (other local users and web pages cannot drive it); file names are relative to the
working folder and may not leave it (absolute paths, ``..`` and symlinks out are refused);
one job runs at a time.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import secrets
import shlex
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlparse

from ..errors import FlexmorError, OptionError

__all__ = ["App", "Workspace", "make_server"]

log = logging.getLogger(__name__)

#: Files listed in the page (suffixes of FE models and reduced bodies are added from the registries).
MAX_FILES = 500


class Workspace:
    """The working folder; :meth:`path` resolves a relative name inside it or raises OptionError."""

    def __init__(self, folder):
        self.root = Path(folder).resolve()
        if not self.root.is_dir():
            raise OptionError(f"{folder} is not a folder", params=("folder",))

    def path(self, name: str, *, exists: bool = True) -> Path:
        """``name`` (relative, ``/``-separated) as an absolute path inside the folder."""
        name = str(name or "").strip()
        if not name or name.startswith(("/", "\\")) or ":" in name or ".." in Path(name).parts:
            raise OptionError(f"{name!r}: give a file name relative to the working folder, without '..'")
        p = (self.root / name).resolve()
        if p != self.root and self.root not in p.parents:
            raise OptionError(f"{name!r} leaves the working folder {self.root}")
        if exists and not p.is_file():
            raise OptionError(f"{name!r} is not a file in {self.root}")
        return p

    def files(self) -> dict:
        """Relative names of the FE models and reduced bodies under the folder, by kind: the files a
        registered reader takes (:meth:`flexmor.io.Registry.takes`; not their companion files)."""
        from ..io import BODY_FORMATS, MODEL_FORMATS

        registries = {"body": BODY_FORMATS, "model": MODEL_FORMATS}
        out: dict = {"model": [], "body": []}
        for p in sorted(self.root.rglob("*")):
            if len(out["model"]) + len(out["body"]) >= MAX_FILES:
                break
            if not p.is_file() or any(part.startswith(".") for part in p.relative_to(self.root).parts) \
                    or self.root not in p.resolve().parents:
                continue
            for kind in ("body", "model"):
                if registries[kind].takes(p) is not None:
                    out[kind].append(p.relative_to(self.root).as_posix())
                    break
        return out


class _Capture(logging.Handler):
    """The library's log records of one job, for the page's progress view."""

    def __init__(self, lines):
        super().__init__(logging.INFO)
        self.lines = lines

    def emit(self, record):
        self.lines.append(f"{time.strftime('%H:%M:%S')} {record.getMessage()}")


def run_cli(main, argv, log_lines) -> dict:
    """Run ``main(argv)`` (the command line) in-process; returns ``code``, ``result`` (its --json
    object) and ``error`` (its error lines), the library's log records going to ``log_lines``."""
    out, err = io.StringIO(), io.StringIO()
    handler, logger = _Capture(log_lines), logging.getLogger("flexmor")
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(argv))
            except SystemExit as exc:  # argparse: a bad flag or value
                code = exc.code if isinstance(exc.code, int) else 2
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
    text = out.getvalue().strip()
    try:
        result = json.loads(text.splitlines()[-1]) if text else None
    except json.JSONDecodeError:
        result = None
    errors = [ln for ln in err.getvalue().splitlines() if ln.startswith(("flexmor: error", "usage:")) or
              "error:" in ln]
    return {"code": code, "result": result, "error": "\n".join(errors) if code else ""}


class App:
    """State of the one user: the folder, the models read, the running or last job.

    ``main`` is the command line's ``main(argv) -> exit code`` that runs the commands.
    """

    def __init__(self, folder, main):
        self.ws = Workspace(folder)
        self.main = main
        self.token = secrets.token_urlsafe(16)
        self.lock = threading.Lock()
        self.job = None
        self.models = {}

    # -- reading and selecting (library calls, as the CLI's _read_model) -------------------------
    def model(self, name: str, selections=()):
        from ..io import read
        from ..selection import with_selections

        path = self.ws.path(name)
        key = (str(path), path.stat().st_mtime)
        if key not in self.models:
            self.models = {key: read(path)}  # one model at a time
        return with_selections(self.models[key], list(selections))

    def open(self, req) -> dict:
        from ..report.view3d import body_scene

        model = self.model(req["file"], req.get("select", ()))
        scene, _ = body_scene(model)
        return {"summary": model.summary(), "sets": {k: int(v.size) for k, v in model.node_sets.items()},
                "scene": scene}

    def preview(self, req) -> dict:
        """The nodes of each ``--select`` form, for highlighting before the run."""
        from ..selection import parse_selection

        model = self.model(req["file"], req.get("select", ()))
        out = {}
        for text in req.get("select", ()):
            name = parse_selection(text)[0].upper()
            ids = model.node_sets[name]
            out[name] = {"n": int(ids.size), "xyz": model.node_xyz(ids).tolist() if ids.size else []}
        return {"sets": out}

    def errors(self, req) -> dict:
        """The rel_error(f) plot of bodies (the curves stored with them) and their error measures."""
        import base64

        from ..io import read_body
        from ..report import plots

        curves, rows = {}, []
        for name in req.get("bodies", ()):
            red = read_body(self.ws.path(name))
            e = red.errors or {}
            rows.append({"file": name, "method": red.method, "order": red.order, "band_hz": e.get("band_hz"),
                         "band_error": e.get("band_error"), "max_rel_error": e.get("max_rel_error")})
            if e.get("rel_error") is not None:
                curves[Path(name).stem] = (e["freqs_hz"], e["rel_error"])
        png = plots.rel_error_png(None, curves, title="rel_error(f) over the band") if curves else None
        return {"rows": rows, "png": base64.b64encode(png).decode("ascii") if png else None}

    def modes(self, req) -> dict:
        """The 3D scene of one body: full modes beside their MAC pairs, deformations; and its MAC matrix.

        The model is the one the body was reduced from (:func:`flexmor.workflow.body_model`: its
        ``--select`` sets, couplings and damping, as ``flexmor compare`` uses it).
        """
        import base64

        from ..io import read_body
        from ..options import Band
        from ..ports import make_ports
        from ..report import plots
        from ..report.view3d import modes_scene
        from ..workflow import body_model

        red = read_body(self.ws.path(req["body"]))
        if not self.lock.acquire(blocking=False):
            raise OptionError("another run is in progress; wait for it to finish")
        try:
            model = body_model(self.model(req["file"]), red)
            ports = make_ports(model, red.input_names, red.output_names)
            label = Path(req["body"]).stem
            scene, modal = modes_scene(model, ports, [red], [label], band=Band.of((red.errors or {}).get("band_hz")),
                                       n_modes=int(req.get("n_modes") or 12))
        finally:
            self.lock.release()
        png = plots.mac_png({label: modal[label]["mac"]})
        return {"scene": scene, "mac_png": base64.b64encode(png).decode("ascii")}

    # -- commands ---------------------------------------------------------------------------------
    def argv(self, req) -> list:
        """The ``flexmor`` command line of a request, every file confined to the folder."""
        cmd = req.get("command")
        p = self.ws.path
        if cmd == "reduce":
            argv = ["reduce", str(p(req["file"]))]
            for s in req.get("select", ()):
                argv += ["--select", s]
            argv += ["--method", str(req["method"])]
            if str(req.get("order", "")).strip():
                argv += ["--order", str(req["order"]).strip()]
            for flag in ("interface", "input", "output"):
                for s in req.get(flag, ()):
                    argv += [f"--{flag}", s]
            for flag in ("band", "rayleigh", "modal-damping", "tol"):
                v = str(req.get(flag.replace("-", "_"), "") or "").strip()
                if v:
                    argv += [f"--{flag}", v]
            for name, value in (req.get("options") or {}).items():
                if str(value).strip():
                    argv += ["--" + name.replace("_", "-"), str(value).strip()]
            argv += ["-o", str(p(req["out"], exists=False)), "--force", "--json"]
        elif cmd in ("compare", "report"):
            argv = [cmd, str(p(req["file"]))] + [str(p(b)) for b in req["bodies"]]
            if str(req.get("band", "") or "").strip():
                argv += ["--band", str(req["band"]).strip()]
            if cmd == "report":
                argv += ["-o", str(p(req["out"], exists=False)), "--force"]
            argv.append("--json")
        elif cmd == "export":
            argv = ["export", str(p(req["body"])), "-o", str(p(req["out"], exists=False)), "--force", "--json"]
            if req.get("format"):
                argv += ["--format", str(req["format"])]
            if req.get("file"):
                argv += ["--model", str(p(req["file"]))]
        else:
            raise OptionError(f"unknown command {cmd!r}; use reduce, compare, report or export")
        return argv

    def start(self, req) -> dict:
        """Start a command in a background thread (one at a time)."""
        argv = self.argv(req)
        if not self.lock.acquire(blocking=False):
            raise OptionError("another run is in progress; wait for it to finish")
        job = {"id": secrets.token_hex(4), "argv": argv, "state": "running", "log": [], "t0": time.monotonic(),
               "command": "flexmor " + " ".join(shlex.quote(a.replace(str(self.ws.root) + "/", "")) for a in argv)}
        self.job = job

        def work():
            try:
                job.update(run_cli(self.main, argv, job["log"]))
                job["state"] = "done" if job["code"] == 0 else "failed"
            except Exception as exc:  # shown in the page; the server keeps running
                log.exception("ui job failed")
                job.update(state="failed", error=f"{type(exc).__name__}: {exc}")
            finally:
                job["seconds"] = time.monotonic() - job["t0"]
                self.lock.release()

        threading.Thread(target=work, daemon=True).start()
        return self.status()

    def status(self) -> dict:
        job = self.job
        if job is None:
            return {"state": "idle"}
        out = {k: v for k, v in job.items() if k not in ("t0", "argv")}
        out["log"] = job["log"][-200:]
        out.setdefault("seconds", time.monotonic() - job["t0"])
        return out

    def state(self) -> dict:
        from ..options import option_fields
        from ..reduction import methods
        from ..workflow import DEFAULT_BAND

        meths = {}
        for name, m in sorted(methods().items()):
            opts = []
            for opt, f in option_fields(m.options_class).items():
                if opt in ("band", "interface"):
                    continue
                md = f.metadata
                opts.append({"name": opt, "default": None if f.default is None else str(f.default),
                             "help": md["help"], "choices": list(md["choices"])})
            meths[name] = {"description": m.description, "options": opts}
        return {"folder": str(self.ws.root), "files": self.ws.files(), "methods": meths,
                "default_band": list(DEFAULT_BAND)}


_ROUTES_POST = {"/api/open": "open", "/api/preview": "preview", "/api/run": "start", "/api/errors": "errors",
                "/api/modes": "modes"}


def _handler(app: App):
    class Handler(BaseHTTPRequestHandler):
        server_version = "flexmor-ui"

        def log_message(self, fmt, *args):  # the page shows what matters; keep the terminal quiet
            log.debug("%s " + fmt, self.address_string(), *args)

        def _send(self, code, body, ctype="application/json"):
            data = body if isinstance(body, bytes) else (json.dumps(body) if ctype == "application/json"
                                                          else body).encode("utf-8")
            self.send_response(code)
            self.send_header("Content-Type", ctype + "; charset=utf-8" if "text" in ctype or "json" in ctype
                             else ctype)
            self.send_header("Content-Length", str(len(data)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(data)

        def _authorized(self, url) -> bool:
            given = self.headers.get("X-Flexmor-Token") or parse_qs(url.query).get("token", [""])[0]
            if secrets.compare_digest(given, app.token):
                return True
            self._send(403, {"error": "missing or wrong token: open the URL that flexmor ui printed"})
            return False

        def do_GET(self):
            url = urlparse(self.path)
            if not self._authorized(url):
                return
            if url.path == "/":
                page = resources.files(__package__).joinpath("app.html").read_text(encoding="utf-8")
                return self._send(200, page, "text/html")
            if url.path == "/view3d.js":
                from ..report.view3d import viewer_js

                return self._send(200, viewer_js(), "text/javascript")
            if url.path == "/api/state":
                return self._send(200, app.state())
            if url.path == "/api/job":
                return self._send(200, app.status())
            if url.path == "/file":  # a report written in the folder
                try:
                    path = app.ws.path(parse_qs(url.query).get("name", [""])[0])
                except FlexmorError as exc:
                    return self._send(400, {"error": exc.message()})
                ctype = "text/html" if path.suffix.lower() in (".html", ".htm") else "application/octet-stream"
                return self._send(200, path.read_bytes(), ctype)
            self._send(404, {"error": f"no such page {url.path}"})

        def do_POST(self):
            url = urlparse(self.path)
            if not self._authorized(url):
                return
            if url.path not in _ROUTES_POST:
                return self._send(404, {"error": f"no such request {url.path}"})
            try:
                n = int(self.headers.get("Content-Length") or 0)
                req = json.loads(self.rfile.read(n) or b"{}")
                self._send(200, getattr(app, _ROUTES_POST[url.path])(req))
            except FlexmorError as exc:
                self._send(400, {"error": exc.message()})
            except (KeyError, TypeError, ValueError) as exc:
                self._send(400, {"error": f"bad request: {type(exc).__name__}: {exc}"})

    return Handler


def make_server(folder, main, port: int = 0, host: str = "127.0.0.1"):
    """The HTTP server of the app on ``host:port`` (0: a free port) running commands with the command
    line's ``main``; returns ``(server, app, url)``."""
    app = App(folder, main)
    server = ThreadingHTTPServer((host, int(port)), _handler(app))
    server.daemon_threads = True
    url = f"http://{host}:{server.server_address[1]}/?token={app.token}"
    return server, app, url
