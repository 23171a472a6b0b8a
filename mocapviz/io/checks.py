"""What the readers accept: the limits on the values of a motion file and what a plausible file holds (one place
for each), and the checks that apply them, each raising a :class:`~mocapviz.errors.MocapFormatError` that names the
file, the line and the value, or, for a legitimately partial file, warning :class:`~mocapviz.errors.MocapFormatWarning`.

FPS_RANGE            frames per second a file may state: 1 to 10,000 (:data:`mocapviz.motion.FPS_RANGE`).
ANGLE_LIMIT_DEG      |rotation| at most 100,000 degrees (about 278 turns).
DISTANCE_LIMIT_CM    |position|, |translation|, |offset| and bone lengths at most 1e7 cm (100 km).
DIRECTION_TOLERANCE  an ASF bone direction is a unit vector: its length within 1 ± 0.05 (normalised to 1).
FIGURE_UNITS         the length units a figure's size tells apart (m, mm, cm, inch, CMU's 0.45 inch), by size.
figure_unit          the unit a file's figure is in, guessed from its size, and whether to say so.
numbered             names made unique as a Motion needs them: a repeated one numbered (``a``, ``a#2``, ...).
check_frame_rate     a frame rate inside FPS_RANGE.
first_outside        the first value of a block beyond a limit (or not finite), for a reader to name its line.
unit_directions      ASF bone directions, normalised; zero or far from unit length refused (bone and line named).
check_limits         the values of an ASF ``limits`` line: numbers within ANGLE_LIMIT_DEG, or the ASF's ``inf``
                     / ``-inf`` (no limit); NaN, overflow (``1e400``) and a lower limit above the upper refused.
complete_frames      every AMC frame has a line for every bone with channels (root included); only a file cut off
                     inside its last frame is read, without that frame (with a warning); an empty frame, a bone
                     missing from every frame, a missing line elsewhere, or a cut-off only frame is refused.
checked_forward_kinematics   forward kinematics a block of frames at a time into the float32 arrays a Motion
                     keeps, every position checked against DISTANCE_LIMIT_CM (frame and joint named).
format_warning       warn MocapFormatWarning, or keep it for the caller inside collect_format_warnings().
collect_format_warnings   the format warnings of the reads inside it (this thread), for ingest to name per file.

Why these limits: a Motion keeps positions and angles in float32, whose resolution is 1 cm at 1e7 cm, and the
forward kinematics takes sines of half angles in float32, accurate to 0.005 degrees at 1e5 degrees; beyond them a
value is a broken file (a fuzzed ``1e39``), not a capture. Why the plausibility checks: a real capture never drops
a bone's lines (all 343 CMU and HDM05 AMC files here have every bone with DOFs in every frame, but one cut off
inside its last frame) and writes unit directions (within 1e-6 here), so anything else is a damaged file that would
otherwise load as a rest pose or with bones folded onto one point.
"""
from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Callable, Iterator

import numpy as np

from ..errors import MocapFormatError, MocapFormatWarning
from ..motion import FPS_RANGE, fps_problem, rotations
from .text import number

__all__ = ["ANGLE_LIMIT_DEG", "DIRECTION_TOLERANCE", "DISTANCE_LIMIT_CM", "FPS_RANGE", "check_frame_rate",
           "check_limits", "checked_forward_kinematics", "collect_format_warnings", "complete_frames", "describe",
           "first_outside", "format_warning", "unit_directions"]

ANGLE_LIMIT_DEG = 1e5
DISTANCE_LIMIT_CM = 1e7
DIRECTION_TOLERANCE = 0.05
FIGURE_UNITS = (  # (name, centimetres per unit, smallest and largest size of a person in that unit)
    ("metres", 100.0, 0.5, 3.0),
    ("millimetres", 0.1, 500.0, 3000.0),
    ("centimetres", 1.0, 90.0, 300.0),
    ("inches", 2.54, 35.0, 90.0),  # the textbook BVH example (66 units), PyMO's sample (60)
    ("CMU units of 0.45 inch", 2.54 / 0.45, 15.0, 35.0),  # the cgspeed BVH conversions of CMU (26 units)
)


