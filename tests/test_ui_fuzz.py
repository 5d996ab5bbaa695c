"""``flexmor ui`` under bad requests: malformed JSON, huge bodies, encoded ``..``, absolute paths and
symlinks out of the folder, unknown routes and methods, slow clients and concurrent jobs.

The server works in a folder next to an "outside" folder that holds a canary file; symlinks lead
from inside to outside. Every answer must be a well-formed HTTP response below 500 (4xx with a
JSON reason for the bad requests), the server must keep serving, no file outside may be opened,
created or changed, and inside only the files of the accepted jobs may appear.
"""

from __future__ import annotations

import collections
import contextlib
import json
import os
import random
import re
import secrets
import shutil
import socket
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from urllib.parse import quote

import pytest
from helpers import CCX

from flexmor.cli import main
from flexmor.ui import MAX_BODY, make_server

#: (outside folder, list of the opens seen) while a test watches; the audit hook is the process's own
_WATCHED: list = []
_HOOKED: list = []


def _audit(event, args):
    if not _WATCHED or event not in ("open", "os.listdir", "os.scandir") or not args:
        return
    path = args[0]
    if path is None or isinstance(path, int):
        return
    try:
        real = os.path.realpath(os.fsdecode(os.fspath(path)))
    except (TypeError, ValueError, OSError):
        return
    for prefix, hits in list(_WATCHED):
        if real == prefix or real.startswith(prefix + os.sep):
            hits.append((event, real))


class World:
    """The served folder ``inside``, its sibling ``outside`` (canary, symlink targets) and the server."""

    def __init__(self, base: Path, **server_options):
        self.inside, self.outside = base / "inside", base / "outside"
        self.inside.mkdir()
        self.outside.mkdir()
        for p in CCX.glob("beam8_free_mat.*"):
            shutil.copy(p, self.inside / p.name)
        (self.inside / "sub").mkdir()
        (self.inside / "notes.txt").write_text("not a model\n")
        self.canary = "CANARY-" + secrets.token_hex(12)
        for name in ("canary.inp", "canary.sti", "canary.h5", "canary.html"):
            (self.outside / name).write_text(self.canary + "\n")
        (self.outside / "secret").mkdir()
        (self.outside / "secret" / "deep.sti").write_text(self.canary + "\n")
        (self.inside / "out_link").symlink_to(self.outside)  # a folder link out
        (self.inside / "canary_link.sti").symlink_to(self.outside / "canary.sti")  # a file link out
        (self.inside / "sub" / "up_link").symlink_to("../../outside")  # a relative link out
        (self.inside / "dangling.h5").symlink_to(self.outside / "created.h5")  # a write through it lands outside
        self.server, self.app, self.url = make_server(self.inside, main, 0, **server_options)
        self.port = self.server.server_address[1]
        self.token = self.app.token
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()

    # -- requests -------------------------------------------------------------------------------
    def raw(self, method, target, body=None, *, token=True, headers=(), length=None) -> bytes:
        """The bytes of a request (Content-Length from the body unless ``length`` is given)."""
        lines = [f"{method} {target} HTTP/1.1", "Host: 127.0.0.1"]
        if token:
            lines.append(f"X-Flexmor-Token: {self.token}")
        if body is not None:
            body = body if isinstance(body, bytes) else json.dumps(body).encode()
            lines.append(f"Content-Length: {len(body) if length is None else length}")
        lines += list(headers)
        return "\r\n".join(lines).encode("utf-8", "surrogateescape") + b"\r\n\r\n" + (body or b"")

    def send(self, data: bytes, *, shut=True, timeout=60.0):
        """Send ``data`` on a new connection and read the answer to its end: ``(status, headers, body)``."""
        with socket.create_connection(("127.0.0.1", self.port), timeout=timeout) as s:
            try:
                s.sendall(data)
                if shut:
                    s.shutdown(socket.SHUT_WR)
            except OSError:  # answered and closed before all was sent
                pass
            chunks = []
            while True:
                try:
                    chunk = s.recv(1 << 16)
                except ConnectionResetError:
                    break
                if not chunk:
                    break
                chunks.append(chunk)
        return parse(b"".join(chunks), head=data.startswith(b"HEAD "))

    def get(self, target, **kw):
        return self.send(self.raw("GET", target, **kw))

    def post(self, target, body, **kw):
        return self.send(self.raw("POST", target, body, **kw))

    def wait_job(self, timeout=120):
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            status, _, body = self.get("/api/job")
            job = json.loads(body)
            if job["state"] != "running":
                return job
            time.sleep(0.05)
        raise AssertionError("the job did not end")


