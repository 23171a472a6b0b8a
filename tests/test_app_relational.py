"""Browser tests of the dashboard's Relational query page (Müller, Röder & Clausen 2005 §5) in headless Chromium: the
hits shown are those of :func:`mocapviz.relational.query.query_by_example` for the query chosen through the widgets;
its boxes' notes without a browser. Then, without a browser, the page's default query: the suggested query a new clip
ticks (its precision: tests/test_suggestion.py)."""

from __future__ import annotations

import re
import time

import pytest
from browser_helpers import (
    assert_no_exception_names,
    in_own_loop,
    open_dashboard,
    open_tab,
    pick_document,
    record_first_answer,
    record_timing,
    text_of,
    timed,
)
from playwright.sync_api import expect

from mocapviz.app.backend import Backend
from mocapviz.app.pages.relational import (
    DEFAULT_FEATURES,
    MODES,
    RelationalPage,
)
from mocapviz.app.state import Selection
from mocapviz.app.widgets import PAGE_SIZE
from mocapviz.engine import Engine
from mocapviz.features import feature_groups
from mocapviz.relational import index
from mocapviz.relational.query import query_by_example
from mocapviz.validation import plural

COUNT = ".mv-hit-count"
KNEES = ["rknee_bent", "lknee_bent"]


def _open_page(page, url: str) -> None:
    """Open the Relational query tab and wait for its first answer (the session clip's suggested query, run on
    opening once the indexes are loaded) and Run enabled."""
    open_dashboard(page, url)
    open_tab(page, "Relational query")
    page.locator(".mv-hit-count", has_text=re.compile(r"hits? for ")).wait_for(timeout=600_000)
    page.locator(".mv-run button:not([disabled])").wait_for(timeout=600_000)


def _set_query(page, db, doc: int, span, features, mode: str, m: int = 1) -> None:
    """Choose the clip, span, ticked features and kind of hit through the page's widgets."""
    row = db.documents.set_index("doc_id").loc[doc]
    fps, info = float(row["fps"]), page.locator(".mv-query-span-info")
    pick_document(page, ".mv-query-doc", doc)
    expect(info).to_contain_text(f"{row['n_frames']} frames · 0.00–")  # the whole new clip, before the span changes
    expect(info).to_contain_text(f"of {row['name']}")
    page.locator(".mv-query-first input").fill(str(span[0]))
    page.locator(".mv-query-first input").press("Enter")
    expect(info).to_contain_text(f" · {span[0] / fps:.2f}–")  # wait for the server before the next change
    page.locator(".mv-query-last input").fill(str(span[1]))
    page.locator(".mv-query-last input").press("Enter")
    expect(info).to_contain_text(f"{span[1] - span[0] + 1} frames · {span[0] / fps:.2f}–{(span[1] + 1) / fps:.2f} s")
    for group, names in feature_groups("2005").items():
        for name in names:
            box = page.locator(f".mv-features-{group}").get_by_label(name, exact=True)
            if box.is_checked() != (name in features):
                box.click()
    page.locator(".mv-query-mode").get_by_role("button", name=mode, exact=True).click()
    if mode == "mismatch":
        page.locator(".mv-query-m input").fill(str(m))
        page.locator(".mv-query-m input").press("Enter")


def _shown_count(page) -> int:
    expect(page.locator(COUNT)).to_contain_text(re.compile(r"\d+ hits?"))
    return int(re.search(r"(\d+) hits?", text_of(page, COUNT)).group(1))


def _expected_hits(db, doc: int, span, features, mode: str, m: int = 1):
    """The library's hits of the page's query, without the query's own document (the engine's default, as on
    every page: exclude_document)."""
    hits = query_by_example(db, db.motion(doc)[span[0]:span[1] + 1], features, MODES[mode], m,
                            indexes=index.load(db))
    return hits[hits["doc_id"] != doc].reset_index(drop=True)


QUERIES = {
    "adaptive": (3, (5, 95), KNEES, "adaptive fuzzy", 1),  # elbowToKnee (dg): 13 hits on the sample
    "mismatch": (10, (0, 214), list(DEFAULT_FEATURES), "mismatch", 2),  # sneak2StepsLStart (dg), whole clip: 5
    # segments on the kick features, so m = 2 counts (throwBasketball has 1: any m is 0 there)
}


