"""mocapviz.datasets on the real shared archives (located as mocapviz.datasets locates them).

MOCAPVIZ_HOME always points into pytest's tmp folders, so the user's cache is never touched.
"""

from __future__ import annotations

import functools
import http.server
import shutil
import threading
import urllib.parse
import urllib.request
from importlib import resources
from pathlib import Path

import pooch
import pytest

from mocapviz import datasets
from mocapviz.datasets import DatasetError
from mocapviz.labels import read_labels_tsv


@pytest.fixture(scope="module")
def archives_folder() -> Path:
    """The local folder that holds the shared archives."""
    url = urllib.parse.urlparse(datasets.data_url())
    if url.scheme != "file":
        pytest.skip(f"these tests need the archives in a local folder, not at {datasets.data_url()}")
    return Path(urllib.request.url2pathname(url.path))


@pytest.fixture(scope="module")
def module_home(tmp_path_factory):
    """A cache shared by this module's tests that fetch hdm05-cut once."""
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(datasets.HOME_ENV, str(home))
        yield home


@pytest.fixture(scope="module")
def hdm05(module_home) -> Path:
    return datasets.fetch("hdm05-cut")


@pytest.fixture
def home(tmp_path, monkeypatch) -> Path:
    """A fresh, empty cache for one test."""
    folder = tmp_path / "home"
    monkeypatch.setenv(datasets.HOME_ENV, str(folder))
    return folder


def test_fetch_hdm05_unpacks_the_full_archive(hdm05, module_home):
    assert hdm05 == module_home.resolve() / "hdm05-cut" / "hdm05-cut"
    table = read_labels_tsv(hdm05 / "labels.tsv")
    assert len(table) == 287
    assert table["frames"].sum() == 70_996
    assert len(list((hdm05 / "amc").glob("*.amc"))) == 287
    assert sorted(p.name for p in (hdm05 / "asf").iterdir()) == [f"HDM_{a}.asf" for a in ("bd", "bk", "dg", "mm", "tr")]


def test_fetch_again_reuses_the_cache_and_info_reports_it(hdm05):
    assert datasets.fetch("hdm05-cut") == hdm05
    cached = datasets.info().set_index("name")["cached"]
    assert cached["hdm05-cut"]
    assert not cached["bandai-namco-2"]


def test_registry_matches_the_manifest(archives_folder):
    manifest = (archives_folder / "MANIFEST.md").read_text(encoding="utf-8")
    assert datasets.names() == ["hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2"]
    for row in datasets.info().itertuples():
        assert f"| {row.name} |" in manifest
        assert f"| {row.sha256} |" in manifest
        assert f"{row.frames:,}" in manifest


def test_info_in_an_empty_cache(home):
    table = datasets.info()
    assert list(table.columns) == ["name", "description", "files", "frames", "fps", "licence", "sha256", "cached"]
    assert not table["cached"].any()


def test_corrupted_archive_is_rejected(archives_folder, home, tmp_path, monkeypatch):
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    copy = mirror / "bandai-namco-1.tar.xz"
    shutil.copyfile(archives_folder / copy.name, copy)
    with copy.open("r+b") as f:
        f.seek(100_000)
        f.write(b"corrupt")
    monkeypatch.setenv(datasets.DATA_URL_ENV, str(mirror))
    expected = datasets.ARCHIVES["bandai-namco-1"].sha256
    with pytest.raises(DatasetError, match="bandai-namco-1.tar.xz") as error:
        datasets.fetch("bandai-namco-1")
    assert expected in str(error.value)
    assert pooch.file_hash(str(copy)) in str(error.value)
    assert not (home / "bandai-namco-1").exists()
    assert not (home / "bandai-namco-1.tar.xz").exists()


