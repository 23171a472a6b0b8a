"""Cost growth: build and query times on databases of 250k, 1M and 4M frames at 30 Hz, with the fitted exponent.

The databases. The largest (``DATABASE``, tag ``scaling-v1``): the four shared archives ingested at 30 Hz (about
446k real frames), then derived documents appended (``benchmarks.common.add_variants``) until 4M frames: a
left/right MIRRORED copy of every document, then TIME-STRETCHED copies of the originals and of their mirror images
(resampled to s x 30 Hz and relabelled 30 Hz: the motion performed s times slower, s = 1.1, 1.2, 1.3, ... in turn;
new interpolated frames, none repeated verbatim). The smaller ones are nested: the documents of the largest in a
fixed random order (seed 0), the shortest prefix holding at least 250k / 1M frames, copied into a database of their
own (``MotionDB.create`` + ``append_motions``), so every size has the same mix of real, mirrored and stretched
frames. All are cached under ``<repo>/.cache/bench/scaling-v1[-quick]/``.

Per size (each step timed ``repeats`` times, median; the LNG and query steps over many queries, median per query):

- relational features (``mocapviz.features.relational_features(db)``, 31 features) + index build
  (``mocapviz.relational.index.build(db, values=...)``): seconds;
- F15E features (``mocapviz.features.numeric_features(db, "F15E")``) + kd-tree build (``mocapviz.similarity.knn.KnnIndex``): seconds;
- exact 16-NN: a batch of 1000 random database frames, ``KnnIndex.query(q, 16)``, all threads: ms per query;
- exact relational query: 300 random |Q| = 10 queries on the upper-body index (``random_queries``,
  ``InvertedIndex.exact``): median ms per query, and the median hit count (which grows with the database);
- LNG: 1 s queries (30 frames) from real documents, ``mocapviz.match.lng(q, KnnIndex, k=256, n_matches=10,
  exclude=own document)``: median s per query.

The exponent b of time ~ frames^b is the least-squares slope of log(time) on log(frames) over the sizes. The
papers' claims beside: relational features + index build linear (b = 1, Müller, Röder & Clausen 2005 §5); kd-tree
build O(n log n) (b ≈ 1); kNN query O(log n) (b ≈ 0); LNG O(k m log n) for fixed k, m (b ≈ 0, Krüger et al. 2010
§4.1); exact relational queries: proportional to the inverted-list lengths merged (b ≈ 1 when the lists grow with
the data, as here), no sublinear claim in the paper.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
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
    log,
    machine_info,
    markdown,
    write_results_csv,
)
from .common import fmt as _f

FPS = 30
SIZES = (250_000, 1_000_000, 4_000_000)
SIZES_QUICK = (20_000, 40_000, 80_000)
STRETCHES = tuple(round(1 + 0.1 * i, 1) for i in range(1, 11))
DATABASE = BenchDB(
    "scaling-v1", fps=FPS, min_frames=max(SIZES), stretches=STRETCHES, quick_min_frames=max(SIZES_QUICK),
    quick_files={"hdm05-cut": 40, "cmu-asfamc": 4, "bandai-namco-1": 10, "bandai-namco-2": 100},
)  # fmt: skip
N_KNN = 1000
K_KNN = 16
N_REL = 300
REL_LENGTH = 10
N_LNG = 40
N_LNG_QUICK = 4
K_LNG = 256
SEED = 0
# step: (the papers' exponent, what it says)
CLAIMS = {
    "relational features + index build": (1.0, "linear (Müller et al. 2005)"),
    "F15E features + kd-tree build": (1.0, "O(n log n) kd-tree, ≈ linear"),
    "exact 16-NN query": (0.0, "O(log n) (kd-tree, Krüger et al. 2010)"),
    "exact relational query, 10 segments": (None, "∝ inverted-list lengths; no sublinear claim"),
    "LNG, 1 s query, k = 256": (0.0, "O(k m log n) (Krüger et al. 2010 §4.1)"),
}


def subset_db(db, n: int, folder: Path):
    """The cached database of the shortest prefix of ``db``'s documents in a fixed random order holding >= n frames."""
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
    docs = db.documents.iloc[np.random.default_rng(SEED).permutation(len(db))]
    take = docs.iloc[: int(np.searchsorted(np.cumsum(docs["n_frames"].to_numpy()), n)) + 1]
    log(f"subset of {n:,} frames: {len(take):,} documents -> {folder}")
    sub = MotionDB.create(folder / "db.tmp")
    cols = ["name", "path", "format", "source_fps", "sha256", "mirror_of", "variant"]
    motions, metas, frames = [], [], 0
    for row in take.to_dict("records"):
        motions.append(db.motion(int(row["doc_id"])))
        metas.append({c: row[c] for c in cols if c in row and not (isinstance(row[c], float) and np.isnan(row[c]))})
        frames += motions[-1].n_frames
        if frames >= 500_000:
            sub = sub.append_motions(motions, metas)
            motions, metas, frames = [], [], 0
    if motions:
        sub = sub.append_motions(motions, metas)
    (folder / "db.tmp").rename(folder / "db")
    sub = MotionDB.open(folder / "db")
    record_file.write_text(json.dumps({"n_frames": sub.n_frames, "documents": len(sub), "of": str(db.path)}))
    return sub


