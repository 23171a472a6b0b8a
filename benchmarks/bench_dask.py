"""Dask scale-out: ingest and feature extraction in this process against a local Dask cluster.

Steps, each on the same data and timed ``repeats`` times (median):

- ``MotionDB.ingest(files, fps=30)`` of the shared archives (all four; --quick: the quick subset) into a fresh
  database: serial (``threads=1``), 2 threads (``threads=2``), and on a local cluster
  (``scheduler=client``: a ``dask.distributed.LocalCluster`` of 2 worker processes, 1 thread each, started once
  by ``mocapviz.parallel.dask_client("local", n_workers=2)``; its start-up time is reported on its own row);
- ``mocapviz.features.store_numeric(db, "F15E")`` and ``mocapviz.features.relational_features(db)`` (31
  features) of that database: threads in this process (``threads=1`` and ``threads=2``) against the same local
  cluster.

Peak memory: the largest sum of resident memory (RSS) of this process and all its descendants (the cluster's
worker processes), sampled every 50 ms by psutil during the step (the serial steps run before
the cluster is started, so their peaks do not include its idle workers) (getrusage's max RSS cannot sum
concurrent processes; tracemalloc misses numpy memory maps). Ratio: cluster seconds / serial (threads=1) seconds
(< 1: the cluster is faster).
"""

from __future__ import annotations

import os
import shutil
import statistics
import sys
import threading
import time
from pathlib import Path

import pandas as pd

from .common import REPO, BenchDB, CpuMonitor, _source_files, log, machine_info, write_results_csv
from .common import fmt as _f

FPS = 30
WORKERS = 2
SPEC = BenchDB("dask", fps=FPS)  # only its archives and quick subset are used; nothing is cached


class PeakRSS:
    """Peak of the summed RSS of this process and its descendants while the ``with`` block runs (psutil)."""

    def __init__(self, interval: float = 0.05):
        import psutil

        self.proc, self.interval, self.peak = psutil.Process(), interval, 0
        self._stop = threading.Event()

    def _sample(self) -> int:
        import psutil

        total = 0
        for p in [self.proc, *self.proc.children(recursive=True)]:
            try:
                total += p.memory_info().rss
            except psutil.Error:
                pass
        return total

    def _run(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, self._sample())
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self._sample())

    @property
    def mb(self) -> float:
        return self.peak / 2**20