def numbered(names) -> tuple[str, ...]:
    """Names made unique, in order: the second ``a`` is ``a#2``, the third ``a#3`` (C3D labels, FBX node names).

    Examples
    --------
    >>> numbered(["LFHD", "C7", "LFHD", "LFHD"])
    ('LFHD', 'C7', 'LFHD#2', 'LFHD#3')
    """
    seen: dict[str, int] = {}
    out = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        out.append(name if seen[name] == 1 else f"{name}#{seen[name]}")
    return tuple(out)


def figure_unit(size: float) -> tuple[float, str | None]:
    """The length unit of a file that does not state one, from its figure's size: the first of
    :data:`FIGURE_UNITS` in whose range of a person's size it lies, else centimetres.

    The size is the largest extent of the figure's joints within one frame (its height standing, its arm span in a
    T pose): 100 to 190 cm for the adults of the archives here. Metres, millimetres and centimetres are taken
    silently; inches, CMU's units and a size that is no person's in any unit come with a sentence to say
    (a :class:`~mocapviz.errors.MocapFormatWarning`), naming the size and ``scale=`` to override.

    Parameters
    ----------
    size : float
        The figure's size in file units.

    Returns
    -------
    (float, str or None)
        Centimetres per file unit, and the sentence to warn (None for m, mm and cm).

    Examples
    --------
    >>> figure_unit(1.7), figure_unit(170.0), figure_unit(1700.0)
    ((100.0, None), (1.0, None), (0.1, None))
    >>> cm, said = figure_unit(26.2)  # a cgspeed BVH of a CMU take
    >>> round(cm, 3), said
    (5.644, 'a figure 26.2 units tall: read as CMU units of 0.45 inch (148 cm); pass scale= (cm per unit) to override')
    >>> figure_unit(8.0)[1]
    'a figure 8 units tall is no person in m, mm, cm, inches or CMU units: read as cm; pass scale= if it is one'
    """
    for name, cm, low, high in FIGURE_UNITS:
        if low <= size <= high:
            return cm, (None if cm in (100.0, 1.0, 0.1) else
                        f"a figure {size:.3g} units tall: read as {name} ({size * cm:.0f} cm); pass scale= (cm per "
                        "unit) to override")
    return 1.0, (f"a figure {size:.3g} units tall is no person in m, mm, cm, inches or CMU units: read as cm; pass "
                 "scale= if it is one")
_UNBOUNDED = {"inf": np.inf, "-inf": -np.inf}  # the ASF specification's words for no limit
_collected: contextvars.ContextVar[list | None] = contextvars.ContextVar("mocapviz_format_warnings", default=None)
_BLOCK = 1 << 16  # joint-frames per forward-kinematics block: about 12 MB of temporaries


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


