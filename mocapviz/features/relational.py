"""Boolean relational motion features (Müller, Röder & Clausen 2005, §3; Müller & Röder 2006).

Every feature answers one yes/no question about a pose, or about a short time window around it ("is the right
foot behind the plane of the left leg?", "is the left hand moving fast?"), from the 24 canonical joints. The
definitions, thresholds and quirks follow the Bonn HDM05 toolbox as written down in the design note
RELATIONAL_FEATURES.md (the "spec"; § numbers below refer to it).

Public functions
----------------
relational_features  Motion or MotionDB -> (T, f) bool feature values and their f names.
feature_names        the f column names of a relational set.
feature_groups       {"lower", "upper", "mix"} -> names, in column order.
feature_table        pandas.DataFrame, one row per feature: name, group, spec row, definition, thresholds, unit.
RELATIONAL_SETS      ("2005", "2006").

Relational sets
---------------
"2005"   31 features in the toolbox order of spec §2 (NOT the order of the paper's Table 1): lower = columns
         1-11, upper = 12-23, mix = 24-31. Each row of ``_SET_2005`` names its toolbox number and paper label.
"2006"   39 features F1-F39 in the order of spec §3: upper F1-F14, lower F15-F26, mix F27-F39.

Names
-----
A name says what a 1 bit means (``rfoot_behind`` = 1 when the right foot is behind). The first letter ``r``/``l``
of a sided feature is the body side. Where a 2006 feature asks the same question as a 2005 feature but with
another definition (other joints, thresholds or unit), the 2006 name carries the suffix ``_2006``
(``rfoot_raised`` vs ``rfoot_raised_2006``); features with identical definitions share the name (``rknee_bent``,
``lknee_bent``, ``relbow_bent``, ``lelbow_bent``, ``feet_crossed``). The 2005 toolbox "root fast" tests 1 cm/s
(practically "the root is not at rest", spec §5.2), so it is ``root_moving``; ``root_fast`` is the 2006 F39.

Conventions (spec §1)
---------------------
Positions in cm, y up. Body-size units come from the first frame of each document
(:func:`mocapviz.motion.skeleton.body_sizes`), except the touch features, whose radius is relative to the tested
segment's own length in each frame. Velocities use windows given in milliseconds, converted with each
document's frame rate, so any frame rate works. Almost every feature is "robust": two thresholds on the same
quantity, combined by a hysteresis (on at a rising edge of the strict stream, off at the first 0 of the lax
stream, §1.6). Features with a single threshold are stored with ``lax == strict``, for which the hysteresis is
the identity.

Implementation
--------------
Small geometric primitives (``_plane_distance`` ... ``_robust``) take and return arrays; quantity classes
(``_Plane``, ``_Speed``, ...) name the joints a primitive is applied to and know their own left/right mirror
image; the feature tables ``_SET_2005`` / ``_SET_2006`` combine a quantity with a comparison, two thresholds and
a unit. Left features are generated from the right ones by :func:`_pair`. A MotionDB is evaluated in batches of
whole documents: geometry is vectorised over all frames of a batch, velocities and the hysteresis run per
document, so nothing crosses a document boundary; the batches run on threads or as Dask tasks
(:func:`mocapviz.db.batches.map_documents`).
"""
from __future__ import annotations

import contextlib
import functools
import math
from dataclasses import dataclass, fields, replace

import numba
import numpy as np
import pandas as pd

from ..db.batches import map_documents
from ..db.database import MotionDB
from ..errors import ParameterError
from ..motion import Motion
from ..motion.skeleton import CANONICAL_JOINTS, body_size_table
from ..parallel import optional_client
from ..validation import finite_positions, one_of, renamed
from . import RELATIONAL_SETS  # the set names, with the package

__all__ = ["RELATIONAL_SETS", "feature_groups", "feature_names", "feature_table", "relational_features"]

GROUPS = ("lower", "upper", "mix")

_INDEX = {name: k for k, name in enumerate(CANONICAL_JOINTS)}
_UP = np.array([[0.0], [1.0], [0.0]])  # the vertical axis, [shape=(3, 1)]
_BATCH_FRAMES = 1 << 15  # a MotionDB is evaluated in batches of whole documents of about this many frames

# ====================================================================================== geometric primitives
# Vectors are stored coordinates first: a trajectory is an array [shape=(3, T)] whose rows x, y, z are contiguous,
# which keeps the row-wise arithmetic below fast on long batches.


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Frame-wise dot product: a, b [shape=(3, ...)] -> [shape=(...)]."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean length: v [shape=(3, ...)] -> [shape=(...)]."""
    return np.sqrt(_dot(v, v))


_KERNEL = {"cache": True, "nogil": True, "error_model": "numpy"}  # numpy float semantics: x / 0 -> inf or NaN


@numba.njit(inline="always", **_KERNEL)
def _plane_normal_at(p1, p2, p3, t):  # pragma: no cover - compiled
    """Unit normal of the plane through p1, p2, p3 at frame t: unit((p1 - p3) x (p2 - p3)), a 3-tuple."""
    ux, uy, uz = p1[0, t] - p3[0, t], p1[1, t] - p3[1, t], p1[2, t] - p3[2, t]
    vx, vy, vz = p2[0, t] - p3[0, t], p2[1, t] - p3[1, t], p2[2, t] - p3[2, t]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / norm, ny / norm, nz / norm


@numba.njit(**_KERNEL)
def _plane_distance(p1, p2, p3, q):  # pragma: no cover - compiled
    """Signed distance of q from the plane through p1, p2, p3 (toolbox ``feature_distPointPlane``, spec §1.4).

    Parameters
    ----------
    p1, p2, p3, q : np.ndarray [shape=(3, T)], float64

    Returns
    -------
    np.ndarray [shape=(T,)]: n . (q - p3) with n = unit((p1 - p3) x (p2 - p3)); positive on the normal's side.
    """
    out = np.empty(q.shape[1])
    for t in range(out.shape[0]):
        nx, ny, nz = _plane_normal_at(p1, p2, p3, t)
        out[t] = nx * (q[0, t] - p3[0, t]) + ny * (q[1, t] - p3[1, t]) + nz * (q[2, t] - p3[2, t])
    return out


@numba.njit(**_KERNEL)
def _plane_velocity(p1, p2, p3, v):  # pragma: no cover - compiled
    """Component of v along the unit normal of the plane through p1, p2, p3 (``feature_velRelPointPlane``).

    p1, p2, p3, v : np.ndarray [shape=(3, T)], float64 -> np.ndarray [shape=(T,)], the unit of v.
    """
    out = np.empty(v.shape[1])
    for t in range(out.shape[0]):
        nx, ny, nz = _plane_normal_at(p1, p2, p3, t)
        out[t] = nx * v[0, t] + ny * v[1, t] + nz * v[2, t]
    return out


