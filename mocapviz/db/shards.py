"""A MotionDB split by documents into shards: the unit of work of sharded search (:mod:`mocapviz.sharded`).

A shard is a run of consecutive documents in storage order, so its frames are one contiguous block of the
database's arrays: :func:`shard_view` is a MotionDB of those documents whose arrays are views of the parent's
memory-mapped ones (nothing copied) and whose documents keep their doc ids. Every search of mocapviz run on a view
returns the same hit table (doc ids, in-document frames, seconds) as on the whole database, restricted to those
documents; only the database-wide frame numbers, which stay inside the library, are the view's own.
"""
from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..validation import count

__all__ = ["shard_view", "split_documents"]


def split_documents(db, n_shards: int) -> list[np.ndarray]:
    """The doc ids of ``n_shards`` shards: consecutive documents in storage order, of about equal frames.

    Parameters
    ----------
    db : MotionDB
    n_shards : int
        Shards wanted, >= 1; at most one per document (fewer are returned for a smaller database).

    Returns
    -------
    list of np.ndarray [shape=(n_i,)], int64
        Each shard's doc ids, in storage order; together every document once.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> shards = split_documents(db, 2)
    >>> [len(s) for s in shards], sum(int(db.documents.set_index("doc_id").loc[s, "n_frames"].sum()) for s in shards)
    ([10, 14], 5543)
    """
    n_shards = count(n_shards, "n_shards")
    docs = db.documents.sort_values("start")
    if docs.empty:
        raise ParameterError(f"{db.path} has no document to shard")
    n_shards = min(n_shards, len(docs))
    ends = np.cumsum(docs["n_frames"].to_numpy(np.int64))
    cuts = np.searchsorted(ends, ends[-1] * np.arange(1, n_shards) / n_shards, side="left") + 1
    cuts = np.unique(np.clip(cuts, 1, len(docs) - 1)) if n_shards > 1 else np.empty(0, dtype=np.int64)
    return [part.astype(np.int64) for part in np.split(docs["doc_id"].to_numpy(), cuts)]


def shard_view(db, doc_ids, labels: bool = True) -> object:
    """A MotionDB of some consecutive documents of ``db``: their rows of the arrays (views, not copies), their
    rows of the documents table (doc ids kept, ``start`` counted from the shard's first frame).

    Parameters
    ----------
    db : MotionDB
    doc_ids : array_like of int
        Consecutive documents in storage order (a shard of :func:`split_documents`).
    labels : bool
        Keep every label column (``actor``, ``class``, ...); False keeps ``label`` alone, so that the view's hit
        tables carry one label column: a :class:`~mocapviz.sharded.shard.Shard`'s hits get their labels once, from
        the whole database, when they are merged (taking 14 label columns cost a shard 1.5 ms per 7,000 hits).

    Returns
    -------
    MotionDB
        Read it, search it; its derived data (features, indexes) are those computed from its own frames, or the
        parent's rows of them passed explicitly (a view never loads the parent's stored derived data, whose
        length differs: those loads refuse it).

    Raises
    ------
    ParameterError
        Unknown doc ids, or documents that are not consecutive.

    Examples
    --------
    >>> from mocapviz import MotionDB
    >>> db = MotionDB.sample()
    >>> view = shard_view(db, split_documents(db, 2)[1])
    >>> len(view), view.n_frames, int(view.documents["start"].iloc[0])
    (14, 2733, 0)
    >>> bool((view.motion(20).positions == db.motion(20).positions).all())
    True
    >>> len(db.label_columns), shard_view(db, split_documents(db, 2)[1], labels=False).label_columns
    (10, ['label'])
    """
    from .database import MotionDB

    wanted = np.asarray(doc_ids, dtype=np.int64).reshape(-1)
    docs = db.documents.sort_values("start").reset_index(drop=True)
    rows = np.flatnonzero(docs["doc_id"].isin(wanted).to_numpy())
    if len(rows) != len(np.unique(wanted)):
        missing = sorted(set(wanted.tolist()) - set(docs["doc_id"].tolist()))
        raise ParameterError(f"no document {missing[0]} in {db.path}" if missing else "doc ids given twice")
    if len(rows) == 0 or rows[-1] - rows[0] + 1 != len(rows):
        raise ParameterError("a shard is a run of consecutive documents in storage order (split_documents)")
    part = docs.iloc[rows].copy()
    if not labels:
        part = part.drop(columns=[c for c in db.label_columns if c != "label"])
    first = int(part["start"].iloc[0])
    stop = int(part["start"].iloc[-1] + part["n_frames"].iloc[-1])
    part["start"] = part["start"] - first
    manifest = {**db.manifest, "shard": [first, stop]}
    arrays = {"positions": db.positions[first:stop],
              "quaternions": None if db.quaternions is None else db.quaternions[first:stop]}  # fmt: skip
    view = MotionDB(db.path, manifest, part.reset_index(drop=True), arrays)
    view.shard_frames = (first, stop)
    return view
