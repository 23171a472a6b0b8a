"""Marker-only documents (mocapviz.db.marker_documents): C3D files of no known marker set stored beside a MotionDB
and searched by the marker numeric set (mocapviz.features.marker_numeric, mocapviz.similarity.marker_search).

Real data: the peer-readers C3D files with no known set (GPL test data: read here, never copied into the repo) and
copies derived from them in the tests (a stretch cut out, the same stretch time-stretched, the take turned and
moved on the floor), each stored as its own marker-only document. The search is checked against a brute-force
subsequence DTW written here on random stretches (hypothesis). A mixed database (HDM05 AMC of the embedded sample
+ a marker-only C3D) answers every canonical search as the database without it does.
"""

from __future__ import annotations

import contextlib
import io
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapviz import Motion, MotionDB
from mocapviz.cli import main
from mocapviz.db.marker_documents import add_marker_documents
from mocapviz.engine import CANONICAL_JOINTS, CANONICAL_PARENTS, Engine
from mocapviz.errors import MocapvizError, ParameterError, SkeletonMappingError
from mocapviz.features.marker_numeric import marker_features, marker_label_set
from mocapviz.integrity import check
from mocapviz.io import datasets
from mocapviz.io.c3d import read_c3d

PEERS = {"Vicon.c3d": (51, 580, 100.0), "Optotrak.c3d": (54, 29, 30.0), "FP_Type3.c3d": (34, 2, 250.0),
         "BTS.c3d": (22, 675, 100.0)}  # markers, frames, fps: docs/c3d.md's table (read by ezc3d's own tests too)
CUT = (200, 320)  # the stretch of Vicon.c3d cut out


