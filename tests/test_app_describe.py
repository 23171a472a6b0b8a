"""The dashboard's Describe page (scene descriptions, Müller, Röder & Clausen 2005 §6.3): its helpers without a
browser, and the page in headless Chromium: a typo is shown as one line with its line and column, the hits shown
are those of :func:`mocapviz.relational.scene.find` run here on the same database, a hit plays, an empty result says
which part found nothing, and a stored template's description fills the editor."""

from __future__ import annotations

import html
import re
import time

import numpy as np
import pytest
from browser_helpers import (
    EXCEPTION_NAME,
    assert_no_exception_names,
    in_own_loop,
    open_dashboard,
    open_tab,
    record_timing,
    timed,
)
from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import expect

from mocapviz.app.pages import describe as page_mod
from mocapviz.app.widgets import PAGE_SIZE
from mocapviz.errors import DescriptionError, ParameterError
from mocapviz.relational import index
from mocapviz.relational.description import named_descriptions, parse_description
from mocapviz.relational.scene import describe, find
from mocapviz.relational.templates import learn_class, store_template

TAB = "Describe"
TYPO = """lknee: straight bent straight
    and lfot: lowered raised lowered
    and overlap lknee bent, lfoot raised"""
KICK = TYPO.replace("lfot:", "lfoot:")  # the left kick (kick_left written out): 5 hits on the sample
# a jump whose right foot stays up 3 s or more: none on the sample, 'rfoot' finds nothing
EMPTY = ("rfoot: lowered raised lowered and lfoot: lowered raised lowered and overlap rfoot raised, lfoot raised "
         "and rfoot raised for 3.. s")
# two events of their own (not the shipped library's, which may change): w's two rhand progressions
TWO = """define w: rhand: below_neck above_neck below_neck and rhand: slow fast slow
    and overlap rhand above_neck, rhand fast;
define t: rhand: below_neck above_neck below_neck and relbow: bent straight bent;
w | t"""
TEMPLATE = "describe-test-kick"  # stored with the sample by test_describe_a_stored_template


# ============================================================================ helpers, no browser
def test_parse_status_is_one_line_with_line_and_column():
    with pytest.raises(DescriptionError) as error:
        parse_description(TYPO)
    ok, message = page_mod.parse_status(TYPO)
    assert ok is False and message == str(error.value) and "\n" not in message
    assert message.startswith(f"line 2, column {error.value.column}: ") and "'lfoot'" in message
    assert EXCEPTION_NAME.search(message) is None
    assert page_mod.parse_status(KICK) == (True, "Reads well in the 2005 set: features lknee_bent, lfoot_raised.")
    assert page_mod.parse_status("  \n")[0] is None
    ok, message = page_mod.parse_status("kick_rigth then punch_left")
    assert ok is False and message.startswith("line 1, column 1: ") and "'kick_right'" in message


def test_a_chain_of_doubling_definitions_reads_in_linear_time():
    """Each definition used twice by the next (round3's doubling_defs, to the deepest chain the limits allow): the
    page's reading of the text visits each named description once; it doubled per level (20 levels 2.7 s)."""
    import time

    from mocapviz.relational.description import MAX_DEPTH

    levels = MAX_DEPTH // 2 - 1
    text = "define a0: rknee: straight bent;\n" + "".join(f"define a{i}: a{i - 1} | a{i - 1};\n"
                                                         for i in range(1, levels + 1)) + f"a{levels}"  # fmt: skip
    t0 = time.perf_counter()
    assert page_mod.parse_status(text) == (True, "Reads well in the 2005 set: features rknee_bent.")
    described = parse_description(text)
    assert page_mod.description_features(described) == ["rknee_bent"]
    assert sorted(page_mod._named_bodies(described), key=lambda n: int(n[1:])) == [f"a{i}" for i in range(levels + 1)]
    assert time.perf_counter() - t0 < 5.0  # 2^49 visits before: never within a lifetime


