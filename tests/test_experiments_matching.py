"""mocapviz.experiments.matching on the HDM05 cut clips at 30 Hz: the lazy neighbourhood graph against subsequence
DTW (Krüger et al. 2010 §4.2), Fig. 3's similarity matrices, Müller 2005 §7's segment-restricted alignment and
Table 2's numerical / logical search."""

from __future__ import annotations

import numpy as np
import pytest

from mocapviz import MotionDB
from mocapviz.experiments import alignment, lng_accuracy, numerical_search, similarity_matrices, summarize_accuracy
from mocapviz.experiments.matching import krueger2010_table2
from mocapviz.features.numeric import numeric_of


@pytest.fixture(scope="module")
def db(hdm05_dir, tmp_path_factory):
    return MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("expmatch") / "db", fps=30, progress=False)


@pytest.fixture(scope="module")
def jog(db) -> list[int]:
    return db.select(label="jogLeftCircle4StepsRstart")["doc_id"].astype(int).tolist()


def test_lng_accuracy_equals_dtw_with_large_neighbourhoods(db):
    """With 4096 neighbours per frame (23 % of the frames) nearly every match's cost is DTW's exactly, and the
    ranking of the matches by the graph's costs is DTW's (the paper: rho > 0.99)."""
    per_query = lng_accuracy(db, n_queries=4, seconds=(1.0,), k=4096, eps=(0.0, 0.5), seed=3)
    assert len(per_query) == 8 and set(per_query["eps"]) == {0.0, 0.5}
    exact = per_query[per_query["eps"] == 0.0]
    assert exact["spearman"].mean() >= 0.99
    assert exact["equal"].mean() >= 0.9
    assert (exact["m"] == 30).all()
    summary = summarize_accuracy(per_query)
    assert summary["queries"].tolist() == [4, 4]
    assert summary["paper_graph_s"].tolist() == [0.03, 0.03]


def test_lng_accuracy_falls_with_small_neighbourhoods(db):
    """The condition of §4.1 fails more often with fewer neighbours: recall of DTW's matches drops."""
    small = lng_accuracy(db, n_queries=6, seconds=(1.0,), k=64, eps=(0.0,), seed=5)
    large = lng_accuracy(db, n_queries=6, seconds=(1.0,), k=2048, eps=(0.0,), seed=5)
    assert (small["query_start"] == large["query_start"]).all()
    assert small["recall"].mean() < large["recall"].mean()
    assert (small["lng_matches"] <= large["lng_matches"] + 2).all()


def test_similarity_matrices_hold_distances_kNN_cells_and_paths(db, jog):
    out = similarity_matrices(db, jog[0], (0, 40), jog[1:4], numeric_sets=("F15E", "F15x3E"), k=24)
    rows = np.concatenate([np.arange(db.frames(d).start, db.frames(d).stop) for d in jog[1:4]])
    X = np.asarray(numeric_of(db, "F15E"), dtype=np.float64)
    q = X[db.frames(jog[0]).start : db.frames(jog[0]).start + 40]
    np.testing.assert_allclose(out["F15E"]["distance"], np.linalg.norm(q[:, None] - X[rows][None], axis=-1),
                               rtol=1e-9)  # fmt: skip
    for name in ("F15E", "F15x3E"):
        res = out[name]
        assert (res["computed"].sum(axis=1) == 24).all()  # k cells per query frame, nothing else
        # every computed cell of a row is no farther than every skipped one
        d = res["distance"]
        assert (np.where(res["computed"], d, -np.inf).max(axis=1) <= np.where(res["computed"], np.inf, d).min(axis=1)
                + 1e-9).all()  # fmt: skip
        for path in res["matches"]["path"]:
            assert res["computed"][path[:, 0], path[:, 1]].all()  # the graph's paths run over kNN cells only
    dpc = out["Dpc1"]
    assert dpc["computed"].all() and dpc["distance"].shape == (40, len(rows))
    best = dpc["matches"].iloc[0]
    assert dpc["distance"][best.path[:, 0], best.path[:, 1]].sum() == pytest.approx(best.cost, rel=1e-9)
    assert out["database_starts"].tolist() == [0, *np.cumsum([len(range(*db.frames(d).indices(db.n_frames)))
                                                             for d in jog[1:3]])]  # fmt: skip


