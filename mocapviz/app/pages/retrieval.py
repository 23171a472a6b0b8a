"""Retrieval quality page: how well each search method of the product finds the documents of the query's class on
the open database (:func:`mocapviz.experiments.retrieval_quality`).

Labelled documents are the queries (a seeded sample of :func:`default_queries` by default: 24 on the demo database,
fewer on a large one, so that the page answers in seconds to tens of seconds; 0 evaluates them all); each method ranks the other documents, judged by :mod:`mocapviz.experiments.evaluation`. The
summary table (mAP leave-one-out and leave-group-out, P@1, P@10, recall of brute-force DTW's top 10, ms per query),
the AP per class and method and the precision/recall curves appear behind the Evaluate button, computed as a job of
the server's queue (:mod:`mocapviz.app.jobs`: progress per query, Cancel) and cached per database and settings
(:meth:`Backend.retrieval`).
"""

from __future__ import annotations

import pandas as pd
import panel as pn

from ...engine import METHOD_LABELS, METHODS
from ...errors import ParameterError
from ...validation import plural
from ...viz.retrieval import class_ap_bars, pr_curves
from ..jobs import JobTask
from ..widgets import BoundedIntInput, action_button, notes

DEFAULT_METHODS = ["dtw", "exact", "fast", "lng256"]  # the relational ones build the indexes on first use
DEFAULT_QUERIES = 24  # queries offered first on a database of up to SMALL_DATABASE documents ...
SMALL_DATABASE = 300  # ... fewer on a larger one: each query's rankings (brute-force DTW, ...) grow with it
MIN_QUERIES = 4
NO_GROUP = "(none)"
SUMMARY_TITLES = {"method": "method", "queries": "queries", "map_loo": "mAP (leave-one-out)",
                  "map_lgo": "mAP (leave-group-out)", "p_at_1": "P@1", "p_at_10": "P@10",
                  "recall_dtw_top10": "recall of DTW top 10", "ms_per_query": "ms / query (K = 10)", "note": "note"}
NA = "–"
NOTE_WIDTH = 300  # pixels of the summary's note column (its text wraps)


