"""How well scene descriptions find what they describe (Müller, Röder & Clausen 2005 §6.3; issue 25, scope 4).

Three measurements of :func:`mocapviz.relational.scene.find`, each against a different kind of truth:

- **cut clips** (:func:`clip_quality`): a labelled clip (HDM05 cut clips, Bandai Namco 1) holds one motion of its
  class; a description *fires* on a clip when it has at least one hit there. Per description: precision and recall of
  the clips of its target classes (:data:`TARGETS`), and how often it fires on each other class;
- **long takes** (:func:`event_quality`): a hit is a true positive when it overlaps an annotated event of the same
  document not yet matched (greedy, best rank first, :func:`match_events`); used for the CMU martial-arts takes
  135_02 … 135_11 and the hand annotation ``tests/data/cmu135_kicks_punches.csv`` (:func:`read_annotations`);
- **composite streams** (:func:`composite_streams`, :func:`composite_quality`): documents made by concatenating real
  HDM05 cut clips of different classes in a known order (derived data: each next clip translated on the floor to
  continue where the previous ended, a short linear blend between them), searched with ``template:A then template:B
  within T s`` where the templates are learned from *other* actors, and the reversed order;
- **derived CMU streams** (:func:`cmu_sequence_streams`, :func:`cmu_sequence_quality`): the annotated takes hold no
  kick followed by a punch, so every annotated kick and punch is cut from its take with a margin of its own motion
  and the cuts are concatenated kick-punch, punch-kick and alone (derived documents, cut and concatenated), for
  ``kick_right then punch_left within 2 s`` with a frame-exact truth.

clip_quality        db, descriptions -> per-description precision / recall / fire rates on labelled cut clips.
match_events        hits, events -> greedy one-to-one matching of hits to annotated intervals.
event_quality       db, descriptions, events -> precision and recall per description on long takes.
read_annotations    the hand annotation CSV (file, event, side, start, end, certain, note).
sequence_events     annotated events -> "X followed by Y within T s" events (the truth of a sequence query).
composite_streams   a labelled MotionDB -> concatenated derived streams (motions, metas, truth).
composite_quality   templates of other actors, "A then B" on the streams -> F1, and the hits of "B then A".
cmu_sequence_streams  the annotated CMU kicks and punches cut with margins -> derived kick-punch / punch-kick / single
                    streams with frame-exact events.
cmu_sequence_quality  "kick then punch within 2 s" on those derived streams -> precision, recall, F1.

References
----------
.. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH 2005,
   §6.3 "Towards scene descriptions", Fig. 10.
.. [2] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture data.
   SCA 2006 (the templates of ``template:NAME`` atoms).
"""
from __future__ import annotations

import contextlib
import re
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..validation import number

__all__ = ["CMU_SEQUENCE_QUERIES", "CMU_TAKES", "SIDES", "TARGETS", "clip_quality", "cmu_sequence_quality",
           "cmu_sequence_streams", "composite_quality", "composite_streams", "event_quality", "match_events",
           "read_annotations", "sequence_events"]

# description -> the labels (HDM05 ``class``, Bandai Namco 1 ``content``) of the cut clips it should fire on; a
# description missing here has no labelled class in the shared data (its fire rate is reported, nothing else)
TARGETS = {
    "kick_right": ("kick",),
    "kick_left": ("kickLFront1Reps",),
    "punch_right": ("punch",),
    "punch_left": ("punch",),
    "jump": ("hopBothLegs1hops",),
    "hop": ("hopBothLegs1hops",),
    "squat": ("squat1Reps",),
    "lie_down": ("lieDownFloor",),
    "throw": ("throwBasketball",),
    "wave": ("bye", "byebye"),
    "walk_step": ("walk", "walk-left", "walk-right", "walk-back", "sneak2StepsLStart", "jogLeftCircle4StepsRstart"),
}  # fmt: skip
# the side of the clips whose class holds both sides, found by looking at their feature runs (the Bandai kick clip
# kicks with the right foot three times; punch 001 punches five times with the left hand, 002 with the right);
# a ``*_left`` / ``*_right`` description's targets are the clips of its class on its side or of unknown side
SIDES = {"dataset-1_kick_normal_001": "right", "dataset-1_punch_normal_001": "left",
         "dataset-1_punch_normal_002": "right"}  # fmt: skip
# the CMU martial-arts takes (subject 135) with kicks and punches, by document name
CMU_TAKES = tuple(f"135_{k:02d}" for k in range(2, 12))


def _side(name: str) -> str | None:
    found = re.search(r"_(left|right)$", name)
    return found.group(1) if found else None


def _indexes(db, relational_set: str, indexes):
    if indexes is not None:
        return indexes
    from ..relational.index import load_or_build

    return load_or_build(db, relational_set, progress=False)


