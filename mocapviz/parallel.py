"""Running work in parallel: on threads of this process or as tasks of a Dask cluster, results in order.

default_threads   the default ``threads``: the cores this process may use, at most ``MAX_DEFAULT_THREADS``.
parallelism       how many items run at once for given ``threads`` / Dask client.
map_ordered       ``fn(item)`` of every item, on threads or as Dask tasks, yielded in item order.
dask_client       a ``scheduler`` argument ("local", an address, a Client) as a ``dask.distributed.Client``.
optional_client   :func:`dask_client`, or None when ``scheduler`` is None (work in this process).
local_workers     the cores this process may run on (the local cluster's worker processes).
watching          within it, long work reports its progress and stops when asked (cooperative cancellation).
checkpoint        the check between two steps: raises :class:`~mocapviz.errors.Cancelled` when asked to stop.
progress_bar      a tqdm progress bar whose every step is a :func:`checkpoint` and reports to :func:`watching`.

Both back ends follow one rule. Work runs on ``threads`` threads of this process (numpy and numba release the
GIL; ``threads=1`` runs each item in the calling thread when its result is asked for), or as tasks of a
``dask.distributed.Client``. At most ``AHEAD_PER_THREAD`` items per thread (per Dask worker thread) are started
beyond the one whose result is waited for, so that results waiting to be consumed stay few whatever the length
of the input. Results come in item order, not in order of completion, so the first failing item *in that order*
raises its exception. When the consumer stops early (the generator closed, or an exception) the items not
started are cancelled; threads finish the item they are on, Dask tasks are cancelled. Callers that may stop
early wrap the generator in ``contextlib.closing``.

Cooperative cancellation and progress: code run inside ``with watching(cancel, report):`` (in the same thread)
stops between two steps once ``cancel`` is set: every item :func:`map_ordered` yields, and every step of a
:func:`progress_bar` (the batches of :func:`mocapviz.db.batches.map_documents`, the queries, measures and feature
sets of the experiments), is a :func:`checkpoint`, which raises :class:`~mocapviz.errors.Cancelled`. The same steps
call ``report(fraction, label)``: nested bars make one fraction (a step of the outer bar split by the inner one).
Outside :func:`watching` a checkpoint costs one context-variable lookup and does nothing.

A Dask task must be small and importable on the workers: ``fn`` is a module-level function (or a
``functools.partial`` of one) and an item holds paths and ranges, never arrays. Per-document work on a MotionDB
(:func:`mocapviz.db.batches.map_documents`) sends (database path, manifest generation, a range of whole documents)
and the worker opens the memory-mapped database itself.

``scheduler`` values understood by :func:`dask_client` (and by every ``scheduler=`` parameter of mocapviz, where
``None`` means "in this process, as without Dask"):

``"local"``
    Start a :class:`dask.distributed.LocalCluster` sized to the machine: one worker *process* per usable core
    (:func:`local_workers`), one thread each (the tasks are numpy / numba code that would otherwise compete for
    the cores; processes also keep the GIL out of the way of the pure-Python parsers). Closed on exit.
an address, e.g. ``"tcp://10.0.0.5:8786"`` or ``"10.0.0.5:8786"``
    Connect to a running scheduler (``dask scheduler`` + ``dask worker``). The workers must see the same file
    system paths as the client (the motion files and the MotionDB are opened by the workers themselves). Reaching
    it (connection, handshake, an ``identity`` request, registration, a first worker) takes at most
    ``CONNECT_TIMEOUT`` (10 s); a peer that is not a Dask scheduler, or one without workers, is a
    :class:`~mocapviz.errors.SchedulerError` naming the address within that time.
a ``dask.distributed.Client``
    Used as it is, and left open.

The client consumes the results in submission order and is the only writer of a database, so a failed or
cancelled task leaves it as it was. A worker that dies is replaced (the local cluster's nanny restarts it) and
its tasks are run again elsewhere by the scheduler.

See ``docs/architecture.md`` (the base layer).
"""
from __future__ import annotations

