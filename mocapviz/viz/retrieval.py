"""HoloViews plots of the retrieval quality of the search methods (:func:`mocapviz.experiments.retrieval_quality`).

class_ap_bars        mean average precision per class, one bar per method side by side (leave-one-out or
                     leave-group-out).
pr_curves            mean interpolated precision at the 11 standard recall levels, one line per method (each its
                     own colour, dash and marker: methods of equal precision, dtw / exact / fast, lie on each
                     other), the legend beside the plot.
summary_bars         one measure of the summary table (mAP, P@1, recall of DTW's top 10, ms per query) per method.
retrieval_layout     the class bars and the curves of both protocols in one layout.

Pure functions from the experiment's DataFrames to HoloViews objects that render with the bokeh backend (HTML,
the dashboard) and with the matplotlib backend (the PNG files of ``mocapviz reproduce``).
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import holoviews.plotting.mpl  # and the matplotlib one (the PNG files of `mocapviz reproduce`)
import pandas as pd

from ..errors import ParameterError
from .palette import DASHES, MARKERS, MPL_DASHES, MPL_MARKERS, SERIES

__all__ = ["class_ap_bars", "pr_curves", "retrieval_layout", "summary_bars"]

PROTOCOLS = {"loo": "leave-one-out", "lgo": "leave-group-out"}
MEASURES = {"map_loo": "mAP, leave-one-out", "map_lgo": "mAP, leave-group-out", "p_at_1": "P@1", "p_at_10": "P@10",
            "recall_dtw_top10": "recall of DTW's top 10", "ms_per_query": "ms per query (K = 10)"}  # fmt: skip
LEGEND_WIDTH = 120  # pixels beside the P/R plot for its legend


def _protocol(protocol: str, table: pd.DataFrame) -> str:
    if protocol not in PROTOCOLS:
        raise ParameterError(f"protocol must be one of {', '.join(PROTOCOLS)}; got {protocol!r}")
    group = table.attrs.get("group_column")
    return f"leave-{group}-out" if protocol == "lgo" and group else PROTOCOLS[protocol]


def _check(table: pd.DataFrame, columns, what: str) -> None:
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ParameterError(f"{what}: the table has no column(s) {missing}; it has {list(table.columns)} (pass "
                             f"the DataFrames of retrieval_quality)")  # fmt: skip


def class_ap_bars(per_class: pd.DataFrame, protocol: str = "loo", title: str | None = None, width: int = 900,
                  height: int = 360) -> hv.Bars:  # fmt: skip
    """Mean AP per class, one bar per method side by side.

    Parameters
    ----------
    per_class : pandas.DataFrame
        ``retrieval_quality(...)["per_class"]`` (method, class, ap_loo, ap_lgo, ...).
    protocol : {"loo", "lgo"}
        Leave-one-out or leave-group-out AP.
    title : str, optional
        Default: "average precision per class (protocol)".
    width, height : int
        Pixels.

    Returns
    -------
    hv.Bars
        kdims class, method; vdim AP in [0, 1]; classes without a defined AP for a method have no bar.
    """
    name = _protocol(protocol, per_class)
    column = f"ap_{protocol}"
    _check(per_class, ["method", "class", column], "class_ap_bars")
    data = per_class[["class", "method", column]].dropna(subset=[column]).rename(columns={column: "AP"})
    data["class"], data["method"] = data["class"].astype(str), data["method"].astype(str)
    title = title or f"average precision per class ({name})"
    ap = hv.Dimension("AP", label=f"mean AP ({name})", range=(0, 1.02))
    bars = hv.Bars(data, kdims=["class", "method"], vdims=[ap])
    bars = bars.opts(width=width, height=height, tools=["hover"], xrotation=45, title=title, multi_level=False,
                     color="method", cmap=list(SERIES), show_legend=True, legend_position="right",
                     backend="bokeh")  # fmt: skip
    return bars.opts(fig_size=220, aspect=2.8, xrotation=35, title=title, multi_level=False, show_legend=True,
                     legend_position="right", backend="matplotlib")  # fmt: skip


def pr_curves(curves: pd.DataFrame, protocol: str = "loo", title: str | None = None, width: int = 560,
              height: int = 360) -> hv.Overlay:  # fmt: skip
    """Mean interpolated precision at the recall levels, one line (with markers) per method.

    Parameters
    ----------
    curves : pandas.DataFrame
        ``retrieval_quality(...)["curves"]`` (method, protocol, recall, precision).
    protocol : {"loo", "lgo"}
        Leave-one-out or leave-group-out.
    title : str, optional
        The figure's title.
    width, height : int
        Pixels.

    Returns
    -------
    hv.Overlay
        An hv.Curve and an hv.Scatter per method (x: recall 0..1, y: precision 0..1), method i in colour, dash and
        marker i of :mod:`mocapviz.viz.palette` (the markers shrink from one method to the next, so that those
        drawn on each other all show); the legend right of the plot (``width`` + :data:`LEGEND_WIDTH` pixels).
    """
    _check(curves, ["method", "protocol", "recall", "precision"], "pr_curves")
    name = _protocol(protocol, curves)
    data = curves[curves["protocol"] == protocol]
    x = hv.Dimension("recall", range=(-0.02, 1.02))
    y = hv.Dimension("precision", label="mean interpolated precision", range=(-0.02, 1.05))
    layers = []
    methods = list(dict.fromkeys(data["method"]))
    for i, (method, part) in enumerate(data.groupby("method", sort=False)):
        colour, dash, marker = SERIES[i % len(SERIES)], DASHES[i % len(DASHES)], MARKERS[i % len(MARKERS)]
        size = 6 + 3 * (len(methods) - 1 - i)  # the first drawn largest: a later one on it stays visible inside
        part = part[["recall", "precision"]]
        layers.append(hv.Curve(part, kdims=[x], vdims=[y], label=str(method))
                      .opts(color=colour, line_width=2, line_dash=dash, tools=["hover"], backend="bokeh")
                      .opts(color=colour, linewidth=2, linestyle=MPL_DASHES[dash], backend="matplotlib"))  # fmt: skip
        layers.append(hv.Scatter(part, kdims=[x], vdims=[y], label=str(method))
                      .opts(color=colour, size=size, marker=marker, fill_alpha=0.35, backend="bokeh")
                      .opts(color=colour, s=4 * size, marker=MPL_MARKERS[marker], backend="matplotlib"))
    if not layers:  # an empty protocol (no leave-group-out): an empty frame with the same axes
        layers = [hv.Curve([], kdims=[x], vdims=[y])]
    title = title or f"precision / recall ({name})"
    overlay = hv.Overlay(layers).opts(width=width + LEGEND_WIDTH, height=height, title=title, legend_position="right",
                                      show_grid=True, backend="bokeh")  # fmt: skip
    return overlay.opts(fig_size=200, aspect=1.5, title=title, legend_position="right", show_grid=True,
                        backend="matplotlib")


def summary_bars(summary: pd.DataFrame, measure: str = "map_loo", title: str | None = None, logy: bool = False,
                 width: int = 560, height: int = 320) -> hv.Bars:  # fmt: skip
    """One bar per method of a summary measure (:data:`MEASURES`: ``map_loo``, ``map_lgo``, ``p_at_1``,
    ``p_at_10``, ``recall_dtw_top10``, ``ms_per_query``).

    Parameters
    ----------
    summary : pandas.DataFrame
        :func:`~mocapviz.experiments.retrieval_quality`'s ``"summary"``, one row per method.
    measure : str
        The column drawn.
    title : str, optional
        Default: the measure's label.
    logy : bool
        A log y axis (for times).
    width, height : int
        Pixels.

    Returns
    -------
    hv.Bars
        x = method, y = the measure (fractions in [0, 1], or milliseconds).
    """
    if measure not in MEASURES:
        raise ParameterError(f"measure must be one of {', '.join(MEASURES)}; got {measure!r}")
    _check(summary, ["method", measure], "summary_bars")
    data = summary[["method", measure]].dropna(subset=[measure]).copy()
    data["method"] = data["method"].astype(str)
    label = MEASURES[measure]
    if measure == "map_lgo" and summary.attrs.get("group_column"):
        label = f"mAP, leave-{summary.attrs['group_column']}-out"
    span = (0, 1.02)
    if measure == "ms_per_query":  # a log axis needs a positive lower end: half the smallest time
        positive = data.loc[data[measure] > 0, measure]
        span = (float(positive.min()) / 2 if logy and len(positive) else 0, None)
    value = hv.Dimension(measure, label=label, range=span)
    title = title or label
    bars = hv.Bars(data, kdims=["method"], vdims=[value])
    bars = bars.opts(width=width, height=height, tools=["hover"], title=title, logy=logy, color="method",
                     cmap=list(SERIES), xrotation=30, backend="bokeh")  # fmt: skip
    return bars.opts(fig_size=160, aspect=1.8, title=title, logy=logy, xrotation=30, backend="matplotlib")


def retrieval_layout(result: dict, width: int = 900) -> hv.Layout:
    """The per-class AP bars and the P/R curves of a :func:`~mocapviz.experiments.retrieval_quality` result, one
    row per protocol: leave-one-out, and leave-group-out when the result has its figures.

    Parameters
    ----------
    result : dict
        :func:`~mocapviz.experiments.retrieval_quality`'s DataFrames by name.
    width : int
        Pixels of each row.

    Returns
    -------
    hv.Layout
    """
    per_class, curves = result["per_class"], result["curves"]
    protocols = ["loo"] + (["lgo"] if per_class["ap_lgo"].notna().any() else [])
    panels = []
    for p in protocols:  # one row per protocol: the class bars, then the curves
        panels += [class_ap_bars(per_class, p, width=width), pr_curves(curves, p, width=width // 2)]
    return hv.Layout(panels).cols(2)
