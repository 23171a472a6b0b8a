"""Müller, Röder & Clausen 2005 Tables 2-3 and Figs. 7-9 (mocapviz.experiments.relational) on real HDM05 clips.

The index statistics are checked against a direct count over the feature values, the random-query hit counts
against a brute-force scan of the feature sequence, the query-by-example table against the hits themselves.
"""
from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB
from mocapviz.experiments import index_statistics, query_statistics, relational_query
from mocapviz.experiments.relational import (
    DEFAULT_QUERIES,
    HIT_GROUPS,
    TABLE2_COLUMNS,
    mueller2005_table2,
    mueller2005_table3,
)
from mocapviz.features import feature_groups, feature_names, relational_features
from mocapviz.features.segmentation import encode
from mocapviz.relational.index import build
from mocapviz.relational.query import query_by_example

PER_CLASS = 5  # 11 classes: 55 clips


@pytest.fixture(scope="module")
def db(hdm05_dir, hdm05_labels, tmp_path_factory):
    """About 60 HDM05 cut clips (the first 5 of each class), ingested at 120 Hz."""
    rows = hdm05_labels.sort_values("file").groupby("class").head(PER_CLASS)
    files = [hdm05_dir / f for f in rows["file"]]
    return MotionDB.ingest(files, tmp_path_factory.mktemp("exp") / "db", fps=120, threads=1, progress=False)


@pytest.fixture(scope="module")
def values(db):
    return relational_features(db, progress=False)[0]


@pytest.fixture(scope="module")
def upper(db, values):
    return build(db, progress=False, values=values)["upper"]


# ---------------------------------------------------------------------- Table 2
def test_index_statistics_counts_match_the_features(db, values):
    table = index_statistics(db, values=values, t_read=1.5)
    groups = feature_groups("2005")
    assert table["group"].tolist() == list(groups)
    assert table["index"].tolist()[0].startswith("I_l^")
    names = feature_names("2005")
    starts = db.documents["start"].to_numpy()
    for row in table.to_dict("records"):
        codes = encode(values[:, [names.index(n) for n in groups[row["group"]]]])
        new = np.ones(codes.size, dtype=bool)
        new[1:] = codes[1:] != codes[:-1]
        new[starts] = True
        assert row["f"] == len(groups[row["group"]]) and row["2^f"] == 2 ** row["f"]
        assert row["frames"] == db.n_frames
        assert row["segments"] == new.sum() <= row["frames"]
        assert row["lists"] == np.unique(codes).size <= row["2^f"]
        assert 8 <= row["bytes/segment"] <= 40, row
        assert row["MB"] == pytest.approx(row["bytes/segment"] * row["segments"] / 2**20)
        assert row["t_read"] == 1.5 and np.isnan(row["t_features"]) and row["t_index"] > 0
        assert row["t_total"] == pytest.approx(row["t_read"] + row["t_index"])
        assert row["minutes"] == pytest.approx(db.n_frames / 120 / 60)


def test_index_statistics_times_the_features_and_matches_the_saved_index(db, values, upper):
    table = index_statistics(db).set_index("group")
    assert table["t_features"].gt(0).all() and table["t_read"].isna().all()
    # one number for the three groups: the features are computed in one pass
    assert table["t_features"].nunique() == 1
    # the same lists and segments as the index that mocapviz.relational.index.build saves
    assert table.loc["upper", "segments"] == upper.n_segments == np.diff(upper.list_offsets).sum()
    assert table.loc["upper", "lists"] == upper.list_codes.size
    assert table.loc["upper", "MB"] * 2**20 == upper.nbytes()
    with pytest.raises(ValueError, match="shape"):
        index_statistics(db, values=values[:, :5])


def test_mueller2005_table2_is_consistent():
    """The transcription of Table 2: MB / segments = bytes per segment, the times add up, the columns match."""
    paper = mueller2005_table2()
    assert paper.columns.tolist() == TABLE2_COLUMNS
    assert len(paper) == 6 and (paper["2^f"] == 2 ** paper["f"]).all()
    bps = paper["MB"] * 2**20 / paper["segments"]
    assert np.allclose(bps, paper["bytes/segment"], rtol=0.02), bps
    assert (paper["t_read"] + paper["t_features"] + paper["t_index"] == paper["t_total"]).all()
    assert (paper["segments"] <= paper["frames"]).all() and (paper["lists"] <= paper["2^f"]).all()


