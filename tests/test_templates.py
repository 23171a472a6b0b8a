"""mocapviz.relational.templates: warping and averaging against a hand-worked example, order independence, quantisation and
the masked matching cost."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapviz import ParameterError
from mocapviz.match import subsequence_dtw
from mocapviz.relational.templates import (
    DELTA_RANGE,
    DONT_CARE,
    classify,
    find_instances,
    learn_template,
    quantised_distance,
    shortest_instance,
    template_distance,
)

# two features; A and B agree everywhere (B holds its middle pose twice), C raises feature 2 throughout
A = np.array([[0, 0], [1, 0], [1, 1]], bool)
B = np.array([[0, 0], [1, 0], [1, 0], [1, 1]], bool)
C = np.array([[0, 1], [1, 1], [1, 1]], bool)


def test_warping_and_averaging_equals_the_hand_worked_example():
    """By hand: DTW costs (mean |difference| per cell) A–B 0, A–C 1, B–C 1.5, so the medoid is A. Aligned to A, B's
    two middle frames both go to A's middle column and C aligns diagonally; the averages are
    [0, 1/3], [1, 1/3], [1, 1]. Aligning to that template changes no path, so the second round settles."""
    t = learn_template([A, B, C], ["f1", "f2"], label="abc")
    np.testing.assert_allclose(t.values, [[0, 1 / 3], [1, 1 / 3], [1, 1]])
    assert (t.n_examples, t.iterations, t.label) == (3, 2, "abc")
    np.testing.assert_array_equal(t.quantised(0.1), [[0, DONT_CARE], [1, DONT_CARE], [1, 1]])
    np.testing.assert_array_equal(t.quantised(0.4), [[0, 0], [1, 0], [1, 1]])  # 1/3 < 0.4


@pytest.mark.parametrize("order", list(itertools.permutations(range(3))))
def test_the_template_does_not_depend_on_the_order_of_the_examples(order):
    examples = [A, B, C]
    t = learn_template([examples[i] for i in order], ["f1", "f2"])
    np.testing.assert_allclose(t.values, [[0, 1 / 3], [1, 1 / 3], [1, 1]])


def test_one_example_is_its_own_template():
    t = learn_template([B], ["f1", "f2"])
    np.testing.assert_array_equal(t.values, B.astype(float))


def test_template_distance_is_the_brute_force_masked_mean():
    rng = np.random.default_rng(0)
    a, x = rng.random((5, 7)), rng.random((9, 7)) < 0.5
    mask = rng.random((5, 7)) < 0.6
    mask[0] = False  # a row that cares about nothing costs 0
    ref = np.array([[np.abs(a[i] - x[j])[mask[i]].mean() if mask[i].any() else 0.0 for j in range(9)]
                    for i in range(5)])  # fmt: skip
    np.testing.assert_allclose(template_distance(a, x, mask), ref)
    q = np.where(mask, np.round(a), DONT_CARE)
    np.testing.assert_allclose(quantised_distance(q, x), template_distance(q, x, mask))


def test_a_quantised_template_finds_its_class_and_ignores_dont_care_features():
    """A database of the three examples plus a clip that moves feature 1 the other way: the template's hits are
    A, B and C at cost 0 (feature 2 is don't care), the other clip is far."""
    other = np.array([[1, 0], [0, 0], [0, 0]], bool)
    db = np.concatenate([other, A, B, C])
    starts = np.array([0, 3, 6, 10])
    t = learn_template([A, B, C], ["f1", "f2"])
    hits = subsequence_dtw(t.quantised(), db, starts, n_matches=4, distance=quantised_distance, paths=False)
    assert sorted(hits["doc_id"][:3]) == [1, 2, 3] and (hits["cost"][:3] == 0).all()
    assert (hits.loc[hits["doc_id"] == 0, "cost"] > 0).all()


def test_delta_zero_is_refused_for_it_would_make_every_entry_dont_care():
    """At δ = 0 no average is below 0 or above 1: the whole template would be don't care and every stretch of the
    database a perfect match at cost 0. Refused by the library's range (the dashboard's box takes its bounds)."""
    t = learn_template([A, B, C], ["f1", "f2"])
    tiny = t.quantised(1e-9)  # the smallest δ still cares for the entries every example agrees on
    np.testing.assert_array_equal(tiny, [[0, DONT_CARE], [1, DONT_CARE], [1, 1]])
    db, starts = np.concatenate([A[::-1], A]), np.array([0, 3])
    assert find_instances(t, db, starts, n_matches=2, delta=1e-9)["normalised_cost"].max() > 0
    for delta in (0, 0.0, -0.1, 0.5, float("nan")):
        with pytest.raises(ParameterError, match=r"delta must be a number in \(0, 0.5\)"):
            t.quantised(delta)
        with pytest.raises(ParameterError, match="delta"):
            find_instances(t, db, starts, delta=delta)
    assert (DELTA_RANGE.low, DELTA_RANGE.low_open, DELTA_RANGE.high, DELTA_RANGE.high_open) == (0, True, 0.5, True)


@pytest.mark.parametrize(("examples", "message"), [
    ([], "at least one example"),
    ([np.zeros((3, 3), bool)], r"shape \(3, 3\)"),
    ([np.full((3, 2), 0.5)], "other than 0/1"),
])  # fmt: skip
def test_bad_examples_are_named(examples, message):
    with pytest.raises(ParameterError, match=message):
        learn_template(examples, ["f1", "f2"])


def test_find_instances_normalises_and_thresholds_by_template_frames():
    other = np.array([[1, 0], [0, 0], [0, 0]], bool)
    db = np.concatenate([other, A, B, C])
    starts = np.array([0, 3, 6, 10])
    t = learn_template([A, B, C], ["f1", "f2"])
    every = find_instances(t, db, starts, n_matches=10)
    np.testing.assert_allclose(every["normalised_cost"], every["cost"] / 3)
    kept = find_instances(t, db, starts, n_matches=10, max_cost=0.0)
    assert sorted(kept["doc_id"]) == [1, 2, 3]
    lengths = np.diff(np.r_[starts, len(db)])  # each example is matched whole: frames within it, half-open
    assert (kept["start"] >= 0).all() and (kept["start"] < kept["end"]).all()
    assert (kept["end"] <= lengths[kept["doc_id"]]).all() and kept.set_index("doc_id").loc[1, "end"] == 3
    with pytest.raises(ParameterError, match=r"needs \(frames, 2\)"):
        find_instances(t, db[:, :1], starts)


def test_classify_ranks_the_nearest_template_first():
    ups = learn_template([A, B], ["f1", "f2"], label="up")
    downs = learn_template([A[::-1], B[::-1]], ["f1", "f2"], label="down")
    ranked = classify(C, [downs, ups])
    assert ranked["label"].tolist() == ["up", "down"] and ranked["cost"].is_monotonic_increasing


def test_a_template_longer_than_an_instance_finds_it_down_to_half_the_fastest_example():
    """The medoid of slow examples can be longer than a quicker instance; the warping absorbs it, down to half the
    fastest example's frames (shortest_instance); a still shorter stretch is no instance unless min_frames allows."""
    slow = np.repeat(A, 4, axis=0)  # 12 frames
    half = np.repeat(A, 2, axis=0)  # 6 frames: twice as fast
    t = learn_template([slow, slow], ["f1", "f2"])
    assert shortest_instance(t) == 6
    hits = find_instances(t, np.concatenate([half, C]), np.array([0, 6]), n_matches=2)
    assert hits["doc_id"].tolist()[0] == 0 and hits["cost"].iloc[0] == 0
    assert find_instances(t, np.concatenate([A, C]), np.array([0, 3]), n_matches=2).empty  # 3 frames: too short
    hits = find_instances(t, np.concatenate([A, C]), np.array([0, 3]), n_matches=2, min_frames=1)
    assert hits["doc_id"].tolist()[0] == 0 and hits["cost"].iloc[0] == 0


def test_bounded_rows_is_plain_subsequence_dtw_when_unbounded_and_stops_pile_ups():
    """The row-bounded subsequence DTW (every aligned cell pays) equals the basic step set's costs when the bound
    is the template's length, over several documents; bounded, a template cannot squeeze onto a short stretch."""
    from mocapviz.match import subsequence_costs
    from mocapviz.relational.templates import _bounded_costs

    rng = np.random.default_rng(1)
    q = np.where(rng.random((9, 6)) < 0.3, DONT_CARE, rng.random((9, 6)) < 0.5).astype(float)
    x = rng.random((80, 6)) < 0.5
    starts = np.array([0, 17, 40, 41, 60])
    want, _ = subsequence_costs(q, x, starts, distance=quantised_distance)
    got, first = _bounded_costs(q, x, starts, len(q))
    np.testing.assert_allclose(got, want)
    doc = np.searchsorted(starts, np.arange(80), side="right") - 1
    ok = np.isfinite(got)
    assert (doc[first[ok]] == doc[ok]).all()  # no match crosses a document start
    bounded, first = _bounded_costs(q, x, starts, 3)
    assert (bounded[ok] >= got[ok] - 1e-12).all()
    assert (np.arange(80) - first + 1 >= 3)[np.isfinite(bounded)].all()  # 9 rows, at most 3 per frame
    # a slow template (each phase 4 rows) against a stretch holding each phase for one frame
    slow = learn_template([np.repeat(A, 4, axis=0)] * 2, ["f1", "f2"])
    assert find_instances(slow, A, None, min_frames=1).iloc[0]["cost"] == 0  # 4 rows per frame: allowed
    assert find_instances(slow, A, None, min_frames=1, max_rows=2).empty  # 12 rows on 3 frames: not


@pytest.mark.parametrize("n_features", [1, 39, 64, 65, 130])
def test_bit_rows_set_bit_c_of_word_c_over_64_block_by_block(n_features):
    """Packed rows against a bit-by-bit reference, with blocks that do not divide the rows, bool or numbers."""
    from mocapviz.relational.templates import _bit_rows

    x = np.random.default_rng(n_features).random((1000, n_features)) < 0.5
    want = np.zeros((1000, -(-n_features // 64)), dtype=np.uint64)
    for c in range(n_features):
        want[:, c // 64] |= x[:, c].astype(np.uint64) << np.uint64(c % 64)
    np.testing.assert_array_equal(_bit_rows(x, block=97), want)
    np.testing.assert_array_equal(_bit_rows(x.astype(np.float32)), want)


@pytest.mark.parametrize("n_features", [1, 63, 64, 65, 130])
def test_bounded_costs_count_mismatches_over_any_number_of_feature_words(n_features):
    """The packed 64-bit words of the row-bounded DTW give the masked mean of :func:`quantised_distance` at any
    width (one word, exactly one, one and a bit, three), rows caring for nothing included, and threads split the
    documents without changing a cost: the unbounded costs equal the basic step set's (the paths' starts may differ
    between equal-cost paths)."""
    from mocapviz.match import subsequence_costs
    from mocapviz.relational.templates import _bounded_costs

    rng = np.random.default_rng(n_features)
    q = np.where(rng.random((7, n_features)) < 0.3, DONT_CARE, rng.random((7, n_features)) < 0.5).astype(float)
    q[3] = DONT_CARE  # a row that cares for no feature costs 0 everywhere
    x = rng.random((300, n_features)) < 0.5
    starts = np.r_[0, np.sort(rng.choice(np.arange(1, 300), 40, replace=False))]
    want, _ = subsequence_costs(q, x, starts, distance=quantised_distance)
    got, first = _bounded_costs(q, x, starts, len(q))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    doc = np.searchsorted(starts, np.arange(len(x)), side="right") - 1
    ok = np.isfinite(want)
    assert (doc[first[ok]] == doc[ok]).all() and (first[ok] <= np.arange(len(x))[ok]).all()
    assert (first[~ok] == -1).all()
    # documents shorter than `least` frames are left out (inf, -1), the others' costs unchanged
    least = 8
    skipped, skipped_first = _bounded_costs(q, x, starts, 3, least)
    all_docs, all_first = _bounded_costs(q, x, starts, 3)
    short = np.diff(np.r_[starts, len(x)])[doc] < least
    assert short.any() and (~short).any()
    assert np.isinf(skipped[short]).all() and (skipped_first[short] == -1).all()
    np.testing.assert_array_equal(skipped[~short], all_docs[~short])
    np.testing.assert_array_equal(skipped_first[~short], all_first[~short])


def _exact_bounded(q, x, starts, max_rows):
    """The row-bounded DTW of :func:`_bounded_costs` in exact arithmetic (fractions), cell by cell as its docstring
    states it: a cell (i, j) ends a run of r <= max_rows rows on frame j, entered from frame j - 1 at row i - r
    (diagonal) or i - r + 1 (held; it wins ties), or started at row 0; of equal costs the shortest run wins."""
    from fractions import Fraction

    care = q != DONT_CARE
    cost, first = [None] * len(x), np.full(len(x), -1)
    for a, b in zip(starts, [*starts[1:], len(x)]):
        prev = None
        for j in range(a, b):
            local = [Fraction(int(((x[j] != (q[i] == 1)) & care[i]).sum()), int(care[i].sum())) if care[i].any()
                     else Fraction(0) for i in range(len(q))]  # fmt: skip
            enter = [(Fraction(0), j)] + [None] * (len(q) - 1)
            for r0 in range(1, len(q)):
                if prev is not None:
                    diagonal, held = prev[r0 - 1], prev[r0]
                    better = diagonal is not None and (held is None or diagonal[0] < held[0])
                    enter[r0] = diagonal if better else held
            acc = []
            for i in range(len(q)):
                best, run = None, Fraction(0)
                for r0 in range(i, max(-1, i - max_rows), -1):
                    run += local[r0]
                    if enter[r0] is not None and (best is None or enter[r0][0] + run < best[0]):
                        best = (enter[r0][0] + run, enter[r0][1])
                acc.append(best)
            prev = acc
            cost[j] = acc[-1]
            first[j] = -1 if acc[-1] is None else acc[-1][1]
    return np.array([np.inf if c is None else float(c[0]) for c in cost]), first


def test_row_bounded_costs_and_path_starts_equal_exact_arithmetic_on_real_frames():
    """The O(m) sliding-window kernel against the cell-by-cell recursion in fractions, on the relational features of
    two real clips of the sample (HDM05 at 120 Hz) and a template learned from the sample's hops: equal costs and the
    same path start at every frame, ties included (the frames' features repeat, so equal-cost paths abound; the
    previous kernel, summing each run anew in floating point, picked another start at 32 of these 180 frames)."""
    from mocapviz import MotionDB
    from mocapviz.features import relational_features
    from mocapviz.relational.templates import _bounded_costs, learn_class, steepest_rows

    db = MotionDB.sample()
    values, _ = relational_features(db, "2006", progress=False)
    template = learn_class(db, "hopBothLegs1hops", relational_set="2006", values=values)
    q = template.quantised(0.1)
    docs = db.documents.set_index("doc_id")
    pieces = [values[docs.loc[d, "start"] : docs.loc[d, "start"] + 90] for d in (template.meta["doc_ids"][0], 0)]
    x, starts = np.concatenate(pieces), np.array([0, len(pieces[0])])
    for max_rows in (steepest_rows(template), 5):
        want, want_first = _exact_bounded(q, x, starts, max_rows)
        got, first = _bounded_costs(q, x, starts, max_rows)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(first, want_first)


def test_a_match_starts_at_the_latest_frame_its_cost_allows_in_exact_arithmetic_on_real_frames():
    """Matches begin where the template begins, not in the rest pose before it: on two real clips of the sample (a
    hop of the template's own and a clip of another class), every match found keeps its cost, an alignment of the
    whole template from its start to its end costs exactly that (the fractions' recursion on those frames alone),
    and from one frame later it costs more or spans fewer frames than the shortest instance. The start never moves
    earlier than subsequence DTW's, and on these frames it moves later for some match (the test would pass
    vacuously otherwise)."""
    from mocapviz import MotionDB
    from mocapviz.features import relational_features
    from mocapviz.relational.templates import _costs, find_instances, learn_class, shortest_instance, steepest_rows

    db = MotionDB.sample()
    values, _ = relational_features(db, "2006", progress=False)
    template = learn_class(db, "hopBothLegs1hops", relational_set="2006", values=values)
    q, least, rows = template.quantised(0.1), shortest_instance(template), steepest_rows(template)
    docs = db.documents.set_index("doc_id")
    pieces = [values[docs.loc[d, "start"] : docs.loc[d, "start"] + 150] for d in (template.meta["doc_ids"][1], 3)]
    x, starts = np.concatenate(pieces), np.array([0, len(pieces[0])])
    hits = find_instances(template, x, starts, n_matches=6)
    _, free_first = _costs(template, q, x, starts, None)
    assert len(hits) >= 3

    def exact(a, e):  # least cost of a whole alignment in frames a..e ending at e, inf below the shortest instance
        cost, first = _exact_bounded(q, x[a : e + 1], np.array([0]), rows)
        return cost[-1] if e - (a + first[-1]) + 1 >= least else np.inf

    moved = 0
    first = starts[hits["doc_id"].to_numpy()]  # the hits' frames of x, last included (theirs: in-document, half-open)
    for start, end, cost in zip(hits["start"] + first, hits["end"] - 1 + first, hits["cost"]):
        assert free_first[end] <= start <= end - least + 1
        assert exact(start, end) == pytest.approx(cost, abs=1e-9)
        if start < end - least + 1:
            assert exact(start + 1, end) > cost + 1e-9
        moved += start > free_first[end]
    assert moved >= 1


def test_learned_threshold_is_the_best_f1_cut_between_the_class_and_the_other_clips(hdm05_db30):
    """learn_class's threshold on real clips (HDM05 at 30 Hz, the kick template of four actors): against a brute
    force over every cut at an example's cost, the F1 of "cost <= threshold" (examples judged as unseen, the four
    actors' clips of the other classes as impostors) is the best any cut reaches, and the threshold lies halfway
    between that cut and the nearest impostor above it. Measured: 0.042 where the examples' worst cost is 0.074."""
    from mocapviz.features import relational_features
    from mocapviz.relational.templates import document_costs, learn_class

    db = hdm05_db30
    values, _ = relational_features(db, "2006", progress=False)
    actors = ["bd", "bk", "dg", "mm"]
    t = learn_class(db, "kickLFront1Reps", actors, "2006", values)
    docs = db.documents
    others = ((docs["label"] != "kickLFront1Reps") & docs["actor"].isin(actors)).to_numpy()
    neg = document_costs(t, values, docs["start"].to_numpy())[others]
    neg = neg[np.isfinite(neg)]  # clips shorter than the shortest instance hold no match
    pos = np.asarray(t.meta["unseen_costs"])
    assert t.meta["negatives"] == len(neg) > 200 and t.meta["nearest_negative"] == pytest.approx(neg.min())

    def f1(cut):
        tp, fp = (pos <= cut).sum(), (neg <= cut).sum()
        return 2 * tp / (2 * tp + fp + (len(pos) - tp))

    best = max(f1(c) for c in pos)
    cut = min(c for c in pos if f1(c) == best)
    threshold = t.meta["threshold"]
    assert f1(threshold) == pytest.approx(best)
    assert threshold == pytest.approx((cut + neg[neg > cut].min()) / 2)
    assert threshold < t.meta["example_threshold"] == pytest.approx(max(t.meta["unseen_costs"] + t.meta["example_costs"]))


def test_a_feature_one_group_does_otherwise_is_dont_care_when_learned_by_group():
    """Four 'actors' of two examples each: seven examples never raise feature 2 while feature 1 rises, one of actor
    d raises it in the middle. Pooled, feature 2's middle is 1/8 < δ = 0.2: cared for (0). By group, actor d's mean
    is 1/2 and a share 1/4 >= δ of the groups disagree: don't care. Feature 1 is kept either way."""
    plain = np.array([[0, 0], [1, 0], [1, 0], [0, 0]], bool)
    other = np.array([[0, 0], [1, 1], [1, 1], [0, 0]], bool)
    examples = [plain] * 7 + [other]
    groups = ["a", "a", "b", "b", "c", "c", "d", "d"]
    t = learn_template(examples, ["f1", "f2"], groups=groups)
    assert t.meta["groups"] == ["a", "b", "c", "d"] and t.group_values.shape == (4, 4, 2)
    np.testing.assert_allclose(t.group_values.mean(axis=0), t.values)  # equal group sizes: the pooled mean
    assert t.quantised(0.2, by_group=False)[1, 1] == 0.0
    assert t.quantised(0.2)[1, 1] == DONT_CARE
    np.testing.assert_array_equal(t.quantised(0.2)[:, 0], [0, 1, 1, 0])  # feature 1: every group agrees
    assert learn_template(examples, ["f1", "f2"]).group_values is None
    with pytest.raises(ParameterError, match="one group per example"):
        learn_template(examples, ["f1", "f2"], groups=groups[:-1])


def test_group_values_survive_save_and_load_and_are_checked(tmp_path):
    from mocapviz import MotionDBError
    from mocapviz.relational.templates import MotionTemplate

    t = learn_template([A, B, C], ["f1", "f2"], groups=["x", "y", "y"])
    t.save(tmp_path / "t.npz")
    back = MotionTemplate.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(back.group_values, t.group_values)
    np.testing.assert_array_equal(back.quantised(0.2), t.quantised(0.2))
    with np.load(tmp_path / "t.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["group_values"] = arrays["group_values"] * 0.5
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(MotionDBError, match="bad.npz: its arrays differ from those written"):
        MotionTemplate.load(tmp_path / "bad.npz")


def test_learn_class_from_at_most_some_examples_spread_over_the_class(hdm05_db30):
    """``max_examples``: the class's documents at evenly spread positions, first and last included; the template
    is the one learned from those documents alone (by actor, as learn_class groups them)."""
    from mocapviz.features import relational_features
    from mocapviz.relational.templates import learn_class

    db, label = hdm05_db30, "kickLFront1Reps"
    values, names = relational_features(db, "2006", progress=False)
    docs = db.documents[db.documents["label"] == label]
    n = len(docs)
    assert n > 5
    template = learn_class(db, label, values=values, max_examples=5)
    picked = [int(docs["doc_id"].iloc[round(i * (n - 1) / 4)]) for i in range(5)]
    assert template.meta["doc_ids"] == picked and template.n_examples == 5 and template.meta["class_documents"] == n
    rows = docs.set_index("doc_id").loc[picked]
    alone = learn_template([values[s : s + f] for s, f in zip(rows["start"], rows["n_frames"])], names, label,
                           groups=rows["actor"].tolist())  # fmt: skip
    np.testing.assert_array_equal(template.values, alone.values)
    every = learn_class(db, label, values=values, max_examples=n)  # as many as the class has: all of them
    assert every.meta["doc_ids"] == docs["doc_id"].tolist() and every.meta["class_documents"] == n
    with pytest.raises(ParameterError, match="max_examples"):
        learn_class(db, label, values=values, max_examples=0)


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_the_medoids_pair_costs_are_dtws_exactly(data):
    """The medoid's pair costs (one numba pass over bit-packed frames, issue 43) equal mocapviz.match.dtw's with
    template_distance over the two lengths, bit for bit, on random boolean examples of 1 to 70 features; so the
    medoid, and the learned template, are those of the pair-by-pair loop."""
    from mocapviz.match import dtw
    from mocapviz.relational.templates import _bit_rows, _pair_costs

    f = data.draw(st.integers(1, 70), label="features")
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    xs = [rng.random((int(rng.integers(1, 30)), f)) < rng.random() for _ in range(int(rng.integers(1, 7)))]
    n = len(xs)
    want = np.zeros((n, n))
    for i, j in itertools.combinations(range(n), 2):
        want[i, j] = dtw(xs[i].astype(np.float64), xs[j], distance=template_distance)[0] / (len(xs[i]) + len(xs[j]))
    got = np.zeros((n, n))
    bounds = np.r_[0, np.cumsum([len(x) for x in xs])].astype(np.int64)
    _pair_costs(_bit_rows(np.concatenate(xs)), bounds, float(f), np.arange(n), got)
    np.testing.assert_array_equal(got, want)


def test_learning_by_the_mismatch_loop_gives_the_templates_of_the_matrix_products(monkeypatch):
    """Learning aligns each example to its reference by _mean_mismatch (a numba loop, issue 43) instead of
    template_distance's three matrix products: equal within 1e-15 on random values, and every class of the demo
    database (at most 8 examples each) learns the same template, group means and meta either way."""
    from mocapviz import MotionDB
    from mocapviz.features import relational_features
    from mocapviz.relational import templates

    rng = np.random.default_rng(4)
    a, x = rng.random((30, 39)), rng.random((25, 39)) < 0.5
    np.testing.assert_allclose(templates._mean_mismatch(a, x), template_distance(a, x), rtol=0, atol=1e-15)
    db = MotionDB.demo()
    values, _ = relational_features(db, "2006", progress=False)
    for label in sorted(db.documents["label"].dropna().unique()):
        loop = templates.learn_class(db, label, values=values, max_examples=8)
        with monkeypatch.context() as m:
            m.setattr(templates, "_mean_mismatch", template_distance)
            products = templates.learn_class(db, label, values=values, max_examples=8)
        np.testing.assert_array_equal(loop.values, products.values)
        np.testing.assert_array_equal(loop.group_values, products.group_values)
        assert loop.meta == products.meta
