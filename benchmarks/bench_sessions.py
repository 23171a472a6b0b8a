"""The server's capacity (issue 43 item 4): ``mocapviz serve`` on the embedded sample, N simulated sessions driven at
the protocol level (tests/protocol_sessions.py: Bokeh's WebSocket protocol, no browser per session), each running
the scripted round of every page over and over (open, choose a document, whole-clip search, kNN, relational query,
motion template, description; Index statistics and Correlations opened), while one real Chromium (Playwright,
Debian's) runs the same round ``BROWSER_ROUNDS`` times and measures its own steps. Every answer is checked against
the library's (the texts name the session's document, class and K with the hit counts the library gives).

Reported per N (``SESSIONS``): p50 / p95 seconds of each step for the browser and for the simulated sessions, the
rounds the simulated sessions completed, the server's CPU (share of one core, sampled every second: 200 % is both
cores) and its peak RSS (psutil), the load average. The browser's figures with N = 0 (alone) are the baseline of
the same run.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .bench_startup import sample_db
from .common import REPO, CpuMonitor, header, loadavg, log, machine_info, markdown, write_results_csv
from .common import fmt as _f

sys.path.insert(0, str(REPO / "tests"))  # the session drivers live beside the browser tests that use them

SESSIONS = (0, 1, 8, 32)  # simulated sessions beside the browser
BROWSER_ROUNDS = 3  # browser rounds per N, one after the other (1 with --quick)
DOCS = range(2, 10)  # the sample's documents of actor dg, one class each: the sessions' queries, in turn
CHROMIUM = Path("/usr/bin/chromium")
READY_S = 900  # the server's warm-up on a loaded 2-core machine (numba kernels compiled when not cached)


def serve(db: Path, log_path: Path, options=()) -> tuple[subprocess.Popen, str]:
    """``mocapviz serve DB`` on a free port, in a subprocess; returns once it says it is ready: (process, url)."""
    from browser_helpers import free_port

    port = free_port()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(db), "--port", str(port), *options],
                            stdout=log_path.open("w"), stderr=subprocess.STDOUT, cwd=REPO, env=env)  # fmt: skip
    deadline = time.monotonic() + READY_S
    while "mocapviz: ready:" not in log_path.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError(f"mocapviz serve did not start:\n{log_path.read_text()[-3000:]}")
        time.sleep(0.5)
    return proc, f"http://127.0.0.1:{port}/"


def measure(url: str, pid: int, queries: list, sessions, browser_rounds: int) -> list[dict]:
    """One row per (N, step, who): p50/p95 seconds and the counts, with the server's CPU and RSS of that N."""
    from dashboard_sessions import KINDS
    from protocol_sessions import run_load

    from conftest import CHROMIUM_ARGS

    rows = []
    for n in sessions:
        log(f"{n} simulated session(s) + 1 browser, {browser_rounds} browser round(s)")
        load = run_load(url, pid, queries, n, CHROMIUM, CHROMIUM_ARGS, browser_rounds=browser_rounds)
        errors = load.errors + load.browser.errors
        for e in errors:
            log(f"ERROR: {e}")
        common = {"sessions": n, "rounds": load.rounds, "wall_s": load.wall_s, "errors": len(errors),
                  "cpu_mean_pct": float(np.mean(load.cpu)) if load.cpu else np.nan,
                  "cpu_max_pct": float(np.max(load.cpu)) if load.cpu else np.nan,
                  "rss_max_mb": float(np.max(load.rss_mb)) if load.rss_mb else np.nan, "load": loadavg()}
        for kind in KINDS:
            for who in ("browser", "simulated"):
                if who == "simulated" and not n:
                    continue
                values = load.browser.seconds[kind] if who == "browser" else load.simulated[kind]
                rows.append({**common, "step": kind, "who": who, "n": len(values),
                             "p50_s": load.p(who, kind, 50), "p95_s": load.p(who, kind, 95)})
        log(f"N = {n}: browser p95 " + ", ".join(f"{k} {load.p('browser', k, 95):.2f}" for k in KINDS)
            + ("; simulated p95 " + ", ".join(f"{k} {load.p('simulated', k, 95):.2f}" for k in KINDS) if n else "")
            + f"; {load.rounds} rounds; server CPU mean {common['cpu_mean_pct']:.0f} %, peak RSS "
            f"{common['rss_max_mb']:.0f} MB; load {common['load']}")  # each N as it ends: a long run may be cut
    return rows


