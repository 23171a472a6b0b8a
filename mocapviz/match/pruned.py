"""DTW top-K search with admissible lower bounds: every document (or window of frames) is aligned with the query
only as far as its lower bound and the running K-th best cost allow (Rakthanmanon et al., KDD 2012, generalised
from one-dimensional series to d-dimensional feature sequences and to unconstrained DTW; cells are pruned as in
PrunedDTW, Silva & Batista 2016).

Cost model: :mod:`mocapviz.match.time_warping`'s "basic" step set (diagonal, next query frame, next database frame, each
adding the local Euclidean cost of the cell entered), so costs and matches are those of :func:`~mocapviz.match.dtw`
and :func:`~mocapviz.match.subsequence_dtw`, to the last bit.

Two tasks, a kernel each (:func:`_align_whole` and :func:`_align`, column by column over the database frames of one
range):

- *whole*: DTW of the query against a whole range (path from its first to its last frame), ranked by the
  normalised cost cost / (m + n) (query frames m, range frames n).
- *stretches*: subsequence DTW inside each range, the local minima of the end cost (ends whose match is shorter
  than ``min_length`` frames never count), K non-overlapping matches of least cost.

Pruning (admissible: the result is the brute-force result, tested). ``rows[r, i]`` is a lower bound of the
least local cost of query frame i against any frame of range r (:mod:`mocapviz.match.bounds`). Every path holds
at least one cell in each query row, so an alignment through cell (i, j) with accumulated cost A costs at least
A + sum(rows[r, i+1:]); cells above the limit are dropped and never extended, and a range whose whole bound
exceeds the limit is never opened (ranges may come in any order: the best first makes the limit fall fast).
The limit is the running K-th best: of the normalised costs (whole) or of
the best match per range (stretches: the K best per-range minima are K candidates in K different ranges, and
the greedy choice of non-overlapping matches takes at least K matches no worse than the K-th of them, so the
final K-th cost cannot exceed it). It may start lower than infinity: at a cost that K matches are known to reach
in other ranges (K whole-range costs, or K per-range minima of K different ranges, found by a cheaper search), by
the same argument; a sharded search shares it between shards (:class:`mocapviz.sharded.ShardedDB`).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _local(q, x, i, j):  # pragma: no cover - compiled
    s = 0.0
    for t in range(q.shape[1]):
        diff = np.float64(q[i, t]) - np.float64(x[j, t])
        s += diff * diff
    return np.sqrt(s)


@numba.njit(cache=True, inline="always")
def _column(qt, x, j, first, stop, out):  # pragma: no cover - compiled
    """out[first:stop] = the local costs of query rows first..stop-1 against frame x[j], from qt (d, m) = q.T as
    float64: per row the sum over features in :func:`_local`'s order (the same bits), feature by feature over
    the rows so that the compiler vectorises it (over slices: indices from 0 need no negative-index check)."""
    local = out[first:stop]
    n = local.shape[0]
    for i in range(n):
        local[i] = 0.0
    for t in range(qt.shape[0]):
        v = np.float64(x[j, t])
        row = qt[t, first:stop]
        for i in range(n):
            diff = row[i] - v
            local[i] += diff * diff
    for i in range(n):
        local[i] = np.sqrt(local[i])


@numba.njit(cache=True)
def _align(q, qt, x, a, b, rest, limit, end_cost, end_start, work, work_s):  # pragma: no cover - compiled
    """Pruned subsequence DTW of query q (m, d) against frames x[a:b] (a match starts anywhere), column by column
    (qt: q.T as float64, (d, m)); the whole task has its own kernel, :func:`_align_whole`.

    rest (m,): rest[i] = a lower bound of the cost still to come after query row i (0 for the last row).
    limit: cells whose accumulated cost + rest exceed it are dropped.
    end_cost, end_start (b - a,): written with the accumulated cost of the last query row at every frame (inf
    where dropped) and the frame where that alignment starts (-1 where none).
    work (3, m) float64, work_s (2, m) int64: scratch rows, reused from range to range (no allocation per range).
    Returns the number of cells whose local cost was computed (those with a live predecessor). The local costs
    of a column's rows next to the previous column's live ones are computed together first, feature by feature
    over the rows (a loop the compiler vectorises: several times faster than cell by cell), each the same sum in
    the same order as :func:`_local`'s: the same bits; rows reached further down are computed one by one."""
    m = q.shape[0]
    prev = work[0]
    cur = work[1]
    local = work[2]
    prev_s = work_s[0]
    cur_s = work_s[1]
    lo_p, hi_p = 0, -1  # alive rows of the previous column: [lo_p, hi_p]
    cells = 0
    for j in range(a, b):
        lo_c, hi_c = m, -1
        first = 0
        ahead = min(hi_p + 1, m - 1)  # rows first..ahead: local costs computed before the column's recursion
        if ahead > first:
            _column(qt, x, j, first, ahead + 1, local)
        else:
            ahead = first - 1
        i = first
        while i < m:
            if i > hi_p + 1 and hi_c != i - 1:
                break  # neither the previous column nor the cell above is alive: the rest of the column is dead
            best = np.inf
            arg = -1
            if i == 0:
                best, arg = 0.0, 3
            else:
                if lo_p <= i - 1 <= hi_p and prev[i - 1] < best:
                    best, arg = prev[i - 1], 0
                if i - 1 >= first and i - 1 <= hi_c and cur[i - 1] < best:
                    best, arg = cur[i - 1], 1
                if lo_p <= i <= hi_p and prev[i] < best:
                    best, arg = prev[i], 2
            if arg < 0:
                cur[i] = np.inf
                i += 1
                continue
            cells += 1
            v = best + (local[i] if i <= ahead else _local(q, x, i, j))
            if v + rest[i] > limit:
                v = np.inf
            cur[i] = v
            if v < np.inf:
                if arg == 0:
                    cur_s[i] = prev_s[i - 1]
                elif arg == 1:
                    cur_s[i] = cur_s[i - 1]
                elif arg == 2:
                    cur_s[i] = prev_s[i]
                else:
                    cur_s[i] = j
                lo_c = min(lo_c, i)
                hi_c = i
            i += 1
        if hi_c == m - 1:
            end_cost[j - a] = cur[m - 1]
            end_start[j - a] = cur_s[m - 1]
        else:
            end_cost[j - a] = np.inf
            end_start[j - a] = -1
        prev, cur = cur, prev
        prev_s, cur_s = cur_s, prev_s
        lo_p, hi_p = (lo_c, hi_c) if hi_c >= 0 else (0, -1)
    return cells


