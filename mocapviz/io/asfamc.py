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
- Every frame of the AMC has a line for the root and for every bone with DOFs (a bone without DOFs may have
  none). A file cut off inside its last frame (CMU ``golf_01.amc``) is read without that frame, with a
  :class:`~mocapviz.errors.MocapFormatWarning`; a line missing from any other frame, a frame without bone lines,
  a bone with DOFs that no frame has, or a file whose only frame is incomplete is refused
  (:func:`mocapviz.io.checks.complete_frames`).
- Text: keywords (``:units``, ``:bonedata``, ``begin``, ``dof``, ``:RADIANS``, ...), DOF and axis-order names in
  any case; bone names as written (case-sensitive); words separated by any ASCII white space; lines end with LF
  or CR LF; bytes read as Latin-1 (so ASF and AMC bone names match byte for byte), a UTF-8 BOM skipped.
- Values: plain decimal numbers (no ``nan``, ``inf``; ``limits`` may say ``inf`` / ``-inf``, the ASF's no limit);
  ``:units length`` 0.001 to 1000; bone lengths from 0 to 1e7 cm; bone directions unit vectors (length 1 ± 0.05,
  normalised); ``id`` a finite number; angles and ``limits`` within ±1e5 degrees; root translations and positions
  within ±1e7 cm (:mod:`mocapviz.io.checks`).
"""
from __future__ import annotations

import functools
import os
from collections import Counter
from dataclasses import dataclass

import numba
import numpy as np

from ..errors import MocapFormatError, ParameterError
from ..motion import Motion, fps_problem, rotations
from .checks import (
    ANGLE_LIMIT_DEG,
    DISTANCE_LIMIT_CM,
    check_limits,
    checked_forward_kinematics,
    complete_frames,
    describe,
    first_outside,
    unit_directions,
)
from .text import name_hash, number, read_bytes, scan, words

_ROT_DOFS = ("rx", "ry", "rz")
_ROOT_CHANNELS = ("TX", "TY", "TZ", "RX", "RY", "RZ")
_UNIT_RANGE = (1e-3, 1e3)  # ``:units length`` u: one file unit is 1/u inch


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An ASF skeleton: the root plus B bones, in an order where parents come first.

    Read with :func:`read_asf`; the fields are its attributes.

    Parameters
    ----------
    path : str
        The ASF file.
    bone_names : tuple of str [length B]
        The bones, parents first.
    parents : np.ndarray [shape=(B,)]
        Index of the parent bone, -1 for the root.
    offsets : np.ndarray [shape=(B, 3)]
        length * direction, cm.
    axis_quaternions : np.ndarray [shape=(B, 4)]
        The bones' C, (w, x, y, z).
    axis_orders : tuple of str [length B]
        Rotation order of each bone (``"XYZ"``...).
    dofs : tuple of tuple of str
        Each bone's rotational DOFs in AMC column order.
    root_order : tuple of str
        The root's AMC channels, e.g. ``("TX", "TY", "TZ", "RX", "RY", "RZ")``.
    root_axis : str
        The root's rotation order.
    root_position : np.ndarray [shape=(3,)]
        Added to the root translation, cm.
    root_quaternion : np.ndarray [shape=(4,)]
        The root's C (from ``orientation``).
    cm_per_unit : float
        Centimetres per length unit of the file (2.54 / ``:units length``).
    degrees : bool
        Angles in degrees (else radians).
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


def _floats(tokens, n, path, line, what, limit: float = float("inf"), unit: str = ""):
    """``n`` plain decimal numbers, each within ``±limit`` (in ``unit``, for the message), or a MocapFormatError."""
    vals = [number(t) for t in tokens]
    if None in vals:
        raise MocapFormatError(path, f"{what}: expected {n} numbers, got {' '.join(tokens)!r}", line)
    if len(vals) != n:
        raise MocapFormatError(path, f"{what}: expected {n} numbers, got {len(vals)}", line)
    for k, v in enumerate(vals):
        if not np.isfinite(v):
            raise MocapFormatError(path, f"{what}: number out of range (not finite): {tokens[k]!r}", line)
        if abs(v) > limit:
            raise MocapFormatError(path, f"{what}: {describe(v)} is beyond ±{limit:g}{unit}", line)
    return vals


def _angle_limit(degrees: bool) -> tuple[float, str]:
    """The largest angle accepted, in the file's angle unit, and that unit (for messages)."""
    return (ANGLE_LIMIT_DEG, " degrees") if degrees else (float(np.radians(ANGLE_LIMIT_DEG)), " radians")


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
        Missing sections, malformed bone blocks, unsupported DOFs or rotation orders, hierarchy problems, values
        beyond the limits of :mod:`mocapviz.io.checks` (units, lengths, angles); the message names the file and
        line.
    """
    path = os.fspath(path)
    # parsed once per path and content (a file rewritten within one timestamp tick is still read again)
    return _read_asf_cached(path, read_bytes(path))


@functools.lru_cache(maxsize=64)
def _read_asf_cached(path, raw: bytes) -> AsfSkeleton:
    # ASF/AMC are ASCII; HDM05 headers hold Latin-1 bytes, which Latin-1 decodes without loss (and bone names keep
    # the bytes the AMC scanner hashes)
    return _parse_asf(path, raw.decode("latin-1").split("\n"))


def _parse_asf(path, lines: list[str]) -> AsfSkeleton:
    section = None
    length_unit = 1.0
    degrees = True
    root = {"order": _ROOT_CHANNELS, "axis": "XYZ", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0]}
    bones: list[dict] = []
    bone = None
    hierarchy: dict[str, str] = {}
    seen = set()
    hierarchy_line: dict[str, int] = {}
    units_line = None
    for ln, line in enumerate(lines, start=1):
        tok = words(line)
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0]
        if key.startswith(":"):
            section = _keyword(key[1:])
            seen.add(section)
            if bone is not None:
                raise MocapFormatError(path, f"bone block {bone.get('name', '?')!r} has no 'end'", ln)
            continue
        k = _keyword(key)
        if section == "units":
            if k == "length":
                length_unit = _floats(tok[1:2], 1, path, ln, "units length")[0]
                low, high = _UNIT_RANGE
                if not low <= length_unit <= high:
                    raise MocapFormatError(path, f"units length {describe(length_unit)} is outside {low:g} to {high:g} "
                                                 "(one unit is 1/length inch)", ln)
                units_line = ln
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
            elif k == "position":
                root[k] = _floats(tok[1:], 3, path, ln, "root position")
                root["position_line"] = ln
            elif k == "orientation":
                root[k] = _floats(tok[1:], 3, path, ln, "root orientation", *_angle_limit(degrees))
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
            elif k == "id":
                _floats(tok[1:], 1, path, ln, "id")
            elif k == "direction":
                bone["direction"] = _floats(tok[1:], 3, path, ln, "direction")
                bone["direction_line"] = ln
            elif k == "length":
                bone["length"] = _floats(tok[1:], 1, path, ln, "length")[0]
                if bone["length"] < 0:
                    raise MocapFormatError(path, f"bone length {describe(bone['length'])} is negative", ln)
                bone["length_line"] = ln
            elif k == "axis":
                if len(tok) != 5:
                    raise MocapFormatError(path, "axis needs three angles and an order, e.g. 'axis 0 0 20 XYZ'", ln)
                bone["axis"] = _floats(tok[1:4], 3, path, ln, "axis", *_angle_limit(degrees))
                bone["order"] = _check_order(tok[4], path, ln)
            elif k == "dof":
                dof = tuple(t.lower() for t in tok[1:])
                bad = [d for d in dof if d not in _ROT_DOFS]
                if bad or len(set(dof)) != len(dof):
                    raise MocapFormatError(
                        path, f"unsupported DOF {' '.join(bad or dof)!r} (rotational rx, ry, rz only)", ln
                    )
                bone["dof"] = dof
            elif k == "limits" or key.startswith("("):  # a limits line, or its continuation (one pair a line)
                check_limits(tok[1:] if k == "limits" else tok, path, ln, *_angle_limit(degrees))
        elif section == "hierarchy":
            if k in ("begin", "end"):
                continue
            for child in tok[1:]:
                if child in hierarchy:
                    raise MocapFormatError(path, f"bone {child!r} has two parents in :hierarchy", ln)
                hierarchy[child] = tok[0]
                hierarchy_line[child] = ln
    if bone is not None:
        raise MocapFormatError(path, f"file ends inside bone block {bone.get('name', '?')!r}", len(lines))
    for need in ("bonedata", "hierarchy"):
        if need not in seen:
            raise MocapFormatError(path, f"no :{need} section (not an ASF file?)")
    if not bones:
        raise MocapFormatError(path, "no bones in :bonedata")
    names = [b["name"] for b in bones]
    dup = [n for n, c in Counter(names).items() if c > 1]
    if dup:
        second = [b for b in bones if b["name"] == min(dup)][1]
        raise MocapFormatError(path, f"bone {min(dup)!r} defined twice", second["line"])
    known = set(names) | {"root"}
    for child, parent in hierarchy.items():
        if child not in known or parent not in known:
            missing = child if child not in known else parent
            raise MocapFormatError(path, f":hierarchy names unknown bone {missing!r}", hierarchy_line[child])
    orphans = [i for i, n in enumerate(names) if n not in hierarchy]
    if orphans:
        raise MocapFormatError(path, f"bone {names[orphans[0]]!r} is not in :hierarchy", bones[orphans[0]]["line"])
    order, parent_index = _topological_order(names, hierarchy, path, hierarchy_line)
    bones = [bones[i] for i in order]
    cm = 2.54 / length_unit
    lengths = np.array([b["length"] for b in bones])  # file units; compared before scaling (1e308 * cm overflows)
    long = np.flatnonzero(~(lengths <= DISTANCE_LIMIT_CM / cm))
    if long.size:
        b = bones[long[0]]
        raise MocapFormatError(path, f"bone {b['name']!r} is {describe(b['length'] * cm)} cm long (length "
                                     f"{describe(b['length'])} at :units length {describe(length_unit)}"
                                     f"{'' if units_line is None else f', line {units_line}'}), beyond "
                                     f"{DISTANCE_LIMIT_CM:g} cm", b["length_line"])
    if first_outside(np.array(root["position"]), DISTANCE_LIMIT_CM / cm) is not None:
        raise MocapFormatError(path, f"root position {' '.join(map(describe, root['position']))} is beyond "
                                     f"±{DISTANCE_LIMIT_CM:g} cm", root.get("position_line"))
    root_position = np.array(root["position"]) * cm
    lengths = lengths * cm
    direction = unit_directions([b["direction"] for b in bones], [b["name"] for b in bones],
                                [b["direction_line"] for b in bones], path)
    offsets = direction * lengths[:, None]
    axis_q = np.stack([rotations.from_euler(b["order"], b["axis"], degrees) for b in bones])
    return AsfSkeleton(
        path=path,
        bone_names=tuple(b["name"] for b in bones),
        parents=parent_index,
        offsets=offsets,
        axis_quaternions=axis_q,
        axis_orders=tuple(b["order"] for b in bones),
        dofs=tuple(b["dof"] for b in bones),
        root_order=tuple(root["order"]),
        root_axis=root["axis"],
        root_position=root_position,
        root_quaternion=rotations.from_euler(root["axis"], root["orientation"], degrees),
        cm_per_unit=cm,
        degrees=degrees,
    )


def _keyword(word: str) -> str:
    """A keyword in lower case; a word with other than ASCII letters is no keyword ("ſ".upper() is "S")."""
    return word.lower() if word.isascii() else word


def _topological_order(names: list[str], hierarchy: dict[str, str], path, lines: dict[str, int]
                       ) -> tuple[list[int], np.ndarray]:
    """Bones (file indices) in a stable order where each comes after its parent, and each one's parent index in
    that order (-1: the root).

    The order is that of repeated passes over the bones in file order, each placing the bones whose parent is
    placed (the order the readers always had), found in one walk: a bone is placed in its parent's pass when it
    comes after its parent in the file, in the next pass otherwise. Linear in the number of bones.
    """
    index = {n: i for i, n in enumerate(names)}
    children: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        children.setdefault(hierarchy[n], []).append(i)
    passes = np.full(len(names), -1, dtype=np.int64)
    todo = [("root", -1, 0)]  # (bone, its file index, its pass)
    while todo:
        parent, at, k = todo.pop()
        for i in children.get(parent, ()):
            passes[i] = k + (i < at) if at >= 0 else 1
            todo.append((names[i], i, int(passes[i])))
    stuck = np.flatnonzero(passes < 0)
    if stuck.size:
        raise MocapFormatError(path, f":hierarchy has a cycle through bone {names[stuck[0]]!r}",
                               lines.get(names[stuck[0]]))
    order = np.lexsort((np.arange(len(names)), passes)).tolist()
    position = {i: k for k, i in enumerate(order)}
    parents = np.array([position[index[hierarchy[names[i]]]] if hierarchy[names[i]] != "root" else -1
                        for i in order], dtype=np.int64)
    return order, parents


def _header_end(raw: bytes, path) -> tuple[int, int, bool | None]:
    """Byte offset and 1-based line number where the frames start, and the angle unit the header states."""
    pos = 0
    line = 1
    degrees = None
    while pos < len(raw):
        nl = raw.find(b"\n", pos)
        end = len(raw) if nl < 0 else nl
        s = raw[pos:end].strip()
        if s and not s.startswith(b"#") and not s.startswith(b":"):
            return pos, line, degrees
        if s.upper() == b":RADIANS":
            degrees = False
        elif s.upper() == b":DEGREES":
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
        Frame rate (AMC files do not store it; CMU and HDM05 are 120), 1 to 10,000.

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
        malformed or non-finite numbers, angles or translations beyond the limits of :mod:`mocapviz.io.checks`;
        the message names the file and line.
    ParameterError
        ``fps`` outside 1 to 10,000.
    """
    path = os.fspath(path)
    try:
        problem = fps_problem(float(fps))
    except (TypeError, ValueError):
        problem = f"{fps!r} is not a number"
    if problem:
        raise ParameterError(f"fps of {path}: {problem}")
    raw = read_bytes(path)
    start, first_line, header_degrees = _header_end(raw, path)
    sc = scan(raw, path, first_line, start=start)
    del raw
    degrees = skeleton.degrees if header_degrees is None else header_degrees
    lineno = lambda i: first_line + int(i)

    blank_or_name = (sc.name_start >= 0) | (sc.n_values == 0)
    odd = ~blank_or_name & (sc.n_values > 1)
    if odd.any():
        raise MocapFormatError(path, "expected a frame number or a bone line", lineno(np.argmax(odd)))
    markers = np.flatnonzero(~blank_or_name)  # lines holding one number: frame numbers
    del blank_or_name, odd
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
            path, f"frame numbers jump from {frame_numbers[k]:.15g} to {frame_numbers[k + 1]:.15g}", lineno(markers[k + 1])
        )
    n_frames = markers.size

    # line_of[f, b]: the line of bone b in frame f, counted from the frame's number (-1: none), in one pass over the
    # lines; in the smallest integer type that holds the longest frame (1 byte a bone for real skeletons)
    names = ("root",) + skeleton.bone_names
    n_joints = len(names)
    counts = np.array([len(skeleton.root_order)] + [len(d) for d in skeleton.dofs], dtype=np.int64)
    known = _channel_layout(skeleton).name_hashes
    by_hash = np.argsort(known)
    longest = int(np.diff(markers, append=sc.n_lines).max())
    line_of = np.full((n_frames, n_joints), -1, dtype=next(t for t in _OFFSET_TYPES if longest <= np.iinfo(t).max))
    error = np.zeros(2, dtype=np.int64)
    _bone_lines_kernel(sc.name_start, sc.name_hash, sc.n_values, known[by_hash], by_hash, counts, line_of, error)
    code, line = int(error[0]), int(error[1])
    if code == _BEFORE_FIRST_FRAME:
        raise MocapFormatError(path, "bone line before the first frame number", lineno(line))
    if code == _UNKNOWN_BONE:
        raise MocapFormatError(
            path, f"unknown bone {sc.token(line)!r} (not in {os.path.basename(skeleton.path)})", lineno(line)
        )
    if code in (_WRONG_COUNT, _TWICE):
        b = int(by_hash[np.searchsorted(known[by_hash], sc.name_hash[line])])
        if code == _TWICE:
            raise MocapFormatError(path, f"bone {names[b]!r} appears twice in one frame", lineno(line))
        dof = " ".join(skeleton.root_order if b == 0 else skeleton.dofs[b - 1]) or "none"
        raise MocapFormatError(
            path, f"bone {names[b]!r} has {sc.n_values[line]} values, the skeleton gives it {counts[b]} ({dof})",
            lineno(line),
        )
    values, first_value = sc.values, sc.first_value
    del sc  # the file's bytes and the rest of the line layout are not needed any more
    n_frames = complete_frames(line_of >= 0, counts > 0, names, path, lambda f: f"{frame_numbers[f]:.0f}",
                               lambda f: lineno(markers[f]))
    markers, line_of = markers[:n_frames], line_of[:n_frames]

    layout = _channel_layout(skeleton)  # (every channel's bone has a line in every frame kept)
    bone, column, slot, trans = layout.bone, layout.column, layout.euler_slot, layout.translation
    rot = slot >= 0
    # per channel: the largest value accepted (angles in the file's unit; translations in file units)
    limit = np.where(rot, ANGLE_LIMIT_DEG if degrees else np.radians(ANGLE_LIMIT_DEG),
                     DISTANCE_LIMIT_CM / skeleton.cm_per_unit)
    n_bones = len(skeleton.bone_names)
    # the file's rotation channels as they are, in degrees, for Motion.euler
    channels = np.empty((n_frames, int(np.count_nonzero(rot))), dtype=np.float32)

    def block(a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        at = first_value[markers[a:b, None] + line_of[a:b][:, bone]] + column  # (b-a, channels): where each value is
        vals = values[at]
        bad = first_outside(vals, limit)
        if bad is not None:
            t, c = bad
            line = int(np.searchsorted(first_value, at[t, c], side="right") - 1)
            what = f"{'rotation' if rot[c] else 'translation'} of bone {names[bone[c]]!r}"
            unit = ("degrees" if degrees else "radians") if rot[c] else f"file units ({DISTANCE_LIMIT_CM:g} cm)"
            raise MocapFormatError(path, f"{what}: {describe(vals[t, c])} is beyond ±{limit[c]:g} {unit}",
                                   lineno(line))
        euler = np.zeros((b - a, (n_bones + 1) * 3))  # each joint's angles in its own axis order
        euler[:, slot[rot]] = vals[:, rot]
        channels[a:b] = vals[:, rot] if degrees else np.degrees(vals[:, rot])
        t_local = np.empty((b - a, n_bones + 1, 3))
        t_local[:, 1:] = skeleton.offsets
        translation = np.zeros((b - a, 3))
        translation[:, trans[~rot]] = vals[:, ~rot]
        t_local[:, 0] = translation * skeleton.cm_per_unit + skeleton.root_position
        return euler.reshape(b - a, n_bones + 1, 3), t_local

    axis_q = np.concatenate([skeleton.root_quaternion[None], skeleton.axis_quaternions])
    parents = np.concatenate([[-1], skeleton.parents + 1])
    positions, q_local, _ = checked_forward_kinematics(
        n_frames,
        parents,
        (skeleton.root_axis,) + skeleton.axis_orders,
        block,
        names=names,
        path=path,
        frame_line=lambda f: lineno(markers[f]),
        own_frame=np.ones(n_bones + 1, dtype=bool),
        pre=axis_q,
        post=_conj(axis_q),
        degrees=degrees,
    )
    return Motion(
        positions=positions,
        fps=fps,
        joint_names=names,
        parents=parents,
        quaternions=q_local,
        source=path,
        euler=channels,
    )


_BEFORE_FIRST_FRAME, _UNKNOWN_BONE, _WRONG_COUNT, _TWICE = 1, 2, 3, 4
_OFFSET_TYPES = (np.int8, np.int16, np.int32, np.int64)  # for line_of: lines from a frame's number to its bone lines


@numba.njit(cache=True, nogil=True)
def _bone_lines_kernel(name_start, name_hash, n_values, sorted_hashes, bone_of_sorted, counts, line_of, error):  # pragma: no cover
    # every line that starts with a name is a bone line of the frame of the last frame number before it; line_of
    # keeps how many lines after that frame number it is
    frame = -1
    start = 0
    for i in range(name_start.shape[0]):
        if name_start[i] < 0:
            if n_values[i] > 0:
                frame += 1  # (lines of more than one number were refused before)
                start = i
            continue
        if frame < 0:
            error[0], error[1] = _BEFORE_FIRST_FRAME, i
            return
        k = np.searchsorted(sorted_hashes, name_hash[i])
        if k >= sorted_hashes.shape[0] or sorted_hashes[k] != name_hash[i]:
            error[0], error[1] = _UNKNOWN_BONE, i
            return
        b = bone_of_sorted[k]
        if n_values[i] != counts[b]:
            error[0], error[1] = _WRONG_COUNT, i
            return
        if line_of[frame, b] >= 0:
            error[0], error[1] = _TWICE, i
            return
        line_of[frame, b] = i - start


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
