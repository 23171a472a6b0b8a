"""Hybrid search: relational query by example picks candidate documents, DTW on numeric features ranks them.

The relational stage (Müller, Röder & Clausen 2005 §5-6.2, :func:`mocapviz.relational.query.query_by_example`) with a lenient
feature selection -- few features, adaptive fuzzy hits or m-mismatch hits -- keeps the documents that share the
query's coarse course of relations (e.g. "a foot raised, then both down") and drops most others, whatever their
speed or style. The numeric stage (Krüger et al. 2010 §3.2 features, :class:`mocapviz.similarity.search.SimilaritySearch`)
aligns the whole query with each candidate document by DTW and ranks them by cost / (query frames + document
frames). This is the refinement the 2005 paper points to at the end of §6.2 ("one could refine the retrieval results
by applying more involved DTW-based techniques, see Sect. 7"): the index cuts the search space down, DTW ranks.

hybrid_search     example -> DataFrame of ranked candidate documents.
HYBRID_QUERIES    lenient selections per HDM05 class (keyword arguments of hybrid_search).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..db.hits import HitTable, hit_table
from ..errors import ParameterError
from ..motion import Motion
from ..relational.query import MODES, query_by_example
from ..validation import count
from .search import SimilaritySearch

# Lenient selections per HDM05 class for the hybrid, as keyword arguments of hybrid_search: fewer features than
# DEFAULT_QUERIES (mocapviz.experiments.relational), so that the relational stage keeps (nearly) every clip of the
# class and DTW sorts out the rest. Chosen on the 287 HDM05 cut clips, leave-actor-out (query clips of one actor,
# candidate documents of the other four), by the hybrid's mean AP at 30 Hz and checked at 120 Hz; docs/similarity.md
# gives the numbers. Kick: both feet raised, adaptive (recall 1; the four Fig. 9 features keep a third of the kicks).
# Throw: the left hand above the neck alone (recall 1; both hands give varying run orders and miss 80 %), ranked
# with F15x3E (windows of F15E), which tells throws from arm rotations and elbow-to-knee better than F15E.
HYBRID_QUERIES: dict[str, dict] = {
    "kickLFront1Reps": {"features": ["lfoot_raised", "rfoot_raised"], "mode": "adaptive", "numeric_set": "F15E"},
    "throwBasketball": {"features": ["lhand_above_neck"], "mode": "adaptive", "numeric_set": "F15x3E"},
}

HIT_COLUMNS = {"start": "hit_start", "end": "hit_end", "score": "hit_score"}  # the best relational hit (half-open)


def _example_motion(db, example) -> tuple[Motion, int | None]:
    """The query clip and its document (None for a Motion)."""
    if isinstance(example, Motion):
        return example, None
    if isinstance(example, (int, np.integer)) and not isinstance(example, (bool, np.bool_)):
        return db.motion(int(example)), int(example)
    raise ParameterError(f"example must be a doc id of {db.path} or a Motion; got {type(example).__name__}")


def hybrid_search(db, example, features=None, mode: str = "adaptive", mismatches: int = 1, relational_set: str = "2005",
                  numeric_set: str = "F15E", n_matches: int | None = None, indexes: dict | None = None, search=None,
                  exclude_document: bool = True) -> pd.DataFrame:  # fmt: skip
    """Relational hits as candidate documents, re-ranked by whole-clip DTW on a numeric set.

    Parameters
    ----------
    db : MotionDB
        With relational indexes (:func:`mocapviz.relational.index.build`); numeric features are read when stored, else computed.
    example : int or Motion
        The query clip: a doc id of ``db`` (the whole document) or a Motion (resampled for the DTW when its rate
        differs from the database's).
    features : list of str, optional
        The relational selection (names of ``relational_set``); default all, as
        :func:`~mocapviz.relational.query.query_by_example` (strict: few candidates). :data:`HYBRID_QUERIES` holds lenient ones per HDM05 class.
    mode : {"adaptive", "fuzzy", "exact", "mismatch"}
        The relational hits (see :func:`~mocapviz.relational.query.query_by_example`); lenient: ``adaptive`` or ``mismatch``.
    mismatches : int
        m for ``mode="mismatch"``.
    relational_set : {"2005", "2006"}
        The relational feature set.
    numeric_set : str
        The numeric set of the DTW (:data:`mocapviz.features.NUMERIC_SETS`; default F15E, cm); that of ``search``
        when one is given.
    n_matches : int, optional
        Documents to return at most (default: every candidate).
    indexes : dict, optional
        Group -> InvertedIndex, if already loaded.
    search : SimilaritySearch, optional
        The DTW search to rank with (built once and reused over many queries; its ``documents`` restrict the
        candidates, e.g. to the other actors' clips in a leave-actor-out evaluation). Default:
        ``SimilaritySearch(db, numeric_set)`` over every document.
    exclude_document : bool
        Leave the query's own document (when ``example`` is a doc id) out of the candidates.

    Returns
    -------
    pandas.DataFrame, one row per candidate document, best first: the hit table of
    :func:`mocapviz.db.hits.hit_table` (``rank``, ``doc_id``, ``name``, ``start`` 0 and ``end`` the document's
    frames, ``frames``, ``start_s``, ``end_s``), ``cost`` (accumulated Euclidean DTW cost of the whole query against the whole document, in
    ``numeric_set`` units), ``normalised_cost`` (cost / (query frames + document frames)), the label columns, and
    the document's best relational hit: ``hit_start``, ``hit_end`` (frames of the document, half-open), ``hit_score`` (§6.2,
    seconds). ``attrs``: ``relational_hits`` (hits of the relational stage), ``candidates`` (documents ranked).

    Raises
    ------
    ParameterError
        A bad ``example``, ``mode`` or ``n_matches``, a ``search`` over another numeric set; the relational and
        numeric stages raise their own errors.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §6.2 (hits of a query by example, to be refined by DTW-based techniques, §7).
    .. [2] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.2 (the numeric features the DTW compares).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> ranked = hybrid_search(db, 7, ["lfoot_raised"], indexes=build(db, save=False, progress=False))
    >>> ranked["label"].tolist(), ranked["normalised_cost"].round(2).tolist()  # 4 candidates, the other kick first
    (['kickLFront1Reps', 'depositFloorR', 'squat1Reps', 'squat1Reps'], [24.25, 53.03, 54.83, 68.01])
    """
    if mode not in MODES:
        raise ParameterError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
    if n_matches is not None:  # None: every candidate
        count(n_matches, "n_matches")
    motion, own = _example_motion(db, example)
    if search is None:
        search = SimilaritySearch(db, numeric_set)
    elif search.numeric_set != numeric_set:
        raise ParameterError(f"numeric_set {numeric_set!r} differs from the search's {search.numeric_set!r}; pass "
                             f"numeric_set={search.numeric_set!r} or a SimilaritySearch over {numeric_set}")
    hits = query_by_example(db, motion, features, mode=mode, mismatches=mismatches, relational_set=relational_set,
                            indexes=indexes)  # fmt: skip
    # each document once, with its best hit (hits come best first)
    best = hits.drop_duplicates("doc_id").rename(columns=HIT_COLUMNS)[["doc_id", *HIT_COLUMNS.values()]]
    keep = best["doc_id"].isin(search.documents["doc_id"])
    if exclude_document:
        keep &= best["doc_id"] != own
    best = best[keep]
    if best.empty:
        ranked = hit_table(db, [], [], [], cost=np.zeros(0), normalised_cost=np.zeros(0))
    else:
        ranked = search.clips(motion if own is None else own, mode="exact", candidates=best["doc_id"].to_numpy(),
                              n_matches=len(best) if n_matches is None else min(n_matches, len(best)))  # fmt: skip
    out = HitTable(ranked.merge(best, on="doc_id", how="left"))
    out.attrs.update(relational_hits=len(hits), candidates=len(best))
    return out
