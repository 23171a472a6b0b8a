"""Adaptive segmentation (Müller, Röder & Clausen 2005, §4): F-runs of maximal length.

A boolean feature function F with f components maps every frame to a feature vector in {0, 1}^f. The
F-segments of a motion are its runs of maximal length with a constant feature vector, and the feature
sequence F[D] lists one vector per segment. Vectors are coded as integers with feature 1 as the least
significant bit (the toolbox's index convention, RELATIONAL_FEATURES.md §1.7).

encode            (T, f) bool -> (T,) int64 codes.
decode            (M,) codes -> (M, f) bool.
segment           (T, f) bool -> FeatureSequence (codes, start frames, lengths), never across documents.
"""
from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ..errors import ParameterError

MAX_FEATURES = 62  # codes are int64


class FeatureSequence(NamedTuple):
    """The feature sequence F[D] of a segmentation (a named tuple: the fields are its attributes).

    Parameters
    ----------
    codes : np.ndarray [shape=(M,)], int64
        Feature vector of each segment (feature 1 = bit 0).
    starts : np.ndarray [shape=(M,)], int64
        First frame of each segment.
    lengths : np.ndarray [shape=(M,)], int64
        Frames in each segment.
    n_features : int
        f.
    """

    codes: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    n_features: int

    def vectors(self) -> np.ndarray:
        """The feature vectors.

        Returns
        -------
        np.ndarray [shape=(M, f)], bool
            One row per segment.
        """
        return decode(self.codes, self.n_features)


def _check(values) -> np.ndarray:
    values = np.asarray(values)
    if values.ndim != 2:
        raise ParameterError(f"feature values must have shape (T, f), got {values.shape}")
    if values.shape[1] == 0:
        raise ParameterError("no features selected: pick at least one feature")
    if values.shape[1] > MAX_FEATURES:
        raise ParameterError(f"at most {MAX_FEATURES} features per segmentation, got {values.shape[1]}")
    return values.astype(bool, copy=False)


def encode(values: np.ndarray) -> np.ndarray:
    """Feature vectors as integer codes.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        Feature values, f <= 62.

    Returns
    -------
    np.ndarray [shape=(T,)], int64
        The sum of ``values[:, k] << k``.

    Examples
    --------
    >>> encode(np.array([[1, 0], [0, 1], [1, 1]], bool)).tolist()
    [1, 2, 3]
    """
    return _encode_kernel(_check(values))


@numba.njit(cache=True, nogil=True)
def _encode_kernel(values):  # pragma: no cover - compiled
    """values (T, f) bool -> (T,) int64 codes, feature k as bit k."""
    out = np.empty(values.shape[0], dtype=np.int64)
    for t in range(values.shape[0]):
        code = 0
        for k in range(values.shape[1]):
            if values[t, k]:
                code |= np.int64(1) << k
        out[t] = code
    return out


def decode(codes: np.ndarray, n_features: int) -> np.ndarray:
    """Integer codes back to feature vectors (the inverse of :func:`encode`).

    Parameters
    ----------
    codes : np.ndarray [shape=(M,)], int
        Codes, feature 1 = bit 0.
    n_features : int
        f.

    Returns
    -------
    np.ndarray [shape=(M, f)], bool

    Examples
    --------
    >>> decode(np.array([1, 2, 3]), 2).astype(int).tolist()
    [[1, 0], [0, 1], [1, 1]]
    """
    codes = np.asarray(codes, dtype=np.int64)
    return ((codes[:, None] >> np.arange(n_features, dtype=np.int64)) & 1).astype(bool)


def segment(values: np.ndarray, doc_starts=None) -> FeatureSequence:
    """F-segmentation: runs of maximal length of a constant feature vector.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        Feature values of consecutive frames (any subset of features: the segmentation adapts to it).
    doc_starts : array-like of int, optional
        First frames of the documents concatenated in ``values``; a segment never crosses one.

    Returns
    -------
    FeatureSequence
        The segments' codes, start frames and lengths.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §4 (adaptive segmentation: F-segments, the feature sequence F[D]).

    Examples
    --------
    >>> segment(np.array([[1, 0], [1, 0], [0, 0], [1, 0]], bool)).codes
    array([1, 0, 1])
    """
    codes = encode(values)
    n = codes.shape[0]
    change = np.ones(n, dtype=bool)
    change[1:] = codes[1:] != codes[:-1]
    if doc_starts is not None:
        doc_starts = np.asarray(doc_starts, dtype=np.int64)
        change[doc_starts[doc_starts < n]] = True
    starts = np.flatnonzero(change)
    lengths = np.diff(np.append(starts, n))
    return FeatureSequence(codes[starts], starts, lengths, values.shape[1])
