"""The dashboard's Correlations and Index statistics pages in headless Chromium, against the embedded sample served by
`mocapviz serve`: the numbers shown are the library's for the same database and settings."""

from __future__ import annotations

import time

import pandas as pd
import pytest
from browser_helpers import open_dashboard, open_tab, record_timing, run_in_thread, text_of

from mocapviz.app.backend import Backend
from mocapviz.app.pages import correlations as corr_page
from mocapviz.app.pages import statistics as stats_page
from mocapviz.errors import ParameterError
from mocapviz.experiments.correlation import (
    available_measures,
    correlation_sample,
    pose_correlations,
    pose_limits,
    segment_correlations,
)
from mocapviz.experiments.numeric import krueger2010_table1
from mocapviz.experiments.relational import index_statistics, mueller2005_table2, query_statistics
from mocapviz.viz.correlation import value_font
from mocapviz.viz.paper import comparison_bars

WAIT_MS = 240_000  # the server shares two cores with other test runs


def _rows(page, css: str) -> list[dict]:
    """The rows of the HTML table of the DataFrame pane with css class ``css``: [{header: text}] (index included)."""
    table = page.locator(f"{css} table").first
    table.wait_for(timeout=WAIT_MS)
    cells = table.evaluate("t => [...t.rows].map(r => [...r.cells].map(c => c.textContent.trim()))")
    header = cells[0]
    data = [r for r in cells[1:] if any(r[1:])]  # pandas puts the index name on a row of its own, otherwise empty
    return [dict(zip(header, r)) for r in data]


def _matrix_rows(page, css: str) -> dict[str, dict[str, str]]:
    """A correlation values table as {row measure: {column: text}} (the first column holds the row measures)."""
    return {next(iter(r.values())): r for r in _rows(page, css)}


def _expected_pose(sample_db, measures, clips: int = 2):
    sample = correlation_sample(sample_db, clips_per_class=clips, min_clips=clips, seed=corr_page.SEED)
    return pose_correlations(sample_db, rows=measures, columns=measures, docs=sample, n_queries=128, k=64,
                             seed=corr_page.SEED)  # fmt: skip


def _assert_matrix(shown: dict, expected) -> None:
    assert list(shown) == list(expected.index)
    for row in expected.index:
        for col in expected.columns:
            assert shown[row][col] == f"{expected.loc[row, col]:.3f}", (row, col)


def _open_values(page, css: str) -> None:
    """Expand the collapsed "values" card ``css``."""
    card = page.locator(css).first
    card.wait_for(timeout=WAIT_MS)
    card.locator(".card-header").first.click()


# ============================================================================ Correlations
def test_correlations_match_the_library(sample_db, sample_dashboard, page, screenshot):
    open_dashboard(page, sample_dashboard)
    open_tab(page, "Correlations")
    t0 = time.perf_counter()  # opening the tab computes both matrices with the default settings (issue 39)
    _open_values(page, ".mv-values-pose")
    record_timing("correlations_pose_s", time.perf_counter() - t0, "s")
    measures = list(corr_page.DEFAULT_MEASURES)
    _assert_matrix(_matrix_rows(page, ".mv-correlation-pose"), _expected_pose(sample_db, measures))
    assert "128 random query frames of the sample's 22 clips" in text_of(page, ".mv-pose-caption")

    _open_values(page, ".mv-values-segment")
    record_timing("correlations_both_s", time.perf_counter() - t0, "s")
    sample = correlation_sample(sample_db, clips_per_class=2, min_clips=2, seed=corr_page.SEED)
    segment = segment_correlations(sample_db, sample, measures=measures, n_first=8)
    shown = _matrix_rows(page, ".mv-correlation-segment")
    _assert_matrix(shown, segment)
    assert [shown[m]["precision"] for m in measures] == [f"{segment.attrs['precision'][m]:.3f}" for m in measures]
    assert "the 22 clips" in text_of(page, ".mv-segment-caption")
    screenshot("correlations")


def _heatmap_box(page, kind: str) -> dict:
    """The bounding box of a heat map's canvas (``kind``: "pose" or "segment")."""
    canvas = page.locator(f".mv-heatmap-{kind} canvas").first
    canvas.wait_for(timeout=WAIT_MS)
    return canvas.bounding_box()


def _add_measures(page, names) -> None:
    """Tick more measures in the chooser."""
    chooser = page.locator(".mv-measures")
    for name in names:
        chooser.locator(".choices").first.click()
        chooser.locator(f".choices__list--dropdown .choices__item--choice[data-value='{name}']").click()
    page.keyboard.press("Escape")


