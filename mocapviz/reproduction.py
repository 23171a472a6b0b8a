"""``mocapviz reproduce``: run the papers' experiments on the shared real data and write tables and figures.

Each experiment of :mod:`mocapviz.experiments` (the table in docs/architecture.md) has a runner here that chooses its
database and settings, calls the experiment function and turns the result into named tables (pandas DataFrames,
written as CSV) and figures (HoloViews objects from :mod:`mocapviz.viz`, written as PNG with the matplotlib
backend and as self-contained HTML with the bokeh backend). A runner's name is the experiment function's name, but
``annotation``'s (:func:`mocapviz.experiments.annotation.simulated_annotation`) and ``audit``'s
(:func:`mocapviz.experiments.audit.audit_quality`).

Settings: without ``full`` every experiment runs in minutes on the shared HDM05 cut clips (287 clips, 70,996 frames at
120 Hz / 17,878 at 30 Hz), with fewer random queries where the paper uses thousands. With ``full`` the query counts
are the papers' and the "large" database is every shared archive (HDM05, CMU, Bandai Namco 1 and 2) at 30 Hz,
about 446k frames, ingested once per run.

Output: ``OUT/<name>/<table>.csv``, ``OUT/<name>/<figure>.png`` and ``.html``, and ``OUT/<name>/settings.json``
(the settings, the databases' sizes, seconds, package version). Each experiment's folder is written under a
temporary name and renamed into place when complete, so an interrupted run never leaves a half-written folder.
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .engine import MotionDB
from .errors import ParameterError
from .io import datasets
from .store import atomic_folder

__all__ = ["EXPERIMENTS", "Result", "reproduce", "write_result"]

_LARGE_ARCHIVES = ("hdm05-cut", "cmu-asfamc", "bandai-namco-1", "bandai-namco-2")


@dataclass
class Result:
    """What a runner gives back: tables (CSV) and HoloViews figures (PNG + HTML), by file stem.

    Parameters
    ----------
    tables : dict
        File stem -> pandas.DataFrame.
    figures : dict
        File stem -> HoloViews object.
    settings : dict
        What the runner was run with (JSON-serialisable), written as ``settings.json``.
    """

    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    figures: dict[str, object] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)


class _Data:
    """The databases of one reproduce run, ingested on first use into a temporary folder and shared by runners."""

    def __init__(self, folder: Path, full: bool, progress: bool):
        self.folder, self.full, self.progress = folder, full, progress
        self._dbs: dict[tuple, MotionDB] = {}
        self._indexes = None

    def _ingest(self, archives: tuple[str, ...], fps: float) -> MotionDB:
        key = (archives, fps)
        if key not in self._dbs:
            paths = [datasets.fetch(name) for name in archives]
            out = self.folder / f"{'+'.join(archives)}-{fps:g}hz.mdb"
            self._dbs[key] = MotionDB.ingest(paths, out, fps=fps, progress=self.progress)
        return self._dbs[key]

    def hdm05(self, fps: float) -> MotionDB:
        """The 287 labelled HDM05 cut clips at ``fps``."""
        return self._ingest(("hdm05-cut",), fps)

    def cmu(self, fps: float) -> MotionDB:
        """The 32 shared CMU trials at ``fps``."""
        return self._ingest(("cmu-asfamc",), fps)

    def large(self) -> MotionDB:
        """Every shared archive at 30 Hz with ``full``; else the HDM05 clips at 30 Hz."""
        return self._ingest(_LARGE_ARCHIVES, 30.0) if self.full else self.hdm05(30.0)

    def relational_indexes(self) -> dict:
        """Inverted indexes (2005 features) of the HDM05 clips at 120 Hz, built once."""
        if self._indexes is None:
            from .engine import Engine

            self._indexes = Engine(self.hdm05(120.0)).indexes("2005", progress=self.progress)
        return self._indexes

    @staticmethod
    def describe(db: MotionDB) -> dict:
        return {"path": db.path.name, "documents": len(db), "frames": db.n_frames, "fps": db.fps}


def _stacked(ours: pd.DataFrame, paper: pd.DataFrame, ours_name: str) -> pd.DataFrame:
    """Ours and the paper's rows in one long table with a ``source`` column."""
    return pd.concat([ours.assign(source=ours_name), paper.assign(source="paper")], ignore_index=True)


