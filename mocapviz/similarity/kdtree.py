"""mocapviz's own kd-tree (numba): the "kdtree" engine of :class:`mocapviz.similarity.knn.KnnIndex`.

build_kdtree    the tree over (M, d) points: sliding-midpoint splits of the widest side of each node's *tight*
                bounding box, leaves of up to ``leafsize`` points stored contiguously in leaf order (float32 when
                the points are float32 values, as F15E is: the same numbers in half the memory).
query_kdtree    exact (or eps-approximate) k nearest, within an optional radius, of a batch of queries over threads.

What makes it faster than scipy's cKDTree on F15E (measured in benchmarks/bench_knn.py §4(b)): each node keeps the
tight box of its points, so the distance from a query to a node is the distance to that box (never larger than
to the cell cut by the splits, so more nodes are skipped); a node's box distance is computed once, when its parent
is opened, and kept on the stack beside it; leaves of 64 points are scanned contiguously, a point being dropped
after half of its coordinates once they already exceed the k-th distance; queries run in the order of the leaves
they fall in, so consecutive queries touch the same memory. Searching a block of neighbouring queries together
(one traversal, each query with its own bound) was measured slower, on random database frames and on the
consecutive frames of clips alike, and is not done.

Exactness: each query keeps a max-heap of its k best (squared distance, point); a node or a point is skipped only
when its box or its distance is not below that query's current k-th squared distance (times 1 / (1 + eps)^2 for
nodes when eps > 0). Squared distances are sums of squared coordinate differences in float64, in coordinate order,
as scipy's ``cdist(..., "sqeuclidean")`` computes them.
"""

from __future__ import annotations

import numba
import numpy as np

from ..parallel import map_ordered

LEAFSIZE = 64  # points per leaf (measured best of 8 ... 256 on F15E, 1M frames, k = 16 and 256)
_PER_TASK = 64  # queries per task of a thread


# ============================================================================ build
@numba.njit(cache=True, nogil=True)
def _grow(a, n):  # pragma: no cover - compiled
    out = np.empty((n,) + a.shape[1:], dtype=a.dtype)
    out[: len(a)] = a
    return out


@numba.njit(cache=True, nogil=True)
def _swap(points, perm, i, j):  # pragma: no cover - compiled
    for c in range(points.shape[1]):
        points[i, c], points[j, c] = points[j, c], points[i, c]
    perm[i], perm[j] = perm[j], perm[i]


