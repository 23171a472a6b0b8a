"""The engine: every use case of mocapviz over one MotionDB, the one way Python, the command line, the dashboard,
the notebooks and ``mocapviz reproduce`` ask a database anything.

An :class:`Engine` splits the database by documents into shards (:class:`~mocapviz.engine.shard.Shard`: a run of
consecutive documents and the derived data its searches need, made once and kept). Without a scheduler the shards
live in this process (one shard, the whole database, by default); with one they are Dask actors resident on the
cluster's workers. Either way every query runs the same per-shard method on every shard and the same merge here,
so one process and a cluster give the same table by construction, not by a second implementation.

Why the merge is exact: a hit never crosses a document and a shard holds whole documents, so each shard's K best
hits (by the search's own order: cost, then the document or the frame) contain every hit of the global K best that
lies in its documents, and the overlaps a search resolves are within one document. Merging the shards' lists by the
same order therefore gives the one-shard answer: the same hits, order and costs (tested on random queries with 1, 2
and 3 shards). Fast mode of the similarity search is approximate on any number of shards: its coarse pass and
budget are per shard.

Every parameter is declared once, in :mod:`mocapviz.engine.parameters`, and checked here, at the boundary
(:func:`~mocapviz.engine.parameters.checked`); the kernels below trust their inputs.

A worker that dies mid-query: its shards are started again on the workers left and the query is asked of them once
more (the whole answer, recomputed); when that fails too, a :class:`~mocapviz.errors.ClusterError`, never a partial
answer.
"""
from __future__ import annotations

import contextlib
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from typing_extensions import Self

from ..db.database import MotionDB
from ..db.hits import first_frames, hit_table
from ..db.shards import split_documents
from ..errors import ClusterError, MocapvizError, ParameterError
from ..match.time_warping import check_query_length, shortest_match
from ..parallel import dask_client
from ..validation import count, frame_span, plural
from .parameters import PARAMETERS, checked
from .shard import Shard

__all__ = ["Engine", "ShardedDB"]