def test_correlations_recompute_with_other_measures(sample_db, sample_dashboard, page, screenshot):
    """Two measures (of the six shown first): the heat maps' cells grow to fill their column, values and names
    readable."""
    open_dashboard(page, sample_dashboard)
    open_tab(page, "Correlations")
    page.locator(".mv-compute button").click()
    page.locator(".mv-values-pose").first.wait_for(timeout=WAIT_MS)
    page.locator(".mv-values-segment").first.wait_for(timeout=WAIT_MS)
    six = _heatmap_box(page, "pose")
    deadline = time.monotonic() + WAIT_MS / 1000
    while six is None and time.monotonic() < deadline:  # (the page answered on opening: Compute redraws it)
        time.sleep(0.5)
        six = _heatmap_box(page, "pose")
    chooser = page.locator(".mv-measures")
    for name in ("Fp16", "F30E", "F39E", "F15x3E"):
        chooser.locator(f".choices__item[data-value='{name}'] .choices__button").click()
    _add_measures(page, ["F15x5E"])
    chooser.locator(".choices__item[data-value='Dpc1'] .choices__button").click()
    _open_values(page, ".mv-values-pose")  # the card stays open when the matrix is replaced
    page.locator(".mv-compute button").click()
    measures = ["F15E", "F15x5E"]
    deadline = time.monotonic() + WAIT_MS / 1000
    shown = _matrix_rows(page, ".mv-correlation-pose")
    while list(shown) != measures and time.monotonic() < deadline:
        time.sleep(0.5)
        shown = _matrix_rows(page, ".mv-correlation-pose")
    _assert_matrix(shown, _expected_pose(sample_db, measures))
    _open_values(page, ".mv-values-segment")
    while list(_matrix_rows(page, ".mv-correlation-segment")) != measures and time.monotonic() < deadline:
        time.sleep(0.5)
    two = _heatmap_box(page, "pose")
    cell = corr_page.heatmap_cell(2)
    assert cell > corr_page.heatmap_cell(6) and two["width"] >= 2 * cell + 100 and two["height"] >= 2 * cell + 80
    assert two["width"] <= corr_page.WIDTH and six["width"] <= corr_page.WIDTH
    screenshot("two-measures")


def test_segment_based_says_when_the_database_cannot(sample_db, sample_dashboard, page, screenshot):
    """Three clips per class (the sample has two): the pose-based matrix over every document, here of all 14
    measures, whose heat map still fits its column."""
    open_dashboard(page, sample_dashboard)
    open_tab(page, "Correlations")
    page.locator(".mv-compute button").click()
    page.locator(".mv-values-segment").first.wait_for(timeout=WAIT_MS)
    clips = page.locator(".mv-clips input")
    clips.fill("3")
    clips.press("Enter")
    every = list(available_measures(sample_db))
    assert len(every) == 14
    _add_measures(page, [m for m in every if m not in corr_page.DEFAULT_MEASURES])
    page.locator(".mv-compute button").click()
    problem = page.locator(".mv-segment-problem")
    problem.get_by_text("Segment-based comparisons need several clips per class").wait_for(timeout=WAIT_MS)
    assert "0 class(es) with at least 3 clips" in text_of(page, ".mv-segment-problem")
    assert not page.locator(".mv-values-segment").first.is_visible()
    caption = page.locator(".mv-pose-caption")
    caption.get_by_text(f"all {len(sample_db)} documents (no sample)").wait_for(timeout=WAIT_MS)
    assert page.locator(".mv-error").filter(has_text="failed").count() == 0
    _open_values(page, ".mv-values-pose")
    assert list(_matrix_rows(page, ".mv-correlation-pose")) == every
    box = _heatmap_box(page, "pose")
    assert box["width"] <= corr_page.WIDTH and box["height"] >= 14 * corr_page.heatmap_cell(14)
    assert value_font(corr_page.heatmap_cell(14)) is not None  # the values are printed: they fit the cells
    values, card = page.locator(".mv-correlation-pose").first, page.locator(".mv-values-pose").first.bounding_box()
    wide, shown, overflow = values.evaluate("e => [e.scrollWidth, e.clientWidth, getComputedStyle(e).overflowX]")
    assert wide > shown and overflow == "auto"  # 14 columns of values: scrolled sideways inside the card
    assert values.bounding_box()["x"] + values.bounding_box()["width"] <= card["x"] + card["width"] + 1
    screenshot("fourteen-measures")


# ============================================================================ Index statistics
@pytest.fixture(scope="module")
def sample_indexes(sample_db):
    """The sample's relational indexes (group -> InvertedIndex) as the dashboard opens them."""
    return Backend(sample_db).engine.indexes()