@pytest.mark.parametrize("name", list(QUERIES))
def test_query_shows_the_library_hits_and_plays_one(name, sample_db, sample_dashboard, page, screenshot):
    doc, span, features, mode, m = QUERIES[name]
    _open_page(page, sample_dashboard)
    _set_query(page, sample_db, doc, span, features, mode, m)
    t0 = time.perf_counter()
    page.locator(".mv-run button").click()
    kind = f"{MODES[mode]} hits" + (f" with m = {m}" if mode == "mismatch" else "")
    expect(page.locator(COUNT)).to_contain_text(kind)  # the query the server ran had the widgets' settings
    record_first_answer("relational", time.perf_counter() - t0)
    shown = _shown_count(page)
    expected = _expected_hits(sample_db, doc, span, features, mode, m)
    assert shown == len(expected) > 1
    rows = page.locator(".mv-hits .tabulator-row")
    expect(rows.first).to_be_visible()
    assert rows.count() == min(len(expected), PAGE_SIZE)  # one page of the table
    assert "Precision" in text_of(page, ".mv-hit-quality")
    screenshot(f"{name}-hits")
    target = expected.iloc[1]
    cell = rows.nth(1).locator('.tabulator-cell[tabulator-field="name"]')
    assert cell.inner_text().strip() == target["name"]
    canvas = page.locator(".mv-query-player .mv-player canvas")
    expect(canvas).to_have_attribute("data-clips", "1")  # the query alone
    cell.click()
    caption = page.locator(".mv-hit-caption")
    expect(caption).to_contain_text(f"beside hit 2: {target['name']}")
    expect(caption).to_contain_text(f"frames {target['start']}:{target['end']}")  # half-open, as in the table
    expect(canvas).to_have_attribute("data-clips", "2")  # query beside hit
    screenshot(f"{name}-hit-played")


def _entered(page, css: str, typed: str, shown: int, note: str) -> None:
    """Type ``typed`` into the number box ``css`` and press Enter: it shows ``shown``, its note says ``note``."""
    box = page.locator(f"{css} input")
    box.fill(typed)
    box.press("Enter")
    page.locator(".mv-input-note", has_text=note).first.wait_for()
    expect(box).to_have_value(str(shown))


def test_no_feature_says_so_and_out_of_range_entries_are_corrected(sample_db, sample_dashboard, page, screenshot):
    """Run without a ticked feature: a message, no query. Then frames outside the clip become its first or last
    frame, and m more than the query's segments less one becomes that: the boxes, the span and the query the server
    runs agree, and the message is gone."""
    doc, (first, last), m_most = 10, (0, 214), 4  # sneak2StepsLStart (dg): 215 frames, 5 segments on the kick
    _open_page(page, sample_dashboard)
    _set_query(page, sample_db, doc, (20, 100), [], "mismatch", 0)
    page.locator(".mv-run button").click()
    message = page.locator(".mv-query-message")
    expect(message).to_contain_text("Tick at least one feature")
    assert not page.locator(".mv-error").is_visible()  # validated before running: no exception shown
    assert_no_exception_names(page)
    assert text_of(page, COUNT) == ""
    screenshot("no-feature")

    for name in DEFAULT_FEATURES:
        page.locator(".mv-features-lower").get_by_label(name, exact=True).click()
    info = page.locator(".mv-query-span-info")
    _entered(page, ".mv-query-last", "99999", last, f"last frame must be 0–{last}: 99,999 was set to {last}.")
    _entered(page, ".mv-query-first", "-50", first, f"first frame must be 0–{last}: -50 was set to 0.")
    expect(info).to_contain_text(f"{last - first + 1} frames · 0.00–")
    expect(page.locator(".mv-query-span")).to_contain_text(f"{first} .. {last}")
    expect(page.locator(".mv-query-m")).to_contain_text(f"m mismatching segments (0–{m_most})")
    _entered(page, ".mv-query-m", "50", m_most, f"m mismatching segments must be 0–{m_most}: 50 was set to {m_most}.")
    _entered(page, ".mv-query-m", "", m_most, f"m mismatching segments was empty: set back to {m_most}.")
    page.locator(".mv-run button").click()
    expect(page.locator(COUNT)).to_contain_text(f"mismatch hits with m = {m_most}")
    expected = _expected_hits(sample_db, doc, (first, last), list(DEFAULT_FEATURES), "mismatch", m_most)
    assert _shown_count(page) == len(expected)
    assert not message.is_visible()
    assert_no_exception_names(page)
    screenshot("corrected")


def test_notes_say_what_the_user_changed_only(sample_db):
    """No note when the page opens (m's default moved into 0–0 silently); a first frame typed after the last (or a
    last before the first) makes them change places, and the box that was typed says so."""
    from mocapviz.app.backend import Backend
    from mocapviz.app.pages.relational import RelationalPage
    from mocapviz.app.state import Selection

    page = RelationalPage(Backend.open(sample_db.path), Selection())
    boxes = (page.first, page.last, page.mismatches)
    assert not any(b.note.visible for b in boxes), [b.note.object for b in boxes]
    page.doc.value = 10  # sneak2StepsLStart: 215 frames
    page.last.value = 50
    page.first.value = 120
    assert tuple(page.span.value) == (50, 120) and (page.first.value, page.last.value) == (50, 120)
    assert page.first.note.object == ("**first frame** 120 is after the last frame 50: the two were swapped, the "
                                      "span is now frames 50–120.")
    assert page.query()["span"] == (50, 121)
    page.last.value = 10
    assert (page.first.value, page.last.value) == (10, 50) and not page.first.note.visible
    assert "**last frame** 10 is before the first frame 50" in page.last.note.object


