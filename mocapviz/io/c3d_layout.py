"""The layout of a C3D file, checked in Python before ezc3d reads it.

check_layout   the header and the parameter section walked, and checked against each other: what cannot be read
               right is refused with a MocapFormatError naming the field and both values, a file without marker
               trajectories with one saying what it holds instead; what is certain is read with a note (a
               MocapFormatWarning, issued by the reader) saying what was used instead.
Layout         what the check found: its notes and the header's first frame number.

A C3D file states its layout twice: in the 512-byte header (16-bit words: 2 points, 3 analog samples per frame of all
channels, 4-5 first and last frame, 7-8 scale, 9 data block, 10 analog samples per frame of one channel, 11-12 frame
rate) and in the POINT and ANALOG parameters (USED, FRAMES, SCALE, RATE, DATA_START). ezc3d reads the data by the
parameters where both exist (POINT:USED, POINT:FRAMES unless 0, POINT:RATE unless 0, ANALOG:USED, ANALOG:RATE /
POINT:RATE, POINT:SCALE's sign for the points) and by the header elsewhere (first frame, data block, the header
scale's sign for the analog samples); a file whose two copies disagree is damaged, and either reading of it can be
the wrong one (POINT:USED 43 in a file of 42 points shifts every marker by a sample; ANALOG:USED 1 where the header
has no analog samples crashes ezc3d). Checked:

- the file holds marker trajectories: a file of 0 points is refused saying what it holds instead (analog channels
  only: a force-plate or EMG recording; a ROTATION group only: a markerless system's segment poses);
- POINT:USED equals the header's point count (and is not 0);
- the header's first frame is not after its last; POINT:FRAMES (when stated and not 0) equals last - first + 1, or,
  beyond 65,535 frames, exceeds it while the header's 16-bit last frame is 65,535;
- POINT:RATE equals the header's rate; when one of them is not a frame rate (0, NaN, beyond 1 to 10,000 fps) the
  other is used, with a note; neither: refused;
- POINT:SCALE and the header scale are finite and non-zero, of one sign (negative: float data), and for integer
  data of one size (it scales every coordinate; for float data it scales nothing that is read);
- analog samples per frame in the header (word 3) = ANALOG:USED × word 10, word 10 = ANALOG:RATE / POINT:RATE,
  ANALOG:SCALE and OFFSET hold a value per channel; without analog channels ANALOG:RATE is still finite, not
  negative and at most one sample per frame per byte of the file (ezc3d allocates that many per frame);
- the parameters ezc3d indexes (POINT USED, SCALE, RATE, FRAMES; ANALOG USED, RATE, GEN_SCALE) hold a value;
- the header's data block equals POINT:DATA_START (when stated and not 0: ezc3d reads the header's) and starts
  after the parameter section; the point and analog data of every frame fit in the file, or the file ends with a
  whole frame before the frames stated (a writer that stated the frames it meant to record and stopped early): the
  frames it holds are read, with a note naming both counts. A file that ends inside a frame is refused.
- the parameter groups: every parameter in a group the section defines (group numbers need not be 1 to N: BTS
  numbers an empty group 20).

References
----------
.. [1] C3D.ORG, "The C3D File Format: A Technical User Guide" (2008-2021): the header, the parameter section, the
   POINT and ANALOG groups, processor types and DEC floating point.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from ..errors import MocapFormatError
from ..motion import fps_problem
from .checks import describe

__all__ = ["Layout", "check_layout"]

_BLOCK = 512
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS (big-endian)
_DEC = 85
_LONG_LAST = 65535  # the header's last frame of a file of more frames than its 16-bit word holds
_INDEXED = {"POINT": ("USED", "SCALE", "RATE", "FRAMES"), "ANALOG": ("USED", "RATE", "GEN_SCALE")}


@dataclass(frozen=True)
class _Header:
    """The header words that state the data's layout."""

    points: int
    analog: int  # samples per frame, all channels
    first: int
    last: int
    scale: float
    block: int  # 1-based block of the first frame's data
    per_frame: int  # analog samples per frame of one channel
    rate: float


@dataclass(frozen=True)
class Layout:
    """What :func:`check_layout` found in a C3D file that reads right.

    Attributes
    ----------
    notes : tuple of str
        What was read otherwise than the file states it (a frame rate of 0 replaced by the other copy's, the frames a
        truncated file holds), for the reader to warn; empty for a consistent file.
    first_frame : int
        The header's first frame number as the writer stored it (1 for most, 0 for some, 1166 for a take cut from a
        longer one).
    """

    notes: tuple
    first_frame: int


