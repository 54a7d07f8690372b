"""The explorer's local web server: the page, its JSON answers, and work that outlasts a blink.

Standard library only (``http.server`` on threads): the page (``static/``) draws everything
itself, so the server's answer to a change is the library's numbers as JSON, nothing more. Each
request runs on a worker thread; when it takes longer than :data:`BUDGET` (a stiff point, a long
line, the first run compiling the solver) the answer is ``{"pending": id}`` at once and the page
says so and asks again (``/api/job/<id>``) while staying usable. A request that a newer one of
the same kind has overtaken before it started is dropped, so a slider dragged over a slow region
does not queue stale work. A bad input is ``{"error": one line}``.

Served on 127.0.0.1 only; requests naming another host (a web page trying DNS rebinding) are
refused.
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import threading
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources

from ..parameters import ParameterError
from . import answers

HOST = "127.0.0.1"
# How long a request may take before it is answered "pending" and finished in the background.
BUDGET = 0.08
# Finished background answers kept for the page to fetch.
KEEP_JOBS = 256
STATIC = {"/": ("index.html", "text/html; charset=utf-8"),
          "/static/app.js": ("app.js", "text/javascript; charset=utf-8"),
          "/static/style.css": ("style.css", "text/css; charset=utf-8")}
# What each kind of request runs, and on which pool: a point and the map are quick, a line
# and an export may take seconds and must not hold up the quick ones.
KINDS = {"point": ("fast", answers.point), "map": ("fast", answers.solvability_map),
         "line": ("slow", answers.line), "export": ("slow", None)}
FIRST_RUN = "the first run of a new version compiles the solver: about a minute"


def _one_line(text) -> str:
    return " ".join(str(text).split())


class Explorer:
    """The server's state: worker pools, background jobs, the directory exports go to.

    Parameters
    ----------
    directory : str
        Where the export button writes (files are never replaced).
    budget : float
        Seconds a request may take before its answer goes to the background.
    """

    def __init__(self, directory: str = ".", budget: float = BUDGET):
        self.directory = os.path.abspath(directory)
        self.budget = budget
        self.pools = {"fast": ThreadPoolExecutor(2, thread_name_prefix="explore-fast"),
                      "slow": ThreadPoolExecutor(1, thread_name_prefix="explore-slow")}
        self.jobs: dict[str, object] = {}
        self.latest: dict[str, int] = {}
        self.ids = itertools.count(1)
        self.lock = threading.Lock()
        self.warm = threading.Event()

    def warm_up(self) -> None:
        """Compile and load what the page's first answers need, on the quick pool."""

        def run():
            try:
                form = default_form()
                answers.point(form)
                answers.solvability_map(form)
                answers.line(form)
            except Exception:  # the page's own requests report what fails
                pass
            finally:
                self.warm.set()

        self.pools["fast"].submit(run)

    def _run(self, kind: str, seq: int, form: dict, client: str) -> dict:
        with self.lock:
            if seq < self.latest.get((client, kind), 0):
                return {"stale": True}
        t0 = time.perf_counter()
        try:
            if kind == "export":
                answer = answers.export(form, self.directory)
            else:
                answer = KINDS[kind][1](form)
        except ParameterError as exc:
            answer = {"error": _one_line(exc)}
        except Exception as exc:  # one line on the page; the traceback for the terminal
            traceback.print_exc(file=sys.stderr)
            answer = {"error": _one_line(f"{kind} failed: {type(exc).__name__}: {exc}")}
        answer["seconds"] = time.perf_counter() - t0
        return answer

    def ask(self, kind: str, seq: int, form: dict, client: str = "") -> dict:
        """Answer request ``seq`` of ``kind`` within the budget, or ``{"pending": id}``.

        ``seq`` counts a page's requests of one kind; ``client`` names the page (each open page
        has its own count, so that one page's requests never overtake another's)."""
        if kind not in KINDS:
            return {"error": f"unknown request {kind!r}"}
        with self.lock:
            self.latest[client, kind] = max(seq, self.latest.get((client, kind), 0))
            while len(self.latest) > KEEP_JOBS:
                self.latest.pop(next(iter(self.latest)))
        future = self.pools[KINDS[kind][0]].submit(self._run, kind, seq, form, client)
        try:
            return future.result(timeout=self.budget)
        except FutureTimeout:
            pass
        job = str(next(self.ids))
        with self.lock:
            self.jobs[job] = future
            while len(self.jobs) > KEEP_JOBS:
                self.jobs.pop(next(iter(self.jobs)))
        why = ("working in the background: " + FIRST_RUN) if not self.warm.is_set() else \
            {"point": "a stiff point: solving in the background",
             "map": "reading the atlas in the background",
             "line": "solving the line in the background",
             "export": "writing the files in the background"}[kind]
        return {"pending": job, "note": why}

    def job(self, job: str, wait: float = 0.25) -> dict:
        """A background answer, waiting up to ``wait`` s; ``{"pending": job}`` if still running."""
        with self.lock:
            future = self.jobs.get(job)
        if future is None:
            return {"error": f"no background job {job!r} (the server keeps the last {KEEP_JOBS})"}
        try:
            return future.result(timeout=wait)
        except FutureTimeout:
            return {"pending": job}

    def close(self) -> None:
        for pool in self.pools.values():
            pool.shutdown(wait=False, cancel_futures=True)


