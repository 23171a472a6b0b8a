"""mocapviz.match on real motion: DTW, band-restricted and subsequence DTW against a plain-Python dynamic program,
and the lazy neighbourhood graph against subsequence DTW (Krüger et al. 2010 §4.1: equal paths and costs when the
DTW-aligned frames lie in the neighbourhoods).

Features: F15E of the HDM05 cut clips of the shared data at 30 Hz (287 documents, about 17.9k frames).
"""

from __future__ import annotations

import importlib
import itertools

import numpy as np
import pytest

from mocapviz import MotionDB, ParameterError
from mocapviz.features.distances import dquat_pairwise
from mocapviz.features.numeric import numeric_features
from mocapviz.match import STEP_SETS, band_from_path, dtw, lng, select_matches, subsequence_costs, subsequence_dtw
from mocapviz.match.neighbourhood_graph import graph_matches, neighbourhoods
from mocapviz.similarity.knn import KnnIndex

dtw_mod = importlib.import_module("mocapviz.match.time_warping")  # the module, not the function the package exports


@pytest.fixture(scope="module")
def db(hdm05_dir, tmp_path_factory):
    return MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("match") / "db", fps=30, progress=False)


@pytest.fixture(scope="module")
def X(db) -> np.ndarray:
    return numeric_features(db, "F15E")


@pytest.fixture(scope="module")
def starts(db) -> np.ndarray:
    return db.documents["start"].to_numpy()


@pytest.fixture(scope="module")
def index(X) -> KnnIndex:
    return KnnIndex(X)


def reference_dp(cost: np.ndarray, steps, free_start: bool) -> np.ndarray:
    """Accumulated costs (m, n) of a cost matrix (m, n) by the textbook recursion, in plain Python."""
    m, n = cost.shape
    acc = np.full((m, n), np.inf)
    for i in range(m):
        for j in range(n):
            if i == 0 and (free_start or j == 0):
                acc[i, j] = cost[i, j]
                continue
            best = min((acc[i - di, j - dj] + w * cost[i, j] for di, dj, w in steps if i >= di and j >= dj),
                       default=np.inf)  # fmt: skip
            acc[i, j] = best
    return acc


def path_cost(cost: np.ndarray, path: np.ndarray, steps) -> float:
    """The cost of a path under a step set: the first cell with weight 1, then each step's weight times its cell;
    fails when a move is not a step of the set."""
    weights = {(int(di), int(dj)): w for di, dj, w in steps}
    total = cost[path[0, 0], path[0, 1]]
    for (i0, j0), (i1, j1) in itertools.pairwise(path):
        total += weights[(int(i1 - i0), int(j1 - j0))] * cost[i1, j1]
    return total


def euclidean(a, b) -> np.ndarray:
    return np.sqrt(((a[:, None, :].astype(np.float64) - b[None, :, :]) ** 2).sum(-1))


@pytest.mark.parametrize("steps", list(STEP_SETS))
def test_dtw_equals_the_textbook_recursion(X, starts, steps):
    a, b = X[starts[3] : starts[3] + 40], X[starts[40] + 5 : starts[40] + 70]
    cost = euclidean(a, b)
    ref = reference_dp(cost, STEP_SETS[steps], free_start=False)
    total, path = dtw(a, b, steps=steps)
    assert total == pytest.approx(ref[-1, -1], rel=1e-12)
    assert tuple(path[0]) == (0, 0) and tuple(path[-1]) == (len(a) - 1, len(b) - 1)
    assert path_cost(cost, path, STEP_SETS[steps]) == pytest.approx(total, rel=1e-12)


def test_dtw_takes_a_distance_of_the_distances_module(db, starts):
    quats = np.asarray(db.quaternions)
    a, b = quats[starts[7] : starts[7] + 20], quats[starts[8] : starts[8] + 25]
    cost = dquat_pairwise(a, b)
    total, path = dtw(a, b, distance=dquat_pairwise)
    assert total == pytest.approx(reference_dp(cost, STEP_SETS["basic"], False)[-1, -1], rel=1e-12)
    assert path_cost(cost, path, STEP_SETS["basic"]) == pytest.approx(total, rel=1e-12)


