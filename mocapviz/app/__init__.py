"""The Panel dashboard (``mocapviz serve [DB]``): browse a MotionDB, query it, compare, all in the browser.

backend.py     Backend: one MotionDB and its cached indexes, feature sets, kd-trees and page results (per database,
               shared by sessions).
state.py       Selection: the session's clip, frame and span, shared by its pages.
documents.py   the documents as pages list and pick them: each one's archive and performer, the Database page's
               filters, DocumentPicker (type to find a document by id, name, label, performer or archive).
progress.py    Task: long computations in a worker thread behind a progress bar; errors as one red line.
jobs.py        JobQueue, JobTask: whole-database computations as jobs, one at a time per server, queued, with progress
               and Cancel, stopped when their session closes.
player.py      SkeletonPlayer: clips sent once and animated in the browser (player.js, Canvas 2D), one or more
               side by side or overlaid, aligned playback.
pages/         one module per page: database (documents, player, timelines, curves), relational (query by
               example, Müller et al. 2005), similarity (DTW search of clips and stretches, kNN of a frame, LNG
               matching, similarity matrix; Krüger et al. 2010), retrieval (retrieval quality of every search
               method: mAP, per-class AP, P/R curves), templates (motion templates, Müller & Röder 2006: a class
               learned from its examples, drawn, its instances found and played), describe (scene descriptions,
               Müller et al. 2005 §6.3: written, read as typed, found; a hit's features drawn, the hit played),
               correlations (Fig. 2), statistics (Müller Tables 2-3, Krüger Table 1), reconstruction (Krüger §5.2),
               audit (the near-copies of the database: pairs, clusters, a pair played, keep one of each cluster).

:func:`dashboard` builds one session's page; :func:`warm_up` runs a small one of each slow first action so that the
first click answers at once; :func:`serve` runs the server (bound to 127.0.0.1 unless told otherwise);
:func:`websocket_origins` lists the addresses it answers to (loopback names, the bound address, on any address other
than loopback the ones listed too, never ``*``), and :func:`refusal` refuses any request whose ``Host``, and any
WebSocket whose ``Origin``, is not one of them.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import re
import time
import warnings
import weakref
from pathlib import Path
from urllib.parse import urlsplit

import panel as pn
from bokeh.util.warnings import BokehUserWarning
from tornado.routing import Matcher, Rule
from tornado.web import RequestHandler

from ..errors import MocapvizError, ParameterError
from ..validation import parse_port, plural
from .auth import Login, signed_in_line
from .backend import Backend, answers_in_memory
from .jobs import on_session_closed, release_memory
from .state import Selection
from .upload import UPLOAD_MESSAGE_BYTES
from .widgets import when_drawn

LOG = logging.getLogger("mocapviz.app")
LOCAL = "127.0.0.1"
TITLE = "mocapviz"


def _pages():
    from .pages import (
        audit,
        correlations,
        database,
        describe,
        reconstruction,
        relational,
        retrieval,
        similarity,
        statistics,
        templates,
    )

    return [("Database", database.DatabasePage), ("Relational query", relational.RelationalPage),
            ("Similarity search", similarity.SimilarityPage), ("Retrieval quality", retrieval.RetrievalPage),
            ("Motion templates", templates.TemplatesPage), ("Describe", describe.DescribePage),
            ("Correlations", correlations.CorrelationsPage),
            ("Index statistics", statistics.StatisticsPage), ("Reconstruction", reconstruction.ReconstructionPage),
            ("Audit", audit.AuditPage)]


def dashboard(db_path, scheduler=None) -> pn.viewable.Viewable:
    """One session's dashboard over the MotionDB at ``db_path``: a header and one tab per page.

    Pages are built when their tab is first opened (the first page at once), so the first page shows quickly; a
    page then answers its default question at once (its ``first_answer``: the session's clip searched, ... behind
    its progress bar), so no page opens empty, and no query runs for a page not yet shown. When the browser session
    closes, its jobs are cancelled (:mod:`mocapviz.app.jobs`) and the memory of its pages returned
    (:func:`session_closed`).
    """
    backend = Backend.open(db_path, scheduler)
    selection = Selection(doc=first_document(backend))
    pages = _pages()
    built: dict[int, object] = {}

    def build(i: int):
        if i not in built:
            built[i] = pages[i][1](backend, selection)
        return built[i]

    tabs = pn.Tabs(*[(name, pn.Column(sizing_mode="stretch_width")) for name, _ in pages], dynamic=False,
                   sizing_mode="stretch_width", css_classes=["mv-tabs"])

    def show(event=None):
        i = tabs.active
        holder = tabs[i]
        first, page = not len(holder), build(i)
        if hasattr(page, "activate"):
            page.activate()
        if first:
            marker = when_drawn(page.first_answer) if hasattr(page, "first_answer") else None
            holder.extend([page] + ([marker] if marker is not None else []))  # one change: the page drawn once

    tabs.param.watch(show, "active")
    show()
    if pn.state.curdoc is not None:  # a browser session (not the dashboard built before the server starts)
        _SESSIONS["open"] += 1
        LOG.info("session opened (%d open)", _SESSIONS["open"])
        on_session_closed(session_closed)
    db = backend.db
    header = pn.pane.Markdown(
        f"## mocapviz · {db.path.name}\n{plural(len(db), 'document')} · {plural(db.n_frames, 'frame')} · "
        + (f"{db.fps:g} fps" if db.fps else "mixed frame rates") + signed_in_line(), css_classes=["mv-header"],
        margin=(0, 10))
    layout = pn.Column(header, tabs, sizing_mode="stretch_width")
    _DASHBOARDS.add(layout)
    return layout


def first_document(backend: Backend) -> int:
    """The document a new session starts at (the first of the database)."""
    return int(backend.documents["doc_id"].iloc[0])


# a session without a browser connected (gone away, or not yet connected: a busy server may take seconds between
# serving the page and its WebSocket) is dropped after CLOSED_SESSION_LIFETIME_MS (Bokeh's 15 s: shorter, a slow
# connection would find its session gone and be built again), looked for every CLOSED_SESSION_CHECK_MS (Bokeh:
# 17 s), so that the jobs and memory of a closed session go within about 17 s, not 32
CLOSED_SESSION_LIFETIME_MS = 15_000
CLOSED_SESSION_CHECK_MS = 2000
_SESSIONS = {"open": 0}  # browser sessions of this server now (for the log)
_DASHBOARDS: weakref.WeakSet = weakref.WeakSet()  # the dashboards still in memory: a closed session's must go
RELEASE_AFTER_S = 2.0  # seconds after a session closed when its memory is given back (Bokeh has dropped it by then)


def session_closed() -> None:
    """A browser session closed: log it, and a little later (its document dropped by Bokeh and Panel) collect its
    pages and give their memory back to the system (:func:`mocapviz.app.jobs.release_memory`)."""
    _SESSIONS["open"] -= 1
    LOG.info("session closed (%d open)", _SESSIONS["open"])
    try:
        asyncio.get_running_loop().call_later(RELEASE_AFTER_S, _release)
    except RuntimeError:  # not on the server's event loop
        _release()


def _release() -> None:
    release_memory()
    answers, size = answers_in_memory()
    LOG.info("memory released: %d dashboard(s) in memory, %d session(s) open; %d answers kept for the next "
             "sessions (%.1f MB)", len(_DASHBOARDS), _SESSIONS["open"], answers, size / 1e6)


WARM_SPAN = 12  # frames of the small queries of the warm-up


def warm_up(backend: Backend) -> dict[str, float]:
    """Run a small one of every action whose first click would otherwise wait, as the pages run them, so that each
    answers in about a second: numba kernels compiled (or loaded from numba's cache), indexes, kd-trees and feature
    sets loaded into ``backend``'s caches, the plotting code imported.

    - Similarity search: DTW search of whole clips and stretches, exact and fast, with warping paths (the F15E
      kd-tree and coarse database of the engine's shard); kNN of a frame (:meth:`Engine.neighbours`) and its Fig. 1
      picture; lazy neighbourhood graph matching with the page's default k (:func:`~.pages.similarity.graph_k`).
    - Relational query: the relational indexes (:meth:`Engine.indexes`, built and saved when missing) and a query by
      example of each kind of hit.
    - Database page: a clip's relational features (its row click draws them).
    - Describe page: a shipped scene description found through the 2005 indexes (the ranking kernel loaded).
    - Motion templates page: the relational features of every frame in the 2006 set, which every template is
      learned from and searched in (8 s on every shared archive at 30 Hz, 446,551 frames), and the page's first
      answer: the template of the first clip's class learned and searched with the page's defaults (the search kernel
      loaded, the answer kept).

    The small queries use a few frames of the longest document; their results are not kept. A step the database
    cannot run (a :class:`~mocapviz.errors.MocapvizError`) is skipped. Returns the seconds of each step (logged at INFO
    level).
    """
    from .pages import relational, similarity

    docs = backend.documents
    doc = int(docs.loc[docs["n_frames"].idxmax(), "doc_id"])
    span = (0, min(WARM_SPAN, int(docs["n_frames"].max())))  # frames of the document, half-open
    db, seconds = backend.db, {}

    def step(name: str, fn) -> None:
        t0 = time.perf_counter()
        try:
            fn()
        except MocapvizError as exc:  # a database the action cannot run on (clips of one frame, ...): its page says so
            LOG.info("warm-up of %s skipped: %s", name, exc)
        seconds[name] = time.perf_counter() - t0

    def search() -> None:
        for kind in similarity.SEARCH_KINDS.values():
            for mode in ("fast", "exact"):
                similarity.search_span(backend, "F15E", doc, span, kind, mode, 1, True)

    def knn() -> None:
        table = similarity.nearest_frames(backend, "F15E", doc, 0, 8, True)
        similarity.neighbours_png(backend, doc, 0, table)

    def lng() -> None:
        k = similarity.graph_k(db.n_frames, backend.fps)
        similarity.match_span(backend, "F15E", doc, span, k, 1, True)

    def relational_query() -> None:
        example = db.motion(doc)[span[0]:span[1]]
        for mode in relational.MODES.values():
            backend.engine.query(example, features=list(relational.DEFAULT_FEATURES), mode=mode, mismatches=1,
                                 relational_set=relational.RELATIONAL_SET)  # fmt: skip

    step("search", search)
    step("knn", knn)
    step("lng", lng)
    step("relational", relational_query)
    step("row_click", lambda: backend.clip_relational(doc))
    step("describe", lambda: backend.engine.find("kick_right", n_matches=1, relational_set="2005"))
    step("templates", lambda: _first_template(backend))
    LOG.info("warmed up in %.1f s (%s)", sum(seconds.values()),
             ", ".join(f"{name} {s:.1f} s" for name, s in seconds.items()))
    return seconds


def _first_template(backend: Backend) -> None:
    """The Motion templates page's first answer for a new session (the class of the session's first clip, every
    actor, its defaults: :func:`~.pages.templates.opening_class`), kept in ``backend``'s caches; only the 2006
    features of every frame when no class has two documents."""
    from .pages import templates

    backend.engine.relational_values("2006")
    label = templates.opening_class(backend.documents, first_document(backend))
    if label is not None:
        templates.learn_and_search(backend, label, (), "2006", templates.DEFAULT_DELTA, templates.DEFAULT_MATCHES,
                                   None)  # fmt: skip


def log_to_stderr() -> None:
    """The server's log on stderr from INFO up (sessions opened and closed, jobs started, finished and cancelled,
    the warm-up's times), one ``mocapviz: <message>`` line each; once per process."""
    if not LOG.handlers:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("mocapviz: %(message)s"))
        LOG.addHandler(handler)
        LOG.setLevel(logging.INFO)
        LOG.propagate = False


