"""Marker-derived joints against the AMC of the same take (issue 27): how close :mod:`mocapviz.motion.markers`
comes to the skeleton CMU fitted to the same markers.

marker_pairs      the C3D takes of a folder that have an AMC of the same take in a CMU folder (by its labels.tsv).
frame_lag         the frame offset between two clips of one take: the lag that best correlates their feet heights.
aligned_takes     two clips of one take cut to the frames they share.
pair_agreement    per relational 2005 feature, the share of aligned frames where the C3D-derived and the
                  AMC-derived feature agree; and F15E (Krüger et al. 2010) distance in the body frame.
pair_search       the DTW similarity search with the C3D take as query over a database of the AMC takes and the
                  C3D take itself (excluded from the answers): the rank of the AMC of the same take.
marker_comparison all three for every pair: one row per pair.
floor_alignment   the rotation about the vertical and the shift that carry one take's world onto the other's.
real_marker_clip  reconstruction test data from a take's C3D-derived clip (markers) and its AMC (truth).
pair_reconstruction  Krüger et al. 2010 §5.2 from REAL markers: the six joints the paper's sparse markers stand for,
                  estimated from the C3D take's marker clusters, rebuilt into the full body with a prior that leaves
                  the take out, against the AMC of the same take; beside the paper's simulated markers.
marker_reconstruction  pair_reconstruction of every pair, with the CMU takes (30 Hz) as the prior.

Reproduce (the shared archives ``c3d-markers`` and ``cmu-asfamc``)::

    python -c "from mocapviz.experiments.markers import marker_comparison; print(marker_comparison().T)"
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from ..db import MotionDB
from ..features import numeric_features, relational_features
from ..io import datasets, load
from ..motion import Motion
from ..motion.skeleton import CANONICAL_JOINTS
from ..similarity.search import SimilaritySearch

__all__ = ["aligned_takes", "floor_alignment", "frame_lag", "marker_comparison", "marker_pairs",
           "marker_reconstruction", "pair_agreement", "pair_reconstruction", "pair_search", "real_marker_clip"]

_FEET = [CANONICAL_JOINTS.index("lankle"), CANONICAL_JOINTS.index("rankle")]
SEARCH_FPS = 30.0  # the database of pair_search: the kNN rate of Krüger et al. 2010


def marker_pairs(c3d_dir=None, cmu_dir=None) -> pd.DataFrame:
    """The C3D files ``cmu_<subject>_<trial>.c3d`` whose take has an AMC in the CMU folder's ``labels.tsv``.

    Parameters
    ----------
    c3d_dir, cmu_dir : path, optional
        The unpacked archives; default :func:`mocapviz.io.datasets.fetch` of ``c3d-markers`` and ``cmu-asfamc``.

    Returns
    -------
    pandas.DataFrame
        One row per pair: ``take`` (``135_02``), ``c3d``, ``amc`` (paths).
    """
    c3d_dir = Path(c3d_dir or datasets.fetch("c3d-markers"))
    cmu_dir = Path(cmu_dir or datasets.fetch("cmu-asfamc"))
    table = pd.read_csv(cmu_dir / "labels.tsv", sep="\t", dtype=str).dropna(subset=["cmu_subject", "cmu_trial"])
    amcs = {f"{int(s)}_{t}": cmu_dir / f for f, s, t in zip(table["file"], table["cmu_subject"], table["cmu_trial"])}
    rows = []
    for c3d in sorted(c3d_dir.glob("cmu_*.c3d")):
        subject, trial = c3d.stem.split("_")[1:3]
        take = f"{int(subject)}_{trial}"
        if take in amcs:
            rows.append({"take": take, "c3d": c3d, "amc": amcs[take]})
    return pd.DataFrame(rows, columns=["take", "c3d", "amc"])


def frame_lag(a: Motion, b: Motion, max_lag_s: float = 2.0) -> int:
    """The lag L (frames) such that frame t of ``a`` shows what frame t - L of ``b`` shows.

    Both clips canonical at one frame rate; the lag maximises the correlation (Pearson) of the summed heights of
    the two ankles, over the frames the clips share, within ±``max_lag_s``.

    Parameters
    ----------
    a, b : Motion
        Canonical clips of one take, at the same frame rate.
    max_lag_s : float
        The largest lag tried, seconds.

    Returns
    -------
    int
        The lag; 0 when the clips start together.

    Examples
    --------
    >>> m = MotionDB.sample().motion(7)  # 129 frames at 120 fps
    >>> frame_lag(m[10:], m), frame_lag(m, m[10:], max_lag_s=0.5)
    (-10, 10)
    """
    x, y = a.positions[:, _FEET, 1].sum(axis=1), b.positions[:, _FEET, 1].sum(axis=1)
    best, lag = -np.inf, 0
    for k in range(-int(max_lag_s * a.fps), int(max_lag_s * a.fps) + 1):
        xs, ys = x[max(k, 0):], y[max(-k, 0):]
        n = min(len(xs), len(ys))
        if n < 2:
            continue
        r = np.corrcoef(xs[:n], ys[:n])[0, 1]
        if r > best:
            best, lag = r, k
    return lag


def _aligned(c3d: Path, amc: Path) -> tuple[Motion, Motion, int]:
    """The two takes canonical, at the C3D's rate, cut to the frames they share; and the lag."""
    return aligned_takes(load(c3d).canonical(), load(amc).canonical())


