"""A MotionDB is never lost, duplicated or silently wrong: concurrent writers, kill -9 at random points, failed
ingests beside successful ones, and every kind of corrupted file — all with real processes on the embedded
sample's real clips (no shared archives needed)."""

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB, MotionDBError
from mocapviz.cli.database import run_check
from mocapviz.io import datasets


@pytest.fixture(scope="module")
def sample():
    return datasets.sample()


@pytest.fixture(scope="module")
def reference(sample, tmp_path_factory):
    """Every sample clip ingested once, serially: the frames each document must hold."""
    return MotionDB.ingest(sample, tmp_path_factory.mktemp("ref") / "db", progress=False)


def _frames(db, name):
    row = db.documents.set_index("name").loc[name]
    return np.asarray(db.positions[row["start"] : row["start"] + row["n_frames"]])


def _hdm05(db):
    return [n for n in db.documents["name"] if n.startswith("HDM_")]


def _assert_sound(db, reference, names=None):
    """Each document once, each holding exactly its file's frames, and a fully verified open."""
    db = MotionDB.open(db.path, verify=True)
    got = list(db.documents["name"])
    assert len(set(got)) == len(got), f"duplicate documents: {got}"
    if names is not None:
        assert sorted(got) == sorted(names)
    for name in got:
        np.testing.assert_array_equal(_frames(db, name), _frames(reference, name))
    return db


_INGEST = textwrap.dedent(
    """
    import sys, time
    import mocapviz.db.database as d
    from mocapviz import MocapvizError
    real = d._commit
    def slow(*args):
        time.sleep(float(sys.argv[3]))  # hold the writer lock a while: the other writer meets it
        return real(*args)
    d._commit = slow
    try:
        db = d.MotionDB.ingest(sys.argv[2], sys.argv[1], progress=False)
    except MocapvizError as exc:
        print("error:", exc)
        sys.exit(2)
    print("ok", len(db))
    """
)


