"""Query by example over a MotionDB's relational indexes, checked against a direct scan of the features."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB, MotionDBError
from mocapviz.cli import main
from mocapviz.errors import ParameterError
from mocapviz.features import feature_groups, relational_features
from mocapviz.features.segmentation import segment
from mocapviz.relational.index import build, load
from mocapviz.relational.query import query_by_example, query_segmentation
from mocapviz.validation import plural

KICK = ["rfoot_raised", "lfoot_raised", "rknee_bent", "lknee_bent"]  # Fig. 9 of the paper (DEFAULT_QUERIES)


@pytest.fixture(scope="module")
def db(sample_db):
    """The embedded sample (22 HDM05 clips, 2 CMU trials) at 120 Hz with its 2005 indexes."""
    build(sample_db, progress=False)
    return sample_db


@pytest.fixture(scope="module")
def db_values(db):
    return relational_features(db, progress=False)


@pytest.fixture(scope="module")
def hdm(hdm05_db30):
    """The 287 HDM05 clips at 30 Hz with their 2005 indexes, and their relational features (values, names)."""
    build(hdm05_db30, progress=False)
    return hdm05_db30, relational_features(hdm05_db30, progress=False)


def scan_hits(db, values, names, example, chosen, m: int = 0, allowed=None) -> set:
    """Brute force: segment every document by the chosen features alone, and find the example's sequence
    of chosen-feature vectors as consecutive runs (the restricted feature function of §5.2), at most ``m`` runs
    differing, only at the ``allowed`` query positions (default: any)."""
    cols = [names.index(f) for f in chosen]
    ex_values, _ = relational_features(example)
    q = segment(ex_values[:, cols]).codes
    free = np.zeros(len(q), dtype=bool)
    free[list(range(len(q))) if allowed is None else allowed] = True
    hits = set()
    for row in db.documents.itertuples():
        seq = segment(values[row.start : row.start + row.n_frames, cols])
        for k in range(len(seq.codes) - len(q) + 1):
            differ = seq.codes[k : k + len(q)] != q
            if differ.sum() <= m and not (differ & ~free).any():
                last = k + len(q) - 1
                hits.add((row.doc_id, int(seq.starts[k]), int(seq.starts[last] + seq.lengths[last])))  # half-open end
    return hits


@pytest.mark.parametrize(
    "label, chosen",
    [
        ("squat1Reps", ["rknee_bent", "lknee_bent", "rfoot_fast", "lfoot_fast"]),
        ("kickLFront1Reps", ["lfoot_raised", "rfoot_raised", "lknee_bent"]),
        ("rotateArmsBothBackward1Reps", ["rhand_above_neck", "lhand_above_neck"]),
    ],
)
def test_adaptive_query_equals_the_restricted_scan(db, db_values, label, chosen):
    values, names = db_values
    missing = [c for c in chosen if c not in names]
    assert not missing, f"feature names changed: {missing}"
    doc = db.select(label=label)["doc_id"].iloc[0]
    example = db.motion(doc)
    hits = query_by_example(db, example, chosen)
    got = set(zip(hits["doc_id"], hits["start"], hits["end"]))
    assert got == scan_hits(db, values, names, example, chosen)
    # the query document itself is found over its whole length, with a perfect temporal score
    own = hits[(hits["doc_id"] == doc) & (hits["start"] == 0)]
    assert len(own) == 1 and own["end"].iloc[0] == example.n_frames
    assert own["score"].iloc[0] == 0.0 and own["rank"].iloc[0] == 1 or hits["score"].iloc[0] == 0.0
    assert (np.diff(hits["score"]) >= 0).all() and hits["rank"].tolist() == list(range(1, len(hits) + 1))


def spans(hits) -> set:
    return set(zip(hits["doc_id"], hits["start"], hits["end"]))


@pytest.mark.parametrize(
    "label, chosen, mode, m, allowed",
    [
        ("kickLFront1Reps", ["rfoot_raised"], "exact", 0, None),
        ("kickLFront1Reps", KICK, "exact", 0, None),
        ("kickLFront1Reps", KICK, "mismatch", 0, None),
        ("kickLFront1Reps", KICK, "mismatch", 1, None),
        ("kickLFront1Reps", KICK, "mismatch", 2, None),
        ("kickLFront1Reps", KICK, "mismatch", 2, [0, 3]),
        ("kickLFront1Reps", KICK, "mismatch", 1, []),
        ("throwBasketball", ["rhand_above_neck", "lhand_above_neck"], "mismatch", 1, None),
        ("squat1Reps", ["rknee_bent", "rfoot_fast", "lfoot_fast"], "mismatch", 2, None),
        ("grabHighR", ["rhand_above_neck", "rhand_in_front"], "exact", 0, None),
        ("grabHighR", ["rhand_above_neck", "rhand_in_front"], "mismatch", 1, [1]),
    ],
)
def test_exact_and_mismatch_count_only_the_selected_features(hdm, label, chosen, mode, m, allowed):
    """Exact and m-mismatch hits over the 287 HDM05 clips = the runs of the selected features found by a scan of
    the per-frame feature matrix; left-out features are don't care."""
    db, (values, names) = hdm
    for doc in db.select(label=label)["doc_id"].iloc[:3]:
        example = db.motion(int(doc))
        hits = query_by_example(db, example, chosen, mode=mode, mismatches=m, allowed=allowed)
        expected = scan_hits(db, values, names, example, chosen, m, allowed)
        assert spans(hits) == expected and len(hits) == len(expected)
        assert ((hits["doc_id"] == doc) & (hits["start"] == 0)).any()  # the query finds itself
        n_runs = len(segment(relational_features(example)[0][:, [names.index(f) for f in chosen]]).codes)
        assert (hits["n_segments"] == n_runs).all()  # the query is segmented on the selected features alone
        if mode == "exact":  # the selection's exact hits are its adaptive fuzzy hits (§5.2)
            assert spans(query_by_example(db, example, chosen, mode="adaptive")) == expected


