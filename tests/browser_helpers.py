"""Helpers of the dashboard's browser tests (fixtures `page`, `sample_dashboard`, ... are in conftest.py)."""

from __future__ import annotations

import json
import time
from pathlib import Path

ARTIFACTS = Path(__file__).resolve().parent.parent / "build" / "test-artifacts" / "dashboard"


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


def open_tab(page, name: str) -> None:
    """Click the page tab called ``name`` ("Relational query", "Similarity search", ...)."""
    page.locator(".mv-tabs .bk-tab", has_text=name).click()  # bokeh's tab headers carry no ARIA role


def timed(action, wait) -> float:
    """Milliseconds from ``action()`` (a click) until ``wait()`` returns (the result is shown)."""
    t0 = time.perf_counter()
    action()
    wait()
    return 1000 * (time.perf_counter() - t0)


def record_timing(name: str, value: float, unit: str) -> None:
    """Add a measured figure to build/test-artifacts/dashboard/timings.json (reported, never asserted)."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    out = ARTIFACTS / "timings.json"
    data = json.loads(out.read_text()) if out.exists() else {}
    data[name] = {"value": round(float(value), 3), "unit": unit}
    out.write_text(json.dumps(data, indent=1, sort_keys=True))
