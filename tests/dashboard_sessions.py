"""Simultaneous browser sessions of one served dashboard (Playwright's async API, one context per session): each runs
a scripted round of every page and checks that every answer it sees is the one of its own query.

Used by tests/test_app_sessions.py on the embedded sample; runs on any served database (a script can drive a large
one the same way). Debian's Chromium only, never `playwright install`.
"""

from __future__ import annotations

import asyncio
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

KINDS = ("open", "row_click", "search", "knn", "relational", "template", "describe")
TIMEOUT_MS = 600_000  # a loaded 2-core machine serving 8 sessions answers slowly: measured, not bounded here


@dataclass
class Query:
    """What one session asks: its document (name, frames), the hit count of the Relational query page's default
    query of its whole clip, the class of its motion template, the Describe page's K and its expected hit count."""

    doc_id: int
    name: str
    n_frames: int
    relational_hits: int
    template_label: str
    k: int
    describe_hits: int


@dataclass
class Rounds:
    """The seconds of each answer per kind, the errors seen (console errors, uncaught exceptions, wrong answers)
    and the open browser contexts (closed by :func:`close`)."""

    seconds: dict = field(default_factory=lambda: {kind: [] for kind in KINDS})
    errors: list = field(default_factory=list)
    contexts: list = field(default_factory=list)

    def percentile(self, kind: str, q: float) -> float:
        return float(np.percentile(self.seconds[kind], q))


async def _tab(page, name: str) -> None:
    await page.locator(".mv-tabs .bk-tab", has_text=name).click()


async def _timed(rounds: Rounds, kind: str, action, shown) -> None:
    """Seconds from ``action()`` (a click, a page load) until the locator ``shown`` is visible."""
    t0 = time.perf_counter()
    await action()
    await shown.wait_for(timeout=TIMEOUT_MS)
    rounds.seconds[kind].append(time.perf_counter() - t0)


async def session_round(browser, url: str, q: Query, rounds: Rounds) -> None:
    """One session: open the dashboard, choose ``q``'s document, search its whole clip (DTW) and the kNN of its first
    frame, run the relational query by example on it, learn and search the template of ``q.template_label``, find the
    Describe page's example with K = ``q.k``, then open Index statistics and Correlations (which answer on opening
    with their default computations, jobs queued one at a time, the answers shared by the sessions). Every answer is waited for by text naming the session's own query; the context stays
    open (in ``rounds.contexts``)."""
    context = await browser.new_context(viewport={"width": 1400, "height": 1000})
    rounds.contexts.append(context)
    page = await context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    who = f"session of document {q.doc_id}"
    page.on("pageerror", lambda e: rounds.errors.append(f"{who}: uncaught {e}\n{e.stack}"))
    page.on("console", lambda m: rounds.errors.append(f"{who}: console {m.text} at {m.location.get('url')}")
            if m.type == "error" else None)  # fmt: skip

    await _timed(rounds, "open", lambda: page.goto(url), page.locator(".mv-player canvas[data-drawn]").first)
    row = page.locator(".mv-documents .tabulator-cell[tabulator-field='name']").get_by_text(q.name, exact=True)
    await row.wait_for()
    await _timed(rounds, "row_click", row.click,
                 page.locator(".mv-player-caption", has_text=re.compile(rf"of {q.n_frames} ")).first)

    await _tab(page, "Similarity search")
    await page.locator(".mv-similarity-query", has_text=f"document {q.doc_id} ({q.name})").wait_for()
    await _timed(rounds, "search", page.locator(".mv-search-run button").click,
                 page.locator(".mv-search-count", has_text=f"like document {q.doc_id} frames 0:{q.n_frames} "))
    await _timed(rounds, "knn", page.locator(".mv-knn-search button").click,
                 page.locator(".mv-knn-count", has_text=f"of document {q.doc_id} frame 0 "))

    await _tab(page, "Relational query")
    await page.locator(".mv-hit-caption", has_text=q.name).wait_for()
    # the library's count of the page's default query of this clip ("N hits for ..."; 12 must not match 112)
    await _timed(rounds, "relational", page.locator(".mv-run button").click,
                 page.locator(".mv-hit-count", has_text=re.compile(rf"(^|\D){q.relational_hits} hits? for ")))
    if not await page.locator(".mv-hit-caption", has_text=q.name).count():
        rounds.errors.append(f"{who}: the relational query's clip changed")

    await _tab(page, "Motion templates")
    await page.locator(".mv-templates-class select").select_option(q.template_label)
    await _timed(rounds, "template", page.locator(".mv-templates-run button").click,
                 page.locator(".mv-templates-count", has_text=f"of the {q.template_label} template"))

    await _tab(page, "Describe")
    await page.locator(".mv-describe-find button:not([disabled])").wait_for()
    box = page.locator(".mv-describe-k input")
    await box.fill(str(q.k))
    await box.press("Enter")
    await _timed(rounds, "describe", page.locator(".mv-describe-find button").click,
                 page.locator(".mv-describe-count",
                              has_text=re.compile(rf"(^|\D){q.describe_hits} hits? \(K = {q.k};")))

    await _tab(page, "Index statistics")
    await page.locator(".mv-table1 table").first.wait_for()
    await _tab(page, "Correlations")
    await page.locator(".mv-heatmap-segment canvas").first.wait_for()


async def _run(chromium: Path, args: list, url: str, queries: list, rounds: Rounds, hold) -> None:
    from playwright.async_api import async_playwright

    async with async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(chromium), args=args)
        results = await asyncio.gather(*[session_round(browser, url, q, rounds) for q in queries],
                                       return_exceptions=True)  # fmt: skip
        rounds.errors.extend(f"{q.name}: {type(r).__name__}: {r}" for q, r in zip(queries, results)
                             if isinstance(r, BaseException))  # fmt: skip
        hold()  # the sessions are open: measure the server now
        for context in rounds.contexts:
            await context.close()
        await browser.close()


def run_sessions(chromium: Path, args: list, url: str, queries: list, hold=lambda: None) -> Rounds:
    """Run :func:`session_round` of every query at once, one browser context each, in a thread of its own (the async
    Playwright API apart from any sync one of the caller); ``hold()`` is called while all the sessions are still
    open, then they are closed. Returns the :class:`Rounds`."""
    rounds = Rounds()
    failure: list = []

    def main() -> None:
        try:
            asyncio.run(_run(chromium, args, url, queries, rounds, hold))
        except BaseException as exc:  # noqa: BLE001 - reported by the caller
            failure.append(exc)

    thread = threading.Thread(target=main, name="sessions")
    thread.start()
    thread.join()
    if failure:
        raise failure[0]
    return rounds


def queries_of(db, docs) -> list[Query]:
    """One query per document of ``docs`` (one per session), with the hit counts the library gives for it: the
    relational query's count of the page's default query of the whole clip, the Describe page's example with
    K = 1, 2, 3, 4, 1, ... in turn."""
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages import describe, relational

    backend = Backend(db)
    out = []
    for i, doc in enumerate(docs):
        row = db.document(doc)
        n, k = int(row["n_frames"]), 1 + i % 4
        found = describe.search(backend, describe.EXAMPLE, "2005", k)
        hits = relational.search(backend, relational.first_query(backend, doc))  # what the page's Run shows
        out.append(Query(doc, str(row["name"]), n, len(hits), str(row["label"]), k, len(found)))
    return out


def rss_mb(pid: int) -> float:
    """The resident set size of process ``pid`` (MB), from /proc."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")
