"""Markers -> canonical joints (mocapviz.motion.markers) and the measurement against the AMC of the same take
(mocapviz.experiments.markers).

The formula tests use hand-made geometry (synthetic points, said so in each test): the Harrington et al. 2007
regression and the chord rule are checked against values worked out by hand and against rigid motions of the
markers. Everything else runs on the real C3D files of the ``c3d-markers`` archive and the CMU AMC of take 135_02.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapviz import MotionDB, load
from mocapviz.errors import ParameterError, SkeletonMappingError
from mocapviz.experiments.markers import (
    floor_alignment,
    frame_lag,
    marker_comparison,
    marker_pairs,
    marker_reconstruction,
)
from mocapviz.motion.markers import chord, fill_gaps, harrington_hips, marker_joints
from mocapviz.motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS, to_canonical

J = CANONICAL_JOINTS.index


# ------------------------------------------------------------------------------ formulas on hand-made geometry
def test_harrington_by_hand_and_under_rigid_motion():
    """Synthetic pelvis: ASIS 24 cm apart, PSIS 8 cm apart 16 cm behind, facing +z. By hand (mm): PW = 240,
    PD = 160, x = -0.24 * 160 - 9.9 = -48.3, y = -0.30 * 240 - 10.9 = -82.9, z = 0.33 * 240 + 7.3 = 86.5."""
    pts = np.array([[12, 0, 0], [-12, 0, 0], [4, 0, -16], [-4, 0, -16]], dtype=float)[:, None]  # (4, T=1, 3)
    left, right = harrington_hips(*pts)
    np.testing.assert_allclose(left[0], [8.65, -8.29, -4.83], atol=1e-9)
    np.testing.assert_allclose(right[0], [-8.65, -8.29, -4.83], atol=1e-9)
    turn = Rotation.from_euler("xyz", [20, -70, 35], degrees=True).as_matrix()
    moved = pts @ turn.T + [100.0, 50.0, -30.0]
    l2, r2 = harrington_hips(*moved)
    np.testing.assert_allclose(l2, left @ turn.T + [100.0, 50.0, -30.0], atol=1e-9)
    np.testing.assert_allclose(r2, right @ turn.T + [100.0, 50.0, -30.0], atol=1e-9)


def test_chord_puts_the_centre_medially_at_a_right_angle():
    """Synthetic bent leg: hip above, lateral knee marker, wand on the lateral thigh; the centre is ``offset`` from
    the marker, on the side away from the wand, and sees hip and marker at 90 degrees."""
    hip, knee_marker, wand = np.array([[3.0, 45, 10]]), np.array([[9.0, 2, 4]]), np.array([[14.0, 25, 6]])
    centre = chord(hip, wand, knee_marker, 6.0)
    assert np.linalg.norm(centre - knee_marker) == pytest.approx(6.0)
    assert np.dot((knee_marker - centre)[0], (hip - centre)[0]) == pytest.approx(0.0, abs=1e-9)
    normal = np.cross(hip - knee_marker, wand - knee_marker)[0]
    assert np.dot(centre[0] - knee_marker[0], normal) == pytest.approx(0.0, abs=1e-9)  # in the plane
    assert centre[0, 0] < knee_marker[0, 0]  # medial: the wand is lateral (+x)


def test_fill_gaps_fills_short_gaps_only():
    """Synthetic straight-line marker at 100 fps: gaps of 20 frames inside and at the start are filled (linear
    inside: exact for a straight line; held at the start), a 40-frame gap is not (0.25 s = 25 frames)."""
    t = np.arange(200.0)
    p = np.stack([t, 2 * t, -t], axis=1)[:, None].repeat(2, axis=1)
    gappy = p.copy()
    gappy[50:70, 0] = np.nan
    gappy[:20, 1] = np.nan
    gappy[100:140, 1] = np.nan
    out = fill_gaps(gappy, 100.0)
    np.testing.assert_allclose(out[:, 0], p[:, 0], atol=1e-4)
    np.testing.assert_allclose(out[:20, 1], np.repeat(p[20:21, 1], 20, axis=0))
    assert np.isnan(out[100:140, 1]).all() and not np.isnan(out[140:, 1]).any()


# ------------------------------------------------------------------------------ real files
@pytest.fixture(scope="module")
def take(c3d_dir):
    return load(c3d_dir / "cmu_07_01.c3d")


def test_canonical_of_a_c3d_is_the_24_joints_and_canonical_again_is_itself(take):
    c = take.canonical()
    assert c.joint_names == CANONICAL_JOINTS and (c.parents == CANONICAL_PARENTS).all()
    assert c.positions.shape == (take.n_frames, 24, 3) and np.isfinite(c.positions).all()
    assert to_canonical(c) is c and c.fps == take.fps and c.source == take.source


def test_bones_keep_their_length(c3d_dir):
    """Real CMU and HDM05 takes (walks, jumps, karate, breakdance): bones are rigid, so the estimated thigh, shank,
    upper arm and forearm lengths vary by less than 8 % (coefficient of variation) over each take."""
    bones = [("lhip", "lknee"), ("rknee", "rankle"), ("lshoulder", "lelbow"), ("relbow", "rwrist")]
    for name in ("cmu_135_02.c3d", "cmu_85_12.c3d", "cmu_16_07.c3d", "HDM_mm_01-02_03_120.c3d"):
        p = load(c3d_dir / name).canonical().positions
        for a, b in bones:
            length = np.linalg.norm(p[:, J(a)] - p[:, J(b)], axis=1)
            assert length.std() / length.mean() < 0.08, (name, a, b, length.mean(), length.std())


def test_missing_markers_named_with_a_template_and_aliases_fix_it(take):
    names = tuple("LWT1" if n == "LFWT" else n for n in take.joint_names)
    renamed = replace(take, joint_names=names)
    with pytest.raises(SkeletonMappingError) as exc:
        renamed.canonical()
    line = next(t for t in exc.value.template.splitlines() if '"LFWT"' in t)
    assert exc.value.missing == ["LFWT"] and '"LFWT": "?"' in line and "LWT1" in line
    assert '"RFWT": "RFWT"' in exc.value.template and "mapping=" in str(exc.value)
    np.testing.assert_array_equal(renamed.canonical({"LFWT": "LWT1"}).positions, take.canonical().positions)
    with pytest.raises(ParameterError, match="NOPE"):
        marker_joints(take, aliases={"LFWT": "NOPE"})


def test_long_gap_refused_naming_marker_and_frames(take):
    p = take.positions.copy()
    p[100:160, take.joint_names.index("LKNE")] = np.nan  # 0.5 s of a real take blanked out
    with pytest.raises(SkeletonMappingError, match=r"LKNE \(frames 100 to 159, 60 frames\)"):
        replace(take, positions=p).canonical()
    assert np.isfinite(marker_joints(replace(take, positions=p), max_gap_s=1.0).positions).all()


def test_ingest_a_folder_of_c3d_files(c3d_dir, tmp_path):
    """The nine CMU and HDM05 files carry the whole 41-marker set and no gap the filling cannot close (manifest:
    gaps 0 or 2.4 %); the three gait-lab Plug-in Gait files convert with what was estimated said
    (tests/test_c3d_plugin_gait.py): all twelve become documents with their frame counts, btk_Gait's cut to the
    194 frames in which its subject is in view."""
    with pytest.warns(UserWarning, match="btk_Gait.c3d: .* cut"):
        db = MotionDB.ingest(c3d_dir, tmp_path / "db", progress=False)
    docs = db.documents.set_index("name")
    assert sorted(docs.index) == sorted(p.stem for p in c3d_dir.glob("*.c3d"))
    assert docs.loc["cmu_135_02", "n_frames"] == 5202 and docs.loc["HDM_bd_01-02_01_120", "n_frames"] == 2900
    assert docs.loc["btk_Gait", "n_frames"] == 194 and docs.loc["btk_FunctionalWalk", "n_frames"] == 438
    assert (docs["format"] == "c3d").all()


def test_frame_lag_finds_a_known_shift(c3d_dir, cmu_dir):
    a = load(c3d_dir / "cmu_135_02.c3d").canonical()
    b = load(cmu_dir / "amc/martialwalk/135_02.amc").canonical()
    assert frame_lag(a, b) == 0  # the same 5202 frames from frame 1 (both files)
    assert frame_lag(a[37:], b) == -37 and frame_lag(a, b[37:]) == 37


def test_only_135_02_has_an_amc(c3d_dir, cmu_dir):
    pairs = marker_pairs(c3d_dir, cmu_dir)
    assert pairs["take"].tolist() == ["135_02"]


def test_c3d_joints_agree_with_the_amc_of_the_same_take(c3d_dir, cmu_dir):
    """CMU 135_02 from its markers and from the skeleton CMU fitted to them: the 31 relational features agree on
    at least 95 % of the frames on average, F15E (hands, feet, head in the body frame) within 8 cm, and the DTW
    search over the 32 AMC takes ranks the same take's AMC first."""
    row = marker_comparison(c3d_dir, cmu_dir).iloc[0]
    print(row.to_dict())
    assert row["take"] == "135_02" and row["lag"] == 0 and row["frames"] == 5202
    assert row["agreement"] >= 0.95
    assert row["f15e_cm"] < 8.0
    assert row["rank_of_amc"] == 1 and row["searched"] == 32


