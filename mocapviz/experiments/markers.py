"""Marker-derived joints against the AMC of the same take (issue 27): how close :mod:`mocapviz.motion.markers`
comes to the skeleton CMU fitted to the same markers.

marker_pairs      the C3D takes of a folder that have an AMC of the same take in a CMU folder (by its labels.tsv).
frame_lag         the frame offset between two clips of one take: the lag that best correlates their feet heights.
pair_agreement    per relational 2005 feature, the share of aligned frames where the C3D-derived and the
                  AMC-derived feature agree; and F15E (Krüger et al. 2010) distance in the body frame.
pair_search       the DTW similarity search with the C3D take as query over a database of the AMC takes and the
                  C3D take itself (excluded from the answers): the rank of the AMC of the same take.
marker_comparison all three for every pair: one row per pair.

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

__all__ = ["frame_lag", "marker_comparison", "marker_pairs", "pair_agreement", "pair_search"]

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
    a = load(c3d).canonical()
    b = load(amc).canonical()
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
