"""The FBX reader (mocapviz.io.fbx) on the peer-readers archive's six FBX files: frame counts and rates from the
archive's MANIFEST.md, ASCII and binary twins, takes, the CMU take against its BVH twin, canonical mapping, ingest,
damaged files (hypothesis-mutated bytes; the long tier is ``-m slow``)."""
from __future__ import annotations

import json
import subprocess
import sys
from typing import NamedTuple

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapviz import MotionDB, load
from mocapviz.errors import MocapFormatError, MocapFormatWarning, ParameterError, SkeletonMappingError
from mocapviz.io import FORMATS
from mocapviz.io.fbx import read_fbx

pytest.importorskip("ufbx", reason="the FBX reader needs ufbx")

SAUSAGE = ["ufbx_maya_game_sausage_6100_ascii_wiggle.fbx", "ufbx_maya_game_sausage_6100_binary_wiggle.fbx",
           "ufbx_maya_game_sausage_7500_ascii_wiggle.fbx", "ufbx_maya_game_sausage_7500_binary_wiggle.fbx"]
# MANIFEST.md: (joints, frames, fps). isaac: 38 LimbNodes, 2752 keys at 120 fps; sausage: 4 LimbNodes, keys on frames
# 1-20 at 24 fps; assimp: 16 LimbNodes, 0-0.833 s at 24 fps (TimeMode 11), that is frames 0 to 20
EXPECTED = {"isaac_01_01_cmu.fbx": (38, 2752, 120.0), "assimp_animation_with_skeleton.fbx": (16, 21, 24.0),
            **{name: (4, 20, 24.0) for name in SAUSAGE}}  # fmt: skip
BVH_UNIT_CM = 100.0  # the CMU FBX's file unit per unit of its BVH twin (module docstring of test_cross_format)
CMU_UNIT_CM = 2.54 / 0.45  # the BVH twin's unit (CMU's 0.45 inch, as its ASF): what the BVH reader guesses


class _Pair(NamedTuple):
    fbx: object
    bvh: object
    path: object


@pytest.fixture(scope="module")
def peer(fetch_archive):
    return fetch_archive("peer-readers")


@pytest.fixture(scope="module")
def cmu_pair(peer):
    """(the CMU FBX read in cm at the BVH twin's unit, the BVH twin, the FBX file)."""
    fbx = read_fbx(peer / "fbx/isaac_01_01_cmu.fbx", scale=CMU_UNIT_CM / BVH_UNIT_CM)
    with pytest.warns(MocapFormatWarning, match="read as CMU units of 0.45 inch"):
        bvh = load(peer / "bvh/assimp_01_01.bvh")
    return _Pair(fbx, bvh, peer / "fbx/isaac_01_01_cmu.fbx")


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_peer_fbx_loads_with_its_manifest_frames_and_rate(peer, name):
    m = load(peer / "fbx" / name)
    joints, frames, fps = EXPECTED[name]
    assert (m.n_joints, m.n_frames, m.fps) == (joints, frames, fps)
    assert m.positions.dtype == np.float32 and np.isfinite(m.positions).all()
    assert np.allclose(np.linalg.norm(m.quaternions, axis=-1), 1.0, atol=1e-5)
    assert (m.parents < np.arange(m.n_joints)).all()  # parents first


def test_fbx_is_a_format_of_load_and_ingest():
    assert ".fbx" in FORMATS


def test_ascii_and_binary_twins_give_the_same_positions(peer):
    first, *others = [load(peer / "fbx" / name) for name in SAUSAGE]
    assert first.joint_names == ("joint1", "joint2", "joint3", "joint4")
    assert np.ptp(first.positions, axis=0).max() > 0.5  # it moves (a wiggle), so equal positions mean something
    for other in others:
        assert other.joint_names == first.joint_names
        np.testing.assert_allclose(other.positions, first.positions, atol=1e-4)
        np.testing.assert_allclose(other.quaternions, first.quaternions, atol=1e-5)


def test_take_selection_and_an_unknown_take(peer):
    path = peer / "fbx/ufbx_maya_game_sausage_7500_binary_wiggle.fbx"
    assert load(path, take="wiggle").labels["take"] == "wiggle"
    with pytest.raises(MocapFormatError, match=r"no take 'walk'; the file's takes: 'wiggle'") as exc:
        load(path, take="walk")
    assert str(path) in str(exc.value)
    with pytest.raises(ParameterError):
        read_fbx(path, take=3)


