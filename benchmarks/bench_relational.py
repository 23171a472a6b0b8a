"""Relational indexing and retrieval benchmarks (Müller, Röder & Clausen 2005, Tables 2 and 3) on the shared data.

The benchmark database: all four shared archives ingested at 120 Hz (``MotionDB.ingest(..., fps=120, threads=2)``;
Bandai Namco is 30 Hz and is upsampled, linear positions / slerp rotations). If it still held fewer than 1M frames
(an archive missing), left/right mirrored copies of the HDM05 / CMU documents (``mocapviz.motion.skeleton.mirror``) would
be added; the output says which. The database is cached under ``<repo>/.cache/bench/<tag>[-quick]/``
(``benchmarks.common.benchmark_db``) with the wall time of the ingest that built it, so reruns skip the build.

(a) Feature extraction (``mocapviz.features.relational_features(db)``, all 31 features) and index build
    (``mocapviz.relational.index.build(db, values=...)``: segmentation, inverted lists of the three groups, saved) in
    frames/s, beside the paper's Table 2 (1,288,846 frames, Matlab on a 3.6 GHz Pentium 4); index size in bytes
    per segment; Table 2 itself from :func:`mocapviz.experiments.index_statistics` beside ``mueller2005_table2()``.
(b) Exact, fuzzy (eq. 11), adaptive fuzzy (64 alternatives per set) and 1-mismatch queries, |Q| = 5, 10, 20
    segments, on the upper-body index (as the paper's Table 3 uses I_u): ``InvertedIndex.exact`` / ``fuzzy`` /
    ``adaptive_fuzzy`` / ``mismatch`` against a plain vectorised numpy scan of the feature sequence: one pass
    for the query's first segment (exact: ``codes == q[0]``; fuzzy: ``np.isin(codes, V_1, kind="table")``;
    mismatch: ``codes == q[0]`` or ``q[1]`` at the next position, pigeonhole), then every further query segment
    checked at the survivors only (adaptive fuzzy: the survivors' runs walked forward as in §5.2; mismatch:
    mismatches counted, survivors with more than m dropped). Index and scan must give identical hit sets on
    every timed query (asserted) before anything is timed.
(c) Table 3 (:func:`mocapviz.experiments.query_statistics`: random queries grouped by hit count) beside the
    paper's.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .common import (
    REPO,
    BenchDB,
    CpuMonitor,
    benchmark_db,
    describe_db,
    header,
    ingest_how,
    log,
    machine_info,
    markdown,
    write_results_csv,
)
from .common import fmt as _f

FPS = 120
MIN_FRAMES = 1_000_000
DATABASE = BenchDB("relational-v2", fps=FPS, min_frames=MIN_FRAMES, mirror_archives=("hdm05-cut", "cmu-asfamc"))
LENGTHS = (5, 10, 20)
FUZZY_SIZE = 64
MISMATCHES = 1  # m of the m-mismatch queries
N_TIMED = 1000  # queries per (mode, L) for (b); quick: N_TIMED_QUICK
N_TIMED_QUICK = 30
N_TABLE3 = 10_000  # queries per (mode, L) for (c), as the paper
N_TABLE3_QUICK = 200
TARGET_FPS = 1_000_000  # features + index build, frames/s
TARGET_MS = {"exact": 0.5, "fuzzy": 5.0}  # median query time
PAPER_FRAMES = 1_288_846
# Table 2, D^180: read once (71 s), then features and index build of each group (lower, upper, mix)
PAPER_T_READ = 71.0
PAPER_T_FEATURES = 26.0 + 33.0 + 54.0
PAPER_T_INDEX = 13.0 + 25.0 + 12.0


# ============================================================================ (b) numpy linear scans
def scan_exact(codes: np.ndarray, segment_doc: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Exact hits by a plain vectorised scan: the windows whose first segment has the query's first code, narrowed
    by each further query code at the survivors only; documents kept apart."""
    n = len(query)
    k = np.flatnonzero(codes[: codes.size - n + 1] == query[0])
    for l in range(1, n):
        k = k[codes[k + l] == query[l]]
    return k[segment_doc[k] == segment_doc[k + n - 1]]