def clip_quality(db, descriptions=None, targets=None, label_column: str = "label", relational_set: str = "2005",
                 indexes: dict | None = None, sides: dict | None = None) -> dict:  # fmt: skip
    """Precision and recall of scene descriptions on labelled cut clips, and how often each fires elsewhere.

    A description *fires* on a clip when :func:`~mocapviz.relational.scene.find` returns at least one hit in it.
    The clips it should fire on are those whose label is one of its target classes (and, for a ``*_left`` /
    ``*_right`` description, whose side in ``sides`` is its own or unknown). Only labelled clips are judged: a
    take without a label (a lab's own, beside an archive's clips) counts nowhere, and every table's
    ``attrs["unlabelled"]`` says how many were left out.

    Parameters
    ----------
    db : MotionDB
        Labelled cut clips (one motion each), e.g. the HDM05 cut clips or Bandai Namco 1.
    descriptions : dict or sequence of str, optional
        Name -> description text, or names of shipped descriptions; default every shipped description.
    targets : dict, optional
        Name -> tuple of labels it should fire on (default :data:`TARGETS`); labels not in ``db`` are ignored.
    label_column : str
        The documents' column holding the class.
    relational_set : {"2005", "2006"}
        The set the descriptions are read in (the shipped library: 2005).
    indexes : dict, optional
        Group -> InvertedIndex of ``db`` (default: loaded, or built and saved).
    sides : dict, optional
        Document name -> "left" / "right" (default :data:`SIDES`).

    Returns
    -------
    dict
        Name -> pandas.DataFrame:

        - ``per_description``: one row per description: ``description``, ``classes`` (its target labels present
          in ``db``, "; "-joined, "" when none), ``clips`` (target clips), ``fired`` (clips with a hit), ``tp``,
          ``precision`` (tp / fired; NaN when it fires nowhere or has no target clip), ``recall`` (tp / clips;
          NaN without target clips), ``f1``, ``fire_rate`` (share of all clips it fires on), ``fire_rate_other``
          (share of the non-target clips it fires on), ``worst_other`` (the other class it fires on most, with
          its rate), ``hits`` (hits in all clips), ``ms`` (the search's time).
        - ``fire_rates``: description × class (index: description), the share of the class's clips it fires on.
        - ``fired``: one row per (description, clip with a hit): ``description``, ``doc_id``, ``name``, ``class``,
          ``hits``, ``target``.

    Raises
    ------
    ParameterError
        ``db`` has no ``label_column``, or a description cannot be read.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> q = clip_quality(db, ["kick_left", "squat"])["per_description"]
    >>> print(q[["description", "clips", "fired", "tp", "recall"]].to_string(index=False))
    description  clips  fired  tp  recall
      kick_left      2      2   2     1.0
          squat      2      3   2     1.0
    """
    from ..relational.description import named_descriptions
    from ..relational.scene import find

    docs = db.documents
    if label_column not in docs.columns:
        raise ParameterError(f"{db.path}: the documents have no {label_column!r} column")
    judged = docs[label_column].notna().to_numpy()
    docs = docs[judged].reset_index(drop=True)  # a take without a label is neither a target nor an other clip
    targets = TARGETS if targets is None else dict(targets)
    sides = SIDES if sides is None else dict(sides)
    if descriptions is None:
        descriptions = list(named_descriptions(relational_set))
    if not isinstance(descriptions, dict):
        descriptions = {name: name for name in descriptions}
    indexes = _indexes(db, relational_set, indexes)
    labels = docs[label_column].astype(str).to_numpy()
    names = docs["name"].astype(str).to_numpy()
    present = set(labels)
    rows, fired_rows, rates = [], [], {}
    for name, text in descriptions.items():
        t0 = time.perf_counter()
        hits = find(db, text, relational_set=relational_set, indexes=indexes)
        ms = 1e3 * (time.perf_counter() - t0)
        hits = hits[hits["doc_id"].isin(docs["doc_id"])]
        counts = hits.groupby("doc_id").size()
        fired = docs["doc_id"].isin(counts.index).to_numpy()
        classes = [c for c in targets.get(name, ()) if c in present]
        side = _side(name)
        target = np.isin(labels, classes)
        if side is not None:
            target &= np.array([sides.get(n, side) == side for n in names])
        tp = int((fired & target).sum())
        n_target, n_fired = int(target.sum()), int(fired.sum())
        precision = tp / n_fired if n_target and n_fired else np.nan
        recall = tp / n_target if n_target else np.nan
        f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else np.nan
        per_class = pd.Series(fired, index=labels).groupby(level=0).mean()
        rates[name] = per_class
        # "elsewhere": the classes that are not targets (a target class's clips of the other side count as other)
        other = ~np.isin(labels, classes)
        worst = per_class[[c for c in per_class.index if c not in classes]]
        rows.append({"description": name, "classes": "; ".join(classes), "clips": n_target, "fired": n_fired,
                     "tp": tp, "precision": precision, "recall": recall, "f1": f1,
                     "fire_rate": float(fired.mean()) if len(fired) else np.nan,
                     "fire_rate_other": float(fired[other].mean()) if other.any() else np.nan,
                     "worst_other": f"{worst.idxmax()} {worst.max():.2f}" if len(worst) and worst.max() > 0 else "",
                     "hits": len(hits), "ms": ms})  # fmt: skip
        for i in np.flatnonzero(fired):
            fired_rows.append({"description": name, "doc_id": int(docs["doc_id"].iloc[i]), "name": names[i],
                               "class": labels[i], "hits": int(counts[docs["doc_id"].iloc[i]]),
                               "target": bool(target[i])})  # fmt: skip
    fire_rates = pd.DataFrame(rates).T
    fire_rates.index.name = "description"
    out = {"per_description": pd.DataFrame(rows), "fire_rates": fire_rates,
           "fired": pd.DataFrame(fired_rows, columns=["description", "doc_id", "name", "class", "hits", "target"])}
    for frame in out.values():
        frame.attrs["unlabelled"] = int((~judged).sum())
    return out


# ================================================================================================ long takes
ANNOTATION_COLUMNS = ["file", "event", "side", "start", "end", "certain", "note"]


def match_events(hits: pd.DataFrame, events: pd.DataFrame) -> dict:
    """Match hits to annotated events one to one: each hit, best rank first, takes the not yet matched event of its
    document that it overlaps most (ties: the earliest event); a hit that overlaps none is a false positive.

    Parameters
    ----------
    hits : pandas.DataFrame
        The hit table (``rank``, ``doc_id``, ``start``, ``end``: in-document frames, half-open); without ``rank``
        the row order is the rank.
    events : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` (in-document frames, half-open), one row per annotated event.

    Returns
    -------
    dict
        ``hits``, ``events``, ``tp`` (matched hits = matched events), ``precision`` (tp / hits, NaN without hits),
        ``recall`` (tp / events, NaN without events), ``f1``, and ``matched``: for every hit (in rank order) the
        row position of its event in ``events``, or -1 (np.ndarray [shape=(hits,)], int).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3.

    Examples
    --------
    >>> hits = pd.DataFrame({"rank": [1, 2, 3], "doc_id": [0, 0, 1], "start": [10, 12, 0], "end": [20, 30, 5]})
    >>> events = pd.DataFrame({"doc_id": [0, 0], "start": [15, 25], "end": [40, 35]})
    >>> m = match_events(hits, events)
    >>> m["matched"].tolist(), m["tp"], m["precision"], m["recall"]
    ([0, 1, -1], 2, 0.6666666666666666, 1.0)
    """
    for frame, what in ((hits, "hits"), (events, "events")):
        missing = {"doc_id", "start", "end"} - set(frame.columns)
        if missing:
            raise ParameterError(f"{what} need the columns doc_id, start, end; missing {sorted(missing)}")
    order = np.argsort(hits["rank"].to_numpy(), kind="stable") if "rank" in hits.columns else np.arange(len(hits))
    h_doc, h_s, h_e = (hits[c].to_numpy(np.int64)[order] for c in ("doc_id", "start", "end"))
    e_doc, e_s, e_e = (events[c].to_numpy(np.int64) for c in ("doc_id", "start", "end"))
    free = np.ones(len(events), dtype=bool)
    matched_sorted = np.full(len(hits), -1, dtype=np.int64)
    for i in range(len(hits)):
        overlap = np.minimum(e_e, h_e[i]) - np.maximum(e_s, h_s[i])
        ok = free & (e_doc == h_doc[i]) & (overlap > 0)
        if ok.any():
            best = np.flatnonzero(ok)[np.lexsort((e_s[ok], -overlap[ok]))[0]]
            free[best] = False
            matched_sorted[i] = best
    matched = np.empty_like(matched_sorted)
    matched[order] = matched_sorted
    tp = int((matched >= 0).sum())
    precision = tp / len(hits) if len(hits) else np.nan
    recall = tp / len(events) if len(events) else np.nan
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else np.nan
    return {"hits": len(hits), "events": len(events), "tp": tp, "precision": precision, "recall": recall, "f1": f1,
            "matched": matched}  # fmt: skip


