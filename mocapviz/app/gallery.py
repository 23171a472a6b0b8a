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
from ..viz.palette import SIDES
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


def _rows(selection) -> list[int]:
    """A selection (row numbers of a table) as plain ints, as both sides of the gallery keep it."""
    return [int(i) for i in selection]


class GalleryView(JSComponent):
    """The browser side of :class:`HitGallery` (``gallery.js``); its parameters are the wire format."""

    positions = param.Bytes(default=None, doc="float32 little-endian (sum n_i, 24, 3) cm: the page's cells")
    meta = param.Dict(default={}, doc="lengths, rates, rows, labels, bounds, bone tree, layout")
    selection = param.List(default=[], item_type=int, doc="the selected rows of the table (synced both ways)")

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

    Attributes
    ----------
    page : int parameter, the shown page (from 0; one past the last shows the last).
    mode : RadioButtonGroup, "Table" or "Gallery".
    view : GalleryView, the browser component.
    """

    page = param.Integer(default=0, bounds=(0, None))

    def __init__(self, backend, table: pn.widgets.Tabulator, css_class: str):
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
        table.param.watch(lambda event: self.go(0), "value")
        table.param.watch(lambda event: setattr(self.view, "selection", _rows(event.new)), "selection")
        self.view.param.watch(lambda event: setattr(self.table, "selection", _rows(event.new)), "selection")

    def __panel__(self):
        return pn.Column(self.mode, self.table, self.box, margin=0, sizing_mode="stretch_width")

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
                               height=lines * CELL[1])
        self.previous.disabled, self.next.disabled = self.page == 0, self.page >= self.n_pages - 1
        self.caption.object = (f"hits {first + 1}–{min(n, first + PAGE_SIZE)} of {n:,} · page {self.page + 1} of "
                               f"{self.n_pages} · hover a hit to play it, click to open it, ctrl- or shift-click to "
                               "select several for the download") if n else "No hit to show."
