"""Numeric features (mocapviz.features.numeric, Krüger et al. 2010 §3.1-3.2) on real HDM05 and CMU clips: the sets
against positions picked by hand from ``body_frame``, invariance, windows and their ends, the PCA baselines, storage
with a MotionDB, and bad input."""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from importlib import import_module

import numpy as np
import pytest

import mocapviz
from mocapviz import MotionDB, MotionDBError, ParameterError
from mocapviz.features import (
    NUMERIC_SETS,
    PCAModel,
    fit_pca,
    load_numeric,
    numeric_columns,
    numeric_features,
    store_numeric,
    window_offsets,
)
from mocapviz.motion.skeleton import CANONICAL_JOINTS, body_frame, heading

nm = import_module("mocapviz.features.numeric")  # the module (its function is `numeric_features`)

F15 = ["lwrist", "rwrist", "lankle", "rankle", "head"]
F30 = F15 + ["lelbow", "relbow", "lknee", "rknee", "chest"]
F39 = F30 + ["lshoulder", "rshoulder", "belly"]
DIMS = {"F15E": 15, "F30E": 30, "F39E": 39, "F15x3E": 45, "F15x5E": 75, "F30x3E": 90, "Fp8": 8, "Fp16": 16, "Fp25": 25}


def idx(names) -> list[int]:
    return [CANONICAL_JOINTS.index(n) for n in names]


def by_hand(positions: np.ndarray, centre: int, sample: int, joints) -> np.ndarray:
    """Joints of frame ``sample`` in the body frame of frame ``centre``, with an explicit rotation matrix: the
    heading angle of ``centre`` (facing +z at 0), rotated back by it about y. [shape=(3 * len(joints),)], float64."""
    p = positions.astype(np.float64)
    theta = float(heading(p[centre : centre + 1])[0])
    rot = np.array([[np.cos(theta), 0.0, -np.sin(theta)], [0.0, 1.0, 0.0], [np.sin(theta), 0.0, np.cos(theta)]])
    return ((p[sample, idx(joints)] - p[centre, 0]) @ rot.T).ravel()


# ------------------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def hdm05_files(hdm05_dir, hdm05_labels):
    """files(label) -> the sorted HDM05 clip paths of a class."""
    return lambda label: [hdm05_dir / f for f in sorted(hdm05_labels.loc[hdm05_labels["class"] == label, "file"])]


@pytest.fixture(scope="module")
def clip(hdm05_files):
    """clip(label, k) -> the k-th HDM05 clip of a class, canonical (cached)."""
    return cache(lambda label, k=0: mocapviz.load(hdm05_files(label)[k]).canonical())


@pytest.fixture(scope="module")
def reference_db(hdm05_files, tmp_path_factory):
    """A PCA reference: two clips of each of the 11 HDM05 classes (about 11,000 frames)."""
    classes = [
        "depositFloorR",
        "elbowToKnee1RepsLelbowStart",
        "grabHighR",
        "hopBothLegs1hops",
        "jogLeftCircle4StepsRstart",
        "kickLFront1Reps",
        "lieDownFloor",
        "rotateArmsBothBackward1Reps",
        "sneak2StepsLStart",
        "squat1Reps",
        "throwBasketball",
    ]
    files = [f for c in classes for f in hdm05_files(c)[:2]]
    return MotionDB.ingest(files, tmp_path_factory.mktemp("ref") / "db", progress=False)


@pytest.fixture(scope="module")
def pca(reference_db):
    return fit_pca(reference_db, progress=False)


def two_documents(hdm05_files, out) -> MotionDB:
    return MotionDB.ingest(
        [hdm05_files("jogLeftCircle4StepsRstart")[0], hdm05_files("kickLFront1Reps")[0]], out, progress=False
    )


