"""Cost growth: every query path on databases of 1M, 4M and 10M frames at 120 Hz, one process and sharded.

The databases. The largest (``DATABASE``, tag ``scaling-v2``): the four shared archives ingested at 120 Hz (the
1.78M real frames of bench_relational's database), then derived documents appended (``benchmarks.common.
add_variants``) until 10M frames: a left/right MIRRORED copy of every document, then TIME-STRETCHED copies of the
originals and of their mirror images (resampled to s x 120 Hz and relabelled 120 Hz: the motion performed s times
slower, s = 1.03, 1.06, ... in turn). The smaller ones are nested prefixes of the largest's documents REAL FIRST
(:func:`document_order`: the real documents in a fixed random order, then the derived ones), copied into databases
of their own (``MotionDB.create`` + ``append_motions``): 1M frames are real only, and the derived share of every
size is printed. All are cached under ``<repo>/.cache/bench/scaling-v2[-quick]/`` with the build's wall time, peak
RSS and peak disk (``build-peaks.json``).

Per size, each group of query paths runs in a FRESH process (``python -m benchmarks.bench_scaling --worker GROUP
DB PLAN OUT``), so that its memory is its own: setup timed once, a warm-up query, then the queries (median ms):

- open: ``MotionDB.open``;
- relational: ``query_by_example`` exact / fuzzy / 1-mismatch on the lower-body 2005 features of 1 s examples,
  and the scene descriptions ``DESCRIPTIONS`` (``mocapviz.relational.scene.find``);
- knn: 16-NN single queries and one batch (``KnnIndex.query``, F15E);
- search: ``SimilaritySearch.stretches`` (1 s) and ``.clips`` (whole HDM05 clips), exact and fast, K = 10;
- lng: ``match_motion`` (the lazy neighbourhood graph, k = 256) of 1 s queries;
- templates: ``search_template(...)`` (the exact search by lower bounds, its default) of one learned kick template
  (2006 set);
- sharded: the same queries through ``Engine(db, scheduler="local", n_shards=2)`` (``mocapviz.engine``), and each
  shard's own work (a ``mocapviz.engine.shard.Shard`` in this process, no Dask) with the pickled sizes of what is sent
  to and returned by a shard.

Memory: the peak of ``RssAnon`` (/proc/self/status, sampled every 10 ms while the queries run: the heap, not the
memory-mapped database) and ``ru_maxrss`` of each fresh process. The exponent b of time ~ frames^b is the
least-squares slope of log(time) on log(frames) over the sizes; the issue's targets at 10M frames beside (#26).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .bench_dask import PeakRSS
from .common import (
    REPO,
    BenchDB,
    CpuMonitor,
    benchmark_db,
    describe_db,
    header,
    loadavg,
    log,
    machine_info,
    markdown,
    write_results_csv,
)
from .common import fmt as _f

FPS = 120
SIZES = (1_000_000, 4_000_000, 10_000_000)
SIZES_QUICK = (20_000, 40_000, 80_000)
STRETCHES = (1.03, 1.06, 1.09, 1.12)  # slowed down by a few percent; rounds are used in turn until 10M frames
DATABASE = BenchDB(
    "scaling-v2", fps=FPS, min_frames=max(SIZES), stretches=STRETCHES, quick_min_frames=max(SIZES_QUICK),
    quick_files={"hdm05-cut": 40, "cmu-asfamc": 4, "bandai-namco-1": 10, "bandai-namco-2": 100},
    chunk_frames=4_000_000,
)  # fmt: skip
SUBSET_CHUNK = 2_000_000  # frames per commit when copying a subset
SEED = 0
TRAIN_ACTORS = ("bd", "bk", "dg", "tr")
DESCRIPTIONS = ("kick_right", "kick_right then punch_left within 2 s")
K_KNN = 16
K_SEARCH = 10
# queries per path and run kind: (full, quick); the sharded run asks a prefix of the same queries
N = {"relational": (40, 6), "knn_single": (500, 50), "knn_batch": (1000, 200), "stretches": (12, 3),
     "clips": (12, 3), "lng": (16, 3), "open": (5, 3)}  # fmt: skip
N_SHARDED = {"relational": (10, 3), "knn_single": (100, 20), "knn_batch": (1000, 200), "stretches": (6, 2),
             "clips": (6, 2), "lng": (6, 2)}  # fmt: skip
QUERY_SECONDS = 1.0  # stretches, LNG and relational examples: 1 s of a real document
GROUPS = ("open", "relational", "knn", "search", "lng", "templates", "sharded")


def _is_real(docs) -> np.ndarray:
    real = ~docs["format"].eq("memory").to_numpy()
    if "mirror_of" in docs:
        real &= docs["mirror_of"].isna().to_numpy()
    return real


def document_order(db) -> pd.DataFrame:
    """The documents of ``db``, REAL FIRST: the real documents in a fixed random order (seed 0), then the derived
    ones (mirrored / stretched) in a fixed random order. A size's database is the shortest prefix holding n frames,
    so sizes up to the real frames hold real frames only and the derived share grows with the size."""
    docs = db.documents
    real = _is_real(docs)
    rng = np.random.default_rng(SEED)
    first, then = np.flatnonzero(real), np.flatnonzero(~real)
    return docs.iloc[np.concatenate([rng.permutation(first), rng.permutation(then)])]


def subset_db(db, n: int, folder: Path):
    """The cached database of the shortest prefix of :func:`document_order` holding >= n frames."""
    from mocapviz.db.database import MotionDB
    from mocapviz.errors import MotionDBError

    record_file = folder / "subset.json"
    if record_file.is_file():
        try:
            sub = MotionDB.open(folder / "db")
            if json.loads(record_file.read_text()).get("n_frames") == sub.n_frames:
                return sub
        except (MotionDBError, ValueError, OSError) as exc:
            log(f"cached subset unusable ({exc}); rebuilding")
    if folder.exists():
        shutil.rmtree(folder)
    docs = document_order(db)
    take = docs.iloc[: int(np.searchsorted(np.cumsum(docs["n_frames"].to_numpy()), n)) + 1]
    log(f"subset of {n:,} frames: {len(take):,} documents -> {folder}")
    sub = MotionDB.create(folder / "db.tmp")
    cols = ["name", "path", "format", "source_fps", "sha256", "mirror_of", "variant"]
    motions, metas, frames = [], [], 0
    for row in take.to_dict("records"):
        motions.append(db.motion(int(row["doc_id"])))
        metas.append({c: row[c] for c in cols if c in row and not pd.isna(row[c])})
        frames += motions[-1].n_frames
        if frames >= SUBSET_CHUNK:
            sub = sub.append_motions(motions, metas)
            motions, metas, frames = [], [], 0
            log(f"  {sub.n_frames:,} frames")
    if motions:
        sub = sub.append_motions(motions, metas)
    (folder / "db.tmp").rename(folder / "db")
    sub = MotionDB.open(folder / "db")
    record_file.write_text(json.dumps({"n_frames": sub.n_frames, "documents": len(sub), "of": str(db.path)}))
    return sub


class DiskPeak:
    """Peak bytes on disk under a folder while the ``with`` block runs (allocated blocks, sampled every second),
    and the lowest free space of its file system."""

    def __init__(self, folder: Path, interval: float = 1.0):
        import threading

        self.folder, self.interval, self.peak, self.min_free = Path(folder), interval, 0, None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _sample(self) -> None:
        total = 0
        for root, _, files in os.walk(self.folder):
            for f in files:
                try:
                    total += os.lstat(os.path.join(root, f)).st_blocks * 512
                except OSError:
                    pass
        self.peak = max(self.peak, total)
        free = shutil.disk_usage(self.folder if self.folder.exists() else REPO).free
        self.min_free = free if self.min_free is None else min(self.min_free, free)

    def _run(self):
        while not self._stop.is_set():
            self._sample()
            self._stop.wait(self.interval)

    def __enter__(self):
        self.folder.mkdir(parents=True, exist_ok=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._sample()


def build_databases(quick: bool) -> tuple:
    """The largest database (built once, cached), its build record, and {nominal size: MotionDB} of every size;
    the first build records its wall time, peak RSS (this process, psutil, sampled every 50 ms) and the peak disk
    use of the cache folder in ``build-peaks.json``."""
    sizes = SIZES_QUICK if quick else SIZES
    folder = REPO / ".cache" / "bench" / (DATABASE.tag + ("-quick" if quick else ""))
    peaks_file = folder / "build-peaks.json"
    t0 = time.perf_counter()
    with PeakRSS() as mem, DiskPeak(folder) as disk:
        big, record = benchmark_db(DATABASE, quick)
        t_big = time.perf_counter() - t0
        dbs = {}
        for n in sizes:
            # the largest size is the whole database (it holds just over max(sizes) frames)
            dbs[n] = big if n >= max(sizes) or n >= big.n_frames else subset_db(big, n, folder / f"subset-{n}")
    built = time.perf_counter() - t0
    old = json.loads(peaks_file.read_text()) if peaks_file.is_file() else {}
    if not old or not record.get("cached"):
        old = {"wall_s": built, "largest_s": t_big, "peak_rss_MB": mem.mb, "peak_disk_GB": disk.peak / 1e9,
               "min_free_GB": (disk.min_free or 0) / 1e9, "built": time.strftime("%Y-%m-%dT%H:%M:%S"),
               "load_start": loadavg()}  # fmt: skip
        peaks_file.write_text(json.dumps(old, indent=2))
    final_disk = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) / 1e9
    return big, record, dbs, old | {"final_disk_GB": final_disk}


# ============================================================================ measuring, one fresh process per group
def _status_kb(key: str, pid: int | str = "self") -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return 0


def _peaks_mb(pids) -> float:
    """The sum of the processes' own peak RSS (``VmHWM``, file-backed pages included), read once: no sampling
    thread competes with the timed queries (psutil's process walk every 50 ms took 1.3 ms of the coordinator's
    GIL each time). An upper bound of their simultaneous peak."""
    total = 0
    for pid in pids:
        try:
            total += _status_kb("VmHWM", pid)
        except OSError:  # gone meanwhile
            pass
    return total / 1024


class AnonPeak:
    """Peak anonymous RSS (``RssAnon`` of /proc/self/status: the heap, not the memory-mapped database files) of
    this process while the ``with`` block runs, sampled every 10 ms; ``at_start`` the value when it began."""

    def __init__(self, interval: float = 0.01):
        import threading

        self.interval, self.peak, self.at_start = interval, 0, _status_kb("RssAnon")
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, _status_kb("RssAnon"))
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, _status_kb("RssAnon"))

    def record(self) -> dict:
        return {"anon_start_MB": self.at_start / 1024, "anon_peak_MB": self.peak / 1024,
                "anon_added_MB": (self.peak - self.at_start) / 1024, "file_rss_MB": _status_kb("RssFile") / 1024,
                "hwm_MB": _status_kb("VmHWM") / 1024}  # fmt: skip


def _per_query(fn, items, runs: int = 1) -> list[float]:
    """Seconds of ``fn(item)`` per item (the best of ``runs``)."""
    out = []
    for item in items:
        best = np.inf
        for _ in range(runs):
            t0 = time.perf_counter()
            fn(item)
            best = min(best, time.perf_counter() - t0)
        out.append(best)
    return out


def _doc_lookup(db) -> dict:
    """(sha256, name) -> doc_id: the same document in every size's database."""
    docs = db.documents
    return {(str(h), str(n)): int(d) for h, n, d in zip(docs["sha256"], docs["name"], docs["doc_id"])}


