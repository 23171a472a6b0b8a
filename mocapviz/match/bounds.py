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
    n_r, m, d = low.shape[0], q.shape[0], q.shape[1]
    out = np.empty((n_r, m))
    for r in range(n_r):
        for i in range(m):
            s = 0.0
            for t in range(d):
                v = np.float64(q[i, t])
                if v < low[r, t]:
                    s += (low[r, t] - v) ** 2
                elif v > high[r, t]:
                    s += (v - high[r, t]) ** 2
            out[r, i] = np.sqrt(s)
    return out