# ------------------------------------------------------------------------------------------ sets and shapes
def test_every_set_has_its_dimension_on_hdm05_and_cmu(clip, cmu_dir, pca):
    cmu = mocapviz.load(cmu_dir / "amc" / "martialwalk" / "135_02.amc")  # CMU ASF skeleton, not yet canonical
    assert NUMERIC_SETS == tuple(DIMS)
    for motion in (clip("kickLFront1Reps"), cmu):
        values = {name: numeric_features(motion, name, pca=pca) for name in NUMERIC_SETS}
        for name, v in values.items():
            assert v.shape == (motion.n_frames, DIMS[name]) and v.dtype == np.float32, name
            assert np.isfinite(v).all() and len(numeric_columns(name)) == DIMS[name], name
        # the larger sets extend the smaller ones column by column
        np.testing.assert_array_equal(values["F30E"][:, :15], values["F15E"])
        np.testing.assert_array_equal(values["F39E"][:, :30], values["F30E"])
        np.testing.assert_array_equal(values["Fp25"][:, :8], values["Fp8"])
    np.testing.assert_array_equal(numeric_features(cmu, "F39E"), numeric_features(cmu.canonical(), "F39E"))
    assert numeric_columns("F15E")[:4] == ["lwrist.x", "lwrist.y", "lwrist.z", "rwrist.x"]
    assert numeric_columns("F15x3E")[0] == "lwrist.x@-0.150s" and numeric_columns("F15x3E")[-1] == "head.z@+0.150s"
    assert numeric_columns("Fp8") == [f"pc{k}" for k in range(1, 9)]


def test_frame_sets_are_the_body_frame_positions_of_their_joints(clip):
    for label in ("jogLeftCircle4StepsRstart", "grabHighR", "squat1Reps", "depositFloorR"):
        m = clip(label)
        bf = body_frame(m.positions)
        for name, joints in (("F15E", F15), ("F30E", F30), ("F39E", F39)):
            np.testing.assert_array_equal(numeric_features(m, name), bf[:, idx(joints)].reshape(m.n_frames, -1),
                                          err_msg=name)  # fmt: skip
    # the body frame itself: left joints at x > 0 (standing clips), the head above the root, and leaning forward
    # to put something on the floor moves the head to +z
    for label in ("grabHighR", "squat1Reps"):
        f15 = numeric_features(clip(label), "F15E").reshape(-1, 5, 3)
        assert (f15[:, [0, 2], 0] > 0).all() and (f15[:, [1, 3], 0] < 0).all(), label
        assert (f15[:, 4, 1] > 30).all(), label
    assert numeric_features(clip("depositFloorR"), "F15E")[:, 14].max() > 30
    # a jog around a circle turns the body by more than 1 rad; F15E against an explicit rotation matrix
    m = clip("jogLeftCircle4StepsRstart")
    assert np.ptp(np.unwrap(heading(m.positions))) > 1.0
    for t in (0, 100, m.n_frames - 1):
        np.testing.assert_allclose(numeric_features(m, "F15E")[t], by_hand(m.positions, t, t, F15), atol=1e-4)


def test_f15e_is_invariant_to_turning_and_moving_on_the_floor(clip, pca):
    m = clip("kickLFront1Reps")
    p = m.positions.astype(np.float64)
    for phi, shift in ((0.7, (250.0, 0.0, -130.0)), (-2.9, (-410.0, 0.0, 380.0)), (np.pi, (0.0, 0.0, 0.0))):
        rot = np.array([[np.cos(phi), 0, np.sin(phi)], [0, 1, 0], [-np.sin(phi), 0, np.cos(phi)]])
        moved = replace(m, positions=(p @ rot.T + shift).astype(np.float32))
        assert np.abs(moved.positions - m.positions).max() > 100  # really moved
        for name in ("F15E", "F39E", "F15x5E"):
            np.testing.assert_allclose(numeric_features(moved, name), numeric_features(m, name), atol=1e-3,
                                       err_msg=f"{name} {phi}")  # fmt: skip
        np.testing.assert_allclose(numeric_features(moved, "Fp25", pca=pca), numeric_features(m, "Fp25", pca=pca),
                                   atol=1e-3)  # fmt: skip


# ----------------------------------------------------------------------------------------------- windows
def test_window_offsets_are_seconds_rounded_to_frames():
    np.testing.assert_array_equal(window_offsets(3, 120), [-18, 0, 18])
    np.testing.assert_array_equal(window_offsets(5, 120), [-18, -9, 0, 9, 18])
    np.testing.assert_array_equal(window_offsets(3, 30), [-4, 0, 4])  # 4.5 frames: halves towards the centre
    np.testing.assert_array_equal(window_offsets(5, 30), [-4, -2, 0, 2, 4])
    np.testing.assert_array_equal(window_offsets(1, 30), [0])
    for fps in (24.0, 25.0, 29.97, 30.0, 60.0, 100.0, 120.0, 240.0):
        for n in (3, 5):
            off = window_offsets(n, fps)
            nominal = np.linspace(-0.15, 0.15, n) * fps
            assert (np.abs(off - nominal) <= 0.5 + 1e-9).all(), (n, fps, off)  # the nearest frame
            np.testing.assert_array_equal(off, -off[::-1])