def is_loopback(address: str) -> bool:
    """True for ``localhost`` and loopback IP addresses (127.0.0.0/8, ::1): reachable from this machine only."""
    if address == "localhost":
        return True
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        return False


_ORIGIN = re.compile(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9]([A-Za-z0-9.-]*[A-Za-z0-9])?)(:(?P<port>[^:\]/]*))?")
_ORIGIN_HINT = ("give HOST:PORT as the browser's address bar shows it (e.g. --allow-origin myhost.example.org:5006), "
                "without scheme, path or wildcard")


_ANY_ADDRESS = ("0.0.0.0", "::")  # --address values that bind every interface: no address of their own to allow


def websocket_origins(address: str, port: int, allow_origin=()) -> list[str]:
    """The addresses (``host:port``, as browsers send them) the dashboard answers to: every request's ``Host`` header
    and every WebSocket's ``Origin`` must be one of them (:func:`refusal`).

    Parameters
    ----------
    address : str
        The interface the server listens on.
    port : int
        Its port.
    allow_origin : sequence of str
        ``HOST:PORT`` (or ``HOST``: the address without a port, as behind a proxy on port 80 or 443) of the addresses
        users open the dashboard at other than this machine's loopback names (``mocapviz serve --allow-origin``,
        repeatable). Required when ``address`` is not loopback: the dashboard is then reachable from the network,
        and without a list any web page a user opens could drive it.

    Returns
    -------
    list of str
        ``127.0.0.1:PORT``, ``localhost:PORT`` and ``[::1]:PORT``, ``address:PORT`` for an address other than
        ``0.0.0.0`` and ``::``, then ``allow_origin``.

    Raises
    ------
    ParameterError
        ``address`` is not loopback and ``allow_origin`` is empty; an origin is ``*``, holds a wildcard, a scheme or
        a path, or a port outside 1..65535.

    Examples
    --------
    >>> websocket_origins("127.0.0.2", 5006, ["lab.example.org:5006"])
    ['127.0.0.1:5006', 'localhost:5006', '[::1]:5006', '127.0.0.2:5006', 'lab.example.org:5006']
    """
    allow_origin = list(allow_origin or ())
    if not is_loopback(address) and not allow_origin:
        raise ParameterError(f"serving on {address} makes the dashboard reachable from the network: list the "
                             f"origins browsers will open it at with --allow-origin HOST:PORT (repeatable; "
                             f"allow_origin= in Python), e.g. --allow-origin myhost.example.org:{port}; '*' is "
                             f"not accepted")  # fmt: skip
    for origin in allow_origin:
        found = _ORIGIN.fullmatch(str(origin))
        if found is None:
            raise ParameterError(f"--allow-origin {origin!r}: {_ORIGIN_HINT}")
        if found["port"] is not None:
            parse_port(found["port"], f"the port of --allow-origin {origin}")
    hosts = [LOCAL, "localhost", "[::1]"]
    if address not in _ANY_ADDRESS:
        hosts.append(f"[{address}]" if ":" in address else address)
    origins = list(dict.fromkeys(f"{host}:{port}" for host in hosts))
    return origins + [o for o in allow_origin if o not in origins]