def aligned_takes(a: Motion, b: Motion) -> tuple[Motion, Motion, int]:
    """Two canonical clips of one take (e.g. from its C3D and its AMC) cut to the frames they share, ``b`` at
    ``a``'s rate; and the lag (:func:`frame_lag`).

    Parameters
    ----------
    a, b : Motion
        Canonical clips of one take.

    Returns
    -------
    a, b : Motion
        The shared frames, as many of each.
    lag : int
        Frames (``a``'s rate).

    Examples
    --------
    >>> m = MotionDB.sample().motion(7)
    >>> x, y, lag = aligned_takes(m[5:], m)
    >>> lag, x.n_frames, bool((x.positions == y.positions).all())
    (-5, 124, True)
    """
    if b.fps != a.fps:
        b = b.resample(a.fps)
    lag = frame_lag(a, b)
    n = min(a.n_frames - max(lag, 0), b.n_frames - max(-lag, 0))
    return a[max(lag, 0) : max(lag, 0) + n], b[max(-lag, 0) : max(-lag, 0) + n], lag


def pair_agreement(c3d, amc) -> pd.DataFrame:
    """Relational 2005 features and F15E of the C3D take against the AMC of the same take, frames aligned.

    Parameters
    ----------
    c3d, amc : path
        The two files of one take (the AMC's ASF found beside it).

    Returns
    -------
    pandas.DataFrame
        One row per 2005 feature: ``feature``, ``agreement`` (share of frames where both agree, 0-1).
        ``attrs``: ``lag`` (frames, :func:`frame_lag`), ``frames`` (aligned), ``f15e_cm`` (mean over frames and
        the five F15E points of the distance between the two, body frame, cm).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. ACM TOG
       24(3), 2005 (the relational features).
    .. [2] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.2 (F15E).
    """
    a, b, lag = _aligned(Path(c3d), Path(amc))
    fa, names = relational_features(a, progress=False)
    fb, _ = relational_features(b, progress=False)
    out = pd.DataFrame({"feature": names, "agreement": (fa == fb).mean(axis=0)})
    ea, eb = numeric_features(a, "F15E", progress=False), numeric_features(b, "F15E", progress=False)
    out.attrs.update(lag=lag, frames=a.n_frames,
                     f15e_cm=float(np.linalg.norm((ea - eb).reshape(len(ea), -1, 3), axis=2).mean()))  # fmt: skip
    return out


def pair_search(c3d, amc, amc_folder, workdir=None) -> pd.DataFrame:
    """Search the AMC takes with the C3D take: DTW over F15E (:class:`~mocapviz.similarity.search.SimilaritySearch`).

    The database holds every AMC of ``amc_folder`` and the C3D take, at :data:`SEARCH_FPS`; the query is the C3D
    take's document, left out of the answers.

    Parameters
    ----------
    c3d, amc : path
        The C3D take and the AMC of the same take (inside ``amc_folder``).
    amc_folder : path
        The AMC takes searched (with their ASFs and labels.tsv).
    workdir : path, optional
        Where the temporary database goes (default a temporary folder, removed after).

    Returns
    -------
    pandas.DataFrame
        The ranking (``rank``, ``name``, ``normalised_cost`` ...) of every AMC take; ``attrs["rank_of_pair"]``: the
        rank of ``amc`` (1 = first).
    """
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        db = MotionDB.ingest([amc_folder, c3d], Path(tmp) / "db", fps=SEARCH_FPS, progress=False)
        docs = db.documents
        query = int(docs.loc[docs["path"] == str(Path(c3d)), "doc_id"].iloc[0])
        hits = SimilaritySearch(db, "F15E").clips(query, n_matches=len(docs) - 1, mode="exact",
                                                  exclude_document=True)  # fmt: skip
    hits.attrs["rank_of_pair"] = int(hits.loc[hits["name"] == Path(amc).stem, "rank"].iloc[0])
    return hits


