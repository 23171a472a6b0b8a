"""The Motion container: validation, slicing, duration, joint access, resampling arithmetic."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mocapviz.motion import Motion


def _motion(t=10, j=3, fps=30.0, quaternions=True, **kw):
    rng = np.random.default_rng(t * 100 + j)
    q = rng.normal(size=(t, j, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Motion(
        positions=rng.normal(size=(t, j, 3)) * 50,
        fps=fps,
        joint_names=[f"j{k}" for k in range(j)],
        parents=[-1] + list(range(j - 1)),
        quaternions=q if quaternions else None,
        source="synthetic.bvh",
        **kw,
    )


def test_types_are_normalised():
    m = _motion()
    assert m.positions.dtype == np.float32 and m.positions.shape == (10, 3, 3)
    assert m.quaternions.dtype == np.float32 and m.quaternions.shape == (10, 3, 4)
    assert m.parents.dtype == np.int64 and m.parents.tolist() == [-1, 0, 1]
    assert m.joint_names == ("j0", "j1", "j2") and isinstance(m.joint_names, tuple)
    assert isinstance(m.fps, float) and m.fps == 30.0
    assert m.n_frames == 10 and m.n_joints == 3
    assert m.labels == {} and _motion().labels is not m.labels
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.fps = 60.0


@pytest.mark.parametrize(
    "change",
    [
        {"positions": np.zeros((10, 3))},
        {"positions": np.zeros((10, 3, 2))},
        {"positions": np.zeros((10, 3, 3, 1))},
        {"joint_names": ("a", "b")},
        {"parents": np.array([-1, 0])},
        {"parents": np.array([[-1, 0, 1]])},
        {"fps": 0.0},
        {"fps": -120.0},
        {"fps": float("nan")},
        {"fps": float("inf")},
        {"quaternions": np.zeros((10, 3, 3))},
        {"quaternions": np.zeros((9, 3, 4))},
        {"quaternions": np.zeros((10, 2, 4))},
    ],
)
def test_validation(change):
    base = {"positions": np.zeros((10, 3, 3)), "fps": 30.0, "joint_names": ("a", "b", "c"), "parents": [-1, 0, 1]}
    with pytest.raises(ValueError):
        Motion(**{**base, **change})


def test_duration():
    assert _motion(t=90, fps=30).duration == pytest.approx(3.0)
    assert _motion(t=1, fps=120).duration == pytest.approx(1 / 120)
    assert _motion(t=253, fps=120)[10:70].duration == pytest.approx(0.5)


def test_slicing():
    m = _motion(t=20, labels={"class": "walk"})
    s = m[5:12]
    assert isinstance(s, Motion) and s.n_frames == 7
    np.testing.assert_array_equal(s.positions, m.positions[5:12])
    np.testing.assert_array_equal(s.quaternions, m.quaternions[5:12])
    assert s.fps == m.fps and s.joint_names == m.joint_names and s.source == m.source
    assert s.labels == {"class": "walk"}
    np.testing.assert_array_equal(s.parents, m.parents)
    one = m[3]
    assert one.n_frames == 1
    np.testing.assert_array_equal(one.positions[0], m.positions[3])
    np.testing.assert_array_equal(m[np.int64(-1)].positions, m.positions[-1:])
    np.testing.assert_array_equal(m[-20].positions, m.positions[:1])
    for bad in (20, -21):
        with pytest.raises(IndexError):
            m[bad]
    picked = m[np.array([0, 4, 19])]
    np.testing.assert_array_equal(picked.positions, m.positions[[0, 4, 19]])
    np.testing.assert_array_equal(picked.quaternions, m.quaternions[[0, 4, 19]])
    stepped = m[::4]
    assert stepped.n_frames == 5
    np.testing.assert_array_equal(stepped.positions, m.positions[::4])
    no_rot = _motion(quaternions=False)[2:4]
    assert no_rot.quaternions is None and no_rot.n_frames == 2


def test_joint():
    m = _motion()
    np.testing.assert_array_equal(m.joint("j1"), m.positions[:, 1])
    with pytest.raises(KeyError, match="j0, j1, j2"):
        m.joint("knee")


def test_resample_linear_trajectory():
    t = np.arange(10) / 30.0
    pos = np.zeros((10, 2, 3))
    pos[:, 0, 0] = 100 * t  # 100 cm/s along x
    pos[:, 1, 1] = 50 - 20 * t
    m = Motion(positions=pos, fps=30, joint_names=("a", "b"), parents=[-1, 0])
    r = m.resample(25)
    # frames at k / 25 s up to the last one at or before 9 / 30 s
    assert r.n_frames == int(np.floor(9 / 30 * 25)) + 1 == 8
    tk = np.arange(8) / 25.0
    np.testing.assert_allclose(r.positions[:, 0, 0], 100 * tk, atol=1e-4)
    np.testing.assert_allclose(r.positions[:, 1, 1], 50 - 20 * tk, atol=1e-4)
    assert r.quaternions is None and r.fps == 25.0
    # resampling to an exact multiple keeps the end frame
    assert m.resample(60).n_frames == 19 and m.resample(10).n_frames == 4
    np.testing.assert_array_equal(m.resample(10).positions, m.positions[::3])
    for bad in (0, -1, float("nan")):
        with pytest.raises(ValueError):
            m.resample(bad)


def test_resample_quaternions_slerp():
    from mocapviz.motion import rotations

    angles = np.zeros((5, 1, 1))
    angles[:, 0, 0] = [0, 20, 40, 60, 80]
    q = rotations.from_euler("z", angles)
    m = Motion(positions=np.zeros((5, 1, 3)), fps=10, joint_names=("a",), parents=[-1], quaternions=q)
    r = m.resample(20)
    assert r.n_frames == 9
    expected = rotations.from_euler("z", np.arange(9)[:, None, None] * 10.0)
    np.testing.assert_allclose(np.abs(np.sum(r.quaternions * expected, axis=-1)), 1.0, atol=1e-6)
