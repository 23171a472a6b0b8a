"""The dashboard on a large database (issue 28): each document's archive and performer (HDM05 actor, CMU subject,
none for Bandai Namco), the document browser's filters against a brute-force scan, the one document picker of every
page, and result tables paged on the server: an 11,156-hit relational result builds and sends one page of rows.
Then in headless Chromium: the picker lists what is typed (any case) and sets the query clip; the Database page's
text filter."""

from __future__ import annotations

import contextlib
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bokeh.document import Document
from browser_helpers import open_dashboard, open_tab
from playwright.sync_api import expect

import mocapviz.app.pages.relational as relational_module
from mocapviz import MotionDB
from mocapviz.app.documents import (
    MAX_COMPLETIONS,
    NO_PERFORMER,
    DocumentPicker,
    document_table,
    filter_documents,
    option_label,
)
from mocapviz.app.pages.database import PAGE_ROWS, DatabasePage
from mocapviz.app.pages.relational import RelationalPage
from mocapviz.app.state import Selection
from mocapviz.app.widgets import PAGE_SIZE
from mocapviz.db.hits import hit_table


def _finish(coroutine) -> None:
    """Run a page's coroutine that only yields to the event loop (``asyncio.sleep(0)``) to its end, without a loop
    (the browser tests of the session run one in this thread)."""
    with contextlib.suppress(StopIteration):
        while True:
            coroutine.send(None)


def _model(widget):
    """The Bokeh model a widget rendered (what the browser receives)."""
    return next(iter(widget._models.values()))[0]


# ============================================================================ archive and performer
def test_archive_and_performer_of_the_sample(sample_db):
    table = document_table(sample_db.documents)
    assert table["doc_id"].tolist() == sample_db.documents["doc_id"].tolist()
    for doc, shown in zip(sample_db.documents.to_dict("records"), table.to_dict("records")):
        path = Path(doc["path"])
        archive = next(p for p in reversed(path.parent.parts) if p in ("hdm05-cut", "cmu-asfamc"))
        assert shown["archive"] == archive
        if archive == "hdm05-cut":  # HDM_dg_kickLFront1Reps_...: the actor is in the name too
            assert shown["performer"] == doc["actor"] == doc["name"].split("_")[1]
        else:  # 135_08: subject 135
            assert shown["performer"] == doc["name"].split("_")[0] == str(doc["cmu_subject"])
        assert shown["seconds"] == pytest.approx(doc["n_frames"] / doc["fps"], abs=0.0051)  # to 0.01 s
        assert option_label(shown) == (f"{doc['doc_id']}: {doc['name']} · {doc['label']} · {shown['performer']} · "
                                       f"{archive}")  # fmt: skip


def test_cmu_subjects_and_trials_without_one(cmu_db30):
    table = document_table(cmu_db30.documents).set_index("name")
    labels = cmu_db30.documents.set_index("name")
    assert (table["archive"] == "cmu-asfamc").all()
    for name, row in table.iterrows():
        subject = labels.at[name, "cmu_subject"]
        trial = re.fullmatch(r"(\d+)_\d+", name)
        want = str(subject) if isinstance(subject, str) and subject else trial.group(1) if trial else NO_PERFORMER
        assert row["performer"] == want, name
    assert table.at["md_02", "performer"] == "05"  # the labels table's subject (the name has none)
    assert table.at["golf_01", "performer"] == NO_PERFORMER  # a trial the archive names no subject for


def test_bandai_namco_names_no_performer(bandai1_files, tmp_path):
    db = MotionDB.ingest(bandai1_files[:3], tmp_path / "db", fps=30, progress=False)
    table = document_table(db.documents)
    assert (table["archive"] == "bandai-namco-1").all() and (table["performer"] == NO_PERFORMER).all()
    assert table["label"].tolist() == db.documents["content"].tolist()


# ============================================================================ the browser's filters
@pytest.mark.parametrize("filters", [
    {}, {"labels": ["squat1Reps", "kickLFront1Reps"]}, {"performers": ["mm"]}, {"archives": ["cmu-asfamc"]},
    {"text": "KICK"}, {"text": "135"}, {"text": "hdm05", "performers": ["dg"], "seconds": (0.5, 1.5)},
    {"text": "no such document"}])  # fmt: skip
def test_filters_keep_what_a_scan_keeps(sample_db, filters):
    table = document_table(sample_db.documents)
    shown = filter_documents(table, **filters)

    def kept(row) -> bool:
        words = f"{row['doc_id']} {row['name']} {row['label']} {row['performer']} {row['archive']}".lower()
        lo, hi = filters.get("seconds", (0, math.inf))
        return (row["label"] in filters.get("labels", [row["label"]])
                and row["performer"] in filters.get("performers", [row["performer"]])
                and row["archive"] in filters.get("archives", [row["archive"]])
                and filters.get("text", "").lower() in words and lo <= row["seconds"] <= hi)  # fmt: skip

    assert shown["doc_id"].tolist() == [r["doc_id"] for r in table.to_dict("records") if kept(r)]
    assert shown.index.tolist() == list(range(len(shown)))