def test_band_restricted_dtw(X, starts):
    """A full band is plain DTW; a band around the optimal path finds it; a band off it costs more; cells outside
    the band are never on the path."""
    a, b = X[starts[10] : starts[10] + 60], X[starts[11] : starts[11] + 80]
    total, path = dtw(a, b)
    full = np.tile([0, len(b)], (len(a), 1))
    assert dtw(a, b, band=full)[0] == total
    band = band_from_path(path, (len(a), len(b)), margin=2)
    t_band, p_band = dtw(a, b, band=band)
    assert t_band == total and np.array_equal(p_band, path)
    # a band of width 3 around the diagonal: a valid path, no cheaper than the optimum, inside the band
    diag = np.round(np.linspace(0, len(b) - 1, len(a))).astype(np.int64)
    narrow = np.stack([diag - 1, diag + 2], axis=1)
    t_narrow, p_narrow = dtw(a, b, band=narrow)
    assert t_narrow >= total
    lo, hi = np.clip(narrow[:, 0], 0, None), narrow[:, 1]
    assert ((p_narrow[:, 1] >= lo[p_narrow[:, 0]]) & (p_narrow[:, 1] < hi[p_narrow[:, 0]])).all()
    assert path_cost(euclidean(a, b), p_narrow, STEP_SETS["basic"]) == pytest.approx(t_narrow, rel=1e-12)


def test_band_from_path_dilates_by_the_margin():
    path = np.array([[0, 0], [1, 1], [2, 1], [3, 2]])
    assert band_from_path(path, (4, 3)).tolist() == [[0, 1], [1, 2], [1, 2], [2, 3]]
    assert band_from_path(path, (4, 5), margin=1).tolist() == [[0, 3], [0, 3], [0, 4], [0, 4]]


@pytest.mark.parametrize("steps", ["basic", "slope"])
def test_subsequence_costs_equal_the_recursion_per_document(X, starts, steps, monkeypatch):
    """Streamed in blocks of a few frames (so that block edges fall inside documents) and over document
    boundaries: the same as the recursion run on each document alone."""
    monkeypatch.setattr(dtw_mod, "_BLOCK_ELEMENTS", 7 * 25)
    docs = [20, 21, 22]
    frames = np.concatenate([np.arange(starts[d], starts[d + 1]) for d in docs])
    local_starts = np.r_[0, np.cumsum([starts[d + 1] - starts[d] for d in docs])[:-1]]
    q = X[starts[100] + 3 : starts[100] + 28]
    cost, first = subsequence_costs(q, X[frames], local_starts, steps=steps)
    for d0, d1 in zip(local_starts, np.r_[local_starts[1:], len(frames)]):
        ref = reference_dp(euclidean(q, X[frames[d0:d1]]), STEP_SETS[steps], free_start=True)[-1]
        np.testing.assert_allclose(cost[d0:d1], ref, rtol=1e-12)
        assert (first[d0:d1][np.isfinite(ref)] >= d0).all()
        assert (first[d0:d1][~np.isfinite(ref)] == -1).all()


def test_subsequence_dtw_matches_are_optimal_non_overlapping_and_within_documents(X, starts):
    q = X[starts[30] + 10 : starts[30] + 40]
    out = subsequence_dtw(q, X, starts, n_matches=15)
    assert len(out) == 15
    assert (np.diff(out["cost"]) >= 0).all()
    spans = sorted(zip(out["start"], out["end"]))
    assert all(e0 < s1 for (_, e0), (s1, _) in itertools.pairwise(spans)), "matches overlap"
    cost, first = subsequence_costs(q, X, starts)
    assert out["cost"].iloc[0] == cost.min() == 0.0  # the query is a stretch of the database
    for row in out.itertuples():
        assert starts[row.doc_id] <= row.start <= row.end < np.r_[starts, len(X)][row.doc_id + 1]
        assert row.cost == cost[row.end] and row.start == first[row.end]
        seg = euclidean(q, X[row.start : row.end + 1])
        assert path_cost(seg, row.path - [0, row.start], STEP_SETS["basic"]) == pytest.approx(row.cost, rel=1e-12)
        assert tuple(row.path[0]) == (0, row.start) and tuple(row.path[-1]) == (len(q) - 1, row.end)


def test_select_matches_is_greedy_by_cost():
    starts, ends = np.array([0, 5, 3, 12, 20]), np.array([4, 9, 7, 15, 25])
    costs = np.array([3.0, 1.0, 0.5, np.inf, 2.0])
    # 2 (cost 0.5, [3, 7]) first; 1 ([5, 9]) and 0 ([0, 4]) overlap it; then 4; 3 is infinite
    assert select_matches(starts, ends, costs, 10).tolist() == [2, 4]
    assert select_matches(starts, ends, costs, 1).tolist() == [2]


