"""The dashboard's Database page in headless Chromium, against the embedded sample served by `mocapviz serve`."""

from __future__ import annotations

import re
import time

import pytest
from browser_helpers import free_port, open_dashboard, record_first_answer, record_timing, text_of
from playwright.sync_api import expect

from mocapviz.features import relational_features
from mocapviz.features.segmentation import segment


def test_first_page_lists_documents_and_plays_the_first_clip(sample_db, sample_dashboard, page, screenshot):
    seconds = open_dashboard(page, sample_dashboard)
    record_timing("first_page_s", seconds, "s")
    docs = sample_db.documents
    # the rate, one for all documents, is said in the count line instead of a column (issue 39: 1280 pixels)
    assert text_of(page, ".mv-doc-count") == f"{len(docs)} of {len(docs)} documents · all 120 fps"
    first = docs.iloc[0]
    caption = page.locator(".mv-player-caption").first.inner_text()
    assert f"of {first['n_frames']} " in caption  # one step per frame of the first document
    values, _ = relational_features(sample_db.motion(int(first["doc_id"])), progress=False)
    assert f"{len(segment(values).starts)} segments in the clip" in text_of(page, ".mv-timeline-info")
    # at 1400 pixels the documents table fits beside the player: every column shown, none scrolled out of view
    holder = page.locator(".mv-documents .tabulator-tableholder")
    scroll, client = holder.evaluate("e => [e.scrollWidth, e.clientWidth]")
    assert scroll <= client, (scroll, client)
    table, player = page.locator(".mv-documents").bounding_box(), page.locator(".mv-player").first.bounding_box()
    assert table["x"] + table["width"] <= player["x"]
    assert not page.locator(".mv-documents .tabulator-col[tabulator-field='fps']").is_visible()
    last = page.locator(".mv-documents .tabulator-col[tabulator-field='n_frames']").bounding_box()
    assert last["x"] + last["width"] <= table["x"] + table["width"] + 1
    screenshot("database")


def test_filter_and_select_a_document(sample_db, sample_dashboard, page, screenshot):
    open_dashboard(page, sample_dashboard)
    docs = sample_db.documents
    label = "kickLFront1Reps"
    expected = docs[docs["label"] == label]
    assert len(expected) >= 2
    page.locator(".mv-documents").wait_for()
    choice = page.locator(".choices").first
    choice.click()
    page.keyboard.type(label)
    page.keyboard.press("Enter")
    page.keyboard.press("Escape")
    page.locator(".mv-header").click()  # close the dropdown
    count = page.locator(".mv-doc-count")
    count.get_by_text(f"{len(expected)} of {len(docs)} documents").wait_for()
    target = expected.iloc[-1]
    values, _ = relational_features(sample_db.motion(int(target["doc_id"])), progress=False)
    t0 = time.perf_counter()
    page.locator(".mv-documents").get_by_text(target["name"], exact=True).click()
    caption = page.locator(".mv-player-caption")
    caption.get_by_text(re.compile(rf"of {target['n_frames']} ")).wait_for()
    page.locator(".mv-timeline-info").get_by_text(f"{len(segment(values).starts)} segments in the clip").wait_for()
    record_first_answer("row_click", time.perf_counter() - t0)  # the player and the plots show the clip
    canvas = page.locator(".mv-player canvas")
    expect(canvas).to_have_attribute("data-clips", "1")
    expect(canvas).to_have_attribute("data-frames", "0")  # a new clip starts at its first frame
    screenshot("selected")


def test_player_steps_through_frames(sample_db, sample_dashboard, page):
    open_dashboard(page, sample_dashboard)
    caption = page.locator(".mv-player-caption")
    canvas = page.locator(".mv-player canvas")
    drawn = int(canvas.get_attribute("data-drawn"))
    page.locator(".mv-player button.next").click()
    caption.get_by_text(re.compile(r"^step (?!1 )\d+ of")).wait_for()
    expect(canvas).to_have_attribute("data-frames", "1")
    assert int(canvas.get_attribute("data-drawn")) > drawn


