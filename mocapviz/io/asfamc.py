"""Acclaim ASF skeletons and AMC motions (CMU, HDM05 and other Vicon exports).

read_asf      ASF file -> AsfSkeleton (bones, axes, DOFs, hierarchy, units).
read_amc      AMC file + AsfSkeleton -> Motion (positions by forward kinematics, local quaternions).

Conventions (Acclaim ASF/AMC specification, as read by the CMU and HDM05 tools):

- A bone's ``axis a b c ORDER`` gives its local frame C as rotations about the fixed x, y, z axes applied in
  ORDER (``XYZ``: x first, i.e. ``C = Rz Ry Rx``). The AMC values of the bone's ``dof`` (rx, ry, rz in any
  listed order) give M, composed in the same ORDER. The bone's rotation relative to its parent is
  ``C M C^-1``; the position of the bone's tip is its parent's tip plus the bone's global rotation applied to
  ``length * direction``.
- The root's ``order`` lists its AMC channels (TX TY TZ RX RY RZ in any order), its ``axis`` the rotation
  order, ``position`` is added to the translation, and ``orientation`` is the root's C.
- ``:units length u``: lengths and root translations are in units of 1/u inch; centimetres = value * 2.54 / u.
  ``:units angle deg|rad`` (an AMC ``:RADIANS`` header overrides it).
- A bone with DOFs that has no line in any frame of the AMC keeps its rest pose; a bone line missing from
  only some frames is an error, except in the last frame, which is dropped with a warning (a file cut off
  inside its last frame, as CMU ``golf_01.amc``).
"""
from __future__ import annotations

import functools
import os
import warnings
from dataclasses import dataclass

import numpy as np

from .. import rotations
from ..errors import MocapFormatError
from ..motion import Motion
from .text import name_hash, scan

