"""MotionDB on the embedded sample and the shared archives: round trip, resampling, append, atomicity."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import mocapviz
from mocapviz import MocapFormatError, MocapFormatWarning, MotionDB, MotionDBError
from mocapviz.io import datasets, load
from mocapviz.motion.skeleton import CANONICAL_JOINTS

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def sample_dir(tmp_path_factory) -> Path:
    os.environ.setdefault("MOCAPVIZ_HOME", str(REPO / ".cache" / "mocapviz"))
    return datasets.sample()


@pytest.fixture(scope="session")
def sample_db(sample_dir, tmp_path_factory) -> MotionDB:
    return MotionDB.ingest(sample_dir, tmp_path_factory.mktemp("db") / "sample.mdb", progress=False)


def _hdm05_table(sample_dir: Path) -> pd.DataFrame:
    return pd.read_csv(sample_dir / "hdm05-cut" / "labels.tsv", sep="\t")


def _state(path: Path) -> dict:
    """Bytes of every file a MotionDB holds, by name (to check that a failed write changed nothing)."""
    return {f.name: f.read_bytes() for f in sorted(path.iterdir()) if f.name != ".lock"}


def test_round_trip_equals_the_readers(sample_db, sample_dir):
    db = MotionDB.open(sample_db.path)
    docs = db.documents
    assert len(docs) == 24 and db.n_frames == docs["n_frames"].sum()
    assert db.positions.shape == (db.n_frames, 24, 3) and db.positions.dtype == np.float32
    assert (docs["start"].to_numpy() == np.concatenate([[0], np.cumsum(docs["n_frames"])[:-1]])).all()
    for row in docs.itertuples():
        ref = mocapviz.load(row.path).canonical()
        got = db.motion(row.doc_id)
        assert got.joint_names == CANONICAL_JOINTS
        np.testing.assert_array_equal(got.positions, ref.positions)
        np.testing.assert_array_equal(got.quaternions, ref.quaternions)
        assert got.fps == 120.0 and got.source == row.path


def test_frame_counts_and_labels_match_labels_tsv(sample_db, sample_dir):
    table = _hdm05_table(sample_dir)
    docs = sample_db.documents.set_index("name")
    for row in table.itertuples():
        doc = docs.loc[Path(row.file).stem]
        assert doc["n_frames"] == row.frames
        assert doc["label"] == row._3 == doc["class"]  # column 'class'
        assert doc["actor"] == row.actor
    cmu = docs.loc["131_01"]
    assert cmu["label"] == "Start Walk Stop" and cmu["cmu_subject"] == "131"


def test_select_by_label_and_actor(sample_db, sample_dir):
    table = _hdm05_table(sample_dir)
    squats = sample_db.select(label="squat1Reps")
    assert len(squats) == (table["class"] == "squat1Reps").sum() == 2
    both = sample_db.select(label=["squat1Reps", "grabHighR"], actor="mm")
    assert set(both["name"]) == {Path(f).stem for f in table.query("actor == 'mm' and `class` in ['squat1Reps', 'grabHighR']")["file"]}
    with pytest.raises(KeyError, match="no column 'colour'"):
        sample_db.select(colour="red")


def test_document_of_maps_frames_back(sample_db):
    docs = sample_db.documents
    frames = np.concatenate([docs["start"], docs["start"] + docs["n_frames"] - 1])
    np.testing.assert_array_equal(sample_db.document_of(frames), np.concatenate([docs["doc_id"]] * 2))


def test_resampling_at_ingest_takes_every_fourth_frame(sample_dir, sample_db, tmp_path):
    db30 = MotionDB.ingest(sample_dir / "hdm05-cut", tmp_path / "db30", fps=30, progress=False)
    assert db30.fps == 30.0
    full = sample_db.documents.set_index("name")
    for row in db30.documents.itertuples():
        src = full.loc[row.name]
        assert row.n_frames == (src["n_frames"] - 1) // 4 + 1
        a = sample_db.positions[src["start"] : src["start"] + src["n_frames"] : 4]
        np.testing.assert_allclose(db30.positions[row.start : row.start + row.n_frames], a, atol=1e-4)


def test_append_continues_ids_and_skips_known_files(sample_dir, tmp_path):
    out = tmp_path / "db"
    first = MotionDB.ingest(sample_dir / "hdm05-cut", out, progress=False)
    assert first.manifest["generation"] == 1
    both = MotionDB.ingest(sample_dir / "cmu-asfamc", out, progress=False)
    assert len(both) == 24 and both.documents["doc_id"].tolist() == list(range(24))
    np.testing.assert_array_equal(both.positions[: first.n_frames], first.positions)
    before = _state(out)
    again = MotionDB.ingest(sample_dir, out, progress=False)  # everything known: nothing written
    assert len(again) == 24 and _state(out) == before


def test_append_at_another_rate_is_refused(sample_dir, tmp_path):
    db = MotionDB.ingest(sample_dir / "hdm05-cut", tmp_path / "db", fps=30, progress=False)
    with pytest.raises(MotionDBError, match="30.0 fps"):
        db.append(sample_dir / "cmu-asfamc", fps=60, progress=False)


def _corrupt_copy(sample_dir: Path, tmp_path: Path) -> tuple[Path, Path]:
    """A copy of the sample's CMU folder with one AMC cut in the middle of a line."""
    src = shutil.copytree(sample_dir / "cmu-asfamc", tmp_path / "cmu-bad")
    bad = next((src / "amc").rglob("135_*.amc"))
    data = bad.read_bytes()
    bad.write_bytes(data[: len(data) // 2] + b"\nlfemur 1.0\n")
    return src, bad


def test_bad_file_stops_and_leaves_the_db_as_it_was(sample_dir, tmp_path):
    out = tmp_path / "db"
    MotionDB.ingest(sample_dir / "hdm05-cut", out, progress=False)
    before = _state(out)
    src, bad = _corrupt_copy(sample_dir, tmp_path)
    with pytest.raises(MocapFormatError) as err:
        MotionDB.ingest(src, out, progress=False)
    assert err.value.path == str(bad) and err.value.line is not None
    assert _state(out) == before
    fresh = tmp_path / "fresh"
    with pytest.raises(MocapFormatError):
        MotionDB.ingest(src, fresh, progress=False)
    assert not fresh.exists()


def test_skip_bad_warns_and_ingests_the_rest(sample_dir, tmp_path):
    src, bad = _corrupt_copy(sample_dir, tmp_path)
    with pytest.warns(UserWarning, match=bad.name):
        db = MotionDB.ingest(src, tmp_path / "db", skip_bad=True, progress=False)
    assert db.documents["name"].tolist() == ["131_01"]


_INTERRUPTED = textwrap.dedent(
    """
    import os, sys
    import mocapviz.db.database as d
    where = sys.argv[3]
    if where == "before-manifest":      # every new file written, the manifest not yet switched
        d.atomic_write = lambda *a, **k: os._exit(3)
    elif where == "mid-array":          # killed while writing the grown positions array
        real = d._write_grown
        def half(old, n_old, new, width, target):
            real(old, n_old, new[: len(new) // 2], width, target.with_name(target.name + ".tmp"))
            os._exit(3)
        d._write_grown = half
    d.MotionDB.ingest(sys.argv[1], sys.argv[2], progress=False)
    """
)


@pytest.mark.parametrize("where", ["before-manifest", "mid-array"])
def test_ingest_killed_during_commit_leaves_the_previous_db(sample_dir, tmp_path, where):
    out = tmp_path / "db"
    old = MotionDB.ingest(sample_dir / "hdm05-cut", out, progress=False)
    proc = subprocess.run([sys.executable, "-c", _INTERRUPTED, str(sample_dir / "cmu-asfamc"), str(out), where], check=False)
    assert proc.returncode == 3
    db = MotionDB.open(out)
    assert len(db) == len(old) == 22 and db.manifest == old.manifest
    np.testing.assert_array_equal(db.positions, old.positions)
    # the next ingest cleans up and completes
    done = MotionDB.ingest(sample_dir / "cmu-asfamc", out, progress=False)
    assert len(done) == 24
    current = [*done.manifest["arrays"].values(), done.manifest["documents"]]
    previous = [f.replace(f".g{done.manifest['generation']}.", f".g{old.manifest['generation']}.") for f in current]
    # no temporary file left; the previous generation's files kept for readers that read its manifest
    assert sorted(f.name for f in out.iterdir() if f.suffix in (".npy", ".parquet", ".tmp")) == sorted(current + previous)


def test_ingest_killed_at_any_moment_leaves_a_readable_db(hdm05_dir, tmp_path):
    """SIGKILL a real ingest of the 287 HDM05 clips at several moments; the DB always opens consistently."""
    for delay in (0.5, 1.5, 3.0, 6.0):
        out = tmp_path / f"db{delay}"
        proc = subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "ingest", str(hdm05_dir), "--out", str(out),
                                 "--quiet"])
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if not (out / "manifest.json").exists():
            assert not out.exists() or not any(f.suffix == ".json" for f in out.iterdir())
            continue
        db = MotionDB.open(out)
        assert len(db) in (0, 287)
        assert db.documents["n_frames"].sum() == db.n_frames