def scan_fuzzy(codes: np.ndarray, segment_doc: np.ndarray, sets) -> np.ndarray:
    """Plain fuzzy hits (§5.2, eq. 11) by the same scan: the windows whose first segment lies in V_1 (``np.isin``
    over the sequence), narrowed by membership of segment k + l in V_l at the survivors only."""
    from mocapviz.relational.index import merge_adjacent

    sets = merge_adjacent(sets)
    n = len(sets)
    k = np.flatnonzero(np.isin(codes[: codes.size - n + 1], sets[0], kind="table"))
    for l in range(1, n):
        k = k[np.isin(codes[k + l], sets[l], kind="table")]
    return k[segment_doc[k] == segment_doc[k + n - 1]]


def scan_mismatch(codes: np.ndarray, segment_doc: np.ndarray, query: np.ndarray, mismatches: int) -> np.ndarray:
    """m-mismatch hits (§5.2) by the same scan: a window with at most m mismatches agrees with the query in one of
    its first m + 1 segments (pigeonhole), so the windows that do are the candidates (one vectorised pass per
    position); their mismatches are then counted query segment by query segment, dropping those with more than m."""
    n, m = len(query), codes.size - len(query) + 1
    near = codes[:m] == query[0]
    for a in range(1, mismatches + 1):
        near |= codes[a : a + m] == query[a]
    k = np.flatnonzero(near)
    missed = np.zeros(k.size, dtype=np.int64)
    for l in range(n):
        missed += codes[k + l] != query[l]
        keep = missed <= mismatches
        k, missed = k[keep], missed[keep]
    return k[segment_doc[k] == segment_doc[k + n - 1]]


def scan_adaptive_fuzzy(codes: np.ndarray, new_doc: np.ndarray, segment_doc: np.ndarray, sets) -> np.ndarray:
    """Adaptive fuzzy hits (§5.2) by the same scan: the run starts of V_1 (``np.isin`` over the sequence), then
    per set the survivors' runs walked forward a segment at a time, all survivors at once, and the survivors kept
    whose next run lies in the next set. ``new_doc``: (M + 1,) bool, segment p starts a document (True at M);
    ``codes``: (M + 1,), any code at M.

    Returns the same (H, J+1) array as :meth:`InvertedIndex.adaptive_fuzzy` (J = sets after merging).
    """
    from mocapviz.relational.index import merge_adjacent

    sets = merge_adjacent(sets)
    k = np.flatnonzero(np.isin(codes[:-1], sets[0], kind="table"))
    k = k[new_doc[k] | ~np.isin(codes[k - 1], sets[0], kind="table")]  # run starts (k = 0 starts a document)
    rows = []
    for j, s in enumerate(sets):
        if j:  # the run after the previous one must lie in V_j, in the same document
            keep = ~new_doc[k] & np.isin(codes[k], s, kind="table")
            rows, k = [r[keep] for r in rows], k[keep]
        rows.append(k)
        k = k + 1
        live = ~new_doc[k] & np.isin(codes[k], s, kind="table")
        while live.any():  # walk to the end of each run of V_j
            k[live] += 1
            live[live] = ~new_doc[k[live]] & np.isin(codes[k[live]], s, kind="table")
    rows.append(k)
    return np.stack(rows, axis=1)


def _same_hits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return False
    if a.ndim == 1:
        return np.array_equal(np.sort(a), np.sort(b))
    return np.array_equal(np.unique(a, axis=0), np.unique(b, axis=0))


def _time(fn, arg) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = fn(arg)
    return (time.perf_counter() - t0) * 1e3, out


