"""The C heap's settings (mocapviz.heap), measured in real processes started as Dask's nanny starts its workers
(MALLOC_TRIM_THRESHOLD_=65536 in the environment): page faults of repeated 4 MB temporary arrays."""
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
np.ones(1 << 19).sum()  # the first allocation of the size may fault in either case
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    np.ones(1 << 19).sum()  # 4 MB allocated, touched, freed
print(json.dumps({"faults": resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before, "kept": kept}))
"""


def probe(mode: str) -> dict:
    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_a_worker_like_process_faults_in_every_temporary_array_until_it_keeps_freed_memory():
    pinned, kept = probe("pinned"), probe("keep")
    assert kept["kept"] is True
    assert pinned["faults"] >= 50 * 100  # each array mapped afresh and its pages faulted in again
    assert kept["faults"] < pinned["faults"] / 20
