"""Numeric pose features for kNN search (Krüger, Tautges, Weber & Zinke 2010, §3.1-3.2).

Every frame becomes a float vector of joint positions in the frame's *body frame* (root at the origin, rotated
about the vertical axis so that the body faces +z: :func:`mocapviz.motion.skeleton.heading` and
:func:`mocapviz.motion.skeleton.body_frame`), in centimetres, y up.

Public API
----------
numeric_features  Motion or MotionDB -> (T, d) float32 values of one numeric set.
numeric_columns   the d column names of a set.
window_offsets    the frame offsets of the windowed sets' samples at a frame rate.
fit_pca           PCAModel of body-frame poses of a reference set (the Fp_n baselines).
PCAModel          mean, principal axes and variances; project / reconstruct; save / load as .npz.
store_numeric     compute feature sets of a MotionDB and store them beside it (``<db>/features/``).
extend_numeric    stored sets of an earlier generation extended with the documents appended since.
load_numeric      a stored set, memory-mapped; MotionDBError when missing or stale.
numeric_of        a MotionDB's set: the stored one when current, else computed (nothing written).
default_pca       a MotionDB's PCA reference: its stored pca.npz, else fitted on it.
NUMERIC_SETS      the set names, in the order below.

Feature sets
------------
"F15E"     §3.2: lwrist, rwrist, lankle, rankle, head (4 end effectors and the head), x y z each: 15 columns.
"F30E"     F15E + lelbow, relbow, lknee, rknee, chest: 30 columns.
"F39E"     F30E + lshoulder, rshoulder, belly: 39 columns.
"F15x3E"   §3.2 "feature sets on windows of frames": F15E of 3 samples spread evenly over a 0.3 s window
"F15x5E"   centred on the frame (5 samples; F30E x 3), every sample in the *centre* frame's body frame, the
"F30x3E"   samples' columns concatenated in time order (45, 75, 90 columns). Offsets are seconds rounded to
           frames at each document's rate (:func:`window_offsets`); a sample beyond a document's end takes
           its first / last frame, so no window reads a neighbouring document.
"Fp8"      §3.1 Fp_n^pca: the first n principal components of all 24 canonical joint positions in the body
"Fp16"     frame (72-d), with a PCA fitted once on a reference set (the paper: the entire HDM05 database)
"Fp25"     and passed as ``pca=``.

Storage
-------
``store_numeric(db)`` writes ``<db.path>/features/numeric-<name>.npy`` ((N, d) float32) and a JSON header
``numeric-<name>.json`` (the DB generation and frame count it was computed for, the window offsets, the PCA
reference), and the PCA model as ``features/pca.npz``. Files are written under temporary names and renamed into
place; the old header is removed before the data is replaced and the new header renamed in last, under a lock,
so a header on disk always describes the data beside it.

Implementation
--------------
A MotionDB is processed in batches of whole documents (about ``_BATCH_FRAMES`` frames each) on threads or as
Dask tasks (:func:`mocapviz.db.batches.map_documents`); within a batch everything is vectorised numpy over all frames
(the heading once per frame, one gather and one rotation per window sample), in float32 like
:func:`mocapviz.motion.skeleton.body_frame`; the PCA in float64.
"""

from __future__ import annotations

import contextlib
import functools
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..checked_map import verified_blocks
from ..db import layout
from ..db.arrays import load_arrays, save_arrays
from ..db.batches import map_documents
from ..db.database import MotionDB
from ..errors import MotionDBError, ParameterError, StaleDataError
from ..motion import Motion
from ..motion.skeleton import CANONICAL_JOINTS, body_frame, heading
from ..parallel import optional_client
from ..store import (
    atomic_write,
    check_format,
    commit,
    fingerprint,
    load_or_build,
    locked,
    stamp,
    temporary_file,
    verify,
)
from ..validation import finite_positions, one_of
from . import NUMERIC_SETS  # the names, with the package: the command line lists them without importing this module

__all__ = [
    "NUMERIC_SETS",
    "PCAModel",
    "default_pca",
    "extend_numeric",
    "fit_pca",
    "load_numeric",
    "numeric_columns",
    "numeric_features",
    "numeric_of",
    "store_numeric",
    "window_offsets",
]

WINDOW_SECONDS = 0.3  # §3.2: "a window of fixed length 0.3 sec"
_F15 = ("lwrist", "rwrist", "lankle", "rankle", "head")
_F30 = _F15 + ("lelbow", "relbow", "lknee", "rknee", "chest")
_F39 = _F30 + ("lshoulder", "rshoulder", "belly")
_POSE_DIMS = 3 * len(CANONICAL_JOINTS)  # 72: the PCA's input, all canonical joints in the body frame
_FRAME_JOINTS = ("root", "lhip", "rhip")  # what the body frame itself is computed from
_BATCH_FRAMES = 1 << 15  # a MotionDB is processed in batches of whole documents of about this many frames
_HEADER_FORMAT = "mocapviz.numeric-features"
_PCA_FORMAT = "mocapviz.PCAModel"
_PCA_VERSION = 2  # of a PCA model file; 2: mocapviz.db.arrays' header and sha256 (a version 1 file is stale)
_HEADER_VERSION = 2  # of a numeric-feature header; 2: it holds the data file's size and sha256
_STALE_HINT = "run `mocapviz features DB` (store_numeric(db)) to compute them"
_PCA_HINT = "fit it again: `mocapviz features DB` for a database's own, fit_pca(reference).save(path) for another"


