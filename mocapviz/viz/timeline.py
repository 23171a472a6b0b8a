"""A clip's features over time: the dashboard's Database page and the query pages.

relational_timeline   Müller, Röder & Clausen 2005 §3-4: one row per boolean feature, its runs of 1 drawn as bars
                      coloured by feature group (lower / upper / mix: :data:`mocapviz.viz.palette.PARTS`), the segment boundaries of the whole feature
                      vector (§4, the F-segmentation of :func:`mocapviz.features.segmentation.segment`) as thin lines, an optional highlighted span.
numeric_curves        Krüger, Tautges, Weber & Zinke 2010 §3.2: the coordinates of a numeric feature set (e.g. F15E,
                      cm in the body frame) against time, one colour per joint and one dash per axis.
runs                  (feature, start, stop) runs of 1 of a boolean (T, f) array.

Both builders return HoloViews objects with bokeh options; x is time in seconds.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh
import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..features.segmentation import segment
from .palette import DASHES, PARTS, SERIES, series_style

LEGEND_ROW = 17  # pixels per legend entry of numeric_curves (9 pt labels, no spacing)
LEGEND_MARGIN = 80  # pixels of a bokeh figure's height outside its plot area: title, x axis, legend padding
LEGEND_COLUMNS = 3  # at most; more entries make the figure taller instead


def runs(values: np.ndarray) -> pd.DataFrame:
    """The runs of 1 of every column of a boolean array.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        E.g. a clip's relational features.

    Returns
    -------
    pandas.DataFrame
        ``feature`` (column number), ``start``, ``stop`` (frames, stop exclusive), by feature then start.

    Examples
    --------
    >>> runs(np.array([[1, 0], [1, 1], [0, 1], [1, 0]], dtype=bool)).values.tolist()
    [[0, 0, 2], [0, 3, 4], [1, 1, 3]]
    """
    values = np.asarray(values, dtype=bool)
    if values.ndim != 2:
        raise ParameterError(f"values must be (T, f) booleans; got shape {values.shape}")
    padded = np.zeros((values.shape[0] + 2, values.shape[1]), dtype=np.int8)
    padded[1:-1] = values
    edges = np.diff(padded, axis=0)
    feature, start = np.nonzero(edges.T == 1)  # row-major: by feature, then frame; rises and falls pair up
    stop = np.nonzero(edges.T == -1)[1]
    return pd.DataFrame({"feature": feature, "start": start, "stop": stop})


def relational_timeline(values: np.ndarray, names, fps: float, groups: dict | None = None, span=None,
                        width: int = 900, row_height: int = 14, segments: bool = True) -> hv.Overlay:
    """Boolean feature timelines of one clip.

    Parameters
    ----------
    values : np.ndarray [shape=(T, f)], bool
        The clip's relational features (:func:`mocapviz.features.relational_features`).
    names : list of str
        The f feature names (rows, top to bottom).
    fps : float
        Frames per second (x is in seconds).
    groups : dict, optional
        Group -> list of names (:func:`mocapviz.features.feature_groups`), for the colours; default one colour.
    span : (int, int), optional
        (first, last) frames, shaded (the query span).
    width : int
        Pixels.
    row_height : int
        Pixels per feature row.
    segments : bool
        Draw the segment boundaries of the whole feature vector.

    Returns
    -------
    holoviews.Overlay
        Rectangles (the runs; hover shows feature and times), the boundaries and the span.
    """
    values = np.asarray(values, dtype=bool)
    names = list(names)
    if values.ndim != 2 or values.shape[1] != len(names):
        raise ParameterError(f"values {values.shape} do not match {len(names)} feature names")
    if fps <= 0:
        raise ParameterError(f"fps must be positive, got {fps}")
    group_of = {n: g for g, members in (groups or {}).items() for n in members}
    r = runs(values)
    f = len(names)
    row = f - 1 - r["feature"].to_numpy()  # first feature on top
    table = pd.DataFrame({
        "x0": r["start"] / fps, "y0": row - 0.4, "x1": r["stop"] / fps, "y1": row + 0.4,
        "feature": [names[i] for i in r["feature"]],
        "group": [group_of.get(names[i], "feature") for i in r["feature"]],
        "from_s": r["start"] / fps, "to_s": r["stop"] / fps,
    })
    table["colour"] = [PARTS.get(g, "#555555") for g in table["group"]]
    duration = values.shape[0] / fps
    ticks = [(f - 1 - i, n) for i, n in enumerate(names)]
    rects = hv.Rectangles(table, kdims=["x0", "y0", "x1", "y1"], vdims=["feature", "group", "from_s", "to_s",
                                                                        "colour"])
    rects = rects.opts(color="colour", line_color=None, tools=["hover"], width=width, height=max(120, row_height * f
                       + 60), yticks=ticks, xlabel="time (s)", ylabel="", xlim=(0, duration), ylim=(-0.6, f - 0.4),
                       show_grid=False, toolbar="above")
    layers = [rects]
    if segments:
        bounds = segment(values).starts[1:] / fps
        layers.append(hv.VLines(bounds).opts(color="#bbbbbb", line_width=0.5))
    if span is not None:
        a, b = span
        layers.append(hv.VSpan(a / fps, (b + 1) / fps).opts(color="orange", alpha=0.2))
    return hv.Overlay(layers).opts(title=f"{f} relational features, {len(segment(values).starts)} segments")


def numeric_curves(values: np.ndarray, columns, fps: float, title: str = "", width: int = 900,
                   height: int = 260, span=None) -> hv.Overlay:
    """Numeric feature coordinates of one clip against time.

    Parameters
    ----------
    values : np.ndarray [shape=(T, d)], float
        The clip's numeric features (cm for the end-effector sets).
    columns : list of str
        The d coordinate names (:func:`mocapviz.features.numeric_columns`).
    fps : float
        Frames per second (x is in seconds).
    title : str
        The figure's title.
    width, height : int
        Pixels.
    span : (int, int), optional
        (first, last) frames, shaded.

    Returns
    -------
    holoviews.Overlay
        One Curve per coordinate (legend clickable to hide), x in seconds. The legend stays beside the plot area:
        in as many columns (at most three) as its entries need to fit the plot's height, the figure made taller
        than ``height`` when three are not enough.
    """
    values = np.asarray(values, dtype=np.float64)
    columns = list(columns)
    if values.ndim != 2 or values.shape[1] != len(columns):
        raise ParameterError(f"values {values.shape} do not match {len(columns)} column names")
    if fps <= 0:
        raise ParameterError(f"fps must be positive, got {fps}")
    t = np.arange(values.shape[0]) / fps
    curves = [hv.Curve((t, values[:, j]), "time (s)", hv.Dimension("value", label="feature value"), label=c).opts(
        color=colour, line_dash=dash, alpha=alpha) for j, (c, (colour, dash, alpha)) in
        enumerate(zip(columns, coordinate_styles(columns)))]  # fmt: skip
    if span is not None:
        curves.append(hv.VSpan(span[0] / fps, (span[1] + 1) / fps).opts(color="orange", alpha=0.2))
    cols, height = legend_layout(len(columns), height)
    return hv.Overlay(curves).opts({
        "Curve": {"line_width": 1, "tools": ["hover"]},
        "Overlay": {"width": width, "height": height, "title": title, "legend_position": "right", "show_legend": True,
                    "legend_cols": cols, "click_policy": "hide",
                    "legend_opts": {"label_text_font_size": "9pt", "label_height": 12, "glyph_height": 12,
                                    "spacing": 0, "padding": 4, "margin": 4}},
    }, backend="bokeh")


def coordinate_styles(columns) -> list[tuple[str, str, float]]:
    """(colour, dash, alpha) of each coordinate of a numeric set, all different: a joint's colour, an axis's dash
    (x solid, y dashed, z dotted), the samples of a window (``lwrist.x@-0.150s``) each fainter than its centre;
    columns without joint and axis (``pc1``) one after another (:func:`mocapviz.viz.palette.series_style`).

    Parameters
    ----------
    columns : list of str
        :func:`mocapviz.features.numeric_columns`.

    Returns
    -------
    list of (str, str, float)

    Examples
    --------
    >>> coordinate_styles(["lwrist.x", "lwrist.y", "rwrist.x"])
    [('#ff7f0e', 'solid', 1.0), ('#ff7f0e', 'dashed', 1.0), ('#2ca02c', 'solid', 1.0)]
    """
    names = [str(c).split("@")[0] for c in columns]
    if not all(n.count(".") == 1 for n in names):
        return [(*series_style(i), 1.0) for i in range(len(columns))]
    joints = list(dict.fromkeys(n.split(".")[0] for n in names))
    axes = list(dict.fromkeys(n.split(".")[1] for n in names))
    offsets = [str(c).partition("@")[2] for c in columns]
    others = [o for o in dict.fromkeys(offsets) if o.strip("+-0.s")]  # the samples off the window's centre
    alpha = {o: 0.3 + 0.45 * i / max(1, len(others) - 1) for i, o in enumerate(others)}
    return [(SERIES[joints.index(n.split(".")[0]) % len(SERIES)], DASHES[axes.index(n.split(".")[1]) % len(DASHES)],
             alpha.get(o, 1.0)) for n, o in zip(names, offsets)]  # fmt: skip


def legend_layout(entries: int, height: int) -> tuple[int, int]:
    """(legend columns, figure height) so that a legend of ``entries`` beside a figure of ``height`` pixels stays
    within its plot area: more columns, up to :data:`LEGEND_COLUMNS`, then a taller figure.

    Parameters
    ----------
    entries : int
        Legend entries.
    height : int
        The figure's height, pixels.

    Returns
    -------
    columns : int
        Legend columns.
    height : int
        The figure's height, pixels (at least the one given).

    Examples
    --------
    >>> legend_layout(3, 300)
    (1, 300)
    """
    rows = max(1, (height - LEGEND_MARGIN) // LEGEND_ROW)
    cols = -(-entries // rows)
    if cols <= LEGEND_COLUMNS:
        return max(cols, 1), height
    return LEGEND_COLUMNS, LEGEND_MARGIN + LEGEND_ROW * -(-entries // LEGEND_COLUMNS)
