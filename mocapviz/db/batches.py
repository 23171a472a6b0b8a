"""Per-document work on a MotionDB in batches of whole documents, on threads or Dask workers.

document_batches  a MotionDB cut into batches of whole documents, contiguous in its frames.
read_batch        one batch's positions in memory (a :class:`FrameBatch`).
map_documents     a ``work`` function on each batch, results in frame order (:func:`mocapviz.parallel.map_ordered`).
open_db           a worker's memory-mapped MotionDB, opened once per process and generation.

See ``docs/architecture.md`` (the db layer).
"""
from __future__ import annotations

import collections
import contextlib
import functools
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import MotionDBError
from ..motion.skeleton import CANONICAL_JOINTS
from ..parallel import map_ordered, progress_bar
from ..validation import finite_positions
from .database import MotionDB

__all__ = ["PROGRESS_MIN_DOCUMENTS", "FrameBatch", "document_batches", "map_documents", "open_db", "read_batch"]

PROGRESS_MIN_DOCUMENTS = 50  # a MotionDB of more documents than this shows a progress bar (with progress=True)


def document_batches(db: MotionDB, max_frames: int) -> tuple[pd.DataFrame, list[tuple[int, int]]]:
    """Cut a MotionDB into batches of whole documents, contiguous in the frame arrays, for per-batch feature work.

    Parameters
    ----------
    db : MotionDB
        The database.
    max_frames : int
        A batch holds documents while their frames add up to at most this many (at least one document each).

    Returns
    -------
    docs : pandas.DataFrame
        The document table sorted by first frame.
    batches : list of (first, last)
        Positions in ``docs``: documents ``docs.iloc[first:last]`` form one batch; in frame order.
    """
    docs = db.documents.sort_values("start")
    starts = docs["start"].to_numpy(np.int64)
    lengths = docs["n_frames"].to_numpy(np.int64)
    batches, first = [], 0
    while first < len(docs):
        last = first + 1
        while (last < len(docs) and starts[last] == starts[last - 1] + lengths[last - 1]
               and starts[last] + lengths[last] - starts[first] <= max_frames):
            last += 1  # fmt: skip
        batches.append((first, last))
        first = last
    return docs, batches


@dataclass(frozen=True)
class FrameBatch:
    """The frames of documents ``docs.iloc[first:last]`` read from a MotionDB (:func:`read_batch`).

    The fields are its attributes.

    Parameters
    ----------
    db_path : str
        The database's folder (for messages).
    docs : pandas.DataFrame
        The batch's rows of the documents table.
    start, stop : int
        The batch is database frames ``start:stop``.
    positions : np.ndarray [shape=(stop - start, 24, 3)], float32
        The batch's joint positions, cm.
    bounds : np.ndarray [shape=(D + 1,)], int64
        Document d is rows ``bounds[d]:bounds[d + 1]`` of ``positions``.
    fps : np.ndarray [shape=(D,)], float64
        Each document's frame rate.
    """

    db_path: str
    docs: pd.DataFrame
    start: int
    stop: int
    positions: np.ndarray
    bounds: np.ndarray
    fps: np.ndarray

    def where(self, t: int) -> str:
        """Names row ``t`` of ``positions`` for an error: database, document id, source file and frame.

        Parameters
        ----------
        t : int
            A row of :attr:`positions`.

        Returns
        -------
        str
            ``"<db>: document <id> (<path>), frame <frame within the document>"``.
        """
        d = int(np.searchsorted(self.bounds, t, side="right")) - 1
        row = self.docs.iloc[d]
        return f"{self.db_path}: document {row['doc_id']} ({row['path']}), frame {t - int(self.bounds[d])}"


def read_batch(db: MotionDB, docs: pd.DataFrame, first: int, last: int) -> FrameBatch:
    """The positions of documents ``docs.iloc[first:last]`` (one batch of :func:`document_batches`), in memory.

    Parameters
    ----------
    db : MotionDB
        The database.
    docs : pandas.DataFrame
        Its documents, in frame order (as :func:`document_batches` returns them).
    first, last : int
        Rows ``first:last`` of ``docs``: whole documents, contiguous in the frames.

    Returns
    -------
    FrameBatch
        Their positions [shape=(frames, 24, 3)] copied from the memory map, cm, with document bounds and rates.
    """
    part = docs.iloc[first:last]
    lengths = part["n_frames"].to_numpy(np.int64)
    start = int(part["start"].iloc[0])
    stop = start + int(lengths.sum())
    return FrameBatch(str(db.path), part, start, stop, np.asarray(db.positions[start:stop]),
                      np.concatenate([[0], np.cumsum(lengths)]), part["fps"].to_numpy(np.float64))  # fmt: skip


