"""Global motion matching benchmark (Krüger, Tautges, Weber & Zinke 2010 §4.1) on F15E features of >= 1M frames.

What is measured, per query length (1 s = 30 frames and 3 s = 90 frames at 30 Hz):

(a) Times. The lazy neighbourhood graph ``mocapviz.match.lng(query, KnnIndex(F15E), k, radius=None,
    n_matches=10, starts=..., exclude=own document, min_length=None)`` (the paper's graph: matches of any length,
    as both searches here) end to end (kNN search included), with its two parts from
    ``out.attrs["seconds"]``: the kNN search and the graph (construction + shortest paths + match selection,
    i.e. "LNG excluding kNN", beside the paper's 0.03 s for a 1 s query and 0.08 s for a 3 s query). k = 256
    is the configuration of the targets; k = 64, k = 1024 and eps = 0.1 / 0.5 (approximate kNN, k = 256) are
    printed beside it, and k = 256 without the exclusion of the own document as a timing diagnostic (the query
    then finds itself). Baselines on the first queries of each length: our subsequence DTW
    ``mocapviz.match.subsequence_dtw(query, F15E, starts, n_matches=10, min_length=None)`` (numba, compiled before
    timing) and the
    dtaidistance library's C subsequence DTW: ``dtaidistance.dtw_ndim.warping_paths_fast(query, F15E64,
    penalty=0, psi=[0, 0, n, n], psi_neg=False, keep_int_repr=True, inner_dist="euclidean")`` — the call its
    ``subsequence_alignment(...).align()`` makes (psi relaxation of both ends of the series), with the local
    cost set to the Euclidean distance as ours, so that the last row of its accumulated-cost matrix is our cost
    model exactly. It needs float64 (the F15E copy is made once, not timed); it does not know documents (its
    alignments may cross them); its top-K selection (a Python backtrack per match) is not timed, which favours
    it. Ratios: the baseline's median seconds over its queries (it does O(m n) work whatever the query) / LNG's
    median seconds over all queries of that length.
(b) Quality against subsequence DTW, on every timed query: the accumulated cost of the best subsequence-DTW
    alignment ending at every database frame (``mocapviz.match.subsequence_costs``; ends inside the query's own
    document dropped). Per query, Spearman's rho between the costs of LNG's matches (up to 10) and the
    subsequence-DTW costs at the same end frames (queries with fewer than 3 matches have none), averaged over
    queries; the fraction of LNG match costs equal to DTW's at their end (relative difference < 1e-9: LNG found
    the optimal path there); recall: the fraction of subsequence DTW's top-10 non-overlapping matches outside
    the own document that an LNG match overlaps. The reference top 10 is chosen as ``subsequence_dtw`` does
    (local minima per document, ``select_matches``); on the baseline queries it is checked against
    ``subsequence_dtw``'s own output. Why matches are missed, for k = 256: the share of DTW's top-10 matches
    whose optimal path (``mocapviz.match.dtw`` of the query against the matched stretch) lies wholly inside
    LNG's neighbourhoods (the k nearest frames of each query frame, own document excluded) -- then the graph
    has that path and its cost -- and the share of the path cells that do.
    In (a) and (b), the row "k=256, real frames only" runs LNG k = 256 on the real frames alone: the first
    ``real_frames`` frames of the same database (its real documents; the mirrored copies are appended after
    them), with their own ``KnnIndex`` and subsequence-DTW reference, so that the effect of the mirrored copies
    on recall is measured, not assumed.

Queries: random 1 s / 3 s stretches of the real (not mirrored) documents, uniform over the possible stretches
(seeded), each searched outside its own document. The database: the kNN benchmark's (``bench_knn.DATABASE``:
the four shared archives at 30 Hz plus left/right mirrored copies up to 1M frames, cached under
``<repo>/.cache/bench/knn-v2[-quick]/``); the mirrored copies are other documents, so a query may match its
own document's mirror image.
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

from .bench_knn import DATABASE, FPS
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

SECONDS = (1, 3)  # query lengths
K_MATCHES = 10
K_MAIN = 256
N_QUERIES = 16  # per length, timed with LNG and compared with subsequence DTW; quick: N_QUERIES_QUICK
N_QUERIES_QUICK = 4
N_BASELINE = 3  # per length, also timed with subsequence DTW and the library; quick: N_BASELINE_QUICK
N_BASELINE_QUICK = 1
TARGET_SPEEDUP = 100.0
TARGET_RHO = 0.99
EQUAL_RTOL = 1e-9
PAPER_GRAPH_S = {1: 0.03, 3: 0.08}  # Krüger et al. 2010: LNG time without the kNN search, 1 s and 3 s queries
SEED = 11
REAL = "k=256, real frames only"
# (label, k, eps, exclude own document, runs at most, on the real frames only): the first row is the one the
# targets apply to
CONFIGS = (
    ("k=256", K_MAIN, 0.0, True, None, False),
    ("k=64", 64, 0.0, True, None, False),
    ("k=1024", 1024, 0.0, True, 1, False),
    ("k=256, eps=0.1", K_MAIN, 0.1, True, None, False),
    ("k=256, eps=0.5", K_MAIN, 0.5, True, None, False),
    ("k=256, own document not excluded (timing only)", K_MAIN, 0.0, False, None, False),
    (REAL, K_MAIN, 0.0, True, None, True),
)
COVERED = {False: CONFIGS[0][0], True: REAL}  # {real frames only: the row whose neighbourhoods are checked}


# ============================================================================ queries and reference
def pick_queries(db, m: int, n: int, rng) -> list[dict]:
    """n random m-frame stretches of real (not mirrored) documents of at least m frames, uniform over stretches."""
    docs = db.documents
    real = docs["mirror_of"].isna().to_numpy() if "mirror_of" in docs else np.ones(len(docs), bool)
    ok = np.flatnonzero(real & (docs["n_frames"].to_numpy() >= m))
    if not len(ok):
        raise RuntimeError(f"no real document of at least {m} frames")
    weight = (docs["n_frames"].to_numpy()[ok] - m + 1).astype(float)
    out = []
    for d in rng.choice(ok, n, replace=True, p=weight / weight.sum()):
        start, frames = int(docs["start"].iloc[d]), int(docs["n_frames"].iloc[d])
        first = start + int(rng.integers(0, frames - m + 1))
        out.append({"m": m, "doc": int(d), "name": str(docs["name"].iloc[d]), "doc_start": start,
                    "doc_stop": start + frames, "first": first})  # fmt: skip
    return out


def reference(q: np.ndarray, features: np.ndarray, starts: np.ndarray, query: dict) -> dict:
    """Subsequence DTW's cost and start at every end frame (own document's ends set to inf) and its top-K
    non-overlapping matches outside the own document."""
    from mocapviz.match import best_ends, subsequence_costs

    t0 = time.perf_counter()
    cost, first = subsequence_costs(q, features, starts)
    seconds = time.perf_counter() - t0
    cost[query["doc_start"] : query["doc_stop"]] = np.inf
    ends = best_ends(cost, first, starts, K_MATCHES)
    return {"cost": cost, "first": first, "ends": ends, "starts": first[ends], "seconds": seconds}


def quality(matches: pd.DataFrame, ref: dict) -> dict:
    """Spearman rho of LNG's match costs against subsequence DTW's at the same ends, the counts of exactly equal
    costs and of subsequence DTW's top matches recalled (:func:`mocapviz.experiments.matching.agreement`)."""
    from mocapviz.experiments.matching import agreement

    a = agreement(matches, ref["cost"], ref["starts"], ref["ends"], EQUAL_RTOL)
    n, n_ref = len(matches), len(ref["ends"])
    return {"rho": a["spearman"], "n_matches": n, "n_equal": round(a["equal"] * n) if n else 0, "n_ref": n_ref,
            "n_recalled": round(a["recall"] * n_ref) if n_ref else 0, "lower_than_dtw": a["below_dtw"]}


