"""Motion templates: a motion class learned from examples, and its instances found by DTW (Müller & Röder 2006).

A *motion template* (MT) of a class is a (K, f) matrix over the f relational features of a set (the 39 of the
"2006" set by default): each example's boolean feature matrix is time-warped onto a common reference and the
aligned columns are averaged, so a feature that is consistent across the examples stays near 0 or 1 and an
inconsistent one drifts towards the middle. Quantised with a threshold δ, the entries below δ become 0, those
above 1 − δ become 1 and the rest "don't care"; matching then ignores the don't-care entries, which is how the
template, not the user, chooses the features that matter (Müller & Röder 2006 §3–4).

learn_template      (T_i, f) feature matrices of n examples -> MotionTemplate (iterative warping and averaging).
find_instances      a template's matches in (N, f) feature values by subsequence DTW, best first (§5).
classify            a clip's (T, f) feature values against several templates: the classes by DTW cost (§6).
MotionTemplate      the real-valued template, its quantisation and the local cost of matching it.
template_distance   the masked l1 local cost of template rows against boolean frames, (K, n).
quantised_distance  the same for a quantised template, its don't-care entries left out (the matching cost).

Learning, as implemented here (our reading of the method, written independently): the reference starts as the
*medoid* example (least summed DTW cost to the others, normalised by the two lengths); each iteration aligns every
example to the current reference by DTW (local cost: mean absolute difference over the features) and replaces
each reference column by the mean, over the examples, of the example columns aligned to it (an example whose
several frames align to one column contributes their mean once). Iterations stop when no entry moves by more
than ``tol``. All examples are averaged at once, so the result does not depend on their order; the template has
the medoid's length.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .errors import ParameterError
from .match import dtw, subsequence_dtw
from .validation import count

DONT_CARE = 0.5  # the value a quantised template holds where a feature does not matter
DELTA = 0.1  # default quantisation threshold: < δ -> 0, > 1 - δ -> 1, else don't care
ITERATIONS = 10
TOL = 1e-6


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
    meta : dict, anything else worth keeping (relational set, the example documents, ...).
    """

    values: np.ndarray
    features: list[str]
    label: str = ""
    n_examples: int = 0
    iterations: int = 0
    meta: dict = field(default_factory=dict)

    def quantised(self, delta: float = DELTA) -> np.ndarray:
        """The template with entries < δ set to 0, > 1 − δ set to 1 and the rest to :data:`DONT_CARE` (0.5).

        Returns np.ndarray [shape=(K, f)], float64 in {0, 0.5, 1}.
        """
        delta = _delta(delta)
        out = np.full(self.values.shape, DONT_CARE)
        out[self.values < delta] = 0.0
        out[self.values > 1.0 - delta] = 1.0
        return out


