"""Global motion matching in a MotionDB: the stretches that move like a query, by the lazy neighbourhood graph of
Krüger, Tautges, Weber & Zinke 2010 §4.1 (``method="lng"``) or by subsequence DTW (``"dtw"``, its reference),
as the one hit table (:func:`mocapviz.db.hits.hit_table`).

The algorithms work on feature arrays (:mod:`mocapviz.match`); this module is where a MotionDB, its stored numeric
set, the query by example and the hit table meet, for the command line (``mocapviz match``) and the dashboard.
"""
from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..db.hits import from_database_frames, hit_table
from ..errors import ParameterError
from ..features.numeric import numeric_of
from ..match import lng, subsequence_dtw
from ..match.time_warping import shortest_match
from ..validation import MIN_LENGTH, count, number, one_of
from .knn import KnnIndex
from .search import example_features

METHODS = ("lng", "dtw")
DEFAULT_K = 256  # neighbours per query frame of the graph (Krüger et al. 2010 §4.2)
LNG_K_AT_30HZ = DEFAULT_K  # scaled with the frame rate and the database's size (graph_k)
LNG_REFERENCE_FRAMES = 100_000  # frames at 30 Hz up to which LNG_K_AT_30HZ finds matches (graph_k)


def match_motion(db, example, frames=None, numeric_set: str = "F15E", method: str = "lng", n_matches: int = 10,
                 k: int = DEFAULT_K, radius: float | None = None, eps: float = 0.0, exclude_document: bool = False,
                 paths: bool = False, features: np.ndarray | None = None, index: KnnIndex | None = None,
                 option: str = "frames", min_length: float | None = MIN_LENGTH,
                 checked: bool = False) -> pd.DataFrame:  # fmt: skip
    """The stretches of a MotionDB most like a query, by the lazy neighbourhood graph or subsequence DTW.

    Parameters
    ----------
    db : MotionDB
        Its ``numeric_set`` is read when stored (``mocapviz features DB``), else computed.
    example : int, Motion, str or os.PathLike
        The query (:func:`~mocapviz.similarity.search.example_features`): a doc id, a Motion or a motion file.
    frames : (int, int) or slice, optional
        [start, stop) frames of the example (default: all).
    numeric_set : str
        The numeric set compared (default F15E, cm).
    method : {"lng", "dtw"}
        The lazy neighbourhood graph (§4.1, default) or subsequence DTW over every frame.
    n_matches : int
        Matches to return at most, best first.
    k, radius, eps :
        The graph's neighbours per query frame (default 256), their largest distance (feature units) and the kNN
        approximation (:meth:`KnnIndex.query`); ``method="lng"`` only.
    exclude_document : bool
        Leave the query's own document out (when ``example`` is a doc id).
    paths : bool
        Add each match's warping path: an (L, 2) array of (query frame, frame of the hit's document).
    features : np.ndarray [shape=(N, d)], optional
        The stored numeric set, if already loaded; ``index`` a :class:`KnnIndex` over it, if already built.
    option : str
        How the caller names ``frames`` in an error.
    min_length : float, optional
        The shortest match, a share in (0, 1] of the query's frames (default 0.5: half as long), by either method:
        the rule of the similarity search's stretches (:func:`mocapviz.match.time_warping.shortest_match`); None:
        any length (a match may then hold the whole query on one frame).
    checked : bool
        ``method="dtw"``: the query's length was checked against a whole database already (``db`` is a shard of
        it, :mod:`mocapviz.sharded`, whose documents may all be shorter than the query and still hold matches).

    Returns
    -------
    pandas.DataFrame
        The hit table (``start``, ``end``: the document's frames, half-open) with ``cost`` (accumulated DTW cost,
        feature units) and ``cost_per_frame`` (cost / query frames), [``path``]. ``attrs``: ``method``,
        ``query_frames``, ``ms``, ``min_length``.

    Raises
    ------
    ParameterError
        A bad method, K, k, radius, eps or min_length, ``k``/``radius``/``eps`` given with ``method="dtw"``, a bad
        example.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §4.1 (the lazy neighbourhood graph) and §4.2 (against subsequence DTW).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> hits = match_motion(db, 7, (0, 60), method="dtw", n_matches=2, exclude_document=True)
    >>> list(hits.columns[:10])
    ['rank', 'doc_id', 'name', 'start', 'end', 'frames', 'start_s', 'end_s', 'cost', 'cost_per_frame']
    """
    method = one_of(method, "method", METHODS)
    n_matches = count(n_matches, "n_matches")
    k = count(k, "k")
    if radius is not None:
        radius = number(radius, "radius", 0.0, low_open=True)
    eps = number(eps, "eps", 0.0)
    if method == "dtw" and (k != DEFAULT_K or radius is not None or eps):
        raise ParameterError("k, radius and eps shape the neighbourhood graph of method='lng'; subsequence DTW "
                             "(method='dtw') compares every frame: leave them out")
    X = np.asarray(numeric_of(db, numeric_set, progress=False)) if features is None else features
    query, own = example_features(db, X, example, frames, numeric_set, option)
    shortest_match(min_length, len(query))  # checked before either search starts
    starts = db.documents["start"].to_numpy()
    span = db.frames(own) if own is not None and exclude_document else None
    t0 = time.perf_counter()
    if method == "dtw":
        found = subsequence_dtw(query, X, starts, n_matches=n_matches + (n_matches if span else 0), paths=paths,
                                min_length=min_length, checked=checked)
        if span is not None:
            found = found[(found["end"] < span.start) | (found["start"] >= span.stop)].head(n_matches)
    else:
        index = KnnIndex(X) if index is None else index
        found = lng(query, index, k=k, radius=radius, n_matches=n_matches, starts=starts, eps=eps,
                    exclude=None if span is None else (span.start, span.stop), paths=paths,
                    min_length=min_length)  # fmt: skip
    ms = 1e3 * (time.perf_counter() - t0)
    first = found["start"].to_numpy(np.int64)
    doc_ids, a, b = from_database_frames(db, first, found["end"].to_numpy(np.int64) + 1)
    columns = {"cost": found["cost"].to_numpy(np.float64), "cost_per_frame": found["cost"].to_numpy(np.float64) / len(query)}
    if paths:
        columns["path"] = [np.asarray(p) - np.array([0, f - s]) for p, f, s in zip(found["path"], first, a)]
    table = hit_table(db, doc_ids, a, b, **columns)
    table.attrs.update(method=method, query_frames=len(query), ms=ms, min_length=min_length)
    return table