@dataclass(frozen=True)
class _Set:
    """A numeric feature set: joint positions of ``samples`` window samples, or the first ``pcs`` PCs."""

    joints: tuple[str, ...] = ()
    samples: int = 1
    pcs: int = 0

    @property
    def dims(self) -> int:
        return self.pcs or 3 * len(self.joints) * self.samples


_SETS = {
    "F15E": _Set(_F15), "F30E": _Set(_F30), "F39E": _Set(_F39),
    "F15x3E": _Set(_F15, 3), "F15x5E": _Set(_F15, 5), "F30x3E": _Set(_F30, 3),
    "Fp8": _Set(pcs=8), "Fp16": _Set(pcs=16), "Fp25": _Set(pcs=25),
}  # fmt: skip
if tuple(_SETS) != NUMERIC_SETS:  # pragma: no cover - a set defined here is named in features/__init__.py too
    raise ImportError(f"mocapviz.features.NUMERIC_SETS {NUMERIC_SETS} differs from the sets defined, {tuple(_SETS)}")
_PCA_COMPONENTS = max(s.pcs for s in _SETS.values())  # a default model serves every Fp set


def _spec(numeric_set: str) -> _Set:
    return _SETS[one_of(numeric_set, "numeric set", NUMERIC_SETS)]


# ================================================================================================ geometry


def window_offsets(n_samples: int, fps: float) -> np.ndarray:
    """Frame offsets of the samples of a windowed feature set (§3.2: 3 or 5 samples over 0.3 s).

    The nominal offsets (k / (n - 1) - 1/2) * 0.3 s, k = 0 .. n-1, times ``fps``, rounded to the nearest frame,
    halves towards the centre frame (at 120 Hz the 3-sample offsets are -18, 0, 18; at 30 Hz, 4.5 frames, -4, 0, 4;
    at 24 Hz, 3.6 frames, -4, 0, 4).

    Parameters
    ----------
    n_samples : int
        Samples per window, at least 1 (3 or 5 for the windowed sets).
    fps : float
        Frames per second of the document.

    Returns
    -------
    np.ndarray [shape=(n_samples,)], int64
        Frame offsets from the centre frame, ascending, symmetric about the 0 in the middle.

    Examples
    --------
    >>> window_offsets(3, 120).tolist(), window_offsets(5, 30).tolist()
    ([-18, 0, 18], [-4, -2, 0, 2, 4])
    """
    if n_samples == 1:
        return np.zeros(1, dtype=np.int64)
    nominal = (np.arange(n_samples) / (n_samples - 1) - 0.5) * (WINDOW_SECONDS * fps)
    return (np.sign(nominal) * np.ceil(np.abs(nominal) - 0.5 - 1e-9)).astype(np.int64)


def _joint_features(positions: np.ndarray, bounds: np.ndarray, fps: np.ndarray, spec: _Set) -> np.ndarray:
    """F15E ... F30x3E of a batch of whole documents (§3.2).

    Each window sample's joints are put into the centre frame's body frame with the transform of
    :func:`mocapviz.motion.skeleton.body_frame` (root of the centre frame to the origin, then a rotation by minus its
    :func:`mocapviz.motion.skeleton.heading` about y), with the same float32 operations, so that the centre sample is
    exactly ``body_frame(positions)[:, joints]``. Coordinates are handled as rows [shape=(k, N)] (contiguous
    frames) and interleaved into the output once.

    Parameters
    ----------
    positions : np.ndarray [shape=(N, 24, 3)], float32, canonical joints, cm, y up
    bounds : np.ndarray [shape=(D+1,)], int -- document d is frames bounds[d]:bounds[d+1] of the batch
    fps : np.ndarray [shape=(D,)] -- each document's frame rate (for the window offsets)
    spec : _Set

    Returns
    -------
    np.ndarray [shape=(N, spec.dims)], float32, cm: for each window sample in time order, for each joint of the
    set, its x y z in the centre frame's body frame.
    """
    n, k = positions.shape[0], len(spec.joints)
    theta = heading(positions)
    c, s = np.cos(theta), np.sin(theta)
    joints = np.take(positions, [CANONICAL_JOINTS.index(j) for j in spec.joints], axis=1).T  # [shape=(3, k, N)]
    root = positions[:, CANONICAL_JOINTS.index("root")].T  # [shape=(3, N)]
    lengths = np.diff(bounds)
    first, last = np.repeat(bounds[:-1], lengths), np.repeat(bounds[1:] - 1, lengths)
    offsets = np.stack([window_offsets(spec.samples, f) for f in fps]) if len(fps) else np.zeros((0, spec.samples))
    out = np.empty((n, spec.samples, k, 3), dtype=np.float32)
    for i in range(spec.samples):
        frames = np.clip(np.arange(n) + np.repeat(offsets[:, i], lengths), first, last)  # clamped to the document
        x, y, z = (joints[axis][:, frames] - root[axis] for axis in range(3))  # [shape=(k, N)] each
        out[:, i, :, 0] = (x * c - z * s).T
        out[:, i, :, 1] = y.T
        out[:, i, :, 2] = (x * s + z * c).T
    return out.reshape(n, spec.dims)


# ===================================================================================================== PCA