# ============================================================================================ the runners


def _index_statistics(data: _Data) -> Result:
    from .engine import index_statistics, mueller2005_table2
    from .viz.paper import comparison_bars

    db = data.hdm05(120.0)
    data.relational_indexes()
    ours = index_statistics(db, "2005")
    both = _stacked(ours, mueller2005_table2(), "HDM05 cut")
    both["segments per 100 frames"] = 100 * both["segments"] / both["frames"]
    both["case"] = both["group"] + " " + both["minutes"].round(0).astype(int).astype(str) + " min"
    return Result(
        tables={"table2": both},
        figures={"segments": comparison_bars(both, "case", "segments per 100 frames", title="Müller 2005 Table 2: "
                                             "segments per 100 frames"),
                 "bytes_per_segment": comparison_bars(both, "case", "bytes/segment", title="index bytes per segment")},
        settings={"database": data.describe(db)},
    )  # fmt: skip


def _query_statistics(data: _Data) -> Result:
    from .engine import mueller2005_table3, query_statistics
    from .viz.paper import curves

    n_queries = 10_000 if data.full else 300
    ours = query_statistics(data.relational_indexes()["upper"], n_queries=n_queries)
    both = _stacked(ours, mueller2005_table3(), "HDM05 cut")
    both["series"] = both["source"] + ", " + both["mode"] + ", " + both["hits"] + " hits"
    return Result(
        tables={"table3": both},
        figures={"query_times": curves(both, "L", "mean_ms", "series", title="Müller 2005 Table 3: mean query time",
                                       xlabel="query length L (segments)", ylabel="ms", logy=True)},
        settings={"n_queries": n_queries, "database": data.describe(data.hdm05(120.0))},
    )  # fmt: skip


def _relational_query(data: _Data) -> Result:
    from .engine import relational_query
    from .viz.paper import comparison_bars

    db = data.hdm05(120.0)
    table = relational_query(db, indexes=data.relational_indexes())
    long = table.melt(id_vars=["class"], value_vars=["precision", "recall"], var_name="source", value_name="value")
    return Result(
        tables={"queries": table},
        figures={"precision_recall": comparison_bars(long, "class", "value", title="query by example per class "
                                                     "(Müller 2005 Figs. 7-9)", ylabel="precision / recall")},
        settings={"database": data.describe(db)},
    )  # fmt: skip


def _alignment(data: _Data) -> Result:
    from .engine import alignment
    from .viz import alignment_layout

    db = data.hdm05(120.0)
    docs = db.documents.set_index("doc_id")
    jog = docs.index[docs["label"] == "jogLeftCircle4StepsRstart"]
    a = int(jog[0])
    b = int(next(d for d in jog if docs.loc[d, "actor"] != docs.loc[a, "actor"]))
    features = ["rfoot_behind", "lfoot_behind"]
    res = alignment(db, a, b, features=features, margin=4)
    summary = res["summary"].assign(clip_a=docs.loc[a, "name"], clip_b=docs.loc[b, "name"])
    paths = pd.DataFrame({"frame_a": res["path_full"][:, 0], "frame_b_full": res["path_full"][:, 1]})
    return Result(
        tables={"summary": summary, "path_full": paths,
                "path_band": pd.DataFrame(res["path_band"], columns=["frame_a", "frame_b"])},
        figures={"alignment": alignment_layout(res)},
        settings={"features": features, "margin": 4, "database": data.describe(db)},
    )  # fmt: skip


def _knn_timings(data: _Data) -> Result:
    from .engine import knn_timings, krueger2010_table1
    from .viz.paper import comparison_bars

    db = data.large()
    ours = knn_timings(db, n_queries=1000, threads=1, database="this run")
    both = _stacked(ours, krueger2010_table1(), "this run")
    both["source"] = both["source"].where(both["source"] != "paper", "paper " + both["database"])
    figures = {f"knn{k}": comparison_bars(both[both["k"] == k], "set", "mean_ms", logy=True, ylabel="ms per query",
                                          title=f"Krüger 2010 Table 1: exact {k}-NN, one thread")
               for k in (16, 256)}  # fmt: skip
    return Result(tables={"table1": both}, figures=figures, settings={"database": data.describe(db), "threads": 1})