def read_annotations(path, db=None) -> pd.DataFrame:
    """A hand annotation of events in long takes (e.g. ``tests/data/cmu135_kicks_punches.csv``).

    Parameters
    ----------
    path : str or os.PathLike
        CSV with the columns ``file`` (the take's file name or path; its stem is the document's name), ``event``,
        ``side``, ``start``, ``end`` (in-document frames at the take's own rate, half-open), ``certain``, ``note``.
    db : MotionDB, optional
        When given, every row's take must be a document of ``db`` and its frames inside it; ``doc_id`` is added.

    Returns
    -------
    pandas.DataFrame
        The rows, with ``name`` (the file's stem) and, with ``db``, ``doc_id``.

    Raises
    ------
    ParameterError
        A missing column, ``start >= end``, a negative frame, or (with ``db``) an unknown take or a frame past its
        end.
    """
    table = pd.read_csv(path)
    missing = [c for c in ANNOTATION_COLUMNS[:5] if c not in table.columns]
    if missing:
        raise ParameterError(f"{path}: missing column(s) {missing}; expected {', '.join(ANNOTATION_COLUMNS)}")
    table["event"] = table["event"].astype(str).str.strip().str.lower()
    table["side"] = table["side"].astype(str).str.strip().str.lower()
    table["name"] = [Path(str(f)).stem for f in table["file"]]
    bad = table[(table["start"] < 0) | (table["start"] >= table["end"])]
    if len(bad):
        raise ParameterError(f"{path}: rows {list(bad.index)} need 0 <= start < end")
    if db is not None:
        docs = db.documents.set_index("name")
        unknown = sorted(set(table["name"]) - set(docs.index))
        if unknown:
            raise ParameterError(f"{path}: takes {unknown} are not documents of {db.path}")
        table["doc_id"] = docs.loc[table["name"], "doc_id"].to_numpy()
        past = table[table["end"].to_numpy() > docs.loc[table["name"], "n_frames"].to_numpy()]
        if len(past):
            raise ParameterError(f"{path}: rows {list(past.index)} end after their take's last frame")
    return table


def sequence_events(events: pd.DataFrame, first: dict, second: dict, within: float, fps: float) -> pd.DataFrame:
    """The truth of a sequence query ``A then B within T s`` from annotated events: every event matching ``first``
    that is followed, in the same document, by an event matching ``second`` starting at or after its end and at most
    ``within`` seconds later gives one event, from its start to the end of the first such follower.

    Parameters
    ----------
    events : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` (half-open frames) and the columns ``first`` / ``second`` select on.
    first, second : dict
        Column -> value (or tuple of values) an event must have, e.g. ``{"event": "kick", "side": "right"}``.
    within : float
        Seconds, >= 0.
    fps : float
        The documents' frame rate.

    Returns
    -------
    pandas.DataFrame
        ``doc_id``, ``start``, ``end``, ``first_row``, ``second_row`` (row labels in ``events``).

    Examples
    --------
    >>> ev = pd.DataFrame({"doc_id": [0, 0, 0, 1], "event": ["kick", "punch", "punch", "punch"],
    ...                    "start": [0, 130, 200, 0], "end": [100, 150, 220, 10]})
    >>> sequence_events(ev, {"event": "kick"}, {"event": "punch"}, 2.0, 120.0)
       doc_id  start  end  first_row  second_row
    0       0      0  150          0           1
    """
    within = number(within, "within (seconds)", 0.0)

    def chosen(spec):
        keep = np.ones(len(events), dtype=bool)
        for column, value in spec.items():
            values = value if isinstance(value, (tuple, list, set)) else (value,)
            keep &= events[column].isin(values).to_numpy()
        return events[keep]

    a, b = chosen(first), chosen(second)
    rows = []
    for label, row in a.iterrows():
        gap = b["start"] - row["end"]
        follow = b[(b["doc_id"] == row["doc_id"]) & (gap >= 0) & (gap <= within * fps + 1e-9)]
        if len(follow):
            nxt = follow.sort_values(["start", "end"]).iloc[0]
            rows.append({"doc_id": int(row["doc_id"]), "start": int(row["start"]), "end": int(nxt["end"]),
                         "first_row": label, "second_row": nxt.name})  # fmt: skip
    return pd.DataFrame(rows, columns=["doc_id", "start", "end", "first_row", "second_row"])


# the queries measured on the CMU takes: name -> (description, the annotated events it should find)
CMU_QUERIES = {
    "kick_right": ("kick_right", {"event": "kick", "side": "right"}, None),
    "kick_left": ("kick_left", {"event": "kick", "side": "left"}, None),
    "kick (either side)": ("kick_left | kick_right", {"event": "kick"}, None),
    "punch_left": ("punch_left", {"event": "punch", "side": "left"}, None),
    "punch_right": ("punch_right", {"event": "punch", "side": "right"}, None),
    "punch (either side)": ("punch_left | punch_right", {"event": "punch"}, None),
    "kick_right then punch_left within 2 s": ("kick_right then punch_left within 2 s",
                                              {"event": "kick", "side": "right"}, {"event": "punch", "side": "left"}),
    "kick then punch within 2 s": ("(kick_left | kick_right) then (punch_left | punch_right) within 2 s",
                                   {"event": "kick"}, {"event": "punch"}),
}  # fmt: skip


