"""Motion-template search on >= 1M frames: the full DTW pass, the keyframe pre-filter and the exact search by lower
bounds (Müller & Röder 2006; issue 43).

The database is bench_relational's (``relational-v2``: every shared archive at 120 Hz plus left/right mirrored
copies of the HDM05 and CMU documents up to 1M frames, cached under ``.cache/bench``). For every HDM05 class a
template is learned (``mocapviz.relational.templates.learn_class``, the 2006 features) from the real clips of four actors
(not ``mm``), then searched in the whole database three ways, each timed ``repeats`` times (median):

- **full pass** (the baseline): subsequence DTW of the quantised template over every frame
  (``find_instances(..., bounds=False)``: the product's own streamed numba DTW over bit-packed frames);
- **pre-filter**: ``keyframe_ranges`` (four keyframes looked up in the 2006 relational indexes, built once,
  not timed, chained in the template's order at the examples' pace) and then the same DTW over the candidate
  ranges only (``find_instances(ranges=...)``); it may miss hits;
- **bounds** (the library's default): the documents aligned best lower bound first until no other can hold one of
  the K best (``find_instances``, default ``bounds=True``: the row and run bounds of the module docstring); the
  per-document distinct codes it reads (``document_codes``) are made once per values array, timed apart.

Reported per class: the template's frames, the share of the database's frames each search aligns, the times and
speed-ups over the full pass, the share of the full pass's hits of normalised cost <= 0.1 (among its best 50) that
the pre-filter finds again with equal cost, and whether the bounded search's answer equals the full pass's (the
same documents, frames and costs in the same order).
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .bench_relational import DATABASE
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

N_MATCHES = 50
GOOD = 0.1  # normalised cost of the hits compared
TRAIN_ACTORS = ("bd", "bk", "dg", "tr")


def _timed(fn, repeats: int) -> tuple[float, object]:
    runs, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        runs.append(time.perf_counter() - t0)
    return statistics.median(runs), out


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from mocapviz.features import relational_features
    from mocapviz.relational import index
    from mocapviz.relational.templates import document_codes, find_instances, keyframe_ranges, learn_class

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    db, record = benchmark_db(DATABASE, quick)
    log(f"relational features (2006) of {db.n_frames:,} frames")
    t0 = time.perf_counter()
    values, _ = relational_features(db, "2006", progress=False)
    t_features = time.perf_counter() - t0
    t0 = time.perf_counter()
    indexes = index.build(db, "2006", values=values, save=False, progress=False)
    t_index = time.perf_counter() - t0
    docs = db.documents
    real = docs[docs["path"].astype("string").str.contains("hdm05-cut", na=False) & docs["label"].notna()]
    if "actor" in real.columns:
        real = real[real["actor"].notna()]
    starts = docs["start"].to_numpy()
    t0 = time.perf_counter()
    document_codes(values, starts)
    t_codes = time.perf_counter() - t0
    rows = []
    classes = sorted(real["label"].dropna().unique())
    for label in classes[:3] if quick else classes:
        template = learn_class(db, label, TRAIN_ACTORS, "2006", values)
        find_instances(template, values[: 10 * len(template.values)], None, n_matches=1)  # numba warm-up
        log(f"{label}: {len(template.values)} template frames")
        full_s, full = _timed(lambda t=template: find_instances(t, values, starts, n_matches=N_MATCHES, bounds=False),
                              repeats)  # fmt: skip
        bounded_s, bounded = _timed(lambda t=template: find_instances(t, values, starts, n_matches=N_MATCHES), repeats)
        range_s, ranges = _timed(lambda t=template: keyframe_ranges(t, indexes, starts, len(values)), repeats)
        pre_s, pre = _timed(lambda t=template, r=ranges: find_instances(t, values, starts, n_matches=N_MATCHES,
                                                                          ranges=r), repeats)  # fmt: skip
        good = full[full["normalised_cost"] <= GOOD]
        both = good.merge(pre, on=["doc_id", "start", "end"], suffixes=("", "_pre"))
        same = both[np.isclose(both["cost"], both["cost_pre"])]
        rows.append({"class": label, "template_frames": len(template.values), "examples": template.n_examples,
                     "aligned_share": float((ranges[:, 1] - ranges[:, 0]).sum() / len(values)),
                     "full_s": full_s, "keyframes_s": range_s, "prefiltered_s": pre_s,
                     "speedup": full_s / (range_s + pre_s), "good_hits": len(good),
                     "found_again": len(same) / len(good) if len(good) else np.nan,
                     "bounded_aligned_share": bounded.attrs["aligned"] / len(values), "bounded_s": bounded_s,
                     "bounded_speedup": full_s / bounded_s,
                     "bounded_equal": bool(full.reset_index(drop=True).equals(bounded.reset_index(drop=True)))})  # fmt: skip
    table = pd.DataFrame(rows)
    info["others"] = monitor.report()
    notes = [f"repeats: {repeats} (median)",
             (f"relational features 2006 of the database: {t_features:.1f} s; the three 2006 indexes built in "
             f"memory: {t_index:.1f} s; the documents' distinct codes and runs (document_codes, once per values "
             f"array): {t_codes:.2f} s (none in the times below)"),
             f"K = {N_MATCHES} matches, δ = 0.1 (the library's default), at most steepest_rows rows per frame"]  # fmt: skip
    title = ("### Motion templates: the full DTW pass, the keyframe pre-filter and the exact search by lower bounds"
             + (" (quick)" if quick else ""))  # fmt: skip
    print(header(title, info, ("numpy",), notes))
    for line in describe_db(db, record):
        print(f"- {line}")
    print()
    print(markdown(
        "| class | template frames | examples | full pass s | pre-filter: frames aligned | keyframes s | "
        "pre-filtered DTW s | speed-up | full-pass hits <= 0.1 | found again | bounds: frames aligned | bounds s | "
        "speed-up | equal to the full pass |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        [[r["class"], str(r["template_frames"]), str(r["examples"]), _f(r["full_s"]), f"{r['aligned_share']:.1%}",
          _f(r["keyframes_s"], 3), _f(r["prefiltered_s"]), f"{r['speedup']:.1f}×", str(r["good_hits"]),
          f"{r['found_again']:.0%}" if r["good_hits"] else "—", f"{r['bounded_aligned_share']:.1%}",
          _f(r["bounded_s"], 3), f"{r['bounded_speedup']:.1f}×", "yes" if r["bounded_equal"] else "NO"]
         for r in rows]))  # fmt: skip
    print()
    print(f"Median over the classes: pre-filter {table['aligned_share'].median():.1%} of the frames aligned, speed-up "
          f"{table['speedup'].median():.1f}×, full-pass good hits found again {table['found_again'].mean():.1%} "
          f"(mean); bounds {table['bounded_aligned_share'].median():.1%} aligned, speed-up "
          f"{table['bounded_speedup'].median():.1f}× (least {table['bounded_speedup'].min():.1f}×), equal to the full "
          f"pass in {int(table['bounded_equal'].sum())} of {len(table)} classes. Full pass = the baseline: subsequence "
          "DTW over every frame.")
    out = Path(out_dir) if out_dir else REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    write_results_csv(out / f"templates{'-quick' if quick else ''}.csv", {"templates": table}, info)
    print()
    print(f"CSV: benchmarks/results/templates{'-quick' if quick else ''}.csv; total benchmark time "
          f"{time.perf_counter() - t_start:.0f} s")
    return 0
