"""mocapviz.viz on real experiment outputs: the HoloViews layouts hold exactly the data of the results they draw
(cells not computed by the lazy neighbourhood graph, match paths, the alignment band) and render with bokeh.

Data: the HDM05 cut clips of the shared data at 30 Hz; the query of Fig. 3 and its small database are clips of
``jogLeftCircle4StepsRstart`` (a left-turning jog), the aligned pair two other clips of that class.
"""

from __future__ import annotations

import holoviews as hv
import numpy as np
import pandas as pd
import pytest
from bokeh.models import LinearColorMapper

from mocapviz import MotionDB
from mocapviz.experiments.matching import PAPER_SECONDS, alignment, lng_accuracy, similarity_matrices
from mocapviz.viz import accuracy_plot, accuracy_table, alignment_layout, band_polygon, similarity_layout
from mocapviz.viz.matching import MEASURES, NOT_COMPUTED, polygon_area

JOG = "jogLeftCircle4StepsRstart"
SETS = ("F15E", "F15x3E")
LOWER = ["rfoot_behind", "lfoot_behind", "rfoot_raised", "lfoot_raised"]


@pytest.fixture(scope="module")
def db(hdm05_dir, tmp_path_factory):
    return MotionDB.ingest([hdm05_dir], tmp_path_factory.mktemp("viz") / "db", fps=30, progress=False)


@pytest.fixture(scope="module")
def jog(db) -> list[int]:
    return sorted(int(d) for d in db.select(label=JOG)["doc_id"])


@pytest.fixture(scope="module")
def similarity(db, jog) -> dict:
    return similarity_matrices(db, jog[0], numeric_sets=SETS, k=32)


@pytest.fixture(scope="module")
def aligned(db, jog) -> dict:
    return alignment(db, jog[0], jog[2], features=LOWER, repeats=1)


@pytest.fixture(scope="module")
def accuracy(db) -> pd.DataFrame:
    return lng_accuracy(db, n_queries=3, seconds=(1.0,), k=128, eps=(0.0, 0.5))


def _figures(layout) -> dict:
    """Render a layout with bokeh -> {title text: bokeh figure}."""
    grid = hv.render(layout, backend="bokeh")
    return {fig.title.text: fig for fig, _, _ in grid.children}


