"""HoloViews plots of the rank-correlation experiments (:mod:`mocapviz.experiments.correlation`).

correlation_heatmap   Krüger, Tautges, Weber & Zinke 2010, Fig. 2: the (asymmetric) matrix of mean Spearman rank
                      correlations, neighbours chosen by the row measure, compared with the column measure, the value
                      printed in every cell.

A pure function: a matrix in, a HoloViews object out, with options for the bokeh backend (notebooks, the dashboard)
and for the matplotlib backend (``hv.save(obj, "fig2.png", backend="matplotlib")``). Cells sit on an integer grid
(column j at x = j, row i at y = i, the y axis inverted so that row 0 is on top) with the measure names as ticks:
matplotlib cannot put text on a heat map's categorical axes, and this way both backends draw the same picture.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import holoviews.plotting.mpl  # registers the matplotlib backend (PNG output) and its options
import numpy as np
import pandas as pd
from bokeh.models import CustomJSHover

from ..errors import ParameterError

ROWS = "neighbours by"
COLUMNS = "compared with"
DIVERGING = "RdBu_r"  # values of both signs: blue below 0, white 0, red above, symmetric about 0
SEQUENTIAL = "Blues"  # values of one sign: light at the smallest, dark at the largest
WHITE_TEXT_FROM = 0.6  # the share of the colour scale from which a cell is dark: its value printed in white
VALUE_FONT_PT = (6, 14)  # the values' font size grows with the cell between these
VALUE_CHARS = 5  # "-0.12": the widest value printed


def value_font(cell: int) -> int | None:
    """The font size (points) of the values printed in cells of ``cell`` pixels: the largest within
    :data:`VALUE_FONT_PT` whose values fit the cell (:data:`VALUE_CHARS` characters of about 0.62 em, 2 pixels of
    margin on each side); None when even the smallest would not.

    Parameters
    ----------
    cell : int
        The cell's width, pixels.

    Returns
    -------
    int or None
        Points.

    Examples
    --------
    >>> value_font(40), value_font(5)
    (8, None)
    """
    font = min(int((cell - 4) / (VALUE_CHARS * 0.62 * 4 / 3)), VALUE_FONT_PT[1])
    return font if font >= VALUE_FONT_PT[0] else None


def colour_scale(values) -> tuple[str, tuple[float, float]]:
    """The colour map and its range for a heat map of ``values``, fitted to them: values of both signs on a
    diverging map symmetric about 0 (to the largest |value|), values of one sign on a sequential map from their
    least to their greatest (a matrix of 0.8..1.0 then spans the whole scale instead of a sliver of -1..1).

    Parameters
    ----------
    values : array_like
        The values (NaN ignored).

    Returns
    -------
    (str, (float, float))
        The colour map's name and (low, high).

    Examples
    --------
    >>> colour_scale([0.81, 0.9, 1.0]), colour_scale([-0.2, 0.5])
    (('Blues', (0.81, 1.0)), ('RdBu_r', (-0.5, 0.5)))
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
    if lo < 0 < hi:
        most = max(-lo, hi)
        return DIVERGING, (-most, most)
    if lo == hi:  # one value: a range around it
        lo, hi = lo - 0.5, hi + 0.5
    return SEQUENTIAL, (lo, hi)


def _dark(v: np.ndarray, cmap: str, clim: tuple[float, float]) -> np.ndarray:
    """Cells drawn dark by ``cmap`` over ``clim`` (their values printed in white)."""
    lo, hi = clim
    if cmap == DIVERGING:
        return np.abs(np.nan_to_num(v)) >= WHITE_TEXT_FROM * hi
    return np.nan_to_num((v - lo) / (hi - lo)) >= WHITE_TEXT_FROM


def _names(names: list[str]) -> CustomJSHover:
    """A bokeh hover formatter showing the name at an integer grid position."""
    return CustomJSHover(code="return names[Math.round(value)]", args={"names": names})


