"""Running ingest and feature extraction on Dask (a local cluster, or a ``dask.distributed`` scheduler).

The one place that turns a ``scheduler`` argument into a :class:`dask.distributed.Client` and closes what it
started, and where the workers open a MotionDB. The tasks themselves are run by :mod:`mocapviz.batch` (the same
ordered map with bounded look-ahead as on threads).

``scheduler`` values understood by :func:`dask_client` (and by every ``scheduler=`` parameter of mocapviz, where
``None`` means "in this process, as without Dask"):

``"local"``
    Start a :class:`dask.distributed.LocalCluster` sized to the machine: one worker *process* per usable core
    (:func:`local_workers`), one thread each (the tasks are numpy / numba code that would otherwise compete for
    the cores; processes also keep the GIL out of the way of the pure-Python parsers). Closed on exit.
an address, e.g. ``"tcp://10.0.0.5:8786"`` or ``"10.0.0.5:8786"``
    Connect to a running scheduler (``dask scheduler`` + ``dask worker``). The workers must see the same file
    system paths as the client (the motion files and the MotionDB are opened by the workers themselves).
a ``dask.distributed.Client``
    Used as it is, and left open.

Tasks are small: file paths (ingest) or a database path, its generation and a range of whole documents
(features); the worker opens the memory-mapped :class:`~mocapviz.database.MotionDB` itself (:func:`open_db`) and
returns numpy arrays. The client consumes the results in submission order (:func:`mocapviz.batch.map_ordered`)
and is the only writer of the database, so a failed or cancelled task leaves the database as it was. A worker
that dies is replaced (the local cluster's nanny restarts it) and its tasks are run again elsewhere by the
scheduler.
"""
from __future__ import annotations

import collections
import contextlib
import logging
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from .errors import ParameterError

LOCAL = "local"
CONNECT_TIMEOUT = 10.0  # seconds to wait for a scheduler given by address

__all__ = ["LOCAL", "dask_client", "local_workers", "n_threads", "open_db", "optional_client"]


def local_workers() -> int:
    """Worker processes of the default local cluster: the cores this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def dask_client(scheduler=LOCAL, n_workers: int | None = None, timeout: float | None = None) -> Iterator:
    """A :class:`dask.distributed.Client` for ``scheduler``, closed on exit if this call started it.

    Parameters
    ----------
    scheduler : "local", str or dask.distributed.Client
        ``"local"``: start a LocalCluster (``n_workers`` processes, default :func:`local_workers`, one thread
        each) and stop it on exit. A scheduler address (``"tcp://host:8786"``, ``"host:8786"``): connect, and
        disconnect on exit (the cluster keeps running). A Client: yielded as it is and left open.
    n_workers : int, optional
        Workers of a local cluster (ignored otherwise).
    timeout : float, seconds, optional
        How long to try to reach a scheduler given by address (default ``CONNECT_TIMEOUT``, 10 s).

    Yields
    ------
    dask.distributed.Client

    Raises
    ------
    OSError
        The scheduler cannot be reached: "cannot reach dask scheduler at ADDRESS: ...".
    TypeError
        ``scheduler`` is neither a string nor a Client.
    """
    from distributed import Client, LocalCluster

    if isinstance(scheduler, Client):
        yield scheduler
        return
    if not isinstance(scheduler, (str, os.PathLike)):
        raise ParameterError(f"scheduler must be 'local', a dask scheduler address or a dask Client, got {scheduler!r}")
    with contextlib.ExitStack() as stack:
        if str(scheduler) == LOCAL:
            cluster = stack.enter_context(
                LocalCluster(n_workers=n_workers or local_workers(), threads_per_worker=1, processes=True,
                             dashboard_address=None, silence_logs=logging.ERROR)
            )  # fmt: skip
            client = stack.enter_context(Client(cluster))
        else:
            address = os.fspath(scheduler).strip()
            try:
                client = Client(address, timeout=CONNECT_TIMEOUT if timeout is None else timeout)
            except (OSError, ValueError, TimeoutError) as exc:
                detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                raise OSError(f"cannot reach dask scheduler at {address}: {detail}") from None
            stack.enter_context(client)
        yield client


@contextlib.contextmanager
def optional_client(scheduler) -> Iterator:
    """:func:`dask_client` of ``scheduler``, or None (no Dask: work in this process) when ``scheduler`` is None."""
    if scheduler is None:
        yield None
        return
    with dask_client(scheduler) as client:
        yield client


def n_threads(client) -> int:
    """Worker threads of a Dask client's cluster now (at least 1)."""
    return max(1, sum(client.nthreads().values()))


# ------------------------------------------------------------------------------------------- worker side
_OPEN: collections.OrderedDict = collections.OrderedDict()
_OPEN_LOCK = threading.Lock()
_OPEN_MAX = 4


def open_db(path, generation: int):
    """The MotionDB at ``path``, opened once per worker process and generation (memory-mapped).

    Parameters
    ----------
    path : str, the database directory (as the workers see it)
    generation : int, the manifest generation the client planned its tasks for

    Returns
    -------
    mocapviz.MotionDB

    Raises
    ------
    mocapviz.MotionDBError
        The database is now at another generation (it changed while the tasks ran).
    """
    from .database import MotionDB
    from .errors import MotionDBError

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
