"""mocapviz.store: atomic files and folders, the advisory lock, the format check, and concurrent writers of a
MotionDB and its derived data in real processes (embedded sample: no shared archives needed)."""

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from mocapviz import MotionDB, MotionDBError
from mocapviz.io import datasets
from mocapviz.relational import index
from mocapviz.store import atomic_file, atomic_folder, atomic_write, check_format, load_or_build, locked


@pytest.fixture(scope="module")
def sample_dir():
    return datasets.sample()


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith((".tmp", ".old")))


# ------------------------------------------------------------------------------------------- single process
def test_atomic_file_keeps_the_old_file_when_the_writer_fails(tmp_path):
    target = tmp_path / "table.csv"
    atomic_write(target, b"old")
    with pytest.raises(RuntimeError), atomic_file(target) as tmp:
        tmp.write_bytes(b"half of the new")
        raise RuntimeError("killed")
    assert target.read_bytes() == b"old" and _leftovers(tmp_path) == []


def test_two_writers_never_share_a_temporary_file(tmp_path):
    target = tmp_path / "x.npz"
    with atomic_file(target) as a, atomic_file(target) as b:
        assert a != b and a.parent == b.parent == tmp_path and a.name.startswith(".x.npz.")
        a.write_bytes(b"a")
        b.write_bytes(b"b")
    assert target.read_bytes() == b"a"  # the outer block committed last
    assert _leftovers(tmp_path) == []


def test_atomic_folder_replaces_only_when_complete_and_can_keep_a_winner(tmp_path):
    target = tmp_path / "result"
    with atomic_folder(target) as tmp:
        (tmp / "a.txt").write_text("1")
    with pytest.raises(RuntimeError), atomic_folder(target) as tmp:
        (tmp / "a.txt").write_text("2")
        raise RuntimeError("failed run")
    assert (target / "a.txt").read_text() == "1"
    with atomic_folder(target, replace=False) as tmp:
        (tmp / "a.txt").write_text("3")
    assert (target / "a.txt").read_text() == "1"
    with atomic_folder(target) as tmp:
        (tmp / "b.txt").write_text("4")
    assert sorted(p.name for p in target.iterdir()) == ["b.txt"]
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("header", [[1, 2], None, "x", {"format": "mocapviz.Other", "version": 1},
                                    {"format": "mocapviz.MotionDB", "version": 99}])
def test_check_format_refuses_anything_else(header):
    with pytest.raises(MotionDBError, match=r"x\.json: not a mocapviz\.MotionDB version 1 file .*; rebuild"):
        check_format(header, "mocapviz.MotionDB", 1, "x.json", "rebuild it")
    assert check_format({"format": "mocapviz.MotionDB", "version": 1}, "mocapviz.MotionDB", 1, "x") is not None


def test_load_or_build_builds_only_when_loading_fails():
    def missing():
        raise MotionDBError("not stored")

    assert load_or_build(lambda: "stored", lambda: "built") == "stored"
    assert load_or_build(missing, lambda: "built") == "built"
    with pytest.raises(ZeroDivisionError):  # a bug in the loader is not "missing"
        load_or_build(lambda: 1 / 0, lambda: "built")


# ------------------------------------------------------------------------------------------- real processes
_HOLD = textwrap.dedent(
    """
    import sys, time, pathlib
    from mocapviz.store import locked
    folder = pathlib.Path(sys.argv[1])
    with locked(folder):
        (folder / "holding").write_text("yes")
        time.sleep(float(sys.argv[2]))
        (folder / "released").write_text("yes")
    """
)


def _hold(folder, seconds):
    proc = subprocess.Popen([sys.executable, "-c", _HOLD, str(folder), str(seconds)])
    deadline = time.monotonic() + 60
    while not (folder / "holding").exists():
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.02)
    return proc


def test_lock_held_by_another_process_fails_fast_or_waits(tmp_path):
    proc = _hold(tmp_path, 1.0)
    with pytest.raises(MotionDBError, match="another process is writing"), locked(tmp_path, wait=False, what="DB"):
        pass
    with locked(tmp_path):  # waits for the other process to let go
        assert (tmp_path / "released").exists()
    assert proc.wait(60) == 0


_DERIVED = textwrap.dedent(
    """
    import sys
    from mocapviz import MotionDB
    from mocapviz.relational import index
    from mocapviz.features import store_numeric
    db = MotionDB.open(sys.argv[1])
    for _ in range(3):
        index.build(db, progress=False)
        store_numeric(db, "F15E", progress=False)
    """
)


def test_two_processes_writing_derived_data_at_once(sample_dir, tmp_path):
    from mocapviz.features import load_numeric, numeric_features

    db = MotionDB.ingest(sample_dir / "hdm05-cut", tmp_path / "db", progress=False)
    procs = [subprocess.Popen([sys.executable, "-c", _DERIVED, str(db.path)]) for _ in range(2)]
    assert [p.wait(600) for p in procs] == [0, 0]
    stored, fresh = index.load(db), index.build(db, progress=False, save=False)
    for group in fresh:
        assert stored[group]._stored().keys() == fresh[group]._stored().keys()
        for key, value in fresh[group]._stored().items():
            np.testing.assert_array_equal(stored[group]._stored()[key], value)
    np.testing.assert_array_equal(load_numeric(db, "F15E"), numeric_features(db, "F15E", progress=False))
    for folder in (db.path / "index", db.path / "features"):
        assert _leftovers(folder) == []
    assert os.listdir(db.path / "index")


def test_a_folder_another_process_renamed_into_place_first_is_kept(tmp_path, monkeypatch):
    """Two fresh ingests create one database: the other's folder takes the name between this one's check and its
    rename (made to happen here by the rename itself); with ``replace=False`` theirs is kept, ours discarded, no
    error (a concurrent-ingest test once saw ENOTEMPTY from the rename)."""
    target, rename = tmp_path / "db", os.replace

    def racing(src, dst):
        if Path(dst) == target and not target.exists():
            target.mkdir()
            (target / "theirs").write_text("1")
        return rename(src, dst)

    monkeypatch.setattr(os, "replace", racing)
    with atomic_folder(target, replace=False) as tmp:
        (tmp / "mine").write_text("2")
    assert [f.name for f in target.iterdir()] == ["theirs"]
    assert not list(tmp_path.glob(".db.*"))
