"""Sharded search: one MotionDB searched by a Dask cluster, its documents split into shards kept resident on the
workers (:class:`~mocapviz.sharded.shard.Shard`, Dask actors), every query fanned out and the hit tables merged.

Why the merge is exact: a hit never crosses a document and a shard holds whole documents, so each shard's K best
hits (by the search's own order: cost, then the document or the frame) contain every hit of the global K best that
lies in its documents, and the overlaps a search resolves are within one document. Merging the shards' lists by the
same order therefore gives the single-process answer: the same hits, order and costs (tested on every query path).
Fast mode of the similarity search is not exact on one process either: its coarse pass and budget are per shard.

A worker that dies mid-query: its shards are started again on the workers left and the query is asked of them once
more (the whole answer, recomputed); when that fails too, a :class:`~mocapviz.errors.ClusterError`, never a partial
answer.
"""
from __future__ import annotations

import contextlib
import time

import numpy as np
import pandas as pd

from ..db.database import MotionDB
from ..db.hits import first_frames, hit_table
from ..db.shards import split_documents
from ..errors import ClusterError, MocapvizError, ParameterError
from ..match.time_warping import check_query_length, shortest_match
from ..parallel import dask_client
from ..validation import MIN_LENGTH, count
from .shard import Shard

__all__ = ["ShardedDB"]