def check_layout(path) -> Layout:
    """Check a C3D file's header and parameters against each other and against the file's size.

    Parameters
    ----------
    path : str
        A ``.c3d`` file.

    Returns
    -------
    Layout
        The notes (empty for a consistent file) and the first frame number.

    Raises
    ------
    MocapFormatError
        Naming the file, the field and both values: no C3D header, a parameter section not laid out as the format
        says, header and parameters that disagree, a scale that is 0 or not finite, data that ends inside a frame;
        a file without marker trajectories saying what it holds (``analog data only: no marker trajectories``,
        ``rotations only: no marker trajectories``).
    """
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
    processor = data[start + 3]
    order = _PROCESSORS[processor]
    entries, end = _walk_parameters(path, data, start + 4, min(len(data), start + max(1, data[start + 2]) * _BLOCK),
                                    order)  # fmt: skip
    params = _Parameters(data, entries, order, processor)
    scale, rate = _floats(data[12:16] + data[20:24], order, processor)
    words = struct.unpack_from(order + "HHHH", data, 2), struct.unpack_from(order + "HH", data, 16)
    header = _Header(*words[0], scale, *words[1], rate)
    for group, names in _INDEXED.items():
        for name in names:
            if params.entry(group, name) and not len(params.numbers(group, name)):
                raise MocapFormatError(path, f"{group}:{name} holds no value")
    _markers(path, header, params)
    notes = []
    frames = _frames(path, header, params)
    fps = _rate(path, header, params, notes)
    _points(path, header, params)
    _scale(path, header, params)
    _analog(path, header, params, fps, frames, len(data))
    _data_block(path, header, params, end, frames, data, notes)
    return Layout(tuple(notes), header.first)


class _Parameters:
    """The numeric values of the parameter entries, decoded for the file's processor."""

    def __init__(self, data: bytes, entries: dict, order: str, processor: int):
        self._data, self._entries, self._order, self._processor = data, entries, order, processor

    def entry(self, group: str, name: str) -> tuple | None:
        """(data type, dimensions, byte offset of the values) of GROUP:NAME, or None when absent."""
        return self._entries.get((group, name))

    def numbers(self, group: str, name: str) -> np.ndarray:
        """Its values [shape=(n,)] float64 (integers as stored, signed), empty when absent or text."""
        kind, shape, at = self.entry(group, name) or (-1, (), 0)
        n = int(np.prod(shape, dtype=np.int64))
        raw = self._data[at : at + abs(kind) * n]
        if kind == 4:
            return _floats(raw, self._order, self._processor)
        if kind in (1, 2):
            return np.frombuffer(raw, self._order + ("i1" if kind == 1 else "i2")).astype(np.float64)
        return np.empty(0)

    def first(self, group: str, name: str) -> float | None:
        """Its first value (what ezc3d reads), None when absent or text."""
        values = self.numbers(group, name)
        return float(values[0]) if len(values) else None

    def count(self, group: str, name: str) -> float | None:
        """Its first value as a count: an integer read unsigned (C3D writers store counts above 32,767 so), a
        float rounded down (NaN and infinities as they are); None when absent."""
        value = self.first(group, name)
        if value is None or not math.isfinite(value):
            return value
        kind = self.entry(group, name)[0]
        return int(value) % 65536 if kind == 2 else int(value) % 256 if kind == 1 else math.floor(value)


def _floats(raw: bytes, order: str, processor: int) -> np.ndarray:
    """32-bit floats [shape=(len(raw) // 4,)] as float64: IEEE (Intel, MIPS) or DEC F-floating (the two 16-bit
    halves swapped and the exponent 2 higher than IEEE's)."""
    if processor != _DEC:
        return np.frombuffer(raw, order + "f4").astype(np.float64)
    b = np.frombuffer(raw, np.uint8).reshape(-1, 4)
    ieee = np.stack([b[:, 2], b[:, 3], b[:, 0], np.where(b[:, 1] > 0, b[:, 1] - 1, 0)], axis=1).astype(np.uint8)
    return ieee.view("<f4").ravel().astype(np.float64)


def _walk_parameters(path, data: bytes, at: int, end: int, order: str) -> tuple[dict, int]:
    """Walk the parameter entries from byte ``at`` to ``end``: each one inside the section and linking to the byte
    after its own data (as ezc3d requires, which reads the data first), valid types and dimensions, groups
    numbered 1 to N and defined once, every parameter in one of them.

    Returns ({(GROUP, NAME): (data type, dimensions, offset of the data)}, the byte after the last entry)."""
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
        after = described + 1 + data[described]  # the end of its description
        if step == 0:
            return _named(path, groups, params), after
        if link + step != after:
            fail(f"links to byte {link + step}, not to the end of its own data at byte {after}")
        at = after
    return _named(path, groups, params), at


