"""Finding what a scene description describes (Müller, Röder & Clausen 2005 §6.3): through the relational index,
and by a frame-wise scan that defines the answer.

Semantics (docs/descriptions.md):

- A **progression** ``part: s_1 ... s_L`` of feature f matches L consecutive maximal runs of f in one document whose
  values are s_1 ... s_L (``*``: either). Its first and last states only frame the motion: the hit runs from the
  last frame of the first run to the first frame of the last run (so ``straight bent straight`` is the bend, plus
  one frame on either side). Through the index it is the adaptive query of §5.2 on f's group index with only f
  selected (:meth:`~mocapviz.relational.index.InvertedIndex.adaptive_mismatch`; ``*`` steps are allowed
  mismatches).
- ``A for LO..HI s`` keeps the hits where every run in state A lasts LO..HI seconds at the document's rate.
- An **event** (progressions joined by ``and``) matches one hit of each progression, all sharing at least one frame;
  each ``overlap A, B`` needs a frame where a run in state A and a run in state B hold together. The event's hit is
  the union of its progressions' hits.
- ``A then B within T s``: a hit of A and a later hit of B in the same document, B starting at or after A's end and
  at most T s later; the hit spans from A's start to B's end. ``A | B``: the hits of either.
- A ``template:NAME`` atom's hits are the template's instances (:func:`~mocapviz.relational.templates.search_template`)
  whose normalised cost is at most ``template_cost`` (default: the template's learned threshold). NAME is a template
  stored with the database, or one the caller passes in ``templates``; never a path.

Every hit is scored by its length in seconds (the tightest first) and overlapping hits in one document are
resolved best first, as :func:`mocapviz.match.subsequence_dtw` does; ``overlapping=True`` keeps them all.
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace

import numba
import numpy as np
import pandas as pd

from ..db.hits import hit_table
from ..errors import DescriptionError, MotionDBError, ParameterError, UnknownKeyError
from ..validation import count, number, one_of
from .description import (
    MAX_PAIRS,
    Alternatives,
    Description,
    Event,
    Named,
    Progression,
    Sequence,
    TemplateAtom,
    declared_set,
    excerpt,
    parse_description,
    template_names,
    walk,
)
from .vocabulary import vocabulary_of

__all__ = ["TEMPLATE_COST", "describe", "empty_reason", "find", "find_by_scan", "read_description"]

TEMPLATE_COST = 0.15  # a template atom's instances without a learned threshold: normalised cost at most this
TEMPLATE_MATCHES = 100_000  # instances of a template atom considered at most


# ================================================================================================ hit sets
@dataclass
class _Hits:
    """The hits of one node: global frames [start, end), and how to recover the parts that made each one."""

    label: str
    start: np.ndarray
    end: np.ndarray
    children: list = field(default_factory=list)
    index: np.ndarray | None = None  # (n, len(children)) rows of the children joined into each hit
    pick: np.ndarray | None = None  # alternatives: (n,) which child each hit comes from (index: its row there)

    def __len__(self) -> int:
        return int(self.start.size)


def _leaf(label: str, start, end) -> _Hits:
    start, end = np.asarray(start, dtype=np.int64), np.asarray(end, dtype=np.int64)
    order = np.lexsort((end, start))
    start, end = start[order], end[order]
    keep = np.ones(start.size, dtype=bool)
    keep[1:] = (np.diff(start) != 0) | (np.diff(end) != 0)
    return _Hits(label, start[keep], end[keep])


def _unique(label: str, start, end, children, index) -> _Hits:
    """Joined hits, one per distinct (start, end) (the first of each in (start, end, rows) order)."""
    start, end = np.asarray(start, dtype=np.int64), np.asarray(end, dtype=np.int64)
    index = np.asarray(index, dtype=np.int64)
    order = np.lexsort((*index.T[::-1], end, start))
    start, end, index = start[order], end[order], index[order]
    keep = np.ones(start.size, dtype=bool)
    keep[1:] = (np.diff(start) != 0) | (np.diff(end) != 0)
    return _Hits(label, start[keep], end[keep], children, index[keep])


# ================================================================================================ the context
class _Context:
    """What evaluating a description over one database needs: documents, rates, relational values or indexes."""

    def __init__(self, db, relational_set: str, template_cost: float, templates: dict, indexes=None, values=None):
        self.db, self.relational_set, self.template_cost, self.templates = db, relational_set, template_cost, templates
        docs = db.documents
        self.doc_start = docs["start"].to_numpy(np.int64)
        self.doc_end = self.doc_start + docs["n_frames"].to_numpy(np.int64)
        self.fps = docs["fps"].to_numpy(np.float64)
        self.indexes, self.values = indexes, values
        self.counts: list[tuple[str, int]] = []  # (node, raw hits), in evaluation order (--explain)
        self.cache: dict = {}  # per feature: what the state conditions count frames with
        self.memo: dict = {}  # (id(node), prefix) -> its hits: every distinct node evaluated once per run

    def doc_of(self, frames: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.doc_start, frames, side="right") - 1

    def seconds(self, frames: np.ndarray, at: np.ndarray) -> np.ndarray:
        """``frames`` (counts) in seconds at the rate of the documents holding frames ``at``."""
        return frames / self.fps[self.doc_of(at)]

    def note(self, label: str, hits: _Hits) -> _Hits:
        self.counts.append((label, len(hits)))
        return hits


def _label(prefix: str, node) -> str:
    text = node.part if isinstance(node, Progression) else str(node)
    return f"{prefix}/{text}" if prefix else text


# ================================================================================================ runs
def _index_runs(ctx: _Context, p: Progression) -> tuple[np.ndarray, np.ndarray]:
    """(run starts, run ends) [shape=(H, L)], global frames, of the progression's hits, from the relational index."""
    group = vocabulary_of(ctx.relational_set).group[p.feature]
    index = ctx.indexes[group]
    bit = index.feature_names.index(p.feature)
    stars = [k for k, v in enumerate(p.values) if v is None]
    query = np.array([(v or 0) << bit for v in p.values], dtype=np.int64)
    rows = index.adaptive_mismatch(query, [bit], m=len(stars), allowed=stars or None)
    n = len(p.values)
    starts = index.starts[rows[:, :n]]
    last = rows[:, n] - 1
    ends = np.concatenate([starts[:, 1:], (index.starts[last] + index.lengths[last])[:, None]], axis=1)
    return starts, ends


