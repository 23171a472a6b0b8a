"""The canonical skeleton: 24 named joints, mapping of reader skeletons onto them, body frame, body sizes.

CANONICAL_JOINTS      the 24 joint names, in the fixed order of RELATIONAL_FEATURES.md §1.2.
CANONICAL_PARENTS     their tree (parent index, -1 for the root).
ASF_MAP               canonical joint -> (ASF node whose tip it is, ASF node whose rotation acts there).
guess_mapping         canonical joint -> source joint, for ASF skeletons and BVH rigs.
name_mapping          canonical joint -> joint name by the BVH name rules alone.
to_canonical          a Motion on the canonical joints.
body_frame            positions with the root at the origin, facing +z (Krüger et al. 2010 §3.2).
mirror                the left/right mirror image of a canonical clip.
body_sizes            humerus, femur, hip/shoulder width, chest and body length (Müller toolbox, §1.3 of the
                      feature spec), from the first frame; body_size_table: the same of many frames.
"""
from __future__ import annotations

import functools
import re
from dataclasses import replace

import numpy as np
import pandas as pd

from .errors import SkeletonMappingError
from .motion import Motion

CANONICAL_JOINTS = (
    "root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes",
    "belly", "chest", "neck", "head", "headtop",
    "lclavicle", "lshoulder", "lelbow", "lwrist", "lfingers",
    "rclavicle", "rshoulder", "relbow", "rwrist", "rfingers",
)  # fmt: skip
_PARENT_NAMES = {
    "lhip": "root", "lknee": "lhip", "lankle": "lknee", "ltoes": "lankle",
    "rhip": "root", "rknee": "rhip", "rankle": "rknee", "rtoes": "rankle",
    "belly": "root", "chest": "belly", "neck": "chest", "head": "neck", "headtop": "head",
    "lclavicle": "neck", "lshoulder": "lclavicle", "lelbow": "lshoulder", "lwrist": "lelbow", "lfingers": "lwrist",
    "rclavicle": "neck", "rshoulder": "rclavicle", "relbow": "rshoulder", "rwrist": "relbow", "rfingers": "rwrist",
}  # fmt: skip
CANONICAL_PARENTS = np.array([-1] + [CANONICAL_JOINTS.index(_PARENT_NAMES[j]) for j in CANONICAL_JOINTS[1:]])

# RELATIONAL_FEATURES.md §1.2: a canonical joint is the distal end (tip) of an ASF node; the rotation that
# acts there is that of the ASF bone starting at it (None: no bone starts there).
ASF_MAP = {
    "root": ("root", "root"),
    "lhip": ("lhipjoint", "lfemur"), "lknee": ("lfemur", "ltibia"), "lankle": ("ltibia", "lfoot"),
    "ltoes": ("ltoes", None),
    "rhip": ("rhipjoint", "rfemur"), "rknee": ("rfemur", "rtibia"), "rankle": ("rtibia", "rfoot"),
    "rtoes": ("rtoes", None),
    "belly": ("lowerback", "upperback"), "chest": ("upperback", "thorax"), "neck": ("thorax", "lowerneck"),
    "head": ("upperneck", "head"), "headtop": ("head", None),
    "lclavicle": ("thorax", "lclavicle"), "lshoulder": ("lclavicle", "lhumerus"),
    "lelbow": ("lhumerus", "lradius"), "lwrist": ("lwrist", "lhand"), "lfingers": ("lfingers", None),
    "rclavicle": ("thorax", "rclavicle"), "rshoulder": ("rclavicle", "rhumerus"),
    "relbow": ("rhumerus", "rradius"), "rwrist": ("rwrist", "rhand"), "rfingers": ("rfingers", None),
}  # fmt: skip

