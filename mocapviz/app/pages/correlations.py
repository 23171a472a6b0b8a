"""Correlations page: Spearman rank correlations between feature sets and distance measures (Krüger, Tautges, Weber
& Zinke 2010, §3.3, Fig. 2), pose-based and segment-based, for the open database.

Both use the correlation sample (:func:`mocapviz.experiments.correlation.correlation_sample`: the labelled classes
with at least ``clips per class`` clips, that many clips of each; the paper: 8 per class). Pose-based
(:func:`pose_correlations`, Fig. 2) draws random query frames from the sample's clips, or from every document when
the database has no such sample; segment-based (:func:`segment_correlations`, DTW between all pairs of clips) needs
the sample, and the page says so when the database cannot give one. Computed when *Compute* is pressed (opening the
tab computes nothing; matrices already computed for the database and settings, by any session, show at once), as
jobs of the server's queue (:mod:`mocapviz.app.jobs`: progress, Cancel), with a fixed seed (:data:`SEED`), so the
same settings always give the same matrices, and cached per database and settings.
"""

from __future__ import annotations

import pandas as pd
import panel as pn

from ...engine import available_measures, correlation_sample, pose_correlations, pose_limits, segment_correlations
from ...validation import plural
from ...viz.correlation import correlation_heatmap
from ..jobs import JobTask
from ..widgets import BoundedIntInput, action_button, notes

SEED = 0
DEFAULT_MEASURES = ("Fp16", "F15E", "F30E", "F39E", "F15x3E", "Dpc1")  # cheap on a small database: ~5 s in all
PAPER_CLIPS = 8  # clips per class of the paper's sample (76 clips of 9 HDM05 classes)
DEFAULT_QUERIES, DEFAULT_K = 128, 64  # fewer than the paper's 1024 and 256: seconds on a small database
QUICK_CLIPS = 3  # clips per class offered first: DTW of all pairs of 33 clips, not 88 (~15 s on 3,395 documents)
PAPER_SETTINGS = {"n_queries": 1024, "k": 256, "clips": PAPER_CLIPS, "n_first": PAPER_CLIPS}  # Fig. 2 of the paper
WIDTH = 660  # pixels of each of the two matrices' columns: side by side on a 1400-pixel screen
CELL = (24, 110)  # pixels of a heat map's cell: as large as the column allows within these


def default_clips(documents: pd.DataFrame) -> int:
    """Clips per class for the sample: the paper's 8, or fewer when the database has fewer (the second largest
    class's count, so that two classes qualify), at least 2."""
    if "label" not in documents or documents["label"].isna().all():
        return PAPER_CLIPS
    counts = documents["label"].value_counts().to_numpy()
    return max(2, min(PAPER_CLIPS, int(counts[1]) if len(counts) > 1 else 0))


def sample_of(db, clips: int) -> tuple[pd.DataFrame | None, str]:
    """The correlation sample with ``clips`` clips per class (classes with at least that many), or None and why
    the database cannot give one."""
    try:
        return correlation_sample(db, clips_per_class=clips, min_clips=clips, seed=SEED), ""
    except ValueError as exc:
        return None, str(exc)


def pose_key(measures: tuple, n_queries: int, k: int, clips: int) -> tuple:
    """The Backend cache key of :func:`pose_matrix`."""
    return ("correlations", "pose", measures, n_queries, k, clips, SEED)


def pose_matrix(backend, measures: tuple, n_queries: int, k: int, clips: int) -> pd.DataFrame:
    """Fig. 2 on the open database: rows = columns = ``measures``; query frames from the correlation sample's clips
    (all documents without one). Cached per settings."""
    def compute():
        sample, _ = sample_of(backend.db, clips)
        return pose_correlations(backend.db, rows=measures, columns=measures, docs=sample, n_queries=n_queries, k=k,
                                 seed=SEED)  # fmt: skip
    return backend.cached(pose_key(measures, n_queries, k, clips), compute)


def segment_key(measures: tuple, clips: int, n_first: int) -> tuple:
    """The Backend cache key of :func:`segment_matrix`."""
    return ("correlations", "segment", measures, clips, n_first, SEED)


def segment_matrix(backend, measures: tuple, clips: int, n_first: int) -> pd.DataFrame:
    """§3.3 segment-based on the correlation sample (which must exist: :func:`segment_problem`). Cached per
    settings."""
    def compute():
        return segment_correlations(backend.db, sample_of(backend.db, clips)[0], measures=measures, n_first=n_first)
    return backend.cached(segment_key(measures, clips, n_first), compute)


def segment_problem(db, clips: int, n_first: int) -> str:
    """Why the segment-based comparison cannot run with these settings ("" when it can)."""
    sample, why = sample_of(db, clips)
    if sample is None:
        return (f"**Segment-based comparisons need several clips per class**, and this database cannot give a "
                f"sample of {plural(clips, 'clip')} per class: {why}. Lower *clips per class* (at least 2), or open a labelled "
                f"database with more takes per class (the paper: {PAPER_CLIPS} per class).")
    if not 2 <= n_first < len(sample):
        return (f"*first n* must be between 2 and {len(sample) - 1} (the sample's {plural(len(sample), 'clip')} less "
                f"the query clip); it is {n_first}.")
    return ""