_NOT_OURS = "is not an address of this dashboard (mocapviz serve --allow-origin adds one)"


def refusal(headers, allowed) -> str | None:
    """Why the dashboard's server refuses a request, judged by its headers; None when it answers it.

    The ``Host`` header must be one of ``allowed``: a page of any other name reaching the port (a DNS rebinding
    name that resolves to 127.0.0.1, say) gets no page, script or session token. A WebSocket handshake (``Upgrade:
    websocket``) must also carry an ``Origin`` (browsers always send one) whose ``host:port`` is one of ``allowed``,
    even when it equals ``Host``: tornado accepts that case, and one without ``Origin``, before Bokeh's own list is
    consulted. Names are compared without regard to case.

    Parameters
    ----------
    headers : mapping of str to str
        The request's headers: tornado's ``HTTPHeaders``, or a dict spelling the names ``Host``, ``Upgrade``,
        ``Origin``.
    allowed : collection of str
        ``host:port`` names, as :func:`websocket_origins` returns them.

    Returns
    -------
    str or None
        One line naming the refused header and value, or None.

    Examples
    --------
    >>> allowed = websocket_origins("127.0.0.1", 5006)
    >>> refusal({"Host": "localhost:5006"}, allowed) is None
    True
    >>> refusal({"Host": "evil.example.com:5006"}, allowed)
    "Host 'evil.example.com:5006' is not an address of this dashboard (mocapviz serve --allow-origin adds one)"
    >>> refusal({"Host": "localhost:5006", "Upgrade": "websocket", "Origin": "http://a.example"}, allowed)
    "WebSocket Origin 'http://a.example' is not an address of this dashboard (mocapviz serve --allow-origin adds one)"
    """
    allowed = {name.lower() for name in allowed}
    host = headers.get("Host", "")
    if host.lower() not in allowed:
        return f"Host {host!r} {_NOT_OURS}"
    if headers.get("Upgrade", "").lower() == "websocket":
        origin = headers.get("Origin")
        if origin is None:
            return "a WebSocket handshake without an Origin header is refused"
        if urlsplit(origin).netloc.lower() not in allowed:
            return f"WebSocket Origin {origin!r} {_NOT_OURS}"
    return None


