"""Reconstruction of full-body motion from six sparse markers: Krüger, Tautges, Weber & Zinke 2010 §5.2,
Tables 3 and 4 (after Chai & Hodgins 2005; the method is :mod:`mocapviz.similarity.reconstruction`).

reconstruction      Table 3: per test motion the average (max) per-joint error of the reconstruction with pose
                    priors from different databases (the test actor's clips left out, only the test clip left out,
                    another database), the bone-length error, the baselines (nearest neighbour, weighted mean);
                    Table 4: one test motion with the neighbours searched in each numeric set; per-frame
                    and per-joint errors for plots.
krueger2010_table3  Table 3 as printed (CMU_86_* and HDM_bk_* test motions; priors HDM, CMU-, CMU).
krueger2010_table4  Table 4 as printed (CMU_86_03, nine numeric sets).
default_test_docs   the test clips: one clip of actor bk per class (all of bk's clips with ``full``).

Ours beside the paper's, as tidy tables and bars: :mod:`mocapviz.viz.reconstruction` (``compare_table3``,
``compare_table4``, ``reconstruction_figures``).

Prior variants (Table 3 columns). The paper's test motions are whole takes; its priors are "HDM: entire HDM05
database (possibly without test motion). CMU-: CMU database without collection 86. CMU: entire CMU database
(possibly without test motion)". With a labelled HDM05 database ``db`` (cut clips, 30 Hz) and another one
``other_db`` (the CMU trials):

``HDM-actor``   ``db`` without any clip of the test clip's actor (like CMU-, which leaves the test's collection out);
``HDM``         ``db`` without the test clip only (the actor's other takes of the same class are in);
``CMU``         ``other_db`` (the test motion is not in it).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from ..errors import ParameterError
from ..features.numeric import NUMERIC_SETS, PCAModel
from ..motion.skeleton import CANONICAL_JOINTS, heading
from ..similarity.reconstruction import DEFAULT_K, PosePrior, reconstruct, reconstruction_errors, synthetic_markers
from ..validation import some_of

__all__ = ["VARIANTS", "default_test_docs", "krueger2010_table3", "krueger2010_table4", "reconstruction"]

VARIANTS = ("HDM-actor", "HDM", "CMU")
BASELINES = ("llm", "mean", "nn")
_PAPER_SETS = ("F15E", "Fp8", "Fp16", "Fp25", "F30E", "F39E", "F15x3E", "F15x5E", "F30x3E")

# Table 3: motion, frames, (mean, max) for the priors HDM, CMU-, CMU
_PAPER_TABLE3 = {
    "CMU_86_01": (1145, (2.63, 6.47), (2.06, 4.11), (1.30, 3.42)),
    "CMU_86_08": (2302, (3.06, 6.67), (2.67, 6.95), (1.96, 6.82)),
    "CMU_86_15": (1773, (3.37, 6.41), (2.64, 8.01), (2.31, 5.88)),
    "CMU_86_avg": (29040, (2.79, 7.99), (2.30, 5.58), (1.74, 5.05)),
    "HDM_bk_01-01_01": (2571, (1.33, 5.13), (2.69, 5.04), (2.70, 5.43)),
    "HDM_bk_02-01_01": (912, (2.17, 6.45), (3.23, 8.68), (3.22, 8.65)),
}
# Table 4: CMU_86_03, prior the entire CMU database without the test motion
_PAPER_TABLE4 = {
    "F15E": (1.66, 4.73), "Fp8": (1.71, 5.09), "Fp16": (1.49, 5.25), "Fp25": (1.41, 4.80), "F30E": (1.35, 4.55),
    "F39E": (1.34, 4.92), "F15x3E": (1.38, 4.80), "F15x5E": (1.40, 4.79), "F30x3E": (1.30, 4.35),
}  # fmt: skip


def krueger2010_table3() -> pd.DataFrame:
    """Table 3 of Krüger et al. 2010: average (max) reconstruction errors in cm per joint.

    Returns
    -------
    pandas.DataFrame
        One row per test motion: ``motion``, ``frames``, ``HDM_mean``, ``HDM_max``, ``CMU-_mean``, ``CMU-_max``,
        ``CMU_mean``, ``CMU_max`` (cm). CMU_86_avg is the average over the 15 motions of collection 86.
    """
    rows = []
    for motion, (frames, *cells) in _PAPER_TABLE3.items():
        row = {"motion": motion, "frames": frames}
        for name, (mean, worst) in zip(("HDM", "CMU-", "CMU"), cells):
            row[f"{name}_mean"], row[f"{name}_max"] = mean, worst
        rows.append(row)
    return pd.DataFrame(rows)


def krueger2010_table4() -> pd.DataFrame:
    """Table 4 of Krüger et al. 2010: average (max) errors (cm per joint) of CMU_86_03 per feature set of the
    neighbour search (prior: the entire CMU database without the test motion).

    Returns
    -------
    pandas.DataFrame
        One row: ``motion``, then ``<set>_mean``, ``<set>_max`` (cm) for the nine sets in the paper's order.
    """
    row = {"motion": "CMU_86_03"}
    for name, (mean, worst) in _PAPER_TABLE4.items():
        row[f"{name}_mean"], row[f"{name}_max"] = mean, worst
    return pd.DataFrame([row])


def default_test_docs(db, actor: str = "bk", full: bool = False) -> list[int]:
    """Test clips of ``db`` (the paper's HDM05 test motions are bk's): the first clip of ``actor`` in every class
    (11 clips, 839 frames at 30 Hz for bk in the shared HDM05 cut clips), or with ``full`` all of the actor's
    clips (65, 4,518 frames); doc_ids in increasing order.

    Parameters
    ----------
    db : MotionDB
        A labelled database with an ``actor`` column.
    actor : str
        The test actor.
    full : bool
        All of the actor's clips, not one per class.

    Returns
    -------
    list of int
        Doc ids, increasing.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> default_test_docs(MotionDB.sample(), actor="mm")[:4]
    [13, 14, 15, 16]
    """
    docs = db.documents
    if "actor" not in docs or not (docs["actor"] == actor).any():
        raise ParameterError(f"{db.path} has no clip of actor {actor!r} (an 'actor' label column is needed)")
    mine = docs[docs["actor"] == actor].sort_values("doc_id")
    return sorted(int(d) for d in (mine["doc_id"] if full else mine.groupby("label")["doc_id"].first()))


def frame_actors(db) -> np.ndarray:
    """The actor of every frame of a MotionDB.

    Parameters
    ----------
    db : MotionDB
        A database with an ``actor`` column.

    Returns
    -------
    np.ndarray [shape=(N,)], object
        The documents' ``actor`` labels, one per database frame.
    """
    return db.documents.set_index("doc_id").loc[db.document_of(np.arange(db.n_frames)), "actor"].to_numpy()


def marker_clip(db, doc: int, noise_cm: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A document of ``db`` as reconstruction test data (Krüger et al. 2010 §5.2).

    Parameters
    ----------
    db : MotionDB
        The database.
    doc : int
        The test clip's doc id.
    noise_cm : float
        Half-width of the uniform marker noise, cm (the paper: 0.1 cm).
    seed : int
        Seed of the noise (with ``doc``).

    Returns
    -------
    truth : np.ndarray [shape=(T, 24, 3)], float64
        The clip's canonical joints, cm.
    markers : np.ndarray [shape=(T, 6, 3)]
        The joints of :data:`mocapviz.similarity.reconstruction.MARKERS` with uniform noise of +-``noise_cm`` per
        coordinate, drawn from ``np.random.default_rng([seed, doc])`` (reproducible per clip), cm.
    headings : np.ndarray [shape=(T,)]
        The clip's heading, radians.
    """
    truth = np.asarray(db.positions[db.frames(doc)], dtype=np.float64)
    markers = synthetic_markers(truth, noise_cm, np.random.default_rng([seed, doc]))
    return truth, markers, heading(truth)


