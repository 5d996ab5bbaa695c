"""``flexmor ui``: a local web application for the whole workflow, on the standard library's HTTP server.

The page (``app.html``) shows the body in the report's 3D viewer (:mod:`flexmor.report.view3d`)
and composes the command lines of ``flexmor reduce``, ``compare``, ``report`` and ``export``;
the server runs them in-process through the command line's ``main`` (handed in by
``flexmor ui``: same parser, same validation, same library calls and files as typed in a shell) and shows each command
so that it can be repeated. Long runs go to a background thread; the page polls their log (the
library's ``logging`` records) and elapsed time.

Safety: the server binds 127.0.0.1; every request carries the random token of the URL it
printed (other local users and web pages cannot drive it); file names are relative to the
working folder and may not leave it (absolute paths, ``..``, backslashes, control characters and
symlinks out are refused, and an output may not be a folder); the commands take only the flags
the page offers (a method's own options, no other file names). One job runs at a time (another
is refused with 429). A bad request is answered 4xx with a one-line JSON ``{"error": reason}``:
bodies over :data:`MAX_BODY` bytes (413, read no further), a missing or false Content-Length
(411, 400), JSON that is malformed or of the wrong type (400 naming the field), unknown pages
(404) and methods (405), unknown job ids (404). Each connection is served in its own thread; a
request must arrive whole within :data:`TIMEOUT` seconds (a silent or trickling client is dropped
or answered 408), and at most :data:`MAX_CONNECTIONS` are served at once.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import re
import secrets
import shlex
import socket
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path, PurePosixPath
from urllib.parse import parse_qs

from ..errors import FlexmorError, OptionError

__all__ = ["App", "Workspace", "make_server", "MAX_BODY", "MAX_CONNECTIONS", "TIMEOUT"]

log = logging.getLogger(__name__)

#: Files listed in the page (suffixes of FE models and reduced bodies are added from the registries).
MAX_FILES = 500
#: The largest request body read, in bytes (a request is a few names and options).
MAX_BODY = 1 << 20
#: Seconds a request (its line, headers and body) may take to arrive, however it trickles in.
TIMEOUT = 30.0
#: Connections served at once; one more is answered 503 and closed.
MAX_CONNECTIONS = 64
#: The longest file name taken, and the most items in a list of a request.
MAX_NAME, MAX_ITEMS = 1024, 200


def _shown(value, n: int = 80) -> str:
    """``repr(value)`` cut to about ``n`` characters, for messages."""
    text = repr(value)
    return text if len(text) <= n else text[:n] + "...'"


def _kind(value) -> str:
    return {dict: "an object", list: "a list", str: "a text", bool: "true/false", type(None): "null"}.get(
        type(value), "a number")


def _text(req: dict, key: str, *, required: bool = False) -> str:
    """The text field ``key`` of a request ("" when absent and not required); a number is taken as its text."""
    v = req.get(key)
    if v is None:
        if required:
            raise OptionError(f"the request lacks {key!r}")
        return ""
    if isinstance(v, bool) or not isinstance(v, (str, int, float)):
        raise OptionError(f"{key!r} must be a text, not {_kind(v)}")
    return str(v)


def _texts(req: dict, key: str, *, required: bool = False) -> list:
    """The list-of-texts field ``key`` of a request ([] when absent and not required)."""
    v = req.get(key)
    if v is None and not required:
        return []
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        raise OptionError(f"{key!r} must be a list of texts, not {_kind(v)}"
                          + ("" if not isinstance(v, list) else " holding other values"))
    if len(v) > MAX_ITEMS:
        raise OptionError(f"{key!r} holds {len(v)} items; at most {MAX_ITEMS}")
    return v


class Workspace:
    """The working folder; :meth:`path` resolves a relative name inside it or raises OptionError."""

    def __init__(self, folder):
        self.root = Path(folder).resolve()
        if not self.root.is_dir():
            raise OptionError(f"{folder} is not a folder", params=("folder",))

    def path(self, name: str, *, exists: bool = True) -> Path:
        """``name`` (relative, ``/``-separated) as an absolute path inside the folder.

        With ``exists`` the path must be a file; without (an output), it may not be a folder.
        Symbolic links are followed and must end inside the folder.
        """
        if not isinstance(name, str):
            raise OptionError(f"{_shown(name)}: a file name must be a text, not {_kind(name)}")
        name = name.strip()
        if not name or name.startswith("/") or ":" in name or ".." in PurePosixPath(name).parts:
            raise OptionError(f"{_shown(name)}: give a file name relative to the working folder, without '..'")
        if "\\" in name or any(ord(c) < 32 or c == "\x7f" for c in name) or len(name) > MAX_NAME:
            raise OptionError(f"{_shown(name)}: a file name may not hold backslashes or control characters "
                              f"nor be longer than {MAX_NAME} characters")
        try:
            p = (self.root / name).resolve()
            inside = p != self.root and p.is_relative_to(self.root)
            is_file, is_dir = (p.is_file(), p.is_dir()) if inside else (False, False)
        except (OSError, ValueError) as exc:
            raise OptionError(f"{_shown(name)} is not a usable file name ({getattr(exc, 'strerror', None) or exc})") \
                from None
        if p == self.root:
            raise OptionError(f"{_shown(name)} is the working folder itself; give a file name")
        if not inside:
            raise OptionError(f"{_shown(name)} leaves the working folder {self.root}")
        if exists and not is_file:
            raise OptionError(f"{_shown(name)} is not a file in {self.root}")
        if not exists and is_dir:
            raise OptionError(f"{_shown(name)} is a folder; give the name of a file to write")
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


class _Refused(Exception):
    """A request answered with HTTP ``status`` and ``reason`` (and ``headers``); the server's own, not the library's."""

    def __init__(self, status: int, reason: str, headers=None):
        super().__init__(reason)
        self.status, self.reason, self.headers = status, reason, dict(headers or {})


def _busy() -> _Refused:
    return _Refused(429, "another run is in progress; wait for it to finish", {"Retry-After": "2"})


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

    ``main`` is the command line's ``main(argv) -> exit code`` that runs the commands. The
    request methods take the decoded JSON object of a request and refuse fields of the wrong
    type with an OptionError naming the field.
    """

    def __init__(self, folder, main):
        self.ws = Workspace(folder)
        self.main = main
        self.token = secrets.token_urlsafe(16)
        self.lock = threading.Lock()  # the one job (or modes computation) running
        self.reading = threading.Lock()  # one model read at a time, into the cache
        self.job = None
        self.models = {}

    # -- reading and selecting (library calls, as the CLI's _read_model) -------------------------
    def model(self, name: str, selections=()):
        """The model of the file ``name`` in the folder (read once while the file is unchanged; one
        model held at a time) with the node sets of ``selections``."""
        from ..io import read
        from ..selection import with_selections

        path = self.ws.path(name)
        with self.reading:
            key = (str(path), path.stat().st_mtime)
            if key not in self.models:
                self.models = {key: read(path)}  # one model at a time
            model = self.models[key]
        return with_selections(model, list(selections))

    def open(self, req) -> dict:
        """The answer to opening a model: its summary, its node sets and their sizes, its 3D scene."""
        from ..report.view3d import body_scene

        model = self.model(_text(req, "file", required=True), _texts(req, "select"))
        scene, _ = body_scene(model)
        return {"summary": model.summary(), "sets": {k: int(v.size) for k, v in model.node_sets.items()},
                "scene": scene}

    def preview(self, req) -> dict:
        """The nodes of each ``--select`` form, for highlighting before the run."""
        from ..selection import parse_selection

        selects = _texts(req, "select")
        model = self.model(_text(req, "file", required=True), selects)
        out = {}
        for text in selects:
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
        for name in _texts(req, "bodies"):
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
        from ..ports import body_ports
        from ..report import plots
        from ..report.view3d import modes_scene
        from ..workflow import body_model

        body, file = _text(req, "body", required=True), _text(req, "file", required=True)
        n_modes = _text(req, "n_modes").strip() or "12"
        if not re.fullmatch(r"[0-9]{1,3}", n_modes) or not 1 <= int(n_modes) <= 100:
            raise OptionError(f"'n_modes' must be a whole number from 1 to 100, not {_shown(n_modes)}")
        red = read_body(self.ws.path(body))
        if not self.lock.acquire(blocking=False):
            raise _busy()
        try:
            model = body_model(self.model(file), red)
            ports = body_ports(model, red)
            label = Path(body).stem
            scene, modal = modes_scene(model, ports, [red], [label], band=Band.of((red.errors or {}).get("band_hz")),
                                       n_modes=int(n_modes))
        finally:
            self.lock.release()
        png = plots.mac_png({label: modal[label]["mac"]})
        return {"scene": scene, "mac_png": base64.b64encode(png).decode("ascii")}

    # -- commands ---------------------------------------------------------------------------------
    def _method_options(self, method: str) -> dict:
        """The options of ``method`` the page offers: flag -> option name (without the common band and interface)."""
        from ..options import option_fields
        from ..reduction import method_name, methods

        fields = option_fields(methods()[method_name(method)].options_class)
        return {name: name.replace("_", "-") for name in fields if name not in ("band", "interface")}

    def argv(self, req) -> list:
        """The ``flexmor`` command line of a request, every file confined to the folder and the
        method options limited to the method's own (no flag can name another file)."""
        if not isinstance(req, dict):
            raise OptionError(f"the request must be a JSON object, not {_kind(req)}")
        cmd = _text(req, "command")
        p = self.ws.path
        if cmd == "reduce":
            argv = ["reduce", str(p(_text(req, "file", required=True)))]
            for s in _texts(req, "select"):
                argv += ["--select", s]
            method = _text(req, "method", required=True)
            argv += ["--method", method]
            if _text(req, "order").strip():
                argv += ["--order", _text(req, "order").strip()]
            for flag in ("interface", "input", "output"):
                for s in _texts(req, flag):
                    argv += [f"--{flag}", s]
            for flag in ("band", "rayleigh", "modal-damping", "tol"):
                v = _text(req, flag.replace("-", "_")).strip()
                if v:
                    argv += [f"--{flag}", v]
            options = req.get("options") or {}
            if not isinstance(options, dict):
                raise OptionError(f"'options' must be an object of option names and values, not {_kind(options)}")
            flags = self._method_options(method)
            for name in options:
                value = _text(options, name).strip()
                if not value:  # left empty in the page: the default
                    continue
                if name not in flags:
                    raise OptionError(f"'options': {_shown(name)} is not an option of --method {method}; "
                                      f"its options: {', '.join(flags) or 'none'}")
                argv += ["--" + flags[name], value]
            argv += ["-o", str(p(_text(req, "out", required=True), exists=False)), "--force", "--json"]
        elif cmd in ("compare", "report"):
            argv = [cmd, str(p(_text(req, "file", required=True)))] + [
                str(p(b)) for b in _texts(req, "bodies", required=True)]
            if _text(req, "band").strip():
                argv += ["--band", _text(req, "band").strip()]
            if cmd == "report":
                argv += ["-o", str(p(_text(req, "out", required=True), exists=False)), "--force"]
            argv.append("--json")
        elif cmd == "export":
            argv = ["export", str(p(_text(req, "body", required=True))),
                    "-o", str(p(_text(req, "out", required=True), exists=False)), "--force", "--json"]
            if _text(req, "format"):
                argv += ["--format", _text(req, "format")]
            if _text(req, "file"):
                argv += ["--model", str(p(_text(req, "file")))]
        else:
            raise OptionError(f"unknown command {_shown(cmd)}; use reduce, compare, report or export")
        return argv

    def start(self, req) -> dict:
        """Start a command in a background thread (one at a time: another is refused with 429)."""
        argv = self.argv(req)
        if not self.lock.acquire(blocking=False):
            raise _busy()
        job = {"id": secrets.token_hex(4), "argv": argv, "state": "running", "log": [], "t0": time.monotonic(),
               "command": "flexmor " + " ".join(shlex.quote(a.replace(str(self.ws.root) + "/", "")) for a in argv)}
        self.job = job

        def work():
            try:
                job.update(run_cli(self.main, argv, job["log"]))
                job["state"] = "done" if job["code"] == 0 else "failed"
            except BaseException as exc:  # shown in the page; the server keeps running
                log.exception("ui job failed")
                job.update(state="failed", error=f"{type(exc).__name__}: {exc}")
            finally:
                job["seconds"] = time.monotonic() - job["t0"]
                self.lock.release()

        try:
            threading.Thread(target=work, daemon=True).start()
        except BaseException:
            self.lock.release()
            raise
        return self.status()

    def status(self, job_id: str | None = None) -> dict:
        """The running or last job; with ``job_id``, that job (404 when it is not the last one)."""
        job = self.job
        if job_id is not None and (job is None or not secrets.compare_digest(job_id.encode(), job["id"].encode())):
            raise _Refused(404, f"no job {_shown(job_id, 40)}" + (f"; the last one is {job['id']}" if job else
                                                                  "; none has run"))
        if job is None:
            return {"state": "idle"}
        out = {k: v for k, v in job.items() if k not in ("t0", "argv")}
        out["log"] = job["log"][-200:]
        out.setdefault("seconds", time.monotonic() - job["t0"])
        return out

    def state(self) -> dict:
        """What the page needs to start: the methods with their options, the default band and the folder's files."""
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


