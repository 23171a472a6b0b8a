"""Writing BVH: a rig and its channel values, a posed rig, an AMC clip on its ASF rig, a stretch of a BVH file.

bvh_bytes       joints, offsets, channels and per-frame values -> the text of a BVH file.
pose_bvh        a :class:`mocapviz.motion.rig.Pose` (the canonical rig of an export) -> BVH text.
asf_bvh         an AMC Motion and its ASF skeleton -> BVH text on the ASF rig.
cut_bvh         frames ``start:end`` of a BVH file: its header as it is, its frame lines byte for byte.

Every writer takes ``comments``: lines written as ``# ...`` right after ``HIERARCHY``, which
:func:`mocapviz.io.bvh.read_bvh` skips (as readers that only look for the keywords they know, such as Blender's,
do). Values are written with six decimals (degrees and centimetres: 1e-6, far below a motion's precision).

Conventions of the written files (so that every BVH reader reads the same positions): rotation channels
``Zrotation Xrotation Yrotation`` (``R = Rz Rx Ry``) unless the rig has its own order; a joint with position channels
has ``OFFSET 0 0 0``, so that a reader that adds the channels to the offset and one that replaces it agree.
"""
from __future__ import annotations

import io
import re

import numpy as np

from ..errors import MocapFormatError
from ..motion import Motion, rotations
from ..motion.rig import Pose
from .bvh import _MOTION, _motion_header
from .text import words

ROTATION = "ZXY"  # the channels written, in file order: Zrotation Xrotation Yrotation
_POSITION = ["Xposition", "Yposition", "Zposition"]
_FRAMES = re.compile(rb"(?im)^([ \t]*frames[ \t]*:[ \t]*)([0-9]+)")


def _comment_lines(comments) -> list[str]:
    """``# ...`` lines of ``comments`` (one line each; line breaks inside become spaces)."""
    return ["# " + " ".join(str(c).split()) for c in comments or ()]


def bvh_bytes(names, parents, offsets, channels, values, fps: float, end_sites=None, comments=()) -> bytes:
    """The text of a BVH file.

    Parameters
    ----------
    names : sequence of str [length J]
        Joint names; the first is the root.
    parents : array_like [shape=(J,)], int
        Parent of each joint, -1 for the root; parents come first.
    offsets : array_like [shape=(J, 3)]
        OFFSET of each joint, in the file's unit.
    channels : sequence of sequence of str [length J]
        Each joint's channel names in file order (``Xposition``, ``Zrotation``, ...).
    values : array_like [shape=(T, C)]
        The channel values of every frame, joints in index order, each joint's channels in its order (degrees, file
        units). The file lists them in the hierarchy's depth-first order (a rig listed breadth first, as an FBX
        scene lists its nodes, is reordered).
    fps : float
        Frames per second (``Frame Time: 1/fps``).
    end_sites : dict, optional
        Joint index -> End Site offset, for joints without children (default: ``0 0 0``).
    comments : sequence of str
        Lines written as ``# ...`` after ``HIERARCHY``.

    Returns
    -------
    bytes
        The file (ASCII, LF line ends).

    Examples
    --------
    >>> text = bvh_bytes(["hips", "knee"], [-1, 0], [[0, 0, 0], [0, -40, 0]],
    ...                  [_POSITION + ["Zrotation"], ["Xrotation"]], [[0, 90, 0, 10, 45]], 30, comments=["hi"])
    >>> print(text.decode())  # doctest: +NORMALIZE_WHITESPACE
    HIERARCHY
    # hi
    ROOT hips
    {
      OFFSET 0.000000 0.000000 0.000000
      CHANNELS 4 Xposition Yposition Zposition Zrotation
      JOINT knee
      {
        OFFSET 0.000000 -40.000000 0.000000
        CHANNELS 1 Xrotation
        End Site
        {
          OFFSET 0.000000 0.000000 0.000000
        }
      }
    }
    MOTION
    Frames: 1
    Frame Time: 0.0333333333
    0.000000 90.000000 0.000000 10.000000 45.000000
    <BLANKLINE>
    """
    parents = np.asarray(parents, dtype=np.int64)
    offsets = np.asarray(offsets, dtype=np.float64)
    end_sites = end_sites or {}
    lines = ["HIERARCHY", *_comment_lines(comments)]
    written: list[int] = []  # the joints in the order the hierarchy lists them

    def joint(j: int, depth: int) -> None:
        written.append(j)
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {_triple(offsets[j])}")
        lines.append(f"{pad}  CHANNELS {len(channels[j])} {' '.join(channels[j])}".rstrip())
        kids = np.flatnonzero(parents == j)
        for k in kids:
            joint(int(k), depth + 1)
        if not kids.size:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {_triple(end_sites.get(j, (0, 0, 0)))}",
                          f"{pad}  }}"])  # fmt: skip
        lines.append(pad + "}")

    joint(0, 0)
    widths = [len(c) for c in channels]
    first = np.concatenate([[0], np.cumsum(widths)])
    order = np.array([c for j in written for c in range(first[j], first[j + 1])], dtype=np.int64)
    values = np.asarray(values, dtype=np.float64).reshape(-1, first[-1])[:, order]
    lines += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {1.0 / fps:.10f}", ""]
    out = io.BytesIO()
    out.write("\n".join(lines).encode("utf-8"))
    np.savetxt(out, values, fmt="%.6f", delimiter=" ")
    return out.getvalue()


