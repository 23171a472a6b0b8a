"""The canonical skeleton: 24 named joints, mapping of reader skeletons onto them, body frame, body sizes.

CANONICAL_JOINTS      the 24 joint names, in the fixed order of RELATIONAL_FEATURES.md §1.2 (from joints.py).
CANONICAL_PARENTS     their tree (parent index, -1 for the root; from joints.py).
ASF_MAP               canonical joint -> (ASF node whose tip it is, ASF node whose rotation acts there).
guess_mapping         canonical joint -> source joint, for ASF skeletons and any humanoid rig: the chains are
                      found from the hierarchy and the clip's geometry, names only break near ties.
name_mapping          canonical joint -> joint name by the BVH name rules alone.
to_canonical          a Motion on the canonical joints.
body_frame            positions with the root at the origin, facing +z (Krüger et al. 2010 §3.2).
mirror                the left/right mirror image of a canonical clip.
body_sizes            humerus, femur, hip/shoulder width, chest and body length (Müller toolbox, §1.3 of the
                      feature spec), from the first frame; body_size_table: the same of many frames.
"""
from __future__ import annotations

import functools
import itertools
import re
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import SkeletonMappingError
from .joints import CANONICAL_JOINTS, CANONICAL_PARENTS
from .markers import is_marker_motion, marker_joints

