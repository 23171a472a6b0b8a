"""Quaternion helpers and forward kinematics (mocapviz.motion.rotations) against scipy and hand-worked geometry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapviz.motion import rotations

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def _scipy(q: np.ndarray) -> Rotation:
    """scipy Rotation of (w, x, y, z) quaternions."""
    q = np.asarray(q, dtype=np.float64)
    return Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1).reshape(-1, 4))


def _wxyz(r: Rotation) -> np.ndarray:
    q = r.as_quat()
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


@pytest.mark.parametrize("order", ORDERS)
def test_from_euler_matches_scipy(order, rng):
    angles = rng.uniform(-180, 180, size=(50, 3))
    q = rotations.from_euler(order, angles)
    assert q.shape == (50, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    # "XYZ": x first, then y, then z about the fixed axes, R = Rz Ry Rx: scipy's extrinsic lower-case order
    expected = Rotation.from_euler(order.lower(), angles, degrees=True).as_matrix()
    np.testing.assert_allclose(_scipy(q).as_matrix(), expected, atol=1e-12)
    # and the product of single-axis matrices written out
    mats = [Rotation.from_euler(a.lower(), angles[:, k : k + 1], degrees=True).as_matrix() for k, a in enumerate(order)]
    np.testing.assert_allclose(_scipy(q).as_matrix(), mats[2] @ mats[1] @ mats[0], atol=1e-12)
    # radians, lower case
    np.testing.assert_allclose(rotations.from_euler(order.lower(), np.radians(angles), degrees=False), q, atol=1e-12)


def test_from_euler_fewer_axes_and_shapes(rng):
    angles = rng.uniform(-90, 90, size=(4, 5, 2))
    q = rotations.from_euler("zx", angles)
    assert q.shape == (4, 5, 4)
    expected = Rotation.from_euler("zx", angles.reshape(-1, 2), degrees=True).as_matrix()
    np.testing.assert_allclose(_scipy(q).as_matrix(), expected, atol=1e-12)
    np.testing.assert_allclose(rotations.from_euler("Y", [90.0]), [np.sqrt(0.5), 0, np.sqrt(0.5), 0], atol=1e-12)
    np.testing.assert_allclose(rotations.from_euler("XYZ", [90, 0, 0]), [np.sqrt(0.5), np.sqrt(0.5), 0, 0])
    with pytest.raises(ValueError):
        rotations.from_euler("XYZ", [1.0, 2.0])


def test_multiply_and_rotate_match_scipy(rng):
    a = _wxyz(Rotation.random(100, random_state=1))
    b = _wxyz(Rotation.random(100, random_state=2))
    v = rng.normal(size=(100, 3))
    ab = rotations.multiply(a, b)
    np.testing.assert_allclose(_scipy(ab).as_matrix(), _scipy(a).as_matrix() @ _scipy(b).as_matrix(), atol=1e-12)
    # b first, then a
    np.testing.assert_allclose(rotations.rotate(ab, v), rotations.rotate(a, rotations.rotate(b, v)), atol=1e-12)
    np.testing.assert_allclose(rotations.rotate(a, v), _scipy(a).apply(v), atol=1e-12)
    np.testing.assert_allclose(rotations.rotate(a, v), np.einsum("nij,nj->ni", _scipy(a).as_matrix(), v), atol=1e-12)
    # broadcasting: one rotation, many vectors; many rotations, one vector
    np.testing.assert_allclose(rotations.rotate(a[0], v), _scipy(a[:1]).apply(v), atol=1e-12)
    np.testing.assert_allclose(rotations.rotate(a, v[0]), _scipy(a).apply(v[0]), atol=1e-12)
    np.testing.assert_allclose(rotations.multiply(a[:, None], b[None, :3]).shape, (100, 3, 4))
    # known values: 90 degrees about z takes x to y
    qz = rotations.from_euler("Z", [90.0])
    np.testing.assert_allclose(rotations.rotate(qz, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)


def test_angle_matches_scipy():
    a = _wxyz(Rotation.random(200, random_state=3))
    b = _wxyz(Rotation.random(200, random_state=4))
    expected = (_scipy(a).inv() * _scipy(b)).magnitude()
    np.testing.assert_allclose(rotations.angle(a, b), expected, atol=1e-6)
    np.testing.assert_allclose(rotations.angle(a, -a), 0.0, atol=1e-6)  # q and -q: the same rotation
    qx = rotations.from_euler("X", [[30.0], [170.0]])
    np.testing.assert_allclose(rotations.angle(np.array([1.0, 0, 0, 0]), qx), np.radians([30.0, 170.0]), atol=1e-7)


def test_slerp_endpoints_and_midpoint():
    a = _wxyz(Rotation.random(50, random_state=5))
    b = _wxyz(Rotation.random(50, random_state=6))
    sign = lambda p, q: np.sign(np.sum(p * q, axis=-1, keepdims=True))
    q0 = rotations.slerp(a, b, np.zeros(50))
    q1 = rotations.slerp(a, b, np.ones(50))
    np.testing.assert_allclose(q0, a, atol=1e-12)
    np.testing.assert_allclose(q1 * sign(q1, b), b, atol=1e-12)
    full = rotations.angle(a, b)
    for t in (0.25, 0.5, 0.9):
        qt = rotations.slerp(a, b, np.full(50, t))
        np.testing.assert_allclose(np.linalg.norm(qt, axis=-1), 1.0, atol=1e-12)
        np.testing.assert_allclose(rotations.angle(a, qt), t * full, atol=1e-9)
        np.testing.assert_allclose(rotations.angle(qt, b), (1 - t) * full, atol=1e-9)
    # agrees with scipy's Slerp at the midpoint
    from scipy.spatial.transform import Slerp

    for k in range(5):
        s = Slerp([0, 1], _scipy(np.stack([a[k], b[k]])))
        np.testing.assert_allclose(_scipy(rotations.slerp(a[k], b[k], 0.5)).as_matrix()[0], s([0.5]).as_matrix()[0],
                                   atol=1e-9)  # fmt: skip


def test_slerp_shorter_arc_and_identical():
    a = rotations.from_euler("Z", [10.0])
    b = -rotations.from_euler("Z", [50.0])  # the same rotation as +q: the arc must be 40 degrees, not 320
    mid = rotations.slerp(a, b, 0.5)
    np.testing.assert_allclose(rotations.angle(mid, rotations.from_euler("Z", [30.0])), 0.0, atol=1e-7)
    same = rotations.slerp(a, a, 0.3)
    np.testing.assert_allclose(same, a, atol=1e-12)
    assert np.all(np.isfinite(same))


def test_forward_kinematics_chain_parent_frame():
    """BVH style: P_j = P_p + R(Q_p) t_j. Root at (1, 2, 3) turned 90 deg about z; joint 1 turned 90 deg about
    x; joint 2 hangs (0, 1, 0) below joint 1 in joint 1's frame."""
    parents = np.array([-1, 0, 1])
    euler = np.zeros((1, 3, 3))
    euler[0, 0, 0] = 90.0  # root: z
    euler[0, 1, 0] = 90.0  # joint 1: x
    orders = ["z", "x", ""]
    t = np.array([[[1.0, 2.0, 3.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    q, p = rotations.forward_kinematics(parents, euler, orders, t)
    # joint 1 = (1,2,3) + Rz90 (1,0,0) = (1,3,3); joint 2 = (1,3,3) + Rz90 Rx90 (0,1,0) = (1,3,3) + (0,0,1)
    np.testing.assert_allclose(p[0], [[1, 2, 3], [1, 3, 3], [1, 3, 4]], atol=1e-12)
    np.testing.assert_allclose(q[0, 0], rotations.from_euler("Z", [90.0]), atol=1e-12)
    np.testing.assert_allclose(q[0, 1], rotations.from_euler("X", [90.0]), atol=1e-12)
    np.testing.assert_allclose(q[0, 2], [1, 0, 0, 0], atol=1e-12)


# forward_kinematics works from single-precision sines and cosines (documented): rotations to ~1e-7
FK_TOL = 1e-6


def test_forward_kinematics_chain_own_frame_and_axes():
    """ASF style: P_j = P_p + R(Q_j) t_j and q_j = C E C^-1."""
    parents = np.array([-1, 0, 1])
    euler = np.zeros((2, 3, 3))
    euler[1, 1, 0] = 90.0  # frame 1: joint 1 turns 90 deg about its x
    t = np.array([[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0]]])
    q, p = rotations.forward_kinematics(parents, euler, ["xyz"] * 3, t, own_frame=np.ones(3, bool))
    np.testing.assert_allclose(p[0], [[0, 0, 0], [0, 2, 0], [0, 5, 0]], atol=FK_TOL)
    # Rx90 takes y to z: the bone of joint 1 and the one below it both turn
    np.testing.assert_allclose(p[1], [[0, 0, 0], [0, 0, 2], [0, 0, 5]], atol=FK_TOL)
    # the same with joint 1's axis C = 90 deg about z: "its x" is the world y; turning about y leaves the
    # y-directed bones where they are ...
    c = np.tile([1.0, 0, 0, 0], (3, 1))
    c[1] = rotations.from_euler("Z", [90.0])
    conj = c * [1, -1, -1, -1]
    q, p = rotations.forward_kinematics(parents, euler, ["xyz"] * 3, t, own_frame=np.ones(3, bool), pre=c, post=conj)
    np.testing.assert_allclose(p[1], [[0, 0, 0], [0, 2, 0], [0, 5, 0]], atol=FK_TOL)
    np.testing.assert_allclose(q[1, 1], rotations.from_euler("Y", [90.0]), atol=FK_TOL)
    # ... while a bone along x swings to -z
    t2 = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
    _, p = rotations.forward_kinematics(parents, euler, ["xyz"] * 3, t2, own_frame=np.ones(3, bool), pre=c, post=conj)
    np.testing.assert_allclose(p[1], [[0, 0, 0], [0, 0, -1], [0, 0, -2]], atol=FK_TOL)


def test_forward_kinematics_matches_scipy_random_chain(rng):
    """A 6-joint branching tree, 20 frames, per-frame translations, radians: every joint against scipy."""
    parents = np.array([-1, 0, 1, 1, 3, 0])
    orders = ["zxy", "xyz", "yzx", "x", "zy", ""]
    euler = rng.uniform(-np.pi, np.pi, size=(20, 6, 3))
    t = rng.normal(size=(20, 6, 3))
    q, p = rotations.forward_kinematics(parents, euler, orders, t, degrees=False)
    for f in range(20):
        rot, pos = [], []
        for j in range(6):
            n = len(orders[j])
            local = Rotation.from_euler(orders[j], euler[f, j, :n]) if n else Rotation.identity()
            np.testing.assert_allclose(_scipy(q[f, j]).as_matrix()[0], local.as_matrix(), atol=FK_TOL)
            if parents[j] < 0:
                rot.append(local)
                pos.append(t[f, j])
            else:
                pos.append(pos[parents[j]] + rot[parents[j]].apply(t[f, j]))
                rot.append(rot[parents[j]] * local)
        np.testing.assert_allclose(p[f], np.array(pos), atol=FK_TOL)


def test_forward_kinematics_rejects_bad_parent_order():
    with pytest.raises(ValueError):
        rotations.forward_kinematics(np.array([1, -1]), np.zeros((1, 2, 3)), ["", ""], np.zeros((1, 2, 3)))


@pytest.mark.parametrize("order", ORDERS)
def test_to_euler_inverts_from_euler_also_at_gimbal_lock(order):
    rng = np.random.default_rng(3)
    q = rng.normal(size=(2000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    locked = rotations.from_euler(order, [[10, 90, 30], [10, -90, 30], [-170, 90, 5], [0, 89.9999999, 7]])
    for x in (q, locked):
        angles = rotations.to_euler(order, x)
        assert np.abs(angles[:, 1]).max() <= 90.0
        assert rotations.angle(x, rotations.from_euler(order, angles)).max() < 1e-6
    # the same angles as scipy's extrinsic convention away from the lock (order = axes in the order applied)
    np.testing.assert_allclose(rotations.to_euler(order, q[:50]), _scipy(q[:50]).as_euler(order.lower(), degrees=True),
                               atol=1e-6)


def test_from_matrix_inverts_the_rotation_matrix():
    rng = np.random.default_rng(4)
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    m = np.stack([rotations.rotate(q, np.eye(3)[k]) for k in range(3)], axis=-1)  # columns: the turned axes
    assert rotations.angle(q, rotations.from_matrix(m)).max() < 1e-6