def default_queries(n_documents: int) -> int:
    """The queries offered first: :data:`DEFAULT_QUERIES` on up to :data:`SMALL_DATABASE` documents, proportionally
    fewer on more (at least :data:`MIN_QUERIES`): about the same evaluation time on any database (3,395
    documents: 4 queries, under a minute with the default methods, most of it their first search)."""
    return max(MIN_QUERIES, min(DEFAULT_QUERIES, DEFAULT_QUERIES * SMALL_DATABASE // max(n_documents, 1)))


def label_columns(documents: pd.DataFrame, columns) -> list[str]:
    """The label columns that can judge a search: some value shared by at least two documents."""
    out = []
    for c in columns:
        counts = documents[c].dropna().astype(str).replace("", None).dropna().value_counts()
        if len(counts) and counts.max() >= 2:
            out.append(c)
    return out


def summary_titles(summary: pd.DataFrame) -> dict:
    """Column titles of the summary table (the leave-group-out column named after its group)."""
    titles = dict(SUMMARY_TITLES)
    if summary.attrs.get("group_column"):
        titles["map_lgo"] = f"mAP (leave-{summary.attrs['group_column']}-out)"
    return titles


def summary_view(summary: pd.DataFrame) -> pd.DataFrame:
    """The summary table as shown (titles by :func:`summary_titles`): fractions to 3 decimals, ms to 0.1."""
    shown = summary[list(SUMMARY_TITLES)].copy()
    for c in ("map_loo", "map_lgo", "p_at_1", "p_at_10", "recall_dtw_top10"):
        shown[c] = shown[c].map(lambda v: NA if pd.isna(v) else f"{v:.3f}")
    shown["ms_per_query"] = shown["ms_per_query"].map(lambda v: NA if pd.isna(v) else f"{v:.1f}")
    return shown


def count_text(summary: pd.DataFrame, methods, label: str, group) -> str:
    """What was evaluated, above the summary table: the queries, the documents (and how many of them have no
    ``label``: searched, never relevant, never a query), the relevance rule and the methods."""
    attrs = summary.attrs
    unlabelled = attrs.get("unlabelled", 0)
    left_out = f" ({unlabelled} without a {label}: searched, never relevant, never a query)" if unlabelled else ""
    return (f"**{plural(attrs['queries'], 'query', 'queries')}** of {plural(attrs['documents'], 'document')}{left_out}, relevant = same {label}"
            + (f", leave-{group}-out" if group else "")
            + ", " + ", ".join(f"{m}: {METHOD_LABELS.get(m, m)}" for m in methods))  # fmt: skip


class RetrievalPage(pn.viewable.Viewer):
    """Evaluate the search methods on the open database: summary table, AP per class, P/R curves."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        docs = backend.documents
        labels = label_columns(docs, backend.db.label_columns)
        groups = [c for c in backend.db.label_columns if docs[c].notna().any()]
        self.methods = pn.widgets.MultiChoice(name="methods", options=list(METHODS), value=list(DEFAULT_METHODS),
                                              width=460, css_classes=["mv-retrieval-methods"])
        self.label = pn.widgets.Select(name="relevant = same", options=labels or ["label"],
                                       value="label" if "label" in labels else (labels or ["label"])[0], width=160,
                                       css_classes=["mv-retrieval-label"])  # fmt: skip
        self.group = pn.widgets.Select(name="leave-group-out by", options=[NO_GROUP, *groups],
                                       value="actor" if "actor" in groups else NO_GROUP, width=160,
                                       css_classes=["mv-retrieval-group"])  # fmt: skip
        labelled = int(docs[self.label.value].notna().sum()) if self.label.value in docs else len(docs)
        self.n_queries = BoundedIntInput("queries, 0 = all", min(default_queries(len(docs)), labelled), 0, labelled,
                                         width=150, css_classes=["mv-retrieval-n"])
        self.label.param.watch(self._bound_queries, "value")
        self.button = action_button("Evaluate", "mv-retrieval-run", self._evaluate)
        self.task = JobTask()
        self.count = pn.pane.Markdown("", css_classes=["mv-retrieval-count"], margin=(0, 10))
        # the note (why a method skipped queries, ...) wraps in a column of its own width instead of being cut off
        self.summary = pn.widgets.Tabulator(pd.DataFrame(columns=list(SUMMARY_TITLES)), titles=dict(SUMMARY_TITLES),
                                            show_index=False, selectable=False,
                                            disabled=True, sizing_mode="stretch_width", layout="fit_data_table",
                                            widths={"note": NOTE_WIDTH}, formatters={"note": {"type": "textarea"}},
                                            css_classes=["mv-retrieval-summary"],
                                            configuration={"renderVertical": "basic"})  # fmt: skip
        self.figures = pn.Column(sizing_mode="stretch_width", css_classes=["mv-retrieval-figures"])
        self.result = None

    def __panel__(self):
        db = self.backend.db
        intro = pn.pane.Markdown(
            f"Every labelled document of **{db.path.name}** (or a seeded sample of them) is a query; each method "
            "ranks the other documents, and a document is relevant when it carries the query's label. "
            "**dtw**: brute-force whole-clip DTW (the reference); **exact** / **fast**: the Similarity page's search "
            "modes; **lng256** / **lng1024**: the lazy neighbourhood graph (Krüger et al. 2010 §4.1), documents "
            "ranked by their best match; **relational**: query by example with the class's feature selection "
            "(Müller et al. 2005; HDM05 classes only); **hybrid**: relational hits re-ranked by DTW. "
            "Leave-group-out: a query of actor A searches only the other actors' documents. Time: one search for the "
            "10 best documents.",
            sizing_mode="stretch_width")  # fmt: skip
        return pn.Column(intro, pn.Row(self.methods, self.label, self.group, self.n_queries, self.button),
                         notes(self.n_queries),
                         pn.Column(self.task, css_classes=["mv-retrieval-task"], sizing_mode="stretch_width",
                                   margin=0),
                         self.count, self.summary, self.figures, sizing_mode="stretch_width")

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the default methods evaluated on the default queries, as a
        job (Cancel stops it)."""
        await self._evaluate()

    def _bound_queries(self, event=None) -> None:
        """At most as many queries as documents carry the chosen label."""
        docs = self.backend.documents
        label = self.label.value
        self.n_queries.set_bounds(0, int(docs[label].notna().sum()) if label in docs else len(docs))

    def _settings(self) -> tuple:
        n = int(self.n_queries.value or 0)
        group = None if self.group.value == NO_GROUP else self.group.value
        return tuple(self.methods.value), self.label.value, group if group else False, n or None

    def _compute(self, methods, label, group, n_queries) -> dict:
        if not methods:
            raise ParameterError("choose at least one method")
        if group == label:
            raise ParameterError(f"the label and the leave-group-out column are both {label!r}; choose another group")
        return self.backend.retrieval(methods, label_column=label, group_column=group, n_queries=n_queries)

    async def _evaluate(self, event=None) -> None:
        settings = self._settings()
        result = await self.task.run("Evaluating", self._compute, *settings, busy=self.button,
                                     stale=(self.count, self.summary, self.figures))
        if result is None:
            self.result = None
            return
        self.result = result
        summary = result["summary"]
        self.summary.param.update(value=summary_view(summary), titles=summary_titles(summary))
        methods, label, group, _ = settings
        self.count.object = count_text(summary, methods, label, group)
        panes = []
        for protocol in ("loo", "lgo"):
            if result["per_class"][f"ap_{protocol}"].notna().any():
                panes.append(pn.Row(
                    pn.pane.HoloViews(class_ap_bars(result["per_class"], protocol, width=720, height=340),
                                      css_classes=[f"mv-retrieval-bars-{protocol}"]),
                    pn.pane.HoloViews(pr_curves(result["curves"], protocol, width=420, height=340),
                                      css_classes=[f"mv-retrieval-curves-{protocol}"])))  # fmt: skip
        self.figures[:] = panes
        self.figures.visible = True