QUERY_DOCS = [5, 60, 120, 200, 250]


@pytest.mark.parametrize("doc", QUERY_DOCS)
def test_lng_equals_subsequence_dtw_where_the_dtw_path_lies_in_the_neighbourhoods(X, starts, index, doc):
    """§4.1: "The paths found by our method are equal to the paths found by subsequence DTW under the condition
    that all frames assigned to each other by subsequence DTW are in the neighbourhood". Checked match by match:
    where the condition holds, same cost (up to the last bit of the summation order) and same path; everywhere,
    the graph's cost is no lower than DTW's at the same end frame. The paper's graph and DTW: any match length."""
    stop = starts[doc + 1]
    q = X[starts[doc] + 5 : starts[doc] + 35]
    d, f = neighbourhoods(q, index, k=2048, exclude=[starts[doc], stop])
    out = graph_matches(d, f, starts, len(X), n_matches=10, min_length=None)
    cost, first = subsequence_costs(q, X, starts)
    assert len(out) == 10
    checked = 0
    for row in out.itertuples():
        assert row.cost >= cost[row.end] * (1 - 1e-12)
        _, dtw_path = dtw(q, X[first[row.end] : row.end + 1])
        dtw_path += [0, first[row.end]]
        inside = all(fr in set(f[i]) for i, fr in dtw_path)
        if inside:
            checked += 1
            assert row.cost == pytest.approx(cost[row.end], rel=1e-12)
            assert np.array_equal(row.path, dtw_path)
        assert not (starts[doc] <= row.start < stop)
    assert checked >= 5, "too few matches met the condition to test anything"


def test_lng_finds_the_best_dtw_matches_whose_paths_lie_in_the_neighbourhoods(X, starts, index):
    """Of subsequence DTW's best 10 matches outside the query's document, each whose path lies in the
    neighbourhoods (2048 per frame) is among the graph's best 20, with the same cost."""
    checked = 0
    for doc in QUERY_DOCS:
        stop = starts[doc + 1]
        q = X[starts[doc] + 5 : starts[doc] + 35]
        d, f = neighbourhoods(q, index, k=2048, exclude=[starts[doc], stop])
        found = graph_matches(d, f, starts, len(X), n_matches=20, paths=False)
        best = subsequence_dtw(q, X, starts, n_matches=40)  # matches never span documents: filter the own one
        best = best[(best["end"] < starts[doc]) | (best["start"] >= stop)].head(10)
        cost_at = dict(zip(found["end"], found["cost"]))
        inside = [all(fr in set(f[i]) for i, fr in row.path) for row in best.itertuples()]
        for row in best[inside].itertuples():
            assert cost_at.get(row.end) == pytest.approx(row.cost, rel=1e-12)
        checked += sum(inside)
    assert checked >= 10, "too few matches met the condition to test anything"


def test_lng_paths_are_valid_steps_inside_one_document(X, starts, index):
    lengths = np.diff(np.r_[starts, len(X)])
    doc = 77 + int(np.argmax(lengths[77:] >= 100))
    q = X[starts[doc] + 2 : starts[doc] + 62]
    out = lng(q, index, k=128, radius=60.0, n_matches=20, starts=starts)
    assert len(out) > 1 and set(out.attrs["seconds"]) == {"knn", "graph"}
    doc_of = np.searchsorted(starts, np.arange(len(X)), side="right") - 1
    for row in out.itertuples():
        p = row.path
        assert tuple(p[0]) == (0, row.start) and tuple(p[-1]) == (len(q) - 1, row.end)
        assert {tuple(s) for s in np.diff(p, axis=0)} <= {(1, 1), (1, 0), (0, 1)}
        assert (doc_of[p[:, 1]] == row.doc_id).all()
        assert path_cost(euclidean(q, X), p, STEP_SETS["basic"]) == pytest.approx(row.cost, rel=1e-9)
        # every node of the path is a neighbour of its query frame within the radius
        assert (np.linalg.norm(q[p[:, 0]].astype(np.float64) - X[p[:, 1]], axis=1) < 60.0).all()


def test_lng_with_the_brute_force_engine_gives_the_same_matches(X, starts, index):
    q = X[starts[150] : starts[150] + 30]
    brute = KnnIndex(X, engine="brute")
    a = lng(q, index, k=256, starts=starts)
    b = lng(q, brute, k=256, starts=starts)
    assert a[["start", "end"]].equals(b[["start", "end"]])
    np.testing.assert_allclose(a["cost"], b["cost"], rtol=1e-9)


