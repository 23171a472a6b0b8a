"""The `mocapviz` command: ingest, info, datasets; one-line errors with non-zero exit."""
from __future__ import annotations

import collections
import contextlib
import io
import os
import shlex
import shutil
import subprocess
import sys
import traceback
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

from mocapviz import MotionDB
from mocapviz.cli import database as cli_database
from mocapviz.cli import main
from mocapviz.io import datasets

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def sample_dir() -> Path:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    return datasets.sample()


def test_ingest_then_info(sample_dir, tmp_path, capsys):
    out = tmp_path / "db"
    assert main(["ingest", str(sample_dir / "hdm05-cut"), "--out", str(out), "--fps", "30", "--quiet"]) == 0
    assert "22 documents" in capsys.readouterr().out
    db = MotionDB.open(out)
    assert main(["info", str(out), "--documents"]) == 0
    text = capsys.readouterr().out
    total = next(line for line in text.splitlines() if line.startswith("total")).split()
    assert int(total[1]) == 22 and int(total[2]) == db.n_frames
    assert all(name in text for name in db.documents["name"])


def test_datasets_list_and_fetch_sample(capsys):
    assert main(["datasets", "list"]) == 0
    text = capsys.readouterr().out
    for name in ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2", "c3d-markers"):
        assert name in text
    assert main(["datasets", "fetch", "sample"]) == 0
    assert Path(capsys.readouterr().out.strip()) == datasets.sample()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["info", "/nonexistent/db"], "/nonexistent/db: does not exist"),
        (["ingest", "/nonexistent/*.amc", "--out", "{tmp}/db"], "no .amc, .bvh, .c3d or .fbx file matches this pattern"),
        (["ingest", "/nonexistent", "--out", "{tmp}/db"], "/nonexistent: does not exist"),
        (["ingest", "{tmp}/empty", "--out", "{tmp}/db"], "empty: no .amc, .bvh, .c3d or .fbx files in this folder"),
        (["datasets", "fetch", "no-such-archive"], "no-such-archive"),
        (["ingest", "{bad}", "--out", "{tmp}/db2", "--quiet"], "line 4: OFFSET needs three"),
    ],
)
def test_errors_are_one_line_and_exit_1(argv, needle, tmp_path, sample_dir, capsys, monkeypatch):
    if argv[0] == "ingest" and "{bad}" not in argv:  # bad arguments are refused before any Dask cluster starts
        monkeypatch.setattr(cli_database, "dask_client",
                            lambda *a, **k: pytest.fail("a cluster started on an error path"))
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    (tmp_path / "empty").mkdir()
    argv = [a.format(tmp=tmp_path, bad=bad) for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err


def test_a_busy_dask_dashboard_port_adds_no_line_to_an_error(tmp_path, capsys):
    """Another cluster on the machine holds Dask's dashboard port (8787): the local cluster an ingest starts takes a
    free port silently, and the error stays one line (it was preceded by "Port 8787 is already in use" and two more
    lines when two mocapviz commands ran at once)."""
    import socket

    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    with socket.socket() as busy:
        try:
            busy.bind(("", 8787))
            busy.listen()
        except OSError:  # already held by something else: the condition this test makes
            pass
        assert main(["ingest", str(bad), "--out", str(tmp_path / "db"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and "line 4: OFFSET needs three" in err and "\n" not in err, err


def test_a_count_of_one_takes_the_singular(sample_db, capsys):
    """issue 39: "1 matches", "1 frames", "1 examples": a count the commands print agrees with its word."""
    assert main(["knn", str(sample_db.path), "--frame", "7:10", "-k", "1"]) == 0
    assert capsys.readouterr().out.startswith("1 neighbour of document 7 frame 10 by F15E")
    assert main(["search", str(sample_db.path), "--example", "7", "-K", "1"]) == 0
    assert capsys.readouterr().out.startswith("1 clip like 7 (")
    assert main(["find", str(sample_db.path), "kick_left", "-K", "1"]) == 0
    assert capsys.readouterr().out.startswith("1 hit in ")


def test_console_script_runs_as_module(sample_dir, tmp_path):
    """The same command through a fresh interpreter (as the installed `mocapviz` script runs it)."""
    res = subprocess.run([sys.executable, "-m", "mocapviz.cli", "info", str(tmp_path)], capture_output=True, text=True, check=False)
    assert res.returncode == 1 and res.stderr.count("\n") == 1 and "not a MotionDB" in res.stderr


@pytest.fixture(scope="module")
def sample_db(sample_dir, tmp_path_factory) -> MotionDB:
    out = tmp_path_factory.mktemp("cli") / "db30"
    assert main(["ingest", str(sample_dir), "--out", str(out), "--fps", "30", "--quiet"]) == 0
    return MotionDB.open(out)


def _table(text: str) -> list[list[str]]:
    """Rows of the neighbour table printed by `mocapviz knn` (after its header lines), split on whitespace."""
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if line.split()[:2] == ["rank", "doc_id"])
    return [line.split() for line in lines[head + 1 :]]


def test_features_then_knn_prints_the_index_answer(sample_db, capsys):
    """`mocapviz features` stores every numeric set; `mocapviz knn` prints the neighbours KnnIndex finds."""
    from mocapviz.features import NUMERIC_SETS, load_numeric
    from mocapviz.similarity.knn import KnnIndex

    assert main(["features", str(sample_db.path), "--quiet"]) == 0
    capsys.readouterr()
    stored = {n: load_numeric(sample_db, n) for n in NUMERIC_SETS}  # raises if missing or stale
    assert all(a.shape[0] == sample_db.n_frames for a in stored.values())

    doc = int(sample_db.select(label="squat1Reps")["doc_id"].iloc[0])
    span = sample_db.frames(doc)
    assert main(["knn", str(sample_db.path), "--frame", f"{doc}:12", "-k", "7", "--numeric-set", "F30E",
                 "--exclude-document"]) == 0  # fmt: skip
    rows = _table(capsys.readouterr().out)
    valid = np.ones(sample_db.n_frames, bool)
    valid[span] = False
    d, i = KnnIndex(stored["F30E"], valid=valid).query(stored["F30E"][span.start + 12], 7)
    assert [int(r[0]) for r in rows] == list(range(1, 8))
    assert [int(r[1]) for r in rows] == sample_db.document_of(i).tolist()
    assert all(int(r[1]) != doc for r in rows)
    np.testing.assert_allclose([float(r[5]) for r in rows], d, atol=1e-3)


def test_knn_radius_prints_only_neighbours_within_it(sample_db, capsys):
    doc = int(sample_db.documents["doc_id"].iloc[-1])
    assert main(["knn", str(sample_db.path), "--frame", f"{doc}:5", "-k", "50", "--radius", "4",
                 "--no-exclude-document"]) == 0  # fmt: skip
    rows = _table(capsys.readouterr().out)
    assert 1 <= len(rows) < 50 and rows[0][3] == "5" and float(rows[0][5]) == 0.0
    assert all(float(r[5]) < 4 for r in rows)


@pytest.mark.parametrize(
    "args, needle, status",
    [
        (["--frame", "0:100000"], "document 0 has frames 0..", 1),
        (["--frame", "3"], "DOC:FRAME", 2),
        (["--frame", "999:0"], "no document 999", 1),
        (["--frame", "0:1", "--numeric-set", "F16E"], "unknown numeric set F16E", 2),
        (["--frame", "0:1", "-k", "0"], "-k must be at least 1", 2),
        (["--frame", "0:1", "-k", "100000"], "k must be between 1", 1),
    ],
)
def test_knn_errors_are_one_line(sample_db, args, needle, status, capsys):
    assert main(["knn", str(sample_db.path), *args, "--quiet"]) == status
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err


def test_skip_bad_and_label_table_from_the_command_line(sample_dir, tmp_path, capsys):
    """--skip-bad turns a bad file into one warning line; --labels replaces the labels found beside the data."""
    src = tmp_path / "clips"
    src.mkdir()
    (src / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    good = next((sample_dir / "hdm05-cut" / "amc").glob("*.amc"))
    table = tmp_path / "labels.csv"
    table.write_text(f"file,label,mood\n{good.name},my-label,calm\n")
    out = tmp_path / "db"
    assert main(["ingest", str(src), str(good), "--out", str(out), "--skip-bad", "--labels", str(table),
                 "--quiet"]) == 0  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mocapviz: warning: skipped") and "broken.bvh, line 4" in err[0]
    docs = MotionDB.open(out).documents
    assert docs["name"].tolist() == [good.stem] and docs["label"].tolist() == ["my-label"]
    assert docs["mood"].tolist() == ["calm"]


def test_ingest_prints_the_format_warnings_of_each_file(sample_dir, tmp_path, capsys):
    """A file read with a frame left out is named, with the line, in one warning line (reader threads)."""
    from test_database import cut_in_last_frame

    src = shutil.copytree(sample_dir / "cmu-asfamc", tmp_path / "cmu")
    cut = next((src / "amc").rglob("131_01.amc"))
    line = cut_in_last_frame(cut)
    assert main(["ingest", str(src), "--out", str(tmp_path / "db"), "--no-cluster", "--jobs", "2", "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mocapviz: warning: {cut.resolve()}, line {line}: last frame "), err
    assert err[0].endswith("is incomplete (no line for bone 'lfemur': the file ends inside it); dropped it")


def test_operating_system_errors_are_one_line(sample_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli_database, "dask_client",
                        lambda *a, **k: pytest.fail("a cluster started on an error path"))
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["ingest", str(sample_dir / "cmu-asfamc"), "--out", str(blocker / "db"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and "\n" not in err


def test_match_prints_the_library_matches(sample_db, capsys):
    """`mocapviz match` with a document of the DB as the example: the graph's (and subsequence DTW's) matches
    outside that document, as :func:`mocapviz.match.lng` / ``subsequence_dtw`` find them."""
    from mocapviz.features import load_numeric
    from mocapviz.match import lng, subsequence_dtw
    from mocapviz.similarity.knn import KnnIndex

    assert main(["features", str(sample_db.path), "--numeric-sets", "F15E", "--quiet"]) == 0
    capsys.readouterr()
    X = load_numeric(sample_db, "F15E")
    starts = sample_db.documents["start"].to_numpy()
    doc = int(sample_db.select(label="squat1Reps")["doc_id"].iloc[0])
    span = sample_db.frames(doc)
    q = X[span.start + 5 : span.start + 35]
    assert main(["match", str(sample_db.path), "--example", str(doc), "--frames", "5:35", "-K", "4", "-k", "256"]) == 0
    rows = _table(capsys.readouterr().out)
    ref = lng(q, KnnIndex(X), k=256, n_matches=4, starts=starts, exclude=[span.start, span.stop])
    assert len(rows) == len(ref) >= 1
    assert [int(r[1]) for r in rows] == ref["doc_id"].tolist()
    assert [int(r[3]) for r in rows] == (ref["start"] - starts[ref["doc_id"]]).tolist()
    np.testing.assert_allclose([float(r[8]) for r in rows], ref["cost"], atol=1e-3)  # after frames, start_s, end_s

    assert main(["match", str(sample_db.path), "--example", str(doc), "--frames", "5:35", "-K", "3", "--method",
                 "dtw", "--paths"]) == 0  # fmt: skip
    text = capsys.readouterr().out
    ref = subsequence_dtw(q, X, starts, n_matches=20)
    ref = ref[ref["doc_id"] != doc].head(3)
    rows = _table(text.split("\npath 1")[0])
    assert [int(r[4]) for r in rows] == (ref["end"] + 1 - starts[ref["doc_id"]]).tolist()  # end: half-open
    first = ref["path"].iloc[0]
    assert f"0:{first[0, 1] - starts[ref['doc_id'].iloc[0]]} " in text.split("\npath 1")[1]


def test_match_keeps_matches_of_at_least_min_length_and_knn_one_row_per_document(sample_db, capsys):
    """`mocapviz match` gives the graph (and subsequence DTW) the similarity search's shortest match (--min-length,
    default 0.5 of the query): a whole kick found 1-frame "matches" without it. `mocapviz knn --per-document`
    prints each document once."""
    assert main(["features", str(sample_db.path), "--numeric-sets", "F15E", "--quiet"]) == 0
    capsys.readouterr()
    shortest = -(-int(sample_db.document(7)["n_frames"]) // 2)  # half the query, rounded up
    frames = {}
    for option in (["-k", "1024"], ["-k", "1024", "--min-length", "0.01"], ["--method", "dtw"]):
        assert main(["match", str(sample_db.path), "--example", "7", "-K", "10", *option]) == 0
        frames[option[-1]] = [int(r[5]) for r in _table(capsys.readouterr().out)]
    assert frames["1024"] and min(frames["1024"]) >= shortest
    assert min(frames["0.01"]) < shortest  # the old answer: short "matches"
    assert frames["dtw"] and min(frames["dtw"]) >= shortest
    assert main(["match", str(sample_db.path), "--example", "7", "--min-length", "0"]) == 2
    assert "--min-length must be a number in (0, 1]" in capsys.readouterr().err

    assert main(["knn", str(sample_db.path), "--frame", "7:10", "-k", "300", "--per-document",
                 "--no-exclude-document"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    docs = [int(r[1]) for r in _table(out)]
    assert len(docs) == len(set(docs)) > 1 and docs[0] == 7 and "one row per document" in out
    assert main(["knn", str(sample_db.path), "--frame", "7:10", "-k", "300", "--per-document"]) == 0
    assert 7 not in [int(r[1]) for r in _table(capsys.readouterr().out)]  # by default, without its own document


def test_match_errors_are_one_line(sample_dir, sample_db, tmp_path, capsys):
    bare = tmp_path / "bare"
    assert main(["ingest", str(sample_dir / "hdm05-cut"), "--out", str(bare), "--fps", "30", "--quiet"]) == 0
    cases = [
        ([str(bare), "--example", "0"], "run `mocapviz features DB`"),
        ([str(sample_db.path), "--example", "0", "--frames", "5:6"], "at least 2 frames"),
        ([str(sample_db.path), "--example", "0", "-k", "100000"], "k must be between 1"),
    ]
    main(["features", str(sample_db.path), "--numeric-sets", "F15E", "--quiet"])
    capsys.readouterr()
    for args, needle in cases:
        assert main(["match", *args]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err, (args, err)


def test_malformed_option_values_are_one_line_errors(sample_db, tmp_path, capsys):
    """Values the command parses itself (a JSON mapping, a list of integers) give typed one-line errors; the command
    catches only mocapviz's typed errors and OSError, so anything else would be a bug with a traceback."""
    mapping = tmp_path / "mapping.json"
    mapping.write_text("{not json")
    cases = [
        (["ingest", str(tmp_path), "--out", str(tmp_path / "db"), "--mapping", str(mapping)], "not JSON"),
        (["query", str(sample_db.path), "--example", "0", "--features", "rknee_bent", "--mismatch", "1",
          "--mismatch-at", "x"], "--mismatch-at must be comma-separated integers"),
    ]
    for argv, needle in cases:
        assert main(argv) == (1 if argv[0] == "ingest" else 2)  # the parser refuses --mismatch-at x
        err = capsys.readouterr().err.strip()
        assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err


# ------------------------------------------------------------------------------ every bad value: one line, never run
# Each row: a command line with a bad value, the words its one error line must hold (the option and the allowed range
# or values), and the exit status: 2 when the argument parser refuses it (syntax, range, names), 1 when the command
# does (a value checked against the database or the clip: frames of a document, the query's segments, k neighbours).
# Placeholders: {db} the demo database (2005 indexes, F15E and F30E stored), {clip} a real AMC file of the sample,
# {out} a fresh output folder, {missing} a path that does not exist, {text} a text file, {notjson} / {listjson} /
# {badjoint} --mapping files. `python tests/test_cli.py` counts the outcomes of every row (see `tally`).
INGEST = "ingest {clip} --out {out} --no-cluster --quiet"
QUERY = "query {db} --example 11 --features rknee_bent,lknee_bent"  # a squat: 4 segments on these features
KNN = "knn {db} --frame 0:1 --quiet"
MATCH = "match {db} --example 0 --frames 0:30"
SEARCH = "search {db} --example 0 --frames 0:30"
BAD_VALUES = [
    (f"{INGEST} --fps 0", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps -30", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps x", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps nan", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps inf", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps 100000", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --fps ''", ["--fps", "[1, 10000]"], 2),
    (f"{INGEST} --jobs 0", ["--jobs", "between 1 and 256"], 2),
    (f"{INGEST} --jobs -1", ["--jobs", "between 1 and 256"], 2),
    (f"{INGEST} --jobs x", ["--jobs", "between 1 and 256"], 2),
    (f"{INGEST} --jobs 2.5", ["--jobs", "between 1 and 256"], 2),
    (f"{INGEST} --jobs 100000", ["--jobs", "between 1 and 256"], 2),
    (f"{INGEST} --up x", ["--up", "'auto', 'y', 'z'"], 2),
    (f"{INGEST} --mapping {{missing}}", ["--mapping", "missing"], 1),
    (f"{INGEST} --mapping {{notjson}}", ["--mapping", "not JSON"], 1),
    (f"{INGEST} --mapping {{listjson}}", ["--mapping", "JSON object"], 1),
    (f"{INGEST} --mapping {{badjoint}}", ["--mapping", "nosuchjoint", "lknee"], 1),
    (f"{INGEST} --labels {{missing}}", ["--labels", "missing"], 1),
    (f"{INGEST} --asf {{missing}}", ["--asf", "missing"], 1),
    (f"{INGEST} --asf {{text}}", ["--asf", "text.txt"], 1),
    ("ingest {missing} --out {out} --no-cluster", ["missing: does not exist"], 1),
    ("ingest {clip} --out {text}/db --no-cluster", ["--out", "is a file"], 1),
    ("ingest {clip} --out {out} --scheduler '' --quiet", ["--scheduler", "tcp://"], 2),
    ("ingest {clip} --out {out} --scheduler tcp://127.0.0.1:1 --no-cluster", ["exclude each other"], 1),
    ("ingest {clip} --out {out} --scheduler tcp://127.0.0.1:1 --jobs 2", ["--jobs"], 1),
    ("info {missing}", ["missing: does not exist"], 1),
    ("info {clip}", ["not a MotionDB"], 1),
    ("index {db} --relational-set 2007 --no-cluster", ["--relational-set", "'2005', '2006'"], 2),
    ("index {db} --feature-set 2007 --no-cluster", ["--feature-set", "'2005', '2006'"], 2),
    ("index {missing} --no-cluster --quiet", ["missing: does not exist"], 1),
    ("index {db} --scheduler '' --quiet", ["--scheduler", "tcp://"], 2),
    ("index {db} --scheduler 'tcp://a b' --quiet", ["--scheduler", "tcp://"], 2),
    (f"{QUERY} -K -5", ["-K", "at least 1"], 2),
    (f"{QUERY} --top -5", ["--top", "at least 1"], 2),
    (f"{QUERY} --matches 0", ["--matches", "at least 1"], 2),
    (f"{QUERY} -K x", ["-K", "at least 1"], 2),
    (f"{QUERY} -K 2,3", ["-K", "at least 1"], 2),
    (f"{QUERY} --mismatch -1", ["--mismatch", "at least 0"], 2),
    (f"{QUERY} --mismatch x", ["--mismatch", "at least 0"], 2),
    (f"{QUERY} --mismatch 99", ["--mismatch", "between 0 and 3", "4 segment(s)"], 1),
    (f"{QUERY} --mismatch 4", ["--mismatch", "between 0 and 3", "4 segment(s)"], 1),
    (f"{QUERY} --mismatch 1 --mismatch-at x", ["--mismatch-at", "integers"], 2),
    (f"{QUERY} --mismatch 1 --mismatch-at ''", ["--mismatch-at", "integers"], 2),
    (f"{QUERY} --mismatch 1 --mismatch-at -1", ["--mismatch-at", "from 0"], 2),
    (f"{QUERY} --mismatch 1 --mismatch-at 99", ["--mismatch-at", "from 0 to 3"], 1),
    (f"{QUERY} --mismatch 1 --mismatch-at 1,4", ["--mismatch-at", "from 0 to 3", "got 4"], 1),
    (f"{QUERY} --mismatch-at 0", ["--mismatch-at", "--mismatch"], 1),
    (f"{QUERY} --mismatch 1 --mode fuzzy", ["--mismatch", "--mode fuzzy"], 1),
    (f"{QUERY} --frames 0:999999", ["frames 0:999999", "document 11", "frames 0.."], 1),
    (f"{QUERY} --frames 5:6", ["frames 5:6", "at least 2 frames"], 1),
    (f"{QUERY} --frames 10:5", ["--frames", "A < B"], 2),
    (f"{QUERY} --frames a:b", ["--frames", "A:B"], 2),
    (f"{QUERY} --frames 5", ["--frames", "A:B"], 2),
    (f"{QUERY} --frames 0:1:2", ["--frames", "A:B"], 2),
    (f"{QUERY} --frames=-5:10", ["--frames -5:10: frames count from 0"], 2),
    (f"{QUERY} --frames -5:10", ["--frames -5:10: frames count from 0"], 2),
    (f"{QUERY} --frames ''", ["--frames", "A:B"], 2),
    ("query {db} --example 0 --features nosuch", ["unknown feature(s) 'nosuch'", "rknee_bent"], 1),
    ("query {db} --example 0 --features ''", ["--features", "rknee_bent"], 1),
    ("query {db} --example 0 --features ,", ["--features", "rknee_bent"], 1),
    (f"{QUERY} --mode x", ["--mode", "exact, fuzzy, adaptive, mismatch"], 2),
    (f"{QUERY} --relational-set 2007", ["--relational-set", "2005, 2006"], 2),
    ("query {db} --example 9999", ["--example 9999", "doc ids 0.."], 1),
    ("query {db} --example -1", ["--example -1", "doc ids 0.."], 1),
    ("query {db} --example {missing}", ["--example", "missing", "doc ids 0.."], 1),
    ("query {db} --example {clip} --frames 0:999999", ["frames 0:999999", "HDM_", "frames 0.."], 1),
    ("query {db} --frames 0:10", ["--example"], 2),
    ("features {db} --numeric-sets F16E --no-cluster --quiet", ["--numeric-sets", "F16E", "F15E"], 2),
    ("features {db} --numeric-sets '' --no-cluster --quiet", ["--numeric-sets", "F15E"], 2),
    ("features {db} --numeric-sets , --no-cluster --quiet", ["--numeric-sets", "F15E"], 2),
    ("features {db} --sets F15E,,F30E --no-cluster --quiet", ["--sets", "F15E"], 2),
    ("features {db} --numeric-sets Fp8 --pca {missing} --no-cluster --quiet", ["--pca", "missing"], 1),
    ("features {db} --numeric-sets Fp8 --pca {text} --no-cluster --quiet", ["--pca", "text.txt"], 1),
    ("features {db} --numeric-sets F15E --pca {clip} --no-cluster --quiet", ["--pca", "Fp8"], 1),
    ("features {db} --numeric-sets F15E --scheduler '' --quiet", ["--scheduler", "tcp://"], 2),
    ("knn {db} --frame 0:100000 --quiet", ["--frame", "document 0 has frames 0.."], 1),
    ("knn {db} --frame 3 --quiet", ["--frame", "DOC:FRAME"], 2),
    ("knn {db} --frame a:b --quiet", ["--frame", "DOC:FRAME"], 2),
    ("knn {db} --frame '' --quiet", ["--frame", "DOC:FRAME"], 2),
    ("knn {db} --frame 0:-1 --quiet", ["--frame", "from 0"], 2),
    ("knn {db} --frame=-1:0 --quiet", ["--frame", "from 0"], 2),
    ("knn {db} --frame 999:0 --quiet", ["--frame", "no document 999"], 1),
    (f"{KNN} --numeric-set F15E,F30E", ["--numeric-set", "one", "F15E,F30E"], 2),
    (f"{KNN} --features F15E,F30E", ["--features", "one", "F15E,F30E"], 2),
    (f"{KNN} --numeric-set F16E", ["--numeric-set", "F16E", "F30E"], 2),
    (f"{KNN} --numeric-set ''", ["--numeric-set", "F30E"], 2),
    (f"{KNN} -k 0", ["-k", "at least 1"], 2),
    (f"{KNN} -k -1", ["-k", "at least 1"], 2),
    (f"{KNN} -k x", ["-k", "at least 1"], 2),
    (f"{KNN} -k 100000000", ["k must be between 1 and the number of indexed frames"], 1),
    (f"{KNN} --radius 0", ["--radius", "> 0"], 2),
    (f"{KNN} --radius -2", ["--radius", "> 0"], 2),
    (f"{KNN} --radius nan", ["--radius", "> 0"], 2),
    (f"{KNN} --radius x", ["--radius", "> 0"], 2),
    (f"{KNN} --eps -1", ["--eps", ">= 0"], 2),
    (f"{KNN} --eps nan", ["--eps", ">= 0"], 2),
    (f"{KNN} --eps inf", ["--eps", ">= 0"], 2),
    (f"{MATCH} -K -3 --method dtw", ["-K", "at least 1"], 2),
    (f"{MATCH} -K 0", ["-K", "at least 1"], 2),
    (f"{MATCH} --matches x", ["--matches", "at least 1"], 2),
    (f"{MATCH} -k 0", ["-k", "at least 1"], 2),
    (f"{MATCH} -k -3", ["-k", "at least 1"], 2),
    (f"{MATCH} -k 100000000", ["k must be between 1 and the number of indexed frames"], 1),
    (f"{MATCH} -k 64 --method dtw", ["-k", "--method lng"], 1),
    (f"{MATCH} --radius 5 --method dtw", ["--radius", "--method lng"], 1),
    (f"{MATCH} --radius -2", ["--radius", "> 0"], 2),
    (f"{MATCH} --eps -1", ["--eps", ">= 0"], 2),
    (f"{MATCH} --numeric-set F15E,F30E", ["--numeric-set", "one", "F15E,F30E"], 2),
    (f"{MATCH} --numeric-set F16E", ["--numeric-set", "F16E", "F30E"], 2),
    (f"{MATCH} --method x", ["--method", "lng, dtw"], 2),
    ("match {db} --example 0 --frames 0:999999", ["frames 0:999999", "document 0", "frames 0.."], 1),
    ("match {db} --example 0 --frames 5:6", ["frames 5:6", "at least 2 frames"], 1),
    ("match {db} --example 9999", ["--example 9999", "doc ids 0.."], 1),
    ("match {db} --example {missing}", ["--example", "missing", "doc ids 0.."], 1),
    ("match {db} --example {clip} --frames 0:999999", ["frames 0:999999", "HDM_", "frames 0.."], 1),
    (f"{SEARCH} -K -1", ["-K", "at least 1"], 2),
    (f"{SEARCH} -K 0", ["-K", "at least 1"], 2),
    (f"{SEARCH} -K x", ["-K", "at least 1"], 2),
    (f"{SEARCH} --stretches --min-length 0", ["--min-length", "(0, 1]"], 2),
    (f"{SEARCH} --stretches --min-length 1.5", ["--min-length", "(0, 1]"], 2),
    (f"{SEARCH} --stretches --min-length nan", ["--min-length", "(0, 1]"], 2),
    (f"{SEARCH} --stretches --min-length x", ["--min-length", "(0, 1]"], 2),
    (f"{SEARCH} --min-length 0.7", ["--min-length", "--stretches"], 1),
    (f"{SEARCH} --numeric-set F15E,F30E", ["--numeric-set", "one", "F15E,F30E"], 2),
    (f"{SEARCH} --mode x", ["--mode", "exact, fast, brute"], 2),
    (f"{SEARCH} --csv {{missing}}/hits.csv", ["--csv", "missing"], 1),
    ("search {db} --example 0 --frames 0:999999", ["frames 0:999999", "document 0", "frames 0.."], 1),  # the library's
    ("search {db} --example 0 --frames 5:6", ["frames 5:6", "at least 2 frames"], 1),
    ("search {db} --example 9999", ["--example 9999", "doc ids 0.."], 1),
    ("search {db} --example {missing}", ["--example", "missing", "doc ids 0.."], 1),
    ("reproduce nosuch --out {out}", ["unknown experiment(s)", "rank_correlations"], 1),
    ("serve {db} --port 0", ["--port", "from 1 to 65535"], 2),
    ("serve {db} --port -1", ["--port", "from 1 to 65535"], 2),
    ("serve {db} --port 70000", ["--port", "from 1 to 65535"], 2),
    ("serve {db} --port x", ["--port", "from 1 to 65535"], 2),
    ("serve {db} --address 0.0.0.0", ["--allow-origin", "HOST:PORT"], 1),
    ("serve {db} --address 0.0.0.0 --allow-origin '*'", ["--allow-origin", "'*'", "HOST:PORT"], 1),
    ("serve {db} --address 0.0.0.0 --allow-origin ''", ["--allow-origin", "HOST:PORT"], 1),
    ("serve {db} --address 0.0.0.0 --allow-origin http://host:5006", ["--allow-origin", "HOST:PORT"], 1),
    ("serve {db} --address 0.0.0.0 --allow-origin host:99999", ["--allow-origin host:99999", "1 to 65535"], 1),
    ("serve {missing}", ["missing: does not exist"], 1),
    ("export {db} --doc 7 --frames 0:500 --format bvh --out {out}", ["--frames 0:500", "document 7", "frames 0.."], 1),
    ("export {db} --doc 7 --frames 9:3 --format bvh --out {out}", ["--frames 9:3", "A < B"], 2),
    ("export {db} --doc x --format bvh --out {out}", ["--doc", "at least 0"], 2),
    ("export {db} --doc 999 --format bvh --out {out}", ["no document 999", "doc ids 0.."], 1),
    ("export {db} --doc 7 --format fbx --out {out}", ["--format", "'bvh', 'amc', 'glb'"], 2),
    ("export {db} --doc 7 --format bvh --rig x --out {out}", ["--rig", "'source', 'canonical'"], 2),
    ("export {db} --doc 7 --format amc --rig canonical --out {out}", ["format 'amc'", "'bvh' or 'glb'"], 1),
    ("export {db} --hits {missing} --format bvh --out {out}", ["missing", "cannot read it as CSV", "--csv FILE"], 1),
    ("export {db} --hits {text} --format bvh --out {out}", ["text.txt has no column doc_id, start, end", "--csv"], 1),
    ("export {db} --hits {text} --doc 7 --format bvh --out {out}", ["--doc", "not allowed with argument --hits"], 2),
    ("datasets get", ["action", "'list', 'fetch'"], 2),
    ("datasets fetch", ["NAME", "hdm05-cut"], 1),
    ("datasets fetch nosuch", ["unknown dataset 'nosuch'", "hdm05-cut"], 1),
    ("datasets list hdm05-cut", ["datasets list", "NAME"], 1),
]


class _WouldRun(BaseException):
    """Raised instead of starting a server or a Dask cluster: the command accepted its arguments."""


@contextlib.contextmanager
def _no_server_no_cluster():
    """`mocapviz.app.serve` and the Dask clients raise _WouldRun instead of serving or starting a cluster."""
    def would_run(*args, **kwargs):
        raise _WouldRun

    with mock.patch("mocapviz.app.serve", would_run), mock.patch.object(cli_database, "dask_client", would_run), \
            mock.patch("mocapviz.parallel.dask_client", would_run):  # fmt: skip
        yield


def run_cli(argv: list[str]) -> tuple[int | None, str, str]:
    """``mocapviz ARGV`` in this process: (exit status, stdout, stderr); status None when it ended in an uncaught
    exception (its traceback in stderr), 0 when it would have started a server or a cluster."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _no_server_no_cluster():
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
        except _WouldRun:
            status = 0
        except Exception:  # noqa: BLE001 - a bug: counted, with its traceback
            traceback.print_exc(file=err)
            status = None
    return status, out.getvalue(), err.getvalue()


def outcome(status: int | None, err: str) -> str:
    """"one-line error", "other error" (several lines, e.g. argparse's usage), "exit 0" or "traceback"."""
    if status is None:
        return "traceback"
    if status == 0:
        return "exit 0"
    lines = err.strip().splitlines()
    return "one-line error" if len(lines) == 1 and lines[0].startswith("mocapviz: error: ") else "other error"


def bad_value_paths(folder: Path, sample_dir: Path, db: Path) -> dict[str, str]:
    """The placeholders of BAD_VALUES, with the files they name written into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {"text": ("text.txt", "plain text\n"), "notjson": ("mapping.json", "{not json"),
             "listjson": ("list.json", "[1, 2]"), "badjoint": ("joints.json", '{"nosuchjoint": "Hips"}')}
    for name, content in files.values():
        (folder / name).write_text(content)
    clip = min((sample_dir / "hdm05-cut" / "amc").glob("*.amc"))
    return {"db": str(db), "clip": str(clip), "out": str(folder / "out"), "missing": str(folder / "missing"),
            **{key: str(folder / name) for key, (name, _) in files.items()}}


def tally(paths: dict[str, str], folder: Path) -> collections.Counter:
    """Outcome of every row of BAD_VALUES (each with its own --out folder), printed one per line."""
    counts: collections.Counter = collections.Counter()
    for i, (line, needles, _) in enumerate(BAD_VALUES):
        argv = [w.format(**{**paths, "out": str(folder / f"out{i}")}) for w in shlex.split(line)]
        status, _, err = run_cli(argv)
        what = outcome(status, err)
        if what == "one-line error" and not all(needle in err for needle in needles):
            what = "one-line error not naming the option and range"
        counts[what] += 1
        last = err.strip().splitlines()[-1] if err.strip() else ""
        print(f"{what:15} {status!s:4} {line}\n{'':20}{last[:160]}", flush=True)
    return counts


@pytest.fixture(scope="module")
def demo_db(sample_db, tmp_path_factory) -> Path:
    """A copy of the 30 Hz sample with its 2005 relational indexes and the F15E and F30E sets, as the demo has."""
    db = tmp_path_factory.mktemp("demo") / "sample.mdb"
    shutil.copytree(sample_db.path, db)
    assert main(["index", str(db), "--no-cluster", "--quiet"]) == 0
    assert main(["features", str(db), "--numeric-sets", "F15E,F30E", "--no-cluster", "--quiet"]) == 0
    return db


@pytest.mark.parametrize("line, needles, status", BAD_VALUES, ids=[row[0] for row in BAD_VALUES])
def test_every_bad_value_is_refused_in_one_line(line, needles, status, demo_db, sample_dir, tmp_path):
    paths = bad_value_paths(tmp_path, sample_dir, demo_db)
    got, out, err = run_cli([w.format(**paths) for w in shlex.split(line)])
    assert outcome(got, err) == "one-line error" and got == status, f"status {got}:\n{err}{out}"
    assert all(needle in err for needle in needles), (needles, err)


def test_values_in_range_are_applied_exactly(demo_db, capsys):
    """What is not refused runs as written: --mismatch up to the query's segments minus one (never capped), the
    listed --mismatch-at segments, a -K beyond the hits (all of them), an open-ended --frames span."""
    from mocapviz.relational.query import query_by_example

    db = MotionDB.open(demo_db)
    features = ["rknee_bent", "lknee_bent"]
    hits = query_by_example(db, db.motion(11), features, mode="mismatch", mismatches=3, allowed=[0, 3])
    assert main(["query", str(demo_db), "--example", "11", "--features", ",".join(features), "--mismatch", "3",
                 "--mismatch-at", "0,3", "-K", "100000", "--no-exclude-document"]) == 0  # fmt: skip (the kernel's hits)
    text = capsys.readouterr().out
    assert text.startswith(f"{len(hits)} hits in ") and "(mismatch, " in text
    assert len(_table(text)) == len(hits) > 2  # -K 100000: every hit, none cut
    assert main(["query", str(demo_db), "--example", "11", "--features", ",".join(features), "--mismatch", "3",
                 "--mismatch-at", "0,3", "--top", "2"]) == 0  # fmt: skip
    assert len(_table(capsys.readouterr().out)) == 2

    runs = []
    for frames in ("0:30", ":30"):
        assert main(["match", str(demo_db), "--example", "11", "--frames", frames, "--method", "dtw", "-K", "3"]) == 0
        out = capsys.readouterr().out
        runs.append((out.splitlines()[0].split(" in ")[0], _table(out)))
    assert runs[0] == runs[1] and len(runs[0][1]) == 3
    assert main(["match", str(demo_db), "--example", "11", "--frames", "10:", "--method", "dtw", "-K", "3"]) == 0
    assert "matches of a 30-frame query" in capsys.readouterr().out  # document 11 has 40 frames


@pytest.mark.parametrize(
    "address, allow, expected",
    [
        ("127.0.0.1", None, []),
        ("localhost", ["lab.example.org:8080"], ["lab.example.org:8080"]),
        ("::1", (), []),
        ("127.0.0.2", None, ["127.0.0.2:5006"]),
        ("0.0.0.0", ["myhost.example.org:5006"], ["myhost.example.org:5006"]),
        ("::", ["myhost.example.org:5006"], ["myhost.example.org:5006"]),
        ("192.168.1.5", ["192.168.1.5:5006", "lab"], ["192.168.1.5:5006", "lab"]),
        ("192.168.1.5", ["lab"], ["192.168.1.5:5006", "lab"]),
        ("fe80::1", ["[fe80::1]:5006"], ["[fe80::1]:5006"]),
        ("fe80::1", ["lab"], ["[fe80::1]:5006", "lab"]),
    ],
)
def test_websocket_origins_are_loopback_the_bound_address_and_the_listed_ones(address, allow, expected):
    from mocapviz.app import websocket_origins

    assert websocket_origins(address, 5006, allow) == ["127.0.0.1:5006", "localhost:5006", "[::1]:5006", *expected]


@pytest.mark.parametrize(
    "address, allow, needle",
    [
        ("0.0.0.0", None, "--allow-origin HOST:PORT"),
        ("::", [], "--allow-origin HOST:PORT"),
        ("192.168.1.5", None, "--allow-origin HOST:PORT"),
        ("0.0.0.0", ["*"], "--allow-origin '*': give HOST:PORT"),
        ("0.0.0.0", ["*.example.org:5006"], "without scheme, path or wildcard"),
        ("0.0.0.0", ["192.168.*.*:5006"], "without scheme, path or wildcard"),
        ("0.0.0.0", ["host:*"], "port of --allow-origin host:*"),
        ("0.0.0.0", ["https://host:5006"], "without scheme"),
        ("0.0.0.0", ["host:5006/path"], "without scheme, path"),
        ("127.0.0.1", ["host:0"], "from 1 to 65535"),
    ],
)
def test_websocket_origins_refuse_a_wildcard_or_no_list(address, allow, needle):
    from mocapviz.app import websocket_origins
    from mocapviz.errors import ParameterError

    with pytest.raises(ParameterError) as error:
        websocket_origins(address, 5006, allow)
    assert needle in str(error.value) and "\n" not in str(error.value)


def test_serve_passes_the_listed_origins_on(demo_db, monkeypatch, capsys):
    seen = {}
    monkeypatch.setattr("mocapviz.app.serve", lambda db, **options: seen.update(options, db=db))
    assert main(["serve", str(demo_db), "--address", "0.0.0.0", "--port", "5007", "--allow-origin",
                 "lab.example.org:5007", "--allow-origin", "10.0.0.7:5007"]) == 0  # fmt: skip
    assert seen["allow_origin"] == ["lab.example.org:5007", "10.0.0.7:5007"]
    assert (seen["db"], seen["address"], seen["port"]) == (str(demo_db), "0.0.0.0", 5007)
    assert "serving" in capsys.readouterr().out


if __name__ == "__main__":  # count the outcomes: python tests/test_cli.py (builds the demo database in a temp folder)
    import tempfile

    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    with tempfile.TemporaryDirectory() as scratch:
        db = Path(scratch) / "sample.mdb"
        for argv in (["ingest", str(datasets.sample()), "--out", str(db), "--fps", "30", "--no-cluster", "--quiet"],
                     ["index", str(db), "--no-cluster", "--quiet"],
                     ["features", str(db), "--numeric-sets", "F15E,F30E", "--no-cluster", "--quiet"]):
            assert run_cli(argv)[0] == 0, argv
        found = tally(bad_value_paths(Path(scratch) / "files", datasets.sample(), db), Path(scratch))
        print(f"{len(BAD_VALUES)} bad-value cases: " + ", ".join(f"{n} {what}" for what, n in found.most_common()))


def test_reproduce_help_names_every_experiment():
    """``mocapviz reproduce --help`` (a light parser that does not import the experiments) names each of them."""
    from mocapviz.reproduction import EXPERIMENTS

    done = subprocess.run([sys.executable, "-m", "mocapviz.cli", "reproduce", "--help"], capture_output=True, text=True,
                          check=True)  # fmt: skip
    text = " ".join(done.stdout.split())
    assert [name for name in EXPERIMENTS if name not in text] == []
