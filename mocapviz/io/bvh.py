"""Biovision BVH motions (any rig: CMU conversions, Bandai Namco, MotionBuilder exports, ...).

read_bvh      BVH file -> Motion (positions by forward kinematics, local quaternions).

Conventions:

- Each joint has 0 to 6 channels, ``Xposition Yposition Zposition`` and ``Xrotation Yrotation Zrotation``
  in any order. Rotation channels ``c1 c2 c3`` compose as ``R = R_c1 R_c2 R_c3`` (read left to right).
- A position channel replaces that component of the joint's OFFSET (the MotionBuilder convention; files
  whose root OFFSET is zero read the same under the other convention).
- ``End Site`` blocks become joints named ``<parent>_end``, without channels.
- Units: guessed from the figure's size in the first frame (:func:`mocapviz.io.checks.figure_unit`): metres,
  millimetres, centimetres, inches or CMU's 0.45-inch units (the cgspeed conversions of CMU), the last two and a
  size that is no person's with a :class:`~mocapviz.errors.MocapFormatWarning`; pass ``scale`` (centimetres per
  file unit) to override.
- Up axis: y; with ``up="auto"`` (default) a file whose figure stands along z (head above hips on z) is
  turned to y up, keeping it right-handed; ``up="z"`` forces the conversion, ``up="y"`` prevents it. "auto" looks
  at the rest pose (the OFFSETs chained, every rotation zero) when its head is clearly above its root along y or z
  (that component at least twice each other's), else at the motion (the mean head - root vector), so that a figure
  lying on the floor throughout a y-up file is not taken for one standing in a z-up file.
- Comments: lines inside HIERARCHY whose first word starts with ``#`` are skipped (an export's note of its source,
  :mod:`mocapviz.io.bvh_writer`).
- Text: keywords (``HIERARCHY``, ``ROOT``, ``JOINT``, ``End Site``, ``OFFSET``, ``CHANNELS``, ``MOTION``,
  ``Frames:``, ``Frame Time:``) and channel names in any case; words separated by any ASCII white space (space,
  tab, vertical tab, form feed, CR); lines end with LF or CR LF. UTF-8 (with or without a byte-order mark), else
  Latin-1 (joint names).
- Values: numbers in plain decimal notation (no ``nan``, ``inf``); frame rate 1 to 10,000 fps; rotation channels
  within ±1e5 degrees; offsets and position channels within ±1e7 file units and positions within ±1e7 cm
  (:mod:`mocapviz.io.checks`).
- Frame count: a ``Frames:`` line off by at most :data:`FRAMES_SLACK` rows (a common exporter slip) loads the rows
  the file holds, with a :class:`~mocapviz.errors.MocapFormatWarning` naming both counts; a larger difference (a
  truncated or damaged file) is refused.
"""
from __future__ import annotations

import functools
import os
import re
import warnings

import numpy as np

from ..errors import MocapFormatError, MocapFormatWarning, ParameterError
from ..motion import Motion, rotations
from .checks import (
    ANGLE_LIMIT_DEG,
    DISTANCE_LIMIT_CM,
    check_frame_rate,
    checked_forward_kinematics,
    describe,
    figure_unit,
    first_outside,
    format_warning,
)
from .text import decode, number, read_bytes, scan, words

FRAMES_SLACK = 3
"""Rows a BVH file may hold more or fewer than its ``Frames:`` line says and still load (with a warning)."""
_MOTION = re.compile(rb"(?im)^[ \t\r\v\f]*motion(?=[ \t\r\v\f\n]|\Z)")  # as _parse_hierarchy's words see it
_CACHED_TEXT = 1 << 16  # hierarchies up to this size are parsed once per process (the files of one rig share one)

_CHANNELS = {
    "xposition": ("t", 0), "yposition": ("t", 1), "zposition": ("t", 2),
    "xrotation": ("r", "x"), "yrotation": ("r", "y"), "zrotation": ("r", "z"),
}  # fmt: skip


