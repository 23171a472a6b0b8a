"""HoloViews plots of the global motion matching experiments (:mod:`mocapviz.experiments.matching`).

similarity_layout   Krüger, Tautges, Weber & Zinke 2010, Fig. 3: per feature set the distance matrix of a query
                    against a small database, the cells the lazy neighbourhood graph never computed in flat blue,
                    its match paths in red; the Dpc panel computed in full by subsequence DTW.
alignment_layout    Müller, Röder & Clausen 2005 §7, Fig. 11: the local cost matrix of two clips, the band of the
                    matched relational segments (grey), the full and the band-restricted DTW paths.
accuracy_plot       Krüger et al. 2010 §4.2: the graph against subsequence DTW per query length and eps (Spearman,
                    equal costs, recall, same best match) and the times of both.

Every builder is a pure function: experiment output in, a HoloViews object (bokeh backend options) out. Show it in
a notebook after ``hv.extension("bokeh")``, or turn it into a bokeh figure with ``hv.render(obj, backend="bokeh")``.
Matrices are drawn with the second sequence (database or clip b) on the x axis and the first (query or clip a) on
the y axis, frame 0 at the bottom; a cell (i, j) is centred on x = j, y = i.
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options
import holoviews.plotting.mpl  # and the matplotlib one (the PNG files of `mocapviz reproduce`)
import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..validation import plural
from .palette import SERIES

NOT_COMPUTED = "#2b5fd9"  # Fig. 3's blue: cells the graph did not have to compute
PATH_COLOUR = "red"
BAND_PATH_COLOUR = "#00b7eb"
BOUNDARY_COLOUR = "orange"
MEASURES = {"spearman": "Spearman ρ", "equal": "equal cost", "recall": "recall", "same_best": "same best match"}
TIMES = {"knn_s": "kNN", "graph_s": "graph", "dtw_s": "subsequence DTW"}
PAPER_METHOD = "paper: graph (Fp16)"


def _panels(result: dict) -> list[str]:
    """The names of the result's matrix panels (feature sets, then Dpc), in the result's order."""
    return [k for k, v in result.items() if isinstance(v, dict) and {"distance", "computed", "matches"} <= set(v)]


def _path_xy(paths) -> list[np.ndarray]:
    """(L, 2) (row frame, column frame) paths -> float (L, 2) (x = column, y = row) arrays for hv.Path."""
    return [np.asarray(p, dtype=np.float64)[:, ::-1] for p in paths if p is not None and len(p)]


def _image(matrix: np.ndarray, x: hv.Dimension, y: hv.Dimension, value: hv.Dimension) -> hv.Image:
    m, n = matrix.shape
    return hv.Image((np.arange(n), np.arange(m), matrix), kdims=[x, y], vdims=[value])


def similarity_layout(result: dict, cols: int = 3, width: int = 380, height: int = 260) -> hv.Layout:
    """Krüger et al. 2010, Fig. 3: similarity matrices of a query against a small database, with warping paths.

    Parameters
    ----------
    result : dict
        :func:`mocapviz.experiments.matching.similarity_matrices`'s output: ``"query"`` ({doc, frames}),
        ``"database_docs"`` (B document ids), ``"database_starts"`` ((B,) int, first frame of each document in the
        small database's frame numbers) and per feature set and ``"Dpc<n>"`` a dict of ``"distance"`` ((m, n)
        float local costs: Euclidean in cm for the numeric sets, cm² for Dpc), ``"computed"`` ((m, n) bool, the
        kNN cells the graph visited) and ``"matches"`` (DataFrame with a ``path`` column of (L, 2) int (query
        frame, small-database frame) arrays).
    cols : int
        Panels per row.
    width, height : int
        Pixels per panel.

    Returns
    -------
    hv.Layout
        One panel per feature set and the Dpc panel, in the result's order. Each panel is an hv.Overlay labelled
        with the set's name of

        - an hv.Image (x: small-database frame 0..n-1, y: query frame 0..m-1) of the distances of the computed
          cells in grey, darker = more similar (its own colour range per panel); cells not computed are NaN and
          drawn in flat blue (``clipping_colors``), as in the paper: "blue regions do not have to be computed";
        - hv.VLines at the document boundaries of the small database (x = start - 0.5);
        - an hv.Path in red, one sub-path per match: x = database frame, y = query frame.

        The title gives the set and the share of cells computed.
    """
    names = _panels(result)
    if not names:
        raise ParameterError("no panels: the result holds no dict with 'distance', 'computed' and 'matches'")
    starts = np.asarray(result.get("database_starts", [0]), dtype=np.int64)
    docs = result.get("database_docs")
    x = hv.Dimension("database_frame", label="small database frame" + (f" (documents {', '.join(map(str, docs))})"
                                                                       if docs is not None else ""))  # fmt: skip
    y = hv.Dimension("query_frame", label="query frame" + (f" (document {result['query']['doc']})"
                                                           if "query" in result else ""))  # fmt: skip
    panels = []
    for name in names:
        part = result[name]
        dist = np.asarray(part["distance"], dtype=np.float64)
        computed = np.asarray(part["computed"], dtype=bool)
        if computed.shape != dist.shape:
            raise ParameterError(f"{name}: 'computed' has shape {computed.shape}, 'distance' {dist.shape}")
        unit = "cm²" if name.startswith("Dpc") else "cm"
        value = hv.Dimension(f"distance_{name}", label=f"{name} distance", unit=unit)
        image = _image(np.where(computed, dist, np.nan), x, y, value).opts(
            cmap="gray", clipping_colors={"NaN": NOT_COMPUTED}, colorbar=True, tools=["hover"], axiswise=True,
            backend="bokeh").opts(cmap="gray", clipping_colors={"NaN": NOT_COMPUTED}, colorbar=True,
                                  backend="matplotlib")  # fmt: skip
        boundaries = hv.VLines(starts[1:] - 0.5, kdims=[x]).opts(color=BOUNDARY_COLOUR, line_width=1.5,
                                                                  line_dash="dashed", backend="bokeh").opts(
            color=BOUNDARY_COLOUR, linewidth=1.5, linestyle="dashed", backend="matplotlib")  # fmt: skip
        paths = hv.Path(_path_xy(part["matches"]["path"]), kdims=[x, y]).opts(color=PATH_COLOUR, line_width=2.5,
                                                                              backend="bokeh").opts(
            color=PATH_COLOUR, linewidth=2, backend="matplotlib")  # fmt: skip
        share = computed.mean()
        how = "subsequence DTW" if name.startswith("Dpc") else "LNG"
        title = f"{name} ({how}): {share:.1%} of cells computed, {plural(len(part['matches']), 'match', 'matches')}"
        panels.append(hv.Overlay([image, boundaries, paths], label=name).opts(
            title=title, width=width, height=height, backend="bokeh"))  # fmt: skip
    return hv.Layout(panels).cols(cols)


def band_polygon(band) -> np.ndarray:
    """The outline (V, 2) of a band's cells as (x = frame of b, y = frame of a) vertices: up the lower bounds,
    down the upper bounds, cell (i, j) being the unit square centred on (j, i). Its area (shoelace) is the
    number of band cells, sum(hi - lo).

    Parameters
    ----------
    band : np.ndarray [shape=(m, 2)], int
        Per frame i of a the [lo, hi) frames of b (non-decreasing bounds).

    Returns
    -------
    np.ndarray [shape=(V, 2)], float64
        The vertices (x, y), in frames.

    Examples
    --------
    >>> polygon_area(band_polygon(np.array([[0, 2], [1, 3]])))  # 2 + 2 cells
    4.0
    """
    band = np.asarray(band, dtype=np.float64)
    m = len(band)
    rows = np.arange(m, dtype=np.float64)
    up = np.column_stack([np.repeat(band[:, 0] - 0.5, 2), np.column_stack([rows - 0.5, rows + 0.5]).ravel()])
    down = np.column_stack([np.repeat(band[::-1, 1] - 0.5, 2),
                            np.column_stack([rows[::-1] + 0.5, rows[::-1] - 0.5]).ravel()])  # fmt: skip
    return np.vstack([up, down])


def polygon_area(vertices) -> float:
    """The area of a simple (or staircase) polygon by the shoelace formula.

    Parameters
    ----------
    vertices : np.ndarray [shape=(V, 2)]
        The outline, in order.

    Returns
    -------
    float
        In the squared units of the vertices.
    """
    x, y = np.asarray(vertices, dtype=np.float64).T
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)


def alignment_layout(result: dict, width: int = 430, height: int = 400) -> hv.Layout:
    """Müller, Röder & Clausen 2005 §7, Fig. 11: segment-restricted DTW of two logically similar clips.

    Parameters
    ----------
    result : dict
        :func:`mocapviz.experiments.matching.alignment`'s output: ``"cost"`` ((m, n) float Euclidean local costs
        of the numeric features, cm; m frames of clip a, n of clip b), ``"band"`` ((m, 2) int [lo, hi) frames of b
        per frame of a), ``"path_full"`` and ``"path_band"`` ((L, 2) int (frame of a, frame of b)),
        ``"segments_a"`` / ``"segments_b"`` (FeatureSequence: ``starts``, ``lengths``), ``"segment_path"``
        ((P, 2) matched segment pairs) and ``"summary"`` (one-row DataFrame).
    width, height : int
        Pixels per panel.

    Returns
    -------
    hv.Layout
        Two panels (x: frame of b, y: frame of a, frame 0 at the bottom):

        - ``cost``: the local cost matrix in grey (darker = lower cost), the segment boundaries of both clips as
          thin lines (hv.HLines for a, hv.VLines for b), the full DTW path (red) and the band DTW path (dashed
          cyan);
        - ``band``: the rectangles of the matched segment pairs (hv.Rectangles, light grey), the band they span,
          enlarged by the margin (hv.Polygons outline of :func:`band_polygon`, grey: only these cells are
          computed), the segment boundaries and both paths.
    """
    cost = np.asarray(result["cost"], dtype=np.float64)
    m, n = cost.shape
    band = np.asarray(result["band"])
    if band.shape != (m, 2):
        raise ParameterError(f"band has shape {band.shape}; the cost matrix {cost.shape} needs ({m}, 2)")
    summary = result["summary"].iloc[0] if "summary" in result else None
    seg_a, seg_b = result["segments_a"], result["segments_b"]
    doc_a = f" (document {summary['doc_a']})" if summary is not None else ""
    doc_b = f" (document {summary['doc_b']})" if summary is not None else ""
    x = hv.Dimension("frame_b", label=f"frame of clip b{doc_b}")
    y = hv.Dimension("frame_a", label=f"frame of clip a{doc_a}")

    def lines():
        style = {"color": BOUNDARY_COLOUR, "line_width": 0.8, "alpha": 0.7, "backend": "bokeh"}
        mpl = {"color": BOUNDARY_COLOUR, "linewidth": 0.6, "alpha": 0.7, "backend": "matplotlib"}
        return [hv.HLines(np.asarray(seg_a.starts[1:], np.float64) - 0.5, kdims=[y]).opts(**style).opts(**mpl),
                hv.VLines(np.asarray(seg_b.starts[1:], np.float64) - 0.5, kdims=[x]).opts(**style).opts(**mpl)]

    def paths():
        full = hv.Curve(_path_xy([result["path_full"]])[0] if len(result["path_full"]) else [], x, y,
                        label="full DTW").opts(color=PATH_COLOUR, line_width=2.5, backend="bokeh").opts(
            color=PATH_COLOUR, linewidth=2, backend="matplotlib")  # fmt: skip
        inside = hv.Curve(_path_xy([result["path_band"]])[0] if len(result["path_band"]) else [], x, y,
                          label="band DTW").opts(color=BAND_PATH_COLOUR, line_width=2, line_dash="dashed",
                                                 backend="bokeh").opts(
            color=BAND_PATH_COLOUR, linewidth=1.5, linestyle="dashed", backend="matplotlib")  # fmt: skip
        return [full, inside]

    image = _image(cost, x, y, hv.Dimension("cost", label="local cost", unit="cm")).opts(
        cmap="gray", colorbar=True, tools=["hover"], backend="bokeh").opts(cmap="gray", colorbar=True,
                                                                           backend="matplotlib")  # fmt: skip
    pairs = np.asarray(result["segment_path"], dtype=np.int64).reshape(-1, 2)
    a0 = np.asarray(seg_a.starts)[pairs[:, 0]] - 0.5
    b0 = np.asarray(seg_b.starts)[pairs[:, 1]] - 0.5
    rects = hv.Rectangles((b0, a0, b0 + np.asarray(seg_b.lengths)[pairs[:, 1]],
                           a0 + np.asarray(seg_a.lengths)[pairs[:, 0]]), kdims=[x, y, "x1", "y1"],
                          label="matched segments").opts(fill_color="#d9d9d9", line_color="#bdbdbd",
                                                         backend="bokeh").opts(
        facecolor="#d9d9d9", edgecolor="#bdbdbd", backend="matplotlib")  # fmt: skip
    area = hv.Polygons([band_polygon(band)], kdims=[x, y], label="band").opts(
        fill_color="grey", fill_alpha=0.45, line_color="dimgrey", backend="bokeh").opts(
        facecolor="grey", alpha=0.45, edgecolor="dimgrey", backend="matplotlib")  # fmt: skip
    cells = int((np.clip(band[:, 1], 0, n) - np.clip(band[:, 0], 0, n)).sum())
    if summary is not None:
        t_cost = (f"local costs; full DTW {summary['cost_full']:.0f}, band DTW {summary['cost_band']:.0f}"
                  f"{' (same path)' if summary['same_path'] else ''}")  # fmt: skip
    else:
        t_cost = "local costs"
    t_band = f"band: {cells:,} of {m * n:,} cells ({cells / (m * n):.0%}), {len(pairs)} segment pairs"
    common = {"width": width, "height": height, "xlim": (-0.5, n - 0.5), "ylim": (-0.5, m - 0.5),
              "legend_position": "top_left", "backend": "bokeh"}  # fmt: skip
    left = hv.Overlay([image, *lines(), *paths()], label="cost").opts(title=t_cost, **common)
    right = hv.Overlay([rects, area, *lines(), *paths()], label="band").opts(title=t_band, **common)
    return hv.Layout([left, right]).cols(2)


def _setting(seconds, eps) -> str:
    return f"{seconds:g} s, ε={eps:g}"


def accuracy_table(per_query: pd.DataFrame) -> pd.DataFrame:
    """:func:`mocapviz.experiments.matching.lng_accuracy`'s rows as the long table :func:`accuracy_plot` draws:
    one row per (setting, measure) with the mean over the queries where the measure is defined (``queries``);
    Spearman is NaN for queries where the graph found fewer than 3 matches, and those are left out.

    Parameters
    ----------
    per_query : pandas.DataFrame
        :func:`mocapviz.experiments.matching.lng_accuracy`'s rows.

    Returns
    -------
    pandas.DataFrame
        One row per (setting, measure): the mean and the number of queries it is defined for.
    """
    rows = []
    for (sec, eps), g in per_query.groupby(["seconds", "eps"], sort=True):
        for col, label in MEASURES.items():
            values = g[col].astype(float).dropna()
            rows.append({"setting": _setting(sec, eps), "measure": label, "mean": float(values.mean())
                         if len(values) else np.nan, "queries": len(values)})  # fmt: skip
    return pd.DataFrame(rows)


def accuracy_plot(per_query: pd.DataFrame, paper_seconds: dict | None = None, paper_spearman: float | None = 0.99,
                  width: int = 900, height: int = 330) -> hv.Layout:  # fmt: skip
    """Krüger et al. 2010 §4.2: the lazy neighbourhood graph against subsequence DTW on random queries.

    Parameters
    ----------
    per_query : pd.DataFrame
        :func:`mocapviz.experiments.matching.lng_accuracy`'s output, one row per (seconds, eps, query) with
        ``spearman``, ``equal``, ``recall``, ``same_best`` (shares in [0, 1]; Spearman NaN when the graph found
        fewer than 3 matches) and ``knn_s``, ``graph_s``, ``dtw_s`` (seconds).
    paper_seconds : dict, optional
        {query seconds: the paper's alignment time in s} (``experiments.matching.PAPER_SECONDS``: 0.03 s for 1 s
        queries, 0.08 s for 3 s, Fp16, kNN excluded), drawn as a fourth bar per setting.
    paper_spearman : float, optional
        The paper's rank correlation (> 0.99), a dashed horizontal line.
    width, height : int
        Pixels per panel.

    Returns
    -------
    hv.Layout
        Two panels:

        - ``quality``: hv.Bars of the mean Spearman ρ, equal-cost share, recall and same-best share per setting
          ("<seconds> s, ε=<eps>"), grouped by measure (:func:`accuracy_table`; hover shows the queries counted);
        - ``time``: hv.Bars of the mean kNN, graph and subsequence DTW seconds per query for each setting (log y).
    """
    need = {"seconds", "eps", *MEASURES, *TIMES}
    missing = need - set(per_query.columns)
    if missing:
        raise ParameterError(f"per_query lacks columns {sorted(missing)}; pass lng_accuracy's output")
    table = accuracy_table(per_query)
    setting = hv.Dimension("setting", label="query length, ε")
    measure = hv.Dimension("measure", values=list(MEASURES.values()))
    quality = hv.Bars(table, kdims=[setting, measure], vdims=[hv.Dimension("mean", label="mean over queries",
                                                                           range=(0, 1.05)), "queries"])  # fmt: skip
    quality = quality.opts(tools=["hover"], xrotation=45, multi_level=True, color="measure", cmap=list(SERIES),
                           backend="bokeh")  # fmt: skip
    layers = [quality]
    if paper_spearman is not None:
        layers.append(hv.HLine(paper_spearman).opts(color="black", line_dash="dashed", line_width=1,
                                                    backend="bokeh"))  # fmt: skip
    title = "LNG vs subsequence DTW" + (f" (dashed: paper's ρ {paper_spearman:g})" if paper_spearman else "")
    left = hv.Overlay(layers, label="quality").opts(title=title, width=width, height=height, backend="bokeh")
    rows = []
    for (sec, eps), g in per_query.groupby(["seconds", "eps"], sort=True):
        for col, label in TIMES.items():
            rows.append({"setting": _setting(sec, eps), "method": label, "seconds": float(g[col].mean())})
        if paper_seconds and sec in paper_seconds:
            rows.append({"setting": _setting(sec, eps), "method": PAPER_METHOD,
                         "seconds": float(paper_seconds[sec])})  # fmt: skip
    times = pd.DataFrame(rows)
    positive = times["seconds"][times["seconds"] > 0]
    bottom = 10 ** np.floor(np.log10(positive.min())) if len(positive) else 1e-4
    method = hv.Dimension("method", values=[*TIMES.values(), PAPER_METHOD])
    times = hv.Bars(times, kdims=[setting, method], vdims=[hv.Dimension("seconds", unit="s")])
    right = times.relabel(label="time").opts(logy=True, ylim=(bottom, None), tools=["hover"], multi_level=True,
                                             xrotation=45, color="method", cmap=list(SERIES),
                                             title="mean time per query", width=width, height=height,
                                             backend="bokeh")  # fmt: skip
    return hv.Layout([left, right]).cols(1)
