"""Experiments of Müller, Röder & Clausen 2005, §6 (relational indexing and retrieval), as DataFrames.

index_statistics    Table 2: per group index (lower, upper, mix) the number of features f, lists, frames,
                    segments, size and the times to read, compute features and build the index.
mueller2005_table2  Table 2 as printed in the paper (I^60 and I^180 indexes), in the same columns.
random_queries      random query sequences of a database that are guaranteed at least one hit (§6.2).
query_statistics    Table 3: exact and adaptive fuzzy random queries on one index, grouped by hit count.
mueller2005_table3  Table 3 as printed in the paper, in the same columns.
relational_query    Figs. 7-9 (§6.2): query by example for each labelled class, with precision and recall.
DEFAULT_QUERIES     the feature selection per HDM05 class used by :func:`relational_query`.
"""
from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..features import feature_names, relational_features
from ..parallel import progress_bar
from ..relational import index as index_mod
from . import evaluation

__all__ = [
    "ALTERNATIVES",
    "DEFAULT_QUERIES",
    "HIT_GROUPS",
    "index_statistics",
    "mueller2005_table2",
    "mueller2005_table3",
    "query_statistics",
    "random_queries",
    "relational_query",
]

TABLE2_COLUMNS = ["index", "group", "minutes", "f", "2^f", "lists", "frames", "segments", "MB", "bytes/segment",
                  "t_read", "t_features", "t_index", "t_total"]  # fmt: skip
TABLE3_COLUMNS = ["mode", "L", "hits", "queries", "mean_hits", "std_hits", "mean_ms", "median_ms", "p90_ms"]
HIT_GROUPS = ("1–9", "10–99", "≥100")  # Table 3's groups by the number of hits h
_GROUP_SYMBOL = {"lower": "l", "upper": "u", "mix": "m"}
_MODES = ("exact", "fuzzy")

# Feature selections per HDM05 class, after the paper's query-by-example figures: Fig. 7 (punch: hands in front
# + elbows bent, F_u1 F_u2 F_u7 F_u8), Fig. 8 (squat: knee bent + feet fast, from F_l5 F_l6 F_l7 ...), Fig. 9
# (kick: feet raised + knees bent, F_l3 F_l4 F_l7 F_l8); locomotion uses "foot in front/behind" as in the walking
# example of Figs. 3-6. Few features per query: a query clip's whole length is matched, and every extra feature
# adds segments that other takes order differently. Chosen by trying a few selections on the 287 HDM05 cut
# clips at 120 Hz, each queried with its class's first clip and the table printed by the benchmark.
DEFAULT_QUERIES: dict[str, list[str]] = {
    "depositFloorR": ["torso_bent", "rhand_touching_leg"],
    "elbowToKnee1RepsLelbowStart": ["rfoot_raised", "lfoot_raised"],
    "grabHighR": ["rhand_above_neck", "rhand_in_front"],
    "hopBothLegs1hops": ["rknee_bent", "lknee_bent"],
    "jogLeftCircle4StepsRstart": ["rfoot_behind", "lfoot_behind"],
    "kickLFront1Reps": ["rfoot_raised", "lfoot_raised", "rknee_bent", "lknee_bent"],
    "lieDownFloor": ["torso_bent", "rknee_bent", "lknee_bent"],
    "rotateArmsBothBackward1Reps": ["rhand_above_neck", "rarm_sideways"],
    "sneak2StepsLStart": ["rfoot_behind", "lfoot_behind", "rknee_bent", "lknee_bent"],
    "squat1Reps": ["rknee_bent", "rfoot_fast", "lfoot_fast"],
    "throwBasketball": ["rhand_above_neck", "lhand_above_neck"],
}


