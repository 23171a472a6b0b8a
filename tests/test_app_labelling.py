"""Segment labels written from the dashboard (issue 40 items 3 and 4), in headless Chromium on a served copy of the
demo whose actors mm and tr carry no class (:func:`mocapviz.experiments.annotation.annotator_view`), served with
``--auth``: alice may annotate, carol is an admin, bob may only read.

Every check reads the labels back from the database folder (``Engine(db).segment_labels()``): ✓ and ✗ on the
Similarity table and gallery, "accept page", "undo", "label this span" on the Database page (its strip and count),
two sessions labelling at once, no button for a reader, and the labelling loop of the Motion templates page: two
review rounds of kickLFront1Reps by the true classes, the second round's template more precise among the reviewed
documents (1 of 2, then 2 of 3; measured beforehand with the annotation experiment's calls: review_page, K = 3).
The browser tests take about 45 s with the server's start (marked slow); one fast test without a browser checks the
Database page's count column, its strip and that an open page's table follows a clip added to its database.
"""

from __future__ import annotations

import re
import shutil

import pytest
from browser_helpers import open_tab
from playwright.sync_api import expect

from mocapviz import Engine, MotionDB, users
from mocapviz.app.backend import Backend
from mocapviz.app.gallery import CELL, REVIEW_BOX
from mocapviz.app.pages.database import LABELS, DatabasePage, lanes, segment_strip
from mocapviz.app.state import Selection
from mocapviz.experiments.annotation import annotator_view

HIDDEN = ("mm", "tr")  # the actors whose clips carry no class in the served copy
CLASS, K = "kickLFront1Reps", 3  # the loop's class and page size
USERS = {"alice": ("alice's passphrase", "annotate"), "bob": ("bob's passphrase", "read"),
         "carol": ("carol's passphrase", "admin")}  # fmt: skip
SECRET = "the labelling test's cookie secret, at least 32 characters"


@pytest.fixture(scope="module")
def lab(tmp_path_factory, serve_dashboard):
    """(url, database folder, true classes by doc id) of the served annotator's view of the demo."""
    folder = tmp_path_factory.mktemp("labelling")
    demo = MotionDB.demo()
    docs = demo.documents
    hidden = docs.loc[docs["actor"].isin(HIDDEN).fillna(False).to_numpy(bool), "doc_id"]
    view = annotator_view(demo, hidden, folder / "lab.mdb")
    for name, (password, role) in USERS.items():
        users.add_user(folder / "users.json", name, password, role)
    (folder / "secret").write_text(SECRET + "\n")
    url = serve_dashboard(view.path, "--auth", str(folder / "users.json"), "--cookie-secret-file",
                          str(folder / "secret"))  # fmt: skip
    return url, view.path, docs.set_index("doc_id")["label"]


def _labels(db_path, label=None):
    return Engine(MotionDB.open(db_path)).segment_labels(label=label)


def _sign_in(page, url: str, name: str) -> None:
    page.goto(url)
    page.fill("#username", name)
    page.fill("#password", USERS[name][0])
    page.click("#sign-in")
    page.locator(".mv-player canvas[data-drawn]").first.wait_for(state="visible")


def _rows(page, css: str, n: int):
    """The first ``n`` rows of a result table, once shown, and their hits (doc_id, start, end)."""
    rows = page.locator(f"{css} .tabulator-row")
    rows.nth(n - 1).wait_for()

    def number(row, field: str) -> int:
        return int(row.locator(f".tabulator-cell[tabulator-field={field}]").inner_text().replace(",", ""))

    return rows, [tuple(number(rows.nth(i), f) for f in ("doc_id", "start", "end")) for i in range(n)]


def _click(rows, i: int, mark: str) -> None:
    rows.nth(i).locator(".tabulator-cell", has_text=mark).click()


def _state(rows, i: int):
    return rows.nth(i).locator(".tabulator-cell[tabulator-field=review]")


def _reviews(db_path, label: str) -> dict:
    """{(doc, start, end): (source, author)} of the label's accepted and rejected hits."""
    t = _labels(db_path, label)
    return {(int(d), int(a), int(b)): (s, w) for d, a, b, s, w in zip(t["doc_id"], t["start"], t["end"], t["source"],
                                                                        t["author"])}  # fmt: skip


