"""Motion templates: a motion class learned from examples, and its instances found by DTW (Müller & Röder 2006).

A *motion template* (MT) of a class is a (K, f) matrix over the f relational features of a set (the 39 of the
"2006" set by default): each example's boolean feature matrix is time-warped onto a common reference and the
aligned columns are averaged, so a feature that is consistent across the examples stays near 0 or 1 and an
inconsistent one drifts towards the middle. Quantised with a threshold δ, the entries below δ become 0, those
above 1 − δ become 1 and the rest "don't care"; matching then ignores the don't-care entries, which is how the
template, not the user, chooses the features that matter (Müller & Röder 2006 §3–4).

learn_template      (T_i, f) feature matrices of n examples -> MotionTemplate (iterative warping and averaging).
learn_class         a MotionDB's documents of one label (optionally of some actors only) -> MotionTemplate.
find_instances      a template's matches in (N, f) feature values by subsequence DTW, best first (§5).
shortest_instance   the fewest frames a match may span (half the fastest example's).
steepest_rows       the most template rows one database frame may take in a match (the same rule, frame by frame).
document_costs      every document's best match cost of a template (for ranking whole clips).
keyframe_ranges     the frame ranges where a template's keyframes occur, read from the relational indexes (the
                    pre-filter that spares the full DTW pass over a large database; it may miss a hit).
document_codes      each document's distinct frame codes and runs of equal codes (FrameCodes), kept per values array.
row_bounds          per document, a lower bound on any match's cost: each row's least mismatch among its codes, summed.
run_bounds          a tighter bound that keeps the order: the template aligned to the document's runs of equal frames.
classify            a clip's (T, f) feature values against several templates: the classes by DTW cost (§6).
store_template      a template into a MotionDB's derived data, ``DB/templates/<name>.npz`` (template_path).
stored_templates    the templates stored with a MotionDB, one row each; load_template reads one back, by its
                    name only (is_template_name: never a path).
MotionTemplate      the real-valued template, its quantisation and the local cost of matching it.
template_distance   the masked l1 local cost of template rows against boolean frames, (K, n).
quantised_distance  the same for a quantised template, its don't-care entries left out (the matching cost).

Exact top-K search by lower bounds (:func:`find_instances` with ``bounds``, the default of :func:`search_template`):
the documents are aligned in increasing order of a lower bound on their best match cost and the search stops when
the next bound exceeds the K-th best cost found, so it returns the full pass's matches and costs while aligning a
fraction of the frames (:func:`_ranked_ends`). Why the bounds hold, for the template DTW as implemented
(:func:`_bounded_costs` and the unbounded :func:`mocapviz.match.subsequence_costs`): a match is a warping path
through the cells (template row, database frame) of one document that takes every template row at least once, and
each cell it takes pays the row's mismatch share against that frame (:func:`quantised_distance`, never negative).

- *Row bound.* The path's cost is at least the sum, over the rows, of each row's least cost against any frame of
  the document; a frame's cost depends only on its code, so the least over the document's distinct codes is the
  same number. The rules that restrict a match (:func:`steepest_rows`, :func:`shortest_instance`) only remove
  paths, so they never lower a document's best cost below it.
- *Run bound.* Map every frame of the path to its run (consecutive frames of one code): the path becomes a
  monotone path through (template row, run) cells with the basic steps, covering every row; each distinct cell it
  keeps costs what the frames' cells cost, and a run of L frames holds at most L times the rows a match may take on
  one frame. Dropping the repeated cells only removes non-negative terms, so the least such path over the runs
  costs no more than the match. Runs are fewer than frames (one in six on the shared archives at 120 Hz), so the
  bound costs a fraction of the alignment it may spare; it is computed only for the documents that come up.

Learning, as implemented here (our reading of the method, written independently): the reference starts as the
*medoid* example (least summed DTW cost to the others, normalised by the two lengths); each iteration aligns every
example to the current reference by DTW (local cost: mean absolute difference over the features) and replaces
each reference column by the mean, over the examples, of the example columns aligned to it (an example whose
several frames align to one column contributes their mean once). Iterations stop when no entry moves by more
than ``tol``. All examples are averaged at once, so the result does not depend on their order; the template has
the medoid's length.

Two refinements of our own, measured leave-actor-out on the 287 HDM05 cut clips (``template_quality``), both on by
default and both switchable off:

- *Consistent in every group.* When the examples come in groups (their actors; :func:`learn_class` passes the
  ``group`` column), the template also keeps each group's mean of the aligned columns (``group_values``), and
  :meth:`MotionTemplate.quantised` applies δ at both levels: an entry is 0 when fewer than a share δ of the groups
  (each counted once, however many examples it has) reach δ in their mean, 1 symmetrically, else don't care. A
  feature that one actor does differently, e.g. how the arms swing during a kick, is then not demanded of a new
  actor although the pooled mean of many examples of the other actors stays below δ. With one example per group
  (Bandai Namco's styles) it is close to the pooled rule; ``quantised(by_group=False)`` or
  ``learn_class(..., by_group=False)`` gives the pooled rule always.
- *No pile-up of template rows.* Unconstrained subsequence DTW may align dozens of template rows to one database
  frame: a 56-row kick template was matched to a deposit's first 17 frames with 28 rows on one frame, at a lower
  cost than most of an unseen actor's kicks. A match may now align at most :func:`steepest_rows` template rows to
  one database frame (the template's rows over the fewest frames an instance may span: the rule of
  :func:`shortest_instance` applied frame by frame); every aligned cell still pays its cost, so an unbounded
  ``max_rows=0`` is the earlier matching exactly. A database frame may still hold one template row as long as it
  likes (slow instances).
- The examples' worst cost (``meta["example_threshold"]``) of a template learned by group also counts each group's
  examples judged by the other groups only (``meta["unseen_costs"]``): their own costs under a template that cares
  about what every group keeps are optimistic for an unseen actor.
- *A threshold that separates.* The worst example is one outlier: a kick template's reached 0.052-0.074 while the
  other classes' clips of the same actors began at 0.033 (jogs, throws, deposits), and an unseen actor's kicks cost
  at most 0.016-0.051. :func:`learn_class` sets ``meta["threshold"]`` from the labelled database it learns from
  (:func:`separating_threshold`): the example cost with the best F1 against the other classes' clips of the same
  actors, raised halfway to the nearest such clip above it.
"""

from __future__ import annotations

import re
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
import pandas as pd

from .. import store
from ..db import layout
from ..db.arrays import load_arrays, save_arrays
from ..db.hits import hit_table
from ..errors import ParameterError, UnknownKeyError
from ..features import RELATIONAL_SETS, feature_names, relational_features
from ..match import best_ends, dtw, subsequence_costs
from ..match.time_warping import _check_document_starts, matches_frame
from ..parallel import default_threads, map_ordered
from ..validation import Interval, count, number

FORMAT = "mocapviz.MotionTemplate"
VERSION = 2  # 2: one sha256 over all its arrays (mocapviz.db.arrays); a version 1 file is stale: learn it again
_RELEARN = "learn it again (`mocapviz template learn`)"
DONT_CARE = 0.5  # the value a quantised template holds where a feature does not matter
TIE = 1e-9  # row-bounded alignment: costs this close are equal (sums of mismatch shares in another order)
DELTA = 0.1  # default quantisation threshold: < δ -> 0, > 1 - δ -> 1, else don't care
# δ = 0 would leave no entry below 0 or above 1: all "don't care", every stretch a perfect match; δ = 0.5 none
DELTA_RANGE = Interval(0.0, 0.5, low_open=True, high_open=True)
MAX_COST_RANGE = Interval(0.0, 1.0)  # a normalised cost: the mean mismatch per template frame
ITERATIONS = 10
KEYFRAMES = 4  # template rows used by the pre-filter
TOLERANCE = 0.2  # a keyframe occurs where at most this share of its cared-for features disagree
SPEED = 2.0  # instances up to this much faster than the fastest example (or slower than the slowest) are sought
TOL = 1e-6
MAX_NEGATIVES = 500  # documents of other labels a learned threshold is judged against at most
_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,127}")  # a stored template's name: filename-safe
_SAFE = re.compile(r"[^A-Za-z0-9._-]")
_CODES: dict[int, tuple] = {}  # id(values) -> (weak reference to values, starts, FrameCodes): document_codes


