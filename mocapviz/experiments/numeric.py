"""Experiments of Krüger, Tautges, Weber & Zinke 2010 on numeric similarity search, as DataFrames.

knn_timings             Table 1 (§3.3): k-nearest-neighbour search times per numeric set, ours beside the paper's.
krueger2010_table1      Table 1 as printed in the paper (HDM05 380,813 frames and CMU 1,038,388 frames at 30 Hz).
base_pose_experiment    §5.3: fat-graph base poses with kd-tree radius searches, against the O(n²) construction
                        (the algorithm itself: :func:`mocapviz.similarity.knn.base_poses`).
"""
from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..features.numeric import NUMERIC_SETS, default_pca, numeric_of
from ..parallel import progress_bar
from ..similarity.knn import KnnIndex, base_poses, base_poses_quadratic
from ..validation import renamed, some_of

__all__ = ["base_pose_experiment", "knn_timings", "krueger2010_table1"]

# Table 1 (ms per query, exact search, ANN library on 2010 hardware): rows (database, k), columns the sets
_PAPER_TABLE1 = {
    ("HDM05", 16): (0.19, 1.33, 2.86, 1.11, 3.87, 5.27, 7.95, 14.01, 18.98),
    ("HDM05", 256): (1.03, 4.99, 8.68, 4.53, 12.50, 16.37, 23.70, 36.22, 46.71),
    ("CMU", 16): (0.25, 2.15, 5.37, 1.65, 6.37, 8.71, 20.62, 37.08, 55.59),
    ("CMU", 256): (1.35, 8.97, 18.10, 7.36, 24.12, 31.68, 60.23, 96.55, 136.29),
}
_PAPER_SETS = ("Fp8", "Fp16", "Fp25", "F15E", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E")
_PAPER_FRAMES = {"HDM05": 380_813, "CMU": 1_038_388}


def krueger2010_table1() -> pd.DataFrame:
    """Table 1 of Krüger et al. 2010: mean ms per exact k-NN query, per database, k and numeric set.

    Returns
    -------
    pandas.DataFrame, columns ``database``, ``frames``, ``k``, ``set``, ``mean_ms``.
    """
    return pd.DataFrame(
        [{"database": db, "frames": _PAPER_FRAMES[db], "k": k, "set": s, "mean_ms": ms}
         for (db, k), row in _PAPER_TABLE1.items() for s, ms in zip(_PAPER_SETS, row)]
    )  # fmt: skip


@renamed(workers="threads")
def knn_timings(db, numeric_sets=_PAPER_SETS, ks=(16, 256), n_queries: int = 1000, pca=None,
                database: str | None = None,
                seed: int = 0, threads: int | None = None, repeats: int = 3) -> pd.DataFrame:  # fmt: skip
    """k-NN search times per numeric set (Krüger et al. 2010 §3.3, Table 1).

    For each set a :class:`mocapviz.similarity.knn.KnnIndex` (scipy cKDTree) is built over all frames of ``db``, then
    ``n_queries`` random frames of the database are searched for their k nearest neighbours, exactly (ε = 0),
    as one batch on ``threads`` threads; the mean time per query is the batch's wall time / n_queries, the
    median of ``repeats`` runs.

    Parameters
    ----------
    db : MotionDB
        Features are taken from ``<db>/features`` when stored and current, else computed.
    numeric_sets : sequence of str
        Names of :data:`mocapviz.features.numeric.NUMERIC_SETS`; default the nine sets of Table 1.
    ks : sequence of int
    n_queries : int
    pca : PCAModel, optional
        The reference PCA for the Fp sets (the paper: fitted on all of HDM05); default
        :func:`mocapviz.features.numeric.default_pca` (the stored one, else fitted on ``db``).
    database : str, optional
        Name of the database for the table (default: the folder name of ``db``).
    seed : int
    threads : int, optional
        Threads of the batched query (default :func:`mocapviz.parallel.default_threads`: the cores, at most 8; the
        paper's searches ran on one). (Formerly ``workers``: still accepted, with a FutureWarning.)
    repeats : int
        Runs of each batch; the median is reported.

    Returns
    -------
    pandas.DataFrame
        One row per (set, k): ``database``, ``frames``, ``set``, ``d``, ``k``, ``features_s`` (loading the stored
        features, or computing them), ``build_s`` (tree construction), ``mean_ms`` (per query), ``queries``.

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §3.3, Table 1 (:func:`krueger2010_table1` holds the paper's figures).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> table = knn_timings(MotionDB.sample(), ["F15E", "F30x3E"], ks=(16,), n_queries=100, repeats=1)
    >>> print(table[["frames", "set", "d", "k", "queries"]].to_string(index=False))  # and the times, in seconds
     frames    set  d  k  queries
       5543   F15E 15 16      100
       5543 F30x3E 90 16      100
    """
    some_of(numeric_sets, "numeric set(s)", NUMERIC_SETS)
    rng = np.random.default_rng(seed)
    frames = rng.choice(db.n_frames, size=min(n_queries, db.n_frames), replace=False)
    name = database or getattr(db, "path", "db").name
    if pca is None and any(s.startswith("Fp") for s in numeric_sets):
        pca = default_pca(db)
    rows = []
    for s in progress_bar(numeric_sets, desc="k-NN timings", unit="set", disable=True):
        t0 = time.perf_counter()
        x = np.ascontiguousarray(numeric_of(db, s, pca))
        t_features = time.perf_counter() - t0
        t0 = time.perf_counter()
        index = KnnIndex(x)
        build = time.perf_counter() - t0
        queries = x[frames]
        for k in progress_bar(ks, desc=s, unit="k", disable=True):
            index.query(queries[:10], k, threads=threads)  # warm-up
            runs = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                index.query(queries, k, threads=threads)
                runs.append(time.perf_counter() - t0)
            elapsed = float(np.median(runs))
            rows.append({"database": name, "frames": db.n_frames, "set": s, "d": x.shape[1], "k": k,
                         "features_s": t_features, "build_s": build, "mean_ms": 1e3 * elapsed / len(frames),
                         "queries": len(frames)})  # fmt: skip
    return pd.DataFrame(rows)


def base_pose_experiment(features: np.ndarray, radius: float, k: int = 32,
                         quadratic_frames: int = 5000) -> pd.DataFrame:  # fmt: skip
    """Fat-graph base poses (Krüger et al. 2010 §5.3): the kd-tree construction (:func:`mocapviz.similarity.knn.base_poses`)
    against the O(n²) one.

    Parameters
    ----------
    features : np.ndarray [shape=(N, d)], e.g. F15E of a database (cm)
    radius : float
        Neighbourhood radius, in the features' unit.
    k : int
        At most k neighbours per frame.
    quadratic_frames : int
        The O(n²) construction runs on this many evenly spaced frames only (and the kd-tree one again on the same
        subset, to compare results).

    Returns
    -------
    pandas.DataFrame
        One row per (method, frames): ``method``, ``frames``, ``base_poses``, ``seconds``, ``same_as_quadratic``
        (the subset rows: both constructions chose the same base poses in the same order and put every frame in
        the same cluster; None for the whole database, which has no reference).

    References
    ----------
    .. [1] B. Krüger, J. Tautges, A. Weber, A. Zinke. Fast local and global similarity searches in large motion
       capture databases. SCA 2010, §5.3 (fast fat graphs).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import numeric_of
    >>> table = base_pose_experiment(numeric_of(MotionDB.sample(), "F15E"), radius=20.0, quadratic_frames=1000)
    >>> table[["method", "frames", "same_as_quadratic"]].values.tolist()
    [['O(n²) distance matrix', 1000, True], ['kd-tree, O(n log n)', 1000, True], ['kd-tree, O(n log n)', 5543, None]]
    """
    features = np.asarray(features)
    sub = np.ascontiguousarray(features[np.linspace(0, len(features) - 1, min(quadratic_frames, len(features)),
                                                    dtype=np.int64)])  # fmt: skip
    t0 = time.perf_counter()
    base_q, cluster_q = base_poses_quadratic(sub, radius, k=k)
    t_q = time.perf_counter() - t0
    t0 = time.perf_counter()
    base_s, cluster_s = base_poses(sub, radius, k=k)
    t_s = time.perf_counter() - t0
    same = bool(np.array_equal(base_q, base_s) and np.array_equal(cluster_q, cluster_s))
    rows = [{"method": "O(n²) distance matrix", "frames": len(sub), "base_poses": len(base_q), "seconds": t_q,
             "same_as_quadratic": True},
            {"method": "kd-tree, O(n log n)", "frames": len(sub), "base_poses": len(base_s), "seconds": t_s,
             "same_as_quadratic": same}]  # fmt: skip
    if len(features) > len(sub):
        t0 = time.perf_counter()
        base_all, _ = base_poses(features, radius, k=k)
        rows.append({"method": "kd-tree, O(n log n)", "frames": len(features), "base_poses": len(base_all),
                     "seconds": time.perf_counter() - t0, "same_as_quadratic": None})  # fmt: skip
    return pd.DataFrame(rows)
