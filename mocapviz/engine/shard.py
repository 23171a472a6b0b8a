"""One shard of a MotionDB, in this process or resident on a Dask worker (a Dask actor): its documents as a view of
the database (:func:`mocapviz.db.shards.shard_view`), and the derived data its searches need, made once and kept
across queries: each numeric set's rows with its similarity search and kd-tree, each relational set's frame-wise
values and inverted indexes. A shard that holds the whole database uses the derived data stored with it (inverted
indexes loaded, or built and stored as ``mocapviz index`` would); a part of it makes its own in memory.

Every search method runs one library function on the shard and returns its hit table packed (:meth:`Shard.packed`:
doc ids, in-document frames and the search's own columns as numpy arrays, as on the whole database; names, seconds
and labels are added once, by :class:`mocapviz.engine.Engine` when it merges them): a DataFrame costs
milliseconds to pickle, its arrays microseconds.

A shard lets its worker process keep the memory its queries free (:func:`mocapviz.heap.keep_freed_memory`): Dask's
nanny pins glibc's thresholds low, which made every query map and fault in its temporary arrays afresh (a relational
scene query took twice its CPU time).
"""
from __future__ import annotations

import threading

import numpy as np

from ..db.database import MotionDB
from ..db.shards import shard_view
from ..errors import MotionDBError
from ..heap import keep_freed_memory

__all__ = ["Shard"]