def parse(raw: bytes, head: bool = False):
    """A complete HTTP/1.x response: status line, headers, a body of its Content-Length."""
    top, sep, body = raw.partition(b"\r\n\r\n")
    assert sep, f"not an HTTP response: {raw[:200]!r}"
    lines = top.decode("iso-8859-1").split("\r\n")
    m = re.fullmatch(r"HTTP/1\.[01] ([1-5][0-9][0-9]) (\S.*)", lines[0])
    assert m, f"bad status line {lines[0]!r}"
    headers = {}
    for line in lines[1:]:
        k, _, v = line.partition(": ")
        headers[k.lower()] = v
    if not head:
        assert int(headers["content-length"]) == len(body), (lines[0], headers, body[:200])
    return int(m.group(1)), headers, body


def reason(body: bytes) -> str:
    """The ``error`` of a refusal (a non-empty text)."""
    text = json.loads(body)["error"]
    assert isinstance(text, str) and text.strip()
    return text


def snapshot(root: Path) -> dict:
    """Relative name -> (size, mtime) of everything under ``root``, symlinks not followed."""
    out = {}
    for dirpath, dirs, files in os.walk(root, followlinks=False):
        for name in dirs + files:
            p = Path(dirpath, name)
            st = p.lstat()
            out[p.relative_to(root).as_posix()] = (st.st_size, st.st_mtime_ns)
    return out


@pytest.fixture()
def world(tmp_path):
    if not _HOOKED:
        sys.addaudithook(_audit)
        _HOOKED.append(True)
    w = World(tmp_path, timeout=2.0)
    w.before_outside = snapshot(w.outside)
    hits: list = []
    entry = (str(w.outside.resolve()), hits)
    _WATCHED.append(entry)
    try:
        yield w
    finally:
        _WATCHED.remove(entry)
        w.close()
    assert not hits, f"files outside the folder were opened or listed: {sorted(set(hits))[:5]}"
    assert snapshot(w.outside) == w.before_outside


# -- one test per hardening (each failed on the server before it) ---------------------------------
def test_bodies_are_limited_and_need_a_length(world):
    w = world
    # over the limit: 413 at once, the body left unread (not allocated, not waited for)
    t0 = time.monotonic()
    status, _, body = w.send(w.raw("POST", "/api/open", b"{" + b" " * 4096, length=10 ** 14))
    assert status == 413 and str(MAX_BODY) in reason(body)
    status, _, body = w.send(w.raw("POST", "/api/open", b" " * (MAX_BODY + 1)))
    assert status == 413
    assert time.monotonic() - t0 < 10
    # missing, negative, signed, garbage, conflicting lengths; a chunked body
    assert w.send(w.raw("POST", "/api/open"))[0] == 411
    for length in ("-1", "+2", "1_0", "abc", "", " 2 2", "99999999999999999999999"):
        status, _, body = w.send(w.raw("POST", "/api/open", b"{}", length=length))
        assert status == 400 and "Content-Length" in reason(body), length
    status, _, body = w.send(w.raw("POST", "/api/open", b"{}", headers=["Content-Length: 3"]))
    assert status == 400 and "Content-Length" in reason(body)
    chunked = w.raw("POST", "/api/open", headers=["Transfer-Encoding: chunked"]) + b"2\r\n{}\r\n0\r\n\r\n"
    status, _, body = w.send(chunked)
    assert status == 411 and "Content-Length" in reason(body)
    # a body shorter than announced, the client done sending
    status, _, body = w.send(w.raw("POST", "/api/open", b"{}", length=50))
    assert status == 400 and "ended after 2 of its 50 bytes" in reason(body)


