"""Simulated sessions of a served dashboard, driven at the protocol level (Bokeh's WebSocket protocol), no browser.

A :class:`Client` is one session of ``mocapviz serve``: :func:`bokeh.client.pull_session` pulls the session's
document (the same the server builds for a browser), then the client changes widget values and sends button clicks
(``ButtonClick`` events) in that document, so the server runs the callbacks a browser's clicks run, and waits for the
answers by watching the result panes change. :func:`protocol_round` runs the scripted round of
:func:`dashboard_sessions.session_round` (open, choose a document, whole-clip search, kNN, relational query, motion
template, description; Index statistics and Correlations opened), checking each answer names the session's own query
and has the library's hit count; :func:`run_load` runs N such sessions in a loop while one real Chromium runs the
browser round, and measures the server's CPU and RSS (psutil). Used by benchmarks/bench_sessions.py and
tests/test_app_sessions.py.

The client holds a copy of every model the server sends (Panel's, the dashboard's own), so it imports their classes
first (:func:`_register_models`). Bokeh's client opens its WebSocket without an ``Origin`` header, which the
dashboard refuses (:func:`mocapviz.app.refusal`): :func:`_with_origin` adds the server's own, as a browser does.
"""

from __future__ import annotations

import asyncio
import html
import importlib
import re
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from dashboard_sessions import KINDS, TIMEOUT_MS, Query, Rounds, run_sessions

TIMEOUT_S = TIMEOUT_MS / 1000
_TAGS = re.compile(r"<[^>]+>")
_MODEL_MODULES = ("panel.models.tabulator", "mocapviz.app.player", "mocapviz.app.gallery",
                  *(f"mocapviz.app.pages.{page}" for page in ("database", "relational", "similarity", "templates",
                                                               "describe", "statistics", "correlations")))


def _register_models() -> None:
    """Import the classes of every model a dashboard's document holds (Panel's lazily loaded ones, the dashboard's
    player and gallery components), so that the client can read the document."""
    for module in _MODEL_MODULES:
        importlib.import_module(module)


def _with_origin() -> None:
    """Make Bokeh's client send ``Origin: http://host:port`` (the server's own address) with its WebSocket
    handshake, as a browser does; once per process."""
    from bokeh.client import connection

    if getattr(connection.websocket_connect, "with_origin", False):
        return
    plain = connection.websocket_connect

    async def connect(request, *args, **kwargs):
        netloc = request.url.split("/")[2]
        request.headers["Origin"] = f"http://{netloc}"
        return await plain(request, *args, **kwargs)

    connect.with_origin = True
    connection.websocket_connect = connect


class Client:
    """One dashboard session over Bokeh's WebSocket protocol, on an event loop of its own (one thread each)."""

    def __init__(self, url: str):
        from bokeh.client import pull_session
        from tornado.ioloop import IOLoop

        _register_models()
        _with_origin()
        asyncio.set_event_loop(asyncio.new_event_loop())  # this thread's own (Bokeh's client asks for the current one)
        self.loop = IOLoop.current()
        self.session = pull_session(url=url, io_loop=self.loop)
        self.doc = self.session.document
        self._found: dict = {}
        self._seen = 0  # models in the document when :meth:`_draw` last looked
        from bokeh.events import DocumentReady

        self.doc.callbacks.send_event(DocumentReady())  # BokehJS's once the page is drawn: pn.state.onload runs
        self._draw()

    def _draw(self) -> None:
        """Do what the browser's drawing of new views does: a :class:`mocapviz.app.widgets.Drawn` marker reports
        ``drawn`` (its page's first answer then starts)."""
        if len(self.doc.models) == self._seen:
            return
        self._seen = len(self.doc.models)
        for m in list(self.doc.models):
            if type(m).__name__.startswith("Drawn") and hasattr(m, "drawn") and not m.drawn:
                m.drawn = True

    def model(self, css: str):
        """The first model of the document with CSS class ``css`` (None while there is none)."""
        found = self._found.get(css)
        if found is not None and self.doc.get_model_by_id(found.id) is found:
            return found
        for m in self.doc.models:
            if css in (getattr(m, "css_classes", None) or ()):
                self._found[css] = m
                return m
        return None

    def text(self, css: str) -> str:
        """The text a pane of class ``css`` shows (its HTML unescaped, tags dropped, blanks collapsed); "" while
        there is no such pane."""
        m = self.model(css)
        raw = getattr(m, "text", None) or ""
        return " ".join(_TAGS.sub(" ", html.unescape(html.unescape(str(raw)))).split())

    def wait(self, predicate, what: str, timeout: float = TIMEOUT_S) -> None:
        """Process the server's messages until ``predicate()`` holds (checked after each message); fails with
        ``what`` after ``timeout`` seconds (the session is then unusable: close it)."""
        if predicate():
            return
        deadline = time.monotonic() + timeout
        expired = []

        def stop():
            expired.append(True)
            self.loop.stop()

        timer = self.loop.call_later(timeout, stop)

        failed = []

        def done() -> bool:
            try:
                self._draw()
                return predicate() or time.monotonic() > deadline
            except Exception as exc:  # noqa: BLE001 - raised again below, out of the event loop
                failed.append(exc)
                return True

        self.session._connection._loop_until(done)
        self.loop.remove_timeout(timer)
        if failed:
            raise failed[0]
        if expired or not predicate():
            raise TimeoutError(f"no {what} after {timeout:.0f} s")

    def wait_text(self, css: str, pattern, timeout: float = TIMEOUT_S) -> str:
        """Wait until the pane of class ``css`` shows text matching ``pattern`` (a str to find or a regex)."""
        found = (lambda t: pattern in t) if isinstance(pattern, str) else (lambda t: pattern.search(t) is not None)
        self.wait(lambda: found(self.text(css)), f"{pattern!r} in .{css} (it shows {self.text(css)!r})", timeout)
        return self.text(css)

    def click(self, css: str) -> None:
        """Click the button of class ``css`` (a ``ButtonClick`` event, as BokehJS sends it), once it is enabled."""
        from bokeh.events import ButtonClick

        self.wait(lambda: self.model(css) is not None and not self.model(css).disabled, f"enabled .{css} button")
        self.doc.callbacks.send_event(ButtonClick(self.model(css)))

    def tab(self, name: str) -> None:
        """Open the page tab called ``name``."""
        tabs = self.model("mv-tabs")
        tabs.active = [t.title for t in tabs.tabs].index(name)

    def close(self) -> None:
        self.session.close()
        self.loop.close(all_fds=True)
        asyncio.set_event_loop(None)