@dataclass
class MotionTemplate:
    """A learned motion template.

    Attributes
    ----------
    values : np.ndarray [shape=(K, f)], float64 in [0, 1]: the averaged feature values, one row per template frame.
    features : list of str [length f], the relational feature names of the columns.
    label : str, the class it was learned from.
    n_examples : int
    iterations : int, warping-and-averaging rounds until it settled.
    meta : dict, anything else worth keeping (the examples' frames, relational set, example documents, ...).
    group_values : np.ndarray [shape=(G, K, f)] or None, the mean of each group's aligned examples (``meta["groups"]``
    names the groups), when learned with groups: what :meth:`quantised` judges consistency by.

    ``save(path)`` writes it as an ``.npz`` (no pickle) through :mod:`mocapviz.db.arrays` with a format header and the
    sha256 of its arrays; ``MotionTemplate.load(path)`` checks both.

    Parameters
    ----------
    values : np.ndarray [shape=(K, f)], float64
        The averaged feature values in [0, 1].
    features : list of str
        The f feature names.
    label : str
        The class.
    n_examples : int
        Examples it was learned from.
    iterations : int
        Warping-and-averaging rounds.
    meta : dict
        Anything else worth keeping. (Learned with :func:`learn_template` from feature matrices or with
        :func:`learn_class` from a MotionDB's class.)
    group_values : np.ndarray [shape=(G, K, f)], optional
        Each group's mean of its aligned examples (:func:`learn_template` with ``groups``).

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §3-4 (templates learned by iterative warping and averaging; quantised with δ).

    Examples
    --------
    >>> import numpy as np
    >>> slow = np.array([[0, 0], [0, 0], [1, 0], [1, 1], [1, 1]], dtype=bool)  # two features over 5 frames
    >>> fast = np.array([[0, 0], [1, 0], [1, 1]], dtype=bool)  # the same course in 3 frames
    >>> t = learn_template([slow, fast], ["rfoot_raised", "lfoot_raised"], label="toy")
    >>> t.values.tolist(), t.n_examples  # the medoid's length, the examples warped onto it and averaged
    ([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], 2)
    """

    values: np.ndarray
    features: list[str]
    label: str = ""
    n_examples: int = 0
    iterations: int = 0
    meta: dict = field(default_factory=dict)
    group_values: np.ndarray | None = None

    def quantised(self, delta: float = DELTA, by_group: bool = True) -> np.ndarray:
        """The template with entries < δ set to 0, > 1 − δ set to 1 and the rest to :data:`DONT_CARE` (0.5).

        Learned with groups (``group_values``), an entry is 0 when the groups whose mean is not below δ are fewer
        than a share δ of the groups, 1 when those whose mean is not above 1 − δ are, else don't care: δ applied to
        the examples of each group and to the groups (see the module docstring). With a single example per group
        this is the rule above.

        Parameters
        ----------
        delta : float
            The threshold δ, 0 < δ < 0.5 (:data:`DELTA_RANGE`; at 0 every entry would be don't care).
        by_group : bool
            Judge by the groups when the template has them (default); False: by the pooled ``values`` always.

        Returns
        -------
        np.ndarray [shape=(K, f)], float64
            Values in {0, 0.5, 1}.

        Examples
        --------
        >>> MotionTemplate(np.array([[0.05, 0.5, 0.95]]), ["a", "b", "c"]).quantised(0.1).tolist()
        [[0.0, 0.5, 1.0]]
        >>> per_actor = np.array([[[0.0]], [[0.0]], [[0.0]], [[0.3]]])  # one actor of four lifts the foot 30 %
        >>> t = MotionTemplate(per_actor.mean(axis=0), ["lfoot_raised"], group_values=per_actor)
        >>> t.quantised(0.1).tolist(), t.quantised(0.1, by_group=False).tolist()  # pooled 0.075 < δ
        ([[0.5]], [[0.0]])
        """
        delta = DELTA_RANGE.check(delta, "delta")
        out = np.full(self.values.shape, DONT_CARE)
        if by_group and self.group_values is not None and len(self.group_values):
            g = np.asarray(self.group_values, dtype=np.float64)
            out[(g >= delta).mean(axis=0) < delta] = 0.0
            out[(g <= 1.0 - delta).mean(axis=0) < delta] = 1.0
            return out
        out[self.values < delta] = 0.0
        out[self.values > 1.0 - delta] = 1.0
        return out


    def save(self, path) -> None:
        """Write the template to ``path`` (.npz) atomically, with its header and checksum.

        Parameters
        ----------
        path : str or os.PathLike
            The file (its folder is created; an existing file is replaced).
        """
        header = {"features": self.features, "label": self.label, "n_examples": self.n_examples,
                  "iterations": self.iterations, "meta": self.meta}  # fmt: skip
        arrays = {"values": self.values}
        if self.group_values is not None:
            arrays["group_values"] = np.asarray(self.group_values, dtype=np.float64)
        save_arrays(path, arrays, header, FORMAT, VERSION)

    @classmethod
    def load(cls, path) -> MotionTemplate:
        """A template written by :meth:`save`.

        Parameters
        ----------
        path : str or os.PathLike
            A file written by :meth:`save`.

        Returns
        -------
        MotionTemplate

        Raises
        ------
        MotionDBError
            The file is not a template or is damaged; the message names it. A template of an older version is
            stale (a StaleDataError).
        """
        arrays, header = load_arrays(path, FORMAT, VERSION, "motion template", _RELEARN)
        return cls(arrays["values"], list(header["features"]), header["label"], int(header["n_examples"]),
                   int(header["iterations"]), dict(header["meta"]), arrays.get("group_values"))  # fmt: skip


