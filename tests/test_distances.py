"""Frame distances of Krüger et al. 2010 §3.1 (Deuler, Dquat, Dpc_n, Dwb) on real HDM05 / Bandai Namco clips.

Checked against hand computations and brute force: Deuler against the AMC text, Dpc_1 against a grid search over
rotation angles, window clouds against explicit frame lists; and the properties the measures must have (zero
self-distance, symmetry, pairwise = one-to-many, quaternion sign and rigid floor-motion invariance, weight-0
joints ignored), plus the errors for bad input.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mocapviz.features.distances import (
    LEE_WEIGHTS,
    WB_WEIGHTS,
    deuler,
    deuler_pairwise,
    dpc,
    dpc_pairwise,
    dquat,
    dquat_pairwise,
    dwb,
    dwb_pairwise,
    joint_weights,
    lee_frames,
    pc_align,
    window_clouds,
)
from mocapviz.io import load, read_asf
from mocapviz.motion import Motion, rotations
from mocapviz.motion.skeleton import CANONICAL_JOINTS

JOG = "HDM_bd_jogLeftCircle4StepsRstart_001_120.amc"  # turns on a circle: root rz runs from -706 to -547 degrees
KICK = "HDM_bd_kickLFront1Reps_001_120.amc"  # same actor, root rz near -180


@pytest.fixture(scope="module")
def jog(hdm05_dir):
    return load(hdm05_dir / "amc" / JOG)


@pytest.fixture(scope="module")
def kick(hdm05_dir):
    return load(hdm05_dir / "amc" / KICK)


def _rot_y(positions, angle_deg, shift):
    """positions (..., 3) turned about the vertical axis and moved by ``shift`` (3,)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    r = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.asarray(positions, dtype=np.float64) @ r.T + shift


def _descriptors(motion, n=5):
    """Every measure's descriptors of every 4th frame (30 Hz) of a clip: name -> (T, ...) array."""
    canon = motion.canonical()
    frames = np.arange(0, motion.n_frames, 4)
    return {
        "deuler": motion.euler[frames],
        "dquat": canon.quaternions[frames],
        "dpc": window_clouds(canon.positions, n, frames=frames),
        "dwb": lee_frames(canon.quaternions, canon.fps)[frames],
    }


ONE_TO_MANY = {"deuler": deuler, "dquat": dquat, "dpc": dpc, "dwb": dwb}
PAIRWISE = {"deuler": deuler_pairwise, "dquat": dquat_pairwise, "dpc": dpc_pairwise, "dwb": dwb_pairwise}
MEASURES = sorted(ONE_TO_MANY)


# --------------------------------------------------------------------------------------------- properties