# ============================================================================ Table 2
def index_statistics(db, relational_set: str = "2005", values: np.ndarray | None = None, t_read: float | None = None,
                     t_features: float | None = None) -> pd.DataFrame:  # fmt: skip
    """Feature computation and index construction statistics (Müller, Röder & Clausen 2005, Table 2).

    One row per feature group: the group's index (lower ``I_l``, upper ``I_u``, mix ``I_m``) over all frames of
    ``db``. The indexes are built in memory (:meth:`mocapviz.relational.index.InvertedIndex.from_features`) and not saved;
    ``mocapviz.relational.index.build`` does the same and writes them.

    Parameters
    ----------
    db : MotionDB
    relational_set : {"2005", "2006"}
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's relational features if already computed (then ``t_features`` is the caller's figure, or
        NaN); default: computed here with :func:`mocapviz.features.relational_features` and timed.
    t_read : float, optional
        Seconds spent reading the data, measured by the caller: e.g. the wall time of ``MotionDB.ingest`` that
        built ``db`` from the motion files. NaN when not given (the database was already read).
    t_features : float, optional
        Seconds of the feature computation when ``values`` is given.

    Returns
    -------
    pandas.DataFrame
        One row per group, columns ``index`` (``I_l^<minutes>`` ...), ``group``, ``minutes`` (of motion), ``f``,
        ``2^f``, ``lists`` (non-empty inverted lists), ``frames``, ``segments``, ``MB`` (index size,
        :meth:`InvertedIndex.nbytes` / 2^20, the paper's MB: 4.33 MB / 135,742 segments = 33.4 bytes/segment),
        ``bytes/segment``, ``t_read``, ``t_features``, ``t_index``, ``t_total`` (seconds; ``t_total`` = sum of
        the three, NaN parts count as 0).

    Notes
    -----
    ``t_features`` is the time of all f features of the set, computed in one pass for the three groups (the
    paper computed each group on its own), so the same value appears on every row. ``t_index`` is the group's
    segmentation plus inverted-list construction (``time.perf_counter``), without writing the file.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §6.1, Table 2 (:func:`mueller2005_table2` holds the paper's figures).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> table = index_statistics(MotionDB.sample())  # the sample's 0.8 minutes at 120 Hz
    >>> print(table[["index", "group", "f", "lists", "frames", "segments"]].to_string(index=False))
    index group  f  lists  frames  segments
    I_l^1 lower 11     84    5543       338
    I_u^1 upper 12    107    5543       281
    I_m^1   mix  8     16    5543       144
    """
    names = feature_names(relational_set)
    if values is None:
        t0 = time.perf_counter()
        values, names = relational_features(db, relational_set, progress=False)
        t_features = time.perf_counter() - t0
    values = np.asarray(values)
    if values.shape != (db.n_frames, len(names)):
        raise ParameterError(f"values must have shape ({db.n_frames}, {len(names)}) (frames of the database, features "
                         f"of the {relational_set} set), got {values.shape}")  # fmt: skip
    doc_starts = db.documents["start"].to_numpy(np.int64)
    minutes = float((db.documents["n_frames"] / db.documents["fps"]).sum() / 60.0)  # per document: rates may mix
    t_read = float("nan") if t_read is None else float(t_read)
    t_features = float("nan") if t_features is None else float(t_features)
    rows = []
    groups = index_mod.feature_group_values(values, relational_set).items()
    for group, (members, group_values) in progress_bar(groups, desc="group indexes", unit="index", disable=True):
        t0 = time.perf_counter()
        idx = index_mod.InvertedIndex.from_features(group_values, doc_starts, members)
        t_index = time.perf_counter() - t0
        nbytes = idx.nbytes()
        rows.append({
            "index": f"I_{_GROUP_SYMBOL.get(group, group)}^{minutes:.0f}",
            "group": group,
            "minutes": minutes,
            "f": idx.n_features,
            "2^f": 2**idx.n_features,
            "lists": int(idx.list_codes.size),
            "frames": int(db.n_frames),
            "segments": int(idx.n_segments),
            "MB": nbytes / 2**20,
            "bytes/segment": nbytes / idx.n_segments if idx.n_segments else float("nan"),
            "t_read": t_read,
            "t_features": t_features,
            "t_index": t_index,
            "t_total": np.nansum([t_read, t_features, t_index]),
        })  # fmt: skip
    return pd.DataFrame(rows, columns=TABLE2_COLUMNS)


