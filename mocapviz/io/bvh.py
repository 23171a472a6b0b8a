"""Biovision BVH motions (any rig: CMU conversions, Bandai Namco, MotionBuilder exports, ...).

read_bvh      BVH file -> Motion (positions by forward kinematics, local quaternions).

Conventions:

- Each joint has 0 to 6 channels, ``Xposition Yposition Zposition`` and ``Xrotation Yrotation Zrotation``
  in any order. Rotation channels ``c1 c2 c3`` compose as ``R = R_c1 R_c2 R_c3`` (read left to right).
- A position channel replaces that component of the joint's OFFSET (the MotionBuilder convention; files
  whose root OFFSET is zero read the same under the other convention).
- ``End Site`` blocks become joints named ``<parent>_end``, without channels.
- Units: a figure between 0.5 and 3 units tall is taken to be in metres, between 500 and 3000 in
  millimetres, otherwise centimetres; pass ``scale`` (centimetres per file unit) to override.
- Up axis: y; with ``up="auto"`` (default) a file whose figure stands along z (head above hips on z) is
  turned to y up, keeping it right-handed; ``up="z"`` forces the conversion, ``up="y"`` prevents it.
"""
from __future__ import annotations

import functools
import math
import os
import re

import numpy as np

from .. import rotations
from ..errors import MocapFormatError, ParameterError
from ..motion import Motion
from .text import scan

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
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.channels: list[list[str]] = []

    def layout(self) -> _Hierarchy:
        euler_slot, translation_slot, orders = [], [], []
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


@functools.lru_cache(maxsize=128)
def _cached_hierarchy(text: str) -> _Hierarchy:
    """Parse (once per distinct text: the files of one rig share it) the HIERARCHY text before MOTION."""
    lines = text.split("\n")
    return _parse_hierarchy(lines + ["MOTION"], None)[0].layout()


def _parse_hierarchy(lines: list[str], path) -> tuple[_Hierarchy, int]:
    """Parse HIERARCHY; return it and the index of the MOTION line."""
    h = _Hierarchy()
    stack: list[int] = []
    pending = None  # joint declared, waiting for its '{'
    i = 0
    first = next((k for k, line in enumerate(lines) if line.strip()), None)
    if first is None or lines[first].strip().lstrip("\ufeff").upper() != "HIERARCHY":
        raise MocapFormatError(path, "file does not start with HIERARCHY (not a BVH file?)", (first or 0) + 1)
    for i in range(first + 1, len(lines)):
        tok = lines[i].split()
        ln = i + 1
        if not tok:
            continue
        key = tok[0].upper()
        if key in ("ROOT", "JOINT"):
            if (key == "ROOT") != (not stack):
                raise MocapFormatError(path, f"{tok[0]} at the wrong nesting level", ln)
            if len(tok) < 2:
                raise MocapFormatError(path, f"{tok[0]} without a name", ln)
            name = " ".join(tok[1:])
            if name in h.names:
                raise MocapFormatError(path, f"joint {name!r} defined twice", ln)
            pending = (name, stack[-1] if stack else -1)
        elif key == "END":
            if not stack:
                raise MocapFormatError(path, "End Site outside a joint", ln)
            name = f"{h.names[stack[-1]]}_end"
            k = 2
            while name in h.names:  # several End Sites under one joint
                name = f"{h.names[stack[-1]]}_end{k}"
                k += 1
            pending = (name, stack[-1])
        elif key == "{":
            if pending is None:
                raise MocapFormatError(path, "'{' without a joint", ln)
            h.names.append(pending[0])
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
            try:
                off = [float(t) for t in tok[1:]]
            except ValueError:
                off = []
            if len(off) != 3 or not all(map(math.isfinite, off)):
                raise MocapFormatError(path, "OFFSET needs three finite numbers", ln)
            h.offsets[stack[-1]] = off
        elif key == "CHANNELS":
            if not stack:
                raise MocapFormatError(path, "CHANNELS outside a joint", ln)
            try:
                n = int(tok[1])
            except (IndexError, ValueError):
                raise MocapFormatError(path, "CHANNELS needs a count", ln) from None
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


