"""The `mocapviz` command: ingest, info, datasets; one-line errors with non-zero exit."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocapviz import MotionDB, cli, datasets
from mocapviz.cli import main

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
    for name in ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2"):
        assert name in text
    assert main(["datasets", "fetch", "sample"]) == 0
    assert Path(capsys.readouterr().out.strip()) == datasets.sample()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["info", "/nonexistent/db"], "not a MotionDB"),
        (["ingest", "/nonexistent/*.amc", "--out", "{tmp}/db"], "no .amc or .bvh files"),
        (["datasets", "fetch", "no-such-archive"], "no-such-archive"),
        (["ingest", "{bad}", "--out", "{tmp}/db2", "--quiet"], "line 4: OFFSET needs three"),
    ],
)
def test_errors_are_one_line_and_exit_1(argv, needle, tmp_path, sample_dir, capsys, monkeypatch):
    if argv[0] == "ingest" and "{bad}" not in argv:  # bad arguments are refused before any Dask cluster starts
        monkeypatch.setattr(cli, "dask_client", lambda *a, **k: pytest.fail("a cluster started on an error path"))
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    argv = [a.format(tmp=tmp_path, bad=bad) for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err


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
    from mocapviz.knn import KnnIndex

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
    assert main(["knn", str(sample_db.path), "--frame", f"{doc}:5", "-k", "50", "--radius", "4"]) == 0
    rows = _table(capsys.readouterr().out)
    assert 1 <= len(rows) < 50 and rows[0][3] == "5" and float(rows[0][5]) == 0.0
    assert all(float(r[5]) < 4 for r in rows)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--frame", "0:100000"], "document 0 has frames 0.."),
        (["--frame", "3"], "DOC:FRAME"),
        (["--frame", "999:0"], "no document 999"),
        (["--frame", "0:1", "--numeric-set", "F16E"], "unknown numeric set F16E"),
        (["--frame", "0:1", "-k", "0"], "k must be between 1"),
    ],
)
def test_knn_errors_are_one_line(sample_db, args, needle, capsys):
    assert main(["knn", str(sample_db.path), *args, "--quiet"]) == 1
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


def test_operating_system_errors_are_one_line(sample_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli, "dask_client", lambda *a, **k: pytest.fail("a cluster started on an error path"))
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["ingest", str(sample_dir / "cmu-asfamc"), "--out", str(blocker / "db"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocapviz: error:") and "\n" not in err


def test_match_prints_the_library_matches(sample_db, capsys):
    """`mocapviz match` with a document of the DB as the example: the graph's (and subsequence DTW's) matches
    outside that document, as :func:`mocapviz.match.lng` / ``subsequence_dtw`` find them."""
    from mocapviz.features import load_numeric
    from mocapviz.knn import KnnIndex
    from mocapviz.match import lng, subsequence_dtw

    assert main(["features", str(sample_db.path), "--numeric-sets", "F15E", "--quiet"]) == 0
    capsys.readouterr()
    X = load_numeric(sample_db, "F15E")
    starts = sample_db.documents["start"].to_numpy()
    doc = int(sample_db.select(label="squat1Reps")["doc_id"].iloc[0])
    span = sample_db.frames(doc)
    q = X[span.start + 5 : span.start + 35]
    assert main(["match", str(sample_db.path), "--example", str(doc), "--frames", "5:35", "-K", "4", "-k", "64"]) == 0
    rows = _table(capsys.readouterr().out)
    ref = lng(q, KnnIndex(X), k=64, n_matches=4, starts=starts, exclude=[span.start, span.stop])
    assert len(rows) == len(ref) >= 1
    assert [int(r[1]) for r in rows] == ref["doc_id"].tolist()
    assert [int(r[3]) for r in rows] == (ref["start"] - starts[ref["doc_id"]]).tolist()
    np.testing.assert_allclose([float(r[5]) for r in rows], ref["cost"], atol=1e-3)

    assert main(["match", str(sample_db.path), "--example", str(doc), "--frames", "5:35", "-K", "3", "--method",
                 "dtw", "--paths"]) == 0  # fmt: skip
    text = capsys.readouterr().out
    ref = subsequence_dtw(q, X, starts, n_matches=20)
    ref = ref[ref["doc_id"] != doc].head(3)
    rows = _table(text.split("\npath 1")[0])
    assert [int(r[4]) for r in rows] == (ref["end"] - starts[ref["doc_id"]]).tolist()
    first = ref["path"].iloc[0]
    assert f"0:{first[0, 1] - starts[ref['doc_id'].iloc[0]]} " in text.split("\npath 1")[1]


def test_match_errors_are_one_line(sample_dir, sample_db, tmp_path, capsys):
    bare = tmp_path / "bare"
    assert main(["ingest", str(sample_dir / "hdm05-cut"), "--out", str(bare), "--fps", "30", "--quiet"]) == 0
    cases = [
        ([str(bare), "--example", "0"], "run `mocapviz features DB`"),
        ([str(sample_db.path), "--example", "0", "--frames", "5:6"], "at least 2 frames"),
        ([str(sample_db.path), "--example", "0", "-k", "0"], "k must be between 1"),
        ([str(sample_db.path), "--example", "0", "--radius", "-2"], "radius must be a positive"),
        ([str(sample_db.path), "--example", "0", "--numeric-set", "F16E"], "unknown numeric set F16E"),
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
        assert main(argv) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("mocapviz: error:") and needle in err and "\n" not in err
