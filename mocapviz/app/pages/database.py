"""Database page: the document browser (filter by label, performer, archive, text and length; paged on the server, so
a database of thousands of documents sends one page), the 3D skeleton player of the chosen clip with the query span,
and beneath it the clip's relational feature timelines (Müller et al. 2005 §3-4) and numeric feature curves (Krüger
et al. 2010 §3.2).

Segment labels (:meth:`mocapviz.engine.Engine.segment_labels`) show here too: the table counts each document's (its
"segment labels" column, once the database has some: labels of any name, rejected hits left out), a strip above the timelines draws the clip's as
coloured spans with their names, and a user who may annotate labels the player's span ("label this span": a
``manual`` label by the session's user). The table follows the database: documents added while serving
(:meth:`mocapviz.app.backend.Backend.on_new_documents`) appear in an open session's table and filters."""

from __future__ import annotations

import html

import holoviews as hv
import pandas as pd
import panel as pn

from ...engine import NUMERIC_SETS, feature_groups, numeric_columns, segment
from ...errors import MocapvizError
from ...validation import plural
from ...viz.palette import PART_NAMES, PARTS, SERIES, legend
from ...viz.timeline import numeric_curves, relational_timeline
from ..auth import can, session_user
from ..documents import filter_documents
from ..downloads import HitDownload
from ..player import SkeletonPlayer
from ..progress import in_thread
from ..state import half_open, inclusive
from ..widgets import results_table

TABLE_TITLES = {"doc_id": "id", "n_frames": "frames"}
LABELS = "segment labels"  # the table's column: each document's segment labels (rejected hits left out; the column
# is left out while the database has none: the documents table then fits beside the player at 1400 pixels)
LANE_PX = 22  # height of a lane of the segment label strip (overlapping labels take the lanes below)
# pixels: each title in full beside its sort arrow (at 1280 pixels too: "perfor…", "seco…" were cut at 92 and 80)
NARROW_COLUMNS = {"doc_id": 56, "performer": 104, "archive": 112, "seconds": 94, "n_frames": 84, "fps": 58,
                  LABELS: 132}
CHAR_PX, LABEL_PX = 8, (100, 280)  # a label's width per character (Tabulator's 14 px font) and its column's bounds
SAME_FOR_ALL = ("archive", "fps")  # columns left out when every document has the same value (the count line says it)
PAGE_ROWS = 12  # documents per page of the table (beside the player)