def test_open_checks_format_version_and_consistency(sample_db, tmp_path):
    copy = Path(shutil.copytree(sample_db.path, tmp_path / "copy"))
    manifest = json.loads((copy / "manifest.json").read_text())
    (copy / "manifest.json").write_text(json.dumps({**manifest, "version": 99}))
    with pytest.raises(MotionDBError, match="version 99"):
        MotionDB.open(copy)
    (copy / "manifest.json").write_text(json.dumps({**manifest, "n_frames": manifest["n_frames"] - 1}))
    with pytest.raises(MotionDBError, match="manifest says"):
        MotionDB.open(copy)
    with pytest.raises(MotionDBError, match="not a MotionDB"):
        MotionDB.open(tmp_path)
    with pytest.raises(MotionDBError, match="nosuch: does not exist"):
        MotionDB.open(tmp_path / "nosuch")
    with pytest.raises(MotionDBError, match="not an empty directory"):
        MotionDB.ingest(sample_db.documents["path"].iloc[0], tmp_path, progress=False)


def test_explicit_label_table_overrides(sample_dir, tmp_path):
    amc = sorted((sample_dir / "hdm05-cut" / "amc").glob("*.amc"))[:2]
    table = tmp_path / "mine.csv"
    pd.DataFrame({"file": [str(a) for a in amc], "label": ["first", "second"], "mood": ["calm", "wild"]}).to_csv(
        table, index=False
    )
    db = MotionDB.ingest(amc, tmp_path / "db", labels=table, progress=False)
    assert db.documents["label"].tolist() == ["first", "second"]
    assert db.documents["mood"].tolist() == ["calm", "wild"]