def main(quick: bool = False, repeats: int = 3, out_dir: Path | None = None) -> int:
    """``repeats`` is not used: each N runs for as long as the browser's rounds."""
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    from dashboard_sessions import queries_of

    from mocapviz import MotionDB

    if not CHROMIUM.exists():
        log(f"{CHROMIUM} not found (apt-get install chromium): no sessions benchmark")
        return 0
    t_start = time.perf_counter()
    monitor, info = CpuMonitor(), machine_info()
    db = sample_db()
    queries = queries_of(MotionDB.open(db), DOCS)
    log_path = REPO / ".cache" / "bench" / "sessions-serve.log"
    log_path.parent.mkdir(parents=True, exist_ok=True)
    proc, url = serve(db, log_path)
    try:
        sessions = SESSIONS  # --quick: one browser round per N
        rows = measure(url, proc.pid, queries, sessions, 1 if quick else BROWSER_ROUNDS)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    info["others"] = monitor.report()
    table = pd.DataFrame(rows)
    notes = [("`mocapviz serve` (one process) on the embedded sample (24 clips, 5,543 frames at 120 Hz), after its "
             "warm-up; the load generator (tests/protocol_sessions.py) and Chromium on the same 2 cores"),
             (f"each simulated session: the scripted round of tests/dashboard_sessions.py in a loop, a new session per "
             f"round, the documents {DOCS.start}..{DOCS.stop - 1} in turn; the browser: "
             f"{1 if quick else BROWSER_ROUNDS} round(s) of document {DOCS.start}; every answer checked"),
             "server CPU: % of one core, mean and max of 1 s samples (200 % = both cores); RSS: peak (psutil)",
             "baseline: the browser alone (0 simulated sessions), same server, same run"]
    print(header("### The server's capacity: simulated sessions and one browser (bench_sessions)"
                 + (" (quick)" if quick else ""), info, ("numpy", "bokeh", "panel"), notes))
    print()
    print(markdown("| sessions | step | browser p50 s | browser p95 s | simulated p50 s | simulated p95 s | "
                   "simulated answers |", "|---:|---|---:|---:|---:|---:|---:|",
                   [[str(n), kind, _f(b["p50_s"]), _f(b["p95_s"]),
                     *((_f(s["p50_s"]), _f(s["p95_s"]), str(s["n"])) if s is not None else ("—", "—", "0"))]
                    for (n, kind), g in table.groupby(["sessions", "step"], sort=False)
                    for b, s in [(g[g["who"] == "browser"].iloc[0],
                                  g[g["who"] == "simulated"].iloc[0] if (g["who"] == "simulated").any() else None)]]))
    print()
    per_n = table.drop_duplicates("sessions")
    print(markdown("| sessions | simulated rounds | seconds | server CPU mean % | max % | peak RSS MB | errors | "
                   "load average |", "|---:|---:|---:|---:|---:|---:|---:|---|",
                   [[str(r.sessions), str(r.rounds), _f(r.wall_s, 0), _f(r.cpu_mean_pct, 0), _f(r.cpu_max_pct, 0),
                     _f(r.rss_max_mb, 0), str(r.errors), r.load] for r in per_n.itertuples()]))
    print()
    csv = (out_dir or REPO / "benchmarks" / "results") / f"sessions{'-quick' if quick else ''}.csv"
    write_results_csv(csv, {"steps": table}, info)
    print(f"CSV: benchmarks/results/{csv.name}; total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(quick="--quick" in sys.argv))
