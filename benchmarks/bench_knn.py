"""kNN benchmark (Krüger, Tautges, Weber & Zinke 2010, Table 1 and §5.3) on F15E features of >= 1M frames.

(a) Build time and memory of the search structures: ``mocapviz.similarity.knn.KnnIndex`` with its engines "kdtree"
    (ours, numba: :mod:`mocapviz.similarity.kdtree`, the default), "ckdtree" (scipy cKDTree, the default before
    issue 43) and "brute" (a float64 copy), and pykdtree (PyPI, OpenMP kd-tree, float32) when it is installed.
(b) 16-NN and 256-NN per query, exact, batched queries over all cores: ours ("kdtree"), and scipy's cKDTree
    beside it, against numpy brute force
    (``KnnIndex(engine="brute")``: scipy ``cdist`` + ``argpartition``, chunked, threads; on a sample of the
    queries) and against pykdtree, the fastest other engine found (faiss-cpu has no exact search faster than
    its flat index, which is brute force with BLAS). Ours single-threaded and eps = 0.5 beside them. Before
    timing, ours, cKDTree and brute force must agree on the sampled queries (up to exact ties). Queries: random
    database frames. Each figure: median of ``repeats`` runs of the whole batch; the engines alternate
    within a repeat so that they see the same machine state. CPU ms/query (process time of all threads per
    query) is printed too: it is less disturbed by other processes than wall time. Beside these batched
    figures, the single-query latency: ``N_SINGLE`` queries one at a time (one row per call, ``threads=1``),
    the engines alternating query by query; the median.
(c) Fat-graph base poses (§5.3): ``base_poses`` against ``base_poses_quadratic`` on evenly spaced subsets of
    the real frames (identical results required), and ``base_poses`` on the whole database.
(d) Table 1 for every feature set (F15E ... F30x3E, Fp8/16/25): :func:`mocapviz.experiments.knn_timings`, with
    each set's slowdown against F15E beside the paper's (CMU column).

The benchmark database: all four shared archives ingested at 30 Hz (``MotionDB.ingest(..., fps=30, threads=2)``),
about 446k frames. The paper's scale (1-1.3M frames) is reached by appending left/right MIRRORED copies
(``mocapviz.motion.skeleton.mirror``) of the documents, archive by archive, until the database holds 1M frames; when
every document has been mirrored once (about 892k frames) the next round repeats mirrored copies, i.e. exact
duplicates of frames already present. The output says how many frames of each kind there are. The database
is cached under ``<repo>/.cache/bench/<tag>[-quick]/`` (``benchmarks.common.benchmark_db``) with the wall time of
the ingest that built it.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from mocapviz.features import numeric_features

from .common import (
    REPO,
    BenchDB,
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

FPS = 30
DATABASE = BenchDB("knn-v2", fps=FPS, min_frames=1_000_000)
KS = (16, 256)
N_QUERIES = {16: 20_000, 256: 5_000}  # batch per figure; quick: N_QUERIES_QUICK
N_QUERIES_QUICK = {16: 2_000, 256: 500}
N_BRUTE = 200  # queries timed (and checked) with brute force; quick: N_BRUTE_QUICK
N_BRUTE_QUICK = 50
N_SINGLE = 200  # queries timed one at a time (single-query latency), per k; quick: N_SINGLE_QUICK
N_SINGLE_QUICK = 50
EPS = 0.5  # the approximation the paper found harmless for reconstruction (§5.2)
N_SET_QUERIES = 500  # per feature set in (d); quick: N_SET_QUERIES_QUICK
N_SET_QUERIES_QUICK = 100
TARGET_MS = {16: 0.1, 256: 1.0}
TARGET_SPEEDUP = 50.0
# Table 1, F15E, ms per query: HDM05 (380,813 frames) and CMU (1,038,388 frames) at 30 Hz, ANN library, 2010 PC
PAPER_MS = {16: (1.11, 1.65), 256: (4.53, 7.36)}
FAT_RADIUS = 10.0  # cm, F15E
FAT_K = 32
FAT_SIZES = (2_000, 5_000, 10_000)
FAT_SIZES_QUICK = (1_000, 2_000)


# ============================================================================ engines
def _rss() -> int:
    """Resident memory of this process, bytes."""
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _pykdtree():
    try:
        from pykdtree.kdtree import KDTree
    except ImportError:
        return None
    return KDTree


def _build_timed(make, repeats: int) -> tuple[object, list[float], int]:
    """Build ``repeats`` times: the last structure, the wall seconds of each build, and the resident memory the
    first build added (later builds reuse memory the allocator got back from their predecessor)."""
    times, rss, built = [], 0, None
    for _ in range(repeats):
        built = None  # release the previous one first
        rss0 = _rss()
        t0 = time.perf_counter()
        built = make()
        times.append(time.perf_counter() - t0)
        rss = _rss() - rss0 if len(times) == 1 else rss
    return built, times, rss


def build_engines(features: np.ndarray, repeats: int) -> tuple[dict, list[dict]]:
    """{name: search function (queries, k, **options) -> (distances, indices)} and one build row per engine."""
    from mocapviz.similarity.knn import KnnIndex

    engines, rows = {}, []
    for engine, label in (("kdtree", "ours: KnnIndex(engine='kdtree'), numba, float32 points, leafsize 64"),
                          ("ckdtree", "scipy cKDTree: KnnIndex(engine='ckdtree'), float64, leafsize 16 (before)"),
                          ("brute", "brute force: KnnIndex(engine='brute')")):  # fmt: skip
        index, times, rss = _build_timed(lambda engine=engine: KnnIndex(features, engine=engine), repeats)
        rows.append({"engine": label, "build_s": statistics.median(times), "runs_s": times,
                     "nbytes_MB": index.nbytes / 2**20, "rss_MB": rss / 2**20})  # fmt: skip
        engines[engine] = lambda q, k, eps=0.0, threads=None, index=index: index.query(q, k, eps=eps, threads=threads)
    kdtree = _pykdtree()
    if kdtree is not None:
        data = np.ascontiguousarray(features, dtype=np.float32)
        tree, times, rss = _build_timed(lambda: kdtree(data, leafsize=16), repeats)
        rows.append({"engine": "pykdtree (PyPI), float32, leafsize 16", "build_s": statistics.median(times),
                     "runs_s": times, "nbytes_MB": (data.nbytes + 8 * len(data)) / 2**20,
                     "rss_MB": rss / 2**20})  # fmt: skip
        engines["pykdtree"] = lambda q, k, eps=0.0, tree=tree: tree.query(
            np.ascontiguousarray(q, dtype=np.float32), k=k, eps=eps
        )
    return engines, rows


def _timed(fn) -> tuple[float, float, object]:
    """Wall and CPU (all threads) seconds of fn(), and its result."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def _disagreements(features, queries, d, i, d_ref, i_ref) -> int:
    """Entries where two exact results differ by more than an exact tie (see tests/test_knn.py)."""
    bad = int((np.abs(d - d_ref) > 1e-5).sum())
    for r, c in zip(*np.nonzero(i != i_ref)):
        to_all = np.linalg.norm(features[i_ref[r, c]].astype(np.float64) - queries[r])
        own = np.linalg.norm(features[i[r, c]].astype(np.float64) - queries[r])
        bad += int(abs(own - to_all) > 1e-9)
    return bad