def correlation_heatmap(matrix: pd.DataFrame, title: str = "", cell: int = 46) -> hv.Overlay:
    """Krüger et al. 2010, Fig. 2: a rank-correlation matrix as a heat map with its values.

    Parameters
    ----------
    matrix : pd.DataFrame [shape=(R, C)]
        Mean Spearman's rho in [-1, 1] (NaN allowed: an empty cell): rows = the measure the neighbours were chosen
        by, columns = the measure they are compared with (:func:`mocapviz.experiments.correlation.pose_correlations`,
        ``segment_correlations``). Not symmetric in general, and drawn as it is.
    title : str
        The figure's title.
    cell : int
        Size of one cell in screen pixels (bokeh); the matplotlib figure is scaled alike (80 pixels per inch). The
        values' font grows with it (:func:`value_font`); in cells too small for them, hovering shows the values.

    Returns
    -------
    hv.Overlay
        Of

        - an hv.HeatMap: x = column position 0..C-1, ticks the column names left to right in the matrix's order
          (axis label "compared with"); y = row position 0..R-1, ticks the row names top to bottom in the
          matrix's order ("neighbours by"); colour = rho on a scale fitted to the matrix (:func:`colour_scale`:
          light to dark blue from its least to its greatest value, or blue-white-red about 0 when it holds both
          signs), the colour bar showing that range. Bokeh: hover shows the row and column names and rho;
        - two hv.Labels with the values to 2 decimals, centred in their cells: black, and white on dark cells;
          left out when the cells are too small to hold them.

    Raises
    ------
    ValueError
        An empty matrix or non-numeric values.
    """
    if matrix.empty:
        raise ParameterError("the correlation matrix is empty")
    values = matrix.to_numpy()
    if values.dtype.kind not in "fiu":
        raise ParameterError(f"the correlation matrix must hold numbers; got dtype {values.dtype}")
    rows, cols = [str(r) for r in matrix.index], [str(c) for c in matrix.columns]
    x, y = np.tile(np.arange(len(cols)), len(rows)), np.repeat(np.arange(len(rows)), len(cols))
    v = values.astype(np.float64).ravel()
    kdims = [hv.Dimension("x", label=COLUMNS), hv.Dimension("y", label=ROWS)]
    heat = hv.HeatMap((x, y, v), kdims=kdims, vdims=[hv.Dimension("rho", label="ρ")])
    text = np.array(["" if np.isnan(a) else f"{a:.2f}" for a in v], dtype=object)
    cmap, clim = colour_scale(v)
    dark = _dark(v, cmap, clim)  # white text on dark cells
    font = value_font(cell)
    labels = [hv.Labels((x[on], y[on], text[on]), kdims=kdims, vdims=["text"]).opts(
        text_font_size=f"{font}pt", text_color=ink, backend="bokeh").opts(size=font, color=ink, backend="matplotlib")
        for on, ink in ((~dark, "black"), (dark, "white"))] if font else []  # fmt: skip
    width, height = cell * len(cols) + 170, cell * len(rows) + 120
    common = {"cmap": cmap, "clim": clim, "colorbar": True, "xticks": list(enumerate(cols)),
              "yticks": list(enumerate(rows)), "invert_yaxis": True, "xrotation": 45}  # fmt: skip
    heat = heat.opts(
        tools=["hover"], hover_tooltips=[(ROWS, "@{y}{custom}"), (COLUMNS, "@{x}{custom}"), ("ρ", "@{rho}{0.000}")],
        hover_formatters={"@{y}": _names(rows), "@{x}": _names(cols)}, padding=0, backend="bokeh", **common,
    ).opts(show_values=False, backend="matplotlib", **common)  # fmt: skip
    return hv.Overlay([heat, *labels]).opts(title=title, width=width, height=height, backend="bokeh").opts(
        title=title, fig_inches=width / 80, aspect=len(cols) / len(rows), padding=0, backend="matplotlib")  # fmt: skip
