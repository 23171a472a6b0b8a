"""Index statistics page: the open database's index and search figures beside the papers' tables.

- Müller, Röder & Clausen 2005, Table 2 (§6.1): per feature group the inverted index's lists, segments, size and
  construction times (:func:`mocapviz.experiments.relational.index_statistics`), with the paper's D^60 / D^180 rows.
- Müller et al. 2005, Table 3 (§6.2): exact and adaptive fuzzy random queries on one group index, grouped by hit
  count (:func:`query_statistics`), with the paper's I_u^180 values; and every query's time against its hit count.
- Krüger, Tautges, Weber & Zinke 2010, Table 1 (§3.3): exact k-NN query times per feature set
  (:func:`mocapviz.experiments.numeric.knn_timings`), with the paper's HDM05 and CMU times.

Computed when *Compute* is pressed (opening the tab computes nothing; tables already computed for the database, by
any session, show at once), as jobs of the server's queue (:mod:`mocapviz.app.jobs`: progress, Cancel), with quick
settings (:data:`SIZES`: :data:`QUERIES` random queries, :data:`KNN_QUERIES` k-NN queries) or the papers' sizes, and
cached per database and settings (:meth:`Backend.cached`); each table appears as soon as it is ready.
"""

from __future__ import annotations

import pandas as pd
import panel as pn

from ...engine import (
    index_statistics,
    knn_timings,
    krueger2010_table1,
    mueller2005_table2,
    mueller2005_table3,
    query_statistics,
)
from ...validation import plural
from ...viz.paper import comparison_bars, curves
from ...viz.statistics import query_time_scatter
from ..jobs import JobTask
from ..widgets import action_button

OURS = "this database"
NA = "–"  # a missing value in a table
LEGEND_OUTSIDE = {"legend_position": "right", "backend": "bokeh"}  # bar legends beside the bars, not over them
SEED = 0
QUERIES = 200  # random queries per (mode, L) cell of Table 3 (the paper: 10,000)
TABLE3_LENGTHS = (5, 10, 20)  # the paper's query lengths |Q| in segments
SCATTER_LENGTHS = (1, 2, 3, 5, 10, 20)  # short queries too: on a small index the long ones all have a single hit
SCATTER_POINTS = 5000  # queries drawn in the scatter at most (a seeded sample of them at the papers' sizes)
KNN_QUERIES = 20  # k-NN queries per feature set of Table 1 (batched, one thread)
KNN_REPEATS = 1  # timed runs of each batch of Table 1 (the median is shown)
SIZES = {"quick": (QUERIES, KNN_QUERIES, KNN_REPEATS),  # (Table 3 queries, Table 1 queries, Table 1 repeats)
         "the papers' sizes (minutes)": (10_000, 1000, 3)}  # fmt: skip
TABLE2_SHOWN = ["source", "index", "minutes", "f", "lists", "frames", "segments", "MB", "bytes/segment", "t_read",
                "t_features", "t_index", "t_total"]  # fmt: skip
TABLE3_RENAMED = {"mean_hits": "µh", "std_hits": "σh", "mean_ms": "µt (ms)",
                  "median_ms": "median (ms)", "p90_ms": "p90 (ms)"}  # fmt: skip
TABLE3_PAPER = {"mean_hits": "paper µh", "std_hits": "paper σh", "mean_ms": "paper µt (ms)"}


def cell_text(x) -> str:
    """A table cell: integers with thousands separators, other numbers to 3 significant digits (at least 0.001)."""
    if pd.isna(x):
        return NA
    if float(x).is_integer():
        return f"{int(x):,}"
    return f"{x:.3g}" if abs(x) >= 0.001 else f"{x:.2e}"


def _table(frame: pd.DataFrame, css: str) -> pn.pane.DataFrame:
    formatters = {c: cell_text for c in frame.columns if pd.api.types.is_numeric_dtype(frame[c])}
    return pn.pane.DataFrame(frame, index=False, formatters=formatters, na_rep=NA, css_classes=[css, "mv-result-table"],
                             sizing_mode="stretch_width", margin=(0, 10))