def event_quality(db, annotations: pd.DataFrame, queries: dict | None = None, within: float = 2.0,
                  certain_only: bool = False, indexes: dict | None = None, relational_set: str = "2005") -> dict:  # fmt: skip
    """Precision and recall of descriptions on long takes against interval annotations (:func:`match_events`).

    Only the hits in the annotated takes count (a take with no annotated event of a kind still counts: its hits
    are false positives).

    Parameters
    ----------
    db : MotionDB
        Holding the annotated takes (e.g. the CMU trials at 120 Hz).
    annotations : pandas.DataFrame
        :func:`read_annotations` with ``db`` (``doc_id`` column).
    queries : dict, optional
        Name -> (description, selection of the first events, selection of the second events or None); with a
        second selection the truth is :func:`sequence_events` within ``within`` s. Default :data:`CMU_QUERIES`.
    within : float
        The sequences' time limit in seconds (the truth's; the description says its own).
    certain_only : bool
        Use only the rows marked certain as truth (the uncertain ones are then neither counted nor penalised:
        hits matching them are dropped).
    indexes : dict, optional
        The relational indexes of ``db`` (default: loaded or built).
    relational_set : {"2005", "2006"}

    Returns
    -------
    dict
        ``summary``: one row per query: ``query``, ``description``, ``events``, ``hits``, ``tp``, ``precision``,
        ``recall``, ``f1``; ``hits``: every hit in the takes with ``query`` and ``matched`` (the annotation row it
        matched, -1 for none).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §1 and §6.3 ("a kick of the right foot followed by a punch").
    """
    from ..relational.scene import find

    queries = CMU_QUERIES if queries is None else queries
    if "doc_id" not in annotations.columns:
        raise ParameterError("annotations need a doc_id column: read them with read_annotations(path, db)")
    indexes = _indexes(db, relational_set, indexes)
    takes = set(annotations["doc_id"])
    fps = db.documents.set_index("doc_id")["fps"]
    truth_rows = annotations
    dropped = annotations.iloc[0:0]
    if certain_only and "certain" in annotations.columns:
        sure = annotations["certain"].astype(str).str.lower().isin(["1", "true", "yes", "y"])
        truth_rows, dropped = annotations[sure], annotations[~sure]
    rows, all_hits = [], []
    for name, (text, first, second) in queries.items():
        hits = find(db, text, relational_set=relational_set, indexes=indexes)
        hits = hits[hits["doc_id"].isin(takes)].reset_index(drop=True)
        if second is None:
            sel = np.ones(len(truth_rows), dtype=bool)
            for column, value in first.items():
                sel &= truth_rows[column].isin(value if isinstance(value, (tuple, list)) else (value,)).to_numpy()
            truth = truth_rows[sel][["doc_id", "start", "end"]]
        else:
            rate = float(fps.loc[list(takes)].iloc[0])
            truth = sequence_events(truth_rows, first, second, within, rate)[["doc_id", "start", "end"]]
        if len(dropped):  # hits on uncertain events are left out, not counted as false
            unsure = match_events(hits, dropped[["doc_id", "start", "end"]])["matched"]
            hits = hits[unsure < 0].reset_index(drop=True)
        m = match_events(hits, truth.reset_index(drop=True))
        rows.append({"query": name, "description": text, "events": m["events"], "hits": m["hits"], "tp": m["tp"],
                     "precision": m["precision"], "recall": m["recall"], "f1": m["f1"]})  # fmt: skip
        all_hits.append(hits.assign(query=name, matched=m["matched"]))
    hits = pd.concat(all_hits, ignore_index=True) if all_hits else pd.DataFrame()
    return {"summary": pd.DataFrame(rows), "hits": hits}


# ================================================================================================ composite streams
# (A, B) class pairs of the composite streams: "template:A then template:B" should find every A clip followed by B
PAIRS = (("kickLFront1Reps", "squat1Reps"), ("squat1Reps", "hopBothLegs1hops"),
         ("throwBasketball", "kickLFront1Reps"))  # fmt: skip


def _concatenate(clips: list, blend: int):
    """Positions of clips joined end to start: each next clip translated on the floor (x, z) so that its first
    root position continues the previous clip's last one, the ``blend`` frames where they meet mixed linearly.
    Returns (positions [shape=(sum(T) - blend * (len(clips) - 1), J, 3)], the start of each clip in them)."""
    out = clips[0].astype(np.float32).copy()
    starts = [0]
    for clip in clips[1:]:
        clip = clip.astype(np.float32).copy()
        shift = out[-1, 0, :] - clip[0, 0, :]
        clip[:, :, 0] += shift[0]
        clip[:, :, 2] += shift[2]
        if blend:
            w = (np.arange(1, blend + 1, dtype=np.float32) / (blend + 1))[:, None, None]
            out[-blend:] = (1 - w) * out[-blend:] + w * clip[:blend]
            starts.append(len(out) - blend)
            out = np.concatenate([out, clip[blend:]])
        else:
            starts.append(len(out))
            out = np.concatenate([out, clip])
    return out, starts


