"""A motion template drawn as the papers draw it: features × time, white 0, black 1, grey "don't care".

template_image   MotionTemplate -> hv.Image (one row per relational feature, one column per template frame),
                 the quantised template (Müller & Röder 2006, Figs. 3-5) or its real values in [0, 1].
"""

from __future__ import annotations

import holoviews as hv
import holoviews.plotting.bokeh  # registers the bokeh backend and its options

from ..relational.templates import DELTA, MotionTemplate
from ..validation import plural

__all__ = ["template_image"]


def template_image(template: MotionTemplate, quantised: bool = True, delta: float = DELTA, width: int = 700,
                   height: int | None = None) -> hv.Image:  # fmt: skip
    """The template as an image: features (rows, in the set's order, first at the top) × template frames.

    Parameters
    ----------
    template : MotionTemplate
        A learned template.
    quantised : bool
        Draw the quantised template (0 white, 1 black, don't care grey); False: the real values (a grey scale
        from white 0 to black 1).
    delta : float
        The quantisation threshold δ.
    width, height : int
        Pixels (height default: 12 px per feature).

    Returns
    -------
    hv.Image
        Key dimensions ``frame`` and ``feature`` (row f - 1 - i is feature i) and value ``value``.
    """
    values = template.quantised(delta) if quantised else template.values
    k, f = values.shape
    what = "quantised, grey = don't care" if quantised else "averaged values"
    title = (f"{template.label or 'motion template'}: {plural(template.n_examples, 'example')}, {plural(k, 'frame')} "
             f"({what})")
    # row 0 of an Image is drawn at the top: feature 0 first, as in the papers' figures
    image = hv.Image(values.T, bounds=(-0.5, -0.5, k - 0.5, f - 0.5), kdims=["frame", "feature"], vdims=["value"])
    ticks = [(f - 1 - i, name) for i, name in enumerate(template.features)]
    return image.opts(
        cmap=["#ffffff", "#9a9a9a", "#000000"] if quantised else "Greys", clim=(0.0, 1.0), yticks=ticks,
        width=width, height=height or 40 + 12 * f, title=title, colorbar=not quantised, tools=["hover"],
        xlabel="template frame", ylabel="", fontsize={"yticks": 7},
    )  # fmt: skip
