"""The audit of a collection (issue 41; mocapviz.similarity.audit, Engine.audit, ``mocapviz audit``): copies of
real clips of the demo (derived copies, made here: mirrored, trimmed, time-scaled, retargeted to another actor's
bones, with marker noise, resampled to 60 Hz in a second database) planted beside the real takes are found with
the planted spans (within 3 frames, 0.1 s; a cut in a held pose within 0.2 s); the CLI prints and writes what Python returns; a split file's leakage and the clean set
follow from the pairs; bad input gets typed errors naming the file and line."""
from __future__ import annotations

import shutil
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB
from mocapviz.engine import Engine
from mocapviz.errors import ParameterError
from mocapviz.motion.skeleton import bone_lengths, mirror, retarget
from mocapviz.similarity.audit import PAIR_COLUMNS, read_split, warping_path

SOURCE = 45  # CMU 135_04 in the demo: 9.8 s of front kicks at 30 Hz
THRESHOLD = 6.0  # cm: above every planted copy's cost here, below two performances of one class (docs/audit.md)


@pytest.fixture(scope="module")
def demo():
    return MotionDB.demo()


def _planted(demo, tmp_path, copies: list, names: list) -> MotionDB:
    db = MotionDB.open(shutil.copytree(demo.path, tmp_path / "planted.mdb"))
    return db.append_motions(copies, [{"name": n} for n in names])


def _pair_of(pairs: pd.DataFrame, a: int, b: int) -> pd.DataFrame:
    return pairs[(pairs["doc_a"] == a) & (pairs["doc_b"] == b)]


def test_planted_copies_of_every_kind_are_found_with_their_spans(demo, tmp_path):
    clip = demo.motion(SOURCE)
    n = clip.n_frames
    rng = np.random.default_rng(7)
    other = bone_lengths(demo.motion(27).positions)  # mm's bones (HDM05), the take is CMU subject 135's
    noisy = replace(clip, positions=clip.positions + rng.normal(0, 1 / np.sqrt(3), clip.positions.shape)
                    .astype(np.float32))  # fmt: skip
    slower = replace(clip.resample(clip.fps * 1.2), fps=clip.fps)  # the take played 20 % slower
    copies = [mirror(clip), clip[60:n - 60], slower, retarget(clip, other), noisy]
    db = _planted(demo, tmp_path, copies, ["mirrored", "trimmed", "slower", "retargeted", "noisy"])
    pairs = Engine(db).audit(threshold=THRESHOLD)
    assert list(pairs.columns) == PAIR_COLUMNS
    first = len(demo)
    spans = {first: (0, n), first + 1: (60, n - 60), first + 2: (0, n), first + 3: (0, n), first + 4: (0, n)}
    for copy, (a, b) in spans.items():
        found = _pair_of(pairs, SOURCE, copy)
        assert len(found) >= 1, f"copy {copy} not found"
        best = found.iloc[0]
        assert bool(best["mirrored"]) == (copy == first)
        assert abs(best["start_a"] - a) <= 3 and abs(best["end_a"] - b) <= 3, best.to_dict()
        length_b = db.document(copy)["n_frames"]
        assert best["start_b"] <= 3 and best["end_b"] >= length_b - 3, best.to_dict()
    assert _pair_of(pairs, SOURCE, first + 2).iloc[0]["scale"] == pytest.approx(1.2, abs=0.03)
    # the copies are one cluster with their source; the clean set keeps one of them (the longest: the slower copy)
    cluster = pairs[pairs["doc_a"] == SOURCE]["cluster"].unique()
    assert len(cluster) == 1
    kept = Engine(db).keep_one(pairs)["doc_id"].tolist()
    members = {SOURCE, *spans}
    assert [d for d in kept if d in members] == [first + 2]


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(a=st.integers(0, 120), length=st.integers(45, 150), doc=st.sampled_from([44, 45, 46, 47]))
def test_a_trimmed_copy_anywhere_in_a_take_is_found_where_it_was_cut(demo, tmp_path_factory, a, length, doc):
    clip = demo.motion(doc)
    b = min(a + length, clip.n_frames)
    db = _planted(demo, tmp_path_factory.mktemp("trim"), [clip[a:b]], ["cut"])
    found = _pair_of(Engine(db).audit(threshold=THRESHOLD, mirrored=False), doc, len(demo))
    assert len(found) >= 1
    best = found.iloc[0]
    # within 0.2 s: where a cut falls in a held pose, its frames match the copy's first or last frame equally well
    assert abs(best["start_a"] - a) <= 6 and abs(best["end_a"] - b) <= 6 and best["cost"] < 0.5, best.to_dict()


