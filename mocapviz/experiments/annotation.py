"""The annotation loop measured with a simulated annotator (issue 40 item 4): label a few examples, learn a motion
template, search it, accept or reject a page of hits, learn again.

One group of a labelled database (an actor of HDM05, a style of Bandai Namco) is **hidden**: a copy of the database
is made in which its documents carry no class (:func:`annotator_view`), and the true classes are the oracle. Per
class, :func:`annotation_loop` starts from the visible documents of the class (the other groups' file-name labels),
learns the class's template from them (:meth:`Engine.learn_template`, at most 16 examples: the engine's default),
searches it (:meth:`Engine.search_template`) and shows a page of K = 20 hits, the best hit of each of the first 20
documents still unlabelled (no file-name label, no segment label of the class yet: neither accepted nor
rejected). The annotator reviews the page, each hit costing 1:

- ``one by one``: accept the hit when it lies in a hidden document of the class, reject it otherwise; the review
  stops at the hit that brings the class to the target (90 % of its hidden documents labelled);
- ``whole page``: accept every hit of the page in one click (the page's 20 hits all cost 1: each was looked at),
  so wrong hits become labels too and the next template learns from them.

Accepted hits become segment labels (source ``accepted hit``), rejected ones ``rejected hit``
(:meth:`Engine.add_labels`); the template is learned again from every label of the class, and the loop repeats
until the target is reached (stop ``target``) or the search finds no hit in a document not yet reviewed (stop
``exhausted``). The baselines review the unlabelled documents without a search: in document order (the cost is
the position at which the target is reached, :func:`order_cost`) and in random order (the expected position,
:func:`expected_random_cost`).

annotator_view        db, hidden documents -> a copy of the database whose hidden documents carry no class.
annotation_loop       engine, oracle, class -> one row per reviewed hit.
review_page           engine, template, class -> a round's page: the best hit of each document not yet labelled.
unlabelled_documents  db -> the doc ids without a file-name label.
order_cost            the cost of reviewing documents in a given order until the target.
expected_random_cost  the same in random order, its expectation.
simulated_annotation  db, hidden group -> {"per_class", "trace", "summary"}: every class, both variants, the
                      baselines.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..validation import count, one_of

__all__ = ["annotation_loop", "annotator_view", "expected_random_cost", "order_cost", "review_page",
           "simulated_annotation", "unlabelled_documents"]

PAGE = 20
"""The hits the annotator reviews per round: a page of the gallery."""
TARGET = 0.9
"""The share of a class's hidden documents to label."""
VARIANTS = ("one by one", "whole page")
"""How the annotator reviews a page: each hit judged by the oracle, or the whole page accepted in one click."""
HIDDEN_COLUMNS = ("label", "class", "content")
"""The document columns that name a clip's class (HDM05's ``class`` and Bandai Namco's ``content`` repeat
``label``): blanked in the hidden documents."""
AUTHOR = "simulated annotator"


def annotator_view(db, hidden, out, columns=HIDDEN_COLUMNS):
    """A copy of ``db`` at ``out`` in which the documents ``hidden`` carry no class: what the annotator sees.

    The clips are copied as they are (:meth:`MotionDB.append_motions`, same document ids and order, same names and
    other columns); only ``columns`` are blanked in the hidden documents, so that no file-name label of theirs
    reaches a template or a search.

    Parameters
    ----------
    db : MotionDB
        A labelled database (not changed).
    hidden : sequence of int
        Document ids whose class is hidden.
    out : str or os.PathLike
        The new database's folder (must not exist, or be empty).
    columns : sequence of str
        The document columns blanked (those present).

    Returns
    -------
    MotionDB
        The copy, with the documents of ``db`` in order (doc ids 0, 1, ... as ``db``'s when those are).
    """
    from ..db.database import MotionDB

    docs = db.documents
    hidden = {int(d) for d in hidden}
    kept = [c for c in docs.columns if c not in ("doc_id", "start", "n_frames", "fps")]
    blank = [c for c in columns if c in docs.columns]
    metas = []
    for row in docs.to_dict("records"):
        meta = {c: row[c] for c in kept}
        if int(row["doc_id"]) in hidden:
            meta |= dict.fromkeys(blank)
        metas.append(meta)
    view = MotionDB.create(out).append_motions([db.motion(int(d)) for d in docs["doc_id"]], metas)
    if not np.array_equal(view.documents["doc_id"], docs["doc_id"]):
        raise ParameterError(f"{out}: the copy of {db.path} does not hold its documents in order")
    return view