class _Refused(Matcher):
    """Matches the requests :func:`refusal` refuses, handing its reason to :class:`_Refuse`."""

    def __init__(self, allowed):
        self.allowed = allowed

    def match(self, request):
        reason = refusal(request.headers, self.allowed)
        return None if reason is None else {"target_kwargs": {"reason": reason}}


class _Refuse(RequestHandler):
    """403 and the reason as plain text, whatever the method and path."""

    def initialize(self, reason: str) -> None:
        self.reason = reason

    def prepare(self) -> None:
        LOG.warning("refused %s %s: %s", self.request.method, self.request.path, self.reason)
        self.set_status(403)
        self.set_header("Content-Type", "text/plain; charset=utf-8")
        self.finish(f"{self.reason}\n")


def serve(db_path, port: int = 5006, address: str = LOCAL, show: bool = False, start: bool = True,
          allow_origin=(), scheduler=None, ready=None, auth=None, cookie_secret_file=None):
    """Serve the dashboard of the MotionDB at ``db_path`` on http://address:port/ until interrupted.

    The database is opened (and checked), one dashboard built and :func:`warm_up` run before the server listens, so
    a bad path fails at once, the first page comes quickly and the first search, kNN, matching and relational query
    answer in about a second. A session whose browser went away is dropped within
    :data:`CLOSED_SESSION_LIFETIME_MS` + :data:`CLOSED_SESSION_CHECK_MS`, its jobs cancelled and its memory returned;
    sessions, jobs and the warm-up are logged on stderr (:func:`log_to_stderr`). The server answers only requests whose ``Host`` is one of :func:`websocket_origins`
    (this machine's loopback names at ``port``, ``address``, ``allow_origin``), and opens a WebSocket only for a page
    of one of them (:func:`refusal`); anything else gets a 403. Any address other than loopback (127.0.0.1,
    localhost, ::1) exposes the database to the network: ``allow_origin`` must then list the addresses (``HOST:PORT``)
    users open it at, and a warning says who can reach it. With ``scheduler`` (a Dask scheduler's address, or
    "local") every session's searches run sharded on that cluster (:class:`mocapviz.sharded.ShardedDB`, one for the
    server), with the same answers. With ``auth`` (a users file, :mod:`mocapviz.users`) every request needs a user
    signed in at ``/login`` (:class:`mocapviz.app.auth.Login`; the cookie secret from ``cookie_secret_file``, else the
    environment, else new). ``ready(url)`` (e.g. a print) is called from the server's event loop once it is
    listening and answering requests: what ``mocapviz serve`` reports as "ready". With ``start=False`` the server is
    returned bound to its port but not started; called in a running event loop (Jupyter), it starts the server on
    that loop and returns it.

    Raises
    ------
    MotionDBError
        ``db_path`` is not a MotionDB, or holds no documents.
    ParameterError
        Not loopback and no ``allow_origin``, or a malformed origin (:func:`websocket_origins`).
    """
    origins = websocket_origins(address, port, allow_origin)
    login = None if auth is None else Login(auth, cookie_secret_file)
    log_to_stderr()
    dashboard(db_path, scheduler)  # once before listening: the first visitor then finds numba kernels, the EGL
    # context,
    # HoloViews' option trees and the first clip's features ready
    warm_up(Backend.open(db_path, scheduler))  # and the first search, kNN, matching and relational query answer at
    # once
    # bokehjs sends a model it received from the server in full with the first message it sends after receiving it,
    # e.g. a button of a page just opened, clicked before anything else changed on the page; the server then warns
    # that it knows the model already, and goes on with the one it has: harmless, and nothing a page can change
    warnings.filterwarnings("ignore", message="reference already known", category=BokehUserWarning)
    if not is_loopback(address) and login is None:
        warnings.warn(f"serving on {address}: anyone who can reach this machine's port {port} can browse "
                      f"{db_path} (pages of {', '.join(origins)} may use it); --auth FILE (auth= in Python) asks "
                      f"for a user name and password", UserWarning, stacklevel=2)
    elif not is_loopback(address):
        warnings.warn(f"serving on {address} over plain HTTP: passwords and sign-in cookies cross the network "
                      f"unencrypted unless a TLS proxy is in front", UserWarning, stacklevel=2)
    pn.extension("tabulator", notifications=False)
    path = Path(db_path)
    # Bokeh's own origin list, consulted after ours, cannot parse a bracketed IPv6 name (ours holds them); Panel's
    # URL-syncing location component, which the dashboard does not use, fails on one (a 500 for Host [::1]:PORT)
    server = pn.serve({"/": lambda: dashboard(path, scheduler)}, port=port, address=address, show=show, start=False,
                      verbose=False, websocket_origin=[o for o in origins if not o.startswith("[")], location=False,
                      title=f"{TITLE} · {path.name}", check_unused_sessions_milliseconds=CLOSED_SESSION_CHECK_MS,
                      unused_session_lifetime_milliseconds=CLOSED_SESSION_LIFETIME_MS,
                      websocket_max_message_size=UPLOAD_MESSAGE_BYTES,
                      **(login.options() if login else {}))
    # The refusal is the first rule of the tornado application's router (where tornado's Application.add_handlers
    # puts rules of its own), ahead of every page, static file and WebSocket route of Bokeh and Panel. Bokeh's Server
    # keeps that application as _tornado, as Panel reads it; nothing outside this server changes.
    server._tornado.default_router.rules.insert(0, Rule(_Refused(origins), _Refuse))
    if login is not None:  # then, with --auth, every request of a visitor not signed in
        server._tornado.default_router.rules.insert(1, login.rule())
    if start:
        server.start()  # its socket is bound and listening since it was made; the loop answers on it
        if ready is not None:
            host = f"[{address}]" if ":" in address else address
            server.io_loop.add_callback(ready, f"http://{host}:{server.port}/")
        if not server.io_loop.asyncio_loop.is_running():  # in a running loop (Jupyter) the server runs on that one
            server.io_loop.start()
    return server


__all__ = ["Backend", "Selection", "dashboard", "is_loopback", "refusal", "serve", "warm_up", "websocket_origins"]
