"""Checked reads (issue 29 scope 2): what verifying every block of the frame arrays and numeric features by its xxh3
when first read costs, on bench_relational's 120 Hz database (``DATABASE``, cache tag ``relational-v2``).

Each figure from a fresh process (``subprocess``), after one untimed run that fills the page cache, ``repeats``
times, median reported:

- **open**: ``MotionDB.open(path)`` (sizes, the schema of the manifest, the documents table's sha256; the arrays
  are mapped, nothing of them read);
- **first search**: open, then ``SimilaritySearch(db, "F15E").clips(DOC, n_matches=10)`` (its F15E set
  verified whole on load, its example's position blocks on read), and the same call again in that process (every
  block then already verified);
- **verify**: every block of positions, quaternions and F15E by xxh3 (``mocapviz.checked_map.verified_blocks``),
  against the fair baseline of the same bytes through sha256 (``hashlib``), each file read from the page cache;
- **full check**: ``mocapviz check DB`` (sha256 of every file, derived data included).

The database's manifest and its F15E header get block hashes first if they were written without them
(``MotionDB.add_block_checksums``, ``store_numeric``), said in the output.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from .bench_relational import DATABASE
from .common import REPO, CpuMonitor, benchmark_db, describe_db, header, log, machine_info, markdown

DOC = 7  # the example document of the first search
TARGET_OPEN_S = 1.0

_OPEN = "import sys, time; from mocapviz import MotionDB; t = time.perf_counter(); MotionDB.open(sys.argv[1]); " \
        "print(time.perf_counter() - t)"  # fmt: skip
_SEARCH = """
import sys, time
import numpy as np
from mocapviz import MotionDB
from mocapviz.similarity import SimilaritySearch
if sys.argv[3] == "unchecked":  # the baseline: the same search with every check on read switched off
    import mocapviz.db.database, mocapviz.features.numeric
    mocapviz.db.database.open_checked = lambda f, *a: np.load(f, mmap_mode="r")
    mocapviz.features.numeric.verified_blocks = lambda *a, **k: None
t = time.perf_counter()
db = MotionDB.open(sys.argv[1])
SimilaritySearch(db, "F15E").clips(int(sys.argv[2]), n_matches=10)
first = time.perf_counter() - t
t = time.perf_counter()
SimilaritySearch(db, "F15E").clips(int(sys.argv[2]), n_matches=10)
print(first, time.perf_counter() - t)
"""
_VERIFY = """
import hashlib, json, sys, time
from mocapviz.checked_map import verified_blocks
f, fp = sys.argv[1], json.loads(sys.argv[2])
t = time.perf_counter(); verified_blocks(f, fp); xxh = time.perf_counter() - t
t = time.perf_counter()
with open(f, "rb") as fh:
    hashlib.file_digest(fh, "sha256")
print(xxh, time.perf_counter() - t)
"""


def _run(code: str, *args: str) -> list[float]:
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=True, cwd=REPO,
                         env=dict(os.environ, PYTHONPATH=str(REPO))).stdout  # fmt: skip
    return [float(v) for v in out.split()]


def _median(code: str, args: list[str], repeats: int) -> list[float]:
    _run(code, *args)  # warm: page cache, numba's disk cache
    runs = [_run(code, *args) for _ in range(repeats)]
    return [statistics.median(r[i] for r in runs) for i in range(len(runs[0]))]


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from mocapviz.db import layout
    from mocapviz.features.numeric import store_numeric

    t_start = time.perf_counter()
    monitor, info = CpuMonitor(), machine_info()
    db, record = benchmark_db(DATABASE, quick)
    notes = describe_db(db, record)
    if not all("xxh3" in c for c in db.manifest["checksums"].values()):
        t0 = time.perf_counter()
        db = db.add_block_checksums()
        notes.append(f"block hashes added to the manifest (written before they were kept): "
                     f"{time.perf_counter() - t0:.1f} s, sha256 of each array checked first")  # fmt: skip
    data, head = layout.numeric_data(db.path, "F15E"), layout.numeric_header(db.path, "F15E")
    if not head.is_file() or "xxh3" not in (json.loads(head.read_text()).get("data") or {}):
        log("storing F15E with block hashes")
        store_numeric(db, ["F15E"], progress=False)
        notes.append("F15E stored again (its header was written before block hashes were kept)")
    files = [(name, db.path / f, db.manifest["checksums"][f]) for name, f in db.manifest["arrays"].items()]
    files.append(("F15E", data, json.loads(head.read_text())["data"]))
    path = str(db.path)
    log("open")
    t_open = _median(_OPEN, [path], repeats)[0]
    log("first search")
    first, again = _median(_SEARCH, [path, str(DOC), "checked"], repeats)
    first_plain, again_plain = _median(_SEARCH, [path, str(DOC), "unchecked"], repeats)
    rows = []
    for name, f, fp in files:
        log(f"verify {name}")
        xxh, sha = _median(_VERIFY, [str(f), json.dumps(fp)], repeats)
        rows.append([name, f"{fp['size'] / 2**20:,.0f}", f"{len(fp['xxh3'])}", f"{xxh:.3f}",
                     f"{fp['size'] / 2**30 / xxh:.1f}", f"{sha:.3f}", f"{sha / xxh:.1f}×"])  # fmt: skip
    log("mocapviz check")
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mocapviz.cli", "check", path], capture_output=True, check=False, cwd=REPO)
    t_check = time.perf_counter() - t0
    info["others"] = monitor.report()
    print(header("### Checked reads: xxh3 of every block on first read (bench_integrity)", info, ("numpy",),
                 notes + [f"each figure: median of {repeats} fresh processes after one warm run (page cache warm)"]))
    print()
    print(markdown("| step | seconds | target / baseline | meets / cost |", "|---|---:|---|---|", [
        ["open (`MotionDB.open`)", f"{t_open:.3f}", f"≤ {TARGET_OPEN_S:g} s", "yes" if t_open <= TARGET_OPEN_S else "NO"],
        [f"first search of the process (open + `SimilaritySearch(db, \"F15E\").clips` of document {DOC}, F15E verified on load)",
         f"{first:.3f}", f"baseline without checks: {first_plain:.3f} s", f"+{first - first_plain:.3f} s"],
        ["the same search again in that process (nothing left to verify)", f"{again:.3f}",
         f"baseline without checks: {again_plain:.3f} s", f"+{again - again_plain:.3f} s"],
        ["full check (`mocapviz check DB`: sha256 of every file, derived data included)", f"{t_check:.1f}", "", ""],
    ]))  # fmt: skip
    print()
    print(markdown("| file | MiB | blocks | xxh3 s | xxh3 GiB/s | sha256 s | sha256 / xxh3 |",
                   "|---|---:|---:|---:|---:|---:|---:|", rows))
    print()
    print("- baseline: the same fresh-process search with `open_checked` and `verified_blocks` switched off (plain "
          "memory maps, sizes checked only), in the same run; a frame array's blocks are verified only where a "
          "search reads them")
    print(f"- total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
