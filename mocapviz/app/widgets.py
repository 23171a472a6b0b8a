"""Widgets every page builds the same way: the primary button that starts a computation and the table of results."""

from __future__ import annotations

import pandas as pd
import panel as pn


def action_button(label: str, css_class: str, callback, width: int = 120) -> pn.widgets.Button:
    """A primary button (css class ``css_class``, for the browser tests) calling ``callback`` (sync or async)."""
    button = pn.widgets.Button(label=label, button_type="primary", width=width, align="end", css_classes=[css_class])
    button.on_click(callback)
    return button


def results_table(value: pd.DataFrame, css_class: str, titles: dict | None = None, page_size: int = 12,
                  selectable: bool = False, **params) -> pn.widgets.Tabulator:
    """A read-only, paginated table of ``value`` (a DataFrame; its columns renamed for display by ``titles``), one
    row selectable when ``selectable`` (watch its ``selection``).

    Rows are drawn plainly rather than by Tabulator's virtual renderer: a page holds a dozen rows, and the virtual
    renderer sometimes drew none after new data arrived while the page around it was laid out again (seen in the
    browser tests; the rows appeared only on a resize)."""
    return pn.widgets.Tabulator(value, titles=titles or {}, pagination="local", page_size=page_size,
                                selectable=1 if selectable else False, show_index=False, disabled=True,
                                sizing_mode="stretch_width", css_classes=[css_class],
                                configuration={"renderVertical": "basic"}, **params)
