"""Frame-to-frame distance measures of Krüger, Tautges, Weber & Zinke 2010, §3.1.

Each measure compares per-frame *descriptors* and comes in two forms that share one kernel: one query frame
against m frames (a vector (m,), the form a nearest-neighbour experiment calls once per query) and two frame
sets against each other (a matrix (n, m), computed in blocks of rows); the one-to-many form is the kernel
applied to a single row.

Public functions
----------------
deuler, deuler_pairwise   Deuler: Euclidean distance of the source file's Euler angles (degrees), wrapped.
dquat, dquat_pairwise     Dquat: (weighted) sum over joints of the rotation angle between local quaternions.
dpc, dpc_pairwise         Dpc_n: Kovar & Gleicher's point-cloud distance of n-frame windows.
dwb, dwb_pairwise         Dwb: Lee et al.'s transition cost with Wang & Bodenheimer's joint weights (or Lee's).
window_clouds             the point clouds of n-frame windows that dpc compares.
pc_align                  Kovar & Gleicher's closed-form alignment: rotation about y, translation on the floor.
lee_frames                local quaternions with their angular velocities: the descriptors dwb compares.
joint_weights             None, "lee", "wb" or an array -> weights over the joints.
LEE_WEIGHTS, WB_WEIGHTS   the joint weight tables of Lee et al. 2002 and Wang & Bodenheimer 2003.

Inputs
------
Arrays, so that one code path serves a single Motion, a list of clips and a whole MotionDB (concatenated
frames, ``lengths`` = the documents' frame counts so that windows and velocities stop at document ends):

========  ==========================  ===========================================  ===============================
measure   descriptor of T frames      from a Motion                                from a MotionDB
========  ==========================  ===========================================  ===============================
Deuler    (T, C) degrees              ``motion.euler`` (the AMC/BVH channels)      not stored (read the files)
Dquat     (T, J, 4) unit (w,x,y,z)    ``motion.quaternions`` (any skeleton) or     ``db.quaternions``
                                      ``motion.canonical().quaternions``
Dpc_n     (T, n*J, 3) cm              ``window_clouds(motion.canonical()           ``window_clouds(db.positions,
                                      .positions, n)``                             n, lengths=n_frames)``
Dwb       (T, 24, 7)                  ``lee_frames(motion.canonical()              ``lee_frames(db.quaternions,
                                      .quaternions, motion.fps)``                  fps, lengths=n_frames)``
========  ==========================  ===========================================  ===============================

The named weight tables (``"lee"``, ``"wb"``) are over the 24 canonical joints in the order of
:data:`mocapviz.motion.skeleton.CANONICAL_JOINTS`; for another skeleton pass an array of weights.

Root handling: no measure uses the root translation. The root's rotation is the source's global orientation,
heading included; it counts in Deuler, in Dquat (unless weighted 0) and in Dwb with Lee's weights (his
"pelvis"), not with Wang & Bodenheimer's. Dpc removes heading and floor position by its alignment.
"""
from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..motion import rotations
from ..motion.skeleton import CANONICAL_JOINTS

__all__ = [
    "LEE_WEIGHTS", "NU", "WB_WEIGHTS", "deuler", "deuler_pairwise", "dpc", "dpc_pairwise", "dquat",
    "dquat_pairwise", "dwb", "dwb_pairwise", "joint_weights", "lee_frames", "pc_align", "window_clouds",
]  # fmt: skip

# Lee, Chai, Reitsma, Hodgins & Pollard 2002 (transition cost), as Krüger et al. 2010 §3.1 state them: 1 for the
# shoulders, elbows, hips, knees, pelvis and spine, 0 for all other joints (Lee et al. name neck, head, wrists,
# ankles and toes). On the canonical joints, each carrying the rotation of the source bone that starts there
# (skeleton.ASF_MAP): pelvis = root; spine = belly (ASF upperback) and chest (thorax) -- the ASF lowerback
# rotation has no canonical joint. [UNCERTAIN] "shoulder" is taken as the humerus rotation (lshoulder), so the
# clavicles get 0.
LEE_WEIGHTS = {name: 0.0 for name in CANONICAL_JOINTS} | {
    name: 1.0 for name in ("root", "belly", "chest", "lhip", "rhip", "lknee", "rknee",
                           "lshoulder", "rshoulder", "lelbow", "relbow")
}  # fmt: skip

# Wang & Bodenheimer 2003 (SCA, "An evaluation of a cost metric for selecting transitions between motion
# segments"), optimised by constrained least squares; Krüger et al. 2010 §3.1: non-zero only on the left and
# right hip, knee, shoulder and elbow. [UNCERTAIN] The optimised values are not in Krüger et al. 2010 and the
# WB03 table was not available here: equal weights 1 on those eight joints until the published values are
# entered (left = right assumed).
WB_WEIGHTS = {name: 0.0 for name in CANONICAL_JOINTS} | {
    name: 1.0 for name in ("lhip", "rhip", "lknee", "rknee", "lshoulder", "rshoulder", "lelbow", "relbow")
}  # fmt: skip