def _rank_correlations(data: _Data) -> Result:
    from .engine import paper_claims, rank_correlations
    from .viz.correlation import correlation_heatmap

    db = data.hdm05(30.0)
    large = data.large()
    n_queries, k = (1024, 256) if data.full else (256, 256)
    res = rank_correlations(db, large_db=large, n_queries=n_queries, k=k, progress=data.progress)
    titles = {"pose": "pose-based, sample database", "pose_large": f"pose-based, {large.n_frames:,} frames",
              "segment": "segment-based (DTW), sample database"}
    return Result(
        tables={**res, "paper_claims": paper_claims(res)},
        figures={name: correlation_heatmap(res[name], title=f"Krüger 2010 Fig. 2: {title}")
                 for name, title in titles.items()},
        settings={"n_queries": n_queries, "k": k, "database": data.describe(db), "large": data.describe(large)},
    )  # fmt: skip


def _similarity_matrices(data: _Data) -> Result:
    from .engine import similarity_matrices
    from .viz import similarity_layout

    db = data.hdm05(30.0)
    jog = db.select(label="jogLeftCircle4StepsRstart")["doc_id"].astype(int).tolist()
    res = similarity_matrices(db, jog[0], k=64, n_matches=3)
    panels = [k for k, v in res.items() if isinstance(v, dict) and "matches" in v]
    matches = pd.concat([res[p]["matches"].drop(columns="path").assign(set=p) for p in panels], ignore_index=True)
    return Result(tables={"matches": matches}, figures={"fig3": similarity_layout(res)},
                  settings={"query_doc": jog[0], "k": 64, "database": data.describe(db)})  # fmt: skip


def _lng_accuracy(data: _Data) -> Result:
    from .engine import PAPER_SECONDS, PAPER_SPEARMAN, lng_accuracy, summarize_accuracy
    from .viz import accuracy_plot

    db = data.large()
    n_queries, k = (128, 256) if data.full else (16, 1024)
    per_query = lng_accuracy(db, "Fp16", n_queries=n_queries, k=k, progress=data.progress)
    return Result(tables={"per_query": per_query, "summary": summarize_accuracy(per_query)},
                  figures={"accuracy": accuracy_plot(per_query, PAPER_SECONDS, PAPER_SPEARMAN)},
                  settings={"n_queries": n_queries, "k": k, "numeric_set": "Fp16", "database": data.describe(db)})


def _numerical_search(data: _Data) -> Result:
    from .engine import krueger2010_table2, numerical_search
    from .viz.paper import comparison_bars

    db = data.hdm05(30.0)
    ours = numerical_search(db)
    long = ours.melt(id_vars=["class", "set"], value_vars=["recall", "logical_recall"], var_name="search")
    long["case"] = long["class"] + " " + long["search"]
    return Result(tables={"table2": ours, "paper_table2": krueger2010_table2()},
                  figures={"recall": comparison_bars(long, "case", "value", source="set", ylabel="recall",
                                                     title="Krüger 2010 Table 2: recall per class and numeric set")},
                  settings={"database": data.describe(db)})  # fmt: skip


def _reconstruction(data: _Data) -> Result:
    from .engine import krueger2010_table3, krueger2010_table4, marker_comparison, marker_reconstruction, reconstruction
    from .viz.reconstruction import reconstruction_figures

    db, other = data.hdm05(30.0), data.cmu(30.0)
    res = reconstruction(db, other_db=other, full=data.full, progress=data.progress)
    paper3, paper4 = krueger2010_table3(), krueger2010_table4()
    # §5.2 from REAL markers: the C3D takes with an AMC of the same take (CMU 135_02), the CMU takes as the prior
    real = marker_reconstruction(prior_db=other)
    return Result(tables={**res, "paper_table3": paper3, "paper_table4": paper4, "real_markers": real,
                          "marker_model": marker_comparison()},
                  figures=reconstruction_figures(res, paper3, paper4),
                  settings={"database": data.describe(db), "other_database": data.describe(other),
                            "real_markers": "C3D takes of c3d-markers with an AMC in cmu-asfamc; joints estimated "
                                            "from their marker clusters, aligned to the AMC in time and on the floor"})


