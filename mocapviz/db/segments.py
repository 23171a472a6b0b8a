"""Segment labels: who said which stretch of which document is what, kept with the database, every change kept.

A segment label is a row (``label_id``, ``doc_id``, ``start``, ``end``: frames of the document, half-open as every
hit, ``label``, ``author``, ``time``: UTC ISO 8601, ``source``: one of :data:`SOURCES`, ``note``). The file-name
labels of ``db.documents`` say what a whole clip is; segment labels say what a stretch of it is, and who said so.

What is stored is the **log of changes** (``DB/labels/changes.json``, :func:`mocapviz.db.layout.labels_file`), never
the table: each change is one entry (``add`` a row, ``remove`` one, ``edit`` one) numbered 1, 2, ... with its
author and time and the row it leaves (None after a remove). The current table is the log replayed. An **undo** of
change k is itself a change: it puts k's row back as it was before k (an undone add is a remove, an undone remove an
add of the same ``label_id``, an undone edit an edit back) and records ``undoes = k``; it is refused when a later
change has touched that row since (undo that one first), so an undo always restores the state before k exactly.
Label ids are never reused.

Writers (:meth:`SegmentLabels.add`, ...) hold the lock of ``DB/labels/`` (:func:`mocapviz.store.locked`), read
the log again, check the change against it, append and replace the file atomically (:func:`mocapviz.store.
atomic_write`): several processes writing at once all land, in some order. Readers take no lock: a file is always
a whole log. The file carries the format header (:func:`mocapviz.store.stamp`) and the sha256 of its changes, so a
damaged file is a MotionDBError naming it, never a wrong table.

Exchange formats (:func:`exported`, :func:`read_labels`): CSV with the hit table's columns
(:func:`mocapviz.db.hits.hit_table`) and the label's, and BABEL-style JSON (Punnakkal et al. 2021's
``frame_ann`` per sequence: segments in seconds at the document's own rate, with action names). Both name the
documents, so labels move to another database holding the same documents under the same names.
"""
from __future__ import annotations

import hashlib
import json
import os
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from .. import store
from ..errors import MotionDBError, ParameterError
from ..validation import one_of, text
from .hits import hit_table
from .layout import labels_file, labels_folder

__all__ = ["COLUMNS", "POSITIVE", "SOURCES", "SegmentLabels", "babel_json", "exported", "label_hits", "overlapping", "read_labels"]

FORMAT = "mocapviz.SegmentLabels"
VERSION = 1
SOURCES = ("manual", "accepted hit", "rejected hit", "imported")
"""Where a label comes from: typed or drawn by a user, a search's hit accepted or rejected (a rejected hit says the
stretch is *not* of its label: never an example or a relevant stretch), or read from a file."""
POSITIVE = ("manual", "accepted hit", "imported")
"""The sources whose rows say the stretch *is* of its label (the examples a template learns from)."""
COLUMNS = ["label_id", "doc_id", "start", "end", "label", "author", "time", "source", "note"]
_ROW = ("doc_id", "start", "end", "label", "source", "note")
NOTE_CHARACTERS = 1000


