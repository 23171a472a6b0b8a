"""Canonical joints, name mapping, body frame and body sizes (mocapviz.motion.skeleton) on real clips."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from mocapviz.errors import SkeletonMappingError
from mocapviz.io import load
from mocapviz.motion.skeleton import CANONICAL_JOINTS, body_frame, body_sizes, guess_mapping, heading, to_canonical

# RELATIONAL_FEATURES.md §1.2, typed from the table: canonical joint -> (ASF node whose tip it is,
# ASF node whose rotation acts there or None)
SPEC_TABLE = {
    "root": ("root", "root"),
    "lhip": ("lhipjoint", "lfemur"),
    "lknee": ("lfemur", "ltibia"),
    "lankle": ("ltibia", "lfoot"),
    "ltoes": ("ltoes", None),
    "rhip": ("rhipjoint", "rfemur"),
    "rknee": ("rfemur", "rtibia"),
    "rankle": ("rtibia", "rfoot"),
    "rtoes": ("rtoes", None),
    "belly": ("lowerback", "upperback"),
    "chest": ("upperback", "thorax"),
    "neck": ("thorax", "lowerneck"),
    "head": ("upperneck", "head"),
    "headtop": ("head", None),
    "lclavicle": ("thorax", "lclavicle"),
    "lshoulder": ("lclavicle", "lhumerus"),
    "lelbow": ("lhumerus", "lradius"),
    "lwrist": ("lwrist", "lhand"),
    "lfingers": ("lfingers", None),
    "rclavicle": ("thorax", "rclavicle"),
    "rshoulder": ("rclavicle", "rhumerus"),
    "relbow": ("rhumerus", "rradius"),
    "rwrist": ("rwrist", "rhand"),
    "rfingers": ("rfingers", None),
}
SIDE_JOINTS = ("hip", "shoulder", "knee", "ankle", "elbow")


def _idx(name: str) -> int:
    return CANONICAL_JOINTS.index(name)


def _clip(labels, actor, cls, k=0):
    rows = labels[(labels.actor == actor) & (labels["class"] == cls)].sort_values("file")
    return rows.file.iloc[k]


def test_canonical_joint_names_are_the_spec_table():
    assert CANONICAL_JOINTS == tuple(SPEC_TABLE)
    assert len(CANONICAL_JOINTS) == 24


def test_hdm05_canonical_takes_the_spec_tips(hdm05_dir, hdm05_labels):
    motion = load(hdm05_dir / _clip(hdm05_labels, "mm", "elbowToKnee1RepsLelbowStart"))
    c = motion.canonical()
    assert c.joint_names == CANONICAL_JOINTS
    assert c.n_frames == motion.n_frames and c.fps == motion.fps and c.source == motion.source
    np.testing.assert_array_equal(c.parents[1:] < np.arange(1, 24), True)
    for k, (canon, (tip, dof)) in enumerate(SPEC_TABLE.items()):
        np.testing.assert_array_equal(c.positions[:, k], motion.joint(tip), err_msg=canon)
        if dof is None:
            np.testing.assert_array_equal(c.quaternions[:, k], np.tile([1, 0, 0, 0], (c.n_frames, 1)), err_msg=canon)
        else:
            np.testing.assert_array_equal(c.quaternions[:, k], motion.quaternions[:, motion.joint_names.index(dof)])
    # same point, two names: the clavicles start at the neck
    np.testing.assert_array_equal(c.joint("lclavicle"), c.joint("neck"))
    np.testing.assert_array_equal(c.joint("rclavicle"), c.joint("neck"))
    assert c.canonical() is c


def test_bandai_mapping_by_name(bandai1_files):
    motion = load(bandai1_files[0])
    m = guess_mapping(motion)
    assert set(m) == set(CANONICAL_JOINTS)
    expected = {
        "root": "Hips", "belly": "Spine", "chest": "Chest", "neck": "Neck", "head": "Head",
        "lhip": "UpperLeg_L", "lknee": "LowerLeg_L", "lankle": "Foot_L", "lclavicle": "Shoulder_L",
        "lshoulder": "UpperArm_L", "lelbow": "LowerArm_L", "lwrist": "Hand_L",
        "rhip": "UpperLeg_R", "rknee": "LowerLeg_R", "rankle": "Foot_R", "rclavicle": "Shoulder_R",
        "rshoulder": "UpperArm_R", "relbow": "LowerArm_R", "rwrist": "Hand_R",
    }  # fmt: skip
    assert {k: m[k] for k in expected} == expected
    assert m["ltoes"] in ("Toes_L", "Toes_L_end") and m["rtoes"] in ("Toes_R", "Toes_R_end")
    c = motion.canonical()
    for canon, joint in m.items():
        np.testing.assert_array_equal(c.joint(canon), motion.joint(joint))
    # BVH: the rotation at a canonical joint is that joint's own local rotation
    np.testing.assert_array_equal(
        c.quaternions[:, _idx("lknee")], motion.quaternions[:, motion.joint_names.index("LowerLeg_L")]
    )


def test_cmu_and_bandai_map_all_24(cmu_dir, bandai1_files):
    paths = sorted((cmu_dir / "amc").glob("*/*.amc"))[::4] + bandai1_files[::20]
    for path in paths:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # golf_01's truncated last frame
            motion = load(path)
        assert set(guess_mapping(motion)) == set(CANONICAL_JOINTS), path.name
        assert motion.canonical().positions.shape == (motion.n_frames, 24, 3)


def _sides(motion) -> tuple[np.ndarray, np.ndarray]:
    """Mean body-frame x over frames of the left and the right joints of SIDE_JOINTS."""
    x = body_frame(motion.canonical().positions)[..., 0].mean(axis=0)
    return x[[_idx("l" + j) for j in SIDE_JOINTS]], x[[_idx("r" + j) for j in SIDE_JOINTS]]


def _check_sides(paths):
    wrong_joints = 0
    for path in paths:
        left, right = _sides(load(path))
        # the two sides as a whole, in every clip
        assert left.mean() > 0 > right.mean(), (path.name, left, right)
        # hips (the heading's own line) and elbows are never crossed over on average
        assert left[0] > 0 > right[0] and left[4] > 0 > right[4], (path.name, left, right)
        # joint by joint, but for the ankles: feet set close together (Bandai's standing clips) or crossing
        # (HDM05's jog in a circle) put an ankle on the other side, a crossed knee or a twisted shoulder
        # is rare
        no_ankle = [0, 1, 2, 4]
        wrong_joints += int((left[no_ankle] <= 0).sum() + (right[no_ankle] >= 0).sum())
    assert wrong_joints <= 0.01 * len(paths) * 2 * 4, wrong_joints


def test_left_is_plus_x_in_body_frame_bandai(bandai1_files):
    _check_sides(bandai1_files)


def test_left_is_plus_x_in_body_frame_hdm05(hdm05_dir, hdm05_labels):
    _check_sides([hdm05_dir / f for f in hdm05_labels.file])


def test_body_frame_root_origin_and_facing(hdm05_dir, hdm05_labels, bandai1_files, cmu_dir):
    walks = [hdm05_dir / _clip(hdm05_labels, a, "jogLeftCircle4StepsRstart") for a in ("bd", "bk", "dg", "mm", "tr")]
    walks += [p for p in bandai1_files if "_walk_" in p.name or "_walk-left_" in p.name]
    walks += [cmu_dir / "amc" / "mjackson" / "131_01.amc", cmu_dir / "amc" / "walk" / "walk_03.amc"]
    for path in walks:
        c = load(path).canonical()
        b = body_frame(c.positions)
        assert b.dtype == np.float32 and b.shape == c.positions.shape
        np.testing.assert_array_equal(b[:, 0], 0.0)
        # heights are kept
        np.testing.assert_allclose(b[..., 1], c.positions[..., 1] - c.positions[:, :1, 1], atol=1e-3)
        # distances from the root are kept (a rotation about y)
        np.testing.assert_allclose(
            np.linalg.norm(b, axis=-1), np.linalg.norm(c.positions - c.positions[:, :1], axis=-1), atol=1e-3
        )
        # the feet point forward: toes in front of the ankles along +z
        z = b[..., 2].mean(axis=0)
        assert z[_idx("ltoes")] > z[_idx("lankle")] + 2 and z[_idx("rtoes")] > z[_idx("rankle")] + 2, path.name
        np.testing.assert_allclose(np.sin(heading(b)), 0.0, atol=1e-4)
        np.testing.assert_allclose(np.cos(heading(b)), 1.0, atol=1e-4)


def test_body_frame_invariant_to_turn_and_shift(hdm05_dir, hdm05_labels):
    c = load(hdm05_dir / _clip(hdm05_labels, "bd", "throwBasketball")).canonical()
    p = c.positions.astype(np.float64)
    base_heading = heading(p)
    for a in (0.3, 2.0, -2.9):
        turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])  # +z towards +x
        moved = p @ turn.T + [120.0, 3.0, -45.0]
        np.testing.assert_allclose(body_frame(moved), body_frame(p), atol=2e-3)
        d = heading(moved) - base_heading - a
        np.testing.assert_allclose(np.angle(np.exp(1j * d)), 0.0, atol=1e-6)


def test_heading_of_a_synthetic_pose():
    pose = np.zeros((4, 24, 3))
    pose[:, _idx("lhip")] = [1.0, 0.0, 0.0]
    pose[:, _idx("rhip")] = [-1.0, 0.0, 0.0]
    # facing +z (left is +x)
    np.testing.assert_allclose(heading(pose), 0.0)
    # turned to face +x: left hip at -z
    turned = pose.copy()
    turned[:, _idx("lhip")] = [0.0, 0.0, -1.0]
    turned[:, _idx("rhip")] = [0.0, 0.0, 1.0]
    np.testing.assert_allclose(heading(turned), np.pi / 2)


def test_unmappable_skeleton_error_and_explicit_mapping(bandai1_files):
    motion = load(bandai1_files[3])
    # a joint the name rules do not know, or no names at all: the structure maps them as before
    renamed = dataclasses.replace(
        motion, joint_names=tuple("Knoechel_L" if n == "Foot_L" else n for n in motion.joint_names)
    )
    assert guess_mapping(renamed)["lankle"] == "Knoechel_L"
    np.testing.assert_array_equal(renamed.canonical().positions, motion.canonical().positions)
    fixed = renamed.canonical(mapping={"lankle": "Knoechel_L"})
    np.testing.assert_array_equal(fixed.positions, motion.canonical().positions)
    anonymous = dataclasses.replace(motion, joint_names=tuple(f"j{k}" for k in range(motion.n_joints)))
    np.testing.assert_array_equal(to_canonical(anonymous).positions, motion.canonical().positions)
    full = {canon: f"j{motion.joint_names.index(joint)}" for canon, joint in guess_mapping(motion).items()}
    np.testing.assert_array_equal(anonymous.canonical(mapping=full).positions, motion.canonical().positions)

    # nothing mappable at all (the joints strung into one chain, no names): every canonical joint listed
    chain = dataclasses.replace(anonymous, parents=np.arange(-1, motion.n_joints - 1))
    with pytest.raises(SkeletonMappingError) as info:
        to_canonical(chain)
    msg = str(info.value)
    assert isinstance(info.value, ValueError) and "no pelvis" in msg
    missing = msg.split("canonical joint(s)")[1].split("onto")[0]
    assert all(j in missing.replace(",", " ").split() for j in CANONICAL_JOINTS)
    assert info.value.missing == list(CANONICAL_JOINTS) and '"lankle": "?"' in info.value.template
    np.testing.assert_array_equal(chain.canonical(mapping=full).positions, motion.canonical().positions)
    # a mapping that names joints the skeleton does not have
    with pytest.raises(SkeletonMappingError, match="nowhere"):
        renamed.canonical(mapping={"lankle": "nowhere"})
    with pytest.raises(SkeletonMappingError):
        renamed.canonical(mapping={"ankle": "Knoechel_L"})


def test_asf_skeleton_with_renamed_bones(hdm05_dir, hdm05_labels):
    """Bone names the ASF table does not know: the structure puts every canonical joint at the table's bone tip."""
    for actor in ("tr", "dg"):
        motion = load(hdm05_dir / _clip(hdm05_labels, actor, "squat1Reps"))
        renamed = dataclasses.replace(motion, joint_names=tuple(n.upper() for n in motion.joint_names))
        assert guess_mapping(renamed) == {canon: tip.upper() for canon, (tip, _) in SPEC_TABLE.items()}
        np.testing.assert_array_equal(renamed.canonical().positions, motion.canonical().positions)
        # the rotation acting at each point: the bone starting there, as in the table
        np.testing.assert_array_equal(renamed.canonical().quaternions, motion.canonical().quaternions)
    mapping = {canon: tip.upper() for canon, (tip, _) in SPEC_TABLE.items()}
    np.testing.assert_array_equal(renamed.canonical(mapping=mapping).positions, motion.canonical().positions)