def test_windowed_samples_are_the_offset_frames_in_the_centre_body_frame(clip):
    m = clip("jogLeftCircle4StepsRstart")
    f15, f30 = numeric_features(m, "F15E"), numeric_features(m, "F30E")
    x3, x5, y3 = numeric_features(m, "F15x3E"), numeric_features(m, "F15x5E"), numeric_features(m, "F30x3E")
    # the centre sample is the frame's own pose
    np.testing.assert_array_equal(x3[:, 15:30], f15)
    np.testing.assert_array_equal(x5[:, 30:45], f15)
    np.testing.assert_array_equal(y3[:, 30:60], f30)
    # the others: frames t - 18 / t - 9 / t + 9 / t + 18 (0.15 s and 0.075 s at 120 Hz), in frame t's body frame
    for t in (40, 200, m.n_frames // 2):
        for k, off in enumerate((-18, -9, 0, 9, 18)):
            np.testing.assert_allclose(x5[t, 15 * k : 15 * k + 15], by_hand(m.positions, t, t + off, F15), atol=2e-4)
        np.testing.assert_allclose(y3[t, :30], by_hand(m.positions, t, t - 18, F30), atol=2e-4)
        # not the sample frame's own body frame: the body turns during the window
        assert np.abs(x3[t, :15] - f15[t - 18]).max() > 1.0


def test_window_offsets_agree_between_120_and_30_hz(clip):
    m120 = clip("jogLeftCircle4StepsRstart")
    m30 = m120.resample(30)
    np.testing.assert_array_equal(m30.positions, m120.positions[::4][: m30.n_frames])  # frame k = frame 4k
    a30, a120 = numeric_features(m30, "F15x3E"), numeric_features(m120, "F15x3E")
    inner = np.arange(5, m30.n_frames - 5)
    # exactly: the 30 Hz samples are 120 Hz frames 4(k - 4), 4k, 4(k + 4) in the body frame of frame 4k
    for k in inner[::17]:
        for s, off in enumerate((-4, 0, 4)):
            np.testing.assert_allclose(
                a30[k, 15 * s : 15 * s + 15], by_hand(m120.positions, 4 * k, 4 * (k + off), F15), atol=2e-4
            )
    # and consistently: 0.133 s at 30 Hz vs 0.150 s at 120 Hz, a small difference next to the motion over 0.15 s
    same = a30[inner] - a120[4 * inner]
    np.testing.assert_array_equal(same[:, 15:30], 0.0)
    moved = a120[4 * inner][:, :15] - a120[4 * inner][:, 15:30]
    ratio = np.median(np.abs(same[:, :15])) / np.median(np.abs(moved))
    assert ratio < 0.25, ratio
    assert np.median(np.abs(moved)) > 2.0  # the jog moves several cm in 0.15 s


def test_windows_are_clamped_at_the_document_ends(clip):
    m = clip("squat1Reps")
    for name, samples in (("F15x3E", 3), ("F15x5E", 5)):
        v = numeric_features(m, name).reshape(m.n_frames, samples, 15)
        centre = samples // 2
        np.testing.assert_array_equal(v[0, 0], v[0, centre])  # the first frame's earliest sample is itself
        np.testing.assert_array_equal(v[-1, -1], v[-1, centre])
        # frame 5: its -0.15 s sample is frame 0 (clamped), in frame 5's body frame
        np.testing.assert_allclose(v[5, 0], by_hand(m.positions, 5, 0, F15), atol=2e-4)
        np.testing.assert_allclose(v[-3, -1], by_hand(m.positions, m.n_frames - 3, m.n_frames - 1, F15), atol=2e-4)
    # a one-frame clip is a window of one pose
    one = numeric_features(m[:1], "F15x5E")
    np.testing.assert_array_equal(one, np.tile(numeric_features(m[:1], "F15E"), 5))


def test_no_window_reads_the_neighbouring_document(hdm05_files, tmp_path, monkeypatch):
    db = two_documents(hdm05_files, tmp_path / "db")
    split = int(db.documents["n_frames"].iloc[0])
    for name in ("F15E", "F15x3E", "F15x5E", "F30x3E"):
        whole = numeric_features(db, name, progress=False)
        per_doc = np.concatenate([numeric_features(db.motion(d), name) for d in db.documents["doc_id"]])
        np.testing.assert_array_equal(whole, per_doc, err_msg=name)
        # the frames on either side of the boundary only see their own document
        v = whole.reshape(db.n_frames, -1, 3 * (len(F30) if name == "F30x3E" else len(F15)))
        c = v.shape[1] // 2
        np.testing.assert_array_equal(v[split - 1, -1], v[split - 1, c])
        np.testing.assert_array_equal(v[split, 0], v[split, c])
        # and several batches (whole documents each) give the same
        monkeypatch.setattr(nm, "_BATCH_FRAMES", 10)
        np.testing.assert_array_equal(numeric_features(db, name, progress=False, threads=2), whole)
        monkeypatch.undo()


def test_a_database_in_many_batches_equals_its_documents(reference_db, pca, monkeypatch):
    monkeypatch.setattr(nm, "_BATCH_FRAMES", 10)  # 22 batches of one document, more than the threads keep in flight
    for name in ("F30x3E", "Fp8"):
        per_doc = np.concatenate(
            [numeric_features(reference_db.motion(d), name, pca=pca) for d in reference_db.documents["doc_id"]]
        )
        np.testing.assert_array_equal(numeric_features(reference_db, name, pca=pca, progress=False, threads=2), per_doc)
    again = fit_pca(reference_db, progress=False, threads=2)
    np.testing.assert_allclose(again.explained_variance, pca.explained_variance, rtol=1e-9)
    np.testing.assert_allclose(np.abs(again.components @ pca.components.T), np.eye(25), atol=1e-6)


# ---------------------------------------------------------------------------------------------------- PCA
def test_pca_components_are_orthonormal_and_sorted(reference_db, pca):
    c = pca.components
    assert c.shape == (25, 72) and pca.mean.shape == (72,) and pca.n_frames == reference_db.n_frames
    np.testing.assert_allclose(c @ c.T, np.eye(25), atol=1e-10)
    ev = pca.explained_variance
    assert (np.diff(ev) <= 0).all() and ev[-1] > 0
    assert 0.9 < pca.explained_variance_ratio.sum() <= 1.0
    assert str(reference_db.path) in pca.reference
    # the same as numpy's covariance of the body-frame poses, eigen-decomposed independently
    poses = body_frame(np.asarray(reference_db.positions)).reshape(-1, 72).astype(np.float64)
    np.testing.assert_allclose(pca.mean, poses.mean(axis=0), atol=1e-6)
    cov = np.cov(poses, rowvar=False)
    np.testing.assert_allclose(ev, np.sort(np.linalg.eigvalsh(cov))[::-1][:25], rtol=1e-6)
    np.testing.assert_allclose(pca.total_variance, np.trace(cov), rtol=1e-9)
    np.testing.assert_allclose(np.einsum("kd,de,ke->k", c, cov, c), ev, rtol=1e-6)


def test_more_components_reconstruct_poses_better(pca, hdm05_files, cmu_dir):
    # clips outside the reference set (the 4th of a class; CMU)
    for motion in (
        mocapviz.load(hdm05_files("squat1Reps")[3]),
        mocapviz.load(cmu_dir / "amc" / "walk" / "walk_03.amc"),
    ):
        poses = body_frame(motion.canonical().positions).reshape(-1, 72).astype(np.float64)
        errors = []
        for n in (8, 16, 25):
            coef = numeric_features(motion, f"Fp{n}", pca=pca)
            np.testing.assert_allclose(coef, pca.project(poses, n), atol=1e-3)
            rec = pca.reconstruct(coef)
            errors.append(np.sqrt(((rec - poses) ** 2).reshape(-1, 24, 3).sum(axis=2).mean()))  # RMS joint error, cm
        assert errors[0] > errors[1] > errors[2], errors
        assert errors[2] < 0.5 * errors[0], errors


def test_pca_model_round_trip_and_bad_files(pca, tmp_path):
    path = tmp_path / "pca.npz"
    pca.save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["pca.npz"]  # no temporary file left
    back = PCAModel.load(path)
    for field in ("mean", "components", "explained_variance"):
        np.testing.assert_array_equal(getattr(back, field), getattr(pca, field))
    assert (back.total_variance, back.n_frames, back.reference) == (pca.total_variance, pca.n_frames, pca.reference)
    with np.load(path, allow_pickle=False) as z:  # plain arrays and a JSON header, no pickled objects
        assert set(z.files) == {"header", "mean", "components", "explained_variance"}
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="bad.npz"):
        PCAModel.load(bad)
    np.savez(tmp_path / "other.npz", mean=np.zeros(72))
    with pytest.raises(ValueError, match=r"other\.npz.*not a mocapviz\.PCAModel"):
        PCAModel.load(tmp_path / "other.npz")