def test_floor_alignment_finds_the_amcs_world(c3d_dir, cmu_dir):
    """The AMC of 135_02 keeps other world axes than its C3D file: carried over, the C3D take's root lies within a
    few centimetres of the AMC's on every frame (the marker model's pelvis centre against CMU's fitted root), where
    before it was metres away; a known turn and shift of a real clip is undone exactly."""
    a = load(c3d_dir / "cmu_135_02.c3d").canonical()
    b = load(cmu_dir / "amc/martialwalk/135_02.amc").canonical()
    before = np.linalg.norm(a.positions[:, 0] - b.positions[:, 0], axis=1)
    after = np.linalg.norm(floor_alignment(a.positions, b.positions)[:, 0] - b.positions[:, 0], axis=1)
    assert np.median(before) > 100 and np.percentile(after, 95) < 10
    turn = Rotation.from_euler("y", 33, degrees=True).as_matrix()
    moved = b.positions @ turn.T + [250.0, 3.0, -80.0]
    assert np.abs(floor_alignment(moved, b.positions) - b.positions).max() < 1e-3


def test_real_markers_rebuild_the_take_as_closely_as_the_marker_model(c3d_dir, cmu_dir):
    """Krüger et al. 2010 §5.2 from real markers: the six joints estimated from 135_02's marker clusters, rebuilt
    with the other CMU takes as the prior, come as close to the AMC of the take as all 24 marker-derived joints do
    (within 1 cm of that floor) and under 10 cm per joint; the paper's simulated markers (the AMC's own joints
    +-1 mm) do better than both."""
    table = marker_reconstruction(c3d_dir, cmu_dir).set_index("markers")
    real, simulated = table.loc["real (C3D marker clusters)"], table.loc["simulated (AMC joints ± noise)"]
    floor = table.loc["none: the C3D take's 24 joints"]
    assert real["take"] == "135_02" and real["frames"] == 5202 // 4 + 1 and real["fps"] == 30
    assert real["mean_cm"] < min(10.0, floor["mean_cm"] + 1.0)
    assert simulated["mean_cm"] < min(real["mean_cm"], floor["mean_cm"])