def test_cross_format_cmu_01_01_agrees_with_its_bvh_twin(cmu_pair):
    """The CMU take 01_01 as FBX (IsaacGymEnvs) and as BVH (assimp): the same joint positions on every frame.

    Alignment: both have 2,752 frames at 120 Hz and their frames line up one to one (a shift of one frame either
    way makes the error ten times larger); frame 0 of both is the BVH conversion's synthetic reference pose, which
    the FBX kept, so it is compared too, separately. Units: the FBX was written by Blender from the BVH, one BVH unit
    taken for one metre, and says its unit is the centimetre: its positions are 100 times the BVH's, exactly
    (the test reads it with ``scale=0.01``). Joints: the 34 both name alike; the FBX's end bones named after their
    joints (``Head_end``...) are the BVH's End Sites; the hand bones differ in name (``LeftHandIndex1`` against
    ``LFingers``) and are left out.

    Agreement: within 0.1 mm where the FBX holds the take's values, within 0.1 BVH unit (0.56 cm) elsewhere.
    Blender's exporter simplified the curves: of the 288 curves 53 do not move, most others keep 2,100 to 2,751 of
    the 2,752 keys (one rotation curve of Hips 1,906), on whole frames, and between the kept keys the file holds
    their linear interpolation. On the frames where every moving curve has a key (besides the reference pose, the
    last: found by :func:`keyed_on_every_moving_curve`) the two agree within 0.1 mm; on the others within 0.1 BVH
    unit (measured 0.098, median 0.02), largest at the hands and toes. Frame 0 agrees within 1.1 units.
    """
    fbx, bvh, _ = cmu_pair
    assert (fbx.n_frames, fbx.fps) == (bvh.n_frames, bvh.fps) == (2752, 120.0)
    common = [n for n in fbx.joint_names if n in bvh.joint_names]
    assert len(common) == 34 and "Head_end" in common
    a = fbx.positions[:, [fbx.joint_names.index(n) for n in common]].astype(np.float64)
    b = bvh.positions[:, [bvh.joint_names.index(n) for n in common]].astype(np.float64)
    error = np.linalg.norm(a - b, axis=2) / CMU_UNIT_CM  # BVH units
    keyed = keyed_on_every_moving_curve(cmu_pair.path)
    assert keyed[keyed > 0].tolist() == [2751]
    assert error[keyed[keyed > 0]].max() * CMU_UNIT_CM < 0.01  # 0.1 mm
    assert error[1:].max() < 0.1
    assert np.median(error[1:]) < 0.02
    assert error[0].max() < 1.1
    shifted = np.linalg.norm(a[2:] - b[1:-1], axis=2) / CMU_UNIT_CM  # one frame off: clearly worse
    assert shifted.max() > 5 * error[1:].max()