@numba.njit(cache=True)
def _align_whole(q, qt, x, a, b, rest, limit, work):  # pragma: no cover - compiled
    """Pruned DTW of query q (m, d) against the whole range x[a:b] (path from (0, a) to (m - 1, b - 1)), column by
    column: :func:`_align`'s recursion and cells for the *whole* task, without its bookkeeping of where a match
    starts (a whole range's match starts at its first frame), so that its inner loop is a few instructions a cell.

    rest (m,): rest[i] = a lower bound of the cost still to come after query row i; limit: cells whose raw cost
    + rest exceed it are dropped. work (3, m) float64: scratch rows. Returns the DTW cost (inf when every path was
    dropped) and the number of cells whose local cost was computed: the same cells and bits as :func:`_align`
    (the local costs of a column's rows next to the previous column's live ones computed together first, by
    :func:`_column`; rows reached further down one by one)."""
    m = q.shape[0]
    prev = work[0]
    cur = work[1]
    local = work[2]
    cells = 0
    # the first column: the path enters at (0, a) and goes down
    up = 0.0
    hi_p = -1
    for i in range(m):
        v = up + _local(q, x, i, a)
        cells += 1
        if v + rest[i] > limit:
            break
        cur[i] = v
        hi_p = i
        up = v
    if hi_p < 0:
        return np.inf, cells
    lo_p = 0
    prev, cur = cur, prev
    for j in range(a + 1, b):
        ahead = min(hi_p + 1, m - 1)  # rows lo_p..ahead have a live neighbour in the previous column
        _column(qt, x, j, lo_p, ahead + 1, local)
        cells += ahead + 1 - lo_p
        lo_c, hi_c = m, -1
        up = np.inf
        diag = np.inf  # prev[i - 1]
        for i in range(lo_p, ahead + 1):
            left = prev[i] if i <= hi_p else np.inf
            best = min(diag, up, left)
            diag = left
            v = best + local[i]
            if v + rest[i] > limit:
                v = np.inf
            if v < np.inf:
                lo_c = min(lo_c, i)
                hi_c = i
            cur[i] = v
            up = v
        i = ahead + 1
        while i < m and up < np.inf:  # below the previous column's live rows: only the cell above leads here
            cells += 1
            v = up + _local(q, x, i, j)
            if v + rest[i] > limit:
                break
            cur[i] = v
            hi_c = i
            up = v
            i += 1
        if hi_c < 0:
            return np.inf, cells
        prev, cur = cur, prev
        lo_p, hi_p = lo_c, hi_c
    return (prev[m - 1] if hi_p == m - 1 else np.inf), cells


