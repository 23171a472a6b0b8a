"""Relational features (mocapviz.features.relational): the feature tables against the spec, the primitives against
hand-made and closed-form answers, and the features' behaviour on real labelled HDM05 clips."""
from __future__ import annotations

import re
from dataclasses import replace
from functools import cache
from importlib import import_module
from itertools import pairwise

import numpy as np
import pandas as pd
import pytest

import mocapviz
from mocapviz import MotionDB, ParameterError
from mocapviz.db import batches
from mocapviz.features import RELATIONAL_SETS, feature_groups, feature_names, feature_table, relational_features
from mocapviz.motion.skeleton import CANONICAL_JOINTS

rf = import_module("mocapviz.features.relational")  # the module (its function is `relational_features`)

# spec §1.7 (motionTemplateFlipFeatureStructs.m): the 2006 left/right mirror permutation over F1-F39
MIRROR_2006 = [(1, 2), (3, 4), (5, 6), (7, 8), (11, 12), (13, 14), (15, 16), (17, 18), (20, 21), (25, 26), (27, 28),
               (29, 30), (33, 34), (35, 36)]  # fmt: skip
# spec §2: the 2005 left/right pairs, toolbox numbers
MIRROR_2005 = [(1, 2), (3, 4), (5, 6), (7, 8), (10, 11), (12, 13), (14, 15), (16, 17), (18, 19), (22, 23), (24, 25),
               (28, 29), (30, 31)]  # fmt: skip


def permutation(pairs, n) -> list[int]:
    p = list(range(n))
    for a, b in pairs:
        p[a - 1], p[b - 1] = b - 1, a - 1
    return p


def column(values, names, name) -> np.ndarray:
    return values[:, names.index(name)]


# ------------------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def clip(hdm05_dir, hdm05_labels):
    """clip(label, k) -> the k-th HDM05 clip of a class, canonical (cached)."""

    @cache
    def get(label: str, k: int = 0) -> mocapviz.Motion:
        files = hdm05_labels.loc[hdm05_labels["class"] == label, "file"].tolist()
        return mocapviz.load(hdm05_dir / files[k]).canonical()

    return get


@pytest.fixture(scope="module")
def features(clip):
    """features(label, k, relational_set) -> (values, names) of a clip (cached)."""

    @cache
    def get(label: str, k: int = 0, relational_set: str = "2005"):
        return relational_features(clip(label, k), relational_set)

    return get


def mirrored(motion: mocapviz.Motion) -> mocapviz.Motion:
    """Left/right mirror image: x -> -x and every l* joint swapped with its r* twin."""
    twin = [CANONICAL_JOINTS.index({"l": "r", "r": "l"}[n[0]] + n[1:]) if n[0] in "lr" and n != "root" else k
            for k, n in enumerate(CANONICAL_JOINTS)]  # fmt: skip
    return replace(motion, positions=motion.positions[:, twin] * np.float32([-1, 1, 1]), quaternions=None)


def symmetric_asf(src, dst) -> None:
    """Copy an ASF skeleton with every left bone as long as its right twin (so that hum_L = hum_R, femur_L =
    femur_R): the toolbox uses one side's unit for some features of both sides, which a mirror test must not see."""
    blocks = re.split(r"(?=\bbegin\b)", src.read_text())
    length = {}
    for b in blocks:
        name, size = re.search(r"\bname\s+(\S+)", b), re.search(r"\blength\s+(\S+)", b)
        if name and size:
            length[name.group(1)] = size.group(1)
    out = []
    for b in blocks:
        name = re.search(r"\bname\s+(l\S+)", b)
        if name and "r" + name.group(1)[1:] in length:
            b = re.sub(r"\blength\s+\S+", "length " + length["r" + name.group(1)[1:]], b)
        out.append(b)
    dst.write_text("".join(out))