def annotation_loop(engine, truth: pd.Series, label: str, *, variant: str = "one by one", page: int = PAGE,
                    target: float = TARGET, author: str = AUTHOR) -> pd.DataFrame:  # fmt: skip
    """The simulated annotator's loop for one class on ``engine``'s database (an :func:`annotator_view`): learn,
    search, review a page, label, learn again, until the target or until the search finds nothing new.

    Parameters
    ----------
    engine : Engine
        Over the annotator's view; the segment labels of the loop are written into its database.
    truth : pandas.Series
        The oracle: each document's true class, indexed by doc id (missing: of no class).
    label : str
        The class: a file-name label of the visible documents.
    variant : {"one by one", "whole page"}
        How a page is reviewed (:data:`VARIANTS`).
    page : int
        Hits per page (K).
    target : float
        The share of the class's unlabelled documents to label, in (0, 1].

    Returns
    -------
    pandas.DataFrame
        One row per reviewed hit, in review order: ``class``, ``variant``, ``round`` (1, 2, ...), ``rank`` (on its
        page), ``doc_id``, ``start``, ``end`` (frames of the document), ``normalised_cost``, ``correct`` (the hit
        lies in a document of the class), ``accepted``, ``reviewed`` (hits reviewed so far), ``labelled`` (the
        class's unlabelled documents labelled so far). ``attrs``: ``stop`` ("target" or "exhausted"),
        ``to_label`` (the class's unlabelled documents), ``needed`` (the target's count of them).
    """
    variant = one_of(variant, "variant", VARIANTS)
    page = count(page, "page")
    unlabelled = unlabelled_documents(engine.db)
    of_class = unlabelled[(truth.reindex(unlabelled) == label).fillna(False).to_numpy(bool)]
    needed = _needed(len(of_class), target)
    rows, labelled = [], set()
    round_ = 0
    while len(labelled) < needed:  # each round reviews at least one document not reviewed before
        round_ += 1
        hits = review_page(engine, engine.learn_template(label), unlabelled, label, page)
        if hits.empty:
            break
        correct = (truth.reindex(hits["doc_id"]) == label).fillna(False).to_numpy(bool)
        if variant == "one by one":  # the review stops at the hit that reaches the target
            found = np.cumsum(correct) + len(labelled)
            reached = np.flatnonzero(found >= needed)
            hits, correct = (hits.iloc[: reached[0] + 1], correct[: reached[0] + 1]) if len(reached) else (hits, correct)
        accepted = correct if variant == "one by one" else np.ones(len(hits), bool)
        engine.add_labels(hits[accepted], label=label, author=author, source="accepted hit")
        if not accepted.all():
            engine.add_labels(hits[~accepted], label=label, author=author, source="rejected hit")
        for i, (hit, ok, yes) in enumerate(zip(hits.itertuples(), correct, accepted)):
            labelled |= {hit.doc_id} if ok and yes else set()  # (a correct hit lies in one of ``of_class``)
            rows.append({"class": label, "variant": variant, "round": round_, "rank": i + 1, "doc_id": hit.doc_id,
                         "start": hit.start, "end": hit.end, "normalised_cost": hit.normalised_cost,
                         "correct": bool(ok), "accepted": bool(yes), "reviewed": len(rows) + 1,
                         "labelled": len(labelled)})  # fmt: skip
    stop = "target" if len(labelled) >= needed else "exhausted"
    trace = pd.DataFrame(rows, columns=_TRACE)
    trace.attrs |= {"stop": stop, "to_label": len(of_class), "needed": needed}
    return trace


_TRACE = ["class", "variant", "round", "rank", "doc_id", "start", "end", "normalised_cost", "correct", "accepted",
          "reviewed", "labelled"]  # fmt: skip


def unlabelled_documents(db) -> np.ndarray:
    """The doc ids without a file-name label, in document order."""
    docs = db.documents
    return docs.loc[docs["label"].isna().to_numpy(bool), "doc_id"].to_numpy(np.int64)


def _needed(n: int, target: float) -> int:
    """How many of ``n`` documents make ``target`` of them (rounded up; 0.9 of 10 is 9)."""
    if not 0 < target <= 1:
        raise ParameterError(f"target {target!r}: a share in (0, 1]")
    return math.ceil(round(target * n, 9))


def review_page(engine, template, unlabelled: np.ndarray, label: str, size: int) -> pd.DataFrame:
    """A page to review (the loop's, and the Motion templates page's "review round"): the best hit of each of the
    first ``size`` documents among ``unlabelled`` that carry no segment label of ``label`` yet (accepted or
    rejected), in the search's order: the search asks for more instances until it has them or has no more."""
    seen = set(engine.segment_labels(label=label)["doc_id"].astype(int))
    open_ = np.setdiff1d(unlabelled, list(seen))
    n = 4 * size
    while True:
        hits = engine.search_template(template, n_matches=n)
        fresh = hits[hits["doc_id"].isin(open_)].drop_duplicates("doc_id")
        if len(fresh) >= size or len(hits) < n:
            return fresh.head(size).reset_index(drop=True)
        n *= 4


