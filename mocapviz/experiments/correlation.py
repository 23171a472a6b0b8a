"""Rank correlations between feature sets and distance measures: Krüger, Tautges, Weber & Zinke 2010, §3.3, Fig. 2.

TABLE1_SETS            the nine numeric sets of Table 1, in its order (the rows of the pose-based comparison on a
                       large database).
CORRELATION_MEASURES   the 14 measures of Fig. 2 in the figure's order: TABLE1_SETS and the five distance measures of
                       §3.1.
available_measures     the measures a MotionDB supports (Deuler needs AMC files; Dquat, Dwb need rotations).
correlation_sample     the sample database: clips of the labelled classes with at least 8 clips (the paper: 76
                       hand-cut HDM05 clips of 9 classes).
pose_correlations      Fig. 2, pose-based: for random query frames the k nearest frames by the row measure;
                       Spearman's rho between their row-measure and their column-measure distances, averaged.
segment_correlations   §3.3 "Motion segment based comparisons": DTW distances of all pairs of clips per measure; per
                       clip, rho over the first n clips of the row measure's ranking, averaged; retrieval precision.
rank_correlations      all of §3.3 at once: the sample, pose-based on it and on a large database, segment-based.
PAPER_FIG2_CLAIMS      the paper's statements about Fig. 2 (its numbers are in the figure only, not in the text).
paper_claims           our values beside each statement.

Measures
--------
Every measure is a frame descriptor and a pairwise distance on descriptors, in one table (``_MEASURES``) that the
pose- and segment-based experiments share (the one-to-many form of a distance is one row of the pairwise one,
:mod:`mocapviz.features.distances`):

==============  ====================================================  ==============================
measure         descriptor of database frames                         distance
==============  ====================================================  ==============================
Fp8 ... F30x3E  ``numeric_of(db, name, pca)`` rows, cm                Euclidean (scipy ``cdist``)
Deuler          the AMC files' Euler channels, degrees:               ``deuler_pairwise`` (wrapped)
                ``read_document(path, fps).euler`` rows
Dquat           ``db.quaternions`` rows (24 local rotations)          ``dquat_pairwise`` (weights 1)
Dpc1, Dpc11     ``window_clouds(db.positions, n, frames, lengths)``   ``dpc_pairwise``, cm²
Dwb             ``lee_frames(db.quaternions, fps, lengths, frames)``  ``dwb_pairwise`` (Wang &
                                                                      Bodenheimer's weights)
==============  ====================================================  ==============================

Descriptors are built only for the frames a computation needs (the query frames and their neighbours, or the
frames of the sample clips), in blocks, so the distance measures also run on databases of 500k+ frames.
"""

from __future__ import annotations

import itertools
import math
import time
import warnings

import numpy as np
import pandas as pd
from scipy.spatial.distance import cdist
from scipy.stats import rankdata

from ..db.ingest import read_document
from ..errors import ParameterError
from ..features.distances import deuler_pairwise, dpc_pairwise, dquat_pairwise, dwb_pairwise, lee_frames, window_clouds
from ..features.numeric import default_pca, numeric_of
from ..match.time_warping import dtw
from ..parallel import progress_bar
from ..similarity.knn import KnnIndex
from ..validation import count

__all__ = [
    "CORRELATION_MEASURES", "DISTANCE_MEASURES", "PAPER_FIG2_CLAIMS", "TABLE1_SETS", "available_measures",
    "correlation_sample", "paper_claims", "pose_correlations", "pose_limits", "rank_correlations",
    "segment_correlations",
]  # fmt: skip

