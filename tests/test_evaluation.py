"""mocapviz.experiments.evaluation: relevance, precision, recall and average precision against hand-worked rankings, and against
their definitions on the labels of the 287 HDM05 clips."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mocapviz.errors import ParameterError
from mocapviz.experiments.evaluation import average_precision, precision_at, precision_recall, relevance

# doc 0 is the query (label A); the other A documents are 1, 3 and 5; doc 4 has no label
LABELS = pd.Series(["A", "A", "B", "A", None, "A"], index=[0, 1, 2, 3, 4, 5])
# ranked hits: the query itself (left out), 1 (A), 2 (B), 1 again (counts once), 4 (no label), 3 (A); 5 never found
HITS = [0, 1, 2, 1, 4, 3]


def test_a_ranking_judged_by_hand():
    ranking, n_relevant = relevance(HITS, LABELS, query_doc=0)
    assert ranking["doc_id"].tolist() == [1, 2, 4, 3] and ranking["rank"].tolist() == [1, 2, 3, 4]
    assert ranking["relevant"].tolist() == [True, False, False, True]
    assert n_relevant == 3  # documents 1, 3, 5
    curve = precision_recall(ranking, n_relevant)
    np.testing.assert_allclose(curve["precision"], [1 / 1, 1 / 2, 1 / 3, 2 / 4])
    np.testing.assert_allclose(curve["recall"], [1 / 3, 1 / 3, 1 / 3, 2 / 3])
    assert curve.attrs["n_relevant"] == 3
    # precision 1/1 at doc 1, 2/4 at doc 3, doc 5 never found adds 0
    assert average_precision(ranking, n_relevant) == pytest.approx((1 / 1 + 2 / 4) / 3)
    assert precision_at(ranking, 1) == 1.0 and precision_at(ranking, 2) == 0.5
    assert precision_at(ranking, 3) == pytest.approx(1 / 3)  # R-precision: 3 relevant documents
    assert precision_at(ranking, 10) == pytest.approx(2 / 10)  # missing ranks count as not relevant


def test_candidates_restrict_the_relevant_set():
    # leave-one-out style: the search could only return documents 1-4, so document 5 is not missed
    ranking, n_relevant = relevance(HITS, LABELS, query_doc=0, candidates=[1, 2, 3, 4])
    assert n_relevant == 2 and ranking["relevant"].tolist() == [True, False, False, True]
    assert average_precision(ranking, n_relevant) == pytest.approx((1 / 1 + 2 / 4) / 2)
    # a returned document outside the candidates is never relevant (document 1 here)
    ranking, n_relevant = relevance(HITS, LABELS, query_doc=0, candidates=[2, 3, 4, 5])
    assert n_relevant == 2 and ranking["relevant"].tolist() == [False, False, False, True]
    assert average_precision(ranking, n_relevant) == pytest.approx((1 / 4) / 2)


def test_a_query_that_is_no_document_is_judged_by_its_label():
    """A motion template of class A: nothing is left out, document 0 counts like any other A document."""
    ranking, n_relevant = relevance(HITS, LABELS, query_doc=None, label="A")
    assert ranking["doc_id"].tolist() == [0, 1, 2, 4, 3] and n_relevant == 4
    assert ranking["relevant"].tolist() == [True, True, False, False, True]
    assert average_precision(ranking, n_relevant) == pytest.approx((1 + 1 + 3 / 5) / 4)
    for bad in ({"query_doc": None}, {"query_doc": 0, "label": "A"}):
        with pytest.raises(ParameterError, match="query_doc"):
            relevance(HITS, LABELS, **bad)


def test_perfect_empty_and_unjudgeable_rankings():
    ranking, n_relevant = relevance([3, 5, 1, 2], LABELS, query_doc=0)
    assert average_precision(ranking, n_relevant) == 1.0 and precision_at(ranking, n_relevant) == 1.0
    empty, n_relevant = relevance([0], LABELS, query_doc=0)  # only the query found itself
    assert empty.empty and average_precision(empty, n_relevant) == 0.0 and precision_at(empty, 1) == 0.0
    assert precision_recall(empty, n_relevant).empty
    # a query without a label, or alone in its class: nothing is relevant, recall and AP are undefined
    for query, labels in ((4, LABELS), (2, LABELS)):
        ranking, n_relevant = relevance([1, 2, 3], labels, query_doc=query)
        assert n_relevant == 0 and not ranking["relevant"].any()
        assert np.isnan(average_precision(ranking, n_relevant))
        assert precision_recall(ranking, n_relevant)["recall"].isna().all()


def test_missing_labels_of_a_string_column_are_never_relevant():
    """pandas' string dtype holds pd.NA for a missing label (as ``documents[...].astype("string")`` gives)."""
    ranking, n_relevant = relevance(HITS + [7], LABELS.astype("string"), query_doc=0)  # 7: not a labelled document
    assert ranking["relevant"].tolist() == [True, False, False, True, False] and n_relevant == 3


def test_bad_arguments_say_what_to_pass():
    with pytest.raises(ParameterError, match="query_doc 9 is not a document"):
        relevance(HITS, LABELS, query_doc=9)
    ranking, _ = relevance(HITS, LABELS, query_doc=0)
    with pytest.raises(ParameterError, match="n must be at least 1; got 0"):
        precision_at(ranking, 0)


def test_on_the_hdm05_labels_against_the_definitions(hdm05_db30):
    """Rank every other clip by a fixed, label-blind order (document id descending) and judge it for the first clip
    of each class: AP, precision and recall equal the textbook formulas written out here."""
    docs = hdm05_db30.documents
    labels = pd.Series(docs["label"].to_numpy(), index=docs["doc_id"].to_numpy())
    order = docs["doc_id"].to_numpy()[::-1]
    for label, group in docs.groupby("label"):
        query = int(group["doc_id"].min())
        others = set(group["doc_id"]) - {query}
        ranking, n_relevant = relevance(order, labels, query_doc=query)
        ranked = [d for d in order if d != query]
        hits_at = np.cumsum([d in others for d in ranked])
        assert n_relevant == len(others) and len(ranking) == len(docs) - 1
        curve = precision_recall(ranking, n_relevant)
        np.testing.assert_allclose(curve["precision"], hits_at / np.arange(1, len(ranked) + 1))
        np.testing.assert_allclose(curve["recall"], hits_at / len(others))
        found = [i + 1 for i, d in enumerate(ranked) if d in others]
        expected_ap = np.mean([(j + 1) / rank for j, rank in enumerate(found)])
        assert average_precision(ranking, n_relevant) == pytest.approx(expected_ap), label
        assert precision_at(ranking, len(others)) == pytest.approx(hits_at[len(others) - 1] / len(others))
        # a ranking that puts the class first is perfect
        perfect, _ = relevance(sorted(others) + sorted(set(labels.index) - others), labels, query_doc=query)
        assert average_precision(perfect, n_relevant) == 1.0