def keyed_on_every_moving_curve(path) -> np.ndarray:
    """The frames (at 120 Hz) on which every animation curve of the FBX file whose value changes has a key, read by
    ufbx in a child process (the binding can crash its process: :mod:`mocapviz.io.fbx`)."""
    script = (
        "import gc, json, sys; gc.disable(); import ufbx\n"
        "s = ufbx.load_file(sys.argv[1], ignore_geometry=True); frames = None\n"
        "for i in range(len(s.anim_curves)):\n"
        "    ks = s.anim_curves[i].keyframes\n"
        "    if len({ks[k].value for k in range(len(ks))}) < 2: continue\n"
        "    mine = {round(ks[k].time * 120) for k in range(len(ks))}\n"
        "    frames = mine if frames is None else frames & mine\n"
        "print(json.dumps(sorted(frames)), flush=True)\n"
        "import os; os._exit(0)\n"  # the binding's objects crash the interpreter's teardown
    )
    run = subprocess.run([sys.executable, "-c", script, str(path)], check=False, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    return np.array(json.loads(run.stdout))


def test_cmu_fbx_maps_to_canonical_like_its_bvh(cmu_pair):
    fbx, bvh, _ = cmu_pair
    a, b = fbx.canonical(), bvh.canonical()
    assert a.joint_names == b.joint_names
    error = np.linalg.norm(a.positions[1:].astype(np.float64) - b.positions[1:], axis=2) / CMU_UNIT_CM
    assert error.max() < 0.11  # the same joints (the fingers' ends are the only ones named apart), as above


def test_file_unit_turns_into_centimetres(peer, cmu_pair):
    fbx, _, _ = cmu_pair
    native = load(peer / "fbx/isaac_01_01_cmu.fbx")  # the file's own unit: centimetres
    np.testing.assert_allclose(native.positions, fbx.positions * BVH_UNIT_CM / CMU_UNIT_CM, rtol=1e-5, atol=1e-3)


@pytest.mark.parametrize("name", ["ufbx_maya_game_sausage_7500_binary_wiggle.fbx", "assimp_animation_with_skeleton.fbx"])
def test_keyframed_armatures_load_but_do_not_map_to_canonical(peer, name):
    m = load(peer / "fbx" / name)
    with pytest.raises(SkeletonMappingError, match=r"cannot map canonical joint\(s\) root, .*pass mapping="):
        m.canonical()


def test_ingest_of_a_folder_with_an_fbx_file(peer, tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    (folder / "cmu_01_01.fbx").write_bytes((peer / "fbx/isaac_01_01_cmu.fbx").read_bytes())
    db = MotionDB.ingest(folder, tmp_path / "db", fps=30, progress=False)
    docs = db.documents
    assert len(docs) == 1 and docs["path"].iloc[0].endswith("cmu_01_01.fbx")
    assert docs["name"].tolist() == ["cmu_01_01"] and docs["fbx_take"].tolist() == ["01_01|01_01"]  # its one take
    assert int(docs["n_frames"].iloc[0]) == 688  # 2,752 frames at 120 Hz resampled to 30 Hz (22.925 s)


# ------------------------------------------------------------------------------------------------------ damaged files
def _outcome(path):
    """A Motion with finite positions and unit quaternions, or a MocapFormatError naming the file: anything else
    fails the test (an exception of another type propagates)."""
    try:
        m = read_fbx(path)
    except MocapFormatError as exc:
        assert str(path) in str(exc)
        return "refused"
    assert np.isfinite(m.positions).all() and np.abs(m.positions).max() <= 1e7
    assert np.allclose(np.linalg.norm(m.quaternions, axis=-1), 1.0, atol=1e-3)
    assert 1 <= m.fps <= 10_000
    return "loaded"


def _mutate(data: bytes, draw) -> bytes:
    data = bytearray(data)
    if draw(st.booleans()):  # truncated
        return bytes(data[: draw(st.integers(0, len(data) - 1))])
    for _ in range(draw(st.integers(1, 3))):  # bit flips anywhere
        at = draw(st.integers(0, len(data) - 1))
        data[at] ^= 1 << draw(st.integers(0, 7))
    return bytes(data)


def _fuzz(peer, tmp_path, names, cases):
    @settings(max_examples=cases, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])  # fmt: skip
    @given(st.data())
    def case(data):
        name = data.draw(st.sampled_from(names))
        path = tmp_path / f"damaged_{name}"
        path.write_bytes(_mutate((peer / "fbx" / name).read_bytes(), data.draw))
        _outcome(path)

    case()


def test_damaged_small_fbx_files_load_or_are_refused(peer, tmp_path):
    _fuzz(peer, tmp_path, SAUSAGE, 25)


@pytest.mark.slow
def test_damaged_fbx_files_load_or_are_refused_long(peer, tmp_path):
    """Every file, the 1.7 MB CMU take included: 150 cases, 47 s in the last clean-clone make test."""
    _fuzz(peer, tmp_path, sorted(EXPECTED), 150)


def test_not_an_fbx_file_is_refused(tmp_path):
    path = tmp_path / "empty.fbx"
    path.write_bytes(b"")
    with pytest.raises(MocapFormatError, match="empty.fbx"):
        load(path)
    path.write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00" + bytes(100))
    with pytest.raises(MocapFormatError, match="empty.fbx"):
        load(path)



def test_ingest_reads_the_take_asked_for(peer, tmp_path, capsys):
    """``mocapviz ingest --take NAME`` reads that take of each FBX file (the CMU file's only take is "01_01|01_01");
    a take a file does not have is refused, naming the file and its takes, and no database is made."""
    from mocapviz.cli import main

    folder = tmp_path / "takes"
    folder.mkdir()
    (folder / "cmu_01_01.fbx").write_bytes((peer / "fbx/isaac_01_01_cmu.fbx").read_bytes())
    assert main(["ingest", str(folder), "--out", str(tmp_path / "bad"), "--take", "walk", "--fps", "30",
                 "--no-cluster", "--quiet"]) != 0
    said = capsys.readouterr().err
    assert "cmu_01_01.fbx" in said and "no take 'walk'" in said and "'01_01|01_01'" in said
    assert not (tmp_path / "bad").exists() or not any((tmp_path / "bad").iterdir())
    assert main(["ingest", str(folder), "--out", str(tmp_path / "db"), "--take", "01_01|01_01", "--fps", "30",
                 "--no-cluster", "--quiet"]) == 0
    assert MotionDB.open(tmp_path / "db").documents["n_frames"].tolist() == [688]