class ShardedDB:
    """A MotionDB searched by a Dask cluster, one shard per worker (or ``n_shards``), each kept resident there.

    The methods are the library's searches with their own parameters, answered by every shard and merged:
    :meth:`knn` (:meth:`KnnIndex.query`), :meth:`clips` and :meth:`stretches` (:class:`SimilaritySearch`),
    :meth:`query_by_example`, :meth:`find` (scene descriptions), :meth:`search_template`. Each returns the hit
    table the single process returns (docs/glossary.md, "Results").

    Parameters
    ----------
    db : MotionDB or str or os.PathLike
        The database; its folder must be readable by every worker at the same path.
    scheduler : "local", str or dask.distributed.Client
        As every ``scheduler=`` of mocapviz (:func:`mocapviz.parallel.dask_client`): a local cluster for this
        object's life, a scheduler's address, or a Client.
    n_shards : int, optional
        Shards (default: one per worker at the start).
    shards : sequence of array_like of int, optional
        Instead of ``n_shards``: each shard's doc ids, runs of consecutive documents in storage order that hold
        every document once, in that order (default :func:`~mocapviz.db.shards.split_documents`, shards of about
        equal frames); uneven shards, e.g. a few short documents alone, are how the tests reach every case.
    numeric_sets, relational_sets : sequence of str
        Derived data every shard makes now rather than on its first query (kd-trees, inverted indexes).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> with ShardedDB(db, "local", n_shards=2) as sharded:  # doctest: +SKIP
    ...     hits = sharded.clips(7, n_matches=3, mode="exact")
    """

    def __init__(self, db, scheduler="local", n_shards: int | None = None, numeric_sets=(), relational_sets=(),
                 shards=None):  # fmt: skip
        self.db = db if isinstance(db, MotionDB) else MotionDB.open(db)
        if shards is not None:
            shards = _given_shards(self.db, shards, n_shards)
        self._stack = contextlib.ExitStack()
        try:
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
        self._features: dict[str, np.ndarray] = {}

    def close(self) -> None:
        """Let the shards go (and stop a local cluster started here)."""
        self.actors = []
        self._stack.close()

    def __enter__(self) -> ShardedDB:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"ShardedDB({str(self.db.path)!r}: {len(self.shards)} shards on {len(self._workers())} workers)"

    # ------------------------------------------------------------------ the shards
    def _workers(self) -> list[str]:
        return sorted(self.client.scheduler_info()["workers"])

    def _start(self, i: int, worker: str | None):
        future = self.client.submit(Shard, str(self.db.path), self.shards[i].tolist(), self.db.manifest["generation"],
                                    actor=True, workers=None if worker is None else [worker], pure=False)  # fmt: skip
        return future.result()

    def _fan(self, method: str, *args, **kwargs) -> list:
        """``method(*args, **kwargs)`` on every shard at once; a shard whose worker failed is started again on a
        live worker and asked once more; then a ClusterError."""
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

    def features(self, numeric_set: str) -> np.ndarray:
        """The database's values of a numeric set, here (to turn an example into its query once)."""
        if numeric_set not in self._features:
            from ..features import numeric_of

            self._features[numeric_set] = numeric_of(self.db, numeric_set)
        return self._features[numeric_set]

    def _query(self, example, frames, numeric_set: str):
        from ..similarity.search import example_features

        return example_features(self.db, self.features(numeric_set), example, frames, numeric_set)

    def knn_index(self, numeric_set: str = "F15E"):
        """A stand-in for a :class:`~mocapviz.similarity.knn.KnnIndex` of a numeric set whose ``query`` asks every
        shard (what the lazy neighbourhood graph and the dashboard's kNN table use)."""
        return _ShardedIndex(self, numeric_set)

    def search(self, numeric_set: str = "F15E"):
        """A stand-in for a :class:`~mocapviz.similarity.search.SimilaritySearch` of a numeric set: its ``clips`` and
        ``stretches`` ask every shard."""
        return _ShardedSearch(self, numeric_set)

    # ------------------------------------------------------------------ searches
    def knn(self, queries, k: int, numeric_set: str = "F15E", radius: float | None = None, eps: float = 0.0,
            exclude=None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """:meth:`mocapviz.similarity.knn.KnnIndex.query` over every shard: the k nearest database frames.

        Parameters
        ----------
        queries : np.ndarray [shape=(q, d) or (d,)]
            Query rows of ``numeric_set``.
        k : int
            Neighbours, >= 1.
        numeric_set : str
        radius, eps
            As :meth:`KnnIndex.query`.
        exclude : np.ndarray [shape=(q, 2), or (2,) for one query], int, optional
            Database-wide [a, b) frames left out, per query (a shard whose frames are all left out answers
            nothing for that query).

        Returns
        -------
        distances : np.ndarray [shape=(q, k)], float64 (inf where fewer)
        frames : np.ndarray [shape=(q, k)], int64, database-wide (-1 where fewer); nearest first.
        """
        from ..similarity.knn import excluded_ranges

        k = count(k, "k", 1, self.db.n_frames, "the number of indexed frames")  # checked as one kd-tree would
        queries = np.atleast_2d(np.asarray(queries, dtype=np.float64))  # searched in float64, as by one kd-tree
        if exclude is not None:
            exclude = excluded_ranges(exclude, len(queries), self.db.n_frames)
        parts = self._fan("knn", numeric_set, queries, k, radius, eps, exclude)
        distances = np.concatenate([d for d, _ in parts], axis=1)
        frames = np.concatenate([f for _, f in parts], axis=1)
        order = np.lexsort((np.where(frames < 0, np.iinfo(np.int64).max, frames), distances), axis=1)[:, :k]
        distances, frames = np.take_along_axis(distances, order, 1), np.take_along_axis(frames, order, 1)
        if distances.shape[1] < k:
            pad = k - distances.shape[1]
            distances = np.pad(distances, ((0, 0), (0, pad)), constant_values=np.inf)
            frames = np.pad(frames, ((0, 0), (0, pad)), constant_values=-1)
        return distances, frames

    def clips(self, example, frames=None, n_matches: int = 10, numeric_set: str = "F15E", mode: str = "fast",
              exclude_document: bool = False, paths: bool = False) -> pd.DataFrame:  # fmt: skip
        """:meth:`SimilaritySearch.clips` over every shard: the documents that move most like the example, by
        normalised DTW cost then doc id (``mode="exact"`` / ``"brute"``: exactly the single process's answer)."""
        query = self._query(example, frames, numeric_set)
        n_matches = count(n_matches, "n_matches")
        t0 = time.perf_counter()
        options = {"n_matches": n_matches, "exclude_document": exclude_document}
        limit = self._limit("clips", numeric_set, query, "normalised_cost", mode, options)
        tables = self._fan("clips", numeric_set, query, mode=mode, paths=paths, limit=limit, **options)
        return _work_added(self._merged(tables, ["normalised_cost", "doc_id"], n_matches, t0), tables)

    def stretches(self, example, frames=None, n_matches: int = 10, numeric_set: str = "F15E", mode: str = "fast",
                  min_length: float | None = MIN_LENGTH, exclude_document: bool = False,
                  paths: bool = False) -> pd.DataFrame:  # fmt: skip
        """:meth:`SimilaritySearch.stretches` over every shard: the K best non-overlapping stretches by DTW cost, then
        by their last frame in the database (exact and brute mode: the single process's answer)."""
        from ..similarity.search import check_stretch_query

        query = self._query(example, frames, numeric_set)
        n_matches = count(n_matches, "n_matches")
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

    def match_motion(self, example, frames=None, numeric_set: str = "F15E", method: str = "lng", n_matches: int = 10,
                     k: int | None = None, radius: float | None = None, eps: float = 0.0,
                     exclude_document: bool = False, paths: bool = False,
                     min_length: float | None = MIN_LENGTH) -> pd.DataFrame:  # fmt: skip
        """:func:`mocapviz.similarity.motion_matching.match_motion` over the cluster. ``method="lng"``: the k nearest
        neighbours of every query frame come from every shard and are merged (:meth:`knn`), the graph is built
        here; ``"dtw"``: subsequence DTW on every shard, matches merged by cost, then by their last frame."""
        from ..similarity.motion_matching import DEFAULT_K, match_motion

        if method == "dtw":
            query = self._query(example, frames, numeric_set)
            n_matches = count(n_matches, "n_matches")
            t0 = time.perf_counter()
            shortest_match(min_length, len(query.values))  # checked here, once, on the whole database
            check_query_length(len(query.values), self.db.documents["start"].sort_values().to_numpy(), self.db.n_frames)
            tables = self._fan("match_dtw", numeric_set, query, n_matches, exclude_document, paths, min_length)
            table = self._merged(tables, ["cost", "_last"], n_matches, t0)
            table.attrs.update(method="dtw", query_frames=len(query.values))
            return table
        return match_motion(self.db, example, frames, numeric_set, method, n_matches, DEFAULT_K if k is None else k,
                            radius, eps, exclude_document, paths, features=self.features(numeric_set),
                            index=_ShardedIndex(self, numeric_set), min_length=min_length)  # fmt: skip

    def query_by_example(self, example, features=None, mode: str = "adaptive", mismatches: int = 1,
                         relational_set: str = "2005", allowed=None) -> pd.DataFrame:  # fmt: skip
        """:func:`mocapviz.relational.query.query_by_example` over every shard (each with its own inverted indexes):
        the hits ranked by score, then doc id and start, and the segments numbered in the whole database, as on one
        process."""
        from ..relational.query import check_example_query, relational_example

        check_example_query(self.db, example, features, mode, mismatches, relational_set)
        t0 = time.perf_counter()
        example = relational_example(example, relational_set)  # once, here; the shards get its values (a few kB)
        packs = self._fan("query_by_example", example, features, relational_set, mode, mismatches, allowed)
        offset = 0
        for pack in packs:  # a shard numbers its segments from its first; the database from the first shard's
            for column in ("first_segment", "last_segment"):
                pack["columns"][column] = pack["columns"][column].astype(np.int64) + offset
            offset += pack["attrs"].pop("group_segments")
        table = self._merged(packs, ["score", "doc_id", "start"], None, t0)
        table.attrs["group_segments"] = offset
        return table

    def find(self, description, n_matches: int | None = None, relational_set: str | None = None,
             template_cost: float | None = None, overlapping: bool = False) -> pd.DataFrame:  # fmt: skip
        """:func:`mocapviz.relational.scene.find` over every shard: hits by score (seconds), then database frame."""
        from ..relational.scene import empty_reason, read_description

        parsed, template_cost, _ = read_description(self.db, description, relational_set, template_cost)
        n_matches = None if n_matches is None else count(n_matches, "n_matches")
        t0 = time.perf_counter()
        results = self._fan("find", parsed.text, parsed.relational_set, n_matches=n_matches,
                            template_cost=template_cost, overlapping=overlapping)  # fmt: skip
        table = self._merged(results, ["score", "_first"], n_matches, t0)
        # every shard evaluates the same parts in the same order: their counts add up place by place (a label may
        # come twice: 'kick_right | kick_right')
        counts = [(label, sum(p["attrs"]["counts"][i][1] for p in results))
                  for i, (label, _) in enumerate(results[0]["attrs"]["counts"])]  # fmt: skip
        table.attrs.update(description=str(parsed), relational_set=parsed.relational_set, counts=counts,
                           candidates=sum(p["attrs"]["candidates"] for p in results),
                           empty_reason=empty_reason(counts) if table.empty else "")  # fmt: skip
        return table

    def search_template(self, template, n_matches: int = 10, delta: float | None = None,
                        max_cost: float | None = None, prefilter: bool = False) -> pd.DataFrame:  # fmt: skip
        """:func:`mocapviz.relational.templates.search_template` over every shard: instances by cost, then by their
        last frame in the database, as on one process (``prefilter``: each shard aligns only where the template's
        keyframes occur in its own inverted indexes; attrs ``aligned``: the share of all frames aligned)."""
        n_matches = count(n_matches, "n_matches")
        options = {"n_matches": n_matches, "max_cost": max_cost, "prefilter": bool(prefilter),
                   **({} if delta is None else {"delta": delta})}  # fmt: skip
        t0 = time.perf_counter()
        packs = self._fan("search_template", template, **options)
        table = self._merged(packs, ["cost", "_last"], n_matches, t0)
        table.attrs["aligned"] = sum(p["attrs"]["aligned_frames"] for p in packs) / max(1, self.db.n_frames)
        table.attrs.pop("aligned_frames", None)
        return table

    # ------------------------------------------------------------------ the merge
    def _merged(self, packs: list, order: list[str], n_matches: int | None, t0: float) -> pd.DataFrame:
        """The shards' packed hit tables (:meth:`Shard.packed`; None: nothing could match there) as one hit table, in
        ``order`` (``_first`` / ``_last``: the hit's first / last database frame), the first ``n_matches``, ranked
        again, with the shards' column order."""
        packs = [p for p in packs if p is not None]
        if not packs:
            return hit_table(self.db, [], [], [])
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
        return merged


class _ShardedIndex:
    """What the lazy neighbourhood graph asks of a kd-tree (:class:`mocapviz.similarity.knn.KnnIndex`), answered by
    the shards: the k nearest database frames of each query frame, merged (:meth:`ShardedDB.knn`)."""

    def __init__(self, sharded: ShardedDB, numeric_set: str):
        self.sharded, self.numeric_set = sharded, numeric_set
        self.n_frames, self.dim = sharded.features(numeric_set).shape
        self.n_indexed = self.n_frames

    def query(self, x, k: int, radius=None, eps: float = 0.0, threads=None, exclude=None):
        distances, frames = self.sharded.knn(x, k, self.numeric_set, radius, eps, exclude)
        return (distances[0], frames[0]) if np.ndim(x) == 1 else (distances, frames)


class _ShardedSearch:
    """``clips`` and ``stretches`` of :class:`~mocapviz.similarity.search.SimilaritySearch`, asked of the shards."""

    def __init__(self, sharded: ShardedDB, numeric_set: str):
        self.sharded, self.numeric_set = sharded, numeric_set

    def clips(self, example, frames=None, **options) -> pd.DataFrame:
        return self.sharded.clips(example, frames, numeric_set=self.numeric_set, **options)

    def stretches(self, example, frames=None, **options) -> pd.DataFrame:
        return self.sharded.stretches(example, frames, numeric_set=self.numeric_set, **options)


def _work_added(table: pd.DataFrame, packs: list) -> pd.DataFrame:
    """A similarity search's table with its work counted over every shard (attrs ``documents``, ``ranges``,
    ``aligned``, ``cells``, ``brute_cells``; the first shard's alone otherwise): documents searched and brute
    force's cells are then the single process's."""
    for key in ("documents", "ranges", "aligned", "cells", "brute_cells"):
        if key in packs[0]["attrs"]:
            table.attrs[key] = sum(int(p["attrs"][key]) for p in packs)
    return table


def _given_shards(db: MotionDB, shards, n_shards) -> list[np.ndarray]:
    """``shards=`` of :class:`ShardedDB` as int64 arrays, checked: not empty, consecutive documents in storage order,
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