@dataclass(frozen=True, eq=False)
class PCAModel:
    """Principal components of body-frame poses (§3.1 Fp_n^pca), fitted once on a reference set.

    Made by :func:`fit_pca` or :meth:`load`; the parameters are its attributes.

    Parameters
    ----------
    mean : np.ndarray [shape=(72,)], float64
        Mean body-frame pose (joint-major x y z, canonical order), cm.
    components : np.ndarray [shape=(n, 72)], float64
        Orthonormal principal axes, by decreasing variance; the sign of each makes its largest-magnitude entry
        positive.
    explained_variance : np.ndarray [shape=(n,)], float64
        The variance along each axis, decreasing, cm^2.
    total_variance : float
        The variance of all 72 dimensions (for ratios), cm^2.
    n_frames : int
        Frames the model was fitted on.
    reference : str
        What it was fitted on.
    """

    mean: np.ndarray
    components: np.ndarray
    explained_variance: np.ndarray
    total_variance: float
    n_frames: int
    reference: str

    def __post_init__(self):
        n = np.shape(self.components)[0] if np.ndim(self.components) == 2 else -1
        if (
            np.shape(self.mean) != (_POSE_DIMS,)
            or np.shape(self.components) != (n, _POSE_DIMS)
            or n < 1
            or np.shape(self.explained_variance) != (n,)
        ):
            raise ParameterError(
                f"PCAModel needs mean (72,), components (n, 72), explained_variance (n,); got "
                f"{np.shape(self.mean)}, {np.shape(self.components)}, {np.shape(self.explained_variance)}"
            )
        for name in ("mean", "components", "explained_variance"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.float64))
        object.__setattr__(self, "total_variance", float(self.total_variance))
        object.__setattr__(self, "n_frames", int(self.n_frames))
        object.__setattr__(self, "reference", str(self.reference))

    @property
    def n_components(self) -> int:
        return self.components.shape[0]

    @property
    def explained_variance_ratio(self) -> np.ndarray:
        """Share of the total variance along each axis, [shape=(n,)]."""
        return self.explained_variance / self.total_variance

    def project(self, poses: np.ndarray, n: int | None = None) -> np.ndarray:
        """Coefficients of the first ``n`` (default all) components of body-frame poses.

        Parameters
        ----------
        poses : np.ndarray [shape=(T, 72) or (T, 24, 3)]
            Poses in the body frame (:func:`mocapviz.motion.skeleton.body_frame`), cm.
        n : int, optional
            Components, 1 <= n <= :attr:`n_components` (default all).

        Returns
        -------
        np.ndarray [shape=(T, n)], float64
            Coefficients, cm along the unit principal axes.
        """
        n = self.n_components if n is None else n
        if not 1 <= n <= self.n_components:
            raise ParameterError(f"the PCA model ({self.reference}) has {self.n_components} components; asked for {n}")
        x = np.asarray(poses, dtype=np.float64).reshape(-1, _POSE_DIMS)
        return (self.components[:n] @ (x - self.mean).T).T  # this way round BLAS is about 2x faster for small n

    def reconstruct(self, coefficients: np.ndarray) -> np.ndarray:
        """Body-frame poses from the coefficients of the first n components (the inverse of :meth:`project`).

        Parameters
        ----------
        coefficients : np.ndarray [shape=(T, n)]
            Coefficients of the first n components, cm.

        Returns
        -------
        np.ndarray [shape=(T, 72)], float64
            Body-frame poses, joint-major x y z, cm.
        """
        c = np.asarray(coefficients, dtype=np.float64)
        return self.mean + c @ self.components[: c.shape[1]]

    def save(self, path) -> None:
        """Write the model as an ``.npz`` (no pickled objects), atomically (:func:`mocapviz.db.arrays.save_arrays`).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).
        """
        arrays = {"mean": self.mean, "components": self.components, "explained_variance": self.explained_variance}
        header = {"total_variance": self.total_variance, "n_frames": self.n_frames, "reference": self.reference}
        save_arrays(path, arrays, header, _PCA_FORMAT, _PCA_VERSION)

    @classmethod
    def load(cls, path) -> PCAModel:
        """Read a model written by :meth:`save`.

        Parameters
        ----------
        path : str or os.PathLike
            A file written by :meth:`save`.

        Returns
        -------
        PCAModel

        Raises
        ------
        MotionDBError
            Not such a file (names the file and what is wrong), as for every other saved artefact; one written by
            an older mocapviz is stale (a StaleDataError).
        """
        arrays, header = load_arrays(path, _PCA_FORMAT, _PCA_VERSION, "PCA model", _PCA_HINT)
        try:
            return cls(**arrays, total_variance=header["total_variance"], n_frames=header["n_frames"],
                       reference=header["reference"])  # fmt: skip
        except (KeyError, TypeError, ValueError) as exc:
            raise MotionDBError(f"{path}: malformed PCA model ({exc})") from None