def _player_shows(client: Client, name: str, n_frames: int) -> bool:
    view = client.model("mv-player")
    meta = view.data.meta if view is not None else {}
    return meta.get("titles") == [name] and meta.get("lengths") == [n_frames]


def protocol_round(url: str, q: Query, seconds: dict) -> None:
    """One simulated session: the steps of :func:`dashboard_sessions.session_round`, each answer waited for by its
    text naming ``q``'s document, class and K with the library's hit count (a TimeoutError otherwise); the seconds
    of each step appended to ``seconds[kind]``; the session closed at the end."""
    t0 = time.perf_counter()
    client = Client(url)
    try:
        client.wait(lambda: client.model("mv-player") is not None and client.model("mv-player").data.meta, "player")
        seconds["open"].append(time.perf_counter() - t0)
        _steps(client, q, seconds)
    finally:
        client.close()


def _timed(seconds: dict, kind: str, action, wait) -> None:
    t0 = time.perf_counter()
    action()
    wait()
    seconds[kind].append(time.perf_counter() - t0)


def _steps(c: Client, q: Query, seconds: dict) -> None:
    from panel.models.tabulator import SelectionEvent

    table = c.model("mv-documents")
    row = list(table.source.data["name"]).index(q.name)  # the row clicked, as Tabulator reports it
    click = SelectionEvent(table, indices=[row], selected=True, flush=True)
    # what BokehJS sends with it (the Python class sends only its model: it is meant to be received)
    click.event_values = lambda: {"model": table, "indices": [row], "selected": True, "flush": True}
    _timed(seconds, "row_click", lambda: c.doc.callbacks.send_event(click),
           lambda: c.wait(lambda: _player_shows(c, q.name, q.n_frames), f"player of {q.name}"))

    c.tab("Similarity search")
    c.wait_text("mv-similarity-query", f"document {q.doc_id} ({q.name})")
    _timed(seconds, "search", lambda: c.click("mv-search-run"),
           lambda: c.wait_text("mv-search-count", f"like document {q.doc_id} frames 0:{q.n_frames} "))
    _timed(seconds, "knn", lambda: c.click("mv-knn-search"),
           lambda: c.wait_text("mv-knn-count", f"of document {q.doc_id} frame 0 "))

    c.tab("Relational query")
    c.wait_text("mv-hit-caption", q.name)
    _timed(seconds, "relational", lambda: c.click("mv-run"),
           lambda: c.wait_text("mv-hit-count", re.compile(rf"(^|\D){q.relational_hits} hits? for ")))
    if q.name not in c.text("mv-hit-caption"):
        raise AssertionError(f"session of document {q.doc_id}: the relational query's clip changed")

    c.tab("Motion templates")
    c.wait(lambda: c.model("mv-templates-class") is not None, "the class menu")
    c.model("mv-templates-class").value = q.template_label
    _timed(seconds, "template", lambda: c.click("mv-templates-run"),
           lambda: c.wait_text("mv-templates-count", f"of the {q.template_label} template"))

    c.tab("Describe")
    c.wait(lambda: c.model("mv-describe-k") is not None, "the K box")
    c.model("mv-describe-k").value = q.k
    _timed(seconds, "describe", lambda: c.click("mv-describe-find"),
           lambda: c.wait_text("mv-describe-count", re.compile(rf"(^|\D){q.describe_hits} hits? \(K = {q.k};")))

    c.tab("Index statistics")
    c.wait_text("mv-table1", "k")
    c.tab("Correlations")
    c.wait(lambda: bool(getattr(c.model("mv-heatmap-segment"), "renderers", None)), "the segment heatmap")