if TYPE_CHECKING:  # a type only: motion.py imports this module (Motion.canonical), never the other way
    from .motion import Motion


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
    "shoulder": ("arm", "upperarm", "uparm", "humerus", "shldr"),
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

    ASF skeletons with the CMU / HDM05 bone names follow :data:`ASF_MAP` (the feature spec's table). Any other
    rig is mapped by its structure, read from the hierarchy and the clip's positions (so a rig's own rest pose
    and its joint order do not matter):

    - the pelvis (canonical root) is the joint with three long branches, two legs and the spine; the spine
      is the branch that splits into two long branches (the arms) at the upper spine, and the head chain is
      the longest other branch there; each chain follows, at every joint, the child with the longest path
      below it (children named ``thumb`` last). Joints on top of their parent (zero-length bones, end sites
      at the joint) and joints named twist/roll lying on their bone are not points of their own (of joints on
      top of each other, the one that rotates most stands for the point);
    - leg: the hip starts the first bone at least half as long as the leg's longest, then knee and ankle;
      the toes are the last point of the chain (a toe joint's end site, a toe joint, the foot's end site);
    - arm: clavicle, shoulder, elbow and wrist are read off the chain as the reading whose upper arm is
      closest to 0.32 times the leg (thigh + shin) and whose forearm closest to 0.9 times the upper arm
      (a point in the middle of the forearm, as the CMU rigs' radius tip, is passed over when it lies on the
      forearm in every frame); the clavicle is the upper-spine joint itself when the chain starts at the
      shoulder; the fingers are the last point of the chain (the wrist itself when nothing is beyond it);
    - spine: the neck is the joint of the spine or head chain closest to the clavicles' inner ends, belly
      and chest the first and last points between the pelvis and the neck; the head is the head chain's
      joint named ``head`` (else its second-to-last point), the head top the last point;
    - sides from the names (two mirrored chains whose names differ by ``Left``/``Right``, ``L``/``R``,
      ``_l``/``_r``...), else from the geometry: left = up x forward, up from the pelvis to the neck,
      forward from ankle to toes and the knees' bend;
    - a rig whose legs point away from its head (pelvis-to-feet against pelvis-to-neck, cosine below -0.5) in
      less than a tenth of the frames (a quadruped) is not taken, unless its leg and arm joints have leg and
      arm names.

    Names are hints only (the arm's reading, the head, thumbs, twist joints, sides); the name rules of
    :func:`name_mapping` are used as they were when a rig has no such structure but names for all 24 joints.
    The rigs that mapped by name before (CMU-derived and Bandai Namco BVH) map to the same joints.

    Parameters
    ----------
    motion : Motion
        A clip on its source skeleton (its positions are read, cm).
    partial : bool
        Return what could be mapped instead of raising.

    Returns
    -------
    dict
        Canonical joint name -> joint name of ``motion``; all 24 unless ``partial``.

    Raises
    ------
    SkeletonMappingError
        Listing the canonical joints that could not be mapped, the structural role that is missing (pelvis,
        spine, legs, arms, head, sides) and a template for ``mapping=``: a dict literal of canonical joint ->
        "?" with the candidate joints found as comments. The error's ``missing`` (list of canonical joints)
        and ``template`` (str) attributes hold the same.

    Examples
    --------
    >>> from mocapviz import load
    >>> from mocapviz.io import datasets
    >>> m = load(datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc")
    >>> mapping = guess_mapping(m)
    >>> len(mapping), mapping["lknee"], mapping["head"]  # an ASF bone's tip is the joint below it
    (24, 'lfemur', 'upperneck')
    """
    found, reason, candidates = _guess(motion)
    missing = [c for c in CANONICAL_JOINTS if c not in found]
    if missing and not partial:
        raise _mapping_error(motion, missing, reason, candidates)
    return found


def _guess(motion: Motion) -> tuple[dict[str, str], str, dict[str, list]]:
    """(canonical joint -> joint found, why the others are missing, canonical joint -> candidate joints)."""
    names = motion.joint_names
    if _is_asf(names):
        found = {c: tip for c, (tip, _) in ASF_MAP.items() if tip in names}
        return found, "bones of the ASF table (RELATIONAL_FEATURES.md §1.2) are missing", {}
    rig = _Rig(motion)
    try:
        return _structural_mapping(rig), "", {}
    except _NotHumanoid as exc:
        by_name = _guess_by_name(rig)
        candidates = {c: exc.found.get(c, []) + ([by_name[c]] if c in by_name else []) for c in CANONICAL_JOINTS}
        return by_name, exc.missing, candidates


def _shown(names: tuple, at_most: int = 40) -> str:
    """The first ``at_most`` joint names, comma separated, and how many there are when that is not all."""
    return ", ".join(names[:at_most]) + (f", ... ({len(names)} joints)" if len(names) > at_most else "")


def _mapping_error(motion: Motion, missing: list, reason: str, candidates: dict) -> SkeletonMappingError:
    lines = ["mapping = {"]
    for c in CANONICAL_JOINTS:
        found = list(dict.fromkeys(candidates.get(c, [])))
        note = f"candidates: {', '.join(found[:5])}" if found else "no candidate found"
        lines.append(f'    "{c}": "?",  # {note}')
    template = "\n".join(lines + ["}"])
    why = f": {reason}" if reason else ""
    exc = SkeletonMappingError(
        f"{motion.source or 'motion'}: cannot map canonical joint(s) {', '.join(missing)} onto the skeleton's "
        f"joints ({_shown(motion.joint_names)}){why}; pass mapping={{canonical: joint}} for them, for example "
        f"this template with each '?' replaced by a joint name:\n{template}"
    )
    exc.missing = list(missing)
    exc.template = template
    return exc


@functools.lru_cache(maxsize=256)
def name_mapping(names: tuple) -> dict[str, str]:
    """Canonical joint -> joint, by the name rules alone (cached: many files share a rig).

    Parameters
    ----------
    names : tuple of str
        A rig's joint names.

    Returns
    -------
    dict
        Canonical joint name -> joint name, for the canonical joints whose names were found (may be fewer than
        24).
    """
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


def _guess_by_name(rig: _Rig) -> dict[str, str]:
    """The name rules (:func:`name_mapping`); toes, head top and fingers: the deepest joint below the toe, head
    and wrist joints along first non-thumb children, when it is not on top of them."""
    names = rig.names
    found = dict(name_mapping(names))
    index = {n: k for k, n in enumerate(names)}
    first = rig.pos[0]

    def tip_below(joint: str) -> str:
        j = k = index[joint]
        while rig.children[k]:
            kids = [c for c in rig.children[k] if "thumb" not in names[c].lower()] or rig.children[k]
            k = kids[0]
        return names[k] if np.linalg.norm(first[k] - first[j]) >= _DEGENERATE_CM else joint

    for canon, base in (("ltoes", "ltoes"), ("rtoes", "rtoes"), ("headtop", "head"),
                        ("lfingers", "lwrist"), ("rfingers", "rwrist")):  # fmt: skip
        if base in found:
            found[canon] = tip_below(found[base])
    return found


# ------------------------------------------------------------------------------------------ structural mapping
_TWIST = re.compile(r"twist|roll", re.IGNORECASE)
_LEFT_WORDS = {"l", "left", "lef", "lft", "lt"}  # "lef"/"righ": "Left..."/"Right..." share their "t..."
_RIGHT_WORDS = {"r", "right", "righ", "rgt", "rt"}
_SAMPLE_FRAMES = 64  # frames the geometry is measured on, spread over the clip (the first one included)
_HUB_CANDIDATES = 8  # joints tried as the pelvis, longest third branch first
_BRANCH = 0.3  # a branch counts when its path is at least this fraction of the longest one at its joint
_ARM_PER_LEG = 0.32  # upper arm / (thigh + shin): HDM05 0.34, CMU 0.35, Bandai Namco 0.30
_FOREARM_PER_ARM = 0.9  # forearm / upper arm: HDM05 0.93, Bandai Namco 0.92
_ON_BONE = 0.03  # a point is on a bone when off it by at most this fraction of the bone's length
_NAME_BONUS = 0.25  # what a fitting name adds to the score of a reading of an arm chain
_ROLL_BONUS = 0.15  # what passing over a forearm roll joint adds to it (HDM05 actor dg's long forearm needs it)
_ARM_ROLES = ("clavicle", "shoulder", "elbow", "wrist")
_LEG_NAMES = {p for r in ("hip", "knee", "ankle", "toes") for p in _SIDED_PARTS[r]}
_ARM_NAMES = {p for r in _ARM_ROLES for p in _SIDED_PARTS[r]}


class _NotHumanoid(Exception):
    """What the structural mapping could not find (internal): ``missing`` in words, ``found`` canonical joint ->
    candidate joint names (both sides while the sides are unknown); ``final``: legs, spine and arms were found
    (no other joint is tried as the pelvis)."""

    def __init__(self, missing: str, found: dict | None = None, final: bool = False):
        super().__init__(missing)
        self.missing = missing
        self.found = {c: list(v) for c, v in (found or {}).items()}
        self.final = final


class _Rig:
    """A skeleton's tree, bone lengths and longest branches, built in O(J) (J joints).

    Attributes
    ----------
    names : tuple of str [length J]
    hint : list of str [length J]
        The name that says what a point is: the joint's own, or for an AMC motion (whose points are bone tips)
        that of the bone starting there along :attr:`main`.
    children : list of list of int
    pos : np.ndarray [shape=(S, J, 3)], float64, cm -- S <= 64 frames spread over the clip, the first included.
    length : np.ndarray [shape=(J,)], cm -- median distance to the parent over those frames, 0 for roots.
    spin : np.ndarray [shape=(J,)] -- how much each joint rotates: mean of |(x, y, z)| (the sine of half the angle)
        of its local quaternion over those frames (0 without quaternions).
    weight : np.ndarray [shape=(J,)], cm -- length plus the longest path from the joint down to a leaf.
    main : list of int [length J]
        The child with the largest weight (children named thumb only when there is no other), -1 at leaves.
    """

    def __init__(self, motion: Motion):
        names = motion.joint_names
        n = len(names)
        parents = motion.parents
        where = motion.source or "motion"
        if n and (parents.min() < -1 or parents.max() >= n):
            raise SkeletonMappingError(f"{where}: joint parents out of range (-1 to {n - 1})")
        children: list[list[int]] = [[] for _ in range(n)]
        order = []
        for k, p in enumerate(parents.tolist()):
            (children[p] if p >= 0 else order).append(k)
        for k in order:  # breadth first from the roots: the list grows while it is walked
            order.extend(children[k])
        if len(order) != n:
            raise SkeletonMappingError(f"{where}: the joints' parents form a cycle")
        t = motion.n_frames
        frames = np.unique(np.linspace(0, t - 1, min(t, _SAMPLE_FRAMES)).round().astype(np.int64))
        self.pos = motion.positions[frames].astype(np.float64)
        quat = motion.quaternions
        self.spin = np.zeros(n)
        if quat is not None:
            self.spin = np.linalg.norm(quat[frames, :, 1:].astype(np.float64), axis=-1).mean(axis=0)
        length = np.median(np.linalg.norm(self.pos - self.pos[:, np.maximum(parents, 0)], axis=-1), axis=0)
        length[parents < 0] = 0.0
        thumb = ["thumb" in name.lower() for name in names]
        lengths = length.tolist()
        reach = [0.0] * n
        main = [-1] * n
        for j in reversed(order):
            best = None
            for c in children[j]:
                w = lengths[c] + reach[c]
                reach[j] = max(reach[j], w)
                if best is None or (not thumb[c], w) > best:
                    best, main[j] = (not thumb[c], w), c
        self.names = names
        self.children = children
        self.length = length
        self.weight = length + np.array(reach)
        self.main = main
        amc = str(motion.source or "").lower().endswith(".amc")
        self.hint = [names[main[k]] if main[k] >= 0 else "" for k in range(n)] if amc else list(names)

    def path(self, j: int, stop: int = -1) -> list[int]:
        """``j`` and its :attr:`main` descendants, down to a leaf or to ``stop``."""
        out = []
        while j >= 0:
            out.append(j)
            if j == stop:
                break
            j = self.main[j]
        return out

    def points(self, joints: list[int]) -> list[int]:
        """The joints of a chain (each the child of the one before) that are points of their own: without joints
        on top of their parent and joints named twist/roll lying on the bone between their neighbours. Of joints
        on top of each other, the one that rotates most stands for their point (the first on a tie)."""
        out = []
        for i, k in enumerate(joints):
            if self.length[k] < _DEGENERATE_CM:
                if out and out[-1] == joints[i - 1] and self.spin[k] > self.spin[out[-1]]:
                    out[-1] = k
                continue
            twist = out and i + 1 < len(joints) and _TWIST.search(self.names[k])
            if twist and np.median(self.off_bone(out[-1], k, joints[i + 1])) <= _ON_BONE:
                continue
            out.append(k)
        return out

    def dist(self, a: int, b: int) -> float:
        """Median distance between joints a and b, cm."""
        return float(np.median(np.linalg.norm(self.pos[:, a] - self.pos[:, b], axis=-1)))

    def off_bone(self, a: int, k: int, b: int) -> np.ndarray:
        """Distance of joint k from the segment a-b in each frame, relative to the segment's length, shape (S,)."""
        pa, ab = self.pos[:, a], self.pos[:, b] - self.pos[:, a]
        span = np.maximum(np.einsum("si,si->s", ab, ab), 1e-12)
        t = np.clip(np.einsum("si,si->s", self.pos[:, k] - pa, ab) / span, 0.0, 1.0)
        return np.linalg.norm(pa + t[:, None] * ab - self.pos[:, k], axis=-1) / np.sqrt(span)


def _pair_side(a: str, b: str) -> int:
    """+1 when names ``a`` and ``b`` differ only by a left (a) / right (b) word, -1 the other way round, else 0."""
    a, b = a.lower(), b.lower()
    i = 0
    while i < min(len(a), len(b)) and a[i] == b[i]:
        i += 1
    j = 0
    while j < min(len(a), len(b)) - i and a[-1 - j] == b[-1 - j]:
        j += 1
    core_a, core_b = a[i : len(a) - j], b[i : len(b) - j]
    if core_a in _LEFT_WORDS and core_b in _RIGHT_WORDS:
        return 1
    if core_a in _RIGHT_WORDS and core_b in _LEFT_WORDS:
        return -1
    return 0


def _structural_mapping(rig: _Rig) -> dict[str, str]:
    """Canonical joint -> joint name from the rig's structure (see :func:`guess_mapping`); raises _NotHumanoid."""
    hubs = []
    for j, kids in enumerate(rig.children):
        if len(kids) >= 3:
            w = sorted((rig.weight[c] for c in kids), reverse=True)
            if w[2] > 0 and w[2] >= _BRANCH * w[0]:
                hubs.append((-w[2], j))
    if not hubs:
        raise _NotHumanoid("no pelvis: no joint has three long branches (two legs and the spine)")
    failures = []
    for _, hub in sorted(hubs)[:_HUB_CANDIDATES]:
        try:
            return _fit(rig, hub)
        except _NotHumanoid as exc:
            if exc.final:
                raise
            failures.append(exc)
    raise max(failures, key=lambda e: len(e.found))  # the pelvis candidate that got furthest


def _fit(rig: _Rig, hub: int) -> dict[str, str]:
    """The humanoid with its pelvis at joint ``hub``, or _NotHumanoid saying what is missing."""
    names, w = rig.names, rig.weight
    found: dict[str, list] = {"root": [names[hub]]}
    kids = sorted(rig.children[hub], key=lambda c: -w[c])
    kids = [c for c in kids if w[c] >= _BRANCH * w[kids[0]]]
    theta = _BRANCH * w[kids[2]]
    fork = {}  # branch of the hub -> (first joint down its chain with two long branches, those branches)
    for c in kids:
        k = c
        while k >= 0:
            long = [g for g in rig.children[k] if w[g] >= theta]
            if len(long) >= 2:
                fork[c] = (k, sorted(long, key=lambda g: -w[g])[:8])
                break
            k = rig.main[k]
    spines = [c for c in kids if c in fork]
    spine = max(spines, key=lambda c: (len(fork[c][1]) >= 3, w[c])) if spines else None
    rest = [c for c in kids if c != spine][:4]
    if len(rest) < 2:
        raise _NotHumanoid(f"no legs: {names[hub]!r} has one long branch besides the spine", found)
    similar = lambda pair: (abs(np.log(w[pair[0]] / w[pair[1]])), -w[pair[0]] - w[pair[1]])
    legs = min(itertools.combinations(rest, 2), key=similar)
    try:
        leg_roles = [_leg_roles(rig, rig.points(rig.path(c)), found) for c in legs]
    except _NotHumanoid:
        if spine is not None:
            raise
        leg_roles = []
    for k, role in enumerate(("hip", "knee", "ankle", "toes")):
        found["l" + role] = found["r" + role] = [names[r[k]] for r in leg_roles]
    if spine is None:
        raise _NotHumanoid(f"no spine: no branch of {names[hub]!r} splits into two arms", found)
    upper, long = fork[spine]
    arms = min(itertools.combinations(long, 2), key=similar)
    leg = np.mean([rig.dist(r[0], r[1]) + rig.dist(r[1], r[2]) for r in leg_roles])
    arm_roles = [_arm_roles(rig, upper, rig.points(rig.path(c)), leg, found) for c in arms]
    for k, role in enumerate(_ARM_ROLES + ("fingers",)):
        found["l" + role] = found["r" + role] = [names[r[k]] for r in arm_roles]

    # spine and head: the points from the hub up to the upper spine, then the head chain
    head_kids = [g for g in rig.children[upper] if g not in arms]
    seq = [hub] + rig.points(rig.path(spine, stop=upper))
    at_upper = len(seq) - 1
    if head_kids:
        seq += rig.points(rig.path(max(head_kids, key=lambda g: w[g])))
    if len(seq) == at_upper + 1:
        raise _NotHumanoid(f"no head: nothing above {names[upper]!r} but the arms", found)
    named = [i for i in range(at_upper + 1, len(seq)) if _side_and_part(rig.hint[seq[i]]) == ("", "head")]
    head = named[0] if named else len(seq) - 2 if len(seq) - at_upper > 3 else len(seq) - 1
    inner_ends = (rig.pos[:, arm_roles[0][0]] + rig.pos[:, arm_roles[1][0]]) / 2
    gap = [np.median(np.linalg.norm(rig.pos[:, seq[i]] - inner_ends, axis=-1)) for i in range(at_upper, head)]
    neck = at_upper + int(np.argmin(gap)) if gap else at_upper
    inner = seq[1:neck] or [hub]
    roles = {"root": hub, "belly": inner[0], "chest": inner[-1], "neck": seq[neck], "head": seq[head],
             "headtop": seq[-1]}  # fmt: skip
    found.update({c: [names[k]] for c, k in roles.items()})

    # sides: names first, else up x forward
    pos = rig.pos
    up = pos[:, seq[neck]] - pos[:, hub]
    up /= np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-9)
    forward = np.zeros_like(up)
    for hip, knee, ankle, toes in leg_roles:
        forward += pos[:, toes] - pos[:, ankle] + pos[:, knee] - (pos[:, hip] + pos[:, ankle]) / 2
    forward -= np.einsum("si,si->s", forward, up)[:, None] * up
    left = np.cross(up, forward)  # y up, z forward: x, the body's left

    def left_first(chains, first_points) -> bool:
        vote = sum(_pair_side(names[a], names[b]) for a, b in zip(*(rig.path(c) for c in chains)))
        if vote:
            return vote > 0
        d = pos[:, first_points[0]] - pos[:, first_points[1]]
        # cosine between d and left, frames weighted by |left| (small where the trunk is bent along the feet)
        scale = np.sum(np.linalg.norm(d, axis=-1) * np.linalg.norm(left, axis=-1))
        cos = np.einsum("si,si->", d, left) / max(scale, 1e-9)
        if abs(cos) < 0.2:
            raise _NotHumanoid(
                "no sides: the names do not say left and right, and neither toes nor bent knees show which way "
                "the body faces",
                found,
                final=True,
            )
        return cos > 0

    if not left_first(legs, (leg_roles[0][0], leg_roles[1][0])):
        leg_roles.reverse()
    if not left_first(arms, (arm_roles[0][1], arm_roles[1][1])):
        arm_roles.reverse()
    for side, lr, ar in zip("lr", leg_roles, arm_roles):
        roles.update({side + role: k for role, k in zip(("hip", "knee", "ankle", "toes"), lr)})
        roles.update({side + role: k for role, k in zip(_ARM_ROLES + ("fingers",), ar)})
    found.update({c: [names[k]] for c, k in roles.items()})

    # a humanoid's legs point away from its head; a quadruped's hang across its spine
    feet = (pos[:, roles["lankle"]] + pos[:, roles["rankle"]]) / 2 - pos[:, hub]
    along = np.einsum("si,si->s", feet, up) / np.maximum(np.linalg.norm(feet, axis=-1), 1e-9)
    named_limbs = any(_side_and_part(rig.hint[k])[1] in _LEG_NAMES for k in leg_roles[0][:3]) and any(
        _side_and_part(rig.hint[k])[1] in _ARM_NAMES for k in arm_roles[0][1:4]
    )
    upright = np.quantile(along, 0.1)  # a tenth of the clip standing (or lying) straight is enough
    if upright > -0.5 and not named_limbs:
        raise _NotHumanoid(
            f"not a humanoid: the legs never point away from the head (cosine {upright:.2f} or more between "
            "pelvis-to-feet and pelvis-to-neck in 90 % of the frames; a quadruped?)",
            found,
            final=True,
        )
    return {c: names[roles[c]] for c in CANONICAL_JOINTS}


def _leg_roles(rig: _Rig, pts: list[int], found: dict) -> tuple[int, int, int, int]:
    """(hip, knee, ankle, toes) of a leg chain's points: the hip starts the first bone at least half as long as
    the longest; the toes are the last point (the ankle itself when nothing is beyond it)."""
    bones = [rig.dist(a, b) for a, b in itertools.pairwise(pts)]
    hip = next((i for i, b in enumerate(bones) if b >= 0.5 * max(bones)), 0) if bones else 0
    if hip + 2 >= len(pts):
        chain = ", ".join(rig.names[k] for k in pts) or "nothing"
        raise _NotHumanoid(f"no hip, knee and ankle in a leg chain ({chain})", found)
    return pts[hip], pts[hip + 1], pts[hip + 2], pts[-1]


def _arm_roles(rig: _Rig, upper: int, pts: list[int], leg: float, found: dict) -> tuple[int, ...]:
    """(clavicle, shoulder, elbow, wrist, fingers) of an arm chain's points below the upper-spine joint ``upper``:
    the reading whose bones have the most human proportions, names adding to it (see :func:`guess_mapping`)."""
    best = None
    for c in (-1, 0, 1):
        shoulder, elbow = c + 1, c + 2
        for wrist in (elbow + 1, elbow + 2):
            if wrist >= len(pts):
                continue
            roll = 0.0
            if wrist == elbow + 2:
                if rig.off_bone(pts[elbow], pts[elbow + 1], pts[wrist]).max() > _ON_BONE:
                    continue  # the point passed over is not on the forearm
                roll = _ROLL_BONUS  # on the forearm in every frame: likely a forearm roll joint
            roles = (upper if c < 0 else pts[c], pts[shoulder], pts[elbow], pts[wrist])
            arm = max(rig.dist(pts[shoulder], pts[elbow]), 1e-6)
            forearm = max(rig.dist(pts[elbow], pts[wrist]), 1e-6)
            score = roll - abs(np.log(arm / (_ARM_PER_LEG * leg))) - abs(np.log(forearm / (_FOREARM_PER_ARM * arm)))
            for role, k in zip(_ARM_ROLES, roles):
                part = _side_and_part(rig.hint[k])[1]
                if role == "wrist" and part == "fingerbase":  # the CMU-derived rigs' wrist (see name_mapping)
                    score += 2 * _NAME_BONUS
                elif part in _SIDED_PARTS[role]:
                    score += _NAME_BONUS
            if best is None or score > best[0]:
                best = (score, roles + (pts[-1],))
    if best is None:
        chain = ", ".join(rig.names[k] for k in pts) or "nothing"
        raise _NotHumanoid(f"no shoulder, elbow and wrist in an arm chain ({chain})", found)
    return best[1]


def to_canonical(motion: Motion, mapping: dict[str, str] | None = None) -> Motion:
    """``motion`` on the 24 canonical joints, in the order of :data:`CANONICAL_JOINTS`.

    Parameters
    ----------
    motion : Motion
        Any reader's Motion (or an already canonical one, returned as is when ``mapping`` is None). A marker
        Motion (a C3D file's) goes to :func:`mocapviz.motion.markers.marker_joints`, the joint-centre estimates.
    mapping : dict, optional
        Canonical joint -> joint of ``motion``, overriding the automatic rules of :func:`guess_mapping`; for a
        marker Motion: marker of the marker set -> the clip's marker name (``aliases`` of ``marker_joints``).

    Returns
    -------
    Motion
        positions (T, 24, 3); quaternions (T, 24, 4): the local rotation acting at each canonical joint in
        the source skeleton (ASF/AMC: the bone starting there towards the next canonical joint, by the ASF table
        or the structure; BVH: the joint itself), identity where none.

    Raises
    ------
    SkeletonMappingError
        Unknown joints in ``mapping``, or canonical joints that cannot be mapped (the message names them, says
        what the rig lacks and ends with a ``mapping=`` template, see :func:`guess_mapping`). A ``mapping`` for
        all 24 joints is taken as it is, without looking at the rig.
    """
    if motion.joint_names == CANONICAL_JOINTS and not mapping:
        return motion
    if is_marker_motion(motion):
        return marker_joints(motion, aliases=mapping)
    mapping = dict(mapping or {})
    unknown = {c: j for c, j in mapping.items() if c not in CANONICAL_JOINTS or j not in motion.joint_names}
    if unknown:
        raise SkeletonMappingError(
            f"{motion.source or 'motion'}: mapping entries {unknown} name unknown joints; canonical joints are "
            f"{', '.join(CANONICAL_JOINTS)}; the skeleton has {_shown(motion.joint_names)}"
        )
    if all(c in mapping for c in CANONICAL_JOINTS):
        found = mapping
    else:
        found, reason, candidates = _guess(motion)
        found.update(mapping)
        missing = [c for c in CANONICAL_JOINTS if c not in found]
        if missing:
            raise _mapping_error(motion, missing, reason, candidates)
    names = motion.joint_names
    index = np.array([names.index(found[c]) for c in CANONICAL_JOINTS])
    quat = None
    if motion.quaternions is not None:
        asf = _is_asf(names)
        if asf:
            rot_joint = [(ASF_MAP[c][1] if c not in mapping else found[c]) for c in CANONICAL_JOINTS]
        elif str(motion.source or "").lower().endswith(".amc"):
            rot_joint = _bones_starting_at(motion, found)
        else:
            rot_joint = [found[c] for c in CANONICAL_JOINTS]
        idx = np.array([names.index(r) if r in names and not r.endswith("_end") else -1 for r in rot_joint])
        # taken straight into the result (fancy indexing would copy the selected joints first), identity where none
        quat = np.take(motion.quaternions, np.maximum(idx, 0), axis=1)
        quat[:, idx < 0] = np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32)
    return replace(
        motion,
        positions=np.take(motion.positions, index, axis=1),
        joint_names=CANONICAL_JOINTS,
        parents=CANONICAL_PARENTS,
        quaternions=quat,
    )


