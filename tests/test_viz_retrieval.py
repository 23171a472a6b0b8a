"""Plots of the retrieval quality (mocapviz.viz.retrieval): the data drawn is the experiment's, both backends
render, bad input is a clear error."""

from __future__ import annotations

import holoviews as hv
import numpy as np
import pandas as pd
import pytest

from mocapviz.errors import ParameterError
from mocapviz.experiments.retrieval import RECALL_LEVELS, retrieval_quality
from mocapviz.viz import class_ap_bars, pr_curves, retrieval_layout, summary_bars


@pytest.fixture(scope="module")
def result(sample_db):
    """The experiment on the embedded sample (22 HDM05 clips of two actors, 2 CMU trials), fast methods only."""
    return retrieval_quality(sample_db, methods=["dtw", "fast", "lng256"], progress=False)


def _render_both(obj, tmp_path, name: str) -> None:
    hv.render(obj, backend="bokeh")
    out = tmp_path / f"{name}.png"
    hv.save(obj, out, backend="matplotlib")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_class_bars_draw_the_per_class_table(result, tmp_path):
    per_class = result["per_class"]
    for protocol in ("loo", "lgo"):
        bars = class_ap_bars(per_class, protocol)
        drawn = bars.dframe()
        expected = per_class.dropna(subset=[f"ap_{protocol}"])
        assert len(drawn) == len(expected) and set(drawn["method"]) == {"dtw", "fast", "lng256"}
        merged = drawn.merge(expected, on=["class", "method"])
        np.testing.assert_allclose(merged["AP"], merged[f"ap_{protocol}"])
        _render_both(bars, tmp_path, f"bars-{protocol}")
    assert "leave-actor-out" in class_ap_bars(per_class, "lgo").vdims[0].label
    # the CMU trials' classes have a single document: no AP, no bar
    assert "Motorcycle" not in set(class_ap_bars(per_class).dframe()["class"])


def test_curves_draw_one_line_per_method(result, tmp_path):
    overlay = pr_curves(result["curves"], "loo")
    lines = [el for el in overlay if isinstance(el, hv.Curve)]
    assert [c.label for c in lines] == ["dtw", "fast", "lng256"]
    curves = result["curves"]
    for line in lines:
        expected = curves[(curves["method"] == line.label) & (curves["protocol"] == "loo")]
        np.testing.assert_allclose(line.dimension_values("recall"), RECALL_LEVELS)
        np.testing.assert_allclose(line.dimension_values("precision"), expected["precision"])
    _render_both(overlay, tmp_path, "curves")


def test_summary_bars_and_layout_render(result, tmp_path):
    summary = result["summary"]
    bars = summary_bars(summary, "map_loo")
    np.testing.assert_allclose(bars.dimension_values("map_loo"), summary["map_loo"])
    _render_both(summary_bars(summary, "ms_per_query", logy=True), tmp_path, "ms")
    layout = retrieval_layout(result)
    assert len(layout) == 4, "bars and curves of both protocols"
    _render_both(layout, tmp_path, "layout")
    no_group = {k: v.assign(ap_lgo=np.nan) if k == "per_class" else v for k, v in result.items()}
    assert len(retrieval_layout(no_group)) == 2


def test_an_empty_protocol_draws_empty_axes(tmp_path):
    curves = pd.DataFrame({"method": ["dtw"] * 2, "protocol": ["loo"] * 2, "recall": [0.0, 1.0],
                           "precision": [1.0, 0.5]})
    _render_both(pr_curves(curves, "lgo"), tmp_path, "empty")


def test_bad_input_is_a_clear_error(result):
    with pytest.raises(ParameterError, match="protocol"):
        class_ap_bars(result["per_class"], "lao")
    with pytest.raises(ParameterError, match="no column"):
        class_ap_bars(result["summary"])
    with pytest.raises(ParameterError, match="no column"):
        pr_curves(result["per_class"])
    with pytest.raises(ParameterError, match="measure"):
        summary_bars(result["summary"], "accuracy")


def test_methods_of_equal_precision_stay_apart_with_the_legend_beside_the_plot(tmp_path):
    """dtw, exact and fast rank alike (exact is dtw's answer): their curves used to lie on each other in one style
    under the legend. Each method now has its own colour, dash and marker, the markers of later methods smaller
    (all show on each other), and the legend sits right of the plot."""
    same = [1.0, 0.9, 0.8, 0.6, 0.5, 0.5, 0.4, 0.3, 0.3, 0.2, 0.1]
    curves = pd.concat([pd.DataFrame({"method": m, "protocol": "loo", "recall": RECALL_LEVELS, "precision": same})
                        for m in ("dtw", "exact", "fast")])  # fmt: skip
    overlay = pr_curves(curves, "loo", width=400)
    lines = [el.opts.get("style", "bokeh").kwargs for el in overlay if isinstance(el, hv.Curve)]
    dots = [el.opts.get("style", "bokeh").kwargs for el in overlay if isinstance(el, hv.Scatter)]
    for key, drawn in (("color", lines), ("line_dash", lines), ("marker", dots), ("size", dots)):
        assert len({d[key] for d in drawn}) == 3, key
    assert dots[0]["size"] > dots[1]["size"] > dots[2]["size"]
    options = overlay.opts.get("plot", "bokeh").kwargs
    assert options["legend_position"] == "right" and options["width"] > 400
    _render_both(overlay, tmp_path, "equal")
