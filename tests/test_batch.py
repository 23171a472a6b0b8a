"""mocapviz.db.batches: the default threads, the ordered map with bounded look-ahead on threads (order, the first
failure in order, cancellation when the consumer stops), and the batches of whole documents of a real MotionDB.
The Dask back end of the same map is tested on a real local cluster in test_cluster.py."""

from __future__ import annotations

import itertools
import os
import threading
import time

import numpy as np
import pytest

from mocapviz import MotionDB, ParameterError, parallel
from mocapviz.db import batches
from mocapviz.motion.skeleton import CANONICAL_JOINTS


def test_default_threads_are_the_usable_cores_at_most_8():
    assert parallel.default_threads() == min(8, len(os.sched_getaffinity(0)))
    assert parallel.parallelism() == parallel.default_threads() and parallel.parallelism(3) == 3
    for bad in (0, -1, 2.0, True):
        with pytest.raises(ParameterError, match="threads"):
            parallel.parallelism(bad)


def _slow_square(x: int) -> int:
    time.sleep(0.02 if x % 3 == 0 else 0.001)  # later items often finish first
    return x * x


def test_results_come_in_item_order_whatever_order_they_finish_in():
    assert list(parallel.map_ordered(_slow_square, range(40), threads=4)) == [x * x for x in range(40)]
    assert list(parallel.map_ordered(_slow_square, [], threads=4)) == []


def test_one_thread_runs_in_the_calling_thread_one_item_at_a_time():
    pulled = []

    def items():
        for i in range(5):
            pulled.append(i)
            yield i

    results = parallel.map_ordered(lambda i: (i, threading.current_thread()), items(), threads=1)
    assert next(results) == (0, threading.current_thread()) and pulled == [0]
    assert [i for i, _ in results] == [1, 2, 3, 4]


def test_look_ahead_is_bounded_and_pending_items_are_cancelled_on_close():
    pulled, started = [], []

    def items():
        for i in range(1000):
            pulled.append(i)
            yield i

    def work(i):
        started.append(i)
        time.sleep(0.01)
        return i

    threads = 2
    results = parallel.map_ordered(work, items(), threads=threads)
    assert next(results) == 0
    assert len(pulled) <= parallel.AHEAD_PER_THREAD * threads + 1  # the one waited for, and the look-ahead
    results.close()
    n_started = len(started)
    assert n_started <= parallel.AHEAD_PER_THREAD * threads + 1
    time.sleep(0.1)
    assert len(started) == n_started  # nothing starts after the consumer has stopped


def test_the_first_failing_item_in_order_raises():
    def work(i):
        if i == 7:
            time.sleep(0.05)  # fails late ...
            raise ValueError("item 7")
        if i == 9:
            raise KeyError("item 9")  # ... this one fails first
        return i

    got = []
    with pytest.raises(ValueError, match="item 7"):
        for value in parallel.map_ordered(work, range(20), threads=4):
            got.append(value)  # noqa: PERF402 - the values before the exception
    assert got == list(range(7))


def _frames_and_documents(positions, bounds, fps):
    return positions.shape[0], len(bounds) - 1, fps.copy()


def test_map_documents_covers_the_database_in_frame_order(hdm05_dir, tmp_path, capsys, monkeypatch):
    files = sorted((hdm05_dir / "amc").rglob("*.amc"))[:12]
    db = MotionDB.ingest(files, tmp_path / "db", fps=30, progress=False)
    longest = int(db.documents["n_frames"].max())
    for threads in (1, 3):
        out = list(batches.map_documents(db, _frames_and_documents, longest, threads=threads, progress=False))
        assert len(out) > 1  # several batches
        frames = [f for f, _ in out]
        assert frames[0].start == 0 and frames[-1].stop == db.n_frames
        assert all(a.stop == b.start for a, b in itertools.pairwise(frames))
        assert [n for _, (n, _, _) in out] == [f.stop - f.start for f in frames]
        assert sum(d for _, (_, d, _) in out) == len(db)
        assert all((fps == 30).all() for _, (_, _, fps) in out)
    # the progress bar counts documents, and only for databases of more documents than the threshold
    list(batches.map_documents(db, _frames_and_documents, longest, desc="test bar"))
    assert "test bar" not in capsys.readouterr().err
    monkeypatch.setattr(batches, "PROGRESS_MIN_DOCUMENTS", 2)
    list(batches.map_documents(db, _frames_and_documents, longest, desc="test bar"))
    err = capsys.readouterr().err
    assert "test bar" in err and f"{len(db)}/{len(db)}" in err


def test_map_documents_names_the_first_bad_document_and_frame(hdm05_dir, tmp_path):
    files = sorted((hdm05_dir / "amc").rglob("*.amc"))[:6]
    db = MotionDB.ingest(files, tmp_path / "db", fps=30, progress=False)
    positions = np.array(db.positions)
    for doc, frame, joint in ((4, 3, "lwrist"), (2, 17, "head")):
        positions[int(db.documents["start"].iloc[doc]) + frame, CANONICAL_JOINTS.index(joint)] = np.nan
    db.positions = positions
    with pytest.raises(ParameterError, match=r"document 2 \(.*\), frame 17: joint head"):
        list(batches.map_documents(db, _frames_and_documents, 1, threads=2, progress=False))
    # joints not checked are not reported
    out = list(batches.map_documents(db, _frames_and_documents, 1, joints=[0], threads=2, progress=False))
    assert len(out) == len(db)
