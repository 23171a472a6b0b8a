"""mocapviz.io.datasets on the real shared archives (located as mocapviz.io.datasets locates them) and the embedded sample.

MOCAPVIZ_HOME always points into pytest's tmp folders, so the user's cache is never touched. Without the shared
archives (MOCAPVIZ_DATA_URL unset and no ../shared/data beside the checkout) the tests that need them are skipped
with the reason; the tests of the embedded sample and of the error messages run anyway.
"""

from __future__ import annotations

import functools
import http.server
import re
import shutil
import threading
import urllib.parse
import urllib.request
from importlib import resources
from pathlib import Path

import pooch
import pytest

from mocapviz.cli import main
from mocapviz.io import datasets
from mocapviz.io.datasets import DatasetError
from mocapviz.io.labels import read_labels_tsv

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def archives_folder() -> Path:
    """The local folder that holds the shared archives (skips the test when there is none)."""
    try:
        base = datasets.data_url()
    except DatasetError as exc:
        pytest.skip(f"needs the shared archives: {str(exc).splitlines()[0]}")
    url = urllib.parse.urlparse(base)
    if url.scheme != "file":
        pytest.skip(f"these tests need the archives in a local folder, not at {base}")
    return Path(urllib.request.url2pathname(url.path))


@pytest.fixture(scope="module")
def module_home(tmp_path_factory):
    """A cache shared by this module's tests that fetch hdm05-cut once."""
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(datasets.HOME_ENV, str(home))
        yield home


@pytest.fixture(scope="module")
def hdm05(module_home, fetch_archive) -> Path:
    return fetch_archive("hdm05-cut")


@pytest.fixture
def no_data(monkeypatch, tmp_path):
    """No base location: MOCAPVIZ_DATA_URL unset and the package seen as installed outside a checkout."""
    monkeypatch.delenv(datasets.DATA_URL_ENV, raising=False)
    monkeypatch.setattr(datasets, "__file__", str(tmp_path / "site-packages" / "mocapviz" / "io" / "datasets.py"))


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
    flat = " ".join(manifest.split())
    assert datasets.names() == ["hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2", "c3d-markers",
                                "peer-readers"]
    shared = datasets.info().query("not embedded")
    assert shared["name"].tolist() == datasets.names()
    for row in shared.itertuples():
        assert f"| {row.name} |" in manifest
        assert f"| {row.sha256} |" in manifest
        assert (archives_folder / f"{row.name}.tar.xz").stat().st_size == row.size
        if row.name == "peer-readers":  # many sources, each file's in the archive's own manifest
            inner = (datasets.fetch(row.name) / "MANIFEST.md").read_text(encoding="utf-8")
            for repo, commit in re.findall(r"([\w.-]+/[\w.-]+) @ (\w+)", row.source.removeprefix("github.com/")):
                assert f"{repo}@{commit}" in inner, (repo, commit)
            bvh = sorted((datasets.fetch(row.name) / "bvh").glob("*.bvh"))
            frames = [re.search(r"Frames:\s*(\d+)", f.read_text(encoding="latin-1")).group(1) for f in bvh]
            assert len(bvh) == 6 and sum(map(int, frames)) == row.frames
            continue
        assert f"{row.frames:,}" in manifest
        repo, commit = re.search(r"github\.com/([\w.-]+/[\w.-]+)\W*@ (\w+)", row.source).groups()
        assert f"{repo} @ {commit}" in flat, row.source


def test_info_in_an_empty_cache(home):
    table = datasets.info()
    assert list(table.columns) == datasets.INFO_COLUMNS
    assert list(table.columns) == ["name", "description", "files", "frames", "fps", "size", "embedded", "licence",
                                   "source", "sha256", "cached"]
    assert not table["cached"].any()
    assert table["name"].tolist() == [*datasets.names(), "sample", "demo"]
    assert table["embedded"].tolist() == [False] * len(datasets.names()) + [True, True]
    assert table["source"].str.len().gt(0).all() and table["licence"].str.len().gt(0).all()


def test_info_describes_the_embedded_sample(home, no_data):
    sample = datasets.info().set_index("name").loc["sample"]
    archive = resources.files("mocapviz") / "data" / "sample.tar.xz"
    assert sample["embedded"] and not sample["cached"]
    assert sample["size"] == archive.stat().st_size
    assert sample["sha256"] == pooch.file_hash(str(archive))
    folder = datasets.sample()
    assert datasets.info().set_index("name").loc["sample", "cached"]
    readme = (folder / "README.md").read_text(encoding="utf-8")
    assert f"24 motion files, {sample['frames']} frames in total" in readme
    assert sample["fps"] == 120
    assert len(list(folder.rglob("*.amc"))) == 24 and len(list(folder.rglob("*.asf"))) == 4
    assert "CC BY-SA 3.0" in sample["licence"] and "mocap.cs.cmu.edu" in sample["licence"]


