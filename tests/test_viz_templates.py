"""mocapviz.viz.templates: the template image reads back the template, feature 0 at the top."""

import holoviews as hv
import numpy as np

from mocapviz.relational.templates import DONT_CARE, MotionTemplate
from mocapviz.viz.templates import template_image


def test_template_image_holds_the_quantised_template_first_feature_on_top():
    t = MotionTemplate(np.array([[0, 1 / 3], [1, 1 / 3], [1, 1.0]]), ["zeta", "alpha"], "abc", 3, 2)
    image = template_image(t)
    # (frame, y): y = 1 is the first feature (zeta), y = 0 the second (alpha)
    assert [image[0, 1], image[1, 1], image[2, 1]] == [0.0, 1.0, 1.0]
    assert [image[0, 0], image[1, 0], image[2, 0]] == [DONT_CARE, DONT_CARE, 1.0]
    plot = hv.render(image, backend="bokeh")
    assert plot.yaxis[0].major_label_overrides == {1: "zeta", 0: "alpha"}
    raw = template_image(t, quantised=False)
    np.testing.assert_allclose([raw[j, 1] for j in range(3)], t.values[:, 0])  # zeta, unquantised
    np.testing.assert_allclose([raw[j, 0] for j in range(3)], t.values[:, 1])