def fit_pca(
    source, n_components: int = 25, reference: str | None = None, progress: bool = True, threads: int | None = None,
    scheduler=None,
) -> PCAModel:
    """Principal components of all 24 canonical joint positions in the body frame (§3.1, Fp_n^pca).

    The paper fits once on a fixed reference database (the entire HDM05) and uses that model for every search.

    Parameters
    ----------
    source : Motion or MotionDB
        The reference frames (a Motion on any skeleton is mapped with ``canonical()``).
    n_components : int
        Principal axes kept, 1 to 72.
    reference : str, optional
        Description stored with the model; default: the clip or database (path, generation, frames).
    progress : bool
        Progress bar, as for :func:`numeric_features`.
    threads : int, optional
        Threads over batches of documents, as for :func:`numeric_features`.
    scheduler : None, "local", str or dask.distributed.Client
        As for :func:`numeric_features` (with Dask, the workers compute the body-frame poses; the moments are
        summed here, in batch order, so the model is the same).

    Returns
    -------
    PCAModel
        ``mean`` [shape=(72,)] and ``components`` [shape=(n_components, 72)] in cm, ``explained_variance`` in cm².

    Raises
    ------
    ValueError
        ``n_components`` out of range, fewer than 2 frames, or a NaN / infinite position (names the frame).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> pca = fit_pca(MotionDB.sample(), n_components=8, progress=False)
    >>> pca.components.shape, pca.n_frames
    ((8, 72), 5543)
    >>> bool(pca.explained_variance_ratio.sum() < 1)
    True
    """
    if not 1 <= n_components <= _POSE_DIMS:
        raise ParameterError(f"n_components must be in 1..{_POSE_DIMS}, got {n_components}")
    _n_frames(source)  # a Motion or a MotionDB

    count, total, outer = 0, np.zeros(_POSE_DIMS), np.zeros((_POSE_DIMS, _POSE_DIMS))
    with optional_client(scheduler if isinstance(source, MotionDB) else None) as client:
        batches = _batches(source, _pca_input, range(len(CANONICAL_JOINTS)), "PCA moments", progress, threads, client)
        with contextlib.closing(batches):
            for _, poses in batches:  # the sums here, in the calling thread: BLAS runs its own threads
                x = poses.astype(np.float64)
                count, total, outer = count + x.shape[0], total + x.sum(axis=0), outer + x.T @ x
    if count < 2:
        raise ParameterError(f"{_describe(source)}: {count} frame(s); a PCA needs at least 2")
    mean = total / count
    cov = (outer - count * np.outer(mean, mean)) / (count - 1)
    variance, axes = np.linalg.eigh(cov)  # ascending
    order = np.argsort(variance)[::-1][:n_components]
    components = axes[:, order].T
    components *= np.sign(components[np.arange(n_components), np.abs(components).argmax(axis=1)])[:, None]
    return PCAModel(
        mean=mean,
        components=components,
        explained_variance=np.maximum(variance[order], 0.0),
        total_variance=float(np.trace(cov)),
        n_frames=count,
        reference=reference or _describe(source),
    )


# ========================================================================================== batch processing


def _pca_input(positions: np.ndarray, bounds: np.ndarray, fps: np.ndarray) -> np.ndarray:
    """The PCA's input (§3.1): all 24 canonical joints of a batch in the body frame
    (:func:`mocapviz.motion.skeleton.body_frame`), flattened to [shape=(N, 72)], float32, cm (x y z per joint)."""
    return body_frame(positions).reshape(-1, _POSE_DIMS)


def _describe(source) -> str:
    if isinstance(source, MotionDB):
        return (
            f"MotionDB {source.path} (generation {source.manifest['generation']}, {len(source)} documents, "
            f"{source.n_frames} frames)"
        )
    return f"{source.source or 'motion'} ({source.n_frames} frames at {source.fps:g} fps)"


def _batches(source, work: Callable, joints, desc: str, progress: bool, threads: int | None, client=None) -> Iterator:
    """(frames, work(positions, bounds, fps)) for the batches of whole documents of ``source``, in frame order.

    ``source`` is a Motion (one batch, in the calling thread) or a MotionDB (the callers check which with
    :func:`_n_frames`): batches of whole documents of about ``_BATCH_FRAMES`` frames on ``threads`` threads, or as
    Dask tasks of ``client`` (:func:`mocapviz.db.batches.map_documents`; ``work`` then a module-level function or a
    partial of one). ``frames`` is the slice of the source's frames a result covers. Every batch is checked for
    non-finite positions of ``joints`` (canonical indices) first; the first bad batch in frame order raises.
    """
    if isinstance(source, MotionDB):
        yield from map_documents(source, work, _BATCH_FRAMES, joints, threads, client, desc, progress,
                                 name="mocapviz-numeric")  # fmt: skip
        return
    motion = source.canonical()
    name = source.source or "motion"
    finite_positions(motion.positions, lambda t: f"{name}, frame {t}", list(joints), CANONICAL_JOINTS)
    yield slice(0, motion.n_frames), work(motion.positions, np.array([0, motion.n_frames]), np.array([motion.fps]))


def _joint_work(spec: _Set, positions: np.ndarray, bounds: np.ndarray, fps: np.ndarray) -> np.ndarray:
    """:func:`_joint_features` of a batch (module level, so that Dask workers can import it)."""
    return _joint_features(positions, bounds, fps, spec)


def _fill(source, numeric_set: str, pca: PCAModel | None, out: np.ndarray, progress: bool, threads: int | None,
          client=None) -> None:  # fmt: skip
    """Write the values of numeric set ``numeric_set`` of every frame of ``source`` into ``out`` [shape=(T, d)]
    (batches on threads, or as Dask tasks of ``client``)."""
    spec = _spec(numeric_set)
    desc = f"numeric features {numeric_set}"
    if spec.pcs:
        if pca is None:
            raise ParameterError(
                f"feature set {numeric_set} needs a PCA model: pass pca=fit_pca(reference) or "
                f"pca=PCAModel.load(path) (the paper's reference is the whole HDM05 database)"
            )
        if pca.n_components < spec.pcs:
            raise ParameterError(
                f"feature set {numeric_set} needs {spec.pcs} components; the PCA model ({pca.reference}) "
                f"has {pca.n_components}"
            )
        batches = _batches(source, _pca_input, range(len(CANONICAL_JOINTS)), desc, progress, threads, client)
        with contextlib.closing(batches):
            for frames, poses in batches:
                out[frames] = pca.project(poses, spec.pcs)  # here, in the calling thread: BLAS runs its own threads
        return

    joints = [CANONICAL_JOINTS.index(j) for j in _FRAME_JOINTS + spec.joints]
    batches = _batches(source, functools.partial(_joint_work, spec), joints, desc, progress, threads, client)
    with contextlib.closing(batches):
        for frames, values in batches:
            out[frames] = values