def test_fetch_sample_is_the_embedded_sample(home, no_data):
    assert datasets.fetch("sample") == datasets.sample()
    assert datasets.fetch("demo") == datasets.demo()


def test_info_describes_the_embedded_demo(home, no_data):
    demo = datasets.info().set_index("name").loc["demo"]
    archive = resources.files("mocapviz") / "data" / "demo.tar.xz"
    assert demo["size"] == archive.stat().st_size and demo["sha256"] == pooch.file_hash(str(archive))
    folder = datasets.demo()
    readme = (folder / "README.md").read_text(encoding="utf-8")
    assert f"54 motion files, {demo['frames']} frames in total" in readme
    assert len(list(folder.rglob("*.amc"))) == 52 and len(list(folder.rglob("*.c3d"))) == 2
    assert len(list(folder.rglob("*.asf"))) == 5 and not list(folder.rglob("*.bvh"))  # never Bandai Namco's


def test_package_data_stays_under_10_mb_and_each_file_under_6_mb():
    sizes = [p.stat().st_size for p in Path(str(resources.files("mocapviz") / "data")).glob("*.tar.xz")]
    assert sum(sizes) <= 10 * 1024 * 1024 and max(sizes) <= 6_000_000


def test_demo_holds_every_hdm05_class_from_four_actors_and_cmu_kicks_and_punches(home, no_data):
    folder = datasets.demo()
    assert [p.name for p in sorted(folder.iterdir()) if p.is_dir()] == sorted(datasets.DEMO_ORDER)
    table = read_labels_tsv(folder / "hdm05-cut" / "labels.tsv")
    per_class = table.groupby("class")["actor"].nunique()
    assert len(per_class) == 11 and per_class.min() >= 3
    cmu = read_labels_tsv(folder / "cmu-asfamc" / "labels.tsv").set_index("cmu_trial")["description"]
    assert {cmu["04"], cmu["07"], cmu["11"], cmu["09"]} == {"Front Kick", "Mawashigeri", "Yokogeri", "Oiduki"}
    c3d = read_labels_tsv(folder / "c3d-markers" / "labels.tsv")
    assert c3d["file"].tolist() == ["cmu_85_02.c3d"]  # the HDM05 scene take stays unlabelled, on purpose
    licence = (folder / "LICENSE.md").read_text(encoding="utf-8")
    assert "CC BY-SA 3.0" in licence and "NSF EIA-0196217" in licence and "c3d-markers/" in licence


def test_demo_files_are_unchanged_files_of_the_shared_archives(hdm05, home, fetch_archive):
    folder = datasets.demo()
    for name in datasets.DEMO_ORDER:
        shared = fetch_archive(name)
        files = [p for p in (folder / name).rglob("*") if p.suffix in (".amc", ".asf", ".c3d")]
        assert files and all(p.read_bytes() == (shared / p.relative_to(folder / name)).read_bytes() for p in files)


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
    unpack_all = datasets._extract

    def unpack_then_fail(archive, folder):
        unpack_all(archive, folder)
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(datasets, "_extract", unpack_then_fail)
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


def test_no_base_location_says_where_the_archives_come_from(home, no_data):
    with pytest.raises(DatasetError) as error:
        datasets.fetch("hdm05-cut")
    lines = str(error.value).splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("mocap archives not found: set MOCAPVIZ_DATA_URL to a folder or http(s) URL")
    assert "NAME.tar.xz" in lines[0] and "../shared/data" in lines[0] and "'sample' needs none" in lines[0]
    for source in ("resources.mpi-inf.mpg.de/HDM05", "mocap.cs.cmu.edu",
                   "github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset"):
        assert source in lines[1]
        assert any(source in row for row in datasets.info()["source"])
    assert "CC BY-SA 3.0" in lines[1] and "CC BY-NC 4.0" in lines[1]


def test_default_folder_is_only_the_checkouts_shared_data(tmp_path, monkeypatch):
    assert datasets._default_folders() == [REPO.parent / "shared" / "data"]
    installed = tmp_path / "site-packages" / "mocapviz"
    monkeypatch.setattr(datasets, "__file__", str(installed / "io" / "datasets.py"))
    assert datasets._default_folders() == []
    (tmp_path / "site-packages" / "pyproject.toml").parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / "site-packages" / "pyproject.toml").write_text("[project]\n")
    assert datasets._default_folders() == [tmp_path / "shared" / "data"]


def test_installed_package_without_the_variable_has_no_base_location(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.DATA_URL_ENV, raising=False)
    monkeypatch.setattr(datasets, "__file__", str(tmp_path / "site-packages" / "mocapviz" / "io" / "datasets.py"))
    with pytest.raises(DatasetError, match="mocap archives not found"):
        datasets.data_url()


