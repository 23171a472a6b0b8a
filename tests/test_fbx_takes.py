"""Every take of an FBX file a document (issue 42, item 1): a real two-take FBX file made by Blender from two Bandai
Namco BVH clips of one rig (tests/blender_takes.py: each clip an action of one armature, exported with
``bake_anim_use_all_actions``, one animation stack per action), read, ingested with a BVH and AMC clips, ingested
again, ingested one take at a time, shown by the Database page and exported on both rigs.

Skips without Blender (the bpy wheel in .cache/blender, ``make blender``), ufbx or the shared archives.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mocapviz import MotionDB, load
from mocapviz.db.ingest import held_documents
from mocapviz.io import datasets
from mocapviz.io.fbx import read_fbx, take_names

pytest.importorskip("ufbx", reason="the FBX reader needs ufbx")

REPO = Path(__file__).resolve().parents[1]
BLENDER_PY = REPO / ".cache" / "blender" / "bin" / "python"  # as tests/test_clients.py finds it
SCRIPT = Path(__file__).with_name("blender_takes.py")
CLIPS = {"bow": "dataset-1_bow_active_001", "bye": "dataset-1_bye_active_001"}  # Bandai Namco 1, one rig, 30 Hz
FRAMES = {"bow": 128, "bye": 185}  # the BVH files' Frames: lines
OBJECT = CLIPS["bow"]  # Blender names a stack <armature object>|<action>; the armature is the first file's
TAKES = {action: f"{OBJECT}|{action}" for action in CLIPS}
BLENDER_CM = 2.0  # Blender's exporter simplifies curves: its FBX stays within 1.1 cm of the BVH (measured)
HDM05 = ("HDM_dg_squat1Reps_033_120", "HDM_mm_squat1Reps_037_120")


@pytest.fixture(scope="module")
def bvh(bandai1_files) -> dict[str, Path]:
    by_stem = {f.stem: f for f in bandai1_files}
    return {action: by_stem[stem] for action, stem in CLIPS.items()}


@pytest.fixture(scope="module")
def two_takes(bvh, tmp_path_factory) -> Path:
    """``two.fbx``: the bow clip and the bye clip as two takes of one armature, written by Blender."""
    if not BLENDER_PY.exists():
        pytest.skip(f"Blender (the bpy wheel) is not installed: `make blender` ({BLENDER_PY})")
    out = tmp_path_factory.mktemp("takes") / "two.fbx"
    run = subprocess.run([str(BLENDER_PY), str(SCRIPT), str(out), str(bvh["bow"]), "bow", str(bvh["bye"]), "bye"],
                         capture_output=True, text=True, timeout=300, check=False)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    made = json.loads(run.stdout.strip().splitlines()[-1])
    assert made["actions"] == {a: [1.0, float(n)] for a, n in FRAMES.items()} and made["fps"] == 30
    return out


def _common(a, b) -> tuple[list[int], list[int]]:
    """Indices in ``a`` and in ``b`` of the joints both name (the BVH's End Sites are not in the FBX)."""
    names = [n for n in a.joint_names if n in b.joint_names]
    return [a.joint_names.index(n) for n in names], [b.joint_names.index(n) for n in names]


def test_the_takes_are_the_two_clips(two_takes, bvh):
    """Blender wrote one stack per action; each take read is its BVH clip: its frame count, its rate, its joints'
    positions frame by frame (a shift of one frame is far off)."""
    assert take_names(two_takes) == (TAKES["bow"], TAKES["bye"])
    for action, take in TAKES.items():
        fbx, clip = read_fbx(two_takes, take=take), load(bvh[action])
        assert fbx.labels["take"] == take
        assert fbx.n_frames == clip.n_frames == FRAMES[action]
        assert fbx.fps == pytest.approx(clip.fps, rel=1e-5)  # Blender's 30 fps: 30.00003 in the file
        i, j = _common(fbx, clip)
        assert len(i) == 22
        err = np.linalg.norm(fbx.positions[:, i] - clip.positions[:, j], axis=-1).max()
        shifted = np.linalg.norm(fbx.positions[1:, i] - clip.positions[:-1, j], axis=-1).max()
        assert err < BLENDER_CM < shifted, (action, err, shifted)
    assert read_fbx(two_takes).labels["take"] == TAKES["bow"]  # no take asked: the first


@pytest.fixture(scope="module")
def mixed(two_takes, bvh, tmp_path_factory) -> MotionDB:
    """A database of the two-take FBX file, a BVH file and two AMC files, ingested at once (each at its own rate)."""
    amc = datasets.sample() / "hdm05-cut" / "amc"
    files = [two_takes, bvh["bow"], *(amc / f"{name}.amc" for name in HDM05)]
    return MotionDB.ingest(files, tmp_path_factory.mktemp("mixed") / "db", progress=False)


def test_ingest_makes_a_document_of_each_take(mixed, two_takes):
    docs = mixed.documents
    names = [f"two#{TAKES['bow']}", f"two#{TAKES['bye']}", CLIPS["bow"], *HDM05]
    assert docs["name"].tolist() == names
    assert docs["format"].tolist() == ["fbx", "fbx", "bvh", "amc", "amc"]
    assert docs["fbx_take"].iloc[:2].tolist() == [TAKES["bow"], TAKES["bye"]] and docs["fbx_take"].iloc[2:].isna().all()
    assert docs["sha256"].iloc[0] == docs["sha256"].iloc[1]  # one file, two documents
    for row in docs.iloc[:2].itertuples():
        take = read_fbx(two_takes, take=row.fbx_take)
        assert (row.n_frames, row.fps, row.source_fps) == (take.n_frames, take.fps, take.fps)
        np.testing.assert_array_equal(mixed.motion(row.doc_id).positions, take.canonical().positions)
        assert mixed.motion(row.doc_id).labels["fbx_take"] == row.fbx_take
    assert docs["n_frames"].iloc[:3].tolist() == [FRAMES["bow"], FRAMES["bye"], FRAMES["bow"]]
    assert docs["n_frames"].iloc[3:].tolist() == [159, 189]  # the AMC files' frames (their labels.tsv)
    assert docs["fps"].iloc[3:].tolist() == [120.0, 120.0]


def test_ingest_again_adds_nothing(mixed, two_takes, bvh):
    again = mixed.append([two_takes, bvh["bow"]], progress=False)
    assert len(again) == len(mixed) and again.manifest["generation"] == mixed.manifest["generation"]
    reopened = MotionDB.open(mixed.path)
    assert reopened.documents["fbx_take"].dtype == "string"  # text with missing cells, not objects
    assert reopened.select(fbx_take=TAKES["bye"])["name"].tolist() == [f"two#{TAKES['bye']}"]


def test_one_take_then_the_rest(two_takes, tmp_path, capsys):
    """``--take NAME`` reads that take only (named as ingest names it when it reads all); a later ingest without it
    adds the file's other take and nothing else; a take the file lacks is refused, naming its takes."""
    from mocapviz.cli import main

    quiet = ["--no-cluster", "--quiet"]
    assert main(["ingest", str(two_takes), "--out", str(tmp_path / "bad"), "--take", "walk", *quiet]) != 0
    said = capsys.readouterr().err
    assert "two.fbx" in said and "no take 'walk'" in said and repr(TAKES["bye"]) in said
    assert not (tmp_path / "bad").exists()
    assert main(["ingest", str(two_takes), "--out", str(tmp_path / "db"), "--take", TAKES["bye"], *quiet]) == 0
    one = MotionDB.open(tmp_path / "db")
    assert one.documents[["name", "fbx_take", "n_frames"]].values.tolist() == [
        [f"two#{TAKES['bye']}", TAKES["bye"], FRAMES["bye"]]]  # fmt: skip
    both = one.append(two_takes, progress=False)
    assert both.documents["fbx_take"].tolist() == [TAKES["bye"], TAKES["bow"]]
    assert both.documents["n_frames"].tolist() == [FRAMES["bye"], FRAMES["bow"]]
    assert len(both.append(two_takes, progress=False)) == 2
    assert len(both.append(two_takes, progress=False, take=TAKES["bow"])) == 2


def test_held_documents_keep_old_identities():
    """A document without a take (another format, or an FBX file ingested before takes were recorded) holds its whole
    file; an FBX take holds that take of its file."""
    docs = pd.DataFrame({"sha256": ["a", "b", "b", "c"], "fbx_take": [None, "x", "y", pd.NA]})
    assert held_documents(docs) == {"a": {None}, "b": {"x", "y"}, "c": {None}}
    assert held_documents(docs.drop(columns="fbx_take")) == {"a": {None}, "b": {None}, "c": {None}}


def test_the_database_page_lists_the_takes(mixed):
    from bokeh.document import Document

    from mocapviz.app.backend import Backend
    from mocapviz.app.documents import document_table
    from mocapviz.app.pages.database import DatabasePage
    from mocapviz.app.state import Selection

    table = document_table(mixed.documents)
    assert table["name"].tolist() == mixed.documents["name"].tolist()
    assert table["label"].tolist()[:2] == ["", ""] and table["label"].iloc[3] == "squat1Reps"
    page = DatabasePage(Backend.open(mixed.path), Selection(doc=0, span=(0, 10)))
    page.__panel__().get_root(Document())
    page.text_filter.value_input = "bye"
    assert page.table.value["name"].tolist() == [f"two#{TAKES['bye']}"]


@pytest.mark.parametrize("rig", ["source", "canonical"])
def test_export_of_a_take(mixed, two_takes, rig, tmp_path):
    """The second take's document as BVH: on its source rig the take's own joints (not the file's first take's),
    posed to its positions; on the canonical rig the database's 24 joints. AMC is refused (no ASF rig)."""
    from mocapviz.errors import ParameterError
    from mocapviz.export import export_stretch

    doc = int(mixed.select(fbx_take=TAKES["bye"])["doc_id"].iloc[0])
    (path,) = export_stretch(mixed, doc, tmp_path, 10, 60, format="bvh", rig=rig)
    back = load(path)
    assert back.n_frames == 50
    if rig == "source":
        take = read_fbx(two_takes, take=TAKES["bye"])
        i, j = _common(back, take)
        assert len(i) == take.n_joints
        np.testing.assert_allclose(back.positions[:, i], take.positions[10:60, j], atol=1e-3)
    else:
        np.testing.assert_allclose(back.canonical().positions, mixed.motion(doc).positions[10:60], atol=1e-3)
    with pytest.raises(ParameterError, match="'amc' copies the frames of an ASF/AMC source"):
        export_stretch(mixed, doc, tmp_path / "amc", format="amc")
