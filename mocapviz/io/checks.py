"""What the readers accept: the limits on the values of a motion file (one place for each) and the checks that
apply them, each raising a :class:`~mocapviz.errors.MocapFormatError` that names the file, the line and the value.

FPS_RANGE            frames per second a file may state: 1 to 10,000 (:data:`mocapviz.motion.FPS_RANGE`).
ANGLE_LIMIT_DEG      |rotation| at most 100,000 degrees (about 278 turns).
DISTANCE_LIMIT_CM    |position|, |translation|, |offset| and bone lengths at most 1e7 cm (100 km).
check_frame_rate     a frame rate inside FPS_RANGE.
first_outside        the first value of a block beyond a limit (or not finite), for a reader to name its line.
checked_forward_kinematics   forward kinematics a block of frames at a time into the float32 arrays a Motion
                     keeps, every position checked against DISTANCE_LIMIT_CM (frame and joint named).

Why these limits: a Motion keeps positions and angles in float32, whose resolution is 1 cm at 1e7 cm, and the
forward kinematics takes sines of half angles in float32, accurate to 0.005 degrees at 1e5 degrees; beyond them a
value is a broken file (a fuzzed ``1e39``), not a capture.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import MocapFormatError
from ..motion import FPS_RANGE, fps_problem, rotations

__all__ = ["ANGLE_LIMIT_DEG", "DISTANCE_LIMIT_CM", "FPS_RANGE", "check_frame_rate", "checked_forward_kinematics",
           "describe", "first_outside"]

ANGLE_LIMIT_DEG = 1e5
DISTANCE_LIMIT_CM = 1e7
_BLOCK = 1 << 18  # joint-frames per forward-kinematics block: about 40 MB of temporaries


def check_frame_rate(fps: float, path, line: int | None, what: str) -> float:
    """``fps`` when it is inside :data:`FPS_RANGE`, else a MocapFormatError naming ``what`` (``"Frame Time 1e+308 s"``).

    Parameters
    ----------
    fps : float
        Frames per second, as the file states it.
    path : str or os.PathLike
        The file, for the message.
    line : int or None
        Its line, for the message.
    what : str
        How the file states the rate (``"Frame Time 1e+308 s"``).

    Returns
    -------
    float
        ``fps``, unchanged.

    Raises
    ------
    MocapFormatError
        A rate outside 1 to 10,000 fps, or not finite.
    """
    problem = fps_problem(fps)
    if problem:
        raise MocapFormatError(path, f"{what}: {problem}", line)
    return fps


def first_outside(values: np.ndarray, limit) -> tuple | None:
    """Index (a tuple, row-major first) of the first element of ``values`` with ``|v| > limit`` or not finite.

    Parameters
    ----------
    values : np.ndarray [shape=(N, C)]
        A block of a file's values.
    limit : float or np.ndarray [shape=(C,)]
        The largest magnitude allowed, one for all or per column.

    Returns
    -------
    tuple of int or None
        (row, column) of the first offending value; None when every value is within the limit.

    Examples
    --------
    >>> first_outside(np.array([[1.0, 2.0], [np.nan, 5.0]]), 10.0), first_outside(np.ones((2, 2)), 10.0)
    ((1, 0), None)
    """
    bad = ~(np.abs(values) <= limit)  # NaN compares false
    if not bad.any():
        return None
    return tuple(int(i) for i in np.argwhere(bad)[0])


def describe(value: float) -> str:
    """A value for an error message: ``1e+39``, ``-inf``, ``12.5``.

    Parameters
    ----------
    value : float
        The offending value.

    Returns
    -------
    str
        At most 6 significant digits.

    Examples
    --------
    >>> describe(1e39), describe(-np.inf), describe(12.5)
    ('1e+39', '-inf', '12.5')
    """
    return f"{value:.6g}"


def checked_forward_kinematics(
    n_frames: int,
    parents: np.ndarray,
    orders,
    block: Callable[[int, int], tuple[np.ndarray, np.ndarray]],
    *,
    names,
    path,
    frame_line: Callable[[int], int | None],
    scale: float | Callable[[np.ndarray], float] = 1.0,
    **fk_options,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Forward kinematics of a whole clip, a block of frames at a time, into float32 arrays.

    Peak memory is the returned arrays plus one block's temporaries (:func:`mocapviz.motion.rotations.forward_kinematics`
    of the whole clip would hold float64 copies of everything, several times the result).

    Parameters
    ----------
    n_frames : int
        Frames of the clip (T).
    parents, orders
        The joint tree and rotation orders, see :func:`mocapviz.motion.rotations.forward_kinematics` (J joints).
    block : callable
        ``block(a, b) -> (euler, translations)``: Euler angles [shape=(b-a, J, 3)] and local translations
        [shape=(b-a, J, 3)] (file units) of frames a to b-1 (it may also keep what else the reader returns of
        those frames, such as the file's channel values).
    names : sequence of str [length J]
        Joint names, for error messages.
    path : str
        The file, for error messages.
    frame_line : callable
        ``frame_line(frame) -> int or None``: the file line of a frame (0-based), for error messages.
    scale : float or callable
        Centimetres per file unit, or ``scale(positions) -> float`` of the first frame's positions [shape=(J, 3)]
        (file units).
    **fk_options
        ``own_frame``, ``pre``, ``post``, ``degrees`` of :func:`~mocapviz.motion.rotations.forward_kinematics`.

    Returns
    -------
    positions : np.ndarray [shape=(T, J, 3)], float32
        Global joint positions, cm.
    quaternions : np.ndarray [shape=(T, J, 4)], float32
        Local rotations (w, x, y, z).
    scale : float
        The centimetres per file unit used.

    Raises
    ------
    MocapFormatError
        A position beyond :data:`DISTANCE_LIMIT_CM` (or not finite), naming the frame, its line, the joint and the
        position.
    """
    n_joints = len(names)
    positions = np.empty((n_frames, n_joints, 3), dtype=np.float32)
    quaternions = np.empty((n_frames, n_joints, 4), dtype=np.float32)
    step = max(1, _BLOCK // max(1, n_joints))
    for a in range(0, n_frames, step):
        b = min(n_frames, a + step)
        euler, translations = block(a, b)
        q, p = rotations.forward_kinematics(parents, euler, orders, translations, **fk_options)
        del euler, translations
        if callable(scale):
            scale = float(scale(p[0]))
        if scale != 1.0:
            p *= scale
        bad = first_outside(p.reshape(b - a, -1), DISTANCE_LIMIT_CM)
        if bad is not None:
            t, k = bad
            j = k // 3
            raise MocapFormatError(
                path, f"frame {a + t}: joint {names[j]!r} comes out at {describe(p[t, j, k % 3])} cm, beyond "
                      f"±{DISTANCE_LIMIT_CM:g} cm (an absurd translation, offset or bone length)", frame_line(a + t))
        positions[a:b] = p
        quaternions[a:b] = q
    return positions, quaternions, float(scale)