TABLE1_SETS = ("Fp8", "Fp16", "Fp25", "F15E", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E")  # Table 1's order
DISTANCE_MEASURES = ("Deuler", "Dquat", "Dpc1", "Dpc11", "Dwb")
CORRELATION_MEASURES = TABLE1_SETS + DISTANCE_MEASURES  # Fig. 2's order
_BLOCK_FRAMES = 1 << 15  # descriptors of at most this many frames at once (Dpc11: 32768 x 264 x 3 float64 = 200 MB)
_BLOCK_PAIRS = 1 << 22  # distances of at most this many (query, frame) pairs at once (32 MB)


# ============================================================================ measures: descriptors and distances
class _Descriptors:
    """Per-frame descriptors of one MotionDB for every measure of :data:`CORRELATION_MEASURES`.

    Holds what several calls share: the PCA reference, the last numeric feature set used (one at a time, so that
    a large database never holds more than one set), and the Euler channels of the AMC files read so far.
    """

    def __init__(self, db, measures, pca):
        if db.fps is None:
            raise ParameterError(f"{db.path}: the documents have different frame rates; ingest with one rate (fps=30)")
        self.db, self.fps = db, float(db.fps)
        self.pca = default_pca(db) if pca is None and any(m.startswith("Fp") for m in measures) else pca
        self.starts = db.documents["start"].to_numpy(np.int64)
        self.lengths = db.documents["n_frames"].to_numpy(np.int64)
        self._numeric: tuple[str | None, np.ndarray | None] = (None, None)
        self._euler: dict[int, np.ndarray] = {}

    def numeric(self, name: str) -> np.ndarray:
        """Feature set ``name`` of every frame of the database, [shape=(N, d)], float32, cm."""
        if self._numeric[0] != name:
            self._numeric = (None, None)  # free the previous set first
            self._numeric = (name, numeric_of(self.db, name, self.pca))
        return self._numeric[1]

    def euler(self, frames: np.ndarray) -> np.ndarray:
        """The source files' Euler channels (degrees) of database frames, [shape=(F, C)]; each document's file is
        read once (at the database's frame rate)."""
        doc = np.searchsorted(self.starts, frames, side="right") - 1
        out = None
        for d in np.unique(doc):
            if d not in self._euler:
                self._euler[d] = self._read_euler(int(d))
            rows = doc == d
            if out is None:
                out = np.empty((len(frames), self._euler[d].shape[1]), dtype=np.float32)
            out[rows] = self._euler[d][frames[rows] - self.starts[d]]
        return np.empty((0, 0), dtype=np.float32) if out is None else out

    def _read_euler(self, d: int) -> np.ndarray:
        row = self.db.documents.iloc[d]
        motion, _ = read_document(row["path"], fps=self.fps)
        if motion.euler is None or motion.n_frames != row["n_frames"]:
            raise ParameterError(
                f"Deuler: {row['path']} read at {self.fps:g} Hz has "
                f"{'no Euler channels' if motion.euler is None else f'{motion.n_frames} frames'}, the database's "
                f"document {row['doc_id']} has {row['n_frames']} frames (the file changed since ingest?)"
            )
        if self._euler:
            d0, first = next(iter(self._euler.items()))
            if first.shape[1] != motion.euler.shape[1]:
                raise ParameterError(
                    f"Deuler compares Euler channels of one skeleton, but {row['path']} has {motion.euler.shape[1]} "
                    f"channels and {self.db.documents.iloc[d0]['path']} {first.shape[1]}"
                )
        return motion.euler

    def __call__(self, measure: str, frames: np.ndarray) -> np.ndarray:
        """Descriptors of ``measure`` of database frames ``frames`` [shape=(F,)], int: see the module docstring."""
        return _MEASURES[measure][0](self, np.asarray(frames, dtype=np.int64))

    @staticmethod
    def pairwise(measure: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances [shape=(len(a), len(b))], float64, of ``measure`` between two descriptor arrays."""
        return _MEASURES[measure][1](a, b)


def _euclidean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return cdist(a, b)  # per pair sums of squared differences: exact, no |a|² - 2ab + |b|² cancellation


_MEASURES = {
    **{name: (lambda ctx, f, name=name: ctx.numeric(name)[f], _euclidean) for name in TABLE1_SETS},
    "Deuler": (lambda ctx, f: ctx.euler(f), deuler_pairwise),
    "Dquat": (lambda ctx, f: ctx.db.quaternions[f], dquat_pairwise),
    "Dpc1": (lambda ctx, f: window_clouds(ctx.db.positions[:], 1, f, ctx.lengths), dpc_pairwise),
    "Dpc11": (lambda ctx, f: window_clouds(ctx.db.positions[:], 11, f, ctx.lengths), dpc_pairwise),
    "Dwb": (lambda ctx, f: lee_frames(ctx.db.quaternions[:], ctx.fps, ctx.lengths, f), dwb_pairwise),
}


def _check_measures(names, what: str) -> tuple[str, ...]:
    names = (names,) if isinstance(names, str) else tuple(names)
    unknown = [m for m in names if m not in _MEASURES]
    if unknown:
        raise ParameterError(f"unknown measure(s) {', '.join(map(repr, unknown))} in {what}; known: "
                         f"{', '.join(CORRELATION_MEASURES)}")  # fmt: skip
    if not names or len(set(names)) != len(names):
        raise ParameterError(f"{what} must name at least one measure, each once; got {names}")
    return names


def available_measures(db) -> tuple[str, ...]:
    """The measures of :data:`CORRELATION_MEASURES` a MotionDB supports, in that order.

    The feature sets and Dpc1 always; Dpc11 when every document has at least 11 frames (its window); Dquat and Dwb
    when every document has joint rotations (a MotionDB stores NaN for a source without them) and all documents
    come in one format; Deuler when every document is an AMC file (§3.1: "the Euler angles in the standard asf/amc
    representation"; the files are read again, and must all have one skeleton's channels).

    Why one format for Dquat and Dwb: they compare local joint rotations, which are relative to each rig's rest
    pose. The ASF skeletons of HDM05 and CMU share one convention (random frames of the two are about 9 rad apart
    in Dquat, as within each), a BVH rig such as Bandai Namco's another: an HDM05 frame and its nearest Bandai
    frame by F15E are 27 rad apart in Dquat, against 0.6 rad for its nearest HDM05 frame, whatever the poses.
    The test is by format, a proxy for the rig: a database mixing several BVH rigs passes it.

    Parameters
    ----------
    db : MotionDB
        The database.

    Returns
    -------
    tuple of str
        Measure names, in the order of :data:`CORRELATION_MEASURES`.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> available_measures(MotionDB.sample())[-5:]  # the sample's files are all AMC: every measure
    ('Deuler', 'Dquat', 'Dpc1', 'Dpc11', 'Dwb')
    """
    docs = db.documents
    rotations = (docs["format"].nunique() == 1
                 and not np.isnan(db.quaternions[docs["start"].to_numpy(np.int64), 0, 0]).any())  # fmt: skip
    ok = {"Dpc11": bool((docs["n_frames"] >= 11).all()), "Dquat": rotations, "Dwb": rotations,
          "Deuler": bool((docs["format"] == "amc").all())}  # fmt: skip
    return tuple(m for m in CORRELATION_MEASURES if ok.get(m, True))


def _documents(db, docs) -> tuple[pd.DataFrame, np.ndarray]:
    """The documents meant by ``docs`` (None: all; a DataFrame with ``doc_id``; doc ids) in frame order, and their
    database frames [shape=(F,)], int64, increasing."""
    table = db.documents
    if docs is not None:
        ids = docs["doc_id"] if isinstance(docs, pd.DataFrame) else pd.Series(np.asarray(docs).ravel())
        missing = sorted(set(ids.tolist()) - set(table["doc_id"].tolist()))
        if missing:
            raise ParameterError(f"{db.path}: no document(s) {missing[:10]}")
        table = table[table["doc_id"].isin(ids.tolist())]
    table = table.sort_values("start")
    if table.empty:
        raise ParameterError("no documents selected")
    starts, lengths = table["start"].to_numpy(np.int64), table["n_frames"].to_numpy(np.int64)
    return table, np.repeat(starts - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())


def _check_deuler(table: pd.DataFrame, measures) -> None:
    if "Deuler" in measures and not (table["format"] == "amc").all():
        bad = table[table["format"] != "amc"].iloc[0]
        raise ParameterError(
            f"Deuler compares the Euler angles of ASF/AMC files (§3.1) but document {bad['doc_id']} ({bad['path']}) "
            f"is {bad['format']}; leave Deuler out of the measures for this database (see available_measures)"
        )


def _spearman(ranks_a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Spearman's rho per row: ``ranks_a`` [shape=(Q, n)], centred ranks of one side (:func:`_centred_ranks`),
    against the values ``b`` [shape=(Q, n)]. Ties get average ranks; rho = cov / sqrt(var_a var_b) is exactly 1
    for equal rankings; NaN where a side is constant. Returns [shape=(Q,)], in [-1, 1]."""
    ranks_b = _centred_ranks(b)
    cov = np.einsum("qn,qn->q", ranks_a, ranks_b)
    var = np.einsum("qn,qn->q", ranks_a, ranks_a) * np.einsum("qn,qn->q", ranks_b, ranks_b)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.clip(cov / np.sqrt(var), -1.0, 1.0)


def _nanmean(x: np.ndarray) -> np.ndarray:
    """Mean over the last axis ignoring NaN (an undefined rho), NaN where all are."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(x, axis=-1)


def _centred_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks along the last axis (ties averaged) minus their mean (n + 1) / 2."""
    return rankdata(x, axis=-1) - (x.shape[-1] + 1) / 2.0


# ============================================================================ correlation sample
def correlation_sample(db, clips_per_class: int = 8, min_clips: int = 8, max_classes: int = 11,
                       seed: int = 0) -> pd.DataFrame:  # fmt: skip
    """The sample database of Fig. 2 and §3.3 (Krüger et al. 2010): clips of the well-represented classes.

    The paper used "76 hand-cut motion sequences from the HDM05 database ... nine motion classes where at least
    eight motions of every class were available". Here: the classes (``label``) with at least
    ``max(min_clips, clips_per_class)`` clips, the ``max_classes`` largest of them (ties by name), and from each
    ``clips_per_class`` clips drawn at random. On the 287 HDM05 cut clips all 11 classes qualify: 88 clips.

    Parameters
    ----------
    db : MotionDB
        Labelled (``label`` column).
    clips_per_class : int
        Clips drawn per class, >= 1.
    min_clips : int
        A class needs at least this many clips.
    max_classes : int
        At most this many classes, the largest.
    seed : int
        The draw is reproducible: the same seed gives the same clips.

    Returns
    -------
    pandas.DataFrame
        The chosen rows of ``db.documents`` (doc_id, path, start, n_frames, fps, label, ...), class by class
        (largest first), by doc_id within a class.

    Raises
    ------
    ValueError
        No labels, fewer than 2 qualifying classes, or counts < 1.
    """
    if clips_per_class < 1 or max_classes < 2:
        raise ParameterError(f"clips_per_class must be >= 1 and max_classes >= 2; got {clips_per_class}, {max_classes}")
    labels = db.documents["label"]
    if labels.isna().all():
        raise ParameterError(f"{db.path}: the documents have no labels (ingest with a label table)")
    need = max(min_clips, clips_per_class)
    counts = labels.value_counts()
    counts = counts[counts >= need]
    if len(counts) < 2:
        raise ParameterError(f"{db.path}: {len(counts)} class(es) with at least {need} clips; the rank correlations "
                         f"of §3.3 need at least 2 (largest classes: {labels.value_counts().head(3).to_dict()})")  # fmt: skip
    classes = sorted(counts.index, key=lambda c: (-counts[c], str(c)))[:max_classes]
    rng = np.random.default_rng(seed)
    parts = []
    for c in classes:
        rows = db.documents[labels == c].sort_values("doc_id")
        parts.append(rows.iloc[np.sort(rng.choice(len(rows), clips_per_class, replace=False))])
    return pd.concat(parts, ignore_index=True)


# ============================================================================ Fig. 2: pose-based
def _query_block(per_query: int, n_frames: int) -> int:
    """Queries per block: the union of their neighbours' frames (at most ``per_query`` each, ``n_frames`` in all)
    stays below ``_BLOCK_FRAMES`` descriptors, their distance matrix below ``_BLOCK_PAIRS`` entries."""
    if n_frames <= _BLOCK_FRAMES:
        return max(1, _BLOCK_PAIRS // n_frames)
    return max(1, min(_BLOCK_FRAMES // per_query, math.isqrt(_BLOCK_PAIRS // per_query)))


def _nearest(ctx: _Descriptors, measure: str, queries: np.ndarray, frames: np.ndarray, k: int):
    """The k nearest of ``frames`` to each query frame by ``measure``, the query itself left out.

    Feature sets: a kd-tree (:class:`mocapviz.similarity.knn.KnnIndex`) over ``frames``; distance measures: brute force, the
    pairwise distances of blocks of queries against blocks of frames, keeping the k smallest.

    Returns
    -------
    distances : np.ndarray [shape=(Q, k)], float64, increasing (units of the measure).
    neighbours : np.ndarray [shape=(Q, k)], int64 database frames; equal distances by frame number (brute force).
    """
    if measure in TABLE1_SETS:
        x = ctx.numeric(measure)
        valid = np.zeros(len(x), dtype=bool)
        valid[frames] = True
        return KnnIndex(x, valid=valid).query(x[queries], k, exclude=np.stack([queries, queries + 1], axis=1))
    f_step = min(len(frames), _BLOCK_FRAMES)
    q_step = max(1, _BLOCK_PAIRS // f_step)
    dist, near = np.empty((len(queries), k)), np.empty((len(queries), k), dtype=np.int64)
    for q0 in range(0, len(queries), q_step):
        q = queries[q0 : q0 + q_step]
        desc_q = ctx(measure, q)
        best_d, best_i = np.full((len(q), 0), np.inf), np.full((len(q), 0), -1, dtype=np.int64)
        for f0 in range(0, len(frames), f_step):
            f = frames[f0 : f0 + f_step]
            d = ctx.pairwise(measure, desc_q, ctx(measure, f))
            d[q[:, None] == f[None]] = np.inf  # the query itself
            best_d = np.concatenate([best_d, d], axis=1)
            best_i = np.concatenate([best_i, np.broadcast_to(f, d.shape)], axis=1)
            order = np.lexsort((best_i, best_d), axis=1)[:, :k]
            best_d, best_i = np.take_along_axis(best_d, order, axis=1), np.take_along_axis(best_i, order, axis=1)
        dist[q0 : q0 + q_step], near[q0 : q0 + q_step] = best_d, best_i
    return dist, near


def pose_limits(db, docs=None) -> dict[str, tuple[int, int]]:
    """The ranges :func:`pose_correlations` accepts for ``k`` and ``n_queries`` on the frames of ``docs``: k from 1 to
    the frames less the query, the queries from 1 to the frames (drawn without replacement). The one statement of
    both limits: the function checks them, the dashboard's boxes take them.

    Parameters
    ----------
    db : MotionDB
    docs : pd.DataFrame (``doc_id`` column) or sequence of int, optional
        As for :func:`pose_correlations` (default all documents).

    Returns
    -------
    dict
        ``{"k": (1, F - 1), "n_queries": (1, F)}`` for the F frames of ``docs``.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> pose_limits(db, [7])  # document 7: 129 frames
    {'k': (1, 128), 'n_queries': (1, 129)}
    """
    frames = len(_documents(db, docs)[1])
    return {"k": (1, frames - 1), "n_queries": (1, frames)}


def _check_pose_limits(db, docs, k, n_queries) -> None:
    """A ParameterError naming k or n_queries outside :func:`pose_limits`."""
    limits = pose_limits(db, docs)
    count(k, "k", *limits["k"], most_is="the frames of the documents, less the query")
    count(n_queries, "n_queries", *limits["n_queries"], most_is="the frames of the documents")


def pose_correlations(db, rows=CORRELATION_MEASURES, columns=CORRELATION_MEASURES, docs=None, n_queries: int = 1024,
                      k: int = 256, pca=None, seed: int = 0, progress: bool = False) -> pd.DataFrame:  # fmt: skip
    """Pose-based rank correlations of Fig. 2 (Krüger et al. 2010, §3.3 "Pose-based comparisons").

    Fig. 2: "Average values for 1024 random samples choosing 256 nearest neighbors according to the feature set
    given in the vertical axis with the distance measure given in the horizontal axis." For each of ``n_queries``
    random frames of ``docs``: the k nearest other frames of ``docs`` by the row measure (a kd-tree for the feature
    sets, brute force for the distance measures); the row measure's distances of these k frames (those of the
    search) and the column measure's distances of the same k frames from the query; Spearman's rho between the
    two (ranks with ties averaged); the mean over the queries. The matrix is not symmetric: the neighbours are
    always chosen by the row measure. The diagonal is exactly 1.

    Scaling (the paper's second variant, "pose-based comparisons on large databases", rows = the kd-tree feature
    sets): queries are processed in blocks; for a column measure the descriptors of only the block's queries and
    neighbours are built (never of all frames), so Dquat, Dpc and Dwb columns run on databases of 500k+ frames in
    bounded memory. Deuler reads the AMC files of the documents whose frames are needed (each once). A feature set
    is computed (or memory-mapped when stored, :func:`mocapviz.features.numeric.store_numeric`) once per row and
    once per column. Rows that are distance measures search all frames of ``docs`` by brute force (pairwise
    distances in blocks): meant for a small sample.

    Parameters
    ----------
    db : MotionDB
        At one frame rate (the paper: 30 Hz).
    rows, columns : sequence of str
        Measures of :data:`CORRELATION_MEASURES` (default all 14, in Fig. 2's order).
    docs : pd.DataFrame (``doc_id`` column) or sequence of int, optional
        The documents to search and draw queries from (default all): e.g. :func:`correlation_sample`.
    n_queries : int
        Random query frames (the paper: 1024), drawn without replacement; at most the frames of ``docs``
        (:func:`pose_limits`).
    k : int
        Neighbours per query (the paper: 256); at most the frames of ``docs`` less one (:func:`pose_limits`).
    pca : PCAModel, optional
        Reference of the Fp sets (the paper: all of HDM05); default :func:`mocapviz.features.numeric.default_pca`.
    seed : int
        Seed of the random query frames.
    progress : bool
        Progress bars (tqdm) over the rows and columns.

    Returns
    -------
    pandas.DataFrame [shape=(len(rows), len(columns))]
        Mean rho in [-1, 1] (NaN only if every query had a constant side); index named "neighbours by", columns
        "compared with". ``attrs``: ``n_queries``, ``k``, ``frames`` (frames searched), ``documents``, ``queries``
        (the query frames, list of int), ``seconds`` ({"neighbours": {row: s}, "distances": {column: s}}).

    Raises
    ------
    ValueError
        An unknown measure (named), k or n_queries out of range for the frames of ``docs``, documents at different
        frame rates, Deuler on a database with non-AMC documents, or an AMC file that no longer matches its
        document.
    """
    rows, columns = _check_measures(rows, "rows"), _check_measures(columns, "columns")
    table, frames = _documents(db, docs)
    _check_deuler(table, rows + columns)
    _check_pose_limits(db, docs, k, n_queries)
    ctx = _Descriptors(db, rows + columns, pca)
    queries = np.sort(np.random.default_rng(seed).choice(frames, n_queries, replace=False))
    seconds = {"neighbours": {}, "distances": {}}
    neighbours, own = {}, {}
    for row in progress_bar(rows, desc="nearest frames", unit="measure", disable=not progress):
        t0 = time.perf_counter()
        own_d, neighbours[row] = _nearest(ctx, row, queries, frames, k)
        own[row] = (own_d, _centred_ranks(own_d))
        seconds["neighbours"][row] = time.perf_counter() - t0
    rho = np.zeros((len(rows), len(columns)))
    step = _query_block(len(rows) * k, len(frames))
    columns_bar = progress_bar(columns, desc="distances of the neighbours", unit="measure", disable=not progress)
    for c, col in enumerate(columns_bar):
        t0 = time.perf_counter()
        others = [row for row in rows if row != col]  # the column's own row keeps the distances of its search
        per_query = {row: np.empty(n_queries) for row in rows}
        for q0 in range(0, n_queries, step):
            block = slice(q0, q0 + step)
            if col in rows:
                per_query[col][block] = _spearman(own[col][1][block], own[col][0][block])
            if not others:
                continue
            near = np.stack([neighbours[row][block] for row in others])  # (R', B, k)
            union, where = np.unique(near, return_inverse=True)  # every frame's descriptor built once per block
            d = ctx.pairwise(col, ctx(col, queries[block]), ctx(col, union))  # (B, len(union))
            d = d[np.arange(d.shape[0])[:, None], where.reshape(near.shape)]  # (R', B, k)
            for row, dist in zip(others, d):
                per_query[row][block] = _spearman(own[row][1][block], dist)
        rho[:, c] = [_nanmean(per_query[row]) for row in rows]
        seconds["distances"][col] = time.perf_counter() - t0
    out = pd.DataFrame(rho, index=pd.Index(rows, name="neighbours by"), columns=pd.Index(columns, name="compared with"))
    out.attrs.update(n_queries=n_queries, k=k, frames=len(frames), documents=len(table), queries=queries.tolist(),
                     seconds=seconds)  # fmt: skip
    return out


# ============================================================================ §3.3: motion segment based
def segment_correlations(db, docs, measures=CORRELATION_MEASURES, n_first: int = 8, pca=None,
                         progress: bool = False) -> pd.DataFrame:  # fmt: skip
    """Motion-segment-based rank correlations (Krüger et al. 2010, §3.3 "Motion segment based comparisons").

    "We performed a dynamic time warping between each pair of 76 motion sequences for every feature set and
    distance measure. Based on this DTW-distances (accumulated pose distances along the warping path) we performed a
    ranking. ... we computed rank correlations for the first eight motions of this ranking." Per measure, the
    frame distances of all frames of the clips against each other are computed once (one pairwise matrix over the
    sample, e.g. 88 clips, about 5,500 frames at 30 Hz: 30M pairs) and each pair of clips is aligned by DTW
    (:func:`mocapviz.match.dtw`, basic steps) on its block of that matrix. For a clip and a row measure, the other
    clips are ranked by the row measure's DTW distance; over the first ``n_first`` of them, Spearman's rho between
    the row measure's and the column measure's DTW distances; the mean over the clips.

    DTW distances are the accumulated local distances along the optimal path, **not normalised** by the path
    length: that is the paper's definition ("accumulated pose distances along the warping path"), and it is what
    ranks clips in :func:`mocapviz.match.subsequence_dtw` too. Longer clips thus get larger distances; every
    measure shares that bias, which raises all correlations a little. DTW with basic steps on a symmetric local
    distance is symmetric, so each pair is aligned once.

    Parameters
    ----------
    db : MotionDB
        At one frame rate.
    docs : pd.DataFrame (``doc_id``, ``label``) or sequence of int
        The clips, e.g. :func:`correlation_sample`; at least ``n_first + 1``.
    measures : sequence of str
        Rows and columns (default all 14 of :data:`CORRELATION_MEASURES`).
    n_first : int
        Clips of each ranking compared (the paper: 8, the least number of clips per class).
    pca : PCAModel, optional
        Reference of the Fp sets; default :func:`mocapviz.features.numeric.default_pca`.
    progress : bool
        Progress bar over the measures.

    Returns
    -------
    pandas.DataFrame [shape=(len(measures), len(measures))]
        Mean rho in [-1, 1]; index "neighbours by" (the ranking measure), columns "compared with". ``attrs``:
        ``clips``, ``frames``, ``n_first``, ``precision`` (pd.Series per measure: the share of the first
        ``n_first`` clips of each ranking with the clip's own label, averaged over the clips), ``chance`` (that
        share for a random ranking), ``dtw`` ({measure: pd.DataFrame (clips x clips) of DTW distances, indexed by
        doc_id; 0 on the diagonal}), ``seconds`` (pd.DataFrame per measure: ``matrix``, the pairwise frame
        distances, and ``dtw``).

    Raises
    ------
    ValueError
        An unknown measure, fewer than ``n_first + 1`` clips, n_first < 2, documents at different rates, Deuler on
        non-AMC documents.
    """
    measures = _check_measures(measures, "measures")
    table, frames = _documents(db, docs)
    _check_deuler(table, measures)
    n = len(table)
    if not 2 <= n_first < n:
        raise ParameterError(f"n_first must be between 2 and the number of other clips ({n - 1}); got {n_first}")
    ctx = _Descriptors(db, measures, pca)
    bounds = np.concatenate([[0], np.cumsum(table["n_frames"].to_numpy(np.int64))])
    clip_frames = [np.arange(a, b) for a, b in itertools.pairwise(bounds)]  # in the sample's frame numbers
    dists, seconds = {}, []
    for m in progress_bar(measures, desc="DTW of all pairs of clips", unit="measure", disable=not progress):
        t0 = time.perf_counter()
        desc = ctx(m, frames)
        local = ctx.pairwise(m, desc, desc)  # (F, F): every frame of the sample against every other
        del desc
        t1 = time.perf_counter()
        d = np.zeros((n, n))
        for i in progress_bar(range(n), desc=f"DTW of {m}", unit="clip", disable=True):
            for j in range(i + 1, n):
                d[i, j] = d[j, i] = _dtw_on(local, clip_frames[i], clip_frames[j])
        del local
        dists[m] = d
        seconds.append({"measure": m, "matrix": t1 - t0, "dtw": time.perf_counter() - t1})
    ranked = {}
    for m in measures:
        d = dists[m] + np.diag(np.full(n, np.inf))  # a clip is not in its own ranking
        order = np.argsort(d, axis=1, kind="stable")[:, :n_first]
        ranked[m] = (order, _centred_ranks(np.take_along_axis(d, order, axis=1)))
    rho = np.array([[_nanmean(_spearman(ranked[r][1], np.take_along_axis(dists[c], ranked[r][0], axis=1)))
                     for c in measures] for r in measures])  # fmt: skip
    labels = table["label"].to_numpy()
    same = labels[:, None] == labels[None]
    ids = table["doc_id"].to_numpy()
    out = pd.DataFrame(rho, index=pd.Index(measures, name="neighbours by"),
                       columns=pd.Index(measures, name="compared with"))  # fmt: skip
    out.attrs.update(
        clips=n, frames=len(frames), n_first=n_first,
        precision=pd.Series({m: float(np.take_along_axis(same, ranked[m][0], axis=1).mean()) for m in measures},
                            name="precision").rename_axis("measure"),
        chance=float(((same.sum(axis=1) - 1) / (n - 1)).mean()),
        dtw={m: pd.DataFrame(dists[m], index=pd.Index(ids, name="doc_id"), columns=ids) for m in measures},
        seconds=pd.DataFrame(seconds).set_index("measure"),
    )  # fmt: skip
    return out


def _dtw_on(local: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """DTW distance (basic steps, accumulated local distances) of two clips given by their rows ``a`` and columns
    ``b`` of a precomputed local distance matrix ``local``."""
    return dtw(a, b, distance=lambda i, j: local[np.ix_(i, j)])[0]


# ============================================================================ all of §3.3
def rank_correlations(db, large_db=None, clips_per_class: int = 8, n_queries: int = 1024, k: int = 256,
                      n_first: int = 8, pca=None, seed: int = 0, progress: bool = False) -> dict:  # fmt: skip
    """Krüger et al. 2010, Fig. 2 and §3.3: rank correlations between feature sets and distance measures.

    1. ``sample``: :func:`correlation_sample` of ``db`` (the paper: 76 HDM05 clips of 9 classes).
    2. ``pose``: :func:`pose_correlations` on the sample's frames, all 14 measures (Fig. 2).
    3. ``pose_large``: :func:`pose_correlations` on every frame of ``large_db`` (default ``db``), rows the nine
       kd-tree feature sets, columns :func:`available_measures` of that database ("pose-based comparisons on
       large databases", whose figure is in the paper's supplementary material).
    4. ``segment``: :func:`segment_correlations` on the sample (§3.3 "motion segment based comparisons").
    5. ``precision``: per measure the share of same-class clips among the first ``n_first`` of the segment-based
       rankings, with the share a random ranking would have (``chance``).

    Parameters
    ----------
    db : MotionDB
        Labelled, one frame rate (the paper: HDM05 at 30 Hz).
    large_db : MotionDB, optional
        The large database (the paper: HDM05 and CMU); its documents need no labels.
    clips_per_class, n_queries, k, n_first, seed : int
        As for :func:`correlation_sample`, :func:`pose_correlations` and :func:`segment_correlations` (the paper:
        8, 1024, 256, 8).
    pca : PCAModel, optional
        Reference of the Fp sets for all three experiments; default ``default_pca(db)`` (the paper: one PCA fitted
        on the whole HDM05 database).
    progress : bool
        Progress bars.

    Returns
    -------
    dict
        Keys "sample", "pose", "pose_large", "segment" (pandas.DataFrame, as the functions above) and "precision"
        (pandas.DataFrame indexed by measure: ``precision``, ``chance``).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.3, Fig. 2.
    """
    pca = default_pca(db) if pca is None else pca
    sample = correlation_sample(db, clips_per_class=clips_per_class, seed=seed)
    large = db if large_db is None else large_db
    pose = pose_correlations(db, docs=sample, n_queries=n_queries, k=k, pca=pca, seed=seed, progress=progress)
    pose_large = pose_correlations(large, rows=TABLE1_SETS, columns=available_measures(large), n_queries=n_queries,
                                   k=k, pca=pca, seed=seed, progress=progress)  # fmt: skip
    segment = segment_correlations(db, sample, n_first=n_first, pca=pca, progress=progress)
    precision = segment.attrs["precision"].to_frame().assign(chance=segment.attrs["chance"])
    return {"sample": sample, "pose": pose, "pose_large": pose_large, "segment": segment, "precision": precision}


# ============================================================================ the paper's statements about Fig. 2
_FRAME_WINDOWED = [("F15E", "F15x3E"), ("F15E", "F15x5E"), ("F30E", "F30x3E")]
_PCA = ("Fp8", "Fp16", "Fp25")
_POSITION_SETS = ("F15E", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E")
_F15E_TARGETS = ("F30E", "F39E", "F15x3E", "F15x5E", "F30x3E", "Dpc1", "Dpc11")


def _both(pairs) -> list[tuple[str, str]]:
    return [p for a, b in pairs for p in ((a, b), (b, a))]


# (matrix, statement, cells (row, column), check). Checks: ("min", t): every cell >= t, our reading of the paper's
# words (very high 0.9, high 0.8, rather high 0.6; it gives no numbers); ("greater",): the first cell > the second;
# ("cells", other, +1 / -1): the mean of the cells above / below the mean of the other cells; ("than", matrix,
# +1 / -1): the mean of the cells above / below their mean in another matrix; ("asymmetric",): the largest
# |rho(a, b) - rho(b, a)| of the matrix > 0.
_CLAIMS = [
    ("pose", "the matrices are not symmetric", [], ("asymmetric",)),
    ("pose", ("asymmetry especially prominent for Dquat in comparison to Deuler: Euler-similar frames are "
              "quaternion-similar, not vice versa"), [("Deuler", "Dquat"), ("Dquat", "Deuler")], ("greater",)),
    ("pose", ("asymmetry of the frame-based sets and their 3- or 5-frame counterparts: frames similar over l "
              "frames are similar in one frame, not vice versa (F15E, 3 frames)"),
     [("F15x3E", "F15E"), ("F15E", "F15x3E")], ("greater",)),
    ("pose", "... (F15E, 5 frames)", [("F15x5E", "F15E"), ("F15E", "F15x5E")], ("greater",)),
    ("pose", "... (F30E, 3 frames)", [("F30x3E", "F30E"), ("F30E", "F30x3E")], ("greater",)),
    ("pose", "a rather high rank correlation between Dpc1 and Dpc11", _both([("Dpc1", "Dpc11")]), ("min", 0.6)),
    ("pose", "... and between frame-based sets and their counterparts of 3 or 5 frames", _both(_FRAME_WINDOWED),
     ("min", 0.6)),
    ("pose", "F15x3E and F15x5E are very highly correlated", _both([("F15x3E", "F15x5E")]), ("min", 0.9)),
    ("pose", "F30E and F39E are very highly correlated", _both([("F30E", "F39E")]), ("min", 0.9)),
    ("pose", "F15E and F30E are highly correlated", _both([("F15E", "F30E")]), ("min", 0.8)),
    ("pose", "Fp8: a strong loss in correlation (Fp16 comparable to the other sets)",
     _both([("Fp8", s) for s in _POSITION_SETS]), ("cells", _both([("Fp16", s) for s in _POSITION_SETS]), -1)),
    ("pose", "Fp16 and Fp25 are very highly correlated", _both([("Fp16", "Fp25")]), ("min", 0.9)),
    ("pose", ("conclusions: the correlation of F15E to the higher-dimensional sets, Dpc1 and Dpc11 is higher "
              "than for Fp16"), [("F15E", m) for m in _F15E_TARGETS], ("cells", [("Fp16", m) for m in _F15E_TARGETS], +1)),
    ("pose_large", "large DB: F15x3E, F15x5E and F30x3E are still very highly correlated",
     _both([("F15x3E", "F15x5E"), ("F15x3E", "F30x3E"), ("F15x5E", "F30x3E")]), ("min", 0.9)),
    ("pose_large", "large DB: ... and highly correlated to Dpc11",
     [("F15x3E", "Dpc11"), ("F15x5E", "Dpc11"), ("F30x3E", "Dpc11")], ("min", 0.8)),
    ("pose_large", "large DB: F30E and F39E are still very highly correlated", _both([("F30E", "F39E")]),
     ("min", 0.9)),
    ("pose_large", "large DB: ... still a high correlation to F15E", [("F30E", "F15E"), ("F39E", "F15E")],
     ("min", 0.8)),
    ("pose_large", "large DB: ... a rather high correlation to Dpc1", [("F30E", "Dpc1"), ("F39E", "Dpc1")],
     ("min", 0.6)),
    ("pose_large", "large DB: the correlations to the PCA-based sets are somewhat lower than on the small DB",
     [(s, p) for s in _POSITION_SETS for p in _PCA], ("than", "pose", -1)),
    ("pose_large", "large DB: ... and so are those between frame-based sets and their 3- or 5-frame counterparts",
     _both(_FRAME_WINDOWED), ("than", "pose", -1)),
    ("segment", "segment-based: a higher correlation for Dwb to almost all others than pose-based",
     _both([("Dwb", m) for m in CORRELATION_MEASURES if m != "Dwb"]), ("than", "pose", +1)),
    ("segment", "segment-based: the correlations for the PCA sets decrease",
     _both([(p, m) for p in _PCA for m in CORRELATION_MEASURES if m not in _PCA]), ("than", "pose", -1)),
    ("segment", "segment-based: the correlations between F15E, F30E and F39E increase",
     _both([("F15E", "F30E"), ("F15E", "F39E"), ("F30E", "F39E")]), ("than", "pose", +1)),
    ("segment", "segment-based: ... especially to their counterparts of several frames", _both(_FRAME_WINDOWED),
     ("than", "pose", +1)),
]  # fmt: skip


def _check_text(check) -> str:
    kind = check[0]
    if kind == "min":
        return f"each >= {check[1]} (our reading of the words)"
    if kind == "greater":
        return "first > second"
    if kind == "cells":
        return f"mean {'above' if check[2] > 0 else 'below'} that of " + ", ".join(f"{a}→{b}" for a, b in check[1])
    if kind == "than":
        return f"mean {'higher' if check[2] > 0 else 'lower'} than in {check[1]}"
    return "max |ρ(a→b) − ρ(b→a)| > 0"


PAPER_FIG2_CLAIMS = pd.DataFrame(
    [{"matrix": m, "claim": text, "cells": cells, "check": _check_text(check)} for m, text, cells, check in _CLAIMS]
)
"""The paper's qualitative statements about Fig. 2 and the large-database and segment-based variants (§3.3), one
row each: ``matrix`` ("pose": Fig. 2, the sample; "pose_large"; "segment"), ``claim`` (paraphrased), ``cells`` (the
(row, column) pairs it concerns: row = neighbours by, column = compared with), ``check`` (how :func:`paper_claims`
tests it). Fig. 2's values are only drawn in the figure, not given in the text; thresholds such as "very high"
>= 0.9 are ours."""


def _mean_of(matrix, cells) -> float:
    if matrix is None or any(a not in matrix.index or b not in matrix.columns for a, b in cells):
        return np.nan
    return float(np.mean([matrix.loc[a, b] for a, b in cells]))


def paper_claims(matrices, kind: str = "pose") -> pd.DataFrame:
    """Our values beside each of the paper's statements about Fig. 2 (:data:`PAPER_FIG2_CLAIMS`).

    Parameters
    ----------
    matrices : dict or pd.DataFrame
        :func:`rank_correlations`' output (keys "pose", "pose_large", "segment"), or one matrix of
        :func:`pose_correlations` / :func:`segment_correlations`, taken as the matrix ``kind``.
    kind : str
        What a single matrix is: "pose", "pose_large" or "segment".

    Returns
    -------
    pandas.DataFrame
        :data:`PAPER_FIG2_CLAIMS` with ``ours`` (the values, text), ``value`` (the cells: their minimum for a
        threshold, the first cell, or their mean), ``reference`` (the threshold, the second cell, or the mean it is
        compared with) and ``holds`` (bool; None where a matrix or a measure is missing).
    """
    mats = dict(matrices) if isinstance(matrices, dict) else {kind: matrices}
    out = []
    for m, _, cells, check in _CLAIMS:
        mat, value, reference, ours = mats.get(m), np.nan, np.nan, ""
        if mat is not None and check[0] == "asymmetric":
            common = [x for x in mat.index if x in mat.columns]
            sub = mat.loc[common, common].to_numpy()
            value, reference = float(np.nanmax(np.abs(sub - sub.T))), 0.0
            ours = f"max |ρ(a→b) − ρ(b→a)| = {value:.3f}"
        elif not np.isnan(_mean_of(mat, cells)):
            vals = [float(mat.loc[a, b]) for a, b in cells]
            ours = ", ".join(f"{v:.3f}" for v in vals)
            if check[0] == "min":
                value, reference = min(vals), check[1]
            elif check[0] == "greater":
                value, reference = vals
            elif check[0] == "cells":
                value, reference = float(np.mean(vals)), _mean_of(mat, check[1])
                ours = f"mean {value:.3f} vs {reference:.3f}"
            else:
                value, reference = float(np.mean(vals)), _mean_of(mats.get(check[1]), cells)
                ours = f"mean {value:.3f} vs {reference:.3f} in {check[1]}"
        sign = check[2] if check[0] in ("cells", "than") else 1
        holds = None
        if np.isfinite(value) and np.isfinite(reference):
            holds = bool(value >= reference) if check[0] == "min" else bool(sign * (value - reference) > 0)
        out.append({"ours": ours, "value": value, "reference": reference, "holds": holds})
    return pd.concat([PAPER_FIG2_CLAIMS, pd.DataFrame(out)], axis=1)