def _median_runs(fn, repeats: int) -> tuple[float, list[float], object]:
    times, out = [], None
    for _ in range(repeats):
        out = None
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def measure(db, quick: bool, repeats: int) -> dict:
    """Every step's time on one database."""
    from mocapviz.experiments.relational import random_queries
    from mocapviz.features import numeric_features, relational_features
    from mocapviz.match import lng
    from mocapviz.relational.index import build
    from mocapviz.similarity.knn import KnnIndex

    from .bench_match import pick_queries

    n = db.n_frames
    out = {"frames": n, "documents": len(db)}
    rng = np.random.default_rng(SEED)

    def rel_build():
        values, _ = relational_features(db, "2005", progress=False)
        return build(db, "2005", progress=False, values=values)

    relational_features(db.motion(int(db.documents["doc_id"].iloc[0])))  # numba: compile or load from the disk cache
    log(f"{n:,} frames: relational features + index build")
    out["relational features + index build"], runs, indexes = _median_runs(rel_build, repeats)
    out["relational_runs"] = runs
    upper = indexes["upper"]
    del indexes

    log(f"{n:,} frames: F15E + kd-tree")
    holder = {}

    def knn_build():
        holder["features"] = None
        holder["features"] = numeric_features(db, "F15E", progress=False)
        return KnnIndex(holder["features"])

    out["F15E features + kd-tree build"], runs, index = _median_runs(knn_build, repeats)
    out["knn_build_runs"] = runs
    features = holder["features"]

    queries = np.asarray(features[rng.integers(0, n, N_KNN)], dtype=np.float64)
    index.query(queries[:10], K_KNN)  # warm-up
    t, runs, _ = _median_runs(lambda: index.query(queries, K_KNN), repeats)
    out["exact 16-NN query"] = t / N_KNN
    out["knn_runs_s"] = runs

    log(f"{n:,} frames: relational queries")
    rel = [q for _, q in random_queries(upper, N_REL if not quick else 50, REL_LENGTH, "exact", 64, rng)]
    upper.exact(rel[0])
    per_q, hits = [], []
    for q in rel:
        best = np.inf
        for _ in range(max(2, min(repeats, 3))):
            t0 = time.perf_counter()
            h = upper.exact(q)
            best = min(best, time.perf_counter() - t0)
        per_q.append(best)
        hits.append(len(h))
    out["exact relational query, 10 segments"] = float(np.median(per_q))
    out["relational_median_hits"] = float(np.median(hits))

    log(f"{n:,} frames: LNG")
    starts = db.documents["start"].to_numpy()
    lng(np.asarray(features[:30], dtype=np.float64), index, k=8, starts=starts)  # numba: load the compiled code
    walls, knn_s = [], []
    for query in pick_queries(db, FPS, N_LNG_QUICK if quick else N_LNG, rng):
        q = np.asarray(features[query["first"] : query["first"] + query["m"]], dtype=np.float64)
        own = np.array([query["doc_start"], query["doc_stop"]])
        best, best_knn = np.inf, np.inf
        for _ in range(max(1, min(repeats, 2))):
            t0 = time.perf_counter()
            res = lng(q, index, k=K_LNG, radius=None, n_matches=10, starts=starts, exclude=own)
            wall = time.perf_counter() - t0
            if wall < best:
                best, best_knn = wall, res.attrs["seconds"]["knn"]
        walls.append(best)
        knn_s.append(best_knn)
    out["LNG, 1 s query, k = 256"] = float(np.median(walls))
    out["lng_knn_s"] = float(np.median(knn_s))
    return out


def exponent(frames, times) -> float | None:
    frames, times = np.asarray(frames, float), np.asarray(times, float)
    ok = np.isfinite(times) & (times > 0)
    if ok.sum() < 2:
        return None
    return float(np.polyfit(np.log(frames[ok]), np.log(times[ok]), 1)[0])


