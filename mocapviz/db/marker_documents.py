"""Marker-only documents: C3D files whose markers match no known marker set, kept beside a MotionDB.

A MotionDB stores every document on the 24 canonical joints; a C3D file whose labels match no marker set
(:mod:`mocapviz.motion.markers`) has none. Ingested with ``markers_only="keep"`` such a file becomes a
**marker-only document**: its markers are stored as every C3D document's are (``DB/markers/<sha256>.npz``,
:mod:`mocapviz.db.markers`: at the file's own rate, gaps as a mask, no non-finite value stored) and it gets a row in
its own table, ``DB/markers/documents.json`` (:func:`mocapviz.db.layout.marker_documents_file`), never in the
documents table nor in the frame arrays. So nothing that reads canonical joints (frame arrays, numeric and
relational sets, indexes, shards, pages) ever meets one, and every existing search answers as it did without it.

Its ids are negative (-1, -2, ... in the order stored), so that no id names both a document of the documents table
(0, 1, ...) and a marker-only one, whatever is appended later. They are searched by their markers alone
(:mod:`mocapviz.similarity.marker_search`).

MarkerDocuments         the table of a database's marker-only documents (a view a hit table can be made from).
read_marker_documents   that table, as stored now.
add_marker_documents    store marker Motions as new marker-only documents (ingest does it for the files kept).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .. import store
from ..errors import MotionDBError, ParameterError, UnknownKeyError
from ..motion import Motion
from ..store import check_format, stamp
from .layout import marker_documents_file, markers_file, markers_folder
from .markers import read_markers, save_markers

__all__ = ["COLUMNS", "MarkerDocuments", "add_marker_documents", "read_marker_documents"]

FORMAT, VERSION = "mocapviz.MarkerDocuments", 1
COLUMNS = ["doc_id", "name", "path", "format", "n_frames", "fps", "source_fps", "sha256", "label", "markers"]
"""The columns of every row (``markers``: the marker labels, in the file's order); label columns follow."""


class MarkerDocuments:
    """The marker-only documents of the database at ``path``.

    Attributes
    ----------
    path : pathlib.Path
        The database folder.
    documents : pandas.DataFrame
        One row per marker-only document: :data:`COLUMNS`, the label columns, and ``start``: the document's first
        frame if the marker-only documents were laid end to end in id order, -1 first (what a hit table needs).

    Parameters
    ----------
    path : str or os.PathLike
    rows : list of dict
        The stored rows (:func:`read_marker_documents` reads them).
    """

    def __init__(self, path, rows: list[dict]):
        self.path = Path(path)
        docs = pd.DataFrame(rows, columns=list(dict.fromkeys(COLUMNS + [k for r in rows for k in r])))
        docs = docs.sort_values("doc_id", ascending=False, ignore_index=True)
        for c in ("doc_id", "n_frames"):
            docs[c] = docs[c].astype("int64")
        n_frames = docs["n_frames"].to_numpy(np.int64)
        docs["start"] = np.cumsum(n_frames) - n_frames
        self.documents = docs

    def __len__(self) -> int:
        return len(self.documents)

    @property
    def label_columns(self) -> list[str]:
        """``label`` and the label tables' columns (``actor``, ...), as :attr:`MotionDB.label_columns`."""
        return ["label"] + [c for c in self.documents.columns if c not in COLUMNS and c != "start"]

    def document(self, doc_id: int) -> pd.Series:
        """The row of marker-only document ``doc_id`` (an UnknownKeyError naming the ids held when none)."""
        rows = self.documents[self.documents["doc_id"] == doc_id]
        if rows.empty:
            held = f"ids {self.documents['doc_id'].max()}..{self.documents['doc_id'].min()}" if len(self) else "none"
            raise UnknownKeyError(f"{self.path}: no marker-only document {doc_id} (marker-only documents: {held})")
        return rows.iloc[0]

    def motion(self, doc_id: int) -> Motion:
        """Marker-only document ``doc_id``'s markers: a marker Motion [shape=(T, M, 3)], cm, y up, NaN in gaps, at
        the file's own rate, ``joint_names`` the marker labels (:func:`mocapviz.db.markers.read_markers`)."""
        row = self.document(doc_id)
        what = f"marker-only document {doc_id} ({row['name']})"
        path = markers_file(self.path, row["sha256"])
        if not path.is_file():
            raise MotionDBError(f"{path}: the markers of {what} are missing; ingest its file again into a new "
                                "database")  # fmt: skip
        motion = read_markers(path, what)
        labels = {"label": None if pd.isna(row["label"]) else row["label"],
                  **{c: row[c] for c in self.label_columns[1:] if not pd.isna(row[c])}}  # fmt: skip
        return Motion(positions=motion.positions, fps=motion.fps, joint_names=motion.joint_names,
                      parents=motion.parents,
                      source=motion.source, labels={**motion.labels, **labels})  # fmt: skip


def read_marker_documents(db_path) -> MarkerDocuments:
    """The marker-only documents stored beside the database at ``db_path`` (none when it holds no table).

    Parameters
    ----------
    db_path : str or os.PathLike
        The database folder.

    Returns
    -------
    MarkerDocuments

    Raises
    ------
    MotionDBError
        The table is unreadable or damaged (naming the file).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> len(read_marker_documents(MotionDB.sample().path))
    0
    """
    f = marker_documents_file(db_path)
    if not f.is_file():
        return MarkerDocuments(db_path, [])
    try:
        table = check_format(json.loads(f.read_text(encoding="utf-8")), FORMAT, VERSION, f)
        rows = table["documents"]
        if not isinstance(rows, list) or not all(isinstance(r, dict) and set(COLUMNS) <= set(r) for r in rows):
            raise ValueError(f"every row needs {', '.join(COLUMNS)}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise MotionDBError(f"{f}: damaged table of marker-only documents ({exc}); ingest their files again into "
                            "a new database") from None  # fmt: skip
    return MarkerDocuments(db_path, rows)


def add_marker_documents(db_path, motions, metas) -> list[int]:
    """Store marker Motions as new marker-only documents of the database at ``db_path``.

    Parameters
    ----------
    db_path : str or os.PathLike
        The database folder.
    motions : list of Motion
        Marker Motions (no skeleton: every parent -1) [shape=(T, M, 3)], cm, NaN in gaps, T >= 1; some marker seen.
    metas : list of dict
        One per motion: ``name``, ``path``, ``sha256`` (its file's, or any unique key: the markers file's name),
        ``label`` and label columns; ``format`` and ``source_fps`` optional.

    Returns
    -------
    list of int
        The new documents' ids (negative, continuing the stored ones); a motion whose ``sha256`` is held already is
        skipped (its id not listed).

    Raises
    ------
    ParameterError
        A motion with a skeleton, without frames or with no marker ever seen; metas of another length.
    """
    motions, metas = list(motions), [dict(m) for m in metas]
    if len(motions) != len(metas):
        raise ParameterError(f"{len(motions)} motions but {len(metas)} metas")
    for m, meta in zip(motions, metas):
        what = f"{meta.get('name')} ({m.source})"
        if (np.asarray(m.parents) != -1).any():
            raise ParameterError(f"{what}: not a marker Motion (it has a skeleton); store it in the MotionDB")
        if not m.n_frames or not np.isfinite(m.positions).all(axis=2).any():
            raise ParameterError(f"{what}: no frame, or no marker ever seen: nothing to store")
    folder = markers_folder(db_path)
    folder.mkdir(exist_ok=True)
    new = []
    with store.locked(folder):
        held = read_marker_documents(db_path).documents
        rows = held[[c for c in held.columns if c != "start"]].to_dict("records")
        known = set(held["sha256"])
        next_id = int(held["doc_id"].min()) - 1 if len(held) else -1
        for m, meta in zip(motions, metas):
            if meta["sha256"] in known:
                continue
            known.add(meta["sha256"])
            save_markers(markers_file(db_path, meta["sha256"]), m, meta["name"])
            rows.append({**{k: _plain(v) for k, v in meta.items() if k != "markers_only"}, "doc_id": next_id, "n_frames": m.n_frames,
                         "fps": float(m.fps), "markers": list(m.joint_names),
                         "format": meta.get("format", "c3d"), "source_fps": float(meta.get("source_fps", m.fps)),
                         "label": meta.get("label")})  # fmt: skip
            new.append(next_id)
            next_id -= 1
        rows = [{k: _plain(v) for k, v in r.items()} for r in rows]
        store.atomic_write(marker_documents_file(db_path),
                           json.dumps({**stamp(FORMAT, VERSION), "documents": rows}, indent=1).encode())
    return new


def _plain(value):
    """A table value as JSON holds it: numpy scalars as Python numbers, NaN and pandas' missing values as None."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or (not isinstance(value, (str, list)) and pd.isna(value)):
        return None
    return value
