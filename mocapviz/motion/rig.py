"""Joint rotations that reproduce given joint positions on a fixed rig (the canonical rig of an export).

A rig is a joint tree with one rest offset per joint (its position relative to its parent, in the parent's frame).
Posed by local rotations, joint ``j`` lies at ``P[parent] + R(Q[parent]) @ t[j]`` with ``Q[j] = Q[parent] * q[j]``
(the BVH and glTF convention). :func:`fit_pose` finds rotations ``q`` such that this reproduces a clip's positions:

- a joint with one child turns by the smallest rotation (the swing) that takes the child's rest offset to the
  child's bone in that frame, seen from the parent;
- a joint with several children by the rotation that fits their bones best (least squares, the Kabsch solution):
  fitted to the largest set of its children that the rotation then reproduces within the tolerance in every frame
  (every subset tried, up to 6 children), so that one child moving against its siblings (the spine against the
  hips) does not pull the others off;
- a child the rotation does not put within ``tolerance`` of its position in some frame (a bone whose length varies,
  because it spans several source bones; a branch that moves against its siblings, such as the spine against the
  hips) gets a translation of its own in every frame: ``t[j]`` is then the offset the frame needs, exactly.

The root always translates. A joint without children keeps its parent's rotation (local identity).

:func:`canonical_rest` gives the canonical rig its rest offsets: an upright T-pose facing +z, y up, each bone as long
as it is in the document.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from . import rotations
from .skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS

TOLERANCE_CM = 0.001
"""How far a child may be from where the fitted rotation puts it before it gets a translation of its own, cm. Misses
add up along a chain: the canonical tree is at most 8 bones deep, so 8 x 0.001 cm stays within the 0.01 cm an export
promises."""


_UP, _DOWN, _LEFT, _RIGHT, _FORWARD = (0, 1, 0), (0, -1, 0), (1, 0, 0), (-1, 0, 0), (0, 0, 1)
STANDARD_DIRECTIONS = {
    "root": (0, 0, 0), "lhip": _LEFT, "rhip": _RIGHT,
    "lknee": _DOWN, "lankle": _DOWN, "ltoes": _FORWARD, "rknee": _DOWN, "rankle": _DOWN, "rtoes": _FORWARD,
    "belly": _UP, "chest": _UP, "neck": _UP, "head": _UP, "headtop": _UP,
    "lclavicle": _LEFT, "lshoulder": _LEFT, "lelbow": _LEFT, "lwrist": _LEFT, "lfingers": _LEFT,
    "rclavicle": _RIGHT, "rshoulder": _RIGHT, "relbow": _RIGHT, "rwrist": _RIGHT, "rfingers": _RIGHT,
}  # fmt: skip
"""Direction of each canonical joint's rest offset from its parent: a T-pose facing +z, y up, the figure's left on
+x (the hips and clavicles: sideways, and lowered below their parent by :func:`canonical_rest`)."""


def canonical_rest(positions: np.ndarray) -> np.ndarray:
    """Rest offsets of the canonical rig for a clip: an upright T-pose with the clip's bone lengths.

    Every bone has its median length over the frames of ``positions`` and points along
    :data:`STANDARD_DIRECTIONS`: facing +z, y up, the figure's left on +x; legs straight down, feet (ankle to toes)
    forward, spine, neck and head up, arms out sideways, horizontally. The hips lie on one line across the body (x),
    below the root by the root's distance from that line (medians over the frames of the hips' distances along that
    line and of the root's from it), so that the root and its hips keep the shape they have in the clip and one
    rotation poses both; the clavicles likewise below the neck. A bone of length zero (the canonical clavicles of
    HDM05 and CMU start where the neck is) has offset zero.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Positions of the canonical joints (:data:`~mocapviz.motion.skeleton.CANONICAL_JOINTS`), cm, y up; the
        frames whose bone lengths count (an export uses the whole document, so every stretch of it gets one rig).

    Returns
    -------
    np.ndarray [shape=(24, 3)], float64
        Each joint's offset from its parent at rest, cm (the root's: zero).

    Raises
    ------
    ParameterError
        ``positions`` is not (T, 24, 3) with T >= 1.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> rest = canonical_rest(MotionDB.sample().motion(7).positions)
    >>> knee, neck = CANONICAL_JOINTS.index("lknee"), CANONICAL_JOINTS.index("neck")
    >>> bool(rest[knee, 1] < 0 and rest[neck, 1] > 0), bool(np.abs(rest[knee, [0, 2]]).max() == 0)
    (True, True)
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (len(CANONICAL_JOINTS), 3) or not len(p):
        raise ParameterError(f"positions must be (T, {len(CANONICAL_JOINTS)}, 3) canonical joints with T >= 1, got "
                             f"shape {p.shape}")
    bones = p - p[:, np.maximum(CANONICAL_PARENTS, 0)]
    lengths = np.median(np.linalg.norm(bones, axis=-1), axis=0)
    offsets = lengths[:, None] * np.array([STANDARD_DIRECTIONS[j] for j in CANONICAL_JOINTS], dtype=np.float64)
    for pair in ("hip", "clavicle"):  # two children of one joint, across the body: keep their triangle
        left, right = CANONICAL_JOINTS.index("l" + pair), CANONICAL_JOINTS.index("r" + pair)
        across = bones[:, left] - bones[:, right]
        across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-12)
        sideways = np.einsum("tjk,tk->tj", bones[:, [left, right]], across)  # (T, 2): along the line across
        below = np.linalg.norm(bones[:, left] - sideways[:, :1] * across, axis=-1)  # the parent's distance from it
        offsets[[left, right]] = 0.0
        offsets[[left, right], 0] = np.median(sideways, axis=0)
        offsets[[left, right], 1] = -np.median(below)
    return offsets + 0.0  # (no -0.0 in a written OFFSET)


