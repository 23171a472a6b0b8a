"""The dashboard's Motion templates page (Müller & Röder 2006): its computations against :mod:`mocapviz.relational.templates`
on the embedded sample, and the page in headless Chromium: the hits it shows are those of ``learn_class`` +
``search_template`` run here for the same inputs, the template is drawn and a hit plays beside a training example."""

from __future__ import annotations

import dataclasses
import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from browser_helpers import open_dashboard, open_tab, record_timing, run_in_thread, text_of, timed
from playwright.sync_api import expect

from mocapviz.app.pages import templates as page_mod
from mocapviz.app.state import Selection
from mocapviz.db.hits import database_frames
from mocapviz.errors import ParameterError
from mocapviz.features import relational_features
from mocapviz.match import dtw
from mocapviz.relational.templates import (
    DELTA,
    DELTA_RANGE,
    DONT_CARE,
    MAX_COST_RANGE,
    learn_class,
    search_template,
    template_distance,
)

TAB = "Motion templates"
KICK, SQUAT = "kickLFront1Reps", "squat1Reps"


@pytest.fixture(scope="module")
def features(sample_db):
    """The sample's relational features of both sets: {set: (N, f) bool}."""
    return {s: relational_features(sample_db, s, progress=False)[0] for s in ("2006", "2005")}


def _library(db, values, label, actors=None, relational_set="2006", delta=DELTA, k=20, max_cost=None):
    """The template and hits (the hit table) as the library computes them (the reference of every check)."""
    template = learn_class(db, label, actors=actors, relational_set=relational_set, values=values)
    hits = search_template(db, template, n_matches=k, delta=delta, max_cost=max_cost, values=values)
    return template, hits


# ============================================================================ the computations, no browser
def test_class_options_are_labels_of_two_documents_or_more(sample_db):
    docs = pd.DataFrame({"label": ["a", "a", "b", None, "", "", "c", "c", "c"]})
    assert page_mod.class_options(docs) == ["a", "c"]
    assert page_mod.class_options(pd.DataFrame({"name": ["x", "y"]})) == []
    classes = page_mod.class_options(sample_db.documents)
    assert len(classes) == 11 and KICK in classes and SQUAT in classes
    assert "Motorcycle" not in classes  # a CMU trial: one document only


def test_the_page_starts_with_the_class_of_most_documents(sample_db):
    docs = pd.DataFrame({"label": ["b", "b", "a", "a", "c", "c", "c", None]})
    assert page_mod.default_class(docs) == "c"
    assert page_mod.default_class(docs.iloc[:4]) == "a"  # a tie: the first in sorted order
    assert page_mod.default_class(pd.DataFrame({"label": ["a", "b"]})) is None
    assert page_mod.default_class(sample_db.documents) == page_mod.class_options(sample_db.documents)[0]


def test_actors_of_a_class(sample_db):
    assert page_mod.actors_of(sample_db.documents, KICK) == ["dg", "mm"]
    assert page_mod.actors_of(pd.DataFrame({"label": ["a", "a"]}), "a") == []


def test_learn_and_search_equal_the_library_and_are_cached(sample_db, backend, features):
    template, table = page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 20, None)
    expected_t, expected = _library(sample_db, features["2006"], KICK)
    np.testing.assert_array_equal(template.values, expected_t.values)
    assert template.meta["doc_ids"] == [7, 18] and template.n_examples == 2
    assert len(table) == len(expected) == 20
    np.testing.assert_array_equal(table["doc_id"], expected["doc_id"])
    np.testing.assert_array_equal(table["start"], expected["start"])  # frames of the document, half-open
    np.testing.assert_array_equal(table["end"], expected["end"])
    np.testing.assert_array_equal(table["frames"], expected["end"] - expected["start"])
    np.testing.assert_allclose(table["normalised_cost"], expected["normalised_cost"])
    np.testing.assert_allclose(table["cost"], expected["cost"])
    np.testing.assert_allclose(table["start_s"], expected["start"] / 120.0)
    np.testing.assert_allclose(table["end_s"], expected["end"] / 120.0)
    assert list(table["rank"]) == list(range(1, 21))
    assert (table["label"].iloc[:2] == KICK).all()
    # cached: the same template again, and "no actor chosen" is "every actor"
    assert page_mod.learn(backend, KICK, [], "2006") is template
    assert page_mod.learn(backend, KICK, None, "2006") is template
    assert page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 20, None)[1] is table


