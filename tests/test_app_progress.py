"""Task (mocapviz.app.progress): a page's long computation in a worker thread, its errors as one line without an
exception type."""

from __future__ import annotations

import asyncio
import logging
import threading

import panel as pn

from mocapviz.app.progress import Task
from mocapviz.errors import ParameterError


def _run(coroutine):
    """Run a coroutine on a fresh event loop in its own thread (the browser tests' Playwright holds this thread's
    loop); return (result, the loop's thread)."""
    out = {}

    def main():
        out["thread"] = threading.current_thread()
        out["result"] = asyncio.run(coroutine)

    thread = threading.Thread(target=main)
    thread.start()
    thread.join()
    return out["result"], out["thread"]


def test_result_comes_from_a_worker_thread_and_the_button_is_freed():
    task, button = Task(), pn.widgets.Button(label="Run")
    seen = {}

    def work(x):
        seen["thread"], seen["disabled"] = threading.current_thread(), button.disabled
        return 2 * x

    result, loop_thread = _run(task.run("Doubling", work, 21, busy=button))
    assert result == 42
    assert seen["thread"] is not loop_thread and seen["disabled"] is True
    assert button.disabled is False and task.bar.active is False
    assert task.status.object.startswith("Doubling: done in") and not task.error.visible


def test_a_users_error_is_its_message_alone_and_one_log_line(caplog):
    task, button = Task(), pn.widgets.Button(label="Run")

    def fail():
        raise ParameterError("k = 9 is larger than the prior (5 frames)")

    with caplog.at_level(logging.WARNING, logger="mocapviz.app"):
        assert _run(task.run("Reconstructing", fail, busy=[button]))[0] is None
    assert task.error.visible and button.disabled is False
    assert task.error.object == "**Reconstructing failed.** k = 9 is larger than the prior (5 frames)"
    assert [(r.levelname, r.getMessage(), r.exc_info) for r in caplog.records] == [
        ("WARNING", "Reconstructing refused: k = 9 is larger than the prior (5 frames)", None)]


def test_an_unexpected_error_is_generic_on_the_page_with_its_traceback_in_the_log(caplog):
    task = Task()

    def fail():
        raise ZeroDivisionError("division by zero")

    with caplog.at_level(logging.WARNING, logger="mocapviz.app"):
        assert _run(task.run("Searching", fail))[0] is None
    assert task.error.object == "**Searching failed** (an unexpected error); see the server log."
    assert "ZeroDivisionError" not in task.error.object and "division" not in task.error.object
    (record,) = caplog.records
    assert record.levelname == "ERROR" and record.exc_info[0] is ZeroDivisionError


def test_the_red_line_goes_away_when_the_next_run_succeeds():
    task = Task()
    assert _run(task.run("Searching", lambda: 1 / 0))[0] is None
    assert task.error.visible
    assert _run(task.run("Searching", lambda: 2))[0] == 2
    assert not task.error.visible and task.status.object.startswith("Searching: done in")