def test_each_allowed_mismatch_only_adds_hits(hdm):
    db, _ = hdm
    example = db.motion(int(db.select(label="kickLFront1Reps")["doc_id"].iloc[0]))
    by_m = [spans(query_by_example(db, example, KICK, mode="mismatch", mismatches=m)) for m in range(3)]
    assert by_m[0] == spans(query_by_example(db, example, KICK, mode="exact"))
    assert by_m[0] <= by_m[1] <= by_m[2] and len(by_m[2]) > len(by_m[0])
    nowhere = query_by_example(db, example, KICK, mode="mismatch", mismatches=2, allowed=[])
    first = query_by_example(db, example, KICK, mode="mismatch", mismatches=2, allowed=[0])
    assert spans(nowhere) == by_m[0] and by_m[0] <= spans(first) <= by_m[1]


def test_a_whole_group_selected_is_the_strict_exact_query(hdm):
    """All features of a group: the query's runs are the stored segments, and the hits those of eq. 7 (§5.1)."""
    db, (_values, names) = hdm
    lower = feature_groups("2005")["lower"]
    idx = load(db)["lower"]
    doc = int(db.select(label="hopBothLegs1hops")["doc_id"].iloc[0])
    example = db.motion(doc)
    hits = query_by_example(db, example, lower, mode="exact")
    q = segment(relational_features(example)[0][:, [names.index(f) for f in lower]]).codes
    assert sorted(hits["first_segment"]) == idx.exact(q).tolist()


def test_plain_fuzzy_needs_one_stored_segment_per_query_segment(hdm):
    """Plain fuzzy hits (eq. 11) run on the stored segmentation under all features of the group: each query segment
    must be exactly one stored segment. A left-out feature that changes inside a query segment splits the stored
    segments there, so the query's own clip is no plain fuzzy hit (the kick query finds nothing at all), while the
    adaptive fuzzy hits, which coarsen the stored segmentation, find it."""
    db, (_values, names) = hdm
    idx = load(db)["lower"]
    lower = feature_groups("2005")["lower"]
    mask = sum(1 << lower.index(f) for f in KICK)
    kicks = db.select(label="kickLFront1Reps")["doc_id"].astype(int).tolist()
    row_of = {int(d): i for i, d in enumerate(db.documents["doc_id"])}
    for doc in kicks[:5]:
        example = db.motion(doc)
        q = segment(relational_features(example)[0][:, [names.index(f) for f in KICK]]).codes
        q_lower = [sum(((int(c) >> j) & 1) << lower.index(f) for j, f in enumerate(KICK)) for c in q]
        codes, seg_doc = idx.codes & mask, idx.segment_doc
        expected = [k for k in range(idx.n_segments - len(q) + 1)
                    if seg_doc[k] == seg_doc[k + len(q) - 1] and list(codes[k : k + len(q)]) == q_lower]
        fuzzy = query_by_example(db, example, KICK, mode="fuzzy")
        assert sorted(fuzzy["first_segment"]) == expected
        own_segments = np.diff(idx.doc_first_segment)[row_of[doc]]
        own = (fuzzy["doc_id"] == doc) & (fuzzy["start"] == 0) & (fuzzy["end"] == example.n_frames)
        assert own.any() == (own_segments == len(q))  # found itself only if no left-out feature splits a segment
        adaptive = query_by_example(db, example, KICK, mode="adaptive")
        assert ((adaptive["doc_id"] == doc) & (adaptive["start"] == 0)).any()
        if doc == kicks[0]:  # the documented example: nothing found, the clip's 7 runs are more stored segments
            assert fuzzy.empty and own_segments > len(q)