def test_cli_list_shows_every_dataset_with_the_sample_embedded(home, capsys):
    assert main(["datasets", "list"]) == 0
    out = capsys.readouterr().out
    for row in datasets.info().itertuples():
        assert f"{row.name}: {row.description}" in out
        assert f"licence: {row.licence}" in out and f"source: {row.source}" in out
    block = out.split("sample: ", 1)[1]
    assert "5,543 frames at 120 Hz; 1.1 MB .tar.xz; embedded in the package, no download" in block
    assert "28,643 frames at 120 Hz; 5.7 MB .tar.xz; embedded in the package, no download" in out.split("demo: ", 1)[1]
    assert out.splitlines()[-1].endswith(f"cache {home.resolve()} (MOCAPVIZ_HOME)")


def test_cli_list_and_fetch_without_the_archives(home, no_data, capsys):
    assert main(["datasets", "list"]) == 0
    assert "shared archives not found: set MOCAPVIZ_DATA_URL" in capsys.readouterr().out.splitlines()[-1]
    assert main(["datasets", "fetch", "hdm05-cut"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("mocapviz: error: mocap archives not found: set MOCAPVIZ_DATA_URL")
    assert "mocap.cs.cmu.edu" in err and len(err.splitlines()) == 2
    assert main(["datasets", "fetch", "sample"]) == 0
    assert Path(capsys.readouterr().out.strip()) == datasets.sample()


def test_sample_holds_real_hdm05_and_cmu_files(home, no_data):
    archive = resources.files("mocapviz") / "data" / "sample.tar.xz"
    assert archive.stat().st_size <= 5 * 1024 * 1024
    folder = datasets.sample()
    assert folder.parent.parent == home.resolve()
    assert folder.parent.name.startswith("sample-")
    assert datasets.sample() == folder
    amc = sorted((folder / "hdm05-cut" / "amc").glob("*.amc"))
    assert len(amc) == 22
    cmu = sorted(p.relative_to(folder / "cmu-asfamc").as_posix() for p in folder.glob("cmu-asfamc/amc/*/*.amc"))
    assert cmu == ["amc/martialwalk/135_08.amc", "amc/mjackson/131_01.amc"]
    licence = (folder / "LICENSE.md").read_text(encoding="utf-8")
    assert "CC BY-SA 3.0" in licence and "NSF EIA-0196217" in licence
    assert not list(folder.rglob("*.bvh"))
    table = read_labels_tsv(folder / "hdm05-cut" / "labels.tsv")
    assert table.groupby("actor")["class"].nunique().to_dict() == {"dg": 11, "mm": 11}


def test_sample_files_are_unchanged_files_of_the_shared_archives(hdm05, home, fetch_archive):
    folder = datasets.sample()
    amc = sorted((folder / "hdm05-cut" / "amc").glob("*.amc"))
    assert len(amc) == 22
    assert all(p.read_bytes() == (hdm05 / "amc" / p.name).read_bytes() for p in amc)
    cmu = fetch_archive("cmu-asfamc")
    for p in folder.glob("cmu-asfamc/amc/*/*.amc"):
        assert p.read_bytes() == (cmu / p.relative_to(folder / "cmu-asfamc")).read_bytes()


def test_unsupported_scheme(home, monkeypatch):
    monkeypatch.setenv(datasets.DATA_URL_ENV, "s3://bucket/mocap")
    with pytest.raises(DatasetError, match="unsupported scheme 's3'"):
        datasets.fetch("cmu-asfamc")


# ------------------------------------------------------------------------------------ members that must not unpack
def _tar(path: Path, *members: tuple[str, str, str]) -> Path:
    """A small .tar.xz of (name, kind, content or link target) members: kind "file", "dir", "symlink", "hardlink"
    or "device"."""
    import io
    import tarfile

    kinds = {"file": tarfile.REGTYPE, "dir": tarfile.DIRTYPE, "symlink": tarfile.SYMTYPE, "hardlink": tarfile.LNKTYPE,
             "device": tarfile.CHRTYPE}
    with tarfile.open(path, "w:xz") as tar:
        for name, kind, value in members:
            info = tarfile.TarInfo(name)
            info.type, info.mode = kinds[kind], 0o755 if kind == "dir" else 0o644
            data = value.encode() if kind == "file" else b""
            if kind in ("symlink", "hardlink"):
                info.linkname = value
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data) if data else None)
    return path