def _named(path, groups: dict, params: dict) -> dict:
    """{(GROUP, NAME): entry} of {(group number, NAME): entry}, every parameter's group defined."""
    used = {g for g, _ in params}
    if used - set(groups):
        raise MocapFormatError(path, f"parameter section: groups {sorted(groups)} defined, parameters in groups "
                                     f"{sorted(used)} (group {min(used - set(groups))} is not defined)")  # fmt: skip
    return {(groups[g], name): value for (g, name), value in params.items()}


def _frames(path, header: _Header, params: _Parameters) -> int:
    """The number of frames: the header's, or POINT:FRAMES beyond the header's 16-bit last frame."""
    if header.first > header.last:
        raise MocapFormatError(path, f"the header's first frame {header.first} is after its last frame {header.last}")
    value = params.first("POINT", "FRAMES")
    if value is not None and params.entry("POINT", "FRAMES")[0] == 4 and not (math.isfinite(value) and value >= 0
                                                                              and value == int(value)):  # fmt: skip
        raise MocapFormatError(path, f"POINT:FRAMES {describe(value)} is not a number of frames")
    stated, counted = params.count("POINT", "FRAMES"), header.last - header.first + 1
    if not stated or stated == counted:
        return counted
    if header.last == _LONG_LAST and stated > counted:
        return stated
    raise MocapFormatError(path, f"POINT:FRAMES {stated} but the header says {counted} frames (first frame "
                                 f"{header.first}, last {header.last})")  # fmt: skip


def _rate(path, header: _Header, params: _Parameters, notes: list) -> float:
    """The frame rate, POINT:RATE or the header's; a note when one of them is no frame rate and the other is used."""
    stated = params.first("POINT", "RATE")
    shown = "absent" if stated is None else f"{describe(stated)} fps"
    if stated is not None and fps_problem(stated) is None:
        if fps_problem(header.rate) is None:
            if not math.isclose(stated, header.rate, rel_tol=1e-5):
                raise MocapFormatError(path, f"POINT:RATE {shown} but the header says {describe(header.rate)} fps")
        else:
            notes.append(f"the header's frame rate {describe(header.rate)} fps is no frame rate; read at "
                         f"POINT:RATE {shown}")  # fmt: skip
        return stated
    if fps_problem(header.rate) is None and not stated:
        notes.append(f"POINT:RATE {shown}; read at the header's {describe(header.rate)} fps")
        return header.rate
    raise MocapFormatError(path, f"POINT:RATE {shown} and the header's {describe(header.rate)} fps: "
                                 f"{fps_problem(stated or 0.0) or fps_problem(header.rate)}")  # fmt: skip


def _markers(path, header: _Header, params: _Parameters) -> None:
    """A file of 0 points (in the header and POINT:USED) refused saying what it holds instead of markers."""
    if header.points or params.count("POINT", "USED"):
        return
    point = "no POINT group" if params.entry("POINT", "USED") is None else "POINT:USED 0"
    rotations, channels = params.count("ROTATION", "USED"), params.count("ANALOG", "USED")
    if rotations:
        rate = params.first("ROTATION", "RATE")
        raise MocapFormatError(path, f"rotations only: no marker trajectories (0 points, {point}; ROTATION:USED "
                                     f"{rotations} segment rotations{'' if rate is None else f' at {describe(rate)} Hz'}"
                                     ": a markerless system's poses, which mocapviz does not read)")  # fmt: skip
    if channels:
        rate = params.first("ANALOG", "RATE")
        raise MocapFormatError(path, f"analog data only: no marker trajectories (0 points, {point}; ANALOG:USED "
                                     f"{channels} channels{'' if rate is None else f' at {describe(rate)} Hz'}: "
                                     "force plates, EMG or other analog signals)")  # fmt: skip


def _points(path, header: _Header, params: _Parameters) -> None:
    used = params.count("POINT", "USED")
    if used != header.points:
        shown = "absent" if used is None else used
        raise MocapFormatError(path, f"POINT:USED {shown} but the header says {header.points} points")
    if not used:
        raise MocapFormatError(path, "POINT:USED 0 and the header says 0 points: no marker data")


