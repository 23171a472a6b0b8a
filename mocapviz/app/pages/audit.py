"""Audit page: the near-copies in the open database (issue 41; :meth:`mocapviz.engine.Engine.audit`, docs/audit.md).

Every pair of stretches of the database that are the same motion again (repeated, left/right mirrored, at another
rate, trimmed, time-scaled within *max scale*, on other bones), each at least *min length* long. Computed when the
page is first shown (the engine's defaults) and when *Run* is pressed, as a job of the server's queue
(:mod:`mocapviz.app.jobs`: progress, Cancel), with the widgets of the engine's "audit" parameters
(:mod:`mocapviz.engine.parameters`: bounds and defaults; an empty threshold is learned from the collection's own
copies), and cached per database and settings (:meth:`Backend.cached`).

Shown: a summary line (pairs, clusters, mirrored pairs, the threshold and how it was set), the table of pairs (best
first; a mirrored pair says "mirrored") and the clusters of copies (the documents the pairs join, and the one
:meth:`~mocapviz.engine.Engine.keep_one` keeps). A pair chosen in the table plays its two stretches side by side,
aligned on the pair's warping path (:meth:`~mocapviz.engine.Engine.audit_path`: each step shows the same moment of
both; a mirrored pair's side B says so). Downloads: the pair table as CSV, and the documents left when each cluster
keeps one (a clean training set) as CSV.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import panel as pn

from ...engine.parameters import PARAMETERS, default
from ...validation import plural
from ..downloads import csv_download
from ..jobs import JobTask
from ..player import SkeletonPlayer
from ..upload import query_clip
from ..widgets import action_button, clear, hit_columns, notes, parameter_box, results_table

USE = "audit"  # the engine's use case of the page's widgets
MIRRORED = "mirrored"  # a mirrored pair's cell in the table's mirrored column
PAIR_TITLES = {"cluster": "cluster", "doc_a": "document A", "name_a": "name A", "start_a": "start A",
               "end_a": "end A (excl.)", "doc_b": "document B", "name_b": "name B", "start_b": "start B",
               "end_b": "end B (excl.)", "seconds": "seconds", "cost": "cost (cm)", "mirrored": "mirrored",
               "scale": "time scale"}  # fmt: skip
PAIR_DECIMALS = {"seconds": 2, "cost": 2, "scale": 3}
CLUSTER_TITLES = {"cluster": "cluster", "documents": "documents", "pairs": "pairs", "kept": "kept by keep-one"}
KEPT_COLUMNS = ["doc_id", "name", "label", "n_frames", "fps"]  # the keep-one download's columns (those the db has)
PLAY_HINT = "Click a pair to play its two stretches side by side, aligned on the pair's warping path."


def run_audit(backend, numeric_set: str, min_length: float, threshold: float | None, max_scale: float,
              mirrored: bool) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The audit of the open database and what keep-one leaves of it: (pairs, kept documents) of
    :meth:`Engine.audit` (its parameters) and :meth:`Engine.keep_one`."""
    pairs = backend.engine.audit(numeric_set=numeric_set, min_length=min_length, threshold=threshold,
                                 max_scale=max_scale, mirrored=mirrored)  # fmt: skip
    return pairs, backend.engine.keep_one(pairs)