def test_query_segmentation_is_the_selected_columns_segmented_per_group(db):
    """Per group touched: the runs of the selected columns alone (same boundaries and lengths as segmenting just
    those columns); untouched groups are left out."""
    values, names = relational_features(db.motion(7), progress=False)
    chosen = ["rfoot_raised", "lknee_bent", "rhand_above_neck"]  # lower and upper, no mix
    groups = query_segmentation(values, names, chosen)
    assert set(groups) == {"lower", "upper"}
    for group, (picked, seq) in groups.items():
        members = feature_groups()[group]
        assert [members[i] for i in picked] == [f for f in chosen if f in members]
        alone = segment(values[:, [names.index(f) for f in chosen if f in members]])
        assert np.array_equal(seq.lengths, alone.lengths) and np.array_equal(seq.starts, alone.starts)
    assert len(groups["lower"][1].codes) > 1  # the kick raises its foot and bends its knee: several runs


def test_bad_mismatch_arguments_say_what_to_pass(db):
    example = db.motion(int(db.select(label="squat1Reps")["doc_id"].iloc[0]))
    with pytest.raises(ParameterError, match="mismatches must be an integer >= 0.*got -1"):
        query_by_example(db, example, ["rknee_bent"], mode="mismatch", mismatches=-1)
    with pytest.raises(ParameterError, match=r"allowed mismatch positions must lie in \[0, \d+\), got \[99\]"):
        query_by_example(db, example, ["rknee_bent", "rfoot_fast"], mode="mismatch", mismatches=1, allowed=[99])


def test_features_from_two_groups_are_joined_by_overlap(db):
    doc = db.select(label="rotateArmsBothBackward1Reps")["doc_id"].iloc[0]
    example = db.motion(doc)
    upper = query_by_example(db, example, ["rhand_above_neck"])
    lower = query_by_example(db, example, ["rknee_bent"])
    both = query_by_example(db, example, ["rhand_above_neck", "rknee_bent"])
    assert len(both) and set(both["doc_id"]) <= set(upper["doc_id"]) & set(lower["doc_id"])
    assert (both["doc_id"] == doc).any()


def test_bad_queries_say_what_to_do(db, tmp_path, db_values):
    example = db.motion(0)
    with pytest.raises(ValueError, match="unknown feature.*no_such_feature"):
        query_by_example(db, example, ["no_such_feature"])
    with pytest.raises(ValueError, match="no features selected"):
        query_by_example(db, example, [])
    with pytest.raises(ValueError, match="mode must be"):
        query_by_example(db, example, None, mode="sloppy")
    longest = db.documents["n_frames"].idxmax()
    long_clip = db.motion(int(db.documents["doc_id"].iloc[longest]))
    from dataclasses import replace

    doubled = replace(long_clip, positions=np.concatenate([long_clip.positions] * 2), quaternions=None)
    with pytest.raises(ValueError, match="longer than every document"):
        query_by_example(db, doubled, ["rknee_bent"])
    bare = MotionDB.ingest(db.documents["path"].iloc[:2].tolist(), tmp_path / "bare", progress=False)
    with pytest.raises(MotionDBError, match="mocapviz index"):
        query_by_example(bare, example, ["rknee_bent"])
    with pytest.raises(MotionDBError, match="--relational-set 2006"):
        query_by_example(bare, example, None, relational_set="2006")
    build(bare, progress=False)
    bare = bare.append(db.documents["path"].iloc[2:3].tolist(), progress=False)
    with pytest.raises(MotionDBError, match="rebuild"):
        query_by_example(bare, example, ["rknee_bent"])