def test_search_with_actors_set_delta_and_max_cost_equals_the_library(sample_db, backend, features):
    template, table = page_mod.learn_and_search(backend, SQUAT, ("dg",), "2005", 0.2, 5, 0.09)
    expected_t, expected = _library(sample_db, features["2005"], SQUAT, ["dg"], "2005", 0.2, 5, 0.09)
    np.testing.assert_array_equal(template.values, expected_t.values)
    assert template.meta["doc_ids"] == [11] and len(template.features) == 31
    assert 0 < len(expected) < 5  # the limit leaves out some of the K
    np.testing.assert_array_equal(table["start"], expected["start"])
    assert (table["normalised_cost"] <= 0.09).all()


def test_bad_inputs_say_why(backend):
    with pytest.raises(ParameterError, match="K must be between 1 and 100"):
        page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 101, None)
    with pytest.raises(ParameterError, match="max cost"):
        page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 5, 1.5)
    with pytest.raises(ParameterError, match="delta"):
        page_mod.learn_and_search(backend, KICK, (), "2006", 0.5, 5, None)
    with pytest.raises(ParameterError, match=r"delta must be a number in \(0, 0.5\); got 0"):
        page_mod.learn_and_search(backend, KICK, (), "2006", 0.0, 5, None)  # every entry would be don't care
    with pytest.raises(ParameterError, match="relational set"):
        page_mod.learn_and_search(backend, KICK, (), "2007", DELTA, 5, None)
    with pytest.raises(ParameterError, match="actor in"):
        page_mod.learn_and_search(backend, KICK, ("nobody",), "2006", DELTA, 5, None)


def test_hits_tied_at_cost_zero_are_said_to_be_in_no_order(backend):
    hits = pd.DataFrame({"normalised_cost": [0.0, 0.0004, 0.0005, 0.2]})  # shown as 0.000, 0.000, 0.001, 0.200
    assert "2 of them at cost 0.000" in page_mod.tie_note(hits, 0.1) and "δ = 0.1" in page_mod.tie_note(hits, 0.1)
    assert page_mod.tie_note(hits.iloc[1:], 0.1) == page_mod.tie_note(hits.iloc[:0], 0.1) == ""  # one or none
    _, table = page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 20, None)
    zero = int((page_mod.hits_view(table)["normalised_cost"] == "0.000").sum())
    assert (f"{zero} of them at cost 0.000" in page_mod.tie_note(table, DELTA)) == (zero >= 2)


def test_hits_view_rounds_as_shown(backend):
    _, table = page_mod.learn_and_search(backend, KICK, (), "2006", DELTA, 20, None)
    shown = page_mod.hits_view(table)
    assert list(shown.columns) == list(page_mod.HIT_TITLES)
    assert list(shown["normalised_cost"]) == [f"{v:.3f}" for v in table["normalised_cost"]]
    assert list(shown["start_s"]) == [f"{v:.2f}" for v in table["start_s"]]