def _base_poses(data: _Data) -> Result:
    from .engine import Engine, base_pose_experiment
    from .viz.paper import curves

    db = data.large()
    table = base_pose_experiment(Engine(db).numeric("F15E"), radius=10.0, k=32, quadratic_frames=5000)
    return Result(tables={"base_poses": table},
                  figures={"scaling": curves(table, "frames", "seconds", "method", logx=True, logy=True,
                                             title="Krüger 2010 §5.3: base poses, r = 10 cm, k = 32")},
                  settings={"radius_cm": 10.0, "k": 32, "database": data.describe(db)})  # fmt: skip


def _retrieval_quality(data: _Data) -> Result:
    from .engine import retrieval_quality
    from .viz.retrieval import class_ap_bars, pr_curves, summary_bars

    runs = {"hdm05": (data.hdm05(30.0), "label", None)}  # the HDM05 clips: class, leave-actor-out
    if data.full:  # Bandai Namco 1 (one actor): content with leave-style-out, style with leave-content-out
        bandai = data._ingest(("bandai-namco-1",), 30.0)
        runs["bandai_content"] = (bandai, "label", "style")
        runs["bandai_style"] = (bandai, "style", "label")
    tables, figures, settings = {}, {}, {}
    for name, (db, label, group) in runs.items():
        res = retrieval_quality(db, label_column=label, group_column=group, progress=data.progress)
        where = f"{name.replace('_', ' ')}: {label}"
        for table, frame in res.items():
            tables[f"{name}_{table}"] = frame
        for protocol in ("loo", "lgo"):
            if res["per_class"][f"ap_{protocol}"].notna().any():
                figures[f"{name}_class_ap_{protocol}"] = class_ap_bars(res["per_class"], protocol,
                                                                      title=f"{where}: AP per class ({protocol})")
                figures[f"{name}_pr_{protocol}"] = pr_curves(res["curves"], protocol,
                                                             title=f"{where}: precision / recall ({protocol})")
        figures[f"{name}_map"] = summary_bars(res["summary"], "map_loo", title=f"{where}: mAP, leave-one-out")
        figures[f"{name}_ms"] = summary_bars(res["summary"], "ms_per_query", logy=True,
                                             title=f"{where}: ms per query (K = 10)")
        settings[name] = {"database": data.describe(db), **res["summary"].attrs}
    return Result(tables=tables, figures=figures, settings=settings)


def _template_quality(data: _Data) -> Result:
    from .engine import template_quality
    from .viz.retrieval import class_ap_bars

    # HDM05: templates of four actors searched in the fifth's clips; Bandai Namco 1 (one actor, 15 styles of every
    # content): content templates of the other styles searched in one style's clips
    runs = {"hdm05": (data.hdm05(30.0), "actor"), "bandai_content": (data._ingest(("bandai-namco-1",), 30.0), "style")}
    tables, figures, settings = {}, {}, {}
    for name, (db, group) in runs.items():
        res = template_quality(db, group=group, progress=data.progress)
        for table, frame in res.items():
            tables[f"{name}_{table}"] = frame
        bars = res["per_class"].rename(columns={"ap_group": "ap_lgo"}).assign(method="template")
        bars.attrs["group_column"] = group
        figures[f"{name}_class_ap"] = class_ap_bars(bars, "lgo", title=f"{name.replace('_', ' ')}: motion "
                                                    f"templates, AP per class (leave-{group}-out)")  # fmt: skip
        settings[name] = {"database": data.describe(db), "group": group, "relational_set": "2006"}
    return Result(tables=tables, figures=figures, settings=settings)


