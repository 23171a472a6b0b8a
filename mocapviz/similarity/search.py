"""Similarity search: the clips, or stretches of long takes, of a MotionDB that move most like a query, ranked by
DTW on a numeric feature set (Krüger et al. 2010 §3.2 features; DTW as in :mod:`mocapviz.match.time_warping`).

Two tasks:

- :meth:`SimilaritySearch.clips`: whole documents ranked by DTW cost normalised by query + document frames.
- :meth:`SimilaritySearch.stretches`: the K best non-overlapping stretches inside documents by subsequence DTW
  (raw cost, as :func:`mocapviz.match.subsequence_dtw` ranks them), at least ``min_length`` × the query long.

Three modes, one answer where they agree:

- ``"exact"``: exactly the brute-force top K (tested against :func:`~mocapviz.match.dtw` per document and
  :func:`~mocapviz.match.subsequence_dtw`), with admissible pruning (:mod:`mocapviz.match.pruned`): documents are
  aligned most promising first (whole clips: by the coarse DTW below; stretches: by lower bound), a document
  whose lower bound exceeds the running K-th best is skipped, and cells whose cost plus the bound of the rows
  still to come exceed it are dropped. Lower bounds (:mod:`mocapviz.match.bounds`): each query frame's distance
  to a document's bounding box (LB_Keogh's envelope with the whole document as envelope), each document frame's
  distance to the query's box (whole clips: every document frame is on the path), the path's first and last
  cells (LB_Kim), and, for stretches, the query frames' k nearest database frames (a document without a
  neighbour of query frame i is at least the k-th neighbour's distance away from it). Whole clips also start
  from an upper bound: the K-th least cost of the straight path (:func:`mocapviz.match.bounds.diagonal_costs`)
  among the first documents in coarse order, a cost K documents are known to reach.
- ``"fast"``: exact DTW on a few candidates only. Whole clips: the ``budget`` documents of least DTW cost on the
  block means of 0.2 s (``POOL_SECONDS``; 1/36 of the cells at 6 frames a block; every cell, by
  :func:`mocapviz.match.pruned.range_costs`), aligned with exact mode's bounds and pruning. Stretches: windows around every
  kNN neighbour of a query frame (wide enough for a match from half to twice the query's speed) and around the
  3 K best matches of subsequence DTW on the block means, merged, aligned with the exact mode's pruning. The
  costs returned are exact; what can be missed is measured: recall of exact DTW's top K in ``mocapviz reproduce
  retrieval_quality`` and ``benchmarks/bench_search.py``.
- ``"brute"``: every cell of every document (the reference, for benchmarks).

The paper's own method, the lazy neighbourhood graph (:func:`mocapviz.match.lng`), needs a neighbour for every
query frame along the whole path; fast mode needs one anywhere in the match and then aligns exactly.
"""

from __future__ import annotations

import os
import time
import weakref
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numba
import numpy as np
import pandas as pd

from ..db.hits import hit_table
from ..errors import ParameterError
from ..features import numeric_features, numeric_of
from ..features.numeric import NUMERIC_SETS, default_pca
from ..match.bounds import box_rows, diagonal_costs, range_of, row_bounds, whole_rows
from ..match.pruned import range_costs, search_ranges
from ..match.time_warping import dtw, select_matches, shortest_match
from ..motion import Motion
from ..validation import MIN_LENGTH, count, frame_span, number, one_of

if TYPE_CHECKING:
    from .knn import KnnIndex

MODES = ("exact", "fast", "brute")
NEIGHBOURS = 32  # k: nearest database frames per query frame (bounds and fast mode's seeds)
CLIP_BUDGET = 24  # fast mode, whole clips: documents aligned at most (at least 2 x the matches asked for) ...
POOL_SECONDS = 0.2  # ... chosen by DTW on the means of 0.2 s blocks of frames (6 frames at 30 Hz)
WINDOW_SPEED = 2.0  # fast mode, stretches: windows fit a match from 1/2 to 2 x the query's speed ...
WINDOW_PAD = 0.5  # ... plus this share of the query on both sides; and windows around the
COARSE_CANDIDATES = 3  # ... 3 K best matches of subsequence DTW on the coarse database
UPPER_SLACK = 1e-9  # whole clips: the straight paths' K-th cost, relative slack against rounding (see clips)
COARSE_CHUNK = 4096  # whole clips: block means whose local costs are computed at once (query blocks x this, float64)