def test_summary_names_examples_frames_and_dont_care_share(backend):
    template = page_mod.learn(backend, KICK, (), "2006")
    share = float((template.quantised(DELTA) == DONT_CARE).mean())
    assert page_mod.dont_care_share(template, DELTA) == pytest.approx(share)
    assert 0 < share < 1
    line = page_mod.template_summary(template, DELTA)
    assert "2 examples (documents 7, 18; every actor)" in line
    assert f"{len(template.values)} frames × 39 features" in line and f"{share:.1%} don't care" in line
    many = dataclasses.replace(template, n_examples=16, meta={**template.meta, "doc_ids": list(range(100, 116)),
                                                               "class_documents": 236})  # fmt: skip
    line = page_mod.template_summary(many, DELTA)  # a class of a large database: counted, not listed
    assert "16 of its 236 examples (16 documents; every actor)" in line and "100" not in line


def test_image_legend_says_what_the_shades_mean(backend):
    template = page_mod.learn(backend, KICK, (), "2006")
    share = page_mod.dont_care_share(template, 0.2)
    assert "δ = 0.2" in page_mod.image_legend(template, 0.2, True)
    assert f"{share:.1%} of the entries" in page_mod.image_legend(template, 0.2, True)
    assert "Averaged values of the 2 aligned examples" in page_mod.image_legend(template, 0.2, False)


def test_training_example_and_its_alignment(backend, features, sample_db):
    template = page_mod.learn(backend, KICK, (), "2006")
    assert page_mod.training_example(template, 7) == 18  # a hit in a training example: shown beside the other
    assert page_mod.training_example(template, 12) == 7
    one = page_mod.learn(backend, SQUAT, ("dg",), "2005")
    assert page_mod.training_example(one, 11) == 11  # the only example
    start, end = 3213 - sample_db.frames(12).start, 3251 - sample_db.frames(12).start  # a stretch of document 12
    path = page_mod.example_alignment(backend, template, 7, 12, start, end)
    rows = sample_db.frames(7)
    hit = features["2006"][database_frames(sample_db, 12, start, end)]
    _, expected = dtw(features["2006"][rows].astype(float), hit, distance=template_distance)
    np.testing.assert_array_equal(path, expected)
    assert tuple(path[0]) == (0, 0) and tuple(path[-1]) == (rows.stop - rows.start - 1, end - start - 1)


def test_the_boxes_are_the_librarys_ranges_and_a_failed_run_clears_the_hits(backend, monkeypatch):
    """δ and the max cost are bounded by the library's own ranges (DELTA_RANGE, MAX_COST_RANGE): δ = 0 (every
    entry don't care, every stretch a perfect hit) cannot be entered; a max cost of 5 becomes 1, -1 becomes 0 and an
    emptied box means none, each shown. A run that fails leaves no hits of the previous run on the page."""
    page = page_mod.TemplatesPage(backend, Selection())
    assert (page.delta.start, page.delta.end) == DELTA_RANGE.closed(page_mod.STEP) == (0.01, 0.49)
    assert (page.max_cost.start, page.max_cost.end) == (MAX_COST_RANGE.low, MAX_COST_RANGE.high) == (0, 1)
    page.delta.value = 0.0
    assert page.delta.value == 0.01 and "0 was set to 0.01" in page.delta.note.object
    for typed, kept in ((5.0, 1.0), (-1.0, 0.0), (float("nan"), None)):
        page.max_cost.value = typed
        assert page.max_cost.value == kept and page._inputs()[-1] == kept
    page.delta.value, page.label.value = DELTA, KICK
    run_in_thread(page._run())
    assert len(page.table.value) == 20 and page.summary.object and page.image.object is not None

    def refused(*args):
        raise ParameterError("K must be between 1 and 100; got 101")

    monkeypatch.setattr(page_mod, "learn_and_search", refused)
    run_in_thread(page._run())
    assert page.task.error.visible and page.table.value.empty and page.count.object == ""
    assert page.summary.object == "" and page.image.object is None and page.hits is None


def test_a_database_without_classes_says_so_in_one_line():
    backend = SimpleNamespace(documents=pd.DataFrame({"doc_id": [0, 1], "name": ["a", "b"]}))
    view = page_mod.TemplatesPage(backend, Selection()).__panel__()
    assert "its documents have no label" in view.object
    backend = SimpleNamespace(documents=pd.DataFrame({"doc_id": [0, 1], "label": ["x", "y"]}))
    assert "no label is shared by two" in page_mod.TemplatesPage(backend, Selection()).__panel__().object