def reconstruction(db, other_db=None, test_docs=None, k: int = DEFAULT_K, numeric_sets=NUMERIC_SETS,
                   table4_doc: int | None = None, noise_cm: float = 0.1, seed: int = 0, pca: PCAModel | None = None,
                   baselines: bool = True, full: bool = False, progress: bool = False, **options) -> dict[str, pd.DataFrame]:  # fmt: skip
    """Tables 3 and 4 of Krüger et al. 2010 (§5.2): motions reconstructed from six noisy markers.

    For each test clip of ``db``: synthetic markers (:func:`mocapviz.similarity.reconstruction.synthetic_markers`, uniform
    noise of +-``noise_cm`` per coordinate, the same markers for every prior), the heading from the clip's hip
    line, then :func:`mocapviz.similarity.reconstruction.reconstruct` with each prior variant (module docstring), and the errors
    of :func:`mocapviz.similarity.reconstruction.reconstruction_errors`.

    Parameters
    ----------
    db : MotionDB
        Labelled (``actor``, ``label``) HDM05 cut clips at one frame rate (30 Hz in the paper's kNN experiments).
    other_db : MotionDB, optional
        A second database for the ``CMU`` column (the shared CMU trials at ``db``'s frame rate).
    test_docs : list of int, optional
        doc_ids of ``db`` (default :func:`default_test_docs`: bk's first clip of every class, or with ``full`` all
        of bk's clips).
    k : int
        Neighbours per frame.
    numeric_sets : sequence of str
        The numeric sets of Table 4 (F15E: one pass; the others: two passes).
    table4_doc : int, optional
        The Table 4 test clip (default the first test doc); empty ``numeric_sets``: no Table 4.
    noise_cm : float
        The marker noise, +- cm per coordinate.
    seed : int
        Its seed (each clip's noise comes from (seed, doc_id)).
    pca : PCAModel, optional
        For the Fp sets (default :func:`mocapviz.features.numeric.default_pca` of ``db``).
    baselines : bool
        Also run the nearest-neighbour pose and the weighted neighbour mean (``"baselines"``).
    full : bool
        The default test clips are all of bk's (about 6x the time) instead of one per class.
    progress : bool
        A progress bar over the test clips.
    **options
        Passed to :func:`mocapviz.similarity.reconstruction.reconstruct` (variance, bandwidth, marker_sigma,
        smooth_sigma).

    Returns
    -------
    dict
        Name -> pandas.DataFrame:
        ``"table3"``: one row per test clip and a last row ``avg`` (all test frames: the frame-weighted mean of the
        means, the largest max): ``motion`` (name), ``doc_id``, ``class``, ``frames``, and per variant ``<v>_mean``,
        ``<v>_max`` (the worst frame's mean joint error), ``<v>_bone`` (mean bone-length error), all cm.
        ``"table4"``: one row: ``motion``, ``doc_id``, ``frames``, ``prior`` (``HDM``), and per set ``<set>_mean``,
        ``<set>_max``, ``<set>_bone``.
        ``"baselines"``: per (motion, variant, method in llm / mean / nn): ``mean_cm``, ``max_cm``, ``bone_cm``,
        ``seconds`` (the reconstruction's wall time), ``frames``.
        ``"frames"``: per-frame errors of the Table 4 test clip: ``frame``, ``time_s``, ``variant``, ``error_cm``.
        ``"joints"``: per joint and variant the mean error over all test frames: ``joint``, ``variant``,
        ``error_cm``.

    Raises
    ------
    ValueError
        Unknown doc_ids or numeric sets, a database without ``actor`` labels, databases at different frame rates.
    """
    docs = db.documents.set_index("doc_id")
    if "actor" not in docs:
        raise ParameterError(f"{db.path}: the documents need an 'actor' label column for the HDM-actor prior")
    if db.fps is None:
        raise ParameterError(f"{db.path}: documents at different frame rates; resample the database to one")
    if other_db is not None and other_db.fps != db.fps:
        raise ParameterError(f"other_db is at {other_db.fps} fps, db at {db.fps} fps: the markers must be at the "
                         "prior's rate")  # fmt: skip
    test_docs = default_test_docs(db, full=full) if test_docs is None else [int(d) for d in test_docs]
    unknown = [d for d in test_docs if d not in docs.index]
    if unknown or not test_docs:
        raise ParameterError(f"test_docs {unknown or test_docs} are not doc_ids of {db.path}")
    some_of(numeric_sets, "numeric set(s)", NUMERIC_SETS)
    table4_doc = test_docs[0] if table4_doc is None else int(table4_doc)
    if table4_doc not in docs.index:
        raise ParameterError(f"table4_doc {table4_doc} is not a doc_id of {db.path}")

    variants = [v for v in VARIANTS if v != "CMU" or other_db is not None]
    prior = PosePrior(db, pca=pca)
    other = PosePrior(other_db) if other_db is not None else None
    actor_of = frame_actors(db)
    by_actor: dict[str, PosePrior] = {}

    def priors(doc: int) -> dict[str, PosePrior]:
        actor = docs.loc[doc, "actor"]
        if actor not in by_actor:
            by_actor[actor] = prior.restrict(actor_of != actor)
        own = np.ones(db.n_frames, dtype=bool)
        own[db.frames(doc)] = False
        out = {"HDM-actor": by_actor[actor], "HDM": prior.restrict(own)}
        if other is not None:
            out["CMU"] = other
        return out

    rows, base_rows, frame_rows = [], [], []
    joint_sum = {v: np.zeros(len(CANONICAL_JOINTS)) for v in variants}
    work = tqdm(test_docs, desc="reconstructing", unit="clip") if progress else test_docs
    for doc in work:
        truth, markers, h = marker_clip(db, doc, noise_cm, seed)
        row = {"motion": docs.loc[doc, "name"], "doc_id": doc, "class": docs.loc[doc, "label"], "frames": len(truth)}
        for variant, pr in priors(doc).items():
            for method in BASELINES if baselines else ("llm",):
                t0 = time.perf_counter()
                est = reconstruct(markers, h, pr, k=min(k, pr.n_valid), method=method, **options)
                seconds = time.perf_counter() - t0
                err = reconstruction_errors(truth, est)
                base_rows.append({"motion": row["motion"], "variant": variant, "method": method,
                                  "frames": len(truth), "mean_cm": err["mean_cm"], "max_cm": err["max_cm"],
                                  "bone_cm": err["bone_cm"], "seconds": seconds})  # fmt: skip
                if method != "llm":
                    continue
                row.update({f"{variant}_mean": err["mean_cm"], f"{variant}_max": err["max_cm"],
                            f"{variant}_bone": err["bone_cm"]})  # fmt: skip
                joint_sum[variant] += err["per_joint_cm"] * len(truth)
                if doc == table4_doc:
                    frame_rows += [{"frame": i, "time_s": i / db.fps, "variant": variant, "error_cm": e}
                                   for i, e in enumerate(err["per_frame_cm"])]  # fmt: skip
        rows.append(row)
    table3 = pd.DataFrame(rows)
    n = table3["frames"].to_numpy()
    avg = {"motion": "avg", "doc_id": -1, "class": "", "frames": int(n.sum())}
    for v in variants:
        avg[f"{v}_mean"] = float(np.average(table3[f"{v}_mean"], weights=n))
        avg[f"{v}_max"] = float(table3[f"{v}_max"].max())
        avg[f"{v}_bone"] = float(np.average(table3[f"{v}_bone"], weights=n))
    table3 = pd.concat([table3, pd.DataFrame([avg])], ignore_index=True)
    joints = pd.DataFrame([{"joint": j, "variant": v, "error_cm": joint_sum[v][i] / n.sum()}
                           for v in variants for i, j in enumerate(CANONICAL_JOINTS)])  # fmt: skip

    out = {"table3": table3, "baselines": pd.DataFrame(base_rows), "joints": joints}
    if table4_doc not in test_docs:  # its per-frame errors were not computed above
        truth, markers, h = marker_clip(db, table4_doc, noise_cm, seed)
        for variant, pr in priors(table4_doc).items():
            err = reconstruction_errors(truth, reconstruct(markers, h, pr, k=min(k, pr.n_valid), **options))
            frame_rows += [{"frame": i, "time_s": i / db.fps, "variant": variant, "error_cm": e}
                           for i, e in enumerate(err["per_frame_cm"])]  # fmt: skip
    out["frames"] = pd.DataFrame(frame_rows)
    if len(numeric_sets):
        truth, markers, h = marker_clip(db, table4_doc, noise_cm, seed)
        pr = priors(table4_doc)["HDM"]
        row = {"motion": docs.loc[table4_doc, "name"], "doc_id": table4_doc, "frames": len(truth), "prior": "HDM"}
        names = tqdm(numeric_sets, desc="Table 4", unit="set") if progress else numeric_sets
        for name in names:
            err = reconstruction_errors(truth, reconstruct(markers, h, pr, numeric_set=name, k=min(k, pr.n_valid),
                                                           **options))  # fmt: skip
            row.update({f"{name}_mean": err["mean_cm"], f"{name}_max": err["max_cm"], f"{name}_bone": err["bone_cm"]})
        out["table4"] = pd.DataFrame([row])
    return out