class DatabasePage(pn.viewable.Viewer):
    """Browse the documents and play one; its span becomes the example of the query pages."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self._loading = False
        self.table_data = docs = label_counts(backend.document_table(), backend.engine.segment_labels())
        self.label_filter = pn.widgets.MultiChoice(label="label", options=_choices(docs["label"]), width=260,
                                                   css_classes=["mv-filter-label"])
        self.performer_filter = pn.widgets.MultiChoice(label="performer", options=_choices(docs["performer"]),
                                                       width=160, css_classes=["mv-filter-performer"])
        self.archive_filter = pn.widgets.MultiChoice(label="archive", options=_choices(docs["archive"]), width=200,
                                                     css_classes=["mv-filter-archive"])
        self.text_filter = pn.widgets.TextInput(label="name, label, performer or archive contains", width=260,
                                                placeholder="e.g. kick, 135, bandai", css_classes=["mv-filter-text"])
        longest = float(docs["seconds"].max())
        self.length_filter = pn.widgets.RangeSlider(label="length (s)", start=0.0, end=max(longest, 0.1),
                                                    value=(0.0, max(longest, 0.1)), step=0.1, width=220)
        # the columns share the table's width (the player takes the rest of a 1400-pixel screen): long names end in
        # "…" and show in full on hover, rather than the last columns being cut off
        self.same = {c: docs[c].iloc[0] for c in SAME_FOR_ALL if docs[c].nunique() == 1 and docs[c].notna().all()}
        self.table = results_table(docs, "mv-documents", TABLE_TITLES, page_size=PAGE_ROWS, selectable=True,
                                   layout="fit_columns", widths=column_widths(docs), tooltips=True,
                                   hidden_columns=list(self.same))  # fmt: skip
        self.count = pn.pane.Markdown("", css_classes=["mv-doc-count"])
        for w in (self.label_filter, self.performer_filter, self.archive_filter, self.length_filter):
            w.param.watch(self._filter, "value")
        self.text_filter.param.watch(self._filter, "value_input")  # as the user types
        self.table.param.watch(self._on_select, "selection")
        self.player = SkeletonPlayer()
        self.player.param.watch(self._on_step, "step")
        self.span = pn.widgets.IntRangeSlider(label="query span (frames)", start=0, end=1, value=(0, 1), width=420,
                                              css_classes=["mv-span"])
        self.span_start = pn.widgets.Button(label="span starts here", width=130)
        self.span_end = pn.widgets.Button(label="span ends here", width=130)
        self.span_start.on_click(lambda e: self._set_span(self.player.frames()[0], None))
        self.span_end.on_click(lambda e: self._set_span(None, self.player.frames()[0]))
        self.span.param.watch(self._on_span, "value_throttled")
        self.span_label = pn.widgets.TextInput(name="label", placeholder="what the span is", width=200,
                                               css_classes=["mv-span-label"])
        self.label_span = pn.widgets.Button(label="label this span", width=130, align="end",
                                            css_classes=["mv-label-span"])
        self.label_span.on_click(self._label_span)
        self.label_status = pn.pane.Markdown("", margin=(0, 10), css_classes=["mv-label-span-status"])
        self.strip = pn.pane.HTML("", sizing_mode="stretch_width", css_classes=["mv-segment-labels"])
        self.download = HitDownload(backend, self._clip, lambda: "the Database page's player (the query span)",
                                    "mv-clip-download", noun="clip")  # fmt: skip
        selection.param.watch(lambda *events: self.download.refresh(), ["doc", "span"])
        self.numeric_set = pn.widgets.Select(label="numeric feature set", options=list(NUMERIC_SETS[:3]) + [
            s for s in NUMERIC_SETS[3:] if not s.startswith("Fp")], value="F15E", width=160)
        self.numeric_set.param.watch(self._on_numeric_set, "value")
        self.timeline = pn.pane.HoloViews(None, sizing_mode="stretch_width", linked_axes=False,
                                          css_classes=["mv-timeline"])
        self.timeline_info = pn.pane.Markdown("", css_classes=["mv-timeline-info"], margin=(0, 10))
        self.curves = pn.pane.HoloViews(None, sizing_mode="stretch_width", linked_axes=False,
                                        css_classes=["mv-curves"])
        self._pipes: dict = {}  # plot -> (key, Pipe): the plots are DynamicMaps, updated in place by new clips
        self._wanted = None  # the document last asked for (a click, another page): an older one is not shown
        self._loaded = False  # the plots are drawn once the browser has the page (pn.state.onload): the
        # page, its table and player come first (its GET answered in 0.8 s instead of 1.2 s on the sample)
        self._filter()
        self.show_document(selection.doc)
        pn.state.onload(self._first_plots)
        selection.param.watch(self._follow, ["doc", "span"])
        backend.on_new_documents(self._new_documents)

    def __panel__(self):
        filters = pn.Column(pn.Row(self.label_filter, self.performer_filter, self.archive_filter),
                            pn.Row(self.text_filter, self.length_filter), margin=0)
        left = pn.Column("### Documents", filters, self.count, self.table, sizing_mode="stretch_width")
        labelling = [pn.Row(self.span_label, self.label_span), self.label_status] if can(None, "annotate") else []
        right = pn.Column("### Player", self.player, self.span, pn.Row(self.span_start, self.span_end),
                          *labelling, self.download.panel())
        return pn.Column(pn.Row(left, right, sizing_mode="stretch_width"), "### Segment labels", self.strip,
                         "### Relational features", self.timeline_info, self.timeline,
                         "### Numeric features", self.numeric_set, self.curves, sizing_mode="stretch_width")

    # ------------------------------------------------------------------ table
    def _filter(self, event=None) -> None:
        t = self.table_data
        shown = filter_documents(t, self.label_filter.value, self.performer_filter.value, self.archive_filter.value,
                                 self.text_filter.value_input or "", self.length_filter.value)
        self.table.param.update(value=shown, hidden_columns=list(self.same) + ([] if t[LABELS].any() else [LABELS]))
        self.count.object = f"{len(shown)} of {plural(len(t), 'document')}" + "".join(
            f" · all {value:g} fps" if c == "fps" else f" · all from {value}" for c, value in self.same.items())

    def _new_documents(self, backend) -> None:
        """Documents were added while serving: the table and the filters' options hold them (called by the
        Backend's thread, as the pickers' :meth:`~mocapviz.app.documents.DocumentPicker._new_documents`)."""
        self.table_data = docs = label_counts(backend.document_table(), backend.engine.segment_labels())
        for w, column in ((self.label_filter, "label"), (self.performer_filter, "performer"),
                          (self.archive_filter, "archive")):
            w.options = _choices(docs[column])
        self._filter()

    def _labels_changed(self) -> None:
        """The segment labels changed: the table's counts and the clip's strip show them."""
        self.table_data = label_counts(self.table_data.drop(columns=[LABELS]), self.backend.engine.segment_labels())
        self._filter()
        self._draw_labels()

    def _label_span(self, event=None) -> None:
        """Write the player's span as a ``manual`` segment label of the label box's text, by the session's user."""
        start, end = self.selection.span
        label = self.span_label.value.strip()
        try:
            label_id = self.backend.engine.add_label(self.doc, frames=(start, end), label=label,
                                                     author=session_user().name, source="manual")
        except MocapvizError as exc:
            self.label_status.object = f'<span style="color:#c0392b">Not labelled: {exc}</span>'
            return
        self.label_status.object = (f"Frames {start}:{end} of document {self.doc} labelled **{label}** "
                                    f"(label {label_id}).")
        self._labels_changed()

    def _draw_labels(self) -> None:
        """The strip of the clip's segment labels."""
        labels = self.backend.engine.segment_labels()
        self.strip.object = segment_strip(labels[labels["doc_id"] == self.doc], self.n_frames, self.doc_fps)

    async def _on_select(self, event) -> None:
        if event.new:
            await self.open_document(int(self.table.value["doc_id"].iloc[event.new[0]]))

    # ------------------------------------------------------------------ clip
    async def open_document(self, doc: int, span=None) -> None:
        """:meth:`show_document` once the clip's relational features and the numeric set are ready, computed off
        the event loop; when another document was asked for meanwhile, that one is shown instead."""
        self._wanted = doc
        await in_thread(self._prepare, doc, self.numeric_set.value)
        if self._wanted == doc:
            self.show_document(doc, span)

    def _prepare(self, doc: int, numeric_set: str) -> None:
        """Compute what the plots of ``doc`` read (cached by the Backend): in a worker thread."""
        self.backend.clip_relational(doc)
        self.backend.engine.numeric(numeric_set)

    async def _on_numeric_set(self, event) -> None:
        await in_thread(self.backend.engine.numeric, event.new)
        if self.numeric_set.value == event.new:
            self._draw_curves()

    def show_document(self, doc: int, span=None) -> None:
        """Load document ``doc`` into the player and the plots; ``span`` (start, end, half-open), default the whole
        clip, becomes the session's span (the slider shows its first and last frames)."""
        row = self.backend.db.document(doc)
        n = int(row["n_frames"])
        if span is None or not 0 <= span[0] < span[1] <= n:
            span = (0, n)
        self.doc, self.n_frames, self.doc_fps = doc, n, float(row["fps"])
        self._loading = True  # the Selection's watchers (_follow) must not draw the plots a second time
        try:
            self.span.param.update(start=0, end=max(n - 1, 1), value=inclusive(span))
            self.selection.param.update(doc=doc, frame=0, span=tuple(span))
        finally:
            self._loading = False
        self.player.load([self.backend.db.positions[self.backend.db.frames(doc)]], titles=[str(row["name"])],
                         fps=self.doc_fps)
        self._draw_labels()
        if self._loaded:
            self._draw_timeline()
            self._draw_curves()
        else:
            self._count_segments()

    def _first_plots(self) -> None:
        """Draw the clip's plots once the browser has the page: building them (HoloViews to Bokeh, about a second)
        then no longer delays the page reaching the browser, nor every other session waiting meanwhile."""
        self._loaded = True
        self._draw_timeline()
        self._draw_curves()

    def _clip(self) -> pd.DataFrame:
        """The player's clip, its query span, as a one-row hit table (for the download under the player)."""
        start, end = self.selection.span
        return pd.DataFrame({"rank": [1], "doc_id": [self.selection.doc], "start": [start], "end": [end]})

    async def _follow(self, *events) -> None:
        """Show the clip and span chosen on another page."""
        doc, span = self.selection.doc, tuple(self.selection.span)
        if self._loading:
            return
        if doc != self.doc:
            await self.open_document(doc, span)
        elif span != half_open(self.span.value):
            self.span.value = inclusive(span)
            self._draw_timeline()
            self._draw_curves()

    def _on_step(self, event) -> None:
        self.selection.frame = self.player.frames()[0]

    def _set_span(self, first, last) -> None:
        a, b = self.span.value
        a = a if first is None else first
        b = b if last is None else last
        if a > b:
            a, b = b, a
        self.span.value = (a, b)
        self._on_span()

    def _on_span(self, event=None) -> None:
        self.selection.span = half_open(self.span.value)
        self._draw_timeline()
        self._draw_curves()

    def _partial_span(self):
        """The span to shade: None when it is the whole clip."""
        a, b = self.selection.span
        return None if (a, b) == (0, self.n_frames) else (a, b)

    def _draw_timeline(self) -> None:
        self._count_segments()
        self._show(self.timeline, "2005", self._timeline_frame)

    def _count_segments(self) -> None:
        """The line above the timeline: the clip's features and its segments, in the clip and in the span."""
        values, names = self.backend.clip_relational(self.doc)
        a, b = self.selection.span
        self.timeline_info.object = (
            f"{plural(len(names), 'feature')} of the 2005 set ({legend(PARTS, PART_NAMES, 'feature groups')}), "
            f"{plural(len(segment(values).starts), 'segment')} in the clip, {len(segment(values[a:b]).starts):,} "
            f"in the span {a}..{b - 1}")

    def _draw_curves(self) -> None:
        self._show(self.curves, self.numeric_set.value, self._curves_frame)

    def _show(self, pane, key: str, frame) -> None:
        """Show the current clip and span in ``pane``: a new DynamicMap of ``frame`` the first time (and when
        ``key``, the feature set, changes), else new data for the one shown. Bokeh then updates the plot's data in
        place instead of building a new figure: a row click answers about twice as fast. Nothing before the page
        has loaded (:meth:`_first_plots` draws them then)."""
        if not self._loaded:
            return
        data = (self.doc, self.doc_fps, self._partial_span())
        shown = self._pipes.get(id(pane))
        if shown is not None and shown[0] == key:
            shown[1].send(data)
            return
        pipe = hv.streams.Pipe(data=data)
        self._pipes[id(pane)] = (key, pipe)
        pane.object = hv.DynamicMap(lambda data: frame(key, *data), streams=[pipe])

    def _timeline_frame(self, relational_set: str, doc: int, fps: float, span) -> hv.Overlay:
        values, names = self.backend.clip_relational(doc, relational_set)
        return _framewise(relational_timeline(values, names, fps, feature_groups(relational_set)), span, fps)

    def _curves_frame(self, name: str, doc: int, fps: float, span) -> hv.Overlay:
        X = self.backend.engine.numeric(name)[self.backend.db.frames(doc)]
        return _framewise(numeric_curves(X, numeric_columns(name), fps, title=f"{name} (cm, body frame)"), span, fps)


