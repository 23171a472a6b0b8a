"""Query by example over a MotionDB's relational indexes, checked against a direct scan of the features."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from mocapviz import MotionDB, MotionDBError, datasets
from mocapviz.cli import main
from mocapviz.features import relational
from mocapviz.index import build
from mocapviz.query import query_by_example
from mocapviz.segment import segment

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """The embedded sample (22 HDM05 clips, 2 CMU trials) at 120 Hz with its 2005 indexes."""
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    db = MotionDB.ingest(datasets.sample(), tmp_path_factory.mktemp("q") / "db", progress=False)
    build(db, progress=False)
    return db


@pytest.fixture(scope="module")
def db_values(db):
    return relational(db, progress=False)


def scan_hits(db, values, names, example, chosen) -> set:
    """Brute force: segment every document by the chosen features alone, and find the example's sequence
    of chosen-feature vectors as consecutive runs (the restricted feature function of §5.2)."""
    cols = [names.index(f) for f in chosen]
    ex_values, _ = relational(example)
    q = segment(ex_values[:, cols]).codes
    hits = set()
    for row in db.documents.itertuples():
        seq = segment(values[row.start : row.start + row.n_frames, cols])
        for k in range(len(seq.codes) - len(q) + 1):
            if np.array_equal(seq.codes[k : k + len(q)], q):
                last = k + len(q) - 1
                hits.add((row.doc_id, int(seq.starts[k]), int(seq.starts[last] + seq.lengths[last] - 1)))
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
    got = set(zip(hits["doc_id"], hits["start_frame"], hits["end_frame"]))
    assert got == scan_hits(db, values, names, example, chosen)
    # the query document itself is found over its whole length, with a perfect temporal score
    own = hits[(hits["doc_id"] == doc) & (hits["start_frame"] == 0)]
    assert len(own) == 1 and own["end_frame"].iloc[0] == example.n_frames - 1
    assert own["score"].iloc[0] == 0.0 and own["rank"].iloc[0] == 1 or hits["score"].iloc[0] == 0.0
    assert (np.diff(hits["score"]) >= 0).all() and hits["rank"].tolist() == list(range(1, len(hits) + 1))


def test_exact_and_mismatch_modes(db):
    doc = db.select(label="squat1Reps")["doc_id"].iloc[0]
    example = db.motion(doc)
    exact = query_by_example(db, example, ["rknee_bent"], mode="exact")  # all 11 lower features must match
    assert ((exact["doc_id"] == doc) & (exact["start_frame"] == 0)).any()
    loose = query_by_example(db, example, ["rknee_bent"], mode="mismatch", mismatches=1)
    key = lambda t: set(zip(t["doc_id"], t["first_segment"]))
    assert key(exact) <= key(loose)
    nowhere = query_by_example(db, example, ["rknee_bent"], mode="mismatch", mismatches=1, allowed=[])
    first = query_by_example(db, example, ["rknee_bent"], mode="mismatch", mismatches=1, allowed=[0])
    assert key(nowhere) == key(exact) and key(exact) <= key(first) <= key(loose)


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
    with pytest.raises(MotionDBError, match="--feature-set 2006"):
        query_by_example(bare, example, None, feature_set="2006")
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
                 "rknee_bent,lknee_bent"]) == 0  # fmt: skip
    first = capsys.readouterr().out.splitlines()[0]
    hits = query_by_example(copy, copy.motion(doc), ["rknee_bent", "lknee_bent"])
    assert first.startswith(f"{len(hits)} hits")
    assert main(["query", str(copy.path), "--example", str(doc), "--features", "bogus"]) == 1
    assert "unknown feature" in capsys.readouterr().err
    assert main(["query", str(copy.path), "--example", str(doc), "--features", ""]) == 1
    assert "no features selected" in capsys.readouterr().err
    assert main(["query", str(copy.path), "--example", str(doc), "--features", "rknee_bent", "--mismatch", "1",
                 "--mismatch-at", "0"]) == 0  # fmt: skip
    at_first = query_by_example(copy, copy.motion(doc), ["rknee_bent"], mode="mismatch", allowed=[0])
    assert capsys.readouterr().out.startswith(f"{len(at_first)} hits")
