"""An uploaded take as the query (issue 40, 1; docs/dashboard.md, "Your take as the query"): in headless Chromium, a
BVH of a rig the database never saw (AnimatedDrawings' CMU-style jumping jacks, 30 Hz, from the peer readers'
archive) and a CMU C3D are searched on the Similarity and Relational pages with the tables the library gives for the
same file; a truncated BVH shows its typed error naming the file, a take of too many frames is refused, the session's
folder is gone once it closes, and "Add to the database" adds the take. Without a browser: the size limit, an AMC
without its ASF, a zip of AMC + ASF, and the button's absence for a role that may not add takes."""

from __future__ import annotations

import io
import re
import shutil
import tarfile
import time
import zipfile
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest
from browser_helpers import assert_no_exception_names, in_own_loop, open_dashboard, open_tab, pick_document, text_of
from playwright.sync_api import expect

from mocapviz import MotionDB
from mocapviz.app import upload as upload_module
from mocapviz.app.backend import Backend
from mocapviz.app.state import Selection
from mocapviz.app.upload import MAX_UPLOAD_BYTES, UploadBox, read_upload
from mocapviz.engine import Engine
from mocapviz.errors import MocapFormatError, ParameterError
from mocapviz.io import datasets, find_asf

BVH = "animdraw_cmu1_jumping_jacks.bvh"  # 125 frames at 30 Hz, 31 joints of CMU-style names, mixed rotation orders
C3D = "cmu_07_01.c3d"
RELATIONAL_SET = "2005"


@pytest.fixture(scope="module")
def peer_bvh(tmp_path_factory) -> Path:
    """The peer readers' jumping-jacks BVH, unpacked from ../shared/data/peer-readers.tar.xz (not a registered
    archive of mocapviz.io.datasets)."""
    url = datasets.data_url()
    if not url.startswith("file://"):
        pytest.skip(f"the peer readers' archive is read from a folder; {url} is not one")
    archive = Path(urlsplit(url).path) / "peer-readers.tar.xz"
    folder = tmp_path_factory.mktemp("peer")
    with tarfile.open(archive) as tar:
        member = tar.getmember(f"peer-readers/bvh/{BVH}")
        tar.extractall(folder, members=[member], filter="data")
    return folder / "peer-readers" / "bvh" / BVH


def _upload(page, css: str, *files) -> None:
    page.locator(f"{css}-input input[type=file]").set_input_files([str(f) for f in files])


def _cells(page, table_css: str, field: str, rows: int) -> list[str]:
    """The texts of column ``field`` in the first ``rows`` rows of a Tabulator."""
    cells = page.locator(f"{table_css} .tabulator-row .tabulator-cell[tabulator-field='{field}']")
    return [cells.nth(i).inner_text().strip() for i in range(rows)]


def _searched(page, path: Path, db) -> None:
    """Search the uploaded take on the Similarity page: the table is Engine(db).clips(path) (defaults: exact, K 10)."""
    page.locator(".mv-search-run button").click()
    expect(page.locator(".mv-search-count")).to_contain_text(f"like uploaded {path.name}", timeout=120_000)
    expected = Engine(db).clips(str(path), n_matches=10, mode="exact")
    assert _cells(page, ".mv-search-table", "doc_id", len(expected)) == [str(d) for d in expected["doc_id"]]


def _queried(page, path: Path, db) -> None:
    """Run the Relational page's query of the uploaded take: its hits are Engine(db).query(path) with the query the
    library suggests for the file."""
    page.locator(".mv-run button:not([disabled])").click()
    engine = Engine(db)
    q = engine.suggest_query(str(path), relational_set=RELATIONAL_SET)
    expected = engine.query(str(path), features=list(q.features), mode=q.mode, mismatches=q.mismatches,
                            relational_set=RELATIONAL_SET)  # fmt: skip
    count = page.locator(".mv-hit-count", has_text=re.compile(rf"^{len(expected)} hits? for "))
    count.wait_for(timeout=120_000)
    shown = min(len(expected), 10)
    assert _cells(page, ".mv-hits", "doc_id", shown) == [str(d) for d in expected["doc_id"][:shown]]