def plan_queries(db, quick: bool) -> dict:
    """The queries of every size, drawn once (seed 0) from the REAL documents of the smallest database (which
    every larger one holds): documents by (sha256, name), 1 s stretches by their first frame."""
    rng = np.random.default_rng(SEED)
    docs = db.documents.reset_index(drop=True)
    real = _is_real(docs)
    m = round(QUERY_SECONDS * FPS)
    long_ = np.flatnonzero(real & (docs["n_frames"].to_numpy() >= m))
    hdm = np.flatnonzero(real & docs["path"].astype("string").str.contains("hdm05", na=False).to_numpy())
    k = 1 if quick else 0

    def stretch(i):
        return {"key": [str(docs["sha256"][i]), str(docs["name"][i])],
                "first": int(rng.integers(0, int(docs["n_frames"][i]) - m + 1)), "m": m}  # fmt: skip

    def pick(pool, n):
        return [int(i) for i in rng.choice(pool, n, replace=len(pool) < n)]

    return {
        "stretches": [stretch(i) for i in pick(long_, N["stretches"][k])],
        "lng": [stretch(i) for i in pick(long_, N["lng"][k])],
        "relational": [stretch(i) for i in pick(long_, N["relational"][k])],
        "clips": [{"key": [str(docs["sha256"][i]), str(docs["name"][i])]} for i in pick(hdm if len(hdm) else long_,
                                                                                       N["clips"][k])],
        "knn_seed": SEED,
    }  # fmt: skip


def _example(db, lookup, q):
    d = lookup[tuple(q["key"])]
    return d, (q["first"], q["first"] + q["m"]) if "first" in q else None


def _knn_queries(features, n: int) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    return np.asarray(features[rng.integers(0, len(features), n)], dtype=np.float32)