class _Hierarchy:
    """The HIERARCHY section: joints in file order (parents first), offsets, channels.

    After :meth:`layout`, also where each channel of a frame line goes: ``euler_slot`` (flat index into
    the (J, 3) Euler angles, each joint's angles in application order) or ``translation_slot`` (flat index
    into the (J, 3) translations), -1 where the channel is of the other kind.
    """

    def __init__(self):
        self.names: list[str] = []
        self.known: set[str] = set()
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.channels: list[list[str]] = []

    def layout(self) -> _Hierarchy:
        euler_slot, translation_slot, orders = [], [], []
        self.channel_names = [f"{self.names[j]} {c.capitalize()}" for j, chans in enumerate(self.channels) for c in chans]
        for j, chans in enumerate(self.channels):
            # R = R_c1 R_c2 R_c3: the last rotation channel is applied first
            rot = [_CHANNELS[c][1] for c in chans if _CHANNELS[c][0] == "r"][::-1]
            orders.append("".join(rot))
            seen = 0
            for c in chans:
                kind, axis = _CHANNELS[c]
                if kind == "t":
                    translation_slot.append(3 * j + axis)
                    euler_slot.append(-1)
                else:
                    euler_slot.append(3 * j + len(rot) - 1 - seen)
                    translation_slot.append(-1)
                    seen += 1
        self.orders = tuple(orders)
        self.euler_slot = np.array(euler_slot, dtype=np.int64)
        self.translation_slot = np.array(translation_slot, dtype=np.int64)
        self.offsets = np.array(self.offsets, dtype=np.float64).reshape(-1, 3)
        self.parents = np.array(self.parents, dtype=np.int64)
        return self


def _hierarchy(text: str) -> _Hierarchy:
    """The HIERARCHY text before MOTION, parsed (once per distinct text when it is short)."""
    return _cached_hierarchy(text) if len(text) <= _CACHED_TEXT else _parse_text(text)


@functools.lru_cache(maxsize=128)
def _cached_hierarchy(text: str) -> _Hierarchy:
    return _parse_text(text)


def _parse_text(text: str) -> _Hierarchy:
    lines = text.split("\n")
    h, at = _parse_hierarchy(lines + ["MOTION"], None)
    if at != len(lines):  # (cannot happen: _MOTION and words() split alike; a guard, not a silent misread)
        raise MocapFormatError(None, "a second MOTION keyword inside HIERARCHY", at + 1)
    return h.layout()


def _parse_hierarchy(lines: list[str], path) -> tuple[_Hierarchy, int]:
    """Parse HIERARCHY; return it and the index of the MOTION line."""
    h = _Hierarchy()
    stack: list[int] = []
    pending = None  # joint declared, waiting for its '{'
    i = 0
    first = next((k for k, line in enumerate(lines) if words(line)), None)
    if first is None or [w.upper() for w in words(lines[first])] != ["HIERARCHY"]:
        raise MocapFormatError(path, "file does not start with HIERARCHY (not a BVH file?)", (first or 0) + 1)
    for i in range(first + 1, len(lines)):
        tok = words(lines[i])
        ln = i + 1
        if not tok or tok[0].startswith("#"):  # a blank or a comment line (mocapviz exports name their source so)
            continue
        key = tok[0].upper() if tok[0].isascii() else tok[0]  # ("motıon".upper() is "MOTION")
        if key in ("ROOT", "JOINT"):
            if (key == "ROOT") != (not stack):
                raise MocapFormatError(path, f"{tok[0]} at the wrong nesting level", ln)
            if len(tok) < 2:
                raise MocapFormatError(path, f"{tok[0]} without a name", ln)
            name = " ".join(tok[1:])
            if name in h.known:
                raise MocapFormatError(path, f"joint {name!r} defined twice", ln)
            pending = (name, stack[-1] if stack else -1)
        elif key == "END":
            if not stack:
                raise MocapFormatError(path, "End Site outside a joint", ln)
            name = f"{h.names[stack[-1]]}_end"
            k = 2
            while name in h.known:  # several End Sites under one joint
                name = f"{h.names[stack[-1]]}_end{k}"
                k += 1
            pending = (name, stack[-1])
        elif key == "{":
            if pending is None:
                raise MocapFormatError(path, "'{' without a joint", ln)
            h.names.append(pending[0])
            h.known.add(pending[0])
            h.parents.append(pending[1])
            h.offsets.append(None)
            h.channels.append([])
            stack.append(len(h.names) - 1)
            pending = None
        elif key == "}":
            if not stack:
                raise MocapFormatError(path, "unbalanced '}'", ln)
            j = stack.pop()
            if h.offsets[j] is None:
                raise MocapFormatError(path, f"joint {h.names[j]!r} has no OFFSET", ln)
        elif key == "OFFSET":
            if not stack:
                raise MocapFormatError(path, "OFFSET outside a joint", ln)
            off = [number(t) for t in tok[1:]]
            if len(off) != 3 or None in off:
                raise MocapFormatError(path, f"OFFSET needs three numbers, got {' '.join(tok[1:])!r}", ln)
            if first_outside(np.array(off), DISTANCE_LIMIT_CM) is not None:
                raise MocapFormatError(path, f"OFFSET {' '.join(tok[1:])} is beyond ±{DISTANCE_LIMIT_CM:g}", ln)
            h.offsets[stack[-1]] = off
        elif key == "CHANNELS":
            if not stack:
                raise MocapFormatError(path, "CHANNELS outside a joint", ln)
            if len(tok) < 2 or not tok[1].isascii() or not tok[1].isdigit():
                raise MocapFormatError(path, "CHANNELS needs a count", ln)
            n = int(tok[1])
            chans = [t.lower() for t in tok[2:]]
            if n != len(chans):
                raise MocapFormatError(path, f"CHANNELS says {n} but lists {len(chans)}", ln)
            bad = [c for c in chans if c not in _CHANNELS]
            if bad or len(set(chans)) != len(chans) or n > 6:
                raise MocapFormatError(path, f"unsupported channels {' '.join(tok[2:])!r}", ln)
            h.channels[stack[-1]] = chans
        elif key == "MOTION":
            if stack:
                raise MocapFormatError(path, "MOTION inside an open joint block (missing '}')", ln)
            if not h.names:
                raise MocapFormatError(path, "no joints in HIERARCHY", ln)
            return h, i
        else:
            raise MocapFormatError(path, f"unexpected {tok[0]!r} in HIERARCHY", ln)
    raise MocapFormatError(path, "no MOTION section (truncated file?)", len(lines))


