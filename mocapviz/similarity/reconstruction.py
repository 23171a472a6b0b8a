"""Full-body motion from six sparse markers with local linear pose models (Krüger, Tautges, Weber & Zinke 2010
§5.2, Tables 3-4, after Chai & Hodgins 2005, "Performance animation from low-dimensional control signals").

Every frame of a motion is rebuilt from the positions of six markers: the four end effectors, the head and the
root (:data:`MARKERS`). For each frame the k nearest poses of a prior database are fetched with a kd-tree on a
numeric feature set (F15E: the five non-root markers in the body frame, exactly what the markers give), a local
linear model (weighted mean and weighted PCA of those k poses) is fitted, and the pose is the model's point that
best explains the markers, stays likely under the model, and continues the previous frames smoothly.

Public API
----------
MARKERS               the six marker joints: lwrist, rwrist, lankle, rankle, head, root.
synthetic_markers     a motion's joints at the markers, disturbed by uniform noise of +-1 mm (the paper's test data).
body_frame_markers    markers minus the root marker, rotated into the body frame: (T, 5, 3), the F15E layout.
marker_query          the same as an F15E query vector (T, 15).
PosePrior             a prior database: body-frame poses, a valid mask (leave-one-out), kd-trees per numeric set.
reconstruct           markers + headings -> (T, 24, 3) world positions (one pass with F15E, two passes otherwise).
reconstruction_errors mean / max per-joint error, per-joint and per-frame errors, bone-length error.
BONES                 the 23 (parent, child) joint pairs of the canonical skeleton.

The method in detail
--------------------
Coordinates. A database pose y is all 24 canonical joints in its *body frame*
(:func:`mocapviz.motion.skeleton.body_frame`: root at the origin, heading from the hip line rotated to face +z), flattened
joint-major to 72 numbers, in cm. The markers are put into the same frame: marker minus root marker, rotated by
minus the heading. Markers alone do not give the heading (five points and a root do not fix the pelvis
orientation); we treat the root marker as a rigid pelvis marker cluster that gives position *and* heading, and
take the heading from the test motion's hip line, noise-free. [UNCERTAIN] The paper does not say how it obtains
the body frame; Chai & Hodgins express their control signals relative to the root, as far as we know from their
paper's description, and we do not know how the heading was measured there.

Neighbour search (§5.2). F15E = lwrist, rwrist, lankle, rankle, head in the body frame, so the five body-frame
markers (:func:`marker_query`) *are* an F15E vector and can be searched directly in a :class:`mocapviz.similarity.knn.KnnIndex`
over the prior's F15E features. Chai & Hodgins searched a precomputed neighbourhood graph around the neighbours of
the previous frame; Krüger et al. replace it by an exact kd-tree search.

Local linear model (after Chai & Hodgins 2005). The k neighbours' poses y_i with distances d_i to the query are
weighted by a Gaussian kernel w_i = exp(-d_i^2 / (2 h^2)), h = ``bandwidth`` x the median of the k distances
(``bandwidth=None``: equal weights). [UNCERTAIN] The kernel and its width are our choice, not taken from either
paper (the median makes the width free of the feature set's units, so the same bandwidth serves F15E, F30x3E and
the PCA sets); with the default width the farthest neighbours weigh almost nothing, so the kernel rather than k
decides how local the model is. Mean mu = sum w_i y_i / sum w_i; principal axes u_j and variances lambda_j of the weighted
covariance sum w_i (y_i - mu)(y_i - mu)^T / sum w_i (an eigendecomposition of the 72 x 72 matrix), keeping the
first r axes whose variances sum to ``variance`` of the total, r <= k - 1 (axes with lambda_j <= 1e-9 of the
largest are dropped: they carry nothing).

Pose estimate. x = mu + U c, c in R^r minimises

    E(c) = |S x - m|^2 / marker_sigma^2  +  sum_j c_j^2 / lambda_j  +  |x - p|^2 / smooth_sigma^2

with S the 15 rows of the five non-root marker joints, m the body-frame markers (the root marker is the origin of
the body frame, and every database pose has its root there, so the root term vanishes), the second term the
Gaussian prior of the local model and p = 2 x_{t-1} - x_{t-2} the constant-velocity prediction from the two
previous *estimated* body-frame poses (x_{t-1} at the second frame, no smoothness term at the first). The three
terms are the negative log-likelihoods of Gaussian marker noise, the local model and Gaussian acceleration, so
the sigmas are in cm. The estimate is online (causal), as in Chai & Hodgins: each frame is solved from the past
only. E is quadratic in c, so each frame is a small r x r linear system: the per-frame matrices are built for all
frames at once (batched numpy), the sequential part is two (r x 72) products per frame. The smoothness term lives
in the body frame (each pose in its own frame), so the root's travel and turning do not enter it. The body-frame
pose is then rotated by the heading and moved to the root marker.

Two passes for the other numeric sets (Table 4). F30E, F39E, the windowed sets and the PCA sets need joints the
markers do not give. Pass 1 reconstructs with F15E from the markers; pass 2 computes the set on the pass-1
reconstruction (as a Motion at the prior's frame rate; Fp_n with the prior database's PCA model), searches the
neighbours in that set, rebuilds the local models and solves again with the same markers and smoothness. [UNCERTAIN]
The paper only says that kd-trees "search around arbitrary, i.e. newly synthesized poses", against Chai &
Hodgins' search around the neighbours of previously synthesised frames.

Defaults (``DEFAULT_K`` = 1024, ``DEFAULT_VARIANCE`` = 0.999, ``DEFAULT_BANDWIDTH`` = 0.35,
``DEFAULT_MARKER_SIGMA`` = 0.5 cm, ``DEFAULT_SMOOTH_SIGMA`` = 10 cm) were chosen by a sweep on the HDM05 cut clips
at 30 Hz (actor bk's first clip of each of the 11 classes; priors: HDM05 without bk, and without the test clip
only), the paper giving none. The error falls steadily with k (mean of both priors: k = 16 6.2 cm, 64 5.3, 256
4.4, 1024 3.7, 2048 3.5): the Gaussian kernel, not k, then sets how local the model is. k = 2048 is a little better
on this 17,878-frame database at twice the cost. sigma_m between 0.25 and 0.5 cm is best (1 cm and more loosens the
markers); the smoothness term changes the error by < 0.01 cm at sigma_s >= 10 cm and raises it at 3 cm (it lags
behind fast motions), so it is kept weak: the markers pin the pose. Notebook 07 shows the sweep.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from ..db.database import MotionDB
from ..errors import ParameterError
from ..features.numeric import NUMERIC_SETS, PCAModel, default_pca, numeric_features, numeric_of
from ..motion import Motion
from ..motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS, body_frame
from ..validation import Interval, count
from .knn import KnnIndex

__all__ = [
    "BONES",
    "DEFAULT_BANDWIDTH",
    "DEFAULT_K",
    "DEFAULT_MARKER_SIGMA",
    "DEFAULT_SMOOTH_SIGMA",
    "DEFAULT_VARIANCE",
    "MARKERS",
    "METHODS",
    "NOISE_RANGE_CM",
    "PosePrior",
    "body_frame_markers",
    "marker_query",
    "reconstruct",
    "reconstruction_errors",
    "synthetic_markers",
]

MARKERS = ("lwrist", "rwrist", "lankle", "rankle", "head", "root")  # §5.2: 4 end effectors, the head, the root
_MARKER_JOINTS = np.array([CANONICAL_JOINTS.index(j) for j in MARKERS])
_QUERY_ROWS = np.array([3 * j + a for j in _MARKER_JOINTS[:5] for a in range(3)])  # S: rows of x for the markers
BONES = tuple((int(p), c) for c, p in enumerate(CANONICAL_PARENTS) if p >= 0)  # 23 (parent, child)
METHODS = ("llm", "mean", "nn")
# the synthetic markers' noise, cm: at most 1 m, about half a body's height (a marker farther off no longer says
# where its joint is; §5.2 uses 1 mm)
NOISE_RANGE_CM = Interval(0.0, 100.0)

DEFAULT_K = 1024
DEFAULT_VARIANCE = 0.999
DEFAULT_BANDWIDTH = 0.35
DEFAULT_MARKER_SIGMA = 0.5  # cm
DEFAULT_SMOOTH_SIGMA = 10.0  # cm
_POSE_DIMS = 3 * len(CANONICAL_JOINTS)
_CHUNK_BYTES = 64 << 20  # neighbour poses gathered at once (float64)
_TINY_VARIANCE = 1e-9  # relative to a frame's largest local variance: such axes are dropped


# ============================================================================ markers
def synthetic_markers(positions, noise_cm: float = 0.1, seed=None) -> np.ndarray:
    """Marker positions of a motion, as in §5.2: the joints of :data:`MARKERS` "randomly disturbed within a range
    of 1 mm".

    Parameters
    ----------
    positions : np.ndarray [shape=(T, 24, 3)]
        Canonical joints, cm, y up.
    noise_cm : float
        Each coordinate gets independent uniform noise in [-noise_cm, noise_cm] cm (in :data:`NOISE_RANGE_CM`,
        0..100 cm; default 0.1 cm = 1 mm).
    seed : int or np.random.Generator, optional
        The noise's generator or seed.

    Returns
    -------
    np.ndarray [shape=(T, 6, 3)], float64
        Markers in the order of :data:`MARKERS`, cm.
    """
    pos = np.asarray(positions)
    if pos.ndim != 3 or pos.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise ParameterError(f"positions must have shape (T, {len(CANONICAL_JOINTS)}, 3); got {pos.shape}")
    noise_cm = NOISE_RANGE_CM.check(noise_cm, "noise_cm")
    rng = np.random.default_rng(seed)
    clean = pos[:, _MARKER_JOINTS].astype(np.float64)
    return clean + rng.uniform(-noise_cm, noise_cm, size=clean.shape)


def _check_markers(markers, headings) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(markers)
    if m.ndim != 3 or m.shape[1:] != (len(MARKERS), 3) or m.shape[0] < 1:
        raise ParameterError(f"markers must have shape (T, {len(MARKERS)}, 3), T >= 1, in the order {MARKERS}; "
                         f"got {m.shape}")  # fmt: skip
    if not np.issubdtype(m.dtype, np.number):
        raise ParameterError(f"markers must be real numbers; got dtype {m.dtype}")
    m = m.astype(np.float64)
    bad = ~np.isfinite(m).all(axis=(1, 2))
    if bad.any():
        t = int(np.argmax(bad))
        which = [MARKERS[j] for j in np.flatnonzero(~np.isfinite(m[t]).all(axis=1))]
        raise ParameterError(f"markers: frame {t} has a NaN or infinite position (marker {', '.join(which)}); "
                         f"{int(bad.sum())} such frame(s). Fill gaps before reconstructing")  # fmt: skip
    h = np.asarray(headings, dtype=np.float64)
    if h.shape != (m.shape[0],):
        raise ParameterError(f"headings must have shape ({m.shape[0]},), one angle per marker frame; got {h.shape}")
    if not np.isfinite(h).all():
        raise ParameterError(f"headings: frame {int(np.argmax(~np.isfinite(h)))} is NaN or infinite")
    return m, h


def body_frame_markers(markers, headings) -> np.ndarray:
    """The five non-root markers relative to the root marker, in the body frame.

    Parameters
    ----------
    markers : np.ndarray [shape=(T, 6, 3)]
        Marker positions, cm, y up, in the order of :data:`MARKERS`.
    headings : np.ndarray [shape=(T,)]
        Radians (:func:`mocapviz.motion.skeleton.heading`: 0 facing +z).

    Returns
    -------
    np.ndarray [shape=(T, 5, 3)], float64
        lwrist, rwrist, lankle, rankle, head minus the root marker, rotated by minus the heading about y (the
        transform of :func:`mocapviz.motion.skeleton.body_frame`), cm.
    """
    m, h = _check_markers(markers, headings)
    d = m[:, :5] - m[:, 5:]
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    return np.stack([d[..., 0] * c - d[..., 2] * s, d[..., 1], d[..., 0] * s + d[..., 2] * c], axis=-1)


def marker_query(markers, headings) -> np.ndarray:
    """:func:`body_frame_markers` as F15E feature vectors: the kd-tree query of §5.2.

    Parameters
    ----------
    markers : np.ndarray [shape=(T, 6, 3)]
        Marker positions, cm, y up, in the order of :data:`MARKERS`.
    headings : np.ndarray [shape=(T,)]
        Radians (:func:`mocapviz.motion.skeleton.heading`: 0 facing +z).

    Returns
    -------
    np.ndarray [shape=(T, 15)], float64
        cm, in the column order of F15E (:func:`mocapviz.features.numeric_columns`).
    """
    return body_frame_markers(markers, headings).reshape(-1, 15)


def _to_world(body: np.ndarray, root: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Body-frame poses (T, 24, 3) -> world: rotate by the heading about y, then move the root to ``root``."""
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    x, y, z = body[..., 0], body[..., 1], body[..., 2]
    return np.stack([x * c + z * s, y, -x * s + z * c], axis=-1) + root[:, None, :]