def values_table(matrix: pd.DataFrame, css: str) -> pn.pane.DataFrame:
    """The matrix's values to 3 decimals (rows: neighbours by; columns: compared with; extra columns as they are);
    wider than its card (many measures), it scrolls sideways rather than being cut off."""
    return pn.pane.DataFrame(matrix.round(3), float_format=lambda x: f"{x:.3f}", css_classes=[css],
                             sizing_mode="stretch_width", styles={"overflow-x": "auto"})


def heatmap_cell(n_columns: int) -> int:
    """The cell size (pixels) of a heat map of ``n_columns`` measures in a column of :data:`WIDTH` pixels (less the
    row names and the colour bar): large for 2 measures, small enough for 14; the values' font follows
    (:func:`mocapviz.viz.correlation.value_font`)."""
    return max(CELL[0], min(CELL[1], (WIDTH - 190) // max(n_columns, 1)))


class MatrixView(pn.viewable.Viewer):
    """One correlation matrix: its heat map (Fig. 2's form), a caption and its values in a card that stays open or
    closed across recomputations. Hidden until the first matrix."""

    def __init__(self, kind: str):
        super().__init__()
        self.kind = kind
        # not linked: the two heat maps share their axes' names, and linked axes would keep the ranges of the other
        # one's measures (two measures' cells squeezed into a corner of a six-measure frame)
        self.plot = pn.pane.HoloViews(None, linked_axes=False, css_classes=[f"mv-heatmap-{kind}"])
        self.caption = pn.pane.Markdown("", css_classes=[f"mv-{kind}-caption"], sizing_mode="stretch_width")
        self.values = pn.Card(title="values", collapsed=True, css_classes=[f"mv-values-{kind}"], width=WIDTH - 20)
        self.layout = pn.Column(self.plot, self.caption, self.values, visible=False, width=WIDTH)

    def __panel__(self):
        return self.layout

    def show(self, matrix: pd.DataFrame, caption: str, table: pd.DataFrame | None = None) -> None:
        """Draw ``matrix`` [shape=(R, C)], rho; ``table`` (default the matrix) goes into the values card."""
        cell = heatmap_cell(len(matrix.columns))
        self.plot.object = correlation_heatmap(matrix, title=f"{self.kind}-based", cell=cell)
        self.caption.object = caption
        self.values[:] = [values_table(matrix if table is None else table, f"mv-correlation-{self.kind}")]
        self.layout.visible = True

    def hide(self) -> None:
        self.layout.visible = False


class CorrelationsPage(pn.viewable.Viewer):
    """Krüger 2010 Fig. 2 for the open database: the measures and settings chosen, both heat maps computed."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        db = backend.db
        options = list(available_measures(db))
        self.measures = pn.widgets.MultiChoice(label="feature sets and distance measures", options=options,
                                               value=[m for m in DEFAULT_MEASURES if m in options], width=520,
                                               css_classes=["mv-measures"])  # fmt: skip
        # bounds by pose_limits on the sample's frames (_bound_sample)
        self.n_queries = BoundedIntInput("queries", DEFAULT_QUERIES, 1, None, width=130, css_classes=["mv-queries"])
        self.k = BoundedIntInput("k", DEFAULT_K, 1, None, width=110, css_classes=["mv-k"])
        self.clips = BoundedIntInput("clips per class", min(QUICK_CLIPS, default_clips(db.documents)), 2, None,
                                     width=130, css_classes=["mv-clips"])
        self.n_first = BoundedIntInput("first n", PAPER_CLIPS, 2, max(2, len(db) - 1), width=110,
                                       css_classes=["mv-first-n"])
        self.clips.param.watch(self._bound_sample, "value")
        self._bound_sample()
        self.button = action_button("Compute", "mv-compute", self._compute, width=110)
        self.paper = pn.widgets.Button(name="the paper's settings", width=160, align="end",
                                       css_classes=["mv-paper-settings"])  # fmt: skip
        self.paper.on_click(lambda event: self.paper_settings())
        self.pose_task, self.segment_task = JobTask(), JobTask()
        self.pose, self.segment = MatrixView("pose"), MatrixView("segment")
        self.segment_note = pn.pane.Alert("", alert_type="warning", visible=False, css_classes=["mv-segment-problem"])

    def __panel__(self):
        intro = pn.pane.Markdown(
            "Mean Spearman rank correlation ρ between the distances of two measures (Krüger et al. 2010, §3.3, "
            "Fig. 2): the neighbours are chosen by the **row** measure and their distances compared with those of "
            "the **column** measure, so the matrix is not symmetric. The paper: 1024 queries, k = 256, 8 clips of "
            "each of 9 classes, the first 8 of each ranking.", sizing_mode="stretch_width")
        controls = pn.Row(self.measures, self.n_queries, self.k, self.clips, self.n_first, self.paper, self.button)
        inputs = notes(self.n_queries, self.k, self.clips, self.n_first)
        pose = pn.Column("### Pose-based (Fig. 2)", self.pose_task, self.pose, width=WIDTH)
        segment = pn.Column("### Segment-based (DTW of clips)", self.segment_task, self.segment_note, self.segment,
                            width=WIDTH)
        return pn.Column(intro, controls, inputs, pn.FlexBox(pose, segment), sizing_mode="stretch_width")

    def _bound_sample(self, event=None) -> None:
        """The bounds that follow the sample of *clips per class*: queries and k those of the library on the
        sample's frames (:func:`mocapviz.experiments.correlation.pose_limits`; all documents without a sample);
        *first n* from 2 to the sample's clips less the query clip (without a sample the documents less one, and the
        page says why the segment-based matrix cannot be computed)."""
        sample, _ = sample_of(self.backend.db, self.clips.value)
        limits = pose_limits(self.backend.db, sample)
        self.n_queries.set_bounds(*limits["n_queries"])
        self.k.set_bounds(*limits["k"])
        most = len(sample) - 1 if sample is not None else len(self.backend.db) - 1
        self.n_first.set_bounds(2, max(2, most))

    def paper_settings(self) -> None:
        """The paper's 1024 queries, k = 256, 8 clips per class and the first 8 clips (as far as the database allows:
        each box keeps to its bounds and says so); Compute then runs Fig. 2 at the paper's size (minutes on a large
        database)."""
        self.clips.value = min(PAPER_SETTINGS["clips"], default_clips(self.backend.db.documents))
        for name in ("n_queries", "k", "n_first"):
            getattr(self, name).value = PAPER_SETTINGS[name]

    def activate(self) -> None:
        """Show the matrices of the chosen settings if they were computed already (by any session); compute
        nothing."""
        measures, n_queries, k, clips, n_first = self.settings()
        if not measures or self.pose_task.running or self.segment_task.running:
            return
        if self.backend.is_cached(pose_key(measures, n_queries, k, clips)) and not self.pose.layout.visible:
            self._show_pose(pose_matrix(self.backend, measures, n_queries, k, clips), clips)
            self.pose_task.status.object = ""
        if (self.backend.is_cached(segment_key(measures, clips, n_first)) and not self.segment.layout.visible
                and not segment_problem(self.backend.db, clips, n_first)):
            self._show_segment(segment_matrix(self.backend, measures, clips, n_first))

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: both matrices with the default settings, as jobs (Cancel
        stops them)."""
        await self._compute()

    def settings(self) -> tuple[tuple, int, int, int, int]:
        """(measures in Fig. 2's order, queries, k, clips per class, first n) as chosen."""
        chosen = [m for m in self.measures.options if m in self.measures.value]
        return tuple(chosen), self.n_queries.value, self.k.value, self.clips.value, self.n_first.value

    async def _compute(self, event=None) -> None:
        measures, n_queries, k, clips, n_first = self.settings()
        if not measures:
            self.pose_task.status.object = "Choose at least one measure."
            self.pose.hide()
            self.segment.hide()
            return
        self.button.disabled = True
        try:
            pose = await self.pose_task.run(f"Pose-based, {plural(len(measures), 'measure')}", pose_matrix, self.backend,
                                            measures, n_queries, k, clips, stale=[self.pose.layout])  # fmt: skip
            if pose is not None:
                self._show_pose(pose, clips)
            if self.pose_task.stopped:
                return
            problem = segment_problem(self.backend.db, clips, n_first)
            self.segment_note.object, self.segment_note.visible = problem, bool(problem)
            if problem:
                self.segment.hide()
                self.segment_task.status.object = ""
                return
            segment = await self.segment_task.run(f"Segment-based, {plural(len(measures), 'measure')}", segment_matrix,
                                                  self.backend, measures, clips, n_first,
                                                  stale=[self.segment.layout])  # fmt: skip
            if segment is not None:
                self._show_segment(segment)
        finally:
            self.button.disabled = False

    def _show_pose(self, pose: pd.DataFrame, clips: int) -> None:
        self.pose.show(pose, self._pose_caption(pose, sampled=sample_of(self.backend.db, clips)[0] is not None))

    def _show_segment(self, segment: pd.DataFrame) -> None:
        self.segment.show(segment, self._segment_caption(segment), segment.assign(precision=segment.attrs["precision"]))

    @staticmethod
    def _pose_caption(matrix: pd.DataFrame, sampled: bool) -> str:
        a = matrix.attrs
        clips = f"the sample's {plural(a['documents'], 'clip')}" if sampled else \
            f"all {plural(a['documents'], 'document')} (no sample)"
        return (f"{plural(a['n_queries'], 'random query frame')} of {clips} ({plural(a['frames'], 'frame')}), their "
                f"k = {a['k']} nearest {plural(a['k'], 'frame', number=False)} by the row measure.")

    @staticmethod
    def _segment_caption(matrix: pd.DataFrame) -> str:
        a = matrix.attrs
        return (f"DTW between all pairs of the {plural(a['clips'], 'clip')} ({plural(a['frames'], 'frame')}); ρ over "
                f"the first {plural(a['n_first'], 'clip')} of each ranking. *precision*: the share of those with the clip's own class "
                f"(a random ranking: {a['chance']:.3f}).")
