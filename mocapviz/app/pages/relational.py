"""Relational query page: query by example over the database's relational indexes (Müller, Röder & Clausen 2005
§5: exact hits §5.1, fuzzy and adaptive fuzzy hits §5.2, m-mismatch hits; ranking §6.2).

The example is a frame span of one document (by default the session's clip and span from the Database page's
player); the user ticks relational features of the three groups (lower, upper, mix; the rest are "don't care")
and a kind of hit. The hits are ranked by :func:`mocapviz.relational.query.query_by_example`; clicking one plays the query
span beside it. When the database has labels, the hits are judged against the query document's label
(:func:`mocapviz.viz.query.precision_recall`, the definition of :mod:`mocapviz.experiments.evaluation`: documents are ranked by
their first hit, the query document itself is left out, a document is relevant when it has the query's label; recall
is over the other documents with that label).
"""

from __future__ import annotations

import asyncio

import numpy as np
import pandas as pd
import panel as pn

from ...engine import feature_groups, query_segmentation
from ...validation import plural
from ...viz.query import precision_recall, precision_recall_plot
from ..documents import UPLOADED, DocumentPicker
from ..downloads import table_download
from ..gallery import HitGallery
from ..player import SkeletonPlayer
from ..progress import Task, in_thread
from ..state import half_open, inclusive
from ..upload import Upload, UploadBox, cache_key, example, query_clip, query_fps, query_frames, query_name
from ..widgets import BoundedIntInput, action_button, clear, hit_columns, hit_titles, notes, results_table

RELATIONAL_SET = "2005"
# the "kicking" query of Müller et al. 2005 §6.2 (Fig. 9): F_l3, F_l4, F_l7, F_l8; ticked for a span of one frame
# and before the indexes are loaded (suggested_query)
DEFAULT_FEATURES = ("rfoot_raised", "lfoot_raised", "rknee_bent", "lknee_bent")
MODES = {"exact": "exact", "fuzzy": "fuzzy", "adaptive fuzzy": "adaptive", "mismatch": "mismatch"}
DEFAULT_MODE, DEFAULT_MISMATCHES = "mismatch", 0  # until a clip's suggested_query sets m
GROUP_TITLES = {"lower": "lower body", "upper": "upper body", "mix": "mix"}
HIT_TITLES = hit_titles("rank", "doc_id", "name", "label", "start", "end", "start_s", "end_s", "score")
HIT_DECIMALS = {"start_s": 2, "end_s": 2, "score": 3}


def suggested_query(backend, doc: int, first: int, last: int) -> dict:
    """The query the page suggests for frames ``first``..``last`` (inclusive) of document ``doc``: the features,
    mode and m of :meth:`mocapviz.engine.Engine.suggest_query` (the most specific selection of one group's
    features that finds 5 other documents; docs/relational.md), cached by the Backend; :data:`DEFAULT_FEATURES`
    with m = 0 for a span of one frame.

    On the 287 HDM05 cut clips at 30 Hz, each clip queried whole, the first 5 other documents the suggested query
    finds are of the clip's class for 81 % (every class at least 53 %; 82 % and 57 % over the 167 clips of three
    actors), and every clip finds 5 other documents; the page's earlier default (the 4 features that change least
    often, m = 1) 40 %, and 58 clips found no other document (:mod:`mocapviz.relational.suggestion`).

    Parameters
    ----------
    backend : Backend
    doc : int or Upload
        Document id, or the session's uploaded take.
    first, last : int
        Frames of the document, inclusive.

    Returns
    -------
    dict, as :meth:`RelationalPage.query` (span half-open).
    """
    first, last = int(first), int(last)
    q = {"doc": doc, "span": (first, last + 1), "features": list(DEFAULT_FEATURES), "mode": MODES[DEFAULT_MODE],
         "mismatches": 0}
    if last > first:
        suggested = backend.cached(("relational suggestion", RELATIONAL_SET, cache_key(doc), first, last),
                                   lambda: backend.engine.suggest_query(example(doc), frames=(first, last + 1),
                                                                        relational_set=RELATIONAL_SET))
        q.update(features=list(suggested.features), mode=suggested.mode, mismatches=int(suggested.mismatches))
    return q


