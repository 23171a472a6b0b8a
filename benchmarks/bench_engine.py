"""Engine overhead (issue 38): every use case asked through ``mocapviz.engine.Engine(db)`` (no scheduler: one shard,
the whole database, in this process) beside the library function the engine wraps, on the same derived data and
with the same arguments.

The engine adds a step to every one-process query: its boundary checks, the shard's hit table packed into arrays
(:meth:`mocapviz.engine.shard.Shard.packed`), the packs merged and the hit table rebuilt
(:meth:`Engine._merged`). This benchmark measures what that step costs per query.

Databases (cached under ``<repo>/.cache/bench/``, shared with the benchmarks that build them): the HDM05 cut at 30 Hz
(``bench_search.CLIPS_DB``, 287 documents) and every shared archive at 30 Hz (``bench_dashboard.DATABASE``). Before
timing, each database gets what ``mocapviz features DB`` and ``mocapviz index DB`` store (F15E; the 2005 and 2006
inverted indexes) when it lacks them. The baselines are given the engine's own derived data: ``engine.numeric("F15E")``,
``engine.indexes(set)``, ``engine.relational_values("2006")``, and a ``SimilaritySearch(db, "F15E", features=...)``
whose kd-tree (``knn_index``) serves kNN and LNG.

Per use case, ``QUERIES`` queries drawn at random (seed 0); each is asked once of both (a warm-up: numba, first use
of the derived data) and their hit tables compared — (doc_id, start, end) row for row must be the same, or the run
fails — then ``RUNS`` times each, engine and library alternating (which goes first alternates too), wall and CPU time
of this process. A row's figures: the median over its queries of each query's median; "added" is the median over
the queries of (engine − library).

Also timed: ``Engine(db)`` itself (median of ``RUNS``), and the first query of each use case on a fresh ``Engine(db)``
(the shard makes its derived data then: F15E read, kd-tree built, indexes read, 2006 values computed), in this
process after the runs above (numba compiled, the database's files in the page cache).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .common import (
    REPO,
    CpuMonitor,
    benchmark_db,
    describe_db,
    header,
    log,
    machine_info,
    markdown,
    write_results_csv,
)
from .common import fmt as _f

SEED = 0
QUERIES = (5, 2)  # queries per use case: (full, quick)
RUNS = (9, 3)  # timed runs of each query on each side after its warm-up: (full, quick)
LEARN_CLASSES = (3, 1)  # classes (of the HDM05 labels, at random) whose templates are learned and searched
K = 10  # n_matches of the similarity searches and matching
K_TEMPLATE = 20  # n_matches of the template search (the engine's default, given to both)
K_KNN = 16
BATCH = 200  # rows of the batched kNN query
SECONDS = 1.0  # the stretch, LNG, DTW and relational examples: 1 s of a document
DELTA = 0.1  # the library's search_template default (the engine's is 0.2): given to both
DESCRIPTIONS = ("kick_right", "kick_right then punch_left within 2 s")
TRAIN_ACTORS = ("bd", "bk", "dg", "tr")


def _databases():
    from .bench_dashboard import DATABASE as EVERY_ARCHIVE
    from .bench_search import CLIPS_DB as HDM05

    return (("HDM05 cut, 30 Hz", HDM05), ("every shared archive, 30 Hz", EVERY_ARCHIVE))


@dataclass
class Case:
    """One use case: the engine's call (``engine(an_engine, item)``) and the library's (``library(item)``) of one
    query item; ``same`` compares their answers (None when the same)."""

    use: str
    call: str
    items: list
    engine: object
    library: object
    same: object


def _hits(table) -> np.ndarray:
    return table[["doc_id", "start", "end"]].to_numpy(np.int64)


def same_hits(a, b) -> str | None:
    """None when two hit tables hold the same (doc_id, start, end) rows in the same order, else what differs."""
    x, y = _hits(a), _hits(b)
    if x.shape == y.shape and np.array_equal(x, y):
        return None
    return f"{len(x)} vs {len(y)} rows; first differing: " + next(
        (f"row {i}: engine {tuple(u)} library {tuple(v)}" for i, (u, v) in enumerate(zip(x, y))
         if not np.array_equal(u, v)), "(a prefix)")  # fmt: skip


def same_knn(a, b) -> str | None:
    (da, fa), (db_, fb) = a, b
    fa, fb = np.atleast_2d(fa), np.atleast_2d(fb)
    if fa.shape == fb.shape and np.array_equal(fa, fb) and np.array_equal(np.atleast_2d(da), np.atleast_2d(db_)):
        return None
    return f"neighbours differ ({fa.shape} vs {fb.shape})"


def same_template(a, b) -> str | None:
    if np.array_equal(np.asarray(a.values), np.asarray(b.values), equal_nan=True) and list(a.features) == list(
            b.features):
        return None
    return "template values differ"


def prepare(db) -> dict:
    """Store F15E and the 2005 / 2006 inverted indexes when missing or stale (as ``mocapviz features`` and
    ``mocapviz index`` do); returns the seconds each took (0: already stored)."""
    from mocapviz.errors import MotionDBError
    from mocapviz.features.numeric import load_numeric, store_numeric
    from mocapviz.relational.index import load_or_build

    took = {}
    t0 = time.perf_counter()
    try:
        load_numeric(db, "F15E")
        took["F15E stored"] = 0.0
    except MotionDBError:
        store_numeric(db, ["F15E"], progress=False)
        took["F15E stored"] = time.perf_counter() - t0
    for name in ("2005", "2006"):
        t0 = time.perf_counter()
        load_or_build(db, name)
        took[f"indexes {name}"] = time.perf_counter() - t0
    return took


def library_setup(db) -> tuple[dict, dict]:
    """The derived data the baselines use, made as a library user makes it (the stored F15E read, a
    SimilaritySearch and its kd-tree, the stored indexes read, the 2006 values computed), and the seconds of each."""
    from mocapviz.features import numeric_of, relational_features
    from mocapviz.relational.index import load_or_build
    from mocapviz.similarity.search import SimilaritySearch

    made, took = {}, {}

    def step(name, fn):
        t0 = time.perf_counter()
        made[name] = fn()
        took[name] = time.perf_counter() - t0

    step("F15E", lambda: numeric_of(db, "F15E"))
    step("search", lambda: SimilaritySearch(db, "F15E", features=made["F15E"]))
    step("kd-tree", lambda: made["search"].knn_index)
    step("indexes 2005", lambda: load_or_build(db, "2005"))
    step("indexes 2006", lambda: load_or_build(db, "2006"))
    step("values 2006", lambda: relational_features(db, "2006", progress=False)[0])
    return made, took


def cases(db, lib: dict, n_queries: int, n_classes: int) -> tuple[list[Case], dict]:
    """The use cases and their queries (seed 0) on ``db``; ``lib``: the baselines' derived data, taken from the
    engine (:func:`main`)."""
    from mocapviz.features import feature_groups
    from mocapviz.relational.query import query_by_example
    from mocapviz.relational.scene import find
    from mocapviz.relational.templates import learn_class, search_template
    from mocapviz.similarity.knn import describe_frames
    from mocapviz.similarity.motion_matching import match_motion

    rng = np.random.default_rng(SEED)
    docs = db.documents.reset_index(drop=True)
    features, search, index = lib["F15E"], lib["search"], lib["search"].knn_index
    idx05, idx06, values06 = lib["indexes 2005"], lib["indexes 2006"], lib["values 2006"]
    m = round(SECONDS * db.typical_fps)
    long_ = docs[docs["n_frames"] >= 2 * m]
    hdm = docs[docs["path"].astype("string").str.contains("hdm05", na=False).to_numpy()]

    def pick(table, n):
        return table.iloc[np.sort(rng.choice(len(table), min(n, len(table)), replace=False))]

    def spans(n):  # (doc_id, (a, a + m)) in-document
        out, picked = [], pick(long_, n)
        for d, length in zip(picked["doc_id"], picked["n_frames"]):
            a = int(rng.integers(0, int(length) - m + 1))
            out.append((int(d), (a, a + m)))
        return out

    clips = [int(d) for d in pick(hdm if len(hdm) else docs, n_queries)["doc_id"]]
    stretch, lng, dtw, rel = spans(n_queries), spans(n_queries), spans(n_queries), spans(n_queries)
    rel_motions = [db.motion(d)[a:b] for d, (a, b) in rel]
    rows = rng.integers(0, db.n_frames, n_queries)
    single = [np.asarray(features[r], dtype=np.float64) for r in rows]
    batches = [np.asarray(features[rng.integers(0, db.n_frames, BATCH)], dtype=np.float64)
               for _ in range(max(1, n_queries // 2))]  # fmt: skip
    # neighbours: a frame of a document, its own document left out
    picked = pick(docs, n_queries)
    frames_of = [(int(d), int(rng.integers(0, int(n)))) for d, n in zip(picked["doc_id"], picked["n_frames"])]
    lower = feature_groups("2005")["lower"]
    labelled = hdm[hdm["label"].notna()] if "label" in hdm else hdm.iloc[:0]
    labels = sorted(labelled["label"].astype(str).unique())
    classes = [labels[i] for i in np.sort(rng.choice(len(labels), min(n_classes, len(labels)), replace=False))]
    templates = [learn_class(db, label, TRAIN_ACTORS, "2006", values=values06, max_examples=16) for label in classes]

    def neighbours_lib(q):
        d, f = q
        span = db.frames(d)
        dist, found = index.query(np.asarray(features[span.start + f], dtype=np.float64)[None], K_KNN,
                                  exclude=np.array([[span.start, span.stop]]))  # fmt: skip
        return describe_frames(db, found[0], dist[0])

    out = [
        *[Case("clips", f"whole HDM05 clip, {mode}, K = {K}, own document excluded", clips,
               lambda eng, d, mode=mode: eng.clips(d, n_matches=K, mode=mode, exclude_document=True),
               lambda d, mode=mode: search.clips(d, n_matches=K, mode=mode, exclude_document=True), same_hits)
          for mode in ("exact", "fast")],
        *[Case("stretches", f"{SECONDS:g} s, {mode}, K = {K}, own document excluded", stretch,
               lambda eng, e, mode=mode: eng.stretches(e[0], frames=e[1], n_matches=K, mode=mode, exclude_document=True),
               lambda e, mode=mode: search.stretches(e[0], e[1], n_matches=K, mode=mode, exclude_document=True),
               same_hits) for mode in ("exact", "fast")],
        Case("knn", f"{K_KNN}-NN of one row", single, lambda eng, q: eng.knn(q, k=K_KNN),
             lambda q: index.query(q, K_KNN), same_knn),
        Case("knn", f"{K_KNN}-NN of a batch of {BATCH} rows (per call)", batches, lambda eng, q: eng.knn(q, k=K_KNN),
             lambda q: index.query(q, K_KNN), same_knn),
        Case("neighbours", f"{K_KNN} nearest frames of a frame, own document excluded (hit table)", frames_of,
             lambda eng, q: eng.neighbours(q[0], q[1], k=K_KNN, exclude_document=True), neighbours_lib, same_hits),
        Case("match", f"LNG, {SECONDS:g} s, k = 256, K = {K}, own document excluded", lng,
             lambda eng, e: eng.match(e[0], frames=e[1], method="lng", n_matches=K, k=256, exclude_document=True),
             lambda e: match_motion(db, e[0], e[1], "F15E", "lng", K, 256, exclude_document=True, features=features,
                                    index=index), same_hits),
        Case("match", f"subsequence DTW, {SECONDS:g} s, K = {K}, own document excluded", dtw,
             lambda eng, e: eng.match(e[0], frames=e[1], method="dtw", n_matches=K, exclude_document=True),
             lambda e: match_motion(db, e[0], e[1], "F15E", "dtw", K, exclude_document=True, features=features),
             same_hits),
        *[Case("query", f"{SECONDS:g} s example, lower body (2005), {mode}" + (", 1 mismatch" if mode == "mismatch"
                                                                                else ""), rel_motions,
               lambda eng, e, mode=mode: eng.query(e, features=lower, mode=mode, mismatches=1),
               lambda e, mode=mode: query_by_example(db, e, lower, mode=mode, mismatches=1, indexes=idx05), same_hits)
          for mode in ("exact", "fuzzy", "adaptive", "mismatch")],
        Case("find", "shipped descriptions, every hit (n_matches=None)", list(DESCRIPTIONS),
             lambda eng, t: eng.find(t, n_matches=None), lambda t: find(db, t, indexes=idx05), same_hits),
        Case("learn_template", f"class template (2006), actors {', '.join(TRAIN_ACTORS)}, <= 16 examples", classes,
             lambda eng, lb: eng.learn_template(lb, actors=TRAIN_ACTORS, relational_set="2006", max_examples=16),
             lambda lb: learn_class(db, lb, TRAIN_ACTORS, "2006", values=values06, max_examples=16), same_template),
        *[Case("search_template", f"δ = {DELTA:g}, K = {K_TEMPLATE}" + (", pre-filter" if pre else ""), templates,
               lambda eng, t, pre=pre: eng.search_template(t, n_matches=K_TEMPLATE, delta=DELTA, prefilter=pre),
               lambda t, pre=pre: search_template(db, t, n_matches=K_TEMPLATE, delta=DELTA, prefilter=pre,
                                                  values=values06, indexes=idx06 if pre else None), same_hits)
          for pre in (False, True)],
    ]  # fmt: skip
    return out, {"classes": classes, "template rows": [len(t.values) for t in templates]}


def _timed(fn, item) -> tuple[float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    fn(item)
    return time.perf_counter() - t0, time.process_time() - c0


def measure(case: Case, engine, runs: int) -> dict:
    """Warm-up and comparison, then ``runs`` alternating runs per query: the row of the table."""
    differ = []
    ask = lambda item: case.engine(engine, item)
    for item in case.items:
        why = case.same(ask(item), case.library(item))
        if why is not None:
            differ.append(why)
    eng, lib, added, added_cpu = [], [], [], []
    for item in case.items:
        e_wall, e_cpu, l_wall, l_cpu = [], [], [], []
        for r in range(runs):
            sides = [(ask, e_wall, e_cpu), (case.library, l_wall, l_cpu)]
            for fn, wall, cpu in sides if r % 2 == 0 else sides[::-1]:
                w, c = _timed(fn, item)
                wall.append(w)
                cpu.append(c)
        e, lb = float(np.median(e_wall)), float(np.median(l_wall))
        eng.append(e)
        lib.append(lb)
        added.append(e - lb)
        added_cpu.append(float(np.median(e_cpu)) - float(np.median(l_cpu)))
    return {"use": case.use, "call": case.call, "queries": len(case.items), "runs": runs,
            "library_ms": 1e3 * float(np.median(lib)), "engine_ms": 1e3 * float(np.median(eng)),
            "added_ms": 1e3 * float(np.median(added)), "added_cpu_ms": 1e3 * float(np.median(added_cpu)),
            "ratio": float(np.median(eng)) / max(float(np.median(lib)), 1e-12), "same": not differ,
            "differ": "; ".join(differ[:2])}  # fmt: skip


def first_queries(db, case_list: list[Case], runs: int) -> tuple[float, list[dict]]:
    """``Engine(db)``'s construction (median of ``runs``), then each use case's first query on a fresh engine."""
    from mocapviz.engine import Engine

    built = []
    for _ in range(runs):
        t0 = time.perf_counter()
        Engine(db)
        built.append(time.perf_counter() - t0)
    firsts = []
    for case in case_list:
        t0 = time.perf_counter()
        engine = Engine(db)
        t1 = time.perf_counter()
        case.engine(engine, case.items[0])
        firsts.append({"use": case.use, "call": case.call, "construct_ms": 1e3 * (t1 - t0),
                       "first_ms": 1e3 * (time.perf_counter() - t1)})  # fmt: skip
    return 1e3 * float(np.median(built)), firsts


def run_database(label: str, spec, quick: bool, repeats: int) -> dict:
    from mocapviz.engine import Engine

    k = 1 if quick else 0
    t0 = time.perf_counter()
    db, record = benchmark_db(spec, quick)
    t_db = time.perf_counter() - t0
    log(f"{label}: {db.n_frames:,} frames, {len(db):,} documents ({t_db:.1f} s)")
    stored = prepare(db)
    _, lib_took = library_setup(db)  # timed as a library user pays them (the engine's own are used below)
    engine = Engine(db)
    lib = {"F15E": engine.numeric("F15E"), "indexes 2005": engine.indexes("2005"),
           "indexes 2006": engine.indexes("2006"), "values 2006": engine.relational_values("2006")}  # fmt: skip
    from mocapviz.similarity.search import SimilaritySearch

    lib["search"] = SimilaritySearch(db, "F15E", features=lib["F15E"])
    case_list, drawn = cases(db, lib, QUERIES[k], LEARN_CLASSES[k])
    runs = max(RUNS[k], repeats) if not quick else RUNS[k]
    rows = []
    for case in case_list:
        log(f"  {case.use}: {case.call}")
        rows.append(measure(case, engine, runs) | {"database": label})
    construct_ms, firsts = first_queries(db, case_list, runs)
    return {"label": label, "db": db, "record": record, "rows": rows, "construct_ms": construct_ms,
            "firsts": firsts, "stored": stored, "lib_took": lib_took, "drawn": drawn, "runs": runs}  # fmt: skip


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    t_start = time.perf_counter()
    monitor, info = CpuMonitor(), machine_info()
    results = [run_database(label, spec, quick, repeats) for label, spec in _databases()]
    info["others"] = monitor.report()
    k = 1 if quick else 0
    notes = []
    for res in results:
        notes += [f"**{res['label']}**: " + "; ".join(describe_db(res["db"], res["record"]))]
        stored = ", ".join(f"{n} {s:.1f} s" for n, s in res["stored"].items())
        notes.append(f"{res['label']}: derived data stored before timing (0: already stored): {stored}; the "
                     "library's derived data as a user makes it: "
                     + ", ".join(f"{n} {1e3 * s:,.0f} ms" for n, s in res["lib_took"].items())
                     + f"; templates of {', '.join(res['drawn']['classes'])} "
                     f"({'/'.join(map(str, res['drawn']['template rows']))} rows)")  # fmt: skip
    notes += [
        (f"each row: {QUERIES[k]} queries drawn at random (seed {SEED}; find: the {len(DESCRIPTIONS)} descriptions; "
         f"learn_template: {LEARN_CLASSES[k]} classes; kNN batches: {max(1, QUERIES[k] // 2)}), each asked once of "
         f"both (warm-up, hit tables compared), then {results[0]['runs']} runs of each, engine and library "
         "alternating; ms: the median over the queries of each query's median wall time; added: the median over the "
         "queries of (engine − library), wall and CPU time of this process"),
        ("engine: `Engine(db)` (no scheduler: one shard holding the whole database, in this process); library: "
         "`SimilaritySearch(db, 'F15E', features=engine.numeric('F15E')).clips/stretches`, its `knn_index.query` "
         "(kNN; neighbours: + `describe_frames`), `match_motion(..., features=, index=)`, "
         "`query_by_example(..., indexes=engine.indexes('2005'))`, `scene.find(..., indexes=)`, "
         "`learn_class(..., values=engine.relational_values('2006'))`, `templates.search_template(..., values=, "
         "indexes=)`; the same arguments on both sides (k = 256 to LNG, δ = 0.1 and K = 20 to the template search, "
         "n_matches=None to find)"),
        ("same hits: (doc_id, start, end) of every query's hit table equal row for row (kNN: frames and distances; "
         "learn_template: the template's values)"),
    ]
    command = "python -m benchmarks --only engine" + (" --quick" if quick else "")
    print(header("### Engine overhead: every use case through Engine(db) beside the library function it wraps "
                 "(bench_engine)", info, ("numpy", "numba", "scipy", "pykdtree"),
                 [f"command: `{command}` (or `python -m benchmarks.bench_engine`)", *notes]))  # fmt: skip
    print()
    rows = [r for res in results for r in res["rows"]]
    print(markdown(
        "| database | use case | call | queries | library ms | Engine ms | added ms | added CPU ms | Engine / library "
        "| same hits |", "|---|---|---|---:|---:|---:|---:|---:|---:|---|",
        [[r["database"], f"`{r['use']}`", r["call"], str(r["queries"]), _f(r["library_ms"], 3), _f(r["engine_ms"], 3),
          _f(r["added_ms"], 3), _f(r["added_cpu_ms"], 3), f"{r['ratio']:.2f}×",
          "yes" if r["same"] else f"NO: {r['differ']}"] for r in rows]))  # fmt: skip
    print()
    print("added CPU ms: the CPU time of this process (engine − library), far less disturbed than wall time by the "
          "other processes sharing the 2 cores; where the two 'added' columns differ by more than a few ms, the wall "
          "figure is the machine's noise (a query of hundreds of ms shifted by another process), not the engine's work.")
    print()
    print("#### `Engine(db)` and the first query of each use case on a fresh engine")
    print()
    for res in results:
        print(f"- {res['label']}: `Engine(db)` of an open MotionDB {res['construct_ms']:.2f} ms (median of "
              f"{res['runs']}: one Shard over a view of every document; its derived data made on first use)")
    print()
    firsts = [f | {"database": res["label"]} for res in results for f in res["firsts"]]
    print(markdown("| database | use case | call | Engine(db) ms | first query ms | warm query ms (table above) |",
                   "|---|---|---|---:|---:|---:|",
                   [[f["database"], f"`{f['use']}`", f["call"], _f(f["construct_ms"], 2), _f(f["first_ms"], 1),
                     _f(next(r["engine_ms"] for r in rows if r["database"] == f["database"] and r["call"] == f["call"]
                             and r["use"] == f["use"]), 1)] for f in firsts]))  # fmt: skip
    print()
    print("First query: a fresh `Engine(db)` per row, its first query (the first of the row's queries) timed once: "
          "the shard makes the derived data the use case needs then (F15E read from the database, the kd-tree and "
          "the similarity search's boxes built, the stored indexes read, the 2006 values computed), as the library "
          "user pays the steps listed above; in this process after the timed runs (numba compiled, files cached).")
    print()
    failed = [r for r in rows if not r["same"]]
    out = Path(out_dir) if out_dir is not None else REPO / "benchmarks" / "results"
    csv = out / f"engine{'-quick' if quick else ''}.csv"
    write_results_csv(csv, {"overhead": pd.DataFrame(rows), "first query": pd.DataFrame(firsts)}, info)
    print(f"CSV: benchmarks/results/{csv.name}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    if failed:  # the section says so (its rows "NO"), and the run fails
        print(f"\n**FAILED: {len(failed)} rows gave a different hit table through the engine**: "
              + "; ".join(f"{r['database']} {r['use']} ({r['call']}): {r['differ']}" for r in failed))
        log(f"bench_engine: {len(failed)} use cases answered differently through Engine(db)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
