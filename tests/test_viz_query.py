"""mocapviz.viz.query: precision and recall of ranked hits (by mocapviz.experiments.evaluation) against hand-computed values, and
the plot holding them."""

from __future__ import annotations

import holoviews as hv
import numpy as np
import pandas as pd
import pytest

from mocapviz.errors import ParameterError
from mocapviz.viz.query import precision_recall, precision_recall_plot

# doc 0 is the query (label A); the other A documents are 1 and 3; doc 4 has no label
DOCUMENTS = pd.DataFrame({"doc_id": [0, 1, 2, 3, 4], "label": ["A", "A", "B", "A", None]})


def test_hits_become_a_ranking_of_documents_judged_by_mocapviz_evaluation():
    # hits by rank: the query's own doc (left out), 1 (A), 2 (B), 1 again (counted once), 4 (no label), 3 (A)
    curve = precision_recall([0, 1, 2, 1, 4, 3], DOCUMENTS, query_doc=0)
    assert curve["doc_id"].tolist() == [1, 2, 4, 3]
    assert curve["rank"].tolist() == [1, 2, 3, 4]  # ranks of documents
    assert curve["hit_rank"].tolist() == [2, 3, 5, 6]  # each document's first hit in the hits table
    assert curve["relevant"].tolist() == [True, False, False, True]
    np.testing.assert_allclose(curve["precision"], [1 / 1, 1 / 2, 1 / 3, 2 / 4])
    np.testing.assert_allclose(curve["recall"], [1 / 2, 1 / 2, 1 / 2, 2 / 2])  # two other A documents: 1 and 3
    assert curve.attrs["n_relevant"] == 2
    assert curve.attrs["average_precision"] == pytest.approx((1 / 1 + 2 / 4) / 2)


def test_recall_is_undefined_without_other_documents_of_the_label():
    curve = precision_recall([2, 0, 1], DOCUMENTS, query_doc=2)
    assert curve["relevant"].tolist() == [False, False] and curve["hit_rank"].tolist() == [2, 3]
    np.testing.assert_allclose(curve["precision"], [0.0, 0.0])
    assert curve["recall"].isna().all() and curve.attrs["n_relevant"] == 0
    assert np.isnan(curve.attrs["average_precision"])


def test_an_unlabelled_or_unknown_query_cannot_be_judged():
    with pytest.raises(ParameterError, match="no label"):
        precision_recall([1], DOCUMENTS, query_doc=4)
    with pytest.raises(ParameterError, match="query_doc 9 is not a document"):
        precision_recall([1], DOCUMENTS, query_doc=9)


def test_plot_holds_the_two_curves():
    curve = precision_recall([0, 1, 2, 1, 4, 3], DOCUMENTS, query_doc=0)
    plot = precision_recall_plot(curve, label="A")
    lines = {el.label: el for el in plot if isinstance(el, hv.Curve)}
    assert set(lines) == {"precision", "recall"}
    np.testing.assert_allclose(lines["precision"].dimension_values("rank"), [1, 2, 3, 4])
    np.testing.assert_allclose(lines["precision"].dimension_values("fraction"), [1, 1 / 2, 1 / 3, 2 / 4])
    np.testing.assert_allclose(lines["recall"].dimension_values("fraction"), [0.5, 0.5, 0.5, 1.0])
    assert len([el for el in plot if isinstance(el, hv.Scatter)]) == 2
    assert plot.opts.get().kwargs["title"].endswith(": A")
    hv.render(plot, backend="bokeh")  # renders without error


def test_a_one_hit_query_shows_both_markers_at_rank_1_with_whole_rank_ticks():
    """One relevant document found first: precision and recall are both 1 at rank 1. Their markers used to lie on
    each other, on an axis ticked at 0.5 and 1.5; now they sit either side of rank 1, the only tick."""
    curve = precision_recall([0, 1], pd.DataFrame({"doc_id": [0, 1], "label": ["A", "A"]}), query_doc=0)
    assert curve[["rank", "precision", "recall"]].values.tolist() == [[1, 1.0, 1.0]]
    plot = precision_recall_plot(curve)
    markers = {el.label: el for el in plot if isinstance(el, hv.Scatter)}
    x = {name: float(m.dimension_values("rank")[0]) for name, m in markers.items()}
    assert x["precision"] < 1 < x["recall"] and x["recall"] - x["precision"] >= 0.1
    assert all(m.dimension_values("document_rank").tolist() == [1] for m in markers.values())  # hover: the rank
    styles = [m.opts.get("style").kwargs for m in markers.values()]
    assert styles[0]["marker"] != styles[1]["marker"] and styles[0]["color"] != styles[1]["color"]
    fig = hv.render(plot, backend="bokeh")
    assert list(fig.xaxis[0].ticker.ticks) == [1] and (fig.x_range.start, fig.x_range.end) == (0.5, 1.5)
    many = precision_recall(list(range(1, 45)), pd.DataFrame({"doc_id": range(45), "label": ["A"] * 45}), 0)
    ticks = hv.render(precision_recall_plot(many), backend="bokeh").xaxis[0].ticker.ticks
    assert all(float(t).is_integer() for t in ticks) and len(ticks) <= 20