def scaled_k(k_at_30hz: int, fps: float) -> int:
    """Neighbours per query frame for the graph at ``fps``: ``k_at_30hz`` at 30 Hz or less, proportionally more at
    higher frame rates (a pose's nearest frames then include more of its own neighbouring frames, leaving fewer for
    other motions, and the graph finds no path)."""
    return round(k_at_30hz * max(1.0, fps / 30.0))


def graph_k(n_frames: int, fps: float) -> int:
    """The default neighbours per query frame of the lazy neighbourhood graph on a database of ``n_frames`` frames at
    ``fps``: the papers' 256 at 30 Hz (:func:`scaled_k` at higher rates), times the database's frames at 30 Hz over
    :data:`LNG_REFERENCE_FRAMES` when it holds more, at most ``n_frames``.

    A pose's k nearest frames are shared by every take of similar motions; in a database of many takes of the same
    motions they fill up with other takes' frames before the graph can follow any one take, and it finds no path.
    Measured on every shared archive at 30 Hz (446,551 frames; 16 clips of the four archives, their first 3 s and
    whole: 32 queries): k = 256 found no match for 20 queries, this rule's k = 1,143 for 16 (most of them CMU
    trials, which no other take resembles), in a median of 1.0 s against 0.5 s. The sample (5,543 frames at 120 Hz)
    and HDM05 (71k frames at 120 Hz: 18k at 30 Hz) keep the papers' k scaled with the rate: 1,024.

    Examples
    --------
    >>> graph_k(5_543, 120.0), graph_k(71_000, 30.0), graph_k(446_551, 30.0), graph_k(100, 30.0)
    (1024, 256, 1143, 100)
    """
    at_30hz = n_frames * 30.0 / fps
    return min(int(n_frames), round(scaled_k(LNG_K_AT_30HZ, fps) * max(1.0, at_30hz / LNG_REFERENCE_FRAMES)))
