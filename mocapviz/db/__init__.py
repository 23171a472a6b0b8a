"""The database layer: many clips on the canonical skeleton, on disk, and the one table every search returns.

database.py  :class:`MotionDB`: open, the documents table, frames, motions, append (atomic generations).
ingest.py    files, folders and globs read in parallel into new documents (``MotionDB.ingest``).
batches.py   per-document work in batches of whole documents, on threads or Dask workers.
hits.py      the result convention: :func:`hits.hit_table` builds every hit table (doc_id, in-document half-open
             ``start``/``end``, seconds at the document's own rate); :func:`hits.from_database_frames` and
             :func:`hits.database_frames` convert database-wide frame numbers.

See ``docs/architecture.md``.
"""
from .._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"MotionDB": ".database", "expand_paths": ".ingest",
                                               "read_document": ".ingest", "map_documents": ".batches",
                                               "hit_table": ".hits"})  # fmt: skip
__all__ = ["MotionDB", "expand_paths", "hit_table", "map_documents", "read_document"]
