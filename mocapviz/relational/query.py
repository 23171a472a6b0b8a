"""Query by example over the relational indexes of a MotionDB (Müller, Röder & Clausen 2005, §5–6.2).

A query is a motion clip plus a choice of relational features from any of the three groups (lower, upper,
mix). For each group touched by the choice, the clip's own segmentation under the chosen features gives the
query sequence; features left out are "don't care", which makes every query segment a fuzzy set of
feature vectors (§5.2: restricting F to some components = a special choice of fuzzy sets). Hits of several
groups are joined when they overlap in the same document. Hits are ranked by the temporal heuristic of
§6.2: the sum over query segments of the difference between query and hit segment durations.

query_by_example   Motion (or its RelationalExample) + feature names -> DataFrame of ranked hits.
example_hits       the same hits, the arguments taken as checked (a shard's part of a sharded query).
check_example_query those checks, once, where the whole database is known.
relational_example a Motion's frame-wise values of a relational set: what a query needs of its example (a few kB,
                   what a sharded query sends to its shards instead of the clip).
query_segmentation the query sequence per feature group: the example's segmentation on the selected features.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd

from ..db.hits import hit_table
from ..errors import ParameterError
from ..features import feature_groups, feature_names, relational_features
from ..features.segmentation import segment
from ..validation import some_of
from . import index as index_mod

MODES = ("adaptive", "fuzzy", "exact", "mismatch")


class RelationalExample(NamedTuple):
    """What query by example needs of its example clip: the frame-wise values of one relational set and the rate.

    Attributes
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The example's relational features (:func:`mocapviz.features.relational_features`), columns ``names``.
    names : list of str [length f]
        The feature names of ``relational_set``.
    fps : float
        The example's frames per second.
    relational_set : str
        "2005" or "2006".
    """

    values: np.ndarray
    names: list
    fps: float
    relational_set: str

    @property
    def duration(self) -> float:
        """The example's length in seconds (T / fps)."""
        return len(self.values) / self.fps


def relational_example(example, relational_set: str = "2005") -> RelationalExample:
    """The values of ``relational_set`` of an example clip, computed once (a RelationalExample is returned as is).

    Parameters
    ----------
    example : Motion or RelationalExample
    relational_set : {"2005", "2006"}

    Returns
    -------
    RelationalExample

    Raises
    ------
    ParameterError
        A RelationalExample of another relational set.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> ex = relational_example(MotionDB.sample().motion(7))
    >>> ex.values.shape, ex.fps, round(ex.duration, 3)
    ((129, 31), 120.0, 1.075)
    """
    if isinstance(example, RelationalExample):
        if example.relational_set != relational_set:
            raise ParameterError(f"the example's values are of the {example.relational_set} set; the query asks for "
                                 f"the {relational_set} set: compute them with relational_example(motion, "
                                 f"{relational_set!r})")  # fmt: skip
        return example
    values, names = relational_features(example, relational_set)
    return RelationalExample(values, list(names), float(example.fps), relational_set)


def _check_features(features, relational_set: str) -> list[str]:
    names = feature_names(relational_set)
    if features is None:
        return list(names)
    features = [features] if isinstance(features, str) else list(features)
    if not features:
        raise ParameterError(f"no features selected; choose some of the {relational_set} set: {', '.join(names)}")
    return some_of(features, "feature(s)", names)


