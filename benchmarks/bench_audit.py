"""Audit of a collection: the index self-join of ``Engine.audit`` against brute-force subsequence DTW and STUMPY.

The database is bench_dashboard's (``dashboard-30hz``: every shared archive ingested at 30 Hz, real frames only,
no derived copies, cached under ``.cache/bench``). Three measurements:

1. **Ours on the whole collection**: ``Engine(db).audit()`` with its defaults (F15E, shortest stretch 1 s, the
   threshold learned from the collection, time scaling within 1.25, mirrored copies too), run ONCE (no repeats:
   it takes minutes) in a fresh Python process, so that its wall time and peak memory (the child's
   ``ru_maxrss``) are the audit's own: pairs, clusters of copies, the learned threshold.
2. **Brute force on a subset with planted copies** (``SUBSET`` documents drawn with a fixed seed, then
   ``PLANTED_PER_KIND`` derived copies of each kind of ``mocapviz.experiments.audit.plant_copies`` appended: mirrored,
   stretched, trimmed, noisy, retargeted, resampled, all together): every window of the shortest stretch (1 s)
   starting every 5th frame of every document (the audit's own query stride), and its left/right mirror, is
   aligned by subsequence DTW (``mocapviz.match.time_warping.subsequence_costs``, the product's numba DTW) to every
   frame of the subset, on the audit's own features (``mocapviz.similarity.audit.Collection``: retargeted, smoothed
   F15E at 30 Hz) and with the audit's own cost (DTW against the other side's half frames). In every other
   document the alignment of least accumulated cost is kept; the window is a copied window (with that document as
   its partner) when that alignment obeys the audit's rule for a pair (its span at least the shortest stretch and
   at most ``max_scale`` times it) and its mean local cost along its path is at most the threshold learned in 1.
   Ours on the same subset: ``Engine(subset).audit(threshold=<the same>)`` (features included). Both are scored
   the same way: a planted copy is found when the copied windows (brute force's, or those a pair of ours covers
   by at least half) of the copy's document with its source as partner cover at least half of the copy, and those
   of the source with the copy as partner at least half of the copied span (``_found``): **the speed-up at equal
   recall of the planted copies**. Also reported: ours' recall of all of brute force's copied windows (real
   performances included: a window that matches a stretch of a re-performance by itself, while the whole
   performances' alignment does not, is one brute force finds and ours does not).
3. **STUMPY** (``stumpy.mstump``, the multidimensional matrix profile) on the same features of the subset's first
   10k and 20k frames (all dimensions, m = 30 frames, one numba thread): its time, the growth exponent and the time extrapolated to
   the whole collection. Its distance is the z-normalised Euclidean distance of every dimension (not ours: no DTW,
   no mirror, no threshold in cm, documents not kept apart), so its figures are a cost of the all-pairs self-join
   only, not a like-for-like answer.

Not measured: the growth to 1M / 4M frames (derived copies), left for a later run.
"""

from __future__ import annotations

import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .bench_dashboard import DATABASE
from .common import (
    REPO,
    CpuMonitor,
    benchmark_db,
    describe_db,
    header,
    log,
    machine_info,
    markdown,
    package_version,
    write_results_csv,
)
from .common import fmt as _f

SUBSET = 300  # documents of the brute-force comparison (30 with --quick)
PLANTED_PER_KIND = 5  # derived copies of each kind planted in the subset (1 with --quick)
SEED = 0
STEP = 5  # the audit's query stride: a sixth of the shortest stretch of 30 frames
STUMPY_FRAMES = (10_000, 20_000)  # (2,000 and 4,000 with --quick)
STUMPY_M = 30