def mueller2005_table2() -> pd.DataFrame:
    """Table 2 of Müller, Röder & Clausen 2005 (Matlab, 3.6 GHz Pentium 4), in the columns of
    :func:`index_statistics`: the indexes of the 60-minute subset D^60 and the 180-minute database D^180 (120 Hz).

    Returns
    -------
    pandas.DataFrame
        Six rows (I_l, I_u, I_m of each database), the columns of :func:`index_statistics`; sizes in MB,
        times in seconds.

    Examples
    --------
    >>> mueller2005_table2()[["index", "f", "lists"]].head(2).values.tolist()
    [['I_l^60', 11, 409], ['I_l^180', 11, 550]]
    """
    raw = [  # index, group, minutes, f, lists, frames, segments, MB, bytes/segment, t_read, t_features, t_index, total
        ("I_l^60", "lower", 60, 11, 409, 425_294, 21_108, 0.72, 35.8, 26, 10, 6, 42),
        ("I_l^180", "lower", 180, 11, 550, 1_288_846, 41_587, 1.41, 35.5, 71, 26, 13, 110),
        ("I_u^60", "upper", 60, 12, 642, 425_294, 53_036, 1.71, 33.8, 26, 13, 10, 49),
        ("I_u^180", "upper", 180, 12, 877, 1_288_846, 135_742, 4.33, 33.4, 71, 33, 25, 129),
        ("I_m^60", "mix", 60, 8, 55, 425_294, 19_067, 0.60, 33.0, 26, 20, 3, 49),
        ("I_m^180", "mix", 180, 8, 75, 1_288_846, 55_526, 1.80, 34.0, 71, 54, 12, 137),
    ]
    rows = [dict(zip(["index", "group", "minutes", "f", "lists", "frames", "segments", "MB", "bytes/segment",
                      "t_read", "t_features", "t_index", "t_total"], r)) for r in raw]  # fmt: skip
    out = pd.DataFrame(rows)
    out["2^f"] = 2 ** out["f"]
    for c in ("minutes", "t_read", "t_features", "t_index", "t_total"):
        out[c] = out[c].astype(float)
    return out[TABLE2_COLUMNS]


# ============================================================================ Table 3
def _valid_starts(index, length: int) -> np.ndarray:
    """Segment positions k such that segments k .. k+length-1 exist and lie in one document."""
    k = np.arange(max(0, index.n_segments - length + 1))
    return k[index.segment_doc[k] == index.segment_doc[k + length - 1]]


ALTERNATIVES = ("disjoint", "random", "dont_care")