def _triple(v) -> str:
    return " ".join(f"{float(x):.6f}" for x in v)


def _rotation_channels(order: str) -> list[str]:
    """BVH channel names of a rotation order given in file order (``"ZXY"``)."""
    return [f"{a.upper()}rotation" for a in order]


def _euler(q: np.ndarray, order: str) -> np.ndarray:
    """Channel values [shape=(..., 3)], degrees, of rotations ``q`` for channels in file order ``order``."""
    return rotations.to_euler(order[::-1], q)[..., ::-1]  # channels c1 c2 c3: R = R_c1 R_c2 R_c3


def pose_bvh(names, parents, pose: Pose, fps: float, comments=()) -> bytes:
    """A posed rig as BVH: every joint with ``Zrotation Xrotation Yrotation``, the moving ones (the root, and joints
    whose offset varies) also with ``Xposition Yposition Zposition`` first and ``OFFSET 0 0 0``.

    Parameters
    ----------
    names : sequence of str [length J]
        Joint names.
    parents : array_like [shape=(J,)], int
        Parents, -1 for the root.
    pose : Pose
        Rotations and translations (cm) of every frame (:func:`mocapviz.motion.rig.fit_pose`).
    fps : float
        Frames per second.
    comments : sequence of str
        ``# ...`` lines after ``HIERARCHY``.

    Returns
    -------
    bytes
        The BVH file, in centimetres, y up.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.motion.rig import fit_pose
    >>> m = MotionDB.sample().motion(7)
    >>> pose = fit_pose(m.positions, m.parents, m.positions[0] - m.positions[0, np.maximum(m.parents, 0)])
    >>> text = pose_bvh(m.joint_names, m.parents, pose, m.fps, comments=["document 7"]).decode()
    >>> text.splitlines()[:4]
    ['HIERARCHY', '# document 7', 'ROOT root', '{']
    """
    moving = np.asarray(pose.moving)
    channels = [(_POSITION if moving[j] else []) + _rotation_channels(ROTATION) for j in range(len(names))]
    euler = _euler(pose.rotations, ROTATION)  # (T, J, 3)
    parts = [np.concatenate([pose.translations[:, j], euler[:, j]], axis=1) if moving[j] else euler[:, j]
             for j in range(len(names))]
    offsets = np.where(moving[:, None], 0.0, pose.offsets)
    return bvh_bytes(names, parents, offsets, channels, np.concatenate(parts, axis=1), fps, comments=comments)


