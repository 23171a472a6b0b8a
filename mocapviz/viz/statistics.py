"""HoloViews plots of the index statistics (:mod:`mocapviz.experiments.relational`): query time against hits.

query_time_scatter   Müller, Röder & Clausen 2005, §6.2 / Table 3: every random query as a point (hit count, query
                     time), one colour per query mode (exact, adaptive fuzzy), with the median time per hit count as
                     a line: how the time of an inverted-list query grows with the number of hits it returns.

A pure function from the per-query table of :func:`mocapviz.experiments.relational.query_statistics`
(``per_query=True``) to a HoloViews overlay with options for the bokeh and the matplotlib backends.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import holoviews.plotting.mpl  # registers the matplotlib backend (PNG output) and its options
import pandas as pd

from ..errors import ParameterError
from .palette import SERIES

__all__ = ["median_times", "query_time_scatter"]

_COLUMNS = ("mode", "L", "hits", "ms")


def median_times(per_query: pd.DataFrame) -> pd.DataFrame:
    """The median query time per (mode, hit count).

    Parameters
    ----------
    per_query : pandas.DataFrame
        :func:`mocapviz.experiments.relational.query_statistics` with ``per_query=True``.

    Returns
    -------
    pandas.DataFrame
        Columns ``mode``, ``hits`` (int), ``ms`` (float, milliseconds), sorted by mode (first appearance) and hits.
    """
    modes = list(dict.fromkeys(per_query["mode"]))
    out = per_query.groupby(["mode", "hits"], sort=True)["ms"].median().reset_index()
    out["order"] = out["mode"].map(modes.index)
    return out.sort_values(["order", "hits"]).drop(columns="order").reset_index(drop=True)


def query_time_scatter(per_query: pd.DataFrame, title: str = "", width: int = 620, height: int = 340) -> hv.Overlay:
    """Query time against hit count of random relational queries (Müller et al. 2005, §6.2, Table 3).

    Parameters
    ----------
    per_query : pd.DataFrame [shape=(Q, ...)]
        One row per query: ``mode`` ("exact" / "fuzzy"), ``L`` (query length in segments), ``hits`` (int >= 1) and
        ``ms`` (float > 0, milliseconds), as :func:`query_statistics` returns with ``per_query=True``.
    title : str
    width, height : int
        Size in screen pixels (bokeh); the matplotlib figure keeps the aspect.

    Returns
    -------
    hv.Overlay of, per mode in order of first appearance, an hv.Scatter of its queries (x = hits, y = ms, hover
    shows L) and an hv.Curve of :func:`median_times` of that mode, in one colour; both axes logarithmic.

    Raises
    ------
    ValueError
        A missing column, or no queries.
    """
    missing = [c for c in _COLUMNS if c not in per_query.columns]
    if missing:
        raise ParameterError(f"query_time_scatter: the table has no column(s) {missing}; it has {list(per_query.columns)}")
    if per_query.empty:
        raise ParameterError("query_time_scatter: no queries to plot")
    data = per_query[list(_COLUMNS)].astype({"hits": int, "ms": float})
    medians = median_times(data)
    x, y = hv.Dimension("hits", label="hits"), hv.Dimension("ms", label="query time (ms)")
    layers = []
    for i, (mode, part) in enumerate(data.groupby("mode", sort=False)):
        colour = SERIES[i % len(SERIES)]
        layers.append(hv.Scatter(part, kdims=[x], vdims=[y, "L"], label=str(mode)).opts(
            color=colour, size=5, alpha=0.5, tools=["hover"], backend="bokeh").opts(
            color=colour, s=12, alpha=0.5, backend="matplotlib"))  # fmt: skip
        layers.append(hv.Curve(medians[medians["mode"] == mode], kdims=[x], vdims=[y], label=f"{mode}, median").opts(
            color=colour, line_width=2, backend="bokeh").opts(color=colour, linewidth=2, backend="matplotlib"))  # fmt: skip
    overlay = hv.Overlay(layers).opts(width=width, height=height, logx=True, logy=True, title=title,
                                      legend_position="right", backend="bokeh")  # fmt: skip
    return overlay.opts(fig_inches=width / 80, aspect=width / height, logx=True, logy=True, title=title,
                        legend_position="right", backend="matplotlib")
