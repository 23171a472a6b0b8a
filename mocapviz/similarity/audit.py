"""Audit of a collection: every pair of stretches that are near-copies of each other (the same take twice, its
left/right mirror, another frame rate, a trimmed or re-timed copy, a retargeted one), found by an index-based
self-join and verified by DTW, grouped into clusters of copies; and the leakage of a test split into a training
split.

How (docs/audit.md):

1. **Features**: a body-frame numeric set (Krüger et al. 2010 §3.2, F15E by default) of every frame, after the
   joints are smoothed over 0.1 s and retargeted to the collection's median bone lengths (a copy on another
   actor's bones stays near), resampled to one common rate (the first collection's typical rate); and the same of
   each document's left/right mirror (:func:`mocapviz.motion.skeleton.mirror`).
2. **Candidates** (the self-join): every 5th frame (a sixth of the shortest stretch; 1 s at 30 Hz), and its
   mirror, asks a kd-tree of the other collection's frames (itself for a self-audit) for its 64 nearest frames
   within twice the threshold (of another document: a pair is kept whichever of its two documents asked). Frame
   pairs of two documents in the same or neighbouring cells of half the shortest stretch a side form a candidate;
   a copy makes a line of them, at any time scaling.
3. **Verification**: DTW (:func:`mocapviz.match.time_warping.dtw`) of the candidate's box, widened by the shortest
   stretch on every side (a long one in tiles of 20 shortest stretches a side), against the other side's half
   frames (a copy re-timed by a factor that is no whole number has poses between the original's frames); then the
   runs of its warping path whose local cost, averaged over the shortest stretch, stays under the threshold: each
   run at least the shortest stretch long in both documents, with a time scaling (measured where the stretch
   moves) inside the band, is a pair. Its cost is the path's mean local cost (feature units, cm). A box one side of
   which is over the band's times the other's is also aligned by subsequence DTW (the shorter side whole, free start
   and end in the longer: in a take of a repeated movement the box's own path aligns a copy to the wrong
   repetitions).
4. **The threshold**, when not given, is learned from the collection itself (:func:`learn_threshold`): copies of
   its own stretches made with the transforms a copy goes through (marker noise of 1 cm, a time scaling up to
   ±20 %, another actor's bone lengths on the same kind of rig) and their mean DTW cost to the original: the
   threshold is their 99th percentile (docs/audit.md: what it separates, measured).

The pairs are one row each (:data:`PAIR_COLUMNS`), the frames of each side in its own document (half-open, at the
document's own rate), built with :func:`mocapviz.db.hits.hit_table` for either side.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy.ndimage import uniform_filter1d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..db.hits import hit_table
from ..errors import ParameterError
from ..features.numeric import numeric_columns, numeric_features
from ..match.time_warping import dtw, subsequence_costs
from ..motion.skeleton import bone_lengths, mirror, retarget
from ..parallel import progress_bar

__all__ = ["PAIR_COLUMNS", "Collection", "audit_features", "audit_pairs", "clusters_of", "keep_one", "leakage",
           "learn_threshold", "read_split", "warping_path"]

PAIR_COLUMNS = ["doc_a", "name_a", "start_a", "end_a", "doc_b", "name_b", "start_b", "end_b", "seconds", "cost",
                "mirrored", "scale", "cluster"]  # fmt: skip
_NOISE_CM = 1.0  # the copies' marker noise when learning the threshold (each joint, 3D standard deviation)
_STRETCH = 0.2  # and their time scaling, up to ±20 %
_SMOOTH_S = 0.1  # the joints' moving average before the features, seconds
_HALF_STEPS = ((1, 1, 1.0), (1, 0, 1.0), (0, 1, 1.0), (1, 2, 1.0))  # DTW steps (a, b's half frames, weight): the
# basic steps and one frame of each, so that a copy at the same pace steps over b's midpoints instead of visiting them
_TILE = 20  # candidates are aligned in tiles of at most this many shortest stretches a side
_MOVING_CM = 0.5  # a frame whose features move more than this (cm per frame at the common rate) is moving


class Collection:
    """One collection's audit features: every document retargeted to one body (the first collection's median bone
    lengths), its body-frame numeric set at the common ``rate``, and the same of its left/right mirror image.

    Attributes
    ----------
    db : MotionDB
    x, mirrored : np.ndarray [shape=(M, d)], float32
        Features at the common rate (cm, on the common body); ``mirrored`` of the documents' mirror images.
    starts : np.ndarray [shape=(n_docs + 1,)], int64
        Each document's first row in ``x`` (and the end).
    body : np.ndarray [shape=(24,)]
        The common body's bone lengths (cm).
    """

    def __init__(self, db, numeric_set: str, rate: float, body=None, progress: bool = False):
        self.db, self.rate, self.numeric_set = db, float(rate), numeric_set
        docs = db.documents
        self.body = _median_body(db) if body is None else np.asarray(body, dtype=np.float64)
        xs, ms = [], []
        for doc, fps in progress_bar(list(zip(docs["doc_id"], docs["fps"])), desc="audit: features", unit="doc",
                                     disable=not progress):  # fmt: skip
            motion = db.motion(int(doc))
            xs.append(_resampled(audit_features(motion, numeric_set, self.body), float(fps), self.rate))
            ms.append(_resampled(audit_features(mirror(motion), numeric_set, self.body), float(fps), self.rate))
        dims = len(numeric_columns(numeric_set))
        self.x = np.concatenate(xs).astype(np.float32) if xs else np.zeros((0, dims), np.float32)
        self.mirrored = np.concatenate(ms).astype(np.float32) if ms else self.x.copy()
        self.starts = np.concatenate([[0], np.cumsum([len(x) for x in xs])]).astype(np.int64)
        self.doc_ids = docs["doc_id"].to_numpy(dtype=np.int64)
        self.fps = docs["fps"].to_numpy(dtype=np.float64)
        self.n_frames = docs["n_frames"].to_numpy(dtype=np.int64)

    def document_of(self, rows: np.ndarray) -> np.ndarray:
        """The position (in ``db.documents``) of the document of each row of ``x``."""
        return np.searchsorted(self.starts, rows, side="right") - 1

    def own_frames(self, pos: int, a: int, b: int) -> tuple[int, int]:
        """Rows [a, b) of document ``pos`` at the common rate as its own frames, half-open."""
        first = int(self.starts[pos])
        ratio = self.fps[pos] / self.rate
        start = int(np.floor((a - first) * ratio + 1e-9))
        end = int(np.ceil((b - first) * ratio - 1e-9))
        n = int(self.n_frames[pos])
        return min(max(start, 0), n - 1), min(max(end, start + 1), n)


def audit_features(motion, numeric_set: str, body) -> np.ndarray:
    """The features the audit compares of one clip: its joints smoothed over 0.1 s (a moving average, so that
    marker noise of a copy moves the body frame less), retargeted to the bone lengths ``body``
    (:func:`~mocapviz.motion.skeleton.retarget`), then the body-frame numeric set.

    Parameters
    ----------
    motion : Motion
        A clip (any skeleton; mapped to the canonical joints).
    numeric_set : str
        One of :data:`mocapviz.features.POSITION_SETS`.
    body : array_like [shape=(24,)]
        Bone lengths, cm.

    Returns
    -------
    np.ndarray [shape=(T, d)], float32
        cm, at the clip's own rate.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.motion.skeleton import bone_lengths
    >>> db = MotionDB.sample()
    >>> audit_features(db.motion(7), "F15E", bone_lengths(db.motion(0).positions)).shape
    (129, 15)
    """
    motion = motion.canonical()
    width = max(1, round(_SMOOTH_S * motion.fps))
    smooth = replace(motion, positions=uniform_filter1d(motion.positions, width, axis=0, mode="nearest"))
    return numeric_features(retarget(smooth, body), numeric_set, progress=False)


def warping_path(a, b, *, mirrored: bool = False, numeric_set: str = "F15E") -> np.ndarray:
    """The DTW warping path of two stretches of a pair, as the audit aligns them: both clips' audit features
    (:func:`audit_features` on ``a``'s bone lengths; ``a``'s left/right mirror image when ``mirrored``, as a mirrored
    pair's side a), ``b``'s resampled to ``a``'s rate, aligned by :func:`mocapviz.match.time_warping.dtw`, and each
    step's row of ``b`` turned back into ``b``'s own frame. Played step by step, the two stretches show the same
    moment of the motion side by side.

    Parameters
    ----------
    a, b : Motion
        The two stretches (any rates, any skeletons).
    mirrored : bool
        The pair is mirrored: ``b`` is a copy of ``a``'s mirror image.
    numeric_set : str
        One of :data:`mocapviz.features.POSITION_SETS`.

    Returns
    -------
    np.ndarray [shape=(L, 2)], int64
        Each step's frame of ``a`` and of ``b`` (from each clip's first frame), from (0, 0) to (a.n_frames - 1,
        b.n_frames - 1), both columns non-decreasing, no step repeated.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> walk = MotionDB.sample().motion(7)[10:70]  # 60 frames at 120 Hz
    >>> path = warping_path(walk, walk.resample(240.0))  # the same stretch at twice the rate: 119 frames
    >>> path[:3].tolist(), path[-1].tolist(), len(path)
    ([[0, 0], [1, 2], [2, 4]], [59, 118], 60)
    """
    if a.n_frames == 0 or b.n_frames == 0:
        raise ParameterError(f"an empty stretch has no warping path ({a.n_frames} and {b.n_frames} frames)")
    body = bone_lengths(a.canonical().positions[:: max(1, a.n_frames // 8)])
    xa = audit_features(mirror(a) if mirrored else a, numeric_set, body)
    xb = _resampled(audit_features(b, numeric_set, body), b.fps, a.fps)
    _, path = dtw(xa, xb)
    frames_b = np.minimum(np.round(path[:, 1] * b.fps / a.fps), b.n_frames - 1).astype(np.int64)
    steps = np.column_stack([path[:, 0].astype(np.int64), frames_b])
    keep = np.concatenate([[True], (np.diff(steps, axis=0) != 0).any(axis=1)])
    steps = steps[keep]
    if (steps[-1] != [a.n_frames - 1, b.n_frames - 1]).any():  # b's last rows at a's rate may stop short of its end
        steps = np.vstack([steps, [a.n_frames - 1, b.n_frames - 1]])
    return steps


def _document_bones(db) -> np.ndarray:
    """Each document's bone lengths (n_docs, 24), cm, from up to 8 of its frames."""
    starts, counts = db.documents["start"].to_numpy(), db.documents["n_frames"].to_numpy()
    return np.array([bone_lengths(db.positions[int(s):int(s) + int(n)][:: max(1, int(n) // 8)])
                     for s, n in zip(starts, counts)]).reshape(-1, 24)  # fmt: skip


def _median_body(db) -> np.ndarray:
    """The median bone lengths of a database's documents (cm)."""
    return np.median(_document_bones(db), axis=0) if len(db) else np.zeros(24)


def _resampled(values: np.ndarray, fps: float, rate: float) -> np.ndarray:
    """Rows at ``fps`` linearly resampled to ``rate`` (the same rows when equal)."""
    if abs(fps - rate) < 1e-6 or len(values) < 2:
        return np.asarray(values, dtype=np.float32)
    t = np.arange(0.0, (len(values) - 1) / fps + 1e-9, 1.0 / rate) * fps
    lo = np.minimum(t.astype(np.int64), len(values) - 2)
    w = (t - lo)[:, None]
    return ((1 - w) * values[lo] + w * values[lo + 1]).astype(np.float32)


def _half_frames(x: np.ndarray) -> np.ndarray:
    """Rows with the midpoint of each two neighbours between them (2 T - 1 rows): a copy re-timed by a factor
    that is no whole number has poses between the original's frames, and at 30 Hz a fast movement moves far in one
    frame; aligned to half frames, such a copy costs what its noise costs."""
    out = np.empty((max(2 * len(x) - 1, 0), x.shape[1]), dtype=x.dtype)
    out[0::2] = x
    out[1::2] = (x[:-1] + x[1:]) / 2
    return out


def _mean_cost(a: np.ndarray, b: np.ndarray) -> float:
    """DTW of a and b's half frames (:func:`_half_frames`, :data:`_HALF_STEPS`): the mean local cost along the
    optimal path, cm."""
    total, path = dtw(a, _half_frames(b), steps=_HALF_STEPS)
    return total / max(len(path), 1)


def learn_threshold(collection: Collection, min_frames: int, n_copies: int = 200, seed: int = 0) -> dict:
    """The default threshold of the audit, learned from the collection: ``n_copies`` stretches of its documents
    (2 × the shortest stretch, drawn at random with ``seed``), each copied with marker noise (1 cm), a time
    scaling of up to ±20 %, and the bone lengths of another document on a rig of the same bones; the threshold is
    the 99th percentile of the copies' mean DTW cost to their originals.

    Returns
    -------
    dict
        ``threshold`` (cm), ``copies_p99`` (cm), ``n_copies``, ``how`` (the rule, in words), ``costs`` (each
        copy's, cm) and ``sources`` (each copy's document, its position in ``db.documents``).
    """
    db, rng = collection.db, np.random.default_rng(seed)
    docs = db.documents
    long = np.flatnonzero(docs["n_frames"].to_numpy() * collection.rate / docs["fps"].to_numpy() >= 2 * min_frames)
    if len(long) == 0:
        raise ParameterError(f"no document is {2 * min_frames} frames long at {collection.rate:g} Hz: the audit needs "
                             "stretches at least twice the shortest one to learn its threshold; give threshold=")
    costs, sources = [], []
    bones = _document_bones(db) > 1e-3
    numeric_set = collection.numeric_set
    for _ in range(n_copies):
        pos = int(rng.choice(long))
        sources.append(pos)
        motion = db.motion(int(docs["doc_id"].iloc[pos]))
        n = round(2 * min_frames * motion.fps / collection.rate)
        a = int(rng.integers(0, motion.n_frames - n + 1))
        piece = motion[a:a + n]
        alike = np.flatnonzero((bones == bones[pos]).all(axis=1))  # another actor on a rig of the same bones
        other = db.motion(int(docs["doc_id"].iloc[int(rng.choice(alike))]))
        copy = retarget(piece, bone_lengths(other.positions[:: max(1, other.n_frames // 8)]))
        noise = rng.normal(0.0, _NOISE_CM / np.sqrt(3), copy.positions.shape).astype(np.float32)
        copy = replace(copy, positions=copy.positions + noise)
        stretch = 1.0 + rng.uniform(-_STRETCH, _STRETCH)
        x, y = (audit_features(m, numeric_set, collection.body) for m in (piece, copy))
        costs.append(_mean_cost(_resampled(x, motion.fps, collection.rate),
                                _resampled(y, motion.fps * stretch, collection.rate)))  # fmt: skip
    p99 = float(np.percentile(costs, 99))
    return {"threshold": p99, "copies_p99": p99, "n_copies": n_copies, "costs": np.array(costs),
            "sources": np.array(sources),
            "how": f"the 99th percentile of the mean DTW cost of {n_copies} copies of the collection's own stretches "
                   "(1 cm marker noise, time scaled up to ±20 %, another actor's bone lengths) to their "
                   "originals"}  # fmt: skip


def audit_pairs(first: Collection, second: Collection | None, *, min_frames: int, threshold: float,
                max_scale: float = 1.25, mirrored: bool = True, k: int = 64, progress: bool = False) -> pd.DataFrame:
    """Every maximal pair of near-copy stretches between ``first`` and ``second`` (within ``first`` when None).

    Parameters
    ----------
    first, second : Collection
        At the same rate and body length (``second`` made with ``first``'s).
    min_frames : int
        The shortest stretch, frames at the common rate.
    threshold : float
        The largest mean DTW cost of a pair (cm).
    max_scale : float
        Time scalings within [1 / max_scale, max_scale] (one side's frames over the other's).
    mirrored : bool
        Also pairs of a stretch and another's left/right mirror image.
    k : int
        Nearest frames per query frame.
    progress : bool
        A progress bar over the candidates verified.

    Returns
    -------
    pandas.DataFrame
        One row per pair: :data:`PAIR_COLUMNS` (frames at each document's own rate), best first.
    """
    other = first if second is None else second
    candidates = _candidates(first, other, second is None, min_frames, threshold, mirrored, k)
    rows = []
    for doc_a, doc_b, flip, i0, i1, j0, j1 in progress_bar(candidates, desc="audit: verifying", unit="candidate",
                                                          disable=not progress):  # fmt: skip
        rows.extend(_verified(first, other, doc_a, doc_b, flip, i0, i1, j0, j1, min_frames, threshold, max_scale))
    return _table(first, other, _deduplicated(rows, min_frames // 2))


def _candidates(first, other, self_join, min_frames, threshold, mirrored, k) -> list[tuple]:
    """Boxes (doc_a, doc_b, mirrored, i0, i1, j0, j1) of rows where frames of a (or its mirror) have near
    frames of b: the self-join by the kd-tree of ``other``'s frames."""
    if len(first.x) == 0 or len(other.x) == 0:
        return []
    step = max(1, min_frames // 6)
    rows = np.arange(0, len(first.x), step)
    tree = cKDTree(other.x)
    found = []
    for flip, values in ((False, first.x), (True, first.mirrored))[: 1 + bool(mirrored)]:
        dist, near = tree.query(values[rows], k=min(k, len(other.x)), distance_upper_bound=2 * threshold, workers=-1)
        dist, near = dist.reshape(len(rows), -1), near.reshape(len(rows), -1)
        q, col = np.nonzero(np.isfinite(dist))
        a, b = rows[q], near[q, col]
        da, db_ = first.document_of(a), other.document_of(b)
        if self_join:  # each pair of documents once, the lower position first, whichever asked (a document's own
            keep = da != db_  # frames may crowd out its copy's for one of the two; a mirror pair is symmetric)
            swap = da > db_
            da, db_, a, b = np.where(swap, db_, da), np.where(swap, da, db_), np.where(swap, b, a), np.where(swap, a, b)
        else:
            keep = np.ones(len(a), bool)
        found.append(np.column_stack([da[keep], db_[keep], np.full(keep.sum(), int(flip)), a[keep], b[keep]]))
    points = np.unique(np.concatenate(found), axis=0) if found else np.zeros((0, 5), np.int64)
    if len(points) == 0:
        return []
    group = np.unique(points[:, :3], axis=0, return_inverse=True)[1].reshape(-1)
    label = _near_groups(group, points[:, 3], points[:, 4], max(2 * step, min_frames // 2))
    tile = _TILE * min_frames  # a long candidate is aligned in tiles of at most this many frames a side (DTW's
    # memory is their product); the pairs of neighbouring tiles that continue each other are joined (_merged)
    boxes = pd.DataFrame({"da": points[:, 0], "db": points[:, 1], "flip": points[:, 2], "a": points[:, 3],
                          "b": points[:, 4], "label": label})
    for side in ("a", "b"):  # each candidate's span cut into equal tiles of about `tile` frames, from its own start
        first = boxes.groupby("label")[side].transform("min")
        span = boxes.groupby("label")[side].transform("max") - first + 1
        boxes["t" + side] = ((boxes[side] - first) * np.maximum(1, np.round(span / tile)) // span).astype(np.int64)
    boxes = boxes.groupby(["label", "ta", "tb"]).agg(
        da=("da", "first"), db=("db", "first"), flip=("flip", "first"), i0=("a", "min"), i1=("a", "max"),
        j0=("b", "min"), j1=("b", "max"), n=("a", "size"))  # fmt: skip
    least = max(2, min_frames // (2 * step))
    boxes = boxes[(boxes["n"] >= least) & (boxes["i1"] - boxes["i0"] + step >= min_frames // 2)
                  & (boxes["j1"] - boxes["j0"] + 1 >= min_frames // 2)]  # fmt: skip
    return [(int(r.da), int(r.db), bool(r.flip), int(r.i0), int(r.i1) + step, int(r.j0), int(r.j1) + 1)
            for r in boxes.itertuples()]  # fmt: skip


def _near_groups(group: np.ndarray, a: np.ndarray, b: np.ndarray, gap: int) -> np.ndarray:
    """The connected components of points (a, b) of each group, a point joined to those of its group in the same or
    a neighbouring cell of ``gap`` x ``gap`` frames (memory of the order of the points: cells, not pairs of points).

    Returns
    -------
    np.ndarray [shape=(n,)], int64
        Each point's component.
    """
    ca, cb = a // gap, b // gap
    width = int(max(ca.max(), cb.max())) + 3  # cell coordinates of one group, shifted by 1, fit in width
    keys = (group.astype(np.int64) * width + ca + 1) * width + cb + 1
    cells, cell_of = np.unique(keys, return_inverse=True)
    sources, targets = [], []
    for da, db in ((0, 1), (1, -1), (1, 0), (1, 1)):  # each neighbour once (the other half are the reverse)
        at = np.searchsorted(cells, cells + da * width + db)
        hit = (at < len(cells)) & (cells[np.minimum(at, len(cells) - 1)] == cells + da * width + db)
        sources.append(np.flatnonzero(hit))
        targets.append(at[hit])
    sources, targets = np.concatenate(sources), np.concatenate(targets)
    graph = coo_matrix((np.ones(len(sources)), (sources, targets)), shape=(len(cells), len(cells)))
    return connected_components(graph, directed=False)[1][cell_of.reshape(-1)]


def _verified(first, other, pa, pb, flip, i0, i1, j0, j1, min_frames, threshold, max_scale) -> list[dict]:
    """The pairs inside one candidate box: DTW of the widened box, then the runs of its path whose local cost,
    averaged over ``min_frames`` steps, stays at most ``threshold``. When one side of the box is over ``max_scale``
    times the other's, the shorter side is also aligned as a whole within the longer one (subsequence DTW: free
    start and end there), since the box's own path must then stall along the longer side, and a copy inside a
    longer take of a repeated movement (a wave, a walk) is aligned by it to the wrong repetition."""
    pad = min_frames  # a fast stretch may have no near frame in the sparse index: its box may end early
    a0, a1 = max(i0 - pad, int(first.starts[pa])), min(i1 + pad, int(first.starts[pa + 1]))
    b0, b1 = max(j0 - pad, int(other.starts[pb])), min(j1 + pad, int(other.starts[pb + 1]))
    if min(a1 - a0, b1 - b0) < min_frames:
        return []
    xa = (first.mirrored if flip else first.x)[a0:a1]
    xb = other.x[b0:b1]
    half_b = _half_frames(xb)
    _, path = dtw(xa, half_b, steps=_HALF_STEPS)  # b's index counts half frames
    found = _runs(xa, half_b, path, min_frames, threshold, max_scale)
    if max(len(xa), len(xb)) > max_scale * min(len(xa), len(xb)):
        swap = len(xb) < len(xa)
        short, long_ = (xb, xa) if swap else (xa, xb)
        half = _half_frames(long_)
        accumulated, begins = subsequence_costs(short, half, steps=_HALF_STEPS)
        end = int(np.argmin(accumulated))
        if np.isfinite(accumulated[end]):
            begin = int(begins[end])
            _, sub = dtw(short, half[begin:end + 1], steps=_HALF_STEPS)
            runs = _runs(short, half, sub + np.array([0, begin]), min_frames, threshold, max_scale)
            found += [(h0, h1, f0, f1, cost, 1.0 / scale) for f0, f1, h0, h1, cost, scale in runs] if swap else runs
    return [{"pa": pa, "pb": pb, "a0": a0 + f0, "a1": a0 + f1, "b0": b0 + h0, "b1": b0 + h1, "cost": cost,
             "mirrored": flip, "scale": scale} for f0, f1, h0, h1, cost, scale in found]  # fmt: skip


def _runs(xf: np.ndarray, xh: np.ndarray, path: np.ndarray, min_frames: int, threshold: float,
          max_scale: float) -> list[tuple]:
    """The pairs along one warping path of full frames ``xf`` and half frames ``xh`` (:func:`_half_frames`):
    (f0, f1, h0, h1, cost, scale), frames [f0, f1) of ``xf`` and [h0, h1) of the half frames' own rows, the mean
    local cost and the time scaling (h's frames over f's)."""
    local = np.linalg.norm(xf[path[:, 0]] - xh[path[:, 1]], axis=1)
    w = min(min_frames, len(local))
    smooth = np.convolve(local, np.ones(w) / w, mode="same")
    ok = np.concatenate([[False], smooth <= threshold, [False]])
    edges = np.flatnonzero(np.diff(ok.astype(np.int8)))
    speed = np.linalg.norm(np.diff(xf, axis=0), axis=1)
    moving = np.concatenate([speed, speed[-1:]]) > _MOVING_CM
    out = []
    for s, e in _joined(list(zip(edges[::2], edges[1::2])), local, min_frames, threshold):
        s, e = _trimmed(path, local, s, e, threshold)
        ia, ib = path[s:e, 0], path[s:e, 1] / 2.0
        first_h, last_h = int(np.floor(ib[0])), int(np.ceil(ib[-1]))
        nf, nh = int(ia[-1] - ia[0] + 1), last_h - first_h + 1
        cost = float(local[s:e].mean())
        scale = _time_scale(ia, ib, moving, min_frames)
        if min(nf, nh) < min_frames or not (1 / max_scale <= scale <= max_scale) or cost > threshold:
            continue
        out.append((int(ia[0]), int(ia[-1]) + 1, first_h, last_h + 1, cost, scale))
    return out


def _time_scale(ia: np.ndarray, ib: np.ndarray, moving: np.ndarray, min_frames: int) -> float:
    """b's frames over a's along a run of the path (``ib`` in frames, halves included), between its first and last steps where ``a`` moves (a standing
    pose at either end can align at any pace: it does not tell the copy's time scale); the whole run when fewer than
    half the shortest stretch move."""
    steps = np.flatnonzero(moving[ia])
    if len(steps) >= max(2, min_frames // 2) and ia[steps[-1]] > ia[steps[0]]:
        ia, ib = ia[steps[0]:steps[-1] + 1], ib[steps[0]:steps[-1] + 1]
    return float(ib[-1] - ib[0] + 1) / float(ia[-1] - ia[0] + 1)


def _joined(runs: list, local: np.ndarray, gap: int, threshold: float) -> list:
    """Runs [s, e) of path steps, each joined with the next when fewer than ``gap`` steps lie between them and the
    joined run's mean local cost stays at most ``threshold`` (one copy whose noise crossed the threshold briefly)."""
    out: list = []
    for s, e in runs:
        if out and s - out[-1][1] < gap and local[out[-1][0]:e].mean() <= threshold:
            out[-1] = (out[-1][0], e)
        else:
            out.append((s, e))
    return out


def _trimmed(path: np.ndarray, local: np.ndarray, s: int, e: int, threshold: float) -> tuple[int, int]:
    """A run [s, e) of path steps without its ends' steps of a local cost over ``threshold`` and without the
    stalls at its ends (steps where one side stands still: the rest of a longer document, not the copy), then
    grown by the diagonal steps next to it of a local cost at most ``threshold`` (the moving average that found the
    run is raised near a stall)."""
    while e - s > 1 and local[s] > threshold:
        s += 1
    while e - s > 1 and local[e - 1] > threshold:
        e -= 1
    while e - s > 1 and (path[s + 1] == path[s]).any():
        s += 1
    while e - s > 1 and (path[e - 1] == path[e - 2]).any():
        e -= 1
    while s > 0 and local[s - 1] <= threshold and (path[s] != path[s - 1]).all():
        s -= 1
    while e < len(path) and local[e] <= threshold and (path[e] != path[e - 1]).all():
        e += 1
    return s, e


def _deduplicated(rows: list[dict], gap: int) -> list[dict]:
    """The maximal pairs, best first: a pair that overlaps a longer one of the same two documents by more than half
    of the shorter on both sides is dropped (a part of the same copy, or the copy found twice, e.g. mirrored and
    not for a symmetric motion); then pairs that continue each other across fewer than ``gap`` frames joined."""
    kept: list[dict] = []
    longest = sorted(rows, key=lambda r: (-min(r["a1"] - r["a0"], r["b1"] - r["b0"]), r["cost"], r["pa"], r["pb"],
                                          r["a0"], r["b0"]))  # fmt: skip
    for r in longest:
        if not any(k["pa"] == r["pa"] and k["pb"] == r["pb"] and _overlap(k["a0"], k["a1"], r["a0"], r["a1"]) > 0.5
                   and _overlap(k["b0"], k["b1"], r["b0"], r["b1"]) > 0.5 for k in kept):  # fmt: skip
            kept.append(r)
    return sorted(_merged(kept, gap), key=lambda r: (r["cost"], r["pa"], r["pb"], r["a0"], r["b0"]))


def _merged(rows: list[dict], gap: int) -> list[dict]:
    """Pairs of the same two documents (and mirroring) that continue each other (the next starts less than ``gap``
    frames after the one before ends, in both documents) as one: found in two candidates, one copy is one pair (its cost the mean over
    both, weighted by their frames)."""
    out: list[dict] = []
    for r in sorted(rows, key=lambda r: (r["pa"], r["pb"], r["mirrored"], r["a0"], r["b0"])):
        last = out[-1] if out else None
        if (last is not None and (last["pa"], last["pb"], last["mirrored"]) == (r["pa"], r["pb"], r["mirrored"])
                and r["a0"] <= last["a1"] + gap and r["b0"] <= last["b1"] + gap and r["a1"] > last["a1"]
                and r["b1"] > last["b1"] and r["b0"] >= last["b0"]):  # fmt: skip
            n_last, n_r = last["a1"] - last["a0"], r["a1"] - r["a0"]
            last.update(a1=r["a1"], b1=r["b1"], cost=(last["cost"] * n_last + r["cost"] * n_r) / (n_last + n_r))
            last["scale"] = (last["b1"] - last["b0"]) / (last["a1"] - last["a0"])
        else:
            out.append(dict(r))
    return out


def _overlap(a0, a1, b0, b1) -> float:
    return max(0, min(a1, b1) - max(a0, b0)) / max(1, min(a1 - a0, b1 - b0))


def _table(first, other, rows: list[dict]) -> pd.DataFrame:
    """The pair table (:data:`PAIR_COLUMNS`), each side's frames in its own document via hit_table."""
    if not rows:
        return pd.DataFrame({c: pd.Series(dtype=t) for c, t in zip(PAIR_COLUMNS, [
            "int64", "object", "int64", "int64", "int64", "object", "int64", "int64", "float64", "float64", "bool",
            "float64", "int64"])})  # fmt: skip
    sides = []
    for coll, p, f0, f1 in ((first, "pa", "a0", "a1"), (other, "pb", "b0", "b1")):
        spans = [coll.own_frames(r[p], r[f0], r[f1]) for r in rows]
        hits = hit_table(coll.db, coll.doc_ids[[r[p] for r in rows]], [s for s, _ in spans], [e for _, e in spans])
        sides.append(hits)
    a, b = sides
    table = pd.DataFrame({
        "doc_a": a["doc_id"].to_numpy(), "name_a": a["name"].to_numpy(), "start_a": a["start"].to_numpy(),
        "end_a": a["end"].to_numpy(), "doc_b": b["doc_id"].to_numpy(), "name_b": b["name"].to_numpy(),
        "start_b": b["start"].to_numpy(), "end_b": b["end"].to_numpy(),
        "seconds": np.minimum(a["end_s"] - a["start_s"], b["end_s"] - b["start_s"]).to_numpy(),
        "cost": [r["cost"] for r in rows], "mirrored": [bool(r["mirrored"]) for r in rows],
        "scale": [r["scale"] for r in rows]})  # fmt: skip
    table["cluster"] = clusters_of(table, same=other is first)
    return table


def clusters_of(pairs: pd.DataFrame, same: bool = True) -> np.ndarray:
    """The cluster of copies of each pair: the connected components of the documents the pairs join (of one
    collection when ``same``, else a's and b's documents as separate nodes), numbered 0, 1, ... by their best pair.

    Returns
    -------
    np.ndarray [shape=(len(pairs),)], int64
    """
    if pairs.empty:
        return np.zeros(0, dtype=np.int64)
    a = pairs["doc_a"].to_numpy(dtype=np.int64)
    b = pairs["doc_b"].to_numpy(dtype=np.int64) + (0 if same else int(a.max()) + 1)
    nodes, inverse = np.unique(np.concatenate([a, b]), return_inverse=True)
    graph = coo_matrix((np.ones(len(a)), (inverse[: len(a)], inverse[len(a):])), shape=(len(nodes), len(nodes)))
    _, label = connected_components(graph, directed=False)
    per_pair = label[inverse[: len(a)]]
    order = {c: i for i, c in enumerate(pd.unique(per_pair[np.argsort(pairs["cost"].to_numpy(), kind="stable")]))}
    return np.array([order[c] for c in per_pair], dtype=np.int64)


def keep_one(pairs: pd.DataFrame, documents: pd.DataFrame) -> pd.DataFrame:
    """The documents left when each cluster of copies keeps one (its longest document, the lowest id on a tie):
    a clean training set. Documents in no pair are all kept.

    Returns
    -------
    pandas.DataFrame
        Rows of ``documents`` (doc_id, name, ...), in their order.
    """
    dropped: set[int] = set()
    frames = documents.set_index("doc_id")["n_frames"]
    for _, group in pairs.groupby("cluster"):
        docs = sorted(set(group["doc_a"]) | set(group["doc_b"]), key=lambda d: (-int(frames[d]), d))
        dropped.update(docs[1:])
    return documents[~documents["doc_id"].isin(dropped)]


def read_split(path, documents: pd.DataFrame) -> pd.Series:
    """A split file: CSV of ``doc`` (a doc id or a name) and ``split`` (train, val or test; another name is
    kept as it is). Returns the split of each doc id named (a Series indexed by doc_id).

    Raises
    ------
    ParameterError
        No such file, a missing column, or a document not in the database (named, with its line).
    """
    try:
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read the split file ({exc})") from None
    missing = {"doc", "split"} - set(table.columns)
    if missing:
        raise ParameterError(f"{path}: a split file needs the columns doc and split; {', '.join(sorted(missing))} "
                             f"missing (it has {', '.join(table.columns)})")  # fmt: skip
    by_name = dict(zip(documents["name"].astype(str), documents["doc_id"]))
    ids = set(documents["doc_id"].tolist())
    out = {}
    for line, (doc, split) in enumerate(zip(table["doc"], table["split"]), start=2):
        doc = doc.strip()
        if doc.isdigit() and int(doc) in ids:
            out[int(doc)] = split.strip()
        elif doc in by_name:
            out[int(by_name[doc])] = split.strip()
        else:
            raise ParameterError(f"{path}, line {line}: no document {doc!r} in the database")
    return pd.Series(out, name="split", dtype=object).rename_axis("doc_id")


def leakage(pairs: pd.DataFrame, split: pd.Series, test: str = "test", train: str = "train") -> pd.DataFrame:
    """The pairs that leak: a stretch of a ``test`` document with a near-copy in a ``train`` document, the test
    side first (columns as :data:`PAIR_COLUMNS`, with ``split_a`` and ``split_b``)."""
    sa = pairs["doc_a"].map(split)
    sb = pairs["doc_b"].map(split)
    forward = pairs[(sa == test) & (sb == train)]
    swapped = pairs[(sb == test) & (sa == train)].rename(columns={
        "doc_a": "doc_b", "name_a": "name_b", "start_a": "start_b", "end_a": "end_b",
        "doc_b": "doc_a", "name_b": "name_a", "start_b": "start_a", "end_b": "end_a"})  # fmt: skip
    swapped = swapped.assign(scale=1.0 / swapped["scale"])
    out = pd.concat([forward, swapped[pairs.columns]]).sort_values(["cost", "doc_a", "start_a"], kind="stable")
    return out.assign(split_a=test, split_b=train).reset_index(drop=True)