def _n_frames(source) -> int:
    if isinstance(source, (Motion, MotionDB)):
        return source.n_frames
    raise ParameterError(f"numeric features need a Motion or a MotionDB, got {type(source).__name__}")


def numeric_features(
    source, numeric_set: str, pca: PCAModel | None = None, progress: bool = True, threads: int | None = None,
    scheduler=None,
) -> np.ndarray:
    """Numeric feature values of every frame (Krüger et al. 2010 §3.2; PCA baselines §3.1).

    Parameters
    ----------
    source : Motion or MotionDB
        A Motion on any skeleton (mapped with ``motion.canonical()``), or a MotionDB: all its frames in its frame
        (document) order; windows are clamped to each document, never reading a neighbouring one.
    numeric_set : str
        One of :data:`NUMERIC_SETS`: "F15E", "F30E", "F39E" (positions in the frame's body frame), "F15x3E",
        "F15x5E", "F30x3E" (3 or 5 samples of a 0.3 s window, in the centre frame's body frame), "Fp8", "Fp16",
        "Fp25" (principal components; need ``pca``). Column names: :func:`numeric_columns`.
    pca : PCAModel, optional
        The reference PCA (:func:`fit_pca`, :meth:`PCAModel.load`), for the Fp sets; unused by the others.
    progress : bool
        Progress bar over the documents of a MotionDB with more than 50 documents.
    threads : int, optional
        Threads over batches of documents of a MotionDB (default :func:`mocapviz.parallel.default_threads`: the
        cores this process may use, at most 8).
    scheduler : None, "local", str or dask.distributed.Client
        Compute the batches of a MotionDB as Dask tasks (:func:`mocapviz.parallel.dask_client`: ``"local"`` starts
        a local cluster for this call, an address connects to a scheduler whose workers see the database's path,
        a Client is used as it is). None (default): threads in this process. The values are the same either way.

    Returns
    -------
    np.ndarray [shape=(T, d)], float32
        One row per frame, cm (Fp: cm along unit principal axes); columns :func:`numeric_columns`.

    Raises
    ------
    ValueError
        An unknown set (lists the known ones); a PCA set without a model, or with too few components; a NaN or
        infinite position of a joint the set uses (names the clip or document and the frame).
    mocapviz.SkeletonMappingError
        A Motion whose joints cannot be mapped onto the canonical skeleton.
    TypeError
        ``source`` is neither a Motion nor a MotionDB.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.2 (the feature sets F15E ... F30x3E) and §3.1 (the PCA sets Fp_n).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> x = numeric_features(db.motion(7)[0:120], "F15E")  # hands, feet and head in the body frame, cm
    >>> x.shape, x.dtype, numeric_columns("F15E")[:3]
    ((120, 15), dtype('float32'), ['lwrist.x', 'lwrist.y', 'lwrist.z'])
    >>> numeric_features(db, "F15x3E", progress=False).shape  # every frame of the database, windows of 0.3 s
    (5543, 45)
    >>> pca = fit_pca(db, n_components=8, progress=False)
    >>> numeric_features(db.motion(7), "Fp8", pca=pca).shape
    (129, 8)
    """
    spec = _spec(numeric_set)
    out = np.empty((_n_frames(source), spec.dims), dtype=np.float32)
    with optional_client(scheduler if isinstance(source, MotionDB) else None) as client:
        _fill(source, numeric_set, pca, out, progress, threads, client)
    return out


def numeric_columns(numeric_set: str) -> list[str]:
    """Column names of a numeric feature set.

    ``"lwrist.x"`` ... for the frame sets; ``"lwrist.x@-0.150s"`` ... (nominal window offset) for the windowed
    ones, samples in time order; ``"pc1"`` ... for the PCA sets.

    Parameters
    ----------
    numeric_set : str
        One of :data:`NUMERIC_SETS`.

    Returns
    -------
    list of str
        d names, in column order.

    Examples
    --------
    >>> numeric_columns("F15x3E")[:2], len(numeric_columns("F15x3E")), numeric_columns("Fp8")[0]
    (['lwrist.x@-0.150s', 'lwrist.y@-0.150s'], 45, 'pc1')
    """
    spec = _spec(numeric_set)
    if spec.pcs:
        return [f"pc{k + 1}" for k in range(spec.pcs)]
    cols = [f"{j}.{axis}" for j in spec.joints for axis in "xyz"]
    if spec.samples == 1:
        return cols
    nominal = (np.arange(spec.samples) / (spec.samples - 1) - 0.5) * WINDOW_SECONDS
    return [f"{c}@{t:+.3f}s" for t in nominal for c in cols]


# ================================================================================================== storage


