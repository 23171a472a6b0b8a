"""mocapviz.similarity.hybrid: relational candidates re-ranked by whole-clip DTW, checked against query_by_example and a
brute-force DTW of every candidate on the 287 HDM05 clips at 30 Hz."""

from __future__ import annotations

import numpy as np
import pytest

from mocapviz.errors import ParameterError
from mocapviz.features import numeric_of
from mocapviz.match import dtw
from mocapviz.relational.index import build
from mocapviz.relational.query import query_by_example
from mocapviz.similarity.hybrid import HYBRID_QUERIES, hybrid_search
from mocapviz.similarity.search import SimilaritySearch

LENIENT = ["lfoot_raised", "rfoot_raised"]


@pytest.fixture(scope="module")
def db(hdm05_db30):
    build(hdm05_db30, progress=False)
    return hdm05_db30


@pytest.fixture(scope="module")
def f15e(db):
    return np.asarray(numeric_of(db, "F15E"), dtype=np.float64)


def _doc_of(db, label: str, i: int = 0) -> int:
    return int(db.select(label=label)["doc_id"].iloc[i])


def _brute_force(db, features, query: int, docs) -> list[tuple[int, float]]:
    """(doc_id, DTW cost / (m + n)) of every document, whole query against whole document, sorted."""
    q = features[db.frames(query)]
    costs = []
    for d in docs:
        x = features[db.frames(int(d))]
        costs.append((int(d), dtw(q, x)[0] / (len(q) + len(x))))
    return sorted(costs, key=lambda t: (t[1], t[0]))


@pytest.mark.parametrize("label, mode, m", [("kickLFront1Reps", "mismatch", 1), ("throwBasketball", "adaptive", 0)])
def test_the_ranking_is_brute_force_dtw_of_the_relational_candidates(db, f15e, label, mode, m):
    query = _doc_of(db, label)
    features = LENIENT if label.startswith("kick") else ["lhand_above_neck"]
    hits = query_by_example(db, db.motion(query), features, mode=mode, mismatches=m)
    ranked = hybrid_search(db, query, features, mode=mode, mismatches=m)
    candidates = set(hits["doc_id"]) - {query}
    assert set(ranked["doc_id"]) == candidates and len(ranked) == len(candidates) > 5  # every hit document, once
    expected = _brute_force(db, f15e, query, candidates)
    np.testing.assert_allclose(ranked["normalised_cost"], [c for _, c in expected], rtol=1e-4)
    assert ranked["doc_id"].tolist() == [d for d, _ in expected]
    assert ranked["rank"].tolist() == list(range(1, len(ranked) + 1))
    m = db.frames(query).stop - db.frames(query).start
    np.testing.assert_allclose(ranked["normalised_cost"], ranked["cost"] / (m + ranked["frames"]))
    # each document's best relational hit comes along
    best = hits.drop_duplicates("doc_id").set_index("doc_id")
    row = ranked.iloc[0]
    assert (row["hit_start"], row["hit_end"], row["hit_score"]) == tuple(
        best.loc[row["doc_id"], ["start", "end", "score"]])
    assert ranked.attrs == {"relational_hits": len(hits), "candidates": len(candidates)}


def test_documents_are_a_subset_of_the_relational_hits_and_of_the_search(db):
    query = _doc_of(db, "kickLFront1Reps", 3)
    actor = db.documents.set_index("doc_id").loc[query, "actor"]
    others = db.documents.loc[db.documents["actor"] != actor, "doc_id"].to_numpy()
    search = SimilaritySearch(db, "F15E", documents=others)  # leave-actor-out
    ranked = hybrid_search(db, query, LENIENT, mode="mismatch", mismatches=1, search=search)
    hit_docs = set(query_by_example(db, db.motion(query), LENIENT, mode="mismatch", mismatches=1)["doc_id"])
    assert set(ranked["doc_id"]) == hit_docs & set(others)
    top = hybrid_search(db, query, LENIENT, mode="mismatch", mismatches=1, search=search, n_matches=5)
    assert top["doc_id"].tolist() == ranked["doc_id"].tolist()[:5]


def test_the_query_document_only_when_asked(db):
    query = _doc_of(db, "throwBasketball", 2)
    kept = hybrid_search(db, query, ["lhand_above_neck"], exclude_document=False)
    assert kept["doc_id"].iloc[0] == query and kept["cost"].iloc[0] == pytest.approx(0.0, abs=1e-6)
    # a Motion has no document: its own clip is found first, as for the doc id with the document kept
    as_motion = hybrid_search(db, db.motion(query), ["lhand_above_neck"])
    assert as_motion["doc_id"].tolist() == kept["doc_id"].tolist()
    np.testing.assert_allclose(as_motion["normalised_cost"], kept["normalised_cost"], rtol=1e-4, atol=1e-6)
    assert query not in set(hybrid_search(db, query, ["lhand_above_neck"])["doc_id"])


def test_no_candidate_gives_an_empty_table(db):
    query = _doc_of(db, "kickLFront1Reps")
    # the four Fig. 9 kick features with plain fuzzy hits find nothing (see query_by_example)
    ranked = hybrid_search(db, query, HYBRID_QUERIES["kickLFront1Reps"]["features"] + ["rknee_bent", "lknee_bent"],
                           mode="fuzzy")
    assert ranked.empty and {"rank", "doc_id", "cost", "normalised_cost", "label", "hit_start"} <= set(ranked.columns)


def test_lenient_table_entries_run(db):
    for label, spec in HYBRID_QUERIES.items():
        ranked = hybrid_search(db, _doc_of(db, label), n_matches=3, **spec)
        assert len(ranked) == 3 and (ranked["label"] == label).sum() >= 2, (label, ranked)


def test_bad_arguments_say_what_to_pass(db):
    query = _doc_of(db, "kickLFront1Reps")
    with pytest.raises(ParameterError, match="mode must be one of"):
        hybrid_search(db, query, LENIENT, mode="loose")
    with pytest.raises(ParameterError, match="n_matches must be at least 1; got 0"):
        hybrid_search(db, query, LENIENT, n_matches=0)
    with pytest.raises(ParameterError, match="example must be a doc id.*or a Motion; got str"):
        hybrid_search(db, "kick", LENIENT)
    with pytest.raises(ParameterError, match="numeric_set 'F15E' differs from the search's 'F30E'"):
        hybrid_search(db, query, LENIENT, search=SimilaritySearch(db, "F30E"))
