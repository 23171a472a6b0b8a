"""The annotation loop's simulated annotator (mocapviz.experiments.annotation, issue 40 item 4) on the demo database:
actor tr's clips of three classes hidden, the loop labels them, the labels written into the copy are the oracle's,
the baselines' costs equal counts made here by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
import pytest

from mocapviz import Engine, MotionDB
from mocapviz.errors import MotionDBError, ParameterError
from mocapviz.experiments.annotation import annotator_view, expected_random_cost, order_cost, simulated_annotation

CLASSES = ["kickLFront1Reps", "squat1Reps", "jogLeftCircle4StepsRstart"]


@pytest.fixture(scope="module")
def demo():
    return MotionDB.demo()


@pytest.fixture(scope="module")
def runs(demo, tmp_path_factory):
    """Two runs of the whole protocol into two work folders."""
    work = [tmp_path_factory.mktemp(f"annotation{i}") for i in range(2)]
    return work, [simulated_annotation(demo, "tr", Engine, w, classes=CLASSES) for w in work]


def test_the_view_hides_the_classes_of_the_hidden_actor_only(demo, runs):
    view = MotionDB.open(runs[0][0] / "view.mdb")
    docs, seen = demo.documents, view.documents
    hidden = docs["actor"].eq("tr").fillna(False).to_numpy(bool)
    assert hidden.sum() == 11 and list(seen["doc_id"]) == list(docs["doc_id"])
    assert seen.loc[hidden, ["label", "class"]].isna().all().all()
    pd.testing.assert_frame_equal(seen.loc[~hidden, ["name", "label", "actor"]], docs.loc[~hidden, ["name", "label", "actor"]],
                                  check_dtype=False)  # fmt: skip
    assert np.array_equal(view.positions, demo.positions)
    assert np.array_equal(view.quaternions, demo.quaternions, equal_nan=True)  # (NaN where a clip has no rotations)
    with pytest.raises(ParameterError, match="no document has actor 'nobody'"):
        simulated_annotation(demo, "nobody", Engine, runs[0][0] / "x")


def test_the_loop_labels_90_percent_of_each_class_with_the_oracles_labels(demo, runs):
    work, (first, _) = runs
    per_class = first["per_class"].set_index("class")
    truth = demo.documents.set_index("doc_id")["label"]
    tr = demo.documents.loc[demo.documents["actor"].eq("tr").fillna(False).to_numpy(bool), "doc_id"]
    labels = Engine(MotionDB.open(work[0] / "one_by_one.mdb")).segment_labels()
    for c in CLASSES:
        of_class = set(tr[truth[tr].eq(c).to_numpy(bool)])
        accepted = labels[(labels["label"] == c) & (labels["source"] == "accepted hit")]
        assert len(set(accepted["doc_id"]) & of_class) >= math.ceil(0.9 * len(of_class))
        assert per_class.loc[c, "one_by_one_stop"] == "target"
        assert per_class.loc[c, "one_by_one_labelled"] >= per_class.loc[c, "needed"]
    # one by one: every accepted hit lies in a clip of its class, every rejected one elsewhere
    right = truth.reindex(labels["doc_id"]).to_numpy() == labels["label"].to_numpy()
    assert len(labels) == first["trace"]["variant"].eq("one by one").sum()
    assert right[(labels["source"] == "accepted hit").to_numpy()].all()
    assert not right[(labels["source"] == "rejected hit").to_numpy()].any()
    assert (per_class["one_by_one_precision"] == 1.0).all()
    # the whole page: every hit shown is accepted, and its precision is the share of right ones among them
    whole = Engine(MotionDB.open(work[0] / "whole_page.mdb")).segment_labels()
    assert set(whole["source"]) == {"accepted hit"}
    for c in CLASSES:
        mine = whole[whole["label"] == c]
        assert len(mine) == per_class.loc[c, "whole_page_reviewed"]
        assert per_class.loc[c, "whole_page_precision"] == pytest.approx((truth.reindex(mine["doc_id"]) == c).mean())
    assert (per_class["whole_page_precision"] < 1).all()


def test_the_baselines_equal_counts_by_hand(demo, runs):
    per_class = runs[1][0]["per_class"].set_index("class")
    docs = demo.documents
    unlabelled = docs[docs["label"].isna() | docs["actor"].eq("tr").fillna(False)].sort_values("doc_id")
    for c in CLASSES:
        n = int((unlabelled["label"] == c).sum())
        seen, position = 0, None
        for i, label in enumerate(unlabelled["label"], 1):
            seen += label == c
            if seen >= math.ceil(0.9 * n):
                position = i
                break
        assert per_class.loc[c, "document_order"] == position
        assert per_class.loc[c, "unlabelled"] == len(unlabelled) and per_class.loc[c, "to_label"] == n
    # the expected position in random order: every order of 3 clips of the class among 7
    orders = [order_cost(p, "a", 0.6) for p in set(itertools.permutations("aaabbbb"))]
    assert expected_random_cost(7, 3, 0.6) == pytest.approx(np.mean(orders))
    assert order_cost(["b", None, "a", "a"], "a", 0.5) == 3 and order_cost(["b"], "a") == 0


def test_two_runs_are_equal(runs):
    first, second = runs[1]
    for name in ("per_class", "trace", "curves", "summary"):
        pd.testing.assert_frame_equal(first[name], second[name])


def test_the_view_refuses_a_database_folder_that_exists(demo, runs):
    with pytest.raises(MotionDBError, match="exists and is not an empty directory"):
        annotator_view(demo, [0], runs[0][0] / "view.mdb")