class Shard:
    """The documents ``doc_ids`` of the MotionDB at ``path`` and their derived data, made on first use and kept.

    Parameters
    ----------
    db : MotionDB or str
        The MotionDB (in this process), or its folder as the worker sees it.
    doc_ids : sequence of int
        Consecutive documents in storage order (:func:`mocapviz.db.shards.split_documents`).
    generation : int
        The database's generation the coordinator opened: a shard refuses another (the database changed).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.db.shards import split_documents
    >>> db = MotionDB.sample()
    >>> shard = Shard(str(db.path), split_documents(db, 2)[1].tolist(), db.manifest["generation"])
    >>> shard.offset, len(shard.view)
    (2810, 14)
    """

    def __init__(self, db, doc_ids, generation):
        parent = db if isinstance(db, MotionDB) else MotionDB.open(db)
        if parent.manifest.get("generation") != generation:
            raise MotionDBError(f"{parent.path} changed since the engine opened it; open it again")
        self.parent, self.view = parent, shard_view(parent, doc_ids, labels=False)
        self.offset = self.view.shard_frames[0]
        self.doc_ids = np.asarray(doc_ids, dtype=np.int64)
        self.whole = len(self.doc_ids) == len(parent)
        self._made: dict = {}
        self._locks: dict = {}
        self._guard = threading.Lock()
        if not isinstance(db, MotionDB):  # a worker process of its own
            keep_freed_memory()

    def holds(self, kind: str, name: str) -> bool:
        """Whether the derived data ``(kind, name)`` of :meth:`_once` is made."""
        return (kind, name) in self._made

    def _once(self, key, make):
        """``make()``'s result, made once per ``key`` and kept; callers on other threads wait for it."""
        with self._guard:
            if key in self._made:
                return self._made[key]
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            if key not in self._made:
                value = make()
                with self._guard:
                    self._made[key] = value
            return self._made[key]

    # ------------------------------------------------------------------ derived data, made once
    def numeric(self, numeric_set: str) -> np.ndarray:
        """The shard's rows of a numeric set: the database's stored ones, else computed on the shard (Fp sets with
        the database's PCA model, as on the whole database)."""
        return self._once(("numeric", numeric_set), lambda: self._numeric_rows(numeric_set))

    def _numeric_rows(self, numeric_set: str) -> np.ndarray:
        from ..features.numeric import _spec, default_pca, load_numeric, numeric_features, numeric_of

        if self.whole:
            return numeric_of(self.parent, numeric_set)
        a, b = self.view.shard_frames
        try:
            return load_numeric(self.parent, numeric_set)[a:b]
        except MotionDBError:
            pca = default_pca(self.parent) if _spec(numeric_set).pcs else None
            return numeric_features(self.view, numeric_set, pca=pca, progress=False)

    def search(self, numeric_set: str):
        """The shard's :class:`~mocapviz.similarity.search.SimilaritySearch` of a numeric set (its kd-tree too)."""
        from ..similarity.search import SimilaritySearch

        return self._once(("search", numeric_set),
                          lambda: SimilaritySearch(self.view, numeric_set, features=self.numeric(numeric_set)))

    def values(self, relational_set: str) -> np.ndarray:
        """The shard's frame-wise relational values of a set (computed per document, as on the whole database)."""
        from ..features import relational_features

        return self._once(("values", relational_set),
                          lambda: relational_features(self.view, relational_set, progress=False)[0])

    def indexes(self, relational_set: str, progress: bool = False) -> dict:
        """The shard's inverted indexes of a relational set: the whole database's stored ones (built and stored
        when missing or stale, a progress bar while their features are computed when ``progress``), a part's built
        from :meth:`values` and kept in memory."""
        from ..relational.index import build, load_or_build

        if self.whole:
            return self._once(("indexes", relational_set),
                              lambda: load_or_build(self.parent, relational_set, progress=progress))
        return self._once(("indexes", relational_set), lambda: build(
            self.view, relational_set, progress=False, values=self.values(relational_set), save=False))

    def warm(self, numeric_sets=(), relational_sets=()) -> int:
        """Make the derived data of these sets now (before the first query); returns the shard's frames."""
        for name in numeric_sets:
            self.search(name).knn_index  # noqa: B018 - built on first use
        for name in relational_sets:
            self.indexes(name)
        return self.view.n_frames

    # ------------------------------------------------------------------ searches
    def knn(self, numeric_set: str, queries: np.ndarray, k: int, radius=None, eps: float = 0.0, exclude=None):
        """The k nearest frames of the shard to each query row: (distances (q, k'), database-wide frames (q, k'),
        -1 where fewer), k' = min(k, the shard's indexed frames). ``exclude``: database-wide [a, b) per query,
        checked by the coordinator; a query whose range holds every frame of the shard finds nothing here."""
        index = self.search(numeric_set).knn_index
        k = min(int(k), index.n_indexed)
        queries = np.atleast_2d(queries)
        if exclude is None:  # every query asks every frame of the shard
            distances, found = index.query(queries, k, radius=radius, eps=eps)
            return distances, np.where(found >= 0, found + self.offset, -1) if self.offset else found
        distances, frames = np.full((len(queries), k), np.inf), np.full((len(queries), k), -1, dtype=np.int64)
        rows = np.arange(len(queries))
        if exclude is not None:
            exclude = np.clip(np.asarray(exclude, dtype=np.int64).reshape(-1, 2) - self.offset, 0, self.view.n_frames)
            rows = np.flatnonzero(exclude[:, 1] - exclude[:, 0] < self.view.n_frames)
            exclude = exclude[rows]
        if len(rows):
            distances[rows], found = index.query(queries[rows], k, radius=radius, eps=eps, exclude=exclude)
            frames[rows] = np.where(found >= 0, found + self.offset, -1)
        return distances, frames

    def packed(self, table) -> dict:
        """A hit table as it travels to the coordinator: ``columns`` (doc_id, start, end and the search's own
        columns, numpy arrays; integers that fit in 32 bits sent as int32), ``dtypes`` (each column's own dtype,
        restored on arrival), ``order`` (the table's column order) and ``attrs``.

        The reply's bytes cost the cluster's round trip about 4 ms per MB (on loopback): a relational query's
        7,000 hits per shard at 10M frames are 0.4 MB with 64-bit integers, 0.2 MB with 32-bit ones."""
        derived = {"rank", "name", "frames", "start_s", "end_s", *self.view.label_columns}
        columns = {c: table[c].to_numpy() for c in table.columns if c not in derived}
        return {"columns": {c: _narrow(v) for c, v in columns.items()},
                "dtypes": {c: v.dtype for c, v in columns.items()},
                "order": list(table.columns), "attrs": dict(table.attrs)}  # fmt: skip

    def clips(self, numeric_set: str, query, **options) -> dict:
        """:meth:`SimilaritySearch.clips` on the shard (``query``: a :class:`~mocapviz.similarity.search.Query`)."""
        return self.packed(self.search(numeric_set).clips(query, **options))

    def stretches(self, numeric_set: str, query, **options) -> dict:
        """:meth:`SimilaritySearch.stretches` on the shard, the query checked by the coordinator (the shard's
        documents may all be shorter than it and still hold matches)."""
        return self.packed(self.search(numeric_set).stretches(query, checked=True, **options))

    def match_dtw(self, numeric_set: str, query, n_matches: int, exclude_document: bool, paths: bool,
                  min_length: float | None) -> dict:
        """:func:`~mocapviz.similarity.motion_matching.match_motion` by subsequence DTW on the shard (the query's own
        document left out when it is one of the shard's; its length checked by the coordinator)."""
        from ..similarity.motion_matching import match_motion

        own = exclude_document and query.doc_id is not None and query.doc_id in self.doc_ids
        return self.packed(match_motion(self.view, query, numeric_set=numeric_set, method="dtw", n_matches=n_matches,
                                        exclude_document=own, paths=paths, features=self.numeric(numeric_set),
                                        min_length=min_length, checked=True))

    def query_by_example(self, example, features, relational_set: str, mode: str, mismatches: int,
                         allowed) -> dict:  # fmt: skip
        """:func:`~mocapviz.relational.query.query_by_example` on the shard, its arguments checked by the coordinator
        (:func:`~mocapviz.relational.query.example_hits`: a document of the shard shorter than the example may hold a
        hit); ``example``: a Motion or its :class:`~mocapviz.relational.query.RelationalExample`. Attrs
        ``group_segments``: the shard's segments of the first group queried (``first_segment`` / ``last_segment``
        count from the shard's first segment)."""
        from ..relational.query import example_hits

        return self.packed(example_hits(self.view, example, features, mode, mismatches, relational_set,
                                        self.indexes(relational_set), allowed))  # fmt: skip

    def find(self, description: str, relational_set: str, **options) -> dict:
        """:func:`~mocapviz.relational.scene.find` on the shard (its attrs: the hits of each part, ``counts``)."""
        from ..relational.description import template_names
        from ..relational.scene import find

        values = self.values(relational_set) if template_names(description) else None
        return self.packed(find(self.view, description, relational_set=relational_set,
                                indexes=self.indexes(relational_set), values=values, **options))  # fmt: skip

    def search_template(self, template, **options) -> dict:
        """:func:`~mocapviz.relational.templates.search_template` on the shard (the template's relational set; the
        pre-filter on the shard's own inverted indexes); attrs ``aligned_frames``: the frames the DTW pass aligned."""
        from ..features import RELATIONAL_SETS, feature_names
        from ..relational.templates import search_template

        relational_set = next((s for s in RELATIONAL_SETS if feature_names(s) == list(template.features)), None)
        values = self.values(relational_set) if relational_set else None
        indexes = self.indexes(relational_set) if relational_set and options.get("prefilter") else None
        table = search_template(self.view, template, values=values, indexes=indexes, **options)
        table.attrs["aligned_frames"] = round(table.attrs["aligned"] * self.view.n_frames)
        return self.packed(table)


def _narrow(values: np.ndarray) -> np.ndarray:
    """``values`` as int32 when they are 64-bit integers that fit in it, else as they are."""
    small = np.iinfo(np.int32)
    if values.dtype == np.int64 and (not values.size or small.min <= values.min() and values.max() <= small.max):
        return values.astype(np.int32)
    return values
