"""HumanML3D's joint arrays (issue 42, item 5): exported and read back, they are the database's frames.

The layout is checked against HumanML3D's own kinematic chains; an exported array, its placement undone with the
manifest's yaw and origin, equals the database's canonical joints at 20 fps (120 Hz sources: every 6th frame, no
interpolation; other rates: Motion.resample); its T is derived from the frames and the rate; random stretches
(hypothesis) and real BVH clips of another rate agree too; the manifest's seconds are the hit table's; an exported
clip read back finds its source clip first; bad arrays are refused naming the file.
"""
from __future__ import annotations

import io
import itertools
import pickle
import zipfile
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB, load
from mocapviz.cli import main
from mocapviz.cli.parser import build_parser
from mocapviz.db.hits import hit_table
from mocapviz.engine import Engine
from mocapviz.engine.parameters import parameter
from mocapviz.errors import MocapFormatError, ParameterError
from mocapviz.export import export_hits, export_stretch, hit_files, hits_zip, source_frames, stretch_files
from mocapviz.export.joint_arrays import MANIFEST
from mocapviz.io.humanml3d import EXTRAPOLATED, JOINTS, PARENTS, PLACED, joint_array, joint_positions
from mocapviz.motion import Motion
from mocapviz.motion.joints import CANONICAL_JOINTS, CANONICAL_PARENTS

TOLERANCE_CM = 1e-3  # float32 metres of positions within a few metres: about 1e-5 cm
# HumanML3D's paramUtil.t2m_kinematic_chain: right leg, left leg, spine to head, right arm, left arm
T2M_CHAINS = [[0, 2, 5, 8, 11], [0, 1, 4, 7, 10], [0, 3, 6, 9, 12, 15], [9, 14, 17, 19, 21], [9, 13, 16, 18, 20]]
SMPL_NAMES = ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
              "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
              "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist"]
KEPT = [c for c in CANONICAL_JOINTS if c not in EXTRAPOLATED]  # the 21 canonical joints an array gives back


@pytest.fixture(scope="module")
def db():
    return MotionDB.sample()


def _expected_frames(n: int, fps: float) -> int:
    """Frames at k / 20 s within the n frames' span, (n - 1) / fps s, counted exactly."""
    last = Fraction(n - 1) / Fraction(fps).limit_denominator(10**6)
    return int(last * 20) + 1


def _unplaced_cm(array: np.ndarray, row) -> np.ndarray:
    """The array's canonical joints (:func:`load`'s) back in the database's coordinates, cm, by the manifest's
    placement: p = R_y(-yaw) q + origin."""
    yaw = np.radians(float(row["yaw_deg"]))
    origin = np.array([row["origin_x_m"], row["origin_y_m"], row["origin_z_m"]], dtype=np.float64)
    c, s = np.cos(-yaw), np.sin(-yaw)
    x, y, z = array[..., 0], array[..., 1], array[..., 2]
    return 100.0 * (np.stack([c * x + s * z, y, c * z - s * x], axis=-1) + origin)


def _check_stretch(db, doc: int, start: int, end: int, array_path, row) -> float:
    """The exported array of document ``doc``'s frames start:end read back equals them at 20 fps; returns the
    largest error, cm."""
    fps = float(db.document(doc)["fps"])
    raw = np.load(array_path)
    assert raw.dtype == np.float32 and raw.shape == (_expected_frames(end - start, fps), 22, 3)
    assert int(row["frames"]) == len(raw)
    motion = load(array_path, layout="humanml3d")
    assert motion.fps == 20.0 and motion.joint_names == CANONICAL_JOINTS and motion.n_frames == len(raw)
    reference = db.motion(doc)[start:end]
    expected = reference.positions[::6] if fps == 120.0 else reference.resample(20).positions  # 120 Hz: exact
    kept = [CANONICAL_JOINTS.index(c) for c in KEPT]
    back = _unplaced_cm(motion.positions.astype(np.float64) / 100.0, row)
    error = float(np.abs(back[:, kept] - expected[:, kept]).max())
    assert error < TOLERANCE_CM, (doc, start, end, error)
    # HumanML3D's placement: floor at 0, the first root over the origin, the first frame facing +z by hips and
    # shoulders (right minus left, crossed with up: (across_z, 0, -across_x))
    assert abs(float(raw[..., 1].min())) < 1e-6 and np.abs(raw[0, 0, [0, 2]]).max() < 1e-6
    i = {n: JOINTS.index(n) for n in ("right_hip", "left_hip", "right_shoulder", "left_shoulder")}
    across = raw[0, i["right_hip"]] - raw[0, i["left_hip"]] + raw[0, i["right_shoulder"]] - raw[0, i["left_shoulder"]]
    forward = np.array([across[2], 0.0, -across[0]])
    assert np.allclose(forward / np.linalg.norm(forward), [0, 0, 1], atol=1e-5)
    return error


