"""The dashboard's gallery of hits: a result table shown as a grid of small animated skeletons, because motion people
look rather than read (docs/glossary.md "gallery").

A :class:`HitGallery` puts a "Table | Gallery" toggle over a result table (the rows of a hit table:
:func:`mocapviz.db.hits.hit_table`) and shows the table's hits a page at a time (:data:`PAGE_SIZE` cells, whatever
the size of the result: only the shown page's cells are built and sent) on one canvas (:class:`GalleryView`, code in
``gallery.js`` after the ``skeleton.js`` it shares with the player). Each cell is a skeleton seen by a fixed camera,
drawn from a low-rate copy of its hit (:func:`cell_frames`), showing the hit's middle key pose, with its rank, document
name (in up to three lines: a long name in full, its class not cut off) and seconds under it; the cell under the
pointer plays. A click makes the cell's row the table's selection, so
the page plays it in its aligned player as after a click in the table; a ctrl-, cmd- or shift-click adds the row to the
selection or removes it, and the download under the table exports the selected hits. The two selections are one: the
table's shows in the gallery and the gallery's is the table's.

A session whose user may annotate (:func:`mocapviz.app.auth.can`) reviews hits there too (:class:`HitReview`, made by
every :class:`HitGallery`): a ✓ and a ✗ button on every row of the table and in every cell of the gallery write the
hit as a segment label of the label in the page's "label" box, source ``accepted hit`` or ``rejected hit``; the
table's ``review`` column and the cell's buttons show each hit's state (read from the database's labels, so another
session's reviews show too); "accept page" accepts every shown hit at once, "undo" undoes the user's last change.

Wire format (one message per page, :func:`gallery_page`): ``positions`` is the float32 little-endian bytes of every
cell's (n_i, 24, 3) positions in cm, concatenated (frames of ``db.positions``, each cell moved along the floor so that
its first root position is above the origin); n_i ≤ :data:`MAX_FRAMES` frames at ≤ :data:`MAX_FPS` Hz, so at most
11,520 bytes per cell and 276,480 per page of 24 (a Bokeh binary buffer); ``meta`` the cells' lengths, rates, table
rows, labels and camera boxes, the bone tree, the side colours and the layout (about 150 bytes of JSON per cell).
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pandas as pd
import panel as pn
import param
from panel.custom import JSComponent

from ..engine import CANONICAL_PARENTS, first_frames
from ..errors import MocapvizError
from ..validation import plural
from ..viz.palette import SIDES
from .auth import can, session_user
from .player import component_code, joint_sides, recentred, scene_box

PAGE_SIZE = 24  # cells per page
COLUMNS = 8  # cells per line
CELL = (150, 176)  # (width, height) of a cell in px, its labels included
# px of the label lines under a cell's skeleton: the title (rank and document name) in up to 3 lines of 13 px, broken
# after "_" where it can, then the seconds: an HDM05 name (HDM_bd_elbowToKnee1RepsLelbowStart_001_120) in full, so
# the class it names shows
LABEL_HEIGHT = 56
MAX_FPS = 10.0  # the highest rate of a cell's frames, Hz
MAX_FRAMES = 40  # the most frames of a cell (a longer hit is shown at a lower rate)
MODES = ("Table", "Gallery")
VERDICTS = {"accept": "accepted hit", "reject": "rejected hit"}  # a review button -> the source of the label written
STATES = {"accepted hit": "accepted", "rejected hit": "rejected"}  # a label's source -> the hit's state shown
REVIEW = "review"  # the table's column of the hits' states
BUTTONS = {"accept": "✓", "reject": "✗"}  # the table's review buttons (Tabulator button columns)
REVIEW_BOX = 18  # px of a gallery cell's ✓ and ✗ buttons, in its top right corner (✗ in the corner, ✓ left of it)


def cell_frames(start: int, end: int, fps: float) -> np.ndarray:
    """The frames a gallery cell shows of the hit ``start:end`` (frames of its document, half-open): evenly spread
    from ``start``, at most :data:`MAX_FPS` per second of the hit and at most :data:`MAX_FRAMES`, at least one.

    Parameters
    ----------
    start, end : int
        The hit's frames within its document, half-open (a hit table's ``start`` and ``end``).
    fps : float
        The document's frame rate.

    Returns
    -------
    np.ndarray [shape=(n,)], int64
        In-document frame numbers, increasing, ``start`` first; they play at ``n * fps / (end - start)`` Hz.

    Examples
    --------
    >>> cell_frames(0, 120, 120.0).tolist()  # 1 s at 120 Hz: 10 frames
    [0, 12, 24, 36, 48, 60, 72, 84, 96, 108]
    >>> len(cell_frames(60, 1260, 120.0)), len(cell_frames(5, 6, 120.0))  # 10 s: 40 frames; one frame: itself
    (40, 1)
    """
    frames = int(end) - int(start)
    count = max(1, min(MAX_FRAMES, frames, math.floor(frames * MAX_FPS / fps + 1e-9)))
    return int(start) + (np.arange(count, dtype=np.int64) * frames) // count


def gallery_page(db, hits: pd.DataFrame, page: int, page_size: int = PAGE_SIZE) -> tuple[bytes, dict]:
    """What the gallery sends the browser for page ``page`` of ``hits``: rows ``page * page_size`` up to the next page.

    Parameters
    ----------
    db : MotionDB
        The database of the hits.
    hits : pandas.DataFrame
        A hit table's rows (``doc_id``, ``start``, ``end``; ``rank`` and ``name`` for the labels), as a result table
        shows them.
    page : int
        The page, from 0.
    page_size : int
        Cells per page.

    Returns
    -------
    positions : bytes
        float32 little-endian (sum n_i, 24, 3), cm: each cell's :func:`cell_frames` of ``db.positions``, recentred
        (:func:`mocapviz.app.player.recentred`), concatenated.
    meta : dict
        ``lengths`` (n_i), ``rates`` (Hz), ``rows`` (the cells' rows of ``hits``, from 0), ``labels`` (two lines
        each), ``bounds`` (each cell's camera box, cm), ``n_joints``, ``parents``, ``sides``, ``columns``, ``cell``,
        ``label_height``.
    """
    rows = np.arange(page * page_size, min(len(hits), (page + 1) * page_size))
    shown = hits.iloc[rows]
    docs = shown["doc_id"].to_numpy(np.int64)
    fps = db.documents.set_index("doc_id").loc[docs, "fps"].to_numpy(np.float64)
    ranks = shown["rank"].to_numpy() if "rank" in shown else rows + 1
    names = shown["name"].astype(str).to_numpy() if "name" in shown else docs.astype(str)
    spans = list(zip(shown["start"].to_numpy(np.int64), shown["end"].to_numpy(np.int64)))
    database_rows = [cell_frames(start, end, rate) + first
                     for (start, end), rate, first in zip(spans, fps, first_frames(db, docs))]
    lengths = [len(r) for r in database_rows]
    every = np.asarray(db.positions[np.concatenate(database_rows)]) if lengths else None  # one read for the page
    cells = [recentred(c) for c in np.split(every, np.cumsum(lengths)[:-1])] if lengths else []
    meta = {"lengths": lengths, "rows": rows.tolist(),
            "rates": [float(n * rate / (end - start)) for n, rate, (start, end) in zip(lengths, fps, spans)],
            "labels": [[f"{int(rank)} · {name}", f"{start / rate:.2f}–{end / rate:.2f} s"]
                       for rank, name, (start, end), rate in zip(ranks, names, spans, fps)],
            "bounds": [scene_box([c]) for c in cells], "n_joints": len(CANONICAL_PARENTS),
            "parents": [int(p) for p in CANONICAL_PARENTS], "sides": joint_sides(), "side_colours": SIDES,
            "columns": COLUMNS,
            "cell": list(CELL), "label_height": LABEL_HEIGHT}  # fmt: skip
    positions = np.concatenate([c.reshape(-1) for c in cells]).astype("<f4").tobytes() if cells else b""
    return positions, meta


def review_states(labels: pd.DataFrame, hits: pd.DataFrame) -> list[str]:
    """Each hit's review: "accepted" or "rejected" when a segment label of ``labels`` with that source (``accepted
    hit``, ``rejected hit``) covers exactly its frames (the latest such label), else "".

    Parameters
    ----------
    labels : pandas.DataFrame
        Segment labels of one label (:meth:`mocapviz.engine.Engine.segment_labels`: doc_id, start, end, source,
        label_id).
    hits : pandas.DataFrame
        A hit table's rows (doc_id, start, end: frames of the document, half-open).

    Returns
    -------
    list of str, one per hit.
    """
    reviewed = labels[labels["source"].isin(list(STATES))].sort_values("label_id")
    last = {(int(d), int(a), int(b)): STATES[s]
            for d, a, b, s in zip(reviewed["doc_id"], reviewed["start"], reviewed["end"], reviewed["source"])}
    return [last.get((int(d), int(a), int(b)), "") for d, a, b in zip(hits["doc_id"], hits["start"], hits["end"])]


def _rows(selection) -> list[int]:
    """A selection (row numbers of a table) as plain ints, as both sides of the gallery keep it."""
    return [int(i) for i in selection]


class GalleryView(JSComponent):
    """The browser side of :class:`HitGallery` (``gallery.js``); its parameters are the wire format."""

    positions = param.Bytes(default=None, doc="float32 little-endian (sum n_i, 24, 3) cm: the page's cells")
    meta = param.Dict(default={}, doc="lengths, rates, rows, labels, bounds, bone tree, layout")
    selection = param.List(default=[], item_type=int, doc="the selected rows of the table (synced both ways)")
    reviewing = param.Boolean(default=False, doc="the cells show their ✓ and ✗ buttons (the user may annotate)")
    states = param.List(default=[], doc="the review of each cell of the page: 'accepted', 'rejected' or ''")
    verdict = param.Dict(default={}, doc="set by a click on a cell's button: {row, verdict ('accept'|'reject'), n}")

    _esm = component_code("gallery.js")

    _stylesheets: ClassVar[list[str]] = [".mvg canvas { display: block; cursor: pointer; }"]


class HitGallery(pn.viewable.Viewer):
    """A result table with a "Table | Gallery" toggle over it: the table, or its hits as animated skeletons.

    Every page with a result table builds one, and shows it where the table was. The table is made to select several
    rows (ctrl-, cmd- or shift-click), as the gallery does.

    Parameters
    ----------
    backend : mocapviz.app.backend.Backend
        The database the hits are in.
    table : panel.widgets.Tabulator
        The result table (a hit table's columns: ``doc_id``, ``start``, ``end``, ``rank``, ``name``, ...).
    css_class : str
        The gallery's class; its toggle is ``css_class-mode``, its page buttons ``css_class-previous`` and
        ``css_class-next`` (for the browser tests).
    selection : mocapviz.app.state.Selection, optional
        The session's clip: the review's label box starts with its class (:meth:`HitReview.suggest`).

    Attributes
    ----------
    page : int parameter, the shown page (from 0; one past the last shows the last).
    mode : RadioButtonGroup, "Table" or "Gallery".
    view : GalleryView, the browser component.
    review : HitReview or None, the ✓ / ✗ review (None when the session's user may not annotate).
    """

    page = param.Integer(default=0, bounds=(0, None))

    def __init__(self, backend, table: pn.widgets.Tabulator, css_class: str, selection=None):
        super().__init__()
        self.backend, self.table = backend, table
        table.selectable = True
        self.mode = pn.widgets.RadioButtonGroup(options=list(MODES), value="Table", width=160,
                                                css_classes=[f"{css_class}-mode"])
        self.view = GalleryView(css_classes=[css_class], width=COLUMNS * CELL[0], height=CELL[1])
        self.previous = pn.widgets.Button(label="‹ previous", width=100, css_classes=[f"{css_class}-previous"])
        self.next = pn.widgets.Button(label="next ›", width=100, css_classes=[f"{css_class}-next"])
        self.caption = pn.pane.Markdown("", margin=(0, 10), css_classes=[f"{css_class}-caption"])
        self.box = pn.Column(pn.Row(self.previous, self.next, self.caption), self.view, visible=False, margin=0)
        self.previous.on_click(lambda event: self.go(self.page - 1))
        self.next.on_click(lambda event: self.go(self.page + 1))
        self.mode.param.watch(self._on_mode, "value")
        self.param.watch(lambda event: self.go(event.new), "page")
        table.param.watch(self._on_value, "value")
        table.param.watch(lambda event: setattr(self.view, "selection", _rows(event.new)), "selection")
        self.view.param.watch(lambda event: setattr(self.table, "selection", _rows(event.new)), "selection")
        self._reviewed = False  # the table's value was set by the review (its column of states): stay on the page
        self.review = HitReview(backend, self, css_class) if can(None, "annotate") else None
        if self.review is not None and selection is not None:
            self.review.follow(selection)

    def __panel__(self):
        review = [] if self.review is None else [self.review]
        return pn.Column(pn.Row(self.mode, *review), self.table, self.box, margin=0, sizing_mode="stretch_width")

    def _on_value(self, event) -> None:
        """New hits: the first page, with their review states (the states alone: :meth:`show_states`)."""
        if self._reviewed:
            return
        if self.review is not None and self.n_hits and REVIEW not in event.new.columns:
            self.review.refresh(page=0)  # sets the value again, with its column of states
        else:
            self.go(0)

    def show_hits(self, value: pd.DataFrame) -> None:
        """The page's new hits, nothing selected, with their review states in the same value: one change of the
        table's columns (a second one right after made Tabulator 6.4's ``setColumns`` fail while it was still
        building the table, under load, and the states' column was then missing)."""
        if self.review is not None and value is not None and "doc_id" in value and len(value):
            value = value.assign(**{REVIEW: self.review.states(value)})
        self.table.param.update(selection=[], value=value)

    def shown_rows(self) -> list[int]:
        """The rows of the table shown now: the gallery's page, or the table's."""
        size = PAGE_SIZE if self.mode.value == "Gallery" else self.table.page_size
        page = self.page if self.mode.value == "Gallery" else max(0, self.table.page - 1)
        return list(range(page * size, min(self.n_hits, (page + 1) * size)))

    def show_states(self, states: list[str], page: int | None = None) -> None:
        """Put the hits' review ``states`` into the table's column, then show page ``page`` of new hits, or (None)
        only the new states of the cells shown (a review: no cell sent again)."""
        self._reviewed = True
        try:
            self.table.value = self.table.value.assign(**{REVIEW: states})
        finally:
            self._reviewed = False
        if page is not None:
            self.go(page)
        elif self.mode.value == "Gallery":
            self.view.states = [str(states[r]) for r in self.view.meta.get("rows", []) if r < len(states)]

    @property
    def n_hits(self) -> int:
        """The table's hits (all pages)."""
        value = self.table.value
        return 0 if value is None or "doc_id" not in value else len(value)

    @property
    def n_pages(self) -> int:
        """The gallery's pages (one when the table is empty)."""
        return max(1, math.ceil(self.n_hits / PAGE_SIZE))

    def _on_mode(self, event) -> None:
        gallery = event.new == "Gallery"
        self.table.visible, self.box.visible = not gallery, gallery
        if gallery:  # the page of the first selected hit, else the one shown before
            self.go(self.table.selection[0] // PAGE_SIZE if self.table.selection else self.page)

    def go(self, page: int) -> None:
        """Show page ``page`` (from 0; moved into the table's pages): what setting :attr:`page` does."""
        page = min(max(0, page), self.n_pages - 1)
        if page != self.page:
            self.page = page  # -> go(page) again, which shows it
        else:
            self._show()

    def _show(self) -> None:
        """Send the shown page's cells (only while the gallery is shown: a result nobody looks at costs nothing)."""
        if self.mode.value != "Gallery":
            return
        n = self.n_hits
        first = self.page * PAGE_SIZE
        positions, meta = gallery_page(self.backend.db, self.table.value, self.page) if n else (b"", {})
        lines = max(1, math.ceil(len(meta.get("rows", ())) / COLUMNS))
        self.view.param.update(positions=positions, meta=meta, selection=_rows(self.table.selection),
                               height=lines * CELL[1], reviewing=self.review is not None,
                               states=[str(s) for s in self.table.value[REVIEW].iloc[meta["rows"]]]
                               if n and REVIEW in self.table.value else [])
        self.previous.disabled, self.next.disabled = self.page == 0, self.page >= self.n_pages - 1
        self.caption.object = (f"hits {first + 1}–{min(n, first + PAGE_SIZE)} of {n:,} · page {self.page + 1} of "
                               f"{self.n_pages} · hover a hit to play it, click to open it, ctrl- or shift-click to "
                               "select several for the download") if n else "No hit to show."


class HitReview(pn.viewable.Viewer):
    """Accept or reject the hits of a :class:`HitGallery` as segment labels, one click each.

    A ✓ / ✗ button column in the table and two buttons in every gallery cell write the hit (doc_id, start, end) as
    a segment label of :attr:`label`'s text (:meth:`mocapviz.engine.Engine.add_labels`), source ``accepted hit``
    or ``rejected hit``, authored by the session's user (:func:`mocapviz.app.auth.session_user`; without
    ``--auth`` the operating system's user); a hit reviewed the other way before loses that label first. "accept
    page" accepts every shown hit in one call; "undo" undoes the user's last change
    (:meth:`~mocapviz.engine.Engine.undo_label`). Made by a HitGallery only for a user who may annotate.

    Parameters
    ----------
    backend : mocapviz.app.backend.Backend
    gallery : HitGallery
    css_class : str
        The gallery's class: the label box is ``css_class-label``, the buttons ``css_class-accept-page`` and
        ``css_class-undo``, the status line ``css_class-review-status``.
    """

    def __init__(self, backend, gallery: HitGallery, css_class: str):
        super().__init__()
        self.backend, self.gallery, self.table = backend, gallery, gallery.table
        # no title over the box (its placeholder says what it is): the row is as high as the Table | Gallery toggle,
        # so the table and the gallery stay where they were
        self.label = pn.widgets.TextInput(placeholder="label of the hits reviewed", width=220,
                                          css_classes=[f"{css_class}-label"])
        self.accept_page = pn.widgets.Button(name="accept page", width=110,
                                             css_classes=[f"{css_class}-accept-page"])
        self.undo = pn.widgets.Button(name="undo", width=70, css_classes=[f"{css_class}-undo"])
        self.status = pn.pane.Markdown("", margin=(0, 10), css_classes=[f"{css_class}-review-status"])
        self._suggesting = False
        self._typed = False  # the user wrote the label: the page's suggestions no longer replace it
        self.table.param.update(buttons=dict(BUTTONS), widths={**self.table.widths, **dict.fromkeys(BUTTONS, 34)})
        self.table.on_click(self._on_cell)
        gallery.view.param.watch(self._on_verdict, "verdict")
        self.accept_page.on_click(lambda event: self.judge(self.gallery.shown_rows(), "accept"))
        self.undo.on_click(self._undo)
        self.label.param.watch(self._on_label, "value")

    def __panel__(self):
        return pn.Row(self.label, self.accept_page, self.undo, self.status, margin=0)

    def suggest(self, label) -> None:
        """Make ``label`` (a class; None or empty: none) the label box's text, unless the user wrote one."""
        if not self._typed:
            self._suggesting = True
            try:
                self.label.value = "" if label is None or pd.isna(label) else str(label)
            finally:
                self._suggesting = False

    def follow(self, selection) -> None:
        """Suggest the class of the session's clip (``selection.doc``), now and when it changes."""
        def class_of(*events) -> None:
            docs = self.backend.documents
            own = docs.loc[docs["doc_id"] == selection.doc, "label"] if "label" in docs else pd.Series(dtype=object)
            self.suggest(own.iloc[0] if len(own) else None)

        selection.param.watch(class_of, "doc")
        class_of()

    def _on_label(self, event) -> None:
        self._typed = self._typed or not self._suggesting
        self.refresh()

    def refresh(self, page: int | None = None) -> None:
        """Read the hits' states again from the database's labels and show them (:meth:`HitGallery.show_states`:
        ``page`` None stays on the page shown)."""
        value = self.table.value
        if value is None or "doc_id" not in value or not len(value):
            return
        self.gallery.show_states(self.states(value), page)

    def states(self, hits: pd.DataFrame) -> list[str]:
        """The review states of the rows of a hit table, read from the database's labels of the box's label."""
        label = self.label.value.strip()
        labels = self.backend.engine.segment_labels(label=label) if label else None
        return review_states(labels, hits) if labels is not None else [""] * len(hits)

    def _on_cell(self, event) -> None:
        if event.column in VERDICTS:
            self.judge([event.row], event.column)

    def _on_verdict(self, event) -> None:
        if event.new.get("verdict") in VERDICTS:
            self.judge([int(event.new["row"])], event.new["verdict"])

    def judge(self, rows, verdict: str) -> list[int]:
        """Write the hits at ``rows`` of the table as segment labels of the box's label, source
        :data:`VERDICTS` [``verdict``]; hits already so reviewed are left, a label of the other verdict on the same
        frames removed first. Returns the new labels' ids (an error goes to the status line: none written)."""
        value = self.table.value
        hits = value.iloc[[r for r in rows if 0 <= r < len(value)]]
        label, source = self.label.value.strip(), VERDICTS[verdict]
        if not label:
            self.tell("Write the **label** the hits are reviewed for first.", error=True)
            return []
        engine, author = self.backend.engine, session_user().name
        try:
            labels = engine.segment_labels(label=label)
            states = review_states(labels, hits)
            todo = hits[[s != STATES[source] for s in states]]
            other = labels[(labels["source"] != source) & labels["source"].isin(list(STATES))]
            keys = set(zip(todo["doc_id"].astype(int), todo["start"].astype(int), todo["end"].astype(int)))
            for label_id, d, a, b in zip(other["label_id"], other["doc_id"], other["start"], other["end"]):
                if (int(d), int(a), int(b)) in keys:
                    engine.remove_label(int(label_id), author=author)
            ids = engine.add_labels(todo, label=label, author=author, source=source) if len(todo) else []
        except MocapvizError as exc:
            self.tell(f"Not written: {exc}", error=True)
            return []
        self.tell(f"{plural(len(ids), 'hit')} {STATES[source]} as **{label}**"
                  + (f" ({len(hits) - len(ids)} already were)" if len(hits) > len(ids) else ""))
        self.refresh()
        return ids

    def _undo(self, event=None) -> None:
        try:
            change = self.backend.engine.undo_label(author=session_user().name)
        except MocapvizError as exc:
            self.tell(f"Nothing undone: {exc}", error=True)
            return
        self.tell(f"Change {change} undid your last change.")
        self.refresh()

    def tell(self, text: str, error: bool = False) -> None:
        """Show ``text`` (Markdown) on the status line, red when ``error``."""
        self.status.object = f'<span style="color:#c0392b">{text}</span>' if error else text