def default_form() -> dict:
    """The page's inputs at start: the paper's figure 2 with its material."""
    form = {k: s["default"] for k, s in answers.SLIDERS.items()}
    form.update(answers.MATERIAL_DEFAULTS, eps_from="eps", N_from="N", material=True,
                rtol=repr(answers.DEFAULT_RTOL), line_x="eps", line_y="Delta")
    return form


class _Handler(BaseHTTPRequestHandler):
    server_version = "cosserat-channel-explore"
    explorer: Explorer = None  # set per server by make_server

    def log_message(self, format, *args):  # quiet: the terminal shows the address and errors
        pass

    def _send(self, body: bytes, ctype: str, code: int = HTTPStatus.OK) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, obj, code: int = HTTPStatus.OK) -> None:
        self._send(json.dumps(obj, allow_nan=False).encode(), "application/json", code)

    def _host_ok(self) -> bool:
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
        if host in (HOST, "localhost", "[::1]"):
            return True
        self._json({"error": "this server answers requests to 127.0.0.1 only"},
                   HTTPStatus.FORBIDDEN)
        return False

    def do_GET(self):
        if not self._host_ok():
            return
        path = self.path.split("?", 1)[0]
        if path in STATIC:
            name, ctype = STATIC[path]
            body = resources.files(__package__).joinpath("static", name).read_bytes()
            self._send(body, ctype)
        elif path == "/api/meta":
            self._json(answers.meta() | {"defaults": default_form()})
        elif path == "/favicon.ico":
            self._send(b"", "image/x-icon", HTTPStatus.NO_CONTENT)
        elif path.startswith("/api/job/"):
            self._json(self.explorer.job(path.rsplit("/", 1)[1]))
        else:
            self._json({"error": f"no page {path!r}"}, HTTPStatus.NOT_FOUND)

    def do_POST(self):
        if not self._host_ok():
            return
        path = self.path.split("?", 1)[0]
        try:
            length = int(self.headers.get("Content-Length") or 0)
            body = json.loads(self.rfile.read(min(length, 1 << 20)) or b"{}")
            kind = path.removeprefix("/api/")
            answer = self.explorer.ask(kind, int(body.get("seq", 0)), body.get("form") or {},
                                       str(body.get("client", "")))
        except (ValueError, TypeError, AttributeError) as exc:
            answer = {"error": _one_line(f"bad request: {exc}")}
        self._json(answer)


def make_server(port: int = 0, directory: str = ".", budget: float = BUDGET):
    """A server on 127.0.0.1 (``port`` 0: a free one) and its :class:`Explorer`, warming up."""
    explorer = Explorer(directory, budget)
    handler = type("Handler", (_Handler,), {"explorer": explorer})
    httpd = ThreadingHTTPServer((HOST, port), handler)
    httpd.daemon_threads = True
    explorer.warm_up()
    return httpd, explorer


def url_of(httpd) -> str:
    return f"http://{HOST}:{httpd.server_address[1]}/"


class Running:
    """A server running on a background thread (the notebook's :func:`explore`): its ``url``,
    :meth:`stop`, and the page itself as a notebook cell's output (an ``iframe``)."""

    def __init__(self, port: int = 0, directory: str = ".", height: int = 980):
        self.httpd, self.explorer = make_server(port, directory)
        self.url = url_of(self.httpd)
        self.height = height
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True,
                                       name="explore-server")
        self.thread.start()

    def stop(self) -> None:
        """Stop serving and free the port."""
        self.httpd.shutdown()
        self.httpd.server_close()
        self.explorer.close()

    def __repr__(self) -> str:
        return f"<cosserat-channel explorer at {self.url}>"

    def _repr_html_(self) -> str:
        return (f'<iframe src="{self.url}" width="100%" height="{self.height}" '
                f'style="border:0" title="cosserat-channel explorer"></iframe>'
                f'<div>explorer at <a href="{self.url}" target="_blank">{self.url}</a></div>')