def column_widths(docs: pd.DataFrame) -> dict:
    """The fixed widths (pixels) of the documents table's columns: :data:`NARROW_COLUMNS`, and the label's as wide as
    the longest label (within :data:`LABEL_PX`), so that no class is cut; the name takes the rest (in full on hover)."""
    longest = int(docs["label"].dropna().astype(str).str.len().max()) if docs["label"].notna().any() else 0
    return {**NARROW_COLUMNS, "label": min(max(CHAR_PX * longest + 12, LABEL_PX[0]), LABEL_PX[1])}


def _framewise(plot: hv.Overlay, span, fps: float) -> hv.Overlay:
    """``plot`` with the span shaded as its last layer (of no width when ``span`` is None, so that every frame of a
    DynamicMap has the same layers), its axes following each frame, as wide as the page."""
    a, b = span if span is not None else (0, 0)  # (start, end) frames, half-open
    shade = hv.VSpan(a / fps, b / fps).opts(color="orange", alpha=0.2)
    # as wide as the page, on the first frame and on the next ones (HoloViews sets a fixed size when it updates one)
    width = {"hooks": [_stretch_width]}
    layers = [layer.opts(framewise=True, **width, backend="bokeh") for layer in [*plot, shade]]
    return hv.Overlay(layers).opts(**{**plot.opts.get(backend="bokeh").kwargs, "framewise": True, **width},
                                   backend="bokeh")