def single_latency(engines: dict, queries: np.ndarray, k: int, variants: list) -> dict:
    """{variant name: median ms} of single queries, each alone (one row, ``threads=1`` where the engine takes it),
    the variants alternating query by query; variants with no single-query options are left out."""
    times = {name: [] for name, *_, single in variants if single is not None}
    for q in queries:
        for name, engine, _, _, single in variants:
            if single is not None:
                t0 = time.perf_counter()
                engines[engine](q[None], k, **single)
                times[name].append((time.perf_counter() - t0) * 1e3)
    return {name: statistics.median(t) for name, t in times.items()}


def bench_queries(features: np.ndarray, engines: dict, quick: bool, repeats: int, seed: int = 7):
    """(b): per k, per-query times of each engine on the same random database frames: batched, and single."""
    rng = np.random.default_rng(seed)
    n_queries = N_QUERIES_QUICK if quick else N_QUERIES
    n_brute = N_BRUTE_QUICK if quick else N_BRUTE
    rows, notes = [], []
    for k in KS:
        queries = features[rng.choice(len(features), n_queries[k], replace=False)].astype(np.float64)
        sample = queries[:n_brute]
        d_ref, i_ref = engines["brute"](sample, k)
        bad = 0
        for engine in ("kdtree", "ckdtree"):
            d, i = engines[engine](sample, k)
            bad += (wrong := _disagreements(features, sample, d, i, d_ref, i_ref))
            notes.append(f"k={k}: KnnIndex(engine='{engine}') and brute force on {n_brute} queries: "
                         + ("identical (up to exact ties)" if not wrong else f"{wrong} ENTRIES DIFFER"))  # fmt: skip
        if "pykdtree" in engines:
            d_p, i_p = engines["pykdtree"](sample, k)
            bad_p = _disagreements(features, sample, d_p.astype(np.float64), i_p.astype(np.int64), d_ref, i_ref)
            notes.append(f"k={k}: pykdtree (float32 distances) and brute force on {n_brute} queries: "
                         + ("identical (up to exact ties)" if not bad_p else f"{bad_p} entries differ by > 1e-5 "
                            "or beyond a tie (float32 rounding)"))  # fmt: skip
        # (name, engine, batched options, batch, single-query options or None)
        variants = [("ours (kdtree), all cores", "kdtree", {}, queries, {"threads": 1}),
                    ("ours (kdtree), 1 thread", "kdtree", {"threads": 1}, queries, None),
                    (f"ours (kdtree), eps = {EPS}, all cores", "kdtree", {"eps": EPS}, queries,
                     {"eps": EPS, "threads": 1}),
                    ("scipy cKDTree (engine='ckdtree', before), all cores", "ckdtree", {}, queries, {"threads": 1}),
                    ("scipy cKDTree (engine='ckdtree', before), 1 thread", "ckdtree", {"threads": 1}, queries, None),
                    (f"scipy cKDTree (engine='ckdtree', before), eps = {EPS}, all cores", "ckdtree", {"eps": EPS},
                     queries, {"eps": EPS, "threads": 1}),
                    ("numpy brute force, all cores", "brute", {}, sample, {"threads": 1})]  # fmt: skip
        if "pykdtree" in engines:
            variants.insert(6, ("pykdtree, all cores", "pykdtree", {}, queries, {}))
        runs = {name: [] for name, *_ in variants}
        for _ in range(repeats):
            for name, engine, options, q, _ in variants:
                log(f"k={k}: {name}, {len(q):,} queries")
                wall, cpu, _ = _timed(lambda e=engine, q=q, o=options, k=k: engines[e](q, k, **o))
                runs[name].append((wall / len(q) * 1e3, cpu / len(q) * 1e3))
        n_single = N_SINGLE_QUICK if quick else N_SINGLE
        log(f"k={k}: single-query latency, {n_single} queries")
        single = single_latency(engines, queries[:n_single], k, variants)
        brute_ms = statistics.median(r[0] for r in runs["numpy brute force, all cores"])
        brute_single = single["numpy brute force, all cores"]
        for name, _, _, q, _ in variants:
            ms = statistics.median(r[0] for r in runs[name])
            ours = name.startswith("ours") and "eps" not in name and "1 thread" not in name
            meets = ""
            if ours:
                misses = ([f"{ms:.3f} ms > {TARGET_MS[k]:g}"] if ms > TARGET_MS[k] else []) + (
                    [f"{brute_ms / ms:.0f}× < {TARGET_SPEEDUP:.0f}×"] if brute_ms / ms < TARGET_SPEEDUP else [])
                meets = "NO: " + ", ".join(misses) if misses else "yes"
            rows.append({"k": k, "engine": name, "queries": len(q), "ms_per_query": ms,
                         "cpu_ms_per_query": statistics.median(r[1] for r in runs[name]),
                         "runs_ms": [r[0] for r in runs[name]], "vs_brute": brute_ms / ms,
                         "single_queries": n_single if name in single else None,
                         "single_ms": single.get(name), "single_vs_brute": brute_single / single[name]
                         if name in single else None,
                         "paper_hdm05_ms": PAPER_MS[k][0], "paper_cmu_ms": PAPER_MS[k][1],
                         "target": f"≤ {TARGET_MS[k]:g} ms, ≥ {TARGET_SPEEDUP:.0f}× brute" if ours else "",
                         "meets": meets, "differ": bad})  # fmt: skip
    return rows, notes


