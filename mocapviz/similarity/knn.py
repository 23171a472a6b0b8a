"""k-nearest-neighbour and radius searches on per-frame feature arrays (Krüger, Tautges, Weber & Zinke 2010).

KnnIndex               a search structure over the frames of a feature array (N, d), e.g. F15E (N, 15) in cm:
                       exact and eps-approximate k nearest neighbours (§3.3, Table 1), "radius r, at most k"
                       (§4.1, the search step of the lazy neighbourhood graph), batched over threads. Engines:
                       "kdtree" (the default: mocapviz's own kd-tree, numba, :mod:`mocapviz.similarity.kdtree`),
                       "ckdtree" (scipy.spatial.cKDTree, the preprocessing of §4.1) and "brute" (numpy/scipy,
                       chunked, exact: the reference in the tests and the baseline of the benchmark).
describe_frames        database frames -> a table of documents, frames within them and labels (for results).
base_poses             fat-graph base poses in O(n log n) (§5.3): a radius search from every frame (at most k
                       neighbours), then greedily the frame with the most remaining neighbours.
base_poses_quadratic   the same clustering from full distance matrices, O(n^2): the reference.

Conventions shared by all functions:

- Distances are Euclidean, in the units of the features (cm for F15E), returned as float64.
- A neighbour lies within radius r when its distance is *strictly* less than r (scipy's
  ``distance_upper_bound``).
- Rows of results are sorted by distance; equal distances by frame number (lowest first). Which of several
  frames tied at the k-th distance are returned is not specified.
- Missing neighbours (fewer than k within r) are index -1 with distance inf.
- Frame numbers are rows of the feature array given to the index (database frame numbers when the features
  cover a whole MotionDB).
"""

from __future__ import annotations

import heapq
import tempfile
import time

import numba
import numpy as np
import pandas as pd
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from ..db.hits import from_database_frames, hit_table
from ..errors import ParameterError
from ..parallel import map_ordered, parallelism
from ..validation import count, one_of, renamed
from . import kdtree

ENGINES = ("kdtree", "ckdtree", "brute")
LEAFSIZE = 16  # points per leaf of scipy's kd-tree (the "kdtree" engine's: kdtree.LEAFSIZE)
_NODE_BYTES = 72  # sizeof(ckdtreenode) in scipy: 9 fields of 8 bytes
_BRUTE_CHUNK_BYTES = 64 << 20  # distance matrix of one brute-force chunk of queries
_ORDER_MIN = 64  # queries from which a batch is searched in the tree's leaf order
_ORDER_EPS = 10.0  # approximation of the 1-NN search that finds a query's place in that order
SPILL_BYTES = 256 << 20  # a float64 copy for the kd-tree above this size is a memory-mapped temporary file
_COPY_ROWS = 1 << 20  # rows copied at a time into it
_SPARE = 64  # at least so many neighbours asked beyond k when a frame range is excluded (KnnIndex._search_excluding)


# ============================================================================ input checks
def _check_features(features) -> np.ndarray:
    """The feature array as a real (N, d) array (not copied), or a ValueError saying what is wrong."""
    arr = np.asarray(features)
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ParameterError(f"features must be a 2-D array (frames, dimensions) with at least one of each; got shape "
                         f"{arr.shape}")  # fmt: skip
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ParameterError(f"features must be real numbers; got dtype {arr.dtype}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ParameterError(f"features: frame {int(np.argmax(bad))} is not finite (NaN or inf); "
                         f"{int(bad.sum())} such frame(s)")  # fmt: skip
    return arr


def _check_valid(valid, n: int) -> np.ndarray:
    """``valid`` as a bool (n,) mask (all True when None)."""
    if valid is None:
        return np.ones(n, dtype=bool)
    mask = np.asarray(valid)
    if mask.dtype != bool or mask.shape != (n,):
        raise ParameterError(f"valid must be a bool mask of shape ({n},), one entry per frame; got {mask.dtype} "
                         f"{mask.shape}")  # fmt: skip
    if not mask.any():
        raise ParameterError("valid selects no frame: there is nothing to search")
    return mask


def frames_mask(frames, n: int) -> np.ndarray:
    """A bool (n,) mask from a mask or from [start, stop) frame ranges.

    Parameters
    ----------
    frames : np.ndarray
        bool [shape=(n,)], True for the frames meant; or int [shape=(B, 2)], one [start, stop) range of frame
        numbers per row, e.g. documents' ``start`` and ``start + n_frames``.
    n : int
        Number of frames.

    Returns
    -------
    np.ndarray [shape=(n,)], bool
    """
    arr = np.asarray(frames)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ParameterError(f"a frame mask must have shape ({n},); got {arr.shape}")
        return arr
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.issubdtype(arr.dtype, np.integer):
        raise ParameterError(f"frames must be a bool mask ({n},) or int [start, stop) ranges (B, 2); got {arr.dtype} "
                         f"{arr.shape}")  # fmt: skip
    if arr.size and (arr.min() < 0 or arr.max() > n or (arr[:, 0] > arr[:, 1]).any()):
        raise ParameterError(f"frame ranges must satisfy 0 <= start <= stop <= {n}")
    # +1 at every start, -1 at every stop, summed: > 0 inside any range
    edges = np.zeros(n + 1, dtype=np.int64)
    np.add.at(edges, arr[:, 0], 1)
    np.add.at(edges, arr[:, 1], -1)
    return np.cumsum(edges[:n]) > 0