def _bones_starting_at(motion: Motion, found: dict) -> list:
    """For an AMC motion (a point is a bone's tip) mapped without the ASF table: per canonical joint, the bone that
    starts at its point towards the next canonical joint (the root: the root itself; tips: None), as the table has."""
    names, parents = motion.joint_names, motion.parents
    index = {n: k for k, n in enumerate(names)}
    out = []
    for c in CANONICAL_JOINTS:
        kids = [k for k, p in enumerate(CANONICAL_PARENTS) if CANONICAL_JOINTS[p] == c and p >= 0]
        if c == "root" or not kids:
            out.append(found[c] if c == "root" else None)
            continue
        start, k = index[found[c]], index[found[CANONICAL_JOINTS[kids[0]]]]
        while k >= 0 and parents[k] != start:
            k = parents[k]
        out.append(names[k] if k >= 0 else None)
    return out


def _index(name: str) -> int:
    return CANONICAL_JOINTS.index(name)


def heading(positions: np.ndarray) -> np.ndarray:
    """Facing direction of a canonical pose sequence as an angle about the vertical axis.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints, cm, y up.

    Returns
    -------
    np.ndarray [shape=(T,)]
        Radians: 0 when the body faces +z, pi/2 when it faces +x. The forward direction is the horizontal hip
        line (left hip minus right hip) crossed with the up axis.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.2 (features in a body-centred frame).
    """
    across = positions[:, _index("lhip")] - positions[:, _index("rhip")]
    # forward = across x up = (-across_z, 0, across_x)
    return np.arctan2(-across[:, 2], across[:, 0])