def cluster_table(pairs: pd.DataFrame, kept: pd.DataFrame) -> pd.DataFrame:
    """One row per cluster of copies: ``cluster``, ``documents`` ("id name" of each, by id), ``pairs`` and ``kept``
    (the one of them in ``kept``, the keep-one documents).

    Examples
    --------
    >>> pairs = pd.DataFrame({"doc_a": [1, 1], "name_a": ["x", "x"], "doc_b": [2, 3], "name_b": ["y", "z"],
    ...                       "cluster": [0, 0]})
    >>> cluster_table(pairs, pd.DataFrame({"doc_id": [0, 2]})).to_dict("records")
    [{'cluster': 0, 'documents': '1 x, 2 y, 3 z', 'pairs': 2, 'kept': '2 y'}]
    """
    kept_ids, rows = set(kept["doc_id"].astype(int)), []
    for cluster, group in pairs.groupby("cluster"):
        names = {**dict(zip(group["doc_a"].astype(int), group["name_a"])),
                 **dict(zip(group["doc_b"].astype(int), group["name_b"]))}  # fmt: skip
        docs = sorted(names)
        rows.append({"cluster": int(cluster), "documents": ", ".join(f"{d} {names[d]}" for d in docs),
                     "pairs": len(group), "kept": ", ".join(f"{d} {names[d]}" for d in docs if d in kept_ids)})
    return pd.DataFrame(rows, columns=list(CLUSTER_TITLES))


