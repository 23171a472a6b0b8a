"""The documents of a database as the dashboard lists and picks them, at any size.

Every document gets two columns its table may not have: its **archive** (the shared archive its source file came
from, read from the file's path: ``hdm05-cut``, ``cmu-asfamc``, ``bandai-namco-1``, …) and its **performer** (HDM05:
the actor, ``bd``; CMU: the subject number, ``135`` for trial ``135_02``; Bandai Namco names none: "—").
:func:`document_table` adds them, :func:`filter_documents` keeps the rows a set of filters asks for (the Database
page's document browser), and :class:`DocumentPicker` is the one widget every page picks a document with: type a
part of its id, name, label, performer or archive, and choose among the matches.
"""

from __future__ import annotations

import re
from pathlib import PurePath

import numpy as np
import pandas as pd
import panel as pn
import param

from ..io.datasets import ARCHIVES

NO_PERFORMER = "—"  # the performer of a document whose archive names none (Bandai Namco)
TABLE_COLUMNS = ("doc_id", "name", "label", "performer", "archive", "seconds", "n_frames", "fps")
MAX_COMPLETIONS = 50  # matches the picker lists at once (type more to narrow them)
UPLOADED = -1  # a picker's value for the session's uploaded take (mocapviz.app.upload; no document has a negative id)
_CMU_TRIAL = re.compile(r"^(\d+)_\d+$")  # a CMU trial's file name: subject_trial, "135_02"


def archive_of(path: str) -> str:
    """The archive a document's source file came from: the innermost folder of ``path`` named like a shared archive
    (:data:`mocapviz.io.datasets.ARCHIVES`), else the name of the file's own folder ("" for no path).

    Examples
    --------
    >>> archive_of("shared/cmu-asfamc/amc/martialwalk/135_02.amc")
    'cmu-asfamc'
    >>> archive_of("takes/walk_01.bvh")
    'takes'
    """
    parts = PurePath(str(path)).parts[:-1]
    return next((p for p in reversed(parts) if p in ARCHIVES), parts[-1] if parts else "")


def _text(value) -> str:
    """A cell as text: "" for a missing one."""
    return "" if value is None or (isinstance(value, float) and np.isnan(value)) or pd.isna(value) else str(value)


def performer_of(row) -> str:
    """Who performed a document (a row of ``db.documents``): its ``actor`` (HDM05), else its CMU subject
    (``cmu_subject``, else the subject number of a trial's name ``135_02``), else :data:`NO_PERFORMER`.

    Examples
    --------
    >>> performer_of({"name": "135_02", "cmu_subject": None})
    '135'
    >>> performer_of({"name": "dataset-1_bow_active_001"})
    '—'
    """
    for column in ("actor", "cmu_subject"):
        if text := _text(row.get(column)).strip():
            return text
    trial = _CMU_TRIAL.match(_text(row.get("name")))
    return trial.group(1) if trial else NO_PERFORMER


def document_table(documents: pd.DataFrame) -> pd.DataFrame:
    """The documents as the dashboard lists them: one row per document, columns :data:`TABLE_COLUMNS`.

    Parameters
    ----------
    documents : pandas.DataFrame
        ``db.documents`` (``doc_id``, ``name``, ``path``, ``n_frames``, ``fps`` and any label columns).

    Returns
    -------
    pandas.DataFrame
        ``doc_id``, ``name``, ``label`` ("" when none), ``performer`` (:func:`performer_of`), ``archive``
        (:func:`archive_of`), ``seconds`` (n_frames / fps, to 0.01 s), ``n_frames``, ``fps``; in document order.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> table = document_table(MotionDB.sample().documents)
    >>> table.loc[[0, 2], ["name", "performer", "archive"]].to_numpy().tolist()
    [['135_08', '135', 'cmu-asfamc'], ['HDM_dg_depositFloorR_013_120', 'dg', 'hdm05-cut']]
    """
    rows = documents.to_dict("records")
    labels = documents["label"] if "label" in documents else pd.Series([None] * len(documents))
    return pd.DataFrame({
        "doc_id": documents["doc_id"].to_numpy(np.int64), "name": documents["name"].astype(str).to_numpy(),
        "label": [_text(v) for v in labels], "performer": [performer_of(r) for r in rows],
        "archive": [archive_of(_text(r.get("path"))) for r in rows],
        "seconds": (documents["n_frames"] / documents["fps"]).round(2).to_numpy(),
        "n_frames": documents["n_frames"].to_numpy(np.int64), "fps": documents["fps"].to_numpy(np.float64)})  # fmt: skip


