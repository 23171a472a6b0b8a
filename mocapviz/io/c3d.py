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
- Units: POINT:UNITS ``mm`` (also when absent), ``cm`` or ``m``; the Motion is in centimetres.
- Up axis: the Motion is y up, right-handed. POINT:X_SCREEN and POINT:Y_SCREEN (``+X``, ``-Z``, ...) say which
  file axes point right and up on screen; the file's Y_SCREEN axis becomes y, its X_SCREEN axis x. Without them
  (``up="auto"``) the file axis (y or z) along which the markers spread most in a frame (median over frames: a
  standing body is taller than wide) is up, positive upwards. ``up="y"`` / ``up="z"`` override.
- Frame rate: POINT:RATE (the header's rate when absent), 1 to 10,000 fps; positions within ±1e7 cm
  (:mod:`mocapviz.io.checks`).
"""
from __future__ import annotations

import os
import struct

import numpy as np

from ..errors import MocapFormatError, ParameterError
from ..motion import Motion
from .checks import DISTANCE_LIMIT_CM, check_frame_rate, describe, first_outside

_CM_PER_UNIT = {"mm": 0.1, "cm": 1.0, "m": 100.0}
_AXES = {"X": 0, "Y": 1, "Z": 2}
_MODEL_OUTPUTS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "REACTIONS", "SCALARS")  # POINT parameters listing non-markers


def read_c3d(path, up: str = "auto") -> Motion:
    """Read the labelled marker trajectories of a C3D file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.c3d`` file.
    up : {"auto", "y", "z"}
        The file's up axis; "auto" reads POINT:Y_SCREEN, else the data (module docstring). The Motion is y up.

    Returns
    -------
    Motion
        A marker Motion: ``joint_names`` the M marker labels (prefix cut, unlabelled points dropped), positions
        [shape=(T, M, 3)] float32 in cm, y up, NaN in gaps; ``parents`` all -1, no quaternions; ``fps`` from
        POINT:RATE; ``labels["first_frame"]``: the header's first frame number.

    Raises
    ------
    MocapFormatError
        Not a readable C3D file (the reason ezc3d gives), no labelled points, unknown POINT:UNITS, a frame rate
        outside 1 to 10,000 fps, or a coordinate beyond ±1e7 cm or infinite (naming the frame and marker).
    ParameterError
        A bad ``up``.

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
    path = os.fspath(path)
    _check_structure(path)
    import ezc3d

    try:
        c3d = ezc3d.c3d(path)
        point = c3d["parameters"]["POINT"]
        xyz = np.asarray(c3d["data"]["points"][:3], dtype=np.float64)  # (3, P, T)
        header = c3d["header"]["points"]
    except Exception as exc:  # noqa: BLE001 - ezc3d raises plain RuntimeError/IndexError/... on a damaged file
        raise MocapFormatError(path, f"not a readable C3D file ({type(exc).__name__}: {exc})") from None
    fps = _rate(point, header, path)
    cm = _CM_PER_UNIT.get(_text(point, "UNITS", "mm").lower())
    if cm is None:
        raise MocapFormatError(path, f"POINT:UNITS {_text(point, 'UNITS', '')!r} is not one of mm, cm, m")
    names, keep = _labels(point, xyz.shape[1])
    if xyz.shape[2] == 0:
        raise MocapFormatError(path, "no frames of point data")
    if not keep:
        raise MocapFormatError(path, f"no labelled points (of {xyz.shape[1]} points)")
    pos = xyz[:, keep].transpose(2, 1, 0) * cm  # (T, M, 3)
    pos[(pos == 0).all(axis=2)] = np.nan
    bad = first_outside(np.where(np.isnan(pos), 0.0, pos).reshape(len(pos), -1), DISTANCE_LIMIT_CM)
    if bad is not None:
        t, k = bad
        raise MocapFormatError(path, f"frame {t}: marker {names[k // 3]!r} at {describe(pos[t, k // 3, k % 3])} cm, "
                                     f"beyond ±{DISTANCE_LIMIT_CM:g} cm or not finite")  # fmt: skip
    turn = _turn(point, pos, up, path)
    return Motion(positions=(pos @ turn.T).astype(np.float32), fps=fps, joint_names=names,
                  parents=np.full(len(names), -1), source=path, labels={"first_frame": int(header["first_frame"]) + 1})


_BLOCK = 512
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)