def _quiet(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the format warnings of Optotrak (29 of 1149 frames) and FP_Type3
        return function(*args, **kwargs)


@pytest.fixture(scope="module")
def peer_files(peer_readers_dir):
    return [peer_readers_dir / "c3d" / name for name in PEERS]


@pytest.fixture(scope="module")
def peer_db(peer_files, tmp_path_factory):
    return _quiet(MotionDB.ingest, peer_files, tmp_path_factory.mktemp("peers") / "db", progress=False,
                  markers_only="keep")


def _marker_motion(positions, fps, names, source="copy"):
    return Motion(positions=np.asarray(positions, np.float32), fps=fps, joint_names=tuple(names),
                  parents=np.full(len(names), -1), source=source)


def _time_stretched(positions: np.ndarray, frames: int) -> np.ndarray:
    """``positions`` (T, M, 3) resampled to ``frames`` frames by linear interpolation (NaN where a neighbour is)."""
    t = np.linspace(0, len(positions) - 1, frames)
    lo = np.floor(t).astype(int)
    hi = np.minimum(lo + 1, len(positions) - 1)
    w = (t - lo)[:, None, None]
    return positions[lo] * (1 - w) + positions[hi] * w


# ---------------------------------------------------------------------------------------------- storage
def test_files_of_no_known_set_are_refused_unless_kept(peer_files, tmp_path):
    with pytest.raises(SkeletonMappingError):
        _quiet(MotionDB.ingest, peer_files[:1], tmp_path / "refused", progress=False)
    assert not (tmp_path / "refused").exists()  # no database made


def test_kept_files_are_marker_only_documents_with_their_markers(peer_db, peer_files):
    only = peer_db.marker_documents.documents
    assert len(peer_db) == 0 and peer_db.n_frames == 0  # no canonical frame, no document row
    assert only["doc_id"].tolist() == [-1, -2, -3, -4]
    assert only["name"].tolist() == [f.stem for f in peer_files]
    assert [(len(m), n, fps) for m, n, fps in zip(only["markers"], only["n_frames"], only["fps"])] == list(PEERS.values())
    for doc_id, f in zip(only["doc_id"], peer_files):
        stored, read = peer_db.marker_documents.motion(doc_id), _quiet(read_c3d, f)
        assert stored.joint_names == read.joint_names
        np.testing.assert_array_equal(stored.positions, read.positions.astype(np.float32))  # NaN in the same gaps
    assert peer_db.marker_documents.motion(-1).positions[0, 0, 0] == pytest.approx(4.416278839111328)  # ezc3d's test


def test_ingest_again_skips_them_and_check_reads_them_back(peer_db, peer_files):
    again = _quiet(peer_db.append, peer_files, progress=False, markers_only="keep")
    assert len(again.marker_documents) == 4 and len(again) == 0
    report = check(peer_db.path)
    assert report["ok"].all(), report[~report["ok"]]
    assert (report["what"].str.startswith("markers of marker-only document")).sum() == 4


def test_a_canonical_search_of_a_marker_only_document_says_what_it_is(peer_db):
    with pytest.raises(KeyError, match="marker-only document"):
        peer_db.document(-1)
    engine = Engine(peer_db)  # no canonical document: only the marker search answers
    with pytest.raises(ParameterError, match="canonical joints"):
        engine.marker_stretches(0)
    with pytest.raises(MocapvizError, match="marker-only document"):
        engine.clips(-1)
    with pytest.raises(ParameterError, match="no document with canonical joints, only 4 marker-only documents"):
        engine.clips(Motion(positions=np.zeros((30, 24, 3), np.float32), fps=100.0,
                                joint_names=CANONICAL_JOINTS, parents=CANONICAL_PARENTS))


# ---------------------------------------------------------------------------------------------- the feature set
def test_the_marker_numeric_set_ignores_where_the_take_is_and_which_way_it_faces(peer_db):
    vicon = peer_db.marker_documents.motion(-1)
    names, order = marker_label_set(vicon.joint_names)
    angle = np.deg2rad(127.0)
    turn = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    moved = vicon.positions.astype(np.float64) @ turn.T + np.array([250.0, 3.0, -80.0])
    shuffled = np.random.default_rng(0).permutation(len(names))  # the file's marker order does not matter either
    names2, order2 = marker_label_set(np.array(vicon.joint_names)[shuffled])
    assert names2 == names
    a = marker_features(vicon.positions[:, order])
    b = marker_features(moved[:, shuffled][:, order2])
    assert np.isfinite(a).all() and a.shape == (580, 3 * 51)
    np.testing.assert_allclose(a, b, atol=2e-3)  # cm
    assert np.abs(a).max() > 10  # not trivially zero


# ---------------------------------------------------------------------------------------------- the search
@pytest.fixture(scope="module")
def copies_db(peer_db, tmp_path_factory):
    """The peers plus three copies derived here from Vicon.c3d: frames 200:320 cut out, the same stretch played
    1.5 x slower (180 frames), and the whole take turned by 127 degrees and moved."""
    vicon = peer_db.marker_documents.motion(-1)
    a, b = CUT
    angle = np.deg2rad(127.0)
    turn = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    copies = [vicon.positions[a:b], _time_stretched(vicon.positions[a:b].astype(np.float64), 180),
              vicon.positions.astype(np.float64) @ turn.T + np.array([250.0, 3.0, -80.0])]
    db = _quiet(MotionDB.ingest, [vicon.source], tmp_path_factory.mktemp("copies") / "db", progress=False,
                markers_only="keep")
    ids = add_marker_documents(db.path, [_marker_motion(p, 100.0, vicon.joint_names) for p in copies],
                               [{"name": n, "path": "", "sha256": n, "label": None}
                                for n in ("vicon-cut", "vicon-slow", "vicon-turned")])
    assert ids == [-2, -3, -4]
    return MotionDB.open(db.path)


def test_a_cut_stretch_finds_the_take_it_was_cut_from_at_its_frames(copies_db):
    hits = Engine(copies_db).marker_stretches(-2, n_matches=3)  # the whole cut document, itself left out
    best = hits.iloc[0]
    assert (best["doc_id"], best["start"], best["end"]) in {(-1, *CUT), (-4, *CUT)}
    assert set(hits["doc_id"].head(2)) == {-1, -4}  # the take and its turned copy, both at the cut's frames
    assert (hits.head(2)[["start", "end"]].to_numpy() == CUT).all()
    assert best["cost"] / best["frames"] < 0.05  # cm a frame: the same markers (gaps at the cut's edges filled alike)
    assert hits.attrs["searched"] == 3 and hits.attrs["other_markers"] == 0


def test_a_time_stretched_copy_finds_the_stretch_it_was_made_from(copies_db):
    hits = Engine(copies_db).marker_stretches(-3, n_matches=5)
    take = hits[hits["doc_id"] == -1].iloc[0]
    assert take["rank"] <= 3  # the cut (-2) may come first: it is the same stretch
    assert abs(take["start"] - CUT[0]) <= 2 and abs(take["end"] - CUT[1]) <= 2
    cut = hits[hits["doc_id"] == -2].iloc[0]
    assert (cut["start"], cut["end"]) == (0, CUT[1] - CUT[0])


def test_other_marker_sets_and_rates_are_not_compared_and_counted(peer_db):
    hits = Engine(peer_db).marker_stretches(-4, frames=(400, 500), n_matches=2, exclude_document=False)  # BTS
    # (frames 400:500: it sees no marker before frame ~250, where every stretch is alike)
    assert hits["doc_id"].tolist()[0] == -4 and (hits.iloc[0]["start"], hits.iloc[0]["end"]) == (400, 500)
    assert hits.attrs["other_markers"] == 3 and hits.attrs["searched"] == 1
    alone = Engine(peer_db).marker_stretches(-4, frames=(400, 500))  # its own document left out: nothing else
    assert alone.empty and list(alone.columns[:8]) == ["rank", "doc_id", "name", "start", "end", "frames",
                                                      "start_s", "end_s"]


def _dtw_cost(q: np.ndarray, x: np.ndarray) -> float:
    """Plain DTW with steps (1,1), (1,0), (0,1) of unit weight and Euclidean frame costs, as a loop."""
    d = np.sqrt(((q[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    acc = np.full((len(q) + 1, len(x) + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, len(q) + 1):
        for j in range(1, len(x) + 1):
            acc[i, j] = d[i - 1, j - 1] + min(acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1])
    return float(acc[-1, -1])


@pytest.fixture(scope="module")
def random_db(tmp_path_factory):
    """Four documents of four random-walk markers (one 40 frames long, gaps of NaN in some), one of other labels."""
    rng = np.random.default_rng(5)
    db = MotionDB.create(tmp_path_factory.mktemp("random") / "db")
    motions = []
    for i, n in enumerate([40, 25, 31, 18]):
        p = np.cumsum(rng.normal(0, 3, (n, 4, 3)), axis=0) + rng.normal(0, 20, (1, 4, 3))
        if i % 2:
            p[rng.integers(0, n, 3), rng.integers(0, 4, 3)] = np.nan
        motions.append(_marker_motion(p, 60.0, ["D", "B", "A", "C"]))
    motions.append(_marker_motion(np.zeros((30, 2, 3)), 60.0, ["X", "Y"]))
    add_marker_documents(db.path, motions, [{"name": f"r{i}", "path": "", "sha256": f"r{i}", "label": None}
                                            for i in range(len(motions))])  # fmt: skip
    return db


@settings(max_examples=40, deadline=None)
@given(doc=st.integers(-4, -1), start=st.integers(0, 16), length=st.integers(2, 12), exclude=st.booleans(),
       min_length=st.sampled_from([0.5, 1.0, None]))
def test_the_best_stretch_is_brute_forces_best(random_db, doc, start, length, exclude, min_length):
    only = random_db.marker_documents
    n = int(only.document(doc)["n_frames"])
    start, end = min(start, n - 2), min(start + length, n)
    hits = Engine(random_db).marker_stretches(doc, frames=(start, end), n_matches=1, min_length=min_length,
                                              exclude_document=exclude)  # fmt: skip
    features = {}
    for d in only.documents["doc_id"]:
        m = only.motion(int(d))
        if len(m.joint_names) == 4:
            features[int(d)] = marker_features(m.positions[:, marker_label_set(m.joint_names)[1]])
    q = features[doc][start:end]
    shortest = 1 if min_length is None else int(np.ceil(min_length * len(q)))
    # subsequence DTW's rule: each end frame's best alignment (any start), a candidate when at least shortest long
    ends = [min((_dtw_cost(q, x[a : b + 1]), b + 1 - a) for a in range(b + 1))
            for d, x in features.items() if not (exclude and d == doc) for b in range(len(x))]  # fmt: skip
    brute = min(cost for cost, length in ends if length >= shortest)
    best = hits.iloc[0]
    assert best["cost"] == pytest.approx(brute, rel=1e-5, abs=1e-3)
    x = features[int(best["doc_id"])]
    assert _dtw_cost(q, x[best["start"] : best["end"]]) == pytest.approx(best["cost"], rel=1e-5, abs=1e-3)
    assert best["frames"] >= shortest and not (exclude and best["doc_id"] == doc)
    assert hits.attrs["other_markers"] == 1


# ---------------------------------------------------------------------------------------------- a mixed database
SAMPLE_CLIPS = ["HDM_dg_squat1Reps_033_120.amc", "HDM_mm_squat1Reps_037_120.amc", "HDM_dg_kickLFront1Reps_017_120.amc",
                "HDM_mm_kickLFront1Reps_023_120.amc", "HDM_dg_depositFloorR_013_120.amc"]


@pytest.fixture(scope="module")
def mixed(peer_files, tmp_path_factory):
    amc = datasets.sample() / "hdm05-cut" / "amc"
    files = [amc / f for f in SAMPLE_CLIPS]
    plain = MotionDB.ingest(files, tmp_path_factory.mktemp("plain") / "db", progress=False)
    both = _quiet(MotionDB.ingest, [*files, peer_files[0]], tmp_path_factory.mktemp("mixed") / "db", progress=False,
                  markers_only="keep")
    return plain, both


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(pd.DataFrame(a).drop(columns=["path"], errors="ignore"),
                                  pd.DataFrame(b).drop(columns=["path"], errors="ignore"))


def test_a_mixed_database_answers_every_canonical_search_as_without_the_marker_only_document(mixed):
    plain, both = mixed
    assert len(both.marker_documents) == 1 and len(both) == len(plain)
    pd.testing.assert_frame_equal(plain.documents.drop(columns="path"), both.documents.drop(columns="path"))
    np.testing.assert_array_equal(plain.positions, both.positions)
    e0, e1 = Engine(plain), Engine(both)
    asks = [("clips", (0,), {"n_matches": 3}), ("stretches", (2,), {"frames": (10, 70), "n_matches": 4}),
            ("match", (3,), {"frames": (0, 60), "method": "dtw", "n_matches": 3}),
            ("match", (3,), {"frames": (0, 60), "n_matches": 3}),
            ("neighbours", (1, 30), {"k": 8}), ("query", (2,), {"exclude_document": False})]
    for method, args, kwargs in asks:
        a, b = getattr(e0, method)(*args, **kwargs), getattr(e1, method)(*args, **kwargs)
        assert len(a), method
        _same(a, b)
    said = e1.clips(0, n_matches=3)
    assert said.attrs["marker_only_skipped"] == 1 and "marker_only_skipped" not in e0.clips(0, n_matches=3).attrs
    hits = e1.marker_stretches(-1, frames=CUT, n_matches=1, exclude_document=False)
    assert (hits.iloc[0]["doc_id"], hits.iloc[0]["start"], hits.iloc[0]["end"]) == (-1, *CUT)


def test_the_command_line_ingests_and_searches_marker_only_documents(peer_files, tmp_path):
    out = tmp_path / "db"
    with _quiet_stdout() as text:
        assert _quiet(main, ["ingest", str(peer_files[0]), str(peer_files[3]), "--out", str(out), "--quiet",
                             "--no-cluster", "--markers-only", "keep"]) == 0  # fmt: skip
        assert main(["markers", str(out), "--example", "-1", "--frames", f"{CUT[0]}:{CUT[1]}", "--no-exclude-document",
                     "-K", "2", "--csv", str(tmp_path / "hits.csv")]) == 0  # fmt: skip
        assert main(["info", str(out), "--documents"]) == 0
    printed = text.getvalue()
    assert "and 2 marker-only documents (no canonical joints)" in printed
    assert "not compared: 1 marker-only document of other marker labels" in printed
    table = pd.read_csv(tmp_path / "hits.csv")
    assert table.loc[0, ["doc_id", "start", "end"]].tolist() == [-1, *CUT]
    with pytest.raises(MocapvizError):
        Engine(out).marker_stretches(-1, frames=(570, 600))  # outside the take


@contextlib.contextmanager
def _quiet_stdout():
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        yield buffer