# ============================================================================ the parts
def bench_build(db, record: dict, repeats: int) -> tuple[list[dict], np.ndarray, dict, pd.DataFrame]:
    """(a): features and index build, timed ``repeats`` times (median)."""
    from mocapviz.experiments import index_statistics
    from mocapviz.features import relational_features
    from mocapviz.relational.index import build

    relational_features(db.motion(int(db.documents["doc_id"].iloc[0])))  # numba: compile or load from the disk cache
    t_feat, t_build, cpu_feat = [], [], []
    for _ in range(repeats):
        log(f"features of {db.n_frames:,} frames")
        c0 = CpuMonitor._ours()
        t0 = time.perf_counter()
        values, _ = relational_features(db, "2005", progress=False)
        t_feat.append(time.perf_counter() - t0)
        cpu_feat.append(CpuMonitor._ours() - c0)
        log(f"  {t_feat[-1]:.2f} s; index build")
        t0 = time.perf_counter()
        indexes = build(db, "2005", progress=False, values=values)
        t_build.append(time.perf_counter() - t0)
        log(f"  {t_build[-1]:.2f} s")
    tf, tb = statistics.median(t_feat), statistics.median(t_build)
    n = db.n_frames
    paper_tf, paper_ti, paper_tr = PAPER_T_FEATURES, PAPER_T_INDEX, PAPER_T_READ
    rows = [
        {"step": f"read: MotionDB.ingest at {FPS} Hz, {ingest_how(record)} (paper: AMC read, t_r)",
         "s": record["t_ingest"], "paper_s": paper_tr, "target": ""},
        {"step": "features: relational_features(db), all 31 (paper: t_f of I_l + I_u + I_m)", "s": tf, "paper_s": paper_tf,
         "target": ""},
        {"step": "index build: build(db, values=...), 3 groups, saved (paper: t_i of the three)", "s": tb,
         "paper_s": paper_ti, "target": ""},
        {"step": "features + index build", "s": tf + tb, "paper_s": paper_tf + paper_ti,
         "target": f"≥ {TARGET_FPS:,} frames/s"},
    ]  # fmt: skip
    for r in rows:
        r["frames"] = n
        r["frames/s"] = n / r["s"]
        r["paper_frames/s"] = PAPER_FRAMES / r["paper_s"]
        r["speed-up"] = r["frames/s"] / r["paper_frames/s"]
        r["meets"] = ("yes" if r["frames/s"] >= TARGET_FPS else "NO") if r["target"] else ""
    rows[1]["runs_s"] = t_feat
    rows[2]["runs_s"] = t_build
    rows[1]["frames/CPU-s"] = n / statistics.median(cpu_feat)
    table2 = index_statistics(db, "2005", values=values, t_read=record["t_ingest"], t_features=tf)
    return rows, values, indexes, table2


