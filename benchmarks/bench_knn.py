"""kNN benchmark (Krüger, Tautges, Weber & Zinke 2010, Table 1 and §5.3) on F15E features of >= 1M frames.

(a) Build time and memory of the search structures: ``mocapviz.knn.KnnIndex`` (scipy cKDTree), the brute-force
    engine (a float64 copy), and pykdtree (PyPI, OpenMP kd-tree, float32) when it is installed.
(b) 16-NN and 256-NN per query, exact, batched queries over all cores: ours against numpy brute force
    (``KnnIndex(engine="brute")``: scipy ``cdist`` + ``argpartition``, chunked, threads; on a sample of the
    queries) and against pykdtree, the fastest other engine found (faiss-cpu has no exact search faster than
    its flat index, which is brute force with BLAS). Ours single-threaded and eps = 0.5 beside them. Before
    timing, ours and brute force must agree on the sampled queries (up to exact ties). Queries: random
    database frames. Each figure: median of ``repeats`` runs of the whole batch; the engines alternate
    within a repeat so that they see the same machine state. CPU ms/query (process time of all threads per
    query) is printed too: it is less disturbed by other processes than wall time.
(c) Fat-graph base poses (§5.3): ``base_poses`` against ``base_poses_quadratic`` on evenly spaced subsets of
    the real frames (identical results required), and ``base_poses`` on the whole database.

The benchmark database: all four shared archives ingested at 30 Hz (``MotionDB.ingest(..., fps=30, n_jobs=2)``),
about 446k frames. The paper's scale (1-1.3M frames) is reached by appending left/right MIRRORED copies
(``mocapviz.skeleton.mirror``) of the documents, archive by archive, until the database holds 1M frames; when
every document has been mirrored once (about 892k frames) the next round repeats mirrored copies, i.e. exact
duplicates of frames already present. The output says how many frames of each kind there are. The database
is cached under ``<repo>/.cache/bench/<VERSION>[-quick]/`` with the wall time of the ingest that built it.
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

from .bench_io import CpuMonitor, _fetch, _loadavg, _log, _markdown, machine_info

REPO = Path(__file__).resolve().parent.parent
VERSION = "knn-v1"  # bump to rebuild the cached benchmark database
ARCHIVES = ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2")
FPS = 30
N_JOBS = 2
MIN_FRAMES = 1_000_000
QUICK_FILES = {"hdm05-cut": 40, "cmu-asfamc": 4, "bandai-namco-1": 10, "bandai-namco-2": 0}
END_EFFECTORS = ("lwrist", "rwrist", "lankle", "rankle", "head")
KS = (16, 256)
N_QUERIES = {16: 20_000, 256: 5_000}  # batch per figure; quick: N_QUERIES_QUICK
N_QUERIES_QUICK = {16: 2_000, 256: 500}
N_BRUTE = 200  # queries timed (and checked) with brute force; quick: N_BRUTE_QUICK
N_BRUTE_QUICK = 50
EPS = 0.5  # the approximation the paper found harmless for reconstruction (§5.2)
TARGET_MS = {16: 0.1, 256: 1.0}
TARGET_SPEEDUP = 50.0
# Table 1, F15E, ms per query: HDM05 (380,813 frames) and CMU (1,038,388 frames) at 30 Hz, ANN library, 2010 PC
PAPER_MS = {16: (1.11, 1.65), 256: (4.53, 7.36)}
FAT_RADIUS = 10.0  # cm, F15E
FAT_K = 32
FAT_SIZES = (2_000, 5_000, 10_000)
FAT_SIZES_QUICK = (1_000, 2_000)


# ============================================================================ the benchmark database
def _cache_dir(quick: bool) -> Path:
    return REPO / ".cache" / "bench" / (VERSION + ("-quick" if quick else ""))


def _source_files(quick: bool) -> tuple[dict, list[str]]:
    """{archive: [files]} of the archives that could be fetched, and notes on the ones that could not."""
    from mocapviz.database import expand_paths

    files, notes = {}, []
    for name in ARCHIVES:
        if quick and not QUICK_FILES[name]:
            continue
        root, err = _fetch(name)
        if root is None:
            notes.append(f"{name} missing ({err})")
            continue
        found = expand_paths(root)
        if quick:
            found = found[:: max(1, len(found) // QUICK_FILES[name])][: QUICK_FILES[name]]
        files[name] = [str(f) for f in found]
    return files, notes


def _add_mirrored(db, archive_of: dict, need: int) -> dict:
    """Append mirrored copies of the documents (archive by archive, in database order) until ``need`` frames.

    The first round mirrors each document once; later rounds (if needed) repeat the mirrored copies. MotionDB
    has no public way to add in-memory Motions (ingest reads files), so this goes through its private commit,
    under its writer lock, as ``MotionDB.append`` does. Returns {"documents", "frames", "repeated_frames"}.
    """
    from mocapviz import database
    from mocapviz.skeleton import mirror

    docs = db.documents
    positions, quaternions, metas, frames, repeated = [], [], [], db.n_frames, 0
    for round_ in range(1, 1 + -(-need // max(1, db.n_frames))):
        for row in docs.itertuples():
            if frames >= need:
                break
            m = mirror(db.motion(int(row.doc_id)))
            positions.append(m.positions)
            quaternions.append(m.quaternions)
            metas.append({"name": f"{row.name}_mirror{round_}", "path": row.path, "format": row.format,
                          "n_frames": m.n_frames, "fps": m.fps, "source_fps": row.source_fps,
                          "sha256": f"mirror{round_}-{row.sha256}", "label": row.label,
                          "archive": archive_of.get(row.path, "?"), "mirrored": True})  # fmt: skip
            frames += m.n_frames
            repeated += m.n_frames if round_ > 1 else 0
    if metas:
        with database._locked(db.path):
            database._commit(db.path, database._read_manifest(db.path), positions, quaternions, metas)
    return {"documents": len(metas), "frames": frames - db.n_frames, "repeated_frames": repeated}


def benchmark_db(quick: bool):
    """The cached benchmark MotionDB and its build record (ingest seconds, sources, mirrored copies)."""
    from mocapviz.database import MotionDB
    from mocapviz.errors import MotionDBError

    folder = _cache_dir(quick)
    record_file = folder / "build.json"
    if record_file.is_file():
        try:
            db = MotionDB.open(folder / "db")
            record = json.loads(record_file.read_text())
            if record.get("n_frames") == db.n_frames:
                record["cached"] = True
                return db, record
        except (MotionDBError, ValueError, OSError) as exc:
            _log(f"cached benchmark database unusable ({exc}); rebuilding")
    files, missing = _source_files(quick)
    if not files:
        raise RuntimeError("no shared archive could be fetched: " + "; ".join(missing))
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f"db.tmp-{os.getpid()}"
    for old in folder.glob("db.tmp-*"):  # left by an interrupted build of this benchmark
        shutil.rmtree(old)
    all_files = [f for fs in files.values() for f in fs]
    _log(f"building the benchmark database: {len(all_files)} files at {FPS} Hz, n_jobs={N_JOBS} -> {folder / 'db'}")
    t0 = time.perf_counter()
    db = MotionDB.ingest(all_files, tmp, fps=FPS, n_jobs=N_JOBS, progress=False)
    t_ingest = time.perf_counter() - t0
    _log(f"  ingest {t_ingest:.1f} s, {db.n_frames:,} frames")
    real_frames = db.n_frames
    mirrored = {"documents": 0, "frames": 0, "repeated_frames": 0}
    if db.n_frames < MIN_FRAMES and not quick:
        archive_of = {str(Path(f).resolve()): name for name, fs in files.items() for f in fs}
        mirrored = _add_mirrored(db, archive_of, MIN_FRAMES)
        _log(f"  added {mirrored['documents']} mirrored documents, {mirrored['frames']:,} frames")
    if (folder / "db").exists():
        shutil.rmtree(folder / "db")
    tmp.rename(folder / "db")
    db = MotionDB.open(folder / "db")
    record = {
        "version": VERSION,
        "t_ingest": t_ingest,
        "n_jobs": N_JOBS,
        "fps": FPS,
        "files": {k: len(v) for k, v in files.items()},
        "missing": missing,
        "real_frames": real_frames,
        "mirrored_documents": mirrored["documents"],
        "mirrored_frames": mirrored["frames"],
        "repeated_frames": mirrored["repeated_frames"],
        "n_frames": db.n_frames,
        "n_documents": len(db),
        "built": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
    record_file.write_text(json.dumps(record, indent=2))
    record["cached"] = False
    return db, record


def describe_db(db, record: dict) -> list[str]:
    """Lines saying what the benchmark database holds: real frames per archive, mirrored and repeated copies."""
    docs = db.documents
    mirrored = docs["name"].str.contains("_mirror", regex=False)
    parts = []
    for name in record["files"]:
        root, _ = _fetch(name)
        sel = ~mirrored & docs["path"].str.startswith(str(Path(root).resolve()))
        parts.append(f"{name} {int(sel.sum())} documents, {int(docs.loc[sel, 'n_frames'].sum()):,} frames")
    lines = [f"benchmark database: {len(db):,} documents, {db.n_frames:,} frames at {FPS} Hz "
             f"({db.n_frames / FPS / 3600:.1f} h); real: {record['real_frames']:,} frames — " + "; ".join(parts)]
    if record["mirrored_documents"]:
        lines.append(
            f"**{record['mirrored_documents']:,} left/right MIRRORED copies** of real documents "
            f"({record['mirrored_frames']:,} frames, `mocapviz.skeleton.mirror`) were appended to reach "
            f"{MIN_FRAMES:,} frames; of these, **{record['repeated_frames']:,} frames repeat a mirrored copy** "
            "(second round: exact duplicates of frames already in the database)"
        )
    elif db.n_frames < MIN_FRAMES:
        lines.append("quick run: a small database, far from the paper's scale; no mirrored copies")
    if record["missing"]:
        lines.append("missing archives: " + "; ".join(record["missing"]))
    cached = " (database from the cache; measured when it was built)" if record["cached"] else ""
    lines.append(f"MotionDB.ingest of the {sum(record['files'].values())} source files at {FPS} Hz, "
                 f"n_jobs={record['n_jobs']}: {record['t_ingest']:.1f} s{cached}")  # fmt: skip
    return lines


# ============================================================================ features
def f15e_from_skeleton(db, chunk: int = 1 << 17) -> np.ndarray:
    """F15E of every frame (Krüger et al. 2010 §3.2): body-frame positions of lwrist, rwrist, lankle, rankle and
    head, (N, 15) float32, cm. A stand-in until ``mocapviz.features.numeric.numeric(db, "F15E")`` lands."""
    from mocapviz.skeleton import CANONICAL_JOINTS, body_frame

    joints = [CANONICAL_JOINTS.index(j) for j in END_EFFECTORS]
    out = np.empty((db.n_frames, 3 * len(joints)), dtype=np.float32)
    for s in range(0, db.n_frames, chunk):
        pose = body_frame(np.asarray(db.positions[s : s + chunk]))
        out[s : s + chunk] = pose[:, joints].reshape(len(pose), -1)
    return out


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
    from mocapviz.knn import KnnIndex

    engines, rows = {}, []
    for engine, label in (("ckdtree", "ours: KnnIndex(engine='ckdtree')"),
                          ("brute", "brute force: KnnIndex(engine='brute')")):  # fmt: skip
        index, times, rss = _build_timed(lambda engine=engine: KnnIndex(features, engine=engine), repeats)
        rows.append({"engine": label, "build_s": statistics.median(times), "runs_s": times,
                     "nbytes_MB": index.nbytes / 2**20, "rss_MB": rss / 2**20})  # fmt: skip
        engines[engine] = lambda q, k, eps=0.0, workers=-1, index=index: index.query(q, k, eps=eps, workers=workers)
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


def bench_queries(features: np.ndarray, engines: dict, quick: bool, repeats: int, seed: int = 7):
    """(b): per k, per-query times of each engine on the same random database frames."""
    rng = np.random.default_rng(seed)
    n_queries = N_QUERIES_QUICK if quick else N_QUERIES
    n_brute = N_BRUTE_QUICK if quick else N_BRUTE
    rows, notes = [], []
    for k in KS:
        queries = features[rng.choice(len(features), n_queries[k], replace=False)].astype(np.float64)
        sample = queries[:n_brute]
        d_ref, i_ref = engines["brute"](sample, k)
        d, i = engines["ckdtree"](sample, k)
        bad = _disagreements(features, sample, d, i, d_ref, i_ref)
        notes.append(f"k={k}: ours and brute force on {n_brute} queries: "
                     + ("identical (up to exact ties)" if not bad else f"{bad} ENTRIES DIFFER"))  # fmt: skip
        if "pykdtree" in engines:
            d_p, i_p = engines["pykdtree"](sample, k)
            bad_p = _disagreements(features, sample, d_p.astype(np.float64), i_p.astype(np.int64), d_ref, i_ref)
            notes.append(f"k={k}: pykdtree (float32 distances) and brute force on {n_brute} queries: "
                         + ("identical (up to exact ties)" if not bad_p else f"{bad_p} entries differ by > 1e-5 "
                            "or beyond a tie (float32 rounding)"))  # fmt: skip
        variants = [("ours (ckdtree), all cores", "ckdtree", {}, queries),
                    ("ours (ckdtree), 1 thread", "ckdtree", {"workers": 1}, queries),
                    (f"ours (ckdtree), eps = {EPS}, all cores", "ckdtree", {"eps": EPS}, queries),
                    ("numpy brute force, all cores", "brute", {}, sample)]  # fmt: skip
        if "pykdtree" in engines:
            variants.insert(3, ("pykdtree, all cores", "pykdtree", {}, queries))
        runs = {name: [] for name, *_ in variants}
        for _ in range(repeats):
            for name, engine, options, q in variants:
                _log(f"k={k}: {name}, {len(q):,} queries")
                wall, cpu, _ = _timed(lambda e=engine, q=q, o=options, k=k: engines[e](q, k, **o))
                runs[name].append((wall / len(q) * 1e3, cpu / len(q) * 1e3))
        brute_ms = statistics.median(r[0] for r in runs["numpy brute force, all cores"])
        for name, _, _, q in variants:
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
                         "paper_hdm05_ms": PAPER_MS[k][0], "paper_cmu_ms": PAPER_MS[k][1],
                         "target": f"≤ {TARGET_MS[k]:g} ms, ≥ {TARGET_SPEEDUP:.0f}× brute" if ours else "",
                         "meets": meets, "differ": bad})  # fmt: skip
    return rows, notes


# ============================================================================ (c) fat-graph base poses
def bench_fat_graph(features: np.ndarray, real_frames: int, quick: bool) -> list[dict]:
    """(c): base_poses beside base_poses_quadratic on evenly spaced real frames; base_poses on all frames."""
    from mocapviz.knn import base_poses, base_poses_quadratic

    rows = []
    base_poses(features[:100], FAT_RADIUS, k=FAT_K)  # numba: compile or load from the disk cache
    for n in FAT_SIZES_QUICK if quick else FAT_SIZES:
        subset = features[: real_frames : max(1, real_frames // n)][:n]
        _log(f"base poses of {len(subset):,} frames")
        wall, _, (base, cluster) = _timed(lambda subset=subset: base_poses(subset, FAT_RADIUS, k=FAT_K))
        wall_q, _, (base_q, cluster_q) = _timed(lambda subset=subset: base_poses_quadratic(subset, FAT_RADIUS,
                                                                                            k=FAT_K))  # fmt: skip
        same = np.array_equal(base, base_q) and np.array_equal(cluster, cluster_q)
        rows.append({"frames": len(subset), "base_poses": len(base), "ours_s": wall, "quadratic_s": wall_q,
                     "speed-up": wall_q / wall, "identical": "yes" if same else "NO"})  # fmt: skip
    if not quick:
        _log(f"base poses of all {len(features):,} frames")
        wall, _, (base, _) = _timed(lambda: base_poses(features, FAT_RADIUS, k=FAT_K))
        rows.append({"frames": len(features), "base_poses": len(base), "ours_s": wall, "quadratic_s": None,
                     "speed-up": None, "identical": "(no reference: n^2 = "
                     f"{len(features) ** 2 * 8 / 2**40:.0f} TiB of distances)"})  # fmt: skip
    return rows


# ============================================================================ output
def _f(v, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    if isinstance(v, (int, np.integer)):
        return f"{v:,}"
    return f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.{digits}f}"


def _header(info: dict, quick: bool, repeats: int) -> str:
    return "\n".join([
        "# mocapviz kNN benchmark (Krüger, Tautges, Weber & Zinke 2010, Table 1, §5.3)"
        + (" (--quick: small database)" if quick else ""),
        "",
        f"- date: {time.strftime('%Y-%m-%dT%H:%M:%S')}, mocapviz {info['mocapviz']} @ {info['commit']}",
        f"- CPU: {info['cpu']}, {info['cores']} cores ({info['usable_cores']} usable), RAM {info['ram_gib']} GiB",
        (f"- {info['os']}; Python {info['python']}, numpy {info['numpy']}, scipy {info['scipy']}, "
         f"numba {info['numba']}, pykdtree {info['pykdtree']}"),
        f"- each figure: median of {repeats} runs of the whole query batch; engines alternate within a run",
        f"- load average (1/5/15 min) at start: {info['load_start']}, at end: {_loadavg()}; {info.get('others', '')}",
        "- paper (Table 1, F15E, exact): ANN library on a 2010 PC; HDM05 380,813 frames, CMU 1,038,388 frames",
    ])  # fmt: skip


def table_build(rows: list[dict]) -> str:
    return _markdown(
        "| engine | build s (median) | runs s | structure MB | RSS growth MB |",
        "|---|---:|---|---:|---:|",
        ([r["engine"], _f(r["build_s"]), ", ".join(f"{t:.2f}" for t in r["runs_s"]), _f(r["nbytes_MB"], 1),
          _f(r["rss_MB"], 1)] for r in rows),
    )  # fmt: skip


def table_queries(rows: list[dict]) -> str:
    return _markdown(
        "| k | engine | queries | ms/query | CPU ms/query | runs ms/query | brute / this | paper ms HDM05 / CMU "
        "| target | meets |",
        "|---:|---|---:|---:|---:|---|---:|---|---|---|",
        ([str(r["k"]), r["engine"], f"{r['queries']:,}", _f(r["ms_per_query"], 4), _f(r["cpu_ms_per_query"], 4),
          ", ".join(f"{t:.4f}" for t in r["runs_ms"]), f"{r['vs_brute']:.0f}×",
          f"{r['paper_hdm05_ms']:g} / {r['paper_cmu_ms']:g}", r["target"], r["meets"]] for r in rows),
    )  # fmt: skip


def table_fat(rows: list[dict]) -> str:
    return _markdown(
        "| frames | base poses | base_poses s (kd-tree, O(n log n)) | base_poses_quadratic s (O(n²)) | speed-up "
        "| identical |",
        "|---:|---:|---:|---:|---:|---|",
        ([f"{r['frames']:,}", f"{r['base_poses']:,}", _f(r["ours_s"]), _f(r["quadratic_s"]),
          "—" if r["speed-up"] is None else f"{r['speed-up']:.1f}×", r["identical"]] for r in rows),
    )  # fmt: skip


def write_csv(path: Path, build_rows, query_rows, fat_rows, info: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    ignore = path.parent / ".gitignore"
    if not ignore.exists():
        ignore.write_text("*.csv\n")
    parts = [
        pd.DataFrame(build_rows).assign(section="build").drop(columns=["runs_s"]),
        pd.DataFrame(query_rows).assign(section="queries").drop(columns=["runs_ms"]),
        pd.DataFrame(fat_rows).assign(section="fat_graph"),
    ]
    out = pd.concat(parts, ignore_index=True)
    for k in ("cpu", "python", "numpy", "scipy", "commit"):
        out[k] = info[k]
    out.insert(0, "section", out.pop("section"))
    out.to_csv(path, index=False)


# ============================================================================ main
def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from importlib import metadata

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    try:
        info["pykdtree"] = metadata.version("pykdtree")
    except metadata.PackageNotFoundError:
        info["pykdtree"] = "not installed (pip install pykdtree to compare)"
    db, record = benchmark_db(quick)
    _log(f"F15E of {db.n_frames:,} frames")
    t0 = time.perf_counter()
    features = f15e_from_skeleton(db)
    t_features = time.perf_counter() - t0
    engines, build_rows = build_engines(features, repeats)
    query_rows, query_notes = bench_queries(features, engines, quick, repeats)
    del engines
    fat_rows = bench_fat_graph(features, record["real_frames"], quick)
    info["others"] = monitor.report()

    print(_header(info, quick, repeats))
    for line in describe_db(db, record):
        print(f"- {line}")
    print(f"- F15E features: `f15e_from_skeleton` (mocapviz.skeleton.body_frame of {', '.join(END_EFFECTORS)}), "
          f"({db.n_frames:,}, 15) float32 cm, {t_features:.1f} s")  # fmt: skip
    print()
    print("## (a) Build time and memory")
    print()
    print(table_build(build_rows))
    print()
    print("Structure MB: ours = float64 copy of the features + tree permutation and its inverse + nodes (72 B each) "
          "+ frame map (`KnnIndex.nbytes`); brute = the float64 copy; pykdtree = float32 data + permutation "
          "(nodes not counted). RSS growth: resident memory after the first build minus before (includes allocator "
          "slack; pykdtree's float32 copy was made before and is not in it).")  # fmt: skip
    print()
    print("## (b) k nearest neighbours per query (exact unless eps; ms, lower is better)")
    print()
    print(table_queries(query_rows))
    print()
    print("Queries: random database frames (each finds itself). Brute force: `KnnIndex(engine='brute')` — scipy "
          "`cdist` (sums of squared differences) + `np.argpartition`, 64 MB chunks of queries over threads; timed on "
          "the first queries of the batch only. CPU ms/query: process CPU time (all threads) per query.")  # fmt: skip
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
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("knn-quick.csv" if quick else "knn.csv")
    write_csv(csv_path, build_rows, query_rows, fat_rows, info)
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
