"""Markers -> the 24 canonical joints: joint-centre estimates for the CMU/HDM05 41-marker set and Vicon Plug-in Gait.

is_marker_motion   whether a Motion holds marker trajectories (a C3D file's: no skeleton, no rotations).
marker_gaps        the share of gap (NaN) frames per marker.
fill_gaps          short gaps filled by linear interpolation (at most ``max_gap_s``, default 0.25 s).
marker_set         which marker set a clip carries ("cmu" or "plug-in gait").
marker_joints      a marker Motion on the canonical joints (what :meth:`Motion.canonical` does with one).

The estimates (all lengths in cm; each offset scaled by a segment length measured on the clip, as the median over
its frames, because marker files carry no anthropometry):

- hips: Harrington et al. 2007 (below) from the pelvis markers: Plug-in Gait's LASI RASI and LPSI RPSI (or SACR),
  the CMU/HDM05 front and back waist markers LFWT RFWT LBWT RBWT in their places. root: the midpoint of the hips.
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

Gaps (NaN samples of a marker, :func:`marker_gaps`) up to ``max_gap_s`` (0.25 s: a fraction of a step) are filled
(:func:`fill_gaps`): linearly inside the clip, by holding the nearest sample at its start or end. Longer gaps are not
guessed (no rigid-cluster reconstruction): a joint that needs such a marker there cannot be placed, and
:func:`marker_joints` raises, naming the marker and frames (cut the clip with ``motion[a:b]`` or pass a larger
``max_gap_s``).

References
----------
.. [1] J. Harrington, A. Morris, C. Zavatsky et al. Prediction of the hip joint centre in adults, children, and
   patients with cerebral palsy based on magnetic resonance imaging. J. Biomech. 40(3), 595-602, 2007.
   In the pelvis frame (origin mid-ASIS, x forward, y up, z lateral), mm, PW = inter-ASIS distance, PD = distance
   from mid-ASIS to mid-PSIS: x = -0.24 PD - 9.9, y = -0.30 PW - 10.9, z = ±(0.33 PW + 7.3).
.. [2] R. B. Davis, S. Õunpuu, D. Tyburski, J. R. Gage. A gait analysis data collection and reduction technique.
   Human Movement Science 10(5), 575-587, 1991 (marker placement, the chord rule for knee and ankle centres).
.. [3] Vicon. Plug-in Gait Reference Guide (marker names LASI ... RTOE, chord function, offsets).
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import ParameterError, SkeletonMappingError
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
"""The markers each set needs for the 24 joints (Plug-in Gait: SACR may stand for LPSI and RPSI)."""


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
    have = set(names) | set((aliases or {}).keys())
    return "plug-in gait" if {"LASI", "RASI"} <= have else "cmu"


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
        Positions [shape=(T, 24, 3)], float32, cm, on :data:`~mocapviz.motion.skeleton.CANONICAL_JOINTS`; no
        rotations; ``fps``, ``source``, ``labels`` kept.

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
    See the module docstring: Harrington et al. 2007 (hips), Davis et al. 1991 (chord rule).

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
    aliases = dict(aliases or {})
    unknown = {k: v for k, v in aliases.items() if v not in motion.joint_names}
    if unknown:
        raise ParameterError(f"aliases {unknown} name markers {motion.source or 'the motion'} does not have; "
                             f"it has {', '.join(motion.joint_names)}")  # fmt: skip
    kind = marker_set(motion.joint_names, aliases)
    index = {n: k for k, n in enumerate(motion.joint_names)}
    index.update({k: index[v] for k, v in aliases.items()})
    if kind == "plug-in gait" and "SACR" in index and not {"LPSI", "RPSI"} <= set(index):
        index["LPSI"] = index["RPSI"] = index["SACR"]
    missing = [m for m in MARKER_SETS[kind] if m not in index]
    if missing:
        raise _missing_error(motion, kind, missing, index)
    filled = fill_gaps(motion.positions, motion.fps, max_gap_s).astype(np.float64)
    if np.isnan(filled[:, [index[m] for m in MARKER_SETS[kind]]]).any():
        raise _gap_error(motion, filled, index, kind, max_gap_s)
    joints = _joints(lambda name: filled[:, index[name]], kind)
    bad = ~np.isfinite(joints).all(axis=2)
    if bad.any():
        frames, which = np.flatnonzero(bad.any(axis=1)), [CANONICAL_JOINTS[j] for j in np.flatnonzero(bad.any(axis=0))]
        raise SkeletonMappingError(
            f"{motion.source or 'motion'}: no centre for {', '.join(which)} in {len(frames)} frames (first: frame "
            f"{frames[0]}): the markers that place them coincide there (a damaged file?)"
        )
    return replace(motion, positions=joints.astype(np.float32), joint_names=CANONICAL_JOINTS,
                   parents=CANONICAL_PARENTS, quaternions=None)  # fmt: skip


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


def _gap_error(motion: Motion, filled: np.ndarray, index: dict, kind: str, max_gap_s: float) -> SkeletonMappingError:
    parts = []
    for m in MARKER_SETS[kind]:
        gap = np.flatnonzero(np.isnan(filled[:, index[m]]).any(axis=1))
        if len(gap):
            parts.append(f"{m} (frames {gap[0]} to {gap[-1]}, {len(gap)} frames)")
    return SkeletonMappingError(
        f"{motion.source or 'motion'}: gaps longer than {max_gap_s:g} s in "
        f"{', '.join(parts)}; cut the clip (motion[a:b]) or fill more (mocapviz.motion.markers.marker_joints with "
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
    origin = (lasi + rasi) / 2
    back = (lpsi + rpsi) / 2
    width, depth = 10 * _length(lasi, rasi), 10 * _length(origin, back)  # mm
    side = _unit(rasi - lasi)
    fwd = origin - back
    fwd = _unit(fwd - np.sum(fwd * side, axis=-1, keepdims=True) * side)
    up = np.cross(side, fwd)
    x, y, z = (-0.24 * depth - 9.9) / 10, (-0.30 * width - 10.9) / 10, (0.33 * width + 7.3) / 10  # cm
    centre = origin + x * fwd + y * up
    return centre - z * side, centre + z * side


def _joints(marker, kind: str) -> np.ndarray:
    """The 24 canonical joints [shape=(T, 24, 3)] from ``marker(name) -> (T, 3)`` of the set ``kind``."""
    mid = lambda a, b: (marker(a) + marker(b)) / 2
    out = {}
    pelvis = ("LASI", "RASI", "LPSI", "RPSI") if kind == "plug-in gait" else ("LFWT", "RFWT", "LBWT", "RBWT")
    out["lhip"], out["rhip"] = harrington_hips(*(marker(n) for n in pelvis))
    out["root"] = sum(marker(n) for n in pelvis) / 4
    neck, chest = mid("CLAV", "C7"), mid("STRN", "T10")
    out["neck"] = out["lclavicle"] = out["rclavicle"] = neck
    out["chest"], out["belly"] = chest, (out["root"] + chest) / 2
    down = _unit(chest - neck)
    shank = "SHN" if kind == "cmu" else "TIB"
    for s in "lr":
        S = s.upper()
        hip, knee_m, ankle_m = out[s + "hip"], marker(S + "KNE"), marker(S + "ANK")
        knee = chord(hip, marker(S + "THI"), knee_m, MARKER_RADIUS_CM + _KNEE * _length(hip, knee_m))
        out[s + "knee"] = knee
        out[s + "ankle"] = chord(knee, marker(S + shank), ankle_m, MARKER_RADIUS_CM + _ANKLE * _length(knee, ankle_m))
        out[s + "toes"] = marker(S + "TOE")
        sho, elb = marker(S + "SHO"), marker(S + "ELB")
        arm = _length(sho, elb)
        out[s + "shoulder"] = shoulder = sho + (MARKER_RADIUS_CM + _SHOULDER * arm) * down
        out[s + "wrist"] = wrist = mid(S + "WRA", S + "WRB")
        wand = marker(S + "UPA") if kind == "cmu" else wrist
        out[s + "elbow"] = chord(shoulder, wand, elb, MARKER_RADIUS_CM + _ELBOW * arm)
        out[s + "fingers"] = marker(S + "FIN")
    centre = (marker("LFHD") + marker("RFHD") + marker("LBHD") + marker("RBHD")) / 4
    width = (_length(marker("LFHD"), marker("RFHD")) + _length(marker("LBHD"), marker("RBHD"))) / 2
    up = _unit(np.cross(mid("LFHD", "RFHD") - mid("LBHD", "RBHD"), mid("LFHD", "LBHD") - mid("RFHD", "RBHD")))
    out["head"], out["headtop"] = centre - _HEAD_DOWN * width * up, centre + _HEAD_UP * width * up
    return np.stack([out[j] for j in CANONICAL_JOINTS], axis=1)