def _duration(seconds: float) -> str:
    """"42 s", "12 min" or "3.4 h"."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min" if seconds < 7200 else \
        f"{seconds / 3600:.1f} h"  # fmt: skip


def _full_audit(path: str) -> None:
    """In a child process: ``Engine(MotionDB.open(path)).audit()`` once; one JSON line of its figures on stdout."""
    from mocapviz.db.database import MotionDB
    from mocapviz.engine import Engine

    db = MotionDB.open(path)
    t0 = time.perf_counter()
    pairs = Engine(db).audit()
    seconds = time.perf_counter() - t0
    print(json.dumps({"seconds": seconds, "pairs": len(pairs), "clusters": int(pairs["cluster"].nunique()),
                      "threshold": pairs.attrs["threshold"], "mirrored": int(pairs["mirrored"].sum()),
                      "documents": len(set(pairs["doc_a"]) | set(pairs["doc_b"])),
                      "max_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))  # fmt: skip


def _run_full(db) -> dict:
    """Measurement 1, in a fresh process (its peak memory its own)."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "benchmarks.bench_audit", str(db.path)], capture_output=True,
                         text=True, env=env, cwd=REPO, check=True)  # fmt: skip
    result = json.loads(out.stdout.strip().splitlines()[-1])
    return result | {"process_s": time.perf_counter() - t0}


def _subset_db(db, n: int, folder: Path):
    """A MotionDB of ``n`` documents of ``db`` drawn with ``SEED`` (in database order)."""
    from mocapviz.db.database import MotionDB

    docs = db.documents
    picked = docs.iloc[np.sort(np.random.default_rng(SEED).choice(len(docs), min(n, len(docs)), replace=False))]
    motions = [db.motion(int(d)) for d in picked["doc_id"]]
    metas = [{"name": r.name, "path": r.path, "source_fps": r.source_fps} for r in picked.itertuples()]
    return MotionDB.create(folder).append_motions(motions, metas)


def _windows(collection, m: int) -> list[tuple[int, int]]:
    """(document position, first row) of every window of ``m`` rows starting every ``STEP``-th row of a document."""
    return [(pos, s) for pos in range(len(collection.starts) - 1)
            for s in range(int(collection.starts[pos]), int(collection.starts[pos + 1]) - m + 1, STEP)]  # fmt: skip


def _brute_force(collection, m: int, threshold: float, max_scale: float) -> tuple[set, int]:
    """Measurement 2's reference: {(document position, first row, partner position)} of the copied windows, and
    the number of windows. Per window and side (itself, its mirror image): subsequence DTW over the subset's half
    frames with the audit's steps (its cost model: ``_half_frames``, ``_HALF_STEPS`` of
    ``mocapviz.similarity.audit``), the least accumulated cost in each other document, kept when its span is ``m``
    to ``max_scale`` x ``m`` frames (the audit's rule: each side at least the shortest stretch, the time scaling
    within the band) and its path's mean local cost is at most ``threshold``."""
    from mocapviz.match.time_warping import dtw, subsequence_costs
    from mocapviz.similarity.audit import _HALF_STEPS, _half_frames

    starts = collection.starts
    half = np.concatenate([_half_frames(collection.x[a:b]) for a, b in itertools.pairwise(starts)])
    hs = np.concatenate([[0], np.cumsum(2 * np.diff(starts) - 1)])  # each document's first half frame
    found, windows = set(), _windows(collection, m)
    for pos, s in windows:
        for values in (collection.x, collection.mirrored):
            query = values[s:s + m]
            cost, first = subsequence_costs(query, half, hs[:-1], steps=_HALF_STEPS)
            cost[hs[pos]:hs[pos + 1]] = np.inf
            best = np.minimum.reduceat(cost, hs[:-1])
            # a path has at most m + 2 max_scale m steps: no mean under the threshold above this
            for other in np.flatnonzero(best <= threshold * (1 + 2 * max_scale) * m):
                if (pos, s, int(other)) in found:
                    continue
                end = int(hs[other]) + int(np.argmin(cost[hs[other]:hs[other + 1]]))
                frames = (end - int(first[end])) / 2 + 1
                if not m <= frames <= max_scale * m:
                    continue
                total, path = dtw(query, half[first[end]:end + 1], steps=_HALF_STEPS)
                if total / len(path) <= threshold:
                    found.add((pos, s, int(other)))
    return found, len(windows)