@numba.njit(cache=True, nogil=True)
def _build(points, leafsize):  # pragma: no cover - compiled
    """Nodes of the tree over points (M, d), whose rows it puts in leaf order (in place): perm (M,) (the original
    row of each), start, stop, left, right (-1 for a leaf), lo, hi (n_nodes, d) tight boxes, and the depth."""
    m, d = points.shape
    perm = np.arange(m)
    cap = max(16, 4 * (m // max(leafsize, 1)) + 16)
    start = np.empty(cap, np.int64)
    stop = np.empty(cap, np.int64)
    left = np.full(cap, -1, np.int64)
    right = np.full(cap, -1, np.int64)
    lo = np.empty((cap, d))
    hi = np.empty((cap, d))
    stack = np.empty(256, np.int64)
    level = np.empty(256, np.int64)
    start[0], stop[0] = 0, m
    n_nodes, top, depth = 1, 1, 0
    stack[0], level[0] = 0, 0
    while top > 0:
        top -= 1
        node, lev = stack[top], level[top]
        depth = max(depth, lev)
        a, b = start[node], stop[node]
        for j in range(d):
            lo[node, j] = points[a, j]
            hi[node, j] = points[a, j]
        for p in range(a + 1, b):
            for j in range(d):
                v = points[p, j]
                if v < lo[node, j]:
                    lo[node, j] = v
                elif v > hi[node, j]:
                    hi[node, j] = v
        dim, width = 0, -1.0
        for j in range(d):
            if hi[node, j] - lo[node, j] > width:
                dim, width = j, hi[node, j] - lo[node, j]
        if b - a <= leafsize or width <= 0.0 or lev >= 250:  # small, all points equal, or too deep: a leaf
            continue
        split = min(lo[node, dim] + 0.5 * width, hi[node, dim])  # min: rounding between two neighbouring floats
        i, j = a, b - 1  # partition: coordinate < split to the left
        while i <= j:
            if points[i, dim] < split:
                i += 1
            else:
                _swap(points, perm, i, j)
                j -= 1
        if i == a:  # sliding midpoint: every point at or above the midpoint; the lowest alone to the left
            low = a
            for p in range(a + 1, b):
                if points[p, dim] < points[low, dim]:
                    low = p
            _swap(points, perm, a, low)
            i = a + 1
        if n_nodes + 2 > len(start):
            cap = 2 * len(start)
            start, stop, left, right = _grow(start, cap), _grow(stop, cap), _grow(left, cap), _grow(right, cap)
            left[n_nodes:] = -1
            right[n_nodes:] = -1
            lo, hi = _grow(lo, cap), _grow(hi, cap)
        left[node], right[node] = n_nodes, n_nodes + 1
        start[n_nodes], stop[n_nodes], start[n_nodes + 1], stop[n_nodes + 1] = a, i, i, b
        stack[top], level[top] = n_nodes + 1, lev + 1
        stack[top + 1], level[top + 1] = n_nodes, lev + 1
        top += 2
        n_nodes += 2
    return (perm, start[:n_nodes].copy(), stop[:n_nodes].copy(), left[:n_nodes].copy(), right[:n_nodes].copy(),
            lo[:n_nodes].copy(), hi[:n_nodes].copy(), depth)  # fmt: skip


class KdTree:
    """The built tree (see :func:`build_kdtree`): arrays only, searched by :func:`query_kdtree`.

    Attributes
    ----------
    points : np.ndarray [shape=(M, d)], float32 (when every coordinate is a float32 value) or float64, the points
        in leaf order.
    perm : np.ndarray [shape=(M,)], int64, the position in the data of each row of ``points``.
    start, stop, left, right : np.ndarray [shape=(n_nodes,)], int64, each node's rows [start, stop) of
        ``points`` and its children (-1 for a leaf).
    lo, hi : np.ndarray [shape=(n_nodes, d)], float64, each node's tight bounding box.
    depth : int, the deepest level (the root is 0).
    nbytes : int, memory held.
    """

    def __init__(self, data: np.ndarray, leafsize: int):
        self.points = _working_copy(data)
        perm, self.start, self.stop, self.left, self.right, self.lo, self.hi, depth = _build(self.points, leafsize)
        self.perm, self.depth = perm, int(depth)
        self.nbytes = sum(a.nbytes for a in (self.points, self.perm, self.start, self.stop, self.left, self.right,
                                             self.lo, self.hi))  # fmt: skip


def _working_copy(data: np.ndarray, rows: int = 1 << 20) -> np.ndarray:
    """A copy of data (M, d) to build the tree in: float32 when that loses nothing (F15E is float32), else
    float64; converted ``rows`` at a time so that no other whole copy is made on the way."""
    out = np.empty(data.shape, dtype=np.float32)
    for a in range(0, len(data), rows):
        part = data[a : a + rows]
        out[a : a + rows] = part
        if not np.array_equal(out[a : a + rows], part):
            return np.array(data, dtype=np.float64)
    return out


def build_kdtree(data: np.ndarray, leafsize: int) -> KdTree:
    """The tree over data (M, d) float64 (copied in leaf order; ``data`` itself is not kept).

    Parameters
    ----------
    data : np.ndarray [shape=(M, d)], float64
    leafsize : int
        Most points in a leaf (a leaf of equal points may hold more).

    Returns
    -------
    KdTree

    Examples
    --------
    >>> import numpy as np
    >>> tree = build_kdtree(np.arange(10.0)[:, None], leafsize=4)
    >>> int(tree.start[0]), int(tree.stop[0]), bool((tree.stop - tree.start)[tree.left < 0].max() <= 4)
    (0, 10, True)
    """
    return KdTree(np.ascontiguousarray(data, dtype=np.float64), int(leafsize))


# ============================================================================ search
@numba.njit(cache=True, nogil=True)
def _leaf_of(q, left, right, lo, hi):  # pragma: no cover - compiled
    """The leaf a query descends to: at each node the child whose box is nearer."""
    node = 0
    while left[node] >= 0:
        a, b = left[node], right[node]
        da, db = 0.0, 0.0
        for j in range(q.shape[0]):
            x = q[j]
            if x < lo[a, j]:
                da += (lo[a, j] - x) ** 2
            elif x > hi[a, j]:
                da += (x - hi[a, j]) ** 2
            if x < lo[b, j]:
                db += (lo[b, j] - x) ** 2
            elif x > hi[b, j]:
                db += (x - hi[b, j]) ** 2
        node = a if da <= db else b
    return node


@numba.njit(cache=True, nogil=True)
def _leaves(queries, left, right, lo, hi):  # pragma: no cover - compiled
    out = np.empty(len(queries), np.int64)
    for i in range(len(queries)):
        out[i] = _leaf_of(queries[i], left, right, lo, hi)
    return out


@numba.njit(cache=True, nogil=True)
def _box_d2(q, lo, hi, node):  # pragma: no cover - compiled
    s = 0.0
    for j in range(q.shape[0]):
        x = q[j]
        if x < lo[node, j]:
            s += (lo[node, j] - x) ** 2
        elif x > hi[node, j]:
            s += (x - hi[node, j]) ** 2
    return s


@numba.njit(cache=True, nogil=True)
def _push(hd, hi_, n, d2, idx):  # pragma: no cover - compiled
    """Into the max-heap (hd, hi_) of n entries of capacity k: add (d2, idx), or replace the root when full.
    Returns the new number of entries."""
    k = len(hd)
    if n < k:
        c = n
        while c > 0:
            p = (c - 1) >> 1
            if hd[p] >= d2:
                break
            hd[c], hi_[c] = hd[p], hi_[p]
            c = p
        hd[c], hi_[c] = d2, idx
        return n + 1
    c = 0
    while True:
        ch = 2 * c + 1
        if ch >= k:
            break
        if ch + 1 < k and hd[ch + 1] > hd[ch]:
            ch += 1
        if hd[ch] <= d2:
            break
        hd[c], hi_[c] = hd[ch], hi_[ch]
        c = ch
    hd[c], hi_[c] = d2, idx
    return n


@numba.njit(cache=True, nogil=True)
def _search_each(queries, order, first, last, k, bound2, shrink, points, perm, start, stop, left, right, lo, hi,
                 depth, out_d2, out_i):  # pragma: no cover - compiled  # fmt: skip
    """Each query ``order[first:last]`` of ``queries``: its k nearest at squared distance < bound2, into out_d2 /
    out_i (unsorted heaps; -1 / inf where fewer). ``shrink`` = 1 / (1 + eps)^2 scales the bound a box must be
    under (eps-approximate search)."""
    d = queries.shape[1]
    hd = np.empty(k)
    hx = np.empty(k, np.int64)
    stack = np.empty(2 * depth + 4, np.int64)
    near = np.empty(2 * depth + 4)
    for t in range(first, last):
        row = order[t]
        q = queries[row]
        hd[:] = np.inf
        hx[:] = -1
        cnt = 0
        kth = bound2
        top = 1
        stack[0], near[0] = 0, 0.0
        while top > 0:
            top -= 1
            node = stack[top]
            if near[top] >= kth * shrink:
                continue
            if left[node] < 0:
                half = d // 2
                for p in range(start[node], stop[node]):
                    s = 0.0
                    for j in range(half):
                        s += (q[j] - points[p, j]) ** 2
                    if s >= kth:
                        continue
                    for j in range(half, d):
                        s += (q[j] - points[p, j]) ** 2
                    if s < kth:
                        cnt = _push(hd, hx, cnt, s, p)
                        if cnt == k:
                            kth = hd[0]
                continue
            ca, cb = left[node], right[node]
            da, db = _box_d2(q, lo, hi, ca), _box_d2(q, lo, hi, cb)
            if da > db:
                ca, cb, da, db = cb, ca, db, da
            if db < kth * shrink:
                stack[top], near[top] = cb, db
                top += 1
            if da < kth * shrink:
                stack[top], near[top] = ca, da
                top += 1
        for t2 in range(k):
            out_d2[row, t2] = hd[t2]
            out_i[row, t2] = perm[hx[t2]] if hx[t2] >= 0 else -1


def query_kdtree(tree: KdTree, x: np.ndarray, k: int, radius: float | None, eps: float, threads: int):
    """k nearest (within radius) of queries x (q, d) float64: distances (q, k) float64 increasing, positions in
    the tree's data (q, k) int64, -1 / inf for missing neighbours (ties in any order).

    Parameters
    ----------
    tree : KdTree
    x : np.ndarray [shape=(q, d)], float64
    k : int
        1 <= k <= M.
    radius : float or None
        Only neighbours at distance < radius.
    eps : float
        The k-th distance returned is at most (1 + eps) times the true one (0: exact).
    threads : int
        Threads sharing the queries.

    Returns
    -------
    distances : np.ndarray [shape=(q, k)], float64
    positions : np.ndarray [shape=(q, k)], int64

    Examples
    --------
    >>> import numpy as np
    >>> tree = build_kdtree(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [0.0, 2.0]]), leafsize=1)
    >>> d, i = query_kdtree(tree, np.array([[0.0, 0.0], [2.9, 0.0]]), 2, None, 0.0, 1)
    >>> i.tolist(), np.round(d, 2).tolist()
    ([[0, 1], [2, 1]], [[0.0, 1.0], [0.1, 1.9]])
    """
    n_q = len(x)
    out_d2 = np.empty((n_q, k))
    out_i = np.empty((n_q, k), np.int64)
    order = np.argsort(_leaves(x, tree.left, tree.right, tree.lo, tree.hi), kind="stable") if n_q > 1 else np.zeros(n_q, np.int64)
    bound2 = np.inf if radius is None else radius * radius
    shrink = 1.0 / (1.0 + eps) ** 2
    tasks = range(0, max(n_q, 1), _PER_TASK)  # one (empty) task for an empty batch

    def run(first):
        _search_each(x, order, first, min(n_q, first + _PER_TASK), k, bound2, shrink, tree.points, tree.perm,
                     tree.start, tree.stop, tree.left, tree.right, tree.lo, tree.hi, tree.depth, out_d2, out_i)

    for _ in map_ordered(run, tasks, threads=min(threads, len(tasks)), name="mocapviz-kdtree"):
        pass
    sort = np.argsort(out_d2, axis=1, kind="stable")
    return np.sqrt(np.take_along_axis(out_d2, sort, axis=1)), np.take_along_axis(out_i, sort, axis=1)