def _ingest(out, what, hold=0.0):
    return subprocess.Popen([sys.executable, "-c", _INGEST, str(out), str(what), str(hold)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip


def test_two_ingests_of_the_same_files_at_once_store_each_document_once(sample, reference, tmp_path):
    out = tmp_path / "db"
    procs = [_ingest(out, sample / "hdm05-cut", hold=1.0) for _ in range(2)]
    results = [(p.wait(300), p.stdout.read(), p.stderr.read()) for p in procs]
    assert [r[0] for r in results] == [0, 0], results
    _assert_sound(MotionDB.open(out), reference, _hdm05(reference))


def test_two_ingests_of_different_files_into_one_database_keep_both(sample, reference, tmp_path):
    out = tmp_path / "db"
    MotionDB.ingest(sample / "cmu-asfamc", out, progress=False)
    amc = sample / "hdm05-cut" / "amc"
    procs = [_ingest(out, amc / f"HDM_{actor}_*.amc", hold=1.0) for actor in ("dg", "mm")]
    assert [p.wait(300) for p in procs] == [0, 0]
    _assert_sound(MotionDB.open(out), reference, list(reference.documents["name"]))


def test_a_failing_fresh_ingest_never_removes_what_another_committed(sample, reference, tmp_path):
    """The measured data loss: a fresh ingest that fails on a bad file while another ingest into the same new
    folder commits. The failing one may remove only the empty database it created, never the other's documents."""
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")  # truncated: a typed read error
    out = tmp_path / "db"
    good = _ingest(out, sample / "hdm05-cut", hold=1.5)
    time.sleep(0.5)
    failing = _ingest(out, bad)
    assert failing.wait(300) == 2 and good.wait(300) == 0, (failing.stdout.read(), good.stderr.read())
    _assert_sound(MotionDB.open(out), reference, _hdm05(reference))


_KILLABLE = textwrap.dedent(
    """
    import os, sys
    import mocapviz.db.database as d
    print(os.getpid(), flush=True)
    d.MotionDB.ingest(sys.argv[2], sys.argv[1], progress=False)
    print("done", flush=True)
    """
)


@pytest.mark.parametrize("seed", range(6))
def test_kill_9_at_a_random_point_leaves_a_database_that_reopens_or_nothing(sample, reference, tmp_path, seed):
    """kill -9 of a fresh ingest, then of an append, at a random moment: afterwards the folder is either absent,
    or a database that opens fully verified with the previous or the new documents; re-running completes it."""
    rng = np.random.default_rng(seed)
    out = tmp_path / "db"
    for what in (sample / "cmu-asfamc", sample / "hdm05-cut"):
        before = set(MotionDB.open(out).documents["name"]) if (out / "manifest.json").exists() else set()
        proc = subprocess.Popen([sys.executable, "-c", _KILLABLE, str(out), str(what)], stdout=subprocess.PIPE,
                                text=True)  # fmt: skip
        proc.stdout.readline()  # the child is running Python: from here on anything may be interrupted
        time.sleep(float(rng.uniform(0.0, 2.5)))
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(60)
        if (out / "manifest.json").exists():
            now = set(_assert_sound(MotionDB.open(out), reference).documents["name"])
            assert now == before or now > before
        db = MotionDB.ingest(what, out, progress=False)  # the re-run completes what was interrupted
        _assert_sound(db, reference)
    assert sorted(MotionDB.open(out).documents["name"]) == sorted(reference.documents["name"])


# ------------------------------------------------------------------------------------------- corruption
def _copy(db, tmp_path):
    return Path(shutil.copytree(db.path, tmp_path / "copy"))


def _manifest(folder):
    return json.loads((folder / "manifest.json").read_text())


def test_a_damaged_documents_table_is_named(reference, tmp_path):
    for change in ("start", "n_frames"):
        folder = _copy(reference, tmp_path / change)
        table = folder / _manifest(folder)["documents"]
        docs = pd.read_parquet(table)
        docs.loc[3, change] += 7  # shifted start / moved n_frames: silently different answers before
        docs.to_parquet(table, index=False)
        with pytest.raises(MotionDBError, match=rf"{table.name}: .*damaged"):
            MotionDB.open(folder)


def test_flipped_position_bytes_are_found_by_a_full_check(reference, tmp_path):
    folder = _copy(reference, tmp_path)
    arr = folder / _manifest(folder)["arrays"]["positions"]
    data = bytearray(arr.read_bytes())
    data[len(data) // 2] ^= 0xFF
    arr.write_bytes(bytes(data))
    MotionDB.open(folder)  # same size: the fast path cannot tell
    with pytest.raises(MotionDBError, match=rf"{arr.name}: its sha256 differs"):
        MotionDB.open(folder, verify=True)


def test_a_truncated_array_is_named_at_open(reference, tmp_path):
    folder = _copy(reference, tmp_path)
    arr = folder / _manifest(folder)["arrays"]["quaternions"]
    arr.write_bytes(arr.read_bytes()[:-100])
    with pytest.raises(MotionDBError, match=rf"{arr.name}: .* bytes, .* when written: the file is damaged"):
        MotionDB.open(folder)


def test_a_waiting_ingest_survives_the_removal_of_the_empty_database_a_failed_one_created(sample, reference,
                                                                                          tmp_path):
    """The failing ingest creates the database and holds the lock while it reads its bad file; the good one waits.
    The failing one removes its empty database; the good one then creates it again and commits."""
    bad = tmp_path / "bad"
    bad.mkdir()
    for i in range(40):  # enough files that the failing one still reads when the good one arrives
        shutil.copy(next((sample / "hdm05-cut" / "amc").glob("*.amc")), bad / f"ok_{i:02d}.amc")
    shutil.copytree(sample / "hdm05-cut" / "asf", tmp_path / "asf")
    (bad / "zz_broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    out = tmp_path / "db"
    failing = _ingest(out, bad)
    while not (out / "manifest.json").exists():
        assert failing.poll() is None
        time.sleep(0.01)
    good = _ingest(out, sample / "hdm05-cut")
    assert failing.wait(300) == 2 and good.wait(300) == 0, (failing.stdout.read(), good.stdout.read(),
                                                             good.stderr.read())  # fmt: skip
    _assert_sound(MotionDB.open(out), reference, _hdm05(reference))


@pytest.fixture
def derived(reference, tmp_path):
    """A copy of the reference database with its relational indexes and two numeric sets (one of them Fp)."""
    from mocapviz.features import store_numeric
    from mocapviz.relational import index

    db = MotionDB.open(_copy(reference, tmp_path))
    index.build(db, progress=False)
    store_numeric(db, ["F15E", "Fp8"], progress=False)
    return db


def test_check_reads_every_file_back(derived):
    from mocapviz.integrity import check

    report = check(derived.path)
    assert report["ok"].all() and set(report["status"]) == {"ok"} and not report["rebuild"].any(), report
    assert set(report["what"]) == {"MotionDB", "relational index", "numeric set F15E", "numeric set Fp8", "PCA model"}
    assert (report["what"] == "relational index").sum() == 3


def test_damaged_derived_files_are_named_never_answered(derived):
    from mocapviz.features import load_numeric
    from mocapviz.integrity import check
    from mocapviz.relational import index

    lower = index.index_path(derived, "2005", "lower")
    with np.load(lower) as z:  # permuted codes, same size: silently different answers before
        arrays = {k: z[k] for k in z.files}
    arrays["list_codes"] = arrays["list_codes"][::-1].copy()
    with open(lower, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(MotionDBError, match=rf"{lower.name}: its arrays differ .* damaged"):
        index.load(derived)
    upper = index.index_path(derived, "2005", "upper")
    upper.write_bytes(upper.read_bytes()[:-200])  # truncated: BadZipFile before
    with pytest.raises(MotionDBError, match=rf"{upper.name}: not a readable index"):
        index.InvertedIndex.load(upper)
    data = derived.path / "features" / "numeric-F15E.npy"
    raw = bytearray(data.read_bytes())
    raw[-5] ^= 0x40
    data.write_bytes(bytes(raw))
    with pytest.raises(MotionDBError, match=r"numeric-F15E.npy: bytes 0–[\d,]+ \(block 1 of 1\) differ .* damaged"):
        load_numeric(derived, "F15E")  # same size: the per-block xxh3 of the first read tells
    with pytest.raises(MotionDBError, match=r"numeric-F15E.npy: its sha256 differs"):
        load_numeric(derived, "F15E", full_check=True)
    (derived.path / "features" / "numeric-Fp8.json").write_text("null")  # an empty header: AttributeError before
    with pytest.raises(MotionDBError, match=r"numeric-Fp8.json: not a mocapviz.numeric-features version 2 file"):
        load_numeric(derived, "Fp8")
    report = check(derived.path).set_index("file")
    bad = sorted(report.index[~report["ok"]])
    assert bad == ["features/numeric-F15E.npy", "features/numeric-Fp8.npy", "index/relational-2005-lower.npz",
                   "index/relational-2005-upper.npz"]  # fmt: skip
    assert set(report.loc[bad, "status"]) == {"damaged"}  # (and each names the command that computes it again)
    assert report.loc["index/relational-2005-lower.npz", "rebuild"] == f"mocapviz index {derived.path}"
    assert report.loc["features/numeric-Fp8.npy", "rebuild"] == f"mocapviz features {derived.path} --numeric-sets Fp8"
    assert report.loc["index/relational-2005-mix.npz", "ok"] and report.loc["features/pca.npz", "ok"]
    with pytest.raises(MotionDBError, match=rf": 4 files of {len(report)} are damaged \(see above\)"):
        run_check(argparse.Namespace(db=derived.path))  # the count and its words agree (1: the next test)


def test_mocapviz_check_prints_every_file_and_fails_on_a_damaged_one(derived, capsys):
    from mocapviz.cli import main

    assert main(["check", str(derived.path)]) == 0
    out = capsys.readouterr().out
    assert out.count(" ok") >= 8 and "DAMAGED" not in out
    arr = derived.path / _manifest(derived.path)["arrays"]["positions"]
    raw = bytearray(arr.read_bytes())
    raw[-3] ^= 0x01
    arr.write_bytes(bytes(raw))
    assert main(["check", str(derived.path)]) == 1
    out, err = capsys.readouterr()
    assert "DAMAGED" in out and arr.name in out
    assert err.count("\n") == 1 and "1 file of 1 is damaged" in err
