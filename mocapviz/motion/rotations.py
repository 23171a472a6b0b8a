"""Rotations as unit quaternions, and forward kinematics.

Quaternions are stored scalar first, ``(w, x, y, z)``, as float arrays whose last axis has length 4.
Rotations act on column vectors: ``rotate(q, v)`` is ``R(q) @ v``.

Public functions
----------------
from_euler             Euler angles (any axis order) -> quaternions.
to_euler               quaternions -> Euler angles (any axis order of three axes), the inverse of from_euler.
from_matrix            rotation matrices -> quaternions.
multiply               Hamilton product of two quaternion arrays (broadcasting).
rotate                 Rotate vectors by quaternions (broadcasting).
angle                  Rotation angle between two quaternion arrays (radians).
slerp                  Spherical linear interpolation between two quaternion arrays.
forward_kinematics     Local rotations and global positions from Euler channels, compiled over frames.
"""
from __future__ import annotations

import numba
import numpy as np

from ..errors import ParameterError

_AXES = "xyz"


def from_euler(order: str, angles: np.ndarray, degrees: bool = True) -> np.ndarray:
    """Quaternions of Euler-angle rotations.

    Parameters
    ----------
    order : str
        Axes in the order the rotations are applied to a vector, e.g. ``"XYZ"`` = first about x, then y,
        then z about the fixed (parent) axes, i.e. ``R = Rz @ Ry @ Rx``. This is the ASF ``axis``
        convention. BVH channels ``Zrotation Xrotation Yrotation`` mean ``R = Rz @ Rx @ Ry``, which is
        order ``"YXZ"`` here (the channel order reversed). One to three letters from x, y, z, any case.
    angles : np.ndarray [shape=(..., len(order))]
        Angles, one column per letter of ``order``.
    degrees : bool
        Angles in degrees (default) or radians.

    Returns
    -------
    np.ndarray [shape=(..., 4)], float64
        Unit quaternions ``(w, x, y, z)``.

    Examples
    --------
    >>> from_euler("XYZ", [90, 0, 0]).round(3)
    array([0.707, 0.707, 0.   , 0.   ])
    """
    axes = [_AXES.index(a) for a in order.lower()]
    half = np.asarray(angles, dtype=np.float64) * (0.5 * np.pi / 180.0 if degrees else 0.5)
    if half.shape[-1] != len(axes):
        raise ParameterError(f"from_euler: {len(axes)} axes in {order!r} but angles have {half.shape[-1]} columns")
    c, s = np.cos(half), np.sin(half)
    q = np.zeros(half.shape[:-1] + (4,))
    q[..., 0] = 1.0
    for k, axis in enumerate(axes):
        qk = np.zeros(half.shape[:-1] + (4,))
        qk[..., 0] = c[..., k]
        qk[..., 1 + axis] = s[..., k]
        q = multiply(qk, q)
    return q


def to_euler(order: str, q: np.ndarray, degrees: bool = True) -> np.ndarray:
    """Euler angles of rotations, the inverse of :func:`from_euler`.

    Parameters
    ----------
    order : str
        Three different axes in the order the rotations are applied (as :func:`from_euler`), e.g. ``"XYZ"``:
        ``R = Rz @ Ry @ Rx``; any case.
    q : np.ndarray [shape=(..., 4)]
        Unit quaternions ``(w, x, y, z)``.
    degrees : bool
        Angles in degrees (default) or radians.

    Returns
    -------
    np.ndarray [shape=(..., 3)], float64
        One column per letter of ``order``; the middle angle within ±90 degrees. At gimbal lock (middle angle
        ±90 degrees) the last rotation is 0 and the first takes the whole turn about the shared axis.

    Examples
    --------
    >>> to_euler("YXZ", from_euler("YXZ", [10, -20, 30])).round(6)
    array([ 10., -20.,  30.])
    """
    axes = [_AXES.index(a) for a in order.lower()]
    if sorted(axes) != [0, 1, 2]:
        raise ParameterError(f"to_euler: order must name x, y and z once each, got {order!r}")
    m = _matrix(np.asarray(q, dtype=np.float64))
    k, j, i = axes  # R = R_i R_j R_k: k is applied first
    e = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    cos_middle = np.hypot(m[..., i, i], m[..., i, j])
    middle = np.arctan2(e * m[..., i, k], cos_middle)
    locked = cos_middle < 1e-7
    # at gimbal lock R = R_i(outer) R_j(middle): R_i(outer) = R R_j(-middle), read off its own plane (p, r)
    turn = m @ _matrix(from_euler("xyz"[j], -middle[..., None], degrees=False))
    p, r = (i + 1) % 3, (i + 2) % 3
    outer = np.where(locked, np.arctan2(turn[..., r, p], turn[..., p, p]), np.arctan2(-e * m[..., j, k], m[..., k, k]))
    inner = np.where(locked, 0.0, np.arctan2(-e * m[..., i, j], m[..., i, i]))
    out = np.stack([inner, middle, outer], axis=-1)
    return np.degrees(out) if degrees else out