# ----------------------------------------------------------------------------------------------------- the layout
def test_the_layout_is_humanml3ds_kinematic_chains():
    assert list(JOINTS) == SMPL_NAMES
    parents = np.full(22, -1)
    for chain in T2M_CHAINS:
        for parent, child in itertools.pairwise(chain):
            parents[child] = parent
    assert parents.tolist() == PARENTS.tolist()
    one_to_one = {j: a for j, (a, b, f) in PLACED.items() if f == 0.0}
    assert len(one_to_one) == 19 and len(set(one_to_one.values())) == 19
    # a one-to-one joint's parent is the canonical joint's ancestor's image: the two trees agree where they map
    for j, c in one_to_one.items():
        parent = JOINTS[PARENTS[JOINTS.index(j)]] if PARENTS[JOINTS.index(j)] >= 0 else None
        ancestors, k = [], CANONICAL_PARENTS[CANONICAL_JOINTS.index(c)]
        while k >= 0:
            ancestors.append(CANONICAL_JOINTS[k])
            k = CANONICAL_PARENTS[k]
        while parent is not None and parent not in one_to_one:  # spine3, a collar: up to the next mapped joint
            parent = JOINTS[PARENTS[JOINTS.index(parent)]]
        assert parent is None or one_to_one[parent] in ancestors, (j, parent)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_canonical_joints_come_back_from_the_22(seed):
    """Random poses: the 21 canonical joints that are not extrapolated come back from the 22 (one-to-one, or a
    clavicle solved from its collar)."""
    from mocapviz.io.humanml3d import canonical_positions

    p = np.random.default_rng(seed).normal(scale=50.0, size=(3, 24, 3))
    back = canonical_positions(joint_positions(p))
    kept = [CANONICAL_JOINTS.index(c) for c in KEPT]
    assert np.allclose(back[:, kept], p[:, kept], atol=1e-9)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.integers(0, 23), yaw=st.floats(-np.pi, np.pi), shift=st.tuples(*[st.floats(-500, 500)] * 3))
def test_the_placement_does_not_depend_on_where_the_clip_stands(db, doc, yaw, shift):
    """A clip turned about y and moved anywhere gives the same array (HumanML3D's placement), within float32."""
    m = db.motion(doc)[:60]
    c, s = np.cos(yaw), np.sin(yaw)
    x, y, z = (m.positions[..., k].astype(np.float64) for k in range(3))
    moved = np.stack([c * x + s * z, y, c * z - s * x], axis=-1) + np.array(shift)
    a, _, _ = joint_array(m)
    b, _, _ = joint_array(Motion(moved, m.fps, m.joint_names, m.parents))
    assert np.abs(a - b).max() < 5e-5  # metres