def test_against_a_second_collection_at_another_rate(demo, tmp_path):
    """A copy at 60 Hz in a database of its own: compared at the first one's 30 Hz, reported in its own frames."""
    clip = demo.motion(SOURCE)
    fast = clip.resample(60.0)
    other = MotionDB.create(tmp_path / "other.mdb").append_motions([fast], [{"name": "at60"}])
    pairs = Engine(demo).audit(other, threshold=THRESHOLD)
    found = pairs[pairs["doc_a"] == SOURCE]
    assert len(found) >= 1 and (pairs["doc_b"] == 0).all()
    best = found.iloc[0]
    assert best["end_b"] >= fast.n_frames - 6 and best["start_b"] <= 6  # frames of the 60 Hz document
    assert best["seconds"] == pytest.approx(clip.n_frames / clip.fps, abs=0.2)


def test_the_command_line_prints_and_writes_what_python_returns(demo, tmp_path):
    db = _planted(demo, tmp_path, [mirror(demo.motion(SOURCE))], ["mirrored"])
    split = tmp_path / "split.csv"
    split.write_text("doc,split\n" + "".join(f"{d},train\n" for d in range(len(db) - 1)) + "mirrored,test\n")
    out = tmp_path / "pairs.csv"
    leaks, clean = tmp_path / "leaks.csv", tmp_path / "clean.csv"
    done = subprocess.run([sys.executable, "-m", "mocapviz.cli", "audit", str(db.path), "--threshold", str(THRESHOLD),
                           "--split", str(split), "--csv", str(out), "--leakage-csv", str(leaks), "--keep-one",
                           str(clean), "--quiet"], check=False, capture_output=True, text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr
    engine = Engine(db)
    pairs = engine.audit(threshold=THRESHOLD)
    written = pd.read_csv(out, keep_default_na=False)
    assert written[["doc_a", "start_a", "end_a", "doc_b", "start_b", "end_b", "mirrored"]].equals(
        pairs[["doc_a", "start_a", "end_a", "doc_b", "start_b", "end_b", "mirrored"]].reset_index(drop=True))
    assert np.allclose(written["cost"], pairs["cost"])
    leaked = pd.read_csv(leaks)
    assert set(leaked["doc_a"]) == {len(db) - 1} and SOURCE in set(leaked["doc_b"])
    assert "leakage: 1 test document with a near-copy in train" in done.stdout
    assert pd.read_csv(clean)["doc_id"].tolist() == engine.keep_one(pairs)["doc_id"].tolist()


def test_bad_input_gets_typed_errors(demo, tmp_path):
    engine = Engine(demo)
    with pytest.raises(ParameterError, match="audit set 'Fp8'"):
        engine.audit(numeric_set="Fp8")
    with pytest.raises(ParameterError, match="min_length"):
        engine.audit(min_length=0.0)
    bad = tmp_path / "split.csv"
    bad.write_text("document,part\n0,train\n")
    with pytest.raises(ParameterError, match=r"split.csv: a split file needs the columns doc and split"):
        read_split(bad, demo.documents)
    bad.write_text("doc,split\n0,train\nno_such_take,test\n")
    with pytest.raises(ParameterError, match=r"split.csv, line 3: no document 'no_such_take'"):
        read_split(bad, demo.documents)
    done = subprocess.run([sys.executable, "-m", "mocapviz.cli", "audit", str(demo.path), "--split", "/nonexistent.csv"],
                          check=False, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode != 0 and "--split /nonexistent.csv: no such file" in done.stderr


def test_a_long_copy_is_one_pair_though_aligned_in_tiles(demo, tmp_path):
    """The HDM05 scene of the demo (document 52, from C3D markers, 24 s at 30 Hz) played 15 % slower: with a shortest
    stretch of 0.5 s it is over two tiles of 20 shortest stretches long on both sides, aligned tile by tile and
    reported as one pair."""
    clip = demo.motion(52)
    assert clip.n_frames > 2 * 20 * 15
    slower = replace(clip.resample(clip.fps * 1.15), fps=clip.fps)
    db = _planted(demo, tmp_path, [slower], ["slower scene"])
    found = _pair_of(Engine(db).audit(threshold=THRESHOLD, mirrored=False, min_length=0.5), 52, len(demo))
    assert len(found) == 1, found
    best = found.iloc[0]
    assert best["start_a"] <= 6 and best["end_a"] >= clip.n_frames - 6, best.to_dict()
    assert best["scale"] == pytest.approx(1.15, abs=0.03)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(a=st.integers(0, 150), length=st.integers(30, 140), factor=st.floats(0.8, 1.25), mirrored=st.booleans())
def test_a_pairs_warping_path_follows_the_copys_time_scaling(demo, a, length, factor, mirrored):
    """Engine.audit_path of a stretch of CMU 135_04 (front kicks) and its copy re-timed by ``factor`` (mirrored or
    not, appended as a derived copy): every step shows the copy's frame at the source frame × factor, within 1.5 frames
    (the copy's frames are the source's resampled, so the true time of each is known), from (0, 0) to both ends."""
    clip = demo.motion(SOURCE)[a:a + length]
    copy = replace(clip.resample(clip.fps * factor), fps=clip.fps)
    copy = mirror(copy) if mirrored else copy
    path = warping_path(clip, copy, mirrored=mirrored)
    assert path[0].tolist() == [0, 0] and path[-1].tolist() == [clip.n_frames - 1, copy.n_frames - 1]
    assert (np.diff(path, axis=0) >= 0).all() and (np.diff(path, axis=0).sum(axis=1) > 0).all()
    assert np.abs(path[:, 1] - path[:, 0] * factor).max() <= 1.5


def test_audit_path_of_a_pair_in_the_database(demo, tmp_path):
    """The path of a pair found in a database (the source's stretch and its mirrored copy, 20 % faster) is the path
    of the two stretches read from it; a bad pair gets a typed error naming what is wrong."""
    clip = demo.motion(SOURCE)[60:240]
    copy = mirror(replace(clip.resample(clip.fps / 1.2), fps=clip.fps))
    db = _planted(demo, tmp_path, [copy], ["faster mirror"])
    engine = Engine(db)
    pairs = _pair_of(engine.audit(threshold=THRESHOLD), SOURCE, len(demo))
    assert len(pairs) == 1 and pairs["mirrored"].iloc[0]
    pair = pairs.iloc[0]
    path = engine.audit_path(pair)
    assert path[-1].tolist() == [pair["end_a"] - pair["start_a"] - 1, pair["end_b"] - pair["start_b"] - 1]
    source_frame = pair["start_a"] + path[:, 0] - 60  # the clip's frame shown at each step, and the copy's
    assert np.abs(pair["start_b"] + path[:, 1] - source_frame / 1.2).max() <= 1.5
    with pytest.raises(ParameterError, match="end_a"):
        engine.audit_path(pair.drop("end_a"))
    with pytest.raises(ParameterError, match=r"start_b:end_b"):
        engine.audit_path(pair.to_dict() | {"end_b": 10_000})


@pytest.mark.slow
def test_a_copy_inside_a_longer_take_of_a_repeated_movement_is_found(bandai2_dir, tmp_path):
    """Bandai Namco's feminine left-hand waves 024 and 025 (real takes) and, as derived copies, a stretch of each
    resampled to 25 Hz and back to 30 Hz (the planted `resampled` kind the full planted-copies run missed): the
    box of a copy within its source covers the whole repeated wave, so the box's own warping path aligns the copy
    to the wrong waves; the shorter side aligned within the longer finds each copy where it was cut (within 3
    frames)."""
    from mocapviz.io import load

    takes = [load(bandai2_dir / "data" / f"dataset-2_wave-left-hand_feminine_{t}.bvh").canonical().resample(30.0)
             for t in ("024", "025")]  # fmt: skip
    spans = [(63, 174), (72, 197)]
    copies = [take[a:b].resample(25.0).resample(30.0) for take, (a, b) in zip(takes, spans)]
    db = MotionDB.create(tmp_path / "waves.mdb").append_motions(
        takes + copies, [{"name": n} for n in ("024", "025", "024 copy", "025 copy")])
    pairs = Engine(db).audit(threshold=THRESHOLD)
    for source, (a, b) in enumerate(spans):
        found = _pair_of(pairs, source, source + 2)
        assert len(found) == 1, pairs
        assert abs(found["start_a"].iloc[0] - a) <= 3 and abs(found["end_a"].iloc[0] - b) <= 3, found