# ============================================================================ the prior
class PosePrior:
    """A prior database for the local pose models: body-frame poses of its frames, which frames may be used,
    and kd-trees over its numeric features, built once per numeric set and reused for every test motion.

    Parameters
    ----------
    db : MotionDB
        Canonical joints; the test motions must be at its frame rate (the windowed sets' offsets are in frames).
    valid : np.ndarray [shape=(N,)], bool, optional
        Frames the prior may use (default all), e.g. leaving out the test clip or the test actor's clips.
    pca : PCAModel, optional
        For the Fp sets (default :func:`mocapviz.features.numeric.default_pca` of ``db``, fitted when first needed, on
        all frames whatever ``valid`` says: the paper fits one reference PCA for every search).
    engine : str
        KnnIndex engine ("kdtree", "ckdtree" or "brute": the same neighbours).

    Attributes
    ----------
    db, valid, n_valid, engine
    poses : np.ndarray [shape=(N, 72)], float32, cm -- every frame in its body frame, joint-major x y z.

    Raises
    ------
    ValueError
        ``valid`` not a bool mask over the frames, or selecting no frame.
    """

    def __init__(self, db: MotionDB, valid=None, pca: PCAModel | None = None, engine: str = "kdtree",
                 _shared: dict | None = None):  # fmt: skip
        if not isinstance(db, MotionDB):
            raise ParameterError(f"db must be a MotionDB; got {type(db).__name__}")
        self.db, self.engine = db, engine
        n = db.n_frames
        if valid is None:
            valid = np.ones(n, dtype=bool)
        valid = np.asarray(valid)
        if valid.dtype != bool or valid.shape != (n,):
            raise ParameterError(f"valid must be a bool mask of shape ({n},), one entry per frame of {db.path}; got "
                             f"{valid.dtype} {valid.shape}")  # fmt: skip
        if not valid.any():
            raise ParameterError(f"valid excludes every frame of {db.path}: the prior would be empty")
        self.valid, self.n_valid = valid, int(valid.sum())
        self._shared = {"features": {}, "pca": pca} if _shared is None else _shared
        if "poses" not in self._shared:
            self._shared["poses"] = body_frame(db.positions[:]).reshape(n, _POSE_DIMS)
        self._indexes: dict[str, KnnIndex] = {}

    @property
    def poses(self) -> np.ndarray:
        return self._shared["poses"]

    @property
    def pca(self) -> PCAModel:
        """The PCA model of the Fp sets (the given one, else the database's default, fitted on first use)."""
        if self._shared["pca"] is None:
            self._shared["pca"] = default_pca(self.db)
        return self._shared["pca"]

    @property
    def fps(self) -> float | None:
        return self.db.fps

    def __repr__(self) -> str:
        return f"PosePrior({self.db.path}: {self.n_valid:,} of {self.db.n_frames:,} frames)"

    def restrict(self, valid) -> PosePrior:
        """The same database with another valid mask; poses, features and PCA are shared, trees are rebuilt.

        Parameters
        ----------
        valid : np.ndarray [shape=(N,)], bool
            The frames that may be neighbours (e.g. all but the test clip's).

        Returns
        -------
        PosePrior
        """
        return PosePrior(self.db, valid, engine=self.engine, _shared=self._shared)

    def features(self, numeric_set: str) -> np.ndarray:
        """The database's values of a numeric set, computed once (``numeric_of``; Fp sets with :attr:`pca`).

        Parameters
        ----------
        numeric_set : str
            One of :data:`mocapviz.features.NUMERIC_SETS`.

        Returns
        -------
        np.ndarray [shape=(N, d)]
            Every database frame's values, cm.
        """
        if numeric_set not in NUMERIC_SETS:
            raise ParameterError(f"unknown numeric set {numeric_set!r}; known sets: {', '.join(NUMERIC_SETS)}")
        cache = self._shared["features"]
        if numeric_set not in cache:
            pca = self.pca if numeric_set.startswith("Fp") else None
            cache[numeric_set] = np.asarray(numeric_of(self.db, numeric_set, pca=pca))
        return cache[numeric_set]

    def index(self, numeric_set: str = "F15E") -> KnnIndex:
        """The kd-tree over the valid frames' values of a set (built on first use).

        Parameters
        ----------
        numeric_set : str
            One of :data:`mocapviz.features.NUMERIC_SETS` (default F15E).

        Returns
        -------
        KnnIndex
        """
        if numeric_set not in self._indexes:
            self._indexes[numeric_set] = KnnIndex(self.features(numeric_set), engine=self.engine, valid=self.valid)
        return self._indexes[numeric_set]

    def _check_k(self, k) -> int:
        k = count(k, "k")
        if k > self.n_valid:
            raise ParameterError(f"k = {k} is larger than the prior ({self.n_valid:,} valid frames of {self.db.path})")
        return int(k)