def store_numeric(
    db: MotionDB, numeric_sets=None, pca: PCAModel | None = None, progress: bool = True, threads: int | None = None,
    scheduler=None,
) -> dict[str, np.ndarray]:
    """Compute numeric feature sets of a MotionDB and store them in ``<db.path>/features/``.

    Each set goes to ``numeric-<name>.npy`` ((N, d) float32, written to a temporary file and renamed) with a JSON
    header ``numeric-<name>.json``: the database generation and frame count it describes (so that
    :func:`load_numeric` notices a changed database), columns, window offsets per frame rate, and for the PCA sets
    the model's reference and checksum. The PCA model is stored as ``features/pca.npz``.

    Parameters
    ----------
    db : MotionDB
        The database; its folder must be writable.
    numeric_sets : str or list of str, optional
        Sets to compute (default: all of :data:`NUMERIC_SETS`).
    pca : PCAModel, optional
        The reference PCA for the Fp sets. Default: fitted on this database (the header says so; a ``pca.npz``
        fitted on this same generation is reused); the paper's reference is the entire HDM05 database, fitted
        once with :func:`fit_pca`.
    progress : bool
        Progress bar, as for :func:`numeric_features`.
    threads : int, optional
        Threads over batches of documents, as for :func:`numeric_features`.
    scheduler : None, "local", str or dask.distributed.Client
        Compute the batches of documents as Dask tasks (one client for all the sets; see :func:`numeric_features`).
        The values are gathered here and written in frame order; the files are only renamed into place once a set
        is complete, so a failed or cancelled task leaves that set's previous files.

    Returns
    -------
    dict
        Set name -> np.ndarray [shape=(N, d)], float32 memory map of the stored file (:func:`load_numeric`), cm.

    Raises
    ------
    ValueError
        Unknown set names (before anything is computed); bad positions as in :func:`numeric_features`. Sets stored
        before the failing one stay stored; the failing one keeps its previous files.
    """
    numeric_sets = (list(NUMERIC_SETS) if numeric_sets is None else [numeric_sets] if isinstance(numeric_sets, str)
                    else list(numeric_sets))  # fmt: skip
    specs = {name: _spec(name) for name in numeric_sets}
    with optional_client(scheduler) as client:
        return _store_numeric(db, specs, pca, progress, threads, client)


def _store_numeric(db: MotionDB, specs: dict, pca: PCAModel | None, progress: bool, threads: int | None,
                   client) -> dict[str, np.ndarray]:
    """:func:`store_numeric` of the sets ``specs`` (name -> _Set), batches on threads or on ``client``."""
    names = list(specs)
    folder, pca_file = layout.features_folder(db.path), layout.pca_file(db.path)
    folder.mkdir(exist_ok=True)
    pca_header = None
    if any(s.pcs for s in specs.values()):
        fitted_here = pca is None
        if fitted_here:
            pca = _own_pca(db, progress, threads, client)
        with locked(folder):
            pca.save(pca_file)
            pca_header = {
                "file": pca_file.name,
                "sha256": fingerprint(pca_file)["sha256"],
                "reference": pca.reference,
                "n_components": pca.n_components,
                "n_frames": pca.n_frames,
                "fitted_on_this_database": fitted_here,
            }
    for name, spec in specs.items():
        _write_set(db, name, _header(db, name, pca_header if spec.pcs else None),
                   lambda out, name=name: _fill(db, name, pca, out, progress, threads, client))
    return {name: load_numeric(db, name) for name in names}


def _header(db: MotionDB, numeric_set: str, pca_header: dict | None) -> dict:
    """The header of a numeric set of ``db`` as stored (without its data file's fingerprint): the database's
    generation, frames and documents it describes (their :meth:`~mocapviz.db.database.MotionDB.prefix_digest`, so
    that :func:`extend_numeric` can tell an appended database), columns, window offsets per frame rate, the PCA."""
    spec = _spec(numeric_set)
    fps_values = sorted({float(f) for f in db.documents["fps"]})
    return {
        **stamp(_HEADER_FORMAT, _HEADER_VERSION),
        "set": numeric_set,
        "dims": spec.dims,
        "dtype": "float32",
        "generation": db.manifest["generation"],
        "n_frames": db.n_frames,
        "n_documents": len(db),
        "documents": db.prefix_digest(len(db)),
        "columns": numeric_columns(numeric_set),
        "window": None
        if spec.samples == 1
        else {
            "seconds": WINDOW_SECONDS,
            "samples": spec.samples,
            "offsets_frames": {f"{f:g}": window_offsets(spec.samples, f).tolist() for f in fps_values},
        },
        "pca": pca_header,
        "paper": "Krüger, Tautges, Weber, Zinke 2010, §3.2" if not spec.pcs else "Krüger et al. 2010, §3.1",
    }


def _write_set(db: MotionDB, numeric_set: str, header: dict, fill: Callable[[np.ndarray], None]) -> None:
    """Store a numeric set: ``fill(out)`` writes the (N, d) values into a new temporary file, which then replaces
    the data file and its header together, under the features' lock (a reader's memory map of the old file stays
    valid)."""
    data_path, header_path = layout.numeric_data(db.path, numeric_set), layout.numeric_header(db.path, numeric_set)
    with temporary_file(data_path) as tmp:
        out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.float32, shape=(db.n_frames, header["dims"]))
        fill(out)
        out.flush()
        del out
        header["data"] = fingerprint(tmp)
        with locked(header_path.parent):  # readers pair a header with its data under the shared lock
            header_path.unlink(missing_ok=True)  # no header = missing: never an old header on new data
            commit(tmp, data_path)
            atomic_write(header_path, json.dumps(header, indent=1).encode())