def test_features_and_parts_of_a_hit():
    two = parse_description(TWO)
    assert page_mod.description_features(two) == ["rhand_above_neck", "rhand_fast", "relbow_bent"]
    assert page_mod.description_features(parse_description("template:x then kick_left")) == \
        ["lknee_bent", "lfoot_raised"]  # fmt: skip
    assert page_mod.part_spans("kick_left/lknee 36:66, template:squat1Reps-bd-dg 52:98") == \
        [("kick_left/lknee", 36, 66), ("template:squat1Reps-bd-dg", 52, 98)]  # fmt: skip
    # w's two rhand progressions take w's rhand features in turn; t's rhand is its own
    assert page_mod.matched_features(two, "w/rhand 94:166, w/rhand 139:367") == \
        [("rhand_above_neck", 94, 166), ("rhand_fast", 139, 367)]  # fmt: skip
    assert page_mod.matched_features(two, "t/rhand 1:9, t/relbow 3:5") == \
        [("rhand_above_neck", 1, 9), ("relbow_bent", 3, 5)]  # fmt: skip
    unnamed = parse_description("rknee_bent: 0 1 0 and lfoot: lowered raised lowered")
    assert page_mod.matched_features(unnamed, "rknee_bent 5:9, lfoot 6:8, template:t 1:2") == \
        [("rknee_bent", 5, 9), ("lfoot_raised", 6, 8), (None, 1, 2)]  # fmt: skip


def test_reading_set_follows_the_text():
    assert page_mod.reading_set("set 2006;\nrknee: straight bent straight", "2005") == "2006"
    assert page_mod.reading_set("kick_left", "2006") == "2006"
    assert page_mod.reading_set("set 2007; kick_left", "2005") == "2005"  # parse_status names the error
    assert page_mod.parse_status("set 2007; kick_left")[1].startswith("line 1, column 5: ")


def test_window_and_editing_helpers():
    assert page_mod.hit_window(30, 90, 100, 120.0) == (0, 100)
    assert page_mod.hit_window(300, 360, 1000, 30.0) == (285, 375)
    assert page_mod.insert_name("kick_right then", "punch_left") == "kick_right then punch_left"
    assert page_mod.insert_name("", "jump") == "jump"
    assert page_mod.insert_progression("rknee: straight bent straight\n", "rfoot", "lowered", "raised") == \
        "rknee: straight bent straight\n    and rfoot: lowered raised lowered"  # fmt: skip
    for relational_set in page_mod.RELATIONAL_SETS:
        names = page_mod.names_view(relational_set)
        assert list(names["name"]) == list(named_descriptions(relational_set))
        assert not names["description"].str.contains("\n").any()
        words = page_mod.vocabulary_view(relational_set)
        assert list(words.columns) == ["part", "state_0", "state_1", "feature", "group"] and len(words) >= 31


def test_search_equals_find_is_cached_and_checks_k(sample_db, backend):
    hits = page_mod.search(backend, KICK, "2005", 4)
    expected = find(sample_db, KICK, n_matches=4, indexes=index.load_or_build(sample_db, "2005"))
    assert len(hits) == len(expected) == 4
    for c in ("doc_id", "start", "end", "parts"):
        np.testing.assert_array_equal(hits[c], expected[c])
    assert page_mod.search(backend, KICK, "2005", 4) is hits
    assert page_mod.search(backend, EMPTY, "2005", 4).attrs["empty_reason"].startswith("'rfoot' found nothing")
    with pytest.raises(ParameterError, match="K"):
        page_mod.search(backend, KICK, "2005", 0)
    with pytest.raises(DescriptionError, match="line 2, column"):
        page_mod.search(backend, TYPO, "2005", 4)


# ============================================================================ the page in the browser
def test_the_status_names_a_template_not_stored_before_find(sample_db):
    """issue 39: "Reads well ... template nosuch", then Find failed on it. With the database, the status refuses a
    template it does not store, naming it; the text alone still reads."""
    text = "template:nosuch then kick_left"
    assert page_mod.parse_status(text)[0] is True
    ok, message = page_mod.parse_status(text, db=sample_db)
    assert ok is False and message.startswith("template nosuch is not stored with this database")
    ok, message = page_mod.parse_status("template:nosuch then template:nosuch2", db=sample_db)
    assert ok is False and message.startswith("templates nosuch, nosuch2 are not stored")
    assert page_mod.parse_status(KICK, db=sample_db)[0] is True


def test_k_is_bounded_and_an_empty_find_says_no_hit_once(backend):
    """issue 39: the K box took 1,000,000,000, and an empty result read "No hit: no hit: 'rfoot' found nothing"."""
    from mocapviz.app.state import Selection
    from mocapviz.app.widgets import MAX_MATCHES

    page = page_mod.DescribePage(backend, Selection())
    assert (page.n_matches.start, page.n_matches.end) == (1, MAX_MATCHES)
    with pytest.raises(ParameterError, match="K"):
        page_mod.search(backend, KICK, "2005", 10**9)
    page._set_text(EMPTY)
    in_own_loop(page._on_find())
    reason = page_mod.search(backend, EMPTY, "2005", page.n_matches.value).attrs["empty_reason"]
    assert page.count.object == f"<b>No hit</b>: {html.escape(reason)}."
    assert page.count.object.lower().count("no hit") == 1
    page._set_text(KICK)
    in_own_loop(page._on_find())
    assert page.count.object.startswith(f"<b>{len(page.hits)} hits</b>") and len(page.hits) > 1