def _covered(pairs: pd.DataFrame, collection, m: int) -> set:
    """{(document position, first row, partner position)} of the windows a pair covers by at least half."""
    pos_of = {int(d): i for i, d in enumerate(collection.doc_ids)}
    out = set()
    for r in pairs.itertuples():
        pa, pb = pos_of[int(r.doc_a)], pos_of[int(r.doc_b)]
        for pos, partner, start, end in ((pa, pb, r.start_a, r.end_a), (pb, pa, r.start_b, r.end_b)):
            first = int(collection.starts[pos])  # every document at the common rate: rows = own frames
            for s in range(first, int(collection.starts[pos + 1]) - m + 1, STEP):
                if min(s + m, first + end) - max(s, first + start) >= m / 2:
                    out.add((pos, s, partner))
    return out


def _found(windows: set, truth: pd.DataFrame, collection, m: int) -> int:
    """The planted copies whose copied windows (``(document position, first row, partner position)``) cover at
    least half of the copy with its source as partner, and at least half of the copied span of the source with the
    copy as partner (every document at the common rate: rows = own frames)."""
    pos_of = {int(d): i for i, d in enumerate(collection.doc_ids)}
    found = 0
    for t in truth.itertuples():
        source, copy = pos_of[int(t.source_doc)], pos_of[int(t.copy_doc)]
        ok = True
        for pos, partner, a, b in ((copy, source, t.copy_start, t.copy_end), (source, copy, t.source_start,
                                                                              t.source_end)):  # fmt: skip
            first = int(collection.starts[pos])
            covered = np.zeros(int(b - a), bool)
            for s in range(first, int(collection.starts[pos + 1]) - m + 1, STEP):
                if (pos, s, partner) in windows:
                    covered[max(0, s - first - a):max(0, min(b, s - first + m) - a)] = True
            ok &= covered.mean() >= 0.5
        found += bool(ok)
    return found