# ============================================================================ Fig. 3
def test_similarity_layout_panels_mask_and_paths(similarity):
    layout = similarity_layout(similarity)
    panels = layout.values()
    assert [p.label for p in panels] == [*SETS, "Dpc1"]  # one panel per set + Dpc
    for panel in panels:
        part = similarity[panel.label]
        dist, computed = part["distance"], part["computed"]
        m, n = dist.shape
        image = panel.get(0)
        assert isinstance(image, hv.Image)
        z = image.dimension_values(2, flat=False)
        assert z.shape == (m, n)
        # blue (NaN) cells are exactly those the graph did not compute; the grey ones are the distances
        assert np.isnan(z).sum() == (~computed).sum()
        np.testing.assert_array_equal(np.isnan(z), ~computed)
        np.testing.assert_allclose(z[computed], dist[computed])
        i, j = np.argwhere(computed)[len(np.argwhere(computed)) // 2]
        assert image[float(j), float(i)] == pytest.approx(dist[i, j])  # x = database frame, y = query frame
        # document boundaries of the small database
        lines = panel.get(1)
        np.testing.assert_array_equal(lines.dimension_values(0), similarity["database_starts"][1:] - 0.5)
        # the red overlay holds the match paths, (query, frame) -> (x = frame, y = query)
        path = panel.get(2)
        drawn = path.split()
        assert len(drawn) == len(part["matches"]) > 0
        for sub, p in zip(drawn, part["matches"]["path"]):
            np.testing.assert_array_equal(sub.array(), p[:, ::-1])
        assert path.opts.get().kwargs["color"] == "red"
        share = f"{computed.mean():.1%} of cells computed"
        assert share in panel.opts.get().kwargs["title"]
    assert np.isnan(panels[-1].get(0).dimension_values(2)).sum() == 0  # Dpc: DTW computes every cell
    assert (~similarity["F15E"]["computed"]).sum() > 0


def test_similarity_layout_renders_with_blue_nan_and_own_colour_range(similarity):
    figures = _figures(similarity_layout(similarity))
    assert len(figures) == len(SETS) + 1
    for title, fig in figures.items():
        name = title.split(" ")[0]
        part = similarity[name]
        (mapper,) = fig.select(LinearColorMapper)
        assert mapper.nan_color == NOT_COMPUTED
        grey = part["distance"][part["computed"]]
        assert mapper.low == pytest.approx(grey.min()) and mapper.high == pytest.approx(grey.max())


def test_similarity_layout_rejects_results_without_panels(similarity):
    with pytest.raises(ValueError, match="no panels"):
        similarity_layout({k: v for k, v in similarity.items() if k not in (*SETS, "Dpc1")})
    bad = dict(similarity, F15E=dict(similarity["F15E"], computed=similarity["F15E"]["computed"][1:]))
    with pytest.raises(ValueError, match="computed"):
        similarity_layout(bad)


# ============================================================================ Müller 2005 Fig. 11
def test_band_polygon_area_is_the_band_cells():
    band = np.array([[0, 3], [1, 3], [2, 6], [7, 9], [7, 10]])  # row 3 does not overlap row 2
    poly = band_polygon(band)
    assert polygon_area(poly) == (band[:, 1] - band[:, 0]).sum() == 14
    assert poly[0].tolist() == [-0.5, -0.5] and poly[-1].tolist() == [2.5, -0.5]


def test_alignment_layout(aligned):
    layout = alignment_layout(aligned)
    cost_panel, band_panel = layout.values()
    m, n = aligned["cost"].shape
    summary = aligned["summary"].iloc[0]
    image = cost_panel.get(0)
    np.testing.assert_allclose(image.dimension_values(2, flat=False), aligned["cost"])
    # segment boundaries of both clips
    hlines, vlines = cost_panel.get(1), cost_panel.get(2)
    np.testing.assert_array_equal(hlines.dimension_values(0), aligned["segments_a"].starts[1:] - 0.5)
    np.testing.assert_array_equal(vlines.dimension_values(0), aligned["segments_b"].starts[1:] - 0.5)
    # both paths, (frame of a, frame of b) -> (x = b, y = a)
    for panel in (cost_panel, band_panel):
        full, inside = [e for e in panel if isinstance(e, hv.Curve)]
        np.testing.assert_array_equal(full.array(), aligned["path_full"][:, ::-1])
        np.testing.assert_array_equal(inside.array(), aligned["path_band"][:, ::-1])
    # the grey band: its area is the band's cells, and the summary's
    (area,) = [e for e in band_panel if isinstance(e, hv.Polygons)]
    poly = area.split()[0].array()
    assert polygon_area(poly) == summary["band_cells"] == (aligned["band"][:, 1] - aligned["band"][:, 0]).sum()
    assert 0 < summary["band_cells"] < m * n
    (rects,) = [e for e in band_panel if isinstance(e, hv.Rectangles)]
    assert len(rects) == len(aligned["segment_path"])
    # every matched segment rectangle lies inside the band (the band covers it, enlarged by the margin)
    band = aligned["band"]
    for x0, y0, x1, y1 in rects.array():
        rows = np.arange(int(y0 + 0.5), int(y1 + 0.5))
        assert (band[rows, 0] <= x0 + 0.5).all() and (band[rows, 1] >= x1 + 0.5).all()
    assert f"{summary['band_cells']:,} of {m * n:,} cells" in band_panel.opts.get().kwargs["title"]
    assert len(_figures(layout)) == 2


def test_alignment_layout_rejects_a_band_of_the_wrong_shape(aligned):
    with pytest.raises(ValueError, match="band"):
        alignment_layout(dict(aligned, band=aligned["band"][1:]))


# ============================================================================ §4.2
def test_accuracy_plot(accuracy):
    layout = accuracy_plot(accuracy, PAPER_SECONDS)
    quality, times = layout.values()
    bars = quality.get(0)
    table = accuracy_table(accuracy)
    settings = accuracy.groupby(["seconds", "eps"]).ngroups
    assert len(bars) == len(table) == settings * len(MEASURES)
    data = bars.dframe()
    for (sec, eps), g in accuracy.groupby(["seconds", "eps"]):
        for col, label in MEASURES.items():
            row = data[(data["setting"] == f"{sec:g} s, ε={eps:g}") & (data["measure"] == label)]
            want = g[col].astype(float).dropna()
            assert row["queries"].item() == len(want)
            if len(want):
                assert row["mean"].item() == pytest.approx(want.mean())
    assert quality.get(1).data == 0.99  # the paper's rank correlation
    t = times.dframe()
    dtw = t[t["method"] == "subsequence DTW"].set_index("setting")["seconds"]
    assert dtw.to_numpy() == pytest.approx(accuracy.groupby(["seconds", "eps"])["dtw_s"].mean().to_numpy())
    assert (t.loc[t["method"] == "paper: graph (Fp16)", "seconds"] == PAPER_SECONDS[1.0]).all()
    assert len(_figures(layout)) == 2
    with pytest.raises(ValueError, match="recall"):
        accuracy_plot(accuracy.drop(columns="recall"))


def test_the_correlation_colour_scale_is_fitted_to_the_matrix():
    """Fig. 2's heat map colours its values from their least to their greatest (a matrix of 0.83..1.0 used to be a
    sliver of the fixed -1..1 scale: every cell the same red), a sequential map for values of one sign, a diverging
    one symmetric about 0 for both signs; the printed values are white on the dark cells."""
    from mocapviz.viz.correlation import correlation_heatmap

    names = ["F15E", "F30E", "Dpc1"]
    matrix = pd.DataFrame([[1.0, 0.83, 0.9], [0.91, 1.0, 0.87], [0.85, 0.88, 1.0]], index=names, columns=names)
    for m, expected in ((matrix, (0.83, 1.0)), (matrix - 0.9, (-0.1, 0.1))):
        fig = hv.render(correlation_heatmap(m), backend="bokeh")
        (mapper,) = fig.select(LinearColorMapper)
        assert (mapper.low, mapper.high) == pytest.approx(expected)
        values = m.to_numpy().ravel()
        assert mapper.low <= values.min() and values.max() <= mapper.high
    assert mapper.palette[0] != mapper.palette[-1] and len(set(mapper.palette)) > 2
    plot = correlation_heatmap(matrix)
    white = [el for el in plot if isinstance(el, hv.Labels) and el.opts.get("style", "bokeh").kwargs.get(
        "text_color") == "white"]
    assert sorted(white[0]["text"]) == ["1.00"] * 3  # the top 40 % of the scale: from 0.83 + 0.6 x 0.17 = 0.932
