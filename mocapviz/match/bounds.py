"""Lower bounds of DTW costs from a kNN search (for :mod:`mocapviz.match.pruned`).

A query frame's k nearest database frames (:class:`mocapviz.similarity.knn.KnnIndex`, exact) say, for every range of
database frames (a document or a window), how close that frame can come to the range: the nearest neighbour
inside the range if there is one, else the k-th neighbour's distance, which no frame left out of the list can
undercut. Every DTW path over a range holds at least one cell in each query row, so the sum of these row bounds
bounds the cost of every alignment inside the range from below (the kNN form of LB_Keogh's per-row envelope
distance, Keogh & Ratanamahatana 2005, for d-dimensional frames and unconstrained warping).

:func:`box_rows` is the plain envelope form: a query frame's distance to the bounding box of a range's frames.
"""

from __future__ import annotations

import numba
import numpy as np


def range_of(frames: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The range holding each database frame (-1 when none does).

    Parameters
    ----------
    frames : np.ndarray [shape=(...)], int
        Database frames (-1: missing neighbour).
    lo, hi : np.ndarray [shape=(R,)], int
        Ranges [lo, hi), sorted by lo and disjoint.

    Returns
    -------
    np.ndarray [shape=frames.shape], int64
        Range numbers.

    Examples
    --------
    >>> range_of(np.array([0, 5, 12, -1]), np.array([0, 10]), np.array([4, 20])).tolist()
    [0, -1, 1, -1]
    """
    r = np.searchsorted(lo, frames, side="right") - 1
    inside = (frames >= 0) & (r >= 0)
    inside[inside] &= frames[inside] < hi[r[inside]]
    return np.where(inside, r, -1)


def row_bounds(distances: np.ndarray, frames: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Per range and query frame, a lower bound of the least local cost of that query frame against the range.

    Parameters
    ----------
    distances : np.ndarray [shape=(m, k)], float
        Increasing per row (inf where missing): the query frames' k nearest database frames, exact (eps = 0), in
        the search's feature units.
    frames : np.ndarray [shape=(m, k)], int64
        Their database frames (-1 where missing: then every indexed frame was returned, and a range with none of
        them holds no indexed frame).
    lo, hi : np.ndarray [shape=(R,)], int
        Ranges [lo, hi), sorted and disjoint.

    Returns
    -------
    np.ndarray [shape=(R, m)], float64
        The nearest neighbour of the query frame inside the range, else the k-th neighbour's distance (inf when
        the list is not full).
    """
    m, k = distances.shape
    full = frames[:, -1] >= 0
    kth = np.where(full, distances[:, -1], np.inf).astype(np.float64)
    out = np.broadcast_to(kth, (len(lo), m)).copy()
    r = range_of(frames, lo, hi)
    hit = r >= 0
    rows = np.broadcast_to(np.arange(m)[:, None], (m, k))
    np.minimum.at(out, (r[hit], rows[hit]), distances[hit])
    return out


@numba.njit(cache=True)
def box_rows(q, low, high):  # pragma: no cover - compiled
    """Per range and query frame, the Euclidean distance of the query frame to the range's bounding box.

    Parameters
    ----------
    q : np.ndarray [shape=(m, d)]
        The query's features (feature units).
    low, high : np.ndarray [shape=(R, d)]
        Per range the least and greatest value of every feature.

    Returns
    -------
    np.ndarray [shape=(R, m)], float64
        No frame of the range is nearer the query frame than its box (LB_Keogh's envelope distance with the whole
        range as the envelope).
    """
    n_r, m = low.shape[0], q.shape[0]
    out = np.empty((n_r, m))
    for r in range(n_r):
        for i in range(m):
            out[r, i] = _box_distance(q[i], low[r], high[r])
    return out


@numba.njit(cache=True, inline="always")
def _box_distance(v, low, high):  # pragma: no cover - compiled
    """The Euclidean distance of the point ``v`` (d,) to the box [low, high] (d,), float64."""
    s = 0.0
    for t in range(v.shape[0]):
        x = np.float64(v[t])
        if x < low[t]:
            s += (low[t] - x) ** 2
        elif x > high[t]:
            s += (x - high[t]) ** 2
    return np.sqrt(s)


@numba.njit(cache=True)
def diagonal_costs(q, x, lo, hi):  # pragma: no cover - compiled
    """Per range, the cost of the straight warping path from (0, lo) to (m - 1, hi - 1): an upper bound of the
    whole-range DTW cost (DTW takes the least cost over every path, this is one of them).

    Parameters
    ----------
    q : np.ndarray [shape=(m, d)]
        The query's features (feature units).
    x : np.ndarray [shape=(N, d)]
        The database's features.
    lo, hi : np.ndarray [shape=(R,)], int
        Ranges [lo, hi) of x, non-empty.

    Returns
    -------
    np.ndarray [shape=(R,)], float64
        The sum of the local Euclidean costs of the max(m, n) cells (round(k (m-1) / (L-1)), lo + round(k (n-1) /
        (L-1))), k = 0..L-1, L = max(m, n): a warping path (each step moves one frame on the longer side, zero or
        one on the other), so no less than :func:`~mocapviz.match.dtw`'s cost of the range.

    Examples
    --------
    >>> q = np.array([[0.0], [1.0], [2.0]])
    >>> x = np.array([[0.0], [2.0], [0.0], [1.0], [1.0], [2.0]])
    >>> diagonal_costs(q, x, np.array([0, 2]), np.array([2, 6])).tolist()  # cells (0,0) (1,1) (2,1); (0,0) (1,1) (1,2) (2,3)
    [1.0, 0.0]
    """
    n_r, m, d = lo.shape[0], q.shape[0], q.shape[1]
    out = np.empty(n_r)
    for r in range(n_r):
        n = hi[r] - lo[r]
        steps = max(m, n) - 1
        total = 0.0
        for k in range(steps + 1):
            i = (2 * k * (m - 1) + steps) // (2 * steps) if steps else 0
            j = (2 * k * (n - 1) + steps) // (2 * steps) if steps else 0
            s = 0.0
            for t in range(d):
                diff = np.float64(q[i, t]) - np.float64(x[lo[r] + j, t])
                s += diff * diff
            total += np.sqrt(s)
        out[r] = total
    return out


@numba.njit(cache=True)
def whole_rows(q, x, lo, hi, low, high, which):  # pragma: no cover - compiled
    """The row bounds and lower bounds of whole-range DTW (:func:`mocapviz.match.pruned.search_ranges`, whole task)
    for the ranges ``which``: each query frame's distance to the range's box (:func:`box_rows`), the first and
    last rows the exact cost of the path's first and last cells (LB_Kim: every path starts at (0, lo) and ends at
    (m - 1, hi - 1)).

    Parameters
    ----------
    q : np.ndarray [shape=(m, d)]
        The query's features (feature units).
    x : np.ndarray [shape=(N, d)]
        The database's features.
    lo, hi : np.ndarray [shape=(R,)], int
        Ranges [lo, hi) of x.
    low, high : np.ndarray [shape=(R, d)]
        Per range the least and greatest value of every feature.
    which : np.ndarray [shape=(W,)], int
        The ranges bounded (the others get 0).

    Returns
    -------
    rows : np.ndarray [shape=(R, m)], float64
        Per range and query frame a lower bound of the local cost of any cell of that row on a path.
    bound : np.ndarray [shape=(R,)], float64
        rows.sum(axis=1) / (m + hi - lo): a lower bound of the range's normalised DTW cost.

    Examples
    --------
    >>> q = np.array([[0.0], [3.0]])
    >>> x = np.array([[1.0], [2.0], [5.0]])
    >>> rows, bound = whole_rows(q, x, np.array([0]), np.array([3]), np.array([[1.0]]), np.array([[5.0]]),
    ...                          np.array([0]))
    >>> rows.tolist(), bound.tolist()  # |0 - 1| (first cell), |3 - 5| (last cell); (1 + 2) / (2 + 3)
    ([[1.0, 2.0]], [0.6])
    """
    n_r, m, d = lo.shape[0], q.shape[0], q.shape[1]
    rows = np.zeros((n_r, m))
    bound = np.zeros(n_r)
    for r in which:
        for i in range(m):
            rows[r, i] = _box_distance(q[i], low[r], high[r])
        for i, j in ((0, lo[r]), (m - 1, hi[r] - 1)):
            s = 0.0
            for t in range(d):
                diff = np.float64(q[i, t]) - np.float64(x[j, t])
                s += diff * diff
            rows[r, i] = np.sqrt(s)
        total = 0.0
        for i in range(m):
            total += rows[r, i]
        bound[r] = total / (m + hi[r] - lo[r])
    return rows, bound