def composite_streams(db, pairs=PAIRS, actors=None, repeats: int = 2, within: float = 2.0, blend_s: float = 0.1,
                      seed: int = 0, group: str = "actor") -> tuple[list, list, pd.DataFrame]:  # fmt: skip
    """Documents made of real labelled cut clips in a known order, for ``A then B within T s`` with known truth.

    For every pair (A, B) and actor, one stream: ``repeats`` times an A clip, then a B clip, then filler clips of
    the other classes of the pair list and of neither class, until the filler lasts more than ``within`` s (so that
    no B is followed by an A within ``within`` s: the reversed query has no true hit). All clips of one stream are
    the actor's own, drawn without replacement (seeded). Each next clip is translated on the floor to continue where
    the previous one ended (its heading is kept) and the two overlap in a linear blend of ``blend_s`` seconds.
    These are **derived** documents (labelled ``derived = "concatenated HDM05 cut clips"``), not recordings.

    Parameters
    ----------
    db : MotionDB
        Labelled cut clips with a ``group`` column (HDM05: ``label`` = class, ``actor``), one frame rate.
    pairs : sequence of (str, str)
        The (A, B) classes.
    actors : sequence of str, optional
        Default every actor with at least ``repeats`` clips of A and of B.
    repeats : int
        A-B pairs per stream, >= 1.
    within : float
        The filler between a B and the next A lasts more than this (seconds).
    blend_s : float
        The blend between consecutive clips in seconds (0: cut), rounded to frames.
    seed : int
        The clips' random choice.
    group : str
        The actor column.

    Returns
    -------
    motions : list of Motion
        One per stream, canonical positions, at ``db.fps``, no rotations.
    metas : list of dict
        One per stream: ``name`` (``composite_<A>_<B>_<actor>``), ``label`` ("composite"), ``actor``, ``first``,
        ``second``, ``derived``, ``clips`` (the source documents' names, in order), ``blend_s``.
    parts : pandas.DataFrame
        One row per clip of every stream: ``stream`` (index into ``motions``), ``name`` (the stream's), ``order``,
        ``doc_id`` (source), ``class``, ``role`` ("A", "B" or "filler"), ``start``, ``end`` (in-stream frames,
        half-open; consecutive clips share their ``blend`` frames), ``frames`` (the source clip's length).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> motions, metas, parts = composite_streams(db, [("kickLFront1Reps", "squat1Reps")], repeats=1)
    >>> [m["name"] for m in metas]
    ['composite_kickLFront1Reps_squat1Reps_dg', 'composite_kickLFront1Reps_squat1Reps_mm']
    >>> first = parts[parts["stream"] == 0]  # A, B: the clips' frames less one 0.1 s blend (12 frames at 120 Hz)
    >>> bool(motions[0].n_frames == first["frames"].sum() - 12), first["role"].tolist()
    (True, ['A', 'B'])
    """
    from ..motion.motion import Motion
    from ..motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS

    within = number(within, "within (seconds)", 0.0)
    blend_s = number(blend_s, "blend_s (seconds)", 0.0, 1.0)
    if int(repeats) != repeats or repeats < 1:
        raise ParameterError(f"repeats must be a whole number >= 1; got {repeats!r}")
    docs = db.documents
    if group not in docs.columns:
        raise ParameterError(f"{db.path}: the documents have no {group!r} column")
    fps = float(docs["fps"].iloc[0])
    if not np.allclose(docs["fps"], fps):
        raise ParameterError(f"{db.path}: documents at several frame rates; ingest at one rate (fps=...)")
    blend = round(blend_s * fps)
    rng = np.random.default_rng(seed)
    motions, metas, parts = [], [], []
    for a, b in pairs:
        if a == b:
            raise ParameterError(f"a pair of one class ({a}) has no order to reverse")
        for actor in sorted(map(str, docs[group].dropna().unique())) if actors is None else list(actors):
            mine = docs[docs[group].astype(str) == actor]
            pool = {c: list(rng.permutation(mine.loc[mine["label"] == c, "doc_id"].to_numpy())) for c in (a, b)}
            if min(len(pool[a]), len(pool[b])) < repeats:
                if actors is None:
                    continue
                raise ParameterError(f"actor {actor} has fewer than {repeats} clips of {a} or {b}")
            others = mine[~mine["label"].isin([a, b])]
            fill_pool = list(rng.permutation(others["doc_id"].to_numpy()))
            order = []
            for k in range(repeats):
                order += [(pool[a].pop(), "A"), (pool[b].pop(), "B")]
                if k < repeats - 1:
                    filled = 0.0
                    while filled <= within + 2 * blend / fps:
                        if not fill_pool:
                            raise ParameterError(f"actor {actor}: not enough clips of other classes to fill between "
                                                 "the pairs")  # fmt: skip
                        doc = fill_pool.pop()
                        order.append((doc, "filler"))
                        filled += float(docs.loc[docs["doc_id"] == doc, "n_frames"].iloc[0]) / fps - blend / fps
            clips = [np.asarray(db.motion(int(d)).positions) for d, _ in order]
            positions, starts = _concatenate(clips, blend)
            name = f"composite_{a}_{b}_{actor}"
            labels = docs.set_index("doc_id")["label"]
            for k, ((d, role), s, clip) in enumerate(zip(order, starts, clips)):
                parts.append({"stream": len(motions), "name": name, "order": k, "doc_id": int(d),
                              "class": str(labels.loc[d]), "role": role, "start": int(s), "end": int(s + len(clip)),
                              "frames": len(clip)})  # fmt: skip
            motions.append(Motion(positions=positions, fps=fps, joint_names=CANONICAL_JOINTS,
                                  parents=CANONICAL_PARENTS, source=name, labels={"label": "composite"}))  # fmt: skip
            metas.append({"name": name, "label": "composite", "actor": actor, "first": a, "second": b,
                          "derived": "concatenated HDM05 cut clips", "blend_s": blend / fps,
                          "clips": " ".join(str(docs.loc[docs["doc_id"] == d, "name"].iloc[0]) for d, _ in order)})
    if not motions:
        raise ParameterError(f"no actor has {repeats} clips of both classes of any pair of {list(pairs)}")
    return motions, metas, pd.DataFrame(parts)


def composite_truth(parts: pd.DataFrame, within: float, fps: float) -> pd.DataFrame:
    """The events of ``A then B within T s`` in composite streams: every A clip followed by a B clip that starts
    (in the stream) at most ``within`` s after the A clip ends — from the A clip's start to the B clip's end.

    Parameters
    ----------
    parts : pandas.DataFrame
        :func:`composite_streams`' parts, with ``doc_id`` replaced by the stream's document id in column
        ``stream_doc``.
    within : float
        Seconds.
    fps : float
        The streams' rate.

    Returns
    -------
    pandas.DataFrame
        ``doc_id`` (the stream's), ``start``, ``end``.
    """
    rows = []
    for _, clips in parts.sort_values(["stream", "order"]).groupby("stream"):
        a = clips[clips["role"] == "A"]
        b = clips[clips["role"] == "B"]
        for _, x in a.iterrows():
            follow = b[(b["order"] > x["order"]) & (b["start"] - x["end"] <= within * fps)]
            if len(follow):
                y = follow.iloc[0]
                rows.append({"doc_id": int(x["stream_doc"]), "start": int(x["start"]), "end": int(y["end"])})
    return pd.DataFrame(rows, columns=["doc_id", "start", "end"])


@contextlib.contextmanager
def _streams_db(motions: list, metas: list, folder, name: str):
    """A MotionDB ``name`` of derived stream documents in ``folder`` (kept), or in a temporary folder removed on exit,
    and {document name: doc_id}."""
    from ..db.database import MotionDB

    with contextlib.ExitStack() as stack:
        if folder is None:
            folder = stack.enter_context(tempfile.TemporaryDirectory(prefix=f"mocapviz-{name}-"))
        streams = MotionDB.create(Path(folder) / f"{name}.mdb").append_motions(motions, metas)
        yield streams, dict(zip(streams.documents["name"], streams.documents["doc_id"]))


