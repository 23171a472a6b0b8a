"""Retrieval quality of every search method of the product on a labelled MotionDB (issue 16, item 5).

Every labelled document (or a seeded sample of ``n_queries``) is a query; each method ranks the *documents* of the
database, and the ranking is judged by :mod:`mocapviz.experiments.evaluation` (the product's one definition of relevance,
precision, recall and AP: the query's own document is left out, relevant = the other documents with the query's
label among the documents searched). On a partly labelled database (a lab's own takes beside an archive's) the
documents without a label are searched like any other but are never a query and never relevant, so a method that
ranks one of them high pays for it; the tables' ``attrs["unlabelled"]`` says how many there are.

Methods (:data:`METHODS`):

- ``dtw``: brute-force whole-clip DTW (:meth:`mocapviz.similarity.search.SimilaritySearch.clips`, ``mode="brute"``), every
  document aligned with the whole query, ranked by cost / (query frames + document frames). The reference
  ranking: "recall of DTW's top 10" is measured against it.
- ``exact``: the same ranking with admissible pruning (``mode="exact"``); must equal ``dtw``.
- ``fast``: ``mode="fast"``: the ``CLIP_BUDGET`` (:mod:`mocapviz.similarity.search`) documents of least DTW cost on 0.2 s
  block means aligned exactly and ranked by their exact cost; the rest follow the coarse order (a full ranking, as the docstring of
  :meth:`~mocapviz.similarity.search.SimilaritySearch.clips` describes).
- ``lng256``, ``lng1024``: the lazy neighbourhood graph of Krüger et al. 2010 §4.1 (:func:`mocapviz.match.lng`)
  with k = 256 / 1024 neighbours per query frame; each document ranked by its best match's cost. Documents
  without a graph path are not retrieved (they add 0 to AP).
- ``relational``: query by example (Müller, Röder & Clausen 2005, :func:`mocapviz.relational.query.query_by_example`,
  adaptive fuzzy hits) with the selection of :data:`mocapviz.experiments.relational.DEFAULT_QUERIES` for the
  query's class, documents ranked by their best hit's score. Classes without a selection are skipped (noted).
- ``hybrid``: :func:`mocapviz.similarity.hybrid.hybrid_search`: relational hits (the lenient
  :data:`~mocapviz.similarity.hybrid.HYBRID_QUERIES` settings of the class, with their numeric set, else its
  ``DEFAULT_QUERIES`` selection, adaptive, on ``numeric_set``) re-ranked by exact whole-clip DTW.

Protocols: *leave-one-out* (LOO): the query's document is left out, every other document searched.
*Leave-group-out* (LGO, e.g. leave-actor-out): a query of group A searches only the documents of other groups
(a restricted :class:`~mocapviz.similarity.search.SimilaritySearch` / kd-tree per group, so fast mode and the graph see only
those documents); relevant documents are counted among them. P@1, P@10 and the recall of DTW's top 10 are LOO
figures. Time per query: wall time of one LOO search asking for K = 10 documents (relational: the query by
example), each method warmed up once before the first query (numba compilation excluded).

retrieval_quality   db -> {"summary", "per_class", "curves", "per_query"} DataFrames.
relational_indexes  the stored relational indexes of a database, else built in memory (nothing written).
METHODS             the method names.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..parallel import progress_bar
from ..similarity.search import CLIP_BUDGET
from . import evaluation

__all__ = ["METHODS", "RECALL_LEVELS", "relational_indexes", "retrieval_quality"]

METHODS = ("dtw", "exact", "fast", "lng256", "lng1024", "relational", "hybrid")
RECALL_LEVELS = np.round(np.linspace(0.0, 1.0, 11), 2)  # the 11 standard recall levels of the P/R curves
TIMING_K = 10  # documents asked for in the timed search
TOP = 10  # the recall of DTW's top TOP documents
SUMMARY_COLUMNS = ["method", "queries", "map_loo", "map_lgo", "p_at_1", "p_at_10", "recall_dtw_top10",
                   "ms_per_query", "median_ms", "note"]  # fmt: skip
PER_QUERY_COLUMNS = ["method", "query_doc", "class", "group", "ap_loo", "relevant_loo", "ap_lgo", "relevant_lgo",
                     "p_at_1", "p_at_10", "recall_dtw_top10", "retrieved", "ms"]  # fmt: skip
METHOD_LABELS = {"dtw": "DTW (brute force)", "exact": "exact (pruned DTW)", "fast": "fast (coarse DTW, then exact)",
                 "lng256": "LNG k=256", "lng1024": "LNG k=1024", "relational": "relational (QbE)",
                 "hybrid": "hybrid (relational + DTW)"}  # fmt: skip


def _lng_k(method: str) -> int | None:
    return int(method[3:]) if method.startswith("lng") and method[3:].isdigit() else None


def _check_methods(methods) -> list[str]:
    if methods is None:
        return list(METHODS)
    methods = [methods] if isinstance(methods, str) else list(methods)
    unknown = [m for m in methods if m not in METHODS and not (_lng_k(m) and _lng_k(m) > 0)]
    if unknown or not methods:
        raise ParameterError(f"unknown method(s) {unknown or methods!r}; choose from {', '.join(METHODS)} (or lng<k>)")
    return list(dict.fromkeys(methods))


def _interpolated(ranking: pd.DataFrame, n_relevant: int, levels=RECALL_LEVELS) -> np.ndarray:
    """Interpolated precision at the recall ``levels``: the best precision at any rank whose recall reaches the
    level (0 where the ranking never reaches it)."""
    curve = evaluation.precision_recall(ranking, n_relevant)
    precision, recall = curve["precision"].to_numpy(), curve["recall"].to_numpy()
    out = np.zeros(len(levels))
    for i, level in enumerate(levels):
        reached = recall >= level - 1e-12
        if reached.any():
            out[i] = precision[reached].max()
    return out


class _Runner:
    """The searches of one evaluation: one SimilaritySearch (with its kd-tree) per protocol context (None = every
    document, else the documents outside one group), the relational indexes, the query motions."""

    def __init__(self, db, numeric_set: str, labels: pd.Series, groups: pd.Series | None, indexes):
        from ..similarity.search import SimilaritySearch

        self.db, self.numeric_set, self.labels, self.groups = db, numeric_set, labels, groups
        self._make = SimilaritySearch
        self._searches: dict = {}
        self._indexes = indexes
        docs = db.documents.sort_values("start")
        self.by_start = docs["doc_id"].to_numpy(np.int64)  # lng's doc_id indexes the documents in start order
        self.starts = docs["start"].to_numpy(np.int64)
        self._hits: dict = {}
        self._hits_ms: dict = {}

    # ------------------------------------------------------------------ contexts
    def candidates(self, group) -> np.ndarray | None:
        """Doc ids searchable for a query of ``group`` (None: every document)."""
        if group is None:
            return None
        return self.groups.index[(self.groups != group) | self.groups.isna()].to_numpy(np.int64)

    def search(self, group=None, numeric_set: str | None = None):
        key = (group, numeric_set or self.numeric_set)
        if key not in self._searches:
            self._searches[key] = self._make(self.db, key[1], documents=self.candidates(group))
        return self._searches[key]

    def indexes(self) -> dict:
        if self._indexes is None:
            self._indexes = relational_indexes(self.db)
        return self._indexes

    # ------------------------------------------------------------------ selections
    def relational_selection(self, q: int):
        from .relational import DEFAULT_QUERIES

        return DEFAULT_QUERIES.get(str(self.labels.get(q)))

    def hybrid_selection(self, q: int) -> dict | None:
        """Keyword arguments of :func:`mocapviz.similarity.hybrid.hybrid_search` for the query's class: its lenient
        ``HYBRID_QUERIES`` entry when there is one, else the class's ``DEFAULT_QUERIES`` selection, adaptive; None
        for a class with neither."""
        from ..similarity import hybrid

        cls = str(self.labels.get(q))
        spec = getattr(hybrid, "HYBRID_QUERIES", {}).get(cls)
        if isinstance(spec, dict):
            return dict(spec)
        if spec is not None:  # (features, mode, mismatches)
            features, mode, mismatches = spec
            return {"features": list(features), "mode": mode, "mismatches": int(mismatches)}
        features = self.relational_selection(q)
        return None if features is None else {"features": list(features), "mode": "adaptive"}

    # ------------------------------------------------------------------ one method, one query
    def rank(self, method: str, q: int, group=None) -> np.ndarray | None:
        """The documents ``method`` retrieves for query document ``q``, best first (own document excluded), in
        the context of ``group`` (None: leave-one-out); None when the method does not apply to the query."""
        if method in ("dtw", "exact", "fast"):
            s = self.search(group)
            mode = "brute" if method == "dtw" else method
            table = s.clips(q, n_matches=len(s.documents), mode=mode, exclude_document=True,
                            budget=CLIP_BUDGET if method == "fast" else None)  # fmt: skip
            return table["doc_id"].to_numpy(np.int64)
        if _lng_k(method):
            out = self._lng(q, _lng_k(method), group, n_matches=None)
            return pd.unique(self.by_start[out["doc_id"].to_numpy(np.int64)])
        if method == "relational":
            hits = self._relational_hits(q)
            if hits is None:
                return None
            docs = pd.unique(hits["doc_id"].to_numpy(np.int64))
            docs = docs[docs != q]
            if group is not None:
                docs = docs[np.isin(docs, self.candidates(group))]
            return docs
        if method == "hybrid":
            return self._hybrid(q, group)
        raise ParameterError(f"unknown method {method!r}")  # pragma: no cover - checked before

    def timed(self, method: str, q: int) -> float:
        """Milliseconds of one leave-one-out search asking for K = TIMING_K documents."""
        if method == "relational":
            return self._hits_ms.get(q, float("nan"))
        t0 = time.perf_counter()
        if method in ("dtw", "exact", "fast"):
            self.search(None).clips(q, n_matches=TIMING_K, mode="brute" if method == "dtw" else method,
                                    exclude_document=True)  # fmt: skip
        elif _lng_k(method):
            self._lng(q, _lng_k(method), None, n_matches=TIMING_K)
        elif method == "hybrid" and self._hybrid(q, None, n_matches=TIMING_K) is None:
            return float("nan")
        return 1e3 * (time.perf_counter() - t0)

    def _lng(self, q: int, k: int, group, n_matches: int | None) -> pd.DataFrame:
        from ..match import lng

        s = self.search(group)
        index = s.knn_index
        k = min(k, index.n_indexed)
        span = self.db.frames(q)
        # every end node of the graph is a candidate match; n_matches = k keeps them all (each document's best
        # match comes first in cost order, so ranking documents by it needs no more)
        return lng(s.features[span.start : span.stop], index, k=k, n_matches=k if n_matches is None else n_matches,
                   starts=self.starts, exclude=(span.start, span.stop), paths=False, min_length=None)  # fmt: skip

    def _relational_hits(self, q: int) -> pd.DataFrame | None:
        if q not in self._hits:
            from ..relational.query import query_by_example

            features = self.relational_selection(q)
            if features is None:
                self._hits[q] = None
                return None
            motion = self.db.motion(q)
            indexes = self.indexes()
            t0 = time.perf_counter()
            self._hits[q] = query_by_example(self.db, motion, list(features), mode="adaptive", indexes=indexes)
            self._hits_ms[q] = 1e3 * (time.perf_counter() - t0)
        return self._hits[q]

    def _hybrid(self, q: int, group, n_matches: int | None = None) -> np.ndarray | None:
        from ..similarity.hybrid import hybrid_search

        selection = self.hybrid_selection(q)
        if selection is None:
            return None
        numeric_set = selection.pop("numeric_set", self.numeric_set)  # a class's own set, e.g. F15x3E for throws
        ranked = hybrid_search(self.db, q, **selection, numeric_set=numeric_set, n_matches=n_matches,
                               indexes=self.indexes(), search=self.search(group, numeric_set), exclude_document=True)
        return ranked["doc_id"].to_numpy(np.int64)


def relational_indexes(db, relational_set: str = "2005") -> dict:
    """The relational indexes of ``db``: the stored ones when current, else built in memory (nothing is written
    into the database, so a read-only database can be evaluated).

    Parameters
    ----------
    db : MotionDB
        The database.
    relational_set : {"2005", "2006"}
        The relational set.

    Returns
    -------
    dict
        Group -> InvertedIndex.
    """
    from ..relational.index import load_or_build

    return load_or_build(db, relational_set, save=False)


def _queries(labels: pd.Series, queries, n_queries, seed) -> np.ndarray:
    if queries is not None:
        chosen = np.asarray(queries, dtype=np.int64).reshape(-1)
        unknown = chosen[~np.isin(chosen, labels.index)]
        if len(unknown):
            raise ParameterError(f"queries {unknown[:5].tolist()} are not documents of the database")
        unlabelled = chosen[labels.reindex(chosen).isna().to_numpy()]
        if len(unlabelled):
            raise ParameterError(f"queries {unlabelled[:5].tolist()} have no {labels.name!r}, so no ranking of theirs "
                                 "can be judged; choose labelled documents")  # fmt: skip
        return chosen
    pool = labels.index[labels.notna()].to_numpy(np.int64)
    if len(pool) == 0:
        raise ParameterError("no document has a label: nothing to evaluate")
    if n_queries is None or n_queries >= len(pool):
        return np.sort(pool)
    if isinstance(n_queries, bool) or not isinstance(n_queries, (int, np.integer)) or n_queries < 1:
        raise ParameterError(f"n_queries must be an integer of at least 1, or None for every labelled document; "
                             f"got {n_queries!r}")  # fmt: skip
    return np.sort(np.random.default_rng(seed).choice(pool, size=int(n_queries), replace=False))


def retrieval_quality(db, methods=None, label_column: str = "label", group_column: str | bool | None = None,
                      numeric_set: str = "F15E", n_queries: int | None = None, seed: int = 0, queries=None,
                      indexes: dict | None = None, timing: bool = True, progress: bool = True) -> dict:  # fmt: skip
    """Retrieval quality of the search methods on a labelled MotionDB (see the module docstring).

    Parameters
    ----------
    db : MotionDB
        Documents with a label column (e.g. the 287 HDM05 cut clips: ``label``, ``actor``; Bandai Namco: ``label``
        = content, ``style``). Opened read-only is enough: relational indexes are loaded when stored, else built
        in memory (never written).
    methods : sequence of str, optional
        Names of :data:`METHODS` (``lng<k>`` for any k); default all.
    label_column : str
        The document column that decides relevance; documents without a label are searched but never relevant
        and never queries.
    group_column : str, False or None
        Leave-group-out protocol: a query of group g searches only documents of other groups (documents with no
        group are searchable by all). None (default): ``"actor"`` when the documents have that column, else
        none; False: no leave-group-out (``map_lgo`` NaN).
    numeric_set : str
        The numeric set of DTW, fast mode and the graph (default F15E, cm).
    n_queries : int, optional
        Evaluate a seeded random sample of the labelled documents (default all).
    seed : int
        Seed of that sample.
    queries : sequence of int, optional
        Explicit query doc ids (overrides ``n_queries``), each labelled.
    indexes : dict, optional
        The 2005 relational indexes (group -> InvertedIndex), if loaded.
    timing : bool
        Time one K = 10 search per query and method (an extra search; off: ``ms`` NaN).
    progress : bool
        A progress bar over the queries.

    Returns
    -------
    dict
        Name -> pandas.DataFrame:

        - ``summary``: one row per method: ``method``, ``queries`` (queries the method ran on), ``map_loo``
          (mean AP leave-one-out over the queries with another relevant document), ``map_lgo`` (mean AP
          leave-group-out, queries with a relevant document in other groups), ``p_at_1``, ``p_at_10`` (LOO),
          ``recall_dtw_top10`` (mean share of brute-force DTW's 10 best documents among the method's first 10,
          LOO), ``ms_per_query`` (mean) and ``median_ms`` (K = 10, LOO), ``note``. ``attrs``: label_column,
          group_column, numeric_set, queries, documents, unlabelled (the documents without a label: searched,
          never relevant, never a query), notes.
        - ``per_class``: per (method, class): ``queries``, ``ap_loo`` (mean), ``n_loo`` (queries with a defined
          AP), ``ap_lgo``, ``n_lgo``, ``p_at_1``. The summary's ``map_loo`` is the ``n_loo``-weighted mean of
          ``ap_loo``.
        - ``curves``: per (method, protocol "loo" / "lgo", recall level of :data:`RECALL_LEVELS`): ``precision``,
          the mean interpolated precision over the queries with a relevant document, and ``queries``.
        - ``per_query``: one row per (method, query): :data:`PER_QUERY_COLUMNS`.

    Raises
    ------
    ParameterError
        An unknown method, a missing label or group column, no labelled document, an unlabelled query.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> result = retrieval_quality(MotionDB.sample(), methods=["exact"], queries=[7, 11], timing=False,
    ...                            progress=False)
    >>> result["summary"][["method", "queries"]].values.tolist()
    [['exact', 2]]
    """
    methods = _check_methods(methods)
    docs = db.documents
    if label_column not in docs.columns:
        raise ParameterError(f"the documents have no column {label_column!r}; columns: {', '.join(docs.columns)}")
    if group_column is None:
        group_column = "actor" if "actor" in docs.columns and docs["actor"].notna().any() else False
    if group_column is not False and group_column not in docs.columns:
        raise ParameterError(f"the documents have no column {group_column!r}; columns: {', '.join(docs.columns)}")
    ids = docs["doc_id"].astype(np.int64).to_numpy()
    labels = pd.Series(docs[label_column].astype(object).where(docs[label_column].notna(), None).to_numpy(),
                       index=ids, name=label_column).replace("", None)  # fmt: skip
    groups = None if group_column is False else pd.Series(docs[group_column].astype(object).to_numpy(), index=ids)
    chosen = _queries(labels, queries, n_queries, seed)
    runner = _Runner(db, numeric_set, labels, groups, indexes)
    notes: dict[str, str] = {}
    broken: dict[str, str] = {}

    # warm-up (untimed): numba kernels compile or load from cache, kd-trees and coarse databases are built
    first = int(chosen[0])
    for method in methods:
        try:
            runner.rank(method, first)
            if timing:
                runner.timed(method, first)
        except Exception as exc:  # the hybrid stage may be missing or changed: noted, not fatal
            if method not in ("relational", "hybrid"):
                raise
            broken[method] = f"not run: {type(exc).__name__}: {exc}"
    runner._hits.clear()  # the relational query of the first query is timed again below

    rows = []
    sums = {}  # (method, protocol) -> [sum of interpolated precision, queries]
    for q in progress_bar(chosen, desc="retrieval quality", unit="query", disable=not progress):
        q = int(q)
        group = None if groups is None or pd.isna(groups.get(q)) else groups.get(q)
        if group is not None and not len(runner.candidates(group)):
            group = None  # every document is in the query's group: no leave-group-out figure for it
        ranked = {"dtw": runner.rank("dtw", q)}  # the reference ranking, also when "dtw" is not evaluated
        reference = ranked["dtw"][:TOP]
        for method in methods:
            if method in broken:
                continue
            loo = ranked[method] if method in ranked else runner.rank(method, q)
            if loo is None:
                continue
            ranking, n_rel = evaluation.relevance(loo, labels, q)
            row = {"method": method, "query_doc": q, "class": labels.get(q),
                   "group": None if groups is None else groups.get(q),
                   "ap_loo": evaluation.average_precision(ranking, n_rel), "relevant_loo": n_rel,
                   "p_at_1": evaluation.precision_at(ranking, 1) if n_rel else np.nan,
                   "p_at_10": evaluation.precision_at(ranking, 10) if n_rel else np.nan,
                   "recall_dtw_top10": len(set(loo[:TOP].tolist()) & set(reference.tolist())) / max(1, len(reference)),
                   "retrieved": len(ranking), "ap_lgo": np.nan, "relevant_lgo": 0,
                   "ms": runner.timed(method, q) if timing else np.nan}  # fmt: skip
            if n_rel:
                acc = sums.setdefault((method, "loo"), [np.zeros(len(RECALL_LEVELS)), 0])
                acc[0] += _interpolated(ranking, n_rel)
                acc[1] += 1
            if group is not None:
                lgo = runner.rank(method, q, group)
                ranking_g, n_rel_g = evaluation.relevance(lgo, labels, q, candidates=runner.candidates(group))
                row["ap_lgo"], row["relevant_lgo"] = evaluation.average_precision(ranking_g, n_rel_g), n_rel_g
                if n_rel_g:
                    acc = sums.setdefault((method, "lgo"), [np.zeros(len(RECALL_LEVELS)), 0])
                    acc[0] += _interpolated(ranking_g, n_rel_g)
                    acc[1] += 1
            rows.append(row)
    per_query = pd.DataFrame(rows, columns=PER_QUERY_COLUMNS)

    for method in methods:
        ran = per_query[per_query["method"] == method]
        if method in broken:
            notes[method] = broken[method]
        elif len(ran) < len(chosen):
            skipped = sorted({str(labels.get(int(q))) for q in chosen if int(q) not in set(ran["query_doc"])})
            why = "no relational selection (DEFAULT_QUERIES) for the class" if method in ("relational", "hybrid") \
                else "not applicable"  # fmt: skip
            notes[method] = (f"{len(chosen) - len(ran)} of {len(chosen)} queries skipped ({why}): "
                             + ", ".join(skipped[:8]) + (" ..." if len(skipped) > 8 else ""))  # fmt: skip
        if _lng_k(method) and len(ran):
            notes.setdefault(method, f"documents without a graph path are not retrieved (mean "
                                     f"{ran['retrieved'].mean():.1f} documents ranked per query)")  # fmt: skip

    summary = []
    for method in methods:
        ran = per_query[per_query["method"] == method]
        judged = ran[ran["relevant_loo"] > 0]
        summary.append({
            "method": method, "queries": len(ran),
            "map_loo": ran["ap_loo"].mean() if len(ran) else np.nan,
            "map_lgo": ran["ap_lgo"].mean() if len(ran) else np.nan,
            "p_at_1": judged["p_at_1"].mean() if len(judged) else np.nan,
            "p_at_10": judged["p_at_10"].mean() if len(judged) else np.nan,
            "recall_dtw_top10": ran["recall_dtw_top10"].mean() if len(ran) else np.nan,
            "ms_per_query": ran["ms"].mean() if len(ran) else np.nan,
            "median_ms": ran["ms"].median() if len(ran) else np.nan,
            "note": notes.get(method, ""),
        })  # fmt: skip
    summary = pd.DataFrame(summary, columns=SUMMARY_COLUMNS)

    per_class = (per_query.groupby(["method", "class"], sort=False)
                 .agg(queries=("query_doc", "size"), ap_loo=("ap_loo", "mean"), n_loo=("ap_loo", "count"),
                      ap_lgo=("ap_lgo", "mean"), n_lgo=("ap_lgo", "count"), p_at_1=("p_at_1", "mean"))
                 .reset_index())  # fmt: skip
    order = per_class["method"].map({m: i for i, m in enumerate(methods)})
    per_class = per_class.assign(_order=order).sort_values(["_order", "class"], kind="stable")
    per_class = per_class.drop(columns="_order").reset_index(drop=True)

    curves = [{"method": method, "protocol": protocol, "recall": r, "precision": total[i] / n, "queries": n}
              for (method, protocol), (total, n) in sums.items() for i, r in enumerate(RECALL_LEVELS)]  # fmt: skip
    curves = pd.DataFrame(curves, columns=["method", "protocol", "recall", "precision", "queries"])
    settings = {"label_column": label_column, "group_column": group_column or None, "numeric_set": numeric_set,
                "queries": len(chosen), "documents": len(docs), "unlabelled": int(labels.isna().sum()),
                "notes": notes}  # fmt: skip
    for frame in (summary, per_class, curves, per_query):
        frame.attrs.update(settings)
    return {"summary": summary, "per_class": per_class, "curves": curves, "per_query": per_query}