# ---------------------------------------------------------------------- Table 3
def _scan_exact(codes, doc, query) -> int:
    n = len(query)
    return sum(
        np.array_equal(codes[k : k + n], query) and doc[k] == doc[k + n - 1] for k in range(codes.size - n + 1)
    )


def _merge(sets):
    out = []
    for s in sets:
        s = {int(c) for c in s}
        while out and out[-1] & s:
            s |= out.pop()
        out.append(s)
    return out


def _scan_adaptive(codes, doc, sets) -> int:
    """Adaptive fuzzy hits straight from §5.2: runs of V_1, then of V_2 right after, ... in one document."""
    sets = _merge(sets)
    m, hits = codes.size, 0
    for k in range(m):
        if codes[k] not in sets[0] or (k > 0 and doc[k - 1] == doc[k] and codes[k - 1] in sets[0]):
            continue
        p = k
        for s in sets:
            if p >= m or doc[p] != doc[k] or codes[p] not in s:
                break
            while p < m and doc[p] == doc[k] and codes[p] in s:
                p += 1
        else:
            hits += 1
    return hits


def test_query_statistics_hits_equal_a_brute_force_scan(upper):
    raw = query_statistics(upper, n_queries=30, lengths=(3, 8), fuzzy_size=16, seed=3, per_query=True)
    assert len(raw) == 2 * 2 * 30 and (raw["hits"] >= 1).all() and (raw["ms"] > 0).all()
    codes, doc = upper.codes, upper.segment_doc
    for row in raw.to_dict("records"):
        k, length, q = row["k"], row["L"], row["query"]
        assert doc[k] == doc[k + length - 1]
        if row["mode"] == "exact":
            assert np.array_equal(q, codes[k : k + length])
            assert row["hits"] == _scan_exact(codes, doc, q)
        else:
            assert len(q) == length and all(len(set(s)) == 16 and s[0] == c for s, c in zip(q, codes[k:]))
            assert all(not set(a) & set(b) for a, b in itertools.pairwise(q)), "adjacent fuzzy sets must be disjoint"
            assert row["hits"] == _scan_adaptive(codes, doc, q)


@pytest.mark.parametrize("alternatives, size", [("random", 512), ("dont_care", 16)])
def test_overlapping_fuzzy_sets_still_have_a_hit(upper, alternatives, size):
    """Sets whose neighbours may meet (conjoined by the index) still give >= 1 hit, the brute-force count."""
    raw = query_statistics(upper, n_queries=20, lengths=(6,), modes=("fuzzy",), fuzzy_size=size, seed=5,
                           alternatives=alternatives, per_query=True)  # fmt: skip
    assert any(set(a) & set(b) for q in raw["query"] for a, b in itertools.pairwise(q))
    for row in raw.to_dict("records"):
        q = row["query"]
        assert all(len(set(s)) == size for s in q)
        if alternatives == "dont_care":  # the set = every vector that agrees with w on all but log2(size) bits
            for s in q:
                assert int(np.bitwise_and.reduce(~(s ^ s[0]) & (2**upper.n_features - 1))).bit_count() == 8
        assert row["hits"] == _scan_adaptive(upper.codes, upper.segment_doc, q) >= 1


def test_query_statistics_groups(upper):
    table = query_statistics(upper, n_queries=40, lengths=(2, 5), seed=1)
    assert table[["mode", "L", "hits"]].value_counts().eq(1).all()
    assert len(table) == 2 * 2 * len(HIT_GROUPS)
    assert table.groupby(["mode", "L"])["queries"].sum().eq(40).all()
    lo, mid, hi = (table[table["hits"] == g] for g in HIT_GROUPS)
    assert lo["mean_hits"].dropna().between(1, 9).all() and mid["mean_hits"].dropna().between(10, 99).all()
    assert hi["mean_hits"].dropna().ge(100).all()
    assert table.loc[table["queries"] > 0, "mean_ms"].gt(0).all()
    assert table.columns.tolist() == mueller2005_table3().columns.tolist()
    assert len(mueller2005_table3()) == 18


