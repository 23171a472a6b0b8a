"""8 simultaneous browser sessions on a large served database (issue 28 scope 2, measured by hand, not in CI):
``python tests/sessions_large.py DB [--sessions 8] [--port 5099]``.

Serves DB with ``mocapviz serve`` in a subprocess (its warm-up included; the script waits for "ready"), then runs
:func:`dashboard_sessions.session_round` for one session alone and for ``--sessions`` at once, each on one of the
documents of the document browser's first page with the answers the library gives for it (as
tests/test_app_sessions.py does on the sample), and prints the seconds of every kind of answer (first session alone;
p50 / p95 of the simultaneous ones), the errors, the server's RSS, and the CPU seconds the server and the whole
machine (the browsers included) used while the simultaneous sessions ran, and the answers the server kept for the
next sessions once they closed (from its log). Writes them as JSON to
build/test-artifacts/dashboard/sessions-large.json. Needs Debian's Chromium (``/usr/bin/chromium``).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from browser_helpers import ARTIFACTS
from dashboard_sessions import KINDS, Query, rss_mb, run_sessions

from conftest import CHROMIUM_ARGS
from mocapviz import MotionDB
from mocapviz.app.backend import Backend
from mocapviz.app.pages import describe, relational


def queries(db, n: int) -> list[Query]:
    """One query per session: the first ``n`` documents (the document browser's first page), with the hit counts
    the library gives for the page's default relational query of each and for the Describe example."""
    backend = Backend(db)
    out = []
    for i, doc in enumerate(db.documents["doc_id"].iloc[:n]):
        row = db.document(int(doc))
        k = 1 + i % 4
        hits = relational.search(backend, relational.first_query(backend, int(doc)))
        found = describe.search(backend, describe.EXAMPLE, "2005", k)
        out.append(Query(int(doc), str(row["name"]), int(row["n_frames"]), len(hits), str(row["label"]), k,
                         len(found)))
    return out


def cpu_seconds(pid: int | None = None) -> float:
    """CPU seconds (user + system) used so far by process ``pid``, or by the whole machine (every CPU) for None."""
    import os

    tick = os.sysconf("SC_CLK_TCK")
    if pid is None:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        return (fields[0] + fields[1] + fields[2] + fields[5] + fields[6]) / tick
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / tick


def serve(db: Path, port: int, log: Path) -> subprocess.Popen:
    """``mocapviz serve DB --port PORT`` in a subprocess, once its log says it is ready."""
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(db), "--port", str(port)],
                            stdout=log.open("w"), stderr=subprocess.STDOUT)  # fmt: skip
    deadline = time.monotonic() + 900
    while "ready:" not in log.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise SystemExit(f"mocapviz serve did not get ready:\n{log.read_text()}")
        time.sleep(0.5)
    return proc


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("db", type=Path)
    parser.add_argument("--sessions", type=int, default=8)
    parser.add_argument("--port", type=int, default=5099)
    parser.add_argument("--rounds", type=int, default=1,
                        help="rounds of the simultaneous sessions (the same queries): the server's RSS after each "
                             "round closed shows whether closed sessions' memory is reused")
    args = parser.parse_args(argv)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    log = ARTIFACTS / "sessions-large-server.log"
    t0 = time.perf_counter()
    proc = serve(args.db, args.port, log)
    started = time.perf_counter() - t0
    try:
        url = f"http://127.0.0.1:{args.port}/"
        qs = queries(MotionDB.open(args.db), args.sessions)
        rss = {"started": rss_mb(proc.pid)}
        chromium = Path("/usr/bin/chromium")
        alone = run_sessions(chromium, CHROMIUM_ARGS, url, qs[:1], hold=lambda: rss.update(one=rss_mb(proc.pid)))
        cpu0, machine0, wall0 = cpu_seconds(proc.pid), cpu_seconds(), time.perf_counter()
        many = run_sessions(chromium, CHROMIUM_ARGS, url, qs, hold=lambda: rss.update(many=rss_mb(proc.pid)))
        cpu = {"wall_s": time.perf_counter() - wall0, "server_cpu_s": cpu_seconds(proc.pid) - cpu0,
               "machine_cpu_s": cpu_seconds() - machine0}
        time.sleep(25)  # the server drops closed sessions about 17 s after their browsers went
        rss["closed"] = rss_mb(proc.pid)
        for i in range(2, args.rounds + 1):
            again = run_sessions(chromium, CHROMIUM_ARGS, url, qs)
            many.errors.extend(again.errors)
            time.sleep(25)
            rss[f"closed_after_round_{i}"] = rss_mb(proc.pid)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    kept = re.findall(r"(\d+) answers kept for the next sessions \(([\d.]+) MB\)", log.read_text())
    out = {"database": str(args.db), "sessions": args.sessions, "serve_ready_s": round(started, 1),
           "alone_s": {k: round(alone.seconds[k][0], 3) for k in KINDS},
           "p50_s": {k: round(many.percentile(k, 50), 3) for k in KINDS},
           "p95_s": {k: round(many.percentile(k, 95), 3) for k in KINDS},
           "errors": alone.errors + many.errors, "server_rss_mb": {k: round(v) for k, v in rss.items()},
           "simultaneous_cpu": {k: round(v, 1) for k, v in cpu.items()},
           "answers_kept_after_close": {"answers": int(kept[-1][0]), "mb": float(kept[-1][1])} if kept else None}  # fmt: skip
    (ARTIFACTS / "sessions-large.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))
    return 1 if out["errors"] else 0


if __name__ == "__main__":
    sys.exit(main())