def _motion_header(lines: list[str], at: int, path) -> tuple[int, float, int]:
    """Frame count, frame time and index of the first data line after the MOTION line."""
    values = {}
    where = {}
    i = at + 1
    for key in ("frames", "frame time"):
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise MocapFormatError(path, f"missing '{key.title()}:' line (truncated file?)", len(lines))
        head, _, rest = lines[i].partition(":")
        if head.strip().lower() != key:
            raise MocapFormatError(path, f"expected '{key.title()}:', got {lines[i].strip()!r}", i + 1)
        try:
            values[key] = float(rest)
        except ValueError:
            raise MocapFormatError(path, f"'{key.title()}:' needs a number", i + 1) from None
        where[key] = i + 1
        i += 1
    n, dt = values["frames"], values["frame time"]
    if not (np.isfinite(n) and n == int(n) and n >= 1):
        raise MocapFormatError(path, f"frame count must be a positive integer, got {n:g}", where["frames"])
    if not (np.isfinite(dt) and dt > 0):
        raise MocapFormatError(path, "frame time must be a positive number", i)
    return int(n), dt, i


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
        Malformed HIERARCHY, unsupported channels, frame count different from the header, wrong number of
        values on a line, malformed or non-finite numbers; the message names the file and line.
    """
    path = os.fspath(path)
    if up not in ("auto", "y", "z"):
        raise ParameterError(f"up must be 'auto', 'y' or 'z', got {up!r}")
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise MocapFormatError(path, f"cannot read file ({exc.strerror})") from None
    if not raw.strip():
        raise MocapFormatError(path, "file is empty")
    found = re.search(rb"(?m)^[ \t]*MOTION\b", raw)
    if found is None:
        _parse_hierarchy(raw.decode("latin-1").split("\n"), path)  # raises, naming the problem
    mpos = found.start()
    hier_text = raw[:mpos].decode("utf-8-sig" if raw.startswith(b"\xef\xbb\xbf") else "latin-1")
    try:
        h = _cached_hierarchy(hier_text)
    except MocapFormatError as exc:
        raise MocapFormatError(path, exc.reason, exc.line) from None
    motion_line = hier_text.count("\n")
    lines = [""] * motion_line + raw[mpos : mpos + 200].decode("latin-1").split("\n")
    n_frames, frame_time, data_line = _motion_header(lines, motion_line, path)
    start = mpos + sum(len(s) + 1 for s in lines[motion_line:data_line])
    sc = scan(raw[start:], path, first_line=data_line + 1)

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
    if data.size != n_frames:
        # the first frame line beyond the header's count, or where the first missing frame should be
        where = sc.first_line + (int(data[n_frames]) if data.size > n_frames else int(data[-1]) + 1 if data.size else 0)
        raise MocapFormatError(path, f"header says {n_frames} frames, the file has {data.size}", where)
    if data.size and data[-1] - data[0] + 1 != data.size:
        gap = int(data[np.argmax(np.diff(data) > 1)] + 1)
        raise MocapFormatError(path, "blank line inside the frame data", sc.first_line + gap)
    values = sc.values.reshape(n_frames, n_channels)

    n_joints = len(h.names)
    translations = np.broadcast_to(h.offsets.ravel(), (n_frames, 3 * n_joints)).copy()
    euler = np.zeros((n_frames, 3 * n_joints))
    rot = h.euler_slot >= 0
    euler[:, h.euler_slot[rot]] = values[:, rot]
    translations[:, h.translation_slot[~rot]] = values[:, ~rot]
    translations = translations.reshape(n_frames, n_joints, 3)
    euler = euler.reshape(n_frames, n_joints, 3)
    q_local, positions = rotations.forward_kinematics(h.parents, euler, h.orders, translations)

    if scale is None:
        # the figure's size without its root: a root may stay at the world origin, metres away from the
        # figure (Bandai Namco's joint_Root)
        body = h.parents >= 0
        height = np.ptp(positions[0, body] if body.sum() > 1 else positions[0], axis=0).max()
        scale = 100.0 if 0.5 <= height <= 3.0 else 0.1 if 500.0 <= height <= 3000.0 else 1.0
    positions *= scale
    fps = 1.0 / frame_time
    if abs(fps - round(fps)) <= 1e-4 * fps:
        fps = float(round(fps))
    motion = Motion(
        positions=positions.astype(np.float32),
        fps=fps,
        joint_names=tuple(h.names),
        parents=h.parents,
        quaternions=q_local.astype(np.float32),
        source=path,
        euler=values[:, rot],
    )
    if up == "z" or (up == "auto" and _stands_on_z(motion)):
        motion = _z_up_to_y_up(motion)
    return motion


def _stands_on_z(motion: Motion) -> bool:
    """True if the figure's head is above its hips along z rather than y (needs a rig the name rules map)."""
    from ..skeleton import name_mapping

    mapping = name_mapping(motion.joint_names)
    if "head" not in mapping or "root" not in mapping:
        return False
    names = motion.joint_names
    d = (motion.positions[:, names.index(mapping["head"])] - motion.positions[:, names.index(mapping["root"])]).mean(0)
    return d[2] > abs(d[1]) and d[2] > abs(d[0])


def _z_up_to_y_up(motion: Motion) -> Motion:
    """Turn a z-up clip to y up by -90 degrees about x: (x, y, z) -> (x, z, -y)."""
    from dataclasses import replace

    p = motion.positions
    turned = np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    quat = motion.quaternions
    if quat is not None:
        # only the root's rotation is expressed in world axes; turn it with the frame
        turn = rotations.from_euler("X", [-90.0])
        roots = motion.parents < 0
        quat = quat.copy()
        quat[:, roots] = rotations.multiply(turn, quat[:, roots].astype(np.float64)).astype(np.float32)
    return replace(motion, positions=turned, quaternions=quat)