def asf_bvh(motion: Motion, skeleton, comments=()) -> bytes:
    """An AMC clip as BVH on its own ASF rig: a BVH joint per ASF bone, at the bone's start.

    Each bone's BVH offset is its parent bone's ASF ``direction * length`` (zero under the root), a leaf bone's End
    Site its own; the root has ``Xposition Yposition Zposition`` and its rotation channels, every bone three rotation
    channels in its ASF axis order (``axis ... XYZ``: ``Zrotation Yrotation Xrotation``). The values are each bone's
    rotation relative to its parent as Euler angles, ``C M C^-1`` of the ASF convention: BVH has no per-bone axis
    ``C``, so they equal the AMC's DOF values only where the bone's axis is zero, and a one- or two-DOF bone with a
    tilted axis turns about all three. Forward kinematics of the file gives the AMC's positions.

    Parameters
    ----------
    motion : Motion
        The clip as :func:`mocapviz.io.asfamc.read_amc` returns it (joints ``root`` and every bone's tip).
    skeleton : AsfSkeleton
        Its skeleton (:func:`mocapviz.io.read_asf`).
    comments : sequence of str
        ``# ...`` lines after ``HIERARCHY``.

    Returns
    -------
    bytes
        The BVH file, in centimetres, y up.

    Examples
    --------
    >>> from mocapviz.io import datasets, load, read_asf, find_asf
    >>> amc = datasets.sample() / "hdm05-cut/amc/HDM_mm_kickLFront1Reps_023_120.amc"
    >>> text = asf_bvh(load(amc)[:10], read_asf(find_asf(amc))).decode()
    >>> text.splitlines()[1:4], "Frames: 10" in text
    (['ROOT root', '{', '  OFFSET 0.000000 0.000000 0.000000'], True)
    """
    names = motion.joint_names
    parents = motion.parents
    orders = [skeleton.root_axis, *skeleton.axis_orders]
    offsets = np.zeros((len(names), 3))
    has_parent_bone = parents > 0
    offsets[has_parent_bone] = skeleton.offsets[parents[has_parent_bone] - 1]
    end_sites = {j: skeleton.offsets[j - 1] for j in range(1, len(names)) if not np.any(parents == j)}
    channels = [_POSITION + _rotation_channels(orders[0][::-1])]
    channels += [_rotation_channels(o[::-1]) for o in orders[1:]]
    quat = motion.quaternions.astype(np.float64)
    parts = [motion.positions[:, 0].astype(np.float64)]
    parts += [_euler(quat[:, j], orders[j][::-1]) for j in range(len(names))]
    return bvh_bytes(names, parents, offsets, channels, np.concatenate(parts, axis=1), motion.fps, end_sites, comments)


def cut_bvh(raw: bytes, start: int, end: int, comments=(), path=None) -> bytes:
    """Frames ``start:end`` of a BVH file: its header unchanged but for ``Frames:`` and the ``# ...`` comment lines
    after ``HIERARCHY``, then exactly its frame lines ``start:end`` (each line's bytes as in the file, ended as the
    file ends its lines).

    Parameters
    ----------
    raw : bytes
        The BVH file.
    start, end : int
        Frames, half-open, ``0 <= start < end <= frames``.
    comments : sequence of str
        ``# ...`` lines after ``HIERARCHY``.
    path : str, optional
        The file, for error messages.

    Returns
    -------
    bytes
        The cut file.

    Raises
    ------
    MocapFormatError
        No MOTION section, or a frame count other than the header's.

    Examples
    --------
    >>> raw = bvh_bytes(["hips"], [-1], [[0, 0, 0]], [["Yrotation"]], [[1], [2], [3]], 30)
    >>> print(cut_bvh(raw, 1, 3).decode().split("MOTION")[1])
    <BLANKLINE>
    Frames: 2
    Frame Time: 0.0333333333
    2.000000
    3.000000
    <BLANKLINE>
    """
    found = _MOTION.search(raw)
    if found is None:
        raise MocapFormatError(path, "no MOTION line")
    mpos = raw.rfind(b"\n", 0, found.start()) + 1
    n_frames, _, data_start, _ = _motion_header(raw, mpos, raw.count(b"\n", 0, mpos) + 1, path)
    newline = b"\r\n" if b"\r\n" in raw[:data_start] else b"\n"
    frames = [line.rstrip(b"\r") for line in raw[data_start:].split(b"\n") if line.strip()]
    if len(frames) != n_frames:
        raise MocapFormatError(path, f"header says {n_frames} frames, the file has {len(frames)}")
    if not 0 <= start < end <= n_frames:
        raise MocapFormatError(path, f"frames {start}:{end} are not inside its {n_frames} frames")
    motion_part = _FRAMES.sub(lambda m: m.group(1) + str(end - start).encode(), raw[mpos:data_start], count=1)
    head = raw[:mpos]
    first = next(i for i, line in enumerate(head.split(b"\n")) if words(line.decode("latin-1")))
    at = sum(len(line) + 1 for line in head.split(b"\n")[: first + 1])  # after the HIERARCHY line
    notes = b"".join(c.encode("utf-8") + newline for c in _comment_lines(comments))
    return head[:at] + notes + head[at:] + motion_part + newline.join(frames[start:end]) + newline