def _descriptions(data: _Data) -> Result:
    import holoviews as hv
    import holoviews.plotting.bokeh  # registers the backends the figure's options are checked against
    import holoviews.plotting.mpl

    from .engine import (
        clip_quality,
        cmu_sequence_quality,
        composite_quality,
        event_quality,
        read_annotations,
    )

    # the shipped descriptions (2005 words) on labelled cut clips: HDM05 at 120 Hz, Bandai Namco 1 at its 30 Hz
    tables, settings = {}, {}
    quality = []
    runs = {"hdm05": (data.hdm05(120.0), data.relational_indexes()),
            "bandai1": (data._ingest(("bandai-namco-1",), 30.0), None)}  # fmt: skip
    for name, (db, indexes) in runs.items():
        res = clip_quality(db, indexes=indexes)
        quality.append(res["per_description"].assign(dataset=name))
        tables[f"{name}_fire_rates"] = res["fire_rates"]
        tables[f"{name}_fired"] = res["fired"]
        settings[name] = {"database": data.describe(db)}
    clips = pd.concat(quality, ignore_index=True)
    tables["clips"] = clips
    # the CMU martial-arts takes against the hand annotation kept with the tests (a checkout only)
    annotation = Path(__file__).resolve().parent.parent / "tests" / "data" / "cmu135_kicks_punches.csv"
    if annotation.is_file():
        cmu = data.cmu(120.0)
        events = event_quality(cmu, read_annotations(annotation, cmu))
        tables["cmu_events"] = events["summary"]
        tables["cmu_hits"] = events["hits"].drop(columns=["parts"], errors="ignore")
        settings["cmu"] = {"database": data.describe(cmu), "annotation": str(annotation)}
        # the annotated takes hold no kick followed by a punch: derived streams (the annotated kicks and punches cut
        # from their takes with 0.75 s of their own motion, concatenated kick-punch, punch-kick and alone, with
        # fillers from the takes without events) give "kick then punch" a frame-exact truth
        sequences = cmu_sequence_quality(cmu, read_annotations(annotation, cmu))
        tables["cmu_sequences"] = sequences["summary"]
        tables["cmu_sequences_per_kind"] = sequences["per_kind"]
        tables["cmu_sequences_parts"] = sequences["parts"]
        tables["cmu_sequences_hits"] = sequences["hits"].drop(columns=["parts"], errors="ignore")
        settings["cmu_sequences"] = {"derived": "cut and concatenated CMU 135 takes (not recordings)",
                                     "margin_s": 0.75, "filler_s": 2.5, "blend_s": 0.1, "within_s": 2.0,
                                     "streams": int(sequences["summary"]["streams"].iloc[0])}  # fmt: skip
    else:
        settings["cmu"] = f"skipped: {annotation} not found (it is kept with the tests of a checkout)"
    # composite streams of HDM05 clips at 30 Hz (derived documents), templates learned without the stream's actor
    hdm30 = data.hdm05(30.0)
    sweep = []
    for cost in (None, 0.06, 0.08, 0.1, 0.15):  # None: each template's learned threshold
        res = composite_quality(hdm30, template_cost=cost)
        sweep.append(res["summary"])
        if cost is None:
            tables["composite_per_pair"] = res["per_pair"].assign(template_cost="learned")
            tables["composite_per_stream"] = res["per_stream"].assign(template_cost="learned")
            tables["composite_parts"] = res["parts"]
    tables["composite_sweep"] = pd.concat(sweep, ignore_index=True)
    settings["composite"] = {"database": data.describe(hdm30), "within_s": 2.0, "blend_s": 0.1,
                             "derived": "streams of concatenated HDM05 cut clips"}  # fmt: skip
    # the figure: precision and recall of every description that has a labelled class
    judged = clips.dropna(subset=["recall"])
    long = pd.concat([judged.assign(measure=m, value=judged[m].fillna(0.0)) for m in ("precision", "recall")])
    long["description"] = long["description"] + " (" + long["dataset"] + ")"
    title = "shipped scene descriptions on labelled cut clips: precision and recall"
    bars = hv.Bars(long, ["description", "measure"], hv.Dimension("value", range=(0, 1.02)))
    bars = bars.opts(title=title, xrotation=60, width=1000, height=420, backend="bokeh")
    bars = bars.opts(title=title, xrotation=60, aspect=3, fig_size=350, backend="matplotlib")
    return Result(tables=tables, figures={"precision_recall": bars}, settings=settings)


