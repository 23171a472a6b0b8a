"""The lazy neighbourhood graph: fast global motion matching (Krüger, Tautges, Weber & Zinke 2010 §4.1).

neighbourhoods   the search step: for each query frame, at most k database frames within radius r (KnnIndex).
graph_matches    graph construction and path search on given neighbourhoods: nodes are the neighbours, edges the
                 DTW steps between them, edge cost the distance of the node entered; one shortest-path pass in
                 topological order, O(k m log k). Returns the top ``n_matches`` non-overlapping matches with their
                 paths, each at least ``min_length`` × the query long (default half, as every search).
reached_neighbourhoods
                 the search step a block of query frames at a time, stopping where no path of the graph goes on (no
                 match then): what lng runs by default.
lng              both steps: ``lng(query, knn_index, k=..., radius=...)``.

The cost model is subsequence DTW's "basic" step set (:mod:`mocapviz.match.time_warping`): a diagonal step (next query
frame, next database frame), a "horizontal" step (next query frame, same database frame) and a "vertical" step
(same query frame, next database frame), each adding the local cost of the cell entered. When every cell of the
optimal subsequence-DTW path ending at a frame lies in the neighbourhoods, the graph finds that path and its cost
(the paper's condition for equal results); otherwise the graph's cost there is higher, or there is no path.
Paths never cross a document boundary.
"""

from __future__ import annotations

import time

import numba
import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..validation import MIN_LENGTH, count, renamed
from .time_warping import (
    _check_document_starts,
    _sequence,
    check_query_length,
    matches_frame,
    select_matches,
    shortest_match,
)

FIRST_ROWS = 32  # query frames in the first block that reached_neighbourhoods searches (twice as many each block)


