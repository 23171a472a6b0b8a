"""Whole-database computations of the dashboard (index statistics, correlations, retrieval quality) as jobs: one at a
time per server, the others queued, each with its progress, a Cancel button, and stopped when its session closes.

:class:`JobQueue` runs jobs one after another (:data:`JOB_SLOTS` at a time) on worker threads of its own, off the
server's event loop and apart from the threads that answer the pages' queries, so a long job never delays another
session's search. A job runs inside :func:`mocapviz.parallel.watching`: every step of the library's batch loops
(:func:`mocapviz.parallel.progress_bar`, :func:`mocapviz.parallel.map_ordered`) reports the fraction done and checks
its cancel event, so Cancel (or the end of its browser session) stops it between two steps. :class:`JobTask` is a
page's :class:`~mocapviz.app.progress.Task` run as such a job: a bar of the fraction done, the step, the place in the
queue while waiting, and Cancel; once the page has the job's outcome, what the job computed is freed
(:func:`release_memory`) on the server's event loop, never in the job's thread: a full collection there runs the
finalizers of other sessions' objects beside the event loop, and pages lost updates (the retrieval page's error or
its "done" never reached the browser: 2 of 81 evaluate / refused / evaluate rounds on one served sample with the
collection in the job's thread, 0 of 100 without it; ``python scripts/stress_job_updates.py``).
"""

from __future__ import annotations

import asyncio
import functools
import gc
import logging
import threading
import time
from concurrent.futures import Future, InvalidStateError, ThreadPoolExecutor

import panel as pn

from ..errors import Cancelled
from ..heap import trim_free_memory
from ..parallel import watching
from .progress import Task

LOG = logging.getLogger("mocapviz.app")
JOB_SLOTS = 1  # whole-database jobs running at once per server: each may use every core and much memory
POLL_S = 0.25  # seconds between two looks of a page at its job's progress


def release_memory() -> None:
    """Collect garbage, then give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing
    elsewhere), so that the memory of a finished, cancelled or closed computation leaves the server's RSS. Called on
    the server's event loop (the finalizers the collection runs belong to every session's objects)."""
    gc.collect()
    trim_free_memory()


class Job:
    """One whole-database computation: ``fn()`` run by a :class:`JobQueue`.

    Attributes
    ----------
    fraction : float or None, the share done in [0, 1] (None until its first step reports), never decreasing.
    step : str, the steps it is in ("k-NN timings 3/9 › F30E 1/2").
    started : float or None, :func:`time.perf_counter` when it started running.
    future : concurrent.futures.Future of ``fn()``'s result (:class:`~mocapviz.errors.Cancelled` when stopped).
    """

    def __init__(self, fn, name: str = ""):
        self.fn, self.name = fn, name
        self.cancel_event = threading.Event()
        self.fraction: float | None = None
        self.step = ""
        self.started: float | None = None
        self.future: Future = Future()

    def report(self, fraction: float, step: str) -> None:
        """:func:`mocapviz.parallel.watching`'s ``report``: from the job's thread."""
        self.fraction = max(self.fraction or 0.0, fraction)
        self.step = step

    @property
    def cancelled(self) -> bool:
        return self.cancel_event.is_set()


class JobQueue:
    """Jobs run in submission order, ``slots`` at a time, each in a worker thread (one queue per server)."""

    def __init__(self, slots: int = JOB_SLOTS):
        self._pool = ThreadPoolExecutor(slots, thread_name_prefix="mocapviz-job")
        self._waiting: list[Job] = []
        self._lock = threading.Lock()

    def submit(self, fn, name: str = "") -> Job:
        """Queue ``fn()`` as a :class:`Job` called ``name`` (for the server log); its ``future`` gets the result."""
        job = Job(fn, name)
        with self._lock:
            self._waiting.append(job)
        future = self._pool.submit(self._run, job)
        future.add_done_callback(lambda f: _copy_outcome(f, job.future))
        return job

    def position(self, job: Job) -> int:
        """1 for the next job to start, 2 for the one after it, ...; 0 once ``job`` runs (or was cancelled)."""
        with self._lock:
            return self._waiting.index(job) + 1 if job in self._waiting else 0

    def cancel(self, job: Job) -> None:
        """Stop ``job``: a waiting job leaves the queue at once (its future raises Cancelled); a running one stops at
        its next step."""
        job.cancel_event.set()
        with self._lock:
            waiting = job in self._waiting
            if waiting:
                self._waiting.remove(job)
        if waiting:
            _settle(job.future, Cancelled("cancelled before it started"))

    def _run(self, job: Job):
        with self._lock:
            if job not in self._waiting:  # cancelled while waiting
                raise Cancelled("cancelled before it started")
            self._waiting.remove(job)
        job.started = time.perf_counter()
        LOG.info("job started: %s", job.name)
        outcome = "failed"
        try:
            with watching(job.cancel_event, job.report):
                result = job.fn()
            outcome = "finished"
            return result
        except Cancelled:
            outcome = "cancelled"
            raise
        finally:
            job.fn = None  # the arguments it held (a page, a backend) are not kept by the finished job
            LOG.info("job %s after %.1f s: %s", outcome, time.perf_counter() - job.started, job.name)