def bench_queries(index, quick: bool, seed: int = 1) -> tuple[list[dict], list[str]]:
    """(b): per query mode and L, the same random queries through the index and the numpy scan."""
    from mocapviz.experiments.relational import mueller2005_table3, random_queries

    n_timed = N_TIMED_QUICK if quick else N_TIMED
    codes, seg_doc = index.codes, index.segment_doc
    new_doc = np.ones(codes.size + 1, dtype=bool)  # segment p starts a document; one past the end for the walk
    new_doc[1:-1] = seg_doc[1:] != seg_doc[:-1]
    codes_end = np.append(codes, 0)
    paper = mueller2005_table3()
    # name: (kind of random query, index method, numpy scan, target median ms or None, the paper's Table 3 mode)
    modes = {
        "exact": ("exact", index.exact, lambda q: scan_exact(codes, seg_doc, q), TARGET_MS["exact"], "exact"),
        f"fuzzy (eq. 11), {FUZZY_SIZE} per set": ("fuzzy", index.fuzzy, lambda q: scan_fuzzy(codes, seg_doc, q),
                                                  TARGET_MS["fuzzy"], "fuzzy"),
        f"adaptive fuzzy, {FUZZY_SIZE} per set": (
            "fuzzy", index.adaptive_fuzzy, lambda q: scan_adaptive_fuzzy(codes_end, new_doc, seg_doc, q),
            TARGET_MS["fuzzy"], "fuzzy"),
        f"{MISMATCHES}-mismatch": ("exact", lambda q: index.mismatch(q, MISMATCHES),
                                   lambda q: scan_mismatch(codes, seg_doc, q, MISMATCHES), None, None),
    }  # fmt: skip
    rng = np.random.default_rng(seed)
    rows, notes = [], []
    for name, (kind, ours_fn, scan_fn, target, paper_mode) in modes.items():
        for length in LENGTHS:
            queries = [q for _, q in random_queries(index, n_timed, length, kind, FUZZY_SIZE, rng)]
            bad = sum(not _same_hits(ours_fn(q), scan_fn(q)) for q in queries)
            assert not bad, f"{name} |Q|={length}: index and scan give different hits on {bad} queries"
            ours_fn(queries[0]), scan_fn(queries[0])  # warm-up
            # each method over all queries in a block (as a user's session of queries runs, caches warm), the
            # blocks alternated twice so that both see the same machine state; per query the faster of two runs
            hits = [len(ours_fn(q)) for q in queries]
            rounds = [([_time(ours_fn, q)[0] for q in queries], [_time(scan_fn, q)[0] for q in queries])
                      for _ in range(2)]  # fmt: skip
            ours = np.minimum(rounds[0][0], rounds[1][0])
            scan = np.minimum(rounds[0][1], rounds[1][1])
            pt = paper[(paper["mode"] == paper_mode) & (paper["L"] == length)]["mean_ms"]
            med, scan_med = float(np.median(ours)), float(np.median(scan))
            speedup = scan_med / med
            ok = target is None or med <= target  # the speed-up over the fair scan is reported, not targeted
            rows.append({
                "mode": name, "L": length, "queries": len(queries), "median_hits": float(np.median(hits)),
                "ours_median_ms": med, "ours_p90_ms": float(np.percentile(ours, 90)),
                "scan_median_ms": scan_med, "scan_p90_ms": float(np.percentile(scan, 90)),
                "speed-up": speedup, "paper_mean_ms": f"{pt.min():.0f}–{pt.max():.0f}" if len(pt) else "—",
                "target": f"median ≤ {target:g} ms" if target else "—",
                "meets": "yes" if ok else "NO", "checked": len(queries), "differ": bad,
            })  # fmt: skip
            log(f"{name} L={length}: ours {med:.3f} ms, scan {scan_med:.3f} ms")
        notes.append(f"{name}: hit sets of index and scan identical on all {len(queries):,} queries of each |Q|")
    return rows, notes


def bench_table3(index, quick: bool) -> pd.DataFrame:
    """(c): Table 3 of ours beside the paper's."""
    from mocapviz.experiments import query_statistics
    from mocapviz.experiments.relational import mueller2005_table3

    n = N_TABLE3_QUICK if quick else N_TABLE3
    log(f"Table 3: {n:,} queries per cell")
    ours = query_statistics(index, n_queries=n, lengths=LENGTHS, modes=("exact", "fuzzy"), fuzzy_size=FUZZY_SIZE)
    paper = mueller2005_table3()
    return ours.merge(paper[["mode", "L", "hits", "mean_hits", "std_hits", "mean_ms"]], on=["mode", "L", "hits"],
                      suffixes=("", "_paper"))  # fmt: skip


# ============================================================================ output
def _header(info: dict, quick: bool, repeats: int) -> str:
    return header(
        "# mocapviz relational indexing benchmarks (Müller, Röder & Clausen 2005, Tables 2–3)"
        + (" (--quick: small database)" if quick else ""),
        info, ("numpy", "numba"),
        [f"features / index build: median of {repeats} runs; queries: single-threaded, each timed alone",
         "paper: Matlab on a 3.6 GHz Pentium 4, 1 GB RAM; D^180 = 1,288,846 frames at 120 Hz"],
    )  # fmt: skip