# ============================================================================ the page in the browser
def _cells(page, field: str, rows: int) -> list[str]:
    cells = page.locator(f".mv-templates-table .tabulator-row .tabulator-cell[tabulator-field='{field}']")
    return [cells.nth(i).inner_text().strip() for i in range(rows)]


def _assert_table_shows(page, db, expected: pd.DataFrame, offset: int = 0, rows: int = 10) -> None:
    """The table's visible page shows rows offset.. of the library's hits: document, frames, cost as shown."""
    part = expected.iloc[offset : offset + rows]
    n = len(part)
    assert _cells(page, "rank", n) == [str(offset + i + 1) for i in range(n)]
    assert _cells(page, "doc_id", n) == [str(d) for d in part["doc_id"]]
    assert _cells(page, "start", n) == [str(f) for f in part["start"]]  # frames of the document, half-open
    assert _cells(page, "end", n) == [str(f) for f in part["end"]]
    assert _cells(page, "normalised_cost", n) == [f"{v:.3f}" for v in part["normalised_cost"]]


def _steps(db, values: np.ndarray, example: slice, hit: pd.Series) -> np.ndarray:
    """The DTW path of a training example's clip (database frames ``example``) and a hit's frames, on the
    relational features ``values`` with the template's learning cost."""
    rows = database_frames(db, hit["doc_id"], hit["start"], hit["end"])
    _, path = dtw(values[example].astype(float), values[rows], distance=template_distance)
    return path


def _set(page, css: str, value) -> None:
    box = page.locator(f"{css} input")
    box.fill(str(value))
    box.press("Enter")