GOOD = ("evil/README.md", "file", "fine\n")
MALICIOUS = {  # name: (members, the member refused, why)
    "dot-dot": ([GOOD, ("evil/../../outside.txt", "file", "x")], "evil/../../outside.txt", "outside the folder"),
    "absolute": ([GOOD, ("{outside}/outside.txt", "file", "x")], "{outside}/outside.txt", "absolute path"),
    "symlink-out": ([GOOD, ("evil/up", "symlink", "../../..")], "evil/up", "outside the folder"),
    "symlink-absolute": ([GOOD, ("evil/etc", "symlink", "/etc")], "evil/etc", "absolute path '/etc'"),
    "through-a-link": ([GOOD, ("evil/here", "symlink", "."), ("evil/here/../../outside.txt", "file", "x")],
                       "evil/here/../../outside.txt", "outside the folder"),
    "link-then-write": ([("evil", "dir", ""), ("evil/out", "symlink", "../../.."),
                         ("evil/out/outside.txt", "file", "x")], "evil/out", "outside the folder"),
    "hardlink-out": ([GOOD, ("evil/passwd", "hardlink", "../../etc/passwd")], "evil/passwd", "outside the folder"),
    "device": ([GOOD, ("evil/tty", "device", "")], "evil/tty", "device"),
}  # fmt: skip


@pytest.mark.parametrize("data_filter", [True, False], ids=["with tarfile's data filter", "member checks alone"])
@pytest.mark.parametrize("case", list(MALICIOUS))
def test_unpacking_refuses_members_outside_the_folder(case, data_filter, tmp_path, monkeypatch):
    """Whatever the sha256 says: an absolute, ``..``, link-escaping or device member is a DatasetError naming the
    archive and the member, nothing is written outside the cache nor left in it."""
    if not data_filter:
        monkeypatch.setattr(datasets, "_DATA_FILTER", None)  # as on Python < 3.10.12 / 3.11.4
    outside = tmp_path / "outside"
    outside.mkdir()
    members, refused, why = MALICIOUS[case]
    members = [(name.format(outside=outside), kind, value) for name, kind, value in members]
    refused = refused.format(outside=outside)
    archive = _tar(tmp_path / f"{case}.tar.xz", *members)
    cache = outside / "cache" / "deep"  # "../../outside.txt" from the staging folder lands in outside/
    with pytest.raises(DatasetError) as error:
        datasets._unpack(archive, cache / "evil", replace=False)
    message = str(error.value)
    assert f"{case}.tar.xz: member {refused!r} refused" in message and why in message and "\n" not in message
    assert sorted(p.name for p in outside.iterdir()) == ["cache"]  # no outside.txt
    assert list(cache.iterdir()) == []  # no target, no staging folder left
    assert not Path("/etc/evil").exists()


@pytest.mark.parametrize("data_filter", [True, False], ids=["with tarfile's data filter", "member checks alone"])
def test_unpacking_keeps_links_inside_the_folder(data_filter, tmp_path, monkeypatch):
    if not data_filter:
        monkeypatch.setattr(datasets, "_DATA_FILTER", None)
    archive = _tar(tmp_path / "ok.tar.xz", ("ok", "dir", ""), ("ok/a.txt", "file", "a"),
                   ("ok/b.txt", "symlink", "a.txt"), ("ok/sub", "dir", ""), ("ok/sub/c.txt", "symlink", "../a.txt"),
                   ("ok/d.txt", "hardlink", "ok/a.txt"))
    datasets._unpack(archive, tmp_path / "cache" / "ok", replace=False)
    top = tmp_path / "cache" / "ok" / "ok"
    assert [(top / n).read_text() for n in ("a.txt", "b.txt", "sub/c.txt", "d.txt")] == ["a"] * 4
    assert (top / "b.txt").is_symlink()


def test_unreadable_archive_is_a_dataset_error(tmp_path):
    bad = tmp_path / "bad.tar.xz"
    bad.write_bytes(b"not an archive")
    with pytest.raises(DatasetError, match="bad.tar.xz: cannot unpack it"):
        datasets._unpack(bad, tmp_path / "cache" / "bad", replace=False)
    assert list((tmp_path / "cache").iterdir()) == []


def test_fetch_refuses_a_malicious_archive_even_with_its_sha256(tmp_path, home, monkeypatch, capsys):
    """A registered archive whose sha256 matches but which holds a ``..`` member: `mocapviz datasets fetch` says
    which member, in one line, and the cache holds no unpacked folder."""
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    archive = _tar(mirror / "evil.tar.xz", GOOD, ("evil/../../../outside.txt", "file", "x"))
    entry = datasets.Archive(name="evil", description="", files="", frames=0, fps=30, licence="", source="",
                             sha256=pooch.file_hash(str(archive)), size=archive.stat().st_size)
    monkeypatch.setitem(datasets.ARCHIVES, "evil", entry)
    monkeypatch.setenv(datasets.DATA_URL_ENV, str(mirror))
    assert main(["datasets", "fetch", "evil"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("mocapviz: error: evil.tar.xz: member 'evil/../../../outside.txt' refused")
    assert err.count("\n") == 1
    assert not (home / "evil").exists() and not (home / "outside.txt").exists()
    assert not (tmp_path / "outside.txt").exists()