def neighbourhoods(query, knn_index, k: int, radius: float | None = None, eps: float = 0.0, exclude=None,
                   threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The search step of §4.1: for each query frame, the at most ``k`` nearest database frames at distance <
    ``radius`` (fixed-radius kNN).

    Parameters
    ----------
    query : np.ndarray [shape=(m, d)]
        Features of the query frames in the index's feature set (F15E: cm).
    knn_index : mocapviz.similarity.knn.KnnIndex
        The index over the database's features (N, d).
    k : int
        At most this many neighbours per query frame.
    radius : float, optional
        Only neighbours at distance < radius, feature units.
    eps : float
        ε-approximate kNN (:meth:`mocapviz.similarity.knn.KnnIndex.query`; 0: exact).
    exclude : np.ndarray [shape=(2,)], int, optional
        One [start, stop) range of database frames no query frame may match (e.g. the query's own document).
    threads : int, optional
        Threads of the kNN search.

    Returns
    -------
    distances : np.ndarray [shape=(m, k)], float64
        Increasing per row; inf where missing.
    frames : np.ndarray [shape=(m, k)], int64
        Database frames; -1 where missing.
    """
    q = _sequence(query, "query", knn_index.dim, other="the index")
    if len(q) < 2:
        raise ParameterError(f"a query needs at least 2 frames; got {len(q)}")
    if exclude is not None:
        exclude = np.broadcast_to(np.asarray(exclude, dtype=np.int64).reshape(-1)[:2], (len(q), 2))
    return knn_index.query(q, k, radius=radius, eps=eps, threads=threads, exclude=exclude)


def reached_neighbourhoods(query, knn_index, k: int, radius: float | None = None, eps: float = 0.0, exclude=None,
                           threads: int | None = None, starts=None) -> tuple[np.ndarray, np.ndarray, int]:  # fmt: skip
    """:func:`neighbourhoods` a block of query frames at a time (:data:`FIRST_ROWS`, then twice as many each block),
    stopping after the first query frame whose neighbours no path of the graph reaches: every match is a path
    through every query frame, so there is then no match, and the neighbourhoods of the frames after it are not
    searched (left missing). On a whole clip of 10 s or more most paths end within its first few seconds.

    Parameters
    ----------
    query, knn_index, k, radius, eps, exclude, threads :
        As for :func:`neighbourhoods`.
    starts : np.ndarray [shape=(B,)], int, optional
        First frame of every document (paths never cross a document boundary); default one document.

    Returns
    -------
    distances, frames : np.ndarray [shape=(m, k)]
        As from :func:`neighbourhoods` up to the last row searched; inf / -1 after it.
    rows : int
        Query frames searched (m when some path reaches the last one; the block that ends the search is searched
        whole).

    Examples
    --------
    >>> import numpy as np
    >>> from mocapviz.similarity.knn import KnnIndex
    >>> x = np.arange(10.0)[:, None]  # one document of 10 frames, 1-D features
    >>> _, frames, rows = reached_neighbourhoods(np.array([[2.0], [3.0], [8.0], [9.0]]), KnnIndex(x), k=2, radius=1.5)
    >>> rows, frames[:2].tolist()  # no step leads from frames 2-3 to 7-9: no path through the query
    (4, [[2, 1], [3, 2]])
    """
    q = _sequence(query, "query", knn_index.dim, other="the index")
    if len(q) < 2:
        raise ParameterError(f"a query needs at least 2 frames; got {len(q)}")
    if exclude is not None:
        exclude = np.asarray(exclude, dtype=np.int64).reshape(-1)[:2]
    doc_starts = _check_document_starts(starts, knn_index.n_frames)
    k = count(k, "k", 1, knn_index.n_indexed, "the number of indexed frames")  # as the index refuses it, before the
    d = np.full((len(q), k), np.inf)  # (m, k) arrays are made
    f = np.full((len(q), k), -1, dtype=np.int64)
    a, size, front, front_docs = 0, FIRST_ROWS, None, None
    while a < len(q):
        b = min(len(q), a + size)
        d[a:b], f[a:b] = knn_index.query(q[a:b], k, radius=radius, eps=eps, threads=threads,
                                         exclude=None if exclude is None else np.broadcast_to(exclude, (b - a, 2)))
        docs = np.searchsorted(doc_starts, f[a:b], side="right") - 1
        if front is None:  # the first row: every node starts a path
            first = np.sort(f[a][f[a] >= 0])
            front, front_docs = first, np.searchsorted(doc_starts, first, side="right") - 1
        front, front_docs, _ = _reachable(front, front_docs, f[a + (a == 0) : b], docs[(a == 0) :])
        if len(front) == 0:
            return d, f, b
        a, size = b, 2 * size
    return d, f, len(q)


@numba.njit(cache=True)
def _reachable(front, front_docs, frames, docs):  # pragma: no cover - compiled
    """The nodes that paths from the first row reach, row by row (the steps of :func:`_shortest_paths`, no costs).

    front, front_docs (n,): the frames reached in the row before, increasing, and their documents. frames, docs
    (r, k): the neighbours of the next r rows (-1 where missing) and their documents. Returns the frames reached in
    the last row handled and their documents (empty at the first row with none reached: the rows after it are not
    handled), and that row's index (r when every row has some)."""
    for i in range(frames.shape[0]):
        n = np.sum(frames[i] >= 0)
        order = np.argsort(np.where(frames[i] >= 0, frames[i], np.iinfo(np.int64).max))[:n]
        row, doc = frames[i][order], docs[i][order]
        reached = np.zeros(n, dtype=np.bool_)
        p = 0  # first node of the row before whose frame is >= f - 1
        for c in range(n):
            f = row[c]
            while p < len(front) and front[p] < f - 1:
                p += 1
            q = p
            if q < len(front) and front[q] == f - 1:
                reached[c] = front_docs[q] == doc[c]  # diagonal
                q += 1
            if q < len(front) and front[q] == f:  # horizontal
                reached[c] = True
            if c > 0 and reached[c - 1] and row[c - 1] == f - 1 and doc[c - 1] == doc[c]:  # vertical
                reached[c] = True
        front, front_docs = row[reached], doc[reached]
        if len(front) == 0:
            return front, front_docs, i
    return front, front_docs, frames.shape[0]


@numba.njit(cache=True)
def _shortest_paths(frames, dist, docs):  # pragma: no cover - compiled
    """Single-source shortest paths on the lazy neighbourhood graph, row by row (a topological order).

    frames, dist, docs (m, k): the neighbours of each query frame (-1 / inf where missing) and their documents.
    Returns, per row sorted by frame: the frames F, the accumulated costs A, the start frames S, the predecessor
    step P (-1 start, 0 diagonal, 1 horizontal, 2 vertical) and column C of every node, and counts (m,)."""
    m, k = frames.shape
    F = np.full((m, k), -1, dtype=np.int64)
    A = np.full((m, k), np.inf)
    S = np.full((m, k), -1, dtype=np.int64)
    P = np.full((m, k), -1, dtype=np.int8)
    C = np.full((m, k), -1, dtype=np.int64)
    D = np.full((m, k), -1, dtype=np.int64)
    cost = np.full((m, k), np.inf)
    counts = np.zeros(m, dtype=np.int64)
    for i in range(m):
        order = np.argsort(np.where(frames[i] >= 0, frames[i], np.iinfo(np.int64).max))
        for c in range(k):
            f = frames[i, order[c]]
            if f < 0:
                break
            F[i, c], D[i, c], cost[i, c] = f, docs[i, order[c]], dist[i, order[c]]
            counts[i] += 1
    for c in range(counts[0]):
        A[0, c], S[0, c] = cost[0, c], F[0, c]
    for i in range(1, m):
        p = 0  # first node of the previous row whose frame is >= f - 1
        for c in range(counts[i]):
            f, doc = F[i, c], D[i, c]
            best, arg, col = np.inf, -1, -1
            while p < counts[i - 1] and F[i - 1, p] < f - 1:
                p += 1
            q = p
            if q < counts[i - 1] and F[i - 1, q] == f - 1:
                if D[i - 1, q] == doc and A[i - 1, q] < best:  # diagonal
                    best, arg, col = A[i - 1, q], 0, q
                q += 1
            if q < counts[i - 1] and F[i - 1, q] == f and D[i - 1, q] == doc and A[i - 1, q] < best:  # horizontal
                best, arg, col = A[i - 1, q], 1, q
            if c > 0 and F[i, c - 1] == f - 1 and D[i, c - 1] == doc and A[i, c - 1] < best:  # vertical
                best, arg, col = A[i, c - 1], 2, c - 1
            if arg >= 0:
                A[i, c] = best + cost[i, c]
                P[i, c], C[i, c] = arg, col
                S[i, c] = S[i, c - 1] if arg == 2 else S[i - 1, col]
    return F, A, S, P, C, counts


@numba.njit(cache=True)
def _graph_path(F, P, C, i, c):  # pragma: no cover - compiled
    """The path ending in node (row i, column c) as (L, 2) rows of (query frame, database frame)."""
    out = np.empty((F.shape[0] * (F.shape[1] + 1), 2), dtype=np.int64)
    n = 0
    while True:
        out[n, 0], out[n, 1] = i, F[i, c]
        n += 1
        step = P[i, c]
        if step < 0:
            break
        c = C[i, c]
        if step != 2:
            i -= 1
    return out[:n][::-1].copy()


def graph_matches(distances, frames, starts=None, n_frames: int | None = None, n_matches: int = 10,
                  paths: bool = True, min_length: float | None = MIN_LENGTH) -> pd.DataFrame:  # fmt: skip
    """Graph construction and path search of §4.1 on given neighbourhoods: the top ``n_matches`` non-overlapping
    matches.

    Parameters
    ----------
    distances, frames : np.ndarray [shape=(m, k)]
        From :func:`neighbourhoods` (inf / -1 where missing).
    starts : np.ndarray [shape=(B,)], int, optional
        First frame of every document; default one document.
    n_frames : int, optional
        Database frames (default: the largest neighbour frame + 1).
    n_matches : int
        Matches wanted.
    paths : bool
        Return each match's path.
    min_length : float, optional
        The shortest match, a share in (0, 1] of the query's frames (default 0.5): an end node whose shortest path
        spans fewer database frames is no candidate, the rule of :func:`mocapviz.match.subsequence_dtw` and of the
        similarity search's stretches (:func:`mocapviz.match.time_warping.shortest_match`). None: any length
        (the paper's graph: a path may stay on one database frame for the whole query).

    Returns
    -------
    pandas.DataFrame
        Like :func:`mocapviz.match.subsequence_dtw`'s: doc_id, start, end (database frames, inclusive), cost (sum
        of the local costs along the path, feature units), path ((L, 2) (query frame, database frame)).
    """
    d = np.asarray(distances, dtype=np.float64)
    f = np.asarray(frames, dtype=np.int64)
    if d.ndim != 2 or d.shape != f.shape or len(d) < 2:
        raise ParameterError(f"distances and frames must be (m, k) arrays of the same shape with m >= 2; got {d.shape} "
                         f"and {f.shape}")  # fmt: skip
    shortest = shortest_match(min_length, len(d))
    n = int(f.max()) + 1 if n_frames is None else int(n_frames)
    doc_starts = _check_document_starts(starts, max(n, 1))
    docs = np.searchsorted(doc_starts, f, side="right") - 1
    F, A, S, P, C, counts = _shortest_paths(f, d, docs)
    last = len(F) - 1
    cols = np.arange(counts[last])
    cols = cols[F[last, cols] - S[last, cols] + 1 >= shortest]
    chosen = cols[select_matches(S[last, cols], F[last, cols], A[last, cols], count(n_matches, "n_matches"))]
    found = [_graph_path(F, P, C, last, c) if paths else None for c in chosen]
    return matches_frame(doc_starts, S[last, chosen], F[last, chosen], A[last, chosen], found)


@renamed(k_matches="n_matches")
def lng(query, knn_index, k: int = 64, radius: float | None = None, n_matches: int = 10, starts=None,
        eps: float = 0.0, exclude=None, threads: int | None = None, paths: bool = True,
        min_length: float | None = MIN_LENGTH, early_stop: bool = True) -> pd.DataFrame:  # fmt: skip
    """Global motion matching with the lazy neighbourhood graph (Krüger et al. 2010 §4.1): the top ``n_matches``
    non-overlapping stretches of the database that align to the query, ranked by global cost, with their
    alignments, in O(k m log n).

    Parameters
    ----------
    query : np.ndarray [shape=(m, d)]
        Features of the query frames (m >= 2) in the index's feature set (F15E: cm).
    knn_index : mocapviz.similarity.knn.KnnIndex
        Over the database's features (N, d), e.g. ``KnnIndex(numeric_of(db, "F15E"))``.
    k : int
        At most this many neighbours per query frame (1 <= k <= indexed frames).
    radius : float, optional
        Only neighbours at distance < radius (feature units).
    n_matches : int
        Matches wanted (its old name ``k_matches`` still works, with a FutureWarning).
    starts : np.ndarray [shape=(B,)], int, optional
        First frame of every document (``db.documents.start``); default one document.
    eps : float
        ε-approximate kNN (see :meth:`mocapviz.similarity.knn.KnnIndex.query`).
    exclude : (int, int), optional
        A [start, stop) range of database frames not to match (the query's own document).
    threads : int, optional
        kNN threads (default :func:`mocapviz.parallel.default_threads`).
    paths : bool
        Return each match's path.
    min_length : float, optional
        The shortest match, a share in (0, 1] of the query's frames (default 0.5: half as long), as for
        :func:`graph_matches`; None: any length.
    early_stop : bool
        Search the neighbourhoods a block of query frames at a time and stop at the first block with a query frame
        that no path reaches (:func:`reached_neighbourhoods`: no match then, the answer of the full search); False:
        every query frame's neighbourhood before the graph, as in the paper. The matches are the same either way.

    Returns
    -------
    pandas.DataFrame
        Best first: doc_id (index into ``starts``), start, end (database frames, inclusive), cost (feature
        units), path ((L, 2) int64 (query frame, database frame)). ``attrs["seconds"]`` holds {"knn": ...,
        "graph": ...}, ``attrs["searched"]`` the query frames whose neighbourhoods were searched. :func:`mocapviz.similarity.motion_matching.match_motion` gives the matches of a MotionDB
        as the hit table.

    Raises
    ------
    ValueError / TypeError
        A query of fewer than 2 frames, longer than the longest document or of the wrong dimension, k or radius
        out of range (from the index).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §4.1 (the lazy neighbourhood graph) and §4.2 (against subsequence DTW).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_of
    >>> from mocapviz.similarity.knn import KnnIndex
    >>> db = MotionDB.sample()
    >>> x, starts = numeric_of(db, "F15E"), db.documents["start"].to_numpy()
    >>> own = db.frames(7)
    >>> matches = lng(x[own.start : own.start + 60], KnnIndex(x), k=1024, starts=starts, n_matches=2,
    ...               exclude=(own.start, own.stop))  # 0.5 s of a kick, its own clip left out
    >>> matches["doc_id"].tolist(), matches["cost"].round(1).tolist()  # the cost of subsequence DTW's best match
    ([18, 12], [2489.7, 4156.3])
    >>> (matches["end"] - matches["start"] + 1).tolist()  # each at least half the query (min_length=0.5)
    [41, 30]
    """
    check_query_length(len(query), _check_document_starts(starts, knn_index.n_frames), knn_index.n_frames)
    t0 = time.perf_counter()
    if early_stop:
        d, f, searched = reached_neighbourhoods(query, knn_index, k, radius, eps, exclude, threads, starts)
    else:
        d, f = neighbourhoods(query, knn_index, k, radius, eps, exclude, threads)
        searched = len(d)
    t1 = time.perf_counter()
    out = graph_matches(d, f, starts, knn_index.n_frames, n_matches, paths, min_length)
    out.attrs["seconds"] = {"knn": t1 - t0, "graph": time.perf_counter() - t1}
    out.attrs["searched"] = searched
    return out