def _scale(path, header: _Header, params: _Parameters) -> None:
    """POINT:SCALE and the header's scale: finite, non-zero, one sign (negative: floats), for integers one size."""
    stated = params.first("POINT", "SCALE")
    if stated is None:
        raise MocapFormatError(path, f"no POINT:SCALE (the header's scale is {describe(header.scale)})")
    named = (("POINT:SCALE", stated), ("the header's scale", header.scale))
    for (name, value), (other, its) in zip(named, named[::-1]):
        if not math.isfinite(value) or value == 0:
            raise MocapFormatError(path, f"{name} {describe(value)} is no scale factor (finite, not 0); {other} is "
                                         f"{describe(its)}")  # fmt: skip
    if (stated < 0) != (header.scale < 0):
        raise MocapFormatError(path, f"POINT:SCALE {describe(stated)} but the header's scale is "
                                     f"{describe(header.scale)}: one says float data, the other integers "
                                     "(sign)")  # fmt: skip
    if stated > 0 and not math.isclose(stated, header.scale, rel_tol=1e-5):
        raise MocapFormatError(path, f"POINT:SCALE {describe(stated)} but the header's scale is "
                                     f"{describe(header.scale)} (integer data: it scales every "
                                     "coordinate)")  # fmt: skip


def _analog(path, header: _Header, params: _Parameters, fps: float, frames: int, size: int) -> None:
    """Analog channels × samples per frame as the header states them; SCALE and OFFSET per channel; ANALOG:RATE
    within what the file can hold."""
    channels = params.count("ANALOG", "USED") or 0
    rate = params.first("ANALOG", "RATE")
    per_frame = (rate or 0.0) / fps
    if channels or header.analog:
        if header.analog != channels * header.per_frame:
            raise MocapFormatError(path, f"ANALOG:USED {channels} channels × {header.per_frame} samples per frame "
                                         f"(header word 10) = {channels * header.per_frame}, but the header says "
                                         f"{header.analog} analog samples per frame (word 3)")  # fmt: skip
        if not (math.isfinite(per_frame) and math.floor(per_frame) == header.per_frame
                and math.isclose(per_frame, header.per_frame, rel_tol=1e-4)):  # ezc3d rounds down: 8.9999 is 8
            shown = "absent" if rate is None else f"{describe(rate)} Hz"
            raise MocapFormatError(path, f"ANALOG:RATE {shown} is {describe(per_frame)} samples per frame at "
                                         f"{describe(fps)} fps but the header says {header.per_frame} "
                                         "(word 10)")  # fmt: skip
        counts = {n: len(params.numbers("ANALOG", n)) for n in ("SCALE", "OFFSET")}
        if min(counts.values()) < channels:
            raise MocapFormatError(path, f"ANALOG:USED {channels} channels but {counts['SCALE']} ANALOG:SCALE and "
                                         f"{counts['OFFSET']} ANALOG:OFFSET values")  # fmt: skip
    elif rate is not None and not (math.isfinite(per_frame) and 0 <= per_frame * frames <= size):
        raise MocapFormatError(path, f"ANALOG:RATE {describe(rate)} Hz is {describe(per_frame)} analog samples per "
                                     f"frame at {describe(fps)} fps: more than the file holds")  # fmt: skip


def _data_block(path, header: _Header, params: _Parameters, end: int, frames: int, data: bytes, notes: list) -> None:
    """The header's data block = POINT:DATA_START (0: not stated), after the parameter section; every frame's data
    in the file, or a file ending with a whole frame before the frames stated (ezc3d reads the whole frames there
    are: a note naming both counts)."""
    stated, size = params.count("POINT", "DATA_START"), len(data)
    if stated and stated != header.block:
        raise MocapFormatError(path, f"the header's data block {header.block} but POINT:DATA_START {stated}")
    if (header.block - 1) * _BLOCK < end:
        raise MocapFormatError(path, f"the header's data block {header.block} (byte {(header.block - 1) * _BLOCK}) "
                                     f"starts inside the parameter section (it ends at byte {end})")  # fmt: skip
    start, frame = (header.block - 1) * _BLOCK, (4 * header.points + header.analog) * (4 if header.scale < 0 else 2)
    need = start + frames * frame
    if need <= size:
        return
    held, rest = divmod(max(0, size - start), frame)
    if not held or any(data[size - rest :]):
        raise MocapFormatError(path, f"truncated or damaged: {frames} frames of {header.points} points from block "
                                     f"{header.block} need {need} bytes, the file has {size}")  # fmt: skip
    notes.append(f"the header says {frames} frames but the file holds {held} (its data ends after frame {held}, "
                 f"at byte {size}): read the {held} frames it holds")  # fmt: skip