def template_distance(template: np.ndarray, frames: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Mean absolute difference of template rows and frames over the features each row cares about.

    Parameters
    ----------
    template : np.ndarray [shape=(K, f)]
        Template rows, values in [0, 1].
    frames : np.ndarray [shape=(n, f)], bool or {0, 1}
        Relational features of database frames.
    mask : np.ndarray [shape=(K, f)], bool, optional
        The entries that count (default all). A row that cares about no feature costs 0 against every frame.

    Returns
    -------
    np.ndarray [shape=(K, n)], float64 in [0, 1].
    """
    a = np.asarray(template, dtype=np.float64)
    x = np.asarray(frames, dtype=np.float64)
    w = np.ones_like(a) if mask is None else np.asarray(mask, dtype=np.float64)
    # for binary x: |a - x| = a + x - 2 a x, so the masked sum is three matrix products
    wa = w * a
    total = wa.sum(axis=1)[:, None] + w @ x.T - 2.0 * (wa @ x.T)
    cared = w.sum(axis=1)[:, None]
    return np.divide(total, cared, out=np.zeros_like(total), where=cared > 0)


def _mean_mismatch(template: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """:func:`template_distance` of template rows against boolean frames over every feature, (K, n), in one numba
    loop (:func:`_mismatch_loop`: each cell's absolute differences summed in feature order, over f) instead of three
    matrix products: what learning aligns each example to its reference by. The two agree to the last bits or so
    (tests/test_templates.py); at the sizes of learning (a few hundred frames) the products are slow, slower still
    when the BLAS threads share their cores."""
    out = np.empty((len(template), len(frames)))
    _mismatch_loop(np.asarray(template, dtype=np.float64), np.asarray(frames, dtype=np.float64), out)
    return out


@numba.njit(cache=True, nogil=True)
def _mismatch_loop(a, x, out):  # pragma: no cover
    """``out[i, j]``: the mean over the features of ``|a[i] - x[j]|``."""
    f = a.shape[1]
    for i in range(a.shape[0]):
        for j in range(x.shape[0]):
            total = 0.0
            for k in range(f):
                total += abs(a[i, k] - x[j, k])
            out[i, j] = total / f if f else 0.0


def quantised_distance(template: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """:func:`template_distance` of quantised template rows (values 0, 1 or :data:`DONT_CARE`), ignoring the
    don't-care entries: the local cost of matching a template, as ``distance=`` of
    :func:`mocapviz.match.subsequence_dtw`.

    Parameters
    ----------
    template : np.ndarray [shape=(K, f)]
        Quantised template rows (:meth:`MotionTemplate.quantised`).
    frames : np.ndarray [shape=(n, f)], bool or {0, 1}
        Relational features of database frames.

    Returns
    -------
    np.ndarray [shape=(K, n)], float64
        Mean mismatch over the cared-for features, in [0, 1].

    Examples
    --------
    >>> frames = np.array([[0, 1], [1, 0]], dtype=bool)
    >>> template_distance([[0.5, 1.0]], frames).tolist(), quantised_distance([[0.5, 1.0]], frames).tolist()
    ([[0.25, 0.75]], [[0.0, 1.0]])
    """
    rows = np.asarray(template, dtype=np.float64)
    return template_distance(rows, frames, rows != DONT_CARE)


def learn_template(examples, features: list[str], label: str = "", iterations: int = ITERATIONS,
                   tol: float = TOL, groups=None) -> MotionTemplate:  # fmt: skip
    """Learn a motion template from examples of one class (Müller & Röder 2006 §3–4; see the module docstring).

    Parameters
    ----------
    examples : sequence of np.ndarray [shape=(T_i, f)], bool or {0, 1}
        The relational features of each example clip (e.g. rows of :func:`mocapviz.features.relational_features`
        of a document), at least one, each at least one frame, all with the same f.
    features : list of str [length f]
        The feature names of the columns.
    label : str
        The class.
    iterations : int
        At most this many warping-and-averaging rounds (default 10).
    tol : float
        Stop when no template entry changes by more than this.
    groups : sequence of str, optional
        Each example's group (e.g. its actor). The template then also holds each group's mean of its aligned
        examples (``group_values``, groups named in ``meta["groups"]`` in sorted order), by which
        :meth:`MotionTemplate.quantised` judges consistency; ``values`` stay the mean over all examples.

    Returns
    -------
    MotionTemplate
        ``values`` [shape=(K, f)] with K the medoid example's frames; ``meta`` holds ``example_frames`` (each
        example's length), ``example_costs`` (each example's best normalised match cost, :func:`document_costs`)
        and ``threshold`` = ``example_threshold``, the highest of those: the cost up to which a match is as good as
        the examples' own (with groups, judged as unseen: ``unseen_costs``). :func:`learn_class` replaces
        ``threshold`` by one that also keeps the other classes out (:func:`separating_threshold`).

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §3-4.

    Examples
    --------
    >>> fast = np.array([[0, 0], [1, 0], [1, 1]], dtype=bool)
    >>> slow = np.array([[0, 1], [1, 0], [1, 0], [1, 1]], dtype=bool)
    >>> t = learn_template([fast, slow], ["rfoot_raised", "lfoot_raised"])
    >>> t.values.round(2).tolist()  # the first frames disagree in lfoot_raised: 0.5, "don't care"
    [[0.0, 0.5], [1.0, 0.0], [1.0, 1.0]]
    >>> t.quantised(0.1).tolist()
    [[0.0, 0.5], [1.0, 0.0], [1.0, 1.0]]
    """
    xs = _examples(examples, features)
    count(iterations, "iterations")
    if groups is not None:
        groups = [str(g) for g in groups]
        if len(groups) != len(xs):
            raise ParameterError(f"{len(groups)} groups for {len(xs)} examples; give one group per example")
    ref = xs[_medoid(xs)].astype(np.float64)
    done, aligned = 0, []
    for done in range(1, iterations + 1):
        aligned = []  # each example's columns aligned to the reference
        for x in xs:
            _, path = dtw(ref, x, distance=_mean_mismatch)
            # the path takes every reference column, in order: each column's frames are one stretch of it (sums
            # of 0/1, exact in any order)
            opens = np.flatnonzero(np.r_[True, path[1:, 0] != path[:-1, 0]])
            sums = np.add.reduceat(x[path[:, 1]].astype(np.float64), opens, axis=0)
            aligned.append(sums / np.diff(np.r_[opens, len(path)])[:, None])
        new = np.sum(aligned, axis=0) / len(xs)
        moved = float(np.abs(new - ref).max())
        ref = new
        if moved <= tol:
            break
    template = MotionTemplate(ref, list(features), label, len(xs), done, {"example_frames": [len(x) for x in xs]})
    if groups is not None:
        names = sorted(set(groups))
        template.group_values = np.stack([np.mean([a for a, g in zip(aligned, groups) if g == name], axis=0)
                                          for name in names])  # fmt: skip
        template.meta["groups"] = names
    starts = np.cumsum([0] + [len(x) for x in xs[:-1]])
    own = document_costs(template, np.concatenate(xs), starts)
    template.meta |= {"example_costs": own.tolist(), "threshold": float(own.max()), "example_threshold": float(own.max())}
    if groups is not None and len(template.meta["groups"]) > 1:
        # judged by the other groups' consistency only, as an unseen group would be: the examples' own costs
        # under a template that cares about everything all groups keep are optimistic
        unseen = np.empty(len(xs))
        for k, name in enumerate(template.meta["groups"]):
            others = MotionTemplate(ref, template.features, label, meta=template.meta,
                                    group_values=np.delete(template.group_values, k, axis=0))  # fmt: skip
            mine = np.flatnonzero(np.asarray(groups) == name)
            unseen[mine] = document_costs(others, np.concatenate([xs[i] for i in mine]),
                                          np.cumsum([0] + [len(xs[i]) for i in mine[:-1]]))  # fmt: skip
        worst = float(max(own.max(), unseen.max()))
        template.meta |= {"unseen_costs": unseen.tolist(), "threshold": worst, "example_threshold": worst}
    return template


def shortest_instance(template: MotionTemplate, speed: float = SPEED) -> int:
    """The fewest frames a match of ``template`` may span: its fastest example's frames (``meta["example_frames"]``;
    the template's own length when not recorded) over ``speed``, at least 1. Shorter alignments squeeze the template
    onto a few frames that agree with its don't-care rows, and are no instances.

    Parameters
    ----------
    template : MotionTemplate
        A learned template.
    speed : float
        At least 1: how much faster than the fastest example an instance may be.

    Returns
    -------
    int
        Frames.
    """
    frames = template.meta.get("example_frames") or [len(template.values)]
    return max(1, int(np.ceil(min(frames) / number(speed, "speed", 1.0))))


def steepest_rows(template: MotionTemplate, speed: float = SPEED, min_frames: int | None = None) -> int:
    """The most template rows a match may align to one database frame: the template's rows over the fewest frames
    an instance may span (``min_frames``, default :func:`shortest_instance`: the fastest example's frames over
    ``speed``), rounded up, at least 2. :func:`shortest_instance`'s rule frame by frame: no stretch of an instance
    may run faster than the fastest instance allowed as a whole, so a match cannot pile the template's rows onto a
    few frames that happen to agree with them.

    Parameters
    ----------
    template : MotionTemplate
        A learned template.
    speed : float
        At least 1.
    min_frames : int, optional
        The fewest frames of an instance, when not :func:`shortest_instance`.

    Returns
    -------
    int
        Template rows.

    Examples
    --------
    >>> t = MotionTemplate(np.zeros((56, 2)), ["a", "b"], meta={"example_frames": [33, 56, 90]})
    >>> steepest_rows(t), shortest_instance(t)  # 56 rows on at least 33 / 2 -> 17 frames: 3.3 rows per frame
    (4, 17)
    """
    least = shortest_instance(template, speed) if min_frames is None else count(min_frames, "min_frames")
    return max(2, int(np.ceil(len(template.values) / least)))


def find_instances(template: MotionTemplate, values: np.ndarray, starts=None, n_matches: int = 10,
                   delta: float = DELTA, max_cost: float | None = None, ranges=None,
                   min_frames: int | None = None, max_rows: int | None = None,
                   bounds: bool = True) -> pd.DataFrame:  # fmt: skip
    """The stretches of a database that match a template: subsequence DTW of the quantised template against the
    frames' relational features with the don't-care entries left out (:func:`quantised_distance`).

    With ``bounds`` (default) the documents are aligned best lower bound first (:func:`_ranked_ends`) and the
    documents whose bound exceeds the K-th best cost found are never aligned: the answer is the full pass's (the
    same matches and costs), found aligning a fraction of the frames.

    Parameters
    ----------
    template : MotionTemplate
        A learned template.
    values : np.ndarray [shape=(N, f)], bool
        The database's relational features, columns as ``template.features``.
    starts : np.ndarray [shape=(B,)], int, optional
        The first frame of every document (matches stay inside one).
    n_matches : int
        At most this many non-overlapping matches.
    delta : float
        The quantisation threshold δ.
    max_cost : float, optional
        Keep only matches whose ``normalised_cost`` (cost per template frame, the mean mismatch per frame in
        [0, 1]) is at most this.
    ranges : np.ndarray [shape=(R, 2)], int, optional
        Align only within these [start, stop) frame ranges, each inside one document (:func:`keyframe_ranges`,
        the pre-filter); default the whole database.
    min_frames : int, optional
        No match spans fewer frames (default :func:`shortest_instance`: half the fastest example's frames).
    max_rows : int, optional
        No database frame of a match takes more template rows (default :func:`steepest_rows` of ``min_frames``); 0:
        any number (the plain subsequence DTW of earlier versions).
    bounds : bool
        Align the documents in the order of their lower bounds (:func:`row_bounds`)
        and stop when no unaligned document can hold one of the ``n_matches`` best (default); False: the full pass
        over every frame (or every range). Ignored with ``ranges``.

    Returns
    -------
    pd.DataFrame, best first: doc_id (the document's position in ``starts``; 0 without), start, end (frames within
    that document, half-open: end is one past the last frame, as every hit table), cost, normalised_cost.
    ``attrs["aligned"]``: the frames the DTW aligned.
    """
    x = np.asarray(values)
    if x.ndim != 2 or x.shape[1] != len(template.features):
        raise ParameterError(f"values have shape {x.shape}; the template needs (frames, {len(template.features)})")
    q = template.quantised(delta)
    count(n_matches, "n_matches")
    # subsequence DTW's pieces, without its rule that a match be at least as long as the query: a template (the
    # medoid example's length) may be longer than a faster instance, which the warping absorbs, down to min_frames
    doc_starts = np.zeros(1, dtype=np.int64) if starts is None else np.asarray(starts, dtype=np.int64)
    if ranges is None and bounds:
        costs, ends, first, aligned = _ranked_ends(template, q, x, doc_starts, n_matches, max_cost, min_frames,
                                                   max_rows)  # fmt: skip
        xs = x
    else:
        if ranges is None:
            frames, parts = np.arange(len(x)), starts
        else:
            ranges = np.asarray(ranges, dtype=np.int64).reshape(-1, 2)
            if not len(ranges):
                empty = pd.DataFrame(columns=["doc_id", "start", "end", "cost", "normalised_cost"])
                empty.attrs["aligned"] = 0
                return empty
            frames = np.concatenate([np.arange(a, b) for a, b in ranges])
            parts = np.r_[0, np.cumsum(ranges[:, 1] - ranges[:, 0])[:-1]]
        xs = x[frames]
        cost, first = _costs(template, q, xs, parts, min_frames, max_rows)
        ends = best_ends(cost, first, parts, n_matches)
        costs, first, aligned = cost[ends], first[ends], len(frames)
    if max_cost is not None:
        keep = costs / len(q) <= max_cost
        costs, ends, first = costs[keep], ends[keep], first[keep]
    begin = _tight_starts(q, xs, first, ends, costs, *_limits(template, q, min_frames, max_rows)[::-1])
    if ranges is not None or not bounds:
        begin, ends = frames[begin], frames[ends]
    hits = matches_frame(doc_starts, begin, ends, costs, [None] * len(ends))
    first = doc_starts[hits["doc_id"].to_numpy()]
    hits = hits.drop(columns="path").assign(start=hits["start"] - first, end=hits["end"] + 1 - first)
    hits["normalised_cost"] = hits["cost"] / len(q)
    hits.attrs["aligned"] = int(aligned)
    return hits


def _ranked_ends(template, q, x, doc_starts, n_matches, max_cost, min_frames, max_rows):
    """The ``n_matches`` best non-overlapping matches of the full pass (:func:`best_ends` over :func:`_costs` of every
    frame), found by aligning the documents in increasing order of a lower bound on their best cost
    (see the module docstring) until the next document's bound exceeds the K-th best cost found
    (or the largest cost ``max_cost`` keeps), plus :data:`TIE`.

    Every document first gets its row bound (:func:`row_bounds`); the
    documents that come up for alignment are first bounded again by the run bound
    (:func:`run_bounds`: ordered, tighter, a fraction of the alignment's work),
    eight times the frames about to be aligned at a time, and take their place in the order by it. Documents are
    aligned a batch at a time, each batch up to twice the frames of the one before.

    Matches never cross documents, so the full pass's greedy choice of non-overlapping matches is each document's
    own greedy choice, merged by (cost, last frame); a document whose bound exceeds the K-th best cost found holds
    no match that enters the K best, and the best K of each batch are all it can give to the answer. Each aligned
    document's costs are the full pass's, computed on its frames alone.

    Returns
    -------
    (costs, ends, first, aligned) : the matches' costs, their last and first frames of ``x`` (best first, ties by
    the earlier end, as :func:`best_ends`) and the number of frames aligned.
    """
    n = len(x)
    lengths = np.diff(np.r_[doc_starts, n])
    least, rows = _limits(template, q, min_frames, max_rows)
    codes = document_codes(x, doc_starts)
    bound = row_bounds(q, codes)
    bound[lengths < least] = np.inf  # no match ends there
    refined = ~np.isfinite(bound)
    ceiling = np.inf if max_cost is None else max_cost * len(q)
    found_cost, found_end, found_first = [np.empty(0)], [np.empty(0, np.int64)], [np.empty(0, np.int64)]
    best, waiting = np.empty(0), np.isfinite(bound)
    budget = max(int(np.sort(lengths[waiting])[:n_matches].sum()), n // 256, 1)
    aligned = 0
    while True:
        limit = min(best[n_matches - 1] if len(best) >= n_matches else np.inf, ceiling) + TIE
        pending = np.flatnonzero(waiting & (bound <= limit))
        if not len(pending):
            break
        pending = pending[np.argsort(bound[pending], kind="stable")]
        frames_before = np.cumsum(lengths[pending])
        ahead = pending[: max(1, int(np.searchsorted(frames_before, 8 * budget, side="right")))]
        fresh = ahead[~refined[ahead]] if np.isfinite(limit) else ahead[:0]
        if len(fresh):  # bound them by their runs first, then look again
            bound[fresh] = np.maximum(bound[fresh], run_bounds(q, codes, fresh, rows))
            refined[fresh] = True
            continue
        batch = np.sort(pending[: max(1, int(np.searchsorted(frames_before, budget, side="right")))])
        waiting[batch] = False
        size = lengths[batch]
        frames = np.repeat(doc_starts[batch], size) + (np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size))
        parts = np.cumsum(size) - size
        cost, first = _costs(template, q, x[frames], parts, min_frames, max_rows)
        ends = best_ends(cost, first, parts, n_matches)
        found_cost.append(cost[ends])
        found_end.append(frames[ends])
        found_first.append(frames[first[ends]])
        best = np.sort(np.r_[best, cost[ends]])[:n_matches]
        aligned += len(frames)
        budget *= 2
    costs, ends, first = np.concatenate(found_cost), np.concatenate(found_end), np.concatenate(found_first)
    top = np.lexsort((ends, costs))[:n_matches]
    return costs[top], ends[top], first[top], aligned


def keyframe_ranges(template: MotionTemplate, indexes: dict, doc_starts, n_frames: int, delta: float = DELTA,
                    keyframes: int = KEYFRAMES, tolerance: float = TOLERANCE,
                    speed: float = SPEED) -> np.ndarray:  # fmt: skip
    """Candidate frame ranges for a template, from the relational indexes instead of the frames (the pre-filter).

    ``keyframes`` template rows are chosen (in each of as many equal parts of the template, the row that cares
    about the most features). A keyframe *occurs* at a frame whose features disagree with it on at most
    ``tolerance`` of its cared-for features; the disagreements are counted per stored segment of each group's
    inverted index (the code of the segment against the keyframe's bits of that group), so no frame's features
    are read. A *chain* is an occurrence of every keyframe, in the template's order, in one document, each gap
    between ``lo`` and ``hi`` times the gap of the two rows in the template (plus two frames), where [lo, hi] is
    the pace of the template's examples (their frames over the template's, ``meta["example_frames"]``; 1 when not
    recorded) widened by ``speed`` both ways; a range is what a chain ending at frame t can belong to: from ``hi``
    times the last keyframe's row before t to ``hi`` times the rows after it past t, inside the document.
    Instances at most ``speed`` times faster or slower than the fastest / slowest example, whose keyframes all
    agree that well, are inside the ranges; anything else may be missed (measured in
    ``benchmarks/bench_templates.py``).

    Parameters
    ----------
    template : MotionTemplate
        A template of a relational set whose indexes are given.
    indexes : dict
        Group -> mocapviz.relational.index.InvertedIndex
        (``mocapviz.relational.index.load_or_build(db, relational_set)``).
    doc_starts : np.ndarray [shape=(B,)], int
        First frame of every document.
    n_frames : int
        Frames of the database.
    delta : float
        The quantisation threshold δ.
    keyframes : int
        Keyframes, 1 .. template frames (default 4).
    tolerance : float
        The share in [0, 1] of a keyframe's cared-for features that may disagree (default 0.2; 1 makes every
        frame an occurrence: the ranges then cover every document at least as long as a chain).
    speed : float
        How much faster than the fastest example or slower than the slowest an instance may be (>= 1, default 2).

    Returns
    -------
    np.ndarray [shape=(R, 2)], int64
        [start, stop) database frame ranges, inside documents, in frame order.
    """
    q = template.quantised(delta)
    k = len(q)
    count(keyframes, "keyframes", most=k, most_is="the template's frames")
    tolerance, speed = number(tolerance, "tolerance", 0.0, 1.0), number(speed, "speed", 1.0)
    parts = np.array_split(np.arange(k), keyframes)
    cared = (q != DONT_CARE).sum(axis=1)
    rows = [int(p[np.argmax(cared[p])]) for p in parts]
    pace = np.asarray(template.meta.get("example_frames") or [k], dtype=np.float64) / k
    lo, hi = pace.min() / speed, pace.max() * speed
    doc_starts = np.asarray(doc_starts, dtype=np.int64)
    doc = np.repeat(np.arange(len(doc_starts)), np.diff(np.r_[doc_starts, n_frames]))
    first = doc_starts[doc]  # the first frame of each frame's document
    reach = None
    for i, r in enumerate(rows):
        occurs = _disagreements(template, q[r], indexes, n_frames) <= tolerance * max(1, cared[r])
        if reach is None:
            reach = occurs
        else:
            gap = r - rows[i - 1]
            reach = occurs & _seen(reach, first, int(gap * lo), int(np.ceil(gap * hi)) + 2)
    before, after = int(np.ceil(rows[-1] * hi)) + 2, int(np.ceil((k - 1 - rows[-1]) * hi)) + 2
    ends = np.flatnonzero(reach)
    last = np.r_[doc_starts[1:], n_frames][doc[ends]]  # one past each end's document
    cover = np.zeros(n_frames + 1, dtype=np.int64)
    np.add.at(cover, np.maximum(ends - before, first[ends]), 1)
    np.add.at(cover, np.minimum(ends + after + 1, last), -1)
    candidate = np.cumsum(cover[:-1]) > 0
    edges = np.flatnonzero(np.diff(np.r_[0, candidate.astype(np.int8), 0]))
    ranges = edges.reshape(-1, 2)
    # split ranges at document starts (a match never crosses one)
    cuts = np.unique(np.r_[ranges.ravel(), doc_starts[(doc_starts > 0)]])
    out = np.stack([cuts[:-1], cuts[1:]], axis=1)
    out = out[(out[:, 1] > out[:, 0])]
    return out[candidate[out[:, 0]]].astype(np.int64)


def _disagreements(template: MotionTemplate, row: np.ndarray, indexes: dict, n_frames: int) -> np.ndarray:
    """(N,) int64: for every frame, the cared-for features of one quantised template row it disagrees with, counted
    per stored segment of each group's inverted index (segment code against the row's bits)."""
    wrong = np.zeros(n_frames, dtype=np.int64)
    for idx in indexes.values():
        cols = [template.features.index(name) for name in idx.feature_names]
        bits = np.int64(1) << np.arange(len(cols), dtype=np.int64)
        mask = int(bits[row[cols] != DONT_CARE].sum())
        want = int(bits[row[cols] == 1.0].sum())
        per_code = np.bitwise_count((idx.list_codes ^ want) & mask).astype(np.int64)
        per_frame = np.repeat(per_code[idx.rank], idx.lengths)  # the segments tile the database's frames
        if len(per_frame) != n_frames:
            raise ParameterError(f"an index of {len(per_frame):,} frames for a database of {n_frames:,}")
        wrong += per_frame
    return wrong


def _seen(mask: np.ndarray, first: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """(N,) bool: frames t with a True of ``mask`` among frames t - hi .. t - lo of their own document (``first``:
    each frame's document start)."""
    n = len(mask)
    total = np.r_[0, np.cumsum(mask, dtype=np.int64)]
    t = np.arange(n)
    a = np.maximum(t - hi, first)
    b = np.maximum(t - lo + 1, a)
    return total[np.minimum(b, n)] > total[np.minimum(a, n)]


def _costs(template, q, x, starts, min_frames, max_rows=None) -> tuple[np.ndarray, np.ndarray]:
    """Subsequence DTW's (cost, first) per end frame of the quantised template ``q`` over ``x``, inf where the
    alignment spans fewer than ``min_frames`` frames (None: :func:`shortest_instance`), at most ``max_rows``
    template rows on one frame (None: :func:`steepest_rows`; 0 or at least the template's rows: unbounded, the
    basic step set of :func:`mocapviz.match.subsequence_costs`)."""
    least, rows = _limits(template, q, min_frames, max_rows)
    if rows >= len(q):
        cost, first = subsequence_costs(q, x, starts, distance=quantised_distance)
    else:
        cost, first = _bounded_costs(q, x, starts, rows, least)
    cost[np.arange(len(cost)) - first + 1 < least] = np.inf
    return cost, first


def _limits(template, q, min_frames, max_rows) -> tuple[int, int]:
    """(the fewest frames a match spans, the most template rows one frame takes: ``len(q)`` when unbounded)."""
    least = shortest_instance(template) if min_frames is None else count(min_frames, "min_frames")
    rows = steepest_rows(template, min_frames=least) if max_rows is None else count(max_rows, "max_rows", least=0)
    return least, len(q) if rows == 0 else min(rows, len(q))


def _tight_starts(q, x, first, ends, costs, max_rows: int, least: int) -> np.ndarray:
    """The latest start of each match: of the alignments of the whole template ending at frame ``ends[h]`` and
    costing no more than ``costs[h]`` (within :data:`TIE`) over at least ``least`` frames, the one that starts last.

    Subsequence DTW leaves a match's start free: frames before an instance that cost nothing against the template's
    first rows (a rest pose held before a kick) join it at no cost, and the alignment keeps them (of equal costs it
    keeps the longer path, which the minimum length needs). A match then reaches back into the motion before it,
    and "A then B" misses an A that its B overlaps. Aligned backwards from each end (the template's rows and the
    frames reversed, the path fixed to start at the end frame), the latest start is the first frame back where the
    alignment's cost reaches the match's own; the costs are unchanged, only the starts move later (never earlier).

    Parameters
    ----------
    q : np.ndarray [shape=(m, f)]
        The quantised template.
    x : np.ndarray [shape=(n, f)], bool
        The frames aligned.
    first, ends : np.ndarray [shape=(h,)], int
        The matches' first and last frames of ``x`` (inclusive), none overlapping another.
    costs : np.ndarray [shape=(h,)], float
        Their costs (sums of per-frame mismatch shares).
    max_rows, least : int
        As :func:`_bounded_costs` (``max_rows >= m``: unbounded).

    Returns
    -------
    np.ndarray [shape=(h,)], int64
        The latest first frames, each in ``first[h] .. ends[h] - least + 1``.
    """
    first, ends = np.asarray(first, dtype=np.int64), np.asarray(ends, dtype=np.int64)
    if not len(ends):
        return first
    lengths = ends - first + 1
    bounds = np.r_[0, np.cumsum(lengths)]
    # every match's frames, its last frame first (the matches do not overlap: at most n rows)
    back = np.repeat(ends, lengths) - (np.arange(bounds[-1]) - np.repeat(bounds[:-1], lengths))
    r = q[::-1]
    steps = _latest_run_starts(_bit_rows(x[back]), _bit_rows(r == 1.0), _bit_rows(r != DONT_CARE),
                               (r != DONT_CARE).sum(axis=1).astype(np.float64), bounds,
                               np.asarray(costs, dtype=np.float64), min(max_rows, len(q)), least)  # fmt: skip
    return ends - steps


def _bounded_costs(q, x, starts, max_rows: int, least: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(cost, first) per end frame of subsequence DTW with the basic steps (every aligned cell pays its
    :func:`quantised_distance`) whose path takes at most ``max_rows`` template rows on any one database frame; inf
    (and -1) throughout a document of fewer than ``least`` frames, where no alignment spanning ``least`` frames ends.

    The frames' features and the template rows are packed into 64-bit words (:func:`_bit_rows`), so a cell's
    cost is a count of set bits; the documents of at least ``least`` frames are aligned, in groups of about equal
    frames on threads (:func:`mocapviz.parallel.map_ordered`)."""
    x = np.asarray(x)
    n = len(x)
    bounds = np.r_[_check_document_starts(starts, n), n]
    docs = np.column_stack([bounds[:-1], bounds[1:]])
    docs = docs[docs[:, 1] - docs[:, 0] >= least]
    frames = _bit_rows(x)
    values, care = _bit_rows(q == 1.0), _bit_rows(q != DONT_CARE)
    cared = (q != DONT_CARE).sum(axis=1).astype(np.float64)
    cost, first = np.full(n, np.inf), np.full(n, -1, dtype=np.int64)
    # about 4 groups per thread, cut after the documents where equal shares of the aligned frames end
    done = np.cumsum(docs[:, 1] - docs[:, 0])
    shares = np.linspace(0, done[-1] if len(done) else 0, 4 * default_threads() + 1)[1:-1]
    groups = [g for g in np.split(docs, np.unique(np.searchsorted(done, shares) + 1)) if len(g)]
    list(map_ordered(lambda group: _bounded_run(frames, values, care, cared, group, max_rows, cost, first), groups,
                     name="mocapviz-template"))  # fmt: skip
    first[~np.isfinite(cost)] = -1
    return cost, first


def _bit_rows(flags: np.ndarray, block: int = 1 << 20) -> np.ndarray:
    """(r, f) flags (bool, or numbers: nonzero is set) as (r, w) uint64, bit c of word c // 64 = column c (w =
    ceil(f / 64), at least 1); packed ``block`` rows at a time, so that no temporary copy of all the rows is made."""
    r, f = flags.shape
    width = max(1, -(-f // 64))
    words = np.zeros((r, width), dtype="<u8")
    as_bytes = words.view(np.uint8).reshape(r, 8 * width)
    for a in range(0, r, block):
        part = flags[a : a + block]
        packed = np.packbits(part if part.dtype == bool else part != 0, axis=1, bitorder="little")
        as_bytes[a : a + block, : packed.shape[1]] = packed
    return words.astype(np.uint64, copy=False)


@numba.njit(cache=True, nogil=True, inline="always")
def _set_bits(v):  # pragma: no cover
    """The number of set bits of a uint64 (the SWAR count)."""
    v = v - ((v >> np.uint64(1)) & np.uint64(0x5555555555555555))
    v = (v & np.uint64(0x3333333333333333)) + ((v >> np.uint64(2)) & np.uint64(0x3333333333333333))
    v = (v + (v >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (v * np.uint64(0x0101010101010101)) >> np.uint64(56)


@numba.njit(cache=True, nogil=True)
def _frame_work(m):  # pragma: no cover
    """The work arrays of :func:`_bounded_frame` for a template of m rows: total (m + 1), entry, enter_first,
    window, prev, prev_first, acc, start (m each)."""
    return (np.empty(m + 1), np.empty(m), np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64), np.empty(m),
            np.empty(m, dtype=np.int64), np.empty(m), np.empty(m, dtype=np.int64))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _bounded_run(frames, values, care, cared, docs, max_rows, cost, first):  # pragma: no cover
    """The documents ``docs`` ((r, 2) [start, stop) frames) of :func:`_bounded_costs`, written into ``cost`` /
    ``first``. A frame's cost against template row i is its mismatches on the row's cared-for features (``care``;
    ``values`` the 1 entries) over their number ``cared[i]`` (0 when it cares for none). A cell (i, j) is reached by
    a run of r <= max_rows rows i - r + 1 .. i on frame j, entered from frame j - 1 at row i - r (diagonally) or at
    row i - r + 1 (that row held), or started at row 0; each cell of the run pays its cost."""
    m = values.shape[0]
    total, entry, enter_first, window, prev, prev_first, acc, start = _frame_work(m)
    for d in range(len(docs)):
        for j in range(docs[d, 0], docs[d, 1]):
            _bounded_frame(frames, values, care, cared, j, j > docs[d, 0], True, max_rows, total, entry, enter_first,
                           window, prev, prev_first, acc, start)  # fmt: skip
            cost[j], first[j] = acc[m - 1], start[m - 1]
            prev[:] = acc
            prev_first[:] = start


@numba.njit(cache=True, nogil=True)
def _bounded_frame(frames, values, care, cared, j, same, fresh, max_rows, total, entry, enter_first, window, prev,
                   prev_first, acc, start):  # pragma: no cover  # fmt: skip
    """Frame j of :func:`_bounded_run`: ``acc`` / ``start`` (the cost and path start of every template row ending
    on frame j) from ``prev`` / ``prev_first`` (frame j - 1's, used when ``same``: j is not its document's first);
    a path may begin (at row 0) on frame j when ``fresh`` (always in a search; on the first frame only when the
    start is fixed, :func:`_latest_run_starts`).

    A run of rows r0 .. i on frame j costs ``total[i + 1] - total[r0]`` (``total``: the running sum of the frame's
    local costs), so the best run into row i is ``total[i + 1]`` plus the least ``entry[r0] = enter[r0] -
    total[r0]`` over the last ``max_rows`` rows r0: a sliding-window minimum (``window``: the rows whose entry may
    still be least, increasing in entry), O(m) per frame whatever ``max_rows``. Sums taken in another order differ in
    their last bits, so costs within :data:`TIE` of each other are ties: the held row wins them, and of the runs the
    latest row (the shortest run), as if the costs were exact."""
    m, w = values.shape
    total[0] = 0.0
    for i in range(m):
        bad = 0
        for k in range(w):
            bad += _set_bits((frames[j, k] ^ values[i, k]) & care[i, k])
        total[i + 1] = total[i] + (bad / cared[i] if cared[i] > 0 else 0.0)
    # the cheapest way into row r0 of frame j before its run: a start (row 0) or from frame j - 1 at row r0
    # (held) or r0 - 1 (diagonal), the held row winning ties
    entry[0], enter_first[0] = (0.0, j) if fresh else (np.inf, -1)
    for r0 in range(1, m):
        entry[r0], enter_first[r0] = np.inf, -1
        if same:
            if prev[r0 - 1] < prev[r0] - TIE:
                entry[r0], enter_first[r0] = prev[r0 - 1] - total[r0], prev_first[r0 - 1]
            else:
                entry[r0], enter_first[r0] = prev[r0] - total[r0], prev_first[r0]
    head, tail = 0, 0  # window[head:tail]
    for i in range(m):
        while tail > head and entry[window[tail - 1]] >= entry[i] - TIE:
            tail -= 1
        window[tail] = i
        tail += 1
        if window[head] <= i - max_rows:
            head += 1
        r0 = window[head]
        if entry[r0] < np.inf:
            acc[i], start[i] = total[i + 1] + entry[r0], enter_first[r0]
        else:
            acc[i], start[i] = np.inf, -1


@numba.njit(cache=True, nogil=True)
def _latest_run_starts(frames, values, care, cared, bounds, costs, max_rows, least):  # pragma: no cover
    """For each match h (rows ``bounds[h]:bounds[h + 1]`` of ``frames``: its frames from the last back to the
    first; ``values`` / ``care`` / ``cared``: the template's rows reversed), the fewest frames back from the end,
    less one, at which an alignment fixed to begin on the end frame covers the whole template at no more than
    ``costs[h]`` (+ :data:`TIE`) over at least ``least`` frames (:func:`_tight_starts`)."""
    m = values.shape[0]
    total, entry, enter_first, window, prev, prev_first, acc, start = _frame_work(m)
    steps = np.empty(len(costs), dtype=np.int64)
    for h in range(len(costs)):
        a, b = bounds[h], bounds[h + 1]
        steps[h] = b - a - 1  # the match as found, when no later start costs as little
        for j in range(a, b):
            _bounded_frame(frames, values, care, cared, j, j > a, j == a, max_rows, total, entry, enter_first, window,
                           prev, prev_first, acc, start)  # fmt: skip
            if j - a + 1 >= least and acc[m - 1] <= costs[h] + TIE:
                steps[h] = j - a
                break
            prev[:] = acc
            prev_first[:] = start
    return steps


@dataclass(frozen=True)
class FrameCodes:
    """The distinct relational codes of each document of a database.

    Attributes
    ----------
    codes : np.ndarray [shape=(U, w)], uint64
        The database's distinct frame codes: bit c of word c // 64 is feature c (:func:`_bit_rows`).
    ids : np.ndarray [shape=(P,)], int64
        Row of ``codes`` of each (document, distinct code) pair, the documents in order.
    offsets : np.ndarray [shape=(B + 1,)], int64
        Document b's codes are ``ids[offsets[b]:offsets[b + 1]]``.
    runs : np.ndarray [shape=(R,)], int64
        Row of ``codes`` of each run of equal consecutive frames, the documents in order.
    run_lengths : np.ndarray [shape=(R,)], int64
        The frames of each run.
    run_offsets : np.ndarray [shape=(B + 1,)], int64
        Document b's runs are ``runs[run_offsets[b]:run_offsets[b + 1]]``.
    """

    codes: np.ndarray
    ids: np.ndarray
    offsets: np.ndarray
    runs: np.ndarray
    run_lengths: np.ndarray
    run_offsets: np.ndarray


def document_codes(values: np.ndarray, starts) -> FrameCodes:
    """Each document's distinct frame codes, computed once per values array (and kept while that array lives:
    later calls with the same array object and document starts return the same FrameCodes, so the array must not
    be changed in place afterwards, as no relational feature array is).

    Parameters
    ----------
    values : np.ndarray [shape=(N, f)], bool
        The relational features of every frame.
    starts : array_like [shape=(B,)], int
        The first frame of every document (increasing, the first 0).

    Returns
    -------
    FrameCodes

    Examples
    --------
    >>> values = np.array([[0, 1], [0, 1], [1, 1], [0, 1], [1, 0]], dtype=bool)  # two documents: 3 + 2 frames
    >>> fc = document_codes(values, [0, 3])
    >>> fc.codes[:, 0].tolist()  # bit c is feature c: [0, 1] is 0b10 = 2, [1, 1] is 3, [1, 0] is 1
    [1, 2, 3]
    >>> fc.ids.tolist(), fc.offsets.tolist()  # rows of codes: the first document holds 2 and 3, the second 2 and 1
    ([1, 2, 0, 1], [0, 2, 4])
    >>> fc.runs.tolist(), fc.run_lengths.tolist(), fc.run_offsets.tolist()  # the first two frames are one run
    ([1, 2, 1, 0], [2, 1, 1, 1], [0, 2, 4])
    """
    starts = np.asarray(starts, dtype=np.int64).reshape(-1)
    held = _CODES.get(id(values))
    if held is not None and held[0]() is values and np.array_equal(held[1], starts):
        return held[2]
    words = _bit_rows(np.asarray(values))
    n, w = words.shape
    if w == 1:
        codes, inverse = np.unique(words[:, 0], return_inverse=True)
        codes = codes.reshape(-1, 1)
    else:
        keys = np.ascontiguousarray(words).view(np.dtype((np.void, 8 * w))).reshape(-1)
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        codes = words[first]
    inverse = inverse.reshape(-1).astype(np.int64)
    doc = np.repeat(np.arange(len(starts), dtype=np.int64), np.diff(np.r_[starts, n]))
    pairs = np.unique(doc * len(codes) + inverse)
    opens = np.ones(n, dtype=bool)
    opens[1:] = inverse[1:] != inverse[:-1]
    opens[starts[starts < n]] = True
    at = np.flatnonzero(opens)
    found = FrameCodes(codes, pairs % len(codes), np.searchsorted(pairs // len(codes), np.arange(len(starts) + 1)),
                       inverse[at], np.diff(np.r_[at, n]), np.searchsorted(doc[at], np.arange(len(starts) + 1)))
    try:
        key = id(values)
        _CODES[key] = (weakref.ref(values, lambda _, key=key: _CODES.pop(key, None)), starts, found)
    except TypeError:  # an object without weak references (a list): not kept
        pass
    return found


def row_bounds(q: np.ndarray, codes: FrameCodes) -> np.ndarray:
    """A lower bound on the DTW cost of any match of the quantised template ``q`` in each document: the sum over
    the template's rows of the row's least mismatch share among the document's distinct codes (see the module
    docstring).

    Parameters
    ----------
    q : np.ndarray [shape=(m, f)]
        A quantised template (:meth:`MotionTemplate.quantised`: 0, 1 or
        :data:`DONT_CARE`).
    codes : FrameCodes
        The documents' codes (:func:`document_codes`) over the same f features.

    Returns
    -------
    np.ndarray [shape=(B,)], float64
        In the cost's units (a sum of per-row mismatch shares; over ``m``: a normalised cost); inf for a document
        without frames.

    Examples
    --------
    >>> values = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 1]], dtype=bool)
    >>> q = np.array([[0, 0], [1, 1], [1, DONT_CARE]])  # three rows: 00, 11, 1x
    >>> row_bounds(q, document_codes(values, [0, 3])).tolist()  # the first holds all three; the second: 01 only
    [0.0, 2.0]
    """
    q = np.asarray(q, dtype=np.float64)
    values, care = _bit_rows(q == 1.0), _bit_rows(q != DONT_CARE)
    out = np.empty(len(codes.offsets) - 1)
    _row_bounds(codes.codes, codes.ids, codes.offsets, values, care, (q != DONT_CARE).sum(axis=1).astype(np.float64),
                out)  # fmt: skip
    return out


def run_bounds(q: np.ndarray, codes: FrameCodes, documents, max_rows: int = 0) -> np.ndarray:
    """A lower bound on the DTW cost of any match of the quantised template ``q`` in each of ``documents``: the
    least cost of aligning every template row, in order, to the document's runs of equal frames (subsequence DTW
    with the basic steps over the runs, a run of L frames taking at most L × ``max_rows`` rows; see the module
    docstring), less twice :data:`TIE` per step of the path (the alignment kernel takes
    costs that close as equal). Never above the document's best match cost.

    Parameters
    ----------
    q : np.ndarray [shape=(m, f)]
        A quantised template.
    codes : FrameCodes
        The documents' codes and runs (:func:`document_codes`).
    documents : array_like [shape=(b,)], int
        The documents (positions in the database's order) to bound.
    max_rows : int
        The most template rows a match aligns to one frame (:func:`steepest_rows`);
        0: any number.

    Returns
    -------
    np.ndarray [shape=(b,)], float64
        In the cost's units; inf for a document without frames.

    Examples
    --------
    >>> values = np.array([[0, 0], [1, 1], [0, 0], [1, 1], [0, 0]], dtype=bool)  # one document: 00 11 00 11 00
    >>> fc = document_codes(values, [0])
    >>> q = np.array([[1, 1], [0, 0], [1, 1]])  # 11 00 11: in order, it fits
    >>> row_bounds(q, fc).tolist(), run_bounds(q, fc, [0]).round(6).tolist()
    ([0.0], [0.0])
    >>> fc = document_codes(values[:3], [0])  # 00 11 00 holds no 11 after the 00 that follows its 11
    >>> row_bounds(q, fc).tolist(), run_bounds(q, fc, [0]).round(6).tolist()  # order counts: one row must pay
    ([0.0], [1.0])
    >>> q = np.array([[0, 0], [0, 0], [0, 0], [1, 1]])  # three rows of 00 on one frame, then 11
    >>> run_bounds(q, fc, [0]).round(6).tolist(), run_bounds(q, fc, [0], max_rows=2).round(6).tolist()
    ([0.0], [1.0])
    """
    q = np.asarray(q, dtype=np.float64)
    documents = np.asarray(documents, dtype=np.int64).reshape(-1)
    m = len(q)
    values, care = _bit_rows(q == 1.0), _bit_rows(q != DONT_CARE)
    cared = (q != DONT_CARE).sum(axis=1).astype(np.float64)
    rows = m if max_rows == 0 else min(int(max_rows), m)
    out = np.empty(len(documents))
    groups = [g for g in np.array_split(np.arange(len(documents)), 4 * default_threads()) if len(g)]
    list(map_ordered(lambda g: _run_bounds(codes.codes, codes.runs, codes.run_lengths, codes.run_offsets,
                                           documents[g], values, care, cared, rows, out, g[0]), groups,
                     name="mocapviz-bounds"))  # fmt: skip
    steps = m + codes.run_offsets[documents + 1] - codes.run_offsets[documents]
    return np.maximum(out - 2 * TIE * steps, 0.0)  # no cost is negative


@numba.njit(cache=True, nogil=True)
def _run_bounds(codes, runs, run_lengths, run_offsets, documents, values, care, cared, max_rows, out,
                at):  # pragma: no cover  # fmt: skip
    """:func:`run_bounds` of ``documents`` into ``out[at:]``: per document, run by run, the alignment kernel's frame
    step (:func:`_bounded_frame`) with the run's code as the frame and at most its
    frames times ``max_rows`` rows on it; the least cost of the last row over the runs."""
    m = values.shape[0]
    total, entry, enter_first, window, prev, prev_first, acc, start = _frame_work(m)
    for d in range(len(documents)):
        a, b = run_offsets[documents[d]], run_offsets[documents[d] + 1]
        best = np.inf
        for r in range(a, b):
            _bounded_frame(codes, values, care, cared, runs[r], r > a, True, min(m, run_lengths[r] * max_rows), total,
                           entry, enter_first, window, prev, prev_first, acc, start)  # fmt: skip
            best = min(best, acc[m - 1])
            prev[:] = acc
            prev_first[:] = start
        out[at + d] = best


@numba.njit(cache=True, nogil=True)
def _row_bounds(codes, ids, offsets, values, care, cared, out):  # pragma: no cover
    """:func:`row_bounds` into ``out``: per document, each row's fewest mismatched cared-for bits among its codes,
    over the row's cared-for features (0 for a row that cares for none), summed over the rows."""
    m, w = values.shape
    fewest = np.empty(m, dtype=np.int64)
    for d in range(len(offsets) - 1):
        if offsets[d + 1] == offsets[d]:
            out[d] = np.inf
            continue
        fewest[:] = 1 << 62
        for p in range(offsets[d], offsets[d + 1]):
            u = ids[p]
            for i in range(m):
                if fewest[i] == 0:
                    continue
                bad = 0
                for k in range(w):
                    bad += _set_bits((codes[u, k] ^ values[i, k]) & care[i, k])
                fewest[i] = min(fewest[i], bad)
        total = 0.0
        for i in range(m):
            if cared[i] > 0:
                total += fewest[i] / cared[i]
        out[d] = total


def document_costs(template: MotionTemplate, values: np.ndarray, starts, delta: float = DELTA,
                   min_frames: int | None = None, max_rows: int | None = None) -> np.ndarray:  # fmt: skip
    """The best (least) normalised cost of a match of ``template`` ending in each document: every document gets
    one, so whole clips can be ranked by how well they hold an instance.

    Parameters
    ----------
    template : MotionTemplate
        A learned template.
    values : np.ndarray [shape=(N, f)], bool
        The database's relational features, columns as ``template.features``.
    starts : np.ndarray [shape=(B,)], int
        The first frame of every document.
    delta : float
        The quantisation threshold δ.
    min_frames : int, optional
        No match spans fewer frames (default :func:`shortest_instance`).
    max_rows : int, optional
        No database frame of a match takes more template rows (default :func:`steepest_rows`; 0: any number).

    Returns
    -------
    np.ndarray [shape=(B,)], float64
        Per document the least normalised cost (mean mismatch per template frame, in [0, 1]); inf for a document
        where no match ends.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import relational_features
    >>> db = MotionDB.sample()
    >>> values, _ = relational_features(db, "2006", progress=False)
    >>> t = learn_class(db, "squat1Reps", values=values)
    >>> costs = document_costs(t, values, db.documents["start"].to_numpy())
    >>> db.documents["doc_id"].to_numpy()[np.argsort(costs, kind="stable")[:3]].tolist()  # its examples first
    [11, 22, 12]
    """
    x = np.asarray(values)
    q = template.quantised(delta)
    cost, _ = _costs(template, q, x, starts, min_frames, max_rows)
    bounds = np.r_[np.asarray(starts, dtype=np.int64), len(x)]
    return np.minimum.reduceat(cost, bounds[:-1]) / len(q)


def classify(values: np.ndarray, templates, delta: float = DELTA) -> pd.DataFrame:
    """Rank the classes of several templates for one clip by whole-clip DTW cost (the nearest template first).

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The clip's relational features.
    templates : sequence of MotionTemplate
        Templates over the same features.
    delta : float
        The quantisation threshold δ.

    Returns
    -------
    pandas.DataFrame
        Best first: label, cost (DTW cost normalised by template + clip frames).

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §6 (classification by the nearest template).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.features import relational_features
    >>> db = MotionDB.sample()
    >>> values, _ = relational_features(db, "2006", progress=False)
    >>> squat = learn_class(db, "squat1Reps", actors=["dg"], values=values)
    >>> kick = learn_class(db, "kickLFront1Reps", actors=["dg"], values=values)
    >>> classify(values[db.frames(22)], [squat, kick])["label"].tolist()  # a squat of actor mm
    ['squat1Reps', 'kickLFront1Reps']
    """
    x = np.asarray(values)
    rows = []
    for t in templates:
        cost, _ = dtw(t.quantised(delta), x, distance=quantised_distance)
        rows.append({"label": t.label, "cost": cost / (len(t.values) + len(x))})
    if not rows:
        raise ParameterError("classify needs at least one template")
    return pd.DataFrame(rows).sort_values("cost", kind="stable").reset_index(drop=True)


def learn_class(db, label: str, actors=None, relational_set: str = "2006", values: np.ndarray | None = None,
                iterations: int = ITERATIONS, group: str = "actor", by_group: bool = True,
                max_examples: int | None = None, segments: pd.DataFrame | None = None,
                extra: list | None = None) -> MotionTemplate:  # fmt: skip
    """Learn the template of the documents of a MotionDB with ``label`` (of ``actors`` only, when given), of the
    stretches labelled so (``segments``), and of clips that are no documents (``extra``: an uploaded take).

    Parameters
    ----------
    db : MotionDB
        The database holding the examples.
    label : str
        A value of the documents' ``label`` column.
    actors : sequence of str, optional
        Only the documents whose ``group`` column (default ``actor``) is one of these.
    relational_set : {"2005", "2006"}
        The features (default the 39 of Müller & Röder 2006, as in the paper).
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's relational features when already computed.
    iterations : int
        At most this many rounds, see :func:`learn_template`.
    group : str
        The column ``actors`` selects from (e.g. ``style`` in Bandai Namco's data).
    by_group : bool
        Keep each group's mean (``learn_template(..., groups=...)`` with the examples' ``group`` values, when the
        documents have that column), so that a feature counts only when it is consistent in (almost) every group
        (:meth:`MotionTemplate.quantised`); False: judge the pooled examples, as earlier versions did.
    max_examples : int, optional
        Learn from at most this many of the class's documents, spread evenly over them in document order (first and
        last included). Learning grows faster than the examples (a class of 208 takes: 16 minutes; 16 of them: 2
        s), and a template of hundreds of takes of different styles cares for little more than what every take
        of the database shares. Default: all of them.
    segments : pandas.DataFrame, optional
        ``doc_id``, ``start``, ``end`` (frames of the document, half-open) of segment labels of the class
        (:meth:`mocapviz.db.segments.SegmentLabels.table`): each stretch is an example beside the documents whose
        file-name label is ``label`` (spread over with them by ``max_examples``), and their documents are no
        negatives.
    extra : list of np.ndarray [shape=(T_i, f)], bool, optional
        The relational features (``relational_set``) of more examples that are no documents of ``db`` (a take of
        the user's, :meth:`mocapviz.engine.Engine.clip_relational`), each always learned from (``max_examples``
        spreads over the database's examples only), in a group of its own when learned by group.

    Returns
    -------
    MotionTemplate
        ``meta`` holds the relational set, the example doc ids, the class's documents and segments
        (``class_documents``, more than the examples with ``max_examples``; of the examples, ``file_examples``
        documents and ``segment_examples`` segments, and ``extra_examples``), the actors, the database path and its
        ``generation`` (``db.manifest["generation"]``: the state of the database it was learned from),
        ``groups`` when learned by group, and the learned ``threshold`` (:func:`separating_threshold` of the
        examples' costs, judged as unseen when learned by group, and the best costs of the documents of other
        labels, of ``actors`` when given, at most :data:`MAX_NEGATIVES` of them spread evenly: ``negatives`` of
        them, the least ``nearest_negative``; the examples' worst cost stays ``example_threshold``).

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §3-4 (a class template from its labelled examples).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> t = learn_class(db, "squat1Reps")  # the two squats of the sample, the 39 features of 2006
    >>> t.values.shape, t.n_examples, t.meta["doc_ids"], t.meta["example_frames"]
    ((159, 39), 2, [11, 22], [159, 189])
    >>> float((t.quantised(0.1) == 0.5).mean().round(2))  # share of don't-care entries
    0.12
    """
    docs = db.documents
    labelled = docs["label"].astype("string").isin([str(label)]).to_numpy(bool)  # an unlabelled document: False
    chosen, extra = _class_examples(docs, labelled, segments), list(extra or [])
    if actors is not None:
        if group not in docs.columns:
            raise ParameterError(f"{db.path}: the documents have no {group} column; leave actors out")
        chosen = chosen[chosen[group].astype("string").isin([str(a) for a in actors])]
    if chosen.empty and not extra:
        known = ", ".join(sorted(map(str, docs["label"].dropna().unique()))[:20])
        raise ParameterError(f"no document of {db.path} has label {label!r}"
                             + (f" and {group} in {list(actors)}" if actors is not None else "")
                             + f", nor any segment label; labels: {known}")  # fmt: skip
    of_class, class_docs = len(chosen), chosen["doc_id"].to_numpy()  # every example's document: never a negative
    if max_examples is not None and of_class > count(max_examples, "max_examples"):
        chosen = chosen.iloc[np.linspace(0, of_class - 1, max_examples).round().astype(np.int64)]
    if values is None:
        values, names = relational_features(db, relational_set, progress=False)
    else:
        names = feature_names(relational_set)
    examples = [values[s : s + n] for s, n in zip(chosen["start"], chosen["n_frames"])]
    for i, clip in enumerate(extra):
        if np.ndim(clip) != 2 or np.shape(clip)[1] != len(names) or len(clip) < 2:
            raise ParameterError(f"extra example {i}: {np.shape(clip)} values, not (T >= 2, {len(names)}) of the "
                                 f"{relational_set} set")  # fmt: skip
    groups = None
    if by_group and group in docs.columns and chosen[group].notna().all():
        groups = chosen[group].astype(str).tolist() + [f"extra {i}" for i in range(len(extra))]
    template = learn_template(examples + [np.asarray(c, dtype=bool) for c in extra], names, str(label), iterations,
                              groups=groups)  # fmt: skip
    others = docs["label"].notna().to_numpy() & ~labelled & ~docs["doc_id"].isin(class_docs).to_numpy()
    if actors is not None:
        others &= docs[group].astype("string").isin([str(a) for a in actors]).to_numpy(bool)
    negatives = _negative_costs(template, values, docs[others])
    positives = template.meta.get("unseen_costs", template.meta["example_costs"])
    template.meta |= {"threshold": separating_threshold(positives, negatives), "negatives": len(negatives),
                      "nearest_negative": float(negatives.min()) if len(negatives) else None}  # fmt: skip
    template.meta |= {"relational_set": str(relational_set), "doc_ids": chosen["doc_id"].astype(int).tolist(),
                      "class_documents": of_class, "segment_examples": int(chosen["segment"].sum()),
                      "file_examples": int((~chosen["segment"]).sum()), "extra_examples": len(extra),
                     "database": str(db.path), "generation": db.manifest["generation"],
                     "actors": None if actors is None else [str(a) for a in actors]}
    return template


def _class_examples(docs: pd.DataFrame, labelled: np.ndarray, segments: pd.DataFrame | None) -> pd.DataFrame:
    """The examples of a class as rows of ``docs`` (``start``, ``n_frames``: database-wide frames of each example):
    its file-labelled documents whole, then each segment's stretch (its document's row, narrowed), marked by a
    ``segment`` column."""
    whole = docs[labelled].assign(segment=False)
    if segments is None or not len(segments):
        return whole
    rows = docs.set_index("doc_id", drop=False).loc[np.asarray(segments["doc_id"], np.int64)].reset_index(drop=True)
    rows["start"] = rows["start"].to_numpy(np.int64) + np.asarray(segments["start"], np.int64)
    rows["n_frames"] = np.asarray(segments["end"], np.int64) - np.asarray(segments["start"], np.int64)
    return pd.concat([whole, rows.assign(segment=True)], ignore_index=True)


def _negative_costs(template: MotionTemplate, values: np.ndarray, others: pd.DataFrame) -> np.ndarray:
    """The best normalised cost (:func:`document_costs`, finite ones) in each of the documents ``others`` (rows of
    ``db.documents``), at most :data:`MAX_NEGATIVES` of them spread evenly in their order (a template pass over
    every other document of a large database would double the learning: 0.5 s more for a walk of 240 rows among
    446,551 frames)."""
    if len(others) > MAX_NEGATIVES:
        others = others.iloc[np.linspace(0, len(others) - 1, MAX_NEGATIVES).round().astype(np.int64)]
    if others.empty:
        return np.empty(0)
    lengths = others["n_frames"].to_numpy(np.int64)
    frames = np.repeat(others["start"].to_numpy(np.int64), lengths) + (
        np.arange(lengths.sum()) - np.repeat(np.r_[0, np.cumsum(lengths)[:-1]], lengths))
    costs = document_costs(template, values[frames], np.r_[0, np.cumsum(lengths)[:-1]])
    return costs[np.isfinite(costs)]


def separating_threshold(positives, negatives) -> float:
    """The normalised cost up to which a template's matches count as its class: learned from the class's examples
    and the other classes' documents.

    Of the positive costs, the one at which "cost <= it" has the best F1 (true matches: the positives up to it;
    false: the negatives up to it; the least such cost when several tie), raised halfway to the least negative
    above it (none above: kept). Without negatives this is the highest positive cost, the examples' worst.

    Parameters
    ----------
    positives : array_like [shape=(p,)], float
        Each example's best normalised match cost (judged as an unseen example would be: ``meta["unseen_costs"]``).
    negatives : array_like [shape=(n,)], float
        The best normalised cost in each document of another class (:func:`document_costs`), finite.

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        No positive cost.

    Examples
    --------
    >>> separating_threshold([0.01, 0.02, 0.06], [0.03, 0.04, 0.05])  # 0.06: one more example, three impostors
    0.025
    >>> round(separating_threshold([0.01, 0.05], [0.1, 0.2]), 6)  # apart: halfway between the classes
    0.075
    >>> separating_threshold([0.01, 0.05], [])
    0.05
    """
    pos = np.sort(np.asarray(positives, dtype=np.float64).reshape(-1))
    neg = np.sort(np.asarray(negatives, dtype=np.float64).reshape(-1))
    if not len(pos):
        raise ParameterError("no example cost: a threshold needs the class's examples")
    tp = np.searchsorted(pos, pos, side="right")
    fp = np.searchsorted(neg, pos, side="right")
    f1 = 2 * tp / (2 * tp + fp + (len(pos) - tp))
    best = pos[int(np.argmax(f1))]
    above = neg[neg > best]
    return float((best + above[0]) / 2) if len(above) else float(best)


def is_template_name(name) -> bool:
    """Whether ``name`` can name a stored template: 1 to 128 letters, digits, ``.``, ``_`` and ``-``, not starting
    with ``.`` (so never a path: no ``/``, never ``..``).

    Examples
    --------
    >>> is_template_name("squat1Reps-dg-mm"), is_template_name("/etc/passwd"), is_template_name("../t")
    (True, False, False)
    """
    return isinstance(name, str) and _NAME.fullmatch(name) is not None


def template_path(db, name: str) -> Path:
    """Where the template ``name`` of a MotionDB is stored: ``DB/templates/<name>.npz``.

    ``name`` is filename-safe (:func:`is_template_name`); anything else is a ParameterError.

    Parameters
    ----------
    db : MotionDB
        The database.
    name : str
        The template's name.

    Returns
    -------
    pathlib.Path
        ``DB/templates/<name>.npz`` (:func:`mocapviz.db.layout.template_file`).
    """
    if not is_template_name(name):
        raise ParameterError(f"template name {name!r} is not filename-safe: use letters, digits, '.', '_' and '-' "
                             "(not first '.'), at most 128 characters")
    return layout.template_file(db.path, name)


def store_template(db, template: MotionTemplate, name: str | None = None) -> Path:
    """Store a template with a MotionDB's derived data (:func:`template_path`), replacing one of that name.

    Parameters
    ----------
    db : MotionDB
        The database (writable).
    template : MotionTemplate
        The template to store.
    name : str, optional
        Default the label, then ``-`` and each actor when it was learned from some only (``squat1Reps-bd-dg``),
        with every character that is not filename-safe replaced by ``_``.

    Returns
    -------
    pathlib.Path
        The stored file (written atomically under the lock of ``DB/templates/``).
    """
    if name is None:
        words = [template.label, *(template.meta.get("actors") or [])]
        name = _SAFE.sub("_", "-".join(words)).lstrip(".") or "template"
    path = template_path(db, name)
    path.parent.mkdir(exist_ok=True)
    with store.locked(path.parent):
        template.save(path)
    return path


def load_template(db, name: str) -> MotionTemplate:
    """The template stored as ``name`` with a MotionDB (:func:`store_template`), whatever database generation it was
    learned from (a template is portable; :func:`stored_templates` shows the generation).

    Parameters
    ----------
    db : MotionDB
        The database it is stored with.
    name : str
        The name it was stored under.

    Returns
    -------
    MotionTemplate

    Raises
    ------
    UnknownKeyError
        No template of that name is stored, or ``name`` is not a stored template's name (:func:`template_path`: a
        path, a suffix of another folder, ...): one message for both, whether or not a file of that name exists
        anywhere, naming the stored ones. Nothing outside ``DB/templates/`` is looked at.
    MotionDBError
        The stored file is damaged; the message names it.
    """
    path = template_path(db, name) if is_template_name(name) else None
    if path is None or not path.is_file():
        stored = ", ".join(layout.template_files(db.path)) or "none"
        shown = repr(name) if len(str(name)) <= 128 else f"{str(name)[:60]!r}... ({len(str(name))} characters)"
        raise UnknownKeyError(f"no stored template {shown} in {db.path}; stored: {stored} "
                              f"(`mocapviz template learn {db.path} --label CLASS` stores one)")  # fmt: skip
    return MotionTemplate.load(path)


def stored_templates(db) -> pd.DataFrame:
    """The templates stored with a MotionDB, by name.

    Parameters
    ----------
    db : MotionDB
        The database.

    Returns
    -------
    pandas.DataFrame
        One row per template: name, label, n_examples, frames (template rows), relational_set, actors
        (comma-separated; empty when learned from every actor), generation (of the database it was learned from;
        None when unknown) and current (that generation is the database's now).

    Raises
    ------
    MotionDBError
        A damaged file; the message names it.
    """
    rows = []
    for name, path in layout.template_files(db.path).items():
        t = MotionTemplate.load(path)
        rows.append({"name": name, "label": t.label, "n_examples": t.n_examples, "frames": len(t.values),
                     "relational_set": t.meta.get("relational_set"), "actors": ",".join(t.meta.get("actors") or []),
                     "generation": t.meta.get("generation"),
                     "current": t.meta.get("generation") == db.manifest["generation"]})  # fmt: skip
    columns = ["name", "label", "n_examples", "frames", "relational_set", "actors", "generation", "current"]
    return pd.DataFrame(rows, columns=columns)


def _medoid(xs: list[np.ndarray]) -> int:
    """Index of the example of least summed normalised DTW cost to the others; ties go to the example that sorts
    first by (length, content), so that the choice does not depend on the order of the examples.

    The cost of two examples is :func:`mocapviz.match.dtw`'s with :func:`template_distance` (basic steps; between
    boolean frames, their differing features over f), over the sum of their lengths: computed by :func:`_pair_costs`
    on the frames packed into 64-bit words, every pair at once on threads, with the same sums in the same order."""
    n = len(xs)
    bounds = np.r_[0, np.cumsum([len(x) for x in xs])].astype(np.int64)
    words = _bit_rows(np.concatenate(xs))
    costs = np.zeros((n, n))
    groups = [np.arange(g, n, 4 * default_threads(), dtype=np.int64) for g in range(min(n, 4 * default_threads()))]
    list(map_ordered(lambda rows: _pair_costs(words, bounds, float(xs[0].shape[1]), rows, costs), groups,
                     name="mocapviz-medoid"))  # fmt: skip
    total = _summed(costs)
    best = np.flatnonzero(np.isclose(total, total.min(), rtol=0, atol=1e-12))
    return min(best, key=lambda i: (len(xs[i]), xs[i].tobytes()))


@numba.njit(cache=True, nogil=True)
def _pair_costs(words, bounds, f, rows, out):  # pragma: no cover
    """For each example i of ``rows`` and each later one j (frames ``bounds[i]:bounds[i + 1]`` of ``words``), the DTW
    cost of i against j over their lengths into ``out[i, j]``: the accumulation of :func:`mocapviz.match.dtw` (basic
    steps, diagonal first, the least predecessor plus the cell) with the cell cost of :func:`template_distance`,
    differing bits over ``f``."""
    n, w = len(bounds) - 1, words.shape[1]
    for i in rows:
        a0, m = bounds[i], bounds[i + 1] - bounds[i]
        prev, cur = np.empty(m), np.empty(m)
        for j in range(i + 1, n):
            b0, b1 = bounds[j], bounds[j + 1]
            for jj in range(b1 - b0):
                for ii in range(m):
                    bad = 0
                    for k in range(w):
                        bad += _set_bits(words[a0 + ii, k] ^ words[b0 + jj, k])
                    c = bad / f
                    if ii == 0 and jj == 0:
                        cur[ii] = c
                        continue
                    best = np.inf
                    if ii > 0 and jj > 0:
                        best = prev[ii - 1] + c
                    if ii > 0 and cur[ii - 1] + c < best:
                        best = cur[ii - 1] + c
                    if jj > 0 and prev[ii] + c < best:
                        best = prev[ii] + c
                    cur[ii] = best
                prev, cur = cur, prev
            out[i, j] = prev[m - 1] / (m + b1 - b0)


@numba.njit(cache=True)
def _summed(costs):  # pragma: no cover
    """Each example's sum of its pair costs (the upper triangle of ``costs``), added pair by pair in the order
    i = 0, 1, ..., j > i, as the medoid's definition reads."""
    n = len(costs)
    total = np.zeros(n)
    for i in range(n):
        for j in range(i + 1, n):
            total[i] += costs[i, j]
            total[j] += costs[i, j]
    return total


def _examples(examples, features) -> list[np.ndarray]:
    xs = [np.asarray(x) for x in examples]
    if not xs:
        raise ParameterError("a motion template needs at least one example")
    f = len(features)
    for i, x in enumerate(xs):
        if x.ndim != 2 or x.shape[1] != f or len(x) < 1:
            raise ParameterError(f"example {i} has shape {x.shape}; expected (frames >= 1, {f}) feature values")
        if not np.isin(x, (0, 1)).all():
            raise ParameterError(f"example {i} holds values other than 0/1 (boolean relational features expected)")
    return [x.astype(bool) for x in xs]


def search_template(db, template: MotionTemplate, n_matches: int = 10, delta: float = DELTA,
                    max_cost: float | None = None, prefilter: bool = False, values: np.ndarray | None = None,
                    indexes: dict | None = None, lower_bounds: bool = True) -> pd.DataFrame:  # fmt: skip
    """The instances of a motion template in a MotionDB, ranked, as the one hit table.

    Parameters
    ----------
    db : MotionDB
    template : MotionTemplate
        Learned on a relational set (its features are all of that set's, in order).
    n_matches : int
        At most this many non-overlapping instances (K >= 1).
    delta : float
        The quantisation threshold δ, 0 < δ < 0.5 (:data:`DELTA_RANGE`, :meth:`MotionTemplate.quantised`).
    max_cost : float, optional
        Keep only instances whose normalised cost (mean mismatch per template frame, in [0, 1]) is at most this.
    prefilter : bool
        Align only where the template's keyframes occur (:func:`keyframe_ranges` on the relational indexes,
        built and stored when missing): fast where the keyframes are rare, and it may miss a hit.
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's relational features of the template's set, if already computed (default: computed now).
    indexes : dict, optional
        Group -> InvertedIndex for ``prefilter``, if already loaded.
    lower_bounds : bool
        Without ``prefilter``: align the documents best lower bound first and stop when no other can hold one of
        the K best (:func:`find_instances` with ``bounds``; the answer is the full pass's), default; False: the full
        pass over every frame (Müller & Röder's matching as such).

    Returns
    -------
    pandas.DataFrame
        The hit table of :func:`mocapviz.db.hits.hit_table` (``start``, ``end``: frames of the document,
        half-open), with ``cost`` (the DTW cost, a sum of per-frame mean mismatches) and ``normalised_cost``.
        ``attrs``: ``relational_set``, ``ms`` (search time), ``aligned`` (share of the frames aligned: 1 for the
        full pass).

    Raises
    ------
    ParameterError
        A template whose features are not those of a relational set, a bad K, δ or max cost.

    References
    ----------
    .. [1] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §4-5 (matching a class template by subsequence DTW with don't-care entries).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> t = learn_class(db, "kickLFront1Reps", actors=["dg"])
    >>> hits = search_template(db, t, n_matches=3)
    >>> print(hits[["rank", "doc_id", "label", "start", "end", "normalised_cost"]].round(3).to_string(index=False))
     rank  doc_id           label  start  end  normalised_cost
        1       7 kickLFront1Reps      3  125            0.000
        2      12 throwBasketball      9   74            0.142
        3      18 kickLFront1Reps     31  130            0.148
    """
    relational_set = next((s for s in RELATIONAL_SETS if feature_names(s) == template.features), None)
    if relational_set is None:
        sets = ", ".join(f"{s}: {len(feature_names(s))}" for s in RELATIONAL_SETS)
        raise ParameterError(f"the template's {len(template.features)} features are not those of a relational set "
                             f"({sets}); learn it again with `mocapviz template learn`")
    n_matches = count(n_matches, "n_matches")
    delta = DELTA_RANGE.check(delta, "delta")
    if max_cost is not None:
        max_cost = MAX_COST_RANGE.check(max_cost, "max_cost (a mean mismatch per frame)")
    if values is None:
        values, _ = relational_features(db, relational_set, progress=False)
    starts = db.documents["start"].to_numpy()
    t0 = time.perf_counter()
    ranges = None
    if prefilter:
        from .index import load_or_build

        indexes = load_or_build(db, relational_set) if indexes is None else indexes
        ranges = keyframe_ranges(template, indexes, starts, db.n_frames, delta=delta)
    found = find_instances(template, values, starts, n_matches=n_matches, delta=delta, max_cost=max_cost,
                           ranges=ranges, bounds=lower_bounds)  # fmt: skip
    ms = 1e3 * (time.perf_counter() - t0)
    doc_ids = db.documents["doc_id"].to_numpy(np.int64)[found["doc_id"].to_numpy(np.int64)]
    table = hit_table(db, doc_ids, found["start"].to_numpy(np.int64), found["end"].to_numpy(np.int64),
                      cost=found["cost"].to_numpy(np.float64),
                      normalised_cost=found["normalised_cost"].to_numpy(np.float64))  # fmt: skip
    table.attrs.update(relational_set=relational_set, ms=ms, aligned=found.attrs["aligned"] / max(1, db.n_frames))
    return table