def _default_query(db, doc: int) -> tuple[list[str], int]:
    """The features and m the page starts with for the whole clip ``doc``: its suggested query."""
    suggested = Engine(db).suggest_query(doc)
    return suggested.features, suggested.mismatches


def test_round_trip_on_hdm05(hdm05_db30, hdm05_dashboard, page, screenshot):
    """Click Run to hits shown over the 287 HDM05 clips at 30 Hz: the default query (first clip, whole, its
    suggested features, m-mismatch hits)."""
    _open_page(page, hdm05_dashboard)
    docs = hdm05_db30.documents
    doc, n = int(docs["doc_id"].iloc[0]), int(docs["n_frames"].iloc[0])
    ms = timed(lambda: page.locator(".mv-run button").click(),
               lambda: page.locator(".mv-hits .tabulator-row").first.wait_for(timeout=600_000))
    record_timing("relational_round_trip_ms", ms, "ms")
    features, m = _default_query(hdm05_db30, doc)
    expected = _expected_hits(hdm05_db30, doc, (0, n - 1), features, "mismatch", m)
    assert _shown_count(page) == len(expected)
    screenshot("hdm05")


# ============================================================================ the default query, no browser
def test_a_new_clip_ticks_its_suggested_query(sample_db):
    """Before the indexes are loaded a new clip ticks the kick features; once they are, a new clip ticks its
    suggested query (:meth:`mocapviz.engine.Engine.suggest_query` of the clip) and m; a narrower span of the same
    clip keeps them. (A Backend of its own: the one Backend.open shares may hold the indexes already.)"""
    backend = Backend(sample_db)
    page = RelationalPage(backend, Selection(doc=10, span=(0, 215)))
    assert sorted(page.query()["features"]) == sorted(DEFAULT_FEATURES)
    backend.engine.indexes("2005")
    for doc in (12, 7):
        page.doc.value = doc
        suggested, q = Engine(sample_db).suggest_query(doc), page.query()
        assert (sorted(q["features"]), q["mode"], q["mismatches"]) == (sorted(suggested.features), suggested.mode,
                                                                       suggested.mismatches)  # fmt: skip
    assert q["features"] == ["lknee_bent"]  # the kick (7): the other kick is its first hit (first_query's example)
    page.first.value = 20  # a narrower span of the same clip keeps the ticks
    assert page.query()["features"] == q["features"] and page.query()["span"] == (20, 129)


def test_a_new_run_shows_the_query_alone_again_and_counts_agree_in_number(sample_db):
    """issue 39: the player's caption (and the player) stayed "... beside hit 2" of a table a new run replaced; a
    count of one read "1 hits". A new run shows the query alone with its caption; one hit reads "1 hit"."""
    backend = Backend.open(sample_db.path)
    doc = int(sample_db.documents.loc[sample_db.documents["name"].str.startswith("HDM_dg_sneak"), "doc_id"].iloc[0])
    n = int(sample_db.document(doc)["n_frames"])
    page = RelationalPage(backend, Selection(doc=doc, span=(0, n)))
    in_own_loop(page._on_run())
    assert len(page.hits) > 1 and page.count.object.startswith(f"**{len(page.hits)} hits** for ")
    page.table.selection = [1]
    assert "beside hit 2" in page.player_caption.object
    page.mismatches.value = 0  # a new query: exact, fewer hits
    in_own_loop(page._on_run())
    assert page.player_caption.object.startswith(f"Query: **{sample_db.document(doc)['name']}**, frames 0–{n - 1}. ")
    assert page.count.object.startswith(f"**{plural(len(page.hits), 'hit')}** for ")
    page._show_hits(page.shown_query, page.hits.iloc[:1])
    assert page.count.object.startswith("**1 hit** for ")


def test_a_new_clip_gets_its_suggested_m_again_and_the_pages_first_query(sample_db):
    """A clip whose m the user changed, then another clip: m is back at that clip's suggestion and the query is the
    page's first query of that clip (:func:`first_query`), with its hits; the same clip again keeps what the user
    set."""
    from mocapviz.app.pages.relational import first_query, search

    backend = Backend.open(sample_db.path)
    backend.engine.indexes("2005")
    page = RelationalPage(backend, Selection(doc=0, span=(0, 1)))
    assert page.mismatches.value == 0 and page.query_segments() == 1
    page.doc.value = 10  # sneak2StepsLStart (dg): several segments, so m can be raised
    page.mismatches.value = 1
    page.doc.value = 3
    q, first = page.query(), first_query(backend, 3)
    assert {**q, "features": sorted(q["features"])} == {**first, "features": sorted(first["features"])}
    assert page.mismatches.value == first["mismatches"] == 0
    assert len(page.search(q)) == len(search(backend, first)) < len(search(backend, {**first, "mismatches": 1}))
    page.mismatches.value = 1
    page.first.value = 5  # the same clip, a narrower span: the user's m stays
    assert page.mismatches.value == 1
