"""The structural mapping of humanoid rigs (mocapviz.motion.skeleton.guess_mapping) on real clips rewritten to the naming
conventions users meet, and its refusals.

Each real clip (Bandai Namco BVH; HDM05 ASF/AMC written out as a CMU-derived BVH) is parsed into a small joint tree,
its joints renamed (Mixamo, Unreal mannequin, SMPL, OpenPose-like, 3ds Max Biped, Daz/Poser-friendly CMU, terse
abbreviations, numbered names without sides), its siblings reordered, extra joints added where the convention has
them (zero-offset twist/roll joints in the chains, Unreal's twist and IK leaves, Mixamo's fingers, a toe joint
turned into an End Site) and written to a BVH file. Read back and mapped without help, every canonical joint must
sit where the original rig has it, in every frame.
"""

from __future__ import annotations

import ast
import copy
import dataclasses
import re
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from mocapviz import Motion
from mocapviz.errors import SkeletonMappingError
from mocapviz.io import load
from mocapviz.motion.skeleton import CANONICAL_JOINTS, guess_mapping, to_canonical

ROT = ["Zrotation", "Xrotation", "Yrotation"]


# ------------------------------------------------------------------------------------------- a small BVH model
@dataclasses.dataclass
class Joint:
    """A BVH joint (``name`` None: an End Site) with its channels' values over the frames, shape (T, C)."""

    name: str | None
    offset: np.ndarray
    channels: list
    values: np.ndarray
    children: list = dataclasses.field(default_factory=list)

    def walk(self):
        yield self
        for c in self.children:
            yield from c.walk()

    def find(self, name: str) -> Joint:
        return next(j for j in self.walk() if j.name == name)

    def parent_of(self, name: str) -> Joint:
        return next(j for j in self.walk() if any(c.name == name for c in j.children))


def parse_bvh(path: Path) -> tuple[Joint, str]:
    """The joint tree of a BVH file and its ``Frame Time`` text."""
    lines = Path(path).read_text().splitlines()
    stack: list[Joint] = []
    root = pending = None
    with_channels = []
    i = 0
    while lines[i].strip() != "MOTION":
        tok = lines[i].split()
        i += 1
        if not tok or tok[0] == "HIERARCHY":
            continue
        if tok[0] in ("ROOT", "JOINT"):
            pending = " ".join(tok[1:])
        elif tok[0] == "End":
            pending = None
        elif tok[0] == "{":
            joint = Joint(pending, np.zeros(3), [], None)
            if stack:
                stack[-1].children.append(joint)
            else:
                root = joint
            stack.append(joint)
        elif tok[0] == "}":
            stack.pop()
        elif tok[0] == "OFFSET":
            stack[-1].offset = np.array([float(v) for v in tok[1:4]])
        elif tok[0] == "CHANNELS":
            stack[-1].channels = tok[2:]
            with_channels.append(stack[-1])
    frame_time = lines[i + 2].split(":")[1].strip()
    data = np.array([[float(v) for v in line.split()] for line in lines[i + 3 :] if line.strip()])
    col = 0
    for joint in root.walk():
        n = len(joint.channels)
        joint.values = data[:, col : col + n]
        col += n
    assert col == data.shape[1]
    return root, frame_time


