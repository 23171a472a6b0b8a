"""Running per-document work in batches: on threads in this process or as Dask tasks, results in order.

default_threads   the default ``threads``: the cores this process may use, at most ``MAX_DEFAULT_THREADS``.
parallelism       how many items run at once for given ``threads`` / Dask client.
map_ordered       ``fn(item)`` of every item, on threads or as Dask tasks, yielded in item order.
map_documents     a ``work`` function on each batch of whole documents of a MotionDB, in frame order.

Both back ends follow one rule. Work runs on ``threads`` threads of this process (numpy and numba release the
GIL; ``threads=1`` runs each item in the calling thread when its result is asked for), or as tasks of a
``dask.distributed.Client`` (:mod:`mocapviz.cluster` turns a ``scheduler=`` into one). At most
``AHEAD_PER_THREAD`` items per thread (per Dask worker thread) are started beyond the one whose result is waited
for, so that results waiting to be consumed stay few whatever the length of the input. Results come in item
order, not in order of completion, so the first failing item *in that order* raises its exception. When the
consumer stops early (the generator closed, or an exception) the items not started are cancelled; threads finish
the item they are on, Dask tasks are cancelled. Callers that may stop early wrap the generator in
``contextlib.closing``.

A Dask task must be small and importable on the workers: ``fn`` is a module-level function (or a
``functools.partial`` of one) and an item holds paths and ranges, never arrays. For a MotionDB an item is (database
path, manifest generation, a range of whole documents): the worker opens the memory-mapped database itself
(:func:`mocapviz.cluster.open_db`) and only the results travel back.
"""
from __future__ import annotations

import collections
import contextlib
import functools
import itertools
import uuid
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from tqdm.auto import tqdm

from .cluster import local_workers, n_threads, open_db
from .database import MotionDB, document_batches, read_batch
from .validation import count, finite_positions

__all__ = ["AHEAD_PER_THREAD", "MAX_DEFAULT_THREADS", "PROGRESS_MIN_DOCUMENTS", "default_threads", "map_documents",
           "map_ordered", "parallelism"]  # fmt: skip

MAX_DEFAULT_THREADS = 8  # more threads than this rarely pay: the batches are memory-bound
AHEAD_PER_THREAD = 2  # items started beyond the one waited for, per thread (or Dask worker thread)
PROGRESS_MIN_DOCUMENTS = 50  # a MotionDB of more documents than this shows a progress bar (with progress=True)


def default_threads() -> int:
    """The default ``threads`` of mocapviz: the cores this process may run on (``os.sched_getaffinity``), at most
    ``MAX_DEFAULT_THREADS`` (8), at least 1."""
    return min(MAX_DEFAULT_THREADS, local_workers())


def parallelism(threads: int | None = None, client=None) -> int:
    """How many items :func:`map_ordered` runs at once.

    Parameters
    ----------
    threads : int, optional
        Threads in this process (default :func:`default_threads`); ignored when ``client`` is given.
    client : dask.distributed.Client, optional
        Run as Dask tasks: the cluster's worker threads now.

    Returns
    -------
    int, at least 1.

    Raises
    ------
    mocapviz.ParameterError
        ``threads`` not a positive integer.
    """
    if client is not None:
        return n_threads(client)
    return default_threads() if threads is None else count(threads, "threads")


def map_ordered(fn: Callable, items: Iterable, threads: int | None = None, client=None,
                name: str = "mocapviz") -> Iterator:
    """``fn(item)`` of every item, on threads of this process or as Dask tasks, yielded in the order of ``items``.

    At most ``AHEAD_PER_THREAD`` items per thread are started beyond the one waited for (see the module
    docstring); ``items`` is consumed as far as that, lazily.

    Parameters
    ----------
    fn : callable
        ``fn(item) -> result``; for Dask, importable on the workers (a module-level function or a
        ``functools.partial`` of one).
    items : iterable
        The arguments; for Dask, small and picklable.
    threads : int, optional
        Threads in this process (default :func:`default_threads`); 1 runs every item in the calling thread.
        Ignored when ``client`` is given.
    client : dask.distributed.Client, optional
        Run each item as a Dask task of this client instead.
    name : str
        Prefix of the threads' names and of the Dask task keys (shown on the dashboard).

    Yields
    ------
    ``fn(item)`` for each item, in order. The exception of the first failing item in order is raised here.

    Raises
    ------
    mocapviz.ParameterError
        ``threads`` not a positive integer (when the first result is asked for).
    """
    workers = parallelism(threads, client)
    ahead = AHEAD_PER_THREAD * workers
    if client is not None:
        yield from _ordered(items, ahead, lambda item: client.submit(fn, item, key=f"{name}-{uuid.uuid4().hex}"),
                            _dask_result, lambda pending: _dask_cancel(client, pending))  # fmt: skip
    elif workers == 1:
        yield from map(fn, items)
    else:
        with ThreadPoolExecutor(workers, thread_name_prefix=name) as pool:
            yield from _ordered(items, ahead, lambda item: pool.submit(fn, item), lambda future: future.result(),
                                lambda pending: [future.cancel() for future in pending])  # fmt: skip