def test_random_queries_reject_bad_parameters(upper):
    from mocapviz.experiments.relational import random_queries

    with pytest.raises(ValueError, match="shorter"):
        random_queries(upper, 1, 10**6)
    with pytest.raises(ValueError, match="fuzzy_size"):
        random_queries(upper, 1, 2, "fuzzy", fuzzy_size=2**11)
    with pytest.raises(ValueError, match="mode"):
        random_queries(upper, 1, 2, "adaptive")
    with pytest.raises(ValueError, match="power of 2"):
        random_queries(upper, 1, 2, "fuzzy", fuzzy_size=48, alternatives="dont_care")
    with pytest.raises(ValueError, match="alternatives"):
        random_queries(upper, 1, 2, "fuzzy", alternatives="some")


# ---------------------------------------------------------------------- Figs. 7-9
def _ap_by_definition(ranked_docs, relevant_docs) -> float:
    """Average precision straight from its definition: the mean over the relevant documents of the precision at the
    rank where each is found (0 when never found)."""
    ranked = list(dict.fromkeys(ranked_docs))
    found = [ranked.index(d) + 1 for d in relevant_docs if d in ranked]
    return sum(sum(r <= rank for r in found) / rank for rank in found) / len(relevant_docs)


def test_relational_query_per_class(db, upper):
    table = relational_query(db)
    assert set(table["class"]) == set(DEFAULT_QUERIES) == set(db.documents["label"])
    assert table["self_retrieved"].all()
    assert (table["relevant"] == PER_CLASS - 1).all()  # the query document is left out of the relevant set
    assert table["precision"].dropna().between(0, 1).all() and table["ap"].between(0, 1).all()
    assert (table["hits"] >= table["hit_docs"]).all() and (table["ms"] > 0).all()
    assert (table["recall"] > 0).any() and (table["ap"] <= table["recall"] + 1e-12).all()
    # every class's row agrees with its hits: documents ranked by their best hit, the query document left out
    labels = db.documents.set_index("doc_id")["label"]
    for row in table.to_dict("records"):
        hits = query_by_example(db, db.motion(int(row["query_doc"])), DEFAULT_QUERIES[row["class"]])
        ranked = [d for d in hits.sort_values("score", kind="stable")["doc_id"] if d != row["query_doc"]]
        others = [d for d in labels.index[labels == row["class"]] if d != row["query_doc"]]
        hit_docs = set(ranked)
        assert row["hits"] == len(hits) and row["hit_docs"] == len(hit_docs)
        assert row["relevant_retrieved"] == len(hit_docs & set(others))
        assert row["recall"] == pytest.approx(row["relevant_retrieved"] / len(others))
        if hit_docs:
            assert row["precision"] == pytest.approx(row["relevant_retrieved"] / len(hit_docs))
        top = list(dict.fromkeys(ranked))[: len(others)]
        assert row["r_precision"] == pytest.approx(sum(d in others for d in top) / len(others))
        assert row["ap"] == pytest.approx(_ap_by_definition(ranked, others))


def test_relational_query_with_given_queries(db, upper):
    squats = db.select(label="squat1Reps")["doc_id"].tolist()
    table = relational_query(db, {"squat1Reps": (squats[2], ["rknee_bent"])})
    assert table["query_doc"].tolist() == [squats[2]] and table["features"].iloc[0] == "rknee_bent"
    assert table["self_retrieved"].iloc[0] and table["relevant"].iloc[0] == PER_CLASS - 1
    with pytest.raises(ValueError, match="no document of class"):
        relational_query(db, {"punchRFront": (None, ["rhand_in_front"])})
    with pytest.raises(ValueError, match="not of class"):
        relational_query(db, {"squat1Reps": (int(db.select(label="grabHighR")["doc_id"].iloc[0]), ["rknee_bent"])})
    assert isinstance(table, pd.DataFrame)
