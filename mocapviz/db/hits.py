"""The one result convention: every hit of every search, as one table (docs/glossary.md "Results").

A hit is a stretch of one document. Every search of mocapviz (relational query by example, similarity search of
clips and stretches, the lazy neighbourhood graph and subsequence DTW, motion templates, kNN poses as one-frame
stretches) returns its hits through :func:`hit_table`, so that every table in Python, on the command line
(``--csv``) and in the dashboard has the same columns with the same meaning:

========== ======================================================================================================
rank       1, 2, ... best first
doc_id     the document (``db.documents.doc_id``)
name       the document's name (its file's stem)
start      the first frame of the hit, counted from the document's first frame (0)
end        one past the hit's last frame: frames ``start:end`` of the document, half-open
frames     ``end - start``
start_s    ``start / fps`` with the document's own frame rate, seconds
end_s      ``end / fps``
...        the search's own columns (``cost``, ``score``, ``distance``, ...), in the order it gives them
label ...  the document's label columns (``label``, ``actor``, ...)
========== ======================================================================================================

Database-wide frame numbers (rows of ``db.positions``) stay inside the library: :func:`from_database_frames` turns
them into hits, :func:`database_frames` turns a hit back into them (to play or cut it).
"""
from __future__ import annotations

import warnings
import weakref

import numpy as np
import pandas as pd

from ..errors import ParameterError

__all__ = ["COLUMNS", "HitTable", "database_frames", "first_frames", "from_database_frames", "hit_table"]

COLUMNS = ["rank", "doc_id", "name", "start", "end", "frames", "start_s", "end_s"]
# columns of earlier releases, still readable (with a FutureWarning) with their old meaning: the last frame included
_OLD = {"start_frame": ("start", 0), "end_frame": ("end", -1), "first": ("start", 0), "last": ("end", -1)}


class HitTable(pd.DataFrame):
    """A pandas DataFrame of hits (:func:`hit_table`) that still answers the old column names ``start_frame``,
    ``end_frame`` (the last frame, included), ``first`` and ``last`` with a FutureWarning naming the new one."""

    @property
    def _constructor(self):
        return HitTable

    def __getitem__(self, key):
        if isinstance(key, str) and key in _OLD and key not in self.columns:
            new, shift = _OLD[key]
            warnings.warn(f"the hit column {key!r} is now {new!r} (in-document frames, half-open: {new} "
                          f"{'= last frame + 1' if shift else 'as before'})", FutureWarning, stacklevel=2)  # fmt: skip
            return super().__getitem__(new) + shift
        return super().__getitem__(key)


def hit_table(db, doc_ids, starts, ends, **columns) -> HitTable:
    """The ranked table of hits ``doc_ids[i]``, frames ``starts[i]:ends[i]`` of that document, best first.

    Parameters
    ----------
    db : MotionDB
        The database the hits are in (their names, frame rates and labels come from ``db.documents``).
    doc_ids : array_like [shape=(n,)], int
        The documents, in rank order.
    starts, ends : array_like [shape=(n,)], int
        Frames within each document, half-open: ``0 <= start < end <= n_frames``.
    **columns : array_like [shape=(n,)]
        The search's own columns (e.g. ``cost=...``), placed after ``end_s`` in the order given.

    Returns
    -------
    HitTable
        ``rank, doc_id, name, start, end, frames, start_s, end_s``, the search's columns, the label columns.

    Raises
    ------
    ParameterError
        A doc id not in ``db`` or a span outside its document (a bug of the caller, named with the row).

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> t = hit_table(db, [3, 0], [10, 0], [70, 120], cost=[1.5, 2.0])
    >>> print(t[["rank", "doc_id", "start", "end", "frames", "start_s", "end_s", "cost"]].to_string(index=False))
     rank  doc_id  start  end  frames  start_s    end_s  cost
        1       3     10   70      60 0.083333 0.583333   1.5
        2       0      0  120     120 0.000000 1.000000   2.0
    """
    doc_ids = np.asarray(doc_ids, dtype=np.int64).reshape(-1)
    starts = np.asarray(starts, dtype=np.int64).reshape(-1)
    ends = np.asarray(ends, dtype=np.int64).reshape(-1)
    if not len(doc_ids) == len(starts) == len(ends):
        raise ParameterError(f"{len(doc_ids)} doc ids, {len(starts)} starts and {len(ends)} ends: give one each per hit")
    docs = _documents(db)
    pos = _rows(docs, doc_ids)
    missing = pos < 0
    if missing.any():
        raise ParameterError(f"hit {int(np.argmax(missing)) + 1}: no document {doc_ids[missing][0]} in {db.path}")
    n_frames, fps = docs["n_frames"][pos], docs["fps"][pos]
    bad = (starts < 0) | (ends <= starts) | (ends > n_frames)
    if bad.any():
        i = int(np.argmax(bad))
        raise ParameterError(f"hit {i + 1}: frames {starts[i]}:{ends[i]} are not a stretch of document {doc_ids[i]} "
                             f"(0:{n_frames[i]})")  # fmt: skip
    table = {"rank": np.arange(1, len(doc_ids) + 1), "doc_id": doc_ids, "name": docs["name"].take(pos),
             "start": starts, "end": ends, "frames": ends - starts, "start_s": starts / fps, "end_s": ends / fps}
    for name, values in columns.items():
        if name in table:
            raise ParameterError(f"column {name!r} is one of the hit table's own")
        table[name] = values.to_numpy() if isinstance(values, pd.Series) else values
    for name in db.label_columns:
        if name not in table:
            table[name] = docs[name].take(pos)
    return HitTable(table)


_DOCUMENTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _documents(db) -> dict:
    """The columns of ``db.documents`` a hit table takes, sorted by doc id (numpy arrays; names and labels as pandas
    arrays of their own dtype), made once per MotionDB: pandas' row lookups cost milliseconds per search."""
    got = _DOCUMENTS.get(db)
    if got is None or got["_table"] is not db.documents:
        docs = db.documents.sort_values("doc_id")
        got = {"_table": db.documents, "doc_id": docs["doc_id"].to_numpy(np.int64),
               "n_frames": docs["n_frames"].to_numpy(np.int64), "fps": docs["fps"].to_numpy(np.float64),
               "first": docs["start"].to_numpy(np.int64), "name": docs["name"].array}  # fmt: skip
        for name in db.label_columns:
            got[name] = (docs[name] if name in docs else pd.Series([None] * len(docs), dtype=object)).array
        _DOCUMENTS[db] = got
    return got


def _rows(docs: dict, doc_ids: np.ndarray) -> np.ndarray:
    """The row of each doc id in :func:`_documents`' columns, -1 for an id it does not hold. Doc ids are
    consecutive in every database (0, 1, ...) and in every shard of one: then the row is an offset, not a binary
    search (1.2 ms for 15,000 hits among 19,000 documents, in random order)."""
    ids = docs["doc_id"]
    if not len(ids):
        return np.full(len(doc_ids), -1, dtype=np.int64)
    if ids[-1] - ids[0] == len(ids) - 1:  # sorted and unique, so consecutive
        pos = doc_ids - ids[0]
        return np.where((pos >= 0) & (pos < len(ids)), pos, -1)
    pos = np.minimum(np.searchsorted(ids, doc_ids), len(ids) - 1)
    return np.where(ids[pos] == doc_ids, pos, -1)


def first_frames(db, doc_ids) -> np.ndarray:
    """The database-wide frame (row of ``db.positions``) where each of ``doc_ids`` begins.

    Parameters
    ----------
    db : MotionDB
    doc_ids : array_like [shape=(n,)], int
        Documents of ``db`` (not checked: a hit table's own).

    Returns
    -------
    np.ndarray [shape=(n,)], int64

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> first_frames(db, [1, 0]).tolist() == [db.frames(1).start, db.frames(0).start]
    True
    """
    docs = _documents(db)
    return docs["first"][_rows(docs, np.asarray(doc_ids, dtype=np.int64).reshape(-1))]


def from_database_frames(db, first, stop) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Database-wide half-open frame ranges ``first[i]:stop[i]`` as (doc_ids, starts, ends) within documents.

    Parameters
    ----------
    db : MotionDB
    first, stop : array_like [shape=(n,)], int
        Rows of ``db.positions``; each range inside one document.

    Returns
    -------
    doc_ids, starts, ends : np.ndarray [shape=(n,)], int64

    Raises
    ------
    ParameterError
        A range that is empty, outside the database or crosses into the next document.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> d0 = int(db.documents.set_index("doc_id").loc[2, "start"])
    >>> [a.tolist() for a in from_database_frames(db, [d0 + 5], [d0 + 25])]
    [[2], [5], [25]]
    """
    first = np.asarray(first, dtype=np.int64).reshape(-1)
    stop = np.asarray(stop, dtype=np.int64).reshape(-1)
    docs = db.documents.sort_values("start")
    starts = docs["start"].to_numpy(np.int64)
    row = np.searchsorted(starts, first, side="right") - 1
    bad = (first < 0) | (stop <= first) | (stop > db.n_frames)
    ok_row = np.clip(row, 0, len(docs) - 1)
    bad |= stop > starts[ok_row] + docs["n_frames"].to_numpy(np.int64)[ok_row]
    if bad.any():
        i = int(np.argmax(bad))
        raise ParameterError(f"database frames {first[i]}:{stop[i]} are not inside one document of {db.path}")
    return docs["doc_id"].to_numpy(np.int64)[row], first - starts[row], stop - starts[row]


def database_frames(db, doc_id: int, start: int, end: int) -> slice:
    """The rows of ``db.positions`` of frames ``start:end`` of document ``doc_id`` (a hit's stretch).

    Parameters
    ----------
    db : MotionDB
        The database of the hit.
    doc_id : int
        The hit's document.
    start, end : int
        Frames within the document, half-open: ``0 <= start < end <= n_frames``.

    Returns
    -------
    slice
        Database-wide frames (rows of ``db.positions``), to play or cut the hit.

    Raises
    ------
    ParameterError
        A span outside the document.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> sl = database_frames(db, 2, 5, 25)
    >>> sl.stop - sl.start
    20
    """
    span = db.frames(int(doc_id))
    if not 0 <= int(start) < int(end) <= span.stop - span.start:
        raise ParameterError(f"frames {start}:{end} are not a stretch of document {doc_id} (0:{span.stop - span.start})")
    return slice(span.start + int(start), span.start + int(end))