def _matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices [shape=(..., 3, 3)] of unit quaternions (normalised first)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)  # fmt: skip


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Quaternions of rotation matrices.

    Parameters
    ----------
    m : np.ndarray [shape=(..., 3, 3)]
        Proper rotation matrices (orthonormal, determinant 1).

    Returns
    -------
    np.ndarray [shape=(..., 4)], float64
        Unit quaternions ``(w, x, y, z)`` with ``w >= 0``.

    Examples
    --------
    >>> from_matrix(np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])).round(3)  # 90 degrees about z
    array([0.707, 0.   , 0.   , 0.707])
    """
    m = np.asarray(m, dtype=np.float64)
    # the largest of 4w², 4x², 4y², 4z² gives the best-conditioned formula (Shepperd's method)
    d = np.stack([m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2], m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], axis=-1)
    big = np.argmax(d, axis=-1)[..., None]
    c = np.stack([
        np.stack([1 + d[..., 0], m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * d[..., 1] - d[..., 0], m[..., 0, 1] + m[..., 1, 0],
                  m[..., 0, 2] + m[..., 2, 0]], -1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * d[..., 2] - d[..., 0],
                  m[..., 1, 2] + m[..., 2, 1]], -1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                  1 + 2 * d[..., 3] - d[..., 0]], -1),
    ], axis=-2)  # fmt: skip
    q = np.take_along_axis(c, big[..., None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (rotation ``b`` first, then ``a``).

    Parameters
    ----------
    a, b : np.ndarray [shape=(..., 4)]
        Quaternions ``(w, x, y, z)``, broadcast against each other.

    Returns
    -------
    np.ndarray [shape=(..., 4)]

    Examples
    --------
    >>> multiply(from_euler("XYZ", [0, 0, 90]), from_euler("XYZ", [90, 0, 0])).round(3)  # x by 90°, then z
    array([0.5, 0.5, 0.5, 0.5])
    """
    aw, ax, ay, az = np.moveaxis(np.asarray(a), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors by unit quaternions (broadcasting): ``R(q) @ v``.

    Parameters
    ----------
    q : np.ndarray [shape=(..., 4)]
        Unit quaternions ``(w, x, y, z)``.
    v : np.ndarray [shape=(..., 3)]
        Vectors (e.g. cm).

    Returns
    -------
    np.ndarray [shape=(..., 3)]
        The rotated vectors, in the units of ``v``.

    Examples
    --------
    >>> rotate(from_euler("XYZ", [0, 0, 90]), [1.0, 0.0, 0.0]).round(3)  # x turned 90° about z
    array([0., 1., 0.])
    """
    q = np.asarray(q)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle of the rotation taking ``a`` to ``b``.

    Parameters
    ----------
    a, b : np.ndarray [shape=(..., 4)]
        Unit quaternions ``(w, x, y, z)``, broadcast against each other.

    Returns
    -------
    np.ndarray [shape=(...)]
        Radians in [0, pi] (``q`` and ``-q`` are one rotation: angle 0).

    Examples
    --------
    >>> q = from_euler("XYZ", [90, 0, 0])
    >>> float(angle(q, from_euler("XYZ", [0, 0, 0])).round(4)), float(angle(q, -q))
    (1.5708, 0.0)
    """
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation from ``a`` (t = 0) to ``b`` (t = 1) along the shorter arc.

    Parameters
    ----------
    a, b : np.ndarray [shape=(..., 4)]
        Unit quaternions.
    t : np.ndarray [shape=(...) broadcastable against a[..., 0]]
        Interpolation parameters in [0, 1].

    Returns
    -------
    np.ndarray [shape=(..., 4)], unit quaternions.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    d = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(d < 0, -b, b)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, 0.0, 1.0))
    s = np.sin(theta)
    near = s < 1e-6
    safe = np.where(near, 1.0, s)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(near, t, np.sin(t * theta) / safe)
    q = wa * a + wb * b
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@numba.njit(cache=True, nogil=True, inline="always")
def _qmul(aw, ax, ay, az, bw, bx, by, bz):  # pragma: no cover - numba
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@numba.njit(cache=True, nogil=True)
def _fk_kernel(parents, cos_half, sin_half, axes, pre, post, t_local, own_frame, q_local, q_global, p_global):  # pragma: no cover
    n_frames, n_joints = cos_half.shape[0], cos_half.shape[1]
    per_frame_t = t_local.shape[0] > 1
    q = np.empty(4)
    for f in range(n_frames):
        tf = f if per_frame_t else 0
        for j in range(n_joints):
            # local rotation = pre * E(euler) * post, E composed in the joint's axis order
            lw, lx, ly, lz = pre[j, 0], pre[j, 1], pre[j, 2], pre[j, 3]
            ew, ex, ey, ez = 1.0, 0.0, 0.0, 0.0
            for k in range(3):
                a = axes[j, k]
                if a < 0:
                    continue
                q[0] = cos_half[f, j, k]
                q[1] = 0.0
                q[2] = 0.0
                q[3] = 0.0
                q[1 + a] = sin_half[f, j, k]
                ew, ex, ey, ez = _qmul(q[0], q[1], q[2], q[3], ew, ex, ey, ez)
            lw, lx, ly, lz = _qmul(lw, lx, ly, lz, ew, ex, ey, ez)
            lw, lx, ly, lz = _qmul(lw, lx, ly, lz, post[j, 0], post[j, 1], post[j, 2], post[j, 3])
            q_local[f, j, 0] = lw
            q_local[f, j, 1] = lx
            q_local[f, j, 2] = ly
            q_local[f, j, 3] = lz
            p = parents[j]
            vx, vy, vz = t_local[tf, j, 0], t_local[tf, j, 1], t_local[tf, j, 2]
            if p < 0:
                q_global[j, 0] = lw
                q_global[j, 1] = lx
                q_global[j, 2] = ly
                q_global[j, 3] = lz
                p_global[f, j, 0] = vx
                p_global[f, j, 1] = vy
                p_global[f, j, 2] = vz
                continue
            pw, px, py, pz = q_global[p, 0], q_global[p, 1], q_global[p, 2], q_global[p, 3]
            gw, gx, gy, gz = _qmul(pw, px, py, pz, lw, lx, ly, lz)
            q_global[j, 0] = gw
            q_global[j, 1] = gx
            q_global[j, 2] = gy
            q_global[j, 3] = gz
            if own_frame[j]:
                rw, rx, ry, rz = gw, gx, gy, gz
            else:
                rw, rx, ry, rz = pw, px, py, pz
            # v' = v + w t + u x t with t = 2 u x v
            tx = 2.0 * (ry * vz - rz * vy)
            ty = 2.0 * (rz * vx - rx * vz)
            tz = 2.0 * (rx * vy - ry * vx)
            p_global[f, j, 0] = p_global[f, p, 0] + vx + rw * tx + (ry * tz - rz * ty)
            p_global[f, j, 1] = p_global[f, p, 1] + vy + rw * ty + (rz * tx - rx * tz)
            p_global[f, j, 2] = p_global[f, p, 2] + vz + rw * tz + (rx * ty - ry * tx)


