"""Motion templates stored with a MotionDB (``DB/templates/``) and the ``mocapviz template learn|search`` command.

The CLI round trips run on a copy of the embedded sample (22 HDM05 clips of actors dg and mm, 2 CMU trials, 120 Hz;
no shared archives needed); one test learns and searches on all 287 HDM05 clips at 30 Hz (``hdm05_db30``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB
from mocapviz.cli import main
from mocapviz.engine.parameters import default
from mocapviz.errors import DescriptionError, MotionDBError, ParameterError, UnknownKeyError
from mocapviz.features import feature_names, relational_features
from mocapviz.relational.scene import find
from mocapviz.relational.templates import (
    MotionTemplate,
    find_instances,
    learn_class,
    learn_template,
    load_template,
    store_template,
    stored_templates,
    template_path,
)
from mocapviz.validation import plural


@pytest.fixture(scope="module")
def db(sample_db, tmp_path_factory) -> MotionDB:
    """A copy of the embedded sample (its stored templates are this module's own)."""
    folder = tmp_path_factory.mktemp("templates-cli") / "db"
    shutil.copytree(sample_db.path, folder)
    return MotionDB.open(folder)


@pytest.fixture(scope="module")
def values(db) -> np.ndarray:
    return relational_features(db, "2006", progress=False)[0]


def _same(a: MotionTemplate, b: MotionTemplate) -> None:
    assert np.array_equal(a.values, b.values)
    assert (a.features, a.label, a.n_examples, a.iterations) == (b.features, b.label, b.n_examples, b.iterations)
    assert a.meta["doc_ids"] == b.meta["doc_ids"]


def _error(capsys) -> str:
    """The one line of stderr (and nothing printed on stdout)."""
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mocapviz: error: "), err
    assert not out.strip(), out
    return lines[0]


# --------------------------------------------------------------------------------------------------- learn
def test_learn_via_the_cli_equals_learn_class_and_is_stored(db, tmp_path, capsys):
    out = tmp_path / "squat.npz"
    assert main(["template", "learn", str(db.path), "--label", "squat1Reps", "--actors", "dg", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    expected = learn_class(db, "squat1Reps", actors=["dg"])
    _same(MotionTemplate.load(out), expected)
    _same(load_template(db, "squat1Reps-dg"), expected)
    assert expected.meta["doc_ids"] == [11] and expected.meta["generation"] == db.manifest["generation"]
    dont_care = (expected.quantised(default("search_template", "delta")) == 0.5).mean()  # at the δ it is searched with
    assert (f"1 example (1 document with that file-name label, 0 segment labels), {len(expected.values)} frames x 39 "
            "features") in printed
    assert f"{dont_care:.0%} don't care" in printed and plural(expected.iterations, "iteration") in printed
    assert str(template_path(db, "squat1Reps-dg")) in printed and f"written to {out}" in printed


def test_learn_on_a_database_with_unlabelled_takes(tmp_path, capsys):
    """A lab's own take has no label (NA): learning a class ignores it, as example and as other class, and the
    template equals the one learned without the take (it crashed: boolean value of NA is ambiguous)."""
    from mocapviz.app.pages.templates import actors_of
    from mocapviz.io import datasets

    sample = datasets.sample()
    own = tmp_path / "own"
    own.mkdir()
    shutil.copy(sample / "cmu-asfamc" / "asf" / "martialwalk.asf", own)  # no labels.tsv: an unlabelled take
    shutil.copy(sample / "cmu-asfamc" / "amc" / "martialwalk" / "135_08.amc", own)
    mixed = MotionDB.ingest([sample / "hdm05-cut", own], tmp_path / "mixed", progress=False)
    labelled = MotionDB.ingest([sample / "hdm05-cut"], tmp_path / "labelled", progress=False)
    assert mixed.documents["label"].isna().sum() == 1 and labelled.documents["label"].notna().all()
    assert main(["template", "learn", str(mixed.path), "--label", "kickLFront1Reps"]) == 0
    capsys.readouterr()
    got, expected = load_template(mixed, "kickLFront1Reps"), learn_class(labelled, "kickLFront1Reps")
    _same(got, expected)
    assert got.meta["negatives"] == expected.meta["negatives"] > 0
    assert got.meta["threshold"] == expected.meta["threshold"]
    assert actors_of(mixed.documents, "kickLFront1Reps") == actors_of(labelled.documents, "kickLFront1Reps")


def test_learn_2005_set_from_every_actor(db, capsys):
    assert main(["template", "learn", str(db.path), "--label", "kickLFront1Reps", "--relational-set", "2005"]) == 0
    stored = load_template(db, "kickLFront1Reps")
    _same(stored, learn_class(db, "kickLFront1Reps", relational_set="2005"))
    assert stored.features == feature_names("2005") and stored.meta["doc_ids"] == [7, 18]
    assert "2 examples" in capsys.readouterr().out


# -------------------------------------------------------------------------------------------------- search
@pytest.fixture(scope="module")
def kick(db) -> MotionTemplate:
    """The kick template of actor dg, stored as kickLFront1Reps-dg (searched in both actors' clips)."""
    template = learn_class(db, "kickLFront1Reps", actors=["dg"])
    store_template(db, template)
    return template


@pytest.mark.parametrize("by", ["name", "file"])
def test_search_csv_equals_find_instances_with_frames_within_documents(by, db, kick, values, tmp_path, capsys):
    what = "kickLFront1Reps-dg" if by == "name" else str(tmp_path / "kick.npz")
    if by == "file":
        kick.save(what)
    csv = tmp_path / "hits.csv"
    assert main(["template", "search", str(db.path), what, "-K", "6", "--csv", str(csv)]) == 0
    printed = capsys.readouterr().out
    got = pd.read_csv(csv)
    hits = find_instances(kick, values, db.documents["start"].to_numpy(), n_matches=6)
    assert len(got) == len(hits) == 6
    docs = db.documents.iloc[hits["doc_id"].to_numpy()]
    assert got["doc_id"].tolist() == docs["doc_id"].tolist() and got["rank"].tolist() == list(range(1, 7))
    np.testing.assert_allclose(got["cost"], hits["cost"])
    np.testing.assert_allclose(got["normalised_cost"], hits["normalised_cost"])
    assert np.array_equal(got["start"], hits["start"]) and np.array_equal(got["end"], hits["end"])  # in-document
    assert (got["start"] >= 0).all() and (got["end"] <= docs["n_frames"].to_numpy()).all()  # frames within the document, half-open
    assert np.array_equal(got["frames"], got["end"] - got["start"])
    assert got["name"].tolist() == docs["name"].tolist() and got["label"].tolist() == docs["label"].tolist()
    assert got["normalised_cost"].is_monotonic_increasing  # best first
    assert got.loc[0, "name"] == "HDM_dg_kickLFront1Reps_017_120" and got.loc[0, "cost"] == 0  # its own example
    assert "6 matches of template 'kickLFront1Reps'" in printed and f"ranked table written to {csv}" in printed


def test_max_cost_keeps_exactly_the_cheaper_hits(db, kick, tmp_path, capsys):
    every, cheap = tmp_path / "every.csv", tmp_path / "cheap.csv"
    assert main(["template", "search", str(db.path), "kickLFront1Reps-dg", "-K", "8", "--csv", str(every)]) == 0
    all_hits = pd.read_csv(every)
    limit = float(all_hits["normalised_cost"].iloc[3])  # at least the four best pass
    assert limit < all_hits["normalised_cost"].max()
    assert main(["template", "search", str(db.path), "kickLFront1Reps-dg", "-K", "8", "--max-cost", str(limit),
                 "--csv", str(cheap)]) == 0  # fmt: skip
    kept = pd.read_csv(cheap)
    assert (kept["normalised_cost"] <= limit).all() and 4 <= len(kept) < len(all_hits)
    expected = all_hits[all_hits["normalised_cost"] <= limit].reset_index(drop=True)
    pd.testing.assert_frame_equal(kept, expected)
    assert f"normalised cost <= {limit:g}" in capsys.readouterr().out


def test_prefilter_aligns_only_the_keyframe_ranges(db, kick, values, tmp_path, capsys):
    """--prefilter gives find_instances over keyframe_ranges (indexes built and stored when missing)."""
    from mocapviz.relational import index
    from mocapviz.relational.templates import keyframe_ranges

    csv = tmp_path / "pre.csv"
    assert main(["template", "search", str(db.path), "kickLFront1Reps-dg", "-K", "6", "--prefilter", "--csv",
                 str(csv)]) == 0  # fmt: skip
    assert "keyframe pre-filter" in capsys.readouterr().out
    starts = db.documents["start"].to_numpy()
    ranges = keyframe_ranges(kick, index.load(db, "2006"), starts, db.n_frames)
    assert 0 < (ranges[:, 1] - ranges[:, 0]).sum() < db.n_frames
    hits = find_instances(kick, values, starts, n_matches=6, ranges=ranges)
    got = pd.read_csv(csv)
    assert got["doc_id"].tolist() == db.documents["doc_id"].to_numpy()[hits["doc_id"]].tolist()
    np.testing.assert_allclose(got["cost"], hits["cost"])


def test_no_match_says_what_to_try(db, tmp_path, capsys):
    """Every feature of the set true at once occurs nowhere: at cost 0 nothing matches."""
    path = tmp_path / "impossible.npz"
    MotionTemplate(np.ones((20, 39)), feature_names("2006"), "impossible", 1, 1).save(path)
    csv = tmp_path / "h.csv"
    assert main(["template", "search", str(db.path), str(path), "--max-cost", "0", "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    assert "0 matches" in out and "no matches (try a larger --max-cost)" in out
    assert pd.read_csv(csv).empty


# ------------------------------------------------------------------------------------------------ bad input
BAD = [  # (arguments after the DB, words of the one error line, exit status)
    ("learn --label nope", ["--label: unknown label 'nope'; choose one of", "squat1Reps", "Motorcycle"], 1),
    ("learn --label squat1Reps --actors dg,xx", ["--actors: unknown actor 'xx'; choose one of dg, mm"], 1),
    ("learn --label squat1Reps --relational-set 2007", ["--relational-set", "2005, 2006"], 2),
    ("learn --label squat1Reps --out {tmp}/missing/t.npz", ["--out", "no folder"], 1),
    ("learn", ["--label"], 2),
    ("search nope", ["nope: no such template file", "no stored template 'nope'", "kickLFront1Reps-dg"], 1),
    ("search ../x", ["../x: no such template file", "no stored template '../x' in "], 1),
    ("search kickLFront1Reps-dg -K 0", ["-K/--matches must be at least 1; got 0"], 2),
    ("search kickLFront1Reps-dg --matches x", ["-K/--matches", "integer"], 2),
    ("search kickLFront1Reps-dg --max-cost 1.5", ["--max-cost must be a number in [0, 1]; got '1.5'"], 2),
    ("search kickLFront1Reps-dg --max-cost -0.1", ["--max-cost must be a number in [0, 1]"], 2),
    ("search kickLFront1Reps-dg --max-cost nan", ["--max-cost must be a number in [0, 1]"], 2),
    ("search kickLFront1Reps-dg --csv {tmp}/missing/h.csv", ["--csv", "no folder"], 1),
    ("search {tmp}/truncated.npz", ["truncated.npz: not a readable motion template"], 1),
    ("search {tmp}/altered.npz", ["altered.npz: its arrays differ from those written (sha256)"], 1),
    ("search {tmp}/other.npz", ["other.npz: the template's 2 features are not those of a relational set",
                                "2006: 39"], 1),
]


@pytest.mark.parametrize("line, needles, status", BAD, ids=[row[0] for row in BAD])
def test_bad_input_is_one_typed_line(line, needles, status, db, kick, tmp_path, capsys):
    good = tmp_path / "good.npz"
    kick.save(good)
    (tmp_path / "truncated.npz").write_bytes(good.read_bytes()[:300])
    with np.load(good) as z:  # the same header, other values
        np.savez(tmp_path / "altered.npz", header=z["header"], values=1 - z["values"])
    learn_template([np.eye(2, dtype=bool)], ["a", "b"], "other").save(tmp_path / "other.npz")
    action, *rest = line.format(tmp=tmp_path).split()
    assert main(["template", action, str(db.path), *rest]) == status
    error = _error(capsys)
    assert all(needle in error for needle in needles), error


# ------------------------------------------------------------------------------------- storage (Python API)
def test_store_list_and_load_back(db, tmp_path):
    copy = tmp_path / "db"
    shutil.copytree(db.path, copy, ignore=shutil.ignore_patterns("templates"))
    mine = MotionDB.open(copy)
    assert stored_templates(mine).empty and list(stored_templates(mine).columns)[:6] == [
        "name", "label", "n_examples", "frames", "relational_set", "actors"]  # fmt: skip
    squat = learn_class(mine, "squat1Reps", actors=["dg", "mm"])
    path = store_template(mine, squat)
    assert path == copy / "templates" / "squat1Reps-dg-mm.npz"
    _same(load_template(mine, "squat1Reps-dg-mm"), squat)
    odd = MotionTemplate(squat.values, squat.features, "a b/../c", 2, 1)
    assert store_template(mine, odd).name == "a_b_.._c.npz"  # filename-safe
    assert store_template(mine, squat, name="mine").name == "mine.npz"
    for bad in ("../up", ".hidden", "", "a/b", "x" * 129):
        with pytest.raises(ParameterError, match="not filename-safe"):
            store_template(mine, squat, name=bad)
    listed = stored_templates(mine).set_index("name")
    assert listed.index.tolist() == ["a_b_.._c", "mine", "squat1Reps-dg-mm"]
    row = listed.loc["squat1Reps-dg-mm"]
    assert (row["label"], row["n_examples"], row["frames"], row["relational_set"], row["actors"]) == (
        "squat1Reps", 2, len(squat.values), "2006", "dg,mm")  # fmt: skip
    assert row["generation"] == mine.manifest["generation"] and row["current"]
    assert listed.loc["mine", "actors"] == "dg,mm" and pd.isna(listed.loc["a_b_.._c", "generation"])
    with pytest.raises(UnknownKeyError, match=rf"^no stored template 'nope' in {copy}; stored: a_b_.._c, mine, "
                       r"squat1Reps-dg-mm \(`mocapviz template learn"):  # fmt: skip
        load_template(mine, "nope")


def test_a_template_of_an_earlier_generation_loads_and_is_listed_as_such(db, tmp_path, capsys):
    copy = tmp_path / "db"
    shutil.copytree(db.path, copy, ignore=shutil.ignore_patterns("templates"))
    mine = MotionDB.open(copy)
    squat = learn_class(mine, "squat1Reps")
    store_template(mine, squat)
    newer = mine.append_motions([mine.motion(11)], [{"name": "again", "label": "squat1Reps", "actor": "dg"}])
    assert newer.manifest["generation"] == mine.manifest["generation"] + 1
    row = stored_templates(newer).iloc[0]
    assert row["generation"] == mine.manifest["generation"] and not row["current"]
    _same(load_template(newer, "squat1Reps"), squat)  # portable
    assert main(["template", "search", str(copy), "squat1Reps", "-K", "3"]) == 0
    assert "again" in capsys.readouterr().out  # the appended copy is found


def test_a_damaged_stored_template_is_named(db, tmp_path, capsys):
    copy = tmp_path / "db"
    shutil.copytree(db.path, copy, ignore=shutil.ignore_patterns("templates"))
    mine = MotionDB.open(copy)
    path = store_template(mine, learn_class(mine, "squat1Reps", actors=["mm"]))
    path.write_bytes(path.read_bytes()[:-40])
    for call in (lambda: load_template(mine, "squat1Reps-mm"), lambda: stored_templates(mine)):
        with pytest.raises(MotionDBError, match="squat1Reps-mm.npz"):
            call()
    assert main(["template", "search", str(copy), "squat1Reps-mm"]) == 1
    assert "squat1Reps-mm.npz" in _error(capsys)
    assert main(["check", str(copy)]) == 1  # `mocapviz check` reads the stored templates too
    out = capsys.readouterr().out
    assert "templates/squat1Reps-mm.npz" in out and "DAMAGED" in out


# ------------------------------------------------------------------ template:NAME never reaches outside the DB
@contextlib.contextmanager
def _opened_files():
    """The paths ``open`` is asked for inside the block (an audit hook: builtins.open, io.open, os.open, np.load)."""
    seen: list[str] = []
    _OPENED.append(seen)
    try:
        yield seen
    finally:
        _OPENED.remove(seen)


_OPENED: list[list[str]] = []
sys.addaudithook(lambda name, args: [seen.append(str(args[0])) for seen in _OPENED] if name == "open" else None)


def _refused(db, name: str) -> str:
    """The message of ``find(db, "template:NAME")``, with NAME in it replaced by ``<NAME>``; neither the file NAME
    nor NAME.npz is opened."""
    with _opened_files() as opened, pytest.raises(DescriptionError) as err:
        find(db, f"template:{name} then kick_left within 2 s")
    forbidden = {Path(name).resolve(), Path(f"{name}.npz").resolve()}
    assert not [p for p in opened if Path(p).resolve() in forbidden], opened
    message = str(err.value)
    stored = ", ".join(sorted(stored_templates(db)["name"]))
    assert message == (f"no stored template {name!r} in {db.path}; stored: {stored} (`mocapviz template learn "
                       f"{db.path} --label CLASS` stores one)")  # fmt: skip
    return message.replace(repr(name), "<NAME>")


def test_a_template_name_is_a_stored_template_never_a_path(db, kick, tmp_path, capsys, monkeypatch):
    """Issue 37's reproducers: `template:/elsewhere/t.npz` was loaded and searched, `template:/etc/ld.so.conf` opened,
    `template:DB/positions.g0.npy` an untyped TypeError, and the messages told existing from missing files. Now every
    refused or unknown name is the one message, the same whether a file of that name exists or not (paths relative
    to the working directory, as the reproducers are written, so that they fit the language's 80-character names)."""
    monkeypatch.chdir(tmp_path)
    kick.save(tmp_path / "t.npz")  # a real template outside the database
    rel = os.path.relpath(db.path, tmp_path)
    existing = ["t.npz", "/etc/ld.so.conf", f"{rel}/positions.g0.npy", f"{rel}/templates/kickLFront1Reps-dg.npz",
                f"{rel}/templates", f"./{rel}/manifest.json"]
    assert all(Path(p).exists() for p in existing) and template_path(db, "kickLFront1Reps-dg").is_file()
    missing = ["u.npz", "/etc/no-such.conf", f"{rel}/positions.g9.npy", f"{rel}/templates/nope.npz",
               "kickLFront1Reps-dg.npz", f"{rel}/templates/kickLFront1Reps-dg", "nope", "-", "a" * 71]
    messages = {_refused(db, name) for name in existing + missing}
    assert len(messages) == 1, messages
    assert main(["find", str(db.path), "template:/etc/ld.so.conf"]) == 1
    assert _error(capsys) == f"mocapviz: error: {_refused(db, '/etc/ld.so.conf').replace('<NAME>', repr('/etc/ld.so.conf'))}"
    with _opened_files() as opened:  # the stored name still works, and the hook sees what is opened
        assert len(find(db, "template:kickLFront1Reps-dg", template_cost=0.2)) > 0
    assert str(template_path(db, "kickLFront1Reps-dg")) in opened


def test_template_file_route_from_the_command_line(db, kick, tmp_path, capsys):
    """`find DB TEXT --template-file NAME=FILE` brings a learned template from a file (never stored here) under a
    name; the same hits as the same template passed to find, and as it stored with the database."""
    out = tmp_path / "squat.npz"
    assert main(["template", "learn", str(db.path), "--label", "squat1Reps", "--actors", "mm", "--out", str(out)]) == 0
    capsys.readouterr()
    squat = MotionTemplate.load(out)
    text = "template:mine then template:kick within 4 s | template:mine"
    with pytest.raises(DescriptionError, match="no stored template 'mine'"):
        find(db, text)
    expected = find(db, text, templates={"mine": squat, "kick": kick}, template_cost=0.3)
    assert len(expected) > 0 and expected["parts"].str.contains("template:mine").all()
    csv = tmp_path / "hits.csv"
    kick_file = tmp_path / "kick.npz"
    kick.save(kick_file)
    assert main(["find", str(db.path), text, "--template-file", f"mine={out}", "--template-file",
                 f"kick={kick_file}", "--template-cost", "0.3", "-K", "1000", "--csv", str(csv)]) == 0  # fmt: skip
    assert f"{len(expected)} hits" in capsys.readouterr().out
    got = pd.read_csv(csv)
    assert got[["doc_id", "start", "end"]].equals(expected[["doc_id", "start", "end"]].reset_index(drop=True))
    stored = find(db, text.replace("mine", "squat1Reps-mm").replace("template:kick ", "template:kickLFront1Reps-dg "),
                  template_cost=0.3)  # fmt: skip
    assert stored[["doc_id", "start", "end"]].equals(expected[["doc_id", "start", "end"]])
    for bad, says in [(f"{out}", "give NAME=FILE"), (f"../x={out}", "give NAME=FILE"),
                      (f"mine={tmp_path / 'none.npz'}", "--template-file mine: "),
                      (f"mine={Path(db.path) / 'positions.g0.npy'}", "not a readable motion template (not an .npz")]:
        assert main(["find", str(db.path), "template:mine", "--template-file", bad]) == 1
        assert says in _error(capsys), bad
    # the engine hands the file's templates to its shards: the same hits on a local cluster
    assert main(["find", str(db.path), text, "--template-file", f"mine={out}", "--template-file",
                 f"kick={kick_file}", "--template-cost", "0.3", "-K", "1000", "--scheduler", "local"]) == 0  # fmt: skip
    assert f"{len(expected)} hits" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------- all of HDM05 (30 Hz)
def test_a_template_of_four_actors_finds_the_fifth_actors_instances(hdm05_db30, tmp_path, capsys):
    """Learned from bd, bk, dg and mm via the CLI, the squat template's best hits in the whole database are the
    squats, those of the fifth actor, tr, among them."""
    db = MotionDB.open(shutil.copytree(hdm05_db30.path, tmp_path / "db"))
    assert main(["template", "learn", str(db.path), "--label", "squat1Reps", "--actors", "bd,bk,dg,mm"]) == 0
    capsys.readouterr()
    squats = db.documents[db.documents["label"] == "squat1Reps"]
    k = len(squats)
    csv = tmp_path / "hits.csv"
    assert main(["template", "search", str(db.path), "squat1Reps-bd-bk-dg-mm", "-K", str(k), "--csv", str(csv)]) == 0
    got = pd.read_csv(csv)
    values = relational_features(db, "2006", progress=False)[0]
    hits = find_instances(load_template(db, "squat1Reps-bd-bk-dg-mm"), values, db.documents["start"].to_numpy(),
                          n_matches=k)  # fmt: skip
    np.testing.assert_allclose(got["cost"], hits["cost"])
    assert got["doc_id"].tolist() == db.documents["doc_id"].to_numpy()[hits["doc_id"]].tolist()
    # measured: the 52 best hits are the 52 squats, one each, the 12 of tr among them
    assert sorted(got["doc_id"]) == sorted(squats["doc_id"]), got.loc[got["label"] != "squat1Reps", ["name", "cost"]]
    assert (got["actor"] == "tr").sum() == (squats["actor"] == "tr").sum() == 12