def unit_directions(directions, names, lines, path) -> np.ndarray:
    """ASF bone directions as unit vectors; each must have a length within 1 ± :data:`DIRECTION_TOLERANCE`.

    Parameters
    ----------
    directions : array_like [shape=(B, 3)]
        The ``direction`` of each bone, finite, as written.
    names : sequence of str [length B]
        The bones, for the message.
    lines : sequence of int [length B]
        The line of each ``direction``, for the message.
    path : str
        The ASF file, for the message.

    Returns
    -------
    np.ndarray [shape=(B, 3)]
        The directions divided by their lengths.

    Raises
    ------
    MocapFormatError
        The first direction of length zero, or further from 1 than the tolerance (the bone and its line named).

    Examples
    --------
    >>> unit_directions([[0.0, 2e-7, 1.0000004]], ["ltoes"], [40], "a.asf").round(6).tolist()
    [[0.0, 0.0, 1.0]]
    >>> unit_directions([[0.0, 0.0, 0.0]], ["ltoes"], [40], "a.asf")
    Traceback (most recent call last):
    mocapviz.errors.MocapFormatError: a.asf, line 40: bone 'ltoes': direction 0 0 0 has length 0, not 1 ± 0.05
    """
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    big = np.abs(d).max(axis=1, keepdims=True)  # scaled first, so that 1e300 does not overflow the norm
    scaled = np.divide(d, big, out=np.zeros_like(d), where=big > 0)
    length = np.linalg.norm(scaled, axis=1) * big[:, 0]
    bad = np.flatnonzero(~(np.abs(length - 1.0) <= DIRECTION_TOLERANCE))
    if bad.size:
        b = int(bad[0])
        raise MocapFormatError(path, f"bone {names[b]!r}: direction {' '.join(map(describe, d[b]))} has length "
                                     f"{describe(length[b])}, not 1 ± {DIRECTION_TOLERANCE:g}", lines[b])
    return scaled / np.linalg.norm(scaled, axis=1, keepdims=True)


def check_limits(tokens, path, line: int, limit: float, unit: str) -> list[float]:
    """The values of an ASF ``limits`` line (or of a continuation line): ``(min max)`` pairs of plain decimal numbers
    within ``±limit``, or ``inf`` / ``-inf`` (the ASF's no limit).

    Parameters
    ----------
    tokens : list of str
        The words after ``limits`` (all the words of a continuation line), parentheses included.
    path : str
        The ASF file, for the message.
    line : int
        Its line, for the message.
    limit : float
        The largest magnitude of a limit, in the file's angle unit (:data:`ANGLE_LIMIT_DEG` in degrees).
    unit : str
        That unit, for the message (``" degrees"``).

    Returns
    -------
    list of float
        The values, min and max of each pair in turn (``inf`` for no limit).

    Raises
    ------
    MocapFormatError
        A value that is no number (``nan``), not finite (``1e400``) or beyond ``±limit``, an odd number of values,
        or a pair whose min is above its max.

    Examples
    --------
    >>> check_limits(["(-160.0", "20.0)"], "a.asf", 30, 1e5, " degrees"), check_limits(["(-inf", "inf)"], "a.asf", 31,
    ...                                                                                  1e5, " degrees")
    ([-160.0, 20.0], [-inf, inf])
    >>> check_limits(["(nan", "20.0)"], "a.asf", 30, 1e5, " degrees")
    Traceback (most recent call last):
    mocapviz.errors.MocapFormatError: a.asf, line 30: limits: 'nan' is not a number (nor inf or -inf)
    """
    values = []
    for token in " ".join(tokens).replace("(", " ").replace(")", " ").split():
        v = _UNBOUNDED.get(token.lower(), number(token))
        if v is None:
            raise MocapFormatError(path, f"limits: {token!r} is not a number (nor inf or -inf)", line)
        if token.lower() not in _UNBOUNDED and not abs(v) <= limit:
            beyond = "out of range (not finite)" if np.isinf(v) else f"beyond ±{limit:g}{unit}"
            raise MocapFormatError(path, f"limits: {token} is {beyond}", line)
        values.append(v)
    if len(values) % 2:
        raise MocapFormatError(path, f"limits need (min max) pairs, got {len(values)} values", line)
    for lo, hi in zip(values[::2], values[1::2]):
        if lo > hi:
            raise MocapFormatError(path, f"limits ({describe(lo)} {describe(hi)}): the min is above the max", line)
    return values


