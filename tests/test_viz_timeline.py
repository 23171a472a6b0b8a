"""Plot builders of a clip's features over time (mocapviz.viz.timeline), on a real HDM05 clip of the sample."""

from __future__ import annotations

import holoviews as hv
import numpy as np
import pytest

from mocapviz.features import feature_groups, numeric_columns, numeric_features, relational_features
from mocapviz.viz.palette import PARTS, SIDES
from mocapviz.viz.timeline import numeric_curves, relational_timeline, runs


@pytest.fixture(scope="module")
def kick(sample_db):
    doc = int(sample_db.select(label="kickLFront1Reps")["doc_id"].iloc[0])
    return sample_db.motion(doc)


def _runs_by_loop(values: np.ndarray) -> list[tuple[int, int, int]]:
    out = []
    for f in range(values.shape[1]):
        t = 0
        while t < len(values):
            if values[t, f]:
                s = t
                while t < len(values) and values[t, f]:
                    t += 1
                out.append((f, s, t))
            else:
                t += 1
    return out


def test_runs_equal_a_loop_over_real_features(kick):
    values, _ = relational_features(kick, progress=False)
    table = runs(values)
    assert list(table.itertuples(index=False, name=None)) == _runs_by_loop(values)
    assert (table["stop"] > table["start"]).all()


def test_runs_rejects_a_vector():
    with pytest.raises(ValueError, match=r"\(T, f\)"):
        runs(np.ones(5, bool))


def test_relational_timeline_draws_every_run_in_seconds(kick):
    values, names = relational_features(kick, progress=False)
    groups = feature_groups()
    plot = relational_timeline(values, names, kick.fps, groups, span=(10, 40))
    rects = plot.get(0)
    expected = runs(values)
    assert len(rects) == len(expected)
    np.testing.assert_allclose(rects.dimension_values("x0"), expected["start"] / kick.fps)
    np.testing.assert_allclose(rects.dimension_values("x1"), expected["stop"] / kick.fps)
    # the first feature is the top row; colours follow the groups
    top = rects.dimension_values("feature")[rects.dimension_values("y0") > len(names) - 1.5]
    assert set(top) <= {names[0]}
    for group in ("lower", "upper", "mix"):  # the palette's parts of the body, never a side's red or blue
        shown = set(rects.dimension_values("colour")[rects.dimension_values("group") == group])
        assert shown == {PARTS[group]} and not shown & set(SIDES.values())
    spans = [layer for layer in plot if isinstance(layer, hv.VSpan)]
    assert len(spans) == 1 and tuple(spans[0].data) == (10 / kick.fps, 41 / kick.fps)
    hv.render(plot, backend="bokeh")


def test_relational_timeline_checks_its_input(kick):
    values, names = relational_features(kick, progress=False)
    with pytest.raises(ValueError, match="do not match"):
        relational_timeline(values, names[:-1], kick.fps)
    with pytest.raises(ValueError, match="fps"):
        relational_timeline(values, names, 0)


def test_numeric_curves_one_curve_per_coordinate(kick):
    X = numeric_features(kick, "F15E", progress=False)
    cols = numeric_columns("F15E")
    plot = numeric_curves(X, cols, kick.fps, span=(0, 5))
    curves = [c for c in plot if isinstance(c, hv.Curve)]
    assert [c.label for c in curves] == cols
    np.testing.assert_allclose(curves[3].dimension_values(1), X[:, 3])
    np.testing.assert_allclose(curves[0].dimension_values(0), np.arange(len(X)) / kick.fps)
    with pytest.raises(ValueError, match="do not match"):
        numeric_curves(X, cols[:3], kick.fps)


@pytest.mark.parametrize("numeric_set", ["F15E", "F39E", "F15x5E", "Fp25"])
def test_numeric_curves_draw_every_coordinate_in_a_style_of_its_own(kick, numeric_set):
    """F15E's 15 curves used to cycle through 10 colours (two coordinates looked the same): now a colour per
    joint, a dash per axis (fainter samples of a window), every curve distinct."""
    cols = numeric_columns(numeric_set)
    plot = numeric_curves(np.zeros((5, len(cols))), cols, kick.fps)
    styles = [(c.opts.get("style").kwargs["color"], c.opts.get("style").kwargs["line_dash"],
               c.opts.get("style").kwargs["alpha"]) for c in plot if isinstance(c, hv.Curve)]
    assert len(styles) == len(cols) == len(set(styles))
    if numeric_set == "F15E":
        assert len({s[0] for s in styles}) == 5 and len({s[1] for s in styles}) == 3  # 5 joints x 3 axes