# ----------------------------------------------------------------------------------------- the feature sets
@pytest.mark.parametrize("relational_set, sizes", [("2005", (11, 12, 8)), ("2006", (12, 14, 13))])
def test_names_and_groups(relational_set, sizes):
    names = feature_names(relational_set)
    groups = feature_groups(relational_set)
    assert RELATIONAL_SETS == ("2005", "2006")
    assert len(names) == sum(sizes) and len(set(names)) == len(names)
    assert all(re.fullmatch(r"[a-z][a-z0-9]*(_[a-z0-9]+)*", n) for n in names), names
    assert list(groups) == ["lower", "upper", "mix"]
    assert tuple(len(groups[g]) for g in ("lower", "upper", "mix")) == sizes
    order = ("lower", "upper", "mix") if relational_set == "2005" else ("upper", "lower", "mix")
    assert [n for g in order for n in groups[g]] == names  # columns: 2005 toolbox order, 2006 F1-F39
    table = feature_table(relational_set)
    assert table["name"].tolist() == names
    # each column names its spec row, in order: 2005 toolbox #1..#31, 2006 F1..F39
    key = r"2005 #(\d+)\b" if relational_set == "2005" else r"2006 F(\d+)\b"
    assert [int(re.match(key, s).group(1)) for s in table["spec"]] == list(range(1, len(names) + 1))
    # sided features come in r/l pairs
    for n in names:
        if re.match(r"[rl](foot|knee|leg|hand|elbow|arm)", n):
            assert {"r": "l", "l": "r"}[n[0]] + n[1:] in names, n


def test_names_say_what_one_means_and_shared_names_mean_the_same():
    n05, n06 = feature_names("2005"), feature_names("2006")
    # names other modules rely on
    for n in ("rknee_bent", "lknee_bent", "rfoot_fast", "lfoot_fast", "rfoot_raised", "lfoot_raised",
              "rhand_above_neck", "lhand_above_neck", "rfoot_behind", "rhand_fast", "feet_crossed"):  # fmt: skip
        assert n in n05
    for n in ("root_fast", "spine_horizontal", "rknee_bent", "rhand_above_neck_2006", "rfoot_raised_2006"):
        assert n in n06
    t05, t06 = feature_table("2005").set_index("name"), feature_table("2006").set_index("name")
    shared = sorted(set(n05) & set(n06))
    assert shared == ["feet_crossed", "lelbow_bent", "lknee_bent", "relbow_bent", "rknee_bent"]
    cols = ["definition", "op", "lax", "strict", "unit"]
    assert t05.loc[shared, cols].to_dict("index") == t06.loc[shared, cols].to_dict("index")
    # the documented toolbox quirks (spec §5): 2005 foot fast without hysteresis, root "fast" at 1 cm/s,
    # 2005 #4 in right-femur units; 2006 F1/F2/F5/F6/F35/F36 in left-humerus units, all other 2006 in right
    assert (t05.loc["rfoot_fast", "lax"], t05.loc["rfoot_fast", "strict"]) == (1.0, 1.0)
    assert (t05.loc["root_moving", "lax"], t05.loc["root_moving", "unit"]) == (1.0, "cm")
    assert t05.loc["lfoot_raised", "unit"] == "femur_r"
    left_humerus = {n for n in n06 if t06.loc[n, "unit"] == "humerus_l"}
    assert left_humerus == {"rhand_moving_forward", "lhand_moving_forward", "rhand_moving_up", "lhand_moving_up",
                            "shoulders_rotated_right", "shoulders_rotated_left"}  # fmt: skip
    assert t06["robust"].all() and not t05["robust"].iloc[23:].any()  # 2005 mix: single thresholds


def test_unknown_feature_set_lists_the_known_ones(clip):
    for call in (lambda: feature_names("2007"), lambda: feature_groups("x"),
                 lambda: relational_features(clip("squat1Reps"), "1999")):  # fmt: skip
        with pytest.raises(ValueError, match="2005, 2006"):
            call()


# -------------------------------------------------------------------------------------------- primitives
def test_hysteresis_cases_of_the_spec():
    robust = rf._robust
    b = lambda s: np.array([c == "1" for c in s])
    # 1. on at a rising edge of the strict stream, 2. off at the first 0 of the lax stream; a lax run without any
    #    strict 1 stays off; a strict 1 in the first frame is a rising edge (a 0 is prepended)
    assert robust(b("0111110110"), b("0011000000")).tolist() == b("0011110000").tolist()
    assert robust(b("1110011100"), b("1000001000")).tolist() == b("1110001100").tolist()
    # a strict stream that stays 1 switches on only once; a later rise after switching off switches on again
    assert robust(b("0111101111"), b("0011100110")).tolist() == b("0011100111").tolist()
    # 3. a rise of strict in the very frame where lax falls is discarded (only possible if strict is not in lax)
    assert robust(b("1100000"), b("0010000")).tolist() == b("0000000").tolist()
    assert robust(b("0000110"), b("0100000")).tolist() == b("0111110").tolist()  # on; off at the next fall only
    # 4. lax == strict: the identity
    rng = np.random.default_rng(0)
    f = rng.random(500) < 0.4
    assert (robust(f, f) == f).all()
    # causal: the output up to t depends on the inputs up to t only
    lax = rng.random(300) < 0.7
    strict = lax & (rng.random(300) < 0.3)
    full = robust(lax, strict)
    assert all((robust(lax[:t], strict[:t]) == full[:t]).all() for t in (1, 17, 150, 299))


