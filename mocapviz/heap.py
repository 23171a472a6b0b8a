"""The C heap of this process (glibc's malloc): give its free pages back to the system, or keep them for the next
query.

A search allocates temporary arrays of a few hundred kB to tens of MB and frees them when it answers. glibc decides
what happens to that memory with two thresholds: blocks above ``M_MMAP_THRESHOLD`` are mapped and unmapped for each
allocation, and free memory above ``M_TRIM_THRESHOLD`` at the top of the heap is returned to the system. Both adapt
to the program (up to 32 MB and 64 MB) unless a threshold was set, and Dask's nanny sets one in every worker it
starts (``MALLOC_TRIM_THRESHOLD_=65536``, ``distributed.nanny.pre-spawn-environ``): there every array above 128 kB is
mapped afresh and its pages faulted in on every query. A shard's two-event scene query at 10M frames took 35 ms of
CPU in such a worker against 16 ms in a plain process (thread time of ``Shard.find`` measured inside the workers);
with :func:`keep_freed_memory` the sharded query's median went from 45 to 24 ms.

Python's own objects (those up to 512 bytes: most of a page's widgets, models and dicts) come from CPython's
allocator, pymalloc, in 1 MB arenas that return to the system only when every object in them is gone. A closed
browser session frees some 15 MB of such objects, spread over arenas that long-lived objects (imports, caches) share:
the arenas stay, and ``malloc_trim`` cannot reach them. With ``PYTHONMALLOC=malloc`` those objects come from glibc's
heap like any other, and trimming returns each free page of it.

=========================== ==================================================================================
trim_free_memory            give the heap's free pages back to the system now (a server after a job or a closed
                            session)
keep_freed_memory           let this process reuse freed memory for the next queries (a shard resident on a
                            worker)
restart_with_trimmable_heap run this program again with Python's objects on glibc's heap (``mocapviz serve``)
=========================== ==================================================================================

They do nothing where the C library is not glibc.
"""
from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["keep_freed_memory", "restart_with_trimmable_heap", "trim_free_memory"]

M_TRIM_THRESHOLD = -1  # mallopt parameters (glibc's malloc.h)
M_MMAP_THRESHOLD = -3
MMAP_BYTES = 32 << 20  # glibc's own ceiling for its adaptive thresholds on 64-bit systems
TRIM_BYTES = 64 << 20


def _libc():
    try:
        libc = ctypes.CDLL("libc.so.6")
        return libc if hasattr(libc, "mallopt") else None
    except OSError:  # not glibc
        return None


def trim_free_memory() -> None:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing elsewhere): the temporary
    arrays of a search, once freed, then leave the process's resident memory instead of staying as free heap.

    Examples
    --------
    >>> trim_free_memory()
    """
    libc = _libc()
    if libc is not None:
        libc.malloc_trim(0)


def keep_freed_memory(mmap_bytes: int = MMAP_BYTES, trim_bytes: int = TRIM_BYTES) -> bool:
    """Let this process keep and reuse the memory its queries free: blocks below ``mmap_bytes`` come from the heap
    (not a fresh mapping each time), and the heap is returned to the system only when more than ``trim_bytes`` of it
    is free at its top. These are the values glibc's adaptive thresholds reach on their own; this sets them where an
    environment variable (Dask's nanny) pinned them low. Process-wide and lasting.

    Parameters
    ----------
    mmap_bytes : int
        ``M_MMAP_THRESHOLD``: the smallest block that gets a mapping of its own (bytes).
    trim_bytes : int
        ``M_TRIM_THRESHOLD``: free bytes at the heap's top above which they are returned to the system.

    Returns
    -------
    bool
        True when glibc took both settings; False elsewhere (nothing changed).

    Examples
    --------
    >>> applied = keep_freed_memory()  # True where the C library is glibc
    """
    libc = _libc()
    if libc is None:
        return False
    return bool(libc.mallopt(M_MMAP_THRESHOLD, int(mmap_bytes))) and bool(libc.mallopt(M_TRIM_THRESHOLD,
                                                                                           int(trim_bytes)))


def restart_with_trimmable_heap() -> None:
    """Replace this process (``os.execve``: same pid, command line and environment) by one whose Python objects come from
    glibc's heap (``PYTHONMALLOC=malloc``), so that :func:`trim_free_memory` gives back what a long-running server
    frees, small objects included; pymalloc keeps an arena while any object in it lives. Does nothing (returns)
    where the C library is not glibc, or when ``PYTHONMALLOC`` is set already (the restarted process, or a user's
    choice: ``PYTHONMALLOC=pymalloc`` keeps CPython's allocator). Call it first thing in a program's main: anything
    done before it is done twice, and it never returns when it restarts.
    """
    if _libc() is None or "PYTHONMALLOC" in os.environ:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *sys.orig_argv[1:]], {**os.environ, "PYTHONMALLOC": "malloc"})