UNITS = {"relational features + index build": ("s", 1.0), "F15E features + kd-tree build": ("s", 1.0),
         "exact 16-NN query": ("ms", 1e3), "exact relational query, 10 segments": ("ms", 1e3),
         "LNG, 1 s query, k = 256": ("s", 1.0)}  # fmt: skip


def table(rows: list[dict]) -> tuple[str, pd.DataFrame]:
    frames = [r["frames"] for r in rows]
    header = ("| step | " + " | ".join(f"{n:,} frames" for n in frames)
              + " | fitted exponent b | paper's exponent | paper's claim | b − paper |")  # fmt: skip
    align = "|---|" + "---:|" * len(rows) + "---:|---:|---|---:|"
    lines, records = [], []
    for step, (claim_b, claim) in CLAIMS.items():
        unit, scale = UNITS[step]
        times = [r[step] for r in rows]
        b = exponent(frames, times)
        diff = None if b is None or claim_b is None else b - claim_b
        lines.append([f"{step} ({unit})"] + [_f(t * scale, 3) for t in times]
                     + [_f(b, 2), "—" if claim_b is None else f"{claim_b:g}", claim, _f(diff, 2)])  # fmt: skip
        records.append({"step": step, "unit": unit, **{f"t_{n}": t * scale for n, t in zip(frames, times)},
                        "exponent": b, "paper_exponent": claim_b, "paper_claim": claim})  # fmt: skip
    return markdown(header, align, lines), pd.DataFrame(records)


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    sizes = SIZES_QUICK if quick else SIZES
    big, record = benchmark_db(DATABASE, quick)
    folder = REPO / ".cache" / "bench" / (DATABASE.tag + ("-quick" if quick else ""))
    rows = []
    for n in sizes:
        # the largest size is the whole database (it holds just over max(sizes) frames)
        db = big if n >= max(sizes) or n >= big.n_frames else subset_db(big, n, folder / f"subset-{n}")
        with PeakRSS() as mem:
            row = measure(db, quick, repeats)
        rows.append(row | {"nominal": n, "peak_rss_MB": mem.mb})
        log(f"{n:,}: " + ", ".join(f"{k} {v:.4g}" for k, v in rows[-1].items() if isinstance(v, float)))
    info["others"] = monitor.report()
    text, df = table(rows)

    print(f"# Cost growth: build and query time against database size ({'QUICK run' if quick else 'full run'})")
    print()
    print(f"- machine: {info['cpu']}, {info['usable_cores']} usable cores, {info['ram_gib']} GiB RAM; Python "
          f"{info['python']}, numpy {info['numpy']}, numba {info['numba']}, scipy {info['scipy']}; commit "
          f"{info['commit']}")  # fmt: skip
    print(f"- each step: median of {repeats} runs (queries: median over the queries of the best of 2–3 runs each)")
    for line in describe_db(big, record):
        print(f"- {line}")
    print("- smaller sizes: nested prefixes of the largest database's documents in a fixed random order (seed 0), "
          "copied into databases of their own, so every size has the same mix of real / mirrored / stretched frames")
    print(f"- {info['others']}")
    print()
    print("## Time per size and fitted exponent (time ∝ frames^b)")
    print()
    print(text)
    print()
    print(f"Queries: 16-NN: a batch of {N_KNN} random database frames, exact, all threads, ms per query; relational: "
          f"{N_REL if not quick else 50} random exact queries of |Q| = {REL_LENGTH} segments on the upper-body index "
          "(each with ≥ 1 hit), median ms; LNG: "
          f"{N_LNG_QUICK if quick else N_LNG} random 1 s stretches of real documents, own document excluded, k = "
          f"{K_LNG}, 10 matches, median s. b: least-squares slope of log time on log frames. Median hits of the "
          "relational queries per size: " + ", ".join(f"{r['relational_median_hits']:g}" for r in rows)
          + "; LNG's kNN part (s): " + ", ".join(f"{r['lng_knn_s']:.3f}" for r in rows)
          + "; peak memory while measuring each size (MB: largest RSS of this process and its children, sampled "
          "every 50 ms with psutil; includes the memory-mapped database pages touched): "
          + ", ".join(f"{r['peak_rss_MB']:,.0f}" for r in rows))  # fmt: skip
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("scaling-quick.csv" if quick else "scaling.csv")
    per_size = pd.DataFrame([{k: (json.dumps(v) if isinstance(v, list) else v) for k, v in r.items()} for r in rows])
    write_results_csv(csv_path, {"exponents": df, "sizes": per_size}, info)
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    sys.exit(main(quick=quick, repeats=1 if quick else 3))