def random_queries(index, n_queries: int, length: int, mode: str = "exact", fuzzy_size: int = 64,
                   rng: np.random.Generator | int | None = 0, alternatives: str = "disjoint") -> list:  # fmt: skip
    """Random queries guaranteed to have at least one hit (Müller, Röder & Clausen 2005, §6.2 and Table 3).

    Each query takes ``length`` consecutive segments w_k .. w_{k+L-1} of the indexed feature sequence, at a
    position k drawn uniformly among those whose L segments lie in one document.

    Parameters
    ----------
    index : InvertedIndex
        The index queried (one feature group's).
    n_queries, length : int
        Number of queries and segments per query (L = |Q|).
    mode : {"exact", "fuzzy"}
        ``exact``: the query is the codes (w_k, ..., w_{k+L-1}) [shape=(L,)]. ``fuzzy``: a list of L fuzzy sets
        V_1..V_L of ``fuzzy_size`` codes each, V_l holding w_{k+l-1}; every such query has an adaptive fuzzy hit
        at the run that contains segment k (also when the index conjoins overlapping neighbours).
    fuzzy_size : int
        Elements per fuzzy set (the paper: 64).
    rng : numpy.random.Generator, int or None
        The random generator, or its seed.
    alternatives : {"disjoint", "random", "dont_care"}
        How the other ``fuzzy_size - 1`` codes of a fuzzy set are drawn (fuzzy queries only; the paper does not
        say). ``disjoint`` (default): at random among the codes {0, ..., 2^f - 1} outside V_{l-1} and other than
        w_{k+l}, so that adjacent sets are disjoint as §5.2 defines a fuzzy query and the query keeps its L
        sets. ``random``: at random among all codes; adjacent sets then often meet (two random 64-subsets of
        4096 codes share one code on average) and the index conjoins them, so the query shrinks to a few large
        sets. ``dont_care``: log2(fuzzy_size) randomly chosen features of w_{k+l-1} are left free (the set is
        the 2^d vectors that agree with it on the other features), as a feature selection makes them (§5.2).

    Returns
    -------
    list of (int, query)
        Per query the segment position k it was taken from, and the query (codes or fuzzy sets).

    Raises
    ------
    ValueError
        No document has ``length`` segments, an unknown mode or ``alternatives``, or a ``fuzzy_size`` that
        does not fit (more than about half of the 2^f codes for ``disjoint``; not a power of 2 up to 2^f for
        ``dont_care``).
    """
    if mode not in _MODES:
        raise ParameterError(f"mode must be one of {', '.join(_MODES)}, got {mode!r}")
    if alternatives not in ALTERNATIVES:
        raise ParameterError(f"alternatives must be one of {', '.join(ALTERNATIVES)}, got {alternatives!r}")
    f = index.n_features
    n_codes = 2**f
    if mode == "fuzzy":
        if alternatives == "dont_care":
            if fuzzy_size < 1 or fuzzy_size & (fuzzy_size - 1) or fuzzy_size > n_codes:
                raise ParameterError(f"fuzzy_size must be a power of 2 up to 2^f = {n_codes} for alternatives="
                                 f"'dont_care', got {fuzzy_size}")  # fmt: skip
        else:
            most = (n_codes - 1) // 2 if alternatives == "disjoint" else n_codes
            if not 1 <= fuzzy_size <= most:
                raise ParameterError(f"fuzzy_size must lie in [1, {most}] for 2^f = {n_codes} codes and "
                                 f"alternatives={alternatives!r}, got {fuzzy_size}")  # fmt: skip
    rng = np.random.default_rng(rng)
    starts = _valid_starts(index, length)
    if starts.size == 0:
        raise ParameterError(f"no document has {length} consecutive segments; choose a shorter query length")
    free_bits = fuzzy_size.bit_length() - 1
    # every combination of free_bits bits, as rows of 0/1: the offsets of a don't-care set
    combos = (np.arange(fuzzy_size)[:, None] >> np.arange(free_bits)) & 1
    allowed = np.ones(n_codes, dtype=bool)
    out = []
    for k in rng.choice(starts, size=n_queries):
        codes = index.codes[k : k + length]
        if mode == "exact":
            out.append((int(k), codes.copy()))
            continue
        sets = []
        for j, c in enumerate(codes):
            if alternatives == "dont_care":
                bits = rng.choice(f, size=free_bits, replace=False)
                fixed = int(c) & ~int(np.sum(np.int64(1) << bits))
                others = fixed | (combos << bits).sum(axis=1)
                others = others[others != c]
            else:
                allowed[:] = True
                allowed[c] = False
                if alternatives == "disjoint":
                    if sets:
                        allowed[sets[-1]] = False
                    if j + 1 < length:
                        allowed[codes[j + 1]] = False
                others = rng.choice(np.flatnonzero(allowed), size=fuzzy_size - 1, replace=False)
            sets.append(np.concatenate([[c], others]).astype(np.int64))
        out.append((int(k), sets))
    return out


def _hit_group(h: int) -> str:
    return HIT_GROUPS[0] if h < 10 else HIT_GROUPS[1] if h < 100 else HIT_GROUPS[2]


