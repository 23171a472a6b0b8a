"""The query by example a clip suggests: which relational features to tick and how many query segments may
disagree, chosen for the clip against the database's indexes (what the dashboard's Relational page opens with and
``mocapviz query`` asks without ``--features``).

The rule (a *suggested query*, docs/glossary.md): the most specific selection of features that still finds
:data:`ANSWERS` other documents. For each feature group (lower, upper, mix), the :data:`POOL` features that change
least often in the clip but at least once, speed and velocity features left out (:func:`speed_features`); every
selection of 1 to :data:`MOST` of them (one group: features of several groups must hit overlapping stretches,
which few other takes do) is looked up in the group's inverted index with m = 0 mismatching segments (the exact
hits on the selection, §5.2), a selection being grown only from one that answers (a selection's hits lie in the
documents of each of its subsets'). Of those that hit at least :data:`ANSWERS` documents other than the clip's own,
the one with the most features wins, then the one with the most query segments (the most specific progression),
then the first in the set's order. When none answers, m grows by one, up to :data:`MAX_MISMATCHES`; when none
answers even then, the selection that found the most other documents.

Why: the earlier default (the four features that change least often, m = 1) is unspecific where a clip has few
changes and finds nothing where its features change often in an order other takes do not share. On the 287
HDM05 cut clips at 30 Hz (5 actors, 11 classes), each clip queried whole, the others judged by the page's quality
line (:func:`mocapviz.experiments.evaluation.precision_at`, a missing rank counting as wrong): mean precision of the
first 5 documents 0.81 (every class at least 0.53; the earlier default 0.40, with 58 clips finding no other
document, and 0.14 for rotateArms); on the 167 clips of actors bd, dg and mm 0.82 (every class at least 0.57;
earlier 0.33); every clip finds at least 5 other documents. Speed and velocity features flicker with a take's
tempo: with them in the pool, 0.81 and throwBasketball 0.41. About 10 ms per clip (suggestion and query) on 287
clips. Measured by ``tests/test_suggestion.py`` (a 3-actor subset) and issue 39's report.

suggest_query     a clip's relational values + the database's indexes -> SuggestedQuery (features, mode, m).
speed_features    the features of a relational set that threshold a speed or a velocity.
"""
from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from ..features import feature_groups, feature_table
from .query import query_segmentation

__all__ = ["ANSWERS", "FALLBACK", "MAX_MISMATCHES", "MOST", "POOL", "SuggestedQuery", "speed_features",
           "suggest_query"]  # fmt: skip

ANSWERS = 5  # other documents a suggested query finds at least (a full first page of the quality line's P@5)
POOL = 6  # features per group a selection is drawn from: those that change least often in the clip
MOST = 3  # features in a selection at most (4: the same choices on HDM05; 2: mean P@5 0.75)
MAX_MISMATCHES = 3  # m tried at most when no selection answers with m = 0
# Müller et al. 2005 §6.2's kicking query (F_l3, F_l4, F_l7, F_l8): for a clip where no feature changes
FALLBACK = ("rfoot_raised", "lfoot_raised", "rknee_bent", "lknee_bent")


class SuggestedQuery(NamedTuple):
    """A query by example chosen for a clip (:func:`suggest_query`).

    Attributes
    ----------
    features : list of str
        The relational features to tick (one group's).
    mode : str
        "mismatch" (m-mismatch hits, Müller et al. 2005 §5.2).
    mismatches : int
        m, the query segments that may disagree.
    others : int
        Documents other than the clip's own the query hits.
    """

    features: list
    mode: str
    mismatches: int
    others: int


def speed_features(relational_set: str = "2005") -> set[str]:
    """The features of ``relational_set`` that threshold a joint's speed or a velocity (``rfoot_fast``,
    ``root_moving``, ``rhand_moving_up``, ...): left out of a suggested query, their on/off pattern follows a take's
    tempo more than its motion.

    Examples
    --------
    >>> sorted(speed_features("2005"))
    ['lfoot_fast', 'lhand_fast', 'rfoot_fast', 'rhand_fast', 'root_moving']
    """
    table = feature_table(relational_set)
    return set(table.loc[table["definition"].str.contains(r"_Speed\(|Velocity\("), "name"])