_ROT_DOFS = ("rx", "ry", "rz")
_ROOT_CHANNELS = ("TX", "TY", "TZ", "RX", "RY", "RZ")


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An ASF skeleton: the root plus B bones, in an order where parents come first.

    Attributes
    ----------
    path : str
    bone_names : tuple of str [length B]
    parents : np.ndarray [shape=(B,)] -- index of the parent bone, -1 for the root.
    offsets : np.ndarray [shape=(B, 3)] -- length * direction, centimetres.
    axis_quaternions : np.ndarray [shape=(B, 4)] -- the bones' C.
    axis_orders : tuple of str [length B] -- rotation order of each bone (``"XYZ"``...).
    dofs : tuple of tuple of str -- each bone's rotational DOFs in AMC column order.
    root_order : tuple of str -- the root's AMC channels, e.g. ``("TX", "TY", "TZ", "RX", "RY", "RZ")``.
    root_axis : str
    root_position : np.ndarray [shape=(3,)], cm
    root_quaternion : np.ndarray [shape=(4,)] -- the root's C (from ``orientation``).
    cm_per_unit : float
    degrees : bool
    """

    path: str
    bone_names: tuple
    parents: np.ndarray
    offsets: np.ndarray
    axis_quaternions: np.ndarray
    axis_orders: tuple
    dofs: tuple
    root_order: tuple
    root_axis: str
    root_position: np.ndarray
    root_quaternion: np.ndarray
    cm_per_unit: float
    degrees: bool


def _check_order(order: str, path, line: int) -> str:
    if len(order) != 3 or sorted(order.upper()) != ["X", "Y", "Z"]:
        raise MocapFormatError(path, f"unsupported rotation order {order!r} (need a permutation of XYZ)", line)
    return order.upper()


def _floats(tokens, n, path, line, what):
    try:
        vals = [float(t) for t in tokens]
    except ValueError:
        raise MocapFormatError(path, f"{what}: expected {n} numbers, got {' '.join(tokens)!r}", line) from None
    if len(vals) != n:
        raise MocapFormatError(path, f"{what}: expected {n} numbers, got {len(vals)}", line)
    if not np.all(np.isfinite(vals)):
        raise MocapFormatError(path, f"{what}: non-finite value", line)
    return vals


def _read_text(path) -> str:
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise MocapFormatError(path, f"cannot read file ({exc.strerror})") from None
    if not raw.strip():
        raise MocapFormatError(path, "file is empty")
    if b"\x00" in raw[:4096]:
        raise MocapFormatError(path, "binary data, not a text file")
    # ASF/AMC are ASCII; HDM05 headers hold Latin-1 bytes, which latin-1 decodes without loss.
    return raw.decode("latin-1")


def read_asf(path) -> AsfSkeleton:
    """Parse an ASF skeleton file.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    AsfSkeleton

    Raises
    ------
    MocapFormatError
        Missing sections, malformed bone blocks, unsupported DOFs or rotation orders, hierarchy problems;
        the message names the file and line.
    """
    path = os.fspath(path)
    st = os.stat(path) if os.path.exists(path) else None
    key = (path, st.st_mtime_ns, st.st_size) if st else (path, 0, 0)
    return _read_asf_cached(*key)


@functools.lru_cache(maxsize=64)
def _read_asf_cached(path, _mtime, _size) -> AsfSkeleton:
    lines = _read_text(path).splitlines()
    section = None
    length_unit = 1.0
    degrees = True
    root = {"order": _ROOT_CHANNELS, "axis": "XYZ", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0]}
    bones: list[dict] = []
    bone = None
    hierarchy: dict[str, str] = {}
    seen = set()
    for ln, raw in enumerate(lines, start=1):
        tok = raw.split()
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0]
        if key.startswith(":"):
            section = key[1:].lower()
            seen.add(section)
            if bone is not None:
                raise MocapFormatError(path, f"bone block {bone.get('name', '?')!r} has no 'end'", ln)
            continue
        k = key.lower()
        if section == "units":
            if k == "length":
                length_unit = _floats(tok[1:2], 1, path, ln, "units length")[0]
                if length_unit <= 0:
                    raise MocapFormatError(path, "units length must be positive", ln)
            elif k == "angle":
                unit = tok[1].lower() if len(tok) > 1 else ""
                if unit not in ("deg", "rad"):
                    raise MocapFormatError(path, f"units angle must be deg or rad, got {unit!r}", ln)
                degrees = unit == "deg"
        elif section == "root":
            if k == "order":
                chans = tuple(t.upper() for t in tok[1:])
                if sorted(chans) != sorted(set(chans)) or not set(chans) <= set(_ROOT_CHANNELS):
                    raise MocapFormatError(path, f"unsupported root order {' '.join(tok[1:])!r}", ln)
                root["order"] = chans
            elif k == "axis":
                root["axis"] = _check_order(tok[1] if len(tok) > 1 else "", path, ln)
            elif k in ("position", "orientation"):
                root[k] = _floats(tok[1:], 3, path, ln, f"root {k}")
        elif section == "bonedata":
            if k == "begin":
                if bone is not None:
                    raise MocapFormatError(path, "'begin' inside a bone block", ln)
                bone = {"line": ln, "dof": ()}
            elif k == "end":
                if bone is None:
                    raise MocapFormatError(path, "'end' without 'begin'", ln)
                for need in ("name", "direction", "length", "axis"):
                    if need not in bone:
                        raise MocapFormatError(path, f"bone block has no {need!r}", bone["line"])
                bones.append(bone)
                bone = None
            elif bone is None:
                raise MocapFormatError(path, f"{key!r} outside a bone block", ln)
            elif k == "name":
                if len(tok) != 2:
                    raise MocapFormatError(path, "bone name must be one word", ln)
                bone["name"] = tok[1]
            elif k == "direction":
                bone["direction"] = _floats(tok[1:], 3, path, ln, "direction")
            elif k == "length":
                bone["length"] = _floats(tok[1:], 1, path, ln, "length")[0]
            elif k == "axis":
                if len(tok) != 5:
                    raise MocapFormatError(path, "axis needs three angles and an order, e.g. 'axis 0 0 20 XYZ'", ln)
                bone["axis"] = _floats(tok[1:4], 3, path, ln, "axis")
                bone["order"] = _check_order(tok[4], path, ln)
            elif k == "dof":
                dof = tuple(t.lower() for t in tok[1:])
                bad = [d for d in dof if d not in _ROT_DOFS]
                if bad or len(set(dof)) != len(dof):
                    raise MocapFormatError(
                        path, f"unsupported DOF {' '.join(bad or dof)!r} (rotational rx, ry, rz only)", ln
                    )
                bone["dof"] = dof
        elif section == "hierarchy":
            if k in ("begin", "end"):
                continue
            for child in tok[1:]:
                if child in hierarchy:
                    raise MocapFormatError(path, f"bone {child!r} has two parents in :hierarchy", ln)
                hierarchy[child] = tok[0]
    if bone is not None:
        raise MocapFormatError(path, f"file ends inside bone block {bone.get('name', '?')!r}", len(lines))
    for need in ("bonedata", "hierarchy"):
        if need not in seen:
            raise MocapFormatError(path, f"no :{need} section (not an ASF file?)")
    if not bones:
        raise MocapFormatError(path, "no bones in :bonedata")
    names = [b["name"] for b in bones]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise MocapFormatError(path, f"bone {min(dup)!r} defined twice")
    known = set(names) | {"root"}
    for child, parent in hierarchy.items():
        if child not in known or parent not in known:
            missing = child if child not in known else parent
            raise MocapFormatError(path, f":hierarchy names unknown bone {missing!r}")
    orphans = [n for n in names if n not in hierarchy]
    if orphans:
        raise MocapFormatError(path, f"bone {orphans[0]!r} is not in :hierarchy")
    # stable topological order: file order, each bone after its parent
    order: list[int] = []
    placed = {"root": -1}
    pending = list(range(len(bones)))
    while pending:
        waiting = []
        for i in pending:
            if hierarchy[names[i]] in placed:
                placed[names[i]] = len(order)
                order.append(i)
            else:
                waiting.append(i)
        if len(waiting) == len(pending):
            raise MocapFormatError(path, f":hierarchy has a cycle through bone {names[pending[0]]!r}")
        pending = waiting
    bones = [bones[i] for i in order]
    cm = 2.54 / length_unit
    direction = np.array([b["direction"] for b in bones], dtype=np.float64)
    norm = np.linalg.norm(direction, axis=1, keepdims=True)
    direction = np.divide(direction, norm, out=np.zeros_like(direction), where=norm > 0)
    offsets = direction * np.array([b["length"] for b in bones])[:, None] * cm
    axis_q = np.stack([rotations.from_euler(b["order"], b["axis"], degrees) for b in bones])
    return AsfSkeleton(
        path=path,
        bone_names=tuple(b["name"] for b in bones),
        parents=np.array([placed[hierarchy[b["name"]]] for b in bones], dtype=np.int64),
        offsets=offsets,
        axis_quaternions=axis_q,
        axis_orders=tuple(b["order"] for b in bones),
        dofs=tuple(b["dof"] for b in bones),
        root_order=tuple(root["order"]),
        root_axis=root["axis"],
        root_position=np.array(root["position"]) * cm,
        root_quaternion=rotations.from_euler(root["axis"], root["orientation"], degrees),
        cm_per_unit=cm,
        degrees=degrees,
    )


def _header_end(text: str, path) -> tuple[int, int, bool | None]:
    """Byte offset and 1-based line number where the frames start, and the angle unit the header states."""
    pos = 0
    line = 1
    degrees = None
    while pos < len(text):
        nl = text.find("\n", pos)
        end = len(text) if nl < 0 else nl
        s = text[pos:end].strip()
        if s and not s.startswith("#") and not s.startswith(":"):
            return pos, line, degrees
        if s.upper() == ":RADIANS":
            degrees = False
        elif s.upper() == ":DEGREES":
            degrees = True
        pos = end + 1
        line += 1
    raise MocapFormatError(path, "no frames after the header")


def read_amc(path, skeleton: AsfSkeleton, fps: float = 120.0) -> Motion:
    """Read an AMC motion onto its ASF skeleton and run forward kinematics.

    Parameters
    ----------
    path : str or os.PathLike
    skeleton : AsfSkeleton
        From :func:`read_asf`.
    fps : float
        Frame rate (AMC files do not store it; CMU and HDM05 are 120).

    Returns
    -------
    Motion
        Joints ``root`` and the tip of every bone (named after the bone), positions (T, B+1, 3) in cm,
        local quaternions (T, B+1, 4), and ``euler`` (T, C): the C rotation channel values in degrees (the
        root's, then each bone's DOFs, bones in :attr:`AsfSkeleton.bone_names` order).

    Raises
    ------
    MocapFormatError
        Unknown bones, wrong value counts, duplicated or missing bone lines, frame numbers out of sequence,
        malformed or non-finite numbers; the message names the file and line.
    """
    path = os.fspath(path)
    text = _read_text(path)
    start, first_line, header_degrees = _header_end(text, path)
    sc = scan(text[start:].encode("latin-1"), path, first_line)
    degrees = skeleton.degrees if header_degrees is None else header_degrees
    lineno = lambda i: sc.first_line + int(i)

    has_name = sc.name_start >= 0
    marker = ~has_name & (sc.n_values == 1)
    odd = ~has_name & (sc.n_values > 1)
    if odd.any():
        raise MocapFormatError(path, "expected a frame number or a bone line", lineno(np.argmax(odd)))
    markers = np.flatnonzero(marker)
    if markers.size == 0:
        raise MocapFormatError(path, "no frames")
    frame_numbers = sc.values[sc.first_value[markers]]
    if np.any(frame_numbers != np.round(frame_numbers)):
        bad = markers[np.argmax(frame_numbers != np.round(frame_numbers))]
        raise MocapFormatError(path, "frame number is not an integer", lineno(bad))
    jumps = np.flatnonzero(np.diff(frame_numbers) != 1)
    if jumps.size:
        k = jumps[0]
        raise MocapFormatError(
            path, f"frame numbers jump from {frame_numbers[k]:.0f} to {frame_numbers[k + 1]:.0f}", lineno(markers[k + 1])
        )
    n_frames = markers.size
    bone_lines = np.flatnonzero(has_name)
    frame_of_line = np.cumsum(marker) - 1
    if bone_lines.size and frame_of_line[bone_lines[0]] < 0:
        raise MocapFormatError(path, "bone line before the first frame number", lineno(bone_lines[0]))

    names = ("root",) + skeleton.bone_names
    counts = np.array([len(skeleton.root_order)] + [len(d) for d in skeleton.dofs])
    known = _channel_layout(skeleton).name_hashes
    by_hash = np.argsort(known)
    hashes = sc.name_hash[bone_lines]
    pos = np.minimum(np.searchsorted(known[by_hash], hashes), len(names) - 1)
    bone_of_line = by_hash[pos]
    unknown = known[bone_of_line] != hashes
    if unknown.any():
        line = bone_lines[np.argmax(unknown)]
        raise MocapFormatError(
            path, f"unknown bone {sc.token(line)!r} (not in {os.path.basename(skeleton.path)})", lineno(line)
        )
    wrong = sc.n_values[bone_lines] != counts[bone_of_line]
    if wrong.any():
        k = np.argmax(wrong)
        b = bone_of_line[k]
        dof = " ".join(skeleton.root_order if b == 0 else skeleton.dofs[b - 1]) or "none"
        raise MocapFormatError(
            path,
            f"bone {names[b]!r} has {sc.n_values[bone_lines[k]]} values, the skeleton gives it "
            f"{counts[b]} ({dof})",
            lineno(bone_lines[k]),
        )
    frames = frame_of_line[bone_lines]
    slot = frames * len(names) + bone_of_line
    seen = np.bincount(slot, minlength=n_frames * len(names))
    if seen.max(initial=0) > 1:
        k = np.flatnonzero(seen[slot] > 1)[1]
        raise MocapFormatError(path, f"bone {names[bone_of_line[k]]!r} appears twice in one frame", lineno(bone_lines[k]))
    present = seen.reshape(n_frames, len(names)) > 0
    incomplete = (present != present.any(axis=0)).any(axis=1)
    if n_frames > 1 and incomplete[-1] and not incomplete[:-1].any():
        # the file ends inside its last frame (CMU golf_01.amc): keep the complete frames
        warnings.warn(
            f"{path}: last frame {frame_numbers[-1]:.0f} is incomplete (truncated file?); dropped it", stacklevel=2
        )
        n_frames -= 1
        keep = frame_of_line[bone_lines] < n_frames
        bone_lines, bone_of_line = bone_lines[keep], bone_of_line[keep]
        markers, frame_numbers, present = markers[:-1], frame_numbers[:-1], present[:-1]
    partly = present.any(axis=0) & ~present.all(axis=0)
    if partly.any():
        b = int(np.argmax(partly))
        f = int(np.argmax(~present[:, b]))
        raise MocapFormatError(
            path, f"frame {frame_numbers[f]:.0f} has no line for bone {names[b]!r} (truncated file?)", lineno(markers[f])
        )

    # one gather for every channel of every frame: line_of[f, b] is the line of bone b in frame f
    line_of = np.zeros((n_frames, len(names)), dtype=np.int64)
    line_of[frame_of_line[bone_lines], bone_of_line] = bone_lines
    layout = _channel_layout(skeleton)
    use = present[0, layout.bone]
    vals = sc.values[sc.first_value[line_of[:, layout.bone[use]]] + layout.column[use]]
    n_bones = len(skeleton.bone_names)
    euler = np.zeros((n_frames, (n_bones + 1) * 3))  # each joint's angles in its own axis order
    translation = np.zeros((n_frames, 3))
    rot = layout.euler_slot[use] >= 0
    euler[:, layout.euler_slot[use][rot]] = vals[:, rot]
    translation[:, layout.translation[use][~rot]] = vals[:, ~rot]
    euler = euler.reshape(n_frames, n_bones + 1, 3)
    # the file's rotation channels as they are (bones without lines: 0), for Motion.euler
    channels = np.zeros((n_frames, int(np.count_nonzero(layout.euler_slot >= 0))))
    channels[:, (np.cumsum(layout.euler_slot >= 0) - 1)[use][rot]] = vals[:, rot]
    translation = translation * skeleton.cm_per_unit + skeleton.root_position
    axis_q = np.concatenate([skeleton.root_quaternion[None], skeleton.axis_quaternions])
    t_local = np.zeros((n_frames, n_bones + 1, 3))
    t_local[:, 0] = translation
    t_local[:, 1:] = skeleton.offsets
    parents = np.concatenate([[-1], skeleton.parents + 1])
    q_local, positions = rotations.forward_kinematics(
        parents,
        euler,
        (skeleton.root_axis,) + skeleton.axis_orders,
        t_local,
        own_frame=np.ones(n_bones + 1, dtype=bool),
        pre=axis_q,
        post=_conj(axis_q),
        degrees=degrees,
    )
    return Motion(
        positions=positions.astype(np.float32),
        fps=fps,
        joint_names=names,
        parents=parents,
        quaternions=q_local.astype(np.float32),
        source=path,
        euler=channels if degrees else np.degrees(channels),
    )


@dataclass(frozen=True)
class _Layout:
    """Where each AMC channel of a skeleton goes: one entry per channel, root first, in file column order."""

    bone: np.ndarray  # joint index (0 = root) whose line holds the channel
    column: np.ndarray  # position of the value on that line
    euler_slot: np.ndarray  # flat index into euler (J, 3) in the joint's axis order, or -1
    translation: np.ndarray  # root translation component 0-2, or -1
    name_hashes: np.ndarray  # name_hash of "root" and every bone, by joint index


@functools.lru_cache(maxsize=64)
def _channel_layout(skeleton: AsfSkeleton) -> _Layout:
    bone, column, slot, trans = [], [], [], []
    for k, c in enumerate(skeleton.root_order):
        bone.append(0)
        column.append(k)
        slot.append(skeleton.root_axis.index(c[1]) if c[0] == "R" else -1)
        trans.append("XYZ".index(c[1]) if c[0] == "T" else -1)
    for b, dof in enumerate(skeleton.dofs):
        order = skeleton.axis_orders[b].lower()
        for k, d in enumerate(dof):
            bone.append(b + 1)
            column.append(k)
            slot.append(3 * (b + 1) + order.index(d[1]))
            trans.append(-1)
    names = ("root",) + skeleton.bone_names
    return _Layout(*(np.array(v, dtype=np.int64) for v in (bone, column, slot, trans)),
                   name_hashes=np.array([name_hash(n) for n in names], dtype=np.uint64))


def _conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])