@dataclass(frozen=True)
class Pose:
    """A clip posed on a fixed rig (:func:`fit_pose`); the parameters are its attributes.

    Parameters
    ----------
    offsets : np.ndarray [shape=(J, 3)], float64
        Rest offsets, cm, in the parent's frame (the root's: zero).
    rotations : np.ndarray [shape=(T, J, 4)], float64
        Local rotations ``(w, x, y, z)``.
    translations : np.ndarray [shape=(T, J, 3)], float64
        Local offsets per frame, cm: the rest offset where ``moving`` is false, the root's position for the root.
    moving : np.ndarray [shape=(J,)], bool
        Joints whose offset is animated (the root, and children no rotation of their parent reproduces).
    """

    offsets: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    moving: np.ndarray


def fit_pose(positions: np.ndarray, parents: np.ndarray, offsets: np.ndarray,
             tolerance: float = TOLERANCE_CM) -> Pose:
    """Local rotations (and, where needed, translations) that reproduce ``positions`` on the rig ``offsets``.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, J, 3)]
        Joint positions, cm.
    parents : np.ndarray [shape=(J,)], int
        Parent of each joint, -1 for the root; parents come first.
    offsets : np.ndarray [shape=(J, 3)]
        Rest offsets, cm (e.g. the bones of one frame: ``positions[0] - positions[0, parents]``).
    tolerance : float
        Largest distance, cm, between a child and where its parent's rotation puts it without a translation.

    Returns
    -------
    Pose
        Forward kinematics of its rotations and translations gives ``positions`` (up to rounding, 1e-9 cm).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> m = MotionDB.sample().motion(7)
    >>> parents = m.parents
    >>> rest = m.positions[0] - m.positions[0, np.maximum(parents, 0)]
    >>> pose = fit_pose(m.positions, parents, rest)
    >>> pose.rotations.shape, bool(pose.moving[0])
    ((129, 24, 4), True)
    """
    p = np.asarray(positions, dtype=np.float64)
    parents = np.asarray(parents, dtype=np.int64)
    offsets = np.asarray(offsets, dtype=np.float64).copy()
    n_frames, n_joints = p.shape[:2]
    roots = parents < 0
    offsets[roots] = 0.0
    local = np.zeros((n_frames, n_joints, 4))
    local[..., 0] = 1.0
    world = local.copy()
    translations = np.broadcast_to(offsets, p.shape).copy()
    translations[:, roots] = p[:, roots]
    moving = roots.copy()
    for j in range(n_joints):
        kids = np.flatnonzero(parents == j)
        parent_turn = world[:, parents[j]] if parents[j] >= 0 else local[:, j]  # (identity for a root)
        inverse = parent_turn * np.array([1.0, -1.0, -1.0, -1.0])
        bones = rotations.rotate(inverse[:, None], p[:, kids] - p[:, j : j + 1])  # (T, k, 3) in the parent's frame
        q, needed, off = _fit_children(offsets[kids], bones, tolerance)
        local[:, j] = q
        world[:, j] = rotations.multiply(parent_turn, q) if parents[j] >= 0 else q
        for k, c in enumerate(kids):
            if off[k]:
                moving[c] = True
                translations[:, c] = needed[:, k]
    return Pose(offsets=offsets, rotations=local, translations=translations, moving=moving)


