"""Downloads of what the dashboard shows: the hits of a result table and the clip under the player, as motion files
(BVH or glTF binary, on the canonical skeleton or the source file's own rig, or HumanML3D's joint arrays with their
manifest; :mod:`mocapviz.export`).

Under every result table (Relational query, Similarity, Motion templates, Describe) a :class:`HitDownload` gives
the selected hit as one file, several selected hits (ctrl- or shift-click in the table or its gallery,
:mod:`mocapviz.app.gallery`) or every hit of the table (none selected) as one zip archive; under the player it gives
the clip's query span. The file is made when the button is clicked, in memory, from the server's database and (for
the source rig) the ingested source file. A table that is not a hit table (the Audit page's pairs, the documents
it keeps) downloads as CSV (:func:`csv_download`).
"""

from __future__ import annotations

import io
from collections.abc import Callable

import pandas as pd
import panel as pn

from ..engine.parameters import parameter
from ..errors import MocapvizError

_NAMES = {"bvh": "BVH", "glb": "glTF (.glb)", "humanml3d": "HumanML3D joints (.npy)", "canonical": "canonical skeleton",
          "source": "source rig"}  # fmt: skip
FORMATS = {_NAMES.get(f, f): f for f in parameter("export_format").choices if f != "amc"}  # amc: source rig only
RIGS = {_NAMES.get(r, r): r for r in reversed(parameter("rig").choices)}
ONE_FILE = ("bvh", "glb")
"""Formats that export one hit as one file (an array comes with its manifest: a zip archive)."""


class _Download(pn.widgets.FileDownload):
    """A FileDownload whose callback may give None: the export failed (its reason is shown beside the button) and
    nothing is sent."""

    def _sync_data(self, fileobj):
        if fileobj is not None:
            super()._sync_data(fileobj)


def table_hits(table: pn.widgets.Tabulator) -> pd.DataFrame:
    """The hits a result table offers for download: its selected rows, or all its rows when none is selected
    (``doc_id``, ``start``, ``end``, ``rank`` and the columns it shows)."""
    value = table.value
    if value is None or value.empty or "doc_id" not in value:
        return pd.DataFrame(columns=["doc_id", "start", "end"])
    return value.iloc[list(table.selection)] if table.selection else value


class HitDownload:
    """A format and rig choice and a download button for the hits ``hits()`` returns (a hit table: ``doc_id``,
    ``start``, ``end`` within the document, half-open; ``rank`` and the search's columns if it has them).

    Parameters
    ----------
    backend : mocapviz.app.backend.Backend
        The database the hits are in.
    hits : callable
        () -> pandas.DataFrame, asked when the button is clicked (and by :meth:`refresh`, for the label).
    search : callable
        () -> str: what found them, written into every file.
    css_class : str
        The button's class (for the browser tests).
    noun : str
        What one row is, for the button's label ("hit", "clip").
    """

    def __init__(self, backend, hits: Callable[[], pd.DataFrame], search: Callable[[], str], css_class: str,
                 noun: str = "hit"):  # fmt: skip
        self.backend, self.hits, self.search, self.noun = backend, hits, search, noun
        self.format = pn.widgets.Select(label="file format", options=FORMATS, value="bvh", width=120)
        self.rig = pn.widgets.Select(label="skeleton", options=RIGS, value="canonical", width=160)
        self.button = _Download(callback=self._file, filename="hits.zip", auto=True, width=220, align="end",
                                css_classes=[css_class])
        self.note = pn.pane.Markdown("", visible=False, margin=(0, 10), css_classes=[f"{css_class}-note"])
        self.format.param.watch(lambda *events: self.refresh(), "value")
        self.refresh()

    def panel(self) -> pn.Column:
        """The choices, the button and the note of a failed export."""
        return pn.Column(pn.Row(self.format, self.rig, self.button), self.note, margin=0)

    def refresh(self) -> None:
        """The button's label and file name for the hits as they are now (disabled when there are none)."""
        n = len(self.hits())
        ext = self.format.value
        one = n == 1 and ext in ONE_FILE
        self.button.disabled = n == 0
        self.button.label = (f"Download this {self.noun} (.{ext})" if one else
                             f"Download this {self.noun} (.zip)" if n == 1 else
                             f"Download {n} {self.noun}s (.zip)" if n else f"No {self.noun} to download")
        self.button.filename = f"{self.noun}.{ext}" if one else f"{self.noun}s.zip"

    def _file(self) -> io.BytesIO | None:
        from ..engine import zipped

        try:
            files = self.backend.engine.export_files(self.hits(), format=self.format.value, rig=self.rig.value,
                                                     search=self.search())
        except MocapvizError as exc:  # e.g. the source file is gone: said under the button, nothing downloaded
            self.note.param.update(object=f"Not exported: {exc}", visible=True)
            return None
        self.note.param.update(object="", visible=False)
        if len(files) == 1:  # one hit (BVH or glTF: one file), as the export names it
            (self.button.filename, data), = files.items()
        else:
            data, self.button.filename = zipped(files), f"{self.noun}s.zip"
        return io.BytesIO(data)


def table_download(backend, table: pn.widgets.Tabulator, search: Callable[[], str], css_class: str) -> HitDownload:
    """A :class:`HitDownload` of a result table's hits (:func:`table_hits`), its label following the table's rows
    and selection."""
    download = HitDownload(backend, lambda: table_hits(table), search, css_class)
    table.param.watch(lambda *events: download.refresh(), ["value", "selection"])  # one call per batch of changes
    return download


def csv_download(table: Callable[[], pd.DataFrame | None], filename: str, label: str,
                 css_class: str) -> pn.widgets.FileDownload:
    """A button downloading ``table()`` (asked when it is clicked; None: nothing to download, nothing sent) as the CSV
    file ``filename``: UTF-8, a header line, no index."""

    def data() -> io.BytesIO | None:
        frame = table()
        return None if frame is None else io.BytesIO(frame.to_csv(index=False).encode("utf-8"))

    return _Download(callback=data, filename=filename, label=label, auto=True, width=330, align="end",
                     css_classes=[css_class])
