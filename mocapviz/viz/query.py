"""Judging the hits of a query by example against the documents' labels (Müller, Röder & Clausen 2005 §6.2, where
the hits of a query are counted as relevant or not by hand; here a label table decides).

precision_recall        ranked hits + document labels -> precision and recall after each ranked document.
precision_recall_plot   that table as two curves over the rank.

Relevance, precision and recall are those of :mod:`mocapviz.experiments.evaluation`, the one definition of the product: the
hits are turned into a ranking of documents (a document counts once, at its first hit), the query's own document is
left out of the ranking and of the relevant set, and a document is relevant when it carries the query document's
label.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import numpy as np
import pandas as pd

from ..errors import ParameterError
from .palette import MARKERS, SERIES

MARKER_OFFSET = 0.08  # ranks: precision's markers left of their rank, recall's right
MAX_TICKS = 20  # rank ticks at most
from ..experiments import evaluation


def precision_recall(hit_docs, documents: pd.DataFrame, query_doc: int) -> pd.DataFrame:
    """Precision and recall of ranked hits with respect to the query document's label.

    Parameters
    ----------
    hit_docs : sequence of int [shape=(H,)]
        The document id of each hit, best first.
    documents : pandas.DataFrame
        With ``doc_id`` and ``label`` (the database's document table).
    query_doc : int
        The query clip's document id.

    Returns
    -------
    pandas.DataFrame
        One row per distinct document with a hit, other than the query's, in the order of its first hit:
        ``rank`` (1-based rank of the document), ``doc_id``, ``relevant`` (bool), ``precision`` and ``recall``
        after this document (:func:`mocapviz.experiments.evaluation.precision_recall`), ``hit_rank`` (1-based
        position of the document's first hit in ``hit_docs``, as in the hits table). ``attrs["n_relevant"]`` is
        the number of other documents with the query's label (recall is NaN when 0) and
        ``attrs["average_precision"]`` the ranking's AP (:func:`mocapviz.experiments.evaluation.average_precision`).

    Raises
    ------
    ParameterError
        The query document has no label, or is not in ``documents``.
    """
    labels = pd.Series(documents["label"].to_numpy(), index=documents["doc_id"].astype(np.int64))
    label = labels.get(query_doc)
    if query_doc in labels.index and (pd.isna(label) or label == ""):
        raise ParameterError(f"document {query_doc} has no label, so no hit can be judged; pick a labelled query clip")
    ranking, n_relevant = evaluation.relevance(hit_docs, labels, query_doc)
    docs = np.asarray(hit_docs, dtype=np.int64)
    first_hit = pd.Series(np.arange(1, len(docs) + 1)).groupby(docs).min()
    curve = evaluation.precision_recall(ranking, n_relevant)
    curve["hit_rank"] = first_hit.reindex(curve["doc_id"]).to_numpy(dtype=np.int64)
    curve.attrs["average_precision"] = evaluation.average_precision(ranking, n_relevant)
    return curve


def precision_recall_plot(curve: pd.DataFrame, label: str = "", width: int = 720, height: int = 280) -> hv.Overlay:
    """Precision and recall over the rank, as returned by :func:`precision_recall`.

    Parameters
    ----------
    curve : pandas.DataFrame
        With ``rank``, ``precision``, ``recall`` (and ``doc_id``, ``relevant`` for the hover).
    label : str
        The query's label (for the title).
    width, height : int
        Pixels.

    Returns
    -------
    holoviews.Overlay
        Two step curves with markers (y: fraction 0..1, x: rank of the document): precision's markers (circles)
        a little left of their rank, recall's (squares) a little right (:data:`MARKER_OFFSET`), so that equal
        values never hide each other; ticks at whole ranks only (every one up to :data:`MAX_TICKS` documents, then every second, ...).
    """
    y = hv.Dimension("fraction", range=(-0.04, 1.05))  # a line at 0 stays visible above the axis
    layers = []
    for i, (column, offset) in enumerate((("precision", -MARKER_OFFSET), ("recall", MARKER_OFFSET))):
        colour, marker = SERIES[i], MARKERS[i]
        data = curve[["rank", column, "doc_id", "relevant"]].rename(columns={column: "fraction"})
        layers.append(hv.Curve(data, "rank", [y, "doc_id", "relevant"], label=column)
                      .opts(interpolation="steps-post", color=colour, line_width=2))
        shifted = data.assign(document_rank=data["rank"], rank=data["rank"] + offset)
        layers.append(hv.Scatter(shifted, "rank", [y, "document_rank", "doc_id", "relevant"], label=column)
                      .opts(color=colour, marker=marker, size=8, tools=["hover"]))
    n = int(curve["rank"].max()) if len(curve) else 1
    ticks = list(range(1, n + 1, -(-n // MAX_TICKS)))  # whole ranks only, at most MAX_TICKS of them
    title = f"precision / recall over rank: {label}" if label else "precision / recall over rank"
    return hv.Overlay(layers).opts(width=width, height=height, title=title, legend_position="bottom_right",
                                   xlabel="rank of document", ylabel="fraction", show_grid=True, toolbar="above",
                                   xlim=(0.5, n + 0.5), xticks=ticks)