# ============================================================================ local linear models
def _local_models(poses: np.ndarray, dist: np.ndarray, frames: np.ndarray, variance: float, bandwidth,
                  mean_only: bool = False):
    """Weighted mean and PCA of each frame's k neighbour poses (the local linear models of Chai & Hodgins 2005).

    Parameters
    ----------
    poses : (N, 72) body-frame poses of the prior; dist, frames : (T, k) neighbour distances and frame numbers.
    variance : share of the local variance kept; bandwidth : kernel width / median distance, or None (equal).
    mean_only : return the weighted means (T, 72) only.

    Returns
    -------
    mean (T, 72), basis (T, 72, R) (columns beyond a frame's rank are zero), inv_var (T, R) (1 / lambda_j; 1
    beyond the rank, where the column is zero), rank (T,) int.
    """
    T, k = dist.shape
    if bandwidth is None:
        w = np.ones((T, k))
    else:
        h = bandwidth * np.median(dist, axis=1, keepdims=True)
        w = np.exp(-0.5 * (dist / np.maximum(h, 1e-9)) ** 2)
        w = np.where(np.isfinite(w) & (w.sum(axis=1, keepdims=True) > 0), w, 1.0)
    w /= w.sum(axis=1, keepdims=True)
    mean = np.empty((T, _POSE_DIMS))
    cov = None if mean_only else np.empty((T, _POSE_DIMS, _POSE_DIMS))
    step = max(1, _CHUNK_BYTES // (8 * k * _POSE_DIMS))  # frames per chunk of gathered neighbour poses
    for a in range(0, T, step):
        Y = poses[frames[a : a + step]].astype(np.float64)  # (t, k, 72)
        mean[a : a + step] = np.einsum("tk,tkd->td", w[a : a + step], Y)
        if mean_only:
            continue
        Z = np.sqrt(w[a : a + step])[..., None] * (Y - mean[a : a + step, None])
        cov[a : a + step] = np.matmul(np.swapaxes(Z, 1, 2), Z)  # weighted covariance (t, 72, 72)
    if mean_only:
        return mean
    if k == 1:
        return mean, np.zeros((T, _POSE_DIMS, 0)), np.ones((T, 0)), np.zeros(T, dtype=np.int64)
    lam, vecs = np.linalg.eigh(cov)  # cheaper than an SVD of the (k, 72) matrices for k >> 72
    lam, vt = np.maximum(lam[:, ::-1], 0.0), np.swapaxes(vecs[..., ::-1], 1, 2)  # descending; rows = axes
    total = lam.sum(axis=1, keepdims=True)
    share = np.cumsum(lam, axis=1) / np.where(total > 0, total, 1.0)
    rank = 1 + (share < variance - 1e-12).sum(axis=1)
    rank = np.minimum(rank, (lam > _TINY_VARIANCE * lam[:, :1]).sum(axis=1))
    rank = np.minimum(np.where(total[:, 0] > 0, rank, 0), k - 1)
    R = int(rank.max())
    keep = np.arange(R)[None] < rank[:, None]  # (T, R)
    basis = np.swapaxes(vt[:, :R], 1, 2) * keep[:, None, :]
    inv_var = np.where(keep, 1.0 / np.where(keep, lam[:, :R], 1.0), 1.0)
    return mean, basis, inv_var, rank


def _solve(mean, basis, inv_var, rank, targets, marker_sigma: float, smooth_sigma: float | None, progress: bool):
    """The per-frame quadratic problem of the module docstring, frame by frame (online).

    mean, basis, inv_var, rank : :func:`_local_models`; targets : (T, 15) body-frame markers.
    Returns (T, 72) body-frame poses.
    """
    T, _, R = basis.shape
    if R == 0:
        return mean.copy()
    keep = np.arange(R)[None] < rank[:, None]  # (T, R), the columns in use
    SU = basis[:, _QUERY_ROWS, :]  # (T, 15, R)
    A = np.einsum("tmi,tmj->tij", SU, SU) / marker_sigma**2
    A[:, np.arange(R), np.arange(R)] += inv_var
    b = np.einsum("tmi,tm->ti", SU, targets - mean[:, _QUERY_ROWS]) / marker_sigma**2
    c_first = np.linalg.solve(A, b[..., None])[..., 0]
    if smooth_sigma is None or not np.isfinite(smooth_sigma) or T == 1:
        return mean + np.einsum("tdr,tr->td", basis, c_first)
    As = A.copy()
    As[:, np.arange(R), np.arange(R)] += keep / smooth_sigma**2  # U^T U = identity on the used columns
    inv = np.linalg.inv(As)
    c0 = np.einsum("tij,tj->ti", inv, b)
    G = np.einsum("tij,tdj->tid", inv, basis) / smooth_sigma**2  # (T, R, 72)
    out = np.empty_like(mean)
    out[0] = mean[0] + basis[0] @ c_first[0]
    frames = range(1, T)
    if progress:
        frames = tqdm(frames, desc="solving frames", unit="frame", leave=False)
    for t in frames:
        p = out[t - 1] if t == 1 else 2.0 * out[t - 1] - out[t - 2]
        c = c0[t] + G[t] @ (p - mean[t])
        out[t] = mean[t] + basis[t] @ c
    return out


def _one_pass(prior: PosePrior, numeric_set: str, queries, targets, k, method, variance, bandwidth, marker_sigma,
              smooth_sigma, progress):  # fmt: skip
    dist, frames = prior.index(numeric_set).query(queries, k)
    if method == "nn":
        return prior.poses[frames[:, 0]].astype(np.float64), frames
    if method == "mean":
        return _local_models(prior.poses, dist, frames, variance, bandwidth, mean_only=True), frames
    mean, basis, inv_var, rank = _local_models(prior.poses, dist, frames, variance, bandwidth)
    return _solve(mean, basis, inv_var, rank, targets, marker_sigma, smooth_sigma, progress), frames


def reconstruct(markers, headings, prior, numeric_set: str = "F15E", k: int = DEFAULT_K, valid=None,
                pca: PCAModel | None = None, method: str = "llm", variance: float = DEFAULT_VARIANCE,
                bandwidth: float | None = DEFAULT_BANDWIDTH, marker_sigma: float = DEFAULT_MARKER_SIGMA,
                smooth_sigma: float | None = DEFAULT_SMOOTH_SIGMA, return_info: bool = False,
                progress: bool = False):  # fmt: skip
    """Full-body poses from six markers with local linear models (Krüger et al. 2010 §5.2; Chai & Hodgins 2005).

    See the module docstring for the method and every choice in it.

    Parameters
    ----------
    markers : np.ndarray [shape=(T, 6, 3)]
        Marker positions, cm, y up, in the order of :data:`MARKERS` (e.g. :func:`synthetic_markers`), at the
        prior database's frame rate.
    headings : np.ndarray [shape=(T,)]
        The body's heading per frame, radians (the root marker cluster's; :func:`mocapviz.motion.skeleton.heading`
        of the test motion in the experiments).
    prior : PosePrior or MotionDB
        The pose prior; a MotionDB is wrapped in a :class:`PosePrior` (with ``valid`` and ``pca``). Pass a
        PosePrior to reuse its kd-trees for several motions.
    numeric_set : str
        Numeric set of the neighbour search. "F15E": one pass, queried with the markers. Any other set of
        :data:`mocapviz.features.NUMERIC_SETS`: pass 1 with F15E, pass 2 with the set computed on the pass-1
        result ([UNCERTAIN], module docstring).
    k : int
        Neighbours per frame (1 <= k <= valid frames of the prior).
    valid : np.ndarray [shape=(N,)], bool, optional
        Frames of the prior database that may be used (only with a MotionDB; a PosePrior carries its own).
    pca : PCAModel, optional
        For the Fp sets (only with a MotionDB).
    method : str
        "llm": the local linear model (the method); baselines: "mean" (the kernel-weighted mean of the k
        neighbours), "nn" (the nearest neighbour's pose). All are placed with the root marker and heading.
    variance : float
        Share in (0, 1] of the local variance the model keeps.
    bandwidth : float or None
        The kernel width (> 0) in units of the median neighbour distance (None: equal weights).
    marker_sigma : float
        The marker term's standard deviation, cm (> 0).
    smooth_sigma : float or None
        The smoothness term's, cm (> 0; None: no smoothness term).
    return_info : bool
        Also return a dict: ``"frames"`` (T, k) the last pass's neighbour frames of the prior database,
        ``"pass1"`` (T, 24, 3) the F15E result when two passes were run.
    progress : bool
        Progress bar over the frames of the sequential solve.

    Returns
    -------
    np.ndarray [shape=(T, 24, 3)], float64
        World coordinates in cm (y up) of the canonical joints; with ``return_info``, (positions, info).

    Raises
    ------
    ValueError
        Markers not (T, 6, 3) or not finite (names the frame and marker), headings not (T,) finite, an unknown
        numeric set or method, k larger than the prior, a valid mask excluding everything, parameters out of
        range, a windowed set on a database with mixed frame rates.
    TypeError
        ``prior`` neither a PosePrior nor a MotionDB.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §5.2 (reconstruction from few markers, kd-tree neighbours), Tables 3-4.
    .. [2] J. Chai, J. K. Hodgins. Performance animation from low-dimensional control signals. ACM TOG 24(3),
       2005 (local linear models of the neighbour poses).

    Examples
    --------
    >>> import numpy as np
    >>> from mocapviz import MotionDB
    >>> from mocapviz.motion.skeleton import heading
    >>> db = MotionDB.sample()
    >>> truth = np.asarray(db.motion(18).positions[:60])  # 0.5 s of a kick, cm
    >>> markers = synthetic_markers(truth, seed=0)  # six markers, +-1 mm of noise
    >>> prior = np.ones(db.n_frames, dtype=bool)
    >>> prior[db.frames(18)] = False  # the test clip is not in the prior
    >>> estimate = reconstruct(markers, heading(truth), db, k=256, valid=prior)
    >>> estimate.shape, bool(reconstruction_errors(truth, estimate)["mean_cm"] < 10)
    ((60, 24, 3), True)
    """
    m, h = _check_markers(markers, headings)
    if isinstance(prior, MotionDB):
        prior = PosePrior(prior, valid=valid, pca=pca)
    elif isinstance(prior, PosePrior):
        if valid is not None or pca is not None:
            raise ParameterError("valid and pca go with a MotionDB prior; a PosePrior carries its own (restrict())")
    else:
        raise ParameterError(f"prior must be a PosePrior or a MotionDB; got {type(prior).__name__}")
    if numeric_set not in NUMERIC_SETS:
        raise ParameterError(f"unknown numeric set {numeric_set!r}; known sets: {', '.join(NUMERIC_SETS)}")
    if method not in METHODS:
        raise ParameterError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    k = prior._check_k(k)
    if not 0 < variance <= 1:
        raise ParameterError(f"variance must be in (0, 1]; got {variance!r}")
    if bandwidth is not None and not (np.isfinite(bandwidth) and bandwidth > 0):
        raise ParameterError(f"bandwidth must be a positive number or None; got {bandwidth!r}")
    if not (np.isfinite(marker_sigma) and marker_sigma > 0):
        raise ParameterError(f"marker_sigma must be a positive number (cm); got {marker_sigma!r}")
    if smooth_sigma is not None and not smooth_sigma > 0:
        raise ParameterError(f"smooth_sigma must be a positive number (cm) or None; got {smooth_sigma!r}")
    query = marker_query(m, h)
    args = (query, k, method, variance, bandwidth, marker_sigma, smooth_sigma, progress)
    body, frames = _one_pass(prior, "F15E", query, *args)
    world = _to_world(body.reshape(-1, len(CANONICAL_JOINTS), 3), m[:, 5], h)
    info = {"frames": frames}
    if numeric_set != "F15E":
        fps = prior.fps
        if fps is None:
            raise ParameterError(f"{prior.db.path} has documents at different frame rates; the two-pass search needs "
                             "one (the test motion's)")  # fmt: skip
        motion = Motion(world.astype(np.float32), fps, CANONICAL_JOINTS, CANONICAL_PARENTS)
        pca_model = prior.pca if numeric_set.startswith("Fp") else None
        q2 = numeric_features(motion, numeric_set, pca=pca_model, progress=False).astype(np.float64)
        body, frames = _one_pass(prior, numeric_set, q2, *args)
        info = {"frames": frames, "pass1": world}
        world = _to_world(body.reshape(-1, len(CANONICAL_JOINTS), 3), m[:, 5], h)
    return (world, info) if return_info else world


# ============================================================================ errors
def reconstruction_errors(truth, estimate) -> dict:
    """Reconstruction errors as in Table 3 ("average (max) reconstruction errors (in cm per joint)").

    Parameters
    ----------
    truth, estimate : np.ndarray [shape=(T, 24, 3)]
        Canonical joints of the same frames, cm.

    Returns
    -------
    dict
        ``mean_cm`` : float, the mean over frames and joints of the Euclidean joint error.
        ``max_cm`` : float, the largest *per-frame mean* joint error over the frames (our reading of the paper's
            "max ... per joint": the worst frame, measured like the mean). [UNCERTAIN]
        ``max_joint_cm`` : float, the largest single joint error.
        ``per_frame_cm`` : np.ndarray (T,), mean joint error of each frame.
        ``per_joint_cm`` : np.ndarray (24,), mean error of each joint over the frames.
        ``bone_cm`` : float, mean over the 23 bones (:data:`BONES`) and the frames of |estimated bone length -
            the actor's|, the actor's lengths taken from the truth's first frame (ASF bones are rigid).
        ``per_bone_cm`` : np.ndarray (23,), the same per bone.

    Raises
    ------
    ValueError
        Shapes not (T, 24, 3) or not equal, or T = 0.
    """
    a, b = np.asarray(truth, dtype=np.float64), np.asarray(estimate, dtype=np.float64)
    if a.ndim != 3 or a.shape[1:] != (len(CANONICAL_JOINTS), 3) or a.shape != b.shape or len(a) == 0:
        raise ParameterError(f"truth and estimate must both have shape (T, 24, 3), T >= 1; got {a.shape} and {b.shape}")
    err = np.linalg.norm(a - b, axis=-1)  # (T, 24)
    per_frame = err.mean(axis=1)
    parent, child = np.array(BONES).T
    actor = np.linalg.norm(a[0, child] - a[0, parent], axis=-1)  # (23,)
    bones = np.abs(np.linalg.norm(b[:, child] - b[:, parent], axis=-1) - actor)  # (T, 23)
    return {
        "mean_cm": float(err.mean()), "max_cm": float(per_frame.max()), "max_joint_cm": float(err.max()),
        "per_frame_cm": per_frame, "per_joint_cm": err.mean(axis=0),
        "bone_cm": float(bones.mean()), "per_bone_cm": bones.mean(axis=0),
    }  # fmt: skip