def test_templates_page_shows_the_library_hits_and_plays_one(page, sample_dashboard, sample_db, features, screenshot):
    open_dashboard(page, sample_dashboard)
    open_tab(page, TAB)
    page.locator(".mv-templates-count", has_text="template in the whole database").wait_for()  # the opening answer
    page.locator(".mv-templates-class select").select_option(KICK)
    assert page.locator(".mv-templates-k input").input_value() == "20"
    assert page.locator(".mv-templates-delta input").input_value() == f"{page_mod.DEFAULT_DELTA:g}"
    count = page.locator(".mv-templates-count", has_text=f"of the {KICK} template")
    ms = timed(page.locator(".mv-templates-run button").click, count.wait_for)
    record_timing("templates_learn_search_ms", ms, "ms")

    template, expected = _library(sample_db, features["2006"], KICK, delta=page_mod.DEFAULT_DELTA)
    assert int(re.match(r"\s*(\d+) hits?", text_of(page, ".mv-templates-count")).group(1)) == len(expected) == 20
    _assert_table_shows(page, sample_db, expected)
    page.locator(".mv-templates-table .tabulator-page[data-page='next']").click()
    page.locator(".mv-templates-table .tabulator-cell[tabulator-field='rank']", has_text="11").wait_for()
    _assert_table_shows(page, sample_db, expected, offset=10)
    page.locator(".mv-templates-table .tabulator-page[data-page='prev']").click()
    page.locator(".mv-templates-table .tabulator-cell[tabulator-field='rank']", has_text="1").first.wait_for()

    summary = text_of(page, ".mv-templates-summary")
    share = float((template.quantised(page_mod.DEFAULT_DELTA) == DONT_CARE).mean())
    assert f"{template.n_examples} examples" in summary and f"{len(template.values)} frames" in summary
    assert f"{share:.1%} don't care" in summary
    page.locator(".mv-templates-image canvas").first.wait_for(state="visible")
    assert not page.locator(".mv-templates-task .mv-error").is_visible()

    # the second hit (document 18, a training example) plays beside the other example, document 7, aligned by DTW
    page.locator(".mv-templates-table .tabulator-row").nth(1).click()
    page.locator(".mv-templates-playing", has_text="Playing").wait_for()
    path = _steps(sample_db, features["2006"], sample_db.frames(7), expected.iloc[1])
    assert "training example document 7 " in text_of(page, ".mv-templates-playing")
    assert "hit 2 (document 18," in text_of(page, ".mv-templates-playing")
    page.locator(".mv-templates-player .mv-player-caption", has_text=f"of {len(path)} ").wait_for()
    expect(page.locator(".mv-templates-player canvas")).to_have_attribute("data-clips", "2")
    assert f"{share:.1%} of the entries" in text_of(page, ".mv-templates-legend")
    page.locator(".mv-templates-view .bk-btn", has_text="averaged values").click()
    page.locator(".mv-templates-legend", has_text="Averaged values of the 2 aligned examples").wait_for()
    page.locator(".mv-templates-image canvas").first.wait_for(state="visible")
    screenshot("templates")

    # one actor, the 2005 set, another δ, K and a limit on the cost
    page.locator(".mv-templates-class select").select_option(SQUAT)
    page.locator(".mv-templates-actors .choices").first.click()
    page.keyboard.type("dg")
    page.keyboard.press("Enter")
    page.keyboard.press("Escape")
    page.locator(".mv-header").click()  # close the dropdown
    page.locator(".mv-templates-set .bk-btn", has_text="2005").click()
    _set(page, ".mv-templates-delta", 0.2)
    _set(page, ".mv-templates-k", 5)
    _set(page, ".mv-templates-max-cost", 0.09)
    page.locator(".mv-templates-run button").click()
    page.locator(".mv-templates-count", has_text=f"of the {SQUAT} template").wait_for()
    _, expected = _library(sample_db, features["2005"], SQUAT, ["dg"], "2005", 0.2, 5, 0.09)
    assert 0 < len(expected) < 5
    assert int(re.match(r"\s*(\d+) hits?", text_of(page, ".mv-templates-count")).group(1)) == len(expected)
    assert "cost / frame ≤ 0.09" in text_of(page, ".mv-templates-count")
    _assert_table_shows(page, sample_db, expected, rows=len(expected))
    assert page.locator(".mv-templates-table .tabulator-row").count() == len(expected)
    assert "1 example (document 11; actors dg)" in text_of(page, ".mv-templates-summary")
    page.locator(".mv-templates-view .bk-btn", has_text="quantised").click()
    page.locator(".mv-templates-legend", has_text="Quantised at δ = 0.2").wait_for()
    page.locator(".mv-templates-table .tabulator-row").nth(1).click()
    path = _steps(sample_db, features["2005"], sample_db.frames(11), expected.iloc[1])
    page.locator(".mv-templates-player .mv-player-caption", has_text=f"of {len(path)} ").wait_for()
    assert "training example document 11 " in text_of(page, ".mv-templates-playing")
    screenshot("templates-actor")

    # the boxes show the values that run: a max cost of 5 is 1, δ = 0 is 0.01, an emptied max cost is none
    _set(page, ".mv-templates-max-cost", 5)
    page.locator(".mv-input-note", has_text="max cost / frame must be 0–1: 5 was set to 1.").wait_for()
    expect(page.locator(".mv-templates-max-cost input")).to_have_value("1")
    _set(page, ".mv-templates-delta", 0)
    page.locator(".mv-input-note", has_text="δ (quantisation) must be 0.01–0.49: 0 was set to 0.01.").wait_for()
    _set(page, ".mv-templates-max-cost", "")
    page.locator(".mv-templates-run button").click()
    page.locator(".mv-templates-count", has_text=f"of the {SQUAT} template in the whole database (K = 5)").wait_for()
    page.locator(".mv-templates-summary", has_text="don't care at δ = 0.01").wait_for()