def filter_documents(table: pd.DataFrame, labels=(), performers=(), archives=(), text: str = "",
                     seconds: tuple[float, float] | None = None) -> pd.DataFrame:  # fmt: skip
    """The rows of a :func:`document_table` that every given filter keeps (an empty filter keeps all).

    Parameters
    ----------
    table : pandas.DataFrame
        A :func:`document_table`.
    labels, performers, archives : sequence of str
        Keep the documents with one of these labels, performers, archives.
    text : str
        Keep the documents whose id, name, label, performer or archive contains it (any case).
    seconds : (float, float), optional
        Keep the documents of this length, ends included.

    Returns
    -------
    pandas.DataFrame
        The kept rows, in table order, numbered from 0.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> table = document_table(MotionDB.sample().documents)
    >>> filter_documents(table, performers=["mm"], text="squat")["name"].tolist()
    ['HDM_mm_squat1Reps_037_120']
    """
    keep = np.ones(len(table), dtype=bool)
    for column, wanted in (("label", labels), ("performer", performers), ("archive", archives)):
        if wanted:
            keep &= table[column].isin(list(wanted)).to_numpy()
    if text.strip():
        keep &= searchable(table).str.contains(text.strip().lower(), regex=False).to_numpy()
    if seconds is not None:
        lo, hi = seconds
        keep &= ((table["seconds"] >= lo - 1e-9) & (table["seconds"] <= hi + 1e-9)).to_numpy()
    return table[keep].reset_index(drop=True)


def searchable(table: pd.DataFrame) -> pd.Series:
    """Each document's id, name, label, performer and archive as one lower-case line (what text filters search)."""
    return (table["doc_id"].astype(str) + " " + table["name"] + " " + table["label"] + " " + table["performer"]
            + " " + table["archive"]).str.lower()  # fmt: skip


def option_label(row) -> str:
    """A document as the picker lists it: "id: name · label · performer · archive" (empty parts left out)."""
    parts = [row["name"], row["label"], "" if row["performer"] == NO_PERFORMER else row["performer"], row["archive"]]
    return f"{int(row['doc_id'])}: " + " · ".join(p for p in parts if p)


def picker_options(table: pd.DataFrame) -> dict[str, int]:
    """{option label: doc_id} of a :func:`document_table`, in document order (:func:`option_label`)."""
    return {option_label(row): int(row["doc_id"]) for row in table.to_dict("records")}


class DocumentPicker(pn.widgets.AutocompleteInput):
    """The document picker of every page: a text box that lists the documents whose id, name, label, performer or
    archive contains what is typed (any case, at most :data:`MAX_COMPLETIONS` at once), one chosen by a click or
    Enter. ``value`` is the chosen document's id (an int), as a Select's would be.

    The whole list goes to the browser once (about 75 bytes per document) and is filtered there as the user types;
    typed text that names no document changes nothing (the page keeps the last chosen one). When the database grows
    while it is served (an ingest), the new documents join the list (:meth:`Backend.on_new_documents
    <mocapviz.app.backend.Backend.on_new_documents>`). Given the session's ``selection``, the picker of a query page
    lists the take the user uploaded first, as "uploaded: NAME (T frames)", value :data:`UPLOADED`.

    Parameters
    ----------
    backend : mocapviz.app.backend.Backend
        The database (its :meth:`~mocapviz.app.backend.Backend.doc_options`).
    label : str
        The box's title.
    value : int
        The document shown first.
    selection : mocapviz.app.state.Selection, optional
        The session's choices: its uploaded take (``selection.upload``) is offered too.
    """

    max_completions = param.Integer(default=MAX_COMPLETIONS, bounds=(1, None), doc="matches listed at once")

    def __init__(self, backend, label: str, value: int, selection=None, **params):
        self._upload = None if selection is None else selection.upload
        super().__init__(label=label, options=self._choices(backend), value=int(value), search_strategy="includes",
                         case_sensitive=False, min_characters=1, restrict=True,
                         placeholder="type a part of a name, label, performer or archive", **params)
        self._session = pn.state.curdoc  # the session's document (None outside a served session)
        backend.on_new_documents(self._new_documents)
        if selection is not None:
            selection.param.watch(lambda event: self._offer(backend, event.new), "upload")

    def _choices(self, backend) -> dict:
        """{option label: value}: the uploaded take (if any) first, then the database's documents."""
        upload = {} if self._upload is None else {self._upload.title: UPLOADED}
        return {**upload, **backend.doc_options()}

    def _offer(self, backend, upload) -> None:
        """The session uploaded a take: it is a choice (instead of the one before)."""
        self._upload = upload
        self.options = self._choices(backend)

    def _new_documents(self, backend) -> None:
        """The database served grew: its documents, the new ones too, are the choices (set on the session's event
        loop: the switch happens on another thread, and a change sent from there can reach the browser's menu half
        made)."""
        options = self._choices(backend)
        if self._session is None or self._session.session_context is None:
            self.options = options
        else:
            self._session.add_next_tick_callback(lambda: setattr(self, "options", options))
