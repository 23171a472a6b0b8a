"""HumanML3D's joint arrays: the 22 SMPL body joints at 20 fps in metres, y up, one ``.npy`` of shape (T, 22, 3) per
clip (the ``new_joints/`` folder of Guo et al., CVPR 2022), written from and read back into the canonical joints.

LAYOUTS              the array layouts :func:`mocapviz.load` reads from ``.npy`` files: ``("humanml3d",)``.
JOINTS, PARENTS      the 22 joints in HumanML3D's order and their tree (its ``t2m_kinematic_chain``).
FPS                  20 frames per second.
PLACED               each of the 22 joints as a point of the canonical skeleton (docs/export.md has the table).
EXTRAPOLATED         the canonical joints the 22 lack, placed beyond two of them when an array is read.
joint_positions      canonical positions (T, 24, 3) -> the 22 joints (T, 22, 3), same unit.
canonical_positions  the 22 joints (T, 22, 3) -> canonical positions (T, 24, 3): the inverse where there is one.
placement            HumanML3D's placement of a clip: floor at y = 0, first root over the origin, facing +z.
turned               points turned about the vertical axis.
joint_array          a canonical Motion -> the (T, 22, 3) float32 array in metres, placed, and its placement.
read_joint_array     a ``.npy`` file of such an array -> a Motion on the 24 canonical joints, cm.

Where the layout comes from: HumanML3D's ``paramUtil.py`` (``t2m_kinematic_chain = [[0, 2, 5, 8, 11], [0, 1, 4, 7,
10], [0, 3, 6, 9, 12, 15], [9, 14, 17, 19, 21], [9, 13, 16, 18, 20]]``: legs, spine to head, arms from spine3),
``raw_pose_processing.py`` (SMPL-H joints of AMASS sampled at 20 fps, y up) and ``motion_representation.py``
(``new_joints``: the floor at y = 0, the first frame's root moved over the origin, the clip turned about y so that
the first frame faces +z by its hips and shoulders, ``face_joint_indx = [2, 1, 17, 16]``).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import MocapFormatError, ParameterError
from ..motion import Motion, fps_problem
from ..motion.joints import CANONICAL_JOINTS, CANONICAL_PARENTS

__all__ = ["EXTRAPOLATED", "FPS", "JOINTS", "LAYOUTS", "PARENTS", "PLACED", "canonical_positions", "joint_array",
           "joint_positions", "placement", "read_joint_array", "turned"]

LAYOUTS = ("humanml3d",)
FPS = 20.0
CM_PER_M = 100.0

JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle", "right_ankle",
    "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip
PARENTS = np.array([-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19])

PLACED = {
    "pelvis": ("root", "root", 0.0), "left_hip": ("lhip", "lhip", 0.0), "right_hip": ("rhip", "rhip", 0.0),
    "spine1": ("belly", "belly", 0.0), "left_knee": ("lknee", "lknee", 0.0), "right_knee": ("rknee", "rknee", 0.0),
    "spine2": ("chest", "chest", 0.0), "left_ankle": ("lankle", "lankle", 0.0),
    "right_ankle": ("rankle", "rankle", 0.0), "spine3": ("chest", "neck", 0.5), "left_foot": ("ltoes", "ltoes", 0.0),
    "right_foot": ("rtoes", "rtoes", 0.0), "neck": ("neck", "neck", 0.0),
    "left_collar": ("lclavicle", "lshoulder", 0.5), "right_collar": ("rclavicle", "rshoulder", 0.5),
    "head": ("head", "head", 0.0), "left_shoulder": ("lshoulder", "lshoulder", 0.0),
    "right_shoulder": ("rshoulder", "rshoulder", 0.0), "left_elbow": ("lelbow", "lelbow", 0.0),
    "right_elbow": ("relbow", "relbow", 0.0), "left_wrist": ("lwrist", "lwrist", 0.0),
    "right_wrist": ("rwrist", "rwrist", 0.0),
}  # fmt: skip
"""Joint -> (canonical a, canonical b, f): the joint is the point ``a + f (b - a)`` of the canonical skeleton; f = 0
is one canonical joint. spine3 is halfway up the chest (chest to neck), a collar halfway from the clavicle joint
to the shoulder (an ASF clavicle joint is the neck; SMPL's collar lies out on the collarbone)."""

EXTRAPOLATED = {"headtop": ("neck", "head", 0.5), "lfingers": ("lelbow", "lwrist", 0.4),
                "rfingers": ("relbow", "rwrist", 0.4)}  # fmt: skip
"""Canonical joint the 22 lack -> (a, b, r): read as ``b + r (b - a)``, beyond b on the line from a. The ratios are
the medians of the embedded sample's 24 clips (HDM05 and CMU): head to head top 0.51 of neck to head, wrist to
finger tips 0.24 to 0.44 of elbow to wrist."""

_FACING = ("right_hip", "left_hip", "right_shoulder", "left_shoulder")  # HumanML3D's face_joint_indx [2, 1, 17, 16]


def _canonical(name: str) -> int:
    return CANONICAL_JOINTS.index(name)


def joint_positions(positions: np.ndarray) -> np.ndarray:
    """The 22 joints of HumanML3D's layout from canonical joint positions (:data:`PLACED`).

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints (any unit).

    Returns
    -------
    np.ndarray [shape=(T, 22, 3)], float64
        The same unit, in the order of :data:`JOINTS`.

    Examples
    --------
    >>> p = np.zeros((1, 24, 3)); p[0, CANONICAL_JOINTS.index("neck"), 1] = 10.0
    >>> joint_positions(p)[0, JOINTS.index("spine3")]  # halfway from the chest (at 0) to the neck
    array([0., 5., 0.])
    """
    p = np.asarray(positions, dtype=np.float64)
    a = p[:, [_canonical(PLACED[j][0]) for j in JOINTS]]
    b = p[:, [_canonical(PLACED[j][1]) for j in JOINTS]]
    f = np.array([PLACED[j][2] for j in JOINTS])[:, None]
    return a + f * (b - a)


def canonical_positions(joints: np.ndarray) -> np.ndarray:
    """Canonical joint positions from the 22 joints: a joint of :data:`PLACED` at f = 0 is its canonical joint, a
    clavicle is solved from its collar and shoulder (``(collar - f shoulder) / (1 - f)``), the joints of
    :data:`EXTRAPOLATED` are placed beyond two others; spine3 is not used. The inverse of :func:`joint_positions`
    for every canonical joint but those three.

    Parameters
    ----------
    joints : np.ndarray [shape=(T, 22, 3)]
        In the order of :data:`JOINTS` (any unit).

    Returns
    -------
    np.ndarray [shape=(T, 24, 3)], float64
        The same unit, in the order of :data:`mocapviz.motion.joints.CANONICAL_JOINTS`.

    Examples
    --------
    >>> p = np.random.default_rng(0).normal(size=(2, 24, 3))
    >>> back = canonical_positions(joint_positions(p))
    >>> kept = [CANONICAL_JOINTS.index(j) for j in CANONICAL_JOINTS if j not in EXTRAPOLATED]
    >>> len(kept), bool(np.allclose(back[:, kept], p[:, kept]))
    (21, True)
    """
    q = np.asarray(joints, dtype=np.float64)
    out = np.empty((q.shape[0], len(CANONICAL_JOINTS), 3))
    for j, (a, b, f) in PLACED.items():
        if f == 0.0:
            out[:, _canonical(a)] = q[:, JOINTS.index(j)]
    for j, (a, b, f) in PLACED.items():
        if f != 0.0 and j != "spine3":  # a collar: solve for its clavicle, the shoulder (f = 0) known
            out[:, _canonical(a)] = (q[:, JOINTS.index(j)] - f * out[:, _canonical(b)]) / (1.0 - f)
    for c, (a, b, r) in EXTRAPOLATED.items():
        out[:, _canonical(c)] = out[:, _canonical(b)] + r * (out[:, _canonical(b)] - out[:, _canonical(a)])
    return out


def placement(joints: np.ndarray) -> tuple[float, np.ndarray]:
    """HumanML3D's placement of a clip (``new_joints``): the turn about y and the origin that put the floor at y = 0
    (the lowest joint of any frame), the first frame's root over the origin, and the first frame facing +z.

    The first frame's facing is HumanML3D's: the up axis crossed with the sum of its hip line and shoulder line
    (right minus left), so that the left joints have x > 0 as in :func:`mocapviz.motion.skeleton.body_frame`.

    Parameters
    ----------
    joints : np.ndarray [shape=(T, 22, 3)]
        The 22 joints, y up.

    Returns
    -------
    yaw : float
        Radians the clip is turned about +y (right-handed) once moved.
    origin : np.ndarray [shape=(3,)], float64
        The point moved to the origin: the first root's x and z, the lowest y. A placed position is
        ``R_y(yaw) (p - origin)``.

    Examples
    --------
    >>> q = np.zeros((1, 22, 3))
    >>> q[0, [JOINTS.index("left_hip"), JOINTS.index("left_shoulder")], 2] = 1.0  # the left side at +z: faces -x
    >>> q[0, [JOINTS.index("right_hip"), JOINTS.index("right_shoulder")], 2] = -1.0
    >>> yaw, origin = placement(q)
    >>> round(float(np.degrees(yaw)), 6), origin.tolist()
    (90.0, [0.0, 0.0, 0.0])
    """
    q = np.asarray(joints, dtype=np.float64)
    rh, lh, rs, ls = (JOINTS.index(j) for j in _FACING)
    across = q[0, rh] - q[0, lh] + q[0, rs] - q[0, ls]
    forward_x, forward_z = across[2], -across[0]  # (0, 1, 0) x across
    yaw = -float(np.arctan2(forward_x, forward_z))  # facing +z: arctan2 is 0
    origin = np.array([q[0, 0, 0], float(q[..., 1].min()), q[0, 0, 2]])
    return yaw, origin


def turned(points: np.ndarray, yaw: float) -> np.ndarray:
    """``points`` [shape=(..., 3)] turned by ``yaw`` radians about +y (right-handed: +z towards +x).

    Examples
    --------
    >>> turned(np.array([0.0, 1.0, 1.0]), np.pi / 2).round(6).tolist()
    [1.0, 1.0, 0.0]
    """
    c, s = np.cos(yaw), np.sin(yaw)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return np.stack([c * x + s * z, y, c * z - s * x], axis=-1)


def joint_array(motion: Motion) -> tuple[np.ndarray, float, np.ndarray]:
    """A clip as HumanML3D's joint array: resampled to 20 fps (:meth:`mocapviz.motion.Motion.resample`), the 22
    joints (:func:`joint_positions`), metres, placed (:func:`placement`; the trajectory kept, the whole clip moved
    and turned once).

    Parameters
    ----------
    motion : Motion
        On the 24 canonical joints (:meth:`~mocapviz.motion.Motion.canonical`), cm, y up.

    Returns
    -------
    array : np.ndarray [shape=(T, 22, 3)], float32
        Metres; T = floor((n - 1) * 20 / fps) + 1 for n frames at ``fps``: every 1/20 s from the first frame on.
    yaw : float
        Radians turned about +y.
    origin : np.ndarray [shape=(3,)]
        Metres, in the clip's coordinates: the point moved to the origin before turning.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> array, yaw, origin = joint_array(MotionDB.sample().motion(7))  # 129 frames at 120 Hz
    >>> array.shape, array.dtype, float(array[..., 1].min())
    ((22, 22, 3), dtype('float32'), 0.0)
    """
    if motion.joint_names != CANONICAL_JOINTS:
        raise ParameterError(f"{motion.source or 'the motion'}: HumanML3D's joints are made from the 24 canonical "
                             "joints; pass motion.canonical()")  # fmt: skip
    joints = joint_positions(motion.resample(FPS).positions) / CM_PER_M
    yaw, origin = placement(joints)
    return turned(joints - origin, yaw).astype(np.float32), yaw, origin


def read_joint_array(path, fps: float | None = None) -> Motion:
    """A ``.npy`` file of HumanML3D's layout read as a Motion on the 24 canonical joints
    (:func:`canonical_positions`), cm, y up.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.npy`` file holding one float array [shape=(T, 22, 3)] in metres, y up (no pickled objects: read with
        ``allow_pickle=False``).
    fps : float, optional
        Its frame rate; default :data:`FPS` (20).

    Returns
    -------
    Motion
        Positions [shape=(T, 24, 3)] float32 in cm as the file places them, no rotations, ``source`` the file.

    Raises
    ------
    MocapFormatError
        Not a ``.npy`` array, a pickle-bearing or non-float array, another shape (HumanML3D's (T, 263) feature
        vectors named as such), a value not finite or beyond 100 km (frame, joint and axis named).
    ParameterError
        ``fps`` outside 1 to 10,000.

    Examples
    --------
    >>> import tempfile
    >>> from mocapviz import MotionDB
    >>> array, _, _ = joint_array(MotionDB.sample().motion(7))
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     np.save(f"{folder}/kick.npy", array)
    ...     m = read_joint_array(f"{folder}/kick.npy")
    >>> m.positions.shape, m.fps, m.joint_names == CANONICAL_JOINTS
    ((22, 24, 3), 20.0, True)
    """
    fps = FPS if fps is None else fps
    problem = fps_problem(float(fps))
    if problem:
        raise ParameterError(f"fps: {problem}")
    path = os.fspath(path)
    with open(path, "rb") as f:
        magic = f.read(6)
    if magic != b"\x93NUMPY" and not magic.startswith(b"PK\x03\x04"):  # neither .npy nor .npz
        raise MocapFormatError(path, "not a NumPy .npy array (it does not start with the .npy magic bytes)")
    try:
        array = np.load(path, allow_pickle=False)
    except ValueError as exc:  # an object array: pickled Python objects
        raise MocapFormatError(path, f"holds pickled Python objects, which are not read (a joint array is plain "
                               f"floats): {exc}") from None
    except (OSError, EOFError) as exc:
        raise MocapFormatError(path, f"not a readable NumPy .npy array ({exc})") from None
    if not isinstance(array, np.ndarray):  # an .npz archive
        array.close()
        raise MocapFormatError(path, "an .npz archive, not one .npy array of shape (T, 22, 3)")
    _check(path, array)
    positions = canonical_positions(array.astype(np.float64) * CM_PER_M)
    return Motion(positions.astype(np.float32), float(fps), CANONICAL_JOINTS, CANONICAL_PARENTS, source=path)


def _check(path: str, array: np.ndarray) -> None:
    """A MocapFormatError naming what is wrong with ``array`` as a (T, 22, 3) float array in metres."""
    from .checks import DISTANCE_LIMIT_CM, describe, first_outside  # numba: loaded by the first file read

    if array.dtype.kind != "f":
        raise MocapFormatError(path, f"holds {array.dtype} values; a joint array holds floats (metres)")
    if array.ndim == 2 and array.shape[1] == 263:
        raise MocapFormatError(path, f"shape {array.shape}: HumanML3D's feature vectors (new_joint_vecs), not joint "
                               "positions; pass the arrays of its new_joints folder, (T, 22, 3)")  # fmt: skip
    if array.ndim != 3 or array.shape[1:] != (len(JOINTS), 3) or array.shape[0] == 0:
        raise MocapFormatError(path, f"shape {array.shape}; HumanML3D's joint arrays are (T, 22, 3) with T >= 1: "
                               "frames, the 22 joints, x y z in metres")  # fmt: skip
    bad = first_outside(array, DISTANCE_LIMIT_CM / CM_PER_M)
    if bad is not None:
        t, j, axis = bad
        raise MocapFormatError(path, f"frame {t}, joint {JOINTS[j]}, {'xyz'[axis]}: {describe(float(array[bad]))} "
                               f"(positions must be finite, within {DISTANCE_LIMIT_CM / CM_PER_M:g} m)")  # fmt: skip