def test_file_url_base_location(archives_folder, home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, archives_folder.as_uri())
    folder = datasets.fetch("bandai-namco-1")
    assert folder == home.resolve() / "bandai-namco-1" / "bandai-namco-1"
    assert len(list((folder / "data").glob("*.bvh"))) == 174
    assert (folder / "cfg" / "content_label.txt").is_file()


@pytest.fixture
def http_url(archives_folder):
    """An http:// URL of the archives folder, served on the loopback interface for one test."""
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(archives_folder))
    handler.log_message = lambda *args: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}/"
    server.shutdown()
    server.server_close()
    thread.join()


def test_http_base_location(http_url, home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, http_url)
    folder = datasets.fetch("bandai-namco-1")
    assert len(list((folder / "data").glob("*.bvh"))) == 174


def test_http_missing_archive_is_a_dataset_error(http_url, home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, http_url + "nowhere/")
    with pytest.raises(DatasetError, match="cannot download .*nowhere/bandai-namco-1.tar.xz.*404"):
        datasets.fetch("bandai-namco-1")


def test_interrupted_unpack_leaves_nothing_behind(archives_folder, home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, str(archives_folder))
    unpack_all = pooch.Untar._extract_file

    def unpack_then_fail(self, fname, extract_dir):
        unpack_all(self, fname, extract_dir)
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(pooch.Untar, "_extract_file", unpack_then_fail)
        with pytest.raises(KeyboardInterrupt):
            datasets.fetch("bandai-namco-1")
    assert (home / "bandai-namco-1.tar.xz").is_file()
    assert sorted(p.name for p in home.iterdir()) == ["bandai-namco-1.tar.xz"]
    assert len(list((datasets.fetch("bandai-namco-1") / "data").glob("*.json"))) == 175


def test_unknown_name_lists_the_known_ones(home):
    with pytest.raises(DatasetError, match="unknown dataset 'hdm06'.*hdm05-cut, cmu-asfamc, bandai-namco-1"):
        datasets.fetch("hdm06")


def test_missing_archive_in_the_base_folder(home, tmp_path, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, str(tmp_path))
    with pytest.raises(DatasetError, match="archive not found: .*cmu-asfamc.tar.xz"):
        datasets.fetch("cmu-asfamc")


def test_no_base_location_says_to_set_the_variable(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.DATA_URL_ENV, raising=False)
    monkeypatch.setattr(datasets, "_default_folders", lambda: [tmp_path / "missing"])
    with pytest.raises(DatasetError, match="set MOCAPVIZ_DATA_URL"):
        datasets.data_url()


def test_sample_holds_real_hdm05_and_cmu_files(hdm05, home):
    archive = resources.files("mocapviz") / "data" / "sample.tar.xz"
    assert archive.stat().st_size <= 5 * 1024 * 1024
    folder = datasets.sample()
    assert folder.parent.parent == home.resolve()
    assert folder.parent.name.startswith("sample-")
    assert datasets.sample() == folder
    amc = sorted((folder / "hdm05-cut" / "amc").glob("*.amc"))
    assert len(amc) == 22
    assert all((p.read_bytes() == (hdm05 / "amc" / p.name).read_bytes()) for p in amc)
    cmu = sorted(p.relative_to(folder / "cmu-asfamc").as_posix() for p in folder.glob("cmu-asfamc/amc/*/*.amc"))
    assert cmu == ["amc/martialwalk/135_08.amc", "amc/mjackson/131_01.amc"]
    licence = (folder / "LICENSE.md").read_text(encoding="utf-8")
    assert "CC BY-SA 3.0" in licence and "NSF EIA-0196217" in licence
    assert not list(folder.rglob("*.bvh"))
    table = read_labels_tsv(folder / "hdm05-cut" / "labels.tsv")
    assert table.groupby("actor")["class"].nunique().to_dict() == {"dg": 11, "mm": 11}


def test_unsupported_scheme(home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, "s3://bucket/mocap")
    with pytest.raises(DatasetError, match="unsupported scheme 's3'"):
        datasets.fetch("cmu-asfamc")