@pytest.mark.slow
def test_uploaded_bvh_and_c3d_are_searched_as_the_library_searches_the_files(page, sample_dashboard, sample_db,
                                                                             sample_server_log, peer_bvh, c3d_dir,
                                                                             tmp_path):  # fmt: skip
    open_dashboard(page, sample_dashboard)
    open_tab(page, "Similarity search")
    page.locator(".mv-search-count", has_text="clips").wait_for(timeout=120_000)  # the page's first answer
    c3d = c3d_dir / C3D
    for take in (c3d, peer_bvh):  # the C3D, then the BVH on the Similarity page's upload box
        _upload(page, ".mv-similarity-upload", take)
        frames = Engine(sample_db).example(str(take)).n_frames  # at the sample's 120 Hz
        expect(page.locator(".mv-similarity-upload-info")).to_contain_text(f"uploaded: {take.name} ({frames} frames)",
                                                                            timeout=120_000)  # fmt: skip
        expect(page.locator(".mv-similarity-query")).to_contain_text(f"uploaded {take.name}")
        _searched(page, take, sample_db)

    open_tab(page, "Relational query")  # the session's query clip is the BVH, all of it
    expect(page.locator(".mv-query-span-info")).to_contain_text(f"{frames} frames", timeout=120_000)
    expect(page.locator(".mv-query-doc input")).to_have_value(f"uploaded: {BVH} ({frames} frames)")
    page.locator(".mv-hit-count", has_text=re.compile(r"hits? for ")).wait_for(timeout=600_000)
    _queried(page, peer_bvh, sample_db)
    _upload(page, ".mv-upload", c3d)  # the C3D on the Relational page's box
    expect(page.locator(".mv-upload-info")).to_contain_text(f"uploaded: {C3D}", timeout=120_000)
    expect(page.locator(".mv-query-span-info")).to_contain_text(f"uploaded: {C3D}")
    _queried(page, c3d, sample_db)

    broken = tmp_path / "broken.bvh"  # the BVH cut inside its frames
    data = peer_bvh.read_bytes()
    broken.write_bytes(data[: len(data) * 2 // 3])
    _upload(page, ".mv-upload", broken)
    error = page.locator(".mv-upload-error")
    expect(error).to_contain_text("Reading broken.bvh failed", timeout=60_000)
    expect(error).to_contain_text(re.compile(r"broken\.bvh, line \d+"))
    long = tmp_path / "long.bvh"  # a take of one frame more than the limit: refused by name, nothing else read
    long.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
                    "Xrotation Yrotation\n End Site\n {\n  OFFSET 0 10 0\n }\n}\nMOTION\nFrames: 100001\n"
                    "Frame Time: 0.0083333\n" + "0 90 0 0 0 0\n" * 100_001)  # fmt: skip
    _upload(page, ".mv-upload", long)
    expect(page.locator(".mv-upload-error", has_text="long.bvh")).to_contain_text(
        "over the upload limit of 100,000 frames", timeout=60_000)
    expect(page.locator(".mv-query-span-info")).to_contain_text(f"uploaded: {C3D}")  # the last good take stays
    assert_no_exception_names(page)

    folders = re.findall(r"uploads of a session in (\S+)", sample_server_log.read_text())
    folder = Path(folders[-1])  # this session's (the sessions of other tests uploaded nothing)
    assert [f.name for f in folder.glob("*/uploads/*")] == [C3D]  # the last take read, the refused ones gone
    page.close()  # the session ends when Bokeh drops it: within 15 + 2 s of its connection closing
    deadline = time.monotonic() + 60
    while folder.exists() and time.monotonic() < deadline:
        time.sleep(1)
    assert not folder.exists()


@pytest.mark.slow
def test_add_to_the_database_ingests_the_take(page, sample_db, serve_dashboard, peer_bvh, tmp_path):
    copy = tmp_path / "db"
    shutil.copytree(sample_db.path, copy)
    open_dashboard(page, serve_dashboard(copy))
    open_tab(page, "Relational query")
    _upload(page, ".mv-upload", peer_bvh)
    expect(page.locator(".mv-upload-info")).to_contain_text(f"uploaded: {BVH}", timeout=120_000)
    page.locator(".mv-upload-add button").click()
    added = page.locator(".mv-upload-info", has_text="added to the database as document")
    added.wait_for(timeout=120_000)
    doc = int(re.search(r"document (\d+)", text_of(page, ".mv-upload-info")).group(1))
    db = MotionDB.open(copy)
    assert len(db) == len(sample_db) + 1 and db.document(doc)["name"] == peer_bvh.stem
    assert db.document(doc)["n_frames"] == Engine(sample_db).example(str(peer_bvh)).n_frames  # at the DB's 120 Hz
    pick_document(page, ".mv-query-doc", doc)  # the picker lists the new document (the server followed)
    expect(page.locator(".mv-query-span-info")).to_contain_text(f"of {peer_bvh.stem}")


# ============================================================================ without a browser
def test_limits_and_pairs_are_read_as_stated(tmp_path):
    engine = Engine(MotionDB.sample())
    with pytest.raises(ParameterError, match=r"big\.bvh: 50\.0 MB is over the upload limit of 50 MB"):
        read_upload(engine, [("big.bvh", b"\0" * (MAX_UPLOAD_BYTES + 1))], tmp_path / "a")
    amc = datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc"
    asf = find_asf(amc)
    with pytest.raises(MocapFormatError, match=rf"{amc.name}: an AMC needs its ASF skeleton"):
        read_upload(engine, [(amc.name, amc.read_bytes())], tmp_path / "b")
    packed = io.BytesIO()
    with zipfile.ZipFile(packed, "w") as z:
        z.writestr(f"take/{amc.name}", amc.read_bytes())
        z.writestr(f"take/{asf.name}", asf.read_bytes())
    take = read_upload(engine, [("take.zip", packed.getvalue())], tmp_path / "c")
    assert (take.name, take.n_frames) == (amc.name, 130)  # the sample's own 120 Hz: as read
    assert take.positions.shape == (130, 24, 3) and take.asf == tmp_path / "c" / "uploads" / asf.name


def test_the_add_button_is_absent_without_the_role(tmp_path, monkeypatch, peer_bvh):
    backend = Backend(MotionDB.sample())
    take = read_upload(backend.engine, [(BVH, peer_bvh.read_bytes())], tmp_path)
    for role_allows in (True, False):
        monkeypatch.setattr(upload_module, "can", lambda user, action, allows=role_allows: allows)
        selection = Selection(doc=0)
        box = UploadBox(backend, selection)
        selection.upload = take
        assert box.add.visible is role_allows


def test_describe_this_clip_describes_the_uploaded_take(tmp_path, peer_bvh):
    from mocapviz.app.pages.describe import DescribePage
    from mocapviz.engine import describe_clip

    backend = Backend(MotionDB.demo())
    selection = Selection(doc=0)
    describe = DescribePage(backend, selection)
    take = read_upload(backend.engine, [(BVH, peer_bvh.read_bytes())], tmp_path)
    selection.param.update(upload=take, use_upload=True, upload_span=(10, 90))
    assert describe.clip_note.object.endswith(f"uploaded {BVH}, frames 10:90")
    in_own_loop(describe._on_describe_clip())
    values, names = Engine(backend.db).clip_relational(str(peer_bvh), frames=(10, 90), relational_set="2005")
    assert describe.editor.value == describe_clip(values, names, f"uploaded {BVH}")
    assert "described from the template 'uploaded animdraw_cmu1_jumping_jacks.bvh'" in describe.editor.value


def test_the_neighbours_of_an_uploaded_frame_are_the_engines(tmp_path, peer_bvh):
    """The Similarity page's kNN takes an uploaded take's frame (it was refused): the library's neighbours of that
    frame of the same file, and the Fig. 1 picture drawn with the take's pose; a frame outside the take is refused
    naming it."""
    from mocapviz.app.pages.similarity import nearest_frames, neighbours_png

    backend = Backend(MotionDB.demo())
    take = read_upload(backend.engine, [(BVH, peer_bvh.read_bytes())], tmp_path)
    table = nearest_frames(backend, "F15E", take, 30, 6, exclude_own=True)
    expected = Engine(backend.db).neighbours(str(peer_bvh), 30, k=6)
    assert table[["doc_id", "start", "end"]].equals(expected[["doc_id", "start", "end"]])
    assert neighbours_png(backend, take, 30, table).startswith(b"\x89PNG")
    with pytest.raises(ParameterError, match=f"frame {take.n_frames} is outside uploaded {BVH}"):
        nearest_frames(backend, "F15E", take, take.n_frames, 6, exclude_own=True)


def test_the_templates_page_learns_from_the_uploaded_take_too(tmp_path, peer_bvh):
    """Motion templates with "learn from the uploaded take too": the class's documents and the take, as
    Engine.learn_template(examples=[file]) learns them; without the box ticked, the documents alone."""
    from mocapviz.app.pages.templates import TemplatesPage

    backend = Backend(MotionDB.demo())
    selection = Selection(doc=5)  # bd's kick: the page opens on kickLFront1Reps
    templates = TemplatesPage(backend, selection)
    take = read_upload(backend.engine, [(BVH, peer_bvh.read_bytes())], tmp_path)
    selection.param.update(upload=take, use_upload=True)
    in_own_loop(templates._run())
    alone = templates.template
    assert alone.meta["extra_examples"] == 0 and "uploaded take" not in templates.count.object
    templates.with_take.value = True
    in_own_loop(templates._run())
    label = templates.label.value
    expected = Engine(backend.db).learn_template(label, examples=[str(peer_bvh)])
    assert templates.template.meta["extra_examples"] == 1 and templates.template.n_examples == alone.n_examples + 1
    assert np.array_equal(templates.template.values, expected.values)
    assert "the uploaded take among its examples" in templates.count.object