@numba.njit(cache=True)
def _box_bound(x, a, b, qmin, qmax):  # pragma: no cover - compiled
    """Sum over frames x[a:b] of their Euclidean distance to the box [qmin, qmax] (d,): a lower bound of the cost
    of any path that visits every one of these frames."""
    total = 0.0
    for j in range(a, b):
        s = 0.0
        for t in range(x.shape[1]):
            v = np.float64(x[j, t])
            if v < qmin[t]:
                s += (qmin[t] - v) ** 2
            elif v > qmax[t]:
                s += (v - qmax[t]) ** 2
        total += np.sqrt(s)
    return total


@numba.njit(cache=True)
def _insert(best, value):  # pragma: no cover - compiled
    """Insert ``value`` into the increasing array ``best`` (the K least values so far), dropping the largest."""
    k = best.shape[0]
    if value >= best[k - 1]:
        return
    t = k - 1
    while t > 0 and best[t - 1] > value:
        best[t] = best[t - 1]
        t -= 1
    best[t] = value


@numba.njit(cache=True)
def _rest(row_bounds, out):  # pragma: no cover - compiled
    """out[i] = sum(row_bounds[i + 1:]) (written in place)."""
    m = row_bounds.shape[0]
    s = 0.0
    for i in range(m - 1, -1, -1):
        out[i] = s
        s += row_bounds[i]
    return out


@numba.njit(cache=True)
def _append(out_s, out_e, out_c, n_out, start, end, cost):  # pragma: no cover - compiled
    """Append one candidate (start, end, cost) to the growing arrays out_*; returns them and the new count."""
    if n_out == out_s.shape[0]:
        grow = out_s.shape[0] * 2
        s2, e2, c2 = np.empty(grow, np.int64), np.empty(grow, np.int64), np.empty(grow)
        s2[:n_out], e2[:n_out], c2[:n_out] = out_s, out_e, out_c
        out_s, out_e, out_c = s2, e2, c2
    out_s[n_out], out_e[n_out], out_c[n_out] = start, end, cost
    return out_s, out_e, out_c, n_out + 1