import asyncio
import collections
import contextlib
import contextvars
import itertools
import logging
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor

from .errors import Cancelled, ParameterError, SchedulerError
from .validation import count

__all__ = ["AHEAD_PER_THREAD", "LOCAL", "MAX_DEFAULT_THREADS", "checkpoint", "dask_client", "default_threads",
           "local_workers", "map_ordered", "n_threads", "optional_client", "parallelism", "progress_bar",
           "watching"]  # fmt: skip

MAX_DEFAULT_THREADS = 8  # more threads than this rarely pay: the batches are memory-bound
AHEAD_PER_THREAD = 2  # items started beyond the one waited for, per thread (or Dask worker thread)
LOCAL = "local"
CONNECT_TIMEOUT = 10.0  # seconds to reach a scheduler given by address (connect, handshake, identity, a worker)


def local_workers() -> int:
    """Worker processes of the default local cluster: the cores this process may run on (at least 1).

    Returns
    -------
    int
        ``len(os.sched_getaffinity(0))`` (``os.cpu_count()`` where that does not exist).
    """
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
        The bound on reaching a scheduler given by address (default ``CONNECT_TIMEOUT``, 10 s): the connection,
        the Dask handshake, an ``identity`` request, the client's registration and the wait for a first worker
        all count against it (:func:`_connect`).

    Yields
    ------
    dask.distributed.Client

    Raises
    ------
    mocapviz.errors.SchedulerError
        (a ClusterError and an OSError) Within ``timeout``: the scheduler cannot be reached, what answers there is
        not a Dask scheduler, or it has no worker: "cannot reach dask scheduler at ADDRESS: ...".
    mocapviz.ParameterError
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
                             dashboard_address=None, silence_logs=logging.ERROR,
                             # no dashboard; its HTTP routes on a free port (never 8787: a second cluster on the
                             # machine printed "Port 8787 is already in use" into a command's one-line output)
                             scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            )  # fmt: skip
            client = stack.enter_context(Client(cluster))
        else:
            client = stack.enter_context(_connect(os.fspath(scheduler).strip(),
                                                  CONNECT_TIMEOUT if timeout is None else timeout))  # fmt: skip
        yield client


def _connect(address: str, timeout: float):
    """A Client of the Dask scheduler at ``address`` with at least one worker, or a SchedulerError within
    ``timeout`` seconds (plus the time to start a thread).

    The Client of distributed bounds its connection and registration by its ``timeout`` but not the handshake
    that comes between (a peer that accepts and never answers holds it forever), and it reads whatever a peer
    sends as a Dask frame (an HTTP status line is a 3 EiB frame length). So a probe first makes the same
    connection, handshake and an ``identity`` request on a thread of its own, under one deadline
    (:func:`_probe`); only a peer that answered as a Dask scheduler gets the Client, with the time left.
    """
    from distributed import Client

    deadline = time.monotonic() + timeout
    _probe(address, timeout)
    try:
        client = Client(address, timeout=max(0.5, deadline - time.monotonic()))
    except (OSError, ValueError, TimeoutError) as exc:
        raise SchedulerError(f"cannot reach dask scheduler at {address}: {_first_line(exc)}") from None
    try:
        client.wait_for_workers(1, timeout=max(0.5, deadline - time.monotonic()))
    except (OSError, TimeoutError):
        client.close()
        raise SchedulerError(f"cannot reach dask scheduler at {address}: it has no worker (waited {timeout:g} s "
                             "in all; start `dask worker ADDRESS`)") from None  # fmt: skip
    return client