def _open_page(page, url: str) -> None:
    open_dashboard(page, url)
    open_tab(page, TAB)
    page.locator(".mv-describe-find button:not([disabled])").wait_for(timeout=600_000)


def _type(page, text: str) -> None:
    """Replace the editor's text as a user types it (each keystroke reaches the server as value_input)."""
    editor = page.locator(".mv-describe-editor textarea")
    editor.fill("")
    editor.press_sequentially(text, delay=2)


def _rows(page, want: list, timeout: float = 10.0) -> list[tuple[int, int, int]]:
    """(document, start, end) of the hit table's rows on its shown page, read again until they are ``want`` or
    ``timeout`` seconds have passed (Tabulator renders its rows anew when the table's data is set: a loaded CI
    machine once read none between two renderings)."""
    rows = page.locator(".mv-describe-hits .tabulator-row")
    deadline = time.monotonic() + timeout
    while True:
        try:
            got = [tuple(int(rows.nth(i).locator(f'.tabulator-cell[tabulator-field="{c}"]').inner_text(timeout=1000))
                         for c in ("doc_id", "start", "end")) for i in range(rows.count())]
        except PlaywrightError:  # a row went away while it was read
            got = None
        if got == want or time.monotonic() > deadline:
            return got
        page.wait_for_timeout(100)


def test_typo_fix_find_play_and_empty(sample_db, sample_dashboard, page, screenshot):
    _open_page(page, sample_dashboard)
    status = page.locator(".mv-describe-parse")
    expect(status).to_contain_text("Reads well")  # the example the editor starts with
    _type(page, TYPO)
    with pytest.raises(DescriptionError) as error:
        parse_description(TYPO)
    expect(status).to_contain_text(str(error.value))  # live, while typing: line and column, one line
    assert str(error.value).startswith("line 2, column")
    assert_no_exception_names(page)
    screenshot("typo")

    _type(page, KICK)
    expect(status).to_contain_text("Reads well in the 2005 set: features lknee_bent, lfoot_raised.")
    k = page.locator(".mv-describe-k input")
    k.fill("0")
    k.press("Enter")
    page.locator(".mv-input-note", has_text="K (results) must be 1–100: 0 was set to 1.").wait_for()
    k.fill("1000000000")  # issue 39: it was taken
    k.press("Enter")
    page.locator(".mv-input-note", has_text="K (results) must be 1–100: 1,000,000,000 was set to 100.").wait_for()
    k.fill("4")
    k.press("Enter")
    expect(k).to_have_value("4")
    count = page.locator(".mv-describe-count")
    ms = timed(lambda: page.locator(".mv-describe-find button").click(),
               lambda: expect(count).to_contain_text("4 hits"))
    record_timing("describe_find_ms", ms, "ms")
    expected = find(sample_db, KICK, n_matches=4, indexes=index.load(sample_db, "2005"))
    expect(page.locator(".mv-describe-hits .tabulator-row")).to_have_count(len(expected))
    want = list(zip(expected["doc_id"], expected["start"], expected["end"]))
    assert _rows(page, want) == want
    parts = page.locator(".mv-describe-hits .tabulator-row").first.locator('.tabulator-cell[tabulator-field="parts"]')
    assert parts.inner_text().strip() == expected["parts"].iloc[0]
    screenshot("hits")

    target = expected.iloc[1]
    page.locator(".mv-describe-hits .tabulator-row").nth(1).locator('.tabulator-cell[tabulator-field="name"]').click()
    caption = page.locator(".mv-describe-caption")
    expect(caption).to_contain_text(f"Playing hit 2: {target['name']}")
    expect(caption).to_contain_text(f"frames {target['start']}:{target['end']}")
    canvas = page.locator(".mv-describe-player .mv-player canvas")
    expect(canvas).to_have_attribute("data-clips", "1")
    expect(canvas).to_have_attribute("data-drawn", re.compile(r"[1-9]"))
    expect(page.locator(".mv-describe-timeline canvas").first).to_be_visible()  # the feature bars of the hit
    screenshot("hit-played")

    _type(page, EMPTY)
    expect(status).to_contain_text(page_mod.parse_status(EMPTY)[1])
    page.locator(".mv-describe-find button").click()
    reason = find(sample_db, EMPTY, indexes=index.load(sample_db, "2005")).attrs["empty_reason"]
    assert reason
    expect(count).to_contain_text(f"No hit: {reason}.")
    expect(page.locator(".mv-describe-hits .tabulator-row")).to_have_count(0)
    assert not page.locator(".mv-error").is_visible()
    assert_no_exception_names(page)
    screenshot("empty")