@dataclass
class Load:
    """What :func:`run_load` measured: the seconds of each step of the simulated sessions and of the browser, the
    rounds each completed, the errors, the server's CPU (share of one core, sampled) and RSS (MB)."""

    simulated: dict = field(default_factory=lambda: {kind: [] for kind in KINDS})
    browser: Rounds | None = None
    rounds: int = 0
    errors: list = field(default_factory=list)
    cpu: list = field(default_factory=list)
    rss_mb: list = field(default_factory=list)
    wall_s: float = 0.0

    def p(self, which: str, kind: str, q: float) -> float:
        values = self.simulated[kind] if which == "simulated" else self.browser.seconds[kind]
        return float(np.percentile(values, q)) if values else float("nan")


def _server_processes(pid: int) -> list:
    import psutil

    root = psutil.Process(pid)
    return [root, *root.children(recursive=True)]


PER_PROCESS = 4  # simulated sessions per worker process: each reads its sessions' patches in Python, under one GIL


def _simulate(url: str, queries: list, first: int, count: int, done, min_rounds: int, out) -> None:
    """Sessions ``first .. first + count - 1`` (one thread each) of :func:`run_load`, in a worker process: each runs
    :func:`protocol_round` of ``queries[i % len(queries)]`` until ``done`` is set and it ran ``min_rounds`` rounds, or
    until its first error; puts (seconds per kind, rounds, errors) on ``out``."""
    _register_models()  # imported before any session is timed
    _with_origin()
    seconds, errors, rounds = {kind: [] for kind in KINDS}, [], [0]
    lock = threading.Lock()

    def session(i: int) -> None:
        q, ran = queries[i % len(queries)], 0
        while ran < min_rounds or not done.is_set():
            mine = {kind: [] for kind in KINDS}
            try:
                protocol_round(url, q, mine)
            except Exception as exc:  # noqa: BLE001 - reported by the caller
                with lock:
                    errors.append(f"simulated session {i} ({q.name}): {type(exc).__name__}: {exc}")
                return
            ran += 1
            with lock:
                rounds[0] += 1
                for kind in KINDS:
                    seconds[kind].extend(mine[kind])

    threads = [threading.Thread(target=session, args=(i,), name=f"simulated-{i}") for i in range(first, first + count)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    out.put((seconds, rounds[0], errors))


def run_load(url: str, pid: int, queries: list, n: int, chromium=None, chromium_args=(), browser_rounds: int = 3,
             min_rounds: int = 1) -> Load:
    """``n`` simulated sessions, each running :func:`protocol_round` of ``queries[i % len(queries)]`` over and over
    (:data:`PER_PROCESS` per worker process), while one Chromium runs :func:`dashboard_sessions.session_round`
    ``browser_rounds`` times one after the other (of ``queries[0]``; none without ``chromium``); the simulated
    sessions stop once the browser is done and each ran ``min_rounds`` rounds. The server (process ``pid`` and its
    children) is sampled every second meanwhile."""
    import multiprocessing

    import psutil

    load = Load()
    spawn = multiprocessing.get_context("spawn")
    done, out = spawn.Event(), spawn.Queue()
    groups = [(first, min(PER_PROCESS, n - first)) for first in range(0, n, PER_PROCESS)]
    workers = [spawn.Process(target=_simulate, args=(url, queries, first, count, done, min_rounds, out),
                             name=f"simulated-{first}") for first, count in groups]  # fmt: skip

    def sample() -> None:
        procs = _server_processes(pid)
        for p in procs:
            p.cpu_percent(None)
        while not stopped.wait(1.0):
            try:
                load.cpu.append(sum(p.cpu_percent(None) for p in procs))
                load.rss_mb.append(sum(p.memory_info().rss for p in procs) / 2**20)
            except psutil.NoSuchProcess:
                procs = _server_processes(pid)

    stopped = threading.Event()
    sampler = threading.Thread(target=sample, name="server-sampler")
    sampler.start()
    t0 = time.perf_counter()
    for w in workers:
        w.start()
    try:
        if chromium is not None:
            load.browser = Rounds()
            for _ in range(browser_rounds):
                rounds = run_sessions(chromium, list(chromium_args), url, queries[:1])
                load.browser.errors.extend(rounds.errors)
                for kind in KINDS:
                    load.browser.seconds[kind].extend(rounds.seconds[kind])
    finally:
        done.set()
        for _ in workers:
            seconds, rounds, errors = out.get(timeout=2 * TIMEOUT_S)  # a round left at most TIMEOUT_S per answer
            load.rounds += rounds
            load.errors.extend(errors)
            for kind in KINDS:
                load.simulated[kind].extend(seconds[kind])
        for w in workers:
            w.join()
        load.wall_s = time.perf_counter() - t0
        stopped.set()
        sampler.join()
    return load