# BVH name rules: after the side (left/right) is split off, the rest of a joint name must equal one of
# these (lower case, separators removed); the first listed name found wins.
_SIDED_PARTS = {
    "hip": ("upleg", "upperleg", "thigh", "femur", "hip"),
    "knee": ("leg", "lowerleg", "lowleg", "knee", "shin", "calf", "tibia"),
    "ankle": ("foot", "ankle"),
    "toes": ("toebase", "toe", "toes", "ball"),
    "clavicle": ("shoulder", "clavicle", "collar"),
    "shoulder": ("arm", "upperarm", "uparm", "humerus"),
    "elbow": ("forearm", "lowerarm", "lowarm", "elbow", "radius"),
    "wrist": ("hand", "wrist"),
}
_CENTRE_PARTS = {
    "root": ("hips", "pelvis", "hip", "root"),
    "belly": ("spine", "abdomen", "spine0", "lowerspine"),
    "chest": ("chest", "upperchest", "spine2", "spine1", "thorax"),
    "neck": ("neck", "neck1", "lowerneck"),
    "head": ("head",),
}
_KNOWN_PARTS = {p for parts in _SIDED_PARTS.values() for p in parts} | {"hipjoint", "thumb", "fingerbase"}
_PREFIX = re.compile(r"^(.*:|mixamorig_?|joint_|bip0*1[ _]|def-|j_)", re.IGNORECASE)
_DEGENERATE_CM = 0.5  # an end site closer than this to its joint carries no information


def _side_and_part(name: str) -> tuple[str, str]:
    """('l' | 'r' | '', normalised part) of a joint name: 'LeftUpLeg' -> ('l', 'upleg')."""
    tokens = [t for t in re.split(r"[\s_.\-]+", _PREFIX.sub("", name).lower()) if t]
    if not tokens:
        return "", ""
    for side, words in (("l", ("l", "left")), ("r", ("r", "right"))):
        if tokens[0] in words and len(tokens) > 1:
            return side, "".join(tokens[1:])
        if tokens[-1] in words and len(tokens) > 1:
            return side, "".join(tokens[:-1])
    joined = "".join(tokens)
    for side, word in (("l", "left"), ("r", "right")):
        if joined.startswith(word) and len(joined) > len(word):
            return side, joined[len(word):]
    if joined[0] in "lr" and joined[1:] in _KNOWN_PARTS:
        return joined[0], joined[1:]
    return "", joined


def _is_asf(joint_names) -> bool:
    names = set(joint_names)
    return {"root", "lfemur", "ltibia", "rfemur", "rtibia", "lhumerus", "rhumerus"} <= names


def guess_mapping(motion: Motion, partial: bool = False) -> dict[str, str]:
    """Canonical joint -> joint of ``motion`` whose position it takes.

    ASF skeletons (CMU / HDM05 bone names) follow :data:`ASF_MAP`. Other rigs (BVH) are mapped by name: the
    side is read from ``Left``/``Right``/``L``/``R`` prefixes or suffixes, and the rest of the name is
    matched against synonyms (``UpLeg``/``UpperLeg``/``Thigh`` = hip, ``Leg``/``LowerLeg`` = knee, ...).
    Toes, head top and fingers take the end site or deepest joint below the toe, head and hand joints
    when it is not on top of them.

    Parameters
    ----------
    motion : Motion
    partial : bool
        Return what could be mapped instead of raising.

    Raises
    ------
    SkeletonMappingError
        Listing the canonical joints that could not be mapped and the joints the skeleton has.
    """
    names = motion.joint_names
    if _is_asf(names):
        found = {c: tip for c, (tip, _) in ASF_MAP.items() if tip in names}
    else:
        found = _guess_by_name(motion)
    missing = [c for c in CANONICAL_JOINTS if c not in found]
    if missing and not partial:
        raise SkeletonMappingError(
            f"{motion.source or 'motion'}: cannot map canonical joint(s) {', '.join(missing)} onto the "
            f"skeleton's joints ({', '.join(names)}); pass mapping={{canonical: joint}} for them"
        )
    return found


@functools.lru_cache(maxsize=256)
def name_mapping(names: tuple) -> dict[str, str]:
    """Canonical joint -> joint, by the name rules alone (cached: many files share a rig)."""
    by_key: dict[tuple[str, str], str] = {}
    for n in names:
        by_key.setdefault(_side_and_part(n), n)
    found: dict[str, str] = {}
    for canon, synonyms in _CENTRE_PARTS.items():
        for s in synonyms:
            joint = by_key.get(("", s))
            if joint is not None and joint not in found.values():
                found[canon] = joint
                break
    for side in "lr":
        for canon, synonyms in _SIDED_PARTS.items():
            for s in synonyms:
                if (side, s) in by_key:
                    found[side + canon] = by_key[(side, s)]
                    break
        # CMU-derived rigs keep the ASF wrist bone: Hand = its start, FingerBase = its tip, the ASF wrist
        if (side, "fingerbase") in by_key:
            found[side + "wrist"] = by_key[(side, "fingerbase")]
    return found