def test_bandai_labels_and_mixed_sources(bandai1_files, sample_dir, tmp_path):
    files = bandai1_files[:6]
    db = MotionDB.ingest(files, tmp_path / "db", fps=30, progress=False)
    for row in db.documents.itertuples():
        _, content, style, _ = row.name.split("_")
        assert row.label == row.content == content and row.style == style
    db = db.append(sample_dir / "cmu-asfamc", progress=False)  # 120 Hz AMC resampled to the DB's 30 fps
    assert db.fps == 30.0 and len(db) == 8


def test_ingest_all_hdm05_frames_at_120(hdm05_dir, hdm05_labels, tmp_path):
    db = MotionDB.ingest(hdm05_dir, tmp_path / "db", progress=False, threads=2)
    assert len(db) == 287 and db.n_frames == hdm05_labels["frames"].sum() == 70_996
    counts = db.documents.set_index("name")["n_frames"]
    expect = hdm05_labels.assign(name=[Path(f).stem for f in hdm05_labels["file"]]).set_index("name")["frames"]
    pd.testing.assert_series_equal(counts.sort_index(), expect.sort_index(), check_names=False, check_dtype=False)


def test_ingest_on_threads_equals_serial_and_n_jobs_is_threads_with_a_warning(sample_dir, sample_db, tmp_path):
    """Threads read the files (docs/glossary.md: processes only as Dask workers); the old ``n_jobs=`` still works."""
    on_threads = MotionDB.ingest(sample_dir, tmp_path / "threads", progress=False, threads=3)
    with pytest.warns(FutureWarning, match="n_jobs= is deprecated; pass threads="):
        old = MotionDB.ingest(sample_dir, tmp_path / "old", progress=False, n_jobs=2)
    for db in (on_threads, old):
        assert np.array_equal(db.positions, sample_db.positions)
        assert np.array_equal(db.quaternions, sample_db.quaternions, equal_nan=True)
        pd.testing.assert_frame_equal(db.documents.drop(columns="path"), sample_db.documents.drop(columns="path"))
    with pytest.raises(mocapviz.ParameterError, match="threads must be"):
        MotionDB.ingest(sample_dir, tmp_path / "bad", progress=False, threads=0)
    assert not (tmp_path / "bad").exists()