def query_segmentation(values: np.ndarray, names: list[str], features, relational_set: str = "2005") -> dict:
    """The query sequence of each feature group an example's selection touches (§5.2): the example's segmentation
    on the selected features of the group alone (the others set to 0, so codes keep the group's bit numbering).

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The example's relational features, columns ``names``.
    names : list of str [length f]
        The feature names of ``relational_set``.
    features : list of str
        The selected feature names (checked against the set); None: all.
    relational_set : {"2005", "2006"}
        The relational set.

    Returns
    -------
    dict
        Group -> (chosen, seq): ``chosen`` the selected columns within the group's features, ``seq`` the
        :class:`~mocapviz.features.segmentation.FeatureSequence` (``seq.codes``: the L query segments,
        ``seq.lengths`` their frames); groups without a selected feature are left out.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import relational_features
    >>> values, names = relational_features(MotionDB.sample().motion(7))
    >>> groups = query_segmentation(values, names, ["lfoot_raised", "rhand_in_front"])
    >>> {group: (chosen, len(seq.codes)) for group, (chosen, seq) in groups.items()}
    {'lower': ([3], 3), 'upper': ([0], 1)}
    """
    chosen = _check_features(features, relational_set)
    out = {}
    for group, members in feature_groups(relational_set).items():
        picked = [members.index(f) for f in chosen if f in members]
        if picked:
            keep = np.isin(np.arange(len(members)), picked)
            out[group] = (picked, segment(values[:, [names.index(n) for n in members]] & keep))
    return out


def _group_hits(idx: index_mod.InvertedIndex, seq, chosen: list[int], mode: str, mismatches: int,
                allowed=None) -> tuple[np.ndarray, np.ndarray]:
    """Hits of one group as stored-segment bounds, and the query's segment lengths.

    ``seq`` is the query sequence of this group and ``chosen`` its selected columns (:func:`query_segmentation`).
    Returns ``bounds`` [shape=(H, L+1)] (stored segment where each hit segment starts, then the stop) and the
    query's segment lengths in frames [shape=(L,)].
    """
    if mode == "mismatch":
        return idx.adaptive_mismatch(seq.codes, chosen, min(mismatches, len(seq.codes) - 1), allowed), seq.lengths
    mask = int(np.sum(np.int64(1) << np.asarray(chosen, dtype=np.int64)))
    # V_l: every occurring code of the group that agrees with the query's segment l on the chosen features
    sets = [idx.list_codes[(idx.list_codes & mask) == c] for c in seq.codes]
    if any(s.size == 0 for s in sets):
        return np.empty((0, len(sets) + 1), dtype=np.int64), seq.lengths
    if mode == "fuzzy":
        k = idx.fuzzy(sets)
        return k[:, None] + np.arange(len(sets) + 1), seq.lengths
    return idx.adaptive_fuzzy(sets), seq.lengths


def longer_than_every_document(db, example) -> str:
    """Why ``example`` can match nothing in ``db`` (it lasts longer than every document), or "".

    Parameters
    ----------
    db : MotionDB
    example : Motion

    Returns
    -------
    str
        The message of the ParameterError :func:`query_by_example` raises, or "" when some document is as long.
    """
    docs = db.documents
    longest = float((docs["n_frames"] / docs["fps"]).max()) if len(docs) else 0.0
    if example.duration <= longest:
        return ""
    return (f"the query lasts {example.duration:.2f} s, longer than every document of {db.path} (longest "
            f"{longest:.2f} s); choose a shorter span")


