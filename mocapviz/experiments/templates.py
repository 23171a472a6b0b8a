"""How well motion templates find and classify their class (Müller & Röder 2006 §5–6), leave-group-out.

For every labelled class and every group (actor) that holds clips of it, a template is learned from the class's
clips of the *other* groups (:func:`mocapviz.relational.templates.learn_class`) and then

- searched in the held-out group's clips (``search="group"``, the leave-actor-out protocol of the issue) and in
  all clips of the database (``search="all"``; the training clips are then among the candidates: an optimistic
  figure, reported beside the other): every clip is ranked by its best match's normalised cost (mean mismatch
  per template frame, :func:`mocapviz.relational.templates.document_costs`), judged by :mod:`mocapviz.experiments.evaluation` with the
  class as the label sought (no clip is the query): AP and R-precision of the ranking, and precision and recall of
  the clips holding a match of normalised cost at most the template's learned threshold
  (:func:`mocapviz.relational.templates.separating_threshold`, or ``max_cost``): the hits a user gets without choosing a threshold;
- used to classify: every clip of the held-out group goes to the class of the nearest template learned without
  its group (:func:`mocapviz.relational.templates.classify`).

template_quality   db -> {"summary", "per_class", "per_template", "classification"} DataFrames.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..features import relational_features
from ..relational.templates import DELTA, classify, document_costs, learn_class
from ..validation import number
from . import evaluation

__all__ = ["template_quality"]


def template_quality(db, relational_set: str = "2006", group: str = "actor", delta: float = DELTA,
                     max_cost: float | None = None, progress: bool = False, by_group: bool = True,
                     max_rows: int | None = None) -> dict:  # fmt: skip
    """Leave-group-out retrieval and classification quality of motion templates on a labelled MotionDB.

    Parameters
    ----------
    db : MotionDB
        With ``label`` and ``group`` columns (HDM05: ``actor``).
    relational_set : {"2005", "2006"}
        The features the templates are learned on.
    group : str
        The column whose values are left out in turn.
    delta : float
        The quantisation threshold of the templates.
    max_cost : float, optional
        The normalised cost in [0, 1] up to which a clip's best match counts as a hit (precision and recall);
        default each template's learned ``meta["threshold"]`` (:func:`mocapviz.relational.templates.separating_threshold`).
    progress : bool
        A progress bar over the templates.
    by_group : bool
        Learn each template keeping its training groups apart, so that a feature counts only when (almost) every
        training group is consistent in it (default; ``learn_class(..., by_group=...)``); False: the pooled rule.
    max_rows : int, optional
        The most template rows one clip frame may take in a match (default
        :func:`mocapviz.relational.templates.steepest_rows` of each template); 0: any number. ``by_group=False,
        max_rows=0`` is the method of earlier versions (HDM05: mAP 0.965, kickLFront1Reps of actor tr 0.64).

    Returns
    -------
    dict
        Name -> pandas.DataFrame:

        - ``per_template``: one row per (class, held-out group): ``class``, ``group``, ``examples`` (training
          clips), ``frames`` (template length), ``cared`` (share of entries that are not don't care),
          ``ap_group``, ``ap_all`` (average precision searching the group's clips / all clips),
          ``r_precision_group``, ``precision_group``, ``recall_group`` (of the group's clips with a match of cost
          <= the threshold; precision NaN when there is none), ``learn_s``, ``search_ms`` (searching the group's
          clips).
        - ``per_class``: per class, the mean of those over the held-out groups.
        - ``summary``: one row: ``templates``, ``map_group``, ``map_all``, ``min_class_ap_group``,
          ``precision_group``, ``recall_group`` (means over the templates), ``classification_accuracy``,
          ``clips_classified``.
        - ``classification``: one row per held-out clip: ``doc_id``, ``class``, ``predicted``, ``correct``.

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §5-6 (retrieval and classification with class templates).
    """
    if max_cost is not None:
        max_cost = number(max_cost, "max_cost", 0.0, 1.0)
    docs = db.documents
    for column in ("label", group):
        if column not in docs.columns:
            raise ParameterError(f"{db.path}: the documents have no {column!r} column; template_quality needs labels "
                                 f"and a group column (e.g. actor)")  # fmt: skip
    docs = docs[docs["label"].notna() & docs[group].notna()]
    if docs.empty:
        raise ParameterError(f"{db.path}: no document has both a label and a {group}")
    values, _ = relational_features(db, relational_set, progress=progress)
    labels = db.documents.set_index("doc_id")["label"]
    groups = sorted(map(str, docs[group].unique()))
    classes = sorted(map(str, docs["label"].unique()))
    every = _pool(db, docs)
    rows, predictions = [], []
    work = [(g, c) for g in groups for c in classes]
    if progress:
        from tqdm.auto import tqdm

        work = tqdm(work, desc="motion templates", unit="template")
    templates = {}
    for g, c in work:
        train = docs[(docs["label"].astype(str) == c) & (docs[group].astype(str) != g)]
        held = docs[docs[group].astype(str) == g]
        if train.empty or not (held["label"].astype(str) == c).any():
            continue
        t0 = time.perf_counter()
        template = learn_class(db, c, sorted(map(str, train[group].unique())), relational_set, values,
                               group=group, by_group=by_group)  # fmt: skip
        learn_s = time.perf_counter() - t0
        templates[(g, c)] = template
        t0 = time.perf_counter()
        threshold = template.meta["threshold"] if max_cost is None else max_cost
        judged = _search(template, values, _pool(db, held), labels, c, delta, threshold, max_rows)
        search_ms = 1000 * (time.perf_counter() - t0)
        ap_all = _search(template, values, every, labels, c, delta, threshold, max_rows)["ap"]
        rows.append({"class": c, "group": g, "examples": len(train), "frames": len(template.values),
                     "cared": float((template.quantised(delta) != 0.5).mean()), "ap_group": judged["ap"],
                     "ap_all": ap_all, "r_precision_group": judged["r_precision"],
                     "precision_group": judged["precision"], "recall_group": judged["recall"], "learn_s": learn_s,
                     "search_ms": search_ms})  # fmt: skip
    for g in groups:
        mine = [t for (tg, _), t in templates.items() if tg == g]
        if not mine:
            continue
        for _, row in docs[docs[group].astype(str) == g].iterrows():
            clip = values[row["start"] : row["start"] + row["n_frames"]]
            predicted = classify(clip, mine, delta)["label"].iloc[0]
            predictions.append({"doc_id": int(row["doc_id"]), "class": str(row["label"]), "predicted": predicted,
                                "correct": predicted == str(row["label"])})  # fmt: skip
    per_template = pd.DataFrame(rows)
    if per_template.empty:
        raise ParameterError(f"{db.path}: no class has clips in two {group} groups; nothing to leave out")
    per_class = per_template.groupby("class").agg(
        groups=("group", "size"), examples=("examples", "mean"), frames=("frames", "mean"), cared=("cared", "mean"),
        ap_group=("ap_group", "mean"), ap_all=("ap_all", "mean"), r_precision_group=("r_precision_group", "mean"),
        precision_group=("precision_group", "mean"), recall_group=("recall_group", "mean"),
        learn_s=("learn_s", "mean"), search_ms=("search_ms", "mean")).reset_index()  # fmt: skip
    classification = pd.DataFrame(predictions, columns=["doc_id", "class", "predicted", "correct"])
    summary = pd.DataFrame([{
        "templates": len(per_template), "map_group": per_template["ap_group"].mean(),
        "map_all": per_template["ap_all"].mean(), "min_class_ap_group": per_class["ap_group"].min(),
        "precision_group": per_template["precision_group"].mean(),
        "recall_group": per_template["recall_group"].mean(),
        "classification_accuracy": classification["correct"].mean() if len(classification) else np.nan,
        "clips_classified": len(classification),
    }])  # fmt: skip
    return {"summary": summary, "per_class": per_class, "per_template": per_template,
            "classification": classification}  # fmt: skip


def _pool(db, docs: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame rows of ``docs`` in the database, their document starts within those rows, their doc ids)."""
    rows = np.concatenate([np.arange(s, s + n) for s, n in zip(docs["start"], docs["n_frames"])])
    starts = np.concatenate([[0], np.cumsum(docs["n_frames"].to_numpy())[:-1]]).astype(np.int64)
    return rows, starts, docs["doc_id"].to_numpy(np.int64)


def _search(template, values, pool, labels, label: str, delta: float, max_cost: float, max_rows=None) -> dict:
    """AP and R-precision of the clips of ``pool`` ranked by their best match of ``template``, and precision and
    recall of those whose best match costs at most ``max_cost``."""
    rows, starts, doc_ids = pool
    costs = document_costs(template, values[rows], starts, delta, max_rows=max_rows)
    order = np.argsort(costs, kind="stable")
    ranking, n_relevant = evaluation.relevance(doc_ids[order], labels, None, candidates=doc_ids, label=label)
    hits = int((costs <= max_cost).sum())  # the first ``hits`` of the ranking
    found = int(ranking["relevant"].to_numpy(dtype=bool)[:hits].sum())
    return {"ap": evaluation.average_precision(ranking, n_relevant),
            "r_precision": evaluation.precision_at(ranking, max(1, n_relevant)),
            "precision": found / hits if hits else float("nan"),
            "recall": found / n_relevant if n_relevant else float("nan")}