# Lee et al. 2002's nu weighs joint-velocity against joint-angle differences. [UNCERTAIN] No value reproduced
# here; velocities are per second (so the cost does not depend on the frame rate), and nu = (1/30 s)^2 makes the
# velocity term that of velocities measured per frame at 30 Hz (Krüger's kNN frame rate) with nu = 1.
NU = (1.0 / 30.0) ** 2

_BLOCK_ELEMENTS = 1 << 22  # float64 elements of the largest temporary a pairwise block may create (32 MB)
_UNIT_TOLERANCE = 1e-3  # |‖q‖ - 1| allowed for a stored (float32) unit quaternion before it is an error
_TABLES = {"lee": LEE_WEIGHTS, "wb": WB_WEIGHTS}


# ---------------------------------------------------------------------------------------------- validation


def _array(x, name: str, ndim: int, last: int | None = None) -> np.ndarray:
    """``x`` as a finite float array of ``ndim`` dimensions (last axis ``last`` long), else a ValueError."""
    x = np.asarray(x)
    if x.dtype.kind not in "fiu":
        raise ParameterError(f"{name} must be a numeric array, got dtype {x.dtype}")
    if x.ndim != ndim or (last is not None and x.shape[-1] != last):
        want = ", ".join(["n"] * (ndim - 1) + [str(last) if last is not None else "c"])
        raise ParameterError(f"{name} must have shape ({want}), got {x.shape}")
    if not np.isfinite(x).all():
        raise ParameterError(f"{name} contains NaN or infinite values (a MotionDB marks missing rotations with NaN)")
    return x


def _same_frame_shape(a: np.ndarray, b: np.ndarray, a_name: str, b_name: str, skip_a: int) -> None:
    if a.shape[skip_a:] != b.shape[1:]:
        raise ParameterError(
            f"{a_name} frames have shape {a.shape[skip_a:]} but {b_name} frames {b.shape[1:]}; "
            "both must come from the same skeleton (same joints / channels)"
        )


def _squared_norms(q: np.ndarray, name: str) -> np.ndarray:
    """Squared norms [shape=(...)] of quaternions [shape=(..., 4)]; a ValueError unless they are unit to 1e-3
    (float32 storage is to 1e-7)."""
    sq = np.einsum("...c,...c->...", q, q)
    if sq.size and np.abs(sq - 1.0).max() > 2 * _UNIT_TOLERANCE:
        raise ParameterError(f"{name} are not unit quaternions (a norm is {np.sqrt(sq.flat[np.abs(sq - 1).argmax()]):.4g})")
    return sq


def joint_weights(weights, n_joints: int) -> np.ndarray:
    """Joint weights as an array.

    Parameters
    ----------
    weights : None, "lee", "wb" or array_like [shape=(n_joints,)]
        None: 1 for every joint. ``"lee"`` / ``"wb"``: :data:`LEE_WEIGHTS` / :data:`WB_WEIGHTS`, over the 24
        canonical joints. An array: non-negative, finite, not all zero.
    n_joints : int
        J, the number of joints of the frames the weights go with.

    Returns
    -------
    np.ndarray [shape=(n_joints,)], float64

    Raises
    ------
    ValueError
        Unknown table name, a named table with J != 24, wrong shape, negative / non-finite / all-zero weights.
    """
    if weights is None:
        return np.ones(n_joints)
    if isinstance(weights, str):
        if weights not in _TABLES:
            raise ParameterError(f"unknown weight table {weights!r}; use 'lee', 'wb', None or an array of {n_joints}")
        if n_joints != len(CANONICAL_JOINTS):
            raise ParameterError(
                f"weight table {weights!r} is over the {len(CANONICAL_JOINTS)} canonical joints but the frames have "
                f"{n_joints} joints; use motion.canonical() (or MotionDB arrays) or pass an array of weights"
            )
        return np.array([_TABLES[weights][name] for name in CANONICAL_JOINTS])
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n_joints,):
        raise ParameterError(f"weights must have shape ({n_joints},), one per joint, got {w.shape}")
    if not np.isfinite(w).all() or (w < 0).any() or not w.any():
        raise ParameterError("weights must be finite, non-negative and not all zero")
    return w