def _timed(fn, repeats: int, before=None) -> dict:
    times, peaks = [], []
    for _ in range(repeats):
        if before is not None:
            before()
        with PeakRSS() as mem:
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        peaks.append(mem.mb)
    return {"s": statistics.median(times), "runs_s": times, "peak_MB": max(peaks)}


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from mocapviz.db.database import MotionDB
    from mocapviz.features import relational_features, store_numeric
    from mocapviz.parallel import dask_client

    t_start = time.perf_counter()
    monitor = CpuMonitor()
    info = machine_info()
    files, missing = _source_files(SPEC, quick)
    paths = [f for fs in files.values() for f in fs]
    work = REPO / ".cache" / "bench" / ("dask-tmp-quick" if quick else "dask-tmp")
    target = work / "db"

    def fresh():
        if work.exists():
            shutil.rmtree(work)
        work.mkdir(parents=True)

    def ingest(**kw):
        return lambda: MotionDB.ingest(paths, target, fps=FPS, progress=False, **kw)

    rows = []
    order = ["ingest", "cluster start-up", "store_numeric F15E", "relational (31 features)"]
    # warm-up: numba caches, imports, page cache of the archives
    fresh()
    MotionDB.ingest(paths[:20], target, fps=FPS, progress=False)
    relational_features(MotionDB.open(target), progress=False)
    store_numeric(MotionDB.open(target), "F15E", progress=False)
    log(f"ingest of {len(paths)} files, serial and with threads={WORKERS}")
    for label, kw in (("serial (threads=1)", {"threads": 1}), (f"{WORKERS} threads (threads={WORKERS})",
                                                               {"threads": WORKERS})):  # fmt: skip
        rows.append({"step": "ingest", "how": label, **_timed(ingest(**kw), repeats, fresh)})
    features = (("store_numeric F15E", lambda db, **kw: store_numeric(db, "F15E", progress=False, **kw)),
                ("relational (31 features)", lambda db, **kw: relational_features(db, "2005", progress=False, **kw)))

    def bench_features(db, configs):
        for step, fn in features:
            for label, kw in configs:
                rows.append({"step": step, "how": label, **_timed(lambda kw=kw, fn=fn: fn(db, **kw), repeats)})
                log(f"{step} {label}: {rows[-1]['s']:.2f} s")

    # serial feature runs first, on the database the last ingest left, with no cluster running
    db = MotionDB.open(target)
    n_frames = db.n_frames
    log(f"features of {n_frames:,} frames, in this process")
    bench_features(db, (("serial (threads=1)", {"threads": 1}), (f"{WORKERS} threads (threads={WORKERS})",
                                                                 {"threads": WORKERS})))  # fmt: skip
    with PeakRSS() as mem:
        t0 = time.perf_counter()
        cm = dask_client("local", n_workers=WORKERS)
        client = cm.__enter__()
        t_start_cluster = time.perf_counter() - t0
    try:
        rows.append({"step": "cluster start-up", "how": f"LocalCluster, {WORKERS} workers × 1 thread",
                     "s": t_start_cluster, "runs_s": [t_start_cluster], "peak_MB": mem.mb})  # fmt: skip
        client.run(_warm_worker, str(target))  # imports and numba on the workers, not timed
        rows.append({"step": "ingest", "how": f"local cluster ({WORKERS} workers)",
                     **_timed(ingest(scheduler=client), repeats, fresh)})  # fmt: skip
        db = MotionDB.open(target)
        assert db.n_frames == n_frames, (db.n_frames, n_frames)
        log(f"features of {n_frames:,} frames, on the cluster")
        bench_features(db, ((f"local cluster ({WORKERS} workers)", {"scheduler": client}),))
    finally:
        cm.__exit__(None, None, None)
    shutil.rmtree(work, ignore_errors=True)
    rows.sort(key=lambda r: order.index(r["step"]))  # stable: serial rows before the cluster's
    serial = {r["step"]: r["s"] for r in rows if "threads=1" in r["how"]}
    for r in rows:
        r["frames"] = n_frames
        r["frames/s"] = n_frames / r["s"] if r["step"] != "cluster start-up" else None
        r["ratio_vs_serial"] = r["s"] / serial[r["step"]] if r["step"] in serial else None
    info["others"] = monitor.report()

    print(f"# Dask scale-out: serial vs {WORKERS}-worker local cluster ({'QUICK run' if quick else 'full run'})")
    print()
    print(f"- machine: {info['cpu']}, {info['usable_cores']} usable cores, {info['ram_gib']} GiB RAM; Python "
          f"{info['python']}, numpy {info['numpy']}; dask/distributed {_version('distributed')}; commit "
          f"{info['commit']}")  # fmt: skip
    print(f"- data: {len(paths)} files (" + ", ".join(f"{k} {len(v)}" for k, v in files.items())
          + f") ingested at {FPS} Hz → {n_frames:,} frames" + (f"; missing: {'; '.join(missing)}" if missing else ""))
    print(f"- each figure: median of {repeats} runs; ingest into a fresh database each run")
    print("- peak MB: largest summed RSS of this process and all its child processes (cluster workers), "
          "sampled every 50 ms with psutil")
    print(f"- {info['others']}")
    print()
    print("| step | how | s (median) | frames/s | ratio vs serial (threads=1) | peak MB | runs s |")
    print("|---|---|---:|---:|---:|---:|---|")
    for r in rows:
        print(f"| {r['step']} | {r['how']} | {_f(r['s'], 2)} | {_f(r['frames/s'])} | {_f(r['ratio_vs_serial'], 2)} "
              f"| {_f(r['peak_MB'], 0)} | {', '.join(f'{t:.2f}' for t in r['runs_s'])} |")
    print()
    print("Ratio < 1: faster than serial. The cluster start-up (LocalCluster + Client, 2 worker processes) is paid "
          "once per `scheduler=\"local\"` call; the rows above reuse one running cluster (`scheduler=client`).")
    out_dir = Path(out_dir) if out_dir is not None else Path(__file__).resolve().parent / "results"
    csv_path = out_dir / ("dask-quick.csv" if quick else "dask.csv")
    df = pd.DataFrame([{k: (", ".join(f"{t:.3f}" for t in v) if k == "runs_s" else v) for k, v in r.items()}
                       for r in rows])  # fmt: skip
    write_results_csv(csv_path, {"dask": df}, info)
    print()
    print(f"CSV: {csv_path}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


def _warm_worker(path: str) -> None:
    import mocapviz.io  # noqa: F401 - the readers the ingest tasks use
    from mocapviz.db.database import MotionDB
    from mocapviz.features import numeric_features, relational_features

    motion = MotionDB.open(path).motion(0)
    relational_features(motion, progress=False)
    numeric_features(motion, "F15E", progress=False)


def _version(name: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "not installed"


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv, repeats=1 if "--quick" in sys.argv else 3))
