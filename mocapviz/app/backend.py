"""The dashboard's back end: one opened MotionDB and everything its pages compute from it, cached per database.

A :class:`Backend` is shared by every browser session showing the same database (``Backend.open`` keeps one per
database path and generation, so an ingest that adds documents gives a fresh one). Its results are computed once,
under a lock per result, and kept: a second session, or the same page opened again, gets them at once. The derived
data of the whole database (indexes, feature sets, kd-trees: its :class:`~mocapviz.engine.Engine`'s, and the jobs'
tables, :data:`DERIVED`) stay for the life of the server, one copy for all sessions; the answers to single queries (a search, a kNN, a template's hits, ...) are
kept :data:`ANSWERS_KEPT` per kind, the least recently used forgotten first, so the server's memory does not grow
with every query ever asked.
"""

from __future__ import annotations

import sys
import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pandas as pd

from ..engine import Engine, MotionDB
from ..errors import MotionDBError
from .documents import document_table, picker_options

_BACKENDS: dict = {}
_BY_MANIFEST: dict = {}  # (path, manifest's (mtime, size), scheduler) -> Backend: a session's open reads no table
_OPEN_LOCK = threading.Lock()
# kinds of results (a key's first element) computed over the whole database: kept while the server runs
DERIVED = frozenset({"relational", "statistics", "correlations", "retrieval"})
ANSWERS_KEPT = {"recon-prior": 4, "reconstruction": 16}  # answers kept of these kinds (each holds kd-trees, clips)
DEFAULT_ANSWERS_KEPT = 256  # answers kept of any other kind (hit tables, neighbours, images: small)


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
        self.db = db
        self.scheduler = scheduler
        self.engine = Engine(db, scheduler=scheduler)  # every search and the derived data of the whole database
        self.documents = db.documents
        self.fps = db.typical_fps
        self._results: dict = {}
        self._locks: dict = {}
        self._recent: dict = {}  # kind -> OrderedDict of its answers' keys, least recently used first
        self._guard = threading.Lock()

    def fps_of(self, doc_id: int) -> float:
        """The frame rate of document ``doc_id`` (frames per second)."""
        return float(self.db.document(doc_id)["fps"])

    @classmethod
    def open(cls, path, scheduler=None) -> Backend:
        """The Backend of the MotionDB at ``path`` (one per database path, generation and scheduler, shared); with a
        ``scheduler`` (a Dask scheduler's address, or "local") its searches run sharded on that cluster.

        The database is opened (and checked) once per state of its manifest: a new browser session of an unchanged
        database gets the shared Backend without reading its documents table again.

        Raises
        ------
        MotionDBError
            Not a MotionDB, or an empty one (nothing to show).
        """
        folder = str(Path(path).resolve())
        try:
            manifest = (Path(path) / "manifest.json").stat()
            seen = (folder, manifest.st_mtime_ns, manifest.st_size, scheduler)
        except OSError:  # no manifest: MotionDB.open says what is wrong
            seen = None
        with _OPEN_LOCK:
            if seen in _BY_MANIFEST:
                return _BY_MANIFEST[seen]
        db = MotionDB.open(path)
        if len(db) == 0:
            raise MotionDBError(f"{path}: the database holds no documents; ingest some first (`mocapviz ingest`)")
        key = (folder, db.manifest.get("generation"), scheduler)
        with _OPEN_LOCK:
            if key not in _BACKENDS:
                _BACKENDS[key] = cls(db, scheduler)
            if seen is not None:
                _BY_MANIFEST[seen] = _BACKENDS[key]
            return _BACKENDS[key]

    def cached(self, key, compute):
        """``compute()``'s result, computed once per ``key`` (a hashable) and kept (answers: the
        :func:`answers_kept` most recent of their kind); concurrent callers wait."""
        with self._guard:
            if key in self._results:
                self._used(key)
                return self._results[key]
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            with self._guard:
                if key in self._results:  # computed by the caller this one waited for
                    self._used(key)
                    return self._results[key]
            result = compute()
            with self._guard:
                self._results[key] = result
                self._used(key)
            return result

    def _used(self, key) -> None:
        """An answer just used becomes the most recent of its kind; the least recent beyond the bound go (under the
        guard)."""
        most = answers_kept(key)
        if most is None:
            return
        recent = self._recent.setdefault(key[0] if isinstance(key, tuple) else key, OrderedDict())
        recent[key] = None
        recent.move_to_end(key)
        while len(recent) > most:
            old, _ = recent.popitem(last=False)
            self._results.pop(old, None)
            self._locks.pop(old, None)

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
