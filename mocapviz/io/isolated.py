"""Reading a file with native code (ezc3d) where a crash cannot take the calling process down.

read_isolated   ``function(path, *args)`` computed in a helper process and its result returned; a crash, a hang,
                running out of its memory or an exception there becomes a MocapFormatError naming the file.

How: each thread that reads gets a *helper*, a small Python process started with :mod:`subprocess` (so also inside
Dask's daemonic worker processes, where :mod:`multiprocessing` may not start children, and under the Panel server's
threads, where forking the server itself is unsafe). The helper imports the reader once, then reads one file per
request, single-threaded, under a memory limit, and sends the result back through a pipe. A helper that crashed or
hung is gone (the next read starts a new one); one whose read raised is retired too (native code that failed may
have left its memory in a bad state); one that read well is kept for the thread's next file. Helpers end with their
caller: they read their requests from a pipe that closes with it.

Cost (docs/c3d.md): about 0.4 s to start a helper, once per reading thread; then about 1 % of the read, the pickled
result copied through a pipe. A child forked per read would isolate every read from the others but cost 45 % more
(the page faults of a fresh process, measured on the 12 files of the ``c3d-markers`` archive), so a helper is
replaced only after a read that failed.
"""

from __future__ import annotations

import atexit
import fcntl
import importlib
import os
import pickle
import resource
import select
import signal
import struct
import subprocess
import sys
import threading
import time

from ..errors import MocapFormatError

_REPLY = struct.Struct("<bq")  # kind, payload bytes
_VALUE, _RAISED, _READY = 0, 1, 2
_PIPE_BYTES = 1 << 20
_START_S = 60.0  # a helper not ready after this is given up
_EXIT_S = 5.0  # a helper whose pipe closed is waited for this long before it is killed
_BOOT = ("import sys; sys.path[:0] = sys.argv[3:]; from mocapviz.io.isolated import _serve; "
         "_serve(*map(int, sys.argv[1:3]))")  # the helper: the caller's sys.path, then the loop


def read_isolated(function, path, *args, reader: str, preload: tuple = (), memory: int, timeout: float):
    """``function(path, *args)`` computed in this thread's helper process.

    Parameters
    ----------
    function : callable
        A module-level function (the helper imports it by module and name); its arguments and result must pickle.
    path : str
        The file it reads, for the messages.
    *args
        More arguments of ``function``.
    reader : str
        What reads, for the messages ("the C3D reader (ezc3d)").
    preload : tuple of str
        Modules the helper imports when it starts (the native library), not while a read is timed.
    memory : int, bytes
        The address space the call may add to what the helper maps (``RLIMIT_AS``, where ``/proc`` tells the
        helper's size: Linux): a reader allocating more fails with a MemoryError instead of exhausting the machine.
    timeout : float, seconds
        How long the call may take; then the helper is killed.

    Returns
    -------
    object
        What ``function`` returned.

    Raises
    ------
    MocapFormatError
        Naming ``path``: "``reader`` crashed on this file (signal 11, SIGSEGV)", "``reader`` raised ``Type:
        message``", "``reader`` needed more than its ``memory`` MiB", "``reader`` did not finish within ``timeout``
        s", or no helper could be started.
    """
    request = pickle.dumps(("call", function.__module__, function.__qualname__, (path, *args), memory))
    try:
        helper = _take(preload)
        kind, payload = helper.call(request, timeout)
    except TimeoutError:
        helper.kill()
        raise MocapFormatError(path, f"{reader} did not finish within {timeout:g} s") from None
    except EOFError:
        raise MocapFormatError(path, f"{reader} crashed on this file ({_how(helper.ended())})") from None
    except OSError as exc:  # no helper started, or it had ended before the request (then killed)
        raise MocapFormatError(path, f"{reader} could not be run in a helper process ({exc})") from None
    except BaseException:  # interrupted (KeyboardInterrupt): nobody would read the helper's reply
        helper.kill()
        raise
    if kind == _RAISED:
        helper.close()
        raised = payload.decode(errors="replace")
        if raised.startswith("MemoryError") or raised.endswith("std::bad_alloc"):  # Python's, or C++'s via SWIG
            raise MocapFormatError(path, f"{reader} needed more than its {memory / 2**20:g} MiB ({raised})")
        raise MocapFormatError(path, f"{reader} raised {raised}")
    _give_back(helper, preload)
    return pickle.loads(payload)


def _how(code: int) -> str:
    """``signal 11, SIGSEGV`` of a negative return code, ``exit 3`` of a positive one."""
    if code < 0 and -code in signal.valid_signals():
        return f"signal {-code}, {signal.Signals(-code).name}"
    return f"exit {code}"