def extend_numeric(db: MotionDB, numeric_sets=None, progress: bool = False, threads: int | None = None
                   ) -> dict[str, np.ndarray]:  # fmt: skip
    """Stored numeric sets of an earlier generation of a MotionDB brought up to date incrementally: only the
    documents appended since they were stored are computed (a frame's values read its own document only), their
    rows appended to the stored ones, the header's generation advanced. Equal to :func:`store_numeric` of the whole
    database; an Fp set keeps the stored PCA model (``pca.npz``, the reference it was computed with, even when it
    was fitted on an earlier generation of this database: ``mocapviz features DB`` fits it again).

    Parameters
    ----------
    db : MotionDB
        The database, grown by an ingest since the sets were stored; its folder writable.
    numeric_sets : str or list of str, optional
        Default: every stored set (:func:`mocapviz.db.layout.numeric_sets`).
    progress : bool
        Progress bar over the new documents.
    threads : int, optional
        Threads over batches of the new documents.

    Returns
    -------
    dict
        Set name -> np.ndarray [shape=(N, d)], float32 memory map of the stored file (:func:`load_numeric`).

    Raises
    ------
    mocapviz.MotionDBError
        A set not stored, or stored for other documents than the first of this database (another database, one
        stored before headers recorded their documents, or its PCA model replaced: a
        :class:`~mocapviz.errors.StaleDataError`); store it whole (:func:`store_numeric`).
    """
    from ..db.shards import shard_view

    names = (layout.numeric_sets(db.path) if numeric_sets is None else [numeric_sets] if isinstance(numeric_sets, str)
             else list(numeric_sets))  # fmt: skip
    for name in names:
        header, old = _stored_set(db, name)
        added = db.added_since(header.get("n_documents"), header.get("n_frames"), header.get("documents"))
        pca = None
        if _spec(name).pcs:
            pca = PCAModel.load(layout.pca_file(db.path))
            if _file_sha256(layout.pca_file(db.path)) != (header.get("pca") or {}).get("sha256"):
                raise StaleDataError(f"{db.path}: numeric feature set {name}: pca.npz replaced since it was stored")
        view = shard_view(db, added, labels=False) if len(added) else None

        def fill(out, old=old, view=view, name=name, pca=pca):
            n_old = old.shape[0]
            for s in range(0, n_old, 1 << 18):
                out[s : min(s + (1 << 18), n_old)] = old[s : min(s + (1 << 18), n_old)]
            if view is not None:
                _fill(view, name, pca, out[n_old:], progress, threads)

        _write_set(db, name, _header(db, name, header.get("pca")), fill)
    return {name: load_numeric(db, name) for name in names}


