"""The C heap's settings (mocapviz.heap), measured in real processes: started as Dask's nanny starts its workers
(MALLOC_TRIM_THRESHOLD_=65536 in the environment), page faults of repeated 1 MB temporary arrays; restarted with
Python's objects on glibc's heap (``mocapviz serve``), the resident memory small objects leave when freed."""
import json
import os
import subprocess
import sys

import pytest

from mocapviz.heap import _libc

pytestmark = pytest.mark.skipif(_libc() is None, reason="the C library is not glibc: mocapviz.heap does nothing")

PROBE = """
import json, resource, sys
import numpy as np
from mocapviz.heap import keep_freed_memory
kept = keep_freed_memory() if sys.argv[1] == "keep" else None
np.ones(1 << 17).sum()  # the first allocation of the size may fault in either case
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    np.ones(1 << 17).sum()  # 1 MB allocated, touched, freed (under 2 MB: no huge page can back its mapping)
print(json.dumps({"faults": resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before, "kept": kept}))
"""


def probe(mode: str) -> dict:
    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_a_worker_like_process_faults_in_every_temporary_array_until_it_keeps_freed_memory():
    pinned, kept = probe("pinned"), probe("keep")
    assert kept["kept"] is True
    assert pinned["faults"] >= 50 * 100  # each array mapped afresh and its 256 pages faulted in again
    assert kept["faults"] < pinned["faults"] / 20


FRAGMENTS = """
import gc, json, os, sys
from mocapviz.heap import restart_with_trimmable_heap, trim_free_memory
restart_with_trimmable_heap()
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
before = rss()
objects = [{"i": i, "name": f"object {i}"} for i in range(1_000_000)]  # small objects, as a session's pages make
kept = objects[::500]  # a few survive among them (what a cache or an import keeps meanwhile)
grown = rss() - before
del objects
gc.collect()
trim_free_memory()
print(json.dumps({"pythonmalloc": os.environ.get("PYTHONMALLOC"), "grown": grown, "kept": rss() - before}))
"""


def fragments(env: dict) -> dict:
    out = subprocess.run([sys.executable, "-c", FRAGMENTS], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_a_restarted_server_gives_back_the_small_objects_it_freed_between_survivors():
    """A million small objects with one in 500 kept, the rest freed, then the heap trimmed: with CPython's pymalloc
    (PYTHONMALLOC=pymalloc, which the restart respects) every 1 MB arena still holds a survivor and the memory stays;
    restarted on glibc's heap, the free pages between the survivors go back to the system."""
    base = {k: v for k, v in os.environ.items() if k != "PYTHONMALLOC"}
    restarted, pymalloc = fragments(base), fragments({**base, "PYTHONMALLOC": "pymalloc"})
    assert restarted["pythonmalloc"] == "malloc" and pymalloc["pythonmalloc"] == "pymalloc"
    assert pymalloc["grown"] > 100e6 and restarted["grown"] > 100e6
    assert pymalloc["kept"] > 0.8 * pymalloc["grown"]  # the arenas stay
    assert restarted["kept"] < 0.2 * restarted["grown"]  # the pages go