def query_statistics(index, n_queries: int = 10_000, lengths=(5, 10, 20), modes=("exact", "fuzzy"),
                     fuzzy_size: int = 64, seed: int = 0, alternatives: str = "disjoint",
                     per_query: bool = False) -> pd.DataFrame:  # fmt: skip
    """Random query statistics on one index (Müller, Röder & Clausen 2005, Table 3; the paper uses I_u^180).

    For each mode and query length L, ``n_queries`` queries from :func:`random_queries` (each has at least one
    hit). ``exact`` queries go to :meth:`InvertedIndex.exact`; ``fuzzy`` queries, sets of ``fuzzy_size``
    alternatives, to :meth:`InvertedIndex.adaptive_fuzzy`, as the paper's Table 3 fuzzy queries are adaptive
    (§6.2). Each query is timed alone with ``time.perf_counter`` (building the random sets is not timed).

    Parameters
    ----------
    index : InvertedIndex
        One group's index (the paper: the upper group, I_u^180).
    n_queries : int
        Queries per (mode, L) cell (the paper: 10,000).
    lengths : tuple of int
        Query lengths |Q| in segments.
    modes : tuple of {"exact", "fuzzy"}
        Exact queries, and adaptive fuzzy queries.
    fuzzy_size : int
        Alternatives per fuzzy set (the paper: 64).
    seed : int
        Seed of the random queries.
    alternatives : {"disjoint", "random", "dont_care"}
        How fuzzy sets are drawn, see :func:`random_queries` (default: random codes, adjacent sets disjoint).
    per_query : bool
        Return one row per query instead of the grouped table: ``mode``, ``L``, ``k`` (the segment position the
        query was taken from), ``query`` (the codes [shape=(L,)], or the list of L fuzzy sets), ``hits``, ``ms``,
        ``group``.

    Returns
    -------
    pandas.DataFrame
        One row per (mode, L, hits group "1–9" / "10–99" / "≥100"): ``queries`` (how many fell in the group),
        ``mean_hits`` (µh), ``std_hits`` (σh, sample standard deviation), ``mean_ms`` (µt), ``median_ms`` and
        ``p90_ms``. Groups without queries have NaN statistics.

    Raises
    ------
    RuntimeError
        A query found no hit (each one is built from the database, so this is a bug in the index).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §6.2, Table 3 (:func:`mueller2005_table3` holds the paper's figures).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> upper = build(MotionDB.sample(), save=False, progress=False)["upper"]
    >>> table = query_statistics(upper, n_queries=50, lengths=(3,), fuzzy_size=8)
    >>> print(table[["mode", "L", "hits", "queries"]].to_string(index=False))  # a small database: few hits each
     mode  L  hits  queries
    exact  3   1–9       50
    exact  3 10–99        0
    exact  3  ≥100        0
    fuzzy  3   1–9       50
    fuzzy  3 10–99        0
    fuzzy  3  ≥100        0
    """
    rng = np.random.default_rng(seed)
    rows = []
    for mode, length in progress_bar([(m, n) for m in modes for n in lengths], desc="random queries", disable=True):
        run = index.exact if mode == "exact" else index.adaptive_fuzzy
        queries = random_queries(index, n_queries, length, mode, fuzzy_size, rng, alternatives)
        for k, q in progress_bar(queries, desc=f"{mode}, L = {length}", unit="query", disable=True):
            t0 = time.perf_counter()
            hits = run(q)
            ms = (time.perf_counter() - t0) * 1e3
            h = int(hits.shape[0])
            if h == 0:
                raise AssertionError(f"{mode} query of {length} segments taken at segment {k} found no hit")  # a bug
            rows.append((mode, length, k, q, h, ms, _hit_group(h)))
    raw = pd.DataFrame(rows, columns=["mode", "L", "k", "query", "hits", "ms", "group"])
    if per_query:
        return raw
    out = []
    for mode in modes:
        for length in lengths:
            cell = raw[(raw["mode"] == mode) & (raw["L"] == length)]
            for g in HIT_GROUPS:
                sel = cell[cell["group"] == g]
                n = len(sel)
                out.append({
                    "mode": mode, "L": length, "hits": g, "queries": n,
                    "mean_hits": sel["hits"].mean() if n else np.nan,
                    "std_hits": sel["hits"].std() if n > 1 else np.nan,
                    "mean_ms": sel["ms"].mean() if n else np.nan,
                    "median_ms": sel["ms"].median() if n else np.nan,
                    "p90_ms": sel["ms"].quantile(0.9) if n else np.nan,
                })  # fmt: skip
    return pd.DataFrame(out, columns=TABLE3_COLUMNS)