def _group_relational(db, plan, quick, out):
    from mocapviz.features import feature_groups, relational_features
    from mocapviz.relational.index import build
    from mocapviz.relational.query import query_by_example
    from mocapviz.relational.scene import find

    t0 = time.perf_counter()
    values, _ = relational_features(db, "2005", progress=False)
    indexes = build(db, "2005", progress=False, values=values, save=False)
    out["setup: relational 2005 features + indexes (s)"] = time.perf_counter() - t0
    del values
    lookup = _doc_lookup(db)
    lower = feature_groups("2005")["lower"]
    examples = [db.motion(d)[a:b] for d, (a, b) in (_example(db, lookup, q) for q in plan["relational"])]
    query_by_example(db, examples[0], lower, mode="exact", indexes=indexes)  # warm-up (numba)
    find(db, DESCRIPTIONS[0], indexes=indexes)
    with AnonPeak() as mem:
        for mode in ("exact", "fuzzy", "mismatch"):
            hits = []

            def run(ex, mode=mode, hits=hits):
                hits.append(len(query_by_example(db, ex, lower, mode=mode, mismatches=1, indexes=indexes)))

            out[f"relational {mode} (ms)"] = 1e3 * float(np.median(_per_query(run, examples, 2)))
            out[f"relational {mode} hits"] = float(np.median(hits))
        for text in DESCRIPTIONS:
            hits = []
            out[f"scene: {text} (ms)"] = 1e3 * float(np.median(_per_query(
                lambda t, hits=hits: hits.append(len(find(db, t, indexes=indexes))), [text] * 3)))  # fmt: skip
            out[f"scene: {text} hits"] = hits[-1]
    out["mem"] = mem.record()


def _group_knn(db, plan, quick, out):
    from mocapviz.features import numeric_features
    from mocapviz.similarity.knn import KnnIndex

    k = 1 if quick else 0
    t0 = time.perf_counter()
    features = numeric_features(db, "F15E", progress=False)
    index = KnnIndex(features)
    out["setup: F15E features + kd-tree (s)"] = time.perf_counter() - t0
    single = _knn_queries(features, N["knn_single"][k]).astype(np.float64)
    batch = _knn_queries(features, N["knn_batch"][k]).astype(np.float64)
    index.query(batch[:10], K_KNN)
    with AnonPeak() as mem:
        out["16-NN single (ms)"] = 1e3 * float(np.median(_per_query(lambda q: index.query(q, K_KNN), single, 2)))
        t = min(_per_query(lambda b: index.query(b, K_KNN), [batch], 3))
        out["16-NN batched, per query (ms)"] = 1e3 * t / len(batch)
    out["mem"] = mem.record()


def _group_search(db, plan, quick, out):
    from mocapviz.features import numeric_features
    from mocapviz.similarity.search import SimilaritySearch

    t0 = time.perf_counter()
    features = numeric_features(db, "F15E", progress=False)
    search = SimilaritySearch(db, "F15E", features=features)
    search.knn_index  # noqa: B018 - built on first use
    search.coarse  # noqa: B018
    out["setup: F15E + SimilaritySearch (kd-tree, boxes, coarse) (s)"] = time.perf_counter() - t0
    lookup = _doc_lookup(db)
    stretches = [_example(db, lookup, q) for q in plan["stretches"]]
    clips = [_example(db, lookup, q)[0] for q in plan["clips"]]
    search.stretches(stretches[0][0], stretches[0][1], n_matches=K_SEARCH, mode="exact", exclude_document=True)
    search.stretches(stretches[0][0], stretches[0][1], n_matches=K_SEARCH, mode="fast", exclude_document=True)
    search.clips(clips[0], n_matches=K_SEARCH, mode="exact", exclude_document=True)
    search.clips(clips[0], n_matches=K_SEARCH, mode="fast", exclude_document=True)
    with AnonPeak() as mem:
        for mode in ("exact", "fast"):
            out[f"stretches 1 s, {mode} (ms)"] = 1e3 * float(np.median(_per_query(
                lambda e, mode=mode: search.stretches(e[0], e[1], n_matches=K_SEARCH, mode=mode,
                                                      exclude_document=True), stretches)))  # fmt: skip
            out[f"clips, {mode} (ms)"] = 1e3 * float(np.median(_per_query(
                lambda d, mode=mode: search.clips(d, n_matches=K_SEARCH, mode=mode, exclude_document=True), clips)))
    sha = db.documents.set_index("doc_id")["sha256"].astype(str)

    def own_copies(hits, d):  # derived copies of the query's document (their sha256 ends with the original's)
        return int(sum(sha[h].endswith("-" + sha[d]) for h in hits["doc_id"]))

    out["stretches exact: hits of 10 that are derived copies of the query's document (median)"] = float(np.median([
        own_copies(search.stretches(e[0], e[1], n_matches=K_SEARCH, mode="exact", exclude_document=True), e[0])
        for e in stretches]))  # fmt: skip
    out["clips exact: hits of 10 that are derived copies of the query's document (median)"] = float(np.median([
        own_copies(search.clips(d, n_matches=K_SEARCH, mode="exact", exclude_document=True), d) for d in clips]))
    out["clip query frames (median)"] = float(np.median([db.documents.set_index("doc_id").loc[d, "n_frames"]
                                                         for d in clips]))  # fmt: skip
    out["mem"] = mem.record()


def _group_lng(db, plan, quick, out):
    from mocapviz.features import numeric_features
    from mocapviz.similarity.knn import KnnIndex
    from mocapviz.similarity.motion_matching import match_motion

    features = numeric_features(db, "F15E", progress=False)
    index = KnnIndex(features)
    lookup = _doc_lookup(db)
    queries = [_example(db, lookup, q) for q in plan["lng"]]
    match_motion(db, queries[0][0], queries[0][1], features=features, index=index, exclude_document=True)
    with AnonPeak() as mem:
        out["LNG 1 s, k = 256 (ms)"] = 1e3 * float(np.median(_per_query(
            lambda e: match_motion(db, e[0], e[1], n_matches=K_SEARCH, features=features, index=index,
                                   exclude_document=True), queries)))  # fmt: skip
    out["mem"] = mem.record()


def _group_templates(db, plan, quick, out):
    from mocapviz.features import relational_features
    from mocapviz.relational.index import build
    from mocapviz.relational.templates import MotionTemplate, search_template

    template = MotionTemplate.load(plan["template"])
    t0 = time.perf_counter()
    values, _ = relational_features(db, "2006", progress=False)
    build(db, "2006", progress=False, values=values, save=False)
    out["setup: relational 2006 features + indexes (s)"] = time.perf_counter() - t0
    first = search_template(db, template, n_matches=K_SEARCH, values=values)
    out["template: share of frames aligned"] = float(first.attrs.get("aligned", np.nan))
    with AnonPeak() as mem:
        out["template search, lower bounds (ms)"] = 1e3 * float(np.median(_per_query(
            lambda _: search_template(db, template, n_matches=K_SEARCH, values=values), range(3))))  # fmt: skip
    out["mem"] = mem.record()