def composite_quality(db, pairs=PAIRS, within: float = 2.0, template_cost: float | None = None,
                      relational_set: str = "2006", repeats: int = 2, actors=None, blend_s: float = 0.1, seed: int = 0,
                      folder=None, progress: bool = False) -> dict:  # fmt: skip
    """``template:A then template:B within T s`` on composite streams (:func:`composite_streams`), with templates
    learned from the *other* actors, against the known truth; and the reversed query, which should find nothing.

    Parameters
    ----------
    db : MotionDB
        Labelled HDM05 cut clips with ``actor`` (one frame rate; 30 Hz is the templates' usual rate).
    pairs : sequence of (str, str)
        The (A, B) classes.
    within : float
        T in seconds, used by the query and the truth.
    template_cost : float, optional
        The template atoms' largest normalised cost (:func:`mocapviz.relational.scene.find`); default each template's
        learned threshold (``meta["threshold"]``, :func:`mocapviz.relational.templates.separating_threshold`).
    relational_set : {"2005", "2006"}
        The templates' features.
    repeats, actors, blend_s, seed
        As :func:`composite_streams`.
    folder : str or os.PathLike, optional
        Where the streams' MotionDB (``composite.mdb``, with the templates stored under ``<class>-without-<actor>``)
        is made and kept; default a temporary folder, removed afterwards.
    progress : bool
        Print one line per stream.

    Returns
    -------
    dict
        ``per_stream``: one row per stream: ``stream``, ``first``, ``second``, ``actor``, ``frames``, ``events``,
        ``hits``, ``tp``, ``precision``, ``recall``, ``f1``, ``reversed_hits`` (hits of ``template:B then
        template:A``; every stream is built so that it has no true one); ``per_pair``: the same summed per (A, B);
        ``summary``: one row over all streams (``f1`` from the summed counts); ``parts``: the streams' clips;
        ``hits``: every hit with ``query`` ("forward" / "reversed") and ``matched``.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3 ("followed by").
    .. [2] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006.
    """
    from ..features import relational_features
    from ..relational.index import build
    from ..relational.scene import find
    from ..relational.templates import learn_class, store_template

    motions, metas, parts = composite_streams(db, pairs, actors, repeats, within, blend_s, seed)
    with _streams_db(motions, metas, folder, "composite") as (streams, doc_of):
        parts["stream_doc"] = [doc_of[n] for n in parts["name"]]
        fps = float(streams.documents["fps"].iloc[0])
        indexes = build(streams, relational_set, progress=False, save=False)
        stream_values, _ = relational_features(streams, relational_set, progress=False)
        source_values, _ = relational_features(db, relational_set, progress=False)
        all_actors = sorted(map(str, db.documents["actor"].dropna().unique()))
        learned = {}
        rows, all_hits = [], []
        for meta in metas:
            a, b, actor = meta["first"], meta["second"], meta["actor"]
            for c in (a, b):
                if (c, actor) not in learned:
                    others = [x for x in all_actors if x != actor]
                    template = learn_class(db, c, others, relational_set, source_values)
                    learned[(c, actor)] = store_template(streams, template, f"{c}-without-{actor}").stem
            ta, tb = learned[(a, actor)], learned[(b, actor)]
            doc = doc_of[meta["name"]]
            truth = composite_truth(parts[parts["name"] == meta["name"]], within, fps)
            row = {"stream": meta["name"], "first": a, "second": b, "actor": actor,
                   "frames": int(streams.documents.loc[streams.documents["doc_id"] == doc, "n_frames"].iloc[0])}
            for query, text in (("forward", f"template:{ta} then template:{tb} within {within:g} s"),
                                ("reversed", f"template:{tb} then template:{ta} within {within:g} s")):  # fmt: skip
                hits = find(streams, text, template_cost=template_cost, indexes=indexes, values=stream_values)
                hits = hits[hits["doc_id"] == doc].reset_index(drop=True)
                if query == "forward":
                    m = match_events(hits, truth)
                    row.update(events=m["events"], hits=m["hits"], tp=m["tp"], precision=m["precision"],
                               recall=m["recall"], f1=m["f1"])  # fmt: skip
                    matched = m["matched"]
                else:
                    row["reversed_hits"] = len(hits)
                    matched = np.full(len(hits), -1)
                all_hits.append(hits.assign(query=query, stream=meta["name"], matched=matched))
            rows.append(row)
            if progress:
                print(f"{meta['name']}: {row['tp']}/{row['events']} found, {row['hits']} hits, "
                      f"{row['reversed_hits']} reversed")  # fmt: skip
    per_stream = pd.DataFrame(rows)

    def summed(frame: pd.DataFrame) -> pd.Series:
        tp, hits, events = frame["tp"].sum(), frame["hits"].sum(), frame["events"].sum()
        p = tp / hits if hits else np.nan
        r = tp / events if events else np.nan
        return pd.Series({"streams": len(frame), "events": events, "hits": hits, "tp": tp, "precision": p,
                          "recall": r, "f1": 2 * p * r / (p + r) if p + r > 0 else np.nan,
                          "reversed_hits": frame["reversed_hits"].sum()})  # fmt: skip

    per_pair = per_stream.groupby(["first", "second"], sort=False).apply(summed, include_groups=False).reset_index()
    summary = summed(per_stream).to_frame().T.assign(within_s=within, template_cost="learned" if template_cost is None else template_cost,
                                                      blend_s=metas[0]["blend_s"])  # fmt: skip
    return {"per_stream": per_stream, "per_pair": per_pair, "summary": summary, "parts": parts,
            "hits": pd.concat(all_hits, ignore_index=True)}


# ================================================================================================ CMU sequence streams
# the sequence queries measured on the derived CMU streams: name -> (description, first events, second events)
CMU_SEQUENCE_QUERIES = {
    "kick_right then punch_left within 2 s": ("kick_right then punch_left within 2 s",
                                              {"event": "kick", "side": "right"}, {"event": "punch", "side": "left"}),
    "kick then punch within 2 s": ("(kick_left | kick_right) then (punch_left | punch_right) within 2 s",
                                   {"event": "kick"}, {"event": "punch"}),
}  # fmt: skip
CMU_SEQUENCE_DERIVED = "cut and concatenated CMU 135 takes (annotated kicks and punches with margins, fillers)"


def _event_cuts(annotations: pd.DataFrame, n_frames: dict, margin: int, blend: int) -> pd.DataFrame:
    """One window per certain annotated event: the event with up to ``margin`` frames of its own take either side,
    shortened so that no other annotated event (certain or not) is inside or cut; events that overlap another
    one, or whose window leaves fewer than ``blend`` frames on a side (the blend would touch the event), are left
    out."""
    sure = (annotations["certain"].astype(str).str.lower().isin(["1", "true", "yes", "y"])
            if "certain" in annotations.columns else pd.Series(True, index=annotations.index))  # fmt: skip
    rows = []
    for label, ev in annotations[sure].iterrows():
        same = annotations[(annotations["doc_id"] == ev["doc_id"]) & (annotations.index != label)]
        if ((same["start"] < ev["end"]) & (same["end"] > ev["start"])).any():
            continue
        before = same.loc[same["end"] <= ev["start"], "end"].to_numpy()
        after = same.loc[same["start"] >= ev["end"], "start"].to_numpy()
        lo = max(0, int(ev["start"]) - margin, int(before.max(initial=0)))
        hi = min(int(n_frames[ev["doc_id"]]), int(ev["end"]) + margin, int(after.min(initial=np.iinfo(np.int64).max)))
        if ev["start"] - lo < blend or hi - ev["end"] < blend:
            continue
        rows.append({"row": label, "take": ev["name"], "take_doc": int(ev["doc_id"]), "event": ev["event"],
                     "side": ev["side"], "cut_start": lo, "cut_end": hi, "event_start": int(ev["start"]),
                     "event_end": int(ev["end"])})  # fmt: skip
    return pd.DataFrame(rows)