def table_build(rows: list[dict]) -> str:
    return markdown(
        "| step | frames | ours s | ours frames/s | paper s | paper frames/s | ours/paper | target | meets |",
        "|---|---:|---:|---:|---:|---:|---:|---|---|",
        ([r["step"], f"{r['frames']:,}", _f(r["s"]), _f(r["frames/s"]), _f(r["paper_s"], 0),
          _f(r["paper_frames/s"]), f"{r['speed-up']:.0f}×", r["target"], r["meets"]] for r in rows),
    )  # fmt: skip


def table_sizes(ours: pd.DataFrame, paper: pd.DataFrame) -> str:
    p180 = paper[paper["minutes"] == 180].set_index("group")
    lines = []
    for r in ours.to_dict("records"):
        p = p180.loc[r["group"]]
        pair = [("lists", "{:,}", "{:,}"), ("frames", "{:,}", "{:,}"), ("segments", "{:,}", "{:,}"),
                ("MB", "{:.2f}", "{:.2f}"), ("bytes/segment", "{:.1f}", "{:.1f}"), ("t_read", "{:.1f}", "{:.0f}"),
                ("t_features", "{:.2f}", "{:.0f}"), ("t_index", "{:.3f}", "{:.0f}"), ("t_total", "{:.1f}", "{:.0f}")]
        cells = {k: f"{a.format(r[k])} / {b.format(p[k])}" for k, a, b in pair}
        density = f"{r['segments'] / r['frames']:.3f} / {p['segments'] / p['frames']:.3f}"
        lines.append([r["index"], str(r["f"]), cells["lists"], cells["frames"], cells["segments"], density,
                      cells["MB"], cells["bytes/segment"], cells["t_read"], cells["t_features"], cells["t_index"],
                      cells["t_total"]])  # fmt: skip
    return markdown(
        "| index (ours / paper I^180) | f | lists | frames | segments | segments per frame | MB | bytes/segment "
        "| t_read s | t_features s | t_index s | total s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        lines,
    )


def table_queries(rows: list[dict]) -> str:
    return markdown(
        "| query | |Q| | queries | median hits | ours median ms | ours p90 ms | scan median ms | scan p90 ms "
        "| speed-up vs scan | paper µt ms (by hit group) | target | meets |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|",
        ([r["mode"], str(r["L"]), f"{r['queries']:,}", _f(r["median_hits"], 0), _f(r["ours_median_ms"], 3),
          _f(r["ours_p90_ms"], 3), _f(r["scan_median_ms"], 3), _f(r["scan_p90_ms"], 3), f"{r['speed-up']:.1f}×",
          r["paper_mean_ms"], r["target"], r["meets"]] for r in rows),
    )  # fmt: skip


def table_t3(t3: pd.DataFrame) -> str:
    return markdown(
        "| mode | |Q| | hits | queries | µh ours | µh paper | σh ours | σh paper | µt ms ours | µt ms paper "
        "| median ms ours | p90 ms ours | paper µt / ours |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ([r["mode"], str(r["L"]), r["hits"], f"{r['queries']:,}", _f(r["mean_hits"], 1), _f(r["mean_hits_paper"], 1),
          _f(r["std_hits"], 1), _f(r["std_hits_paper"], 1), _f(r["mean_ms"], 3), _f(r["mean_ms_paper"], 0),
          _f(r["median_ms"], 3), _f(r["p90_ms"], 3),
          "—" if not r["queries"] else f"{r['mean_ms_paper'] / r['mean_ms']:.0f}×"] for r in t3.to_dict("records")),
    )  # fmt: skip