# ============================================================================ (c) fat-graph base poses
def bench_fat_graph(features: np.ndarray, real_frames: int, quick: bool) -> list[dict]:
    """(c): base_poses beside base_poses_quadratic on evenly spaced real frames; base_poses on all frames."""
    from mocapviz.similarity.knn import base_poses, base_poses_quadratic

    rows = []
    base_poses(features[:100], FAT_RADIUS, k=FAT_K)  # numba: compile or load from the disk cache
    for n in FAT_SIZES_QUICK if quick else FAT_SIZES:
        subset = features[: real_frames : max(1, real_frames // n)][:n]
        log(f"base poses of {len(subset):,} frames")
        wall, _, (base, cluster) = _timed(lambda subset=subset: base_poses(subset, FAT_RADIUS, k=FAT_K))
        wall_q, _, (base_q, cluster_q) = _timed(lambda subset=subset: base_poses_quadratic(subset, FAT_RADIUS,
                                                                                            k=FAT_K))  # fmt: skip
        same = np.array_equal(base, base_q) and np.array_equal(cluster, cluster_q)
        rows.append({"frames": len(subset), "base_poses": len(base), "ours_s": wall, "quadratic_s": wall_q,
                     "speed-up": wall_q / wall, "identical": "yes" if same else "NO"})  # fmt: skip
    if not quick:
        log(f"base poses of all {len(features):,} frames")
        wall, _, (base, _) = _timed(lambda: base_poses(features, FAT_RADIUS, k=FAT_K))
        rows.append({"frames": len(features), "base_poses": len(base), "ours_s": wall, "quadratic_s": None,
                     "speed-up": None, "identical": "(no reference: n^2 = "
                     f"{len(features) ** 2 * 8 / 2**40:.0f} TiB of distances)"})  # fmt: skip
    return rows


# ============================================================================ (d) Table 1, all feature sets
def bench_sets(db, quick: bool) -> pd.DataFrame:
    """(d): :func:`mocapviz.experiments.knn_timings` on every set of Table 1, beside the paper's CMU column."""
    from mocapviz.experiments import knn_timings
    from mocapviz.experiments.numeric import krueger2010_table1

    log("Table 1: every feature set")
    ours = knn_timings(db, ks=KS, n_queries=N_SET_QUERIES_QUICK if quick else N_SET_QUERIES, database="benchmark")
    paper = krueger2010_table1().query("database == 'CMU'")[["set", "k", "mean_ms"]].rename(columns={"mean_ms": "paper_ms"})
    out = ours.merge(paper, on=["set", "k"])
    f15 = out[out["set"] == "F15E"].set_index("k")
    out["slowdown"] = out["mean_ms"] / out["k"].map(f15["mean_ms"])
    out["paper_slowdown"] = out["paper_ms"] / out["k"].map(f15["paper_ms"])
    return out


# ============================================================================ output
def _header(info: dict, quick: bool, repeats: int) -> str:
    return header(
        "# mocapviz kNN benchmark (Krüger, Tautges, Weber & Zinke 2010, Table 1, §5.3)"
        + (" (--quick: small database)" if quick else ""),
        info, ("numpy", "scipy", "numba", "pykdtree"),
        [f"each figure: median of {repeats} runs of the whole query batch; engines alternate within a run",
         "paper (Table 1, F15E, exact): ANN library on a 2010 PC; HDM05 380,813 frames, CMU 1,038,388 frames"],
    )  # fmt: skip


def table_build(rows: list[dict]) -> str:
    return markdown(
        "| engine | build s (median) | runs s | structure MB | RSS growth MB |",
        "|---|---:|---|---:|---:|",
        ([r["engine"], _f(r["build_s"]), ", ".join(f"{t:.2f}" for t in r["runs_s"]), _f(r["nbytes_MB"], 1),
          _f(r["rss_MB"], 1)] for r in rows),
    )  # fmt: skip


def table_queries(rows: list[dict]) -> str:
    return markdown(
        "| k | engine | batch of queries | batched, ms per query | batched, CPU ms per query | batched runs ms per "
        "query | brute / this, batched | single query latency ms (median) | brute / this, single query "
        "| paper ms HDM05 / CMU | target (batched) | meets |",
        "|---:|---|---:|---:|---:|---|---:|---:|---:|---|---|---|",
        ([str(r["k"]), r["engine"], f"{r['queries']:,}", _f(r["ms_per_query"], 4), _f(r["cpu_ms_per_query"], 4),
          ", ".join(f"{t:.4f}" for t in r["runs_ms"]), f"{r['vs_brute']:.0f}×", _f(r["single_ms"], 4),
          "—" if r["single_vs_brute"] is None else f"{r['single_vs_brute']:.0f}×",
          f"{r['paper_hdm05_ms']:g} / {r['paper_cmu_ms']:g}", r["target"], r["meets"]] for r in rows),
    )  # fmt: skip


def table_sets(rows: pd.DataFrame) -> str:
    wide = rows.pivot_table(index=["set", "d", "features_s", "build_s"], columns="k",
                            values=["mean_ms", "slowdown", "paper_ms", "paper_slowdown"], sort=False)  # fmt: skip
    return markdown(
        "| set | d | features s | tree build s | 16-NN ms | × F15E | paper 16-NN ms (CMU) | paper × F15E "
        "| 256-NN ms | × F15E | paper 256-NN ms (CMU) | paper × F15E |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ([s, str(d), _f(fs), _f(bs)] + [c for k in KS for c in (
            _f(r[("mean_ms", k)], 3), f"{r[('slowdown', k)]:.1f}×", _f(r[("paper_ms", k)]),
            f"{r[('paper_slowdown', k)]:.1f}×")]
         for (s, d, fs, bs), r in wide.iterrows()),
    )  # fmt: skip