def test_malformed_json_and_fields_of_the_wrong_type_are_named(world):
    w = world
    cases = {b"{bad": "not JSON", b"\xff\xfe\x00": "not JSON", b"[" * 100_000 + b"]" * 100_000: "not JSON",
             b"[1, 2]": "JSON object", b'"file"': "JSON object", b"null": "JSON object", b"12": "JSON object",
             b'{"file": ["a"]}': "'file' must be a text", b'{"file": {"x": 1}}': "'file' must be a text",
             b'{"file": true}': "'file' must be a text", b'{"select": []}': "lacks 'file'",
             b'{"file": "beam8_free_mat.sti", "select": "B=box:1,0,0,1,1,1"}': "'select' must be a list",
             b'{"file": "beam8_free_mat.sti", "select": [1]}': "'select' must be a list"}
    for data, words in cases.items():
        status, _, body = w.send(w.raw("POST", "/api/open", data))
        assert status == 400 and words in reason(body), (data[:40], body)
    for req, words in [({"bodies": "x.h5"}, "'bodies' must be a list"),
                       ({"body": "x.h5", "file": "beam8_free_mat.sti", "n_modes": "1e9"}, "'n_modes'"),
                       ({"command": ["reduce"]}, "'command' must be a text"),
                       ({"command": "reduce", "file": "beam8_free_mat.sti", "method": "krylov", "options": [1],
                         "out": "a.h5"}, "'options' must be an object")]:
        route = {"bodies": "/api/errors", "body": "/api/modes"}.get(next(iter(req)), "/api/run")
        status, _, body = w.post(route, req)
        assert status == 400 and words in reason(body), (req, body)


#: Names refused for reading and for writing: out of the folder (``..``, absolute, through a symlink),
#: malformed (backslashes, control characters, too long), the folder itself or a folder in it.
BAD_NAMES = ["../outside/canary.sti", "sub/../../outside/canary.sti", "/etc/passwd", "out_link/canary.sti",
             "canary_link.sti", "sub/up_link/canary.sti", "out_link/secret/deep.sti", "..\\outside\\canary.sti",
             "C:\\outside\\canary.sti", "beam8_free_mat.sti\x00.html", "a\x00b", "a\nb", "x" * 5000, "", " ", ".",
             "sub", "./", "out_link", "sub/up_link", "dangling.h5"]
#: Names inside the folder (a percent sign is a character: requests are decoded once) naming no file
MISSING = ["%2e%2e/outside/canary.sti", "..%2Foutside%2Fcanary.sti", "~/x", "sub/none.sti", "dangling.h5"]


def test_names_that_leave_the_folder_are_refused(world):
    w = world
    bad = BAD_NAMES + [str(w.outside / "canary.sti"), "//" + str(w.outside / "canary.sti")]
    for name in bad + MISSING:
        for target in (f"/file?name={quote(name, safe='')}", f"/file?name={quote(quote(name, safe=''), safe='')}"):
            status, _, body = w.get(target)
            assert status == 400 and reason(body) and w.canary.encode() not in body, (name, status, body)
        status, _, body = w.post("/api/open", {"file": name})
        assert status == 400 and w.canary.encode() not in body, (name, body)
    # outputs: through a symlink out (dangling.h5: the write would create the file outside), a folder
    (w.inside / "body.h5").write_bytes(b"")
    for name in bad + ["out_link/new.h5", "sub/up_link/new.h5"]:
        status, _, body = w.post("/api/run", {"command": "export", "body": "body.h5", "out": name})
        assert status == 400 and reason(body), (name, body)
    for out in ("dangling.h5", "out_link/new.h5", ".", "sub"):
        status, _, body = w.post("/api/run", {"command": "export", "body": "body.h5", "out": out})
        assert status == 400 and re.search("leaves the working folder|is a folder|folder itself", reason(body))
    assert w.app.job is None


def test_commands_take_only_the_method_options(world):
    """A flag that names another file (--mesh, --output-file ...) cannot come in through the options."""
    w = world
    for name in ("mesh", "output_file", "output-file", "preload", "verbose", "json", "o"):
        req = {"command": "reduce", "file": "beam8_free_mat.sti", "method": "krylov", "order": "4",
               "input": ["TIP:y"], "options": {name: str(w.outside / "canary.inp")}, "out": "k.h5"}
        status, _, body = w.post("/api/run", req)
        assert status == 400 and "is not an option of --method krylov" in reason(body), (name, body)
    assert w.app.job is None