@pytest.mark.parametrize("measure", MEASURES)
def test_zero_distance_to_itself_and_positive_to_others(jog, measure):
    desc = _descriptors(jog)[measure]
    for i in (0, len(desc) // 2, len(desc) - 1):
        d = ONE_TO_MANY[measure](desc[i], desc)
        assert d.shape == (len(desc),)
        others = np.delete(d, i)
        assert d[i] <= 1e-9 * np.median(others)
        assert (others > 1e3 * max(d[i], 1e-12)).all()


@pytest.mark.parametrize("measure", MEASURES)
def test_symmetric(jog, kick, measure):
    a, b = _descriptors(jog)[measure], _descriptors(kick)[measure]
    ab = PAIRWISE[measure](a, b)
    ba = PAIRWISE[measure](b, a)
    assert ab.shape == (len(a), len(b))
    np.testing.assert_allclose(ab, ba.T, rtol=1e-9, atol=1e-9)
    aa = PAIRWISE[measure](a, a)
    np.testing.assert_allclose(aa, aa.T, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("measure", MEASURES)
def test_pairwise_equals_one_to_many_row_by_row(jog, kick, measure):
    a, b = _descriptors(jog)[measure], _descriptors(kick)[measure]
    matrix = PAIRWISE[measure](a, b)
    for i in range(len(a)):
        np.testing.assert_allclose(matrix[i], ONE_TO_MANY[measure](a[i], b), rtol=1e-10, atol=1e-10)


def test_pairwise_blocks_match_one_block(jog, kick, monkeypatch):
    """The row blocks of the pairwise form (memory bound) do not change the result."""
    from mocapviz.features import distances

    a, b = _descriptors(jog)["dquat"], _descriptors(kick)["dquat"]
    whole = dquat_pairwise(a, b)
    monkeypatch.setattr(distances, "_BLOCK_ELEMENTS", 7 * b.size)
    np.testing.assert_array_equal(dquat_pairwise(a, b), whole)


# ----------------------------------------------------------------------------------------------- Deuler


def _amc_frame(path, frame_number):
    """{bone: [values]} of one frame of an AMC file, parsed by hand."""
    out, inside = {}, False
    with open(path, encoding="latin-1") as fh:
        for line in fh:
            tok = line.split()
            if not tok or tok[0].startswith(("#", ":")):
                continue
            if len(tok) == 1 and tok[0].isdigit():
                if inside:
                    break
                inside = int(tok[0]) == frame_number
                continue
            if inside:
                out[tok[0]] = [float(v) for v in tok[1:]]
    return out


def test_deuler_matches_hand_computation_on_amc_text(hdm05_dir, jog, kick):
    skeleton = read_asf(hdm05_dir / "asf" / "HDM_bd.asf")
    assert skeleton.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ")
    fj, fk = 101, 40  # AMC frame numbers (1-based)
    frames = [_amc_frame(hdm05_dir / "amc" / name, f) for name, f in ((JOG, fj), (KICK, fk))]
    channels = []
    for values in frames:
        row = values["root"][3:]  # translation excluded
        for bone, dof in zip(skeleton.bone_names, skeleton.dofs):
            if dof:
                row += values[bone]
        channels.append(row)
    assert len(channels[0]) == jog.euler.shape[1]
    total, wrapped = 0.0, False
    for x, y in zip(*channels):
        d = x - y
        wrapped |= abs(d) > 180
        while d > 180:
            d -= 360
        while d < -180:
            d += 360
        total += d * d
    assert wrapped  # root rz: -600-odd against -180-odd degrees
    got = deuler(jog.euler[fj - 1], kick.euler[fk - 1 : fk])
    assert got.shape == (1,)
    assert got[0] == pytest.approx(math.sqrt(total), abs=1e-3)
    np.testing.assert_allclose(jog.euler[fj - 1], channels[0], atol=1e-4)


def test_deuler_wraps_each_channel():
    a = np.array([179.0, -90.0, 10.0])
    frames = np.array([[-179.0, 270.0, 10.0], [179.0, -90.0, 370.0 + 3.0], [0.0, 90.0, 10.0]])
    np.testing.assert_allclose(deuler(a, frames), [2.0, 3.0, math.hypot(179.0, 180.0)])


# ------------------------------------------------------------------------------------------------ Dquat


def test_dquat_is_the_sum_of_rotation_angles_and_sign_invariant(jog, kick):
    a, b = jog.canonical().quaternions[::8], kick.canonical().quaternions[::8]
    q64a, q64b = a.astype(np.float64), b.astype(np.float64)
    q64a /= np.linalg.norm(q64a, axis=-1, keepdims=True)
    q64b /= np.linalg.norm(q64b, axis=-1, keepdims=True)
    expected = (2 * np.arccos(np.clip(np.abs(np.einsum("njc,mjc->nmj", q64a, q64b)), 0, 1))).sum(-1)
    got = dquat_pairwise(a, b)
    np.testing.assert_allclose(got, expected, atol=1e-5)  # arccos near 1 limits the reference
    assert got.min() > 0.1
    signs = np.where(np.random.default_rng(1).random(b.shape[:2]) < 0.5, -1.0, 1.0)[..., None]
    np.testing.assert_allclose(dquat_pairwise(a, b * signs), got, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dquat_pairwise(-a, b), got, rtol=1e-12, atol=1e-12)


def test_dquat_weights(jog, kick):
    a, b = jog.quaternions[::8], kick.quaternions[::8]  # the 31 ASF joints
    w = np.zeros(a.shape[1])
    w[jog.joint_names.index("lfemur")] = 2.0
    j = jog.joint_names.index("lfemur")
    expected = 2.0 * dquat_pairwise(a[:, j : j + 1], b[:, j : j + 1])
    np.testing.assert_allclose(dquat_pairwise(a, b, weights=w), expected, rtol=1e-12)


# -------------------------------------------------------------------------------------------------- Dpc


def test_window_clouds_clamp_at_clip_ends(jog, kick):
    pa, pb = jog.canonical().positions, kick.canonical().positions
    both = np.concatenate([pa, pb])
    first_b = len(pa)
    clouds = window_clouds(both, 5, frames=[0, 50, first_b - 1, first_b], lengths=[len(pa), len(pb)])
    assert clouds.shape == (4, 5 * 24, 3) and clouds.dtype == np.float64
    expected = (
        [0, 0, 0, 1, 2],
        [48, 49, 50, 51, 52],
        [first_b - 3, first_b - 2] + [first_b - 1] * 3,
        [first_b] * 3 + [first_b + 1, first_b + 2],
    )
    for cloud, frames in zip(clouds, expected):
        np.testing.assert_array_equal(cloud, both[frames].reshape(-1, 3))
    np.testing.assert_array_equal(window_clouds(pa, 1), pa)


def _grid_minimum(a, b, steps=36_000):
    """min over a grid of rotation angles about y of sum |a - (R b + t)|^2, t the best floor translation."""
    theta = np.arange(steps) * (2 * np.pi / steps)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    x, y, z = b[:, 0], b[:, 1], b[:, 2]
    turned = np.stack([c * x + s * z, np.broadcast_to(y, c.shape[:1] + y.shape), -s * x + c * z], axis=-1)
    shift = a.mean(0) - turned.mean(1)
    shift[:, 1] = 0.0  # translation on the floor only
    cost = ((a - turned - shift[:, None]) ** 2).sum((1, 2))
    k = int(np.argmin(cost))
    return cost[k], theta[k]


def test_dpc1_equals_grid_search_over_rotations(jog, kick):
    pa, pb = jog.canonical().positions.astype(np.float64), kick.canonical().positions.astype(np.float64)
    for i, j in ((0, 0), (60, 100), (200, 30), (120, 150)):
        a, b = pa[i], pb[j]
        best, best_theta = _grid_minimum(a, b)
        d = dpc(a, b[None])[0]
        assert d <= best * (1 + 1e-12)
        assert best - d <= 1e-6 * best
        theta, x0, z0 = pc_align(a, b)
        assert abs((theta - best_theta + np.pi) % (2 * np.pi) - np.pi) < 2e-4
        aligned = _rot_y(b, math.degrees(theta), np.array([x0, 0.0, z0]))
        assert ((a - aligned) ** 2).sum() == pytest.approx(d, rel=1e-9)


def test_dpc_window_equals_aligned_sum_over_window_frames(jog, kick):
    ca = window_clouds(jog.canonical().positions, 11, frames=[0, 120])
    cb = window_clouds(kick.canonical().positions, 11, frames=[80])
    for a in ca:
        theta, x0, z0 = pc_align(a, cb[0])
        aligned = _rot_y(cb[0], math.degrees(theta), np.array([x0, 0.0, z0]))
        assert dpc(a, cb)[0] == pytest.approx(((a - aligned) ** 2).sum(), rel=1e-9)


@pytest.mark.parametrize("n", [1, 5, 11])
def test_dpc_invariant_to_turning_and_moving_on_the_floor_not_to_tilting(jog, kick, n):
    pa, pb = jog.canonical().positions, kick.canonical().positions
    ca = window_clouds(pa, n)[::6]
    cb = window_clouds(pb, n)[::6]
    reference = dpc_pairwise(ca, cb)
    moved = window_clouds(_rot_y(pb, 137.0, np.array([250.0, 0.0, -410.0])), n)[::6]
    np.testing.assert_allclose(dpc_pairwise(ca, moved), reference, rtol=1e-3)
    self_moved = dpc_pairwise(ca, window_clouds(_rot_y(pa, -71.0, np.array([-90.0, 0.0, 33.0])), n)[::6])
    assert np.diag(self_moved).max() <= 1e-6 * np.median(reference)
    c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
    tilted = pb.astype(np.float64) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T  # 20 degrees about x
    changed = np.abs(dpc_pairwise(ca, window_clouds(tilted, n)[::6]) / reference - 1)
    assert np.median(changed) > 0.1


def test_dpc_point_weights(jog, kick):
    ca = window_clouds(jog.canonical().positions, 1)[::20]
    cb = window_clouds(kick.canonical().positions, 1)[::20]
    w = np.zeros(24)
    legs = [CANONICAL_JOINTS.index(j) for j in ("lknee", "lankle", "rknee", "rankle")]
    w[legs] = 1.0
    np.testing.assert_allclose(dpc_pairwise(ca, cb, weights=w), dpc_pairwise(ca[:, legs], cb[:, legs]), rtol=1e-8)
    np.testing.assert_allclose(dpc_pairwise(ca, cb, weights=np.full(24, 3.0)), 3 * dpc_pairwise(ca, cb), rtol=1e-9)


# -------------------------------------------------------------------------------------------------- Dwb


def _turn_joint(quaternions, joint, seed):
    """quaternions with one canonical joint's rotation changed by a different random rotation in every frame."""
    rng = np.random.default_rng(seed)
    out = quaternions.astype(np.float64)
    k = CANONICAL_JOINTS.index(joint)
    turn = rotations.from_euler("XYZ", rng.uniform(-40, 40, (len(out), 3)))
    out[:, k] = rotations.multiply(turn, out[:, k])
    return out


def test_dwb_ignores_joints_of_weight_zero(jog, kick):
    qa, qb = jog.canonical().quaternions, kick.canonical().quaternions
    a, b = lee_frames(qa, 120.0)[::8], lee_frames(qb, 120.0)
    assert LEE_WEIGHTS["rankle"] == LEE_WEIGHTS["head"] == 0 and WB_WEIGHTS["belly"] == 0 < LEE_WEIGHTS["belly"]
    lee, wb, flat = (dwb_pairwise(a, b[::8], weights=w) for w in ("lee", "wb", None))
    for joint in ("rankle", "head"):
        changed = lee_frames(_turn_joint(qb, joint, 3), 120.0)[::8]
        np.testing.assert_allclose(dwb_pairwise(a, changed, weights="lee"), lee, rtol=1e-12, atol=1e-15)
        assert np.abs(dwb_pairwise(a, changed, weights=None) / flat - 1).max() > 0.01
    changed = lee_frames(_turn_joint(qb, "belly", 4), 120.0)[::8]
    np.testing.assert_allclose(dwb_pairwise(a, changed, weights="wb"), wb, rtol=1e-12, atol=1e-15)
    assert np.abs(dwb_pairwise(a, changed, weights="lee") / lee - 1).max() > 0.01


def test_dwb_terms(jog, kick):
    """Position term = sum w (angle/2)^2; velocity term scales with nu; sign flips in the clip change nothing."""
    qa, qb = jog.canonical().quaternions, kick.canonical().quaternions
    a, b = lee_frames(qa, 120.0)[::10], lee_frames(qb, 120.0)[::10]
    w = joint_weights("lee", 24)
    angles = np.stack([np.array([dquat(x[k : k + 1, :4], b[:, k : k + 1, :4]) for k in range(24)]).T for x in a])
    np.testing.assert_allclose(dwb_pairwise(a, b, weights="lee", nu=0.0), ((angles / 2) ** 2) @ w, rtol=1e-9)
    velocity = 0.25 * ((a[:, None, :, 4:] - b[None, :, :, 4:]) ** 2).sum(-1) @ w
    np.testing.assert_allclose(
        dwb_pairwise(a, b, weights="lee", nu=0.5) - dwb_pairwise(a, b, weights="lee", nu=0.0), 0.5 * velocity, rtol=1e-8
    )
    signs = np.where(np.random.default_rng(2).random(qb.shape[:2]) < 0.5, -1.0, 1.0)[..., None]
    flipped = lee_frames(qb * signs, 120.0)[::10]
    np.testing.assert_allclose(dwb_pairwise(a, flipped), dwb_pairwise(a, b), rtol=1e-9, atol=1e-12)


def test_lee_frames_angular_velocity(kick):
    q = kick.canonical().quaternions
    v = lee_frames(q, 120.0)
    knee = CANONICAL_JOINTS.index("lknee")
    t = 70
    step = rotations.angle(q[t + 1, knee], q[t - 1, knee])
    assert np.linalg.norm(v[t, knee, 4:]) == pytest.approx(step * 60.0, rel=1e-5)  # angle over 2 frames at 120 Hz
    np.testing.assert_allclose(lee_frames(q, 30.0)[:, :, 4:], v[:, :, 4:] / 4, rtol=1e-12)
    edges = lee_frames(np.concatenate([q, q]), 120.0, lengths=[len(q), len(q)])
    np.testing.assert_allclose(edges[len(q)], v[0], rtol=1e-12)  # the second clip starts with a forward difference


# ----------------------------------------------------------------------------------------- Motion.euler


def test_motion_euler_travels_with_slicing_canonical_and_resampling(jog, bandai1_files):
    assert jog.euler.dtype == np.float32 and jog.euler.shape == (jog.n_frames, 59)
    np.testing.assert_array_equal(jog[10:20].euler, jog.euler[10:20])
    np.testing.assert_array_equal(jog[5].euler, jog.euler[5:6])
    np.testing.assert_array_equal(jog.canonical().euler, jog.euler)
    m = Motion(positions=np.zeros((2, 1, 3)), fps=2, joint_names=("a",), parents=[-1], euler=[[179.0], [-179.0]])
    assert abs(m.resample(4).euler[1, 0]) == pytest.approx(180.0)
    with pytest.raises(ValueError, match="euler"):
        Motion(positions=np.zeros((2, 1, 3)), fps=2, joint_names=("a",), parents=[-1], euler=np.zeros((3, 2)))
    bvh = load(bandai1_files[0])
    with open(bandai1_files[0], encoding="latin-1") as fh:
        lines = fh.read().split("\n")
    channels = [c for ln in lines if ln.strip().startswith("CHANNELS") for c in ln.split()[2:]]
    first = np.array(lines[next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1].split(), float)
    rot = [c.endswith("rotation") for c in channels]
    np.testing.assert_allclose(bvh.euler[0], first[rot], rtol=1e-6, atol=1e-5)


# ------------------------------------------------------------------------------------------- bad input


def test_bad_input_errors(jog, kick):
    canon = jog.canonical()
    q = canon.quaternions
    with pytest.raises(ValueError, match="same skeleton"):
        dquat(q[0], jog.quaternions)  # 24 against 31 joints
    with pytest.raises(ValueError, match="same skeleton"):
        deuler(jog.euler[0], jog.euler[:, :-3])
    with pytest.raises(ValueError, match="shape"):
        dquat(q, q)  # frames passed as the query
    with pytest.raises(ValueError, match="shape"):
        dquat_pairwise(q[:, :, :3], q)
    nan = q.copy()
    nan[3, 5, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        dquat(q[0], nan)
    with pytest.raises(ValueError, match="NaN"):
        window_clouds(np.where(np.isnan(nan[..., :3]), np.nan, canon.positions), 5)
    with pytest.raises(ValueError, match="unit quaternions"):
        dquat(q[0], q * 1.1)
    with pytest.raises(ValueError, match="too few frames"):
        window_clouds(canon.positions[:3], 5)
    with pytest.raises(ValueError, match="too few frames"):
        window_clouds(canon.positions[:20], 11, lengths=[15, 5])
    with pytest.raises(ValueError, match="odd"):
        window_clouds(canon.positions, 4)
    with pytest.raises(ValueError, match="lengths"):
        window_clouds(canon.positions, 1, lengths=[10, 10])
    with pytest.raises(ValueError, match="frame indices"):
        window_clouds(canon.positions, 1, frames=[jog.n_frames])
    with pytest.raises(ValueError, match="at least 2 frames"):
        lee_frames(q[:1], 120.0)
    with pytest.raises(ValueError, match="at least 2 frames"):
        lee_frames(q[:6], 120.0, lengths=[5, 1])
    with pytest.raises(ValueError, match="fps"):
        lee_frames(q, 0.0)
    frames = lee_frames(q, 120.0)
    with pytest.raises(ValueError, match="unknown weight table"):
        dwb(frames[0], frames, weights="kovar")
    with pytest.raises(ValueError, match="canonical"):
        dquat(jog.quaternions[0], jog.quaternions, weights="lee")
    with pytest.raises(ValueError, match="weights"):
        dquat(q[0], q, weights=np.ones(23))
    with pytest.raises(ValueError, match="weights"):
        dquat(q[0], q, weights=-np.ones(24))
    with pytest.raises(ValueError, match="nu"):
        dwb(frames[0], frames, nu=-1.0)
    clouds = window_clouds(canon.positions, 5)
    with pytest.raises(ValueError, match="same skeleton"):
        dpc(clouds[0], window_clouds(canon.positions, 1))
    with pytest.raises(ValueError, match="weights"):
        dpc(clouds[0], clouds, weights=np.ones(24))
    with pytest.raises(ValueError, match="numeric"):
        deuler(np.array(["a"]), jog.euler)
