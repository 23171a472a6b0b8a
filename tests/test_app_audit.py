"""The dashboard's Audit page (issue 41 item 4), in headless Chromium and without a browser, on a copy of the demo with
a planted copy: document 54 is the left/right mirror image of document 45 (CMU 135_04, a front kick, 11 s at 30 Hz)
appended to it. What the page shows and downloads is the engine's audit of the same database, computed here."""

from __future__ import annotations

import io
import shutil
import time

import numpy as np
import pandas as pd
import pytest
from browser_helpers import open_dashboard, open_tab, page_text, run_in_thread, text_of

from mocapviz import MotionDB
from mocapviz.app.backend import Backend
from mocapviz.app.pages import audit as audit_page
from mocapviz.app.state import Selection
from mocapviz.engine import Engine
from mocapviz.engine.parameters import PARAMETERS
from mocapviz.motion.skeleton import mirror

WAIT_MS = 240_000  # the server shares two cores with other test runs
PLANTED = 45  # the demo's CMU 135_04; its mirror image is appended as the new last document
PAIR = ["doc_a", "start_a", "end_a", "doc_b", "start_b", "end_b", "mirrored"]


@pytest.fixture(scope="module")
def audit_db(tmp_path_factory) -> MotionDB:
    """A copy of the demo with the mirror image of document 45 appended (document 54, "mirror_of_45")."""
    path = tmp_path_factory.mktemp("audit") / "demo.mdb"
    shutil.copytree(MotionDB.demo().path, path)
    db = MotionDB.open(path)
    db.append_motions([mirror(db.motion(PLANTED))], [{"name": f"mirror_of_{PLANTED}"}])
    return MotionDB.open(path)


@pytest.fixture(scope="module")
def expected(audit_db):
    """The engine's audit of :func:`audit_db` with its defaults (the threshold learned) and what keep-one leaves."""
    engine = Engine(audit_db)
    pairs = engine.audit()
    return pairs, engine.keep_one(pairs)


def _planted(audit_db) -> int:
    return int(audit_db.documents["doc_id"].iloc[-1])


def _shown_pairs(page) -> list[dict]:
    """The rows of the pair table on its first page: {field: text}."""
    rows = page.locator(".mv-audit-table .tabulator-row")
    rows.first.wait_for(timeout=WAIT_MS)
    return rows.evaluate_all("""rs => rs.map(r => Object.fromEntries([...r.querySelectorAll('.tabulator-cell')]
        .map(c => [c.getAttribute('tabulator-field'), c.textContent.trim()])))""")


def _wait_summary(page, text: str) -> str:
    page.locator(".mv-audit-summary").get_by_text(text).first.wait_for(timeout=WAIT_MS)
    return text_of(page, ".mv-audit-summary")


def _download(page, css: str) -> pd.DataFrame:
    with page.expect_download(timeout=WAIT_MS) as info:
        page.locator(f"{css} button").click()
    return pd.read_csv(info.value.path())


# ============================================================================ in the browser
@pytest.mark.slow
def test_the_audit_shows_the_planted_mirror_and_keeps_one_of_each_cluster(audit_db, expected, serve_dashboard, page,
                                                                          screenshot):  # fmt: skip
    pairs, kept = expected
    planted = _planted(audit_db)
    open_dashboard(page, serve_dashboard(audit_db.path))
    open_tab(page, "Audit")  # the page answers when first shown: the engine's defaults, the threshold learned
    summary = _wait_summary(page, "cluster")
    assert summary.startswith(f"{len(pairs)} pair") and f"threshold {pairs.attrs['threshold']:.2f} cm (learned" in summary
    assert f"{pairs['cluster'].nunique()} cluster" in summary and f"{int(pairs['mirrored'].sum())} mirrored" in summary
    assert f"Keep-one leaves {len(kept)} documents" in summary

    shown = _shown_pairs(page)
    assert len(shown) == min(len(pairs), 10)
    want = pairs.head(10)
    assert [(int(r["doc_a"]), int(r["start_a"]), int(r["doc_b"]), int(r["start_b"])) for r in shown] == list(
        zip(want["doc_a"], want["start_a"], want["doc_b"], want["start_b"]))
    row = next(i for i, r in enumerate(shown) if {int(r["doc_a"]), int(r["doc_b"])} == {PLANTED, planted})
    assert shown[row]["mirrored"] == "mirrored"

    # the pair table and the keep-one list as CSV: the engine's
    got = _download(page, ".mv-audit-pairs-csv")
    pd.testing.assert_frame_equal(got[PAIR], pairs[PAIR].reset_index(drop=True), check_dtype=False)
    documents = _download(page, ".mv-audit-keep-csv")
    clusters = pairs.groupby("cluster").apply(lambda g: len(set(g["doc_a"]) | set(g["doc_b"])))
    assert documents["doc_id"].tolist() == kept["doc_id"].tolist()
    assert len(documents) == len(audit_db) - int((clusters - 1).sum())  # one of each cluster kept
    assert len({PLANTED, planted} & set(documents["doc_id"])) == 1

    # the planted pair played: its two stretches side by side, the mirrored side said so
    page.locator(".mv-audit-table .tabulator-row").nth(row).locator(".tabulator-cell[tabulator-field='name_a']").click()
    page.locator(".mv-audit-player canvas[data-drawn]").first.wait_for(timeout=WAIT_MS)
    playing = text_of(page, ".mv-audit-playing")
    assert f"document {PLANTED} (135_04)" in playing and "(mirrored)" in playing, playing
    steps = len(Engine(audit_db).audit_path(pairs.iloc[row]))  # the table shows the pairs in the engine's order
    assert f"aligned on the pair's warping path ({steps} steps)" in playing, playing
    screenshot("audit")

    # a threshold of its own: the table follows the engine's audit with it
    threshold = round(pairs.attrs["threshold"] / 2, 2)
    box = page.locator(".mv-audit-threshold input")
    box.fill(str(threshold))
    box.press("Enter")
    page.locator(".mv-audit-run button").click()
    given = Engine(audit_db).audit(threshold=threshold)
    summary = _wait_summary(page, "(given)")
    assert summary.startswith(f"{len(given)} pair") and f"threshold {threshold:.2f} cm (given)" in summary