def test_unknown_routes_and_methods(world):
    w = world
    for target in ("/api/nope", "/%2e%2e/%2e%2e/etc/passwd", "/file/../../etc/passwd", "/api/state/",
                   "/API/STATE", "http://x/api/nope", "/api/%2e%2e/state", "/./api/state"):
        status, _, body = w.get(target)
        assert status == 404 and reason(body), target
        status, _, body = w.post(target, {})
        assert status == 404 and reason(body), target
    assert w.get("http://127.0.0.1/api/state")[0] == 200  # an absolute target is its path
    assert w.get("//api/state")[0] == 200  # as http.server normalizes it
    status, headers, body = w.post("/api/state", {})
    assert status == 405 and headers["allow"] == "GET" and "takes a GET" in reason(body)
    status, headers, body = w.get("/api/open")
    assert status == 405 and headers["allow"] == "POST"
    for method in ("PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "FOO", "do_GET"):
        status, headers, body = w.send(w.raw(method, "/api/state", b"{}"))
        assert status == 405 and "GET, POST" == headers["allow"] and method[:10] in reason(body), method
        assert w.send(w.raw(method, "/api/state", b"{}", token=False))[0] == 403
    status, headers, _ = w.send(w.raw("HEAD", "/api/state"))
    assert status == 405


def test_tokens_of_any_bytes_and_malformed_requests_get_an_answer(world):
    w = world
    for given in ("\xff\xfe", "é" * 22, w.token + "x", w.token[:-1], ""):
        data = w.raw("GET", "/api/state", token=False, headers=[f"X-Flexmor-Token: {given}"])
        status, _, body = w.send(data.replace(given.encode("utf-8", "surrogateescape"), given.encode("latin-1")))
        assert status == 403 and "token" in reason(body)
        assert w.get(f"/api/state?token={quote(given)}", token=False)[0] == 403
    for data in (b"\r\n\r\n", b"GET\r\n\r\n", b"GET /\r\n\r\n", b"GET /?token=" + w.token.encode() + b"\r\n",
                 b"GET / HTTP/2.0\r\n\r\n", b"GET / HTTP/x\r\n\r\n", b"GET / FTP/1.0\r\n\r\n",
                 b"GET / HTTP/1.1 extra\r\n\r\n", b"\x00\x01\x02\r\n\r\n",
                 b"GET " + b"a" * 70_000 + b" HTTP/1.1\r\n\r\n",
                 w.raw("GET", "/api/state", headers=[f"X-{i}: {i}" for i in range(120)]),
                 w.raw("GET", "/api/state", headers=["X-Long: " + "a" * 70_000])):
        status, _, body = w.send(data)
        assert 400 <= status < 500 and reason(body), (data[:40], status, body)
    assert w.get("/api/state")[0] == 200


def test_silent_clients_do_not_block_the_server(world):
    """Connections that send nothing, half a request, or trickle it in, are ended after the timeout (2 s here)."""
    w = world
    trickling = socket.create_connection(("127.0.0.1", w.port), timeout=30)
    trickling.sendall(b"GET /api/state HTTP/1.1\r\nX-Slow: ")

    def trickle():  # a byte every 0.4 s: never silent for the 2 s of the socket's timeout
        with contextlib.suppress(OSError):
            for _ in range(50):
                trickling.sendall(b"a")
                time.sleep(0.4)

    threading.Thread(target=trickle, daemon=True).start()
    stuck = []
    for part in (b"", b"GET /api/state HTTP/1.1\r\n", b"GET /api/st", w.raw("POST", "/api/open", b"{}", length=9)[:-2]):
        s = socket.create_connection(("127.0.0.1", w.port), timeout=30)
        s.sendall(part)
        stuck.append(s)
    t0 = time.monotonic()
    assert w.get("/api/state")[0] == 200 and time.monotonic() - t0 < 1.5  # served beside them
    for s in [*stuck, trickling]:
        with s:
            answer = b""
            with contextlib.suppress(ConnectionResetError):
                while chunk := s.recv(1 << 16):
                    answer += chunk
            assert answer == b"" or parse(answer)[0] == 408
    assert time.monotonic() - t0 < 8  # ended after the timeout, not held (the trickle would last 20 s)


def test_connections_over_the_cap_are_answered_at_once(tmp_path):
    w = World(tmp_path, timeout=2.0, max_connections=3)
    try:
        stuck = [socket.create_connection(("127.0.0.1", w.port), timeout=30) for _ in range(3)]
        time.sleep(0.2)
        status, headers, body = w.get("/api/state")
        assert status == 503 and "too many connections" in reason(body) and headers["retry-after"]
        for s in stuck:
            s.close()
        time.sleep(0.3)
        assert w.get("/api/state")[0] == 200
    finally:
        w.close()


def _reduce_req(out="fz.h5"):
    return {"command": "reduce", "file": "beam8_free_mat.sti", "select": ["B=box:1,0,0,1,1,1"], "method": "krylov",
            "order": "6", "input": ["B@rbe3:y"], "out": out}


def test_jobs_run_one_at_a_time_and_unknown_ids_are_404(world):
    w = world
    assert w.get("/api/job?id=0000")[0] == 404  # none has run
    status, _, body = w.post("/api/run", _reduce_req())
    assert status == 200
    job = json.loads(body)
    status, headers, body = w.post("/api/run", _reduce_req("other.h5"))  # while the first runs
    assert status == 429 and "another run is in progress" in reason(body) and headers["retry-after"]
    status, _, body = w.post("/api/modes", {"file": "beam8_free_mat.sti", "body": "beam8_free_mat.sti"})
    assert status == 400  # not a body: refused before waiting for the job
    status, _, body = w.get("/api/job?id=" + ("0" * 8 if job["id"] != "0" * 8 else "1" * 8))
    assert status == 404 and "no job" in reason(body)
    assert json.loads(w.get("/api/job?id=" + job["id"])[2])["id"] == job["id"]
    assert w.wait_job()["state"] == "done"
    assert (w.inside / "fz.h5").is_file() and not (w.inside / "other.h5").exists()


# -- the mix: at least 10^4 requests, several threads at once -------------------------------------
def _cases(w: World, rng: random.Random, n: int) -> list:
    """About ``n`` requests ``(class, bytes, expected statuses, job output or None, sent at once with the
    next)``, drawn with ``rng``."""
    outside = str(w.outside / "canary.sti")
    names = BAD_NAMES + [outside, "//" + outside]
    inputs = names + MISSING
    valid_get = ["/api/state", "/api/job", "/", "/file?name=beam8_free_mat.inp", "/file?name=fz.h5",
                 "/file?name=.%2Fbeam8_free_mat.inp"]
    valid_post = [("/api/open", {"file": "beam8_free_mat.sti"}),
                  ("/api/open", {"file": "./beam8_free_mat.sti", "select": ["B=box:1,0,0,1,1,1"]}),
                  ("/api/preview", {"file": "beam8_free_mat.sti", "select": ["N=nearest:0,0,0"]}),
                  ("/api/errors", {"bodies": []})]

    def pick(seq):
        return seq[rng.randrange(len(seq))]

    def junk(k):
        return bytes(rng.randrange(256) for _ in range(k))

    def bad_name(among=names):
        name = pick(among)
        return name if rng.random() < 0.7 else name.replace("/", pick(["//", "/./"]))

    def bad_json():
        kind = rng.randrange(6)
        # an empty request is a valid one for /api/errors (no bodies): it takes only what is not an object
        route = pick(["/api/open", "/api/preview", "/api/run", "/api/modes"] + ["/api/errors"] * (kind < 4))
        if kind == 0:
            data = junk(rng.randrange(1, 200))
        elif kind == 1:
            text = json.dumps(pick(valid_post)[1]).encode()
            data = text[: rng.randrange(1, len(text))]
        elif kind == 2:
            data = json.dumps(pick([[1], "x", 3, None, 2.5, True, [{"file": "a"}]])).encode()
        elif kind == 3:
            data = b"[" * rng.randrange(1000, 50_000)
        elif kind == 4:
            key = pick(["file", "select", "bodies", "body", "command", "options", "out", "n_modes", "method"])
            data = json.dumps({key: pick([None, 1, [1], {"a": [1]}, [None], True, -1e308, "", "x" * 3000]),
                               "command": pick(["reduce", "export", "rm", 5])}).encode()
        else:
            data = b'{"file": "' + junk(8).replace(b'"', b"") + b'"}'
        return route, data

    cases, jobs = [], 0
    classes = ["valid_get", "valid_post", "no_token", "bad_name_get", "bad_name_post", "bad_json", "bad_length",
               "huge_body", "unknown_route", "bad_method", "bad_request", "bad_option", "job_id", "job"]
    weights = [6, 3, 8, 12, 12, 14, 8, 2, 10, 8, 8, 4, 4, 0.25]
    for _ in range(n):
        cls = rng.choices(classes, weights)[0]
        job = None
        if cls == "valid_get":
            data, ok = w.raw("GET", pick(valid_get)), {200}
        elif cls == "valid_post":
            route, req = pick(valid_post)
            data, ok = w.raw("POST", route, req), {200}
        elif cls == "no_token":
            target = pick(valid_get + ["/api/open", "/nope"])
            given = pick(["", "x", w.token[:-1], w.token.upper(), "%00", "é"])
            data = w.raw(pick(["GET", "POST", "PUT"]), target + ("?token=" + quote(given) if rng.random() < .5 else ""),
                         b"{}", token=False, headers=[f"X-Flexmor-Token: {given}"] if rng.random() < .5 else [])
            ok = {403}
        elif cls == "bad_name_get":
            name = quote(bad_name(inputs), safe=pick(["", "/", "/."]))
            data, ok = w.raw("GET", "/file?name=" + (quote(name, safe="") if rng.random() < .3 else name)), {400}
        elif cls == "bad_name_post":
            name, out = bad_name(inputs), bad_name()
            route, req = pick([("/api/open", {"file": name}), ("/api/preview", {"file": name, "select": []}),
                               ("/api/errors", {"bodies": ["fz.h5", name]}),
                               ("/api/modes", {"file": "beam8_free_mat.sti", "body": name}),
                               ("/api/modes", {"file": name, "body": "fz.h5", "n_modes": 0}),
                               ("/api/run", {"command": "export", "body": "fz.h5", "out": out}),
                               ("/api/run", {"command": "export", "body": name, "out": "e.h5"}),
                               ("/api/run", {"command": "export", "body": "fz.h5", "out": "e.h5", "file": name or "."}),
                               ("/api/run", {**_reduce_req(), "out": out}),
                               ("/api/run", {**_reduce_req(), "file": name}),
                               ("/api/run", {"command": "compare", "file": "beam8_free_mat.sti", "bodies": [name]}),
                               ("/api/run", {"command": "report", "file": "beam8_free_mat.sti", "bodies": [name],
                                             "out": "r.html"}),
                               ("/api/run", {"command": "report", "file": "beam8_free_mat.sti", "bodies": ["fz.h5"],
                                             "out": out})])
            data, ok = w.raw("POST", route, req), {400}
        elif cls == "bad_json":
            route, body = bad_json()
            data, ok = w.raw("POST", route, body), {400}
        elif cls == "bad_length":
            length = pick(["-1", "-0", "+3", "abc", "1_0", "", "0x10", "3.0", "1e3", "99999999999999999999", None])
            if length is None:
                data, ok = w.raw("POST", "/api/open"), {411}
            else:
                data, ok = w.raw("POST", "/api/open", b"{}", length=length), {400}
        elif cls == "huge_body":
            data = w.raw("POST", pick(list(("/api/open", "/api/run"))), b"{" + b" " * rng.randrange(0, 1 << 16),
                         length=rng.choice([MAX_BODY + 1, 10 ** 9, 10 ** 15]))
            ok = {413}
        elif cls == "unknown_route":
            target = pick(["/api/nope", "/%2e%2e/%2e%2e" + str(w.outside / "canary.sti"), "/file/..%2F..%2Fetc",
                           "/" + quote(outside), "/api/state/..", "/.%2e/", "/api//state", "/favicon.ico",
                           "/" + junk(6).hex(), "/file%3Fname=beam8_free_mat.inp"])
            data, ok = w.raw(pick(["GET", "POST"]), target, b"{}" if rng.random() < .5 else None), {404}
        elif cls == "bad_method":
            method = pick(["PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "HEAD", "PROPFIND", "X" * 30, "get", "Post"])
            data, ok = w.raw(method, pick(valid_get + ["/api/open", "/nope"]), b"{}"), {405}
        elif cls == "bad_request":
            data = pick([b"\r\n\r\n", b"GET /\r\n\r\n", b"GET / HTTP/2.0\r\n\r\n", b"GET / FTP/1.1\r\n\r\n",
                         b"GET / HTTP/1.1 x\r\n\r\n", junk(40).replace(b"\r\n", b"") + b"\r\n\r\n",
                         w.raw("GET", "/api/state", headers=[f"X-{i}: {i}" for i in range(101)]),
                         w.raw("GET", "/api/state", headers=["X-Long: " + "b" * 66_000]),
                         b"GET /" + b"c" * 66_000 + b" HTTP/1.1\r\n\r\n"])
            ok = {400, 414, 431}
        elif cls == "bad_option":
            flag = pick(["mesh", "output_file", "preload", "units", "memory_limit", "json", "verbose", "o", "backend"])
            data, ok = w.raw("POST", "/api/run", {**_reduce_req(), "options": {flag: outside}}), {400}
        elif cls == "job_id":
            data, ok = w.raw("GET", "/api/job?id=" + quote(pick(["x", "", "0" * 8, "../../", "%00", junk(4).hex()]))), \
                {404}
        else:  # real jobs: two exports of the reduced body at once (the second gets 429 while the first runs)
            for _ in range(2):
                jobs += 1
                job = f"exp{jobs}.h5"
                data = w.raw("POST", "/api/run", {"command": "export", "body": "fz.h5", "out": job})
                cases.append((cls, data, {200, 429}, job, True))
            continue
        cases.append((cls, data, ok, job, False))
    return cases


@pytest.mark.slow
def test_ten_thousand_bad_requests(world):
    w = world
    # a body to export and to ask about, written by a valid job before the mix
    assert w.post("/api/run", _reduce_req())[0] == 200
    assert w.wait_job()["state"] == "done"
    before_inside = snapshot(w.inside)
    cases = _cases(w, random.Random(33), 10_400)
    canary = w.canary.encode()
    batches, i = [], 0
    while i < len(cases):  # the two requests of a job pair go out together from one thread
        n = 2 if cases[i][4] else 1
        batches.append(cases[i:i + n])
        i += n

    def send(batch):
        out = []
        for cls, data, ok, job, _ in batch:
            status, headers, body = w.send(data)
            out.append((cls, status, ok, job, body, data.startswith(b"HEAD ")))
        return out

    t0 = time.monotonic()
    with ThreadPoolExecutor(8) as pool:
        results = [r for rs in pool.map(send, batches) for r in rs]
    seconds = time.monotonic() - t0
    counts, wrong, accepted = collections.Counter(), [], []
    for cls, status, ok, job, body, head in results:
        counts[cls, status] += 1
        if status not in ok:
            wrong.append((cls, status, body[:200]))
        if status >= 400 and not head:
            reason(body)
        assert canary not in body
        if job and status == 200:
            accepted.append(job)
    w.counts = counts
    print(f"\n{len(results)} requests in {seconds:.1f} s:", dict(sorted(counts.items())))
    assert not wrong, sorted(set((c, s, b[:120]) for c, s, b in wrong))[:20]
    assert len(results) >= 10_000 and len({c for c, _ in counts}) == 14 and counts["job", 429] > 0
    # the server still serves, every accepted job ended and wrote its file, nothing else appeared inside
    assert w.get("/api/state")[0] == 200
    while json.loads(w.get("/api/job")[2])["state"] == "running":
        time.sleep(0.05)
    after = snapshot(w.inside)
    assert set(after) - set(before_inside) == set(accepted) and accepted
    assert all(after[k] == v for k, v in before_inside.items())
