"""The dashboard's back end: one opened MotionDB and everything its pages compute from it, cached per database.

A :class:`Backend` is shared by every browser session showing the same database (``Backend.open`` keeps one per
database path and scheduler). Its results are computed once, under a lock per result, and kept: a second session,
or the same page opened again, gets them at once. The derived data of the whole database (indexes, feature sets,
kd-trees: its :class:`~mocapviz.engine.Engine`'s, and the jobs' tables, :data:`DERIVED`) stay for the life of the
generation served, one copy for all sessions; the answers to single queries (a search, a kNN, a template's hits,
...) are kept :data:`ANSWERS_KEPT` per kind, the least recently used forgotten first, so the server's memory does
not grow with every query ever asked.

A served Backend follows its database (:meth:`Backend.follow`): when ``mocapviz ingest`` commits a new generation
(documents appended), it opens it, makes a new Engine with the derived data the old one held (stored indexes and
feature sets extended with the new documents if the ingest has not yet: :func:`mocapviz.engine.update_derived`),
then switches to it: new answers come from the new generation, the kept ones are dropped, and the callbacks of
:meth:`Backend.on_new_documents` (every session's document pickers) are told. A query already running finishes
on the generation it started on: its engine keeps the memory maps it reads, whose files a commit keeps.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
import weakref
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pandas as pd

from ..engine import NUMERIC_SETS, RELATIONAL_SETS, Engine, MotionDB, layout
from ..errors import MotionDBError
from .documents import document_table, picker_options

LOG = logging.getLogger("mocapviz.app")
_BACKENDS: dict = {}  # (folder, scheduler) -> the Backend that serves it
_OPEN_LOCK = threading.Lock()
# kinds of results (a key's first element) computed over the whole database: kept while the server runs
DERIVED = frozenset({"relational", "statistics", "correlations", "retrieval"})
ANSWERS_KEPT = {"recon-prior": 4, "reconstruction": 16}  # answers kept of these kinds (each holds kd-trees, clips)
DEFAULT_ANSWERS_KEPT = 256  # answers kept of any other kind (hit tables, neighbours, images: small)
FOLLOW_SECONDS = 2.0  # a served Backend reads its database's manifest this often for a new generation


def _size(value, depth: int = 1) -> int:
    """Bytes of an answer: numpy arrays and pandas tables by their buffers, ``depth`` levels into tuples, lists and
    dicts, anything else by ``sys.getsizeof``."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, pd.DataFrame):
        return int(value.memory_usage(deep=True).sum())
    if isinstance(value, pd.Series):
        return int(value.memory_usage(deep=True))
    if depth and isinstance(value, (tuple, list, dict)):
        return sum(_size(v, depth - 1) for v in (value.values() if isinstance(value, dict) else value))
    return sys.getsizeof(value)


def answers_in_memory() -> tuple[int, int]:
    """(answers, bytes) kept by every Backend of this process (:meth:`Backend.kept_answers`)."""
    with _OPEN_LOCK:
        backends = list(_BACKENDS.values())
    counts = [b.kept_answers() for b in backends]
    return sum(n for n, _ in counts), sum(size for _, size in counts)


def answers_kept(key) -> int | None:
    """How many results of ``key``'s kind the Backend keeps (None: all, derived data of the whole database); the
    whole-database pose prior ``("recon-prior",)`` is derived data, its restrictions to one prior are answers."""
    kind = key[0] if isinstance(key, tuple) and key else key
    if kind in DERIVED or key == ("recon-prior",):
        return None
    return ANSWERS_KEPT.get(kind, DEFAULT_ANSWERS_KEPT)


def _used(results: dict, locks: dict, recent: dict, key) -> None:
    """An answer just used becomes the most recent of its kind; the least recent beyond the bound go (called under
    the Backend's guard, with the dicts of one generation)."""
    most = answers_kept(key)
    if most is None:
        return
    kind = recent.setdefault(key[0] if isinstance(key, tuple) else key, OrderedDict())
    kind[key] = None
    kind.move_to_end(key)
    while len(kind) > most:
        old, _ = kind.popitem(last=False)
        results.pop(old, None)
        locks.pop(old, None)