def _motion_header(raw: bytes, pos: int, line: int, path) -> tuple[int, float, int, int]:
    """Parse ``Frames:`` and ``Frame Time:`` after the MOTION line.

    Parameters
    ----------
    raw : bytes -- the file.
    pos, line : byte offset and 1-based number of the MOTION line.

    Returns
    -------
    Frame count, frame time (s), byte offset and 1-based line number of the first line after the header.
    """
    values = {}
    for key in ("frames", "frame time"):
        while True:  # to the next line that is not blank
            end = raw.find(b"\n", pos)
            if end < 0:
                raise MocapFormatError(path, f"missing '{key.title()}:' line (truncated file?)", line)
            pos, line = end + 1, line + 1
            nl = raw.find(b"\n", pos)
            text = raw[pos : len(raw) if nl < 0 else nl].decode("latin-1")
            if words(text):
                break
        head, colon, rest = text.partition(":")
        if not colon or " ".join(words(head)).lower() != key:
            shown = text.strip(" \t\r\v\f")[:60]
            raise MocapFormatError(path, f"expected '{key.title()}:', got {shown!r}", line)
        value = number(rest.strip(" \t\r\v\f"))
        if value is None:
            raise MocapFormatError(path, f"'{key.title()}:' needs a number, got {rest.strip()[:40]!r}", line)
        if key == "frames" and not (1 <= value <= 2**53 and value == int(value)):
            raise MocapFormatError(path, f"frame count must be a positive integer, got {rest.strip()[:40]}", line)
        if key == "frame time":
            if not (np.isfinite(value) and value > 0):
                raise MocapFormatError(path, f"Frame Time must be a positive number of seconds, got {describe(value)}",
                                       line)
            check_frame_rate(1.0 / value, path, line, f"Frame Time {describe(value)} s")
        values[key] = value
    end = raw.find(b"\n", pos)
    return int(values["frames"]), values["frame time"], len(raw) if end < 0 else end + 1, line + 1


