"""Takes added while the dashboard serves the database (issue 40 item 2), with real processes: ``mocapviz ingest``
run as a process of its own into the database that ``mocapviz serve`` serves (another process) or that a Backend of
this process follows. The server switches to the new generation by itself (mocapviz.app.backend.Backend.follow):
an open session's document picker offers the new take and a search from the Similarity page finds it, a new
session's Database page lists it; a query running while the ingest commits finishes with the old generation's answer.
The ingest brings the stored indexes and feature sets up to date incrementally and says so. ~40 s (the server's
start and warm-up on the demo, two ingests of one CMU take)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import threading
import time

import pytest
from browser_helpers import open_dashboard, open_tab
from playwright.sync_api import TimeoutError as PlaywrightTimeout
from playwright.sync_api import expect

from mocapviz import MotionDB, load
from mocapviz.app.backend import FOLLOW_SECONDS, Backend
from mocapviz.app.documents import DocumentPicker
from mocapviz.relational import query as relational_query
from mocapviz.relational.index import build
from mocapviz.relational.index import load as load_index

pytestmark = pytest.mark.slow
SEEN_WITHIN_S = 4 * FOLLOW_SECONDS + 20  # the server reads the manifest every FOLLOW_SECONDS, then extends and warms
FEATURES = ["rknee_bent", "lknee_bent", "rhand_fast"]


@pytest.fixture
def demo_copy(tmp_path):
    """A copy of the demo (54 documents at 30 Hz) with its 2005 relational index stored."""
    db = MotionDB.open(shutil.copytree(MotionDB.demo().path, tmp_path / "demo.mdb"))
    build(db, "2005", progress=False)
    return db


@pytest.fixture
def take(cmu_dir):
    """A CMU take the demo does not hold (modern dance md_03, 434 frames at 120 Hz; its ASF in the archive)."""
    return cmu_dir / "amc" / "moderndance" / "md_03.amc"


def _ingest(take, db) -> str:
    """``mocapviz ingest TAKE --out DB`` as a process of its own; its standard output."""
    done = subprocess.run([sys.executable, "-m", "mocapviz.cli", "ingest", str(take), "--out", str(db.path), "--quiet"],
                          check=False, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_a_served_database_shows_a_take_ingested_meanwhile(demo_copy, take, serve_dashboard, page, browser):
    url = serve_dashboard(demo_copy.path)
    open_dashboard(page, url)
    open_tab(page, "Relational query")  # an open session, its document picker made before the ingest
    page.locator(".mv-run button:not([disabled])").wait_for(timeout=300_000)
    new = len(demo_copy)  # the id of the new document (ids count from 0)
    out = _ingest(take, demo_copy)
    assert f"{new + 1} documents" in out  # its index extended by the ingest, or already by the server that followed
    assert re.search(r"relational index 2005: (extended \(1 document, \d+ frames|current)", out), out
    assert load_index(MotionDB.open(demo_copy.path), "2005")["lower"].meta["n_documents"] == new + 1
    _offered(page, new, "md_03")  # (a): the open session's picker offers it once the server has followed
    expect(page.locator(".mv-query-span-info")).to_contain_text("of md_03")  # the session's clip now
    open_tab(page, "Similarity search")  # a search of the new take, its own document allowed, finds it first
    page.locator(".mv-exclude-own input").uncheck()
    page.locator(".mv-search-run button").click()
    expect(page.locator(".mv-search-table .tabulator-row").first).to_contain_text("md_03", timeout=60_000)
    fresh = browser.new_page()  # a new session: its Database page lists the new take
    try:
        open_dashboard(fresh, url)
        fresh.locator(".mv-filter-text input").fill("md_03")
        expect(fresh.locator(".mv-doc-count")).to_contain_text(f"1 of {new + 1} documents")
        expect(fresh.locator(".mv-documents").get_by_text("md_03", exact=True)).to_be_visible()
    finally:
        fresh.close()
    assert "followed in" in serve_dashboard.log_of(url).read_text()


def _offered(page, doc: int, name: str) -> None:
    """Choose ``doc`` in the Relational page's picker, typing its name again until the picker offers it (at most
    :data:`SEEN_WITHIN_S` seconds after the ingest)."""
    deadline = time.monotonic() + SEEN_WITHIN_S
    match = page.locator(".mv-query-doc .bk-menu > div", has_text=re.compile(rf"^{doc}: {name}"))
    while True:
        box = page.locator(".mv-query-doc input")
        box.fill("")
        box.press_sequentially(name)
        try:
            match.first.click(timeout=2000)
            return
        except PlaywrightTimeout:
            assert time.monotonic() < deadline, f"the picker did not offer {doc}: {name} within {SEEN_WITHIN_S} s"


def test_a_query_running_while_the_ingest_commits_answers_from_the_old_generation(demo_copy, take, monkeypatch):
    backend = Backend(demo_copy)
    new = len(demo_copy)  # the id the ingested take gets
    picker = DocumentPicker(backend, "query clip", 0)
    example = load(take).canonical()[0:60]
    before = backend.engine.query(example, features=FEATURES, mode="adaptive")
    started, commit_done = threading.Event(), threading.Event()
    original = relational_query.example_hits

    def paused(*args, **kwargs):  # the query waits inside the engine until the ingest has committed
        started.set()
        assert commit_done.wait(120)
        return original(*args, **kwargs)

    monkeypatch.setattr(relational_query, "example_hits", paused)
    answer = {}
    running = threading.Thread(target=lambda: answer.update(hits=backend.engine.query(example, features=FEATURES,
                                                                                    mode="adaptive")))  # fmt: skip
    running.start()
    assert started.wait(60)
    _ingest(take, demo_copy)
    assert backend.follow()  # switched while the query runs on the old engine
    commit_done.set()
    running.join(120)
    monkeypatch.setattr(relational_query, "example_hits", original)
    assert answer["hits"].equals(before) and (answer["hits"]["doc_id"] < new).all()
    after = backend.engine.query(example, features=FEATURES, mode="adaptive")
    assert new in set(after["doc_id"]) and set(before["doc_id"]) <= set(after["doc_id"])
    assert len(backend.documents) == new + 1 and picker.options == backend.doc_options()  # the picker told
    assert load_index(backend.db, "2005")["lower"].meta["n_documents"] == new + 1  # the ingest extended the stored index
    assert not backend.follow()  # nothing newer