def span_features(backend, doc: int, first: int, last: int) -> tuple[np.ndarray, list[str]]:
    """The relational features (:data:`RELATIONAL_SET`) of frames ``first``..``last`` (inclusive, as the page's span
    slider shows them) of document ``doc``, computed on that stretch of the clip and cached by the Backend: what
    the query's segments are read from.

    Parameters
    ----------
    backend : Backend
    doc : int
        Document id.
    first, last : int
        Frames of the document, inclusive (at least two frames: the velocity features need two).

    Returns
    -------
    values : np.ndarray [shape=(last - first + 1, f)], bool
    names : list of str
        The f feature names.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.app.backend import Backend
    >>> values, names = span_features(Backend(MotionDB.sample()), 10, 0, 214)
    >>> values.shape == (215, len(names)), values.dtype
    (True, dtype('bool'))
    """
    first, last = int(first), int(last)
    return backend.cached(("relational span", RELATIONAL_SET, cache_key(doc), first, last),
                          lambda: backend.engine.clip_relational(example(doc), frames=(first, last + 1),
                                                                 relational_set=RELATIONAL_SET))


def search(backend, q: dict) -> pd.DataFrame:
    """The ranked hits of the query ``q`` of the page (:meth:`RelationalPage.query`, :func:`first_query`):
    :func:`mocapviz.relational.query.query_by_example` of its span over the Backend's indexes, cached per database.

    Parameters
    ----------
    backend : Backend
    q : dict
        doc (document id), span ((start, end) frames of the document, half-open), features (names of
        :data:`RELATIONAL_SET`), mode (a value of :data:`MODES`), mismatches (m, for the mismatch mode).

    Returns
    -------
    pd.DataFrame, the hit table, best first (start, end: frames of the document, half-open), with ``score``.
    """
    key = ("relational query", RELATIONAL_SET, cache_key(q["doc"]), tuple(q["span"]), tuple(sorted(q["features"])), q["mode"],
           q["mismatches"] if q["mode"] == "mismatch" else 0)
    start, end = q["span"]
    return backend.cached(key, lambda: backend.engine.query(example(q["doc"]), frames=(start, end), features=q["features"],
                                                            mode=q["mode"], mismatches=q["mismatches"],
                                                            relational_set=RELATIONAL_SET))  # fmt: skip


def first_query(backend, doc: int) -> dict:
    """The query the page poses when clip ``doc`` is chosen: the whole clip's :func:`suggested_query`.

    Returns
    -------
    dict, as :meth:`RelationalPage.query` (span half-open).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> from mocapviz.app.backend import Backend
    >>> backend = Backend(MotionDB.sample())
    >>> q = first_query(backend, 7)  # a kick
    >>> q["span"], q["features"], q["mode"], q["mismatches"]
    ((0, 129), ['lknee_bent'], 'mismatch', 0)
    >>> hits = search(backend, q)
    >>> hits.loc[hits["doc_id"] != 7, "label"].iloc[0]  # the first other document: the sample's other kick
    'kickLFront1Reps'
    """
    return suggested_query(backend, doc, 0, int(backend.db.document(doc)["n_frames"]) - 1)