@numba.njit(cache=True)
def _local_minima(end_cost, end_start, a, min_length, out_s, out_e, out_c, n_out):  # pragma: no cover - compiled
    """Append the local minima of one range's end costs (ends with a match of at least min_length frames) to
    out_*; returns them, the new count and the range's least such cost."""
    n = end_cost.shape[0]
    least = np.inf
    for t in range(n):
        c = end_cost[t]
        if c == np.inf or a + t - end_start[t] + 1 < min_length:
            continue
        left = np.inf
        if t > 0 and a + t - 1 - end_start[t - 1] + 1 >= min_length:
            left = end_cost[t - 1]
        right = np.inf
        if t + 1 < n and a + t + 1 - end_start[t + 1] + 1 >= min_length:
            right = end_cost[t + 1]
        if c <= left and c <= right:
            out_s, out_e, out_c, n_out = _append(out_s, out_e, out_c, n_out, end_start[t], a + t, c)
            least = min(least, c)
    return out_s, out_e, out_c, n_out, least


@numba.njit(cache=True)
def search_ranges(q, x, lo, hi, order, bound, rows, n_matches, whole, min_length, prune, budget, limit, qmin,
                  qmax):  # pragma: no cover
    """Align the query with ranges [lo[r], hi[r]) of x in ``order`` and collect the candidate matches.

    Compiled (numba): every argument must be given, positionally, with the dtype shown.

    Parameters
    ----------
    q : np.ndarray [shape=(m, d)], float32
        The query's features (feature units, e.g. cm).
    x : np.ndarray [shape=(N, d)], float32
        The database's features.
    lo, hi : np.ndarray [shape=(R,)], int64
        The ranges [lo, hi) of x (documents or windows).
    order : np.ndarray [shape=(R,)], int64
        The order in which ranges are aligned (most promising first).
    bound : np.ndarray [shape=(R,)], float64
        A lower bound of each range's best (normalised, when ``whole``) cost.
    rows : np.ndarray [shape=(R, m)], float64
        Per-range row bounds (raw cost, :mod:`mocapviz.match.bounds`).
    n_matches : int
        K: the running limit is the K-th best.
    whole : bool
        True: DTW of the query against each whole range, one candidate per range (lo, hi - 1, cost), the K best
        kept by normalised cost cost / (m + n). False: subsequence DTW inside each range, the candidates the local
        minima of the end cost among matches of at least ``min_length`` frames, the limit the K-th best per-range
        minimum (see the module docstring).
    min_length : int
        The shortest match, frames (``whole=False``).
    prune : bool
        Use the bounds and the running limit (False: brute force, every cell of every range).
    budget : int
        Ranges to align at most (-1: all).
    limit : float
        The running limit's start (``np.inf``: none): a cost that K matches are known to reach elsewhere (another
        shard's, :class:`mocapviz.sharded.ShardedDB`), normalised as the limit; what costs more is pruned here.
    qmin, qmax : np.ndarray [shape=(d,)]
        The query's bounding box (whole: every frame of a range is on the path, each costs at least its distance
        to the box; checked before a range is aligned).

    Returns
    -------
    starts, ends : np.ndarray [shape=(C,)], int64
        The candidates' first and last frames of x (inclusive).
    costs : np.ndarray [shape=(C,)], float64
        Their raw costs.
    aligned : int
        Ranges aligned.
    cells : int
        Local costs computed.
    """
    m = q.shape[0]
    out_s = np.empty(64, np.int64)
    out_e = np.empty(64, np.int64)
    out_c = np.empty(64)
    n_out = 0
    best = np.full(n_matches, limit)
    aligned = 0
    cells = 0
    buf_c = np.empty(0)
    buf_s = np.empty(0, dtype=np.int64)
    work = np.empty((3, m))
    work_s = np.empty((2, m), dtype=np.int64)
    rest = np.zeros(m)
    qt = np.empty((q.shape[1], m))
    for i in range(m):
        for t in range(q.shape[1]):
            qt[t, i] = np.float64(q[i, t])
    for t in range(order.shape[0]):
        r = order[t]
        if prune and bound[r] > best[n_matches - 1]:
            continue
        if budget >= 0 and aligned >= budget:
            break
        n = hi[r] - lo[r]
        norm = m + n if whole else 1
        limit = best[n_matches - 1] * norm if prune else np.inf
        if whole and prune and _box_bound(x, lo[r], hi[r], qmin, qmax) > limit:
            continue
        if prune:
            _rest(rows[r], rest)
        aligned += 1
        if whole:
            least, c = _align_whole(q, qt, x, lo[r], hi[r], rest, limit, work)
            cells += c
            if least < np.inf:
                out_s, out_e, out_c, n_out = _append(out_s, out_e, out_c, n_out, lo[r], hi[r] - 1, least)
        else:
            if buf_c.shape[0] < n:
                buf_c = np.empty(n)
                buf_s = np.empty(n, dtype=np.int64)
            cells += _align(q, qt, x, lo[r], hi[r], rest, limit, buf_c, buf_s, work, work_s)
            out_s, out_e, out_c, n_out, least = _local_minima(buf_c[:n], buf_s[:n], lo[r], min_length, out_s, out_e,
                                                              out_c, n_out)  # fmt: skip
        if least < np.inf:
            _insert(best, least / norm)
    return out_s[:n_out], out_e[:n_out], out_c[:n_out], aligned, cells


