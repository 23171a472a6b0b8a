"""Markers -> the 24 canonical joints: joint-centre estimates for the CMU/HDM05 41-marker set and Vicon Plug-in Gait.

is_marker_motion   whether a Motion holds marker trajectories (a C3D file's: no skeleton, no rotations).
marker_gaps        the share of gap (NaN) frames per marker.
fill_gaps          short gaps filled by linear interpolation (at most ``max_gap_s``, default 0.25 s).
marker_set         which marker set a clip carries ("cmu" or "plug-in gait").
match_set          how a clip matches its set: the markers the joints use, those missing, the variant (full or
                   lower body, head markers or not).
rigid_fill         gaps of a marker of a rigid cluster (the four head markers) placed from the others seen.
marker_joints      a marker Motion on the canonical joints (what :meth:`Motion.canonical` does with one).

The estimates (all lengths in cm; each offset scaled by a segment length measured on the clip, as the median over
its frames, because marker files carry no anthropometry):

- hips: Harrington et al. 2007 (below) from the pelvis markers: Plug-in Gait's LASI RASI and LPSI RPSI (or SACR),
  the CMU/HDM05 front and back waist markers LFWT RFWT LBWT RBWT in their places. root: the centre of the four
  pelvis markers.
- knees, ankles: the Plug-in Gait chord rule (Davis et al. 1991): the joint centre lies in the plane of the joint
  above, a lateral wand marker (thigh LTHI; shank LSHN for CMU, LTIB for Plug-in Gait) and the lateral joint
  marker (LKNE, LANK), at the offset d from that marker, medially, where the segment from the joint above meets
  the offset at a right angle. d = marker radius (0.7 cm, 14 mm markers) + half the joint's width, the width taken
  as 0.25 x thigh length (knee, hip to LKNE) and 0.17 x shank length (ankle, knee to LANK): knee and ankle widths
  of an adult (about 10.5 and 7 cm) over thigh and shank lengths (about 42 cm).
- elbows: the chord rule with the upper-arm wand LUPA (CMU) or, where there is none, the wrist centre (Plug-in
  Gait's rule), d = 0.7 cm + 0.12 x upper-arm length (shoulder to LELB): half an elbow width of about 7 cm.
- shoulders: LSHO moved down the trunk (from the mid-point of CLAV and C7 to that of STRN and T10) by 0.7 cm
  + 0.17 x upper-arm length: the glenohumeral centre lies about 5 cm below the acromion marker.
- wrists: the midpoint of the wrist-bar markers LWRA LWRB; fingers: LFIN; toes: LTOE.
- neck (and both clavicles, which the canonical skeleton puts at the neck): the midpoint of CLAV and C7; chest:
  that of STRN and T10; belly: midway between root and chest.
- head: the centre of the four head markers LFHD RFHD LBHD RBHD moved down the head's up axis (normal to its
  forward and left axes) by 0.5 x head width (|LFHD - RFHD| + |LBHD - RBHD|, halved) to the skull base, where the
  canonical head joint is; headtop: moved up by 0.6 x head width to the vertex.

Plug-in Gait as gait labs record it (:data:`PLUG_IN_GAIT_NAMES`, :data:`PLUG_IN_GAIT_OPTIONAL`):

- the older (Helen Hayes) names stand for the set's: VSAC for SACR, LSHA for LTIB, IJ (jugular notch) for CLAV,
  PX (xiphoid) for STRN, a single wrist marker LWRI for LWRA (the wrist is then that marker);
- without T10, the chest is behind STRN by half the trunk's depth there: STRN + (C7 - CLAV) / 2;
- without LFIN, the fingers lie along the forearm (LELB to the wrist) 0.055 H beyond the wrist, H the body height
  estimated from the legs (hip to ankle centre = 0.491 H, Winter 2009);
- without all four head markers, head and headtop lie on the trunk's axis (root to neck) 0.07 H and 0.18 H above
  the neck (skull base 0.89 H, vertex 1.0 H, jugular notch 0.82 H);
- a lower-body clip (no arm marker seen: LELB RELB LWRA RWRA; trunk markers such as C7 or LSHO may be there, as in
  the Davis protocol's lower-body set): the trunk, arms and head are not measured; they are placed in the pelvis frame (up, to the side) from the mid-hip point at Winter's heights (neck 0.29 H above it, chest 0.19,
  shoulders 0.27 and 0.12 H to the side, elbows 0.10, wrists -0.045, fingers -0.10, 0.13 H to the side; head 0.36,
  headtop 0.47): a standing upper body carried by the pelvis.

Marker names are matched as written, then upper-cased (a lab writing ``lasi`` or ``Lasi`` for LASI). Each of these
is said in one :class:`~mocapviz.errors.MocapFormatWarning` per clip, with the gaps filled.

Gaps (NaN samples of a marker, :func:`marker_gaps`), in this order, said in the warning (marker, frames):

1. the leading and trailing frames in which none of the markers the joints need is seen (the subject outside the
   cameras' view) are cut; ``labels["first_frame"]`` moves with the cut;
2. a head marker missing where the three others are seen is placed by a rigid-body fill (:func:`rigid_fill`,
   Söderkvist & Wedin 1993): the head is rigid, so this holds over gaps of any length (1 s of LFHD blanked in a
   real walk comes back within 0.2 cm, a linear fill is 2.5 cm off);
3. gaps up to ``max_gap_s`` (0.25 s: a fraction of a step) are filled (:func:`fill_gaps`): linearly inside the
   clip, by holding the nearest sample at its start or end.

Longer gaps in other markers are not guessed: a joint that needs such a marker there cannot be placed, and
:func:`marker_joints` raises, naming the file, the marker and frames (cut the clip with ``motion[a:b]`` or pass a
larger ``max_gap_s``). No non-finite position is ever returned.

References
----------
.. [1] J. Harrington, A. Morris, C. Zavatsky et al. Prediction of the hip joint centre in adults, children, and
   patients with cerebral palsy based on magnetic resonance imaging. J. Biomech. 40(3), 595-602, 2007.
   In the pelvis frame (origin mid-ASIS, x forward, y up, z lateral), mm, PW = inter-ASIS distance, PD = distance
   from mid-ASIS to mid-PSIS: x = -0.24 PD - 9.9, y = -0.30 PW - 10.9, z = ±(0.33 PW + 7.3).
.. [2] R. B. Davis, S. Õunpuu, D. Tyburski, J. R. Gage. A gait analysis data collection and reduction technique.
   Human Movement Science 10(5), 575-587, 1991 (marker placement, the chord rule for knee and ankle centres).
.. [3] Vicon. Plug-in Gait Reference Guide (marker names LASI ... RTOE, chord function, offsets).
.. [4] D. A. Winter. Biomechanics and Motor Control of Human Movement, 4th ed., Wiley, 2009, fig. 4.1 (segment
   lengths as fractions of the body height).
.. [5] I. Söderkvist, P.-Å. Wedin. Determining the movements of the skeleton using well-configured markers.
   J. Biomech. 26(12), 1473-1477, 1993.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import MocapFormatWarning, ParameterError, SkeletonMappingError
from ..validation import number
from .joints import CANONICAL_JOINTS, CANONICAL_PARENTS

if TYPE_CHECKING:  # a type only: motion.py reaches this module through Motion.canonical, never the other way
    from .motion import Motion

MAX_GAP_S = 0.25
MARKER_RADIUS_CM = 0.7
_KNEE, _ANKLE, _ELBOW, _SHOULDER = 0.125, 0.085, 0.12, 0.17  # offset (beyond the radius) per segment length
_HEAD_DOWN, _HEAD_UP = 0.5, 0.6  # per head width
_COMMON = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "CLAV", "STRN")
_SIDED = ("SHO", "ELB", "WRA", "WRB", "FIN", "THI", "KNE", "ANK", "TOE")
MARKER_SETS = {
    "cmu": _COMMON + tuple(s + m for s in "LR" for m in _SIDED + ("UPA", "SHN"))
    + ("LFWT", "RFWT", "LBWT", "RBWT"),
    "plug-in gait": _COMMON + tuple(s + m for s in "LR" for m in _SIDED + ("TIB",)) + ("LASI", "RASI", "LPSI", "RPSI"),
}  # fmt: skip
"""The markers each set uses for the 24 joints (Plug-in Gait: SACR may stand for LPSI and RPSI; the markers of
:data:`PLUG_IN_GAIT_OPTIONAL` may be absent, and the older names of :data:`PLUG_IN_GAIT_NAMES` stand for theirs)."""
PLUG_IN_GAIT_NAMES = {"SACR": "VSAC", "LTIB": "LSHA", "RTIB": "RSHA", "CLAV": "IJ", "STRN": "PX",
                      "LWRA": "LWRI", "RWRA": "RWRI"}  # fmt: skip
"""Plug-in Gait marker -> its older (Helen Hayes, Davis et al. 1991) name, taken where the clip lacks the first:
a single wrist marker WRI, the shank wand SHA, the virtual sacrum VSAC, the jugular notch IJ, the xiphoid PX."""
_HEAD = ("LFHD", "RFHD", "LBHD", "RBHD")
_UPPER = ("C7", "CLAV", "STRN", "LSHO", "LELB", "LWRA", "RSHO", "RELB", "RWRA")
_ARMS = ("LELB", "RELB", "LWRA", "RWRA")
PLUG_IN_GAIT_OPTIONAL = _HEAD + ("T10", "LWRB", "RWRB", "LFIN", "RFIN")
"""Plug-in Gait markers placed by a stated rule when the clip lacks them (or never sees them): see the module
docstring. Without an arm marker seen (LELB RELB LWRA RWRA), a clip is lower-body Plug-in Gait."""
# Heights of body landmarks as fractions of the body height H (Winter 2009, fig. 4.1): hip 0.530 (greater
# trochanter), ankle 0.039, so a leg (hip to ankle centre) is 0.491 H; the offsets below are (up, lateral) from the
# mid-hip point in H: shoulder 0.818 (acromion; the joint centre 0.02 H lower), elbow 0.630, wrist 0.485, knuckles
# 0.43 (between wrist and fingertip 0.377), skull base 0.89 (between chin 0.870 and eye 0.936), vertex 1.0;
# neck (jugular notch) 0.82, chest (xiphoid) 0.72; half the shoulder width 0.13 H.
_LEG_PER_H = 0.491
_STANDING = {"neck": (0.29, 0), "chest": (0.19, 0), "shoulder": (0.27, 0.12), "elbow": (0.10, 0.13),
             "wrist": (-0.045, 0.13), "fingers": (-0.10, 0.13), "head": (0.36, 0), "headtop": (0.47, 0)}  # fmt: skip


def is_marker_motion(motion: Motion) -> bool:
    """Whether ``motion`` holds marker trajectories: more than one point, none with a parent, no rotations.

    Parameters
    ----------
    motion : Motion

    Returns
    -------
    bool
        True for what :func:`mocapviz.io.c3d.read_c3d` returns.

    Examples
    --------
    >>> from mocapviz.motion import Motion
    >>> is_marker_motion(Motion(np.zeros((2, 3, 3)), 120.0, ("A", "B", "C"), [-1, -1, -1]))
    True
    """
    return motion.quaternions is None and motion.n_joints > 1 and bool((motion.parents < 0).all())


def marker_gaps(motion: Motion) -> pd.Series:
    """The share of frames in which each marker is missing (NaN).

    Parameters
    ----------
    motion : Motion
        A marker Motion.

    Returns
    -------
    pandas.Series of float
        Marker name -> share of gap frames, 0 to 1.

    Examples
    --------
    >>> from mocapviz.motion import Motion
    >>> p = np.zeros((4, 2, 3)); p[1:3, 1] = np.nan
    >>> marker_gaps(Motion(p, 120.0, ("A", "B"), [-1, -1])).tolist()
    [0.0, 0.5]
    """
    gaps = np.isnan(motion.positions).any(axis=2).mean(axis=0) if motion.n_frames else np.zeros(motion.n_joints)
    return pd.Series(gaps, index=list(motion.joint_names), name="gaps")


def fill_gaps(positions: np.ndarray, fps: float, max_gap_s: float = MAX_GAP_S) -> np.ndarray:
    """Gaps of at most ``max_gap_s`` between two seen samples filled by linear interpolation.

    Parameters
    ----------
    positions : np.ndarray [shape=(T, M, 3)]
        Marker positions, cm, NaN in gaps.
    fps : float
        Frames per second.
    max_gap_s : float
        The longest gap filled, seconds (``round(max_gap_s * fps)`` frames).

    Returns
    -------
    np.ndarray [shape=(T, M, 3)], float32
        A copy, the short gaps filled: inside the clip linearly between the samples either side, at its start or
        end by holding the nearest sample; longer gaps still NaN.

    Examples
    --------
    >>> p = np.arange(6.0).repeat(3).reshape(6, 1, 3); p[2:4] = np.nan
    >>> fill_gaps(p, 10.0, 0.2)[:, 0, 0].tolist(), bool(np.isnan(fill_gaps(p, 10.0, 0.1)).any())
    ([0.0, 1.0, 2.0, 3.0, 4.0, 5.0], True)
    """
    out = np.array(positions, dtype=np.float32)
    longest = round(max_gap_s * fps)
    frames = np.arange(len(out))
    for m in np.flatnonzero(np.isnan(out).any(axis=(0, 2))):
        gap = np.isnan(out[:, m]).any(axis=1)
        seen = np.flatnonzero(~gap)
        if not len(seen):
            continue
        nxt = np.searchsorted(seen, frames)  # the first seen frame at or after each frame
        after = np.where(nxt < len(seen), seen[np.minimum(nxt, len(seen) - 1)], len(out))
        before = np.where(nxt > 0, seen[np.maximum(nxt - 1, 0)], -1)
        short = gap & (after - before - 1 <= longest)  # np.interp holds the end values beyond the first/last seen
        for k in range(3):
            out[short, m, k] = np.interp(frames[short], seen, out[seen, m, k])
    return out


def marker_set(names, aliases: dict | None = None) -> str:
    """The marker set of a clip: "plug-in gait" (pelvis markers LASI RASI) or "cmu" (CMU/HDM05, the default).

    Parameters
    ----------
    names : sequence of str
        The clip's marker names.
    aliases : dict, optional
        Marker of :data:`MARKER_SETS` -> the clip's name for it.

    Returns
    -------
    str
        A key of :data:`MARKER_SETS`.
    """
    have = {n.upper() for n in names} | set((aliases or {}).keys())
    return "plug-in gait" if {"LASI", "RASI"} <= have else "cmu"


@dataclass(frozen=True)
class SetMatch:
    """How a marker clip matches the marker set of its names (:func:`match_set`).

    Attributes
    ----------
    kind : str
        The set, a key of :data:`MARKER_SETS`.
    body : str
        "full body", or "lower body" (Plug-in Gait without an arm marker seen: the upper body placed by rule).
    head : bool
        Whether the four head markers are seen.
    needed : tuple of str
        The markers of the set the joints are placed from.
    missing : tuple of str
        Those of ``needed`` the clip lacks or never sees: the joints cannot be placed unless empty.
    index : dict
        Marker of the set -> the clip's column for it (older names, aliases and upper-cased names resolved).
    notes : tuple of str
        The rules applied for markers a Plug-in Gait clip lacks (said in :func:`marker_joints`' warning).
    """

    kind: str
    body: str
    head: bool
    needed: tuple
    missing: tuple
    index: dict
    notes: tuple

    def describe(self) -> str:
        """One line: the set and its variant, or what it lacks.

        Examples
        --------
        >>> SetMatch("plug-in gait", "lower body", False, (), (), {}, ()).describe()
        'plug-in gait, lower body, no head markers'
        >>> SetMatch("cmu", "full body", False, ("LFHD", "C7"), ("LFHD", "C7"), {}, ()).describe()
        'none: closest cmu, which lacks LFHD, C7'
        """
        if self.missing:
            return f"none: closest {self.kind}, which lacks {', '.join(self.missing)}"
        return f"{self.kind}, {self.body}, {'with' if self.head else 'no'} head markers"


def match_set(motion: Motion, aliases: dict | None = None) -> SetMatch:
    """Which marker set a marker clip carries, in which variant, and which markers of it are missing.

    Parameters
    ----------
    motion : Motion
        A marker Motion (:func:`is_marker_motion`).
    aliases : dict, optional
        Marker of :data:`MARKER_SETS` -> the clip's name for it.

    Returns
    -------
    SetMatch
        The set (:func:`marker_set`), the markers the joints need, those missing; for Plug-in Gait the markers of
        :data:`PLUG_IN_GAIT_OPTIONAL` the clip lacks are not needed, nor the upper body of a lower-body clip.

    Raises
    ------
    ParameterError
        Aliases naming markers the clip does not have.

    Examples
    --------
    >>> from mocapviz.motion import Motion
    >>> names = ("lasi", "RASI", "SACR") + tuple(s + m for s in "LR" for m in ("THI", "KNE", "TIB", "ANK", "TOE"))
    >>> match = match_set(Motion(np.ones((2, len(names), 3)), 100.0, names, [-1] * len(names)))
    >>> match.describe(), match.index["LASI"], match.index["LPSI"] == match.index["SACR"]
    ('plug-in gait, lower body, no head markers', 0, True)
    """
    aliases = dict(aliases or {})
    unknown = {k: v for k, v in aliases.items() if v not in motion.joint_names}
    if unknown:
        raise ParameterError(f"aliases {unknown} name markers {motion.source or 'the motion'} does not have; "
                             f"it has {', '.join(motion.joint_names)}")  # fmt: skip
    kind = marker_set(motion.joint_names, aliases)
    index = {n: k for k, n in enumerate(motion.joint_names)}
    for k, n in enumerate(motion.joint_names):
        index.setdefault(n.upper(), k)
    if kind == "plug-in gait":
        index.update({m: index[old] for m, old in PLUG_IN_GAIT_NAMES.items() if m not in index and old in index})
    index.update({k: index[v] for k, v in aliases.items()})
    if kind == "plug-in gait" and "SACR" in index and not {"LPSI", "RPSI"} <= set(index):
        index["LPSI"] = index["RPSI"] = index["SACR"]
    seen = ~np.isnan(motion.positions).any(axis=2)  # (T, M)
    have = {m for m in MARKER_SETS[kind] if m in index and (seen[:, index[m]].any() or not motion.n_frames)}
    needed, notes, body = list(MARKER_SETS[kind]), [], "full body"
    if kind == "plug-in gait":
        upper = set(_UPPER + PLUG_IN_GAIT_OPTIONAL)
        if not have & set(_ARMS):
            trunk = [m for m in MARKER_SETS[kind] if m in upper and m in have]
            what = (f"no arm marker seen (a lower-body Plug-in Gait clip; {', '.join(trunk)} not used)" if trunk else
                    "no upper-body marker seen (a lower-body Plug-in Gait clip)")  # fmt: skip
            notes.append(f"{what}: the trunk, arms and head are not measured, they stand on the pelvis in a standing "
                         "posture (Winter 2009 proportions)")
            skip, body = upper, "lower body"
        else:
            skip = {m for m in PLUG_IN_GAIT_OPTIONAL if m not in have} | (set() if set(_HEAD) <= have else set(_HEAD))
            if skip:
                notes.append(f"{', '.join(m for m in PLUG_IN_GAIT_OPTIONAL if m in skip)} not used (absent, or "
                             f"not all four head markers): {_ESTIMATED_WHEN_ABSENT}")
        needed = [m for m in needed if m not in skip]
    missing = tuple(m for m in needed if m not in have)
    return SetMatch(kind, body, set(_HEAD) <= have and body == "full body", tuple(needed), missing, index,
                    tuple(notes))  # fmt: skip


def marker_joints(motion: Motion, aliases: dict | None = None, max_gap_s: float = MAX_GAP_S) -> Motion:
    """A marker Motion on the 24 canonical joints, by the joint-centre estimates of the module docstring.

    Parameters
    ----------
    motion : Motion
        Marker trajectories (:func:`is_marker_motion`), cm, y up, NaN in gaps.
    aliases : dict, optional
        Marker of :data:`MARKER_SETS` -> the clip's name for it, for clips that name markers otherwise
        (``{"LFWT": "LASI_1"}``); :meth:`Motion.canonical` passes its ``mapping`` here.
    max_gap_s : float
        The longest gap filled (:func:`fill_gaps`), seconds.

    Returns
    -------
    Motion
        Positions [shape=(T, 24, 3)], float32, cm, finite, on :data:`~mocapviz.motion.skeleton.CANONICAL_JOINTS`;
        no rotations; ``fps``, ``source``, ``labels`` kept. T is the clip's frames but the leading and trailing
        ones that see none of the markers needed (cut; ``labels["first_frame"]`` moved by the frames cut).

    Warns
    -----
    MocapFormatWarning
        Naming the clip, once, when anything was estimated or filled: frames cut, head markers placed by the
        rigid-body fill, short gaps filled (each marker with its frames), Plug-in Gait markers absent and placed
        by rule, a lower-body clip's upper body not measured.

    Raises
    ------
    SkeletonMappingError
        Markers of the set missing (naming them, with a template for ``aliases``: each needed marker -> "?" or the
        name found), a gap that cannot be filled in a marker a joint needs (naming marker and frames), or markers
        on top of each other where a joint needs them apart (naming joints and frames).
    ParameterError
        Aliases naming markers the clip does not have, or a negative ``max_gap_s``.

    References
    ----------
    See the module docstring: Harrington et al. 2007 (hips), Davis et al. 1991 (chord rule), Winter 2009 (body
    proportions), Söderkvist & Wedin 1993 (rigid-body fill).

    Examples
    --------
    >>> from mocapviz.motion import Motion
    >>> m = Motion(np.zeros((1, 2, 3)), 120.0, ("LFHD", "RFHD"), [-1, -1], source="walk.c3d")
    >>> marker_joints(m)
    Traceback (most recent call last):
    ...
    mocapviz.errors.SkeletonMappingError: walk.c3d: the cmu marker set lacks LBHD, RBHD, C7, ...
    """
    max_gap_s = number(max_gap_s, "max_gap_s", low=0)
    match = match_set(motion, aliases)
    kind, index, needed, notes = match.kind, match.index, list(match.needed), list(match.notes)
    if match.missing:
        raise _missing_error(motion, kind, list(match.missing), index)
    seen = ~np.isnan(motion.positions).any(axis=2)  # (T, M)
    have = {m for m in needed if seen[:, index[m]].any() or not motion.n_frames}
    name = lambda m: m if motion.joint_names[index[m]] == m else f"{m} ({motion.joint_names[index[m]]})"
    columns = sorted({index[m] for m in needed})
    rows = np.flatnonzero(seen[:, columns].any(axis=1))
    rows = rows if len(rows) else np.array([0, motion.n_frames - 1])  # no frame: nothing to cut
    if rows[0] > 0 or rows[-1] < motion.n_frames - 1:
        ends = [f"the first {rows[0]}" if rows[0] else "", f"the last {motion.n_frames - 1 - rows[-1]}"
                if rows[-1] < motion.n_frames - 1 else ""]  # fmt: skip
        notes.append(f"{' and '.join(e for e in ends if e)} frames see none of the markers the joints need (the "
                     f"subject outside the cameras' view): cut, the joints are frames {rows[0]} to {rows[-1]} of the "
                     f"{motion.n_frames}")
        motion = replace(motion, positions=motion.positions[rows[0]:rows[-1] + 1],
                         labels={**motion.labels, "first_frame": motion.labels.get("first_frame", 1) + int(rows[0])})
    positions = motion.positions
    if set(_HEAD) <= have:
        positions, placed = rigid_fill(positions, [index[m] for m in _HEAD])
        if placed:
            notes.append("gaps of a head marker placed from the three others seen (rigid-body fill: the "
                         f"cluster's nearest complete frame moved onto them): "
                         f"{_frames({_HEAD[k]: f for k, f in placed.items()}, _HEAD, name, rows[0])}")
    gappy = {m: np.flatnonzero(np.isnan(positions[:, index[m]]).any(axis=1)) for m in needed}
    filled = fill_gaps(positions, motion.fps, max_gap_s).astype(np.float64)
    if np.isnan(filled[:, [index[m] for m in needed]]).any():
        raise _gap_error(motion, filled, [(name(m), index[m]) for m in needed], max_gap_s, rows[0])
    gappy = {m: f for m, f in gappy.items() if len(f)}
    if gappy:
        notes.append(f"gaps of at most {max_gap_s:g} s filled (linearly inside the clip, the nearest sample held "
                     f"at its ends): {_frames(gappy, list(gappy), name, rows[0])}")
    if notes:
        warnings.warn(MocapFormatWarning(motion.source, "; ".join(notes)), stacklevel=2)
    joints = _joints({m: filled[:, index[m]] for m in needed}, kind)
    bad = ~np.isfinite(joints).all(axis=2)
    if bad.any():
        frames, which = np.flatnonzero(bad.any(axis=1)), [CANONICAL_JOINTS[j] for j in np.flatnonzero(bad.any(axis=0))]
        raise SkeletonMappingError(
            f"{motion.source or 'motion'}: no centre for {', '.join(which)} in {len(frames)} frames (first: frame "
            f"{frames[0]}): the markers that place them coincide there (a damaged file?)"
        )
    return replace(motion, positions=joints.astype(np.float32), joint_names=CANONICAL_JOINTS,
                   parents=CANONICAL_PARENTS, quaternions=None)  # fmt: skip


_ESTIMATED_WHEN_ABSENT = ("placed by rule (head markers: head and headtop on the trunk's axis above the neck; T10: "
                          "chest behind STRN by half the C7-CLAV depth; WRB: the wrist is WRA; FIN: fingers along "
                          "the forearm)")


def _frames(frames: dict, order, name=str, offset: int = 0) -> str:
    """``{marker: frame indices}`` as "LFHD (frames 0 to 29 and 100 to 199, 130 frames), ..." in ``order``, each
    marker shown as ``name(marker)``, frames counted from ``offset``; more than three stretches end in "...
    (n stretches)"."""
    parts = []
    for m in order:
        f = np.asarray(frames.get(m, []), dtype=np.int64) + offset
        if not len(f):
            continue
        cut = np.flatnonzero(np.diff(f) > 1)
        runs = [f"{a} to {b}" if b > a else f"{a}" for a, b in zip(f[np.r_[0, cut + 1]], f[np.r_[cut, len(f) - 1]])]
        shown = " and ".join(runs) if len(runs) <= 3 else f"{', '.join(runs[:3])}, ... ({len(runs)} stretches)"
        parts.append(f"{name(m)} (frames {shown}, {len(f)} frame{'s' if len(f) > 1 else ''})")
    return ", ".join(parts)


def rigid_fill(positions: np.ndarray, cluster: list) -> tuple[np.ndarray, dict]:
    """Markers of a rigid cluster (the four head markers) missing in frames where at least three of it are seen,
    placed by the rigid motion that best takes the cluster's nearest complete frame onto the markers seen.

    The rigid motion is the least-squares rotation and translation of the seen markers (Söderkvist & Wedin 1993,
    by the singular value decomposition); the missing marker moves with them: a "rigid body fill".

    Parameters
    ----------
    positions : np.ndarray [shape=(T, M, 3)]
        Marker positions, NaN in gaps.
    cluster : list of int
        Columns of the markers of one rigid segment (at least four).

    Returns
    -------
    (positions, placed) : np.ndarray [shape=(T, M, 3)], dict
        A copy with the gaps placed; ``placed``: position in ``cluster`` -> frames placed (int arrays), for the
        markers that had any. Frames with fewer than three cluster markers seen, or a clip without a complete frame,
        stay NaN.

    References
    ----------
    .. [1] I. Söderkvist, P.-Å. Wedin. Determining the movements of the skeleton using well-configured markers.
       J. Biomech. 26(12), 1473-1477, 1993.

    Examples
    --------
    >>> head = np.array([[0.0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 3]])
    >>> p = np.stack([head, head @ np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]]) + 5.0])  # turned 90 degrees, moved
    >>> gap = p.copy(); gap[1, 3] = np.nan
    >>> out, placed = rigid_fill(gap, [0, 1, 2, 3])
    >>> bool(np.allclose(out, p)), {k: v.tolist() for k, v in placed.items()}
    (True, {3: [1]})
    """
    out = np.array(positions, dtype=np.float64)
    sub = out[:, cluster]
    seen = ~np.isnan(sub).any(axis=2)
    complete = np.flatnonzero(seen.all(axis=1))
    todo = np.flatnonzero(~seen.all(axis=1) & (seen.sum(axis=1) >= 3))
    placed: dict = {}
    if not len(complete):
        return out.astype(positions.dtype), placed
    after = np.minimum(np.searchsorted(complete, todo), len(complete) - 1)
    before = np.maximum(after - 1, 0)
    nearest = np.where(np.abs(complete[before] - todo) < np.abs(complete[after] - todo), complete[before],
                       complete[after])  # fmt: skip
    for t, s in zip(todo, nearest):
        ok = seen[t]
        a, b = sub[s, ok], sub[t, ok]
        ca, cb = a.mean(axis=0), b.mean(axis=0)
        u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
        d = np.sign(np.linalg.det(vt.T @ u.T))
        rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
        for k in np.flatnonzero(~ok):
            out[t, cluster[k]] = (sub[s, k] - ca) @ rot.T + cb
            placed.setdefault(int(k), []).append(int(t))
    return out.astype(positions.dtype), {k: np.array(v) for k, v in placed.items()}


def _missing_error(motion: Motion, kind: str, missing: list, index: dict) -> SkeletonMappingError:
    names = motion.joint_names
    used = {names[index[m]] for m in MARKER_SETS[kind] if m in index}
    lines = ["aliases = {"]
    for m in MARKER_SETS[kind]:
        near = [n for n in names if n[:1].upper() == m[0] and n not in used] if m in missing else []
        note = f"  # candidates: {', '.join(near[:5])}" if near else ("  # not found" if m in missing else "")
        lines.append(f'    "{m}": "{names[index[m]] if m in index else "?"}",{note}')
    template = "\n".join(lines + ["}"])
    exc = SkeletonMappingError(
        f"{motion.source or 'motion'}: the {kind} marker set lacks {', '.join(missing)}, needed for the canonical "
        f"joints; the clip has {', '.join(names[:60])}{' ...' if len(names) > 60 else ''}. Pass mapping= (aliases: "
        f"marker of the set -> the clip's marker), for example this template with each '?' replaced:\n{template}"
    )
    exc.missing, exc.template = list(missing), template
    return exc


def _gap_error(motion: Motion, filled: np.ndarray, needed: list, max_gap_s: float, offset: int) -> SkeletonMappingError:
    """The gaps left in ``needed`` (``(shown name, column)`` each), frames counted from ``offset``."""
    gaps = {m: np.flatnonzero(np.isnan(filled[:, k]).any(axis=1)) for m, k in needed}
    parts = _frames(gaps, [m for m, _ in needed], offset=offset)
    return SkeletonMappingError(
        f"{motion.source or 'motion'}: gaps longer than {max_gap_s:g} s in "
        f"{parts}; cut the clip (motion[a:b]) or fill more (mocapviz.motion.markers.marker_joints with "
        f"a larger max_gap_s)"
    )


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _length(a: np.ndarray, b: np.ndarray) -> float:
    """Median distance between two trajectories [shape=(T, 3)], cm."""
    return float(np.nanmedian(np.linalg.norm(a - b, axis=-1)))


def chord(above: np.ndarray, wand: np.ndarray, marker: np.ndarray, offset: float) -> np.ndarray:
    """The chord rule (Davis et al. 1991; Plug-in Gait): a joint centre from a lateral marker and a wand.

    Parameters
    ----------
    above : np.ndarray [shape=(T, 3)]
        The joint centre above (hip for the knee, knee for the ankle, shoulder for the elbow), cm.
    wand : np.ndarray [shape=(T, 3)]
        A marker on the lateral side of the segment, in the plane of the joint's axis, cm.
    marker : np.ndarray [shape=(T, 3)]
        The lateral joint marker, cm.
    offset : float
        Marker radius + half the joint's width, cm.

    Returns
    -------
    np.ndarray [shape=(T, 3)]
        The joint centre J: in the plane of the three points, ``|J - marker| = offset``, ``(marker - J)``
        perpendicular to ``(above - J)``, on the side away from the wand.

    Examples
    --------
    >>> hip, wand, knee = np.array([[0.0, 40, 0]]), np.array([[8.0, 20, 0]]), np.array([[5.0, 0, 0]])
    >>> chord(hip, wand, knee, 5.0).round(2).tolist()  # the marker 5 cm lateral of a vertical femur
    [[0.0, 0.0, 0.0]]
    """
    u = above - marker
    length = np.linalg.norm(u, axis=-1, keepdims=True)
    u = _unit(u)
    away = marker - wand
    w = _unit(away - np.sum(away * u, axis=-1, keepdims=True) * u)
    cos = np.clip(offset / length, 0.0, 1.0)
    return marker + offset * (cos * u + np.sqrt(1.0 - cos**2) * w)


def harrington_hips(lasi, rasi, lpsi, rpsi) -> tuple[np.ndarray, np.ndarray]:
    """Left and right hip joint centres from the four pelvis markers (Harrington et al. 2007).

    Parameters
    ----------
    lasi, rasi, lpsi, rpsi : np.ndarray [shape=(T, 3)]
        Left/right anterior and posterior superior iliac spine markers, cm, y up.

    Returns
    -------
    (left, right) : np.ndarray [shape=(T, 3)] each
        cm. With PW (inter-ASIS) and PD (mid-ASIS to mid-PSIS) the clip's medians in mm, in the pelvis frame
        (origin mid-ASIS, x forward, y up, z to the side): x = -0.24 PD - 9.9, y = -0.30 PW - 10.9,
        z = 0.33 PW + 7.3 (mm).

    References
    ----------
    .. [1] Harrington et al. 2007, J. Biomech. 40(3), 595-602 (see the module docstring).

    Examples
    --------
    >>> one = lambda *p: np.array([p], dtype=float)  # ASIS 24 cm apart, PSIS 16 cm behind, standing, facing +z
    >>> left, right = harrington_hips(one(12, 0, 0), one(-12, 0, 0), one(4, 0, -16), one(-4, 0, -16))
    >>> left.round(2).tolist(), right.round(2).tolist()
    ([[8.65, -8.29, -4.83]], [[-8.65, -8.29, -4.83]])
    """
    origin, fwd, up, side = _pelvis_frame(lasi, rasi, lpsi, rpsi)
    width, depth = 10 * _length(lasi, rasi), 10 * _length(origin, (lpsi + rpsi) / 2)  # mm
    x, y, z = (-0.24 * depth - 9.9) / 10, (-0.30 * width - 10.9) / 10, (0.33 * width + 7.3) / 10  # cm
    centre = origin + x * fwd + y * up
    return centre - z * side, centre + z * side


def _pelvis_frame(lasi, rasi, lpsi, rpsi) -> tuple[np.ndarray, ...]:
    """Mid-ASIS and the pelvis axes [shape=(T, 3)] each: forward, up, to the right (LASI to RASI)."""
    origin = (lasi + rasi) / 2
    side = _unit(rasi - lasi)
    fwd = origin - (lpsi + rpsi) / 2
    fwd = _unit(fwd - np.sum(fwd * side, axis=-1, keepdims=True) * side)
    return origin, fwd, np.cross(side, fwd), side


def _joints(marker: dict, kind: str) -> np.ndarray:
    """The 24 canonical joints [shape=(T, 24, 3)] from ``marker[name] -> (T, 3)`` of the set ``kind`` (Plug-in Gait:
    the markers of :data:`PLUG_IN_GAIT_OPTIONAL`, or the whole upper body, may be absent: placed by rule)."""
    mid = lambda a, b: (marker[a] + marker[b]) / 2
    out = {}
    pelvis = [marker[n] for n in (("LASI", "RASI", "LPSI", "RPSI") if kind == "plug-in gait" else
                                  ("LFWT", "RFWT", "LBWT", "RBWT"))]  # fmt: skip
    out["lhip"], out["rhip"] = harrington_hips(*pelvis)
    out["root"] = sum(pelvis) / 4
    shank = "SHN" if kind == "cmu" else "TIB"
    for s in "lr":
        S = s.upper()
        hip, knee_m, ankle_m = out[s + "hip"], marker[S + "KNE"], marker[S + "ANK"]
        knee = chord(hip, marker[S + "THI"], knee_m, MARKER_RADIUS_CM + _KNEE * _length(hip, knee_m))
        out[s + "knee"] = knee
        out[s + "ankle"] = chord(knee, marker[S + shank], ankle_m, MARKER_RADIUS_CM + _ANKLE * _length(knee, ankle_m))
        out[s + "toes"] = marker[S + "TOE"]
    height = (_length(out["lhip"], out["lankle"]) + _length(out["rhip"], out["rankle"])) / 2 / _LEG_PER_H
    if "C7" not in marker:  # lower-body Plug-in Gait: a standing upper body carried by the pelvis
        *_, up, right = _pelvis_frame(*pelvis)
        base = (out["lhip"] + out["rhip"]) / 2
        at = lambda part, sign=0: base + height * (_STANDING[part][0] * up + sign * _STANDING[part][1] * right)
        out["neck"], out["chest"], out["head"], out["headtop"] = at("neck"), at("chest"), at("head"), at("headtop")
        for s, sign in (("l", -1), ("r", 1)):
            for part in ("shoulder", "elbow", "wrist", "fingers"):
                out[s + part] = at(part, sign)
    else:
        t10 = marker["T10"] if "T10" in marker else marker["STRN"] + marker["C7"] - marker["CLAV"]
        neck, chest = mid("CLAV", "C7"), (marker["STRN"] + t10) / 2
        out["neck"], out["chest"] = neck, chest
        down = _unit(chest - neck)
        for s in "lr":
            S = s.upper()
            sho, elb = marker[S + "SHO"], marker[S + "ELB"]
            arm = _length(sho, elb)
            out[s + "shoulder"] = shoulder = sho + (MARKER_RADIUS_CM + _SHOULDER * arm) * down
            out[s + "wrist"] = wrist = mid(S + "WRA", S + "WRB") if S + "WRB" in marker else marker[S + "WRA"]
            wand = marker[S + "UPA"] if kind == "cmu" else wrist
            out[s + "elbow"] = chord(shoulder, wand, elb, MARKER_RADIUS_CM + _ELBOW * arm)
            out[s + "fingers"] = (marker[S + "FIN"] if S + "FIN" in marker else
                                  wrist + (_STANDING["wrist"][0] - _STANDING["fingers"][0]) * height * _unit(wrist - elb))
        if set(_HEAD) <= set(marker):
            centre = sum(marker[n] for n in _HEAD) / 4
            width = (_length(marker["LFHD"], marker["RFHD"]) + _length(marker["LBHD"], marker["RBHD"])) / 2
            up = _unit(np.cross(mid("LFHD", "RFHD") - mid("LBHD", "RBHD"), mid("LFHD", "LBHD") - mid("RFHD", "RBHD")))
            out["head"], out["headtop"] = centre - _HEAD_DOWN * width * up, centre + _HEAD_UP * width * up
        else:  # no head markers: on the trunk's axis (root to neck) above the neck
            up = _unit(neck - out["root"])
            for part in ("head", "headtop"):
                out[part] = neck + (_STANDING[part][0] - _STANDING["neck"][0]) * height * up
    out["lclavicle"] = out["rclavicle"] = out["neck"]
    out["belly"] = (out["root"] + out["chest"]) / 2
    return np.stack([out[j] for j in CANONICAL_JOINTS], axis=1)