class AuditPage(pn.viewable.Viewer):
    """The near-copies of the open database: settings, Run (a job), the pairs, the clusters, a pair played."""

    def __init__(self, backend, selection):
        super().__init__()
        self.backend, self.selection = backend, selection
        self.numeric_set = pn.widgets.Select(label="numeric set", width=140, css_classes=["mv-audit-set"],
                                             **PARAMETERS["audit_set"].widget(default(USE, "audit_set")))
        self.min_length = parameter_box("min length (s)", "audit_length", USE, width=170,
                                        css_classes=["mv-audit-length"])
        self.threshold = parameter_box("threshold (cm)", "threshold", USE, width=220,
                                       css_classes=["mv-audit-threshold"])
        self.max_scale = parameter_box("max scale", "max_scale", USE, width=140, css_classes=["mv-audit-scale"])
        self.mirrored = pn.widgets.Checkbox(label="also mirrored copies", value=default(USE, "mirrored"), width=180,
                                            align="end", css_classes=["mv-audit-mirrored"])  # fmt: skip
        self.button = action_button("Run", "mv-audit-run", self._run)
        self.task = JobTask()
        self.summary = pn.pane.Markdown("", css_classes=["mv-audit-summary"], margin=(0, 10))
        self.table = results_table(pd.DataFrame(columns=list(PAIR_TITLES)), "mv-audit-table", PAIR_TITLES,
                                   page_size=10, selectable=True)  # fmt: skip
        self.table.param.watch(self._on_select, "selection")
        self.clusters = results_table(pd.DataFrame(columns=list(CLUSTER_TITLES)), "mv-audit-clusters",
                                      CLUSTER_TITLES, page_size=10)  # fmt: skip
        self.pairs = self.kept = None  # the audit shown
        self.pairs_download = csv_download(lambda: self.pairs, "audit_pairs.csv", "Download the pairs (.csv)",
                                           "mv-audit-pairs-csv")  # fmt: skip
        self.kept_download = csv_download(self._kept_documents, "keep_one.csv",
                                          "Download the documents, one of each cluster (.csv)", "mv-audit-keep-csv")
        self.playing = pn.pane.Markdown(PLAY_HINT, margin=(0, 10), css_classes=["mv-audit-playing"])
        self.player = SkeletonPlayer(size=(760, 380))
        self.player_box = pn.Column(self.player, visible=False, css_classes=["mv-audit-player"])

    def __panel__(self):
        intro = pn.pane.Markdown(
            "Every pair of stretches of the database that are the same motion again: repeated, left/right mirrored, "
            "at another rate, trimmed, time-scaled within *max scale* or on other bones, each at least *min length* "
            "long (mean DTW cost per step under the *threshold*, cm on the collection's median body; empty: learned "
            "from copies of the collection's own stretches). A cluster is the documents its pairs join; keep-one "
            "keeps its longest document.", sizing_mode="stretch_width")
        boxes = (self.min_length, self.threshold, self.max_scale)
        return pn.Column(intro, pn.Row(self.numeric_set, *boxes, self.mirrored, self.button), notes(*boxes),
                         pn.Column(self.task, css_classes=["mv-audit-task"], sizing_mode="stretch_width", margin=0),
                         self.summary, "### Pairs of copies", self.table,
                         pn.Row(self.pairs_download, self.kept_download), self.playing, self.player_box,
                         "### Clusters of copies", self.clusters, sizing_mode="stretch_width")

    async def first_answer(self) -> None:
        """The page's answer when it is first shown: the audit with the engine's defaults, as a job (Cancel stops
        it; an audit computed already by any session shows at once)."""
        await self._run()

    def _key(self) -> tuple:
        """The audit the widgets ask for: (numeric set, min length, threshold, max scale, mirrored)."""
        return (self.numeric_set.value, self.min_length.value, self.threshold.value, self.max_scale.value,
                self.mirrored.value)

    async def _run(self, event=None) -> None:
        key = self._key()
        found = await self.task.run("Auditing the database", self.backend.cached, ("audit", *key),
                                    lambda: run_audit(self.backend, *key), busy=self.button)
        if found is None:  # failed or cancelled: no answer of other settings stays under it
            self.pairs = self.kept = None
            clear(self.summary, self.table, self.clusters, self.player_box)
            return
        self.pairs, self.kept = found
        self._show(*found)

    def _show(self, pairs: pd.DataFrame, kept: pd.DataFrame) -> None:
        attrs = pairs.attrs
        how = "given" if attrs["threshold_how"] == "given" else f"learned: {attrs['threshold_how']}"
        self.summary.object = (
            f"**{plural(len(pairs), 'pair')}** of copies in {plural(pairs['cluster'].nunique(), 'cluster')}, "
            f"{int(pairs['mirrored'].sum())} mirrored, among {plural(len(self.backend.db), 'document')} (stretches "
            f"of at least {attrs['min_length']:g} s); threshold {attrs['threshold']:.2f} cm ({how}). Keep-one "
            f"leaves {plural(len(kept), 'document')}.")
        shown = pairs.assign(mirrored=np.where(pairs["mirrored"].astype(bool), MIRRORED, ""))
        self.table.param.update(selection=[], value=hit_columns(shown, PAIR_TITLES, PAIR_DECIMALS))
        self.clusters.value = cluster_table(pairs, kept)
        self.player_box.visible, self.playing.object = False, PLAY_HINT

    def _kept_documents(self) -> pd.DataFrame | None:
        return None if self.kept is None else self.kept[[c for c in KEPT_COLUMNS if c in self.kept]]

    def _on_select(self, event) -> None:
        if not event.new or self.pairs is None:
            return
        pair = self.pairs.iloc[event.new[0]]
        sides = [(int(pair[f"doc_{s}"]), str(pair[f"name_{s}"]), int(pair[f"start_{s}"]), int(pair[f"end_{s}"]))
                 for s in "ab"]  # fmt: skip
        clips = [query_clip(self.backend, doc, start, end) for doc, _, start, end in sides]
        mirrored = f" ({MIRRORED})" if pair["mirrored"] else ""
        titles = [f"A: document {sides[0][0]} {sides[0][1]}", f"B: document {sides[1][0]} {sides[1][1]}{mirrored}"]
        path = self.backend.engine.audit_path(pair, numeric_set=self.pairs.attrs["numeric_set"])
        self.player.load(clips, titles=titles, alignment=path,
                         fps=self.backend.fps_of(sides[0][0]) * len(path) / len(clips[0]))  # a in real time
        self.player_box.visible = True
        self.playing.object = (
            f"Playing document {sides[0][0]} ({sides[0][1]}) frames {sides[0][2]}:{sides[0][3]} beside document "
            f"{sides[1][0]} ({sides[1][1]}) frames {sides[1][2]}:{sides[1][3]}{mirrored}, aligned on the pair's warping "
            f"path ({plural(len(path), 'step')}).")
