"""C3D marker files (Vicon, Qualisys, Motion Analysis, ... exports): the trajectories of the labelled markers.

read_c3d      C3D file -> a marker Motion (markers as joints without a skeleton), read with ezc3d.

Conventions:

- The Motion's ``joint_names`` are the marker labels (POINT:LABELS, then LABELS2, ...), the Vicon subject prefix
  cut at the last ``:`` (``male:LFHD`` -> ``LFHD``); ``parents`` are all -1 and there are no rotations: a
  *marker Motion* (:func:`mocapviz.motion.markers.is_marker_motion`). :meth:`Motion.canonical` turns it into the
  24 canonical joints by the joint-centre estimates of :mod:`mocapviz.motion.markers`.
- Unlabelled points (labels starting with ``*``, as HDM05's ``*0 *1 *2``, or empty) are dropped: they are no
  marker of a set and need not be the same point from frame to frame. A label repeated in one file keeps its
  first point under its name; the later ones are named ``LABEL#2``, ``LABEL#3``, ... Model outputs stored as
  points (Plug-in Gait angles, forces, moments, powers: the labels listed in POINT:ANGLES, FORCES, MOMENTS,
  POWERS, REACTIONS, SCALARS) are no markers and are dropped too.
- Gaps: a sample whose residual is negative (the C3D "invalid" flag, which ezc3d reads as NaN) or whose three
  coordinates are exactly 0 is NaN; :func:`mocapviz.motion.markers.marker_gaps` gives the share of gap frames
  per marker.
- Units: POINT:UNITS ``mm`` (also when absent or empty), ``cm`` or ``m``, one for all points or one per point (as
  Optotrak writes it); the Motion is in centimetres.
- Up axis: the Motion is y up, right-handed. POINT:X_SCREEN and POINT:Y_SCREEN (``+X``, ``-Z``, ...) say which
  file axes point right and up on screen; the file's Y_SCREEN axis becomes y, its X_SCREEN axis x. Without them
  (``up="auto"``) the file axis (y or z) along which the markers spread most in a frame (median over frames: a
  standing body is taller than wide) is up, positive upwards. ``up="y"`` / ``up="z"`` override.
- Frame rate: POINT:RATE (the header's rate when absent), 1 to 10,000 fps; positions within ±1e7 cm
  (:mod:`mocapviz.io.checks`).
- Damaged files: before ezc3d sees a file, :func:`mocapviz.io.c3d_layout.check_layout` checks its header against its
  parameters (points, frames, rates, scale, analog samples, data block, the file's size) and refuses a file that
  cannot be read right, naming the field and both values; ezc3d then reads in a helper process
  (:func:`mocapviz.io.isolated.read_isolated`), so that a crash inside it is a MocapFormatError, not the end of the
  calling process (an ingest, a Dask worker, the dashboard's server). A file that stops with a whole frame before
  the frames its header states loads the frames it holds, with a MocapFormatWarning naming both counts; a file of
  analog channels or rotations only is refused saying so.
- First frame: ``labels["first_frame"]`` is the header's first frame number as written (1 mostly; 0 for some
  writers; a take cut from a longer one keeps its number).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import MocapFormatError, ParameterError
from ..motion import Motion
from .c3d_layout import check_layout
from .checks import DISTANCE_LIMIT_CM, check_frame_rate, describe, first_outside, format_warning, numbered
from .isolated import read_isolated
from .marker_mapping import read_marker_mapping, relabel

_CM_PER_UNIT = {"mm": 0.1, "cm": 1.0, "m": 100.0}
_AXES = {"X": 0, "Y": 1, "Z": 2}
_MODEL_OUTPUTS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "REACTIONS", "SCALARS")  # POINT parameters listing non-markers
# ezc3d's read in its helper process (mocapviz.io.isolated): at most this memory (ezc3d needs 10 to 25 times the
# file's size: 45 MB for cmu_135_02's 3.4 MB) and this time (it reads about 30 MB/s here); a damaged file that passes
# the checks and still asks for more is refused instead of exhausting the machine's memory or hanging the caller
_MEMORY_FIXED, _MEMORY_PER_BYTE = 512 * 2**20, 64
_TIMEOUT_FIXED_S, _TIMEOUT_BYTES_PER_S = 60.0, 2**20


def read_c3d(path, up: str = "auto", marker_mapping=None) -> Motion:
    """Read the labelled marker trajectories of a C3D file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.c3d`` file.
    up : {"auto", "y", "z"}
        The file's up axis; "auto" reads POINT:Y_SCREEN, else the data (module docstring). The Motion is y up.
    marker_mapping : str, os.PathLike or dict, optional
        A mapping file (:mod:`mocapviz.io.marker_mapping`), or its dict: the file's labels (prefix cut) renamed onto
        a marker set's names, e.g. ``{"r asis": "RASI"}``.

    Returns
    -------
    Motion
        A marker Motion: ``joint_names`` the M marker labels (prefix cut, unlabelled points dropped, renamed by
        ``marker_mapping``), positions
        [shape=(T, M, 3)] float32 in cm, y up, NaN in gaps; ``parents`` all -1, no quaternions; ``fps`` from
        POINT:RATE; ``labels["first_frame"]``: the header's first frame number.

    Raises
    ------
    MocapFormatError
        Naming the file: a header and parameters that disagree or do not fit the file (naming the field and both
        values, :func:`mocapviz.io.c3d_layout.check_layout`), a file without marker trajectories (saying what it
        holds: ``analog data only``, ``rotations only``), ezc3d crashing, hanging or failing on it (the signal,
        or the reason ezc3d gives), no labelled points, unknown POINT:UNITS, a frame rate outside 1 to 10,000 fps,
        or a coordinate beyond ±1e7 cm or infinite (naming the frame and marker).
    ParameterError
        A bad ``up``; a ``marker_mapping`` giving two markers one name.

    Warns
    -----
    MocapFormatWarning
        A frame rate of 0 (or none) in the header or in POINT:RATE, the other one used; a file that ends with a whole
        frame before the frames its header states (naming both counts), the frames it holds read.

    References
    ----------
    .. [1] C3D.ORG, "The C3D File Format: A Technical User Guide" (2008-2021): header, POINT group, residuals.

    Examples
    --------
    >>> from mocapviz.io import datasets
    >>> m = read_c3d(datasets.fetch("c3d-markers") / "cmu_07_01.c3d")  # doctest: +SKIP
    >>> m.n_frames, m.fps, m.joint_names[:3]  # doctest: +SKIP
    (316, 120.0, ('LFIN', 'LFWT', 'LWRB'))
    """
    if up not in ("auto", "y", "z"):
        raise ParameterError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    if marker_mapping is not None and not isinstance(marker_mapping, dict):
        marker_mapping = read_marker_mapping(marker_mapping)
    path = os.fspath(path)
    layout = check_layout(path)
    for note in layout.notes:
        format_warning(path, note)
    size = os.path.getsize(path)
    point, xyz, header = read_isolated(_ezc3d_points, path, reader="the C3D reader (ezc3d)", preload=("ezc3d",),
                                       memory=_MEMORY_FIXED + _MEMORY_PER_BYTE * size,
                                       timeout=_TIMEOUT_FIXED_S + size / _TIMEOUT_BYTES_PER_S)  # fmt: skip
    xyz = xyz.astype(np.float64)  # (3, P, T)
    fps = _rate(point, header, path)
    cm = _units(point, xyz.shape[1], path)
    names, keep = _labels(point, xyz.shape[1])
    names = relabel(names, marker_mapping, path) if marker_mapping else names
    if xyz.shape[2] == 0:
        raise MocapFormatError(path, "no frames of point data")
    if not keep:
        raise MocapFormatError(path, f"no labelled points (of {xyz.shape[1]} points)")
    pos = (xyz * cm[None, :, None])[:, keep].transpose(2, 1, 0)  # (T, M, 3)
    pos[(pos == 0).all(axis=2)] = np.nan
    bad = first_outside(np.where(np.isnan(pos), 0.0, pos).reshape(len(pos), -1), DISTANCE_LIMIT_CM)
    if bad is not None:
        t, k = bad
        raise MocapFormatError(path, f"frame {t}: marker {names[k // 3]!r} at {describe(pos[t, k // 3, k % 3])} cm, "
                                     f"beyond ±{DISTANCE_LIMIT_CM:g} cm or not finite")  # fmt: skip
    turn = _turn(point, pos, up, path)
    return Motion(positions=(pos @ turn.T).astype(np.float32), fps=fps, joint_names=names,
                  parents=np.full(len(names), -1), source=path, labels={"first_frame": layout.first_frame})


def _units(point: dict, n_points: int, path) -> np.ndarray:
    """Centimetres per file unit of each point [shape=(P,)]: POINT:UNITS one for all (``mm`` when absent or empty)
    or one per point."""
    units = [str(v).strip() for v in point.get("UNITS", {}).get("value", [])] or ["mm"]
    if len(units) != 1 and len(units) < n_points:
        raise MocapFormatError(path, f"POINT:UNITS holds {len(units)} units for {n_points} points (one for all, or "
                                     "one per point)")  # fmt: skip
    cm = [_CM_PER_UNIT.get((u or "mm").lower()) for u in units[:n_points]]
    if None in cm:
        raise MocapFormatError(path, f"POINT:UNITS {units[cm.index(None)]!r} is not one of mm, cm, m")
    return np.resize(np.array(cm, dtype=np.float64), n_points)


def _ezc3d_points(path: str) -> tuple[dict, np.ndarray, dict]:
    """(the POINT parameters, the coordinates [shape=(3, P, T)] in the file's unit, the header's points section) as
    ezc3d reads them: what runs in the helper process. The coordinates are float32 when that holds them
    exactly (a file of floats: half the bytes to send back), else float64 (integers times the scale)."""
    import ezc3d

    c3d = ezc3d.c3d(path)
    xyz = np.asarray(c3d["data"]["points"][:3], dtype=np.float64)
    single = xyz.astype(np.float32)
    return c3d["parameters"]["POINT"], single if np.array_equal(single, xyz, equal_nan=True) else xyz, \
        c3d["header"]["points"]


def _text(group: dict, name: str, default: str) -> str:
    value = group.get(name, {}).get("value", [])
    return str(value[0]).strip() if len(value) else default


def _rate(point: dict, header: dict, path) -> float:
    value = point.get("RATE", {}).get("value", [])
    try:
        fps = float(value[0]) if len(value) else float(header["frame_rate"])
    except (TypeError, ValueError):
        raise MocapFormatError(path, f"POINT:RATE {value!r} is not a number") from None
    return check_frame_rate(fps, path, None, f"POINT:RATE {describe(fps)}")


def _labels(point: dict, n_points: int) -> tuple[tuple, list]:
    """(marker names, indices of the labelled points): LABELS, LABELS2, ... prefix cut, unlabelled points and model
    outputs dropped, repeated names numbered."""
    raw = []
    for k in range(1, 100):
        group = point.get("LABELS" if k == 1 else f"LABELS{k}")
        if group is None:
            break
        raw += [str(v) for v in group.get("value", [])]
    outputs = {str(v).strip() for group in _MODEL_OUTPUTS for v in point.get(group, {}).get("value", [])}
    names, keep = [], []
    for i, label in enumerate(raw[:n_points]):
        name = label.strip().rsplit(":", 1)[-1].strip()
        if not name or name.startswith("*") or label.strip() in outputs:
            continue
        names.append(name)
        keep.append(i)
    return numbered(names), keep


def _turn(point: dict, pos: np.ndarray, up: str, path) -> np.ndarray:
    """The rotation [shape=(3, 3)] from the file's axes to x right, y up (right-handed)."""
    screen = [_text(point, "X_SCREEN", ""), _text(point, "Y_SCREEN", "")]
    if up == "auto" and all(len(s) == 2 and s[0] in "+-" and s[1].upper() in _AXES for s in screen):
        axes = [(_AXES[s[1].upper()], 1.0 if s[0] == "+" else -1.0) for s in screen]
        if axes[0][0] == axes[1][0]:
            raise MocapFormatError(path, f"POINT:X_SCREEN {screen[0]!r} and Y_SCREEN {screen[1]!r} name one axis")
    else:
        if up == "auto":
            spread = _spread(pos)
            up = "z" if spread[2] > spread[1] else "y"
        axes = [(0, 1.0), (_AXES[up.upper()], 1.0)]
    turn = np.zeros((3, 3))
    for row, (axis, sign) in enumerate(axes):
        turn[row, axis] = sign
    turn[2] = np.cross(turn[0], turn[1])
    return turn


def _spread(pos: np.ndarray) -> np.ndarray:
    """Median over frames of the markers' extent along each file axis [shape=(3,)] (frames with two markers or more)."""
    seen = np.isfinite(pos).all(axis=2, keepdims=True)
    frames = seen[:, :, 0].sum(axis=1) >= 2
    if not frames.any():
        return np.zeros(3)
    high = np.where(seen, pos, -np.inf)[frames].max(axis=1)
    low = np.where(seen, pos, np.inf)[frames].min(axis=1)
    return np.median(high - low, axis=0)
