"""Widgets every page builds the same way: the primary button that starts a computation, the table of results,
the number boxes that keep their bounds (:class:`BoundedIntInput`, :class:`BoundedFloatInput`), and
:func:`when_drawn`, which runs a page's first answer once the browser has drawn the page."""

from __future__ import annotations

import math

import pandas as pd
import panel as pn
import param
from panel.custom import JSComponent

from ..engine.parameters import PARAMETERS, default

PAGE_SIZE = 25  # rows of a result table's page (the rest stay on the server until their page is shown)
MAX_MATCHES = 100  # K of the pages that list matches (Similarity, Templates, Describe): a gallery, 4 table pages
# The titles of the hit table's columns (mocapviz.db.hits.hit_table), the same on every page: each page shows the
# columns it wants, in this order, under these titles (``hit_columns``).
HIT_TITLES = {"rank": "rank", "doc_id": "document", "name": "name", "label": "label", "start": "start frame",
              "end": "end frame (excl.)", "frames": "frames", "start_s": "start (s)", "end_s": "end (s)",
              "distance": "distance", "score": "score", "cost": "cost", "normalised_cost": "normalised cost",
              "cost_per_frame": "cost / frame", "n_segments": "segments", "parts": "parts"}  # fmt: skip


def hit_titles(*columns: str) -> dict:
    """The :data:`HIT_TITLES` of ``columns``, in the order given (a page's table)."""
    return {c: HIT_TITLES[c] for c in columns}


def hit_columns(hits: pd.DataFrame, titles: dict, decimals: dict | None = None) -> pd.DataFrame:
    """The columns of ``titles`` that ``hits`` has, in that order, rounded by ``decimals`` (column -> places)."""
    return hits[[c for c in titles if c in hits]].round(decimals or {})


class _KeepsBounds:
    """What :class:`BoundedIntInput` and :class:`BoundedFloatInput` share: the server enforces ``start`` / ``end``.

    A value entered outside them becomes the nearest bound, an emptied box gets its last value back (or, ``optional``,
    means "none": the value None), and ``note`` (a Markdown pane, placed by the page next to the box; hidden while
    empty) says what was changed, naming the range. The label names the range too, and follows :meth:`set_bounds`.
    So the box always shows the value that runs. Bounds come from the library's own checks (a database's frames,
    a :class:`~mocapviz.validation.Interval`), so the box never takes a value the run refuses.

    The bounds are not sent to the browser: Bokeh's spinner, given them, silently keeps its previous value when a
    typed one is out of bounds, while the box goes on showing the typed text until it loses focus.
    """

    def _keep_bounds(self, label: str, optional: bool = False) -> None:
        self.base_label, self.optional = label, optional
        self.note = pn.pane.Markdown("", visible=False, margin=(0, 10), css_classes=["mv-input-note"])
        self._last = self.value
        self._correcting = False
        self._users = False  # the value was entered in the box (not set by the page): moving it is worth a note
        self.name = self._title()
        self.param.watch(self._check, "value")  # registered first: runs before the page's own watchers

    def _text(self, x) -> str:
        return f"{x:,}" if isinstance(x, int) else f"{x:g}"

    def range_text(self) -> str:
        """The accepted values in words: "1–256", "≥ 0"."""
        if self.end is None:
            return "any" if self.start is None else f"≥ {self._text(self.start)}"
        if self.start is None:
            return f"≤ {self._text(self.end)}"
        return f"{self._text(self.start)}–{self._text(self.end)}"

    def _title(self) -> str:
        return f"{self.base_label} ({self.range_text()}{', empty: none' if self.optional else ''})"

    def bounded(self, value):
        """``value`` moved into [start, end]."""
        if value is None:
            return value
        if self.start is not None and value < self.start:
            return self.start
        if self.end is not None and value > self.end:
            return self.end
        return value

    def _check(self, event) -> None:
        if self._correcting:
            return
        value = event.new
        if isinstance(value, float) and math.isnan(value):
            value = None
        if value is None and not self.optional:
            fixed, why = self._last, f"**{self.base_label}** was empty: set back to {self._text(self._last)}."
        else:
            fixed = self.bounded(value)
            why = (f"**{self.base_label}** must be {self.range_text()}: {self._text(value)} was set to "
                   f"{self._text(fixed)}.") if fixed != value else ""
        if fixed != event.new:  # NaN (a cleared box) too
            self._set(fixed)
        self._last, self._users = fixed, True
        self.tell(why)

    def tell(self, why: str) -> None:
        """Show ``why`` (Markdown) under the box, or hide the note when it is empty."""
        self.note.param.update(object=why, visible=bool(why))

    def _set(self, value) -> None:
        self._correcting = True
        try:
            self.value = value
        finally:
            self._correcting = False

    def set_bounds(self, start, end, value=None) -> None:
        """New bounds (and, optionally, a new value); the value is moved inside them and the label follows. The note
        says so when the value moved was one entered in the box; a value the page set (its default, or ``value``)
        moves silently."""
        old = self.value
        self._correcting = True
        try:
            self.param.update(start=start, end=end)
            self.name = self._title()
            self.value = self.bounded(old if value is None else value)
            self._last = self.value
        finally:
            self._correcting = False
        moved = value is None and self._users and old is not None and self.value != old
        if value is not None:
            self._users = False
        why = f"**{self.base_label}** must now be {self.range_text()}: {self._text(old)} was set to " \
              f"{self._text(self.value)}." if moved else ""
        self.tell(why)