def test_warm_up_fills_what_the_first_clicks_need(sample_db):
    """What `mocapviz serve` runs before it listens: afterwards the Backend holds the kd-tree, the DTW search (its
    kd-tree and coarse database), the F15E features and the relational indexes, and the kernels of the LNG,
    the DTW search and the index queries are compiled."""
    from mocapviz import app
    from mocapviz.app.backend import Backend
    from mocapviz.match import neighbourhood_graph, pruned, time_warping
    from mocapviz.relational import index, scene

    backend = Backend(sample_db)  # not the shared one of Backend.open: its caches start empty
    seconds = app.warm_up(backend)
    assert set(seconds) == {"search", "knn", "lng", "relational", "row_click", "describe", "templates"}
    longest = int(sample_db.documents.loc[sample_db.documents["n_frames"].idxmax(), "doc_id"])
    for kind, name in (("numeric", "F15E"), ("search", "F15E"), ("indexes", "2005"), ("values", "2006")):
        assert backend.engine.holds(kind, name), (kind, name)
    assert backend.is_cached(("relational", longest, "2005"))
    for kernel in (neighbourhood_graph._shortest_paths, neighbourhood_graph._graph_path, pruned.search_ranges,
                   time_warping._accumulate, time_warping._backtrack, index._adaptive_walk, index._mismatch_walk,
                   scene._non_overlapping):
        assert kernel.signatures, kernel


def test_serve_refuses_a_missing_database(tmp_path, capsys):
    from mocapviz.cli import main

    assert main(["serve", str(tmp_path / "no-such-db")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("mocapviz: error:") and "no-such-db" in err and "Traceback" not in err


def test_serving_beyond_localhost_needs_listed_origins_and_warns(sample_db, monkeypatch):
    """On 0.0.0.0 the server refuses to start without allow_origin (at once, before building a dashboard); with it,
    it warns and hands Bokeh exactly the loopback and listed origins, never "*" ([::1], which Bokeh cannot parse, is
    checked by the server's own refusal alone: tests/test_app_hostcheck.py)."""
    from mocapviz import app
    from mocapviz.errors import ParameterError

    port = free_port()
    with pytest.raises(ParameterError, match="--allow-origin HOST:PORT"):
        app.serve(sample_db.path, port=port, address="0.0.0.0", start=False)
    handed = {}
    real = app.pn.serve
    monkeypatch.setattr(app.pn, "serve", lambda *args, **options: handed.update(options) or real(*args, **options))
    with pytest.warns(UserWarning, match="anyone who can reach"):
        server = app.serve(sample_db.path, port=port, address="0.0.0.0", start=False,
                           allow_origin=[f"lab.example.org:{port}"])
    server.stop()
    assert handed["websocket_origin"] == [f"127.0.0.1:{port}", f"localhost:{port}", f"lab.example.org:{port}"]


def test_ready_is_printed_when_the_port_answers(sample_db):
    """`mocapviz serve` warms up first and prints "ready: URL" only once the server listens: a connection made as
    soon as the line is read succeeds at the first try (no retry), and the page and a first query of the warmed-up
    caches follow (GET / answers the dashboard). On glibc the server runs with Python's objects on glibc's heap
    (``PYTHONMALLOC=malloc``): ``mocapviz serve`` restarted itself in the same process."""
    import os
    import queue
    import socket
    import subprocess
    import sys
    import threading
    import urllib.request
    from pathlib import Path

    from mocapviz.heap import _libc

    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(sample_db.path), "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in proc.stdout], daemon=True).start()
    try:
        seen = []
        while not (seen and "ready:" in seen[-1]):
            seen.append(lines.get(timeout=600))  # the warm-up of the sample takes seconds; a hang fails here
        with socket.create_connection(("127.0.0.1", port), timeout=5):  # listening already when the line came
            pass
        environ = Path(f"/proc/{proc.pid}/environ").read_text().split("\0")  # the same pid after the restart
        if _libc() is not None and "PYTHONMALLOC" not in os.environ:  # serve restarted on glibc's heap
            assert "PYTHONMALLOC=malloc" in environ
        assert "warming up" in seen[0] and f"ready: http://127.0.0.1:{port}/" in seen[-1]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=120) as answer:
            assert answer.status == 200 and f"mocapviz · {sample_db.path.name}" in answer.read().decode()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