# -------------------------------------------------------------------------------------------------- storage
def test_store_and_load_round_trip(hdm05_files, pca, tmp_path):
    db = two_documents(hdm05_files, tmp_path / "db")
    stored = store_numeric(db, ["F15E", "F15x3E", "Fp8", "Fp25"], progress=False)
    folder = db.path / "features"
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".lock")) == sorted(
        [f"numeric-{n}.{ext}" for n in ("F15E", "F15x3E", "Fp8", "Fp25") for ext in ("npy", "json")] + ["pca.npz"]
    )
    header = json.loads((folder / "numeric-Fp8.json").read_text())
    assert header["generation"] == db.manifest["generation"] and header["n_frames"] == db.n_frames
    assert header["pca"]["fitted_on_this_database"] and "this database" in header["pca"]["reference"]
    assert json.loads((folder / "numeric-F15x3E.json").read_text())["window"]["offsets_frames"] == {"120": [-18, 0, 18]}
    own = PCAModel.load(folder / "pca.npz")  # the default: fitted on this database
    assert own.n_frames == db.n_frames and own.n_components == 25
    for name in ("F15E", "F15x3E", "Fp8", "Fp25"):
        loaded = load_numeric(db, name)
        assert isinstance(loaded, np.memmap) and loaded.dtype == np.float32
        np.testing.assert_array_equal(loaded, numeric_features(db, name, pca=own, progress=False))
        np.testing.assert_array_equal(stored[name], loaded)
    # storing another Fp set later reuses the database's own model: the sets stored before stay valid
    store_numeric(db, "Fp16", progress=False)
    assert PCAModel.load(folder / "pca.npz").reference == own.reference
    np.testing.assert_array_equal(load_numeric(db, "Fp8"), stored["Fp8"])
    # with a given reference model: stored with it, the header names it
    store_numeric(db, "Fp16", pca=pca, progress=False)
    header = json.loads((folder / "numeric-Fp16.json").read_text())
    assert not header["pca"]["fitted_on_this_database"] and header["pca"]["reference"] == pca.reference
    np.testing.assert_array_equal(load_numeric(db, "Fp16"), numeric_features(db, "Fp16", pca=pca, progress=False))
    # pca.npz was replaced: the Fp sets stored with the old model are stale, the others not
    with pytest.raises(MotionDBError, match=r"Fp8 is stale.*pca\.npz.*run `mocapviz features DB`"):
        load_numeric(db, "Fp8")
    load_numeric(db, "F15E")
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")]