# ------------------------------------------------------------------ the tables, ours beside the paper's
def table2(backend) -> pd.DataFrame:
    """Table 2 of the open database (one row per group index) above the paper's six rows; column ``source``."""
    ours = backend.cached(("statistics", "table2"), lambda: index_statistics(backend.db, "2005"))
    return pd.concat([ours.assign(source=OURS), mueller2005_table2().assign(source="paper")], ignore_index=True)


def table3(backend, group: str, queries: int = QUERIES) -> pd.DataFrame:
    """Table 3 on the open database's ``group`` index: one row per (mode, L, hits group) with our statistics of
    ``queries`` random queries per (mode, L) and the paper's µh, σh, µt (I_u^180) beside them."""
    ours = backend.cached(("statistics", "table3", group, queries), lambda: query_statistics(
        backend.engine.indexes()[group], n_queries=queries, lengths=TABLE3_LENGTHS, seed=SEED))  # fmt: skip
    paper = mueller2005_table3()[["mode", "L", "hits", *TABLE3_PAPER]].rename(columns=TABLE3_PAPER)
    return ours.merge(paper, on=["mode", "L", "hits"], how="left").rename(columns=TABLE3_RENAMED)


def query_times(backend, group: str, queries: int = QUERIES) -> pd.DataFrame:
    """Every random query of :data:`SCATTER_LENGTHS` on the ``group`` index: mode, L, k, query, hits, ms, group."""
    return backend.cached(("statistics", "query_times", group, queries), lambda: query_statistics(
        backend.engine.indexes()[group], n_queries=queries, lengths=SCATTER_LENGTHS, seed=SEED, per_query=True))  # fmt: skip


def table1(backend, queries: int = KNN_QUERIES, repeats: int = KNN_REPEATS) -> pd.DataFrame:
    """Table 1 in long form: our mean ms per k-NN query per (set, k) (``database`` = :data:`OURS`; ``queries``
    random frames, the median of ``repeats`` timed runs) and the paper's HDM05 and CMU rows; columns database,
    frames, set, d, k, mean_ms."""
    ours = backend.cached(("statistics", "table1", queries, repeats), lambda: knn_timings(
        backend.db, n_queries=min(queries, backend.db.n_frames), threads=1, seed=SEED, database=OURS,
        repeats=repeats))  # fmt: skip
    paper = krueger2010_table1().merge(ours[["set", "d"]].drop_duplicates(), on="set", how="left")
    return pd.concat([ours, paper.assign(database=paper["database"] + " (paper)")], ignore_index=True)


def table1_wide(long: pd.DataFrame) -> pd.DataFrame:
    """Table 1 as printed: one row per feature set (in the paper's order), its dimension d, and one column of mean
    ms per (database, k)."""
    wide = long.pivot_table(index=["set", "d"], columns=["k", "database"], values="mean_ms", sort=False)
    databases = list(dict.fromkeys(long["database"]))
    wide = wide[sorted(wide.columns, key=lambda c: (c[0], databases.index(c[1])))]
    wide.columns = [f"{db}, k={k}" for k, db in wide.columns]
    return wide.reset_index()


