"""Helpers of the dashboard's browser tests (fixtures `page`, `sample_dashboard`, ... are in conftest.py)."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

ARTIFACTS = Path(__file__).resolve().parent.parent / "build" / "test-artifacts" / "dashboard"


def in_own_loop(coroutine):
    """Run a coroutine on a fresh event loop in its own thread (the browser tests' Playwright holds this thread's
    loop); return (result, the loop's thread)."""
    import asyncio
    import threading

    out = {}

    def main():
        out["thread"] = threading.current_thread()
        out["result"] = asyncio.run(coroutine)

    thread = threading.Thread(target=main)
    thread.start()
    thread.join()
    return out["result"], out["thread"]


def free_port() -> int:
    """A TCP port of 127.0.0.1 that nothing listens on now."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def open_dashboard(page, url: str) -> float:
    """Load the dashboard; return the seconds until the first page (the player's first frame) is visible."""
    t0 = time.perf_counter()
    page.goto(url)
    page.locator(".mv-player canvas[data-drawn]").first.wait_for(state="visible")
    return time.perf_counter() - t0


def text_of(page, css: str) -> str:
    """The text of a Panel pane with css class ``css`` (its content lives in the pane's shadow root)."""
    return page.locator(f"{css} div").first.inner_text().strip()


_ALL_TEXT = """() => {  // the text of the page, inside Panel's shadow roots too (innerText of the body misses it)
    const parts = [];
    const walk = (root) => {
        for (const el of root.querySelectorAll('*')) {
            if (el.shadowRoot) walk(el.shadowRoot);
            if (el.tagName === 'STYLE' || el.tagName === 'SCRIPT') continue;
            for (const node of el.childNodes) {
                if (node.nodeType === 3 && node.textContent.trim()) parts.push(node.textContent);
            }
        }
    };
    walk(document);
    return parts.join(' ');
}"""
EXCEPTION_NAME = re.compile(r"\b[A-Z]\w*(Error|Exception)\b|Traceback")  # ValueError, KeyError, MocapvizError, ...


def page_text(page) -> str:
    """All the text the page holds, shadow roots included."""
    return page.evaluate(_ALL_TEXT)


def assert_no_exception_names(page) -> None:
    """Fail when an exception's class name or a traceback shows anywhere on the page."""
    found = EXCEPTION_NAME.search(page_text(page))
    assert found is None, f"the page shows {found.group(0)!r}"


def open_tab(page, name: str) -> None:
    """Click the page tab called ``name`` ("Relational query", "Similarity search", ...)."""
    page.locator(".mv-tabs .bk-tab", has_text=name).click()  # bokeh's tab headers carry no ARIA role


def pick_document(page, css: str, doc: int) -> None:
    """Choose document ``doc`` in the document picker of css class ``css`` (mocapviz.app.documents.DocumentPicker):
    type its id as the list writes it ("7: ") and click the match that starts with it. Typing starts once the page
    holds a picker offering the document (choices that change while the menu is open make BokehJS throw), with the
    mouse away from where the menu opens: a menu item under a resting pointer takes the hover, and BokehJS throws when
    the next key narrows the menu below it (``_bump_hover``, ``change_input``)."""
    page.wait_for_function("""(prefix) => window.Bokeh && Bokeh.documents.some((d) => [...d.all_models].some(
        (m) => Array.isArray(m.completions) && m.completions.some((c) => c.startsWith(prefix))))""", arg=f"{doc}: ")
    page.mouse.move(0, 0)
    box = page.locator(f"{css} input")
    box.fill("")
    box.press_sequentially(f"{doc}: ")
    page.locator(f"{css} .bk-menu > div", has_text=re.compile(rf"^{doc}: ")).first.click()


def picked_document(page, css: str) -> int:
    """The id of the document a picker shows."""
    return int(page.locator(f"{css} input").input_value().split(":")[0])


def timed(action, wait) -> float:
    """Milliseconds from ``action()`` (a click) until ``wait()`` returns (the result is shown)."""
    t0 = time.perf_counter()
    action()
    wait()
    return 1000 * (time.perf_counter() - t0)


def _timings() -> tuple[Path, dict]:
    """timings.json and what it holds; entries of the older form {"value": v, "unit": u} become plain numbers, their
    units moving to "units"."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    out = ARTIFACTS / "timings.json"
    data = json.loads(out.read_text()) if out.exists() else {}
    units = data.setdefault("units", {})
    for name, entry in list(data.items()):
        if isinstance(entry, dict) and set(entry) == {"value", "unit"}:
            data[name], units[name] = entry["value"], entry["unit"]
    return out, data


def record_timing(name: str, value: float, unit: str) -> None:
    """Add a measured figure to build/test-artifacts/dashboard/timings.json (reported, never asserted): ``name``
    holds the number, ``units[name]`` its unit."""
    out, data = _timings()
    data[name] = round(float(value), 3)
    data["units"][name] = unit
    out.write_text(json.dumps(data, indent=1, sort_keys=True))


def record_figures(name: str, values: dict, unit: str) -> None:
    """Add a group of measured figures (``{key: number}``) to timings.json under ``name``, ``units[name]`` their
    unit: e.g. the p95 seconds of each kind of answer."""
    out, data = _timings()
    data[name] = {key: round(float(v), 3) for key, v in values.items()}
    data["units"][name] = unit
    out.write_text(json.dumps(data, indent=1, sort_keys=True))


_FIRST_ANSWERS: set[str] = set()  # the actions measured in this test session (one server per database and session)


def record_first_answer(action: str, seconds: float) -> None:
    """Record the seconds from a click to its result under ``first_answer_s[action]`` in timings.json ("knn",
    "search", "lng", "relational", "row_click", "open", "template", "describe"), for the first such click of the test session only: the first after
    the session's `mocapviz serve` started, which its warm-up must have made fast. Later calls are ignored."""
    if action in _FIRST_ANSWERS:
        return
    _FIRST_ANSWERS.add(action)
    out, data = _timings()
    data.setdefault("first_answer_s", {})[action] = round(float(seconds), 3)
    data["units"]["first_answer_s"] = "s from the click to the result shown, first of its kind after the server started"
    out.write_text(json.dumps(data, indent=1, sort_keys=True))


def run_in_thread(coroutine):
    """Run a coroutine (a page's button handler, driven without a browser) on a fresh event loop in a thread of its
    own, and return its result: the browser tests' Playwright holds this thread's loop, so asyncio.run here fails."""
    import asyncio
    import threading

    out = {}

    def main():
        try:
            out["result"] = asyncio.run(coroutine)
        except BaseException as exc:  # noqa: BLE001 - raised again in the calling thread
            out["error"] = exc

    thread = threading.Thread(target=main)
    thread.start()
    thread.join()
    if "error" in out:
        raise out["error"]
    return out["result"]
