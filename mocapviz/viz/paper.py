"""HoloViews plots that put a measured table beside the paper's: the figures of ``mocapviz reproduce``.

comparison_bars   grouped bars of one value per category, this run beside the paper (Müller 2005 Tables 2-3,
                  Krüger 2010 Tables 1-4), optionally on a log axis.
curves            one line per group over a numeric key (query time against query length, time against frames),
                  optionally log-log.

Both are pure functions from DataFrames to HoloViews objects that render with the bokeh backend (HTML) and the
matplotlib backend (PNG), so ``hv.save(obj, "x.png", backend="matplotlib")`` works on a headless machine.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import holoviews.plotting.mpl  # and the matplotlib one (the PNG files of `mocapviz reproduce`)
import numpy as np
import pandas as pd

from ..errors import ParameterError
from .palette import SERIES

__all__ = ["comparison_bars", "curves"]


def _check_columns(table: pd.DataFrame, columns, what: str) -> None:
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ParameterError(f"{what}: the table has no column(s) {missing}; it has {list(table.columns)}")


def log_floor(smallest: float) -> float:
    """The power of ten strictly below ``smallest`` (> 0): the lower end of a log axis on which the bar of
    ``smallest`` still shows.

    Parameters
    ----------
    smallest : float
        The smallest value drawn, > 0.

    Returns
    -------
    float

    Examples
    --------
    >>> [float(log_floor(v)) for v in (0.03, 1.0, 250)]
    [0.01, 0.1, 100.0]
    """
    low = 10.0 ** np.floor(np.log10(float(smallest)))
    return low / 10 if low >= smallest else low


def comparison_bars(table: pd.DataFrame, category: str, value: str, source: str = "source", title: str = "",
                    ylabel: str | None = None, logy: bool = False, width: int = 700,
                    height: int = 320) -> hv.Bars:  # fmt: skip
    """Bars of ``value`` per ``category``, one bar per ``source`` (e.g. "this run", "paper") side by side.

    Parameters
    ----------
    table : pandas.DataFrame
        Long format: one row per (category, source) with the value; rows with a missing value are left out.
    category, value, source : str
        Column names.
    title, ylabel : str
        The figure's title and the value axis's label (default ``value``).
    logy : bool
        Logarithmic value axis (times spanning orders of magnitude).
    width, height : int
        Pixels (bokeh).

    Returns
    -------
    hv.Bars
        x = category and source, y = ``value``.
    """
    _check_columns(table, [category, value, source], "comparison_bars")
    data = table[[category, source, value]].dropna(subset=[value]).copy()
    data[category] = data[category].astype(str)
    data[source] = data[source].astype(str)
    # a log axis needs a positive lower end: the power of ten below the smallest positive value; the bars rise from
    # it (HoloViews starts log-scale bars at the value dimension's lower range, 0.01 without one: a smaller value
    # would hang down from there)
    ylim = (log_floor(data.loc[data[value] > 0, value].min()), None) if logy and (data[value] > 0).any() \
        else (None, None)
    value_dim = hv.Dimension(value, label=ylabel or value, range=ylim)
    bars = hv.Bars(data, kdims=[category, source], vdims=[value_dim], label=title)
    bars = bars.opts(width=width, height=height, tools=["hover"], xrotation=45, logy=logy, ylim=ylim, title=title,
                     multi_level=False, color=source, cmap=list(SERIES), show_legend=True, backend="bokeh")  # fmt: skip
    return bars.opts(fig_size=200, aspect=2.5, xrotation=30, logy=logy, ylim=ylim, title=title, multi_level=False,
                     show_legend=True, legend_position="right", backend="matplotlib")  # fmt: skip


def curves(table: pd.DataFrame, x: str, y: str, group: str, title: str = "", xlabel: str | None = None,
           ylabel: str | None = None, logx: bool = False, logy: bool = False, markers: bool = True, width: int = 600,
           height: int = 320) -> hv.Overlay:  # fmt: skip
    """One line (with markers unless ``markers`` is false) per value of ``group``: ``y`` against ``x``.

    Parameters
    ----------
    table : pandas.DataFrame
        Long format, numeric ``x`` and ``y``; rows with a missing ``y`` are left out.
    x, y, group : str
        Column names.
    title, xlabel, ylabel : str
        The figure's title and the axes' labels (default the column names).
    logx, logy : bool
        Logarithmic axes.
    markers : bool
        A marker on every point (few points, e.g. query lengths); off for dense series such as frames.
    width, height : int
        Pixels (bokeh).

    Returns
    -------
    hv.Overlay
        An hv.Curve and an hv.Scatter per group.
    """
    _check_columns(table, [x, y, group], "curves")
    data = table.dropna(subset=[y]).sort_values(x)
    xd, yd = hv.Dimension(x, label=xlabel or x), hv.Dimension(y, label=ylabel or y)
    layers = []
    for name, part in data.groupby(group, sort=False):
        layers.append(hv.Curve(part, kdims=[xd], vdims=[yd], label=str(name)).opts(tools=["hover"], backend="bokeh"))
        if markers:
            layers.append(hv.Scatter(part, kdims=[xd], vdims=[yd], label=str(name)).opts(size=6, backend="bokeh"))
    overlay = hv.Overlay(layers).opts(width=width, height=height, logx=logx, logy=logy, title=title,
                                      legend_position="right", backend="bokeh")  # fmt: skip
    return overlay.opts(fig_size=200, aspect=2.5, logx=logx, logy=logy, title=title, legend_position="right",
                        backend="matplotlib")