_ROUTES_GET = ("/", "/view3d.js", "/api/state", "/api/job", "/file")
_ROUTES_POST = {"/api/open": "open", "/api/preview": "preview", "/api/run": "start", "/api/errors": "errors",
                "/api/modes": "modes"}
#: The scheme and host of an absolute request target
_ABSOLUTE = re.compile(r"https?://", re.IGNORECASE)
#: A Content-Length: digits only (``int()`` would also take signs, blanks and underscores).
_LENGTH = re.compile(r"[0-9]{1,18}")


def _handler(app: App, timeout: float):
    class Handler(BaseHTTPRequestHandler):
        server_version = "flexmor-ui"

        def version_string(self):
            return self.server_version

        def setup(self):
            self.timeout = timeout  # socketserver sets it on the socket: a silent client is dropped
            super().setup()

        def log_message(self, fmt, *args):  # the page shows what matters; keep the terminal quiet
            log.debug("%s " + fmt, self.address_string(), *args)

        def _send(self, code, body, ctype="application/json", headers=None):
            data = body if isinstance(body, bytes) else (json.dumps(body) if ctype == "application/json"
                                                          else body).encode("utf-8")
            try:
                self.send_response(code)
                self.send_header("Content-Type", ctype + "; charset=utf-8" if "text" in ctype or "json" in ctype
                                 else ctype)
                self.send_header("Content-Length", str(len(data)))
                self.send_header("Cache-Control", "no-store")
                for k, v in (headers or {}).items():
                    self.send_header(k, v)
                if self.close_connection:
                    self.send_header("Connection", "close")
                self.end_headers()
                if self.command != "HEAD":
                    self.wfile.write(data)
            except OSError:  # the client has gone
                self.close_connection = True

        def send_error(self, code, message=None, explain=None):
            """The base class's refusals (bad request line, too many or too long headers ...) as JSON."""
            self.close_connection = True
            if getattr(self, "request_version", "") in ("", "HTTP/0.9"):
                self.request_version = "HTTP/1.0"  # a status line and headers, also to a bare request line
            if code == HTTPStatus.HTTP_VERSION_NOT_SUPPORTED:  # the client's fault: a 4xx
                code, message = HTTPStatus.BAD_REQUEST, f"{message}: use HTTP/1.0 or HTTP/1.1"
            short, long = self.responses.get(code, ("Error", ""))
            self._send(code, {"error": message or long or short})

        def parse_request(self):
            words = str(self.raw_requestline, "iso-8859-1").split()
            if self.server.late(self.connection):
                self.command, self.requestline, self.request_version = "", " ".join(words)[:200], "HTTP/1.0"
                self.send_error(408, f"the request did not arrive within {timeout:g} s")
                return False
            if len(words) < 3:  # HTTP/0.9 or an empty or bare line: the base class would wait for headers
                self.command, self.requestline, self.request_version = "", " ".join(words)[:200], "HTTP/1.0"
                self.send_error(400, "a request line is 'METHOD PATH HTTP/1.1' followed by headers")
                return False
            return super().parse_request()

        def __getattr__(self, name):
            if name.startswith("do_"):  # any other method: 405, not the base class's 501
                return self._not_allowed
            raise AttributeError(name)

        def _not_allowed(self):
            self._answer(self._refuse_method)

        def _arrived(self):
            """The request is in: no deadline from now on (a long computation is not cut), unless it came late."""
            if not self.server.arrived(self.connection):
                self.close_connection = True
                raise _Refused(408, f"the request did not arrive within {timeout:g} s")

        def _refuse_method(self):
            self._arrived()
            self._authorize()
            raise _Refused(405, f"method {_shown(self.command, 40)} is not served; use GET or POST",
                           {"Allow": "GET, POST"})

        def do_GET(self):
            self._answer(self._get)

        def do_POST(self):
            self._answer(self._post)

        def _answer(self, serve):
            """Serve, and turn every failure into an answer: 4xx with its reason; 500 naming the
            exception (the traceback goes to the log, never to the client)."""
            try:
                code, body, ctype = serve()
                self._send(code, body, ctype)
            except _Refused as r:
                self._send(r.status, {"error": r.reason}, headers=r.headers)
            except FlexmorError as exc:
                self._send(400, {"error": exc.message()})
            except TimeoutError:
                self.close_connection = True
                self._send(408, {"error": f"the request did not arrive within {timeout:g} s"})
            except OSError as exc:  # a file in the folder that cannot be read or written
                name = Path(exc.filename).name if isinstance(exc.filename, str) else "a file"
                self._send(400, {"error": f"{name}: {exc.strerror or exc}"})
            except (KeyError, TypeError, ValueError, RecursionError) as exc:
                self._send(400, {"error": f"bad request: {type(exc).__name__}: {exc}"[:500]})
            except Exception as exc:
                log.exception("ui request %s failed", self.requestline[:200])
                self._send(500, {"error": f"internal error ({type(exc).__name__}); the request was not done"})

        def _target(self):
            """The path and query of the request line (decoded once, by parse_qs); of an absolute
            target (``http://host/path``) its path."""
            path, _, query = self.path.partition("?")
            if _ABSOLUTE.match(path):
                path = "/" + path.split("/", 3)[3] if path.count("/") >= 3 else "/"
            try:
                return path, parse_qs(query.partition("#")[0], keep_blank_values=True, max_num_fields=20)
            except ValueError:
                raise _Refused(400, "too many query fields") from None

        def _authorize(self):
            path, query = self._target()
            given = self.headers.get("X-Flexmor-Token") or query.get("token", [""])[0]
            if not secrets.compare_digest(given.encode("utf-8", "surrogateescape"), app.token.encode("ascii")):
                raise _Refused(403, "missing or wrong token: open the URL that flexmor ui printed")
            return path, query

        def _get(self):
            self._arrived()
            path, query = self._authorize()
            if path in _ROUTES_POST:
                raise _Refused(405, f"{path} takes a POST", {"Allow": "POST"})
            if path == "/":
                page = resources.files(__package__).joinpath("app.html").read_text(encoding="utf-8")
                return 200, page, "text/html"
            if path == "/view3d.js":
                from ..report.view3d import viewer_js

                return 200, viewer_js(), "text/javascript"
            if path == "/api/state":
                return 200, app.state(), "application/json"
            if path == "/api/job":
                return 200, app.status(query["id"][0] if "id" in query else None), "application/json"
            if path == "/file":  # a report written in the folder
                name = query.get("name", [""])[0]
                target = app.ws.path(name)
                try:
                    data = target.read_bytes()
                except OSError as exc:
                    raise _Refused(400, f"{_shown(name)} cannot be read ({exc.strerror})") from None
                ctype = "text/html" if target.suffix.lower() in (".html", ".htm") else "application/octet-stream"
                return 200, data, ctype
            raise _Refused(404, f"no such page {_shown(path)}")

        def _post(self):
            path, _ = self._authorize()
            if path not in _ROUTES_POST:
                if path in _ROUTES_GET:
                    raise _Refused(405, f"{path} takes a GET", {"Allow": "GET"})
                raise _Refused(404, f"no such request {_shown(path)}")
            data = self._body()
            self._arrived()
            try:
                req = json.loads(data or b"{}")
            except (ValueError, RecursionError) as exc:
                raise _Refused(400, f"the body is not JSON: {exc}"[:300]) from None
            if not isinstance(req, dict):
                raise _Refused(400, f"the body must be a JSON object {{...}}, not {_kind(req)}")
            return 200, getattr(app, _ROUTES_POST[path])(req), "application/json"

        def _body(self) -> bytes:
            """The request body: at most MAX_BODY bytes, announced by one Content-Length."""
            if self.headers.get("Transfer-Encoding"):
                self.close_connection = True
                raise _Refused(411, "send the body with a Content-Length, not a Transfer-Encoding")
            lengths = self.headers.get_all("Content-Length") or []
            if not lengths:
                raise _Refused(411, "a POST needs a Content-Length header")
            text = lengths[0].strip()
            if len(set(v.strip() for v in lengths)) > 1 or not _LENGTH.fullmatch(text):
                self.close_connection = True
                raise _Refused(400, f"Content-Length must be one number of bytes, not {_shown(', '.join(lengths))}")
            n = int(text)
            if n > MAX_BODY:
                self.close_connection = True
                raise _Refused(413, f"the body of {n} bytes is over the limit of {MAX_BODY} bytes")
            data = self.rfile.read(n)
            if len(data) < n:
                self.close_connection = True
                self._arrived()  # 408 when its reading was ended for lateness
                raise _Refused(400, f"the body ended after {len(data)} of its {n} bytes")
            return data

        def finish(self):
            """End the answer, then read and drop what the client still sends (a refused body, up to
            MAX_BODY bytes and a second): closed with unread data the connection would be reset, and
            the client could lose the answer."""
            try:
                super().finish()
            finally:
                _linger(self.connection, MAX_BODY + (1 << 16), 1.0)

    return Handler