def query_by_example(db, example, features=None, mode: str = "adaptive", mismatches: int = 1,
                     relational_set: str = "2005", indexes: dict | None = None, allowed=None) -> pd.DataFrame:
    """Find the stretches of a MotionDB that move like ``example`` in the chosen feature aspects.

    Parameters
    ----------
    db : MotionDB
        With relational indexes built (:func:`mocapviz.relational.index.build` / ``mocapviz index DB``).
    example : Motion or RelationalExample
        The query clip (any skeleton; e.g. ``db.motion(3)[120:360]`` or ``mocapviz.load(path)``), or its values
        (:func:`relational_example`).
    features : list of str, optional
        Feature names of ``relational_set`` (any groups); the rest are "don't care". Default: all.
    mode : {"adaptive", "fuzzy", "exact", "mismatch"}
        In every mode only the selected features count and the query is segmented on them alone.
        ``adaptive`` (default): adaptive fuzzy hits, the database segmentation coarsened to the query's
        don't-care sets (§5.2). The sets (every vector that agrees with the query on the selected features)
        partition the vectors, so the coarsened segmentation is the database's segmentation under the selected
        features alone, and these are the *exact* hits of the selection. ``exact``: those same hits (eq. 7 for
        the feature function restricted to the selection, §5.2); selecting every feature of a group gives the
        strict form of §5.1 on the stored segmentation. ``mismatch``: as exact, with at most ``mismatches``
        of the query's segments allowed to disagree (each a run of the selected features in the database, as
        :meth:`~mocapviz.relational.index.InvertedIndex.adaptive_mismatch`); ``mismatches`` is capped at the query's
        segments - 1. ``fuzzy``: plain fuzzy hits (§5.2, eq. 11) on the database segmentation as stored, i.e.
        under *all* features of the group: query segment l must be exactly one stored segment. A left-out
        feature that changes inside a query segment splits the database's segments there, so the query's
        coarser segments do not line up with whole stored segments and the stretch is no hit -- plain fuzzy
        hits therefore can miss the query's own clip (the four kick features on a kick clip find nothing, not
        even the clip itself); adaptive fuzzy hits (§5.2) were made for exactly this.
    mismatches : int
        m for ``mode="mismatch"``, at least 0.
    allowed : list of int, optional
        For ``mode="mismatch"``: the 0-based query segments (of the selected features' segmentation) that may
        disagree (default: any).
    relational_set : {"2005", "2006"}
    indexes : dict, optional
        Group -> InvertedIndex, if already loaded (default :func:`mocapviz.relational.index.load`).

    Returns
    -------
    pandas.DataFrame, one row per hit, best first: the hit table of :func:`mocapviz.db.hits.hit_table` (``rank``,
    ``doc_id``, ``name``, ``start``, ``end`` in the document's frames, half-open, ``frames``, ``start_s``,
    ``end_s``), then ``first_segment``, ``last_segment`` (database segment positions, of the first group queried),
    ``n_segments`` (query segments), ``score`` (seconds of segment-duration difference; lower is better), and the
    label columns of the documents.

    Raises
    ------
    ValueError
        Unknown or no features, unknown mode, a query longer than every document.
    ParameterError
        ``mismatches`` below 0, ``allowed`` positions outside the query's segments.
    MotionDBError
        The database has no (current) index.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §5.2 (fuzzy and adaptive fuzzy hits, m-mismatch hits: a selection of features as fuzzy sets)
       and §6.2 (query by example, hits ranked by the temporal heuristic).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> indexes = build(db, save=False, progress=False)  # or stored once: `mocapviz index DB`
    >>> hits = query_by_example(db, db.motion(7), ["lfoot_raised"], indexes=indexes)  # kick with the left foot
    >>> print(hits[["rank", "doc_id", "label", "score"]].round(3).to_string(index=False))
     rank  doc_id           label  score
        1       7 kickLFront1Reps  0.000
        2      11      squat1Reps  0.250
        3      18 kickLFront1Reps  0.358
        4      22      squat1Reps  0.500
        5       2   depositFloorR  1.350
    >>> hits = query_by_example(db, db.motion(7), ["lfoot_raised", "lknee_bent"], indexes=indexes)
    >>> hits["label"].tolist()  # two aspects: only the kicks
    ['kickLFront1Reps', 'kickLFront1Reps']
    """
    check_example_query(db, example, features, mode, mismatches, relational_set)
    return example_hits(db, example, features, mode, mismatches, relational_set, indexes, allowed)


def check_example_query(db, example, features, mode: str, mismatches: int, relational_set: str) -> None:
    """Refuse what :func:`query_by_example` cannot answer in ``db`` (checked once, where the whole database is known).

    Parameters
    ----------
    db, example, features, mode, mismatches, relational_set
        As :func:`query_by_example`.

    Raises
    ------
    ParameterError
        An unknown mode or feature, ``mismatches`` below 0, an example longer than every document of ``db``.
    """
    if mode not in MODES:
        raise ParameterError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if mode == "mismatch" and not (isinstance(mismatches, (int, np.integer)) and mismatches >= 0):
        raise ParameterError(f"mismatches must be an integer >= 0 (query segments that may disagree), "
                             f"got {mismatches!r}")
    _check_features(features, relational_set)
    too_long = longer_than_every_document(db, example)
    if too_long:
        raise ParameterError(too_long)