def _annotation(data: _Data) -> Result:
    from .engine import Engine, simulated_annotation

    # HDM05 cut at 30 Hz: every actor hidden in turn (about 35 s each); Bandai Namco 1 at 30 Hz: the style
    # "normal" (the only one holding all 16 contents: its 21 clips are the 11 of the 10 contents every style has,
    # and 10 of contents no other style has, which no template is learned for), with full every style in turn
    hdm05, bandai = data.hdm05(30.0), data._ingest(("bandai-namco-1",), 30.0)
    styles = sorted(bandai.documents["style"].unique()) if data.full else ["normal"]
    runs = {"hdm05": (hdm05, "actor", sorted(hdm05.documents["actor"].unique())), "bandai": (bandai, "style", styles)}
    tables, figures, settings = {}, {}, {}
    for name, (db, group, hidden) in runs.items():
        parts = [simulated_annotation(db, h, Engine, data.folder / "annotation" / f"{name}-{h}", group=group)
                 for h in hidden]  # fmt: skip
        for table in parts[0]:
            tables[f"{name}_{table}"] = pd.concat([p[table] for p in parts], ignore_index=True)
        for part, h in zip(parts, hidden):
            figures[f"{name}_{h}"] = _annotation_curves(part["curves"], f"{name}, {group} {h} hidden: the loop "
                                                        "(solid, one by one) against document order (dashed)")
        settings[name] = {"database": data.describe(db), "group": group, "hidden": list(map(str, hidden)),
                          "page": 20, "target": 0.9, "max_examples": 16}  # fmt: skip
    return Result(tables=tables, figures=figures, settings=settings)


def _annotation_curves(table: pd.DataFrame, title: str):
    """Hits reviewed against the share of the class's hidden clips labelled, a colour per class: the loop reviewing
    one by one (solid, in the legend) and the document order (dashed)."""
    import holoviews as hv
    import holoviews.plotting.bokeh  # registers the backends the options are checked against
    import holoviews.plotting.mpl
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    layers = []
    for i, (label, part) in enumerate(table.groupby("class", sort=False)):
        colour = to_hex(colormaps["tab20"](i % 20))
        for method, dash in (("loop, one by one", "solid"), ("document order", "dashed")):
            rows = part[part["method"] == method]
            line = hv.Curve(rows, hv.Dimension("reviewed", label="hits reviewed"),
                            hv.Dimension("share", label="hidden clips labelled (share)", range=(0, 1.02)),
                            label=label if dash == "solid" else "")  # fmt: skip
            line = line.opts(color=colour, line_dash=dash, line_width=2, backend="bokeh")
            layers.append(line.opts(color=colour, linestyle=dash, linewidth=1.5, backend="matplotlib"))
    overlay = hv.Overlay(layers).opts(width=900, height=420, title=title, legend_position="right", backend="bokeh")
    return overlay.opts(fig_size=250, aspect=2.2, title=title, legend_position="right", fontsize={"title": 9},
                        backend="matplotlib")


def _audit(data: _Data) -> Result:
    from .engine import Engine, audit_quality
    from .viz.paper import comparison_bars

    # copies of real clips planted in the large database (the HDM05 cut clips at 30 Hz; every shared archive with
    # full), audited with the learned threshold
    db = data.large()
    n_per_kind = 20 if data.full else 5
    table = audit_quality(db, data.folder / "audit" / "planted.mdb", Engine, n_per_kind=n_per_kind,
                          progress=data.progress)  # fmt: skip
    attrs = table.attrs
    bars = comparison_bars(table.assign(source=db.path.name), "kind", "recall", title="audit: recall of planted "
                           f"copies per kind (threshold {attrs['threshold']:.2f} cm)", ylabel="recall")  # fmt: skip
    settings = {"database": data.describe(db), "n_per_kind": n_per_kind, "seed": 0, "threshold": attrs["threshold"],
                "threshold_how": attrs["threshold_how"], "audit_seconds": attrs["seconds"],
                "pairs": len(attrs["pairs"]), "derived": "planted copies of real clips (mirrored, stretched, trimmed, "
                "noisy, retargeted, resampled, all together)"}  # fmt: skip
    return Result(tables={"quality": table, "copies": attrs["copies"], "pairs": attrs["pairs"]},
                  figures={"recall": bars}, settings=settings)  # fmt: skip