def _copy_outcome(source: Future, target: Future) -> None:
    """The pool's future's result or exception into the job's (unless set already: cancelled while waiting)."""
    exc = source.exception()
    _settle(target, exc, None if exc is not None else source.result())


def _settle(future: Future, exc: BaseException | None, result=None) -> None:
    """Set ``future``'s exception (or result) unless it is set already (the first outcome stays)."""
    try:
        if exc is not None:
            future.set_exception(exc)
        else:
            future.set_result(result)
    except InvalidStateError:
        pass


JOBS = JobQueue()  # the server's queue: shared by every session of the process


def on_session_closed(callback) -> None:
    """Call ``callback()`` when the browser session building the page now closes (nothing outside a session)."""
    doc = pn.state.curdoc
    if doc is not None and doc.session_context is not None:
        doc.on_session_destroyed(lambda context: callback())


class JobTask(Task):
    """A :class:`~mocapviz.app.progress.Task` whose computations run as :class:`Job` s of the server's
    :class:`JobQueue`: the bar shows the fraction done, the status line the step (or the place in the queue), and a
    Cancel button stops the job between two steps; closing the browser session cancels it too.

    ``await job_task.run("Table 1", fn, *args, busy=button)`` returns ``fn(*args)``, or None when it failed (the
    error shown, as :class:`Task` does) or was cancelled ("… cancelled").
    """

    def __init__(self, queue: JobQueue | None = None, **params):
        super().__init__(**params)
        self.queue = JOBS if queue is None else queue
        self.job: Job | None = None
        self.stopped = False  # the last run was cancelled
        self._label = ""
        self.cancel_button = pn.widgets.Button(name="Cancel", width=90, visible=False, css_classes=["mv-job-cancel"])
        self.cancel_button.on_click(lambda event: self.cancel())
        on_session_closed(self.cancel)

    def __panel__(self):
        return pn.Column(self.bar, pn.Row(self.status, self.cancel_button, margin=0), self.error,
                         sizing_mode="stretch_width", margin=0)

    def cancel(self) -> None:
        """Stop the job of this page (waiting or running)."""
        if self.job is not None:
            LOG.info("job cancelled: %s", self._label)
            self.queue.cancel(self.job)

    @property
    def running(self) -> bool:
        """A job of this page is waiting or running."""
        return self.job is not None

    async def run(self, label: str, fn, *args, **options):
        self._label, self.stopped = label, False
        try:
            return await super().run(label, fn, *args, **options)
        except Cancelled:
            self.stopped = True
            self.status.object = f"{label}: cancelled"
            return None
        finally:
            self.job = None
            self.cancel_button.visible = False
            asyncio.get_running_loop().call_soon(release_memory)  # after the page's updates, never in the job's thread

    async def _call(self, fn, *args):
        job = self.job = self.queue.submit(functools.partial(fn, *args), self._label)
        self.cancel_button.visible = True
        result = asyncio.wrap_future(job.future)
        while not result.done():
            self._show(job)
            await asyncio.wait([result], timeout=POLL_S)
        return result.result()

    def _show(self, job: Job) -> None:
        """The job's progress on the bar and status line (from the event loop)."""
        if job.cancelled:
            self.status.object = f"{self._label}: cancelling …"
            return
        ahead = self.queue.position(job)
        if ahead:
            self.status.object = (f"{self._label}: waiting, number {ahead} in the queue (the server runs one "
                                  f"whole-database computation at a time)")
            return
        elapsed = time.perf_counter() - job.started if job.started else 0.0
        done = f"{100 * job.fraction:.0f} % · " if job.fraction is not None else ""
        self.status.object = f"{self._label} … {done}{job.step + ' · ' if job.step else ''}{elapsed:.0f} s"
        if job.fraction is not None:
            self.bar.param.update(value=int(100 * job.fraction), active=True)