def test_database_page_sends_one_page_of_documents(backend):
    page = DatabasePage(backend, Selection(doc=0, span=(0, 10)))
    page.__panel__().get_root(Document())
    model = _model(page.table)
    assert len(model.source.data["doc_id"]) == min(PAGE_ROWS, len(backend.documents))
    page.text_filter.value_input = "squat"
    assert page.table.value["name"].str.contains("squat").all() and len(page.table.value) == 2
    assert page.count.object.startswith(f"2 of {len(backend.documents)} documents")  # (then "· all 120 fps")


# ============================================================================ the picker
def test_the_picker_offers_every_document_by_id(backend, sample_db):
    picker = DocumentPicker(backend, "query clip", 7)
    model = picker.get_root(Document())
    assert picker.value == 7 and model.value.startswith("7: HDM_")
    table = document_table(sample_db.documents)
    assert model.completions == [option_label(r) for r in table.to_dict("records")]
    assert [picker.options[c] for c in model.completions] == table["doc_id"].tolist()
    assert (model.search_strategy, model.case_sensitive, model.restrict) == ("includes", False, True)
    assert model.max_completions == MAX_COMPLETIONS and model.min_characters == 1
    picker._process_events({"value": model.completions[11]})  # the browser sends the chosen line
    assert picker.value == int(table["doc_id"].iloc[11])


# ============================================================================ paged results
def test_an_11k_hit_result_builds_one_page(sample_db, backend, monkeypatch):
    """A result of 11,156 hits (the size of a relational query of a standing clip on every shared archive): the
    table sends one page of rows, the precision curve is one aggregate over the documents, and a hit chosen on a later
    page plays the right one."""
    rng = np.random.default_rng(28)
    docs = sample_db.documents
    pick = rng.integers(0, len(docs), 11_156)
    starts = rng.integers(0, docs["n_frames"].to_numpy()[pick] - 1)
    hits = hit_table(sample_db, docs["doc_id"].to_numpy()[pick], starts, starts + 1, score=np.sort(rng.random(11_156)))
    drawn = []
    real = relational_module.precision_recall_plot
    monkeypatch.setattr(relational_module, "precision_recall_plot", lambda curve, **kw: drawn.append(curve) or
                        real(curve, **kw))  # fmt: skip
    page = RelationalPage(backend, Selection(doc=10, span=(0, 100)))
    page.__panel__().get_root(Document())
    q = page.query()
    page._show_hits(q, hits)
    _finish(page._show_quality(q, hits))
    data = _model(page.table).source.data
    assert len(data["rank"]) == PAGE_SIZE and list(data["rank"]) == list(range(1, PAGE_SIZE + 1))
    assert _model(page.table).max_page == math.ceil(len(hits) / PAGE_SIZE)
    assert len(drawn) == 1 and len(drawn[0]) == len(pd.unique(hits["doc_id"])) - 1  # documents, not hits
    page.table.page = 3
    assert list(_model(page.table).source.data["rank"]) == list(range(2 * PAGE_SIZE + 1, 3 * PAGE_SIZE + 1))
    page.table.selection = [2 * PAGE_SIZE + 4]  # the fifth row of page 3
    hit = hits.iloc[2 * PAGE_SIZE + 4]
    assert f"beside hit {2 * PAGE_SIZE + 5}: **{hit['name']}**, frames {hit['start']}:{hit['end']}" in \
        page.player_caption.object  # fmt: skip


# ============================================================================ in the browser
def test_pick_a_query_clip_by_typing(sample_db, sample_dashboard, page):
    open_dashboard(page, sample_dashboard)
    table = document_table(sample_db.documents)
    box = page.locator(".mv-filter-text input")
    box.press_sequentially("Squat")
    squats = table[table["name"].str.contains("squat", case=False)]
    expect(page.locator(".mv-doc-count")).to_contain_text(f"{len(squats)} of {len(table)} documents")
    expect(page.locator(".mv-documents .tabulator-row")).to_have_count(len(squats))

    open_tab(page, "Relational query")
    picker = page.locator(".mv-query-doc input")
    picker.fill("")
    picker.press_sequentially("SQUAT MM")  # no line holds it: nothing listed
    expect(page.locator(".mv-query-doc .bk-menu")).to_be_hidden()
    picker.fill("")
    picker.press_sequentially("sQuAt")
    listed = page.locator(".mv-query-doc .bk-menu > div")
    expect(listed).to_have_count(len(squats))
    assert listed.all_inner_texts() == [option_label(r) for r in squats.to_dict("records")]
    target = squats.iloc[-1]
    listed.nth(len(squats) - 1).click()
    info = page.locator(".mv-query-span-info")
    expect(info).to_contain_text(target["name"])  # the caption follows the pick (it names the previous one first)
    expect(info).to_contain_text(f"{target['n_frames']} frames · 0.00–")