def mueller2005_table3() -> pd.DataFrame:
    """Table 3 of Müller, Röder & Clausen 2005: 10,000 random queries per row on I_u^180 (Matlab, Pentium 4),
    in the columns of :func:`query_statistics` (``mean_ms`` = the paper's µt; it gives no query counts, medians
    or p90, which are NaN). Fuzzy rows are adaptive fuzzy queries with 64 alternatives per set.

    Returns
    -------
    pandas.DataFrame
        One row per (mode, L, hits group), the columns of :func:`query_statistics`; times in milliseconds.
    """
    raw = {  # (mode, L): ((µh, σh, µt) for 1-9, 10-99, >=100 hits)
        ("exact", 5): ((3.0, 2.4, 16), (44, 28, 20), (649, 567, 144)),
        ("exact", 10): ((1.7, 1.6, 17), (34, 22, 26), (239, 147, 71)),
        ("exact", 20): ((1.1, 0.6, 19), (32, 26, 36), (130, 5, 52)),
        ("fuzzy", 5): ((3.6, 2.5, 23), (44, 27, 29), (1878, 1101, 291)),
        ("fuzzy", 10): ((2.4, 2.1, 28), (40, 26, 35), (1814, 1149, 281)),
        ("fuzzy", 20): ((2.0, 1.9, 42), (36, 24, 35), (1908, 1152, 294)),
    }
    rows = []
    for (mode, length), groups in raw.items():
        for g, (mh, sh, mt) in zip(HIT_GROUPS, groups):
            rows.append({"mode": mode, "L": length, "hits": g, "queries": np.nan, "mean_hits": float(mh),
                         "std_hits": float(sh), "mean_ms": float(mt), "median_ms": np.nan, "p90_ms": np.nan})  # fmt: skip
    return pd.DataFrame(rows, columns=TABLE3_COLUMNS)