def test_stored_features_go_stale_when_the_database_grows(hdm05_files, tmp_path):
    db = two_documents(hdm05_files, tmp_path / "db")
    with pytest.raises(MotionDBError, match=r"F15E is not stored.*run `mocapviz features DB`"):
        load_numeric(db, "F15E")
    store_numeric(db, ["F15E", "F30x3E"], progress=False)
    grown = db.append(hdm05_files("squat1Reps")[:1], progress=False)
    for name in ("F15E", "F30x3E"):
        with pytest.raises(
            MotionDBError,
            match=rf"{name} is stale.*generation {db.manifest['generation']} "
            rf"\({db.n_frames} frames\).*run `mocapviz features DB`",
        ):
            load_numeric(grown, name)
    store_numeric(grown, "F15E", progress=False)
    np.testing.assert_array_equal(load_numeric(grown, "F15E")[: db.n_frames],
                                  numeric_features(db, "F15E", progress=False))  # fmt: skip
    assert load_numeric(grown, "F15E").shape == (grown.n_frames, 15)


def test_a_failed_store_keeps_the_previous_files_and_leaves_no_temporary_ones(hdm05_files, tmp_path, monkeypatch):
    db = two_documents(hdm05_files, tmp_path / "db")
    store_numeric(db, "F15x3E", progress=False)
    before = np.array(load_numeric(db, "F15x3E"))
    calls = []
    original = nm._joint_features

    def failing(*args):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("disk on fire")
        return original(*args) + 1.0  # different values, in case they were written

    monkeypatch.setattr(nm, "_joint_features", failing)
    monkeypatch.setattr(nm, "_BATCH_FRAMES", 10)  # one batch per document
    with pytest.raises(RuntimeError, match="disk on fire"):
        store_numeric(db, "F15x3E", progress=False, threads=1)
    monkeypatch.undo()
    np.testing.assert_array_equal(load_numeric(db, "F15x3E"), before)
    assert sorted(p.name for p in (db.path / "features").iterdir()) == [
        ".lock",
        "numeric-F15x3E.json",
        "numeric-F15x3E.npy",
    ]

    # killed after the new data is in place but before its header: the set reads as missing, never as the old
    # header over new data
    def no_header(target, data):
        if target.suffix == ".json":
            raise KeyboardInterrupt
        return original_write(target, data)

    original_write = nm.atomic_write
    monkeypatch.setattr(nm, "atomic_write", no_header)
    with pytest.raises(KeyboardInterrupt):
        store_numeric(db, "F15x3E", progress=False)
    monkeypatch.undo()
    with pytest.raises(MotionDBError, match="F15x3E is not stored"):
        load_numeric(db, "F15x3E")
    assert not [p for p in (db.path / "features").iterdir() if p.name.endswith(".tmp")]