def test_body_sizes_hdm05(hdm05_dir, hdm05_labels):
    for actor in ("bd", "bk", "dg", "mm", "tr"):
        sizes = body_sizes(load(hdm05_dir / _clip(hdm05_labels, actor, "squat1Reps")).canonical().positions)
        assert 20 < sizes["humerus_l"] < 40 and 20 < sizes["humerus_r"] < 40, (actor, sizes)
        assert 35 < sizes["femur_l"] < 55 and 35 < sizes["femur_r"] < 55, (actor, sizes)
        assert 10 < sizes["hip_width"] < 30, (actor, sizes)
        # between the clavicle tips; actor bk's ASF clavicles measure 51 cm together
        assert 25 < sizes["shoulder_width"] < 55, (actor, sizes)
        assert 100 < sizes["body_length"] < 200, (actor, sizes)


def test_body_sizes_by_hand(hdm05_dir, hdm05_labels):
    c = load(hdm05_dir / _clip(hdm05_labels, "dg", "grabHighR")).canonical()
    sizes = body_sizes(c.positions)
    p = c.positions[0].astype(np.float64)

    def d(a, b):
        return np.linalg.norm(p[_idx(a)] - p[_idx(b)])

    expected = {
        "humerus_r": d("rshoulder", "relbow"),
        "humerus_l": d("lshoulder", "lelbow"),
        "femur_r": d("rhip", "rknee"),
        "femur_l": d("lhip", "lknee"),
        "hip_width": d("lhip", "rhip"),
        "shoulder_width": d("lshoulder", "rshoulder"),
        "chest_length": d("chest", "neck"),
        "body_length": d("rankle", "rknee")
        + d("rknee", "rhip")
        + d("root", "belly")
        + d("belly", "chest")
        + d("chest", "neck")
        + d("neck", "head")
        + d("head", "headtop"),
    }
    assert set(sizes.index) == set(expected)
    for k, v in expected.items():
        assert sizes[k] == pytest.approx(v, abs=1e-4), k
    # first frame only: later frames do not change the result
    assert body_sizes(np.concatenate([c.positions[:1], c.positions[::-1]])).equals(sizes)
    # humerus: the ASF bone length (a rigid bone), whatever the pose
    later = body_sizes(c.positions[len(c.positions) // 2 :])
    assert later["humerus_l"] == pytest.approx(sizes["humerus_l"], abs=1e-3)


# CMU-derived BVH naming (the conversions of the CMU database to BVH): one BVH joint at the start of every
# ASF bone; the ASF root is "Hips".
CMU_BVH_NAMES = {
    "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot", "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg", "rfoot": "RightFoot",
    "rtoes": "RightToeBase", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
    "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head", "lclavicle": "LeftShoulder", "lhumerus": "LeftArm",
    "lradius": "LeftForeArm", "lwrist": "LeftHand", "lhand": "LeftFingerBase", "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb", "rclavicle": "RightShoulder", "rhumerus": "RightArm", "rradius": "RightForeArm",
    "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1", "rthumb": "RThumb",
}  # fmt: skip


def _asf_as_cmu_bvh(amc, asf) -> str:
    """A real ASF/AMC clip rewritten as a CMU-derived BVH: same motion, BVH conventions, ZXY channels.

    BVH joint b sits at the start of ASF bone b, its OFFSET is the parent bone's vector, its rotation the
    bone's local rotation C M C^-1; leaves get an End Site at their own bone's tip.
    """
    from scipy.spatial.transform import Rotation

    from mocapviz.io import read_amc, read_asf

    sk = read_asf(asf)
    m = read_amc(amc, sk)
    q = m.quaternions.astype(np.float64)  # joint 0 = root, joint b + 1 = bone b
    # BVH "Zrotation Xrotation Yrotation" = R = Rz Rx Ry = intrinsic ZXY
    euler = Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_euler("ZXY", degrees=True)
    euler = euler.reshape(m.n_frames, m.n_joints, 3)
    children = {b: [c for c in range(len(sk.bone_names)) if sk.parents[c] == b] for b in range(-1, len(sk.bone_names))}
    out = ["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0 0 0",
           "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]  # fmt: skip
    order = []  # BVH joint order: bone indices, depth first

    def emit(b: int, offset, depth: int):
        pad = "  " * depth
        out.append(f"{pad}JOINT {CMU_BVH_NAMES[sk.bone_names[b]]}")
        out.append(pad + "{")
        out.append(f"{pad}  OFFSET {offset[0]:.9g} {offset[1]:.9g} {offset[2]:.9g}")
        out.append(f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation")
        order.append(b)
        for c in children[b]:
            emit(c, sk.offsets[b], depth + 1)
        if not children[b]:
            tip = sk.offsets[b]
            out.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {tip[0]:.9g} {tip[1]:.9g} {tip[2]:.9g}", pad + "  }"])
        out.append(pad + "}")

    for c in children[-1]:
        emit(c, np.zeros(3), 1)
    out += ["}", "MOTION", f"Frames: {m.n_frames}", "Frame Time: 0.00833333"]
    root = m.positions[:, 0]
    for f in range(m.n_frames):
        vals = list(root[f]) + list(euler[f, 0]) + [v for b in order for v in euler[f, b + 1]]
        out.append(" ".join(f"{v:.9g}" for v in vals))
    return "\n".join(out) + "\n"


def test_cmu_derived_bvh_maps_onto_the_asf_canonical_joints(hdm05_dir, hdm05_labels, tmp_path):
    """The BVH name rules put every canonical joint of a CMU-style rig exactly where the ASF table does."""
    amc = hdm05_dir / _clip(hdm05_labels, "bd", "kickLFront1Reps")
    bvh = tmp_path / "kick.bvh"
    bvh.write_text(_asf_as_cmu_bvh(amc, hdm05_dir / "asf" / "HDM_bd.asf"))
    from_bvh = load(bvh).canonical()
    from_asf = load(amc).canonical()
    assert from_bvh.fps == 120.0
    np.testing.assert_allclose(from_bvh.positions, from_asf.positions, atol=2e-3)
    # the rotation acting at each canonical joint is the same bone's in both (up to the quaternion sign)
    dot = np.abs(np.sum(from_bvh.quaternions * from_asf.quaternions, axis=-1))
    np.testing.assert_allclose(dot, 1.0, atol=1e-5)
    mapping = guess_mapping(load(bvh))
    assert mapping["lwrist"] == "LeftFingerBase" and mapping["chest"] == "Spine1" and mapping["ltoes"] == "LeftToeBase_end"


def test_mirror_swaps_sides_and_is_an_involution(hdm05_dir, hdm05_labels):
    from mocapviz.motion.skeleton import mirror

    kick = load(hdm05_dir / _clip(hdm05_labels, "bd", "kickLFront1Reps")).canonical()
    m = mirror(kick)
    assert m.joint_names == CANONICAL_JOINTS
    np.testing.assert_array_equal(mirror(m).positions, kick.positions)
    np.testing.assert_allclose(mirror(m).quaternions, kick.quaternions)
    # a left kick becomes a right kick: the mirrored right ankle rises as high as the original left one
    assert m.positions[:, _idx("rankle"), 1].max() == kick.positions[:, _idx("lankle"), 1].max()
    assert m.positions[:, _idx("lankle"), 1].max() < kick.positions[:, _idx("lankle"), 1].max() - 20
    # and the left side is still on +x in the body frame
    bf = body_frame(m.positions)
    assert bf[:, _idx("lhip"), 0].mean() > 0 > bf[:, _idx("rhip"), 0].mean()
    # the mirrored pose's joint angles equal the original's on the twin joints (bone lengths preserved)
    for a, b in (("lknee", "lankle"), ("lshoulder", "lelbow")):
        twin = lambda n: "r" + n[1:]
        d0 = np.linalg.norm(kick.positions[:, _idx(a)] - kick.positions[:, _idx(b)], axis=1)
        d1 = np.linalg.norm(m.positions[:, _idx(twin(a))] - m.positions[:, _idx(twin(b))], axis=1)
        np.testing.assert_allclose(d0, d1, rtol=1e-6)