_SUBSETS_UP_TO = 6  # children of one joint whose subsets are all tried (2^6 fits); more: all of them, once


def _fit_children(rest: np.ndarray, bones: np.ndarray, tolerance: float):
    """The rotation [shape=(T, 4)] of a joint that reproduces the most of its children (rest offsets (k, 3), bones
    (T, k, 3) in the parent's frame) within ``tolerance`` in every frame: fitted to the largest set of children that
    it then reproduces (of sets that large, the one it misses least), else to all of them. Also the offset each child
    needs [shape=(T, k, 3)] and which children it misses [shape=(k,)]."""
    usable = [k for k in range(len(rest)) if np.linalg.norm(rest[k]) > 1e-6]  # (a zero offset fixes no rotation)
    sizes = range(len(usable), 0, -1) if len(usable) <= _SUBSETS_UP_TO else [len(usable)]
    first = None
    for size in sizes:
        fitting = []
        for use in map(list, itertools.combinations(usable, size)):
            q = _best_rotation(rest[use], bones[:, use])
            needed = rotations.rotate((q * np.array([1.0, -1.0, -1.0, -1.0]))[:, None], bones)
            miss = np.linalg.norm(needed - rest, axis=-1).max(axis=0)
            first = first or (q, needed, miss)
            if (miss[use] <= tolerance).all():
                fitting.append((miss[use].max(), q, needed, miss))
        if fitting:
            _, q, needed, miss = min(fitting, key=lambda f: f[0])
            return q, needed, miss > tolerance
    if first is None:  # no child with an offset: the joint keeps its parent's rotation
        return _best_rotation(rest[:0], bones[:, :0]), bones, np.linalg.norm(bones - rest, axis=-1).max(axis=0) > tolerance
    q, needed, miss = first
    return q, needed, miss > tolerance


def _best_rotation(rest: np.ndarray, bones: np.ndarray) -> np.ndarray:
    """Per frame, the rotation [shape=(T, 4)] taking the rest vectors (k, 3) closest to the bones (T, k, 3): none
    (identity), the swing of one vector, or the least-squares fit (Kabsch) of several."""
    n_frames = bones.shape[0]
    if len(rest) == 0:
        return np.tile([1.0, 0.0, 0.0, 0.0], (n_frames, 1))
    if len(rest) == 1:
        a = rest[0] / np.linalg.norm(rest[0])
        b = bones[:, 0] / np.maximum(np.linalg.norm(bones[:, 0], axis=-1, keepdims=True), 1e-12)
        q = np.concatenate([(1.0 + b @ a)[:, None], np.cross(a, b)], axis=-1)
        opposite = q[:, 0] < 1e-9  # half a turn: about any axis perpendicular to a
        if opposite.any():
            axis = np.cross(a, np.eye(3)[np.argmin(np.abs(a))])
            q[opposite] = np.concatenate([[0.0], axis / np.linalg.norm(axis)])
        return q / np.linalg.norm(q, axis=-1, keepdims=True)
    h = np.einsum("ki,tkj->tij", rest, bones)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones((n_frames, 3))
    fix[:, 2] = np.where(d == 0, 1.0, d)
    r = np.swapaxes(vt, -1, -2) @ (fix[:, :, None] * np.swapaxes(u, -1, -2))
    return rotations.from_matrix(r)