def _stretch_width(plot, element) -> None:
    plot.state.sizing_mode = "stretch_width"


def label_counts(docs: pd.DataFrame, labels: pd.DataFrame) -> pd.DataFrame:
    """The documents table with its :data:`LABELS` column: each document's segment labels of ``labels``
    (:meth:`mocapviz.engine.Engine.segment_labels`), rejected hits left out (they say what a stretch is not)."""
    kept = labels.loc[labels["source"] != "rejected hit", "doc_id"].astype(int)
    return docs.assign(**{LABELS: docs["doc_id"].map(kept.value_counts()).fillna(0).astype(int)})


def lanes(starts, ends) -> list[int]:
    """The lane of each span (start, end half-open; in the given order) so that spans of one lane do not overlap:
    each the first lane free at its start, spans taken by start.

    Examples
    --------
    >>> lanes([0, 5, 12, 3], [10, 15, 20, 4])  # 3:4 ends before 5:15 begins: they share lane 1
    [0, 1, 0, 1]
    """
    ends_of: list[int] = []  # the end of each lane's last span
    lane = [0] * len(starts)
    for i in sorted(range(len(starts)), key=lambda i: (starts[i], i)):
        free = next((k for k, end in enumerate(ends_of) if end <= starts[i]), len(ends_of))
        ends_of[free:free + 1] = [ends[i]]
        lane[i] = free
    return lane