@numba.njit(cache=True)
def range_costs(q, xt, lo, hi, chunk):  # pragma: no cover
    """Whole-range DTW costs of the query against every range [lo[r], hi[r]), brute force (every cell), with the
    local costs of consecutive ranges computed together: short ranges (e.g. the block means of fast mode's coarse
    pass) cost a few nanoseconds a cell instead of a column kernel's fixed cost per column.

    Compiled (numba): every argument must be given, positionally, with the dtype shown.

    Parameters
    ----------
    q : np.ndarray [shape=(m, d)], float32
        The query's features.
    xt : np.ndarray [shape=(d, N)], float64
        The database's features, feature-major (``x.T`` as float64: the local costs are then a loop over frames
        that the compiler vectorises, each the sum of :func:`_local`, in its order: the same bits).
    lo, hi : np.ndarray [shape=(R,)], int64
        The ranges [lo, hi) of the frames, sorted by lo, disjoint, non-empty.
    chunk : int
        Frames whose local costs are held at once (m x chunk float64; a longer range is one chunk of its own).

    Returns
    -------
    np.ndarray [shape=(R,)], float64
        The DTW cost (path from the range's first to its last frame, :func:`~mocapviz.match.dtw`'s cost model) of
        each range: :func:`search_ranges`' whole costs without pruning, to the last bit.
    """
    m, d = q.shape
    n_r = lo.shape[0]
    out = np.empty(n_r)
    col = np.empty(m)
    r0 = 0
    while r0 < n_r:
        r1 = r0 + 1  # ranges r0..r1-1 make one chunk of frames [lo[r0], hi[r1 - 1])
        while r1 < n_r and hi[r1] - lo[r0] <= chunk:
            r1 += 1
        a, b = lo[r0], hi[r1 - 1]
        local = np.zeros((m, b - a))
        for i in range(m):
            row = local[i]
            for t in range(d):
                v = np.float64(q[i, t])
                xs = xt[t, a:b]
                for j in range(b - a):
                    diff = v - xs[j]
                    row[j] += diff * diff
            for j in range(b - a):
                row[j] = np.sqrt(row[j])
        for r in range(r0, r1):
            s = lo[r] - a
            col[0] = local[0, s]
            for i in range(1, m):
                col[i] = col[i - 1] + local[i, s]
            for j in range(s + 1, hi[r] - a):
                diag = col[0]
                col[0] = diag + local[0, j]
                for i in range(1, m):
                    left = col[i]
                    best = min(diag, col[i - 1], left)
                    col[i] = best + local[i, j]
                    diag = left
            out[r] = col[m - 1]
        r0 = r1
    return out
