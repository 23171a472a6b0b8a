"""Task (mocapviz.app.progress): a page's long computation in a worker thread, its errors as one line."""

from __future__ import annotations

import asyncio
import threading

import panel as pn

from mocapviz.app.progress import Task


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


def test_an_error_is_one_line_naming_its_type():
    task, button = Task(), pn.widgets.Button(label="Run")

    def fail():
        raise ValueError("k = 9 is larger than the prior (5 frames)")

    assert _run(task.run("Reconstructing", fail, busy=[button]))[0] is None
    assert task.error.visible and button.disabled is False
    assert task.error.object == "**Reconstructing failed.** ValueError: k = 9 is larger than the prior (5 frames)"