def _group_open(db, plan, quick, out):
    from mocapviz.db.database import MotionDB

    path = db.path
    t0 = time.perf_counter()
    MotionDB.open(path)
    out["open, first in the process (ms)"] = 1e3 * (time.perf_counter() - t0)
    out["open, again (ms)"] = 1e3 * float(np.median(_per_query(MotionDB.open, [path] * N["open"][0])))


def _pickled(obj) -> int:
    import pickle

    return len(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))


# runs per query of the sharded paths, the best kept: as the one-process groups time them (relational and the
# single 16-NN query best of 2), so that "added" compares like with like
_RUNS = {"relational exact": 2, "relational fuzzy": 2, "relational mismatch": 2, "16-NN single": 2}


def _group_sharded(db, plan, quick, out):
    """The same queries through Engine(db, scheduler="local", n_shards=2), and each shard's own work timed here (a
    :class:`~mocapviz.engine.shard.Shard` made in this process: no Dask) with the pickled sizes of what travels.

    Every engine call is given the arguments that make it the query the one-process groups time: ``k=256`` to LNG
    (the engine's default is graph_k of the database), ``n_matches=None`` to find (every hit, as ``scene.find``),
    ``delta=0.1`` to the template search (the library's default; the engine's is 0.2), ``mismatches=1`` to every
    relational query (as ``query_by_example`` is called)."""
    import psutil

    from mocapviz.db.shards import split_documents
    from mocapviz.engine import Engine
    from mocapviz.engine.shard import Shard
    from mocapviz.features import feature_groups
    from mocapviz.relational.templates import MotionTemplate

    k = 1 if quick else 0
    lookup = _doc_lookup(db)
    template = MotionTemplate.load(plan["template"])
    lower = feature_groups("2005")["lower"]
    rel = [db.motion(d)[a:b] for d, (a, b) in (_example(db, lookup, q) for q in plan["relational"][:N_SHARDED["relational"][k]])]
    stretches = [_example(db, lookup, q) for q in plan["stretches"][: N_SHARDED["stretches"][k]]]
    clips = [_example(db, lookup, q)[0] for q in plan["clips"][: N_SHARDED["clips"][k]]]
    lng = [_example(db, lookup, q) for q in plan["lng"][: N_SHARDED["lng"][k]]]
    t0 = time.perf_counter()
    with Engine(db, scheduler="local", n_shards=2, numeric_sets=("F15E",), relational_sets=("2005", "2006")) as sh:
        out["setup: Engine start + warm (s)"] = time.perf_counter() - t0
        features = sh.numeric("F15E")
        single = _knn_queries(features, N_SHARDED["knn_single"][k])
        batch = _knn_queries(features, N_SHARDED["knn_batch"][k])
        calls = {
            "relational exact": (rel, lambda e: sh.query(e, features=lower, mode="exact", mismatches=1)),
            "relational fuzzy": (rel, lambda e: sh.query(e, features=lower, mode="fuzzy", mismatches=1)),
            "relational mismatch": (rel, lambda e: sh.query(e, features=lower, mode="mismatch", mismatches=1)),
            **{f"scene: {t}": ([t] * 3, lambda t: sh.find(t, n_matches=None)) for t in DESCRIPTIONS},
            "16-NN single": (single, lambda q: sh.knn(q, k=K_KNN)),
            "16-NN batched, per query": ([batch], lambda b: sh.knn(b, k=K_KNN)),
            "stretches 1 s, exact": (stretches, lambda e: sh.stretches(e[0], frames=e[1], n_matches=K_SEARCH,
                                                                       mode="exact", exclude_document=True)),
            "stretches 1 s, fast": (stretches, lambda e: sh.stretches(e[0], frames=e[1], n_matches=K_SEARCH,
                                                                      mode="fast", exclude_document=True)),
            "clips, exact": (clips, lambda d: sh.clips(d, n_matches=K_SEARCH, mode="exact", exclude_document=True)),
            "clips, fast": (clips, lambda d: sh.clips(d, n_matches=K_SEARCH, mode="fast", exclude_document=True)),
            "LNG 1 s, k = 256": (lng, lambda e: sh.match(e[0], frames=e[1], method="lng", n_matches=K_SEARCH, k=256,
                                                          exclude_document=True)),
            "template search, lower bounds": ([template], lambda t: sh.search_template(t, n_matches=K_SEARCH, delta=0.1)),
        }  # fmt: skip
        for name, (items, fn) in calls.items():
            fn(items[0])  # warm-up: numba in the workers, first use of the shard's data
            per = np.median(_per_query(fn, items, _RUNS.get(name, 1)))
            out[f"sharded {name} (ms)"] = 1e3 * float(per) / (len(batch) if "batched" in name else 1)
        out["sharded_peak_rss_MB"] = _peaks_mb([os.getpid(), *(c.pid for c in psutil.Process().children(True))])

    # each shard's own work and the sizes that travel: the same calls on Shard objects in this process
    from mocapviz.relational.query import relational_example
    from mocapviz.relational.scene import read_description
    from mocapviz.similarity.search import example_features

    parts = split_documents(db, 2)
    gen = db.manifest["generation"]
    feats_all = features
    q_stretch = [example_features(db, feats_all, e[0], e[1], "F15E") for e in stretches]
    q_clip = [example_features(db, feats_all, d, None, "F15E") for d in clips]
    parsed = [read_description(db, t) for t in DESCRIPTIONS]
    rel_values = [relational_example(e, "2005") for e in rel]  # what Engine.query sends a shard
    q_lng = [np.asarray(feats_all[db.documents.set_index("doc_id").loc[d, "start"] + a:
                                  db.documents.set_index("doc_id").loc[d, "start"] + b], dtype=np.float32)
             for d, (a, b) in lng]
    shard_calls = lambda s: {
        "relational exact": (rel_values, lambda e: s.query_by_example(e, lower, "2005", mode="exact", mismatches=1,
                                                                      allowed=None)),
        "relational fuzzy": (rel_values, lambda e: s.query_by_example(e, lower, "2005", mode="fuzzy", mismatches=1,
                                                                      allowed=None)),
        "relational mismatch": (rel_values, lambda e: s.query_by_example(e, lower, "2005", mode="mismatch",
                                                                         mismatches=1, allowed=None)),
        **{f"scene: {t}": ([p] * 3, lambda p: s.find(p[0].text, p[0].relational_set, n_matches=None,
                                                      template_cost=p[1]))
           for t, p in zip(DESCRIPTIONS, parsed)},
        "16-NN single": (single, lambda q: s.knn("F15E", q, K_KNN)),
        "16-NN batched, per query": ([batch], lambda b: s.knn("F15E", b, K_KNN)),
        "stretches 1 s, exact": (q_stretch, lambda q: s.stretches("F15E", q, n_matches=K_SEARCH, mode="exact",
                                                                  exclude_document=True)),
        "stretches 1 s, fast": (q_stretch, lambda q: s.stretches("F15E", q, n_matches=K_SEARCH, mode="fast",
                                                                 exclude_document=True)),
        "clips, exact": (q_clip, lambda q: s.clips("F15E", q, n_matches=K_SEARCH, mode="exact", exclude_document=True)),
        "clips, fast": (q_clip, lambda q: s.clips("F15E", q, n_matches=K_SEARCH, mode="fast", exclude_document=True)),
        "LNG 1 s, k = 256": (q_lng, lambda q: s.knn("F15E", q, 256)),  # the shards' part of LNG: the kNN
        "template search, lower bounds": ([template], lambda t: s.search_template(t, n_matches=K_SEARCH, delta=0.1)),
    }  # fmt: skip
    shard_out = []
    for i, ids in enumerate(parts):
        s = Shard(str(db.path), ids.tolist(), gen)
        s.warm(("F15E",), ("2005", "2006"))
        rec = {"shard": i, "frames": s.view.n_frames, "documents": len(ids)}
        for name, (items, fn) in shard_calls(s).items():
            result = fn(items[0])
            rec[f"{name} (ms)"] = 1e3 * float(np.median(_per_query(fn, items, _RUNS.get(name, 1)))) / (
                len(batch) if "batched" in name else 1)
            rec[f"{name} reply (B)"] = _pickled(result) / (len(batch) if "batched" in name else 1)
            rec[f"{name} ask (B)"] = _pickled(items[0]) / (len(batch) if "batched" in name else 1)
        shard_out.append(rec)
        del s
    out["shards"] = shard_out