def _probe(address: str, timeout: float) -> None:
    """Connect to ``address``, make the Dask handshake and ask the peer's ``identity``, all within ``timeout``
    seconds, on a thread of its own (so that it needs no event loop of the caller's and a stuck read cannot
    outlive the bound); raise a SchedulerError unless the peer answered as a Dask scheduler."""
    outcome: dict = {}

    def ask() -> None:
        try:
            outcome["identity"] = asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))
        except BaseException as exc:  # noqa: BLE001 - whatever a peer that is not Dask makes the comm layer raise
            outcome["error"] = exc

    thread = threading.Thread(target=ask, name="mocapviz-scheduler-probe", daemon=True)
    thread.start()
    thread.join(timeout + 1.0)  # (asyncio.wait_for has cancelled the request by then)
    error, kind = outcome.get("error"), (outcome.get("identity") or {}).get("type")
    if kind == "Scheduler":
        return
    if error is None and kind is not None:
        why = f"what answers there is a Dask {kind}, not a scheduler"
    elif error is None or isinstance(error, TimeoutError):
        why = (f"no answer as a Dask scheduler within {timeout:g} s (it accepts connections but does not speak the "
               "Dask protocol, or nothing answers)")  # fmt: skip
    elif isinstance(error, OSError):
        why = _first_line(error)
    elif isinstance(error, MemoryError):  # (the first 8 bytes of "HTTP/1.0 426 ..." are a 3 EiB frame length)
        why = "what answers there does not speak the Dask protocol (its reply announces a message larger than memory)"
    else:  # (a reply that is not a Dask message: a msgpack error, ...)
        why = f"what answers there does not speak the Dask protocol ({type(error).__name__}: {_first_line(error)})"
    raise SchedulerError(f"cannot reach dask scheduler at {address}: {why}")


async def _identity(address: str, timeout: float) -> dict:
    """The ``identity`` of the Dask server at ``address`` (``{"type": "Scheduler", ...}``), over one connection."""
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity", "reply": True})
        reply = await comm.read()
    finally:
        comm.abort()
    return reply if isinstance(reply, dict) else {}