def _linger(sock, limit: int, seconds: float) -> None:
    """Half-close ``sock`` (the client reads the answer to its end) and drop up to ``limit`` bytes it
    still sends, for up to ``seconds`` (0: only what has arrived)."""
    end, n = time.monotonic() + seconds, 0
    try:
        sock.shutdown(socket.SHUT_WR)
        sock.settimeout(min(0.2, seconds) if seconds > 0 else 0.0)
        while n < limit:
            chunk = sock.recv(1 << 16)
            if not chunk or time.monotonic() > end:
                break
            n += len(chunk)
    except OSError:  # nothing more (BlockingIOError, a timeout) or the client has gone
        pass


class _Server(ThreadingHTTPServer):
    """The threaded HTTP server, serving at most ``max_connections`` at once (one more is answered 503
    at once), ending the requests that have not arrived within ``timeout`` seconds (a client that
    trickles its bytes in keeps the socket's own timeout from firing), logging, not printing, a
    connection's failure, and not waiting for its connections when closed."""

    daemon_threads = True
    block_on_close = False

    def __init__(self, address, handler, max_connections: int, timeout: float, poll=None):
        super().__init__(address, handler)
        self.poll = poll  # called between polls; what it raises ends serve_forever
        self.slots = threading.BoundedSemaphore(max_connections)
        self.request_timeout = timeout
        self.arriving: dict = {}  # socket -> deadline of its request (None: late, its reading ended)
        self.arriving_lock = threading.Lock()

    def arrived(self, request) -> bool:
        """The request on ``request`` is in; False when it came too late."""
        with self.arriving_lock:
            return self.arriving.pop(request, 0) is not None

    def late(self, request) -> bool:
        """Whether the request on ``request`` missed its deadline (its reading was ended)."""
        with self.arriving_lock:
            return request in self.arriving and self.arriving[request] is None

    def service_actions(self):
        """Called by serve_forever between polls: end the reading of the requests past their deadline."""
        now = time.monotonic()
        with self.arriving_lock:
            late = [sock for sock, t in self.arriving.items() if t is not None and t < now]
            for sock in late:
                self.arriving[sock] = None
        for sock in late:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RD)  # the handler's read returns at once
        if self.poll is not None:
            self.poll()

    def process_request(self, request, client_address):
        if not self.slots.acquire(blocking=False):
            body = b'{"error": "too many connections at once; try again"}'
            with contextlib.suppress(OSError):
                request.settimeout(1.0)
                request.sendall(b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: application/json\r\n"
                                b"Retry-After: 1\r\nConnection: close\r\nContent-Length: %d\r\n\r\n%s"
                                % (len(body), body))
            _linger(request, 1 << 16, 0.0)
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.slots.release()
            raise

    def process_request_thread(self, request, client_address):
        with self.arriving_lock:
            self.arriving[request] = time.monotonic() + self.request_timeout
        try:
            super().process_request_thread(request, client_address)
        finally:
            with self.arriving_lock:
                self.arriving.pop(request, None)
            self.slots.release()

    def handle_error(self, request, client_address):
        log.debug("connection from %s ended by an error", client_address, exc_info=True)


def make_server(folder, main, port: int = 0, host: str = "127.0.0.1", *, timeout: float = TIMEOUT,
                max_connections: int = MAX_CONNECTIONS, poll=None):
    """The HTTP server of the app on ``host:port`` (0: a free port) running commands with the command
    line's ``main``; returns ``(server, app, url)``.

    Each connection is served in its own thread; a request must arrive whole within ``timeout``
    seconds, and at most ``max_connections`` are served at once. ``poll`` (no arguments) is called
    by ``serve_forever`` about every half second; an exception it raises ends the serving.
    """
    app = App(folder, main)
    server = _Server((host, int(port)), _handler(app, float(timeout)), int(max_connections), float(timeout),
                     poll)
    url = f"http://{host}:{server.server_address[1]}/?token={app.token}"
    return server, app, url
