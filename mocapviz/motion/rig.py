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
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from . import rotations

TOLERANCE_CM = 0.001
"""How far a child may be from where the fitted rotation puts it before it gets a translation of its own, cm. Misses
add up along a chain: the canonical tree is at most 8 bones deep, so 8 x 0.001 cm stays within the 0.01 cm an export
promises."""


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