def _stored_set(db: MotionDB, numeric_set: str) -> tuple[dict, np.ndarray]:
    """The stored header and data (memory-mapped, its size checked) of a numeric set, whatever database state they
    describe; MotionDBError when not stored or unreadable."""
    data_path, header_path = layout.numeric_data(db.path, numeric_set), layout.numeric_header(db.path, numeric_set)
    if not header_path.is_file():
        raise MotionDBError(f"{db.path}: numeric feature set {numeric_set} is not stored; {_STALE_HINT}")
    with locked(header_path.parent, shared=True):
        try:
            header = check_format(json.loads(header_path.read_text()), _HEADER_FORMAT, _HEADER_VERSION, header_path)
            verify(data_path, header.get("data"), rebuild=_STALE_HINT)
            data = np.load(data_path, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise MotionDBError(f"{header_path.parent}: numeric feature set {numeric_set} unreadable ({exc}); "
                                f"{_STALE_HINT}") from None  # fmt: skip
    if data.shape != (header.get("n_frames"), _spec(numeric_set).dims):
        raise StaleDataError(f"{data_path}: holds {data.shape}, its header says {header.get('n_frames')} frames")
    return header, data


def _own_pca(db: MotionDB, progress: bool, threads: int | None, client=None) -> PCAModel:
    """The default PCA reference of a database: fitted on the database itself, or the stored ``pca.npz`` when it
    was fitted on this very generation (so that Fp sets stored one at a time share one model)."""
    reference = f"this database: {_describe(db)}"
    return load_or_build(
        lambda: _stored_pca(db, reference),
        lambda: fit_pca(db, _PCA_COMPONENTS, reference=reference, progress=progress, threads=threads, scheduler=client),
    )


def load_numeric(db: MotionDB, numeric_set: str, full_check: bool = False) -> np.ndarray:
    """A numeric feature set stored by :func:`store_numeric`, memory-mapped read-only.

    The data file's size is checked against the one recorded in its header and its contents against the xxh3 of
    each block (the first time the file is read in this process, :mod:`mocapviz.checked_map`); with ``full_check``
    its sha256 too (``mocapviz check DB``).

    Parameters
    ----------
    db : MotionDB
        The database the set was stored with.
    numeric_set : str
        One of :data:`NUMERIC_SETS`.
    full_check : bool
        Also check the data file's sha256 (reads it whole).

    Returns
    -------
    np.ndarray [shape=(N, d)], float32
        A read-only memory map, cm; row i is frame i of the database.

    Raises
    ------
    ValueError
        An unknown set numeric_set.
    mocapviz.MotionDBError
        The set is not stored, or stale (a :class:`~mocapviz.errors.StaleDataError`): computed for another
        generation or frame count of the database, or with a PCA model other than the stored ``pca.npz``; or its
        files are unreadable or damaged (size, sha256). The message says to run ``mocapviz features DB``.
    """
    spec = _spec(numeric_set)
    data_path, header_path = layout.numeric_data(db.path, numeric_set), layout.numeric_header(db.path, numeric_set)
    missing = MotionDBError(f"{db.path}: numeric feature set {numeric_set} is not stored; {_STALE_HINT}")
    if not header_path.parent.is_dir():
        raise missing
    with locked(header_path.parent, shared=True):  # (a writer swaps header and data under the exclusive lock)
        if not header_path.is_file():
            raise missing
        try:
            header = json.loads(header_path.read_text())
            data = np.load(data_path, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise MotionDBError(
                f"{header_path.parent}: numeric feature set {numeric_set} unreadable ({exc}); {_STALE_HINT}"
            ) from None
        check_format(header, _HEADER_FORMAT, _HEADER_VERSION, header_path, _STALE_HINT)
        verify(data_path, header.get("data"), full=full_check, rebuild=_STALE_HINT)
        verified_blocks(data_path, header.get("data"), rebuild=_STALE_HINT)  # (once per process: xxh3, fast)
        stale = None
        if (header.get("generation"), header.get("n_frames")) != (db.manifest["generation"], db.n_frames):
            stale = (
                f"it was computed for generation {header.get('generation')} ({header.get('n_frames')} frames); "
                f"the database is at generation {db.manifest['generation']} ({db.n_frames} frames)"
            )
        elif data.shape != (db.n_frames, spec.dims) or data.dtype != np.float32:
            stale = f"{data_path.name} holds {data.shape} {data.dtype}, expected ({db.n_frames}, {spec.dims}) float32"
        elif spec.pcs and _file_sha256(layout.pca_file(db.path)) != (header.get("pca") or {}).get("sha256"):
            stale = "pca.npz has been replaced since it was computed"
    if stale:
        raise StaleDataError(f"{db.path}: numeric feature set {numeric_set} is stale: {stale}; {_STALE_HINT}")
    return data


def add_block_checksums(db: MotionDB, numeric_set: str) -> bool:
    """Record the per-block xxh3 of a stored numeric set written before they were kept, after checking its data file
    against the sha256 of its header (``mocapviz check DB`` does this); from then on its blocks are verified when
    first read (:func:`load_numeric`).

    Parameters
    ----------
    db : MotionDB
        The database the set is stored with.
    numeric_set : str
        One of :data:`NUMERIC_SETS`, stored.

    Returns
    -------
    bool
        Whether the header was rewritten (False: it had them already).

    Raises
    ------
    mocapviz.MotionDBError
        The set is not stored or its data differ from its recorded sha256 (nothing written).
    """
    data_path, header_path = layout.numeric_data(db.path, numeric_set), layout.numeric_header(db.path, numeric_set)
    load_numeric(db, numeric_set)  # stored, current and readable
    with locked(header_path.parent):
        header = json.loads(header_path.read_text())
        if "xxh3" in header["data"]:
            return False
        now = fingerprint(data_path)
        if (now["size"], now["sha256"]) != (header["data"].get("size"), header["data"].get("sha256")):
            raise MotionDBError(f"{data_path}: its sha256 differs from the one recorded when it was written: the file "
                                f"is damaged; {_STALE_HINT}")  # fmt: skip
        header["data"] = now
        atomic_write(header_path, json.dumps(header, indent=1).encode())
    return True


def numeric_of(db: MotionDB, numeric_set: str, pca: PCAModel | None = None, progress: bool = False) -> np.ndarray:
    """A MotionDB's numeric feature set: the stored one when it is current; else, when it was stored for the
    database before documents were appended, extended with theirs and stored (:func:`extend_numeric`); else
    computed now (nothing written).

    Parameters
    ----------
    db : MotionDB
        The database.
    numeric_set : str
        One of :data:`NUMERIC_SETS`.
    pca : PCAModel, optional
        For an Fp set: computed with this model. Default: the stored set when current, else computed with
        :func:`default_pca`.
    progress : bool
        Progress bar when computed.

    Returns
    -------
    np.ndarray [shape=(N, d)], float32
        Values of every database frame, cm (a read-only memory map when stored).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> numeric_of(MotionDB.sample(), "F30E").shape
    (5543, 30)
    """
    if _spec(numeric_set).pcs and pca is not None:
        return numeric_features(db, numeric_set, pca=pca, progress=progress)

    def extended_or_computed() -> np.ndarray:
        try:
            return extend_numeric(db, numeric_set, progress=progress)[numeric_set]
        except (MotionDBError, OSError):  # not stored for a first part of this database, or a read-only folder
            pca = default_pca(db, progress) if _spec(numeric_set).pcs else None
            return numeric_features(db, numeric_set, pca=pca, progress=progress)

    return load_or_build(lambda: load_numeric(db, numeric_set), extended_or_computed)


def default_pca(db: MotionDB, progress: bool = False) -> PCAModel:
    """The PCA reference of a MotionDB when none is given: its stored ``features/pca.npz``, else fitted on it.

    Parameters
    ----------
    db : MotionDB
        The database.
    progress : bool
        Progress bar when fitted.

    Returns
    -------
    PCAModel
        Nothing is written when it is fitted here.
    """
    return load_or_build(lambda: _stored_pca(db), lambda: fit_pca(db, progress=progress))


def _stored_pca(db: MotionDB, reference: str | None = None) -> PCAModel:
    """The stored ``features/pca.npz`` of a MotionDB (of this ``reference`` with the default components when
    given), or MotionDBError."""
    path = layout.pca_file(db.path)
    if not path.is_file():
        raise MotionDBError(f"{db.path}: no stored PCA model")
    stored = PCAModel.load(path)
    if reference is not None and (stored.reference, stored.n_components) != (reference, _PCA_COMPONENTS):
        raise MotionDBError(f"{path}: fitted on {stored.reference}, not {reference}")
    return stored


def _file_sha256(path: Path) -> str | None:
    try:
        return fingerprint(path)["sha256"]
    except OSError:
        return None