class BoundedIntInput(_KeepsBounds, pn.widgets.IntInput):
    """An IntInput whose bounds the server enforces (see :class:`_KeepsBounds`): ``BoundedIntInput("k", 64, 1,
    256, css_classes=[...])`` shows "k (1–256)"."""

    _rename = {**pn.widgets.IntInput._rename, "start": None, "end": None}

    def __init__(self, label: str, value: int, start: int | None = None, end: int | None = None, **params):
        super().__init__(value=value, start=start, end=end, **params)
        self._keep_bounds(label)


class BoundedFloatInput(_KeepsBounds, pn.widgets.FloatInput):
    """A FloatInput whose bounds the server enforces (see :class:`_KeepsBounds`); ``optional``: an empty box is
    the value None ("none"), not an error."""

    _rename = {**pn.widgets.FloatInput._rename, "start": None, "end": None}

    def __init__(self, label: str, value: float | None, start: float | None = None, end: float | None = None,
                 optional: bool = False, **params):
        super().__init__(value=value, start=start, end=end, **params)
        self._keep_bounds(label, optional)

    @classmethod
    def within(cls, label: str, value: float | None, interval, step: float, **params) -> BoundedFloatInput:
        """A box stepping by ``step`` whose bounds are the library's :class:`~mocapviz.validation.Interval` of the
        parameter (an open end one step inside it, :meth:`~mocapviz.validation.Interval.closed`)."""
        return cls(label, value, *interval.closed(step), step=step, **params)


def parameter_box(label: str, name: str, use: str, most: int | None = None, value=None, **params):
    """A bounded box of the declared parameter ``name`` of use case ``use`` (:mod:`mocapviz.engine.parameters`):
    its default (or ``value``: a page's own choice for its database) and the table's bounds, the upper one lowered to
    ``most`` where the page shows its answer as a picture or a page of rows; never a value the engine refuses.

    Examples
    --------
    >>> box = parameter_box("K", "n_matches", "search_template", most=100)
    >>> box.value, box.start, box.end
    (20, 1, 100)
    """
    parameter = PARAMETERS[name]
    spec = parameter.widget(default(use, name) if value is None else value)
    end = spec.get("end")
    if most is not None:
        end = most if end is None else min(end, most)
    if parameter.kind == "int":
        return BoundedIntInput(label, spec["value"], spec["start"], end, **params)
    return BoundedFloatInput(label, spec["value"], spec["start"], end, optional=parameter.optional,
                             step=spec["step"], **params)  # fmt: skip


