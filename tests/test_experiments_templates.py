"""Motion templates evaluated leave-actor-out on real clips: the embedded sample (two actors) and the 287 HDM05 cut
clips (five actors, the issue's target: mAP >= 0.90, no class below 0.75)."""

import numpy as np
import pytest

from mocapviz import MotionDB, ParameterError
from mocapviz.experiments.evaluation import average_precision, relevance
from mocapviz.experiments.templates import template_quality
from mocapviz.features import relational_features
from mocapviz.io import datasets
from mocapviz.relational.templates import MotionTemplate, document_costs, learn_class


@pytest.fixture(scope="module")
def sample_db30(tmp_path_factory):
    return MotionDB.ingest(datasets.sample() / "hdm05-cut", tmp_path_factory.mktemp("s30") / "db", fps=30,
                           progress=False)  # fmt: skip


def test_learn_class_uses_the_label_and_actors_asked_for(sample_db30, tmp_path):
    t = learn_class(sample_db30, "squat1Reps", actors=["dg"])
    expected = sample_db30.select(label="squat1Reps", actor="dg")["doc_id"].tolist()
    assert t.meta["doc_ids"] == expected and t.n_examples == len(expected) == 1
    assert t.values.shape[1] == 39 and t.meta["relational_set"] == "2006"
    t.save(tmp_path / "squat.npz")
    back = MotionTemplate.load(tmp_path / "squat.npz")
    np.testing.assert_array_equal(back.values, t.values)
    assert (back.label, back.features, back.meta) == (t.label, t.features, t.meta)
    with pytest.raises(ParameterError, match="no document .* has label 'fly'"):
        learn_class(sample_db30, "fly")


def test_the_evaluation_equals_ranking_the_clips_by_hand(sample_db30):
    """Two actors: the squat template learned on dg's clips ranks mm's clips; the experiment's AP is that of the
    ranking by document_costs, judged by the product's evaluation."""
    res = template_quality(sample_db30)
    row = res["per_template"].set_index(["class", "group"]).loc[("squat1Reps", "mm")]
    values, _ = relational_features(sample_db30, "2006", progress=False)
    t = learn_class(sample_db30, "squat1Reps", actors=["dg"], values=values)
    mm = sample_db30.select(actor="mm")
    rows = np.concatenate([np.arange(s, s + n) for s, n in zip(mm["start"], mm["n_frames"])])
    starts = np.concatenate([[0], np.cumsum(mm["n_frames"].to_numpy())[:-1]])
    order = np.argsort(document_costs(t, values[rows], starts), kind="stable")
    ranking, n = relevance(mm["doc_id"].to_numpy()[order], sample_db30.documents.set_index("doc_id")["label"], None,
                           candidates=mm["doc_id"], label="squat1Reps")  # fmt: skip
    assert row["ap_group"] == pytest.approx(average_precision(ranking, n))
    assert len(res["classification"]) == len(sample_db30.documents)
    assert set(res["per_template"]["group"]) == {"dg", "mm"}


def test_leave_actor_out_on_hdm05_meets_the_target(hdm05_db30):
    res = template_quality(hdm05_db30)
    summary, per_class = res["summary"].iloc[0], res["per_class"]
    assert summary["templates"] == 55 and len(per_class) == 11  # 11 classes x 5 actors
    assert summary["map_group"] >= 0.90 and per_class["ap_group"].min() >= 0.75
    assert summary["classification_accuracy"] >= 0.95 and summary["clips_classified"] == 287


def test_the_keyframe_prefilter_keeps_the_full_passs_good_hits(hdm05_db30):
    """Templates learned on four actors: every hit of normalised cost <= 0.1 of the full DTW pass over the 287
    clips is found again when only the keyframe ranges (read from the 2006 relational indexes) are aligned, and the
    costs are the same."""
    from mocapviz.relational import index
    from mocapviz.relational.templates import find_instances, keyframe_ranges

    values, _ = relational_features(hdm05_db30, "2006", progress=False)
    indexes = index.build(hdm05_db30, "2006", values=values, save=False, progress=False)
    starts = hdm05_db30.documents["start"].to_numpy()
    aligned = []
    for label in ("squat1Reps", "kickLFront1Reps", "elbowToKnee1RepsLelbowStart", "jogLeftCircle4StepsRstart"):
        t = learn_class(hdm05_db30, label, ["bd", "bk", "dg", "tr"], values=values)
        ranges = keyframe_ranges(t, indexes, starts, len(values))
        assert (np.diff(ranges, axis=1) > 0).all() and (np.diff(ranges.ravel()) >= 0).all()
        full = find_instances(t, values, starts, n_matches=40, max_cost=0.1)
        pre = find_instances(t, values, starts, n_matches=40, max_cost=0.1, ranges=ranges)
        assert len(full) > 10
        merged = full.merge(pre, on=["doc_id", "start", "end"], suffixes=("", "_pre"))
        assert len(merged) == len(full)
        np.testing.assert_allclose(merged["cost_pre"], merged["cost"])
        aligned.append((ranges[:, 1] - ranges[:, 0]).sum() / len(values))
    assert min(aligned) < 0.9  # it does leave frames out


@pytest.mark.slow
def test_every_class_clears_080_for_every_held_out_actor(hdm05_db30):
    """Issue 25: learned without the searched actor, every (class, actor) reaches AP >= 0.80 on the 287 HDM05 clips
    (kickLFront1Reps of actor tr was 0.64 and throwBasketball of mm 0.50 with the pooled quantisation and
    unbounded subsequence DTW, which ``by_group=False, max_rows=0`` still gives), at no cost in mAP or
    classification."""
    res = template_quality(hdm05_db30)
    per = res["per_template"].set_index(["class", "group"])["ap_group"]
    summary = res["summary"].iloc[0]
    assert per.min() >= 0.80, per.sort_values().head()
    assert per[("kickLFront1Reps", "tr")] >= 0.80 and per[("throwBasketball", "mm")] >= 0.80
    assert summary["map_group"] >= 0.99 and summary["classification_accuracy"] >= 0.99
    old = template_quality(hdm05_db30, by_group=False, max_rows=0)
    before = old["per_template"].set_index(["class", "group"])["ap_group"]
    assert before[("kickLFront1Reps", "tr")] < 0.80 and before.min() < 0.80
    assert old["summary"].iloc[0]["map_group"] < summary["map_group"]