def complete_frames(present: np.ndarray, required: np.ndarray, names, path,
                    frame_number: Callable[[int], str], frame_line: Callable[[int], int]) -> int:
    """How many frames of an AMC file to read: all of them when every frame has a line for every required bone, all
    but the last when only the last is incomplete (the file was cut off inside it: a
    :class:`~mocapviz.errors.MocapFormatWarning` names it), else a MocapFormatError.

    Parameters
    ----------
    present : np.ndarray [shape=(T, J)], bool
        Whether frame t has a line for joint j.
    required : np.ndarray [shape=(J,)], bool
        The joints that must have a line in every frame: the root and every bone with DOFs (a bone without DOFs
        has no values, and real files leave it out).
    names : sequence of str [length J]
        The joints, for messages.
    path : str
        The AMC file, for messages.
    frame_number, frame_line : callable
        The frame number of frame t as the file writes it (``"445"``), and the 1-based line of that number.

    Returns
    -------
    int
        The number of leading frames to read (T or T - 1).

    Raises
    ------
    MocapFormatError
        A frame with no bone lines, a bone with DOFs that no frame has a line for, a line missing from a frame
        other than the last, or a file whose only frame is incomplete; the frame and its line named.

    Examples
    --------
    >>> present = np.array([[True, True], [True, False], [True, True]])
    >>> complete_frames(present[[0, 2]], np.array([True, True]), ["root", "lfemur"], "a.amc", lambda t: str(t + 1),
    ...                 lambda t: 2 + 3 * t)
    2
    >>> complete_frames(present, np.array([True, True]), ["root", "lfemur"], "a.amc", lambda t: str(t + 1),
    ...                 lambda t: 2 + 3 * t)
    Traceback (most recent call last):
    mocapviz.errors.MocapFormatError: a.amc, line 5: frame 2 has no line for bone 'lfemur'
    """
    missing = ~present & required
    bad = missing.any(axis=1)
    n_frames = bad.shape[0]
    if not bad.any():
        return n_frames
    t = int(np.argmax(bad))
    b = int(np.argmax(missing[t]))
    where = f"frame {frame_number(t)}"
    if t == n_frames - 1 and n_frames > 1:
        format_warning(path, f"last frame {frame_number(t)} is incomplete (no line for bone {names[b]!r}: the file "
                             "ends inside it); dropped it", frame_line(t))
        return n_frames - 1
    if not present[t].any():
        reason = f"{where} has no bone lines"
    elif missing[:, b].all() and n_frames > 1:
        reason = f"no frame has a line for bone {names[b]!r} (the skeleton gives it values)"
    elif n_frames == 1:
        reason = f"{where}, the only one, has no line for bone {names[b]!r} (the file ends inside it?)"
    else:
        reason = f"{where} has no line for bone {names[b]!r}"
    raise MocapFormatError(path, reason, frame_line(t))


def format_warning(path, reason: str, line: int | None = None) -> None:
    """Warn :class:`~mocapviz.errors.MocapFormatWarning` (``"<path>, line <line>: <reason>"``) of a file read with a
    part left out; inside :func:`collect_format_warnings` (in this thread), keep it for the caller instead.

    Parameters
    ----------
    path : str
        The file.
    reason : str
        What was left out and why.
    line : int, optional
        The line, 1-based.
    """
    kept = _collected.get()
    if kept is None:
        warnings.warn(MocapFormatWarning(path, reason, line), stacklevel=3)
    else:
        kept.append((path, reason, line))


@contextlib.contextmanager
def collect_format_warnings() -> Iterator[list[tuple]]:
    """Keep the :func:`format_warning` of the reads inside the block (this thread or task only: ingest reads files
    on several threads, where ``warnings.catch_warnings`` would mix the files up) instead of warning.

    Yields
    ------
    list of tuple
        ``(path, reason, line)`` of each warning, filled in as they come (``MocapFormatWarning(*w)`` rebuilds one).

    Examples
    --------
    >>> with collect_format_warnings() as kept:
    ...     format_warning("a.amc", "last frame 9 is incomplete; dropped it", 40)
    >>> kept
    [('a.amc', 'last frame 9 is incomplete; dropped it', 40)]
    """
    kept: list[tuple] = []
    token = _collected.set(kept)
    try:
        yield kept
    finally:
        _collected.reset(token)