# ============================================================================ Figs. 7-9
def relational_query(db, queries: dict | None = None, relational_set: str = "2005", indexes: dict | None = None,
                     label_column: str = "label") -> pd.DataFrame:  # fmt: skip
    """Query by example per motion class, with precision and recall (Müller, Röder & Clausen 2005, §6.2,
    Figs. 7-9).

    For each class, one document of that class is the query clip and a few relational features are selected
    (the rest are "don't care"); :func:`mocapviz.relational.query.query_by_example` finds its adaptive fuzzy hits. A
    document counts as retrieved if any hit lies in it, ranked by its best hit.

    Parameters
    ----------
    db : MotionDB
        Labelled documents (e.g. the HDM05 cut clips at 120 Hz). Its relational indexes are loaded, or built and
        saved (``mocapviz.relational.index.build``) if it has none yet.
    queries : dict, optional
        {class: (doc_id or None, [feature names])}; doc_id None = the class's first document. Default: every
        class of :data:`DEFAULT_QUERIES` that ``db`` holds, each queried with its first document (lowest doc_id).
    relational_set : {"2005", "2006"}
        The relational set of the features and indexes.
    indexes : dict, optional
        Group -> InvertedIndex, if already loaded.
    label_column : str
        The documents' column holding the class.

    Returns
    -------
    pandas.DataFrame
        One row per class: ``class``, ``query_doc``, ``query_name``, ``features`` (comma separated),
        ``query_frames``, ``n_segments`` (query segments, summed over the groups touched), ``hits``,
        ``self_retrieved`` (a hit lies in the query document), then the retrieval quality by
        :mod:`mocapviz.experiments.evaluation` (documents ranked by their best hit's score, the query document left
        out of the ranking and of the relevant set): ``hit_docs`` (other documents with a hit), ``relevant``
        (other documents of the class), ``relevant_retrieved``, ``precision`` (relevant_retrieved / hit_docs, NaN
        without hits), ``recall`` (relevant_retrieved / relevant), ``r_precision`` (precision at rank
        ``relevant``), ``ap`` (average precision; unfound relevant documents add 0), and ``ms`` (query time: the
        query clip's features included; index loading and the first call's compilation of the feature kernels
        excluded).

    Raises
    ------
    ValueError
        A class the database does not hold, or a query document of another class.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §6.2, Figs. 7-9 (query by example with a few selected features).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> table = relational_query(db, indexes=build(db, save=False, progress=False))  # one query per class
    >>> rows = table.set_index("class").loc[["kickLFront1Reps", "squat1Reps"]]
    >>> rows[["query_doc", "hits", "relevant"]].values.tolist()
    [[7, 2, 1], [11, 2, 1]]
    """
    from ..relational.query import query_by_example

    if indexes is None:
        indexes = index_mod.load_or_build(db, relational_set)
    docs = db.documents
    labels = docs[label_column].astype("string")
    labels_by_doc = pd.Series(labels.to_numpy(), index=docs["doc_id"].astype(np.int64))
    if queries is None:
        present = set(labels.dropna())
        queries = {c: (None, f) for c, f in DEFAULT_QUERIES.items() if c in present}
    rows = []
    if len(docs):  # untimed warm-up: the feature kernels compile (or load from numba's cache) on first use
        relational_features(db.motion(int(docs["doc_id"].iloc[0]))[:2], relational_set)
    for cls, spec in queries.items():
        doc_id, features = spec if isinstance(spec, tuple) else (None, spec)
        members = docs.loc[(labels == cls).fillna(False).to_numpy(), "doc_id"].to_numpy()
        if members.size == 0:
            raise ParameterError(f"no document of class {cls!r} in {db.path}; classes: {sorted(set(labels.dropna()))}")
        doc_id = int(members.min()) if doc_id is None else int(doc_id)
        if doc_id not in set(members.tolist()):
            raise ParameterError(f"document {doc_id} is not of class {cls!r}")
        example = db.motion(doc_id)
        t0 = time.perf_counter()
        hits = query_by_example(db, example, list(features), mode="adaptive", relational_set=relational_set,
                                indexes=indexes)  # fmt: skip
        ms = (time.perf_counter() - t0) * 1e3
        # hits come best first, so each document is ranked by its best hit
        ranking, n_relevant = evaluation.relevance(hits["doc_id"], labels_by_doc, doc_id)
        curve = evaluation.precision_recall(ranking, n_relevant)
        rows.append({
            "class": cls,
            "query_doc": doc_id,
            "query_name": docs.loc[docs["doc_id"] == doc_id, "name"].iloc[0],
            "features": ", ".join(features),
            "query_frames": example.n_frames,
            "n_segments": int(hits["n_segments"].iloc[0]) if len(hits) else 0,
            "hits": len(hits),
            "self_retrieved": bool((hits["doc_id"] == doc_id).any()),
            "hit_docs": len(ranking),
            "relevant": n_relevant,
            "relevant_retrieved": int(ranking["relevant"].sum()),
            "precision": curve["precision"].iloc[-1] if len(curve) else float("nan"),
            "recall": ranking["relevant"].sum() / n_relevant if n_relevant else float("nan"),
            "r_precision": evaluation.precision_at(ranking, n_relevant) if n_relevant else float("nan"),
            "ap": evaluation.average_precision(ranking, n_relevant),
            "ms": ms,
        })  # fmt: skip
    return pd.DataFrame(rows)