def notes(*inputs) -> pn.Column:
    """The notes of some bounded inputs, one under the other (each hidden while empty)."""
    return pn.Column(*[w.note for w in inputs], margin=0, sizing_mode="stretch_width")


def clear(*shown) -> None:
    """Empty what showed a previous result, so that no old answer stays on the page under the error of a run that
    failed: a table loses its rows (keeping its columns), a text pane its text, a plot or picture its object, a
    layout (a player's box, a card) is hidden (the page shows it again with its next result)."""
    for w in shown:
        if isinstance(w, pn.widgets.Tabulator):
            w.param.update(selection=[], value=w.value.iloc[:0])
        elif isinstance(w, (pn.pane.Markdown, pn.pane.HTML)):
            w.object = ""
        elif isinstance(w, (pn.pane.HoloViews, pn.pane.PNG)):
            w.object = None
        else:
            w.visible = False


def action_button(label: str, css_class: str, callback, width: int = 120) -> pn.widgets.Button:
    """A primary button (css class ``css_class``, for the browser tests) calling ``callback`` (sync or async)."""
    button = pn.widgets.Button(label=label, button_type="primary", width=width, align="end", css_classes=[css_class])
    button.on_click(callback)
    return button


def results_table(value: pd.DataFrame, css_class: str, titles: dict | None = None, page_size: int = PAGE_SIZE,
                  selectable: bool = False, tooltips: bool = False, **params) -> pn.widgets.Tabulator:
    """A read-only table of ``value`` (a DataFrame; its columns renamed for display by ``titles``) paged on the
    server, one row selectable when ``selectable`` (watch its ``selection``: row numbers of ``value``, whatever the
    page); ``tooltips``: a cell's text shows in full on hover (for a table whose columns are narrowed to fit,
    ``layout="fit_columns"``).

    Only the shown page's ``page_size`` rows are sent to the browser (Tabulator's remote pagination), so a result of
    any size shows at once: 11,000 hits cost what 25 do. Rows are drawn plainly rather than by Tabulator's virtual
    renderer: the virtual renderer sometimes drew none after new data arrived while the page around it was laid out
    again (seen in the browser tests; the rows appeared only on a resize)."""
    return pn.widgets.Tabulator(value, titles=titles or {}, pagination="remote", page_size=page_size,
                                selectable=1 if selectable else False, show_index=False, disabled=True,
                                sizing_mode="stretch_width", css_classes=[css_class],
                                configuration={"renderVertical": "basic",
                                               **({"columnDefaults": {"tooltip": True}} if tooltips else {})},
                                **params)


class Drawn(JSComponent):
    """An empty component whose browser side sets ``drawn`` once it is drawn: appended to a layout, after the
    layout's other views (its module loads after theirs are built)."""

    drawn = param.Boolean(default=False, doc="the browser has drawn the component")
    _esm = "export function render({ model }) { model.drawn = true; }"


def when_drawn(callback) -> Drawn | None:
    """A marker to put after a page just built: once the browser has drawn it, ``callback`` (sync or async, no
    argument) runs; outside a browser session ``callback`` runs at once (and None is returned).

    A page's first answer starts here rather than when the page is built: updates to the widgets of a page the
    browser has not drawn yet (its Run button disabled, its progress bar moved) reached views without their elements
    ("Cannot read properties of undefined (reading 'setAttribute')" in Bokeh's and Panel's code).
    """
    doc = pn.state.curdoc
    if doc is None or doc.session_context is None:
        pn.state.execute(callback)
        return None
    marker = Drawn(width=0, height=0, margin=0)
    marker.param.watch(lambda event: pn.state.execute(callback) if event.new else None, "drawn")
    return marker