# ------------------------------------------------------------------ the page
class StatisticsPage(pn.viewable.Viewer):
    """Müller 2005 Tables 2-3 and Krüger 2010 Table 1 for the open database, each beside the paper's numbers."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.task = JobTask()
        self.size = pn.widgets.RadioButtonGroup(options=list(SIZES), value="quick", css_classes=["mv-statistics-size"])
        self.button = action_button("Compute", "mv-statistics-run", self._compute, width=110)
        self.group = pn.widgets.Select(label="index of Table 3", options=["upper", "lower", "mix"], value="upper",
                                       width=160, css_classes=["mv-table3-group"])  # fmt: skip
        self.group.param.watch(lambda e: pn.state.execute(self._queries), "value")
        self.table2 = pn.Column(sizing_mode="stretch_width")
        self.table3 = pn.Column(sizing_mode="stretch_width")
        self.table1 = pn.Column(sizing_mode="stretch_width")
        self.computed = False  # Compute was pressed: another index of Table 3 is then computed when chosen

    def __panel__(self):
        db = self.backend.db
        quick, paper = SIZES["quick"], SIZES[list(SIZES)[1]]
        intro = pn.pane.Markdown(
            f"The indexes of **{db.path.name}** ({plural(db.n_frames, 'frame')}, {plural(len(db), 'document')}) beside the papers' "
            f"tables: Müller, Röder & Clausen 2005 Tables 2 and 3 (relational indexes, 120 Hz), Krüger et al. 2010 "
            f"Table 1 (kd-tree k-NN search, 30 Hz). *Quick*: {quick[0]} random queries per row of Table 3, "
            f"{quick[1]} k-NN queries per feature set; *the papers' sizes*: {paper[0]:,} and {paper[1]:,}, "
            f"{paper[2]} timed runs.", sizing_mode="stretch_width")
        return pn.Column(intro, pn.Row(self.size, self.button), self.task,
                         "### Müller 2005, Table 2: feature computation and index construction", self.table2,
                         "### Müller 2005, Table 3: random queries", self.group, self.table3,
                         "### Krüger 2010, Table 1: k-NN query times", self.table1, sizing_mode="stretch_width")

    def activate(self) -> None:
        """Show the tables already computed for this database and size (by any session); compute nothing."""
        _, knn_queries, repeats = SIZES[self.size.value]
        if self.backend.is_cached(("statistics", "table2")) and not len(self.table2):
            self.table2[:] = self._table2_view(table2(self.backend))
        if not len(self.table3):
            self._cached_table3()
        if self.backend.is_cached(("statistics", "table1", knn_queries, repeats)) and not len(self.table1):
            self.table1[:] = self._table1_view(table1(self.backend, knn_queries, repeats), knn_queries)

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the three tables at the quick size, as jobs (Cancel stops
        them; tables computed already by any session show at once)."""
        await self._compute()

    def _cached_table3(self) -> bool:
        """Show Table 3 of the chosen index and size if it was computed already; False when it was not."""
        group, (queries, _, _) = self.group.value, SIZES[self.size.value]
        if not all(self.backend.is_cached(("statistics", name, group, queries)) for name in ("table3", "query_times")):
            return False
        self.table3[:] = self._table3_view(table3(self.backend, group, queries),
                                           query_times(self.backend, group, queries))
        return True

    async def _compute(self, event=None) -> None:
        """The three tables, one job each (queued behind other sessions' jobs); Cancel stops the rest too."""
        self.computed = True
        _, knn_queries, repeats = SIZES[self.size.value]
        self.button.disabled = True
        try:
            both = await self.task.run("Table 2: relational features and indexes", table2, self.backend)
            if both is not None:
                self.table2[:] = self._table2_view(both)
            if self.task.stopped or not await self._queries():
                return
            long = await self.task.run("Table 1: k-NN query times", table1, self.backend, knn_queries, repeats)
            if long is not None:
                self.table1[:] = self._table1_view(long, knn_queries)
        finally:
            self.button.disabled = False

    async def _queries(self) -> bool:
        """Table 3 on the chosen index: at once when computed already, as a job once Compute was pressed (not while
        another of the page's jobs runs); False when that job was cancelled."""
        if self._cached_table3() or not self.computed or self.task.running:
            return True
        group, (queries, _, _) = self.group.value, SIZES[self.size.value]
        self.group.disabled = True
        result = await self.task.run(f"Table 3: random queries on the {group} index",
                                     lambda: (table3(self.backend, group, queries),
                                              query_times(self.backend, group, queries)),
                                     stale=(self.table3,))  # another index's table must not stay under the error
        self.group.disabled = False
        if result is not None:
            self.table3[:] = self._table3_view(*result)
            self.table3.visible = True
        return not self.task.stopped

    # ------------------------------------------------------------------ views
    @staticmethod
    def _table2_view(both: pd.DataFrame) -> list:
        both = both.assign(**{"segments per 100 frames": 100 * both["segments"] / both["frames"]})
        bars = [comparison_bars(both, "index", column, title=title, width=600, height=300).opts(**LEGEND_OUTSIDE)
                for column, title in (("segments per 100 frames", "segments per 100 frames"),
                                      ("bytes/segment", "index bytes per segment"))]  # fmt: skip
        note = pn.pane.Markdown("Times in seconds (the paper: Matlab on a 3.6 GHz Pentium 4). ``t_read`` is the "
                                "reading of the motion files, done at ingest here, so not measured.")
        return [_table(both[TABLE2_SHOWN], "mv-table2"), note,
                pn.Row(*[pn.pane.HoloViews(b, css_classes=["mv-table2-bars"]) for b in bars])]

    @staticmethod
    def _table3_view(table: pd.DataFrame, per_query: pd.DataFrame) -> list:
        long = pd.concat([table.rename(columns={"µt (ms)": "mean_ms"}).assign(source=OURS),
                          mueller2005_table3().assign(source="paper")], ignore_index=True)  # fmt: skip
        long["series"] = long["source"] + ", " + long["mode"] + ", " + long["hits"] + " hits"
        mean = curves(long, "L", "mean_ms", "series", title="mean query time per hit group",
                      xlabel="query length L (segments)", ylabel="ms", logy=True, width=620, height=340)
        drawn = per_query.sample(n=min(len(per_query), SCATTER_POINTS), random_state=SEED).sort_index()
        scatter = query_time_scatter(drawn, title=f"query time against hits ({len(drawn):,} of {len(per_query):,} "
                                                  f"random queries, L = {', '.join(map(str, SCATTER_LENGTHS))})")
        queries = int(table.groupby(["mode", "L"])["queries"].sum().iloc[0])
        note = pn.pane.Markdown(f"Fuzzy queries are adaptive, 64 alternatives per set (§6.2). µh, σh: mean and "
                                f"standard deviation of the hit count; µt: mean time per query. {plural(queries, 'query', 'queries')} "
                                f"per (mode, L); the paper's 10,000 on I_u^180.")
        return [_table(table, "mv-table3"), note,
                pn.Row(pn.pane.HoloViews(mean, css_classes=["mv-table3-curves"]),
                       pn.pane.HoloViews(scatter, css_classes=["mv-query-times"]))]

    def _table1_view(self, long: pd.DataFrame, queries: int) -> list:
        bars = [comparison_bars(long[long["k"] == k], "set", "mean_ms", source="database", logy=True, width=640,
                                height=320, ylabel="ms per query", title=f"k = {k}").opts(**LEGEND_OUTSIDE)
                for k in sorted(set(long["k"]))]
        note = pn.pane.Markdown(
            f"Mean milliseconds per exact k-NN query (scipy cKDTree, one thread; {plural(queries, 'query', 'queries')}) on this "
            f"database's {plural(self.backend.db.n_frames, 'frame')}; the paper (ANN library, 2010): HDM05 380,813 and CMU "
            f"1,038,388 frames at 30 Hz.", css_classes=["mv-table1-note"])
        return [_table(table1_wide(long), "mv-table1"), note,
                # not linked: each log axis starts below its own bars (linked, k = 256's bars would float above the
                # lower end k = 16's smaller times give the shared axis)
                pn.Row(*[pn.pane.HoloViews(b, linked_axes=False, css_classes=["mv-table1-bars"]) for b in bars])]
