"""Segment labels (mocapviz/db/segments.py, the engine's label use cases, ``mocapviz labels``): the table is the log
replayed and equals a plain in-memory model after any sequence of adds, removes and undos (hypothesis); 4 processes
adding at once all land; a writer killed mid-way leaves a whole log; export -> import into another database gives
the same labels; a template learned from segment labels finds its class in clips that carry no label of it."""
from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import Engine, MotionDB
from mocapviz.cli import main
from mocapviz.db.layout import labels_file
from mocapviz.db.segments import SegmentLabels
from mocapviz.errors import MotionDBError, ParameterError


@pytest.fixture(scope="module")
def demo_copy(tmp_path_factory):
    """The demo database copied (labels are written into its folder)."""
    return shutil.copytree(MotionDB.demo().path, tmp_path_factory.mktemp("labels") / "demo.mdb")


@pytest.fixture
def db(demo_copy, tmp_path):
    """A fresh copy per test, without labels."""
    return MotionDB.open(shutil.copytree(demo_copy, tmp_path / "demo.mdb"))


def test_add_list_remove_undo_round_trip(db):
    engine = Engine(db)
    first = engine.add_label(45, frames=(82, 106), label="front kick", author="ann", note="right leg")
    second = engine.add_label(45, frames=slice(132, 159), label="front kick", author="bob", source="accepted hit")
    table = engine.segment_labels()
    assert table[["label_id", "doc_id", "name", "start", "end", "frames", "author", "source"]].values.tolist() == [
        [first, 45, "135_04", 82, 106, 24, "ann", "manual"], [second, 45, "135_04", 132, 159, 27, "bob", "accepted hit"]]
    assert table["start_s"].tolist() == [82 / 30, 132 / 30] and table["note"].tolist() == ["right leg", ""]
    before = engine.segment_labels()
    engine.remove_label(first, author="bob")
    assert engine.segment_labels()["label_id"].tolist() == [second]
    engine.undo_label(author="bob")  # bob's last change: the remove
    pd.testing.assert_frame_equal(engine.segment_labels(), before)  # author and time as they were
    history = engine.label_history()
    assert history["op"].tolist() == ["add", "add", "remove", "add"] and history["undoes"].tolist()[-1] == 3
    assert history["author"].tolist() == ["ann", "bob", "bob", "bob"]
    engine.undo_label(author="ann")  # ann's add
    assert engine.segment_labels()["label_id"].tolist() == [second]