def order_cost(classes, label: str, target: float = TARGET) -> int:
    """Documents reviewed, in the given order, until ``target`` of those of class ``label`` have been seen.

    Parameters
    ----------
    classes : sequence
        The true class of each document, in review order (missing: none).
    label : str
    target : float

    Returns
    -------
    int
        The 1-based position of the document that reaches the target (0 when the class has none).

    Examples
    --------
    >>> order_cost(["a", "b", "a", "b", "b", "a"], "a", target=0.6)  # 2 of 3: the second "a" is 3rd
    3
    """
    hits = np.flatnonzero(_of(classes, label))
    needed = _needed(len(hits), target)
    return int(hits[needed - 1] + 1) if needed else 0


def expected_random_cost(n_documents: int, n_class: int, target: float = TARGET) -> float:
    """The expected :func:`order_cost` of reviewing ``n_documents`` in a uniformly random order, ``n_class`` of
    them of the class: the m-th of them (m = the target's count) lies on average at m (N + 1) / (n + 1).

    Examples
    --------
    >>> expected_random_cost(6, 3, target=0.6)  # the 2nd of 3 among 6: 2 * 7 / 4
    3.5
    """
    needed = _needed(n_class, target)
    return needed * (n_documents + 1) / (n_class + 1)


def simulated_annotation(db, hidden, make_engine: Callable, work, *, group: str = "actor", classes=None,
                         page: int = PAGE, target: float = TARGET, variants=VARIANTS) -> dict:  # fmt: skip
    """The annotation loop on every class of ``db`` with the group ``hidden``'s classes hidden, both variants, and
    the baselines.

    Parameters
    ----------
    db : MotionDB
        Labelled (``label``) with a ``group`` column; not changed.
    hidden : str
        The value of ``group`` whose documents lose their class.
    make_engine : callable
        MotionDB -> Engine (``mocapviz.Engine``; the experiments sit below the engine and do not import it).
    work : str or os.PathLike
        A folder for the annotator's views: one copy per variant, ``<work>/<variant>.mdb``, holding the labels
        written (it must not hold those copies already).
    group : str
        The column ``hidden`` is a value of (HDM05: ``actor``; Bandai Namco: ``style``).
    classes : sequence of str, optional
        The classes annotated, in this order (default every label of the hidden documents that some visible
        document has too: the loop starts from those).
    page, target : int, float
        Hits per page, the share of each class's hidden documents to label.
    variants : sequence of str
        Of :data:`VARIANTS`.

    Returns
    -------
    dict
        - ``per_class``: one row per class: ``class``, ``to_label`` (its hidden documents), ``needed``, then for
          each variant (``one_by_one_``, ``whole_page_`` prefixes) ``reviewed`` (hits reviewed until the target,
          or in all when the search ran out), ``labelled``, ``precision`` (of its accepted hits), ``rounds``,
          ``stop``; ``document_order`` and ``random_order`` (the baselines' costs over the unlabelled documents in
          document order, expected in random order), ``unlabelled`` (the documents the annotator may review).
        - ``trace``: every reviewed hit (:func:`annotation_loop`'s rows of every class and variant).
        - ``curves``: reviewed against labelled per class, for the loop (each variant) and the document order.
        - ``summary``: one row per method: classes, classes reaching the target, total reviewed, mean precision.

        Each with a ``hidden`` column (``hidden``).

    Raises
    ------
    ParameterError
        No ``group`` column, no document of ``hidden``, or a class no visible document has.
    """
    from ..db.database import MotionDB

    docs = db.documents
    if group not in docs.columns:
        raise ParameterError(f"{db.path}: the documents have no {group} column")
    hidden_ids = docs.loc[docs[group].astype("string").eq(str(hidden)).fillna(False).to_numpy(bool), "doc_id"]
    if hidden_ids.empty:
        raise ParameterError(f"{db.path}: no document has {group} {hidden!r}")
    truth = docs.set_index("doc_id")["label"].astype("string")
    visible = set(truth.drop(hidden_ids).dropna())
    if classes is None:  # a class no visible document holds has no starting example
        classes = sorted(set(truth[hidden_ids].dropna()) & visible)
    classes = [str(c) for c in classes]
    if missing := [c for c in classes if c not in visible]:
        raise ParameterError(f"{db.path}: no document but those of {group} {hidden!r} has label {missing[0]!r}: "
                             "the loop has no example to start from")
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    view = annotator_view(db, hidden_ids, work / "view.mdb")
    order = truth.reindex(unlabelled_documents(view)).tolist()
    traces, rows = [], {c: _baselines(order, c, target) for c in classes}
    for variant in variants:
        engine = make_engine(MotionDB.open(shutil.copytree(view.path, work / f"{variant.replace(' ', '_')}.mdb")))
        for c in classes:
            trace = annotation_loop(engine, truth, c, variant=variant, page=page, target=target)
            traces.append(trace)
            rows[c] |= _loop_figures(trace, variant.replace(" ", "_"))
    trace = pd.concat(traces, ignore_index=True)
    per_class = pd.DataFrame(list(rows.values()))
    tables = {"per_class": per_class, "trace": trace, "curves": _curves(trace, order, classes),
              "summary": _summary(per_class, variants)}
    return {name: table.assign(hidden=str(hidden)) for name, table in tables.items()}