def test_alignment_band_dtw_finds_the_full_dtw_path(db, jog):
    """Müller 2005 §7: DTW restricted to the enlarged area of the matched segments; on two jogs of the same class
    it finds the path of full DTW at a fraction of the matrix."""
    out = alignment(db, jog[0], jog[1], margin=4, repeats=1)
    s = out["summary"].iloc[0]
    assert s["cost_band"] >= s["cost_full"] - 1e-9
    assert 0 < s["band_share"] < 0.6
    band, path = out["band"], out["path_band"]
    assert ((path[:, 1] >= band[path[:, 0], 0]) & (path[:, 1] < band[path[:, 0], 1])).all()
    assert s["same_path"] and s["cost_band"] == s["cost_full"] and s["path_diff_max"] == 0
    # the segment path pairs every segment of both clips, in order
    pairs = out["segment_path"]
    assert pairs[0].tolist() == [0, 0]
    assert pairs[-1].tolist() == [len(out["segments_a"].codes) - 1, len(out["segments_b"].codes) - 1]
    # the two foot features and no margin: fewer, longer segments; the cost can only grow
    narrow = alignment(db, jog[0], jog[1], features=["rfoot_behind", "lfoot_behind"], margin=0,
                       repeats=1)["summary"].iloc[0]  # fmt: skip
    assert narrow["segments_a"] < s["segments_a"] and narrow["cost_band"] >= s["cost_full"] - 1e-9


def test_numerical_search_counts_hits_against_the_labels(db):
    out = numerical_search(db, classes=["squat1Reps", "elbowToKnee1RepsLelbowStart"],
                           numeric_sets=("F15E", "F15x3E"), k=1024, n_matches=30, iterations=1)  # fmt: skip
    assert len(out) == 4 and set(out["set"]) == {"F15E", "F15x3E"}
    squat = out[out["class"] == "squat1Reps"]
    relevant = int((db.documents["label"] == "squat1Reps").sum()) - 1
    assert (squat["relevant"] == relevant).all()
    assert (out["correct"] >= 1).all(), "a class query finds at least one clip of its class"
    assert (out["logical_correct"] >= out["correct"]).all() and (out["logical_wrong"] >= out["wrong"]).all()
    assert (out["logical_recall"] >= out["recall"]).all()
    f15e = out[out["set"] == "F15E"]
    assert (f15e["correct_new"] == 0).all() and (f15e["wrong_new"] == 0).all()
    assert (out["recall"] <= 1).all()
    with pytest.raises(ValueError, match="not in"):
        numerical_search(db, classes=["moonwalk"])
    table = krueger2010_table2()
    assert len(table) == 18 and table.loc[(table["set"] == "F30x3E") & (table["correct"] == 9), "wrong"].item() == 2


def test_lng_accuracy_queries_last_their_seconds_at_each_documents_own_rate(tmp_path):
    """A database mixing 120 Hz and 30 Hz documents (the embedded sample's HDM05 clips, two CMU trials resampled
    to 30 Hz): a 1 s query is 120 frames in the former and 30 in the latter; typical_fps is the rate of most
    frames."""
    from mocapviz.io import datasets

    sample = datasets.sample()
    hdm = MotionDB.ingest(sample / "hdm05-cut", tmp_path / "hdm", progress=False)
    cmu = MotionDB.ingest(sample / "cmu-asfamc", tmp_path / "cmu", progress=False)
    db = MotionDB.create(tmp_path / "mixed").append_motions(  # (appending refuses another rate; creating mixes)
        [hdm.motion(int(d)) for d in hdm.documents["doc_id"]]
        + [cmu.motion(int(d)).resample(30.0) for d in cmu.documents["doc_id"]])
    assert db.fps is None and sorted(set(db.documents["fps"])) == [30.0, 120.0] and db.typical_fps == 120.0
    rows = lng_accuracy(db, n_queries=24, seconds=(1.0,), k=16, eps=(0.0,), seed=1)
    rates = db.documents.set_index("doc_id").loc[rows["query_doc"], "fps"].to_numpy()
    assert set(rates) == {30.0, 120.0}
    np.testing.assert_array_equal(rows["m"].to_numpy(), np.round(rates).astype(int))