@pytest.mark.slow
def test_an_audit_waiting_behind_another_job_is_cancelled(audit_db, expected, serve_dashboard, page):
    """The statistics page's papers' sizes hold the server's one job slot: the audit waits in the queue, its Cancel
    takes it out (no table shown); once the statistics are cancelled too, Run audits."""
    open_dashboard(page, serve_dashboard(audit_db.path))
    open_tab(page, "Index statistics")
    page.locator(".mv-table1 table").first.wait_for(timeout=WAIT_MS)  # its quick first answer, done
    page.locator(".mv-statistics-size button", has_text="papers").click()
    page.locator(".mv-statistics-run button").click()
    deadline = time.monotonic() + WAIT_MS / 1000
    while "Table 3: random queries on the upper index …" not in page_text(page) and time.monotonic() < deadline:
        time.sleep(0.2)  # the long job runs (10,000 queries per row)
    open_tab(page, "Audit")  # its first answer is queued behind it
    status = page.locator(".mv-audit-task").get_by_text("waiting, number 1 in the queue")
    status.wait_for(timeout=WAIT_MS)
    page.locator(".mv-audit-task .mv-job-cancel button").click()
    page.locator(".mv-audit-task").get_by_text("Auditing the database: cancelled").wait_for(timeout=WAIT_MS)
    assert text_of(page, ".mv-audit-summary") == "" and page.locator(".mv-audit-table .tabulator-row").count() == 0

    open_tab(page, "Index statistics")
    page.locator(".mv-job-cancel button").filter(visible=True).click()
    page.get_by_text("Table 3: random queries on the upper index: cancelled").wait_for(timeout=WAIT_MS)
    open_tab(page, "Audit")
    page.locator(".mv-audit-run button").click()
    summary = _wait_summary(page, "cluster")
    assert summary.startswith(f"{len(expected[0])} pair")


# ============================================================================ without a browser
def test_the_widgets_are_the_parameter_tables_and_run_shows_the_engines_audit(audit_db, expected):
    page = audit_page.AuditPage(Backend.open(audit_db.path), Selection())
    for box, name in ((page.min_length, "audit_length"), (page.max_scale, "max_scale")):
        p = PARAMETERS[name]
        assert (box.value, box.start, box.end) == (p.default, p.low, p.high), name
    threshold = PARAMETERS["threshold"]
    assert page.threshold.value is None and page.threshold.optional and threshold.optional
    assert page.threshold.start == threshold.low + page.threshold.step and page.threshold.end is None  # (0, inf)
    assert page.numeric_set.options == list(PARAMETERS["audit_set"].choices)
    assert page.numeric_set.value == PARAMETERS["audit_set"].default
    assert page.mirrored.value is PARAMETERS["mirrored"].default

    run_in_thread(page.first_answer())
    pairs, kept = expected
    assert page.pairs[PAIR].equals(pairs[PAIR]) and page.kept["doc_id"].tolist() == kept["doc_id"].tolist()
    assert page.table.value["mirrored"].tolist() == ["mirrored" if m else "" for m in pairs["mirrored"]]
    clusters = page.clusters.value
    assert len(clusters) == pairs["cluster"].nunique()
    assert all(len(k.split(", ")) == 1 for k in clusters["kept"])  # keep-one keeps one document of each cluster
    csv = pd.read_csv(io.BytesIO(page.kept_download.callback().getvalue()))
    assert csv["doc_id"].tolist() == kept["doc_id"].tolist()

    planted = _planted(audit_db)  # a pair chosen plays on the engine's warping path of it
    row = next(i for i, (a, b) in enumerate(zip(pairs["doc_a"], pairs["doc_b"])) if {a, b} == {PLANTED, planted})
    page.table.selection = [row]
    path = Engine(audit_db).audit_path(pairs.iloc[row])
    assert page.player_box.visible and np.array_equal(page.player._alignment, path)
    assert f"warping path ({len(path)} steps)" in page.playing.object

    page.mirrored.value = False  # the widgets' values are what runs
    run_in_thread(page._run())
    assert not page.pairs["mirrored"].any() and page.pairs.attrs["threshold"] == pairs.attrs["threshold"]
