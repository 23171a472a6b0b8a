"""Retrieval quality: the one definition of precision, recall and average precision used by the whole product.

A search returns a ranking of *documents* (hits or matches in a document count once, at the rank of the first
one). It is judged against the query document's label:

- The query's own document is left out of the ranking and of the relevant set (finding the query itself says
  nothing about a search method).
- Relevant documents are the *other* documents with the query's label, among the documents that were searched
  (``candidates``; default: all).
- precision@n = relevant documents among the first n of the ranking / n (n at most the ranking's length);
  recall@n = relevant documents among the first n / all relevant documents.
- Average precision (AP) = the mean, over *all* relevant documents, of the precision at the rank where each is
  found; a relevant document never found adds 0 (so a search that returns few hits is not rewarded for
  stopping early). mAP is the mean AP over queries; R-precision is precision@(number of relevant documents).

relevance        ranked document ids -> the judged ranking (doc_id, relevant) without the query document.
segment_relevance  a ranked hit table judged against segment labels (and file-name labels) of a class.
precision_recall that ranking -> precision and recall after every rank (the curve of the dashboard and notebooks).
average_precision, precision_at   single numbers from a judged ranking.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import ParameterError


def relevance(ranked_docs, labels: pd.Series, query_doc: int | None, candidates=None,
              label=None) -> tuple[pd.DataFrame, int]:  # fmt: skip
    """Judge a ranking of documents by the query document's label (or by a class ``label`` when the query is not a
    document, e.g. a motion template).

    Parameters
    ----------
    ranked_docs : sequence of int
        Document ids, best first; repeats (several hits in one document) count at their first rank.
    labels : pd.Series
        Label of every document, indexed by doc_id (missing labels are never relevant).
    query_doc : int or None
        The query's document: left out of the ranking and of the relevant set. None: the query is no document;
        pass ``label``.
    candidates : sequence of int, optional
        The documents the search could return (e.g. the other actors' documents in a leave-actor-out
        evaluation); relevant documents outside them are not counted. Default: every document of ``labels``.
    label : optional
        The class sought when ``query_doc`` is None.

    Returns
    -------
    ranking : pd.DataFrame, one row per distinct document other than the query's, in rank order: ``rank``
        (1-based), ``doc_id``, ``relevant`` (bool).
    n_relevant : int, documents with the query's label among the candidates, the query's own excluded.

    Raises
    ------
    ParameterError
        ``query_doc`` is not in ``labels``; neither or both of ``query_doc`` and ``label`` given.

    Examples
    --------
    A search for clip 7 (a kick) of the sample returned documents 7 (itself), 18 (the other kick), 3 and 18 again:

    >>> from mocapviz import MotionDB
    >>> labels = MotionDB.sample().documents.set_index("doc_id")["label"]
    >>> ranking, n_relevant = relevance([7, 18, 3, 18], labels, query_doc=7)
    >>> print(ranking.to_string(index=False))  # the query's own document left out, repeats at their first rank
     rank  doc_id  relevant
        1      18      True
        2       3     False
    >>> n_relevant  # the other kick
    1
    >>> average_precision(ranking, n_relevant), precision_at(ranking, 2)
    (1.0, 0.5)
    """
    if (query_doc is None) == (label is None):
        raise ParameterError("pass the query's document (query_doc) or, for a query that is no document, its label")
    if query_doc is not None and query_doc not in labels.index:
        raise ParameterError(f"query_doc {query_doc} is not a document of the labels given (doc ids "
                             f"{labels.index.min()}..{labels.index.max()})")  # fmt: skip
    if query_doc is not None:
        label = labels.loc[query_doc]
    pool = labels if candidates is None else labels.reindex(pd.Index(candidates).unique())
    pool = pool.drop(index=[] if query_doc is None else [query_doc], errors="ignore")
    n_relevant = 0 if pd.isna(label) else int((pool == label).sum())
    docs = pd.unique(np.asarray(ranked_docs, dtype=np.int64))
    docs = docs[docs != query_doc]
    judged = labels.reindex(docs)  # documents without a label (NaN / None / pd.NA) are never relevant
    relevant = np.zeros(len(docs), dtype=bool) if pd.isna(label) else judged.eq(label).fillna(False).to_numpy(bool)
    if candidates is not None:
        relevant = relevant & np.isin(docs, np.asarray(pool.index))  # (to_numpy may give a read-only view)
    ranking = pd.DataFrame({"rank": np.arange(1, len(docs) + 1), "doc_id": docs, "relevant": relevant})
    return ranking, n_relevant


def segment_relevance(hits: pd.DataFrame, segments: pd.DataFrame, label, labels: pd.Series | None = None
                      ) -> tuple[pd.DataFrame, int]:  # fmt: skip
    """Judge a ranked hit table by segment labels: the relevant items are the segments of ``label`` (and the
    documents whose file-name label is ``label``); a hit is relevant when it overlaps (at least one frame in common,
    half-open) a relevant item that no earlier hit overlapped, which it then counts as found. So every item counts
    once, as a document does in :func:`relevance`, and precision, recall and AP keep their meaning.

    Parameters
    ----------
    hits : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` (a hit table), best first.
    segments : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` of the segments of the class (say, the manual, accepted and imported ones:
        :data:`mocapviz.db.segments.POSITIVE`).
    label : str
        The class (for ``labels``).
    labels : pandas.Series, optional
        File-name label of every document, by doc_id: the documents of ``label`` are relevant items, whole.

    Returns
    -------
    ranking : pandas.DataFrame, ``rank``, ``doc_id``, ``start``, ``end``, ``relevant`` per hit.
    n_relevant : int, the relevant items.

    Examples
    --------
    >>> hits = pd.DataFrame({"doc_id": [4, 4, 4, 9], "start": [0, 5, 50, 0], "end": [10, 12, 60, 30]})
    >>> segments = pd.DataFrame({"doc_id": [4, 4], "start": [8, 100], "end": [20, 120]})
    >>> ranking, n = segment_relevance(hits, segments, "kick")
    >>> ranking["relevant"].tolist(), n  # the second hit overlaps the segment the first found already
    ([True, False, False, False], 2)
    """
    items = [(int(d), int(a), int(b)) for d, a, b in zip(segments["doc_id"], segments["start"], segments["end"])]
    if labels is not None:
        items += [(int(d), 0, np.iinfo(np.int64).max) for d in labels.index[labels.eq(label).fillna(False).to_numpy(bool)]]
    found = np.zeros(len(items), dtype=bool)
    by_doc: dict = {}
    for i, (d, _, _) in enumerate(items):
        by_doc.setdefault(d, []).append(i)
    relevant = []
    for d, a, b in zip(hits["doc_id"], hits["start"], hits["end"]):
        fresh = [i for i in by_doc.get(int(d), []) if not found[i] and items[i][1] < b and a < items[i][2]]
        if fresh:
            found[fresh[0]] = True
        relevant.append(bool(fresh))
    ranking = pd.DataFrame({"rank": np.arange(1, len(hits) + 1), "doc_id": np.asarray(hits["doc_id"], np.int64),
                            "start": np.asarray(hits["start"], np.int64), "end": np.asarray(hits["end"], np.int64),
                            "relevant": np.array(relevant, dtype=bool)})  # fmt: skip
    return ranking, len(items)


def precision_recall(ranking: pd.DataFrame, n_relevant: int) -> pd.DataFrame:
    """Precision and recall after every rank of a judged ranking (:func:`relevance`).

    Parameters
    ----------
    ranking : pandas.DataFrame
        The judged ranking of :func:`relevance` (``rank``, ``doc_id``, ``relevant``).
    n_relevant : int
        Relevant documents in all (:func:`relevance`'s second value).

    Returns
    -------
    pandas.DataFrame
        The ranking's columns plus ``precision`` and ``recall`` (fractions in [0, 1]; recall NaN when no other
        document is relevant). ``attrs["n_relevant"]`` holds ``n_relevant``.

    Examples
    --------
    >>> import pandas as pd
    >>> ranking = pd.DataFrame({"rank": [1, 2, 3], "doc_id": [4, 9, 2], "relevant": [True, False, True]})
    >>> curve = precision_recall(ranking, n_relevant=4)
    >>> curve["precision"].round(3).tolist(), curve["recall"].tolist()
    ([1.0, 0.5, 0.667], [0.25, 0.25, 0.5])
    """
    found = np.cumsum(ranking["relevant"].to_numpy(dtype=bool))
    out = ranking.assign(
        precision=found / np.arange(1, len(ranking) + 1),
        recall=found / n_relevant if n_relevant else np.full(len(ranking), np.nan),
    )
    out.attrs["n_relevant"] = n_relevant
    return out


def average_precision(ranking: pd.DataFrame, n_relevant: int) -> float:
    """AP of a judged ranking: mean precision at the ranks of the relevant documents over all ``n_relevant``
    (unfound ones add 0). NaN when no other document is relevant.

    Parameters
    ----------
    ranking : pandas.DataFrame
        The judged ranking of :func:`relevance`.
    n_relevant : int
        Relevant documents in all.

    Returns
    -------
    float
        In [0, 1], or NaN.

    Examples
    --------
    >>> import pandas as pd
    >>> ranking = pd.DataFrame({"rank": [1, 2, 3], "doc_id": [4, 9, 2], "relevant": [True, False, True]})
    >>> round(average_precision(ranking, n_relevant=4), 4)  # (1/1 + 2/3 + 0 + 0) / 4
    0.4167
    """
    if n_relevant == 0:
        return float("nan")
    relevant = ranking["relevant"].to_numpy(dtype=bool)
    ranks = np.flatnonzero(relevant) + 1
    return float((np.arange(1, len(ranks) + 1) / ranks).sum() / n_relevant)


def precision_at(ranking: pd.DataFrame, n: int) -> float:
    """Relevant documents among the first ``n`` of the ranking / n (precision@n); a ranking shorter than n counts
    its missing ranks as not relevant (a search that returns nothing has precision 0, not NaN).

    Parameters
    ----------
    ranking : pandas.DataFrame
        The judged ranking of :func:`relevance`.
    n : int
        Ranks counted, at least 1.

    Returns
    -------
    float
        In [0, 1].

    Examples
    --------
    >>> import pandas as pd
    >>> ranking = pd.DataFrame({"rank": [1, 2, 3], "doc_id": [4, 9, 2], "relevant": [True, False, True]})
    >>> precision_at(ranking, 1), precision_at(ranking, 10)
    (1.0, 0.2)
    """
    if n < 1:
        raise ParameterError(f"n must be at least 1; got {n}")
    return float(ranking["relevant"].to_numpy(dtype=bool)[:n].sum() / n)