def test_statistics_tables_match_the_library(sample_db, sample_dashboard, sample_indexes, page, screenshot):
    open_dashboard(page, sample_dashboard)
    open_tab(page, "Index statistics")
    t0 = time.perf_counter()  # opening the tab computes the three tables, quick size (issue 39)
    page.locator(".mv-table1 table").first.wait_for(timeout=WAIT_MS)
    record_timing("statistics_all_s", time.perf_counter() - t0, "s")

    # Table 2: our three group indexes, then the paper's six rows
    rows = _rows(page, ".mv-table2")
    ours, paper = index_statistics(sample_db), mueller2005_table2()
    assert [r["source"] for r in rows] == ["this database"] * 3 + ["paper"] * 6
    for shown, (_, want) in zip(rows, [*ours.iterrows(), *paper.iterrows()]):
        for col in ("index", "f", "lists", "frames", "segments"):
            assert shown[col] == (want[col] if col == "index" else stats_page.cell_text(want[col])), col
    assert rows[0]["frames"] == f"{sample_db.n_frames:,}"

    # Table 3: counts and mean hits of the same random queries (times differ from run to run)
    rows = _rows(page, ".mv-table3")
    want = query_statistics(sample_indexes["upper"], n_queries=stats_page.QUERIES, lengths=stats_page.TABLE3_LENGTHS,
                            seed=stats_page.SEED)  # fmt: skip
    assert len(rows) == len(want) == 18
    for shown, (_, w) in zip(rows, want.iterrows()):
        assert (shown["mode"], shown["L"], shown["hits"]) == (w["mode"], str(w["L"]), w["hits"])
        assert shown["queries"] == stats_page.cell_text(w["queries"]) and shown["µh"] == stats_page.cell_text(w["mean_hits"])
    assert rows[0]["paper µt (ms)"] == "16" and rows[17]["paper µh"] == "1,908"

    # Table 1: one row per feature set with its dimension, our times beside the paper's
    rows = _rows(page, ".mv-table1")
    paper = krueger2010_table1()
    dims = {"Fp8": 8, "Fp16": 16, "Fp25": 25, "F15E": 15, "F30E": 30, "F39E": 39, "F15x3E": 45, "F15x5E": 75,
            "F30x3E": 90}  # fmt: skip
    assert [(r["set"], r["d"]) for r in rows] == [(s, str(d)) for s, d in dims.items()]
    for r in rows:
        for k in (16, 256):
            assert float(r[f"this database, k={k}"]) > 0
            for db in ("HDM05", "CMU"):
                ms = paper[(paper["database"] == db) & (paper["k"] == k) & (paper["set"] == r["set"])]["mean_ms"]
                assert r[f"{db} (paper), k={k}"] == stats_page.cell_text(ms.iloc[0])
    assert f"{sample_db.n_frames:,} frames" in text_of(page, ".mv-table1-note")
    for css in (".mv-table2-bars", ".mv-table3-curves", ".mv-query-times", ".mv-table1-bars"):
        assert page.locator(f"{css} canvas").first.is_visible(), css
    screenshot("statistics")

    # another index for Table 3: the table follows
    page.locator(".mv-table3-group select").select_option("lower")
    want = query_statistics(sample_indexes["lower"], n_queries=stats_page.QUERIES, lengths=stats_page.TABLE3_LENGTHS,
                            seed=stats_page.SEED)  # fmt: skip
    expected = [stats_page.cell_text(v) for v in want["mean_hits"]]
    deadline = time.monotonic() + WAIT_MS / 1000
    while [r["µh"] for r in _rows(page, ".mv-table3")] != expected and time.monotonic() < deadline:
        time.sleep(0.5)
    assert [r["µh"] for r in _rows(page, ".mv-table3")] == expected


# ============================================================================ the pages' helpers, without a browser
def test_default_clips_follows_the_second_largest_class():
    docs = pd.DataFrame({"label": ["a"] * 9 + ["b"] * 5 + ["c"]})
    assert corr_page.default_clips(docs) == 5
    assert corr_page.default_clips(pd.DataFrame({"label": ["a"] * 20 + ["b"] * 12})) == corr_page.PAPER_CLIPS
    assert corr_page.default_clips(pd.DataFrame({"label": ["a", "a", "a"]})) == 2
    assert corr_page.default_clips(pd.DataFrame({"label": [None, None]})) == corr_page.PAPER_CLIPS


def test_segment_problem_names_what_is_missing(sample_db):
    assert corr_page.default_clips(sample_db.documents) == 2
    assert corr_page.segment_problem(sample_db, 2, 8) == ""
    assert "need several clips per class" in corr_page.segment_problem(sample_db, 3, 8)
    assert "between 2 and 21" in corr_page.segment_problem(sample_db, 2, 22)


