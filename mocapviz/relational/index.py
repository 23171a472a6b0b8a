"""Inverted-list indexes over relational feature sequences (Müller, Röder & Clausen 2005, §5).

For a feature sequence F[D] = (w_1, ..., w_M) the index stores, for every feature vector v that occurs,
the sorted list L(v) of the segment positions k with w_k = v (§5.1), plus each segment's start frame and
length (so hits map back to frames) and the first segment of every document (so no hit spans two
documents). Positions are 0-based here (the paper counts from 1).

InvertedIndex                 the index of one feature set; query methods:
    exact(query)              segments k with F[Q] = (w_k, ..., w_{k+L-1}), eq. (7)
    fuzzy(fuzzy_sets)         w_{k+l} in V_l for every l, eq. (11)
    adaptive_fuzzy(fuzzy_sets)
                              §5.2: the database segmentation coarsened to the fuzzy sets
    mismatch(query, m)        at most m query segments may disagree (§5.2, last paragraph)
    adaptive_mismatch(query, selected, m)
                              m-mismatch hits on the segmentation coarsened to some features (§5.2)
feature_group_values          the columns of each feature group of a set's values.
build(db, relational_set)     one index per feature group (lower, upper, mix) over a MotionDB, saved with it.
load(db, relational_set)      the saved indexes of a MotionDB (checked to be current).
extend(db, relational_set)    the saved indexes of an earlier generation extended with the documents appended since.
load_or_build(db, ...)        the saved indexes when current, else extended, else built.
"""
from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from .. import store
from ..db import layout
from ..db.arrays import load_arrays, save_arrays
from ..errors import MotionDBError, ParameterError, StaleDataError
from ..features.segmentation import FeatureSequence, decode, encode, segment

FORMAT = "mocapviz.InvertedIndex"
_REBUILD = "rebuild it with `mocapviz index DB`"
VERSION = 2  # 2: the header holds the sha256 of the arrays, checked at every load


def merge_adjacent(fuzzy_sets: list[np.ndarray]) -> list[np.ndarray]:
    """Conjoin adjacent fuzzy sets with a common element until no two neighbours intersect (§5.2).

    Parameters
    ----------
    fuzzy_sets : list of np.ndarray [shape=(n_l,)], int64 codes

    Returns
    -------
    list of sorted unique code arrays, V_l ∩ V_{l+1} = ∅ for all l.
    """
    out: list[np.ndarray] = []
    for s in fuzzy_sets:
        s = np.unique(np.asarray(s, dtype=np.int64))
        if out and np.intersect1d(out[-1], s).size:
            out[-1] = np.union1d(out[-1], s)
            # the grown set may now meet its left neighbour too
            while len(out) > 1 and np.intersect1d(out[-2], out[-1]).size:
                last = out.pop()
                out[-1] = np.union1d(out[-1], last)
        else:
            out.append(s)
    return out


@numba.njit(cache=True, nogil=True)
def _concatenate_lists(positions, offsets, lists):  # pragma: no cover - compiled
    """positions[offsets[k]:offsets[k+1]] for each k of ``lists``, concatenated into one int64 array."""
    n = 0
    for k in lists:
        n += offsets[k + 1] - offsets[k]
    out = np.empty(n, dtype=np.int64)
    at = 0
    for k in lists:
        for p in range(offsets[k], offsets[k + 1]):
            out[at] = positions[p]
            at += 1
    return out


@numba.njit(cache=True, nogil=True)
def _verify_shifted(rank, segment_doc, member, cand, s, out):  # pragma: no cover - compiled
    """Fuzzy hits among candidate segments of one set (eq. 11 from its smallest list).

    rank : (M,) int -- list index of each segment's code; member : (L, K) bool -- list k's code is in V_l;
    cand : (C,) int, sorted -- segments whose code is in V_s; out : (C,) int. Hit k = c - s when segments
    k..k+L-1 exist, lie in one document and w_{k+l} ∈ V_l for every l. Returns the number of hits in ``out``.
    """
    n_sets = member.shape[0]
    m = rank.shape[0]
    h = 0
    for c in cand:
        k = c - s
        if k < 0 or k + n_sets > m or segment_doc[k] != segment_doc[k + n_sets - 1]:
            continue
        ok = True
        for l in range(n_sets):
            if not member[l, rank[k + l]]:
                ok = False
                break
        if ok:
            out[h] = k
            h += 1
    return h


@numba.njit(cache=True, nogil=True)
def _adaptive_walk(rank, segment_doc, member, cand, s, out):  # pragma: no cover - compiled
    """Adaptive fuzzy hits through candidate segments of one set (§5.2), by walking the coarsened runs.

    rank : (M,) int -- list index of each segment's code; member : (L, K) bool -- list k's code is in V_l;
    cand : (C,) int, sorted -- segments whose code is in V_s; out : (C, L+1) int. A candidate that starts a
    maximal run of V_s is extended backwards over runs of V_{s-1}, ..., V_1 and forwards over runs of V_{s+1},
    ..., V_L, all in its document; each complete walk is one hit row of ``out``. Returns the number of hits.
    """
    n_sets = member.shape[0]
    m = rank.shape[0]
    h = 0
    for c in cand:
        doc = segment_doc[c]
        if c > 0 and segment_doc[c - 1] == doc and member[s, rank[c - 1]]:
            continue  # inside a run of V_s: its run start is the candidate that counts
        ok = True
        pos = c
        for l in range(s - 1, -1, -1):
            if pos == 0 or segment_doc[pos - 1] != doc or not member[l, rank[pos - 1]]:
                ok = False
                break
            pos -= 1
            while pos > 0 and segment_doc[pos - 1] == doc and member[l, rank[pos - 1]]:
                pos -= 1
            out[h, l] = pos
        if not ok:
            continue
        out[h, s] = c
        pos = c + 1
        while pos < m and segment_doc[pos] == doc and member[s, rank[pos]]:
            pos += 1
        for l in range(s + 1, n_sets):
            if pos == m or segment_doc[pos] != doc or not member[l, rank[pos]]:
                ok = False
                break
            out[h, l] = pos
            pos += 1
            while pos < m and segment_doc[pos] == doc and member[l, rank[pos]]:
                pos += 1
        if ok:
            out[h, n_sets] = pos
            h += 1
    return h