EXPERIMENTS: dict[str, Callable[[_Data], Result]] = {
    "index_statistics": _index_statistics,
    "query_statistics": _query_statistics,
    "relational_query": _relational_query,
    "alignment": _alignment,
    "knn_timings": _knn_timings,
    "rank_correlations": _rank_correlations,
    "similarity_matrices": _similarity_matrices,
    "lng_accuracy": _lng_accuracy,
    "numerical_search": _numerical_search,
    "reconstruction": _reconstruction,
    "base_poses": _base_poses,
    "retrieval_quality": _retrieval_quality,
    "template_quality": _template_quality,
    "descriptions": _descriptions,
    "annotation": _annotation,
    "audit": _audit,
}


# ============================================================================================== writing


def _write_csv(frame: pd.DataFrame, path: Path) -> None:
    """A table as CSV; a meaningful index (e.g. a correlation matrix's measure names) becomes the first column."""
    keep_index = not isinstance(frame.index, pd.RangeIndex) or frame.index.name is not None
    arrays = [c for c in frame.columns if frame[c].dtype == object and frame[c].map(lambda v: isinstance(v, np.ndarray)).any()]
    frame = frame.drop(columns=arrays)
    frame.to_csv(path, index=keep_index)


def write_result(result: Result, folder) -> list[Path]:
    """Write a runner's tables (CSV), figures (PNG via matplotlib, HTML via bokeh) and settings into ``folder``.

    Columns holding arrays (warping paths) are left out of the CSV files.

    Parameters
    ----------
    result : Result
        A runner's output.
    folder : str or os.PathLike
        The experiment's output folder (created).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    import holoviews as hv

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, frame in result.tables.items():
        _write_csv(frame, folder / f"{name}.csv")
        written.append(folder / f"{name}.csv")
    for name, figure in result.figures.items():
        hv.save(figure, folder / f"{name}.png", backend="matplotlib")
        hv.save(figure, folder / f"{name}.html", backend="bokeh", title=name)
        written += [folder / f"{name}.png", folder / f"{name}.html"]
    (folder / "settings.json").write_text(json.dumps(result.settings, indent=2, default=str))
    return written + [folder / "settings.json"]


def reproduce(names, out, full: bool = False, progress: bool = True, log: Callable[[str], None] = print) -> dict:
    """Run experiments and write each one's tables and figures to ``out/<name>/``.

    Parameters
    ----------
    names : str or sequence of str
        Experiment function names (keys of :data:`EXPERIMENTS`) or ``"all"``.
    out : str or os.PathLike
        Output folder (created).
    full : bool
        The papers' sizes (thousands of queries, every shared archive as the large database) instead of minutes.
    progress : bool
        Progress bars of the long steps.
    log : callable
        Receives one line per finished experiment.

    Returns
    -------
    dict
        Experiment name -> its output folder (pathlib.Path).

    Raises
    ------
    ValueError
        An unknown experiment name (the known ones are listed).
    """
    names = list(EXPERIMENTS) if names in ("all", ["all"]) else [names] if isinstance(names, str) else list(names)
    unknown = [n for n in names if n not in EXPERIMENTS]
    if unknown:
        raise ParameterError(f"unknown experiment(s) {unknown}; known: all, {', '.join(EXPERIMENTS)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from ._version import __version__

    folders = {}
    with tempfile.TemporaryDirectory(prefix="mocapviz-reproduce-") as work:
        data = _Data(Path(work), full, progress)
        for name in names:
            t0 = time.perf_counter()
            result = EXPERIMENTS[name](data)
            result.settings = {"experiment": name, "full": full, "seconds": round(time.perf_counter() - t0, 2),
                               "mocapviz": __version__, **result.settings}  # fmt: skip
            with atomic_folder(out / name) as tmp:
                files = write_result(result, tmp)
            folders[name] = out / name
            log(f"{name}: {len(files)} files in {out / name} ({result.settings['seconds']:.0f} s)")
    return folders