def body_frame(positions: np.ndarray) -> np.ndarray:
    """Poses in the body frame: root at the origin, rotated about y so that the body faces +z.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints, cm, y up.

    Returns
    -------
    np.ndarray [shape=(T, 24, 3)], float32
        cm. In this frame the left joints have x > 0.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> pose = body_frame(MotionDB.sample().motion(7).positions[:1])
    >>> pose.shape, bool(np.abs(pose[0, 0]).max() == 0)  # the root at the origin
    ((1, 24, 3), True)
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
    frames : np.ndarray [shape=(D, 24, 3)]
        Canonical joints, cm, e.g. the first frame of each of D clips.

    Returns
    -------
    pandas.DataFrame [shape=(D, 8)]
        cm, the columns of :func:`body_sizes`.
    """
    p = np.asarray(frames, dtype=np.float64)
    length = lambda a, b: np.linalg.norm(p[:, _index(a)] - p[:, _index(b)], axis=-1)
    return pd.DataFrame({name: sum(length(a, b) for a, b in chain) for name, chain in _SIZE_CHAINS.items()})


def body_sizes(positions: np.ndarray) -> pd.Series:
    """Body-size units of the relational features, measured on the first frame (feature spec §1.3).

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints, cm.

    Returns
    -------
    pandas.Series of float
        cm: ``humerus_r``, ``humerus_l`` (shoulder-elbow), ``femur_r``, ``femur_l`` (hip-knee), ``hip_width``,
        ``shoulder_width``, ``chest_length`` (chest-neck), ``body_length`` (rankle-rknee + rknee-rhip +
        root-belly + belly-chest + chest-neck + neck-head + head-headtop).
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


def bone_lengths(positions: np.ndarray) -> np.ndarray:
    """Each canonical joint's distance to its parent (0 for the root), the median over the given frames.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints, cm.

    Returns
    -------
    np.ndarray [shape=(24,)], float64
        cm.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> lengths = bone_lengths(MotionDB.sample().motion(0).positions)
    >>> lengths.shape, float(lengths[0])
    ((24,), 0.0)
    """
    p = np.asarray(positions, dtype=np.float64)
    parents = np.maximum(CANONICAL_PARENTS, 0)
    return np.median(np.linalg.norm(p - p[:, parents], axis=-1), axis=0)


SHORTEST_BONE_CM = 2.0
"""cm: :func:`retarget` keeps the length of a bone this short or shorter (a clavicle some rigs put at the neck)."""


def retarget(motion: Motion, lengths) -> Motion:
    """The same movement on a body of other bone lengths: each bone (joint minus its parent) scaled to its new
    length on every frame, the root's path kept; what a copy of a take retargeted to another actor looks like.

    Parameters
    ----------
    motion : Motion
        Canonical joints (any other skeleton is mapped first).
    lengths : array_like [shape=(24,)]
        The new body's bone lengths, cm (:func:`bone_lengths` of another actor's clip).

    Returns
    -------
    Motion
        Positions (T, 24, 3) on the new bones; quaternions (the joints' rotations) unchanged. A bone shorter than
        2 cm in ``motion`` keeps its length (its direction is not defined).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> other = bone_lengths(db.motion(12).positions)
    >>> moved = retarget(db.motion(0), other)
    >>> bool(np.allclose(bone_lengths(moved.positions)[1:], other[1:], rtol=1e-3))
    True
    """
    motion = to_canonical(motion)
    p = np.asarray(motion.positions, dtype=np.float64)
    own = bone_lengths(p)
    ratio = np.where(own > SHORTEST_BONE_CM, np.asarray(lengths, dtype=np.float64) / np.maximum(own, 1e-3), 1.0)
    # a bone of (almost) no length, such as a clavicle some rigs put at the neck, has no direction to scale (or only
    # the direction of its markers' noise): it stays as it is
    out = p.copy()
    for j in range(1, len(CANONICAL_JOINTS)):  # parents come before their children
        parent = CANONICAL_PARENTS[j]
        out[:, j] = out[:, parent] + (p[:, j] - p[:, parent]) * ratio[j]
    return replace(motion, positions=out.astype(np.float32))