def _stumpy(x: np.ndarray, sizes) -> list[dict]:
    """Measurement 3: ``stumpy.mstump`` of the first n rows on one thread, timed once per size (after a small
    warm-up). One thread: on a shared 2-core machine numba's parallel loops wait for the busier core (2 threads
    gave a growth exponent of 3 to 4 from 10k to 19k frames while another process used a core)."""
    import numba
    import stumpy

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        stumpy.mstump(x[:500].T.astype(np.float64), STUMPY_M)  # numba compilation, not timed
        rows = []
        for n in sizes:
            t0 = time.perf_counter()
            stumpy.mstump(x[:n].T.astype(np.float64), STUMPY_M)
            rows.append({"frames": n, "seconds": time.perf_counter() - t0})
    finally:
        numba.set_num_threads(threads)
    return rows


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from mocapviz.engine import Engine
    from mocapviz.experiments.audit import plant_copies
    from mocapviz.similarity.audit import Collection

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    db, record = benchmark_db(DATABASE, quick)
    log(f"audit of the whole collection ({db.n_frames:,} frames) in a child process")
    full = _run_full(db)
    threshold = full["threshold"]
    log(f"  {full['seconds']:.0f} s, {full['pairs']:,} pairs, threshold {threshold:.2f} cm")

    n_subset = 30 if quick else SUBSET
    with tempfile.TemporaryDirectory() as tmp:
        sub = _subset_db(db, n_subset, Path(tmp) / "subset.mdb")
        sub, truth = plant_copies(sub, Path(tmp) / "planted.mdb", n_per_kind=1 if quick else PLANTED_PER_KIND,
                                  seed=SEED)  # fmt: skip
        rate = float(sub.typical_fps)
        m = max(2, round(1.0 * rate))
        max_scale = 1.25
        log(f"subset: {n_subset} documents and {len(truth)} planted copies, {sub.n_frames:,} frames; brute force")
        t0 = time.perf_counter()
        collection = Collection(sub, "F15E", rate)
        t_features = time.perf_counter() - t0
        t0 = time.perf_counter()
        brute, n_windows = _brute_force(collection, m, threshold, max_scale)
        t_brute = time.perf_counter() - t0 + t_features
        log(f"  {t_brute:.0f} s, {len(brute):,} copied windows of {n_windows:,}; ours on the subset")
        Engine(sub).audit(threshold=threshold)  # warm-up (numba, imports), not timed
        t0 = time.perf_counter()
        pairs = Engine(sub).audit(threshold=threshold)
        t_ours = time.perf_counter() - t0
        ours = _covered(pairs, collection, m)
        found_brute, found_ours = _found(brute, truth, collection, m), _found(ours, truth, collection, m)
        sub_frames, sub_docs = sub.n_frames, len(sub)
        x_sub = collection.x[: collection.starts[n_subset]]  # STUMPY on the real documents' frames
        del sub, collection
    recall = len(brute & ours) / len(brute) if brute else float("nan")
    extra = len(ours - brute)
    planted = len(truth)

    stumpy_version = package_version("stumpy")
    sizes = [min(n, len(x_sub)) for n in ((2_000, 4_000) if quick else STUMPY_FRAMES)]
    stump = []
    try:
        log(f"stumpy.mstump on {sizes} frames")
        stump = _stumpy(x_sub, sizes)
    except ImportError:
        log("stumpy not installed: its rows are left out")
    info["others"] = monitor.report()

    n_full = db.n_frames
    brute_full_s = t_brute * (n_full / sub_frames) ** 2  # every window against every frame: O(n^2)
    rows = [
        {"row": "ours, whole collection", "what": "Engine(db).audit(), threshold learned; one run, child process",
         "frames": n_full, "seconds": full["seconds"], "peak_mib": full["max_rss_mib"], "pairs": full["pairs"],
         "clusters": full["clusters"], "planted": np.nan, "recall": np.nan, "extrapolated": False},
        {"row": "brute force, subset", "what": "subsequence DTW of every 1 s window (+ mirror) every 5th frame",
         "frames": sub_frames, "seconds": t_brute, "peak_mib": np.nan, "pairs": np.nan, "clusters": np.nan,
         "planted": found_brute / planted, "recall": np.nan, "extrapolated": False},
        {"row": "ours, subset", "what": "Engine(subset).audit(threshold=same)", "frames": sub_frames,
         "seconds": t_ours, "peak_mib": np.nan, "pairs": len(pairs), "clusters": int(pairs["cluster"].nunique()),
         "planted": found_ours / planted, "recall": recall, "extrapolated": False},
        {"row": "brute force, whole collection", "what": "the subset's time × (frames ratio)², extrapolated",
         "frames": n_full, "seconds": brute_full_s, "peak_mib": np.nan, "pairs": np.nan, "clusters": np.nan,
         "planted": np.nan, "recall": np.nan, "extrapolated": True},
    ]  # fmt: skip
    exponent = np.nan
    if len(stump) == 2:
        exponent = float(np.log(stump[1]["seconds"] / stump[0]["seconds"]) / np.log(stump[1]["frames"]
                                                                                    / stump[0]["frames"]))
    for s in stump:
        rows.append({"row": "STUMPY mstump", "what": f"m = {STUMPY_M}, {x_sub.shape[1]} dimensions, z-normalised",
                     "frames": s["frames"], "seconds": s["seconds"], "peak_mib": np.nan, "pairs": np.nan,
                     "clusters": np.nan, "planted": np.nan, "recall": np.nan, "extrapolated": False})  # fmt: skip
    if stump:
        low = stump[0]["seconds"] * (n_full / stump[0]["frames"]) ** 2
        rows.append({"row": "STUMPY mstump, whole collection", "what": f"the {stump[-1]['frames']:,}-frame run's "
                     f"time × (frames ratio)², extrapolated (from the {stump[0]['frames']:,}-frame run: ≈ {low:,.0f} s)", "frames": n_full, "seconds": stump[-1]["seconds"] * (n_full / stump[-1]["frames"]) ** 2,
                     "peak_mib": np.nan, "pairs": np.nan, "clusters": np.nan, "planted": np.nan,
                     "recall": np.nan, "extrapolated": True})  # fmt: skip
    table = pd.DataFrame(rows)

    notes = [
        *describe_db(db, record),
        (f"threshold: learned on the whole collection, {threshold:.2f} cm (the same given to the subset's audit "
         "and to brute force); shortest stretch 1 s (30 frames), time scaling within 1.25, mirrored copies included"),
        (f"ours, whole collection: ONE run (no repeats: it takes minutes; --repeats is ignored here) in a fresh "
         f"process (`python -m benchmarks.bench_audit DB`), the audit's own wall time; peak memory = the child's "
         f"ru_maxrss (the process's whole peak: Python, the database's arrays, features and kd-tree); "
         f"{full['documents']:,} documents in a pair, {full['mirrored']:,} mirrored pairs; the child process "
         f"took {full['process_s']:.0f} s in all (start-up, opening the database)"),
        (f"subset: {n_subset} real documents drawn with seed {SEED} and {planted} DERIVED copies of their clips "
         f"planted among them (`plant_copies`, {planted // 7} of each kind), {sub_docs} documents, {sub_frames:,} "
         f"frames; one run each; brute force's time includes the audit features of the subset ({t_features:.1f} s), "
         "as ours does; STUMPY runs on the real documents' frames only"),
        (f"STUMPY: {stumpy_version}, on ONE thread (`numba.set_num_threads(1)`: with 2 threads on this shared machine "
         "its time grew as n^3 to n^4, waiting for the busier core); compilation (a 500-frame warm-up) not timed; "
         "ours' kd-tree queries use both cores, brute force's subsequence DTW one"),
    ]
    title = "### Audit of a collection: index self-join vs brute-force subsequence DTW and STUMPY" + \
        (" (quick)" if quick else "")  # fmt: skip
    print(header(title, info, ("numpy", "numba", "scipy"), notes))
    print()
    print(markdown(
        "| row | what | frames | seconds | peak memory MiB | pairs | clusters | planted copies found | recall of "
        "brute force's windows |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
        [[r["row"], r["what"], _f(int(r["frames"])), ("≈ " if r["extrapolated"] else "") + _f(r["seconds"], 1),
          _f(r["peak_mib"], 0), _f(r["pairs"], 0), _f(r["clusters"], 0),
          *(f"{r[c]:.1%}" if np.isfinite(r[c]) else "—" for c in ("planted", "recall"))] for r in rows]))  # fmt: skip
    print()
    speed = t_brute / t_ours
    equal = "equal recall" if found_ours == found_brute else "a higher recall" if found_ours > found_brute else \
        "a LOWER recall"  # fmt: skip
    print(f"On the subset with planted copies: brute force {t_brute:.1f} s, ours {t_ours:.2f} s: **{speed:.0f}× "
          f"faster at {equal} of the planted copies** (brute force {found_brute} of {planted}, ours {found_ours} of "
          f"{planted}, scored alike). Of brute force's {len(brute):,} copied (window, partner document) of "
          f"{n_windows:,} windows, ours covers {recall:.1%} and {extra:,} more (a pair's cost is its mean over its "
          "whole length, so a window inside a pair may cost more than the threshold on its own); the missed "
          "windows inspected (a subset of 150 documents) were stretches of two performances of one action that "
          "match for a second while the performances' whole alignment does not. Brute force on the whole collection, extrapolated O(n²): ≈ "
          f"{_duration(brute_full_s)} against ours' {_duration(full['seconds'])} (measured).")
    if stump:
        print()
        print(f"STUMPY's growth exponent from {stump[0]['frames']:,} to {stump[-1]['frames']:,} frames: "
              f"{exponent:.2f}{' (over 2: the machine was shared, see the load above)' if exponent > 2.2 else ''}; "
              f"extrapolated O(n²) to {n_full:,} frames: ≈ {_duration(low)} from the smaller run, "
              f"{_duration(stump[-1]['seconds'] * (n_full / stump[-1]['frames']) ** 2)} from the larger. Its distance is not "
              "ours: the z-normalised Euclidean distance of fixed-length windows (no time warping, no mirror, "
              "no threshold in cm, windows across document boundaries), so it is a cost, not an answer.")
    else:
        print()
        print(f"STUMPY: not measured ({stumpy_version}).")
    print()
    print("Not measured this time: the growth to 1M / 4M frames (derived copies of the archives), left for a later run.")
    print()
    print("Commands: `python -m benchmarks --only audit` (this section; `--quick` for a smoke run).")
    out = Path(out_dir) if out_dir else REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    write_results_csv(out / f"audit{'-quick' if quick else ''}.csv", {"audit": table}, info)
    print()
    print(f"CSV: benchmarks/results/audit{'-quick' if quick else ''}.csv; total benchmark time "
          f"{time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    _full_audit(sys.argv[1])