def read_bvh(path, up: str = "auto", scale: float | None = None) -> Motion:
    """Read a BVH file and run forward kinematics.

    Parameters
    ----------
    path : str or os.PathLike
    up : {"auto", "y", "z"}
        Up axis of the file (see module docstring); the Motion is always y up.
    scale : float, optional
        Centimetres per file unit; default: guessed from the figure's height (m, cm or mm).

    Returns
    -------
    Motion
        All joints and end sites of the file in file order, positions (T, J, 3) in cm, y up, local
        quaternions (T, J, 4), ``euler`` (T, C): the file's rotation channel values in degrees, in file
        order; fps = 1 / Frame Time (rounded to an integer when within 0.01 %).

    Raises
    ------
    MocapFormatError
        Malformed HIERARCHY, unsupported channels, a frame count more than :data:`FRAMES_SLACK` rows away from
        the header's (closer: a MocapFormatWarning, the rows loaded), wrong number of
        values on a line, malformed or non-finite numbers, a frame rate outside 1 to 10,000 fps, values or
        positions beyond the limits of :mod:`mocapviz.io.checks`; the message names the file, the line and the
        value.
    ParameterError
        A bad ``up`` or ``scale``.
    """
    path = os.fspath(path)
    if up not in ("auto", "y", "z"):
        raise ParameterError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    if scale is not None and not (isinstance(scale, (int, float, np.number)) and 0 < scale < float("inf")):
        raise ParameterError(f"scale (centimetres per file unit) must be a positive number, got {scale!r}")
    raw = read_bytes(path)
    found = _MOTION.search(raw)
    if found is None:
        _parse_hierarchy(decode(raw).split("\n"), path)  # raises, naming the problem
        raise MocapFormatError(path, "no MOTION line")  # (not reached: without MOTION the parse raises)
    mpos = raw.rfind(b"\n", 0, found.start()) + 1  # the start of the MOTION line
    try:
        h = _hierarchy(decode(raw[:mpos]))
    except MocapFormatError as exc:
        raise MocapFormatError(path, exc.reason, exc.line) from None
    motion_line = raw.count(b"\n", 0, mpos) + 1
    n_frames, frame_time, start, data_line = _motion_header(raw, mpos, motion_line, path)
    sc = scan(raw, path, first_line=data_line, start=start)

    n_channels = len(h.euler_slot)
    named = np.flatnonzero(sc.name_start >= 0)
    if named.size:
        raise MocapFormatError(path, f"unexpected text {sc.token(named[0])!r} in MOTION data", sc.first_line + int(named[0]))
    data = np.flatnonzero(sc.n_values > 0)
    wrong = np.flatnonzero(sc.n_values[data] != n_channels)
    if wrong.size:
        k = data[wrong[0]]
        raise MocapFormatError(
            path, f"frame line has {sc.n_values[k]} values, the hierarchy has {n_channels} channels", sc.first_line + int(k)
        )
    if data.size and data.size != n_frames and abs(data.size - n_frames) <= FRAMES_SLACK:  # an exporter's slip
        where = sc.first_line + int(data[min(n_frames, data.size - 1)])
        warnings.warn(MocapFormatWarning(path, f"header says {n_frames} frames, the file has {data.size}: loaded the "
                                               f"{data.size} it has", line=where), stacklevel=2)  # fmt: skip
        n_frames = int(data.size)
    if data.size > n_frames:  # named at the first frame line beyond the header's count
        raise MocapFormatError(path, f"header says {n_frames} frames, the file has {data.size}",
                               sc.first_line + int(data[n_frames]))
    if data.size < n_frames:  # named at the file's last line (a file of N lines has no line N + 1)
        last = raw.count(b"\n") + (not raw.endswith(b"\n"))
        raise MocapFormatError(path, f"header says {n_frames} frames, the file has {data.size}: it ends at line "
                                     f"{last}", last)
    if data.size and data[-1] - data[0] + 1 != data.size:
        gap = int(data[np.argmax(np.diff(data) > 1)] + 1)
        raise MocapFormatError(path, "blank line inside the frame data", sc.first_line + gap)
    values = sc.values.reshape(n_frames, n_channels)
    first_frame_line = sc.first_line + (int(data[0]) if data.size else 0)
    del sc, data, raw, found  # (only ``values`` is needed from here on)

    # limits per channel: rotations in degrees, positions in file units
    rot = h.euler_slot >= 0
    limit = np.where(rot, ANGLE_LIMIT_DEG, DISTANCE_LIMIT_CM)
    n_joints = len(h.names)
    euler_out = np.empty((n_frames, int(rot.sum())), dtype=np.float32)

    def block(a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        v = values[a:b]
        bad = first_outside(v, limit)
        if bad is not None:
            t, c = bad
            unit = "degrees" if rot[c] else "file units"
            raise MocapFormatError(path, f"channel {h.channel_names[c]} = {describe(v[t, c])} is beyond "
                                         f"±{limit[c]:g} {unit}", first_frame_line + a + t)
        translations = np.empty((b - a, 3 * n_joints))
        translations[:] = h.offsets.ravel()
        euler = np.zeros((b - a, 3 * n_joints))
        euler[:, h.euler_slot[rot]] = v[:, rot]
        translations[:, h.translation_slot[~rot]] = v[:, ~rot]
        euler_out[a:b] = v[:, rot]
        return euler.reshape(b - a, n_joints, 3), translations.reshape(b - a, n_joints, 3)

    def guess_scale(first: np.ndarray) -> float:
        # the figure's size without its root (a root may stay at the world origin, metres away from the figure:
        # Bandai Namco's joint_Root), the larger of its first frame's and its rest pose's (the OFFSETs chained): a
        # take may begin lying or crouching, a rest pose may be folded
        body = h.parents >= 0
        rest = np.zeros_like(first)
        for j, p in enumerate(h.parents):  # parents come first
            rest[j] = h.offsets[j] + (rest[p] if p >= 0 else 0.0)
        size = max(np.ptp(pose[body] if body.sum() > 1 else pose, axis=0).max() for pose in (first, rest))
        cm, said = figure_unit(float(size))
        if said is not None:
            format_warning(path, said)
        return cm

    positions, q_local, scale = checked_forward_kinematics(
        n_frames, h.parents, h.orders, block, names=h.names, path=path,
        frame_line=lambda t: first_frame_line + t, scale=guess_scale if scale is None else scale,
    )  # fmt: skip
    fps = 1.0 / frame_time
    if abs(fps - round(fps)) <= 1e-4 * fps:
        fps = float(round(fps))
    motion = Motion(
        positions=positions,
        fps=fps,
        joint_names=tuple(h.names),
        parents=h.parents,
        quaternions=q_local,
        source=path,
        euler=euler_out,
    )
    if up == "z" or (up == "auto" and _stands_on_z(motion, h.offsets)):
        motion = _z_up_to_y_up(motion)
    return motion


def _stands_on_z(motion: Motion, offsets: np.ndarray) -> bool:
    """True if the figure's head is above its hips along z rather than y (needs a rig the name rules map).

    Decided by the rest pose (``offsets`` [shape=(J, 3)], the OFFSETs, chained from the root) when its head - root
    vector points clearly along +y or +z (that component at least twice the size of each other one); otherwise by
    the motion's mean head - root vector (z up when its z component is the largest in size and positive).
    """
    from ..motion.skeleton import name_mapping

    mapping = name_mapping(motion.joint_names)
    if "head" not in mapping or "root" not in mapping:
        return False
    head, root = motion.joint_names.index(mapping["head"]), motion.joint_names.index(mapping["root"])

    def at_rest(j: int) -> np.ndarray:  # a joint's position at rest: the offsets up its chain, summed
        total = np.zeros(3)
        while j >= 0:
            total += offsets[j]
            j = motion.parents[j]
        return total

    rest = at_rest(head) - at_rest(root)
    for axis in (1, 2):
        if rest[axis] > 0 and rest[axis] >= 2 * np.delete(np.abs(rest), axis).max():
            return axis == 2
    d = (motion.positions[:, head] - motion.positions[:, root]).mean(0)
    return d[2] > abs(d[1]) and d[2] > abs(d[0])


def _z_up_to_y_up(motion: Motion) -> Motion:
    """Turn a z-up clip to y up by -90 degrees about x: (x, y, z) -> (x, z, -y).

    In place: ``motion`` is the reader's own, not yet returned (no second copy of a long clip).
    """
    p = motion.positions
    y = p[..., 1].copy()
    p[..., 1] = p[..., 2]
    p[..., 2] = -y
    del y
    quat = motion.quaternions
    if quat is not None:
        # only the root's rotation is expressed in world axes; turn it with the frame
        turn = rotations.from_euler("X", [-90.0])
        roots = np.flatnonzero(motion.parents < 0)
        quat[:, roots] = rotations.multiply(turn, quat[:, roots].astype(np.float64)).astype(np.float32)
    return motion