@numba.njit(cache=True, nogil=True)
def _run_first(codes, segment_doc, mask, pos):  # pragma: no cover - compiled
    """First segment of the run of equal ``code & mask`` (in one document) that holds segment ``pos``."""
    doc, run = segment_doc[pos], codes[pos] & mask
    while pos > 0 and segment_doc[pos - 1] == doc and (codes[pos - 1] & mask) == run:
        pos -= 1
    return pos


@numba.njit(cache=True, nogil=True)
def _run_stop(codes, segment_doc, mask, pos):  # pragma: no cover - compiled
    """One past the last segment of the run of equal ``code & mask`` (in one document) that holds ``pos``."""
    doc, run = segment_doc[pos], codes[pos] & mask
    while pos < codes.shape[0] and segment_doc[pos] == doc and (codes[pos] & mask) == run:
        pos += 1
    return pos


@numba.njit(cache=True, nogil=True)
def _mismatch_walk(codes, segment_doc, mask, query, free, m, cand, anchor, out):  # pragma: no cover - compiled
    """m-mismatch hits on the segmentation coarsened to the bits of ``mask``, through candidate runs (§5.2).

    codes : (M,) int64 stored codes; query : (L,) int64, only ``mask`` bits set; free : (L,) bool -- query
    segment l may disagree; cand : (C,) int -- segments that start a coarsened run (a maximal run of equal
    ``code & mask``) equal to ``query[anchor[i]]``; out : (C, L+1) int. Each candidate is walked over the
    anchor's coarsened runs before and after it in its document, counting the runs that disagree with the query;
    a walk with at most ``m`` of them, all at free positions, is one hit row of ``out`` (the first segment of each
    coarsened run, then one past the last). Returns the number of hits.
    """
    n = query.shape[0]
    h = 0
    for i in range(cand.shape[0]):
        c, s = cand[i], anchor[i]
        doc = segment_doc[c]
        out[h, s] = c
        miss = 0
        pos = c
        for l in range(s - 1, -1, -1):
            if pos == 0 or segment_doc[pos - 1] != doc:
                miss = m + 1
                break
            pos = _run_first(codes, segment_doc, mask, pos - 1)
            out[h, l] = pos
            if (codes[pos] & mask) != query[l]:
                miss += 1 if free[l] else m + 1
            if miss > m:
                break
        pos = _run_stop(codes, segment_doc, mask, c)
        for l in range(s + 1, n):
            if miss > m or pos == codes.shape[0] or segment_doc[pos] != doc:
                miss = m + 1
                break
            out[h, l] = pos
            if (codes[pos] & mask) != query[l]:
                miss += 1 if free[l] else m + 1
            pos = _run_stop(codes, segment_doc, mask, pos)
        if miss <= m:
            out[h, n] = pos
            h += 1
    return h


def _mismatch_plan(sizes: np.ndarray, m: int, allowed) -> tuple[np.ndarray, np.ndarray]:
    """For an m-mismatch query of L segments whose (union) lists hold ``sizes`` (L,) entries: which positions may
    disagree (bool (L,)) and the positions whose lists give every candidate hit. A hit agrees with every position
    where no mismatch is allowed, so the shortest such list holds them all; with mismatches allowed anywhere it
    agrees with at least one of any m + 1 positions (pigeonhole), so the union of the m + 1 shortest lists does.

    Raises
    ------
    ParameterError
        ``m`` outside [0, L), allowed positions outside [0, L).
    """
    n = sizes.size
    if not 0 <= m < n:
        raise ParameterError(f"m must satisfy 0 <= m < {n} (the query's segments), got {m}")
    positions = np.arange(n) if allowed is None else np.unique(np.asarray(allowed, dtype=np.int64))
    if positions.size and (positions.min() < 0 or positions.max() >= n):
        raise ParameterError(f"allowed mismatch positions must lie in [0, {n}), got {positions.tolist()}")
    free = np.isin(np.arange(n), positions)
    fixed = np.flatnonzero(~free)
    anchors = fixed[[np.argmin(sizes[fixed])]] if fixed.size else np.argsort(sizes, kind="stable")[: m + 1]
    return free, anchors