def _of(classes, label: str) -> np.ndarray:
    """Which of ``classes`` (a sequence of class names or missing values) are ``label``."""
    return pd.Series(list(classes), dtype="string").eq(label).fillna(False).to_numpy(bool)


def _baselines(order: list, label: str, target: float) -> dict:
    """A class's row of the per-class table before the loop: its unlabelled documents and the baselines' costs."""
    n_class = int(_of(order, label).sum())
    return {"class": label, "unlabelled": len(order), "to_label": n_class, "needed": _needed(n_class, target),
            "document_order": order_cost(order, label, target),
            "random_order": round(expected_random_cost(len(order), n_class, target), 2)}  # fmt: skip


def _loop_figures(trace: pd.DataFrame, prefix: str) -> dict:
    """A variant's columns of the per-class table: reviewed, labelled, precision, rounds, stop."""
    accepted = trace["correct"][trace["accepted"]]
    return {f"{prefix}_reviewed": len(trace), f"{prefix}_labelled": int(trace["labelled"].max()) if len(trace) else 0,
            f"{prefix}_precision": float(accepted.mean()) if len(accepted) else float("nan"),
            f"{prefix}_rounds": int(trace["round"].max()) if len(trace) else 0, f"{prefix}_stop": trace.attrs["stop"]}


def _curves(trace: pd.DataFrame, order: list, classes: list) -> pd.DataFrame:
    """Hits (documents) reviewed against the class's documents labelled, from (0, 0) to the end of each run:
    ``class``, ``method`` ("loop, one by one", "loop, whole page", "document order"), ``reviewed``,
    ``labelled``, ``share`` (of the class's unlabelled documents)."""
    parts = []
    for c in classes:
        seen = np.cumsum(_of(order, c))
        n_class = int(seen[-1]) if len(seen) else 0
        stop = order_cost(order, c, TARGET) if n_class else 0
        parts.append(pd.DataFrame({"class": c, "method": "document order", "reviewed": np.arange(stop + 1),
                                   "labelled": np.r_[0, seen[:stop]], "to_label": n_class}))  # fmt: skip
        for variant, run in trace[trace["class"] == c].groupby("variant", sort=False):
            parts.append(pd.DataFrame({"class": c, "method": f"loop, {variant}", "reviewed": np.r_[0, run["reviewed"]],
                                       "labelled": np.r_[0, run["labelled"]], "to_label": n_class}))  # fmt: skip
    curves = pd.concat(parts, ignore_index=True)
    curves["share"] = curves["labelled"] / curves.pop("to_label").where(lambda n: n > 0)
    return curves


def _summary(per_class: pd.DataFrame, variants) -> pd.DataFrame:
    """One row per method: ``classes``, ``reached`` (classes labelled to the target), ``reviewed`` (in all),
    ``precision`` (the mean of the classes')."""
    n = len(per_class)
    rows = [{"method": f"loop, {v}", "classes": n,
             "reached": int((per_class[f"{p}_stop"] == "target").sum()),
             "reviewed": int(per_class[f"{p}_reviewed"].sum()), "precision": per_class[f"{p}_precision"].mean()}
            for v, p in ((v, v.replace(" ", "_")) for v in variants)]  # fmt: skip
    rows.append({"method": "document order", "classes": n, "reached": n,
                 "reviewed": int(per_class["document_order"].sum()), "precision": 1.0})
    rows.append({"method": "random order (expected)", "classes": n, "reached": n,
                 "reviewed": float(per_class["random_order"].sum()), "precision": 1.0})
    return pd.DataFrame(rows)