class RelationalPage(pn.viewable.Viewer):
    """Pose a query by example and browse its hits; the query clip and span follow the session's Selection."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.has_labels = "label" in backend.documents and backend.documents["label"].notna().any()
        self._syncing = False
        self.hits, self.shown_query = pd.DataFrame(), None
        self.answered = False  # first_answer has started (it loads the indexes itself)
        self.doc = DocumentPicker(backend, "query clip", selection.doc, selection, width=420,
                                  css_classes=["mv-query-doc"])
        self.upload = UploadBox(backend, selection)
        self.span = pn.widgets.IntRangeSlider(label="query span (frames)", start=0, end=1, value=(0, 1), width=420,
                                              css_classes=["mv-query-span"])
        self.first = BoundedIntInput("first frame", 0, 0, 1, width=140, css_classes=["mv-query-first"])
        self.last = BoundedIntInput("last frame", 1, 0, 1, width=140, css_classes=["mv-query-last"])
        self.span_info = pn.pane.Markdown("", margin=(0, 10), css_classes=["mv-query-span-info"])
        self.features = {g: pn.widgets.CheckBoxGroup(label=GROUP_TITLES[g], options=names, inline=False,
                                                     css_classes=[f"mv-features-{g}"])
                         for g, names in feature_groups(RELATIONAL_SET).items()}
        self._ticked_for = None  # the clip whose suggested features were ticked last
        self.mode = pn.widgets.RadioButtonGroup(label="hits", options=list(MODES), value=DEFAULT_MODE,
                                                css_classes=["mv-query-mode"])
        self.mismatches = BoundedIntInput("m mismatching segments", DEFAULT_MISMATCHES, 0, 1, width=200,
                                          disabled=DEFAULT_MODE != "mismatch", css_classes=["mv-query-m"])
        self.run = action_button("Run query", "mv-run", self._on_run, width=140)
        self.task = Task()
        self.message = pn.pane.Alert("", alert_type="warning", visible=False, css_classes=["mv-query-message"])
        self.count = pn.pane.Markdown("", css_classes=["mv-hit-count"])
        self.quality = pn.pane.Markdown("", css_classes=["mv-hit-quality"])
        self.table = results_table(pd.DataFrame(columns=list(HIT_TITLES)), "mv-hits", HIT_TITLES, selectable=True)
        self.download = table_download(backend, self.table, self._found_by, "mv-hits-download")
        self.gallery = HitGallery(backend, self.table, "mv-hits-gallery", selection)
        self.curve = pn.pane.HoloViews(None, visible=False, css_classes=["mv-precision-recall"])
        self.player = SkeletonPlayer(size=(640, 360))
        self.player_caption = pn.pane.Markdown("", css_classes=["mv-hit-caption"])
        self._watch()
        query, span, _ = selection.query()
        self._set_query(query, inclusive(span))

    def __panel__(self):
        features = pn.Row(*[pn.Column(f"**{GROUP_TITLES[g]}**", w) for g, w in self.features.items()])
        query = pn.Column("### Query", self.doc, self.upload, self.span, pn.Row(self.first, self.last),
                          notes(self.first, self.last), self.span_info,
                          "**Features** (unticked ones are \"don't care\"; a new clip ticks its suggested query: the "
                          "most specific choice of one group's features that finds 5 other clips)", features,
                          "**Hits** (§5: exact, fuzzy, adaptive fuzzy, m-mismatch)", self.mode, self.mismatches,
                          notes(self.mismatches), self.run, self.message, self.task)
        player = pn.Column("### Query beside hit", self.player, self.player_caption, css_classes=["mv-query-player"])
        results = pn.Column("### Hits", self.count, self.quality, self.gallery, self.download.panel(), self.curve,
                            sizing_mode="stretch_width")
        return pn.Column(pn.Row(query, player), results, sizing_mode="stretch_width")

    def _watch(self) -> None:
        self.doc.param.watch(self._on_doc, "value")
        self.span.param.watch(self._on_span, "value_throttled")
        self.first.param.watch(self._on_bound, "value")
        self.last.param.watch(self._on_bound, "value")
        self.mode.param.watch(lambda e: setattr(self.mismatches, "disabled", e.new != "mismatch"), "value")
        for w in self.features.values():
            w.param.watch(lambda e: self._bound_mismatches(), "value")
        self.table.param.watch(self._on_select, "selection")
        self.selection.param.watch(self._on_upload, "upload")

    def _on_upload(self, event) -> None:
        """A take was uploaded (on this page or another): it is the query clip, all of it."""
        if event.new is not None:
            self._set_query(event.new, (0, event.new.n_frames - 1))

    # ------------------------------------------------------------------ the query clip and span
    def activate(self) -> None:
        """Take the session's clip and span (the Database page may have changed them) when the tab is shown."""
        query, span, _ = self.selection.query()
        if (query, span) != (self._query(), half_open(self.span.value)):
            self._set_query(query, inclusive(span))
        if self.answered and not self.backend.engine.holds("indexes", RELATIONAL_SET):
            pn.state.execute(self._load_indexes)

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the relational indexes loaded (built the first time), then the
        session's clip queried by :func:`first_query` (its widgets set to that query) and the hits shown. A span
        narrower than the clip, chosen on the Database page, is queried as it is, with its :func:`suggested_query`."""
        self.answered = True
        if not self.backend.engine.holds("indexes", RELATIONAL_SET):
            await self._load_indexes()
        query, span, _ = self.selection.query()
        self._pose(await in_thread(suggested_query, self.backend, query, *inclusive(span)))
        await self._on_run()

    def _pose(self, q: dict) -> None:
        """Set the widgets to the query ``q`` (as :meth:`query` returns it)."""
        self._set_query(q["doc"], inclusive(q["span"]))
        for w in self.features.values():
            w.value = [name for name in w.options if name in q["features"]]
        self.mode.value = next(label for label, mode in MODES.items() if mode == q["mode"])
        self.mismatches.set_bounds(0, self.query_segments() - 1, q["mismatches"])

    async def _load_indexes(self) -> None:
        """Load (or build, the first time) the relational indexes behind the progress bar; Run waits for them."""
        await self.task.run("Loading the relational indexes", self.backend.engine.indexes, RELATIONAL_SET,
                            busy=self.run)

    def _set_query(self, doc: int, span) -> None:
        """Show document ``doc`` (or the uploaded take) and ``span`` (first, last frames, inclusive, as the slider
        and the boxes show it; clipped to the clip)."""
        n = query_frames(self.backend, doc)
        first, last = sorted(min(max(int(v), 0), n - 1) for v in span)
        self._syncing = True
        try:
            self.doc.value = UPLOADED if isinstance(doc, Upload) else doc
            self.span.param.update(start=0, end=max(n - 1, 1), value=(first, last))
            self.first.set_bounds(0, n - 1, first)
            self.last.set_bounds(0, n - 1, last)
            if doc != self._ticked_for:  # a new clip: tick its suggested query (once the indexes are loaded)
                self._ticked_for = doc
                held = self.backend.engine.holds("indexes", RELATIONAL_SET)
                q = suggested_query(self.backend, doc, first, last if held else first)
                for w in self.features.values():
                    w.value = [name for name in w.options if name in q["features"]]
                self.mismatches.set_bounds(0, self.query_segments() - 1, q["mismatches"])
        finally:
            self._syncing = False
        self._span_changed()

    def _on_doc(self, event) -> None:
        if not self._syncing:
            query = self._query()
            self._set_query(query, (0, query_frames(self.backend, query) - 1))

    def _query(self):
        """The query clip chosen: a document id, or the session's uploaded take."""
        return self.selection.upload if self.doc.value == UPLOADED else int(self.doc.value)

    def _on_span(self, event) -> None:
        if not self._syncing:
            self._set_query(self._query(), event.new)

    def _on_bound(self, event) -> None:
        """The first or last frame box changed (a value out of the clip was already moved into it by the box); a
        first frame after the last (or a last before the first) makes them change places, and the box says so."""
        first, last = self.first.value, self.last.value
        if self._syncing or (first, last) == tuple(self.span.value):
            return
        self._set_query(self._query(), (first, last))
        if first > last:
            box = event.obj
            other, where = ("last", "after") if box is self.first else ("first", "before")
            box.tell(f"**{box.base_label}** {event.new:,} is {where} the {other} frame "
                     f"{(last if box is self.first else first):,}: the two were swapped, the span is now frames "
                     f"{min(first, last):,}–{max(first, last):,}.")

    def _span_changed(self) -> None:
        """Tell the Selection, describe the span and show it in the player."""
        doc, (first, last) = self._query(), self.span.value
        if isinstance(doc, Upload):
            self.selection.param.update(use_upload=True, upload_span=(first, last + 1))
        elif self.selection.query()[:2] != (doc, (first, last + 1)):
            self.selection.param.update(doc=doc, frame=first, span=(first, last + 1), use_upload=False)
        fps = self._doc_fps(doc)
        self.span_info.object = (f"{plural(last - first + 1, 'frame')} · {first / fps:.2f}–{(last + 1) / fps:.2f} s "
                                 f"of {self._doc_name(doc)}")
        self._play_query(doc, first, last)
        self._bound_mismatches()

    def query_segments(self) -> int:
        """The query's segments in the feature group where it has the most, on the ticked features (1 when none
        is ticked or the span is too short): m-mismatch hits allow at most that many less one mismatches, as the
        library caps m per group (:func:`mocapviz.relational.query.query_by_example`)."""
        first, last = self.span.value
        ticked = [n for w in self.features.values() for n in w.value]
        if last <= first or not ticked:
            return 1
        groups = query_segmentation(*self._span_features(), ticked, RELATIONAL_SET)
        return max(len(seq.codes) for _, seq in groups.values())

    def _span_features(self) -> tuple[np.ndarray, list[str]]:
        """The relational features of the query span (:func:`span_features`)."""
        return span_features(self.backend, self._query(), *self.span.value)

    def _bound_mismatches(self) -> None:
        """m from 0 to the query's segments less one (more would be capped to that by the library)."""
        self.mismatches.set_bounds(0, self.query_segments() - 1)

    # ------------------------------------------------------------------ running
    def query(self) -> dict:
        """The query the widgets describe: doc, span (start, end: frames of the document, half-open), features
        (names), mode, mismatches."""
        features = [n for w in self.features.values() for n in w.value]
        return {"doc": self._query(), "span": half_open(self.span.value), "features": features,
                "mode": MODES[self.mode.value], "mismatches": int(self.mismatches.value)}

    def problem(self, q: dict) -> str | None:
        """Why the query ``q`` cannot run (a sentence for the user), or None when it can."""
        if not q["features"]:
            return "Tick at least one feature: the query compares the clips in the ticked features only."
        start, end = q["span"]
        if end - start < 2:
            return ("The span must hold at least two frames (the velocity features need two): set its last frame "
                    "after its first.")
        return None

    def search(self, q: dict) -> pd.DataFrame:
        """The ranked hits of ``q`` (:func:`search`)."""
        return search(self.backend, q)

    async def _on_run(self, event=None) -> None:
        q = self.query()
        reason = self.problem(q)
        self.message.param.update(object=reason or "", visible=reason is not None)
        shown = (self.count, self.quality, self.table, self.curve)
        if reason:
            clear(*shown)
            return
        hits = await self.task.run("Searching", self.search, q, busy=self.run, stale=shown)
        if hits is not None:
            self._show_hits(q, hits)
            await asyncio.sleep(0)  # let the table and count reach the browser before the plot is built
            await self._show_quality(q, hits)
            await asyncio.sleep(0)
            # the table's rows once more, in the page's final layout: Tabulator sometimes draws none when its data
            # arrives while the page around it is laid out again (seen once in CI, on a loaded machine)
            self.table.param.trigger("value")

    # ------------------------------------------------------------------ results
    def _found_by(self) -> str:
        """The query of the hits shown, in words (written into exported files)."""
        q = self.shown_query or {}
        start, end = q.get("span", (0, 0))
        what = query_name(self.backend, q["doc"]) if "doc" in q else "nothing"
        return (f"relational query by example ({q.get('mode')}, {RELATIONAL_SET} set): {what} "
                f"frames {start}:{end}, features {', '.join(q.get('features', []))}")

    def _show_hits(self, q: dict, hits: pd.DataFrame) -> None:
        self.hits, self.shown_query = hits, q
        self.gallery.show_hits(hit_columns(hits, HIT_TITLES, HIT_DECIMALS))
        kind = f"{q['mode']} hits" + (f" with m = {q['mismatches']}" if q["mode"] == "mismatch" else "")
        self.count.object = f"**{plural(len(hits), 'hit')}** for {plural(len(q['features']), 'feature')}, " \
                            f"{kind} (score: seconds of segment-length difference, §6.2; lower " \
                            "is better)"
        self._play_query(q["doc"], q["span"][0], q["span"][1] - 1)  # no hit of the table it replaces beside it

    def _play_query(self, doc: int, first: int, last: int) -> None:
        """The query alone in the player (frames first..last of ``doc``, both included), and its caption."""
        self.player.load([self._clip(doc, first, last + 1)], titles=["query"], fps=self._doc_fps(doc))
        self.player_caption.object = f"Query: **{self._doc_name(doc)}**, frames {first}–{last}. Click a hit to " \
                                     "play it beside the query."

    async def _show_quality(self, q: dict, hits: pd.DataFrame) -> None:
        """Precision and recall against the query document's label, as numbers and over the rank (the numbers reach
        the browser first: the plot of a large result's thousands of documents takes a second to build)."""
        uploaded = isinstance(q["doc"], Upload)  # no document: no label to judge the hits by
        label = self.backend.db.document(q["doc"])["label"] if self.has_labels and not uploaded else None
        if label is None or pd.isna(label):
            self.quality.object = "*No label on the query clip: the hits cannot be judged.*"
            self.curve.visible = False
            return
        curve = precision_recall(hits["doc_id"], self.backend.documents, q["doc"])
        n_rel = curve.attrs["n_relevant"]
        rule = (f"Documents are ranked by their first hit; one is relevant when it is labelled *{label}*; the query's "
                f"own document is left out; recall counts the {plural(n_rel, 'other document')} with that label.")
        if curve.empty:
            self.quality.object = f"No hit outside the query's document. {rule}"
            self.curve.visible = False
            return
        last = curve.iloc[-1]
        recall = "undefined (no other document has this label)" if not n_rel else f"{last['recall']:.2f}"
        ap = curve.attrs["average_precision"]
        self.quality.object = (f"**Precision {last['precision']:.2f}** ({int(curve['relevant'].sum())} of "
                               f"{plural(len(curve), 'document')}) · **recall {recall}** · **AP "
                               f"{'undefined' if pd.isna(ap) else f'{ap:.2f}'}**. {rule}")
        await asyncio.sleep(0)
        self.curve.object = precision_recall_plot(curve, label=str(label))
        self.curve.visible = True

    def _on_select(self, event) -> None:
        if not event.new or self.hits.empty:
            return
        hit = self.hits.iloc[int(event.new[0])]
        q = self.shown_query
        doc, start, end = int(hit["doc_id"]), int(hit["start"]), int(hit["end"])
        self.player.load([self._clip(q["doc"], *q["span"]), self._clip(doc, start, end)],
                         titles=["query", f"hit {int(hit['rank'])}"], fps=self._doc_fps(doc))
        self.player_caption.object = (f"Query: **{self._doc_name(q['doc'])}**, frames {q['span'][0]}:{q['span'][1]}"
                                      f" · beside hit {int(hit['rank'])}: **{hit['name']}**, frames {start}:{end} "
                                      "(end excluded, as in the table)")

    # ------------------------------------------------------------------ helpers
    def _clip(self, doc, start: int, end: int):
        """Frames start:end (half-open) of document ``doc`` (or the uploaded take): (T, 24, 3) cm."""
        return query_clip(self.backend, doc, start, end)

    def _doc_fps(self, doc) -> float:
        return query_fps(self.backend, doc)

    def _doc_name(self, doc) -> str:
        return doc.title if isinstance(doc, Upload) else str(self.backend.db.document(int(doc))["name"])

