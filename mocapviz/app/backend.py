"""The dashboard's back end: one opened MotionDB and everything its pages compute from it, cached per database.

A :class:`Backend` is shared by every browser session showing the same database (``Backend.open`` keeps one per
database path and generation, so an ingest that adds documents gives a fresh one). Its results are computed once,
under a lock per result, and kept: a second session, or the same page opened again, gets them at once. The derived
data of the whole database (:data:`DERIVED`: indexes, feature sets, kd-trees, the jobs' tables) stay for the life of
the server, one copy for all sessions; the answers to single queries (a search, a kNN, a template's hits, ...) are
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

from ..db.database import MotionDB
from ..errors import MotionDBError
from ..features import numeric_of, relational_features
from ..relational import index as index_mod
from ..similarity.knn import KnnIndex
from .documents import document_table, picker_options

_BACKENDS: dict = {}
_BY_MANIFEST: dict = {}  # (path, manifest's (mtime, size), scheduler) -> Backend: a session's open reads no table
_OPEN_LOCK = threading.Lock()
# kinds of results (a key's first element) computed over the whole database: kept while the server runs
DERIVED = frozenset({"indexes", "relational", "numeric", "knn", "search", "templates.features", "statistics",
                     "correlations", "retrieval"})  # fmt: skip
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
    documents : pandas.DataFrame, the database's document table.
    fps : float, the database's typical frame rate: the rate of most of its frames (for defaults that scale with
        the rate, such as the neighbours k at 30 Hz); a duration or playback of a document uses
        :meth:`fps_of` that document.
    """

    def __init__(self, db: MotionDB, scheduler=None):
        self.db = db
        self.scheduler = scheduler
        self.sharded = None
        if scheduler is not None:  # every search asked of the cluster's shards (mocapviz.sharded)
            from ..sharded import ShardedDB

            self.sharded = ShardedDB(db, scheduler)
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
        >>> _ = b.cached(("numeric", "x"), lambda: np.zeros(5000))  # derived data: not an answer
        >>> b.kept_answers()
        (1, 8000)
        """
        with self._guard:
            answers = [value for key, value in self._results.items() if answers_kept(key) is not None]
        return len(answers), sum(_size(v) for v in answers)

    # ------------------------------------------------------------------ derived data
    def indexes(self, relational_set: str = "2005") -> dict:
        """The relational inverted indexes (group -> InvertedIndex); built and saved in DB/index/ when missing or
        stale (Müller et al. 2005 §4), as ``mocapviz index DB`` would."""
        return self.cached(("indexes", relational_set), lambda: index_mod.load_or_build(self.db, relational_set))

    def clip_relational(self, doc: int, relational_set: str = "2005") -> tuple[np.ndarray, list[str]]:
        """One document's relational features: (T, f) bool and the f names, computed on the clip (§3)."""
        return self.cached(("relational", doc, relational_set),
                           lambda: relational_features(self.db.motion(doc), relational_set, progress=False))

    def numeric(self, name: str) -> np.ndarray:
        """A numeric set of every frame, (N, d) float32 cm (stored when current, else computed)."""
        return self.cached(("numeric", name), lambda: numeric_of(self.db, name))

    def knn(self, name: str) -> KnnIndex:
        """The kd-tree over a numeric set (Krüger et al. 2010 §3.3): the one of this process, shared by the kNN
        table, motion matching and :meth:`search` (sharded: one that asks the cluster's shards)."""
        if self.sharded is not None:
            return self.cached(("knn", name), lambda: self.sharded.knn_index(name))
        return self.cached(("knn", name), lambda: KnnIndex(self.numeric(name)))

    def search(self, name: str = "F15E"):
        """The DTW search over a numeric set (:class:`mocapviz.similarity.search.SimilaritySearch`), one per set,
        over :meth:`numeric`'s features and :meth:`knn`'s kd-tree (its coarse database is built on first use);
        sharded: its ``clips`` and ``stretches`` asked of the cluster's shards."""
        from ..similarity.search import SimilaritySearch

        if self.sharded is not None:
            return self.cached(("search", name), lambda: self.sharded.search(name))
        return self.cached(("search", name), lambda: SimilaritySearch(self.db, name, features=self.numeric(name),
                                                                     index=self.knn(name)))

    # ------------------------------------------------------------------ searches the pages ask
    def query_by_example(self, example, features, mode: str, mismatches: int, relational_set: str):
        """:func:`mocapviz.relational.query.query_by_example` with this Backend's indexes, or of the shards."""
        if self.sharded is not None:
            return self.sharded.query_by_example(example, features, mode, mismatches, relational_set)
        from ..relational.query import query_by_example

        return query_by_example(self.db, example, features, mode, mismatches, relational_set,
                                self.indexes(relational_set))  # fmt: skip

    def find(self, text: str, n_matches: int | None, relational_set: str, values=None):
        """:func:`mocapviz.relational.scene.find` with this Backend's indexes (and relational ``values`` for
        template atoms), or of the shards."""
        if self.sharded is not None:
            return self.sharded.find(text, n_matches=n_matches, relational_set=relational_set)
        from ..relational.scene import find

        return find(self.db, text, n_matches=n_matches, relational_set=relational_set,
                    indexes=self.indexes(relational_set), values=values)  # fmt: skip

    def search_template(self, template, n_matches: int, delta: float, max_cost, values=None):
        """:func:`mocapviz.relational.templates.search_template` over ``values`` (the template's set), or of the
        shards."""
        if self.sharded is not None:
            return self.sharded.search_template(template, n_matches=n_matches, delta=delta, max_cost=max_cost)
        from ..relational.templates import search_template

        return search_template(self.db, template, n_matches=n_matches, delta=delta, max_cost=max_cost,
                               values=values)  # fmt: skip

    def retrieval(self, methods, label_column: str = "label", group_column=None, n_queries: int | None = None,
                  seed: int = 0) -> dict:  # fmt: skip
        """:func:`mocapviz.experiments.retrieval_quality` of the database (computed once per arguments; the
        relational methods use this Backend's indexes)."""
        from ..experiments.retrieval import retrieval_quality

        methods = tuple(methods)
        key = ("retrieval", methods, label_column, group_column, n_queries, seed)
        relational_methods = {"relational", "hybrid"} & set(methods)
        return self.cached(key, lambda: retrieval_quality(
            self.db, methods, label_column=label_column, group_column=group_column, n_queries=n_queries, seed=seed,
            indexes=self.indexes() if relational_methods else None, progress=False))

    def document_table(self) -> pd.DataFrame:
        """The documents as the dashboard lists them, with their archive and performer
        (:func:`mocapviz.app.documents.document_table`), built once per database."""
        return self.cached(("document table",), lambda: document_table(self.documents))

    def doc_options(self) -> dict:
        """{"<id>: <name> · <label> · <performer> · <archive>": doc_id} for a document picker, in document order
        (:func:`mocapviz.app.documents.picker_options`), built once per database."""
        return self.cached(("document options",), lambda: picker_options(self.document_table()))


def sample_database() -> Path:
    """The folder of :meth:`MotionDB.sample` (the embedded sample at 120 Hz, built once)."""
    return MotionDB.sample().path