def forward_kinematics(
    parents: np.ndarray,
    euler: np.ndarray,
    orders,
    translations: np.ndarray,
    own_frame: np.ndarray | None = None,
    pre: np.ndarray | None = None,
    post: np.ndarray | None = None,
    degrees: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations and global positions of a joint hierarchy driven by Euler angles, in one compiled pass.

    Joint ``j`` with parent ``p`` has the local rotation ``q[j] = pre[j] * E(euler[j]) * post[j]``, where
    ``E`` composes the rotations about the axes of ``orders[j]`` in that order (see :func:`from_euler`), the
    global rotation ``Q[j] = Q[p] * q[j]`` and the position ``P[j] = P[p] + R(Q[p]) @ translations[j]``
    (BVH: a joint's offset lives in its parent's frame), or ``P[j] = P[p] + R(Q[j]) @ translations[j]``
    where ``own_frame[j]`` (ASF: a joint is the tip of its own bone). A root (parent -1) takes ``q[j]`` and
    ``translations[j]`` as its global rotation and position.

    Parameters
    ----------
    parents : np.ndarray [shape=(J,)], int
        Parent index of each joint, -1 for a root; every parent precedes its children.
    euler : np.ndarray [shape=(T, J, 3)]
        Angles; column k of joint j turns about axis ``orders[j][k]`` (unused columns are ignored).
    orders : sequence of str [length J]
        Rotation order per joint, 0 to 3 letters of xyz (``""``: no rotation channels).
    translations : np.ndarray [shape=(T, J, 3) or (1, J, 3)]
        Local translations (any length unit; positions come out in the same unit).
    own_frame : np.ndarray [shape=(J,)], bool, optional
        Where true, the translation is rotated by the joint's own global rotation. Default all false.
    pre, post : np.ndarray [shape=(J, 4)], optional
        Constant rotations around the Euler part (ASF: the bone axis C and its inverse). Default identity.
    degrees : bool
        Angles in degrees (default) or radians.

    Returns
    -------
    q_local : np.ndarray [shape=(T, J, 4)], float64 -- local rotations ``(w, x, y, z)``.
    positions : np.ndarray [shape=(T, J, 3)], float64

    Notes
    -----
    The sines and cosines of the half angles are taken in single precision (ten times faster here), so
    rotations are accurate to about 1e-7 and positions to about 1e-7 of the skeleton's size: below the
    float32 resolution in which a Motion keeps them.
    """
    parents = np.ascontiguousarray(parents, dtype=np.int64)
    euler = np.ascontiguousarray(euler, dtype=np.float64)
    translations = np.ascontiguousarray(translations, dtype=np.float64)
    n_frames, n_joints = euler.shape[:2]
    if np.any(parents >= np.arange(n_joints)):
        raise ParameterError("forward_kinematics: every parent must come before its children")
    axes = np.full((n_joints, 3), -1, dtype=np.int64)
    for j, order in enumerate(orders):
        for k, a in enumerate(order.lower()):
            axes[j, k] = _AXES.index(a)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (n_joints, 1))
    pre = identity if pre is None else np.ascontiguousarray(pre, dtype=np.float64)
    post = identity if post is None else np.ascontiguousarray(post, dtype=np.float64)
    own = np.zeros(n_joints, dtype=np.bool_) if own_frame is None else np.ascontiguousarray(own_frame, dtype=np.bool_)
    q_local = np.empty((n_frames, n_joints, 4))
    positions = np.empty((n_frames, n_joints, 3))
    # Half angles in float32: numpy's single-precision sin/cos are SIMD (10x the double ones here) and their
    # error (< 1e-7 rad) is below the float32 resolution of the positions returned to users.
    half = (euler * (0.5 * np.pi / 180.0 if degrees else 0.5)).astype(np.float32)
    _fk_kernel(parents, np.cos(half), np.sin(half), axes, pre, post, translations, own, q_local, np.empty((n_joints, 4)), positions)
    return q_local, positions