def marker_comparison(c3d_dir=None, cmu_dir=None) -> pd.DataFrame:
    """:func:`pair_agreement` and :func:`pair_search` of every pair of :func:`marker_pairs`.

    Parameters
    ----------
    c3d_dir, cmu_dir : path, optional
        As :func:`marker_pairs`.

    Returns
    -------
    pandas.DataFrame
        One row per take: ``take``, ``lag`` (frames), ``frames``, ``agreement`` (mean over the 31 features of the
        share of agreeing frames), ``worst_feature``, ``worst_agreement``, ``f15e_cm``, ``rank_of_amc`` (of
        the AMC takes, the rank of the same take's AMC), ``searched`` (AMC takes in the database).
    """
    cmu_dir = Path(cmu_dir or datasets.fetch("cmu-asfamc"))
    rows = []
    for pair in marker_pairs(c3d_dir, cmu_dir).itertuples():
        agree = pair_agreement(pair.c3d, pair.amc)
        worst = agree.loc[agree["agreement"].idxmin()]
        hits = pair_search(pair.c3d, pair.amc, cmu_dir)
        rows.append({"take": pair.take, "lag": agree.attrs["lag"], "frames": agree.attrs["frames"],
                     "agreement": agree["agreement"].mean(), "worst_feature": worst["feature"],
                     "worst_agreement": worst["agreement"], "f15e_cm": agree.attrs["f15e_cm"],
                     "rank_of_amc": hits.attrs["rank_of_pair"], "searched": len(hits)})  # fmt: skip
    return pd.DataFrame(rows)