def template_distance(template: np.ndarray, frames: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Mean absolute difference of template rows and frames over the features each row cares about.

    Parameters
    ----------
    template : np.ndarray [shape=(K, f)], values in [0, 1].
    frames : np.ndarray [shape=(n, f)], bool or {0, 1} (relational features of database frames).
    mask : np.ndarray [shape=(K, f)], bool, optional: the entries that count (default all). A row that cares
        about no feature costs 0 against every frame.

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


def quantised_distance(template: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """:func:`template_distance` of quantised template rows (values 0, 1 or :data:`DONT_CARE`), ignoring the
    don't-care entries: the local cost of matching a template, as ``distance=`` of
    :func:`mocapviz.match.subsequence_dtw`. Shapes as for :func:`template_distance`."""
    rows = np.asarray(template, dtype=np.float64)
    return template_distance(rows, frames, rows != DONT_CARE)


def learn_template(examples, features: list[str], label: str = "", iterations: int = ITERATIONS,
                   tol: float = TOL) -> MotionTemplate:  # fmt: skip
    """Learn a motion template from examples of one class (Müller & Röder 2006 §3–4; see the module docstring).

    Parameters
    ----------
    examples : sequence of np.ndarray [shape=(T_i, f)], bool or {0, 1}: the relational features of each example
        clip (e.g. rows of :func:`mocapviz.features.relational_features` of a document), at least one, each at
        least one frame, all with the same f.
    features : list of str [length f], the feature names of the columns.
    label : str, the class.
    iterations : int, at most this many warping-and-averaging rounds (default 10).
    tol : float, stop when no template entry changes by more than this.

    Returns
    -------
    MotionTemplate
    """
    xs = _examples(examples, features)
    count(iterations, "iterations")
    ref = xs[_medoid(xs)].astype(np.float64)
    done = 0
    for done in range(1, iterations + 1):
        new = np.zeros_like(ref)
        for x in xs:
            _, path = dtw(ref, x, distance=template_distance)
            sums = np.zeros_like(ref)
            np.add.at(sums, path[:, 0], x[path[:, 1]])
            new += sums / np.bincount(path[:, 0], minlength=len(ref))[:, None]
        new /= len(xs)
        moved = float(np.abs(new - ref).max())
        ref = new
        if moved <= tol:
            break
    return MotionTemplate(ref, list(features), label, len(xs), done)


def find_instances(template: MotionTemplate, values: np.ndarray, starts=None, n_matches: int = 10,
                   delta: float = DELTA, max_cost: float | None = None) -> pd.DataFrame:  # fmt: skip
    """The stretches of a database that match a template: subsequence DTW of the quantised template against the
    frames' relational features with the don't-care entries left out (:func:`quantised_distance`).

    Parameters
    ----------
    template : MotionTemplate
    values : np.ndarray [shape=(N, f)], bool: the database's relational features, columns as ``template.features``.
    starts : np.ndarray [shape=(B,)], int, optional: the first frame of every document (matches stay inside one).
    n_matches : int, at most this many non-overlapping matches.
    delta : float, the quantisation threshold.
    max_cost : float, optional: keep only matches whose ``normalised_cost`` (cost per template frame, the mean
        mismatch per frame in [0, 1]) is at most this.

    Returns
    -------
    pd.DataFrame, best first: doc_id (index into ``starts``), start, end (frames, inclusive), cost,
    normalised_cost.
    """
    x = np.asarray(values)
    if x.ndim != 2 or x.shape[1] != len(template.features):
        raise ParameterError(f"values have shape {x.shape}; the template needs (frames, {len(template.features)})")
    q = template.quantised(delta)
    hits = subsequence_dtw(q, x, starts, n_matches=n_matches, distance=quantised_distance, paths=False)
    hits = hits.drop(columns="path").assign(normalised_cost=hits["cost"] / len(q))
    if max_cost is not None:
        hits = hits[hits["normalised_cost"] <= max_cost].reset_index(drop=True)
    return hits


def classify(values: np.ndarray, templates, delta: float = DELTA) -> pd.DataFrame:
    """Rank the classes of several templates for one clip by whole-clip DTW cost (the nearest template first).

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool: the clip's relational features.
    templates : sequence of MotionTemplate (same features).
    delta : float, the quantisation threshold.

    Returns
    -------
    pd.DataFrame, best first: label, cost (DTW cost normalised by template + clip frames).
    """
    x = np.asarray(values)
    rows = []
    for t in templates:
        cost, _ = dtw(t.quantised(delta), x, distance=quantised_distance)
        rows.append({"label": t.label, "cost": cost / (len(t.values) + len(x))})
    if not rows:
        raise ParameterError("classify needs at least one template")
    return pd.DataFrame(rows).sort_values("cost", kind="stable").reset_index(drop=True)


def _medoid(xs: list[np.ndarray]) -> int:
    """Index of the example of least summed normalised DTW cost to the others; ties go to the example that sorts
    first by (length, content), so that the choice does not depend on the order of the examples."""
    n = len(xs)
    total = np.zeros(n)
    for i in range(n):
        for j in range(i + 1, n):
            c, _ = dtw(xs[i].astype(np.float64), xs[j], distance=template_distance)
            c /= len(xs[i]) + len(xs[j])
            total[i] += c
            total[j] += c
    best = np.flatnonzero(np.isclose(total, total.min(), rtol=0, atol=1e-12))
    return min(best, key=lambda i: (len(xs[i]), xs[i].tobytes()))


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


def _delta(delta) -> float:
    if not isinstance(delta, (int, float, np.floating)) or not 0.0 <= float(delta) < 0.5:
        raise ParameterError(f"delta must be a number in [0, 0.5); got {delta!r}")
    return float(delta)