def _first_line(exc: BaseException, limit: int = 200) -> str:
    """An exception's first line, at most ``limit`` characters (its type's name when it has no text)."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text if len(text) <= limit else text[:limit] + "…"


@contextlib.contextmanager
def optional_client(scheduler) -> Iterator:
    """:func:`dask_client` of ``scheduler``, or None (no Dask: work in this process) when ``scheduler`` is None.

    Parameters
    ----------
    scheduler : None, "local", str or dask.distributed.Client
        As every ``scheduler=`` parameter of mocapviz (see the module docstring).

    Yields
    ------
    dask.distributed.Client or None
        Closed on exit when started here.
    """
    if scheduler is None:
        yield None
        return
    with dask_client(scheduler) as client:
        yield client


def n_threads(client) -> int:
    """Worker threads of a Dask client's cluster now (at least 1).

    Parameters
    ----------
    client : dask.distributed.Client
        A connected client.

    Returns
    -------
    int
    """
    return max(1, sum(client.nthreads().values()))


def default_threads() -> int:
    """The default ``threads`` of mocapviz: the cores this process may run on (``os.sched_getaffinity``), at most
    ``MAX_DEFAULT_THREADS`` (8), at least 1.

    Returns
    -------
    int

    Examples
    --------
    >>> 1 <= default_threads() <= MAX_DEFAULT_THREADS
    True
    """
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
        for item in items:
            checkpoint()
            yield fn(item)
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
            checkpoint()
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


# ------------------------------------------------------------------------------- cancellation and progress
class _Watch:
    """The ``cancel`` and ``report`` of one :func:`watching` block, and its open progress bars, outermost first."""

    def __init__(self, cancel, report, outer: _Watch | None):
        own = cancel.is_set if hasattr(cancel, "is_set") else (cancel or (lambda: False))
        self.cancelled = own if outer is None else (lambda: own() or outer.cancelled())
        self.report = report
        self.bars: list = []

    def fraction(self) -> float:
        """Done of the outermost bar, each of its steps split by the bars inside it (unknown totals count 0)."""
        inner = 0.0
        for bar in reversed(self.bars):
            inner = min(1.0, (bar.n + inner) / bar.total) if bar.total else 0.0
        return inner

    def step(self) -> None:
        if self.cancelled():
            raise Cancelled("cancelled")
        if self.report is not None:
            label = " › ".join(f"{b.desc} {b.n:,}/{b.total:,}" if b.total else b.desc for b in self.bars if b.desc)
            self.report(self.fraction(), label)


_WATCH: contextvars.ContextVar = contextvars.ContextVar("mocapviz_watch", default=None)


@contextlib.contextmanager
def watching(cancel=None, report: Callable[[float, str], None] | None = None) -> Iterator[None]:
    """Within the block (in this thread), long work stops between two steps when ``cancel`` is set and reports its
    progress. A block inside another stops when either is cancelled; its steps are reported to its own ``report``.

    Parameters
    ----------
    cancel : threading.Event or callable, optional
        Set (or returning True) when the work is to stop: the next :func:`checkpoint` raises
        :class:`~mocapviz.errors.Cancelled`.
    report : callable, optional
        ``report(fraction, label)`` at every step of a :func:`progress_bar`: the fraction done in [0, 1] over the
        bars open now (a step of an outer bar is split by the bars inside it) and their descriptions and counts,
        e.g. ``"Table 2 1/3 › relational features 120/3,395"``.

    Examples
    --------
    >>> import threading
    >>> from mocapviz.errors import Cancelled
    >>> stop, seen = threading.Event(), []
    >>> try:
    ...     with watching(stop, lambda fraction, label: seen.append(round(fraction, 2))):
    ...         for i in progress_bar(range(4), desc="steps", disable=True):
    ...             if i == 2:
    ...                 stop.set()
    ... except Cancelled:
    ...     print("stopped after", seen)
    stopped after [0.0, 0.25, 0.5]
    """
    token = _WATCH.set(_Watch(cancel, report, _WATCH.get()))
    try:
        yield
    finally:
        _WATCH.reset(token)


def checkpoint() -> None:
    """Between two steps of long work: raise :class:`~mocapviz.errors.Cancelled` when the :func:`watching` block
    around it was asked to stop (nothing outside one).

    Raises
    ------
    mocapviz.errors.Cancelled
    """
    watch = _WATCH.get()
    if watch is not None and watch.cancelled():
        raise Cancelled("cancelled")


class progress_bar:  # lower case, as tqdm: used as a function
    """``tqdm(iterable, total=, desc=, unit=, disable=)`` whose every step (an item taken, an :meth:`update`) is a
    :func:`checkpoint` and is reported to the :func:`watching` block around it, shown or not (``disable``).

    Parameters
    ----------
    iterable : iterable, optional
        The steps (its length the total when it has one).
    total : int, optional
        Steps in all, for :meth:`update`.
    desc, unit : str
        As tqdm's.
    disable : bool
        No bar on the terminal (the steps still report and check).

    Examples
    --------
    >>> with progress_bar(total=3, desc="batches", disable=True) as bar:
    ...     bar.update(2)
    ...     print(bar.n, bar.total)
    2 3
    """

    def __init__(self, iterable=None, total: int | None = None, desc: str = "", unit: str = "it",
                 disable: bool = False, **options):  # fmt: skip
        from tqdm.auto import tqdm  # here, not at import: a command without progress bars does not load it

        if total is None and hasattr(iterable, "__len__"):
            total = len(iterable)
        self.iterable, self.total, self.desc, self.n = iterable, total, desc, 0
        self._watch = _WATCH.get()
        checkpoint()
        self._tqdm = tqdm(iterable, total=total, desc=desc, unit=unit, disable=disable, **options)
        if self._watch is not None:
            self._watch.bars.append(self)
            self._watch.step()

    def __iter__(self):
        try:
            for item in self._tqdm:
                yield item
                self.n += 1
                self._step()
        finally:
            self.close()

    def update(self, n: int = 1) -> None:
        """``n`` more steps done."""
        self._tqdm.update(n)
        self.n += n
        self._step()

    def _step(self) -> None:
        if self._watch is not None:
            self._watch.step()

    def close(self) -> None:
        self._tqdm.close()
        if self._watch is not None and self in self._watch.bars:
            self._watch.bars.remove(self)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
