"""The dashboard's downloads (issue 27): under a result table, the selected hit as one motion file or every hit as a
zip; under the player, the clip's query span. Without a browser: the files equal :mod:`mocapviz.export`'s and read
back as the database's frames; in headless Chromium: the Describe page's hits and the player's clip arrive as
downloads with those bytes."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
from browser_helpers import open_dashboard, open_tab
from playwright.sync_api import expect

from mocapviz.app.backend import Backend
from mocapviz.app.downloads import HitDownload, table_download
from mocapviz.app.widgets import HIT_TITLES, hit_columns, results_table
from mocapviz.export import hit_files, hits_zip, stretch_files
from mocapviz.io import load
from mocapviz.motion.skeleton import CANONICAL_JOINTS

KICK = "kick_left"


def _read_back(data: bytes, suffix: str, tmp_path) -> np.ndarray:
    path = tmp_path / f"back{suffix}"
    path.write_bytes(data)
    return load(path, up="y").canonical({c: c for c in CANONICAL_JOINTS}).positions


def test_a_tables_selected_hit_or_all_its_hits(backend, sample_db, kicks, tmp_path):
    assert len(kicks) >= 2
    table = results_table(hit_columns(kicks, HIT_TITLES), "t", HIT_TITLES, selectable=True)
    download = table_download(backend, table, lambda: "kicks", "t-download")
    assert download.button.label == f"Download {len(kicks)} hits (.zip)" and not download.button.disabled
    everything = download._file().getvalue()  # no selection: every hit of the table, a zip
    assert everything == hits_zip(sample_db, kicks, "bvh", "canonical", "kicks")
    assert len(zipfile.ZipFile(io.BytesIO(everything)).namelist()) == len(kicks)

    table.selection = [1]  # one hit: its file, named as the export names it
    hit = kicks.iloc[1]
    assert download.button.label == "Download this hit (.bvh)"
    data = download._file().getvalue()
    (name, expected), = hit_files(sample_db, table.value.iloc[[1]], "bvh", "canonical", "kicks").items()
    assert data == expected and download.button.filename == name and name.startswith("002_")
    assert b'"score": ' in data  # the search's own columns, as in the zip's files
    want = sample_db.positions[sample_db.frames(int(hit["doc_id"]))][hit["start"]:hit["end"]]
    assert np.abs(_read_back(data, ".bvh", tmp_path) - want).max() < 0.01  # the database's frames, cm

    download.format.value = "glb"
    assert download.button.label == "Download this hit (.glb)"
    glb = download._file().getvalue()
    assert glb[:4] == b"glTF" and download.button.filename.endswith(".glb")
    meta = json.loads(glb[20:20 + int.from_bytes(glb[12:16], "little")])["asset"]["extras"]
    assert (meta["doc_id"], meta["frames"], meta["search"]) == (int(hit["doc_id"]), [hit["start"], hit["end"]],
                                                               "kicks")  # fmt: skip

    table.param.update(selection=[], value=table.value.iloc[:0])  # both at once, as the pages do
    assert download.button.disabled and download.button.label == "No hit to download"


def test_a_failed_export_is_said_beside_the_button(backend, sample_db, tmp_path):
    """The source rig of a document whose source file is not where it was ingested: nothing is sent, the reason
    (the typed error's message) is shown."""
    from mocapviz import MotionDB
    from mocapviz.db.hits import hit_table

    copy = tmp_path / "copy.bvh"
    [bvh] = (p for p in stretch_files(sample_db, 7, 0, 40, "bvh", "canonical").values())
    copy.write_bytes(bvh)
    db = MotionDB.ingest([copy], tmp_path / "db", progress=False)
    copy.unlink()
    hits = hit_table(db, [0], [0], [20])
    download = HitDownload(Backend(db), lambda: hits, lambda: "a test", "x")
    download.rig.value = "source"
    assert download._file() is None
    assert download.note.visible and "is gone" in download.note.object and "canonical" in download.note.object
    download.rig.value = "canonical"
    assert download._file() is not None and not download.note.visible


# ============================================================================ in the browser
def test_describe_hits_and_the_players_clip_download(sample_db, sample_dashboard, page, kicks, tmp_path):
    open_dashboard(page, sample_dashboard)
    span = sample_db.documents.set_index("doc_id").loc[0, "n_frames"]
    with page.expect_download() as clip:
        page.locator(".mv-clip-download button").click()
    assert clip.value.suggested_filename == f"001_doc0_{sample_db.document(0)['name']}_0-{span}.bvh"
    want = sample_db.positions[sample_db.frames(0)]
    assert np.abs(_read_back(clip.value.path().read_bytes(), ".bvh", tmp_path) - want).max() < 0.01

    open_tab(page, "Describe")
    editor = page.locator(".mv-describe-editor textarea")
    editor.fill(KICK)
    page.locator(".mv-describe-find button:not([disabled])").click()
    button = page.locator(".mv-describe-download button")  # (the page opened answering its own example first)
    expect(button).to_contain_text(f"Download {len(kicks)} hits")
    with page.expect_download() as every:
        button.click()
    assert every.value.suggested_filename == "hits.zip"
    got = zipfile.ZipFile(io.BytesIO(every.value.path().read_bytes()))
    names = sorted(zipfile.ZipFile(io.BytesIO(hits_zip(sample_db, kicks))).namelist())
    assert sorted(got.namelist()) == names