def _cell_button(i: int, verdict: str) -> dict:
    """The position on the gallery's canvas of cell ``i``'s ✓ ("accept") or ✗ ("reject") button (gallery.js)."""
    x = (i % 8) * CELL[0] + CELL[0] - (2 * REVIEW_BOX + 8 if verdict == "accept" else REVIEW_BOX + 4)
    return {"x": x + REVIEW_BOX / 2, "y": (i // 8) * CELL[1] + 4 + REVIEW_BOX / 2}


@pytest.mark.slow
def test_accept_reject_accept_page_and_undo_on_the_similarity_page(lab, page):
    url, db, truth = lab
    _sign_in(page, url, "alice")
    open_tab(page, "Similarity search")
    rows, hits = _rows(page, ".mv-search-table", 10)
    label = page.locator(".mv-search-gallery-label input").input_value()
    assert label == truth[0]  # the query clip's class (the session's document 0)
    _click(rows, 0, "✓")
    expect(_state(rows, 0)).to_have_text("accepted")
    _click(rows, 1, "✗")
    expect(_state(rows, 1)).to_have_text("rejected")
    assert _reviews(db, label) == {hits[0]: ("accepted hit", "alice"), hits[1]: ("rejected hit", "alice")}

    page.locator(".mv-search-gallery-mode .bk-btn", has_text="Gallery").click()
    canvas = page.locator(".mv-search-gallery canvas")
    expect(canvas).to_have_attribute("data-states", "accepted,rejected" + "," * 8)
    canvas.click(position=_cell_button(2, "reject"))
    expect(canvas).to_have_attribute("data-states", "accepted,rejected,rejected" + "," * 7)
    canvas.click(position=_cell_button(1, "accept"))  # the other verdict: the rejected label goes
    expect(canvas).to_have_attribute("data-states", "accepted,accepted,rejected" + "," * 7)
    assert _reviews(db, label) == {hits[0]: ("accepted hit", "alice"), hits[1]: ("accepted hit", "alice"),
                                   hits[2]: ("rejected hit", "alice")}  # fmt: skip

    page.locator(".mv-search-gallery-accept-page button").click()
    expect(canvas).to_have_attribute("data-states", ",".join(["accepted"] * 10))
    assert _reviews(db, label) == dict.fromkeys(hits, ("accepted hit", "alice"))

    page.locator(".mv-search-gallery-undo button").click()  # alice's last change: the page's last hit added
    expect(canvas).to_have_attribute("data-states", ",".join(["accepted"] * 9) + ",")
    assert _reviews(db, label) == dict.fromkeys(hits[:9], ("accepted hit", "alice"))
    last = Engine(MotionDB.open(db)).label_history().iloc[-1]
    assert last["author"] == "alice" and last["undoes"] == len(Engine(MotionDB.open(db)).label_history()) - 1


@pytest.mark.slow
def test_label_a_span_on_the_database_page(lab, page):
    url, db, _ = lab
    _sign_in(page, url, "alice")
    n = int(MotionDB.open(db).document(0)["n_frames"])
    handle = page.locator(".mv-span .noUi-handle-lower")
    handle.focus()
    for _ in range(5):
        handle.press("ArrowRight")
    page.locator(".mv-span-label input").fill("arms up")
    page.locator(".mv-span-label input").press("Enter")
    page.locator(".mv-label-span button").click()
    page.locator(".mv-label-span-status", has_text="labelled").wait_for()
    spans = _labels(db, "arms up")
    assert spans[["doc_id", "start", "end", "source", "author"]].values.tolist() == [[0, 5, n, "manual", "alice"]]
    segment = page.locator('.mv-segment-labels .mv-segment[data-label="arms up"]')
    expect(segment).to_have_attribute("data-start", "5")
    expect(segment).to_have_attribute("data-end", str(n))  # half-open: the clip's last frame is n - 1
    count = page.locator(".mv-documents .tabulator-row").first.locator('[tabulator-field="segment labels"]')
    every = _labels(db)
    expect(count).to_have_text(str(int(((every["doc_id"] == 0) & (every["source"] != "rejected hit")).sum())))


@pytest.mark.slow
def test_two_sessions_label_at_once(lab, page, browser):
    url, db, _ = lab
    other = browser.new_context(viewport={"width": 1400, "height": 1000}).new_page()
    other.set_default_timeout(60_000)
    tables = []
    for pg, name in ((page, "alice"), (other, "carol")):
        _sign_in(pg, url, name)
        open_tab(pg, "Similarity search")
        pg.locator(".mv-search-gallery-label input").fill("two sessions")
        pg.locator(".mv-search-gallery-label input").press("Enter")
        tables.append(_rows(pg, ".mv-search-table", 6))
    (alice_rows, hits), (carol_rows, _) = tables
    _click(alice_rows, 4, "✓")  # both clicks sent before either answer is awaited
    _click(carol_rows, 5, "✗")
    expect(_state(alice_rows, 4)).to_have_text("accepted")
    expect(_state(carol_rows, 5)).to_have_text("rejected")
    other.context.close()
    assert _reviews(db, "two sessions") == {hits[4]: ("accepted hit", "alice"), hits[5]: ("rejected hit", "carol")}


@pytest.mark.slow
def test_a_reader_sees_no_review_buttons(lab, page):
    url, _, _ = lab
    _sign_in(page, url, "bob")
    expect(page.locator(".mv-documents .tabulator-row").first).to_be_visible()
    assert page.locator(".mv-label-span").count() == 0 and page.locator(".mv-span-label").count() == 0
    open_tab(page, "Similarity search")
    _rows(page, ".mv-search-table", 3)
    assert page.locator(".mv-search-table .tabulator-cell", has_text=re.compile("^[✓✗]$")).count() == 0
    assert page.locator(".mv-search-gallery-accept-page").count() == 0


@pytest.mark.slow
def test_the_loop_on_the_templates_page_raises_the_reviewed_precision(lab, page):
    url, db, truth = lab
    _sign_in(page, url, "alice")
    open_tab(page, "Motion templates")
    page.locator(".mv-templates-count", has_text="hits").wait_for()  # the page's opening answer
    page.locator(".mv-templates-class select").select_option(CLASS)
    expect(page.locator(".mv-templates-gallery-label input")).to_have_value(CLASS)
    k = page.locator(".mv-templates-k input")
    k.fill(str(K))
    k.press("Enter")
    unlabelled = set(MotionDB.open(db).documents.query("label.isna()")["doc_id"])
    for round_, precision in ((1, "0.50"), (2, "0.67")):
        page.locator(".mv-templates-round button").click()
        page.locator(".mv-templates-count", has_text=f"Round {round_}").wait_for()
        rows, hits = _rows(page, ".mv-templates-table", K)
        assert {d for d, _, _ in hits} <= unlabelled
        for i, (doc, _, _) in enumerate(hits):  # the oracle: the true class
            right = truth[doc] == CLASS
            _click(rows, i, "✓" if right else "✗")
            expect(_state(rows, i)).to_have_text("accepted" if right else "rejected")
        table = page.locator(".mv-templates-rounds table tbody tr")
        expect(table.nth(round_ - 1).locator("td").last).to_have_text(precision)
    reviews = _reviews(db, CLASS)
    assert all((truth[d] == CLASS) == (s == "accepted hit") for (d, _, _), (s, _) in reviews.items())


def test_the_database_table_counts_labels_and_follows_new_documents(tmp_path):
    """Without a browser: the documents table's count column, the strip's spans, and an open page's table and
    filters after a clip is added to the database it shows (Backend.follow, as while serving)."""
    db = MotionDB.open(shutil.copytree(MotionDB.demo().path, tmp_path / "demo.mdb"))
    engine = Engine(db)
    engine.add_label(3, frames=(2, 12), label="reach", author="ann")
    engine.add_label(3, frames=(5, 9), label="grab", author="ann")
    engine.add_label(5, frames=(0, 4), label="reach", author="ann", source="rejected hit")  # not counted
    backend = Backend.open(db.path)
    page = DatabasePage(backend, Selection(doc=3))
    counts = page.table.value.set_index("doc_id")[LABELS]
    assert (counts[3], counts[5], int(counts.sum())) == (2, 0, 2)
    strip = segment_strip(engine.segment_labels().query("doc_id == 3"), 19, 30.0)
    assert strip.count('class="mv-segment"') == 2 and 'data-start="5" data-end="9"' in strip
    assert lanes([2, 5], [12, 9]) == [0, 1]  # the two overlap: one under the other

    n = len(page.table.value)
    row = db.documents.iloc[0].to_dict()
    meta = {k: v for k, v in row.items() if k not in ("doc_id", "start", "n_frames", "fps")} | {"label": "a new class"}
    db.append_motions([db.motion(0)], [meta])
    assert backend.follow()
    assert len(page.table.value) == n + 1 and "a new class" in page.label_filter.options
