"""Task (mocapviz.app.progress): a page's long computation in a worker thread, its errors as one line without an
exception type, no old result left under them; the bounded number boxes of mocapviz.app.widgets."""

from __future__ import annotations

import logging
import threading

import holoviews as hv
import pandas as pd
import panel as pn
from browser_helpers import in_own_loop

from mocapviz.app.progress import Task
from mocapviz.app.widgets import BoundedFloatInput, BoundedIntInput, results_table
from mocapviz.errors import ParameterError
from mocapviz.validation import Interval


def test_result_comes_from_a_worker_thread_and_the_button_is_freed():
    task, button = Task(), pn.widgets.Button(label="Run")
    seen = {}

    def work(x):
        seen["thread"], seen["disabled"] = threading.current_thread(), button.disabled
        return 2 * x

    result, loop_thread = in_own_loop(task.run("Doubling", work, 21, busy=button))
    assert result == 42
    assert seen["thread"] is not loop_thread and seen["disabled"] is True
    assert button.disabled is False and task.bar.active is False
    assert task.status.object.startswith("Doubling: done in") and not task.error.visible


def test_a_users_error_is_its_message_alone_and_one_log_line(caplog):
    task, button = Task(), pn.widgets.Button(label="Run")

    def fail():
        raise ParameterError("k = 9 is larger than the prior (5 frames)")

    with caplog.at_level(logging.WARNING, logger="mocapviz.app"):
        assert in_own_loop(task.run("Reconstructing", fail, busy=[button]))[0] is None
    assert task.error.visible and button.disabled is False
    assert task.error.object == "**Reconstructing failed.** k = 9 is larger than the prior (5 frames)"
    assert [(r.levelname, r.getMessage(), r.exc_info) for r in caplog.records] == [
        ("WARNING", "Reconstructing refused: k = 9 is larger than the prior (5 frames)", None)]


def test_an_unexpected_error_is_generic_on_the_page_with_its_traceback_in_the_log(caplog):
    task = Task()

    def fail():
        raise ZeroDivisionError("division by zero")

    with caplog.at_level(logging.WARNING, logger="mocapviz.app"):
        assert in_own_loop(task.run("Searching", fail))[0] is None
    assert task.error.object == "**Searching failed** (an unexpected error); see the server log."
    assert "ZeroDivisionError" not in task.error.object and "division" not in task.error.object
    (record,) = caplog.records
    assert record.levelname == "ERROR" and record.exc_info[0] is ZeroDivisionError


def test_the_red_line_goes_away_when_the_next_run_succeeds():
    task = Task()
    assert in_own_loop(task.run("Searching", lambda: 1 / 0))[0] is None
    assert task.error.visible
    assert in_own_loop(task.run("Searching", lambda: 2))[0] == 2
    assert not task.error.visible and task.status.object.startswith("Searching: done in")


def test_a_failed_run_leaves_no_old_result_under_its_error():
    """The panes of the previous result passed as ``stale`` are emptied when a run fails (a user's error or an
    unexpected one), kept when it succeeds."""
    def shown():
        table = results_table(pd.DataFrame({"rank": [1, 2]}), "t")
        return (table, pn.pane.Markdown("**2 hits**"), pn.pane.HoloViews(hv.Curve([1, 2])),
                pn.Column("player", visible=True))

    task = Task()
    kept = shown()
    assert in_own_loop(task.run("Searching", lambda: 1, stale=kept))[0] == 1
    assert len(kept[0].value) == 2 and kept[1].object and kept[2].object is not None and kept[3].visible
    for error in (ParameterError("k must be between 1 and 4,257"), ZeroDivisionError()):
        def fail(error=error):
            raise error

        table, count, plot, box = shown()
        assert in_own_loop(task.run("Searching", fail, stale=(table, count, plot, box)))[0] is None
        assert task.error.visible
        assert table.value.empty and list(table.value.columns) == ["rank"]  # its columns stay
        assert count.object == "" and plot.object is None and not box.visible


def test_a_box_bounded_by_an_interval_never_takes_what_the_check_refuses():
    """``BoundedFloatInput.within``: δ in (0, 0.5) stepping by 0.01 is the box 0.01–0.49; 0, 0.5 and -1 typed are
    moved inside, each with a note; every value the box keeps passes the library's check."""
    delta = Interval(0.0, 0.5, low_open=True, high_open=True)
    box = BoundedFloatInput.within("δ", 0.1, delta, 0.01)
    assert (box.start, box.end, box.name) == (0.01, 0.49, "δ (0.01–0.49)")
    for typed, kept in ((0.0, 0.01), (0.5, 0.49), (-1.0, 0.01), (0.3, 0.3)):
        box.value = typed
        assert box.value == kept and delta.check(box.value, "delta") == kept
        assert box.note.visible == (typed != kept)
    assert box.note.object == ""
    box.value = 0.0
    assert box.note.object == "**δ** must be 0.01–0.49: 0 was set to 0.01."
    box.value = float("nan")  # a cleared box
    assert box.value == 0.01 and "was empty" in box.note.object


def test_an_optional_box_is_none_when_empty_and_bounded_when_typed():
    """The templates page's max cost: empty means none (not NaN, not the previous value); 5 becomes 1 and -1
    becomes 0, with a note, so the box shows the value that runs."""
    box = BoundedFloatInput.within("max cost", None, Interval(0.0, 1.0), 0.01, optional=True)
    assert box.value is None and box.name == "max cost (0–1, empty: none)"
    box.value = 0.5
    for typed, kept in ((5.0, 1.0), (-1.0, 0.0)):
        box.value = typed
        assert box.value == kept and box.note.visible
    box.value = float("nan")  # cleared in the browser
    assert box.value is None and not box.note.visible


def test_new_bounds_note_only_a_value_the_user_entered():
    """A value the page set (the default, or one passed to set_bounds) moves silently into new bounds; one the user
    typed moves with a note saying so."""
    m = BoundedIntInput("m", 1, 0, 1)
    m.set_bounds(0, 0)
    assert m.value == 0 and not m.note.visible  # the default, moved before any input: no note
    m.set_bounds(0, 4)
    m.value = 3  # typed
    m.set_bounds(0, 2)
    assert m.value == 2 and m.note.object == "**m** must now be 0–2: 3 was set to 2."
    m.set_bounds(0, 1, 1)  # the page sets a value: the user's is gone
    m.set_bounds(0, 0)
    assert m.value == 0 and not m.note.visible