def _check_radius(radius) -> float | None:
    if radius is None:
        return None
    r = float(radius)
    if not r > 0 or np.isnan(r):
        raise ParameterError(f"radius must be a positive number (or None for no limit); got {radius!r}")
    return r


def _check_eps(eps) -> float:
    e = float(eps)
    if not e >= 0 or not np.isfinite(e):
        raise ParameterError(f"eps must be a finite number >= 0; got {eps!r}")
    return e


def _check_queries(x, dim: int) -> np.ndarray:
    """Queries as a float64 (q, d) array; a ValueError names the first non-finite query row."""
    arr = np.asarray(x)
    if arr.ndim not in (1, 2) or arr.shape[-1] != dim:
        raise ParameterError(f"queries must have shape ({dim},) or (q, {dim}) to match the index; got {arr.shape}")
    if arr.dtype.kind not in "fiu":  # np.floating or np.integer (not bool, complex or objects)
        raise ParameterError(f"queries must be real numbers; got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr.reshape(1, -1) if arr.ndim == 1 else arr, dtype=np.float64)
    if not np.isfinite(arr).all():  # one reduction when all is well (a single query: microseconds count)
        bad = ~np.isfinite(arr).all(axis=1)
        raise ParameterError(f"query row {int(np.argmax(bad))} is not finite (NaN or inf); {int(bad.sum())} such row(s)")
    return arr


def _check_exclude(exclude, n_queries: int) -> np.ndarray:
    """Per-query [start, stop) frame ranges as int64 (q, 2), or a ValueError."""
    arr = np.asarray(exclude)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.shape != (n_queries, 2) or not np.issubdtype(arr.dtype, np.integer) or (arr[:, 0] > arr[:, 1]).any():
        raise ParameterError(f"exclude must be one [start, stop) frame range per query, int ({n_queries}, 2) with start "
                         f"<= stop; got {arr.dtype} {arr.shape}")  # fmt: skip
    return arr.astype(np.int64)


def excluded_ranges(exclude, n_queries: int, frames) -> np.ndarray:
    """``exclude`` of :meth:`KnnIndex.query` checked: one [start, stop) range of frames per query, each leaving
    some indexed frame (fewer than k left are padded, as with a radius; none left is refused).

    Parameters
    ----------
    exclude : array_like [shape=(q, 2), or (2,) for one query], int
    n_queries : int
        q.
    frames : np.ndarray [shape=(n,)], int64, or int
        The indexed frame numbers, increasing (:attr:`KnnIndex.frames`), or N: frames 0..N-1, every one indexed
        (a sharded search's whole database).

    Returns
    -------
    np.ndarray [shape=(q, 2)], int64

    Raises
    ------
    ParameterError
        Not one range per query, a start after its stop, or a range holding every indexed frame.

    Examples
    --------
    >>> excluded_ranges([2, 5], 1, 10).tolist()
    [[2, 5]]
    >>> excluded_ranges([[0, 10]], 1, 10)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    mocapviz.errors.ParameterError: exclude: query 0 leaves out frames 0:10, every indexed frame; ...
    """
    ranges = _check_exclude(exclude, n_queries)
    if isinstance(frames, (int, np.integer)):
        n, inside = int(frames), np.clip(ranges[:, 1], 0, frames) - np.clip(ranges[:, 0], 0, frames)
    else:
        n, inside = len(frames), np.searchsorted(frames, ranges[:, 1]) - np.searchsorted(frames, ranges[:, 0])
    if (inside >= n).any():
        q = int(np.argmax(inside >= n))
        raise ParameterError(f"exclude: query {q} leaves out frames {ranges[q, 0]}:{ranges[q, 1]}, every indexed "
                             f"frame; exclude a shorter range")  # fmt: skip
    return ranges


# ============================================================================ engines
def _float64_rows(features: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """``features[rows]`` (all rows for None) as the C-contiguous float64 (M, d) array scipy's kd-tree searches in.

    Up to :data:`SPILL_BYTES` in memory; above it in an unlinked temporary file of the cache folder
    (:func:`mocapviz.io.datasets.cache_dir`), memory-mapped and filled a block of rows at a time: file-backed pages
    that the kernel writes out and drops under memory pressure, not anonymous memory held for the index's life
    (1.2 GB for F15E at 10M frames; the space is freed with the index). Where no file can be made, in memory.
    """
    n = len(features) if rows is None else len(rows)
    out = _mapped_float64((n, features.shape[1])) if n * features.shape[1] * 8 > SPILL_BYTES else None
    if out is None:
        return np.ascontiguousarray(features if rows is None else features[rows], dtype=np.float64)
    for a in range(0, n, _COPY_ROWS):
        b = min(n, a + _COPY_ROWS)
        out[a:b] = features[a:b] if rows is None else features[rows[a:b]]
    return out


def _mapped_float64(shape: tuple) -> np.ndarray | None:
    """A writable float64 array of ``shape`` in an unlinked temporary file of the cache folder, memory-mapped; None
    where no such file can be made."""
    from ..io.datasets import cache_dir

    try:
        folder = cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder, prefix="kdtree-") as f:
            f.truncate(int(np.prod(shape)) * 8)
            return np.memmap(f, dtype=np.float64, mode="r+", shape=shape)  # the map outlives the closed file
    except OSError:
        return None


def _build_ckdtree(data: np.ndarray, leafsize: int) -> tuple[cKDTree, np.ndarray]:
    """kd-tree over data (M, d) float64 (§4.1 preprocessing) and the rank (M,) int64 of each point in the tree's
    leaf order. Sliding-midpoint splits (``balanced_tree=False``): on F15E queries are about twice as fast as
    with median splits."""
    tree = cKDTree(data, leafsize=leafsize, balanced_tree=False, copy_data=False)
    rank = np.empty(tree.n, dtype=np.int64)
    rank[tree.indices] = np.arange(tree.n)
    return tree, rank


def _leaf_order(tree: cKDTree, rank: np.ndarray, x: np.ndarray, threads: int) -> np.ndarray:
    """A permutation of the queries x (q, d) in the tree's leaf order (of a roughly nearest point, found by a
    cheap approximate 1-NN search), so that consecutive queries visit the same nodes and points: on a 1M-frame
    F15E tree a batch of random queries then takes about a third less time."""
    _, near = tree.query(x, k=1, eps=_ORDER_EPS, workers=threads)
    return np.argsort(rank[near], kind="stable")


def _query_ckdtree(structure, x: np.ndarray, k: int, radius: float | None, eps: float, threads: int):
    """k nearest (within radius) of queries x (q, d): distances (q, k) float64, positions in the tree's data
    (q, k) int64 with -1 for missing neighbours. Rows sorted by distance (ties in any order). Batches of at
    least ``_ORDER_MIN`` queries are searched in leaf order."""
    tree, rank = structure
    bound = np.inf if radius is None else radius
    if len(x) < _ORDER_MIN:  # as given, and one thread for one query (threads split a batch, never one query)
        d, i = tree.query(x, k=k, eps=eps, distance_upper_bound=bound, workers=threads if len(x) > 1 else 1)
        d, i = d.reshape(len(x), k), i.reshape(len(x), k).astype(np.int64, copy=False)
    else:
        order = _leaf_order(tree, rank, x, threads)
        d_sorted, i_sorted = tree.query(x[order], k=k, eps=eps, distance_upper_bound=bound, workers=threads)
        d, i = np.empty((len(x), k)), np.empty((len(x), k), dtype=np.int64)
        d[order], i[order] = d_sorted.reshape(len(x), k), i_sorted.reshape(len(x), k)
    i[i == tree.n] = -1
    return d, i


def _brute_chunk(data: np.ndarray, x: np.ndarray, k: int, radius: float | None):
    """Exact k nearest of queries x (c, d) among data (M, d) from the full distance matrix (c, M).

    Returns distances (c, k) float64 and positions in ``data`` (c, k) int64, rows sorted by (distance, position);
    beyond the radius: -1 and inf. The squared distances are sums of squared coordinate differences (no
    |x|^2 - 2xy + |y|^2 cancellation), so they agree with the kd-tree's to rounding.
    """
    d2 = cdist(x, data, "sqeuclidean")
    idx = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < d2.shape[1] else np.tile(np.arange(k), (len(x), 1))
    d2k = np.take_along_axis(d2, idx, axis=1)
    order = np.lexsort((idx, d2k), axis=1)
    idx, d2k = np.take_along_axis(idx, order, axis=1), np.take_along_axis(d2k, order, axis=1)
    if radius is not None:
        far = d2k >= radius * radius
        d2k[far], idx[far] = np.inf, -1
    return np.sqrt(d2k), idx


def _query_brute(data: np.ndarray, x: np.ndarray, k: int, radius: float | None, eps: float, threads: int):
    """Brute-force search (exact whatever ``eps``), chunks of queries over ``threads`` threads; see
    :func:`_brute_chunk` for the arrays returned."""
    size = max(1, _BRUTE_CHUNK_BYTES // (8 * len(data)))
    starts = range(0, max(len(x), 1), size)  # one (empty) chunk for an empty batch
    parts = list(map_ordered(lambda s: _brute_chunk(data, x[s : s + size], k, radius), starts,
                             threads=min(threads, len(starts)), name="mocapviz-knn"))  # fmt: skip
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


_ENGINES = {
    "kdtree": (kdtree.build_kdtree, kdtree.query_kdtree),
    "ckdtree": (_build_ckdtree, _query_ckdtree),
    "brute": (lambda data, leafsize: data, _query_brute),
}


def _ties_by_frame(d: np.ndarray, i: np.ndarray):
    """Rows sorted by distance, re-sorted so that equal distances come in increasing position order."""
    same = d[:, 1:] == d[:, :-1]
    if not same.any():  # the usual case: no tie at all, one comparison
        return d, i
    tied = (same & np.isfinite(d[:, 1:])).any(axis=1)
    if tied.any():
        order = np.lexsort((i[tied], d[tied]), axis=1)
        i[tied] = np.take_along_axis(i[tied], order, axis=1)
        d[tied] = np.take_along_axis(d[tied], order, axis=1)
    return d, i


def _least_by_frame(search, structure, queries: np.ndarray, k: int, n: int, radius, eps: float, threads: int):
    """The k nearest of each query by distance, then by position (frame order), whatever the search structure:
    ``search`` is asked for one neighbour more, and where the k-th ties with it, for twice as many until the tied
    group is whole (a kd-tree returns any of the points tied across the k-th: one over the whole database and one
    over a shard chose different frames of two documents holding the same pose; HDM05's cut clips share frames).

    Returns
    -------
    distances (q, k) float64 increasing, positions (q, k) int64 (-1 missing), equal distances in position order.
    """
    want = min(k + 1, n)
    d, i = _ties_by_frame(*search(structure, queries, want, radius, eps, threads))
    tied = d[:, k] == d[:, k - 1] if want > k else None
    if tied is None or not tied.any():  # the usual case: one comparison
        return d[:, :k], i[:, :k]
    rows = np.flatnonzero(tied & np.isfinite(d[:, k]))
    d, i = d[:, :k].copy(), i[:, :k].copy()
    while len(rows):
        want = min(2 * want, n)
        more_d, more_i = _ties_by_frame(*search(structure, queries[rows], want, radius, eps, threads))
        whole = (want == n) | ~np.isfinite(more_d[:, -1]) | (more_d[:, -1] > more_d[:, k - 1])
        d[rows[whole]], i[rows[whole]] = more_d[whole, :k], more_i[whole, :k]
        rows = rows[~whole]
    return d, i


# ============================================================================ the index
class KnnIndex:
    """Nearest-neighbour searches over the frames of a feature array (Krüger et al. 2010 §3.3, §4.1).

    Parameters
    ----------
    features : np.ndarray [shape=(N, d)], real (float32 accepted; searched in float64), e.g. F15E in cm.
    engine : str
        "kdtree" (mocapviz's own kd-tree, :mod:`mocapviz.similarity.kdtree`: the same answers as "ckdtree",
        2-5 times faster on F15E), "ckdtree" (scipy.spatial.cKDTree) or "brute" (exact brute force, chunked; for
        tests and baselines).
    valid : np.ndarray [shape=(N,)], bool, optional
        Frames that may be returned (e.g. not those of deleted documents or of the query's own document). The
        search structure holds the valid frames only; results are frame numbers of ``features``.
    leafsize : int, optional
        Points per kd-tree leaf (ignored by "brute"); default 64 for "kdtree", :data:`LEAFSIZE` for "ckdtree".

    Attributes
    ----------
    n_frames, dim : int         N and d.
    n_indexed : int             number of valid frames.
    frames : np.ndarray         (n_indexed,) int64, the valid frame numbers, increasing.
    valid : np.ndarray          (N,) bool.
    build_seconds : float       wall time of building the structure.
    nbytes : int                memory held by the structure and ``frames``: for "ckdtree" the float64 copy of
                                the valid frames, the kd-tree's permutation, its inverse and nodes (72 bytes
                                each); for "kdtree" its points in leaf order (float32 for float32 features),
                                permutation and nodes (:attr:`mocapviz.similarity.kdtree.KdTree.nbytes`).

    Raises
    ------
    ValueError
        Unknown engine, features not (N, d) real and finite (the first bad frame is named), a bad ``valid``
        mask or one selecting no frame, leafsize < 1.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.3 (kd-tree k nearest neighbours of poses, Table 1) and §4.1 (the
       fixed-radius search step of the lazy neighbourhood graph).

    Examples
    --------
    >>> import numpy as np
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_of
    >>> db = MotionDB.sample()
    >>> index = KnnIndex(numeric_of(db, "F15E"))  # every frame of the database, F15E in cm
    >>> index.n_indexed, index.dim
    (5543, 15)
    >>> own = db.frames(7)
    >>> distances, frames = index.query(numeric_of(db, "F15E")[own.start + 40], k=3, exclude=[own.start, own.stop])
    >>> db.document_of(frames).tolist(), np.round(distances, 1).tolist()  # the nearest poses of another kick
    ([18, 18, 18], [41.3, 41.5, 41.8])
    """

    def __init__(self, features, engine: str = "kdtree", valid=None, leafsize: int | None = None):
        one_of(engine, "engine", ENGINES)
        leafsize = (kdtree.LEAFSIZE if engine == "kdtree" else LEAFSIZE) if leafsize is None else leafsize
        if isinstance(leafsize, (bool, np.bool_)) or not isinstance(leafsize, (int, np.integer)) or leafsize < 1:
            raise ParameterError(f"leafsize must be a positive integer; got {leafsize!r}")
        self._features = _check_features(features)
        self.n_frames, self.dim = self._features.shape
        self.engine, self.leafsize = engine, int(leafsize)
        self.valid = _check_valid(valid, self.n_frames)
        self.frames = np.flatnonzero(self.valid)
        self.n_indexed = len(self.frames)
        self._every = self.n_indexed == self.n_frames  # positions in the structure are frame numbers
        t0 = time.perf_counter()
        data = _float64_rows(self._features, None if self._every else self.frames)
        self._structure = _ENGINES[engine][0](data, self.leafsize)
        self.build_seconds = time.perf_counter() - t0
        self.nbytes = data.nbytes + self.frames.nbytes
        if engine == "ckdtree":
            tree, rank = self._structure
            self.nbytes += tree.indices.nbytes + tree.size * _NODE_BYTES + rank.nbytes
        elif engine == "kdtree":  # its own copy of the points in leaf order instead of the float64 one
            self.nbytes += self._structure.nbytes - data.nbytes

    def __repr__(self) -> str:
        return (f"KnnIndex({self.engine}: {self.n_indexed:,} of {self.n_frames:,} frames, d={self.dim}, "
                f"{self.nbytes / 2**20:.1f} MiB, built in {self.build_seconds:.2f} s)")  # fmt: skip

    @renamed(workers="threads")
    def query(self, x, k: int, radius: float | None = None, eps: float = 0.0, threads: int | None = None,
              exclude=None):
        """The k nearest valid frames of each query (§3.3); with ``radius``, at most k within r (§4.1).

        Parameters
        ----------
        x : np.ndarray [shape=(d,) or (q, d)], real
            One query or q queries, in the features' units (cm for F15E).
        k : int
            Neighbours per query, 1 <= k <= n_indexed.
        radius : float, optional
            Only neighbours at distance < radius; fewer than k are padded with -1 / inf.
        eps : float
            Approximation: the k-th returned distance is at most (1 + eps) times the true k-th nearest distance
            (0: exact). The brute engine is always exact.
        threads : int, optional
            Threads of the search (default :func:`mocapviz.parallel.default_threads`: the cores this process may use,
            at most 8). (Formerly ``workers``: still accepted, with a FutureWarning.)
        exclude : np.ndarray [shape=(q, 2) or (2,)], int, optional
            Per query, a [start, stop) range of frames it must not return (e.g. the query's own document, so that
            its neighbouring frames do not fill the list). Searched as k + a few neighbours, more where those
            leave fewer than k outside the range, and filtered, so the result is the k nearest outside the range
            (padded with -1 / inf where fewer are left).

        Returns
        -------
        distances : np.ndarray [shape=(q, k), or (k,) for x (d,)], float64, sorted increasing.
        indices : np.ndarray [shape=(q, k), or (k,) for x (d,)], int64 frame numbers; -1 where missing. Equal
            distances come in frame order, also across the k-th: the k least by (distance, frame), the same from
            every index over these frames (a shard's included).

        Raises
        ------
        ValueError
            x not of dimension d or not finite (the query row is named), k out of range, radius <= 0, eps < 0,
            bad threads, ``exclude`` not one [start, stop) range per query or leaving no indexed frame outside a
            query's range (fewer than k: the rest padded with -1 / inf).
        TypeError
            k not an integer.

        Examples
        --------
        >>> import numpy as np
        >>> index = KnnIndex(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [0.0, 2.0]]))
        >>> distances, frames = index.query([[0.0, 0.0], [2.9, 0.0]], k=2)
        >>> frames.tolist(), np.round(distances, 2).tolist()
        ([[0, 1], [2, 1]], [[0.0, 1.0], [0.1, 1.9]])
        >>> index.query([0.0, 0.0], k=3, radius=1.5)[1].tolist()  # at most k within the radius, -1 padded
        [0, 1, -1]
        """
        queries = _check_queries(x, self.dim)
        k = count(k, "k", 1, self.n_indexed, "the number of indexed frames")
        radius, eps, threads = _check_radius(radius), _check_eps(eps), parallelism(threads)
        if exclude is None:
            d, i = self._search(queries, k, radius, eps, threads)
        else:
            ranges = excluded_ranges(exclude, len(queries), self.frames)
            d, i = self._search_excluding(queries, k, radius, eps, threads, ranges)
        return (d[0], i[0]) if (x.ndim if isinstance(x, np.ndarray) else np.ndim(x)) == 1 else (d, i)

    def _search(self, queries: np.ndarray, k: int, radius, eps: float, threads: int):
        """Checked queries (q, d) -> distances (q, k), database frame numbers (q, k) (-1 missing): the k least by
        (distance, frame) (:func:`_least_by_frame`)."""
        d, i = _least_by_frame(_ENGINES[self.engine][1], self._structure, queries, k, self.n_indexed, radius, eps,
                               threads)  # fmt: skip
        if self._every:  # every frame indexed: positions are frame numbers already (-1 where missing)
            return d, i
        return d, np.where(i >= 0, self.frames[np.maximum(i, 0)], -1)

    def _search_excluding(self, queries, k: int, radius, eps: float, threads: int, ranges: np.ndarray):
        """:meth:`_search` leaving out each query's [start, stop) frame range: each query asks for k + ``spare``
        neighbours, spare first k (at least :data:`_SPARE`, at most the range's frames; on every archive at 30 Hz a
        search for 1,143 + 334 neighbours took as long as for 1,143), and where fewer than k of them lie outside the
        range, again with a spare grown from the share of them inside it, until k are left or the spare
        covers the range. The k least outside the range by (distance, frame) are the first k of the longer list
        outside it, so the answer is that of a search for k + (frames of the range) neighbours, without its cost
        where few of the nearest frames lie in the range (a query frame's own document of 1,901 frames: 2,048 more
        neighbours for every query frame)."""
        d_out = np.full((len(queries), k), np.inf)
        i_out = np.full((len(queries), k), -1, dtype=np.int64)
        inside = np.searchsorted(self.frames, ranges[:, 1]) - np.searchsorted(self.frames, ranges[:, 0])
        spare = np.minimum(inside, max(k, _SPARE))
        rows = np.arange(len(queries))
        while len(rows):
            short = []
            for w in np.unique(spare[rows]):
                group = rows[spare[rows] == w]
                wide = min(k + int(w), self.n_indexed)
                d, i = self._search(queries[group], wide, radius, eps, threads)
                keep = (i >= 0) & ~((i >= ranges[group, :1]) & (i < ranges[group, 1:]))
                whole = (keep.sum(axis=1) >= k) | (i[:, -1] < 0) | (w >= inside[group]) | (wide == self.n_indexed)
                order = np.argsort(~keep[whole], axis=1, kind="stable")[:, :k]  # kept entries first, by distance
                kept = np.take_along_axis(keep[whole], order, axis=1)
                done = group[whole]
                d_out[done, : order.shape[1]] = np.where(kept, np.take_along_axis(d[whole], order, axis=1), np.inf)
                i_out[done, : order.shape[1]] = np.where(kept, np.take_along_axis(i[whole], order, axis=1), -1)
                short.append(group[~whole])
                # again with 4 × the spare, or more where few were outside: k over that share of the list, at the
                # next power of two (few groups)
                kept_n = np.maximum(keep[~whole].sum(axis=1), 1)
                guess = np.ceil(1.5 * (wide * k / kept_n - k)).astype(np.int64)
                grown = 1 << np.ceil(np.log2(np.maximum(4 * w, guess))).astype(np.int64)
                spare[group[~whole]] = np.minimum(grown, inside[group[~whole]])
            rows = np.concatenate(short)
        return d_out, i_out

    def exclude(self, frames) -> KnnIndex:
        """A new index without some frames (e.g. documents), built again on the remaining valid frames.

        Parameters
        ----------
        frames : np.ndarray
            bool (N,) mask of frames to leave out, or int (B, 2) [start, stop) frame ranges such as documents'
            ``start`` and ``start + n_frames``.

        Returns
        -------
        KnnIndex
            With ``valid = self.valid & ~frames``; building it costs about ``build_seconds``.

        Examples
        --------
        >>> import numpy as np
        >>> index = KnnIndex(np.arange(10.0)[:, None])
        >>> index.exclude(np.array([[0, 4]])).query([0.0], k=2)[1].tolist()  # frames 0-3 left out
        [4, 5]
        """
        drop = frames_mask(frames, self.n_frames)
        return KnnIndex(self._features, self.engine, valid=self.valid & ~drop, leafsize=self.leafsize)


def describe_frames(db, frames, distances=None, per_document: bool = False) -> pd.DataFrame:
    """Database frames (e.g. the neighbours of a kNN query) as hits: one-frame stretches of their documents.

    Parameters
    ----------
    db : MotionDB
    frames : np.ndarray [shape=(n,)], int
        Frame numbers of the database (rows of ``db.positions``), e.g. ``KnnIndex.query``'s neighbours; -1
        entries (missing neighbours of a radius search) are left out.
    distances : np.ndarray [shape=(n,)], optional
        The neighbours' distances (feature units, e.g. cm) to put beside them.
    per_document : bool
        One row per document: its first frame in the given order (the nearest, for neighbours nearest first),
        ranked 1, 2, ... again. A pose's nearest frames are mostly its own take's neighbouring frames; this shows
        which documents hold it.

    Returns
    -------
    pandas.DataFrame
        The hit table of :func:`mocapviz.db.hits.hit_table`, one row per frame in the given order: ``rank``,
        ``doc_id``, ``name``, ``start`` (the frame within its document), ``end`` (``start + 1``), ``frames`` (1),
        ``start_s``, ``end_s``, ``distance`` (when given) and the documents' label columns.

    Raises
    ------
    ParameterError
        A frame beyond the database.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> d0 = db.frames(5).start
    >>> hits = describe_frames(db, [d0 + 12, -1], [0.5, 9.0])
    >>> print(hits[["rank", "doc_id", "start", "end", "frames", "distance"]].to_string(index=False))
     rank  doc_id  start  end  frames  distance
        1       5     12   13       1       0.5
    >>> each = describe_frames(db, [d0 + 12, d0 + 13, d0 + 90], [0.5, 0.6, 0.7], per_document=True)
    >>> print(each[["rank", "doc_id", "start", "distance"]].to_string(index=False))  # document 5 (70 frames) once
     rank  doc_id  start  distance
        1       5     12       0.5
        2       6     20       0.7
    """
    frames = np.asarray(frames, dtype=np.int64).ravel()
    keep = frames >= 0
    if frames[keep].size and frames[keep].max() >= db.n_frames:
        raise ParameterError(f"frame {int(frames[keep].max())} is beyond the database's {db.n_frames:,} frames")
    doc_ids, starts, ends = from_database_frames(db, frames[keep], frames[keep] + 1)
    columns = {} if distances is None else {"distance": np.asarray(distances, dtype=np.float64).ravel()[keep]}
    if per_document:
        first = np.sort(np.unique(doc_ids, return_index=True)[1])  # each document's first row, in the given order
        doc_ids, starts, ends = doc_ids[first], starts[first], ends[first]
        columns = {c: v[first] for c, v in columns.items()}
    return hit_table(db, doc_ids, starts, ends, **columns)


# ============================================================================ fat-graph base poses (§5.3)
def _check_fat_graph(radius, k) -> tuple[float, int]:
    """The radius (> 0) and neighbour cap (>= 1) of the base-pose search, or a ValueError."""
    if radius is None or _check_radius(radius) is None:
        raise ParameterError("radius must be a positive number")
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ParameterError(f"k must be a positive integer; got {k!r}")
    return float(radius), int(k)


def _neighbour_table(features, radius: float, k: int, valid, threads: int, chunk: int = 1 << 16):
    """Each valid frame's at most k nearest *other* valid frames within ``radius`` (§5.3 step 1, kd-tree).

    Returns ``frames`` (M,) int64, the valid frame numbers, and ``nb`` (M, k) int64 positions in ``frames`` of
    the neighbours, nearest first, -1 padded. Queries run in chunks of ``chunk`` frames so that only the
    neighbour table stays in memory (8 k M bytes).
    """
    index = KnnIndex(features, valid=valid)
    frames = index.frames
    k = min(k, index.n_indexed - 1)
    nb = np.full((len(frames), max(k, 1)), -1, dtype=np.int64)
    if k < 1:  # a single frame: no neighbours
        return frames, nb
    data = index._features
    for s in range(0, len(frames), chunk):
        rows = frames[s : s + chunk]
        _, found = index.query(data[rows], k + 1, radius=radius, threads=threads)
        found[found == rows[:, None]] = -1  # the frame itself
        kept = (found >= 0) & (np.cumsum(found >= 0, axis=1) <= k)
        positions = np.searchsorted(frames, found)
        # left-align the kept entries of each row
        order = np.argsort(~kept, axis=1, kind="stable")[:, :k]
        left = np.take_along_axis(positions, order, 1)
        nb[s : s + len(rows)] = np.where(np.take_along_axis(kept, order, 1), left, -1)
    return frames, nb


def _reverse_lists(nb: np.ndarray):
    """CSR of the reversed neighbour relation: the frames whose lists hold j are ``rev[ptr[j]:ptr[j + 1]]``."""
    m = len(nb)
    owner = np.repeat(np.arange(m), nb.shape[1])
    target = nb.ravel()
    keep = target >= 0
    owner, target = owner[keep], target[keep]
    order = np.argsort(target, kind="stable")
    ptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(np.bincount(target, minlength=m), out=ptr[1:])
    return owner[order], ptr


@numba.njit(cache=True)
def _greedy_cover(nb, rev, ptr):  # pragma: no cover - compiled
    """Greedy base poses (§5.3 step 2, repeated): ``cluster`` (M,) int64, the base of each frame, and the bases
    in the order chosen. A lazy max-heap keyed (remaining neighbours, -frame): O(k M log M) overall."""
    m, k = nb.shape
    count = np.zeros(m, dtype=np.int64)
    for i in range(m):
        for j in range(k):
            count[i] += nb[i, j] >= 0
    heap = [(-count[i], i) for i in range(m)]
    heapq.heapify(heap)
    cluster = np.full(m, -1, dtype=np.int64)
    bases = np.empty(m, dtype=np.int64)
    n_bases = 0
    while heap:
        key, i = heapq.heappop(heap)
        if cluster[i] >= 0:
            continue
        if -key != count[i]:  # stale: its neighbours were taken since it was pushed
            heapq.heappush(heap, (-count[i], i))
            continue
        bases[n_bases] = i
        n_bases += 1
        for j in range(-1, k):
            f = i if j < 0 else nb[i, j]
            if f < 0 or cluster[f] >= 0:
                continue
            cluster[f] = i
            for p in range(ptr[f], ptr[f + 1]):
                count[rev[p]] -= 1
    return cluster, bases[:n_bases]


def _full_cluster(n: int, frames: np.ndarray, cluster: np.ndarray, bases: np.ndarray):
    """Positions among ``frames`` to frame numbers: bases (B,) and cluster (n,) with -1 for invalid frames."""
    out = np.full(n, -1, dtype=np.int64)
    out[frames] = frames[cluster]
    return frames[bases], out


def base_poses(features, radius: float, k: int = 32, valid=None, threads: int | None = None):
    """Fat-graph base poses in O(k n log n) (Krüger et al. 2010 §5.3, replacing the O(n^2) step of [SO06]).

    1. A radius search from every valid frame: its at most k nearest other frames at distance < radius
       (kd-tree, batched).
    2. Repeatedly, the frame with the most remaining (not yet assigned) neighbours becomes a base pose (ties:
       lowest frame number); it and its remaining neighbours are assigned to it. A frame none of whose
       neighbours chose it ends up chosen itself, as a base pose of a cluster of one or more frames; so every
       valid frame is in exactly one cluster, within ``radius`` of its base pose.

    Parameters
    ----------
    features : np.ndarray [shape=(N, d)], real, e.g. F15E in cm.
    radius : float
        Neighbourhood radius in feature units.
    k : int
        Most neighbours per frame. Memory: 8 k N bytes for the neighbour table.
    valid : np.ndarray [shape=(N,)], bool, optional
        Frames to cluster (default all).
    threads : int, optional
        Threads of the radius search (default :func:`mocapviz.parallel.default_threads`).

    Returns
    -------
    base : np.ndarray [shape=(B,)], int64
        Frame numbers of the base poses, in the order chosen.
    cluster : np.ndarray [shape=(N,)], int64
        The base pose of each frame; -1 for frames not valid.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §5.3 (fast fat graphs: base poses from kd-tree radius searches).

    Examples
    --------
    >>> import numpy as np
    >>> poses = np.array([[0.0], [0.5], [1.0], [5.0], [5.2], [9.0]])  # 1-d "features" for the picture
    >>> base, cluster = base_poses(poses, radius=1.1, k=4)
    >>> base.tolist(), cluster.tolist()
    ([0, 3, 5], [0, 0, 0, 3, 3, 5])
    """
    radius, k = _check_fat_graph(radius, k)
    frames, nb = _neighbour_table(features, radius, k, valid, threads)
    rev, ptr = _reverse_lists(nb)
    cluster, bases = _greedy_cover(nb, rev, ptr)
    return _full_cluster(len(np.asarray(features)), frames, cluster, bases)


def base_poses_quadratic(features, radius: float, k: int = 32, valid=None):
    """The base poses of :func:`base_poses` from the full distance matrix, O(n^2) time and memory ([SO06]'s
    cost; Krüger et al. 2010 §5.3): the reference for tests and benchmarks, for a few thousand frames.

    Neighbours of a frame: the k nearest other valid frames by (distance, frame number) at distance < radius.
    The greedy step recounts remaining neighbours from the adjacency matrix.

    Parameters
    ----------
    features : np.ndarray [shape=(N, d)], real
        As for :func:`base_poses` (a few thousand frames: the distance matrix is (N, N) float64).
    radius : float
        Neighbourhood radius in feature units.
    k : int
        Most neighbours per frame.
    valid : np.ndarray [shape=(N,)], bool, optional
        Frames to cluster (default all).

    Returns
    -------
    base : np.ndarray [shape=(B,)], int64
        Frame numbers of the base poses, in the order chosen (equal to :func:`base_poses`').
    cluster : np.ndarray [shape=(N,)], int64
        The base pose of each frame; -1 for frames not valid.
    """
    radius, k = _check_fat_graph(radius, k)
    arr = _check_features(features)
    frames = np.flatnonzero(_check_valid(valid, len(arr)))
    x = np.asarray(arr[frames], dtype=np.float64)
    m = len(frames)
    d2 = cdist(x, x, "sqeuclidean")
    np.fill_diagonal(d2, np.inf)
    nearest = np.argsort(d2, axis=1, kind="stable")[:, : min(k, m)]
    rows = np.repeat(np.arange(m), nearest.shape[1])
    near = np.take_along_axis(d2, nearest, axis=1).ravel() < radius * radius
    adjacent = np.zeros((m, m), dtype=bool)
    adjacent[rows[near], nearest.ravel()[near]] = True
    count = adjacent.sum(axis=1)
    left = np.ones(m, dtype=bool)
    cluster = np.full(m, -1, dtype=np.int64)
    bases = []
    while left.any():
        b = int(np.argmax(np.where(left, count, -1)))  # first maximum: lowest frame number
        members = left & adjacent[b]
        members[b] = True
        cluster[members] = b
        left &= ~members
        count -= adjacent[:, members].sum(axis=1)
        bases.append(b)
    return _full_cluster(len(arr), frames, cluster, np.array(bases, dtype=np.int64))