def test_names_and_parts_insert_and_a_stored_template_is_described(sample_db, sample_dashboard, page, screenshot):
    template = learn_class(sample_db, "kickLFront1Reps", relational_set="2006")
    store_template(sample_db, template, name=TEMPLATE)  # before the page is built: it lists the stored templates
    _open_page(page, sample_dashboard)
    editor = page.locator(".mv-describe-editor textarea")
    _type(page, "kick_right then ")
    names = page.locator('.mv-describe-names .tabulator-cell[tabulator-field="name"]')
    names.filter(has_text=re.compile("^punch_left$")).click()
    expect(editor).to_have_value("kick_right then punch_left")
    expect(page.locator(".mv-describe-parse")).to_contain_text("Reads well")
    page.locator(".mv-describe-words .bk-tab", has_text="Parts and states").click()
    page.locator('.mv-describe-vocabulary .tabulator-cell[tabulator-field="feature"]',
                 has_text=re.compile("^rfoot_raised$")).click()  # fmt: skip
    expect(editor).to_have_value("kick_right then punch_left\n    and rfoot: lowered raised lowered")
    expect(page.locator(".mv-describe-parse")).to_contain_text("line 2, column")  # a named event takes no "and"
    assert_no_exception_names(page)

    page.locator(".mv-describe-template select").select_option(TEMPLATE)
    page.locator(".mv-describe-template-run button").click()
    text = describe(template)
    expect(editor).to_have_value(text)
    expect(page.locator(".mv-describe-set .bk-btn.bk-active")).to_have_text("2006")  # the template's set
    expect(page.locator(".mv-describe-parse")).to_contain_text("Reads well")
    page.locator(".mv-describe-find button").click()
    expected = find(sample_db, text, n_matches=page_mod.DEFAULT_MATCHES, relational_set="2006",
                    indexes=index.load_or_build(sample_db, "2006"))  # fmt: skip
    assert len(expected) > 0
    expect(page.locator(".mv-describe-count")).to_contain_text(f"{len(expected)} hit")
    expect(page.locator(".mv-describe-hits .tabulator-row")).to_have_count(min(len(expected), PAGE_SIZE))
    want = list(zip(expected["doc_id"], expected["start"], expected["end"]))[:PAGE_SIZE]
    assert _rows(page, want) == want
    assert_no_exception_names(page)
    screenshot("template-described")
    _type(page, "set 2005;\nkick_left")  # a set the text names moves the buttons
    expect(page.locator(".mv-describe-set .bk-btn.bk-active")).to_have_text("2005")
    expect(page.locator(".mv-describe-parse")).to_contain_text("Reads well in the 2005 set")


def test_the_page_never_opens_a_path_a_user_typed(backend, tmp_path, monkeypatch):
    """The Describe page's backend (search, and template_stamps, its cache key) reads templates stored with the
    database only: a real template file outside it, typed as template:PATH, is neither probed nor loaded, and every
    refused or unknown name gives the one message, whether a file of that name exists or not (issue 37)."""
    from mocapviz.features import feature_names
    from mocapviz.relational.templates import MotionTemplate

    monkeypatch.chdir(tmp_path)  # relative paths, as a user would type them
    MotionTemplate(np.full((20, 39), 0.5), feature_names("2006"), "anything", 1, 1).save(tmp_path / "t.npz")
    messages = set()
    for name in ("t.npz", "./t.npz", "/etc/ld.so.conf", "u.npz", "/etc/no-such.conf", "../t.npz"):
        assert page_mod.template_stamps(backend.db, f"template:{name}") == ((name, None),)
        with pytest.raises(DescriptionError) as err:
            page_mod.search(backend, f"set 2006; template:{name}", "2006", 5)
        messages.add(str(err.value).replace(repr(name), "<NAME>"))
    assert len(messages) == 1 and next(iter(messages)).startswith(f"no stored template <NAME> in {backend.db.path};")