def test_cli_index_and_query_print_the_library_answer(db, tmp_path, capsys):
    copy = MotionDB.ingest(db.documents["path"].tolist(), tmp_path / "db", progress=False)
    assert main(["index", str(copy.path), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "lower" in out and "upper" in out and "mix" in out
    doc = int(copy.select(label="squat1Reps")["doc_id"].iloc[0])
    assert main(["query", str(copy.path), "--example", str(doc), "--frames", "0:", "--features",
                 "rknee_bent,lknee_bent", "--no-exclude-document"]) == 0  # fmt: skip
    first = capsys.readouterr().out.splitlines()[0]
    hits = query_by_example(copy, copy.motion(doc), ["rknee_bent", "lknee_bent"])
    assert first.startswith(plural(len(hits), "hit") + " ")
    assert main(["query", str(copy.path), "--example", str(doc), "--features", "rknee_bent,lknee_bent",
                 "--csv", str(tmp_path / "other.csv")]) == 0  # fmt: skip  (by default without its own document)
    capsys.readouterr()
    assert pd.read_csv(tmp_path / "other.csv")["doc_id"].tolist() == hits.loc[hits["doc_id"] != doc, "doc_id"].tolist()
    assert main(["query", str(copy.path), "--example", str(doc), "--features", "bogus"]) == 1
    assert "unknown feature" in capsys.readouterr().err
    assert main(["query", str(copy.path), "--example", str(doc), "--features", ""]) == 1
    assert "--features '' names no feature; choose from the 2005 set" in capsys.readouterr().err
    assert main(["query", str(copy.path), "--example", str(doc), "--features", "rknee_bent", "--mismatch", "1",
                 "--mismatch-at", "0"]) == 0  # fmt: skip
    at_first = query_by_example(copy, copy.motion(doc), ["rknee_bent"], mode="mismatch", allowed=[0])
    at_first = at_first[at_first["doc_id"] != doc]  # the example's own document left out (exclude_document)
    assert capsys.readouterr().out.startswith(plural(len(at_first), "hit") + " ")


def test_hit_durations_use_each_documents_frame_rate(hdm05_dir, bandai1_files, tmp_path):
    """A database mixing 120 Hz (HDM05) and 30 Hz (Bandai Namco) documents: a clip's hit in its own document lasts
    as long as the clip, so its §6.2 score (sum of segment-duration differences, seconds) is 0 at either rate."""
    amc = min((hdm05_dir / "amc").rglob("*.amc"))
    mixed = MotionDB.ingest([amc, bandai1_files[0]], tmp_path / "mixed", progress=False)
    assert sorted(mixed.documents["fps"]) == [30.0, 120.0] and mixed.fps is None
    build(mixed, progress=False)
    for doc in mixed.documents["doc_id"]:
        hits = query_by_example(mixed, mixed.motion(int(doc)), ["rknee_bent", "lknee_bent", "rfoot_raised"])
        own = hits[(hits["doc_id"] == doc) & (hits["start"] == 0)]
        assert len(own) == 1 and own["score"].iloc[0] == pytest.approx(0.0, abs=1e-9), hits.head()


def test_an_examples_values_query_as_the_clip(db):
    """What a sharded query sends its shards (the example's relational values, not the clip) finds the same hits,
    for every mode; values of the other relational set are refused, naming the set to compute."""
    from mocapviz.relational.query import relational_example

    example = db.motion(7)[10:100]
    values = relational_example(example)
    assert values.values.shape == (90, len(relational_features(example)[1])) and values.duration == example.duration
    for mode in ("adaptive", "exact", "fuzzy", "mismatch"):
        a = query_by_example(db, example, ["lfoot_raised", "lknee_bent"], mode=mode)
        b = query_by_example(db, values, ["lfoot_raised", "lknee_bent"], mode=mode)
        assert a.equals(b) and len(a), mode
    with pytest.raises(ParameterError, match="of the 2006 set.*relational_example"):
        query_by_example(db, relational_example(example, "2006"), relational_set="2005")