class Engine:
    """Every use case over one MotionDB, answered by its shards and merged.

    Parameters
    ----------
    db : MotionDB or str or os.PathLike
        The database (with a scheduler, its folder must be readable by every worker at the same path).
    scheduler : None, "local", str or dask.distributed.Client
        None: the shards live in this process. Otherwise as every ``scheduler=`` of mocapviz
        (:func:`mocapviz.parallel.dask_client`): a local cluster for this object's life, a scheduler's address, or
        a Client.
    n_shards : int, optional
        Shards (default: one in this process; one per worker on a cluster).
    shards : sequence of array_like of int, optional
        Instead of ``n_shards``: each shard's doc ids, runs of consecutive documents in storage order that hold
        every document once, in that order (default :func:`~mocapviz.db.shards.split_documents`, shards of about
        equal frames); uneven shards, e.g. a few short documents alone, are how the tests reach every case.
    numeric_sets, relational_sets : sequence of str
        Derived data every shard makes now rather than on its first query (kd-trees, inverted indexes).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> engine = Engine(MotionDB.sample())
    >>> hits = engine.clips(7, n_matches=3, exclude_document=True)
    >>> list(hits.columns[:5]), len(hits)
    (['rank', 'doc_id', 'name', 'start', 'end'], 3)
    >>> two = Engine(MotionDB.sample(), n_shards=2)
    >>> two.clips(7, n_matches=3, exclude_document=True).equals(hits.assign())  # doctest: +SKIP
    True
    """

    def __init__(self, db, *, scheduler=None, n_shards: int | None = None, shards=None, numeric_sets=(),
                 relational_sets=()):  # fmt: skip
        self.db = db if isinstance(db, MotionDB) else MotionDB.open(db)
        if shards is not None:
            shards = _given_shards(self.db, shards, n_shards)
        self.scheduler = scheduler
        self.client = None
        self._stack = contextlib.ExitStack()
        self._features: dict[str, np.ndarray] = {}
        self._marker_only = len(self.db.marker_documents)  # marker-only documents: no canonical search sees them
        try:
            if self.db.documents.empty and self._marker_only:  # nothing to shard: marker_stretches alone answers
                self.shards, self.actors = [], []
            elif scheduler is None:
                self.shards = shards or split_documents(self.db, count(n_shards, "n_shards") if n_shards else 1)
                generation = self.db.manifest.get("generation")
                self.actors = [_Here(Shard(self.db, ids.tolist(), generation)) for ids in self.shards]
            else:
                self.client = self._stack.enter_context(dask_client(scheduler))
                workers = self._workers()
                if not workers:
                    raise ClusterError(f"the dask cluster at {self.client.scheduler.address} has no worker")
                if shards is None:
                    shards = split_documents(self.db, count(n_shards, "n_shards") if n_shards else len(workers))
                self.shards = shards
                self.actors = [self._start(i, workers[i % len(workers)]) for i in range(len(self.shards))]
            if numeric_sets or relational_sets:
                self._fan("warm", tuple(numeric_sets), tuple(relational_sets))
        except BaseException:
            self._stack.close()
            raise

    def close(self) -> None:
        """Let the shards go (and stop a local cluster started here)."""
        self.actors = []
        self._stack.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        where = "this process" if self.client is None else f"{len(self._workers())} workers"
        return f"Engine({str(self.db.path)!r}: {len(self.shards)} shard{'s' * (len(self.shards) != 1)} in {where})"

    # ------------------------------------------------------------------ the shards
    def _workers(self) -> list[str]:
        return sorted(self.client.scheduler_info()["workers"])

    def _start(self, i: int, worker: str | None):
        future = self.client.submit(Shard, str(self.db.path), self.shards[i].tolist(), self.db.manifest["generation"],
                                    actor=True, workers=None if worker is None else [worker], pure=False)  # fmt: skip
        return future.result()

    def _fan(self, method: str, *args, **kwargs) -> list:
        """``method(*args, **kwargs)`` on every shard at once; on a cluster, a shard whose worker failed is started
        again on a live worker and asked once more; then a ClusterError."""
        if not self.actors:  # a database of marker-only documents alone
            raise ParameterError(f"{self.db.path} holds no document with canonical joints, only "
                                 f"{plural(self._marker_only, 'marker-only document')}: search them with "
                                 "marker_stretches (mocapviz markers)")  # fmt: skip
        if self.client is None:
            return [getattr(actor.shard, method)(*args, **kwargs) for actor in self.actors]
        calls = []
        for actor in self.actors:
            try:
                calls.append(getattr(actor, method)(*args, **kwargs))
            except Exception as lost:  # noqa: BLE001 - the worker holding the shard is known to be gone
                calls.append(lost)
        results = []
        for i, call in enumerate(calls):
            try:
                if isinstance(call, Exception):
                    raise call
                results.append(call.result())
            except MocapvizError:
                raise
            except Exception as first:  # noqa: BLE001 - the worker or its connection is gone (many types)
                results.append(self._again(i, method, args, kwargs, first))
        return results

    def _again(self, i: int, method: str, args, kwargs, first: Exception):
        workers = self._workers()
        if not workers:
            raise ClusterError(f"shard {i + 1} of {len(self.shards)} failed ({_why(first)}) and no worker is left; "
                               "no answer") from None  # fmt: skip
        try:
            self.actors[i] = self._start(i, workers[i % len(workers)])
            return getattr(self.actors[i], method)(*args, **kwargs).result()
        except MocapvizError:
            raise
        except Exception as second:  # noqa: BLE001 - as above
            raise ClusterError(f"shard {i + 1} of {len(self.shards)} failed twice ({_why(first)}; then "
                               f"{_why(second)}); no answer") from None  # fmt: skip

    @property
    def _whole(self) -> Shard | None:
        """The one shard in this process that holds the whole database, if that is how it is split."""
        return self.actors[0].shard if self.client is None and len(self.actors) == 1 else None

    # ------------------------------------------------------------------ derived data of the whole database
    def numeric(self, numeric_set: str = "F15E") -> np.ndarray:
        """The database's values of a numeric set, (N, d) float32 (stored when current, else computed; Krüger et
        al. 2010 §3.2), here (to turn an example into its query once, and for the pages' plots)."""
        numeric_set = checked_value("numeric_set", numeric_set)
        if self._whole is not None:
            return self._whole.numeric(numeric_set)
        if numeric_set not in self._features:
            from ..features import numeric_of

            self._features[numeric_set] = numeric_of(self.db, numeric_set)
        return self._features[numeric_set]

    def indexes(self, relational_set: str = "2005", *, progress: bool = False) -> dict:
        """The relational inverted indexes of the whole database (group -> InvertedIndex; Müller et al. 2005 §4),
        loaded, or built and stored in the database when missing or stale, as ``mocapviz index DB`` would (with a
        progress bar while the features are computed when ``progress``)."""
        relational_set = checked_value("relational_set", relational_set)
        if self._whole is not None:
            return self._whole.indexes(relational_set, progress=progress)
        from ..relational.index import load_or_build

        return load_or_build(self.db, relational_set, progress=progress)

    def relational_values(self, relational_set: str = "2005") -> np.ndarray:
        """The relational features of every frame, (N, f) bool (each document on its own; Müller et al. 2005 §3)."""
        relational_set = checked_value("relational_set", relational_set)
        if self._whole is not None:
            return self._whole.values(relational_set)
        from ..features import relational_features

        return relational_features(self.db, relational_set, progress=False)[0]

    def holds(self, kind: str, name: str) -> bool:
        """Whether derived data of the whole database is made and kept in this process: ``kind`` "numeric",
        "search" (a numeric set's DTW search and kd-tree), "values" (relational features) or "indexes", of the set
        ``name`` (on a cluster: False, the workers hold theirs)."""
        return self.client is None and all(actor.shard.holds(kind, name) for actor in self.actors)

    def _query(self, example, frames, numeric_set: str):
        from ..similarity.search import example_features

        return example_features(self.db, self.numeric(numeric_set), example, frames, numeric_set)

    def _motion(self, example, frames):
        """An example as a Motion cut to ``frames`` ([a, b) or a slice; None: all): a doc id, or a Motion or a file
        at the database's rate (:func:`~mocapviz.similarity.search.example_motion`, as the numeric searches take it)."""
        from ..motion import Motion
        from ..similarity.search import example_motion

        if isinstance(example, (int, np.integer)) and not isinstance(example, bool):
            motion, what = self.db.motion(int(self.db.document(int(example))["doc_id"])), f"document {example}"
        elif isinstance(example, Motion):
            motion, what = example_motion(self.db, example), "the example"
        elif isinstance(example, (str, Path)):
            motion, what = example_motion(self.db, example), str(example)
        else:
            return example  # a RelationalExample: its values, as given
        if isinstance(frames, slice):
            frames = (frames.start, frames.stop)
        a, b = frame_span(frames, motion.n_frames, what, "frames")
        return motion[a:b]

    def example(self, example, *, frames=None):
        """The example as every use case reads it, a Motion: a doc id's clip, or a Motion or a motion file (BVH,
        ASF + AMC, C3D, read as ingest reads them) resampled to the database's typical rate; cut to ``frames``
        ([a, b) of it). What a front reads an uploaded take with, so that its frames are those the use cases count."""
        return self._motion(example, frames)

    # ------------------------------------------------------------------ use cases
    @checked("knn")
    def knn(self, queries, *, k=..., numeric_set=..., radius=..., eps=..., exclude=None
            ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """The k nearest database frames of each query row (Krüger et al. 2010 §3.3), over every shard.

        Parameters
        ----------
        queries : np.ndarray [shape=(q, d) or (d,)]
            Query rows of ``numeric_set``.
        k, numeric_set, radius, eps
            As docs/parameters.md.
        exclude : np.ndarray [shape=(q, 2), or (2,) for one query], int, optional
            Database-wide [a, b) frames left out, per query (a shard whose frames are all left out answers
            nothing for that query).

        Returns
        -------
        distances : np.ndarray [shape=(q, k)], float64 (inf where fewer)
        frames : np.ndarray [shape=(q, k)], int64, database-wide (-1 where fewer); nearest first, ties by frame.
        """
        from ..similarity.knn import excluded_ranges

        k = count(k, "k", 1, self.db.n_frames, "the number of indexed frames")
        queries = np.atleast_2d(np.asarray(queries, dtype=np.float64))  # searched in float64, as by one kd-tree
        if exclude is not None:
            exclude = excluded_ranges(exclude, len(queries), self.db.n_frames)
        parts = self._fan("knn", numeric_set, queries, k, radius, eps, exclude)
        if len(parts) == 1:  # one shard's answer is in the merge's order already (ties by frame, missing last)
            distances, frames = parts[0]
        else:
            distances = np.concatenate([d for d, _ in parts], axis=1)
            frames = np.concatenate([f for _, f in parts], axis=1)
            order = np.lexsort((np.where(frames < 0, np.iinfo(np.int64).max, frames), distances), axis=1)[:, :k]
            distances, frames = np.take_along_axis(distances, order, 1), np.take_along_axis(frames, order, 1)
        if distances.shape[1] < k:
            pad = k - distances.shape[1]
            distances = np.pad(distances, ((0, 0), (0, pad)), constant_values=np.inf)
            frames = np.pad(frames, ((0, 0), (0, pad)), constant_values=-1)
        return distances, frames

    @checked("neighbours")
    def neighbours(self, doc_id: int, frame: int, *, k=..., numeric_set=..., radius=..., eps=...,
                   exclude_document=..., per_document=...) -> pd.DataFrame:  # fmt: skip
        """The k nearest frames of the database to frame ``frame`` of document ``doc_id`` (in-document, from 0), or
        of a Motion or a motion file given instead (an uploaded take: read as every use case reads an example, at
        the database's rate; nothing to exclude), as a hit table of one-frame stretches
        (:func:`~mocapviz.similarity.knn.describe_frames`; ``distance`` column), nearest first; ``per_document``:
        the nearest frame of each document.

        Examples
        --------
        >>> from mocapviz import MotionDB
        >>> engine = Engine(MotionDB.sample())
        >>> engine.neighbours(3, 10, k=2)[["doc_id", "start", "end"]].values.tolist()  # its own document left out
        [[14, 21, 22], [14, 22, 23]]
        >>> engine.neighbours(3, 10, k=2, exclude_document=False)[["doc_id", "start", "end"]].values.tolist()
        [[3, 10, 11], [3, 11, 12]]
        """
        from ..similarity.knn import describe_frames

        if _is_doc_id(doc_id):
            span = self.db.frames(int(doc_id))
            if not 0 <= frame < span.stop - span.start:
                raise ParameterError(f"document {doc_id} has frames 0..{span.stop - span.start - 1}; asked for {frame}")
            row, own = self.numeric(numeric_set)[span.start + frame], (span.start, span.stop) if exclude_document else None
        else:  # a take that is no document: its frames' values computed as a search's query's
            values = self._query(doc_id, None, numeric_set).values  # (read and resampled there)
            if not 0 <= frame < len(values):
                raise ParameterError(f"the example has frames 0..{len(values) - 1}; asked for {frame}")
            row, own = values[frame], None
        t0 = time.perf_counter()
        distances, frames = self.knn(row, k=k, numeric_set=numeric_set, radius=radius, eps=eps,
                                     exclude=own)  # fmt: skip
        table = describe_frames(self.db, frames[0], distances[0], per_document=per_document)
        table.attrs.update(ms=1e3 * (time.perf_counter() - t0), found=int((frames[0] >= 0).sum()))
        return table

    @checked("clips")
    def clips(self, example, *, frames=None, n_matches=..., numeric_set=..., mode=..., exclude_document=...,
              paths=...) -> pd.DataFrame:  # fmt: skip
        """The documents that move most like the example, by DTW cost normalised by the frames of both, then doc
        id (Krüger et al. 2010 §3.2 features; :meth:`~mocapviz.similarity.SimilaritySearch.clips` on every shard).
        ``example``: a doc id, a Motion or a motion file; ``frames``: [a, b) of it."""
        query = self._query(example, frames, numeric_set)
        t0 = time.perf_counter()
        options = {"n_matches": n_matches, "exclude_document": exclude_document}
        limit = self._limit("clips", numeric_set, query, "normalised_cost", mode, options)
        tables = self._fan("clips", numeric_set, query, mode=mode, paths=paths, limit=limit, **options)
        return _work_added(self._merged(tables, ["normalised_cost", "doc_id"], n_matches, t0), tables)

    @checked("stretches")
    def stretches(self, example, *, frames=None, n_matches=..., numeric_set=..., mode=..., min_length=...,
                  exclude_document=..., paths=...) -> pd.DataFrame:  # fmt: skip
        """The K best non-overlapping stretches inside documents like the example, by subsequence DTW cost, then
        their last frame in the database (:meth:`~mocapviz.similarity.SimilaritySearch.stretches` on every shard)."""
        from ..similarity.search import check_stretch_query

        query = self._query(example, frames, numeric_set)
        m, docs = len(query.values), self.db.documents
        lengths = docs["n_frames"].to_numpy()
        if exclude_document and query.doc_id is not None:
            lengths = lengths[docs["doc_id"].to_numpy() != query.doc_id]
        check_stretch_query(lengths, m, shortest_match(min_length, m))  # once, on the whole database
        t0 = time.perf_counter()
        options = {"n_matches": n_matches, "min_length": min_length, "exclude_document": exclude_document}
        limit = self._limit("stretches", numeric_set, query, "cost", mode, options)
        tables = self._fan("stretches", numeric_set, query, mode=mode, paths=paths, limit=limit, **options)
        return _work_added(self._merged(tables, ["cost", "_last"], n_matches, t0), tables)

    @checked("marker_stretches")
    def marker_stretches(self, example, *, frames=None, n_matches=..., min_length=..., exclude_document=...
                         ) -> pd.DataFrame:  # fmt: skip
        """The K best non-overlapping stretches of the marker-only documents of the example's marker label set and
        rate, by subsequence DTW on the marker numeric set
        (:func:`mocapviz.similarity.marker_search.marker_stretches`; attrs ``searched``, ``other_markers``,
        ``other_rate``). Answered here, not by the shards: they hold the canonical documents only."""
        from ..similarity.marker_search import marker_stretches

        t0 = time.perf_counter()
        table = marker_stretches(self.db, example, frames, n_matches, min_length, exclude_document)
        table.attrs["ms"] = 1e3 * (time.perf_counter() - t0)
        return table

    def _limit(self, method: str, numeric_set: str, query, column: str, mode: str, options: dict) -> float | None:
        """The K-th best cost shared by every shard in exact mode (:func:`mocapviz.match.pruned.search_ranges`): a
        first, fast round on every shard finds real matches; the K-th least of their documents' best costs is
        reached by K documents, so each shard's exact search prunes what costs more from the start (None: fewer
        than K documents found, or not exact mode). Raised by 1e-9 of itself: a cost equal to it, normalised on
        another shard, must not fall just above it by rounding."""
        if mode != "exact" or len(self.actors) < 2:
            return None
        packs = self._fan(method, numeric_set, query, mode="fast", **options)
        doc_ids = np.concatenate([p["columns"]["doc_id"] for p in packs])
        costs = np.concatenate([p["columns"][column] for p in packs]).astype(np.float64)
        costs = pd.Series(costs).groupby(doc_ids).min().to_numpy()  # each document's best
        costs = np.sort(costs[np.isfinite(costs)])
        k = options["n_matches"]
        return float(costs[k - 1]) * (1 + 1e-9) if len(costs) >= k else None

    @checked("match")
    def match(self, example, *, frames=None, numeric_set=..., method=..., n_matches=..., k=..., radius=..., eps=...,
              exclude_document=..., paths=..., min_length=...) -> pd.DataFrame:  # fmt: skip
        """Global matching of a query (Krüger et al. 2010 §4): ``method="lng"``, the lazy neighbourhood graph on the
        k nearest database frames of every query frame (default ``k``:
        :func:`~mocapviz.similarity.motion_matching.graph_k` of the database; attrs ``k``), merged from every shard
        (:meth:`knn`); ``"dtw"``: subsequence DTW on every shard, matches merged by cost, then their last frame."""
        from ..similarity.motion_matching import graph_k, match_motion

        if method == "dtw":
            query = self._query(example, frames, numeric_set)
            t0 = time.perf_counter()
            shortest_match(min_length, len(query.values))  # checked here, once, on the whole database
            check_query_length(len(query.values), self.db.documents["start"].sort_values().to_numpy(), self.db.n_frames)
            tables = self._fan("match_dtw", numeric_set, query, n_matches, exclude_document, paths, min_length)
            table = self._merged(tables, ["cost", "_last"], n_matches, t0)
            table.attrs.update(method="dtw", query_frames=len(query.values))
            return table
        k = graph_k(self.db.n_frames, self.db.typical_fps) if k is None else k
        table = match_motion(self.db, example, frames, numeric_set, method, n_matches, k, radius, eps,
                             exclude_document, paths, features=self.numeric(numeric_set),
                             index=_ShardedIndex(self, numeric_set), min_length=min_length)  # fmt: skip
        table.attrs["k"] = k
        return table

    @checked("query")
    def query(self, example, *, frames=None, features=..., mode=..., mismatches=..., relational_set=...,
              allowed=..., exclude_document=...) -> pd.DataFrame:  # fmt: skip
        """Query by example (Müller et al. 2005 §5): the stretches whose feature progression on ``features``
        agrees with the example's (``mode``: exact, fuzzy, adaptive or mismatch with up to ``mismatches``
        disagreeing segments, at ``allowed`` when given), ranked by score, then doc id and start, the segments
        numbered in the whole database. ``example``: a doc id, a Motion or a motion file; ``frames``: [a, b);
        ``exclude_document``: leave out the hits in the example's own document (a doc id's)."""
        from ..relational.query import check_example_query, relational_example

        own = int(example) if exclude_document and _is_doc_id(example) else None
        example = self._motion(example, frames)
        check_example_query(self.db, example, features, mode, mismatches, relational_set)
        t0 = time.perf_counter()
        example = relational_example(example, relational_set)  # once, here; the shards get its values (a few kB)
        packs = self._fan("query_by_example", example, features, relational_set, mode, mismatches, allowed)
        offset = 0
        for pack in packs:  # a shard numbers its segments from its first; the database from the first shard's
            for column in ("first_segment", "last_segment"):
                pack["columns"][column] = pack["columns"][column].astype(np.int64) + offset
            offset += pack["attrs"].pop("group_segments")
            if own is not None:
                keep = pack["columns"]["doc_id"] != own
                pack["columns"] = {c: v[keep] for c, v in pack["columns"].items()}
        table = self._merged(packs, ["score", "doc_id", "start"], None, t0)
        table.attrs["group_segments"] = offset
        return table

    @checked("suggest_query")
    def suggest_query(self, example, *, frames=None, relational_set=...):
        """The query by example suggested for a clip (:func:`mocapviz.relational.suggestion.suggest_query`: the
        most specific selection of its features that finds 5 other documents in the database, and its m), what the
        Relational page opens with and ``mocapviz query`` asks without ``--features``. ``example``: a doc id (its
        own document is no answer), a Motion or a motion file; ``frames``: [a, b). Returns a SuggestedQuery
        (features, mode, mismatches, others), to pass on to :meth:`query`."""
        from ..relational.query import relational_example
        from ..relational.suggestion import suggest_query

        motion, own = self._motion(example, frames), None
        if _is_doc_id(example):
            own = int(np.flatnonzero(self.db.documents["doc_id"].to_numpy() == int(example))[0])
        values, names, _, _ = relational_example(motion, relational_set)
        return suggest_query(values, names, self.indexes(relational_set), relational_set, own_row=own)

    @checked("find")
    def find(self, description, *, n_matches=..., relational_set=None, template_cost=..., overlapping=...,
             templates: dict | None = None) -> pd.DataFrame:  # fmt: skip
        """The stretches a scene description describes (Müller et al. 2005 §6.3; docs/relational.md), by score
        (seconds), then database frame; ``n_matches`` None: every hit; ``relational_set`` None: the one the
        description names or needs; ``templates``: {name: MotionTemplate} of ``template:NAME`` atoms not stored."""
        from ..relational.scene import empty_reason, read_description
        from .parameters import default

        if n_matches is ...:
            n_matches = default("find", "n_matches")
        elif n_matches is not None:
            n_matches = checked_value("n_matches", n_matches)
        if relational_set is not None:
            relational_set = checked_value("relational_set", relational_set)

        parsed, template_cost, _ = read_description(self.db, description, relational_set, template_cost, templates)
        t0 = time.perf_counter()
        results = self._fan("find", parsed.text, parsed.relational_set, n_matches=n_matches,
                            template_cost=template_cost, overlapping=overlapping, templates=templates)  # fmt: skip
        table = self._merged(results, ["score", "_first"], n_matches, t0)
        # every shard evaluates the same parts in the same order: their counts add up place by place (a label may
        # come twice: 'kick_right | kick_right')
        counts = [(label, sum(p["attrs"]["counts"][i][1] for p in results))
                  for i, (label, _) in enumerate(results[0]["attrs"]["counts"])]  # fmt: skip
        table.attrs.update(description=str(parsed), relational_set=parsed.relational_set, counts=counts,
                           candidates=sum(p["attrs"]["candidates"] for p in results),
                           empty_reason=empty_reason(counts) if table.empty else "")  # fmt: skip
        return table

    @checked("learn_template")
    def learn_template(self, label: str, *, actors=None, relational_set=..., max_examples=..., iterations=...,
                       examples=None):
        """The motion template of the documents labelled ``label`` and of the stretches with that segment label
        (manual, accepted or imported: :meth:`segment_labels`; of ``actors`` only, when given), from at most
        ``max_examples`` of them spread over the class (Müller & Röder 2006 §3; documents without a label are of
        no class), and of ``examples``: takes that are no documents (Motions or motion files, an uploaded take,
        read as every use case reads an example), each always learned from. Returns a
        :class:`~mocapviz.relational.templates.MotionTemplate` (not stored: see
        :func:`~mocapviz.relational.templates.store_template`)."""
        from ..db.segments import POSITIVE, SegmentLabels
        from ..relational.templates import learn_class

        segments = SegmentLabels(self.db).table(str(label), POSITIVE)
        extra = [self.clip_relational(e, relational_set=relational_set)[0] for e in examples or ()]
        return learn_class(self.db, str(label), actors, relational_set, values=self.relational_values(relational_set),
                           iterations=iterations, max_examples=max_examples, segments=segments,
                           extra=extra)  # fmt: skip

    @checked("search_template")
    def search_template(self, template, *, n_matches=..., delta=..., max_cost=..., prefilter=...,
                        lower_bounds=...) -> pd.DataFrame:  # fmt: skip
        """The instances of a motion template (Müller & Röder 2006 §4), by cost, then their last frame in the
        database; ``template``: a MotionTemplate, a template file or the name of one stored with the database;
        ``prefilter``: each shard aligns only where the template's keyframes occur in its own inverted indexes;
        ``lower_bounds`` (default): each shard aligns its documents best lower bound first until none can hold one
        of its K best, the full pass's answer (attrs ``aligned``: the share of all frames aligned)."""
        template = self.template(template)
        options = {"n_matches": n_matches, "max_cost": max_cost, "prefilter": prefilter, "delta": delta,
                   "lower_bounds": lower_bounds}  # fmt: skip
        t0 = time.perf_counter()
        packs = self._fan("search_template", template, **options)
        table = self._merged(packs, ["cost", "_last"], n_matches, t0)
        table.attrs["aligned"] = sum(p["attrs"]["aligned_frames"] for p in packs) / max(1, self.db.n_frames)
        table.attrs.pop("aligned_frames", None)
        return table

    def template(self, template):
        """A MotionTemplate as given, read from a template file, or the one stored under that name."""
        from ..relational.templates import MotionTemplate, load_template

        if isinstance(template, MotionTemplate):
            return template
        if Path(template).is_file():
            return MotionTemplate.load(template)
        try:
            return load_template(self.db, str(template))
        except ParameterError as exc:  # not a stored name either
            raise ParameterError(f"{template}: no such template file, and {exc}") from None

    @checked("audit")
    def audit(self, other=None, *, numeric_set=..., min_length=..., threshold=..., max_scale=..., mirrored=...,
              progress: bool = False) -> pd.DataFrame:
        """Every pair of stretches of this database (or between it and ``other``) that are near-copies: the same
        motion again, its left/right mirror, at another rate, trimmed, time-scaled within ``max_scale`` or on
        other bones (``mocapviz.similarity.audit``, docs/audit.md), each at least ``min_length`` seconds.

        Parameters
        ----------
        other : MotionDB or path, optional
            A second collection: pairs between the two only (its frames compared at this database's typical rate).

        Returns
        -------
        pandas.DataFrame
            One row per pair (``mocapviz.similarity.audit.PAIR_COLUMNS``), best first; attrs ``threshold``
            (cm) and ``threshold_how`` (given, or how it was learned), ``rate`` (Hz), ``min_length`` (s) and
            ``numeric_set``. :meth:`audit_path` aligns a pair's two stretches.

        Examples
        --------
        >>> from mocapviz import MotionDB
        >>> pairs = Engine(MotionDB.sample()).audit(threshold=5.0)
        >>> list(pairs.columns[:4])
        ['doc_a', 'name_a', 'start_a', 'end_a']
        """
        from ..similarity.audit import Collection, audit_pairs, learn_threshold

        rate = float(self.db.typical_fps or 30.0)
        first = self._audit_collection(self.db, numeric_set, rate, None, progress)
        second = None
        if other is not None:
            other_db = other.db if isinstance(other, Engine) else other if isinstance(other, MotionDB) else \
                MotionDB.open(other)  # fmt: skip
            second = Collection(other_db, numeric_set, rate, body=first.body, progress=progress)
        min_frames = max(2, round(min_length * rate))
        how = "given"
        if threshold is None:
            learned = learn_threshold(first, min_frames)
            threshold, how = learned["threshold"], learned["how"]
        pairs = audit_pairs(first, second, min_frames=min_frames, threshold=threshold, max_scale=max_scale,
                            mirrored=mirrored, progress=progress)  # fmt: skip
        pairs.attrs.update(threshold=float(threshold), threshold_how=how, rate=rate, min_length=float(min_length),
                           numeric_set=numeric_set)
        return pairs

    def _audit_collection(self, db, numeric_set: str, rate: float, body, progress: bool):
        """This database's audit features (kept: a second audit with another threshold reads them again)."""
        from ..similarity.audit import Collection

        key = ("audit", numeric_set, rate)
        if key not in self._features:
            self._features[key] = Collection(db, numeric_set, rate, body=body, progress=progress)
        return self._features[key]

    @checked("audit_path")
    def audit_path(self, pair, *, numeric_set=...) -> np.ndarray:
        """The warping path of one pair of an :meth:`audit` of this database: the frames of its two stretches that
        show the same moment, step by step (``mocapviz.similarity.audit.warping_path``: the audit's features, side
        a mirrored for a mirrored pair), so that a player shows them aligned.

        Parameters
        ----------
        pair : mapping or pandas.Series
            A row of the pair table: ``doc_a``, ``start_a``, ``end_a``, ``doc_b``, ``start_b``, ``end_b`` (frames
            of each document, half-open) and ``mirrored``.

        Returns
        -------
        np.ndarray [shape=(L, 2)], int64
            Each step's frame of stretch a and of stretch b, from each stretch's start: (0, 0) first,
            (end_a - start_a - 1, end_b - start_b - 1) last, both non-decreasing.

        Examples
        --------
        >>> from mocapviz import MotionDB
        >>> pair = {"doc_a": 7, "start_a": 0, "end_a": 60, "doc_b": 7, "start_b": 0, "end_b": 60, "mirrored": False}
        >>> path = Engine(MotionDB.sample()).audit_path(pair)
        >>> bool((path[:, 0] == path[:, 1]).all()), len(path)
        (True, 60)
        """
        from ..similarity.audit import warping_path

        missing = [k for k in ("doc_a", "start_a", "end_a", "doc_b", "start_b", "end_b", "mirrored") if k not in pair]
        if missing:
            raise ParameterError(f"a pair of the audit needs {', '.join(missing)} (a row of the pair table)")
        sides = []
        for s in "ab":
            doc, (a, b) = int(pair[f"doc_{s}"]), (int(pair[f"start_{s}"]), int(pair[f"end_{s}"]))
            n = int(self.db.document(doc)["n_frames"])  # an unknown document: its typed error
            frame_span((a, b), n, f"document {doc}", name=f"the pair's start_{s}:end_{s}", least=1)
            sides.append(self.db.motion(doc)[a:b])
        return warping_path(*sides, mirrored=bool(pair["mirrored"]), numeric_set=numeric_set)

    def leakage(self, pairs: pd.DataFrame, split) -> pd.DataFrame:
        """The pairs of an :meth:`audit` that leak a test document into a train one, the test side first;
        ``split``: a CSV file of ``doc`` (id or name) and ``split`` (train / val / test), or {doc_id: split}."""
        from ..similarity.audit import leakage, read_split

        split = pd.Series(split) if isinstance(split, dict) else read_split(split, self.db.documents)
        return leakage(pairs, split)

    def keep_one(self, pairs: pd.DataFrame) -> pd.DataFrame:
        """The documents left when each cluster of copies of an :meth:`audit` keeps one (its longest): a clean
        training set (rows of ``db.documents``)."""
        from ..similarity.audit import keep_one

        return keep_one(pairs, self.db.documents)

    def quality(self, methods=None, **options) -> dict:
        """Retrieval quality of search methods on the database's labels
        (:func:`mocapviz.experiments.retrieval.retrieval_quality`, its options; the relational methods use this
        engine's indexes)."""
        from ..experiments.retrieval import retrieval_quality

        relational = methods is None or {"relational", "hybrid"} & set(methods)
        return retrieval_quality(self.db, methods, indexes=self.indexes() if relational else None, **options)

    # ------------------------------------------------------------------ segment labels (mocapviz.db.segments)
    @checked("segment_labels")
    def segment_labels(self, *, label=...) -> pd.DataFrame:
        """The database's segment labels now (every change replayed), by label id, as a hit table: rank, doc_id,
        name, start, end (frames of the document, half-open), frames, start_s, end_s, then label_id, label, author,
        source, time (UTC ISO 8601), note and the documents' other label columns; ``label``: that label's only."""
        from ..db.segments import SegmentLabels, label_hits

        return label_hits(self.db, SegmentLabels(self.db).table(label))

    @checked("add_label")
    def add_label(self, doc: int, *, frames, label=..., author=..., source=..., note=...) -> int:
        """Label frames ``frames`` = (a, b), half-open, of document ``doc`` as ``label``, by ``author`` (default the
        operating system's user name), from ``source``; returns the new label's id. One change of the label history,
        written atomically under the labels' lock (several writers at once all land)."""
        from ..db.segments import SegmentLabels

        a, b = (frames.start, frames.stop) if isinstance(frames, slice) else frames
        return SegmentLabels(self.db).add(doc, a, b, label, author=_author(author), source=source, note=note or "")

    @checked("add_label")
    def add_labels(self, hits, *, label=..., author=..., source=..., note=...) -> list[int]:
        """Every row of a hit table (doc_id, start, end) labelled ``label`` at once (a page of hits accepted, with
        ``source="accepted hit"``, or rejected): one change per row, written together; returns the new ids."""
        from ..db.segments import SegmentLabels

        rows = [{"doc_id": d, "start": a, "end": b, "label": label, "source": source, "note": note or ""}
                for d, a, b in zip(hits["doc_id"], hits["start"], hits["end"])]  # fmt: skip
        return SegmentLabels(self.db).add_many(rows, author=_author(author))

    @checked("remove_label")
    def remove_label(self, label_id: int, *, author=...) -> int:
        """Remove the segment label ``label_id`` (a change of the history, by ``author``); returns the change's
        number."""
        from ..db.segments import SegmentLabels

        return SegmentLabels(self.db).remove(label_id, author=_author(author))

    @checked("undo_label")
    def undo_label(self, change: int | None = None, *, author=...) -> int:
        """Undo change ``change`` of the label history (default: ``author``'s last change not undone) by a new
        change that puts the label back exactly as it was; returns that change's number
        (:meth:`mocapviz.db.segments.SegmentLabels.undo`)."""
        from ..db.segments import SegmentLabels

        return SegmentLabels(self.db).undo(change, author=_author(author))

    def label_history(self) -> pd.DataFrame:
        """Every change of the segment labels, in order: change, op (add, remove, edit), label_id, author, time,
        undoes (the change an undo reverts) and the row it leaves
        (:meth:`mocapviz.db.segments.SegmentLabels.history`)."""
        from ..db.segments import SegmentLabels

        return SegmentLabels(self.db).history()

    @checked("export_labels")
    def export_labels(self, out=None, *, format=..., label=...):
        """The segment labels (``label``'s only, when given) as a file: ``format="csv"``, :meth:`segment_labels`'
        columns; ``"babel"``, BABEL-style JSON (per document name, segments with start_t / end_t in seconds at the
        document's rate and action names; :func:`mocapviz.db.segments.babel_json`). Written atomically to ``out``
        (returned), or returned as bytes when ``out`` is None (a page's download)."""
        from ..db.segments import SegmentLabels, exported
        from ..store import atomic_write

        data = exported(self.db, SegmentLabels(self.db).table(label), format)
        if out is None:
            return data
        atomic_write(out, data)
        return Path(out)

    @checked("import_labels")
    def import_labels(self, path, *, author=...) -> list[int]:
        """The labels of a CSV or BABEL-style JSON file (:meth:`export_labels`' formats, read by
        :func:`mocapviz.db.segments.read_labels`; documents matched by name) added with source ``imported``, all or
        none; returns their new ids."""
        from ..db.segments import SegmentLabels, read_labels

        return SegmentLabels(self.db).add_many(read_labels(self.db, path), author=_author(author))

    @checked("segment_labels")
    def label_quality(self, hits, *, label=...) -> dict:
        """How well a ranked hit table finds ``label``, judged by its segment labels (manual, accepted, imported)
        and the documents of that file-name label: a hit is relevant when it overlaps an item not found by an
        earlier hit (:func:`mocapviz.experiments.evaluation.segment_relevance`). Returns ``ranking`` (with
        ``precision`` and ``recall`` after each rank), ``relevant`` (the items), ``precision`` (over every hit),
        ``average_precision``."""
        from ..db.segments import POSITIVE, SegmentLabels
        from ..experiments.evaluation import average_precision, precision_recall, segment_relevance

        if label is None:
            raise ParameterError("label_quality needs a label")
        docs = self.db.documents
        file_labels = docs.set_index("doc_id")["label"].astype("string") if "label" in docs.columns else None
        ranking, n = segment_relevance(hits, SegmentLabels(self.db).table(label, POSITIVE), label, file_labels)
        return {"ranking": precision_recall(ranking, n), "relevant": n,
                "precision": float(ranking["relevant"].mean()) if len(ranking) else float("nan"),
                "average_precision": average_precision(ranking, n)}  # fmt: skip

    @checked("segment_labels")
    def with_label(self, hits, *, label=...) -> pd.DataFrame:
        """The rows of a hit table that overlap a stretch of ``label``: a segment labelled so (not a rejected hit;
        :func:`mocapviz.db.segments.overlapping`: a frame in common) or a document whose file-name label is it;
        ranked again, its attrs kept (``mocapviz search/find --label``)."""
        from ..db.segments import POSITIVE, SegmentLabels, overlapping

        if label is None:
            raise ParameterError("with_label needs a label")
        keep = overlapping(hits, SegmentLabels(self.db).table(label, POSITIVE))
        if "label" in self.db.documents.columns:
            file_label = self.db.documents.set_index("doc_id")["label"].astype("string")
            keep |= (file_label.reindex(hits["doc_id"]) == label).fillna(False).to_numpy(bool)
        kept = hits[keep].copy()
        kept["rank"] = np.arange(1, len(kept) + 1)
        kept.attrs = dict(hits.attrs)
        return kept.reset_index(drop=True)

    @checked("export")
    def export(self, hits, out, *, format=..., rig=..., search: str | None = None) -> list:
        """Every row of a hit table (or its CSV file) written into the folder ``out`` as motion files, all or
        nothing (:func:`mocapviz.export.export_hits`)."""
        from ..export import export_hits

        return export_hits(self.db, hits, out, format, rig, search)

    # ------------------------------------------------------------------ the merge
    def _merged(self, packs: list, order: list[str], n_matches: int | None, t0: float) -> pd.DataFrame:
        """The shards' packed hit tables (:meth:`Shard.packed`; None: nothing could match there) as one hit table, in
        ``order`` (``_first`` / ``_last``: the hit's first / last database frame), the first ``n_matches``, ranked
        again, with the shards' column order."""
        packs = [p for p in packs if p is not None]
        if not packs:
            return self._noted(hit_table(self.db, [], [], []))
        data = {c: np.concatenate([p["columns"][c] for p in packs]).astype(  # int32 on the wire, as they were
                    np.result_type(*(p["dtypes"][c] for p in packs)), copy=False) for c in packs[0]["columns"]}
        first = first_frames(self.db, data["doc_id"])
        keys = {"_first": first + data["start"], "_last": first + data["end"] - 1}
        rows = np.lexsort([keys[c] if c in keys else data[c] for c in order][::-1])[:n_matches]
        picked = {c: v[rows] for c, v in data.items()}
        merged = hit_table(self.db, picked.pop("doc_id"), picked.pop("start"), picked.pop("end"), **picked)
        # the shards' column order (a path after the labels), their one label column standing for all of them
        order = [c for name in packs[0]["order"] for c in (self.db.label_columns if name == "label" else [name])]
        if list(merged.columns) != order and set(merged.columns) == set(order):
            merged = merged[order]
        merged.attrs.update({k: v for k, v in packs[0]["attrs"].items() if isinstance(v, (str, int, float))})
        merged.attrs.update(shards=len(self.shards), ms=1e3 * (time.perf_counter() - t0))
        return self._noted(merged)

    def _noted(self, table: pd.DataFrame) -> pd.DataFrame:
        """A search's table saying, where the database holds marker-only documents, that it did not search them
        (attrs ``marker_only_skipped``: they have no canonical joints, :mod:`mocapviz.db.marker_documents`)."""
        if self._marker_only:
            table.attrs["marker_only_skipped"] = self._marker_only
        return table

    # ------------------------------------------------------------------ for the fronts
    def clip_relational(self, example, *, frames=None, relational_set: str = "2005") -> tuple[np.ndarray, list[str]]:
        """The relational features of one clip, computed on the clip (Müller et al. 2005 §3): what a page draws for
        a document or the span it queries with.

        Parameters
        ----------
        example : int or Motion or str or os.PathLike
            A doc id, a Motion or a motion file.
        frames : tuple of int or slice, optional
            [a, b) of the clip (default: all of it).
        relational_set : {"2005", "2006"}

        Returns
        -------
        values : np.ndarray [shape=(T, f)], bool
        names : list of str, the f feature names.
        """
        from ..features import relational_features

        relational_set = checked_value("relational_set", relational_set)
        return relational_features(self._motion(example, frames), relational_set, progress=False)

    def pose_prior(self):
        """The pose prior of reconstruction from sparse markers over every frame of the database (Krüger et al.
        2010 §5.2): its body-frame poses and kd-trees, made anew on each call (keep it; ``restrict`` leaves
        frames out).

        Returns
        -------
        PosePrior
            :class:`mocapviz.similarity.reconstruction.PosePrior` of this process's database.
        """
        from ..similarity.reconstruction import PosePrior

        return PosePrior(self.db)

    @checked("export")
    def export_files(self, hits, *, format=..., rig=..., search: str | None = None) -> dict:
        """What :meth:`export` writes, in memory: each hit's files of a hit table or its CSV file.

        Parameters
        ----------
        hits : pandas.DataFrame or str or os.PathLike
            A hit table or its CSV file.
        format : {"bvh", "amc", "glb", "humanml3d"}
        rig : {"source", "canonical"}, optional
            Default: canonical for glb and humanml3d, source otherwise.
        search : str, optional
            What found the hits, written into every file.

        Returns
        -------
        dict of str to bytes
            File name -> contents, in the table's order (:func:`mocapviz.export.hit_files`).
        """
        from ..export import hit_files

        return hit_files(self.db, hits, format, rig, search)

    @checked("export")
    def export_stretch(self, doc_id: int, out, *, frames=None, format=..., rig=..., search: str | None = None) -> list:
        """One stretch of a document written into the folder ``out`` as motion files, all or nothing (``mocapviz
        export --doc``; :func:`mocapviz.export.export_stretch`).

        Parameters
        ----------
        doc_id : int
        out : str or os.PathLike
        frames : tuple of int, optional
            [a, b) of the document (default: all of it).
        format, rig, search
            As :meth:`export_files`.

        Returns
        -------
        list of pathlib.Path, the files written.
        """
        from ..export import export_stretch

        a, b = (None, None) if frames is None else frames
        return export_stretch(self.db, doc_id, out, a, b, format, rig, search)

    def build_indexes(self, relational_set: str = "2005", *, progress: bool = False, scheduler=None) -> pd.DataFrame:
        """The relational features of every frame computed and the inverted indexes of a set built and stored with
        the database, even over current ones (``mocapviz index``; Müller et al. 2005 §3-5).

        Parameters
        ----------
        relational_set : {"2005", "2006"}
        progress : bool
            A progress bar while the features are computed.
        scheduler : None, "local", str or dask.distributed.Client
            Where the features are computed (:func:`mocapviz.parallel.dask_client`; None: threads of this
            process), whatever holds this engine's shards.

        Returns
        -------
        pandas.DataFrame
            The indexes' statistics (:func:`mocapviz.experiments.index_statistics`: Müller et al. 2005 Table 2).
        """
        from ..experiments import index_statistics
        from ..features import relational_features
        from ..relational.index import build

        relational_set = checked_value("relational_set", relational_set)
        t0 = time.perf_counter()
        values, _ = relational_features(self.db, relational_set, progress=progress, scheduler=scheduler)
        t_features = time.perf_counter() - t0
        build(self.db, relational_set, values=values)
        return index_statistics(self.db, relational_set, values=values, t_features=t_features)

    def store_numeric(self, numeric_sets=None, *, pca=None, progress: bool = False, scheduler=None) -> dict:
        """Numeric feature sets computed and stored with the database (``mocapviz features``; Krüger et al. 2010
        §3.2).

        Parameters
        ----------
        numeric_sets : sequence of str, optional
            Default: every set.
        pca : MotionDB or PCAModel, optional
            The reference of the Fp sets: a database to fit the model on, or a model (default: fitted on this
            database).
        progress : bool
        scheduler : None, "local", str or dask.distributed.Client
            Where the sets (and the model) are computed, one cluster for all (None: threads of this process),
            whatever holds this engine's shards.

        Returns
        -------
        dict of str to np.ndarray, each set's (N, d) float32 values as stored.
        """
        from ..features import fit_pca, store_numeric
        from ..parallel import optional_client

        with optional_client(scheduler) as client:
            if isinstance(pca, MotionDB):
                pca = fit_pca(pca, progress=progress, scheduler=client)
            return store_numeric(self.db, numeric_sets, pca=pca, progress=progress, scheduler=client)


class _ShardedIndex:
    """What the lazy neighbourhood graph asks of a kd-tree (:class:`mocapviz.similarity.knn.KnnIndex`), answered by
    the shards: the k nearest database frames of each query frame, merged (:meth:`Engine.knn`)."""

    def __init__(self, sharded: Engine, numeric_set: str):
        self.sharded, self.numeric_set = sharded, numeric_set
        self.n_frames, self.dim = sharded.numeric(numeric_set).shape
        self.n_indexed = self.n_frames

    def query(self, x, k: int, radius=None, eps: float = 0.0, threads=None, exclude=None):
        distances, frames = self.sharded.knn(x, k=k, numeric_set=self.numeric_set, radius=radius, eps=eps,
                                             exclude=exclude)
        return (distances[0], frames[0]) if np.ndim(x) == 1 else (distances, frames)


def _is_doc_id(example) -> bool:
    """Whether a use case's ``example`` names a document of the database (an int), not a Motion or a file."""
    return isinstance(example, (int, np.integer)) and not isinstance(example, bool)


def _work_added(table: pd.DataFrame, packs: list) -> pd.DataFrame:
    """A similarity search's table with its work counted over every shard (attrs ``documents``, ``ranges``,
    ``aligned``, ``cells``, ``brute_cells``; the first shard's alone otherwise): documents searched and brute
    force's cells are then the single process's."""
    for key in ("documents", "ranges", "aligned", "cells", "brute_cells"):
        if key in packs[0]["attrs"]:
            table.attrs[key] = sum(int(p["attrs"][key]) for p in packs)
    return table


def _given_shards(db: MotionDB, shards, n_shards) -> list[np.ndarray]:
    """``shards=`` of :class:`Engine` as int64 arrays, checked: not empty, consecutive documents in storage order,
    every document once, in that order (the merge numbers segments shard after shard)."""
    if n_shards is not None:
        raise ParameterError("give n_shards or shards (each shard's doc ids), not both")
    parts = [np.asarray(s, dtype=np.int64).reshape(-1) for s in shards]
    order = db.documents.sort_values("start")["doc_id"].to_numpy(np.int64)
    if not parts or any(len(p) == 0 for p in parts) or not np.array_equal(np.concatenate(parts), order):
        raise ParameterError(f"shards must be runs of consecutive documents of {db.path} in storage order, every "
                             "document once, in that order (as split_documents returns them)")
    return parts


def _why(exc: Exception) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _author(author: str | None) -> str:
    """The author of a label change: as given, else the operating system's user name."""
    import getpass

    return getpass.getuser() if author is None else author


def checked_value(name: str, value):
    """``value`` of the declared parameter ``name``, checked (:meth:`Parameter.check`)."""
    return PARAMETERS[name].check(value)


class _Here:
    """A shard of this process, in the place of a cluster's actor."""

    def __init__(self, shard: Shard):
        self.shard = shard


class ShardedDB(Engine):
    """The engine on a Dask cluster, by its earlier name (``ShardedDB(db, scheduler)``): use
    ``Engine(db, scheduler=...)``; its ``query_by_example`` and ``match_motion`` are :meth:`Engine.query` and
    :meth:`Engine.match`."""

    def __init__(self, db, scheduler="local", n_shards: int | None = None, numeric_sets=(), relational_sets=(),
                 shards=None):  # fmt: skip
        warnings.warn("ShardedDB is now mocapviz.Engine(db, scheduler=...); ShardedDB will go", FutureWarning,
                      stacklevel=2)  # fmt: skip
        super().__init__(db, scheduler=scheduler, n_shards=n_shards, shards=shards, numeric_sets=numeric_sets,
                         relational_sets=relational_sets)  # fmt: skip

    def query_by_example(self, example, features=None, mode="adaptive", mismatches=0, relational_set="2005",
                         allowed=None) -> pd.DataFrame:  # fmt: skip
        return self.query(example, features=features, mode=mode, mismatches=mismatches, relational_set=relational_set,
                          allowed=allowed)  # fmt: skip

    def match_motion(self, example, frames=None, numeric_set="F15E", method="lng", n_matches=10, k=None, radius=None,
                     eps=0.0, exclude_document=False, paths=False, min_length=...) -> pd.DataFrame:  # fmt: skip
        return self.match(example, frames=frames, numeric_set=numeric_set, method=method, n_matches=n_matches,
                          k=... if k is None else k, radius=radius, eps=eps, exclude_document=exclude_document,
                          paths=paths, min_length=min_length)  # fmt: skip