def _document_bounds(n_frames: int, lengths) -> tuple[np.ndarray, np.ndarray]:
    """First and last frame index of the document holding each of ``n_frames`` concatenated frames."""
    lengths = np.array([n_frames] if lengths is None else lengths)
    if lengths.ndim != 1 or lengths.dtype.kind not in "iu" or (lengths < 1).any() or lengths.sum() != n_frames:
        raise ParameterError(
            f"lengths must be positive integer frame counts summing to the {n_frames} frames, got {lengths.tolist()}"
        )
    ends = np.cumsum(lengths)
    first = np.repeat(ends - lengths, lengths)
    return first, np.repeat(ends - 1, lengths)


def _blocks(n_rows: int, elements_per_row: int):
    """Row slices whose temporaries stay below _BLOCK_ELEMENTS."""
    step = max(1, _BLOCK_ELEMENTS // max(1, elements_per_row))
    return (slice(i, min(i + step, n_rows)) for i in range(0, n_rows, step))


# ------------------------------------------------------------------------------------------------- kernels


def _rotation_angle(a: np.ndarray, b: np.ndarray, a_sq: np.ndarray, b_sq: np.ndarray) -> np.ndarray:
    """Angle (radians, [0, pi]) of the rotation between unit quaternions a and b [shape=(..., 4)] (broadcasting),
    given their squared norms ``a_sq``, ``b_sq`` [shape=(...)].

    With s the sign of a.b (q and -q are one rotation) and a.b = cos(phi) for unit a, b,
    |a - s b|^2 = |a|^2 + |b|^2 - 2 |a.b| = 4 sin^2(phi/2) and |a - s b|^2 + |a + s b|^2 = 2 (|a|^2 + |b|^2), so
    the rotation angle 2 arccos|a.b| = 2 phi = 4 arcsin(sqrt(|a - s b|^2 / (2 (|a|^2 + |b|^2)))). The arcsin
    is well conditioned here (phi/2 <= pi/4), and the ratio makes the angle insensitive to float32 rounding
    of the norms, which moves arccos|a.b| of near-equal rotations by 1e-3 rad.
    """
    total = a_sq + b_sq
    chord = np.maximum(total - 2.0 * np.abs(np.einsum("...c,...c->...", a, b)), 0.0)
    return 4.0 * np.arcsin(np.sqrt(chord / (2.0 * total)))


def _euler_kernel(a: tuple, b: tuple) -> np.ndarray:
    diff = a[0] - b[0]
    turns = np.rint(diff * (1.0 / 360.0))
    diff -= 360.0 * turns  # into [-180, 180]
    return np.sqrt(np.einsum("...c,...c->...", diff, diff))


def _quat_kernel(a: tuple, b: tuple, w: np.ndarray) -> np.ndarray:
    return _rotation_angle(a[0], b[0], a[1], b[1]) @ w


def _lee_kernel(a: tuple, b: tuple, w: np.ndarray, nu: float) -> np.ndarray:
    (qa, qa_sq, va, va_sq), (qb, qb_sq, vb, vb_sq) = a, b
    half_angle = 0.5 * _rotation_angle(qa, qb, qa_sq, qb_sq)
    dv_sq = np.maximum(va_sq + vb_sq - 2.0 * np.einsum("...c,...c->...", va, vb), 0.0)  # |va - vb|^2
    return (half_angle * half_angle + (0.25 * nu) * dv_sq) @ w


def _one_to_many(kernel, query: tuple, frames: tuple, *args) -> np.ndarray:
    """kernel(query, frames): the descriptor arrays of one frame (broadcast) against those of m frames."""
    return kernel(tuple(x[None] for x in query), frames, *args)


def _pairwise(kernel, a: tuple, b: tuple, *args) -> np.ndarray:
    """kernel(a[i], b) for every row i, in blocks of rows: the pairwise form of the one-to-many kernel."""
    out = np.empty((len(a[0]), len(b[0])))
    for rows in _blocks(len(a[0]), max(x.size for x in b)):
        out[rows] = kernel(tuple(x[rows, None] for x in a), tuple(x[None] for x in b), *args)
    return out


# ------------------------------------------------------------------------------------------------- Deuler


def _euler_inputs(a, b, a_ndim: int) -> tuple[tuple, tuple]:
    a_name, b_name = ("query", "frames") if a_ndim == 1 else ("a", "b")
    a = _array(a, a_name, a_ndim).astype(np.float64, copy=False)
    b = _array(b, b_name, 2).astype(np.float64, copy=False)
    _same_frame_shape(a, b, a_name, b_name, a_ndim - 1)
    return (a,), (b,)


def deuler(query: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Deuler (Krüger et al. 2010 §3.1): distance on the source's Euler angles, one frame against many.

    The Euler angles are the channel values of the source file ("the Euler angles in the standard asf/amc
    representation", §3.1), root translation excluded. Wrap-around: each channel's difference is taken modulo
    360 degrees into [-180, 180], ``d = (e1 - e2) - 360 round((e1 - e2) / 360)``, so 179 and -179 degrees are 2
    degrees apart, and a channel stored as 248 in one frame and -112 in another, or unwrapped to -705 (HDM05 root
    rz), counts only its difference modulo a full turn. Only this per-channel wrap is applied: two Euler
    triples of one rotation (XYZ (180, 0, 180) and (0, 180, 0), or any pair near gimbal lock) stay far apart,
    the encoding dependence §3.1 contrasts with Dquat. [UNCERTAIN] Krüger et al. do not give the norm; the
    Euclidean one is that of their feature-set kNN.

    Parameters
    ----------
    query : np.ndarray [shape=(C,)]
        One frame's rotation channels in degrees (a row of :attr:`mocapviz.motion.Motion.euler`: the
        AMC/BVH channel values, root translation excluded).
    frames : np.ndarray [shape=(m, C)]
        Frames of the same skeleton (same channels).

    Returns
    -------
    np.ndarray [shape=(m,)], float64
        Distances of ``query`` to each frame, degrees.

    Raises
    ------
    ValueError
        Wrong dimensions, different channel counts, NaN or infinite values.

    Examples
    --------
    >>> deuler(np.array([179.0, 10.0]), np.array([[-179.0, 10.0], [179.0, 13.0]]))
    array([2., 3.])
    """
    query, frames = _euler_inputs(query, frames, 1)
    return _one_to_many(_euler_kernel, query, frames)


def deuler_pairwise(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Deuler between every frame of ``a`` and of ``b``.

    Row i equals ``deuler(a[i], b)``; see :func:`deuler`.

    Parameters
    ----------
    a : np.ndarray [shape=(n, C)]
        Rotation channels in degrees.
    b : np.ndarray [shape=(m, C)]
        Rotation channels of the same skeleton, degrees.

    Returns
    -------
    np.ndarray [shape=(n, m)], float64
        Degrees.

    Examples
    --------
    >>> deuler_pairwise(np.array([[179.0, 10.0], [0.0, 0.0]]), np.array([[-179.0, 10.0]])).round(2).tolist()
    [[2.0], [179.28]]
    """
    a, b = _euler_inputs(a, b, 2)
    return _pairwise(_euler_kernel, a, b)


# -------------------------------------------------------------------------------------------------- Dquat


def _quat_inputs(a, b, a_ndim: int, weights) -> tuple[tuple, tuple, np.ndarray]:
    a_name, b_name = ("query", "frames") if a_ndim == 2 else ("a", "b")
    a = _array(a, a_name, a_ndim, 4).astype(np.float64, copy=False)
    b = _array(b, b_name, 3, 4).astype(np.float64, copy=False)
    _same_frame_shape(a, b, a_name, b_name, a_ndim - 2)
    return (a, _squared_norms(a, a_name)), (b, _squared_norms(b, b_name)), joint_weights(weights, b.shape[1])


def dquat(query: np.ndarray, frames: np.ndarray, weights=None) -> np.ndarray:
    """Dquat (Krüger et al. 2010 §3.1): joint-angle distance on quaternions, one frame against many.

    ``sum_j w_j * 2 arccos |<q1_j, q2_j>|``: the angle of the rotation between the two frames' local rotations
    of each joint, summed over the joints. q and -q are the same rotation and give the same distance.

    Parameters
    ----------
    query : np.ndarray [shape=(J, 4)]
        One frame's local joint rotations, unit quaternions (w, x, y, z).
    frames : np.ndarray [shape=(m, J, 4)]
    weights : None, "lee", "wb" or np.ndarray [shape=(J,)]
        Joint weights (:func:`joint_weights`); default 1 for every joint.

    Returns
    -------
    np.ndarray [shape=(m,)], float64
        Distances of ``query`` to each frame, radians (weighted).

    Raises
    ------
    ValueError
        Wrong shapes, different joint counts, NaN, quaternions that are not unit, bad weights.
    """
    query, frames, w = _quat_inputs(query, frames, 2, weights)
    return _one_to_many(_quat_kernel, query, frames, w)


def dquat_pairwise(a: np.ndarray, b: np.ndarray, weights=None) -> np.ndarray:
    """Dquat between every frame of ``a`` and of ``b``.

    Row i equals ``dquat(a[i], b, weights)``; see :func:`dquat`.

    Parameters
    ----------
    a : np.ndarray [shape=(n, J, 4)]
        Unit local quaternions (w, x, y, z).
    b : np.ndarray [shape=(m, J, 4)]
        Unit local quaternions of the same joints.
    weights : None, "lee", "wb" or np.ndarray [shape=(J,)]
        Joint weights (:func:`joint_weights`; None: all 1).

    Returns
    -------
    np.ndarray [shape=(n, m)], float64
        Weighted sums of rotation angles, radians.
    """
    a, b, w = _quat_inputs(a, b, 3, weights)
    return _pairwise(_quat_kernel, a, b, w)


# ---------------------------------------------------------------------------------------------------- Dpc


def window_clouds(positions: np.ndarray, n: int, frames=None, lengths=None) -> np.ndarray:
    """Point clouds of n-frame windows (Kovar & Gleicher 2004; Krüger et al. 2010 §3.1 Dpc_n).

    The cloud of frame t holds the joints of frames t - (n-1)/2 ... t + (n-1)/2, window frame by window frame.
    Windows are clamped at the ends of each clip: an index before the first frame takes the first frame, one
    after the last frame the last (frame 0 with n = 5 uses frames 0, 0, 0, 1, 2). n counts frames at the
    rate of ``positions`` (Dpc_11 at 30 Hz spans 0.33 s).

    Parameters
    ----------
    positions : np.ndarray [shape=(T, J, 3)], cm, y up
        Joint positions, e.g. the 24 canonical joints (``motion.canonical().positions``, ``db.positions``).
    n : int
        Window length in frames, odd and >= 1 (1, 5, 11, ...).
    frames : array_like of int [shape=(F,)], optional
        The frames whose clouds to build (default all T); e.g. a query frame and its nearest neighbours.
    lengths : array_like of int, optional
        Frame counts of the clips concatenated in ``positions`` (a MotionDB's ``n_frames``); default one clip.

    Returns
    -------
    np.ndarray [shape=(F, n * J, 3)], float64
        One point cloud per frame (as :func:`dpc` computes), cm.

    Raises
    ------
    ValueError
        Bad shapes, NaN, n not a positive odd integer, a clip shorter than n frames, ``lengths`` not summing
        to T, frame indices out of range.
    """
    positions = _array(positions, "positions", 3, 3)
    if not isinstance(n, (int, np.integer)) or n < 1 or n % 2 == 0:
        raise ParameterError(f"window length n must be a positive odd integer (1, 5, 11, ...), got {n!r}")
    first, last = _document_bounds(positions.shape[0], lengths)
    short = (last - first + 1) < n
    if short.any():
        k = int(np.argmax(short))
        raise ParameterError(
            f"the clip starting at frame {first[k]} has {last[k] - first[k] + 1} frames, too few frames for a "
            f"window of n={n} frames"
        )
    frames = np.arange(positions.shape[0]) if frames is None else np.asarray(frames)
    if frames.ndim != 1 or frames.dtype.kind not in "iu" or (frames < 0).any() or (frames >= positions.shape[0]).any():
        raise ParameterError(f"frames must be a 1-D array of frame indices in [0, {positions.shape[0]})")
    window = frames[:, None] + np.arange(n) - (n - 1) // 2
    window = np.clip(window, first[frames, None], last[frames, None])
    return positions[window].reshape(frames.size, n * positions.shape[1], 3).astype(np.float64, copy=False)


def _point_weights(weights, n_points: int) -> np.ndarray:
    if weights is None:
        return np.ones(n_points)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n_points,):
        raise ParameterError(
            f"dpc weights must have shape ({n_points},), one per cloud point (np.tile(joint_weights, n)), got {w.shape}"
        )
    if not np.isfinite(w).all() or (w < 0).any() or not w.any():
        raise ParameterError("dpc weights must be finite, non-negative and not all zero")
    return w


def _cloud_inputs(a, b, a_ndim: int, weights):
    a_name, b_name = ("query", "clouds") if a_ndim == 2 else ("a", "b")
    a = _array(a, a_name, a_ndim, 3).astype(np.float64, copy=False)
    b = _array(b, b_name, 3, 3).astype(np.float64, copy=False)
    _same_frame_shape(a, b, a_name, b_name, a_ndim - 2)
    return a, b, _point_weights(weights, b.shape[1])


def pc_align(a: np.ndarray, b: np.ndarray, weights=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kovar & Gleicher's optimal alignment of point cloud ``b`` onto ``a`` (Kovar & Gleicher 2004, the alignment
    of Kovar, Gleicher & Pighin 2002, "Motion graphs").

    The transform ``T(p) = R_y(theta) p + (x0, 0, z0)``, with ``R_y(theta) p = (x cos + z sin, y, -x sin + z cos)``,
    that minimises ``sum_i w_i |a_i - T(b_i)|^2``. With the weights normalised to sum 1 and
    ``xa = sum w_i xa_i`` (likewise za, xb, zb) the closed form is::

        theta = atan2( sum w_i (xa_i zb_i - xb_i za_i) - (xa zb - xb za),
                       sum w_i (xa_i xb_i + za_i zb_i) - (xa xb + za zb) )
        x0 = xa - xb cos(theta) - zb sin(theta)
        z0 = za + xb sin(theta) - zb cos(theta)

    Kovar & Gleicher write arctan of the quotient; the two-argument form picks the minimising branch.

    Parameters
    ----------
    a, b : np.ndarray [shape=(..., K, 3)], cm, y up
        Point clouds with corresponding points (broadcasting over the leading axes).
    weights : np.ndarray [shape=(K,)], optional
        Point weights, default uniform.

    Returns
    -------
    theta : np.ndarray [shape=(...)], radians
    x0, z0 : np.ndarray [shape=(...)], cm
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim < 2 or a.shape[-1] != 3 or b.ndim < 2 or b.shape[-2:] != a.shape[-2:]:
        raise ParameterError(f"pc_align needs clouds of shape (..., K, 3) with the same K, got {a.shape} and {b.shape}")
    w = _point_weights(weights, a.shape[-2])
    w = w / w.sum()
    xa, za, xb, zb = a[..., 0], a[..., 2], b[..., 0], b[..., 2]
    mxa, mza, mxb, mzb = xa @ w, za @ w, xb @ w, zb @ w
    across = (xa * zb - xb * za) @ w - (mxa * mzb - mxb * mza)
    along = (xa * xb + za * zb) @ w - (mxa * mxb + mza * mzb)
    theta = np.arctan2(across, along)
    c, s = np.cos(theta), np.sin(theta)
    return theta, mxa - mxb * c - mzb * s, mza + mxb * s - mzb * c


def _cloud_moments(clouds: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted horizontal centroids (x, z) [shape=(F, 2)] of clouds [shape=(F, K, 3)], and their weighted
    squared norms about them, sum_i w_i (x_i^2 + y_i^2 + z_i^2) - W (x_mean^2 + z_mean^2) [shape=(F,)], W = sum w."""
    k = w.size
    flat = clouds.reshape(len(clouds), 3 * k)
    mean = np.zeros((k, 3, 2))
    mean[:, 0, 0] = mean[:, 2, 1] = w / w.sum()
    centroid = flat @ mean.reshape(3 * k, 2)
    norm = np.einsum("fi,fi,i->f", flat, flat, np.repeat(w, 3)) - w.sum() * np.einsum("fc,fc->f", centroid, centroid)
    return centroid, norm


def _pc_kernel(a: np.ndarray, b: np.ndarray, b_moments: tuple, w: np.ndarray) -> np.ndarray:
    """Dpc of every cloud of ``a`` [shape=(n, K, 3)] against every cloud of ``b`` [shape=(m, K, 3)] -> (n, m).

    Centred horizontally on their weighted centroids (the optimal translation makes them coincide), two clouds
    are ``sum w |a - R_y(theta) b|^2 = |a|_w^2 + |b|_w^2 - 2 H - 2 (P cos(theta) + Q sin(theta))`` with
    ``H = sum w ya yb``, ``P = sum w (xa xb + za zb)`` and ``Q = sum w (xa zb - za xb)`` (centred x, z): the
    two sums of :func:`pc_align`'s theta. The minimum over theta, at theta = atan2(Q, P), is
    ``|a|_w^2 + |b|_w^2 - 2 H - 2 sqrt(P^2 + Q^2)``. H, P and Q are inner products of the flattened clouds
    (centring subtracts ``W`` times products of centroids), so one matrix product gives them for all pairs.
    """
    n, k = a.shape[:2]
    total = w.sum()
    centroid_a, norm_a = _cloud_moments(a, w)
    centroid_b, norm_b = b_moments
    coef = np.zeros((3, n, k, 3))  # coefficients on b's flattened (x, y, z) coordinates giving P, Q and H
    coef[0, ..., 0], coef[0, ..., 2] = a[..., 0] * w, a[..., 2] * w
    coef[1, ..., 0], coef[1, ..., 2] = -a[..., 2] * w, a[..., 0] * w
    coef[2, ..., 1] = a[..., 1] * w
    g = coef.reshape(3 * n, 3 * k) @ b.reshape(len(b), 3 * k).T
    p = g[:n] - total * (centroid_a @ centroid_b.T)
    q = g[n : 2 * n] - total * (centroid_a[:, :1] * centroid_b[:, 1] - centroid_a[:, 1:] * centroid_b[:, 0])
    d = norm_a[:, None] + norm_b - 2.0 * g[2 * n :] - 2.0 * np.sqrt(p * p + q * q)
    return np.maximum(d, 0.0)  # rounding can leave -1e-9 cm^2 for identical clouds


def dpc(query: np.ndarray, clouds: np.ndarray, weights=None) -> np.ndarray:
    """Dpc_n (Kovar & Gleicher 2004; Krüger et al. 2010 §3.1): point-cloud distance, one window against many.

    ``min over theta, x0, z0 of sum_i w_i |a_i - T_{theta,x0,z0}(b_i)|^2``: the weighted sum of squared
    distances between corresponding points of two window clouds (:func:`window_clouds`) after the optimal
    rotation about the vertical axis and translation on the floor (closed form: :func:`pc_align`). It is
    invariant to where on the floor and in which direction either motion was performed, not to tilting.

    Parameters
    ----------
    query : np.ndarray [shape=(K, 3)], cm
        One frame's window cloud, K = n * J points.
    clouds : np.ndarray [shape=(m, K, 3)], cm
        Window clouds of the same n and joints.
    weights : np.ndarray [shape=(K,)], optional
        Point weights; default 1 for every point. [UNCERTAIN] Kovar & Gleicher leave the weights open (they
        mention emphasising joints or tapering towards the window ends); uniform here.

    Returns
    -------
    np.ndarray [shape=(m,)], float64
        Distances of ``query`` to each cloud, cm^2.

    Raises
    ------
    ValueError
        Wrong shapes, different point counts, NaN, bad weights.
    """
    query, clouds, w = _cloud_inputs(query, clouds, 2, weights)
    return _pc_kernel(query[None], clouds, _cloud_moments(clouds, w), w)[0]


def dpc_pairwise(a: np.ndarray, b: np.ndarray, weights=None) -> np.ndarray:
    """Dpc_n between every cloud of ``a`` and of ``b``.

    Row i equals ``dpc(a[i], b, weights)``; see :func:`dpc`.

    Parameters
    ----------
    a : np.ndarray [shape=(n, K, 3)]
        Point clouds of n-frame windows (:func:`window_clouds`), cm.
    b : np.ndarray [shape=(m, K, 3)]
        Point clouds of the same size, cm.
    weights : np.ndarray [shape=(K,)], optional
        Point weights (default all 1).

    Returns
    -------
    np.ndarray [shape=(n, m)], float64
        cm^2.
    """
    a, b, w = _cloud_inputs(a, b, 3, weights)
    moments = _cloud_moments(b, w)
    out = np.empty((len(a), len(b)))
    for rows in _blocks(len(a), 3 * len(b)):
        out[rows] = _pc_kernel(a[rows], b, moments, w)
    return out


# ---------------------------------------------------------------------------------------------------- Dwb


def lee_frames(quaternions: np.ndarray, fps: float, lengths=None, frames=None) -> np.ndarray:
    """Per-frame joint rotations and joint angular velocities, the descriptors of Lee et al.'s cost (:func:`dwb`).

    The angular velocity of joint j at frame t, in its parent's axes, is ``omega = 2 log(q[t+1] q[t-1]^-1) /
    (2 dt)`` (central difference; forward / backward at the first / last frame of each clip), ``log`` of the
    shorter-arc quaternion being the half-angle axis vector. [UNCERTAIN] Lee et al. 2002 do not say how
    they differentiate.

    Parameters
    ----------
    quaternions : np.ndarray [shape=(T, J, 4)]
        Local joint rotations, unit (w, x, y, z), e.g. ``motion.canonical().quaternions`` or ``db.quaternions``.
    fps : float
        Frame rate of all clips.
    lengths : array_like of int, optional
        Frame counts of the clips concatenated in ``quaternions``; default one clip.
    frames : array_like of int [shape=(F,)], optional
        The frames whose descriptors to build (default all T); only these frames and their neighbours are read
        and checked, so a few frames of a large memory-mapped database cost little.

    Returns
    -------
    np.ndarray [shape=(F, J, 7)] (F = T by default), float64: ``[..., :4]`` the normalised quaternion,
    ``[..., 4:]`` omega in rad/s.

    Raises
    ------
    ValueError
        Bad shapes, NaN, non-unit quaternions, fps not positive, a clip of fewer than 2 frames, ``lengths``
        not summing to T, frame indices out of range.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be a positive number, got {fps!r}")
    quaternions = np.asarray(quaternions)
    if quaternions.ndim != 3 or quaternions.shape[-1] != 4:
        _array(quaternions, "quaternions", 3, 4)  # raises, naming the shape
    first, last = _document_bounds(quaternions.shape[0], lengths)
    if (first == last).any():
        k = int(np.argmax(first == last))
        raise ParameterError(f"the clip at frame {k} has 1 frame; joint velocities need at least 2 frames")
    t = np.arange(quaternions.shape[0]) if frames is None else np.asarray(frames)
    if t.ndim != 1 or t.dtype.kind not in "iu" or (t < 0).any() or (t >= quaternions.shape[0]).any():
        raise ParameterError(f"frames must be a 1-D array of frame indices in [0, {quaternions.shape[0]})")
    before, after = np.maximum(t - 1, first[t]), np.minimum(t + 1, last[t])
    used, where = np.unique(np.concatenate([t, before, after]), return_inverse=True)  # each frame read once
    q = _array(quaternions[used], "quaternions", 3, 4).astype(np.float64, copy=False)
    q_t, q_before, q_after = np.split((q / np.sqrt(_squared_norms(q, "quaternions"))[..., None])[where], 3)
    step = rotations.multiply(q_after, q_before * np.array([1.0, -1.0, -1.0, -1.0]))
    step = np.where(step[..., :1] < 0, -step, step)  # the shorter arc
    sin_half = np.linalg.norm(step[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(sin_half, step[..., 0])
    axis_angle = step[..., 1:] * np.divide(angle, sin_half, out=np.zeros_like(angle), where=sin_half > 0)[..., None]
    dt = ((after - before) / float(fps))[:, None, None]
    return np.concatenate([q_t, axis_angle / dt], axis=-1)


def _lee_inputs(a, b, a_ndim: int, weights, nu):
    a_name, b_name = ("query", "frames") if a_ndim == 2 else ("a", "b")
    a = _array(a, a_name, a_ndim, 7).astype(np.float64, copy=False)
    b = _array(b, b_name, 3, 7).astype(np.float64, copy=False)
    _same_frame_shape(a, b, a_name, b_name, a_ndim - 2)
    if not (np.isfinite(nu) and nu >= 0):
        raise ParameterError(f"nu must be a non-negative number, got {nu!r}")
    parts = []
    for x, name in ((a, a_name), (b, b_name)):
        q, v = x[..., :4], x[..., 4:]
        parts.append((q, _squared_norms(q, name + " quaternions"), v, np.einsum("...c,...c->...", v, v)))
    return parts[0], parts[1], joint_weights(weights, b.shape[1])


def dwb(query: np.ndarray, frames: np.ndarray, weights="wb", nu: float = NU) -> np.ndarray:
    """Dwb (Krüger et al. 2010 §3.1): Lee et al. 2002's transition cost, one frame against many.

    ``D = sum_j w_j |log(q1_j^-1 q2_j)|^2 + nu sum_j w_j |v1_j - v2_j|^2``: Lee et al.'s weighted joint-angle
    differences plus weighted joint-velocity differences, where ``|log(q1^-1 q2)|`` is half the rotation angle
    between the joint's two rotations (Lee's log convention) and ``v = omega / 2`` the joint velocity in the same
    log units (omega from :func:`lee_frames`). Lee's first term also holds the squared distance of the root
    positions; it is left out (a deliberate deviation), since frames of different clips have unrelated floor
    coordinates. With ``weights="wb"`` (default) the weights are Wang & Bodenheimer's optimised ones
    (:data:`WB_WEIGHTS`), with ``"lee"`` Lee's 0/1 weights (:data:`LEE_WEIGHTS`).

    Parameters
    ----------
    query : np.ndarray [shape=(J, 7)]
        One frame of :func:`lee_frames`.
    frames : np.ndarray [shape=(m, J, 7)]
    weights : "wb", "lee", None or np.ndarray [shape=(J,)]
        Joint weights (:func:`joint_weights`); the named tables need the 24 canonical joints.
    nu : float
        Weight of the velocity term, s^2 (default :data:`NU`, [UNCERTAIN]).

    Returns
    -------
    np.ndarray [shape=(m,)], float64
        Distances of ``query`` to each frame, rad^2 (weighted).

    Raises
    ------
    ValueError
        Wrong shapes, different joint counts, NaN, non-unit quaternions, bad weights or nu.
    """
    query, frames, w = _lee_inputs(query, frames, 2, weights, nu)
    return _one_to_many(_lee_kernel, query, frames, w, float(nu))


def dwb_pairwise(a: np.ndarray, b: np.ndarray, weights="wb", nu: float = NU) -> np.ndarray:
    """Dwb between every frame of ``a`` and of ``b``.

    Row i equals ``dwb(a[i], b, weights, nu)``; see :func:`dwb`.

    Parameters
    ----------
    a : np.ndarray [shape=(n, J, 7)]
        Local quaternions with angular velocities (:func:`lee_frames`).
    b : np.ndarray [shape=(m, J, 7)]
        The same descriptors of other frames.
    weights : "wb", "lee", None or np.ndarray [shape=(J,)]
        Joint weights (:func:`joint_weights`; default Wang & Bodenheimer's).
    nu : float
        Weight of the velocity term (:func:`dwb`).

    Returns
    -------
    np.ndarray [shape=(n, m)], float64
        rad^2 (weighted), as :func:`dwb`.
    """
    a, b, w = _lee_inputs(a, b, 3, weights, nu)
    return _pairwise(_lee_kernel, a, b, w, float(nu))