def segment_strip(labels: pd.DataFrame, n_frames: int, fps: float) -> str:
    """HTML: a clip's segment labels as coloured spans with their names along the clip (0 to ``n_frames``,
    left to right), one colour per label name (:data:`mocapviz.viz.palette.SERIES`, names in sorted order),
    overlapping spans in lanes below each other; rejected hits left out. Each span's element carries
    ``data-label``, ``data-start``, ``data-end`` (frames, half-open) and a tooltip naming its frames, seconds,
    author and source."""
    shown = labels[labels["source"] != "rejected hit"].sort_values(["start", "label_id"])
    if shown.empty:
        return '<div class="mv-no-labels">No segment label in this clip.</div>'
    names = sorted(shown["label"].astype(str).unique())
    colour = {n: SERIES[i % len(SERIES)] for i, n in enumerate(names)}
    starts, ends = shown["start"].astype(int).tolist(), shown["end"].astype(int).tolist()
    lane = lanes(starts, ends)
    spans = []
    for (_, row), a, b, k in zip(shown.iterrows(), starts, ends, lane):
        name = html.escape(str(row["label"]))
        tip = html.escape(f"{row['label']}: frames {a}:{b} ({a / fps:.2f}–{b / fps:.2f} s) · {row['author']} · "
                          f"{row['source']}", quote=True)
        spans.append(f'<div class="mv-segment" data-label="{name}" data-start="{a}" data-end="{b}" title="{tip}" '
                     f'style="position:absolute;left:{100 * a / n_frames:.3f}%;width:{100 * (b - a) / n_frames:.3f}%;'
                     f'top:{k * LANE_PX}px;height:{LANE_PX - 3}px;background:{colour[str(row["label"])]};color:#fff;'
                     f'font:12px sans-serif;overflow:hidden;white-space:nowrap;border-radius:3px;padding:2px 4px;'
                     f'box-sizing:border-box">{name}</div>')
    height = (max(lane) + 1) * LANE_PX
    scale = (f'<div style="display:flex;justify-content:space-between;font:11px sans-serif;color:#666">'
             f'<span>0 s</span><span>{plural(n_frames, "frame")} · {n_frames / fps:.2f} s</span></div>')
    return (f'<div style="position:relative;height:{height}px;background:#f4f4f4;width:100%">{"".join(spans)}</div>'
            + scale)


def _choices(column: pd.Series) -> list[str]:
    """The distinct non-empty values of a document table's column, sorted: a filter's options."""
    return sorted(v for v in column.unique() if v)