def test_append_motions_adds_derived_clips(sample_dir, tmp_path):
    """Mirrored copies held in memory are appended after the files, with their labels and given columns."""
    from mocapviz.motion.skeleton import mirror

    db = MotionDB.ingest(sample_dir / "hdm05-cut", tmp_path / "db", fps=30, progress=False)
    ids = db.documents["doc_id"].to_numpy()[:3]
    copies = [mirror(db.motion(int(i))) for i in ids]
    grown = db.append_motions(copies, [{"name": f"m{i}", "mirror_of": int(i)} for i in ids])
    assert len(grown) == len(db) + 3 and grown.n_frames == db.n_frames + sum(c.n_frames for c in copies)
    new = grown.documents.iloc[len(db):]
    assert new["name"].tolist() == [f"m{i}" for i in ids] and new["format"].unique().tolist() == ["memory"]
    assert new["label"].tolist() == db.documents["label"].iloc[:3].tolist()
    assert new["mirror_of"].tolist() == ids.tolist()
    for row, c in zip(new.itertuples(), copies):
        np.testing.assert_array_equal(grown.motion(row.doc_id).positions, c.positions)
    np.testing.assert_array_equal(grown.positions[: db.n_frames], db.positions)


def test_a_new_database_of_clips_without_labels(sample_dir, tmp_path):
    """Clips held in memory that carry no label (a take loaded without its label table, a derived copy) make a new
    database whose documents have an empty label (it crashed: KeyError 'label'), and searching it works."""
    from dataclasses import replace

    from mocapviz.io import load

    clip = load(sample_dir / "hdm05-cut" / "amc" / "HDM_dg_grabHighR_016_120.amc").canonical()
    clip = replace(clip, labels={})
    db = MotionDB.create(tmp_path / "unlabelled.mdb").append_motions([clip, clip[10:80]])
    assert len(db) == 2 and db.documents["label"].isna().all()
    assert db.documents["n_frames"].tolist() == [clip.n_frames, 70]
    grown = db.append_motions([clip[:50]], [{"name": "labelled", "label": "walk"}])
    assert grown.documents["label"].tolist()[2] == "walk" and grown.documents["label"].iloc[:2].isna().all()


def test_append_motions_refuses_other_rates_and_skeletons(sample_dir, tmp_path):
    db = MotionDB.ingest(sample_dir / "hdm05-cut", tmp_path / "db", fps=30, progress=False)
    before = _state(db.path)
    clip = db.motion(0)
    with pytest.raises(ValueError, match="60 fps; the database at 30 fps"):
        db.append_motions([clip.resample(60)])
    with pytest.raises(ValueError, match="canonical joints"):
        db.append_motions([mocapviz.load(db.documents["path"].iloc[0])])
    with pytest.raises(ValueError, match="1 motions but 2 metas"):
        db.append_motions([clip], [{}, {}])
    assert _state(db.path) == before