def test_hysteresis_equals_the_run_description_and_restarts_per_document():
    rng = np.random.default_rng(1)
    lax = rng.random((3, 2000)) < 0.8
    strict = lax & (rng.random((3, 2000)) < 0.05)
    out = rf._robust(lax, strict)
    # spec §1.6: within each maximal run of lax ones, 1 from the first strict 1 to the end of the run
    expect = np.zeros_like(lax)
    for k in range(3):
        t = 0
        while t < lax.shape[1]:
            if not lax[k, t]:
                t += 1
                continue
            end = t
            while end < lax.shape[1] and lax[k, end]:
                end += 1
            hits = np.flatnonzero(strict[k, t:end])
            if hits.size:
                expect[k, t + hits[0] : end] = True
            t = end
    assert (out == expect).all()
    # documents: each starts switched off, with its own "0 prepended" rising edge
    bounds = [0, 700, 701, 2000]
    per_doc = np.concatenate([rf._robust(lax[:, a:b], strict[:, a:b]) for a, b in pairwise(bounds)], 1)
    assert (rf._robust(lax, strict, bounds) == per_doc).all()


def test_velocity_window_and_closed_form():
    assert [rf._window_frames(ms, 120) for ms in (100, 250, 0, 1000 * 2 / 120)] == [12, 30, 1, 2]
    assert [rf._window_frames(100, fps) for fps in (60, 30, 25, 240)] == [6, 3, 3, 24]
    rng = np.random.default_rng(2)
    x = np.cumsum(rng.normal(size=(3, 200)), axis=1)  # a random-walk trajectory, time last
    fps = 120.0
    for w in (1, 2, 5, 12, 30):
        v = rf._velocity(x, w, fps)
        c = -(-w // 2)
        # away from the ends: (x(i + 1 + w - c) - x(i + 1 - c)) / w, per frame -> per second
        i = np.arange(c - 1, 200 - 1 - w + c)
        assert np.allclose(v[:, i], (x[:, i + 1 + w - c] - x[:, i + 1 - c]) / w * fps)
        # everywhere: the toolbox recipe, step by step (mirror padding with the edge repeated, full convolution)
        d = np.diff(x, axis=1)
        d = np.concatenate([d, d[:, -1:]], axis=1)
        p = np.pad(d, [(0, 0), (c, c)], mode="symmetric")
        conv = np.stack([np.convolve(row, np.ones(w) / w) for row in p])
        assert np.allclose(v, conv[:, w : w + 200] * fps)
    # fewer frames than the window: first mirror-padded at the end up to w
    short = x[:, :5]
    d = np.diff(short, axis=1)
    d = np.pad(np.concatenate([d, d[:, -1:]], axis=1), [(0, 0), (0, 7)], mode="symmetric")
    p = np.pad(d, [(0, 0), (6, 6)], mode="symmetric")
    conv = np.stack([np.convolve(row, np.ones(12) / 12) for row in p])
    assert np.allclose(rf._velocity(short, 12, fps), conv[:, 12:17] * fps)


def test_geometric_primitives_on_hand_made_points():
    col = lambda *pts: np.array(pts, dtype=float).T  # (3, T)
    o, ex, ey, ez = col([0, 0, 0]), col([1, 0, 0]), col([0, 1, 0]), col([0, 0, 1])
    # plane through o, ex, ey with p3 = o: normal (ex - o) x (ey - o) = +z
    assert rf._plane_distance(ex, ey, o, col([3, -2, 2.5])) == pytest.approx([2.5])
    assert rf._plane_distance(ey, ex, o, col([3, -2, 2.5])) == pytest.approx([-2.5])  # order fixes the side
    assert rf._normal_plane_distance(o, ey, ez, col([7, 4, 9])) == pytest.approx([4.0])
    # point-segment distance: along the segment perpendicular, beyond the ends the balls (or infinity); the
    # touch kernel gives D / (scale * |p2 - p1|) with |p2 - p1| = 2, joints 0, 1, 2 = p1, p2, q
    q = col([1, 3, 0], [-3, 4, 0], [5, 0, 4])
    joints = np.zeros((24, 3, 3))
    joints[1, 0] = 2.0
    joints[2] = q
    for balls, expected in (((True, True), [3, 5, 5]), ((False, True), [3, np.inf, 5]), ((True, False), [3, 5, np.inf])):
        out = np.empty(3)
        rf._touch_kernel(joints, np.array([0]), np.array([1]), np.array([2]), np.array([balls[0]]),
                         np.array([balls[1]]), np.array([0.5]), out)
        assert out.tolist() == pytest.approx(expected)
    assert rf._plane_velocity(ex, ey, o, col([3, -2, 2.5])) == pytest.approx([2.5])
    assert rf._joint_angle(ex, ey, o) == pytest.approx([90.0])
    assert rf._joint_angle(ex, -ex, o) == pytest.approx([180.0])
    assert rf._segment_angle(ey, o, o, ey) == pytest.approx([180.0])  # (ey - o) vs (o - ey)
    assert rf._vector_angle(col([1, 1, 0]), np.array([[0.0], [1.0], [0.0]])) == pytest.approx([45.0])
    assert rf._vector_angle(col([1e-9, 1, 0]) * 1e8, col([0, 1, 0])) <= 1e-6  # cos rounded above 1 is clipped


def test_plane_normals_point_where_the_spec_says(clip):
    """Spec §1.1/§5.4 on real data: in jogging the body moves forwards, so the 2005 'foot back' plane normal
    points against the root's velocity, the 'hand front' and 2006 'root behind' normals along it."""
    m = clip("jogLeftCircle4StepsRstart")
    j = {n: m.positions[:, k].T.astype(float) for k, n in enumerate(CANONICAL_JOINTS)}
    v = rf._velocity(j["root"], 12, m.fps)
    v[1] = 0.0  # horizontal motion only
    along = lambda p1, p2, p3: np.mean(rf._plane_velocity(j[p1], j[p2], j[p3], v / rf._norm(v)))
    assert along("root", "lhip", "lankle") < -0.5  # 2005 #1: backwards
    assert along("root", "rankle", "rhip") < -0.5  # 2005 #2
    assert along("root", "lshoulder", "rshoulder") > 0.5  # 2005 #12: forwards
    assert along("lankle", "neck", "rankle") > 0.2  # 2006 F31 (the ankle line swings with the steps)
    assert along("neck", "rhip", "lhip") > 0.5  # 2006 F1


def test_features_follow_the_spec_formulas(clip):
    """A few features recomputed from the spec's formulas on a real clip whose first frame was scaled up by 25%
    about the root: units come from the first frame only (§1.3), so every threshold grows by 25%."""
    from mocapviz.motion.skeleton import body_sizes

    def scaled(label):
        m = clip(label)
        pos = m.positions.astype(np.float64)
        pos[0] = pos[0, :1] + 1.25 * (pos[0] - pos[0, :1])
        m = replace(m, positions=pos.astype(np.float32))
        pos = m.positions.astype(np.float64)
        joints = {n: pos[:, k] for k, n in enumerate(CANONICAL_JOINTS)}
        return m, pos, joints, body_sizes(m.positions), *relational_features(m, "2005"), *relational_features(m, "2006")

    robust = rf._robust
    # 2005 #13: plane (root, lshoulder, rshoulder), normal (root - rsh) x (lsh - rsh), lwrist 1.0 / 1.15 hum_L in front
    m, pos, j, size, v05, n05, v06, n06 = scaled("rotateArmsBothBackward1Reps")
    n = np.cross(j["root"] - j["rshoulder"], j["lshoulder"] - j["rshoulder"])
    d = ((j["lwrist"] - j["rshoulder"]) * n).sum(1) / np.linalg.norm(n, axis=1)
    expect = robust(d >= 1.0 * size["humerus_l"], d >= 1.15 * size["humerus_l"])
    assert np.array_equal(column(v05, n05, "lhand_in_front"), expect) and expect.any()

    m, pos, j, size, v05, n05, v06, n06 = scaled("kickLFront1Reps")

    # 2005 #4: y(ltoes) - y(root) + k femur_R >= 0, k = 1.4 / 1.2 (the RIGHT femur, spec §5.6)
    h = j["ltoes"][:, 1] - j["root"][:, 1]
    expect = robust(h + 1.4 * size["femur_r"] >= 0, h + 1.2 * size["femur_r"] >= 0)
    assert np.array_equal(column(v05, n05, "lfoot_raised"), expect)
    # 2006 F33: y(rfingers) < min y of the other joints (without rfingers, rwrist) + 1.4 / 1.2 hum_R
    others = [k for k, n in enumerate(CANONICAL_JOINTS) if n not in ("rfingers", "rwrist")]
    low = pos[:, others, 1].min(axis=1)
    y = j["rfingers"][:, 1]
    expect = robust(y < low + 1.4 * size["humerus_r"], y < low + 1.2 * size["humerus_r"])
    assert np.array_equal(column(v06, n06, "rhand_low"), expect)
    # 2006 F39: root speed from 1-frame forward differences (last one repeated) >= 2.0 / 2.3 hum_R per second
    step = np.diff(j["root"], axis=0)
    speed = np.linalg.norm(np.vstack([step, step[-1:]]), axis=1) * m.fps
    expect = robust(speed >= 2.0 * size["humerus_r"], speed >= 2.3 * size["humerus_r"])
    assert np.array_equal(column(v06, n06, "root_fast"), expect) and expect.any() and not expect.all()
    # 2006 F18: y(ltoes) - min y over all joints >= 1.0 / 1.2 hum_R
    h = j["ltoes"][:, 1] - pos[:, :, 1].min(axis=1)
    expect = robust(h >= 1.0 * size["humerus_r"], h >= 1.2 * size["humerus_r"])
    assert np.array_equal(column(v06, n06, "lfoot_raised_2006"), expect) and expect.any()
    # 2005 #27: root speed over a 2-frame window (x(i + 2) - x(i)) / 2 away from the ends, > 1 cm/s, no hysteresis
    speed = np.linalg.norm(j["root"][2:] - j["root"][:-2], axis=1) / 2 * m.fps
    assert np.array_equal(column(v05, n05, "root_moving")[:-2], speed > 1.0)
    # the scaled first frame matters: with the clip's own first frame the thresholds differ
    unscaled, _ = relational_features(clip("kickLFront1Reps"), "2006")
    assert not np.array_equal(unscaled[:, n06.index("lfoot_raised_2006")], column(v06, n06, "lfoot_raised_2006"))


# ---------------------------------------------------------------------------------- behaviour on real clips
@pytest.mark.parametrize("relational_set", RELATIONAL_SETS)
def test_output_shape_dtype_and_any_skeleton(hdm05_dir, hdm05_labels, clip, relational_set):
    raw = mocapviz.load(hdm05_dir / hdm05_labels["file"].iloc[0])  # ASF bone names, not canonical
    values, names = relational_features(raw, relational_set)
    assert values.dtype == np.bool_ and values.shape == (raw.n_frames, len(feature_names(relational_set)))
    assert names == feature_names(relational_set)
    same, _ = relational_features(raw.canonical(), relational_set)
    assert np.array_equal(values, same)


def test_bvh_rig(bandai1_files):
    m = mocapviz.load(bandai1_files[0])
    for s in RELATIONAL_SETS:
        values, names = relational_features(m, s)
        assert values.shape == (m.n_frames, len(names)) and values.any() and not values.all()


def test_squat_bends_both_knees_but_not_at_the_start(features):
    for k in range(4):
        for s in RELATIONAL_SETS:
            values, names = features("squat1Reps", k, s)
            both = column(values, names, "rknee_bent") & column(values, names, "lknee_bent")
            assert both.mean() > 0.3, (k, s)
            assert not both[:10].any(), (k, s)


def test_left_front_kick_raises_and_moves_the_left_foot(features):
    for s, raised, fast in (("2005", "foot_raised", "foot_fast"), ("2006", "foot_raised_2006", "foot_fast_2006")):
        left = dict.fromkeys(("raised", "fast"), 0)
        right = dict.fromkeys(("raised", "fast"), 0)
        for k in range(4):
            values, names = features("kickLFront1Reps", k, s)
            assert column(values, names, "l" + raised).any() and column(values, names, "l" + fast).any(), (k, s)
            for key, name in (("raised", raised), ("fast", fast)):
                left[key] += column(values, names, "l" + name).sum()
                right[key] += column(values, names, "r" + name).sum()
        # the supporting right foot steps too, but is never raised
        assert left["raised"] > 5 * right["raised"] and left["fast"] > 1.4 * right["fast"], (s, left, right)


def test_hopping_on_both_legs_moves_both_feet_together(features):
    """Both feet leave the floor together; F17/F18 measure a foot against the lowest body point and 2005 #3/#4
    against the root, so neither calls a foot "raised" in a plain hop (HDM05 hops lift the toes < 45 cm)."""
    for k in range(4):
        v05, n05 = features("hopBothLegs1hops", k, "2005")
        v06, n06 = features("hopBothLegs1hops", k, "2006")
        assert (column(v05, n05, "rfoot_fast") & column(v05, n05, "lfoot_fast")).any()
        assert (column(v06, n06, "rfoot_fast_2006") == column(v06, n06, "lfoot_fast_2006")).mean() > 0.85
        assert column(v06, n06, "root_fast").any()
        for name in ("rfoot_raised_2006", "lfoot_raised_2006"):
            assert not column(v06, n06, name).any()


def test_rotating_both_arms_lifts_both_hands_above_the_neck(features):
    for k in range(3):
        for s, suffix in (("2005", ""), ("2006", "_2006")):
            values, names = features("rotateArmsBothBackward1Reps", k, s)
            both = column(values, names, "rhand_above_neck" + suffix) & column(values, names, "lhand_above_neck" + suffix)
            assert both.any(), (k, s)


def test_grab_high_right_lifts_only_the_right_hand(features):
    for k in range(4):
        for s, suffix in (("2005", ""), ("2006", "_2006")):
            values, names = features("grabHighR", k, s)
            assert column(values, names, "rhand_above_neck" + suffix).mean() > 0.2, (k, s)
            assert not column(values, names, "lhand_above_neck" + suffix).any(), (k, s)


def test_lying_down_ends_with_a_horizontal_spine(features):
    for k in range(3):
        values, names = features("lieDownFloor", k, "2006")
        spine = column(values, names, "spine_horizontal")
        assert spine[-30:].all() and not spine[:10].any()
        assert column(values, names, "vertical_extent_small")[-30:].all()


def test_standing_still_at_the_start(features):
    for label in ("squat1Reps", "rotateArmsBothBackward1Reps"):
        for k in range(3):
            v05, n05 = features(label, k, "2005")
            v06, n06 = features(label, k, "2006")
            head05, head06 = v05[:12], v06[:12]
            assert not column(head06, n06, "root_fast").any(), (label, k)
            for name in ("rfoot_fast", "lfoot_fast"):
                assert not column(head05, n05, name).any(), (label, k, name)
                assert not column(head06, n06, name + "_2006").any(), (label, k, name)
            # the 2005 "root fast" tests 1 cm/s on a 2-frame window: practically "not at rest" (spec §5.2)
            assert column(v05, n05, "root_moving").mean() > 0.5


@pytest.mark.parametrize("relational_set", RELATIONAL_SETS)
def test_mirror_symmetry(hdm05_dir, hdm05_labels, tmp_path, relational_set):
    """Features of the mirrored clip, permuted left<->right, equal the clip's own (skeleton made symmetric, so the
    toolbox's one-sided units cannot differ)."""
    pairs = MIRROR_2005 if relational_set == "2005" else MIRROR_2006
    names = feature_names(relational_set)
    perm = permutation(pairs, len(names))
    for a, b in pairs:  # the spec's pairs are our r/l name pairs (and the two shoulder rotations)
        right, left = names[a - 1], names[b - 1]
        assert (right[0], left) == ("r", "l" + right[1:]) or (right, left) == ("shoulders_rotated_right",
                                                                              "shoulders_rotated_left")
    agree = []
    for label, rows in hdm05_labels.groupby("class"):
        for f in rows["file"].iloc[:2]:
            actor = f.split("_")[1]
            asf = tmp_path / f"HDM_{actor}.asf"
            if not asf.exists():
                symmetric_asf(hdm05_dir / "asf" / f"HDM_{actor}.asf", asf)
            m = mocapviz.load(hdm05_dir / f, asf=asf).canonical()
            a, _ = relational_features(m, relational_set)
            b, _ = relational_features(mirrored(m), relational_set)
            agree.append(a == b[:, perm])
    agree = pd.Series(np.concatenate(agree).mean(axis=0), index=names)
    # 2006 F1/F2 take the hand's velocity relative to the LEFT hip for both hands (toolbox), which a mirror
    # turns into the right hip: they differ when the pelvis turns
    loose = ["rhand_moving_forward", "lhand_moving_forward"] if relational_set == "2006" else []
    assert (agree.drop(loose) > 0.99).all(), agree[agree <= 0.99]
    assert (agree[loose] > 0.9).all(), agree[loose]


def test_frame_rate_independence(clip):
    velocity = {"2005": ["rfoot_fast", "lfoot_fast", "rhand_fast", "lhand_fast", "root_moving"],
                "2006": [n for n in feature_names("2006") if "moving" in n or "fast" in n]}  # fmt: skip
    assert len(velocity["2006"]) == 14
    for label in ("jogLeftCircle4StepsRstart", "kickLFront1Reps", "throwBasketball"):
        m = clip(label)
        m60 = m.resample(60)
        for s, chosen in velocity.items():
            a, names = relational_features(m, s)
            b, _ = relational_features(m60, s)
            a = a[::2][: len(b)]  # frame k at 60 Hz is frame 2k at 120 Hz
            cols = [names.index(n) for n in chosen]
            agree = (a[:, cols] == b[:, cols]).mean(axis=0)
            assert (agree > 0.95).all(), (label, s, dict(zip(chosen, agree.round(3))))
            assert a[:, cols].any(axis=0).sum() >= 3  # not trivially all 0


# ------------------------------------------------------------------------------------------------ MotionDB
def test_motiondb_equals_its_documents(hdm05_dir, hdm05_labels, tmp_path, monkeypatch, capsys):
    files = [hdm05_dir / hdm05_labels.loc[hdm05_labels["class"] == c, "file"].iloc[0]
             for c in ("squat1Reps", "hopBothLegs1hops", "kickLFront1Reps", "grabHighR")]  # fmt: skip
    db = MotionDB.ingest(files, tmp_path / "db", progress=False)
    for s in RELATIONAL_SETS:
        values, names = relational_features(db, s, progress=False)
        assert values.shape == (db.n_frames, len(names)) and names == feature_names(s)
        per_doc = np.concatenate([relational_features(db.motion(d), s)[0] for d in db.documents["doc_id"]])
        assert np.array_equal(values, per_doc)
        # in several batches (documents never split) the result is the same
        monkeypatch.setattr(rf, "_BATCH_FRAMES", 150)
        assert np.array_equal(relational_features(db, s, progress=False)[0], values)
        monkeypatch.undo()
    # the documents are computed apart: a hysteresis, a velocity window or a body size across a boundary would
    # make the concatenation differ from the single clips (checked above); the progress bar appears for many docs
    monkeypatch.setattr(batches, "PROGRESS_MIN_DOCUMENTS", 2)
    relational_features(db, progress=True)
    assert "relational features" in capsys.readouterr().err
    relational_features(db, progress=False)
    assert capsys.readouterr().err == ""


def test_feature_set_is_relational_set_with_a_warning(clip):
    m = clip("squat1Reps")
    new, names = relational_features(m, relational_set="2006")
    with pytest.warns(FutureWarning, match="feature_set= is deprecated; pass relational_set="):
        old, old_names = relational_features(m, feature_set="2006")
    assert names == old_names == feature_names("2006") and np.array_equal(old, new)


# --------------------------------------------------------------------------------------------- bad input
def test_bad_input_is_named(clip):
    m = clip("squat1Reps")
    with pytest.raises(ValueError, match=r"HDM_.*squat1Reps.*1 frame"):
        relational_features(m[:1])
    bad = m.positions.copy()
    bad[37, CANONICAL_JOINTS.index("lwrist"), 1] = np.nan
    with pytest.raises(ValueError, match=r"squat1Reps.*frame 37.*lwrist"):
        relational_features(replace(m, positions=bad))
    with pytest.raises(ParameterError, match="Motion or a MotionDB"):
        relational_features(m.positions)