@numba.njit(**_KERNEL)
def _normal_plane_distance(p1, p2, p3, q):  # pragma: no cover - compiled
    """Signed distance of q from the plane through p3 with normal unit(p2 - p1) (``feature_distPointNormalPlane``).

    Parameters
    ----------
    p1, p2, p3, q : np.ndarray [shape=(3, T)], float64

    Returns
    -------
    np.ndarray [shape=(T,)]: unit(p2 - p1) . (q - p3).
    """
    out = np.empty(q.shape[1])
    for t in range(out.shape[0]):
        nx, ny, nz = p2[0, t] - p1[0, t], p2[1, t] - p1[1, t], p2[2, t] - p1[2, t]
        dot = nx * (q[0, t] - p3[0, t]) + ny * (q[1, t] - p3[1, t]) + nz * (q[2, t] - p3[2, t])
        out[t] = dot / np.sqrt(nx * nx + ny * ny + nz * nz)
    return out


@numba.njit(**_KERNEL)
def _direction_velocity(p1, p2, v):  # pragma: no cover - compiled
    """Component of v along unit(p2 - p1) (``feature_velRelPointNormalPlane``).

    p1, p2, v : np.ndarray [shape=(3, T)], float64 -> np.ndarray [shape=(T,)], the unit of v.
    """
    out = np.empty(v.shape[1])
    for t in range(out.shape[0]):
        nx, ny, nz = p2[0, t] - p1[0, t], p2[1, t] - p1[1, t], p2[2, t] - p1[2, t]
        out[t] = (nx * v[0, t] + ny * v[1, t] + nz * v[2, t]) / np.sqrt(nx * nx + ny * ny + nz * nz)
    return out


@numba.njit(**_KERNEL)
def _segment_angle(p1, p2, p3, p4):  # pragma: no cover - compiled
    """Angle in degrees between the vectors p1 - p2 and p3 - p4 (``feature_angleSegmentSegment``).

    Parameters
    ----------
    p1, p2, p3, p4 : np.ndarray [shape=(3, T)], float64

    Returns
    -------
    np.ndarray [shape=(T,)], degrees in [0, 180]; the cosine clipped to [-1, 1] as in :func:`_vector_angle`.
    """
    out = np.empty(p1.shape[1])
    for t in range(out.shape[0]):
        ux, uy, uz = p1[0, t] - p2[0, t], p1[1, t] - p2[1, t], p1[2, t] - p2[2, t]
        vx, vy, vz = p3[0, t] - p4[0, t], p3[1, t] - p4[1, t], p3[2, t] - p4[2, t]
        cos = (ux * vx + uy * vy + uz * vz) / (np.sqrt(ux * ux + uy * uy + uz * uz) * np.sqrt(vx * vx + vy * vy + vz * vz))
        out[t] = np.degrees(np.arccos(min(1.0, max(-1.0, cos))))
    return out