def _guess_by_name(motion: Motion) -> dict[str, str]:
    names = motion.joint_names
    parents = motion.parents
    found = dict(name_mapping(names))
    children = {i: [k for k in range(len(names)) if parents[k] == i] for i in range(len(names))}
    first = motion.positions[0]

    def tip_below(joint: str) -> str:
        """Deepest joint below ``joint`` along its first non-thumb child, if it is not on top of it."""
        j = k = names.index(joint)
        while children[k]:
            kids = [c for c in children[k] if "thumb" not in names[c].lower()] or children[k]
            k = kids[0]
        return names[k] if np.linalg.norm(first[k] - first[j]) >= _DEGENERATE_CM else joint

    for canon, base in (("ltoes", "ltoes"), ("rtoes", "rtoes"), ("headtop", "head"),
                        ("lfingers", "lwrist"), ("rfingers", "rwrist")):  # fmt: skip
        if base in found:
            found[canon] = tip_below(found[base])
    return found


def to_canonical(motion: Motion, mapping: dict[str, str] | None = None) -> Motion:
    """``motion`` on the 24 canonical joints, in the order of :data:`CANONICAL_JOINTS`.

    Parameters
    ----------
    motion : Motion
        Any reader's Motion (or an already canonical one, returned as is when ``mapping`` is None).
    mapping : dict, optional
        Canonical joint -> joint of ``motion``, overriding the automatic rules of :func:`guess_mapping`.

    Returns
    -------
    Motion
        positions (T, 24, 3); quaternions (T, 24, 4): the local rotation acting at each canonical joint in
        the source skeleton (ASF: the bone starting there, BVH: the joint itself), identity where none.

    Raises
    ------
    SkeletonMappingError
        Unknown joints in ``mapping``, or canonical joints that cannot be mapped.
    """
    if motion.joint_names == CANONICAL_JOINTS and not mapping:
        return motion
    mapping = dict(mapping or {})
    unknown = {c: j for c, j in mapping.items() if c not in CANONICAL_JOINTS or j not in motion.joint_names}
    if unknown:
        raise SkeletonMappingError(
            f"{motion.source or 'motion'}: mapping entries {unknown} name unknown joints; canonical joints are "
            f"{', '.join(CANONICAL_JOINTS)}; the skeleton has {', '.join(motion.joint_names)}"
        )
    found = guess_mapping(motion, partial=True)
    found.update(mapping)
    missing = [c for c in CANONICAL_JOINTS if c not in found]
    if missing:
        guess_mapping(motion)  # raises with the full message
    names = motion.joint_names
    index = np.array([names.index(found[c]) for c in CANONICAL_JOINTS])
    quat = None
    if motion.quaternions is not None:
        asf = _is_asf(names)
        rot_joint = [
            (ASF_MAP[c][1] if asf and c not in mapping else found[c]) for c in CANONICAL_JOINTS
        ]
        idx = np.array([names.index(r) if r in names and not r.endswith("_end") else -1 for r in rot_joint])
        quat = np.zeros((motion.n_frames, len(CANONICAL_JOINTS), 4), dtype=np.float32)
        quat[..., 0] = 1.0
        has = idx >= 0
        quat[:, has] = motion.quaternions[:, idx[has]]
    return replace(
        motion,
        positions=motion.positions[:, index],
        joint_names=CANONICAL_JOINTS,
        parents=CANONICAL_PARENTS,
        quaternions=quat,
    )


def _index(name: str) -> int:
    return CANONICAL_JOINTS.index(name)


def heading(positions: np.ndarray) -> np.ndarray:
    """Facing direction of a canonical pose sequence as an angle about the vertical axis.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)], canonical joints, y up

    Returns
    -------
    np.ndarray [shape=(T,)], radians: 0 when the body faces +z, pi/2 when it faces +x. The forward
    direction is the horizontal hip line (left hip minus right hip) crossed with the up axis.
    """
    across = positions[:, _index("lhip")] - positions[:, _index("rhip")]
    # forward = across x up = (-across_z, 0, across_x)
    return np.arctan2(-across[:, 2], across[:, 0])