def write_bvh(root: Joint, frame_time: str, path: Path) -> Path:
    """Write the tree as a BVH file (channels' values in depth-first joint order)."""
    out = ["HIERARCHY"]
    order = []

    def emit(joint: Joint, depth: int):
        pad = "  " * depth
        off = " ".join(f"{v:.9g}" for v in joint.offset)
        if joint.name is None:
            out.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {off}", f"{pad}}}"])
            return
        out.extend([f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {joint.name}", f"{pad}{{", f"{pad}  OFFSET {off}"])
        if joint.channels:
            out.append(f"{pad}  CHANNELS {len(joint.channels)} {' '.join(joint.channels)}")
            order.append(joint)
        for c in joint.children:
            emit(c, depth + 1)
        out.append(f"{pad}}}")

    emit(root, 0)
    data = np.concatenate([j.values for j in order], axis=1)
    out += ["MOTION", f"Frames: {len(data)}", f"Frame Time: {frame_time}"]
    out += [" ".join(f"{v:.9g}" for v in row) for row in data]
    path.write_text("\n".join(out) + "\n")
    return path


def n_frames(root: Joint) -> int:
    return len(root.values)


def renamed(root: Joint, names: dict) -> Joint:
    """A copy with every joint renamed by ``names`` (which must name them all)."""
    tree = copy.deepcopy(root)
    for j in tree.walk():
        if j.name is not None:
            j.name = names[j.name]
    return tree


def reorder(root: Joint, key) -> Joint:
    """Siblings sorted by ``key(joint)`` everywhere (End Sites keep their place after the joints)."""
    for j in root.walk():
        j.children.sort(key=lambda c: (c.name is None, key(c) if c.name is not None else 0))
    return root


def insert_after(root: Joint, name: str, new: str) -> Joint:
    """A zero-offset, zero-rotation joint between ``name`` and its children: positions do not change."""
    joint = root.find(name)
    extra = Joint(new, np.zeros(3), list(ROT), np.zeros((n_frames(root), 3)), joint.children)
    joint.children = [extra]
    return root


def insert_before(root: Joint, name: str, new: str) -> Joint:
    """A zero-rotation joint at ``name``'s place between it and its parent (``name`` then sits on top of it, at
    offset zero): positions do not change, and ``name`` still carries the rotation."""
    joint, parent = root.find(name), root.parent_of(name)
    extra = Joint(new, joint.offset, list(ROT), np.zeros((n_frames(root), 3)), [joint])
    assert not any(c.startswith(("X", "Y", "Z")) and c.endswith("position") for c in joint.channels)
    joint.offset = np.zeros(3)
    parent.children[parent.children.index(joint)] = extra
    return root


def add_leaf(root: Joint, parent: str, name: str, offset, end=(0.0, 0.0, 0.0)) -> Joint:
    """A leaf joint (zero rotations) with an End Site under ``parent``: the other joints do not move."""
    leaf = Joint(name, np.asarray(offset, float), list(ROT), np.zeros((n_frames(root), 3)))
    leaf.children.append(Joint(None, np.asarray(end, float), [], None))
    root.find(parent).children.append(leaf)
    return root


def to_end_site(root: Joint, name: str) -> Joint:
    """Joint ``name`` (only End Sites below it) becomes an End Site of its parent at the same place."""
    joint = root.find(name)
    assert all(c.name is None for c in joint.children)
    offset = joint.offset.copy()
    for k, axis in enumerate("XYZ"):  # position channels replace the OFFSET; they must be constant then
        if f"{axis}position" in joint.channels:
            v = joint.values[:, joint.channels.index(f"{axis}position")]
            assert np.ptp(v) < 1e-9, name
            offset[k] = v[0]
    parent = root.parent_of(name)
    parent.children = [c for c in parent.children if c is not joint] + [Joint(None, offset, [], None)]
    return root


def sided(table: dict) -> dict:
    """Expand ``{S}`` (L/R), ``{Side}`` (Left/Right) and ``{s}`` (l/r) in the keys and values of a name table."""
    out = {}
    for key, value in table.items():
        for S, Side, s in (("L", "Left", "l"), ("R", "Right", "r")):
            out[key.format(S=S, Side=Side, s=s)] = None if value is None else value.format(S=S, Side=Side, s=s)
    return out


# -------------------------------------------------------------------------------------------------- source rigs
# HDM05 ASF bones -> the CMU-derived BVH rig (one BVH joint at the start of every ASF bone; root = Hips)
ASF_TO_CMU = sided({
    "{s}hipjoint": "{S}HipJoint", "{s}femur": "{Side}UpLeg", "{s}tibia": "{Side}Leg", "{s}foot": "{Side}Foot",
    "{s}toes": "{Side}ToeBase", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
    "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head", "{s}clavicle": "{Side}Shoulder",
    "{s}humerus": "{Side}Arm", "{s}radius": "{Side}ForeArm", "{s}wrist": "{Side}Hand", "{s}hand": "{Side}FingerBase",
    "{s}fingers": "{Side}HandIndex1", "{s}thumb": "{S}Thumb",
})  # fmt: skip


def asf_as_bvh_tree(amc: Path, asf: Path) -> tuple[Joint, str]:
    """A real ASF/AMC clip as a CMU-derived BVH tree: joint b at the start of ASF bone b, OFFSET the parent bone's
    vector, rotation the bone's local rotation (ZXY channels); leaves get an End Site at their bone's tip."""
    from scipy.spatial.transform import Rotation

    from mocapviz.io import read_amc, read_asf

    sk = read_asf(asf)
    m = read_amc(amc, sk)
    euler = Rotation.from_quat(m.quaternions.reshape(-1, 4).astype(np.float64), scalar_first=True).as_euler(
        "ZXY", degrees=True
    )
    euler = euler.reshape(m.n_frames, m.n_joints, 3)  # joint 0: root, joint b + 1: bone b
    root = Joint("Hips", np.zeros(3), ["Xposition", "Yposition", "Zposition", *ROT],
                 np.concatenate([m.positions[:, 0], euler[:, 0]], axis=1))  # fmt: skip
    joints = {-1: root}
    for b, bone in enumerate(sk.bone_names):  # parents come first
        parent = int(sk.parents[b])
        offset = sk.offsets[parent] if parent >= 0 else np.zeros(3)
        joints[b] = Joint(ASF_TO_CMU[bone], np.array(offset, float), list(ROT), euler[:, b + 1])
        joints[parent].children.append(joints[b])
    for b in range(len(sk.bone_names)):
        if not joints[b].children:
            joints[b].children.append(Joint(None, np.array(sk.offsets[b], float), [], None))
    return root, f"{1 / m.fps:.9f}"


# ------------------------------------------------------------------------------------------------- conventions
# Bandai Namco's joints -> each convention's names
BANDAI = ["joint_Root", "Hips", "Spine", "Chest", "Neck", "Head", "Shoulder_{S}", "UpperArm_{S}", "LowerArm_{S}",
          "Hand_{S}", "UpperLeg_{S}", "LowerLeg_{S}", "Foot_{S}", "Toes_{S}"]  # fmt: skip
BANDAI_CONVENTIONS = {
    "mixamo": ["Armature", "mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Neck", "mixamorig:Head",
               "mixamorig:{Side}Shoulder", "mixamorig:{Side}Arm", "mixamorig:{Side}ForeArm", "mixamorig:{Side}Hand",
               "mixamorig:{Side}UpLeg", "mixamorig:{Side}Leg", "mixamorig:{Side}Foot", "mixamorig:{Side}ToeBase"],
    "unreal": ["root", "pelvis", "spine_01", "spine_02", "neck_01", "head", "clavicle_{s}", "upperarm_{s}",
               "lowerarm_{s}", "hand_{s}", "thigh_{s}", "calf_{s}", "foot_{s}", "ball_{s}"],
    "smpl": ["root", "Pelvis", "Spine1", "Spine2", "Neck", "Head", "{S}_Collar", "{S}_Shoulder", "{S}_Elbow",
             "{S}_Wrist", "{S}_Hip", "{S}_Knee", "{S}_Ankle", "{S}_Foot"],
    "openpose": ["Base", "MidHip", "Waist", "Chest", "Neck", "Nose", "{S}Collar", "{S}Shoulder", "{S}Elbow", "{S}Wrist",
                 "{S}Hip", "{S}Knee", "{S}Ankle", "{S}Toe"],
}  # fmt: skip


def bandai_variant(tree: Joint, convention: str) -> Joint:
    if convention == "numbered":  # no sides in the names: Bone, Bone.001, ... over a shuffled tree
        rng = np.random.default_rng(7)
        tree = reorder(copy.deepcopy(tree), key=lambda c: rng.random())
        for side in "LR":  # unnamed zero-offset joints in the chains
            for j in ("UpperLeg", "LowerLeg", "UpperArm", "LowerArm"):
                insert_after(tree, f"{j}_{side}", f"{j}_{side}_extra")
        joints = [j for j in tree.walk() if j.name is not None]
        return renamed(tree, {j.name: "Bone" + (f".{k:03d}" if k else "") for k, j in enumerate(joints)})
    names = sided(dict(zip(BANDAI, BANDAI_CONVENTIONS[convention])))
    tree = renamed(tree, names)
    if convention == "mixamo":
        for j in tree.walk():
            j.children.reverse()
    elif convention == "unreal":  # its twist bones are leaves half way down the limb; IK bones under the root
        for s in "lr":
            for bone, child in (("upperarm", "lowerarm"), ("lowerarm", "hand"), ("thigh", "calf"), ("calf", "foot")):
                add_leaf(tree, f"{bone}_{s}", f"{bone}_twist_01_{s}", tree.find(f"{child}_{s}").offset / 2)
        add_leaf(tree, "root", "ik_foot_root", [0, 0, 0])
        add_leaf(tree, "ik_foot_root", "ik_foot_l", [9, 8, 3])
        add_leaf(tree, "ik_foot_root", "ik_foot_r", [-9, 8, 3])
        add_leaf(tree, "root", "ik_hand_root", [0, 0, 0])
        add_leaf(tree, "ik_hand_root", "ik_hand_gun", [-25, 105, 30])
        add_leaf(tree, "ik_hand_gun", "ik_hand_r", [0, 0, 0])
        add_leaf(tree, "ik_hand_gun", "ik_hand_l", [45, 3, 0])
        reorder(tree, key=lambda c: c.name)
    elif convention == "openpose":
        to_end_site(tree, "LToe")  # no toe joints: the feet's End Sites are the toes
        to_end_site(tree, "RToe")
        reorder(tree, key=lambda c: c.name[::-1])
    return tree


# the CMU-derived rig's joints -> each convention's names (None: the joint becomes an End Site)
CMU = ["Hips", "{S}HipJoint", "{Side}UpLeg", "{Side}Leg", "{Side}Foot", "{Side}ToeBase", "LowerBack", "Spine",
       "Spine1", "Neck", "Neck1", "Head", "{Side}Shoulder", "{Side}Arm", "{Side}ForeArm", "{Side}Hand",
       "{Side}FingerBase", "{Side}HandIndex1", "{S}Thumb"]  # fmt: skip
CMU_CONVENTIONS = {
    # in the style of the CMU conversions for Daz/Poser: no toe joints, "Shldr", a forearm twist joint
    "daz": ["hip", "{s}Buttock", "{s}Thigh", "{s}Shin", "{s}Foot", None, "abdomen", "abdomen2", "chest", "neck",
            "neck2", "head", "{s}Collar", "{s}Shldr", "{s}ForeArm", "{s}ForearmTwist", "{s}Hand", "{s}Index1",
            "{s}Thumb1"],
    "mixamo": ["mixamorig:Hips", "mixamorig:{Side}HipJoint", "mixamorig:{Side}UpLeg", "mixamorig:{Side}Leg",
               "mixamorig:{Side}Foot", "mixamorig:{Side}ToeBase", "mixamorig:Spine", "mixamorig:Spine1",
               "mixamorig:Spine2", "mixamorig:Neck", "mixamorig:Neck1", "mixamorig:Head", "mixamorig:{Side}Shoulder",
               "mixamorig:{Side}Arm", "mixamorig:{Side}ForeArm", "mixamorig:{Side}ForeArmRoll",
               "mixamorig:{Side}Hand", "mixamorig:{Side}HandIndex1", "mixamorig:{Side}HandThumb1"],
    "biped": ["Bip01 Pelvis", "Bip01 {S} HipJoint", "Bip01 {S} Thigh", "Bip01 {S} Calf", "Bip01 {S} Foot",
              "Bip01 {S} Toe0", "Bip01 Spine", "Bip01 Spine1", "Bip01 Spine2", "Bip01 Neck", "Bip01 Neck1",
              "Bip01 Head", "Bip01 {S} Clavicle", "Bip01 {S} UpperArm", "Bip01 {S} Forearm", "Bip01 {S} ForeTwist",
              "Bip01 {S} Hand", "Bip01 {S} Finger1", "Bip01 {S} Finger0"],
    "terse": ["pv", "{s}hj", "{s}hp", "{s}kn", "{s}an", "{s}to", "ab0", "ab1", "chs", "nk0", "nk1", "hd", "{s}cl",
              "{s}sh", "{s}el", "{s}fa", "{s}wr", "{s}fi", "{s}th"],
}  # fmt: skip


def cmu_variant(tree: Joint, convention: str) -> Joint:
    names = sided(dict(zip(CMU, CMU_CONVENTIONS[convention])))
    tree = copy.deepcopy(tree)
    for old, new in names.items():
        if new is None:
            to_end_site(tree, old)
    tree = renamed(tree, {k: v for k, v in names.items() if v is not None})
    if convention == "mixamo":  # roll joints in the chains, and three more fingers, shorter than the index finger
        for side in ("Left", "Right"):
            for bone in ("UpLeg", "Leg", "Arm"):
                insert_after(tree, f"mixamorig:{side}{bone}", f"mixamorig:{side}{bone}Roll")
            hand = f"mixamorig:{side}Hand"
            base = tree.find(f"mixamorig:{side}HandIndex1").offset
            for k, finger in enumerate(("Middle", "Ring", "Pinky")):
                bend = np.array([0.0, -1.0 - k, 0.5 * k])
                add_leaf(tree, hand, f"mixamorig:{side}Hand{finger}1", 0.8 * base + bend, end=0.2 * base)
        reorder(tree, key=lambda c: c.name)
    elif convention == "biped":
        reorder(tree, key=lambda c: c.name)
    elif convention == "terse":  # and helper joints before the knees and elbows, which keep the rotation
        for s in "lr":
            insert_before(tree, f"{s}kn", f"{s}kx")
            insert_before(tree, f"{s}el", f"{s}ex")
        reorder(tree, key=lambda c: c.name[::-1])
    return tree


# ------------------------------------------------------------------------------------------------------- tests
def _clip(labels, actor, cls, k=0):
    return labels[(labels.actor == actor) & (labels["class"] == cls)].sort_values("file").file.iloc[k]


@pytest.fixture(scope="module")
def bandai_clips(bandai1_files):
    return [p for p in bandai1_files if "_walk_" in p.name][:1] + [p for p in bandai1_files if "_punch_" in p.name][:1]


@pytest.fixture(scope="module")
def hdm05_clips(hdm05_dir, hdm05_labels):
    """(AMC, ASF) of two actors: bd kicking, dg (the long forearms) throwing."""
    return [
        (hdm05_dir / _clip(hdm05_labels, actor, cls), hdm05_dir / "asf" / f"HDM_{actor}.asf")
        for actor, cls in (("bd", "kickLFront1Reps"), ("dg", "throwBasketball"))
    ]


@pytest.mark.parametrize("convention", [*BANDAI_CONVENTIONS, "numbered"])
def test_bandai_rig_renamed_maps_onto_the_same_positions(convention, bandai_clips, tmp_path):
    for path in bandai_clips:
        original = load(path)
        tree, frame_time = parse_bvh(path)
        out = write_bvh(bandai_variant(tree, convention), frame_time, tmp_path / f"{convention}-{path.name}")
        motion = load(out)
        assert set(motion.joint_names).isdisjoint({"Hips", "UpperLeg_L", "Hand_R"}), motion.joint_names
        got = motion.canonical()
        want = original.canonical()
        assert got.n_frames == original.n_frames
        for k, canon in enumerate(CANONICAL_JOINTS):
            np.testing.assert_allclose(
                got.positions[:, k], want.positions[:, k], atol=1e-3, err_msg=(convention, path.name, canon)
            )
        # the same joint's rotation acts at each, but where the toe joints became End Sites (identity there)
        same = [k for k, c in enumerate(CANONICAL_JOINTS) if convention != "openpose" or not c.endswith("toes")]
        dot = np.abs(np.sum(got.quaternions[:, same] * want.quaternions[:, same], axis=-1))
        np.testing.assert_allclose(dot, 1.0, atol=1e-5, err_msg=convention)


def test_smpl_names_that_mislead_the_name_table(bandai_clips, tmp_path):
    """SMPL's Shoulder is the glenohumeral joint and its Foot the toes, where the name table reads a clavicle and an
    ankle: the structure decides."""
    tree, frame_time = parse_bvh(bandai_clips[0])
    mapping = guess_mapping(load(write_bvh(bandai_variant(tree, "smpl"), frame_time, tmp_path / "smpl.bvh")))
    assert {c: mapping[c] for c in ("root", "lclavicle", "lshoulder", "lwrist", "lhip", "lankle", "ltoes")} == {
        "root": "Pelvis", "lclavicle": "L_Collar", "lshoulder": "L_Shoulder", "lwrist": "L_Wrist", "lhip": "L_Hip",
        "lankle": "L_Ankle", "ltoes": "L_Foot",
    }  # fmt: skip
    assert (mapping["rshoulder"], mapping["rtoes"], mapping["belly"], mapping["chest"]) == (
        "R_Shoulder", "R_Foot", "Spine1", "Spine2"
    )


@pytest.mark.parametrize("convention", list(CMU_CONVENTIONS))
def test_cmu_derived_rig_renamed_maps_onto_the_asf_positions(convention, hdm05_clips, tmp_path):
    """HDM05 clips written as CMU-derived BVH in other conventions: every canonical joint where the original ASF rig
    puts it (RELATIONAL_FEATURES.md §1.2), fingers included; without toe joints (Daz) the toes are the feet's
    End Sites, the ASF foot bones' tips."""
    for amc, asf in hdm05_clips:
        tree, frame_time = asf_as_bvh_tree(amc, asf)
        out = write_bvh(cmu_variant(tree, convention), frame_time, tmp_path / f"{convention}-{amc.stem}.bvh")
        got = load(out).canonical()
        original = load(amc)
        want = original.canonical().positions.copy()
        if convention == "daz":
            for side in "lr":
                want[:, CANONICAL_JOINTS.index(side + "toes")] = original.joint(side + "foot")
        assert got.n_frames == original.n_frames and got.fps == original.fps
        for k, canon in enumerate(CANONICAL_JOINTS):
            np.testing.assert_allclose(
                got.positions[:, k], want[:, k], atol=2e-3, err_msg=(convention, amc.name, canon)
            )
        # the rotation acting at each canonical joint is the same bone's (up to the quaternion's sign)
        dot = np.abs(np.sum(got.quaternions * original.canonical().quaternions, axis=-1))
        np.testing.assert_allclose(dot, 1.0, atol=1e-5, err_msg=(convention, amc.name))


def test_daz_names_failed_by_name_and_map_by_structure(hdm05_clips, tmp_path):
    """The CMU conversion for Daz/Poser (lShldr, no toe joints) that the name rules could not map (issue 18)."""
    tree, frame_time = asf_as_bvh_tree(*hdm05_clips[0])
    motion = load(write_bvh(cmu_variant(tree, "daz"), frame_time, tmp_path / "daz.bvh"))
    mapping = guess_mapping(motion)
    assert (mapping["lshoulder"], mapping["relbow"], mapping["lwrist"], mapping["lfingers"]) == (
        "lShldr", "rForeArm", "lHand", "lIndex1_end"
    )
    assert (mapping["ltoes"], mapping["rtoes"], mapping["neck"], mapping["headtop"]) == (
        "lFoot_end", "rFoot_end", "neck", "head_end"
    )


def test_names_do_not_matter_on_real_rigs(hdm05_dir, hdm05_labels, cmu_dir, bandai1_files, tmp_path):
    """With every joint renamed j0, j1, ... (no side, no role, no thumb in any name) the structure alone puts all 24
    canonical joints where the names did: ASF skeletons (as AMC motions), CMU-derived BVH, Bandai Namco BVH."""
    paths = [hdm05_dir / f for f in hdm05_labels.sort_values("file").file.iloc[::29]]
    paths += sorted((cmu_dir / "amc").glob("*/*.amc"))[::8] + bandai1_files[::25]
    amc, asf = hdm05_dir / _clip(hdm05_labels, "mm", "grabHighR"), hdm05_dir / "asf" / "HDM_mm.asf"
    tree, frame_time = asf_as_bvh_tree(amc, asf)
    paths.append(write_bvh(tree, frame_time, tmp_path / "cmu.bvh"))
    for path in paths:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # golf_01's truncated last frame
            motion = load(path)
        anonymous = dataclasses.replace(motion, joint_names=tuple(f"j{k}" for k in range(motion.n_joints)))
        got, want = anonymous.canonical(), motion.canonical()
        np.testing.assert_array_equal(got.positions, want.positions, err_msg=path.name)
        # and the same rotation acts at each (ASF: the bone starting at the point, BVH: the joint's own)
        np.testing.assert_array_equal(got.quaternions, want.quaternions, err_msg=path.name)


BANDAI_MAPPING = {
    "root": "Hips", "lhip": "UpperLeg_L", "lknee": "LowerLeg_L", "lankle": "Foot_L", "ltoes": "Toes_L",
    "rhip": "UpperLeg_R", "rknee": "LowerLeg_R", "rankle": "Foot_R", "rtoes": "Toes_R", "belly": "Spine",
    "chest": "Chest", "neck": "Neck", "head": "Head", "headtop": "Head", "lclavicle": "Shoulder_L",
    "lshoulder": "UpperArm_L", "lelbow": "LowerArm_L", "lwrist": "Hand_L", "lfingers": "Hand_L",
    "rclavicle": "Shoulder_R", "rshoulder": "UpperArm_R", "relbow": "LowerArm_R", "rwrist": "Hand_R",
    "rfingers": "Hand_R",
}  # fmt: skip
CMU_MAPPING = {
    "root": "Hips", "lhip": "LeftUpLeg", "lknee": "LeftLeg", "lankle": "LeftFoot", "ltoes": "LeftToeBase_end",
    "rhip": "RightUpLeg", "rknee": "RightLeg", "rankle": "RightFoot", "rtoes": "RightToeBase_end", "belly": "Spine",
    "chest": "Spine1", "neck": "Neck", "head": "Head", "headtop": "Head_end", "lclavicle": "LeftShoulder",
    "lshoulder": "LeftArm", "lelbow": "LeftForeArm", "lwrist": "LeftFingerBase", "lfingers": "LeftHandIndex1_end",
    "rclavicle": "RightShoulder", "rshoulder": "RightArm", "relbow": "RightForeArm", "rwrist": "RightFingerBase",
    "rfingers": "RightHandIndex1_end",
}  # fmt: skip


def _bandai_mapping(motion: Motion) -> dict:
    """BANDAI_MAPPING, with the End Site for toes, head top and fingers in the files where it is off its joint (11 of
    the 174 clips of dataset 1)."""
    out = dict(BANDAI_MAPPING)
    for canon in ("ltoes", "rtoes", "headtop", "lfingers", "rfingers"):
        end = out[canon] + "_end"
        if np.linalg.norm(motion.joint(end)[0] - motion.joint(out[canon])[0]) >= 0.5:
            out[canon] = end
    return out


def test_rigs_mapped_by_name_before_keep_their_mapping(bandai1_files, hdm05_dir, hdm05_labels, tmp_path):
    """The joints the name rules chose before the structural mapping (Bandai Namco, CMU-derived BVH)."""
    tips = 0
    for path in bandai1_files[::3]:
        motion = load(path)
        expected = _bandai_mapping(motion)
        assert guess_mapping(motion) == expected, path.name
        tips += expected["ltoes"] == "Toes_L_end"
    assert tips >= 2  # both kinds of files are among them
    for actor, cls in (("bd", "kickLFront1Reps"), ("dg", "squat1Reps"), ("tr", "grabHighR")):
        amc, asf = hdm05_dir / _clip(hdm05_labels, actor, cls), hdm05_dir / "asf" / f"HDM_{actor}.asf"
        tree, frame_time = asf_as_bvh_tree(amc, asf)
        assert guess_mapping(load(write_bvh(tree, frame_time, tmp_path / f"{actor}.bvh"))) == CMU_MAPPING, actor


# ---------------------------------------------------------------------------------------------------- refusals
def _template(exc: SkeletonMappingError) -> tuple[dict, dict]:
    """The error's mapping template as a dict, and each entry's candidates (from its comment)."""
    assert exc.template in str(exc)
    body = exc.template.split("=", 1)[1]
    template = ast.literal_eval(body)
    candidates = {}
    for line in exc.template.splitlines()[1:-1]:
        key = re.match(r'\s*"(\w+)"', line).group(1)
        comment = line.split("#", 1)[1].strip()
        candidates[key] = comment.removeprefix("candidates: ").split(", ") if comment.startswith("candidates") else []
    return template, candidates


def quadruped(frames: int = 40) -> Joint:
    """A four-legged rig with a tail, walking in place: spine along +z, legs down -y, paws pointing forward."""
    t = np.arange(frames) / 30.0

    def leg(name: str, offset, phase):
        swing = np.zeros((frames, 3))
        swing[:, 1] = 25 * np.sin(2 * np.pi * t + phase)  # Xrotation
        upper = Joint(f"{name}Upper", np.asarray(offset, float), list(ROT), swing)
        lower = Joint(f"{name}Lower", np.array([0.0, -22.0, 2.0]), list(ROT), np.zeros((frames, 3)))
        paw = Joint(f"{name}Paw", np.array([0.0, -20.0, -2.0]), list(ROT), np.zeros((frames, 3)))
        paw.children.append(Joint(None, np.array([0.0, -2.0, 7.0]), [], None))
        lower.children.append(paw)
        upper.children.append(lower)
        return upper

    root = Joint("Hips", np.zeros(3), ["Xposition", "Yposition", "Zposition", *ROT],
                 np.concatenate([np.stack([0 * t, 50 + 0 * t, 40 * t], 1), np.zeros((frames, 3))], axis=1))  # fmt: skip
    tail = Joint("Tail1", np.array([0.0, 3.0, -8.0]), list(ROT), np.zeros((frames, 3)))
    tail.children.append(Joint(None, np.array([0.0, -5.0, -30.0]), [], None))
    back = Joint("Back1", np.array([0.0, 3.0, 12.0]), list(ROT), np.zeros((frames, 3)))
    withers = Joint("Withers", np.array([0.0, 0.0, 40.0]), list(ROT), np.zeros((frames, 3)))
    neck = Joint("Neck", np.array([0.0, 5.0, 8.0]), list(ROT), np.zeros((frames, 3)))
    skull = Joint("Skull", np.array([0.0, 12.0, 12.0]), list(ROT), np.zeros((frames, 3)))
    skull.children.append(Joint(None, np.array([0.0, 0.0, 18.0]), [], None))
    neck.children.append(skull)
    withers.children += [leg("FrontLeg1", [7, -4, 3], 0.0), leg("FrontLeg2", [-7, -4, 3], np.pi), neck]
    back.children.append(withers)
    root.children += [leg("HindLeg1", [8, -3, -2], np.pi), leg("HindLeg2", [-8, -3, -2], 0.0), tail, back]
    return root


def test_quadruped_is_refused_with_a_template_that_maps_it(tmp_path):
    motion = load(write_bvh(quadruped(), "0.0333333", tmp_path / "dog.bvh"))
    with pytest.raises(SkeletonMappingError) as info:
        motion.canonical()
    exc = info.value
    assert "not a humanoid" in str(exc) and "legs never point away from the head" in str(exc)
    assert "lhip" in exc.missing and "lshoulder" in exc.missing
    template, candidates = _template(exc)
    assert list(template) == list(CANONICAL_JOINTS) and set(template.values()) == {"?"}
    # the structure found (hind legs, front legs, spine, head) is offered first
    first = {c: candidates[c][0] for c in template}
    assert first["root"] == "Hips" and {first["lhip"], first["rhip"]} == {"HindLeg1Upper", "HindLeg2Upper"}
    assert {first["lshoulder"], first["rshoulder"]} == {"FrontLeg1Upper", "FrontLeg2Upper"}
    assert (first["lankle"], first["ltoes"], first["headtop"]) == (
        first["lhip"].replace("Upper", "Paw"), first["lhip"].replace("Upper", "Paw_end"), "Skull_end"
    )
    # filled in from the candidates, the template is a mapping= that maps the rig
    c = motion.canonical(mapping=first)
    for k, canon in enumerate(CANONICAL_JOINTS):
        np.testing.assert_array_equal(c.positions[:, k], motion.joint(first[canon]))


def test_armless_rig_is_refused_naming_the_missing_arms(bandai_clips):
    """A real Bandai Namco clip with its arms cut off: legs and spine found, the arms reported missing."""
    motion = load(bandai_clips[0])
    arm = ("Shoulder", "UpperArm", "LowerArm", "Hand")
    keep = [k for k, n in enumerate(motion.joint_names) if n.split("_")[0] not in arm]
    new_index = {old: new for new, old in enumerate(keep)}
    armless = Motion(
        positions=motion.positions[:, keep], fps=motion.fps, joint_names=[motion.joint_names[k] for k in keep],
        parents=[new_index.get(int(motion.parents[k]), -1) for k in keep], source="armless.bvh",
    )  # fmt: skip
    with pytest.raises(SkeletonMappingError) as info:
        armless.canonical()
    exc = info.value
    assert "no spine" in str(exc) and "two arms" in str(exc)
    assert {"lshoulder", "relbow", "lwrist", "rfingers"} <= set(exc.missing)
    _, candidates = _template(exc)
    assert set(candidates["lhip"]) == {"UpperLeg_L", "UpperLeg_R"} and candidates["root"][0] == "Hips"
    # the user's mapping for what is missing completes the name rules' partial mapping
    arms = {f"{s}{r}": "Chest" for s in "lr" for r in ("clavicle", "shoulder", "elbow", "wrist", "fingers")}
    c = armless.canonical(mapping=arms)
    np.testing.assert_array_equal(c.joint("lankle"), motion.joint("Foot_L"))
    np.testing.assert_array_equal(c.joint("lwrist"), motion.joint("Chest"))


def _chain(n: int, source: str, wide: bool = False) -> Motion:
    """A rig of n + 1 joints: one chain (or, ``wide``, n leaves of the root), bones 1 cm along y, two frames."""
    parents = np.zeros(n + 1, dtype=np.int64) if wide else np.arange(-1, n)
    parents[0] = -1
    y = np.ones(n + 1) if wide else np.arange(n + 1, dtype=float)
    y[0] = 0
    pos = np.zeros((2, n + 1, 3), dtype=np.float32)
    pos[:, :, 1] = y
    pos[1, :, 0] = 0.1 * np.arange(n + 1)
    names = ["Hips"] + [f"j{k}" for k in range(n)]
    return Motion(positions=pos, fps=30, joint_names=names, parents=parents, source=source)


@pytest.mark.parametrize(
    "n, source, wide",
    [
        (20_000, "H1_wide20000.bvh", True),
        (20_000, "H1b_deep20000.bvh", False),
        (10_000, "H2_chain10000_rev.amc", False),
    ],
)
def test_huge_rigs_are_refused_in_linear_time(n, source, wide):
    """The size reproducers of issue 18 (20,000-joint wide and deep rigs took 39-45 CPU-s, a 10,000-bone ASF chain
    12 CPU-s before the error): refused at once, the message bounded."""
    motion = _chain(n, source, wide)
    start = time.process_time()
    with pytest.raises(SkeletonMappingError) as info:
        motion.canonical()
    assert time.process_time() - start < 2.0
    msg = str(info.value)
    assert "no pelvis" in msg or "no spine" in msg
    assert f"({n + 1} joints)" in msg and len(msg) < 5000
    template, _ = _template(info.value)
    assert set(template.values()) == {"?"}
    # a mapping for all 24 joints is taken as it is, without looking at the rig
    start = time.process_time()
    c = motion.canonical(mapping=dict.fromkeys(CANONICAL_JOINTS, "j5"))
    assert time.process_time() - start < 2.0
    np.testing.assert_array_equal(c.positions[:, 3], motion.positions[:, 6])


def test_parents_forming_a_cycle_are_a_typed_error():
    pos = np.zeros((1, 4, 3), dtype=np.float32)
    motion = Motion(positions=pos, fps=30, joint_names=["a", "b", "c", "d"], parents=[-1, 2, 3, 1])
    with pytest.raises(SkeletonMappingError, match="cycle"):
        to_canonical(motion)


@pytest.mark.slow
def test_bandai2_keeps_its_mapping(bandai2_dir):
    """All 2,902 clips of Bandai Namco 2 (same rig as dataset 1) keep the joints the name rules chose."""
    paths = sorted((bandai2_dir / "data").glob("*.bvh"))
    assert len(paths) > 2000
    for path in paths:
        motion = load(path)
        assert guess_mapping(motion) == _bandai_mapping(motion), path.name


# the joint names of other pipelines, on the cgspeed CMU rig of the peer file assimp_01_01.bvh (renamed copies of a
# real take: the names change, the motion does not): Mixamo's prefix, OptiTrack Motive's bone names with its asset
# prefix, Vicon Shogun's names (Spine1..3, Neck1)
_MOTIVE = {"Hips": "Hip", "LeftUpLeg": "LThigh", "RightUpLeg": "RThigh", "LeftLeg": "LShin", "RightLeg": "RShin",
           "LeftFoot": "LFoot", "RightFoot": "RFoot", "LeftToeBase": "LToe", "RightToeBase": "RToe", "LowerBack": "Ab",
           "Spine": "Chest", "LeftShoulder": "LShoulder", "RightShoulder": "RShoulder", "LeftArm": "LUArm",
           "RightArm": "RUArm", "LeftForeArm": "LFArm", "RightForeArm": "RFArm", "LeftHand": "LHand",
           "RightHand": "RHand"}  # fmt: skip
_SHOGUN = {"LowerBack": "Spine", "Spine": "Spine1", "Spine1": "Spine2", "LHipJoint": "LeftHipJoint",
           "RHipJoint": "RightHipJoint"}  # fmt: skip
RENAMED = {"mixamo": lambda n: f"mixamorig:{n}", "motive": lambda n: f"Skeleton_{_MOTIVE.get(n, n)}",
           "shogun": lambda n: _SHOGUN.get(n, n)}


@pytest.mark.parametrize("pipeline", sorted(RENAMED))
def test_other_pipelines_joint_names_map_like_the_original(fetch_archive, pipeline):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the file's unit (CMU's), said in a warning
        motion = load(fetch_archive("peer-readers") / "bvh" / "assimp_01_01.bvh")
    renamed = dataclasses.replace(motion, joint_names=tuple(map(RENAMED[pipeline], motion.joint_names)))
    assert set(renamed.joint_names).isdisjoint(motion.joint_names) or pipeline == "shogun"
    mapping = guess_mapping(renamed)
    assert {c: motion.joint_names[renamed.joint_names.index(j)] for c, j in mapping.items()} == guess_mapping(motion)
    np.testing.assert_array_equal(renamed.canonical().positions, motion.canonical().positions)