def test_skip_bad_also_skips_an_amc_without_its_skeleton(sample_dir, tmp_path):
    """The checksum of an AMC needs its ASF: a missing one is a bad file like any other."""
    src = shutil.copytree(sample_dir / "cmu-asfamc", tmp_path / "cmu")
    lone = tmp_path / "lone" / "amc"
    lone.mkdir(parents=True)
    orphan = shutil.copy(next((src / "amc").rglob("131_01.amc")), lone / "orphan.amc")
    with pytest.raises(MocapFormatError, match="no ASF skeleton"):
        MotionDB.ingest([src, lone], tmp_path / "db", progress=False)
    assert not (tmp_path / "db").exists()
    with pytest.warns(UserWarning, match="orphan.amc"):
        db = MotionDB.ingest([src, lone], tmp_path / "db", skip_bad=True, progress=False)
    assert len(db) == 2 and Path(orphan).name not in set(db.documents["path"].map(lambda p: Path(p).name))


def cut_in_last_frame(amc: Path) -> int:
    """Cut ``amc`` (in place) inside its last frame, before its ``lfemur`` line (as CMU golf_01.amc ends); return the
    1-based line of that frame's number."""
    data = amc.read_bytes()
    data = data[: data.rfind(b"\nlfemur") + 1]
    amc.write_bytes(data)
    return max(i for i, s in enumerate(data.split(b"\n"), start=1) if s.strip().isdigit())


@pytest.mark.parametrize("threads", [1, 2])
def test_ingest_names_the_format_warnings_of_each_file(sample_dir, tmp_path, threads):
    """A file read with a part left out (an AMC cut inside its last frame) gives one MocapFormatWarning naming it and
    the line, issued by the ingest (collected where the file was read: this thread or a reader thread), and its
    document lacks that frame; the other file gives none."""
    src = shutil.copytree(sample_dir / "cmu-asfamc", tmp_path / "cmu")
    cut = next((src / "amc").rglob("131_01.amc"))
    whole = load(cut).n_frames
    line = cut_in_last_frame(cut)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        db = MotionDB.ingest(src, tmp_path / "db", threads=threads, progress=False)
    (w,) = [w.message for w in seen if issubclass(w.category, MocapFormatWarning)]
    assert Path(w.path) == cut.resolve() and w.line == line and str(w).startswith(f"{w.path}, line {line}: ")
    assert w.reason == f"last frame {whole} is incomplete (no line for bone 'lfemur': the file ends inside it); dropped it"
    docs = db.documents.set_index("name")
    assert docs.loc["131_01", "n_frames"] == whole - 1 and len(docs) == 2


def test_open_refuses_a_manifest_that_is_not_an_object(tmp_path):
    (tmp_path / "manifest.json").write_text("[1, 2]")
    with pytest.raises(MotionDBError, match="not a mocapviz.MotionDB"):
        MotionDB.open(tmp_path)


def test_ingest_shows_a_progress_bar_over_the_files(sample_dir, tmp_path, capsys):
    MotionDB.ingest(sample_dir / "cmu-asfamc", tmp_path / "db", progress=True)
    err = capsys.readouterr().err
    assert "ingest" in err and "2/2" in err and "file" in err


def test_explicit_hdm05_label_table_gives_the_class_as_label(sample_dir, tmp_path):
    """A labels.tsv passed explicitly fills `label` with the main class, as the automatic discovery does."""
    folder = sample_dir / "hdm05-cut"
    found = MotionDB.ingest(folder, tmp_path / "auto", progress=False)
    given = MotionDB.ingest(folder, tmp_path / "given", labels=folder / "labels.tsv", progress=False)
    assert found.documents["label"].notna().all()
    assert given.documents["label"].tolist() == found.documents["label"].tolist() == given.documents["class"].tolist()
