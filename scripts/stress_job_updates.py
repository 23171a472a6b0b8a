"""Count the dashboard updates a page misses around its jobs: the measurement behind ``mocapviz.app.jobs`` releasing a
job's memory on the server's event loop.

Usage::

    python scripts/stress_job_updates.py [--rounds 40] [--timeout 20]

``mocapviz serve`` runs on the embedded sample (ingested once into a temporary folder); headless Debian Chromium
(``/usr/bin/chromium``, driven by Playwright) plays rounds of the Retrieval quality page, each in a new browser
context: Evaluate (12 queries, leave-actor-out), Evaluate again with the label as the group (refused: its red line
must show), Evaluate with the actor as the group (its "done" must show). A round whose red line or "done" does not
reach the page within ``--timeout`` seconds counts as a lost update; the last line prints ``lost updates: N of R``.
With the memory released in the job's thread (the code before this script): 2 of 81 rounds lost one; released on
the event loop: 0 of 100.
"""
from __future__ import annotations

import argparse
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from mocapviz import MotionDB
from mocapviz.io import datasets

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _serve(db: Path, port: int, log: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(db), "--port", str(port)],
                            stdout=log.open("w"), stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 180
    while "ready:" not in log.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            sys.exit(f"mocapviz serve did not start:\n{log.read_text()}")
        time.sleep(0.3)
    return proc


def _round(browser, url: str, timeout_ms: float) -> str | None:
    """One round; None when every update arrived, else what was missed."""
    context = browser.new_context()
    try:
        page = context.new_page()
        page.set_default_timeout(120_000)
        page.goto(url)
        page.locator(".mv-player canvas[data-drawn]").first.wait_for(state="visible")
        page.locator(".mv-tabs .bk-tab", has_text="Retrieval quality").click()
        box = page.locator(".mv-retrieval-n input")
        box.fill("12")
        box.press("Enter")
        page.locator(".mv-retrieval-run button").click()
        page.locator(".mv-retrieval-count", has_text="queries").wait_for()
        for group, shown, missed in (("label", ".mv-retrieval-task .mv-error", "the refusal's red line"),
                                     ("actor", ".mv-retrieval-task >> text=Evaluating: done", "the evaluation's done")):
            page.locator(".mv-retrieval-group select").select_option(group)
            page.locator(".mv-retrieval-run button").click()
            try:
                page.locator(shown).first.wait_for(state="visible", timeout=timeout_ms)
            except Exception:  # noqa: BLE001 - Playwright's timeout: the update never reached the page
                return f"{missed} (the task showed {page.locator('.mv-retrieval-task').text_content()!r})"
        return None
    finally:
        context.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=40)
    parser.add_argument("--timeout", type=float, default=20.0, help="seconds an update may take to show")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        db = MotionDB.ingest([datasets.sample()], Path(tmp) / "db", progress=False).path
        port = _free_port()
        server = _serve(db, port, Path(tmp) / "serve.log")
        lost = 0
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
                for i in range(args.rounds):
                    missed = _round(browser, f"http://127.0.0.1:{port}/", 1000 * args.timeout)
                    lost += missed is not None
                    print(f"round {i + 1}: {'ok' if missed is None else 'LOST ' + missed}", flush=True)
                browser.close()
        finally:
            server.terminate()
            server.wait(30)
    print(f"lost updates: {lost} of {args.rounds}")


if __name__ == "__main__":
    main()