# ------------------------------------------------------------------------------------------------------ caller side
class _Helper:
    """One helper process and the two pipes to it (requests in, replies out)."""

    def __init__(self, preload: tuple):
        to_helper, self._requests = os.pipe()
        self._replies, from_helper = _pipe()
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", _BOOT, str(to_helper), str(from_helper), *sys.path],
                pass_fds=(to_helper, from_helper), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL, start_new_session=True,
            )  # fmt: skip
        finally:
            os.close(to_helper)
            os.close(from_helper)
        try:
            self.call(pickle.dumps(("preload", preload)), _START_S)
        except EOFError:
            raise OSError(f"the helper process ended while starting ({_how(self.ended())})") from None
        except TimeoutError:
            self.kill()
            raise OSError(f"the helper process was not ready within {_START_S:g} s") from None
        except BaseException:
            self.kill()
            raise

    def call(self, request: bytes, timeout: float) -> tuple[int, bytes]:
        """Send one request; (kind, payload) of the reply. TimeoutError after ``timeout`` s; EOFError when the
        helper ended before it replied; OSError when it had ended before the request (then it is closed)."""
        try:
            _write_all(self._requests, struct.pack("<q", len(request)) + request)
        except OSError:
            self.kill()
            raise
        deadline = time.monotonic() + timeout
        kind, size = _REPLY.unpack(self._read(_REPLY.size, deadline))
        return kind, bytes(self._read(size, deadline))

    def _read(self, size: int, deadline: float) -> bytearray:
        out = bytearray(size)
        view, done = memoryview(out), 0
        ready = select.poll()  # not select.select: a server's descriptors may number beyond 1024
        ready.register(self._replies, select.POLLIN)
        while done < size:
            left = deadline - time.monotonic()
            if left <= 0 or not ready.poll(left * 1000):
                raise TimeoutError
            got = os.readv(self._replies, [view[done:]])
            if not got:
                raise EOFError
            done += got
        return out

    def close(self) -> None:
        """Close the pipes: the helper reads the end of its requests and exits."""
        os.close(self._requests)
        os.close(self._replies)
        try:
            self.process.wait(_EXIT_S)
        except subprocess.TimeoutExpired:
            self.kill()

    def ended(self) -> int:
        """The return code of a helper whose reply pipe closed (negative: the signal that ended it)."""
        self.close()
        return self.process.returncode

    def kill(self) -> None:
        """Kill the helper (its own process group) and close the pipes."""
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.forget()
        self.process.wait()

    def forget(self) -> None:
        """Close this process's ends of the pipes (in a forked copy of the caller: the helper stays the original's)."""
        for fd in (self._requests, self._replies):
            try:
                os.close(fd)
            except OSError:  # closed already
                pass


def _pipe() -> tuple[int, int]:
    """A pipe holding up to 1 MiB (Linux's default of 64 KiB makes a result of megabytes cost a process switch per
    64 KiB)."""
    read_end, write_end = os.pipe()
    try:
        fcntl.fcntl(write_end, fcntl.F_SETPIPE_SZ, _PIPE_BYTES)
    except OSError:  # above /proc/sys/fs/pipe-max-size: keep the default
        pass
    return read_end, write_end


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


_idle: dict[tuple, list[_Helper]] = {}  # preloaded modules -> helpers waiting for a read
_lock = threading.Lock()


def _take(preload: tuple) -> _Helper:
    """An idle helper that preloaded ``preload`` and is still running, or a new one."""
    with _lock:
        helpers = _idle.get(preload, [])
        while helpers:
            helper = helpers.pop()
            if helper.process.poll() is None:
                return helper
            helper.forget()  # ended while idle (killed from outside)
    return _Helper(preload)


def _give_back(helper: _Helper, preload: tuple) -> None:
    with _lock:
        _idle.setdefault(preload, []).append(helper)


def _close_all() -> None:
    with _lock:
        for helpers in _idle.values():
            while helpers:
                helpers.pop().close()


def _after_fork_in_child() -> None:
    global _lock
    _lock = threading.Lock()
    for helpers in _idle.values():
        while helpers:
            helpers.pop().forget()


atexit.register(_close_all)
os.register_at_fork(after_in_child=_after_fork_in_child)


# ------------------------------------------------------------------------------------------------------ helper side
def _serve(requests: int, replies: int) -> None:
    """The helper's loop: the modules to preload, then one call per request until the caller closes the pipe."""
    with os.fdopen(requests, "rb") as inp, os.fdopen(replies, "wb") as out:
        while head := inp.read(8):
            what, *request = pickle.loads(inp.read(struct.unpack("<q", head)[0]))
            if what == "call":
                kind, payload = _call(*request)
            else:  # "preload", the first request
                for module in request[0]:
                    importlib.import_module(module)
                kind, payload = _READY, b""
            out.write(_REPLY.pack(kind, len(payload)))
            out.write(payload)
            out.flush()


def _call(module: str, name: str, args: tuple, memory: int) -> tuple[int, bytes]:
    """(kind, payload) of ``module.name(*args)`` computed under the memory limit: the pickled result, or the
    exception as ``Type: message``."""
    try:
        function = getattr(importlib.import_module(module), name)  # imported before the limit, once per helper
        _limit_memory(memory)
        return _VALUE, pickle.dumps(function(*args), pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # noqa: BLE001 - any failure of the reader is reported, typed, by the caller
        return _RAISED, ": ".join([type(exc).__name__] + [str(exc)] * bool(str(exc))).encode(errors="replace")[:2000]


def _limit_memory(memory: int) -> None:
    """Allow this process ``memory`` bytes of address space beyond what it maps now (Linux; elsewhere no limit)."""
    try:
        with open("/proc/self/statm") as statm:
            limit = os.sysconf("SC_PAGE_SIZE") * int(statm.read().split()[0]) + memory
    except OSError:
        return
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    resource.setrlimit(resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard))
