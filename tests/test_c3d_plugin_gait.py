"""Vicon Plug-in Gait on the canonical skeleton (mocapviz.motion.markers), on the three gait-lab files of the
``c3d-markers`` archive (BTKData, BSD-3-Clause), each a gait-lab walk of a few seconds:

- btk_FunctionalWalk (120 fps, 438 frames): lower-body Plug-in Gait; its upper-body markers are named but never
  seen, so the trunk, arms and head stand on the pelvis (said in a warning);
- btk_PiG_Motion-FlatFoot-Full (100 fps, 315 frames): full-body Plug-in Gait, LFHD missing in its first 30 frames
  (0.3 s), placed from the three other head markers (rigid-body fill, said);
- btk_Gait (100 fps, 487 frames): the older Helen Hayes names (VSAC, LSHA, IJ, PX, LWRI) and no head markers; the
  subject is in view in frames 133 to 326 only: the frames outside are cut (said), the head placed on the trunk.

Skipped, with the reason, without ``../shared`` (the ``c3d_dir`` fixture of conftest.py).
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import find_peaks

import mocapviz
from mocapviz.errors import MocapFormatWarning, SkeletonMappingError
from mocapviz.features import relational_features
from mocapviz.motion.markers import fill_gaps, rigid_fill
from mocapviz.motion.skeleton import CANONICAL_JOINTS

J = CANONICAL_JOINTS.index
# file -> (frames in the file, fps, frames on the canonical joints, their first frame number, what the warning says)
FILES = {
    "btk_FunctionalWalk.c3d": (438, 120.0, 438, 480, r"no upper-body marker seen .* not measured"),
    "btk_PiG_Motion-FlatFoot-Full.c3d": (315, 100.0, 315, 148,
                                         r"head marker placed from the three others .*LFHD \(frames 0 to 29, 30 frames\)"),
    "btk_Gait.c3d": (487, 100.0, 194, 134,
                     (r"LFHD, RFHD, LBHD, RBHD, T10, .* the first 133 and the last 160 frames see none .* cut.*"
                      r"CLAV \(IJ\) \(frames 133 to 136, 4 frames\)")),
}  # fmt: skip


@pytest.fixture(scope="module")
def walks(c3d_dir):
    """File -> (marker Motion, canonical Motion, the conversion's warning text)."""
    out = {}
    for name, (*_, said) in FILES.items():
        markers = mocapviz.load(c3d_dir / name)
        with pytest.warns(MocapFormatWarning, match=said) as caught:
            joints = markers.canonical()
        out[name] = markers, joints, " ".join(str(w.message) for w in caught)
    return out


@pytest.mark.parametrize("name", FILES)
def test_the_three_files_convert_with_finite_joints(walks, name):
    frames, fps, kept, first, _ = FILES[name]
    markers, joints, said = walks[name]
    assert (markers.n_frames, markers.fps) == (frames, fps)
    assert joints.joint_names == CANONICAL_JOINTS and joints.positions.shape == (kept, 24, 3)
    assert np.isfinite(joints.positions).all() and joints.fps == fps and joints.labels["first_frame"] == first
    assert name in said  # the warning names the file


@pytest.mark.parametrize("name", FILES)
def test_thigh_and_shank_keep_an_adults_length(walks, name):
    """Thigh (hip to knee centre) and shank (knee to ankle centre) of each side: mean 35 to 50 cm (seen 37 to 41),
    and within 3 cm of it in 95 % of the frames (seen: std 0.3 to 0.8 cm), but btk_Gait's shanks within 6 cm: they
    read 34 to 42 cm, shorter as the knee bends (correlation with the knee angle -0.95; 8 to 58 degrees), while
    the markers LKNE to LANK stay within 2.9 cm of one length: its chord-rule knee centre lies off the knee's
    flexion axis (the older set's thigh wand is not lateral to the knee), a limit of the rule without the knee
    width the lab measured."""
    p = walks[name][1].positions
    for a, b in (("lhip", "lknee"), ("rhip", "rknee"), ("lknee", "lankle"), ("rknee", "rankle")):
        length = np.linalg.norm(p[:, J(a)] - p[:, J(b)], axis=1)
        within = 6.0 if name == "btk_Gait.c3d" and a.endswith("knee") else 3.0
        assert 35 < length.mean() < 50, (name, a, b, length.mean())
        assert np.percentile(np.abs(length - length.mean()), 95) < within, (name, a, b, length.std())


@pytest.mark.parametrize("name", FILES)
def test_their_features_look_like_walking(walks, name):
    """How it was checked, on the canonical joints of each file:

    - the pelvis (root) moves forward: its horizontal displacement over the clip divided by the clip's duration;
      seen 1.20, 1.15 and 1.45 m/s (FunctionalWalk, FlatFoot, Gait); required 0.8 to 2 m/s, with a vertical
      motion of at most 10 cm;
    - the hip flexes and extends with a stride's period: the thigh's angle (hip to knee) from the vertical in the
      plane of walking has peaks (scipy find_peaks, prominence 10 degrees) 0.92 to 1.11 s apart, and swings 35 to 50
      degrees; required: a peak interval 0.8 to 1.3 s and a swing above 25 degrees, on both sides;
    - the 2005 relational features show the feet alternating: ``lfoot_behind`` and ``rfoot_behind`` (a foot behind
      the plane of the other foot and the hips) each hold in at least two periods, and those of the two feet
      never overlap and take turns (seen: R 0-29, L 44-90, R 105-156, L 171-219, ... in FunctionalWalk).
    """
    joints = walks[name][1]
    p = joints.positions.astype(np.float64)
    root = p[:, J("root")]
    travel = root[-1] - root[0]
    travel[1] = 0
    speed = np.linalg.norm(travel) / 100 / (joints.n_frames / joints.fps)
    assert 0.8 < speed < 2.0 and np.ptp(root[:, 1]) < 10, (name, speed)
    forward = travel / np.linalg.norm(travel)
    for side in "lr":
        thigh = p[:, J(side + "knee")] - p[:, J(side + "hip")]
        angle = np.degrees(np.arctan2(thigh @ forward, -thigh[:, 1]))
        peaks, _ = find_peaks(angle, prominence=10)
        period = np.diff(peaks) / joints.fps
        assert len(peaks) >= 2 and ((0.8 < period) & (period < 1.3)).all(), (name, side, period)
        assert np.ptp(angle) > 25, (name, side, np.ptp(angle))
    values, names = relational_features(joints)
    left, right = values[:, names.index("lfoot_behind")], values[:, names.index("rfoot_behind")]
    assert not (left & right).any(), name
    starts = lambda b: np.flatnonzero(np.diff(np.r_[0, b.astype(int)]) == 1)
    order = sorted([(s, "l") for s in starts(left)] + [(s, "r") for s in starts(right)])
    sides = [side for _, side in order]
    assert sides.count("l") >= 2 and sides.count("r") >= 2, (name, order)
    assert all(a != b for a, b in itertools.pairwise(sides)), (name, order)  # the feet take turns


def test_lower_body_file_carries_a_standing_upper_body_on_the_pelvis(walks):
    """btk_FunctionalWalk sees no upper-body marker: the trunk and arms are placed in the pelvis frame (Winter's
    proportions of a height estimated from the legs), so they keep their distance to the root exactly and hang
    below the shoulders; the warning says they are not measured."""
    markers, joints, said = walks["btk_FunctionalWalk.c3d"]
    assert np.isnan(markers.joint("C7")).all() and "not measured" in said
    p = joints.positions
    for joint in ("neck", "head", "lwrist", "rshoulder"):
        d = np.linalg.norm(p[:, J(joint)] - p[:, J("root")], axis=1)
        assert d.std() < 0.2, (joint, d.std())  # seen 0.07 cm at most: the pelvis markers' skin motion
    assert (p[:, J("lwrist"), 1] < p[:, J("lelbow"), 1]).all() and (p[:, J("lelbow"), 1] < p[:, J("lshoulder"), 1]).all()
    assert 40 < (p[:, J("head")] - p[:, J("root")])[:, 1].mean() < 70


def test_head_gap_placed_by_rigid_fill_within_millimetres(c3d_dir):
    """btk_PiG_Motion-FlatFoot-Full sees LFHD from frame 30: blanking it for a second more (frames 100 to 199, where
    the file has it) and placing it from RFHD LBHD RBHD gives it back within 0.3 cm (seen: 0.10 cm mean, 0.17 cm
    worst), where a linear interpolation across the gap is 2.5 cm off on average."""
    m = mocapviz.load(c3d_dir / "btk_PiG_Motion-FlatFoot-Full.c3d")
    head = [m.joint_names.index(n) for n in ("LFHD", "RFHD", "LBHD", "RBHD")]
    truth = m.positions[100:200, head[0]].copy()
    gappy = m.positions.copy()
    gappy[100:200, head[0]] = np.nan
    out, placed = rigid_fill(gappy, head)
    assert placed[0].tolist() == list(range(30)) + list(range(100, 200)) and set(placed) == {0}
    error = np.linalg.norm(out[100:200, head[0]] - truth, axis=1)
    assert error.max() < 0.3
    linear = np.linalg.norm(fill_gaps(gappy, m.fps, 1.0)[100:200, head[0]] - truth, axis=1)
    assert linear.mean() > 5 * error.mean()
    with pytest.warns(MocapFormatWarning, match=r"LFHD \(frames 0 to 29 and 100 to 199, 130 frames\)"):
        joints = replace(m, positions=gappy).canonical()
    assert np.isfinite(joints.positions).all()
    assert ((joints.positions[:, J("head")] - joints.positions[:, J("root")])[:, 1] > 30).all()  # walking upright


def test_a_long_gap_in_a_leg_marker_refused_naming_file_marker_and_frames(c3d_dir):
    """The rigid fill is for the head cluster only: half a second of LKNE blanked in the FlatFoot file (the chord
    rule needs it) is refused, naming the file, the marker and the frames, never stored as NaN (nor said filled)."""
    m = mocapviz.load(c3d_dir / "btk_PiG_Motion-FlatFoot-Full.c3d")
    p = m.positions.copy()
    p[100:150, m.joint_names.index("LKNE")] = np.nan
    with pytest.raises(
        SkeletonMappingError, match=r"btk_PiG_Motion-FlatFoot-Full.c3d: gaps longer than 0.25 s in LKNE "
                                    r"\(frames 100 to 149, 50 frames\)"):  # fmt: skip
        replace(m, positions=p).canonical()