def _scan_runs(ctx: _Context, p: Progression) -> tuple[np.ndarray, np.ndarray]:
    """The same as :func:`_index_runs`, by walking the runs of the feature's frame-wise values in every document."""
    from ..features import feature_names

    column = ctx.values[:, feature_names(ctx.relational_set).index(p.feature)]  # column order, not the groups'
    n = len(p.values)
    found_s, found_e = [], []
    for a, b in zip(ctx.doc_start, ctx.doc_end):
        x = column[a:b]
        cuts = np.flatnonzero(x[1:] != x[:-1]) + 1
        run_start = np.concatenate([[0], cuts]) + a
        run_end = np.concatenate([cuts, [b - a]]) + a
        run_value = x[run_start - a]
        for k in range(len(run_start) - n + 1):
            if all(v is None or run_value[k + i] == v for i, v in enumerate(p.values)):
                found_s.append(run_start[k : k + n])
                found_e.append(run_end[k : k + n])
    if not found_s:
        return np.empty((0, n), dtype=np.int64), np.empty((0, n), dtype=np.int64)
    return np.array(found_s, dtype=np.int64), np.array(found_e, dtype=np.int64)


def _frames_in_state(ctx: _Context, feature: str, value: int, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Frames of [lo, hi) (global, per row) where ``feature`` == ``value``: from the group index's segments (their
    codes hold the feature's bit), or by the scan from the frame-wise column."""
    key = ("ones", feature)
    if key not in ctx.cache:
        if ctx.indexes:
            index = ctx.indexes[vocabulary_of(ctx.relational_set).group[feature]]
            bit = (index.codes >> index.feature_names.index(feature)) & 1
            ones = np.concatenate([[0], np.cumsum(bit * index.lengths)])
            ctx.cache[key] = (index.starts, bit, ones)
        else:
            from ..features import feature_names

            column = ctx.values[:, feature_names(ctx.relational_set).index(feature)]  # column order, not the groups'
            ctx.cache[key] = np.concatenate([[0], np.cumsum(column, dtype=np.int64)])
    got = ctx.cache[key]
    if isinstance(got, tuple):
        starts, bit, ones = got

        def before(f):  # frames with the bit set among the frames before f
            seg = np.searchsorted(starts, f, side="right") - 1
            return ones[seg] + (f - starts[seg]) * bit[seg]

        count = before(hi) - before(lo)
    else:
        count = got[hi] - got[lo]
    return count if value == 1 else (hi - lo) - count


def _framed(ctx: _Context, p: Progression, starts: np.ndarray, ends: np.ndarray, durations) -> tuple:
    """Runs kept by the event's duration conditions on this progression, and the hits they frame: from the last frame
    of the first run to the first frame of the last run, inclusive (half-open: ``end(r_1) - 1 .. start(r_L) + 1``)."""
    keep = np.ones(len(starts), dtype=bool)
    for d in durations:
        lengths = ctx.seconds(ends[:, list(d.ref.steps)] - starts[:, list(d.ref.steps)], starts[:, :1])
        if d.low is not None:
            keep &= (lengths >= d.low - 1e-9).all(axis=1)
        if d.high is not None:
            keep &= (lengths <= d.high + 1e-9).all(axis=1)
    starts, ends = starts[keep], ends[keep]
    return starts, ends, ends[:, 0] - 1, starts[:, -1] + 1


# ================================================================================================ the index path
def _evaluate(ctx: _Context, node, prefix: str = "") -> _Hits:
    """The hits of a description node, each distinct node once per run however often a name uses it (a chain of n
    definitions each using the previous one twice costs n evaluations, not 2**n; ``ctx.memo``)."""
    key = (id(node), prefix)
    if key not in ctx.memo:
        ctx.memo[key] = _evaluate_node(ctx, node, prefix)
    return ctx.memo[key]


def _evaluate_node(ctx: _Context, node, prefix: str) -> _Hits:
    if isinstance(node, Named):
        hits = replace(_evaluate(ctx, node.body, node.name), label=node.name)  # the body's hits may be shared
        return ctx.note(node.name, hits) if not isinstance(node.body, Named) else hits
    if isinstance(node, TemplateAtom):
        return ctx.note(str(node), _template_hits(ctx, node))
    if isinstance(node, Event):
        return _event(ctx, node, prefix)
    if isinstance(node, Sequence):
        first, second = _evaluate(ctx, node.first, prefix), _evaluate(ctx, node.second, prefix)
        return ctx.note(str(node), _then(ctx, first, second, node.within, str(node)))
    if isinstance(node, Alternatives):
        options = [_evaluate(ctx, o, prefix) for o in node.options]
        return ctx.note(str(node), _union(str(node), options))
    raise TypeError(f"not a description node: {node!r}")


def _event(ctx: _Context, event: Event, prefix: str) -> _Hits:
    runs, leaves = [], []
    for i, p in enumerate(event.progressions):
        starts, ends = (_index_runs if ctx.indexes is not None else _scan_runs)(ctx, p)
        starts, ends, a, b = _framed(ctx, p, starts, ends, [d for d in event.durations if d.ref.progression == i])
        runs.append((starts, ends))
        leaves.append(ctx.note(_label(prefix, p), _Hits(_label(prefix, p), a, b)))
    if len(leaves) == 1 and not event.overlaps and not event.conditions:
        return leaves[0]
    rows = _concurrent(ctx, leaves, prefix or str(event)) if ctx.indexes is not None else _concurrent_scan(ctx, leaves)
    ok = np.ones(len(rows), dtype=bool)
    for o in event.overlaps:
        (sa, ea), (sb, eb) = runs[o.a.progression], runs[o.b.progression]
        ia, ib = rows[:, o.a.progression], rows[:, o.b.progression]
        meet = np.zeros(len(rows), dtype=bool)
        for s in o.a.steps:
            for t in o.b.steps:
                meet |= (sa[ia, s] < eb[ib, t]) & (sb[ib, t] < ea[ia, s])
        ok &= meet
    rows = rows[ok]
    if event.conditions and len(rows):
        lo = np.min([leaf.start[rows[:, k]] for k, leaf in enumerate(leaves)], axis=0)
        hi = np.max([leaf.end[rows[:, k]] for k, leaf in enumerate(leaves)], axis=0)
        for c in event.conditions:
            held = _frames_in_state(ctx, c.feature, c.value, lo, hi)
            rows = rows[held > 0] if c.kind == "somewhere" else rows[held == 0]
            lo, hi = (lo[held > 0], hi[held > 0]) if c.kind == "somewhere" else (lo[held == 0], hi[held == 0])
    start = np.min([leaf.start[rows[:, k]] for k, leaf in enumerate(leaves)], axis=0) if len(rows) else rows[:, 0]
    end = np.max([leaf.end[rows[:, k]] for k, leaf in enumerate(leaves)], axis=0) if len(rows) else rows[:, 0]
    joined = _unique(prefix or str(event), start, end, leaves, rows)
    return joined if prefix else ctx.note(str(event), joined)


def _concurrent(ctx: _Context, leaves: list[_Hits], label: str) -> np.ndarray:
    """Rows (one per leaf) of the tuples of hits that share a frame, by sorted interval joins (of event ``label``)."""
    rows = np.arange(len(leaves[0]))[:, None]
    lo, hi = leaves[0].start.copy(), leaves[0].end.copy()
    for leaf in leaves[1:]:
        order = np.argsort(leaf.start, kind="stable")
        s, e = leaf.start[order], leaf.end[order]
        longest = int((e - s).max()) if len(s) else 0
        first = np.searchsorted(s, lo - longest, side="left")
        stop = np.searchsorted(s, hi, side="left")
        i, j = _expand(first, stop, label)
        j = order[j]
        keep = leaf.end[j] > lo[i]
        i, j = i[keep], j[keep]
        rows = np.concatenate([rows[i], j[:, None]], axis=1)
        lo, hi = np.maximum(lo[i], leaf.start[j]), np.minimum(hi[i], leaf.end[j])
    return rows


def _expand(first: np.ndarray, stop: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """All pairs (i, j) with first[i] <= j < stop[i]; a DescriptionError naming part ``label`` when they are more
    than :data:`~mocapviz.relational.description.MAX_PAIRS` (checked before they are made)."""
    sizes = np.maximum(stop - first, 0)
    total = int(sizes.sum())
    if total > MAX_PAIRS:
        raise DescriptionError(f"{excerpt(label)} joins {total:,} pairs of hits; at most {MAX_PAIRS:,} "
                               "(docs/descriptions.md, \"Limits\"): a shorter 'within' or fewer '*' steps ask for "
                               "fewer")  # fmt: skip
    i = np.repeat(np.arange(first.size), sizes)
    offsets = np.arange(total) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return i, first[i] + offsets


def _then(ctx: _Context, a: _Hits, b: _Hits, within: float, label: str) -> _Hits:
    if ctx.indexes is None:
        return _then_scan(ctx, a, b, within, label)
    order = np.argsort(b.start, kind="stable")
    s = b.start[order]
    doc = ctx.doc_of(a.start)
    # frames after A's end, at most to its document's end: a longer bound is no bound (and never overflows int64)
    gap = np.minimum(np.floor(within * ctx.fps[doc] + 1e-9), ctx.doc_end[doc] - a.end)
    reach = a.end + gap.astype(np.int64)
    i, j = _expand(np.searchsorted(s, a.end, side="left"), np.searchsorted(s, reach, side="right"), label)
    j = order[j]
    same = ctx.doc_of(b.start[j]) == ctx.doc_of(a.start[i])
    i, j = i[same], j[same]
    return _unique(label, a.start[i], b.end[j], [a, b], np.stack([i, j], axis=1))


def _union(label: str, options: list[_Hits]) -> _Hits:
    start = np.concatenate([o.start for o in options])
    end = np.concatenate([o.end for o in options])
    which = np.concatenate([np.full(len(o), k) for k, o in enumerate(options)]).astype(np.int64)
    row = np.concatenate([np.arange(len(o)) for o in options]).astype(np.int64)
    hits = _unique(label, start, end, options, np.stack([which, row], axis=1))
    hits.pick, hits.index = hits.index[:, 0], hits.index[:, 1:]
    return hits


def _template_hits(ctx: _Context, atom: TemplateAtom) -> _Hits:
    from .templates import search_template

    template = ctx.templates[atom.name]
    cost = ctx.template_cost
    if cost is None:  # the template's learned threshold (separating_threshold)
        cost = min(1.0, float(template.meta.get("threshold", TEMPLATE_COST)))
    found = search_template(ctx.db, template, n_matches=TEMPLATE_MATCHES, max_cost=cost, values=ctx.values)
    offset = ctx.doc_start[np.searchsorted(ctx.db.documents["doc_id"].to_numpy(), found["doc_id"].to_numpy())]
    return _leaf(str(atom), found["start"].to_numpy() + offset, found["end"].to_numpy() + offset)


# ================================================================================================ the scan path
def _concurrent_scan(ctx: _Context, leaves: list[_Hits]) -> np.ndarray:
    """:func:`_concurrent` by checking every combination of hits within each document."""
    doc = [ctx.doc_of(leaf.start) for leaf in leaves]
    rows = []
    for d in np.unique(doc[0]):
        per = [np.flatnonzero(x == d) for x in doc]
        for combo in itertools.product(*per):
            lo = max(leaves[k].start[r] for k, r in enumerate(combo))
            hi = min(leaves[k].end[r] for k, r in enumerate(combo))
            if lo < hi:
                rows.append(combo)
    return np.array(rows, dtype=np.int64).reshape(-1, len(leaves))


def _then_scan(ctx: _Context, a: _Hits, b: _Hits, within: float, label: str) -> _Hits:
    pairs = []
    for i in range(len(a)):
        d = ctx.doc_of(a.start[i : i + 1])[0]
        for j in range(len(b)):
            gap = b.start[j] - a.end[i]
            if ctx.doc_of(b.start[j : j + 1])[0] == d and 0 <= gap <= within * ctx.fps[d] + 1e-9:
                pairs.append((i, j))
    pairs = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    return _unique(label, a.start[pairs[:, 0]], b.end[pairs[:, 1]], [a, b], pairs)


# ================================================================================================ ranking
def _part_texts(hits: _Hits, rows: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``parts`` of hits ``rows``: each leaf's ``label start:end`` (frames of the document: global minus ``offset``),
    joined by ", ", walking the hit tree once for all rows (never into a branch no row takes)."""
    out = np.empty(rows.size, dtype=object)
    if not rows.size:
        return out
    if hits.pick is not None:
        for branch, child in enumerate(hits.children):
            mask = hits.pick[rows] == branch
            out[mask] = _part_texts(child, hits.index[rows[mask], 0], offset[mask])
        return out
    if not hits.children:
        out[:] = [f"{hits.label} {s}:{e}" for s, e in zip(hits.start[rows] - offset, hits.end[rows] - offset)]
        return out
    texts = [_part_texts(child, hits.index[rows, k], offset) for k, child in enumerate(hits.children)]
    out[:] = [", ".join(t) for t in zip(*texts)]
    return out



@numba.njit(cache=True)
def _non_overlapping(start, end, order, n_frames, limit):  # pragma: no cover - compiled
    taken = np.zeros(n_frames, dtype=np.bool_)
    out = np.empty(order.size, dtype=np.int64)
    n = 0
    for r in order:
        free = True
        for f in range(start[r], end[r]):
            if taken[f]:
                free = False
                break
        if free:
            taken[start[r] : end[r]] = True
            out[n] = r
            n += 1
            if n == limit:
                break
    return out[:n]


def _ranked(ctx: _Context, hits: _Hits, n_matches: int | None, overlapping: bool) -> pd.DataFrame:
    score = ctx.seconds(hits.end - hits.start, hits.start)
    order = np.lexsort((hits.start, score))
    limit = len(hits) if n_matches is None else n_matches
    if overlapping:
        chosen = order[:limit]
    else:
        chosen = _non_overlapping(hits.start, hits.end, order.astype(np.int64), int(ctx.doc_end.max(initial=0)),
                                  limit)  # fmt: skip
    doc_row = ctx.doc_of(hits.start[chosen])
    offset = ctx.doc_start[doc_row]
    parts = _part_texts(hits, chosen, offset)
    doc_ids = ctx.db.documents["doc_id"].to_numpy()[doc_row]
    return hit_table(ctx.db, doc_ids, hits.start[chosen] - offset, hits.end[chosen] - offset,
                     score=score[chosen], parts=np.array(parts, dtype=object))  # fmt: skip


# ================================================================================================ the entry points
def _load_template(db, name: str, given: dict):
    """The template of a ``template:NAME`` atom: the one the caller gave under NAME, else the one stored as NAME
    with ``db`` (:func:`~mocapviz.relational.templates.load_template`); never a file NAME points at."""
    from .templates import load_template

    if name in given:
        return given[name]
    try:
        return load_template(db, name)
    except UnknownKeyError as exc:  # one message for every unknown or refused name
        raise DescriptionError(str(exc)) from None
    except MotionDBError as exc:  # a damaged stored template, named
        raise DescriptionError(f"template:{name}: {exc}") from None


def read_description(db, description, relational_set: str | None = None, template_cost: float | None = None,
                     templates: dict | None = None) -> tuple[Description, float | None, dict]:
    """A description read for ``db``, as :func:`find` reads it (a sharded search reads it once, for every shard).

    Parameters
    ----------
    db : MotionDB
    description : str or Description
    relational_set : {"2005", "2006"}, optional
        As :func:`find`.
    template_cost : float, optional
        As :func:`find` (checked here).
    templates : dict, optional
        As :func:`find` (checked here).

    Returns
    -------
    parsed : Description
        Read in the relational set given, or the one the text names (``set 2006;``), or its templates' set, else
        "2005".
    template_cost : float or None
    templates : dict
        Name -> MotionTemplate of every template atom, each read once.

    Raises
    ------
    DescriptionError
        The text cannot be read, a template is neither given nor stored (or its name is not a stored template's
        name: one message for both, :func:`~mocapviz.relational.templates.load_template`), or it was learned on
        another relational set.
    """
    from ..db.database import MotionDB
    from ..features import RELATIONAL_SETS, feature_names
    from .templates import MotionTemplate, is_template_name

    if not isinstance(db, MotionDB):
        raise ParameterError(f"db must be a MotionDB; got {type(db).__name__}")
    if template_cost is not None:
        template_cost = number(template_cost, "template_cost (a mean mismatch per frame)", 0.0, 1.0)
    if relational_set is not None:
        one_of(relational_set, "relational set", RELATIONAL_SETS)
    given = dict(templates or {})
    for name, template in given.items():
        if not is_template_name(name) or not isinstance(template, MotionTemplate):
            raise ParameterError(f"templates must map template names (letters, digits, '.', '_', '-') to "
                                 f"MotionTemplates; got {str(name)[:60]!r}: {type(template).__name__}")  # fmt: skip
    if isinstance(description, Description):
        if relational_set is not None and relational_set != description.relational_set:
            raise ParameterError(f"the description was read with the {description.relational_set} set, not "
                                 f"{relational_set}")  # fmt: skip
        names, chosen = description.templates(), description.relational_set
    elif isinstance(description, str):
        names, chosen = template_names(description), relational_set or declared_set(description)
    else:
        raise ParameterError(f"description must be text or a Description; got {type(description).__name__}")
    templates, sets = {}, {}
    for name in names:
        templates[name] = _load_template(db, name, given)
        sets[name] = next((s for s in RELATIONAL_SETS if feature_names(s) == templates[name].features), None)
        if sets[name] is None:
            raise DescriptionError(f"template:{name} was not learned on a relational set's features")
    if chosen is None and len(set(sets.values())) > 1:
        raise DescriptionError(f"the templates were learned on different relational sets ({sets}); learn them on "
                               "one set")  # fmt: skip
    chosen = chosen or next(iter(sets.values()), "2005")
    other = [n for n, s in sets.items() if s != chosen]
    if other:
        raise DescriptionError(f"template:{other[0]} was learned on the {sets[other[0]]} relational set; this "
                               f"description is read with the {chosen} set: learn the template on {chosen} "
                               f"(`mocapviz template learn --relational-set {chosen}`) or find with the "
                               f"{sets[other[0]]} set")  # fmt: skip
    parsed = description if isinstance(description, Description) else parse_description(description, chosen)
    return parsed, template_cost, templates


def _has_events(node) -> bool:
    return any(isinstance(n, Event) for n in walk(node))


def empty_reason(counts: list[tuple[str, int]]) -> str:
    """Why a description found nothing: the first part with no hit, and what its parts found (or "" when every part
    found something). Without a "no hit" of its own: the CLI and the Describe page say that before it.

    Parameters
    ----------
    counts : list of (str, int)
        (part, hits) in evaluation order (``attrs["counts"]`` of :func:`find`).

    Returns
    -------
    str

    Examples
    --------
    >>> empty_reason([("kick_left", 3), ("kick_left then kick_left", 0)])
    "'kick_left then kick_left' found nothing (its parts found: kick_left (3))"
    >>> empty_reason([("kick_left", 3)])
    ''
    """
    zero = [label for label, n in counts if n == 0]
    if not zero:
        return ""
    first = zero[0]
    found = [f"{label} ({n})" for label, n in counts if n and label != first]
    if found:
        return f"'{first}' found nothing (its parts found: {', '.join(found[-3:])})"
    return f"'{first}' found nothing"


def _run(db, description, n_matches, relational_set, template_cost, overlapping, indexes, values, scan: bool,
         given: dict | None):
    parsed, template_cost, templates = read_description(db, description, relational_set, template_cost, given)
    n_matches = None if n_matches is None else count(n_matches, "n_matches")
    if scan:
        if values is None:
            from ..features import relational_features

            values, _ = relational_features(db, parsed.relational_set, progress=False)
        ctx = _Context(db, parsed.relational_set, template_cost, templates, values=values)
    else:
        if indexes is None and _has_events(parsed.root):
            from .index import load as load_indexes

            indexes = load_indexes(db, parsed.relational_set)
        ctx = _Context(db, parsed.relational_set, template_cost, templates, indexes={} if indexes is None else indexes,
                       values=values)
    t0 = time.perf_counter()
    hits = _evaluate(ctx, parsed.root)
    table = _ranked(ctx, hits, n_matches, overlapping)
    table.attrs.update(description=str(parsed), relational_set=parsed.relational_set, counts=ctx.counts,
                       candidates=len(hits), ms=1e3 * (time.perf_counter() - t0),
                       empty_reason=empty_reason(ctx.counts) if table.empty else "")  # fmt: skip
    return table


def find(db, description, n_matches: int | None = None, relational_set: str | None = None,
         template_cost: float | None = None, overlapping: bool = False, indexes: dict | None = None,
         values: np.ndarray | None = None, templates: dict | None = None) -> pd.DataFrame:  # fmt: skip
    """The stretches of a MotionDB that a scene description describes, through its relational indexes.

    Parameters
    ----------
    db : MotionDB
        With the relational index of the description's set (``mocapviz index DB``).
    description : str or Description
        The text (docs/descriptions.md) or a parsed :class:`~mocapviz.relational.description.Description`.
    n_matches : int, optional
        At most this many hits (default: all).
    relational_set : {"2005", "2006"}, optional
        The set whose words the text uses (default: its templates' set, else "2005").
    template_cost : float, optional
        A template atom's instances: normalised cost at most this (0..1; default: each template's learned
        threshold ``meta["threshold"]``, :func:`~mocapviz.relational.templates.separating_threshold`, else 0.15).
    overlapping : bool
        Keep hits that overlap a better one in the same document (default: the best of them only).
    indexes : dict, optional
        Group -> InvertedIndex, if already loaded.
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's relational values of the set, for template atoms, if already computed.
    templates : dict, optional
        Name -> :class:`~mocapviz.relational.templates.MotionTemplate` for ``template:NAME`` atoms, instead of the
        template stored as NAME (the CLI's ``--template-file NAME=FILE``). Otherwise NAME is only ever a template
        stored with ``db`` (``DB/templates/NAME.npz``): never a path.

    Returns
    -------
    pandas.DataFrame
        The hit table (:func:`mocapviz.db.hits.hit_table`) with ``score`` (the hit's length in seconds, shortest
        first) and ``parts`` (each progression or template and its frames within the document: ``kick_right/rfoot
        102:131, ...``). ``attrs``: ``description`` (as read), ``counts`` ((part, hits) per part, for
        ``--explain``), ``candidates`` (hits before overlaps were resolved), ``empty_reason`` (which part found
        nothing), ``ms``, ``relational_set``.

    Raises
    ------
    DescriptionError
        The text cannot be read (line and column named), or a template atom is missing or of another set (every
        unknown or refused name: "no stored template NAME in DB; stored: ...").
    MotionDBError
        No relational index of the set (build it with ``mocapviz index``).

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3 (scene descriptions, Fig. 10) and §5.2 (adaptive fuzzy queries).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.relational.index import build
    >>> db = MotionDB.sample()
    >>> indexes = build(db, save=False, progress=False)
    >>> kick = ("lfoot: lowered raised lowered and lknee: straight bent straight"
    ...         " and overlap lfoot raised, lknee bent and lfoot raised for 0.3..2 s")
    >>> hits = find(db, kick, indexes=indexes)
    >>> print(hits[["rank", "doc_id", "label", "start", "end", "score"]].round(3).to_string(index=False))
     rank  doc_id           label  start  end  score
        1      18 kickLFront1Reps     36   98  0.517
        2       7 kickLFront1Reps     10   76  0.550
        3      11      squat1Reps     22  136  0.950
        4      22      squat1Reps     28  144  0.967
    >>> hits["parts"].iloc[0]  # each progression's frames within the document
    'lfoot 52:98, lknee 36:66'
    """
    return _run(db, description, n_matches, relational_set, template_cost, overlapping, indexes, values, False,
                templates)


def find_by_scan(db, description, n_matches: int | None = None, relational_set: str | None = None,
                 template_cost: float | None = None, overlapping: bool = False,
                 values: np.ndarray | None = None, templates: dict | None = None) -> pd.DataFrame:  # fmt: skip
    """:func:`find` without the index: every feature's runs walked frame by frame in every document, events and
    sequences by checking every combination of hits. The reference :func:`find` must equal (and the baseline of
    its benchmark).

    Parameters
    ----------
    db, description, n_matches, relational_set, template_cost, overlapping, templates
        As :func:`find`.
    values : np.ndarray [shape=(N, f)], bool, optional
        The database's frame-wise relational values of the set (default: computed now).

    Returns
    -------
    pandas.DataFrame
        As :func:`find`.
    """
    return _run(db, description, n_matches, relational_set, template_cost, overlapping, None, values, True,
                templates)


# ================================================================================================ learned descriptions
def _feature_runs(column: np.ndarray) -> list[list]:
    """[value, first, stop] runs of one quantised template column (0, 0.5, 1) with don't-care runs resolved: dropped
    at the ends, merged into equal neighbours, split between different ones."""
    cuts = np.flatnonzero(column[1:] != column[:-1]) + 1
    bounds = np.concatenate([[0], cuts, [column.size]])
    runs = [[float(column[a]), int(a), int(b)] for a, b in itertools.pairwise(bounds)]
    while runs and runs[0][0] == 0.5:
        runs.pop(0)
    while runs and runs[-1][0] == 0.5:
        runs.pop()
    out: list[list] = []
    for k, run in enumerate(runs):
        if run[0] != 0.5:
            if out and out[-1][0] == run[0]:
                out[-1][2] = run[2]
            else:
                out.append(run)
            continue
        after = runs[k + 1]
        if out[-1][0] == after[0]:
            out[-1][2] = run[2]
        else:
            middle = (run[1] + run[2]) // 2
            out[-1][2], after[1] = middle, middle
    return out


def describe_clip(values, names, label: str = "clip", delta: float = 0.1) -> str:
    """A clip as an editable scene description: :func:`describe` of the motion template of this one example
    (:func:`mocapviz.relational.templates.learn_template`), what the dashboard's "Describe this clip" writes.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The clip's relational features (:meth:`mocapviz.engine.Engine.clip_relational`: a document, an uploaded
        take, a span of either).
    names : list of str [length f]
        Their names: every feature of the 2005 or 2006 set.
    label : str
        The clip's name, in the description's comment line.
    delta : float
        As :func:`describe` (a template of one example has no don't-care entry: every feature's course is kept).

    Returns
    -------
    str
        The description (:func:`find` reads it); a clip whose features never change and change back gives one
        with no progression, which :func:`find` refuses by saying so.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.engine import Engine
    >>> engine = Engine(MotionDB.demo())
    >>> values, names = engine.clip_relational(5, relational_set="2005")  # a kick of the left foot
    >>> text = describe_clip(values, names, "kick")
    >>> "lfoot: lowered raised lowered" in text
    True
    >>> 5 in engine.find(text, n_matches=10, relational_set="2005")["doc_id"].tolist()  # the clip itself is found
    True
    """
    from .templates import learn_template

    return describe(learn_template([np.asarray(values)], list(names), label=str(label)), delta=delta)


def describe(template, delta: float = 0.1, progressions: int = 4, longest: int = 5) -> str:
    """A motion template as an editable scene description (the paper's future work: descriptions learned from
    examples).

    Every feature whose quantised course (δ) changes and changes back becomes a candidate progression (don't-care
    stretches dropped at the ends, merged into the state around them); the ``progressions`` most consistent ones
    (the largest share of template frames that are not don't-care) with at most ``longest`` states are kept, and
    overlaps of middle states, the longest the template shows first, link every progression to another.

    Parameters
    ----------
    template : MotionTemplate
        Learned on the 2005 or 2006 relational set (:func:`mocapviz.relational.templates.learn_class`).
    delta : float
        The quantisation threshold δ, 0 < δ < 0.5 (:data:`mocapviz.relational.templates.DELTA_RANGE`).
    progressions : int
        Progressions kept, >= 1.
    longest : int
        Most states in one progression, >= 2.

    Returns
    -------
    str
        The description, in the words of the template's relational set, with a comment line saying where it came
        from; :func:`find` reads it.

    Raises
    ------
    ParameterError
        A template not learned on a relational set, bad δ or counts, or a template in which no feature changes.

    References
    ----------
    .. [1] M. Müller, T. Röder, M. Clausen. Efficient content-based retrieval of motion capture data. SIGGRAPH
       2005, §6.3 ("learn such geometric scene descriptions from example motions").
    .. [2] M. Müller, T. Röder. Motion templates for automatic classification and retrieval of motion capture
       data. SCA 2006, §3 (quantised templates).

    Examples
    --------
    >>> import numpy as np
    >>> from mocapviz.features import feature_names
    >>> from mocapviz.relational.templates import MotionTemplate
    >>> names = feature_names("2005")
    >>> values = np.zeros((6, len(names)))
    >>> values[1:5, names.index("lknee_bent")] = 1.0
    >>> values[2:4, names.index("lfoot_raised")] = 1.0
    >>> print(describe(MotionTemplate(values, names, label="toy kick", n_examples=1)))
    # described from the template 'toy kick' (1 examples, 2005 set, δ = 0.1)
    set 2005;
    lfoot: lowered raised lowered
        and lknee: straight bent straight
        and overlap lfoot raised, lknee bent
    """
    from ..features import RELATIONAL_SETS, feature_names

    relational_set = next((s for s in RELATIONAL_SETS if feature_names(s) == list(template.features)), None)
    if relational_set is None:
        raise ParameterError("the template was not learned on the features of a relational set")
    progressions = count(progressions, "progressions")
    longest = count(longest, "longest", 2)
    q = template.quantised(delta)
    words = vocabulary_of(relational_set)
    candidates = []
    for j, feature in enumerate(template.features):
        runs = _feature_runs(q[:, j])
        if 3 <= len(runs) <= longest:
            candidates.append((-float(np.mean(q[:, j] != 0.5)), j, feature, runs))
    if not candidates:
        raise ParameterError(f"no feature of the template '{template.label}' changes with δ = {delta:g}: nothing to "
                             "describe (try a larger δ)")  # fmt: skip
    chosen = sorted(candidates)[:progressions]
    chosen.sort(key=lambda c: c[1])
    lines, steps = [], []
    for _, _, feature, runs in chosen:
        states = [words.states(feature)[int(v)] for v, _, _ in runs]
        lines.append(f"{words.part(feature)}: {' '.join(states)}")
        steps.append([(words.part(feature), states[k], states[: k + 1].count(states[k]), runs[k][1], runs[k][2],
                       states.count(states[k])) for k in range(1, len(runs) - 1)])  # fmt: skip
    pairs = []
    for a in range(len(chosen)):
        for b in range(a + 1, len(chosen)):
            best = max(((min(x[4], y[4]) - max(x[3], y[3]), x, y) for x in steps[a] for y in steps[b]),
                       default=(0, None, None), key=lambda t: t[0])  # fmt: skip
            if best[0] > 0:
                pairs.append((-best[0], a, b, f"overlap {_ref_text(best[1])}, {_ref_text(best[2])}"))
    linked: set[int] = set()
    for _, a, b, line in sorted(pairs):  # the longest shared stretches first, until every progression is linked
        if not {a, b} <= linked:
            lines.append(line)
            linked |= {a, b}
    head = (f"# described from the template '{template.label}' ({template.n_examples} examples, {relational_set} "
            f"set, δ = {delta:g})")  # fmt: skip
    return f"{head}\nset {relational_set};\n" + "\n    and ".join(lines)


def _ref_text(step) -> str:
    part, word, nth, _, _, total = step
    return f"{part} {word}" if total == 1 else f"{part} {word}[{nth}]"
