"""Dynamic time warping: full, band-restricted and subsequence DTW (Müller 2007 ch. 4; Krüger et al. 2010 §4).

dtw                 the optimal alignment of two feature sequences, optionally only inside a band of the cost
                    matrix (Müller, Röder & Clausen 2005 §7: refine a segment-wise alignment).
subsequence_costs   the accumulated cost of the best alignment of a query ending at every database frame, with
                    the frame where that alignment starts; documents are never crossed. O(m n) time, O(m) memory
                    per document boundary: the database is streamed in blocks.
subsequence_dtw     the top ``n_matches`` non-overlapping matches of a query in a database, ranked by cost, with their paths.
best_ends           the end frames of those matches, from subsequence_costs' output.
select_matches      ``n_matches`` non-overlapping intervals of least cost from candidate (start, end, cost) triples (shared
                    with the lazy neighbourhood graph, so both rank matches the same way).

Cost model (the same as the lazy neighbourhood graph's, so the two are comparable):

- The local cost c(i, j) of query frame i and database frame j is the Euclidean distance of their feature
  vectors (any feature set, in its units), or what a ``distance(a, b) -> (len(a), len(b))`` callable returns,
  e.g. one of the ``*_pairwise`` functions of :mod:`mocapviz.features.distances`.
- A step (di, dj, w) goes from cell (i - di, j - dj) to (i, j) and adds w * c(i, j). ``"basic"`` (the default)
  is {(1, 1, 1), (1, 0, 1), (0, 1, 1)}: diagonal, next query frame, next database frame, all with weight 1.
  ``"symmetric"`` weighs the diagonal 2 (Sakoe & Chiba); ``"slope"`` is {(1, 1, 1), (2, 1, 1), (1, 2, 1)},
  which bounds the slope of a path between 1/2 and 2 (Müller 2007 §4.2).
- The first cell of a path adds c(i0, j0) with weight 1. DTW starts at (0, 0) and ends at (m-1, n-1);
  subsequence DTW starts at (0, j0) for any j0 and ends at (m-1, j1) for any j1 >= j0.
- Paths are arrays (L, 2) of (query frame, database frame) pairs. Of several optimal predecessors the first
  step of the step set wins (the diagonal for the built-in sets).
"""

from __future__ import annotations

import numba
import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..validation import MIN_LENGTH, MIN_LENGTH_RANGE, count, renamed

STEP_SETS = {
    "basic": ((1, 1, 1.0), (1, 0, 1.0), (0, 1, 1.0)),
    "symmetric": ((1, 1, 2.0), (1, 0, 1.0), (0, 1, 1.0)),
    "slope": ((1, 1, 1.0), (2, 1, 1.0), (1, 2, 1.0)),
}
_BLOCK_ELEMENTS = 1 << 21  # cost-matrix cells of one block of database frames (16 MB of float64)
MATCH_COLUMNS = ["doc_id", "start", "end", "cost", "path"]