class InvertedIndex:
    """Inverted lists of a feature sequence F[D] over one or more documents.

    Attributes
    ----------
    n_features : int
    feature_names : tuple of str
    codes : np.ndarray [shape=(M,)], int64 -- w_k as integer codes (feature 1 = bit 0).
    starts, lengths : np.ndarray [shape=(M,)], int64 -- first frame and frame count of each segment.
    doc_first_segment : np.ndarray [shape=(D+1,)], int64 -- first segment of each document, then M.
    list_codes : np.ndarray [shape=(K,)], int64 -- the codes that occur, sorted.
    list_offsets : np.ndarray [shape=(K+1,)], int64 -- L(list_codes[i]) = positions[offsets[i]:offsets[i+1]].
    positions : np.ndarray [shape=(M,)], int32 -- all inverted lists, each sorted.
    rank : np.ndarray [shape=(M,)], int32 -- list index of each segment's code (codes = list_codes[rank]).
    meta : dict -- what the index was built from (database generation, feature set, group).

    Parameters
    ----------
    sequence : FeatureSequence
        F[D]: the segments' codes, start frames and lengths (:func:`mocapviz.features.segmentation.segment`).
    doc_first_segment : array_like of int [shape=(D+1,)], optional
        The first segment of each document, then M (default: one document).
    feature_names : sequence of str, optional
        The f feature names (default ``f1``, ``f2``, ...).
    meta : dict, optional
        Stored with the index. (Usually built with :meth:`from_features`, frame-wise values segmented there, or,
        for a MotionDB, with :func:`build`.)

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §5.1 (inverted lists, exact hits), §5.2 (fuzzy, adaptive fuzzy and m-mismatch hits).

    Examples
    --------
    Two features (bit 0: right foot raised, bit 1: left foot raised) over 9 frames, 7 runs of equal vectors:

    >>> import numpy as np
    >>> values = np.array([[0, 0], [1, 0], [1, 0], [1, 1], [0, 1], [0, 0], [1, 0], [1, 1], [1, 1]], dtype=bool)
    >>> index = InvertedIndex.from_features(values, feature_names=["rfoot_raised", "lfoot_raised"])
    >>> index.n_segments, index.codes.tolist(), index.starts.tolist()
    (7, [0, 1, 3, 2, 0, 1, 3], [0, 1, 3, 4, 5, 6, 7])
    >>> index.inverted_list(1).tolist()  # L(v) of v = (1, 0): the segments where only the right foot is raised
    [1, 5]
    >>> index.exact([[1, 0], [1, 1]]).tolist()  # segments k with F[Q] = (w_k, w_k+1)
    [1, 5]
    >>> index.frame_spans([1, 5], [3, 7])  # their frames: start, end (exclusive)
    (array([1, 6]), array([4, 9]))
    """

    def __init__(self, sequence: FeatureSequence, doc_first_segment=None, feature_names=None, meta=None):
        self.n_features = int(sequence.n_features)
        self.codes = np.asarray(sequence.codes, dtype=np.int64)
        self.starts = np.asarray(sequence.starts, dtype=np.int64)
        self.lengths = np.asarray(sequence.lengths, dtype=np.int64)
        m = self.codes.shape[0]
        self.doc_first_segment = np.asarray([0, m] if doc_first_segment is None else doc_first_segment, np.int64)
        if self.doc_first_segment[0] != 0 or self.doc_first_segment[-1] != m:
            raise ParameterError("doc_first_segment must start at 0 and end at the number of segments")
        self.feature_names = tuple(feature_names or (f"f{k + 1}" for k in range(self.n_features)))
        if len(self.feature_names) != self.n_features:
            raise ParameterError(f"{len(self.feature_names)} feature names for {self.n_features} features")
        self.meta = dict(meta or {})
        order = np.argsort(self.codes, kind="stable")  # by code, positions ascending within a code
        self.list_codes, counts = np.unique(self.codes[order], return_counts=True)
        self.list_offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.positions = order.astype(np.int32)
        self.rank = np.empty(m, dtype=np.int32)  # list index of each segment's code: codes = list_codes[rank]
        self.rank[order] = np.repeat(np.arange(self.list_codes.size, dtype=np.int32), counts)
        self.segment_doc = np.repeat(np.arange(self.doc_first_segment.size - 1), np.diff(self.doc_first_segment))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_feature_sequence(cls, sequence, feature_names=None) -> InvertedIndex:
        """Index a feature sequence given directly, one row per segment (one document).

        Parameters
        ----------
        sequence : np.ndarray [shape=(M, f)], bool
            F[D]; each row is one segment (of length 1 frame).
        feature_names : sequence of str, optional
            The f feature names.

        Returns
        -------
        InvertedIndex
            One document of M segments (row k is segment k, frame k).

        Examples
        --------
        >>> index = InvertedIndex.from_feature_sequence([[1, 0], [1, 1], [1, 0], [1, 1]])
        >>> index.exact([[1, 0], [1, 1]]).tolist()
        [0, 2]
        """
        sequence = np.asarray(sequence, dtype=bool)
        m = sequence.shape[0]
        seq = FeatureSequence(encode(sequence), np.arange(m), np.ones(m, dtype=np.int64), sequence.shape[1])
        return cls(seq, feature_names=feature_names)

    @classmethod
    def from_features(cls, values: np.ndarray, doc_starts=None, feature_names=None, meta=None) -> InvertedIndex:
        """Segment frame-wise feature values (adaptive segmentation, §4) and index the runs.

        Parameters
        ----------
        values : np.ndarray [shape=(T, f)], bool
            Relational feature values of every frame.
        doc_starts : array-like of int, optional
            First frame of each document in ``values`` (default: one document); no segment crosses a document
            boundary.
        feature_names : sequence of str, optional
            The f feature names.
        meta : dict, optional
            Stored with the index.

        Returns
        -------
        InvertedIndex
            Over the F-segments (runs of equal feature vectors) of ``values``.
        """
        doc_starts = np.asarray([0] if doc_starts is None else doc_starts, dtype=np.int64)
        seq = segment(values, doc_starts)
        first = np.append(np.searchsorted(seq.starts, doc_starts), seq.codes.shape[0])
        return cls(seq, first, feature_names, meta)

    def appended(self, other: InvertedIndex, frames: int, meta=None) -> InvertedIndex:
        """This index followed by ``other``'s documents: the index of the two feature sequences concatenated.

        A document's segments depend on its own frames only (§4: segments never cross a document boundary), so the
        index of a database that grew by some documents is the old one with the new documents' segments after its
        own: every inverted list gains the new segments' positions (all after its old ones) at its end.

        Parameters
        ----------
        other : InvertedIndex
            An index of the same features over the documents that follow (its frames counted from 0).
        frames : int
            The frames this index covers: ``other``'s frame 0 becomes frame ``frames``.
        meta : dict, optional
            The new index's meta (default: this one's).

        Returns
        -------
        InvertedIndex
            Equal to the index built over all the documents at once.

        Examples
        --------
        >>> import numpy as np
        >>> a, b = np.array([[0], [1], [1]], bool), np.array([[1], [0]], bool)
        >>> both = InvertedIndex.from_features(a).appended(InvertedIndex.from_features(b), 3)
        >>> whole = InvertedIndex.from_features(np.concatenate([a, b]), doc_starts=[0, 3])
        >>> both.positions.tolist() == whole.positions.tolist(), both.starts.tolist(), both.doc_first_segment.tolist()
        (True, [0, 1, 3, 4], [0, 2, 4])
        """
        if other.feature_names != self.feature_names:
            raise ParameterError(f"cannot append an index of {other.feature_names} to one of {self.feature_names}")
        sequence = FeatureSequence(np.concatenate([self.codes, other.codes]),
                                   np.concatenate([self.starts, other.starts + int(frames)]),
                                   np.concatenate([self.lengths, other.lengths]), self.n_features)  # fmt: skip
        first = np.concatenate([self.doc_first_segment[:-1], other.doc_first_segment + self.n_segments])
        return InvertedIndex(sequence, first, self.feature_names, self.meta if meta is None else meta)

    # ------------------------------------------------------------------ lists
    @property
    def n_segments(self) -> int:
        return self.codes.shape[0]

    def inverted_list(self, code: int) -> np.ndarray:
        """L(v) for the code of v: sorted 0-based segment positions (empty if v never occurs).

        Parameters
        ----------
        code : int
            The feature vector v as a code (feature 1 = bit 0).

        Returns
        -------
        np.ndarray [shape=(n,)], int32
            Segment positions k with w_k = v, increasing (a view of the stored lists).
        """
        i = np.searchsorted(self.list_codes, code)
        if i == self.list_codes.size or self.list_codes[i] != code:
            return np.empty(0, dtype=np.int32)
        return self.positions[self.list_offsets[i] : self.list_offsets[i + 1]]

    def union_list(self, codes) -> np.ndarray:
        """L(V) = union of L(v) over the codes of V, sorted.

        Parameters
        ----------
        codes : array_like of int
            The codes of the fuzzy set V (codes that never occur are ignored).

        Returns
        -------
        np.ndarray [shape=(n,)], int64
            Segment positions k with w_k in V, increasing.
        """
        codes = np.unique(np.asarray(codes, dtype=np.int64))
        i = np.searchsorted(self.list_codes, codes)
        i = i[(i < self.list_codes.size) & (self.list_codes[np.minimum(i, self.list_codes.size - 1)] == codes)]
        return self._gather(i)

    def _gather(self, lists: np.ndarray) -> np.ndarray:
        """The sorted union of the inverted lists with the given list indices, int64. The lists are disjoint (a
        segment has one code) and each sorted: a small union is merged by a sort that finds the sorted runs
        (timsort, O(n log lists)); a large one is marked in a mask of the segments and read back (O(segments)),
        ten times faster than a general sort of a million positions."""
        out = _concatenate_lists(self.positions, self.list_offsets, lists)
        if out.size * 16 < self.n_segments:
            return np.sort(out, kind="stable")
        mark = np.zeros(self.n_segments, dtype=bool)
        mark[out] = True
        return np.flatnonzero(mark).astype(np.int64, copy=False)

    def _query_codes(self, query) -> np.ndarray:
        q = np.asarray(query)
        if q.ndim == 2:
            if q.shape[1] != self.n_features:
                raise ParameterError(f"query vectors have {q.shape[1]} features, the index {self.n_features}")
            q = encode(q)
        q = q.astype(np.int64).ravel()
        if q.size == 0:
            raise ParameterError("empty query: it needs at least one segment")
        if np.any((q < 0) | (q >= (1 << self.n_features))):
            raise ParameterError(f"query codes must lie in [0, 2^{self.n_features})")
        return q

    def _query_sets(self, sets) -> tuple[np.ndarray, np.ndarray, int]:
        """Checked fuzzy sets, adjacent ones with a common element merged (:func:`merge_adjacent`).

        Returns (codes, set_id, L): the distinct codes of each set V_l, with set_id l, l = 0..L-1.
        """
        if len(sets) == 0:
            raise ParameterError("empty fuzzy query: it needs at least one set")
        arrays = [np.asarray(s) for s in sets]
        if any(a.size == 0 for a in arrays):
            raise ParameterError("a fuzzy set is empty: every set needs at least one alternative")
        arrays = [self._query_codes(a) if a.ndim == 2 else a.ravel() for a in arrays]
        codes = self._query_codes(np.concatenate(arrays))
        set_id = np.repeat(np.arange(len(arrays)), [a.size for a in arrays])
        order = np.lexsort((set_id, codes))  # by code, then set
        codes, set_id = codes[order], set_id[order]
        same_code = codes[1:] == codes[:-1]
        if (same_code & (set_id[1:] == set_id[:-1] + 1)).any():  # two adjacent sets meet: conjoin (rare)
            merged = merge_adjacent([codes[set_id == l] for l in range(len(arrays))])
            return np.concatenate(merged), np.repeat(np.arange(len(merged)), [m.size for m in merged]), len(merged)
        distinct = np.ones(codes.size, dtype=bool)
        distinct[1:] = ~same_code | (set_id[1:] != set_id[:-1])
        return codes[distinct], set_id[distinct], len(arrays)

    def _valid(self, hits: np.ndarray, n: int) -> np.ndarray:
        """Hits k whose segments k..k+n-1 exist and lie in one document."""
        hits = hits[(hits >= 0) & (hits + n - 1 < self.n_segments)]
        return hits[self.segment_doc[hits] == self.segment_doc[hits + n - 1]]

    def _membership(self, codes: np.ndarray, set_id: np.ndarray, n_sets: int) -> tuple[np.ndarray, np.ndarray]:
        """Which inverted lists each fuzzy set covers; V_l holds the ``codes`` whose ``set_id`` is l.

        Returns
        -------
        member : np.ndarray [shape=(L, K)], bool -- list k's code lies in V_l.
        sizes : np.ndarray [shape=(L,)], int64 -- |L(V_l)|, the number of segments with a code in V_l.
        """
        n_lists = self.list_codes.size
        i = np.minimum(np.searchsorted(self.list_codes, codes), n_lists - 1)
        found = self.list_codes[i] == codes
        set_id, i = set_id[found], i[found]
        member = np.zeros((n_sets, n_lists), dtype=bool)
        member[set_id, i] = True
        sizes = np.bincount(set_id, weights=self.list_offsets[i + 1] - self.list_offsets[i], minlength=n_sets)
        return member, sizes

    def _candidates(self, member: np.ndarray, sizes: np.ndarray) -> tuple[int, np.ndarray]:
        """The most selective set s and the sorted segments with a code in V_s (its union list L(V_s))."""
        s = int(np.argmin(sizes))
        return s, self._gather(np.flatnonzero(member[s]))

    # ------------------------------------------------------------------ queries
    def exact(self, query) -> np.ndarray:
        """Exact hits H_D(F[Q]) (§5.1, eq. 7).

        The intersection of the shifted lists L(w_l) - l is computed from the shortest list: its positions,
        shifted, are the only candidates, and each is checked against the stored sequence at once.

        Parameters
        ----------
        query : np.ndarray [shape=(L, f)] bool vectors or [shape=(L,)] int codes
            The query's feature sequence F[Q].

        Returns
        -------
        np.ndarray [shape=(H,)], int64
            Sorted 0-based positions k of the first matching segment.

        Examples
        --------
        >>> index = InvertedIndex.from_feature_sequence([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [1, 1]])
        >>> index.exact([[1, 0], [1, 1]]).tolist(), index.exact([1, 3]).tolist()  # vectors or their codes
        ([1, 4], [1, 4])
        """
        q = self._query_codes(query)
        return self._fuzzy_hits(q, np.arange(q.size), q.size)

    def fuzzy(self, fuzzy_sets) -> np.ndarray:
        """Fuzzy hits H_D(F[Q]_fuz) (§5.2, eq. 11): w_{k+l} ∈ V_l for all l.

        ∩_l (L(V_l) - l), computed from the smallest union list L(V_s): its positions shifted by -s are the
        candidates, checked against every set at once through the list membership table.

        Parameters
        ----------
        fuzzy_sets : list of (codes [shape=(n_l,)] or bool vectors [shape=(n_l, f)])
            The fuzzy sets V_1..V_L; adjacent sets with a common element are conjoined first.

        Returns
        -------
        np.ndarray [shape=(H,)], int64
            Sorted 0-based positions k.

        Examples
        --------
        >>> index = InvertedIndex.from_feature_sequence([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [1, 1]])
        >>> index.fuzzy([[1], [3, 2]]).tolist()  # V_1 = {(1, 0)}, V_2 = {(1, 1), (0, 1)} as codes
        [1, 4]
        >>> index.fuzzy([[[0, 0], [0, 1]], [[1, 0]]]).tolist()  # left foot free in the first segment
        [0, 3]
        """
        return self._fuzzy_hits(*self._query_sets(fuzzy_sets))

    def _fuzzy_hits(self, codes: np.ndarray, set_id: np.ndarray, n_sets: int) -> np.ndarray:
        member, sizes = self._membership(codes, set_id, n_sets)
        if self.n_segments == 0 or sizes.min() == 0:
            return np.empty(0, dtype=np.int64)
        s, cand = self._candidates(member, sizes)
        out = np.empty(cand.size, dtype=np.int64)
        return out[: _verify_shifted(self.rank, self.segment_doc, member, cand, s, out)]

    def adaptive_fuzzy(self, fuzzy_sets) -> np.ndarray:
        """Adaptive fuzzy hits (§5.2): the segmentation of D coarsened to maximal runs within each V_l.

        A hit starts at a segment k_1 whose vector is in V_1 while its predecessor's is not (or that begins
        a document); the run of segments in V_1 ends before k_2, whose vector must be in V_2, and so on.
        Computed from the smallest union list L(V_s): each of its segments that starts a run of V_s is walked
        backwards and forwards over the neighbouring runs (a compiled loop over the stored sequence).

        Parameters
        ----------
        fuzzy_sets : list of (codes [shape=(n_l,)] or bool vectors [shape=(n_l, f)])
            The fuzzy sets V_1..V_L, as for :meth:`fuzzy`.

        Returns
        -------
        np.ndarray [shape=(H, L+1)], int64
            Per hit the 0-based segment indices k_1 < ... < k_L where each coarsened segment starts, and the
            index one past the end of the last one.

        Examples
        --------
        >>> index = InvertedIndex.from_feature_sequence([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0], [1, 0], [1, 1]])
        >>> index.adaptive_fuzzy([[0, 1], [3]])  # a run of (0, 0) or (1, 0) segments, then (1, 1)
        array([[0, 2, 3],
               [4, 6, 7]])
        """
        codes, set_id, n_sets = self._query_sets(fuzzy_sets)
        member, sizes = self._membership(codes, set_id, n_sets)
        if self.n_segments == 0 or sizes.min() == 0:
            return np.empty((0, n_sets + 1), dtype=np.int64)
        s, cand = self._candidates(member, sizes)
        out = np.empty((cand.size, n_sets + 1), dtype=np.int64)
        h = _adaptive_walk(self.rank, self.segment_doc, member, cand, s, out)
        return out[:h]

    def mismatch(self, query, m: int, allowed=None) -> np.ndarray:
        """m-mismatch hits (§5.2): at most ``m`` query segments may disagree with the database.

        Candidates come from few lists: a hit agrees with every position where no mismatch is allowed, so the
        shortest such list gives them all; with mismatches allowed anywhere it agrees with at least one of any
        m + 1 positions (pigeonhole), so the union of the m + 1 shortest lists does. Each candidate is then
        checked against the stored sequence at once.

        Parameters
        ----------
        query : np.ndarray [shape=(L, f)] bool vectors or [shape=(L,)] int codes
            The query's feature sequence, as for :meth:`exact`.
        m : int
            0 <= m < L.
        allowed : array-like of int, optional
            0-based query positions where a mismatch may occur (default: anywhere).

        Returns
        -------
        np.ndarray [shape=(H,)], int64
            Sorted 0-based positions k.

        Examples
        --------
        >>> index = InvertedIndex.from_feature_sequence([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [0, 0]])
        >>> index.exact([1, 3, 2]).tolist(), index.mismatch([1, 3, 2], m=1).tolist()
        ([1], [1])
        >>> index.mismatch([1, 3, 0], m=1).tolist(), index.mismatch([1, 3, 0], m=1, allowed=[0]).tolist()
        ([1], [])
        """
        q = self._query_codes(query)
        n = q.size
        free, anchors = _mismatch_plan(np.array([self.inverted_list(int(c)).size for c in q]), m, allowed)
        cand = np.unique(np.concatenate([self.inverted_list(int(q[a])).astype(np.int64) - a for a in anchors]))
        cand = cand[(cand >= 0) & (cand + n <= self.n_segments)]
        agree = self.codes[cand[:, None] + np.arange(n)] == q
        ok = agree[:, ~free].all(axis=1) & (agree[:, free].sum(axis=1) >= free.sum() - m)
        return self._valid(cand[ok], n)

    def adaptive_mismatch(self, query, selected, m: int = 0, allowed=None) -> np.ndarray:
        """m-mismatch hits on the database segmentation coarsened to the ``selected`` features (§5.2).

        Only the selected features count: the stored segments are joined into maximal runs on which the selected
        features are constant (the segmentation of D under the selected features alone, §4), and a hit is L
        consecutive such runs in one document of which at most ``m`` differ from the query. With ``m = 0`` these
        are the adaptive fuzzy hits of the sets "every vector that agrees with query[l] on the selected features"
        (:meth:`adaptive_fuzzy`). Candidates come from the union lists of few query segments (a hit agrees with
        every position where no mismatch is allowed; with mismatches allowed anywhere, with at least one of any
        m + 1 positions, by pigeonhole); each candidate that starts a coarsened run is walked over its
        neighbouring runs (a compiled loop over the stored sequence).

        Parameters
        ----------
        query : np.ndarray [shape=(L, f)] bool vectors or [shape=(L,)] int codes
            The query's runs under the selected features (bits of other features are ignored), e.g. the codes of
            ``segment(values & keep)`` with ``keep`` true for the selected columns.
        selected : sequence of int
            0-based feature columns of this index that count (the others are "don't care").
        m : int
            0 <= m < L.
        allowed : array-like of int, optional
            0-based query positions where a mismatch may occur (default: anywhere).

        Returns
        -------
        np.ndarray [shape=(H, L+1)], int64
            Rows sorted: per hit the 0-based stored segment where each coarsened run starts, and the index one past
            the end of the last one (as :meth:`adaptive_fuzzy`).

        Raises
        ------
        ParameterError
            No or unknown selected features, ``m`` outside [0, L), allowed positions outside [0, L).
        """
        selected = np.unique(np.asarray(selected, dtype=np.int64))
        if selected.size == 0 or selected.min() < 0 or selected.max() >= self.n_features:
            raise ParameterError(f"selected must name some of the index's feature columns 0..{self.n_features - 1}, "
                                 f"got {selected.tolist()}")  # fmt: skip
        mask = int(np.sum(np.int64(1) << selected))
        q = self._query_codes(query) & mask
        n = q.size
        lists = [np.flatnonzero((self.list_codes & mask) == c) for c in q]
        free, anchors = _mismatch_plan(np.array([np.diff(self.list_offsets)[i].sum() for i in lists]), m, allowed)
        cand, anchor = [], []
        for a in anchors:
            segs = self._gather(lists[a])
            prev = np.maximum(segs - 1, 0)
            new_doc = self.segment_doc[prev] != self.segment_doc[segs]
            new_run = (segs == 0) | new_doc | (self.codes[prev] & mask != q[a])
            cand.append(segs[new_run])
            anchor.append(np.full(cand[-1].size, a))
        cand, anchor = np.concatenate(cand), np.concatenate(anchor)
        out = np.empty((cand.size, n + 1), dtype=np.int64)
        h = _mismatch_walk(self.codes, self.segment_doc, mask, q, free, m, cand, anchor, out)
        rows = out[:h]  # a hit is fixed by the run it starts at: one row per first segment, sorted
        return rows[np.unique(rows[:, 0], return_index=True)[1]]

    # ------------------------------------------------------------------ frames
    def frame_spans(self, first: np.ndarray, stop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frames covered by segments ``first`` .. ``stop - 1``: (start frame, end frame exclusive).

        Parameters
        ----------
        first, stop : array_like of int [shape=(H,)]
            Per hit its first segment and one past its last (e.g. the columns 0 and L of
            :meth:`adaptive_fuzzy`'s rows).

        Returns
        -------
        start, end : np.ndarray [shape=(H,)], int64
            Frames of the indexed values (database-wide for :func:`build`'s indexes), half-open.
        """
        first = np.asarray(first, dtype=np.int64)
        last = np.asarray(stop, dtype=np.int64) - 1
        return self.starts[first], self.starts[last] + self.lengths[last]

    # ------------------------------------------------------------------ storage
    def nbytes(self) -> int:
        """Bytes of what is stored on disk: the lists, segment starts and lengths, document boundaries.

        Returns
        -------
        int
            Bytes of the stored arrays (the ``MB`` of Müller et al. 2005 Table 2 is this / 2^20).
        """
        return int(sum(a.nbytes for a in self._stored().values()))

    def _stored(self) -> dict:
        return {
            "list_codes": self.list_codes,
            "list_offsets": self.list_offsets,
            "positions": self.positions,
            "starts": self.starts.astype(np.int32),
            "lengths": self.lengths.astype(np.int32),
            "doc_first_segment": self.doc_first_segment,
        }

    def save(self, path) -> None:
        """Write the index to ``path`` atomically (:func:`mocapviz.db.arrays.save_arrays`).

        Parameters
        ----------
        path : str or os.PathLike
            The file (its folder is created); its header holds the format, names, meta and the arrays' sha256.
        """
        header = {"n_features": self.n_features, "feature_names": list(self.feature_names), "meta": self.meta}
        save_arrays(path, self._stored(), header, FORMAT, VERSION)

    @classmethod
    def load(cls, path) -> InvertedIndex:
        """Read an index written by :meth:`save`.

        Parameters
        ----------
        path : str or os.PathLike
            A file written by :meth:`save`.

        Returns
        -------
        InvertedIndex

        Raises
        ------
        MotionDBError
            Missing or unreadable file, another format, or arrays that differ from those written (their sha256 is
            kept in the header and checked here); another version is stale (a StaleDataError).
        """
        arrays, header = load_arrays(path, FORMAT, VERSION, "index", _REBUILD)
        codes = np.repeat(arrays["list_codes"], np.diff(arrays["list_offsets"]))
        seq_codes = np.empty_like(codes)
        seq_codes[arrays["positions"]] = codes
        seq = FeatureSequence(seq_codes, arrays["starts"], arrays["lengths"], header["n_features"])
        return cls(seq, arrays["doc_first_segment"], header["feature_names"], header["meta"])


# ---------------------------------------------------------------------- MotionDB indexes
def index_path(db, relational_set: str, group: str) -> Path:
    """Where the index of one feature group of a MotionDB is stored.

    Parameters
    ----------
    db : MotionDB
        The database.
    relational_set : {"2005", "2006"}
        The relational set.
    group : {"lower", "upper", "mix"}
        The feature group.

    Returns
    -------
    pathlib.Path
        ``DB/index/relational-<set>-<group>.npz`` (:func:`mocapviz.db.layout.index_file`).
    """
    return layout.index_file(db.path, relational_set, group)


def feature_group_values(values: np.ndarray, relational_set: str = "2005") -> dict:
    """The columns of each feature group (lower, upper, mix) of a set's feature values.

    Parameters
    ----------
    values : np.ndarray [shape=(N, f)], bool
        :func:`mocapviz.features.relational_features` of the set.
    relational_set : {"2005", "2006"}
        The set of ``values``' columns.

    Returns
    -------
    dict
        Group -> (member names, values of the members [shape=(N, f_group)]; a view when they are adjacent).
    """
    from ..features import feature_groups, feature_names

    names = feature_names(relational_set)
    out = {}
    for group, members in feature_groups(relational_set).items():
        cols = [names.index(n) for n in members]
        adjacent = cols == list(range(cols[0], cols[0] + len(cols)))
        out[group] = (members, values[:, cols[0] : cols[0] + len(cols)] if adjacent else values[:, cols])
    return out


def build(db, relational_set: str = "2005", progress: bool = True, values: np.ndarray | None = None,
          scheduler=None, save: bool = True) -> dict:
    """Build and save one inverted index per feature group (lower, upper, mix) over a MotionDB (§5.3).

    Parameters
    ----------
    db : MotionDB
        The database (writable when ``save``).
    relational_set : {"2005", "2006"}
        The relational set whose groups are indexed.
    progress : bool
        Progress bar over the documents while the features are computed.
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's relational features if already computed.
    scheduler : None, "local", str or dask.distributed.Client
        Compute the features as Dask tasks (see :func:`mocapviz.features.relational_features`); default: threads here.
        The index itself is built and written here, each file renamed into place when complete.
    save : bool
        Write the indexes into ``DB/index/`` (False: in memory only, e.g. for a read-only database).

    Returns
    -------
    dict
        Group name -> InvertedIndex (segment positions over the whole database; documents kept apart).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §5.3 (one index per feature group, I_l, I_u, I_m) and §6.1 (Table 2).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> indexes = build(db, save=False, progress=False)  # in memory: nothing written
    >>> {group: (index.n_features, index.n_segments) for group, index in indexes.items()}
    {'lower': (11, 338), 'upper': (12, 281), 'mix': (8, 144)}
    >>> lower = indexes["lower"]
    >>> query = lower.codes[lower.doc_first_segment[7]:][:4]  # the first 4 segments of document 7
    >>> db.document_of(lower.starts[lower.exact(query)]).tolist()  # the documents of the exact hits
    [7]
    """
    from ..features import relational_features

    if values is None:
        values, _ = relational_features(db, relational_set, progress=progress, scheduler=scheduler)
    doc_starts = db.documents["start"].to_numpy()
    out = {}
    for group, (members, group_values) in feature_group_values(values, relational_set).items():
        index = InvertedIndex.from_features(group_values, doc_starts, members, _meta(db, relational_set, group))
        if save:
            index.save(index_path(db, relational_set, group))
        out[group] = index
    return out


def load_or_build(db, relational_set: str = "2005", save: bool = True, progress: bool = False) -> dict:
    """The saved indexes of a MotionDB when current (:func:`load`), else extended with the documents appended since
    they were built (:func:`extend`), else built now (:func:`build`); saved unless ``save`` is False (then nothing
    is written: a read-only database can be queried) or the stored ones are of a later generation (this ``db`` is
    an older reader's).

    Parameters
    ----------
    db : MotionDB
        The database.
    relational_set : {"2005", "2006"}
        The relational set.
    save : bool
        Write the indexes when they are built here.
    progress : bool
        Progress bar while the features are computed.

    Returns
    -------
    dict
        Group name -> InvertedIndex.
    """
    def extended_or_built() -> dict:
        try:
            return extend(db, relational_set, save=save, progress=progress)
        except MotionDBError:  # none stored, or not over the first documents of this database: built whole
            return build(db, relational_set, progress=progress, save=save and not _newer(db, relational_set))

    return store.load_or_build(lambda: load(db, relational_set), extended_or_built)


def _meta(db, relational_set: str, group: str) -> dict:
    """What an index records of the database it was built for: its generation, frames and documents (their
    :meth:`~mocapviz.db.database.MotionDB.prefix_digest`, so that :func:`extend` can tell an appended database)."""
    return {"generation": db.manifest["generation"], "n_frames": db.n_frames, "n_documents": len(db),
            "documents": db.prefix_digest(len(db)), "relational_set": relational_set, "group": group}  # fmt: skip


def _newer(db, relational_set: str) -> bool:
    """Whether a stored index of the set was built for a later generation than ``db``'s (a reader of an older
    generation that builds its own must not replace it)."""
    from ..features import feature_groups

    path = index_path(db, relational_set, next(iter(feature_groups(relational_set))))
    try:
        return InvertedIndex.load(path).meta.get("generation", -1) > db.manifest["generation"]
    except MotionDBError:
        return False


def extend(db, relational_set: str = "2005", save: bool = True, progress: bool = False) -> dict:
    """The saved indexes of an earlier generation of a MotionDB brought up to date incrementally: the documents
    appended since they were built are computed alone, their segments appended (:meth:`InvertedIndex.appended`),
    the recorded generation advanced. Equal to :func:`build` of the whole database.

    Parameters
    ----------
    db : MotionDB
        The database, grown by an ingest since the indexes were built (or not: then they are only re-stamped).
    relational_set : {"2005", "2006"}
        The relational set.
    save : bool
        Write the extended indexes (atomically, each group's file replaced whole: a reader's copy stays intact).
    progress : bool
        Progress bar while the new documents' features are computed.

    Returns
    -------
    dict
        Group name -> InvertedIndex over the whole database.

    Raises
    ------
    MotionDBError
        No index stored, or one that was not built over the first documents of this database (another database,
        or one built before indexes recorded their documents: a :class:`~mocapviz.errors.StaleDataError`); build
        it whole (:func:`build`).

    Examples
    --------
    >>> import tempfile, shutil
    >>> from mocapviz import MotionDB
    >>> from mocapviz.io import datasets
    >>> amc = sorted((datasets.sample() / "hdm05-cut" / "amc").glob("*.amc"))
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     db = MotionDB.ingest(amc[:3], f"{tmp}/db.mdb", progress=False)
    ...     _ = build(db, progress=False)
    ...     db = db.append(amc[3:5], progress=False)  # two more documents: the indexes are stale
    ...     grown = extend(db)  # their frames alone computed and appended
    ...     whole = build(db, save=False, progress=False)
    ...     print(all((grown[g].positions == whole[g].positions).all() for g in whole), load(db)["lower"].meta["n_documents"])
    True 5
    """
    from ..db.shards import shard_view
    from ..features import feature_groups, relational_features

    stored = {group: InvertedIndex.load(index_path(db, relational_set, group)) for group in feature_groups(relational_set)}
    metas = [index.meta for index in stored.values()]
    if any((m.get("n_documents"), m.get("documents")) != (metas[0].get("n_documents"), metas[0].get("documents"))
           for m in metas):  # fmt: skip
        raise StaleDataError(f"{db.path}: the {relational_set} indexes of the groups were built for different documents")
    added = db.added_since(metas[0].get("n_documents"), metas[0].get("n_frames"), metas[0].get("documents"))
    old_frames = int(metas[0]["n_frames"])
    new = {}
    if len(added):
        view = shard_view(db, added, labels=False)
        new = build(view, relational_set, progress=progress, save=False,
                    values=relational_features(view, relational_set, progress=progress)[0])
    out = {}
    for group, index in stored.items():
        meta = _meta(db, relational_set, group)
        if new:
            index = index.appended(new[group], old_frames, meta)
        index.meta = meta
        out[group] = index
        if save:
            out[group].save(index_path(db, relational_set, group))
    return out


def load(db, relational_set: str = "2005") -> dict:
    """The saved indexes of a MotionDB, one per feature group.

    Parameters
    ----------
    db : MotionDB
        The database.
    relational_set : {"2005", "2006"}
        The relational set.

    Returns
    -------
    dict
        Group name (``"lower"``, ``"upper"``, ``"mix"``) -> InvertedIndex.

    Raises
    ------
    MotionDBError
        No index built yet, or built for an earlier state of the database (a
        :class:`~mocapviz.errors.StaleDataError`): the message says to run ``mocapviz index DB``.
    """
    from ..features import feature_groups

    option = "" if relational_set == "2005" else f" --relational-set {relational_set}"
    how = f"`mocapviz index {db.path}{option}` or mocapviz.relational.index.build(db, {relational_set!r})"
    out = {}
    for group in feature_groups(relational_set):
        path = index_path(db, relational_set, group)
        if not path.is_file():
            raise MotionDBError(f"{db.path} has no {relational_set} relational index; build it with {how}")
        index = InvertedIndex.load(path)
        if index.meta.get("generation") != db.manifest["generation"] or index.meta.get("n_frames") != db.n_frames:
            raise StaleDataError(f"{path} was built before the database last changed; rebuild it with {how}")
        out[group] = index
    return out


__all__ = ["InvertedIndex", "build", "decode", "extend", "index_path", "load", "merge_adjacent"]