def _check_structure(path) -> None:
    """Refuse, with a MocapFormatError, a file whose header or parameter section is not laid out as the C3D
    format says, or whose point data would end beyond the file: what ezc3d reads without checking (a damaged
    parameter entry can crash it)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise MocapFormatError(path, f"cannot read the file ({exc.strerror or exc})") from None
    if len(data) < 2 * _BLOCK or data[1] != 0x50 or data[0] < 2:
        raise MocapFormatError(path, "not a C3D file (no C3D header: byte 2 must be 0x50, the first word must point "
                                     "to the parameter section)")  # fmt: skip
    start = (data[0] - 1) * _BLOCK
    if start + 4 > len(data) or data[start + 3] not in _PROCESSORS:
        raise MocapFormatError(path, f"parameter section at byte {start}: no processor type 84, 85 or 86")
    order = _PROCESSORS[data[start + 3]]
    params = _check_parameters(path, data, start + 4, min(len(data), start + max(1, data[start + 2]) * _BLOCK), order)
    points, analog, first, last = struct.unpack_from(order + "HHHH", data, 2)
    _check_analog(path, data, params, analog, order)
    scale, (block,) = data[12:16], struct.unpack_from(order + "H", data, 16)
    negative = (scale[1] if data[start + 3] == 85 else scale[3 if order == "<" else 0]) & 0x80
    frames = last - first + 1 if last >= first else 0
    need = (block - 1) * _BLOCK + frames * (4 * points + analog) * (4 if negative else 2)
    if block < 2 or need > len(data):
        raise MocapFormatError(path, f"truncated or damaged: {frames} frames of {points} points from block {block} "
                                     f"need {need} bytes, the file has {len(data)}")  # fmt: skip


def _check_parameters(path, data: bytes, at: int, end: int, order: str) -> dict:
    """Walk the parameter entries from byte ``at`` to ``end``: each one inside the section and linking to the byte
    after its own data (as ezc3d requires, which reads the data first), valid types and dimensions, groups
    numbered 1 to N and defined once, every parameter in one of them.

    Returns {(GROUP, NAME): (data type, dimensions, offset of the data)}."""
    groups, params = {}, {}

    def fail(why: str):
        raise MocapFormatError(path, f"parameter section: the entry at byte {at} {why}")

    while at + 2 <= end:
        chars, group = struct.unpack_from("bb", data, at)
        if chars == 0 or group == 0:
            break
        link = at + 2 + abs(chars)
        if link + 3 > end:
            fail("runs past the section's end")
        name = data[at + 2 : link].decode("latin-1").strip().upper()
        step = struct.unpack_from(order + "h", data, link)[0]
        described = link + 2
        if group < 0:
            if -group in groups:
                fail(f"defines group {-group} a second time")
            groups[-group] = name
        else:
            kind, dims = struct.unpack_from("bB", data, link + 2) if link + 4 <= end else (0, 0)
            if kind not in (-1, 1, 2, 4) or dims > 7:
                fail(f"has data type {kind} and {dims} dimensions (C3D: type -1, 1, 2 or 4, at most 7 dimensions)")
            shape = tuple(data[link + 4 : link + 4 + dims])
            params[(group, name)] = (kind, shape, link + 4 + dims)
            described = link + 4 + dims + abs(kind) * int(np.prod(shape, dtype=np.int64))
        if described >= end or described + 1 + data[described] > end:
            fail("holds more than the section")
        if step == 0:
            break
        if link + step != described + 1 + data[described]:
            fail(f"links to byte {link + step}, not to the end of its own data at byte {described + 1 + data[described]}")
        at = link + step
    used = {g for g, _ in params}
    if used - set(groups) or set(groups) != set(range(1, len(groups) + 1)):
        raise MocapFormatError(path, f"parameter section: groups {sorted(groups)} defined, parameters in groups "
                                     f"{sorted(used)} (C3D writers number the groups 1, 2, 3, ...)")  # fmt: skip
    return {(groups[g], name): value for (g, name), value in params.items()}


def _check_analog(path, data: bytes, params: dict, analog: int, order: str) -> None:
    """Analog samples in the data need ANALOG:USED channels (dividing the header's samples per frame), with a
    SCALE and an OFFSET each: ezc3d indexes them without checking."""
    if analog == 0:
        return
    kind, shape, offset = params.get(("ANALOG", "USED"), (0, (), 0))
    channels = struct.unpack_from(order + "h", data, offset)[0] if kind == 2 and not shape else 0
    counts = {n: int(np.prod(params[("ANALOG", n)][1], dtype=np.int64)) if ("ANALOG", n) in params else 0
              for n in ("SCALE", "OFFSET")}  # fmt: skip
    if channels <= 0 or analog % channels or min(counts.values()) < channels:
        raise MocapFormatError(path, f"{analog} analog samples per frame but ANALOG:USED {channels} channels with "
                                     f"{counts['SCALE']} SCALE and {counts['OFFSET']} OFFSET values")  # fmt: skip

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
    names, keep, seen = [], [], {}
    for i, label in enumerate(raw[:n_points]):
        name = label.strip().rsplit(":", 1)[-1].strip()
        if not name or name.startswith("*") or label.strip() in outputs:
            continue
        seen[name] = seen.get(name, 0) + 1
        names.append(name if seen[name] == 1 else f"{name}#{seen[name]}")
        keep.append(i)
    return tuple(names), keep


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