def _other_documents(index, seq, chosen: list[int], m: int, own_row: int | None) -> int:
    """Documents other than row ``own_row`` with an m-mismatch hit of the query sequence ``seq`` on ``chosen``."""
    bounds = index.adaptive_mismatch(seq.codes, chosen, m)
    rows = np.unique(index.segment_doc[bounds[:, 0]])
    return int(rows.size - np.count_nonzero(rows == own_row))


def _selections(values: np.ndarray, names: list[str], relational_set: str, pool: int, most: int) -> list[list[str]]:
    """Every selection of 1 to ``most`` of the ``pool`` features per group that change least often in the clip but
    at least once (speed features left out; ties in the set's order), fewest features first."""
    changes = dict(zip(names, (np.diff(values.astype(np.int8), axis=0) != 0).sum(axis=0)))
    fast = speed_features(relational_set)
    out = []
    for members in feature_groups(relational_set).values():
        ranked = sorted((f for f in members if changes[f] > 0 and f not in fast), key=lambda f: changes[f])[:pool]
        out += [list(s) for k in range(1, most + 1) for s in itertools.combinations(ranked, k)]
    return sorted(out, key=len)  # stable: the set's order within a size


def suggest_query(values: np.ndarray, names: list[str], indexes: dict, relational_set: str = "2005",
                  own_row: int | None = None, answers: int = ANSWERS, pool: int = POOL, most: int = MOST,
                  max_mismatches: int = MAX_MISMATCHES) -> SuggestedQuery:  # fmt: skip
    """The query by example the rule of this module suggests for a clip.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The clip's relational features (:func:`mocapviz.features.relational_features`), columns ``names``.
    names : list of str [length f]
        The feature names of ``relational_set``.
    indexes : dict
        Group -> :class:`~mocapviz.relational.index.InvertedIndex` of the database searched.
    relational_set : {"2005", "2006"}
    own_row : int, optional
        The clip's document row in the database (its position in ``db.documents``), not counted as an answer;
        None: the clip is no document of the database.
    answers : int
        Other documents a selection must hit (capped at the documents the indexes hold, less the clip's own).
    pool, most, max_mismatches : int
        Features per group drawn from, features per selection at most, m tried at most.

    Returns
    -------
    SuggestedQuery
        :data:`FALLBACK` with m = 0 when no feature changes in the clip.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import relational_features
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> values, names = relational_features(db.motion(7), progress=False)  # a kick
    >>> suggest_query(values, names, build(db, save=False, progress=False), own_row=7)
    SuggestedQuery(features=['lknee_bent'], mode='mismatch', mismatches=0, others=5)
    """
    values = np.asarray(values, dtype=bool)
    n_docs = next(iter(indexes.values())).doc_first_segment.size - 1
    answers = max(1, min(answers, n_docs - (own_row is not None)))
    candidates = _selections(values, names, relational_set, pool, most)
    best = (0, (), 0)  # (other documents, selection, m) of the selection that found the most, if none answers
    for m in range(max_mismatches + 1):
        answered, failed = [], []
        for features in candidates:
            if m == 0 and any(set(f) <= set(features) for f in failed):
                continue  # grown only from a selection that answers
            (group, (chosen, seq)), = query_segmentation(values, names, features, relational_set).items()
            if m >= len(seq.codes):
                continue
            others = _other_documents(indexes[group], seq, chosen, m, own_row)
            best = max(best, (others, tuple(features), m), key=lambda b: b[0])
            if others >= answers:
                answered.append((-len(features), -len(seq.codes), features, others))
            else:
                failed.append(features)
        if answered:
            _, _, features, others = min(answered, key=lambda a: a[:2])  # min: the first of equals
            return SuggestedQuery(features, "mismatch", m, others)
    others, features, m = best
    return SuggestedQuery(list(features), "mismatch", m, others) if others else SuggestedQuery(list(FALLBACK),
                                                                                                "mismatch", 0, 0)