def floor_alignment(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """``src`` carried onto ``dst`` by the rotation about the vertical (y) axis and the shift that bring them closest
    (least squares over every frame and joint: 2-D Procrustes on the floor, the mean height difference up).

    Two recordings of one take may keep different world axes (CMU's AMC takes are turned 90° about y from their C3D
    files and shifted); the figure's own height is not changed, nor is it mirrored.

    Parameters
    ----------
    src, dst : np.ndarray [shape=(T, J, 3)]
        The same joints of the same frames, cm, y up.

    Returns
    -------
    np.ndarray [shape=(T, J, 3)], float64
        ``src`` in ``dst``'s world.

    Examples
    --------
    >>> m = MotionDB.sample().motion(7).positions.astype(float)
    >>> turned = m @ np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]], float).T + [100.0, 5.0, -40.0]
    >>> bool(np.abs(floor_alignment(turned, m) - m).max() < 1e-6)
    True
    """
    s = np.asarray(src, dtype=np.float64)
    d = np.asarray(dst, dtype=np.float64)
    cs, cd = s.reshape(-1, 3).mean(axis=0), d.reshape(-1, 3).mean(axis=0)
    xs = (s - cs)[..., [0, 2]].reshape(-1, 2)
    xd = (d - cd)[..., [0, 2]].reshape(-1, 2)
    u, _, vt = np.linalg.svd(xs.T @ xd)
    flip = np.diag([1.0, np.sign(np.linalg.det(u @ vt))])  # a rotation, never a mirror image
    turn = u @ flip @ vt  # row vectors: x_src @ turn ~ x_dst
    out = s - cs
    out[..., [0, 2]] = out[..., [0, 2]] @ turn
    return out + cd


def real_marker_clip(markers_take: Motion, skeleton_take: Motion) -> tuple[np.ndarray, ...]:
    """Reconstruction test data from real markers: the paper's six marker joints of a take's C3D-derived clip,
    carried into the world of the same take's skeleton clip (:func:`floor_alignment`), and that clip as the truth.

    Parameters
    ----------
    markers_take, skeleton_take : Motion
        Canonical clips of one take, frames aligned and at one rate (:func:`aligned_takes`): joints estimated from
        its markers (:mod:`mocapviz.motion.markers`) and the skeleton fitted to them (its AMC).

    Returns
    -------
    truth : np.ndarray [shape=(T, 24, 3)], float64
        ``skeleton_take``'s joints, cm.
    markers : np.ndarray [shape=(T, 6, 3)], float64
        ``markers_take``'s joints at :data:`mocapviz.similarity.reconstruction.MARKERS`, in the truth's world, cm.
    headings : np.ndarray [shape=(T,)]
        ``markers_take``'s heading, radians (from the marker-derived hips and shoulders, as a live system would).
    joints : np.ndarray [shape=(T, 24, 3)], float64
        All of ``markers_take``'s joints in the truth's world, cm.
    """
    from ..motion.skeleton import heading
    from ..similarity.reconstruction import MARKERS

    n = min(markers_take.n_frames, skeleton_take.n_frames)
    truth = np.asarray(skeleton_take.positions[:n], dtype=np.float64)
    joints = floor_alignment(markers_take.positions[:n], truth)
    return truth, joints[:, [CANONICAL_JOINTS.index(j) for j in MARKERS]], heading(joints), joints


def pair_reconstruction(c3d, amc, prior_db, numeric_set: str = "F15E", k: int = 256, noise_cm: float = 0.1,
                        seed: int = 0) -> pd.DataFrame:
    """Full-body motion rebuilt from six markers of a real C3D take, against the AMC of the same take
    (Krüger et al. 2010 §5.2 with real instead of simulated markers).

    The two takes are aligned in time (:func:`frame_lag`), resampled to the prior's rate, and the C3D take's joints
    (:mod:`mocapviz.motion.markers`: joint centres estimated from the real marker clusters) are carried into the
    AMC's world (:func:`floor_alignment`). The paper's six markers (:data:`mocapviz.similarity.reconstruction.MARKERS`:
    wrists, ankles, head, root) are then those joints of the C3D take, and its heading comes from them too; the prior
    is ``prior_db`` without every document named like either file (the take left out).

    Parameters
    ----------
    c3d, amc : path
        The two files of one take.
    prior_db : MotionDB
        The pose prior (canonical joints at its own frame rate, e.g. the CMU takes at 30 Hz).
    numeric_set, k
        As :func:`mocapviz.similarity.reconstruction.reconstruct`.
    noise_cm, seed
        The simulated markers' noise (the paper's ±1 mm) and its seed.

    Returns
    -------
    pandas.DataFrame
        Three rows, ``markers``: "real (C3D marker clusters)", "simulated (AMC joints ± noise)" and "none: the C3D
        take's 24 joints" (how far the marker model itself is from CMU's skeleton fit: the floor of the real row);
        columns ``take``, ``frames`` (at the prior's rate), ``fps``, ``mean_cm``, ``max_cm`` (worst frame),
        ``bone_cm`` (:func:`~mocapviz.similarity.reconstruction.reconstruction_errors`), ``k``, ``numeric_set``.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §5.2 and Table 3.
    """
    from ..motion.skeleton import heading
    from ..similarity.reconstruction import PosePrior, reconstruct, reconstruction_errors, synthetic_markers

    a, b, _ = _aligned(Path(c3d), Path(amc))
    truth, markers, headings, joints = real_marker_clip(a.resample(prior_db.fps), b.resample(prior_db.fps))
    n = len(truth)
    names = {Path(c3d).stem, Path(amc).stem}
    valid = np.ones(prior_db.n_frames, dtype=bool)
    for doc in prior_db.documents.itertuples():
        if doc.name in names:
            valid[doc.start : doc.start + doc.n_frames] = False
    prior = PosePrior(prior_db, valid=valid)
    estimates = {
        "real (C3D marker clusters)": reconstruct(markers, headings, prior, numeric_set, k),
        "simulated (AMC joints ± noise)": reconstruct(synthetic_markers(truth, noise_cm, seed), heading(truth), prior,
                                                      numeric_set, k),
        "none: the C3D take's 24 joints": joints,
    }  # fmt: skip
    rows = []
    for kind, estimate in estimates.items():
        e = reconstruction_errors(truth, estimate)
        rows.append({"take": Path(amc).stem, "markers": kind, "frames": n, "fps": prior_db.fps, "mean_cm": e["mean_cm"],
                     "max_cm": e["max_cm"], "bone_cm": e["bone_cm"], "k": k, "numeric_set": numeric_set})  # fmt: skip
    return pd.DataFrame(rows)


def marker_reconstruction(c3d_dir=None, cmu_dir=None, numeric_set: str = "F15E", k: int = 256, prior_db=None,
                          workdir=None) -> pd.DataFrame:
    """:func:`pair_reconstruction` of every pair of :func:`marker_pairs`, the prior every CMU take at
    :data:`SEARCH_FPS` (each pair's take left out).

    Parameters
    ----------
    c3d_dir, cmu_dir : path, optional
        As :func:`marker_pairs`.
    numeric_set, k
        As :func:`pair_reconstruction`.
    prior_db : MotionDB, optional
        The prior, if already ingested (the CMU takes at some rate).
    workdir : path, optional
        Where the prior's temporary database goes (default a temporary folder, removed after).

    Returns
    -------
    pandas.DataFrame
        The rows of every pair.
    """
    cmu_dir = Path(cmu_dir or datasets.fetch("cmu-asfamc"))
    pairs = marker_pairs(c3d_dir, cmu_dir)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        prior = prior_db or MotionDB.ingest([cmu_dir], Path(tmp) / "prior", fps=SEARCH_FPS, progress=False)
        tables = [pair_reconstruction(p.c3d, p.amc, prior, numeric_set, k) for p in pairs.itertuples()]
    return pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