def body_frame(positions: np.ndarray) -> np.ndarray:
    """Poses in the body frame: root at the origin, rotated about y so that the body faces +z.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)], canonical joints, cm, y up

    Returns
    -------
    np.ndarray [shape=(T, 24, 3)], float32, cm. In this frame the left joints have x > 0.
    """
    positions = np.asarray(positions)
    centred = positions - positions[:, :1]
    theta = heading(positions)[:, None]
    c, s = np.cos(theta), np.sin(theta)
    x, z = centred[..., 0], centred[..., 2]
    # rotate by -theta about y
    out = np.stack([x * c - z * s, centred[..., 1], x * s + z * c], axis=-1)
    return out.astype(np.float32)


_SIZE_CHAINS = {
    "humerus_r": [("rshoulder", "relbow")],
    "humerus_l": [("lshoulder", "lelbow")],
    "femur_r": [("rhip", "rknee")],
    "femur_l": [("lhip", "lknee")],
    "hip_width": [("lhip", "rhip")],
    "shoulder_width": [("lshoulder", "rshoulder")],
    "chest_length": [("chest", "neck")],
    "body_length": [("rankle", "rknee"), ("rknee", "rhip"), ("root", "belly"), ("belly", "chest"), ("chest", "neck"),
                    ("neck", "head"), ("head", "headtop")],
}  # fmt: skip


def body_size_table(frames: np.ndarray) -> pd.DataFrame:
    """Body-size units of the relational features (feature spec §1.3) of each given frame.

    Parameters
    ----------
    frames : np.ndarray [shape=(D, 24, 3)], canonical joints, cm -- e.g. the first frame of each of D clips.

    Returns
    -------
    pandas.DataFrame [shape=(D, 8)], cm, the columns of :func:`body_sizes`.
    """
    p = np.asarray(frames, dtype=np.float64)
    length = lambda a, b: np.linalg.norm(p[:, _index(a)] - p[:, _index(b)], axis=-1)
    return pd.DataFrame({name: sum(length(a, b) for a, b in chain) for name, chain in _SIZE_CHAINS.items()})


def body_sizes(positions: np.ndarray) -> pd.Series:
    """Body-size units of the relational features, measured on the first frame (feature spec §1.3).

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)], canonical joints, cm

    Returns
    -------
    pandas.Series of float, cm: ``humerus_r``, ``humerus_l`` (shoulder-elbow), ``femur_r``, ``femur_l``
    (hip-knee), ``hip_width``, ``shoulder_width``, ``chest_length`` (chest-neck), ``body_length`` (rankle-rknee
    + rknee-rhip + root-belly + belly-chest + chest-neck + neck-head + head-headtop).
    """
    return body_size_table(np.asarray(positions)[:1]).iloc[0]


def mirror(motion: Motion) -> Motion:
    """The left/right mirror image of a canonical clip: x -> -x, and every l* joint swapped with its r* twin.

    Parameters
    ----------
    motion : Motion
        Canonical joints (any other skeleton is mapped first).

    Returns
    -------
    Motion
        Positions mirrored (T, 24, 3); quaternions mirrored too (the reflection x -> -x turns a rotation
        (w, x, y, z) into (w, x, -y, -z)) and swapped with the joints.
    """
    motion = to_canonical(motion)
    twin = {n: {"l": "r", "r": "l"}.get(n[0], "") + n[1:] for n in CANONICAL_JOINTS}
    swap = np.array([CANONICAL_JOINTS.index(twin[n] if twin[n] in CANONICAL_JOINTS else n) for n in CANONICAL_JOINTS])
    pos = motion.positions[:, swap] * np.array([-1.0, 1.0, 1.0], dtype=np.float32)
    quat = None
    if motion.quaternions is not None:
        quat = motion.quaternions[:, swap] * np.array([1.0, 1.0, -1.0, -1.0], dtype=np.float32)
    return replace(motion, positions=pos, quaternions=quat)