def _mode(mode) -> str:
    if mode not in MODES:
        raise ParameterError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
    return mode


class SimilaritySearch:
    """DTW search over one numeric set of a MotionDB (see the module docstring).

    Parameters
    ----------
    db : MotionDB
        The database searched.
    numeric_set : str
        A numeric set (:data:`mocapviz.features.NUMERIC_SETS`), the stored one when current (``mocapviz features
        DB``), else computed now. Default F15E (cm).
    documents : sequence of int, optional
        The doc ids that may be returned (e.g. the other actors' clips in a leave-actor-out evaluation); default
        every document.
    k : int
        Nearest database frames per query frame for the bounds and fast mode's seeds.
    features : np.ndarray [shape=(N, d)], optional
        The numeric set's values of every database frame, if already loaded (default: read or computed now).
    index : KnnIndex, optional
        A kd-tree over ``features`` of exactly the searchable frames, if already built (default: built on first
        use), so that a caller holding one (the dashboard) does not build a second.

    Attributes
    ----------
    numeric_set : str, the numeric set searched.
    features : np.ndarray [shape=(N, d)], float32, the numeric set's values of every database frame.
    documents : pd.DataFrame, the searchable documents (doc_id, name, start, n_frames, labels), by start.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.2 (the numeric feature sets compared) and §4 (motion matching by DTW; the
       kNN of §3.3 give fast mode's candidates and the lower bounds).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> search = SimilaritySearch(db, "F15E")
    >>> hits = search.clips(7, n_matches=3, mode="exact", exclude_document=True)  # the clips most like clip 7
    >>> print(hits[["rank", "doc_id", "label", "normalised_cost"]].round(2).to_string(index=False))
     rank  doc_id                       label  normalised_cost
        1      18             kickLFront1Reps            24.25
        2      21           sneak2StepsLStart            40.88
        3      14 elbowToKnee1RepsLelbowStart            42.49
    >>> fast = search.clips(7, n_matches=3, exclude_document=True)  # fast mode (default): here the same ranking
    >>> fast["doc_id"].tolist()
    [18, 21, 14]
    >>> stretches = search.stretches(7, (0, 60), n_matches=2, mode="exact", exclude_document=True)
    >>> stretches["label"].tolist(), stretches["cost"].round(1).tolist()
    (['kickLFront1Reps', 'elbowToKnee1RepsLelbowStart'], [2489.7, 4091.2])
    """

    def __init__(self, db, numeric_set: str = "F15E", documents=None, k: int = NEIGHBOURS, features=None,
                 index: KnnIndex | None = None):  # fmt: skip
        self.db, self.numeric_set, self.k = db, one_of(numeric_set, "numeric set", NUMERIC_SETS), count(k, "k")
        self.features = np.asarray(numeric_of(db, numeric_set) if features is None else features)
        docs = db.documents.sort_values("start")
        if documents is not None:
            wanted = pd.Index(np.asarray(documents, dtype=np.int64).reshape(-1))
            for doc_id in wanted.difference(docs["doc_id"])[:1]:
                db.document(int(doc_id))  # the one "no such document" error
            docs = docs[docs["doc_id"].isin(wanted)]
        if docs.empty:
            raise ParameterError(f"no document to search in {db.path}")
        self.documents = docs.reset_index(drop=True)
        self._doc_ids = self.documents["doc_id"].to_numpy(np.int64)  # numpy, not pandas, in the per-query path
        self._lo = self.documents["start"].to_numpy(np.int64)
        self._hi = self._lo + self.documents["n_frames"].to_numpy(np.int64)
        self._low, self._high = _boxes(self.features, self._lo, self._hi)
        self._index = None
        if index is not None:
            valid = np.zeros(len(self.features), dtype=bool)
            for a, b in zip(self._lo, self._hi):
                valid[a:b] = True
            if index.n_frames != len(self.features) or not np.array_equal(index.valid, valid):
                raise ParameterError("index must be a KnnIndex over the searchable frames of the numeric set")
            self._index = index
        self._coarse = self._coarse_t = None
        rate = db.typical_fps
        self.pool = max(1, round(POOL_SECONDS * rate))

    @property
    def coarse(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fast mode's coarse database: the means of blocks of :attr:`pool` frames of every searchable document
        (N', d) float32, and each document's [lo, hi) rows in it (built on first use)."""
        if self._coarse is None:
            self._coarse = _pooled(self.features, self._lo, self._hi, self.pool)
            self._coarse_t = np.ascontiguousarray(self._coarse[0].T, dtype=np.float64)  # for range_costs
        return self._coarse

    def _coarse_query(self, q: np.ndarray) -> np.ndarray:
        """The query's block means (m', d), as :attr:`coarse` holds the database's."""
        return _pooled(q, np.zeros(1, np.int64), np.array([len(q)]), self.pool)[0]

    @property
    def knn_index(self) -> KnnIndex:
        """The kd-tree over the searchable documents' frames (built on first use)."""
        if self._index is None:
            from .knn import KnnIndex  # scipy.spatial: loaded by a search of stretches, not of whole clips

            valid = np.zeros(len(self.features), dtype=bool)
            for a, b in zip(self._lo, self._hi):
                valid[a:b] = True
            self._index = KnnIndex(self.features, valid=valid)
        return self._index

    # ------------------------------------------------------------------------ the query
    def query_features(self, example, frames=None) -> Query:
        """The query's feature values and its document: :func:`example_features` on this search's numeric set.

        Parameters
        ----------
        example : int, Motion, str or os.PathLike
            A doc id, a Motion or a motion file.
        frames : (int, int) or slice, optional
            [start, stop) frames of the example (default all).

        Returns
        -------
        query : np.ndarray [shape=(m, d)], float32
            The query frames' values of :attr:`numeric_set`.
        doc_id : int or None
            The example's document (None for a Motion or a file).
        """
        return example_features(self.db, self.features, example, frames, self.numeric_set)

    def _ranges(self, own: int | None, exclude_document: bool, candidates) -> np.ndarray:
        """Rows of :attr:`documents` to search."""
        if candidates is None and not (exclude_document and own is not None):
            return np.arange(len(self._doc_ids))
        keep = np.ones(len(self._doc_ids), dtype=bool)
        if exclude_document and own is not None:
            keep &= self._doc_ids != own
        if candidates is not None:
            keep &= np.isin(self._doc_ids, np.asarray(candidates, dtype=np.int64).reshape(-1))
        return np.flatnonzero(keep)

    def _neighbours(self, q: np.ndarray):
        """The exact k nearest searchable frames of every query frame, distances (m, k) and frames (m, k). Frames of
        documents left out of a search (the query's own) are simply ignored by the bounds: the k-th distance still
        bounds every frame not returned."""
        index = self.knn_index
        return index.query(q, min(self.k, index.n_indexed))

    # ------------------------------------------------------------------------ whole clips
    def clips(self, example, frames=None, n_matches: int = 10, mode: str = "fast", exclude_document: bool = False,
              paths: bool = False, candidates=None, budget: int | None = None,
              limit: float | None = None) -> pd.DataFrame:  # fmt: skip
        """The documents that move most like the query, ranked by DTW cost / (query frames + document frames).

        Parameters
        ----------
        example : int, Motion, str or os.PathLike
            The query: a doc id of the database, a Motion or a motion file (:func:`example_features`).
        frames : (int, int) or slice, optional
            [start, stop) frames of the example (default all), at least 2.
        n_matches : int
            Documents to return (K >= 1).
        mode : {"fast", "exact", "brute"}
            See the module docstring.
        exclude_document : bool
            Leave out the query's own document.
        paths : bool
            Add each match's warping path ((L, 2) (query frame, document frame)).
        candidates : sequence of int, optional
            Rank only these doc ids (e.g. relational hits).
        budget : int, optional
            Fast mode's documents aligned at most (default max(CLIP_BUDGET, 2 K)).
        limit : float, optional
            A normalised cost that K documents are known to reach elsewhere (e.g. on other shards): documents
            costing more are pruned from the start (exact mode stays exact for the K best overall; fewer than K
            rows may come back).

        Returns
        -------
        pd.DataFrame, best first, the hit table of :func:`mocapviz.db.hits.hit_table`: rank, doc_id, name, start (0),
        end (the document's frames: half-open), frames, start_s, end_s, cost (accumulated Euclidean costs, feature
        units), normalised_cost (cost / (m + frames)), the label columns, [path].
        ``attrs``: mode, query_frames, ms (search time), documents (searched), aligned (documents aligned),
        cells (local costs computed), brute_cells (cells of brute force).
        """
        n_matches, mode = count(n_matches, "n_matches"), _mode(mode)
        q, own = self.query_features(example, frames)
        t0 = time.perf_counter()
        rows_idx = self._ranges(own, exclude_document, candidates)
        lo, hi = self._lo[rows_idx], self._hi[rows_idx]
        m, limit = len(q), _limit(limit)
        budget_n, ub_cells = -1, 0
        coarse = None
        if mode == "brute" or not len(lo):
            order, bound, rows = np.arange(len(lo)), np.zeros(len(lo)), np.zeros((len(lo), m))
        else:
            if mode == "fast":
                budget_n = max(CLIP_BUDGET, 2 * n_matches) if budget is None else count(budget, "budget")
                order, coarse = self._coarse_order(q, rows_idx)
                bounded = order[:budget_n]
                head = bounded
            else:  # likely matches first: the K-th best falls fast
                order, _ = self._coarse_order(q, rows_idx)
                bounded = order
                head = order[: max(CLIP_BUDGET, 2 * n_matches)]
            if len(head) >= n_matches:  # K documents cost no more than their K-th least straight path
                ub = diagonal_costs(q, self.features, lo[head], hi[head]) / (m + hi[head] - lo[head])
                limit = min(limit, np.partition(ub, n_matches - 1)[n_matches - 1] * (1 + UPPER_SLACK))
                ub_cells = int(np.maximum(m, hi[head] - lo[head]).sum())
            rows, bound = whole_rows(q, self.features, lo, hi, self._low[rows_idx], self._high[rows_idx], bounded)
        costs, aligned, cells = _whole_costs(q, self.features, lo, hi, order, bound, rows, n_matches, mode != "brute",
                                             budget_n, limit)  # fmt: skip
        norm = costs / (m + hi - lo)
        found = np.flatnonzero(np.isfinite(norm))
        found = found[np.lexsort((self._doc_ids[rows_idx[found]], norm[found]))][:n_matches]
        if coarse is not None and len(found) < n_matches:  # fast mode with a budget below K: the coarse order after
            rest = order[~np.isin(order, found)][: n_matches - len(found)]
            found = np.r_[found, rest]
            costs[rest] = np.nan
        ms = 1e3 * (time.perf_counter() - t0)
        table = self._table(rows_idx[found], np.zeros(len(found), np.int64), hi[found] - lo[found], costs[found], m)
        if paths:
            table["path"] = [dtw(q, self.features[a:b])[1] if np.isfinite(c) else None
                             for a, b, c in zip(lo[found], hi[found], costs[found])]  # fmt: skip
        table.attrs.update(mode=mode, query_frames=m, ms=ms, documents=len(lo), aligned=int(aligned),
                           cells=int(cells) + ub_cells, brute_cells=int(m * (hi - lo).sum()))  # fmt: skip
        return table

    def _coarse_order(self, q: np.ndarray, rows_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The searchable documents ``rows_idx`` in increasing normalised DTW cost of the query's and their block
        means (:attr:`coarse`), and those costs: every cell (:func:`mocapviz.match.pruned.range_costs`; on blocks
        of 6 frames a cell costs less than a bound would save)."""
        _, c_lo, c_hi = self.coarse
        qc = self._coarse_query(q)
        lo, hi = c_lo[rows_idx], c_hi[rows_idx]
        costs = range_costs(qc, self._coarse_t, lo, hi, COARSE_CHUNK) / (len(qc) + hi - lo)
        return np.argsort(costs, kind="stable"), costs

    # ------------------------------------------------------------------------ stretches
    def stretches(self, example, frames=None, n_matches: int = 10, mode: str = "fast",
                  min_length: float | None = MIN_LENGTH, exclude_document: bool = False, paths: bool = False,
                  limit: float | None = None, checked: bool = False) -> pd.DataFrame:  # fmt: skip
        """The K best non-overlapping stretches of the documents by subsequence DTW (raw cost, as
        :func:`mocapviz.match.subsequence_dtw` ranks them), each at least ``min_length`` × the query's frames.

        Parameters
        ----------
        example : int, Motion, str or os.PathLike
            The query, as for :meth:`clips`.
        frames : (int, int) or slice, optional
            [start, stop) frames of the example; the query's m frames: 2 <= m <= the longest searchable document.
        n_matches : int
            Stretches to return (K >= 1; fewer when there are fewer).
        mode : {"fast", "exact", "brute"}
            See the module docstring.
        min_length : float
            The shortest match, a share in (0, 1] of the query's frames (default 0.5: half as long), the rule of
            every search (:func:`mocapviz.match.time_warping.shortest_match`); None: any length.
        exclude_document : bool
            Leave out the query's own document.
        paths : bool
            Add each match's warping path ((L, 2) (query frame, frame of the hit's document)).
        limit : float, optional
            A cost that the best matches of K different documents are known to reach elsewhere (e.g. on other
            shards): what costs more is pruned from the start (exact mode stays exact for the K best overall).
        checked : bool
            The query was checked against a whole database already (:func:`check_stretch_query`; a shard of
            :class:`mocapviz.engine.ShardedDB`, whose documents may all be shorter than the query and still hold
            matches of ``min_length``): not refused here, and no document to search answers nothing.

        Returns
        -------
        pd.DataFrame as :meth:`clips` (start, end: the stretch's frames in its document, half-open);
        ``attrs`` also holds ``ranges`` (documents or fast mode's windows searched).
        """
        n_matches, mode = count(n_matches, "n_matches"), _mode(mode)
        q, own = self.query_features(example, frames)
        t0 = time.perf_counter()
        rows_idx = self._ranges(own, exclude_document, None)
        lo, hi = self._lo[rows_idx], self._hi[rows_idx]
        m = len(q)
        shortest = shortest_match(min_length, m)
        if not checked:
            check_stretch_query(hi - lo, m, shortest)
        bound = np.zeros(len(lo))
        rows = np.zeros((len(lo), m))
        order = np.arange(len(lo))
        if mode != "brute" and len(lo):
            dist, nb = self._neighbours(q)
            if mode == "fast":
                seeds = _windows(nb, m, self._lo[rows_idx], self._hi[rows_idx])
                lo, hi = _merge(*(np.r_[a, b] for a, b in zip(seeds, self._coarse_windows(q, rows_idx, n_matches,
                                                                                          shortest))))  # fmt: skip
            rows = row_bounds(dist, nb, lo, hi)
            if mode == "exact":
                rows = np.maximum(rows, box_rows(q, self._low[rows_idx], self._high[rows_idx]))
            bound = rows.sum(axis=1)
            order = np.argsort(bound, kind="stable")
        starts, ends, costs, aligned, cells = search_ranges(q, self.features, lo, hi, order, bound, rows, n_matches,
                                                            False, shortest, mode != "brute", -1, _limit(limit),
                                                            *_box(q))  # fmt: skip
        chosen = select_matches(starts, ends, costs, n_matches)
        ms = 1e3 * (time.perf_counter() - t0)
        doc_row = np.searchsorted(self._lo, ends[chosen], side="right") - 1
        first = starts[chosen] - self._lo[doc_row]
        table = self._table(doc_row, first, ends[chosen] + 1 - self._lo[doc_row], costs[chosen], m)
        if paths:
            table["path"] = [dtw(q, self.features[s : e + 1])[1] + np.array([0, s - self._lo[r]])
                             for s, e, r in zip(starts[chosen], ends[chosen], doc_row)]  # fmt: skip
        searched = self._hi[rows_idx] - self._lo[rows_idx]
        table.attrs.update(mode=mode, query_frames=m, ms=ms, documents=len(rows_idx), ranges=len(lo),
                           aligned=int(aligned), cells=int(cells), brute_cells=int(m * searched.sum()))  # fmt: skip
        return table

    def _coarse_windows(self, q: np.ndarray, rows_idx: np.ndarray, n_matches: int, shortest: int):
        """Fast mode's windows from the coarse database: the ``COARSE_CANDIDATES`` x K best non-overlapping matches
        of the query's block means by subsequence DTW, as frames of the documents, padded by WINDOW_PAD x m."""
        y, c_lo, c_hi = self.coarse
        qc = self._coarse_query(q)
        lo, hi = c_lo[rows_idx], c_hi[rows_idx]
        want = COARSE_CANDIDATES * n_matches
        starts, ends, costs, _, _ = search_ranges(qc, y, lo, hi, np.arange(len(lo)), np.zeros(len(lo)),
                                                  np.zeros((len(lo), len(qc))), want, False,
                                                  max(1, shortest // self.pool), True, -1, np.inf, *_box(qc))  # fmt: skip
        chosen = select_matches(starts, ends, costs, want)
        r = np.searchsorted(lo, ends[chosen], side="right") - 1
        pad = int(np.ceil(WINDOW_PAD * len(q)))
        f_lo, f_hi = self._lo[rows_idx][r], self._hi[rows_idx][r]
        a = np.maximum(f_lo, f_lo + (starts[chosen] - lo[r]) * self.pool - pad)
        b = np.minimum(f_hi, f_lo + (ends[chosen] + 1 - lo[r]) * self.pool + pad)
        return _merge(a, b)

    def _table(self, doc_rows, start, end, cost, m: int) -> pd.DataFrame:
        """The ranked hit table (:func:`mocapviz.db.hits.hit_table`) of documents ``doc_rows`` (rows of
        :attr:`documents`), frames ``start:end`` within each (half-open), with their DTW costs."""
        frames = np.asarray(end) - np.asarray(start)
        cost = np.asarray(cost, dtype=np.float64)
        return hit_table(self.db, self._doc_ids[np.asarray(doc_rows, dtype=np.int64)], start, end, cost=cost,
                         normalised_cost=cost / (m + frames))  # fmt: skip


def check_stretch_query(frames, m: int, shortest: int) -> None:
    """Refuse a stretch search that no searchable document can answer: none is as long as the query.

    Parameters
    ----------
    frames : np.ndarray [shape=(n,)], int
        The searchable documents' frames (the query's own left out when it is excluded).
    m : int
        The query's frames.
    shortest : int
        The shortest match, frames (:func:`~mocapviz.match.time_warping.shortest_match`).

    Raises
    ------
    ParameterError
        No searchable document, or every one shorter than the query.
    """
    if not len(frames) or np.max(frames) < max(m, shortest):
        longest = int(np.max(frames)) if len(frames) else 0
        raise ParameterError(f"the query has {m} frames, more than the longest searchable document ({longest} "
                             f"frames); choose a shorter span or search whole clips")  # fmt: skip


class Query(NamedTuple):
    """A query's feature values and its document (None for a Motion or a file): what :func:`example_features`
    returns, and what a search accepts as its example when the values are already computed (a sharded search
    computes them once and sends them to every shard)."""

    values: np.ndarray
    doc_id: int | None


def example_features(db, features: np.ndarray, example, frames=None, numeric_set: str = "F15E",
                     option: str = "frames") -> Query:  # fmt: skip
    """The feature values of a query by example: the one step from an example to the values a search compares.

    Parameters
    ----------
    db : MotionDB
    features : np.ndarray [shape=(N, d)]
        The database's values of ``numeric_set`` (:func:`mocapviz.features.numeric_of`): a document's query is
        read from them, not computed again.
    example : int, Motion, str or os.PathLike
        A doc id of ``db``, a Motion (resampled to the database's typical rate when it differs) or a motion file
        (read with :func:`mocapviz.load`).
    frames : (int, int) or slice, optional
        [start, stop) frames of the example (default: all; None for either end); at least 2, inside the example.
    numeric_set : str
        The numeric set of ``features`` (Fp sets use the database's stored PCA model).
    option : str
        How the caller names ``frames`` in an error (the CLI: ``--frames``).

    Returns
    -------
    Query
        ``values`` (np.ndarray [shape=(m, d)], float32: the query frames' feature values) and ``doc_id`` (the
        example's document, None for a Motion or a file); a Query given as ``example`` is returned as it is (its
        values cut to ``frames``).

    Raises
    ------
    ParameterError
        No such document (:meth:`MotionDB.document`), frames outside the example or fewer than 2, an example of
        another type, or non-finite feature values (named with the frame).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_of
    >>> db = MotionDB.sample()
    >>> q, doc = example_features(db, numeric_of(db, "F15E"), 7, (0, 60))
    >>> q.shape, doc
    ((60, 15), 7)
    """
    doc_id = None
    if isinstance(example, Query):
        values = np.asarray(example.values)
        if values.ndim != 2 or values.shape[1] != features.shape[1]:
            raise ParameterError(f"a Query of {numeric_set} has ({features.shape[1]}) values per frame; got shape "
                                 f"{values.shape}")  # fmt: skip
        a, b = _span(frames, len(values), "the query", option)
        values, doc_id = values[a:b], example.doc_id
    elif isinstance(example, (int, np.integer)) and not isinstance(example, (bool, np.bool_)):
        doc_id = int(example)
        start, n = _document_span(db, doc_id)
        a, b = _span(frames, n, f"document {doc_id}", option)
        values = features[start + a : start + b]
    else:
        example = example_motion(db, example)
        a, b = _span(frames, example.n_frames, str(example.source or "the example"), option)
        pca = default_pca(db) if numeric_set.startswith("Fp") else None
        try:
            values = numeric_features(example[a:b], numeric_set, pca=pca, progress=False)
        except ValueError as exc:  # a non-finite position of the clip, named with its frame and joint
            raise ParameterError(f"the query: {exc}") from None
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise ParameterError(f"the query's {numeric_set} features are not finite at frame {a + int(np.argmax(bad))}")
    return Query(np.ascontiguousarray(values, dtype=np.float32), doc_id)


def example_motion(db, example) -> Motion:
    """An example other than a document, as every use case queries it: a motion file read with
    :func:`mocapviz.load` (BVH, ASF + AMC, C3D: the readers ingest uses), or a Motion; resampled to the database's
    typical rate (:attr:`MotionDB.typical_fps`) when it differs, so that its frames count as the database's do.

    Parameters
    ----------
    db : MotionDB
    example : Motion, str or os.PathLike

    Returns
    -------
    Motion
        Its source joints (the use cases map them to the canonical ones), at ``db.typical_fps``.

    Raises
    ------
    ParameterError
        ``example`` is neither a Motion nor a path.
    MocapFormatError
        The file cannot be read (naming it and the line).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.io import datasets
    >>> db = MotionDB.demo()
    >>> m = example_motion(db, datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc")
    >>> m.fps, m.n_frames  # 130 frames at 120 Hz: 33 at 30 Hz
    (30.0, 33)
    """
    if isinstance(example, (str, os.PathLike)):
        from ..io import load

        example = load(Path(example))
    if not isinstance(example, Motion):
        raise ParameterError(f"example must be a doc id, a Motion or a motion file; got {type(example).__name__}")
    rate = db.typical_fps
    return example.resample(rate) if rate and abs(example.fps - rate) > 1e-6 else example


_SPANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _document_span(db, doc_id: int) -> tuple[int, int]:
    """(start, n_frames) of document ``doc_id`` from a {doc_id: (start, n_frames)} made once per MotionDB (and
    document table): :meth:`MotionDB.frames` filters the pandas table, a millisecond per query on a few hundred
    clips. An unknown doc id raises :meth:`MotionDB.frames`' own error."""
    got = _SPANS.get(db)
    if got is None or got[0] is not db.documents:
        docs = db.documents
        got = (docs, dict(zip(docs["doc_id"].tolist(),
                              zip(docs["start"].tolist(), docs["n_frames"].tolist()))))  # fmt: skip
        _SPANS[db] = got
    span = got[1].get(doc_id)
    if span is None:
        sl = db.frames(doc_id)  # the one "no such document" error (or a document added since)
        return sl.start, sl.stop - sl.start
    return span


def _span(frames, n: int, what: str, option: str = "frames") -> tuple[int, int]:
    """[start, stop) of ``frames`` ((a, b), slice or None) inside 0..n, at least 2 frames, or a ParameterError."""
    if frames is None:
        a, b = 0, n
    elif isinstance(frames, slice):
        if frames.step not in (None, 1):
            raise ParameterError(f"frames must be a contiguous range; got step {frames.step}")
        a, b = 0 if frames.start is None else frames.start, n if frames.stop is None else frames.stop
    else:
        try:
            a, b = frames
        except (TypeError, ValueError):
            raise ParameterError(f"frames must be (start, stop); got {frames!r}") from None
        a, b = 0 if a is None else a, n if b is None else b  # (an open end, as `--frames :30`)
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (a, b)):
        raise ParameterError(f"frames must be integers (start, stop); got {a!r}, {b!r}")
    return frame_span((a, b), n, what, option)


def _boxes(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per range [lo, hi) of x (sorted, disjoint, non-empty) the least and the greatest value of every feature,
    (R, d) float64 each: the ranges' bounding boxes (frames between ranges are left out)."""
    edges = np.column_stack([lo, hi]).ravel()
    edges = edges[:-1] if edges[-1] == len(x) else edges  # reduceat runs the last range to the end by itself
    return (np.minimum.reduceat(x, edges, axis=0)[::2].astype(np.float64),
            np.maximum.reduceat(x, edges, axis=0)[::2].astype(np.float64))  # fmt: skip


def _box(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The query's bounding box: least and greatest value of every feature, (d,) float64 each."""
    return q.min(axis=0).astype(np.float64), q.max(axis=0).astype(np.float64)


def _whole_costs(q, x, lo, hi, order, bound, rows, n_matches: int, prune: bool, budget: int, limit: float = np.inf):
    """Whole-range DTW costs (R,) of the query against ranges [lo, hi) (sorted by lo; inf: not aligned, or pruned
    above the running n_matches-th best normalised cost), the ranges aligned and the cells computed
    (:func:`mocapviz.match.pruned.search_ranges`)."""
    first, _, found, aligned, cells = search_ranges(q, x, lo, hi, order, bound, rows, n_matches, True, 1, prune,
                                                    budget, limit, *_box(q))  # fmt: skip
    costs = np.full(len(lo), np.inf)
    costs[np.searchsorted(lo, first)] = found
    return costs, aligned, cells


def _limit(limit) -> float:
    """A search's starting limit (:func:`mocapviz.match.pruned.search_ranges`): ``limit`` as a float, inf for None."""
    return np.inf if limit is None else number(limit, "limit", 0.0)


def _windows(nb: np.ndarray, m: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fast mode's windows: around every neighbour f of query frame i the frames a match through (i, f) can span
    at 1/WINDOW_SPEED to WINDOW_SPEED x the query's speed, padded by WINDOW_PAD x m, clipped to its document,
    merged where they overlap. Returns sorted, disjoint [lo, hi) arrays."""
    i = np.broadcast_to(np.arange(m)[:, None], nb.shape)
    r = range_of(nb, lo, hi)
    keep = r >= 0
    f, i, r = nb[keep], i[keep], r[keep]  # windows never cross a document: merging keeps them apart
    pad = int(np.ceil(WINDOW_PAD * m))
    a = np.maximum(lo[r], f - np.ceil(WINDOW_SPEED * i).astype(np.int64) - pad)
    b = np.minimum(hi[r], f + np.ceil(WINDOW_SPEED * (m - 1 - i)).astype(np.int64) + pad + 1)
    return _merge(a, b)


def _merge(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frame ranges [a, b) (each inside one document) merged where they overlap: sorted, disjoint [lo, hi)."""
    order = np.argsort(a, kind="stable")
    a, b = np.asarray(a, dtype=np.int64)[order], np.asarray(b, dtype=np.int64)[order]
    if not len(a):
        return a, b
    reach = np.maximum.accumulate(b)
    new = np.ones(len(a), dtype=bool)
    new[1:] = a[1:] >= reach[:-1]
    return a[new], np.maximum.reduceat(b, np.flatnonzero(new))


@numba.njit(cache=True)
def _pooled(x, lo, hi, size):  # pragma: no cover - compiled
    """Means of consecutive blocks of ``size`` frames inside every range [lo, hi) of x (the last block of a range
    may be shorter), each the difference of two float64 prefix sums of x's frames (``np.cumsum`` from frame 0, in
    its order) over the block's frames, as float32. Returns the block means (N', d) float32 and each range's
    [lo', hi') rows among them."""
    d = x.shape[1]
    counts = (hi - lo + size - 1) // size
    ends = np.cumsum(counts)
    means = np.empty((ends[-1] if len(ends) else 0, d), np.float32)
    total = np.zeros(d)  # the prefix sum of frames 0..k-1
    start = np.zeros(d)
    k = 0
    row = 0
    for r in range(len(lo)):
        for a in range(lo[r], hi[r], size):
            b = min(a + size, hi[r])
            while k < a:
                for t in range(d):
                    total[t] += np.float64(x[k, t])
                k += 1
            start[:] = total
            while k < b:
                for t in range(d):
                    total[t] += np.float64(x[k, t])
                k += 1
            for t in range(d):
                means[row, t] = np.float32((total[t] - start[t]) / (b - a))
            row += 1
    return means, ends - counts, ends