class SegmentLabels:
    """The segment labels of one MotionDB: read (:meth:`table`, :meth:`history`) and changed (:meth:`add`,
    :meth:`remove`, :meth:`edit`, :meth:`undo`), each change one atomic write under the labels' lock.

    Parameters
    ----------
    db : MotionDB
        The database (its documents bound the rows; the labels live in its folder).

    Examples
    --------
    >>> import shutil, tempfile
    >>> from mocapviz import MotionDB
    >>> folder = tempfile.mkdtemp()
    >>> db = MotionDB.open(shutil.copytree(MotionDB.sample().path, f"{folder}/db"))
    >>> labels = SegmentLabels(db)
    >>> first = labels.add(7, 10, 40, "kick", author="ann")
    >>> labels.remove(first, author="bob")  # the change's number
    2
    >>> len(labels.table()), labels.undo(author="bob"), labels.table()[["label_id", "doc_id", "author"]].values.tolist()
    (0, 3, [[1, 7, 'ann']])
    >>> print(labels.history()[["change", "op", "label_id", "author", "undoes"]].to_string(index=False))
     change     op  label_id author  undoes
          1    add         1    ann    <NA>
          2 remove         1    bob    <NA>
          3    add         1    bob       2
    >>> shutil.rmtree(folder)
    """

    def __init__(self, db):
        self.db = db
        self.path = labels_file(db.path)

    # ------------------------------------------------------------------ reading
    def changes(self) -> list[dict]:
        """The log as stored: one dict per change, in order (empty when nothing was labelled)."""
        return _read(self.path)

    def table(self, label: str | None = None, sources=None) -> pd.DataFrame:
        """The current labels: the log replayed, by label id.

        Parameters
        ----------
        label : str, optional
            Only the rows of this label.
        sources : sequence of str, optional
            Only the rows of these sources (:data:`SOURCES`; e.g. :data:`POSITIVE`).

        Returns
        -------
        pandas.DataFrame
            :data:`COLUMNS`, one row per label.
        """
        return _frame(_replay(self.changes())[0], label, sources)

    def history(self) -> pd.DataFrame:
        """The log: ``change``, ``op``, ``label_id``, ``author``, ``time``, ``undoes`` (the change an undo reverts,
        else missing) and the row the change leaves (doc_id, start, end, label, source, note; missing after a
        remove)."""
        rows = [{"change": c["change"], "op": c["op"], "label_id": c["label_id"], "author": c["author"],
                 "time": c["time"], "undoes": c.get("undoes"), **(c["row"] or dict.fromkeys(_ROW))}
                for c in self.changes()]  # fmt: skip
        table = pd.DataFrame(rows, columns=["change", "op", "label_id", "author", "time", "undoes", *_ROW])
        for c in ("undoes", "doc_id", "start", "end"):
            table[c] = table[c].astype("Int64")
        return table

    # ------------------------------------------------------------------ changing
    def add(self, doc_id: int, start: int, end: int, label: str, *, author: str, source: str = "manual",
            note: str = "") -> int:  # fmt: skip
        """Label frames ``start:end`` (half-open) of document ``doc_id``; returns the new label's id."""
        return self.add_many([{"doc_id": doc_id, "start": start, "end": end, "label": label, "source": source,
                               "note": note}], author=author)[0]  # fmt: skip

    def add_many(self, rows, *, author: str) -> list[int]:
        """Several labels at once (an import, a page of accepted hits): one change each, written together (all or
        none).

        Parameters
        ----------
        rows : iterable of dict
            Each with ``doc_id``, ``start``, ``end``, ``label`` and optionally ``source`` (default manual) and
            ``note``.
        author : str

        Returns
        -------
        list of int
            The new labels' ids, in the order of ``rows``.
        """
        rows = [self._checked_row(r) for r in rows]
        author = text(author, "author")

        def change(log, state):
            first = 1 + max((c["label_id"] for c in log), default=0)
            return [("add", first + i, row, None) for i, row in enumerate(rows)]

        return [c["label_id"] for c in self._write(change, author)]

    def remove(self, label_id: int, *, author: str) -> int:
        """Remove the label ``label_id``; returns the change's number."""
        author = text(author, "author")
        return self._write(lambda log, state: [("remove", self._current(state, label_id), None, None)], author)[0][
            "change"]

    def edit(self, label_id: int, *, author: str, **fields) -> int:
        """Change fields of the label ``label_id`` (``doc_id``, ``start``, ``end``, ``label``, ``source``,
        ``note``); returns the change's number."""
        author = text(author, "author")
        unknown = sorted(set(fields) - set(_ROW))
        if unknown:
            raise ParameterError(f"a label has no field {unknown[0]!r}; it has {', '.join(_ROW)}")

        def change(log, state):
            label_id_ = self._current(state, label_id)
            return [("edit", label_id_, self._checked_row({**state[label_id_], **fields}), None)]

        return self._write(change, author)[0]["change"]

    def undo(self, change: int | None = None, *, author: str) -> int:
        """Revert change ``change`` (default: ``author``'s last change that is neither an undo nor undone) by a new
        change; returns its number.

        Raises
        ------
        ParameterError
            No such change, nothing of ``author``'s left to undo, the change is undone already, or a later change
            touched its label since (named: undo that one first).
        """
        author = text(author, "author")

        def revert(log, state):
            _, before, undone, last = _replay(log)
            k = self._target(log, undone, change, author)
            label_id, after = log[k - 1]["label_id"], log[k - 1]["row"]
            now = None if label_id not in state else {f: state[label_id][f] for f in _ROW}
            if now != after:
                raise ParameterError(f"change {k} cannot be undone: change {last[label_id]} changed label "
                                     f"{label_id} since; undo that one first")  # fmt: skip
            old = before[k] and {f: before[k][f] for f in _ROW}
            op = "remove" if old is None else "add" if label_id not in state else "edit"
            return [(op, label_id, old, k)]

        return self._write(revert, author)[0]["change"]

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _target(log: list[dict], undone: set, change, author: str) -> int:
        if change is not None:
            k = int(change)
            if not 1 <= k <= len(log):
                raise ParameterError(f"no change {change} in the label history (changes 1..{len(log)})")
            if k in undone:
                raise ParameterError(f"change {k} is undone already")
            return k
        for c in reversed(log):
            if c["author"] == author and c.get("undoes") is None and c["change"] not in undone:
                return c["change"]
        raise ParameterError(f"{author} has no change to undo in the label history")

    @staticmethod
    def _current(state: dict, label_id) -> int:
        try:
            label_id = int(label_id)
        except (TypeError, ValueError):
            raise ParameterError(f"a label id is a whole number; got {label_id!r}") from None
        if label_id not in state:
            raise ParameterError(f"no label {label_id} (labels now: {', '.join(map(str, sorted(state))[:20]) or 'none'})")
        return label_id

    def _checked_row(self, row: dict) -> dict:
        """A row's fields checked against the database: ParameterError naming the value."""
        doc_id, start, end = (row.get(k) for k in ("doc_id", "start", "end"))
        try:
            doc_id, start, end = int(doc_id), int(start), int(end)
        except (TypeError, ValueError):
            raise ParameterError(f"doc_id, start and end must be whole numbers; got {doc_id!r}, {start!r}, {end!r}") from None
        n = _lengths(self.db).get(doc_id)
        if n is None:
            raise ParameterError(f"no document {doc_id} in {self.db.path}")
        if not 0 <= start < end <= n:
            raise ParameterError(f"frames {start}:{end} are not a stretch of document {doc_id} (0:{n}, half-open)")
        note = row.get("note") or ""
        if not isinstance(note, str) or len(note) > NOTE_CHARACTERS:
            raise ParameterError(f"a note is a text of at most {NOTE_CHARACTERS} characters; got {str(note)[:40]!r}")
        return {"doc_id": doc_id, "start": start, "end": end, "label": text(row.get("label"), "label"),
                "source": one_of(row.get("source") or "manual", "source", SOURCES), "note": note}  # fmt: skip

    def _write(self, make, author: str) -> list[dict]:
        """Under the lock: the log read again, ``make(log, state)`` -> [(op, label_id, row, undoes)], those changes
        appended and the file replaced atomically. Returns the new changes."""
        folder = labels_folder(self.db.path)
        folder.mkdir(exist_ok=True)
        with store.locked(folder, what=f"the labels of {self.db.path}"):
            log = _read(self.path)
            state = _replay(log)[0]
            now = datetime.now(timezone.utc).isoformat(timespec="milliseconds")
            new = [{"change": len(log) + i + 1, "op": op, "label_id": int(label_id), "author": author, "time": now,
                    "row": row, "undoes": undoes}
                   for i, (op, label_id, row, undoes) in enumerate(make(log, state))]  # fmt: skip
            log = log + new
            store.atomic_write(self.path, json.dumps({**store.stamp(FORMAT, VERSION), "sha256": _digest(log),
                                                      "changes": log}, indent=0).encode())  # fmt: skip
        return new