GROUP_FNS = {"open": _group_open, "relational": _group_relational, "knn": _group_knn, "search": _group_search,
             "lng": _group_lng, "templates": _group_templates, "sharded": _group_sharded}  # fmt: skip


def worker(group: str, db_path: str, plan_file: str, quick: bool, out_file: str) -> None:
    """Run one group of query paths on one database in this (fresh) process and write its figures as JSON."""
    import resource

    from mocapviz.db.database import MotionDB

    plan = json.loads(Path(plan_file).read_text())
    out = {"group": group, "anon_before_open_MB": _status_kb("RssAnon") / 1024}
    t0 = time.perf_counter()
    db = MotionDB.open(db_path)
    out["open in the worker (ms)"] = 1e3 * (time.perf_counter() - t0)
    GROUP_FNS[group](db, plan, quick, out)
    out["maxrss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out["maxrss_children_MB"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    Path(out_file).write_text(json.dumps(out, default=float))


def run_group(group: str, db, plan_file: Path, quick: bool, scratch: Path) -> dict:
    out_file = scratch / f"{group}-{db.n_frames}.json"
    out_file.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "benchmarks.bench_scaling", "--worker", group, str(db.path), str(plan_file),
           str(out_file)] + (["--quick"] if quick else [])  # fmt: skip
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, check=False, cwd=REPO, capture_output=True, text=True, env=os.environ | {"PYTHONWARNINGS": "ignore"})
    wall = time.perf_counter() - t0
    if proc.returncode != 0 or not out_file.is_file():
        log(f"  {group} at {db.n_frames:,} frames FAILED ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
        return {"group": group, "error": (proc.stderr.strip().splitlines() or ["?"])[-1], "wall_s": wall}
    rec = json.loads(out_file.read_text()) | {"wall_s": wall}
    log(f"  {group} at {db.n_frames:,} frames: {wall:.0f} s")
    return rec


# ============================================================================ the tables
def exponent(frames, times) -> float | None:
    frames, times = np.asarray(frames, float), np.asarray(times, float)
    ok = np.isfinite(times) & (times > 0)
    if ok.sum() < 2:
        return None
    return float(np.polyfit(np.log(frames[ok]), np.log(times[ok]), 1)[0])


# (row label, group, key, target at the largest size as (max value, text) or None, query? (exponent target 0.8))
ROWS = [
    ("MotionDB.open, first in a fresh process (ms)", "open", "open, first in the process (ms)", (1000, "≤ 1 s"), False),
    ("MotionDB.open, again (ms)", "open", "open, again (ms)", (1000, "≤ 1 s"), False),
    ("relational exact, lower body, 1 s example (ms)", "relational", "relational exact (ms)", None, True),
    ("relational fuzzy (ms)", "relational", "relational fuzzy (ms)", None, True),
    ("relational 1-mismatch (ms)", "relational", "relational mismatch (ms)", None, True),
    *[(f"scene `{t}` (ms)", "relational", f"scene: {t} (ms)", None, True) for t in DESCRIPTIONS],
    ("16-NN single query (ms)", "knn", "16-NN single (ms)", (0.5, "≤ 0.5 ms"), True),
    ("16-NN batched, per query (ms)", "knn", "16-NN batched, per query (ms)", None, True),
    ("stretches 1 s, exact (ms)", "search", "stretches 1 s, exact (ms)", (250, "≤ 250 ms"), True),
    ("stretches 1 s, fast (ms)", "search", "stretches 1 s, fast (ms)", None, True),
    ("clips (whole HDM05 clip), exact (ms)", "search", "clips, exact (ms)", None, True),
    ("clips, fast (ms)", "search", "clips, fast (ms)", None, True),
    ("LNG 1 s, k = 256 (ms)", "lng", "LNG 1 s, k = 256 (ms)", None, True),
    ("template search, lower bounds (ms)", "templates", "template search, lower bounds (ms)", None, True),
    ("setup: relational 2005 features + indexes (s)", "relational", "setup: relational 2005 features + indexes (s)",
     None, False),
    ("setup: relational 2006 features + indexes (s)", "templates", "setup: relational 2006 features + indexes (s)",
     None, False),
    ("setup: F15E features + kd-tree (s)", "knn", "setup: F15E features + kd-tree (s)", None, False),
    ("setup: F15E + SimilaritySearch (s)", "search", "setup: F15E + SimilaritySearch (kd-tree, boxes, coarse) (s)",
     None, False),
]  # fmt: skip
SHARDED = ["relational exact", "relational fuzzy", "relational mismatch", *[f"scene: {t}" for t in DESCRIPTIONS],
           "16-NN single", "16-NN batched, per query", "stretches 1 s, exact", "stretches 1 s, fast", "clips, exact",
           "clips, fast", "LNG 1 s, k = 256", "template search, lower bounds"]  # fmt: skip
SINGLE_KEY = {"relational exact": "relational exact (ms)", "relational fuzzy": "relational fuzzy (ms)",
              "relational mismatch": "relational mismatch (ms)", **{f"scene: {t}": f"scene: {t} (ms)" for t in DESCRIPTIONS},
              "16-NN single": "16-NN single (ms)", "16-NN batched, per query": "16-NN batched, per query (ms)",
              "stretches 1 s, exact": "stretches 1 s, exact (ms)", "stretches 1 s, fast": "stretches 1 s, fast (ms)",
              "clips, exact": "clips, exact (ms)", "clips, fast": "clips, fast (ms)",
              "LNG 1 s, k = 256": "LNG 1 s, k = 256 (ms)",
              "template search, lower bounds": "template search, lower bounds (ms)"}  # fmt: skip


def _get(results: dict, n: int, group: str, key: str):
    v = results.get(n, {}).get(group, {}).get(key)
    return None if v is None else float(v)


def time_table(sizes, frames, results) -> tuple[str, pd.DataFrame]:
    head = ("| path | " + " | ".join(f"{f:,} frames" for f in frames)
            + " | exponent b (from 1st size) | target at the largest | meets |")  # fmt: skip
    align = "|---|" + "---:|" * len(frames) + "---:|---|---|"
    lines, records = [], []
    for label, group, key, target, query in ROWS:
        vals = [_get(results, n, group, key) for n in sizes]
        b = exponent(frames, vals)
        goals, ok = [], []
        if target is not None:
            goals.append(target[1])
            ok.append(vals[-1] is not None and vals[-1] <= target[0])
        if query:
            goals.append("b ≤ 0.8")
            ok.append(b is not None and b <= 0.8)
        meets = "—" if not ok else ("yes" if all(ok) else "NO")
        lines.append([label] + [_f(v, 3) for v in vals] + [_f(b, 2), "; ".join(goals) or "—", meets])
        records.append({"path": label, **{f"at_{f}": v for f, v in zip(frames, vals)}, "exponent": b,
                        "target": "; ".join(goals), "meets": meets})  # fmt: skip
    return markdown(head, align, lines), pd.DataFrame(records)


def memory_table(sizes, frames, results) -> tuple[str, pd.DataFrame]:
    head = ("| group (fresh process) | " + " | ".join(f"{f:,}: anon at start / peak / file-backed (MB)" for f in frames)
            + " | max RSS of the process (MB) at the largest | anon peak ≤ 2 GB at the largest |")  # fmt: skip
    align = "|---|" + "---:|" * len(frames) + "---:|---|"
    lines, records = [], []
    for group in ("relational", "knn", "search", "lng", "templates"):
        cells, last = [], None
        for n in sizes:
            m = results.get(n, {}).get(group, {}).get("mem")
            cells.append("—" if not m else f"{m['anon_start_MB']:,.0f} / {m['anon_peak_MB']:,.0f} / "
                                           f"{m['file_rss_MB']:,.0f}")  # fmt: skip
            last = m
            if m:
                records.append({"group": group, "frames": results[n]["frames"], **m})
        hwm = (results.get(sizes[-1], {}).get(group, {}).get("mem") or {}).get("hwm_MB")
        meets = "—" if not last else ("yes" if last["anon_peak_MB"] <= 2048 else "NO")
        lines.append([group] + cells + [_f(hwm, 0), meets])
    return markdown(head, align, lines), pd.DataFrame(records)


def sharded_table(sizes, frames, results) -> tuple[str, pd.DataFrame, list]:
    have = [(n, f) for n, f in zip(sizes, frames) if "shards" in results.get(n, {}).get("sharded", {})]
    head = ("| path | " + " | ".join(f"{f:,}: one process / sharded / added (ms)" for _, f in have)
            + " | per-shard work at the largest (ms, shard 1 / 2) | ask / reply per shard (kB) | added ≤ 20 ms |")
    align = "|---|" + "---:|" * len(have) + "---:|---:|---|"
    lines, records = [], []
    for name in SHARDED:
        cells, added_last = [], None
        for n, f in have:
            one = _get(results, n, GROUP_OF[name], SINGLE_KEY[name])
            two = _get(results, n, "sharded", f"sharded {name} (ms)")
            added = None if one is None or two is None else two - one
            added_last = added
            cells.append(f"{_f(one, 3)} / {_f(two, 3)} / {_f(added, 2)}")
            shards = results[n]["sharded"]["shards"]
            records.append({"path": name, "frames": f, "single_ms": one, "sharded_ms": two, "added_ms": added,
                            **{f"shard{s['shard']}_ms": s.get(f"{name} (ms)") for s in shards},
                            **{f"shard{s['shard']}_reply_B": s.get(f"{name} reply (B)") for s in shards},
                            "ask_B": shards[0].get(f"{name} ask (B)")})  # fmt: skip
        if not have:
            continue
        shards = results[have[-1][0]]["sharded"]["shards"]
        work = " / ".join(_f(s.get(f"{name} (ms)"), 3) for s in shards)
        sizes_kb = (f"{_f((shards[0].get(f'{name} ask (B)') or 0) / 1e3, 1)} / "
                    + " + ".join(_f((s.get(f"{name} reply (B)") or 0) / 1e3, 1) for s in shards))
        meets = "—" if added_last is None else ("yes" if added_last <= 20 else "NO")
        lines.append([name, *cells, work, sizes_kb, meets])
    return markdown(head, align, lines), pd.DataFrame(records), have


GROUP_OF = {name: ("relational" if name.startswith(("relational", "scene")) else "knn" if "NN" in name
                   else "lng" if name.startswith("LNG") else "templates" if name.startswith("template") else "search")
            for name in SHARDED}  # fmt: skip


def projection(results, have) -> str:
    """10^8 frames on N machines, from the per-shard work at the largest measured size (scaled by the frames per
    shard with the path's fitted exponent) plus the measured fixed overhead, and the transfer sizes."""
    if not have:
        return "No sharded figures: no projection."
    n_big = have[-1][0]
    shards = results[n_big]["sharded"]["shards"]
    per_shard_frames = np.mean([s["frames"] for s in shards])
    lines = []
    head = "| path | b (one process) | " + " | ".join(f"N = {m}: per-shard ms / total ms" for m in (10, 50, 100)) + " |"
    align = "|---|---:|" + "---:|" * 3
    for name in ["relational exact", "scene: kick_right", "16-NN single", "stretches 1 s, exact", "clips, fast",
                 "LNG 1 s, k = 256", "template search, lower bounds"]:
        group, key = GROUP_OF[name], SINGLE_KEY[name]
        sizes = sorted(results)
        frames = [results[n]["frames"] for n in sizes]
        b = exponent(frames, [_get(results, n, group, key) for n in sizes])
        work = np.mean([s.get(f"{name} (ms)") or np.nan for s in shards])
        two = _get(results, n_big, "sharded", f"sharded {name} (ms)")
        fixed = max(0.0, (two or 0) - max(s.get(f"{name} (ms)") or 0 for s in shards)) if two else np.nan
        cells = []
        for m in (10, 50, 100):
            per = work * (1e8 / m / per_shard_frames) ** (max(0.0, b) if b is not None else 1.0)
            reply = np.mean([s.get(f"{name} reply (B)") or 0 for s in shards])
            # coordinator: fixed Dask overhead (measured, 2 shards) grows ~ with the replies merged; 1 Gbit/s links
            total = per + fixed + m * reply * 8 / 1e9 * 1e3
            cells.append(f"{_f(per, 2)} / {_f(total, 2)}")
        lines.append([name, _f(b, 2), *cells])
    return markdown(head, align, lines)


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    info["date"] = time.strftime("%Y-%m-%dT%H:%M:%S")
    sizes = SIZES_QUICK if quick else SIZES
    big, record, dbs, peaks = build_databases(quick)
    folder = REPO / ".cache" / "bench" / (DATABASE.tag + ("-quick" if quick else ""))
    scratch = folder / "runs"
    scratch.mkdir(parents=True, exist_ok=True)
    smallest = dbs[sizes[0]]
    plan = plan_queries(smallest, quick)
    plan["template"] = str(learn_template(smallest, folder))  # the smallest size: real documents first
    plan["template_label"] = f"{LEARNED.get('label', '?')}` ({LEARNED.get('frames')} frames, {LEARNED.get('examples')} examples"
    plan_file = scratch / "plan.json"
    plan_file.write_text(json.dumps(plan))
    results = {}
    for n in sizes:
        db = dbs[n]
        docs = db.documents
        real = _is_real(docs)
        results[n] = {"frames": db.n_frames, "documents": len(db),
                      "real_frames": int(docs.loc[real, "n_frames"].sum())}  # fmt: skip
        log(f"{db.n_frames:,} frames ({results[n]['real_frames'] / db.n_frames:.0%} real)")
        for group in GROUPS:
            results[n][group] = run_group(group, db, plan_file, quick, scratch)
    info["others"] = monitor.report()
    info["load_end"] = loadavg()
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    ctx = {"quick": quick, "sizes": list(sizes), "results": {str(n): r for n, r in results.items()}, "info": info,
           "plan": plan, "peaks": peaks, "total_s": time.perf_counter() - t_start}  # fmt: skip
    (out_dir / ("scaling-quick.json" if quick else "scaling.json")).write_text(json.dumps(ctx, default=float, indent=1))
    render(ctx, big, record, out_dir)
    return 0


def render(ctx: dict, big, record: dict, out_dir: Path) -> None:
    """Print the section (markdown) from a run's saved figures and write its CSV."""
    quick, sizes, info, plan, peaks = ctx["quick"], ctx["sizes"], ctx["info"], ctx["plan"], ctx["peaks"]
    results = {int(n): r for n, r in ctx["results"].items()}
    folder = REPO / ".cache" / "bench" / (DATABASE.tag + ("-quick" if quick else ""))
    frames = [results[n]["frames"] for n in sizes]
    times, t_df = time_table(sizes, frames, results)
    mem, m_df = memory_table(sizes, frames, results)
    shard_md, s_df, have = sharded_table(sizes, frames, results)
    proj = projection(results, have)
    errors = [f"{r['group']} at {results[n]['frames']:,}: {r['error']}" for n in sizes
              for r in results[n].values() if isinstance(r, dict) and "error" in r]  # fmt: skip

    title = f"### Cost growth at {' / '.join(f'{s / 1e6:g}M' for s in sizes)} frames: every query path, one " \
            f"process and sharded ({'QUICK run' if quick else 'full run'})"
    notes = [
        ("each group of query paths runs in a FRESH process per size (`python -m benchmarks.bench_scaling --worker "
         "GROUP DB`): setup (features, indexes, kd-tree) timed once, one warm-up query (numba), then the queries; "
         "a figure is the median over its queries (relational: best of 2 runs each) in ms"),
    ]
    head = header(title, info, ("numpy", "numba", "scipy", "pykdtree"), notes)
    head = re.sub(r"at end: [0-9. ]+;", f"at end: {info.get('load_end', loadavg())};", head)
    print(re.sub(r"^- date: [^,]+,", f"- date: {info.get('date', '?')},", head, flags=re.MULTILINE))
    for line in describe_db(big, record):
        print(f"- {line}")
    print("- sizes: nested prefixes of the largest database's documents, REAL FIRST (real documents in a fixed random "
          "order, seed 0, then the derived ones in a fixed random order), copied into databases of their own; "
          "**derived share per size: " + ", ".join(
              f"{results[n]['frames']:,} frames: {1 - results[n]['real_frames'] / results[n]['frames']:.0%} derived "
              f"({results[n]['real_frames']:,} real)" for n in sizes) + "**")
    print(f"- building (first run, cached after): {peaks['wall_s']:.0f} s wall (largest database "
          f"{peaks['largest_s']:.0f} s, then the smaller sizes), **peak RSS {peaks['peak_rss_MB']:,.0f} MB** (psutil, "
          f"every 50 ms; includes the file-backed pages of the memory-mapped arrays read and written), **peak disk {peaks['peak_disk_GB']:.1f} GB** under `.cache/bench/{folder.name}` (allocated "
          f"blocks every second; {peaks['final_disk_GB']:.1f} GB once built), load at the build's start "
          f"{peaks.get('load_start', '?')}")
    print(f"- queries, drawn once from the REAL documents of the smallest size (held by every size): relational: "
          f"{len(plan['relational'])} random 1 s examples, the 11 lower-body features of the 2005 set, "
          f"`query_by_example(db, ex, lower, mode=..., indexes=...)`; scene: `find(db, text, indexes=...)` x 3; "
          f"16-NN: random database frames of F15E, single (`KnnIndex.query(row, 16)`, one row at a time) and one "
          f"batch of {N['knn_batch'][1 if quick else 0]}; similarity: `SimilaritySearch(db, 'F15E')`, "
          f"{len(plan['stretches'])} 1 s stretches and {len(plan['clips'])} whole HDM05 clips, K = {K_SEARCH}, own "
          f"document excluded; LNG: `match_motion(db, doc, (a, a + 120), k = 256, n_matches = {K_SEARCH})` on "
          f"{len(plan['lng'])} 1 s stretches; template: one template learned (2006 set) from the real examples "
          f"of `{plan.get('template_label', '?')}, actors {', '.join(TRAIN_ACTORS)}), `search_template(...)` (by lower bounds) x 3")
    print(f"- {info['others']}")
    if errors:
        print("- FAILED groups: " + "; ".join(errors))
    print()
    print("#### Time per size and fitted exponent (time ∝ frames^b, least squares over the sizes)")
    print()
    print(times)
    print()
    def per_size(group, key, fmt):
        vals = [results[n].get(group, {}).get(key) for n in sizes]
        return ", ".join("—" if v is None else fmt(v) for v in vals)

    print("What grows with the database, per size: median hits of the relational exact query "
          f"{per_size('relational', 'relational exact hits', lambda v: f'{v:,.0f}')}, fuzzy "
          f"{per_size('relational', 'relational fuzzy hits', lambda v: f'{v:,.0f}')}, 1-mismatch "
          f"{per_size('relational', 'relational mismatch hits', lambda v: f'{v:,.0f}')}; hits of the scenes: "
          + "; ".join(f"`{t}` {per_size('relational', f'scene: {t} hits', lambda v: f'{v:,.0f}')}"
                      for t in DESCRIPTIONS)
          + f"; share of the frames the template search by lower bounds aligns: "
          f"{per_size('templates', 'template: share of frames aligned', lambda v: f'{v:.1%}')}; of the 10 hits of "
          "an exact search, derived copies (mirrored / slower) of the query's own document (median): stretches "
          f"{per_size('search', 'stretches exact: hits of 10 that are derived copies of the query' + chr(39) + 's document (median)', lambda v: f'{v:g}')}, clips "
          f"{per_size('search', 'clips exact: hits of 10 that are derived copies of the query' + chr(39) + 's document (median)', lambda v: f'{v:g}')}. Hits and "
          "candidate frames grow with the derived near-copies (mirrored and a few percent slower), so the work of "
          "the relational, scene and template paths grows with them.")
    print()
    print("#### Peak memory of each query path (fresh process per group)")
    print()
    print(mem)
    print()
    print("RssAnon of /proc/self/status (the process's heap: features, kd-tree, indexes, query buffers — NOT the "
          "memory-mapped database arrays, which are file-backed and reported apart as RssFile) sampled every 10 ms "
          "while the queries ran: at the start of the queries (the state the path holds) / the peak. 'max RSS': "
          "VmHWM of the fresh process at its end (setup included, file-backed pages too; `ru_maxrss` is not used: "
          "Linux carries the parent's value over fork + exec). The ≤ 2 GB target is read as the anon peak (everything beyond the mapped arrays).")
    print()
    print("#### Sharded (`Engine(db, scheduler=\"local\", n_shards=2)`: a LocalCluster of 2 workers on this 2-core "
          "machine) beside one process")
    print()
    print(shard_md)
    print()
    print("One process: the figures of the table above (same queries, another fresh process at the same size). "
          "Sharded: the same queries (a prefix of them) through the Engine, warmed (`numeric_sets=('F15E',), "
          "relational_sets=('2005', '2006')`; `k=256` to `match`, `n_matches=None` to `find`, `delta=0.1` to "
          "`search_template`: the one-process calls' arguments), median ms (each relational query and single 16-NN query the best of 2 "
          "runs, as in one process); 'added' = sharded − one process. Per-shard work: the "
          "same `Shard` methods called in one process without Dask (each shard's half of the documents). ask / reply: "
          "pickled bytes of the query sent to a shard and of each shard's reply (hit table or (distances, frames)). "
          "On 2 cores both shards and the coordinator share the CPUs, so sharding cannot be faster here.")
    print()
    if have:
        sh = results[have[-1][0]]["sharded"]
        start = sh.get("setup: Engine start + warm (s)", sh.get("setup: ShardedDB start + warm (s)", 0))  # older runs
        print(f"Engine start + warm at {have[-1][1]:,} frames: {start:.1f} s; "
              f"peak RSS of the coordinator and its 2 workers (the sum of each process's VmHWM, incl. file-backed pages): "
              f"{sh.get('sharded_peak_rss_MB', 0):,.0f} MB")
        print()
    print("Library notes: `Engine.search_template(...)`: each shard aligns its own documents best lower bound "
          "first until none can hold one of its K best; exact clips and stretches run a fast round on every shard first and share the K-th best "
          "cost it finds as each shard's starting limit (the round's time is in the sharded figure); "
          "`Engine.match` (LNG, `k=256`) asks the shards for the 256 nearest frames of every "
          "query frame and builds the graph at the coordinator: its per-shard work is that kNN "
          "(`Shard.knn(F15E, 120 rows, 256)`) and its transfer 120 x 256 (distance, frame) pairs per shard.")
    print()
    print("#### Projection on paper: 10^8 frames on N machines")
    print()
    print("Per-shard work at 10^8 / N frames = the measured per-shard ms at the largest size x (frames ratio)^b "
          "(b: the one-process exponent above); total = that + the fixed cost of one fan-out and merge measured "
          "here (sharded − slowest shard at the largest size) + N replies over 1 Gbit/s links. It assumes one "
          "shard per machine with its data resident and the replies merged at the coordinator; not measured.")
    print()
    print(proj)
    csv_path = Path(out_dir) / ("scaling-quick.csv" if quick else "scaling.csv")
    write_results_csv(csv_path, {"times": t_df, "memory": m_df, "sharded": s_df}, info)
    print()
    print(f"CSV: {csv_path}; total benchmark time {ctx['total_s']:.0f} s")


def learn_template(db, folder: Path) -> Path:
    """One motion template (2006 set) learned from the REAL HDM05 examples of a kick class by the training actors,
    in the smallest size's database (real documents only: derived copies keep their labels), saved for the
    workers."""
    from mocapviz.relational.templates import learn_class

    path = folder / "runs" / "template.json"
    docs = db.documents
    hdm = _is_real(docs) & docs["path"].astype("string").str.contains("hdm05", na=False).to_numpy()
    if not hdm.any():
        raise RuntimeError("no real HDM05 document to learn a template from")
    labels = sorted(docs.loc[hdm, "label"].dropna().unique())
    label = next((lb for lb in labels if "kick" in lb.lower()), labels[0])
    if not _is_real(docs[docs["label"].eq(label).fillna(False).to_numpy()]).all():
        raise RuntimeError(f"derived copies of {label} in {db.path}: the template would learn from them")
    template = learn_class(db, label, TRAIN_ACTORS, "2006")
    template.save(path)
    LEARNED.update(label=label, frames=len(template.values), examples=template.n_examples)
    return path


LEARNED: dict = {}


if __name__ == "__main__":
    if "--worker" in sys.argv:
        args = [a for a in sys.argv[1:] if a not in ("--worker", "--quick")]
        worker(args[0], args[1], args[2], "--quick" in sys.argv, args[3])
        sys.exit(0)
    quick = "--quick" in sys.argv
    if "--render" in sys.argv:  # print the section again from the saved figures (results/scaling[-quick].json)
        os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
        out = Path(__file__).resolve().parent / "results"
        saved = json.loads((out / ("scaling-quick.json" if quick else "scaling.json")).read_text())
        big, record = benchmark_db(DATABASE, quick)
        render(saved, big, record | {"cached": True}, out)
        sys.exit(0)
    sys.exit(main(quick=quick, repeats=1 if quick else 3))