def _joint_angle(a: np.ndarray, b: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """Angle at ``vertex`` between a and b in degrees, 180 = straight limb (``feature_angleJoint``).

    Parameters
    ----------
    a, b, vertex : np.ndarray [shape=(3, T)], float64

    Returns
    -------
    np.ndarray [shape=(T,)], degrees in [0, 180].
    """
    return _segment_angle(a, vertex, b, vertex)


def _vector_angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle in degrees between u and v: [shape=(3, T)] each, or v [shape=(3, 1)] fixed -> [shape=(T,)].

    Rounding beyond [-1, 1] in the cosine is clipped (the toolbox takes the real part of acos, the same thing).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = _dot(u, v) / (_norm(u) * _norm(v))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _window_frames(window_ms: float, fps: float) -> int:
    """Velocity window in frames, w = max(1, ceil(window_ms / 1000 * fps)) (spec §1.5).

    A relative tolerance of 1e-9 keeps a window that is an exact number of frames from rounding up
    (2000/120 ms at 120 Hz is 2 frames, not 3).
    """
    return max(1, math.ceil(window_ms / 1000.0 * fps * (1.0 - 1e-9)))


def _velocity(x: np.ndarray, w: int, fps: float) -> np.ndarray:
    """Smoothed velocity of trajectories (toolbox ``feature_velPoint`` before the norm, spec §1.5).

    Forward differences x(t+1) - x(t), the last one repeated; if there are fewer than w frames, mirror-padded at
    the end to w; then mirror-padded ("symmetric": the edge sample is repeated) by c = ceil(w/2) at both ends and
    averaged over w samples. Away from the ends, frame i gets (x(i + 1 + w - c) - x(i + 1 - c)) / w: a centred
    difference over w frames, centred one frame late, as in the toolbox.

    Parameters
    ----------
    x : np.ndarray [shape=(..., T)], T >= 2, cm -- time is the last axis.
    w : int
        Window in frames (:func:`_window_frames`); 1 = plain forward differences.
    fps : float

    Returns
    -------
    np.ndarray [shape=(..., T)], float64, cm/s.
    """
    n = x.shape[-1]
    flat = np.ascontiguousarray(x, dtype=np.float64).reshape(-1, n)
    out = np.empty_like(flat)
    _velocity_kernel(flat, np.array([0, n]), np.array([w]), np.array([float(fps)]), out)
    return out.reshape(x.shape)


@numba.njit(cache=True, nogil=True)
def _velocity_kernel(x, bounds, windows, fps, out):  # pragma: no cover - compiled
    """:func:`_velocity` of each document of k trajectories at once.

    x, out : (k, N) float64 (out written); bounds : (D+1,) document boundaries; windows : (D,) int, the window
    of each document in frames; fps : (D,). The padding is the symmetric (edge-repeating) extension, which
    repeats with period 2n for an array of n samples; the windowed sums are differences of a running sum.
    """
    for d in range(bounds.shape[0] - 1):
        a = bounds[d]
        n = bounds[d + 1] - a
        w = windows[d]
        c = (w + 1) // 2
        n1 = max(n, w)
        total = n1 + 2 * c
        ext = np.empty(n1)
        running = np.empty(total)
        scale = fps[d] / w
        for j in range(x.shape[0]):
            for m in range(n - 1):
                ext[m] = x[j, a + m + 1] - x[j, a + m]
            ext[n - 1] = ext[n - 2]
            for m in range(n, n1):  # fewer frames than the window: mirrored at the end
                r = m % (2 * n)
                ext[m] = ext[r] if r < n else ext[2 * n - 1 - r]
            acc = 0.0
            for m in range(total):  # mirrored by c at both ends, summed
                r = (m - c + 2 * n1) % (2 * n1)
                acc += ext[r] if r < n1 else ext[2 * n1 - 1 - r]
                running[m] = acc
            for i in range(n):
                out[j, a + i] = (running[i + w] - running[i]) * scale


@numba.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract", "arcp", "afn", "reassoc", "nsz"})
def _touch_kernel(joints, p1, p2, q, ball1, ball2, scale, out):  # pragma: no cover - compiled
    """min over pairs k of D_k / (scale_k * |p2_k - p1_k|), D_k the distance of joint q_k from the segment
    p1_k-p2_k (toolbox ``feature_bool_distPointSegment``, spec §1.4): the perpendicular distance from the line,
    or beyond an end the distance from that end if it is capped with a ball, else infinite.

    joints : (24, 3, N) float64 cm; p1, p2, q : (k,) joint indices; ball1, ball2 : (k,) bool; scale : (k,);
    out : (N,) float64, written. A zero-length segment gives NaN for its pair (ignored unless all pairs are NaN,
    as ``np.fmin``). The frame loop is branch-free (selects), so that it vectorises; no fast-math NaN/inf
    assumptions.
    """
    out[:] = np.nan
    for k in range(p1.shape[0]):
        a, b, c = joints[p1[k]], joints[p2[k]], joints[q[k]]
        cap1 = 0.0 if ball1[k] else np.inf
        cap2 = 0.0 if ball2[k] else np.inf
        for t in range(out.shape[0]):
            ax, ay, az = a[0, t], a[1, t], a[2, t]
            rx, ry, rz = b[0, t] - ax, b[1, t] - ay, b[2, t] - az
            vx, vy, vz = c[0, t] - ax, c[1, t] - ay, c[2, t] - az
            wx, wy, wz = vx - rx, vy - ry, vz - rz
            length = np.sqrt(rx * rx + ry * ry + rz * rz)
            along = (rx * vx + ry * vy + rz * vz) / length
            cx, cy, cz = vy * rz - vz * ry, vz * rx - vx * rz, vx * ry - vy * rx
            perp = np.sqrt(cx * cx + cy * cy + cz * cz) / length
            before = max(np.sqrt(vx * vx + vy * vy + vz * vz), cap1)
            beyond = max(np.sqrt(wx * wx + wy * wy + wz * wz), cap2)
            ratio = (before if along < 0 else (beyond if along > length else perp)) / (scale[k] * length)
            best = out[t]
            out[t] = ratio if (ratio < best or np.isnan(best)) else best


@numba.njit(cache=True)
def _hysteresis_kernel(lax, strict, bounds, out):  # pragma: no cover - compiled
    """lax, strict, out: (k, N) bool; bounds: (D+1,) int64 document boundaries. See :func:`_robust`."""
    for j in range(lax.shape[0]):
        for d in range(bounds.shape[0] - 1):
            on = False
            prev_lax = False
            prev_strict = False
            for t in range(bounds[d], bounds[d + 1]):
                lx = lax[j, t]
                st = strict[j, t]
                descent = prev_lax and not lx
                if on:
                    if descent:
                        on = False
                elif st and not prev_strict and not descent:
                    on = True
                out[j, t] = on
                prev_lax = lx
                prev_strict = st


def _robust(lax: np.ndarray, strict: np.ndarray, bounds=None) -> np.ndarray:
    """Hysteresis of two boolean streams (toolbox ``features_combine_robust``, spec §1.6).

    The output switches on at a rising edge of ``strict`` (a 1 after a 0; a 1 in the first frame of a document
    counts as one) and stays on up to, not including, the first frame where ``lax`` falls from 1 to 0. A rise of
    ``strict`` in the very frame where ``lax`` falls is ignored (the toolbox's "no singular spikes"); that only
    happens when strict is not a subset of lax. With ``lax == strict`` the output equals the input.

    Parameters
    ----------
    lax, strict : np.ndarray [shape=(T,) or (k, T)], bool
        The lax (off) and strict (on) threshold streams of k features; time is the last axis.
    bounds : np.ndarray [shape=(D+1,)], int, optional
        Document boundaries (0, end of document 1, ..., T): every document starts switched off. Default: one
        document.

    Returns
    -------
    np.ndarray, bool, the shape of ``lax``.
    """
    lax = np.asarray(lax, dtype=bool)
    strict = np.asarray(strict, dtype=bool)
    if lax.shape != strict.shape:
        raise ParameterError(f"lax and strict streams differ in shape: {lax.shape} vs {strict.shape}")
    n = lax.shape[-1]
    bounds = np.array([0, n] if bounds is None else bounds, dtype=np.int64)
    lax2 = np.ascontiguousarray(lax.reshape(-1, n))
    strict2 = np.ascontiguousarray(strict.reshape(-1, n))
    out = np.zeros_like(lax2)
    _hysteresis_kernel(lax2, strict2, bounds, out)
    return out.reshape(lax.shape)


# ============================================================================================ evaluation batch


class _Batch:
    """Whole documents of canonical positions, with the per-document quantities the features need.

    Attributes
    ----------
    joints : np.ndarray [shape=(24, 3, N)], float64, cm -- joint, then coordinate, then frame.
    bounds : np.ndarray [shape=(D+1,)], int64 -- document d is frames bounds[d]:bounds[d+1].
    fps : np.ndarray [shape=(D,)]
    sizes : dict of np.ndarray [shape=(D,)] -- :func:`mocapviz.motion.skeleton.body_sizes` of each document's first frame.
    """

    def __init__(self, positions: np.ndarray, bounds, fps):
        self.joints = np.ascontiguousarray(positions.transpose(1, 2, 0), dtype=np.float64)
        self.bounds = np.asarray(bounds, dtype=np.int64)
        self.fps = np.asarray(fps, dtype=np.float64)
        self.lengths = np.diff(self.bounds)
        self.n_frames = int(self.bounds[-1])
        table = body_size_table(positions[self.bounds[:-1]])
        self.sizes = {unit: table[unit].to_numpy() for unit in table.columns}
        self._values: dict = {}
        self._units: dict = {}
        self._velocities: dict = {}

    def __getitem__(self, joint: str) -> np.ndarray:
        """Trajectory of a canonical joint, [shape=(3, N)]."""
        return self.joints[_INDEX[joint]]

    def value(self, quantity: _Quantity) -> np.ndarray:
        """quantity(self), computed once per batch [shape=(N,)]."""
        out = self._values.get(quantity)
        if out is None:
            out = self._values[quantity] = quantity(self)
        return out

    def unit(self, unit: str):
        """Per-frame value of a threshold unit: a body size repeated over each document's frames, or 1."""
        if unit in _SCALAR_UNITS:
            return 1.0
        out = self._units.get(unit)
        if out is None:
            out = self._units[unit] = np.repeat(self.sizes[unit], self.lengths)
        return out

    def prefetch(self, requests) -> None:
        """Compute the smoothed velocities asked for, per document, all trajectories of a window at once.

        ``requests``: iterable of (q, p3, window_ms); the trajectory is q - p3 (q alone when p3 is None).
        """
        todo: dict[float, list] = {}
        for key in dict.fromkeys(requests):
            if key not in self._velocities:
                todo.setdefault(key[2], []).append(key)
        for window_ms, keys in todo.items():
            x = np.stack([self[q] - self[p3] if p3 else self[q] for q, p3, _ in keys])  # (k, 3, N)
            v = np.empty_like(x)
            windows = np.array([_window_frames(window_ms, fps) for fps in self.fps])
            _velocity_kernel(x.reshape(-1, self.n_frames), self.bounds, windows, self.fps, v.reshape(-1, self.n_frames))
            for k, key in enumerate(keys):
                self._velocities[key] = v[k]

    def velocity(self, q: str, p3: str | None, window_ms: float) -> np.ndarray:
        """Smoothed velocity of q - p3 in cm/s [shape=(3, N)] (:func:`_velocity`, per document)."""
        key = (q, p3, window_ms)
        if key not in self._velocities:
            self.prefetch([key])
        return self._velocities[key]


_SCALAR_UNITS = ("deg", "cm", "ratio")
_SIZE_UNITS = ("humerus_r", "humerus_l", "femur_r", "femur_l", "hip_width", "shoulder_width", "chest_length",
               "body_length")  # fmt: skip

# ================================================================================================ quantities


def _twin(joint: str) -> str:
    """The left/right mirror joint: lhip <-> rhip; root, neck, ... are their own twin."""
    if joint[:1] in ("l", "r"):
        other = {"l": "r", "r": "l"}[joint[0]] + joint[1:]
        if other in _INDEX:
            return other
    return joint


def _mirror_value(v):
    if isinstance(v, str):
        return _twin(v)
    if isinstance(v, _Quantity):
        return v.mirror()
    if isinstance(v, tuple):
        return tuple(_mirror_value(x) for x in v)
    return v


class _Quantity:
    """A real-valued per-frame quantity over named joints: ``q(batch) -> (N,)``.

    Subclasses are frozen dataclasses (hashable, so a batch computes each one once). ``mirror()`` gives the same
    quantity on the left/right mirrored body (every joint name swapped with its twin).
    """

    def __call__(self, b: _Batch) -> np.ndarray:
        raise NotImplementedError

    def mirror(self) -> _Quantity:
        return replace(self, **{f.name: _mirror_value(getattr(self, f.name)) for f in fields(self)})

    def velocities(self) -> tuple:
        """(q, p3, window_ms) of the smoothed velocities this quantity needs."""
        return tuple(r for f in fields(self) if isinstance(v := getattr(self, f.name), _Quantity)
                     for r in v.velocities())  # fmt: skip


@dataclass(frozen=True)
class _Plane(_Quantity):
    """Signed distance of q from the plane through p1, p2, p3 (:func:`_plane_distance`)."""

    p1: str
    p2: str
    p3: str
    q: str

    def __call__(self, b):
        return _plane_distance(b[self.p1], b[self.p2], b[self.p3], b[self.q])

    def mirror(self):
        # A reflection reverses the orientation of (p1, p2, p3); swapping p2 and p3 restores the physical side of
        # the normal. This turns the toolbox's right-side planes into exactly its left-side ones, e.g. 2005 #1
        # (root, lhip, lankle; rtoes) into #2 (root, rankle, rhip; ltoes), 2006 F1 into F2.
        return _Plane(_twin(self.p1), _twin(self.p3), _twin(self.p2), _twin(self.q))


@dataclass(frozen=True)
class _NormalPlane(_Quantity):
    """Signed distance of q from the plane through p3 with normal unit(p2 - p1) (:func:`_normal_plane_distance`)."""

    p1: str
    p2: str
    p3: str
    q: str

    def __call__(self, b):
        return _normal_plane_distance(b[self.p1], b[self.p2], b[self.p3], b[self.q])


@dataclass(frozen=True)
class _Height(_Quantity):
    """y(q) - y(ref): height of q above a horizontal plane through ref (normal plane with normal (0, 1, 0))."""

    q: str
    ref: str

    def __call__(self, b):
        return b[self.q][1] - b[self.ref][1]


@dataclass(frozen=True)
class _HeightAboveLowest(_Quantity):
    """y(q) - min y over the 24 canonical joints except ``exclude`` (toolbox ``feature_YBodyMin``)."""

    q: str
    exclude: tuple = ()

    def __call__(self, b):
        keep = [k for j, k in _INDEX.items() if j not in self.exclude]
        return b[self.q][1] - b.joints[keep, 1].min(axis=0)


@dataclass(frozen=True)
class _VerticalExtent(_Quantity):
    """max y - min y over all 24 canonical joints."""

    def __call__(self, b):
        y = b.joints[:, 1]
        return y.max(axis=0) - y.min(axis=0)


@dataclass(frozen=True)
class _HorizontalDiameter(_Quantity):
    """Largest pairwise distance in the x/z plane among ``joints``."""

    joints: tuple

    def __call__(self, b):
        xz = [b[j][::2] for j in self.joints]  # (2, N) each
        d2 = [((xz[i] - xz[k]) ** 2).sum(axis=0) for i in range(len(xz)) for k in range(i + 1, len(xz))]
        return np.sqrt(np.maximum.reduce(d2))


@dataclass(frozen=True)
class _JointAngle(_Quantity):
    """Angle at ``vertex`` between a and b, degrees (:func:`_joint_angle`)."""

    a: str
    b: str
    vertex: str

    def __call__(self, b):
        return _joint_angle(b[self.a], b[self.b], b[self.vertex])


@dataclass(frozen=True)
class _SegmentAngle(_Quantity):
    """Angle between p1 - p2 and p3 - p4, degrees (:func:`_segment_angle`)."""

    p1: str
    p2: str
    p3: str
    p4: str

    def __call__(self, b):
        return _segment_angle(b[self.p1], b[self.p2], b[self.p3], b[self.p4])


@dataclass(frozen=True)
class _AngleToVertical(_Quantity):
    """Angle between p2 - p1 and the up axis (0, 1, 0), degrees (``feature_angleVectorNormalPlane``)."""

    p1: str
    p2: str

    def __call__(self, b):
        return _vector_angle(b[self.p2] - b[self.p1], _UP)


@dataclass(frozen=True)
class _Touch(_Quantity):
    """Smallest relative distance of any of ``points`` from any of ``segments`` (OR of touch tests).

    ``segments``: tuples (p1, p2, balls, scale). The value is min over points and segments of
    D / (scale * |p2 - p1|), with D the point-segment distance of :func:`_touch_kernel` and the segment length of the current
    frame; "q within t * scale * |p2 - p1| of the segment" for any pair is then value <= t.
    """

    points: tuple
    segments: tuple

    def __call__(self, b):
        pairs = [(_INDEX[p1], _INDEX[p2], _INDEX[q], balls[0], balls[1], scale)
                 for p1, p2, balls, scale in self.segments for q in self.points]  # fmt: skip
        p1, p2, q, ball1, ball2, scale = (np.array(column) for column in zip(*pairs))
        out = np.empty(b.n_frames)
        _touch_kernel(b.joints, p1, p2, q, ball1, ball2, scale.astype(np.float64), out)
        return out


@dataclass(frozen=True)
class _Speed(_Quantity):
    """|smoothed velocity of a joint| in cm/s (toolbox ``feature_velPoint``)."""

    joint: str
    window_ms: float

    def __call__(self, b):
        return _norm(b.velocity(self.joint, None, self.window_ms))

    def velocities(self):
        return ((self.joint, None, self.window_ms),)


@dataclass(frozen=True)
class _PlaneVelocity(_Quantity):
    """Smoothed velocity of q - p3 (cm/s) along the current normal of plane p1, p2, p3 (``feature_velRelPointPlane``)."""

    p1: str
    p2: str
    p3: str
    q: str
    window_ms: float

    def __call__(self, b):
        return _plane_velocity(b[self.p1], b[self.p2], b[self.p3], b.velocity(self.q, self.p3, self.window_ms))

    def mirror(self):
        # as _Plane.mirror; keeps the toolbox's reference point: 2006 F1 and F2 both move relative to lhip
        return _PlaneVelocity(_twin(self.p1), _twin(self.p3), _twin(self.p2), _twin(self.q), self.window_ms)

    def velocities(self):
        return ((self.q, self.p3, self.window_ms),)


@dataclass(frozen=True)
class _NormalVelocity(_Quantity):
    """Smoothed velocity of q - p3 (cm/s) along unit(p2 - p1) (``feature_velRelPointNormalPlane``).

    With p3 = p1 and q = p2 this is about d|p2 - p1|/dt, the rate at which the two joints move apart.
    """

    p1: str
    p2: str
    p3: str
    q: str
    window_ms: float

    def __call__(self, b):
        return _direction_velocity(b[self.p1], b[self.p2], b.velocity(self.q, self.p3, self.window_ms))

    def velocities(self):
        return ((self.q, self.p3, self.window_ms),)


@dataclass(frozen=True)
class _Extreme(_Quantity):
    """Smallest (or largest) of the parts: "all parts >= t" is min >= t, "all parts <= t" is max <= t."""

    parts: tuple
    largest: bool = False

    def __call__(self, b):
        return (np.maximum if self.largest else np.minimum).reduce([b.value(p) for p in self.parts])

    def velocities(self):
        return tuple(r for p in self.parts for r in p.velocities())


def _Min(parts: tuple) -> _Extreme:
    return _Extreme(parts)


def _Max(parts: tuple) -> _Extreme:
    return _Extreme(parts, largest=True)


@dataclass(frozen=True)
class _Difference(_Quantity):
    """a - b."""

    a: _Quantity
    b: _Quantity

    def __call__(self, b):
        return b.value(self.a) - b.value(self.b)


@dataclass(frozen=True)
class _Abs(_Quantity):
    """|a|."""

    a: _Quantity

    def __call__(self, b):
        return np.abs(b.value(self.a))


# ================================================================================================== features


@dataclass(frozen=True)
class _Feature:
    """One boolean feature: ``quantity op threshold * unit``, with hysteresis between the lax and strict thresholds.

    op: ">=", ">", "<=", "<" or "in" (closed band, thresholds are (low, high) pairs). ``lax == strict`` means a
    single threshold (no hysteresis). ``spec`` names the spec row and paper feature it implements.
    """

    name: str
    group: str
    spec: str
    quantity: _Quantity
    op: str
    lax: float | tuple
    strict: float | tuple
    unit: str

    def compare(self, value: np.ndarray, threshold, unit) -> np.ndarray:
        if self.op == "in":
            return (value >= threshold[0] * unit) & (value <= threshold[1] * unit)
        return _OPS[self.op](value, threshold * unit)


_OPS = {">=": np.greater_equal, ">": np.greater, "<=": np.less_equal, "<": np.less}
_TWIN_UNIT = {"femur_r": "femur_l", "femur_l": "femur_r", "humerus_r": "humerus_l", "humerus_l": "humerus_r"}


def _pair(right: _Feature, left_spec: str, left_unit: str | None = None) -> list[_Feature]:
    """A right-side feature and its left-side mirror image.

    The left feature has the mirrored quantity, the name with its leading ``r`` turned into ``l`` and the
    twin unit (humerus_r -> humerus_l), unless ``left_unit`` gives the unit the toolbox actually uses.
    """
    if not right.name.startswith("r"):
        raise ParameterError(f"{right.name}: a right-side feature name starts with 'r'")
    left = replace(right, name="l" + right.name[1:], spec=left_spec, quantity=right.quantity.mirror(),
                   unit=left_unit or _TWIN_UNIT.get(right.unit, right.unit))  # fmt: skip
    return [right, left]


_F = _Feature
_MS_2005_ROOT = 1000.0 * 2 / 120  # spec §5.2: the toolbox's 2-frame window at 120 Hz, as a duration
_KNEE = ("rhip", "rankle", "rknee")
_ELBOW = ("rshoulder", "rwrist", "relbow")
_HAND = ("rfingers", "rwrist")
_BOTH = (True, True)

# The two tables: one entry per column, right-side features with their generated left twin (_pair).
# fmt: off
# -------------------------------------------------------------- 2005: 31 features, toolbox order (spec §2)
_SET_2005 = [
    # lower body, set positions 1-11 (spec §2.1)
    *_pair(_F("rfoot_behind", "lower", "2005 #1 footRightBack_robust = paper F_l1 (1 = toe tip BEHIND, §5.4)",
              _Plane("root", "lhip", "lankle", "rtoes"), ">=", 0.0, 0.25, "femur_r"),
           "2005 #2 footLeftBack_robust = paper F_l2 (1 = toe tip BEHIND, §5.4)"),
    *_pair(_F("rfoot_raised", "lower", "2005 #3 footRightLift_robust = paper F_l3",
              _Height("rtoes", "root"), ">=", -1.4, -1.2, "femur_r"),
           "2005 #4 footLeftLift_robust = paper F_l4 (unit: the RIGHT femur, §5.6)", left_unit="femur_r"),
    *_pair(_F("rleg_sideways", "lower", "2005 #5 footRightSideways_robust = paper F_l9",
              _NormalPlane("lhip", "rhip", "rhip", "rankle"), ">=", 1.0, 1.2, "hip_width"),
           "2005 #6 footLeftSideways_robust = paper F_l10"),
    *_pair(_F("rknee_bent", "lower", "2005 #7 kneeRightAngle_robust = paper F_l7",
              _JointAngle(*_KNEE), "<=", 120.0, 110.0, "deg"),
           "2005 #8 kneeLeftAngle_robust = paper F_l8"),
    _F("feet_crossed", "lower", "2005 #9 footCrossover_robust = paper F_l11 (legs crossed)",
       _NormalPlane("lhip", "rhip", "lankle", "rankle"), "<=", 0.0, -0.125, "hip_width"),
    # §5.1: the robust wrapper passes its strict threshold where the plain function ignores it: 1 femur/s for both
    *_pair(_F("rfoot_fast", "lower", "2005 #10 footRightHighVel_robust = paper F_l5 (not robust, §5.1)",
              _Min((_Speed("rtoes", 100.0), _Speed("rankle", 100.0))), ">", 1.0, 1.0, "femur_r"),
           "2005 #11 footLeftHighVel_robust = paper F_l6 (not robust, §5.1)"),
    # upper body, set positions 1-12 (spec §2.2)
    *_pair(_F("rhand_in_front", "upper", "2005 #12 handRightFront_robust = paper F_u1",
              _Plane("root", "lshoulder", "rshoulder", "rwrist"), ">=", 1.0, 1.15, "humerus_r"),
           "2005 #13 handLeftFront_robust = paper F_u2"),
    # §5.3 [UNCERTAIN whether intended, toolbox behaviour kept]: on 0.15 c above the neck, off one chest length
    # below it
    *_pair(_F("rhand_above_neck", "upper", "2005 #14 handRightLift_robust = paper F_u3 (right hand raised)",
              _NormalPlane("chest", "neck", "neck", "rwrist"), ">=", -1.0, 0.15, "chest_length"),
           "2005 #15 handLeftLift_robust = paper F_u4 (left hand raised)"),
    *_pair(_F("rarm_sideways", "upper", "2005 #16 handRightSideways_robust = paper F_u5",
              _NormalPlane("lshoulder", "rshoulder", "rshoulder", "rwrist"), ">=", 0.4, 0.5, "shoulder_width"),
           "2005 #17 handLeftSideways_robust = paper F_u6"),
    *_pair(_F("relbow_bent", "upper", "2005 #18 elbowRightAngle_robust = paper F_u7",
              _JointAngle(*_ELBOW), "<=", 120.0, 110.0, "deg"),
           "2005 #19 elbowLeftAngle_robust = paper F_u8"),
    _F("arms_crossed", "upper", "2005 #20 handCrossover_robust = paper F_u11",
       _NormalPlane("lshoulder", "rshoulder", "lwrist", "rwrist"), "<=", 0.0, -0.125, "shoulder_width"),
    # each hand's fingertip and wrist against the other hand's wrist-fingers segment
    _F("hands_touching", "upper", "2005 #21 handTouch_robust = paper F_u12",
       _Min((_Touch(("lfingers", "lwrist"), (("rfingers", "rwrist", _BOTH, 1.0),)),
             _Touch(("rfingers", "rwrist"), (("lfingers", "lwrist", _BOTH, 1.0),)))), "<=", 1.0, 0.75, "ratio"),
    *_pair(_F("rhand_fast", "upper", "2005 #22 handRightHighVel_robust = paper F_u9",
              _Speed("rfingers", 100.0), ">", 1.0, 1.25, "humerus_r"),
           "2005 #23 handLeftHighVel_robust = paper F_u10"),
    # mix, set positions 1-8 (spec §2.3): single thresholds, no hysteresis
    *_pair(_F("rhand_touching_leg", "mix", "2005 #24 handRightAnyLegTouch = paper F_m1 (any leg)",
              _Touch(_HAND, (("lknee", "lankle", _BOTH, 0.5), ("rknee", "rankle", _BOTH, 0.5),
                             ("lankle", "ltoes", _BOTH, 1.5), ("rankle", "rtoes", _BOTH, 1.5))),
              "<=", 1.0, 1.0, "ratio"),
           "2005 #25 handLeftAnyLegTouch = paper F_m2 (any leg)"),
    _F("torso_bent", "mix", "2005 #26 torsoBent = paper F_m7",
       _Max((_SegmentAngle("neck", "root", "lknee", "lhip"), _SegmentAngle("neck", "root", "rknee", "rhip"))),
       "<=", 110.0, 110.0, "deg"),
    # §5.2 [UNCERTAIN whether the paper used it so]: absolute 1 length unit/s (cm/s here, like the toolbox's
    # reader scaling) and a window of ceil(fs/10) read as milliseconds = 2 frames at 120 Hz
    _F("root_moving", "mix", "2005 #27 bool_velPoint('root','') = paper F_m8 (root fast; threshold 1 cm/s, §5.2)",
       _Speed("root", _MS_2005_ROOT), ">", 1.0, 1.0, "cm"),
    *_pair(_F("rhand_touching_head", "mix", "2005 #28 bool_distPointSegment(neck,headtop,rfingers) = paper F_m3",
              _Touch(("rfingers",), (("neck", "headtop", (False, True), 1.0),)), "<=", 1.0, 1.0, "ratio"),
           "2005 #29 bool_distPointSegment(neck,headtop,lfingers) = paper F_m4"),
    *_pair(_F("rhand_touching_hip", "mix", "2005 #30 bool_distPointSegment(lhip,rhip,rfingers) = paper F_m5",
              _Touch(("rfingers",), (("lhip", "rhip", _BOTH, 1.0),)), "<=", 1.0, 1.0, "ratio"),
           "2005 #31 bool_distPointSegment(lhip,rhip,lfingers) = paper F_m6"),
]

# ---------------------------------------------------------- 2006: 39 features F1-F39 (spec §3)
_SET_2006 = [
    # upper body F1-F14 (spec §3.1)
    *_pair(_F("rhand_moving_forward", "upper", "2006 F1 handRightToFrontRelTorso_robust (rhand moving forwards)",
              _PlaneVelocity("neck", "rhip", "lhip", "rwrist", 250.0), ">", 1.3, 1.8, "humerus_l"),
           "2006 F2 handLeftToFrontRelTorso_robust (lhand moving forwards)", left_unit="humerus_l"),
    *_pair(_F("rhand_above_neck_2006", "upper", "2006 F3 handRightRaisedRelSpine_robust (rhand above neck)",
              _NormalPlane("chest", "neck", "neck", "rwrist"), ">=", 0.0, 0.2, "chest_length"),
           "2006 F4 handLeftRaisedRelSpine_robust (lhand above neck)"),
    *_pair(_F("rhand_moving_up", "upper", "2006 F5 handRightToTopRelSpine_robust (rhand moving upwards)",
              _NormalVelocity("chest", "neck", "neck", "rwrist", 250.0), ">", 1.3, 1.8, "humerus_l"),
           "2006 F6 handLeftToTopRelSpine_robust (lhand moving upwards)", left_unit="humerus_l"),
    *_pair(_F("relbow_bent", "upper", "2006 F7 elbowRightBent_robust = 2005 #18",
              _JointAngle(*_ELBOW), "<=", 120.0, 110.0, "deg"),
           "2006 F8 elbowLeftBent_robust = 2005 #19"),
    _F("hands_apart", "upper", "2006 F9 handsApartRelShoulders_robust (hands far apart sideways)",
       _Abs(_NormalPlane("lshoulder", "rshoulder", "lwrist", "rwrist")), ">=", 2.0, 2.5, "shoulder_width"),
    _F("hands_moving_together", "upper", "2006 F10 handsMoveTogether_robust (hands approaching each other)",
       _NormalVelocity("lwrist", "rwrist", "rwrist", "lwrist", 100.0), ">=", 1.2, 1.4, "humerus_r"),
    *_pair(_F("rhand_moving_away", "upper", "2006 F11 handRightMoveApartRelRoot_robust (rhand moving away from root)",
              _NormalVelocity("rwrist", "root", "rwrist", "root", 0.0), ">=", 1.2, 1.4, "humerus_r"),
           "2006 F12 handLeftMoveApartRelRoot_robust (lhand moving away from root)", left_unit="humerus_r"),
    *_pair(_F("rhand_fast_2006", "upper", "2006 F13 handRightHighVel_robust (rhand fast)",
              _Speed("rfingers", 100.0), ">=", 2.0, 2.5, "humerus_r"),
           "2006 F14 handLeftHighVel_robust (lhand fast)", left_unit="humerus_r"),
    # lower body F15-F26 (spec §3.2)
    *_pair(_F("rfoot_behind_2006", "lower", "2006 F15 footRightBackRelLegLeft_robust (rfoot behind lleg)",
              _Plane("root", "lhip", "lankle", "rankle"), ">=", 0.0, 0.375, "humerus_r"),
           "2006 F16 footLeftBackRelLegRight_robust (lfoot behind rleg)", left_unit="humerus_r"),
    *_pair(_F("rfoot_raised_2006", "lower", "2006 F17 footRightRaisedRelYBodyMin_robust (rfoot raised)",
              _HeightAboveLowest("rtoes"), ">=", 1.0, 1.2, "humerus_r"),
           "2006 F18 footLeftRaisedRelYBodyMin_robust (lfoot raised)", left_unit="humerus_r"),
    _F("feet_apart", "lower", "2006 F19 feetApartRelHips_robust (feet far apart sideways; unit humerus)",
       _Abs(_NormalPlane("lhip", "rhip", "lankle", "rankle")), ">=", 1.8, 2.1, "humerus_r"),
    *_pair(_F("rknee_bent", "lower", "2006 F20 kneeRightBent_robust = 2005 #7",
              _JointAngle(*_KNEE), "<=", 120.0, 110.0, "deg"),
           "2006 F21 kneeLeftBent_robust = 2005 #8"),
    _F("feet_crossed", "lower", "2006 F22 footCrossover_robust = 2005 #9",
       _NormalPlane("lhip", "rhip", "lankle", "rankle"), "<=", 0.0, -0.125, "hip_width"),
    _F("feet_moving_together", "lower", "2006 F23 feetMoveTogetherRelHips_robust (feet approaching sideways)",
       _Difference(_NormalVelocity("lhip", "rhip", "rhip", "lankle", 100.0),
                   _NormalVelocity("lhip", "rhip", "rhip", "rankle", 100.0)), ">=", 1.3, 1.5, "humerus_r"),
    _F("feet_moving_apart", "lower", "2006 F24 feetMoveApartRelHips_robust (feet moving apart sideways)",
       _Difference(_NormalVelocity("lhip", "rhip", "rhip", "rankle", 100.0),
                   _NormalVelocity("lhip", "rhip", "rhip", "lankle", 100.0)), ">=", 1.3, 1.5, "humerus_r"),
    *_pair(_F("rfoot_fast_2006", "lower", "2006 F25 footRightHighVel_robust (rfoot fast)",
              _Min((_Speed("rtoes", 100.0), _Speed("rankle", 100.0))), ">=", 2.0, 2.5, "humerus_r"),
           "2006 F26 footLeftHighVel_robust (lfoot fast)", left_unit="humerus_r"),
    # mix F27-F39 (spec §3.3)
    *_pair(_F("rarm_abducted", "mix", "2006 F27 humerusRightAbductRelSpine_robust (rhumerus abducted)",
              _SegmentAngle("neck", "root", "relbow", "rshoulder"), "<", 155.0, 150.0, "deg"),
           "2006 F28 humerusLeftAbductRelSpine_robust (lhumerus abducted)"),
    *_pair(_F("rleg_abducted", "mix", "2006 F29 femurRightAbductRelSpine_robust (rfemur abducted)",
              _SegmentAngle("neck", "root", "rhip", "rknee"), ">", 45.0, 50.0, "deg"),
           "2006 F30 femurLeftAbductRelSpine_robust (lfemur abducted)"),
    _F("root_behind_feet", "mix", "2006 F31 rootBehindFeetLeftRightNeck_robust (root behind the frontal plane)",
       _Plane("lankle", "neck", "rankle", "root"), "<", -0.35, -0.5, "humerus_r"),
    _F("spine_horizontal", "mix", "2006 F32 spineHorizontalRelY_robust (spine horizontal)",
       _AngleToVertical("root", "neck"), "in", (60.0, 120.0), (70.0, 110.0), "deg"),
    *_pair(_F("rhand_low", "mix", "2006 F33 handRightLowRelYBodyMin_robust (rhand low)",
              _HeightAboveLowest("rfingers", ("rfingers", "rwrist")), "<", 1.4, 1.2, "humerus_r"),
           "2006 F34 handLeftLowRelYBodyMin_robust (lhand low)", left_unit="humerus_r"),
    # F35/F36 test one quantity both ways (the toolbox's F36 keeps F35's plane), so they are written out
    _F("shoulders_rotated_right", "mix", "2006 F35 shouldersRotatedRightRelHip_robust (left shoulder forward)",
       _Difference(_Plane("rhip", "lhip", "neck", "lshoulder"), _Plane("rhip", "lhip", "neck", "rshoulder")),
       ">", 0.35, 0.40, "humerus_l"),
    _F("shoulders_rotated_left", "mix", "2006 F36 shouldersRotatedLeftRelHip_robust (right shoulder forward)",
       _Difference(_Plane("rhip", "lhip", "neck", "lshoulder"), _Plane("rhip", "lhip", "neck", "rshoulder")),
       "<", -0.35, -0.40, "humerus_l"),
    _F("vertical_extent_small", "mix", "2006 F37 bodyExtentRelY_robust (vertical body extent small)",
       _VerticalExtent(), "<=", 0.9, 0.8, "body_length"),
    _F("horizontal_extent_large", "mix", "2006 F38 bodyExtentExtremitiesRelXZ_robust (horizontal extent large)",
       _HorizontalDiameter(("lankle", "rankle", "lwrist", "rwrist", "headtop", "root")), ">=", 3.0, 3.25,
       "humerus_r"),
    _F("root_fast", "mix", "2006 F39 rootHighVel_robust (root fast; 1-frame difference)",
       _Speed("root", 0.0), ">=", 2.0, 2.3, "humerus_r"),
]
# fmt: on

_SETS = {"2005": tuple(_SET_2005), "2006": tuple(_SET_2006)}


def _check_sets() -> None:
    """Import-time self-check of the tables against the spec's sizes."""
    sizes = {"2005": {"lower": 11, "upper": 12, "mix": 8}, "2006": {"upper": 14, "lower": 12, "mix": 13}}
    for name, feats in _SETS.items():
        counts = {g: sum(f.group == g for f in feats) for g in GROUPS}
        names = [f.name for f in feats]
        groups_in_order = list(dict.fromkeys(f.group for f in feats))
        assert counts == {g: sizes[name][g] for g in GROUPS}, (name, counts)
        assert groups_in_order == list(sizes[name]), (name, groups_in_order)
        assert len(set(names)) == len(names), name
        assert all(f.unit in _SCALAR_UNITS + _SIZE_UNITS for f in feats), name
    shared = {f.name: f for f in _SETS["2005"]}
    for f in _SETS["2006"]:
        if f.name in shared:
            g = shared[f.name]
            assert (f.quantity, f.op, f.lax, f.strict, f.unit) == (g.quantity, g.op, g.lax, g.strict, g.unit), f.name


_check_sets()

# ================================================================================================ public API


def _features(relational_set) -> tuple:
    return _SETS[one_of(str(relational_set), "relational set", RELATIONAL_SETS)]


def feature_names(relational_set: str = "2005") -> list[str]:
    """Column names of a relational set, in column order.

    Parameters
    ----------
    relational_set : {"2005", "2006"}
        Which relational set.

    Returns
    -------
    list of str
        31 names for "2005" (toolbox order: lower, upper, mix), 39 for "2006" (F1-F39).

    Raises
    ------
    ValueError
        An unknown set; the message lists the known ones.

    Examples
    --------
    >>> len(feature_names("2005")), len(feature_names("2006"))
    (31, 39)
    """
    return [f.name for f in _features(relational_set)]


def feature_groups(relational_set: str = "2005") -> dict[str, list[str]]:
    """Members of the groups "lower", "upper" and "mix" of a relational set, each in column order.

    "2005": 11 / 12 / 8 features (one inverted index per group, spec §1.7); "2006": 12 / 14 / 13.

    Parameters
    ----------
    relational_set : {"2005", "2006"}
        Which relational set.

    Returns
    -------
    dict
        ``"lower"``, ``"upper"``, ``"mix"`` -> list of feature names.

    Examples
    --------
    >>> {group: len(names) for group, names in feature_groups("2005").items()}
    {'lower': 11, 'upper': 12, 'mix': 8}
    """
    feats = _features(relational_set)
    return {g: [f.name for f in feats if f.group == g] for g in GROUPS}


def feature_table(relational_set: str = "2005") -> pd.DataFrame:
    """One row per feature of a relational set, in column order.

    Parameters
    ----------
    relational_set : {"2005", "2006"}
        Which relational set.

    Returns
    -------
    pandas.DataFrame
        Columns ``name``, ``group``, ``spec`` (spec row / paper feature), ``definition`` (the quantity), ``op``,
        ``lax``, ``strict`` (thresholds in ``unit``; equal when there is no hysteresis), ``unit`` (a body size of
        :func:`mocapviz.motion.skeleton.body_sizes`, "deg", "cm" or "ratio" = of the touched segment's own
        length), ``robust``.

    Examples
    --------
    >>> t = feature_table("2005")
    >>> t.loc[t.name == "rknee_bent", ["group", "op", "lax", "strict", "unit"]].to_numpy().tolist()
    [['lower', '<=', 120.0, 110.0, 'deg']]
    """
    return pd.DataFrame(
        [{"name": f.name, "group": f.group, "spec": f.spec, "definition": repr(f.quantity), "op": f.op,
          "lax": f.lax, "strict": f.strict, "unit": f.unit, "robust": f.lax != f.strict}
         for f in _features(relational_set)]
    )  # fmt: skip


def _evaluate(feats: tuple, batch: _Batch) -> np.ndarray:
    """Feature values of a batch of whole documents, [shape=(N, f)] bool."""
    batch.prefetch(r for f in feats for r in f.quantity.velocities())
    out = np.empty((len(feats), batch.n_frames), dtype=bool)
    robust, lax, strict = [], [], []
    for k, f in enumerate(feats):
        value = batch.value(f.quantity)
        unit = batch.unit(f.unit)
        on_lax = f.compare(value, f.lax, unit)
        if f.lax == f.strict:
            out[k] = on_lax
        else:
            robust.append(k)
            lax.append(on_lax)
            strict.append(f.compare(value, f.strict, unit))
    if robust:
        out[robust] = _robust(np.stack(lax), np.stack(strict), batch.bounds)
    return out.T


def _motion_features(motion: Motion, feats: tuple) -> np.ndarray:
    name = motion.source or "motion"
    motion = motion.canonical()
    if motion.n_frames < 2:
        raise ParameterError(f"{name}: {motion.n_frames} frame(s); relational features need at least 2 (velocities)")
    finite_positions(motion.positions, lambda t: f"{name}, frame {t}", joint_names=CANONICAL_JOINTS)
    return _evaluate(feats, _Batch(motion.positions, [0, motion.n_frames], [motion.fps]))


def _check_lengths(db: MotionDB) -> None:
    """A ParameterError naming the first document of ``db`` with fewer than 2 frames (no velocities)."""
    short = db.documents["n_frames"].to_numpy(np.int64) < 2
    if short.any():
        row = db.documents.iloc[int(np.argmax(short))]
        raise ParameterError(f"{db.path}: document {row['doc_id']} ({row['path']}) has {row['n_frames']} frame(s); "
                         f"relational features need at least 2 per document")  # fmt: skip


def _batch_features(relational_set: str, positions: np.ndarray, bounds: np.ndarray, fps: np.ndarray) -> np.ndarray:
    """The ``work`` of :func:`mocapviz.db.batches.map_documents`: feature values of a batch of whole documents,
    [shape=(N, f)] bool (module level, so that Dask workers can import it)."""
    return _evaluate(_features(relational_set), _Batch(positions, bounds, fps))


def _db_features(db: MotionDB, relational_set: str, progress: bool, threads: int | None, client) -> np.ndarray:
    """Feature values of every frame of a MotionDB, [shape=(N, f)] bool: batches of whole documents of about
    ``_BATCH_FRAMES`` frames on threads or as Dask tasks of ``client``, written here in frame order."""
    n_features = len(_features(relational_set))
    _check_lengths(db)
    out = np.empty((db.n_frames, n_features), dtype=bool)
    batches = map_documents(db, functools.partial(_batch_features, str(relational_set)), _BATCH_FRAMES,
                            threads=threads, client=client, desc=f"relational features {n_features}",
                            progress=progress, name="mocapviz-relational")  # fmt: skip
    with contextlib.closing(batches):
        for frames, values in batches:
            out[frames] = values
    return out


@renamed(feature_set="relational_set")
def relational_features(source, relational_set: str = "2005", progress: bool = True, threads: int | None = None,
                        scheduler=None) -> tuple[np.ndarray, list[str]]:  # fmt: skip
    """Boolean relational features of every frame (Müller, Röder & Clausen 2005 §3; Müller & Röder 2006).

    Parameters
    ----------
    source : Motion or MotionDB
        A Motion on any skeleton (mapped with ``motion.canonical()``), or a MotionDB: each document is computed
        on its own (velocity windows, hysteresis and body sizes never cross a document boundary) and the rows are
        the database's frames, in its frame order (document order).
    relational_set : {"2005", "2006"}
        "2005": 31 features, toolbox order (lower 1-11, upper 12-23, mix 24-31); "2006": F1-F39 (upper F1-F14,
        lower F15-F26, mix F27-F39). See :func:`feature_table` for the definitions. (Formerly ``feature_set``:
        still accepted, with a FutureWarning.)
    progress : bool
        Progress bar over the documents of a MotionDB with more than 50 documents.
    threads : int, optional
        Threads over batches of documents of a MotionDB (default :func:`mocapviz.parallel.default_threads`: the
        cores this process may use, at most 8).
    scheduler : None, "local", str or dask.distributed.Client
        Compute the batches of whole documents of a MotionDB as Dask tasks (:func:`mocapviz.parallel.dask_client`:
        ``"local"`` starts a local cluster for this call, an address connects to a scheduler whose workers see the
        database's path, a Client is used as it is). None (default): threads in this process. Same values.

    Returns
    -------
    values : np.ndarray [shape=(T, f)], bool
    names : list of str [length f]

    Raises
    ------
    ValueError
        Unknown relational set; a clip (document) with fewer than 2 frames; a NaN or infinite position (the
        message names the clip or document and the frame).
    mocapviz.SkeletonMappingError
        A Motion whose joints cannot be mapped onto the canonical skeleton.
    TypeError
        ``source`` is neither a Motion nor a MotionDB.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005, §3 (relational features; the 31 of Table 1 in the HDM05 toolbox's definitions).
    .. [2] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006 (the 39 features of the "2006" set).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> values, names = relational_features(db.motion(7)[0:120])  # a kick of the left foot, 1 s
    >>> values.shape, values.dtype, len(names)
    ((120, 31), dtype('bool'), 31)
    >>> names[:4]
    ['rfoot_behind', 'lfoot_behind', 'rfoot_raised', 'lfoot_raised']
    >>> all_values, _ = relational_features(db, "2006", progress=False)  # every frame, document by document
    >>> all_values.shape
    (5543, 39)
    """
    feats = _features(relational_set)
    names = [f.name for f in feats]
    if isinstance(source, Motion):
        return _motion_features(source, feats), names
    if isinstance(source, MotionDB):
        with optional_client(scheduler) as client:
            return _db_features(source, relational_set, progress, threads, client), names
    raise ParameterError(f"relational features need a Motion or a MotionDB, got {type(source).__name__}")