def map_documents(db: MotionDB, work: Callable, max_frames: int, joints=None, threads: int | None = None,
                  client=None, desc: str = "", progress: bool = True, name: str = "mocapviz") -> Iterator:
    """``work`` on each batch of whole documents of a MotionDB, results yielded in frame order.

    The database is cut into batches of whole documents, contiguous in its frames
    (:func:`mocapviz.db.batches.document_batches`); each batch is read (:func:`mocapviz.db.batches.read_batch`),
    checked for non-finite positions, and given to ``work`` -- on threads here, or as Dask tasks whose workers read
    the batch from their own memory map of the database (``client``). A progress bar counts the documents done
    (:func:`mocapviz.parallel.progress_bar`: inside :func:`mocapviz.parallel.watching` each batch reports its
    progress and may stop the work).

    Parameters
    ----------
    db : MotionDB
        The database.
    work : callable
        ``work(positions, bounds, fps) -> result`` with positions [shape=(n, 24, 3)] float32 cm (the batch's
        frames), bounds [shape=(D + 1,)] int64 (document d is rows ``bounds[d]:bounds[d + 1]``) and fps
        [shape=(D,)] float64 (each document's frame rate). For Dask, a module-level function or a
        ``functools.partial`` of one, with small arguments.
    max_frames : int
        Frames per batch, at most (a longer document is a batch of its own).
    joints : sequence of int, optional
        Canonical joint indices checked for NaN / inf positions (default: all 24).
    threads : int, optional
        Threads in this process, as for :func:`mocapviz.parallel.map_ordered`.
    client : dask.distributed.Client, optional
        Run the batches as Dask tasks instead.
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
    mocapviz.errors.Cancelled
        Inside :func:`mocapviz.parallel.watching`, asked to stop: between two batches.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> def documents_and_frames(positions, bounds, fps):  # the work of one batch
    ...     return len(bounds) - 1, positions.shape[0]
    >>> for frames, result in map_documents(MotionDB.sample(), documents_and_frames, 2000, progress=False):
    ...     print(frames, result)
    slice(0, 1934, None) (6, 1934)
    slice(1934, 3840, None) (9, 1906)
    slice(3840, 5543, None) (9, 1703)
    """
    docs, batches = document_batches(db, max_frames)
    joints = None if joints is None else [int(j) for j in joints]
    if client is None:
        fn, items = functools.partial(_local_batch, db, docs, work, joints), batches
    else:
        path, generation = str(Path(db.path).resolve()), db.manifest["generation"]
        fn, items = _remote_batch, [(path, generation, first, last, joints, work) for first, last in batches]
    bar = progress_bar(total=len(docs), desc=desc, unit="doc",
                       disable=not progress or len(docs) <= PROGRESS_MIN_DOCUMENTS)
    with bar, contextlib.closing(map_ordered(fn, items, threads, client, name)) as results:
        for (first, last), (frames, result) in zip(batches, results):
            bar.update(last - first)
            yield frames, result


def _local_batch(db: MotionDB, docs, work: Callable, joints, batch: tuple[int, int]) -> tuple[slice, object]:
    """Documents ``docs.iloc[first:last]`` read, checked and given to ``work``: (frames, result)."""
    frames = read_batch(db, docs, *batch)
    finite_positions(frames.positions, frames.where, joints, CANONICAL_JOINTS)
    return slice(frames.start, frames.stop), work(frames.positions, frames.bounds, frames.fps)


def _remote_batch(task: tuple) -> tuple[slice, object]:
    """A Dask task: (database path, generation, first, last, joints, work) -> :func:`_local_batch` on the worker's
    own memory map of the database."""
    path, generation, first, last, joints, work = task
    db = open_db(path, generation)
    return _local_batch(db, db.documents.sort_values("start"), work, joints, (first, last))


# ------------------------------------------------------------------------------------------- worker side
_OPEN: collections.OrderedDict = collections.OrderedDict()
_OPEN_LOCK = threading.Lock()
_OPEN_MAX = 4


def open_db(path, generation: int):
    """The MotionDB at ``path``, opened once per worker process and generation (memory-mapped).

    Parameters
    ----------
    path : str
        The database directory (as the workers see it).
    generation : int
        The manifest generation the client planned its tasks for.

    Returns
    -------
    mocapviz.MotionDB

    Raises
    ------
    mocapviz.MotionDBError
        The database is now at another generation (it changed while the tasks ran).
    """
    key = (str(Path(path)), int(generation))
    with _OPEN_LOCK:
        db = _OPEN.get(key)
        if db is not None:
            _OPEN.move_to_end(key)
            return db
    db = MotionDB.open(path)
    if db.manifest["generation"] != generation:
        raise MotionDBError(
            f"{path}: the database changed while its features were computed (generation {generation} planned, "
            f"{db.manifest['generation']} found); run again"
        )
    with _OPEN_LOCK:
        _OPEN[key] = db
        while len(_OPEN) > _OPEN_MAX:
            _OPEN.popitem(last=False)
    return db