def _ordered(items: Iterable, ahead: int, submit: Callable, result: Callable, cancel: Callable) -> Iterator:
    """The look-ahead loop of :func:`map_ordered` over futures: ``submit(item) -> future``, ``result(future)``
    (waits), ``cancel(futures)`` of those still pending when the consumer stops."""
    pending: collections.deque = collections.deque()
    items = iter(items)
    try:
        while True:
            pending.extend(submit(item) for item in itertools.islice(items, ahead + 1 - len(pending)))
            if not pending:
                return
            yield result(pending.popleft())
    finally:
        if pending:
            cancel(pending)


def _dask_result(future):
    """A Dask future's result (waits; raises the task's exception), and the future released."""
    try:
        return future.result()
    finally:
        future.release()


def _dask_cancel(client, pending) -> None:
    """Cancel the Dask futures still pending (a client already closed has dropped them)."""
    if client.status == "running":
        with contextlib.suppress(RuntimeError, OSError):
            client.cancel(list(pending))


def map_documents(db: MotionDB, work: Callable, max_frames: int, joints=None, threads: int | None = None,
                  client=None, desc: str = "", progress: bool = True, name: str = "mocapviz") -> Iterator:
    """``work`` on each batch of whole documents of a MotionDB, results yielded in frame order.

    The database is cut into batches of whole documents, contiguous in its frames
    (:func:`mocapviz.database.document_batches`); each batch is read (:func:`mocapviz.database.read_batch`),
    checked for non-finite positions, and given to ``work`` -- on threads here, or as Dask tasks whose workers read
    the batch from their own memory map of the database (``client``). A progress bar counts the documents done.

    Parameters
    ----------
    db : MotionDB
    work : callable
        ``work(positions, bounds, fps) -> result`` with positions [shape=(n, 24, 3)] float32 cm (the batch's
        frames), bounds [shape=(D + 1,)] int64 (document d is rows ``bounds[d]:bounds[d + 1]``) and fps
        [shape=(D,)] float64 (each document's frame rate). For Dask, a module-level function or a
        ``functools.partial`` of one, with small arguments.
    max_frames : int
        Frames per batch, at most (a longer document is a batch of its own).
    joints : sequence of int, optional
        Canonical joint indices checked for NaN / inf positions (default: all 24).
    threads, client :
        As for :func:`map_ordered`.
    desc : str
        Label of the progress bar.
    progress : bool
        Show a progress bar when the database has more than ``PROGRESS_MIN_DOCUMENTS`` (50) documents.
    name : str
        Prefix of the threads' names and Dask task keys.

    Yields
    ------
    frames : slice
        The database frames the batch covers; consecutive batches follow each other.
    result : object
        ``work`` of the batch.

    Raises
    ------
    mocapviz.ParameterError
        A NaN or infinite position of a checked joint: the first such batch in frame order raises, naming the
        database, the document, its file and the frame within it.
    mocapviz.MotionDBError
        (Dask) the database changed while the tasks ran.
    """
    docs, batches = document_batches(db, max_frames)
    joints = None if joints is None else [int(j) for j in joints]
    if client is None:
        fn, items = functools.partial(_local_batch, db, docs, work, joints), batches
    else:
        path, generation = str(Path(db.path).resolve()), db.manifest["generation"]
        fn, items = _remote_batch, [(path, generation, first, last, joints, work) for first, last in batches]
    bar = tqdm(total=len(docs), desc=desc, unit="doc", disable=not progress or len(docs) <= PROGRESS_MIN_DOCUMENTS)
    with bar, contextlib.closing(map_ordered(fn, items, threads, client, name)) as results:
        for (first, last), (frames, result) in zip(batches, results):
            bar.update(last - first)
            yield frames, result


def _local_batch(db: MotionDB, docs, work: Callable, joints, batch: tuple[int, int]) -> tuple[slice, object]:
    """Documents ``docs.iloc[first:last]`` read, checked and given to ``work``: (frames, result)."""
    frames = read_batch(db, docs, *batch)
    finite_positions(frames.positions, frames.where, joints)
    return slice(frames.start, frames.stop), work(frames.positions, frames.bounds, frames.fps)


def _remote_batch(task: tuple) -> tuple[slice, object]:
    """A Dask task: (database path, generation, first, last, joints, work) -> :func:`_local_batch` on the worker's
    own memory map of the database."""
    path, generation, first, last, joints, work = task
    db = open_db(path, generation)
    return _local_batch(db, db.documents.sort_values("start"), work, joints, (first, last))