def cmu_sequence_streams(db, annotations: pd.DataFrame, margin_s: float = 0.75, filler_s: float = 2.5,
                         blend_s: float = 0.1, within: float = 2.0, units_per_stream: int = 4, seed: int = 0,
                         filler_takes=None) -> tuple[list, list, pd.DataFrame]:  # fmt: skip
    """Derived long documents of real CMU kicks and punches in a known order: the truth of ``kick then punch``.

    Every certain annotated kick and punch (:func:`read_annotations`) is cut from its own take with up to
    ``margin_s`` of the real motion around it (less where another annotated event is nearer; events overlapping
    another one are left out). The cuts are joined into *units* — a kick then a punch (every right kick with a left
    punch, every left kick with a right punch), the same pairs punch first, and every kick and every punch alone —
    and the units of one kind into streams, separated by *fillers*: ``filler_s`` seconds of a take without
    annotated events (the CMU takes 135_03, 135_05, 135_10: steps, blocks), so that nothing of one unit follows
    anything of another within ``within`` s. Clips are joined as :func:`composite_streams` joins them (each next clip
    translated on the floor to continue the previous one, a linear blend of ``blend_s``). These are **derived**
    documents (``derived`` = "cut and concatenated CMU 135 takes ..."), not recordings; their events are known
    frame-exactly.

    Parameters
    ----------
    db : MotionDB
        Holding the annotated takes (the CMU trials, one frame rate).
    annotations : pandas.DataFrame
        :func:`read_annotations` with ``db`` (``doc_id``; ``event`` kick / punch; ``side``; ``certain``).
    margin_s : float
        Real motion kept either side of an event, seconds (at most; 0.5 … 1 s keeps the kick's end and the punch's
        start closer than 2 s).
    filler_s : float
        Length of the fillers between units, seconds; more than ``within + 2 * blend_s``.
    blend_s : float
        The blend between consecutive clips in seconds, rounded to frames.
    within : float
        Seconds; the fillers keep the units further apart than this.
    units_per_stream : int
        Units per stream, >= 1.
    seed : int
        The order of the cuts, the pairing and the fillers' choice.
    filler_takes : sequence of str, optional
        The takes fillers are cut from (default: the :data:`CMU_TAKES` without annotated events, at least
        ``filler_s`` long).

    Returns
    -------
    motions : list of Motion
        One per stream, canonical positions at ``db``'s rate.
    metas : list of dict
        ``name`` (``cmu_sequence_<kind>_<k>``), ``label`` ("derived"), ``kind`` ("kick_punch", "punch_kick",
        "single"), ``derived``, ``clips`` (``take:start-end`` per clip), ``blend_s``, ``margin_s``.
    parts : pandas.DataFrame
        One row per clip: ``stream``, ``name``, ``kind``, ``unit``, ``order``, ``take``, ``role`` ("kick", "punch",
        "filler"), ``side``, ``row`` (annotation row, -1 for fillers), ``cut_start``, ``cut_end`` (in the take),
        ``start``, ``end`` (the clip in the stream, half-open), ``event_start``, ``event_end`` (the event in the
        stream; -1 for fillers).

    Raises
    ------
    ParameterError
        No kick or no punch to cut, no filler take, ``filler_s`` too short, or several frame rates.
    """
    from ..motion.motion import Motion
    from ..motion.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS

    margin_s = number(margin_s, "margin_s (seconds)", 0.0)
    blend_s = number(blend_s, "blend_s (seconds)", 0.0, 1.0)
    within = number(within, "within (seconds)", 0.0)
    filler_s = number(filler_s, "filler_s (seconds)", 0.0)
    if filler_s <= within + 2 * blend_s:
        raise ParameterError(f"filler_s must exceed within + 2 * blend_s = {within + 2 * blend_s:g} s; "
                             f"got {filler_s:g}")
    if int(units_per_stream) != units_per_stream or units_per_stream < 1:
        raise ParameterError(f"units_per_stream must be a whole number >= 1; got {units_per_stream!r}")
    if "doc_id" not in annotations.columns:
        raise ParameterError("annotations need a doc_id column: read them with read_annotations(path, db)")
    docs = db.documents.set_index("doc_id")
    fps = float(docs.loc[annotations["doc_id"].iloc[0], "fps"]) if len(annotations) else float(db.fps)
    blend, margin, filler = round(blend_s * fps), round(margin_s * fps), round(filler_s * fps)
    cuts = _event_cuts(annotations, docs["n_frames"].to_dict(), margin, blend)
    if not len(cuts) or not (cuts["event"] == "kick").any() or not (cuts["event"] == "punch").any():
        raise ParameterError("the annotations need at least one certain kick and one certain punch to cut")
    by_name = db.documents.set_index("name")
    if filler_takes is None:
        filler_takes = [t for t in CMU_TAKES if t in by_name.index and t not in set(annotations["name"])]
    filler_takes = [t for t in filler_takes if t in by_name.index and by_name.loc[t, "n_frames"] >= filler]
    if not filler_takes:
        raise ParameterError(f"no filler take of at least {filler_s:g} s without annotated events")
    if not np.allclose(by_name.loc[list(filler_takes) + list(cuts["take"].unique()), "fps"], fps):
        raise ParameterError("the takes are at several frame rates; ingest at one rate (fps=...)")
    rng = np.random.default_rng(seed)

    def pick(event, side):
        chosen = cuts[(cuts["event"] == event) & (cuts["side"] == side)].index.to_numpy()
        return list(rng.permutation(chosen))

    kicks = {s: pick("kick", s) for s in ("right", "left")}
    punches = {s: pick("punch", s) for s in ("left", "right")}
    pairs = []  # a right kick with a left punch, a left kick with a right punch (punches reused when too few)
    for kick_side, punch_side in (("right", "left"), ("left", "right")):
        mine = punches[punch_side] or punches["left"] or punches["right"]
        pairs += [(k, mine[i % len(mine)]) for i, k in enumerate(kicks[kick_side])]
    singles = [(k,) for k in cuts.index]
    units = {"kick_punch": pairs, "punch_kick": [(p, k) for k, p in pairs], "single": singles}
    motions, metas, parts = [], [], []
    cache = {}

    def positions(take_doc):
        if take_doc not in cache:
            cache[take_doc] = np.asarray(db.motion(int(take_doc)).positions)
        return cache[take_doc]

    for kind, todo in units.items():
        todo = [todo[i] for i in rng.permutation(len(todo))]
        for k in range(0, len(todo), int(units_per_stream)):
            clips, rows = [], []
            for u, unit in enumerate(todo[k : k + int(units_per_stream)]):
                if u:
                    take = filler_takes[int(rng.integers(len(filler_takes)))]
                    n = int(by_name.loc[take, "n_frames"])
                    s = int(rng.integers(0, n - filler + 1))
                    clips.append(positions(by_name.loc[take, "doc_id"])[s : s + filler])
                    rows.append({"unit": u - 0.5, "take": take, "role": "filler", "side": "", "row": -1,
                                 "cut_start": s, "cut_end": s + filler, "offset": None})  # fmt: skip
                for c in unit:
                    cut = cuts.loc[c]
                    clips.append(positions(cut["take_doc"])[cut["cut_start"] : cut["cut_end"]])
                    rows.append({"unit": u, "take": cut["take"], "role": cut["event"], "side": cut["side"],
                                 "row": cut["row"], "cut_start": int(cut["cut_start"]), "cut_end": int(cut["cut_end"]),
                                 "offset": (int(cut["event_start"]) - int(cut["cut_start"]),
                                            int(cut["event_end"]) - int(cut["cut_start"]))})  # fmt: skip
            joined, starts = _concatenate(clips, blend)
            name = f"cmu_sequence_{kind}_{k // int(units_per_stream)}"
            for order, (row, s, clip) in enumerate(zip(rows, starts, clips)):
                offset = row.pop("offset")
                parts.append({"stream": len(motions), "name": name, "kind": kind, "order": order, **row,
                              "unit": int(np.floor(row["unit"])) if row["role"] != "filler" else -1,
                              "start": int(s), "end": int(s + len(clip)),
                              "event_start": int(s + offset[0]) if offset else -1,
                              "event_end": int(s + offset[1]) if offset else -1})  # fmt: skip
            motions.append(Motion(positions=joined, fps=fps, joint_names=CANONICAL_JOINTS, parents=CANONICAL_PARENTS,
                                  source=name, labels={"label": "derived"}))  # fmt: skip
            metas.append({"name": name, "label": "derived", "kind": kind, "derived": CMU_SEQUENCE_DERIVED,
                          "clips": " ".join(f"{r['take']}:{r['cut_start']}-{r['cut_end']}" for r in rows),
                          "blend_s": blend / fps, "margin_s": margin / fps})  # fmt: skip
    return motions, metas, pd.DataFrame(parts)


