"""Shared fixtures: the real archives (unpacked once into a cache) and small helpers over them.

The archives come from :func:`mocapviz.io.datasets.fetch` (base location ``MOCAPVIZ_DATA_URL`` or ``../shared/data``
beside the checkout). The cache defaults to ``<repo>/.cache/mocapviz`` so that a second test run does not unpack
again. Without the archives the tests that need them are skipped, with the reason; the tests of the embedded
sample (:func:`mocapviz.io.datasets.sample`) never need them.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from browser_helpers import ARTIFACTS, free_port  # screenshots and measured round trips go to ARTIFACTS

REPO = Path(__file__).resolve().parent.parent
collect_ignore = ["blender_probe.py", "blender_takes.py"]  # run by Blender's Python (tests/test_clients.py, test_fbx_takes.py); they import bpy, which .venv lacks


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: runs over a whole archive and takes more than 10 s")


def _fetch(name: str) -> Path:
    """The unpacked shared archive ``name``; skips the calling test, with the reason, when the archives are absent
    (``MOCAPVIZ_DATA_URL`` unset and no ``../shared/data``, or the archive missing from that folder). A corrupt or
    undownloadable archive is an error, not a skip."""
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    try:
        from mocapviz.io import datasets
    except ImportError as exc:  # pragma: no cover - the package is broken, not the data missing
        pytest.skip(f"mocapviz.io.datasets cannot be imported ({exc}); real-data tests need it")
    try:
        datasets.data_url()
        folder = datasets.fetch(name)
    except datasets.DatasetError as exc:
        if "not found" in str(exc):
            pytest.skip(f"needs the shared archive {name!r}: {str(exc).splitlines()[0]}")
        raise
    return Path(folder)


@pytest.fixture(scope="session")
def fetch_archive():
    """``fetch_archive(name) -> Path``: :func:`_fetch` for tests and fixtures that choose the archive (and the
    ``MOCAPVIZ_HOME`` cache) themselves."""
    return _fetch


@pytest.fixture(scope="session")
def hdm05_dir() -> Path:
    """The unpacked HDM05 cut clips: ``asf/``, ``amc/``, ``labels.tsv``."""
    return _fetch("hdm05-cut")


@pytest.fixture(scope="session")
def cmu_dir() -> Path:
    """The unpacked CMU trials: ``asf/``, ``amc/<group>/``, ``labels.tsv``."""
    return _fetch("cmu-asfamc")


@pytest.fixture(scope="session")
def bandai1_dir() -> Path:
    """The unpacked Bandai Namco dataset 1: ``data/*.bvh`` (+ ``.json``), ``cfg/``."""
    return _fetch("bandai-namco-1")


@pytest.fixture(scope="session")
def bandai2_dir() -> Path:
    """The unpacked Bandai Namco dataset 2 (2,902 BVH files, about 0.5 GB unpacked): for slow tests only."""
    return _fetch("bandai-namco-2")


@pytest.fixture(scope="session")
def c3d_dir() -> Path:
    """The unpacked C3D marker files: 7 CMU trials, 2 HDM05 scene takes, 3 gait-lab files, ``MANIFEST.md``."""
    return _fetch("c3d-markers")


@pytest.fixture(scope="session")
def peer_readers_dir() -> Path:
    """The unpacked files other tools wrote (``bvh/``, ``c3d/``, ``fbx/``, ``MANIFEST.md``); its C3D files are GPL
    test data: read them in tests, never copy them into the package."""
    return _fetch("peer-readers")


@pytest.fixture(scope="session")
def round3(tmp_path_factory) -> Path:
    """The reproducers of ``../shared/reliability/round3.tar.xz`` (damaged C3D files, hostile descriptions, export
    tables, fake schedulers), unpacked once: the folder holding ``README.md``, ``c3d/``, ``descriptions/``,
    ``export/``, ``scheduler/``. Skips, with the reason, without ``../shared`` beside the checkout."""
    import tarfile

    archive = REPO.parent / "shared" / "reliability" / "round3.tar.xz"
    if not archive.is_file():
        pytest.skip(f"needs the reproducers {archive} (../shared/reliability beside the checkout)")
    out = tmp_path_factory.mktemp("round3")
    with tarfile.open(archive) as tar:
        tar.extractall(out, filter="data")
    return out / "round3"


@pytest.fixture(scope="session")
def hdm05_labels(hdm05_dir):
    """``labels.tsv`` of HDM05 (file, actor, class, take, frames, fps, split)."""
    import pandas as pd

    return pd.read_csv(hdm05_dir / "labels.tsv", sep="\t")


@pytest.fixture(scope="session")
def bandai1_files(bandai1_dir) -> list[Path]:
    """All BVH files of Bandai Namco 1, sorted."""
    files = sorted((bandai1_dir / "data").glob("*.bvh"))
    assert files, f"no BVH files under {bandai1_dir / 'data'}"
    return files


@pytest.fixture(scope="session")
def hdm05_db30(hdm05_dir, tmp_path_factory):
    """All 287 HDM05 cut clips ingested at 30 Hz (the papers' kNN rate), labelled; shared by the test modules."""
    from mocapviz import MotionDB

    return MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("hdm05-30") / "db", fps=30, progress=False)


@pytest.fixture(scope="session")
def cmu_db30(cmu_dir, tmp_path_factory):
    """The 32 shared CMU trials ingested at 30 Hz."""
    from mocapviz import MotionDB

    return MotionDB.ingest([cmu_dir], tmp_path_factory.mktemp("cmu-30") / "db", fps=30, progress=False)


# ---------------------------------------------------------------------------------------------- dashboard (browser)
CHROMIUM = Path("/usr/bin/chromium")  # Debian's package; never `playwright install` (../shared/design/STACK.md)
# --enable-unsafe-swiftshader: WebGL on the CPU (SwiftShader) with no GPU, which Chromium otherwise stops falling back
# to; three.js draws with it in tests/test_clients.py (the dashboard itself draws with Canvas 2D)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--enable-unsafe-swiftshader"]


@pytest.fixture(scope="session")
def sample_db(tmp_path_factory):
    """The embedded sample (22 HDM05 clips of actors dg and mm, 2 CMU trials) ingested at its own 120 Hz."""
    from mocapviz import MotionDB
    from mocapviz.io import datasets

    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    return MotionDB.ingest([datasets.sample()], tmp_path_factory.mktemp("sample") / "db", progress=False)


@pytest.fixture(scope="module")
def backend(sample_db):
    """The dashboard's shared back end of the sample database (:class:`mocapviz.app.backend.Backend`)."""
    from mocapviz.app.backend import Backend

    return Backend.open(sample_db.path)


@pytest.fixture(scope="module")
def kicks(sample_db):
    """The sample's hits of the shipped description ``kick_left`` (a real hit table, through the 2005 indexes)."""
    from mocapviz.relational import index
    from mocapviz.relational.scene import find

    return find(sample_db, "kick_left", indexes=index.load_or_build(sample_db, "2005"))


def _serve(db_path: Path, log_dir: Path, options=()):
    """Start ``mocapviz serve DB --port P [OPTIONS]`` in a subprocess (``{port}`` in an option stands for P); wait
    until it answers; return (url, process, log)."""
    import subprocess
    import sys
    import time
    import urllib.request

    port = free_port()
    log = log_dir / f"serve-{port}.log"
    proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "serve", str(db_path), "--port", str(port),
                             *(option.format(port=port) for option in options)],
                            stdout=log.open("w"), stderr=subprocess.STDOUT, cwd=REPO)
    url = f"http://127.0.0.1:{port}/"
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"mocapviz serve exited with {proc.returncode}:\n{log.read_text()}")
        try:
            with urllib.request.urlopen(url, timeout=5) as r:
                if r.status == 200:
                    return url, proc, log
        except OSError:
            time.sleep(0.3)
    proc.kill()
    pytest.fail(f"mocapviz serve did not answer on {url} within 180 s:\n{log.read_text()}")


@pytest.fixture(scope="session")
def serve_dashboard(tmp_path_factory):
    """``serve_dashboard(db_path, *options) -> url``: the dashboard of a MotionDB served by ``mocapviz serve`` in a
    subprocess, with more ``serve`` arguments in ``options`` (``{port}`` standing for its port), one per database
    and options for the whole session, stopped at the end."""
    servers: dict = {}
    log_dir = tmp_path_factory.mktemp("serve")

    def get(db_path, *options) -> str:
        key = (str(db_path), options)
        if key not in servers:
            servers[key] = _serve(Path(db_path), log_dir, options)
        return servers[key][0]

    get.log_of = lambda url: next(log for u, _, log in servers.values() if u == url)  # the server's output file
    get.pid_of = lambda url: next(proc.pid for u, proc, _ in servers.values() if u == url)  # its process
    yield get
    for _, proc, _ in servers.values():
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except Exception:  # noqa: BLE001 - a server that ignores SIGTERM is killed
            proc.kill()


@pytest.fixture(scope="session")
def sample_dashboard(sample_db, serve_dashboard) -> str:
    """URL of the dashboard over :func:`sample_db`."""
    return serve_dashboard(sample_db.path)


@pytest.fixture
def sample_server_log(sample_dashboard, serve_dashboard) -> Path:
    """The output file (stdout and stderr) of the server of :func:`sample_dashboard`."""
    return serve_dashboard.log_of(sample_dashboard)


@pytest.fixture(scope="session")
def hdm05_dashboard(hdm05_db30, serve_dashboard) -> str:
    """URL of the dashboard over all 287 HDM05 clips at 30 Hz (:func:`hdm05_db30`)."""
    return serve_dashboard(hdm05_db30.path)


@pytest.fixture(scope="session")
def chromium() -> Path:
    """Debian's Chromium (/usr/bin/chromium). Without it the browser tests are skipped, unless
    MOCAPVIZ_REQUIRE_BROWSER=1 (set by `make test`), when they fail."""
    if not CHROMIUM.exists():
        message = f"{CHROMIUM} not found: `apt-get install chromium` (make test does)"
        if os.environ.get("MOCAPVIZ_REQUIRE_BROWSER") == "1":
            pytest.fail(message)
        pytest.skip(message)
    return CHROMIUM


@pytest.fixture(scope="session")
def browser(chromium):
    """Headless Debian Chromium driven by Playwright (skipped without it: :func:`chromium`)."""
    from playwright.sync_api import expect, sync_playwright

    expect.set_options(timeout=30_000)  # a loaded 2-core machine renders slowly; round trips are measured, not bounded
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(chromium), args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    """A fresh browser page (1400 x 1000); the test fails if the page logs any console error or uncaught exception.
    ``page.console_errors`` lists them as they come."""
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    pg = context.new_page()
    pg.set_default_timeout(60_000)
    errors: list[str] = []
    pg.on("console", lambda m: errors.append(f"console.{m.type}: {m.text}") if m.type == "error" else None)
    pg.on("pageerror", lambda e: errors.append(f"uncaught: {e}\n{e.stack}"))
    pg.console_errors = errors
    yield pg
    context.close()
    assert not errors, "browser console errors:\n" + "\n".join(errors)


@pytest.fixture
def screenshot(page, request):
    """``screenshot(name)`` saves a full-page PNG of the page under build/test-artifacts/dashboard/."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)

    def take(name: str) -> Path:
        out = ARTIFACTS / f"{request.node.name}-{name}.png"
        page.screenshot(path=str(out), full_page=True)
        return out

    return take
