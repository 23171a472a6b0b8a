"""Cooperative cancellation and progress of long work (mocapviz.parallel.watching: the batch loop of map_documents,
the experiments' steps) and the dashboard's job queue (mocapviz.app.jobs), on real computations of the sample."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from mocapviz.app import jobs
from mocapviz.app.jobs import JobQueue, JobTask
from mocapviz.db.batches import map_documents
from mocapviz.errors import Cancelled
from mocapviz.experiments.numeric import knn_timings
from mocapviz.experiments.retrieval import retrieval_quality
from mocapviz.parallel import checkpoint, progress_bar, watching


def _documents(positions, bounds, fps):  # the work of one batch: its documents
    return len(bounds) - 1


def test_the_batch_loop_reports_documents_and_stops_between_batches(sample_db):
    """Three batches of the sample (6, 9 and 9 documents); stopped after the first, the others are never read."""
    stop, seen, done = threading.Event(), [], []

    def report(fraction, label):
        seen.append((fraction, label))
        if fraction > 0:
            stop.set()

    def work(positions, bounds, fps):
        done.append(_documents(positions, bounds, fps))
        return done[-1]

    with pytest.raises(Cancelled), watching(stop, report):
        list(map_documents(sample_db, work, 2000, threads=1, desc="documents", progress=False))
    assert done == [6]
    assert seen == [(0.0, "documents 0/24"), (0.25, "documents 6/24")]
    assert list(map_documents(sample_db, _documents, 2000, threads=1, progress=False))[-1][1] == 9  # outside: runs


def test_nested_steps_make_one_fraction():
    seen = []
    with watching(report=lambda fraction, label: seen.append(fraction)):
        for _ in progress_bar(range(2), desc="outer", disable=True):
            for _ in progress_bar(range(4), desc="inner", disable=True):
                pass
    assert seen == [0.0, 0.0, 0.125, 0.25, 0.375, 0.5, 0.5, 0.5, 0.625, 0.75, 0.875, 1.0, 1.0]


def test_a_checkpoint_outside_watching_does_nothing_and_inside_raises_once_cancelled():
    checkpoint()
    stop = threading.Event()
    with watching(stop):
        checkpoint()
        stop.set()
        with pytest.raises(Cancelled):
            checkpoint()
    assert not issubclass(Cancelled, Exception)  # `except Exception` around a step lets it through


def test_an_experiment_stops_at_its_next_query(sample_db):
    """Retrieval quality of 6 queries, cancelled when the second query is done: two queries' work, not six."""
    stop, labels = threading.Event(), []

    def report(fraction, label):
        labels.append(label)
        if label == "retrieval quality 2/6":
            stop.set()

    with pytest.raises(Cancelled), watching(stop, report):
        retrieval_quality(sample_db, ["dtw"], n_queries=6, timing=False, progress=False)
    assert labels[-1] == "retrieval quality 2/6" and "retrieval quality 3/6" not in labels


def test_jobs_run_one_at_a_time_and_a_waiting_one_leaves_the_queue_at_once():
    queue, gate, order = JobQueue(slots=1), threading.Event(), []

    def first():
        order.append("first")
        gate.wait(30)
        return "first done"

    running = queue.submit(first, "first")
    waiting = queue.submit(lambda: order.append("second"), "second")
    third = queue.submit(lambda: "third done", "third")
    while running.started is None:
        time.sleep(0.01)
    assert [queue.position(j) for j in (running, waiting, third)] == [0, 1, 2]
    queue.cancel(waiting)
    with pytest.raises(Cancelled):
        waiting.future.result(timeout=1)  # at once, though the job before it still runs
    assert queue.position(third) == 1
    gate.set()
    assert running.future.result(timeout=30) == "first done" and third.future.result(timeout=30) == "third done"
    assert order == ["first"]  # the cancelled job never ran


def test_a_running_job_stops_at_its_next_step(sample_db):
    """k-NN timings of four feature sets, cancelled during the second: the job ends before the third."""
    queue, inside, gate, labels = JobQueue(), threading.Event(), threading.Event(), []

    def timings():
        def report(fraction, label):
            labels.append(label)
            if label.startswith("k-NN timings 1/4"):
                inside.set()
                gate.wait(30)

        with watching(report=report):  # inside the job's own watching: the job's Cancel still stops it
            return knn_timings(sample_db, ["F15E", "F30E", "F39E", "F15x3E"], ks=(16,), n_queries=20, repeats=1)

    job = queue.submit(timings, "Table 1")
    assert inside.wait(60)
    queue.cancel(job)
    gate.set()
    with pytest.raises(Cancelled):
        job.future.result(timeout=60)
    assert not any(label.startswith("k-NN timings 2/4") for label in labels)


def test_progress_of_a_job_is_its_steps():
    queue, stop = JobQueue(), threading.Event()

    def steps():
        for i in progress_bar(range(50), desc="steps", disable=True):
            if i == 10:
                stop.wait(30)

    job = queue.submit(steps, "steps")
    while job.step != "steps 10/50":
        time.sleep(0.01)
    assert job.fraction == 0.2
    stop.set()
    job.future.result(timeout=30)
    assert job.fraction == 1.0 and job.step == "steps 50/50"


def test_a_job_releases_its_memory_on_the_event_loop_after_its_page_has_the_outcome(monkeypatch):
    """What a dashboard job computed is released (collected, heap trimmed) by the event loop's thread once the page
    has the job's outcome, never in the job's thread: a collection there runs finalizers beside the event loop, and
    pages lost updates. The page runs on an event loop of its own thread, as the server's does."""
    calls, delivered, out = [], [], []
    monkeypatch.setattr(jobs, "release_memory", lambda: calls.append((threading.current_thread().name, bool(delivered))))

    async def page():
        result = await JobTask(JobQueue()).run("Evaluating", lambda: 7)
        delivered.append(result)
        await asyncio.sleep(0)  # the release is the event loop's next callback
        return result

    loop = threading.Thread(target=lambda: out.append(asyncio.run(page())), name="event-loop")
    loop.start()
    loop.join(30)
    assert out == [7]
    assert calls == [("event-loop", True)]


def test_the_backend_keeps_derived_data_and_a_bounded_number_of_answers(sample_db, monkeypatch):
    from mocapviz.app import backend as backend_mod

    monkeypatch.setitem(backend_mod.ANSWERS_KEPT, "similarity.knn", 2)
    backend, computed = backend_mod.Backend(sample_db), []

    def answer(key):
        return backend.cached(key, lambda: computed.append(key) or len(computed))

    features = backend.engine.numeric("F15E")
    for frame in range(5):
        answer(("similarity.knn", frame))
    answer(("similarity.knn", 3))  # recent: still kept
    assert [backend.is_cached(("similarity.knn", f)) for f in range(5)] == [False, False, False, True, True]
    assert answer(("similarity.knn", 0)) == 6 and len(computed) == 6  # forgotten, so computed again
    assert backend.engine.numeric("F15E") is features  # derived data stays