@pytest.mark.parametrize(("doc", "frames", "label", "message"), [
    (99, (0, 5), "kick", "no document 99"),
    (45, (300, 400), "kick", "frames 300:400 are not a stretch of document 45 (0:329"),
    (45, (5, 5), "kick", "frames 5:5"),
    (45, (0, 5), "", "label must be a non-empty printable text"),
    (45, (0, 5), "a\nb", "label must be a non-empty printable text"),
    (45, (0, 5), "x" * 129, "at most 128 characters"),
])  # fmt: skip
def test_a_change_outside_the_database_is_refused_naming_the_value(db, doc, frames, label, message):
    with pytest.raises(ParameterError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Engine(db).add_label(doc, frames=frames, label=label, author="ann")
    assert not labels_file(db.path).exists()


def test_undo_is_refused_when_a_later_change_touched_the_label(db):
    labels = SegmentLabels(db)
    lid = labels.add(3, 0, 10, "hop", author="ann")
    labels.edit(lid, author="bob", label="jump")
    with pytest.raises(ParameterError, match="change 2 changed label 1 since"):
        labels.undo(1, author="ann")
    labels.undo(author="bob")
    assert labels.table()["label"].tolist() == ["hop"]
    with pytest.raises(ParameterError, match="change 2 is undone already"):
        labels.undo(2, author="bob")


class _Model:
    """The plain in-memory model: a dict of rows, and each author's stack of (label_id, row before) to undo."""

    def __init__(self):
        self.rows, self.stack, self.next_id = {}, [], 1

    def add(self, doc, start, end, label, author):
        self.stack.append((self.next_id, None))
        self.rows[self.next_id] = (doc, start, end, label, author)
        self.next_id += 1

    def remove(self, label_id):
        self.stack.append((label_id, self.rows.pop(label_id)))

    def undo(self):
        label_id, row = self.stack.pop()
        if row is None:
            del self.rows[label_id]
        else:
            self.rows[label_id] = row


_STEP = st.one_of(st.tuples(st.just("add"), st.integers(0, 53), st.integers(0, 15), st.integers(1, 15),
                            st.sampled_from(["kick", "hop", "front kick"])),
                  st.tuples(st.just("remove"), st.integers(0, 10)), st.tuples(st.just("undo")))  # fmt: skip


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(steps=st.lists(_STEP, max_size=12))
def test_any_sequence_of_changes_equals_the_in_memory_model(db, steps):
    shutil.rmtree(labels_file(db.path).parent, ignore_errors=True)
    labels, model = SegmentLabels(db), _Model()
    for step in steps:
        if step[0] == "add":
            _, doc, start, length, label = step
            n = int(db.document(doc)["n_frames"])  # (the demo's shortest clip has 16 frames)
            start, length = start % (n - 1), min(length, n - start % (n - 1))
            labels.add(doc, start, start + length, label, author="ann")
            model.add(doc, start, start + length, label, "ann")
        elif step[0] == "remove" and model.rows:
            label_id = sorted(model.rows)[step[1] % len(model.rows)]
            labels.remove(label_id, author="ann")
            model.remove(label_id)
        elif step[0] == "undo" and model.stack:
            before_last = _previous_state(labels)
            labels.undo(author="ann")
            model.undo()
            pd.testing.assert_frame_equal(labels.table(), before_last)  # exactly, author and time included
        table = labels.table()
        assert {r.label_id: (r.doc_id, r.start, r.end, r.label, r.author) for r in table.itertuples()} == model.rows
        assert len(labels.history()) == len(labels.changes())


def _previous_state(labels: SegmentLabels) -> pd.DataFrame:
    """The table before the change an undo would revert now: the log without that change's effect, replayed by
    hand (the changes before it, then the ones after it, which touched other labels)."""
    log = labels.changes()
    undone = {c["undoes"] for c in log if c.get("undoes") is not None}
    k = next(c["change"] for c in reversed(log) if c.get("undoes") is None and c["change"] not in undone)
    from mocapviz.db.segments import _frame, _replay

    state = _replay(log)[0]
    before = _replay(log[: k - 1])[0]
    label_id = log[k - 1]["label_id"]
    if label_id in before:
        state[label_id] = before[label_id]
    else:
        state.pop(label_id, None)
    return _frame(state)


def _adder(path: str, author: str, n: int) -> None:
    db = MotionDB.open(path)
    labels = SegmentLabels(db)
    for i in range(n):
        labels.add(i % 50, 0, 2, f"label {i}", author=author)


def test_four_processes_adding_at_once_all_land(db):
    t0 = time.perf_counter()
    context = multiprocessing.get_context("spawn")
    writers = [context.Process(target=_adder, args=(str(db.path), f"writer{w}", 50)) for w in range(4)]
    for p in writers:
        p.start()
    for p in writers:
        p.join(120)
        assert p.exitcode == 0
    table = SegmentLabels(db).table()
    assert len(table) == 200 and sorted(table["label_id"]) == list(range(1, 201))
    assert table.groupby("author").size().to_dict() == {f"writer{w}": 50 for w in range(4)}
    for w in range(4):  # each writer's labels in its own order
        assert table[table["author"] == f"writer{w}"]["label"].tolist() == [f"label {i}" for i in range(50)]
    assert [c["change"] for c in SegmentLabels(db).changes()] == list(range(1, 201))
    print(f"4 x 50 adds: {time.perf_counter() - t0:.1f} s")


def test_a_writer_killed_mid_way_leaves_a_whole_log(db):
    script = ("import sys; from mocapviz import MotionDB; from mocapviz.db.segments import SegmentLabels\n"
              "labels = SegmentLabels(MotionDB.open(sys.argv[1]))\n"
              "for i in range(100000): labels.add(i % 50, 0, 3, 'x' * 100, author='killed', note='n' * 900)\n")
    writer = subprocess.Popen([sys.executable, "-c", script, str(db.path)], env=os.environ.copy())
    path, seen = labels_file(db.path), 0
    try:
        deadline = time.monotonic() + 60
        while seen < 30 and time.monotonic() < deadline:  # readers meanwhile always see a whole log
            try:
                seen = len(SegmentLabels(db).changes())
            except FileNotFoundError:
                pass
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    finally:
        if writer.poll() is None:
            writer.kill()
    assert seen >= 30
    labels = SegmentLabels(db)
    n = len(labels.changes())
    assert n >= seen and [c["change"] for c in labels.changes()] == list(range(1, n + 1))
    labels.add(0, 0, 2, "after", author="ann")  # the lock was released with the process; a temporary file is ignored
    assert len(labels.table()) == n + 1
    path.write_bytes(path.read_bytes().replace(b'"killed"', b'"kilLed"', 1))  # damage: refused, not misread
    with pytest.raises(MotionDBError, match="sha256"):
        labels.table()


@pytest.mark.parametrize("format", ["csv", "babel"])
def test_export_then_import_into_another_database_gives_the_same_labels(db, tmp_path, format):
    engine = Engine(db)
    engine.add_label(45, frames=(82, 106), label="front kick", author="ann", note="right")
    engine.add_label(5, frames=(3, 37), label="kick", author="bob")
    engine.add_label(52, frames=(80, 100), label="side kick", author="bob", source="rejected hit")
    out = engine.export_labels(tmp_path / f"labels.{'json' if format == 'babel' else 'csv'}", format=format)
    # another database holding the same documents in another order: labels follow the names, not the doc ids
    other = MotionDB.ingest([db.document(d)["path"] for d in (52, 5, 45)], tmp_path / "other.mdb", fps=30,
                            progress=False)  # fmt: skip
    into = Engine(other)
    ids = into.import_labels(out, author="carol")
    got = into.segment_labels()
    kept = engine.segment_labels()
    if format == "babel":  # a rejected hit is no action of BABEL's
        kept = kept[kept["source"] != "rejected hit"]
        data = json.loads(out.read_text())
        assert data["135_04"]["frame_ann"]["labels"][0]["start_t"] == pytest.approx(82 / 30)
        assert data["135_04"]["dur"] == pytest.approx(329 / 30) and data["135_04"]["fps"] == 30.0
    assert len(ids) == len(kept) and set(got["author"]) == {"carol"} and set(got["source"]) == {"imported"}
    columns = ["name", "start", "end", "label"]
    assert sorted(got[columns].values.tolist()) == sorted(kept[columns].values.tolist())
    assert got["doc_id"].tolist() != kept["doc_id"].tolist()


def test_the_command_line(db, tmp_path, capsys):
    path = str(db.path)
    assert main(["labels", path, "add", "--doc", "45", "--frames", "82:106", "--label", "front kick", "--author",
                 "ann"]) == 0  # fmt: skip
    assert main(["labels", path, "add", "--doc", "45", "--frames", "132:159", "--label", "front kick"]) == 0
    assert main(["labels", path, "add", "--doc", "45", "--frames", "300:400", "--label", "x"]) == 1
    assert "frames 300:400 are not a stretch of document 45" in capsys.readouterr().err
    assert main(["labels", path, "list", "--csv", str(tmp_path / "l.csv")]) == 0
    table = pd.read_csv(tmp_path / "l.csv")
    import getpass

    assert table["author"].tolist() == ["ann", getpass.getuser()] and table["end"].tolist() == [106, 159]
    assert main(["labels", path, "remove", "1", "--author", "bob"]) == 0
    assert main(["labels", path, "undo", "--author", "bob"]) == 0
    assert "change 3 undone by change 4" in capsys.readouterr().out
    assert main(["labels", path, "history"]) == 0 and "4 changes" in capsys.readouterr().out
    assert main(["labels", path, "export", "--format", "babel", "--out", str(tmp_path / "l.json")]) == 0
    assert main(["labels", path, "import", str(tmp_path / "l.json"), "--author", "carol"]) == 0
    assert len(Engine(db).segment_labels(label="front kick")) == 4


def test_hits_filtered_and_judged_by_label(db):
    engine = Engine(db)
    engine.add_label(45, frames=(82, 106), label="kick", author="ann")
    hits = pd.DataFrame({"rank": [1, 2, 3, 4], "doc_id": [45, 45, 5, 16], "start": [100, 0, 0, 0],
                         "end": [120, 82, 10, 10]})  # fmt: skip
    assert engine.with_label(hits, label="kick")[["rank", "doc_id", "start"]].values.tolist() == [[1, 45, 100]]
    kept = engine.with_label(hits, label="kickLFront1Reps")  # a file-name label: its documents
    assert kept[["rank", "doc_id"]].values.tolist() == [[1, 5], [2, 16]]
    engine.add_label(45, frames=(130, 160), label="kick", author="ann")
    hits = pd.concat([hits, pd.DataFrame({"rank": [5], "doc_id": [45], "start": [150], "end": [170]})])
    quality = engine.label_quality(hits, label="kick")  # the second segment found at rank 5, the first at rank 1
    assert quality["relevant"] == 2 and quality["ranking"]["relevant"].tolist() == [True, False, False, False, True]
    assert quality["precision"] == 0.4 and quality["average_precision"] == pytest.approx((1 + 2 / 5) / 2)


@pytest.mark.slow
def test_a_template_learned_from_segment_labels_finds_its_class_where_nothing_is_labelled(hdm05_db30, tmp_path):
    """The left front kicks of 3 actors (bd, dg, mm) labelled as segments "front kick", a name no file has: the
    template learned from them alone finds 6 of the other 2 actors' 11 kicks (bk, tr), which carry no label of that
    name, before any clip of another class (the file-name labels, unseen by the learning, are the oracle)."""
    db = MotionDB.open(shutil.copytree(hdm05_db30.path, tmp_path / "hdm.mdb"))
    engine = Engine(db)
    docs = db.documents
    kicks = docs[docs["label"] == "kickLFront1Reps"]
    taught = kicks[kicks["actor"].isin(["bd", "dg", "mm"])]
    engine.add_labels(taught.assign(start=0, end=taught["n_frames"]), label="front kick", author="ann")
    template = engine.learn_template("front kick")
    assert (template.meta["segment_examples"], template.meta["file_examples"]) == (16, 0)
    hits = engine.search_template(template, n_matches=40)
    is_kick = hits["doc_id"].isin(kicks["doc_id"]).to_numpy()
    first_other = int(np.argmin(is_kick))  # the rank (from 0) of the first clip of another class
    new = hits.iloc[:first_other][~hits["doc_id"].iloc[:first_other].isin(taught["doc_id"])]
    assert first_other >= 20 and len(new) >= 6  # of bk's and tr's 11 kicks (measured: 24 and 6, rank 17 the first)
    under = hits[hits["normalised_cost"] <= template.meta["threshold"]]
    assert is_kick[: len(under)].mean() >= 0.95  # its learned threshold (measured: 24 of 25 kicks, then grabHighR)


def test_search_and_find_keep_the_hits_of_a_label(db, tmp_path, capsys):
    """`mocapviz find/search --label NAME`: exactly the hits (of every hit, or of every document's best clip) that
    overlap a segment of NAME or lie in a document of that file-name label, ranked again; an emptied answer says
    why. The two front kicks of CMU 135_04 at 30 Hz, frames 87-101 and 137-154, found by reading the right ankle's
    height (above 30 cm) frame by frame."""
    for frames in ("87:101", "137:154"):
        assert main(["labels", str(db.path), "add", "--doc", "45", "--frames", frames, "--label", "front kick"]) == 0
    every = Engine(db).find("kick_right | kick_left", n_matches=None)
    assert main(["find", str(db.path), "kick_right | kick_left", "--label", "front kick", "--csv",
                 str(tmp_path / "k.csv")]) == 0  # fmt: skip
    kept = pd.read_csv(tmp_path / "k.csv")
    labelled = every[(every["doc_id"] == 45) & (every["start"] < 154) & (every["end"] > 87)
                     & ~((every["start"] >= 101) & (every["end"] <= 137))]  # fmt: skip
    assert kept[["doc_id", "start", "end"]].values.tolist() == labelled[["doc_id", "start", "end"]].values.tolist()
    assert kept["rank"].tolist() == list(range(1, len(kept) + 1)) and len(kept) == 2
    assert main(["find", str(db.path), "squat", "--label", "front kick"]) == 0
    assert "no hit: none of its" in capsys.readouterr().out
    assert main(["search", str(db.path), "--example", "5", "-K", "3", "--label", "kickLFront1Reps", "--csv",
                 str(tmp_path / "c.csv")]) == 0  # fmt: skip
    clips = pd.read_csv(tmp_path / "c.csv")
    assert sorted(clips["doc_id"]) == [16, 27, 38]  # the other three actors' kicks, whatever their rank before


def test_no_segment_labelled_document_is_a_negative_when_the_examples_are_capped(db, monkeypatch):
    """learn_class with max_examples below the examples: the documents of the segments left out by the cap are still
    of the class, so none is judged a negative of its threshold (they were: only the kept examples' documents were
    left out of the negatives)."""
    from mocapviz.db.segments import POSITIVE
    from mocapviz.relational import templates

    engine = Engine(db)
    kicks = [5, 16, 27, 38]  # the demo's four HDM05 kicks (file label kickLFront1Reps), labelled 'kick' as segments
    for doc in kicks:
        engine.add_label(doc, frames=(0, 20), label="kick", author="ann")
    judged = []
    real = templates._negative_costs
    monkeypatch.setattr(templates, "_negative_costs",
                        lambda t, values, others: judged.append(set(others["doc_id"])) or real(t, values, others))
    segments = engine.segment_labels(label="kick")
    template = templates.learn_class(db, "kick", max_examples=2, segments=segments[segments["source"].isin(POSITIVE)])
    assert template.n_examples == 2 and judged and not judged[0] & set(kicks)


def test_a_take_given_as_an_example_is_learned_as_its_document_would_be(db, tmp_path, capsys):
    """learn_template(examples=[file]) (the Templates page's uploaded take, `template learn --example FILE`): a
    document's own source file, read as an example at the database's rate, gives the template its whole-document
    segment label gives; a label nothing has yet is allowed with a take."""
    engine = Engine(db)
    paths = [db.document(doc)["path"] for doc in (5, 16)]
    from_files = engine.learn_template("kick", examples=paths)
    for doc in (5, 16):
        engine.add_label(doc, frames=(0, int(db.document(doc)["n_frames"])), label="kick", author="ann")
    from_labels = engine.learn_template("kick")
    assert np.array_equal(from_files.values, from_labels.values) and from_files.n_examples == 2
    assert from_files.meta["extra_examples"] == 2 and from_files.meta["segment_examples"] == 0
    assert main(["template", "learn", str(db.path), "--label", "new class", "--example", paths[0]]) == 0
    assert "1 example (0 documents with that file-name label, 0 segment labels, 1 take given with --example)" in \
        capsys.readouterr().out


@pytest.mark.slow
def test_four_command_line_writers_at_once_all_land(db):
    """The issue's "4 concurrent CLI writers": four shells each running `mocapviz labels DB add` 4 times at the same
    time; all 16 labels are there afterwards with their authors, and one undo per author restores each one's last."""
    script = ('for i in 1 2 3 4; do "$MOCAPVIZ" labels "$DB" add --doc $((i * 5)) --frames 0:$((i + 4)) '
              '--label "take $i" --author "$WHO" > /dev/null || exit 1; done')  # fmt: skip
    env = dict(os.environ, MOCAPVIZ=str(Path(sys.executable).parent / "mocapviz"), DB=str(db.path))
    shells = [subprocess.Popen(["bash", "-ec", script], env=dict(env, WHO=f"writer{w}")) for w in range(4)]
    assert [s.wait(timeout=300) for s in shells] == [0] * 4
    table = SegmentLabels(db).table()
    assert len(table) == 16 and table.groupby("author").size().to_dict() == {f"writer{w}": 4 for w in range(4)}
    assert sorted(zip(table["doc_id"], table["end"])) == sorted((i * 5, i + 4) for i in range(1, 5) for _ in range(4))
    for w in range(4):
        assert main(["labels", str(db.path), "undo", "--author", f"writer{w}"]) == 0
    after = SegmentLabels(db).table()
    assert len(after) == 12 and (after["label"] == "take 4").sum() == 0