def table_fat(rows: list[dict]) -> str:
    return markdown(
        "| frames | base poses | base_poses s (kd-tree, O(n log n)) | base_poses_quadratic s (O(n²)) | speed-up "
        "| identical |",
        "|---:|---:|---:|---:|---:|---|",
        ([f"{r['frames']:,}", f"{r['base_poses']:,}", _f(r["ours_s"]), _f(r["quadratic_s"]),
          "—" if r["speed-up"] is None else f"{r['speed-up']:.1f}×", r["identical"]] for r in rows),
    )  # fmt: skip


# ============================================================================ main
def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info() | {"pykdtree": package_version("pykdtree")}
    db, record = benchmark_db(DATABASE, quick)
    log(f"F15E of {db.n_frames:,} frames")
    t0 = time.perf_counter()
    features = numeric_features(db, "F15E", progress=False)
    t_features = time.perf_counter() - t0
    engines, build_rows = build_engines(features, repeats)
    query_rows, query_notes = bench_queries(features, engines, quick, repeats)
    del engines
    fat_rows = bench_fat_graph(features, record["real_frames"], quick)
    del features
    set_rows = bench_sets(db, quick)
    info["others"] = monitor.report()

    print(_header(info, quick, repeats))
    for line in describe_db(db, record):
        print(f"- {line}")
    print(f"- F15E features: `mocapviz.features.numeric_features(db, 'F15E')`, ({db.n_frames:,}, 15) float32 cm, "
          f"{t_features:.1f} s")  # fmt: skip
    print()
    print("## (a) Build time and memory")
    print()
    print(table_build(build_rows))
    print()
    print("Structure MB (`KnnIndex.nbytes`): ours (kdtree) = the points in leaf order (float32: F15E is float32) + "
          "permutation + nodes (children, row range and tight box, float64) + frame map; cKDTree = float64 copy of "
          "the features + tree permutation and its inverse + nodes (72 B each) + frame map; brute = the float64 copy; pykdtree = float32 data + permutation "
          "(nodes not counted). RSS growth: resident memory after the first build minus before (includes allocator "
          "slack; pykdtree's float32 copy was made before and is not in it).")  # fmt: skip
    print()
    print("## (b) k nearest neighbours per query (exact unless eps; ms, lower is better)")
    print()
    print(table_queries(query_rows))
    print()
    print("Queries: random database frames (each finds itself). Brute force: `KnnIndex(engine='brute')` — scipy "
          "`cdist` (sums of squared differences) + `np.argpartition`, 64 MB chunks of queries over threads; timed on "
          "the first queries of the batch only. CPU ms/query: process CPU time (all threads) per query. Batched: "
          "the whole batch in one call over all cores (ours 1 thread: `threads=1`), wall time / queries; "
          f"throughput, not the wait for one answer. Single query latency: the first {query_rows[0]['single_queries']} "
          "queries of the batch, each in its own call (one row; ours and brute force `threads=1`, pykdtree "
          "parallelises over queries so uses one thread for one), engines alternating query by query; median "
          "wall ms; shown on the row of the engine and eps it was measured with.")  # fmt: skip
    for n in query_notes:
        print(f"- {n}")
    print()
    print(f"## (c) Fat-graph base poses (§5.3), F15E, radius {FAT_RADIUS:g} cm, at most k = {FAT_K} neighbours")
    print()
    print(table_fat(fat_rows))
    print()
    print("Subsets: evenly spaced frames of the real (not mirrored) part of the database. Identical: same base poses "
          "in the same order and the same cluster of every frame (ties broken by lowest frame number on both "
          "sides).")  # fmt: skip
    print()
    print(f"## (d) Table 1: every feature set, exact k-NN, {set_rows['queries'].iloc[0]:,} random database frames "
          "per set as one batch over all cores (`mocapviz.experiments.knn_timings`)")
    print()
    print(table_sets(set_rows))
    print()
    print("Slowdown: ms per query of the set / ms of F15E, same k, same run; the paper's from its Table 1 (CMU). "
          "Features s: computing the set for the whole database (`numeric_features`; Fp: projection with a PCA fitted on "
          "this database once, not counted).")  # fmt: skip
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("knn-quick.csv" if quick else "knn.csv")
    write_results_csv(csv_path, {
        "build": pd.DataFrame(build_rows).drop(columns=["runs_s"]),
        "queries": pd.DataFrame(query_rows).drop(columns=["runs_ms"]),
        "fat_graph": pd.DataFrame(fat_rows), "feature_sets": set_rows,
    }, info, ("cpu", "python", "numpy", "scipy", "commit"))  # fmt: skip
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
