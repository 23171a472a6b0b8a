"""Judging the hits of a query by example against the documents' labels (Müller, Röder & Clausen 2005 §6.2, where
the hits of a query are counted as relevant or not by hand; here a label table decides).

precision_recall        ranked hits + document labels -> precision and recall after each rank.
precision_recall_plot   that table as two curves over the rank.

Relevance: a hit is *relevant* when its document carries the query document's label. Hits inside the query
document itself are left out (the query always finds itself). Precision after rank k counts hits (the relevant ones
among the first k); recall after rank k counts documents (the distinct relevant documents among the first k hits,
over every other document that carries the label), since one document may hold several hits.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import numpy as np
import pandas as pd


def precision_recall(hit_docs, documents: pd.DataFrame, query_doc: int) -> pd.DataFrame:
    """Precision and recall of ranked hits with respect to the query document's label.

    Parameters
    ----------
    hit_docs : sequence of int [shape=(H,)], the document id of each hit, best first.
    documents : pandas.DataFrame with ``doc_id`` and ``label`` (the database's document table).
    query_doc : int, the query clip's document id.

    Returns
    -------
    pandas.DataFrame, one row per hit outside the query document, in rank order: ``rank`` (the hit's 1-based
    position in ``hit_docs``, as in the hits table), ``doc_id``, ``relevant`` (bool), ``precision`` and ``recall``
    after this hit (fractions in [0, 1]; precision over the judged hits so far).
    ``attrs["n_relevant"]`` is the number of other documents with the query's label (recall is NaN when 0).

    Raises
    ------
    ValueError
        The query document has no label, or is not in ``documents``.
    """
    labels = dict(zip(documents["doc_id"].astype(int), documents["label"]))
    if query_doc not in labels:
        raise ValueError(f"document {query_doc} is not in the document table")
    label = labels[query_doc]
    if pd.isna(label) or label == "":
        raise ValueError(f"document {query_doc} has no label, so no hit can be judged")
    all_docs = np.asarray([int(d) for d in hit_docs], dtype=np.int64)
    judged = all_docs != query_doc
    docs, ranks = all_docs[judged], np.flatnonzero(judged) + 1
    relevant = np.array([labels.get(int(d)) == label for d in docs], dtype=bool)
    n_relevant = sum(1 for d, lab in labels.items() if lab == label and d != query_doc)
    first_time = ~pd.Series(docs).duplicated().to_numpy()
    found = np.cumsum(relevant & first_time)
    out = pd.DataFrame({
        "rank": ranks,
        "doc_id": docs,
        "relevant": relevant,
        "precision": np.cumsum(relevant) / np.arange(1, len(docs) + 1),
        "recall": found / n_relevant if n_relevant else np.full(len(docs), np.nan),
    })
    out.attrs["n_relevant"] = n_relevant
    return out


def precision_recall_plot(curve: pd.DataFrame, label: str = "", width: int = 720, height: int = 280) -> hv.Overlay:
    """Precision and recall over the rank, as returned by :func:`precision_recall`.

    Parameters
    ----------
    curve : pandas.DataFrame with ``rank``, ``precision``, ``recall`` (and ``doc_id``, ``relevant`` for the hover).
    label : str, the query's label (for the title).

    Returns
    -------
    holoviews.Overlay of two step curves with markers (y: fraction 0..1, x: rank of the hit).
    """
    y = hv.Dimension("fraction", range=(-0.04, 1.05))  # a line at 0 stays visible above the axis
    layers = []
    for column, colour in (("precision", "#1f77b4"), ("recall", "#ff7f0e")):
        data = curve[["rank", column, "doc_id", "relevant"]].rename(columns={column: "fraction"})
        layers.append(hv.Curve(data, "rank", [y, "doc_id", "relevant"], label=column)
                      .opts(interpolation="steps-post", color=colour, line_width=2))
        layers.append(hv.Scatter(data, "rank", [y, "doc_id", "relevant"], label=column)
                      .opts(color=colour, size=5, tools=["hover"]))
    title = f"precision / recall over rank: {label}" if label else "precision / recall over rank"
    return hv.Overlay(layers).opts(width=width, height=height, title=title, legend_position="bottom_right",
                                   xlabel="rank of hit", ylabel="fraction", show_grid=True, toolbar="above")