# ============================================================================ input checks
def _sequence(x, name: str, dim: int | None = None, other: str = "the query") -> np.ndarray:
    """A (T, d) float array of finite values (a 1-D array is one feature per frame), or a ValueError."""
    arr = np.asarray(x)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ParameterError(f"{name} must be a real (frames, dimensions) array; got {arr.dtype} {arr.shape}")
    if dim is not None and arr.shape[1] != dim:
        raise ParameterError(f"{name} has {arr.shape[1]} dimensions per frame but {other} has {dim}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ParameterError(f"{name}: frame {int(np.argmax(bad))} is not finite (NaN or inf)")
    return arr if arr.dtype in (np.float32, np.float64) else arr.astype(np.float64)


def _pair(a, b, names: tuple[str, str], distance) -> tuple:
    """Two sequences checked as (T, d) feature arrays of equal d (unless a ``distance`` callable takes them as
    they are), both with at least one frame, or a ValueError naming them."""
    if distance is None:
        a = _sequence(a, names[0])
        b = _sequence(b, names[1], a.shape[1])
    if len(a) < 1 or len(b) < 1:
        raise ParameterError(f"{names[0]} and {names[1]} need at least one frame each; got {len(a)} and {len(b)}")
    return a, b


def _steps(steps) -> np.ndarray:
    """A step set name or ((di, dj, w), ...) as a float64 (S, 3) array, or a ValueError."""
    table = STEP_SETS.get(steps, steps) if isinstance(steps, str) else steps
    if isinstance(table, str):
        raise ParameterError(f"unknown step set {steps!r}; choose one of {', '.join(STEP_SETS)} or give (di, dj, w) rows")
    arr = np.asarray(table, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ParameterError(f"steps must be rows (di, dj, weight); got shape {arr.shape}")
    di, dj, w = arr.T
    if (di < 0).any() or (dj < 0).any() or ((di == 0) & (dj == 0)).any() or (di != np.round(di)).any() or (
            dj != np.round(dj)).any() or not (w > 0).all():  # fmt: skip
        raise ParameterError("each step needs non-negative integer (di, dj), not both 0, and a weight > 0")
    return arr


def _check_document_starts(starts, n: int) -> np.ndarray:
    """Document start frames as increasing int64 (B,) beginning with 0, or a ValueError."""
    if starts is None:
        return np.zeros(1, dtype=np.int64)
    arr = np.asarray(starts)
    if arr.ndim != 1 or len(arr) == 0 or not np.issubdtype(arr.dtype, np.integer):
        raise ParameterError(f"document starts must be a 1-D int array of first frames; got {arr.dtype} {arr.shape}")
    if arr[0] != 0 or (np.diff(arr) <= 0).any() or arr[-1] >= n:
        raise ParameterError(f"document starts must increase strictly from 0 and stay below the {n:,} frames")
    return arr.astype(np.int64)


def check_query_length(m: int, doc_starts: np.ndarray, n: int) -> None:
    """A ValueError unless 2 <= m <= the longest document's frame count (no match could exist).

    Parameters
    ----------
    m : int
        The query's frames.
    doc_starts : np.ndarray [shape=(B,)], int
        First frame of every document.
    n : int
        Frames of the database.
    """
    longest = int(np.diff(np.r_[doc_starts, n]).max())
    if m < 2:
        raise ParameterError(f"a query needs at least 2 frames; got {m}")
    if m > longest:
        raise ParameterError(f"the query has {m} frames, more than the longest document ({longest} frames); a match "
                         f"cannot be shorter than the query")  # fmt: skip


def shortest_match(min_length: float | None, m: int) -> int:
    """The fewest database frames a match of an ``m``-frame query may span: ``min_length`` × m rounded up (at least
    1), the rule of every search that takes ``min_length`` (:func:`subsequence_dtw`, the lazy neighbourhood graph,
    :meth:`mocapviz.similarity.search.SimilaritySearch.stretches`); None: any length.

    Parameters
    ----------
    min_length : float or None
        A share of the query's frames in (0, 1] (:data:`mocapviz.validation.MIN_LENGTH_RANGE`), or None.
    m : int
        The query's frames.

    Returns
    -------
    int

    Examples
    --------
    >>> shortest_match(0.5, 129), shortest_match(None, 129)
    (65, 1)
    """
    if min_length is None:
        return 1
    return max(1, int(np.ceil(MIN_LENGTH_RANGE.check(min_length, "min_length (a share of the query's frames)") * m)))


# ============================================================================ local costs
@numba.njit(cache=True, parallel=True)
def _euclidean_block(q, x, lo, hi):  # pragma: no cover - compiled
    """c[j, i] = |q[i] - x[j]| for lo[j] <= i < hi[j] (other cells left unset). q (m, d), x (b, d) -> (b, m)."""
    b, m, d = x.shape[0], q.shape[0], q.shape[1]
    out = np.empty((b, m))
    for j in numba.prange(b):
        for i in range(lo[j], hi[j]):
            s = 0.0
            for t in range(d):
                diff = np.float64(q[i, t]) - np.float64(x[j, t])
                s += diff * diff
            out[j, i] = np.sqrt(s)
    return out


def _cost_block(query: np.ndarray, frames: np.ndarray, distance, lo=None, hi=None) -> np.ndarray:
    """Local costs (len(frames), m) float64 of every database frame (row) against every query frame (column);
    with ``lo``/``hi``, the Euclidean costs are computed only for query frames lo[j] <= i < hi[j] (the others
    are left unset: readers must stay inside the band)."""
    m = len(query)
    if distance is None:
        if lo is None:
            lo, hi = np.zeros(len(frames), np.int64), np.full(len(frames), m, np.int64)
        return _euclidean_block(query, frames, lo, hi)
    c = np.asarray(distance(query, frames), dtype=np.float64)
    if c.shape != (m, len(frames)):
        raise ParameterError(f"distance(query, frames) must return shape ({m}, {len(frames)}); got {c.shape}")
    if np.isnan(c).any() or (c < 0).any():
        raise ParameterError("distance(query, frames) returned a negative or NaN cost")
    return np.ascontiguousarray(c.T)


# ============================================================================ DTW over a (banded) cost matrix
@numba.njit(cache=True)
def _accumulate(cost, lo, hi, steps):  # pragma: no cover - compiled
    """Accumulated costs D (n, m) and the step taken into each cell (-1: the path starts there; -2: unreachable)
    of a cost matrix given database frame first, cost[j, i], visiting only the cells lo[j] <= i < hi[j] of each
    column (the band); cells outside it are never read. The path starts at (0, 0)."""
    n, m = cost.shape
    acc = np.empty((n, m))
    step = np.empty((n, m), dtype=np.int8)
    for j in range(n):
        for i in range(lo[j], hi[j]):
            c = cost[j, i]
            if i == 0 and j == 0:
                acc[j, i] = c
                step[j, i] = -1
                continue
            best, arg = np.inf, -2
            for s in range(steps.shape[0]):
                pi, pj = i - int(steps[s, 0]), j - int(steps[s, 1])
                if pi < 0 or pj < 0 or pi < lo[pj] or pi >= hi[pj]:
                    continue
                v = acc[pj, pi] + steps[s, 2] * c
                if v < best:
                    best, arg = v, s
            acc[j, i] = best
            step[j, i] = arg
    return acc, step


@numba.njit(cache=True)
def _backtrack(step, steps, i, j):  # pragma: no cover - compiled
    """The path ending in cell (i, j) as (L, 2) rows of (query frame, frame), first cell first."""
    out = np.empty((step.shape[0] + step.shape[1], 2), dtype=np.int64)
    n_out = 0
    while True:
        out[n_out, 0], out[n_out, 1] = i, j
        n_out += 1
        s = step[j, i]
        if s < 0:
            break
        i, j = i - int(steps[s, 0]), j - int(steps[s, 1])
    return out[:n_out][::-1].copy()


def _check_band(band, m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A band (m, 2) of [lo, hi) frames of b per frame of a, both bounds non-decreasing (as every band around a
    monotone path is) -> per frame j of b the [lo, hi) range of frames of a it may align to."""
    arr = np.asarray(band)
    if arr.shape != (m, 2) or not np.issubdtype(arr.dtype, np.integer):
        raise ParameterError(f"band must be int ({m}, 2): one [lo, hi) range of frames of b per frame of a; got "
                         f"{arr.dtype} {arr.shape}")  # fmt: skip
    lo_row, hi_row = np.clip(arr[:, 0], 0, n), np.clip(arr[:, 1], 0, n)
    if (lo_row >= hi_row).any():
        raise ParameterError(f"band row {int(np.argmax(lo_row >= hi_row))} is empty after clipping to [0, {n})")
    if (np.diff(lo_row) < 0).any() or (np.diff(hi_row) < 0).any():
        raise ParameterError("band bounds must not decrease from one frame of a to the next (a warping path is monotone)")
    cols = np.arange(n)
    # rows i with lo_row[i] <= j < hi_row[i]: from the first i whose hi_row exceeds j to the last whose lo_row <= j
    return np.searchsorted(hi_row, cols, side="right").astype(np.int64), np.searchsorted(
        lo_row, cols, side="right").astype(np.int64)  # fmt: skip


def dtw(a, b, distance=None, steps="basic", band=None) -> tuple[float, np.ndarray]:
    """Optimal DTW alignment of two feature sequences, optionally restricted to a band of the cost matrix.

    Müller 2007 §4.1 (classical DTW); with ``band``, Müller, Röder & Clausen 2005 §7: the cost matrix is computed
    only inside the band (e.g. the enlarged area of matched segments), the rest is never visited.

    Parameters
    ----------
    a : np.ndarray [shape=(m, d)], real, feature units (e.g. F15E in cm).
    b : np.ndarray [shape=(n, d)].
    distance : callable, optional
        ``distance(a, b) -> (m, n)`` local costs, e.g. :func:`mocapviz.features.distances.dquat_pairwise` with
        a, b of quaternions; default the Euclidean distance of feature vectors (then ``a``/``b`` are (T, d)).
    steps : str or array (S, 3)
        "basic" (default), "symmetric", "slope" or rows (di, dj, weight); see the module docstring.
    band : np.ndarray [shape=(m, 2)], int, optional
        Per frame of ``a`` the [lo, hi) frames of ``b`` it may align to, both bounds non-decreasing
        (:func:`band_from_path` makes one). Only these cells are computed: time O(band cells); memory O(m n).

    Returns
    -------
    cost : float
        The accumulated cost of the optimal path from (0, 0) to (m-1, n-1) (inf if the band allows none).
    path : np.ndarray [shape=(L, 2)], int64
        (frame of a, frame of b) pairs, empty (0, 2) when there is no path.

    Raises
    ------
    ValueError
        Empty or non-finite sequences (the frame is named), different dimensions, a bad step set or band.

    References
    ----------
    .. [1] M. Müller. Information Retrieval for Music and Motion. Springer 2007, §4.1 (DTW).
    .. [2] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §7 (a segment-wise alignment refined by DTW restricted to a band, Fig. 11).

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[0.0], [1.0], [2.0], [3.0]])
    >>> b = np.array([[0.0], [0.0], [1.0], [2.0], [2.0], [3.0]])  # the same course, slower
    >>> cost, path = dtw(a, b)
    >>> cost, path.tolist()
    (0.0, [[0, 0], [0, 1], [1, 2], [2, 3], [2, 4], [3, 5]])
    >>> dtw(a, b, band=band_from_path(path, (4, 6), margin=1))[0]  # only the cells near the path
    0.0

    Two kicks of the sample, F15E in cm:

    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_features
    >>> db = MotionDB.sample()
    >>> cost, path = dtw(numeric_features(db.motion(7), "F15E"), numeric_features(db.motion(18), "F15E"))
    >>> round(cost, 1), path.shape, path[-1].tolist()  # 129 and 130 frames
    (6280.4, (148, 2), [128, 129])
    """
    steps_arr = _steps(steps)
    a, b = _pair(a, b, ("a", "b"), distance)
    m, n = len(a), len(b)
    if band is None:
        lo, hi = np.zeros(n, dtype=np.int64), np.full(n, m, dtype=np.int64)
    else:
        lo, hi = _check_band(band, m, n)
    if not (lo[0] == 0 < hi[0] and lo[-1] < m <= hi[-1]):
        return np.inf, np.empty((0, 2), dtype=np.int64)  # the band leaves out the first or the last cell
    acc, step = _accumulate(_cost_block(a, b, distance, lo, hi), lo, hi, steps_arr)
    total = float(acc[n - 1, m - 1])
    if not np.isfinite(total):
        return total, np.empty((0, 2), dtype=np.int64)
    return total, _backtrack(step, steps_arr, m - 1, n - 1)


def band_from_path(path, shape: tuple[int, int], margin: int = 0) -> np.ndarray:
    """The [lo, hi) band (m, 2) covering a path (or the cells of matched segments) enlarged by ``margin`` frames
    in both directions (Müller et al. 2005 §7, Fig. 11's grey area).

    Parameters
    ----------
    path : np.ndarray [shape=(L, 2)], int
        (row, column) cells; every row 0..m-1 must occur.
    shape : (int, int)
        (m, n), the cost matrix's shape.
    margin : int
        Frames added on every side.

    Returns
    -------
    np.ndarray [shape=(m, 2)], int64
        Per row the [lo, hi) columns of the band, clipped to 0..n (``band=`` of :func:`dtw`).

    Examples
    --------
    >>> band_from_path([[0, 0], [1, 1], [2, 1], [3, 2]], (4, 3)).tolist()
    [[0, 1], [1, 2], [1, 2], [2, 3]]
    """
    m, n = shape
    cells = np.asarray(path, dtype=np.int64)
    lo = np.full(m, n, dtype=np.int64)
    hi = np.zeros(m, dtype=np.int64)
    np.minimum.at(lo, cells[:, 0], cells[:, 1])
    np.maximum.at(hi, cells[:, 0], cells[:, 1] + 1)
    if (hi == 0).any():
        raise ParameterError(f"the path misses row {int(np.argmax(hi == 0))}")
    if margin:
        # rows within ``margin`` of each other share their ranges: a square dilation of the covered cells
        win = 2 * margin + 1
        lo_pad = np.pad(lo, margin, constant_values=n)
        hi_pad = np.pad(hi, margin, constant_values=0)
        view = np.lib.stride_tricks.sliding_window_view
        lo = view(lo_pad, win).min(axis=1) - margin
        hi = view(hi_pad, win).max(axis=1) + margin
    return np.stack([np.clip(lo, 0, n), np.clip(hi, 0, n)], axis=1)


# ============================================================================ subsequence DTW
@numba.njit(cache=True)
def _subsequence_block(cost, offset, doc, steps, hist_acc, hist_start, hist_doc, last, last_start):  # pragma: no cover
    """Advance subsequence DTW over one block of database frames.

    cost (b, m): local costs of the block's frames, the first being database frame ``offset``; doc (b,): their
    document numbers. hist_* (h, m) / (h,): the accumulated costs, start frames and documents of the h frames
    before the block (h = largest dj; document -1 when there is none), updated in place. Writes the last query
    row of every block frame to last / last_start (b,)."""
    b, m = cost.shape
    h = hist_acc.shape[0]
    acc = np.full((h + b, m), np.inf)
    start = np.full((h + b, m), -1, dtype=np.int64)
    docs = np.empty(h + b, dtype=np.int64)
    acc[:h] = hist_acc
    start[:h] = hist_start
    docs[:h] = hist_doc
    docs[h:] = doc
    for jb in range(b):
        j = h + jb
        for i in range(m):
            c = cost[jb, i]
            if i == 0:
                acc[j, 0] = c
                start[j, 0] = offset + jb
                continue
            best, arg = np.inf, -1
            for s in range(steps.shape[0]):
                pi, pj = i - int(steps[s, 0]), j - int(steps[s, 1])
                if pi < 0 or pj < 0 or docs[pj] != docs[j]:
                    continue
                v = acc[pj, pi] + steps[s, 2] * c
                if v < best:
                    best, arg = v, s
            acc[j, i] = best
            if arg >= 0:
                start[j, i] = start[j - int(steps[arg, 1]), i - int(steps[arg, 0])]
        last[jb] = acc[j, m - 1]
        last_start[jb] = start[j, m - 1]
    hist_acc[:] = acc[b:]
    hist_start[:] = start[b:]
    hist_doc[:] = docs[b:]


def subsequence_costs(query, database, starts=None, distance=None, steps="basic", progress=False):
    """For every database frame j, the least accumulated cost of aligning the whole query to a stretch of one
    document ending at j, and the frame where that stretch starts (subsequence DTW, Müller 2007 §4.4;
    the baseline of Krüger et al. 2010 §4).

    Parameters
    ----------
    query : np.ndarray [shape=(m, d)], real
        The query frames' features, in feature units (or what ``distance`` takes).
    database : np.ndarray [shape=(n, d)]
        The features of all database frames.
    starts : np.ndarray [shape=(B,)], int, optional
        First frame of every document (``db.documents.start``); alignments never cross a document boundary.
        Default: one document.
    distance : callable, optional
        ``distance(query, frames) -> (m, len(frames))``; default Euclidean.
    steps : str or np.ndarray [shape=(S, 3)]
        The step set, as for :func:`dtw`.
    progress : bool
        A tqdm bar over blocks of database frames.

    Returns
    -------
    cost : np.ndarray [shape=(n,)], float64
        Accumulated cost per end frame; inf where no alignment ends (e.g. too close to a document start for the
        "slope" steps).
    start : np.ndarray [shape=(n,)], int64
        First frame of that alignment; -1 where cost is inf.

    Examples
    --------
    >>> import numpy as np
    >>> database = np.array([[5.0], [0.0], [1.0], [2.0], [9.0], [9.0], [0.5], [1.5], [2.5], [9.0]])
    >>> cost, start = subsequence_costs(np.array([[0.0], [1.0], [2.0]]), database, starts=[0, 5])
    >>> cost.tolist()[:5], start.tolist()[:5]
    ([12.0, 3.0, 1.0, 0.0, 7.0], [0, 1, 1, 1, 1])
    """
    steps_arr = _steps(steps)
    query, database = _pair(query, database, ("query", "database"), distance)
    m, n = len(query), len(database)
    doc_starts = _check_document_starts(starts, n)
    h = int(steps_arr[:, 1].max()) or 1
    hist_acc, hist_start = np.full((h, m), np.inf), np.full((h, m), -1, dtype=np.int64)
    hist_doc = np.full(h, -1, dtype=np.int64)
    cost_out, start_out = np.empty(n), np.empty(n, dtype=np.int64)
    block = max(1, _BLOCK_ELEMENTS // m)
    blocks = range(0, n, block)
    if progress:
        from tqdm.auto import tqdm

        blocks = tqdm(blocks, desc="subsequence DTW", unit="block")
    doc_of = np.searchsorted(doc_starts, np.arange(0, n), side="right") - 1
    for a in blocks:
        z = min(n, a + block)
        c = _cost_block(query, database[a:z], distance)
        _subsequence_block(c, a, doc_of[a:z], steps_arr, hist_acc, hist_start, hist_doc, cost_out[a:z],
                           start_out[a:z])  # fmt: skip
    start_out[~np.isfinite(cost_out)] = -1
    return cost_out, start_out


@numba.njit(cache=True)
def _select(order, starts, ends, n_matches):  # pragma: no cover - compiled
    """Indices (into the candidates) of up to n_matches intervals [start, end], taken in ``order``, none
    overlapping one taken before (checked against the taken ones: O(n_matches) per candidate, no array over all
    frames)."""
    out = np.empty(n_matches, dtype=np.int64)
    n_out = 0
    for c in order:
        s, e = starts[c], ends[c]
        free = True
        for t in range(n_out):
            if s <= ends[out[t]] and starts[out[t]] <= e:
                free = False
                break
        if free:
            out[n_out] = c
            n_out += 1
            if n_out == n_matches:
                break
    return out[:n_out]


def select_matches(starts, ends, costs, n_matches: int) -> np.ndarray:
    """The indices of the ``n_matches`` candidate matches [start, end] of least cost that do not overlap each other,
    in increasing cost (ties: earlier end first). The greedy choice of Müller 2007 §4.4: take the best match,
    discard every candidate overlapping it, repeat.

    Parameters
    ----------
    starts, ends : np.ndarray [shape=(c,)], int
        The candidates' first and last database frames (inclusive).
    costs : np.ndarray [shape=(c,)], float
        Their costs; inf candidates are never taken.
    n_matches : int
        Matches wanted.

    Returns
    -------
    np.ndarray [shape=(<= n_matches,)], int64
        Indices into the candidates, best first.

    Examples
    --------
    >>> select_matches([0, 1, 5], [3, 4, 8], [1.0, 0.5, 2.0], n_matches=2).tolist()  # 0:3 overlaps 1:4
    [1, 2]
    """
    starts, ends = np.asarray(starts, dtype=np.int64), np.asarray(ends, dtype=np.int64)
    costs = np.asarray(costs, dtype=np.float64)
    finite = np.flatnonzero(np.isfinite(costs))
    if not len(finite):
        return np.empty(0, dtype=np.int64)
    order = finite[np.lexsort((ends[finite], costs[finite]))]
    return _select(order, starts, ends, count(n_matches, "n_matches"))


def best_ends(cost, first, starts, n_matches: int) -> np.ndarray:
    """The end frames of the ``n_matches`` best non-overlapping subsequence-DTW matches (Müller 2007 §4.4): the local
    minima of the accumulated cost within each document, taken greedily by :func:`select_matches`.

    Parameters
    ----------
    cost, first : np.ndarray [shape=(n,)]
        From :func:`subsequence_costs` (set ``cost`` to inf where no match may end, e.g. inside the query's own
        document).
    starts : np.ndarray [shape=(B,)], int
        First frame of every document (None: one document).
    n_matches : int
        Matches wanted.

    Returns
    -------
    np.ndarray [shape=(<= n_matches,)], int64
        End frames, best first; the matches start at ``first[ends]``.
    """
    cost = np.asarray(cost, dtype=np.float64)
    n = len(cost)
    doc_start = np.zeros(n + 1, dtype=bool)  # frame j opens a document; the end of the database closes the last
    doc_start[_check_document_starts(starts, n)] = True
    doc_start[n] = True
    left, right = np.r_[np.inf, cost[:-1]], np.r_[cost[1:], np.inf]
    cand = np.flatnonzero(np.isfinite(cost) & (doc_start[:n] | (cost <= left)) & (doc_start[1:] | (cost <= right)))
    return cand[select_matches(np.asarray(first)[cand], cand, cost[cand], n_matches)]


def matches_frame(doc_starts: np.ndarray, starts, ends, costs, paths) -> pd.DataFrame:
    """The matches table shared by subsequence DTW and the lazy neighbourhood graph.

    Parameters
    ----------
    doc_starts : np.ndarray [shape=(B,)], int
        First frame of every document.
    starts, ends : array_like of int [shape=(n,)]
        The matches' first and last database frames (inclusive).
    costs : array_like of float [shape=(n,)]
        Their costs, in feature units.
    paths : sequence of np.ndarray [shape=(L, 2)] or None
        Their warping paths.

    Returns
    -------
    pandas.DataFrame
        doc_id (document number, the position in ``doc_starts``), start, end (database frames, inclusive), cost,
        path ((L, 2) array of (query frame, database frame)).
    """
    starts, ends = np.asarray(starts, dtype=np.int64), np.asarray(ends, dtype=np.int64)
    return pd.DataFrame({
        "doc_id": np.searchsorted(doc_starts, ends, side="right") - 1, "start": starts, "end": ends,
        "cost": np.asarray(costs, dtype=np.float64), "path": pd.Series(list(paths), dtype=object),
    })  # fmt: skip


@renamed(k="n_matches")
def subsequence_dtw(query, database, starts=None, n_matches: int = 10, distance=None, steps="basic",
                    paths: bool = True, progress: bool = False, min_length: float | None = MIN_LENGTH,
                    checked: bool = False) -> pd.DataFrame:  # fmt: skip
    """The ``n_matches`` best non-overlapping matches of a query in a database by subsequence DTW (Müller 2007
    §4.4): the local minima of the accumulated cost over the last query frame, best first, each discarding the
    candidates that overlap it. The reference that the lazy neighbourhood graph (Krüger et al. 2010 §4.1)
    approximates.

    Parameters
    ----------
    query : np.ndarray [shape=(m, d)]
        Features of the query frames, 2 <= m <= the longest document, feature units (F15E: cm).
    database : np.ndarray [shape=(n, d)]
        Features of all database frames, e.g. ``numeric_of(db, "F15E")``.
    starts : np.ndarray [shape=(B,)], int, optional
        First frame of every document (``db.documents.start``); default one document.
    n_matches : int
        Matches wanted (fewer when the database has fewer non-overlapping ones); its old name ``k`` still works,
        with a FutureWarning.
    distance : callable, optional
        Local costs, as for :func:`subsequence_costs` (default Euclidean).
    steps : str or np.ndarray [shape=(S, 3)]
        The step set, as for :func:`dtw`.
    paths : bool
        Compute each match's path (by DTW of the query against the matched stretch; same cost).
    progress : bool
        A progress bar over blocks of database frames.
    min_length : float, optional
        The shortest match, a share in (0, 1] of the query's frames (:func:`shortest_match`; default
        :data:`mocapviz.validation.MIN_LENGTH`, half as long as the query); None: any length (Müller's subsequence DTW, whose best
        match may map every query frame to one database frame). An end frame whose best alignment is shorter is
        no candidate.
    checked : bool
        The query's length was checked against a whole database already (:func:`check_query_length`): ``database``
        is a part of it (a shard of :class:`mocapviz.engine.ShardedDB`) whose documents may all be shorter than the
        query and still hold matches of ``min_length``.

    Returns
    -------
    pandas.DataFrame
        One row per match, best first: doc_id (index into ``starts``), start, end (database frames, inclusive),
        cost (accumulated local costs, feature units), path ((L, 2) int64 (query frame, database frame), or None
        when ``paths`` is False). :func:`mocapviz.similarity.motion_matching.match_motion` gives the same matches
        of a MotionDB as the hit table.

    Raises
    ------
    ValueError / TypeError
        A query shorter than 2 frames or longer than the longest document, non-finite frames (named), feature
        dimensions that differ, bad document starts or step set, n_matches not a positive integer.

    References
    ----------
    .. [1] M. Müller. Information Retrieval for Music and Motion. Springer 2007, §4.4 (subsequence DTW).
    .. [2] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §4 (the reference the lazy neighbourhood graph is compared with, §4.2).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_of
    >>> db = MotionDB.sample()
    >>> x, starts = numeric_of(db, "F15E"), db.documents["start"].to_numpy()
    >>> own = db.frames(7)
    >>> matches = subsequence_dtw(x[own.start : own.start + 60], x, starts, n_matches=3)  # 0.5 s of a kick
    >>> matches["doc_id"].tolist(), matches["cost"].round(1).tolist()  # itself first, then the other kick
    ([7, 18, 14], [0.0, 2489.7, 4091.2])
    >>> bool((matches["end"] - matches["start"] + 1).min() >= 30)  # none shorter than half the query
    True
    """
    n_matches = count(n_matches, "n_matches")
    n = len(database)
    doc_starts = _check_document_starts(starts, n)
    if not checked:
        check_query_length(len(query), doc_starts, n)
    shortest = shortest_match(min_length, len(query))
    cost, first = subsequence_costs(query, database, starts, distance, steps, progress)
    cost[np.arange(n) - first + 1 < shortest] = np.inf
    chosen = best_ends(cost, first, doc_starts, n_matches)
    found = []
    for s, e in zip(first[chosen], chosen):
        if paths:
            _, p = dtw(query, database[s : e + 1], distance=distance, steps=steps)
            found.append(p + np.array([0, s]))
        else:
            found.append(None)
    return matches_frame(doc_starts, first[chosen], chosen, cost[chosen], found)
