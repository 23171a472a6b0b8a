"""mocapviz.viz.statistics: the query-time scatter holds every query of the table and the median per hit count, and
renders with bokeh (log axes) and matplotlib."""

from __future__ import annotations

import holoviews as hv
import numpy as np
import pandas as pd
import pytest
from bokeh.models import LogScale

from mocapviz.viz.statistics import median_times, query_time_scatter


@pytest.fixture
def per_query() -> pd.DataFrame:
    """Five exact and four fuzzy queries; hits 3 of the exact ones twice (median 2.0 of 1.0 and 3.0)."""
    return pd.DataFrame({
        "mode": ["exact"] * 5 + ["fuzzy"] * 4,
        "L": [5, 5, 10, 10, 20, 5, 5, 10, 20],
        "hits": [1, 3, 3, 7, 1, 2, 2, 40, 1],
        "ms": [0.5, 1.0, 3.0, 2.0, 0.7, 1.5, 2.5, 9.0, 1.1],
    })  # fmt: skip


def test_median_times(per_query):
    m = median_times(per_query)
    assert list(m["mode"]) == ["exact"] * 3 + ["fuzzy"] * 3
    assert list(m["hits"]) == [1, 3, 7, 1, 2, 40]
    np.testing.assert_allclose(m["ms"], [0.6, 2.0, 2.0, 1.1, 2.0, 9.0])


def test_scatter_holds_every_query_and_the_medians(per_query):
    overlay = query_time_scatter(per_query, title="times")
    scatters = [e for e in overlay if isinstance(e, hv.Scatter)]
    curves = [e for e in overlay if isinstance(e, hv.Curve) and not isinstance(e, hv.Scatter)]
    assert [s.label for s in scatters] == ["exact", "fuzzy"]
    assert [c.label for c in curves] == ["exact, median", "fuzzy, median"]
    exact = scatters[0]
    np.testing.assert_array_equal(exact.dimension_values("hits"), [1, 3, 3, 7, 1])
    np.testing.assert_allclose(exact.dimension_values("ms"), [0.5, 1.0, 3.0, 2.0, 0.7])
    np.testing.assert_array_equal(exact.dimension_values("L"), [5, 5, 10, 10, 20])
    np.testing.assert_allclose(curves[1].dimension_values("ms"), [1.1, 2.0, 9.0])
    assert scatters[0].opts.get("style", backend="bokeh").kwargs["color"] == \
        curves[0].opts.get("style", backend="bokeh").kwargs["color"]  # fmt: skip
    assert scatters[0].opts.get("style", backend="bokeh").kwargs["color"] != \
        scatters[1].opts.get("style", backend="bokeh").kwargs["color"]  # fmt: skip


def test_scatter_renders_log_log(per_query, tmp_path):
    fig = hv.render(query_time_scatter(per_query, title="times"), backend="bokeh")
    assert isinstance(fig.x_scale, LogScale) and isinstance(fig.y_scale, LogScale)
    assert fig.title.text == "times"
    hv.save(query_time_scatter(per_query), tmp_path / "t.png", backend="matplotlib")
    assert (tmp_path / "t.png").stat().st_size > 1000


def test_scatter_rejects_bad_tables(per_query):
    with pytest.raises(ValueError, match="no column"):
        query_time_scatter(per_query.drop(columns="ms"))
    with pytest.raises(ValueError, match="no queries"):
        query_time_scatter(per_query.iloc[:0])