# ---------------------------------------------------------------------------------------------- export, read back
def test_sample_clips_round_trip_through_export_hits(db, tmp_path):
    """Every sample document (22 HDM05, 2 CMU, 120 Hz): its middle, exported as one hit table, read back."""
    docs = db.documents["doc_id"].astype(int).tolist()
    n = [int(db.document(d)["n_frames"]) for d in docs]
    hits = hit_table(db, docs, [k // 4 for k in n], [k - k // 6 for k in n], cost=np.arange(len(docs)) / 10)
    paths = export_hits(db, hits, tmp_path, format="humanml3d", search="every document")
    assert [p.name for p in paths][-1] == MANIFEST and len(paths) == len(docs) + 1
    manifest = pd.read_csv(tmp_path / MANIFEST)
    assert manifest["file"].tolist() == [p.name for p in paths[:-1]]
    assert manifest[["rank", "doc_id", "start", "end"]].values.tolist() == \
        hits[["rank", "doc_id", "start", "end"]].values.tolist()
    fps = db.documents.set_index("doc_id").loc[hits["doc_id"], "fps"].to_numpy()
    assert np.allclose(manifest["start_s"], hits["start"] / fps) and np.allclose(manifest["end_s"], hits["end"] / fps)
    assert np.allclose(manifest["cost"], hits["cost"]) and (manifest["search"] == "every document").all()
    errors = [_check_stretch(db, int(r["doc_id"]), int(r["start"]), int(r["end"]), tmp_path / r["file"], r)
              for _, r in manifest.iterrows()]
    print(f"sample: largest error {max(errors):.2e} cm")


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_stretches_round_trip(db, data, tmp_path_factory):
    doc = data.draw(st.integers(0, 23), label="doc")
    n = int(db.document(doc)["n_frames"])
    start = data.draw(st.integers(0, n - 1), label="start")
    end = data.draw(st.integers(start + 1, n), label="end")
    folder = tmp_path_factory.mktemp("stretch")
    paths = export_stretch(db, doc, folder, start, end, format="humanml3d")
    assert [p.name for p in paths] == [f"001_doc{doc}_{db.document(doc)['name']}_{start}-{end}.npy", MANIFEST]
    [row] = pd.read_csv(folder / MANIFEST).to_dict("records")
    fps = float(db.document(doc)["fps"])
    assert (row["start_s"], row["end_s"]) == (start / fps, end / fps)
    assert (row["source_start"], row["source_end"]) == source_frames(db.document(doc), start, end)
    _check_stretch(db, doc, start, end, paths[0], row)


def test_bvh_clips_at_another_rate_round_trip(bandai1_files, tmp_path):
    """Bandai Namco BVH (not 120 Hz: frames between the 20 fps times, interpolated as Motion.resample does)."""
    db = MotionDB.ingest(bandai1_files[:2], tmp_path / "db", progress=False)
    for doc in db.documents["doc_id"].astype(int):
        n = int(db.document(doc)["n_frames"])
        paths = export_stretch(db, doc, tmp_path / f"out{doc}", 3, n - 2, format="humanml3d")
        [row] = pd.read_csv(paths[1]).to_dict("records")
        _check_stretch(db, doc, 3, n - 2, paths[0], row)


def test_the_zip_and_the_cli_hold_the_same_files(db, tmp_path, capsys):
    hits = hit_table(db, [7, 1], [0, 100], [129, 400], cost=[0.5, 0.7])
    files = hit_files(db, hits, format="humanml3d")
    assert list(files)[-1] == MANIFEST and len(files) == 3
    archive = zipfile.ZipFile(io.BytesIO(hits_zip(db, hits, format="humanml3d")))
    assert archive.namelist() == list(files) and all(archive.read(n) == files[n] for n in files)
    csv = tmp_path / "hits.csv"
    hits.to_csv(csv, index=False)
    assert main(["export", str(db.path), "--hits", str(csv), "--format", "humanml3d", "--out", str(tmp_path / "a")]) == 0
    written = {p.name: p.read_bytes() for p in (tmp_path / "a").iterdir()}
    assert {n: d for n, d in written.items() if n != MANIFEST} == {n: d for n, d in files.items() if n != MANIFEST}
    assert pd.read_csv(tmp_path / "a" / MANIFEST)["search"].tolist() == ["hits of hits.csv"] * 2
    assert main(["export", str(db.path), "--doc", "7", "--frames", "0:60", "--format", "humanml3d", "--out",
                 str(tmp_path / "b")]) == 0  # fmt: skip
    assert "2 file(s) written" in capsys.readouterr().out
    assert np.load(next((tmp_path / "b").glob("*.npy"))).shape == (10, 22, 3)  # 60 frames at 120 Hz: 0.49 s


def test_the_format_choices_are_declared_once():
    parser = build_parser()
    export = next(a for a in parser._actions if a.dest == "command").choices["export"]
    options = {a.dest: a for a in export._actions}
    assert tuple(options["format"].choices) == parameter("export_format").choices
    assert "humanml3d" in parameter("export_format").choices and parameter("layout").choices == ("humanml3d",)


def test_humanml3d_is_made_on_the_canonical_rig_only(db):
    with pytest.raises(ParameterError, match="rig='canonical'"):
        stretch_files(db, 7, 0, 60, format="humanml3d", rig="source")


# ----------------------------------------------------------------------------------------------------- the use case
@pytest.mark.parametrize("doc", [7, 11, 1])  # an HDM05 kick, an HDM05 squat, a CMU trial
def test_a_clip_read_back_finds_its_source_first(db, doc, tmp_path):
    """A 'generated' motion (a real clip exported and read back, 20 fps) searched by whole-clip DTW (F15E) finds the
    document it came from first."""
    [array, _] = export_stretch(db, doc, tmp_path, format="humanml3d")
    found = Engine(db).clips(load(array, layout="humanml3d"), n_matches=3)
    assert int(found["doc_id"].iloc[0]) == doc


# --------------------------------------------------------------------------------------------------- bad input
def test_a_npy_file_needs_a_known_layout(db, tmp_path):
    path = tmp_path / "x.npy"
    np.save(path, np.zeros((4, 22, 3), np.float32))
    with pytest.raises(ParameterError, match="pass layout= one of humanml3d"):
        load(path)
    with pytest.raises(ParameterError, match="unknown layout 'smpl'.*humanml3d"):
        load(path, layout="smpl")
    with pytest.raises(ParameterError, match="layout='humanml3d' is for .npy joint arrays"):
        load(db.document(7)["path"], layout="humanml3d")
    with pytest.raises(ParameterError, match="outside 1 to 10,000"):
        load(path, layout="humanml3d", fps=0.5)
    assert load(path, layout="humanml3d", fps=30).fps == 30.0


BAD = {
    "wrong shape": (np.zeros((4, 21, 3), np.float32), r"shape \(4, 21, 3\); HumanML3D's joint arrays are \(T, 22, 3\)"),
    "feature vectors": (np.zeros((4, 263), np.float32), r"feature vectors \(new_joint_vecs\)"),
    "no frames": (np.zeros((0, 22, 3), np.float32), r"shape \(0, 22, 3\)"),
    "integers": (np.zeros((4, 22, 3), np.int64), "holds int64 values"),
    "objects": (np.array([[None]] * 2, dtype=object), "pickled Python objects"),
}


def _save_as_numpy_does(path, array: np.ndarray) -> None:
    """``array`` written as ``np.save`` writes it, an object array as a pickle after the header (never loaded here)."""
    with open(path, "wb") as f:
        if array.dtype != object:
            np.save(f, array)
            return
        np.lib.format.write_array_header_1_0(f, np.lib.format.header_data_from_array_1_0(array))
        f.write(pickle.dumps(array, protocol=3))


@pytest.mark.parametrize("case", list(BAD) + ["not finite", "too far", "npz", "text"])
def test_bad_arrays_are_refused_naming_the_file(case, tmp_path):
    path = tmp_path / "bad.npy"
    if case in BAD:
        array, reason = BAD[case]
        _save_as_numpy_does(path, array)
    elif case in ("not finite", "too far"):
        array = np.zeros((5, 22, 3), np.float32)
        array[3, JOINTS.index("left_wrist"), 1] = np.nan if case == "not finite" else 2e5
        np.save(path, array)
        reason = f"frame 3, joint left_wrist, y: {'nan' if case == 'not finite' else '200000'}"
    elif case == "npz":
        with open(path, "wb") as f:
            np.savez(f, a=np.zeros((4, 22, 3)))
        reason = "an .npz archive"
    else:
        path.write_text("1 2 3\n")
        reason = "not a NumPy .npy array"
    with pytest.raises(MocapFormatError, match=reason) as caught:
        load(path, layout="humanml3d")
    assert caught.value.path == str(path)