# ============================================================================ main
def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    db, record = benchmark_db(DATABASE, quick)
    build_rows, _, indexes, table2 = bench_build(db, record, repeats)
    upper = indexes["upper"]
    query_rows, query_notes = bench_queries(upper, quick)
    t3 = bench_table3(upper, quick)
    info["others"] = monitor.report()

    from mocapviz.experiments.relational import mueller2005_table2

    print(_header(info, quick, repeats))
    for line in describe_db(db, record):
        print(f"- {line}")
    print()
    print("## (a) Feature extraction and index build (Table 2; frames/s, higher is better)")
    print()
    print(table_build(build_rows))
    print()
    feat = build_rows[1]
    print(f"Feature runs (s): {', '.join(f'{t:.2f}' for t in feat['runs_s'])}; frames per CPU-second "
          f"{feat['frames/CPU-s']:,.0f}. Index build runs (s): "
          f"{', '.join(f'{t:.2f}' for t in build_rows[2]['runs_s'])}. The paper read the data once per index; "
          "its t_r (71 s) is counted once here.")  # fmt: skip
    print()
    print("### Table 2: ours / paper (I^180), `index_statistics` beside `mueller2005_table2`")
    print()
    print(table_sizes(table2, mueller2005_table2()))
    print()
    print(
        "MB = bytes / 2^20 (the paper's unit: 4.33 MB / 135,742 segments = 33.4 bytes). Ours: sorted int32 segment "
        "positions + int32 start frame and length per segment + the list directory and document boundaries. "
        "t_features: all 31 features in one pass (the same figure on each row; the paper computed each group on "
        "its own); t_index: segmentation + inverted lists in memory, without saving."
    )
    print()
    print(f"## (b) Query times on the upper-body index I_u ({upper.n_segments:,} segments, "
          f"{upper.list_codes.size:,} lists), index vs numpy linear scan")  # fmt: skip
    print()
    print(table_queries(query_rows))
    print()
    print(
        "Scan (no index, vectorised numpy over the code sequence, each query segment checked only where all "
        "before it matched): exact = `flatnonzero(codes == q[0])`, then `codes[k + l] == q[l]` at the survivors; "
        "fuzzy = the same with `np.isin(..., V_l, kind='table')` per (merged) set; adaptive fuzzy = the run starts "
        "of V_1, then the survivors' runs walked forward a segment at a time and kept if the next run lies in the "
        "next set (§5.2); m-mismatch = the windows agreeing with the query in one of its first m + 1 segments (m + 1 "
        "vectorised passes: by pigeonhole every hit is among them), then mismatches counted at the survivors, "
        "segment by segment, dropping those with more than m. Same queries through both: each method "
        "over all queries in a block, blocks alternated twice, per query the faster run; random queries of "
        "segments that occur, each with ≥ 1 hit (mismatch: the same exact queries, m = 1). Paper µt: Table 3's "
        "mean time per hit-count group (min–max over its three groups; its fuzzy rows beside both fuzzy modes)."
    )
    for n in query_notes:
        print(f"- {n}")
    print()
    print("## (c) Table 3: random queries on I_u, grouped by hit count h (ours beside the paper)")
    print()
    print(table_t3(t3))
    print()
    n3 = N_TABLE3_QUICK if quick else N_TABLE3
    print(f"{n3:,} queries per (mode, |Q|) (paper: 10,000); fuzzy = adaptive fuzzy with {FUZZY_SIZE} alternatives "
          "per set (the query segment's own code + 63 random codes of the 2^12, none of them in the previous set "
          "or equal to the next segment's code, so that adjacent sets are disjoint as §5.2 requires; "
          "`random_queries(alternatives='disjoint')`). σh: sample standard deviation.")  # fmt: skip
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("relational-quick.csv" if quick else "relational.csv")
    write_results_csv(csv_path, {
        "build": pd.DataFrame(build_rows).drop(columns=["runs_s"], errors="ignore"), "table2": table2,
        "queries": pd.DataFrame(query_rows), "table3": t3,
    }, info, ("cpu", "python", "numpy", "numba", "commit"))  # fmt: skip
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