def cmu_sequence_quality(db, annotations: pd.DataFrame, queries: dict | None = None, definitions: str = "",
                         within: float = 2.0, margin_s: float = 0.75, filler_s: float = 2.5, blend_s: float = 0.1,
                         units_per_stream: int = 4, seed: int = 0, folder=None) -> dict:  # fmt: skip
    """``kick then punch`` on derived streams of the real CMU kicks and punches (:func:`cmu_sequence_streams`),
    against their frame-exact truth (:func:`sequence_events`, :func:`match_events`).

    The annotated CMU takes hold no kick followed by a punch, so the sequence query has no truth there; these
    **derived** (cut and concatenated) documents put every annotated kick before a punch, after a punch, and alone.
    Every hit in every stream counts (a hit in a punch-then-kick or single stream is false: their truth is empty).

    Parameters
    ----------
    db : MotionDB
        The CMU takes (120 Hz: the annotation's rate).
    annotations : pandas.DataFrame
        :func:`read_annotations` with ``db``.
    queries : dict, optional
        Name -> (description, selection of the first events, of the second events); default
        :data:`CMU_SEQUENCE_QUERIES`.
    definitions : str
        ``define`` statements read before every query (e.g. a candidate ``punch_left``; default: the shipped ones).
    within : float
        The truth's time limit in seconds (the description says its own).
    margin_s, filler_s, blend_s, units_per_stream, seed
        As :func:`cmu_sequence_streams`.
    folder : str or os.PathLike, optional
        Where the streams' MotionDB (``cmu_sequences.mdb``) is made and kept; default a temporary folder, removed.

    Returns
    -------
    dict
        ``summary``: one row per query: ``query``, ``description``, ``events``, ``hits``, ``tp``, ``precision``,
        ``recall``, ``f1``, ``tp_both`` (matched hits that overlap both the first and the second event of their
        truth, not only one of them), ``hits_punch_kick`` and ``hits_single`` (hits in the streams without truth:
        should be 0), ``streams``, ``within_s``, ``margin_s``; ``per_kind``: the same per query and stream kind;
        ``parts``: the streams' clips; ``truth``: every query's events; ``hits``: every hit with ``query``,
        ``kind`` and ``matched``.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §1 and §6.3 ("a kick of the right foot followed by a punch").
    """
    from ..relational.index import build
    from ..relational.scene import find

    queries = CMU_SEQUENCE_QUERIES if queries is None else queries
    motions, metas, parts = cmu_sequence_streams(db, annotations, margin_s, filler_s, blend_s, within,
                                                 units_per_stream, seed)  # fmt: skip
    with _streams_db(motions, metas, folder, "cmu_sequences") as (streams, doc_of):
        parts["doc_id"] = [doc_of[n] for n in parts["name"]]
        kind_of = {doc_of[m["name"]]: m["kind"] for m in metas}
        fps = float(streams.documents["fps"].iloc[0])
        indexes = build(streams, "2005", progress=False, save=False)
        events = parts[parts["role"] != "filler"].rename(columns={"role": "event"})
        events = events.assign(start=events["event_start"], end=events["event_end"])
        rows, per_kind, all_hits, truths = [], [], [], []
        for name, (text, first, second) in queries.items():
            hits = find(streams, definitions + "\n" + text, indexes=indexes)
            hits["kind"] = hits["doc_id"].map(kind_of)
            truth = sequence_events(events, first, second, within, fps).reset_index(drop=True)
            m = match_events(hits, truth)
            both = 0
            for i in np.flatnonzero(m["matched"] >= 0):
                t = truth.iloc[m["matched"][i]]
                h = hits.iloc[i]
                a, b = events.loc[t["first_row"]], events.loc[t["second_row"]]
                both += int(h["start"] < a["end"] and h["end"] > a["start"] and h["start"] < b["end"]
                            and h["end"] > b["start"])  # fmt: skip
            rows.append({"query": name, "description": text, "events": m["events"], "hits": m["hits"], "tp": m["tp"],
                         "precision": m["precision"], "recall": m["recall"], "f1": m["f1"], "tp_both": both,
                         "hits_punch_kick": int((hits["kind"] == "punch_kick").sum()),
                         "hits_single": int((hits["kind"] == "single").sum()), "streams": len(motions),
                         "within_s": within, "margin_s": metas[0]["margin_s"]})  # fmt: skip
            truth_kind = truth["doc_id"].map(kind_of)
            hit_tp = pd.Series(m["matched"] >= 0, index=hits.index)
            for kind in ("kick_punch", "punch_kick", "single"):
                n_hits, tp = int((hits["kind"] == kind).sum()), int(hit_tp[hits["kind"] == kind].sum())
                n_events = int((truth_kind == kind).sum())
                per_kind.append({"query": name, "kind": kind, "streams": sum(m_["kind"] == kind for m_ in metas),
                                 "events": n_events, "hits": n_hits, "tp": tp,
                                 "precision": tp / n_hits if n_hits else np.nan,
                                 "recall": tp / n_events if n_events else np.nan})  # fmt: skip
            all_hits.append(hits.assign(query=name, matched=m["matched"]))
            truths.append(truth.assign(query=name))
    return {"summary": pd.DataFrame(rows), "per_kind": pd.DataFrame(per_kind), "parts": parts,
            "truth": pd.concat(truths, ignore_index=True), "hits": pd.concat(all_hits, ignore_index=True)}