def test_bad_max_gap_refused(take):
    for bad in (-0.1, float("nan"), "long"):
        with pytest.raises(ParameterError, match="max_gap_s"):
            marker_joints(take, max_gap_s=bad)


def test_raw_markers_are_kept_beside_the_joints(c3d_dir, cmu_dir, tmp_path):
    """Ingest stores each C3D document's markers with the database (mocapviz.db.markers): read back they are the
    file's (labels, rate, positions, the same gaps as NaN) even after the file is gone; a document read from an AMC
    has none (said so); a damaged markers file is refused, never returned."""
    import shutil

    from mocapviz.db.markers import has_markers, load_markers, markers_path
    from mocapviz.errors import MotionDBError
    from mocapviz.io.c3d import read_c3d

    files = [shutil.copy(c3d_dir / name, tmp_path) for name in ("cmu_07_01.c3d", "cmu_01_01.c3d")]
    db = MotionDB.ingest([*files, cmu_dir / "amc/martialwalk/135_02.amc"], tmp_path / "db", progress=False)
    originals = {f: read_c3d(f) for f in files}
    for f in files:
        Path(f).unlink()  # nothing lost: the markers come from the database now
    docs = db.documents.set_index("name")
    for f, original in originals.items():
        doc = int(docs.at[Path(f).stem, "doc_id"])
        got = load_markers(db, doc)
        assert got.joint_names == original.joint_names and got.fps == original.fps
        np.testing.assert_array_equal(got.positions, original.positions)  # NaN where the file has gaps
        assert got.labels["first_frame"] == original.labels["first_frame"]
    assert np.isnan(originals[files[1]].positions).any()  # cmu_01_01 has gaps (2.4 %, manifest): they survived
    amc = int(docs.at["135_02", "doc_id"])
    assert not has_markers(db, amc)
    with pytest.raises(MotionDBError, match="no markers stored for document .* only documents read from C3D"):
        load_markers(db, amc)
    doc = int(docs.at["cmu_07_01", "doc_id"])
    from mocapviz.integrity import check

    assert check(db.path).query("what.str.startswith('markers')")["ok"].tolist() == [True, True]
    raw = bytearray(markers_path(db, doc).read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    markers_path(db, doc).write_bytes(bytes(raw))
    with pytest.raises(MotionDBError, match="cmu_07_01"):
        load_markers(db, doc)
    report = check(db.path).set_index("what")  # `mocapviz check DB` names the damaged file
    assert not report.loc[f"markers of document {doc}", "ok"]


def test_a_c3d_document_exports_on_the_canonical_rig_and_says_why_not_as_source_bvh(c3d_dir, tmp_path):
    """Hits in C3D documents export as the canonical skeleton (read back within 0.01 cm) and as glTF on the source
    (the markers as points); BVH on the source is refused with what to pass instead."""
    from mocapviz.errors import ParameterError
    from mocapviz.export import stretch_files

    db = MotionDB.ingest([c3d_dir / "cmu_07_01.c3d"], tmp_path / "db", progress=False)
    (name, data), = stretch_files(db, 0, 10, 70, "bvh", "canonical").items()
    (tmp_path / name).write_bytes(data)
    back = load(tmp_path / name).canonical({c: c for c in CANONICAL_JOINTS}).positions
    assert np.abs(back - db.positions[db.frames(0)][10:70]).max() < 0.01
    assert list(stretch_files(db, 0, 10, 70, "glb", "source")) == ["001_doc0_cmu_07_01_10-70.glb"]
    with pytest.raises(ParameterError, match="C3D file: markers, no rig.*rig='canonical'"):
        stretch_files(db, 0, 10, 70, "bvh", "source")