def example_hits(db, example, features, mode: str, mismatches: int, relational_set: str, indexes: dict | None = None,
                 allowed=None) -> pd.DataFrame:
    """:func:`query_by_example`'s hits, its arguments taken as already checked: for a part of a database (a shard,
    :mod:`mocapviz.sharded`), where a document shorter than the example may still hold a hit (adaptive segments
    need not last as long as the query's), so the whole database's length check must not be repeated per part.

    Parameters
    ----------
    db, example, features, mode, mismatches, relational_set, indexes, allowed
        As :func:`query_by_example`, checked by it.

    Returns
    -------
    pandas.DataFrame
        :func:`query_by_example`'s table; attrs ``group_segments``: the segments of the first group queried in
        ``db``'s index (the numbering of ``first_segment`` / ``last_segment``, so that a shard's can be offset).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> indexes = build(db, save=False, progress=False)
    >>> hits = example_hits(db, db.motion(7), ["lfoot_raised"], "adaptive", 1, "2005", indexes)
    >>> hits["doc_id"].tolist()[:3], hits.attrs["group_segments"] == indexes["lower"].n_segments
    ([7, 11, 18], True)
    """
    indexes = index_mod.load(db, relational_set) if indexes is None else indexes
    docs = db.documents
    values, names, _, _ = relational_example(example, relational_set)
    doc_fps = docs["fps"].to_numpy(np.float64)  # per document: a database may mix frame rates
    tables = []
    segmentation = query_segmentation(values, names, features, relational_set)
    first_group = next(iter(segmentation))
    for group, (picked, seq) in segmentation.items():
        idx = indexes[group]
        bounds, q_len = _group_hits(idx, seq, picked, mode, mismatches, allowed)
        first, stop = bounds[:, 0], bounds[:, -1]
        seg_frames = idx.starts[np.minimum(bounds, idx.n_segments - 1)]
        seg_frames[:, -1] = idx.starts[stop - 1] + idx.lengths[stop - 1] if len(stop) else seg_frames[:, -1]
        doc_row = idx.segment_doc[first]
        hit_len = np.diff(seg_frames, axis=1) / doc_fps[doc_row][:, None]  # seconds, at the hit document's rate
        score = np.abs(hit_len - q_len / example.fps).sum(axis=1)
        doc_start = docs["start"].to_numpy()[doc_row]
        tables.append(pd.DataFrame({
            "doc_row": doc_row,
            "start": idx.starts[first] - doc_start,
            "end": seg_frames[:, -1] - doc_start,
            "first_segment": first,
            "last_segment": stop - 1,
            "n_segments": len(q_len),
            "score": score,
        }))  # fmt: skip
    hits = tables[0]
    for other in tables[1:]:
        # several groups: keep pairs of hits in one document whose frame spans overlap
        joined = hits.merge(other, on="doc_row", suffixes=("", "_b"))
        joined = joined[(joined["start"] < joined["end_b"]) & (joined["start_b"] < joined["end"])]
        joined = joined.assign(start=np.minimum(joined["start"], joined["start_b"]),
                               end=np.maximum(joined["end"], joined["end_b"]),
                               score=joined["score"] + joined["score_b"],
                               n_segments=joined["n_segments"] + joined["n_segments_b"])  # fmt: skip
        hits = joined[[c for c in hits.columns]]
    cols = {c: hits[c].to_numpy() for c in ("start", "end", "first_segment", "last_segment", "n_segments", "score")}
    doc_id = docs["doc_id"].to_numpy()[hits["doc_row"].to_numpy(np.int64)]
    rows = np.lexsort((cols["start"], doc_id, cols["score"]))  # by score, then doc id and start
    cols = {c: v[rows] for c, v in cols.items()}
    table = hit_table(db, doc_id[rows], cols.pop("start"), cols.pop("end"), **cols)
    table.attrs["group_segments"] = indexes[first_group].n_segments
    return table