def _lengths(db) -> dict:
    docs = db.documents
    return dict(zip(docs["doc_id"].astype(int), docs["n_frames"].astype(int)))


def _digest(log: list[dict]) -> str:
    return hashlib.sha256(json.dumps(log, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _read(path: Path) -> list[dict]:
    """The stored log (empty when there is no file), checked: format, version and sha256."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return []
    try:
        stored = json.loads(data)
    except ValueError as exc:
        raise MotionDBError(f"{path}: unreadable ({exc}); restore it from a backup") from None
    store.check_format(stored, FORMAT, VERSION, path)
    log = stored.get("changes")
    if not isinstance(log, list) or _digest(log) != stored.get("sha256"):
        raise MotionDBError(f"{path}: its changes differ from the sha256 recorded when it was written: the file is "
                            "damaged; restore it from a backup")  # fmt: skip
    return log


def _replay(log: list[dict]) -> tuple[dict, dict, set, dict]:
    """The log applied in order: the state (label_id -> row with its author and time), each change's full row before
    it (change -> row or None; an undo puts that row back whole, author and time included), the changes undone (an
    undo of an undo re-applies the first) and each label's last change."""
    state, before, undone, last = {}, {}, set(), {}
    for c in log:
        label_id, k, target = c["label_id"], c["change"], c.get("undoes")
        before[k] = state.get(label_id)
        if c["row"] is None:
            state.pop(label_id, None)
        else:
            state[label_id] = before[target] if target is not None else {**c["row"], "author": c["author"],
                                                                          "time": c["time"]}  # fmt: skip
        if target is not None:
            undone.add(target)
            undone.discard(log[target - 1].get("undoes"))
        last[label_id] = k
    return state, before, undone, last


def _frame(state: dict, label=None, sources=None) -> pd.DataFrame:
    rows = [{"label_id": i, **row} for i, row in sorted(state.items())]
    table = pd.DataFrame(rows, columns=COLUMNS)
    if label is not None:
        table = table[table["label"] == label]
    if sources is not None:
        table = table[table["source"].isin(list(sources))]
    for c in ("label_id", "doc_id", "start", "end"):
        table[c] = table[c].astype(np.int64)
    return table.reset_index(drop=True)


# ---------------------------------------------------------------------- exchange
def label_hits(db, table: pd.DataFrame) -> pd.DataFrame:
    """Labels (:meth:`SegmentLabels.table`) as a hit table (:func:`mocapviz.db.hits.hit_table`: rank, doc_id, name,
    start, end, frames, start_s, end_s) with label_id, label, author, source, time and note, then the documents'
    other label columns (their file-name ``label`` gives way to the segment's)."""
    return hit_table(db, table["doc_id"], table["start"], table["end"],
                     **{c: table[c].to_numpy() for c in ("label_id", "label", "author", "source", "time", "note")})


def exported(db, table: pd.DataFrame, format: str = "csv") -> bytes:
    """Labels as a file's content: ``"csv"``, :func:`label_hits`' columns; ``"babel"``, BABEL-style JSON
    (:func:`babel_json`).

    Parameters
    ----------
    db : MotionDB
    table : pandas.DataFrame
        Labels (:meth:`SegmentLabels.table`).
    format : {"csv", "babel"}

    Returns
    -------
    bytes
    """
    if one_of(format, "format", ("csv", "babel")) == "csv":
        return label_hits(db, table).to_csv(index=False).encode()
    return json.dumps(babel_json(db, table), indent=1).encode()


def babel_json(db, table: pd.DataFrame) -> dict:
    """Labels in BABEL's layout (Punnakkal et al. 2021, its ``frame_ann``): per document (by name) that holds a
    label of a positive source (:data:`POSITIVE`; a rejected hit is no action), ``{"feat_p": its file, "dur":
    seconds, "fps": its rate, "frame_ann": {"labels": [{"seg_id", "raw_label", "proc_label", "act_cat", "start_t",
    "end_t"}]}}``, times in seconds at the document's own rate (``fps`` is mocapviz's addition: BABEL's AMASS files
    carry their rate).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()  # 120 Hz
    >>> rows = pd.DataFrame({"label_id": [1], "doc_id": [7], "start": [12], "end": [60], "label": ["kick"],
    ...                      "source": ["manual"]})
    >>> entry = babel_json(db, rows)["HDM_dg_kickLFront1Reps_017_120"]
    >>> entry["frame_ann"]["labels"][0]["start_t"], entry["frame_ann"]["labels"][0]["end_t"], entry["fps"]
    (0.1, 0.5, 120.0)
    """
    docs = db.documents.set_index("doc_id")
    out = {}
    for row in table[table["source"].isin(POSITIVE)].itertuples():
        doc = docs.loc[row.doc_id]
        fps = float(doc["fps"])
        entry = out.setdefault(str(doc["name"]), {"feat_p": Path(str(doc.get("path", doc["name"]))).name,
                                                   "dur": int(doc["n_frames"]) / fps, "fps": fps,
                                                   "frame_ann": {"labels": []}})  # fmt: skip
        entry["frame_ann"]["labels"].append({"seg_id": f"mocapviz-{row.label_id}", "raw_label": row.label,
                                             "proc_label": row.label, "act_cat": [row.label],
                                             "start_t": row.start / fps, "end_t": row.end / fps})  # fmt: skip
    return out


def read_labels(db, path: str | os.PathLike) -> list[dict]:
    """The labels of a CSV (:func:`exported`'s columns; ``name`` or else ``doc_id``, ``start``, ``end``,
    ``label``, optionally ``note``) or BABEL-style JSON file (:func:`babel_json`'s layout, ``proc_label`` or
    else ``raw_label``; seconds turned into frames at the document's rate, rounded) as rows for
    :meth:`SegmentLabels.add_many` (source ``imported``), the documents found by name in ``db``.

    Raises
    ------
    ParameterError
        The file is neither, or names a document ``db`` does not hold (or holds twice), or lacks a column.
    """
    path = Path(path)
    names = db.documents.groupby("name")["doc_id"].agg(list)

    def doc_of(name) -> int:
        ids = names.get(str(name))
        if not ids or len(ids) > 1:
            raise ParameterError(f"{path}: document {name!r} is {'not in' if not ids else 'twice in'} {db.path}")
        return int(ids[0])

    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text())
            rows = []
            for name, entry in data.items():
                doc_id = doc_of(name)
                fps = float(db.document(doc_id)["fps"])
                for seg in ((entry.get("frame_ann") or {}).get("labels") or []):
                    rows.append({"doc_id": doc_id, "start": round(float(seg["start_t"]) * fps),
                                 "end": round(float(seg["end_t"]) * fps),
                                 "label": seg.get("proc_label") or seg.get("raw_label"), "source": "imported"})
        except (ValueError, AttributeError, KeyError, TypeError) as exc:
            raise ParameterError(f"{path}: not a BABEL-style label file ({type(exc).__name__}: {exc})") from None
        return rows
    try:
        table = pd.read_csv(path, dtype={"name": str, "label": str, "note": str}, keep_default_na=False)
    except (ValueError, OSError) as exc:
        raise ParameterError(f"{path}: not a label CSV file ({exc})") from None
    missing = [c for c in ("start", "end", "label") if c not in table.columns]
    if missing or not {"name", "doc_id"} & set(table.columns):
        raise ParameterError(f"{path}: no column {', '.join(missing) or 'name (or doc_id)'}")
    docs = [doc_of(n) for n in table["name"]] if "name" in table.columns else table["doc_id"].tolist()
    notes = table["note"] if "note" in table.columns else [""] * len(table)
    return [{"doc_id": d, "start": s, "end": e, "label": lab, "source": "imported", "note": n}
            for d, s, e, lab, n in zip(docs, table["start"], table["end"], table["label"], notes)]


def overlapping(hits: pd.DataFrame, labels: pd.DataFrame) -> np.ndarray:
    """Whether each hit overlaps a labelled segment: the same document and at least one frame in common
    (``hit.start < label.end`` and ``label.start < hit.end``, both half-open).

    Parameters
    ----------
    hits : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` (a hit table).
    labels : pandas.DataFrame
        ``doc_id``, ``start``, ``end`` of the segments (:meth:`SegmentLabels.table`).

    Returns
    -------
    np.ndarray [shape=(len(hits),)], bool

    Examples
    --------
    >>> hits = pd.DataFrame({"doc_id": [1, 1, 2], "start": [0, 10, 0], "end": [10, 20, 5]})
    >>> overlapping(hits, pd.DataFrame({"doc_id": [1], "start": [9], "end": [10]})).tolist()
    [True, False, False]
    """
    pairs = pd.DataFrame({"row": np.arange(len(hits)), "doc_id": np.asarray(hits["doc_id"], np.int64),
                          "start": np.asarray(hits["start"], np.int64), "end": np.asarray(hits["end"], np.int64)})
    segs = pd.DataFrame({c: np.asarray(labels[c], np.int64) for c in ("doc_id", "start", "end")})
    both = pairs.merge(segs, on="doc_id", suffixes=("", "_label"))
    hit = both.loc[(both["start"] < both["end_label"]) & (both["start_label"] < both["end"]), "row"]
    found = np.zeros(len(hits), dtype=bool)
    found[hit.to_numpy()] = True
    return found