def test_bad_input_raises_clear_errors(X, starts, index):
    q = X[:30]
    with pytest.raises(ValueError, match="at least 2 frames"):
        lng(X[:1], index, k=16)
    with pytest.raises(ValueError, match="k must be between 1"):
        lng(q, index, k=0)
    with pytest.raises(ValueError, match="k must be between 1"):
        lng(q, index, k=len(X) + 1)
    with pytest.raises(ValueError, match="radius must be a positive"):
        lng(q, index, k=16, radius=-1)
    with pytest.raises(ValueError, match="10 dimensions per frame but the index has 15"):
        lng(q[:, :10], index, k=16)
    with pytest.raises(ValueError, match="frame 3 is not finite"):
        bad = q.copy()
        bad[3, 2] = np.nan
        subsequence_dtw(bad, X, starts)
    with pytest.raises(ValueError, match="has 10 dimensions"):
        subsequence_dtw(q, X[:, :10], starts)
    with pytest.raises(ValueError, match="unknown step set"):
        dtw(q, q, steps="fast")
    with pytest.raises(ValueError, match="document starts"):
        subsequence_costs(q, X, starts[::-1])
    with pytest.raises(ValueError, match="band row 0 is empty"):
        dtw(q, q, band=np.tile([40, 50], (30, 1)))
    with pytest.raises(ValueError, match="longer than the longest document|more than the longest document"):
        lng(X[:5000], index, k=16, starts=starts)
    with pytest.raises(ValueError, match="more than the longest document"):
        subsequence_dtw(X[:5000], X, starts)
    with pytest.raises(ParameterError, match="n_matches must be an integer"):
        subsequence_dtw(q, X, starts, n_matches=2.5)


def test_matches_are_at_least_min_length_of_the_query_long(sample_db):
    """The lazy neighbourhood graph and subsequence DTW keep only matches at least ``min_length`` × the query long
    (default half, the similarity search's rule): on the sample, kick 7 as a whole (129 frames) found 1-frame and
    12-frame "matches" without it. Subsequence DTW with the rule equals the similarity search's brute-force
    stretches (another implementation: mocapviz.match.pruned)."""
    from mocapviz.similarity.search import SimilaritySearch

    X = numeric_features(sample_db, "F15E")
    starts = sample_db.documents["start"].to_numpy()
    own = sample_db.frames(7)
    q = X[own]
    shortest = int(np.ceil(0.5 * len(q)))
    assert (len(q), shortest) == (129, 65)
    index = KnnIndex(X)
    options = {"k": 1024, "n_matches": 10, "starts": starts, "exclude": (own.start, own.stop), "paths": False}
    free = lng(q, index, min_length=None, **options)
    assert (free["end"] - free["start"] + 1).min() < shortest  # what the graph returns without the rule
    kept = lng(q, index, **options)
    assert len(kept) >= 1 and (kept["end"] - kept["start"] + 1 >= shortest).all()
    long_free = free[free["end"] - free["start"] + 1 >= shortest]
    assert kept["cost"].iloc[0] <= long_free["cost"].min()  # the best long match is not lost
    longer = lng(q, index, min_length=0.8, **options)
    assert (longer["end"] - longer["start"] + 1 >= 104).all()

    part = X[own.start : own.start + 60]
    dtw_kept = subsequence_dtw(part, X, starts, n_matches=8, paths=False)
    assert (dtw_kept["end"] - dtw_kept["start"] + 1 >= 30).all()
    ref = SimilaritySearch(sample_db, "F15E").stretches(7, frames=(0, 60), n_matches=8, mode="brute")
    doc_start = starts[dtw_kept["doc_id"]]
    assert list(zip(dtw_kept["doc_id"], dtw_kept["start"] - doc_start, dtw_kept["end"] + 1 - doc_start)) == list(
        zip(ref["doc_id"], ref["start"], ref["end"]))
    np.testing.assert_allclose(dtw_kept["cost"], ref["cost"], rtol=1e-9)
    for bad in (0, 1.5, float("nan")):
        with pytest.raises(ParameterError, match=r"min_length .* must be a number in \(0, 1\]"):
            lng(q, index, min_length=bad, **options)
        with pytest.raises(ParameterError, match="min_length"):
            subsequence_dtw(part, X, starts, min_length=bad)
