"""Many users of one dashboard (issue 28): `mocapviz serve` on a copy of the embedded sample, driven by headless
Chromium.

- 8 simultaneous sessions (browser contexts), each a round of every page (open, choose a document, whole-clip search,
  kNN, relational query, motion template, description; Index statistics and Correlations opened): no error, each
  answer the one of the session's own query (the texts name its document, class and K; the hit counts are the
  library's), opening the whole-database pages computes nothing (no job in the server log). The seconds of each kind
  of answer (the first after the server started; p50 / p95 over the 8 sessions) and the server's RSS with 1 and
  with 8 sessions open and after they closed go to build/test-artifacts/dashboard/timings.json; RSS with 8 sessions
  is at most 1.5 times that with one (the features, indexes and kd-trees are the server's, not the sessions'), and
  once they closed no dashboard of theirs is left in the server's memory.
- The job queue: a second session's job waits its turn (its place shown), Cancel stops a running job within seconds,
  closing a session stops its job.
"""

from __future__ import annotations

import re
import shutil
import time

import pytest
from browser_helpers import open_dashboard, open_tab, record_figures, record_first_answer, record_timing
from dashboard_sessions import KINDS, queries_of, rss_mb, run_sessions

from conftest import CHROMIUM_ARGS
from mocapviz import MotionDB
from mocapviz.app.jobs import POLL_S
from mocapviz.app.pages import statistics

pytestmark = pytest.mark.slow  # minutes on a loaded 2-core machine: 8 browser sessions and their server

DOCS = range(2, 10)  # the sample's documents of actor dg, one class each: one per session
RSS_RATIO = 1.5  # RSS with 8 sessions at most this times RSS with one
# the last session dropped, then (2 s later, possibly after the lines of the sessions dropped before it) its pages gone
ALL_GONE = r"session closed \(0 open\)\n(mocapviz: memory released: [1-9].*\n)*mocapviz: memory released: 0 dashboard"
WAIT_S = 120  # for the server to drop the closed sessions (it checks every 2 s, after 15 s without a browser)


@pytest.fixture(scope="module")
def served(sample_db, serve_dashboard, tmp_path_factory):
    """A server of its own (fresh caches, its own RSS) on a copy of the sample: (url, pid, log file, database)."""
    copy = tmp_path_factory.mktemp("sessions") / "db"
    shutil.copytree(sample_db.path, copy)
    url = serve_dashboard(copy)
    return url, serve_dashboard.pid_of(url), serve_dashboard.log_of(url), MotionDB.open(copy)


def _log_until(log, pattern: str, times: int = 1, timeout: float = WAIT_S) -> str:
    """The server's log once it matches ``pattern`` ``times`` times (fails after ``timeout`` seconds)."""
    deadline = time.monotonic() + timeout
    while len(re.findall(pattern, text := log.read_text())) < times:
        assert time.monotonic() < deadline, f"{pattern!r} not in the server log:\n{text[-3000:]}"
        time.sleep(0.5)
    return text


def test_eight_sessions_get_their_own_answers_and_share_the_servers_memory(served, chromium):
    url, pid, log, db = served
    queries = queries_of(db, DOCS)
    rss = {"started": rss_mb(pid)}

    alone = run_sessions(chromium, CHROMIUM_ARGS, url, queries[:1], hold=lambda: rss.update(one_session=rss_mb(pid)))
    assert not alone.errors, alone.errors
    for kind in KINDS:
        record_first_answer(kind, alone.seconds[kind][0])
    _log_until(log, ALL_GONE)

    eight = run_sessions(chromium, CHROMIUM_ARGS, url, queries, hold=lambda: rss.update(eight_sessions=rss_mb(pid)))
    assert not eight.errors, "\n".join(eight.errors)
    assert all(len(eight.seconds[kind]) == len(queries) for kind in KINDS)
    record_figures("sessions_8_p50_s", {k: eight.percentile(k, 50) for k in KINDS}, "s, median over 8 sessions")
    record_figures("sessions_8_p95_s", {k: eight.percentile(k, 95) for k in KINDS}, "s, 95th percentile, 8 sessions")

    # 2 s after the last session was dropped: no dashboard of theirs in the server's memory (no reference kept)
    _log_until(log, ALL_GONE, times=2)
    rss["closed"] = rss_mb(pid)
    record_figures("server_rss_mb", rss, "MB resident (VmRSS) of the mocapviz serve process")
    assert rss["eight_sessions"] <= RSS_RATIO * rss["one_session"], rss


def _status(page, css: str) -> str:
    return page.locator(css).first.inner_text()


def test_jobs_wait_their_turn_and_stop_when_cancelled_or_abandoned(served, browser):
    url, _, log, _ = served
    first, second = browser.new_context(), browser.new_context()
    a, b = first.new_page(), second.new_page()
    for page in (a, b):
        page.set_default_timeout(120_000)
        open_dashboard(page, url)
    # a long job (Index statistics at the papers' sizes) runs ...
    open_tab(a, "Index statistics")
    a.locator(".mv-table1 table").wait_for()  # the quick tables, computed on opening
    a.locator(".mv-statistics-size .bk-btn", has_text="papers").click()
    a.locator(".mv-statistics-run button").click()
    a.locator(".mv-job-cancel button").wait_for()
    a.get_by_text(re.compile(r"Table 3: random queries on the upper index … \d+ %")).wait_for()
    # ... so another session's job waits, its place shown
    open_tab(b, "Correlations")  # opening the tab queues its default computation
    b.get_by_text("Pose-based, 6 measures: waiting, number 1 in the queue").wait_for()
    # Cancel stops the running job between two of its steps; the waiting one then runs
    t0 = time.perf_counter()
    a.locator(".mv-job-cancel button").click()
    a.get_by_text("Table 3: random queries on the upper index: cancelled").wait_for()
    record_timing("job_cancel_s", time.perf_counter() - t0, "s from Cancel to the job stopped")
    quick = f"{statistics.QUERIES:,} queries per (mode, L)"  # the quick Table 3 stays: none of the papers' size
    assert a.locator(".mv-table3 table").first.is_visible() and a.get_by_text(quick).count() == 1
    b.locator(".mv-values-pose").first.wait_for()
    b.locator(".mv-values-segment").first.wait_for()
    assert "job cancelled after" in log.read_text()

    # a session that goes away takes its job with it
    a.locator(".mv-statistics-run button").click()
    a.get_by_text(re.compile(r"Table 3: random queries on the upper index … \d+ %")).wait_for()
    first.close()
    t0 = time.perf_counter()
    # the server ends a closed session 15-17 s after its browser went (CLOSED_SESSION_LIFETIME_MS): Table 3 may have
    # finished by then (16 s on a quick machine) and the run gone on to Table 1; whichever runs is cancelled ...
    text = _log_until(log, r"job cancelled after [\d.]+ s: Table \d", times=2, timeout=60)
    record_timing("abandoned_job_stop_s", time.perf_counter() - t0, "s from closing the browser to the job stopped")
    assert text.count("job cancelled after") == 2
    time.sleep(2 * POLL_S + 1)  # ... and the run stops there: no table of that session starts after it
    last = log.read_text()
    assert "job started: Table" not in last[last.rindex("job cancelled after"):], last[-1500:]
    second.close()