def path_coverage(q: np.ndarray, index, own, features, ref: dict) -> dict:
    """Of subsequence DTW's top matches, how many have their whole optimal path inside the k = K_MAIN
    neighbourhoods of the query frames (the graph then finds that path), and how many path cells lie inside."""
    from mocapviz.match import dtw
    from mocapviz.match.neighbourhood_graph import neighbourhoods

    _, near = neighbourhoods(q, index, K_MAIN, exclude=own)
    out = {"paths": len(ref["ends"]), "paths_inside": 0, "cells": 0, "cells_inside": 0}
    for start, end in zip(ref["starts"], ref["ends"]):
        _, path = dtw(q, np.asarray(features[start : end + 1], dtype=np.float64))
        inside = (near[path[:, 0]] == start + path[:, 1, None]).any(axis=1)
        out["paths_inside"] += int(inside.all())
        out["cells"] += len(inside)
        out["cells_inside"] += int(inside.sum())
    return out


# ============================================================================ timings
def _timed(fn) -> tuple[float, float, object]:
    """Wall and CPU (all threads) seconds of fn(), and its result."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def _library():
    """dtaidistance's C subsequence DTW as f(query, database float64) -> cost (n,) of the best alignment ending
    at every frame, or None (and why) when it is not installed or has no C extension."""
    try:
        from dtaidistance import dtw, dtw_ndim
    except ImportError:
        return None, "dtaidistance not installed (pip install dtaidistance)"
    if not dtw.try_import_c():
        return None, "dtaidistance has no C extension here"

    def run(q: np.ndarray, x64: np.ndarray) -> np.ndarray:
        n = len(x64)
        _, acc = dtw_ndim.warping_paths_fast(q, x64, penalty=0.0, psi=[0, 0, n, n], psi_neg=False,
                                             keep_int_repr=True, inner_dist="euclidean")  # fmt: skip
        return acc[-1, 1:].copy()

    return run, None


def run_lng(searched: dict, queries: list[dict], features, repeats: int) -> dict:
    """{config label: per query {"wall": [...], "knn": [...], "graph": [...], "cpu": [...], "out": first result}}.
    ``searched``: {real frames only: (KnnIndex, document starts)}. The configurations alternate within a repeat."""
    from mocapviz.match import lng

    runs = {c[0]: [{"wall": [], "knn": [], "graph": [], "cpu": [], "out": None} for _ in queries] for c in CONFIGS}
    index, starts = searched[False]
    lng(np.asarray(features[:30], dtype=np.float64), index, k=8, starts=starts)  # numba: load the compiled code
    for rep in range(repeats):
        for label, k, eps, exclude, cap, real in CONFIGS:
            if cap is not None and rep >= cap:
                continue
            index, starts = searched[real]
            log(f"LNG {label}, run {rep + 1}: {len(queries)} queries")
            for qi, query in enumerate(queries):
                q = np.asarray(features[query["first"] : query["first"] + query["m"]], dtype=np.float64)
                own = np.array([query["doc_start"], query["doc_stop"]]) if exclude else None
                wall, cpu, out = _timed(lambda q=q, own=own, k=k, eps=eps, index=index, starts=starts: lng(
                    q, index, k=k, radius=None, n_matches=K_MATCHES, starts=starts, eps=eps, exclude=own, min_length=None))
                r = runs[label][qi]
                r["wall"].append(wall)
                r["cpu"].append(cpu)
                r["knn"].append(out.attrs["seconds"]["knn"])
                r["graph"].append(out.attrs["seconds"]["graph"])
                if r["out"] is None:
                    r["out"] = out[["doc_id", "start", "end", "cost"]]
    return runs


def run_baselines(queries: list[dict], features, starts, x64, library) -> list[dict]:
    """Per baseline query: our subsequence_dtw's and the library's seconds and results."""
    from mocapviz.match import subsequence_costs, subsequence_dtw

    subsequence_dtw(np.asarray(features[:40], dtype=np.float64), features[:5_000], n_matches=2)  # numba: compile / load
    if library is not None:
        library(np.asarray(features[:40], dtype=np.float64), x64[:5_000])
    out = []
    for query in queries:
        q = np.asarray(features[query["first"] : query["first"] + query["m"]], dtype=np.float64)
        log(f"subsequence DTW, {query['m']}-frame query")
        wall, cpu, table = _timed(lambda q=q: subsequence_dtw(q, features, starts, n_matches=K_MATCHES, min_length=None))
        row = {"dtw_s": wall, "dtw_cpu_s": cpu, "dtw_table": table, "lib_s": None, "lib_cpu_s": None, "lib": None}
        if library is not None:
            log(f"dtaidistance, {query['m']}-frame query")
            row["lib_s"], row["lib_cpu_s"], row["lib"] = _timed(lambda q=q: library(q, x64))
            # the same cost model: ours over the database as one document must give the library's costs
            one, _ = subsequence_costs(q, features)
            row["lib_vs_one_document"] = float(np.max(np.abs(row["lib"] - one) / np.maximum(one, 1e-300)))
        out.append(row)
    return out


# ============================================================================ summaries
def _meets(ok: bool, miss: str) -> str:
    return "met" if ok else f"MISSED ({miss})"


def summarise(queries, runs, refs, base, cover) -> tuple[list[dict], list[dict], list[dict], list[str]]:
    """Rows of the time/quality table (per config and length), of the baseline table, per-query rows, notes.
    ``refs``: {real frames only: per query reference}; ``cover``: {config label: per query path_coverage}."""
    rows, base_rows, query_rows, notes = [], [], [], []
    for seconds in SECONDS:
        m = seconds * FPS
        sel = [i for i, q in enumerate(queries) if q["m"] == m]
        bsel = [i for i in sel if i in base]
        for label, k, eps, exclude, _, real in CONFIGS:
            per = [runs[label][i] for i in sel]
            wall = [statistics.median(r["wall"]) for r in per]
            knn = [statistics.median(r["knn"]) for r in per]
            graph = [statistics.median(r["graph"]) for r in per]
            # baseline times hardly depend on the query's content (O(m n) whatever it is), LNG's do: the ratios
            # divide the baselines' median by LNG's median over all queries of the length
            # (the baselines searched the whole database: no ratio for the real frames alone)
            vs_dtw = [base[i]["dtw_s"] for i in bsel if not real]
            vs_lib = [base[i]["lib_s"] for i in bsel if base[i]["lib_s"] is not None and not real]
            row = {"query_s": seconds, "query_frames": m, "config": label, "k": k, "eps": eps, "real_only": real,
                   "exclude_own_document": exclude, "queries": len(sel), "runs": len(per[0]["wall"]),
                   "lng_s": statistics.median(wall), "knn_s": statistics.median(knn),
                   "graph_s": statistics.median(graph), "lng_s_max": max(wall), "graph_s_max": max(graph),
                   "knn_share": statistics.median(a / b for a, b in zip(knn, wall)),
                   "paper_graph_s": PAPER_GRAPH_S[seconds], "baseline_queries": len(bsel),
                   "dtw_s": statistics.median(vs_dtw) if vs_dtw else None,
                   "lib_s": statistics.median(vs_lib) if vs_lib else None,
                   "dtw_over_lng": statistics.median(vs_dtw) / statistics.median(wall) if vs_dtw else None,
                   "lib_over_lng": statistics.median(vs_lib) / statistics.median(wall) if vs_lib else None}  # fmt: skip
            if exclude:
                qual = [quality(runs[label][i]["out"], refs[real][i]) for i in sel]
                rhos = [x["rho"] for x in qual if np.isfinite(x["rho"])]
                matches = sum(x["n_matches"] for x in qual)
                row |= {"rho_mean": float(np.mean(rhos)) if rhos else None, "rho_min": min(rhos) if rhos else None,
                        "queries_with_rho": len(rhos), "matches": matches,
                        "no_match_queries": sum(x["n_matches"] == 0 for x in qual),
                        "equal_fraction": sum(x["n_equal"] for x in qual) / matches if matches else None,
                        "recall": sum(x["n_recalled"] for x in qual) / max(1, sum(x["n_ref"] for x in qual)),
                        "below_dtw": sum(x["lower_than_dtw"] for x in qual)}  # fmt: skip
                if label in cover:
                    c = {key: sum(cover[label][i][key] for i in sel) for key in cover[label][sel[0]]}
                    row |= {"paths_inside": c["paths_inside"] / max(1, c["paths"]),
                            "cells_inside": c["cells_inside"] / max(1, c["cells"])}
                if label == CONFIGS[0][0]:
                    for i, x in zip(sel, qual):
                        q = queries[i]
                        query_rows.append({"query_s": seconds, "document": q["name"], "first": q["first"],
                                           "document_frames": q["doc_stop"] - q["doc_start"],
                                           "lng_s": statistics.median(runs[label][i]["wall"]),
                                           "knn_s": statistics.median(runs[label][i]["knn"]),
                                           "graph_s": statistics.median(runs[label][i]["graph"]),
                                           "subsequence_costs_s": refs[False][i]["seconds"], **x})  # fmt: skip
                if label == CONFIGS[0][0]:
                    r = row
                    miss_dtw = f"{r['dtw_over_lng']:.0f}× < {TARGET_SPEEDUP:.0f}×" if vs_dtw else "not run"
                    miss_lib = f"{r['lib_over_lng']:.0f}× < {TARGET_SPEEDUP:.0f}×" if vs_lib else "not run"
                    r["meets_speedup_dtw"] = _meets(bool(vs_dtw) and r["dtw_over_lng"] >= TARGET_SPEEDUP, miss_dtw)
                    r["meets_speedup_lib"] = _meets(bool(vs_lib) and r["lib_over_lng"] >= TARGET_SPEEDUP, miss_lib)
                    rho = r["rho_mean"]
                    r["meets_rho"] = _meets(rho is not None and rho >= TARGET_RHO,
                                            "no query with 3 matches" if rho is None else f"{rho:.3f} < {TARGET_RHO}")
                    r["meets_rho"] += f", on {r['queries_with_rho']} of {len(sel)} queries (>= 3 matches)"
            rows.append(row)
        for i in bsel:
            b, ref, q = base[i], refs[False][i], queries[i]
            table = b["dtw_table"]
            outside = table[table["doc_id"] != q["doc"]]
            n_out = len(outside)
            same = (np.array_equal(outside["end"].to_numpy(), ref["ends"][:n_out])
                    and np.array_equal(outside["start"].to_numpy(), ref["starts"][:n_out])
                    and np.allclose(outside["cost"].to_numpy(), ref["cost"][ref["ends"][:n_out]], rtol=1e-12))
            br = {"query_s": seconds, "document": q["name"], "first": q["first"],
                  "document_frames": q["doc_stop"] - q["doc_start"], "dtw_s": b["dtw_s"], "dtw_cpu_s": b["dtw_cpu_s"],
                  "lng_s": statistics.median(runs[CONFIGS[0][0]][i]["wall"]),
                  "dtw_matches_outside_own": n_out, "dtw_agrees_with_reference": "yes" if same else "NO",
                  "dtw_best": float(ref["cost"][ref["ends"][0]]) if len(ref["ends"]) else None,
                  "lib_s": b["lib_s"], "lib_cpu_s": b["lib_cpu_s"]}  # fmt: skip
            if b["lib"] is not None:
                lib = b["lib"]
                lib[q["doc_start"] : q["doc_stop"]] = np.inf  # ends inside the own document
                ours = ref["cost"]
                finite = np.isfinite(ours)
                rel = np.abs(lib[finite] - ours[finite]) / np.maximum(ours[finite], 1e-300)
                br |= {"lib_vs_one_document": b["lib_vs_one_document"], "lib_best": float(lib.min()), "lib_best_end": int(np.argmin(lib)),
                       "dtw_best_end": int(ref["ends"][0]) if len(ref["ends"]) else None,
                       "lib_le_ours": bool((lib[finite] <= ours[finite] * (1 + 1e-12)).all()),
                       "lib_equal_fraction": float((rel < EQUAL_RTOL).mean())}  # fmt: skip
                b["lib"] = None
            base_rows.append(br)
    return rows, base_rows, query_rows, notes


# ============================================================================ output
def _header(info: dict, quick: bool, repeats: int) -> str:
    return header(
        "# mocapviz motion-matching benchmark (Krüger, Tautges, Weber & Zinke 2010 §4.1: lazy neighbourhood graph)"
        + (" (--quick: small database)" if quick else ""),
        info, ("numpy", "scipy", "numba", "dtaidistance"),
        [(f"LNG: median over {repeats} run(s) per query (k=1024: 1 run), then the median over the queries; the "
         "configurations alternate within a run. Baselines: one run per query")],
    )  # fmt: skip


def table_lng(rows: list[dict]) -> str:
    def speed(r, key):
        return "—" if r[key] is None else f"{r[key]:.1f}×"

    return markdown(
        "| query | LNG | queries | LNG s (end to end) | kNN s | graph s (excl. kNN) | kNN share of LNG "
        "| paper excl. kNN s | max LNG s | subseq. DTW / LNG | dtaidistance / LNG | target ≥ 100× DTW "
        "| target ≥ 100× library |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|",
        ([f"{r['query_s']} s ({r['query_frames']} frames)", r["config"], f"{r['queries']}", _f(r["lng_s"], 3),
          _f(r["knn_s"], 3), _f(r["graph_s"], 4), f"{r['knn_share']:.0%}", f"{r['paper_graph_s']:g}",
          _f(r["lng_s_max"], 3),
          speed(r, "dtw_over_lng"), speed(r, "lib_over_lng"), r.get("meets_speedup_dtw", ""),
          r.get("meets_speedup_lib", "")] for r in rows),
    )  # fmt: skip


def table_quality(rows: list[dict]) -> str:
    return markdown(
        "| query | LNG | queries | with rho | Spearman rho (mean) | min rho | LNG matches | queries without a match "
        "| LNG cost = DTW cost | recall of DTW top 10 | DTW top-10 paths wholly in the k-neighbourhoods "
        "| DTW path cells in the k-neighbourhoods | target rho ≥ 0.99 |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        ([f"{r['query_s']} s", r["config"], f"{r['queries']}", f"{r['queries_with_rho']}", _f(r["rho_mean"], 3),
          _f(r["rho_min"], 3), f"{r['matches']}", f"{r['no_match_queries']}",
          "—" if r["equal_fraction"] is None else f"{r['equal_fraction']:.0%}", f"{r['recall']:.0%}",
          f"{r['paths_inside']:.0%}" if "paths_inside" in r else "—",
          f"{r['cells_inside']:.0%}" if "cells_inside" in r else "—",
          r.get("meets_rho", "")] for r in rows if r["exclude_own_document"]),
    )  # fmt: skip


def table_baselines(rows: list[dict]) -> str:
    return markdown(
        "| query | document (frames) | LNG k=256 s | subsequence_dtw s (CPU s) | dtaidistance s (CPU s) "
        "| DTW top 10 = reference | best cost: ours / dtaidistance | library ≤ ours everywhere "
        "| library = ours at end frames | library vs ours as one document (max rel. diff.) |",
        "|---|---|---:|---:|---:|---|---|---|---:|---:|",
        ([f"{r['query_s']} s", f"{r['document']} ({r['document_frames']:,})", _f(r["lng_s"], 3),
          f"{_f(r['dtw_s'])} ({_f(r['dtw_cpu_s'])})",
          "—" if r["lib_s"] is None else f"{_f(r['lib_s'])} ({_f(r['lib_cpu_s'])})",
          r["dtw_agrees_with_reference"],
          f"{_f(r['dtw_best'], 3)} / {_f(r.get('lib_best'), 3)}",
          "—" if r.get("lib_le_ours") is None else ("yes" if r["lib_le_ours"] else "NO"),
          "—" if r.get("lib_equal_fraction") is None else f"{r['lib_equal_fraction']:.1%}",
          "—" if r.get("lib_vs_one_document") is None else f"{r['lib_vs_one_document']:.1e}"] for r in rows),
    )  # fmt: skip


# ============================================================================ main
def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))

    from mocapviz.similarity.knn import KnnIndex

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info() | {"dtaidistance": package_version("dtaidistance")}
    db, record = benchmark_db(DATABASE, quick)
    log(f"F15E of {db.n_frames:,} frames")
    t0 = time.perf_counter()
    features = numeric_features(db, "F15E", progress=False)
    t_features = time.perf_counter() - t0
    t0 = time.perf_counter()
    index = KnnIndex(features)
    t_index = time.perf_counter() - t0
    starts = db.documents["start"].to_numpy()
    # the real frames alone (REAL rows): the mirrored copies are appended after the real documents
    n_real = record["real_frames"]
    docs = db.documents
    real_docs = docs["mirror_of"].isna().to_numpy() if "mirror_of" in docs else np.ones(len(docs), bool)
    assert np.array_equal(real_docs, starts < n_real), "the real documents are not the first frames"
    t0 = time.perf_counter()
    searched = {False: (index, starts), True: (KnnIndex(features[:n_real]), starts[real_docs])}
    t_index_real = time.perf_counter() - t0
    library, library_note = _library()
    x64 = np.asarray(features, dtype=np.float64) if library is not None else None

    rng = np.random.default_rng(SEED)
    n_q, n_b = (N_QUERIES_QUICK, N_BASELINE_QUICK) if quick else (N_QUERIES, N_BASELINE)
    queries = [q for s in SECONDS for q in pick_queries(db, s * FPS, n_q, rng)]
    runs = run_lng(searched, queries, features, repeats)
    base_ids = [i for s in SECONDS for i in [j for j, q in enumerate(queries) if q["m"] == s * FPS][:n_b]]
    base = dict(zip(base_ids, run_baselines([queries[i] for i in base_ids], features, starts, x64, library)))
    refs, cover = {False: {}, True: {}}, {label: {} for label in COVERED.values()}
    for i, q in enumerate(queries):
        log(f"subsequence-DTW references, query {i + 1} of {len(queries)} ({q['m']} frames)")
        qa = np.asarray(features[q["first"] : q["first"] + q["m"]], dtype=np.float64)
        own = np.array([q["doc_start"], q["doc_stop"]])
        for real, n in ((False, db.n_frames), (True, n_real)):
            index_, starts_ = searched[real]
            refs[real][i] = reference(qa, features[:n], starts_, q)
            cover[COVERED[real]][i] = path_coverage(qa, index_, own, features, refs[real][i])
    rows, base_rows, query_rows, notes = summarise(queries, runs, refs, base, cover)
    del refs, x64
    info["others"] = monitor.report()

    print(_header(info, quick, repeats))
    for line in describe_db(db, record):
        print(f"- {line}")
    print(f"- F15E features: `mocapviz.features.numeric_features(db, 'F15E')`, ({db.n_frames:,}, 15) float32 cm, "
          f"{t_features:.1f} s; `KnnIndex(F15E)` built in {t_index:.1f} s (not in the LNG times)")  # fmt: skip
    lens = [q["doc_stop"] - q["doc_start"] for q in queries]
    print(f"- queries: {n_q} per length, random stretches of real documents (uniform over stretches, seed {SEED}); "
          f"own documents {min(lens):,}–{max(lens):,} frames (median {int(np.median(lens)):,}), excluded from the "
          f"search; baselines on the first {n_b} per length")  # fmt: skip
    print(f"- real frames only ({REAL!r} rows): the first {n_real:,} frames of the database, its "
          f"{int(real_docs.sum()):,} real documents (the mirrored copies come after them), with their own "
          f"`KnnIndex` (built in {t_index_real:.1f} s) and subsequence-DTW reference; the same queries")  # fmt: skip
    print()
    print(f"## (a) Time per query (s, median; LNG: k neighbours per query frame, radius None, K = {K_MATCHES} "
          "matches)")
    print()
    print(table_lng(rows))
    print()
    print("LNG s: wall time of the whole `lng()` call (kNN search + graph); kNN s / graph s: its "
          "`attrs['seconds']`. Paper: Krüger et al. 2010's LNG time without the kNN search. Speed-ups: the "
          "baseline's median s over its queries (table c; it hardly depends on the query's content) / LNG's median s "
          "over all queries of the length (targets: k=256 row). "
          "`KnnIndex.query(exclude=...)` searches k + 2^ceil(log2(own document frames)) neighbours and drops "
          "the own document's, so the kNN time grows with the length of the query's document (compare the "
          "row without exclusion). kNN share: median over the queries of kNN s / LNG s. Real frames only: no "
          "speed-up (the baselines searched the whole database).")  # fmt: skip
    for r in rows:
        if r["config"] == CONFIGS[0][0]:
            print(f"- baselines, {r['query_s']} s queries (median of {r['baseline_queries']}): subsequence_dtw "
                  f"{_f(r['dtw_s'], 3)} s, dtaidistance {_f(r['lib_s'], 3)} s")
    print()
    print("## (b) Agreement with subsequence DTW (own document excluded on both sides)")
    print()
    print(table_quality(rows))
    print()
    print("Spearman rho: per query with >= 3 LNG matches, between LNG's match costs and subsequence DTW's "
          "accumulated cost at the same end frames (`subsequence_costs`); mean over those queries. LNG cost = DTW "
          "cost: LNG matches whose cost equals DTW's at their end (relative difference < 1e-9). Recall: subsequence "
          "DTW's top-10 non-overlapping matches outside the own document that some LNG match overlaps. Paths "
          f"wholly in the k-neighbourhoods (k = {K_MAIN} rows): DTW's top-10 matches whose optimal path "
          "(`mocapviz.match.dtw` of the query against the matched stretch) has, for every cell (query frame i, "
          f"database frame j), j among the {K_MAIN} nearest frames of query frame i outside the own document: the "
          "graph then has that path and its cost (its own choice of 10 non-overlapping matches may still leave "
          "it out); path cells: the share of all their cells that are. Real frames only: the same queries, LNG "
          "and the DTW reference on the real frames alone. "
          f"LNG costs below DTW's (impossible if both are right): {sum(r.get('below_dtw', 0) for r in rows)}.")
    print()
    print("## (c) Baselines per query: ours and the library's subsequence DTW")
    print()
    print(table_baselines(base_rows))
    print()
    if library is None:
        print(f"- library baseline not run: {library_note}")
    else:
        print("- dtaidistance: `dtaidistance.dtw_ndim.warping_paths_fast(query, F15E_float64, penalty=0, "
              "psi=[0, 0, n, n], psi_neg=False, keep_int_repr=True, inner_dist='euclidean')`, C code (single "
              "thread), the full (m+1) × (n+1) accumulated-cost matrix; the time includes allocating it, not the "
              "float64 copy of the features nor its top-K backtracking. It does not know documents: its "
              "alignments may cross them, so its best cost may be lower than ours, never higher. Library = ours: "
              "end frames whose costs agree to 1e-9 (the rest: a cheaper alignment across a document boundary); "
              "ours as one document: `subsequence_costs(query, F15E)` without document starts, which must equal "
              "the library's costs at every frame (same cost model; not timed).")
    print("- subsequence_dtw: `mocapviz.match.subsequence_dtw(query, F15E, starts, n_matches=10)` (numba; local "
          "costs over both cores, accumulation on one). DTW top 10 = reference: its matches outside the own document "
          "equal the reference's first ones.")  # fmt: skip
    for n in notes:
        print(f"- {n}")
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("match-quick.csv" if quick else "match.csv")
    write_results_csv(csv_path, {"lng": pd.DataFrame(rows), "baselines": pd.DataFrame(base_rows),
                                 "queries": pd.DataFrame(query_rows)},
                      info, ("cpu", "python", "numpy", "scipy", "dtaidistance", "commit"))  # fmt: skip
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