# ------------------------------------------------------------------------------------------------ bad input
def test_bad_input_is_named(clip, pca, hdm05_files, tmp_path):
    m = clip("squat1Reps")
    with pytest.raises(ValueError, match="unknown numeric set 'F16E'; choose one of " + ", ".join(NUMERIC_SETS)):
        numeric_features(m, "F16E")
    with pytest.raises(ValueError, match="unknown numeric set"):
        load_numeric(MotionDB.create(tmp_path / "empty"), "f15e")
    with pytest.raises(ValueError, match="Fp16 needs a PCA model"):
        numeric_features(m, "Fp16")
    small = fit_pca(m, n_components=8)
    assert "squat1Reps" in small.reference
    with pytest.raises(ValueError, match="Fp16 needs 16 components.*has 8"):
        numeric_features(m, "Fp16", pca=small)
    with pytest.raises(ValueError, match="n_components"):
        fit_pca(m, n_components=73)
    with pytest.raises(ParameterError, match="Motion or a MotionDB"):
        numeric_features(m.positions, "F15E")
    # a NaN names the clip, the frame and the joint; a joint the set does not use is not checked
    bad = m.positions.copy()
    bad[37, CANONICAL_JOINTS.index("rwrist")] = np.nan
    bad[50, CANONICAL_JOINTS.index("lfingers")] = np.inf
    broken = replace(m, positions=bad)
    with pytest.raises(ValueError, match=r"HDM_.*squat1Reps.*frame 37: joint rwrist has a non-finite"):
        numeric_features(broken, "F15x3E")
    assert np.isfinite(numeric_features(broken[38:], "F15E")).all()
    with pytest.raises(ValueError, match=r"frame 12: joint lfingers"):
        numeric_features(broken[38:], "Fp8", pca=pca)
    # in a MotionDB: the document, its file and the frame within it
    db = two_documents(hdm05_files, tmp_path / "db")
    positions = np.array(db.positions)
    positions[int(db.documents["start"].iloc[1]) + 21, CANONICAL_JOINTS.index("head")] = np.nan
    db.positions = positions
    with pytest.raises(ValueError, match=r"document 1 \(.*HDM_.*kickLFront.*\), frame 21: joint head"):
        numeric_features(db, "F15E", progress=False)