def test_k_and_queries_are_bounded_by_the_librarys_limits_and_a_failed_run_hides_the_matrix(sample_db,
                                                                                             monkeypatch):
    """The k and queries boxes end where pose_correlations' own check does, on the frames of the sample of *clips
    per class* (measured: the box took k up to 5,542 while the run refused k > 4,257), and follow it; a run that
    fails hides the previous heat map instead of leaving it under the error."""
    from mocapviz.app.state import Selection

    backend = Backend.open(sample_db.path)
    page = corr_page.CorrelationsPage(backend, Selection())
    for clips in (3, 2):  # 3: no sample (the segment-based part says why): every document's frames
        page.clips.value = clips
        limits = pose_limits(sample_db, corr_page.sample_of(sample_db, clips)[0])
        assert (page.k.start, page.k.end) == limits["k"] and (page.n_queries.start, page.n_queries.end) == limits[
            "n_queries"]
    assert page.k.end == int(correlation_sample(sample_db, 2, 2, seed=corr_page.SEED)["n_frames"].sum()) - 1
    most = page.k.end
    with pytest.raises(ParameterError, match=rf"k must be between 1 and .*\({most:,}\); got {most + 1}"):
        corr_page.pose_matrix(backend, ("F15E",), 2, most + 1, 2)
    assert corr_page.pose_matrix(backend, ("F15E",), 2, most, 2).attrs["k"] == most  # the box's end runs
    page.k.value = most + 1
    assert page.k.value == most and page.k.note.visible

    page.measures.value, page.n_queries.value, page.k.value = ["F15E"], 4, 8
    monkeypatch.setattr(corr_page, "segment_problem", lambda *args: "not in this test")
    run_in_thread(page._compute())
    assert page.pose.layout.visible and page.pose.plot.object is not None

    def refused(*args):
        raise ParameterError("k must be between 1 and 4,257")

    monkeypatch.setattr(corr_page, "pose_matrix", refused)
    run_in_thread(page._compute())
    assert page.pose_task.error.visible and not page.pose.layout.visible


def test_log_scale_bars_rise_from_the_axis():
    """Bars on a log axis start at its lower end, a power of ten below the smallest value: none hangs below it."""
    import holoviews as hv

    table = pd.DataFrame({"set": ["F15E", "F15E", "Fp8", "Fp8"], "database": ["ours", "paper", "ours", "paper"],
                          "mean_ms": [0.00805, 1.11, 0.0199, 0.19]})
    fig = hv.render(comparison_bars(table, "set", "mean_ms", source="database", logy=True))
    (bars,) = [r for r in fig.renderers if hasattr(r.glyph, "top")]
    assert bars.glyph.bottom == fig.y_range.start == 0.001
    assert min(bars.data_source.data["mean_ms"]) > bars.glyph.bottom


def test_heatmap_values_shrink_with_the_cells_then_give_way_to_hover():
    assert [corr_page.heatmap_cell(n) for n in (2, 6, 14)] == [110, 78, 33]
    assert [value_font(c) for c in (110, 46, 33, 24)] == [14, 10, 7, None]


def test_table1_wide_keeps_the_papers_order():
    long = pd.DataFrame({"database": ["ours", "ours", "P", "P"], "set": ["F15E", "Fp8", "F15E", "Fp8"],
                         "d": [15, 8, 15, 8], "k": [16, 16, 16, 16], "mean_ms": [0.1, 0.2, 1.1, 0.19]})
    wide = stats_page.table1_wide(long)
    assert list(wide.columns) == ["set", "d", "ours, k=16", "P, k=16"]
    assert list(wide["set"]) == ["F15E", "Fp8"] and list(wide["P, k=16"]) == [1.1, 0.19]


@pytest.mark.parametrize("n", [1, 2])
def test_the_correlation_captions_count_in_number(n):
    """issue 39: the captions of the two matrices and the task's label write each count with its word in number."""
    matrix = pd.DataFrame([[1.0]], index=["F15E"], columns=["F15E"])
    matrix.attrs = {"n_queries": n, "documents": n, "frames": n, "k": n, "clips": n, "n_first": n, "chance": 0.5}
    s = "" if n == 1 else "s"
    pose = corr_page.CorrelationsPage._pose_caption(matrix, sampled=True)
    assert pose.startswith(f"{n} random query frame{s} of the sample's {n} clip{s} ({n} frame{s}), their k = {n} "
                           f"nearest frame{s}"), pose
    assert f"all {n} document{s} (no sample)" in corr_page.CorrelationsPage._pose_caption(matrix, sampled=False)
    segment = corr_page.CorrelationsPage._segment_caption(matrix)
    assert segment.startswith(f"DTW between all pairs of the {n} clip{s} ({n} frame{s}); ρ over the first {n} "
                              f"clip{s} of each ranking."), segment