class Backend:
    """A MotionDB with cached derived data for the dashboard.

    Attributes
    ----------
    db : MotionDB
    engine : Engine, the database's engine (in this process, or on the cluster of ``scheduler``): every search and
        the derived data of the whole database (indexes, feature sets, kd-trees) go through it.
    documents : pandas.DataFrame, the database's document table.
    fps : float, the database's typical frame rate: the rate of most of its frames (for defaults that scale with
        the rate, such as the neighbours k at 30 Hz); a duration or playback of a document uses
        :meth:`fps_of` that document.
    """

    def __init__(self, db: MotionDB, scheduler=None):
        self.scheduler = scheduler
        self._guard = threading.Lock()
        self._switching = threading.Lock()  # one switch to a new generation at a time
        self._watchers: list = []  # weak references to the callbacks of on_new_documents
        self._use(db, Engine(db, scheduler=scheduler))  # every search and the derived data of the whole database

    def _use(self, db: MotionDB, engine: Engine) -> None:
        """Serve ``db`` through ``engine`` from now on, with no answer kept (new dicts: an answer of the previous
        generation still being computed goes to the old ones)."""
        with self._guard:
            self.db, self.engine, self.documents, self.fps = db, engine, db.documents, db.typical_fps
            self._results, self._locks, self._recent = {}, {}, {}  # _recent: kind -> OrderedDict, least recent first

    def fps_of(self, doc_id: int) -> float:
        """The frame rate of document ``doc_id`` (frames per second)."""
        return float(self.db.document(doc_id)["fps"])

    @property
    def generation(self) -> int:
        """The generation of the database served (its manifest's)."""
        return int(self.db.manifest["generation"])

    @classmethod
    def open(cls, path, scheduler=None) -> Backend:
        """The Backend of the MotionDB at ``path`` (one per database path and scheduler, shared, following the
        database: :meth:`follow`); with a ``scheduler`` (a Dask scheduler's address, or "local") its searches run
        sharded on that cluster.

        The database is opened (and checked) once; a new browser session gets the shared Backend, switched to the
        database's newest generation first (waiting for a switch under way), without reading its documents table
        again.

        Raises
        ------
        MotionDBError
            Not a MotionDB, or an empty one (nothing to show).
        """
        key = (str(Path(path).resolve()), scheduler)
        with _OPEN_LOCK:
            backend = _BACKENDS.get(key)
        if backend is not None:
            backend.follow()
            return backend
        db = MotionDB.open(path)
        if len(db) == 0:
            raise MotionDBError(f"{path}: the database holds no documents; ingest some first (`mocapviz ingest`)")
        with _OPEN_LOCK:
            if key not in _BACKENDS:
                _BACKENDS[key] = backend = cls(db, scheduler)
                threading.Thread(target=backend._poll, name="mocapviz-follow", daemon=True).start()
            return _BACKENDS[key]

    # ------------------------------------------------------------------ following the database
    def follow(self) -> bool:
        """Switch to the newest generation of the database if one was committed since (an ingest while serving).

        The new generation is opened and its Engine made with the derived data this one holds (indexes, numeric
        sets and kd-trees: stored ones loaded, or extended with the new documents and stored), all before the
        switch, so that sessions keep their answers from the old generation until the new one is ready; then the
        kept answers are dropped and the :meth:`on_new_documents` callbacks called. A query running on the old
        Engine finishes there (its memory maps stay valid: a commit keeps the previous generation's files).

        Returns
        -------
        bool
            Whether it switched.
        """
        with self._switching:
            try:
                newest = json.loads(layout.manifest_file(self.db.path).read_text())["generation"]
            except (OSError, ValueError, KeyError, TypeError):  # being replaced, or gone: looked at again later
                return False
            if not isinstance(newest, int) or newest <= self.generation:
                return False
            t0, old = time.perf_counter(), self.engine
            db = MotionDB.open(self.db.path)
            engine = Engine(db, scheduler=self.scheduler,
                            numeric_sets=[n for n in NUMERIC_SETS if old.holds("search", n)],
                            relational_sets=[r for r in RELATIONAL_SETS if old.holds("indexes", r)])  # fmt: skip
            added = len(db) - len(self.db)
            self._use(db, engine)
        LOG.info("%s: generation %d, %d documents (%+d), followed in %.1f s", db.path, db.manifest["generation"],
                 len(db), added, time.perf_counter() - t0)
        self._notify()
        return True

    def on_new_documents(self, callback) -> None:
        """Call ``callback(backend)`` after each switch to a new generation (:meth:`follow`), on the thread that
        switched. A bound method is held weakly (a closed session's widgets are not kept alive by it), a function
        strongly."""
        ref = weakref.WeakMethod(callback) if hasattr(callback, "__self__") else (lambda: callback)
        with self._guard:
            self._watchers = [w for w in self._watchers if w() is not None] + [ref]

    def _notify(self) -> None:
        with self._guard:
            callbacks = [c for c in (w() for w in self._watchers) if c is not None]
        for callback in callbacks:
            try:
                callback(self)
            except Exception:  # one session's widget must not stop the others'
                LOG.exception("a new-documents callback failed")

    def _poll(self) -> None:
        """Follow the database every :data:`FOLLOW_SECONDS` (the thread of a served Backend)."""
        while True:
            time.sleep(FOLLOW_SECONDS)
            try:
                self.follow()
            except Exception:  # a damaged new generation: said in the log, the old one still served
                LOG.exception("%s: cannot follow the database", self.db.path)

    def cached(self, key, compute):
        """``compute()``'s result, computed once per ``key`` (a hashable) and kept (answers: the
        :func:`answers_kept` most recent of their kind); concurrent callers wait. A result computed while the
        Backend switched generation is returned but kept with the old generation's."""
        with self._guard:
            results, locks, recent = self._results, self._locks, self._recent
            if key in results:
                _used(results, locks, recent, key)
                return results[key]
            lock = locks.setdefault(key, threading.Lock())
        with lock:
            with self._guard:
                if key in results:  # computed by the caller this one waited for
                    _used(results, locks, recent, key)
                    return results[key]
            result = compute()
            with self._guard:
                results[key] = result
                _used(results, locks, recent, key)
            return result

    def is_cached(self, key) -> bool:
        return key in self._results

    def kept_answers(self) -> tuple[int, int]:
        """(answers, bytes) of the single-query answers kept for the next session (:func:`answers_kept` of their
        kinds; the whole-database data of :data:`DERIVED` left out): arrays and tables counted by their buffers,
        one level into tuples, lists and dicts, anything else by ``sys.getsizeof``.

        Examples
        --------
        >>> from mocapviz import MotionDB
        >>> b = Backend(MotionDB.sample())
        >>> _ = b.cached(("answer", 1), lambda: np.zeros(1000))
        >>> _ = b.cached(("statistics", "x"), lambda: np.zeros(5000))  # derived data: not an answer
        >>> b.kept_answers()
        (1, 8000)
        """
        with self._guard:
            answers = [value for key, value in self._results.items() if answers_kept(key) is not None]
        return len(answers), sum(_size(v) for v in answers)

    # ------------------------------------------------------------------ derived data
    def clip_relational(self, doc: int, relational_set: str = "2005") -> tuple[np.ndarray, list[str]]:
        """One document's relational features: (T, f) bool and the f names, computed on the clip (§3)."""
        return self.cached(("relational", doc, relational_set),
                           lambda: self.engine.clip_relational(doc, relational_set=relational_set))

    def retrieval(self, methods, label_column: str = "label", group_column=None, n_queries: int | None = None,
                  seed: int = 0) -> dict:  # fmt: skip
        """:meth:`Engine.quality` of the database, computed once per arguments."""
        methods = tuple(methods)
        key = ("retrieval", methods, label_column, group_column, n_queries, seed)
        return self.cached(key, lambda: self.engine.quality(methods, label_column=label_column,
                                                            group_column=group_column, n_queries=n_queries,
                                                            seed=seed, progress=False))  # fmt: skip

    def document_table(self) -> pd.DataFrame:
        """The documents as the dashboard lists them, with their archive and performer
        (:func:`mocapviz.app.documents.document_table`), built once per database."""
        return self.cached(("document table",), lambda: document_table(self.documents))

    def doc_options(self) -> dict:
        """{"<id>: <name> · <label> · <performer> · <archive>": doc_id} for a document picker, in document order
        (:func:`mocapviz.app.documents.picker_options`), built once per database."""
        return self.cached(("document options",), lambda: picker_options(self.document_table()))


def demo_database() -> Path:
    """The folder of :meth:`MotionDB.demo` (the embedded demo at 30 Hz, built once): what ``mocapviz serve`` serves
    when given no database."""
    return MotionDB.demo().path
