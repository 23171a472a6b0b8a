"""Global motion matching experiments: Krüger, Tautges, Weber & Zinke 2010 §4.2, §5.1 (Fig. 3, Table 2) and
Müller, Röder & Clausen 2005 §7 (Fig. 11).

lng_accuracy          §4.2: the lazy neighbourhood graph against subsequence DTW on random 1 s and 3 s queries:
                      Spearman's rho of the global distances of the retrieved matches, equal costs, recall of
                      DTW's best matches, and the effect of eps-approximate kNN; times of both.
similarity_matrices   Fig. 3: a query clip against a small database, per numeric set the distance matrix, the cells
                      the graph computed (kNN cells), its paths; subsequence DTW on Dpc1 for comparison.
alignment             Müller 2005 §7, Fig. 11: two logically similar clips aligned segment-wise from their relational
                      feature sequences, then refined by DTW restricted to the enlarged band of matched segments,
                      against full DTW (cost, time, path difference).
numerical_search      Table 2: per query class and numeric set, correct and wrong hits of the graph's matches against
                      the labels, and the iterated "logical" search (Kovar & Gleicher 2004) with its gain in recall.

The experiments reproduce the paper's graph and subsequence DTW as published: a match may have any length
(``min_length=None``), where the library's searches keep only matches at least half the query long.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import pandas as pd
from scipy.spatial.distance import cdist
from scipy.stats import spearmanr

from ..errors import ParameterError
from ..features.distances import dpc_pairwise, window_clouds
from ..features.numeric import numeric_of
from ..features.relational import relational_features
from ..features.segmentation import segment
from ..match.neighbourhood_graph import graph_matches, neighbourhoods
from ..match.time_warping import band_from_path, best_ends, dtw, subsequence_costs, subsequence_dtw
from ..similarity.knn import KnnIndex
from ..validation import renamed

# §4.2: "For the queries of length 1 sec (3 sec) it took on average 0.03 sec (0.08 sec.) to construct the
# alignments using exact nearest-neighbor-searches for the feature set Fp16"; rank correlation > 0.99.
PAPER_SECONDS = {1.0: 0.03, 3.0: 0.08}
PAPER_SPEARMAN = 0.99
TABLE2_SETS = ("F15E", "Fp8", "Fp16", "F30E", "F15x3E", "F30x3E")
FIG3_SETS = ("F15E", "F15x3E", "F30E", "Fp16")


def _document_bounds(db) -> tuple[np.ndarray, np.ndarray]:
    starts = db.documents["start"].to_numpy().astype(np.int64)
    return starts, starts + db.documents["n_frames"].to_numpy().astype(np.int64)


def _overlaps(a_start, a_end, b_start, b_end) -> np.ndarray:
    """(len(a), len(b)) bool: inclusive intervals a[i] and b[j] share a frame."""
    a_start, a_end = np.asarray(a_start)[:, None], np.asarray(a_end)[:, None]
    return (a_start <= np.asarray(b_end)[None]) & (np.asarray(b_start)[None] <= a_end)


# ============================================================================ §4.2: LNG against subsequence DTW
@renamed(feature_set="numeric_set")
def lng_accuracy(db, numeric_set: str = "F15E", n_queries: int = 128, seconds=(1.0, 3.0), k: int = 256,
                 radius: float | None = None, eps=(0.0, 0.1, 0.5), n_matches: int = 10, seed: int = 0,
                 features: np.ndarray | None = None, progress: bool = False) -> pd.DataFrame:  # fmt: skip
    """The lazy neighbourhood graph against subsequence DTW on random queries (Krüger et al. 2010 §4.2).

    For each query length, ``n_queries`` random stretches of random documents (long enough) are matched against
    the whole database, their own document excluded, by the graph (k neighbours per frame, for each eps) and by
    subsequence DTW on the same features (the reference, computed once per query).

    Parameters
    ----------
    db : MotionDB
        E.g. the HDM05 cut clips at 30 Hz.
    numeric_set : str
        A numeric set (:data:`mocapviz.features.NUMERIC_SETS`); its old name ``feature_set`` still works, with a
        FutureWarning.
    n_queries : int
        Queries per query length.
    seconds : tuple of float
        Query lengths in seconds.
    k : int
        The graph's neighbours per query frame.
    radius : float, optional
        Their largest distance, feature units.
    eps : tuple of float
        kNN approximations tried.
    n_matches : int
        Matches kept by both methods.
    seed : int
        Seed of the random queries.
    features : np.ndarray [shape=(N, d)], optional
        The set's values for every frame (default ``numeric_of``).
    progress : bool
        A progress bar over the queries.

    Returns
    -------
    pandas.DataFrame
        One row per (seconds, eps, query): ``seconds``, ``eps``, ``query_doc``, ``query_start`` (database frame),
        ``m`` (query frames), ``lng_matches``, ``spearman`` (rho between the graph's costs of its matches and
        subsequence DTW's accumulated cost at the same end frames; NaN with fewer than 3 matches or a constant
        side), ``equal`` (share of the graph's matches whose cost equals DTW's at their end, relative difference
        < 1e-9), ``below_dtw``, ``recall`` (share of DTW's best ``n_matches`` matches overlapped by a graph
        match), ``same_best`` (the best matches overlap): see :func:`agreement`; ``knn_s``, ``graph_s``,
        ``dtw_s`` (subsequence DTW over the whole database, seconds).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §4.2.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> per_query = lng_accuracy(MotionDB.sample(), n_queries=4, seconds=(0.5,), k=1024, eps=(0.0,))
    >>> len(per_query), int(per_query["below_dtw"].sum())  # the graph never beats DTW's optimum
    (4, 0)
    """
    X = numeric_of(db, numeric_set) if features is None else features
    index = KnnIndex(X)
    starts, stops = _document_bounds(db)
    rng = np.random.default_rng(seed)
    rows = []
    # untimed warm-up: numba compiles the kernels (or loads them from its cache) on their first call
    subsequence_costs(X[:2], X[:4])
    graph_matches(*neighbourhoods(X[:2], index, 1), n_frames=len(X))
    work = [(s, q) for s in seconds for q in range(n_queries)]
    if progress:
        from tqdm.auto import tqdm

        work = tqdm(work, desc="LNG vs subsequence DTW", unit="query")
    fps = db.documents["fps"].to_numpy(np.float64)  # each query's length at its own document's rate
    for sec, _ in work:
        m_of = np.maximum(2, np.round(sec * fps).astype(np.int64))
        long_enough = np.flatnonzero(stops - starts >= m_of)
        if not len(long_enough):
            raise ParameterError(f"no document of {db.path} is {sec:g} s long")
        doc = int(rng.choice(long_enough))
        m = int(m_of[doc])
        q0 = int(rng.integers(starts[doc], stops[doc] - m + 1))
        q = X[q0 : q0 + m]
        t0 = time.perf_counter()
        cost, first = subsequence_costs(q, X, starts)
        t_dtw = time.perf_counter() - t0
        cost[starts[doc] : stops[doc]] = np.inf  # the query's own document is excluded from both
        ref_ends = best_ends(cost, first, starts, n_matches)
        for e in eps:
            t0 = time.perf_counter()
            d, f = neighbourhoods(q, index, k, radius, e, exclude=[starts[doc], stops[doc]])
            t1 = time.perf_counter()
            found = graph_matches(d, f, starts, len(X), n_matches, paths=False, min_length=None)  # as best_ends
            t2 = time.perf_counter()
            rows.append({"seconds": sec, "eps": e, "query_doc": doc, "query_start": q0, "m": m,
                         "lng_matches": len(found), **agreement(found, cost, first[ref_ends], ref_ends),
                         "knn_s": t1 - t0, "graph_s": t2 - t1, "dtw_s": t_dtw})  # fmt: skip
    return pd.DataFrame(rows)


def agreement(found: pd.DataFrame, cost: np.ndarray, ref_starts, ref_ends, rtol: float = 1e-9) -> dict:
    """How well graph matches agree with subsequence DTW (Krüger et al. 2010 §4.1, §4.2).

    Parameters
    ----------
    found : pandas.DataFrame
        The lazy neighbourhood graph's matches (start, end: database frames, inclusive; cost).
    cost : np.ndarray [shape=(n,)]
        Subsequence DTW's accumulated cost at every end frame (:func:`mocapviz.match.subsequence_costs`).
    ref_starts, ref_ends : np.ndarray [shape=(K,)], int
        Subsequence DTW's best matches (:func:`mocapviz.match.best_ends`), database frames, inclusive.
    rtol : float
        Relative difference under which two costs count as equal.

    Returns
    -------
    dict
        ``spearman`` (rho between the graph's match costs and DTW's at the same end frames; NaN with fewer than 3
        matches or one side constant, 1.0 when both are), ``equal`` (share of the graph's costs equal to DTW's:
        it found DTW's optimal path there), ``below_dtw`` (graph costs below DTW's: impossible unless one is
        wrong), ``recall`` (share of DTW's matches some graph match overlaps), ``same_best`` (the best matches
        overlap).
    """
    ends = found["end"].to_numpy(np.int64)
    ours, dtw_cost = found["cost"].to_numpy(np.float64), cost[ends]
    rho = np.nan
    if len(ends) >= 3:
        flat = (np.ptp(ours) == 0, np.ptp(dtw_cost) == 0)
        rho = 1.0 if all(flat) else np.nan if any(flat) else float(spearmanr(ours, dtw_cost).statistic)
    hit = _overlaps(ref_starts, ref_ends, found["start"], ends)
    return {
        "spearman": rho,
        "equal": float(np.mean(np.abs(ours - dtw_cost) <= rtol * np.maximum(dtw_cost, 1e-300))) if len(ends) else np.nan,
        "below_dtw": int((ours < dtw_cost * (1 - rtol)).sum()),
        "recall": float(hit.any(axis=1).mean()) if len(ref_ends) else np.nan,
        "same_best": bool(len(ends) and len(ref_ends) and hit[0, 0]),
    }  # fmt: skip


def summarize_accuracy(per_query: pd.DataFrame) -> pd.DataFrame:
    """:func:`lng_accuracy`'s rows averaged per (seconds, eps), with the paper's figures beside: mean Spearman
    (paper > 0.99), equal-cost share, recall, same best match, mean kNN / graph / LNG / DTW seconds (paper: the
    alignment without kNN 0.03 s for 1 s queries, 0.08 s for 3 s, Fp16) and the speed-up of the graph (kNN
    included) over subsequence DTW.

    Parameters
    ----------
    per_query : pandas.DataFrame
        :func:`lng_accuracy`'s table, one row per query.

    Returns
    -------
    pandas.DataFrame
        One row per (query seconds, eps).
    """
    g = per_query.groupby(["seconds", "eps"])
    out = g.agg(queries=("m", "size"), spearman=("spearman", "mean"), spearman_min=("spearman", "min"),
                equal=("equal", "mean"), recall=("recall", "mean"), same_best=("same_best", "mean"),
                knn_s=("knn_s", "mean"), graph_s=("graph_s", "mean"), dtw_s=("dtw_s", "mean")).reset_index()  # fmt: skip
    out["lng_s"] = out["knn_s"] + out["graph_s"]
    out["speedup"] = out["dtw_s"] / out["lng_s"]
    out["paper_graph_s"] = out["seconds"].map(PAPER_SECONDS)
    out["paper_spearman"] = f"> {PAPER_SPEARMAN}"
    return out


# ============================================================================ Fig. 3: similarity matrices
@renamed(sets="numeric_sets", k_matches="n_matches")
def similarity_matrices(db, query_doc: int, query_frames: tuple[int, int] | None = None, database_docs=None,
                        numeric_sets=FIG3_SETS, k: int = 32, radius: float | None = None, n_matches: int = 3,
                        dpc_window: int = 1) -> dict:  # fmt: skip
    """Fig. 3 of Krüger et al. 2010: a query aligned to the motions of a small database with the lazy
    neighbourhood graph on several numeric sets, and by subsequence DTW on Dpc for comparison.

    The paper's example is a two-step left-turning walk against six steps of one; HDM05's
    ``jogLeftCircle4StepsRstart`` clips (a left-turning jog starting with the right foot) serve the same purpose.

    Parameters
    ----------
    db : MotionDB
        The database.
    query_doc : int
        The document the query comes from.
    query_frames : (int, int), optional
        Frames [a, b) within it (default the whole document).
    database_docs : list of int, optional
        The small database (default every other document of the query's label, at most 3: a labelled query).
    numeric_sets : sequence of str
        Numeric sets (old name ``sets``, with a FutureWarning).
    k : int
        The graph's neighbours per query frame (on the small database).
    radius : float, optional
        Their largest distance, feature units.
    n_matches : int
        Graph / DTW matches kept (old name ``k_matches``, with a FutureWarning).
    dpc_window : int
        Frames of the Dpc window (1: Dpc1, the paper's choice for Fig. 3).

    Returns
    -------
    dict
        ``"query"`` ({doc, frames}), ``"database_docs"``, ``"database_starts"`` (first frame of each database
        document in the small database's frame numbers), and per numeric set name and ``"Dpc{n}"``: a dict with
        ``"distance"`` ((m, n) local costs: Euclidean in the set's units; cm² for Dpc), ``"computed"`` ((m, n)
        bool, the kNN cells the graph visited; all True for Dpc, which DTW computes in full) and ``"matches"`` (a
        matches DataFrame, frames of the small database, with paths).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §4.1-4.2, Fig. 3.
    """
    docs = db.documents
    span = db.frames(query_doc)
    a, b = (0, span.stop - span.start) if query_frames is None else query_frames
    if not 0 <= a < b <= span.stop - span.start or b - a < 2:
        raise ParameterError(f"query frames {a}:{b} are not a span of >= 2 frames of document {query_doc} "
                         f"({span.stop - span.start} frames)")  # fmt: skip
    if database_docs is None:
        label = docs.loc[docs["doc_id"] == query_doc, "label"].iloc[0]
        if pd.isna(label):
            raise ParameterError(f"document {query_doc} has no label, so there are no documents of its class to "
                                 "compare it with; pass database_docs")  # fmt: skip
        database_docs = [int(d) for d in docs.loc[docs["label"] == label, "doc_id"] if d != query_doc][:3]
    database_docs = [int(d) for d in database_docs]
    if not database_docs:
        raise ParameterError("the small database needs at least one document")
    rows = np.concatenate([np.arange(db.frames(d).start, db.frames(d).stop) for d in database_docs])
    lengths = np.array([db.frames(d).stop - db.frames(d).start for d in database_docs])
    local_starts = np.r_[0, np.cumsum(lengths)[:-1]]
    q_rows = np.arange(span.start + a, span.start + b)
    out = {"query": {"doc": int(query_doc), "frames": (int(a), int(b))}, "database_docs": database_docs,
           "database_starts": local_starts}  # fmt: skip
    for name in numeric_sets:
        X = numeric_of(db, name)
        q, small = np.asarray(X[q_rows], dtype=np.float64), np.asarray(X[rows], dtype=np.float64)
        dist = cdist(q, small)  # (m, n) Euclidean, without an (m, n, d) temporary
        index = KnnIndex(small)
        d, f = neighbourhoods(q, index, min(k, len(small)), radius)
        computed = np.zeros(dist.shape, dtype=bool)
        qi = np.repeat(np.arange(len(q)), f.shape[1])
        computed[qi[f.ravel() >= 0], f.ravel()[f.ravel() >= 0]] = True
        out[name] = {"distance": dist, "computed": computed,
                     "matches": graph_matches(d, f, local_starts, len(small), n_matches, min_length=None)}  # fmt: skip
    positions = db.positions[:]  # (every block verified, mocapviz.checked_map)
    q_clouds = window_clouds(positions[span.start : span.stop], dpc_window)[a:b]
    clouds = np.concatenate([window_clouds(positions[db.frames(d)], dpc_window) for d in database_docs])
    out[f"Dpc{dpc_window}"] = {
        "distance": dpc_pairwise(q_clouds, clouds), "computed": np.ones((b - a, len(rows)), dtype=bool),
        "matches": subsequence_dtw(q_clouds, clouds, local_starts, n_matches=n_matches, distance=dpc_pairwise,
                                   min_length=None),
    }  # fmt: skip
    return out


# ============================================================================ Müller 2005 §7: alignment
def _segment_band(seg_a, seg_b, pairs: np.ndarray, shape: tuple[int, int], margin: int) -> np.ndarray:
    """The band (m, 2) covering the frames of matched segment pairs (i of a, j of b), enlarged by ``margin``."""
    rows, cols = [], []
    for i, j in pairs:
        r = np.arange(seg_a.starts[i], seg_a.starts[i] + seg_a.lengths[i])
        rows += [r, r]
        cols += [np.full(len(r), seg_b.starts[j]), np.full(len(r), seg_b.starts[j] + seg_b.lengths[j] - 1)]
    return band_from_path(np.stack([np.concatenate(rows), np.concatenate(cols)], axis=1), shape, margin)


def _median_seconds(fn, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def alignment(db, doc_a: int, doc_b: int, features=None, relational_set: str = "2005", numeric_set: str = "F15E",
              margin: int = 4, repeats: int = 5) -> dict:  # fmt: skip
    """Two-stage time alignment of two logically similar clips (Müller, Röder & Clausen 2005 §7, Fig. 11).

    1. Coarse, from the index's point of view: segment both clips by the chosen relational features and align
       their feature sequences by DTW over segments (local cost: the Hamming distance of the segments' feature
       vectors, so equal progressions align segment to segment).
    2. Fine: DTW on the numeric features, computed only inside the band of the matched segments' frames,
       enlarged by ``margin`` frames on every side (the grey area of Fig. 11).

    Parameters
    ----------
    db : MotionDB
        The database.
    doc_a, doc_b : int
        The two clips (a: rows of the cost matrix, b: columns).
    features : list of str, optional
        Relational features (default all of the set).
    relational_set : {"2005", "2006"}
        The relational set.
    numeric_set : str
        The features of the fine DTW (Euclidean local cost, feature units).
    margin : int
        Frames added to the band on every side.
    repeats : int
        Runs timed per method (median).

    Returns
    -------
    dict
        ``"summary"`` (one-row DataFrame: frames of each clip, segments of each, segment pairs, band cells and
        their share of the matrix, full and band cost and seconds, the coarse stage's seconds, speed-up, whether
        the paths are identical, mean and max path difference in frames of b per frame of a), ``"segments_a"``,
        ``"segments_b"`` (FeatureSequence), ``"segment_path"`` ((P, 2) segment pairs), ``"band"`` ((m, 2)),
        ``"path_full"``, ``"path_band"`` ((L, 2)), ``"cost"`` ((m, n) Euclidean local costs of the whole matrix,
        for plots).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §7, Fig. 11.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> result = alignment(MotionDB.sample(), 7, 18, features=["lfoot_raised", "lknee_bent"], repeats=1)
    >>> summary = result["summary"].iloc[0]
    >>> int(summary["segments_a"]), round(float(summary["band_share"]), 2)  # DTW computed on a quarter of the cells
    (7, 0.25)
    >>> bool(summary["cost_band"] >= summary["cost_full"]), result["band"].shape  # a band never beats full DTW
    (True, (129, 2))
    """
    X = numeric_of(db, numeric_set)
    fa, fb = np.asarray(X[db.frames(doc_a)], np.float64), np.asarray(X[db.frames(doc_b)], np.float64)
    values_a, names = relational_features(db.motion(doc_a), relational_set, progress=False)
    values_b, _ = relational_features(db.motion(doc_b), relational_set, progress=False)
    pick = list(range(len(names))) if features is None else [names.index(f) for f in features]
    shape = (len(fa), len(fb))

    def coarse():
        seg_a, seg_b = segment(values_a[:, pick]), segment(values_b[:, pick])
        _, pairs = dtw(seg_a.vectors().astype(np.float64), seg_b.vectors().astype(np.float64))
        return seg_a, seg_b, pairs, _segment_band(seg_a, seg_b, pairs, shape, margin)

    dtw(fa[:2], fb[:2])  # compile outside the timing
    t_coarse, (seg_a, seg_b, pairs, band) = _median_seconds(coarse, repeats)
    t_full, (c_full, p_full) = _median_seconds(lambda: dtw(fa, fb), repeats)
    t_band, (c_band, p_band) = _median_seconds(lambda: dtw(fa, fb, band=band), repeats)
    same = len(p_full) == len(p_band) and bool(np.array_equal(p_full, p_band))

    def mean_column(path):  # the mean frame of b aligned to each frame of a
        return np.bincount(path[:, 0], path[:, 1], minlength=shape[0]) / np.bincount(path[:, 0], minlength=shape[0])

    diff = np.abs(mean_column(p_full) - mean_column(p_band))
    cells = int((band[:, 1] - band[:, 0]).sum())
    summary = pd.DataFrame([{
        "doc_a": doc_a, "doc_b": doc_b, "frames_a": shape[0], "frames_b": shape[1], "segments_a": len(seg_a.codes),
        "segments_b": len(seg_b.codes), "segment_pairs": len(pairs), "band_cells": cells,
        "band_share": cells / (shape[0] * shape[1]), "cost_full": c_full, "cost_band": c_band,
        "seconds_full": t_full, "seconds_band": t_band, "seconds_coarse": t_coarse,
        "speedup": t_full / (t_band + t_coarse), "same_path": same, "path_diff_mean": float(diff.mean()),
        "path_diff_max": float(diff.max()),
    }])  # fmt: skip
    cost = np.sqrt(((fa[:, None] - fb[None]) ** 2).sum(-1))
    return {"summary": summary, "segments_a": seg_a, "segments_b": seg_b, "segment_path": pairs, "band": band,
            "path_full": p_full, "path_band": p_band, "cost": cost}  # fmt: skip


# ============================================================================ Table 2: numerical / logical search
def _hits(X, index, starts, stops, q_rows: np.ndarray, own_doc: int, k: int, n_matches: int, factor: float):
    """Graph matches of the database frames ``q_rows`` outside document ``own_doc`` whose cost is at most
    ``factor`` times the best one's."""
    d, f = neighbourhoods(X[q_rows], index, k, exclude=[starts[own_doc], stops[own_doc]])
    found = graph_matches(d, f, starts, len(X), n_matches, paths=False, min_length=None)
    if len(found):
        found = found[found["cost"] <= factor * found["cost"].iloc[0]]
    return found


@renamed(k_matches="n_matches")
def numerical_search(db, classes=None, numeric_sets=TABLE2_SETS, k: int = 256, n_matches: int = 50,
                     factor: float = 1.5, iterations: int = 1,
                     label_column: str = "label") -> pd.DataFrame:  # fmt: skip
    """Numerical and "logical" similarity search (Krüger et al. 2010 §5.1, Table 2; Kovar & Gleicher 2004).

    For each class, its first document (whole clip) is the query. Numerical search: the graph's matches over
    the database (the query's document excluded) whose cost is at most ``factor`` times the best match's — a
    threshold relative to the best match, so that it means the same in every numeric set's units (the paper
    does not state its threshold). A hit is correct when its document has the query's label, wrong when it has
    another (a hit in a document without a label is neither). Logical search:
    every hit found so far is used as a new query (its own document excluded), for ``iterations`` rounds; new
    hits are those not overlapping a hit already found.

    Parameters
    ----------
    db : MotionDB
        With labels (e.g. HDM05 cut clips at 30 Hz).
    classes : list of str, optional
        Default: kickLFront1Reps, elbowToKnee1RepsLelbowStart and squat1Reps when present: a kick, an arm-and-leg
        motion and a whole-body motion, like the paper's kick, punch and skier.
    numeric_sets : sequence of str
        Numeric sets (default Table 2's).
    k : int
        Neighbours per query frame.
    n_matches : int
        Matches per search (old name ``k_matches``, with a FutureWarning).
    factor : float
        The relative cost threshold, >= 1.
    iterations : int
        Rounds of logical search, >= 0.
    label_column : str
        The documents' column holding the class.

    Returns
    -------
    pandas.DataFrame
        One row per (class, set): ``class``, ``set``, ``query_doc``, ``relevant`` (other documents of the class),
        ``correct``, ``wrong`` (numerical hits), ``correct_new``, ``wrong_new`` (of those, hits that overlap no
        hit of the first set — the paper's numbers in brackets against F15E), ``recall`` (documents of the class
        with a correct hit / relevant), ``logical_correct``, ``logical_wrong``, ``logical_recall``,
        ``recall_gain`` (logical_recall - recall).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §5.1, Table 2 (:func:`krueger2010_table2` holds the paper's figures).
    """
    if factor < 1:
        raise ParameterError(f"factor must be >= 1 (a threshold relative to the best match); got {factor}")
    docs = db.documents
    labels = docs[label_column].astype("string")
    present = sorted(set(labels.dropna()))
    if classes is None:
        classes = [c for c in ("kickLFront1Reps", "elbowToKnee1RepsLelbowStart", "squat1Reps") if c in present]
    missing = [c for c in classes if c not in present]
    if missing or not classes:
        raise ParameterError(f"classes {missing or classes} not in {db.path}; classes there: {present}")
    starts, stops = _document_bounds(db)
    label_of = labels.to_numpy(dtype=object, na_value=None)  # None: a take without a label, neither correct nor wrong
    labelled = labels.notna().to_numpy()
    rows, reference = [], {}
    for name in numeric_sets:
        X = numeric_of(db, name)
        index = KnnIndex(X)
        for cls in classes:
            members = docs.loc[(labels == cls).fillna(False).to_numpy(), "doc_id"].to_numpy()
            query_doc = int(members.min())
            hits = _hits(X, index, starts, stops, np.arange(starts[query_doc], stops[query_doc]), query_doc, k,
                         n_matches, factor)  # fmt: skip
            correct = label_of[hits["doc_id"].to_numpy()] == cls
            wrong = labelled[hits["doc_id"].to_numpy()] & ~correct
            found = hits.copy()
            frontier = hits
            for _ in range(iterations):
                new = []
                for row in frontier.itertuples():
                    more = _hits(X, index, starts, stops, np.arange(row.start, row.end + 1), int(row.doc_id), k,
                                 n_matches, factor)  # fmt: skip
                    more = more[~more["doc_id"].eq(query_doc)]
                    if len(found) and len(more):
                        more = more[~_overlaps(more["start"], more["end"], found["start"], found["end"]).any(axis=1)]
                    if len(new) and len(more):
                        prev = pd.concat(new)
                        more = more[~_overlaps(more["start"], more["end"], prev["start"], prev["end"]).any(axis=1)]
                    new.append(more)
                frontier = pd.concat(new) if new else found.iloc[:0]
                found = pd.concat([found, frontier], ignore_index=True)
            l_correct = label_of[found["doc_id"].to_numpy()] == cls
            l_wrong = labelled[found["doc_id"].to_numpy()] & ~l_correct
            relevant = len(members) - 1
            if name == numeric_sets[0]:
                reference[cls] = hits
            ref = reference[cls]
            novel = ~_overlaps(hits["start"], hits["end"], ref["start"], ref["end"]).any(axis=1) if len(ref) else (
                np.ones(len(hits), dtype=bool))  # fmt: skip
            recall = len(set(hits["doc_id"][correct])) / relevant if relevant else np.nan
            l_recall = len(set(found["doc_id"][l_correct])) / relevant if relevant else np.nan
            rows.append({
                "class": cls, "set": name, "query_doc": query_doc, "relevant": relevant,
                "correct": int(correct.sum()), "wrong": int(wrong.sum()),
                "correct_new": int((correct & novel).sum()), "wrong_new": int((wrong & novel).sum()),
                "recall": recall, "logical_correct": int(l_correct.sum()), "logical_wrong": int(l_wrong.sum()),
                "logical_recall": l_recall, "recall_gain": l_recall - recall,
            })  # fmt: skip
    return pd.DataFrame(rows)


def krueger2010_table2() -> pd.DataFrame:
    """Table 2 of Krüger et al. 2010 (whole HDM05): correct and wrong hits, in brackets those F15E did not find.

    Returns
    -------
    pandas.DataFrame
        One row per (query, numeric set): ``query``, ``set``, ``correct``, ``wrong``, ``correct_new``,
        ``wrong_new`` (the bracketed figures; NaN for F15E), as :func:`numerical_search` gives them.

    Examples
    --------
    >>> print(krueger2010_table2()[["query", "set", "correct", "wrong"]].head(2).to_string(index=False))
                        query  set  correct  wrong
    HDM_bk_kickRSide1Reps_007 F15E        5      0
    HDM_bk_kickRSide1Reps_007  Fp8        1      0
    """
    data = {
        "HDM_bk_kickRSide1Reps_007": ([5, 1, 4, 5, 3, 4], [0, 0, 0, 0, 0, 0], [None, 0, 0, 0, 0, 0], [None, 0, 0, 0, 0, 0]),
        "HDM_tr_punchRSide1Reps_023": ([6, 4, 6, 8, 6, 9], [0, 0, 0, 0, 0, 2], [None, 0, 0, 2, 3, 6], [None, 0, 0, 0, 0, 2]),
        "HDM_bk_skier1RepsLStart_011": ([9, 8, 9, 9, 10, 10], [0, 0, 0, 0, 0, 0], [None, 0, 0, 0, 1, 1], [None, 0, 0, 0, 0, 0]),
    }  # fmt: skip
    rows = []
    for query, (correct, wrong, correct_new, wrong_new) in data.items():
        for i, name in enumerate(TABLE2_SETS):
            rows.append({"query": query, "set": name, "correct": correct[i], "wrong": wrong[i],
                         "correct_new": correct_new[i], "wrong_new": wrong_new[i]})  # fmt: skip
    return pd.DataFrame(rows)
